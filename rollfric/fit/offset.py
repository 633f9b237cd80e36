"""Whether the angle of the trough's bottom is fitted beside mu: asked for, or from the track.

A camera rolled about its axis turns every angle by the same offset; fitted, the offset takes
that out (0.5 deg of roll: mu +0.67 % without it), but only whole half-swings to both sides of
the bottom tell it from friction (:func:`offset_supported`).
"""

from __future__ import annotations

from rollfric.errors import InputError
from rollfric.fit.start import initial_guess
from rollfric.setup.model import Setup

OFFSET_MIN_TURNS = 3  # turning points inside the track before the offset is fitted by default


def offset_supported(t, theta, setup: Setup) -> tuple[bool, str]:
    """Whether theta(t) pins down the angle of the trough's bottom, and why.

    With Coulomb friction each half-swing is a cosine about +-eps/omega^2 on either side of the
    bottom: an angle offset moves both centres alike, friction moves them apart, so whole
    half-swings to both sides (three turning points inside the track, the release not
    counted) separate the two. With two the fit's start is unreliable (measured: a 0.8 s
    record of an 8 deg swing ran to the offset's bound); with fewer the offset and mu are one.

    Parameters
    ----------
    t, theta : array_like
        The track: times (s) and angles (rad), NaN where the ball was not found.
    setup : Setup
        The setup (for the fitter's self-start).

    Returns
    -------
    supported : bool
        Whether there are at least OFFSET_MIN_TURNS turning points.
    why : str
        The reason, for the user.
    """
    try:
        n = len(initial_guess(t, theta, setup)["turning_points_s"])
    except (InputError, ValueError) as exc:
        return False, f"no turning points found ({exc})"
    if n >= OFFSET_MIN_TURNS:
        return True, f"{n} turning points: the bottom's angle is separable from mu"
    return False, (f"{n} turning point(s): fewer than {OFFSET_MIN_TURNS}, the bottom's angle "
                   "cannot be told from mu")


def resolve_offset(offset, t, theta, setup: Setup, fit_method: str = "lsq") -> tuple[bool, str]:
    """Decide whether the angle offset of the trough's bottom is fitted.

    Parameters
    ----------
    offset : bool or "auto"
        What was asked for; "auto": where the data support it (:func:`offset_supported`).
    t, theta : array_like
        The track: times (s) and angles (rad).
    setup : Setup
        The setup.
    fit_method : str
        The fitting method; "paper1_eps" and "paper2_grid" have no offset.

    Returns
    -------
    fitted : bool
        Whether the offset is fitted.
    why : str
        The reason, for the user.

    Raises
    ------
    rollfric.errors.InputError
        ``offset`` is neither True, False nor "auto".
    """
    if offset is True or offset is False:
        return offset, "asked for" if offset else "not asked for"
    if offset != "auto":
        raise InputError(f"offset must be true, false or 'auto', got {offset!r}")
    if fit_method in ("paper1_eps", "paper2_grid"):  # the thesis's procedures have none
        return False, f"the {fit_method} method has no offset"
    return offset_supported(t, theta, setup)
