"""Sweeps on a two-worker local Dask cluster: parallel cases, a worker killed mid-sweep,
resume, failures recorded, and a tiny sweep through the real pipeline (render in a worker)."""

from __future__ import annotations

import functools
import logging
import os
import sys
import time
from pathlib import Path

import cloudpickle
import pandas as pd
import pytest

from validation import e2e
from validation import sweep as S
from validation import sweep_plots as P
from validation import sweep_run as R
from validation import sweep_table as T

# the case functions below are defined here: ship them to the workers by value
cloudpickle.register_pickle_by_value(sys.modules[__name__])


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


def _mu_spec(mus, name="t", **head):
    return S.sweep_from_dict({"sweep": {"name": name, "stages": "sim",
                                        "metrics": ["mu_engine_bias_rel"], **head},
                              "base": {"scenario": {"motion": {"seconds": 1.0}}},
                              "grid": {"scenario.motion.mu": list(mus)}})


def _counting_case(calls: str, case_dict: dict) -> dict:
    """sim-only case that leaves one file per call (to count who ran what)."""
    m = e2e.sim_only_case(case_dict)
    Path(calls, f"{m['case_id']}.{os.getpid()}.{time.monotonic_ns()}").touch()
    time.sleep(0.3)  # long enough for both workers to take cases
    return m


def _dying_case(marker_dir: str, die_for: float, case_dict: dict) -> dict:
    """Kills its worker process the first time it meets mu == die_for, then succeeds."""
    marker = Path(marker_dir, "died")
    if case_dict["scenario"]["motion"]["mu"] == die_for and not marker.exists():
        marker.touch()
        os._exit(1)  # the worker process dies mid-case
    return e2e.sim_only_case(case_dict)


def _failing_case(bad: float, case_dict: dict) -> dict:
    if case_dict["scenario"]["motion"]["mu"] == bad:
        raise ValueError(f"no good: mu {bad}")
    return e2e.sim_only_case(case_dict)


def test_two_worker_sweep_table_and_plots(client, tmp_path):
    calls = tmp_path / "calls"
    calls.mkdir()
    spec = _mu_spec([0.004, 0.006, 0.008, 0.010, 0.012, 0.014])
    summary = R.run_sweep(spec, tmp_path / "out", client=client, progress=False,
                          case_fn=functools.partial(_counting_case, str(calls)))
    assert summary.n_run == 6 and summary.n_failed == 0
    df = pd.read_parquet(tmp_path / "out" / "results.parquet")
    csv = pd.read_csv(tmp_path / "out" / "results.csv")
    assert len(df) == len(csv) == 6
    assert list(df["case_id"]) == [c.case_id for c in spec.cases]
    assert (df["status"] == "ok").all()
    # one row per case: the swept parameter and the metrics as columns
    assert sorted(df["scenario.motion.mu"]) == [0.004, 0.006, 0.008, 0.010, 0.012, 0.014]
    assert (df["mu_engine"] - df["mu_true"]).abs().max() < 1e-6  # reference engine: exact
    assert df["worker"].nunique() == 2  # both workers ran cases
    assert len(list(calls.iterdir())) == 6
    assert len(list((tmp_path / "out" / "parts").glob("*.parquet"))) == 6
    assert (tmp_path / "out" / "plots" / "scenario_motion_mu.png").stat().st_size > 1000


def test_worker_killed_mid_sweep_loses_nothing(client, tmp_path):
    mus = [0.005, 0.007, 0.009, 0.011]
    spec = _mu_spec(mus, name="kill")
    markers = tmp_path / "m"
    markers.mkdir()
    summary = R.run_sweep(spec, tmp_path / "out", client=client, progress=False,
                          case_fn=functools.partial(_dying_case, str(markers), 0.007))
    assert (markers / "died").exists()  # a worker really died
    df = T.read_parts(tmp_path / "out")
    assert summary.n_failed == 0
    assert sorted(df["case_id"]) == sorted(c.case_id for c in spec.cases)
    assert (df["status"] == "ok").all()
    # the cluster has replaced the dead worker
    client.wait_for_workers(2, timeout=60)


