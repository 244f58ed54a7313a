"""Regenerate the shipped step-size map, ``controllers/data/step_map.csv``.

Sweeps the simulator through the environment's task (real parameters, 10 ms interval,
noise off): axes A, B, C × ±1…10 V in 0.5 V steps × 100/200/500/1000/2000 Hz ×
a = 0.6/0.9/0.95/0.99 × k = 0/1 (a = 0.6 for the blind set's
fastest settings, :mod:`controllers.blind`), six intervals each. Prints the row count, the wall time
and a few rows of the nominal family (axis B, a = 0.9, k = 1).

    python experiments/build_step_map.py [--out PATH]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from controllers.step_map import DEFAULT_PATH, sweep_step_map


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=str(DEFAULT_PATH))
    args = ap.parse_args()
    t0 = time.perf_counter()
    m = sweep_step_map(progress=True)
    wall = time.perf_counter() - t0
    path = m.save(args.out)
    print(f"{len(m)} rows written to {path} in {wall:.1f} s")
    print("axis B, a = 0.9, k = 1, forward: steady step per period [µrad]")
    for f in (100.0, 1000.0, 2000.0):
        rows = m.family("B", f, 0.9, 1.0, 1)
        cells = ", ".join(
            f"{m.amplitude[i]:g} V: {m.step[i] * 1e6:.1f}" for i in rows if m.amplitude[i] % 2 == 0
        )
        print(f"  {f:6.0f} Hz  {cells}")
    print(f"largest steady step: {np.max(np.abs(m.step)) * 1e6:.1f} µrad per period")


if __name__ == "__main__":
    main()
