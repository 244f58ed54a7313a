"""Net against steady steps by direction (issue 31, stop 61): why the direction feature
reads the steady steps.

For each trace, every pair of opposite bursts of one setting: the asymmetry
(|s₊| − |s₋|)/(|s₊| + |s₋|) of the net steps per period (level after the burst − level
before, the steps group) and of the steady steps (the direction feature: two blocks of
whole periods after the first), read by the calibrator's own
:class:`~turntable_env.calibration.signatures.SignatureLayout`. Then the second
independent plant's own steady step per period both ways (its ``step_per_period``,
periods 3–6, no effect) on axes A, B and C.

    python experiments/direction_steps.py [TRACE.csv ...]

Default traces: the second plant's clean, axis-C, asymmetry and contact-wear traces and
the first plant's asymmetry trace (experiments/results/*_traces, written by the traces
scripts).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.segments import read_drive, segment_trace, split_portions
from turntable_env.calibration.signatures import SignatureLayout
from turntable_env.testing.second_plant import FLYBACK_S, PlantParams, step_per_period

RESULTS = Path("experiments/results")
DEFAULT = [RESULTS / "second_plant_traces" / f"{n}.csv"
           for n in ("clean", "axis_C_20kHz", "friction_asymmetry", "contact_wear")] + [
    RESULTS / "independent_traces" / "friction_asymmetry.csv"]  # fmt: skip


def pairs(path: Path) -> list[tuple[str, float, float]]:
    """(setting, net asymmetry, steady asymmetry) of each opposite pair of ``path``."""
    m = load_measurement(path)
    u = m.drives[m.axis]
    segs = split_portions(segment_trace(read_drive(m.time, u, m.meta), float(m.time[-1])))
    lay = SignatureLayout(m.time - m.time[0], u, segs, 1.0)
    f = lay.measure(m.detector_v * m.detector.sensitivity * 1e9)
    steps = f.value[f.group("steps")]
    steady = f.value[f.group("direction")]
    out = []
    for (i, j), ratio in zip(lay.pairs, steady, strict=True):
        sp, sm = steps[i], steps[j]
        amp, freq, _fly = lay.bursts[i].setting
        out.append((f"{amp:g} V {freq:g} Hz", (sp + sm) / (sp - sm), float(ratio)))
    return out


def main(argv: list[str]) -> int:
    paths = [Path(a) for a in argv] or DEFAULT
    for p in paths:
        if not p.exists():
            print(f"{p}: no such trace (write it with experiments/*_traces.py)", file=sys.stderr)
            return 2
    for p in paths:
        print(f"{p}:")
        for setting, net, steady in pairs(p):
            print(f"  {setting:>14}: net {100 * net:+6.2f} %, steady {100 * steady:+6.2f} %")
    params = PlantParams()
    print("second plant's own steady step per period [nm], 2 V, 300 Hz, forward / backward:")
    for axis in "ABC":
        a = 1.0 - FLYBACK_S * 300.0
        s = [1e9 * step_per_period(params, 2.0, 300.0, direction=d, axis=axis, ramp_fraction=a)
             for d in (1, -1)]  # fmt: skip
        asym = 100 * np.sum(s) / (s[0] - s[1])
        print(f"  axis {axis}: {s[0]:.2f} / {s[1]:.2f}  ({asym:+.3f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
