"""Hyperparameter search for an agent: Optuna over rl-zoo3's search space, trials as Ray tasks.

    python experiments/tune_rl.py --algo ppo --trials 16 --timesteps 100000 --parallel 2
    python experiments/tune_rl.py --algo sac --trials 64 --parallel 32 --address auto  # cluster

Each trial trains ``--timesteps`` steps with rl-zoo3's sampled SB3 arguments laid over the
env id's entry of agents/hyperparams/<algo>.yml and is scored by its last evaluation's
mean return (agents/tune.py). ``--parallel`` trials run at once: Ray tasks (a local
instance, or ``--address``) or, without Ray, local processes. The study is kept in
``--out``/study.log: rerunning adds trials to it. Prints one row per trial and the best;
``--out``/best.yml trains at full budget with ``python experiments/train_rl.py --algo ALGO
--hyperparams OUT/best.yml``.
"""

from __future__ import annotations

import argparse
import sys

from agents.train import ENV_ID, ENV_IDS
from agents.tune import TUNABLE, search
from turntable_env.scale import BACKENDS


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--algo", choices=TUNABLE, required=True)
    ap.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID)
    ap.add_argument("--trials", type=int, default=16, help="trials to add to the study")
    ap.add_argument("--timesteps", type=int, default=50_000, help="steps per trial")
    ap.add_argument("--parallel", type=int, default=2, help="trials at a time")
    ap.add_argument("--eval-episodes", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="runs/tune")
    ap.add_argument("--backend", choices=BACKENDS, default="auto")
    ap.add_argument("--address", default=None, help="Ray cluster to join (default: local)")
    args = ap.parse_args(argv)
    try:
        res = search(
            args.algo, args.trials, env_id=args.env_id, timesteps=args.timesteps,
            parallel=args.parallel, eval_episodes=args.eval_episodes, seed=args.seed,
            out=args.out, backend=args.backend, address=args.address,
        )  # fmt: skip
    except ValueError as e:
        print(f"tune_rl: {e}", file=sys.stderr)
        return 2
    df = res.to_pandas()
    cols = ["number", "state", "value", "duration"]
    print(df[[c for c in cols if c in df.columns]].to_string(index=False))
    print(f"best: trial {res.best_number}, mean evaluation return {res.best_value:.3f}; "
          f"{res.best_file}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
