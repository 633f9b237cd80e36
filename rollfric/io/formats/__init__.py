"""Readers of high-speed camera files: Phantom ``.cine`` (:mod:`rollfric.io.formats.cine`) and
Photron ``.cih``/``.cihx`` + ``.mraw`` (:mod:`rollfric.io.formats.photron`).

Each gives a FrameSource (see :mod:`rollfric.io.readers`, which dispatches to them) with the file's
frame rate (``fps``), its per-frame times when it has them (``timestamps``, seconds from the
first frame) and region reads through ``numpy.memmap`` (a region of interest reads only its
own bytes, not the whole frame).
"""
