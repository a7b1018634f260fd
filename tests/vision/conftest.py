"""Vision test fixtures: the tiny random CLIP checkpoint (written once per session)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch

from openreloc_bench.vision.testing import tiny_clip_checkpoint

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the shared helper module vision_scenes.py


@pytest.fixture(scope="session", autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


@pytest.fixture(scope="session")
def tiny_clip_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tiny_clip_checkpoint(tmp_path_factory.mktemp("clip") / "tiny-clip")


@pytest.fixture(scope="session")
def clip_encoder(tiny_clip_dir: Path):
    from openreloc_bench.vision import create_encoder

    return create_encoder("clip", model=str(tiny_clip_dir))
