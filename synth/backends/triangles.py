"""Which of a static draw's triangles a tile of the lean draw path (:mod:`synth.backends.lean`)
needs: each triangle's pixel box and its vertices' largest distance from each lamp, found once,
then per tile the runs of triangles that can touch it (and, for the shadowed surfaces, that
the ball can shadow). The triangles left out have no pixel in the tile's scissor box, or are
nearer a lamp than the ball, so leaving them out changes no pixel.
"""

from __future__ import annotations

import numpy as np

RUN_GAP = 64  # triangles: runs of a draw's triangles closer than this are drawn as one


def _world_triangles(pose, prim):
    """(vertices in the world frame (n, 3), triangles' vertex ids (m, 3))."""
    v = np.asarray(prim.positions, float) @ pose[:3, :3].T + pose[:3, 3]
    if prim.indices is not None:
        tri = np.asarray(prim.indices, dtype=np.int64).reshape(-1, 3)
    else:
        tri = np.arange(len(v)).reshape(-1, 3)
    return v, tri


def triangle_boxes(cam, pose, prim):
    """(n, 4) pixel boxes [x0, y0, x1, y1] of a static primitive's triangles in the frame
    (exact projections, 2 px wider), or None when it is not a triangle list or a vertex is
    not in front of the camera (then it is always drawn whole).

    Parameters
    ----------
    cam : synth.camera.CameraModel
        The camera.
    pose : numpy.ndarray
        The primitive's node's 4x4 pose.
    prim : pyrender.Primitive
        The primitive.

    Returns
    -------
    numpy.ndarray or None
    """
    if prim.mode != 4:  # GL_TRIANGLES
        return None
    v, tri = _world_triangles(pose, prim)
    if cam.projection == "perspective" and np.any(v[:, 2] > cam.camera_z - cam.znear):
        return None
    q = cam.project(v)[tri]  # (n, 3, 2)
    return np.concatenate([q.min(axis=1) - 2.0, q.max(axis=1) + 2.0], axis=1)


def triangle_far(pose, prim, lamps: np.ndarray):
    """(n, lamps) the largest distance of each triangle's vertices from each lamp (a
    triangle's farthest point from a lamp is a vertex), or None when it is not a triangle
    list: what :func:`reach` is compared with.

    Parameters
    ----------
    pose : numpy.ndarray
        The primitive's node's 4x4 pose.
    prim : pyrender.Primitive
        The primitive.
    lamps : numpy.ndarray
        (L, 3) the lamps' positions (m).

    Returns
    -------
    numpy.ndarray or None
    """
    if prim.mode != 4:
        return None
    v, tri = _world_triangles(pose, prim)
    dist = np.linalg.norm(v[:, None, :] - lamps[None, :, :], axis=2)  # (vertices, lamps)
    return dist[tri].max(axis=1)


def reach(centres, lamps: np.ndarray, ball_radius: float) -> np.ndarray:
    """Per lamp, the distance of the ball's nearest point at ``centres`` (K, 3) (a little
    less): a point nearer a lamp than that has the ball behind it, not between it and the
    lamp, so the ball cannot shadow a triangle whose vertices are all nearer.

    Parameters
    ----------
    centres : numpy.ndarray
        (K, 3) the ball's centres (m).
    lamps : numpy.ndarray
        (L, 3) the lamps' positions (m).
    ball_radius : float
        m.

    Returns
    -------
    numpy.ndarray
        (L,) distances (m).
    """
    near = np.linalg.norm(centres[:, None, :] - lamps[None, :, :], axis=2).min(axis=0)
    return near - ball_radius * (1 + 1e-6) - 1e-9


def runs(d, tile, reach=None) -> list:
    """(first triangle, count) runs of draw ``d``'s triangles that can touch ``tile``
    (x0, y0, w, h): the others have no pixel in the scissor box, so leaving them out
    changes no pixel (the drawn ones keep their order); with ``reach`` (:func:`reach`)
    only those the ball can shadow. Runs closer than RUN_GAP triangles are drawn as one.

    Parameters
    ----------
    d : dict
        The draw: its ``count`` (indices), ``boxes`` (:func:`triangle_boxes`) and ``far``
        (:func:`triangle_far`); the boxes' columns are kept in it.
    tile : tuple
        (x0, y0, w, h), px.
    reach : numpy.ndarray, optional
        :func:`reach` of the ball.

    Returns
    -------
    list of tuple
    """
    boxes = d["boxes"]
    n = d["count"] // 3
    if boxes is None:
        return [(0, n)]
    if n <= RUN_GAP:  # a few triangles (the backdrop's two): drawn whole, no pixel
        return [(0, n)]  # changes (see above), and NumPy's per-call cost is saved
    x0, y0, w, h = tile
    if "box_columns" not in d:  # x0, y0, x1, y1 each contiguous
        d["box_columns"] = [np.ascontiguousarray(boxes[:, k]) for k in range(4)]
    bx0, by0, bx1, by1 = d["box_columns"]
    m = bx0 <= x0 + w
    m &= bx1 >= x0
    m &= by0 <= y0 + h
    m &= by1 >= y0
    hit = np.flatnonzero(m)
    if reach is not None and d.get("far") is not None and hit.size:
        hit = hit[(d["far"][hit] >= reach[None, :]).any(axis=1)]
    if hit.size == 0:
        return []
    if hit.size > 16:
        cut = np.flatnonzero(np.diff(hit) > RUN_GAP)
        starts = np.concatenate([[hit[0]], hit[cut + 1]])
        ends = np.concatenate([hit[cut], [hit[-1]]]) + 1
        return list(zip(starts.tolist(), (ends - starts).tolist(), strict=True))
    runs = []  # a few triangles: the same runs without NumPy's per-call cost
    start = prev = None
    for i in hit.tolist():
        if start is None:
            start = i
        elif i - prev > RUN_GAP:
            runs.append((start, prev + 1 - start))
            start = i
        prev = i
    runs.append((start, prev + 1 - start))
    return runs
