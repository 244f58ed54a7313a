"""Reduced per-axis model vs the full 3-D model over the drive range (issue 32, item 1).

The sweep of ``turntable bench`` (:func:`turntable_env.bench.reduced_vs_full_sweep`):
amplitude 20, 90, 200 V on the tubes (input ÷ 45), frequency 10, 100, 2000 Hz, ramp ratio
a 0.5, 0.95, 0.99, amplifier adapted / unadapted / ideal, both directions; real
parameters, axis B, 3 periods. Each row: mean |step| of both models per period and their
relative difference (none where the full step is under 1 nm or the adapted flyback does
not fit the period).

    python experiments/reduced_sweep.py            # writes experiments/results/reduced_sweep.csv
    python experiments/reduced_sweep.py --translation   # reduced_sweep_translation.csv: the
                                                        # reduced model with the translation
    python experiments/reduced_sweep.py --both --check-reference 6   # both files on one
        # 3-D reference; the 6 worst cases of each rerun at half the reference's step

    python experiments/reduced_sweep.py --translation --reference \
        experiments/results/reduced_sweep.csv --convergence   # the translation form on a
        # committed 3-D reference, and each case again at half the reduced step bounds

    python experiments/reduced_sweep.py --both --periods 8 --settle 3   # the steady step,
        # |mean step| over periods 4-8 from rest: reduced_sweep_p8_s3.csv and
        # reduced_sweep_translation_p8_s3.csv

The 3-D model is the reference, run at its fixed fine step (``bench.full_reference_steps``).
The default measure is the bench's, the mean |step| over three periods from rest; the
start from rest is in it, so a 20 V triangle "steps" 1.7 nm there and 0 once settled.

Prints the summary (``reduced_vs_full_max`` and its case, median, share within 5 %).
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from turntable_env.bench import (
    FULL_REFERENCE_DT_FACTOR,
    VS_FULL,
    VS_FULL_PERIODS,
    full_reference_steps,
    period_step,
    reduced_vs_full_sweep,
    sweep_drive,
    vs_full_summary,
)
from turntable_env.reduced import ReducedModel, simulate_batch

OUT = Path(__file__).parent / "results" / "reduced_sweep.csv"
OUT_TRANSLATION = OUT.with_name("reduced_sweep_translation.csv")
SHOWN = 8  # cases over 5 % printed, the worst first
KEYS = ["amplifier", "amplitude_V", "frequency_Hz", "a", "periods", "settle", "full_step_nm",
        "reduced_step_nm", "rel_diff", "note", "full_period_steps_nm",
        "reduced_period_steps_nm"]  # fmt: skip


def _cell(v: object) -> object:
    """A CSV cell: empty for None, a list of per-period steps as ';'-separated nm."""
    if v is None:
        return ""
    return ";".join(f"{x:.4f}" for x in v) if isinstance(v, list) else v


def _write(rows: list[dict], out: Path) -> None:
    out.parent.mkdir(exist_ok=True)
    tmp = out.with_suffix(".tmp")  # written whole, then moved: never half a file
    with tmp.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=KEYS)
        w.writeheader()
        for r in rows:
            w.writerow({k: _cell(r.get(k)) for k in KEYS})
    tmp.replace(out)


def _summary(rows: list[dict], label: str) -> None:
    s = vs_full_summary(rows)
    wc = s["reduced_vs_full_worst_case"]
    print(f"{label}: {len(rows)} cases, {s['reduced_vs_full_cases']} with a full step >= 1 nm: "
          f"{100 * s['reduced_vs_full_within_5pct']:.1f} % within 5 %, median |difference| "
          f"{100 * s['reduced_vs_full_median']:.1f} %, max {100 * s['reduced_vs_full_max']:.1f} %"
          f" ({wc['amplifier']}, {wc['amplitude_V']:+g} V, {wc['frequency_Hz']:g} Hz, "
          f"a = {wc['a']})")  # fmt: skip
    for mode in VS_FULL["amplifier"]:
        sub = [abs(r["rel_diff"]) for r in rows
               if r["amplifier"] == mode and r["rel_diff"] is not None]  # fmt: skip
        print(f"  {mode:<10} median |diff| {100 * np.median(sub):.1f} %  "
              f"max {100 * max(sub):.1f} %")  # fmt: skip
    over = sorted((r for r in rows if r["rel_diff"] is not None and abs(r["rel_diff"]) > 0.05),
                  key=lambda r: -abs(r["rel_diff"]))  # fmt: skip
    for r in over[:SHOWN]:
        print(f"  over 5 %: {r['amplifier']:<10} {r['amplitude_V']:+6g} V {r['frequency_Hz']:6g} Hz"
              f" a = {r['a']:<5} 3-D {r['full_step_nm']:9.3f} nm, reduced "
              f"{r['reduced_step_nm']:9.3f} nm, {100 * r['rel_diff']:+.1f} %")  # fmt: skip
        full, red = (" ".join(f"{x:+.2f}" for x in r[k])
                     for k in ("full_period_steps_nm", "reduced_period_steps_nm"))  # fmt: skip
        print(f"    per period [nm]: 3-D {full}; reduced {red}")
    if len(over) > SHOWN:
        print(f"  ... and {len(over) - SHOWN} more cases over 5 % (the CSV has every case)")


def _check_reference(rows: list[dict], n: int, periods: int, settle: int) -> None:
    """The n worst cases' 3-D step again at half the reference's step: how converged the
    reference is where the verdict is decided."""
    ok = sorted((r for r in rows if r["rel_diff"] is not None),
                key=lambda r: -abs(r["rel_diff"]))[:n]  # fmt: skip
    for r in ok:
        drive, ps, odt = sweep_drive(r, periods)
        rm = ReducedModel(ps, "B")
        half = 1e9 * period_step(
            full_reference_steps(rm, drive, odt, FULL_REFERENCE_DT_FACTOR / 2), settle
        )
        change = 100 * (r["full_step_nm"] / half - 1)
        print(f"  reference check: {r['amplifier']:<10} {r['amplitude_V']:+6g} V "
              f"{r['frequency_Hz']:6g} Hz a = {r['a']:<5} 3-D {r['full_step_nm']:.4f} nm, "
              f"at half the step {half:.4f} nm ({change:+.2f} %)")  # fmt: skip


def _read_reference(path: Path) -> list[dict]:
    """The rows of an earlier sweep's CSV as ``reduced_vs_full_sweep``'s ``reference``: its
    3-D steps per period (as the CSV keeps them, to 1e-4 nm), so a form can be rerun
    without the 3-D model (the sweep refuses rows of another grid, naming the first)."""
    rows = []
    with path.open(newline="") as fh:
        for line, r in enumerate(csv.DictReader(fh), start=2):
            try:
                rows.append({
                    "amplifier": r["amplifier"], "amplitude_V": float(r["amplitude_V"]),
                    "frequency_Hz": float(r["frequency_Hz"]), "a": float(r["a"]),
                    "periods": int(r["periods"]), "settle": int(r["settle"]),
                    "full_step_nm": float(r["full_step_nm"]) if r["full_step_nm"] else None,
                    "full_period_steps_nm": ([float(x) for x in r["full_period_steps_nm"]
                                              .split(";")] if r["full_period_steps_nm"]
                                             else None),
                })  # fmt: skip
            except (KeyError, ValueError) as exc:
                raise ValueError(f"{path}:{line}: not a sweep row ({exc})") from None
    return rows


def _convergence(rows: list[dict], translation: bool, periods: int, settle: int) -> None:
    """Each case's reduced step again at half the reduced model's step bounds
    (``ReducedModel(step_scale=0.5)``: grid, slip step, ringing step): the largest and the
    median change over the cases with a 3-D step of 1 nm or more, and the worst three."""
    models: dict[str, tuple[ReducedModel, ReducedModel]] = {}
    changes = []
    for r in rows:
        if r["rel_diff"] is None:
            continue
        drive, ps, odt = sweep_drive(r, periods)
        if r["amplifier"] not in models:
            models[r["amplifier"]] = ReducedModel(ps, "B", translation=translation,
                                                  step_scale=0.5)  # fmt: skip
        half = simulate_batch([models[r["amplifier"]]], [drive], drive.duration,
                              output_dt=odt)[0].steps  # fmt: skip
        h_nm = 1e9 * period_step(half, settle)
        changes.append((abs(r["reduced_step_nm"] / h_nm - 1.0), r, h_nm))
    changes.sort(key=lambda c: -c[0])
    print(f"  convergence: at half the step bounds the reduced step moves by at most "
          f"{100 * changes[0][0]:.2f} % (median {100 * np.median([c[0] for c in changes]):.3f} "
          f"%, {len(changes)} cases)")  # fmt: skip
    for c, r, h_nm in changes[:3]:
        print(f"    {r['amplifier']:<10} {r['amplitude_V']:+6g} V {r['frequency_Hz']:6g} Hz "
              f"a = {r['a']:<5} {r['reduced_step_nm']:.4f} nm, at half {h_nm:.4f} nm "
              f"({100 * c:.2f} %)")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    form = ap.add_mutually_exclusive_group()
    form.add_argument("--translation", action="store_true",
                      help="the reduced model with the sphere's translation")  # fmt: skip
    form.add_argument("--both", action="store_true",
                      help="both forms on one 3-D reference (both files)")  # fmt: skip
    ap.add_argument("--check-reference", type=int, default=0, metavar="N",
                    help="rerun the N worst cases' 3-D reference at half its step")  # fmt: skip
    ap.add_argument("--periods", type=int, default=VS_FULL_PERIODS,
                    help=f"periods from rest (default {VS_FULL_PERIODS}, the bench's)")  # fmt: skip
    ap.add_argument("--settle", type=int, default=0,
                    help="the steady step: |mean step| after this many periods (default 0: "
                         "the bench's mean |step| over every period)")  # fmt: skip
    ap.add_argument("--reference", type=Path, metavar="CSV",
                    help="take the 3-D steps from an earlier sweep's CSV of this grid, "
                         "periods and settling instead of running the 3-D model")  # fmt: skip
    ap.add_argument("--convergence", action="store_true",
                    help="rerun each reduced case at half its step bounds")  # fmt: skip
    args = ap.parse_args(argv)
    if args.reference is not None and not args.reference.is_file():
        ap.error(f"--reference={args.reference}: no such file")
    if args.check_reference < 0:
        ap.error(f"--check-reference={args.check_reference}: must be >= 0")
    if args.periods < 1:
        ap.error(f"--periods={args.periods}: must be >= 1")
    if not 0 <= args.settle < args.periods:
        ap.error(f"--settle={args.settle}: must lie in 0…{args.periods - 1} (--periods - 1)")
    run = {"periods": args.periods, "settle": args.settle}
    bench_measure = run == {"periods": VS_FULL_PERIODS, "settle": 0}
    tail = "" if bench_measure else f"_p{args.periods}_s{args.settle}"
    reference = None
    if args.reference is not None:
        try:
            reference = _read_reference(args.reference)
            if reference and (reference[0]["periods"], reference[0]["settle"]) != (
                args.periods, args.settle
            ):
                raise ValueError(f"{args.reference}: periods {reference[0]['periods']}, settle "
                                 f"{reference[0]['settle']}, not {args.periods}, {args.settle}")
        except ValueError as exc:
            ap.error(str(exc))
    t0 = time.perf_counter()
    try:
        plain = None if args.translation else reduced_vs_full_sweep(reference=reference, **run)
        moved = (reduced_vs_full_sweep(translation=True, reference=plain or reference, **run)
                 if args.translation or args.both else None)  # fmt: skip
    except ValueError as exc:  # a reference of another grid
        ap.error(str(exc))
    for rows, out, label in ((plain, OUT, "per-axis"),
                             (moved, OUT_TRANSLATION, "translation")):  # fmt: skip
        if rows is None:
            continue
        _write(rows, out.with_name(out.stem + tail + out.suffix))
        _summary(rows, label)
        if args.check_reference:
            _check_reference(rows, args.check_reference, args.periods, args.settle)
        if args.convergence:
            _convergence(rows, rows is moved, args.periods, args.settle)
    rows = plain if plain is not None else moved
    pairs = {}
    for r in rows:
        if r["full_step_nm"] is not None:
            key = (r["amplifier"], abs(r["amplitude_V"]), r["frequency_Hz"], r["a"])
            pairs.setdefault(key, {})[r["amplitude_V"] > 0] = r["full_step_nm"]
    asym = [abs(p[True] - p[False]) / (0.5 * (p[True] + p[False])) for p in pairs.values()
            if len(p) == 2 and min(p.values()) >= 1.0]  # fmt: skip
    print(
        f"the 3-D model's direction asymmetry |s+ − s−|/mean: median "
        f"{100 * np.median(asym):.1f} %, max {100 * max(asym):.1f} %; wall "
        f"{time.perf_counter() - t0:.0f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
