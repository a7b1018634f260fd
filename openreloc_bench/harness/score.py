"""Per-query scoring against a scene's ground truth: the one place errors are computed.

Used by the evaluation runner (estimates come from a method) and by ``openreloc-bench score``
(estimates come from pose files produced elsewhere), so both are scored identically.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench import geometry
from openreloc_bench.data.results import read_results
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import DataError

QUERY_COLUMNS = (
    "query", "success", "t_err_m", "r_err_deg", "runtime_s", "reason",
    "gt_x", "gt_y", "gt_z", "est_x", "est_y", "est_z",
)  # fmt: skip


@dataclass
class Outcome:
    """What happened to one query: an estimate, or a failure with its reason."""

    name: str
    T_wc: np.ndarray | None
    runtime_s: float = float("nan")
    reason: str = ""


def score_split(seq: SceneSequence, outcomes: dict[str, Outcome]) -> pd.DataFrame:
    """One row per ground-truth query of ``seq`` (columns :data:`QUERY_COLUMNS`).

    Queries without an outcome are failures ("missing"); outcomes for names that are not queries of
    this split are a caller error (the pose file names the wrong split or frames).
    """
    names = seq.names
    unknown = sorted(set(outcomes) - set(names))
    if unknown:
        raise ValueError(f"{len(unknown)} estimate(s) for unknown queries of split '{seq.split}', e.g. '{unknown[0]}'")
    gt = seq.poses
    est = np.full_like(gt, np.nan)
    runtime = np.full(len(names), np.nan)
    reasons = []
    for i, n in enumerate(names):
        o = outcomes.get(n)
        if o is None:
            reasons.append("missing")
            continue
        runtime[i] = o.runtime_s
        if o.T_wc is not None:
            est[i] = o.T_wc
        reasons.append(o.reason if o.T_wc is None else "")
    t_err, r_err = geometry.pose_errors(gt, est)
    ok = np.isfinite(t_err) & np.isfinite(r_err)
    t_err[~ok] = np.inf
    r_err[~ok] = np.inf
    return pd.DataFrame({
        "query": names, "success": ok, "t_err_m": t_err, "r_err_deg": r_err, "runtime_s": runtime,
        "reason": [r or ("" if s else "no estimate") for r, s in zip(reasons, ok)],
        "gt_x": gt[:, 0, 3], "gt_y": gt[:, 1, 3], "gt_z": gt[:, 2, 3],
        "est_x": est[:, 0, 3], "est_y": est[:, 1, 3], "est_z": est[:, 2, 3],
    })  # fmt: skip


def outcomes_from_file(path: Path) -> dict[str, Outcome]:
    """Estimates of a pose file as outcomes (read_results rejects NaNs, duplicates, non-unit quaternions)."""
    return {n: Outcome(n, T) for n, T in read_results(path).items()}


def submission_outcomes(
    submission: Path, scene: str, seq: SceneSequence, scene_splits: list[str]
) -> dict[str, Outcome] | None:
    """The estimates a map-free-style submission holds for one split of one scene, or None if it has no file.

    Accepted layouts: ``<scene>/<split>.txt`` (names ``<split>/<id>``) or one ``<scene>.txt`` with the
    names of every split (``scene_splits``; only the names of ``seq.split`` are taken from it). A name
    that is not a query of the scene is an error, never silently dropped: a typo in the split part
    (``Query/000001``) would otherwise lose every estimate.
    """
    per_split = submission / scene / f"{seq.split}.txt"
    per_scene = submission / f"{scene}.txt"
    if per_split.is_file() and per_scene.is_file():
        raise DataError(submission, f"holds both {per_scene.name} and {scene}/{per_split.name}: keep one layout")
    if per_split.is_file():
        path, found = per_split, outcomes_from_file(per_split)
    elif per_scene.is_file():
        path, found = per_scene, outcomes_from_file(per_scene)
        foreign = sorted(n for n in found if n.split("/", 1)[0] not in scene_splits)
        if foreign:
            raise DataError(
                path,
                f"{len(foreign)} name(s) name no split of scene '{scene}', e.g. '{foreign[0]}' "
                f"(splits: {', '.join(scene_splits)}; expected names like '{seq.names[0]}')",
            )
        found = {n: o for n, o in found.items() if n.split("/", 1)[0] == seq.split}
    else:
        return None
    unknown = sorted(set(found) - set(seq.names))
    if unknown:
        raise DataError(
            path,
            f"{len(unknown)} name(s) are not queries of scene '{scene}', e.g. '{unknown[0]}' "
            f"(expected '<split>/<frame id>' like '{seq.names[0]}')",
        )
    return found


def submission_scenes(submission: Path, data: Path) -> list[str]:
    """Scenes a submission covers: its ``<scene>.txt`` files and ``<scene>/`` folders, each of which must
    name a scene under ``data`` (a mistyped name would otherwise drop that scene's estimates unseen)."""
    if not submission.is_dir():
        raise DataError(submission, "submission directory not found")
    entries = [p for p in submission.iterdir() if not p.name.startswith(".")]
    names = {p.stem: p.name for p in entries if p.is_file() and p.suffix == ".txt"}
    names.update({p.name: f"{p.name}/" for p in entries if p.is_dir()})
    if not names:
        raise DataError(submission, f"no '<scene>.txt' or '<scene>/<split>.txt' naming a scene under {data}")
    unknown = sorted(f for n, f in names.items() if not (data / n / "scene.json").is_file())
    if unknown:
        raise DataError(
            submission / unknown[0],
            f"names no scene under {data} (a scene directory with scene.json); rename or remove it, or pass "
            "--suite to score the suite's scenes only",
        )
    return sorted(names)


def score_submission(
    submission: Path, data: Path, scenes: list[str], splits: list[str], method: str, track: str
) -> pd.DataFrame:
    """Per-query rows (with the runner's provenance columns) for pose files produced elsewhere.

    A scene or split without a file counts every query as failed ("missing"), as does a query
    absent from its file; malformed files (duplicates, NaN, non-unit quaternions) are errors.
    """
    from openreloc_bench.data.scene import Scene
    from openreloc_bench.harness.cache import git_commit

    if not submission.is_dir():
        raise DataError(submission, "submission directory not found")
    frames = []
    for name in scenes:
        scene = Scene(data / name)
        for split in splits:
            seq = scene.sequence(split)
            outcomes = submission_outcomes(submission, name, seq, scene.splits()) or {}
            df = score_split(seq, outcomes)
            meta = {
                "method": method,
                "track": track,
                "scene": name,
                "split": split,
                "config_hash": "submission",
                "map_hash": "submission",
                "spec_hash": scene.spec_hash,
                "git_commit": git_commit(),
            }
            for i, (k, v) in enumerate(meta.items()):
                df.insert(i, k, v)
            frames.append(df)
    return pd.concat(frames, ignore_index=True)
