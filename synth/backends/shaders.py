"""pyrender's own shaders, with its mesh shader made cheaper for llvmpipe without changing what
it computes.

Two changes to pyrender's fragment shader (``mesh.frag``), read from the installed package at
run time (a text that does not match is refused, never patched half):

- The shadow filter. pyrender's ``PCF`` softens every shadow-map lookup with a 3 x 3 grid of
  bilinear lookups, each of four depth compares on the NEAREST-filtered map: 36 texture reads
  per lamp per fragment. The nine 2 x 2 footprints are shifted by whole texels, so they cover
  one 4 x 4 block of texels, and the sum weights that block's compares by ``(1 - f, 1, 1, f)``
  along each axis (``f`` the fractional texel position the bilinear mix uses). The replacement
  reads the same 16 texels with four ``textureGather`` calls and applies the same weights.
- The light loops. pyrender loops ``for (i = 0; i < n_spot_lights; i++)`` over uniform arrays
  sized for 26 lamps (and likewise for directional and point lights), so the compiler cannot
  unroll them and indexes the lamps' samplers and uniforms at run time. Here each loop runs to
  the number of such lights the scene has, a compile-time constant, with
  ``if (i >= n_spot_lights) break;`` kept, so the same iterations run: loops over light types
  the scene lacks disappear, the spot loop unrolls.

The same arithmetic on the same values, in a different order of additions in the filter only.
On llvmpipe a tile frame took about 60 % less time (the texture reads were the largest single
cost, the dynamic light loops the next); the rendered pixels were bit-identical to stock
pyrender's in every comparison so far (the tests allow the 1 DN a rounding flip could cost, and
the benchmark reports the largest difference against the stock shader).
"""

from __future__ import annotations

import atexit
import functools
import os
import shutil
import tempfile
from multiprocessing.util import Finalize

import numpy as np

from synth.pyrender_adapter import load

# pyrender's function, replaced from this line up to the next function
_PCF_HEAD = "float PCF(sampler2D depths, vec2 size, vec2 uv, float compare){"
_NEXT = "float shadow_calc("
_VERSION = "#version 330 core"

_GATHER_PCF = """float PCF(sampler2D depths, vec2 size, vec2 uv, float compare){
    // pyrender's 3 x 3 bilinear 2 x 2 compares = the 4 x 4 texels from c, weighted
    // (1 - f, 1, 1, f) per axis; each gather at a texel corner returns the 2 x 2 texels
    // around it as (x0, y1), (x1, y1), (x1, y0), (x0, y0)
    vec2 g = uv * size + 0.5;
    vec2 f = fract(g);
    vec2 c = floor(g) - 1.0;
    vec4 wx = vec4(1.0 - f.x, 1.0, 1.0, f.x);
    vec4 wy = vec4(1.0 - f.y, 1.0, 1.0, f.y);
    vec4 cv = vec4(compare);
    vec4 s00 = vec4(greaterThan(cv, textureGather(depths, (c + vec2(1.0, 1.0)) / size)));
    vec4 s10 = vec4(greaterThan(cv, textureGather(depths, (c + vec2(3.0, 1.0)) / size)));
    vec4 s01 = vec4(greaterThan(cv, textureGather(depths, (c + vec2(1.0, 3.0)) / size)));
    vec4 s11 = vec4(greaterThan(cv, textureGather(depths, (c + vec2(3.0, 3.0)) / size)));
    float result = wy.x * dot(wx, vec4(s00.w, s00.z, s10.w, s10.z))
                 + wy.y * dot(wx, vec4(s00.x, s00.y, s10.x, s10.y))
                 + wy.z * dot(wx, vec4(s01.w, s01.z, s11.w, s11.z))
                 + wy.w * dot(wx, vec4(s01.x, s01.y, s11.x, s11.y));
    return result / 9.0;
}

"""


_LOOPS = {kind: f"for (int i = 0; i < n_{kind}_lights; i++) {{"
          for kind in ("directional", "point", "spot")}


