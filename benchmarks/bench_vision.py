"""Speed of the vision backends on this machine: encoders, describers, segmenters.

Prints ms per crop (batch of 32 and single) for the offline encoder and for CLIP (the tiny random
test checkpoint and a randomly initialised ViT-B/32-shaped one, for a realistic cost), ms per text,
ms per description, and ms per segmentation at 640x480 with the mask quality of each segmenter
against ground truth (mean best IoU per object) on rendered frames.

    .venv/bin/python benchmarks/bench_vision.py [--scene DIR] [--threads 1] [--no-vitb32]

Without ``--scene`` a small 640x480 scene is generated into a temporary directory.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from openreloc_bench.data.scene import Scene
from openreloc_bench.vision import create_describer, create_encoder, create_segmenter
from openreloc_bench.vision import vocabulary as voc
from openreloc_bench.vision.offline import WEIGHTS_DIR
from openreloc_bench.vision.preprocess import object_crop
from openreloc_bench.vision.testing import random_clip_checkpoint, tiny_clip_checkpoint


def ms(fn: Callable[[], object], repeat: int) -> float:
    fn()  # warm-up
    t0 = time.perf_counter()
    for _ in range(repeat):
        fn()
    return 1000 * (time.perf_counter() - t0) / repeat


def bench_encoder(label: str, enc, crops: list[np.ndarray], repeat: int) -> None:
    batch = crops[:32]
    b = ms(lambda: enc.encode_images(batch), max(1, repeat // 4)) / len(batch)
    s = ms(lambda: enc.encode_images(batch[:1]), repeat)
    texts = [f"a photo of a red chair number {i}" for i in range(32)]
    counter = iter(range(10**9))
    # fresh strings each call, so the offline encoder's text cache does not hide the cost
    t = ms(lambda: enc.encode_texts([f"a small blue lamp {next(counter)}"]), repeat)
    tb = ms(lambda: enc.encode_texts([f"{x} {next(counter)}" for x in texts]), max(1, repeat // 4)) / 32
    print(
        f"{label:28s} image: {b:7.2f} ms/crop (batch 32) {s:8.2f} ms (single) | text: {tb:6.2f} ms/text (batch 32) {t:7.2f} ms (single)"
    )


def mean_best_iou(objs, instance: np.ndarray, ids: list[int], min_area: float) -> list[float]:
    out = []
    for oid in ids:
        gt = instance == oid
        if gt.sum() >= min_area:
            out.append(max([float((o.mask & gt).sum() / (o.mask | gt).sum()) for o in objs], default=0.0))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", type=Path, help="a generated scene at 640x480 (default: generate one)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--frames", type=int, default=8, help="query frames for segmentation timing and IoU")
    ap.add_argument("--no-vitb32", action="store_true", help="skip the ViT-B/32-shaped CLIP")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    tmp = Path(tempfile.mkdtemp(prefix="bench_vision_"))
    scene_dir = args.scene
    if scene_dir is None:
        os.environ.setdefault("MUJOCO_GL", "egl")
        from generators.generate import generate_scene
        from generators.spec import TRAINING_SEED_MIN, SceneSpec

        spec = SceneSpec(
            name="bench",
            seed=TRAINING_SEED_MIN + 999_999,
            n_query=args.frames,
            max_mapping_frames=8,
            displaced_share=0.0,
            removed_share=0.0,
            added_share=0.0,
        )
        scene_dir = generate_scene(spec, tmp, progress=False)
    scene = Scene(scene_dir)
    seq = scene.sequence("query")
    frames = [seq[i] for i in range(min(args.frames, len(seq)))]
    ids = [i for i, o in scene.objects.items() if not o.structural]
    h, w = frames[0].color.shape[:2]
    objs = [
        (
            f,
            create_segmenter("gt", exclude_ids=[i for i, o in scene.objects.items() if o.structural]).segment(
                f.color, f.instance
            ),
        )
        for f in frames
    ]
    crops = []
    for f, masks in objs:
        crops += [object_crop(f.color, m.mask) for m in masks]
    while len(crops) < 32:
        crops += crops
    print(
        f"torch threads {args.threads}; {len(frames)} frames {w}x{h} from {scene_dir}; crops of sizes {min(c.shape[0] for c in crops)}-{max(c.shape[0] for c in crops)} px"
    )

    print("\n== encoders ==")
    encoders = {}
    if (WEIGHTS_DIR / "image_tower.pt").is_file():
        encoders["offline"] = create_encoder("offline")
    else:
        print("offline: no committed weights yet (run openreloc-bench train-encoder)")
    encoders["clip (tiny random)"] = create_encoder("clip", model=str(tiny_clip_checkpoint(tmp / "tiny")))
    if not args.no_vitb32:
        b32 = random_clip_checkpoint(
            tmp / "b32",
            text=dict(hidden_size=512, intermediate_size=2048, num_hidden_layers=12, num_attention_heads=8),
            vision=dict(
                hidden_size=768,
                intermediate_size=3072,
                num_hidden_layers=12,
                num_attention_heads=12,
                image_size=224,
                patch_size=32,
            ),
            projection_dim=512,
        )
        encoders["clip (ViT-B/32 shape)"] = create_encoder("clip", model=str(b32))
    for label, enc in encoders.items():
        bench_encoder(label, enc, crops, args.repeat if "B/32" not in label else 4)

    print("\n== describers ==")
    f, masks = objs[0]
    for label, enc in encoders.items():
        if "B/32" in label:
            continue
        d = create_describer("offline", encoder=enc)
        d.describe(f.color, masks[0].mask)
        t = ms(lambda d=d: [d.describe(f.color, m.mask) for m in masks], 2) / len(masks)
        print(
            f"offline describer on {label:22s} {t:7.2f} ms/description  e.g. {d.describe(f.color, masks[0].mask)!r} "
            f"(truth: {scene.objects[masks[0].instance_id].description!r})"
        )
        hits, colour_hits, n = 0, 0, 0
        for fr, ms_ in objs:
            for m in ms_[:10]:
                o = scene.objects[m.instance_id]
                text = f" {d.describe(fr.color, m.mask)} "
                names = {voc.noun(o.category), *voc.HELD_OUT_SYNONYMS.get(o.category, ())}
                hits += any(text.endswith(f" {x} ") for x in names)
                colour_hits += f" {o.attributes.get('colour', '?')} " in text
                n += 1
        print(
            f"{'':43s} category noun right {hits}/{n} = {hits / n:.2f}, colour right {colour_hits / n:.2f} "
            f"(open vocabulary of {len(d.nouns)} nouns x {len(voc.COLOURS)} colours x {len(voc.MATERIALS)} materials)"
        )

    print(f"\n== segmenters ({w}x{h}) ==")
    for name, kw in (("gt", {}), ("noisy-gt", {"seed": 0}), ("graph", {})):
        seg = create_segmenter(name, **kw)
        t = ms(lambda seg=seg: [seg.segment(fr.color, fr.instance) for fr in frames], 1) / len(frames)
        ious, n = [], 0
        for fr in frames:
            out = seg.segment(fr.color, fr.instance)
            n += len(out)
            ious += mean_best_iou(out, fr.instance, ids, 0.002 * h * w)
        print(
            f"{name:10s} {t:8.1f} ms/image  {n / len(frames):5.1f} masks/image  mean best IoU vs GT {np.mean(ious):.3f} ({len(ious)} objects >= 0.2% of the image)"
        )


if __name__ == "__main__":
    main()
