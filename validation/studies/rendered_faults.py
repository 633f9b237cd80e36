"""The verdicts on rendered recordings: ``python -m validation.studies.rendered_faults --out DIR``.

The drawn fault study (:mod:`validation.studies.faults`) on recordings rendered by synth: a
steel ball simulated by sim (the reference engine, no air) and rendered by synth's raster path
with the sensor model, in a small frame around the trough's lower arc (0.25 mm/px, the ball's
whole path and 10 px around it, 1000 Hz). Four clean families of :data:`CASES_PER_FAMILY` cases,
each case's mu and release angle drawn from its seed:

- ``noise``: the sensor presets none, realistic, noisy and dark (the thesis's lighting);
- ``lighting``: the lighting presets thesis, dim, harsh, uneven, flat and backlit;
- ``ball``: the thesis's 1.58 mm and 10 mm balls and a 3 mm one;
- ``mu, angle``: mu from 0.002 to 0.03 and release angles from 0.08 to 0.4 rad.

Each clean case is measured (:func:`validation.studies.faults.run_one`): mu's error in units of
U(mu), the verdict and every reason or finding that came up (on a clean recording: a false
alarm). The first ``fault_bases`` cases of each family are then made faulty in every way of
:data:`SIZES` and :data:`VARIANTS` from the same rendered frames (rendered once): the camera's
bump and drift, the lamps' flicker, timestamps in ms or us, a wrong fps, radius or gravity and
glitches by :mod:`validation.faults.recordings`' functions; a held start and a rest from the
rendered frames themselves (the release frame, or the turning point's, again with fresh sensor
noise). The tables (:func:`validation.studies.faults.fault_summary`, ``clean_summary``) and a
table of each reason by family go to ``DIR/rendered_faults.json``.

The setups are the renderer's (exact geometry and center_px, no ``_u`` keys), the camera
stated square on exactly but where it is turned, as in the drawn study
(:func:`validation.studies.faults.square_on`): U(mu) is the statistical part (the strictest
yardstick), and the path's bound on a turned camera's turn.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import logging
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import sim
import synth
from rollfric.setup.model import THESIS_BALLS, setup_from_dict
from validation.faults.glitches import glitch_frames
from validation.faults.recordings import (
    ArraySource,
    Recording,
    flickered,
    moved,
    stamped,
    wrong_setup,
)
from validation.studies import faults as drawn
from validation.studies.faults import clean_summary, fault_summary, format_tables, run_one

log_ = logging.getLogger(__name__)

PIXEL_SIZE = 0.25e-3  # m/px: the thesis camera's 0.134 mm/px coarsened for small frames
FPS = 1000.0
SECONDS = 1.2  # the record's length
MARGIN_PX = 10  # around the ball's path in the frame
STEEL_KG_M3 = 7850.0

BALLS = {  # name -> (diameter m, mass kg)
    "1.58mm": THESIS_BALLS["1.58mm"],
    "3mm": (3e-3, STEEL_KG_M3 * math.pi / 6 * 3e-3 ** 3),
    "10mm": THESIS_BALLS["10mm"],
}

# family -> what its cases cycle through (the rest: the thesis's lighting, the realistic
# sensor, the 10 mm ball) and the ranges mu and the release angle are drawn from
FAMILIES = {
    "noise": {"noise": ("none", "realistic", "noisy", "dark")},
    "lighting": {"lighting": ("thesis", "dim", "harsh", "uneven", "flat", "backlit")},
    "ball": {"ball": ("1.58mm", "3mm", "10mm")},
    "mu, angle": {"mu": (0.002, 0.03), "theta0": (0.08, 0.4)},
}
MU_RANGE = (0.004, 0.012)
THETA0_RANGE = (0.12, 0.3)  # rad
CASES_PER_FAMILY = 25

# fault -> sizes on the rendered frames: the drawn study's, the held start in frames at
# 1000 Hz (0.1, 0.3 s); the camera's turn (TURNS) is rendered again
SIZES = {**{k: v for k, v in drawn.SIZES.items() if k not in ("yaw", "pitch")},
         "held": (100, 300)}
# the camera turned against the trough's axis (deg): the base rendered again by a camera
# yawed or pitched so (synth.CameraModel), the lab's setup (its center_px) not knowing it
TURNS = {k: drawn.SIZES[k] for k in ("yaw", "pitch")}
# label -> (fault, sizes): the held or resting ball in the measurement's own (median)
# background, no background frame given
VARIANTS = {
    "rest, median background": ("rest", (0.5,)),
    "held, median background": ("held", (300,)),
}


@dataclasses.dataclass(frozen=True)
class Case:
    """One clean rendered recording: its family, seed, motion, ball, lighting, sensor and
    frame."""

    family: str
    seed: int
    mu: float
    theta0: float
    ball: str = "10mm"
    lighting: str = "thesis"
    noise: str = "realistic"
    seconds: float = SECONDS
    margin: int = MARGIN_PX  # px of the frame around the ball's path
    air_density: float = 0.0  # kg/m^3 of the truth's air (the fitter's law, sim's "law")


def draw_case(family: str, i: int, *, seed: int = 0, seconds: float = SECONDS) -> Case:
    """Case ``i`` of ``family`` (:data:`FAMILIES`): the i-th of what the family cycles
    through, mu (log-uniform) and the release angle drawn from (``seed``, family, i).

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    i : int
        The case's number in its family.
    seed : int
        The study's seed.
    seconds : float
        The record's length (s).

    Returns
    -------
    Case
    """
    spec = FAMILIES[family]
    rng = np.random.default_rng([seed, list(FAMILIES).index(family), i])
    lo, hi = spec.get("mu", MU_RANGE)
    mu = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    theta0 = float(rng.uniform(*spec.get("theta0", THETA0_RANGE)))
    kw = {k: v[i % len(v)] for k, v in spec.items() if k in ("ball", "lighting", "noise")}
    return Case(family=family, seed=1000 * seed + i, mu=mu, theta0=theta0, seconds=seconds, **kw)


def frame_geometry(ball_diameter: float, theta0: float, cylinder_radius: float,
                   pixel_size: float = PIXEL_SIZE, margin: int = MARGIN_PX):
    """The frame around the ball's path from ``theta0`` (rad) to ``-theta0``: (width,
    height, center_px), the trough's axis above the frame (y < 0).

    Returns
    -------
    width, height : int
    center_px : tuple of float
    """
    r = ball_diameter / 2 / pixel_size
    L = (cylinder_radius - ball_diameter / 2) / pixel_size  # the centre's path radius, px
    half = L * math.sin(theta0) + r + margin
    width = 2 * math.ceil(half)
    top = L * math.cos(theta0) - r - margin  # the highest ball's top, below the axis
    height = math.ceil(L + r + margin - top)
    return width, height, (width / 2, -top)


@dataclasses.dataclass
class Base:
    """A rendered clean recording, in memory: the frames, background, setup and truth, and
    synth's frames (:meth:`frame_like` draws one frame's picture with another's sensor noise)."""

    case: Case
    frames: list
    background: np.ndarray
    setup: object
    theta: np.ndarray
    centers: np.ndarray
    r_px: float
    synth_frames: object

    def frame_like(self, content: int, noise: int) -> np.ndarray:
        """Frame ``content``'s clean render with the sensor noise of frame number ``noise``
        (the ball still where it was in frame ``content``, a new frame of the camera)."""
        sf = self.synth_frames
        # the sensor's own model (synth.sensor.Sensor.apply): the noise is a function of the
        # frame number alone, so a number past the recording's end gives fresh noise
        return sf._sensor.apply(sf.clean_counts(content), int(sf.frame_scale), int(noise))

    def recording(self, **changes) -> Recording:
        """The clean recording (as :func:`validation.studies.faults.run_one` measures it)."""
        rec = Recording(ArraySource(self.frames), self.setup, self.background, self.case.mu,
                        self.theta, self.centers)
        return dataclasses.replace(rec, **changes)


