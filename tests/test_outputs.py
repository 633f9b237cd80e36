"""Nothing of the user's is deleted or mixed: every command refuses an existing destination
before any work unless --overwrite, replaces only its own outputs, never a folder by a file (or
the reverse), and removes the temporary paths of killed runs (rollfric.output.atomic, .outputs)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from measure_data import write_lab

from rollfric.cli.main import main
from rollfric.errors import InputError
from rollfric.output import atomic
from rollfric.output.folder import OutputError, check_file, check_folder, staged_folder
from validation.metrics import is_metric

ROOT = Path(__file__).resolve().parents[1]


def _snapshot(folder: Path) -> dict:
    """Every path under folder (hidden ones too) -> its bytes (None for a folder)."""
    return {str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes())
            for p in sorted(folder.rglob("*"))}


def _kill_inside_replacing(dest: Path, folder: bool = False) -> Path:
    """Run a process that dies (SIGKILL-like os._exit) while writing ``dest`` through
    rollfric.output.atomic.replacing: the temporary path it leaves behind."""
    code = textwrap.dedent(f"""
        import os, sys
        sys.path.insert(0, {str(ROOT)!r})
        from rollfric.output.atomic import replacing
        with replacing({str(dest)!r}, folder_ok=True) as tmp:
            if {folder!r}:
                tmp.mkdir(); (tmp / "zarr.json").write_text("{{}}")
            else:
                tmp.write_text("half")
            os._exit(9)
    """)
    r = subprocess.run([sys.executable, "-c", code], check=False)
    assert r.returncode == 9
    left = [p for p in dest.parent.iterdir() if p.name.startswith(f".{dest.stem}.part-")]
    assert len(left) == 1
    return left[0]


# -- rollfric.output.atomic and rollfric.output.folder
# --------------------------------------------------------

def test_a_file_never_replaces_a_folder_nor_the_reverse(tmp_path):
    d = tmp_path / "out"
    d.mkdir()
    (d / "keep.txt").write_text("mine")
    with pytest.raises(InputError, match="is a folder"):
        atomic.write_text(d, "x")
    assert (d / "keep.txt").read_text() == "mine"
    f = tmp_path / "f.zarr"
    f.write_text("mine")
    with pytest.raises(InputError, match="is a file"), atomic.replacing(f, folder_ok=True) as t:
        t.mkdir()
    assert f.read_text() == "mine"
    # a folder replaces a folder only when the caller says so
    with pytest.raises(InputError, match="not replaced"), atomic.replacing(d) as t:
        t.mkdir()
    assert (d / "keep.txt").read_text() == "mine"
    with atomic.replacing(d, folder_ok=True) as t:
        t.mkdir()
        (t / "new.txt").write_text("new")
    assert sorted(p.name for p in d.iterdir()) == ["new.txt"]
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_leftovers_of_killed_runs_are_told_apart_and_removed(tmp_path):
    dead_file = _kill_inside_replacing(tmp_path / "fit.json")
    dead_dir = _kill_inside_replacing(tmp_path / "rec.zarr", folder=True)
    assert atomic.is_leftover(dead_file) and atomic.is_leftover(dead_dir)
    # this process's own temporary path (its PID and start time) is in use, not a leftover
    mine = atomic.temp_path(tmp_path / "t.csv")
    mine.write_text("in progress")
    assert not atomic.is_leftover(mine)
    # the same PID with another start time: a PID reused by a later process
    pid = os.getpid()
    reused = tmp_path / f".t.part-{pid}-{atomic._own_start() - 500}.csv"
    reused.write_text("old")
    assert atomic.is_leftover(reused)
    # a live process (PID 1) with no start time in the name (older versions): kept
    (tmp_path / ".x.part-1.csv").write_text("?")
    assert not atomic.is_leftover(tmp_path / ".x.part-1.csv")
    # user files that only look similar are never touched
    for name in (".hidden", "fit.part-1.json", ".notes.part-x.txt"):
        (tmp_path / name).write_text("mine")
    removed = atomic.remove_leftovers(tmp_path)
    assert sorted(removed) == sorted([dead_file, dead_dir, reused])
    assert mine.exists() and (tmp_path / ".x.part-1.csv").exists()
    for name in (".hidden", "fit.part-1.json", ".notes.part-x.txt"):
        assert (tmp_path / name).read_text() == "mine"


def test_check_file_and_folder(tmp_path):
    (tmp_path / "a.json").write_text("{}")
    with pytest.raises(OutputError, match="exists"):
        check_file(tmp_path / "a.json", overwrite=False)
    assert check_file(tmp_path / "a.json", overwrite=True) == tmp_path / "a.json"
    with pytest.raises(OutputError, match="a.json is a file, not a folder"):
        check_file(tmp_path / "a.json" / "b" / "c.json", overwrite=True)
    with pytest.raises(OutputError, match="is a file"):
        check_folder(tmp_path / "a.json", {}, overwrite=True)
    (tmp_path / "d").mkdir()
    check_folder(tmp_path / "d", {"x.csv": "file"}, overwrite=False)  # empty: used as is
    (tmp_path / "d" / "x.csv").mkdir()
    with pytest.raises(OutputError, match="not empty"):
        check_folder(tmp_path / "d", {"x.csv": "file"}, overwrite=False)
    with pytest.raises(OutputError, match="is a folder where"):
        check_folder(tmp_path / "d", {"x.csv": "file"}, overwrite=True)


def test_staged_folder_replaces_own_names_only_and_nothing_on_error(tmp_path):
    own = {"a.csv": "file", "b.png": "file", "rec.zarr": "folder"}
    out = tmp_path / "out"
    out.mkdir()
    for name, text in (("a.csv", "old a"), ("b.png", "old b"), ("mine.txt", "mine")):
        (out / name).write_text(text)
    (out / "rec.zarr").mkdir()
    (out / "rec.zarr" / "old").write_text("old")
    before = _snapshot(out)
    with pytest.raises(RuntimeError, match="boom"), staged_folder(out, own, overwrite=True) as t:
        (t / "a.csv").write_text("new a")
        raise RuntimeError("boom")
    assert _snapshot(out) == before  # an error changes nothing
    with pytest.raises(OutputError, match="not empty"), \
            staged_folder(out, own, overwrite=False):
        pass
    with staged_folder(out, own, overwrite=True) as t:
        (t / "a.csv").write_text("new a")
        (t / "rec.zarr").mkdir()
        (t / "rec.zarr" / "new").write_text("new")
    assert (out / "a.csv").read_text() == "new a"
    assert not (out / "b.png").exists()  # own output not written this time: not left stale
    assert (out / "mine.txt").read_text() == "mine"
    assert sorted(p.name for p in (out / "rec.zarr").iterdir()) == ["new"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


# -- the commands -------------------------------------------------------------------------------

@pytest.fixture
def lab(tmp_path):
    """A setup, a track CSV and a small TIFF recording with its background."""
    return write_lab(tmp_path)


def _fit(lab, out, *extra):
    return main(["fit", str(lab / "track.csv"), "--setup", str(lab / "setup.toml"),
                 "--out", str(out), *extra])


def test_fit_refuses_an_existing_output_and_never_a_folder(lab, capsys):
    folder = lab / "results"
    folder.mkdir()
    (folder / "photo.jpg").write_text("mine")
    for extra in ((), ("--overwrite",)):
        assert _fit(lab, folder, *extra) == 2
        assert "is a folder" in capsys.readouterr().err
    assert (folder / "photo.jpg").read_text() == "mine"
    out = lab / "fit.json"
    out.write_text("earlier")
    # refused before any work: the missing track is not even read
    code = main(["fit", str(lab / "missing.csv"), "--setup", str(lab / "setup.toml"),
                 "--out", str(out)])
    assert code == 2 and "exists (--overwrite" in capsys.readouterr().err
    assert out.read_text() == "earlier"
    assert _fit(lab, out, "--plot", "--overwrite") == 0
    assert json.loads(out.read_text())["mu"] > 0 and (lab / "fit.png").exists()
    # --overwrite without --plot: the earlier figure does not stay beside the new result
    assert _fit(lab, out, "--overwrite") == 0
    assert not (lab / "fit.png").exists()
    # an output that is an input, or that collides with its own figure
    assert _fit(lab, lab / "track.csv", "--overwrite") == 2
    assert "input" in capsys.readouterr().err
    assert _fit(lab, lab / "x.png", "--plot") == 2
    assert "same path" in capsys.readouterr().err
    assert _fit(lab, lab / "setup.toml" / "fit.json") == 2
    assert "is a file, not a folder" in capsys.readouterr().err


def _measure(lab, out, *extra):
    return main(["measure", str(lab / "rec.tif"), "--setup", str(lab / "setup.toml"),
                 "--background", str(lab / "bg.tif"), "--out", str(out), "--no-progress",
                 *extra])


def test_measure_never_mixes_old_and_new_outputs(lab, capsys):
    out = lab / "m"
    assert _measure(lab, out, "--plot") == 0
    assert sorted(p.name for p in out.iterdir()) == ["budget.png", "fit.json", "fit.png",
                                                     "overlays.png", "track.csv"]
    (out / "notes.txt").write_text("mine")
    before = _snapshot(out)
    # refused before any work (the recording is not even opened)
    code = main(["measure", str(lab / "missing.tif"), "--setup", str(lab / "setup.toml"),
                 "--out", str(out), "--no-progress"])
    assert code == 2 and "not empty" in capsys.readouterr().err
    assert _snapshot(out) == before
    (out / "track.csv").write_text("stale")
    assert _measure(lab, out, "--overwrite") == 0
    # own outputs replaced, own outputs not written this time removed, the user's file kept
    assert sorted(p.name for p in out.iterdir()) == ["fit.json", "notes.txt", "track.csv"]
    assert (out / "track.csv").read_text().startswith("frame,")
    assert (out / "notes.txt").read_text() == "mine"
    # an own output name that is a folder is never replaced by a file
    (out / "fit.json").unlink()
    (out / "fit.json").mkdir()
    assert _measure(lab, out, "--overwrite") == 2
    assert "is a folder where measure writes a file" in capsys.readouterr().err
    assert (out / "fit.json").is_dir()
    # --out is a file
    assert _measure(lab, lab / "track.csv", "--overwrite") == 2
    # an existing empty folder is used as it is
    (lab / "empty").mkdir()
    assert _measure(lab, lab / "empty") == 0


def test_measure_never_replaces_or_removes_an_input_named_like_its_output(lab, capsys):
    # audit 2026-11-24: a background image named fit.png inside --out was removed by
    # --overwrite (an own output not written this time), and replaced by the plot with --plot
    out = lab / "m"
    out.mkdir()
    import cv2
    import tifffile

    bg = out / "fit.png"
    cv2.imwrite(str(bg), tifffile.imread(lab / "bg.tif"))
    before = _snapshot(out)
    for extra in (("--overwrite",), ("--overwrite", "--plot")):
        code = main(["measure", str(lab / "rec.tif"), "--setup", str(lab / "setup.toml"),
                     "--background", str(bg), "--out", str(out), "--no-progress", *extra])
        err = capsys.readouterr().err
        assert code == 2 and "is an input" in err and "fit.png" in err, err
        assert _snapshot(out) == before


def test_measure_removes_what_a_killed_run_left(lab):
    out = lab / "m"
    left = _kill_inside_replacing(out, folder=True)
    legacy = lab / ".m.abc123_x"  # older versions' tempfile.mkdtemp folder (mode 0700)
    legacy.mkdir(mode=0o700)
    legacy.chmod(0o700)
    (legacy / "track.csv").write_text("half")
    assert _measure(lab, out) == 0
    assert not left.exists() and not legacy.exists()
    assert sorted(p.name for p in lab.iterdir() if p.name.startswith(".")) == []


def test_measure_keeps_a_users_folder_named_like_a_legacy_leftover(lab):
    # audit 2026-11-24: a user's ".m.20261124" holding the track.csv and fit.json of an earlier
    # run (a mkdtemp-like name) was removed by the next measure into m, without --overwrite
    mine = lab / ".m.20261124"
    mine.mkdir()
    mine.chmod(0o755)
    (mine / "track.csv").write_text("mine")
    (mine / "fit.json").write_text("mine")
    assert _measure(lab, lab / "m") == 0
    assert (mine / "track.csv").read_text() == "mine"
    assert (mine / "fit.json").read_text() == "mine"


def test_simulate_outputs(tmp_path, capsys):
    def sim(out, *extra):
        return main(["simulate", "--seconds", "0.05", "--out", str(out), *extra])

    # a CSV named .json would be its own sidecar
    assert sim(tmp_path / "t.json") == 2
    assert "sidecar" in capsys.readouterr().err and list(tmp_path.iterdir()) == []
    assert sim(tmp_path / "t.csv") == 0
    csv, side = (tmp_path / "t.csv").read_bytes(), (tmp_path / "t.json").read_bytes()
    assert sim(tmp_path / "t.csv", "--mu", "0.01") == 2
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "t.csv").read_bytes() == csv
    # the sidecar alone exists: refused as well
    (tmp_path / "u.json").write_text("mine")
    assert sim(tmp_path / "u.csv") == 2 and "sidecar" in capsys.readouterr().err
    assert (tmp_path / "u.json").read_text() == "mine" and not (tmp_path / "u.csv").exists()
    assert sim(tmp_path / "t.csv", "--mu", "0.01", "--overwrite") == 0
    assert (tmp_path / "t.csv").read_bytes() != csv
    assert json.loads((tmp_path / "t.json").read_text()) != json.loads(side)
    (tmp_path / "d.csv").mkdir()
    assert sim(tmp_path / "d.csv", "--overwrite") == 2 and (tmp_path / "d.csv").is_dir()


def test_render_refuses_before_rendering(tmp_path, capsys):
    traj = tmp_path / "missing.csv"  # never read: the outputs are refused first
    rec = tmp_path / "rec.zarr"
    rec.mkdir()
    (rec / "photo.jpg").write_text("mine")
    assert main(["render", str(traj), "--out", str(rec)]) == 2
    assert "exists" in capsys.readouterr().err
    # a folder that is not a recording is never replaced
    assert main(["render", str(traj), "--out", str(rec), "--overwrite"]) == 2
    assert "does not hold a synth recording" in capsys.readouterr().err
    exp = tmp_path / "export"
    exp.mkdir()
    (exp / "notes.txt").write_text("mine")
    assert main(["render", str(traj), "--out", str(tmp_path / "new.zarr"),
                 "--export", str(exp)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert not (tmp_path / "new.zarr").exists()
    assert main(["render", str(traj), "--out", str(tmp_path / "f.txt"),
                 "--export", str(tmp_path / "f.txt")]) == 2
    assert (rec / "photo.jpg").read_text() == "mine"
    assert (exp / "notes.txt").read_text() == "mine"


def test_render_overwrite_replaces_a_recording_and_export_keeps_other_files(tmp_path):
    import sim
    import synth
    from synth.camera import CameraModel
    from synth.export import export_recording
    from synth.pipeline import is_recording

    traj = sim.simulate(sim.Scenario(theta0=0.03, duration=0.003))
    scene = synth.SceneConfig(camera=CameraModel(width=96, height=64, center_px=(48.0, -520.0)),
                              shadows=False)
    rec = tmp_path / "rec.zarr"
    synth.render(traj, rec, scene=scene, workers=1, seed=1)
    assert is_recording(rec)
    with pytest.raises(InputError, match="exists"):
        synth.render(traj, rec, scene=scene, workers=1, seed=2)
    synth.render(traj, rec, scene=scene, workers=1, seed=2, overwrite=True)
    assert synth.open_recording(rec).attrs["seed"] == 2
    exp = tmp_path / "export"
    exp.mkdir()
    (exp / "notes.txt").write_text("mine")
    (exp / "truth.csv").write_text("stale")
    with pytest.raises(InputError, match="not empty"):
        export_recording(rec, exp)
    export_recording(rec, exp, overwrite=True)
    assert sorted(p.name for p in exp.iterdir()) == ["background.png", "frames.tif",
                                                     "notes.txt", "setup.toml", "truth.csv"]
    assert (exp / "notes.txt").read_text() == "mine"
    assert (exp / "truth.csv").read_text().startswith("frame,")
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_validate_refuses_a_non_empty_report_folder_before_any_work(tmp_path, capsys):
    out = tmp_path / "report"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["validate", str(tmp_path / "missing.toml"), "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    (tmp_path / "file").write_text("x")
    assert main(["validate", "--out", str(tmp_path / "file"), "--overwrite"]) == 2
    assert "is a file" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_validate_report_overwrite_keeps_other_files(tmp_path):
    from validation import case_dict as CD
    from validation import e2e

    d = CD.small_case_dict(seconds=0.05)
    d["render"].update(shadows=False)
    out = tmp_path / "report"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "recording.zarr").mkdir()  # an own output of an earlier --keep-recording run
    (out / "recording.zarr" / "zarr.json").write_text("{}")
    (out / "fit.json").write_text("stale")
    with pytest.raises(OutputError, match="not empty"):
        e2e.run_case(d, report_dir=out, render_workers=1)
    r = e2e.run_case(d, report_dir=out, render_workers=1, overwrite=True)
    # every metric a case reports can be named in a sweep file
    assert [k for k in r.metrics if not is_metric(k)] == []
    assert [k for k in e2e.sim_only_case(d) if not is_metric(k)] == []
    names = sorted(p.name for p in out.iterdir())
    assert "notes.txt" in names and "recording.zarr" not in names
    assert json.loads((out / "fit.json").read_text())["mu"] == pytest.approx(r.fit.mu)
    r2 = e2e.run_case(d, report_dir=out, render_workers=1, overwrite=True, keep_recording=True)
    assert r2.recording == out / "recording.zarr" and (out / "recording.zarr").is_dir()
    assert [p.name for p in tmp_path.iterdir()] == ["report"]


def test_bench_refuses_and_overwrites_its_own_files_only(tmp_path, monkeypatch, capsys):
    from validation.bench import run as bench

    out = tmp_path / "bench"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["bench", "--out", str(out), "--only", "fitting"]) == 2  # before any section
    assert "not empty" in capsys.readouterr().err
    monkeypatch.setitem(bench.SECTIONS, "fitting", lambda quick: [])
    (out / "bench.md").write_text("old")
    assert main(["bench", "--out", str(out), "--only", "fitting", "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["bench.json", "bench.md", "notes.txt"]
    assert (out / "bench.md").read_text() != "old"


def test_sweep_output_folder(tmp_path, capsys):
    from validation import sweep as S
    from validation import sweep_run as R
    from validation import sweep_table as T

    spec = S.sweep_from_dict({"sweep": {"name": "a", "stages": "sim"},
                              "grid": {"scenario.motion.mu": [0.005, 0.006]}})
    other = S.sweep_from_dict({"sweep": {"name": "b", "stages": "sim"},
                               "grid": {"scenario.motion.mu": [0.005]}})
    out = tmp_path / "out"
    assert R.check_out(out, spec) == "new"
    out.mkdir()
    assert R.check_out(out, spec) == "new"
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not empty"):
        R.check_out(out, spec)
    assert R.check_out(out, spec, overwrite=True) == "fresh"
    # a folder of this sweep is resumed; of another sweep refused without --overwrite
    for sc in spec.cases:
        T.write_part(out / "parts", T.part_row(sc, {"status": "ok", "error": "", "metrics": {}}))
    assert R.check_out(out, spec) == "resume"
    with pytest.raises(InputError, match="holds the results of sweep 'a'"):
        R.check_out(out, other)
    # starting afresh removes the sweep's own outputs only
    (out / "results.csv").write_text("old")
    (out / "plots").mkdir()
    (out / "plots" / "x.png").write_text("old")
    R._remove_own_outputs(out)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    # the command refuses before starting a cluster
    sw = tmp_path / "s.toml"
    sw.write_text('[sweep]\nname = "b"\nstages = "sim"\n[grid]\n"scenario.motion.mu" = [0.005]\n')
    assert main(["sweep", str(sw), "--out", str(out), "--no-progress"]) == 2
    assert "not empty" in capsys.readouterr().err
    assert main(["sweep", str(sw), "--out", str(sw), "--no-progress"]) == 2
    assert "is a file" in capsys.readouterr().err


def _read_only(folder: Path) -> bool:
    """Make ``folder`` unwritable: chmod for a user, the immutable attribute for root (who
    writes anywhere else). False if neither is possible here."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return True
    r = subprocess.run(["chattr", "+i", str(folder)], capture_output=True, check=False)
    return r.returncode == 0


