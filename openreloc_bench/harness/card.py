"""The dataset card of a suite: ``OUT/<suite>.md`` and its pictures in ``OUT/<suite>/``.

What a reader of a board needs to know about the data behind it: which scenes, how many frames of each
split, which objects (and which have an identical twin), how hard the queries are on each difficulty
axis, and what the frames and plans look like. It reads the suite YAML and the generated scenes under
``--data`` (``scene.json``, ``objects.json``, ``difficulty.csv``, frames) and nothing else, so the same
data gives the same bytes and the card can be committed next to the boards. Pictures are palette PNGs
of thumbnails and low-resolution figures, about 0.1 MB per scene (smoke: 0.12 MB in all).
"""

from __future__ import annotations

import json
from collections import Counter
from io import BytesIO
from pathlib import Path
from typing import Any

import cv2
import matplotlib

matplotlib.use("Agg")  # headless: no display on benchmark machines
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from PIL import Image  # noqa: E402

from openreloc_bench import bars  # noqa: E402
from openreloc_bench.data import io, paths  # noqa: E402
from openreloc_bench.data.scene import DATA_VERSION, Scene, check_scene_info, other_version  # noqa: E402
from openreloc_bench.data.splits import OWN_POSE_SPLITS, QUERY_SPLIT_TABLE, QUERY_SPLITS  # noqa: E402
from openreloc_bench.errors import DataError  # noqa: E402
from openreloc_bench.harness.suites import scene_state, suite_spec  # noqa: E402
from openreloc_bench.harness.tables import md_table  # noqa: E402

VARIANT_SPLITS = tuple(s.name for s in QUERY_SPLIT_TABLE if s.shares_query_poses)
"""The plain query split and its variants: the same poses."""
SPLIT_COLUMNS = ("mapping", *OWN_POSE_SPLITS, *(s for s in QUERY_SPLITS if s not in OWN_POSE_SPLITS))
"""Splits in the order the scene table lists them: the mapping path, the query sets with poses of their
own, the variants."""

AXES: dict[str, tuple[str, tuple[str, ...]]] = {
    "gap_m": ("distance to the nearest mapping camera (m)", OWN_POSE_SPLITS),
    "gap_deg": ("smallest rotation to a mapping frame within 1 m (deg)", OWN_POSE_SPLITS),
    "visible_objects": ("objects covering >= 0.5% of the image", OWN_POSE_SPLITS),
    "object_area": ("image share covered by objects", OWN_POSE_SPLITS),
    "lookalikes_in_view": ("visible objects with an identical twin in the scene", OWN_POSE_SPLITS),
    "displaced_in_view": (
        "changes in view: moved or added objects it shows, removed ones it would",
        ("query_displaced",),
    ),
    "light_level": ("brightness relative to the mapping lighting", QUERY_SPLITS),
}
"""Each difficulty axis of ``difficulty.csv``: what it measures and the splits whose frames it describes
(the lighting variants and ``query_displaced`` share ``query``'s poses, so their gaps are ``query``'s)."""

INTEGER_AXES = ("visible_objects", "lookalikes_in_view", "displaced_in_view")

SPLIT_COLOURS = {
    "query": "tab:red",
    "query_near": "tab:blue",
    "query_walk": "tab:green",
    "query_displaced": "tab:purple",
}

THUMB_W = 128
"""Width (px) of a contact-sheet thumbnail: enough to recognise a room, small enough to commit."""
SHEET_COLUMNS = 6
PALETTE = 64
"""Colours of a picture's palette: a contact sheet in a quarter of a full-colour PNG's size, thumbnails and
plots still as they look."""
PLOT_DPI = 72


