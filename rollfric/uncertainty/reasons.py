"""Why a result is suspect: a :class:`Reason` (a code and a sentence for the user) and the
fit.json keys a list of them makes (:func:`summary`). The checks that make them are in
:mod:`rollfric.uncertainty.quality` and :mod:`rollfric.uncertainty.period`.
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class Reason:
    """Why a result is suspect: a short ``code`` and a sentence for the user."""

    code: str
    message: str
    # what the reason was judged from, for a later look with more of the measurement
    detail: dict | None = dataclasses.field(default=None, compare=False, repr=False)

    def to_dict(self) -> dict:
        """The reason as fit.json writes it.

        Returns
        -------
        dict
            ``{"code": code, "message": message}``.
        """
        return {"code": self.code, "message": self.message}


def summary(reasons) -> dict:
    """The fit.json keys: ``quality`` ("ok" or "suspect") and ``quality_reasons``.

    Parameters
    ----------
    reasons : iterable of Reason
        The quality reasons of a result; none means "ok".

    Returns
    -------
    dict
        ``quality``: "suspect" when there is a reason, else "ok"; ``quality_reasons``: the
        reasons as dicts (:meth:`Reason.to_dict`).
    """
    reasons = list(reasons)
    return {"quality": "suspect" if reasons else "ok",
            "quality_reasons": [r.to_dict() for r in reasons]}
