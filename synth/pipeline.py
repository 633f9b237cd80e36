"""Render a trajectory into a synthetic recording (a Zarr store), in parallel processes.

:func:`render` is the recipe: the trajectory at the camera's frame times, the truth, the
ball-free frame, the store's arrays, then the frames in batches by render processes
(:mod:`synth.pool`, each running :mod:`synth.worker` with a backend of :mod:`synth.backends`),
and the recording's attributes.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import functools
import json
import os
import time
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
from tqdm import tqdm

import sim
from rollfric.output.atomic import is_leftover, replacing
from rollfric.output.folder import OutputError, check_folder
from rollfric.setup.lens import Calibration
from rollfric.setup.model import Setup
from synth import pool, worker
from synth.backends import make_backend
from synth.camera import CameraModel
from synth.chunks import CHUNK, writer_layout
from synth.config import SceneConfig, SensorConfig, SynthError
from synth.defocus import Defocus
from synth.distortion import cached_window, distort_image
from synth.motion import camera_frames, load_trajectory, subframe_positions, truth_table
from synth.pool import BATCH, MAX_POOL_RESTARTS, start_fork_server
from synth.store import FORMAT, TRUTH_COLUMNS

# the background the render processes subtract, in the store's folder while they render
BACKGROUND_FILE = ".render-background.npy"
# the simulation's metadata a recording leaves out: it differs from run to run of one case
RUN_DEPENDENT_META = ("wall_time_s",)

__all__ = ["BATCH", "MAX_POOL_RESTARTS", "check_output", "is_recording", "load_trajectory",
           "prepare_render", "render", "render_workers", "sensor_noise",
           "start_fork_server", "subframe_positions", "truth_table", "versions"]


# -- the recording's metadata ------------------------------------------------------------------

def versions() -> dict:
    """The installed versions of what a recording depends on (a recording's ``versions``).

    Returns
    -------
    dict
        Distribution name -> version, for those installed.
    """
    out = {}
    for dist in ("rollfric", "pyrender-maintained", "pyrender2", "pyrender", "numpy", "zarr",
                 "PyOpenGL", "trimesh", "mitsuba", "drjit"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            pass
    return out


# -- render processes -------------------------------------------------------------------------

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
    (:func:`synth.pool.start_fork_server`, ~1 s of imports), if it uses one. For a caller with other
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
    traj, timing_attrs = camera_frames(load_trajectory(trajectory), frames, timing, seed)
    workers = render_workers(scene, len(traj), workers)
    if workers > 1 and not scene.camera.thin_lens:
        start_fork_server()  # its imports (~1 s) while this process prepares
    plan = _Plan.of(scene, traj, _setup(traj, scene.camera, sensor), sensor, seed, workers,
                    threads)
    # the render processes start (imports, EGL, programs, meshes: ~1.5 s) while this process
    # prepares. pyrender's background is drawn by the first render process that is ready (it
    # has imported pyrender anyway): this process imports neither pyrender nor trimesh; the
    # others draw the first frame meanwhile (their first frame's set-up)
    remote = bool(plan.early) and scene.renderer == "pyrender"
    first = [worker.background] + [functools.partial(worker.warm, plan.centres[0])] * (
        plan.early - 1)
    with pool.early_pool(plan.early, worker.start, plan.start_args(),
                         first if remote else ()) as (procs, submitted), \
            replacing(out, folder_ok=True) as tmp:
        # Zarr (~0.16 s of imports in a process that has not loaded it, as `rollfric
        # validate`'s) once the render processes are starting: they need not wait for it
        import zarr

        # what needs no background first (~30 ms: the truth), while a process draws it
        g = zarr.open_group(str(tmp), mode="w")
        _write_truth(g, plan, timing)
        drawn = None
        if remote:
            try:
                levels, scale = submitted()[0].result()
                drawn = (levels.astype(np.uint64), scale)  # render_full's dtype
            except cf.process.BrokenProcessPool:  # drawn here; the batches in a new pool
                procs = None
        background = _background(plan, drawn)
        bg_dtype = _create_arrays(g, plan, *background[:3])
        bar = tqdm(total=len(traj), unit="frame", desc="render", disable=not progress)
        if schedule is not None:
            schedule.update(start=t_start, submitted=time.time(), batches=[],
                            workers=workers)
        _render_batches(plan, tmp, g, bg_dtype, background, bar, procs,
                        None if schedule is None else schedule["batches"])
        bar.close()
        g.attrs.update(_attrs(plan, sensor, background[2], timing_attrs))
    return out


# -- the recipe's steps ------------------------------------------------------------------------

@dataclasses.dataclass
class _Plan:
    """One recording's render: what its steps share."""

    scene: SceneConfig
    traj: sim.Trajectory
    setup: Setup
    centres: np.ndarray  # (N, K, 3) the ball's centres at each frame's K sub-frames (m)
    seed: int
    workers: int
    threads: int | None
    oval: tuple  # the bore as built: (ovality, ovality_angle), drawn as its ellipse

    @classmethod
    def of(cls, scene, traj, setup, sensor, seed, workers, threads) -> _Plan:
        if threads is None and workers > 1:
            threads = 1  # one llvmpipe thread per process: the processes fill the cores
        return cls(scene, traj, setup,
                   subframe_positions(traj, scene.motion_blur, sensor.exposure), int(seed),
                   workers, threads, (traj.scenario.ovality, traj.scenario.ovality_angle))

    @property
    def early(self) -> int:
        """Render processes started before the store is written (none for a thin lens:
        they need the background's layers first)."""
        return self.workers if self.workers > 1 and not self.scene.camera.thin_lens else 0

    def start_args(self) -> tuple:
        """:func:`synth.worker.start`'s arguments."""
        return (self.scene.to_dict(), self.setup.ball_radius, self.setup.cylinder_radius,
                self.threads, self.oval, self.seed)

    def init_args(self, store_path, defocus) -> tuple:
        """:func:`synth.worker.init`'s arguments."""
        return (self.scene.to_dict(), self.setup.ball_radius, self.setup.cylinder_radius,
                str(store_path), self.threads, self.oval, self.seed, defocus)


def _setup(traj, cam: CameraModel, sensor: SensorConfig) -> Setup:
    """rollfric's setup of the recording: the simulation's, seen by camera ``cam``."""
    base = traj.setup()
    # the camera's effective bit depth (camera.bit_depth) where rollfric's setup knows the key
    # and the words hold more bits than the sensor gives (10-14 bits in 16-bit words)
    bits = {"bit_depth": sensor.bit_depth} if (
        "bit_depth" in Setup.__dataclass_fields__ and sensor.dtype == "uint16") else {}
    return Setup(cylinder_radius=base.cylinder_radius, ball_diameter=base.ball_diameter,
                 ball_mass=base.ball_mass, fps=base.fps, pixel_size=cam.pixel_size,
                 center_px=cam.center_px, gravity=base.gravity, air_density=base.air_density,
                 calibration=None if cam.lens is None else
                 Calibration(cam.lens.matrix, cam.lens.distortion), **bits)


def _write_truth(g, plan: _Plan, timing) -> None:
    """The truth table (and the camera's timestamps) into the store's group ``g``."""
    tg = g.create_group("truth")
    for name, values in truth_table(plan.traj, plan.scene.camera, plan.setup.ball_radius).items():
        arr = tg.create_array(name, data=np.asarray(values, dtype=np.float64))
        arr.attrs["description"] = TRUTH_COLUMNS[name]
    if timing is not None and timing.timestamps:  # the camera's own time of each frame
        ts = g.create_array("timestamps", data=np.asarray(plan.traj.t, dtype=np.float64))
        ts.attrs["description"] = "time of each frame's exposure (s), the camera's clock"


def _background(plan: _Plan, drawn=None) -> tuple:
    """(the ball-free frame as recorded, the same of the ideal camera or None without a lens,
    its scale, the thin lens's (face, bore, sharp frame) or None); ``drawn``: (levels, scale)
    a render process drew, else drawn here."""
    scene, cam = plan.scene, plan.scene.camera
    defocus = None
    if drawn is not None:
        bg, scale = drawn
    else:
        sr = make_backend(scene, plan.setup.ball_radius, plan.setup.cylinder_radius, plan.seed,
                          oval=plan.oval)
        bg = sr.render_full()
        if cam.thin_lens:  # the layers' blur (synth.defocus), in the ideal frame
            face, bore = sr.layer_coverage()
            defocus = (face, bore, bg)
            blurred = Defocus(scene.replace(camera=cam.ideal()), face, bore,
                              plan.setup.ball_radius).background(bg)
            bg = np.clip(np.rint(blurred), 0, None).astype(bg.dtype)
        sr.close()
        scale = sr.scale
    if cam.lens is None:
        return bg, None, scale, defocus
    bent = np.rint(distort_image(bg, cached_window(cam.lens, cam.width, cam.height)))
    return bent, bg, scale, defocus


def _create_arrays(g, plan: _Plan, bg, bg_ideal, scale) -> str:
    """The store's background arrays and its (empty) frame array; returns the backgrounds'
    dtype."""
    from zarr.codecs import ZstdCodec

    n = len(plan.traj)
    H, W = plan.scene.camera.height, plan.scene.camera.width
    bg_dtype = "uint16" if scale <= 65535 else "uint32"
    g.create_array("background_clean", data=bg.astype(bg_dtype), chunks=(H, W))
    if bg_ideal is not None:  # what the workers subtract from the ideal tiles
        g.create_array("background_ideal_clean", data=bg_ideal.astype(bg_dtype),
                       chunks=bg_ideal.shape)
    diff_dtype = "int16" if scale * plan.scene.motion_blur <= 32767 else "int32"
    # chunks of CHUNK x CHUNK px of one frame, flat names (i.cy.cx: no directories per
    # frame on disk), written by the workers only where the ball and its shadows change
    # the frame (synth.chunks.chunk_writer); a region read decodes the 1-4 chunks it
    # touches. zstd level 1: writing took 2.6 ms a frame instead of 3.8 ms at zarr's
    # default level (one 2.6 MB chunk a frame, then), for 2 % more bytes
    g.create_array("clean_diff", shape=(n, H, W), dtype=diff_dtype,
                   chunks=(1, min(CHUNK, H), min(CHUNK, W)), fill_value=0,
                   chunk_key_encoding={"name": "v2", "separator": "."},
                   compressors=[ZstdCodec(level=1)])
    return bg_dtype


def _render_batches(plan: _Plan, tmp: Path, g, bg_dtype: str, background: tuple, bar,
                    procs=None, schedule: list | None = None) -> None:
    """Every frame's batch: in this process (one worker), in the processes started early
    (``procs``, or a fresh pool if they broke), or in a pool started now (a thin lens)."""
    n, centres = len(plan.traj), plan.centres
    batches = [np.arange(s, min(s + BATCH, n)) for s in range(0, n, BATCH)]
    bg, bg_ideal, _, defocus = background
    if plan.workers == 1:
        worker.init(*plan.init_args(tmp, defocus))
        try:
            for b in batches:
                bar.update(worker.batch(b, centres[b]))
        finally:
            worker.close()
    elif plan.early:
        # the background as the processes subtract it, for them to read without zarr
        bg_file = tmp / BACKGROUND_FILE
        np.save(bg_file, (bg if bg_ideal is None else bg_ideal).astype(bg_dtype))
        spec = (writer_layout(g, g["clean_diff"]), str(bg_file))
        try:
            pool.render_parallel(batches, centres, plan.workers, plan.start_args(), bar,
                                 initializer=worker.start,
                                 batch_fn=functools.partial(worker.batch_in, str(tmp), spec),
                                 pool=procs, schedule=schedule)
        finally:
            bg_file.unlink(missing_ok=True)
    else:
        pool.render_parallel(batches, centres, plan.workers, plan.init_args(tmp, defocus), bar,
                             initializer=worker.init, batch_fn=worker.batch)


def _attrs(plan: _Plan, sensor: SensorConfig, scale: int, timing_attrs) -> dict:
    """The recording's attributes."""
    traj, k_sub = plan.traj, plan.scene.motion_blur
    return {
        "format": FORMAT,
        "setup": plan.setup.to_toml_dict(),
        "scene": plan.scene.to_dict(),
        "sensor": sensor.to_dict(),
        "sensor_noise": sensor_noise(),
        "seed": plan.seed,
        "scenario": _scenario_dict(traj),
        "engine_meta": _jsonable(_engine_meta(traj)),
        "versions": versions(),
        "fps": float(plan.setup.fps),
        "n_frames": len(traj),
        "subframes": int(k_sub),
        "background_scale": int(scale),
        "frame_scale": int(scale * k_sub),
        "gamma": 2.2,
        "truth_columns": TRUTH_COLUMNS,
        **({"timing": timing_attrs} if timing_attrs is not None else {}),
    }


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
    meta = Path(path) / "zarr.json"
    try:
        return json.loads(meta.read_text()).get("attributes", {}).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        return False


def check_output(out, *, overwrite: bool, what: str = "output") -> Path:
    """``out`` as a Path if a recording may be written there: absent, an empty folder, or (with
    ``overwrite``) an earlier recording; SynthError otherwise (a file, a folder of something
    else, an unwritable place). Checked before any work."""
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
    return json.loads(json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist")
                                 else str(o)))
