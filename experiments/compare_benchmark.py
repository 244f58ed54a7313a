"""Compare two controller-benchmark runs episode by episode (``episodes.csv``).

For a refactoring that must not move results: prints, per metric, how many episodes
differ and the largest absolute and relative difference, overall and per plant condition.

    python experiments/compare_benchmark.py OLD/episodes.csv NEW/episodes.csv
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd

KEYS = ["controller", "condition", "axis", "size", "move_nm", "seed"]
METRICS = ["final_error_nm", "settle_time_s", "steps", "energy_J", "overshoot_nm", "success"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    args = ap.parse_args()
    old, new = pd.read_csv(args.old), pd.read_csv(args.new)
    both = old.merge(new, on=KEYS, suffixes=("_old", "_new"), how="outer", indicator=True)
    unmatched = int((both["_merge"] != "both").sum())
    both = both[both["_merge"] == "both"]
    print(f"{len(both)} episodes in both runs, {unmatched} in only one")
    for cond in ["all", *sorted(both["condition"].unique())]:
        part = both if cond == "all" else both[both["condition"] == cond]
        print(f"\n{cond} ({len(part)} episodes)")
        print("| metric | episodes that differ | max |Δ| | max |Δ|/|old| |")
        print("|---|---:|---:|---:|")
        for m in METRICS:
            a, b = part[f"{m}_old"].to_numpy(float), part[f"{m}_new"].to_numpy(float)
            same = (a == b) | (np.isnan(a) & np.isnan(b))
            d = np.where(same, 0.0, np.abs(a - b))
            rel = np.where(same, 0.0, d / np.maximum(np.abs(a), 1e-300))
            print(f"| {m} | {int((~same).sum())} | {np.nanmax(d):.3g} | {np.nanmax(rel):.3g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
