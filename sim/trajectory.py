"""Trajectory: the ground truth of one simulated run, sampled at the camera rate (SI units).

World frame (team contract): origin on the cylinder axis in the plane of the ball centre,
x right, y up, z along the axis towards the camera. Ball centre (L sin theta, -L cos theta, 0).
Quaternions (w, x, y, z) and angular velocities are in the world frame.

CSV columns (one row per camera frame, floats printed with 17 significant digits so the file
round-trips exactly; NaN where an engine has no value)::

    t_s, theta_rad, theta_dot_rad_s, x_m, y_m, z_m, qw, qx, qy, qz,
    wx_rad_s, wy_rad_s, wz_rad_s, normal_force_n, slip_speed_m_s

Next to ``NAME.csv`` a sidecar ``NAME.json`` holds the scenario (TOML form and SI form),
the engine, its version and the settings used, and run diagnostics.
"""

from __future__ import annotations

import dataclasses
import io
import json
from pathlib import Path

import numpy as np

from rollfric.io.limits import MAX_SAMPLES
from rollfric.output.atomic import write_text
from rollfric.setup.tomlfile import decode_utf8, read_text
from sim.scenario import Scenario, ScenarioError, scenario_from_dict

COLUMNS = ("t_s", "theta_rad", "theta_dot_rad_s", "x_m", "y_m", "z_m", "qw", "qx", "qy", "qz",
           "wx_rad_s", "wy_rad_s", "wz_rad_s", "normal_force_n", "slip_speed_m_s")


@dataclasses.dataclass(frozen=True, eq=False)
class Trajectory:
    """Ground truth of one run: arrays of length N (camera frames)."""

    t: np.ndarray  # (N,) s
    theta: np.ndarray  # (N,) rad
    theta_dot: np.ndarray  # (N,) rad/s
    position: np.ndarray  # (N, 3) m, ball centre, world frame
    quaternion: np.ndarray  # (N, 4) wxyz, world frame
    angular_velocity: np.ndarray  # (N, 3) rad/s, world frame
    normal_force: np.ndarray  # (N,) N (NaN where not available)
    slip_speed: np.ndarray  # (N,) m/s, contact-point speed relative to the trough (NaN: n/a)
    scenario: Scenario
    meta: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.t)
        shapes = {"theta": (n,), "theta_dot": (n,), "position": (n, 3), "quaternion": (n, 4),
                  "angular_velocity": (n, 3), "normal_force": (n,), "slip_speed": (n,)}
        for name, shape in shapes.items():
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != shape:
                raise ValueError(f"Trajectory.{name} has shape {a.shape}, expected {shape}")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "t", np.asarray(self.t, dtype=float))

    def __len__(self) -> int:
        return len(self.t)

    @property
    def fps(self) -> float:
        return self.scenario.fps

    def setup(self):
        return self.scenario.setup()

    def table(self) -> np.ndarray:
        """(N, 15) array in COLUMNS order."""
        return np.column_stack([self.t, self.theta, self.theta_dot, self.position,
                                self.quaternion, self.angular_velocity, self.normal_force,
                                self.slip_speed]) + 0.0  # + 0.0 turns -0.0 into 0.0

    def to_dataframe(self):
        import pandas as pd

        return pd.DataFrame(self.table(), columns=list(COLUMNS))

    def sidecar(self) -> dict:
        return {
            "format": "rollfric-sim-trajectory/1",
            "columns": list(COLUMNS),
            "scenario": self.scenario.to_toml_dict(),
            "scenario_si": self.scenario.to_dict(),
            "meta": self.meta,
        }

    def to_csv(self, path: str | Path) -> Path:
        """Write NAME.csv and its sidecar NAME.json atomically; returns the CSV path."""
        path = Path(path)
        side = sidecar_path(path, check=True)
        buf = io.StringIO()
        np.savetxt(buf, self.table(), fmt="%.17g", delimiter=",", header=",".join(COLUMNS),
                   comments="")
        write_text(path, buf.getvalue())
        write_text(side,
                   json.dumps(self.sidecar(), indent=2, sort_keys=False, default=_jsonable)
                   + "\n")
        return path


