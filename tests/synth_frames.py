"""Shared helpers of the synth tests: frames rendered for geometry checks."""

from __future__ import annotations

import math

from synth.backends.raster import SceneRenderer
from synth.config import SceneConfig


def flat_ring_render(cam, r_ball: float, r_cyl: float):
    """A full ring trough (opening pi, no shadows, 2 x 2 supersampled) rendered unlit by
    ``cam``: paper white backdrop, dark anodised face. Returns (image in [0, 1], config)."""
    import pyrender

    cfg = SceneConfig(camera=cam, trough_opening=math.pi, supersample=2, shadows=False)
    sr = SceneRenderer(cfg, r_ball, r_cyl)
    try:
        sr.flags = pyrender.RenderFlags.FLAT
        return sr.render_full().astype(float) / sr.scale, cfg
    finally:
        sr.close()
