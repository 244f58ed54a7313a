"""What a fresh numba cache costs a user's first steps: a single env's first step, then a
vector env's (the parallel batch kernel), each timed in a new process with its own empty
cache directory, so every kernel it needs compiles there.

    python experiments/first_step_compile.py          # prints both, in seconds
    python experiments/first_step_compile.py --json   # one JSON object

Run it at two commits (a git worktree, ``PYTHONPATH`` pointing at it) one after the other
for a side-by-side figure; the numbers are wall seconds on the machine it runs on.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

CHILD = """
import json, time
t = time.perf_counter()
import gymnasium as gym, numpy as np, turntable_env
env = gym.make("PiezoTurntable-v0"); env.reset(seed=0); env.step(env.action_space.sample())
single = time.perf_counter() - t
from turntable_env.envs.vector import PiezoTurntableVectorEnv
t = time.perf_counter()
v = PiezoTurntableVectorEnv(2, 20); v.reset(seed=0); v.step(v.action_space.sample())
print(json.dumps({"single_env_first_step_s": single,
                  "vector_env_first_step_s": time.perf_counter() - t}))
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="first-step-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        r = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True,
                           text=True, check=False)  # fmt: skip
    if r.returncode != 0:
        print(r.stderr.strip().splitlines()[-1] if r.stderr.strip() else "failed",
              file=sys.stderr)  # fmt: skip
        return 1
    out = json.loads(r.stdout.strip().splitlines()[-1])
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k}: {v:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
