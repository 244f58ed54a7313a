"""Linear analysis of the scan-mode loop with python-control (issue 6).

Prints the stick plant (amplifier input → table angle) from the real parameters: its
DC gain, first resonance and damping; the sine sweep on the nonlinear simulators
(reduced and full 3-D) against python-control's prediction up to the first resonance;
the scan PID's gains and margins on the sampled plant. ``--out DIR`` writes the Bode
plot of the plant with the sweep points and the Bode plot of the scan loop.

    python experiments/scan_loop_analysis.py [--axis B] [--out DIR]   (prints its wall time)
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import control as ct
import numpy as np

from controllers.base import ControllerContext
from controllers.scan_pid import pid_transfer_function
from turntable_env.envs.config import EnvConfig
from turntable_env.linear import scan_plant, sine_sweep, stick_plant

FREQS = np.array([10.0, 30.0, 100.0, 300.0, 1000.0, 2000.0, 3000.0, 4000.0, 4500.0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--axis", default="B")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    plant = stick_plant("real", args.axis)
    p_angle = plant[0, 0]
    k0 = float(ct.dcgain(p_angle))
    poles = ct.poles(p_angle)
    osc = poles[np.abs(poles.imag) > 0]
    first = osc[np.argmin(np.abs(osc))]
    f_res = abs(first) / (2 * math.pi)
    zeta = -first.real / abs(first)
    print(f"stick plant, axis {args.axis}: {plant.nstates} states")
    print(f"  DC gain θ/u_in = {k0 * 1e6:.3f} µrad/V ({k0 * 0.01 * 1e9:.1f} nm/V at R_table)")
    print(f"  first resonance {f_res:.0f} Hz, damping ratio {zeta:.4f}")
    print("sine sweep (0.02 V input, every element stuck) vs python-control |θ/u|:")
    print("  f [Hz]   reduced/model − 1   full/model − 1")
    red = sine_sweep("real", args.axis, FREQS, fidelity="reduced")
    full = sine_sweep("real", args.axis, FREQS, fidelity="full")
    pred = np.abs(ct.frequency_response(p_angle, 2 * math.pi * FREQS).complex).ravel()
    for f, r, q, p in zip(FREQS, red.magnitude, full.magnitude, pred, strict=True):
        print(f"  {f:7.0f}   {r / p - 1:+.4f}            {q / p - 1:+.4f}")
    below = FREQS < f_res
    e_red = np.max(np.abs(red.magnitude / pred - 1)[below])
    e_full = np.max(np.abs(full.magnitude / pred - 1)[below])
    print(
        f"  largest |error| below the resonance: reduced {e_red:.2%}, full {e_full:.2%}; "
        f"all stuck: {red.all_stuck and full.all_stuck}"
    )
    ctx = ControllerContext.from_config(EnvConfig(axis=args.axis))
    g = ctx.pid_gains
    pd = scan_plant(plant, ctx.control_interval)[0, 0]
    print(f"scan loop (Δt = {ctx.control_interval * 1e3:g} ms, offset ramped per interval):")
    print(f"  sampled plant DC gain {float(ct.dcgain(pd)) * 1e6:.3f} µrad/V")
    print(
        f"  PID: k_p = {g.kp:.4g} V/rad, k_i = {g.ki:.4g} V/(rad·s), k_d = {g.kd:.4g} V·s/rad "
        f"(normalised k_i·K·Δt = {g.ki * k0 * g.dt:.3f})"
    )
    print(
        f"  margins: phase {g.phase_margin:.1f} deg, gain {g.gain_margin:.2f} "
        f"({20 * math.log10(g.gain_margin):.1f} dB), stability min|1+L| {g.stability_margin:.3f}, "
        f"crossover {g.crossover:.1f} rad/s"
    )
    print(
        f"  detector-noise gain Σt² = {g.noise_gain:.3f}: angle noise "
        f"{math.sqrt(g.noise_gain):.2f}× the reading's"
    )
    if args.out:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        fig, ax = plt.subplots(figsize=(7, 4))
        red.plot(plant, ax=ax)
        ax.loglog(full.frequencies, full.magnitude, "x", label="sine sweep, full 3-D model")
        ax.legend()
        ax.set_title(f"stick plant, axis {args.axis}: amplifier input → table angle")
        fig.savefig(out / "stick_plant_sweep.png", dpi=100)
        plt.figure()
        loop = ct.series(pid_transfer_function(g), pd)
        loop.name = "scan loop C·P"
        ct.bode_plot(
            loop,
            title=f"scan loop C·P: PM {g.phase_margin:.1f}°, GM {g.gain_margin:.2f} "
            f"(at Nyquist), min|1+L| {g.stability_margin:.2f}",
        )
        plt.savefig(out / "scan_loop_bode.png", dpi=100)
        print(f"plots in {out}")
    print(f"wall time {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
