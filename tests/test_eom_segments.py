"""rollfric.fit.eom.solve_segments: the one segment-and-stick loop of the reference integrator and
of sim.losses.

The outputs of both callers (rollfric.fit.eom.solve_reference and sim.losses.solve) were recorded
with the code before they shared the loop (commit c0ae672, each with a copy of its own) in
tests/data/eom_segments_c0ae672.npz, written by ``recorded_outputs()`` below; the shared loop
reproduces them bit for bit (checked here to 1e-12 rad, so that a libm differing in the last
bit does not fail the test). A pluggable right-hand side is checked against the closed form of
a harmonic oscillator with dry (Coulomb) friction.

The recording was made with OpenBLAS's Haswell kernel. SciPy's DOP853 sums its stages with
``np.dot``; OpenBLAS picks its kernel by the CPU (SkylakeX on an AVX-512 machine), whose
different order of summation changes the last bits, and the adaptive steps grow that to
~1e-10 rad (seen on an AMD EPYC with AVX-512, 2026-11-24: 12 of the 14 cases; all 14 equal to
1e-12 with ``OPENBLAS_CORETYPE=Haswell``). So the callers run in a child process with the
recording's kernel, and the comparison stays at 1e-12.
"""

import math
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rollfric.fit import eom
from sim.losses import Losses
from sim.losses import solve as solve_losses

RECORDED = Path(__file__).parent / "data" / "eom_segments_c0ae672.npz"
L, R_BALL, M_BALL, G = 0.0425, 0.005, 4.08e-3, 9.81
T = np.linspace(0.0, 2.0, 101)
# (caller, mu, theta0 in degrees, omega0 in rad/s, mu1 in s/rad, losses)
CASES = [
    ("reference", 0.0, 20.0, 0.0, 0.0, None),
    ("reference", 0.002, 20.0, 1.5, 0.0, None),
    ("reference", 0.02, 60.0, 0.0, 0.05, None),
    ("reference", 0.3, 20.0, 0.0, 0.0, None),  # sticks where it starts
    ("reference", 0.02, 170.0, 0.0, 0.0, None),  # above the axis: rolls down
    ("reference", 0.002, 5.0, 0.0, 0.05, None),
    ("losses", 0.0, 20.0, 0.0, 0.0, Losses(air_density=1.2, air_cd=2.0)),
    ("losses", 0.002, 20.0, 0.0, 0.0, Losses()),
    ("losses", 0.002, 20.0, 1.5, 0.0, Losses(mu_speed=0.5)),
    ("losses", 0.02, 60.0, 0.0, 0.0, Losses(air_density=1.2, air_cd=2.0)),
    ("losses", 0.02, 60.0, 0.0, 0.0, Losses(mu_speed=0.3, air_density=1.2, air_cd=0.47)),
    ("losses", 0.3, 60.0, 0.0, 0.0, Losses(mu_speed=0.5)),  # stops for good mid-run
    ("losses", 0.02, 170.0, 1.5, 0.0, Losses(mu_speed=0.3, air_density=1.2, air_cd=0.47)),
    ("losses", 0.0, 5.0, 0.0, 0.0, Losses(mu_speed=0.5)),
]


def _run(case):
    caller, mu, th0, om0, mu1, losses = case
    if caller == "reference":
        return eom.solve_reference(math.radians(th0), om0, mu, T, track_radius=L, gravity=G,
                                   mu1=mu1)
    return solve_losses(math.radians(th0), om0, mu, T, losses, track_radius=L,
                        ball_radius=R_BALL, ball_mass=M_BALL, gravity=G)


def recorded_outputs() -> dict:
    """theta, theta_dot and t_stop of every case (what the .npz holds), by index."""
    out = {}
    for i, case in enumerate(CASES):
        th, om, t_stop = _run(case)
        out[f"theta{i}"], out[f"omega{i}"], out[f"t_stop{i}"] = th, om, np.array(t_stop)
    return out


