"""Seeded RGB-D sensor model: what a structured-light camera (Kinect v1, PrimeSense, Asus Xtion) records of
the renderer's perfect colour and depth.

Depth follows the published noise models of these cameras, in this order:

1. lateral jitter: each pixel reads the depth a Gaussian sub-pixel shift away, as in the Barron & Malik model
   that ICL-NUIM uses (Handa et al. 2014, "A benchmark for RGB-D visual odometry, 3D reconstruction and
   SLAM"), by nearest neighbour so that edges never blend into depths between foreground and background;
2. disparity noise and quantisation: z -> d = f b / z, Gaussian noise, 1/8 px steps, back to z, so the error
   grows with z^2 (Khoshelham & Elberink 2012, "Accuracy and resolution of Kinect depth data"; the same
   disparity-domain noise as ICL-NUIM and the Redwood model of Choi et al. 2015 that Habitat uses);
3. missing returns: the projector's shadow beside nearer surfaces, random loss along depth
   discontinuities, surfaces seen at grazing angles (Nguyen, Izadi & Lovell 2012, "Modeling Kinect sensor
   noise"), dark surfaces that absorb the infrared pattern, saturated highlights, and depths outside the
   working range.

Colour is a linear-light camera: the render is decoded from sRGB, darkened towards the corners
(vignetting), collected as electrons with photon shot noise (Poisson, as a Gaussian) and read noise,
amplified by the camera's gain with its noise, clipped, re-encoded to sRGB and JPEG-compressed. The camera
raises its gain as the light falls (:func:`colour_gain`), so the benchmark's dark splits are noisier, not
only darker.
Motion blur averages sub-frame renders in linear light (:func:`blend_subframes`).

Every random draw comes from the caller's ``numpy.random.Generator``: the same seed gives the same frames.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Literal

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from openreloc_bench import config

SENSOR_MODELS = ("ideal", "structured-light")
"""``ideal``: the noiseless render, unchanged; ``structured-light``: a Kinect v1 / PrimeSense-class camera."""

MAX_BLUR_SUBFRAMES = 32
"""Each sub-frame is a full render, so more is a typo, not a camera."""

_LUMA = (0.2126, 0.7152, 0.0722)  # sRGB / Rec. 709 luminance weights of linear R, G, B
_LINEAR_LEVELS = 65535  # linear light is encoded through a table of this many steps (exact for 8-bit sRGB)


def _srgb_to_linear(v: np.ndarray) -> np.ndarray:
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb(v: np.ndarray) -> np.ndarray:
    return np.where(v <= 0.0031308, v * 12.92, 1.055 * v ** (1 / 2.4) - 0.055)


_TO_LINEAR = _srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
_TO_SRGB = np.rint(_linear_to_srgb(np.arange(_LINEAR_LEVELS + 1) / _LINEAR_LEVELS) * 255).astype(np.uint8)


@dataclass
class DepthNoise:
    """How a structured-light depth camera departs from the true depth (defaults: Kinect v1 / PrimeSense)."""

    baseline_m: float = 0.075
    """Projector-to-IR-camera baseline in metres (Kinect v1: 7.5 cm, Khoshelham & Elberink 2012)."""
    focal_px: float = 580.0
    """IR camera focal length in its own pixels (Kinect v1 at 640x480, Khoshelham & Elberink 2012); sets the disparity scale whatever the render's resolution."""
    disparity_sigma_px: float = 0.06
    """Std of the Gaussian disparity noise in IR pixels; with the 1/8 px steps, sigma_z is ~4 cm at 5 m as measured by Khoshelham & Elberink 2012."""
    subpixel: float = 0.125
    """Disparity quantisation step in IR pixels (PrimeSense 1/8 px; ICL-NUIM, Handa et al. 2014; Redwood, Choi et al. 2015)."""
    lateral_sigma_px: float = 0.5
    """Std of the per-pixel image-plane jitter in IR pixels (ICL-NUIM, Handa et al. 2014, after Barron & Malik)."""
    min_range_m: float = 0.4
    """Nearest depth returned (PrimeSense Carmine 1.08: 0.35 m; Kinect v1: 0.4-0.5 m)."""
    max_range_m: float = 6.0
    """Farthest depth returned: beyond it the pattern is too faint (Kinect v1 drivers report 4-8 m)."""
    edge_jump: float = 0.05
    """Relative depth step between neighbouring pixels that counts as a discontinuity."""
    edge_width_px: int = 1
    """Pixels on each side of a discontinuity that may lose their return (1: the two pixels across the step)."""
    edge_dropout: float = 0.5
    """Probability that a pixel at a discontinuity returns nothing: block matching fails across edges (Nguyen et al. 2012)."""
    projector_shadow: bool = True
    """Lose the background the projector cannot light beside nearer surfaces (the projector sits baseline_m to the camera's right, as on a Kinect v1)."""
    grazing_deg: float = 75.0
    """Surfaces whose normal is further than this from the viewing ray return nothing (the axial noise explodes past ~70 deg, Nguyen et al. 2012)."""
    dark_threshold: float = 0.02
    """Linear luminance (0-1, under mapping light) below which returns start to drop out: dark surfaces absorb the IR pattern."""
    dark_dropout: float = 0.8
    """Probability of losing a black pixel's return; it rises linearly from 0 at dark_threshold."""
    specular_threshold: float = 0.95
    """Linear luminance (0-1) above which returns start to drop out: saturated highlights mirror the pattern away."""
    specular_dropout: float = 0.5
    """Probability of losing a fully saturated pixel's return; it rises linearly from 0 at specular_threshold."""

    def __post_init__(self) -> None:
        config.check_ranges(
            self,
            positive=("baseline_m", "focal_px", "subpixel", "min_range_m", "edge_jump", "grazing_deg"),
            non_negative=("disparity_sigma_px", "lateral_sigma_px"),
            at_least_one=("edge_width_px",),
            share=("edge_dropout", "dark_threshold", "dark_dropout", "specular_threshold", "specular_dropout"),
        )
        _check_int("edge_width_px", self.edge_width_px)
        _check_bool("projector_shadow", self.projector_shadow)
        if self.max_range_m <= self.min_range_m:
            raise ValueError(f"'max_range_m' must be > 'min_range_m' ({self.min_range_m}), got {self.max_range_m}")
        if self.grazing_deg > 90:
            raise ValueError(f"'grazing_deg' must be in (0, 90], got {self.grazing_deg}")
        if self.specular_threshold == 1:
            raise ValueError("'specular_threshold' must be < 1, got 1")


