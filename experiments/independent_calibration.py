"""Calibrate an independent plant's traces and print the before/after table (issues 19, 31).

    python experiments/independent_calibration.py [--plant first|second|third] [--traces DIR]
        [--only NAME ...] [--base SET|FILE] [--out DIR]
        [--backend auto|ray|processes [--address auto]]

``--plant first`` is ``turntable_env/testing/independent_plant.py`` (its traces by
``experiments/independent_traces.py``), ``second`` is ``turntable_env/testing/
second_plant.py`` (``experiments/second_plant_traces.py``), ``third`` is
``turntable_env/testing/third_plant.py`` (``experiments/third_plant_traces.py``); every trace
of the set is calibrated unless ``--only`` names some.

With ``--backend`` the traces are calibrated at once, each a Ray task of one core (a
local Ray instance, or the cluster ``--address`` names) or, without Ray, a process.

Writes the traces first when DIR has none (``experiments/independent_traces.py``), then
calibrates each file alone — the calibrator is told nothing of the plant or its effects —
and prints one Markdown row per file: the injected effect and the catalogue effect it
corresponds to (or "outside" the catalogue), what was selected and how (by signature or
by the held-out trace error), the held-out error before (prior model), after the nominal
fit and at the end, the noise floor, the acceptance target max(3× floor, 2 % of the RMS
motion), whether it is met, whether the report flags the data as unexplained (the final
model stays above the target: ``diagnosis.unexplained``), the row's
verdict against issue 31's acceptance, the wall time and the commit the calibrator ran at
(``turntable_env.provenance``: ``+`` where tracked files differed from it; ``—`` where a row
made before stop 85 does not record it):

* clean: nothing selected beyond an amplifier effect (the plant's amplifier is not the
  model's), target met (so not flagged);
* a catalogue effect: it is selected (alone or with an amplifier effect) and the target
  is met;
* an effect outside the catalogue: the target is met (fitted) or the residual flagged.

The last line counts the rows that pass. ``results.json`` in ``--out`` holds the same
(rewritten after every row when the traces run one after another), and each file's report
directory; a run into an ``--out`` that already holds a ``results.json`` keeps that file's
rows of the traces it does not calibrate (a table run in parts, row by row).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import time
from pathlib import Path

from turntable_env.calibration.calibrate import calibrate, write_report
from turntable_env.calibration.measurement import Measurement, load_measurement
from turntable_env.files import write_atomic
from turntable_env.plant import set_or_plant
from turntable_env.provenance import code_label, code_version
from turntable_env.scale import BACKENDS, map_tasks

# an independent plant's effect → the catalogue effect a calibrator should name
EXPECTED = {
    "creep": "piezo_creep",
    "hysteresis": "piezo_hysteresis",
    "floor_vibration": "vibration",
    "friction_asymmetry": "friction_asymmetry",
    "slow_amplifier": "amplifier_dynamics",
    "sensor_drift": "sensor_drift",
    "detector_nonlinearity": "detector_nonlinearity",
    "axis_misalignment": "axis_misalignment",
    "contact_wear": "friction_wear",  # the second plant's: friction falls with sliding
    "preload_relaxation": "outside",
    "mount_resonance": "outside",
    "mains_pickup": "outside",
    "mirror_play": "outside",
    "drive_crosstalk": "outside",  # the third plant's: the drive couples into the detector
    "preload_creep": "outside",  # the third plant's: the preload spring relaxes
}
AMPLIFIER = {"amplifier_dynamics", "amplifier_fast_path", "amplifier_lag"}
PLANTS = {  # plant → (its traces' default directory, the script that writes them)
    "first": ("experiments/results/independent_traces", "experiments/independent_traces.py"),
    "second": ("experiments/results/second_plant_traces", "experiments/second_plant_traces.py"),
    "third": ("experiments/results/third_plant_traces", "experiments/third_plant_traces.py"),
}


HEADER = (
    "| trace | injected | expected | selected (how) | before [nm] | nominal [nm] | "
    "after [nm] | floor [nm] | target [nm] | met | flagged | passes | wall [s] | code |\n"
    "|---|---|---|---|---:|---:|---:|---:|---:|---|---|---|---:|---|"
)


def verdict(row: dict) -> bool:
    """The row passes issue 31's acceptance (module docstring)."""
    sel = set(row["selected"])
    expected = [e for e in row["expected"] if e not in ("none", "outside")]
    if "outside" in row["expected"]:
        return bool(row["met"] or row["flagged"])
    if not expected:
        return sel <= AMPLIFIER and row["met"] and not row["flagged"]
    # a slower amplifier is named by either amplifier effect
    named = all(e in sel or (e in AMPLIFIER and sel & AMPLIFIER) for e in expected)
    return bool(named and sel <= set(expected) | AMPLIFIER and row["met"])


def _calibrate_one(job: dict) -> dict:
    """Calibrate one trace alone and write its report; its row of the table."""
    injected = list(job["info"]["effects"])
    expected = [EXPECTED.get(e, "outside") for e in injected] or ["none"]
    t0 = time.perf_counter()
    data: Path | Measurement = Path(job["file"])
    if job.get("corners"):  # the model's drive through resolved flybacks' corners
        m = load_measurement(data)
        data = dataclasses.replace(m, meta={**m.meta, "drive_flybacks": "linear"})
    res = calibrate([data], base=job["base"], workers=job["workers"],
                    seed=job.get("seed", 0), progress=None)  # fmt: skip
    wall = time.perf_counter() - t0
    write_report(res, Path(job["out"]))
    d = res.diagnosis
    how = [h.get("decided_by", "") for h in res.history[1:]]
    cov = (d.get("signatures") or {}).get("coverage") or {}
    return {
        "trace": job["name"],
        "injected": injected,
        "expected": expected,
        "selected": res.selected_effects,
        "decided_by": how,
        # expected effects this trace's protocol gives no signature (signatures.coverage)
        "untestable": [e for e in expected if cov.get(e, {}).get("testable") is False],
        "before_nm": res.error_before,
        "nominal_nm": d["error_nominal"],
        "after_nm": res.error_after,
        "floor_nm": d["noise_floor"],
        "target_nm": d["target"],
        "met": res.error_after <= d["target"],
        "structured": res.residual_structured,
        "flagged": d["unexplained"],
        "wall_s": wall,
        "base": d["base"],  # the prior: a set's name or the earlier calibration's file
        "code": code_version(),  # where it ran (the tables mix rows of several commits)
    }


