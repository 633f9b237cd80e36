"""A camera bumped or drifting during the recording: found from the static scene
(rollfric.track.camera_motion), named, and the centres moved back (drawn recordings whose frames
are shifted from a frame on, or steadily: validation.faults.camera)."""

import math

import numpy as np
import pytest

from rollfric.measurement import measure
from rollfric.track import camera_motion as cm
from synth.drawn.frames import Scene, make_frames
from tests.measure_data import MemorySource, make_recording
from validation.faults.camera import camera_shift, moved_frames

MU = 0.01
N = 400


def _rec():
    # a frame wide enough to show the trough's walls on both sides (the static scene)
    return make_recording(N, noise=1.0, with_center=True, mu=MU, theta0=0.2,
                          center=(240.0, 20.0), width=480, height=280)


def test_a_3px_bump_is_found_at_its_frame_and_corrected():
    """Before: 150 of 399 samples left out as outliers and a 'center' reason (exit 3), the
    bump not named. Now: the bump's frame and size are found, the centres moved back, mu
    within 0.05 % (its standard error 0.005 %) and no reason."""
    rec = _rec()
    frames = moved_frames(rec.frames, camera_shift(N, bump_at=250, bump_px=(3.0, 0.0)))
    df, info, res = measure(MemorySource(frames), rec.setup, rec.background)
    m = info.camera_motion
    assert m["kind"] == "bump" and m["frame"] == 250
    assert m["size_px"] == pytest.approx([3.0, 0.0], abs=0.02)
    assert res.mu == pytest.approx(MU, rel=5e-4)
    assert not [r.code for r in res.quality_reasons]
    assert any("moved by (+3.00, +0.00) px at frame 250" in w for w in info.warnings)
    found = df["found"].to_numpy() == 1
    err = np.hypot(df["x_px"] - rec.centers[:, 0], df["y_px"] - rec.centers[:, 1])[found]
    assert np.median(err) < 0.05  # the centres are back in the background's frame


def test_a_bump_among_glitched_frames():
    """The same bump in a recording with 1.5 % glitched frames of each kind (corrupt bands,
    swaps, repeats, flashes): the glitches are neither sampled as motion nor break it."""
    from validation.faults.glitches import glitch_frames

    rec = _rec()
    moved = moved_frames(rec.frames, camera_shift(N, bump_at=250, bump_px=(3.0, 0.0)))
    frames, glitches = glitch_frames(np.stack(moved), seed=3, centers=rec.centers,
                                     r_px=rec.scene.r_px, bar_frames=0, band_on_ball=0.0)
    df, info, res = measure(MemorySource(list(frames)), rec.setup, rec.background)
    m = info.camera_motion
    assert m["kind"] == "bump" and m["frame"] == 250
    assert m["size_px"] == pytest.approx([3.0, 0.0], abs=0.02)
    assert res.mu == pytest.approx(MU, rel=5e-4)


def test_a_slow_drift_is_found_and_corrected():
    """A drift of (1.5, 1.0) px over the recording: mu +0.59 % with residual reasons before;
    found as a drift of its size, mu within 0.2 % now."""
    rec = _rec()
    frames = moved_frames(rec.frames, camera_shift(N, drift_px=(1.5, 1.0)))
    df, info, res = measure(MemorySource(frames), rec.setup, rec.background)
    m = info.camera_motion
    assert m["kind"] == "drift"
    assert m["size_px"] == pytest.approx([1.5, 1.0], abs=0.02)
    assert res.mu == pytest.approx(MU, rel=2e-3)
    assert not [r.code for r in res.quality_reasons]
    assert any("drifted by (+1.50, +1.00) px" in w for w in info.warnings)


@pytest.mark.parametrize("kw", [dict(noise=4.0), dict(noise=2.0, trough_visible=False)])
def test_a_still_camera_is_still(kw):
    rec = make_recording(200, theta0=0.5, **kw)
    m = cm.find_motion(MemorySource(rec.frames), rec.background, rec.centers, rec.scene.r_px)
    # a backdrop without the trough has nothing to measure a shift on: not a motion
    assert m.kind == ("still" if kw.get("trough_visible", True) else "unknown")
    if m.kind == "still":
        assert np.abs(m.shifts).max() < cm.MOTION_MIN_PX
    assert not m.per_frame(200).any()