@dataclass
class ColourNoise:
    """How the colour camera departs from the render (defaults: a small consumer CMOS sensor, as in a Kinect v1)."""

    full_well: float = 2000.0
    """Electrons a pixel collects at full scale (white) and gain 1; shot noise is Poisson in electrons (small CMOS pixels hold a few thousand; 2000 gives ~3 grey levels of noise on mid-grey before JPEG)."""
    read_sigma: float = 3.0
    """Read noise in electrons at gain 1, amplified with the gain (consumer CMOS: 2-5 electrons)."""
    max_gain: float = 8.0
    """Highest analogue gain the camera uses as the light falls (8x = 18 dB)."""
    auto_exposure: bool = False
    """Scale each image so its mean linear luminance reaches target_mean (gain capped at max_gain); off, a dark split stays dark."""
    target_mean: float = 0.18
    """Mean linear luminance auto-exposure aims for (18% grey, the photographic metering standard)."""
    vignetting: float = 0.15
    """Radial falloff (1 + vignetting r^2)^-2 with r = 1 in the corners: the cos^4 law of a lens whose corner ray has tan^2 = vignetting (0.15: corners at 0.76x the centre)."""
    jpeg_quality: int = 90
    """JPEG quality of the recorded colour frames (RGB-D datasets such as ScanNet store colour as JPEG); 0 = no JPEG."""

    def __post_init__(self) -> None:
        config.check_ranges(
            self, positive=("full_well", "target_mean"), non_negative=("read_sigma", "vignetting", "jpeg_quality")
        )
        config.check_ranges(self, at_least_one=("max_gain",))
        _check_bool("auto_exposure", self.auto_exposure)
        _check_int("jpeg_quality", self.jpeg_quality)
        if self.target_mean > 1:
            raise ValueError(f"'target_mean' must be in (0, 1], got {self.target_mean}")
        if self.jpeg_quality > 100:
            raise ValueError(f"'jpeg_quality' must be in [0, 100], got {self.jpeg_quality}")


