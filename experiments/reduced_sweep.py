"""Reduced per-axis model vs the full 3-D model over the drive range (issue "fast simulation").

Grid: amplitude 20, 90, 200 V on the tubes (input ÷ 45), frequency 10, 100, 2000 Hz,
ramp ratio a 0.5, 0.95, 0.99, amplifier adapted / unadapted / ideal, both directions;
real parameters, axis B, 3 periods. Each row: mean |step| of both models at the table
radius, their relative difference, and the free contact travel for scale. Cases whose
adapted flyback does not fit the period are marked n/a.

    python experiments/reduced_sweep.py            # writes experiments/results/reduced_sweep.csv

Prints the table and a summary (fraction of cases within 5 %).
"""

from __future__ import annotations

import csv
import itertools
import sys
import time
from pathlib import Path

import numpy as np

from turntable_env.reduced import ReducedModel, simulate_reduced
from turntable_env.simulation import simulate, stepping_drive

AMPLITUDES_V = (20.0, 90.0, 200.0)  # on the tubes
FREQUENCIES = (10.0, 100.0, 2000.0)
RATIOS = (0.5, 0.95, 0.99)
MODES = ("adapted", "unadapted", "ideal")
PERIODS = 3
OUT = Path(__file__).parent / "results" / "reduced_sweep.csv"


def main() -> int:
    rows = []
    models: dict[str, ReducedModel] = {}
    t0 = time.perf_counter()
    for mode, amp, f, a, sgn in itertools.product(
        MODES, AMPLITUDES_V, FREQUENCIES, RATIOS, (1.0, -1.0)
    ):
        row = {"amplifier": mode, "amplitude_V": sgn * amp, "frequency_Hz": f, "a": a}
        try:
            drive, ps = stepping_drive(
                "real", amplitude=sgn * amp / 45.0, frequency=f, periods=PERIODS, a=a,
                amplifier=mode,
            )  # fmt: skip
            if mode not in models:
                models[mode] = ReducedModel(ps, "B")
            rm = models[mode]
            full = simulate(rm.params, drive, axis="B", model=rm.full, coarse_factor=0.5,
                            output_dt=min(1e-5, 0.01 / f))  # fmt: skip
            red = simulate_reduced(ps, drive, model=rm, output_dt=min(1e-5, 0.01 / f))
            s_full, s_red = full.step_size, red.step_size
            row.update(
                full_step_nm=1e9 * s_full,
                reduced_step_nm=1e9 * s_red,
                rel_diff=(s_red - s_full) / s_full if s_full > 0 else float("nan"),
                free_travel_nm=1e9 * abs(rm.axis_params.tube_gain[0]) * amp,
            )
        except ValueError as exc:
            row.update(full_step_nm="n/a", reduced_step_nm="n/a", rel_diff="n/a",
                       free_travel_nm="n/a", note=str(exc)[:80])  # fmt: skip
        rows.append(row)
        print(row, flush=True)
    OUT.parent.mkdir(exist_ok=True)
    keys = ["amplifier", "amplitude_V", "frequency_Hz", "a", "full_step_nm", "reduced_step_nm",
            "rel_diff", "free_travel_nm", "note"]  # fmt: skip
    with OUT.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in keys})
    ok = [r for r in rows if isinstance(r["rel_diff"], float) and np.isfinite(r["rel_diff"])]
    within = [r for r in ok if abs(r["rel_diff"]) <= 0.05]
    med = float(np.median([abs(r["rel_diff"]) for r in ok])) if ok else float("nan")
    share = 100 * len(within) / max(len(ok), 1)
    print(f"\n{len(ok)} cases run, {len(within)} within 5 % ({share:.0f} %), median |difference|")
    print(f"{100 * med:.1f} %; wall {time.perf_counter() - t0:.0f} s")
    for mode in MODES:
        sub = [abs(r["rel_diff"]) for r in ok if r["amplifier"] == mode]
        if sub:
            med_m, max_m = 100 * np.median(sub), 100 * max(sub)
            print(f"  {mode:<10} median |diff| {med_m:.1f} %  max {max_m:.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
