"""The RGB-D sensor model: ideal passthrough, seeding, depth noise and missing returns, colour noise, blur."""

from __future__ import annotations

import dataclasses
import json
import math

import cv2
import numpy as np
import pytest

from generators.sensor import (
    ColourNoise,
    DepthNoise,
    SensorSpec,
    blend_subframes,
    colour_gain,
    sensor_colour,
    sensor_depth,
    sensor_record,
)
from openreloc_bench import config

H, W = 120, 160
GREY = np.full((H, W, 3), 128, np.uint8)


def _k(fx: float = 150.0, h: int = H, w: int = W) -> np.ndarray:
    return np.array([[fx, 0, (w - 1) / 2], [0, fx, (h - 1) / 2], [0, 0, 1]])


def _plane(z: float, h: int = H, w: int = W) -> np.ndarray:
    return np.full((h, w), z, np.float32)


def _depth(
    depth: np.ndarray, spec: SensorSpec | None = None, rgb: np.ndarray = GREY, seed: int = 0, **kw
) -> np.ndarray:
    k = kw.pop("K", _k(h=depth.shape[0], w=depth.shape[1]))
    return sensor_depth(depth, rgb, k, spec or SensorSpec(), np.random.default_rng(seed), **kw)


def _srgb(linear: float) -> int:
    """The 8-bit sRGB code of a linear value."""
    v = linear * 12.92 if linear <= 0.0031308 else 1.055 * linear ** (1 / 2.4) - 0.055
    return round(v * 255)


def _linear(code: np.ndarray | float) -> np.ndarray:
    v = np.asarray(code, dtype=np.float64) / 255
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def test_ideal_is_a_bit_identical_passthrough() -> None:
    rng = np.random.default_rng(3)
    depth = rng.uniform(0.1, 9, (H, W)).astype(np.float32)
    depth[:10] = 0
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    ideal = SensorSpec(model="ideal")
    out_d = sensor_depth(depth, rgb, _k(), ideal, rng)
    out_c = sensor_colour(rgb, ideal, rng, light_level=0.2)
    assert out_d.dtype == np.float32 and out_d.tobytes() == depth.tobytes() and out_d is not depth
    assert out_c.dtype == np.uint8 and out_c.tobytes() == rgb.tobytes() and out_c is not rgb


def test_same_seed_same_frames_other_seed_other_frames() -> None:
    depth = _plane(2.0)
    depth[:, 80:] = 1.0
    rgb = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    d1, d2, d3 = (_depth(depth, rgb=rgb, seed=s) for s in (7, 7, 8))
    c1, c2, c3 = (sensor_colour(rgb, SensorSpec(), np.random.default_rng(s), 0.5) for s in (7, 7, 8))
    assert np.array_equal(d1, d2) and not np.array_equal(d1, d3)
    assert np.array_equal(c1, c2) and not np.array_equal(c1, c3)


def test_depth_noise_grows_with_depth_squared_and_is_unbiased() -> None:
    std = {}
    for z in (1.0, 4.0):
        out = _depth(_plane(z))
        valid = out[out > 0]
        assert valid.size > 0.99 * out.size
        assert abs(valid.mean() - z) < 0.005 * z
        std[z] = valid.std()
    assert 10 < std[4.0] / std[1.0] < 25  # (4 / 1)^2 = 16
    assert 0.015 < std[4.0] < 0.04  # Khoshelham & Elberink 2012: ~2.5 cm at 4 m


def test_depth_comes_in_disparity_steps() -> None:
    spec = SensorSpec()
    out = _depth(_plane(2.5), spec)
    steps = spec.depth.focal_px * spec.depth.baseline_m / out[out > 0] / spec.depth.subpixel
    assert np.allclose(steps, np.rint(steps), atol=1e-3)
    assert 2 <= len(np.unique(out)) <= 8


def test_range_limits_and_missing_surfaces_return_nothing() -> None:
    depth = _plane(2.0)
    depth[:, :40] = 0.3  # nearer than min_range_m
    depth[:, 120:] = 7.0  # beyond max_range_m
    depth[:40, 40:120] = 0  # no surface
    out = _depth(depth)
    assert not out[:, :38].any() and not out[:, 122:].any() and not out[:38, 40:120].any()
    assert (out[45:, 45:115] > 0).all()