@dataclass
class SensorSpec:
    """The camera that records the rendered frames: an ideal one, or a structured-light RGB-D camera."""

    model: Literal["ideal", "structured-light"] = "structured-light"
    """'ideal': the noiseless render, bit for bit; 'structured-light': a Kinect v1 / PrimeSense-class RGB-D camera."""
    depth: DepthNoise = field(default_factory=DepthNoise)
    """The depth camera's noise and missing returns."""
    colour: ColourNoise = field(default_factory=ColourNoise)
    """The colour camera's noise, gain, vignetting and compression."""
    blur_subframes: int = 3
    """Sub-frame renders averaged into each mapping frame for motion blur (1 = none; the middle one of an odd
    count is the frame's own render)."""
    blur_exposure: float = 0.05
    """Fraction of the way to the next mapping pose the shutter stays open (0.05 of a 0.25 m / 15 deg step: a handheld camera at 0.5 m/s and 30 deg/s with a 1/40 s exposure)."""

    def __post_init__(self) -> None:
        if self.model not in SENSOR_MODELS:
            raise ValueError(f"'model' must be one of {', '.join(SENSOR_MODELS)}, got {self.model!r}")
        if not isinstance(self.depth, DepthNoise):
            raise ValueError(f"'depth' must be a DepthNoise, got {type(self.depth).__name__}")
        if not isinstance(self.colour, ColourNoise):
            raise ValueError(f"'colour' must be a ColourNoise, got {type(self.colour).__name__}")
        config.check_ranges(self, at_least_one=("blur_subframes",), share=("blur_exposure",))
        _check_int("blur_subframes", self.blur_subframes)
        if self.blur_subframes > MAX_BLUR_SUBFRAMES:
            raise ValueError(f"'blur_subframes' must be at most {MAX_BLUR_SUBFRAMES}, got {self.blur_subframes}")


def _check_int(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"'{name}' must be an integer, got {value!r}")


def _check_bool(name: str, value: Any) -> None:
    if not isinstance(value, bool):
        raise ValueError(f"'{name}' must be true or false, got {value!r}")


def _check_level(light_level: float) -> None:
    if not (math.isfinite(light_level) and light_level > 0):
        raise ValueError(f"light_level must be > 0, got {light_level}")


def _check_rgb(rgb: np.ndarray) -> None:
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb must be uint8 of shape (H, W, 3), got {rgb.dtype} {rgb.shape}")


def exposure_poses(T: np.ndarray, T_neighbour: np.ndarray, spec: SensorSpec) -> list[np.ndarray]:
    """The camera poses of a frame's sub-frames: ``spec.blur_subframes`` poses spread evenly over
    ``blur_exposure`` of the motion to a neighbouring frame, centred on ``T`` (constant velocity; the
    motion's direction does not matter, the spread being symmetric)."""
    delta = np.linalg.solve(T, T_neighbour)
    rotvec = Rotation.from_matrix(delta[:3, :3]).as_rotvec()
    out = []
    for t in np.linspace(-0.5, 0.5, spec.blur_subframes) * spec.blur_exposure:
        step = np.eye(4)
        step[:3, :3] = Rotation.from_rotvec(t * rotvec).as_matrix()
        step[:3, 3] = t * delta[:3, 3]
        out.append(T @ step)
    return out


