"""The trainings' scenes: each training's own part of the seed range reserved for training, its scenes
generated (or finished) under ``train/`` and ``eval/``, or the user's scenes there used as they are, and
the check that the held-out scenes are no training scene.

The generator is imported only to generate, so trainings on existing scenes work where it is not installed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from openreloc_bench.data import io
from openreloc_bench.data.scene import check_scene_info
from openreloc_bench.errors import ConfigError

SEEDS_PER_TRAINING_SEED = 1000
"""Scene seeds of consecutive training seeds (``--seed``) start this far apart."""


@dataclass(frozen=True)
class TrainingData:
    """Where one training's scenes come from. Scene ``i`` of training seed ``s`` has the seed
    ``TRAINING_SEED_MIN + offset + 1000 * s + i`` (``generators.spec``): the offsets keep every training's
    training and held-out scenes apart from each other and from the other trainings'."""

    train_offset: int
    """Offset of the training scenes' seeds."""
    eval_offset: int
    """Offset of the held-out scenes' seeds."""
    spec: dict[str, Any] = field(default_factory=dict)
    """Further spec fields of every scene (``generators.generate.training_specs``)."""

    def seeds(self, offset: int, seed: int, n: int) -> list[int]:
        """The seeds of ``n`` scenes from ``offset`` for training seed ``seed``."""
        from generators.spec import TRAINING_SEED_MIN

        start = TRAINING_SEED_MIN + offset + SEEDS_PER_TRAINING_SEED * seed
        return [start + i for i in range(n)]


ENCODER_DATA = TrainingData(
    0, 500_000, dict(max_mapping_frames=24, n_query=8, displaced_share=0.0, removed_share=0.0, added_share=0.0)
)
"""``train-encoder``: crops come from a few frames of each scene."""
SEGMENTER_DATA = TrainingData(
    200_000, 700_000, dict(with_floors=True, max_mapping_frames=30, n_query=10, displaced_share=0.1)
)
"""``train-segmenter``: a few frames of every split per scene (frames are sampled per split)."""
MERGER_DATA = TrainingData(
    300_000, 800_000, dict(with_floors=True, objects_per_room=30, room_side_max=5.5, n_query=5, displaced_share=0.1)
)
"""``train-merger``: scenes as dense as the benchmark suites' (their mapping paths whole); queries are not used."""


def training_scene_sets(
    data: Path, recipe: TrainingData, seed: int, n_train: int, n_eval: int, width: int, height: int, workers: int
) -> tuple[list[Path], list[Path], bool]:
    """The scenes to train on and the held-out ones: those under ``data/train`` and ``data/eval`` when both
    hold some (never written to), else ``recipe``'s scenes of training seed ``seed``, generated or finished
    there. The third value says whether they were generated."""
    train_dirs, eval_dirs = scene_dirs(data / "train"), scene_dirs(data / "eval")
    if train_dirs and eval_dirs:
        return train_dirs, eval_dirs, False
    size = (width, height, workers)
    train_dirs = training_scenes(
        data / "train", "train", recipe.seeds(recipe.train_offset, seed, n_train), *size, **recipe.spec
    )
    eval_dirs = training_scenes(
        data / "eval", "eval", recipe.seeds(recipe.eval_offset, seed, n_eval), *size, **recipe.spec
    )
    return train_dirs, eval_dirs, True


def scene_seeds(dirs: list[Path]) -> list[int | None]:
    """Each scene's seed, from its ``scene.json`` (checked)."""
    return [check_scene_info(io.read_json(d / "scene.json"), d / "scene.json").get("seed") for d in dirs]


def held_out_seeds(train_dirs: list[Path], eval_dirs: list[Path]) -> tuple[list[int | None], list[int | None]]:
    """The seeds of the training and of the held-out scenes; ConfigError when the two share one."""
    train_seeds, eval_seeds = scene_seeds(train_dirs), scene_seeds(eval_dirs)
    if set(train_seeds) & set(eval_seeds):
        raise ConfigError("training and evaluation scenes share seeds; evaluation must be on held-out scenes")
    return train_seeds, eval_seeds


def scene_dirs(root: Path) -> list[Path]:
    """The generated scenes directly under ``root`` (folders holding a ``scene.json``), sorted."""
    return sorted(p for p in root.iterdir() if (p / "scene.json").is_file()) if root.is_dir() else []


def training_scenes(
    root: Path,
    prefix: str,
    seeds: list[int],
    width: int,
    height: int,
    workers: int,
    with_floors: bool = False,
    **overrides: Any,
) -> list[Path]:
    """Generate (or finish) one training scene per reserved seed under ``root``, in spawned processes
    (``generators.generate.training_specs``: ``overrides`` set further spec fields of every scene)."""
    try:
        from generators.generate import generate_scenes, training_specs
    except ImportError as e:
        raise ConfigError(
            f"the scene generator is not available ({e}); pass --data with train/ and eval/ scenes"
        ) from None
    specs = training_specs(prefix, seeds, width, height, with_floors=with_floors, **overrides)
    root.mkdir(parents=True, exist_ok=True)
    return generate_scenes(specs, root, resume=True, workers=workers, desc=f"{prefix} scenes")
