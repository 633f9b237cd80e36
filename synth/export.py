"""Export a synthetic recording the way a lab camera export looks.

``DIR/frames.tif`` (multi-page TIFF, one page a frame, 8 or 16 bit), ``DIR/background.png``,
``DIR/setup.toml`` (the lab format, rollfric.setup.save_setup) and ``DIR/truth.csv``
(``frame,t_s,x_px,y_px,theta_rad``; x_px, y_px: the projected sphere centre).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rollfric.atomic import replacing
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
    with replacing(out_dir) as tmp:
        tmp.mkdir()
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
    return out_dir
