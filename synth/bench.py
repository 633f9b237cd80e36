"""Benchmarks of the synth renderer (called by ``rollfric bench``; also ``python -m synth.bench``).

Compares, side by side in one run on the same scene: the plain pyrender full-frame render (the
"stock" way: one OffscreenRenderer.render of the whole 1280 x 1024 frame with the ball, with
pyrender's own shaders) and synth's renderer (static background once, then only the ball's and
shadows' tiles, shadow maps once per frame, the shadow filter read with gathers); the largest
difference between the two in 8-bit DN; the throughput of a whole recording with both cores;
the size of the store.

Stock pyrender 0.1.45 cannot be installed beside the fork (both are the ``pyrender`` module, and
0.1.45 breaks under NumPy 2), so the baseline is the same library's plain full-frame render.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def _dir_size(path: Path) -> int:
    """Bytes in the files of a directory tree."""
    return sum(f.stat().st_size for f in Path(path).rglob("*") if f.is_file())


def _disk_usage(path: Path) -> int:
    """Bytes the tree occupies on disk (allocated blocks, directories included), like du."""
    paths = [Path(path), *Path(path).rglob("*")]
    return sum(p.stat().st_blocks * 512 for p in paths)


def render_benchmark(quick: bool = True, *, workers: int = 2, seconds: float | None = None,
                     scene=None) -> dict:
    """Measure ms/frame (plain full frame vs synth tiles), max DN difference, sequence fps with
    ``workers`` processes, and the recording size. quick: 3 full frames, 30 tile frames and a
    300-frame sequence (size extrapolated to 4000 frames); otherwise 6, 100 and 4000."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    import sim
    import synth
    from synth.pipeline import _versions
    from synth.scene import SceneRenderer

    scene = scene or synth.SceneConfig()
    n_full, n_tile, n_seq = (3, 30, 300) if quick else (6, 100, 4000)
    seconds = seconds if seconds is not None else n_seq / 1000.0
    traj = sim.simulate(sim.Scenario(duration=max(seconds, (n_tile - 1) / 1000.0)))
    setup = traj.setup()
    sr = SceneRenderer(scene, setup.ball_radius, setup.cylinder_radius)
    try:
        t0 = time.perf_counter()
        bg = sr.render_full()
        t_bg = time.perf_counter() - t0
        idx_full = np.linspace(0, len(traj) - 1, n_full).round().astype(int)
        idx_tile = np.linspace(0, len(traj) - 1, n_tile).round().astype(int)
        dn = sr.scale / 255.0
        # warm up both paths (shader compilation, buffers)
        sr.set_ball(sr.ball_pose(traj.position[0]))
        sr.render_full(stock_shaders=True)
        pose0 = sr.ball_pose(traj.position[0])
        sr.render_tiles([pose0], sr.tiles_for(traj.position[:1]))
        full_times, tile_times, max_dn, tile_px = [], [], 0.0, []
        fulls = {}
        for i in idx_full:
            sr.set_ball(sr.ball_pose(traj.position[i]))
            t0 = time.perf_counter()
            fulls[i] = sr.render_full(stock_shaders=True)
            full_times.append(time.perf_counter() - t0)
        # synth's full frame: the background with the tiles pasted in; the previous frame's
        # tiles are put back to background first (a video is made frame after frame)
        comp = bg.copy()
        prev: list = []
        for i in sorted(set(idx_tile) | set(idx_full)):
            pose = sr.ball_pose(traj.position[i])
            t0 = time.perf_counter()
            tiles = sr.tiles_for(traj.position[i:i + 1])
            imgs = sr.render_tiles([pose], tiles)
            for x0, y0, w, h in prev:
                comp[y0:y0 + h, x0:x0 + w] = bg[y0:y0 + h, x0:x0 + w]
            for (x0, y0, w, h), img in zip(tiles, imgs, strict=True):
                comp[y0:y0 + h, x0:x0 + w] = img
            prev = tiles
            dt = time.perf_counter() - t0
            if i in idx_tile:
                tile_times.append(dt)
                tile_px.append(sum(w * h for _, _, w, h in tiles))
            if i in fulls:
                d = np.abs(comp.astype(np.int64) - fulls[i].astype(np.int64)).max() / dn
                max_dn = max(max_dn, float(d))
    finally:
        sr.close()
    full_ms = 1e3 * float(np.median(full_times))
    tile_ms = 1e3 * float(np.median(tile_times))
    # a whole recording, both cores
    tmp = Path(tempfile.mkdtemp(prefix="synth-bench-"))
    try:
        t0 = time.perf_counter()
        out = synth.render(traj, tmp / "bench.zarr", scene=scene,
                           sensor=synth.noise_preset("realistic"), seed=0, workers=workers,
                           frames=min(n_seq, len(traj)))
        t_seq = time.perf_counter() - t0
        n_done = min(n_seq, len(traj))
        size = _dir_size(out)
        disk = _disk_usage(out)
        rec = synth.open_recording(out)
        rec.frames[0]
        t0 = time.perf_counter()
        k = min(50, n_done)
        for i in range(k):
            rec.frames[i]
        read_ms = 1e3 * (time.perf_counter() - t0) / k
        # a tracker's region of interest: the ball's box plus 20 px a side
        _, h, w = rec.frames.shape
        tr = rec.truth
        rois = []
        for i in range(k):
            half = int(tr.r_px[i]) + 20
            x, y = int(tr.x_px[i]), int(tr.y_px[i])
            rois.append((max(0, y - half), min(h, y + half + 1), max(0, x - half),
                         min(w, x + half + 1)))
        t0 = time.perf_counter()
        for i in range(k):
            rec.frames.read(i, rois[i])
        roi_ms = 1e3 * (time.perf_counter() - t0) / k
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {
        "frame": f"{scene.camera.width}x{scene.camera.height}",
        "projection": scene.camera.projection,
        "supersample": scene.supersample,
        "motion_blur": scene.motion_blur,
        "shadows": scene.shadows,
        "lamps": len(scene.lighting.lamps),
        "background_render_s": round(t_bg, 3),
        "full_frame_ms": round(full_ms, 1),
        "synth_tile_ms": round(tile_ms, 1),
        "speedup_single_process": round(full_ms / tile_ms, 1),
        "tile_pixels_median": int(np.median(tile_px)),
        "max_diff_dn": max_dn,
        "sequence_frames": n_done,
        "sequence_workers": workers,
        "sequence_s": round(t_seq, 1),
        "sequence_fps": round(n_done / t_seq, 1),
        "sequence_ms_per_frame": round(1e3 * t_seq / n_done, 1),
        "speedup_sequence": round(full_ms / (1e3 * t_seq / n_done), 1),
        "est_4000_frames_s": round(4000 * t_seq / n_done, 1),
        "store_mb": round(size / 1e6, 2),
        "est_store_4000_mb": round(size / 1e6 * 4000 / n_done, 1),
        "store_disk_mb": round(disk / 1e6, 2),
        "read_ms_per_frame": round(read_ms, 1),
        "read_roi_ms_per_frame": round(roi_ms, 3),
        "sensor_noise": rec.frames.noise,
        "roi_px": int(np.median([(r[1] - r[0]) * (r[3] - r[2]) for r in rois])),
        "versions": _versions(),
        "cpus": os.cpu_count(),
    }


def main(argv=None) -> int:
    import argparse
    import json

    p = argparse.ArgumentParser(prog="python -m synth.bench", description=__doc__)
    p.add_argument("--full", action="store_true", help="4000-frame sequence (minutes)")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    print(json.dumps(render_benchmark(quick=not args.full, workers=args.workers), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