def test_projector_shadow_falls_beside_nearer_surfaces_on_the_projector_side() -> None:
    exact = SensorSpec(depth=DepthNoise(lateral_sigma_px=0, edge_dropout=0))
    near_right = _plane(2.0)
    near_right[:, 80:] = 1.0
    out = _depth(near_right, exact)
    width = 150 * 0.075 * (1 / 1.0 - 1 / 2.0)  # the disparity step, 5.6 px
    shadow = np.arange(W)[(np.arange(W) > 80 - width) & (np.arange(W) < 80)]
    assert len(shadow) == 5 and not out[:, shadow].any()
    assert (np.delete(out, shadow, axis=1) > 0).all()
    near_left = _plane(2.0)
    near_left[:, :80] = 1.0
    assert (_depth(near_left, exact) > 0).all()  # the projector sees the background behind the right edge


def test_step_edge_loses_returns_along_the_edge_only() -> None:
    depth = _plane(2.0)
    depth[:, :80] = 1.0
    out = _depth(depth, SensorSpec(depth=DepthNoise(projector_shadow=False)))
    valid = out > 0
    at_edge = valid[:, 79:81].mean()
    assert 0.35 < at_edge < 0.65  # edge_dropout 0.5
    assert valid[:, :76].all() and valid[:, 84:].all()
    assert _depth(depth, SensorSpec(depth=DepthNoise(projector_shadow=False, edge_dropout=0)))[:, 79:81].all()


def _tilted_plane(tilt_deg: float, z0: float = 2.0, fx: float = 2000.0) -> np.ndarray:
    """A plane through (0, 0, z0) whose normal is ``tilt_deg`` from the optical axis, seen with a narrow
    lens (fx = 2000 px) so that every ray meets it at about ``tilt_deg``."""
    x = (np.arange(W) - (W - 1) / 2) / fx
    return np.repeat((z0 / (1 + math.tan(math.radians(tilt_deg)) * x))[None], H, axis=0).astype(np.float32)


@pytest.mark.parametrize(("tilt", "kept_min", "kept_max"), [(0, 0.99, 1), (60, 0.99, 1), (85, 0, 0.05)])
def test_grazing_surfaces_return_nothing(tilt: float, kept_min: float, kept_max: float) -> None:
    out = _depth(_tilted_plane(tilt), K=_k(fx=2000.0))
    assert kept_min <= (out[5:-5, 5:-5] > 0).mean() <= kept_max


def test_dark_and_saturated_surfaces_lose_returns() -> None:
    rgb = GREY.copy()
    rgb[:, :50] = 0
    rgb[:, 110:] = 255
    valid = _depth(_plane(2.0), rgb=rgb) > 0
    spec = DepthNoise()
    assert abs((1 - valid[:, 5:45].mean()) - spec.dark_dropout) < 0.1
    assert abs((1 - valid[:, 115:155].mean()) - spec.specular_dropout) < 0.1
    assert valid[:, 55:105].all()


def test_dim_room_light_does_not_take_returns() -> None:
    """The projector brings its own light: a surface rendered dark because the room is dim keeps its returns."""
    dim = np.full((H, W, 3), _srgb(0.03 * 0.1), np.uint8)  # a dark grey surface (linear 0.03) in 10% light
    assert (_depth(_plane(2.0), rgb=dim) > 0).mean() < 0.5  # as if the surface itself were black
    assert (_depth(_plane(2.0), rgb=dim, light_level=0.1) > 0).all()


def test_colour_keeps_shape_dtype_and_brightness_at_mapping_light() -> None:
    out = sensor_colour(GREY, SensorSpec(), np.random.default_rng(0))
    assert out.shape == GREY.shape and out.dtype == np.uint8
    assert abs(out[40:80, 60:100].mean() - 128) < 2
    assert 0.9 < _linear(out).mean() / _linear(128) < 1  # only the vignetting darkens it


