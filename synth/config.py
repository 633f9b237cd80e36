"""Scene, lighting and sensor configuration (SI units), with named presets.

Everything is a small frozen dataclass with ``to_dict`` (stored in the recording's attrs) and a
``from_dict`` that refuses unknown keys.
"""

from __future__ import annotations

import dataclasses
import math

from rollfric.errors import InputError
from synth.camera import CameraModel


class SynthError(InputError):
    """A synthetic-recording input that cannot be rendered (the message names it)."""


RENDERERS = ("pyrender", "mitsuba")
BALL_MODELS = ("mesh", "sphere")
SPP_CHOICES = tuple(4 ** k for k in range(7))  # samples per pixel of the mitsuba backend
MAX_LAMP_DISTANCE = 100.0  # m: a lamp further away from the trough is no lamp of a lab


@dataclasses.dataclass(frozen=True)
class Lamp:
    """A spot lamp: position and aim point in the world frame (m), intensity (pyrender candela),
    inner/outer cone half-angles (rad)."""

    position: tuple[float, float, float] = (0.06, 0.0, 0.40)
    target: tuple[float, float, float] = (0.0, -0.06, 0.0)
    intensity: float = 0.30
    inner_cone: float = math.radians(12.0)
    outer_cone: float = math.radians(20.0)

    def __post_init__(self) -> None:
        for name in ("position", "target"):
            v = tuple(float(x) for x in getattr(self, name))
            if len(v) != 3 or not all(math.isfinite(x) and abs(x) <= MAX_LAMP_DISTANCE
                                      for x in v):
                raise SynthError(f"lamp {name} must be three numbers within "
                                 f"+-{MAX_LAMP_DISTANCE:g} m, got {v}")
            object.__setattr__(self, name, v)
        if math.dist(self.position, self.target) < 1e-6:
            raise SynthError("a lamp's target must differ from its position")
        if not (self.intensity >= 0 and math.isfinite(self.intensity)):
            raise SynthError(f"lamp intensity must be >= 0, got {self.intensity!r}")
        if not 0 <= self.inner_cone < self.outer_cone <= math.pi / 2:
            raise SynthError("lamp cones must satisfy 0 <= inner_cone < outer_cone <= pi/2")
        if self.position[2] <= 0:
            raise SynthError("lamps must be on the camera side (position z > 0)")


