"""The segmenter's training end to end on tiny scenes: the card it writes, returns and reports."""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "vision"))
from vision_scenes import write_shapes_scene  # noqa: E402

from openreloc_bench.harness.train_segmenter import SegmenterTrainingConfig, main  # noqa: E402
from openreloc_bench.vision.learned_segment import NetConfig  # noqa: E402
from openreloc_bench.vision.segmenter_training import SegTrainConfig  # noqa: E402


def test_training_writes_the_card_it_returns_and_says_the_held_out_scores(tmp_path: Path) -> None:
    for name, seed in (("train/t0", 0), ("train/t1", 1), ("eval/e0", 100)):
        write_shapes_scene(tmp_path / "data" / name, seed=seed)
    cfg = SegmenterTrainingConfig(
        out=tmp_path / "w", data=tmp_path / "data", scenes=1, eval_scenes=1, per_split=2, width=64, height=48,
        workers=1, init=None, net=NetConfig(), train=SegTrainConfig(steps=2, batch=2, crop=48, threads=1),
    )  # fmt: skip
    said: list[str] = []
    card = main(cfg, say=said.append)
    assert card["data"]["train_seeds"] == [0, 1] and card["data"]["eval_seeds"] == [100]
    assert json.loads((tmp_path / "w" / "card.json").read_text()) == {
        **card,
        "net": {"widths": [16, 24, 48, 96, 128], "work_width": 320},
    }
    assert said[0] == "12 training frames from 2 scenes; 6 held-out frames"  # 2 frames of each split per scene
    assert said[-2].startswith(f"held-out (threshold {card['threshold']}): mean best IoU")
    assert said[-1] == f"wrote {tmp_path / 'w'} (use segmenter_options: {{weights: {tmp_path / 'w'}}})"