def _relative_noise(level: float, spec: SensorSpec) -> float:
    """std / mean of a flat patch of a mid-grey surface rendered at ``level`` times the mapping light."""
    image = np.full((H, W, 3), _srgb(float(_linear(128)) * level), np.uint8)
    patch = sensor_colour(image, spec, np.random.default_rng(1), level)[40:80, 60:100].astype(float)
    return float(patch.std() / patch.mean())


@pytest.mark.parametrize("jpeg_quality", [90, 0])
def test_dark_splits_are_noisier_not_only_darker(jpeg_quality: int) -> None:
    spec = SensorSpec(colour=ColourNoise(jpeg_quality=jpeg_quality))
    bright, dark = _relative_noise(1.0, spec), _relative_noise(0.2, spec)
    assert 0.004 < bright < 0.03  # 0.5-3.5 grey levels on mid-grey
    assert dark > 2 * bright  # a fifth of the photons: sqrt(5) times the relative shot noise


def test_the_gain_brightens_a_dark_split_but_not_to_the_mapping_light() -> None:
    spec = SensorSpec(colour=ColourNoise(vignetting=0, jpeg_quality=0))
    rendered = np.full((H, W, 3), _srgb(float(_linear(128)) * 0.2), np.uint8)  # mid-grey at a fifth of the light
    out = _linear(sensor_colour(rendered, spec, np.random.default_rng(0), 0.2)).mean()
    assert out == pytest.approx(5**0.5 * _linear(rendered).mean(), rel=0.05) and out < _linear(128)


def test_colour_gain_compensates_lost_light_up_to_max_gain() -> None:
    spec = SensorSpec()
    assert colour_gain(1.0, spec) == 1 and colour_gain(2.0, spec) == 1
    assert colour_gain(0.2, spec) == pytest.approx(5**0.5)  # half the lost light, in stops
    assert colour_gain(0.001, spec) == spec.colour.max_gain
    with pytest.raises(ValueError, match="light_level"):
        colour_gain(0, spec)


def test_auto_exposure_brightens_a_dark_image_to_the_target() -> None:
    dark = np.full((H, W, 3), 60, np.uint8)
    spec = SensorSpec(colour=ColourNoise(auto_exposure=True, vignetting=0))
    out = sensor_colour(dark, spec, np.random.default_rng(0), light_level=0.2)
    assert _linear(out).mean() == pytest.approx(spec.colour.target_mean, rel=0.05)
    darker = np.full_like(dark, 25)  # it would need a gain of 18
    out = sensor_colour(darker, spec, np.random.default_rng(0), light_level=0.2)
    assert _linear(out).mean() == pytest.approx(spec.colour.max_gain * _linear(25), rel=0.05)


