"""The controller benchmark (issue 6): every registered controller on the fixed suite.

Same run as ``turntable benchmark``: 50 nm / 2 µm / 50 µm moves about A, B and C on the
nominal plant and on 20 randomised plants per task; writes episodes.csv, summary.csv,
summary.md, summary.json and trajectory plots to ``--out`` (default
experiments/results/benchmark) and prints the markdown table and the JSON summary.

    python experiments/controller_benchmark.py [--seeds 20] [--out DIR]   (about 30 s)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from controllers.benchmark import run_benchmark, write_outputs

DEFAULT_OUT = Path(__file__).parent / "results" / "benchmark"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--controllers", default=None, help="comma-separated (default: all)")
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    args = ap.parse_args()
    names = args.controllers.split(",") if args.controllers else None
    res = run_benchmark(names, seeds=args.seeds, progress=True)
    paths = write_outputs(res, args.out)
    print(res.markdown())
    print(json.dumps({k: {m: v[m] for m in ("success_rate", "median_final_error_nm",
          "median_settle_time_s")} for k, v in res.summary().items()}, indent=2))  # fmt: skip
    print("randomised plants: success rate, median settle time [s] (∞: most never settle)")
    for name, entry in res.summary().items():
        r = entry["conditions"].get("randomized")
        if r is not None:
            settle = r["median_settle_time_s"]
            settle_s = "∞" if settle is None else f"{settle:.3g}"
            print(f"  {name:<12} {r['success_rate']:.3f}  {settle_s}")
    print(f"{len(res.rows)} episodes in {res.settings['wall_s']:.1f} s; files in "
          f"{paths['summary_md'].parent}")  # fmt: skip


if __name__ == "__main__":
    main()
