"""``rollfric bench``: speed and accuracy of every stage beside the baseline a user would pick.

One run, one machine, the same inputs for a method and its baseline. Every row names its
baseline and gives the ratio (speed-up, or accuracy gain) over it: this machine is shared and
noisy, so ratios are the headline and absolute times are medians of repeats.

Sections: fitting (least squares vs the thesis's grid search and eps iteration), simulation
(each engine's accurate contact vs the naive mesh surface), rendering (tile renderer vs plain
full-frame pyrender of the same scene), recognition (default locator vs the thesis's locators,
OpenCV HoughCircles and scikit-image RANSAC circle fit, beside the Cramer-Rao bound), and the
default ``rollfric validate`` case end to end (:mod:`validation.bench.e2e`), a sweep on Dask
(:mod:`validation.bench.sweep`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import platform
import statistics
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

import sim
from rollfric.fit import eom
from rollfric.fit.estimate import fit_mu
from rollfric.fit.start import initial_guess
from rollfric.fit.thesis import PAPER2_GRID, fit_paper2_grid
from rollfric.output.folder import check_folder, staged_folder
from rollfric.setup.model import thesis_setup
from synth.backends import make_backend
from synth.backends.mitsuba_runtime import available
from synth.pipeline import subframe_positions
from validation.bench import e2e, locate, sweep
from validation.bench.render import render_benchmark
from validation.bench.table import Row
from validation.bench.table import fmt as _fmt
from validation.case import case_from_dict


def median_time(fn, repeats: int, warmup: bool = True) -> tuple[float, object]:
    """Median wall time of ``repeats`` calls of fn (after a warm-up call) and its result."""
    if warmup:
        fn()
    times = []
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


# --------------------------------------------------------------------------------- fitting
def bench_fit(quick: bool) -> list[Row]:
    """Least-squares fit vs the thesis's grid search (paper 2) and eps iteration (paper 1)."""
    rows = []
    t = np.arange(4000) / 1000.0
    cases = [("10mm", 0.0079, 20.0)] if quick else [
        ("10mm", 0.0079, 20.0), ("12.69mm", 0.0065, 20.0), ("1.58mm", 0.0164, 12.0)]
    sigma = math.radians(0.02)
    for ball, mu, th0 in cases:
        setup = thesis_setup(ball)
        truth, _, _ = eom.solve_reference(math.radians(th0), 0.0, mu, t,
                                          track_radius=setup.track_radius)
        noisy = truth + np.random.default_rng(0).normal(0, sigma, t.size)
        label = f"{ball}, mu {mu}, theta0 {th0:g} deg, 4000 samples"
        sec_lsq, r_clean = median_time(lambda s=setup, y=truth: fit_mu(t, y, s), 5)
        r_noisy = fit_mu(t, noisy, setup)
        # the grid search, from the same self-started first estimate
        first = initial_guess(t, noisy, setup)
        if quick:
            # time 1/21 of the grid (one mu value) and scale to the whole grid
            n_mu = 2 * round(PAPER2_GRID["mu"][0] / PAPER2_GRID["mu"][1]) + 1
            t0 = time.perf_counter()
            fit_paper2_grid(t, noisy, setup, first=first, grid={"mu": (0.0, 1.0)})
            sec_grid = (time.perf_counter() - t0) * n_mu
            r_grid = None
            grid_note = "grid time extrapolated from 1 of its 21 mu values (--quick)"
        else:
            t0 = time.perf_counter()
            r_grid = fit_paper2_grid(t, noisy, setup, first=first)
            sec_grid = time.perf_counter() - t0
            grid_note = "28413 Runge-Kutta solutions"
        rows.append(Row("fitting", f"lsq fit time ({label})", sec_lsq, "s",
                        "thesis grid search (paper 2)", sec_grid, sec_grid / sec_lsq, "speed-up",
                        grid_note))
        err_clean = abs(r_clean.mu / mu - 1)
        err_noisy = abs(r_noisy.mu / mu - 1)
        rows.append(Row("fitting", f"lsq mu error, noiseless ({label})", err_clean, "rel"))
        if r_grid is not None:
            err_grid = abs(r_grid.mu / mu - 1)
            rows.append(Row("fitting", f"lsq mu error, 0.02 deg noise ({label})", err_noisy,
                            "rel", "thesis grid search", err_grid,
                            err_grid / max(err_noisy, 1e-12), "accuracy",
                            "grid resolution in mu is 1e-4"))
        else:
            rows.append(Row("fitting", f"lsq mu error, 0.02 deg noise ({label})", err_noisy,
                            "rel", note=f"mu_stderr {r_noisy.mu_stderr / mu:.1e} rel"))
    # paper 1 on its own ground: the small ball at a small angle
    setup = thesis_setup("1.58mm")
    mu = 0.0229  # the paper's eps = 1.9012 1/s^2 in our convention
    truth, _, _ = eom.solve_reference(math.radians(12.07), 0.0, mu, t,
                                      track_radius=setup.track_radius)
    noisy = truth + np.random.default_rng(1).normal(0, sigma, t.size)
    sec_p1, r_p1 = median_time(lambda: fit_mu(t, noisy, setup, method="paper1_eps"), 1)
    sec_l, r_l = median_time(lambda: fit_mu(t, noisy, setup), 1)
    e_p1, e_l = abs(r_p1.mu / mu - 1), abs(r_l.mu / mu - 1)
    rows.append(Row("fitting", "lsq mu error vs paper 1's eps iteration (1.58mm, 12.07 deg, "
                    "0.02 deg noise)", e_l, "rel", "paper 1 eps iteration", e_p1,
                    e_p1 / max(e_l, 1e-12), "accuracy",
                    f"times: lsq {sec_l:.3f} s, paper 1 {sec_p1:.3f} s; paper 1 is "
                    "biased by its sin(theta) ~ theta model"))
    return rows


