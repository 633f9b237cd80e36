"""MuJoCo 4 engine: a free ball with rolling friction (condim 6) in the trough.

Model units are millimetres, kilograms and seconds (gravity 9810 mm/s^2), converted to SI at the
edge: MuJoCo raises every friction coefficient below 1e-5 to 1e-5 and its rolling coefficient is
a length (mu * r), which for the 1.58 mm ball in metres (mu r ~ 1e-5 m) would be floored.
Gravity points along -y so the model frame is the contract's world frame (in mm).

Surfaces:

- ``tangent`` (default, accurate): one thin box on a mocap body, re-posed before every step so
  that its top face is tangent to the cylinder directly under the ball: one contact with the
  exact cylinder geometry. An out-of-round bore (:mod:`sim.section`) puts the box tangent to
  the ellipse at the point nearest the ball; a trough tilted along its length
  (``tilt``) tilts gravity in the trough's frame, g (0, -cos tilt, sin tilt), and the box
  follows the ball along the axis.
- ``mesh``: the trough as the triangle mesh a user would export, one facet every
  ``mesh_facet_deg`` degrees. MuJoCo collides with the convex hull of a mesh, so each facet is
  its own convex slab (a box whose top face is the facet's two triangles).
- ``heightfield``: an hfield sampled every ``heightfield_cell_mm`` along x.

The contact is an explicit pair with condim 6 and friction (f, f, mu r, mu r, mu r): sliding
f = ``sliding_friction`` (10), torsional and rolling mu r; elliptic cone, noslip iterations, stiff
solref and a solimp width in mm.

Why sliding 10, ``impratio`` 1000 and ``solreffriction`` 5 ms (measured, MuJoCo 4.0): the ball
always rolls, so the rolling rows sit on the elliptic cone sum (f_i / mu_i)^2 <= N^2, which
holds the sliding force F too. MuJoCo splits a force on the cone in proportion to
mu_i^2 x (row residual), so with sliding 1 the contact slides at about (F / N) mu v (measured
0.1 mm/s at 0.44 m/s) and F takes a share (F / N)^2 of the cone from the rolling torque; with
impratio 1 the friction rows are also as soft as the normal row and the ball slips after each
turning point. Together: mu +1.7 % to +2.2 % at mu 0.0065. Sliding 10 shrinks the coupling 100x;
impratio 1000 makes the friction rows 1000x stiffer and keeps the regularised cone coefficient
f / sqrt(impratio) = 0.32 small (it also softens the normal row by 1 + 0.32^2; at 1 the bias
stays). The friction damping 2 / (0.95 solreffriction) times mu r times the rolling rate enters
the cone as a push away from the surface (the convex model's "hover"); at 2 ms it beats the
normal support at mu 0.0164 and 35 deg and the contact flickers (hundreds of frames without
contact); 5 ms keeps it below.

Losses the fitter does not assume (:mod:`sim.losses`): before every step the air drag
-m k |v| v is set as the ball's applied force (``xfrc_applied``) and the contact pairs' rolling
and torsional coefficients are set to (mu + mu_speed v) r for the ball's current speed v.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from sim.engines.common import initial_state, losses_meta, slip_speed, theta_from_centre
from sim.errors import ScenarioError
from sim.losses import applied_force, losses_of, mu_at
from sim.trajectory import Trajectory

DEFAULTS: dict = {
    "timestep_s": 1e-4,
    "noslip_iterations": 20,
    "solref_timeconst_s": 1e-3,
    "solreffriction_timeconst_s": 5e-3,
    "solimp_width_mm": 1.0,
    "cone": "elliptic",
    "impratio": 1000.0,
    "sliding_friction": 10.0,
    "integrator": "Euler",
    "mesh_facet_deg": 1.0,
    "heightfield_cell_mm": 0.5,
    "surface_extent_deg": 85.0,
}

_PAD_HALF_THICKNESS = 1.0  # mm


def _steps_per_frame(timestep: float, fps: float) -> tuple[int, float]:
    n = max(1, round(1.0 / (fps * timestep)))
    return n, 1.0 / (fps * n)


def _mesh_xml(R: float, half_w: float, opts: dict) -> tuple[str, list[str]]:
    """The trough as flat box facets of ``mesh_facet_deg`` over +-``surface_extent_deg``."""
    ext = math.radians(opts["surface_extent_deg"])
    n = max(2, math.ceil(2 * ext / math.radians(opts["mesh_facet_deg"])))
    edges = np.linspace(-ext, ext, n + 1)
    parts, names = [], []
    for i in range(n):
        a0, a1 = float(edges[i]), float(edges[i + 1])
        mid, half = 0.5 * (a0 + a1), 0.5 * (a1 - a0)
        half_chord = R * math.sin(half)
        dist = R * math.cos(half) + _PAD_HALF_THICKNESS  # box centre from the axis
        parts.append(
            f'<geom name="f{i}" type="box" size="{half_chord!r} {_PAD_HALF_THICKNESS} '
            f'{half_w}" pos="{dist * math.sin(mid)!r} {-dist * math.cos(mid)!r} 0" '
            f'euler="0 0 {mid!r}" contype="0" conaffinity="0"/>')
        names.append(f"f{i}")
    return "\n".join(parts), names


def _heightfield_xml(R: float, half_w: float, opts: dict) -> tuple[str, str]:
    """The trough as a heightfield of ``heightfield_cell_mm`` cells: its asset and its geom."""
    ext = math.radians(opts["surface_extent_deg"])
    X = R * math.sin(ext)
    ncol = max(3, int(round(2 * X / opts["heightfield_cell_mm"])) + 1)
    x = np.linspace(-X, X, ncol)
    h = R - np.sqrt(R * R - x * x)
    top = float(h.max())
    elev = np.tile(h / top, (3, 1))  # nrow = 3 rows along the cylinder axis
    data = " ".join(repr(float(v)) for v in elev.ravel())
    asset = (f'<hfield name="trough" nrow="3" ncol="{ncol}" '
             f'size="{X!r} {half_w} {top!r} {_PAD_HALF_THICKNESS}" elevation="{data}"/>')
    # local z (elevation) -> world +y, local y -> world -z
    geom = (f'<geom name="hf" type="hfield" hfield="trough" pos="0 {-R!r} 0" '
            f'quat="{math.cos(-math.pi / 4)!r} {math.sin(-math.pi / 4)!r} 0 0" '
            f'contype="0" conaffinity="0"/>')
    return asset, geom


def _surface_xml(scenario, opts: dict, R: float, half_w: float) -> tuple[str, str, list[str]]:
    """The trough's surface (tangent pad, mesh facets or heightfield): its assets, its bodies
    and the names of the geoms the ball touches."""
    if scenario.surface == "tangent":
        return "", (f'<body name="pad" mocap="true" pos="0 {-(R + _PAD_HALF_THICKNESS)} 0">'
                    f'<geom name="pad" type="box" size="{half_w} {_PAD_HALF_THICKNESS} '
                    f'{half_w}" contype="0" conaffinity="0"/></body>'), ["pad"]
    if scenario.surface == "mesh":
        trough, names = _mesh_xml(R, half_w, opts)
        return "", trough, names
    asset, geom = _heightfield_xml(R, half_w, opts)
    return asset, geom, ["hf"]


def build_xml(scenario, opts: dict) -> str:
    """The MuJoCo model (MJCF text) of a scenario, in millimetres.

    Parameters
    ----------
    scenario : sim.Scenario
        The scenario (its surface: tangent pad, mesh facets or heightfield).
    opts : dict
        The engine's options (``DEFAULTS`` updated by the scenario's ``[engine.options]``).

    Returns
    -------
    str
        The model's XML.
    """
    R = scenario.cylinder_radius * 1e3
    r = scenario.ball_radius * 1e3
    L = R - r
    m = scenario.ball_mass
    g = scenario.gravity * 1e3
    mur = scenario.mu * r  # rolling coefficient is a length (mm)
    _, dt = _steps_per_frame(opts["timestep_s"], scenario.fps)
    if scenario.section.round:
        x0, y0 = L * math.sin(scenario.theta0), -L * math.cos(scenario.theta0)
    else:
        (x0, y0), _v, _w = initial_state(scenario)
        x0, y0 = x0 * 1e3, y0 * 1e3
    gvec = f"0 {-g * math.cos(scenario.tilt)!r} {g * math.sin(scenario.tilt)!r}" \
        if scenario.tilt else f"0 {-g!r} 0"
    width = opts["solimp_width_mm"]
    f0 = opts["sliding_friction"]
    assets, trough, pair_geoms = _surface_xml(scenario, opts, R, max(2.0 * r, 5.0))
    pairs = "\n".join(
        f'<pair geom1="ball" geom2="{gname}" condim="6" '
        f'friction="{f0!r} {f0!r} {mur!r} {mur!r} {mur!r}" '
        f'solref="{opts["solref_timeconst_s"]!r} 1" '
        f'solreffriction="{opts["solreffriction_timeconst_s"]!r} 1" '
        f'solimp="0.9 0.95 {width!r} 0.5 2"/>' for gname in pair_geoms)
    return f"""<mujoco model="rollfric-trough">
  <compiler angle="radian"/>
  <option timestep="{dt!r}" gravity="{gvec}" cone="{opts["cone"]}"
          noslip_iterations="{opts["noslip_iterations"]}" impratio="{opts["impratio"]!r}"
          integrator="{opts["integrator"]}"/>
  <asset>{assets}</asset>
  <worldbody>
    <body name="ball" pos="{x0!r} {y0!r} 0">
      <freejoint name="ball"/>
      <geom name="ball" type="sphere" size="{r!r}" mass="{m!r}" contype="0" conaffinity="0"/>
    </body>
    {trough}
  </worldbody>
  <contact>
    {pairs}
  </contact>
