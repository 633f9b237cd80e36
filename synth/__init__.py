"""synth: synthetic 1000 Hz camera recordings of a ball in a trough, rendered with pyrender,
with exact ground truth.

    >>> import sim, synth
    >>> traj = sim.simulate(sim.Scenario())
    >>> synth.render(traj, "rec.zarr", scene=synth.SceneConfig(), sensor=synth.noise_preset(
    ...     "realistic"), seed=0, progress=True)
    >>> rec = synth.open_recording("rec.zarr")   # rec.frames[i], rec.background, rec.truth
"""

from __future__ import annotations

from synth.camera import CameraModel
from synth.config import (
    LIGHTING_PRESETS,
    NOISE_PRESETS,
    Lamp,
    Lighting,
    SceneConfig,
    SensorConfig,
    SynthError,
    lighting_preset,
    noise_preset,
)
from synth.motion import load_trajectory
from synth.pipeline import render
from synth.store import Recording, SynthFrames, open_frames, open_recording

__all__ = ["LIGHTING_PRESETS", "NOISE_PRESETS", "CameraModel", "Lamp", "Lighting", "Recording",
           "SceneConfig", "SensorConfig", "SynthError", "SynthFrames", "lighting_preset",
           "load_trajectory", "noise_preset", "open_frames", "open_recording", "render"]
