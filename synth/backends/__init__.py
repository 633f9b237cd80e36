"""synth's renderer backends: siblings behind one protocol (:class:`Backend`), picked by name.

- ``pyrender`` (:mod:`synth.backends.raster`): rasterised by pyrender on llvmpipe, drawn
  after its first frame by synth's lean GL path (:mod:`synth.backends.lean`, with the shaders of
  :mod:`synth.backends.shaders`);
- ``mitsuba`` (:mod:`synth.backends.pathtrace`): path traced by Mitsuba 3 on the CPU (the
  integrator :mod:`synth.backends.rim_path`; Mitsuba's import and variant:
  :mod:`synth.backends.mitsuba_runtime`).

Both build the same scene (:mod:`synth.backends.scene_model`) and render, per frame, only the
pixels the ball and its shadows can change (:mod:`synth.backends.footprint`). Importing this
package loads neither pyrender, OpenGL nor Mitsuba: a backend imports them when it is made.
"""

from __future__ import annotations

import os
from typing import Protocol, runtime_checkable

import numpy as np

from synth.backends import mitsuba_runtime, pathtrace, raster
from synth.config import SceneConfig


@runtime_checkable
class Backend(Protocol):
    """What the render pipeline (:mod:`synth.pipeline`) asks of a renderer backend, one per
    process, for the scene's ideal (lens-free) camera."""

    scale: int  # the level of white of one rendered sub-frame

    def render_full(self) -> np.ndarray:
        """The ball-free frame, (H, W) integer levels."""

    def ball_pose(self, centre) -> np.ndarray:
        """What :meth:`render_tiles` takes for the ball at ``centre`` (m)."""

    def tiles_for(self, centres: np.ndarray) -> list:
        """The tiles (x0, y0, w, h) holding every pixel the ball at ``centres`` (K, 3: one
        per sub-frame) changes."""

    def tiles_for_many(self, frames) -> list:
        """:meth:`tiles_for` of several frames' centres, in order."""

    def render_tiles(self, poses, tiles, index: int = 0) -> list[np.ndarray]:
        """Per tile, the sum over the sub-frames' ``poses`` of its rendered levels; ``index``:
        the frame's number (a path tracer seeds its samples with it)."""

    def set_background(self, levels) -> None:
        """The ball-free frame's levels, for pixels a backend need not render again."""

    def close(self) -> None:
        """Free the backend's resources."""


def make_backend(scene: SceneConfig, ball_radius: float, cylinder_radius: float,
                 seed: int = 0, threads: int | None = None, oval=(0.0, 0.0)) -> Backend:
    """The backend ``scene.renderer`` names (one of :data:`synth.config.RENDERERS`), for the
    scene's ideal (lens-free) camera.

    Parameters
    ----------
    scene : SceneConfig
        The scene (its camera's lens is applied to the renders afterwards, by
        synth.distortion).
    ball_radius, cylinder_radius : float
        Sizes (m).
    seed : int, optional
        The recording's seed (Mitsuba's sample streams; pyrender draws no random numbers).
    threads : int, optional
        CPU threads of the backend (llvmpipe's or Dr.Jit's).
    oval : tuple, optional
        The bore's (ovality, ovality_angle) (sim.section; (0, 0): round).

    Returns
    -------
    Backend
        A :class:`synth.backends.raster.SceneRenderer` or
        :class:`synth.backends.pathtrace.MitsubaRenderer`.
    """
    ideal = scene.replace(camera=scene.camera.ideal())
    if scene.renderer == "mitsuba":
        if threads:
            mitsuba_runtime.set_threads(threads)
        return pathtrace.MitsubaRenderer(ideal, ball_radius, cylinder_radius, *oval, seed=seed)
    if threads:
        os.environ["LP_NUM_THREADS"] = str(threads)  # read when llvmpipe starts
    return raster.SceneRenderer(ideal, ball_radius, cylinder_radius, *oval)


__all__ = ["Backend", "make_backend"]