def test_failed_case_recorded_and_sweep_goes_on(client, tmp_path):
    spec = _mu_spec([0.005, 0.007, 0.009], name="fail")
    out = tmp_path / "out"
    summary = R.run_sweep(spec, out, client=client, progress=False,
                          case_fn=functools.partial(_failing_case, 0.007))
    assert summary.n_failed == 1
    df = pd.read_parquet(out / "results.parquet").set_index("scenario.motion.mu")
    assert df.loc[0.007, "status"] == "failed"
    assert "ValueError: no good: mu 0.007" in df.loc[0.007, "error"]
    assert (df.drop(index=0.007)["status"] == "ok").all()
    assert pd.isna(df.loc[0.007, "mu_engine"]) and df.loc[0.005, "mu_engine"] > 0
    # resume does not re-run the failed case unless asked
    again = R.run_sweep(spec, out, client=client, progress=False,
                        case_fn=functools.partial(_failing_case, 0.007))
    assert again.n_run == 0
    retry = R.run_sweep(spec, out, client=client, progress=False, retry_failed=True,
                        case_fn=functools.partial(_failing_case, 0.0))
    assert retry.n_run == 1 and retry.n_failed == 0


def test_resume_runs_only_the_missing_cases(client, tmp_path):
    calls = tmp_path / "calls"
    calls.mkdir()
    fn = functools.partial(_counting_case, str(calls))
    spec = _mu_spec([0.005, 0.006, 0.007, 0.008], name="resume")
    out = tmp_path / "out"
    R.run_sweep(spec, out, client=client, progress=False, case_fn=fn)
    first = pd.read_parquet(out / "results.parquet")
    # an interrupted sweep: two cases never finished, the combined table never written
    lost = [spec.cases[1].case_id, spec.cases[3].case_id]
    for cid in lost:
        (out / "parts" / f"{cid}.parquet").unlink()
    (out / "results.parquet").unlink()
    (out / "results.csv").unlink()
    before = {p.name for p in calls.iterdir()}
    summary = R.run_sweep(spec, out, client=client, progress=False, case_fn=fn)
    assert summary.n_done_before == 2 and summary.n_run == 2
    new = {p.name for p in calls.iterdir()} - before
    assert sorted(n.split(".")[0] for n in new) == sorted(lost)
    second = pd.read_parquet(out / "results.parquet")
    cols = ["case_id", "status", "scenario.motion.mu", "mu_engine", "mu_engine_bias_rel"]
    pd.testing.assert_frame_equal(first[cols], second[cols])


def test_real_pipeline_sweep_keeps_recordings(client, tmp_path):
    """Two tiny cases through sim -> synth -> rollfric on the workers (one renderer each)."""
    from validation.case_dict import small_case_dict

    base = small_case_dict(seconds=0.2)
    base["render"]["shadows"] = False
    spec = S.sweep_from_dict({"sweep": {"name": "real", "metrics": ["center_rms_px"]},
                              "base": base,
                              "grid": {"measure.locator": ["subpixel", "thesis-large"]}})
    out = tmp_path / "out"
    summary = R.run_sweep(spec, out, client=client, progress=False, keep_recordings=True)
    df = pd.read_parquet(out / "results.parquet")
    assert summary.n_failed == 0, df["error"].tolist()
    assert (df["found_fraction"] == 1.0).all()
    by = df.set_index("measure.locator")
    assert by.loc["subpixel", "center_rms_px"] < 0.1
    idx = pd.read_csv(out / "recordings" / "index.csv")
    assert sorted(idx["case_id"]) == sorted(df["case_id"])
    from rollfric.io import readers as io

    for rel in idx["recording"]:
        src = io.open_recording(out / rel)
        assert len(src) == 201
    # the thesis's integer-pixel locator is much coarser than the sub-pixel one
    assert by.loc["thesis-large", "center_rms_px"] > 3 * by.loc["subpixel", "center_rms_px"]


def test_table_holds_this_sweeps_cases_only(tmp_path):
    """Parts of other case ids (an edited sweep file, changed defaults) stay out of the table."""
    spec = _mu_spec([0.005, 0.006], name="own")
    for sc in spec.cases:
        T.write_part(tmp_path / "parts", T.part_row(sc, {"status": "ok", "error": "",
                                                     "metrics": {"mu_engine": 1.0}}))
    T.write_part(tmp_path / "parts", {"case_id": "0123456789ab", "status": "ok", "error": "",
                                      "stale_metric": 5.0})
    df = T.rebuild_table(tmp_path, spec)
    assert list(df["case_id"]) == [c.case_id for c in spec.cases]
    assert "stale_metric" not in df.columns
    assert len(T.read_parts(tmp_path)) == 3  # nothing deleted


