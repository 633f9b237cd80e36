"""Export a synthetic recording the way a lab camera export looks.

``DIR/frames.tif`` (multi-page TIFF, one page a frame, 8 or 16 bit, lossless: deflate with a
horizontal predictor, :data:`COMPRESSION`; a 10-14 bit sensor's full scale in the pages'
``MaxSampleValue`` tag), ``DIR/background.png``,
``DIR/setup.toml`` (the lab format, rollfric.setup.model.save_setup) and ``DIR/truth.csv``
(``frame,t_s,x_px,y_px,theta_rad``; x_px, y_px: the projected sphere centre).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rollfric.output.folder import OutputError, check_folder, staged_folder
from rollfric.setup.model import save_setup, setup_from_dict
from synth.config import SynthError
from synth.store import open_recording

# what an export writes into its folder (--overwrite replaces only these; other files stay)
OUTPUTS = {"frames.tif": "file", "background.png": "file", "setup.toml": "file",
           "truth.csv": "file"}

# the frames' TIFF codec: deflate (zlib level 1, fast) on horizontal differences, lossless and
# read by tifffile + imagecodecs, libtiff, OpenCV and ImageJ; a noisy 8-bit frame shrinks to
# about half, a clean one to a few percent
COMPRESSION = {"compression": "zlib", "compressionargs": {"level": 1}, "predictor": True}


def check_export(out_dir, *, overwrite: bool = False) -> Path:
    """SynthError unless the export may be written to ``out_dir`` (absent, empty, or with
    ``overwrite``: a folder whose export files may be replaced); checked before any work."""
    try:
        return check_folder(out_dir, OUTPUTS, overwrite=overwrite, what="export directory",
                            command="render --export")
    except OutputError as exc:
        raise SynthError(str(exc)) from None


def export_recording(recording, out_dir, *, progress: bool = False,
                     overwrite: bool = False) -> Path:
    """Write the lab-style export of ``recording`` (a path or a synth.Recording) to out_dir.

    An existing non-empty ``out_dir`` is refused unless ``overwrite``; then only the export's
    own files (:data:`OUTPUTS`) are replaced and other files are left alone."""
    import cv2
    import tifffile
    from tqdm import tqdm

    out_dir = check_export(out_dir, overwrite=overwrite)
    rec = recording if hasattr(recording, "frames") else open_recording(recording)
    with staged_folder(out_dir, OUTPUTS, overwrite=overwrite, what="export directory",
                       command="render --export") as tmp:
        frames = rec.frames
        n = len(frames)
        nbytes = n * int(np.prod(frames.shape[1:])) * frames.dtype.itemsize
        # a sensor of 10-14 bits in 16-bit words: its full scale in the TIFF's MaxSampleValue
        # tag (281), as a camera's export states it
        bits = int(rec.attrs.get("sensor", {}).get("bit_depth", 16))
        tags = [(281, "H", 1, 2 ** bits - 1, False)] if (
            frames.dtype == np.uint16 and bits < 16) else []
        pages = (frames[i] for i in tqdm(range(n), unit="frame", desc="export",
                                         disable=not progress))
        with tifffile.TiffWriter(tmp / "frames.tif", bigtiff=nbytes > 3.9e9) as tif:
            # one series of n pages (tifffile.imread gives the stack), written a frame at a time
            tif.write(pages, shape=(n, *frames.shape[1:]), dtype=frames.dtype,
                      photometric="minisblack", extratags=tags, **COMPRESSION)
        if not cv2.imwrite(str(tmp / "background.png"), rec.background):
            raise SynthError(f"could not write {tmp / 'background.png'}")
        save_setup(setup_from_dict(rec.attrs["setup"], source="recording attrs"),
                   tmp / "setup.toml")
        truth = rec.truth
        table = truth[["t_s", "x_px", "y_px", "theta_rad"]].copy()
        table.insert(0, "frame", np.arange(n))
        table.to_csv(tmp / "truth.csv", index=False, float_format="%.10g")
    return out_dir
