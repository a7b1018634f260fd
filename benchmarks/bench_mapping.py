"""Mapping benchmark: time per step, map size (MB, MB/landmark), 3D instance P/R (against the
scene's object boxes), frames kept, and what invalid-object filtering removes: the reference-frame
frequency of every ground-truth category, structural (wall/floor/ceiling...) vs furniture.

    python benchmarks/bench_mapping.py DATA/smoke-room [more scenes] [--encoder offline]
        [--segmenter noisy-gt] [--out results.json]

Builds the oracle-mask map (dataset masks) and, with ``--segmenter``, the clustered map, for each
scene; prints one table row per (scene, instances source).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import torch

from openreloc_bench.data.scene import Scene
from openreloc_bench.openreloc.build import MappingConfig, build_object_map
from openreloc_bench.openreloc.map import map_size_bytes
from openreloc_bench.vision import create_encoder, create_segmenter


def bench_scene(scene_dir: Path, encoder_name: str, encoder_cfg: dict, segmenter: str | None) -> list[dict]:
    seq = Scene(scene_dir).sequence("mapping")
    encoder = create_encoder(encoder_name, **encoder_cfg)
    rows = []
    for source in ["masks"] + ([segmenter] if segmenter else []):
        seg = None if source == "masks" else create_segmenter(source)
        t = time.perf_counter()
        m = build_object_map(seq, MappingConfig(), encoder, seg, progress=False)
        wall = time.perf_counter() - t
        with tempfile.TemporaryDirectory() as d:
            m.save(Path(d))
            size = map_size_bytes(Path(d))
        n = max(len(m.landmarks), 1)
        objects = Scene(scene_dir).objects
        structural = {o.category for o in objects.values() if o.structural}
        freq = {int(i): f for i, f in m.stats["reference_frequency"].items()}
        by_cat = sorted(((round(f, 2), m.landmarks[i].category or "?") for i, f in freq.items()), reverse=True)
        q = m.stats["instance_quality"] or {}
        rows.append(
            {
                "scene": scene_dir.name,
                "instances": source,
                "frames": len(seq),
                "frames_skipped": len(m.stats["frames_skipped"]),
                "reference_frames": m.stats["reference_frames"],
                "landmarks": len(m.landmarks),
                "valid": len(m.valid_ids()),
                "precision@0.5": q.get("precision"),
                "recall@0.5": q.get("recall"),
                "map_MB": size / 1e6,
                "MB_per_landmark": size / 1e6 / n,
                "time_s": wall,
                "timings_s": m.stats["timings_s"],
                "invalid_categories": m.stats["invalid_categories"],
                "frequency_by_category": by_cat,
                "max_furniture_frequency": max((f for f, c in by_cat if c not in structural), default=0.0),
                "structural_frequencies": [f for f, c in by_cat if c in structural],
                "instance_reference": q.get("reference"),
            }
        )
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenes", nargs="+", type=Path)
    p.add_argument("--encoder", default="offline")
    p.add_argument("--encoder-model", default=None, help="passed as model=... (e.g. a CLIP checkpoint)")
    p.add_argument("--segmenter", default="noisy-gt", help="'' to skip the clustered map")
    p.add_argument("--out", type=Path)
    args = p.parse_args()
    torch.set_num_threads(1)
    enc_cfg = {"model": args.encoder_model} if args.encoder_model else {}
    rows = [r for s in args.scenes for r in bench_scene(s, args.encoder, enc_cfg, args.segmenter or None)]
    for r in rows:
        steps = " ".join(f"{k}={v:.1f}" for k, v in r["timings_s"].items() if k != "total")
        print(
            f"{r['scene']:16s} {r['instances']:9s} frames {r['frames']} (skipped {r['frames_skipped']}, "
            f"kept {r['reference_frames']}) landmarks {r['landmarks']} ({r['valid']} valid) "
            f"P/R {r['precision@0.5']:.2f}/{r['recall@0.5']:.2f} map {r['map_MB']:.3f} MB "
            f"({r['MB_per_landmark'] * 1000:.1f} kB/landmark) time {r['time_s']:.1f}s [{steps}] "
            f"filtered: {', '.join(r['invalid_categories'])}"
        )
        print(
            f"    reference-frame frequency: structural {r['structural_frequencies']} | "
            f"furniture max {r['max_furniture_frequency']:.2f} | top: {r['frequency_by_category'][:8]}"
        )
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
