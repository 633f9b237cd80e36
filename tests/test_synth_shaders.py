"""synth's mesh shader (pyrender's, with the shadow filter read by gathers and the light loops
bounded by the scene's light counts) against pyrender's."""

import math
import os

import numpy as np
import pytest

from synth.backends.raster import SceneRenderer
from synth.backends.shaders import fixed_light_loops, gather_mesh_shader, sphere_shader
from synth.camera import CameraModel
from synth.config import SceneConfig, lighting_preset
from synth.pyrender_adapter import compiled_programs

R_CYL = 0.0853
R_BALL = 0.005


def _stock_mesh_frag() -> str:
    import pyrender

    with open(os.path.join(os.path.dirname(pyrender.__file__), "shaders", "mesh.frag")) as f:
        return f.read()


def test_only_the_shadow_filter_is_replaced():
    stock = _stock_mesh_frag()
    ours = gather_mesh_shader(stock)
    assert ours.count("textureGather(") == 4
    a, b = stock.index("float PCF("), stock.index("float shadow_calc(")
    # everything outside the PCF function is pyrender's text (plus the extension line)
    head = stock[:a].replace("#version 330 core", "#version 330 core\n"
                             "#extension GL_ARB_texture_gather : require", 1)
    assert ours.startswith(head) and ours.endswith(stock[b:])


def test_light_loops_get_the_scene_counts_and_keep_their_bound():
    stock = _stock_mesh_frag()
    ours = fixed_light_loops(stock, 0, 2, 0)
    for kind, n in (("directional", 0), ("spot", 2), ("point", 0)):
        assert f"for (int i = 0; i < n_{kind}_lights; i++)" not in ours
        assert (f"for (int i = 0; i < {n}; i++) {{\n        if (i >= n_{kind}_lights) break;"
                in ours)
    # nothing else changed
    assert ours.count("\n") == stock.count("\n") + 3
    with pytest.raises(ValueError, match="n_spot"):
        fixed_light_loops(stock, 0, -1, 0)


def test_sphere_shader_keeps_the_mesh_shader_and_only_feeds_it():
    """The sphere impostor's shader is the mesh shader's text with its two inputs made
    globals and its main renamed, plus a main that sets them: the shading code is pyrender's."""
    stock = gather_mesh_shader(_stock_mesh_frag())
    ours = sphere_shader(stock)
    body = stock.replace("in vec3 frag_position;", "vec3 frag_position;").replace(
        "in vec3 frag_normal;", "vec3 frag_normal;").replace("void main()\n{",
                                                              "void shade_mesh()\n{")
    head, rest = body.split("\n", 1)
    assert ours.startswith(head + "\n#extension GL_ARB_sample_shading : require\n" + rest)
    tail = ours[len(head) + len(rest) + 50:]
    assert tail.count("void main()") == 1 and "shade_mesh();" in tail
    with pytest.raises(RuntimeError, match="frag_normal"):
        sphere_shader(stock.replace("in vec3 frag_normal;", "in vec3 frag_n;"))


def test_an_unknown_shader_is_refused():
    stock = _stock_mesh_frag()
    with pytest.raises(RuntimeError, match="PCF"):
        gather_mesh_shader(stock.replace("float PCF(", "float PCF2("))
    with pytest.raises(RuntimeError, match="result/9.0"):
        gather_mesh_shader(stock.replace("result/9.0", "result/8.0"))
    with pytest.raises(RuntimeError, match="spot-light loop"):
        fixed_light_loops(stock.replace("i < n_spot_lights", "i < n_spot_lights - 0"), 0, 2, 0)


@pytest.mark.parametrize("lighting", ["thesis", "harsh"])
def test_frames_equal_pyrender_own_shaders(lighting):
    """Full frames with the ball and its soft shadows: synth's shader against pyrender's,
    at most 1 DN apart (a different order of additions could flip a rounding)."""
    if lighting == "harsh":
        cam = CameraModel(width=320, height=224, pixel_size=0.4e-3, center_px=(300.0, -100.0))
        theta = -0.35
    else:
        cam = CameraModel(width=256, height=192, center_px=(128.0, -470.0))
        theta = 0.04
    L = R_CYL - R_BALL
    c = np.array([L * math.sin(theta), -L * math.cos(theta), 0.0])
    sr = SceneRenderer(SceneConfig(camera=cam, lighting=lighting_preset(lighting)), R_BALL, R_CYL)
    try:
        bg = sr.render_full(stock_shaders=True)
        sr.set_ball(sr.ball_pose(c))
        stock = sr.render_full(stock_shaders=True)
        ours = sr.render_full()
        # both sets of programs were really compiled and used
        assert all(compiled_programs(cache) for cache in sr._programs.values())
    finally:
        sr.close()
    dn = np.abs(ours.astype(int) - stock.astype(int)) / (sr.scale / 255)
    assert dn.max() <= 1.0, dn.max()
    # the comparison covers the shadow filter: shadow pixels outside the ball's box, some of
    # them in the penumbra (neither the lit nor the fully shadowed value)
    x0, y0, x1, y1 = sr.ball_box(c[None])
    changed = stock != bg
    changed[max(y0, 0):y1, max(x0, 0):x1] = False
    assert changed.sum() > 50
    drop = (bg.astype(int) - stock.astype(int))[changed]
    assert len(np.unique(drop)) > 10