def _recording_kernel_available() -> str | None:
    """Why OpenBLAS's Haswell kernel cannot be chosen here, or None when it can."""
    blas = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
    if "openblas" not in blas.get("name", "").lower():
        return f"NumPy's BLAS is {blas.get('name')!r}, not OpenBLAS"
    if platform.machine() not in ("x86_64", "AMD64"):
        return f"OpenBLAS's Haswell kernel needs x86_64, this is {platform.machine()}"
    from numpy._core._multiarray_umath import __cpu_features__

    if not (__cpu_features__.get("AVX2") and __cpu_features__.get("FMA3")):
        return "OpenBLAS's Haswell kernel needs AVX2 and FMA"
    return None


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """Every case's outputs computed with the recording's BLAS kernel (a child process started
    with ``OPENBLAS_CORETYPE=Haswell``: OpenBLAS reads it once, when it loads)."""
    if os.environ.get("OPENBLAS_CORETYPE") == "Haswell":
        return recorded_outputs()
    why = _recording_kernel_available()
    if why:
        pytest.skip(f"the recording was made with OpenBLAS's Haswell kernel: {why}")
    out = tmp_path_factory.mktemp("eom_segments") / "outputs.npz"
    code = ("import runpy, sys, numpy as np; "
            "np.savez(sys.argv[2], **runpy.run_path(sys.argv[1])['recorded_outputs']())")
    subprocess.run([sys.executable, "-c", code, __file__, str(out)], check=True,
                   env={**os.environ, "OPENBLAS_CORETYPE": "Haswell"})
    return dict(np.load(out))


@pytest.mark.parametrize("i", range(len(CASES)))
def test_both_callers_reproduce_the_outputs_before_the_loop_was_shared(i, outputs):
    rec = np.load(RECORDED)
    th, om = outputs[f"theta{i}"], outputs[f"omega{i}"]
    t_stop = float(outputs[f"t_stop{i}"])
    assert np.max(np.abs(th - rec[f"theta{i}"])) <= 1e-12
    assert np.max(np.abs(om - rec[f"omega{i}"])) <= 1e-12
    t_rec = float(rec[f"t_stop{i}"])
    assert (t_stop == t_rec) if math.isinf(t_rec) else abs(t_stop - t_rec) <= 1e-12


def test_the_cases_cover_sticking_rolling_on_and_rolling_over_the_axis():
    stops = [math.isfinite(_run(c)[2]) for c in CASES]
    assert any(stops) and not all(stops)


def test_a_pluggable_right_hand_side_dry_friction_oscillator():
    # theta'' = -w^2 theta - s f: each half-swing takes pi / w and the turning-point amplitude
    # drops by 2 f / w^2 (closed form); the loop must hand accel the sign of the motion
    w, f = 2.0 * math.pi, 0.5
    t = np.linspace(0.0, 2.0, 2001)  # turning points at t = 0.5 k, on the samples
    th, om, t_stop = eom.solve_segments(0.3, 0.0, t, lambda th, om, s: -w * w * th - s * f,
                                        mu_static=0.0)
    drop = 2.0 * f / w**2
    for k in range(1, 4):
        j = 500 * k
        assert abs(abs(th[j]) - (0.3 - k * drop)) < 1e-9
        assert abs(om[j]) < 1e-8
        assert math.copysign(1.0, th[j]) == (-1.0) ** k
    assert math.isinf(t_stop)


def test_solve_segments_sticks_by_the_static_coefficient():
    # at rest at 10 deg: sticks for mu_static >= tan(10 deg), else leaves towards the bottom
    t = np.linspace(0.0, 0.5, 51)

    def accel(th, om, s):
        return -G / L * math.sin(th)

    th, om, t_stop = eom.solve_segments(math.radians(10), 0.0, t, accel, mu_static=0.18)
    assert t_stop == 0.0 and np.all(th == math.radians(10)) and np.all(om == 0.0)
    th, om, t_stop = eom.solve_segments(math.radians(10), 0.0, t, accel, mu_static=0.17)
    assert math.isinf(t_stop) and om[1] < 0


def test_solve_segments_refuses_bad_times_and_negative_mu():
    with pytest.raises(ValueError, match="increasing"):
        eom.solve_segments(0.1, 0.0, [0.0, 0.0], lambda th, om, s: 0.0, mu_static=0.0)
    with pytest.raises(ValueError, match="mu"):
        eom.solve_segments(0.1, 0.0, T, lambda th, om, s: 0.0, mu_static=-0.1)
