"""Env throughput before and after a change, side by side in one run.

Checks out ``--before`` (a git revision) into a temporary worktree and runs
``turntable_env.bench.env_throughput`` (the figures of ``turntable bench --env-only``)
from that tree and from this one, alternating, ``--rounds`` times each (a warm-up run of
each first: numba compiles or loads its cache). Prints every round and the medians, and
the after/before ratios.

    python experiments/compare_env_throughput.py --before HEAD~3 [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
KEYS = (
    "env_steps_per_s_random",
    "env_steps_per_s_nominal",
    "vector_env_steps_per_s_random",
    "vector_env_steps_per_s_nominal",
)
CODE = (
    "import json, sys; sys.path.insert(0, '.'); "
    "from turntable_env.bench import env_throughput; "
    "print(json.dumps(env_throughput(n_steps={n})))"
)


def _run(tree: Path, n_steps: int) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, "-c", CODE.format(n=n_steps)],
        cwd=tree, capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="git revision to compare against")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=3000, help="env steps per measurement")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "before"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(old),
                        args.before], check=True, capture_output=True)  # fmt: skip
        try:
            trees = {"before": old, "after": ROOT}
            for tree in trees.values():
                _run(tree, 200)  # warm-up: compile or load the numba cache
            runs: dict[str, list[dict[str, float]]] = {k: [] for k in trees}
            for r in range(args.rounds):
                for name, tree in trees.items():
                    runs[name].append(_run(tree, args.steps))
                    row = ", ".join(f"{k} {runs[name][-1][k]:.0f}" for k in KEYS)
                    print(f"round {r + 1} {name:>6}: {row}", flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(old)],
                           check=False, capture_output=True)  # fmt: skip
    print(f"\nmedians over {args.rounds} rounds (env steps/s; before = {args.before})")
    print("| figure | before | after | after/before |")
    print("|---|---:|---:|---:|")
    for k in KEYS:
        b = statistics.median(x[k] for x in runs["before"])
        a = statistics.median(x[k] for x in runs["after"])
        print(f"| {k} | {b:.0f} | {a:.0f} | {a / b:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
