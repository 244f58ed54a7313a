"""How the per-axis model steps under a sampled flyback's readings (issue 31, stop 72).

A function generator's sawtooth (linear ramp over a/f, linear flyback over (1 − a)/f, three
periods between two holds) is sampled at a DAQ rate and run through the calibration's base
plant (``real``, per-axis) four ways: the generator's own drive at 1 MS/s, the drive as the
calibrator reads the samples (:func:`~turntable_env.calibration.segments.read_drive`; with
``--corners`` through the resolved flybacks' corners, stop 91), the samples linear between
them, and a staircase: each of the flyback's samples a jump at
mid-interval, the level held on either side (the reading before stop 72, wherever those
changes were each six times the ramp's). Prints the net rotation of each [µrad] and the
jumps the reading finds.

    python experiments/flyback_reading.py [--rates 10000,25000] [--corners]
    python experiments/flyback_reading.py --phases 8 [--rates 10000,20000,25000] [--aligned]
        [--corners]

``--phases N`` (stop 89) draws N phases of the generator's clock against the DAQ's (a
seeded draw) for each of :data:`PHASE_CASES` and prints, per case and rate, the
generator's mean net rotation and each reading's error against it, mean and RMS over the
phases [µrad]: the reading (since stop 91 each flyback where its burst's landing level
places it, :func:`~turntable_env.calibration.segments.landing_phase`; with ``--corners``
the model's drive through each resolved flyback's corners, :func:`model_drive`), ``mid`` (stop
89's: the ramp run on to each flyback at its interval's middle, ``read_drive(...,
landing=False)``) and ``held`` (before stop 89: each level held flat to the middle,
:func:`held`). A single phase, as the table above draws, is one draw of where the
flyback falls between two samples; ``--aligned`` takes the one phase at which every
flyback ends on a DAQ sample, as the third independent plant's generator and DAQ do.

A flyback of two sample intervals or more steps the model under the staircase where the
generator's, slower than the tubes' period, hardly does; read linear it steps as generated
(``segments.RESOLVED_SAMPLES``). Shorter flybacks stay jumps: there neither reading is the
generator's.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from turntable_env.calibration.segments import flyback_corners, read_drive, segment_trace
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
# (frequency [Hz], ramp ratio a, amplitude [V]) with flybacks within one sample (--phases)
PHASE_CASES = [
    (2000.0, 0.98, 3.0),
    (2000.0, 0.98, 6.0),  # the third plant's 10 kHz trace's burst
    (1000.0, 0.99, 4.0),
    (200.0, 0.97, 3.0),
    (100.0, 0.99, 4.5),
]
HOLD = 0.0201234  # s before and after: the generator's clock at a phase of the DAQ's
GENERATOR_RATE = 1e6  # Hz


def sawtooth(t: np.ndarray, f: float, a: float, amp: float, hold: float = HOLD) -> np.ndarray:
    """The generator's output [V] at times t [s]: PERIODS periods after ``hold`` [s]."""
    ph = (t - hold) * f
    x = ph % 1.0
    u = np.where(x < a, x / a, (1.0 - x) / (1.0 - a)) * amp
    return np.where((ph >= 0) & (ph < PERIODS), u, 0.0)


