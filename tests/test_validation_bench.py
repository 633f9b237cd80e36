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
