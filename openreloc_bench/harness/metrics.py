"""The paper's relocalization metrics, computed from per-query errors.

Conventions (ARCHITECTURE.md): a query without an estimate has infinite translation and rotation
error, so it counts in every recall denominator and never inside a threshold. Recalls are percent
of ALL queries; MTE@X / MRE@X are means over the queries whose translation error is under X (NaN
when there are none, rendered '-' like the paper's failure cells); medians are over all queries
(infinite when more than half failed).
"""

from __future__ import annotations

import numpy as np

THRESHOLDS_M: dict[str, float] = {"100cm": 1.0, "50cm": 0.5, "25cm": 0.25}
"""Translation thresholds of the recalls (the paper adds @100cm for large scenes)."""
ACCURACY_THRESHOLDS = ("50cm", "25cm")
"""Thresholds at which MTE / MRE are reported (paper tables)."""
COMBINED = (0.25, 5.0)
"""(metres, degrees) of the combined recall."""

METRIC_COLUMNS: tuple[str, ...] = (
    "n_queries",
    "n_failed",
    *(f"recall_{k}" for k in THRESHOLDS_M),
    "recall_25cm_5deg",
    *(c for k in ACCURACY_THRESHOLDS for c in (f"mte_{k}_m", f"mre_{k}_deg")),
    "median_te_m",
    "median_re_deg",
)


def summarize(t_err: np.ndarray, r_err: np.ndarray) -> dict[str, float]:
    """All metrics of one set of queries; ``inf``/NaN errors mean the query failed."""
    t = np.asarray(t_err, dtype=np.float64).ravel()
    r = np.asarray(r_err, dtype=np.float64).ravel()
    if t.shape != r.shape:
        raise ValueError(f"translation and rotation errors differ in length ({t.size} vs {r.size})")
    failed = ~(np.isfinite(t) & np.isfinite(r))
    t = np.where(failed, np.inf, t)
    r = np.where(failed, np.inf, r)
    n = t.size
    out: dict[str, float] = {"n_queries": float(n), "n_failed": float(failed.sum())}

    def pct(mask: np.ndarray) -> float:
        return 100.0 * float(mask.sum()) / n if n else float("nan")

    for key, thr in THRESHOLDS_M.items():
        out[f"recall_{key}"] = pct(t < thr)
    out["recall_25cm_5deg"] = pct((t < COMBINED[0]) & (r < COMBINED[1]))
    for key in ACCURACY_THRESHOLDS:
        inside = t < THRESHOLDS_M[key]
        out[f"mte_{key}_m"] = float(t[inside].mean()) if inside.any() else float("nan")
        out[f"mre_{key}_deg"] = float(r[inside].mean()) if inside.any() else float("nan")
    out["median_te_m"] = float(np.median(t)) if n else float("nan")
    out["median_re_deg"] = float(np.median(r)) if n else float("nan")
    return out


def cumulative_curve(errors: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Percent of ALL queries with error <= each grid value (failures never count)."""
    e = np.sort(np.where(np.isfinite(errors), errors, np.inf))
    if e.size == 0:
        return np.full(len(grid), np.nan)
    return 100.0 * np.searchsorted(e, grid, side="right") / e.size
