"""Exact projections of the synth camera models (no rendering)."""

import math

import numpy as np
import pytest

from rollfric.errors import InputError
from synth.camera import CameraModel


def test_orthographic_projection_of_known_points():
    cam = CameraModel(pixel_size=0.1343e-3, center_px=(640.0, 380.0))
    pts = np.array([[0.0, 0.0, 0.0], [0.1343e-3, 0.0, 0.03], [0.0, -0.0803, -0.01],
                    [-0.02686, 0.01343, 0.0]])
    uv = cam.project(pts)
    np.testing.assert_allclose(uv, [[640, 380], [641, 380], [640, 380 + 0.0803 / 0.1343e-3],
                                    [440, 280]], atol=1e-9)


def test_perspective_projection_of_known_points():
    cam = CameraModel(projection="perspective", working_distance=0.5, pixel_size=1e-4,
                      center_px=(100.0, 50.0))
    # in the ball plane one pixel is exactly pixel_size
    np.testing.assert_allclose(cam.project([0.001, -0.002, 0.0]), [110.0, 70.0], atol=1e-9)
    # 0.1 m closer to the camera: magnified by 0.5 / 0.4
    np.testing.assert_allclose(cam.project([0.001, 0.0, 0.1]), [100 + 12.5, 50.0], atol=1e-9)
    # on the axis: always the principal point (the cylinder centre)
    np.testing.assert_allclose(cam.project([0.0, 0.0, -0.3]), [100.0, 50.0], atol=1e-12)


def test_tile_projection_maps_pixel_centres():
    """Pixel (i, j) of a tile is full-frame pixel (x0 + i, y0 + j) under the GL matrix."""
    for proj in ("orthographic", "perspective"):
        cam = CameraModel(projection=proj, working_distance=0.3, center_px=(640.0, 380.0))
        x0, y0, w, h = 700, 900, 64, 40
        P = cam.tile_projection(x0, y0, w, h)
        pts = np.array([[0.0101, -0.0712, 0.002], [0.013, -0.07, -0.004]])
        uv = cam.project(pts)
        cam_pts = np.c_[pts - [0, 0, cam.camera_z], np.ones(len(pts))]
        clip = cam_pts @ P.T
        ndc = clip[:, :2] / clip[:, 3:4]
        i = (ndc[:, 0] + 1) / 2 * w - 0.5
        j = (1 - ndc[:, 1]) / 2 * h - 0.5
        np.testing.assert_allclose(np.c_[i + x0, j + y0], uv, atol=1e-9)


def test_silhouette_centre_and_radius():
    ortho = CameraModel()
    uv, r = ortho.sphere_silhouette([[0.02, -0.07, 0.0]], 0.005)
    np.testing.assert_allclose(uv, ortho.project([[0.02, -0.07, 0.0]]))
    assert r[0] == pytest.approx(0.005 / 0.1343e-3)
    # perspective, on the axis: a circle of radius f r / sqrt(d^2 - r^2)
    cam = CameraModel(projection="perspective", working_distance=0.25, pixel_size=1e-4,
                      center_px=(0.0, 0.0))
    uv, r = cam.sphere_silhouette([[0.0, 0.0, 0.0]], 0.005)
    f = cam.focal_px
    assert r[0] == pytest.approx(f * 0.005 / math.sqrt(0.25 ** 2 - 0.005 ** 2), rel=1e-12)
    # off the axis: the silhouette centre lies outward of the projected centre
    c = np.array([[0.06, -0.06, 0.0]])
    uv, _ = cam.sphere_silhouette(c, 0.005)
    p = cam.project(c)
    shift = uv - p
    assert np.linalg.norm(shift) > 0.1
    cos = shift @ p[0] / (np.linalg.norm(shift) * np.linalg.norm(p[0]))
    assert cos == pytest.approx(1.0, abs=1e-9)  # radial: theta from either centre is the same


def test_bad_camera_refused():
    with pytest.raises(InputError, match="projection"):
        CameraModel(projection="fisheye")
    with pytest.raises(InputError, match="pixel_size"):
        CameraModel(pixel_size=0.0)


def test_roll_turns_the_image_about_the_axis():
    """Rolled by +r, the camera sees the trough bottom (straight below the axis) at theta = +r
    (right of the image vertical), every point turned by r about center_px; the pose's rotation
    is the inverse of that turn."""
    r = math.radians(0.5)
    cam = CameraModel(center_px=(640.0, 380.0), roll=r)
    L = 0.0803
    for th in (0.0, 0.3, -0.2):
        p = np.array([L * math.sin(th), -L * math.cos(th), 0.0])
        u, v = cam.project(p)
        assert math.atan2(u - 640.0, v - 380.0) == pytest.approx(th + r, abs=1e-12)
        assert math.hypot(u - 640.0, v - 380.0) == pytest.approx(L / cam.pixel_size, rel=1e-12)
    # the pose: world point -> camera frame by the inverse pose, then an unrolled projection
    p = np.array([0.01, -0.07, 0.002])
    q = np.linalg.inv(cam.pose()) @ np.append(p, 1.0)
    flat = CameraModel(center_px=(640.0, 380.0))
    np.testing.assert_allclose(flat.project(q[:3] + [0, 0, cam.camera_z]), cam.project(p),
                               atol=1e-9)
