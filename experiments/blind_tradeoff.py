"""What the asymmetry-robust blind set buys and costs against the first one (issue 32's
run-away bound).

A move from beyond the detector is made blind: nothing is read until the spot comes into
view, so a setting that steps backwards on the plant at hand runs the table away until the
blind budget is spent. The first blind set (``controllers/data/blind_settings.csv``, the
default until stop 101) was surveyed on the per-axis model without effects; on held-out
seed 18 (friction asymmetry α = 0.24 on the env's default model) its fastest setting steps
backwards, and every controller ran away (412.9 µm for closed_loop). The same survey on the
env's default model with the catalogue's friction asymmetry |α| <= 0.3
(``controllers/data/blind_asymmetry.csv``, the default since stop 101: ``python
experiments/blind_settings.py --fidelity translation --asymmetry 0.3 --drawn 16
--ramp-ratios 0.6,0.9 --out controllers/data/blind_asymmetry.csv``) keeps only 2–3 V of
the planner's waveform, and 2–4.5 V at 2 kHz with the ramp ratio a = 0.6.

This runs the map controllers, fuzzy (blind, the set's fastest setting) and the shipped
agents (PPO and SAC through their shield, ``ppo_residual`` through its fuzzy base) with
each blind set side by side on the benchmark's held-out and calibrated sets, every task
(the tasks that start inside the detector do not use the blind set), and prints per
controller and set the mean success, the episodes passed and the largest run-away [µm],
then the episodes whose success differs.

    python experiments/blind_tradeoff.py [--workers 2] [--plant-sets held_out,calibrated]

About 15 minutes on this 2-core machine (14 min 33 s at stop 100).
"""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable
from pathlib import Path

from agents import pretrained
from agents.controller import AgentController
from controllers import registry
from controllers.base import Controller
from controllers.benchmark import run_benchmark
from controllers.blind import ASYMMETRY_PATH, BLIND_PATH, BlindSettings
from controllers.closed_loop import ClosedLoopStepController
from controllers.feedforward import FeedForwardController
from controllers.fuzzy import FuzzyStepController
from controllers.metrics import RUNAWAY_LIMIT

SUFFIX = "_asymmetry"


def _variants() -> dict[str, Callable[..., Controller]]:
    """name → (ctx, blind_settings) → controller: the map controllers and fuzzy take the
    blind set themselves, the shipped agents through their shield, ``ppo_residual`` through
    its fuzzy base (which has its own monitor and no shield over it)."""
    out: dict[str, Callable[..., Controller]] = {
        "closed_loop": lambda ctx, bs: ClosedLoopStepController(ctx, blind_settings=bs),
        "feedforward": lambda ctx, bs: FeedForwardController(ctx, blind_settings=bs),
        "fuzzy": lambda ctx, bs: FuzzyStepController(ctx, blind_settings=bs),
    }
    runs = pretrained()
    for algo in ("ppo", "sac", "ppo_residual"):
        if algo in runs:
            out[algo] = functools.partial(_agent, run=runs[algo], name=algo)
    return out


def _agent(ctx, bs, *, run, name):
    return AgentController(ctx, run, name, blind_settings=bs)


def _factory(make: Callable[..., Controller], path: str):
    def build(ctx):
        return make(ctx, BlindSettings.load(path))

    return build


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plant-sets", default="held_out,calibrated")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    if args.workers < 1:
        print(f"error: --workers={args.workers!r}: must be >= 1", file=sys.stderr)
        return 2
    variants = _variants()
    names = []
    for name, make in variants.items():
        for suffix, path in (("", str(BLIND_PATH)), (SUFFIX, str(ASYMMETRY_PATH))):
            registry.register(name + suffix, _factory(make, path),
                              f"{name} stepping blind with {Path(path).name}",
                              overwrite=True)  # fmt: skip
            names.append(name + suffix)
    try:
        result = run_benchmark(names, plant_sets=args.plant_sets.split(","),
                               backend="processes", workers=args.workers)  # fmt: skip
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    df = result.to_pandas()
    print(f"blind set: {BLIND_PATH.name} (the first) vs {ASYMMETRY_PATH.name} (suffix "
          f"{SUFFIX}); run-away limit {RUNAWAY_LIMIT * 1e6:g} µm")  # fmt: skip
    print("controller              | plant set  | mean success | passed  | largest run-away")
    for (ctl, pset), g in df.groupby(["controller", "plant_set"], sort=False):
        print(f"{ctl:23s} | {pset:10s} | {g.success.mean():12.3f} | "
              f"{int(g.success.sum()):3d}/{len(g):3d} | {g.runaway_um.max():8.1f} µm")  # fmt: skip
    print("episodes whose success differs (first → asymmetry-robust):")
    key = ["plant_set", "task", "seed"]
    for name in variants:
        a = df[df.controller == name].set_index(key).success
        b = df[df.controller == name + SUFFIX].set_index(key).success
        for k in a.index[a != b.loc[a.index]]:
            print(f"  {name:12s} {' '.join(map(str, k))}: {a[k]:.0f} → {b[k]:.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
