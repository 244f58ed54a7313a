"""Train a SAC agent on the structured interface and run it on the env.

    python examples/train_agent.py [--timesteps 20000] [--out runs/example_sac]

Trains with the shipped hyperparameters (agents/hyperparams/sac.yml, rl-zoo3 layout) on
the native vector env under VecNormalize, then registers the run as a controller and
moves the turntable with it. A few thousand steps only show the pipeline; the shipped
agent took 400 000.
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import turntable_env  # noqa: F401
from agents import register_run
from agents.train import train
from controllers import LabBrief, make


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--timesteps", type=int, default=20_000)
    ap.add_argument("--out", default="runs/example_sac")
    args = ap.parse_args()
    run = train("sac", timesteps=args.timesteps, out=args.out, progress=False).run
    register_run("example_sac", run)
    env = gym.make("PiezoTurntable-v0")
    obs, _ = env.reset(seed=0, options={"start_angle": 0.0, "target_angle": 2e-4})
    ctl = make("example_sac", env)
    ctl.reset(obs, LabBrief(target_rad=2e-4))
    for _ in range(50):
        obs, _r, terminated, truncated, info = env.step(ctl.act(obs))
        if terminated or truncated:
            break
    print(f"trained {args.timesteps} steps in {run}; final angle {info['angle_rad']:.3e} rad "
          f"(target 2e-4)")  # fmt: skip


if __name__ == "__main__":
    main()
