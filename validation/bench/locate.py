"""Locator benchmark: centre error and speed of every ball locator on frames with known truth,
beside OpenCV HoughCircles, scikit-image CircleModel + RANSAC, a plain edge-point circle fit
(scikit-image ``find_contours`` at the half level + ``CircleModel``), and the Cramer-Rao bound.

Frames are drawn analytically (synth.drawn.frames: exact area coverage, the thesis's
1280 x 1024 geometry with the 85.3 mm trough at 0.1343 mm/px; synth.drawn.shadow: a
backlit ball as a shadowgraph rig records it) and rendered by ``synth``
(the thesis scene with its lamps, specular spots and shadows; clean and with the realistic
sensor model), each with its exact truth.

``bench_locators(quick)`` returns one dict per (case, locator); ``bench_recognition(quick)``
the same as ``validation.bench.run.Row`` lines; ``throughput(...)`` the frames/s of the whole
streaming loop (prediction, ROI, locator) on in-memory 1280 x 1024 frames.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings

import cv2
import numpy as np

import sim
import synth
from rollfric import locate
from rollfric.setup.model import THESIS_BALLS, thesis_setup
from rollfric.track.tracker import track_recording
from synth.drawn.frames import Scene, make_frames
from synth.drawn.mirror import MirrorScene, make_mirror_frames
from synth.drawn.shadow import ShadowScene, background, draw
from validation.bench.table import Row

BALLS = {"10mm": 5.0 / 0.1343, "12.69mm": 6.345 / 0.1343, "1.58mm": 0.79 / 0.1343}


@dataclasses.dataclass
class Case:
    name: str
    r_px: float
    background: np.ndarray
    frames: list
    truth: np.ndarray  # (n, 2) px
    noise: float  # DN rms (for the bound)
    contrast: float  # DN, ball edge step (for the bound)
    center: tuple[float, float]


def drawn_case(ball: str, n: int, *, noise: float = 0.0, shadow: float = 0.0,
               seed: int = 0) -> Case:
    r_px = BALLS[ball]
    scene = Scene(r_px=r_px, noise=noise, shadow=shadow)
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-0.35, 0.35, n)
    truth = np.array([scene.ball_center(t) for t in theta])
    bg, frames = make_frames(scene, [tuple(c) for c in truth], seed=seed)
    contrast = abs(scene.backdrop - scene.ball) * scene.full_scale
    label = f"{ball} drawn" + (f", noise {noise:g} DN" if noise else ", clean") + \
        (", shadow" if shadow else "")
    return Case(label, r_px, bg, frames, truth, noise, contrast, scene.center)


def mirror_case(n: int, *, noise: float = 2.0, seed: int = 0) -> Case:
    """``n`` full frames of the 10 mm ball drawn as a polished steel mirror
    (:mod:`synth.drawn.mirror`: its rim mirrors the backdrop above, the trough below),
    spread over +-0.35 rad of the track, with the sphere's exact centre."""
    scene = MirrorScene(noise=noise)
    rng = np.random.default_rng(seed)
    truth = np.array([scene.ball_center(t) for t in rng.uniform(-0.35, 0.35, n)])
    bg, frames = make_mirror_frames(scene, [tuple(c) for c in truth], seed=seed)
    contrast = scene.backdrop * scene.full_scale / 2  # the upper rim's step, half the lower's
    return Case(f"10mm drawn steel mirror, noise {noise:g} DN", scene.r_px, bg, frames, truth,
                noise, contrast, scene.center)


def shadow_case(n: int, *, noise: float = 8.0, seed: int = 0) -> Case:
    """``n`` drawn shadowgraph frames (:mod:`synth.drawn.shadow`: a backlit ball, a dark
    disc with a bright central spot and a limb shading into its inside, blurred, on a bright
    field; about the real 12-bit clip's, r 63.6 px) at sub-pixel centres spread over a pixel,
    with their exact centres."""
    scene = ShadowScene(noise=noise)
    rng = np.random.default_rng(seed)
    c0 = 0.5 * (scene.width - 1)
    truth = c0 + rng.uniform(-0.5, 0.5, (n, 2))
    frames = [draw(scene, x, y, seed=seed * 1000 + i) for i, (x, y) in enumerate(truth)]
    # the silhouette's step: the backlight against the limb's level at the rim
    contrast = scene.bright - scene.dark - scene.limb
    return Case(f"{scene.r_px:g} px drawn shadowgraph (12 bit), noise {noise:g} DN", scene.r_px,
                background(scene), frames, truth, noise, contrast, (c0, -500.0))


