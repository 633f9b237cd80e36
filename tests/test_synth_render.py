"""Rendered pixels against the exact truth, and tile renders against full-frame renders.

Small frames: crops of the thesis scene at its true scale (0.1343 mm/px), the camera's
centre_px placed so the trough bottom is in view.
"""

import dataclasses
import math

import numpy as np
import pytest

from synth.backends.raster import SceneRenderer
from synth.backends.scene_model import view_sphere
from synth.camera import CameraModel
from synth.config import SceneConfig

R_CYL = 0.0853
R_BALL = 0.005
L = R_CYL - R_BALL


def _centre(theta, z=0.0):
    return np.array([L * math.sin(theta), -L * math.cos(theta), z])


def _silhouette_renderer(camera, ss=2):
    sr = SceneRenderer(SceneConfig(camera=camera, supersample=ss), R_BALL, R_CYL)
    sr.silhouette_mode()
    return sr


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_rendered_ball_centroid_and_radius_match_truth(projection):
    # perspective at a short working distance, ball far off the axis: the silhouette centre
    # and the projected sphere centre differ by ~0.2 px, so the test can tell them apart
    theta = 0.6 if projection == "perspective" else 0.3
    c = _centre(theta)
    cam0 = CameraModel(projection=projection, working_distance=0.25)
    u, v = cam0.project(c)
    cam = CameraModel(width=128, height=112, projection=projection, working_distance=0.25,
                      center_px=(640.0 - (u - 64.3), 380.0 - (v - 55.6)))
    sr = _silhouette_renderer(cam)
    try:
        sr.set_ball(sr.ball_pose(c))
        img = sr.render_full().astype(float) / sr.scale  # coverage in [0, 1]
    finally:
        sr.close()
    yy, xx = np.mgrid[0:cam.height, 0:cam.width]
    area = img.sum()
    cx, cy = (img * xx).sum() / area, (img * yy).sum() / area
    sil, r_px = cam.sphere_silhouette(c[None], R_BALL)
    proj = cam.project(c)
    assert abs(cx - sil[0, 0]) < 0.01 and abs(cy - sil[0, 1]) < 0.01, (cx, cy, sil)
    assert math.sqrt(area / math.pi) == pytest.approx(r_px[0], abs=0.01)
    if projection == "perspective":
        assert np.hypot(cx - proj[0], cy - proj[1]) > 0.1  # the two centres really differ


def test_cylinder_centre_is_the_centre_of_the_bore():
    """A full ring trough in perspective: the backdrop seen through the bore is a disk whose
    centroid is the cylinder centre of the truth."""
    from synth_frames import flat_ring_render

    cam = CameraModel(width=192, height=160, pixel_size=1.2e-3, projection="perspective",
                      working_distance=0.4, center_px=(97.3, 80.6))
    img, cfg = flat_ring_render(cam, R_BALL, R_CYL)
    yy, xx = np.mgrid[0:cam.height, 0:cam.width]
    rho = np.hypot(xx - 97.3, yy - 80.6)
    hole = R_CYL * 0.4 / (0.4 + cfg.trough_length / 2) / 1.2e-3  # far end of the bore, px
    assert img[rho < hole - 2].min() > 0.8 and img[(rho > hole + 2) & (rho < hole + 8)].max() < 0.3
    w = img * (rho < hole + 5)
    assert (w * xx).sum() / w.sum() == pytest.approx(97.3, abs=0.01)
    assert (w * yy).sum() / w.sum() == pytest.approx(80.6, abs=0.01)


@pytest.mark.parametrize("projection,lighting", [("orthographic", "thesis"),
                                                 ("perspective", "thesis"),
                                                 ("orthographic", "harsh")])
