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

Prints the summary (``reduced_vs_full_max`` and its case, median, share within 5 %).
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from turntable_env.bench import VS_FULL, reduced_vs_full_sweep, vs_full_summary

OUT = Path(__file__).parent / "results" / "reduced_sweep.csv"
OUT_TRANSLATION = OUT.with_name("reduced_sweep_translation.csv")
KEYS = ["amplifier", "amplitude_V", "frequency_Hz", "a", "full_step_nm", "reduced_step_nm",
        "rel_diff", "note"]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--translation", action="store_true",
                    help="the reduced model with the sphere's translation")  # fmt: skip
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = reduced_vs_full_sweep(translation=args.translation)
    out = OUT_TRANSLATION if args.translation else OUT
    out.parent.mkdir(exist_ok=True)
    tmp = out.with_suffix(".tmp")
    with tmp.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=KEYS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k, "")) for k in KEYS})
    tmp.replace(out)
    s = vs_full_summary(rows)
    wc = s["reduced_vs_full_worst_case"]
    print(f"{len(rows)} cases, {s['reduced_vs_full_cases']} with a full step >= 1 nm: "
          f"{100 * s['reduced_vs_full_within_5pct']:.0f} % within 5 %, median |difference| "
          f"{100 * s['reduced_vs_full_median']:.1f} %, max {100 * s['reduced_vs_full_max']:.1f} %"
          f" ({wc['amplifier']}, {wc['amplitude_V']:+g} V, {wc['frequency_Hz']:g} Hz, "
          f"a = {wc['a']})")  # fmt: skip
    for mode in VS_FULL["amplifier"]:
        sub = [abs(r["rel_diff"]) for r in rows
               if r["amplifier"] == mode and r["rel_diff"] is not None]  # fmt: skip
        print(f"  {mode:<10} median |diff| {100 * np.median(sub):.1f} %  "
              f"max {100 * max(sub):.1f} %")  # fmt: skip
    pairs = {}
    for r in rows:
        if r["full_step_nm"] is not None:
            key = (r["amplifier"], abs(r["amplitude_V"]), r["frequency_Hz"], r["a"])
            pairs.setdefault(key, {})[r["amplitude_V"] > 0] = r["full_step_nm"]
    asym = [abs(p[True] - p[False]) / (0.5 * (p[True] + p[False])) for p in pairs.values()
            if len(p) == 2 and min(p.values()) >= 1.0]  # fmt: skip
    print(
        f"  the 3-D model's direction asymmetry |s+ − s−|/mean: median "
        f"{100 * np.median(asym):.1f} %, max {100 * max(asym):.1f} %; wall "
        f"{time.perf_counter() - t0:.0f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
