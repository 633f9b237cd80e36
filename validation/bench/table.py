"""A line of ``rollfric bench``'s table (:class:`Row`), shared by the sections' modules."""

from __future__ import annotations

import dataclasses
import math


@dataclasses.dataclass
class Row:
    """One line of the table: a measured value beside its baseline."""

    section: str
    item: str
    value: float
    unit: str
    baseline: str = ""
    baseline_value: float = math.nan
    gain: float = math.nan  # speed-up or error ratio over the baseline (> 1: better)
    gain_kind: str = ""  # "speed-up", "accuracy", "smaller"; "x the bound": value / bound
    note: str = ""


def fmt(v: float | None) -> str:
    """A number as the bench's tables write it.

    Parameters
    ----------
    v : float or None
        The value.

    Returns
    -------
    str
        3 significant figures, no decimals from 100 up, an exponent below 0.01; empty for
        None or NaN.
    """
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    if v == 0:
        return "0"
    if abs(v) >= 100:
        return f"{v:.0f}"
    if abs(v) >= 0.01:
        return f"{v:.3g}"
    return f"{v:.2e}"
