"""What a residual agent does in one benchmark episode: interval by interval, its base's
mode, the agent's action a (the scale 2^a on the base's aim) and the error at the table.

    python experiments/residual_actions.py RUN [--task back_forth] [--seed 0]
        [--plant-set nominal]

RUN is a residual agent's run directory (``interface: {base: ...}``; agents/residual.py).
The episode is the benchmark's (:mod:`controllers.tasks`, suite seed 2026) on the plant
set's plant for that seed; the error is the true one (evaluation only, never the agent's),
at the interval's start (before its action). The env reads the y channel, as the
benchmark's does; the detector's noise is the env's own draw for that seed, not the
benchmark's noise streams, so the values differ from the benchmark's by the noise.
Printed: one line per interval (``k mode a error_um``), then the mean |a| while stepping
and in the interval a new target is commanded.
"""

from __future__ import annotations

import argparse

import numpy as np

from agents import AgentController
from agents.residual import ResidualInterface
from controllers.base import ControllerContext
from controllers.plant_sets import PLANT_SETS
from controllers.tasks import TASKS
from turntable_env.envs import PiezoTurntableEnv

SUITE_SEED = 2026


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("run")
    ap.add_argument("--task", default="back_forth", choices=list(TASKS))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plant-set", default="nominal", choices=list(PLANT_SETS))
    args = ap.parse_args()
    plant_set = PLANT_SETS[args.plant_set]()
    plant, _ = plant_set.plant(args.seed, SUITE_SEED)  # the seed's plant (evaluation only)
    task = TASKS[args.task]
    # the controller is built for the set's base plant, as in the benchmark
    ctx = ControllerContext.from_env(PiezoTurntableEnv(plant=plant_set.base, detector_y=True))
    try:
        ctl = AgentController(ctx, args.run)
    except ValueError as exc:  # a missing file of the run, named
        raise SystemExit(f"error: {exc}") from None
    if not isinstance(ctl.interface, ResidualInterface):
        raise SystemExit(f"{args.run}: not a residual agent (its config has no interface base)")
    env = PiezoTurntableEnv(plant=plant, terminate_on_success=False, detector_y=True)
    spec = task.episode(args.seed, ctx.detector, SUITE_SEED)
    obs, info = env.reset(seed=args.seed, options=spec.options())
    ctl.reset(obs, spec.brief)
    um = ctx.detector.table_radius * 1e6  # µm at the table radius per rad
    stepping: list[float] = []
    jumps: list[float] = []
    for k in range(task.horizon):
        jumped = k > 0 and spec.reference[k] != spec.reference[k - 1]
        action = float(ctl.policy_action(obs)[0])
        mode = ctl.state.mode  # the base as the agent's features saw it
        err = (info["target_rad"] - info["angle_rad"]) * um
        print(f"{k:3d} {mode:4s} {action:+.2f} {err:+.3f}")
        if mode == "step":
            stepping.append(abs(action))
        if jumped:
            jumps.append(abs(action))
        obs, _, _, _, info = env.step(ctl.act(obs))
    print(f"mean |a|: {_mean(stepping):.2f} while the base steps ({len(stepping)} intervals), "
          f"{_mean(jumps):.2f} when a new target comes ({len(jumps)})")


def _mean(x: list[float]) -> float:
    return float(np.mean(x)) if x else float("nan")


if __name__ == "__main__":
    main()