@contextlib.contextmanager
def rendered(case: Case, *, yaw_deg: float = 0.0, pitch_deg: float = 0.0):
    """Simulate and render ``case``, by a camera yawed or pitched by ``yaw_deg``,
    ``pitch_deg`` against the trough's axis (the setup's center_px is the axis's image all the
    same); yields its :class:`Base` (the store is removed after)."""
    d, m = BALLS[case.ball]
    scenario = sim.Scenario(mu=case.mu, theta0=case.theta0, duration=case.seconds, fps=FPS,
                            ball_diameter=d, ball_mass=m, pixel_size=PIXEL_SIZE,
                            seed=case.seed, air_density=case.air_density,
                            air_drag="law" if case.air_density else "constant")
    traj = sim.simulate(scenario)
    w, h, c = frame_geometry(d, case.theta0, scenario.cylinder_radius, margin=case.margin)
    cam = synth.CameraModel(width=w, height=h, pixel_size=PIXEL_SIZE, center_px=c,
                            yaw=math.radians(yaw_deg), pitch=math.radians(pitch_deg))
    scene = synth.SceneConfig(camera=cam, lighting=synth.lighting_preset(case.lighting))
    with tempfile.TemporaryDirectory(prefix="rollfric-rendered-faults-") as tmp:
        path = synth.render(traj, Path(tmp) / "rec.zarr", scene=scene,
                            sensor=synth.noise_preset(case.noise), seed=case.seed, workers=1)
        rec = synth.open_recording(path)
        n = len(rec.truth)
        frames = [np.asarray(rec.frames[i]) for i in range(n)]
        setup = setup_from_dict(rec.attrs["setup"], source="the renderer's setup")
        yield Base(case, frames, np.asarray(rec.background), setup,
                   rec.truth["theta_rad"].to_numpy(),
                   rec.truth[["x_px", "y_px"]].to_numpy(), d / 2 / PIXEL_SIZE, rec.frames)