def test_vignetting_darkens_the_corners() -> None:
    quiet = ColourNoise(full_well=1e12, read_sigma=0, jpeg_quality=0)
    out = _linear(sensor_colour(GREY, SensorSpec(colour=quiet), np.random.default_rng(0)))
    corner, centre = out[:3, :3].mean(), out[H // 2 - 2 : H // 2 + 2, W // 2 - 2 : W // 2 + 2].mean()
    assert corner / centre == pytest.approx(1 / 1.15**2, rel=0.03)
    flat = dataclasses.replace(quiet, vignetting=0)
    assert np.array_equal(sensor_colour(GREY, SensorSpec(colour=flat), np.random.default_rng(0)), GREY)


def test_jpeg_on_and_off() -> None:
    coarse = np.random.default_rng(5).integers(0, 256, (H // 10, W // 10, 3), dtype=np.uint8)
    texture = cv2.resize(coarse, (W, H), interpolation=cv2.INTER_LINEAR)
    quiet = ColourNoise(full_well=1e12, read_sigma=0, vignetting=0)
    off = sensor_colour(
        texture, SensorSpec(colour=dataclasses.replace(quiet, jpeg_quality=0)), np.random.default_rng(0)
    )
    on = sensor_colour(texture, SensorSpec(colour=quiet), np.random.default_rng(0))
    assert np.array_equal(off, texture)
    diff = np.abs(on.astype(int) - texture)
    assert 0 < diff.mean() < 3 and diff.max() < 40


def test_blend_subframes_averages_in_linear_light() -> None:
    frame = np.random.default_rng(2).integers(0, 256, (H, W, 3), dtype=np.uint8)
    assert np.array_equal(blend_subframes([frame] * 3), frame)
    black, white = np.zeros_like(frame), np.full_like(frame, 255)
    assert (blend_subframes([black, white]) == _srgb(0.5)).all()  # 188, not the sRGB mean 128
    ramp = blend_subframes([frame, white])
    assert (ramp >= frame).all() and (ramp <= white).all()
    with pytest.raises(ValueError, match="at least one"):
        blend_subframes([])
    with pytest.raises(ValueError, match="differ"):
        blend_subframes([frame, frame[:10]])


@pytest.mark.parametrize(
    ("make", "key"),
    [
        (lambda: SensorSpec(model="kinect"), "model"),  # type: ignore[arg-type]
        (lambda: SensorSpec(blur_subframes=0), "blur_subframes"),
        (lambda: SensorSpec(blur_subframes=2.5), "blur_subframes"),  # type: ignore[arg-type]
        (lambda: SensorSpec(blur_subframes=1000), "blur_subframes"),
        (lambda: SensorSpec(blur_exposure=1.5), "blur_exposure"),
        (lambda: SensorSpec(depth={"baseline_m": 0.1}), "depth"),  # type: ignore[arg-type]
        (lambda: DepthNoise(baseline_m=0), "baseline_m"),
        (lambda: DepthNoise(subpixel=-0.1), "subpixel"),
        (lambda: DepthNoise(disparity_sigma_px=math.nan), "disparity_sigma_px"),
        (lambda: DepthNoise(min_range_m=5.0, max_range_m=4.0), "max_range_m"),
        (lambda: DepthNoise(grazing_deg=95), "grazing_deg"),
        (lambda: DepthNoise(edge_dropout=1.5), "edge_dropout"),
        (lambda: DepthNoise(edge_width_px=0), "edge_width_px"),
        (lambda: DepthNoise(specular_threshold=1.0), "specular_threshold"),
        (lambda: DepthNoise(projector_shadow=1), "projector_shadow"),  # type: ignore[arg-type]
        (lambda: ColourNoise(full_well=0), "full_well"),
        (lambda: ColourNoise(read_sigma=-1), "read_sigma"),
        (lambda: ColourNoise(max_gain=0.5), "max_gain"),
        (lambda: ColourNoise(target_mean=1.5), "target_mean"),
        (lambda: ColourNoise(auto_exposure="yes"), "auto_exposure"),  # type: ignore[arg-type]
        (lambda: ColourNoise(jpeg_quality=101), "jpeg_quality"),
        (lambda: ColourNoise(jpeg_quality=90.0), "jpeg_quality"),  # type: ignore[arg-type]
    ],
)
def test_bad_values_are_rejected_naming_the_key(make, key: str) -> None:
    with pytest.raises(ValueError, match=key) as e:
        make()
    assert "\n" not in str(e.value)


def test_bad_frames_are_rejected() -> None:
    spec, rng = SensorSpec(), np.random.default_rng(0)
    with pytest.raises(ValueError, match="depth must be float32"):
        sensor_depth(_plane(2.0).astype(np.float64), GREY, _k(), spec, rng)
    with pytest.raises(ValueError, match="differ in size"):
        sensor_depth(_plane(2.0, h=10), GREY, _k(), spec, rng)
    with pytest.raises(ValueError, match="rgb must be uint8"):
        sensor_colour(GREY.astype(np.float32), spec, rng)
    with pytest.raises(ValueError, match="light_level"):
        sensor_colour(GREY, spec, rng, light_level=-1)


def test_record_is_json_and_holds_every_parameter() -> None:
    spec = SensorSpec(depth=DepthNoise(grazing_deg=70.0), colour=ColourNoise(auto_exposure=True))
    record = json.loads(json.dumps(sensor_record(spec)))
    assert set(record) == {f.name for f in dataclasses.fields(SensorSpec)}
    assert set(record["depth"]) == {f.name for f in dataclasses.fields(DepthNoise)}
    assert set(record["colour"]) == {f.name for f in dataclasses.fields(ColourNoise)}
    assert config.from_dict(SensorSpec, record) == spec  # and reads back through the config loader
