"""Calibrate the independent plant's traces and print the before/after table (issue 19).

    python experiments/independent_calibration.py [--traces DIR] [--only NAME ...]
        [--base calibrated] [--out experiments/results/independent_calibration]

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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--traces", default="experiments/results/independent_traces")
    ap.add_argument("--only", nargs="*", default=list(ACCEPTANCE))
    ap.add_argument("--base", default="calibrated")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", default="experiments/results/independent_calibration")
    args = ap.parse_args(argv)
    traces = Path(args.traces)
    if not (traces / "truth.json").exists():
        subprocess.run(
            [sys.executable, "experiments/independent_traces.py", "--out", str(traces)],
            check=True,
        )
    truth = json.loads((traces / "truth.json").read_text())["files"]
    out = Path(args.out)
    rows = []
    print(
        "| trace | injected | expected | selected | before [nm] | nominal [nm] | after [nm] | "
        "floor [nm] | target [nm] | met | structured | wall [s] |"
    )
    print("|---|---|---|---|---:|---:|---:|---:|---:|---|---|---:|")
    for name in args.only:
        info = truth[f"{name}.csv"]
        injected = list(info["effects"])
        expected = [EXPECTED.get(e, "outside") for e in injected] or ["none"]
        t0 = time.perf_counter()
        res = calibrate(
            [traces / f"{name}.csv"], base=args.base, workers=args.workers, progress=None
        )
        wall = time.perf_counter() - t0
        write_report(res, out / name)
        d = res.diagnosis
        sel = res.selected_effects or ["none"]
        row = {
            "trace": name,
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
        rows.append(row)
        print(
            f"| {name} | {', '.join(injected) or 'none'} | {', '.join(expected)} | "
            f"{', '.join(sel)} | {res.error_before:.1f} | {d['error_nominal']:.1f} | "
            f"{res.error_after:.1f} | {d['noise_floor']:.2f} | {d['target']:.1f} | "
            f"{'yes' if row['met'] else 'no'} | {res.residual_structured} | {wall:.0f} |",
            flush=True,
        )
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
