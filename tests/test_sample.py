"""The sample recording shipped inside rollfric, and ``rollfric sample DIR``: what it writes,
that a lab would know no more than it holds, and that measuring it finds the engine's mu."""

import json
import shlex
import tomllib

import numpy as np
import pytest
import tifffile

from rollfric.cli.main import main
from rollfric.sample import sample_path, sample_truth


def test_the_shipped_sample_is_a_small_lossless_recording_with_a_lab_setup():
    path = sample_path("frames.tif")
    assert path.stat().st_size <= 10e6
    with tifffile.TiffFile(path) as tif:
        assert len(tif.pages) == 400
        page = tif.pages[0]
        assert page.dtype == np.uint8
        assert page.compression == tifffile.COMPRESSION.ADOBE_DEFLATE
        assert page.predictor == tifffile.PREDICTOR.HORIZONTAL
    truth = sample_truth()
    setup = tomllib.loads(sample_path("setup.toml").read_text())
    # the lab's keys only: no mu, no angles, and the trough's centre with its uncertainty
    assert set(setup) == {"cylinder", "ball", "camera", "environment"}
    assert setup["environment"]["air_density_kg_m3"] > 1.0  # rendered in room air, said so
    assert setup["cylinder"]["center_px_u"] == [0.2, 0.2]
    assert truth["mu"] == 0.0079 and truth["frames"] == 400
    angles = truth["angles"]
    assert len(angles) == 400 and angles.frame.tolist() == list(range(400))
    assert angles.theta_rad.iloc[0] == pytest.approx(truth["theta0_rad"], abs=1e-12)
    # the truth's ball centres lie on the ball's circle about the setup's trough centre
    cx, cy = setup["cylinder"]["center_px"]
    L_px = (setup["cylinder"]["radius_mm"] - setup["ball"]["diameter_mm"] / 2) \
        / setup["camera"]["pixel_size_mm"]
    np.testing.assert_allclose(np.hypot(angles.x_px - cx, angles.y_px - cy), L_px, rtol=1e-6)
    crop = truth["crop_px"]
    with tifffile.TiffFile(path) as tif:
        assert tif.pages[0].shape == (crop["height"], crop["width"])


def test_sample_then_measure_finds_the_engines_mu_within_U(tmp_path, capsys):
    d = tmp_path / "sample"
    assert main(["sample", str(d)]) == 0
    assert sorted(p.name for p in d.iterdir()) == ["frames.tif", "setup.toml"]
    out = capsys.readouterr().out
    # it prints the command that measures it: run that command
    cmd = next(line.strip() for line in out.splitlines()
               if line.strip().startswith("rollfric measure "))
    argv = shlex.split(cmd)[1:] + ["--no-progress"]
    assert main(argv) == 0
    fit = json.loads((d / "result" / "fit.json").read_text())
    mu = sample_truth()["mu"]
    assert fit["quality"] == "ok" and fit["n_found"] == 400
    assert abs(fit["mu"] - mu) <= fit["U_mu"]
    assert abs(fit["mu"] - mu) < 0.01 * mu  # the render measures mu to better than 1 %


def test_sample_refuses_a_non_empty_folder_without_overwrite(tmp_path, capsys):
    d = tmp_path / "d"
    d.mkdir()
    (d / "notes.txt").write_text("mine")
    assert main(["sample", str(d)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert sorted(p.name for p in d.iterdir()) == ["notes.txt"]
    (d / "setup.toml").write_text("edited")
    assert main(["sample", str(d), "--overwrite"]) == 0
    assert sorted(p.name for p in d.iterdir()) == ["frames.tif", "notes.txt", "setup.toml"]
    assert (d / "notes.txt").read_text() == "mine"
    assert (d / "setup.toml").read_bytes() == sample_path("setup.toml").read_bytes()
    assert (d / "frames.tif").read_bytes() == sample_path("frames.tif").read_bytes()


@pytest.mark.slow
def test_a_first_measure_announces_the_compilation_and_a_second_does_not(tmp_path):
    # a fresh numba cache folder is a fresh install's: the locator's kernels are compiled
    # (a minute or two) on the first run and loaded on the second
    import os
    import subprocess
    import sys

    d = tmp_path / "s"
    assert main(["sample", str(d)]) == 0
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "PYTHONPATH": os.pathsep.join(sys.path)}
    cmd = [sys.executable, "-m", "rollfric.cli.main", "measure", str(d / "frames.tif"), "--setup",
           str(d / "setup.toml"), "--out", str(d / "r"), "--overwrite"]

    def run():
        return subprocess.run(cmd, env=env, capture_output=True, text=True)

    first = run()
    assert first.returncode == 0, first.stderr
    lines = first.stderr.splitlines()
    said = [i for i, line in enumerate(lines)
            if line.startswith("rollfric measure: compiling the locator's kernels")]
    assert len(said) == 1 and "minutes" in lines[said[0]]
    assert "ball found in 400 of 400 frames" in first.stdout
    second = run()
    assert second.returncode == 0 and "compiling" not in second.stderr
