"""Make the tutorial's figures and printed outputs (docs/tutorial.md) by running its commands.

Runs, in a scratch folder, the commands the page shows -- ``rollfric sample``, ``measure
--plot``, ``validate``, a two-case ``sweep``, ``info`` and ``track`` on a real Photron clip --
and writes what they print to ``docs/snippets/tutorial/*.txt`` (included by the page) and the
figures to ``docs/img/tutorial/*.png``. With ``--check`` it writes nothing and compares what the
commands print now with the committed snippets (timings aside; numbers of rendered runs within a
tolerance, as a renderer on another GPU or driver may differ in the last digits): exit 1 on a
difference, naming it.

Usage (from the repository root)::

    PYTHONPATH=$PWD PYOPENGL_PLATFORM=egl python docs/scripts/tutorial.py [--check]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SNIPPETS = ROOT / "docs" / "snippets" / "tutorial"
IMG = ROOT / "docs" / "img" / "tutorial"
REAL = ROOT / "tests" / "data" / "real"

SWEEP_TOML = """\
[sweep]
name = "lighting"
description = "mu and the centre error under two lightings"
mode = "grid"
seeds = 1
metrics = ["mu_bias_rel", "center_rms_px"]

[base]
scenario.motion = { seconds = 0.5 }

[grid]
"render.lighting" = ["thesis", "harsh"]
"""

# the setup of pyMRAW's backlit ball clip (tests/test_ballfree.py): a 12.72 mm ball seen at
# 0.1 mm/px falling down the left side of a 0.5 m trough
REAL_SETUP = """\
[cylinder]
radius_mm = 500.0
center_px = [5111.6, 128.0]

[ball]
diameter_mm = 12.72
mass_g = 4.0

[camera]
fps = 30000.0
pixel_size_mm = 0.1
"""

# snippet -> relative tolerance of its numbers in --check (rendered runs: the renderer's last
# digits may differ between GPUs and drivers; the sample and the real clip are files)
TOLERANCE = {"validate": 0.05, "sweep": 0.05, "sweep_summary": 0.05}

# lines that differ from run to run or only on a first run: not shown
_DROP = re.compile(r"compiling the locator's kernels|budget: \d+ re-fits|^\s*time\s")
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
_TIMING = re.compile(r"[-+]?\d+(?:\.\d+)? s\b")


def _rollfric(args, cwd, expect=(0,)):
    """Run ``rollfric ARGS`` in ``cwd``; return what it printed (stderr, then stdout)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYOPENGL_PLATFORM="egl", COLUMNS="100")
    cmd = [sys.executable, "-c", "import sys; from rollfric.cli.main import main; sys.exit(main())"]
    p = subprocess.run(cmd + list(args), cwd=cwd, env=env, capture_output=True, text=True)
    if p.returncode not in expect:
        raise SystemExit(f"rollfric {' '.join(args)} exited {p.returncode}:\n{p.stderr}")
    text = "\n".join(s for s in (p.stderr.strip(), p.stdout.strip()) if s)
    text = text.replace(f"{Path(cwd).resolve()}/", "").replace(f"{cwd}/", "")
    lines = [ln for ln in text.splitlines() if not _DROP.search(ln)]
    return f"$ rollfric {' '.join(args)}\n" + "\n".join(lines) + "\n"


