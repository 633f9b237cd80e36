"""Mains flicker of the lamps: at 1000 frames/s an AC lamp's brightness swings at 100 Hz, so
every frame differs from the background by a few per cent of the scene's brightness."""

import numpy as np
import pytest
from measure_data import make_recording
from test_measure_roi import _Plain

from rollfric.measurement import measure


@pytest.mark.parametrize("given_background", [True, False])
def test_ten_percent_lamp_flicker_keeps_every_frame(given_background):
    rec = make_recording(300, mu=0.02, theta0=0.4, noise=1.0, fps=1000.0)
    frames = []
    for i, f in enumerate(rec.frames):
        gain = 1.0 + 0.10 * np.sin(2 * np.pi * 100.0 * i / 1000.0)
        frames.append(np.clip(np.rint(np.asarray(f, float) * gain), 0, 255).astype(np.uint8))
    df, _, _ = measure(_Plain(frames), rec.setup, rec.background if given_background else None,
                       fit=False)
    found = df["found"].to_numpy() == 1
    err = np.hypot(df["x_px"] - rec.centers[:, 0], df["y_px"] - rec.centers[:, 1])[found]
    assert found.all()
    # 0.010 px rms without flicker on these frames
    assert np.sqrt(np.mean(err ** 2)) < 0.025 and err.max() < 0.06