def rendered_fault(base: Base, fault: str, magnitude: float, *, seed: int = 0,
                   median_background: bool = False) -> Recording:
    """``base`` made faulty: ``fault`` of :data:`SIZES` of size ``magnitude`` (units there).

    Parameters
    ----------
    base : Base
        The rendered clean recording.
    fault : str
        One of :data:`SIZES`.
    magnitude : float
        Its size.
    seed : int
        Seed of the fault's random parts (flicker phase, glitches).
    median_background : bool
        Give no background frame (the measurement makes its own).

    Returns
    -------
    Recording
        ``truth`` says what the fault is.
    """
    rng = np.random.default_rng(seed + 7919)
    n = len(base.frames)
    frames, setup, stamps, truth = base.frames, base.setup, None, {}
    theta, centers = base.theta, base.centers
    if fault == "held":
        k = int(magnitude)
        if k < 1:
            raise ValueError("a held start holds the ball at least 1 frame")
        # frames 0 .. k - 1 at the release angle (frame 0's picture, each with its own noise)
        frames = [base.frame_like(0, n + j) for j in range(k - 1)] + frames
        theta = np.concatenate([np.full(k - 1, theta[0]), theta])
        centers = np.concatenate([np.repeat(centers[:1], k - 1, axis=0), centers])
        truth = dict(held_frames=k, release_frame=k - 1)
    elif fault == "rest":
        turns = np.flatnonzero(np.diff(np.sign(np.diff(theta))) != 0) + 1
        turns = turns[turns >= 3]
        if not turns.size:
            raise ValueError("the motion has no turning point to rest at")
        k = int(turns[np.argmin(np.abs(turns - magnitude * n))])
        frames = frames[:k + 1] + [base.frame_like(k, j) for j in range(k + 1, n)]
        theta = np.concatenate([theta[:k + 1], np.full(n - k - 1, theta[k])])
        centers = np.concatenate([centers[:k + 1], np.repeat(centers[k:k + 1], n - k - 1, 0)])
        truth = dict(rest_from=k)
    elif fault in ("bump", "drift"):
        frames, shift, truth = moved(frames, fault, magnitude)
        centers = centers + shift
    elif fault == "flicker":
        frames, gain, phase = flickered(frames, magnitude, FPS, rng)
        truth = dict(phase=phase)
    elif fault in ("timestamps_ms", "timestamps_us"):
        unit = fault.split("_")[1]
        stamps = stamped(n, FPS, magnitude, unit)
        truth = dict(unit=unit)
    elif fault in ("fps", "radius", "gravity"):
        setup, truth = wrong_setup(setup, fault, magnitude)
        truth.pop("true_setup")
    elif fault == "glitches":
        out, glitches = glitch_frames(np.stack(frames), seed=seed, rate=magnitude,
                                      centers=centers, r_px=base.r_px)
        frames = list(out)
        truth = dict(glitched=[(g.frame, g.kind) for g in glitches])
    else:
        raise ValueError(f"unknown fault {fault!r} (known: {', '.join(SIZES)})")
    return base.recording(source=ArraySource(frames, timestamps=stamps), setup=setup,
                          background=None if median_background else base.background,
                          theta=theta, centers=centers, fault=fault,
                          magnitude=float(magnitude), truth=truth)


def turned(case: Case, fault: str, degrees: float) -> Recording:
    """``case`` rendered again by a camera turned by ``degrees`` (``fault`` "yaw" or
    "pitch", :data:`TURNS`), with the renderer's setup (the lab's center_px, no turn)."""
    with rendered(case, **{f"{fault}_deg": float(degrees)}) as base:
        rec = base.recording()
        # the frames and truth outlive the render's store (read into memory)
        return dataclasses.replace(rec, fault=fault, magnitude=float(degrees),
                                   truth={f"{fault}_deg": float(degrees)})


