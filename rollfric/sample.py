"""The sample recording shipped with rollfric: 400 frames (1000 Hz) of the thesis's 10 mm
ball in its 85.3 mm trough, rendered by the validation suite (``validation/make_sample.py``)
and stored as a lossless deflate-compressed TIFF stack with its ``setup.toml``.

:func:`write_sample` copies the two files to a folder (``rollfric sample DIR``);
:func:`sample_truth` gives what the simulation used (mu, the release angle, the angle of every
frame), which the lab's files do not hold.
"""

from __future__ import annotations

import importlib.resources
import json
import shutil
from pathlib import Path

from rollfric.output.folder import check_folder, staged_folder

RECORDING = "frames.tif"
SETUP = "setup.toml"
# what `rollfric sample` writes into its folder (--overwrite replaces only these)
OUTPUTS = {RECORDING: "file", SETUP: "file"}


def sample_path(name: str = "") -> Path:
    """The path of the shipped sample's folder, or of one of its files.

    Parameters
    ----------
    name : str, optional
        ``frames.tif``, ``setup.toml``, ``truth.json`` or ``truth.csv``; empty: the folder.

    Returns
    -------
    pathlib.Path
    """
    root = importlib.resources.files("rollfric") / "data" / "sample"
    return Path(str(root / name if name else root))


def sample_truth() -> dict:
    """The sample's ground truth (what made it; no lab knows it).

    Returns
    -------
    dict
        ``mu`` (the engine's, M = mu r N), ``theta0_rad``, ``seed``, ``frames``, ``crop_px``
        (where the frames were cut from the rendered 1280 x 1024), ``scenario`` (sim's
        scenario in lab units) and ``angles``, a pandas DataFrame with one row a frame:
        ``frame, t_s, theta_rad, x_px, y_px`` (the ball's projected centre in the frames).
    """
    import pandas as pd

    truth = json.loads(sample_path("truth.json").read_text())
    truth["angles"] = pd.read_csv(sample_path("truth.csv"))
    return truth


def write_sample(out, *, overwrite: bool = False) -> Path:
    """Write the sample recording and its setup to the folder ``out``.

    Parameters
    ----------
    out : str or pathlib.Path
        The folder; created when absent. An existing non-empty one is refused unless
        ``overwrite`` (then only ``frames.tif`` and ``setup.toml`` are replaced).
    overwrite : bool
        Whether the user said ``--overwrite``.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    rollfric.output.folder.OutputError
        ``out`` may not be written (exit status 2 from the command).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = write_sample(pathlib.Path(tempfile.mkdtemp()) / "sample")
    >>> sorted(p.name for p in d.iterdir())
    ['frames.tif', 'setup.toml']
    """
    out = check_folder(out, OUTPUTS, overwrite=overwrite, what="folder", command="sample")
    with staged_folder(out, OUTPUTS, overwrite=overwrite, what="folder",
                       command="sample") as tmp:
        for name in OUTPUTS:
            shutil.copyfile(sample_path(name), tmp / name)
    return out
