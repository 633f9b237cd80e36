"""rollfric.jit.njit: numba's on-disk cache where a cache directory is writable, and the same
kernel compiled without it (no error at import) where none is."""

import logging

import numba.core.caching as caching
import numpy as np
import pytest

from rollfric import jit
from rollfric.locate import kernels


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
    assert type(kernels._fit_circle._cache).__name__ == "FunctionCache"
    assert kernels._fit_circle.targetoptions.get("nogil") is True


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
