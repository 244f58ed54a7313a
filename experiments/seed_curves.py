"""Learning curves across seeds: mean evaluation return with its 95 % bootstrap interval.

    python experiments/seed_curves.py --runs ppo=/tmp/rl/ppo_seed0,/tmp/rl/ppo_seed1,... \
        --runs sac=... --out agents/pretrained/learning_curves.png

Each ``--runs LABEL=DIR,DIR,...`` names the run directories of one algorithm (written by
``python experiments/train_rl.py``); the figure holds one band per label, and the command
prints, per label, the last common evaluation's mean [95 % interval] and every seed's
value and the seed whose last evaluation is best (the one to ship).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from agents.scale import plot_seed_curves, seed_curves


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", action="append", required=True, help="LABEL=DIR,DIR,...")
    ap.add_argument("--out", default="learning_curves.png")
    args = ap.parse_args()
    curves = {}
    for spec in args.runs:
        label, _, dirs = spec.partition("=")
        runs = [Path(d) for d in dirs.split(",") if d]
        if not label or len(runs) < 2:
            raise SystemExit(f"--runs {spec!r}: need LABEL=DIR,DIR[,...]")
        c = seed_curves(runs)
        curves[label] = c
        seeds = [yaml.safe_load((r / "config.yml").read_text())["run"]["seed"] for r in runs]
        walls = [yaml.safe_load((r / "config.yml").read_text())["run"]["wall_s"] for r in runs]
        last = [round(float(x), 1) for x in c["per_run"][:, -1]]
        best = int(np.argmax(last))
        print(f"{label}: {len(runs)} seeds {seeds}, last common evaluation at "
              f"{int(c['timesteps'][-1])} steps: {c['mean'][-1]:.1f} "
              f"[{c['ci_low'][-1]:.1f}, {c['ci_high'][-1]:.1f}]; per seed "
              f"{last}; best seed {seeds[best]}; wall s {walls}")  # fmt: skip
    print(f"figure: {plot_seed_curves(curves, args.out)}")


if __name__ == "__main__":
    main()
