"""The thesis reproduction ledger: every number the thesis gives for its chapter-2 and
chapter-4 figures, beside this model's, as the Markdown table of docs/thesis.md.

    python experiments/thesis_reproduction.py           # about 30 s on one core
    python experiments/thesis_reproduction.py --json    # the same numbers as JSON

Rows: the friction figures (2.8–2.10), the sawtooth (3.14), the amplifier's slew rates
(4.2/4.3), the detector (4.4, Eq. 4.1–4.2), the measured steps (4.6/4.7) on the real and
the calibrated set, and the thesis's own simulations on Table D.2 (4.8/4.10). Table D.1's
derived values are printed by ``experiments/component_figures.py``; the figures themselves
are drawn by ``turntable report``.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from turntable_env.calibration.thesis_data import thesis_step_sizes
from turntable_env.detector import Detector
from turntable_env.report.figures import (
    amplifier_figure,
    drift_figure,
    hysteresis_figure,
    sawtooth_figure,
    stepping_figure,
    stribeck_figure,
)
from turntable_env.simulation import cycle_minima, simulate, stepping_drive

HEADER = ["thesis", "the thesis says", "this model", "agrees"]


def ledger() -> list[dict[str, Any]]:
    """One row per thesis statement: figure, the thesis's value, the model's, a verdict
    ("yes": within the thesis's own precision; "no": outside it, with the ratio or the
    distance). Unequal steps (Fig. 4.8): a spread over 1 % of the mean step."""
    rows: list[dict[str, Any]] = []

    def row(fig: str, thesis: str, model: str, agrees: str, **numbers: float) -> None:
        rows.append({"figure": fig, "thesis": thesis, "model": model, "agrees": agrees,
                     "numbers": numbers})  # fmt: skip

    # chapter 2: friction
    err = stribeck_figure().numbers["gms_vs_stribeck_max_rel_error"]
    row("Fig. 2.8", "GMS slides on the Stribeck curve", f"largest relative error {err:.0e}, "
        "1 mm/s to 5 m/s", "yes", stribeck_rel_error=err)  # fmt: skip
    h = hysteresis_figure().numbers
    row("Fig. 2.9", "presliding hysteresis; the inner loop closes (nonlocal memory)",
        f"inner loop closes to {h['loop_closure_error_N']:.4f} N of a "
        f"{h['hysteresis_width_N']:.1f} N wide loop", "yes",
        closure_N=h["loop_closure_error_N"], width_N=h["hysteresis_width_N"])  # fmt: skip
    d = drift_figure().numbers
    row("Fig. 2.10", "Breedveld drifts under an oscillating force below breakaway, GMS not",
        f"drift per cycle: Breedveld {d['drift_per_cycle_breedveld_m'] * 1e6:.1f} µm, GMS "
        f"{d['drift_per_cycle_gms_m'] * 1e6:.0e} µm", "yes", **d)  # fmt: skip
    saw = sawtooth_figure().numbers
    row("Fig. 3.14", "sawtooth actuation signal", f"{saw['periods']} periods to "
        f"{saw['peak_V']:.0f} V, flyback at a", "yes (shape)")  # fmt: skip

    # chapter 4: the rig
    a = amplifier_figure().numbers
    for key, quoted, what in (
        ("slew_1V_step_V_per_s", 0.9, "1 V input step"),
        ("slew_3V_step_V_per_s", 2.7, "3 V input step"),
        ("slew_900V_peak_V_per_s", 12.0, "full 900 V swing"),
        ("slew_adapted_90V_V_per_s", 8.0, "adapted input, 90 V"),
    ):
        model = a[key] / 1e6  # V/µs
        ok = abs(model / quoted - 1.0) < 0.05
        row("Fig. 4.2/4.3", f"slew rate, {what}: {quoted:g} V/µs", f"{model:.2f} V/µs",
            "yes" if ok else f"no ({model / quoted:.2f}×)", **{key: a[key]})  # fmt: skip
    det = Detector()
    row("Fig. 4.4", "linear range ±0.2 mm of the spot", f"±{det.angle_range * 1e3:.3f} mrad of "
        f"table angle, ±{det.saturation_voltage:.2f} V", "yes (definition)",
        angle_range_rad=det.angle_range)  # fmt: skip
    for volts, um in ((0.53, 1.5), (1.19, 3.4)):
        x = float(det.table_displacement(volts)) * 1e6
        row("Eq. 4.1–4.2", f"{volts} V → x_table = {um} µm", f"{x:.2f} µm",
            "yes" if abs(x - um) < 0.05 else "no", **{f"x_{volts}V_m": x * 1e-6})  # fmt: skip
    measured = thesis_step_sizes()
    for params in ("real", "calibrated"):
        for signal, n, fig_no, key in (("one", 9, "4.7", "one_directional"),
                                       ("two", 5, "4.6", "two_directional")):  # fmt: skip
            f = stepping_figure(params, signal, periods=n).numbers
            ratio = f["step_m"] / measured[key]
            ok = abs(ratio - 1.0) < 0.1  # the thesis quotes two digits of a 5- or 9-step mean
            step = {f"{params}_{signal}_step_m": f["step_m"]}
            row(f"Fig. {fig_no}", f"{signal}-directional step {measured[key] * 1e6:.2f} µm "
                "(2 V, 100 Hz, adapted)", f"{params} set: {f['step_m'] * 1e6:.3f} µm",
                "yes" if ok else f"no ({ratio:.2f}×)", **step)  # fmt: skip
            if signal == "two":
                back = f["return_m"] / f["excursion_m"]
                row(f"Fig. {fig_no}", "the table returns to its start", f"{params} set: ends "
                    f"{back:+.1%} of the excursion from its start",
                    "yes" if abs(back) < 0.1 else f"no ({abs(back):.0%} off)",
                    **{f"{params}_return_fraction": back})  # fmt: skip

    # the thesis's own simulations (Table D.2, ideal source, 2 Hz)
    drive, ps = stepping_drive("thesis", periods=5, frequency=2.0)
    r = simulate(ps, drive, axis="B", output_dt=1e-3)
    steps = np.abs(r.steps)
    spread = (steps.max() - steps.min()) / steps.mean()
    row("Fig. 4.8", "not every step results in the same displacement", f"steps "
        f"{steps.min() * 1e3:.1f} to {steps.max() * 1e3:.1f} mm at R_table = {ps.table.radius} m "
        f"(spread {spread:.0%})", "yes" if spread > 0.01 else "no (equal steps)",
        step_spread=spread)  # fmt: skip
    drive, ps = stepping_drive("thesis", periods=5, signal="two", cycles=3, frequency=2.0)
    r = simulate(ps, drive, axis="B", output_dt=1e-3)
    mins, exc = cycle_minima(r, drive)
    diff = (max(mins) - min(mins)) / exc
    row("Fig. 4.10", "the minima of the cycles differ by < 0.5 %", f"{diff:.2%} of the "
        f"excursion ({exc * 1e3:.1f} mrad)", "yes" if diff < 0.005 else f"no ({diff / 0.005:.1f}×)",
        minima_spread=diff)  # fmt: skip
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    """The ledger as a Markdown table (docs/thesis.md)."""
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += [f"| {r['figure']} | {r['thesis']} | {r['model']} | {r['agrees']} |" for r in rows]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args(argv)
    rows = ledger()
    print(json.dumps(rows, indent=2) if args.json else markdown(rows))


if __name__ == "__main__":
    main()
