"""Pose result files.

The benchmark format is the visual-localization one (hloc, map-free): one line per query,
``name qw qx qy qz tx ty tz`` with (q, t) of **T_cw** (world-to-camera), after ``#`` header lines.
Files produced elsewhere may add map-free's confidence column and name queries hloc's way
(:func:`read_submission`).
A TUM export (``timestamp tx ty tz qx qy qz qw``, camera-to-world) is offered for ``evo``.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.errors import DataError

RESULTS_HEADER = "# name qw qx qy qz tx ty tz  (T_cw: world-to-camera, quaternion w x y z, metres)"
UNIT_QUAT_TOL = 1e-3


def format_results(poses_wc: dict[str, np.ndarray], comments: list[str] | None = None) -> str:
    lines = [RESULTS_HEADER] + [f"# {c}" for c in comments or []]
    for name in sorted(poses_wc):
        q, t = geometry.pose_to_qt(geometry.invert(poses_wc[name]))
        if any(c.isspace() for c in name) or not name:
            raise ValueError(f"query name {name!r} must be non-empty without whitespace")
        lines.append(name + " " + " ".join(f"{v:.10g}" for v in (*q, *t)))
    return "\n".join(lines) + "\n"


def write_results(path: Path | str, poses_wc: dict[str, np.ndarray], comments: list[str] | None = None) -> None:
    """Write camera-to-world poses as a T_cw result file (sorted by name, atomic)."""
    io.atomic_write_text(path, format_results(poses_wc, comments))


def read_results(path: Path | str) -> dict[str, np.ndarray]:
    """Read a result file into {name: T_wc}. Malformed lines, duplicates, NaNs and non-unit
    quaternions are errors naming the file and line (a submission must be explicit)."""
    return _read_pose_lines(path, confidence=False, names="benchmark")[0]


_HEADER_TRACK = re.compile(r"(?:^|[\s,])track (?P<track>[\w-]+)")


def header_track(path: Path | str) -> str | None:
    """The track a pose file's ``#`` header records (``eval`` writes ``# method ..., track predicted,
    ...``), or None when its header names none."""
    for line in io.read_text(path).splitlines():
        if not line.startswith("#"):
            if line.strip():
                break
            continue
        m = _HEADER_TRACK.search(line[1:])
        if m:
            return m["track"]
    return None


NAME_STYLES = ("benchmark", "hloc")
"""How a submission names its queries: ``benchmark`` (``query/000012``) or ``hloc``, the image path
relative to the scene directory (``query/color/000012.png``), as hloc's pose files write it."""
_HLOC_NAME = re.compile(r"^(?P<split>[^/]+)/color/(?P<id>[^/]+)\.(?:png|jpg|jpeg)$", re.IGNORECASE)


def hloc_name(name: str) -> str | None:
    """The benchmark name (``query/000012``) of an hloc image name (``query/color/000012.png``), else None."""
    m = _HLOC_NAME.match(name)
    return f"{m['split']}/{m['id']}" if m else None


def read_submission(path: Path | str, names: str = "benchmark") -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """A pose file produced elsewhere: ({name: T_wc}, {name: confidence}).

    Lines are ``name qw qx qy qz tx ty tz`` or, as map-free submissions write them, with a trailing
    confidence (kept, not required; every line of a file has it or none). With ``names="hloc"`` each
    name must be an hloc image name and is mapped to the benchmark's. Everything :func:`read_results`
    refuses is refused here too, and two lines naming the same query after the mapping are duplicates.
    """
    if names not in NAME_STYLES:
        raise ValueError(f"names must be one of {NAME_STYLES}, got {names!r}")
    return _read_pose_lines(path, confidence=True, names=names)


def _read_pose_lines(path: Path | str, confidence: bool, names: str) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    poses: dict[str, np.ndarray] = {}
    scores: dict[str, float] = {}
    n_fields = None
    for lineno, parts in io.data_lines(path):
        where = f"line {lineno}"
        if len(parts) != 8 and not (confidence and len(parts) == 9):
            expected = "'name qw qx qy qz tx ty tz [confidence]'" if confidence else "'name qw qx qy qz tx ty tz'"
            raise DataError(path, f"{where}: expected {expected}, got {len(parts)} fields")
        if n_fields is not None and len(parts) != n_fields:
            raise DataError(
                path, f"{where}: {len(parts)} fields after lines of {n_fields}: give a confidence on every line or none"
            )
        n_fields = len(parts)
        name = parts[0]
        if names == "hloc":
            mapped = hloc_name(name)
            if mapped is None:
                raise DataError(path, f"{where}: '{name}' is not an hloc image name like 'query/color/000012.png'")
            name = mapped
        try:
            vals = np.array([float(v) for v in parts[1:]])
        except ValueError:
            raise DataError(path, f"{where}: non-numeric value") from None
        if not np.all(np.isfinite(vals)):
            raise DataError(path, f"{where}: NaN or inf in pose of '{name}'")
        qn = np.linalg.norm(vals[:4])
        if abs(qn - 1.0) > UNIT_QUAT_TOL:
            raise DataError(path, f"{where}: quaternion of '{name}' is not unit (norm {qn:.4f})")
        if name in poses:
            raise DataError(path, f"{where}: duplicate query name '{name}'")
        poses[name] = geometry.invert(geometry.qt_to_pose(vals[:4], vals[4:7]))
        if len(vals) == 8:
            scores[name] = float(vals[7])
    return poses, scores


def write_tum(path: Path | str, poses_wc: dict[str, np.ndarray], timestamps: dict[str, float]) -> None:
    """TUM trajectory (``timestamp tx ty tz qx qy qz qw``, camera-to-world) for evo.

    Queries have no time: callers give each query a fixed stamp (its index in the split), the same in
    the estimate and ground-truth files, so ``evo`` pairs them one to one even when queries failed.
    """
    missing = sorted(set(poses_wc) - set(timestamps))
    if missing:
        raise ValueError(f"no timestamp for {len(missing)} pose(s), e.g. '{missing[0]}'")
    names = sorted(poses_wc, key=lambda n: timestamps[n])
    lines = ["# timestamp tx ty tz qx qy qz qw  (camera-to-world)"]
    for n in names:
        q, t = geometry.pose_to_qt(poses_wc[n])
        lines.append(f"{timestamps[n]:.6f} " + " ".join(f"{v:.10g}" for v in (*t, q[1], q[2], q[3], q[0])))
    io.atomic_write_text(path, "\n".join(lines) + "\n")


def read_tum_trajectory(path: Path | str) -> tuple[np.ndarray, np.ndarray]:
    """(timestamps (N,), T_wc (N,4,4)) from a TUM trajectory / groundtruth file."""
    stamps, poses = [], []
    for lineno, parts in io.data_lines(path):
        try:
            vals = [float(v) for v in parts]
        except ValueError:
            raise DataError(path, f"line {lineno}: non-numeric value") from None
        if len(vals) != 8 or not np.all(np.isfinite(vals)):
            raise DataError(path, f"line {lineno}: expected 'timestamp tx ty tz qx qy qz qw' with finite numbers")
        q = np.array([vals[7], vals[4], vals[5], vals[6]])
        if np.linalg.norm(q) < 1e-6:
            raise DataError(path, f"line {lineno}: zero quaternion")
        stamps.append(vals[0])
        poses.append(geometry.qt_to_pose(q, vals[1:4]))
    return np.array(stamps), (np.stack(poses) if poses else np.zeros((0, 4, 4)))
