"""The period check: do the swings between turning points take the time the equation of
motion gives with L = R - r and g? When not, :func:`period_cause` names the likely cause (a
wrong frame rate, trough radius, gravity or angles in degrees) from what else is known.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from rollfric.fit import eom
from rollfric.uncertainty.reasons import Reason

# period: a correct setup reproduces the swing period to the precision of the turning points
# (a frame in a half-period of ~0.35 s: 0.3 %, averaged over the swings); the period goes as
# sqrt(L), so 3 % is a 6 % error in L = R - r (5 mm on the thesis trough) or in the fps
PERIOD_TOL = 0.03
# where the fit's residuals already say the model does not follow the data, a period off by
# more than this (or by more than PERIOD_FRAMES frame periods over the swings measured) is
# named as their cause: the turning points time the swings to a frame or two (a 2 % radius or
# g 9.6 for 9.81 puts the period 1 % off and the fit's residual at 50 x its noise)
PERIOD_TOL_MISFIT = 0.005
PERIOD_FRAMES = 3.0
# gravity: where labs are, g is 9.78 (equator) .. 9.83 m/s^2 (poles); a setup's g outside
# GRAVITY_SANE is itself a suspect, and the period names it when the swings fit a local g
GRAVITY_LOCAL = (9.78, 9.83)
GRAVITY_SANE = (9.7, 9.9)
# the ball's path in the image: its radius within 2 % of L = R - r agrees with the setup
# (pixel size or trough radius 2 % off)
TRACK_RADIUS_TOL = 0.02


def half_period_frictionless(amplitude: float, track_radius: float, gravity: float) -> float:
    """Half-period of the ball's swing of the given amplitude without friction.

    (2 / omega) K(sin^2(A / 2)), omega^2 = 5 g / (7 L), K the complete elliptic integral.

    Parameters
    ----------
    amplitude : float
        The swing's amplitude A (rad); its magnitude is used, capped at pi / 2.
    track_radius : float
        L = R - r, the radius of the path of the ball's centre (m).
    gravity : float
        g (m/s^2).

    Returns
    -------
    float
        The half-period (s).
    """
    w = math.sqrt(eom.omega_squared(track_radius, gravity))
    m = math.sin(min(abs(amplitude), math.pi / 2) / 2) ** 2
    return 2.0 / w * float(special.ellipk(m))


def round_rate(fps: float) -> bool:
    """True for a frame rate a camera is set to: 24, 25, 30, 50, 60, 100, 120, 125, 250, 500,
    1000, 2000, 4000, 5000, ... (a mantissa of 1, 1.2, 1.25, 1.5, 2, 2.4, 2.5, 3, 4, 5, 6, 7.5
    or 8 within 0.5 %)."""
    if not fps > 0 or not math.isfinite(fps):
        return False
    m = fps / 10 ** math.floor(math.log10(fps))
    return any(abs(m / v - 1) <= 0.005 for v in (1, 1.2, 1.25, 1.5, 2, 2.4, 2.5, 3, 4, 5, 6,
                                                   7.5, 8, 10))


def period_reason(tp_t, tp_y, setup, unit_fps: float, t_data=None, *,
                  misfit: bool = False) -> Reason | None:
    """Compare the half-periods between turning points with L = R - r's; with ``t_data``
    (the times of the samples) only the half-swings the samples cover without a gap of a
    quarter of the small-angle half-period: turning points inside a gap are not seen.
    ``misfit``: the fit's residuals say the model does not follow the data; the period is
    then held to PERIOD_TOL_MISFIT (what the turning points can tell) instead of PERIOD_TOL."""
    if len(tp_t) < 3:
        return None
    keep = np.ones(len(tp_t) - 1, bool)
    if t_data is not None:
        t_data = np.sort(np.asarray(t_data, dtype=float))
        half = math.pi / math.sqrt(eom.omega_squared(setup.track_radius, setup.gravity))
        big = np.nonzero(np.diff(t_data) > 0.25 * half)[0]
        for a, b in zip(t_data[big], t_data[big + 1], strict=True):
            keep &= ~((tp_t[1:] >= a) & (tp_t[:-1] <= b))
        if keep.sum() < 2:
            return None
    amps = (0.5 * np.abs(np.diff(tp_y)))[keep]
    measured = float(np.diff(tp_t)[keep].sum())
    L, g = setup.track_radius, setup.gravity
    expected = sum(half_period_frictionless(a, L, g) for a in amps)
    rho = measured / expected
    tol = max(PERIOD_TOL_MISFIT, PERIOD_FRAMES / (unit_fps * measured)) if misfit \
        else PERIOD_TOL
    if abs(rho - 1) <= tol and not _gravity_explains(rho, setup.gravity):
        return None
    in_deg = sum(half_period_frictionless(math.radians(a), L, g) for a in amps)
    rho_deg = measured / in_deg
    head = (f"the swings take {1e3 * measured / len(amps):.1f} ms per half-swing, the equation "
            f"of motion with L = R - r = {1e3 * L:.2f} mm gives "
            f"{1e3 * expected / len(amps):.1f} ms ({100 * (rho - 1):+.1f} %)")
    detail = {"head": head, "rho": rho, "rho_deg": rho_deg, "unit_fps": unit_fps}
    return Reason("period", head + period_cause(rho, rho_deg, setup, unit_fps), detail)


def _gravity_explains(rho: float, g: float) -> bool:
    """Whether a setup's g outside GRAVITY_SANE is what puts the period ``rho`` (measured /
    expected) off: the swings fit a sane g (a period within PERIOD_TOL of the setup's still
    moves mu: g 9.6 for 9.81 m/s^2, a 1.1 % period, mu -0.43 %)."""
    lo, hi = GRAVITY_SANE
    return not lo <= g <= hi and lo <= g / (rho * rho) <= hi


def period_cause(rho: float, rho_deg: float, setup, unit_fps: float,
                 track_radius_seen: float | None = None) -> str:
    """The cause a period off by ``rho`` (measured / expected) most likely has, as text.

    The period fixes sqrt(L / g) in the frame clock's time, so one ratio cannot tell the frame
    rate, L = R - r and gravity apart; what else is known can: angles in degrees fit the
    swings; a setup's g outside GRAVITY_SANE whose swings fit a local g; a round frame rate
    the swings fit; the ball's path in the image (``track_radius_seen``, m: its radius in px
    times camera.pixel_size_mm) that agrees with the setup's L (then not the radius, but the
    camera's clock) or with the L the swings fit (then the radius).

    Parameters
    ----------
    rho, rho_deg : float
        The measured over the expected half-periods, the angles read as radians and as
        degrees.
    setup : rollfric.setup.model.Setup
        The setup the fit used.
    unit_fps : float
        The frame rate the times were made with (Hz).
    track_radius_seen : float, optional
        L as the image shows it (m); None when not known (a track without its pixels).

    Returns
    -------
    str
        "; ..." or ": ...", to follow the reason's first sentence.
    """
    L, g = setup.track_radius, setup.gravity
    L_fit, g_fit, fps_fit = L * rho * rho, g / (rho * rho), unit_fps * rho
    lo, hi = GRAVITY_LOCAL
    # degrees: the radians' period beyond the tolerance, the degrees' well within it (at a
    # small amplitude both read near 1, and a period 1 % off is no unit's)
    if abs(rho_deg - 1) <= PERIOD_TOL / 3 and abs(rho - 1) > PERIOD_TOL:
        return ("; the angles look like degrees (read as degrees, the swings fit within "
                f"{100 * abs(rho_deg - 1):.1f} %): give theta in radians")
    g_odd = not GRAVITY_SANE[0] <= g <= GRAVITY_SANE[1]
    tol = 2 * PERIOD_TOL  # g goes as the period squared
    if g_odd and lo * (1 - tol) <= g_fit <= hi * (1 + tol):
        return (f": environment.gravity_m_s2 = {g:g} m/s^2 is not the local gravity "
                f"({lo:g}-{hi:g} m/s^2): the swings fit g = {g_fit:.3g} m/s^2")
    gravity_too = (f"; environment.gravity_m_s2 = {g:g} m/s^2 is not a local gravity "
                   f"({lo:g}-{hi:g}) either" if g_odd else "")
    if round_rate(fps_fit):
        return (f": most likely the frame rate is wrong (the swings fit {fps_fit:.4g} Hz, "
                f"the setup says {unit_fps:g} Hz: camera.fps); else L would have to be "
                f"{1e3 * L_fit:.1f} mm" + gravity_too)
    if track_radius_seen is not None and math.isfinite(track_radius_seen):
        seen = track_radius_seen / L - 1
        if abs(seen) <= TRACK_RADIUS_TOL < abs(rho * rho - 1) / 2:
            return (f": the camera's frame rate or clock is off (camera.fps = {unit_fps:g} Hz;"
                    f" the swings fit {fps_fit:.4g} Hz, a clock {100 * (rho - 1):+.1f} % off),"
                    f" not the radius: the ball's path in the image has L = "
                    f"{1e3 * track_radius_seen:.2f} mm as the setup says, the swings would "
                    f"need {1e3 * L_fit:.2f} mm" + gravity_too)
        if abs(track_radius_seen / L_fit - 1) <= TRACK_RADIUS_TOL:
            return (f": cylinder.radius_mm or ball.diameter_mm is off: the swings fit L = "
                    f"{1e3 * L_fit:.2f} mm and the ball's path in the image has "
                    f"{1e3 * track_radius_seen:.2f} mm" + gravity_too)
    if abs(rho * rho - 1) <= 0.25:
        return (f": most likely cylinder.radius_mm or ball.diameter_mm is off (the swings fit "
                f"L = {1e3 * L_fit:.2f} mm), else the camera's frame rate or clock "
                f"(camera.fps: they fit {fps_fit:.4g} Hz)" + gravity_too)
    return (f": check camera.fps (the swings fit {fps_fit:.4g} Hz), the times' unit, "
            f"and cylinder.radius_mm / ball.diameter_mm (they fit L = {1e3 * L_fit:.1f} mm)"
            + gravity_too)
