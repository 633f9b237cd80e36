"""Defocus: a thin lens's depth-dependent blur, drawn as layers at known depths.

A camera with ``f_number`` N (:class:`synth.camera.CameraModel`) has a thin lens of focal
length f (``focal_length``, default 50 mm) and aperture diameter A = f / N, focused at the
distance s from the lens (``focus_distance``; default: the working distance D, the ball's
plane). A point at distance d from the lens is imaged as a uniform disc, its circle of
confusion, of diameter on the sensor

    c = A f |d - s| / (d (s - f)),

in pixels c / p, with p the sensor's pixel pitch: p = pixel_size f / (D - f), the ball plane's
pixel scale times the thin lens's magnification at D (a 50 mm lens at 0.5 m with 0.1343 mm/px:
p = 14.9 um, a high-speed camera's pixel). The projections stay the pinhole's (the chief
rays), so the truth stays the ball centre's projection; for the orthographic camera the
depths are measured from its eye at the working distance, as for the pinhole.

The scene has four layers at known depths: the paper backdrop (``backdrop_distance`` behind
the ball's plane), the trough's bore (drawn at the ball's plane: in a pinhole's view it spans
the trough's length about it; an orthographic camera sees it edge-on), the ball (its centre's
depth) and the trough's front face (``trough_length`` / 2 in front of the ball's plane). Each
layer's light is blurred with its own anti-aliased disc (:func:`disc_kernel`) and the layers
are laid over each other from back to front, each over what lies behind it with its blurred
coverage (premultiplied "over": a near layer's blurred edge lets the blurred far layers show
through; the backdrop hidden behind the trough is filled from its visible neighbourhood by a
normalised blur). The trough's coverage comes from one flat render of its bore and its faces
(:meth:`synth.backends.raster.SceneRenderer.layer_coverage`), the ball's from its exact
silhouette. A pixel on a layer's edge gives its light to the layers in proportion to their
coverage of it.

The background is blurred once, full frame; each frame's tiles are rendered larger by the
blur's reach (:attr:`Defocus.margin`) on every side, composited, and cut back, so that every
pixel that the ball and its shadows change is the full frame's composite.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from synth.backends.footprint import merge_boxes

OVERSAMPLE = 16  # sub-pixel samples per axis of the disc kernel's pixel coverage
DEFAULT_FOCAL_LENGTH = 0.05  # m: CameraModel.focal_length's default


def coc_sensor(depth, *, f_number: float, focus_distance: float, focal_length: float):
    """The circle of confusion's diameter on the sensor of a thin lens.

    Parameters
    ----------
    depth : float or array_like
        Distance d of the point from the lens (m).
    f_number : float
        N: the aperture diameter is A = focal_length / N.
    focus_distance : float
        s: the distance in focus (m).
    focal_length : float
        f (m).

    Returns
    -------
    float or numpy.ndarray
        c = A f |d - s| / (d (s - f)) (m).
    """
    d = np.asarray(depth, dtype=float)
    a = focal_length / f_number
    c = a * focal_length * np.abs(d - focus_distance) / (d * (focus_distance - focal_length))
    return float(c) if c.ndim == 0 else c


def pixel_pitch(camera) -> float:
    """The sensor's pixel pitch (m) of a thin-lens camera: pixel_size f / (D - f)."""
    f = camera.focal_length
    return camera.pixel_size * f / (camera.working_distance - f)


def focus_of(camera) -> float:
    """The distance in focus (m): ``focus_distance``, else the working distance."""
    return camera.working_distance if camera.focus_distance is None else camera.focus_distance


def coc_px(camera, z) -> float | np.ndarray:
    """The circle of confusion's diameter (px) of points at world depth ``z`` (m, towards the
    camera; the ball's plane is z = 0, at distance ``working_distance`` from the lens).

    Parameters
    ----------
    camera : synth.camera.CameraModel
        A camera with ``f_number``.
    z : float or array_like
        World z of the points (m).

    Returns
    -------
    float or numpy.ndarray
    """
    c = coc_sensor(camera.working_distance - np.asarray(z, dtype=float),
                   f_number=camera.f_number, focus_distance=focus_of(camera),
                   focal_length=camera.focal_length)
    return c / pixel_pitch(camera)


@functools.lru_cache(maxsize=256)
def _disc(diameter_q: int) -> np.ndarray:
    rho = diameter_q / 2000.0
    half = int(math.ceil(rho + 0.5))
    n = 2 * half + 1
    sub = (np.arange(n * OVERSAMPLE) + 0.5) / OVERSAMPLE - 0.5 - half  # sample positions
    inside = (sub[:, None] ** 2 + sub[None, :] ** 2) <= rho * rho
    k = inside.reshape(n, OVERSAMPLE, n, OVERSAMPLE).sum(axis=(1, 3)).astype(np.float64)
    total = k.sum()
    if total == 0:  # smaller than the sample spacing: a point
        return np.ones((1, 1))
    k /= total
    # trim all-zero outer rings
    while k.shape[0] > 1 and not k[0].any() and not k[:, 0].any():
        k = k[1:-1, 1:-1]
    k.setflags(write=False)
    return k


