"""Render a trajectory into a synthetic recording (a Zarr store), in parallel processes."""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import faulthandler
import functools
import math
import multiprocessing as mp
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

from rollfric.output.atomic import replacing
from synth.camera import CameraModel
from synth.config import SceneConfig, SensorConfig, SynthError
from synth.store import CHUNK, FORMAT, TRUTH_COLUMNS, writer_layout

BATCH = 16  # frames per task (progress granularity)
# the background the render processes subtract, in the store's folder while they render
BACKGROUND_FILE = ".render-background.npy"
# the simulation's metadata a recording leaves out: it differs from run to run of one case
RUN_DEPENDENT_META = ("wall_time_s",)


# -- trajectories ------------------------------------------------------------------------------

def load_trajectory(source):
    """A sim.Trajectory from a Trajectory, a trajectory CSV or a scenario TOML (simulated)."""
    import sim

    if isinstance(source, sim.Trajectory):
        traj = source
    else:
        path = Path(source)
        if not path.exists():
            raise SynthError(f"trajectory not found: {path}")
        if path.suffix.lower() == ".toml":
            return sim.simulate(sim.load_scenario(path))
        traj = sim.read_trajectory(path)
    for name in ("t", "theta", "theta_dot", "position"):
        if not np.all(np.isfinite(getattr(traj, name))):
            raise SynthError(f"the trajectory has NaN or inf in {name}: it cannot be rendered")
    return traj


def subframe_positions(traj, n_sub: int, exposure: float) -> np.ndarray:
    """(N, n_sub, 3) ball centres at the sub-frame times of each exposure.

    The exposure of frame i is centred on t_i; sub-frame k sits at t_i + ((k + 0.5) / n_sub
    - 0.5) * exposure. Positions between samples follow a cubic Hermite spline through the
    sampled positions with the rolling velocity L theta_dot (cos theta, sin theta, 0); an
    out-of-round or tilted trough (whose ball is not on that circle) uses a cubic spline
    through the positions.
    """
    pos = np.asarray(traj.position, float)
    if n_sub == 1:
        return pos[:, None, :]
    from scipy.interpolate import CubicHermiteSpline, CubicSpline

    t = np.asarray(traj.t, float)
    offs = ((np.arange(n_sub) + 0.5) / n_sub - 0.5) * exposure
    sc = traj.scenario
    if sc.ovality or sc.tilt:
        return CubicSpline(t, pos, axis=0, extrapolate=True)(t[:, None] + offs[None, :])
    L = math.hypot(pos[0, 0], pos[0, 1])
    th, thd = np.asarray(traj.theta), np.asarray(traj.theta_dot)
    vel = L * thd[:, None] * np.column_stack([np.cos(th), np.sin(th), np.zeros_like(th)])
    spline = CubicHermiteSpline(t, pos, vel, axis=0, extrapolate=True)
    return spline(t[:, None] + offs[None, :])


