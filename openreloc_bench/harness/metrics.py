"""The relocalization metrics of the paper and of the field, computed from per-query errors.

Conventions (ARCHITECTURE.md): a query without an estimate has infinite translation and rotation
error, so it counts in every recall denominator and never inside a threshold. Recalls are percent
of ALL queries; MTE@X / MRE@X are means over the queries whose translation error is under X (NaN
when there are none, rendered '-' like the paper's failure cells); medians are over all queries
(infinite when more than half failed). Beside the paper's 50 / 25 cm: rotation-aware recalls (5 cm /
5 deg, 10 cm / 10 deg, 25 cm / 5 deg), map-free's reprojection-error recall (VCRE) and its area under
precision vs coverage for methods that give a confidence, and bootstrap intervals of every recall.
"""

from __future__ import annotations

import numpy as np

THRESHOLDS_M: dict[str, float] = {"100cm": 1.0, "50cm": 0.5, "25cm": 0.25}
"""Translation thresholds of the recalls (the paper adds @100cm for large scenes)."""
POSE_THRESHOLDS: dict[str, tuple[float, float]] = {
    "5cm_5deg": (0.05, 5.0),
    "10cm_10deg": (0.10, 10.0),
    "25cm_5deg": (0.25, 5.0),
}
"""(metres, degrees) of the rotation-aware recalls: 7-Scenes' and 12-Scenes' 5 cm / 5 deg, a middle
step, and map-free's 25 cm / 5 deg."""
VCRE_PX = 90.0
"""Map-free's threshold on the virtual-correspondence reprojection error (pixels)."""
ACCURACY_THRESHOLDS = ("50cm", "25cm")
"""Thresholds at which MTE / MRE are reported (paper tables)."""
AUC_THRESHOLD = "25cm_5deg"
"""The pose threshold of the precision-vs-coverage area (map-free's)."""

RECALLS: tuple[str, ...] = (
    *(f"recall_{k}" for k in THRESHOLDS_M),
    *(f"recall_{k}" for k in POSE_THRESHOLDS),
    "recall_vcre",
)
"""Every recall column, in percent of all queries."""
METRIC_COLUMNS: tuple[str, ...] = (
    "n_queries",
    "n_failed",
    *RECALLS,
    *(c for k in ACCURACY_THRESHOLDS for c in (f"mte_{k}_m", f"mre_{k}_deg")),
    "median_te_m",
    "median_re_deg",
    "median_reproj_px",
    f"auc_{AUC_THRESHOLD}",
)
INTERVAL_COLUMNS: tuple[str, ...] = tuple(f"{k}_{end}" for k in RECALLS for end in ("lo", "hi"))
"""Each recall's 95% bootstrap interval (:func:`recall_intervals`)."""


def _clean(values: np.ndarray | None, n: int) -> np.ndarray:
    """``values`` as float64 with NaN turned to inf (a failure); all inf when not given."""
    if values is None:
        return np.full(n, np.inf)
    v = np.asarray(values, dtype=np.float64).ravel()
    return np.where(np.isnan(v), np.inf, v)


def hits(t_err: np.ndarray, r_err: np.ndarray, reproj_px: np.ndarray | None = None) -> np.ndarray:
    """(N, len(RECALLS)) bool: which query is inside each recall's threshold (failures never are;
    without reprojection errors no query is inside VCRE)."""
    t = np.asarray(t_err, dtype=np.float64).ravel()
    r = np.asarray(r_err, dtype=np.float64).ravel()
    if t.shape != r.shape:
        raise ValueError(f"translation and rotation errors differ in length ({t.size} vs {r.size})")
    ok = np.isfinite(t) & np.isfinite(r)
    cols = [ok & (t < thr) for thr in THRESHOLDS_M.values()]
    cols += [ok & (t < m) & (r < deg) for m, deg in POSE_THRESHOLDS.values()]
    cols.append(ok & (_clean(reproj_px, t.size) < VCRE_PX))
    return np.column_stack(cols) if t.size else np.zeros((0, len(RECALLS)), bool)