def test_a_lamp_added_after_the_first_render_is_drawn():
    """The programs are built for the scene's light counts: a lamp added later gets programs
    for the new count (a loop bounded by the old count would leave it dark)."""
    import pyrender

    from synth.backends.scene_model import look_at

    cam = CameraModel(width=256, height=192, center_px=(128.0, -470.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        before = sr.render_full()
        lamp = pyrender.SpotLight(color=[1.0, 1.0, 1.0], intensity=0.05,
                                  innerConeAngle=0.2, outerConeAngle=0.4)
        sr.scene.add(lamp, pose=look_at([0.0, -0.05, 0.3], [0.0, -0.08, 0.0]), name="extra")
        ours = sr.render_full()
        stock = sr.render_full(stock_shaders=True)
    finally:
        sr.close()
    dn = sr.scale / 255
    assert np.abs(ours.astype(int) - before.astype(int)).max() / dn > 5  # the lamp lights
    assert np.abs(ours.astype(int) - stock.astype(int)).max() / dn <= 1.0


def test_specialised_shader_holds_the_exact_values():
    """specialised_mesh_shader: the lamps', ambient light's and camera's uniforms become
    constants whose float32 bit patterns are the values given; the samplers stay uniforms."""
    import re

    from synth.backends.shaders import (
        SPOT_FIELDS,
        shader_dir,
        specialised_mesh_shader,
        specialised_values_names,
    )

    with open(os.path.join(shader_dir(0, 2, 0), "mesh.frag")) as f:
        text = f.read()
    rng = np.random.default_rng(0)
    values = {name: rng.normal(size=n).astype(np.float32)
              for name, n in specialised_values_names(2)}
    ours = specialised_mesh_shader(text, values, 2)
    for field, glsl_type, _ in SPOT_FIELDS:
        head = f"const {glsl_type} SPOT_{field}["
        line = next(x for x in ours.splitlines() if x.startswith(head))
        bits = np.array([int(b) for b in re.findall(r"uintBitsToFloat\((\d+)u\)", line)],
                        dtype=np.uint32).view(np.float32)
        want = np.concatenate([values[f"spot_lights[{i}].{field}"] for i in range(2)])
        np.testing.assert_array_equal(bits, want)
        assert f"spot_lights[i].{field}" not in ours
    assert "spot_lights[i].shadow_map" in ours and "uniform Material material;" in ours
    for gone in ("uniform vec3 cam_pos;", "uniform vec3 ambient_light;", "n_spot_lights) break"):
        assert gone not in ours
    with pytest.raises(RuntimeError, match="cam_pos"):
        specialised_mesh_shader(text.replace("uniform vec3 cam_pos;", ""), values, 2)


@pytest.mark.parametrize("case", ["thesis", "perspective", "harsh"])
def test_specialised_ball_shader_draws_the_same_tiles(case):
    """The lean path's ball drawn by the specialised shader (synth.backends.lean: the lamps' and
    camera's uniforms as constants) gives the tiles of the uniform shader bit for bit over
    consecutive frames, and the full frame within 1 DN of stock pyrender."""
    if case == "harsh":
        cam = CameraModel(width=320, height=224, pixel_size=0.4e-3, center_px=(300.0, -100.0))
        thetas = np.linspace(-0.5, -0.2, 6)
    else:
        cam = CameraModel(width=256, height=192, center_px=(128.0, -470.0),
                          projection="perspective" if case == "perspective" else "orthographic",
                          working_distance=0.6)
        thetas = np.linspace(-0.04, 0.04, 6)
    lighting = lighting_preset("harsh" if case == "harsh" else "thesis")
    L = R_CYL - R_BALL
    sr = SceneRenderer(SceneConfig(camera=cam, lighting=lighting), R_BALL, R_CYL)
    try:
        bg = sr.render_full()
        cs = [np.array([L * math.sin(t), -L * math.cos(t), 0.0]) for t in thetas]
        frames = [([sr.ball_pose(c)], sr.tiles_for(c[None])) for c in cs]
        sr.render_tiles(*frames[0])  # pyrender's path; the lean path is built
        got = {}
        for flag in (False, True, False):
            sr._lean.specialise, sr._lean.ready = flag, False
            got[flag] = [sr.render_tiles(*f) for f in frames]
            ball = sr._lean.ball_draws[0]
            base = next(d for d in sr._lean.draws if d["node"] is sr._lean.ball)
            assert (ball["pid"] != base["pid"]) == flag  # the specialised program drew
        for a, b in zip(got[False], got[True], strict=True):
            for x, y in zip(a, b, strict=True):
                np.testing.assert_array_equal(x, y)
        poses, tiles = frames[-1]
        comp = bg.copy()
        for (x0, y0, w, h), img in zip(tiles, got[True][-1], strict=True):
            comp[y0:y0 + h, x0:x0 + w] = img
        sr.set_ball(poses[0])
        stock = sr.render_full(stock_shaders=True)
    finally:
        sr.close()
    assert np.any(comp != bg)
    assert np.abs(comp.astype(int) - stock.astype(int)).max() / (sr.scale / 255) <= 1.0
