"""The direction pairs of a few-setting protocol against their bound from the step sizes
(issue 31, stop 105): what :func:`~turntable_env.calibration.signatures.group_scores`
allows one pair's misfit where the pairs are too few to estimate it.

For each calibration report and its trace: the fitted nominal model (report.json's nominal
parameters, as ``experiments/signature_round.py`` rebuilds it, without effects) and the
data are read by the calibrator's own features; then the bursts entering the bound, the
robust scale of their relative step misfits, the bound
(:func:`~turntable_env.calibration.signatures.step_misfit_sd`), each direction pair's
misfit (data − model), and the most any candidate could gain on the direction group
(½ Σ misfit²/(σ² + bound²): the gain of one that explains every pair).

    python experiments/direction_bound.py REPORT_DIR TRACE.csv [REPORT_DIR TRACE.csv ...]

REPORT_DIR holds the report.json of ``turntable calibrate TRACE.csv --report REPORT_DIR``
(or of a row of ``experiments/independent_calibration.py``, in DIR/NAME).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
from signature_round import rebuild

from turntable_env.calibration.signatures import STEP_SCALE_Z, step_misfit_sd
from turntable_env.calibration.trace_fit import signature_search


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", nargs="+", metavar="REPORT_DIR TRACE.csv")
    args = ap.parse_args(argv)
    if len(args.pairs) % 2:
        ap.error("give a REPORT_DIR and a TRACE.csv for each row")
    rows = list(zip(args.pairs[::2], args.pairs[1::2], strict=True))
    for rd, tr in rows:
        if not (Path(rd) / "report.json").is_file():
            ap.error(f"{rd}/report.json: no such file")
        if not Path(tr).is_file():
            ap.error(f"{tr}: no such file")
    print("| trace | bursts in the bound | step misfit scale | bound | pair misfits | "
          "most a candidate gains [nats] |")
    print("|---|---:|---:|---:|---|---:|")
    for rd, tr in rows:
        report = json.loads((Path(rd) / "report.json").read_text())
        problem, x = rebuild(report, Path(tr))
        search = signature_search(problem)
        m = search.features(x, {})
        d = search.data
        st = d.group("steps")
        enter = int(np.sum((np.abs(m.value[st]) >= STEP_SCALE_Z * d.noise[st])
                           & (np.abs(d.value[st]) >= STEP_SCALE_Z * d.noise[st])))  # fmt: skip
        bound = step_misfit_sd(d, m)
        dr = d.group("direction")
        r = d.value[dr] - m.value[dr]
        if bound is None:
            print(f"| {Path(tr).name} | {enter} | — | none | "
                  f"{', '.join(f'{v:+.4f}' for v in r) or '—'} | 0 (not scored) |")
            continue
        most = 0.5 * float(np.sum(r**2 / (d.noise[dr] ** 2 + bound**2)))
        print(f"| {Path(tr).name} | {enter} | {bound * math.sqrt(2):.4f} | {bound:.4f} | "
              f"{', '.join(f'{v:+.4f}' for v in r) or '—'} | {most:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
