"""The simulation engines: reference (exact ODE), mujoco, pybullet.

An engine is a module with ``DEFAULTS`` (its options and their default values, which a
scenario's ``[engine.options]`` may override) and ``run(scenario, progress=False)``, which
returns the :class:`sim.trajectory.Trajectory` (:class:`Engine`). Engines are registered by
name in :data:`ENGINES` (the CLI's ``--engine`` choices); an engine module imports its
physics library inside ``run``, so that listing or checking a scenario stays light. To add
one: write the module and add a line to :data:`ENGINES` (and its surfaces to
:data:`sim.scenario.SURFACES`).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from rollfric.registry import Registry


@runtime_checkable
class Engine(Protocol):
    """A simulation engine (a module): its option defaults and how it runs a scenario."""

    DEFAULTS: dict

    def run(self, scenario, progress: bool = False):
        """Simulate ``scenario`` (a :class:`sim.Scenario`); the ground truth at the camera
        rate as a :class:`sim.Trajectory`."""
        ...


#: The engines by name, the default first.
ENGINES = Registry("engine", {
    "reference": "sim.engines.reference",
    "mujoco": "sim.engines.mujoco_engine",
    "pybullet": "sim.engines.pybullet_engine",
})
