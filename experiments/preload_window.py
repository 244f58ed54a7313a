"""Why the real set's contacts carry F_N = 2 N: the thesis's slew-rate observation (§4.1.2).

The preload spring of the real turntable is not documented. The thesis reports that with
the unadapted amplifier the table followed the input with no net movement, while the
adapted input (Fig. 4.3) stepped it. This scan prints, for each normal force per contact,
the mean step about B (90 V, 100 Hz, 6 periods) with the adapted, unadapted and ideal
amplifier, and the presliding distance the Hertz–Mindlin derivation gives.

    python experiments/preload_window.py
"""

from __future__ import annotations

from turntable_env.params import real_parameters
from turntable_env.simulation import simulate, stepping_drive

FORCES = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0)  # N per contact


def main() -> None:
    print("F_N [N]  presliding [um]  adapted [um]  unadapted [um]  ideal [um]  unadapted/adapted")
    for fn in FORCES:
        ps = real_parameters({"normal_force": fn})
        fr = ps.friction
        presliding = max(n * fr.stribeck.mu_s * fn / k for n, k in zip(fr.nu, fr.k, strict=True))
        steps = {}
        for mode in ("adapted", "unadapted", "ideal"):
            drive, p2 = stepping_drive(ps, periods=6, amplifier=mode)
            steps[mode] = simulate(p2, drive, axis="B").step_size * 1e6
        print(
            f"{fn:7.1f}  {presliding * 1e6:15.3f}  {steps['adapted']:12.4f}  "
            f"{steps['unadapted']:14.4f}  {steps['ideal']:10.4f}  "
            f"{steps['unadapted'] / steps['adapted']:17.2f}"
        )


if __name__ == "__main__":
    main()
