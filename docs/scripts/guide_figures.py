"""Make the figures that open the user guide's and the how-it-works pages (docs/img/guide/).

From the shipped sample recording (and its truth), the equation of motion, and the
systematics study's table (docs/data/systematics.json). A few seconds once the locator's
kernels are compiled.

Usage (from the repository root)::

    PYTHONPATH=$PWD python docs/scripts/guide_figures.py
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
IMG = ROOT / "docs" / "img" / "guide"
DPI = 110


def _sample_track():
    """The sample measured as ``rollfric measure`` does (no fit): the track, the setup, the
    recording and the truth."""
    from rollfric.io.readers import open_recording
    from rollfric.measurement import measure
    from rollfric.sample import sample_path, sample_truth
    from rollfric.setup.model import load_setup

    src = open_recording(sample_path("frames.tif"))
    setup = load_setup(sample_path("setup.toml"))
    df, _, _ = measure(src, setup, None, fit=False)
    return df, setup, src, sample_truth()


def measure_steps(df, setup, src, out):
    """What measure does to a frame: the frame, the background, their difference, the
    located ball."""
    from rollfric.io.background import median, sample

    i = 150
    frame = np.asarray(src[i]).astype(float)
    bg = median(sample(src, 41)[1]).astype(float)
    diff = np.abs(frame - bg)
    x, y = df.loc[i, "x_px"], df.loc[i, "y_px"]
    r = setup.ball_diameter / 2 / setup.pixel_size
    fig, axes = plt.subplots(2, 2, figsize=(9, 3.4), constrained_layout=True)
    panels = [(frame, "1. frame 150", "gray", (0, 255)),
              (bg, "2. background: per-pixel median of 41 frames", "gray", (0, 255)),
              (diff, "3. |frame - background|: the ball stands out", "magma", None),
              (frame, f"4. located centre ({x:.2f}, {y:.2f}) px", "gray", (0, 255))]
    t = np.linspace(0, 2 * np.pi, 200)
    for ax, (img, title, cmap, lim) in zip(axes.flat, panels, strict=True):
        ax.imshow(img, cmap=cmap, vmin=None if lim is None else lim[0],
                  vmax=None if lim is None else lim[1])
        ax.set_title(title, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    axes[1, 1].plot(x + r * np.cos(t), y + r * np.sin(t), "y-", lw=0.8)
    axes[1, 1].plot(x, y, "r+", ms=10)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def mu_effect(setup, out):
    """How mu shows in theta(t): the swing's amplitude falls by the same step each half-swing
    (a constant torque), a step proportional to mu."""
    from rollfric.fit.result import model_theta

    t = np.arange(0.0, 3.0, 1e-3)
    fig, ax = plt.subplots(figsize=(8, 3.6), constrained_layout=True)
    for mu, c in ((0.0, "0.6"), (0.0079, "C0"), (0.02, "C3")):
        th = np.degrees(model_theta(t, mu, np.radians(15.0), 0.0, setup))
        ax.plot(t, th, color=c, lw=1.0, label=f"mu = {mu:g}")
    ax.axhline(0, color="0.8", lw=0.6)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("theta (deg)")
    ax.set_title("released at 15 deg in the sample's trough (R = 85.3 mm, 10 mm ball): "
                 "mu sets how fast the swing dies", fontsize=9)
    ax.legend(fontsize=8, loc="upper right")
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def locator_error(df, truth, out):
    """The located centre minus the true projected centre, every frame of the sample."""
    ang = truth["angles"]
    dx = df["x_px"].to_numpy() - ang["x_px"].to_numpy()
    dy = df["y_px"].to_numpy() - ang["y_px"].to_numpy()
    rms = np.sqrt(np.mean(dx ** 2 + dy ** 2))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.4), constrained_layout=True,
                                 gridspec_kw={"width_ratios": [1, 1.6]})
    a1.plot(dx, dy, ".", ms=3, alpha=0.6)
    lim = 1.1 * max(np.abs(dx).max(), np.abs(dy).max())
    a1.set_xlim(-lim, lim)
    a1.set_ylim(lim, -lim)
    a1.set_aspect("equal")
    a1.axhline(0, color="0.7", lw=0.6)
    a1.axvline(0, color="0.7", lw=0.6)
    a1.set_xlabel("x error (px)")
    a1.set_ylabel("y error (px)")
    a1.set_title(f"400 frames: rms {rms:.3f} px,\nmean ({dx.mean():+.3f}, {dy.mean():+.3f}) px",
                 fontsize=9)
    a2.plot(df["t_s"], dx, ".", ms=2, label="x")
    a2.plot(df["t_s"], dy, ".", ms=2, label="y")
    a2.axhline(0, color="0.7", lw=0.6)
    a2.set_xlabel("t (s)")
    a2.set_ylabel("located - true (px)")
    a2.set_title("the same against time: no drift, no swing-shaped pattern", fontsize=9)
    a2.legend(fontsize=8, markerscale=3)
    fig.suptitle("the sample recording: where the locator puts the ball's centre, against the "
                 "rendered truth", fontsize=10)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def record_length(df, setup, truth, out):
    """mu and its statistical standard error against the length of the record fitted."""
    from rollfric.fit.estimate import fit_mu

    ns = np.arange(100, len(df) + 1, 25)
    mus, errs = [], []
    for n in ns:
        f = fit_mu(df["t_s"].to_numpy()[:n], df["theta_rad"].to_numpy()[:n], setup,
                   checks=False)
        mus.append(f.mu)
        errs.append(f.mu_stderr)
    mus, errs = np.array(mus), np.array(errs)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.4), constrained_layout=True)
    a1.errorbar(ns, mus * 1e3, yerr=errs * 1e3, fmt="o", ms=3, capsize=2,
                label="fit (+- stderr)")
    a1.axhline(truth["mu"] * 1e3, color="C3", lw=0.8, label=f"truth {truth['mu']}")
    a1.set_xlabel("frames fitted (from frame 0, 1000 Hz)")
    a1.set_ylabel("mu x 1000")
    a1.set_title("mu from the first N frames of the sample", fontsize=9)
    a1.legend(fontsize=8)
    a2.loglog(ns, errs / truth["mu"] * 100, "o", ms=3)
    a2.set_xlabel("frames fitted")
    a2.set_ylabel("stderr of mu (% of mu)")
    a2.set_title("the statistical error falls steeply with the length of the record", fontsize=9)
    a2.grid(True, which="both", alpha=0.3)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def _rows(data, source, corrected=None, stages="track"):
    rows = [r for r in data["rows"] if r["source"] == source and r["stages"] == stages
            and r["corrected"] in (corrected, None)]
    rows.sort(key=lambda r: r["magnitude"])
    return (np.array([r["magnitude"] for r in rows]),
            np.array([r["mu_bias_rel"] for r in rows]) * 100, rows[0]["unit"] if rows else "")


def systematics(out):
    """The bias in mu that each error of the apparatus makes (the systematics study), with and
    without the correction rollfric applies where it has one."""
    data = json.loads((ROOT / "docs" / "data" / "systematics.json").read_text())
    panels = [
        ("trough radius as built - nominal", "trough radius error"),
        ("ball diameter as built - nominal", "ball diameter error"),
        ("frame rate as built - nominal", "frame rate error"),
        ("trough centre measured by the lab, x error", "trough centre, x error"),
        ("trough centre measured by the lab, y error", "trough centre, y error"),
        ("camera roll", "camera roll"),
        ("lens k1 at fx = 2400 px", "lens distortion k1"),
        ("air drag, Cd (room air 1.2 kg/m^3)", "air drag coefficient Cd"),
        ("rolling resistance rising with speed, mu_speed", "mu rising with speed"),
    ]
    fig, axes = plt.subplots(3, 3, figsize=(10, 7.5), constrained_layout=True)
    for ax, (source, label) in zip(axes.flat, panels, strict=True):
        m, b, unit = _rows(data, source, corrected=False)
        ax.plot(m, b, "o-", ms=4, color="C3", label="as measured")
        mc, bc, _ = _rows(data, source, corrected=True)
        corrected = [r for r in data["rows"] if r["source"] == source and r["corrected"]]
        if corrected:
            ax.plot(mc, bc, "s-", ms=4, color="C2", label="with rollfric's correction")
            ax.legend(fontsize=7)
        ax.axhline(0, color="0.6", lw=0.6)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel(unit if unit not in ("", "1") else "value")
        ax.set_ylabel("bias in mu (%)")
        ax.grid(alpha=0.3)
    fig.suptitle("what an error of the apparatus does to mu (10 mm ball, mu = 0.0079; "
                 "docs/data/systematics.json)", fontsize=10)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def trough(out):
    """The trough as built: radius, out of round, tilt along the axis."""
    data = json.loads((ROOT / "docs" / "data" / "systematics.json").read_text())
    fig, axes = plt.subplots(1, 3, figsize=(10, 3.2), constrained_layout=True)
    m, b, _ = _rows(data, "trough radius as built - nominal")
    axes[0].plot(m, b, "o-", ms=4)
    axes[0].set_xlabel("radius as built - nominal (mm)")
    axes[0].set_title("a radius off by 1 mm moves mu ~1 %", fontsize=9)
    for source, lab, c in (
            ("trough out of round (D_max - D_min), major axis horizontal", "major axis horizontal",
             "C0"),
            ("trough out of round (D_max - D_min), major axis vertical", "major axis vertical",
             "C3")):
        m, b, _ = _rows(data, source)
        axes[1].plot(np.r_[0.0, m], np.r_[0.0, b], "o-", ms=4, color=c, label=lab)
    axes[1].set_xlabel("out of round, D_max - D_min (mm)")
    axes[1].set_title("out of round: the sign follows the major axis", fontsize=9)
    axes[1].legend(fontsize=7)
    m, b, _ = _rows(data, "trough axis tilted along its length", stages="full")
    axes[2].plot(np.r_[0.0, m], np.r_[0.0, b], "o-", ms=4, color="C2")
    axes[2].set_xlabel("axis tilt along its length (deg)")
    axes[2].set_title("the axis tilted along its length", fontsize=9)
    for ax in axes:
        ax.axhline(0, color="0.6", lw=0.6)
        ax.set_ylabel("bias in mu (%)")
        ax.grid(alpha=0.3)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def engines(out):
    """The engines against the reference: the angle's difference over 4 s and the mu the
    fitter recovers from each, on the exact cylinder (tangent) and on a faceted mesh."""
    import tempfile

    import pandas as pd

    from rollfric.cli.main import main as rollfric
    from rollfric.fit.estimate import fit_mu
    from rollfric.setup.model import thesis_setup

    setup = thesis_setup("10mm")
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.2), sharex=True, constrained_layout=True)
    with tempfile.TemporaryDirectory() as tmp:
        ref = None
        for engine, surface, c, ls in (("reference", "tangent", "k", "-"),
                                       ("mujoco", "tangent", "C0", "-"),
                                       ("pybullet", "tangent", "C1", "-"),
                                       ("mujoco", "mesh", "C0", ":"),
                                       ("pybullet", "mesh", "C1", ":")):
            path = Path(tmp) / f"{engine}_{surface}.csv"
            assert rollfric(["simulate", "--engine", engine, "--surface", surface,
                             "--seconds", "4", "--out", str(path)]) == 0
            df = pd.read_csv(path)
            t, th = df["t_s"].to_numpy(), df["theta_rad"].to_numpy()
            mu = fit_mu(t, th, setup).mu
            label = f"{engine}, {surface}: mu {100 * (mu / 0.0079 - 1):+.2f} %"
            if ref is None:
                ref = th
                a1.plot(t, np.degrees(th), color=c, lw=0.8, label=label)
                continue
            a2.plot(t, np.degrees(th - ref), color=c, ls=ls, lw=1.0, label=label)
    a1.set_ylabel("theta (deg)")
    a1.set_title("4 s from 20 deg, 10 mm ball, mu = 0.0079: the reference (the equation of "
                 "motion)", fontsize=9)
    a1.legend(fontsize=7)
    a2.axhline(0, color="0.6", lw=0.6)
    a2.set_ylabel("engine - reference (deg)")
    a2.set_xlabel("t (s)")
    a2.set_title("the engines' difference, and the mu the fitter recovers from each "
                 "(legend: against the configured 0.0079)", fontsize=9)
    a2.legend(fontsize=7, ncol=2)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def bench_locators(out):
    """The centre error of the default locator and of the alternatives a user might pick, on
    the bench's drawn frames (docs/data/bench.json)."""
    data = json.loads((ROOT / "docs" / "data" / "bench.json").read_text())
    others = ["thesis large-ball", "thesis small-ball", "OpenCV HoughCircles",
              "skimage CircleModel+RANSAC"]
    scenes, table = [], {}
    for r in data["rows"]:
        if r["section"] != "recognition" or ": subpixel vs " not in r["item"]:
            continue
        scene, other = r["item"].split(": subpixel vs ")
        if scene not in scenes:
            scenes.append(scene)
        table[(scene, "subpixel (default)")] = r["value"]
        if other in others:
            table[(scene, other)] = r["baseline_value"]
    methods = ["subpixel (default)"] + others
    fig, ax = plt.subplots(figsize=(9, 8), constrained_layout=True)
    h = 0.8 / len(methods)
    y = np.arange(len(scenes))
    for k, m in enumerate(methods):
        v = np.array([table.get((sc, m)) or np.nan for sc in scenes], dtype=float)
        ax.barh(y + (k - (len(methods) - 1) / 2) * h, v, h, label=m)
    ax.set_xscale("log")
    ax.set_yticks(y, [sc.replace("thesis lighting, ", "") for sc in scenes], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("centre error, rms (px)")
    ax.set_title("each locator's centre error on the bench's frames (drawn or rendered, exact "
                 "centres;\ndocs/data/bench.json; a missing bar: the method found no ball)",
                 fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.4, -0.07), ncol=3)
    ax.grid(axis="x", which="both", alpha=0.3)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def lighting(out):
    """The first frame of the default case rendered under each lighting preset (realistic
    sensor noise), cropped around the ball."""
    import tempfile

    import pandas as pd

    from rollfric.cli.main import main as rollfric
    from rollfric.io.readers import open_recording

    presets = ("thesis", "dim", "harsh", "uneven", "flat")
    fig, axes = plt.subplots(len(presets), 1, figsize=(7, 9.5), constrained_layout=True)
    with tempfile.TemporaryDirectory() as tmp:
        traj = Path(tmp) / "traj.csv"
        assert rollfric(["simulate", "--seconds", "0.002", "--out", str(traj)]) == 0
        for ax, preset in zip(axes, presets, strict=True):
            rec = Path(tmp) / preset
            assert rollfric(["render", str(traj), "--lighting", preset, "--noise", "realistic",
                             "--export", f"{rec}.tif", "--out", str(rec)]) == 0
            frame = np.asarray(open_recording(Path(f"{rec}.tif") / "frames.tif")[0])
            truth = pd.read_csv(Path(f"{rec}.tif") / "truth.csv")
            x, y = int(round(truth.loc[0, "x_px"])), int(round(truth.loc[0, "y_px"]))
            crop = frame[max(y - 70, 0):y + 70, x - 240:x + 100]
            ax.imshow(crop, cmap="gray", vmin=0, vmax=255)
            ax.set_title(f"--lighting {preset}", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle("the default case's first frame (10 mm ball at 20 deg, 0.1343 mm/px), "
                 "the realistic 8-bit sensor", fontsize=9)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def main() -> int:
    t0 = time.perf_counter()
    IMG.mkdir(parents=True, exist_ok=True)
    df, setup, src, truth = _sample_track()
    measure_steps(df, setup, src, IMG / "measure_steps.png")
    mu_effect(setup, IMG / "mu_effect.png")
    locator_error(df, truth, IMG / "locator_error.png")
    record_length(df, setup, truth, IMG / "record_length.png")
    systematics(IMG / "systematics.png")
    trough(IMG / "trough.png")
    engines(IMG / "engines.png")
    bench_locators(IMG / "bench_locators.png")
    lighting(IMG / "lighting.png")
    print(f"wrote 9 figures to {IMG.relative_to(ROOT)} in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
