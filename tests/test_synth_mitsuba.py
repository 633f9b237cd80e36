"""The Mitsuba backend (synth.backends.pathtrace): its camera against the exact projection, seeded
bytes, the window-over-background frame against a full path-traced frame, and a case end to end.

Skipped where Mitsuba 3 (or an LLVM >= 16 for Dr.Jit) is absent: the measurement-only install.
Tiny frames and few samples per pixel keep it quick.
"""

import math

import numpy as np
import pytest

from synth.camera import CameraModel
from synth.config import SceneConfig

ms = pytest.importorskip("synth.backends.pathtrace")
_WHY = pytest.importorskip("synth.backends.mitsuba_runtime").available()
pytestmark = pytest.mark.skipif(_WHY is not None, reason=str(_WHY))

R_CYL = 0.0853
R_BALL = 0.005
L = R_CYL - R_BALL


def _centre(theta, z=0.0):
    return np.array([L * math.sin(theta), -L * math.cos(theta), z])


def _crop_camera(c, width, height, at, **kw):
    """A width x height crop of the thesis camera (any projection) with the ball centre
    ``c`` projected at pixel ``at``."""
    cam0 = CameraModel(**kw)
    u, v = cam0.project(c)
    cx, cy = cam0.center_px
    return CameraModel(width=width, height=height,
                       center_px=(cx - (u - at[0]), cy - (v - at[1])), **kw)


@pytest.mark.parametrize("projection,roll", [("orthographic", 0.0), ("orthographic", 0.3),
                                             ("perspective", 0.0), ("perspective", -0.2)])
