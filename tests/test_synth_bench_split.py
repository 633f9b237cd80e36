"""validation.bench.render.schedule_split: a recording's time split into start-up and frames from
its own
batches' times (a made-up schedule whose split is known)."""

import math

import pytest

from synth.pipeline import BATCH
from validation.bench.render import pool_restarted, schedule_split


def _schedule(n_frames, to_first, first_extra, per_frame, tail=0.0):
    """Two processes taking batches alternately; each batch costs BATCH (or fewer) frames of
    ``per_frame`` s in one process, each process's first batch ``first_extra`` s more; the
    second process's last batch ends ``tail`` s late."""
    start = 100.0
    clock = {1: start + to_first, 2: start + to_first}
    batches = []
    for k, i0 in enumerate(range(0, n_frames, BATCH)):
        pid = 1 + k % 2
        n = min(BATCH, n_frames - i0)
        dur = n * per_frame + (first_extra if k < 2 else 0.0)
        batches.append((i0, pid, clock[pid], clock[pid] + dur))
        clock[pid] += dur
    i0, pid, t0, t1 = batches[-1]
    batches[-1] = (i0, pid, t0, t1 + tail)
    return {"start": start, "submitted": start + to_first, "workers": 2, "batches": batches}


def test_the_split_recovers_a_known_schedule():
    n, per_frame = 40 * BATCH, 0.011
    sched = _schedule(n, to_first=2.5, first_extra=0.8, per_frame=per_frame)
    end = max(b[3] for b in sched["batches"])
    out = schedule_split(sched, n, end - sched["start"])
    assert out["steady_s"] == pytest.approx(per_frame / 2)
    assert out["quarters_s"] == pytest.approx([per_frame / 2] * 4)
    assert out["to_first_batch_s"] == pytest.approx(2.5)
    assert out["first_batch_excess_s"] == pytest.approx(0.8)
    assert out["end_idle_s"] == pytest.approx(0.0, abs=1e-9)
    # all but the frames: the wait for the first batch and the first batches' excess
    assert out["startup_s"] == pytest.approx(2.5 + 0.8)


def test_a_slow_tail_and_a_last_short_batch():
    n, per_frame = 40 * BATCH + 5, 0.010
    sched = _schedule(n, to_first=1.0, first_extra=0.0, per_frame=per_frame, tail=0.7)
    out = schedule_split(sched, n, max(b[3] for b in sched["batches"]) - sched["start"])
    assert out["end_idle_s"] > 0.7 - BATCH * per_frame  # one process waited for the other
    assert out["quarters_s"][3] > out["quarters_s"][0]  # the slow batch is in the last quarter


def test_no_batches_gives_nan():
    out = schedule_split({"start": 0.0, "submitted": 0.0}, 10, 1.0)
    assert all(math.isnan(v) for k, v in out.items() if k != "quarters_s")


def test_a_pool_restart_is_seen_in_the_schedule():
    sched = _schedule(10 * BATCH, to_first=1.0, first_extra=0.0, per_frame=0.01)
    assert not pool_restarted(sched)
    # a process died: its unfinished batches were rendered by a fresh pool's processes
    sched["batches"] += [(10 * BATCH, 3, 200.0, 200.2), (11 * BATCH, 4, 200.0, 200.2)]
    assert pool_restarted(sched)
    assert not pool_restarted({"start": 0.0, "submitted": 0.0})


def test_file_create_probe_leaves_nothing(tmp_path):
    """The bench's file-creation probe times real files and removes them and their folder."""
    from validation.bench.render import file_create_ms

    ms = file_create_ms(tmp_path, n=20)
    assert 0 < ms < 1e4
    assert list(tmp_path.iterdir()) == []
