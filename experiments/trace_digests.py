"""Digests of the independent plants' written traces, to tell a machine's traces from its fits.

The trace sets are written again on every machine (gitignored), and a table row's nominal
fit moved from one machine to the next (docs/calibration.md, stop 79). If the traces are
the same bytes on both machines, the difference is the fit's; if not, the writers'.

    python experiments/trace_digests.py                       # SHA-256 of every file, per plant
    python experiments/trace_digests.py --json OUT.json       # and written with the machine
    python experiments/trace_digests.py --compare REF.json    # each file: same, differs, missing

Plants whose directory holds no traces are skipped (write them with the script
``experiments/independent_calibration.py`` names). Exit 2 on a bad argument or reference.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from independent_calibration import PLANTS

from turntable_env.provenance import machine  # the processor, libraries and BLAS

ROOT = Path(__file__).resolve().parent.parent


def digests(plants: list[str]) -> dict[str, dict[str, str]]:
    """plant → {file name: SHA-256 hex} of its trace directory's .csv and .json files."""
    out = {}
    for plant in plants:
        d = ROOT / PLANTS[plant][0]
        files = sorted(p for p in d.glob("*") if p.suffix in (".csv", ".json"))
        if files:
            out[plant] = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--plants", nargs="+", choices=sorted(PLANTS), default=sorted(PLANTS))
    ap.add_argument("--json", type=Path, help="write the digests and the machine here")
    ap.add_argument("--compare", type=Path, help="a --json file from another machine")
    args = ap.parse_args(argv)
    ref = None
    if args.compare is not None:
        try:
            ref = json.loads(args.compare.read_text())["digests"]
            if not (isinstance(ref, dict) and all(isinstance(v, dict) for v in ref.values())):
                raise TypeError("'digests' is not {plant: {file: digest}}")
        except (OSError, ValueError, KeyError, TypeError) as e:
            print(f"--compare {args.compare}: not a digest file ({e})", file=sys.stderr)
            return 2
    found = digests(args.plants)
    for plant, files in found.items():
        for name, h in files.items():
            line = f"{plant:6s} {name:32s} {h[:16]}"
            if ref is not None:
                other = ref.get(plant, {}).get(name)
                line += "  " + ("missing there" if other is None
                                else "same" if other == h else "differs")  # fmt: skip
            print(line)
    if ref is not None:
        same = sum(ref.get(p, {}).get(n) == h for p, fs in found.items() for n, h in fs.items())
        print(f"{same} of {sum(len(fs) for fs in found.values())} files the same bytes")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"machine": machine(), "digests": found}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
