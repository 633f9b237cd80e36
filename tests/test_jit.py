"""rollfric.jit.njit: numba's on-disk cache where a cache directory is writable, and the same
kernel compiled without it (no error at import) where none is."""

import logging

import numba.core.caching as caching
import numpy as np
import pytest

from rollfric import jit
from rollfric.locate.kernels import circle as kernels


def _weighted_sum(x, w):
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * w[i]
    return s


def test_kernels_are_cached_where_a_cache_directory_is_writable():
    # this checkout's __pycache__ (or the user's cache folder) is writable
    f = jit.njit(_weighted_sum, nogil=True)
    assert type(f._cache).__name__ == "FunctionCache"
    assert f(np.arange(4.0), np.ones(4)) == 6.0
    # the locator's kernels are built this way
    assert type(kernels.fit_circle._cache).__name__ == "FunctionCache"
    assert kernels.fit_circle.targetoptions.get("nogil") is True


def test_without_a_writable_cache_directory_the_kernel_is_compiled_in_the_process(
        monkeypatch, caplog):
    # numba finds no cache locator (a read-only install, no writable home): its own
    # decorator raises at import
    monkeypatch.setattr(caching.CacheImpl, "_locator_classes", [])
    monkeypatch.setattr(caching.config, "CACHE_LOCATOR_CLASSES", None, raising=False)
    monkeypatch.setattr(jit, "_warned", [])
    with pytest.raises(RuntimeError, match="cannot cache"):
        import numba

        numba.njit(cache=True)(_weighted_sum)
    with caplog.at_level(logging.DEBUG, logger="rollfric.jit"):
        f = jit.njit(nogil=True)(_weighted_sum)
        g = jit.njit(_weighted_sum)
    assert type(f._cache).__name__ == "NullCache" and f.targetoptions.get("nogil") is True
    x, w = np.linspace(-1.0, 2.0, 7), np.linspace(3.0, 0.5, 7)
    assert f(x, w) == g(x, w) == _weighted_sum(x, w)
    # said once per module, at debug level
    msgs = [r.getMessage() for r in caplog.records if r.name == "rollfric.jit"]
    assert len(msgs) == 1 and "NUMBA_CACHE_DIR" in msgs[0]
    assert all(r.levelno == logging.DEBUG for r in caplog.records if r.name == "rollfric.jit")
    # announced as compiled in every run, not as cached from the next one
    h = jit.njit(_weighted_sum)
    monkeypatch.setattr(jit, "_kernels", [h])
    with caplog.at_level(logging.INFO, logger="rollfric.jit"):
        caplog.clear()
        assert jit.announce(__name__, "the test's kernel", "about a second")
    msg = caplog.records[-1].getMessage()
    assert "in every run" in msg and "NUMBA_CACHE_DIR" in msg and "first run" not in msg


_COLD_SCRIPT = """
import logging, sys
sys.path.insert(0, sys.argv[1])
logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
import coldmod
from rollfric import jit
jit.announce("coldmod", "the test's kernel", "about a second")
print(coldmod.add(1.0, 2.0), len(jit.cold(jit.kernels("coldmod"))))
"""


def test_a_cold_cache_is_announced_before_compiling_and_a_warm_one_is_not(tmp_path):
    import os
    import subprocess
    import sys

    (tmp_path / "coldmod.py").write_text(
        "from rollfric.jit import njit\n\n\n@njit\ndef add(a, b):\n    return a + b\n")
    # a fresh numba cache folder (numba takes NUMBA_CACHE_DIR before the module's __pycache__)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join(sys.path)}

    def run():
        return subprocess.run([sys.executable, "-c", _COLD_SCRIPT, str(tmp_path)], env=env,
                              capture_output=True, text=True, check=True)

    first = run()
    assert "rollfric.jit: compiling the test's kernel (1 numba kernels) on this first run: " \
           "about a second" in first.stderr
    assert first.stdout.split() == ["3.0", "0"]  # compiled: no longer cold in the process
    second = run()  # loaded from the cache the first run wrote
    assert "compiling" not in second.stderr and second.stdout.split() == ["3.0", "0"]