def sensor_record(spec: SensorSpec) -> dict[str, Any]:
    """Every parameter of ``spec`` as plain JSON-ready data (for ``scene.json`` and the dataset card)."""
    return config.to_dict(spec)


def sensor_depth(
    depth: np.ndarray,
    rgb: np.ndarray,
    K: np.ndarray,
    spec: SensorSpec,
    rng: np.random.Generator,
    light_level: float = 1.0,
) -> np.ndarray:
    """The depth image (float32 metres, 0 = no return) the camera records of the true ``depth`` (0 = no surface).

    ``rgb`` (the colour render of the same view) stands in for the surfaces' infrared reflectance; it was
    rendered at ``light_level`` times the mapping light, which is divided out because the projector brings
    its own light: a dim room does not lose returns. ``K`` is the render's pinhole intrinsics."""
    if depth.ndim != 2 or depth.dtype != np.float32:
        raise ValueError(f"depth must be float32 of shape (H, W), got {depth.dtype} {depth.shape}")
    _check_rgb(rgb)
    if rgb.shape[:2] != depth.shape:
        raise ValueError(f"rgb {rgb.shape[:2]} and depth {depth.shape} differ in size")
    if np.shape(K) != (3, 3):
        raise ValueError(f"K must be 3x3, got shape {np.shape(K)}")
    _check_level(light_level)
    if spec.model == "ideal":
        return depth.copy()
    n = spec.depth
    h, w = depth.shape
    fx, fy, cx, cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
    z = np.nan_to_num(depth, nan=0.0, posinf=0.0, neginf=0.0)
    np.maximum(z, 0, out=z)

    edge = _discontinuities(z, n.edge_jump, n.edge_width_px)
    lost = _grazing(z, fx, fy, cx, cy, n.grazing_deg)
    lost &= ~edge
    if n.projector_shadow:
        lost |= _projector_shadow(z, fx * n.baseline_m)
    keep = np.where(edge, np.float32(1 - n.edge_dropout), np.float32(1))
    if n.dark_dropout > 0 or n.specular_dropout > 0:
        luma = cv2.transform(cv2.LUT(rgb, _TO_LINEAR), np.array([_LUMA], dtype=np.float32))
        luma *= np.float32(1 / light_level)
        np.minimum(luma, 1, out=luma)
        if n.dark_dropout > 0 and n.dark_threshold > 0:
            keep *= _ramp(luma, n.dark_threshold, 0.0, n.dark_dropout)
        if n.specular_dropout > 0:
            keep *= _ramp(luma, n.specular_threshold, 1.0, n.specular_dropout)
    lost |= rng.random((h, w), dtype=np.float32) >= keep
    z[lost] = 0

    noise = rng.standard_normal((3, h, w), dtype=np.float32)
    if n.lateral_sigma_px > 0:  # sigma in sensor pixels, the maps in render pixels
        map_x, map_y = noise[0], noise[1]
        map_x *= np.float32(n.lateral_sigma_px * fx / n.focal_px)
        map_x += np.arange(w, dtype=np.float32)
        map_y *= np.float32(n.lateral_sigma_px * fy / n.focal_px)
        map_y += np.arange(h, dtype=np.float32)[:, None]
        z = cv2.remap(z, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)

    fb = np.float32(n.focal_px * n.baseline_m)
    with np.errstate(divide="ignore"):
        out = np.divide(fb, z, out=z)  # disparity; inf where there is no return, which stays 0 below
        noise[2] *= np.float32(n.disparity_sigma_px)
        out += noise[2]
        out *= np.float32(1 / n.subpixel)
        np.rint(out, out=out)
        out *= np.float32(n.subpixel)
        np.divide(fb, out, out=out)
    cv2.threshold(out, n.min_range_m, 0, cv2.THRESH_TOZERO, dst=out)  # also takes negative disparities
    cv2.threshold(out, n.max_range_m, 0, cv2.THRESH_TOZERO_INV, dst=out)  # and zero ones (inf)
    return out


