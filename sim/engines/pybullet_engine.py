"""PyBullet 3.2 engine: a sphere with rolling friction in the trough (SI units, DIRECT client).

Surfaces:

- ``tangent`` (default, accurate): a static plane re-posed before every stepSimulation so that it
  is tangent to the cylinder directly under the ball: one contact with the exact geometry. An
  out-of-round bore (:mod:`sim.section`) puts it tangent to the ellipse at the point nearest
  the ball; a trough tilted along its length (``tilt``) tilts gravity in the trough's frame,
  g (0, -cos tilt, sin tilt) (the plane is unbounded along the axis).
- ``mesh``: the trough as a concave triangle mesh (GEOM_FORCE_CONCAVE_TRIMESH), one facet every
  ``mesh_facet_deg`` degrees.
- ``heightfield``: a GEOM_HEIGHTFIELD sampled every ``heightfield_cell_mm`` along x.

Friction: Bullet combines rolling friction as rollA * lateralB + rollB * lateralA and limits the
rolling torque to that value times the normal force (a length), so the ball gets
rollingFriction = mu r / lateral_friction and the trough lateralFriction = lateral_friction,
rollingFriction = 0 (combined: mu r). The ball's maximum joint velocity is raised (the default
100 rad/s makes the 1.58 mm ball slip), damping and sleeping are off, contactSlop is 0.

Losses the fitter does not assume (:mod:`sim.losses`): before every step the air drag
-m k |v| v is applied to the ball's centre (``applyExternalForce``, world frame; Bullet clears
it after the step) and the ball's rolling friction is set to (mu + mu_speed v) r / lateral
for its current speed v.
"""

from __future__ import annotations

import math
import time
from importlib.metadata import PackageNotFoundError, version

import numpy as np
from tqdm import tqdm

from sim.engines.common import initial_state, losses_meta, slip_speed, theta_from_centre
from sim.losses import applied_force, losses_of, mu_at
from sim.trajectory import Trajectory

DEFAULTS: dict = {
    "timestep_s": 2.5e-4,
    "solver_iterations": 50,
    "lateral_friction": 1.0,
    "max_angular_velocity_rad_s": 1e5,
    "mesh_facet_deg": 1.0,
    "heightfield_cell_mm": 0.5,
    "surface_extent_deg": 85.0,
}


def _steps_per_frame(timestep: float, fps: float) -> tuple[int, float]:
    n = max(1, round(1.0 / (fps * timestep)))
    return n, 1.0 / (fps * n)


def _quat_mul(a, b):
    """Hamilton product of (x, y, z, w) quaternions."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


_Z_TO_Y = (-math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))  # rot x by -90 deg (xyzw)


def _build_trough(p, client, scenario, opts):
    """Create the trough body; returns its id."""
    R = scenario.cylinder_radius
    half_w = max(2.0 * scenario.ball_diameter, 5e-3)
    ext = math.radians(opts["surface_extent_deg"])
    if scenario.surface == "tangent":
        shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=client)
        return p.createMultiBody(0.0, shape, basePosition=[0, -R, 0],
                                 baseOrientation=_Z_TO_Y, physicsClientId=client)
    if scenario.surface == "mesh":
        n = max(2, math.ceil(2 * ext / math.radians(opts["mesh_facet_deg"])))
        a = np.linspace(-ext, ext, n + 1)
        verts = []
        for zz in (-half_w, half_w):
            verts += [[R * math.sin(ai), -R * math.cos(ai), zz] for ai in a]
        idx = []
        m = n + 1
        for i in range(n):
            # two triangles per facet, wound so the normal points towards the axis
            idx += [i, m + i, i + 1, i + 1, m + i, m + i + 1]
        shape = p.createCollisionShape(p.GEOM_MESH, vertices=verts, indices=idx,
                                       flags=p.GEOM_FORCE_CONCAVE_TRIMESH,
                                       physicsClientId=client)
        return p.createMultiBody(0.0, shape, physicsClientId=client)
    # heightfield: local z up -> world y; Bullet centres the height range on the origin
    X = R * math.sin(ext)
    dx = opts["heightfield_cell_mm"] * 1e-3
    nx = 2 * int(math.ceil(X / dx)) + 1
    x = (np.arange(nx) - (nx - 1) / 2) * dx
    x = np.clip(x, -R * 0.999, R * 0.999)
    h = R - np.sqrt(R * R - x * x)
    ny = 3
    dy = half_w
    data = np.tile(h, ny)  # index ix + iy * nx
    shape = p.createCollisionShape(p.GEOM_HEIGHTFIELD, meshScale=[dx, dy, 1.0],
                                   heightfieldData=data.tolist(), numHeightfieldRows=nx,
                                   numHeightfieldColumns=ny, physicsClientId=client)
    top = float(h.max())
    return p.createMultiBody(0.0, shape, basePosition=[0, -R + 0.5 * top, 0],
                             baseOrientation=_Z_TO_Y, physicsClientId=client)


def _version() -> str:
    try:
        return version("pybullet")
    except PackageNotFoundError:
        return "unknown"


def _set_world(p, client: int, scenario, opts: dict, dt: float) -> None:
    """Gravity (the trough tilted: along its axis too) and the solver's settings."""
    if scenario.tilt:
        p.setGravity(0, -scenario.gravity * math.cos(scenario.tilt),
                     scenario.gravity * math.sin(scenario.tilt), physicsClientId=client)
    else:
        p.setGravity(0, -scenario.gravity, 0, physicsClientId=client)
    p.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0,
                                numSolverIterations=int(opts["solver_iterations"]),
                                contactSlop=0.0, deterministicOverlappingPairs=1,
                                physicsClientId=client)


