"""Fuzzing and properties of the parsers (issue 11).

Hypothesis property tests: whatever a setup, scenario, case or sweep table or a track CSV holds,
its parser returns a valid value or raises the project's InputError (exit status 2), never
another exception; valid values round-trip. Derandomized (the same examples on every run) and
bounded by example counts, not by time.

A seeded fuzz test runs mutated inputs (TIFF stacks, setup TOML, track CSV, scenario TOML, sweep
TOML with a case as its base) through the command line's ``main(argv)`` in-process: the exit
status is 0, 2 or 3 and never a traceback, a refused run writes nothing, and no temporary file is
left behind. Bounded by count and seeded, so it is reproducible.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tifffile
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from measure_data import make_recording

from rollfric.cli.fit import read_track
from rollfric.cli.main import main
from rollfric.errors import InputError
from rollfric.setup.model import PLAUSIBLE, dumps_setup, save_setup, setup_from_dict

PROPS = settings(derandomize=True, database=None, deadline=None, max_examples=50,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

# -- strategies: what a TOML file can hold -------------------------------------------------------

SCALARS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30),
    st.sampled_from([0, 1, -1, 1e300, -1e300, 1e-300, 0.0079, 10.0, 85.3, 1000, 0.1343]),
    st.text(max_size=12), st.booleans())
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=3)),
    max_leaves=4)

SETUP_KEYS = {"cylinder": ["radius_mm", "center_px"], "ball": ["diameter_mm", "mass_g"],
              "camera": ["fps", "pixel_size_mm"], "environment": ["gravity_m_s2"]}


def _tables(schema: dict, extra_sections=("x",)):
    """Tables shaped like ``schema`` (section -> keys), with missing and foreign keys and any
    values, and sometimes a non-table section."""
    section = st.sampled_from([*schema, *extra_sections])
    key_for = {s: st.sampled_from([*ks, "other"]) for s, ks in schema.items()}

    @st.composite
    def build(draw):
        out = {}
        for s in draw(st.lists(section, max_size=len(schema) + 1, unique=True)):
            if s not in schema or draw(st.integers(0, 9)) == 0:
                out[s] = draw(VALUES)
                continue
            keys = draw(st.lists(key_for[s], max_size=4, unique=True))
            out[s] = {k: draw(st.one_of(VALUES, st.floats(1e-3, 1e4))) for k in keys}
        return out

    return build()


@PROPS
@given(_tables(SETUP_KEYS))
def test_setup_parser_returns_a_plausible_setup_or_refuses(data):
    try:
        s = setup_from_dict(data, source="t")
    except InputError:
        return
    for name, (lo, hi, _) in PLAUSIBLE.items():
        assert lo <= getattr(s, name) <= hi
    assert s.ball_diameter < 2 * s.cylinder_radius


def _plausible(name):
    lo, hi, _ = PLAUSIBLE[name]
    return st.floats(lo, hi).filter(lambda v: math.isfinite(v))


@PROPS
@given(r=_plausible("cylinder_radius"), d=_plausible("ball_diameter"),
       m=_plausible("ball_mass"), fps=_plausible("fps"), px=_plausible("pixel_size"),
       g=_plausible("gravity"),
       c=st.none() | st.tuples(st.floats(-1e6, 1e6), st.floats(-1e6, 1e6)))
def test_setup_round_trips_through_its_file_form(r, d, m, fps, px, g, c):
    from rollfric.setup.model import Setup

    try:
        s = Setup(cylinder_radius=r, ball_diameter=d, ball_mass=m, fps=fps, pixel_size=px,
                  center_px=c, gravity=g)
    except InputError:
        return  # a ball wider than the trough; a lab value whose mm/g form leaves the range
    try:
        back = setup_from_dict(tomllib.loads(dumps_setup(s)), source="t")
    except InputError:
        return  # mm and g values at the very edge of the range, rounded over it
    for name in ("cylinder_radius", "ball_diameter", "ball_mass", "pixel_size"):
        assert getattr(back, name) == pytest.approx(getattr(s, name), rel=1e-15)
    assert (back.fps, back.gravity, back.center_px) == (s.fps, s.gravity, s.center_px)


SCENARIO_KEYS = {"cylinder": ["radius_mm"], "ball": ["diameter_mm", "mass_g"],
                 "camera": ["fps", "pixel_size_mm"], "environment": ["gravity_m_s2"],
                 "motion": ["mu", "theta0_deg", "theta_dot0_deg_s", "seconds"],
                 "engine": ["name", "surface", "seed", "options"]}


@PROPS
@given(_tables(SCENARIO_KEYS))
def test_scenario_parser_returns_a_scenario_within_the_limits_or_refuses(data):
    from rollfric.io.limits import MAX_SAMPLES
    from sim.scenario import scenario_from_dict

    try:
        sc = scenario_from_dict(data, source="t")
    except InputError:
        return
    assert 2 <= sc.n_samples <= MAX_SAMPLES + 1
    assert abs(sc.theta0) <= math.radians(80.0)


CASE_KEYS = {"scenario": ["motion", "ball", "engine", "camera"],
             "render": ["lighting", "noise", "motion_blur", "supersample", "seed", "sensor",
                        "camera", "lamps", "intensity_scale"],
             "measure": ["locator", "fit", "offset"], "name": []}


@settings(PROPS, max_examples=40)
@given(_tables(CASE_KEYS, extra_sections=("x", "lab")))
def test_case_parser_returns_a_case_or_refuses(data):
    from validation.case import case_from_dict

    try:
        case_from_dict(data, source="t")
    except InputError:
        pass


@settings(PROPS, max_examples=40)
@given(st.dictionaries(st.sampled_from(["sweep", "base", "grid", "cases", "x"]), VALUES,
                       max_size=4),
       st.dictionaries(st.sampled_from(["name", "mode", "stages", "seeds", "metrics", "x"]),
                       VALUES, max_size=4))
def test_sweep_parser_returns_a_sweep_or_refuses(data, head):
    from validation.sweep import sweep_from_dict

    if head:
        data = {**data, "sweep": head}
    try:
        spec = sweep_from_dict(data, source="t")
    except InputError:
        return
    assert 1 <= len(spec.cases) <= 100_000


# -- the track CSV -------------------------------------------------------------------------------

@PROPS
@given(st.binary(max_size=300) | st.text(alphabet="t_s,theta_rad0123456789.-e\nnaif \r\"",
                                         max_size=300).map(lambda s: s.encode()))
def test_track_reader_returns_checked_columns_or_refuses(tmp_path_factory, raw):
    path = tmp_path_factory.mktemp("track") / "t.csv"
    path.write_bytes(raw)
    try:
        t, theta = read_track(path)
    except InputError:
        return
    assert np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
    assert np.all(np.isnan(theta) | (np.abs(theta) <= math.pi))


@PROPS
@given(st.lists(st.tuples(st.floats(1e-6, 1.0), st.floats(-math.pi, math.pi) | st.just(math.nan)),
                min_size=1, max_size=50))
def test_track_round_trips_through_csv(tmp_path_factory, rows):
    t = np.cumsum([dt for dt, _ in rows])
    theta = np.array([th for _, th in rows])
    path = tmp_path_factory.mktemp("track") / "t.csv"
    path.write_text("t_s,theta_rad\n" + "".join(
        f"{float(a)!r},{'' if math.isnan(b) else repr(float(b))}\n" for a, b in zip(t, theta,
                                                                           strict=True)))
    t2, theta2 = read_track(path)
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(theta2, theta)


# -- fuzzing the command line ----------------------------------------------------------------------

WORDS = [b"1e300", b"-1", b"0", b"nan", b"inf", b'"x"', b"1e-300", b"true", b"[1, 2]", b"{}",
         b"\xdf", b"", b"=", b"[", b"\n["]


def mutate(data: bytes, rng: np.random.Generator, text: bool) -> bytes:
    """One seeded mutation: bytes changed, cut, inserted or repeated; for text also a number
    replaced by a troublesome word, or a line dropped or doubled."""
    b = bytearray(data)
    kind = int(rng.integers(0, 7 if text else 4))
    if kind == 0:
        for _ in range(int(rng.integers(1, 8))):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
    elif kind == 1:
        b = b[:int(rng.integers(0, len(b)))]
    elif kind == 2:
        i = int(rng.integers(0, len(b)))
        b[i:i] = bytes(rng.integers(0, 256, int(rng.integers(1, 16)), dtype=np.uint8))
    elif kind == 3:
        i, j = sorted(int(v) for v in rng.integers(0, len(b), 2))
        b[j:j] = b[i:i + 32]
    elif kind in (4, 5):
        import re

        spans = [m.span() for m in re.finditer(rb"-?\d+(\.\d+)?(e-?\d+)?", bytes(b))]
        if spans:
            i, j = spans[int(rng.integers(0, len(spans)))]
            b[i:j] = WORDS[int(rng.integers(0, len(WORDS)))]
    else:
        lines = bytes(b).split(b"\n")
        k = int(rng.integers(0, len(lines)))
        lines[k:k + 1] = [] if rng.integers(0, 2) else [lines[k], lines[k]]
        b = bytearray(b"\n".join(lines))
    return bytes(b)


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    """Valid inputs to mutate: a small recording (60 frames, 240 x 100 px), its setup, its
    track, a scenario and a sweep whose base is a case."""
    d = tmp_path_factory.mktemp("seeds")
    rec = make_recording(60, noise=1.0, width=240, height=100, center=(120.0, -120.0),
                         with_center=True)
    save_setup(rec.setup, d / "setup.toml")
    buf = io.BytesIO()
    tifffile.imwrite(buf, np.stack(rec.frames))
    pages = io.BytesIO()
    with tifffile.TiffWriter(pages) as tw:
        for f in rec.frames:
            tw.write(f, contiguous=False)
    track = "t_s,theta_rad\n" + "".join(f"{a:.17g},{b:.17g}\n"
                                        for a, b in zip(rec.t, rec.theta, strict=True))
    return {
        "dir": d,
        "tiff": [buf.getvalue(), pages.getvalue()],
        "setup": (d / "setup.toml").read_bytes(),
        "track": track.encode(),
        "scenario": (b"[cylinder]\nradius_mm = 85.3\n[ball]\ndiameter_mm = 10.0\n"
                     b"mass_g = 4.07612\n[motion]\nmu = 0.0079\ntheta0_deg = 20.0\n"
                     b"theta_dot0_deg_s = 0.0\n[engine]\nname = \"reference\"\nseed = 0\n"),
        "sweep": (b"[sweep]\nname = \"f\"\nmode = \"grid\"\nstages = \"sim\"\nseeds = 2\n"
                  b"metrics = [\"mu_bias_rel\", \"center_rms_px\"]\n"
                  b"[base.scenario.motion]\nmu = 0.0079\nseconds = 1.0\n"
                  b"[base.render]\nnoise = \"realistic\"\nmotion_blur = 1\n"
                  b"[base.render.camera]\nwidth = 320\nheight = 112\n"
                  b"center_px = [160.0, -540.0]\n[base.measure]\nlocator = \"subpixel\"\n"
                  b"[grid]\n\"render.sensor.read_noise\" = [0.0, 8.0]\n"),
    }


def _hidden(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.rglob(".*"))


def _run(argv) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main([str(a) for a in argv])
    return code, err.getvalue()


# (what is mutated, count): ~100 runs, each a refusal or a small measurement or fit; run 0 of
# each kind is the unmutated input
FUZZ = {"tiff": 8, "setup": 25, "track": 25, "scenario": 15, "sweep": 30}


@pytest.mark.parametrize("kind", list(FUZZ))
def test_mutated_inputs_through_the_command_line(seeds, tmp_path, kind):
    rng = np.random.default_rng([20261123, list(FUZZ).index(kind)])
    d = seeds["dir"]
    codes = []
    for k in range(FUZZ[kind]):
        work = tmp_path / f"run{k}"
        work.mkdir()
        def mutated(data, text=True, k=k):
            return data if k == 0 else mutate(data, rng, text)

        if kind == "tiff":
            inp = work / "rec.tif"
            inp.write_bytes(mutated(seeds["tiff"][k % 2], text=False))
            out = work / "out"
            argv = ["measure", inp, "--setup", d / "setup.toml", "--out", out, "--no-progress"]
        elif kind == "setup":
            inp = work / "setup.toml"
            inp.write_bytes(mutated(seeds["setup"]))
            (work / "track.csv").write_bytes(seeds["track"])
            out = work / "fit.json"
            argv = ["fit", work / "track.csv", "--setup", inp, "--out", out]
        elif kind == "track":
            inp = work / "track.csv"
            inp.write_bytes(mutated(seeds["track"]))
            out = work / "fit.json"
            argv = ["fit", inp, "--setup", d / "setup.toml", "--out", out]
        elif kind == "scenario":
            inp = work / "scenario.toml"
            inp.write_bytes(mutated(seeds["scenario"]))
            out = work / "t.csv"
            # the run's length and rate fixed by flags (flags override the file)
            argv = ["simulate", inp, "--seconds", "0.05", "--fps", "1000", "--out", out]
        else:
            inp = work / "sweep.toml"
            inp.write_bytes(mutated(seeds["sweep"]))
            out = None
            argv = ["sweep", inp, "--dry-run"]
        before = sorted(p.name for p in work.iterdir())
        code, err = _run(argv)
        codes.append(code)
        assert code in (0, 2, 3), (kind, k, code, err)
        assert "Traceback" not in err, (kind, k, err)
        if code == 2:
            assert err.strip(), (kind, k)
            assert sorted(p.name for p in work.iterdir()) == before  # nothing written
        elif out is not None:
            assert out.exists(), (kind, k)
            if kind in ("setup", "track"):
                assert "mu" in json.loads(out.read_text())
            if kind == "tiff":
                assert {"track.csv", "fit.json"} <= {p.name for p in out.iterdir()}
        assert _hidden(work) == [], (kind, k)  # no temporary file left
    # the unmutated input is measured; the mutations reach refusals
    assert codes[0] in (0, 3) and 2 in codes, (kind, codes)
