from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.vision import create_encoder
from openreloc_bench.vision.clip import clip_preprocess
from openreloc_bench.vision.testing import tiny_clip_checkpoint


def _crops(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [
        rng.integers(0, 256, (int(rng.integers(5, 60)), int(rng.integers(5, 60)), 3), dtype=np.uint8) for _ in range(n)
    ]


def test_shapes_norms_and_dtype(clip_encoder) -> None:
    x = clip_encoder.encode_images(_crops(5))
    t = clip_encoder.encode_texts(["a red chair", "the table", ""])
    assert x.shape == (5, clip_encoder.dim) and t.shape == (3, clip_encoder.dim)
    assert x.dtype == np.float32 and t.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(x, axis=1), 1, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1, atol=1e-5)
    assert clip_encoder.encode_images([]).shape == (0, clip_encoder.dim)


def test_batching_equals_single_and_is_deterministic(clip_encoder) -> None:
    crops = _crops(7, seed=1)
    clip_encoder.batch_size = 3
    batched = clip_encoder.encode_images(crops)
    clip_encoder.batch_size = 32
    single = np.concatenate([clip_encoder.encode_images([c]) for c in crops])
    np.testing.assert_allclose(batched, single, atol=1e-5)
    np.testing.assert_array_equal(batched, clip_encoder.encode_images(crops) if False else batched)
    again = clip_encoder.encode_images(crops)
    np.testing.assert_allclose(again, batched, atol=1e-6)
    texts = ["a mug", "a lamp", "a sofa", "x"]
    np.testing.assert_allclose(
        clip_encoder.encode_texts(texts), np.concatenate([clip_encoder.encode_texts([t]) for t in texts]), atol=1e-5
    )
    # different inputs give different embeddings (the towers are really run)
    assert not np.allclose(batched[0], batched[1])


def test_grey_black_float_and_rgba_crops(clip_encoder) -> None:
    crops = [
        np.zeros((10, 10), np.uint8),
        np.zeros((10, 10, 3), np.uint8),
        np.ones((10, 10, 3), np.float32),
        np.zeros((10, 10, 4), np.uint8),
    ]
    x = clip_encoder.encode_images(crops)
    assert np.all(np.isfinite(x))
    np.testing.assert_allclose(x[0], x[1], atol=1e-6)  # grey zeros == black RGB
    np.testing.assert_allclose(x[1], x[3], atol=1e-6)  # alpha dropped


def test_preprocess_matches_clip_recipe() -> None:
    img = np.zeros((40, 80, 3), np.uint8)
    img[:, 20:60] = 255  # the centre crop of a 2:1 image keeps the middle square, all white
    px = clip_preprocess([img], 16, (0.5, 0.5, 0.5), (0.5, 0.5, 0.5)).numpy()
    assert px.shape == (1, 3, 16, 16)
    np.testing.assert_allclose(px[0, :, :, 2:14], 1.0, atol=0.05)


def test_missing_and_invalid_weight_directories(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found.*save_pretrained"):
        create_encoder("clip", model=str(tmp_path / "nope"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match="no config.json"):
        create_encoder("clip", model=str(tmp_path / "empty"))


def test_checkpoint_helper_is_idempotent(tiny_clip_dir: Path) -> None:
    before = (tiny_clip_dir / "model.safetensors").stat().st_mtime_ns
    assert tiny_clip_checkpoint(tiny_clip_dir) == tiny_clip_dir
    assert (tiny_clip_dir / "model.safetensors").stat().st_mtime_ns == before


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{not json", "not valid JSON"),
        ('{"image_mean": [0.5, 0.5]}', "image_mean"),
        ('{"image_std": [1, 0, 1]}', "> 0"),
    ],
)
def test_malformed_preprocessor_config_is_a_one_line_error(
    tiny_clip_dir: Path, tmp_path: Path, text: str, message: str
) -> None:
    copy = tmp_path / "clip"
    shutil.copytree(tiny_clip_dir, copy)
    (copy / "preprocessor_config.json").write_text(text)
    with pytest.raises(DataError, match=message) as err:
        create_encoder("clip", model=str(copy))
    assert "preprocessor_config.json" in str(err.value) and "\n" not in str(err.value)
