"""A recording whose frames are moved back by the camera's measured shift, so that the ball is
located against a background that matches the static scene in every frame.

Moving only the located centres back (:func:`rollfric.track.camera_motion.correct_for_motion`)
leaves the ball located against a background whose trough wall sits where the moved frame's
does not: the wall's edge beside the ball pulls the centres by a few hundredths of a px, more
the further the camera went (a 2 px drift of the fault study: mu +0.5 %, 4 U). Here each
frame is shifted back by bilinear interpolation, which moves an edge's centroid by exactly the
shift (higher orders ring: bicubic and Lanczos left mu 0.2-0.4 % off on that drift).
"""

from __future__ import annotations

import cv2
import numpy as np

from rollfric.io.source import BaseSource


class SteadiedSource(BaseSource):
    """``source``'s frames moved back by ``shifts`` ((T, 2) px, dx right, dy down: where the
    static scene of each frame lies against the background's), rounded to the frames' type.

    The recording's timestamps, frame rate, bit depth and attributes are the source's.
    """

    def __init__(self, source, shifts) -> None:
        super().__init__(getattr(source, "name", "recording"), len(source), source.shape[1:],
                         source.dtype)
        self.source = source
        self.shifts = np.asarray(shifts, dtype=float).reshape(len(source), 2)
        for name in ("fps", "timestamps", "background", "bit_depth_stated", "attrs"):
            if hasattr(source, name):
                setattr(self, name, getattr(source, name))
        self._bit_depth_data = getattr(source, "_bit_depth_data", None)
        self.concurrent_reads = bool(getattr(source, "concurrent_reads", False))

    def __getitem__(self, i):
        i = self._index(i)
        return self._moved(self.source[i], *self.shifts[i], 0, 0)

    def _read_roi(self, i, y0, y1, x0, x1):
        # the region grown by the shift (and the interpolation's pixel) read and moved: the
        # same bytes as the whole frame moved, cropped
        dx, dy = self.shifts[i]
        pad = int(np.ceil(max(abs(dx), abs(dy)))) + 2
        h, w = self.shape[1:]
        ya, yb, xa, xb = max(0, y0 - pad), min(h, y1 + pad), max(0, x0 - pad), min(w, x1 + pad)
        read = getattr(self.source, "read", None)
        tile = read(i, (ya, yb, xa, xb)) if read is not None else \
            self.source[i][ya:yb, xa:xb]
        return self._moved(tile, dx, dy, xa, ya)[y0 - ya:y1 - ya, x0 - xa:x1 - xa]

    @staticmethod
    def _moved(img, dx: float, dy: float, xa: int, ya: int):
        """``img`` (the frame's region from (xa, ya)) moved back by (dx, dy), the frame's
        edge pixels repeated beyond it."""
        if dx == 0.0 and dy == 0.0:
            return img
        h, w = img.shape
        m = np.float32([[1.0, 0.0, -dx], [0.0, 1.0, -dy]])
        moved = cv2.warpAffine(img.astype(np.float32), m, (w, h), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
        if np.issubdtype(img.dtype, np.integer):
            info = np.iinfo(img.dtype)
            return np.clip(np.rint(moved), info.min, info.max).astype(img.dtype)
        return moved.astype(img.dtype)
