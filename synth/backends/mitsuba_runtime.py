"""Mitsuba 3 in this process, for the path-traced backend (:mod:`synth.backends.pathtrace`):
its import (found where installed: the extra ``rollfric[mitsuba]``), its variant (Dr.Jit's LLVM
JIT, ``llvm_ad_rgb``, with synth's integrator :mod:`synth.backends.rim_path`; else the
``scalar_rgb`` fallback with Mitsuba's own path tracer) and its CPU threads.
"""

from __future__ import annotations

import logging
import os
import sys

from synth.config import SynthError

VARIANT = "llvm_ad_rgb"
FALLBACK = "scalar_rgb"  # when Dr.Jit's LLVM backend cannot start (no LLVM >= 16)
VARIANT_ENV = "ROLLFRIC_MITSUBA_VARIANT"  # forces one of the two (e.g. to test the fallback)

_STATE: dict = {}
log = logging.getLogger(__name__)


def available() -> str | None:
    """Why the Mitsuba backend cannot run here, or None when it can.

    Returns
    -------
    str or None
        A sentence naming what is missing (Mitsuba 3, or an LLVM >= 16 for Dr.Jit's CPU JIT:
        ``DRJIT_LIBLLVM_PATH`` pointing at e.g. Debian's libllvm19), None when it works.
    """
    try:
        load()
    except SynthError as exc:
        return str(exc)
    return None


def find_llvm() -> str | None:
    """The newest libLLVM >= 16 in the usual places (Debian's libllvmNN, llvm.org's packages),
    for Dr.Jit when ``DRJIT_LIBLLVM_PATH`` is not set.

    Returns
    -------
    str or None
    """
    import glob
    import re

    best = None
    for pattern in ("/usr/lib/x86_64-linux-gnu/libLLVM-*.so", "/usr/lib/aarch64-linux-gnu/"
                    "libLLVM-*.so", "/usr/lib/llvm-*/lib/libLLVM*.so", "/usr/lib/libLLVM-*.so"):
        for path in glob.glob(pattern):
            m = re.search(r"(?:libLLVM-|llvm-)(\d+)", path)
            if m and int(m.group(1)) >= 16 and (best is None or int(m.group(1)) > best[0]):
                best = (int(m.group(1)), path)
    return best[1] if best else None


def variant() -> str:
    """The Mitsuba variant this process renders with (:func:`load` chooses it).

    Returns
    -------
    str
        ``llvm_ad_rgb`` (Dr.Jit's CPU JIT, synth's own path tracer), or ``scalar_rgb`` (the
        fallback: Mitsuba's ``path`` integrator in C++ threads, caustics of the ball on the
        trough and backdrop included).
    """
    load()
    return _STATE["variant"]


def load():
    """Import Mitsuba, select its variant and register :class:`RimPath` (once a process).

    ``llvm_ad_rgb`` when Dr.Jit's LLVM backend starts (LLVM >= 16), else ``scalar_rgb`` with a
    warning naming what is missing; the environment variable ``ROLLFRIC_MITSUBA_VARIANT``
    (``llvm_ad_rgb`` or ``scalar_rgb``) forces one.

    Returns
    -------
    module
        The ``mitsuba`` module.

    Raises
    ------
    SynthError
        Mitsuba is not installed, ``ROLLFRIC_MITSUBA_VARIANT`` names another variant, or it
        forces ``llvm_ad_rgb`` where Dr.Jit has no usable LLVM (Debian 12's default LLVM 15
        fails to compile its kernels).
    """
    if "mi" in _STATE:
        return _STATE["mi"]
    forced = os.environ.get(VARIANT_ENV, "").strip()
    if forced not in ("", VARIANT, FALLBACK):
        raise SynthError(f"{VARIANT_ENV}={forced!r}: must be {VARIANT} or {FALLBACK}")
    if "DRJIT_LIBLLVM_PATH" not in os.environ and "drjit" not in sys.modules:
        found = find_llvm()
        if found:
            os.environ["DRJIT_LIBLLVM_PATH"] = found
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError:
        raise SynthError("render.renderer = \"mitsuba\" needs Mitsuba 3: pip install "
                         "\"rollfric[mitsuba]\"") from None
    chosen = forced or VARIANT
    if chosen == VARIANT:
        problem = _llvm_problem(dr)
        if problem and forced:
            raise SynthError(f"{VARIANT_ENV}={VARIANT}: {problem}")
        if problem:
            log.warning("Mitsuba's %s variant cannot start: %s. Rendering with %s instead: "
                        "Mitsuba's own path tracer in C++ threads, several times slower, with "
                        "the ball's caustics on the trough and backdrop (rare bright pixels)",
                        VARIANT, problem, FALLBACK)
            chosen = FALLBACK
    mi.set_variant(chosen)
    if chosen == VARIANT:
        mi.register_integrator("synth_rim_path", lambda props: _rim_path_class()(props))
    _STATE["variant"] = chosen
    _STATE["mi"] = mi
    return mi


def _llvm_problem(dr) -> str | None:
    """Why Dr.Jit's LLVM backend cannot run here (None when it can)."""
    hint = ("Dr.Jit's CPU backend needs LLVM >= 16 (Debian: apt-get install libllvm19; "
            "then DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so)")
    if not dr.has_backend(dr.JitBackend.LLVM):
        return f"no LLVM library found ({hint})"
    version = tuple(dr.detail.llvm_version())
    if version < (16,):
        return (f"LLVM {'.'.join(map(str, version))} found "
                f"(DRJIT_LIBLLVM_PATH={os.environ.get('DRJIT_LIBLLVM_PATH', '')!r}; {hint})")
    return None


def _rim_path_class():
    """The :class:`synth.backends.rim_path.RimPath` class (importable once a variant is set)."""
    from synth.backends.rim_path import RimPath

    return RimPath


def set_threads(n: int) -> None:
    """Use ``n`` CPU threads for Dr.Jit's kernels in this process.

    Parameters
    ----------
    n : int
        Thread count (>= 1).
    """
    load()
    import drjit as dr

    dr.set_thread_count(int(n))
