"""An output folder appears all at once or not at all, and one run at a time writes it:
a run SIGKILLed at every step of putting its outputs in place leaves the old folder or the
new one, and a second run into a folder another run is writing is refused."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from measure_data import write_lab

from rollfric.output.folder import staged_folder
from rollfric.output.swap import claim, claim_path, exchange

ROOT = Path(__file__).resolve().parents[1]
OWN = ("budget.png", "fit.json", "fit.png", "track.csv")

# stages the outputs budget.png, fit.json, track.csv ("new") into argv[1] and SIGKILLs its
# own process before the file-system call number argv[2] (rename, replace, link, exchange)
_SCRIPT = """
import os, signal, sys
from pathlib import Path
import rollfric.output.folder as outputs
k, calls = int(sys.argv[2]), [0]
def killing(f):
    def call(*a, **kw):
        if calls[0] == k:
            os.kill(os.getpid(), signal.SIGKILL)
        calls[0] += 1
        return f(*a, **kw)
    return call
for name in ("rename", "replace", "link"):
    setattr(os, name, killing(getattr(os, name)))
outputs.exchange = killing(outputs.exchange)
own = dict.fromkeys(["budget.png", "fit.json", "fit.png", "track.csv"], "file")
with outputs.staged_folder(Path(sys.argv[1]), own, overwrite=sys.argv[3] == "1") as tmp:
    for name in ("budget.png", "fit.json", "track.csv"):
        (tmp / name).write_text("new")
"""


def _run(out: Path, k: int, overwrite: bool) -> int:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT),
                                                       os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-c", _SCRIPT, str(out), str(k),
                           "1" if overwrite else "0"], env=env, timeout=60).returncode


def _state(out: Path):
    if not out.exists():
        return None
    return {p.name: p.read_text() for p in out.iterdir()}


NEW = {"budget.png": "new", "fit.json": "new", "track.csv": "new"}


@pytest.mark.parametrize("existing", [False, True])
def test_a_run_killed_while_placing_its_outputs_leaves_the_old_folder_or_the_new(tmp_path,
                                                                               existing):
    # issue 33: SIGKILL while outputs were moved in one at a time left --out holding only
    # budget.png, and the next run refused the folder
    old = None
    if existing:  # a folder of the user's with an earlier run's outputs: --overwrite
        old = {"track.csv": "old", "fit.json": "old", "fit.png": "old", "notes.txt": "mine"}
    new = NEW if old is None else {**NEW, "notes.txt": "mine"}
    for k in range(12):
        out = tmp_path / f"k{k}" / "out"
        out.parent.mkdir()
        if old is not None:
            out.mkdir()
            for name, text in old.items():
                (out / name).write_text(text)
        code = _run(out, k, existing)
        assert _state(out) in (old, new), (k, code, _state(out))
        if code == 0:
            assert _state(out) == new
            assert sorted(os.listdir(out.parent)) == ["out"]
            break
        assert code == -9
        # the next run (--overwrite where there are old outputs) completes the job
        assert _run(out, -1, existing or _state(out) is not None) == 0
        assert _state(out) == new
        assert sorted(os.listdir(out.parent)) == ["out"]  # nothing hidden left beside it
    else:
        raise AssertionError("the run never finished")


def test_a_second_run_into_a_folder_being_written_is_refused(tmp_path, capsys):
    # issue 33: two runs into one empty --out both passed the check, and the later replaced
    # the earlier's files without --overwrite
    lab = write_lab(tmp_path)
    out = tmp_path / "m"
    out.mkdir()
    own = dict.fromkeys(OWN, "file")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT),
                                                       os.environ.get("PYTHONPATH", "")]))
    argv = [sys.executable, "-m", "rollfric.cli.main", "measure", str(lab / "rec.tif"), "--setup",
            str(lab / "setup.toml"), "--out", str(out), "--no-progress"]
    with staged_folder(out, own, overwrite=False) as tmp:  # this run writes m now
        (tmp / "track.csv").write_text("first")
        other = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
        assert other.returncode == 2, other.stderr
        assert "is being written by another run now" in other.stderr
        assert "Traceback" not in other.stderr
        assert claim_path(out).exists()
    assert _state(out) == {"track.csv": "first"}  # the first run's outputs, whole
    assert not claim_path(out).exists()
    # once the first is done the folder is not empty: refused as ever without --overwrite
    other = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
    assert other.returncode == 2 and "not empty" in other.stderr
    assert _state(out) == {"track.csv": "first"}
    # a claim is re-entrant in its own process
    with claim(out), claim(out):
        assert claim_path(out).exists()
    assert not claim_path(out).exists()


def test_exchange_swaps_two_folders(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "x").write_text("a")
    (b / "y").write_text("b")
    if not exchange(a, b):
        pytest.skip("no atomic exchange on this system")
    assert [p.name for p in a.iterdir()] == ["y"] and [p.name for p in b.iterdir()] == ["x"]
