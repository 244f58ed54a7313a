"""How far a benchmark plant steps against the nominal step map (issue 32).

For every setting of the map's planner family (a = 0.9, k = 1; amplitudes 1–10 V,
frequencies 100 Hz–2 kHz, both directions), the plant's steady step per period over the
nominal plant's, from rest with the detector noise off: the gains a controller built on
the nominal map has to learn. Prints the table (rows: amplitude, columns: frequency) for
the ``calibrated`` plant set by default, and the spread per amplitude.

    python experiments/step_gain_survey.py [--plant-set calibrated] [--axis B]
"""

from __future__ import annotations

import argparse

import numpy as np

from controllers.plant_sets import PLANT_SETS
from turntable_env.envs.config import EnvConfig
from turntable_env.envs.core import TurntableTask

AMPLITUDES = (1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0)  # V
FREQUENCIES = (100.0, 500.0, 2000.0)  # Hz
INTERVALS = 4


def steady_steps(plant_set: str, axis: str) -> np.ndarray:
    """(amplitudes, frequencies, 2 directions) steady step per period [rad]."""
    base = PLANT_SETS[plant_set]().base
    cfg = EnvConfig(plant=base, axis=axis, noise=False)
    cases = [(d * a, f) for a in AMPLITUDES for f in FREQUENCIES for d in (1.0, -1.0)]
    task = TurntableTask(cfg, len(cases))
    rng = np.random.default_rng(0)
    for b in range(len(cases)):
        task.reset_row(b, rng, {"start_angle": 0.0, "target_angle": 0.0})
    acts = np.array([cfg.scaling.encode(a, f, 0.9, 1.0) for a, f in cases])
    angles = [task.angle.copy()]
    for _ in range(INTERVALS):
        task.step(acts, rng)
        angles.append(task.angle.copy())
    disp = np.diff(np.array(angles), axis=0)  # (intervals, cases)
    per = np.array([f * cfg.control_interval for _a, f in cases])
    steady = disp[1:].mean(axis=0) / per
    return steady.reshape(len(AMPLITUDES), len(FREQUENCIES), 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--plant-set", default="calibrated", choices=sorted(PLANT_SETS))
    ap.add_argument("--axis", default="B", choices=("A", "B", "C"))
    args = ap.parse_args()
    nominal = steady_steps("nominal", args.axis)
    plant = steady_steps(args.plant_set, args.axis)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = plant / nominal
    print(f"{args.plant_set} over nominal, steady step per period, axis {args.axis} "
          "(forward / backward; n/a: the nominal plant steps < 1 nm per period there)")  # fmt: skip
    print("amplitude [V] | " + " | ".join(f"{f:.0f} Hz" for f in FREQUENCIES))
    tiny = np.abs(nominal) * 0.01 < 1e-9  # < 1 nm per period at R = 10 mm
    for i, a in enumerate(AMPLITUDES):
        cells = [
            "n/a" if tiny[i, j].any() else f"{ratio[i, j, 0]:.2f} / {ratio[i, j, 1]:.2f}"
            for j in range(len(FREQUENCIES))
        ]
        print(f"{a:4.1f} | " + " | ".join(cells))
    ok = ~tiny & (np.array(AMPLITUDES)[:, None, None] >= 2.0)
    r = ratio[ok]
    print(f"from 2 V up: ratio {r.min():.2f}–{r.max():.2f}, median {np.median(r):.2f}")


if __name__ == "__main__":
    main()
