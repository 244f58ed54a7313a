"""Which holds each portion gets (issue 31, stop 63): the fit and held-out portions of a
trace, and the direction of the motion before each of their holds.

The calibration interleaves its fit and held-out portions by drive condition
(:func:`~turntable_env.calibration.segments.split_portions`), and every hold is one
condition, "hold", whose occurrences alternate between the portions. On a protocol of
forward burst, hold, reverse burst, hold, … that puts every hold after a forward burst
into one portion and every hold after a reverse burst into the other, and the held-out
error then judges the model on a kind of hold the fit never saw. Since stop 87 the split
gives such holds conditions by the direction before them. This prints, for each trace,
the holds of each portion by the direction of the motion before them (+, −, or none: the
first hold), and says where a portion holds one direction only; and the scans of each
portion by their sense (every scan is one condition, "scan"), and says where a portion
holds one sense only.

    python experiments/portion_split.py [TRACE.csv ...]

Default traces: every CSV of the three independent plants' trace sets
(experiments/results/independent_traces, second_plant_traces and third_plant_traces,
written by the traces scripts).
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.segments import (
    Segment,
    holds_by_motion,
    one_sided,
    read_drive,
    segment_trace,
    split_portions,
)

RESULTS = Path("experiments/results")
TRACE_SETS = ("independent_traces", "second_plant_traces", "third_plant_traces")


def scan_counts(segments: list[Segment]) -> dict[str, Counter]:
    """portion → Counter of its scans' senses (+1, −1); a scan cut in two counts in each
    portion it reaches."""
    out: dict[str, Counter] = {"fit": Counter(), "heldout": Counter()}
    for s in segments:
        if s.kind == "scan":
            out[s.portion][s.direction] += 1
    return out


def main(argv: list[str]) -> int:
    paths = [Path(a) for a in argv] or sorted(
        p for d in TRACE_SETS for p in (RESULTS / d).glob("*.csv"))  # fmt: skip
    if not paths:
        print("no traces: write them with experiments/independent_traces.py and "
              "experiments/second_plant_traces.py", file=sys.stderr)  # fmt: skip
        return 2
    missing = [p for p in paths if not p.is_file()]
    if missing:
        print(f"{missing[0]}: no such trace", file=sys.stderr)
        return 2
    n_sided = n_scans = 0
    for p in paths:
        m = load_measurement(p)
        segs = segment_trace(read_drive(m.time, m.drives[m.axis], m.meta), float(m.time[-1]))
        portions = split_portions(segs)
        c = holds_by_motion(portions)
        sided = one_sided(c)
        n_sided += sided
        text = "; ".join(f"{q}: {c[q][1]} after +, {c[q][-1]} after −, {c[q][0]} first"
                         for q in ("fit", "heldout"))  # fmt: skip
        sc = scan_counts(portions)
        scans = ", ".join(f"{q} {sc[q][1]} up {sc[q][-1]} down" for q in ("fit", "heldout"))
        scans_sided = one_sided(sc)
        n_scans += scans_sided
        print(f"{p.parent.name}/{p.name}: {text}{'  — one direction per portion' * sided}; "
              f"scans: {scans}{'  — one sense per portion' * scans_sided}")  # fmt: skip
    print(f"{n_sided} of {len(paths)} traces put the holds after one direction in one portion")
    print(f"{n_scans} of {len(paths)} traces put the scans of one sense in one portion")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
