"""What each independent trace's protocol can test by signature (issue 31, stop 103).

    python experiments/protocol_coverage.py [TRACE.csv ...]

Per trace (default: the three independent plants' traces, written by the traces
scripts into experiments/results/*_traces): the features of each signature group the
calibrator reads on the data (:class:`~turntable_env.calibration.identify.SignatureSearch`,
from the drive and detector alone, no fit), and the searched catalogue effects the
protocol gives no signature (:func:`~turntable_env.calibration.signatures.coverage`;
report.md tables the same for a calibrated file). A row's injected effect among them can
be named only by the held-out trace error, at the stricter bar.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from turntable_env.calibration.identify import SignatureSearch
from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.trace_fit import SEARCHED, trace_data

RESULTS = Path("experiments/results")
SETS = ("independent_traces", "second_plant_traces", "third_plant_traces")


def coverage_of(path: Path) -> tuple[dict[str, int], dict[str, dict]]:
    """(features per signature group, :meth:`SignatureSearch.coverage` of the searched
    effects) of one trace file."""
    td = trace_data(load_measurement(path))
    y = td.m.detector_y_v if td.has_y else None
    search = SignatureSearch(None, [(td.m.time, td.drive, td.segments, td.m.detector_v, y,
                                     td.scale, td.floor, td.m.detector.table_radius)])  # fmt: skip
    return search.counts(), search.coverage(SEARCHED)


def _injected(path: Path) -> str:
    truth = path.parent / "truth.json"
    if not truth.exists():
        return "?"
    info = json.loads(truth.read_text()).get("files", {}).get(path.name, {})
    return ", ".join(info.get("effects", {})) or "none"


def main(argv: list[str]) -> int:
    paths = [Path(a) for a in argv] or [p for s in SETS
                                        for p in sorted((RESULTS / s).glob("*.csv"))]  # fmt: skip
    if not paths:
        print("no traces: write them with experiments/*_traces.py", file=sys.stderr)
        return 2
    for p in paths:
        if not p.is_file():
            print(f"{p}: no such trace", file=sys.stderr)
            return 2
    groups = ("direction", "relaxation", "scan_shape", "scan_range", "line", "y")
    print("| trace | injected | " + " | ".join(groups) + " | no signature on this protocol |")
    print("|---|---|" + "---:|" * len(groups) + "---|")
    for p in paths:
        counts, cov = coverage_of(p)
        none = [e for e, c in cov.items() if c["testable"] is False]
        print(f"| {p.parent.name}/{p.stem} | {_injected(p)} | "
              + " | ".join(str(counts.get(g, 0)) for g in groups)
              + f" | {', '.join(none) or '—'} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
