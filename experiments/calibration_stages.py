"""Where a trace calibration's wall time goes (issue 31: a 2.5 s trace at 20 kHz in under
5 minutes on this machine's 2 cores): ``turntable calibrate TRACE --report DIR`` run once
in a subprocess (:func:`calibration_speed.calibrate_command`), each progress line timed as
it arrives, every gap between lines counted to the stage of the line that ends it, and the
seconds per stage printed: start-up with the prior model, the global stage with the nominal
fit's starts, the basin hops, the signature round, the candidates on the trace and the
refits with the verdicts (a joint refit's hops count to the hops).

    python experiments/calibration_stages.py                  # the second plant's axis C
    python experiments/calibration_stages.py TRACE --workers 2 --fresh-cache

Wall seconds on the machine it runs on; run it on an otherwise quiet machine. Without
``--fresh-cache`` the kernels come from the environment's numba cache where they are there.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from calibration_speed import ROOT, TRACE, calibrate_command  # this directory is on sys.path

# (stage, pattern of the progress lines that close it), in the order the command prints them
STAGES = (
    ("start-up and the prior model", r"\d+ trace\(s\)|prior model"),
    ("global stage and the starts", r"global stage|start \d+:"),
    ("basin hops", r"hop \d+|nominal model"),
    ("signature round", r"signature "),
    ("candidates on the trace", r"candidate "),
)
REST = "refits, verdicts and the report"

__all__ = ["stage_of", "stage_seconds"]


def stage_of(line: str) -> str:
    """The stage a progress line of ``turntable calibrate`` closes (:data:`STAGES`)."""
    text = line.strip()
    for name, pattern in STAGES:
        if re.match(pattern, text):
            return name
    return REST


def stage_seconds(timed: list[tuple[float, str]], end: float) -> dict[str, float]:
    """Seconds per stage: each gap between lines (from the start at 0 s) goes to the stage
    of the line that ends it, and the gap after the last line to the refits' stage."""
    out = {name: 0.0 for name, _ in STAGES} | {REST: 0.0}
    last = 0.0
    for t, line in timed:
        out[stage_of(line)] += t - last
        last = t
    out[REST] += end - last
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("trace", nargs="?", type=Path, default=TRACE)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--fresh-cache", action="store_true", help="a new numba cache directory")
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error(f"--workers={args.workers}: must be >= 1")
    if not args.trace.is_file():
        ap.error(f"{args.trace}: no such file (python experiments/second_plant_traces.py "
                 "writes the default one)")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="calibration-stages-") as tmp:
        env = dict(os.environ)
        if args.fresh_cache:
            env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "numba")
        cmd = calibrate_command(args.trace, Path(tmp) / "report", args.workers)
        t0 = time.perf_counter()
        timed: list[tuple[float, str]] = []
        with subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True) as proc:  # fmt: skip
            for line in proc.stdout:
                timed.append((time.perf_counter() - t0, line.rstrip("\n")))
        end = time.perf_counter() - t0
        if proc.returncode != 0:
            print(f"calibrate failed ({proc.returncode}): {timed[-1][1] if timed else ''}",
                  file=sys.stderr)  # fmt: skip
            return 1
        report = json.loads((Path(tmp) / "report" / "report.json").read_text())
    cache = "a new numba cache" if args.fresh_cache else "the environment's numba cache"
    for name, s in stage_seconds(timed, end).items():
        print(f"{name:>32}: {s:7.1f} s")
    print(f"{'total':>32}: {end:7.1f} s (report's wall_s {report['wall_s']:.1f} s; "
          f"{report['diagnosis']['n_simulations']} simulations, {args.workers} workers, "
          f"{cache})")
    print(f"effects {report['selected_effects'] or 'none'}, held-out "
          f"{report['error_before']:.4g} -> {report['error_after']:.4g} nm")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
