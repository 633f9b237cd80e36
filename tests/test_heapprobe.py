"""The heap probe, tools/heapprobe (issue 16): a write into freed heap memory is reported
with its bytes and the library that freed the block, nothing is reported without one, and a
recording rendered under the probe (a render process with its llvmpipe thread) writes into no
freed block."""

import importlib.util
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux") or not (shutil.which("cc") or shutil.which("gcc")),
    reason="the heap probe is built with a C compiler, on Linux")

ROOT = Path(__file__).resolve().parents[1]
TOOL = ROOT / "tools" / "heapprobe" / "heapprobe.py"
# a tool of the repository, not an installed module: loaded from its file
_spec = importlib.util.spec_from_file_location("heapprobe", TOOL)
heapprobe = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(heapprobe)


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    return heapprobe.build(tmp_path_factory.mktemp("probe"))


def _run(probe, code: str, **env) -> subprocess.CompletedProcess:
    full = {**os.environ, "LD_PRELOAD": str(probe), "PYTHONPATH": str(ROOT),
            "PYOPENGL_PLATFORM": "egl", **env}
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, env=full, timeout=600)


# the signature of the render processes' crashes: a 4-byte zero at +8 of a freed block
WRITE_AFTER_FREE = """
    import ctypes
    libc = ctypes.CDLL(None)
    libc.malloc.restype = ctypes.c_void_p
    libc.malloc.argtypes = [ctypes.c_size_t]
    libc.free.argtypes = [ctypes.c_void_p]
    p = libc.malloc(112)
    ctypes.memset(p, 0x11, 112)
    libc.free(p)
    if {write}:
        ctypes.c_uint32.from_address(p + 8).value = 0
    for _ in range(10000):  # the block leaves the probe's ring and is checked
        libc.free(libc.malloc(64))
"""


def test_a_write_after_free_is_reported_with_its_bytes(probe):
    out = _run(probe, WRITE_AFTER_FREE.format(write=True))
    assert out.returncode == 0, out.stderr
    found = heapprobe.reports(out.stderr)
    assert len(found) == 1, out.stderr
    assert "bytes +8..+11 of a 120-byte block" in found[0]
    assert found[0].endswith(": 00000000")


def test_held_bytes_are_capped(probe):
    # three 512 KiB blocks freed after the planted write: with a 1 MiB cap the probe lets the
    # oldest blocks go (checked) at once, before the marker; without it, only at exit
    code = WRITE_AFTER_FREE.format(write=True).replace("range(10000)", "range(0)") + """
    for _ in range(3):
        libc.free(libc.malloc(512 * 1024))
    import sys
    print("MARK", file=sys.stderr, flush=True)
    """
    for cap, before in (("1048576", True), (None, False)):
        env = {"SYNTH_HEAPPROBE_MAX_HELD": cap} if cap else {}
        out = _run(probe, code, **env)
        assert out.returncode == 0, out.stderr
        lines = out.stderr.splitlines()
        found = [k for k, line in enumerate(lines) if line in heapprobe.reports(out.stderr)]
        assert len(found) == 1, out.stderr
        assert (found[0] < lines.index("MARK")) == before, out.stderr


def test_no_write_no_report(probe):
    out = _run(probe, WRITE_AFTER_FREE.format(write=False), SYNTH_HEAPPROBE_SUMMARY="1")
    assert out.returncode == 0, out.stderr
    assert heapprobe.reports(out.stderr) == []
    assert "synth heap probe: 0 writes after free reported" in out.stderr


def test_the_probe_changes_no_rendered_byte_and_sees_no_write_after_free(probe, tmp_path):
    # one render process's work in this process (workers=1) with one llvmpipe rasterizer
    # thread beside the GL thread (threads=1), as each of a recording's render processes
    code = f"""
        import sim, synth
        from synth.camera import CameraModel
        cam = CameraModel(width=160, height=128, center_px=(80.0, -500.0))
        traj = sim.simulate(sim.Scenario(theta0=0.03, duration=0.041))
        synth.render(traj, {str(tmp_path / "probed.zarr")!r},
                     scene=synth.SceneConfig(camera=cam), workers=1, threads=1)
    """
    out = _run(probe, code)
    assert out.returncode == 0, out.stderr
    assert heapprobe.reports(out.stderr) == []
    plain = subprocess.run([sys.executable, "-c", textwrap.dedent(code.replace(
        "probed.zarr", "plain.zarr"))], capture_output=True, text=True, timeout=600,
        env={k: v for k, v in {**os.environ, "PYTHONPATH": str(ROOT),
                                "PYOPENGL_PLATFORM": "egl"}.items() if k != "LD_PRELOAD"})
    assert plain.returncode == 0, plain.stderr
    import synth

    a = synth.open_recording(tmp_path / "probed.zarr")
    b = synth.open_recording(tmp_path / "plain.zarr")
    assert len(a) == len(b) == 42
    for i in range(len(a)):
        assert np.array_equal(a.frames[i], b.frames[i])


def test_cli_prints_the_library(tmp_path):
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path), "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, str(TOOL)], capture_output=True,
                         text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    lib = Path(out.stdout.strip())
    assert lib.parent == tmp_path / "synth" and lib.exists()
