"""synth's shadowgraph rig (the backlit lighting preset) and its 10/12/14-bit sensors in 16-bit
words: the rendered ball is a dark disc on a bright field, every frame stays within the sensor's
2**bits - 1, the export's TIFF states it (MaxSampleValue) and the setup carries camera.bit_depth."""

import math
import os

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

R_PX = 5e-3 / 0.1343e-3


def _render(tmp_path, name, lighting, noise, n_s=0.002):
    import sim
    import synth

    traj = sim.simulate(sim.Scenario(theta0=math.radians(6.0), duration=n_s))
    # a strip of the thesis camera around the trough's bottom (the ball near its middle)
    cam = synth.CameraModel(width=192, height=128, center_px=(96.0, -530.0))
    path = synth.render(traj, tmp_path / f"{name}.zarr",
                        scene=synth.SceneConfig(camera=cam,
                                                lighting=synth.lighting_preset(lighting)),
                        sensor=synth.noise_preset(noise), seed=0, workers=1)
    return synth.open_recording(path)


def test_backlit_preset_renders_a_dark_ball_on_a_bright_field(tmp_path):
    rec = _render(tmp_path, "backlit", "backlit", "none")
    full = 255
    bg = rec.background.astype(float)
    for i in range(len(rec)):
        f = rec.frames[i].astype(float)
        x, y = rec.truth[["sil_x_px", "sil_y_px"]].to_numpy()[i]
        yy, xx = np.mgrid[0:f.shape[0], 0:f.shape[1]]
        d = np.hypot(xx - x, yy - y)
        ring = (d > 0.3 * R_PX) & (d < 0.85 * R_PX)  # the disc without its central spot
        field = (d > 1.2 * R_PX) & (d < 1.6 * R_PX) & (yy < y)  # the backlight above it
        assert np.median(f[field]) > 0.6 * full  # a bright field
        assert np.median(f[ring]) < 0.05 * np.median(f[field])  # a dark disc
        assert f[d < 0.3 * R_PX].max() > 0.3 * full  # the lamp's spot near its centre
        assert np.median(bg[ring]) > 0.6 * full  # the ball-free frame is the backlight there
    # the lit preset's ball is not that: bright rim reflections, no dark disc on a bright field
    lit = _render(tmp_path, "thesis", "thesis", "none")
    assert np.median(lit.background[:40].astype(float)) < np.median(bg[:40])


def test_backlit_preset_is_pyrenders_only():
    import synth

    with pytest.raises(synth.SynthError, match="pyrender only"):
        synth.SceneConfig(lighting=synth.lighting_preset("backlit"), renderer="mitsuba")


def _bits_recording(tmp_path, bits):
    import sim
    import synth

    # twice the gain: the backlight clips, at the sensor's full scale and not the word's
    sensor = synth.noise_preset(f"{bits}bit").replace(gain=2.0)
    assert sensor.max_dn == 2 ** bits - 1
    traj = sim.simulate(sim.Scenario(theta0=math.radians(6.0), duration=0.002))
    cam = synth.CameraModel(width=192, height=128, center_px=(96.0, -530.0))
    return synth.open_recording(synth.render(
        traj, tmp_path / "r.zarr", sensor=sensor, seed=0, workers=1,
        scene=synth.SceneConfig(camera=cam, lighting=synth.lighting_preset("backlit"))))


@pytest.mark.parametrize("bits", [10, 12, 14])
def test_sensor_bits_in_16_bit_words_and_the_tiff_tag(tmp_path, bits):
    import tifffile

    from synth.export import export_recording

    rec = _bits_recording(tmp_path, bits)
    frames = [np.asarray(rec.frames[i]) for i in range(len(rec))]
    assert all(f.dtype == np.uint16 for f in frames) and rec.background.dtype == np.uint16
    assert max(int(f.max()) for f in frames) == 2 ** bits - 1  # clipped there, never above
    assert int(rec.background.max()) == 2 ** bits - 1
    out = export_recording(rec, tmp_path / "export")
    with tifffile.TiffFile(out / "frames.tif") as tif:
        assert len(tif.pages) == len(frames)
        assert all(p.tags["MaxSampleValue"].value == 2 ** bits - 1 for p in tif.pages)
        assert np.array_equal(tif.pages[0].asarray(), frames[0])


@pytest.mark.parametrize("bits", [10, 14])
def test_sensor_bits_in_the_recordings_setup(tmp_path, bits):
    from rollfric.setup.model import Setup, load_setup
    from synth.export import export_recording

    if "bit_depth" not in Setup.__dataclass_fields__:
        pytest.skip("rollfric's setup has no camera.bit_depth yet (the bit-depth work)")
    rec = _bits_recording(tmp_path, bits)
    assert rec.attrs["setup"]["camera"]["bit_depth"] == bits
    out = export_recording(rec, tmp_path / "export")
    assert load_setup(out / "setup.toml").bit_depth == bits
