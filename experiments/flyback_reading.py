"""How the per-axis model steps under a sampled flyback's readings (issue 31, stop 72).

A function generator's sawtooth (linear ramp over a/f, linear flyback over (1 − a)/f, three
periods between two holds) is sampled at a DAQ rate and run through the calibration's base
plant (``real``, per-axis) four ways: the generator's own drive at 1 MS/s, the drive as the
calibrator reads the samples (:func:`~turntable_env.calibration.segments.read_drive`), the
samples linear between them, and a staircase: each of the flyback's samples a jump at
mid-interval, the level held on either side (the reading before stop 72, wherever those
changes were each six times the ramp's). Prints the net rotation of each [µrad] and the
jumps the reading finds.

    python experiments/flyback_reading.py [--rates 10000,25000]

A flyback of two sample intervals or more steps the model under the staircase where the
generator's, slower than the tubes' period, hardly does; read linear it steps as generated
(``segments.RESOLVED_SAMPLES``). Shorter flybacks stay jumps: there neither reading is the
generator's.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from turntable_env.calibration.segments import read_drive
from turntable_env.calibration.trace import simulate_trace
from turntable_env.plant import Plant

# (frequency [Hz], ramp ratio a, amplitude [V]): the third independent plant's settings
CASES = [
    (50.0, 0.99, 6.0),
    (50.0, 0.99, 3.0),
    (100.0, 0.99, 4.5),
    (200.0, 0.97, 3.0),
    (500.0, 0.75, 2.0),
    (2000.0, 0.98, 3.0),
]
PERIODS = 3
HOLD = 0.0201234  # s before and after: the generator's clock at a phase of the DAQ's
GENERATOR_RATE = 1e6  # Hz


def sawtooth(t: np.ndarray, f: float, a: float, amp: float) -> np.ndarray:
    """The generator's output [V] at times t [s]: PERIODS periods after HOLD."""
    ph = (t - HOLD) * f
    x = ph % 1.0
    u = np.where(x < a, x / a, (1.0 - x) / (1.0 - a)) * amp
    return np.where((ph >= 0) & (ph < PERIODS), u, 0.0)


def staircase(t: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints of the samples with every change against the ramp's sense larger than
    a fifth of the largest such change made a jump at mid-interval."""
    du = np.diff(u)
    fly = du < -0.2 * float(np.max(-du)) if np.any(du < 0) else np.zeros(du.size, bool)
    bt, bu = [t[0]], [u[0]]
    for i in range(du.size):
        if fly[i]:
            mid = 0.5 * (t[i] + t[i + 1])
            bt += [mid, mid + 1e-9]
            bu += [u[i], u[i + 1]]
        bt.append(t[i + 1])
        bu.append(u[i + 1])
    return np.array(bt), np.array(bu)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="flyback_reading", description=__doc__.splitlines()[0])
    ap.add_argument("--rates", default="10000,25000", help="DAQ rates [Hz], comma-separated")
    args = ap.parse_args(argv)
    try:
        rates = [float(v) for v in args.rates.split(",")]
    except ValueError:
        print(f"flyback_reading: --rates {args.rates!r}: not comma-separated numbers",
              file=sys.stderr)  # fmt: skip
        return 2
    if not rates or any(not 1e3 <= r <= 1e6 for r in rates):
        print(f"flyback_reading: --rates {args.rates!r}: each in 1e3..1e6 Hz", file=sys.stderr)
        return 2
    plant = Plant("real", fidelity="reduced")
    print("case                      rate     jumps  generator     read   linear  staircase")
    for f, a, amp in CASES:
        t_end = 2 * HOLD + PERIODS / f
        tg = np.arange(0.0, t_end, 1.0 / GENERATOR_RATE)
        gen = simulate_trace(plant, "B", tg, sawtooth(tg, f, a, amp)).theta[-1]
        for fs in rates:
            t = np.arange(0.0, t_end, 1.0 / fs)
            u = sawtooth(t, f, a, amp)
            r = read_drive(t, u)
            read = simulate_trace(plant, "B", t, u, breakpoints=(r.time, r.level)).theta[-1]
            lin = simulate_trace(plant, "B", t, u).theta[-1]
            stair = simulate_trace(plant, "B", t, u, breakpoints=staircase(t, u)).theta[-1]
            print(f"{amp:3.1f} V {f:6.0f} Hz a {a:4.2f}  {fs / 1e3:5.0f} kHz {r.jumps.size:5d}"
                  f"  {gen * 1e6:9.3f} {read * 1e6:8.3f} {lin * 1e6:8.3f} {stair * 1e6:10.3f}",
                  flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