def fixed_light_loops(text: str, n_directional: int, n_spot: int, n_point: int) -> str:
    """pyrender's ``mesh.frag`` text with each light loop bounded by a compile-time count (the
    scene's number of such lights) and its run-time bound kept as a ``break``.

    Raises RuntimeError when a loop is not found exactly once."""
    counts = {"directional": n_directional, "spot": n_spot, "point": n_point}
    for kind, head in _LOOPS.items():
        if text.count(head) != 1:
            raise RuntimeError(f"pyrender's mesh.frag has no single {kind}-light loop as "
                               "expected: this pyrender version is not supported by "
                               "synth.backends.shaders")
        n = int(counts[kind])
        if n < 0:
            raise ValueError(f"n_{kind} must be >= 0, got {n}")
        text = text.replace(head, f"for (int i = 0; i < {n}; i++) {{\n"
                                  f"        if (i >= n_{kind}_lights) break;")
    return text


def gather_mesh_shader(text: str) -> str:
    """pyrender's ``mesh.frag`` text with ``PCF`` replaced by the four-gather version.

    Raises RuntimeError when the text does not hold pyrender's function (another pyrender
    version): nothing is patched silently."""
    start = text.find(_PCF_HEAD)
    end = text.find(_NEXT, start)
    if start < 0 or end < 0 or not text.startswith(_VERSION):
        raise RuntimeError("pyrender's mesh.frag has no PCF function as expected: this pyrender "
                           "version is not supported by synth.backends.shaders")
    body = text[start:end]
    # the function being replaced: 3 x 3 calls of the 2 x 2 bilinear compare
    for piece in ("x=-1; x<=1", "y=-1; y<=1", "texture2DShadowLerp", "result/9.0"):
        if piece not in body:
            raise RuntimeError("pyrender's PCF differs from the one synth.backends.shaders "
                               f"replaces (no {piece!r})")
    text = text[:start] + _GATHER_PCF + text[end:]
    # textureGather is core in GLSL 4.00; 3.30 needs the extension (llvmpipe has both)
    return text.replace(_VERSION, _VERSION + "\n#extension GL_ARB_texture_gather : require", 1)


@functools.cache
def shader_dir(n_directional: int, n_spot: int, n_point: int) -> str:
    """A directory holding pyrender's shaders with ``mesh.frag`` patched for a scene with these
    numbers of lights (one per process and light counts, removed at exit, also by a forked
    render process)."""
    src = os.path.join(os.path.dirname(load().__file__), "shaders")
    with open(os.path.join(src, "mesh.frag")) as f:
        text = fixed_light_loops(gather_mesh_shader(f.read()), n_directional, n_spot, n_point)
    out = tempfile.mkdtemp(prefix="synth-shaders-")
    atexit.register(shutil.rmtree, out, ignore_errors=True)
    # a forked render process (synth.pool.pool_context) leaves by os._exit, which runs no
    # atexit functions but multiprocessing's finalizers (in the process that made the folder)
    Finalize(None, shutil.rmtree, (out,), {"ignore_errors": True}, exitpriority=0)
    for name in os.listdir(src):
        shutil.copy(os.path.join(src, name), out)
    with open(os.path.join(out, "mesh.frag"), "w") as f:
        f.write(text)
    with open(os.path.join(out, SPHERE_VERT), "w") as f:
        f.write(_SPHERE_VERT_TEXT)
    with open(os.path.join(out, SPHERE_FRAG), "w") as f:
        f.write(sphere_shader(text))
    return out


SPHERE_VERT, SPHERE_FRAG = "sphere.vert", "sphere.frag"

# one triangle covering the whole viewport (the draw is scissored to the ball's box)
_SPHERE_VERT_TEXT = """#version 330 core
void main()
{
    vec2 p = vec2(float((gl_VertexID & 1) << 2), float((gl_VertexID & 2) << 1)) - 1.0;
    gl_Position = vec4(p, 0.0, 1.0);
}
"""