</mujoco>
"""


def _set_initial_velocity(scenario, data) -> None:
    """The ball's release velocity and spin (rolling without slipping), mm/s and rad/s."""
    R = scenario.cylinder_radius * 1e3
    r = scenario.ball_radius * 1e3
    L = R - r
    th0, w0 = scenario.theta0, scenario.theta_dot0
    if scenario.section.round:
        data.qvel[0:3] = [L * w0 * math.cos(th0), L * w0 * math.sin(th0), 0.0]
        data.qvel[3:6] = [0.0, 0.0, -(L / r) * w0]  # body frame = world frame at identity
    else:
        _p, (vx0, vy0), spin0 = initial_state(scenario)
        data.qvel[0:3] = [vx0 * 1e3, vy0 * 1e3, 0.0]
        data.qvel[3:6] = [0.0, 0.0, spin0]


def _pad_placer(scenario, data):
    """The function that moves the tangent pad (a mocap body) under the ball: tangent to the
    bore at the point nearest the ball's centre."""
    section = scenario.section
    tilted = scenario.tilt != 0.0
    pad_dist = scenario.cylinder_radius * 1e3 + _PAD_HALF_THICKNESS
    mocap_pos, mocap_quat = data.mocap_pos, data.mocap_quat
    q = data.qpos
    last_phi = [math.atan2(q[0], -q[1])]

    def place_pad():
        if section.round:
            phi = math.atan2(q[0], -q[1])
            mocap_pos[0, 0] = pad_dist * math.sin(phi)
            mocap_pos[0, 1] = -pad_dist * math.cos(phi)
        else:  # tangent to the ellipse at the point nearest the ball (sim.section, metres)
            phi = last_phi[0] = section.phi_of_point(q[0] * 1e-3, q[1] * 1e-3, last_phi[0])
            px, py = section.contact(phi)
            mocap_pos[0, 0] = px * 1e3 + _PAD_HALF_THICKNESS * math.sin(phi)
            mocap_pos[0, 1] = py * 1e3 - _PAD_HALF_THICKNESS * math.cos(phi)
        if tilted:
            mocap_pos[0, 2] = q[2]
        mocap_quat[0, 0] = math.cos(0.5 * phi)
        mocap_quat[0, 3] = math.sin(0.5 * phi)

    return place_pad


