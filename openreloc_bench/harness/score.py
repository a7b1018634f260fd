"""Per-query scoring against a scene's ground truth: the one place errors are computed.

Used by the evaluation runner (estimates come from a method) and by ``openreloc-bench score``
(estimates come from pose files produced elsewhere), so both are scored identically.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench import geometry
from openreloc_bench.data.results import header_track, hloc_name, read_submission
from openreloc_bench.data.scene import DIFFICULTY_AXES, Scene
from openreloc_bench.data.types import SceneSequence
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.tracks import DEFAULT_TRACK, MASK_FREE


@dataclass
class Outcome:
    """What happened to one query: an estimate, or a failure with its reason."""

    name: str
    T_wc: np.ndarray | None
    runtime_s: float = float("nan")
    reason: str = ""
    confidence: float = float("nan")
    """The method's or submission's confidence in the estimate (map-free's column), NaN where none was given."""


def score_split(seq: SceneSequence, outcomes: dict[str, Outcome]) -> pd.DataFrame:
    """One row per ground-truth query of ``seq`` (columns :data:`~openreloc_bench.data.runs.QUERY_COLUMNS`,
    then ``confidence``: the outcome's, NaN for a failure or where none was given); ``reproj_err_px`` is
    :func:`reprojection_error`, infinite for a failure.

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
    confidence = np.full(len(names), np.nan)
    reasons = []
    for i, n in enumerate(names):
        o = outcomes.get(n)
        if o is None:
            reasons.append("missing")
            continue
        runtime[i] = o.runtime_s
        if o.T_wc is not None:
            est[i] = o.T_wc
            confidence[i] = o.confidence
        reasons.append(o.reason if o.T_wc is None else "")
    t_err, r_err = geometry.pose_errors(gt, est)
    ok = np.isfinite(t_err) & np.isfinite(r_err)
    t_err[~ok] = np.inf
    r_err[~ok] = np.inf
    reproj = np.array([reprojection_error(seq, i, est[i]) if ok[i] else np.inf for i in range(len(names))])
    return pd.DataFrame({
        "query": names, "success": ok, "t_err_m": t_err, "r_err_deg": r_err, "reproj_err_px": reproj,
        "runtime_s": runtime,
        "reason": [r or ("" if s else "no estimate") for r, s in zip(reasons, ok)],
        "gt_x": gt[:, 0, 3], "gt_y": gt[:, 1, 3], "gt_z": gt[:, 2, 3],
        "est_x": est[:, 0, 3], "est_y": est[:, 1, 3], "est_z": est[:, 2, 3], "confidence": confidence,
    })  # fmt: skip


VIRTUAL_GRID = (8, 6)
"""Columns and rows of the pixel grid whose depth gives a query's virtual correspondences."""
FALLBACK_DEPTH_M = 2.0
"""Depth of a virtual correspondence where the query has no depth reading at all."""


def reprojection_error(seq: SceneSequence, i: int, T_est: np.ndarray) -> float:
    """Map-free's virtual correspondence reprojection error (pixels) of query ``i``: the mean distance
    between where points of the scene appear at the true pose and where the estimate would draw them.
    The points are a grid of the query's pixels lifted by its ground-truth depth (map-free, which has
    none, places them at fixed depths); a pixel without a reading takes the median reading (or 2 m).
    Infinite when a point falls behind the estimated camera."""
    image = seq.depth(i)  # only the depth: scoring decodes no colour
    cols, rows = VIRTUAL_GRID
    u, v = np.meshgrid((np.arange(cols) + 0.5) * seq.width / cols, (np.arange(rows) + 0.5) * seq.height / rows)
    uv = np.column_stack([u.ravel(), v.ravel()])
    depth = np.zeros(len(uv)) if image is None else image[uv[:, 1].astype(int), uv[:, 0].astype(int)]
    valid = image[image > 0] if image is not None else np.zeros(0)
    depth = np.where(depth > 0, depth, float(np.median(valid)) if valid.size else FALLBACK_DEPTH_M)
    points = geometry.transform_points(seq.records[i].T_wc, geometry.unproject(seq.K, uv, depth))
    drawn, z = geometry.project(seq.K, T_est, points)
    if (z <= 0).any():
        return float("inf")
    return float(np.linalg.norm(drawn - uv, axis=1).mean())


def split_difficulty(scene: Scene, split: str) -> pd.DataFrame:
    """``split``'s rows of the scene's ``difficulty.csv`` indexed by frame id (columns :data:`DIFFICULTY_AXES`;
    none for a scene without the file)."""
    table = scene.difficulty()
    if table is None:
        return pd.DataFrame(columns=list(DIFFICULTY_AXES), dtype=float)
    return table.loc[table["split"] == split, ["frame", *DIFFICULTY_AXES]].set_index("frame")


def with_difficulty(table: pd.DataFrame, scene: Scene, split: str) -> pd.DataFrame:
    """``table`` (per-query rows of ``split``) with each query's difficulty joined on (split, frame id) and the
    scene's ``data_version``, so results can be read against what made a query hard and boards can name the
    data they score. NaN where the scene has no ``difficulty.csv`` (imported data) or no row for a query;
    ``data_version`` empty where ``scene.json`` names none."""
    joined = split_difficulty(scene, split).reindex(table["query"].str.partition("/")[2])
    out = table.assign(**{c: joined[c].to_numpy() for c in DIFFICULTY_AXES})
    out["data_version"] = pd.array([scene.data_version] * len(out), dtype="Int64")
    return out


MAPFREE_PREFIX = "pose_"
"""Map-free submissions name a scene's file ``pose_<scene>.txt``."""


def submission_outcomes(
    submission: Path, scene: str, seq: SceneSequence, scene_splits: list[str], names: str = "benchmark"
) -> dict[str, Outcome] | None:
    """The estimates a submission holds for one split of one scene, or None if it has no file.

    Accepted layouts: ``<scene>/<split>.txt`` (names ``<split>/<id>``), or one ``<scene>.txt`` or
    ``pose_<scene>.txt`` (map-free) with the names of every split (``scene_splits``; only the names of
    ``seq.split`` are taken from it). Lines may carry map-free's confidence; ``names="hloc"`` maps hloc
    image names (``query/color/000012.png``). A name that is not a query of the scene is an error,
    never silently dropped: a typo in the split part (``Query/000001``) would otherwise lose every estimate.
    """
    per_split = submission / scene / f"{seq.split}.txt"
    per_scene = [p for p in (submission / f"{scene}.txt", submission / f"{MAPFREE_PREFIX}{scene}.txt") if p.is_file()]
    if per_split.is_file():
        per_scene.append(per_split)
    if len(per_scene) > 1:
        files = " and ".join(str(p.relative_to(submission)) for p in per_scene)
        raise DataError(submission, f"holds both {files}: keep one layout")
    if not per_scene:
        return None
    path = per_scene[0]
    poses, confidence = read_submission(path, names)
    found = {n: Outcome(n, T, confidence=confidence.get(n, float("nan"))) for n, T in poses.items()}
    if path != per_split:
        foreign = sorted(n for n in found if n.split("/", 1)[0] not in scene_splits)
        if foreign:
            raise DataError(
                path,
                f"{len(foreign)} name(s) name no split of scene '{scene}', e.g. '{foreign[0]}' "
                f"(splits: {', '.join(scene_splits)}; expected names like '{seq.names[0]}'){_names_hint(foreign[0], names)}",
            )
        found = {n: o for n, o in found.items() if n.split("/", 1)[0] == seq.split}
    unknown = sorted(set(found) - set(seq.names))
    if unknown:
        raise DataError(
            path,
            f"{len(unknown)} name(s) are not queries of scene '{scene}', e.g. '{unknown[0]}' "
            f"(expected '<split>/<frame id>' like '{seq.names[0]}'){_names_hint(unknown[0], names)}",
        )
    return found


def _names_hint(name: str, names: str) -> str:
    """A pointer to ``--names hloc`` when a benchmark-style file holds an hloc image name."""
    return "; hloc image names need --names hloc" if names == "benchmark" and hloc_name(name) else ""


def submission_scenes(submission: Path, data: Path) -> list[str]:
    """Scenes a submission covers: its ``<scene>.txt`` files and ``<scene>/`` folders, each of which must
    name a scene under ``data`` (a mistyped name would otherwise drop that scene's estimates unseen)."""
    if not submission.is_dir():
        raise DataError(submission, "submission directory not found")
    entries = [p for p in submission.iterdir() if not p.name.startswith(".")]
    names = {_scene_of_file(p.stem, data): p.name for p in entries if p.is_file() and p.suffix == ".txt"}
    names.update({p.name: f"{p.name}/" for p in entries if p.is_dir()})
    if not names:
        raise DataError(
            submission, f"no '<scene>.txt', 'pose_<scene>.txt' or '<scene>/<split>.txt' naming a scene under {data}"
        )
    unknown = sorted(f for n, f in names.items() if not (data / n / "scene.json").is_file())
    if unknown:
        raise DataError(
            submission / unknown[0],
            f"names no scene under {data} (a scene directory with scene.json); rename or remove it, or pass "
            "--suite to score the suite's scenes only",
        )
    return sorted(names)


def submission_track(submission: Path, scenes: list[str], given: str | None, known: tuple[str, ...]) -> str:
    """The track to file a submission under: ``given`` (``--track``), or the one its pose files' headers
    record, else the default track. Files that record another track than ``given``, or disagree among
    themselves, are refused: a score filed under the wrong track would stand in the wrong table."""
    files = sorted(
        p
        for name in scenes
        for p in (
            submission / f"{name}.txt",
            submission / f"{MAPFREE_PREFIX}{name}.txt",
            *submission.glob(f"{name}/*.txt"),
        )
        if p.is_file()
    )
    recorded = {p: t for p in files if (t := header_track(p)) is not None}
    for p, t in recorded.items():
        if t not in known:
            raise DataError(p, f"its header records track '{t}', which is none of {', '.join(known)}")
        if given is not None and t != given:
            raise ConfigError(f"{p} records track '{t}' in its header but --track is {given}: drop --track or fix it")
    tracks = sorted(set(recorded.values()))
    if len(tracks) > 1:
        first = {t: next(p for p, u in recorded.items() if u == t) for t in tracks}
        raise DataError(
            submission, "its files record different tracks: " + ", ".join(f"{first[t].name} {t}" for t in tracks)
        )
    return given or (tracks[0] if tracks else DEFAULT_TRACK)


def _scene_of_file(stem: str, data: Path) -> str:
    """The scene a ``<stem>.txt`` file names: ``<scene>`` or map-free's ``pose_<scene>``."""
    bare = stem.removeprefix(MAPFREE_PREFIX)
    if bare != stem and not (data / stem / "scene.json").is_file() and (data / bare / "scene.json").is_file():
        return bare
    return stem


def check_submission(
    submission: Path, data: Path, scenes: list[str], splits: list[str], names: str = "benchmark"
) -> list[tuple[str, str, int, int]]:
    """``(scene, split, poses, queries)`` for each scene and split a submission is read for, checking its
    files as :func:`score_submission` reads them (a malformed file is a DataError) without scoring: no
    ground truth is read, nothing is written (map-free's validator)."""
    return [
        (scene.name, seq.split, len(outcomes), len(seq))
        for scene, seq, outcomes in _submitted(submission, data, scenes, splits, names)
    ]


def _submitted(
    submission: Path, data: Path, scenes: list[str], splits: list[str], names: str
) -> Iterator[tuple[Scene, SceneSequence, dict[str, Outcome]]]:
    """Each scene and split with the estimates the submission holds for it (none where it has no file)."""
    if not submission.is_dir():
        raise DataError(submission, "submission directory not found")
    for name in scenes:
        scene = Scene(data / name)
        for split in splits:
            seq = scene.sequence(split)
            yield scene, seq, submission_outcomes(submission, name, seq, scene.splits(), names) or {}


def score_submission(
    submission: Path,
    data: Path,
    scenes: list[str],
    splits: list[str],
    method: str,
    track: str,
    names: str = "benchmark",
) -> pd.DataFrame:
    """Per-query rows (with the runner's provenance columns and the submission's ``confidence``) for
    pose files produced elsewhere.

    A scene or split without a file counts every query as failed ("missing"), as does a query
    absent from its file; malformed files (duplicates, NaN, non-unit quaternions) are errors.
    """
    from openreloc_bench.harness.cache import git_commit

    frames = []
    for scene, seq, outcomes in _submitted(submission, data, scenes, splits, names):
        df = with_difficulty(score_split(seq, outcomes), scene, seq.split)
        meta = {
            "method": method,
            "track": track,
            "scene": scene.name,
            "split": seq.split,
            "config_hash": "submission",
            "map_hash": "submission",
            "spec_hash": scene.spec_hash,
            "git_commit": git_commit(),
        }
        for i, (k, v) in enumerate(meta.items()):
            df.insert(i, k, v)
        df["uses_masks"] = track != MASK_FREE  # the track as the submitter declared it
        frames.append(df)
    return pd.concat(frames, ignore_index=True)