def write_card(suite_path: Path, data: Path, out: Path) -> list[Path]:
    """Write the card of the suite at ``suite_path`` from its scenes under ``data``; returns the files
    written (the markdown first). One-line errors for a scene missing, incomplete, from another spec or
    of another benchmark data version."""
    suite, scenes = suite_scenes(Path(suite_path), Path(data))
    name = paths.plain_name(suite.name, "suite name")
    pictures = Path(out) / name
    pictures.mkdir(parents=True, exist_ok=True)
    difficulty = difficulty_table(scenes)
    written = [pictures / "difficulty.png"]
    _write_png(written[0], _figure_rgb(plot_difficulty(difficulty)))
    for scene in bars.tqdm(scenes, desc=f"card {name}", unit="scene"):
        written.append(pictures / f"{scene.name}_frames.png")
        _write_png(written[-1], contact_sheet(scene, difficulty))
        written.append(pictures / f"{scene.name}_plan.png")
        _write_png(written[-1], _figure_rgb(floor_plan_figure(scene)))
    md = Path(out) / f"{name}.md"
    io.atomic_write_text(md, card_markdown(suite, Path(suite_path).name, scenes, difficulty, name))
    return [md, *written]


def suite_scenes(suite_path: Path, data: Path) -> tuple[Any, list[Scene]]:
    """The suite and its scenes under ``data``, refused unless every scene is generated, of this benchmark
    data version, from the suite's spec and complete."""
    suite = suite_spec(suite_path)
    specs = suite.scene_specs()
    if not data.is_dir():
        raise DataError(data, "data directory not found")
    versions: dict[Any, list[str]] = {}
    for spec in specs:
        info_path = data / spec.name / "scene.json"
        if not info_path.is_file():
            raise DataError(
                data / spec.name,
                f"scene not generated: run `openreloc-bench generate {suite_path} --out {data}` first",
            )
        info = check_scene_info(io.read_json(info_path), info_path)
        versions.setdefault(info.get("data_version", 1), []).append(spec.name)
    if len(versions) > 1:
        mix = "; ".join(f"v{v}: {', '.join(names)}" for v, names in sorted(versions.items(), key=str))
        raise DataError(data, f"scenes of different benchmark data versions are mixed ({mix}); regenerate the suite")
    version = next(iter(versions))
    if version != DATA_VERSION:
        raise DataError(
            data,
            f"scenes {other_version(version)}: regenerate them (`openreloc-bench generate {suite_path} --out DIR`) "
            "into a new folder",
        )
    from generators.spec import spec_hash

    for spec in specs:
        state = scene_state(data / spec.name, spec_hash(spec))
        if state == "other spec":
            raise DataError(data / spec.name, f"generated from another spec than {suite_path} describes")
        if state == "partial":
            raise DataError(
                data / spec.name,
                f"incomplete: finish it with `openreloc-bench generate {suite_path} --out {data} --resume`",
            )
    return suite, [Scene(data / spec.name) for spec in specs]


def scene_table(scenes: list[Scene]) -> pd.DataFrame:
    """One row per scene: kind, floors, rooms, frames per split, objects, categories and look-alikes."""
    from generators.difficulty import lookalike_ids

    rows = []
    for s in scenes:
        objects = [o for o in s.objects.values() if not o.structural]
        counts = s.info.get("splits") or {}
        rows.append(
            {
                "scene": s.name,
                "kind": s.info.get("kind", ""),
                "floors": len(s.info.get("floors") or []),
                "rooms": len(s.info.get("rooms") or []),
                **{split: counts.get(split, 0) for split in SPLIT_COLUMNS},
                "objects": len(objects),
                "categories": len({o.category for o in objects}),
                "lookalikes": len(lookalike_ids(list(s.objects.values()))),
            }
        )
    return pd.DataFrame(rows)


def category_table(scenes: list[Scene]) -> pd.DataFrame:
    """Non-structural instances per category over the suite, and in how many scenes each occurs; most first."""
    counts: Counter[str] = Counter()
    in_scenes: Counter[str] = Counter()
    for s in scenes:
        cats = [o.category for o in s.objects.values() if not o.structural]
        counts.update(cats)
        in_scenes.update(set(cats))
    table = pd.DataFrame({"category": list(counts), "instances": list(counts.values())})
    table["scenes"] = table["category"].map(in_scenes)
    return table.sort_values(["instances", "category"], ascending=[False, True], ignore_index=True)


