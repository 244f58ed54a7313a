"""Speed of this checkout against another commit, side by side on one machine:
``turntable bench --quick --json`` run alternately from each (a git worktree of the other
commit in a temporary directory, each with its own numba cache, compiled before timing),
``--repeats`` times, and the medians of the speed figures with their ratio printed.

    python experiments/bench_compare.py e52b118 --repeats 3

Ratios > 1 mean this checkout is faster. Alternating the runs spreads a busy machine's
load over both sides; the spread over repeats says how much a ratio can be trusted.

``--benchmark`` times a subset of ``turntable benchmark`` instead (closed_loop,
feedforward and fuzzy on the nominal and held-out sets' 200 µm, edge and waypoints tasks,
4 seeds: 72 episodes, serial), the wall time its own summary line prints: the
controllers' cost per step, which ``turntable bench`` does not see.

    python experiments/bench_compare.py c53848a --benchmark --repeats 2
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIGURES = (  # speed figures of `turntable bench --json`, higher is faster
    "full_rtf",
    "reduced_rtf",
    "reduced_rtf_analytic",
    "reduced_rtf_no_output",
    "batched_rtf_aggregate",
    "env_steps_per_s_nominal",
    "vector_env_steps_per_s_nominal",
    "vector_env_steps_per_s_random",
)


@contextmanager
def worktree(commit: str) -> Iterator[tuple[Path, Path]]:
    """(a git worktree of ``commit``, a scratch directory), both in a temporary directory
    removed on exit, the worktree with it."""
    with tempfile.TemporaryDirectory() as tmp:
        other = Path(tmp) / "other"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(other), commit],
                       cwd=ROOT, check=True)  # fmt: skip
        try:
            yield other, Path(tmp)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(other)], cwd=ROOT,
                           check=False)  # fmt: skip


def _bench(tree: Path, cache: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "turntable_env.cli", "bench", "--quick", "--json"]
    out = subprocess.run(cmd, cwd=tree, env=env, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


BENCHMARK_SUBSET = ["--controllers", "closed_loop,feedforward,fuzzy", "--plant-sets",
                    "nominal,held_out", "--tasks", "point_200um,edge_5um,waypoints",
                    "--seeds", "4"]  # fmt: skip


def _benchmark(tree: Path, cache: Path, out: Path) -> dict:
    """``turntable benchmark`` on ``BENCHMARK_SUBSET`` from ``tree``: {"wall_s": its
    own count}."""
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "turntable_env.cli", "benchmark", *BENCHMARK_SUBSET,
           "--out", str(out)]  # fmt: skip
    res = subprocess.run(cmd, cwd=tree, env=env, check=True, capture_output=True, text=True)
    line = next(ln for ln in res.stdout.splitlines() if " s; files in " in ln)
    return {"wall_s": float(line.split(" s;")[0])}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("commit", help="the commit to compare with")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--benchmark", action="store_true",
                    help="time a subset of `turntable benchmark` (module docstring)")  # fmt: skip
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error(f"--repeats={args.repeats}: must be >= 1")
    with worktree(args.commit) as (other, tmp):
        trees = {"this": ROOT, args.commit: other}
        caches = {k: tmp / f"numba-{i}" for i, k in enumerate(trees)}

        def one(k: str) -> dict:
            if args.benchmark:
                return _benchmark(trees[k], caches[k], tmp / f"out-{k}")
            return _bench(trees[k], caches[k])

        for k in trees:  # compile both before any timing
            one(k)
        runs: dict[str, list[dict]] = {k: [] for k in trees}
        for _ in range(args.repeats):
            for k in trees:
                runs[k].append(one(k))
    print(f"{'figure':32s} {'this':>10s} {args.commit:>10s} {'ratio':>7s}  range of ratios")
    # a wall time: lower is faster, so the ratio is the other's over this one's
    figures = ("wall_s",) if args.benchmark else FIGURES
    for f in figures:
        a = [r[f] for r in runs["this"] if f in r]
        b = [r[f] for r in runs[args.commit] if f in r]
        if not a or not b:
            continue
        # the ratio > 1 where this checkout is faster: speeds this/other, times other/this
        num, den = (b, a) if args.benchmark else (a, b)
        ratios = [x / y for x, y in zip(num, den, strict=False)]
        print(f"{f:32s} {statistics.median(a):10.4g} {statistics.median(b):10.4g} "
              f"{statistics.median(num) / statistics.median(den):7.3f}  "
              f"{min(ratios):.3f}–{max(ratios):.3f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
