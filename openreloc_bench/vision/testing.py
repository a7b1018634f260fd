"""Test helpers other modules' tests use too: a tiny, randomly initialised CLIP checkpoint on disk.

It goes through exactly the loading path of real checkpoints (``CLIPModel.save_pretrained`` + a
CLIP BPE tokenizer), so code built on ``create_encoder("clip", model=...)`` is testable offline.
Its embeddings carry no meaning.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch

from openreloc_bench.data import io


def _byte_symbols() -> list[str]:
    """GPT-2/CLIP byte-level BPE alphabet: one printable symbol per byte value."""
    printable = (
        list(range(ord("!"), ord("~") + 1)) + list(range(ord("¡"), ord("¬") + 1)) + list(range(ord("®"), ord("ÿ") + 1))
    )
    extra = [256 + i for i in range(256 - len(printable))]
    return [chr(c) for c in printable + extra]


def tiny_clip_checkpoint(directory: Path | str, seed: int = 0, projection_dim: int = 32, image_size: int = 32) -> Path:
    """Write a tiny random CLIP (model, tokenizer, preprocessor config) into ``directory``; return it.

    Idempotent: an existing complete checkpoint is reused (same seed -> same weights either way).
    """
    text = dict(hidden_size=32, intermediate_size=64, num_hidden_layers=2, num_attention_heads=2)
    vision = dict(
        hidden_size=32,
        intermediate_size=64,
        num_hidden_layers=2,
        num_attention_heads=2,
        image_size=image_size,
        patch_size=8,
    )
    return random_clip_checkpoint(directory, text, vision, projection_dim, seed)


def random_clip_checkpoint(directory: Path | str, text: dict, vision: dict, projection_dim: int, seed: int = 0) -> Path:
    """A randomly initialised CLIP of any shape (e.g. ViT-B/32-sized, to measure realistic CPU cost)."""
    from transformers import CLIPConfig, CLIPModel, CLIPTokenizer

    directory = Path(directory)
    if (directory / "config.json").is_file() and (directory / "tokenizer_config.json").is_file():
        return directory
    directory.mkdir(parents=True, exist_ok=True)
    symbols = _byte_symbols()
    tokens = symbols + [s + "</w>" for s in symbols]
    merges = [("t", "h"), ("th", "e</w>"), ("a", "r"), ("c", "h"), ("o", "r"), ("e", "d</w>")]
    tokens += ["".join(m) for m in merges] + ["<|startoftext|>", "<|endoftext|>"]
    vocab = {t: i for i, t in enumerate(dict.fromkeys(tokens))}
    io.atomic_write_text(directory / "vocab.json", json.dumps(vocab))
    io.atomic_write_text(directory / "merges.txt", "#version: 0.2\n" + "\n".join(" ".join(m) for m in merges) + "\n")
    CLIPTokenizer.from_pretrained(str(directory)).save_pretrained(str(directory))
    bos, eos = vocab["<|startoftext|>"], vocab["<|endoftext|>"]
    config = CLIPConfig(
        text_config=dict(
            vocab_size=len(vocab),
            max_position_embeddings=77,
            bos_token_id=bos,
            eos_token_id=eos,
            pad_token_id=eos,
            **text,
        ),
        vision_config=dict(vision),
        projection_dim=projection_dim,
    )
    torch.manual_seed(seed)
    CLIPModel(config).save_pretrained(str(directory))
    size = int(config.vision_config.image_size)
    io.write_json(
        directory / "preprocessor_config.json",
        {
            "crop_size": size,
            "image_mean": [0.48145466, 0.4578275, 0.40821073],
            "image_std": [0.26862954, 0.26130258, 0.27577711],
            "size": {"shortest_edge": size},
        },
    )
    return directory