def test_list_sweep_with_a_failing_case_still_writes_table_plots_and_summary(client, tmp_path):
    """A list sweep whose cases set different keys, one case failing: the table, a plot per
    key and summary.md are written, on the first run and on every rerun."""
    spec = S.sweep_from_dict({
        "sweep": {"name": "lst", "mode": "list", "stages": "sim",
                  "metrics": ["mu_engine_bias_rel"]},
        "base": {"scenario": {"motion": {"seconds": 0.5}}},
        "cases": [{"scenario.motion.mu": 0.005}, {"scenario.motion.mu": 0.0},
                  {"scenario.motion.mu": 0.006}, {"scenario.motion.theta0_deg": 10.0},
                  {"scenario.motion.theta0_deg": 12.0}]})
    out = tmp_path / "out"
    for run in range(2):
        summary = R.run_sweep(spec, out, client=client, progress=False,
                              case_fn=functools.partial(_failing_case, 0.0))
        assert summary.n_run == (5 if run == 0 else 0) and summary.n_failed == 1
        df = pd.read_csv(out / "results.csv")
        assert len(df) == 5 and (df["status"] == "failed").sum() == 1
        assert sorted(p.name for p in (out / "plots").iterdir()) == [
            "scenario_motion_mu.png", "scenario_motion_theta0_deg.png"]
        text = (out / "summary.md").read_text()
        assert "## failed" in text and "no good: mu 0.0" in text and "## notes" not in text
        page = (out / "report.html").read_text()
        assert "4 of 5 case(s) ran, 1 failed" in page and page.count("data:image/png") == 2


def test_overwrite_starts_a_sweep_afresh(client, tmp_path):
    spec = _mu_spec([0.005, 0.006], name="fresh")
    out = tmp_path / "out"
    R.run_sweep(spec, out, client=client, progress=False)
    (out / "notes.txt").write_text("mine")
    again = R.run_sweep(spec, out, client=client, progress=False)
    assert again.n_run == 0  # resumed: nothing to do
    fresh = R.run_sweep(spec, out, client=client, progress=False, overwrite=True)
    assert fresh.n_run == 2 and fresh.n_done_before == 0
    assert (out / "notes.txt").read_text() == "mine"
    with pytest.raises(S.SweepError, match="holds the results of sweep 'fresh'"):
        R.run_sweep(_mu_spec([0.005], name="other"), out, client=client, progress=False)


def test_recordings_measured_again_blind_and_oracle(client, tmp_path):
    """A sweep's kept recordings measured again without rendering (``--from-recordings``):
    blind, the same code gives the same metrics as the run that rendered them; oracle, the
    same recordings with the setup from the recording (the as-built draws stay the
    recording's); the recorded folder is left as it was."""
    from validation.case_dict import small_case_dict

    base = small_case_dict(seconds=0.2)
    base["render"]["shadows"] = False
    base["lab"] = {"draw": True, "seed": "case", "center_px_u": [2.0, 2.0],
                   "cylinder": {"radius_mm": 85.3, "radius_mm_u": 0.5}}
    base["measure"] = {"budget": True}
    spec = S.sweep_from_dict({"sweep": {"name": "rec", "metrics": ["z_budget"]}, "base": base,
                              "grid": {"scenario.motion.mu": [0.005, 0.0079]}})
    src = tmp_path / "src"
    R.run_sweep(spec, src, client=client, progress=False, keep_recordings=True)
    first = pd.read_parquet(src / "results.parquet")
    assert (first["status"] == "ok").all(), first["error"].tolist()
    before = sorted((p.relative_to(src), p.stat().st_mtime_ns) for p in src.rglob("*"))

    blind = T.recorded_sweep(src)
    assert sorted(c.case_id for c in blind.cases) == sorted(first["case_id"])
    R.run_sweep(blind, tmp_path / "blind", client=client, progress=False)
    again = pd.read_parquet(tmp_path / "blind" / "results.parquet")
    assert (again["status"] == "ok").all(), again["error"].tolist()
    cols = ["case_id", "scenario.motion.mu", "mu_recovered", "u_mu", "z_budget",
            "trough_center_err_x_px", "lab_err_cylinder_radius_mm"]
    pd.testing.assert_frame_equal(first[cols], again[cols])
    assert "t_render_s" not in again.columns  # nothing rendered

    oracle = T.recorded_sweep(src, {"measure.oracle": True})
    R.run_sweep(oracle, tmp_path / "oracle", client=client, progress=False)
    o = pd.read_parquet(tmp_path / "oracle" / "results.parquet")
    assert (o["status"] == "ok").all(), o["error"].tolist()
    assert (o["mode"] == "oracle").all() and (first["mode"] == "blind").all()
    m = first.merge(o, on="scenario.motion.mu", suffixes=("", "_o"))
    assert len(m) == 2 and (m["case_id"] != m["case_id_o"]).all()
    assert (m["recording"].map(lambda p: Path(p).stem) == m["case_id"]).all()
    # the recording's as-built setup, the exact trough centre
    assert (m["asbuilt_cylinder_radius_mm_o"] == m["asbuilt_cylinder_radius_mm"]).all()
    assert (m["lab_err_cylinder_radius_mm"] != 0).all()
    assert (m["trough_center_err_x_px_o"].abs() < 1e-9).all()
    assert (m["lab_err_cylinder_radius_mm_o"] == 0).all()
    assert sorted((p.relative_to(src), p.stat().st_mtime_ns) for p in src.rglob("*")) == before

    with pytest.raises(S.SweepError, match="only measure"):
        T.recorded_sweep(src, {"render.seed": 3})


