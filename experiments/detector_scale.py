"""How far a detector's motion lies from the prior model's (stop 90): the ratios
:func:`~turntable_env.calibration.trace_fit.check_scale` refuses a file beyond.

For each trace, the detector's motion over the prior model's (the base plant with no
factor fitted) for the file's drive, as RMS about the first sample and as range. A unit
mistake (a detector logged in mV and written as V: ×1000) or a wrong detector constant
lands far outside what plants of other formulations read.

    python experiments/detector_scale.py [TRACE.csv ...] [--base real]

Default traces: the three independent plants' (experiments/results/*_traces, written by
the traces scripts).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.nominal import NominalModel
from turntable_env.calibration.trace_fit import (
    MAX_SCALE_RATIO,
    TRACE_NOMINAL,
    TraceProblem,
    on_base,
    scale_ratios,
)
from turntable_env.plant import Plant

RESULTS = Path("experiments/results")
PLANTS = ("independent_traces", "second_plant_traces", "third_plant_traces")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("traces", nargs="*", type=Path)
    ap.add_argument("--base", default="real", choices=["real", "thesis", "calibrated"])
    args = ap.parse_args(argv)
    paths = args.traces or sorted(p for d in PLANTS for p in (RESULTS / d).glob("*.csv"))
    if not paths:
        ap.error("no traces: write them with experiments/*_traces.py or name them")
    for p in paths:
        if not p.is_file():
            ap.error(f"{p}: no such file")
    base = Plant(args.base, fidelity="reduced")
    model = NominalModel(base, tuple(TRACE_NOMINAL))
    seen = []
    print("| trace | RMS ratio | range ratio |")
    print("|---|---:|---:|")
    for p in paths:
        td, _ = on_base(load_measurement(p), base)
        ((rms, ptp),) = scale_ratios(TraceProblem([td], model), np.zeros(len(model)))
        seen += [rms, ptp]
        print(f"| {p.parent.name}/{p.stem} | {rms:.3g} | {ptp:.3g} |", flush=True)
    print(f"{len(paths)} traces: ratios {min(seen):.2g}–{max(seen):.2g} (refused beyond "
          f"{MAX_SCALE_RATIO:g}× either way)")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