def rendered_case(ball: str, n: int, *, noise: str = "none", lighting: str = "thesis",
                  seed: int = 0) -> Case:
    """``n`` frames of the ball rendered by ``synth`` (thesis camera, ``lighting`` preset,
    sensor preset ``noise``), spread over one swing from 20 deg, with the silhouette truth.

    The bound's contrast and noise are measured on the frames: the step between the clean
    render's levels just outside and just inside the silhouette, and the rms difference of
    the noisy frame from the clean one in the band around the edge."""
    import tempfile

    diameter, mass = THESIS_BALLS[ball]
    # frames 20 ms apart: positions spread over the swing
    sc = sim.Scenario(ball_diameter=diameter, ball_mass=mass, duration=(n - 1) / 50.0,
                      fps=50.0, seed=seed)
    traj = sim.simulate(sc)
    # 2x2 supersampling on top of MSAA: the render itself is then exact to ~0.005 px, below
    # the locator errors being compared (MSAA alone leaves ~0.015 px)
    scene = synth.SceneConfig(lighting=synth.lighting_preset(lighting), supersample=2)
    with tempfile.TemporaryDirectory() as tmp:
        recs = {}
        for preset in {"none", noise}:
            path = synth.render(traj, f"{tmp}/{preset}.zarr", scene=scene,
                                sensor=synth.noise_preset(preset), seed=seed, workers=1)
            rec = synth.open_recording(path)
            recs[preset] = ([rec.frames[i] for i in range(len(rec))], rec.background,
                            rec.truth, rec.attrs)
    frames, background, truth_df, attrs = recs[noise]
    clean = recs["none"][0]
    truth = truth_df[["sil_x_px", "sil_y_px"]].to_numpy()
    r_px = float(truth_df["r_px"].median())
    yy, xx = np.mgrid[0:background.shape[0], 0:background.shape[1]]
    steps, sq = [], []
    for k, (cx, cy) in enumerate(truth):
        d = np.hypot(xx - cx, yy - cy)
        c = clean[k].astype(float)
        steps.append(np.median(c[(d > r_px + 2) & (d < r_px + 5)])
                     - np.median(c[(d > r_px - 5) & (d < r_px - 2)]))
        band = np.abs(d - r_px) < 3
        sq.append(np.mean((frames[k].astype(float) - c)[band] ** 2))
    noise_dn = float(np.sqrt(np.mean(sq)))
    centre = (float(truth_df["cx_px"].iloc[0]), float(truth_df["cy_px"].iloc[0]))
    label = f"{ball} rendered, {lighting} lighting, noise {noise}"
    return Case(label, r_px, background, frames, truth, noise_dn, abs(float(np.median(steps))),
                centre)


def cramer_rao_rms(r_px: float, contrast: float, noise: float, n_theta: int = 200000) -> float:
    """Lower bound on the rms centre error (px, both axes) of an unbiased estimator for a
    uniform disk of radius r_px, edge step ``contrast`` (DN), area-sampled pixels, Gaussian
    pixel noise ``noise`` (DN) plus 8-bit rounding (1/12 DN^2), levels and radius known.

    Fisher information: (C / sigma)^2 sum over pixels of (d coverage / d centre)^2, where
    d coverage / d cx of a pixel is the integral of the outward normal's x component over the
    arc inside that pixel (computed by summing a finely sampled circle per pixel)."""
    var = noise ** 2 + 1.0 / 12.0
    phi = (np.arange(n_theta) + 0.5) * (2 * np.pi / n_theta)
    dl = r_px * 2 * np.pi / n_theta
    x = 0.37 + r_px * np.cos(phi)  # an arbitrary sub-pixel centre
    y = 0.61 + r_px * np.sin(phi)
    px, py = np.rint(x).astype(np.int64), np.rint(y).astype(np.int64)
    key = (px - px.min()) * 100000 + (py - py.min())
    _, inv = np.unique(key, return_inverse=True)
    gx = np.bincount(inv, weights=np.cos(phi) * dl)
    gy = np.bincount(inv, weights=np.sin(phi) * dl)
    ixx = contrast ** 2 / var * np.sum(gx * gx)
    iyy = contrast ** 2 / var * np.sum(gy * gy)
    return math.sqrt(1.0 / ixx + 1.0 / iyy)


