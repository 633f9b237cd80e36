"""What the render processes' fork server imports (synth.preload) and when it starts
(synth.pipeline.start_fork_server): the renderer's modules, not the sensor model's numba
kernels nor zarr; started once, early, where render processes start from a fork server."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from synth import pipeline

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
    assert {"pyrender", "synth.scene", "synth.leandraw", "synth.store"} <= mods
    assert "numba" not in mods and "synth.sensor" not in mods
    assert "zarr" not in mods


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

    from synth.store import writer_layout

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