def rest_from(theta, tol: float = 1e-9) -> int | None:
    """The frame from which the true angle ``theta`` no longer changes (the ball came to
    rest: tan theta <= mu at a turning point), None if it moves to the end."""
    moving = np.flatnonzero(np.abs(np.diff(np.asarray(theta, dtype=float))) > tol)
    k = 0 if not moving.size else int(moving[-1]) + 1
    return k if k < len(theta) - 2 else None


def reason_table(clean_rows) -> dict:
    """Each reason or finding that came up on a clean recording: family -> count, with the
    total over the families under "all". A ``still:rest`` where the ball really comes to rest
    (the row's ``truth_rest_from``) is a true finding, not counted.

    Parameters
    ----------
    clean_rows : list of dict
        :func:`validation.studies.faults.run_one`'s rows with ``family``.

    Returns
    -------
    dict
        reason -> {family: cases it fired on, "all": their sum}.
    """
    out: dict = {}
    for r in clean_rows:
        for c in set(r["reasons"]) | set(r["findings"]):
            if c == "still:rest" and r.get("truth_rest_from") is not None:
                continue
            d = out.setdefault(c, {})
            d[r["family"]] = d.get(r["family"], 0) + 1
            d["all"] = d.get("all", 0) + 1
    return dict(sorted(out.items()))


def error_table(clean_rows) -> dict:
    """mu's error in units of U(mu) per family (and "all"): n measured, median, the largest
    abs value and how many exceed 1."""
    groups: dict = {}
    for r in clean_rows:
        if r["err_U"] is not None:
            for key in (r["family"], "all"):
                groups.setdefault(key, []).append(r["err_U"])
    return {k: {"n": len(v), "median": float(np.median(v)),
                "max_abs": float(np.max(np.abs(v))),
                "off_by_U": int(np.sum(np.abs(v) > 1.0))} for k, v in groups.items()}


def run_study(*, cases: int = CASES_PER_FAMILY, fault_bases: int = 2, families=None,
              faults=None, seconds: float = SECONDS, seed: int = 0, log=print) -> dict:
    """The study: ``cases`` clean cases per family of ``families`` (default all of
    :data:`FAMILIES`), the first ``fault_bases`` of each made faulty in every way of ``faults``
    (default all of :data:`SIZES` and :data:`VARIANTS`).

    Returns
    -------
    dict
        ``faults`` and ``clean`` (the drawn study's summaries), ``reasons`` (:func:`reason_table`),
        ``errors`` (:func:`error_table`), ``fault_rows``, ``clean_rows``, ``what``.
    """
    fault_rows, clean_rows = [], []
    labels = list(faults or list(SIZES) + list(VARIANTS) + list(TURNS))
    t0 = time.perf_counter()
    for fam in (families or FAMILIES):
        for i in range(cases):
            case = draw_case(fam, i, seed=seed, seconds=seconds)
            t = time.perf_counter()
            with rendered(case) as base:
                t_render = time.perf_counter() - t
                row = run_one(base.recording())
                row.update(family=fam, render_s=round(t_render, 2),
                           truth_rest_from=rest_from(base.theta), **_describe(case))
                clean_rows.append(row)
                log(f"[{fam} {i}] " + _line(row) + f"  ({_what(case)}; render {t_render:.1f} s)")
                if i >= fault_bases:
                    continue
                for label in labels:
                    if label in TURNS:
                        for mag in TURNS[label]:
                            row = run_one(turned(case, label, mag))
                            row.update(fault=label, family=fam, **_describe(case))
                            fault_rows.append(row)
                            log(f"  [{fam} {i}] " + _line(row))
                        continue
                    fault, mags = VARIANTS[label] if label in VARIANTS else (label, SIZES[label])
                    for mag in mags:
                        rec = rendered_fault(base, fault, mag, seed=case.seed,
                                             median_background=label in VARIANTS)
                        row = run_one(rec)
                        row.update(fault=label, family=fam, **_describe(case))
                        fault_rows.append(row)
                        log(f"  [{fam} {i}] " + _line(row))
    return {
        "what": (f"rollfric.measure on recordings rendered by synth (sim's reference engine, no "
                 f"air; {PIXEL_SIZE * 1e3:g} mm/px, a frame around the ball's path and the "
                 f"trough's lower arc, {seconds:g} s at {FPS:g} Hz; mu log-uniform "
                 f"{MU_RANGE[0]:g}..{MU_RANGE[1]:g} and release angle {THETA0_RANGE[0]:g}.."
                 f"{THETA0_RANGE[1]:g} rad unless the family says otherwise; the renderer's "
                 f"setup with its center_px, no _u keys but the camera's, square on exactly, "
                 f"except where it is turned: U(mu) is the statistical part, and the path's "
                 f"bound on a turned camera's turn); faults "
                 f"on the first {fault_bases} cases of each family by "
                 f"validation.faults.recordings' transforms"),
        "families": {k: {kk: list(vv) for kk, vv in v.items()} for k, v in FAMILIES.items()},
        "cases_per_family": cases, "fault_bases": fault_bases, "seed": seed,
        "seconds_total": round(time.perf_counter() - t0, 1),
        "faults": fault_summary(fault_rows), "clean": clean_summary(clean_rows),
        "reasons": reason_table(clean_rows), "errors": error_table(clean_rows),
        "fault_rows": fault_rows, "clean_rows": clean_rows,
    }