def disc_kernel(diameter_px: float) -> np.ndarray:
    """A uniform disc of ``diameter_px``, anti-aliased: each pixel's weight is the fraction of
    its square inside the disc (OVERSAMPLE^2 samples), the weights sum to 1; odd square, the
    disc centred on its middle pixel. A disc smaller than the samples' spacing is a point
    (the 1 x 1 kernel [[1]]).

    Parameters
    ----------
    diameter_px : float
        The disc's diameter (px), >= 0 (rounded to 0.001 px).

    Returns
    -------
    numpy.ndarray
        Read-only float64 kernel.
    """
    if not math.isfinite(diameter_px) or diameter_px < 0:
        raise ValueError(f"disc diameter must be >= 0 px, got {diameter_px!r}")
    return _disc(int(round(diameter_px * 1000)))


def _blur(x: np.ndarray, k: np.ndarray) -> np.ndarray:
    if k.shape == (1, 1):
        return x
    import cv2

    return cv2.filter2D(x, cv2.CV_64F, k, borderType=cv2.BORDER_REPLICATE)


@dataclasses.dataclass(frozen=True)
class Layers:
    """The depths (world z, m) of the scene's layers."""

    backdrop: float
    bore: float
    face: float

    @classmethod
    def of(cls, scene) -> Layers:
        """The layers of a :class:`synth.config.SceneConfig`."""
        return cls(backdrop=-scene.backdrop_distance, bore=0.0, face=scene.trough_length / 2)


