"""Compare two controller-benchmark runs episode by episode (``episodes.csv``).

For a change that must not move results, or must move only some: prints, per plant set and
metric, how many episodes differ and the largest absolute and relative difference, then
every episode whose success changed (controller, plant set, task, seed, old → new).

    python experiments/compare_benchmark.py OLD/episodes.csv NEW/episodes.csv
    python experiments/compare_benchmark.py \\
        <(git show d8cdc60:experiments/results/benchmark/episodes.csv) \\
        experiments/results/benchmark/episodes.csv
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd

KEYS = ["controller", "plant_set", "task", "seed"]
METRICS = ["success", "settle_time_s", "tracking_rms_nm", "hold_rms_nm", "runaway_um",
           "energy_per_um_mJ"]  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    args = ap.parse_args()
    old, new = pd.read_csv(args.old), pd.read_csv(args.new)
    for name, df in (("old", old), ("new", new)):
        missing = [k for k in KEYS + METRICS if k not in df.columns]
        if missing:
            print(f"{name}: {getattr(args, name)}: no column {missing[0]!r}", file=sys.stderr)
            return 2
    both = old.merge(new, on=KEYS, suffixes=("_old", "_new"), how="outer", indicator=True)
    unmatched = int((both["_merge"] != "both").sum())
    both = both[both["_merge"] == "both"]
    print(f"{len(both)} episodes in both runs, {unmatched} in only one")
    for ps in ["all", *sorted(both["plant_set"].unique())]:
        part = both if ps == "all" else both[both["plant_set"] == ps]
        print(f"\n{ps} ({len(part)} episodes)")
        print("| metric | episodes that differ | max |Δ| | max |Δ|/|old| |")
        print("|---|---:|---:|---:|")
        for m in METRICS:
            a, b = part[f"{m}_old"].to_numpy(float), part[f"{m}_new"].to_numpy(float)
            same = (a == b) | (np.isnan(a) & np.isnan(b))
            d = np.where(same, 0.0, np.abs(a - b))
            rel = np.where(same, 0.0, d / np.maximum(np.abs(a), 1e-300))
            print(f"| {m} | {int((~same).sum())} | {np.nanmax(d, initial=0.0):.3g} | "
                  f"{np.nanmax(rel, initial=0.0):.3g} |")  # fmt: skip
    flips = both[both["success_old"] != both["success_new"]]
    print(f"\nsuccess changed in {len(flips)} episodes:")
    for _, r in flips.iterrows():
        print(f"  {r['controller']} {r['plant_set']}/{r['task']} seed {r['seed']}: "
              f"{r['success_old']:g} → {r['success_new']:g}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
