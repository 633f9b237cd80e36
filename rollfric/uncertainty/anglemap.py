"""The budget row of the measurement's own smooth angle error ("method (angle map)").

A locator's error that varies smoothly with the angle (a lamp's shadow or highlight) is what
the budget's noise fit absorbs into its cubic angle map; its 2nd and 3rd order, less the
part the uncertain angle inputs could make and less its noise part, is carried to mu through
the nominal fit's least-squares weights (:func:`method_row`).
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.fit import eom
from rollfric.fit.air import coefficients_of
from rollfric.setup.model import Setup
from rollfric.uncertainty.sensitivity import Refitter

METHOD = "method (angle map)"
METHOD_SIGNIFICANCE = 2.0  # |d| above this many of its noise parts: a smooth angle error
METHOD_NOTE = ("the pipeline's own smooth angle error (the locator's, e.g. a lamp's highlight "
               "or shadow): what the 2nd and 3rd order of the angle map the noise fit absorbs "
               "do to mu, less its noise part; 0 unless above twice that")


def method_row(refit: Refitter, setup: Setup, aug: dict, angle_inputs: list,
               inflation: float) -> tuple[float, str, dict]:
    """The budget row of the measurement's own smooth angle error, a Type A evaluation from
    the record (see the module docstring): the 2nd and 3rd order part of the noise fit's
    angle map (c2 m^2 + c3 m^3 over the model angle m), less what the uncertain inputs that
    act on the angles (``angle_inputs``: their angle changes over +-u) could make (their own
    rows hold that), propagated to mu through the nominal fit's least-squares weights: d. Its
    noise part, the standard deviation s of the same linear functional of white noise of the
    noise fit's rms (times the statistical row's HAC inflation), is removed:
    u = sqrt(d^2 - s^2) when |d| > 2 s (a smooth angle error the record shows), else 0 (d is
    the noise the statistical row holds). Returns (u, the row's note, its details)."""
    t, th = refit.meas.series(setup)
    t, th = t[refit.mask], th[refit.mask]
    m, _, _ = eom.solve(aug["theta0"], aug["omega0"], aug["mu"], t,
                        track_radius=aug.get("length", setup.track_radius),
                        gravity=setup.gravity, mu1=aug.get("mu1", 0.0),
                        air=coefficients_of(setup))
    basis = np.stack([np.ones_like(m), m, m * m, m * m * m], axis=1)
    pinv = np.linalg.pinv(basis)
    high = basis[:, 2:]
    _, jac, _ = refit.fit(setup, jacobian=True)
    names = list(refit.fit(setup)[0])
    w = np.linalg.pinv(jac)[names.index("mu")]  # d mu / d theta_t of the nominal fit
    # the part of the map's 2nd/3rd order the uncertain angle inputs could make is theirs
    eff = [(high @ (pinv @ d)[2:]) for d in angle_inputs]
    eff = [e for e in eff if np.any(e != 0.0)]
    w_eff = w
    if eff:
        a = np.stack(eff, axis=1)
        w_eff = w - a @ (np.linalg.pinv(a) @ w)  # (I - P) w, P the projector onto their span
    v = (w_eff @ high) @ pinv[2:]  # d = v . theta
    d = float(v @ th)
    noise = refit.fit(setup, augmented=True)[2]
    s = float(np.sqrt(np.sum(v * v)) * np.sqrt(np.mean(noise**2))
              * (inflation if inflation > 1.0 else 1.0))
    # an estimate within twice its noise part is noise: the statistical row holds it
    u = math.sqrt(d * d - s * s) if abs(d) > METHOD_SIGNIFICANCE * s else 0.0
    coef = pinv @ th
    details = {"map_c2": float(coef[2]), "map_c3": float(coef[3]), "d_mu": d,
               "d_mu_noise": s, "u_mu": u, "angle_inputs_projected_out": len(eff)}
    note = METHOD_NOTE + f"; d = {d:.2g}, noise part {s:.2g}"
    return u, note, details