_SPHERE_MAIN = """
// synth's sphere impostor: the exact sphere hit by each pixel's ray, shaded by the mesh
// shader's own main() above (renamed shade_mesh) with frag_position and frag_normal set here
uniform mat4 sphere_vp;       // world -> clip
uniform mat4 sphere_inv_vp;   // clip -> world
uniform vec4 sphere_viewport; // x0, y0, width, height (window pixels)
uniform vec2 sphere_samples[4]; // the multisample positions inside a pixel (0..1)
uniform vec3 sphere_centre;
uniform float sphere_radius;
uniform vec4 sphere_band;     // the mesh's last two rings: (sin, cos) of their polar angles

// the ray through window point w: origin at the depth of the sphere's centre, unit direction
void sphere_ray(vec2 w, float zc, out vec3 o, out vec3 d)
{
    vec2 ndc = (w - sphere_viewport.xy) / sphere_viewport.zw * 2.0 - 1.0;
    vec4 a = sphere_inv_vp * vec4(ndc, -1.0, 1.0);
    vec4 b = sphere_inv_vp * vec4(ndc, 1.0, 1.0);
    vec4 c = sphere_inv_vp * vec4(ndc, zc, 1.0);
    d = normalize(b.xyz / b.w - a.xyz / a.w);
    o = c.xyz / c.w - sphere_centre;  // relative to the centre
}

void main()
{
    vec4 cc = sphere_vp * vec4(sphere_centre, 1.0);
    float zc = cc.z / cc.w;
    float r2 = sphere_radius * sphere_radius;
    vec2 pix = floor(gl_FragCoord.xy);
    int mask = 0;
    for (int k = 0; k < 4; k++) {
        vec3 o, d;
        sphere_ray(pix + sphere_samples[k], zc, o, d);
        float b = dot(o, d);
        if (dot(o, o) - b * b < r2) mask |= 1 << k;
    }
    if (mask == 0) discard;
    gl_SampleMask[0] = mask;
    vec3 o, d;
    sphere_ray(gl_FragCoord.xy, zc, o, d);
    float b = dot(o, d);
    vec3 q = o - b * d;  // the ray's closest approach to the centre
    float h2 = r2 - dot(q, q);
    vec3 p;
    if (h2 >= 0.0) {  // the hit point
        p = q - sqrt(h2) * d;
        frag_normal = p / sphere_radius;
    } else {
        // a pixel centre off the sphere with a sample on it: the mesh's outermost band of
        // triangles (between the rings at polar angles sphere_band.xy and .zw, as (sin, cos))
        // continued past the silhouette, as the mesh's triangles are
        float rho = length(q);
        vec3 u = q / rho;
        float s = (rho / sphere_radius - sphere_band.x) / (sphere_band.z - sphere_band.x);
        vec2 sc = mix(sphere_band.xy, sphere_band.zw, s);  // (sin, cos) continued linearly
        p = rho * u - sphere_radius * sc.y * d;
        frag_normal = normalize(sc.x * u - sc.y * d);
    }
    frag_position = sphere_centre + p;
    vec4 clip = sphere_vp * vec4(frag_position, 1.0);
    gl_FragDepth = 0.5 * clip.z / clip.w + 0.5;
    shade_mesh();
}
"""


def sphere_shader(text: str) -> str:
    """The sphere impostor's fragment shader from (patched) ``mesh.frag`` text: its inputs
    ``frag_position`` and ``frag_normal`` become globals that a new ``main`` sets from the
    exact sphere the pixel's ray hits (the depth and each multisample's coverage from the
    same sphere), then runs the mesh shader's own ``main`` (renamed), so the ball is shaded by
    the very BRDF, lamp and shadow code pyrender's mesh shader uses.

    Raises RuntimeError when the text lacks what is replaced."""
    for old, new in (("in vec3 frag_position;", "vec3 frag_position;"),
                     ("in vec3 frag_normal;", "vec3 frag_normal;"),
                     ("void main()\n{", "void shade_mesh()\n{")):
        if text.count(old) != 1:
            raise RuntimeError(f"mesh.frag has no single {old!r}: this pyrender version is not "
                               "supported by synth's sphere impostor")
        text = text.replace(old, new)
    head, rest = text.split("\n", 1)
    return head + "\n#extension GL_ARB_sample_shading : require\n" + rest + _SPHERE_MAIN


def light_counts(scene) -> tuple[int, int, int]:
    """(directional, spot, point) lights of a pyrender.Scene: what the loops are bounded by."""
    return (len(scene.directional_light_nodes), len(scene.spot_light_nodes),
            len(scene.point_light_nodes))