def _describe(case: Case) -> dict:
    return {"seed": case.seed, "mu_true": case.mu, "theta0": case.theta0, "ball": case.ball,
            "lighting": case.lighting, "noise": case.noise}


def _what(case: Case) -> str:
    return (f"mu {case.mu:.4f}, {case.theta0:.2f} rad, {case.ball}, {case.lighting}, "
            f"{case.noise}")


def _line(r) -> str:
    err = "refused" if r["err_U"] is None else \
        f"err {100 * r['err_rel']:+.3f} % = {r['err_U']:+.2f} U"
    return (f"{r['fault']:>14} {r['magnitude']:<7g} {r['verdict']:<8} {err:<28} "
            f"named {r['named']!s:<5} {','.join(r['reasons'] + r['findings'])}")


def format_reasons(study) -> str:
    """The clean recordings' table as Markdown: each reason's count by family, and mu's
    error in U by family."""
    fams = [f for f in study["clean"] if f != "all"]
    lines = ["| reason (clean cases it fired on) | " + " | ".join(
        f"{f} (n {study['clean'][f]['n']})" for f in fams) + " | all |",
        "|---|" + "---|" * (len(fams) + 1)]
    for reason, d in study["reasons"].items():
        lines.append(f"| {reason} | " + " | ".join(str(d.get(f, 0)) for f in fams)
                     + f" | {d.get('all', 0)} |")
    if not study["reasons"]:
        lines.append("| none | " + " | ".join("0" for _ in fams) + " | 0 |")
    e = study["errors"]
    lines.append("| mu's err / U: median, max abs, abs > 1 | " + " | ".join(
        (f"{e[f]['median']:+.2f}, {e[f]['max_abs']:.2f}, {e[f]['off_by_U']}" if f in e else "-")
        for f in fams) + " | " + (f"{e['all']['median']:+.2f}, {e['all']['max_abs']:.2f}, "
                                  f"{e['all']['off_by_U']}" if "all" in e else "-") + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    """The command line: run the study, print the tables, write DIR/rendered_faults.json."""
    p = argparse.ArgumentParser(prog="python -m validation.studies.rendered_faults",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="folder of rendered_faults.json")
    p.add_argument("--cases", type=int, default=CASES_PER_FAMILY,
                   help=f"clean cases per family (default {CASES_PER_FAMILY})")
    p.add_argument("--fault-bases", type=int, default=2,
                   help="cases of each family made faulty (default 2)")
    p.add_argument("--families", nargs="*", choices=list(FAMILIES), help="families (all)")
    p.add_argument("--faults", nargs="*", choices=list(SIZES) + list(VARIANTS) + list(TURNS),
                   help="faults (all)")
    p.add_argument("--seconds", type=float, default=SECONDS,
                   help=f"record length in s (default {SECONDS:g})")
    p.add_argument("--seed", type=int, default=0, help="the study's seed (default 0)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing JSON")
    a = p.parse_args(argv)
    if a.cases < 0 or a.fault_bases < 0 or a.seed < 0 or not 0.2 <= a.seconds <= 10:
        p.error("--cases, --fault-bases and --seed must be >= 0, --seconds 0.2..10")
    out = a.out / "rendered_faults.json"
    if out.exists() and not a.overwrite:
        print(f"{out} exists: give --overwrite to replace it", file=sys.stderr)
        return 2
    logging.getLogger("rollfric").setLevel(logging.ERROR)  # the tables say what was found
    study = run_study(cases=a.cases, fault_bases=a.fault_bases, families=a.families,
                      faults=a.faults, seconds=a.seconds, seed=a.seed)
    print(format_tables(study))
    print()
    print(format_reasons(study))
    a.out.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(study, indent=1, default=_plain) + "\n")
    tmp.replace(out)
    return 0


def _plain(v):
    if isinstance(v, np.generic):
        return v.item()
    raise TypeError(f"not JSON: {type(v).__name__}")


if __name__ == "__main__":
    raise SystemExit(main())
