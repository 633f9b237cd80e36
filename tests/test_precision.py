"""The locator's precision: the centre's Cramér-Rao bound (rollfric.locate.precision)."""

import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pytest
import tifffile
from measure_data import make_recording
from scipy import ndimage

from rollfric.cli.main import main
from rollfric.cli.measure import write_track_csv
from rollfric.io.readers import open_recording
from rollfric.locate.precision import centre_crb
from rollfric.locate.subpixel import locate_subpixel
from rollfric.measurement import measure
from rollfric.setup.model import save_setup
from rollfric.track.precision import estimate_precision
from rollfric.track.tracker import TRACK_COLUMNS
from synth.drawn.frames import Scene, background, draw_ball, make_frames, to_dtype
from validation.bench.locate import cramer_rao_rms


@pytest.mark.parametrize("r", [6.0, 17.5, 40.0])
def test_sharp_edge_matches_the_bench_reference(r):
    # the bench's bound adds the 8-bit rounding (1/12 DN^2): the same total variance here
    ref = cramer_rao_rms(r, 80.0, math.sqrt(4.0 - 1.0 / 12.0))
    assert centre_crb(r, 80.0, 2.0) == pytest.approx(ref, rel=0.02)


def test_scales_as_noise_over_contrast_and_grows_with_blur():
    base = centre_crb(15.0, 100.0, 2.0)
    assert centre_crb(15.0, 50.0, 2.0) == pytest.approx(2 * base, rel=1e-9)
    assert centre_crb(15.0, 100.0, 6.0) == pytest.approx(3 * base, rel=1e-9)
    assert centre_crb(15.0, -100.0, 2.0) == pytest.approx(base, rel=1e-9)
    blurred = [centre_crb(15.0, 100.0, 2.0, e) for e in (0.0, 0.5, 1.0, 2.0)]
    assert np.all(np.diff(blurred) > 0)
    assert math.isinf(centre_crb(15.0, 0.0, 2.0))


def _model(cx, cy, r, e, size, ss=16):
    """A disc's area-sampled coverage blurred by a Gaussian of std e px: drawn on a grid ss
    times finer, blurred there and averaged over each pixel."""
    u = (np.arange(size * ss) + 0.5) / ss - 0.5
    xx, yy = np.meshgrid(u, u)
    fine = ((xx - cx) ** 2 + (yy - cy) ** 2 <= r * r).astype(float)
    if e > 0:
        fine = ndimage.gaussian_filter(fine, e * ss, mode="constant", truncate=5.0)
    return fine.reshape(size, ss, size, ss).mean(axis=(1, 3))


@pytest.mark.parametrize("e", [0.0, 1.2])
def test_matches_a_brute_force_fisher_sum_on_a_drawn_image(e):
    # Fisher information from the finite-difference derivative of a drawn model image
    r, c, s, size, h = 9.0, 60.0, 3.0, 32, 0.05
    cx, cy = 15.37, 15.61
    dx = (_model(cx + h, cy, r, e, size) - _model(cx - h, cy, r, e, size)) / (2 * h)
    dy = (_model(cx, cy + h, r, e, size) - _model(cx, cy - h, r, e, size)) / (2 * h)
    ixx = (c / s) ** 2 * np.sum(dx * dx)
    iyy = (c / s) ** 2 * np.sum(dy * dy)
    brute = math.sqrt(1 / ixx + 1 / iyy)
    assert centre_crb(r, c, s, e) == pytest.approx(brute, rel=0.05)


def _drawn(blur, noise=3.0, n=40, seed=1):
    """A drawn recording (a 14 px ball) blurred by a Gaussian of ``blur`` px before its pixel
    noise: (background, frames, track of the true centres, true contrast DN, recording)."""
    rec = make_recording(n, noise=noise, ball_mm=12.0)
    sc = rec.scene
    rng = np.random.default_rng(seed)
    bgf = background(sc)

    def g(a):
        return ndimage.gaussian_filter(a, blur) if blur > 0 else a
    bg = to_dtype(g(bgf), dataclasses.replace(sc, noise=0.0))
    frames = [to_dtype(g(draw_ball(bgf, sc, cx, cy)), sc, rng) for cx, cy in rec.centers]
    track = pd.DataFrame({"x_px": rec.centers[:, 0], "y_px": rec.centers[:, 1], "found": 1})
    contrast = np.mean([abs(sc.ball - bgf[int(round(cy)), int(round(cx))]) * sc.full_scale
                        for cx, cy in rec.centers])
    return bg, frames, track, contrast, rec


@pytest.mark.parametrize("blur", [0.0, 1.0, 2.0])
def test_estimates_the_drawn_contrast_noise_and_edge_width(blur):
    bg, frames, track, contrast, rec = _drawn(blur)
    p = estimate_precision(frames, bg, track, r_px=rec.scene.r_px, n_frames=30)
    noise = math.sqrt(3.0 ** 2 + 1.0 / 12.0)  # the drawn noise and the rounding to integers
    assert p.frames_used == 30
    assert p.contrast_dn == pytest.approx(contrast, rel=0.1)
    assert p.noise_dn == pytest.approx(noise, rel=0.1)
    if blur > 0:
        assert p.edge_sigma_px == pytest.approx(blur, rel=0.1)
    else:
        assert p.edge_sigma_px < 0.3
    truth = centre_crb(rec.scene.r_px, contrast, noise, blur)
    assert p.crb_px == pytest.approx(truth, rel=0.1)
    assert math.isnan(p.reached_px) and math.isnan(p.ratio)