def test_emitting_sphere_centroid_is_where_the_camera_model_puts_it(projection, roll):
    # a uniformly emitting sphere on black, box pixel filter: a pixel's value is the fraction of
    # its square the silhouette covers; the centroid of that coverage is the silhouette's
    # centre. Perspective at a short distance, ball off the axis: the silhouette centre and the
    # projected sphere centre differ by 0.065 px, so the test tells them apart.
    mi = ms.load()
    c = _centre(0.6 if projection == "perspective" else 0.3)
    # 0.5 mm pixels: a ball of radius 10 px well inside a 48 x 40 frame
    cam = _crop_camera(c, 48, 40, (23.3, 19.6), projection=projection, working_distance=0.25,
                       roll=roll, pixel_size=0.5e-3)
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 1},
        "ball": {"type": "sphere", "center": c.tolist(), "radius": R_BALL,
                 "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1.0] * 3}}}})
    sensor = mi.load_dict(ms.sensor_dict(cam, 0.05, 1.0, 1024))
    img = np.asarray(mi.render(scene, sensor=sensor, seed=1), dtype=float).mean(axis=2)
    yy, xx = np.mgrid[0:cam.height, 0:cam.width]
    area = img.sum()
    cx, cy = (img * xx).sum() / area, (img * yy).sum() / area
    sil, r_px = cam.sphere_silhouette(c[None], R_BALL)
    assert abs(cx - sil[0, 0]) < 0.003 and abs(cy - sil[0, 1]) < 0.003, (cx, cy, sil)
    assert math.sqrt(area / math.pi) == pytest.approx(r_px[0], abs=0.003)
    if projection == "perspective":
        proj = cam.project(c)
        assert np.hypot(cx - proj[0], cy - proj[1]) > 0.05  # 20 times the tolerance


def _tiny_scene(**kw):
    # a 144 x 112 crop of the thesis scene at half its resolution (ball radius 18.6 px), the
    # ball near the trough bottom with backdrop above it and trough below
    c = _centre(0.05)
    cam = _crop_camera(c, 144, 112, (70.2, 50.7), pixel_size=2 * 0.1343e-3)
    return SceneConfig(camera=cam, renderer="mitsuba", **kw), c


def test_pasted_window_equals_full_render_within_monte_carlo_noise():
    cfg, c = _tiny_scene(mitsuba_spp=16, mitsuba_background_spp=64)
    sr = ms.MitsubaRenderer(cfg, R_BALL, R_CYL, seed=3)
    cam = cfg.camera
    full = (0, 0, cam.width, cam.height)
    a = sr.render_window_rgb(c, full, 16, seed=11)  # two independent full renders
    b = sr.render_window_rgb(c, full, 16, seed=12)
    bg = sr.render_window_rgb(None, full, 16, seed=13)
    (x0, y0, w, h), = sr.tiles_for(c[None])
    win = sr._window(x0, y0, w, h)
    pasted = bg.copy()
    wx, wy, ww, wh = win
    pasted[wy:wy + wh, wx:wx + ww] = sr.render_window_rgb(c, win, 16, seed=14)
    assert cam.width * cam.height - ww * wh > 3000, win  # pixels outside the window are tested
    # both differences are between independent estimates at the same samples per pixel: if
    # the pasted frame is an unbiased estimate of the same image their spreads agree, and
    # their means agree with zero, inside the window and outside it. Radiance clipped at white
    # as the store does (the lamps' highlights on the ball are thousands of times brighter)
    a, b, pasted = (np.clip(x, 0.0, 1.0) for x in (a, b, pasted))
    d_ref = (a - b).mean(axis=2)
    d = (pasted - a).mean(axis=2)
    inside = np.zeros(d.shape, dtype=bool)
    inside[wy:wy + wh, wx:wx + ww] = True
    for m in (inside, ~inside):
        ratio = (d[m] ** 2).sum() / (d_ref[m] ** 2).sum()
        assert 0.8 < ratio < 1.25, ratio
        sigma = d_ref[m].std() / math.sqrt(m.sum())
        assert abs(d[m].mean()) < 4 * sigma, (d[m].mean(), sigma)
    # and the ball does change the frame: the window is not backdrop alone
    assert np.abs(a - bg).max() > 0.2


def test_samples_spent_where_the_noise_is_leave_the_mean_frame_unchanged():
    # mitsuba_spp on the ball's rim and edge and in its shadows' penumbra, 4x that on the
    # lamps' highlights, mitsuba_base_spp elsewhere, and the ball-free frame's own pixels
    # where the ball changes nothing (outside its footprint, the trough's front face): the
    # pasted frame is an unbiased estimate of a full frame in every one of those classes
    cfg, c = _tiny_scene(mitsuba_spp=64, mitsuba_base_spp=16, mitsuba_background_spp=64)
    sr = ms.MitsubaRenderer(cfg, R_BALL, R_CYL, seed=3)
    cam = cfg.camera
    full = (0, 0, cam.width, cam.height)
    bg = ms.to_levels(sr.render_window_rgb(None, full, 64, seed=21))
    sr.set_background(bg)
    tiles = sr.tiles_for(c[None])
    plan = np.full(bg.shape, -1)
    pasted = bg.copy()
    for (x0, y0, w, h), img in zip(tiles, sr.render_tiles([c], tiles, index=4), strict=True):
        pasted[y0:y0 + h, x0:x0 + w] = img
        plan[y0:y0 + h, x0:x0 + w] = sr.spp_map(c, (x0, y0, w, h))
    again = sr.render_tiles([c], tiles, index=4)
    assert all(np.array_equal(pasted[y:y + h, x:x + w], a)
               for (x, y, w, h), a in zip(tiles, again, strict=True))  # same seed, same bytes
    assert set(np.unique(plan)) == {-1, 0, 16, 64, 256}, np.unique(plan)
    a, b = (ms.to_levels(sr.render_window_rgb(c, full, 64, seed=s)).astype(float)
            for s in (22, 23))
    d_ref = a - b
    d = pasted - a
    for k in (-1, 0, 16, 64, 256):  # outside the tiles, unchanged, base, rim, highlights
        m = plan == k
        sigma = math.sqrt((d[m].var() + d_ref[m].var() / 2) / m.sum())
        assert abs(d[m].mean()) < 4 * sigma, (k, d[m].mean(), sigma)
    # the rim's pixels were traced with their own samples (not the background's) and the
    # ball changes the frame there
    assert np.abs(a - bg)[plan == 64].mean() > 100


def test_same_seed_same_bytes(tmp_path):
    import sim
    import synth

    cfg, _ = _tiny_scene(mitsuba_spp=4, mitsuba_background_spp=4)
    traj = sim.simulate(sim.Scenario(theta0=0.05, duration=0.002))
    out = []
    for name, seed in (("a", 5), ("b", 5), ("c", 6)):
        p = synth.render(traj, tmp_path / f"{name}.zarr", scene=cfg, seed=seed)
        rec = synth.open_recording(p)
        out.append((np.asarray(rec.frames[1]), np.asarray(rec.background)))
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])
    assert not np.array_equal(out[0][0], out[2][0])