def _loss_applier(mujoco, scenario, model, data, losses):
    """The function that sets the losses (sim.losses) for the ball's current speed: the drag
    as an applied force, mu(v) r as the pairs' rolling and torsional coefficients."""
    ball_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "ball")
    m_ball, r_m = scenario.ball_mass, scenario.ball_radius
    r = scenario.ball_radius * 1e3

    def apply_losses():
        v = data.qvel[0:3] * 1e-3  # m/s
        data.xfrc_applied[ball_id, 0:3] = applied_force(v, losses, r_m, m_ball) * 1e3
        model.pair_friction[:, 2:5] = mu_at(float(np.linalg.norm(v)), scenario.mu,
                                            losses) * r

    return apply_losses


class _Record:
    """The ball's state at each camera frame: qpos, qvel, the contacts' count and their
    normal force summed (N; NaN without contact)."""

    def __init__(self, mujoco, model, data, n: int):
        self.mujoco, self.model, self.data = mujoco, model, data
        self.qpos = np.empty((n, 7))
        self.qvel = np.empty((n, 6))
        self.normal = np.full(n, np.nan)
        self.ncon = np.zeros(n, dtype=int)
        self.f6 = np.zeros(6)

    def __call__(self, i: int) -> None:
        data = self.data
        self.qpos[i] = data.qpos
        self.qvel[i] = data.qvel
        self.ncon[i] = data.ncon
        if data.ncon:
            total = 0.0
            for k in range(data.ncon):
                self.mujoco.mj_contactForce(self.model, data, k, self.f6)
                total += self.f6[0]
            self.normal[i] = total * 1e-3  # kg mm / s^2 -> N


