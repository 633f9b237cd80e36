"""One case end to end through the real pipeline (sim -> synth render -> rollfric measure ->
metrics), the validate CLI and its report, and determinism with a seed."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rollfric.cli.main import main
from validation import case as C
from validation import case_dict as CD
from validation import e2e


def test_validate_small_case_end_to_end(tmp_path, capsys):
    """The cropped camera, 0.3 s of motion, thesis lighting with shadows, realistic noise."""
    d = CD.small_case_dict(seconds=0.3)
    path = tmp_path / "case.toml"
    path.write_text(C.dumps_case(d))
    out = tmp_path / "report"
    assert main(["validate", str(path), "--json", "--out", str(out)]) == 0
    m = json.loads(capsys.readouterr().out)
    for key in ("mu_true", "mu_recovered", "mu_bias_rel", "center_rms_px", "center_max_px",
                "mu_engine", "mu_pipeline_bias_rel", "mu_stderr", "mu_true_within_stderr",
                "center_bias_x_px", "center_bias_y_px", "theta_rms_rad", "found_fraction",
                "t_simulate_s", "t_render_s", "t_measure_s", "t_total_s"):
        assert key in m, key
    assert m["mu_true"] == 0.0079
    assert m["n_frames"] == 301
    assert m["found_fraction"] == 1.0
    # the reference engine is exact: the fitter recovers the configured mu from its theta(t)
    assert abs(m["mu_engine_bias_rel"]) < 1e-4
    # the pipeline: sub-pixel centres of a 37 px ball, mu within 1 % on 0.3 s of motion
    assert m["center_rms_px"] < 0.1 and m["center_max_px"] < 0.5
    assert abs(m["mu_bias_rel"]) < 0.01
    assert m["mu_bias_rel"] == pytest.approx((m["mu_recovered"] - 0.0079) / 0.0079)
    assert m["t_render_s"] > 0 and m["t_total_s"] >= m["t_render_s"] + m["t_measure_s"]
    for name in ("metrics.json", "case.toml", "fit.json", "fit_truth.json", "frames.csv",
                 "angle_vs_model.png", "center_error_hist.png", "center_error_vs_time.png",
                 "overlays.png", "full_frame.png", "report.html"):
        assert (out / name).stat().st_size > 0, name
    # the page stands alone: the verdict first, every figure embedded, nothing from a network
    page = (out / "report.html").read_text()
    assert page.index('class="verdict') < page.index("<pre>") < page.index("<figure>")
    assert page.count("data:image/png;base64,") == 5
    assert "http://" not in page and "https://" not in page and "<script" not in page
    assert json.loads((out / "metrics.json").read_text())["case_id"] == m["case_id"]
    # the report's case file runs the same case
    assert CD.case_id(CD.load_case_dict(out / "case.toml")) == m["case_id"]
    assert not (out / "recording.zarr").exists()


def _tiny(seed: int) -> dict:
    d = CD.small_case_dict(seconds=0.12)
    d["render"].update(shadows=False, seed=seed)
    return d


def _no_timing(m: dict) -> dict:
    return {k: v for k, v in m.items() if not k.startswith("t_") and k != "render_fps"}


def test_same_seed_same_result_other_seed_other_noise(tmp_path):
    a = e2e.run_case(_tiny(3), recording=tmp_path / "a.zarr", render_workers=1)
    b = e2e.run_case(_tiny(3), recording=tmp_path / "b.zarr", render_workers=1)
    c = e2e.run_case(_tiny(4), recording=tmp_path / "c.zarr", render_workers=1)
    ma, mb, mc = _no_timing(a.metrics), _no_timing(b.metrics), _no_timing(c.metrics)
    assert ma == mb
    np.testing.assert_array_equal(a.track["x_px"].to_numpy(), b.track["x_px"].to_numpy())
    from rollfric.io import readers as io

    ra, rb, rc = (io.open_recording(tmp_path / f"{n}.zarr") for n in "abc")
    for i in (0, 60, len(ra) - 1):
        assert ra[i].tobytes() == rb[i].tobytes()
    assert ra[60].tobytes() != rc[60].tobytes()  # another seed, another noise draw
    assert mc["case_id"] != ma["case_id"]
    assert mc["center_rms_px"] != ma["center_rms_px"]
    assert math.isfinite(ma["mu_recovered"])


def test_the_true_angles_fitted_beside_the_render_as_before_it(tmp_path):
    # with render processes the fit of the engine's angles runs on a thread during the render;
    # in one process before it: the same fits and metrics either way
    a = e2e.run_case(_tiny(3), recording=tmp_path / "a.zarr", render_workers=2)
    b = e2e.run_case(_tiny(3), recording=tmp_path / "b.zarr", render_workers=1)
    assert a.metrics["fit_truth_beside_render"] and not b.metrics["fit_truth_beside_render"]
    assert a.fit_truth.mu == b.fit_truth.mu and a.fit_truth.mu_stderr == b.fit_truth.mu_stderr
    ma, mb = (_no_timing(r.metrics) for r in (a, b))
    ma.pop("fit_truth_beside_render"), mb.pop("fit_truth_beside_render")
    assert ma == mb
    assert a.metrics["t_fit_truth_s"] > 0
    # the stages in the order they start, the total last
    assert list(a.timings) == ["simulate", "fit_truth", "render", "measure", "metrics", "total"]


def test_a_failed_fit_beside_the_render_is_raised_and_the_scratch_removed(tmp_path,
                                                                          monkeypatch):
    def fail(case, traj, timings):
        raise ValueError("the true angles cannot be fitted")

    monkeypatch.setattr(e2e, "_fit_truth", fail)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(e2e, "case_scratch", lambda n, folder=None: _made(scratch / "case"))
    with pytest.raises(ValueError, match="cannot be fitted"):
        e2e.run_case(_tiny(3), render_workers=2)
    assert list(scratch.iterdir()) == []


def _made(path):
    path.mkdir()
    return path


def test_a_killed_cases_scratch_folder_is_removed_by_the_next(tmp_path):
    # a case killed by SIGKILL or SIGTERM runs no `finally`: its temporary recording (in RAM in
    # /dev/shm) stays; the next case in that folder removes it, and nothing else
    import os
    import subprocess
    import sys

    code = ("import os, sys; from validation.e2e import case_scratch; "
            "p = case_scratch(10, sys.argv[1]); (p / 'recording.zarr').mkdir(); "
            "print(p); sys.stdout.flush(); os._exit(9)")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True,
                       text=True, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert r.returncode == 9
    dead = tmp_path / r.stdout.strip().rsplit("/", 1)[-1]
    assert dead.is_dir() and dead.name.startswith(".rollfric-case-")
    others = [tmp_path / ".other.part-999999999-1", tmp_path / "rollfric-case-mine"]
    for p in others:
        p.mkdir()
    mine = e2e.case_scratch(10, tmp_path)
    assert mine.is_dir() and not any(mine.iterdir()) and mine.parent == tmp_path
    assert not dead.exists() and all(p.exists() for p in others)
    # a live process's folder (this one's) is kept
    assert e2e.case_scratch(10, tmp_path) != mine and mine.exists()


def test_report_overlays_read_their_crops_alone(tmp_path, monkeypatch):
    # the overlays read each crop's region of the recording (rollfric's FrameSource.read), not
    # the whole frame: the same picture as the whole frames cropped, byte for byte (the crops,
    # 121 px square, cut by the cropped camera's 112 px rows)
    from rollfric.io import readers as io
    from validation import report

    res = e2e.run_case(_tiny(0), report_dir=tmp_path / "r", keep_recording=True,
                       render_workers=1)
    png = (tmp_path / "r" / "overlays.png").read_bytes()
    opened = io.open_recording
    regions = []

    class WholeFrames:  # the reads before: every frame whole, then cropped
        def __init__(self, path):
            self.src = opened(path)
            self.shape = self.src.shape

        def __getitem__(self, i):
            return self.src[i]

        def read(self, i, roi):
            regions.append(roi)
            y0, y1, x0, x1 = roi
            return np.asarray(self.src[i])[y0:y1, x0:x1]

    monkeypatch.setattr(io, "open_recording", WholeFrames)
    report._overlays(res, report.per_frame_errors(res), tmp_path / "o.png", 6)
    assert (tmp_path / "o.png").read_bytes() == png
    assert len(regions) >= 5 and all(y1 - y0 < x1 - x0 for y0, y1, x0, x1 in regions)


def test_the_truth_read_alone_is_synths_without_opening_the_frames(tmp_path, monkeypatch):
    import pandas as pd

    import synth
    import synth.store

    res = e2e.run_case(_tiny(1), recording=tmp_path / "a.zarr", render_workers=1)
    rec = synth.open_recording(tmp_path / "a.zarr")

    def no_frames(group):
        raise AssertionError("the frames were opened")

    monkeypatch.setattr(synth.store, "open_frames", no_frames)
    truth, attrs = synth.store.read_truth(tmp_path / "a.zarr")
    pd.testing.assert_frame_equal(truth, rec.truth, check_exact=True)
    assert truth.index.name == "frame" and attrs == rec.attrs
    # the case's metrics were computed from it
    assert res.metrics["n_frames"] == len(truth)
    pd.testing.assert_frame_equal(res.truth, rec.truth, check_exact=True)
