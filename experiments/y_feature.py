"""The y channel's feature on every trace with one (issue 31, stop 73): the slope of y on x
as the calibrator now reads it, over the bursts' and scans' changes of level
(:meth:`~turntable_env.calibration.signatures.SignatureLayout.measure`, group ``y``), beside
the slope over the whole trace that it replaces, each with its z (slope / standard
deviation; the whole-trace slope's white-noise deviation σ/√Σ(x − x̄)², as before).

    python experiments/y_feature.py [TRACE.csv ...]

Data alone, no model: a trace with no misalignment should score |z| ≲ 3 on the feature
axis_misalignment is named by (4.5 nats for its one parameter: z ≈ 3). The whole-trace
slope gives the third plant's drifting y z 353.7 and its floor vibration z 4.4; over the
moves they score −0.1 and −0.2, the three misaligned detectors 730.6–866.2, and every other
trace of the three plants |z| ≤ 2.6.
"""

from __future__ import annotations

import argparse
import math
import sys

from turntable_env.calibration.signatures import SignatureLayout
from turntable_env.calibration.trace_fit import trace_data
from turntable_env.testing.trace_sets import load_traces


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="y_feature", description=__doc__.splitlines()[0])
    ap.add_argument("traces", nargs="*", help="trace CSVs (default: the three plants' sets)")
    args = ap.parse_args(argv)
    try:
        traces = load_traces(args.traces)
    except ValueError as exc:
        print(f"y_feature: {exc}", file=sys.stderr)
        return 2
    print(f"{'trace':48s} {'moves':>5s} {'slope':>9s} {'z':>8s}   {'whole':>9s} {'z':>8s}")
    for path, m in traces:
        if m.detector_y_v is None:
            continue
        td = trace_data(m)
        lay = SignatureLayout(m.time - m.time[0], td.drive, td.segments, td.floor)
        x, y = m.detector_v * td.scale, m.detector_y_v * td.scale  # nm at R_table
        f = lay.measure(x, y)
        k = f.group("y")
        moves = (f"{float(f.value[k][0]):+9.5f} {float(f.value[k][0] / f.noise[k][0]):+8.1f}"
                 if k.any() else f"{'—':>9s} {'—':>8s}")  # fmt: skip
        xc = x - x.mean()
        sxx = float(xc @ xc)
        whole = float(xc @ (y - y.mean())) / sxx
        z_whole = whole / (td.floor / math.sqrt(sxx))
        name = f"{path.parent.name}/{path.name}"
        print(f"{name:48s} {len(lay.moves):5d} {moves}   {whole:+9.5f} {z_whole:+8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
