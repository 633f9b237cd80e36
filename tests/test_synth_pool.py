"""The render pool re-runs the batches of a process that died, and gives up after a few pools.

No rendering here: the batch function writes one file per frame index, and kills its own
process (``os._exit``) where the test says so, as a crashed llvmpipe worker would die.
"""

import os
from pathlib import Path

import numpy as np
import pytest
from tqdm import tqdm

from synth.pool import MAX_POOL_RESTARTS, render_parallel


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
        render_parallel(batches, centres, 2, (str(out), str(marker), die), bar,
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
    """An early-started pool (synth.pool.early_pool) whose process died in a task before
    the batches (the background's render): every batch is rendered in a fresh pool."""
    import concurrent.futures as cf

    from synth.pool import pool_context

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
        render_parallel(batches, centres, 2, init, bar, initializer=_init, batch_fn=_batch,
                         pool=pool)
    assert sorted(int(p.name) for p in out.iterdir()) == list(range(n))


_POOL_KILLED = """
import sys
import numpy as np
from tqdm import tqdm
sys.path.insert(0, sys.argv[1])
from tests.test_synth_pool import _init, _pids

if __name__ == "__main__":
    from synth.pool import render_parallel
    out = sys.argv[2]
    with tqdm(total=64, disable=True) as bar:  # killed while its processes render
        render_parallel([np.arange(s, s + 16) for s in range(0, 64, 16)],
                         np.zeros((64, 1, 3)), 2, (out, out + "/none", "never"), bar,
                         initializer=_init, batch_fn=_pids)
"""


def _pids(indices, centres):
    # a batch that takes a while, its render process's pid left for the test to watch
    import time

    Path(os.environ["POOL_TEST_OUT"], f"pid-{os.getpid()}").touch()
    time.sleep(1.0)
    return len(indices)


def test_render_processes_exit_when_their_main_process_is_killed(tmp_path):
    # a pool's worker waits on a queue whose pipe it holds both ends of, and a fork server's
    # children keep it alive: a main process killed by SIGKILL left them all running for good
    import signal
    import subprocess
    import sys
    import time

    root = str(Path(__file__).resolve().parents[1])
    main = subprocess.Popen([sys.executable, "-c", _POOL_KILLED, root, str(tmp_path)])
    try:
        deadline = time.monotonic() + 60
        while len(list(tmp_path.glob("pid-*"))) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        pids = {int(p.name[4:]) for p in tmp_path.glob("pid-*")}
        assert len(pids) == 2 and main.poll() is None
        main.send_signal(signal.SIGKILL)
        main.wait()
        deadline = time.monotonic() + 20
        alive = set(pids)
        while alive and time.monotonic() < deadline:
            for pid in list(alive):
                try:
                    os.kill(pid, 0)
                except ProcessLookupError:
                    alive.discard(pid)
                else:  # a zombie of an exited child counts as gone
                    with open(f"/proc/{pid}/stat") as f:
                        if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                            alive.discard(pid)
            time.sleep(0.2)
        assert not alive, f"render processes {sorted(alive)} outlived their main process"
    finally:
        if main.poll() is None:
            main.kill()