def _frames_figure(work, out):
    """Three frames of the sample with the located centre and the path the ball's centre
    takes (a circle of radius R - r about the trough's centre, from the setup)."""
    import matplotlib.pyplot as plt
    import numpy as np
    import pandas as pd

    from rollfric.io.readers import open_recording
    from rollfric.setup.model import load_setup

    src = open_recording(work / "sample" / "frames.tif")
    setup = load_setup(work / "sample" / "setup.toml")
    track = pd.read_csv(work / "sample" / "result" / "track.csv")
    cx, cy = setup.center_px
    rpath = (setup.cylinder_radius - setup.ball_diameter / 2) / setup.pixel_size
    rball = setup.ball_diameter / 2 / setup.pixel_size
    a = np.linspace(np.pi / 2 - 0.4, np.pi / 2 + 0.4, 400)
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 6.2), constrained_layout=True)
    for ax, i in zip(axes, (0, 150, 300), strict=True):
        img = np.asarray(src[i])
        ax.imshow(img, cmap="gray", vmin=0, vmax=255)
        ax.plot(cx + rpath * np.cos(a), cy + rpath * np.sin(a), "c--", lw=0.8,
                label="path of the ball's centre (setup)")
        x, y = track.loc[i, "x_px"], track.loc[i, "y_px"]
        t = np.linspace(0, 2 * np.pi, 100)
        ax.plot(x + rball * np.cos(t), y + rball * np.sin(t), "y-", lw=0.8)
        ax.plot(x, y, "r+", ms=9, label="located centre")
        ax.set_xlim(-0.5, img.shape[1] - 0.5)
        ax.set_ylim(img.shape[0] - 0.5, -0.5)
        ax.set_title(f"frame {i} (t = {track.loc[i, 't_s']:.3f} s): theta = "
                     f"{np.degrees(track.loc[i, 'theta_rad']):+.2f} deg", fontsize=9)
        ax.set_ylabel("y (px)")
    axes[-1].set_xlabel("x (px)")
    axes[0].legend(loc="lower left", fontsize=7)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def _theta_figure(work, out):
    """theta(t) from track.csv, and its difference from the sample's truth."""
    import matplotlib.pyplot as plt
    import numpy as np
    import pandas as pd

    from rollfric.sample import sample_truth

    track = pd.read_csv(work / "sample" / "result" / "track.csv")
    truth = sample_truth()["angles"]
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.5, 5.0), sharex=True,
                                 gridspec_kw={"height_ratios": [2, 1]}, constrained_layout=True)
    a1.plot(track["t_s"], np.degrees(track["theta_rad"]), ".", ms=2, label="track.csv")
    a1.axhline(0, color="0.6", lw=0.6)
    a1.set_ylabel("theta (deg)")
    a1.set_title("the ball's angle about the trough's centre, one point a frame", fontsize=10)
    a1.legend(fontsize=8)
    err = np.degrees(track["theta_rad"].to_numpy() - truth["theta_rad"].to_numpy()) * 1e3
    a2.plot(track["t_s"], err, ".", ms=2, color="C3")
    a2.axhline(0, color="0.6", lw=0.6)
    a2.set_ylabel("measured - true\n(millidegrees)")
    a2.set_xlabel("t (s)")
    a2.set_title(f"error against the sample's truth: rms {np.sqrt(np.mean(err ** 2)):.1f} "
                 "millidegrees", fontsize=10)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def run(work: Path) -> tuple[dict, dict]:
    """Run the tutorial's commands in ``work``; return {snippet: text}, {figure: path}."""
    snip, figs = {}, {}
    snip["sample"] = _rollfric(["sample", "sample"], work)
    snip["measure"] = _rollfric(["measure", "sample/frames.tif", "--setup", "sample/setup.toml",
                                 "--out", "sample/result", "--plot", "--no-progress"], work)
    snip["track_head"] = "$ head -4 sample/result/track.csv\n" + "".join(
        (work / "sample/result/track.csv").read_text().splitlines(keepends=True)[:4])
    figs["frames.png"] = work / "frames.png"
    _frames_figure(work, figs["frames.png"])
    figs["theta.png"] = work / "theta.png"
    _theta_figure(work, figs["theta.png"])
    figs["fit.png"] = work / "sample/result/fit.png"
    figs["budget.png"] = work / "sample/result/budget.png"
    snip["validate"] = _rollfric(["validate", "--seconds", "0.5", "--out", "val",
                                  "--no-progress"], work)
    figs["validate_full_frame.png"] = work / "val/full_frame.png"
    figs["validate_angle.png"] = work / "val/angle_vs_model.png"
    (work / "lighting.toml").write_text(SWEEP_TOML)
    snip["sweep"] = _rollfric(["sweep", "lighting.toml", "--out", "sweep", "--workers", "1",
                               "--no-progress"], work, expect=(0, 1))
    summary = (work / "sweep/summary.md").read_text()
    snip["sweep_summary"] = summary.split("## plots")[0].strip() + "\n"
    figs["sweep_lighting.png"] = work / "sweep/plots/render_lighting.png"
    real = work / "real"
    real.mkdir()
    for name in ("ball_12bit.cihx", "ball_12bit.mraw"):
        shutil.copy(REAL / name, real / name)
    (work / "real_setup.toml").write_text(REAL_SETUP)
    snip["real_info"] = _rollfric(["info", "real/ball_12bit.cihx"], work)
    snip["real_track"] = _rollfric(["track", "real/ball_12bit.cihx", "--setup",
                                    "real_setup.toml", "--background-from", "clip", "--out",
                                    "realtrack", "--plot", "--no-progress"], work)
    figs["real_overlays.png"] = work / "realtrack/overlays.png"
    # the two files the page shows are written from the same text
    snip["lighting.toml"] = SWEEP_TOML
    snip["real_setup.toml"] = REAL_SETUP
    return snip, figs


def _filename(name):
    return name if "." in name else f"{name}.txt"


def _mask_timings(text):
    return _TIMING.sub("<t> s", text)


def differs(name: str, new: str, old: str) -> str | None:
    """Why ``new`` differs from the committed ``old`` (None when they agree): the text apart
    from its numbers must match, the numbers within the snippet's tolerance."""
    new, old = _mask_timings(new), _mask_timings(old)
    if _NUMBER.sub("#", new) != _NUMBER.sub("#", old):
        for a, b in zip(new.splitlines(), old.splitlines(), strict=False):
            if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
                return f"now: {a!r}\n  committed: {b!r}"
        return "a different number of lines"
    rtol = TOLERANCE.get(name, 1e-9)
    for a, b in zip(_NUMBER.findall(new), _NUMBER.findall(old), strict=True):
        x, y = float(a), float(b)
        if abs(x - y) > rtol * max(abs(x), abs(y)) + (1e-12 if rtol < 1e-6 else 1e-6):
            return f"the number {b} is now {a}"
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="compare with the committed snippets; write nothing")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="rollfric-tutorial-") as tmp:
        snip, figs = run(Path(tmp))
        if args.check:
            bad = []
            for name, text in snip.items():
                path = SNIPPETS / _filename(name)
                if not path.exists():
                    bad.append(f"{path}: missing")
                elif (why := differs(name, text, path.read_text())) is not None:
                    bad.append(f"{path.relative_to(ROOT)}: {why}")
            for name in figs:
                if not (IMG / name).exists():
                    bad.append(f"{IMG / name}: missing")
            print("\n".join(bad) if bad else "the tutorial's outputs match the committed ones")
            return 1 if bad else 0
        SNIPPETS.mkdir(parents=True, exist_ok=True)
        IMG.mkdir(parents=True, exist_ok=True)
        for name, text in snip.items():
            (SNIPPETS / _filename(name)).write_text(text)
        for name, src in figs.items():
            shutil.copy(src, IMG / name)
    print(f"wrote {len(snip)} snippets and {len(figs)} figures in "
          f"{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
