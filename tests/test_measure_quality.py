"""rollfric measure: a measurement that cannot be right is written as suspect (exit 3), a
background that is a recording is refused (exit 2)."""

import dataclasses
import json

import numpy as np
import tifffile
from measure_data import make_recording

from rollfric.cli import main
from rollfric.setup import save_setup


def _measure(tmp_path, rec, setup, background="bg.tif"):
    tifffile.imwrite(tmp_path / "rec.tif", np.stack(rec.frames))
    tifffile.imwrite(tmp_path / "bg.tif", rec.background)
    save_setup(setup, tmp_path / "setup.toml")
    out = tmp_path / "out"
    code = main(["measure", str(tmp_path / "rec.tif"), "--setup", str(tmp_path / "setup.toml"),
                 "--background", str(tmp_path / background), "--out", str(out),
                 "--no-progress"])
    return code, out


def test_center_20px_off_is_suspect(tmp_path, capsys):
    rec = make_recording(160, noise=1.0, with_center=True)
    xc, yc = rec.scene.center
    code, out = _measure(tmp_path, rec, dataclasses.replace(rec.setup, center_px=(xc + 20, yc)))
    assert code == 3
    fit = json.loads((out / "fit.json").read_text())
    reasons = {r["code"]: r["message"] for r in fit["quality_reasons"]}
    assert fit["quality"] == "suspect" and "center" in reasons
    # the message gives the centre the ball's path says (the true one, within a pixel)
    x_said = float(reasons["center"].split("about (")[1].split(",")[0])
    assert abs(x_said - xc) < 1.0
    assert "[center]" in capsys.readouterr().err
    assert (out / "track.csv").exists()


def test_center_right_is_ok(tmp_path):
    rec = make_recording(160, noise=1.0, with_center=True)
    code, out = _measure(tmp_path, rec, rec.setup)
    assert code == 0
    assert json.loads((out / "fit.json").read_text())["quality"] == "ok"


def test_center_too_high_is_suspect(tmp_path):
    rec = make_recording(160, noise=1.0, with_center=True)
    xc, yc = rec.scene.center
    code, out = _measure(tmp_path, rec, dataclasses.replace(rec.setup, center_px=(xc, yc - 20)))
    assert code == 3
    fit = json.loads((out / "fit.json").read_text())
    assert "track_radius" in {r["code"] for r in fit["quality_reasons"]}


def test_a_recording_as_background_is_refused(tmp_path, capsys):
    rec = make_recording(80, noise=1.0, with_center=True)
    tifffile.imwrite(tmp_path / "stack.tif", np.stack(rec.frames[:5]))
    code, out = _measure(tmp_path, rec, rec.setup, background="stack.tif")
    assert code == 2 and not out.exists()
    assert "5 pages" in capsys.readouterr().err
