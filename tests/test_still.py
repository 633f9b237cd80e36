"""Held starts and resting balls: found from the track, flagged, left out of the fit."""

import math

import numpy as np
from measure_data import PIX, R
from test_measure_roi import _Plain

from rollfric.fit import eom
from rollfric.measurement import measure
from rollfric.setup.model import Setup
from rollfric.track import still
from synth.drawn.frames import Scene, make_frames


def _recording(n_held, n_moving, n_rest=0, *, mu=0.02, theta0=0.5, fps=200.0, seed=0):
    """Drawn frames of a ball held at theta0 for n_held frames, released (the equation of
    motion from rest), then (n_rest > 0) held at its last place for n_rest frames."""
    center = (180.0, 20.0)
    setup = Setup(cylinder_radius=R, ball_diameter=6e-3, ball_mass=4e-3, fps=fps,
                  pixel_size=PIX, center_px=center)
    L = setup.track_radius / PIX
    t_mov = np.arange(n_moving) / fps
    th_mov, _, _ = eom.solve_reference(theta0, 0.0, mu, t_mov, track_radius=setup.track_radius)
    if n_rest:
        # it comes to rest where it turns (a ball stops when its speed is zero)
        turns = np.flatnonzero(np.diff(np.sign(np.diff(th_mov))) != 0) + 1
        th_mov = th_mov[:turns[-1] + 1]
    theta = np.concatenate([np.full(n_held, theta0), th_mov, np.full(n_rest, th_mov[-1])])
    centers = [(center[0] + L * math.sin(a), center[1] + L * math.cos(a)) for a in theta]
    scene = Scene(width=360, height=240, center=center, R_px=200.0,
                  r_px=setup.ball_radius / PIX, wall_px=20, noise=1.0)
    bg, frames = make_frames(scene, centers, seed=seed)
    return setup, bg, frames, theta


def test_a_held_start_is_flagged_and_left_out_and_mu_comes_out_within_u(tmp_path, capsys):
    import json

    import pandas as pd
    import tifffile

    from rollfric.cli.main import main
    from rollfric.setup.model import save_setup

    n_held = 60  # 0.3 s at 200 Hz (before: mu 0.148, exit 3 for residuals, no word of a hold)
    setup, bg, frames, theta = _recording(n_held, 300)
    tifffile.imwrite(tmp_path / "rec.tif", np.stack(frames))
    save_setup(setup, tmp_path / "setup.toml")
    out = tmp_path / "out"
    code = main(["measure", str(tmp_path / "rec.tif"), "--setup", str(tmp_path / "setup.toml"),
                 "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "held still before its release: frames 0-59" in err
    fit = json.loads((out / "fit.json").read_text())
    assert fit["frames_held"] == n_held and fit["frames_rest"] == 0
    assert abs(fit["mu"] - 0.02) < fit["U_mu"]
    df = pd.read_csv(out / "track.csv", keep_default_na=False)
    flag = df["still"].to_numpy()
    # the held frames (the release's frame included), located all the same
    assert (flag[:n_held] == "held").all() and (flag[n_held:] == "").all()
    assert (df["found"] == 1).all()


def test_a_rest_at_the_end_is_flagged():
    setup, bg, frames, theta = _recording(0, 240, 150, mu=0.02)
    n_mov = len(theta) - 150
    df, info, res = measure(_Plain([np.asarray(f) for f in frames]), setup, bg)
    rest = np.flatnonzero(df["still"].to_numpy() == "rest")
    assert rest.size >= 140 and rest.min() >= n_mov and rest.max() == len(theta) - 1
    assert not (df["flag"] == "stuck").any() and not (df["still"] == "held").any()
    assert res.quality == "ok", [r.message for r in res.quality_reasons]
    assert any("at rest from there on" in w for w in info.warnings)
    assert abs(res.mu - 0.02) < max(3 * res.mu_stderr, 2e-4), (res.mu, res.mu_stderr)


def test_a_release_from_rest_at_the_start_is_not_a_hold():
    setup, bg, frames, theta = _recording(0, 300)
    df, info, res = measure(_Plain([np.asarray(f) for f in frames]), setup, bg)
    assert (df["still"] == "").all()
    sp = still.still_spells(np.arange(300) / 200.0, theta, np.ones(300, bool), setup)
    assert not sp["held"].any() and not sp["rest"].any()


def test_rollfric_fit_leaves_the_still_rows_of_a_track_out(tmp_path):
    from rollfric.cli.fit import read_track

    p = tmp_path / "track.csv"
    p.write_text("t_s,theta_rad,found,flag,still\n0,0.5,1,,held\n0.01,0.5,1,,held\n"
                 + "".join(f"{0.02 + 0.01 * i:.2f},{0.5 - 0.001 * i * i:.6f},1,,\n"
                           for i in range(60))
                 + "0.62,0.1,1,,rest\n")
    t, theta = read_track(p)[:2]
    assert np.isnan(theta[[0, 1, 62]]).all() and np.isfinite(theta[2:62]).all()


def test_a_rest_held_by_the_median_background_is_named_and_the_fit_is_ok():
    # at rest in 400 of 608 frames: the median of all frames holds the ball there
    setup, bg, frames, theta = _recording(0, 240, 400, mu=0.02)
    df, info, res = measure(_Plain([np.asarray(f) for f in frames]), setup, None)
    assert (df["still"] == "rest").sum() >= 390 and (df["found"] == 1).all()
    assert "neither held nor at rest" in info.background
    assert res.quality == "ok", [r.message for r in res.quality_reasons]
    assert abs(res.mu - 0.02) < max(3 * res.mu_stderr, 2e-4), (res.mu, res.mu_stderr)


def test_the_median_without_the_still_frames_tells_a_held_ball_from_the_backdrop():
    import pandas as pd

    from rollfric.io.background import median, sample
    from rollfric.track.still import median_without_still

    # at rest in 400 of 608 frames: the plain median holds the ball at its rest place
    setup, bg_true, frames, theta = _recording(0, 240, 400, mu=0.02)
    src = _Plain([np.asarray(f) for f in frames])
    n = len(frames)
    df = pd.DataFrame({"still": [""] * (n - 400) + ["rest"] * 400})
    _, stack = sample(src, 41)
    plain = median(stack)
    r = setup.ball_radius / PIX
    bg2, same, k2 = median_without_still(src, df, plain, r, 41)
    assert not same and k2 == 14  # the 14 sampled frames before the rest
    assert np.abs(bg2.astype(int) - bg_true.astype(int)).max() <= 5
    # against a background that is right there, it agrees
    _, same, _ = median_without_still(src, df, bg2, r, 41)
    assert same
