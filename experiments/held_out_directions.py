"""Which way a benchmark plant steps, on each model (issue 32, stop 95).

For one seed of a plant set (default: held_out seed 18, friction asymmetry α = 0.24 on
low friction and preload and a fast amplifier, where every controller ran away once the
set ran the translation form), the steady step per period of the map planner's family
(a = 0.9, slew adapted) in both directions, noise off, from rest: the mean over control
intervals 2–3, in µm at R_table. The same plant on the per-axis model (``reduced``), the
env's default (``translation``) and the 3-D model (``full``), so a sign that one model
gives and another does not shows.

    python experiments/held_out_directions.py [--set held_out] [--seed 18] \
        [--settings 4@1000,6@1000,9.5@2000]
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym

import turntable_env  # noqa: F401  (registers the env)
from controllers.benchmark import SUITE_SEED
from controllers.plant_sets import PLANT_SETS
from turntable_env.envs import ActionScaling

FIDELITIES = ("reduced", "translation", "full")
INTERVALS = 3  # control intervals of 10 ms; the first (from rest) is not counted


def _settings(text: str) -> list[tuple[float, float]]:
    out = []
    for item in text.split(","):
        try:
            amp, freq = (float(x) for x in item.split("@"))
        except ValueError:
            raise ValueError(f"--settings: {item!r} is not AMPLITUDE_V@FREQUENCY_HZ") from None
        if not (0.0 < amp <= 10.0 and 0.0 < freq <= 2000.0):
            raise ValueError(f"--settings: {item!r} outside 0–10 V, 0–2000 Hz")
        out.append((amp, freq))
    return out


def steady_step_um(plant, amplitude: float, frequency: float) -> float:
    """Steady step per period [µm at R_table] of ``plant`` under the signed setting."""
    scaling = ActionScaling()
    env = gym.make("PiezoTurntable-v0", plant=plant, noise=False,
                   terminate_on_success=False).unwrapped  # fmt: skip
    env.reset(seed=0, options={"start_angle": 0.0, "target_angle": 0.0})
    act = scaling.encode(amplitude, frequency, 0.9, 1.0)
    angles = [env.step(act)[-1]["angle_rad"] for _ in range(INTERVALS)]
    periods = frequency * env.config.control_interval
    radius = plant.params.table.radius
    return 1e6 * radius * (angles[-1] - angles[0]) / ((INTERVALS - 1) * periods)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", default="held_out", choices=sorted(PLANT_SETS))
    ap.add_argument("--seed", type=int, default=18)
    ap.add_argument("--settings", default="4@1000,6@1000,9.5@2000")
    args = ap.parse_args()
    try:
        settings = _settings(args.settings)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    plant, draw = PLANT_SETS[args.set]().plant(args.seed, SUITE_SEED)
    print(f"{args.set} seed {args.seed}: " + ", ".join(
        f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in draw.items()))
    print("steady step per period [µm at R_table], forward / backward command")
    print("setting     | " + " | ".join(f"{f:>19}" for f in FIDELITIES))
    for amp, freq in settings:
        cells = []
        for fid in FIDELITIES:
            p = plant.replace(fidelity=fid)
            cells.append(f"{steady_step_um(p, amp, freq):+8.4f} / "
                         f"{steady_step_um(p, -amp, freq):+8.4f}")  # fmt: skip
        print(f"{amp:4g} V {freq:4.0f} Hz | " + " | ".join(cells))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
