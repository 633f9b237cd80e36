"""README's picture: the default validate case as a lab would see it.

Left, a frame of the rendered recording with what the measurement found: the trough's axis,
the circle the ball's centre runs on, the located path and the ball; right, the measured
angle against the fitted equation of motion and what is left over. Run from the repository
root (about a minute on two cores):

    PYOPENGL_PLATFORM=egl python docs/scripts/readme_figure.py   # writes docs/img/readme.png
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle

OUT = Path(__file__).resolve().parents[1] / "img" / "readme.png"


def main(out: Path = OUT) -> Path:
    from rollfric import open_recording
    from validation.case_dict import default_case_dict
    from validation.e2e import run_case

    with tempfile.TemporaryDirectory() as tmp:
        res = run_case(default_case_dict(), recording=Path(tmp) / "rec.zarr")
        src = open_recording(res.recording)
        tr, info, fit, m = res.track, res.track_info, res.fit, res.metrics
        theta = tr["theta_rad"].to_numpy(float)
        found = tr["found"].to_numpy() == 1
        k = int(np.nanargmax(np.where(found, np.abs(theta), -np.inf)))
        frame = np.asarray(src[k])

    fig = Figure(figsize=(13, 4.6))
    a, b = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.25, 1]})
    h, w = frame.shape
    a.imshow(frame, cmap="gray", extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    cx, cy = info.center_px
    L, r = info.track_radius_px, info.ball_radius_px
    phi = np.linspace(-1.2, 1.2, 200)
    a.plot(cx + L * np.sin(phi), cy + L * np.cos(phi), "--", color="tab:orange", lw=1,
           label="the circle the centre runs on")
    a.plot(cx, cy, "+", color="tab:orange", ms=12, mew=2, label="trough axis (from the contour)")
    a.plot(tr["x_px"][found], tr["y_px"][found], "-", color="tab:cyan", lw=1,
           label="located path")
    x, y = tr["x_px"].iloc[k], tr["y_px"].iloc[k]
    a.add_patch(Circle((x, y), r, fill=False, color="tab:red", lw=1.5))
    a.plot([cx, x], [cy, y], "-", color="tab:red", lw=0.8,
           label=f"theta = {np.degrees(theta[k]):+.1f} deg")
    a.set_xlim(cx - 1.05 * L, cx + 1.05 * L)
    a.set_ylim(min(h - 0.5, cy + L + 2.5 * r), cy - 0.15 * L)
    a.set_axis_off()
    a.legend(loc="upper left", fontsize=8, framealpha=0.85)
    a.set_title(f"{int(found.sum())} of {len(tr)} frames located to "
                f"{m['center_rms_px']:.3f} px rms", fontsize=10)
    t = tr["t_s"].to_numpy(float)
    b.plot(fit.t, np.degrees(fit.curve), "-", lw=3, color="tab:blue", alpha=0.4,
           label="equation of motion")
    b.plot(t, np.degrees(theta), ".", ms=1.2, color="k", label="measured")
    b.set_xlabel("t (s)")
    b.set_ylabel("theta (deg)")
    b.grid(alpha=0.3)
    b.legend(loc="upper right", fontsize=8)
    b.set_title(f"mu = {m['mu_recovered']:.6f} +- {m['U_mu']:.1g} (k = 2); "
                f"true {m['mu_true']:.4f}", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    return out


if __name__ == "__main__":
    print(main(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT))
