"""synth's renderer backends: siblings behind one protocol (synth.backends.Backend) that share
the scene model and the footprint, and depend on no other backend."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from synth.backends import Backend, make_backend
from synth.backends.footprint import Footprint
from synth.backends.pathtrace import PathTracedFootprint
from synth.backends.scene_model import SceneModel
from synth.camera import CameraModel
from synth.config import SceneConfig

ROOT = Path(__file__).resolve().parents[1]
R_CYL, R_BALL = 0.0853, 0.005
CAM = CameraModel(width=320, height=112, center_px=(160.0, -540.0))
PYRENDER_ONLY = {"raster", "lean", "shaders", "gl_calls", "triangles"}
MITSUBA_ONLY = {"pathtrace", "mitsuba_runtime", "rim_path"}


def _imports(path: Path) -> set[str]:
    """The synth.backends modules a file imports (at its top or in a function)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module == "synth.backends":
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
                "synth.backends."):
            out.add(node.module.split(".")[2])
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[2] for a in node.names
                    if a.name.startswith("synth.backends.")}
    return out


def test_no_backend_depends_on_the_other():
    folder = ROOT / "synth" / "backends"
    for name in PYRENDER_ONLY:
        assert not _imports(folder / f"{name}.py") & MITSUBA_ONLY, name
    for name in MITSUBA_ONLY:
        assert not _imports(folder / f"{name}.py") & PYRENDER_ONLY, name
    for shared in ("scene_model", "footprint"):
        assert not _imports(folder / f"{shared}.py") & (PYRENDER_ONLY | MITSUBA_ONLY), shared


def test_the_pyrender_backend_has_the_protocol():
    sr = make_backend(SceneConfig(camera=CAM), R_BALL, R_CYL)
    try:
        assert isinstance(sr, Backend)
        c = np.array([[0.0, -(R_CYL - R_BALL), 0.0]])
        assert sr.tiles_for_many([c]) == [sr.tiles_for(c)]
        assert sr.render_full().shape == (CAM.height, CAM.width)
    finally:
        sr.close()


def test_the_mitsuba_backend_has_the_protocol():
    from synth.backends.mitsuba_runtime import available

    why = available()
    if why is not None:
        pytest.skip(why)
    sr = make_backend(SceneConfig(camera=CAM, renderer="mitsuba"), R_BALL, R_CYL)
    try:
        assert isinstance(sr, Backend)
    finally:
        sr.close()


@pytest.mark.parametrize("theta", [0.0, 0.1, -0.12])
def test_the_path_traced_footprint_holds_the_rasterised_one(theta):
    """Mitsuba's footprint widens the rasterised one (the lamps' penumbra, ambient
    occlusion): each of its boxes holds the rasterised box, by the margins it adds."""
    model = SceneModel.of(SceneConfig(camera=CAM), R_BALL, R_CYL)
    L = R_CYL - R_BALL
    c = np.array([[L * math.sin(theta), -L * math.cos(theta), 0.0]])
    raster, traced = Footprint(model), PathTracedFootprint(model)
    _, rad = CAM.sphere_silhouette(c, R_BALL)
    margin = model.config.mitsuba_margin * rad[0] + 1.5
    assert traced.ball_box(c) == raster.ball_box(c, margin)
    inner, outer = raster.shadow_boxes(c), traced.shadow_boxes(c)
    assert len(inner) == len(outer) == len(model.lamps)
    for a, b in zip(inner, outer, strict=True):
        assert b[0] <= a[0] and b[1] <= a[1] and b[2] >= a[2] and b[3] >= a[3]
        assert b != a  # the lamps are spheres: their penumbra widens every box