def program_cache(counts: tuple[int, int, int]):
    """A pyrender ShaderProgramCache compiling the patched shaders for a scene with ``counts``
    (directional, spot, point) lights."""
    return load().shader_program.ShaderProgramCache(shader_dir=shader_dir(*counts))


# the spot lamps' uniforms a specialised shader holds as constants: (field, GLSL type, floats)
SPOT_FIELDS = (("color", "vec3", 3), ("intensity", "float", 1), ("position", "vec3", 3),
               ("direction", "vec3", 3), ("light_angle_scale", "float", 1),
               ("light_angle_offset", "float", 1), ("light_matrix", "mat4", 16))


def _glsl_exact(values, glsl_type: str) -> str:
    """A GLSL constant expression of exactly these float32 values (their bit patterns, so no
    decimal rounding can move them); a mat4's 16 values in column-major order."""
    bits = np.asarray(values, dtype=np.float32).ravel().view(np.uint32)
    items = ", ".join(f"uintBitsToFloat({int(b)}u)" for b in bits)
    return items if glsl_type == "float" else f"{glsl_type}({items})"


def specialised_mesh_shader(text: str, values: dict, n_spot: int) -> str:
    """(Patched) ``mesh.frag`` text with the uniforms that stay the same over a recording held
    as constants: each spot lamp's colour, intensity, position, direction, cone factors and
    shadow-camera matrix, the ambient light and the camera's position (``values``: name ->
    float32 values as the program holds them, e.g. ``"spot_lights[0].color"``, ``"cam_pos"``;
    a matrix column-major), and the lamp count's ``break`` dropped (the loop is bounded by
    ``n_spot`` already, :func:`fixed_light_loops`). The shadow maps' samplers and the material
    stay uniforms.

    The same arithmetic on the same float32 values; llvmpipe's compiler folds what depends
    only on them (the ball's draw about a quarter faster, its pixels 0 DN from the uniform
    shader's). Raises RuntimeError when the text lacks what is replaced, KeyError
    when ``values`` lacks a value."""
    if n_spot < 1:
        raise ValueError(f"a specialised shader needs spot lamps, got n_spot={n_spot}")

    def swap(old: str, new: str, count: int | None = 1) -> None:
        nonlocal text
        if count is not None and text.count(old) != count or old not in text:
            raise RuntimeError(f"mesh.frag has no {old!r} as expected: this pyrender version is "
                               "not supported by synth.backends.shaders.specialised_mesh_shader")
        text = text.replace(old, new)

    consts = []
    for field, glsl_type, n in SPOT_FIELDS:
        items = [_glsl_exact(np.asarray(values[f"spot_lights[{i}].{field}"])[:n], glsl_type)
                 for i in range(n_spot)]
        consts.append(f"const {glsl_type} SPOT_{field}[{n_spot}] = "
                      f"{glsl_type}[{n_spot}]({', '.join(items)});")
        swap(f"spot_lights[i].{field}", f"SPOT_{field}[i]", None)
    consts.append(f"const vec3 AMBIENT_LIGHT = {_glsl_exact(values['ambient_light'], 'vec3')};")
    consts.append(f"const vec3 CAM_POS = {_glsl_exact(values['cam_pos'], 'vec3')};")
    swap("uniform vec3 ambient_light;", "")
    swap("* ambient_light", "* AMBIENT_LIGHT")
    swap("uniform vec3 cam_pos;", "")
    swap("cam_pos - frag_position", "CAM_POS - frag_position", None)
    swap("if (i >= n_spot_lights) break;", "")
    swap("in vec3 frag_position;", "\n".join(consts) + "\nin vec3 frag_position;")
    return text


def specialised_values_names(n_spot: int) -> list[tuple[str, int]]:
    """The uniforms :func:`specialised_mesh_shader` holds as constants: (name, floats)."""
    return ([(f"spot_lights[{i}].{field}", n) for i in range(n_spot)
             for field, _, n in SPOT_FIELDS] + [("ambient_light", 3), ("cam_pos", 3)])
