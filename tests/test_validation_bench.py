"""The bench's end-to-end row of the whole ``rollfric validate`` command (validation.bench)."""

from __future__ import annotations

import pytest


@pytest.mark.slow
def test_validate_command_is_timed_as_a_user_runs_it(tmp_path):
    from validation.bench import validate_command

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
    from synth import bench

    kept = dict(bench._STOCK)
    try:
        bench._STOCK.clear()
        times = bench.stock_frame_times(repeats=2)
        # two timed renders, none kept as the process's baseline (stock_frame_seconds' cache)
        assert len(times) == 2 and all(t > 0 for t in times) and not bench._STOCK
    finally:
        bench._STOCK.clear()
        bench._STOCK.update(kept)
