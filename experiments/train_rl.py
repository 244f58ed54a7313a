"""Train an RL agent on PiezoTurntable-v0 (stable-baselines3), as the shipped ones were.

    python experiments/train_rl.py --algo ppo --timesteps 400000 --seed 0 --out runs/ppo
    python experiments/train_rl.py --algo sac --seed 0 --ship   # the shipped SAC agent
    python experiments/train_rl.py --algo sac --env-id PiezoTurntable-v0 --ship  # raw 5-D
    python experiments/train_rl.py --algo ppo --seeds 0,1,2 --ship   # 3 seeds, best shipped
    python experiments/train_rl.py --algo ppo --seeds 0,1,2,3,4 --address auto  # on a cluster

--seeds trains one run per seed as Ray tasks (pip install -e ".[scale]"; a local Ray
instance unless --address names a cluster) or, without Ray, in local processes, and
draws the curve across seeds (mean and 95 % interval) to --out/learning_curves_<algo>.png.

Hyperparameters: the --env-id entry (default PiezoTurntableAgent-v0, the structured
interface) of agents/hyperparams/<algo>.yml (rl-zoo3 layout) and the algorithm's entry of
training.yml (or --training FILE: training_domains.yml trains half the rows on the
calibrated plant's posterior); --timesteps overrides n_timesteps. Writes model.zip,
vecnormalize.pkl, config.yml, logs/progress.csv (and TensorBoard with --tensorboard),
eval/evaluations.npz, checkpoints/ and learning_curve.png to --out, and prints the wall
time and the last evaluation. --ship then copies the agent (without checkpoints) to
agents/pretrained/<algo>/ (the raw env: <algo>_raw/), where
``import agents`` registers it as a controller for ``turntable benchmark``.
"""

from __future__ import annotations

import argparse

import numpy as np

from agents import PRETRAINED_DIR
from agents.interface import RAW_ENV_ID
from agents.train import ALGOS, ENV_ID, ENV_IDS, ship, train
from turntable_env.scale import BACKENDS


def _multi(args: argparse.Namespace, name: str) -> None:
    """--seeds: one run per seed (Ray tasks, or local processes), the curve across seeds."""
    from agents.scale import plot_seed_curves, seed_curves, train_seeds

    seeds = [int(x) for x in args.seeds.split(",") if x.strip()]
    root = args.out or "runs"
    runs = train_seeds(
        args.algo, seeds, env_id=args.env_id, timesteps=args.timesteps, out=root,
        hyperparams=args.hyperparams, training=args.training, backend=args.backend,
        address=args.address, workers=args.workers, trained_agent=args.trained_agent,
    )  # fmt: skip
    c = seed_curves(runs)
    p = plot_seed_curves({name: c}, f"{root}/learning_curves_{name}.png")
    last = c["per_run"][:, -1]
    print(f"{len(runs)} seeds, last evaluation at {int(c['timesteps'][-1])} steps: return "
          f"{c['mean'][-1]:.2f} [{c['ci_low'][-1]:.2f}, {c['ci_high'][-1]:.2f}] (95 %); "
          f"per seed {np.round(last, 2).tolist()}; curve {p}")  # fmt: skip
    if args.ship:
        best = int(np.argmax(last))
        print(f"best seed {seeds[best]}: shipped to {ship(runs[best], PRETRAINED_DIR / name)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--algo", choices=ALGOS, required=True)
    ap.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID)
    ap.add_argument("--timesteps", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="run directory (default runs/<algo>_seed<S>)")
    ap.add_argument("--hyperparams", default=None, help="YAML file (default: the algo's)")
    ap.add_argument(
        "--training", default=None,
        help="training settings YAML (default agents/hyperparams/training.yml; "
        "training_domains.yml: the nominal and the calibrated plant's posterior)",
    )  # fmt: skip
    ap.add_argument("--tensorboard", action="store_true", help="also log for TensorBoard")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--ship", action="store_true", help="copy to agents/pretrained/<algo>/")
    ap.add_argument("--seeds", default=None, help="comma-separated: one run per seed")
    ap.add_argument(
        "--backend",
        choices=BACKENDS,
        default="auto",
        help="--seeds runs as Ray tasks (auto: when installed) or processes",
    )
    ap.add_argument("--address", default=None, help="Ray cluster to join (default: local)")
    ap.add_argument("--workers", type=int, default=None, help="processes for --seeds")
    ap.add_argument(
        "-i", "--trained-agent", default=None,
        help="continue this run directory for --timesteps more steps (rl-zoo3's option; "
        "with --seeds, {seed} in it is each seed)",
    )  # fmt: skip
    args = ap.parse_args()
    name = args.algo + ("_raw" if args.env_id == RAW_ENV_ID else "")
    if args.seeds:
        _multi(args, name)
        return
    out = args.out or f"runs/{name}_seed{args.seed}"
    run = train(
        args.algo,
        env_id=args.env_id,
        timesteps=args.timesteps,
        seed=args.seed,
        out=out,
        hyperparams=args.hyperparams,
        training=args.training,
        tensorboard=args.tensorboard,
        progress=not args.no_progress,
        trained_agent=args.trained_agent,
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
        print(f"shipped to {ship(run, PRETRAINED_DIR / name)}")


if __name__ == "__main__":
    main()
