"""Speed of this checkout against another commit, side by side on one machine:
``turntable bench --quick --json`` run alternately from each (a git worktree of the other
commit in a temporary directory, each with its own numba cache, compiled before timing),
``--repeats`` times, and the medians of the speed figures with their ratio printed.

    python experiments/bench_compare.py e52b118 --repeats 3

Ratios > 1 mean this checkout is faster. Alternating the runs spreads a busy machine's
load over both sides; the spread over repeats says how much a ratio can be trusted.
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("commit", help="the commit to compare with")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error(f"--repeats={args.repeats}: must be >= 1")
    with worktree(args.commit) as (other, tmp):
        trees = {"this": ROOT, args.commit: other}
        caches = {k: tmp / f"numba-{i}" for i, k in enumerate(trees)}
        for k, tree in trees.items():  # compile both before any timing
            _bench(tree, caches[k])
        runs: dict[str, list[dict]] = {k: [] for k in trees}
        for _ in range(args.repeats):
            for k, tree in trees.items():
                runs[k].append(_bench(tree, caches[k]))
    print(f"{'figure':32s} {'this':>10s} {args.commit:>10s} {'ratio':>7s}  range of ratios")
    for f in FIGURES:
        a = [r[f] for r in runs["this"] if f in r]
        b = [r[f] for r in runs[args.commit] if f in r]
        if not a or not b:
            continue
        ratios = [x / y for x, y in zip(a, b, strict=False)]
        print(f"{f:32s} {statistics.median(a):10.4g} {statistics.median(b):10.4g} "
              f"{statistics.median(a) / statistics.median(b):7.3f}  "
              f"{min(ratios):.3f}–{max(ratios):.3f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
