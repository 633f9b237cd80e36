"""``rollfric track``: the track alone of a recording of any length, written by measure's rules;
and ``rollfric measure`` refusing a recording too short to fit before tracking it."""

import json

import numpy as np
import pandas as pd
import pytest
import tifffile
from measure_data import make_recording

from rollfric import measurement as trackmod
from rollfric.cli.main import main
from rollfric.fit.start import MIN_SAMPLES
from rollfric.setup.model import save_setup


def _write(rec, tmp_path):
    tifffile.imwrite(tmp_path / "rec.tif", np.stack(rec.frames))
    tifffile.imwrite(tmp_path / "bg.tif", rec.background)
    save_setup(rec.setup, tmp_path / "setup.toml")
    return tmp_path / "rec.tif"


def _args(tmp_path, command, out, *more):
    return [command, str(tmp_path / "rec.tif"), "--setup", str(tmp_path / "setup.toml"),
            "--background", str(tmp_path / "bg.tif"), "--out", str(out), "--no-progress", *more]


def test_measure_refuses_a_short_recording_before_tracking_it(tmp_path, capsys, monkeypatch):
    rec = make_recording(15, noise=1.0)
    _write(rec, tmp_path)

    def never(*a, **k):
        raise AssertionError("tracked a recording too short to fit")

    monkeypatch.setattr(trackmod, "track_recording", never)
    monkeypatch.setattr(trackmod, "resolve_background", never)
    code = main(_args(tmp_path, "measure", tmp_path / "out"))
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"has only 15 frames: at least {MIN_SAMPLES} are needed to fit mu" in err
    assert "rollfric track" in err and "rec.tif" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_track_writes_the_track_of_a_short_recording(tmp_path, capsys):
    rec = make_recording(15, noise=1.0)
    _write(rec, tmp_path)
    out = tmp_path / "out"
    assert main(_args(tmp_path, "track", out, "--plot")) == 0, capsys.readouterr().err
    df = pd.read_csv(out / "track.csv")
    assert list(df.columns) == ["frame", "t_s", "x_px", "y_px", "theta_rad", "found", "flag",
                                "still", "x_u_px", "y_u_px"]
    assert len(df) == 15 and df["found"].all()
    err = np.hypot(df["x_px"] - rec.centers[:, 0], df["y_px"] - rec.centers[:, 1])
    assert np.sqrt(np.mean(err ** 2)) < 0.1
    assert np.abs(df["theta_rad"] - rec.theta).max() < 1e-3
    np.testing.assert_allclose(df["t_s"], rec.t, atol=1e-6)
    meta = json.loads((out / "track.json").read_text())
    assert meta["recording"].endswith("rec.tif") and meta["setup"].endswith("setup.toml")
    assert meta["background"].endswith("bg.tif") and meta["locator"] == "subpixel"
    assert meta["n_frames"] == 15 and meta["n_found"] == 15
    assert isinstance(meta["warnings"], list) and "mu" not in meta
    assert sorted(p.name for p in out.iterdir()) == ["overlays.png", "track.csv", "track.json"]
    assert "ball found in 15 of 15 frames" in capsys.readouterr().out


def test_track_follows_the_output_rules_of_measure(tmp_path, capsys):
    rec = make_recording(12, noise=1.0)
    _write(rec, tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "overlays.png").write_bytes(b"old")
    code = main(_args(tmp_path, "track", out))
    assert code == 2 and "--overwrite" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "overlays.png"]
    # --overwrite: its own files written, its old overlays.png (not written now) removed
    assert main(_args(tmp_path, "track", out, "--overwrite")) == 0
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "track.csv", "track.json"]
    assert (out / "notes.txt").read_text() == "mine"
    # an output that is an input is refused
    code = main(_args(tmp_path, "track", tmp_path / "rec.tif"))
    assert code == 2 and "Traceback" not in capsys.readouterr().err
    assert main(_args(tmp_path, "track", tmp_path / "o2", "--median-frames", "2")) == 2
    assert "--median-frames must be at least 3" in capsys.readouterr().err
    assert not (tmp_path / "o2").exists()


@pytest.mark.parametrize("bad", ["missing.cine", "notes.txt"])
def test_track_bad_recording_exit_2_nothing_written(tmp_path, capsys, bad):
    save_setup(make_recording(5).setup, tmp_path / "setup.toml")
    (tmp_path / "notes.txt").write_text("x")
    code = main(["track", str(tmp_path / bad), "--setup", str(tmp_path / "setup.toml"),
                 "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and bad in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_track_reports_frames_without_the_ball_without_a_fit(tmp_path, capsys):
    rec = make_recording(12, noise=1.0, missing=(4,))
    _write(rec, tmp_path)
    assert main(_args(tmp_path, "track", tmp_path / "out")) == 0
    err = capsys.readouterr().err
    assert "ball not found in 1 of 12 frames" in err and "left out of the fit" not in err
    df = pd.read_csv(tmp_path / "out" / "track.csv")
    assert df["found"].tolist() == [1] * 4 + [0] + [1] * 7
