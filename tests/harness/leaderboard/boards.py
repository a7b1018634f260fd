"""Board rows and results folders the board tests share."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench.data.scene import DIFFICULTY_AXES


def runs(*rows: tuple[str, str, float, float, float], split: str = "query") -> pd.DataFrame:
    """Board rows: (method, track, R@50cm, R@25cm, map MB) on one split."""
    return pd.DataFrame(
        [{"method": m, "track": t, "split": split, "recall_50cm": r50, "recall_25cm": r25, "map_mb": mb}
         for m, t, r50, r25, mb in rows]
    )  # fmt: skip


def errors(t: list[float]) -> dict[str, np.ndarray]:
    """Translation errors as given, 1° of rotation where localized (inf where not)."""
    t_err = np.array(t, dtype=float)
    return {"t_err_m": t_err, "r_err_deg": np.where(np.isfinite(t_err), 1.0, np.inf)}


def results_dir(root: Path, method: str, versioned: bool = True) -> Path:
    """A results folder whose tables/queries.csv holds eight queries of one scene on two splits, with their
    difficulty and data v2, or (not ``versioned``) as tables were written before either existed."""
    q = pd.DataFrame(
        {
            "method": method, "track": "predicted", "scene": "s1", "split": ["query"] * 4 + ["query_light1"] * 4,
            "query": [f"{s}/{i:06d}" for s in ("query", "query_light1") for i in range(4)],
            "success": True, **errors([0.1, 0.3, 0.6, 0.1, 0.3, 0.3, 0.6, 0.6]), "runtime_s": 0.01, "reason": "",
            **{f"{p}_{a}": 0.0 for p in ("gt", "est") for a in "xyz"},
            "map_hash": "h", "config_hash": "c", "spec_hash": "spec", "git_commit": "abc",
            "gap_m": [0.1, 0.3, 0.6, 0.1] * 2, "gap_deg": np.nan, "light_level": [1.0] * 4 + [0.5] * 4,
            "visible_objects": 3, "object_area": np.nan, "displaced_in_view": 0, "lookalikes_in_view": [0, 1] * 4,
        }
    )  # fmt: skip
    if versioned:
        q["data_version"] = 2
    else:
        q = q.drop(columns=list(DIFFICULTY_AXES))
    (root / "tables").mkdir(parents=True)
    q.to_csv(root / "tables" / "queries.csv", index=False)
    return root