# ------------------------------------------------------------------------------ simulation
def bench_sim(quick: bool) -> list[Row]:
    """Seconds for 4 s of motion per engine (accurate contact) and mu bias vs the naive mesh."""
    rows = []
    base = sim.Scenario()
    ref = sim.simulate(base)
    for engine in ("reference", "mujoco", "pybullet"):
        sc = dataclasses.replace(base, engine=engine)
        sec, traj = median_time(lambda sc=sc: sim.simulate(sc), 1 if quick else 3)
        setup = sc.setup()
        mu_fit = fit_mu(traj.t, traj.theta, setup).mu
        err = abs(mu_fit / sc.mu - 1)
        dev = np.degrees(np.max(np.abs(traj.theta - ref.theta)))
        note = f"max angle error vs reference {dev:.3f} deg"
        if engine == "reference":
            rows.append(Row("simulation", "reference ODE: 4 s of motion", sec, "s",
                            "real time (4 s)", sc.duration, sc.duration / sec, "speed-up",
                            f"mu recovered to {err:.1e} rel"))
            continue
        naive = dataclasses.replace(sc, surface="mesh")
        sec_n, traj_n = median_time(lambda n=naive: sim.simulate(n), 1, warmup=False)
        err_n = abs(fit_mu(traj_n.t, traj_n.theta, setup).mu / sc.mu - 1)
        rows.append(Row("simulation", f"{engine} tangent contact: 4 s of motion", sec, "s",
                        f"{engine} concave mesh", sec_n, sec_n / sec, "speed-up", note))
        rows.append(Row("simulation", f"{engine} tangent contact: mu bias", err, "rel",
                        f"{engine} concave mesh", err_n, err_n / max(err, 1e-12), "accuracy",
                        "10mm ball, mu 0.0079, theta0 20 deg"))
    return rows


