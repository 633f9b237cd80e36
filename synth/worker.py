"""What a render process does: its backend (:mod:`synth.backends`), made once at its start,
and the tasks the pipeline hands it: the ball-free frame, a warm-up frame, batches of frames
written straight into the recording's chunk files (:func:`synth.chunks.chunk_writer_at`), bent
by the lens (:mod:`synth.distortion`) or blurred by a thin lens (:mod:`synth.defocus`) where
the scene has one. A process's state is the module's ``_W``; :mod:`synth.pool` starts the
processes and runs the tasks.
"""

from __future__ import annotations

import os
import time

import numpy as np

from synth.backends import make_backend
from synth.chunks import chunk_writer_at, writer_layout
from synth.config import SceneConfig
from synth.defocus import Defocus
from synth.distortion import cached_window, distort_tile
from synth.pool import crash_report

_W: dict = {}  # this render process's backend, store and background


def init(scene_dict, ball_radius, cylinder_radius, store_path, threads, oval=(0.0, 0.0),
                 seed=0, defocus=None):
    start(scene_dict, ball_radius, cylinder_radius, threads, oval, seed)
    open_store(store_path, defocus)


def start(scene_dict, ball_radius, cylinder_radius, threads, oval=(0.0, 0.0), seed=0):
    """A render process's renderer (its imports, EGL context, programs and meshes): what needs
    no store, so the processes can start while the main process renders the background."""
    crash_report()
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    cfg = SceneConfig.from_dict(scene_dict)
    _W["cfg"] = cfg
    _W["ball_radius"] = ball_radius
    _W["renderer"] = make_backend(cfg, ball_radius, cylinder_radius, seed, threads, oval)


def background():
    """The background (the scene without the ball, a plain render of the full frame) drawn
    by this render process's renderer, so that the main process need not import pyrender
    and trimesh nor make a renderer of its own: (levels as the smallest unsigned dtype that
    holds ``scale``, scale)."""
    sr = _W["renderer"]
    bg = sr.render_full()
    return bg.astype(np.uint16 if sr.scale <= 65535 else np.uint32), int(sr.scale)


def warm(centres) -> None:
    """Draw the tiles of a frame with the ball at ``centres`` and drop them: a render
    process's first frame sets up what every later one uses (the trough's cached shadow maps,
    the lean draw path, the static layer's blocks; ~0.25 s), done while it waits for the
    background. The frames it draws later are the same bytes."""
    sr = _W["renderer"]
    tiles = sr.tiles_for(centres)
    if tiles:
        sr.render_tiles([sr.ball_pose(c) for c in centres], tiles)


def open_store(store_path, defocus=None, spec=None):
    """The recording's store in a render process: its chunk writer and background, read
    through zarr, or from ``spec`` = (:func:`synth.chunks.writer_layout`, the background's
    ``.npy`` file) without it (the processes of :func:`synth.pool.early_pool`, whose fork
    server imports no zarr)."""
    cfg = _W["cfg"]
    lens = cfg.camera.lens
    _W["defocus"] = None
    if defocus is not None:  # (face, bore, sharp background) of the ideal frame
        face, bore, sharp = defocus
        _W["defocus"] = (Defocus(cfg.replace(camera=cfg.camera.ideal()), face, bore,
                                 _W["ball_radius"]), np.asarray(sharp, dtype=np.int64))
    if spec is None:
        import zarr  # ~0.16 s of imports: only a process not started by an early pool

        g = zarr.open_group(store_path, mode="r+")
        layout = writer_layout(g, g["clean_diff"])
        bg = g["background_ideal_clean" if lens is not None else "background_clean"][...]
    else:
        layout, bg = spec[0], np.load(spec[1])
    _W["write"] = chunk_writer_at(layout)
    _W["lens"] = None
    if lens is not None:
        _W["lens"] = (lens, cached_window(lens, cfg.camera.width, cfg.camera.height),
                      (cfg.camera.height, cfg.camera.width))
    _W["bg"] = np.asarray(bg, dtype=np.int64)
    _W["renderer"].set_background(_W["bg"])  # Mitsuba: unchanged pixels from it
    _W["store"] = store_path


def batch_in(store_path, spec, indices, centres):
    """:func:`batch` in a process started by :func:`start`: the store is opened
    at its first batch (it is written after the processes start; ``spec``: see
    :func:`open_store`). Returns (frames, (first index, process id, start, end)), the times
    by ``time.time()`` (the recording's schedule, :func:`synth.pipeline.render`'s ``stats``)."""
    t0 = time.time()
    if _W.get("store") != store_path:
        open_store(store_path, spec=spec)
    n = batch(indices, centres)
    return n, (int(indices[0]), os.getpid(), t0, time.time())


def batch(indices, centres):
    sr = _W["renderer"]
    write = _W["write"]
    bg = _W["bg"]
    k = centres.shape[1]
    lens = _W.get("lens")
    dfc = _W.get("defocus")
    batch_tiles = sr.tiles_for_many(list(centres))  # the batch's footprints at once
    for n, i in enumerate(indices):
        poses = [sr.ball_pose(c) for c in centres[n]]
        tiles = batch_tiles[n]
        patches = []
        if tiles and dfc is not None:  # rendered wider, blurred and cut back (synth.defocus)
            regions = dfc[0].render_frame(sr, poses, centres[n], tiles, dfc[1], index=int(i))
            tiles = [box for box, _ in regions]
            rendered = [np.rint(img).astype(np.int64) for _, img in regions]
        elif tiles:
            rendered = sr.render_tiles(poses, tiles, index=int(i))
        if tiles and lens is None:
            patches = [((x0, y0, w, h), img.astype(np.int64) - k * bg[y0:y0 + h, x0:x0 + w])
                       for (x0, y0, w, h), img in zip(tiles, rendered, strict=True)]
        elif tiles:
            patches = _through_lens(tiles, rendered, bg, k, lens)
        write(int(i), patches)
    return len(indices)


def _through_lens(tiles, rendered, bg, k, lens) -> list:
    """The ideal tiles' difference from the background, bent by the lens: [(box, values)]."""
    lens_, win, shape = lens
    x0 = min(t[0] for t in tiles)
    y0 = min(t[1] for t in tiles)
    x1 = max(t[0] + t[2] for t in tiles)
    y1 = max(t[1] + t[3] for t in tiles)
    canvas = np.zeros((y1 - y0, x1 - x0), dtype=np.float64)
    for (tx, ty, w, h), img in zip(tiles, rendered, strict=True):
        canvas[ty - y0:ty - y0 + h, tx - x0:tx - x0 + w] = \
            img.astype(np.int64) - k * bg[ty:ty + h, tx:tx + w]
    bent = distort_tile(canvas, (x0, y0, x1 - x0, y1 - y0), win, lens_, shape)
    if bent is None:
        return []
    box, vals = bent
    return [(box, np.rint(vals).astype(np.int64))]


def close() -> None:
    """Close this process's backend and forget its state (a render in the main process)."""
    _W.pop("renderer").close()
    _W.clear()