# ------------------------------------------------------------------------------ baselines
def _roi(frame, bg, cx, cy, half):
    x0, y0 = max(0, int(cx) - half), max(0, int(cy) - half)
    x1, y1 = min(frame.shape[1], int(cx) + half + 1), min(frame.shape[0], int(cy) + half + 1)
    diff = cv2.absdiff(frame[y0:y1, x0:x1], bg[y0:y1, x0:x1]).astype(np.float32)
    return diff, x0, y0


def hough_locator(frame, bg, r_px, guess):
    """OpenCV HoughCircles (HOUGH_GRADIENT_ALT) on |frame - background| around the guess."""
    half = int(2 * r_px + 10)
    diff, x0, y0 = _roi(frame, bg, guess[0], guess[1], half)
    d8 = cv2.normalize(diff, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    c = cv2.HoughCircles(d8, cv2.HOUGH_GRADIENT_ALT, dp=1.0, minDist=r_px, param1=100,
                         param2=0.5, minRadius=max(1, int(0.8 * r_px)),
                         maxRadius=int(1.2 * r_px) + 2)
    if c is None:
        return locate.Location.missing("no circle")
    x, y, r = c[0][0]
    return locate.Location(x=float(x) + x0, y=float(y) + y0, r=float(r), found=True)


def ransac_locator(frame, bg, r_px, guess, seed=0):
    """scikit-image Canny edges of |frame - background| + CircleModel fitted by RANSAC."""
    from skimage.feature import canny
    from skimage.measure import CircleModel, ransac

    half = int(1.5 * r_px + 8)
    diff, x0, y0 = _roi(frame, bg, guess[0], guess[1], half)
    edges = canny(diff, sigma=1.0 if r_px > 8 else 0.7)
    yy, xx = np.nonzero(edges)
    if len(xx) < 5:
        return locate.Location.missing("no edges")
    pts = np.column_stack([xx, yy]).astype(float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model, inl = ransac(pts, CircleModel, min_samples=3, residual_threshold=0.7,
                            max_trials=200, rng=seed)
    if model is None:
        return locate.Location.missing("ransac failed")
    cx, cy = model.center
    return locate.Location(x=float(cx) + x0, y=float(cy) + y0, r=float(model.radius),
                           found=True)


def edge_point_locator(frame, bg, r_px, guess):
    """The plain edge-point circle fit: scikit-image ``find_contours`` of |frame - background|
    at the half level between the ball's inside (the median over 0.6 r to r - 1.5 px from the
    guess) and its outside (r + 1.5 to r + 4 px), then a least-squares ``CircleModel`` of the
    contour that lies nearest the guessed circle (the longest of those whose median radius is
    within 20 % of ``r_px``: a specular spot's or a bright central spot's contour is not)."""
    from skimage.measure import CircleModel, find_contours

    half = int(1.5 * r_px + 8)
    diff, x0, y0 = _roi(frame, bg, guess[0], guess[1], half)
    yy, xx = np.mgrid[0:diff.shape[0], 0:diff.shape[1]]
    d = np.hypot(xx + x0 - guess[0], yy + y0 - guess[1])
    inside = diff[(d >= 0.6 * r_px) & (d <= r_px - 1.5)]
    outside = diff[(d >= r_px + 1.5) & (d <= r_px + 4.0)]
    if inside.size == 0 or outside.size == 0:
        return locate.Location.missing("ball outside the frame")
    level = 0.5 * (float(np.median(inside)) + float(np.median(outside)))
    best = None
    for c in find_contours(diff, level):
        rr = np.hypot(c[:, 1] + x0 - guess[0], c[:, 0] + y0 - guess[1])
        if len(c) >= 8 and abs(np.median(rr) - r_px) < 0.2 * r_px and (
                best is None or len(c) > len(best)):
            best = c
    if best is None:
        return locate.Location.missing("no contour near the guessed circle")
    model = CircleModel.from_estimate(best[:, ::-1] + [x0, y0])
    if not model:
        return locate.Location.missing("circle fit failed")
    cx, cy = model.center
    return locate.Location(x=float(cx), y=float(cy), r=float(model.radius), found=True)


def _locators(case: Case):
    r = case.r_px
    out = {
        "subpixel (ROI)": lambda f, g: locate.locate_subpixel(f, case.background, r, guess=g),
        "subpixel (full frame)": lambda f, g: locate.locate_subpixel(f, case.background, r),
        "subpixel, MIRROR options (ROI)": lambda f, g: locate.locate_subpixel(
            f, case.background, r, guess=g, opts=locate.MIRROR),
        "thesis large-ball": lambda f, g: locate.locate_large_thesis(
            f, case.background, r, side=1 if g[0] >= case.center[0] else -1, guess=g),
        "thesis small-ball": lambda f, g: locate.locate_small_thesis(
            f, case.background, roi=(int(g[0]) - int(2 * r + 20), int(g[1]) - int(2 * r + 20),
                                     int(g[0]) + int(2 * r + 21), int(g[1]) + int(2 * r + 21))),
        "OpenCV HoughCircles": lambda f, g: hough_locator(f, case.background, r, g),
        "skimage CircleModel+RANSAC": lambda f, g: ransac_locator(f, case.background, r, g),
        "edge points (find_contours + CircleModel)": lambda f, g: edge_point_locator(
            f, case.background, r, g),
    }
    return out


def run_case(case: Case, *, seed: int = 0) -> list[dict]:
    """Every locator on every frame of ``case``; guesses are the truth plus a 1 px error (what
    the tracker's prediction gives)."""
    rng = np.random.default_rng(seed)
    guesses = case.truth + rng.normal(0, 0.7, case.truth.shape)
    bound = cramer_rao_rms(case.r_px, case.contrast, case.noise)
    rows = []
    for name, fn in _locators(case).items():
        fn(case.frames[0], tuple(guesses[0]))  # warm-up (numba compile, imports)
        errs, times = [], []
        for f, g, t in zip(case.frames, guesses, case.truth, strict=True):
            t0 = time.process_time()
            loc = fn(f, tuple(g))
            times.append(time.process_time() - t0)
            errs.append((loc.x - t[0], loc.y - t[1]) if loc.found else (np.nan, np.nan))
        e = np.array(errs)
        ok = np.isfinite(e[:, 0])
        d = np.hypot(e[ok, 0], e[ok, 1])
        rows.append({
            "case": case.name, "locator": name, "frames": len(case.frames),
            "found": float(ok.mean()),
            "rms_px": float(np.sqrt(np.mean(d ** 2))) if ok.any() else math.nan,
            "max_px": float(d.max()) if ok.any() else math.nan,
            "ms_per_frame": 1e3 * float(np.mean(times)),  # CPU time
            "crb_rms_px": bound,
        })
    return rows


def throughput(ball: str = "10mm", n: int = 300, method: str = "subpixel") -> float:
    """Frames per second of the whole streaming loop (prediction, ROI locator, angles) on
    in-memory 1280 x 1024 8-bit frames of a ball swinging on the track (one core)."""
    scene = Scene(r_px=BALLS[ball])
    setup = thesis_setup(ball, center_px=scene.center)
    t = np.arange(n) / setup.fps
    theta = 0.3 * np.cos(2 * np.pi * 0.8 * t)
    truth = [scene.ball_center(a) for a in theta]
    bg, frames = make_frames(scene, truth)

    class Mem:
        shape = (n, scene.height, scene.width)
        dtype = np.dtype(np.uint8)
        name = "memory"

        def __len__(self):
            return n

        def __getitem__(self, i):
            return frames[i]

    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # one core
    try:
        track_recording(Mem(), setup, bg, method=method, progress=False)  # warm-up
        # CPU time of this process: the machine may be shared, wall time would count the others
        t0 = time.process_time()
        df, _ = track_recording(Mem(), setup, bg, method=method, progress=False)
        dt = time.process_time() - t0
    finally:
        cv2.setNumThreads(threads)
    err = np.hypot(df["x_px"] - np.array(truth)[:, 0], df["y_px"] - np.array(truth)[:, 1])
    if not (df["found"].all() and err.max() < 0.5):
        raise RuntimeError(f"throughput run lost the ball (max error {err.max():.3g} px)")
    return n / dt


def bench_locators(quick: bool = False) -> list[dict]:
    n = 8 if quick else 40
    cases = [drawn_case(b, n, seed=i) for i, b in enumerate(BALLS)]
    cases += [drawn_case(b, n, noise=3.0, seed=10 + i) for i, b in enumerate(BALLS)]
    cases += [drawn_case("10mm", n, shadow=0.5, seed=20)]
    cases += [mirror_case(n, seed=25)]
    cases += [shadow_case(n, seed=26)]
    balls = ("10mm",) if quick else tuple(BALLS)
    cases += [rendered_case(b, n, noise=nz, seed=30 + i) for i, b in enumerate(balls)
              for nz in ("none", "realistic")]
    rows = []
    for c in cases:
        rows.extend(run_case(c))
    return rows


def bench_recognition(quick: bool = False) -> list:
    """The recognition section of ``rollfric bench`` as validation.bench.run.Row lines: per case,
    the default locator (ROI mode) beside each baseline (accuracy gain = baseline rms /
    default rms), the Cramer-Rao bound, and the streaming loop's frames/s."""
    rows = []
    results = bench_locators(quick)
    by_case: dict = {}
    for r in results:
        by_case.setdefault(r["case"], {})[r["locator"]] = r
    for case, locs in by_case.items():
        ours = locs["subpixel (ROI)"]
        rows.append(Row("recognition", f"{case}: subpixel centre rms", ours["rms_px"], "px",
                        "Cramer-Rao bound", ours["crb_rms_px"],
                        ours["rms_px"] / ours["crb_rms_px"] if ours["crb_rms_px"] > 0
                        else math.nan,
                        "x the bound", f"max {ours['max_px']:.3g} px, found "
                        f"{100 * ours['found']:.0f} %, {ours['ms_per_frame']:.2f} ms/frame"))
        for name, r in locs.items():
            if name == "subpixel (ROI)":
                continue
            rows.append(Row("recognition", f"{case}: subpixel vs {name}", ours["rms_px"], "px",
                            name, r["rms_px"],
                            r["rms_px"] / ours["rms_px"] if ours["rms_px"] > 0 else math.nan,
                            "accuracy", f"{name}: found {100 * r['found']:.0f} %, max "
                            f"{r['max_px']:.3g} px, {r['ms_per_frame']:.2f} ms/frame"))
    fps = throughput("10mm", 150 if quick else 600)
    rows.append(Row("recognition", "streaming loop, 10 mm ball, 1280x1024 (frames/s)", fps,
                    "frames/s", "target 1000 frames/s", 1000.0, fps / 1000.0, "speed-up",
                    "in-memory frames, one core: prediction + ROI + subpixel locator + angles"))
    return rows


def to_markdown(rows: list[dict]) -> str:
    head = "| case | locator | found | rms (px) | max (px) | ms/frame | Cramer-Rao rms (px) |"
    lines = [head, "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['locator']} | {100 * r['found']:.0f} % | "
                     f"{r['rms_px']:.4f} | {r['max_px']:.4f} | {r['ms_per_frame']:.2f} | "
                     f"{r['crb_rms_px']:.4f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    import sys

    q = "--quick" in sys.argv
    res = bench_locators(q)
    print(to_markdown(res))
    print(f"\nstreaming loop, 10 mm ball, 1280x1024: {throughput('10mm', 150 if q else 600):.0f}"
          " frames/s")