@dataclasses.dataclass(frozen=True)
class Lighting:
    """Lamps, ambient light, the paper backdrop's reflectance and its own glow (a backlight)."""

    lamps: tuple[Lamp, ...] = (Lamp(position=(0.06, 0.0, 0.40)),
                               Lamp(position=(-0.06, 0.0, 0.40)))
    ambient: float = 0.03  # pyrender ambient light (same on all channels)
    backdrop_reflectance: float = 0.85  # diffuse albedo of the white paper
    # the backdrop's emission (a diffuse backlight panel, display value 0..1; 0: none): a
    # shadowgraph rig shows the ball as a dark disc on it (pyrender only)
    backlight: float = 0.0

    def __post_init__(self) -> None:
        lamps = tuple(lp if isinstance(lp, Lamp) else Lamp(**lp) for lp in self.lamps)
        object.__setattr__(self, "lamps", lamps)
        if not lamps:
            raise SynthError("lighting needs at least one lamp")
        if not 0 <= self.ambient <= 1:
            raise SynthError(f"ambient must be in [0, 1], got {self.ambient!r}")
        if not 0 < self.backdrop_reflectance <= 1:
            raise SynthError(f"backdrop_reflectance must be in (0, 1], got "
                             f"{self.backdrop_reflectance!r}")
        if not 0 <= self.backlight <= 1:
            raise SynthError(f"backlight must be in [0, 1], got {self.backlight!r}")

    def to_dict(self) -> dict:
        """The lighting as plain data (lamps as dicts), the form stored in a recording's attributes.

        Returns
        -------
        dict
        """
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class SceneConfig:
    """What is in front of the camera and how it is rendered.

    The trough is an annular sector (bore radius from the setup, wall ``trough_wall``) of
    length ``trough_length`` centred on the ball plane, open above ``trough_opening`` (the
    half-angle about the bottom that the trough covers). The paper backdrop is a plane
    ``backdrop_distance`` behind the ball plane.
    """

    camera: CameraModel = CameraModel()
    lighting: Lighting = Lighting()
    trough_length: float = 0.03  # m along the axis
    trough_wall: float = 0.012  # m
    trough_opening: float = math.radians(110.0)  # half-angle covered, from the bottom
    trough_color: float = 0.12  # anodised aluminium base colour (dark grey)
    trough_metallic: float = 0.3
    trough_roughness: float = 0.55
    backdrop_distance: float = 0.05  # m behind the ball plane
    ball_metallic: float = 1.0
    ball_roughness: float = 0.12
    ball_color: float = 0.75  # steel
    shadows: bool = True
    supersample: int = 1  # render ss x ss pixels per output pixel (box filter), plus 4x MSAA
    motion_blur: int = 1  # sub-frames integrated over the exposure (1: none)
    ball_silhouette_segments: int = 512  # vertices on the ball mesh's silhouette ring
    # the ball as drawn by synth's lean path: "mesh" (the triangle mesh, the same pixels as
    # stock pyrender) or "sphere" (an exact sphere per pixel, shaded by the same shader code)
    ball_model: str = "mesh"
    # the backend: "pyrender" (rasterised, fast, the default) or "mitsuba" (path traced, a
    # physically based steel ball: synth.backends.pathtrace, the extra rollfric[mitsuba])
    renderer: str = "pyrender"
    # samples per pixel (powers of 4) on the ball and in its shadows' penumbra, and elsewhere in
    # the windows around the ball (at most mitsuba_spp)
    mitsuba_spp: int = 256
    mitsuba_base_spp: int = 64
    mitsuba_background_spp: int = 256  # samples per pixel of the ball-free frame
    mitsuba_max_depth: int = 4  # path vertices (3: the ball reflects the lit backdrop)
    mitsuba_margin: float = 0.15  # window margin around the ball's silhouette, ball radii
    lamp_radius: float = 0.004  # m, the mitsuba lamps' emitting spheres

    def __post_init__(self) -> None:
        if isinstance(self.camera, dict):
            object.__setattr__(self, "camera", CameraModel(**self.camera))
        if isinstance(self.lighting, dict):
            object.__setattr__(self, "lighting", Lighting(**self.lighting))
        if not isinstance(self.supersample, int) or not 1 <= self.supersample <= 4:
            raise SynthError(f"supersample must be an integer 1..4, got {self.supersample!r}")
        if not isinstance(self.motion_blur, int) or not 1 <= self.motion_blur <= 64:
            raise SynthError(f"motion_blur must be an integer 1..64 sub-frames, got "
                             f"{self.motion_blur!r}")
        if self.renderer == "mitsuba" and self.lighting.backlight > 0:
            raise SynthError("a backlight (lighting.backlight, the backlit preset) is rendered "
                             "by pyrender only, not by renderer mitsuba")
        if self.ball_model not in BALL_MODELS:
            raise SynthError(f"ball_model must be one of {', '.join(BALL_MODELS)}, got "
                             f"{self.ball_model!r}")
        if self.renderer not in RENDERERS:
            raise SynthError(f"renderer must be one of {', '.join(RENDERERS)}, got "
                             f"{self.renderer!r}")
        if self.renderer == "mitsuba" and self.camera.thin_lens:
            raise SynthError("a thin lens's defocus (camera f_number) is drawn by the pyrender "
                             "backend's layers only: Mitsuba's thinlens sensor has no "
                             "orthographic form and no principal-point offset; render it with "
                             "renderer = \"pyrender\"")
        for name in ("mitsuba_spp", "mitsuba_base_spp", "mitsuba_background_spp"):
            v = getattr(self, name)
            # Mitsuba's low-discrepancy sampler takes powers of 4 (square powers of two)
            if isinstance(v, bool) or not isinstance(v, int) or v not in SPP_CHOICES:
                raise SynthError(f"{name} must be a power of 4 (1, 4, 16, 64, 256, 1024, "
                                 f"4096), got {v!r}")
        v = self.mitsuba_max_depth
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 64:
            raise SynthError(f"mitsuba_max_depth must be an integer 1..64, got {v!r}")
        for name in ("mitsuba_margin", "lamp_radius"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise SynthError(f"{name} must be positive, got {v!r}")
        for name in ("trough_length", "trough_wall", "backdrop_distance"):
            if not getattr(self, name) > 0:
                raise SynthError(f"{name} must be positive")
        if not 0 < self.trough_opening <= math.pi:
            raise SynthError("trough_opening must be in (0, pi]")
        if self.backdrop_distance <= self.trough_length / 2:
            raise SynthError("backdrop_distance must exceed half the trough length")
        # the scene, from the trough's front face to the backdrop, must lie between the
        # camera's clip planes (the camera sits at z = working_distance in both projections)
        cam = self.camera
        lo = cam.znear + self.trough_length / 2
        hi = cam.zfar - self.backdrop_distance
        if not lo <= cam.working_distance <= hi:
            raise SynthError(
                f"camera working_distance {cam.working_distance * 1e3:g} mm: the camera must "
                f"be {lo * 1e3:g}..{hi * 1e3:g} mm from the ball plane (the trough reaches "
                f"{self.trough_length * 500:g} mm towards it, the backdrop is "
                f"{self.backdrop_distance * 1e3:g} mm behind, the clip planes are "
                f"{cam.znear * 1e3:g}..{cam.zfar * 1e3:g} mm from it)")

    def replace(self, **changes) -> SceneConfig:
        """A copy with some fields changed.

        Parameters
        ----------
        **changes
            Field names and their new values.

        Returns
        -------
        SceneConfig
        """
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """The scene as plain data (camera and lighting as dicts), the form stored in a recording.

        Returns
        -------
        dict
        """
        d = dataclasses.asdict(self)
        d["camera"] = self.camera.to_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> SceneConfig:
        """A scene from the form written by :meth:`to_dict`.

        Parameters
        ----------
        d : dict
            Scene fields; ``camera`` and ``lighting`` as dicts (``lighting.lamps`` a list of lamp
            dicts; absent keys take the defaults).

        Returns
        -------
        SceneConfig
        """
        d = dict(d)
        cam = d.pop("camera", {})
        light = d.pop("lighting", {})
        lamps = tuple(Lamp(**lp) for lp in light.get("lamps", ()))
        light = dict(light) | ({"lamps": lamps} if lamps else {})
        return cls(camera=CameraModel(**cam), lighting=Lighting(**light), **d)


@dataclasses.dataclass(frozen=True)
class SensorConfig:
    """The camera sensor, applied to the clean render when frames are read.

    The clean render's display value c (pyrender encodes gamma 2.2) is turned back into relative
    irradiance E = c**2.2 (1.0: a white the lamps fill the well with at ``reference_exposure``);
    electrons e = E * vignette * (1 + prnu) * full_well * exposure / reference_exposure, Poisson
    shot noise, Gaussian read noise and a per-pixel dark offset (dsnu) in electrons; then
    DN = round(gain * e / full_well * (2**bits - 1) + black_level), clipped to 0..2**bits - 1:
    8 bits in uint8, 10, 12 and 14 bits in 16-bit words (as such cameras store them).
    """

    bit_depth: int = 8
    exposure: float = 200e-6  # s, also the motion-blur window
    reference_exposure: float = 200e-6
    gain: float = 1.0
    full_well: float = 10000.0  # electrons
    shot_noise: bool = True
    read_noise: float = 8.0  # electrons rms
    black_level: float = 0.0  # DN
    vignetting: float = 0.0  # relative fall-off at the image corner (cos^4-like, radial^2)
    prnu: float = 0.0  # photo-response non-uniformity, relative rms (fixed pattern)
    dsnu: float = 0.0  # dark-signal non-uniformity, electrons rms (fixed pattern)

    def __post_init__(self) -> None:
        if self.bit_depth not in (8, 10, 12, 14):
            raise SynthError(f"bit_depth must be 8, 10, 12 or 14, got {self.bit_depth!r}")
        for name in ("exposure", "reference_exposure", "gain", "full_well"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise SynthError(f"sensor {name} must be positive, got {v!r}")
        for name in ("read_noise", "black_level", "prnu", "dsnu"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise SynthError(f"sensor {name} must be >= 0, got {v!r}")
        if not 0 <= self.vignetting < 1:
            raise SynthError(f"vignetting must be in [0, 1), got {self.vignetting!r}")

    @property
    def dtype(self) -> str:
        """The frames' dtype name: ``"uint8"`` for 8-bit sensors, ``"uint16"`` above."""
        return "uint8" if self.bit_depth == 8 else "uint16"

    @property
    def max_dn(self) -> int:
        """The largest digital number, 2**bit_depth - 1."""
        return 2 ** self.bit_depth - 1

    def replace(self, **changes) -> SensorConfig:
        """A copy with some fields changed.

        Parameters
        ----------
        **changes
            Field names and their new values.

        Returns
        -------
        SensorConfig
        """
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """The sensor as plain data, the form stored in a recording's attributes.

        Returns
        -------
        dict
        """
        return dataclasses.asdict(self)


# -- presets -----------------------------------------------------------------------------------

def _lamps(*specs) -> tuple[Lamp, ...]:
    return tuple(Lamp(**s) for s in specs)


LIGHTING_PRESETS: dict[str, Lighting] = {
    # two lamps beside the camera, symmetric, as in the thesis
    "thesis": Lighting(),
    # the same lamps at a third of the power
    "dim": Lighting(lamps=_lamps({"position": (0.06, 0.0, 0.40), "intensity": 0.03},
                                 {"position": (-0.06, 0.0, 0.40), "intensity": 0.03}),
                    ambient=0.01),
    # one strong lamp low and to the side: hard, long shadows, strong gradient
    "harsh": Lighting(lamps=_lamps({"position": (0.20, -0.02, 0.30), "intensity": 0.16,
                                    "inner_cone": math.radians(8.0),
                                    "outer_cone": math.radians(14.0)}),
                      ambient=0.005),
    # unequal lamps: asymmetric specular spots and shadows
    "uneven": Lighting(lamps=_lamps({"position": (0.09, 0.03, 0.35), "intensity": 0.13},
                                    {"position": (-0.05, -0.01, 0.45), "intensity": 0.04})),
    # much ambient light, weak lamps: low contrast between ball and trough
    "flat": Lighting(lamps=_lamps({"position": (0.06, 0.0, 0.40), "intensity": 0.03},
                                  {"position": (-0.06, 0.0, 0.40), "intensity": 0.03}),
                     ambient=0.25),
    # a shadowgraph rig: a bright diffuse backlight behind the ball, which shows as a dark disc
    # with a small spot of the weak lamp at the camera near its centre; no cast shadows
    "backlit": Lighting(lamps=_lamps({"position": (0.0, 0.0, 0.40), "intensity": 0.01}),
                        ambient=0.0, backlight=0.9),
}

NOISE_PRESETS: dict[str, SensorConfig] = {
    # the clean render, quantised: no noise, no fixed pattern, no vignetting
    "none": SensorConfig(shot_noise=False, read_noise=0.0),
    # a typical 8-bit high-speed CMOS camera
    "realistic": SensorConfig(full_well=10000.0, read_noise=8.0, prnu=0.005, dsnu=3.0,
                              vignetting=0.08, black_level=2.0),
    # small pixels, high gain: much shot and read noise
    "noisy": SensorConfig(full_well=2500.0, read_noise=20.0, gain=1.6, prnu=0.01, dsnu=8.0,
                          vignetting=0.15, black_level=4.0),
    # a 10-bit camera (in 16-bit words)
    "10bit": SensorConfig(bit_depth=10, full_well=15000.0, read_noise=6.0, prnu=0.004,
                          dsnu=2.5, vignetting=0.05),
    # a 12-bit camera with a deep well (in 16-bit words)
    "12bit": SensorConfig(bit_depth=12, full_well=30000.0, read_noise=5.0, prnu=0.003,
                          dsnu=2.0, vignetting=0.05),
    # a 14-bit camera with a deeper well (in 16-bit words)
    "14bit": SensorConfig(bit_depth=14, full_well=60000.0, read_noise=4.0, prnu=0.003,
                          dsnu=2.0, vignetting=0.05),
    # underexposed: a quarter of the light
    "dark": SensorConfig(exposure=50e-6, full_well=10000.0, read_noise=8.0, prnu=0.005,
                         dsnu=3.0, vignetting=0.08),
}


def lighting_preset(name: str) -> Lighting:
    """A named lighting preset.

    Parameters
    ----------
    name : str
        One of ``LIGHTING_PRESETS``: thesis, dim, harsh, uneven, flat, backlit.

    Returns
    -------
    Lighting

    Raises
    ------
    SynthError
        For an unknown name (the message lists the known ones).
    """
    try:
        return LIGHTING_PRESETS[name]
    except KeyError:
        raise SynthError(f"unknown lighting preset {name!r} (known: "
                         f"{', '.join(LIGHTING_PRESETS)})") from None


def noise_preset(name: str) -> SensorConfig:
    """A named sensor preset.

    Parameters
    ----------
    name : str
        One of ``NOISE_PRESETS``: none, realistic, noisy, 10bit, 12bit, 14bit, dark.

    Returns
    -------
    SensorConfig

    Raises
    ------
    SynthError
        For an unknown name (the message lists the known ones).
    """
    try:
        return NOISE_PRESETS[name]
    except KeyError:
        raise SynthError(f"unknown noise preset {name!r} (known: "
                         f"{', '.join(NOISE_PRESETS)})") from None