def summarize(
    t_err: np.ndarray,
    r_err: np.ndarray,
    reproj_px: np.ndarray | None = None,
    confidence: np.ndarray | None = None,
) -> dict[str, float]:
    """All metrics of one set of queries; ``inf``/NaN errors mean the query failed. Without
    reprojection errors VCRE is NaN; the precision-vs-coverage area needs every estimate's confidence
    (NaN otherwise)."""
    inside = hits(t_err, r_err, reproj_px)
    t = _clean(t_err, inside.shape[0])
    r = _clean(r_err, inside.shape[0])
    failed = ~(np.isfinite(t) & np.isfinite(r))
    t[failed], r[failed] = np.inf, np.inf
    n = t.size
    out: dict[str, float] = {"n_queries": float(n), "n_failed": float(failed.sum())}
    for j, key in enumerate(RECALLS):
        out[key] = 100.0 * float(inside[:, j].mean()) if n else float("nan")
    if reproj_px is None:
        out["recall_vcre"] = float("nan")
    for key in ACCURACY_THRESHOLDS:
        within = t < THRESHOLDS_M[key]
        out[f"mte_{key}_m"] = float(t[within].mean()) if within.any() else float("nan")
        out[f"mre_{key}_deg"] = float(r[within].mean()) if within.any() else float("nan")
    out["median_te_m"] = float(np.median(t)) if n else float("nan")
    out["median_re_deg"] = float(np.median(r)) if n else float("nan")
    reproj = _clean(reproj_px, n)
    out["median_reproj_px"] = float(np.median(reproj)) if n and reproj_px is not None else float("nan")
    auc_hits = inside[:, RECALLS.index(f"recall_{AUC_THRESHOLD}")]
    out[f"auc_{AUC_THRESHOLD}"] = coverage_auc(confidence, auc_hits, failed) if confidence is not None else float("nan")
    return out


def coverage_auc(confidence: np.ndarray, correct: np.ndarray, failed: np.ndarray) -> float:
    """Map-free's area under precision vs coverage, in percent: estimates ranked by confidence, precision
    is the share correct among the top k, coverage k over all queries (failures included, never
    covered). NaN when an estimate has no confidence. Written here because scikit-learn's average
    precision counts recall among the correct ones, not coverage of all queries."""
    conf = np.asarray(confidence, dtype=np.float64).ravel()[~failed]
    ok = np.asarray(correct, bool).ravel()[~failed]
    n_all = failed.size
    if not n_all or np.isnan(conf).any():
        return float("nan")
    if not conf.size:
        return 0.0
    order = np.argsort(-conf, kind="stable")
    conf, ok = conf[order], ok[order]
    last_of_tie = np.r_[np.flatnonzero(np.diff(conf)), conf.size - 1]  # tied confidences are one step
    k = last_of_tie + 1
    precision = np.cumsum(ok)[last_of_tie] / k
    coverage = k / n_all
    return 100.0 * float(np.sum(np.diff(np.r_[0.0, coverage]) * precision))


def recall_intervals(
    inside: np.ndarray, groups: np.ndarray | None = None, n_boot: int = 1000, seed: int = 0
) -> np.ndarray:
    """(len(RECALLS), 2) 95% percentile-bootstrap intervals of the recalls of :func:`hits` ``inside``:
    scenes (``groups``) resampled, then queries within each, so that a board with few scenes does not
    look surer than it is; queries alone with one group. Seeded: the same rows give the same interval."""
    n = inside.shape[0]
    if not n:
        return np.full((inside.shape[1], 2), np.nan)
    rng = np.random.default_rng(seed)
    labels = np.zeros(n, int) if groups is None else np.unique(np.asarray(groups), return_inverse=True)[1].ravel()
    n_groups = labels.max() + 1
    sums = np.zeros((n_boot, n_groups, inside.shape[1]))
    sizes = np.bincount(labels, minlength=n_groups)
    for g in range(n_groups):
        rows = inside[labels == g].astype(np.float64)
        sums[:, g] = rows[rng.integers(0, len(rows), (n_boot, len(rows)))].sum(axis=1)
    picked = rng.integers(0, n_groups, (n_boot, n_groups)) if n_groups > 1 else np.zeros((n_boot, 1), int)
    boot = np.take_along_axis(sums, picked[..., None], axis=1).sum(axis=1) / sizes[picked].sum(axis=1)[:, None]
    return 100.0 * np.percentile(boot, [2.5, 97.5], axis=0).T


def paired_difference(a: np.ndarray, b: np.ndarray, groups: np.ndarray) -> tuple[float, float, float]:
    """How much more often ``a`` is right than ``b`` on the same queries, in points, with its 95% interval:
    the per-query differences (``a``, ``b``: 0/1, or a share over seeds) resampled as :func:`recall_intervals`
    resamples hits, scenes then queries. The scenes' own difficulty, which widens each method's interval,
    cancels in the difference: two methods can be level by their intervals and one ahead on every scene."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    if not d.size:
        return float("nan"), float("nan"), float("nan")
    lo, hi = recall_intervals(d[:, None], groups)[0]
    return 100.0 * float(d.mean()), float(lo), float(hi)


def cumulative_curve(errors: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Percent of ALL queries with error <= each grid value (failures never count)."""
    e = np.sort(np.where(np.isfinite(errors), errors, np.inf))
    if e.size == 0:
        return np.full(len(grid), np.nan)
    return 100.0 * np.searchsorted(e, grid, side="right") / e.size
