"""Real CLIP through transformers' ``CLIPModel``: a local checkpoint directory or a hub id.

Preprocessing is CLIP's own (resize the shortest side with bicubic filtering, centre crop, mean/std),
written with PIL/numpy so torchvision is never needed. Sizes and mean/std come from the checkpoint's
``preprocessor_config.json`` when it has one, else OpenAI's values.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from PIL import Image

from openreloc_bench.data import io
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.vision.base import ImageTextEncoder, l2_normalize, register_encoder
from openreloc_bench.vision.preprocess import check_crops, check_texts

CLIP_MEAN = (0.48145466, 0.4578275, 0.40821073)
CLIP_STD = (0.26862954, 0.26130258, 0.27577711)
DEFAULT_CLIP = "openai/clip-vit-base-patch32"
_HUB_ID = re.compile(r"^[A-Za-z0-9][\w.-]*(/[\w.-]+)?$")
"""What a hub id looks like; anything else is taken as a local path."""

WEIGHTS_HINT = (
    "give model=<directory> holding a CLIPModel saved with save_pretrained() plus its tokenizer "
    "(e.g. CLIPModel.from_pretrained('openai/clip-vit-base-patch32').save_pretrained(DIR) on a machine "
    "with a network), or a hub id where this machine has a network"
)


def clip_preprocess(
    crops: Sequence[np.ndarray], size: int, mean: Sequence[float], std: Sequence[float]
) -> torch.Tensor:
    """RGB uint8 crops -> (N, 3, size, size) float tensor, CLIP style (shortest side, centre crop)."""
    out = np.empty((len(crops), size, size, 3), dtype=np.float32)
    for i, c in enumerate(crops):
        h, w = c.shape[:2]
        s = size / min(h, w)
        nw, nh = max(size, round(w * s)), max(size, round(h * s))
        img = Image.fromarray(c).resize((nw, nh), Image.Resampling.BICUBIC)
        left, top = (nw - size) // 2, (nh - size) // 2
        out[i] = np.asarray(img.crop((left, top, left + size, top + size)), dtype=np.float32) / 255.0
    out = (out - np.asarray(mean, np.float32)) / np.asarray(std, np.float32)
    return torch.from_numpy(out.transpose(0, 3, 1, 2).copy())


def _channel_values(value: Any, path: Path, key: str) -> tuple[float, float, float]:
    """Three finite per-channel numbers (``std`` also > 0) from a preprocessor config, else a DataError."""
    ok = isinstance(value, (list, tuple)) and len(value) == 3
    ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in value)
    if not ok or (key == "image_std" and min(value) <= 0):
        raise DataError(
            path, f"'{key}' must be three finite numbers{' > 0' if key == 'image_std' else ''}, got {value!r}"
        )
    return (float(value[0]), float(value[1]), float(value[2]))


def _features(out: Any) -> torch.Tensor:
    """transformers < 5 returns the projected tensor, >= 5 an output object with it as pooler_output."""
    return out if isinstance(out, torch.Tensor) else out.pooler_output


@register_encoder("clip")
class ClipEncoder(ImageTextEncoder):
    """CLIP image and text towers (OpenAI/OpenCLIP-converted checkpoints in transformers format)."""

    name = "clip"

    def __init__(self, model: str = DEFAULT_CLIP, batch_size: int = 32, threads: int | None = None):
        from transformers import AutoTokenizer, CLIPModel
        from transformers.utils import logging as hf_logging

        hf_logging.disable_progress_bar()  # no per-load weight bars in benchmark and harness logs

        self.model_id = str(model)
        self.batch_size = int(batch_size)
        if threads:
            torch.set_num_threads(int(threads))
        path = Path(self.model_id).expanduser()
        is_local = path.is_dir()
        if not is_local and not _HUB_ID.match(self.model_id):
            raise ConfigError(f"CLIP weights not found at '{self.model_id}': {WEIGHTS_HINT}")
        if is_local and not (path / "config.json").is_file():
            raise ConfigError(f"'{path}' is not a CLIP checkpoint directory (no config.json): {WEIGHTS_HINT}")
        source = str(path) if is_local else self.model_id
        try:
            self.model = CLIPModel.from_pretrained(source, local_files_only=is_local).eval()
            self.tokenizer = AutoTokenizer.from_pretrained(source, local_files_only=is_local)
        except OSError as e:
            raise ConfigError(
                f"cannot load CLIP '{self.model_id}' ({str(e).splitlines()[0]}): {WEIGHTS_HINT}"
            ) from None
        vcfg = self.model.config.vision_config
        self.image_size = int(vcfg.image_size)
        self.mean, self.std = CLIP_MEAN, CLIP_STD
        pre = path / "preprocessor_config.json" if is_local else None
        if pre is not None and pre.is_file():
            p = io.read_json(pre)
            p = p if isinstance(p, dict) else {}
            self.mean = _channel_values(p.get("image_mean", CLIP_MEAN), pre, "image_mean")
            self.std = _channel_values(p.get("image_std", CLIP_STD), pre, "image_std")
        self.max_length = int(self.model.config.text_config.max_position_embeddings)
        self.dim = int(self.model.config.projection_dim)

    @torch.no_grad()
    def encode_images(self, crops: Sequence[np.ndarray]) -> np.ndarray:
        crops = check_crops(crops)
        out = np.zeros((len(crops), self.dim), np.float32)
        for s in range(0, len(crops), self.batch_size):
            px = clip_preprocess(crops[s : s + self.batch_size], self.image_size, self.mean, self.std)
            out[s : s + len(px)] = _features(self.model.get_image_features(pixel_values=px)).numpy()
        return l2_normalize(out)

    @torch.no_grad()
    def encode_texts(self, texts: Sequence[str]) -> np.ndarray:
        texts = check_texts(texts)
        out = np.zeros((len(texts), self.dim), np.float32)
        for s in range(0, len(texts), self.batch_size):
            tok = self.tokenizer(
                texts[s : s + self.batch_size],
                padding="max_length",
                truncation=True,
                max_length=self.max_length,
                return_tensors="pt",
            )
            feats = self.model.get_text_features(input_ids=tok["input_ids"], attention_mask=tok["attention_mask"])
            out[s : s + len(tok["input_ids"])] = _features(feats).numpy()
        return l2_normalize(out)

    def config(self) -> dict[str, Any]:
        return {"name": self.name, "model": self.model_id}

    @classmethod
    def weights_fingerprint(cls, model: str = "", **_: Any) -> str:
        """The checkpoint's directory or hub id (hashing gigabytes of weights per run would cost more than it saves)."""
        return str(model)