def _writable(folder: Path) -> None:
    if os.geteuid() == 0:
        subprocess.run(["chattr", "-i", str(folder)], capture_output=True, check=False)
    folder.chmod(0o755)


def test_read_only_folder_is_refused_with_a_message(lab, capsys):
    ro = lab / "ro"
    ro.mkdir()
    (ro / "m").mkdir()
    if not _read_only(ro):
        pytest.skip("cannot make a folder read-only here")
    try:
        for argv in (["fit", str(lab / "track.csv"), "--setup", str(lab / "setup.toml"),
                      "--out", str(ro / "a" / "f.json")],
                     ["fit", str(lab / "track.csv"), "--setup", str(lab / "setup.toml"),
                      "--out", str(ro / "f.json")],
                     ["measure", str(lab / "rec.tif"), "--setup", str(lab / "setup.toml"),
                      "--out", str(ro / "m"), "--no-progress"]):
            assert main(argv) == 2
            err = capsys.readouterr().err.lower()
            assert "permission denied" in err or "not permitted" in err
            assert str(ro).lower() in err
        assert sorted(p.name for p in ro.iterdir()) == ["m"]
    finally:
        _writable(ro)


def test_the_folder_the_command_runs_in_as_out(lab, monkeypatch, capsys):
    # audit 2026-11-24: --out . (or "") ended in pathlib's "PosixPath('.') has an empty name",
    # a traceback: for measure after the whole measurement, for fit before the fit
    here = lab / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    for out in (".", ""):
        assert _fit(lab, out) == 2
        err = capsys.readouterr().err
        assert "is a folder" in err and "Traceback" not in err
    assert _measure(lab, ".") == 0
    assert sorted(p.name for p in here.iterdir()) == ["fit.json", "track.csv"]
    assert _measure(lab, "") == 2
    assert "not empty" in capsys.readouterr().err
    assert [p.name for p in lab.iterdir() if p.name.startswith(".")] == []


def test_every_command_names_the_folder_of_out_dot(tmp_path, monkeypatch, capsys):
    # audit 2026-11-24: simulate --out . ended in pathlib's "has an empty name" too
    monkeypatch.chdir(tmp_path)
    for out in (".", ".."):
        assert main(["simulate", "--seconds", "0.05", "--out", out]) == 2
        err = capsys.readouterr().err
        assert "is a folder" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []
