"""Benchmarks of the synth renderer (called by ``rollfric bench``; also ``python -m
validation.bench.render``).

Compares, side by side in one run on the same scene: the plain pyrender full-frame render (the
"stock" way: one OffscreenRenderer.render of the whole 1280 x 1024 frame with the ball, with
pyrender's own shaders) and synth's tile frames (static background once, then only the ball's
and shadows' tiles, shadow maps once per frame, the shadow filter read with gathers) drawn by
synth's lean path (:mod:`synth.backends.lean`) and by pyrender's renderer functions (the path
before it); the largest difference from stock pyrender in 8-bit DN; where a lean tile frame's time
goes; the throughput of a whole recording with both cores; the size of the store and the cost
of reading it.

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

import sim
import synth
from synth.backends.raster import SceneRenderer
from synth.pipeline import BATCH, versions


def _dir_size(path: Path) -> int:
    """Bytes in the files of a directory tree."""
    return sum(f.stat().st_size for f in Path(path).rglob("*") if f.is_file())


def _disk_usage(path: Path) -> int:
    """Bytes the tree occupies on disk (allocated blocks, directories included), like du."""
    paths = [Path(path), *Path(path).rglob("*")]
    return sum(p.stat().st_blocks * 512 for p in paths)


_STOCK: dict = {}  # scene repr -> seconds of a stock full frame measured in this process


def stock_frame_seconds(scene=None, repeats: int = 3) -> float:
    """Median seconds of stock pyrender's full frame of ``scene`` with the ball (pyrender's own
    shaders, one OffscreenRenderer.render), measured once a process and kept: the baseline the
    bench's other rows divide by.

    Parameters
    ----------
    scene, repeats
        As for :func:`stock_frame_times`.

    Returns
    -------
    float
        Seconds per frame.
    """
    scene = scene or synth.SceneConfig()
    key = repr(scene)
    if key not in _STOCK:
        _STOCK[key] = float(np.median(stock_frame_times(scene, repeats)))
    return _STOCK[key]


def stock_frame_times(scene=None, repeats: int = 3) -> list[float]:
    """Seconds of each of ``repeats`` stock pyrender full frames of ``scene``, measured now
    (not kept: :func:`stock_frame_seconds` keeps its first median): for a baseline taken
    beside a measurement, as the machine's speed is then.

    Parameters
    ----------
    scene : synth.SceneConfig, optional
        The scene (default: the default scene).
    repeats : int
        Renders timed (after one warm-up).

    Returns
    -------
    list of float
        Seconds of each frame.
    """
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    scene = scene or synth.SceneConfig()
    traj = sim.simulate(sim.Scenario(duration=0.01))
    setup = traj.setup()
    sr = SceneRenderer(scene, setup.ball_radius, setup.cylinder_radius)
    try:
        sr.set_ball(sr.ball_pose(traj.position[0]))
        sr.render_full(stock_shaders=True)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            sr.render_full(stock_shaders=True)
            times.append(time.perf_counter() - t0)
    finally:
        sr.close()
    return times


def _tile_frames(sr, traj, indices, bg, draw, fulls, timings=None):
    """Render the frames ``indices`` as a recording does (tiles over the background, the
    previous frame's tiles put back first): (seconds per frame, tile pixels per frame, largest
    difference from the stock full frames ``fulls`` in DN). ``draw``: "lean", "pyrender" or
    "sphere" (the lean path with the ball as the exact sphere, ``ball_model = "sphere"``)."""
    if draw != "pyrender":
        model = "sphere" if draw == "sphere" else "mesh"
        if sr._lean.ball_model != model:
            sr._lean.ball_model = model
            sr._lean.ready = False
        draw = "lean"
    comp = bg.copy()
    prev: list = []
    times, px, worst = [], [], 0.0
    dn = sr.scale / 255.0
    for i in indices:
        pose = sr.ball_pose(traj.position[i])
        t0 = time.perf_counter()
        tiles = sr.tiles_for(traj.position[i:i + 1])
        t1 = time.perf_counter()
        if timings is not None:
            timings["footprint (tiles_for)"] = timings.get("footprint (tiles_for)", 0.0) \
                + t1 - t0
        imgs = sr.render_tiles([pose], tiles, draw=draw, timings=timings)
        for x0, y0, w, h in prev:
            comp[y0:y0 + h, x0:x0 + w] = bg[y0:y0 + h, x0:x0 + w]
        for (x0, y0, w, h), img in zip(tiles, imgs, strict=True):
            comp[y0:y0 + h, x0:x0 + w] = img
        prev = tiles
        times.append(time.perf_counter() - t0)
        px.append(sum(w * h for _, _, w, h in tiles))
        if i in fulls:
            d = np.abs(comp.astype(np.int64) - fulls[i].astype(np.int64)).max() / dn
            worst = max(worst, float(d))
    return times, px, worst


def file_create_ms(folder, n: int = 200) -> float:
    """Milliseconds (wall) to create, write (3 kB) and close one file in a new folder inside
    ``folder``, the median of ``n``; the files and their folder are removed. A recording is
    ~2 chunk files a frame, and on a busy disk creating a file can cost more than rendering
    the frame (docs/how/renderer.md): the bench states it for its recording's folder.

    Parameters
    ----------
    folder : str or pathlib.Path
        Where the recording is written.
    n : int
        Files created.

    Returns
    -------
    float
        Median milliseconds a file.
    """
    probe = Path(tempfile.mkdtemp(prefix="file-probe-", dir=folder))
    data = bytes(3000)
    times = []
    try:
        for i in range(n):
            t0 = time.perf_counter()
            (probe / f"c.{i}.0.0").write_bytes(data)
            times.append(time.perf_counter() - t0)
    finally:
        shutil.rmtree(probe, ignore_errors=True)
    return 1e3 * float(np.median(times))


def schedule_split(schedule: dict, n_frames: int, total: float) -> dict:
    """Split a recording's wall time into start-up and frames from its own batches' times
    (``synth.render(..., schedule=...)``), so that no other recording (made under another
    load) enters the split.

    Parameters
    ----------
    schedule : dict
        The recording's schedule: ``start``, ``submitted`` and ``batches`` (first frame,
        process id, start, end), ``time.time()`` seconds.
    n_frames : int
        Frames of the recording.
    total : float
        Its wall time (s).

    Returns
    -------
    dict
        ``steady_s``: seconds per frame of the batches after each process's first, on all
        processes together (their busy time over their frames, divided by the processes);
        ``quarters_s``: the same for the batches of each quarter of the recording's frames;
        ``to_first_batch_s``: from the call to the first batch's start (the fork server and
        its imports, the processes' EGL and renderer, the background, the store);
        ``first_batch_excess_s``: the first batches' time beyond as many steady frames (the
        first frame by pyrender's path: programs, shadow maps), the mean over the processes;
        ``end_idle_s``: how long the first process to finish waited for the last;
        ``startup_s``: ``total`` less ``n_frames`` steady frames (all that is not frames).
        NaN where the recording ran in one process (no batches recorded).
    """
    nan = float("nan")
    rows = sorted(schedule.get("batches") or [], key=lambda b: b[2])
    if not rows:
        return {"steady_s": nan, "quarters_s": [nan] * 4, "to_first_batch_s": nan,
                "first_batch_excess_s": nan, "end_idle_s": nan, "startup_s": nan}
    size = {b[0]: min(BATCH, n_frames - b[0]) for b in rows}
    pids = sorted({b[1] for b in rows})
    procs = schedule.get("workers") or len(pids)  # more ids than workers: a pool restarted
    first = {pid: next(b for b in rows if b[1] == pid) for pid in pids}
    rest = [b for b in rows if b is not first[b[1]]] or rows

    def per_frame(batches):
        frames = sum(size[b[0]] for b in batches)
        return sum(b[3] - b[2] for b in batches) / frames / procs if frames else nan

    steady = per_frame(rest)
    quarters = [per_frame([b for b in rest if k * n_frames <= 4 * b[0] < (k + 1) * n_frames])
                for k in range(4)]
    excess = float(np.mean([first[p][3] - first[p][2] - size[first[p][0]] * steady * procs
                            for p in pids]))
    ends = sorted(max(b[3] for b in rows if b[1] == p) for p in pids)
    return {"steady_s": steady, "quarters_s": quarters,
            "to_first_batch_s": rows[0][2] - schedule["start"],
            "first_batch_excess_s": excess, "end_idle_s": ends[-1] - ends[0],
            "startup_s": total - n_frames * steady}


def pool_restarted(schedule: dict) -> bool:
    """Whether a recording's render processes died and its batches were rendered again by a
    fresh pool (``synth.render`` says so on its progress bar): its batches then come from more
    processes than ``workers``, and its wall time is not a frame's cost.

    Parameters
    ----------
    schedule : dict
        The recording's schedule (``synth.render(..., schedule=...)``).

    Returns
    -------
    bool
    """
    pids = {b[1] for b in schedule.get("batches") or []}
    return bool(schedule.get("workers")) and len(pids) > schedule["workers"]


def render_benchmark(quick: bool = True, *, workers: int = 2, seconds: float | None = None,
                     scene=None) -> dict:
    """Measure ms/frame (stock full frame vs synth's tiles by the lean path and by pyrender's
    path), the largest DN difference of each from stock pyrender, where a lean tile frame's
    time goes, sequence fps with ``workers`` processes, the recording's size and read costs.
    quick: 3 full frames, 30 tile frames a path and a 300-frame sequence (size extrapolated to
    4000 frames); otherwise 6, 100 and 4000."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    scene = scene or synth.SceneConfig()
    n_full, n_tile, n_seq = (3, 30, 300) if quick else (6, 100, 4000)
    seconds = seconds if seconds is not None else n_seq / 1000.0
    traj = sim.simulate(sim.Scenario(duration=max(seconds, (n_tile - 1) / 1000.0)))
    frames, full_ms = _frame_costs(scene, traj, n_full, n_tile)
    tmp = Path(tempfile.mkdtemp(prefix="synth-bench-"))
    try:
        out, seq = _sequence_costs(scene, traj, tmp, workers, n_seq, full_ms)
        reads = _read_costs(out, seq["sequence_frames"])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {**frames, **seq, **reads, "versions": versions(), "cpus": os.cpu_count()}


def _frame_costs(scene, traj, n_full: int, n_tile: int) -> dict:
    """One process's frames of ``scene``: the background, stock pyrender's full frames, the
    tile frames by the lean path, by pyrender's path and with the exact sphere (alternating
    blocks of 10 frames: a shared machine's load falls on all alike), the stages of a lean
    frame: (the bench's rows, the stock full frame's median ms)."""
    setup = traj.setup()
    sr = SceneRenderer(scene, setup.ball_radius, setup.cylinder_radius)
    try:
        t0 = time.perf_counter()
        bg = sr.render_full()
        t_bg = time.perf_counter() - t0
        idx_full = np.linspace(0, len(traj) - 1, n_full).round().astype(int)
        idx_tile = np.linspace(0, len(traj) - 1, n_tile).round().astype(int)
        idx_all = sorted(set(idx_tile) | set(idx_full))
        # warm up every path (shader compilation, buffers; the lean path is built)
        sr.set_ball(sr.ball_pose(traj.position[0]))
        sr.render_full(stock_shaders=True)
        pose0 = sr.ball_pose(traj.position[0])
        sr.render_tiles([pose0], sr.tiles_for(traj.position[:1]))
        sr.render_tiles([pose0], sr.tiles_for(traj.position[:1]), draw="pyrender")
        full_times = []
        fulls = {}
        for i in idx_full:
            sr.set_ball(sr.ball_pose(traj.position[i]))
            t0 = time.perf_counter()
            fulls[i] = sr.render_full(stock_shaders=True)
            full_times.append(time.perf_counter() - t0)
        _STOCK.setdefault(repr(scene), float(np.median(full_times)))
        res = {"lean": ([], [], 0.0), "pyrender": ([], [], 0.0), "sphere": ([], [], 0.0)}
        for start in range(0, len(idx_all), 10):
            block = idx_all[start:start + 10]
            for draw in ("pyrender", "lean", "sphere"):
                times, px, worst = _tile_frames(sr, traj, block, bg, draw, fulls)
                t, p, w = res[draw]
                res[draw] = (t + [x for i, x in zip(block, times, strict=True)
                                  if i in set(idx_tile)],
                             p + [x for i, x in zip(block, px, strict=True)
                                  if i in set(idx_tile)], max(w, worst))
        # where a lean frame's time goes (each stage waited for: a little slower in all)
        stages: dict = {}
        n_stage = min(len(idx_tile), 30)
        _tile_frames(sr, traj, idx_tile[:n_stage], bg, "lean", {}, timings=stages)
        stages_sphere: dict = {}
        _tile_frames(sr, traj, idx_tile[:n_stage], bg, "sphere", {}, timings=stages_sphere)
    finally:
        sr.close()
    full_ms = 1e3 * float(np.median(full_times))
    return _frame_rows(scene, t_bg, full_ms, res, stages, stages_sphere, n_stage), full_ms


def _frame_rows(scene, t_bg, full_ms, res, stages, stages_sphere, n_stage) -> dict:
    """The rows of :func:`_frame_costs`."""
    tile_ms = 1e3 * float(np.median(res["lean"][0]))
    tile_py_ms = 1e3 * float(np.median(res["pyrender"][0]))
    tile_sphere_ms = 1e3 * float(np.median(res["sphere"][0]))
    return {
        "frame": f"{scene.camera.width}x{scene.camera.height}",
        "projection": scene.camera.projection,
        "supersample": scene.supersample,
        "motion_blur": scene.motion_blur,
        "shadows": scene.shadows,
        "lamps": len(scene.lighting.lamps),
        "background_render_s": round(t_bg, 3),
        "full_frame_ms": round(full_ms, 1),
        "synth_tile_ms": round(tile_ms, 2),
        "synth_tile_pyrender_path_ms": round(tile_py_ms, 2),
        "speedup_single_process": round(full_ms / tile_ms, 1),
        "speedup_single_process_pyrender_path": round(full_ms / tile_py_ms, 1),
        "lean_over_pyrender_path": round(tile_py_ms / tile_ms, 2),
        "tile_pixels_median": int(np.median(res["lean"][1])),
        "max_diff_dn": res["lean"][2],
        "max_diff_dn_pyrender_path": res["pyrender"][2],
        "lean_frame_stages_ms": {name: round(1e3 * v / n_stage, 2)
                                 for name, v in stages.items()},
        "synth_tile_sphere_ms": round(tile_sphere_ms, 2),
        "speedup_single_process_sphere": round(full_ms / tile_sphere_ms, 1),
        "max_diff_dn_sphere": res["sphere"][2],
        "sphere_frame_stages_ms": {name: round(1e3 * v / n_stage, 2)
                                   for name, v in stages_sphere.items()},
    }


def _sequence_costs(scene, traj, tmp: Path, workers: int, n_seq: int, full_ms: float):
    """A whole recording of ``scene`` in ``tmp`` with ``workers`` processes (both cores), then
    a shorter one after it in the same process (it reuses the render processes' fork server
    the first one started: its imports): (the recording, the bench's rows; speed-ups over a
    stock full frame of ``full_ms``)."""
    create_ms = file_create_ms(tmp)
    t0 = time.perf_counter()
    sched: dict = {}
    out = synth.render(traj, tmp / "bench.zarr", scene=scene,
                       sensor=synth.noise_preset("realistic"), seed=0, workers=workers,
                       frames=min(n_seq, len(traj)), schedule=sched)
    t_seq = time.perf_counter() - t0
    n_done = min(n_seq, len(traj))
    split = schedule_split(sched, n_done, t_seq)
    later: dict = {}
    n_short = min(2 * BATCH * workers, n_done)
    t0 = time.perf_counter()
    synth.render(traj, tmp / "later.zarr", scene=scene,
                 sensor=synth.noise_preset("realistic"), seed=0, workers=workers,
                 frames=n_short, schedule=later)
    split_later = schedule_split(later, n_short, time.perf_counter() - t0)
    return out, {
        "sequence_frames": n_done,
        "sequence_workers": workers,
        "sequence_s": round(t_seq, 1),
        "sequence_fps": round(n_done / t_seq, 1),
        "sequence_ms_per_frame": round(1e3 * t_seq / n_done, 2),
        "speedup_sequence": round(full_ms / (1e3 * t_seq / n_done), 1),
        "est_4000_frames_s": round(4000 * t_seq / n_done, 1),
        "sequence_startup_s": round(split["startup_s"], 2),
        "sequence_to_first_batch_s": round(split["to_first_batch_s"], 2),
        "sequence_first_batch_excess_s": round(split["first_batch_excess_s"], 2),
        "sequence_end_idle_s": round(split["end_idle_s"], 2),
        "sequence_pool_restarted": pool_restarted(sched),
        "sequence_startup_later_s": round(split_later["startup_s"], 2),
        "sequence_steady_ms_per_frame": round(1e3 * split["steady_s"], 2),
        "sequence_steady_quarters_ms": [round(1e3 * q, 2) for q in split["quarters_s"]],
        "sequence_file_create_ms": round(create_ms, 3),
        "speedup_sequence_steady": round(full_ms / (1e3 * split["steady_s"]), 1),
    }


