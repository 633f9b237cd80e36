"""The friction law decided against its rival: Coulomb + drag against speed + drag.

Rolling friction that does not depend on speed (M = mu r N; Minkin and Sikes, Am. J. Phys. 86,
77, 2018: a linear decay of the amplitude) against a resistance that grows with it
(mu(theta') = mu0 + mu1 |theta'|; Cross's "roughly proportional to speed"), both with the air
of :mod:`rollfric.fit.air`. :func:`friction_law` fits the speed law to the samples the
Coulomb fit used, with mu1 free on both sides of 0, and tests mu1 = 0 against mu1 > 0 (the
physical side) with a one-sided Wald statistic z = mu1 / u(mu1), where u(mu1) holds

- the statistical part: the HAC (Newey-West, prewhitened) covariance of the fit
  (:func:`rollfric.fit.hac.hac_covariance`), as the uncertainty budget's statistical row, never
  below the ordinary one, so residuals correlated from frame to frame do not make a law;
- every uncertain setup input (``K_u``), the air's above all: the drag's Stokes part is
  linear in speed, exactly as mu1 |theta'| g is, so a drag law off by its u makes a mu1. Each
  input moved by u, the fit's shift is its Gauss-Newton step -(J'J)^-1 J' dr (dr the change
  of the residuals at the fitted parameters: the model's for g and the air, the angles' for
  the centre, scale and lens, the times' for the frame rate): the budget's re-fit with the
  input moved, to first order, at the cost of at most one model evaluation an input.

Under Coulomb friction z is a standard normal variable (the one-sided test is the likelihood
ratio test with mu1 >= 0 as its boundary: chi-bar-squared, half chi^2_0, half chi^2_1); its
level is checked by simulation (docs/how/friction-law.md). The smallest mu1 the
recording could have detected is (z_(1-level) + z_power) u(mu1), at the power
:data:`POWER` (0.8).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from scipy import optimize, stats

from rollfric.fit import eom
from rollfric.fit.air import coefficients_of
from rollfric.fit.hac import hac_covariance
from rollfric.fit.lsq import NOISE_FLOOR
from rollfric.uncertainty import quality
from rollfric.uncertainty.asbuilt import TILT, tilted_motion
from rollfric.uncertainty.budget import _contour_centre_as_input
from rollfric.uncertainty.law_outcome import LEVEL, POWER, STATISTIC, LawTest, detectable
from rollfric.uncertainty.reasons import Reason
from rollfric.uncertainty.sensitivity import fitted_mask, moved, setup_inputs, why_not

# the speed law needs the decay's dependence on the amplitude: at least this many turning
# points of the fitted motion (three half-swings) before mu0 and mu1 are told apart
MIN_TURNING_POINTS = 2
# the trough bottom's angle is free in the speed law's fit from this many turning points (as
# rollfric.fit.offset's "auto": with fewer, friction and an offset shift the swing alike)
OFFSET_TURNING_POINTS = 3
# the fit's parameters, their bounds and scales (as rollfric.fit.lsq); mu1 on both sides of 0
_BOUNDS = {"mu": (0.0, 1.0, 1e-3), "theta0": (-math.pi / 2, math.pi / 2, 1e-3),
           "omega0": (-np.inf, np.inf, 1e-2), "offset": (-0.5, 0.5, 1e-3),
           "mu1": (-np.inf, np.inf, 1e-4)}
NFEV = 100
STEPS_PER_RADIAN = 200.0  # the integrator's step, as rollfric.fit.eom.solve


def _turning_points(curve: np.ndarray) -> int:
    d = np.diff(curve)
    d = d[d != 0]
    return int(np.count_nonzero(np.diff(np.sign(d)) != 0))


def friction_law(meas, result, *, level: float = LEVEL) -> LawTest:
    """Test Coulomb + drag against speed + drag on the samples the fit ``result`` used.

    Parameters
    ----------
    meas : rollfric.uncertainty.measured.Measurement
        The measurement ``result`` was fitted to (its setup, the air included).
    result : rollfric.fit.result.FitResult
        Its least-squares fit (model "coulomb" or "velocity"): the start and the samples.
    level : float
        The test's level.

    Returns
    -------
    LawTest
        ``selected`` "speed" when p < ``level``, else "coulomb"; None (with ``why``) for a
        fit other than least squares or a track with fewer than
        :data:`MIN_TURNING_POINTS` turning points.

    Examples
    --------
    The exact motion of a 10 mm ball with mu = 0.008 + 0.0003 |theta'|, in a vacuum:

    >>> import numpy as np, rollfric
    >>> from rollfric.fit.eom import solve_reference
    >>> from rollfric.uncertainty.law import friction_law
    >>> setup = rollfric.thesis_setup("10mm")
    >>> t = np.arange(4000) / 1000.0
    >>> theta, _, _ = solve_reference(np.radians(20.0), 0.0, 0.008, t, mu1=0.0003,
    ...                               track_radius=setup.track_radius)
    >>> theta = theta + np.random.default_rng(1).normal(0.0, 1e-4, t.size)
    >>> fit = rollfric.fit_mu(t, theta, setup)
    >>> law = friction_law(rollfric.Measurement(setup=setup, t=t, theta=theta), fit)
    >>> law.selected, round(law.mu0, 4), round(law.mu1 * 1e4, 1)
    ('speed', 0.008, 3.0)
    """
    start = time.perf_counter()
    if result.method != "lsq":
        return LawTest(None, why=f"the {result.method} fit has no Jacobian (lsq only)")
    # a centre found from the background's contour is an input with its u, as in the budget
    meas, _ = _contour_centre_as_input(meas)
    setup = meas.setup
    t_all, th_all = meas.series(setup)
    used = getattr(result, "used", None)
    mask = used if used is not None and used.shape == t_all.shape else \
        fitted_mask(t_all, th_all, result.n_samples)
    turning = _turning_points(result.curve[mask])
    if turning < MIN_TURNING_POINTS:
        return LawTest(None, why=f"fewer than {MIN_TURNING_POINTS} turning points fitted: "
                                 "too short to tell the laws apart")
    names = [n for n in ("mu", "theta0", "omega0", "offset") if n in result.stderr] \
        or ["mu", "theta0", "omega0"]
    if "offset" not in names and turning >= OFFSET_TURNING_POINTS:
        names.append("offset")  # a nuisance of either law, free where the swings fix it
    names = names + ["mu1", "length"]
    L0 = setup.track_radius
    x0 = {"mu": result.mu, "theta0": result.theta0, "omega0": result.omega0,
          "offset": result.offset, "mu1": result.mu1, "length": L0}
    bounds = dict(_BOUNDS, length=(0.5 * L0, 2.0 * L0, 1e-4))
    lower = np.array([bounds[n][0] for n in names])
    upper = np.array([bounds[n][1] for n in names])
    scale = np.array([bounds[n][2] for n in names])

    def model(x, t, s):
        p = dict(zip(names, x, strict=True))
        off = p.get("offset", 0.0)
        # two-sided: a resistance that falls with speed (mu1 < 0) is within the noise too
        th, _, _ = eom.solve(float(p["theta0"] - off), float(p["omega0"]), float(p["mu"]), t,
                             track_radius=float(p["length"]), gravity=float(s.gravity),
                             mu1=float(p["mu1"]), steps_per_radian=STEPS_PER_RADIAN,
                             air=coefficients_of(s), signed_mu1=True)
        return th + off

    t, y = t_all[mask], th_all[mask]
    sol = optimize.least_squares(lambda x: model(x, t, setup) - y,
                                 np.clip([x0[n] for n in names], lower, upper),
                                 bounds=(lower, upper), x_scale=scale, xtol=1e-10, ftol=1e-10,
                                 gtol=1e-10, max_nfev=NFEV)
    jac, res = sol.jac, sol.fun
    ordinary, hac, _, _ = hac_covariance(jac, res)
    var_stat = np.maximum(np.diag(ordinary), np.diag(hac))
    if not np.all(np.isfinite(var_stat)):
        return LawTest(None, why="the speed law's fit is singular (mu0 and mu1 not apart)")
    i0, i1 = names.index("mu"), names.index("mu1")
    var_inputs, inputs = _inputs_variance(meas, result, model, sol.x, (t, y, mask),
                                          res, jac, i1)
    mu0, mu1 = float(sol.x[i0]), float(sol.x[i1])
    u0 = math.sqrt(var_stat[i0] + var_inputs[i0])
    u1 = math.sqrt(var_stat[i1] + var_inputs[i1])
    z = mu1 / u1 if u1 > 0 else math.nan
    p = float(stats.norm.sf(z)) if math.isfinite(z) else math.nan
    curve = None
    if p < level:  # the speed law's curve, for the residual checks of judged()
        curve = np.full(t_all.shape, np.nan)
        fin = np.isfinite(t_all)
        curve[fin] = model(sol.x, t_all[fin], setup)
    return LawTest("speed" if p < level else "coulomb", p_value=p, z=z, mu0=mu0, mu0_u=u0,
                   mu1=mu1, mu1_u=u1, mu1_u_statistical=math.sqrt(var_stat[i1]),
                   mu1_u_inputs=math.sqrt(var_inputs[i1]),
                   mu1_detectable=detectable(u1, level), level=level,
                   rms_residual=float(np.sqrt(np.mean(res**2))), n_samples=int(res.size),
                   seconds=time.perf_counter() - start, inputs=tuple(inputs), curve=curve)


def _inputs_variance(meas, result, model, x, samples, res, jac, i1):
    """The setup's uncertain inputs through the speed law's fit.

    Parameters
    ----------
    meas : rollfric.uncertainty.measured.Measurement
        The measurement (its setup's ``K_u`` are the inputs).
    result : rollfric.fit.result.FitResult
        The Coulomb fit (the tilt's row remakes its motion).
    model : callable
        ``model(x, t, setup)``: the speed law's angles at the parameters ``x``.
    x : numpy.ndarray
        The speed law's fitted parameters.
    samples : tuple
        ``(t, y, mask)``: the fitted times, their angles and which samples of the series.
    res, jac : numpy.ndarray
        The fit's residuals and Jacobian at ``x``.
    i1 : int
        mu1's index in ``x``.

    Returns
    -------
    var_inputs : numpy.ndarray
        Each parameter's variance from the inputs.
    inputs : list
        ``(source, |shift of mu1|)`` of each input that moves the fit.
    """
    setup = meas.setup
    t, y, mask = samples
    # each uncertain input moved by u: the change of the residuals at the fitted parameters
    # (the model's where the input acts on it, the angles' or times' where on the data; L is
    # fitted, so the track radius acts on neither), and the fit's Gauss-Newton shift
    model_key = (coefficients_of(setup).tobytes(), setup.gravity)
    changes, inputs = [], []
    for source, field, comp, _, u, factor in setup_inputs(setup):
        if u == 0.0 or why_not(meas, field, False):
            continue
        s = moved(setup, field, comp, u, factor)
        tm, thm = meas.series(s)
        tm, thm = tm[mask], thm[mask]
        if np.array_equal(tm, t) and (coefficients_of(s).tobytes(), s.gravity) == model_key:
            r = res + y - thm  # the model as it was, the angles moved
        else:
            r = model(x, tm, s) - thm
        if np.array_equal(r, res):
            continue
        changes.append(r - res)
        inputs.append(source)
    tilt = _tilt_change(setup, result, t)
    if tilt is not None:
        changes.append(tilt)
        inputs.append(TILT)
    var_inputs = np.zeros(len(x))
    if changes:
        dx = -np.linalg.lstsq(jac, np.stack(changes, axis=1), rcond=None)[0]
        var_inputs = np.sum(dx**2, axis=1)
        inputs = [(s, abs(float(d))) for s, d in zip(inputs, dx[i1], strict=True)]
    return var_inputs, inputs


def _tilt_change(setup, result, t):
    """The change of the angles at the fitted times ``t`` that the trough's stated tilt makes
    (:mod:`rollfric.uncertainty.asbuilt`: the Coulomb fit's motion made again in a trough
    tilted by |tilt_deg| + its u, as the budget's row), or None without a stated tilt. The
    axial drift takes a share of the resistance that grows where the swing is slow, which a
    fit reads as a resistance growing with speed: the test must not take it for one."""
    bound = abs(setup.cylinder_tilt) + (setup.u("cylinder_tilt") or 0.0)
    if not bound > 0.0:
        return None
    kw = dict(track_radius=setup.track_radius, gravity=setup.gravity,
              air=coefficients_of(setup))
    args = (result.theta0 - result.offset, result.omega0, result.mu, t)
    tilted, _ = tilted_motion(*args, tilt=bound, **kw)
    level, _ = tilted_motion(*args, tilt=0.0, **kw)
    return level - tilted  # the residual's change: the data moved by the tilt


def law_reason(law: LawTest) -> Reason:
    """The quality reason of a test that rejects Coulomb friction.

    Parameters
    ----------
    law : LawTest
        A test with ``selected`` "speed".

    Returns
    -------
    rollfric.uncertainty.reasons.Reason
        ``friction_law``, with mu0 and mu1.
    """
    return Reason("friction_law", f"the rolling friction depends on speed: mu(theta') = mu0 + "
                  f"mu1 |theta'| with mu0 = {law.mu0:.6f} +- {law.mu0_u:.2g}, mu1 = "
                  f"{law.mu1:.3g} +- {law.mu1_u:.2g} s/rad (Coulomb's mu1 = 0 rejected, p = "
                  f"{law.p_value:.2g} at level {law.level:g}, drag and setup "
                  "uncertainties included): mu is the Coulomb coefficient of a law the data "
                  "reject; --model speed gives mu0 as the result")


# the generic residual reasons a speed law can explain
RESIDUAL_CODES = ("residual_structure", "residual_noise")


def judged(meas, result, law: LawTest, *, model: str = "coulomb"):
    """``result`` with the test's verdict in its quality reasons.

    When the test rejects Coulomb friction and ``model`` is "coulomb", the reason
    ``friction_law`` (:func:`law_reason`) is added, and the generic residual reasons
    (:data:`RESIDUAL_CODES`) the speed law explains (they do not hold for the speed law's
    fit) are taken out. Otherwise ``result`` is returned as it is.

    Parameters
    ----------
    meas : rollfric.uncertainty.measured.Measurement
        The measurement ``result`` was fitted to.
    result : rollfric.fit.result.FitResult
        The fit.
    law : LawTest
        :func:`friction_law` of them.
    model : str
        The model of ``result`` ("coulomb", "speed" or "velocity").

    Returns
    -------
    rollfric.fit.result.FitResult
    """
    if law.selected != "speed" or model != "coulomb":
        return result
    reasons = list(result.quality_reasons)
    if any(r.code in RESIDUAL_CODES for r in reasons):
        t, theta = meas.series(meas.setup)
        good = np.isfinite(t) & np.isfinite(theta)
        used = result.used if result.used is not None else good
        speed = dataclasses.replace(result, curve=law.curve)
        # the checks' own rule (rollfric.uncertainty.quality) on the speed law's residual
        left = {r.code for r in quality._residual_reasons(t, theta, good, used, speed,
                                                          meas.setup, NOISE_FLOOR)}
        reasons = [r for r in reasons if r.code not in RESIDUAL_CODES or r.code in left]
    return dataclasses.replace(result, quality_reasons=tuple(reasons) + (law_reason(law),))


MODELS = ("coulomb", "speed", "velocity")  # the commands' --model; "velocity": "speed"


def fitted_model(model: str) -> str:
    """The least-squares fit's model of a command's ``--model``: "coulomb" or "velocity".

    Parameters
    ----------
    model : str
        One of :data:`MODELS`.

    Returns
    -------
    str
    """
    return "coulomb" if model == "coulomb" else "velocity"


def verdict(meas, result, model: str = "coulomb"):
    """The test as a command makes it: (result judged, fit.json's ``friction_law``), its line
    printed on stdout; with ``model`` "speed" (or "velocity") fit.json's ``model`` says
    "speed".

    Parameters
    ----------
    meas : rollfric.uncertainty.measured.Measurement
        The measurement ``result`` was fitted to.
    result : rollfric.fit.result.FitResult
        The command's fit.
    model : str
        The command's ``--model``.

    Returns
    -------
    result : rollfric.fit.result.FitResult
        With :func:`judged`'s reasons.
    friction_law : dict
        :meth:`LawTest.to_json`.
    """
    law = friction_law(meas, result)
    print(law.line())
    result = judged(meas, result, law, model=fitted_model(model))
    if model != "coulomb" and result.method == "lsq":
        result = dataclasses.replace(result, extra={**result.extra, "model": "speed"})
    return result, law.to_json()


def combined_law(laws, *, level: float = LEVEL) -> dict:
    """The friction law tested on repeated releases together (``rollfric combine``).

    Each release's speed-law fit (fit.json ``friction_law``) gives mu1 with a statistical
    part of its u, independent between releases, and an inputs' part (the drag law, the
    radius, ...), the same error on every release of one setup. mu1 is their mean weighted by
    the statistical parts; its u is the mean's statistical part, scaled by the releases'
    Birge ratio when above 1 (as :mod:`rollfric.uncertainty.combine` does for mu), combined
    with each input's part as a common error (its u(mu1) in each release, weighted: it does not
    average down). The test is the one-sided z = mu1 / u(mu1) of :func:`friction_law`.

    Parameters
    ----------
    laws : sequence of dict
        The releases' ``friction_law`` objects (fit.json); those not tested (``selected``
        null) or without the two parts of u(mu1) are left out.
    level : float
        The test's level.

    Returns
    -------
    dict
        combined.json's ``friction_law``: ``selected`` ("coulomb" or "speed"), ``p_value``,
        ``z``, ``mu1``, ``mu1_u`` with its ``mu1_u_statistical`` and ``mu1_u_inputs``,
        ``mu1_detectable`` (80 % power), ``birge_ratio`` of the releases' mu1, ``n``; or
        ``selected`` null with ``why`` when fewer than two releases were tested.

    Examples
    --------
    Two releases whose mu1 agree within their statistical u; the drag law's part does not
    average down:

    >>> from rollfric.uncertainty.law import combined_law
    >>> run = {"selected": "coulomb", "mu1": 2e-6, "mu1_u_statistical": 3e-6,
    ...        "mu1_u_inputs": 4e-6, "inputs": [{"source": "air drag law", "u_mu1": 4e-6}]}
    >>> c = combined_law([run, dict(run, mu1=1e-6)])
    >>> c["selected"], f"{c['mu1_u_statistical']:.2g}", f"{c['mu1_u_inputs']:.2g}"
    ('coulomb', '2.1e-06', '4e-06')
    """
    def usable(law):
        return (isinstance(law, dict) and law.get("selected") is not None
                and all(isinstance(law.get(k), (int, float)) and math.isfinite(law[k])
                        for k in ("mu1", "mu1_u_statistical", "mu1_u_inputs"))
                and law["mu1_u_statistical"] > 0)

    tested = [law for law in laws if usable(law)]
    if len(tested) < 2:
        return {"selected": None, "n": len(tested), "level": level, "statistic": STATISTIC,
                "why": f"{len(tested)} release(s) with a friction-law test: at least two needed"}
    inv = np.array([law["mu1_u_statistical"] ** -2 for law in tested])
    w = inv / inv.sum()
    mu1s = np.array([law["mu1"] for law in tested])
    mu1 = float(w @ mu1s)
    u_stat = float(inv.sum() ** -0.5)
    n = len(tested)
    birge = math.sqrt(float(np.sum(inv * (mu1s - mu1) ** 2)) / (n - 1))
    # each input a common error: its weighted u(mu1); a release without the per-input list
    # carries its whole inputs' part as one common source
    shared: dict = {}
    for wi, law in zip(w, tested, strict=True):
        rows = [(r.get("source"), r.get("u_mu1")) for r in law.get("inputs") or []
                if isinstance(r, dict) and isinstance(r.get("u_mu1"), (int, float))]
        for source, u in rows or [("inputs", law["mu1_u_inputs"])]:
            shared[source] = shared.get(source, 0.0) + wi * float(u)
    u_inputs = math.sqrt(sum(v * v for v in shared.values()))
    u = math.hypot(max(1.0, birge) * u_stat, u_inputs)
    z = mu1 / u if u > 0 else math.nan
    p = float(stats.norm.sf(z)) if math.isfinite(z) else math.nan
    return {"selected": "speed" if p < level else "coulomb", "p_value": p, "z": z,
            "mu1": mu1, "mu1_u": u, "mu1_u_statistical": max(1.0, birge) * u_stat,
            "mu1_u_inputs": u_inputs, "mu1_detectable": detectable(u), "detectable_power": POWER,
            "birge_ratio": birge, "n": n, "level": level, "statistic": STATISTIC,
            "units": {"mu1": "s/rad"}}