def _ramp(luma: np.ndarray, start: float, end: float, dropout: float) -> np.ndarray:
    """The probability of keeping a return: 1 up to ``start``, falling linearly to 1 - ``dropout`` at ``end``."""
    share = luma - np.float32(start)
    share *= np.float32(1 / (end - start))
    np.clip(share, 0, 1, out=share)
    share *= np.float32(-dropout)
    share += 1
    return share


def _discontinuities(z: np.ndarray, jump: float, width: int) -> np.ndarray:
    """Pixels within ``width`` of a step between neighbours larger than ``jump`` times the larger depth
    (a step to 0, where there is no surface, counts)."""
    edge = np.zeros(z.shape, dtype=np.uint8)
    for a, b, ea, eb in (
        (z[:, 1:], z[:, :-1], edge[:, 1:], edge[:, :-1]),
        (z[1:], z[:-1], edge[1:], edge[:-1]),
    ):
        step = cv2.compare(cv2.absdiff(a, b), cv2.max(a, b) * np.float32(jump), cv2.CMP_GT)
        cv2.bitwise_or(ea, step, dst=ea)
        cv2.bitwise_or(eb, step, dst=eb)
    if width > 1:
        edge = cv2.dilate(edge, np.ones((2 * width - 1, 2 * width - 1), np.uint8))
    return edge > 0


def _grazing(z: np.ndarray, fx: float, fy: float, cx: float, cy: float, grazing_deg: float) -> np.ndarray:
    """Pixels whose surface normal (from the back-projected depth) is more than ``grazing_deg`` from the ray.

    With P = z (x, y, 1), x = (u - cx) / fx, the normal dP/du x dP/dv is parallel to
    n = (-fx z_u, -fy z_v, fx x z_u + fy y z_v + z) and n . (x, y, 1) = z, so cos = z / (|n| |(x, y, 1)|)."""
    a = _central_difference(z, 1)
    a *= np.float32(fx)
    b = _central_difference(z, 0)
    b *= np.float32(fy)
    x = (np.arange(z.shape[1], dtype=np.float32) - np.float32(cx)) / np.float32(fx)
    y = (np.arange(z.shape[0], dtype=np.float32)[:, None] - np.float32(cy)) / np.float32(fy)
    c = x * a
    c += y * b
    c += z
    np.multiply(a, a, out=a)
    np.multiply(b, b, out=b)
    np.multiply(c, c, out=c)
    a += b
    a += c
    a *= (1 + x * x + y * y) * np.float32(math.cos(math.radians(grazing_deg)) ** 2)
    np.multiply(z, z, out=b)
    return b < a


def _central_difference(z: np.ndarray, axis: int) -> np.ndarray:
    """dz along ``axis`` per pixel: central in the interior, one-sided on the border (as ``np.gradient``)."""
    zt, dt = (z, np.empty_like(z)) if axis == 0 else (z.T, np.empty_like(z).T)
    np.subtract(zt[2:], zt[:-2], out=dt[1:-1])
    dt[1:-1] *= np.float32(0.5)
    np.subtract(zt[1], zt[0], out=dt[0])
    np.subtract(zt[-1], zt[-2], out=dt[-1])
    return dt if axis == 0 else dt.T


def _projector_shadow(z: np.ndarray, fb_render: float) -> np.ndarray:
    """Pixels the projector, ``baseline`` to the camera's right, cannot light.

    A point at column u with disparity d = f b / z lands on projector column u - d; it is in shadow when a
    pixel to its right lands further left, because that pixel is nearer and blocks the projector's ray."""
    column = np.divide(np.float32(fb_render), z, out=np.zeros_like(z), where=z > 0)
    np.subtract(np.arange(z.shape[1], dtype=np.float32), column, out=column)
    ahead = np.minimum.accumulate(column[:, :0:-1], axis=1)[:, ::-1]  # the smallest right of each pixel
    shadow = np.zeros(z.shape, dtype=bool)
    np.greater(column[:, :-1], ahead, out=shadow[:, :-1])
    return shadow


