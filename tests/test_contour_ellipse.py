"""rollfric.geometry.ellipse: the contour as an ellipse and the mu bias it implies (against exact
projections of simulated tracks)."""

import math

import numpy as np
import pytest

import sim
from rollfric.fit.estimate import fit_mu
from rollfric.geometry import ellipse as ell

PX = 0.1343e-3


def _arc_points(a, b, angle_deg, center=(640.0, -100.0), n=400, noise=0.0, seed=0):
    """Contour points on both sides of an ellipse (25 .. 110 deg from the bottom), image y
    down, the major axis at angle_deg (clockwise on screen)."""
    phi = np.concatenate([np.linspace(np.radians(25), np.radians(110), n // 2),
                          -np.linspace(np.radians(25), np.radians(110), n // 2)])
    u, v = a * np.cos(phi + np.pi / 2), b * np.sin(phi + np.pi / 2)
    t = math.radians(angle_deg)
    x = center[0] + math.cos(t) * u - math.sin(t) * v
    y = center[1] + math.sin(t) * u + math.cos(t) * v
    rng = np.random.default_rng(seed)
    return np.column_stack([x, y]) + noise * rng.standard_normal((n, 2))


@pytest.mark.parametrize("angle", [0.0, 30.0, 90.0, -60.0])
def test_fit_ellipse_recovers_axes_and_angle(angle):
    pts = _arc_points(636.0, 634.5, angle)
    e = ell.fit_ellipse(pts)
    assert e.semi_axes == pytest.approx((636.0, 634.5), abs=1e-6)
    assert e.center == pytest.approx((640.0, -100.0), abs=1e-6)
    assert (e.angle_deg - angle + 90) % 180 - 90 == pytest.approx(0.0, abs=1e-4)
    assert e.eccentricity == pytest.approx(math.sqrt(1 - (634.5 / 636.0) ** 2), rel=1e-6)
    assert e.significant
    # a circle: ratio 1 within the noise, and not a significant ellipse
    c = ell.fit_ellipse(_arc_points(635.0, 635.0, 0.0, noise=0.05))
    assert abs(c.semi_axes[0] - c.semi_axes[1]) < 0.05
    assert not c.significant


def _track(**changes):
    sc = sim.Scenario(duration=2.0, **changes)
    return sc, sim.simulate(sc)


@pytest.mark.parametrize("pitch_deg, yaw_deg", [(4.0, 0.0), (0.0, 4.0)])
def test_camera_bias_matches_a_tilted_camera(pitch_deg, yaw_deg):
    """An orthographic camera pitched (yawed) by an angle sees the ball plane compressed by its
    cosine vertically (horizontally): the contour's ellipse predicts the mu bias of the fit."""
    sc, tr = _track()
    cp, cy = math.cos(math.radians(pitch_deg)), math.cos(math.radians(yaw_deg))
    x, y = tr.position[:, 0] * cy, tr.position[:, 1] * cp
    theta_m = np.arctan2(x, -y)
    f = fit_mu(tr.t, theta_m, sc.setup(), offset=True)
    measured = f.mu / fit_mu(tr.t, tr.theta, sc.setup(), offset=True).mu - 1
    R = sc.cylinder_radius / PX
    axes = sorted((R * cy, R * cp), reverse=True)
    e = ell.ContourEllipse((0.0, 0.0), tuple(axes), 90.0 if yaw_deg else 0.0, 0.0, 0)
    amp = sc.theta0 - sc.mu  # the first half-swing's turning points
    pred = ell.camera_bias(e, amp)
    assert np.sign(pred) == np.sign(measured) == (1 if pitch_deg else -1)
    assert pred == pytest.approx(measured, rel=0.05)
    # at the bottom the slope is 1 / cos(pitch) (cos(yaw))
    assert ell.camera_bias(e) == pytest.approx(1 / cp - 1 if pitch_deg else cy - 1, rel=1e-6)


@pytest.mark.parametrize("ovality_mm, angle_deg", [(0.4, 0.0), (0.4, 90.0)])
def test_trough_bias_matches_an_out_of_round_trough(ovality_mm, angle_deg):
    """The simulated ellipse's exact angles, fitted with the mean radius: the bias the refit
    with the bottom's curvature implies has the measured sign and size (within 3 %)."""
    sc, tr = _track(ovality=ovality_mm * 1e-3, ovality_angle=math.radians(angle_deg))
    setup = sc.setup()
    f = fit_mu(tr.t, tr.theta, setup, offset=True)
    measured = f.mu / sc.mu - 1
    a, b = sc.section.semi_axes
    e = ell.ContourEllipse((0.0, 0.0), (a / PX, b / PX), -angle_deg, 0.0, 0)
    r_eff, f_b = ell.trough_scale(e, sc.ball_radius / PX, sc.theta0 - 6 * sc.mu)
    assert r_eff == pytest.approx(sc.section.bottom_curvature_radius() / sc.cylinder_radius)
    refit = fit_mu(tr.t, tr.theta, setup.replace(cylinder_radius=setup.cylinder_radius * r_eff),
                   offset=True)
    pred = ell.trough_bias(f.mu, refit.mu, f_b)
    assert abs(measured) > 0.005  # the effect is there: 0.4 mm biases mu by ~0.7 %
    assert np.sign(pred) == np.sign(measured)
    assert pred == pytest.approx(measured, rel=0.03)
    # the same contour read as a camera's: a third of the size, same sign
    assert 0.2 < ell.camera_bias(e, sc.theta0) / measured < 0.5


def test_round_contour_implies_no_bias():
    e = ell.ContourEllipse((0.0, 0.0), (635.0, 635.0), 0.0, 0.0, 0)
    assert ell.camera_bias(e) == pytest.approx(0.0, abs=1e-15)
    r_eff, f_b = ell.trough_scale(e, 37.2)
    assert r_eff == pytest.approx(1.0) and f_b == pytest.approx(1.0)


def test_rendered_out_of_round_bore_is_found_as_its_ellipse():
    """synth draws the bore as the scenario's ellipse; rollfric's contour finds it back."""
    from rollfric.geometry.trough import find_cylinder_center
    from synth.backends.raster import SceneRenderer
    from synth.camera import CameraModel
    from synth.config import SceneConfig

    R, r, ov, ang = 0.0853, 0.005, 0.6e-3, 30.0
    cam = CameraModel()  # the thesis camera, orthographic, 0.1343 mm/px
    sr = SceneRenderer(SceneConfig(camera=cam, shadows=False), r, R, ov, math.radians(ang))
    try:
        bg = sr.render_full().astype(float) * (255.0 / sr.scale)
    finally:
        sr.close()
    c = find_cylinder_center(bg, radius_px=R / cam.pixel_size)
    e = c.ellipse
    a, b = (R + ov / 4) / cam.pixel_size, (R - ov / 4) / cam.pixel_size
    assert e.semi_axes[0] - e.semi_axes[1] == pytest.approx(a - b, abs=0.15)  # 2.2 px
    assert e.mean_radius == pytest.approx(0.5 * (a + b), abs=0.3)
    # counter-clockwise in the world is clockwise on screen (image y down)
    assert e.angle_deg == pytest.approx(-ang, abs=3.0)
    assert e.center == pytest.approx(cam.center_px, abs=0.2)
    assert e.significant  # (a round bore: a - b = 0.018 px, u 0.024 px, measured)