def test_recording_of_another_case_is_refused(tmp_path):
    """Re-measuring a recording as a case it was not rendered from is refused."""
    import sim
    import synth
    from validation.case import case_from_dict
    from validation.case_dict import small_case_dict

    d = small_case_dict(seconds=0.05)
    d["render"]["shadows"] = False
    case = case_from_dict(d)
    synth.render(sim.simulate(case.scenario), tmp_path / "r.zarr", scene=case.scene,
                 sensor=case.sensor, seed=0, workers=1, threads=1)
    other = small_case_dict(seconds=0.05)
    other["scenario"]["motion"]["mu"] = 0.011
    with pytest.raises(e2e.RecordingMismatch):
        e2e.remeasure_case(other, tmp_path / "r.zarr")
    d["render"]["seed"] = 1
    with pytest.raises(e2e.RecordingMismatch):
        e2e.remeasure_case(d, tmp_path / "r.zarr")


def test_from_recordings_cli_checks_its_input(tmp_path, capsys):
    """``rollfric sweep --from-recordings SRC``: the cases of SRC's kept recordings (a
    dry run lists them), refused (exit 2, nothing written) for --out SRC itself, for a --set
    of a key that would change what was rendered, and for a SRC without recordings."""
    from rollfric.cli.main import main
    from validation.case_dict import small_case_dict

    spec = S.sweep_from_dict({"sweep": {"name": "rec"}, "base": small_case_dict(0.1),
                              "grid": {"scenario.motion.mu": [0.005, 0.006]}})
    src = tmp_path / "src"
    for sc in spec.cases:
        T.write_part(src / "parts", T.part_row(sc, {"status": "ok", "error": "", "metrics": {}}))
    (src / "recordings" / f"{spec.cases[0].case_id}.zarr").mkdir(parents=True)
    assert main(["sweep", "--from-recordings", str(src), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert spec.cases[0].case_id in out and spec.cases[1].case_id not in out
    assert "1 case(s)" in out
    assert main(["sweep", "--from-recordings", str(src), "--out", str(src)]) == 2
    assert main(["sweep", "--from-recordings", str(src), "--out", str(tmp_path / "new"),
                 "--set", "render.seed=4"]) == 2
    assert main(["sweep", "--from-recordings", str(tmp_path), "--out",
                 str(tmp_path / "new")]) == 2
    assert not (tmp_path / "new").exists()
    assert "only measure.* keys" in capsys.readouterr().err


def test_metrics_are_plotted_in_the_unit_a_user_reads():
    assert P.metric_axis("mu_bias_rel") == (100.0, "bias in mu (%)")
    assert P.metric_axis("found_fraction") == (100.0, "frames located (%)")
    scale, label = P.metric_axis("theta_rms_rad")
    assert scale == pytest.approx(57.29577951308232) and label == "angle error, rms (deg)"
    assert P.metric_axis("center_rms_px") == (1.0, "centre error, rms (px)")


def test_identical_metrics_share_one_panel_and_the_verdict_counts_cases_within_U():
    df = pd.DataFrame({"status": ["ok"] * 4, "a": [1.0, 2.0, 3.0, 4.0],
                       "b": [1.0, 2.0, 3.0, 4.0], "c": [1.0, 2.0, 3.0, 5.0],
                       "within_U": [True, True, True, False]})
    assert P._distinct_metrics(df, ["a", "b", "c"]) == (["a", "c"], {"b": "a"})
    words, good = T.sweep_verdict(df)
    assert "within U(mu) (k = 2) in 3 of 4 (75 %" in words and good is False
    words, good = T.sweep_verdict(df.assign(within_U=True))
    assert "4 of 4 (100 %" in words and good is True