@pytest.mark.parametrize("thesis", [False, True])
def test_frame_shift_measures_a_known_shift(thesis):
    """Sub-pixel shifts of the static scene to 0.01 px, on the small drawn scene and the
    thesis camera's 1280 x 1024 frame (where a phase correlation that windowed its inputs in
    place left the refinement at 2.52 px for 3)."""
    if thesis:
        sc = Scene(noise=1.0)
        p = sc.ball_center(0.3)
        bg, (frame,) = make_frames(sc, [p], seed=0)
        r = sc.r_px
    else:
        rec = _rec()
        bg, frame, p, r = rec.background, rec.frames[10], rec.centers[10], rec.scene.r_px
    for shift in ((0.37, -1.21), (3.0, 0.0)):
        moved = moved_frames([frame], [shift])[0]
        assert cm.frame_shift(moved, bg, p, r) == pytest.approx(shift, abs=0.01)


@pytest.mark.parametrize("drift_px, sigma", [(0.0, 0.06), (1.0, 0.06), (0.0, 0.3)])
def test_a_drift_must_stand_out_from_the_shifts_own_noise(monkeypatch, drift_px, sigma):
    """Shifts measured with 0.06 px of noise (a dim rendered scene: a still camera's samples
    spread 0.15 px, beyond MOTION_MIN_PX, and were "corrected" as a drift, mu 7 U off): still;
    a 1 px drift under the same noise is a drift; shifts with 0.3 px of noise cannot tell a
    still camera from a moving one: unknown (nothing corrected)."""
    n = 400
    rng = np.random.default_rng(1)
    noise = rng.normal(0.0, sigma, (n, 2))

    def fake_shift(frame, background, ball=None, r_px=0.0, window=None, *, level=0):
        i = int(frame[0, 0])
        return tuple(noise[i] + drift_px * i / (n - 1) * np.array([1.0, 0.0]))

    monkeypatch.setattr(cm, "frame_shift", fake_shift)
    frames = [np.full((8, 8), i, dtype=np.float32) for i in range(n)]
    m = cm.find_motion(MemorySource(frames), np.zeros((8, 8)), np.full((n, 2), np.nan), 3.0)
    spread = np.max(np.hypot(*(m.shifts - m.shifts[0]).T))  # what MOTION_MIN_PX judged
    if drift_px:
        assert m.kind == "drift" and m.size_px[0] == pytest.approx(1.0, abs=0.2)
    elif sigma > cm.MOTION_MIN_PX:
        assert m.kind == "unknown" and not m.per_frame(n).any()
    else:
        assert spread > cm.MOTION_MIN_PX  # the noise alone passed the old test
        assert m.kind == "still"



def _small():
    # a 160 x 66 px frame around the trough's bottom, a ball of 20 px radius: its masked
    # square (2 radii + 2 px a side) is a third of the frame, as on the rendered fault study's
    # 182 x 66 px frames
    return make_recording(N, noise=2.0, with_center=True, mu=MU, theta0=0.2,
                          center=(80.0, -144.0), width=160, height=66, ball_mm=17.0)


@pytest.mark.parametrize("bump_px, drift_px", [((3.0, 0.0), None), ((1.0, 0.0), None),
                                               (None, (2.0, 1.0))])
def test_a_moved_camera_is_found_where_the_balls_square_is_much_of_a_small_frame(bump_px,
                                                                                drift_px):
    """Before: the phase correlation of the frame, its ball's square filled in from the
    background, peaked at no shift (the filled square is the same in both): a 3 px or 1 px
    bump was "still" (exit 3 by 'outliers' and 'center'), a drift "unknown" (mu -0.75 %). Now
    the square is left out of a masked correlation: found, sized and corrected."""
    rec = _small()
    shift = camera_shift(N, bump_at=250 if bump_px else None, bump_px=bump_px or (0.0, 0.0),
                         drift_px=drift_px or (0.0, 0.0))
    frames = moved_frames(rec.frames, shift)
    df, info, res = measure(MemorySource(frames), rec.setup, rec.background)
    m = info.camera_motion
    assert m["kind"] == ("bump" if bump_px else "drift")
    assert m["size_px"] == pytest.approx(bump_px or drift_px, abs=0.05)
    if bump_px:
        assert m["frame"] == 250
    assert res.mu == pytest.approx(MU, rel=5e-4)


