"""The reference integrator's loop: from turning point to turning point, and the sticking rule.

A ball rolling against a resistance that opposes its motion has an equation of motion whose
sign changes at every turning point (theta' = 0). :func:`solve_segments` integrates it with
SciPy's DOP853 one segment of fixed sign at a time, an event at each turning point, where the
ball sticks for good when :func:`sticks` holds (static rolling resistance holds it) or
restarts towards the bottom: no smoothed sign function, no chattering. The right-hand side is
the caller's: :func:`rollfric.fit.eom.solve_reference` (the fitter's equation, the validation
suite's ground truth) and the validation suite's equation with losses the fitter does not
assume share this loop; :mod:`rollfric.fit.eom` re-exports its names.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp


def sticks(theta: float, mu: float) -> bool:
    """True when a ball at rest at angle theta stays there.

    Below the axis (|theta| < pi/2) that is |tan(theta)| <= mu. In general the ball leaves
    rest towards the bottom (against sin(theta)) when gravity's pull along the track beats
    the rolling resistance there, g |sin(theta)| > mu g cos(theta): above the axis it always
    does (and it rests only where sin(theta) = 0).

    Parameters
    ----------
    theta : float
        Angle of the ball at rest, rad.
    mu : float
        Static rolling-resistance coefficient.

    Returns
    -------
    bool
        Whether the ball stays at rest.
    """
    return abs(math.sin(theta)) <= mu * math.cos(theta) or math.sin(theta) == 0.0


def _direction_from_rest(theta: float) -> float:
    """Sign of theta' just after leaving rest at theta (towards the bottom: against
    sin(theta), so also for angles beyond +-pi/2 or wound past +-pi)."""
    return -1.0 if math.sin(theta) > 0 else 1.0


def check_times(t):
    """The sample times as a float array, checked.

    Parameters
    ----------
    t : array_like
        Sample times, s.

    Returns
    -------
    numpy.ndarray
        ``t`` as floats.

    Raises
    ------
    ValueError
        If ``t`` is empty, not 1-D or not strictly increasing.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError("t must be a non-empty 1-D array of times")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing")
    return t


def solve_segments(theta0: float, omega0: float, t, accel, *, mu_static: float,
                   rtol: float = 1e-10, atol: float = 1e-13):
    """Integrate theta'' = accel(theta, theta', s) from turning point to turning point.

    The loop of :func:`solve_reference`, with the right-hand side left to the caller (an
    equation of motion with losses of its own, e.g. a speed-dependent mu or air drag): DOP853
    with an event at every turning point (theta' = 0), where the ball sticks for good when
    :func:`sticks` holds for ``mu_static``, else restarts towards the bottom. Within a segment
    the sign s of theta' is fixed and handed to ``accel``, so there is no smoothed sign
    function and no chattering.

    Parameters
    ----------
    theta0, omega0 : float
        The state at the first sample time ``t[0]``: angle (rad), angular velocity (rad/s).
    t : array_like
        Strictly increasing sample times, s.
    accel : callable
        ``accel(theta, theta_dot, s) -> float``: theta'' (rad/s^2) at the state with the
        resistance acting against the motion of sign ``s`` (+1.0 or -1.0).
    mu_static : float
        Static rolling-resistance coefficient of the sticking rule, >= 0.
    rtol, atol : float
        Tolerances passed to :func:`scipy.integrate.solve_ivp`.

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray, float)
        theta (rad) and theta_dot (rad/s) at ``t``, and the time the ball came to rest for
        good (s; inf if it never did), as :func:`solve_reference`.

    Raises
    ------
    ValueError
        If ``t`` is empty, not 1-D or not strictly increasing, or ``mu_static`` is negative.
    RuntimeError
        If the integrator fails.
    """
    t = check_times(t)
    if not mu_static >= 0:
        raise ValueError(f"mu must not be negative, got mu={mu_static}")
    theta_out = np.empty_like(t)
    omega_out = np.empty_like(t)
    t_now, th, om = float(t[0]), float(theta0), float(omega0)
    t_end = float(t[-1])
    t_stop = math.inf
    while True:
        if om == 0.0:
            if sticks(th, mu_static):
                t_stop = t_now
                sel = t >= t_now
                theta_out[sel] = th
                omega_out[sel] = 0.0
                break
            s = _direction_from_rest(th)
        else:
            s = math.copysign(1.0, om)

        def rhs(_t, y, s=s):
            return (y[1], accel(y[0], y[1], s))

        def turning(_t, y):
            return y[1]

        turning.terminal = True
        turning.direction = -s  # theta' crosses zero against the current motion
        if t_now >= t_end:
            theta_out[-1], omega_out[-1] = th, om
            break
        sol = solve_ivp(rhs, (t_now, t_end), [th, om], method="DOP853", rtol=rtol, atol=atol,
                        events=turning, dense_output=True)
        if not sol.success:
            raise RuntimeError(f"equation of motion: integration failed: {sol.message}")
        seg_end = sol.t[-1]
        sel = (t >= t_now) & (t <= seg_end)
        if np.any(sel):
            y = sol.sol(t[sel])
            theta_out[sel] = y[0]
            omega_out[sel] = y[1]
        if sol.status == 1 and sol.t_events[0].size:  # turning point
            t_now = float(sol.t_events[0][0])
            th, om = float(sol.y_events[0][0][0]), 0.0
            # samples exactly at the turning instant were filled by the dense output
        else:
            break
    return theta_out, omega_out, t_stop


