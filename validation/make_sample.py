"""Make the sample recording that ships inside rollfric (``rollfric/data/sample/``).

The thesis's 10 mm ball in its 85.3 mm trough (sim's default scenario, the reference engine),
in room air (the drag law the fitter models), released at rest at 15 degrees, rendered by
synth with the thesis's room lighting and the realistic sensor noise, then cropped to the band
of the frame the ball crosses so that 400 frames fit in a few MB as a lossless (deflate +
horizontal predictor) TIFF stack::

    PYOPENGL_PLATFORM=egl python -m validation.make_sample [--seed 0] [--out rollfric/data/sample]

Same seed and same library versions, same bytes. It writes

- ``frames.tif``: the recording (8 bit, 1000 Hz);
- ``setup.toml``: what a lab knows (trough radius, ball, camera, the trough's centre in the
  cropped frame as measured on a full-frame background, with its uncertainty); no truth;
- ``truth.json``: the engine's mu and scenario, the crop and the seed;
- ``truth.csv``: per frame ``frame,t_s,theta_rad,x_px,y_px`` (the projected ball centre in the
  cropped frame).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import tomllib
from pathlib import Path

import numpy as np

import sim
import synth
from rollfric.setup.model import save_setup, setup_from_dict
from validation.case_dict import ROOM_AIR_DENSITY

DEFAULT_OUT = Path(__file__).resolve().parent.parent / "rollfric" / "data" / "sample"
FRAMES = 400
THETA0_DEG = 15.0  # released at rest: a 392 x 112 px band, 400 frames in ~9 MB
MARGIN_PX = 8  # around the ball's outline over the whole path
CENTER_PX_U = 0.2  # px: a lab's centre found from the full-frame contour


def make_sample(out=DEFAULT_OUT, *, seed: int = 0, frames: int = FRAMES,
                workers: int = 1) -> Path:
    """Render and write the sample recording (see the module docstring).

    Parameters
    ----------
    out : path-like
        Folder written (created; its four files replaced).
    seed : int
        Seed of the sensor noise.
    frames : int
        Number of frames (at 1000 Hz).
    workers : int
        Render processes.

    Returns
    -------
    pathlib.Path
        ``out``.
    """
    import tifffile

    out = Path(out)

    scenario = sim.Scenario(theta0=math.radians(THETA0_DEG), duration=frames / 1000.0, seed=seed,
                            air_density=ROOM_AIR_DENSITY, air_drag="law")
    traj = sim.simulate(scenario)
    with tempfile.TemporaryDirectory(prefix="rollfric-sample-") as tmp:
        path = synth.render(traj, Path(tmp) / "rec.zarr", scene=synth.SceneConfig(),
                            sensor=synth.noise_preset("realistic"), seed=seed,
                            workers=workers, frames=frames)
        rec = synth.open_recording(path)
        truth = rec.truth
        r_px = scenario.ball_diameter / 2 / scenario.pixel_size
        h, w = rec.frames.shape[1:]
        x0 = max(0, math.floor(truth["x_px"].min() - r_px - MARGIN_PX))
        x1 = min(w, math.ceil(truth["x_px"].max() + r_px + MARGIN_PX) + 1)
        y0 = max(0, math.floor(truth["y_px"].min() - r_px - MARGIN_PX))
        y1 = min(h, math.ceil(truth["y_px"].max() + r_px + MARGIN_PX) + 1)
        stack = np.stack([np.asarray(rec.frames[i])[y0:y1, x0:x1] for i in range(frames)])
        setup = dict(rec.attrs["setup"])
        out.mkdir(parents=True, exist_ok=True)
        # deflate with a horizontal predictor: lossless, read by tifffile through imagecodecs
        tifffile.imwrite(out / "frames.tif", stack, photometric="minisblack",
                         compression="zlib", compressionargs={"level": 9}, predictor=True,
                         metadata=None, software=False)
    cx, cy = setup["cylinder"]["center_px"]
    setup["cylinder"] = {**setup["cylinder"], "center_px": [cx - x0, cy - y0],
                         "center_px_u": [CENTER_PX_U, CENTER_PX_U]}
    save_setup(setup_from_dict(setup, source="sample"), out / "setup.toml")
    table = truth[["t_s", "theta_rad"]].copy()
    table.insert(0, "frame", np.arange(len(table)))
    table["x_px"] = truth["x_px"] - x0
    table["y_px"] = truth["y_px"] - y0
    table.to_csv(out / "truth.csv", index=False, float_format="%.10g")
    meta = {"mu": scenario.mu, "theta0_rad": scenario.theta0, "seed": seed, "frames": frames,
            "engine": scenario.engine, "lighting": "thesis", "noise": "realistic",
            "crop_px": {"x0": x0, "y0": y0, "width": x1 - x0, "height": y1 - y0},
            "scenario": tomllib.loads(sim.dumps_scenario(scenario))}
    (out / "truth.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.make_sample",
                                description="Make rollfric's sample recording.")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="folder (default: the package's)")
    p.add_argument("--seed", type=int, default=0, help="sensor noise seed (default 0)")
    p.add_argument("--frames", type=int, default=FRAMES, help="frames at 1000 Hz")
    args = p.parse_args(argv)
    out = make_sample(args.out, seed=args.seed, frames=args.frames)
    size = sum(f.stat().st_size for f in out.iterdir())
    print(f"wrote {out} ({size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