def test_a_drift_is_the_theil_sen_line_through_its_samples():
    """Samples on a steady drift, two of them 0.3 px off (the ball hid most of the scene
    there): the line the correction uses stays within 0.01 px of the drift."""
    frames = np.linspace(0, 399, 12).round()
    true = np.column_stack([frames / 399 * 2.0, frames / 399 * 1.0])
    s = true.copy()
    s[3] += (0.3, -0.3)
    s[7] += (-0.3, 0.3)
    m = cm.CameraMotion("drift", frames, s, size_px=tuple(s[-1] - s[0]))
    per = m.per_frame(400)
    assert np.abs(per - np.column_stack([np.arange(400) / 399 * 2.0,
                                         np.arange(400) / 399 * 1.0])).max() < 0.01


def test_a_plain_backdrop_cannot_tell_a_shift():
    """A backdrop with a linear shading and noise: a shift along the shading is an offset the
    correlation leaves free, so the shift's standard error is beyond SHIFT_MAX_SE_PX (NaN),
    where the trough's edge in view gives one of a few thousandths of a pixel."""
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[:120, :200]
    plain = 100.0 + 0.3 * xx + 0.2 * yy
    bg = plain + rng.normal(0, 2.0, plain.shape)
    frame = np.roll(plain, 2, axis=1) + rng.normal(0, 2.0, plain.shape)
    assert np.isnan(cm.frame_shift(frame, bg)).all()
    rec = _rec()
    f = moved_frames([rec.frames[10]], [(2.0, 0.0)])[0]
    assert cm.frame_shift(f, rec.background, rec.centers[10] + (2.0, 0.0),
                          rec.scene.r_px) == pytest.approx((2.0, 0.0), abs=0.01)


def test_the_correction_of_a_drift_or_bump_is_a_budget_row():
    """The samples' scatter about the drift's line (or a bump's two levels) is the
    correction's uncertainty: x and y, offset and slope (level and step), each one standard
    uncertainty, of the size a straight-line fit (a difference of means) gives it."""
    from rollfric.uncertainty.motion import patterns

    k = 12
    frames = np.linspace(0, 1100, k).round()
    wiggle = np.where(np.arange(k) % 2 == 0, 0.1, -0.1)
    shifts = np.column_stack([frames / 1100 * 2.0 + wiggle, frames / 1100 * 1.0])
    at = np.array([0.0, 550.0, 1100.0])
    got = dict(patterns({"kind": "drift", "frames": frames, "shifts_px": shifts}, at))
    sigma = 0.1 * math.sqrt(k / (k - 2))
    sxx = float(np.sum((frames - frames.mean()) ** 2))
    assert got["x offset"][:, 0] == pytest.approx(sigma / math.sqrt(k), rel=0.05)
    assert got["x slope"][:, 0] == pytest.approx(sigma * (at - frames.mean()) / math.sqrt(sxx),
                                                 rel=0.05, abs=1e-9)
    assert not got["y slope"].any() and not got["x slope"][:, 1].any()
    bump = {"kind": "bump", "frame": 600, "frames": frames,
            "shifts_px": np.column_stack([np.where(frames >= 600, 3.0, 0.0) + wiggle,
                                          np.zeros(k)])}
    got = dict(patterns(bump, at))
    assert got["x step"][:, 0] == pytest.approx([0.0, 0.0, sigma * math.sqrt(1 / 6 + 1 / 6)],
                                                rel=0.05)
    assert patterns({"kind": "still", "frames": frames, "shifts_px": shifts}, at) == []


