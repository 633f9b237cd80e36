"""Ctrl-C and SIGTERM end a command with 130 / 143 and one line, wherever they land: in
Python code, in a GIL-free numba kernel (whose dispatcher turns the signal's exception into
a SystemError), or in a `rollfric measure` subprocess while it tracks; nothing is written."""

from __future__ import annotations

import argparse
import ctypes
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import tifffile
from measure_data import make_recording

from rollfric.setup.model import save_setup

ROOT = Path(__file__).resolve().parents[1]


def _parser(command, work):
    """A build_parser for main() with one command that runs ``work``."""
    def parser():
        p = argparse.ArgumentParser(prog="rollfric")
        p.add_subparsers(dest="command").add_parser(command).set_defaults(func=work)
        return p
    return parser


def _kernel():
    """A nogil kernel that sends ``sig`` to its own process from inside, then works on: the
    signal's handler runs as the dispatcher returns, deterministically inside the kernel."""
    import numba

    libc = ctypes.CDLL(None)
    kill = libc.kill
    kill.argtypes = (ctypes.c_int, ctypes.c_int)
    kill.restype = ctypes.c_int

    @numba.njit(nogil=True)
    def work(pid, sig, n):
        kill(pid, sig)
        out = np.zeros(n)
        for k in range(n):
            out[k] = np.sqrt(k + 0.5)
        return out, out.sum()

    return work


@pytest.mark.parametrize("signum, status, word", [(signal.SIGINT, 130, "interrupted"),
                                                  (signal.SIGTERM, 143, "terminated")])
def test_a_signal_inside_a_numba_kernel_exits_with_its_status(monkeypatch, capsys, signum,
                                                              status, word):
    # issue 33: Ctrl-C or SIGTERM landing in a kernel ended in exit 1 and "SystemError:
    # CPUDispatcher(_pass_raw) returned a result with an exception set"
    from rollfric.cli import main as cli

    kernel = _kernel()
    cleaned = []

    def work(args):
        try:
            kernel(os.getpid(), int(signum), 1000)
            return 0
        finally:
            cleaned.append(True)

    monkeypatch.setattr(cli, "build_parser", _parser("kernel", work))
    before = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]
    assert cli.main(["kernel"]) == status
    assert cleaned == [True]
    err = capsys.readouterr().err
    assert err == f"rollfric kernel: {word}\n"
    assert [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)] == before


@pytest.mark.parametrize("signum, status, word", [(signal.SIGINT, 130, "interrupted"),
                                                  (signal.SIGTERM, 143, "terminated")])
def test_a_signal_inside_a_finalizer_still_ends_the_command(monkeypatch, capsys, signum, status,
                                                            word):
    # a signal whose handler runs inside an object's __del__ (llvmlite's, as numba frees a
    # compiled function): Python cannot raise there and printed "Exception ignored in ...
    # Traceback"; the command went on as if never interrupted
    from rollfric.cli import main as cli

    ran_on = []

    class Finalized:
        def __del__(self):
            os.kill(os.getpid(), int(signum))  # the handler runs before __del__ returns
            for _ in range(1000):
                pass

    def work(args):
        Finalized()  # freed at once: the signal lands in its finalizer
        for _ in range(200):  # the command's further work, where the interruption belongs
            time.sleep(0.005)
            ran_on.append(True)
        return 0

    monkeypatch.setattr(cli, "build_parser", _parser("freeing", work))
    hook = sys.unraisablehook
    assert cli.main(["freeing"]) == status
    assert len(ran_on) < 200  # interrupted, not run to the end
    assert capsys.readouterr().err == f"rollfric freeing: {word}\n"
    assert sys.unraisablehook is hook


def test_a_signal_in_a_finalizer_as_the_command_ends_is_still_reported(monkeypatch, capsys):
    # the command returns before the signal could be raised again: 130 all the same, and the
    # timer that would raise it is stopped (no SIGALRM left to end the process)
    from rollfric.cli import main as cli

    class Finalized:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)

    def work(args):
        Finalized()
        return 0

    monkeypatch.setattr(cli, "build_parser", _parser("quick", work))
    assert cli.main(["quick"]) == 130
    assert capsys.readouterr().err == "rollfric quick: interrupted\n"
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def test_a_finalizer_that_fails_after_the_signal_prints_no_traceback(monkeypatch, capsys):
    # SIGTERM inside a constructor (llvmlite's OutputString, as numba compiles a kernel in a
    # fresh environment) leaves the object half built; its finalizer then failed with
    # "AttributeError: ... no attribute '_owned'", printed as "Exception ignored in ...
    # Traceback" beside "terminated" (seen once in CI)
    from rollfric.cli import main as cli

    class HalfBuilt:
        def __del__(self):
            raise AttributeError("'OutputString' object has no attribute '_owned'")

    def work(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(1000):
                time.sleep(0.001)
        finally:
            HalfBuilt()  # freed at once as the signal unwinds the command: its finalizer fails
        return 0

    monkeypatch.setattr(cli, "build_parser", _parser("halfbuilt", work))
    # Python's own hook, which prints (pytest's turns the error into a warning)
    monkeypatch.setattr(sys, "unraisablehook", sys.__unraisablehook__)
    assert cli.main(["halfbuilt"]) == 143
    assert capsys.readouterr().err == "rollfric halfbuilt: terminated\n"


def test_an_error_that_is_no_interruption_is_not_taken_for_one(monkeypatch):
    # a SystemError (or any bug) with no signal behind it is still raised, not reported as 130
    from rollfric.cli import main as cli

    def work(args):
        raise SystemError("a real bug")

    monkeypatch.setattr(cli, "build_parser", _parser("bug", work))
    with pytest.raises(SystemError, match="a real bug"):
        cli.main(["bug"])


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lab")
    rec = make_recording(1200, noise=1.0, mu=0.002)
    tifffile.imwrite(folder / "rec.tif", np.stack(rec.frames))
    tifffile.imwrite(folder / "bg.tif", rec.background)
    save_setup(rec.setup, folder / "setup.toml")
    return folder


@pytest.mark.parametrize("signum, status, word", [(signal.SIGINT, 130, "interrupted"),
                                                  (signal.SIGTERM, 143, "terminated")])
def test_a_signal_while_measure_tracks_exits_with_its_status_writing_nothing(lab, tmp_path,
                                                                             signum, status,
                                                                             word):
    # the signal sent at several moments after the progress bar appears (tracking begun): most
    # of tracking is spent in GIL-free kernels; --out is neither created nor touched
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT), os.environ.get("PYTHONPATH", "")]))
    for k, delay in enumerate((0.0, 0.05, 0.15, 0.3)):
        out = tmp_path / f"out{k}"
        p = subprocess.Popen(
            [sys.executable, "-m", "rollfric.cli.main", "measure", str(lab / "rec.tif"),
             "--setup", str(lab / "setup.toml"), "--background", str(lab / "bg.tif"),
             "--out", str(out)],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
        seen = b""
        while b"locating ball" not in seen:  # tqdm's first line: tracking has begun
            chunk = p.stderr.read1(4096)
            assert chunk, f"measure ended before tracking: {seen.decode()}"
            seen += chunk
        time.sleep(delay)
        p.send_signal(signum)
        _, rest = p.communicate(timeout=300)
        err = (seen + rest).decode()
        assert p.returncode == status, err
        assert "Traceback" not in err and f"rollfric measure: {word}\n" in err
        assert not out.exists()
        assert not [n for n in os.listdir(tmp_path) if n.startswith(".")]  # no staging left
