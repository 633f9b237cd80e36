"""Defocus (synth.defocus): the thin lens's circle of confusion, its disc kernel, the layers'
composite, and rendered recordings against their sharp twins."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rollfric.errors import InputError
from synth.camera import CameraModel
from synth.config import SceneConfig, SynthError
from synth.defocus import Defocus, coc_px, disc_kernel, pixel_pitch

PX = 0.1343e-3


def _diameter_from_moment(k: np.ndarray) -> float:
    """A disc of radius rho, sampled by pixel coverage, has per-axis variance
    rho^2 / 4 + 1 / 12 (the disc convolved with the pixel's box)."""
    n = k.shape[0] // 2
    x = np.arange(-n, n + 1, dtype=float)
    var = float((k * x[None, :] ** 2).sum())
    return 4.0 * math.sqrt(var - 1.0 / 12.0)


def test_coc_is_the_thin_lens_formula_in_sensor_pixels():
    cam = CameraModel(pixel_size=PX, working_distance=0.5, f_number=2.8,
                      focus_distance=0.485, focal_length=0.05)
    f, n, s, dist = 0.05, 2.8, 0.485, 0.5
    a = f / n
    pitch = PX * f / (dist - f)  # 14.92 um: the ball plane's scale through the lens
    assert pixel_pitch(cam) == pytest.approx(14.922e-6, rel=1e-4)
    for z in (0.0, 0.015, -0.05, 0.004):
        d = dist - z
        want = a * f * abs(d - s) / (d * (s - f)) / pitch
        assert coc_px(cam, z) == pytest.approx(want, rel=1e-12)
    # in focus: no blur; the ball 15 mm behind the focus at f/2.8: 4.13 px
    assert coc_px(cam, 0.015) == pytest.approx(0.0, abs=1e-12)
    assert coc_px(cam, 0.0) == pytest.approx(4.1265, abs=1e-3)
    # the default focus is the ball's plane; blur scales as 1 / N
    cam_b = CameraModel(pixel_size=PX, working_distance=0.5, f_number=5.6)
    assert coc_px(cam_b, 0.0) == pytest.approx(0.0, abs=1e-12)
    assert coc_px(cam_b, -0.05) * 2 == pytest.approx(
        coc_px(CameraModel(pixel_size=PX, working_distance=0.5, f_number=2.8), -0.05))


@pytest.mark.parametrize("diameter", [3.0, 4.138, 7.5, 16.3, 30.0])
def test_disc_kernel_has_the_coc_diameter(diameter):
    k = disc_kernel(diameter)
    assert k.sum() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(k, k[::-1, :], atol=1e-15)
    np.testing.assert_allclose(k, k.T, atol=1e-15)
    # a full pixel inside the disc weighs 1 / (its area pi d^2 / 4)
    n = k.shape[0] // 2
    assert 2.0 / math.sqrt(math.pi * k[n, n]) == pytest.approx(diameter, rel=0.005)
    if diameter >= 7:  # the moment's pixel (Sheppard) correction holds for wide discs
        assert _diameter_from_moment(k) == pytest.approx(diameter, rel=0.005)
    # a uniform disc: the inner pixels all carry the same weight
    inner = np.hypot(*np.mgrid[-n:n + 1, -n:n + 1]) < diameter / 2 - 1
    assert np.ptp(k[inner]) < 1e-12
    assert k.shape[0] <= 2 * math.ceil(diameter / 2 + 0.5) + 1


def test_disc_kernel_of_a_point_and_bad_input():
    np.testing.assert_array_equal(disc_kernel(0.0), [[1.0]])
    np.testing.assert_array_equal(disc_kernel(0.5), [[1.0]])  # inside its own pixel
    with pytest.raises(ValueError):
        disc_kernel(-1.0)


def _drawn(centre_px=(79.3, 77.8), size=160, face=None, **lens):
    """A Defocus over a drawn scene: a uniform backdrop (600 levels), a dark ball (100) of
    its exact silhouette's coverage, and an optional front-face coverage."""
    cam = CameraModel(width=size, height=size, pixel_size=PX, center_px=centre_px,
                      working_distance=0.5, **lens)
    scene = SceneConfig(camera=cam)
    face = np.zeros((size, size)) if face is None else face
    df = Defocus(scene, face, np.zeros((size, size)), 0.005)
    box = (0, 0, size, size)
    alpha = df.ball_alpha(np.zeros((1, 3)), box)
    backdrop = np.full((size, size), 600.0)
    return df, box, alpha, backdrop, alpha * 100.0 + (1.0 - alpha) * backdrop


@pytest.mark.parametrize("lens", [dict(f_number=2.8, focus_distance=0.485),
                                  dict(f_number=2.8),
                                  dict(f_number=1.4, focus_distance=0.45)])
def test_defocused_drawn_disc_keeps_its_centroid(lens):
    df, box, alpha, backdrop, img = _drawn(**lens)
    out = df.composite(backdrop, box, img, alpha, 0.0)
    w = backdrop - out  # the ball's dark disc, blurred
    yy, xx = np.mgrid[:160, :160]
    c = np.array([(w * xx).sum(), (w * yy).sum()]) / w.sum()
    np.testing.assert_allclose(c, [79.3, 77.8], atol=0.01)
    # and its light is kept: the blur spreads it, it does not remove it
    assert w.sum() == pytest.approx(((backdrop - img)).sum(), rel=1e-9)
    if coc_px(df.camera, 0.0) > 1:
        assert np.abs(out - img).max() > 50  # blurred indeed


def test_all_layers_in_focus_give_the_sharp_image_even_behind_the_face():
    # the front face's anti-aliased edge crosses the ball: with every kernel a point the
    # layers' split and composite give the sharp image back
    yy = np.mgrid[:160, :160][0]
    face = np.clip(yy - 102.4, 0.0, 1.0)
    df, box, alpha, backdrop, _ = _drawn(face=face, f_number=128.0)
    assert all(k.shape == (1, 1) for k in df.kernels.values())
    scene_img = face * 150.0 + (1 - face) * backdrop
    img = face * 150.0 + (1 - face) * (alpha * 100.0 + (1 - alpha) * backdrop)
    out = df.composite(scene_img, box, img, alpha, 0.0)
    np.testing.assert_allclose(out, img, atol=1e-9)
    np.testing.assert_allclose(df.background(scene_img), scene_img, atol=1e-9)


def test_thin_lens_keys_are_checked():
    with pytest.raises(InputError, match="focus_distance needs an f_number"):
        CameraModel(focus_distance=0.4)
    with pytest.raises(InputError, match="f_number"):
        CameraModel(f_number=0.0)
    with pytest.raises(InputError, match="focus_distance must exceed"):
        CameraModel(f_number=4.0, focus_distance=0.03)
    with pytest.raises(InputError, match="working_distance"):
        CameraModel(f_number=4.0, working_distance=0.04, znear=0.01)
    with pytest.raises(SynthError, match="pyrender"):
        SceneConfig(camera=CameraModel(f_number=4.0), renderer="mitsuba")
    # a pinhole is stored as before; a thin lens round-trips
    assert "f_number" not in CameraModel().to_dict()
    cam = CameraModel(f_number=4.0, focus_distance=0.485, focal_length=0.035)
    assert CameraModel(**cam.to_dict()) == cam


def test_case_keys_in_lab_units():
    from validation.case import CaseError, case_from_dict
    from validation.case_dict import apply_overrides, small_case_dict

    d = apply_overrides(small_case_dict(), {"render.camera.f_number": 4,
                                            "render.camera.focus_distance_mm": 485.0,
                                            "render.camera.focal_length_mm": 35.0})
    cam = case_from_dict(d).scene.camera
    assert (cam.f_number, cam.focus_distance, cam.focal_length) == (4.0, 0.485, 0.035)
    with pytest.raises(CaseError, match="f_number"):
        case_from_dict(apply_overrides(small_case_dict(), {"render.camera.f_number": "f/4"}))
    with pytest.raises(CaseError, match="focus_distance"):
        case_from_dict(apply_overrides(small_case_dict(),
                                       {"render.camera.focus_distance_mm": 485.0}))


def _render(tmp_path, name, **camera):
    import sim
    import synth
    from synth.store import open_recording
    from validation.case import case_from_dict
    from validation.case_dict import apply_overrides, small_case_dict

    over = {f"render.camera.{k}": v for k, v in camera.items()}
    c = case_from_dict(apply_overrides(small_case_dict(0.012), over))
    rec = synth.render(sim.simulate(c.scenario), tmp_path / f"{name}.zarr", scene=c.scene,
                       sensor=c.sensor, seed=0, workers=1)
    return open_recording(rec), c


def test_rendered_defocus_against_the_sharp_recording(tmp_path):
    sharp, case = _render(tmp_path, "sharp")
    point, _ = _render(tmp_path, "f128", f_number=128.0)  # every blur under a sample
    ball, _ = _render(tmp_path, "ball", f_number=2.8)  # the ball's plane in focus
    face, _ = _render(tmp_path, "face", f_number=2.8, focus_distance_mm=485.0)
    n = len(sharp.frames)
    fs, fp, fb, ff = (r.frames for r in (sharp, point, ball, face))
    # a pinhole-like aperture: the same frames (rounding of the layers' split aside)
    np.testing.assert_array_equal(fp._bg, fs._bg)
    for i in (0, n // 2, n - 1):
        assert np.abs(fp.clean_counts(i) - fs.clean_counts(i)).max() <= 1
    # focus on the ball: the ball's own pixels are the sharp ones (away from the blurred
    # trough face in front of it), the backdrop and the trough's edge are blurred
    cam = case.scene.camera
    lens = CameraModel(**ball.attrs["scene"]["camera"])
    reach_face = disc_kernel(coc_px(lens, case.scene.trough_length / 2)).shape[0] // 2
    yy, xx = np.mgrid[:cam.height, :cam.width]
    contour_y = cam.center_px[1] + 0.0853 / cam.pixel_size  # the bore's bottom
    for i in (0, n - 1):
        t = sharp.truth.iloc[i]
        inside = np.hypot(xx - t.sil_x_px, yy - t.sil_y_px) < t.r_px - 1.5
        clear = np.hypot(xx - cam.center_px[0], yy - cam.center_px[1]) < \
            contour_y - cam.center_px[1] - reach_face - 1
        sel = inside & clear
        assert sel.sum() > 3000
        d = fb.clean_counts(i)[sel] - fs.clean_counts(i)[sel]
        assert np.abs(d).max() <= 1
        # focus on the face: the same pixels blurred (the highlight spreads)
        assert np.abs(ff.clean_counts(i)[sel] - fs.clean_counts(i)[sel]).max() > 20
    assert np.abs(fb._bg.astype(int) - fs._bg).max() > 20
    # the truth stays the ball centre's projection
    for r in (point, ball, face):
        np.testing.assert_array_equal(r.truth.x_px, sharp.truth.x_px)
        np.testing.assert_array_equal(r.truth.y_px, sharp.truth.y_px)


@pytest.mark.parametrize("camera", [{"projection": "perspective"},
                                    {"lens_distortion": [-0.18, 0.0, 0.0, 0.0, 0.0]}])
def test_a_point_aperture_gives_the_sharp_frames_through_a_pinhole_and_a_lens(tmp_path, camera):
    # a pinhole sees the bore (its own layer); a lens bends the blurred ideal frame: with
    # every blur under a sample, the layers' split and composite give the sharp frames
    sharp, _ = _render(tmp_path, "sharp", **camera)
    point, _ = _render(tmp_path, "f128", f_number=128.0, **camera)
    np.testing.assert_array_equal(point.frames._bg, sharp.frames._bg)
    for i in (0, len(sharp.frames) - 1):
        d = point.frames.clean_counts(i) - sharp.frames.clean_counts(i)
        assert np.abs(d).max() <= 1
