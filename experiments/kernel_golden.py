"""Fingerprints of the compiled kernels on short standard runs, for the bit-identity check
of a kernel refactor (issue 33): the 3-D model (fixed and adaptive step), the reduced
model (ladder and analytic all-stick step, a batch of two), and the env on both
fidelities under fixed actions.

    python experiments/kernel_golden.py > tests/data/kernel_golden.json   # record
    python experiments/kernel_golden.py --compare    # bit for bit against the file
    python experiments/kernel_golden.py --add        # add the runs the file lacks, keep the rest
    python -m pytest tests/test_kernel_golden.py     # within 1e-9 of each run's scale

The committed file was recorded with the kernels before their split into named phases
(commit e52b118), the resumed rung's two runs at stop 84 (``--add``);
tests/test_kernel_golden.py checks today's kernels against it.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import turntable_env  # noqa: F401  (registers the envs)
from turntable_env.params import real_parameters
from turntable_env.reduced import ReducedModel, simulate_batch
from turntable_env.simulation import simulate, stepping_drive

ACTIONS = (  # normalised env actions: amplitude, frequency, a, slew adaptation, scan offset
    np.array([0.6, 0.2, 0.9, 0.5, 0.0]),
    np.array([-0.4, -0.3, 0.7, 0.0, 0.1]),
    np.array([0.9, 0.8, 0.95, 1.0, -0.2]),
)


# the reduced model's runs: (name, analytic all-stick step, resume_rung). The first two pin
# the restart rule they were recorded with (commit e52b118); the resumed rung, the default
# since stop 84, was recorded at that stop
RUNS = (
    ("reduced_ladder", False, False),
    ("reduced_analytic", True, False),
    ("reduced_ladder_resume", False, True),
    ("reduced_analytic_resume", True, True),
)


def _floats(x: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(x, dtype=float).ravel()]


def record() -> dict[str, list[float]]:
    """Run name → the numbers it produced (every sample of a short run)."""
    out: dict[str, list[float]] = {}
    drive, ps = stepping_drive("real", amplitude=2.0, frequency=1000.0, periods=3)
    for name, coarse in (("full_fixed", None), ("full_adaptive", 0.5)):
        r = simulate(ps, drive, axis="B", output_dt=2e-5, coarse_factor=coarse)
        out[name] = _floats(r.angle()) + _floats(r.normal_force[-1]) + [r.step_size]
    real = real_parameters()
    back, _ = stepping_drive("real", amplitude=-3.0, frequency=500.0, periods=2)
    for name, analytic, resume in RUNS:
        models = [ReducedModel(real, "B", analytic=analytic, resume_rung=resume)] * 2
        runs = simulate_batch(models, [drive, back], 5e-3, output_dt=2e-5)
        out[name] = [v for r in runs for v in _floats(r.angle()) + _floats(r.friction[-1])]
    for fidelity in ("reduced", "full"):
        env = gym.make("PiezoTurntable-v0", fidelity=fidelity)
        obs, info = env.reset(seed=3, options={"start_angle": 0.0, "target_angle": 1e-4})
        seq = _floats(obs)
        for act in ACTIONS:
            obs, reward, *_rest, info = env.step(act.astype(np.float32))
            seq += [*_floats(obs), float(reward)]
            seq += [float(v) for k, v in sorted(info.items()) if isinstance(v, float)]
        env.close()
        out[f"env_{fidelity}"] = seq
    return out


GOLDEN = Path(__file__).resolve().parents[1] / "tests" / "data" / "kernel_golden.json"


def compare(now: dict[str, list[float]]) -> dict[str, float]:
    """Run name → the largest difference from the recorded numbers, relative to the run's
    largest magnitude (0.0: bit for bit)."""
    golden = json.loads(GOLDEN.read_text(encoding="utf-8"))
    if set(golden) != set(now):
        raise ValueError(f"{GOLDEN}: runs {sorted(golden)}, now {sorted(now)}")
    out = {}
    for name, ref in golden.items():
        a, b = np.asarray(now[name]), np.asarray(ref)
        if a.shape != b.shape:
            out[name] = math.inf
            continue
        out[name] = float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))
    return out


if __name__ == "__main__":
    if sys.argv[1:] == ["--add"]:
        kept = json.loads(GOLDEN.read_text(encoding="utf-8"))
        new = {k: v for k, v in record().items() if k not in kept}
        GOLDEN.write_text(json.dumps({**kept, **new}, indent=0) + "\n", encoding="utf-8")
        print(f"{GOLDEN}: added {sorted(new) or 'nothing'}")
    elif sys.argv[1:] == ["--compare"]:
        for name, rel in compare(record()).items():
            print(f"{name:24s} {'bit for bit' if rel == 0.0 else f'relative difference {rel:.3g}'}")
    else:
        json.dump(record(), sys.stdout, indent=0)
        sys.stdout.write("\n")