def _read_costs(out: Path, n_done: int) -> dict:
    """The recording's size on disk and what reading it costs: whole frames, a tracker's
    region of interest (the ball's box plus 20 px a side) with and without the sensor model;
    the bench's rows."""
    size = _dir_size(out)
    disk = _disk_usage(out)
    rec = synth.open_recording(out)
    rec.frames[0]
    t0 = time.perf_counter()
    k = min(50, n_done)
    for i in range(k):
        rec.frames[i]
    read_ms = 1e3 * (time.perf_counter() - t0) / k
    _, h, w = rec.frames.shape
    tr = rec.truth
    rois = []
    for i in range(k):
        half = int(tr.r_px[i]) + 20
        x, y = int(tr.x_px[i]), int(tr.y_px[i])
        rois.append((max(0, y - half), min(h, y + half + 1), max(0, x - half),
                     min(w, x + half + 1)))
    # the region path's first read loads (or, after the kernels changed, compiles) the
    # sensor kernel for its array type: once a process, not a frame's cost
    rec.frames.read(0, rois[0])
    t0 = time.perf_counter()
    for i in range(k):
        rec.frames.read(i, rois[i])
    roi_ms = 1e3 * (time.perf_counter() - t0) / k
    t0 = time.perf_counter()
    for i in range(k):
        rec.frames.clean_counts(i, rois[i])
    roi_clean_ms = 1e3 * (time.perf_counter() - t0) / k
    return {
        "store_mb": round(size / 1e6, 2),
        "est_store_4000_mb": round(size / 1e6 * 4000 / n_done, 1),
        "store_disk_mb": round(disk / 1e6, 2),
        "read_ms_per_frame": round(read_ms, 1),
        "read_roi_ms_per_frame": round(roi_ms, 3),
        "read_roi_clean_ms_per_frame": round(roi_clean_ms, 3),
        "sensor_noise": rec.frames.noise,
        "roi_px": int(np.median([(r[1] - r[0]) * (r[3] - r[2]) for r in rois])),
    }


def main(argv=None) -> int:
    import argparse
    import json

    p = argparse.ArgumentParser(prog="python -m validation.bench.render", description=__doc__)
    p.add_argument("--full", action="store_true", help="4000-frame sequence (minutes)")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    print(json.dumps(render_benchmark(quick=not args.full, workers=args.workers), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
