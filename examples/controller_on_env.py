"""A baseline controller moves the turntable 200 µrad on PiezoTurntable-v0.

    python examples/controller_on_env.py [--controller fuzzy] [--target 2e-4] [--steps 200]

The controller sees only what a lab sees: the observation and a LabBrief with the
commanded target. Prints the intervals it took and the final error at the table radius.
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import turntable_env  # noqa: F401  (registers PiezoTurntable-v0)
from controllers import LabBrief, available, make


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controller", default="fuzzy", choices=available())
    ap.add_argument("--target", type=float, default=2e-4, help="target angle [rad]")
    ap.add_argument("--steps", type=int, default=200, help="control intervals at most")
    args = ap.parse_args()
    env = gym.make("PiezoTurntable-v0")  # Table D.1, reduced model, axis B, 10 ms steps
    obs, _ = env.reset(seed=0, options={"start_angle": 0.0, "target_angle": args.target})
    ctl = make(args.controller, env)
    ctl.reset(obs, LabBrief(target_rad=args.target))
    info: dict = {}
    k = 0
    while k < args.steps:
        obs, _r, terminated, truncated, info = env.step(ctl.act(obs))
        k += 1
        if terminated or truncated:
            break
    radius = env.unwrapped.config.parameter_set.detector.table_radius  # m
    err_nm = abs(info["angle_rad"] - args.target) * radius * 1e9
    print(f"{args.controller}: {k} intervals ({k * 0.01:.2f} s), success {info['is_success']}, "
          f"final error {err_nm:.1f} nm at the table radius")  # fmt: skip


if __name__ == "__main__":
    main()