def lookalike_table(scenes: list[Scene]) -> pd.DataFrame:
    """Groups of identical twins (one model placed more than once in a scene): the model, its instances
    over the suite and the scenes holding them; largest first."""
    from generators.difficulty import lookalike_ids

    groups: dict[tuple, Counter[str]] = {}
    for s in scenes:
        for i in sorted(lookalike_ids(list(s.objects.values()))):
            groups.setdefault(s.objects[i].model, Counter())[s.name] += 1
    rows = [
        {
            "category": cat,
            "description": desc,
            "attributes": ", ".join(f"{k}={v}" for k, v in attrs),
            "instances": sum(per_scene.values()),
            "scenes": ", ".join(f"{n} ({c})" for n, c in per_scene.items()),
        }
        for (cat, desc, attrs), per_scene in groups.items()
    ]
    columns = ["category", "description", "attributes", "instances", "scenes"]
    table = pd.DataFrame(rows, columns=columns)
    return table.sort_values(["instances", "category", "description", "attributes"], ascending=[False] + [True] * 3)


def difficulty_table(scenes: list[Scene]) -> pd.DataFrame:
    """Every scene's ``difficulty.csv``, with a ``scene`` column."""
    tables = []
    for s in scenes:
        table = s.difficulty()
        if table is None:
            raise DataError(s.root / "difficulty.csv", "file not found: regenerate the scene")
        tables.append(table.assign(scene=s.name))
    return pd.concat(tables, ignore_index=True)


def difficulty_stats(difficulty: pd.DataFrame) -> pd.DataFrame:
    """Per axis and split: frames, 10th percentile, median, 90th percentile and maximum (generated scenes
    have every split)."""
    rows = []
    for axis, (_, splits) in AXES.items():
        for split in splits:
            v = difficulty.loc[difficulty["split"] == split, axis].to_numpy(dtype=float)
            p10, p50, p90 = np.percentile(v, [10, 50, 90])
            rows.append(
                {"axis": axis, "split": split, "frames": len(v), "p10": p10, "median": p50, "p90": p90, "max": v.max()}
            )
    return pd.DataFrame(rows)


def plot_difficulty(difficulty: pd.DataFrame) -> plt.Figure:
    """Small multiples, one histogram per axis (the query sets with poses of their own overlaid, same bins),
    and the light level of each split as bars."""
    fig, axes = plt.subplots(2, 4, figsize=(13, 5.6))
    for ax, (axis, (what, splits)) in zip(axes.flat, AXES.items()):
        ax.set_title(axis, fontsize=10)
        ax.set_xlabel(what, fontsize=7)
        if axis == "light_level":
            levels = [difficulty.loc[difficulty["split"] == s, axis].median() for s in splits]
            ax.bar([s.removeprefix("query_") for s in splits], levels, color="tab:orange")
            ax.tick_params(axis="x", labelsize=6, rotation=45)
            continue
        values = {s: difficulty.loc[difficulty["split"] == s, axis].to_numpy(dtype=float) for s in splits}
        pooled = np.concatenate(list(values.values()))
        if axis in INTEGER_AXES:
            bins = np.arange(pooled.min(), pooled.max() + 2) - 0.5
        else:
            bins = np.histogram_bin_edges(pooled, bins=20)
        for s, v in values.items():
            ax.hist(v, bins=bins, histtype="step", lw=1.5, color=SPLIT_COLOURS[s], label=f"{s} ({len(v)})")
        ax.set_ylabel("frames", fontsize=7)
        ax.legend(fontsize=6)
    axes.flat[-1].axis("off")
    fig.tight_layout()
    return fig


def floor_plan_figure(scene: Scene) -> plt.Figure:
    """The scene's top-down floor plan as ``preview`` draws it (rooms, objects, mapping path, query poses)."""
    from generators.preview import floor_plan

    return floor_plan(scene)


def _picks(n: int, k: int) -> list[int]:
    """``k`` frame indices spread evenly over ``n`` frames (fewer when ``n < k``)."""
    return np.unique(np.round(np.linspace(0, n - 1, min(k, n))).astype(int)).tolist()


