"""Calibrate the independent plant's traces and print the before/after table (issue 19).

    python experiments/independent_calibration.py [--traces DIR] [--only NAME ...]
        [--base calibrated] [--out experiments/results/independent_calibration]
        [--backend auto|ray|processes [--address auto]]

With ``--backend`` the traces are calibrated at once, each a Ray task of one core (a
local Ray instance, or the cluster ``--address`` names) or, without Ray, a process.

Writes the traces first when DIR has none (``experiments/independent_traces.py``), then
calibrates each file alone — the calibrator is told nothing of the plant or its effects —
and prints one Markdown row per file: the injected effect and the catalogue effect it
corresponds to (or "outside" the catalogue), what was selected, the held-out error before
(prior model), after the nominal fit and at the end, the noise floor, the acceptance
target max(3× floor, 2 % of the RMS motion), whether it is met, and the wall time.
``results.json`` in ``--out`` holds the same, and each file's report directory.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from turntable_env.calibration.calibrate import calibrate, write_report
from turntable_env.scale import BACKENDS, map_tasks

# the independent plant's effect → the catalogue effect a calibrator should name
EXPECTED = {
    "creep": "piezo_creep",
    "hysteresis": "piezo_hysteresis",
    "floor_vibration": "vibration",
    "friction_asymmetry": "friction_asymmetry",
    "slow_amplifier": "amplifier_dynamics",
    "sensor_drift": "sensor_drift",
    "detector_nonlinearity": "detector_nonlinearity",
    "axis_misalignment": "axis_misalignment",
    "preload_relaxation": "outside",
    "mount_resonance": "outside",
}
ACCEPTANCE = (
    "clean", "creep", "hysteresis", "vibration", "friction_asymmetry", "slow_amplifier",
    "preload_relaxation", "mount_resonance",
)  # fmt: skip


def _calibrate_one(job: dict) -> dict:
    """Calibrate one trace alone and write its report; its row of the table."""
    injected = list(job["info"]["effects"])
    expected = [EXPECTED.get(e, "outside") for e in injected] or ["none"]
    t0 = time.perf_counter()
    res = calibrate([Path(job["file"])], base=job["base"], workers=job["workers"], progress=None)
    wall = time.perf_counter() - t0
    write_report(res, Path(job["out"]))
    d = res.diagnosis
    return {
        "trace": job["name"],
        "injected": injected,
        "expected": expected,
        "selected": res.selected_effects,
        "before_nm": res.error_before,
        "nominal_nm": d["error_nominal"],
        "after_nm": res.error_after,
        "floor_nm": d["noise_floor"],
        "target_nm": d["target"],
        "met": res.error_after <= d["target"],
        "structured": res.residual_structured,
        "wall_s": wall,
    }


def _print_row(row: dict) -> dict:
    sel = row["selected"] or ["none"]
    print(
        f"| {row['trace']} | {', '.join(row['injected']) or 'none'} | "
        f"{', '.join(row['expected'])} | {', '.join(sel)} | {row['before_nm']:.1f} | "
        f"{row['nominal_nm']:.1f} | {row['after_nm']:.1f} | {row['floor_nm']:.2f} | "
        f"{row['target_nm']:.1f} | {'yes' if row['met'] else 'no'} | {row['structured']} | "
        f"{row['wall_s']:.0f} |",
        flush=True,
    )
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--traces", default="experiments/results/independent_traces")
    ap.add_argument("--only", nargs="*", default=list(ACCEPTANCE))
    ap.add_argument("--base", default="calibrated")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", default="experiments/results/independent_calibration")
    ap.add_argument(
        "--backend", choices=BACKENDS, default=None,
        help="calibrate the traces in parallel: Ray tasks (auto: when installed) or processes",
    )  # fmt: skip
    ap.add_argument("--address", default=None, help="Ray cluster to join (default: local)")
    args = ap.parse_args(argv)
    traces = Path(args.traces)
    if not (traces / "truth.json").exists():
        subprocess.run(
            [sys.executable, "experiments/independent_traces.py", "--out", str(traces)],
            check=True,
        )
    truth = json.loads((traces / "truth.json").read_text())["files"]
    out = Path(args.out)
    print(
        "| trace | injected | expected | selected | before [nm] | nominal [nm] | after [nm] | "
        "floor [nm] | target [nm] | met | structured | wall [s] |"
    )
    print("|---|---|---|---|---:|---:|---:|---:|---:|---|---|---:|")
    jobs = [
        {"name": name, "file": str(traces / f"{name}.csv"), "info": truth[f"{name}.csv"],
         "base": args.base, "workers": args.workers, "out": str(out / name)}
        for name in args.only
    ]  # fmt: skip
    if args.backend is None:
        rows = [_print_row(_calibrate_one(job)) for job in jobs]
    else:  # the sweep as Ray tasks (or processes), one calibration each, one core each
        for job in jobs:
            job["workers"] = 1
        done = map_tasks(_calibrate_one, jobs, backend=args.backend, address=args.address)
        rows = [_print_row(row) for row in done]
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