def test_tiles_equal_full_frame_render(projection, lighting):
    from synth.config import lighting_preset

    if lighting == "harsh":
        # one low lamp far right: the shadow lands left of the trough's outer edge; a coarser
        # pixel covers ball and shadow in a small frame
        cam = CameraModel(width=320, height=224, pixel_size=0.4e-3, center_px=(300.0, -100.0))
        thetas = (-0.5, -0.35, -0.2)
    else:
        cam = CameraModel(width=256, height=192, projection=projection, working_distance=0.6,
                          center_px=(128.0, -470.0))
        thetas = (-0.03, 0.04, 0.02)
    cfg = SceneConfig(camera=cam, lighting=lighting_preset(lighting))
    sr = SceneRenderer(cfg, R_BALL, R_CYL)
    try:
        bg = sr.render_full()
        # tiles of consecutive frames first (the shadow maps are updated incrementally), then
        # the plain full-frame renders they must equal; some tiles are merged from the ball's
        # box and a shadow's
        composites, merged = [], []
        for theta in thetas:
            c = _centre(theta)
            tiles = sr.tiles_for(c[None])
            boxes = [sr.ball_box(c[None]), *sr.shadow_boxes(c[None])]
            in_frame = [b for b in boxes if min(b[2], cam.width) > max(b[0], 0)
                        and min(b[3], cam.height) > max(b[1], 0)]
            merged.append(len(tiles) < len(in_frame))
            comp = bg.copy()
            imgs = sr.render_tiles([sr.ball_pose(c)], tiles)
            for (x0, y0, w, h), img in zip(tiles, imgs, strict=True):
                comp[y0:y0 + h, x0:x0 + w] = img
            composites.append(comp)
        worst, shadow_checked = 0, False
        for k, theta in enumerate(thetas):
            c = _centre(theta)
            sr.set_ball(sr.ball_pose(c))
            full = sr.render_full()
            sr.set_ball(None)
            diff = np.abs(composites[k].astype(int) - full.astype(int)) / (sr.scale / 255)
            worst = max(worst, diff.max())
            # pixels the ball changed outside its own box: its shadows, which the tiles held
            changed = np.argwhere(full != bg)
            x0, y0, x1, y1 = sr.ball_box(c[None])
            outside = ~((changed[:, 1] >= x0) & (changed[:, 1] < x1)
                        & (changed[:, 0] >= y0) & (changed[:, 0] < y1))
            shadow_checked |= outside.sum() > 50
    finally:
        sr.close()
    assert worst <= 1.0, worst
    assert shadow_checked, "no shadow in view: the test would not check the shadow tiles"
    assert any(merged), "no merged tile: the test would not check merging"


@pytest.mark.parametrize("case", ["thesis", "perspective", "harsh", "tilted", "blur"])
def test_footprints_of_a_batch_equal_frame_by_frame(case):
    """tiles_for_many (a render process's batch: the shadows' rays of all its frames followed
    together) gives each frame the tiles, ball box and shadow boxes that tiles_for of that
    frame alone gives, and the lean path finds them by the frame's centres."""
    from synth.config import lighting_preset

    cam = CameraModel()
    lighting = "harsh" if case == "harsh" else "thesis"
    if case == "perspective":
        cam = dataclasses.replace(cam, projection="perspective")
    if case == "tilted":
        cam = dataclasses.replace(cam, yaw=0.02, pitch=-0.015, roll=0.01)
    cfg = SceneConfig(camera=cam, lighting=lighting_preset(lighting))
    k = 3 if case == "blur" else 1
    thetas = np.linspace(-0.45, 0.45, 40 * k).reshape(40, k)
    frames = [np.array([_centre(t, z=0.001 * t) for t in row]) for row in thetas]
    batch, single = SceneRenderer(cfg, R_BALL, R_CYL), SceneRenderer(cfg, R_BALL, R_CYL)
    got = batch.tiles_for_many(frames[:16]) + batch.tiles_for_many(frames[16:])
    for c, tiles in zip(frames, got, strict=True):
        assert tiles == single.tiles_for(c)
        assert batch.footprint(c) == (tuple(tiles), single.ball_box(c),
                                      tuple(single.shadow_boxes(c)))
    assert sum(len(batch.footprint(c)[2]) for c in frames) >= 40  # shadows were checked
    assert batch.footprint(frames[0] + 1e-9) is None