def colour_gain(light_level: float, spec: SensorSpec) -> float:
    """The analogue gain the camera uses at ``light_level`` (1 = mapping light) without auto-exposure.

    It makes up half the lost light in stops, 1 / sqrt(light_level), between 1 (base gain, at or above
    mapping light) and ``max_gain``: a dark split is recorded brighter than it was rendered yet darker
    than the mapping frames, its few photons' noise amplified with them."""
    _check_level(light_level)
    return float(min(spec.colour.max_gain, max(1.0, light_level**-0.5)))


def sensor_colour(rgb: np.ndarray, spec: SensorSpec, rng: np.random.Generator, light_level: float = 1.0) -> np.ndarray:
    """The colour image (uint8 RGB) the camera records of the render ``rgb``, lit at ``light_level`` times the
    mapping light (the render is already that much darker: what the sensor collects at base gain).

    In linear light: vignetting; the render's light as electrons (full scale = ``full_well``); photon shot
    noise (Poisson, as a Gaussian) and read noise; then the gain (auto-exposure's, or :func:`colour_gain`'s),
    which amplifies signal and noise alike (a gain below 1 is a shorter exposure: fewer electrons);
    clipping, sRGB and JPEG."""
    _check_rgb(rgb)
    _check_level(light_level)
    if spec.model == "ideal":
        return rgb.copy()
    c = spec.colour
    h, w = rgb.shape[:2]
    lin = cv2.LUT(rgb, _TO_LINEAR)
    if c.vignetting > 0:
        lin *= _vignette(h, w, c.vignetting)[..., None]
    if c.auto_exposure:
        mean = float(np.dot(cv2.mean(lin)[:3], _LUMA))
        gain = min(c.max_gain, c.target_mean / max(mean, 1e-6))
    else:
        gain = colour_gain(light_level, spec)
    exposure = min(gain, 1.0)
    electrons = lin
    electrons *= np.float32(c.full_well * exposure)
    noise = electrons + np.float32(c.read_sigma**2)
    np.sqrt(noise, out=noise)
    noise *= rng.standard_normal(lin.shape, dtype=np.float32)
    electrons += noise
    electrons *= np.float32(gain / exposure / c.full_well)
    out = _encode(electrons)
    if c.jpeg_quality > 0:
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(out, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, c.jpeg_quality])
        if not ok:
            raise RuntimeError("OpenCV could not JPEG-encode a frame")
        out = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return out


@lru_cache(maxsize=8)
def _vignette(h: int, w: int, strength: float) -> np.ndarray:
    """(1 + strength r^2)^-2, r the distance from the image centre over the half-diagonal (read-only)."""
    x = np.arange(w, dtype=np.float32) - np.float32((w - 1) / 2)
    y = np.arange(h, dtype=np.float32)[:, None] - np.float32((h - 1) / 2)
    r2 = (x * x + y * y) * np.float32(4 / (w * w + h * h))
    factor = (1 + np.float32(strength) * r2) ** -2
    factor.flags.writeable = False
    return factor


def _encode(lin: np.ndarray) -> np.ndarray:
    """Linear light (clipped to [0, 1]) to 8-bit sRGB, through a table."""
    index = cv2.multiply(lin.reshape(lin.shape[0], -1), _LINEAR_LEVELS, dtype=cv2.CV_16U)  # rounds and saturates
    return np.take(_TO_SRGB, index).reshape(lin.shape)


def blend_subframes(frames: Sequence[np.ndarray]) -> np.ndarray:
    """Motion blur: the mean of sub-frame renders (uint8 RGB) in linear light, as the sensor integrates photons."""
    if not frames:
        raise ValueError("blend_subframes needs at least one frame")
    for f in frames:
        _check_rgb(f)
        if f.shape != frames[0].shape:
            raise ValueError(f"sub-frames differ in size: {f.shape} and {frames[0].shape}")
    total = np.zeros(frames[0].shape, dtype=np.float32)
    for f in frames:
        total += cv2.LUT(f, _TO_LINEAR)
    return _encode(total / np.float32(len(frames)))
