"""What the render processes' fork server imports (synth.preload) and when it starts
(synth.pool.start_fork_server): the renderer's modules, not the sensor model's numba
kernels nor zarr; started once, early, where render processes start from a fork server."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from synth import pipeline, pool

ROOT = Path(__file__).resolve().parents[1]


def _imports(code: str) -> set:
    """Modules a fresh interpreter has loaded after running ``code`` (this checkout first on
    its path)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH",
                                                                                 "")]))
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    out = subprocess.run([sys.executable, "-c", f"{code}; import sys; print(*sys.modules)"],
                         env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def test_the_fork_server_loads_the_renderer_but_not_the_sensor_model():
    mods = _imports("import synth.preload")
    assert {"pyrender", "synth.backends.raster", "synth.backends.lean", "synth.store"} <= mods
    assert "numba" not in mods and "synth.sensor" not in mods
    assert "zarr" not in mods
    # nor pyrender's interactive viewer (pyglet, tkinter, imageio: ~0.1 s of the server's CPU)
    assert not {"pyglet", "tkinter", "imageio"} & mods


def test_the_fork_servers_pyrender_has_no_viewer():
    code = """
import synth.preload, pyrender
try:
    pyrender.Viewer(None)
except RuntimeError as e:
    print("no-viewer" if "render processes" in str(e) else "other")
"""
    assert "no-viewer" in _imports(code.strip())
    # a process that imported pyrender before keeps its viewer
    assert "pyglet" in _imports("import pyrender, synth.preload")


def test_importing_synth_does_not_load_numba():
    assert "numba" not in _imports("import synth")


def test_reading_a_recording_still_has_its_sensor_model(tmp_path):
    import sim
    import synth
    from synth.camera import CameraModel

    traj = sim.simulate(sim.Scenario(theta0=0.03, duration=0.004))
    out = synth.render(traj, tmp_path / "r.zarr", scene=synth.SceneConfig(
        camera=CameraModel(width=96, height=80, center_px=(48.0, -500.0))),
        sensor=synth.noise_preset("realistic"), seed=1, workers=1)
    rec = synth.open_recording(out)
    assert rec.attrs["sensor_noise"] == pipeline.sensor_noise()
    assert rec.frames[0].shape == (80, 96)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a fork server on Linux only")
def test_the_fork_server_starts_once():
    from multiprocessing import forkserver

    assert pipeline.start_fork_server()
    pid = forkserver._forkserver._forkserver_pid
    assert pid is not None
    assert pipeline.start_fork_server()  # running: the same server
    assert forkserver._forkserver._forkserver_pid == pid


def test_the_writer_layout_names_the_chunks_as_zarr_does(tmp_path):
    import zarr
    from zarr.codecs import ZstdCodec

    from synth.chunks import writer_layout

    g = zarr.open_group(str(tmp_path / "s.zarr"), mode="w")
    arr = g.create_array("clean_diff", shape=(3, 256, 384), dtype="int16", chunks=(1, 128, 128),
                         fill_value=0, chunk_key_encoding={"name": "v2", "separator": "."},
                         compressors=[ZstdCodec(level=1)])
    folder, prefix, sep, dtype, chunk, frame, level = writer_layout(g, arr)
    assert (prefix, sep, dtype, chunk, frame, level) == ("", ".", "<i2", (128, 128),
                                                         (256, 384), 1)
    key = arr.metadata.chunk_key_encoding.encode_chunk_key
    assert key((2, 1, 2)) == prefix + sep.join(["2", "1", "2"])
    assert folder == str(tmp_path / "s.zarr" / "clean_diff")
    # zarr's default chunk keys ("c/..."): named as zarr names them
    dflt = g.create_array("dflt", shape=(3, 256, 384), dtype="int16", chunks=(1, 128, 128),
                          fill_value=0, compressors=[ZstdCodec(level=1)])
    _, prefix, sep, *_ = writer_layout(g, dflt)
    assert prefix + sep.join(["2", "1", "2"]) == \
        dflt.metadata.chunk_key_encoding.encode_chunk_key((2, 1, 2))
    # another layout (chunks of two frames): not the pipeline's, no layout
    other = g.create_array("other", shape=(3, 256, 384), dtype="int16", chunks=(2, 128, 128),
                           fill_value=0, compressors=[ZstdCodec(level=1)])
    assert writer_layout(g, other) is None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a fork server on Linux only")
def test_a_render_on_processes_leaves_pyrender_to_them(tmp_path):
    """With render processes, the first of them draws the background (the others draw a
    frame meanwhile): the main process imports neither pyrender nor trimesh, and the
    recording holds the bytes of one drawn in a single process."""
    code = f"""
import sim, synth, numpy as np
from synth.camera import CameraModel
tr = sim.simulate(sim.Scenario(theta0=0.03, duration=0.079))
kw = dict(scene=synth.SceneConfig(camera=CameraModel(width=160, height=128,
          center_px=(80.0, -500.0))), sensor=synth.noise_preset("realistic"), seed=7)
sched = {{}}
two = synth.render(tr, {str(tmp_path / "two.zarr")!r}, workers=2, schedule=sched, **kw)
assert len({{b[1] for b in sched["batches"]}}) <= 2 and sched["workers"] == 2
print("drawn-elsewhere", "pyrender" not in __import__("sys").modules,
      "trimesh" not in __import__("sys").modules)
one = synth.render(tr, {str(tmp_path / "one.zarr")!r}, workers=1, **kw)
a, b = synth.open_recording(one), synth.open_recording(two)
assert a.background.tobytes() == b.background.tobytes()
assert all(a.frames[i].tobytes() == b.frames[i].tobytes() for i in range(len(tr)))
"""
    mods = _imports(code.strip())
    assert "drawn-elsewhere" in mods and "False" not in mods
    assert "pyrender" in mods  # the one-process render drew in this process


def test_prepare_render_starts_the_fork_server_only_for_render_processes():
    import synth
    from synth.camera import CameraModel

    scene = synth.SceneConfig()
    assert pipeline.render_workers(scene, 4001) == min(2, max(1, os.cpu_count() or 1))
    assert pipeline.render_workers(scene, 20) == 1  # one batch: one process
    assert pipeline.render_workers(scene, 4001, workers=1) == 1
    assert not pipeline.prepare_render(scene, 4001, workers=1)
    assert not pipeline.prepare_render(scene, 20, workers=2)
    thin = scene.replace(camera=CameraModel(f_number=4.0))
    assert thin.camera.thin_lens and not pipeline.prepare_render(thin, 4001, workers=2)
    if sys.platform.startswith("linux"):
        assert pipeline.prepare_render(scene, 4001, workers=2)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a fork server on Linux only")
def test_render_processes_start_before_zarr_is_imported(tmp_path):
    """A process that has not loaded Zarr (``rollfric validate``'s, ~0.16 s of imports) starts
    its render processes first and imports Zarr while they start and draw the background."""
    code = f"""
import contextlib, sys
import sim, synth
from synth import pool
from synth.camera import CameraModel
seen = []
early = pool.early_pool
@contextlib.contextmanager
def watched(*a, **k):
    seen.append("zarr" in sys.modules)
    with early(*a, **k) as got:
        yield got
pool.early_pool = watched
tr = sim.simulate(sim.Scenario(theta0=0.03, duration=0.079))
assert "zarr" not in sys.modules
synth.render(tr, {str(tmp_path / "r.zarr")!r}, workers=2, seed=1, scene=synth.SceneConfig(
    camera=CameraModel(width=160, height=128, center_px=(80.0, -500.0))))
print("zarr-at-pool-start", *seen)
"""
    mods = _imports(code.strip())
    assert "zarr-at-pool-start" in mods and "False" in mods and "True" not in mods


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a fork server on Linux only")
def test_the_truth_is_written_while_a_render_process_draws_the_background(tmp_path,
                                                                          monkeypatch):
    """The main process writes what needs no background (the truth, ~30 ms for 4001 frames)
    before it waits for the background a render process draws, not after."""
    import contextlib

    import sim
    import synth

    order = []
    table = pipeline.truth_table
    monkeypatch.setattr(pipeline, "truth_table",
                        lambda *a, **k: order.append("truth") or table(*a, **k))
    early = pool.early_pool

    @contextlib.contextmanager
    def watched(*a, **k):
        with early(*a, **k) as (pool, submitted):
            def waited():
                order.append("background awaited")
                return submitted()
            yield pool, waited

    monkeypatch.setattr(pool, "early_pool", watched)
    from synth.camera import CameraModel

    tr = sim.simulate(sim.Scenario(theta0=0.03, duration=0.079))
    out = synth.render(tr, tmp_path / "r.zarr", workers=2, seed=1, scene=synth.SceneConfig(
        camera=CameraModel(width=160, height=128, center_px=(80.0, -500.0))))
    assert order == ["truth", "background awaited"]
    rec = synth.open_recording(out)
    assert len(rec.truth["t_s"]) == len(tr) and rec.background.shape == (128, 160)
