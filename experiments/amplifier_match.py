"""Is the second plant's slower amplifier out of the model's reach, or its mechanics under
it? (issue 31, stop 88)

The second independent plant's amplifier is a second-order stage (ζ 0.7) with a slew
limit (:mod:`turntable_env.testing.second_plant`); the model's is the HVA 900's first-order
stage with a rate limit and, as options, a second pole (``lag_ratio`` ≤ 1) and a fast
path (:mod:`turntable_env.amplifier`). Part 1 fits the model's amplifier (slew per input
volt, current limit, second pole) to the plant's own amplifier output on the trace's
drive, 1.9–2.6 s (its fastest bursts), for the plant's nominal and slower amplifier,
from the datasheet's amplifier and from a slow start: how close the model's amplifier
structure comes to each [V RMS]. Part 2 puts each match into the model and refits the
mechanics alone (the nominal parameters but the amplifier's, with ``amplifier_lag`` at the
matched ratio) on the clean trace (the nominal amplifier's match) and on the slower-
amplifier trace (the slower one's), from the clean trace's calibrated mechanics: what the
model's mechanics leave under the plant's own drive voltage, beside each table row's
nominal fit, whose amplifier is free.

    python experiments/amplifier_match.py --clean-report DIR/clean/report.json
        [--slow-report DIR/slow_amplifier/report.json]

The reports are the table rows' (``experiments/independent_calibration.py --plant second
--only clean slow_amplifier --out DIR``). About 2 minutes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.optimize

from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.nominal import NominalModel
from turntable_env.calibration.residual import correlation_length
from turntable_env.calibration.trace_fit import TraceProblem, local_fit, on_base
from turntable_env.params import get_parameter_set
from turntable_env.plant import Plant
from turntable_env.testing import second_plant as sp

TRACE = Path("experiments/results/second_plant_traces/slow_amplifier.csv")
CLEAN = TRACE.with_name("clean.csv")
WINDOW_S = (1.9, 2.6)  # s of the trace: its 500 Hz, 2 kHz and 1 kHz bursts
STEP_S = 1e-6  # s, the amplifier waveforms' sampling


def match_amplifier(trace: Path) -> dict[str, tuple[float, float, float, float]]:
    """Per plant amplifier ("nominal", "slow"): the model amplifier's (slew factor,
    current factor, lag ratio) nearest its output on ``trace``'s drive, and the RMS left
    [V]; the better of two starts (the datasheet's, and a slow one)."""
    m = load_measurement(trace)
    t0, u0 = m.time - m.time[0], m.drives[m.axis]
    tt = np.arange(*WINDOW_S, STEP_S)
    uu = np.interp(tt, t0, u0)
    ps = get_parameter_set("real")
    amp, c_load = ps.amplifier, 2.0 * ps.tube.quadrant.capacitance  # one channel's two
    plants = {"nominal": sp.Effects(), "slow": sp.Effects(slow_amplifier=sp.SlowAmplifier())}
    out = {}
    for label, eff in plants.items():
        ref = sp.simulate(sp.PlantParams(), (t0, u0), tt, effects=eff, axis=m.axis).amplifier_V

        def model(p: np.ndarray, ref: np.ndarray = ref) -> np.ndarray:
            a = replace(amp.scaled(math.exp(p[0]), math.exp(p[1])), lag_ratio=float(p[2]))
            return a.simulate(tt, uu, load_capacitance=c_load, initial_output=float(ref[0])).output

        best = None
        for p0 in ([0.0, 0.0, 0.5], [math.log(0.4), math.log(0.1), 0.5]):
            r = scipy.optimize.least_squares(
                lambda p, ref=ref, model=model: (model(p) - ref)[::5], p0,
                bounds=([-4, -4, 0], [3, 3, 1]), diff_step=1e-3,
            )  # fmt: skip
            rms = float(np.sqrt(np.mean((model(r.x) - ref) ** 2)))
            if best is None or rms < best[3]:
                best = (math.exp(r.x[0]), math.exp(r.x[1]), float(r.x[2]), rms)
        out[label] = best
    return out


def mechanics_under(trace: Path, amp: tuple[float, float, float, float], start: Path,
                    own: Path | None) -> dict[str, float]:  # fmt: skip
    """``trace``'s held-out error [nm] with the model amplifier ``amp`` (slew factor,
    current factor, lag ratio, —): at the mechanics of the report ``start``, and with the
    mechanics refitted from there; beside the nominal fit of the report ``own`` (the
    trace's own row) where given."""
    base = Plant("real", fidelity="reduced")
    td, _ = on_base(load_measurement(trace), base)
    model = NominalModel(base)
    pb = TraceProblem([td], model)
    names = list(model.names)
    fitted = json.loads(start.read_text())["parameters"]["nominal"]
    x = np.array([math.log(fitted[n]["value"]) for n in names])
    x[names.index("amplifier_slew")] = math.log(amp[0])
    x[names.index("amplifier_current")] = math.log(amp[1])
    eff = {"amplifier_lag": {"ratio": amp[2]}}
    r = pb.residual(x, eff, "fit")
    pb.weight = 1.0 / (max(pb.rms(x, eff, "fit"), td.floor) * math.sqrt(correlation_length(r)))
    out = {"at_start_mechanics_nm": pb.rms(x, eff, "heldout")}
    mech = [n for n in names if not n.startswith("amplifier")]
    fit = local_fit(pb, x, eff, free_nominal=mech, max_nfev=60)
    out["mechanics_refitted_nm"] = fit.heldout_rms
    if own is not None:
        row = json.loads(own.read_text())["parameters"]["nominal"]
        xo = np.array([math.log(row[n]["value"]) for n in names])
        out["row_nominal_fit_nm"] = pb.rms(xo, {}, "heldout")
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clean-report", type=Path, required=True, help="the clean row's report.json")
    ap.add_argument("--slow-report", type=Path, help="the slower amplifier row's report.json")
    args = ap.parse_args(argv)
    for p in (TRACE, CLEAN, args.clean_report, args.slow_report):
        if p is not None and not p.exists():
            print(f"{p}: no such file", file=sys.stderr)
            return 2
    found = match_amplifier(TRACE)
    for label, (sl, cur, lag, rms) in found.items():
        print(f"plant's {label} amplifier: model slew ×{sl:.3g}, current ×{cur:.3g}, "
              f"lag ratio {lag:.3g}: {rms:.3g} V RMS left")  # fmt: skip
    runs = [
        ("clean", CLEAN, found["nominal"], args.clean_report, args.clean_report),
        ("slower-amplifier", TRACE, found["slow"], args.clean_report, args.slow_report),
    ]
    for label, trace, amp, start, own in runs:
        res = mechanics_under(trace, amp, start, own)
        print(f"{label} trace, the plant's amplifier matched, the clean row's mechanics: "
              f"{res['at_start_mechanics_nm']:.1f} nm held out; mechanics refitted: "
              f"{res['mechanics_refitted_nm']:.1f} nm", end="")  # fmt: skip
        if "row_nominal_fit_nm" in res:
            print(f"; the row's own nominal fit: {res['row_nominal_fit_nm']:.1f} nm", end="")
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