def sidecar_path(csv_path: str | Path, check: bool = False) -> Path:
    """NAME.json beside NAME.csv. ``check``: ScenarioError when the CSV path itself ends in
    .json (it would be its own sidecar)."""
    side = Path(csv_path).with_suffix(".json")
    if check and side == Path(csv_path):
        raise ScenarioError(f"{csv_path}: a trajectory is a CSV file and its sidecar is "
                            f"NAME.json: give a name that does not end in .json (e.g. "
                            f"{Path(csv_path).with_suffix('.csv')})")
    return side


def _jsonable(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"not JSON serialisable: {type(obj)}")




# columns that hold a value in every row (the others: NaN where an engine has no value)
_FINITE_COLUMNS = COLUMNS[:13]


def read_trajectory(path: str | Path) -> Trajectory:
    """Read a trajectory CSV and its JSON sidecar (written by Trajectory.to_csv).

    ScenarioError names the file and the problem: missing, not UTF-8, truncated or
    non-numeric rows, NaN where a value is needed, times not increasing, a sidecar that is not
    the JSON object Trajectory.to_csv writes.
    """
    path = Path(path)
    side = sidecar_path(path)
    if not path.is_file():
        raise ScenarioError(f"trajectory file not found: {path}")
    if not side.is_file():
        raise ScenarioError(f"trajectory sidecar not found: {side} (written next to the CSV)")
    try:
        info = json.loads(read_text(side, "trajectory sidecar", ScenarioError))
    except json.JSONDecodeError as exc:
        raise ScenarioError(f"{side}: not valid JSON ({exc})") from None
    if not isinstance(info, dict) or not isinstance(info.get("scenario_si",
                                                             info.get("scenario")), dict):
        raise ScenarioError(f"{side}: not a trajectory sidecar (a JSON object with 'scenario' "
                            "or 'scenario_si', as rollfric simulate writes)")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    lines = decode_utf8(raw, path, ScenarioError).splitlines()
    header = lines[0].strip().split(",") if lines else []
    if tuple(header) != COLUMNS:
        raise ScenarioError(f"{path}: unexpected columns {header} (expected {list(COLUMNS)})")
    if len(lines) - 1 > MAX_SAMPLES:
        raise ScenarioError(f"{path}: {len(lines) - 1} rows, more than the limit of "
                            f"{MAX_SAMPLES:,}")
    try:
        data = np.loadtxt(lines[1:], delimiter=",", ndmin=2)
    except ValueError as exc:
        raise ScenarioError(f"{path}: not a complete table of numbers (truncated file?): "
                            f"{exc}") from None
    if data.shape[0] < 2 or data.shape[1] != len(COLUMNS):
        raise ScenarioError(f"{path}: {data.shape[0]} row(s) of {data.shape[1]} values; a "
                            f"trajectory needs >= 2 rows of {len(COLUMNS)}")
    bad = ~np.isfinite(data[:, :len(_FINITE_COLUMNS)])
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise ScenarioError(f"{path}: {int(bad.any(axis=1).sum())} row(s) with NaN or inf "
                            f"where a value is needed, the first row {int(row) + 1} "
                            f"({_FINITE_COLUMNS[col]})")
    if not np.all(np.diff(data[:, 0]) > 0):
        raise ScenarioError(f"{path}: the times t_s do not increase from row to row")
    try:
        if "scenario_si" in info:
            scenario = Scenario.from_dict(info["scenario_si"])
        else:
            scenario = scenario_from_dict(info["scenario"], source=str(side))
    except TypeError as exc:
        raise ScenarioError(f"{side}: bad scenario ({exc})") from None
    meta = info.get("meta", {})
    return Trajectory(t=data[:, 0], theta=data[:, 1], theta_dot=data[:, 2],
                      position=data[:, 3:6], quaternion=data[:, 6:10],
                      angular_velocity=data[:, 10:13], normal_force=data[:, 13],
                      slip_speed=data[:, 14], scenario=scenario,
                      meta=meta if isinstance(meta, dict) else {})
