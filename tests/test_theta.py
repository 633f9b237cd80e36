"""Centres -> angles once (rollfric.geometry.theta): the formula, the lens's bent outline taken
off before it, and the same angles in the track and in the budget's re-evaluation."""

import numpy as np
import pandas as pd
import pytest
from test_lens import _target_lens_path

from rollfric.geometry.theta import angles, centre_angles
from rollfric.setup.model import thesis_setup
from rollfric.track.track_info import TrackInfo
from rollfric.uncertainty.measured import Measurement


def test_without_a_lens_the_angles_are_the_formula_and_a_missing_ball_stays_nan():
    setup = thesis_setup("10mm").replace(center_px=None)
    L = setup.track_radius / setup.pixel_size
    th = np.array([-0.3, 0.0, 0.2, np.nan])
    x, y = 100.0 + L * np.sin(th), 50.0 + L * np.cos(th)
    got, xu, yu = centre_angles(x, y, (100.0, 50.0), setup)
    np.testing.assert_allclose(got[:3], th[:3], atol=1e-12)
    assert np.isnan(got[3]) and np.isnan(xu[3]) and np.isnan(yu[3])
    np.testing.assert_array_equal(xu[:3], x[:3])
    arcsin, _, _ = centre_angles(x, y, (100.0, 50.0), setup, method="arcsin")
    np.testing.assert_allclose(arcsin[:3], th[:3], atol=1e-12)
    with pytest.raises(Exception, match="unknown angle method 'acos'"):
        angles(x, y, (100.0, 50.0), method="acos")


def _bent_circle_centres(lens, truth, r, n=256):
    # the least-squares circle through the ball's outline as the lens bends it: what a
    # locator fits in the recorded image (the bent outline is not round)
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    out = []
    for cx, cy in truth:
        pts = lens.distort(np.column_stack([cx + r * np.cos(phi), cy + r * np.sin(phi)]))
        a = np.column_stack([2 * pts[:, 0], 2 * pts[:, 1], np.ones(n)])
        sol = np.linalg.lstsq(a, (pts ** 2).sum(axis=1), rcond=None)[0]
        out.append(sol[:2])
    return np.array(out)


def test_a_lens_s_bent_outline_is_taken_off_before_the_angles():
    # the target's lens (k1 = -0.18): the circles fitted to the bent outlines along the
    # thesis's path give the true centres and angles to 1e-3 px; the centres undistorted as
    # points (the outline's bend left in) miss by more than 0.01 px
    lens, setup, th, truth, L, r = _target_lens_path(9)
    rec = _bent_circle_centres(lens, truth, r)
    got, xu, yu = centre_angles(rec[:, 0], rec[:, 1], setup.center_px, setup)
    assert np.abs(got - th).max() * L < 1e-3
    assert np.abs(np.column_stack([xu, yu]) - truth).max() < 1e-3
    plain = lens.undistort(rec)
    assert np.abs(plain - truth).max() > 0.01
    # recorded as given (not distorted): no correction at all
    as_is, _, _ = centre_angles(rec[:, 0], rec[:, 1], setup.center_px, setup, distorted=False)
    np.testing.assert_array_equal(as_is, angles(rec[:, 0], rec[:, 1], setup.center_px))


def test_the_budget_re_evaluates_the_angles_the_track_has():
    # the re-evaluation of the uncertainty budget takes the same way from the centres
    lens, setup, th, truth, L, r = _target_lens_path(9)
    rec = _bent_circle_centres(lens, truth, r)
    rec[4] = np.nan
    theta, _, _ = centre_angles(rec[:, 0], rec[:, 1], setup.center_px, setup)
    meas = Measurement(setup=setup, frames=np.arange(9.0), x=rec[:, 0], y=rec[:, 1],
                       center=setup.center_px, distorted=True)
    np.testing.assert_array_equal(meas.series(setup)[1], theta)


def _info(**kw):
    setup = thesis_setup("10mm")
    base = dict(setup=setup, recording="rec.tif", n_frames=4, n_found=3, locator="subpixel",
                angle="atan2", center_px=(1.0, 2.0), center_source="setup center_px",
                undistorted=False, background="given", times="frame / camera.fps",
                ball_radius_px=37.2, track_radius_px=600.0, ball_radius_px_seen=None,
                ball_radius_px_seen_n=0, ball_radius_px_seen_rel_sigma=None,
                ball_radius_px_seen_rel_dev=None, n_refitted=0, flags={"not_found": 1},
                warnings=("w",), warnings_radius=(), frames_dropped=((2, 1),),
                timing_irregular=((3, 1.5),), offset_fitted=True, offset_reason="turns",
                contour_ellipse={"e": 0.1}, path_ellipse={"p": 1}, camera_motion={"kind": "still"})
    base.update(kw)
    return TrackInfo(**base)


def test_track_info_gives_the_files_keys_in_their_order():
    track = pd.DataFrame({"still": ["held", "", "", "rest"],
                          "sigma_px": [0.01, 0.03, np.nan, 0.02]})
    keys = _info().json_keys(track)
    assert list(keys) == [
        "n_frames", "n_found", "locator", "angle", "center_px", "center_source", "center_u_px",
        "undistorted", "background", "background_from", "times", "ball_radius_px",
        "ball_radius_px_seen", "ball_radius_px_seen_n", "n_refitted", "frames_flagged",
        "frames_held", "frames_rest", "frames_dropped", "timing_irregular", "located_irregular",
        "warnings", "median_sigma_px", "recording", "contour_ellipse"]
    assert keys["frames_held"] == 1 and keys["frames_rest"] == 1
    assert keys["median_sigma_px"] == pytest.approx(0.02)
    assert keys["frames_dropped"] == [{"after_frame": 2, "frames": 1}]
    assert keys["timing_irregular"] == [{"frame": 3, "step_ratio": 1.5}]
    assert keys["center_px"] == [1.0, 2.0] and keys["frames_flagged"] == {"not_found": 1}
    fitted = _info().json_keys(track, fitted=True)
    assert list(fitted)[-6:] == ["offset_fitted", "offset_reason", "contour_ellipse",
                                 "path_ellipse", "camera_motion", "locator_precision"]
    assert fitted["offset_reason"] == "turns" and fitted["camera_motion"] == {"kind": "still"}
    none = _info().json_keys(track.assign(sigma_px=np.nan))
    assert none["median_sigma_px"] is None
