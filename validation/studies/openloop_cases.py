"""The open-loop study's cases: each family's physics drawn on top of coverage's draw.

:func:`draw_openloop` draws one case of :mod:`validation.studies.openloop`: the motion, locator
noise and as-built setup of :func:`validation.studies.coverage.draw_case`, and, by its family
(:data:`FAMILIES`), the physics the fitter does not assume or knows only within a stated u:
room air with a constant drag coefficient (:func:`swing_cd`: the law's Cd at the swing's
Reynolds number times a drawn wall factor), a tilted trough, an oval bore, a yawed and pitched
camera, a speed law. The draws' scales (:data:`TILT_DEG_U`, :data:`OVALITY_MM_U`,
:data:`CAMERA_DEG`, the wall factor's ranges, :data:`SPEED_FRACTION`) are the study's.
"""

from __future__ import annotations

import math

import numpy as np

from rollfric.fit.air import (
    AIR_VISCOSITY,
    ROOM_AIR_DENSITY,
    ROOM_AIR_DENSITY_U,
    WALL_FACTOR,
    WALL_FACTOR_U,
    cd_sphere,
)
from validation.studies.coverage import draw_case

FAMILIES = ("air", "air_beyond", "tilt", "ovality", "camera", "speed", "all")
# the trough as built: the tolerances the lab states (cylinder.tilt_deg_u, ovality_mm_u)
TILT_DEG_U = 0.05  # deg: a machinist's level reads 0.02-0.05 deg
OVALITY_MM_U = 0.05  # mm, D_max - D_min of the bore
CAMERA_DEG = 0.5  # yaw and pitch drawn uniform within +- this (deg)
# the fitter's wall factor is rectangular over WALL_FACTOR +- sqrt(3) WALL_FACTOR_U (1 .. 2)
WALL_FACTOR_STATED = (WALL_FACTOR - math.sqrt(3.0) * WALL_FACTOR_U,
                      WALL_FACTOR + math.sqrt(3.0) * WALL_FACTOR_U)
WALL_FACTOR_BEYOND = (0.5, 3.0)
SPEED_FRACTION = (0.02, 0.15)  # mu_speed v_top / mu0
PYBULLET = ("tilt", "all")  # families whose truth needs a 3D engine


def swing_cd(d_m: float, L_m: float, theta0: float, density: float,
             wall_factor: float = 1.0, *, mu: float = 0.0, seconds: float = 0.0,
             gravity: float = 9.81) -> tuple[float, float]:
    """The drag law's coefficient at the swing's Reynolds number: the free sphere's
    Schiller-Naumann Cd times ``wall_factor``, weighted by the drag's power (v^3) over the
    record's half-swings: the constant Cd that takes the law's energy from the swing. Each
    half-swing runs at the frictionless speed v_top |cos| (v_top^2 = (10/7) g L (1 - cos A)),
    its amplitude A falling by 2 mu a half-swing (rolling resistance at small angles) until
    |A| <= mu (the ball sticks) or the record (``seconds``) ends; ``seconds`` 0: the first
    half-swing alone.

    Parameters
    ----------
    d_m, L_m : float
        Ball diameter and track radius R - r (m).
    theta0 : float
        Release angle (rad).
    density : float
        Air density (kg/m^3).
    wall_factor : float
        The wall's factor on the free sphere's Cd.
    mu : float
        Rolling-resistance coefficient (the amplitude's loss).
    seconds : float
        The record's length (s).
    gravity : float
        m/s^2.

    Returns
    -------
    cd, re_top : float
        The constant Cd and the Reynolds number at the first swing's top speed.
    """
    half_period = math.pi * math.sqrt(7.0 * L_m / (5.0 * gravity))
    n_half = max(1, math.ceil(seconds / half_period))
    phase = np.linspace(0.0, 0.5 * math.pi, 2001)[1:-1]
    num = den = 0.0
    amp = abs(theta0)
    for _ in range(n_half):
        if amp <= mu:
            break
        v = math.sqrt(10.0 / 7.0 * gravity * L_m * (1.0 - math.cos(amp))) * np.cos(phase)
        power = v**3  # the drag's power over equal steps of time (phase)
        num += float(np.sum(cd_sphere(density * v * d_m / AIR_VISCOSITY) * power))
        den += float(np.sum(power))
        amp -= 2.0 * mu
    v_top = math.sqrt(10.0 / 7.0 * gravity * L_m * (1.0 - math.cos(theta0)))
    return wall_factor * num / den, density * v_top * d_m / AIR_VISCOSITY


def draw_openloop(seed: int, family: str) -> dict:
    """One case: coverage's draw (:func:`validation.studies.coverage.draw_case`) and the
    family's physics, drawn from a stream of its own (the coverage draws stay those of
    ``seed``)."""
    if family not in FAMILIES:
        raise ValueError(f"unknown family {family!r} (known: {', '.join(FAMILIES)})")
    case = {k: v for k, v in draw_case(seed).items() if not k.startswith("contour_")}
    rng = np.random.default_rng(50_000 + seed)
    every = family == "all"
    air = family in ("air", "air_beyond") or every
    lo, hi = WALL_FACTOR_BEYOND if family == "air_beyond" else WALL_FACTOR_STATED
    wall = float(rng.uniform(lo, hi))
    density = float(ROOM_AIR_DENSITY + rng.normal(0.0, ROOM_AIR_DENSITY_U))
    tilt = float(rng.normal(0.0, TILT_DEG_U))
    ovality = float(abs(rng.normal(0.0, OVALITY_MM_U)))
    ovality_angle = float(rng.uniform(0.0, 180.0))
    yaw, pitch = (float(v) for v in rng.uniform(-CAMERA_DEG, CAMERA_DEG, 2))
    speed_fraction = float(rng.uniform(*SPEED_FRACTION))
    speed_on = family == "speed" or (every and rng.uniform() < 0.5)
    d_m = case["true_diameter_mm"] * 1e-3
    L_m = (case["true_radius_mm"] - 0.5 * case["true_diameter_mm"]) * 1e-3
    th0 = math.radians(case["theta0_deg"])
    cd, re_top = swing_cd(d_m, L_m, th0, density, wall, mu=case["mu"],
                          seconds=case["seconds"])
    v_top = math.sqrt(10.0 / 7.0 * 9.81 * L_m * (1.0 - math.cos(th0)))
    case.update(
        family=family,
        engine="pybullet" if family in PYBULLET else "reference",
        air_density=density if air else 0.0,
        wall_factor=wall if air else math.nan,
        wall_factor_off=abs(wall - WALL_FACTOR) if air else 0.0,
        air_cd=cd if air else 0.0, reynolds_top=re_top if air else 0.0,
        tilt_deg=tilt if family == "tilt" or every else 0.0,
        ovality_mm=ovality if family == "ovality" or every else 0.0,
        ovality_angle_deg=ovality_angle,
        yaw_deg=yaw if family == "camera" or every else 0.0,
        pitch_deg=pitch if family == "camera" or every else 0.0,
        speed_fraction=speed_fraction if speed_on else 0.0,
        mu_speed_s_m=speed_fraction * case["mu"] / v_top if speed_on else 0.0)
    case["tilt_abs_deg"] = abs(case["tilt_deg"])
    case["camera_deg"] = max(abs(case["yaw_deg"]), abs(case["pitch_deg"]))
    return case


def family_of(i: int, families) -> str:
    """The i-th case's family: the families in turn."""
    return families[i % len(families)]