def truth_table(traj, camera: CameraModel, ball_radius: float) -> dict:
    """The truth columns (TRUTH_COLUMNS). Through a lens the ball's positions are the distorted
    ones of its ideal projections (:meth:`CameraModel.recorded`: the sphere centre's and the
    silhouette centre's); the axis (cx_px, cy_px) stays in the ideal (undistorted) image."""
    pos = np.asarray(traj.position, float)
    uv = camera.recorded(camera.project(pos))
    sil, rad = camera.sphere_silhouette(pos, ball_radius)
    sil = camera.recorded(sil)
    n = len(pos)
    return {
        "t_s": np.asarray(traj.t, float),
        "theta_rad": np.asarray(traj.theta, float),
        "theta_dot_rad_s": np.asarray(traj.theta_dot, float),
        "x_px": uv[:, 0], "y_px": uv[:, 1],
        "sil_x_px": sil[:, 0], "sil_y_px": sil[:, 1],
        "r_px": rad,
        "cx_px": np.full(n, camera.center_px[0]), "cy_px": np.full(n, camera.center_px[1]),
    }


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in ("rollfric", "pyrender-maintained", "pyrender2", "pyrender", "numpy", "zarr",
                 "PyOpenGL", "trimesh", "mitsuba", "drjit"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            pass
    return out


# -- worker processes --------------------------------------------------------------------------

_W: dict = {}


def make_renderer(scene: SceneConfig, ball_radius: float, cylinder_radius: float,
                  seed: int = 0, threads: int | None = None, oval=(0.0, 0.0)):
    """The backend ``scene.renderer`` names, for the scene's ideal (lens-free) camera.

    Parameters
    ----------
    scene : SceneConfig
        The scene (its camera's lens is applied to the renders afterwards, by synth.distortion).
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
    synth.scene.SceneRenderer or synth.mitsuba_scene.MitsubaRenderer
    """
    ideal = scene.replace(camera=scene.camera.ideal())
    if scene.renderer == "mitsuba":
        from synth.mitsuba_scene import MitsubaRenderer, set_threads

        if threads:
            set_threads(threads)
        return MitsubaRenderer(ideal, ball_radius, cylinder_radius, *oval, seed=seed)
    if threads:
        os.environ["LP_NUM_THREADS"] = str(threads)  # read when llvmpipe starts
    from synth.scene import SceneRenderer

    return SceneRenderer(ideal, ball_radius, cylinder_radius, *oval)


def _worker_init(scene_dict, ball_radius, cylinder_radius, store_path, threads, oval=(0.0, 0.0),
                 seed=0, defocus=None):
    _worker_start(scene_dict, ball_radius, cylinder_radius, threads, oval, seed)
    _worker_open(store_path, defocus)


def crash_report() -> bool:
    """Have this process write the Python stacks of all its threads to stderr if it crashes
    (a segfault, an abort: :mod:`faulthandler`), as render processes do. A render process dies
    now and then in libc's malloc (segfaults in the kernel log: 4 on 2026-11-23, over the day's
    studies and benches: a 4-byte zero written at +8 of a freed block, which glibc trips over
    later; the writer not found, see tools/heapprobe): the lost batches are rendered
    again, and the stacks say where the process was when glibc tripped (not who wrote).

    Returns
    -------
    bool
        Whether it is on (not where stderr has no file descriptor).
    """
    try:
        faulthandler.enable(all_threads=True)
    except (AttributeError, OSError, RuntimeError, ValueError):  # no usable stderr
        return False
    return True


def exit_with_parent() -> bool:
    """Have this render process exit when the process that started it has gone.

    A pool's worker waits for its next task on a queue whose pipe it holds both ends of, so it
    never sees its parent die; forked from the fork server, it also keeps the server alive. A
    main process killed by SIGKILL (or by a SIGTERM it does not handle) left its render
    processes (~370 MB each), the fork server and their semaphores behind for good (seen
    2026-11-24). A daemon thread waits on the parent's sentinel
    (:func:`multiprocessing.parent_process`) and ends the process when it fires.

    Returns
    -------
    bool
        Whether this process has a parent to watch (False in a main process).
    """
    parent = mp.parent_process()
    if parent is None:
        return False

    def watch():
        parent.join()
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()
    return True


def _pool_worker(initializer, *args) -> None:
    """A render pool's initializer: :func:`exit_with_parent`, then ``initializer(*args)``."""
    exit_with_parent()
    initializer(*args)


def _worker_start(scene_dict, ball_radius, cylinder_radius, threads, oval=(0.0, 0.0), seed=0):
    """A render process's renderer (its imports, EGL context, programs and meshes): what needs
    no store, so the processes can start while the main process renders the background."""
    crash_report()
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    cfg = SceneConfig.from_dict(scene_dict)
    _W["cfg"] = cfg
    _W["ball_radius"] = ball_radius
    _W["renderer"] = make_renderer(cfg, ball_radius, cylinder_radius, seed, threads, oval)


def _worker_ready() -> int:
    """A no-op task: submitting one per process makes the pool start them all now."""
    return os.getpid()


def _worker_background():
    """The background (the scene without the ball, a plain render of the full frame) drawn
    by this render process's renderer, so that the main process need not import pyrender
    and trimesh nor make a renderer of its own: (levels as the smallest unsigned dtype that
    holds ``scale``, scale)."""
    sr = _W["renderer"]
    bg = sr.render_full()
    return bg.astype(np.uint16 if sr.scale <= 65535 else np.uint32), int(sr.scale)


def _worker_warm(centres) -> None:
    """Draw the tiles of a frame with the ball at ``centres`` and drop them: a render
    process's first frame sets up what every later one uses (the trough's cached shadow maps,
    the lean draw path, the static layer's blocks; ~0.25 s), done while it waits for the
    background. The frames it draws later are the same bytes."""
    sr = _W["renderer"]
    tiles = sr.tiles_for(centres)
    if tiles:
        sr.render_tiles([sr.ball_pose(c) for c in centres], tiles)


def _worker_open(store_path, defocus=None, spec=None):
    """The recording's store in a render process: its chunk writer and background, read
    through zarr, or from ``spec`` = (:func:`synth.store.writer_layout`, the background's
    ``.npy`` file) without it (the processes of :func:`_early_pool`, whose fork server imports
    no zarr)."""
    cfg = _W["cfg"]
    lens = cfg.camera.lens
    _W["defocus"] = None
    if defocus is not None:  # (face, bore, sharp background) of the ideal frame
        from synth.defocus import Defocus

        face, bore, sharp = defocus
        _W["defocus"] = (Defocus(cfg.replace(camera=cfg.camera.ideal()), face, bore,
                                 _W["ball_radius"]), np.asarray(sharp, dtype=np.int64))
    from synth.store import chunk_writer_at, writer_layout

    if spec is None:
        import zarr

        g = zarr.open_group(store_path, mode="r+")
        layout = writer_layout(g, g["clean_diff"])
        bg = g["background_ideal_clean" if lens is not None else "background_clean"][...]
    else:
        layout, bg = spec[0], np.load(spec[1])
    _W["write"] = chunk_writer_at(layout)
    _W["lens"] = None
    if lens is not None:
        from synth.distortion import cached_window

        _W["lens"] = (lens, cached_window(lens, cfg.camera.width, cfg.camera.height),
                      (cfg.camera.height, cfg.camera.width))
    _W["bg"] = np.asarray(bg, dtype=np.int64)
    if hasattr(_W["renderer"], "set_background"):  # Mitsuba: unchanged pixels from it
        _W["renderer"].set_background(_W["bg"])
    _W["store"] = store_path


def _worker_batch_in(store_path, spec, indices, centres):
    """:func:`_worker_batch` in a process started by :func:`_worker_start`: the store is opened
    at its first batch (it is written after the processes start; ``spec``: see
    :func:`_worker_open`). Returns (frames, (first index, process id, start, end)), the times
    by ``time.time()`` (the recording's schedule, :func:`render`'s ``stats``)."""
    t0 = time.time()
    if _W.get("store") != store_path:
        _worker_open(store_path, spec=spec)
    n = _worker_batch(indices, centres)
    return n, (int(indices[0]), os.getpid(), t0, time.time())


def _worker_batch(indices, centres):
    sr = _W["renderer"]
    write = _W["write"]
    bg = _W["bg"]
    k = centres.shape[1]
    lens = _W.get("lens")
    dfc = _W.get("defocus")
    many = getattr(sr, "tiles_for_many", None)  # the batch's footprints at once (pyrender)
    batch_tiles = many(list(centres)) if many is not None else None
    for n, i in enumerate(indices):
        poses = [sr.ball_pose(c) for c in centres[n]]
        tiles = batch_tiles[n] if batch_tiles is not None else sr.tiles_for(centres[n])
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
    from synth.distortion import distort_tile

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


MAX_POOL_RESTARTS = 3


def pool_context():
    """The multiprocessing context render processes start in: forked from a fork server that
    has imported what they need once (:mod:`synth.preload`; the server makes no EGL context,
    which would not survive a fork) on Linux, spawned elsewhere (macOS's system frameworks,
    which pyglet may load, do not survive a fork either; Windows has no fork server).

    Each process then makes its own EGL context, as a spawned one does, and draws the same
    bytes; a recording's start-up loses the imports of every process but the server's (~2 s
    of CPU each), and a later recording of the same process reuses the server.

    Returns
    -------
    multiprocessing.context.BaseContext
    """
    if not sys.platform.startswith("linux") or "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["synth.preload"])  # used when the server starts
    return ctx


def render_workers(scene: SceneConfig, frames: int, workers: int | None = None) -> int:
    """The number of render processes :func:`render` uses for ``frames`` frames of ``scene``.

    Parameters
    ----------
    scene : SceneConfig
        The scene (Mitsuba's Dr.Jit spreads one process's renders over every core itself).
    frames : int
        Frames to render.
    workers : int, optional
        As asked of :func:`render` (default: the number of CPUs, at most 2).

    Returns
    -------
    int
        At least 1, at most one per batch of frames.
    """
    if workers is None:
        workers = 1 if scene.renderer == "mitsuba" else max(1, min(2, os.cpu_count() or 1))
    return max(1, min(int(workers), max(1, frames // BATCH)))


def prepare_render(scene: SceneConfig, frames: int, workers: int | None = None) -> bool:
    """Start, now, what :func:`render` of ``frames`` frames of ``scene`` (with ``workers``)
    will start first: the fork server its render processes are forked from
    (:func:`start_fork_server`, ~1 s of imports), if it uses one. For a caller with other
    work before the render (``rollfric validate``'s fit of the true angles); the render is
    the same with or without it.

    Parameters
    ----------
    scene : SceneConfig
        The scene to be rendered.
    frames : int
        Frames to be rendered.
    workers : int, optional
        As to be passed to :func:`render`.

    Returns
    -------
    bool
        Whether a fork server was started or is running for it.
    """
    if render_workers(scene, frames, workers) < 2 or scene.camera.thin_lens:
        return False
    return start_fork_server()


def start_fork_server() -> bool:
    """Start the fork server render processes are forked from (:func:`pool_context`), if that
    is how they start here and it is not running yet: its imports (:mod:`synth.preload`,
    ~1 s of CPU) then run while the caller goes on. :func:`render` calls it as soon as it knows
    it will start render processes (before its own imports and preparations, ~0.2 s); a caller
    may call it earlier (before a simulation).

    Returns
    -------
    bool
        Whether render processes start from a fork server here (Linux).
    """
    if pool_context().get_start_method() != "forkserver":
        return False
    from multiprocessing import forkserver

    forkserver.ensure_running()
    return True


def _start_processes(pool, workers, first=(), out=None) -> None:
    """Submit the tasks ``first`` (their futures appended to the list ``out``), then a no-op
    task per process (the pool forks one per task while none is idle); a pool that broke
    meanwhile is reported by the batches' own submission (and ``out`` is then short)."""
    try:
        for task in first:
            out.append(pool.submit(task))
        for _ in range(workers):
            pool.submit(_worker_ready)
    except RuntimeError:  # BrokenProcessPool is one
        pass


@contextlib.contextmanager
def _early_pool(workers, init, first=()):
    """``workers`` render processes (:func:`pool_context`) started now, each running
    ``_worker_start(*init)`` (imports, EGL, the renderer) while the caller goes on, and the
    tasks ``first`` (callables) submitted first, in order, for the processes as they are ready:
    (pool, a function that returns the futures of ``first``, once submitted, raising
    BrokenProcessPool if the pool broke before), (None, None) for 0 workers. Shut down on
    leaving (already done unless the render failed before using it)."""
    if not workers:
        yield None, None
        return
    pool = cf.ProcessPoolExecutor(workers, mp_context=pool_context(),
                                  initializer=_pool_worker, initargs=(_worker_start, *init))
    # a process is spawned per task while none is idle; from a thread, as the first process
    # of a fork server waits for the server's imports (~1 s), the caller's own work meanwhile
    futures: list = []
    first = list(first)
    starter = threading.Thread(target=_start_processes, args=(pool, workers, first, futures),
                               daemon=True)
    starter.start()

    def submitted() -> list:
        starter.join()
        if len(futures) < len(first):
            raise cf.process.BrokenProcessPool("a render process died while starting")
        return futures

    try:
        yield pool, submitted
    finally:
        starter.join()
        pool.shutdown(cancel_futures=True)


def _render_parallel(batches, centres, workers, init, bar, *, initializer=_worker_init,
                     batch_fn=_worker_batch, pool=None, schedule=None) -> None:
    """Render batches in ``workers`` processes (:func:`pool_context`: forked from a fork server
    that made no EGL context, or spawned; EGL contexts do not survive fork).

    A batch writes only its own frames' chunks, so a batch whose process died (llvmpipe has
    crashed a worker once in a 4000-frame run on this machine) is simply rendered again in a
    fresh pool, at most MAX_POOL_RESTARTS times. ``initializer(*init)`` prepares each process
    and ``batch_fn(indices, centres)`` renders a batch (default: _worker_init, _worker_batch);
    ``pool``: a pool already started with that initializer (:func:`_early_pool`), used first.
    A batch function may return (frames, info) instead of frames: each info is appended to the
    list ``schedule`` (if given).
    """
    ctx = pool_context()
    pending = list(range(len(batches)))
    for attempt in range(MAX_POOL_RESTARTS + 1):
        failed = []
        if pool is None:
            pool = cf.ProcessPoolExecutor(workers, mp_context=ctx, initializer=_pool_worker,
                                          initargs=(initializer, *init))
        with pool:
            futs = {}
            try:
                for k in pending:
                    futs[pool.submit(batch_fn, batches[k], centres[batches[k]])] = k
            except cf.process.BrokenProcessPool:  # it broke before (an early pool's process)
                failed = pending[len(futs):]
            for f in cf.as_completed(futs):
                try:
                    done = f.result()
                except cf.process.BrokenProcessPool:
                    failed.append(futs[f])
                    continue
                if isinstance(done, tuple):
                    done, info = done
                    if schedule is not None:
                        schedule.append(info)
                bar.update(done)
        pool = None
        if not failed:
            return
        if attempt == MAX_POOL_RESTARTS:
            raise RuntimeError(f"render processes kept dying: {len(failed)} batches of "
                               f"{BATCH} frames not rendered after {attempt} restarts")
        # on stderr (tqdm writes to stdout unless told): stdout may be a result, e.g.
        # `rollfric validate --json`'s
        bar.write(f"a render process died; rendering {len(failed)} batches again (its threads' "
                  "Python stacks, if it crashed, are above on stderr; to catch a write into "
                  "freed memory where it happens, run under synth's heap probe: "
                  "LD_PRELOAD=$(python tools/heapprobe/heapprobe.py))", file=sys.stderr)
        pending = sorted(failed)


# -- the public API ----------------------------------------------------------------------------

def render(trajectory, out, *, scene: SceneConfig | None = None,
           sensor: SensorConfig | None = None, seed: int = 0, progress: bool = False,
           workers: int | None = None, overwrite: bool = False, frames: int | None = None,
           threads: int | None = None, timing=None, schedule: dict | None = None) -> Path:
    """Render ``trajectory`` (sim.Trajectory, trajectory CSV or scenario TOML) as the lab
    camera would have seen it and store it as a recording at ``out`` (a ``.zarr`` directory).

    ``frames`` limits the number of frames (the first ones); ``workers`` processes render in
    parallel (default: the number of CPUs, at most 2; forked from a fork server that made no
    EGL context, or spawned, as EGL contexts do not survive fork), each with ``threads``
    llvmpipe threads (default 1 when several processes run); the sensor model is stored, not
    applied: frames get their noise when read. ``timing``
    (:class:`synth.camera_clock.FrameTiming`): the camera's jitter and dropped frames, drawn with
    ``seed``; the frames and the truth are then at the real sample times (``truth/t_s``), the
    lost camera frames are listed in the attrs (``timing``), and with ``timing.timestamps`` the
    store carries each frame's time (array ``timestamps``, s). ``schedule``: a dict to receive
    when things happened (``time.time()``, for benchmarks; the bytes are the same): ``start``,
    ``submitted`` (the background and store written, the batches handed to the processes),
    ``workers`` and,
    with early-started render processes, ``batches``, a list of (first frame, process id,
    start, end) per batch. Returns the path.
    """
    t_start = time.time()
    scene = scene or SceneConfig()
    sensor = sensor or SensorConfig()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SynthError(f"seed must be a non-negative integer, got {seed!r}")
    out = check_output(out, overwrite=overwrite)
    traj = load_trajectory(trajectory)
    timing_attrs = None
    if timing is not None:
        from synth.camera_clock import frame_times, resample

        times, numbers = frame_times(len(traj), traj.fps, timing, seed)
        if not timing.ideal:
            traj = resample(traj, times)
        lost = np.setdiff1d(np.arange(numbers[-1] + 1), numbers)
        timing_attrs = {**timing.to_dict(), "dropped_frames": lost.tolist()}
    n = len(traj) if frames is None else int(frames)
    if n < 1 or n > len(traj):
        raise SynthError(f"frames must be 1..{len(traj)}, got {frames!r}")
    if n < len(traj):
        traj = _head(traj, n)
    workers = render_workers(scene, n, workers)
    if workers > 1 and not scene.camera.thin_lens:
        start_fork_server()  # its imports (~1 s) while this process prepares
    from tqdm import tqdm

    from rollfric.setup.lens import Calibration
    from rollfric.setup.model import Setup
    base = traj.setup()
    cam = scene.camera
    # the camera's effective bit depth (camera.bit_depth) where rollfric's setup knows the key
    # and the words hold more bits than the sensor gives (10-14 bits in 16-bit words)
    bits = {"bit_depth": sensor.bit_depth} if (
        "bit_depth" in Setup.__dataclass_fields__ and sensor.dtype == "uint16") else {}
    setup = Setup(cylinder_radius=base.cylinder_radius, ball_diameter=base.ball_diameter,
                  ball_mass=base.ball_mass, fps=base.fps, pixel_size=cam.pixel_size,
                  center_px=cam.center_px, gravity=base.gravity, air_density=base.air_density,
                  calibration=None if cam.lens is None else
                  Calibration(cam.lens.matrix, cam.lens.distortion), **bits)
    r_ball, r_cyl = setup.ball_radius, setup.cylinder_radius
    # the bore as built: an out-of-round trough is drawn as its ellipse (sim.section)
    oval = (traj.scenario.ovality, traj.scenario.ovality_angle)
    k_sub = scene.motion_blur
    centres = subframe_positions(traj, k_sub, sensor.exposure)
    if threads is None and workers > 1:
        threads = 1  # one llvmpipe thread per process: the processes fill the cores

    lens = cam.lens
    # the render processes start (imports, EGL, programs, meshes: ~1.5 s) while this process
    # prepares; a thin lens's processes need the background's layers first
    start = (scene.to_dict(), r_ball, r_cyl, threads, oval, int(seed))
    early = workers if workers > 1 and not cam.thin_lens else 0
    # pyrender's background is drawn by the first render process that is ready (it has
    # imported pyrender anyway): this process imports neither pyrender nor trimesh; the
    # others draw the first frame meanwhile (their first frame's set-up)
    remote = bool(early) and scene.renderer == "pyrender"
    first = [_worker_background] + [functools.partial(_worker_warm, centres[0])] * (early - 1)
    with _early_pool(early, start, first if remote else ()) as (pool, submitted), \
            replacing(out, folder_ok=True) as tmp:
        # Zarr (~0.16 s of imports in a process that has not loaded it, as `rollfric
        # validate`'s) once the render processes are starting: they need not wait for it
        import zarr
        from zarr.codecs import ZstdCodec

        # what needs no background first (~30 ms: the truth), while a process draws it
        g = zarr.open_group(str(tmp), mode="w")
        tg = g.create_group("truth")
        for name, values in truth_table(traj, cam, r_ball).items():
            arr = tg.create_array(name, data=np.asarray(values, dtype=np.float64))
            arr.attrs["description"] = TRUTH_COLUMNS[name]
        if timing is not None and timing.timestamps:  # the camera's own time of each frame
            ts = g.create_array("timestamps", data=np.asarray(traj.t, dtype=np.float64))
            ts.attrs["description"] = "time of each frame's exposure (s), the camera's clock"
        defocus = None
        bg = None
        if remote:
            try:
                levels, scale = submitted()[0].result()
                bg = levels.astype(np.uint64)  # render_full's dtype
            except cf.process.BrokenProcessPool:  # drawn here; the batches in a new pool
                pool = None
        if bg is None:
            sr = make_renderer(scene, r_ball, r_cyl, seed, oval=oval)
            bg = sr.render_full()
            if cam.thin_lens:  # the layers' blur (synth.defocus), in the ideal frame
                from synth.defocus import Defocus, layer_coverage

                face, bore = layer_coverage(sr)
                defocus = (face, bore, bg)
                blurred = Defocus(scene.replace(camera=cam.ideal()), face, bore,
                                  r_ball).background(bg)
                bg = np.clip(np.rint(blurred), 0, None).astype(bg.dtype)
            sr.close()
            scale = sr.scale
        bg_ideal = None
        if lens is not None:
            from synth.distortion import cached_window, distort_image

            bg_ideal = bg
            bg = np.rint(distort_image(bg, cached_window(lens, cam.width, cam.height)))
        frame_scale = scale * k_sub
        H, W = cam.height, cam.width
        bg_dtype = "uint16" if scale <= 65535 else "uint32"
        g.create_array("background_clean", data=bg.astype(bg_dtype), chunks=(H, W))
        if bg_ideal is not None:  # what the workers subtract from the ideal tiles
            g.create_array("background_ideal_clean", data=bg_ideal.astype(bg_dtype),
                           chunks=bg_ideal.shape)
        diff_dtype = "int16" if frame_scale <= 32767 else "int32"
        # chunks of CHUNK x CHUNK px of one frame, flat names (i.cy.cx: no directories per
        # frame on disk), written by the workers only where the ball and its shadows change
        # the frame (synth.store.chunk_writer); a region read decodes the 1-4 chunks it
        # touches. zstd level 1: writing took 2.6 ms a frame instead of 3.8 ms at zarr's
        # default level (one 2.6 MB chunk a frame, then), for 2 % more bytes
        g.create_array("clean_diff", shape=(n, H, W), dtype=diff_dtype,
                       chunks=(1, min(CHUNK, H), min(CHUNK, W)), fill_value=0,
                       chunk_key_encoding={"name": "v2", "separator": "."},
                       compressors=[ZstdCodec(level=1)])
        batches = [np.arange(s, min(s + BATCH, n)) for s in range(0, n, BATCH)]
        bar = tqdm(total=n, unit="frame", desc="render", disable=not progress)
        if schedule is not None:
            schedule.update(start=t_start, submitted=time.time(), batches=[],
                            workers=workers)
        init = (scene.to_dict(), r_ball, r_cyl, str(tmp), threads, oval, int(seed), defocus)
        if workers == 1:
            _worker_init(*init)
            try:
                for b in batches:
                    bar.update(_worker_batch(b, centres[b]))
            finally:
                _W.pop("renderer").close()
                _W.clear()
        elif early:
            # the background as the processes subtract it, for them to read without zarr
            bg_file = tmp / BACKGROUND_FILE
            np.save(bg_file, (bg if bg_ideal is None else bg_ideal).astype(bg_dtype))
            spec = (writer_layout(g, g["clean_diff"]), str(bg_file))
            try:
                _render_parallel(batches, centres, workers, start, bar,
                                 initializer=_worker_start,
                                 batch_fn=functools.partial(_worker_batch_in, str(tmp), spec),
                                 pool=pool,
                                 schedule=None if schedule is None else schedule["batches"])
            finally:
                bg_file.unlink(missing_ok=True)
        else:
            _render_parallel(batches, centres, workers, init, bar)
        bar.close()
        g.attrs.update({
            "format": FORMAT,
            "setup": setup.to_toml_dict(),
            "scene": scene.to_dict(),
            "sensor": sensor.to_dict(),
            "sensor_noise": sensor_noise(),
            "seed": int(seed),
            "scenario": _scenario_dict(traj),
            "engine_meta": _jsonable(_engine_meta(traj)),
            "versions": _versions(),
            "fps": float(setup.fps),
            "n_frames": int(n),
            "subframes": int(k_sub),
            "background_scale": int(scale),
            "frame_scale": int(frame_scale),
            "gamma": 2.2,
            "truth_columns": TRUTH_COLUMNS,
            **({"timing": timing_attrs} if timing_attrs is not None else {}),
        })
    return out


def sensor_noise() -> str:
    """The noise generator a recording's frames get when read (``synth.sensor.NOISE``),
    imported here, not where this module is: a render process (:mod:`synth.preload`) needs
    no sensor model nor its numba kernels (~0.25 s of the fork server's imports).

    Returns
    -------
    str
    """
    from synth.sensor import NOISE

    return NOISE


def is_recording(path) -> bool:
    """True if ``path`` is a folder holding a synth recording (a Zarr group whose attrs say
    so): what ``render(..., overwrite=True)`` may replace."""
    import json

    meta = Path(path) / "zarr.json"
    try:
        return json.loads(meta.read_text()).get("attributes", {}).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        return False


def check_output(out, *, overwrite: bool, what: str = "output") -> Path:
    """``out`` as a Path if a recording may be written there: absent, an empty folder, or (with
    ``overwrite``) an earlier recording; SynthError otherwise (a file, a folder of something
    else, an unwritable place). Checked before any work."""
    from rollfric.output.atomic import is_leftover
    from rollfric.output.folder import OutputError, check_folder

    out = Path(out)
    if out.is_dir() and any(not is_leftover(p) for p in out.iterdir()):
        if not overwrite:
            raise SynthError(f"{what} exists: {out} (use overwrite=True / --overwrite)")
        if not is_recording(out):
            raise SynthError(f"{what} {out} is a folder that does not hold a synth recording: "
                             "not replaced, even with --overwrite")
    try:
        check_folder(out, {}, overwrite=True, what=what, command="render")
    except OutputError as exc:
        raise SynthError(str(exc)) from None
    return out


def _scenario_dict(traj) -> dict:
    sc = getattr(traj, "scenario", None)
    if sc is None:
        return {}
    return _jsonable(sc.to_toml_dict() if hasattr(sc, "to_toml_dict") else dict(sc))


def _engine_meta(traj) -> dict:
    """The simulation's metadata as a recording stores it: everything the engine reported
    but how long it ran (``wall_time_s``), which differs from run to run: the same case and
    seed give a recording of the same bytes, every file of it.

    Parameters
    ----------
    traj : sim.Trajectory
        The simulated trajectory (its ``meta`` dict, if any).

    Returns
    -------
    dict
        ``traj.meta`` without its run-dependent keys.
    """
    meta = getattr(traj, "meta", None) or {}
    return {k: v for k, v in meta.items() if k not in RUN_DEPENDENT_META}


def _jsonable(obj):
    import json

    return json.loads(json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist")
                                 else str(o)))


def _head(traj, n: int):
    import dataclasses

    import sim

    fields = {}
    for f in dataclasses.fields(sim.Trajectory):
        v = getattr(traj, f.name)
        fields[f.name] = v[:n] if isinstance(v, np.ndarray) else v
    return sim.Trajectory(**fields)
