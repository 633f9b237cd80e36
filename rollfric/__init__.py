"""rollfric: rolling friction measured from a high-speed recording of a ball in a trough.

A recording of a steel ball rolling back and forth in a horizontal cylindrical trough is read
frame by frame, the ball's centre is located to a fraction of a pixel, its angle about the
trough's axis is fitted with the equation of motion, and the rolling friction coefficient
mu (torque M = mu r N) is reported with its uncertainty budget.

>>> import rollfric
>>> sorted(rollfric.__all__)[:3]
['Budget', 'Calibration', 'FitResult']

The public API is the names in ``__all__``; they are imported on first use, so that
``import rollfric`` (and the command line's ``--help``) stays light.
"""

from __future__ import annotations

from importlib import import_module
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("rollfric")
except PackageNotFoundError:  # run from a source tree that was never installed
    __version__ = "0+unknown"

# public name -> the module that defines it
_WHERE = {
    # a measurement, from a recording to mu
    "measure": "rollfric.measurement",
    "track_recording": "rollfric.track.tracker",
    "TrackInfo": "rollfric.track.track_info",
    "angles": "rollfric.geometry.theta",
    # recordings and images
    "open_recording": "rollfric.io.readers",
    "read_image": "rollfric.io.readers",
    "RecordingError": "rollfric.io.source",
    # the lab's setup and the camera's calibration
    "Setup": "rollfric.setup.model",
    "load_setup": "rollfric.setup.model",
    "setup_from_dict": "rollfric.setup.model",
    "thesis_setup": "rollfric.setup.model",
    "Calibration": "rollfric.setup.lens",
    # fitting mu and its uncertainty
    "fit_mu": "rollfric.fit.estimate",
    "FitResult": "rollfric.fit.result",
    "Measurement": "rollfric.uncertainty.measured",
    "measurement_from_track": "rollfric.uncertainty.measured",
    "budget": "rollfric.uncertainty.budget",
    "Budget": "rollfric.uncertainty.budget",
    # bad input (the command line's exit status 2)
    "InputError": "rollfric.errors",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(import_module(_WHERE[name]), name)
        globals()[name] = value  # imported once
        return value
    raise AttributeError(f"module 'rollfric' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
