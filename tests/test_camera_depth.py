"""A pinhole off the trough's axis (synth's ``principal_px``): exact projections, the rendered
bore and ball against them, and rollfric's move of the contour's centre to the ball's plane."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rollfric.errors import InputError
from rollfric.geometry.perspective import ball_plane_center, contour_depth_from_radius
from rollfric.setup.model import SetupError, dumps_setup, setup_from_dict, thesis_setup
from synth.camera import CameraModel

R_CYL, R_BALL = 0.0853, 0.005
D = 0.4


def _circle_centre(uv):
    x, y = uv[:, 0], uv[:, 1]
    s, *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), x * x + y * y,
                            rcond=None)
    return np.array([s[0] / 2, s[1] / 2]), math.sqrt(s[2] + s[0] ** 2 / 4 + s[1] ** 2 / 4)


def test_off_axis_pinhole_sees_the_axis_at_depth_about_a_moved_centre():
    cam = CameraModel(projection="perspective", working_distance=D, pixel_size=1e-4,
                      center_px=(640.0, 380.0), principal_px=(639.5, 511.5))
    pp, c = np.array([639.5, 511.5]), np.array([640.0, 380.0])
    # the ball's plane: the axis at center_px, one pixel is pixel_size
    np.testing.assert_allclose(cam.project([0.0, 0.0, 0.0]), c, atol=1e-9)
    np.testing.assert_allclose(cam.project([1e-3, -2e-3, 0.0]), c + [10.0, 20.0], atol=1e-9)
    # the optical axis (through the pinhole, along z) projects to the principal point
    x0, y0 = cam.pinhole_offset
    np.testing.assert_allclose(cam.project([x0, y0, -0.3]), pp, atol=1e-9)
    np.testing.assert_allclose(cam.position, [x0, y0, D], atol=1e-15)
    phi = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    for z in (0.015, -0.015, 0.0):
        ring = np.column_stack([R_CYL * np.sin(phi), -R_CYL * np.cos(phi), np.full(90, z)])
        centre, radius = _circle_centre(cam.project(ring))
        np.testing.assert_allclose(centre, pp + (c - pp) * D / (D - z), atol=1e-7)
        assert radius == pytest.approx(R_CYL / 1e-4 * D / (D - z), rel=1e-9)
        # rollfric's move to the ball's plane, with the depth stated or from the radius
        np.testing.assert_allclose(ball_plane_center(centre, pp, D, z), c, atol=1e-7)
        assert contour_depth_from_radius(radius, R_CYL / 1e-4, D) == pytest.approx(z, abs=1e-9)
    # the back edge 15 mm behind: its centre 4.9 px below the axis (131.5 px x 15 / 415)
    centre, _ = _circle_centre(cam.project(np.column_stack(
        [R_CYL * np.sin(phi), -R_CYL * np.cos(phi), np.full(90, -0.015)])))
    assert centre[1] - c[1] == pytest.approx(131.5 * 0.015 / 0.415, rel=1e-6)
    # GL: the tile projection after the pose lands where project() does
    x0t, y0t, w, h = 700, 900, 64, 40
    P = cam.tile_projection(x0t, y0t, w, h)
    pts = np.array([[0.0101, -0.0712, 0.002], [0.013, -0.07, -0.004]])
    cam_pts = np.c_[pts, np.ones(len(pts))] @ np.linalg.inv(cam.pose()).T
    clip = cam_pts @ P.T
    ndc = clip[:, :2] / clip[:, 3:4]
    got = np.c_[(ndc[:, 0] + 1) / 2 * w - 0.5 + x0t, (1 - ndc[:, 1]) / 2 * h - 0.5 + y0t]
    np.testing.assert_allclose(got, cam.project(pts), atol=1e-9)
    with pytest.raises(InputError, match="principal_px"):
        CameraModel(principal_px=(639.5, 511.5))  # orthographic: no pinhole


def test_rendered_bore_and_ball_seen_from_an_off_axis_pinhole():
    """The backdrop seen through the bore is bounded by its far end: its centroid is there
    (0.1 px), and rollfric moves it onto the ball's plane's axis; the ball's silhouette is
    where the exact projection puts it."""
    from synth_frames import flat_ring_render

    c, pp = (97.3, 100.6), (95.5, 140.6)  # the far edge nested in the near one
    cam = CameraModel(width=192, height=200, pixel_size=1.2e-3, projection="perspective",
                      working_distance=D, center_px=c, principal_px=pp)
    img, cfg = flat_ring_render(cam, R_BALL, R_CYL)
    zb = -cfg.trough_length / 2
    want = np.array(pp) + (np.array(c) - pp) * D / (D - zb)
    hole = R_CYL * D / (D - zb) / 1.2e-3
    yy, xx = np.mgrid[0:cam.height, 0:cam.width]
    rho = np.hypot(xx - want[0], yy - want[1])
    w = img * (rho < hole + 5)
    got = np.array([(w * xx).sum() / w.sum(), (w * yy).sum() / w.sum()])
    assert np.hypot(*(got - want)) < 0.1, (got, want)
    assert got[1] - c[1] == pytest.approx(40.0 * 0.015 / 0.415, abs=0.1)  # 1.4 px below
    area_r = math.sqrt(np.sum((img > 0.5) & (rho < hole + 5)) / math.pi)  # the hole: white
    assert contour_depth_from_radius(area_r, R_CYL / 1.2e-3, D) == pytest.approx(zb, abs=1e-3)
    np.testing.assert_allclose(ball_plane_center(got, pp, D, zb), c, atol=0.1)


def test_setup_depth_keys():
    d = thesis_setup().to_toml_dict()
    d["camera"]["working_distance_mm"] = 500.0
    d["cylinder"]["contour_depth_mm"] = -15.0
    s = setup_from_dict(d)
    assert s.working_distance == pytest.approx(0.5) and s.contour_depth == pytest.approx(-0.015)
    import tomllib

    assert setup_from_dict(tomllib.loads(dumps_setup(s))) == s
    assert setup_from_dict(thesis_setup().to_toml_dict()).contour_depth is None
    for sec, key, val, match in [("camera", "working_distance_mm", -1.0, "positive"),
                                 ("cylinder", "contour_depth_mm", "x", "number"),
                                 ("cylinder", "contour_depth_mm", 300.0, "nearer")]:
        bad = dict(d, **{sec: dict(d[sec], **{key: val})})
        with pytest.raises(SetupError, match=match):
            setup_from_dict(bad)
    # audit 2026-11-24: a depth without the working distance did nothing, silently
    no_wd = dict(d, camera={k: v for k, v in d["camera"].items() if k != "working_distance_mm"})
    with pytest.raises(SetupError, match="contour_depth_mm is used only with "
                                         "camera.working_distance_mm"):
        setup_from_dict(no_wd)


def test_tilted_camera_moves_the_trough_faces_by_the_half_length_times_sin():
    """Orthographic, the camera swung by 1 deg towards +x (yaw) or +y (pitch) about the ball
    plane's axis point: that point stays at center_px; points 15 mm in front of the ball
    plane (nearer the camera) move by 15 mm sin(1 deg) / s (1.95 px at 0.1343 mm/px), left
    for yaw, down for pitch (as a camera moved right or up sees them); a circle
    there projects to an ellipse of axes ratio cos(1 deg); the pose and the GL projection put
    points where project() does."""
    s, a, h = 0.1343e-3, math.radians(1.0), 0.015
    for key, move in (("yaw", (-1.0, 0.0)), ("pitch", (0.0, 1.0))):
        cam = CameraModel(pixel_size=s, center_px=(640.0, 380.0), **{key: a})
        np.testing.assert_allclose(cam.project([0.0, 0.0, 0.0]), (640.0, 380.0), atol=1e-9)
        got = cam.project([0.0, 0.0, h]) - (640.0, 380.0)
        np.testing.assert_allclose(got, np.array(move) * h * math.sin(a) / s, atol=1e-9)
        assert abs(got[0] + got[1]) == pytest.approx(1.95, abs=0.01)
        # the camera's own position: swung that way
        assert cam.position[0 if key == "yaw" else 1] == pytest.approx(cam.camera_z * math.sin(a))
        phi = np.linspace(0, 2 * np.pi, 360, endpoint=False)
        uv = cam.project(np.column_stack([R_CYL * np.sin(phi), -R_CYL * np.cos(phi),
                                          np.full(360, h)]))
        span = uv.max(0) - uv.min(0)
        ratio = span[0] / span[1] if key == "yaw" else span[1] / span[0]
        assert ratio == pytest.approx(math.cos(a), abs=1e-5)
        P = cam.tile_projection(600, 900, 64, 40)
        pts = np.array([[0.0101, -0.0712, 0.002], [-0.003, -0.08, -0.004]])
        cam_pts = np.c_[pts, np.ones(len(pts))] @ np.linalg.inv(cam.pose()).T
        ndc = (cam_pts @ P.T)[:, :2]  # orthographic: w = 1
        got = np.c_[(ndc[:, 0] + 1) / 2 * 64 - 0.5 + 600, (1 - ndc[:, 1]) / 2 * 40 - 0.5 + 900]
        np.testing.assert_allclose(got, cam.project(pts), atol=1e-9)
    with pytest.raises(InputError, match="yaw"):
        CameraModel(yaw=0.5)
