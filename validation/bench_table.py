"""A line of ``rollfric bench``'s table (:class:`Row`), shared by the sections' modules."""

from __future__ import annotations

import dataclasses
import math


@dataclasses.dataclass
class Row:
    """One line of the table: a measured value beside its baseline."""

    section: str
    item: str
    value: float
    unit: str
    baseline: str = ""
    baseline_value: float = math.nan
    gain: float = math.nan  # speed-up or error ratio over the baseline (> 1: better)
    gain_kind: str = ""  # "speed-up", "accuracy", "smaller"; "x the bound": value / bound
    note: str = ""