def test_the_locators_kernels_are_cold_in_a_fresh_cache_folder(tmp_path):
    import os
    import subprocess
    import sys

    code = ("from rollfric import jit; from rollfric.locate.kernels import circle as kernels; "
            "k = jit.kernels('rollfric.locate.kernels'); "
            "print(len(k), len(jit.cold(k)), kernels.fit_circle in k)")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join(sys.path)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    assert int(out[0]) >= 20 and out[1] == out[0] and out[2] == "True"


def test_the_progress_bars_clock_restarts_after_a_compilation():
    import io

    import numba
    from tqdm import tqdm

    bar = tqdm(total=100, file=io.StringIO(), mininterval=0)
    bar.update(3)
    bar.start_t -= 100.0  # as if the first frames had waited 100 s for the compiler
    clock = jit.CompileClock()
    assert not clock.restart(bar)  # nothing compiled
    with clock:
        f = numba.njit(lambda a: a * 2.0)
        assert f(1.5) == 3.0
    assert clock.compiled == 1 and clock.seconds > 0
    assert clock.restart(bar)
    # the count kept, the clock from now: no longer 100 s for 3 frames
    assert bar.n == 3 and bar.format_dict["elapsed"] < 50.0
    assert not clock.restart(bar)  # once per compilation
    # the rate counts the frames after the restart only (none yet: no rate, no ETA of days)
    assert bar.format_dict["initial"] == 3 and bar.format_dict["rate"] is None
    bar.update(2)
    assert bar.n == 5
    bar.close()
    off = tqdm(total=10, disable=True)
    with clock:
        assert numba.njit(lambda a: a + 1.0)(1.0) == 2.0
    assert clock.restart(off)  # a bar without display: nothing to restart, no error


_PKG_SCRIPT = """
import sys
sys.path.insert(0, sys.argv[1])
import stamped
print(stamped.caller.twice(1.0))
"""


def test_a_kernels_cache_is_renewed_when_a_kernel_it_calls_from_another_module_changes(
        tmp_path):
    import os
    import subprocess
    import sys

    # a package of two modules: caller's kernel calls callee's, and numba compiles callee's
    # code into caller's cache, which only caller.py's own stamp would renew
    pkg = tmp_path / "stamped"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from rollfric import jit\nfrom stamped import callee, "
                                     "caller\n\njit.share_source_stamp(__name__)\n")
    (pkg / "callee.py").write_text("from rollfric.jit import njit\n\n\n@njit\ndef one():\n"
                                   "    return 1.0\n")
    (pkg / "caller.py").write_text("from rollfric.jit import njit\nfrom stamped.callee import "
                                   "one\n\n\n@njit\ndef twice(x):\n    return 2.0 * x * one()\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join(sys.path)}

    def run():
        return subprocess.run([sys.executable, "-c", _PKG_SCRIPT, str(tmp_path)], env=env,
                              capture_output=True, text=True, check=True).stdout.split()

    assert run() == ["2.0"]
    assert list((tmp_path / "cache").rglob("*.nbi"))  # cached
    # the callee changes (its size too: the stamp holds even where file times are coarse)
    (pkg / "callee.py").write_text("from rollfric.jit import njit\n\n\n@njit\ndef one():\n"
                                   "    return 5.25\n")
    assert run() == ["10.5"]


def test_the_locators_kernels_share_one_stamp():
    from pathlib import Path

    from rollfric.locate import kernels as package

    files = list(Path(package.__file__).parent.glob("*.py"))
    stamp = (max(f.stat().st_mtime for f in files), sum(f.stat().st_size for f in files))
    ks = jit.kernels("rollfric.locate.kernels")
    assert len(ks) >= 20
    assert all(k._cache._cache_file._source_stamp == stamp for k in ks)