# ------------------------------------------------------------------------------- rendering
def bench_render(quick: bool) -> list[Row]:
    """synth's tile frames (lean path, pyrender's path) vs stock pyrender's full frame of the
    same scene, where a frame's time goes, a whole recording, its size and reads
    (validation.bench.render)."""
    r = render_benchmark(quick=quick)
    frame = f"{r['frame']} {r['projection']}, {r['lamps']} lamps, shadows {r['shadows']}"
    stages = r["lean_frame_stages_ms"]
    total = sum(stages.values()) or math.nan
    rows = [
        Row("rendering", f"tile frame, synth's lean draw path, one process ({frame})",
            r["synth_tile_ms"], "ms/frame", "stock pyrender, full frame, same scene",
            r["full_frame_ms"], r["full_frame_ms"] / r["synth_tile_ms"], "speed-up",
            f"max difference from stock {r['max_diff_dn']:g} DN; median tile "
            f"{r['tile_pixels_median']} px"),
        Row("rendering", "tile frame, pyrender's renderer functions (the path before), one "
            "process", r["synth_tile_pyrender_path_ms"], "ms/frame",
            "stock pyrender, full frame, same scene", r["full_frame_ms"],
            r["full_frame_ms"] / r["synth_tile_pyrender_path_ms"], "speed-up",
            f"max difference from stock {r['max_diff_dn_pyrender_path']:g} DN; the lean path "
            f"is {r['lean_over_pyrender_path']:g}x faster"),
        Row("rendering", "tile frame, lean path, the ball as the exact sphere (ball_model = "
            "\"sphere\"), one process", r["synth_tile_sphere_ms"], "ms/frame",
            "stock pyrender, full frame, same scene", r["full_frame_ms"],
            r["full_frame_ms"] / r["synth_tile_sphere_ms"], "speed-up",
            f"max difference from stock's mesh ball {r['max_diff_dn_sphere']:g} DN (its "
            "faceted highlights and a multisample of its outline: docs/how/renderer.md)"),
    ]
    for name, ms in stages.items():
        rows.append(Row("rendering", f"lean tile frame: {name}", ms, "ms/frame",
                        note=f"{100 * ms / total:.0f} % of the frame's stages (each waited "
                             "for with glFinish)"))
    for name in ("draw: ball", "shadow maps"):
        if name in r.get("sphere_frame_stages_ms", {}):
            rows.append(Row("rendering", f"lean tile frame, sphere ball: {name}",
                            r["sphere_frame_stages_ms"][name], "ms/frame",
                            "the mesh ball", stages.get(name, math.nan),
                            stages.get(name, math.nan) / r["sphere_frame_stages_ms"][name],
                            "speed-up", "each stage waited for with glFinish"))
    rows += [
        Row("rendering", f"sequence of {r['sequence_frames']} frames (a recording), "
            f"{r['sequence_workers']} processes", r["sequence_ms_per_frame"], "ms/frame",
            "stock pyrender, full frame", r["full_frame_ms"], r["speedup_sequence"], "speed-up",
            ("A RENDER PROCESS DIED in this recording and its batches were rendered again: "
             "its times are not a frame's cost; "
             if r.get("sequence_pool_restarted") else "")
            + f"{r['sequence_fps']:g} frames/s; 4000 frames in ~{r['est_4000_frames_s']:g} s; "
            "target >= 100x"),
        Row("rendering", "the same, frames only (start-up excluded: the recording's own "
            "batches after each process's first)", r["sequence_steady_ms_per_frame"], "ms/frame",
            "stock pyrender, full frame", r["full_frame_ms"], r["speedup_sequence_steady"],
            "speed-up", f"by quarter of the recording "
            f"{' / '.join(f'{q:g}' for q in r.get('sequence_steady_quarters_ms', []))} ms; "
            f"the rest of its time {r['sequence_startup_s']:g} s: "
            f"{r.get('sequence_to_first_batch_s', math.nan):g} s to its first batch (fork "
            f"server and imports, EGL, background, store), first batches "
            f"+{r.get('sequence_first_batch_excess_s', math.nan):g} s (pyrender's first frame), "
            f"end idle {r.get('sequence_end_idle_s', math.nan):g} s; a later recording of the "
            f"same process {r.get('sequence_startup_later_s', math.nan):g} s (the fork server "
            "reused); creating a file in the recording's folder "
            f"{r.get('sequence_file_create_ms', math.nan):g} ms (~2 a frame)"),
        Row("rendering", "recording size for 4000 frames", r["est_store_4000_mb"], "MB",
            "8-bit frames stored raw", 4000 * 1.0e-6 * _pixels(r["frame"]),
            4000 * 1.0e-6 * _pixels(r["frame"]) / r["est_store_4000_mb"], "smaller",
            f"reading applies the seeded sensor model: {r['read_ms_per_frame']:g} ms/frame"),
        Row("rendering", f"read a tracker's region ({r['roi_px']} px) with the sensor model",
            r["read_roi_ms_per_frame"], "ms/frame", "read a full frame",
            r["read_ms_per_frame"], r["read_ms_per_frame"] / r["read_roi_ms_per_frame"],
            "speed-up", f"sensor noise {r.get('sensor_noise', '?')}; of which decoding the "
            f"clean region {r['read_roi_clean_ms_per_frame']:g} ms; the locator's own cost "
            "is in the recognition section (streaming loop)"),
    ]
    return rows + _mitsuba_rows(quick)


