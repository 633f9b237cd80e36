"""The full-frame search (coarse_find) and the sub-pixel fit after it on hard frames: heavy
noise, low contrast, bright and dark balls, a ball partly outside the frame, and rendered frames
with the noisy sensor and the dim / flat / harsh lighting presets."""

import math

import numpy as np
import pytest

from rollfric.locate import coarse_find, locate_subpixel
from synth.drawn.frames import Scene, make_frames

R10 = 5.0 / 0.1343  # the thesis's 10 mm ball in px


def _scene(r_px=R10, *, backdrop=0.78, step=100.0, noise=0.0, spot=0.0, **kw):
    """A 320 x 240 backdrop with the trough far away: the ball alone, its edge step ``step`` DN
    (8 bit; negative: a ball brighter than the backdrop)."""
    return Scene(width=320, height=240, center=(160.0, -5000.0), R_px=640.0, r_px=r_px,
                 backdrop=backdrop, ball=backdrop - step / 255.0, spot=spot, noise=noise, **kw)


def _check(scene, centers, seed=0):
    """coarse_find within a pixel and the full search's sub-pixel fit within its stated
    uncertainty, for each ball centre; returns the (coarse, fit) errors and the sigmas."""
    coarse, fit, sig = [], [], []
    for i, (cx, cy) in enumerate(centers):
        bg, (frame,) = make_frames(scene, [(cx, cy)], seed=seed * 100 + i)
        g = coarse_find(frame, bg, scene.r_px)
        assert g is not None, f"ball at ({cx:.1f}, {cy:.1f}) not found by coarse_find"
        coarse.append(math.hypot(g[0] - cx, g[1] - cy))
        loc = locate_subpixel(frame, bg, scene.r_px)
        assert loc.found, f"ball at ({cx:.1f}, {cy:.1f}): {loc.reason}"
        fit.append(math.hypot(loc.x - cx, loc.y - cy))
        sig.append(loc.sigma)
    coarse, fit, sig = map(np.array, (coarse, fit, sig))
    assert coarse.max() < 1.0
    # sigma is the centre's standard error (both axes): the rms error must match it and no
    # frame may be off by many sigma
    assert np.sqrt(np.mean(fit ** 2)) < 2.0 * np.sqrt(np.mean(sig ** 2)) + 0.005
    assert (fit < 4.0 * sig + 0.01).all()
    return coarse, fit, sig


def _centers(n, seed, margin=60.0):
    rng = np.random.default_rng(seed)
    xs, ys = rng.uniform(margin, 320 - margin, n), rng.uniform(margin, 240 - margin, n)
    return list(zip(xs, ys, strict=True))


@pytest.mark.parametrize("noise", [15.0, 25.0])
def test_heavy_noise(noise):
    # 100 DN edge step under 15-25 DN rms noise (the old search found nothing above ~10 DN)
    _check(_scene(noise=noise), _centers(5, seed=int(noise)))


def test_heavy_noise_with_specular_spots():
    _check(_scene(noise=20.0, spot=0.85), _centers(4, seed=3))


def test_low_contrast():
    # a 10 DN edge step under 3 DN noise, on a mid-grey backdrop
    _check(_scene(backdrop=0.5, step=10.0, noise=3.0), _centers(5, seed=1))


@pytest.mark.parametrize("backdrop,step", [(0.1, -100.0), (0.8, 150.0)])
def test_bright_ball_on_dark_and_dark_ball_on_bright(backdrop, step):
    _check(_scene(backdrop=backdrop, step=step, noise=15.0), _centers(4, seed=2))


def test_small_ball_noisy():
    _check(_scene(r_px=0.79 / 0.1343, noise=10.0), _centers(4, seed=5, margin=20.0))


def test_ball_partly_outside_the_frame():
    s = _scene(noise=10.0)
    # a third of the rim (the left and the bottom) outside: both searches
    _check(s, [(0.5 * R10, 110.3), (200.4, 239.0 - 0.5 * R10)], seed=7)
    # centre outside the frame (0.3 r beyond the left edge): the search still finds it
    bg, (frame,) = make_frames(s, [(-0.3 * R10, 120.6)], seed=9)
    g = coarse_find(frame, bg, R10)
    assert g is not None and math.hypot(g[0] + 0.3 * R10, g[1] - 120.6) < 1.5


def test_noise_alone_is_not_a_ball():
    for noise, backdrop in [(25.0, 0.5), (3.0, 0.5), (15.0, 0.1)]:
        bg, (frame,) = make_frames(_scene(noise=noise, backdrop=backdrop), [(None, None)],
                                   seed=11)
        assert coarse_find(frame, bg, R10) is None
        assert not locate_subpixel(frame, bg, R10).found


def test_picks_the_ball_not_a_larger_smudge():
    # a broad soft change (a lamp flicker patch) elsewhere is stronger in |difference| summed
    # over a box but is not a disk of the ball's size: the disk-like candidate wins
    s = _scene(noise=10.0)
    bg, (frame,) = make_frames(s, [(240.2, 150.7)], seed=13)
    yy, xx = np.mgrid[0:240, 0:320]
    patch = 60.0 * np.exp(-((xx - 80) ** 2 + (yy - 90) ** 2) / (2 * 45.0 ** 2))
    frame = np.clip(frame + patch, 0, 255).astype(np.uint8)
    g = coarse_find(frame, bg, R10)
    assert g is not None and math.hypot(g[0] - 240.2, g[1] - 150.7) < 1.0


# --------------------------------------------------------------------------------------------
# rendered frames (synth): the noisy sensor and the hard lighting presets


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    import sim
    import synth

    # a 200 x 176 crop of the thesis camera around the trough bottom; 20 frames of a swing
    cam = synth.CameraModel(width=200, height=176, center_px=(100.0, -500.0))
    traj = sim.simulate(sim.Scenario(theta0=0.04, duration=0.019))
    tmp = tmp_path_factory.mktemp("robust")
    out = {}
    for lighting in ("dim", "flat", "harsh"):
        scene = synth.SceneConfig(camera=cam, lighting=synth.lighting_preset(lighting))
        path = synth.render(traj, tmp / f"{lighting}.zarr", scene=scene,
                            sensor=synth.noise_preset("noisy"), seed=3, workers=1)
        out[lighting] = synth.open_recording(path)
    return out


@pytest.mark.parametrize("lighting", ["dim", "flat", "harsh"])
def test_rendered_noisy_sensor_all_frames_found(rendered, lighting):
    rec = rendered[lighting]
    truth = rec.truth[["sil_x_px", "sil_y_px"]].to_numpy()
    r_px = float(rec.truth["r_px"].median())
    assert len(rec) == 20
    for i in range(len(rec)):
        frame = rec.frames[i]
        g = coarse_find(frame, rec.background, r_px)
        assert g is not None, f"{lighting} frame {i}: not found"
        assert math.hypot(g[0] - truth[i, 0], g[1] - truth[i, 1]) < 2.0
        loc = locate_subpixel(frame, rec.background, r_px)
        assert loc.found, f"{lighting} frame {i}: {loc.reason}"
        assert math.hypot(loc.x - truth[i, 0], loc.y - truth[i, 1]) < 0.5