def print_row(row: dict) -> dict:
    sel = [f"{n} ({h})" for n, h in zip(row["selected"], row["decided_by"], strict=True)]
    untestable = [e for e in row.get("untestable", []) if e not in row["selected"]]
    # why an expected effect is not named: its protocol gives it no signature
    why = f" ({', '.join(untestable)}: no signature on this protocol)" if untestable else ""
    row["pass"] = verdict(row)
    print(
        f"| {row['trace']} | {', '.join(row['injected']) or 'none'} | "
        f"{', '.join(row['expected'])} | {', '.join(sel) or 'none'}{why} | "
        f"{row['before_nm']:.1f} | {row['nominal_nm']:.1f} | {row['after_nm']:.1f} | "
        f"{row['floor_nm']:.2f} | "
        f"{row['target_nm']:.1f} | {'yes' if row['met'] else 'no'} | "
        f"{'yes' if row['flagged'] else 'no'} | {'**yes**' if row['pass'] else 'no'} | "
        f"{row['wall_s']:.0f} | {code_label(row.get('code'))} |",
        flush=True,
    )
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plant", choices=sorted(PLANTS), default="first")
    ap.add_argument("--traces", default=None, help="trace directory (default: by --plant)")
    ap.add_argument("--only", nargs="*", default=None, help="trace names (default: all)")
    ap.add_argument("--base", default="real",
                    help="the prior: a set or a lab's earlier calibration (calibrated.toml, "
                         "report.json), as turntable calibrate --base (default real)")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0,
                    help="the calibration's seed, as turntable calibrate --seed (default 0)")
    ap.add_argument("--corners", action="store_true",
                    help="read each file as declaring '# drive_flybacks: linear' (the model's "
                         "drive through resolved flybacks' corners, segments.flyback_corners)")
    ap.add_argument("--out", default=None, help="default experiments/results/<plant>_calibration")
    ap.add_argument(
        "--backend", choices=BACKENDS, default=None,
        help="calibrate the traces in parallel: Ray tasks (auto: when installed) or processes",
    )  # fmt: skip
    ap.add_argument("--address", default=None, help="Ray cluster to join (default: local)")
    args = ap.parse_args(argv)
    try:  # read before any trace is written or calibrated
        base = set_or_plant(args.base)
    except ValueError as e:
        ap.error(f"--base: {e}")
    default_dir, writer = PLANTS[args.plant]
    traces = Path(args.traces or default_dir)
    if not (traces / "truth.json").exists():
        subprocess.run([sys.executable, writer, "--out", str(traces)], check=True)
    truth = json.loads((traces / "truth.json").read_text())["files"]
    names = args.only or [Path(f).stem for f in truth]
    unknown = [n for n in names if f"{n}.csv" not in truth]
    if unknown:
        ap.error(f"--only: no trace {unknown} in {traces} (has {sorted(truth)})")
    out = Path(args.out or f"experiments/results/{args.plant}_plant_calibration")
    print(HEADER)
    jobs = [
        {"name": name, "file": str(traces / f"{name}.csv"), "info": truth[f"{name}.csv"],
         "base": base, "workers": args.workers, "seed": args.seed, "corners": args.corners,
         "out": str(out / name)}
        for name in names
    ]  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    try:
        kept = _other_rows(out / "results.json", set(names))
    except ValueError as e:
        ap.error(str(e))

    def save(rows: list[dict]) -> None:  # this run's rows and the other traces' earlier ones
        write_atomic(out / "results.json", json.dumps(kept + rows, indent=2))

    if args.backend is None:  # results.json after every row: an interrupted run keeps its rows
        rows = []
        for job in jobs:
            rows.append(print_row(_calibrate_one(job)))
            save(rows)
    else:  # the sweep as Ray tasks (or processes), one calibration each, one core each
        for job in jobs:
            job["workers"] = 1
        done = map_tasks(_calibrate_one, jobs, backend=args.backend, address=args.address)
        rows = [print_row(row) for row in done]
    n_pass = sum(r["pass"] for r in rows)
    print(f"\n{n_pass} of {len(rows)} rows pass ({100.0 * n_pass / max(len(rows), 1):.0f} %); "
          f"wall {sum(r['wall_s'] for r in rows):.0f} s in all")  # fmt: skip
    save(rows)
    return 0


def _other_rows(path: Path, names: set[str]) -> list[dict]:
    """The rows of ``path`` (an earlier run's results.json in the same ``--out``) for traces
    this run does not calibrate: a table run in parts keeps every part's rows. ValueError
    naming the file where it is not a list of rows."""
    if not path.exists():
        return []
    try:
        rows = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: line {e.lineno} column {e.colno}: {e.msg}") from None
    if not isinstance(rows, list) or not all(isinstance(r, dict) and "trace" in r for r in rows):
        raise ValueError(f"{path}: not a list of table rows (each with its 'trace')")
    return [r for r in rows if r["trace"] not in names]


if __name__ == "__main__":
    raise SystemExit(main())
