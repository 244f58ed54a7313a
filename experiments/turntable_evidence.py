"""Evidence for the assembled 3-D turntable (issue 3): prints every figure the README quotes.

    python experiments/turntable_evidence.py            # about 2 minutes on one core
    python experiments/turntable_evidence.py --out DIR  # also the plots

0. The unloaded real tube: free contact travel, axial strain, coupling counted twice.
1. Table D.2: one-directional steps about B, two-directional return (cycle minima).
2. Real parameters: steps about A, B, C, Z for both signs; 90 V steps beside the
   measured 0.37 µm (one-directional) and 0.30 µm (two-directional).
3. Unadapted vs adapted vs ideal amplifier.
4. Energy closure over 1 s of stepping (the standard scenario), and its real-time factor.
5. Convergence: step size at dt·ω_max = 0.1, 0.05, 0.025.
6. Drift in stick after the ring-down.
7. A diverging run stops with an error naming the time and the state.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from turntable_env.model import AXES, SimulationError, TurntableModel
from turntable_env.simulation import cycle_minima, simulate, stepping_drive


def free_travel() -> None:
    print("0. Real tube at 90 V, unloaded (what bounds the step)")
    tube = stepping_drive("real")[1].tube
    q = tube.quadrant
    lever = tube.seat_height + tube.outer_radius  # tube end face -> contact point [m]
    travel = q.tip_deflection(90.0) + q.tip_angle(90.0) * lever
    print(
        f"   ball seat {tube.seat_height * 1e3:.2f} mm, end face -> contact {lever * 1e3:.2f} mm; "
        f"free contact travel {travel * 1e6:.3f} um "
        f"(tip {q.tip_deflection(90.0) * 1e6:.3f} + rotation {q.tip_angle(90.0) * lever * 1e6:.3f})"
    )
    print(f"   mean axial strain x L at 90 V: {0.25 * q.free_elongation(90.0) * 1e9:.1f} nm")
    # the piezo element of Fig. 3.8a in series with the spring would add its own compliance
    piezo_rot = q.compliance_matrix[0, 0] / tube.bending_lever**2  # rad/(N*m)
    k_rot = tube.K_rot_bending
    softening = 1.0 - 1.0 / (1.0 + k_rot * piezo_rot)
    print(f"   counting the PZT compliance twice would soften bending by {softening:.0%}")


def thesis_set(out: Path | None) -> None:
    print("1. Table D.2 (thesis set; ideal amplifier, Fig. 3.14 sawtooth, 90 V)")
    for f in (2.0, 1.0):
        drive, ps = stepping_drive("thesis", periods=5, frequency=f)
        r = simulate(ps, drive, axis="B", output_dt=1e-3)
        steps = r.steps / ps.table.radius * 1e3
        print(f"   {f:.0f} Hz one-directional steps about B [mrad]: {np.round(steps, 3).tolist()}")
    drive, ps = stepping_drive("thesis", periods=5, signal="two", cycles=3)
    r = simulate(ps, drive, axis="B", settle=0.5, output_dt=1e-3)
    mins, exc = cycle_minima(r, drive)
    spread = (max(mins) - min(mins)) / exc
    back = (r.angle()[-1] - r.angle()[0]) / exc
    minima = np.round(np.array(mins) * 1e3, 3).tolist()
    print(f"   2 Hz two-directional, 3 cycles: cycle minima {minima} mrad")
    print(f"   spread {spread:.2%} of the excursion {exc * 1e3:.2f} mrad (thesis: < 0.5 %)")
    print(f"   end - start {back:+.2%} of the excursion")
    print(f"   energy closure {r.energy_closure:.1e}")
    if out:
        import matplotlib.pyplot as plt

        ax = r.plot()
        ax[0].set_title("Table D.2, two-directional about B (cf. Fig. 4.10)")
        plt.gcf().savefig(out / "thesis_two_directional.png", dpi=100)
        plt.close("all")


def real_set(out: Path | None) -> None:
    print("2. Real parameters (Table D.1 + data/real_unlisted.toml), 2 V input = 90 V, 100 Hz")
    _, ps = stepping_drive("real", amplifier="adapted")
    model = TurntableModel(ps)
    for axis in AXES:
        row = []
        for sign in (1.0, -1.0):
            drive, _ = stepping_drive(ps, amplitude=2.0 * sign, periods=5)
            r = simulate(ps, {axis: drive}, axis=axis, model=model)
            row.append(f"{np.mean(r.steps) * 1e6:+.3f}")
        print(f"   axis {axis}: mean step +2 V {row[0]} um, -2 V {row[1]} um")
    for signal, measured in (("one", 0.37), ("two", 0.30)):
        drive, _ = stepping_drive(ps, periods=5, signal=signal, cycles=1)
        r = simulate(ps, drive, axis="B", model=model)
        print(
            f"   {signal}-directional about B: step {r.step_size * 1e6:.3f} um "
            f"(measured {measured:.2f} um, model/measured {r.step_size * 1e6 / measured:.2f}); "
            f"steps {np.round(r.steps * 1e6, 3).tolist()}"
        )
        if signal == "one":
            a_end = r.angles[-1]
            print(
                f"   cross-talk at the end: about A {a_end[0] / a_end[1]:+.1%}, "
                f"about C {a_end[2] / a_end[1]:+.1%} of the rotation about B"
            )
        if out and signal == "one":
            import matplotlib.pyplot as plt

            ax = r.plot()
            ax[0].set_title("real parameters, one-directional about B (cf. Fig. 4.7)")
            plt.gcf().savefig(out / "real_one_directional.png", dpi=100)
            plt.close("all")


def amplifier_modes() -> None:
    print("3. Amplifier modes (real, B, 5 periods)")
    for mode in ("adapted", "unadapted", "ideal"):
        drive, ps = stepping_drive("real", amplifier=mode, periods=5)
        r = simulate(ps, drive, axis="B")
        print(
            f"   {mode:<9}: step {r.step_size * 1e6:.4f} um, net {r.net_rotation * 1e6:+.3f} urad"
        )


def standard_scenario() -> None:
    print("4. Standard scenario: real, axis B, one-directional 90 V 100 Hz a = 0.95, adapted, 1 s")
    drive, ps = stepping_drive("real", periods=100)
    r = simulate(ps, drive, axis="B", output_dt=1e-4)
    s = r.summary()
    print(
        f"   step {s['step_um']:.4f} um, energy closure {s['energy_closure']:.2e} of the "
        f"exchanged energy ({s['energy_closure_vs_dissipation']:.2e} of the dissipation)"
    )
    print(
        f"   real-time factor {s['realtime_factor']:.4f} ({s['wall_s']:.1f} s wall for 1 s, "
        f"{s['n_steps']} steps of {s['dt_s'] * 1e9:.0f} ns)"
    )


def convergence() -> None:
    print("5. Convergence (real, B, 6 periods): step size vs integration step")
    drive, ps = stepping_drive("real", periods=6)
    model = TurntableModel(ps)
    prev = None
    for f in (0.1, 0.05, 0.025):
        r = simulate(ps, drive, axis="B", dt_factor=f, model=model)
        change = "" if prev is None else f", change {abs(r.step_size / prev - 1):.3%}"
        dt_ns = r.info["dt"] * 1e9
        print(f"   dt = {f}/omega_max = {dt_ns:.1f} ns: step {r.step_size * 1e6:.5f} um{change}")
        prev = r.step_size


def drift() -> None:
    print("6. Drift in stick (real, 3 steps about B, then 0 V)")
    drive, ps = stepping_drive("real", periods=3)
    r = simulate(ps, drive, axis="B", settle=0.17, output_dt=1e-5)
    step = r.step_size / r.table_radius
    a, t = r.angle(), r.time
    for settle in (0.0, 0.02, 0.06):
        t0 = drive.duration + settle
        w = a[(t >= t0) & (t <= t0 + 0.1)]
        print(
            f"   0.1 s window from {settle * 1e3:.0f} ms after the drive: excursion "
            f"{np.ptp(w) / step:.2e} steps, change {(w[-1] - w[0]) / step:+.2e} steps"
        )
    # the ring-down: dominant frequency and decay time over 10-40 ms after the drive
    t0 = drive.duration
    w = a[(t >= t0 + 0.01) & (t < t0 + 0.04)]
    spec = np.abs(np.fft.rfft((w - w.mean()) * np.hanning(w.size)))
    f_ring = np.fft.rfftfreq(w.size, t[1] - t[0])[1 + np.argmax(spec[1:])]
    p1 = np.ptp(a[(t >= t0 + 0.01) & (t < t0 + 0.015)])
    p2 = np.ptp(a[(t >= t0 + 0.03) & (t < t0 + 0.035)])
    print(f"   ring-down: {f_ring / 1e3:.1f} kHz, decay time {0.02 / np.log(p1 / p2) * 1e3:.1f} ms")


def divergence() -> None:
    print("7. Divergence: a step of 20 us, far beyond the stability limit")
    drive, ps = stepping_drive("real", periods=1)
    try:
        simulate(ps, drive, axis="B", dt=2e-5)
    except SimulationError as exc:
        print(f"   SimulationError: {exc}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=None, help="write plots here")
    args = p.parse_args()
    if args.out:
        import matplotlib

        matplotlib.use("Agg")
        args.out.mkdir(parents=True, exist_ok=True)
    free_travel()
    thesis_set(args.out)
    real_set(args.out)
    amplifier_modes()
    standard_scenario()
    convergence()
    drift()
    divergence()


if __name__ == "__main__":
    main()
