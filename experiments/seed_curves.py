"""Learning curves across seeds: mean evaluation return with its 95 % bootstrap interval.

    python experiments/seed_curves.py --runs ppo=/tmp/rl/ppo_seed0,/tmp/rl/ppo_seed1,... \
        --runs sac=... --out agents/pretrained/learning_curves.png [--ship NAME]

Each ``--runs LABEL=DIR,DIR,...`` names the run directories of one algorithm (written by
``python experiments/train_rl.py``); the figure holds one band per label, and the command
prints, per label, the last common evaluation's mean [95 % interval] and every seed's
value and the seed whose last evaluation is best (the one to ship). ``--ship NAME`` copies
that seed's run of the first label to ``agents/pretrained/NAME/`` (``agents.train.ship``),
where ``import agents`` registers it as the controller NAME: the choice is the training's
own evaluation, never the benchmark's plants.

``--validate N`` chooses instead by N validation episodes of the training's own
distribution, the same episodes for every seed (``agents.scale.validate_seeds``): each
run's last evaluation drew its episodes from its own seed, so its value moves with them
(docs/rl.md, result 5). It prints each seed's mean validation return and the best seed's
paired margin over the runner-up with its 95 % interval; an interval that includes 0 is
a tie, and ``--ship`` then ships nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from agents import PRETRAINED_DIR
from agents.scale import check_validation, plot_seed_curves, seed_curves, validate_seeds
from agents.train import ship


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", action="append", required=True, help="LABEL=DIR,DIR,...")
    ap.add_argument("--out", default="learning_curves.png")
    ap.add_argument("--ship", default=None, metavar="NAME",
                    help="copy the first label's best seed to agents/pretrained/NAME/")
    ap.add_argument("--validate", type=int, default=None, metavar="N",
                    help="choose the first label's seed by N common validation episodes")
    args = ap.parse_args()
    if args.validate is not None:
        try:
            check_validation(args.validate)
        except ValueError as e:
            ap.error(f"--validate: {e}")  # exit 2, one line, before any work
    if args.ship is not None and not args.ship.isidentifier():
        ap.error(f"--ship {args.ship!r}: must be an identifier (the controller name)")
    curves = {}
    to_ship: Path | None = None  # the first label's chosen seed (None: a tie)
    for i, spec in enumerate(args.runs):
        label, _, dirs = spec.partition("=")
        runs = [Path(d) for d in dirs.split(",") if d]
        if not label or len(runs) < 2:
            raise SystemExit(f"--runs {spec!r}: need LABEL=DIR,DIR[,...]")
        c = seed_curves(runs)
        curves[label] = c
        seeds = [yaml.safe_load((r / "config.yml").read_text())["run"]["seed"] for r in runs]
        walls = [yaml.safe_load((r / "config.yml").read_text())["run"]["wall_s"] for r in runs]
        first = [round(float(x), 1) for x in c["per_run"][:, 0]]
        last = [round(float(x), 1) for x in c["per_run"][:, -1]]
        best = int(np.argmax(last))
        margin = last[best] - max((v for i, v in enumerate(last) if i != best), default=np.nan)
        print(f"{label}: {len(runs)} seeds {seeds}, last common evaluation at "
              f"{int(c['timesteps'][-1])} steps: {c['mean'][-1]:.1f} "
              f"[{c['ci_low'][-1]:.1f}, {c['ci_high'][-1]:.1f}]; per seed "
              f"{last} (first evaluation, at {int(c['timesteps'][0])} steps: {first}); "
              f"best seed {seeds[best]}, by {margin:.1f}; wall s {walls}")  # fmt: skip
        if i == 0 and args.validate is not None:
            v = validate_seeds(runs, episodes=args.validate)
            b, lo, hi = v["best"], *v["margin_ci"]
            print(f"{label}: validation, {args.validate} common episodes: mean return per "
                  f"seed {[round(float(m), 1) for m in v['mean']]}; best seed {seeds[b]}, "
                  f"by {v['margin']:.1f} [{lo:.1f}, {hi:.1f}] over seed "
                  f"{seeds[v['runner_up']]} ({'paired' if v['paired'] else 'unpaired'}, 95 %): "
                  f"{'decided' if v['decided'] else 'a tie, nothing to ship'}")  # fmt: skip
            to_ship = runs[b] if v["decided"] else None
        elif i == 0:
            to_ship = runs[best]
    print(f"figure: {plot_seed_curves(curves, args.out)}")
    if args.ship is not None and to_ship is not None:
        print(f"shipped {to_ship} to {ship(to_ship, PRETRAINED_DIR / args.ship)}")


if __name__ == "__main__":
    main()