def test_a_corrected_drift_on_a_small_frame_is_within_its_budget():
    """The drift of the small frame corrected: the budget holds the correction's row, and mu
    is within its U; the still camera's budget has no such row."""
    from rollfric.uncertainty.budget import budget
    from rollfric.uncertainty.measured import measurement_from_track
    from rollfric.uncertainty.motion import SOURCE

    rec = _small()
    for drift, row in (((2.0, 1.0), True), ((0.0, 0.0), False)):
        frames = moved_frames(rec.frames, camera_shift(N, drift_px=drift))
        df, info, res = measure(MemorySource(frames), rec.setup, rec.background)
        b = budget(measurement_from_track(df, info), res)
        rows = [r for r in b.rows if r.source == SOURCE]
        assert bool(rows) == row
        if row:
            assert rows[0].u_mu > 0 and "drift" in rows[0].note
        assert abs(b.mu - MU) < b.U_mu


def test_what_the_first_pass_over_a_bumped_camera_warned_of_is_withdrawn(caplog):
    """The first pass over a 3 px bump reads the step as 3 dropped frames and says so while
    tracking; the camera's warning says that no longer holds."""
    rec = _rec()
    frames = moved_frames(rec.frames, camera_shift(N, bump_at=250, bump_px=(3.0, 0.0)))
    with caplog.at_level("WARNING", logger="rollfric"):
        df, info, res = measure(MemorySource(frames), rec.setup, rec.background)
    said = [r.getMessage() for r in caplog.records]
    assert any(m.startswith("3 dropped frame(s)") for m in said)
    (moved,) = [w for w in info.warnings if "the camera moved" in w]
    assert "no longer holds: 3 dropped frame(s) found" in moved
    assert not any("dropped" in w for w in info.warnings if w != moved)


def test_a_shift_that_fades_over_frames_is_no_bump(monkeypatch):
    """A grazing light's long shadow of the ball at its release moved the first samples'
    shift by 2.3 px, fading over 30 frames (a clean rendered recording read as a bump at
    frame 25, then a timing reason): a bump is a step, the frames either side of it at the
    two levels, seen in two samples on each side; a fade is not, and a real step is."""
    n = 1200
    rng = np.random.default_rng(2)
    noise = rng.normal(0.0, 0.01, (n, 2))

    def run(profile):
        def fake_shift(frame, background, ball=None, r_px=0.0, *, level=0):
            i = int(frame[0, 0])
            return (profile(i) + noise[i, 0], noise[i, 1])

        monkeypatch.setattr(cm, "frame_shift", fake_shift)
        frames = [np.full((8, 8), i, dtype=np.float32) for i in range(n)]
        return cm.find_motion(MemorySource(frames), np.zeros((8, 8)),
                              np.full((n, 2), np.nan), 3.0)

    assert run(lambda i: 2.3 * max(0.0, 1.0 - i / 30.0)).kind == "still"
    assert run(lambda i: 2.3 * max(0.0, 1.0 - (i - 220) / 60.0) if i >= 220 else 2.3).kind \
        != "bump"
    m = run(lambda i: 2.3 if i < 250 else 0.0)
    assert m.kind == "bump" and m.frame == 250


def test_a_step_where_the_ball_sits_is_checked_where_it_is_at_the_same_place():
    """A dim scene's shifts are biased by where the ball hides the trough's arc: the release
    frame, the ball at its held place, read 0.7 px off the later samples, a "bump" between
    it and the next sample. The step is checked between frames with the ball at the same
    place before and after it: a bias that goes with the ball's place is no camera's; a real
    0.7 px bump at frame 408 is."""
    n = 1200
    t = np.arange(n) / 1000.0
    x = 100.0 + 60.0 * np.cos(2 * np.pi * t / 0.68) * np.exp(-t)

    class Fake:
        centres = np.column_stack([x, np.full(n, 30.0)])
        located = np.ones(n, bool)
        r_px = 20.0

        def __init__(self, camera):
            self.camera = camera

        def __call__(self, i):
            return np.array([0.7 * (i == 0) + self.camera(i), 0.0])

    after = np.array([408, 517, 735, 844, 1063])
    size = np.array([-0.7, 0.0])  # the samples after, less the release frame's
    assert not cm._seen_at_the_same_place(Fake(lambda i: 0.0), after, 408, size, 0.18)
    assert cm._seen_at_the_same_place(Fake(lambda i: 0.7 * (i >= 408)), after, 408,
                                      np.array([0.7, 0.0]), 0.18)
