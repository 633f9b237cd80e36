"""The render pool re-runs the batches of a process that died, and gives up after a few pools.

No rendering here: the batch function writes one file per frame index, and kills its own
process (``os._exit``) where the test says so, as a crashed llvmpipe worker would die.
"""

import os
from pathlib import Path

import numpy as np
import pytest
from tqdm import tqdm

from synth.pipeline import MAX_POOL_RESTARTS, _render_parallel


def _init(out_dir, marker, die):
    os.environ["POOL_TEST_OUT"] = out_dir
    os.environ["POOL_TEST_MARKER"] = marker
    os.environ["POOL_TEST_DIE"] = die


def _batch(indices, centres):
    out, marker = Path(os.environ["POOL_TEST_OUT"]), Path(os.environ["POOL_TEST_MARKER"])
    die = os.environ["POOL_TEST_DIE"]
    if int(indices[0]) == 16 and (die == "always" or not marker.exists()):
        marker.touch()
        os._exit(3)  # the process dies, as a segfault would kill it
    for i, c in zip(indices, centres, strict=True):
        with open(out / f"{int(i)}", "a") as f:
            f.write(f"{c[0, 0]:.1f}\n")
    return len(indices)


def _run(tmp_path, die):
    n = 64
    batches = [np.arange(s, min(s + 16, n)) for s in range(0, n, 16)]
    centres = np.arange(n, dtype=float)[:, None, None] * np.ones((1, 1, 3))
    out = tmp_path / "frames"
    out.mkdir()
    marker = tmp_path / "died"
    with tqdm(total=n, disable=True) as bar:
        _render_parallel(batches, centres, 2, (str(out), str(marker), die), bar,
                         initializer=_init, batch_fn=_batch)
    return out, marker, n


def test_a_dead_process_batches_are_rendered_again(tmp_path, capsys):
    out, marker, n = _run(tmp_path, "once")
    assert marker.exists()  # a process really died
    # the notice goes to stderr: stdout may be a result (rollfric validate --json)
    said = capsys.readouterr()
    assert said.out == "" and "a render process died" in said.err
    # every frame was rendered, each with its own centre (a batch may have been written twice
    # when it finished in the pool that broke; its content is the same)
    for i in range(n):
        lines = (out / str(i)).read_text().split()
        assert lines and set(lines) == {f"{float(i):.1f}"}, (i, lines)


def test_a_batch_that_always_kills_its_process_is_an_error(tmp_path):
    with pytest.raises(RuntimeError, match=f"after {MAX_POOL_RESTARTS} restarts"):
        _run(tmp_path, "always")


def _exit():
    os._exit(3)


def test_a_pool_that_broke_before_its_batches_is_replaced(tmp_path):
    """An early-started pool (synth.pipeline._early_pool) whose process died in a task before
    the batches (the background's render): every batch is rendered in a fresh pool."""
    import concurrent.futures as cf

    from synth.pipeline import pool_context

    n = 64
    batches = [np.arange(s, min(s + 16, n)) for s in range(0, n, 16)]
    centres = np.arange(n, dtype=float)[:, None, None] * np.ones((1, 1, 3))
    out = tmp_path / "frames"
    out.mkdir()
    init = (str(out), str(tmp_path / "died"), "never")
    pool = cf.ProcessPoolExecutor(2, mp_context=pool_context(), initializer=_init,
                                  initargs=init)
    with pytest.raises(cf.process.BrokenProcessPool):
        pool.submit(_exit).result()
    with tqdm(total=n, disable=True) as bar:
        _render_parallel(batches, centres, 2, init, bar, initializer=_init, batch_fn=_batch,
                         pool=pool)
    assert sorted(int(p.name) for p in out.iterdir()) == list(range(n))
