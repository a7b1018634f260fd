"""How many wrong poses sit a whole texture period away from the truth.

Benchmark data v1 textured every surface with a tile repeating exactly every 0.5 m, so a pose shifted
by whole tiles explains as many feature matches as the true one. Data v2 removed the repetition; this
script measures what that changed: per results directory, method and split, the wrong poses (an
estimate more than ``--wrong-m`` from the truth) and the share of them that keep the rotation (within
``--max-rot-deg``) and are shifted by a whole number of periods along every world axis (within
``--tol-m``).

    python benchmarks/periodic_shifts.py RESULTS [RESULTS ...] [--period-m 0.5]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from openreloc_bench.data.runs import load_run_queries
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.methods import uses_masks


def whole_period_shift(offsets: np.ndarray, period_m: float, tol_m: float) -> np.ndarray:
    """(N,) True where every component of the (N, 3) offsets is a whole, not all zero, number of periods."""
    periods = np.round(offsets / period_m)
    return np.all(np.abs(offsets - periods * period_m) <= tol_m, axis=1) & np.any(periods != 0, axis=1)


def shift_table(
    queries: pd.DataFrame, period_m: float, tol_m: float, wrong_m: float, max_rot_deg: float
) -> pd.DataFrame:
    """Per (method, track, split): queries, recall at 50 cm, wrong poses and those at whole periods."""
    est = queries[["est_x", "est_y", "est_z"]].to_numpy(float)
    gt = queries[["gt_x", "gt_y", "gt_z"]].to_numpy(float)
    wrong = np.isfinite(est).all(axis=1) & (queries["t_err_m"].to_numpy(float) > wrong_m)
    periodic = wrong & (queries["r_err_deg"].to_numpy(float) <= max_rot_deg)
    periodic &= whole_period_shift(np.nan_to_num(est - gt), period_m, tol_m)
    df = queries.assign(wrong=wrong, periodic=periodic, r50=queries["t_err_m"] <= 0.5)
    out = df.groupby(["variant", "track", "split"], sort=True).agg(
        queries=("wrong", "size"), recall_50cm=("r50", "mean"), wrong=("wrong", "sum"), at_periods=("periodic", "sum")
    )
    out["recall_50cm"] = (100 * out["recall_50cm"]).round(1)
    out["share_at_periods"] = (100 * out["at_periods"] / out["wrong"].where(out["wrong"] > 0)).round(1)
    return out.reset_index()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("results", nargs="+", type=Path, help="results directories of `openreloc-bench eval`")
    p.add_argument("--period-m", type=float, default=0.5, help="texture period to test (m; data v1: 0.5)")
    p.add_argument("--tol-m", type=float, default=0.05, help="tolerance per axis (m)")
    p.add_argument("--wrong-m", type=float, default=0.5, help="an estimate farther than this is wrong (m)")
    p.add_argument("--max-rot-deg", type=float, default=1.0, help="rotation error of a periodic shift (deg)")
    args = p.parse_args(argv)
    try:
        for r in args.results:
            queries = load_run_queries(r, uses_masks)
            if queries.empty:
                raise ConfigError(f"{r}: no finished query jobs")
            print(f"# {r}")
            table = shift_table(queries, args.period_m, args.tol_m, args.wrong_m, args.max_rot_deg)
            print(table.to_string(index=False))
    except (ConfigError, DataError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
