"""Quality and speed of the class-agnostic segmenters on held-out scenes of all three kinds.

For each segmenter: mean best IoU per ground-truth object and AP50 (objects covering >= 1% of the
image; smaller ones neither count nor penalise), over- and under-segmentation rates (objects split
over >= 2 segments; objects whose main segment is mostly something else), and ms per frame (CPU,
``--threads`` torch threads), per split. Scenes come from the benchmark suites (never trained or
tuned on), e.g. four single-room, four multi-room and two multi-floor scenes:

    .venv/bin/python benchmarks/bench_segmenter.py \\
        --scenes DATA/single-room/room1,...,DATA/multi-room/sc1,...,DATA/multi-floor/sc7 \\
        --segmenters learned,graph,noisy-gt --frames 12 --splits query,query_light4
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from openreloc_bench.data.scene import Scene
from openreloc_bench.vision import create_segmenter
from openreloc_bench.vision.base import label_image
from openreloc_bench.vision.segmenter_training import frame_metrics, summarize


def labels_of(masks, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """A label image (0 = no segment; where masks overlap, the first wins) and the masks' scores."""
    return label_image(masks, shape), np.array([m.score for m in masks], float)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", required=True, help="comma-separated scene directories (held-out scenes)")
    ap.add_argument("--segmenters", default="learned,graph,noisy-gt", help="comma-separated segmenter names")
    ap.add_argument("--weights", help="weights directory of the learned segmenter (default: the shipped ones)")
    ap.add_argument("--splits", default="query,query_light4", help="comma-separated splits")
    ap.add_argument("--frames", type=int, default=12, help="frames per split and scene (evenly spaced)")
    ap.add_argument("--threads", type=int, default=2, help="torch threads")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    scenes = [Scene(Path(s)) for s in args.scenes.split(",") if s]
    print(f"{len(scenes)} scenes: {', '.join(s.name for s in scenes)}")
    header = f"{'segmenter':10s} {'split':14s} {'frames':>6s} {'objects':>7s} {'mIoU':>6s} {'AP50':>6s} {'over':>6s} {'under':>6s} {'ms/frame':>9s}"
    print(header)
    for name in args.segmenters.split(","):
        opts = {"weights": args.weights, "threads": args.threads} if name == "learned" else {}
        seg = create_segmenter(name, **{k: v for k, v in opts.items() if v is not None})
        for split in args.splits.split(","):
            stats, times, size = [], [], None
            for scene in scenes:
                seq = scene.sequence(split)
                for i in np.linspace(0, len(seq) - 1, min(args.frames, len(seq))).round().astype(int):
                    f = seq[int(i)]
                    size = f.color.shape[1::-1]
                    t0 = time.perf_counter()
                    masks = seg.segment(f.color, f.instance)
                    times.append(time.perf_counter() - t0)
                    labels, scores = labels_of(masks, f.instance.shape)
                    present = np.unique(labels)
                    scores = scores[present[present > 0] - 1]  # segments hidden under earlier ones drop out
                    stats.append(frame_metrics(labels, f.instance, scores, 0.01))
            s = summarize(stats)
            print(
                f"{name:10s} {split:14s} {len(stats):6d} {s['objects']:7d} {s['mean_best_iou']:6.3f} {s['ap50']:6.3f} "
                f"{s['over_segmentation']:6.3f} {s['under_segmentation']:6.3f} {1000 * np.median(times):9.1f}"
                f"  ({size[0]}x{size[1]})"
            )


if __name__ == "__main__":
    main()
