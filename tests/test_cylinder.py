"""The trough centre from its contour: drawn contours of exactly known centre.

The contours are drawn with exact area coverage (synth.drawn.frames.disk_coverage), in linear
light, with a lighting gradient on both sides of the edge, optional blur and pixel noise: what
a camera with a linear response records of a sharp edge.
"""

import math

import cv2
import numpy as np
import pytest

from rollfric.geometry import trough as cylinder
from rollfric.geometry.trough import find_cylinder_center
from synth.drawn.frames import disk_coverage

XC, YC, R = 640.3, 380.7, 635.0


def _coverage(h, w, xc, yc, radius):
    return disk_coverage(h, w, xc, yc, radius)


def draw_trough(h=1024, w=1280, xc=XC, yc=YC, radius=R, wall=70.0, blur=0.0, noise=0.0,
                seed=0, gradient=(0.3, -0.5), encode=None):
    """A bright backdrop inside the contour circle, the trough's face (a ring ``wall`` px
    wide) outside it, grey beyond; levels in DN of 8 bit. ``gradient``: the backdrop's
    relative change per 1000 px in x and y (the face's is the opposite). ``blur``: a Gaussian
    (px) in linear light; ``encode``: a gamma the recorded values are encoded with after it."""
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    gx, gy = gradient
    rel = (xx - w / 2) / 1000.0 * gx + (yy - h / 2) / 1000.0 * gy
    inside, face = 0.7 * (1 + rel), 0.2 * (1 - rel)
    c1 = _coverage(h, w, xc, yc, radius)
    c2 = _coverage(h, w, xc, yc, radius + wall)
    img = c1 * inside + (c2 - c1) * face + (1 - c2) * 0.5
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    if encode is not None:
        img = img ** (1.0 / encode)
    img = 255.0 * img
    if noise > 0:
        img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("h, yc, blur", [(1024, YC, 0.0), (1024, YC, 1.5), (1024, 130.7, 0.0),
                                         (500, -200.3, 1.0)])
def test_centre_of_a_drawn_contour(h, yc, blur):
    """Arcs of 253, 204 and 143 degrees (the axis higher in the frame shows less of the
    circle), sharp and blurred, under a lighting gradient: the centre within 0.01 px."""
    img = draw_trough(h=h, yc=yc, blur=blur)
    c = find_cylinder_center(img, radius_px=R)
    assert math.hypot(c.center[0] - XC, c.center[1] - yc) < 0.01
    assert c.radius == pytest.approx(R, abs=0.03)
    # a linear edge: its definitions agree, the Type B part is negligible
    assert max(c.center_u_edge) < 0.003
    assert c.center_u == pytest.approx(np.hypot(c.center_u_fit, c.center_u_edge))


def test_the_provisional_circle_is_not_inherited(monkeypatch):
    """The sub-pixel edges are measured in windows re-centred on each edge: a provisional
    circle (RANSAC on whole-pixel edges) 1 px off moves the centre by < 0.003 px. (Windows
    centred on the provisional circle, as rows were before, kept ~9 % of its error.)"""
    img = draw_trough(blur=1.5)
    for dy in (-1.0, 1.0):
        monkeypatch.setattr(cylinder, "_ransac_circle", lambda *a, dy=dy, **k: (XC, YC + dy, R))
        c = find_cylinder_center(img, radius_px=R)
        assert math.hypot(c.center[0] - XC, c.center[1] - YC) < 0.003


def test_centre_uncertainty_covers_the_scatter_of_noisy_backgrounds():
    """8 noise draws (3 DN rms, about a realistic sensor's): the errors scatter as the fit's
    uncertainty says (z rms within 0.4 .. 1.6), and no draw is off by more than 3 u."""
    z = []
    for seed in range(8):
        c = find_cylinder_center(draw_trough(blur=0.7, noise=3.0, seed=seed), radius_px=R)
        err = np.array(c.center) - (XC, YC)
        assert np.all(np.abs(err) < 3 * np.array(c.center_u))
        z.extend(err / np.array(c.center_u))
    assert 0.4 < math.sqrt(np.mean(np.square(z))) < 1.6