def contact_sheet(scene: Scene, difficulty: pd.DataFrame) -> np.ndarray:
    """RGB thumbnails, one row per split: evenly spread frames of mapping and of each query set with poses of
    its own, then one query viewpoint in every variant (the one with the most moved objects in view)."""
    seqs = {s: {r.frame_id: r.color_path for r in scene.sequence(s).records} for s in SPLIT_COLUMNS}
    rows = [
        [(s, f, seqs[s][f]) for f in (list(seqs[s])[i] for i in _picks(len(seqs[s]), SHEET_COLUMNS))]
        for s in ("mapping", *OWN_POSE_SPLITS)
    ]
    moved = difficulty[(difficulty["scene"] == scene.name) & (difficulty["split"] == "query_displaced")]
    frame = moved.sort_values(["displaced_in_view", "frame"], ascending=[False, True])["frame"].iloc[0]
    rows.append([(s, frame, seqs[s][frame]) for s in VARIANT_SPLITS])
    depths = {r.frame_id: r.depth_path for r in scene.sequence("mapping").records}
    rows.insert(1, [("depth", f, depths[f]) for _, f, _ in rows[0]])
    h = round(THUMB_W * scene.info["intrinsics"]["height"] / scene.info["intrinsics"]["width"])
    sheet = np.full((len(rows) * h, max(map(len, rows)) * THUMB_W, 3), 255, np.uint8)
    for r, row in enumerate(rows):
        for c, (split, frame, path) in enumerate(row):
            image = depth_picture(io.read_depth(path)) if split == "depth" else io.read_rgb(path)
            tile = cv2.resize(
                image, (THUMB_W, h), interpolation=cv2.INTER_NEAREST if split == "depth" else cv2.INTER_AREA
            )
            cv2.rectangle(tile, (0, h - 13), (THUMB_W, h), (0, 0, 0), -1)
            label = f"{split.removeprefix('query_')} {frame}"
            cv2.putText(tile, label, (3, h - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.33, (255, 255, 255), 1, cv2.LINE_AA)
            sheet[r * h : (r + 1) * h, c * THUMB_W : (c + 1) * THUMB_W] = tile
    return sheet


def depth_picture(depth: np.ndarray, far_m: float = 6.0) -> np.ndarray:
    """Metric depth as RGB (turbo colour map up to ``far_m``), missing returns black: the holes a sensor
    leaves show at a glance."""
    scaled = np.clip(depth / far_m * 255, 0, 255).astype(np.uint8)
    rgb = cv2.cvtColor(cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
    rgb[depth <= 0] = 0
    return rgb


def sensor_table(scenes: list[Scene]) -> pd.DataFrame:
    """Every sensor parameter (rows) of each distinct sensor setting among ``scenes`` (columns, headed by
    the scenes that use it), from ``scene.json``; empty for scenes that record none."""
    settings: dict[str, list[str]] = {}
    records: dict[str, dict[str, Any]] = {}
    for scene in scenes:
        record = scene.info.get("spec", {}).get("sensor")
        if record is None:
            continue
        flat = pd.json_normalize(record).iloc[0].to_dict()
        key = json.dumps(flat, sort_keys=True, default=str)
        settings.setdefault(key, []).append(scene.name)
        records[key] = flat
    if not settings:
        return pd.DataFrame()
    parameters = list(next(iter(records.values())))
    columns = {", ".join(names): [records[key].get(p, "") for p in parameters] for key, names in settings.items()}
    return pd.DataFrame({"parameter": parameters, **columns})


def _figure_rgb(fig: plt.Figure) -> np.ndarray:
    """The figure's pixels at :data:`PLOT_DPI`; the figure is closed."""
    fig.set_dpi(PLOT_DPI)
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return rgb


def _write_png(path: Path, rgb: np.ndarray) -> None:
    """``rgb`` as a palette PNG of :data:`PALETTE` colours; Pillow writes no time stamp, so the same
    pixels give the same bytes."""
    buf = BytesIO()
    Image.fromarray(rgb).quantize(PALETTE).save(buf, format="PNG", optimize=True)
    io.atomic_write_bytes(path, buf.getvalue())


def _cell(value: Any) -> str:
    """A markdown table cell: numbers in 3 significant digits, text with its pipes escaped."""
    if isinstance(value, (float, np.floating)):
        return f"{value:.3g}"
    return str(value).replace("|", "\\|")


def _md(table: pd.DataFrame) -> list[str]:
    return md_table(list(table.columns), [[_cell(v) for v in row] for row in table.itertuples(index=False)])


def card_markdown(suite: Any, suite_file: str, scenes: list[Scene], difficulty: pd.DataFrame, name: str) -> str:
    """The card's text; pictures are linked relative to the card, under ``<name>/``."""
    infos = [s.info for s in scenes]
    sizes = sorted({(i["intrinsics"]["width"], i["intrinsics"]["height"]) for i in infos})
    table = scene_table(scenes)
    categories = category_table(scenes)
    total = {c: table[c].sum() if c not in ("scene", "kind") else "" for c in table.columns}
    total.update(scene="**total**", categories=len(categories))
    lines = [
        f"# Dataset card: {name}",
        "",
        _cell(suite.description) or "(no description)",
        "",
        *md_table(
            ["", ""],
            [
                ["Suite file", f"`{suite_file}`"],
                ["Purpose", suite.purpose],
                ["Data version", f"v{DATA_VERSION}"],
                ["Generator version", ", ".join(sorted({str(i.get("generator_version", "")) for i in infos}))],
                ["Image size", ", ".join(f"{w}x{h}" for w, h in sizes)],
                ["Scenes", len(scenes)],
                ["Frames", int(table[list(SPLIT_COLUMNS)].to_numpy().sum())],
            ],
        ),
        "",
        "## Scenes",
        "",
        "Frames per split; objects are the non-structural instances (landmarks), look-alikes those with an "
        "identical twin in their scene (same category, description and attributes).",
        "",
        *_md(pd.concat([table, pd.DataFrame([total])], ignore_index=True)),
        "",
        "## Object categories",
        "",
        *_md(categories),
        "",
        "## Look-alike groups",
        "",
        "One model placed more than once in a scene: appearance alone cannot tell its instances apart.",
        "",
    ]
    twins = lookalike_table(scenes)
    lines += [*_md(twins), ""] if len(twins) else ["None.", ""]
    sensor = sensor_table(scenes)
    lines += [
        "## Sensor",
        "",
        "The camera that recorded the frames (`model: ideal`: the noiseless render): depth noise and missing "
        "returns of a structured-light RGB-D camera, colour noise with a gain that rises as light falls, "
        "vignetting, JPEG, and motion blur on the mapping frames. The second row of each scene's pictures "
        "shows the mapping frames' depth (missing returns black).",
        "",
        *(_md(sensor) if len(sensor) else ["No sensor recorded (data before v3, or imported)."]),
        "",
        "## Difficulty",
        "",
        "Per query frame, from each scene's `difficulty.csv`; the lighting variants and `query_displaced` "
        "share `query`'s viewpoints.",
        "",
        *(f"- `{axis}`: {what}" for axis, (what, _) in AXES.items()),
        "",
        f"![difficulty histograms]({name}/difficulty.png)",
        "",
        *_md(difficulty_stats(difficulty)),
        "",
        "## Scenes in pictures",
        "",
        "Rows: mapping frames spread over the split, their depth, query, query_near and query_walk frames; one "
        "query viewpoint in every variant (the one that sees the most changes). The plan: rooms, objects (changed "
        "ones in red), the mapping path and the query poses.",
        "",
    ]
    for s in scenes:
        lines += [f"### {s.name}", "", f"![{s.name} frames]({name}/{s.name}_frames.png)", ""]
        lines += [f"![{s.name} plan]({name}/{s.name}_plan.png)", ""]
    return "\n".join(lines).rstrip() + "\n"
