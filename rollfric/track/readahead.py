"""Reading a recording one frame ahead of the locator, on a second thread.

The tracking loop (:func:`rollfric.track.tracker.track_recording`) reads each frame's region of
interest
around the ball's predicted centre. :class:`ReadAhead` reads the *next* frame's region, as far as
it can be predicted two frames ahead and grown by a margin, on one worker thread while the
locator works on the current frame: decoding (zstd) and a synthetic recording's sensor model
release the GIL, so the two overlap on a machine with two cores.

What the locator gets is unchanged: a region inside the one read ahead is sliced from it (a
FrameSource's ``read(i, roi)`` gives the same bytes as ``src[i][roi]``, the contract of
:mod:`rollfric.io.readers`); any other region, and every whole frame, is read when asked for. Every
read
of the source goes through the one worker thread, so a reader that is not thread-safe (a video,
a TIFF file handle) is never used by two threads at once. An error of a read that was asked for
is raised in the caller's thread; an error of a read ahead (its larger region may reach a chunk
the real region does not) is dropped and the region read again when asked for, so the caller
sees exactly the errors of plain reads.
"""

from __future__ import annotations

import concurrent.futures

import numpy as np


class ReadAhead:
    """A RegionSource's regions read on one worker thread, one frame ahead.

    Parameters
    ----------
    source : RegionSource
        The recording (it has ``read(i, roi)``; :mod:`rollfric.io.readers`).

    Attributes
    ----------
    hits, misses : int
        Region reads served from the region read ahead / read when asked for.

    Notes
    -----
    Use it as a context manager (or call :meth:`close`): the worker thread ends with it, after
    its current read (a read ahead not begun is cancelled).
    """

    def __init__(self, source) -> None:
        self._source = source
        self._shape = tuple(source.shape[1:])
        self._pool = concurrent.futures.ThreadPoolExecutor(
            max_workers=1, thread_name_prefix="rollfric-read-ahead")
        self._ahead: dict = {}  # frame -> ((y0, y1, x0, x1), future), the last two frames
        self.hits = 0
        self.misses = 0

    def __enter__(self) -> ReadAhead:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """End the worker thread (after its current read; a read ahead not begun is dropped)."""
        self._ahead = {}
        self._pool.shutdown(wait=True, cancel_futures=True)

    def _call(self, fn, *args):
        return self._pool.submit(fn, *args).result()

    def prefetch(self, i: int, box) -> None:
        """Start reading region ``box`` of frame ``i`` (clipped to the frame). The regions read
        ahead for frames ``i - 1`` and ``i`` are kept, those of earlier frames dropped.

        Parameters
        ----------
        i : int
            Frame index (one out of range is ignored).
        box : tuple of int
            (y0, y1, x0, x1), may reach outside the frame.
        """
        h, w = self._shape
        y0, y1, x0, x1 = (int(v) for v in box)
        y0, y1, x0, x1 = max(0, y0), min(h, y1), max(0, x0), min(w, x1)
        for j in [j for j in self._ahead if j < i - 1]:
            del self._ahead[j]
        if not (0 <= i < len(self._source)) or y1 <= y0 or x1 <= x0:
            return
        box = (y0, y1, x0, x1)
        self._ahead[i] = (box, self._pool.submit(self._source.read, i, box))

    def read(self, i: int, roi) -> np.ndarray:
        """Region ``roi`` = (y0, y1, x0, x1) of frame ``i``: the bytes of
        ``source.read(i, roi)``, sliced from the region read ahead when it holds it.

        Parameters
        ----------
        i : int
            Frame index.
        roi : tuple of int
            (y0, y1, x0, x1).

        Returns
        -------
        numpy.ndarray
            (y1 - y0, x1 - x0), the frames' dtype.
        """
        ahead = self._ahead.get(i)
        if ahead is not None:
            b = ahead[0]
            y0, y1, x0, x1 = roi
            if b[0] <= y0 and y1 <= b[1] and b[2] <= x0 and x1 <= b[3] \
                    and y0 < y1 and x0 < x1:
                try:
                    data = ahead[1].result()
                except Exception:  # the larger region's error: read the region itself below
                    data = None
                if data is not None:
                    self.hits += 1
                    return np.ascontiguousarray(data[y0 - b[0]:y1 - b[0], x0 - b[2]:x1 - b[2]])
        self.misses += 1
        return self._call(self._source.read, i, roi)

    def frame(self, i: int) -> np.ndarray:
        """The whole frame ``i`` (``source[i]``, read on the worker thread).

        Parameters
        ----------
        i : int
            Frame index.

        Returns
        -------
        numpy.ndarray
            (H, W).
        """
        return self._call(self._source.__getitem__, i)