def _release_ball(p, client: int, scenario, opts: dict) -> tuple[int, list]:
    """The ball at its release angle, rolling without slipping at its release speed; its body
    id and start position."""
    R, r = scenario.cylinder_radius, scenario.ball_radius
    L = R - r
    th0, w0 = scenario.theta0, scenario.theta_dot0
    if scenario.section.round:
        start_pos = [L * math.sin(th0), -L * math.cos(th0), 0]
        start_v = [L * w0 * math.cos(th0), L * w0 * math.sin(th0), 0.0]
        start_w = [0.0, 0.0, -(L / r) * w0]
    else:
        (x0, y0), (vx0, vy0), spin0 = initial_state(scenario)
        start_pos, start_v, start_w = [x0, y0, 0.0], [vx0, vy0, 0.0], [0.0, 0.0, spin0]
    sphere = p.createCollisionShape(p.GEOM_SPHERE, radius=r, physicsClientId=client)
    ball = p.createMultiBody(scenario.ball_mass, sphere, basePosition=start_pos,
                             physicsClientId=client)
    p.changeDynamics(ball, -1, lateralFriction=1.0,
                     rollingFriction=scenario.mu * r / opts["lateral_friction"],
                     spinningFriction=0.0, restitution=0.0, linearDamping=0.0,
                     angularDamping=0.0,
                     maxJointVelocity=float(opts["max_angular_velocity_rad_s"]),
                     activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING,
                     physicsClientId=client)
    p.resetBaseVelocity(ball, start_v, start_w, physicsClientId=client)
    return ball, start_pos


def _plane_placer(p, client: int, scenario, ball: int, trough: int, start_pos: list):
    """The function that moves the tangent plane under the ball: tangent to the bore at the
    point nearest the ball's centre."""
    section = scenario.section
    R = scenario.cylinder_radius
    get_pose, reset_pose = p.getBasePositionAndOrientation, p.resetBasePositionAndOrientation
    last_phi = [math.atan2(start_pos[0], -start_pos[1])]

    def place_plane():
        (x, y, _), _q = get_pose(ball, physicsClientId=client)
        if section.round:
            phi = math.atan2(x, -y)
            at = [R * math.sin(phi), -R * math.cos(phi), 0.0]
        else:  # tangent to the ellipse at the point nearest the ball
            phi = last_phi[0] = section.phi_of_point(x, y, last_phi[0])
            at = [*(float(v) for v in section.contact(phi)), 0.0]
        qz = (0.0, 0.0, math.sin(0.5 * phi), math.cos(0.5 * phi))
        reset_pose(trough, at, _quat_mul(qz, _Z_TO_Y), physicsClientId=client)

    return place_plane


def _loss_applier(p, client: int, scenario, ball: int, losses, lat: float):
    """The function that sets the losses (sim.losses) for the ball's current speed: the drag
    as an external force, mu(v) r as its rolling friction."""
    r = scenario.ball_radius
    get_pose = p.getBasePositionAndOrientation

    def apply_losses():
        (bx, by, bz), _q = get_pose(ball, physicsClientId=client)
        v, _w = p.getBaseVelocity(ball, physicsClientId=client)
        f = applied_force(v, losses, r, scenario.ball_mass)
        p.applyExternalForce(ball, -1, f.tolist(), [bx, by, bz], p.WORLD_FRAME,
                             physicsClientId=client)
        if losses.mu_speed:
            mu_v = mu_at(float(np.linalg.norm(v)), scenario.mu, losses)
            p.changeDynamics(ball, -1, rollingFriction=mu_v * r / lat,
                             physicsClientId=client)

    return apply_losses


