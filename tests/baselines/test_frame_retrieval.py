from __future__ import annotations

import numpy as np
import pytest

from baselines.frame_retrieval import (
    Vlad,
    VladConfig,
    VocabularyConfig,
    VocabularyTree,
    hamming,
    hamming_matrix,
    top_k,
)
from openreloc_bench.config import from_dict
from openreloc_bench.errors import ConfigError


def _images(
    rng: np.random.Generator, n_images: int = 12, per_image: int = 150, dim: int = 16
) -> tuple[np.ndarray, np.ndarray]:
    """Descriptors of images that each draw from their own few 'patterns' plus noise."""
    patterns = rng.random((n_images * 4, dim)).astype(np.float32)
    rows = [
        patterns[rng.integers(4 * i, 4 * i + 4, per_image)] + rng.normal(0, 0.05, (per_image, dim))
        for i in range(n_images)
    ]
    return np.concatenate(rows).astype(np.float32), np.arange(0, (n_images + 1) * per_image, per_image)


def test_vlad_retrieves_the_image_itself() -> None:
    rng = np.random.default_rng(0)
    desc, offsets = _images(rng)
    vlad = Vlad.fit(desc, VladConfig(clusters=8, training_descriptors=1000))
    db = vlad.describe_all(desc, offsets)
    assert np.allclose(np.linalg.norm(db, axis=1), 1.0, atol=1e-5)
    for i in range(len(db)):
        half = desc[offsets[i] : offsets[i] + 75]  # a partial view of image i
        assert top_k(db, vlad.describe(half), 3)[0] == i
    back = Vlad.from_arrays(vlad.to_arrays())
    assert np.array_equal(back.describe(desc[:10]), vlad.describe(desc[:10]))
    assert np.all(vlad.describe(desc[:0]) == 0)


def test_hamming_matrix_matches_pairwise() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.integers(0, 256, (7, 32), dtype=np.uint8), rng.integers(0, 256, (5, 32), dtype=np.uint8)
    expected = np.array([[int(np.unpackbits(x ^ y).sum()) for y in b] for x in a])
    assert np.array_equal(hamming_matrix(a, b), expected)
    assert np.array_equal(hamming(a[:, None], b[None]), expected)


def test_vocabulary_tree_words_and_scores() -> None:
    rng = np.random.default_rng(2)
    n_images, per_image = 10, 120
    prototypes = rng.integers(0, 256, (n_images * 6, 32), dtype=np.uint8)
    flips = rng.random((n_images * per_image, 256)) < 0.03
    picks = np.concatenate([rng.integers(6 * i, 6 * i + 6, per_image) for i in range(n_images)])
    desc = np.packbits(np.unpackbits(prototypes[picks], axis=1) ^ flips, axis=1)
    offsets = np.arange(0, (n_images + 1) * per_image, per_image)
    cfg = VocabularyConfig(branching=4, depth=3, training_descriptors=2000)
    tree = VocabularyTree.fit(desc, offsets, cfg)
    words, nodes = tree.transform(desc, level=1)
    assert np.all(tree.children[words, 0] == -1)  # words are leaves
    assert np.all(tree.level[nodes] == 1) and np.all(tree.idf[words] >= 0)
    bow = tree.bow_matrix(words, offsets)
    assert np.allclose(np.asarray(bow.sum(axis=1)).ravel(), 1.0)
    for i in range(n_images):
        score, shared = tree.score(bow, tree.bow(words[offsets[i] : offsets[i] + 60]))
        assert np.argmax(score) == i and shared[i] > 0 and score.max() <= 1 + 1e-9
    back = VocabularyTree.from_arrays(tree.to_arrays())
    assert np.array_equal(back.transform(desc[:50], 1)[0], words[:50])


@pytest.mark.parametrize("cls,bad", [(VladConfig, {"clusters": 0}), (VocabularyConfig, {"branching": 1})])
def test_config_validation(cls: type, bad: dict) -> None:
    with pytest.raises(ConfigError):
        from_dict(cls, bad)
