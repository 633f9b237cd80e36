"""sim: ground-truth trajectories of a ball rolling in a cylindrical trough.

Engines: ``reference`` (the equation of motion, DOP853 to 1e-10: the truth), ``mujoco`` and
``pybullet`` (real physics engines with rolling friction, on an exact tangent contact surface
by default, or on the naive faceted surfaces a user would build first: ``mesh``,
``heightfield``).

    >>> import sim
    >>> traj = sim.simulate(sim.Scenario(engine="mujoco", mu=0.0079))
    >>> traj.to_csv("traj.csv")            # + traj.json sidecar
"""

from __future__ import annotations

from rollfric.io.limits import check_memory
from sim.scenario import (
    ENGINES,
    SURFACES,
    Scenario,
    ScenarioError,
    dumps_scenario,
    load_scenario,
    scenario_from_dict,
)
from sim.trajectory import COLUMNS, Trajectory, read_trajectory

__all__ = ["COLUMNS", "ENGINES", "SURFACES", "Scenario", "ScenarioError", "Trajectory",
           "dumps_scenario", "load_scenario", "read_trajectory", "scenario_from_dict",
           "simulate"]


def simulate(scenario: Scenario, progress: bool = False) -> Trajectory:
    """Run one scenario on its engine and return the ground truth at the camera rate."""
    if not isinstance(scenario, Scenario):
        raise ScenarioError(f"simulate() needs a sim.Scenario, got {type(scenario).__name__}")
    # the trajectory's 15 columns, the engine's own arrays and the CSV text: ~4 copies
    check_memory(4 * 15 * 8 * scenario.n_samples,
                 f"a trajectory of {scenario.n_samples:,} samples")
    return ENGINES.load(scenario.engine).run(scenario, progress=progress)