def run(scenario, progress: bool = False):
    """Simulate ``scenario`` with MuJoCo (condim 6 rolling friction, millimetre units).

    Parameters
    ----------
    scenario : sim.Scenario
        The scenario (engine ``mujoco``; options in ``DEFAULTS``).
    progress : bool, optional
        Show a progress bar.

    Returns
    -------
    sim.Trajectory
        The ground truth at the camera rate as MuJoCo computed it (normal force summed over
        contacts, slip speed at the contact), with the engine's version and settings in
        ``meta``.
    """
    import mujoco

    opts = scenario.options()
    if opts["cone"] not in ("elliptic", "pyramidal"):
        raise ScenarioError(f"mujoco option cone must be elliptic or pyramidal, "
                            f"got {opts['cone']!r}")
    start = time.perf_counter()
    model = mujoco.MjModel.from_xml_string(build_xml(scenario, opts))
    data = mujoco.MjData(model)
    _set_initial_velocity(scenario, data)
    n_sub, dt = _steps_per_frame(opts["timestep_s"], scenario.fps)
    n = scenario.n_samples
    record = _Record(mujoco, model, data, n)
    tangent = scenario.surface == "tangent"
    place_pad = _pad_placer(scenario, data)
    if tangent:
        place_pad()
    mujoco.mj_forward(model, data)
    record(0)
    step = mujoco.mj_step
    losses = losses_of(scenario)
    apply_losses = _loss_applier(mujoco, scenario, model, data, losses)
    for i in tqdm(range(1, n), disable=not progress, desc="mujoco", unit="frame",
                  mininterval=0.5):
        if tangent or losses.active:
            for _ in range(n_sub):
                if tangent:
                    place_pad()
                if losses.active:
                    apply_losses()
                step(model, data)
        else:
            step(model, data, nstep=n_sub)
        record(i)
    wall = time.perf_counter() - start
    return _trajectory(scenario, opts, record, f"mujoco {mujoco.__version__}", dt, n_sub, wall)


def _trajectory(scenario, opts: dict, record: _Record, version: str, dt: float, n_sub: int,
                wall: float):
    """The recorded states (mm) as the SI trajectory, with the engine's settings in meta."""
    qpos, qvel = record.qpos, record.qvel
    pos = qpos[:, 0:3] * 1e-3
    vel = qvel[:, 0:3] * 1e-3
    quat = qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1, keepdims=True)
    omega = Rotation.from_quat(quat, scalar_first=True).apply(qvel[:, 3:6])
    theta, theta_dot = theta_from_centre(pos, vel)
    r = scenario.ball_radius * 1e3
    meta = {
        "engine": "mujoco",
        "engine_version": version,
        "surface": scenario.surface,
        "settings": {**opts, "timestep_s": dt, "steps_per_frame": n_sub, "units": "mm, kg, s",
                     "condim": 6, "friction": [1, 1, scenario.mu * r, scenario.mu * r,
                                               scenario.mu * r]},
        "n_geoms": int(record.model.ngeom),
        "max_contacts": int(record.ncon.max()),
        "wall_time_s": wall,
        **losses_meta(scenario, theta_dot),
    }
    return Trajectory(t=scenario.times(), theta=theta, theta_dot=theta_dot, position=pos,
                      quaternion=quat, angular_velocity=omega, normal_force=record.normal,
                      slip_speed=slip_speed(pos, vel, omega, scenario.ball_radius,
                                            scenario.section),
                      scenario=scenario, meta=meta)