class _Record:
    """The ball's state at each camera frame: pose, velocities, the contacts' count and their
    normal force summed (N; NaN without contact)."""

    def __init__(self, p, client: int, ball: int, n: int):
        self.p, self.client, self.ball = p, client, ball
        self.pos = np.empty((n, 3))
        self.quat = np.empty((n, 4))
        self.vel = np.empty((n, 3))
        self.omega = np.empty((n, 3))
        self.normal = np.full(n, np.nan)
        self.ncon = np.zeros(n, dtype=int)

    def __call__(self, i: int) -> None:
        p, client, ball = self.p, self.client, self.ball
        pp, qq = p.getBasePositionAndOrientation(ball, physicsClientId=client)
        v, w = p.getBaseVelocity(ball, physicsClientId=client)
        self.pos[i] = pp
        self.quat[i] = (qq[3], qq[0], qq[1], qq[2])
        self.vel[i] = v
        self.omega[i] = w
        contacts = p.getContactPoints(bodyA=ball, physicsClientId=client)
        self.ncon[i] = len(contacts)
        if contacts:
            self.normal[i] = sum(c[9] for c in contacts)


def run(scenario, progress: bool = False):
    """Simulate ``scenario`` with PyBullet (DIRECT client, ``rollingFriction``).

    Parameters
    ----------
    scenario : sim.Scenario
        The scenario (engine ``pybullet``; options in ``DEFAULTS``).
    progress : bool, optional
        Show a progress bar.

    Returns
    -------
    sim.Trajectory
        The ground truth at the camera rate as PyBullet computed it (normal force summed over
        contacts, NaN where there is none, slip speed at the contact), with the engine's version
        and settings in ``meta``.
    """
    import pybullet as p

    opts = scenario.options()
    start = time.perf_counter()
    client = p.connect(p.DIRECT)
    try:
        n_sub, dt = _steps_per_frame(opts["timestep_s"], scenario.fps)
        _set_world(p, client, scenario, opts, dt)
        lat = opts["lateral_friction"]
        trough = _build_trough(p, client, scenario, opts)
        p.changeDynamics(trough, -1, lateralFriction=lat, rollingFriction=0.0,
                         spinningFriction=0.0, restitution=0.0, physicsClientId=client)
        ball, start_pos = _release_ball(p, client, scenario, opts)
        record = _Record(p, client, ball, scenario.n_samples)
        tangent = scenario.surface == "tangent"
        place_plane = _plane_placer(p, client, scenario, ball, trough, start_pos)
        losses = losses_of(scenario)
        apply_losses = _loss_applier(p, client, scenario, ball, losses, lat)
        step = p.stepSimulation
        if tangent:
            place_plane()
        record(0)
        for i in tqdm(range(1, scenario.n_samples), disable=not progress, desc="pybullet",
                      unit="frame", mininterval=0.5):
            for _ in range(n_sub):
                if tangent:
                    place_plane()
                if losses.active:
                    apply_losses()
                step(physicsClientId=client)
            record(i)
    finally:
        p.disconnect(physicsClientId=client)
    wall = time.perf_counter() - start
    version = f"pybullet {_version()} (API {p.getAPIVersion()})"
    return _trajectory(scenario, opts, record, version, dt, n_sub, wall)


def _trajectory(scenario, opts: dict, record: _Record, version: str, dt: float, n_sub: int,
                wall: float):
    """The recorded states as the trajectory, with the engine's settings in meta."""
    # before the first step there are no contact points yet: the sample at t = 0 has none
    pos, vel, omega = record.pos, record.vel, record.omega
    r, lat = scenario.ball_radius, opts["lateral_friction"]
    theta, theta_dot = theta_from_centre(pos, vel)
    meta = {
        "engine": "pybullet",
        "engine_version": version,
        "surface": scenario.surface,
        "settings": {**opts, "timestep_s": dt, "steps_per_frame": n_sub, "units": "m, kg, s",
                     "ball_rolling_friction_m": scenario.mu * r / lat,
                     "combined_rolling_friction_m": scenario.mu * r},
        "max_contacts": int(record.ncon.max()),
        "wall_time_s": wall,
        **losses_meta(scenario, theta_dot),
    }
    return Trajectory(t=scenario.times(), theta=theta, theta_dot=theta_dot, position=pos,
                      quaternion=record.quat, angular_velocity=omega,
                      normal_force=record.normal,
                      slip_speed=slip_speed(pos, vel, omega, r, scenario.section),
                      scenario=scenario, meta=meta)
