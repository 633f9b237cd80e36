"""JSON files the commands write: values made fit for JSON, a fit's fit.json."""

from __future__ import annotations

import json
import math

import numpy as np

from rollfric.output.atomic import write_text


def json_safe(value):
    """A value made fit for JSON.

    Parameters
    ----------
    value
        A dict, list, tuple or scalar (nested).

    Returns
    -------
    object
        The same with NumPy scalars made plain and non-finite floats made None (JSON null).
    """
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def save_fit(result, path, **extra) -> None:
    """Write ``result.to_dict()`` plus ``extra`` keys as JSON (NaN becomes null), atomically.

    Parameters
    ----------
    result : rollfric.fit.result.FitResult
    path : str or pathlib.Path
    **extra
        More keys for the file.
    """
    write_text(path, json.dumps(json_safe({**result.to_dict(), **extra}), indent=2) + "\n")
