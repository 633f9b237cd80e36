"""The simulation engines: reference (exact ODE), mujoco, pybullet."""