def mitsuba_frames(frames: int = 4) -> dict:
    """Time of the Mitsuba backend's frames of the default case (1280 x 1024, thesis lighting):
    the ball's tiles path traced at its default samples per pixel, beside every tile pixel at
    ``mitsuba_spp`` (256).

    Steady state (the first, compiling, frame timed apart); wall and process CPU time (Dr.Jit's
    threads included); the ball-free frame is a stand-in of zeros (its pixels are copied, not
    traced: the time does not depend on their values).

    Parameters
    ----------
    frames : int, optional
        Steady frames timed per variant (spread over 0.3 s of the swing).

    Returns
    -------
    dict
        ``first_s``, ``wall_s``, ``cpu_s`` and ``samples`` (medians per frame) of the default
        sampling, ``uniform_wall_s``, ``uniform_cpu_s``, ``uniform_samples`` of the baseline,
        ``compiled`` (kernels compiled after the first frame), ``spp``, ``base_spp``.
    """
    case = case_from_dict({"render": {"renderer": "mitsuba"},
                           "scenario": {"motion": {"seconds": 0.3}}})
    traj = sim.simulate(case.scenario)
    st = traj.setup()
    centres = subframe_positions(traj, case.scene.motion_blur, case.sensor.exposure)
    sr = make_backend(case.scene, st.ball_radius, st.cylinder_radius, 0)
    import drjit as dr  # after the renderer chose Dr.Jit's LLVM (mitsuba_runtime.load)

    sr.set_background(np.zeros((sr.camera.height, sr.camera.width), dtype=np.int64))
    cfg = sr.config
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    out = {"spp": cfg.mitsuba_spp, "base_spp": cfg.mitsuba_base_spp}

    def run(index):
        tiles = sr.tiles_for(centres[index])
        n = sum(int(sr.spp_map(centres[index][0], t).sum()) for t in tiles)
        dr.kernel_history()
        w0, c0 = time.perf_counter(), time.process_time()  # all threads
        sr.render_tiles([sr.ball_pose(c) for c in centres[index]], tiles, index=index)
        w, c = time.perf_counter() - w0, time.process_time() - c0
        return w, c, n, sum(1 for k in dr.kernel_history() if not k.get("cache_hit", True))

    out["first_s"] = run(0)[0]
    picks = np.linspace(1, len(centres) - 1, frames).astype(int)
    for name, config in (("", cfg), ("uniform_", cfg.replace(mitsuba_base_spp=cfg.mitsuba_spp))):
        sr.config = config
        res = [run(int(i)) for i in picks]
        out[f"{name}wall_s"] = statistics.median(r[0] for r in res)
        out[f"{name}cpu_s"] = statistics.median(r[1] for r in res)
        out[f"{name}samples"] = statistics.median(r[2] for r in res)
        out.setdefault("compiled", sum(r[3] for r in res))
    sr.close()
    return out