@pytest.mark.parametrize("ss", [1, 2])
def test_reduce_sums_channels_and_supersamples_exactly(ss):
    """The read-back's sum over channels (and supersamples) equals NumPy's plain sum, values
    and dtype, on a flipped RGBA view as read_region gives it."""
    rng = np.random.default_rng(5)
    raw = rng.integers(0, 256, (9 * ss, 10 * ss, 4), dtype=np.uint8)
    raw[0, 0, :3] = 255
    color = raw[::-1, :, :3]
    sr = SceneRenderer(SceneConfig(camera=CameraModel(width=10, height=9), supersample=ss),
                       R_BALL, R_CYL)
    want = color.astype(np.uint32).sum(axis=2)
    want = want.reshape(9, ss, 10, ss).sum(axis=(1, 3))
    got = sr._reduce(color)
    assert got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)


def test_motion_blur_subframes_average():
    """Two sub-frames at the same pose equal twice the single render."""
    cam = CameraModel(width=96, height=80, center_px=(48.0, -560.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        pose = sr.ball_pose(_centre(0.0))
        tiles = [(0, 0, 96, 80)]
        one = sr.render_tiles([pose], tiles)[0]
        two = sr.render_tiles([pose, pose], tiles)[0]
    finally:
        sr.close()
    np.testing.assert_array_equal(two, 2 * one)


def test_scene_config_round_trip():
    cfg = SceneConfig(camera=dataclasses.replace(CameraModel(), projection="perspective"),
                      supersample=2, motion_blur=4)
    assert SceneConfig.from_dict(cfg.to_dict()) == cfg


def test_view_sphere_is_a_closed_sphere_with_a_fine_silhouette():
    for sil in (math.pi / 2, math.acos(R_BALL / 0.25)):
        mesh = view_sphere(R_BALL, sil)
        assert mesh.is_watertight and mesh.is_winding_consistent
        np.testing.assert_allclose(np.linalg.norm(mesh.vertices, axis=1), R_BALL, rtol=1e-12)
        assert mesh.volume == pytest.approx(4 / 3 * math.pi * R_BALL ** 3, rel=0.02)
        assert len(mesh.faces) < 3000
        # the silhouette ring: 512 vertices at the polar angle the camera sees as the edge
        z = mesh.vertices[:, 2] / R_BALL
        assert np.sum(np.abs(z - math.cos(sil)) < 1e-12) == 512


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_lean_draw_path_equals_pyrenders(projection):
    """synth.backends.lean's tiles are pyrender's path's tiles bit for bit: over consecutive frames
    (incremental shadow maps), with sub-frames, alternating with pyrender's path frame by frame
    and after pyrender drew a full frame with the same programs (the lean path sets its
    uniforms again)."""
    cam = CameraModel(width=256, height=192, projection=projection, working_distance=0.6,
                      center_px=(128.0, -470.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        frames = []
        for theta in np.linspace(-0.04, 0.04, 7):
            cs = np.array([_centre(theta), _centre(theta + 0.003)])
            frames.append(([sr.ball_pose(c) for c in cs], sr.tiles_for(cs)))
        ref = [sr.render_tiles(poses, tiles, draw="pyrender") for poses, tiles in frames]
        assert sr._lean is None
        sr.render_tiles(*frames[0])  # pyrender's path, then the lean path is built
        assert sr._lean is not None
        for k, (poses, tiles) in enumerate(frames):
            for x, y in zip(sr.render_tiles(poses, tiles), ref[k], strict=True):
                np.testing.assert_array_equal(x, y)
            if k == 3:
                sr.render_full()
        for k in (5, 2, 6):  # alternating with pyrender's path
            for x, y in zip(sr.render_tiles(*frames[k]), ref[k], strict=True):
                np.testing.assert_array_equal(x, y)
            for x, y in zip(sr.render_tiles(*frames[k], draw="pyrender"), ref[k], strict=True):
                np.testing.assert_array_equal(x, y)
    finally:
        sr.close()


def test_lean_static_layer_follows_a_changed_scene():
    """The lean path keeps the scene without the ball as a layer drawn once; when the static
    scene changes (here the backdrop's colour, then a lamp's intensity) the layer is drawn again:
    its tiles stay pyrender's path's bit for bit."""
    cam = CameraModel(width=160, height=128, center_px=(80.0, -520.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        c = _centre(0.01)
        pose, tiles = sr.ball_pose(c), sr.tiles_for(c[None])
        sr.render_tiles([pose], tiles)  # pyrender's path; the lean path is built
        first = sr.render_tiles([pose], tiles)
        lamp = next(iter(sr.scene.light_nodes))
        for change in ("backdrop", "lamp"):
            if change == "backdrop":
                sr._backdrop_mesh.primitives[0].material.baseColorFactor = [0.5, 0.5, 0.5, 1.0]
            else:
                lamp.light.intensity *= 1.5
            ref = sr.render_tiles([pose], tiles, draw="pyrender")
            got = sr.render_tiles([pose], tiles)
            for x, y in zip(got, ref, strict=True):
                np.testing.assert_array_equal(x, y)
            assert any(np.any(x != y) for x, y in zip(got, first, strict=True)), change
            first = got
    finally:
        sr.close()


def test_lean_draw_falls_back_to_pyrender_for_what_it_does_not_draw():
    from synth.backends.lean import unsupported

    cam = CameraModel(width=96, height=80, center_px=(48.0, -560.0))
    sr = _silhouette_renderer(cam, ss=1)
    try:
        assert "flags" in unsupported(sr)
        c = _centre(0.0)
        tiles = sr.tiles_for(c[None])
        img = sr.render_tiles([sr.ball_pose(c)], tiles)[0]
        assert sr._lean is None and img.max() == sr.scale  # drawn, by pyrender's path
    finally:
        sr.close()


@pytest.mark.parametrize("projection,lighting", [("orthographic", "thesis"),
                                                 ("perspective", "thesis"),
                                                 ("orthographic", "harsh")])
def test_sphere_impostor_is_the_mesh_ball_within_its_faceting(projection, lighting):
    """``ball_model = "sphere"``: the lean path draws the ball as the exact sphere (each
    pixel's ray intersected, each multisample's coverage from the same sphere, shaded by the
    mesh shader's own code). Against stock pyrender's mesh ball: everything but the ball the
    same (<= 1 DN); on the ball the mesh's faceting shows only in the lamps' highlights (a few
    DN on a few pixels: the mesh interpolates its normals over flat triangles); on the outline
    a multisample flips where the 512-gon, snapped to llvmpipe's sub-pixel grid, and the
    circle part (a few thousandths of a pixel). The first tile frame (drawn through pyrender's
    path to build the lean one) is the sphere too."""
    from synth.config import lighting_preset

    cam = CameraModel(width=256, height=192, projection=projection, working_distance=0.6,
                      center_px=(128.0, -470.0))
    thetas = (-0.03, 0.01, 0.04)
    if lighting == "harsh":
        cam = CameraModel(width=256, height=192, center_px=(300.0, -440.0))
        thetas = (-0.5, -0.45, -0.4)
    cfg = SceneConfig(camera=cam, lighting=lighting_preset(lighting), ball_model="sphere")
    sr = SceneRenderer(cfg, R_BALL, R_CYL)
    r_px = R_BALL / cam.pixel_size
    try:
        first = None
        stats = []
        for theta in thetas:
            c = _centre(theta)
            tiles = sr.tiles_for(c[None])
            imgs = sr.render_tiles([sr.ball_pose(c)], tiles)
            if first is None:
                first = (c, tiles, imgs)
            sr.set_ball(sr.ball_pose(c))
            full = sr.render_full(stock_shaders=True)
            sr.set_ball(None)
            cx, cy = cam.project(c[None])[0]
            for (x0, y0, w, h), img in zip(tiles, imgs, strict=True):
                d = np.abs(img.astype(int) - full[y0:y0 + h, x0:x0 + w].astype(int)) / 3
                yy, xx = np.mgrid[y0:y0 + h, x0:x0 + w]
                rho = np.hypot(xx - cx, yy - cy)
                off = rho > r_px + 1.0
                edge = np.abs(rho - r_px) <= 1.0
                inner = rho < r_px - 1.0
                stats.append((d[off].max(initial=0), d[inner].max(initial=0),
                              int((d[inner] > 1).sum()), int(inner.sum()),
                              int((d[edge] > 1).sum())))
        c, tiles, imgs = first
        again = sr.render_tiles([sr.ball_pose(c)], tiles)
        for x, y in zip(imgs, again, strict=True):
            np.testing.assert_array_equal(x, y)
    finally:
        sr.close()
    s = np.array(stats)  # measured (2026-11-23): 0 / 1-3 / 0-12 px / 0-2 px; harsh: 5-7 DN
    assert s[:, 0].max() <= 1.0, s  # the scene around the ball: the same
    assert s[:, 1].max() <= 10.0, s  # the highlights
    assert s[:, 2].sum() <= 0.01 * s[:, 3].sum(), s  # < 1 % of the ball's pixels > 1 DN
    assert s[:, 4].max() <= 3, s  # a few outline pixels a frame
    assert s[:, 3].sum() > 0


def test_lean_shadowed_surfaces_leave_out_what_the_ball_cannot_shadow():
    """In the boxes of the ball's shadows the lean path draws again only the static triangles
    the ball can shadow (a triangle nearer every lamp than the ball's nearest point has the
    ball behind it): the trough's front face, between the lamps and the ball plane, is left to
    the static layer; the back face and the backdrop are drawn. The pixels stay pyrender's
    (test_lean_draw_path_equals_pyrenders, test_tiles_equal_full_frame_render)."""
    cam = CameraModel(width=256, height=192, center_px=(128.0, -470.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        c = _centre(0.02)
        tiles = sr.tiles_for(c[None])
        sr.render_tiles([sr.ball_pose(c)], tiles)
        sr.render_tiles([sr.ball_pose(c)], tiles)
        ld = sr._lean
        reach = ld._reach(c[None])
        half = SceneConfig().trough_length / 2
        full_frame = (0, 0, cam.width, cam.height)
        counted = {"front": [0, 0], "other": [0, 0]}
        for d in ld.static_draws:
            if d["far"] is None:
                continue
            prim = d["prim"]
            pose = sr.scene.get_pose(d["node"])
            v = np.asarray(prim.positions, float) @ pose[:3, :3].T + pose[:3, 3]
            tri = (np.arange(len(v)) if prim.indices is None
                   else np.asarray(prim.indices, dtype=np.int64)).reshape(-1, 3)
            z = v[tri][:, :, 2]
            front = np.all(np.abs(z - half) < 1e-6, axis=1)
            for k, r in enumerate((None, reach)):
                drawn = np.zeros(len(front), bool)
                for a, n in ld._runs(d, full_frame, r):
                    drawn[a:a + n] = True
                counted["front"][k] += int((drawn & front).sum())
                counted["other"][k] += int((drawn & ~front).sum())
    finally:
        sr.close()
    assert counted["front"][0] > 100 and counted["front"][1] == 0, counted
    assert counted["other"][1] == counted["other"][0], counted


def test_disjoint_boxes_cover_the_union_once():
    """disjoint_boxes: the same pixels as the boxes' union, none in two boxes."""
    from synth.backends.footprint import disjoint_boxes

    rng = np.random.default_rng(3)
    cases = [[(0, 0, 10, 10), (5, 5, 15, 15)], [(0, 0, 10, 10), (2, 2, 4, 4)],
             [(2, 2, 4, 4), (0, 0, 10, 10)], [(0, 0, 4, 4), (4, 0, 8, 4)], []]
    for _ in range(50):
        a = rng.integers(0, 30, (3, 2))
        b = a + rng.integers(1, 20, (3, 2))
        cases.append([(int(p[0]), int(p[1]), int(q[0]), int(q[1]))
                      for p, q in zip(a, b, strict=True)])
    for boxes in cases:
        want = np.zeros((60, 60), int)
        for x0, y0, x1, y1 in boxes:
            want[y0:y1, x0:x1] = 1
        got = np.zeros((60, 60), int)
        for x0, y0, x1, y1 in disjoint_boxes(boxes):
            assert x1 > x0 and y1 > y0
            got[y0:y1, x0:x1] += 1
        np.testing.assert_array_equal(got, want)
    assert disjoint_boxes([(0, 0, 4, 4), (4, 0, 8, 4)]) == [(0, 0, 4, 4), (4, 0, 8, 4)]


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_lean_shadowed_surfaces_drawn_once_where_shadow_boxes_overlap(projection):
    """The static surfaces drawn again in the union of the shadows' boxes (cut into boxes that
    do not overlap) give the tiles of drawing them in each box, twice where two boxes overlap,
    bit for bit over consecutive frames (in perspective the two lamps' boxes overlap)."""
    cam = CameraModel(width=256, height=192, projection=projection, working_distance=0.6,
                      center_px=(128.0, -470.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        frames, overlaps = [], 0
        for theta in np.linspace(-0.04, 0.04, 7):
            c = _centre(theta)
            frames.append(([sr.ball_pose(c)], sr.tiles_for(c[None])))
            boxes = sr.shadow_boxes(c[None])
            overlaps += any(max(a[0], b[0]) < min(a[2], b[2]) and max(a[1], b[1]) < min(a[3], b[3])
                            for i, a in enumerate(boxes) for b in boxes[i + 1:])
        sr.render_tiles(*frames[0])  # pyrender's path; the lean path is built
        got = {}
        for flag in (False, True, False):
            sr._lean.disjoint = flag
            got[flag] = [sr.render_tiles(*f) for f in frames]
        for a, b in zip(got[False], got[True], strict=True):
            for x, y in zip(a, b, strict=True):
                np.testing.assert_array_equal(x, y)
    finally:
        sr.close()
    if projection == "perspective":
        assert overlaps >= 3, overlaps  # the test checks overlapping boxes


def test_lean_uniforms_set_only_when_they_change_give_the_same_tiles():
    """The lean path sets a program's model matrix and material uniforms only when they
    differ from what it set last (LeanDraw.keep_uniforms): the same tiles bit for bit as
    setting them for every draw, over consecutive frames and after pyrender drew with the
    same programs in between (a full frame, pyrender's tile path), which sets them its own
    way."""
    cam = CameraModel(width=256, height=192, center_px=(128.0, -470.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        frames = []
        for theta in np.linspace(-0.04, 0.04, 7):
            c = _centre(theta)
            frames.append(([sr.ball_pose(c)], sr.tiles_for(c[None])))
        sr.render_tiles(*frames[0])  # pyrender's path; the lean path is built
        got = {}
        for flag in (False, True):
            sr._lean.keep_uniforms, sr._lean.ready = flag, False
            got[flag] = []
            for k, f in enumerate(frames):
                got[flag].append(sr.render_tiles(*f))
                if k == 2:
                    sr.render_full()
                if k == 4:
                    sr.render_tiles(*frames[1], draw="pyrender")
            assert sr._lean._held or not flag  # the values it set were kept
        for a, b in zip(got[False], got[True], strict=True):
            for x, y in zip(a, b, strict=True):
                np.testing.assert_array_equal(x, y)
    finally:
        sr.close()


def _runs_reference(d, tile, reach=None):
    """LeanDraw._runs as first written (the triangles' boxes tested column by column, the runs
    cut by NumPy): what the faster one must give."""
    boxes, n = d["boxes"], d["count"] // 3
    if boxes is None:
        return [(0, n)]
    x0, y0, w, h = tile
    hit = np.flatnonzero((boxes[:, 0] <= x0 + w) & (boxes[:, 2] >= x0)
                         & (boxes[:, 1] <= y0 + h) & (boxes[:, 3] >= y0))
    if reach is not None and d.get("far") is not None and hit.size:
        hit = hit[(d["far"][hit] >= reach[None, :]).any(axis=1)]
    if hit.size == 0:
        return []
    cut = np.flatnonzero(np.diff(hit) > 64)
    starts = np.concatenate([[hit[0]], hit[cut + 1]])
    ends = np.concatenate([hit[cut], [hit[-1]]]) + 1
    return list(zip(starts.tolist(), (ends - starts).tolist(), strict=True))


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_lean_triangle_runs_equal_the_reference(projection):
    """LeanDraw._runs gives the runs of the reference (column tests, NumPy's cuts) for the
    shadows' boxes and random boxes, with and without the ball's reach; a draw of a few
    triangles (the backdrop's two) is drawn whole."""
    from synth.backends.triangles import RUN_GAP

    cam = CameraModel(width=256, height=192, projection=projection, working_distance=0.6,
                      center_px=(128.0, -470.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    rng = np.random.default_rng(11)
    try:
        c = _centre(0.0)
        sr.render_tiles([sr.ball_pose(c)], sr.tiles_for(c[None]))
        sr.render_tiles([sr.ball_pose(c)], sr.tiles_for(c[None]))
        ld = sr._lean
        checked = 0
        for theta in np.linspace(-0.05, 0.05, 9):
            c = _centre(theta)[None]
            reach = ld._reach(c)
            parts = [(b[0], b[1], b[2] - b[0], b[3] - b[1]) for b in sr.shadow_boxes(c)]
            parts += [tuple(int(v) for v in (rng.integers(-20, 250), rng.integers(-20, 190),
                                             rng.integers(1, 200), rng.integers(1, 200)))
                      for _ in range(4)]
            for part in parts:
                for r in (reach, None):
                    for d in ld.static_draws:
                        got = ld._runs(d, part, r)
                        if d["boxes"] is not None and d["count"] // 3 <= RUN_GAP:
                            assert got == [(0, d["count"] // 3)]
                        else:
                            assert got == _runs_reference(d, part, r)
                            checked += bool(got)
    finally:
        sr.close()
    assert checked > 50, checked


def _pyrender_bounds(scene):
    """pyrender's Scene.bounds computed afresh (its own code, on a shallow copy of the scene:
    the scene's own bounds are left as they are)."""
    import copy

    fresh = copy.copy(scene)
    fresh._bounds = None
    return fresh.bounds


def test_scene_bounds_kept_while_the_ball_moves_equal_pyrenders():
    cam = CameraModel(width=160, height=120, center_px=(80.0, -500.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    scene = sr.scene
    rng = np.random.default_rng(5)
    kept = 0
    for k, theta in enumerate(np.linspace(-1.2, 1.2, 40)):
        # far outside the trough too, so that the ball sets the bounds on some sides
        c = _centre(theta) * (1.0 if k % 3 else 3.0) + rng.normal(0, 0.002, 3)
        # the other nodes' corners are kept when nothing but the ball moved since
        kept += sr._bounds_memo is not None and sr._bounds_memo[0] is scene._bounds
        sr.set_ball(sr.ball_pose(c))
        got = scene.bounds.copy()
        assert got.tobytes() == _pyrender_bounds(scene).tobytes()
        if k == 20:  # a static node moved: pyrender's own bounds, then kept again
            node = next(n for n in scene.mesh_nodes if n is not sr._ball_node)
            pose = scene.get_pose(node).copy()
            pose[1, 3] += 0.01
            scene.set_pose(node, pose)
    assert kept >= 35, kept
    sr.close()


def test_shadow_box_equals_its_reference():
    from synth.backends.footprint import SHADOW_TEX_SZ

    cam = CameraModel(width=256, height=192, center_px=(128.0, -470.0))
    sr = SceneRenderer(SceneConfig(camera=cam), R_BALL, R_CYL)
    try:
        c = _centre(0.0)
        for _ in range(2):  # pyrender's path, then the lean one (its lamps' matrices)
            sr.render_tiles([sr.ball_pose(c)], sr.tiles_for(c[None]))
        ld = sr._lean
        mats = ld._light_mats
        assert len(mats) == 2
        rng = np.random.default_rng(3)
        for theta in np.linspace(-0.9, 0.9, 25):
            c = _centre(theta) + rng.normal(0, 0.001, 3)
            for ln, (V, P) in zip(ld.lamps, mats, strict=True):
                cv = V @ np.append(c, 1.0)
                r = 1.5 * R_BALL
                pts = np.array([[cv[0] + dx, cv[1] + dy, cv[2] + dz, 1.0]
                                for dx in (-r, r) for dy in (-r, r) for dz in (-r, r)])
                clip = pts @ P.T
                t = (clip[:, :2] / clip[:, 3:4] + 1.0) / 2.0 * SHADOW_TEX_SZ
                x0 = min(max(math.floor(t[:, 0].min()) - 4, 0), SHADOW_TEX_SZ)
                y0 = min(max(math.floor(t[:, 1].min()) - 4, 0), SHADOW_TEX_SZ)
                x1 = min(max(math.ceil(t[:, 0].max()) + 4, 0), SHADOW_TEX_SZ)
                y1 = min(max(math.ceil(t[:, 1].max()) + 4, 0), SHADOW_TEX_SZ)
                want = (x0, y0, max(x1 - x0, 1), max(y1 - y0, 1))
                assert sr._shadow_box(ld.inner, ln, ld.flags, (V, P), c) == want
    finally:
        sr.close()
