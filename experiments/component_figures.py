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

import numpy as np

from turntable_env.amplifier import Amplifier, measure_slew_rate
from turntable_env.detector import Detector
from turntable_env.drive import DriveSignal, sawtooth
from turntable_env.friction import GMS, StribeckParams
from turntable_env.friction.experiments import (
    drift_test,
    presliding_hysteresis,
    thesis_drift_models,
)
from turntable_env.params import real_parameters


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

    # Fig. 2.8: GMS steady sliding vs the Stribeck curve
    gms = GMS(stribeck=StribeckParams(0.3, 0.05, 0.8, 2.0, 0.0))
    vs = np.geomspace(1e-3, 5.0, 12)
    steady = []
    for v in vs:
        n = max(30000, int(np.ceil(5 * 7.5e-3 / v / 1e-4)))
        steady.append(gms.simulate_velocity(np.full(n, v), 1e-4, 100.0).force[-1])
    curve = gms.stribeck.curve(vs, 100.0)
    res["gms_vs_stribeck_max_rel_error"] = float(np.max(np.abs(np.array(steady) / curve - 1)))

    # Fig. 2.9
    h = presliding_hysteresis(steps_per_delta=2000)
    res["hysteresis_loop_closure_N"] = h.loop_closure_error
    res["hysteresis_outer_curve_error_N"] = h.outer_curve_error
    res["hysteresis_width_N"] = h.hysteresis_width

    # Fig. 2.10
    breedveld, gms_d = thesis_drift_models()
    b, g = drift_test(breedveld), drift_test(gms_d)
    res["drift_per_cycle_breedveld_m"] = b.drift_per_cycle
    res["drift_per_cycle_gms_m"] = g.drift_per_cycle

    # §4.1.2 amplifier
    amp = Amplifier()
    c2 = 2 * p.tube.quadrant.capacitance
    for step in (1.0, 3.0):
        r = amp.step_response(0.0, step, load_capacitance=c2)
        res[f"slew_{step:g}V_step_V_per_us"] = (
            measure_slew_rate(r.time, r.output, 0, 45 * step) / 1e6
        )
    r = amp.step_response(-10.0, 10.0, duration=400e-6)
    res["slew_900V_10_90_V_per_us"] = measure_slew_rate(r.time, r.output, -450, 450) / 1e6
    res["slew_900V_peak_V_per_us"] = float(np.max(np.diff(r.output) / np.diff(r.time))) / 1e6
    d = DriveSignal(amplitude=2.0, frequency=100.0, a=0.95, n_periods=2, slew_adaptation=1.0)
    t = np.arange(0.0, 0.02, 1e-8)
    ra = amp.simulate(t, d.input_voltage(t, amp, c2), c2)
    m = (t >= 0.0095) & (t < 0.0105)
    res["slew_adapted_k1_V_per_us"] = measure_slew_rate(t[m], ra.output[m], 90, 0) / 1e6
    res["amplifier_tau_s"] = amp.tau

    # §4.1.3 detector
    det = Detector()
    res["detector_0.53V_um"] = float(det.table_displacement(0.53)) * 1e6
    res["detector_1.19V_um"] = float(det.table_displacement(1.19)) * 1e6

    print(json.dumps(res, indent=2))

    if args.out is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        args.out.mkdir(parents=True, exist_ok=True)
        fig, ax = plt.subplots()
        vv = np.linspace(-2, 2, 801)
        ax.plot(vv, gms.stribeck.curve(vv, 100.0), label="Stribeck s(v), Eq. 2.13")
        ax.plot(vs, steady, "o", label="GMS steady sliding")
        ax.set(xlabel="v [m/s]", ylabel="F [N]", title="Fig. 2.8")
        ax.legend()
        fig.savefig(args.out / "fig2_8_stribeck.png", dpi=120)
        fig, ax = plt.subplots()
        h.reference.plot(ax, x="displacement")
        h.with_inner_loop.plot(ax, x="displacement")
        ax.set_title("Fig. 2.9: presliding hysteresis, inner loop")
        fig.savefig(args.out / "fig2_9_hysteresis.png", dpi=120)
        fig, axs = plt.subplots(2, 1, sharex=True)
        axs[0].plot(b.response.time, b.response.applied_force)
        axs[0].set_ylabel("applied force [N]")
        axs[1].plot(b.response.time, b.response.displacement, label="Breedveld")
        axs[1].plot(g.response.time, g.response.displacement, label="GMS")
        axs[1].set(xlabel="time [s]", ylabel="displacement [m]")
        axs[1].legend()
        axs[0].set_title("Fig. 2.10: drift test")
        fig.savefig(args.out / "fig2_10_drift.png", dpi=120)
        fig, ax = plt.subplots()
        ts = np.linspace(0, 5, 5001)
        ax.plot(ts, sawtooth(ts, 100.0, 1.0, 0.95, 1.0, 4.0))
        ax.set(xlabel="time [s]", ylabel="V", title="Fig. 3.14: sawtooth 100 V, 1 Hz, a = 0.95")
        fig.savefig(args.out / "fig3_14_sawtooth.png", dpi=120)
        fig, ax = plt.subplots()
        for step in (1.0, 3.0):
            r = amp.step_response(0.0, step, load_capacitance=c2)
            ax.plot(r.time * 1e6, r.output, label=f"{step:g} V input step")
        ax.plot((t[m] - 0.0095) * 1e6, ra.output[m], label="adapted flyback 90 V -> 0")
        ax.set(
            xlabel="time [us]", ylabel="output [V]", xlim=(0, 100), title="Fig. 4.2/4.3: HVA 900"
        )
        ax.legend()
        fig.savefig(args.out / "fig4_2_amplifier.png", dpi=120)
        print(f"figures written to {args.out}")


if __name__ == "__main__":
    main()
