"""A heap probe: a library loaded with ``LD_PRELOAD`` that reports writes into heap memory
after it was freed (issue 16: synth's render processes dying in glibc's malloc). A diagnostic
tool of the repository, not part of the installed packages.

The probe (``heapprobe.c`` beside this file, built here with the machine's C compiler) holds
every freed block of up to ``SYNTH_HEAPPROBE_MAX_BYTES`` (1 MiB) back from malloc for the next
``SYNTH_HEAPPROBE_BLOCKS`` (4096) frees (fewer while it holds more than
``SYNTH_HEAPPROBE_MAX_HELD``, 256 MiB), its first 256 bytes filled with 0xA5, and checks them
when it lets the block go (and at exit): a changed byte was written after the free, and a line
starting with :data:`PREFIX` on stderr says which bytes, their new values, the block's size
and the library (with offset) and thread that freed it. glibc itself notices such a write
only when it next walks that chunk's bin, long after and only in some bins; the probe catches
it on every free within its window. The program's results are unchanged (same bytes).

Usage (Linux, a C compiler)::

    LD_PRELOAD=$(python tools/heapprobe/heapprobe.py) rollfric render ...

(the render processes inherit it), then look for ``synth heap probe:`` on stderr.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

SOURCE = Path(__file__).with_name("heapprobe.c")
PREFIX = "synth heap probe:"


class ProbeError(RuntimeError):
    """The probe cannot be built here."""


def _cache_folder() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "synth"


def build(folder=None) -> Path:
    """The probe as a shared library, compiled once per source version (kept in ``folder``,
    default ``$XDG_CACHE_HOME/synth`` or ``~/.cache/synth``).

    Parameters
    ----------
    folder : path-like, optional
        Where to keep the library.

    Returns
    -------
    pathlib.Path
        The library, to be named in ``LD_PRELOAD``.

    Raises
    ------
    ProbeError
        Not on Linux, no C compiler (``cc``/``gcc``), or the compile failed.
    """
    if not sys.platform.startswith("linux"):
        raise ProbeError("the heap probe works on Linux (glibc) only")
    source = SOURCE.read_bytes()
    digest = hashlib.sha256(source).hexdigest()[:16]
    folder = Path(folder) if folder is not None else _cache_folder()
    lib = folder / f"heapprobe-{digest}.so"
    if lib.exists():
        return lib
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise ProbeError("the heap probe needs a C compiler (cc or gcc) to be built")
    folder.mkdir(parents=True, exist_ok=True)
    tmp = lib.with_suffix(f".{os.getpid()}.tmp")
    run = subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(tmp), str(SOURCE), "-ldl"],
                         capture_output=True, text=True)
    if run.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise ProbeError(f"the heap probe did not compile: {run.stderr.strip()}")
    os.replace(tmp, lib)
    return lib


def reports(stderr: str) -> list[str]:
    """The probe's reports (writes after free) among a process's stderr lines.

    Parameters
    ----------
    stderr : str
        What the process wrote to stderr.

    Returns
    -------
    list of str
        The lines starting with :data:`PREFIX` that report a write.
    """
    return [line for line in stderr.splitlines()
            if line.startswith(PREFIX) and "written after it was freed" in line]


def main(argv=None) -> int:
    """``python tools/heapprobe/heapprobe.py``: build the probe and print its path (exit 2 if it
    cannot be built)."""
    try:
        print(build())
    except (ProbeError, OSError) as exc:
        print(f"heapprobe: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
