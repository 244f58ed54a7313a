"""Calibration time of this checkout against another commit, side by side on one machine:
``turntable calibrate TRACE --report DIR`` run alternately from each (a git worktree of
the other commit in a temporary directory), every run with a new numba cache, as on a
fresh machine (issue 31's figure: a 2.5 s trace at 20 kHz in under 5 minutes on this
machine's 2 cores), and each run's wall time (report.json ``wall_s``), simulations and
result printed, with the ratio of the medians and whether the two calibrations agree.

    python experiments/calibration_speed.py d621488

Ratios > 1 mean this checkout is faster. Run it on an otherwise quiet machine: the
calibration uses every core it is given.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from bench_compare import ROOT, worktree  # this directory is on sys.path

TRACE = ROOT / "experiments" / "results" / "second_plant_traces" / "axis_C_20kHz.csv"


def calibrate_command(trace: Path, report: Path, workers: int) -> list[str]:
    """``turntable calibrate TRACE --report REPORT --workers N`` as a subprocess's argv,
    its output unbuffered (progress lines arrive as they are printed)."""
    return [sys.executable, "-u", "-m", "turntable_env.cli", "calibrate", str(trace),
            "--report", str(report), "--workers", str(workers)]  # fmt: skip


def _calibrate(tree: Path, trace: Path, out: Path, workers: int) -> dict:
    """One calibration from ``tree`` with a new numba cache: its report.json."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(out / "numba")}
    cmd = calibrate_command(trace, out / "report", workers)
    done = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"calibrate from {tree} failed ({done.returncode}): {last}")
    return json.loads((out / "report" / "report.json").read_text())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("commit", help="the commit to compare with")
    ap.add_argument("--trace", type=Path, default=TRACE, help="the trace (default: %(default)s)")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error(f"--repeats={args.repeats}: must be >= 1")
    if args.workers < 1:
        ap.error(f"--workers={args.workers}: must be >= 1")
    if not args.trace.is_file():
        ap.error(f"--trace {args.trace}: no such file (python experiments/second_plant_traces.py "
                 "writes the default one)")  # fmt: skip
    with worktree(args.commit) as (other, tmp):
        trees = {"this": ROOT, args.commit: other}
        reports: dict[str, list[dict]] = {k: [] for k in trees}
        for r in range(args.repeats):
            for i, (k, tree) in enumerate(trees.items()):
                rep = _calibrate(tree, args.trace.resolve(), tmp / f"run{r}-{i}", args.workers)
                reports[k].append(rep)
                print(f"{k:>12}: {rep['wall_s']:7.1f} s, "
                      f"{rep['diagnosis']['n_simulations']} simulations, "
                      f"effects {rep['selected_effects'] or 'none'}, "
                      f"held-out {rep['error_after']:.4g} nm", flush=True)  # fmt: skip
    med = {k: statistics.median(r["wall_s"] for r in v) for k, v in reports.items()}
    print(f"median wall time: this {med['this']:.1f} s, {args.commit} {med[args.commit]:.1f} s, "
          f"ratio {med[args.commit] / med['this']:.2f} ({args.workers} workers, a new numba "
          "cache each run)")  # fmt: skip
    a, b = reports["this"][0], reports[args.commit][0]
    same = all(a[k] == b[k] for k in ("selected_effects", "parameters", "error_after"))
    print(f"the same calibration (effects, parameters, held-out error): {same}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