def test_reached_precision_is_the_located_scatter_along_the_path(tmp_path):
    rec = make_recording(160, noise=3.0, ball_mm=12.0, seed=3)
    tifffile.imwrite(tmp_path / "rec.tif", np.stack(rec.frames))
    track, _, result = measure(tmp_path / "rec.tif", rec.setup, rec.background)
    L = rec.setup.track_radius / rec.setup.pixel_size
    p = estimate_precision(open_recording(tmp_path / "rec.tif"), rec.background, track,
                           r_px=rec.scene.r_px, rms_residual_rad=result.rms_residual,
                           track_radius_px=L)
    # the drawn noise's effect: the located centres' scatter along the path about the truth
    scatter = float(np.std((track["theta_rad"].to_numpy() - rec.theta) * L))
    assert scatter / 1.5 < p.reached_px < 1.5 * scatter
    assert p.ratio == pytest.approx(p.reached_px / (p.crb_px / math.sqrt(2)), rel=1e-12)
    assert p.ratio > 1.0  # no unbiased locator beats the bound


def test_too_few_found_frames_give_no_estimate():
    bg, frames, track, _, rec = _drawn(0.0, n=40)
    track["found"] = 0
    p = estimate_precision(frames, bg, track, r_px=rec.scene.r_px, rms_residual_rad=1e-4,
                           track_radius_px=100.0)
    assert p.frames_used == 0 and math.isnan(p.crb_px) and p.reached_px == pytest.approx(0.01)
    assert p.json()["crb_px"] is None and p.json()["reached_px"] == pytest.approx(0.01)


def test_measure_writes_locator_precision_to_fit_json(tmp_path):
    rec = make_recording(160, noise=3.0, ball_mm=12.0, seed=3)
    tifffile.imwrite(tmp_path / "rec.tif", np.stack(rec.frames))
    tifffile.imwrite(tmp_path / "bg.tif", rec.background)
    save_setup(rec.setup, tmp_path / "setup.toml")
    code = main(["measure", str(tmp_path / "rec.tif"), "--setup", str(tmp_path / "setup.toml"),
                 "--background", str(tmp_path / "bg.tif"), "--out", str(tmp_path / "m"),
                 "--no-progress"])
    assert code in (0, 3)
    fit = json.loads((tmp_path / "m" / "fit.json").read_text())
    p = fit["locator_precision"]
    assert set(p) == {"crb_px", "reached_px", "ratio", "contrast_dn", "noise_dn",
                      "edge_sigma_px", "frames_used"}
    L = rec.setup.track_radius / rec.setup.pixel_size
    assert p["reached_px"] == pytest.approx(fit["rms_residual_rad"] * L, rel=1e-9)
    assert p["noise_dn"] == pytest.approx(math.sqrt(9 + 1 / 12), rel=0.1)
    # (the bound is taken at the located radius, within a few 0.01 px of the drawn one)
    assert p["crb_px"] == pytest.approx(centre_crb(rec.scene.r_px, p["contrast_dn"],
                                                   p["noise_dn"], p["edge_sigma_px"]), rel=0.01)
    assert p["frames_used"] == 30
    csv = pd.read_csv(tmp_path / "m" / "track.csv")
    assert list(csv.columns) == TRACK_COLUMNS + ["x_u_px", "y_u_px"]
    assert np.allclose(csv["x_u_px"], csv["y_u_px"])


def test_track_csv_gives_each_axis_share_of_the_locators_sigma(tmp_path):
    # a still ball in 150 noisy drawn frames: x_u_px, y_u_px are the located centres' own
    # scatter per axis
    sc = Scene(width=200, height=200, center=(100.0, -400.0), R_px=600.0, r_px=14.0,
               noise=4.0, spot=0.0)
    c = (100.3, 100.6)
    bg, frames = make_frames(sc, [c] * 150, seed=2)
    locs = [locate_subpixel(f, bg, sc.r_px, guess=c) for f in frames]
    track = pd.DataFrame({"frame": np.arange(150), "t_s": np.arange(150) / 100.0,
                          "x_px": [loc.x for loc in locs], "y_px": [loc.y for loc in locs],
                          "theta_rad": 0.0, "found": [int(loc.found) for loc in locs],
                          "flag": "", "still": "", "sigma_px": [loc.sigma for loc in locs]})
    track.loc[3, ["x_px", "y_px", "theta_rad", "sigma_px"]] = np.nan  # a frame not found
    track.loc[3, "found"] = 0
    write_track_csv(track, tmp_path / "track.csv")
    out = pd.read_csv(tmp_path / "track.csv", keep_default_na=False, na_values=[""])
    assert list(out.columns) == TRACK_COLUMNS + ["x_u_px", "y_u_px"]
    assert np.isnan(out.loc[3, "x_u_px"]) and np.isnan(out.loc[3, "y_u_px"])
    ok = out["found"] == 1
    assert np.allclose(out["x_u_px"][ok], track["sigma_px"][ok] / math.sqrt(2), atol=1e-6)
    assert np.array_equal(out["x_u_px"], out["y_u_px"], equal_nan=True)
    for axis in ("x", "y"):
        scatter = float(np.std(out[f"{axis}_px"][ok]))
        assert scatter / 1.3 < float(np.median(out[f"{axis}_u_px"][ok])) < 1.3 * scatter


def test_a_track_at_the_frame_border_gives_nulls_not_an_error():
    # located centres outside the frame: far off, no pixels about them; just off, pixels
    # but none near the rim
    bg, frames, track, _, rec = _drawn(0.0, n=40)
    for x in (-500.0, -rec.scene.r_px - 9.0):
        track["x_px"] = x
        p = estimate_precision(frames, bg, track, r_px=rec.scene.r_px)
        assert math.isnan(p.crb_px) and math.isnan(p.contrast_dn)
        j = p.json()
        assert j["crb_px"] is None and j["ratio"] is None and j["edge_sigma_px"] is None