def test_a_saturated_edge_is_flagged():
    """A backdrop brighter than the sensor's range clips the bright side of the step: its
    edge points then move with the local contrast (here the centre is 0.3-0.7 px off, which no
    fit can tell from a centre shift when the contrast varies from top to bottom). The contour
    says so; its edge definitions disagree (Type B > 0.01 px) without covering it."""
    yy, xx = np.mgrid[0:1024, 0:1280].astype(float)
    rel = (xx - 640) / 1000.0 * 0.3 - (yy - 512) / 1000.0 * 0.5
    c1 = _coverage(1024, 1280, XC, YC, R)
    c2 = _coverage(1024, 1280, XC, YC, R + 70)
    img = c1 * 1.2 * (1 + rel) + (c2 - c1) * 0.2 * (1 - rel) + (1 - c2) * 0.5
    img = np.clip(np.rint(255 * cv2.GaussianBlur(img, (0, 0), 1.0)), 0, 255).astype(np.uint8)
    c = find_cylinder_center(img, radius_px=R)
    assert c.saturated_fraction > 0.5 and c.center_u_edge[1] > 0.01
    assert find_cylinder_center(draw_trough(), radius_px=R).saturated_fraction == 0.0


def _ransac_one_at_a_time(xs, ys, r_expected, rng, iters=400, tol=2.0):
    """The RANSAC circle as a loop, one candidate drawn and scored at a time (the code before
    the candidates were scored together, 2026-11-23)."""
    n = len(xs)
    best = (-1.0, None)
    for _ in range(iters):
        i, j, k = rng.choice(n, 3, replace=False)
        ax, ay, bx, by, cx_, cy_ = xs[i], ys[i], xs[j], ys[j], xs[k], ys[k]
        d = 2 * (ax * (by - cy_) + bx * (cy_ - ay) + cx_ * (ay - by))
        if abs(d) < 1e-9:
            continue
        ux = ((ax * ax + ay * ay) * (by - cy_) + (bx * bx + by * by) * (cy_ - ay)
              + (cx_ * cx_ + cy_ * cy_) * (ay - by)) / d
        uy = ((ax * ax + ay * ay) * (cx_ - bx) + (bx * bx + by * by) * (ax - cx_)
              + (cx_ * cx_ + cy_ * cy_) * (bx - ax)) / d
        r = math.hypot(ax - ux, ay - uy)
        if r_expected is not None:
            if abs(r - r_expected) > 0.3 * r_expected:
                continue
            prior = math.exp(-0.5 * ((r - r_expected) / (0.05 * r_expected)) ** 2)
        else:
            prior = 1.0
        inl = np.abs(np.hypot(xs - ux, ys - uy) - r) < tol
        score = inl.sum() * prior
        if score > best[0]:
            best = (score, (ux, uy, r))
    return best[1]


@pytest.mark.parametrize("seed", range(6))
def test_ransac_scored_together_is_the_loop_one_at_a_time(seed):
    rng = np.random.default_rng(100 + seed)
    # two concentric contours (a thick line's sides), a second circle, scattered edges, and
    # collinear points (no circle through them)
    a = rng.uniform(0.3, 2.8, 1500)
    pts = [np.c_[XC + R * np.sin(a), YC + R * np.cos(a)] + rng.normal(0, 0.7, (1500, 2)),
           np.c_[XC + (R + 3) * np.sin(a[:400]), YC + (R + 3) * np.cos(a[:400])],
           np.c_[300 + 90 * np.sin(a[:300]), 200 + 90 * np.cos(a[:300])],
           rng.uniform(0, 1280, (500, 2)), np.c_[np.arange(40.0), np.full(40, 5.0)]]
    xy = np.round(np.concatenate(pts), 0 if seed % 2 else 3)  # pixel centres, or not
    xs, ys = xy[:, 0], xy[:, 1]
    for r_expected in (R, None, 90.0):
        loop = _ransac_one_at_a_time(xs, ys, r_expected, np.random.default_rng(seed))
        rng_now = np.random.default_rng(seed)
        now = cylinder._ransac_circle(xs, ys, r_expected, rng_now)
        assert now == loop  # to the bit
        after = np.random.default_rng(seed)
        _ransac_one_at_a_time(xs, ys, r_expected, after)
        assert rng_now.bit_generator.state == after.bit_generator.state  # the same draws
