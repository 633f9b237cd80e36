"""The camera's measured motion as a budget row: how far its correction can be trusted.

A bumped or drifting camera is corrected from the static scene
(:mod:`rollfric.track.camera_motion`): the frames are moved back by shifts measured on a dozen
sampled frames. Each sample is off by what the ball hides of the scene there (a few hundredths
of a pixel on a large frame, up to a tenth or two on a small one); the correction carries that
error into every centre, and a drift's slope into the decay of the swing, so into mu. The
samples' scatter about the motion fitted to them measures it:

- a drift: the line through the samples (:func:`rollfric.track.camera_motion.drift_scatter`);
  its offset and slope have the standard errors of a straight-line fit of their scatter
  about it;
- a bump: the two levels either side of the step; the step's size has the standard error of
  the difference of their means.

Each of those patterns (x and y apart) moves the located centres by one standard uncertainty
and mu is fitted again; the row's u(mu) is the root sum of squares of the changes.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rollfric.track.camera_motion import drift_scatter
from rollfric.uncertainty.measured import Measurement
from rollfric.uncertainty.sensitivity import Refitter

SOURCE = "camera motion (its correction)"


def patterns(motion: dict, frames: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """The correction's error patterns at ``frames``: (what, (T, 2) px) each one standard
    uncertainty, for a bump or drift of ``motion`` (fit.json's ``camera_motion``); none for a
    still camera or one whose samples do not say (fewer than two on a side of a bump, or
    three on a drift).

    Parameters
    ----------
    motion : dict
        ``kind``, ``frame``, ``frames``, ``shifts_px``.
    frames : numpy.ndarray
        The frame numbers of the centres.

    Returns
    -------
    list of (str, numpy.ndarray)
    """
    kind = (motion or {}).get("kind")
    if kind not in ("bump", "drift"):
        return []
    f = np.asarray(motion["frames"], dtype=float)
    s = np.asarray(motion["shifts_px"], dtype=float).reshape(-1, 2)
    frames = np.asarray(frames, dtype=float)
    out = []
    if kind == "drift":
        if len(f) < 3:
            return []
        sigmas, sxx = drift_scatter(f, s)  # about the line the correction used
        for k, axis in enumerate("xy"):
            sigma = float(sigmas[k])
            for what, p in (("offset", np.full(frames.shape, sigma / math.sqrt(len(f)))),
                            ("slope", sigma / math.sqrt(sxx) * (frames - f.mean()))):
                out.append((f"{axis} {what}", _axis(p, k)))
        return out
    before, after = s[f < motion["frame"]], s[f >= motion["frame"]]
    if len(before) < 2 or len(after) < 2:
        return []
    for k, axis in enumerate("xy"):
        dev = np.concatenate([before[:, k] - before[:, k].mean(),
                              after[:, k] - after[:, k].mean()])
        sigma = math.sqrt(float(np.sum(dev ** 2)) / (len(dev) - 2))
        u_step = sigma * math.sqrt(1.0 / len(before) + 1.0 / len(after))
        out.append((f"{axis} level", _axis(np.full(frames.shape, sigma / math.sqrt(len(before))),
                                           k)))
        out.append((f"{axis} step", _axis(np.where(frames >= motion["frame"], u_step, 0.0),
                                          k)))
    return out


def _axis(p, k):
    out = np.zeros((len(p), 2))
    out[:, k] = p
    return out


def motion_row(meas: Measurement, result, setup, mu: float, *,
               fit_length: bool = False) -> tuple[tuple | None, int]:
    """The budget row of a corrected camera motion (the module's docstring), or None.

    Parameters
    ----------
    meas : Measurement
        The measurement (its ``camera_motion``; centres located).
    result : FitResult
        Its least-squares fit.
    setup : Setup
        The setup the budget uses.
    mu : float
        The nominal re-fit's mu.
    fit_length : bool
        L is fitted.

    Returns
    -------
    row : tuple or None
        (source, value, u px, None, u_mu, note) as the budget's Row.
    n_refits : int
    """
    if not meas.from_centres or meas.camera_motion is None:
        return None, 0
    frames = meas.frames if meas.frames is not None else np.arange(len(meas.x), dtype=float)
    # a pattern that moves nothing (an axis the samples agree on to the bit) needs no re-fit
    pats = [(w, p) for w, p in patterns(meas.camera_motion, frames) if np.any(p)]
    if not pats:
        return None, 0
    changes, n = [], 0
    for what, p in pats:
        moved = dataclasses.replace(meas, x=meas.x + p[:, 0], y=meas.y + p[:, 1],
                                    camera_motion=None)
        refit = Refitter(moved, result, fit_length=fit_length)
        changes.append((what, refit.mu(setup) - mu))
        n += refit.count
    u_mu = math.sqrt(sum(d * d for _, d in changes))
    u_px = max(float(np.max(np.abs(p))) for _, p in pats)
    kind = meas.camera_motion["kind"]
    worst = max(changes, key=lambda c: abs(c[1]))
    note = (f"the {kind} measured on {len(meas.camera_motion['frames'])} frames, corrected; "
            f"its samples' scatter moves the centres by up to {u_px:.3g} px (1 u), the "
            f"{worst[0]} the most ({100 * worst[1] / mu:+.3g} % of mu)")
    return (SOURCE, None, u_px, None, u_mu, note), n
