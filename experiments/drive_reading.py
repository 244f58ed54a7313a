"""How the calibrator reads each trace's drive (issue 31, stop 71): a fingerprint per file,
to compare two commits' readings.

For every trace: the recording (breakpoints or sampled), the number of jumps read, the
number of segments and a digest of the model's drive (the reading's times, levels and
jumps, rounded to 1 ps and 1 nV) and of the segments' conditions. Run it at two commits
and compare the outputs: a file whose line differs is read differently, and every other
file's calibration input is unchanged. ``--segments`` prints each file's non-hold
segments (start, end [s], condition, periods, ramp ratio read) as well, and ``--floors``
each file's noise floor [nm] as the fit reads it (stop 89: the floor of a quantised
detector changed, and the three plants' 48 traces print theirs as before). Since stop 91
the model's drive is the fit's (``TraceData.breakpoints``: the reading with its resolved
flybacks' corners, ``segments.flyback_corners``).

    python experiments/drive_reading.py [--segments] [--floors] [TRACE.csv ...]

Default traces: every CSV of the three independent plants' trace sets
(experiments/results/independent_traces, second_plant_traces and third_plant_traces,
written by the traces scripts). Stop 71's sawtooth rule (``segments.SAWTOOTH_RATIO``)
changed the lines of the second plant's ``axis_A_10kHz.csv`` and the third plant's
``clean_axis_A_10kHz.csv`` alone; stop 72's description of bursts whose jumps mark only
some of their flybacks changed the latter's line alone (its segments, not its drive), and
its reading of flybacks the samples resolve (``segments.RESOLVED_SAMPLES``: linear, not a
staircase of jumps) the third plant's 13 lines alone. Stop 91's landing of a sampled
sawtooth's flybacks (``segments.landing_phase``) changed the lines of the third plant's 13
traces, the second plant's ``sampled.csv`` and the first plant's ``sampled_12bit.csv``, as
stop 89's run-on had.
"""

from __future__ import annotations

import argparse
import hashlib
import sys

import numpy as np

from turntable_env.calibration.segments import DriveReading, Segment, read_drive, segment_trace
from turntable_env.calibration.trace_fit import trace_data
from turntable_env.testing.trace_sets import load_traces


def fingerprint(
    reading: DriveReading,
    segments: list[Segment],
    drive: tuple[np.ndarray, np.ndarray] | None = None,
) -> str:
    """A 12-hex-digit digest of the model's drive (``drive``, the fit's breakpoints;
    default the reading's own: times to 1 ps, levels to 1 nV), the reading's jumps and the
    segments' conditions and periods."""
    drive = (reading.time, reading.level) if drive is None else drive
    h = hashlib.sha1()
    h.update(np.round(drive[0], 12).tobytes())
    h.update(np.round(drive[1], 9).tobytes())
    h.update(np.round(reading.jumps, 12).tobytes())
    h.update(repr([(s.condition, s.periods) for s in segments]).encode())
    return h.hexdigest()[:12]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="drive_reading", description=__doc__.splitlines()[0])
    ap.add_argument("--segments", action="store_true", help="print each file's segments")
    ap.add_argument("--floors", action="store_true",
                    help="print each file's noise floor [nm] and its source (as the fit reads it)")
    ap.add_argument("traces", nargs="*", help="trace CSVs (default: the three plants' sets)")
    args = ap.parse_args(argv)
    try:
        traces = load_traces(args.traces)
    except ValueError as exc:
        print(f"drive_reading: {exc}", file=sys.stderr)
        return 2
    for path, m in traces:
        reading = read_drive(m.time, m.drives[m.axis], m.meta)
        segs = segment_trace(reading, float(m.time[-1]))
        name = f"{path.parent.name}/{path.name}"
        td = trace_data(m)
        print(f"{name:48s} {reading.recording:11s} jumps {reading.jumps.size:4d} "
              f"segments {len(segs):3d} {fingerprint(reading, segs, td.breakpoints)}")  # fmt: skip
        if args.floors:
            print(f"    noise floor {td.floor:.6g} nm ({td.floor_source})")
        if args.segments:
            for s in segs:
                if s.kind != "hold":
                    print(f"    {s.start:8.4f} {s.end:8.4f}  {s.condition}  x{s.periods}  "
                          f"a {s.ramp_ratio:.3f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
