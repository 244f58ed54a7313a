"""Train an RL agent on PiezoTurntable-v0 (stable-baselines3), as the shipped ones were.

    python experiments/train_rl.py --algo ppo --timesteps 400000 --seed 0 --out runs/ppo
    python experiments/train_rl.py --algo sac --seed 0 --ship   # the shipped SAC agent

Hyperparameters: agents/hyperparams/<algo>.yml (rl-baselines3-zoo layout); --timesteps
overrides n_timesteps. Writes model.zip, vecnormalize.pkl, config.yml, logs/progress.csv
(and TensorBoard with --tensorboard), eval/evaluations.npz, checkpoints/ and
learning_curve.png to --out, and prints the wall time and the last evaluation.
--ship then copies the agent (without checkpoints) to agents/pretrained/<algo>/, where
``import agents`` registers it as a controller for ``turntable benchmark``.
"""

from __future__ import annotations

import argparse

import numpy as np

from agents import PRETRAINED_DIR
from agents.train import ALGOS, ship, train


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--algo", choices=ALGOS, required=True)
    ap.add_argument("--timesteps", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="run directory (default runs/<algo>_seed<S>)")
    ap.add_argument("--hyperparams", default=None, help="YAML file (default: the algo's)")
    ap.add_argument("--tensorboard", action="store_true", help="also log for TensorBoard")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--ship", action="store_true", help="copy to agents/pretrained/<algo>/")
    args = ap.parse_args()
    out = args.out or f"runs/{args.algo}_seed{args.seed}"
    run = train(
        args.algo,
        timesteps=args.timesteps,
        seed=args.seed,
        out=out,
        hyperparams=args.hyperparams,
        tensorboard=args.tensorboard,
        progress=not args.no_progress,
    ).run
    import yaml

    cfg = yaml.safe_load((run / "config.yml").read_text())
    print(f"trained {args.algo} for {cfg['run']['timesteps']} steps in {cfg['run']['wall_s']} s")
    ev = run / "eval" / "evaluations.npz"
    if ev.is_file():
        d = np.load(ev)
        print(
            f"last evaluation at {int(d['timesteps'][-1])} steps: return "
            f"{d['results'][-1].mean():.2f} ± {d['results'][-1].std():.2f}"
        )
    print(f"run directory: {run}")
    if args.ship:
        print(f"shipped to {ship(run, PRETRAINED_DIR / args.algo)}")


if __name__ == "__main__":
    main()
