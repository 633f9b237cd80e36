"""The bench's end-to-end row of the whole ``rollfric validate`` command (validation.bench.e2e)."""

from __future__ import annotations

import pytest


@pytest.mark.slow
def test_validate_command_is_timed_as_a_user_runs_it(tmp_path):
    from validation.bench.e2e import validate_command

    wall, m = validate_command(0.1, tmp_path / "report")
    # the real command ran (its report is there) and its wall time holds the printed total
    # plus the process's start, imports, report and exit
    assert m["n_frames"] == 101 and m["case_id"]
    assert 0 < m["t_total_s"] < wall
    assert (tmp_path / "report" / "overlays.png").is_file()
    with pytest.raises(RuntimeError, match="validate failed"):  # the folder is not empty now
        validate_command(0.1, tmp_path / "report")


@pytest.mark.slow
def test_stock_frames_beside_a_measurement_are_measured_each_time():
    from validation.bench import render as bench

    kept = dict(bench._STOCK)
    try:
        bench._STOCK.clear()
        times = bench.stock_frame_times(repeats=2)
        # two timed renders, none kept as the process's baseline (stock_frame_seconds' cache)
        assert len(times) == 2 and all(t > 0 for t in times) and not bench._STOCK
    finally:
        bench._STOCK.clear()
        bench._STOCK.update(kept)


def test_the_validate_case_is_reported_by_its_median_run_each_beside_its_stock_frames(
        monkeypatch):
    # three runs between stock frames measured before and after each: the ratio of each run
    # is its frames' stock time over its total; the run with the median ratio is reported
    from validation.bench import e2e as bench
    from validation.bench import locate as bench_locate
    from validation.bench import render as sbench

    stock = iter([[0.4] * 3, [0.5] * 3, [0.4] * 3, [0.6] * 3])  # s a frame, before/after
    totals = iter([18.0, 20.0, 16.0])

    def case(_case):
        t = next(totals)
        return ({"n_frames": 4001, "t_total_s": t, "t_render_s": t - 4, "t_measure_s": 3.0,
                 "mu_bias_rel": 0.0, "center_rms_px": 0.02}, {})

    monkeypatch.setattr(sbench, "stock_frame_times", lambda repeats=3: next(stock))
    monkeypatch.setattr(bench, "_case_in_new_process", case)
    monkeypatch.setattr(bench_locate, "throughput", lambda *a: 2000.0)
    monkeypatch.setattr(bench, "validate_command",
                        lambda seconds, out: (21.0, {"t_total_s": 17.0, "n_frames": 4001}))
    rows = {r.item: r for r in bench.bench_e2e(quick=False)}
    # ratios: 4001 * 0.45 / 18 = 100.0, 4001 * 0.45 / 20 = 90.0, 4001 * 0.5 / 16 = 125.0
    total = rows["total"]
    assert total.value == 18.0 and total.baseline_value == pytest.approx(4001 * 0.45)
    assert total.gain == pytest.approx(100.0, rel=1e-3)
    assert "the median of 3 runs of the case, in order 100.0x / 90.0x / 125.0x" in total.note
    assert "(totals 18.0 / 20.0 / 16.0 s)" in total.note
    assert rows["stage render"].value == 14.0  # the stages are the reported run's