def staircase(t: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints of the samples with every change against the ramp's sense larger than
    a fifth of the largest such change made a jump at mid-interval."""
    du = np.diff(u)
    fly = du < -0.2 * float(np.max(-du)) if np.any(du < 0) else np.zeros(du.size, bool)
    return _jumps_held(t, u, fly)


def held(t: np.ndarray, u: np.ndarray, jumps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints of the samples with a jump at the middle of each interval that holds
    one of ``jumps`` [s], the levels held flat on either side (the reading before stop 89)."""
    at = np.zeros(t.size - 1, bool)
    at[np.searchsorted(t, jumps) - 1] = True
    return _jumps_held(t, u, at)


def _jumps_held(t: np.ndarray, u: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints of the samples with a jump at the middle of each interval ``at`` marks,
    each sample's level held flat to it."""
    bt, bu = [t[0]], [u[0]]
    for i in range(t.size - 1):
        if at[i]:
            mid = 0.5 * (t[i] + t[i + 1])
            bt += [mid, mid + 1e-9]
            bu += [u[i], u[i + 1]]
        bt.append(t[i + 1])
        bu.append(u[i + 1])
    return np.array(bt), np.array(bu)


def model_drive(r, t: np.ndarray, corners: bool) -> tuple[np.ndarray, np.ndarray]:
    """The calibration's model drive from a reading: its breakpoints, with the resolved
    flybacks' corners where ``corners`` (as for a file that declares ``drive_flybacks:
    linear``, :func:`~turntable_env.calibration.segments.flyback_corners`)."""
    if not corners:
        return r.time, r.level
    return flyback_corners(r, segment_trace(r, float(t[-1])))


def phase_errors(plant: Plant, f: float, a: float, amp: float, fs: float, phases: np.ndarray,
                 corners: bool = False) -> tuple[float, np.ndarray, np.ndarray]:  # fmt: skip
    """The generator's mean net rotation [rad] over the phases (each a fraction of the
    DAQ's interval by which the burst starts later), and each reading's error against the
    generator's at each phase [rad]: rows (read, held)."""
    gens, errs = [], []
    for ph in phases:
        hold = 0.02 + float(ph) / fs
        t_end = 2 * hold + PERIODS / f
        tg = np.arange(0.0, t_end, 1.0 / GENERATOR_RATE)
        gen = simulate_trace(plant, "B", tg, sawtooth(tg, f, a, amp, hold)).theta[-1]
        t = np.arange(0.0, t_end, 1.0 / fs)
        u = sawtooth(t, f, a, amp, hold)
        r = read_drive(t, u)
        drive = model_drive(r, t, corners)
        read = simulate_trace(plant, "B", t, u, breakpoints=drive).theta[-1]
        m = read_drive(t, u, landing=False)
        mid = simulate_trace(plant, "B", t, u, breakpoints=(m.time, m.level)).theta[-1]
        old = simulate_trace(plant, "B", t, u, breakpoints=held(t, u, r.jumps)).theta[-1]
        gens.append(gen)
        errs.append((read - gen, mid - gen, old - gen))
    return float(np.mean(gens)), np.array(errs).T, np.array(gens)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="flyback_reading", description=__doc__.splitlines()[0])
    ap.add_argument("--rates", default="10000,25000", help="DAQ rates [Hz], comma-separated")
    ap.add_argument("--phases", type=int, default=0,
                    help="draw this many clock phases per case (0: the table of one phase)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the phases' draw")
    ap.add_argument("--corners", action="store_true",
                    help="the reading's drive through each resolved flyback's corners (a file "
                         "declaring drive_flybacks: linear)")
    ap.add_argument("--aligned", action="store_true",
                    help="with --phases: the one phase at which each flyback ends on a DAQ "
                         "sample (the third independent plant's clocks) instead of the draw")
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
    if not 0 <= args.phases <= 1000:
        print(f"flyback_reading: --phases {args.phases}: must be in 0..1000", file=sys.stderr)
        return 2
    plant = Plant("real", fidelity="reduced")
    if args.phases:
        phases = np.random.default_rng(args.seed).uniform(0.0, 1.0, args.phases)
        if args.aligned:
            phases = np.zeros(1)
        print(f"net rotation over {phases.size} clock phases [µrad]: the generator's mean, "
              "each reading's error against it (mean, RMS)")  # fmt: skip
        print("case                      rate   generator   read: mean    rms"
              "    mid: mean    rms   held: mean    rms")  # fmt: skip
        for f, a, amp in PHASE_CASES:
            for fs in rates:
                gen, errs, _ = phase_errors(plant, f, a, amp, fs, phases, args.corners)
                cols = "".join(f"  {np.mean(e) * 1e6:10.3f} {np.sqrt(np.mean(e**2)) * 1e6:7.3f}"
                               for e in errs)  # fmt: skip
                print(f"{amp:3.1f} V {f:6.0f} Hz a {a:4.2f}  {fs / 1e3:5.0f} kHz {gen * 1e6:10.3f}"
                      f"{cols}", flush=True)  # fmt: skip
        return 0
    print("case                      rate     jumps  generator     read   linear  staircase")
    for f, a, amp in CASES:
        t_end = 2 * HOLD + PERIODS / f
        tg = np.arange(0.0, t_end, 1.0 / GENERATOR_RATE)
        gen = simulate_trace(plant, "B", tg, sawtooth(tg, f, a, amp)).theta[-1]
        for fs in rates:
            t = np.arange(0.0, t_end, 1.0 / fs)
            u = sawtooth(t, f, a, amp)
            r = read_drive(t, u)
            drive = model_drive(r, t, args.corners)
            read = simulate_trace(plant, "B", t, u, breakpoints=drive).theta[-1]
            lin = simulate_trace(plant, "B", t, u).theta[-1]
            stair = simulate_trace(plant, "B", t, u, breakpoints=staircase(t, u)).theta[-1]
            print(f"{amp:3.1f} V {f:6.0f} Hz a {a:4.2f}  {fs / 1e3:5.0f} kHz {r.jumps.size:5d}"
                  f"  {gen * 1e6:9.3f} {read * 1e6:8.3f} {lin * 1e6:8.3f} {stair * 1e6:10.3f}",
                  flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
