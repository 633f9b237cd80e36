"""The camera's timing: synth's jitter and dropped frames (synth.camera_clock), rollfric's dropped
frames found from the motion (rollfric.track.dropped_frames) and repaired, and timestamps carried
by a Zarr
recording.

The angles are the reference solution of the equation of motion (rollfric.fit.eom) at the real
sample times, so every expected value is exact; the centres are its projection on a circle."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rollfric.fit import eom
from rollfric.fit.estimate import fit_mu
from rollfric.setup.model import Setup
from rollfric.track.dropped_frames import find_gaps

FPS = 1000.0
SETUP = Setup(cylinder_radius=85.3e-3, ball_diameter=10e-3, ball_mass=4.07612e-3, fps=FPS,
              pixel_size=0.1343e-3)
L_PX = SETUP.track_radius / SETUP.pixel_size  # 598 px: the thesis camera
MU = 0.0079
THETA0 = math.radians(20.0)


def camera_track(numbers, *, noise_px=0.02, seed=0, jitter=None):
    """(x, y, theta) of the ball at camera frames ``numbers`` (+ ``jitter`` s), centres with
    Gaussian noise of ``noise_px`` per axis."""
    t = np.asarray(numbers, dtype=float) / FPS
    if jitter is not None:
        t = t + jitter
    th, _, _ = eom.solve_reference(THETA0, 0.0, MU, t, track_radius=SETUP.track_radius)
    rng = np.random.default_rng(seed)
    x = 640.0 + L_PX * np.sin(th) + rng.normal(0.0, noise_px, th.size)
    y = -80.0 + L_PX * np.cos(th) + rng.normal(0.0, noise_px, th.size)
    return x, y, th


def angles_of(x, y):
    return np.arctan2(x - 640.0, y + 80.0)


# -- synth: the camera's frame times -------------------------------------------------------

def test_frame_times_drop_the_listed_frames_and_keep_the_rest_on_time():
    from synth.camera_clock import FrameTiming, frame_times

    times, numbers = frame_times(1000, FPS, FrameTiming(dropped=(5, 400, 401)), seed=3)
    assert numbers.size == 997
    assert not {5, 400, 401} & set(numbers.tolist())
    np.testing.assert_array_equal(times, numbers / FPS)  # no jitter: exactly frame / fps


def test_frame_times_jitter_has_the_stated_spread_and_the_seed_fixes_it():
    from synth.camera_clock import FrameTiming, frame_times

    timing = FrameTiming(jitter=5e-6, drop_rate=0.01)
    t1, n1 = frame_times(20000, FPS, timing, seed=7)
    t2, n2 = frame_times(20000, FPS, timing, seed=7)
    np.testing.assert_array_equal(t1, t2)
    dev = t1 - n1 / FPS
    assert dev[0] == 0.0
    # 20000 draws: the sample std of N(0, 5 us) is within 2 % of it (6 sigma: 3 %)
    assert np.std(dev[1:]) == pytest.approx(5e-6, rel=0.03)
    # drops at rate 0.01: 200 +- 14 expected (binomial); 5 sigma
    assert abs((20000 - n1.size) - 200) < 5 * math.sqrt(200)
    assert frame_times(20000, FPS, timing, seed=8)[1].size != n1.size or \
        not np.array_equal(frame_times(20000, FPS, timing, seed=8)[0], t1)


def test_frame_times_stay_within_the_motions_span():
    """A jittered last exposure after the simulated span is not recorded (a 2 s case with
    50 us jitter failed to render: times 0..2.0001 s outside the trajectory's 0..2 s)."""
    from synth.camera_clock import FrameTiming, frame_times

    late = 0
    for seed in range(40):
        t, n = frame_times(2001, FPS, FrameTiming(jitter=50e-6), seed=seed)
        assert t[0] == 0.0 and t[-1] <= 2.0
        assert n.size in (2000, 2001) and np.array_equal(n, np.arange(n.size))
        late += n.size == 2000
    assert 5 < late < 35  # about half of the seeds put the last frame late


@pytest.mark.parametrize("bad", [dict(jitter=-1e-6), dict(drop_rate=0.6),
                                 dict(dropped=(0,))])
def test_frame_timing_refuses_bad_values(bad):
    from synth.camera_clock import FrameTiming
    from synth.config import SynthError

    with pytest.raises(SynthError):
        FrameTiming(**bad)


def test_frame_times_refuse_a_jitter_of_a_tenth_period():
    from synth.camera_clock import FrameTiming, frame_times
    from synth.config import SynthError

    with pytest.raises(SynthError, match="jitter"):
        frame_times(100, FPS, FrameTiming(jitter=100e-6))


def test_resample_puts_the_ball_where_the_equation_of_motion_has_it():
    import sim
    from synth.camera_clock import resample

    sc = sim.scenario_from_dict({"motion": {"mu": MU, "theta0_deg": 20.0, "seconds": 0.5},
                                 "engine": {"name": "reference"}})
    traj = sim.simulate(sc)
    ts = np.sort(np.random.default_rng(0).uniform(0.01, 0.49, 300))
    out = resample(traj, ts)
    exact, _, _ = eom.solve_reference(THETA0, 0.0, MU, np.r_[0.0, ts],  # state at t = 0
                                      track_radius=sc.setup().track_radius)
    exact = exact[1:]
    # the Hermite spline between 1 ms samples: below 1e-8 rad (the engine's own error aside)
    ref = resample(traj, traj.t[10:490])
    np.testing.assert_allclose(ref.theta, traj.theta[10:490], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out.theta, exact, rtol=0, atol=1e-7)
    # the centre on the ball's circle at the resampled angle
    pos = out.position
    np.testing.assert_allclose(np.arctan2(pos[:, 0], -pos[:, 1]), out.theta, rtol=0, atol=1e-8)


# -- rollfric: dropped frames from the motion ----------------------------------------------

DROPS = (137, 420, 421, 1234, 1730)


def test_dropped_frames_are_found_where_they_are():
    numbers = np.setdiff1d(np.arange(2000), DROPS)
    x, y, _ = camera_track(numbers)
    gaps = find_gaps(x, y, np.ones(x.size, bool))
    # recorded frame k is followed by the gap: camera frame 137 is lost after recorded 136, ...
    assert gaps.dropped == ((136, 1), (418, 2), (1230, 1), (1725, 1))
    assert gaps.n_dropped == 5 and gaps.irregular == ()
    np.testing.assert_array_equal(gaps.pos, numbers)


@pytest.mark.parametrize("seed", range(6))
def test_no_dropped_frame_is_found_in_a_whole_track(seed):
    # the default case's centre noise is 0.02 px; 0.05 px here, 4 s of 1 kHz
    x, y, _ = camera_track(np.arange(4000), noise_px=0.05, seed=seed)
    gaps = find_gaps(x, y, np.ones(x.size, bool))
    assert gaps.dropped == () and gaps.irregular == ()
    np.testing.assert_array_equal(gaps.pos, np.arange(4000))


def test_a_located_glitch_is_no_dropped_frame():
    # a frame located 3 px off and a repeated frame spoil two steps each: not a gap
    x, y, _ = camera_track(np.arange(1500))
    x[300] += 3.0
    x[801], y[801] = x[800], y[800]
    gaps = find_gaps(x, y, np.ones(x.size, bool))
    assert gaps.dropped == ()


def test_a_frame_half_a_period_late_is_irregular_not_dropped():
    numbers = np.arange(1500, dtype=float)
    numbers[850:] += 0.5  # every frame from 850 on (fast: mid-swing) half a period late
    x, y, _ = camera_track(numbers)
    gaps = find_gaps(x, y, np.ones(x.size, bool))
    assert gaps.dropped == ()
    assert [k for k, _ in gaps.irregular] == [849]
    assert gaps.irregular[0][1] == pytest.approx(1.5, abs=0.05)


def test_the_repaired_track_gives_the_clean_mu_and_the_unrepaired_one_does_not():
    numbers = np.setdiff1d(np.arange(2500), DROPS)
    x, y, _ = camera_track(numbers, seed=4)
    gaps = find_gaps(x, y, np.ones(x.size, bool))
    th = angles_of(x, y)
    clean_x, clean_y, _ = camera_track(np.arange(2500), seed=4)
    clean = fit_mu(np.arange(2500) / FPS, angles_of(clean_x, clean_y), SETUP)
    repaired = fit_mu(gaps.pos / FPS, th, SETUP)
    naive = fit_mu(np.arange(numbers.size) / FPS, th, SETUP)
    se = clean.mu_stderr
    assert abs(clean.mu - MU) < 4 * se
    assert abs(repaired.mu - MU) < 4 * se
    # five lost periods, unrepaired: the swing looks faster and decays sooner (mu up)
    assert (naive.mu - MU) / MU > 0.005 and naive.mu - MU > 20 * se


def test_jitter_is_noise_in_time_that_leaves_mu_unbiased():
    # 20 us jitter, times taken as frame / fps: the angle errs by theta_dot * jitter, zero
    # mean; the fit's residual grows by that (rms over the track), mu stays within its error
    n = 2500
    rng = np.random.default_rng(11)
    jit = rng.normal(0.0, 20e-6, n)
    x, y, th_true = camera_track(np.arange(n), jitter=jit, noise_px=0.0)
    th = angles_of(x, y)
    res = fit_mu(np.arange(n) / FPS, th, SETUP)
    _, thd, _ = eom.solve_reference(THETA0, 0.0, MU, np.arange(n) / FPS,
                                    track_radius=SETUP.track_radius)
    expect = float(np.sqrt(np.mean((thd * 20e-6) ** 2)))
    assert res.rms_residual == pytest.approx(expect, rel=0.1)
    assert abs(res.mu - MU) < 4 * res.mu_stderr


def test_measure_repairs_dropped_frames_and_reports_them(tmp_path):
    """rollfric measure end to end on drawn frames: the dropped frames in fit.json, t_s moved,
    no frame flagged, mu as from the clean recording."""
    import tifffile

    from rollfric import measurement as track_mod
    from tests.measure_data import make_recording

    clean = make_recording(300, mu=0.02, theta0=0.5, fps=200.0, noise=1.0, seed=2)
    drop = [60, 61, 170]
    keep = np.setdiff1d(np.arange(300), drop)
    tifffile.imwrite(tmp_path / "rec.tif", np.stack([clean.frames[i] for i in keep]))
    tifffile.imwrite(tmp_path / "clean.tif", np.stack(clean.frames))
    df, info, res = track_mod.measure(tmp_path / "rec.tif", clean.setup, clean.background)
    _, _, ref = track_mod.measure(tmp_path / "clean.tif", clean.setup, clean.background)
    assert info.frames_dropped == ((59, 2), (167, 1))
    assert info.flags == {}
    np.testing.assert_allclose(df["t_s"].to_numpy(), keep / 200.0, rtol=0, atol=1e-12)
    assert res.mu == pytest.approx(ref.mu, abs=2 * ref.mu_stderr)
    assert not [r for r in res.quality_reasons if r.code == "timing"]


def test_zarr_timestamps_are_the_times(tmp_path):
    """A Zarr recording with a ``timestamps`` array: t_s are its times (a dropped frame shows as
    a gap in them), no drop is looked for in the motion."""
    import zarr

    from rollfric import measurement as track_mod
    from rollfric.io import readers as io
    from tests.measure_data import make_recording

    clean = make_recording(200, mu=0.02, theta0=0.5, fps=200.0, noise=1.0, seed=5)
    keep = np.setdiff1d(np.arange(200), [90])
    g = zarr.open_group(str(tmp_path / "rec.zarr"), mode="w")
    g.create_array("frames", data=np.stack([clean.frames[i] for i in keep]))
    g.create_array("timestamps", data=100.0 + keep / 200.0)
    src = io.open_recording(tmp_path / "rec.zarr")
    np.testing.assert_allclose(src.timestamps, keep / 200.0, rtol=0, atol=1e-12)
    df, info, res = track_mod.measure(src, clean.setup, clean.background)
    assert info.times == "the recording's timestamps" and info.frames_dropped == ()
    assert info.flags == {}
    np.testing.assert_allclose(df["t_s"].to_numpy(), keep / 200.0, rtol=0, atol=1e-9)


def test_a_frame_lost_where_the_ball_turns_is_found_by_the_fit():
    """No step shows a frame lost at a turning point; the fit's residual after it does."""
    from rollfric.track.dropped_frames import turning_gaps

    omega = math.sqrt(5 * 9.80665 / (7 * SETUP.track_radius))
    turn = 3 * int(round(math.pi / omega * FPS))  # the third turning point, camera frame 1008
    numbers = np.setdiff1d(np.arange(3000), [turn])
    x, y, _ = camera_track(numbers, seed=1)
    gaps = find_gaps(x, y, np.ones(x.size, bool))
    assert gaps.dropped == ()  # too slow there for the steps
    th = angles_of(x, y)
    first = fit_mu(gaps.pos / FPS, th, SETUP)
    t, res, found = turning_gaps(gaps.pos / FPS, th, first, SETUP, False)
    assert len(found) == 1 and abs(found[0][0] - (turn - 1)) <= 10
    # unrepaired: mu -0.12 %, a residual that is no noise (its stderr inflated 10-fold)
    assert abs(first.mu - MU) / MU > 5e-4 and first.quality_reasons
    assert abs(res.mu - MU) < 4 * res.mu_stderr and res.mu_stderr < first.mu_stderr / 5
    # and none in a track without a lost frame
    x, y, _ = camera_track(np.arange(3000), seed=1)
    th = angles_of(x, y)
    clean = fit_mu(np.arange(3000) / FPS, th, SETUP)
    assert turning_gaps(np.arange(3000) / FPS, th, clean, SETUP, False)[2] == ()


# -- irregular steps: the timing's or the locator's ------------------------------------------


def _judged(x, y, found, sigma):
    """The tracker's chain: the gaps, the plausibility flags (with the gaps' frame times), the
    lost frames flagged, and the irregular steps split (rollfric.track.tracker.track_recording)."""
    from rollfric.track import plausibility
    from rollfric.track.dropped_frames import split_irregular
    from rollfric.track.timestamps import LOCATOR_FLAGS

    gaps = find_gaps(x, y, found)
    flags = plausibility.flag_frames(x, y, found, sigma=sigma, pos=gaps.pos)
    flags[~found] = "not_found"
    return gaps, flags, split_irregular(gaps.irregular, np.isin(flags, LOCATOR_FLAGS))


def test_an_irregular_step_where_the_ball_leaves_a_shadow_is_the_locators():
    # frames 800-829 lost in a deep shadow; leaving it, half lit, the ball is located 1 px
    # towards its lit side (rim sigma 15x) until the rim is whole again at frame 850: the step
    # 849 -> 850 (mid-swing, 1.9 px a frame) fits no whole number of periods
    x, y, _ = camera_track(np.arange(1500), seed=3)
    found = np.ones(x.size, bool)
    sigma = np.full(x.size, 0.02)
    found[800:830] = False
    x[800:830] = y[800:830] = np.nan
    x[830:850] -= 1.0
    sigma[830:850] = 0.3
    gaps, flags, (timing_steps, located) = _judged(x, y, found, sigma)
    assert [k for k, _ in gaps.irregular] == [849]  # what the timing check alone says
    assert set(flags[830:850]) == {"residual"}
    assert timing_steps == () and [k for k, _ in located] == [849]


def test_a_frame_half_a_period_late_stays_the_timings_after_the_plausibility_checks():
    numbers = np.arange(1500, dtype=float)
    numbers[850:] += 0.5
    x, y, _ = camera_track(numbers)
    gaps, flags, (timing_steps, located) = _judged(x, y, np.ones(x.size, bool),
                                                   np.full(x.size, 0.02))
    assert [k for k, _ in timing_steps] == [849] and located == ()
    # the late frames may look like a jump: a timing error's flag, which does not excuse it
    assert set(flags[845:855]) <= {"", "jump"}


def test_measure_reports_frames_taken_half_a_period_late_as_timing(tmp_path):
    """rollfric measure end to end on drawn frames taken at 200 Hz, from frame 150 on a
    quarter period late: the quality reason is the timing's, not the located frames'."""
    import tifffile

    from rollfric import measurement as track_mod
    from tests.measure_data import make_recording

    fine = make_recording(1200, mu=0.02, theta0=0.5, fps=800.0, noise=1.0, seed=2)
    keep = np.r_[np.arange(0, 600, 4), np.arange(601, 1200, 4)]  # 150 on: 1/4 period late
    tifffile.imwrite(tmp_path / "rec.tif", np.stack([fine.frames[i] for i in keep]))
    setup = fine.setup.replace(fps=200.0)
    _, info, res = track_mod.measure(tmp_path / "rec.tif", setup, fine.background)
    assert [k for k, r in info.timing_irregular] == [149]
    assert info.timing_irregular[0][1] == pytest.approx(1.25, abs=0.05)
    assert info.located_irregular == ()
    codes = [r.code for r in res.quality_reasons]
    assert "timing" in codes and "located_frames" not in codes