class Defocus:
    """The defocus of one scene: its layers' kernels and the trough's coverage.

    Parameters
    ----------
    scene : synth.config.SceneConfig
        The scene; its camera (the ideal one, without the lens's distortion) has
        ``f_number``.
    face, bore : numpy.ndarray
        :meth:`synth.backends.raster.SceneRenderer.layer_coverage` of the frame.
    ball_radius : float
        The ball's radius (m).
    """

    def __init__(self, scene, face: np.ndarray, bore: np.ndarray, ball_radius: float):
        self.camera = scene.camera
        self.layers = Layers.of(scene)
        self.face = np.asarray(face, dtype=np.float64)
        self.bore = np.asarray(bore, dtype=np.float64)
        self.ball_radius = float(ball_radius)
        cam = self.camera
        self.kernels = {name: disc_kernel(float(coc_px(cam, z)))
                        for name, z in dataclasses.asdict(self.layers).items()}
        # the ball rolls near its plane: its blur at z = 0 +- its radius bounds the reach
        ball_max = max(float(coc_px(cam, z)) for z in (-ball_radius, 0.0, ball_radius))
        reach = max([k.shape[0] // 2 for k in self.kernels.values()]
                    + [disc_kernel(ball_max).shape[0] // 2])
        self.margin = int(reach) + 1

    def composite(self, scene_img: np.ndarray, box, ball_img=None, ball_alpha=None,
                  ball_z: float = 0.0) -> np.ndarray:
        """Lay the blurred layers of a region over each other, back to front.

        A pixel's light is split among the layers in proportion to their coverage; the ball
        lies behind the front face and over the bore and the backdrop. With every kernel a
        point, the result is ``ball_img`` (``scene_img`` without the ball) to rounding.

        Parameters
        ----------
        scene_img : numpy.ndarray
            The region's image without the ball (float), any scale.
        box : tuple of int
            (x0, y0, w, h): the region in the frame.
        ball_img, ball_alpha : numpy.ndarray, optional
            The region's image with the ball (same scale) and the ball's coverage.
        ball_z : float, optional
            The ball centre's world z (m).

        Returns
        -------
        numpy.ndarray
            float64 (h, w). Pixels within the blur's reach of the region's edge are valid only
            where the edge is the frame's.
        """
        x0, y0, w, h = box
        s = np.asarray(scene_img, dtype=np.float64)
        a_face = self.face[y0:y0 + h, x0:x0 + w]
        a_bore = self.bore[y0:y0 + h, x0:x0 + w]
        a_back = np.clip(1.0 - a_face - a_bore, 0.0, 1.0)
        k = self.kernels
        num = _blur(a_back * s, k["backdrop"])
        den = _blur(a_back, k["backdrop"])
        with np.errstate(invalid="ignore", divide="ignore"):
            out = np.where(den > 1e-6, num / np.maximum(den, 1e-300), 0.0)
        if a_bore.any():
            # the coverages are shares of the pixel; "over" takes the bore's own coverage,
            # its share of what the face leaves (none known where the face covers all)
            rest = 1.0 - a_face
            a_bore = np.where(rest > 1e-6, np.clip(a_bore / np.where(rest > 1e-6, rest, 1.0),
                                                   0.0, 1.0), 0.0)
            out = _over(_blur(a_bore * s, k["bore"]), _blur(a_bore, k["bore"]), out)
        if ball_alpha is not None:
            # the ball's own light (alpha Ball): the sharp image is a_face F + (1 - a_face)
            # (alpha Ball + (1 - alpha) behind), and behind the face lies the scene's light
            # (the proportional split); where the face hides the ball its light is unknown:
            # the scene's
            alpha = np.asarray(ball_alpha, dtype=np.float64)
            open_ = 1.0 - a_face
            seen = open_ > 0.05
            premult = alpha * s + np.where(
                seen, (np.asarray(ball_img, dtype=np.float64) - s) / np.where(seen, open_, 1.0),
                0.0)
            kb = disc_kernel(float(coc_px(self.camera, ball_z)))
            out = _over(_blur(premult, kb), _blur(alpha, kb), out)
        return _over(_blur(a_face * s, k["face"]), _blur(a_face, k["face"]), out)

    def background(self, bg: np.ndarray) -> np.ndarray:
        """The ball-free frame (full frame, any scale) blurred: float64."""
        H, W = bg.shape
        return self.composite(bg, (0, 0, W, H))

    def ball_alpha(self, centres, box) -> np.ndarray:
        """The ball's coverage of the region ``box`` averaged over the sub-frame ``centres``
        (K, 3): its exact silhouette (area-equivalent disc), anti-aliased by distance."""
        x0, y0, w, h = box
        uv, rad = self.camera.sphere_silhouette(np.atleast_2d(centres), self.ball_radius)
        xs = np.arange(x0, x0 + w, dtype=np.float64)
        ys = np.arange(y0, y0 + h, dtype=np.float64)
        acc = np.zeros((h, w))
        for (u, v), r in zip(uv, rad, strict=True):
            d = np.hypot(xs[None, :] - u, ys[:, None] - v)
            acc += np.clip(r - d + 0.5, 0.0, 1.0)
        return acc / len(uv)

    def frame_tiles(self, tiles, size) -> list:
        """The output regions of a frame whose sharp changes lie in ``tiles``: each tile
        widened by :attr:`margin` on every side (inside the frame ``size`` = (W, H)),
        overlapping ones merged."""
        W, H = size
        m = self.margin
        boxes = [(max(x - m, 0), max(y - m, 0), min(x + w + m, W), min(y + h + m, H))
                 for x, y, w, h in tiles]
        boxes = merge_boxes(boxes, lambda a, b, u: a[0] < b[2] and b[0] < a[2]
                            and a[1] < b[3] and b[1] < a[3])
        return [(x0, y0, x1 - x0, y1 - y0) for x0, y0, x1, y1 in boxes]

    def input_box(self, box, size):
        """The region to render for output region ``box``: widened by :attr:`margin`."""
        W, H = size
        x, y, w, h = box
        m = self.margin
        x0, y0 = max(x - m, 0), max(y - m, 0)
        return (x0, y0, min(x + w + m, W) - x0, min(y + h + m, H) - y0)

    def render_frame(self, renderer, poses, centres, tiles, sharp_bg: np.ndarray,
                     index: int = 0):
        """One frame's defocused regions.

        Parameters
        ----------
        renderer : synth.backends.raster.SceneRenderer
            The scene's renderer (renders the widened tiles with the ball).
        poses : list
            The ball's poses, one per sub-frame.
        centres : numpy.ndarray
            (K, 3) the ball's centres at the sub-frames (m).
        tiles : list
            The sharp frame's changed tiles (:meth:`synth.backends.raster.SceneRenderer.tiles_for`).
        sharp_bg : numpy.ndarray
            The ball-free frame, not blurred (levels, one sub-frame).
        index : int, optional
            The frame's number.

        Returns
        -------
        list of (box, numpy.ndarray)
            Output regions and their float64 images (sum over the sub-frames).
        """
        cam = renderer.camera
        size = (cam.width, cam.height)
        outs = self.frame_tiles(tiles, size)
        ins = [self.input_box(b, size) for b in outs]
        rendered = renderer.render_tiles(poses, ins, index=index)
        k = len(poses)
        ball_z = float(np.mean(np.atleast_2d(centres)[:, 2]))
        result = []
        for (x0, y0, w, h), (ix, iy, iw, ih), img in zip(outs, ins, rendered, strict=True):
            box = (ix, iy, iw, ih)
            img = np.asarray(img, dtype=np.float64)
            alpha = self.ball_alpha(centres, box)
            behind = k * sharp_bg[iy:iy + ih, ix:ix + iw].astype(np.float64)
            scene_img = np.where(alpha > 0, behind, img)
            full = self.composite(scene_img, box, img, alpha, ball_z)
            result.append(((x0, y0, w, h), full[y0 - iy:y0 - iy + h, x0 - ix:x0 - ix + w]))
        return result


def _over(front_premult: np.ndarray, front_alpha: np.ndarray, back: np.ndarray) -> np.ndarray:
    return front_premult + (1.0 - front_alpha) * back
