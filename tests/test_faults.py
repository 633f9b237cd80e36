"""The fault generator (validation.faults.recordings) makes the faults it says, deterministically,
and the
fault study (validation.studies.faults) judges a case."""

import numpy as np
import pytest

from validation.faults import recordings as fl
from validation.faults.recordings import Family, clean, faulty

QUIET = Family(noise=0.0, n=300)  # noiseless: a still ball draws identical frames


def test_a_held_start_holds_the_ball_exactly_n_frames():
    rec = faulty("held", 30, family=QUIET)
    c, f = rec.centers, rec.source.frames
    assert len(f) == QUIET.n + 29 and rec.truth["held_frames"] == 30
    assert np.all(c[:30] == c[0]) and not np.all(c[30] == c[29])
    assert all(np.array_equal(f[i], f[0]) for i in range(30))
    assert not np.array_equal(f[30], f[29])
    assert rec.theta[0] == pytest.approx(QUIET.theta0)


def test_a_rest_holds_the_ball_from_a_turning_point_on():
    rec = faulty("rest", 0.5, family=QUIET)
    k = rec.truth["rest_from"]
    f, th = rec.source.frames, rec.theta
    assert all(np.array_equal(f[i], f[k]) for i in range(k, len(f)))
    assert not np.array_equal(f[k - 1], f[k])
    # it stops where it turns: the angle's extreme, the speed's zero
    assert abs(th[k]) > abs(th[k - 1]) and abs(th[k]) > abs(clean(QUIET).theta[k + 1])


@pytest.mark.parametrize("px", [3, 2])
def test_a_bump_shifts_every_later_frame_by_its_px(px):
    rec, ref = faulty("bump", px, family=QUIET), clean(QUIET)
    k = rec.truth["bump_frame"]
    for i in range(len(ref.source)):
        a, b = rec.source[i], ref.source[i]
        if i < k:
            assert np.array_equal(a, b)
        else:  # the scene moved px to the right (the first px columns replicated)
            assert np.array_equal(a[:, px:], b[:, :-px]) and not np.array_equal(a, b)
    np.testing.assert_allclose(rec.centers[k:] - ref.centers[k:],
                               [[px, 0.0]] * (len(ref.theta) - k))


def test_a_drift_moves_the_scene_steadily():
    import cv2

    rec, ref = faulty("drift", 2.0, family=QUIET), clean(QUIET)
    last = len(ref.source) - 1
    (dx, dy), _ = cv2.phaseCorrelate(ref.background.astype(np.float64),
                                     np.asarray(rec.source[last], np.float64))
    assert (dx, dy) == pytest.approx((2.0, 1.0), abs=0.1)
    np.testing.assert_array_equal(rec.source[0], ref.source[0])


@pytest.mark.parametrize("unit, scale", [("ms", 1e3), ("us", 1e6)])
def test_timestamps_are_in_their_unit(unit, scale):
    rec = faulty(f"timestamps_{unit}", 3.0, family=QUIET)
    ts = rec.source.timestamps
    assert ts[0] == pytest.approx(3.0 * scale)
    np.testing.assert_allclose(np.diff(ts), scale / QUIET.fps, rtol=1e-9)


def test_a_turned_camera_compresses_the_path():
    rec, ref = faulty("yaw", 8.0, family=QUIET), clean(QUIET)
    cx = ref.scene.center[0]
    np.testing.assert_allclose(rec.centers[:, 0] - cx, np.cos(np.radians(8.0))
                               * (ref.centers[:, 0] - cx), atol=1e-9)
    np.testing.assert_allclose(rec.centers[:, 1], ref.centers[:, 1], atol=1e-9)


def test_wrong_setups_and_flicker():
    ref = clean(QUIET)
    assert faulty("fps", 1.1, family=QUIET).setup.fps == pytest.approx(1.1 * ref.setup.fps)
    assert faulty("radius", 1.02, family=QUIET).setup.cylinder_radius == \
        pytest.approx(1.02 * ref.setup.cylinder_radius)
    assert faulty("gravity", 98.1, family=QUIET).setup.gravity == 98.1
    rec = faulty("flicker", 0.1, family=QUIET)
    gain = np.asarray(rec.truth["gain"])
    # the lamp's 100 Hz seen at the frame rate (at 200 Hz: +-0.1 sin(phase), alternating)
    i = np.arange(len(gain))
    np.testing.assert_allclose(gain, 1 + 0.1 * np.sin(2 * np.pi * 100.0 * i / QUIET.fps
                                                      + rec.truth["phase"]), atol=1e-12)
    assert np.ptp(gain) > 0.02
    # the backdrop's level follows the gain
    for i in (0, 1, 7):
        assert float(rec.source[i][200, 5]) == pytest.approx(
            float(ref.source[i][200, 5]) * gain[i], abs=0.51)


@pytest.mark.parametrize("fault, size", [("flicker", 0.1), ("glitches", 0.015), ("held", 20)])
def test_faults_are_deterministic_by_seed(fault, size):
    a, b = faulty(fault, size, seed=4), faulty(fault, size, seed=4)
    c = faulty(fault, size, seed=5)
    same = [np.array_equal(x, y) for x, y in zip(a.source.frames, b.source.frames, strict=True)]
    other = [np.array_equal(x, y) for x, y in zip(a.source.frames, c.source.frames, strict=True)]
    assert all(same) and not all(other)


def test_unknown_fault_is_refused():
    with pytest.raises(ValueError, match="unknown fault"):
        faulty("smoke", 1.0)
    assert set(fl.FAULTS) >= {"held", "rest", "bump", "drift", "yaw", "pitch", "flicker"}


def test_the_study_judges_a_held_start_and_a_clean_case():
    from validation.studies.faults import format_tables, run_study

    study = run_study(seeds=1, clean_seeds=1, faults=["held"], families=["noise 1 DN"],
                      sizes={"held": (60,)}, log=lambda line: None)
    (row,) = study["fault_rows"]
    assert row["named"] is True and row["verdict"] == "ok", row
    assert abs(row["err_U"]) <= 1.0, row
    (c,) = study["clean_rows"]
    assert c["verdict"] == "ok" and not c["reasons"] and not c["findings"], c
    assert abs(c["err_U"]) <= 1.0, c
    assert study["faults"]["held 60"]["named"] == 1
    assert study["clean"]["all"]["false_alarms"] == {}
    assert "| held | 60 | 1 | 1 / 0 / 0 | 1 |" in format_tables(study)
