"""Recreate the component figures of the thesis and print every number the README quotes.

    python experiments/component_figures.py [--out figures/]

Prints (and, with --out, plots): Table D.1 derived values, the Stribeck curve
against GMS steady sliding (Fig. 2.8), presliding hysteresis with nonlocal memory
(Fig. 2.9), the Breedveld-vs-GMS drift test (Fig. 2.10), the sawtooth (Fig. 3.14),
the amplifier slew rates (§4.1.2, Fig. 4.2/4.3) and the detector conversions (§4.1.3).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from turntable_env.detector import Detector
from turntable_env.params import real_parameters
from turntable_env.report.figures import (
    amplifier_figure,
    drift_figure,
    hysteresis_figure,
    sawtooth_figure,
    stribeck_figure,
)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", type=Path, default=None, help="folder for PNG figures")
    args = ap.parse_args()
    res: dict[str, float] = {}

    p = real_parameters()
    res["K_x_N_per_m"] = p.tube.K_bending
    res["K_z_N_per_m"] = p.tube.K_axial
    res["K_phi_Nm"] = p.tube.K_torsion
    res["m_tube_kg"] = p.tube.mass
    res["R_bending_V_Vm"] = p.tube.quadrant.bending_radius_times_voltage
    res["C_quadrant_F"] = p.tube.quadrant.capacitance
    res["tip_deflection_90V_m"] = p.tube.quadrant.tip_deflection(90.0)

    # Figs. 2.8, 2.9, 2.10, 3.14, 4.2/4.3: computed (and drawn) by turntable_env.report
    figs = [stribeck_figure(), hysteresis_figure(), drift_figure(), sawtooth_figure()]
    amp = amplifier_figure()
    figs.append(amp)
    res["gms_vs_stribeck_max_rel_error"] = figs[0].numbers["gms_vs_stribeck_max_rel_error"]
    h = figs[1].numbers
    res["hysteresis_loop_closure_N"] = h["loop_closure_error_N"]
    res["hysteresis_outer_curve_error_N"] = h["outer_curve_error_N"]
    res["hysteresis_width_N"] = h["hysteresis_width_N"]
    res.update(figs[2].numbers)
    a = amp.numbers
    res["slew_1V_step_V_per_us"] = a["slew_1V_step_V_per_s"] / 1e6
    res["slew_3V_step_V_per_us"] = a["slew_3V_step_V_per_s"] / 1e6
    res["slew_900V_10_90_V_per_us"] = a["slew_900V_V_per_s"] / 1e6
    res["slew_900V_peak_V_per_us"] = a["slew_900V_peak_V_per_s"] / 1e6
    res["slew_adapted_k1_V_per_us"] = a["slew_adapted_90V_V_per_s"] / 1e6
    res["amplifier_tau_s"] = a["amplifier_tau_s"]

    # §4.1.3 detector
    det = Detector()
    res["detector_0.53V_um"] = float(det.table_displacement(0.53)) * 1e6
    res["detector_1.19V_um"] = float(det.table_displacement(1.19)) * 1e6

    print(json.dumps(res, indent=2))

    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        for f in figs:
            f.fig.savefig(args.out / f"{f.key}.png", dpi=120)
        print(f"figures written to {args.out}")


if __name__ == "__main__":
    main()
