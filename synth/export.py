"""Export a synthetic recording the way a lab camera export looks.

``DIR/frames.tif`` (multi-page TIFF, one page a frame, 8 or 16 bit), ``DIR/background.png``,
``DIR/setup.toml`` (the lab format, rollfric.setup.save_setup) and ``DIR/truth.csv``
(``frame,t_s,x_px,y_px,theta_rad``; x_px, y_px: the projected sphere centre).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from synth.config import SynthError
from synth.store import open_recording


def export_recording(recording, out_dir, *, progress: bool = False,
                     overwrite: bool = False) -> Path:
    """Write the lab-style export of ``recording`` (a path or a synth.Recording) to out_dir."""
    import cv2
    import tifffile
    from tqdm import tqdm

    from rollfric.setup import save_setup, setup_from_dict

    rec = recording if hasattr(recording, "frames") else open_recording(recording)
    out_dir = Path(out_dir)
    if out_dir.exists() and not overwrite and any(out_dir.iterdir()):
        raise SynthError(f"export directory exists and is not empty: {out_dir}")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    try:
        frames = rec.frames
        n = len(frames)
        nbytes = n * int(np.prod(frames.shape[1:])) * frames.dtype.itemsize
        with tifffile.TiffWriter(tmp / "frames.tif", bigtiff=nbytes > 3.9e9) as tif:
            for i in tqdm(range(n), unit="frame", desc="export", disable=not progress):
                tif.write(frames[i], contiguous=True, photometric="minisblack")
        if not cv2.imwrite(str(tmp / "background.png"), rec.background):
            raise SynthError(f"could not write {tmp / 'background.png'}")
        save_setup(setup_from_dict(rec.attrs["setup"], source="recording attrs"),
                   tmp / "setup.toml")
        truth = rec.truth
        table = truth[["t_s", "x_px", "y_px", "theta_rad"]].copy()
        table.insert(0, "frame", np.arange(n))
        table.to_csv(tmp / "truth.csv", index=False, float_format="%.10g")
        if out_dir.exists():
            shutil.rmtree(out_dir)
        os.replace(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out_dir