def test_short_case_end_to_end_on_the_mitsuba_backend():
    from validation.case_dict import small_case_dict
    from validation.e2e import run_case

    # 61 frames of a 160 x 96 px camera at twice the thesis's pixel size (ball radius 18.6 px),
    # the lab measured the trough centre; 16 samples per pixel
    d = small_case_dict(0.06)
    d["scenario"]["motion"]["theta0_deg"] = 4.0
    d["render"].update(renderer="mitsuba", noise="realistic",
                       camera={"width": 160, "height": 96, "center_px": [80.0, -251.0],
                               "pixel_size": 2 * 0.1343e-3},
                       scene={"mitsuba_spp": 16, "mitsuba_background_spp": 16})
    res = run_case(d, render_workers=1)
    m = res.metrics
    assert m["n_frames"] == 61
    assert m["center_rms_px"] < 0.5, m["center_rms_px"]
    assert m["theta_rms_rad"] < 2e-3, m["theta_rms_rad"]


_VARIANT_SCRIPT = """
import logging, sys
import numpy as np
logging.basicConfig(level=logging.WARNING)
sys.path.insert(0, sys.argv[2])
import test_synth_mitsuba as t
cfg, c = t._tiny_scene(mitsuba_spp=16, mitsuba_background_spp=16)
sr = t.ms.MitsubaRenderer(cfg, t.R_BALL, t.R_CYL, seed=3)
np.save(sys.argv[1], sr.render_window_rgb(c, (0, 0, 144, 112), 16, seed=12))
print(t.ms.variant())
"""


def _in_subprocess(tmp_path, **env):
    import os
    import subprocess
    import sys
    from pathlib import Path

    here = Path(__file__).resolve().parent
    e = dict(os.environ, PYTHONPATH=os.pathsep.join([str(here.parent),
                                                     os.environ.get("PYTHONPATH", "")]), **env)
    out = tmp_path / "img.npy"
    p = subprocess.run([sys.executable, "-c", _VARIANT_SCRIPT, str(out), str(here)], env=e,
                       capture_output=True, text=True, timeout=600)
    return p, (np.load(out) if out.exists() else None)


def test_scalar_fallback_renders_the_same_image_within_monte_carlo_noise(tmp_path):
    # forced by the environment, as where Dr.Jit's LLVM backend cannot start: Mitsuba's own
    # path tracer (C++) in the scalar variant gives the frame synth's path tracer gives
    p, img = _in_subprocess(tmp_path, ROLLFRIC_MITSUBA_VARIANT="scalar_rgb")
    assert p.returncode == 0, p.stderr
    assert p.stdout.split()[-1] == "scalar_rgb"
    cfg, c = _tiny_scene(mitsuba_spp=16, mitsuba_background_spp=16)
    sr = ms.MitsubaRenderer(cfg, R_BALL, R_CYL, seed=3)
    a = sr.render_window_rgb(c, (0, 0, 144, 112), 16, seed=13)
    b = sr.render_window_rgb(c, (0, 0, 144, 112), 16, seed=14)
    a, b, img = (np.clip(x, 0.0, 1.0) for x in (a, b, img))
    d_ref = (a - b).mean(axis=2)
    d = (img - a).mean(axis=2)
    ratio = (d ** 2).sum() / (d_ref ** 2).sum()
    assert 0.8 < ratio < 1.25, ratio
    assert abs(d.mean()) < 4 * d_ref.std() / math.sqrt(d.size), (d.mean(), d_ref.std())


def test_without_llvm_the_backend_says_so_and_falls_back(tmp_path):
    p, img = _in_subprocess(tmp_path, DRJIT_LIBLLVM_PATH=str(tmp_path / "no-libLLVM.so"))
    assert p.returncode == 0, p.stderr
    assert p.stdout.split()[-1] == "scalar_rgb"
    assert "llvm_ad_rgb variant cannot start: no LLVM library found" in p.stderr
    assert "libllvm19" in p.stderr and "Rendering with scalar_rgb" in p.stderr
    assert img.shape == (112, 144, 3) and np.isfinite(img).all()
    # forcing the LLVM variant there, or naming another variant, is an error that says why
    p, _ = _in_subprocess(tmp_path, DRJIT_LIBLLVM_PATH=str(tmp_path / "no-libLLVM.so"),
                          ROLLFRIC_MITSUBA_VARIANT="llvm_ad_rgb")
    assert p.returncode != 0 and "no LLVM library found" in p.stderr
    p, _ = _in_subprocess(tmp_path, ROLLFRIC_MITSUBA_VARIANT="cuda_ad_rgb")
    assert p.returncode != 0 and "must be llvm_ad_rgb or scalar_rgb" in p.stderr