def _mitsuba_rows(quick: bool) -> list[Row]:
    item = "Mitsuba frame (path traced), default case 1280x1024, thesis lamps"
    if quick:
        return [Row("rendering", item, math.nan, "s/frame",
                    note="not run with --quick (~20 s; docs/how/renderers.md)")]

    why = available()
    if why is not None:
        return [Row("rendering", item, math.nan, "s/frame", note=f"not run: {why}")]
    m = mitsuba_frames()
    return [Row("rendering", f"{item}, {m['spp']}/{m['base_spp']} spp where the noise is",
                m["wall_s"], "s/frame",
                f"every tile pixel at {m['spp']} spp", m["uniform_wall_s"],
                m["uniform_wall_s"] / m["wall_s"], "speed-up",
                f"CPU {m['cpu_s']:.2f} s (uniform {m['uniform_cpu_s']:.2f} s); "
                f"{m['samples'] / 1e6:.2f} M samples (uniform {m['uniform_samples'] / 1e6:.2f} "
                f"M); first frame {m['first_s']:.2f} s; kernels compiled after it: "
                f"{m['compiled']}; target <= 1 s")]


def _pixels(frame: str) -> int:
    w, h = frame.split("x")
    return int(w) * int(h)


# --------------------------------------------------------------------------------- report
def machine() -> dict:
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu or "unknown", "cores": os.cpu_count(), "python": platform.python_version(),
            "platform": platform.platform()}




def to_markdown(rows: list[Row], meta: dict) -> str:
    lines = [f"Benchmark of {meta['date']} on {meta['machine']['cpu']} "
             f"({meta['machine']['cores']} cores){' --quick' if meta['quick'] else ''}.",
             "", "| section | measured | value | unit | baseline | baseline value | gain | note |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        gain = f"{_fmt(r.gain)}x {r.gain_kind}" if math.isfinite(r.gain) else ""
        lines.append(f"| {r.section} | {r.item} | {_fmt(r.value)} | {r.unit} | {r.baseline} | "
                     f"{_fmt(r.baseline_value)} | {gain} | {r.note} |")
    return "\n".join(lines) + "\n"


SECTIONS = {
    "fitting": bench_fit,
    "simulation": bench_sim,
    "rendering": bench_render,
    "recognition": locate.bench_recognition,
    "end-to-end": e2e.bench_e2e,
    "sweeps": sweep.bench_sweeps,
}  # keys match validation.bench.cli.SECTION_NAMES


# what bench writes into its folder (--overwrite replaces only these)
OUTPUTS = {"bench.md": "file", "bench.json": "file"}


def run_bench(out: str | Path, *, quick: bool = False, sections=None, progress: bool = True,
              overwrite: bool = False):
    """Run the chosen sections (all by default); write bench.md and bench.json into out.

    An existing non-empty ``out`` is refused before any work unless ``overwrite`` (then only
    bench.md and bench.json are replaced; :mod:`rollfric.output.folder`)."""
    from tqdm.auto import tqdm

    out = Path(out)
    check_folder(out, OUTPUTS, overwrite=overwrite, command="bench")
    names = list(sections or SECTIONS)
    rows: list[Row] = []
    timings = {}
    for name in tqdm(names, desc="bench", disable=not progress):
        t0 = time.perf_counter()
        rows.extend(SECTIONS[name](quick))
        timings[name] = time.perf_counter() - t0
    meta = {"date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "machine": machine(), "quick": quick, "section_seconds": timings}
    md = to_markdown(rows, meta)
    data = {"meta": meta, "rows": [
        {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
         for k, v in dataclasses.asdict(r).items()} for r in rows]}
    with staged_folder(out, OUTPUTS, overwrite=overwrite, command="bench") as tmp:
        (tmp / "bench.md").write_text(md, encoding="utf-8")
        (tmp / "bench.json").write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    return rows, meta
