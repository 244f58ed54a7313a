"""The calibrator against virtual-lab data with one undeclared effect each (issue 8).

For the cases of tests/test_calibrate.py (standard protocol, 1 mV detector noise,
seed 1) plus clean data and creep + drift together: prints the effects selected, the
held-out error before and after [nm at R_table], their ratio, whether a structured
residual remains, and the wall time of each calibration.

    python experiments/calibration_effects.py        (about 4 minutes)
"""

from __future__ import annotations

import time

from turntable_env.calibration.calibrate import calibrate
from turntable_env.calibration.virtual_lab import run_virtual_lab
from turntable_env.effects import CATALOGUE

CASES: list[dict[str, dict[str, float]]] = [
    {},
    {"amplifier_dynamics": CATALOGUE["amplifier_dynamics"].defaults()},
    {"piezo_hysteresis": CATALOGUE["piezo_hysteresis"].defaults()},
    {"piezo_creep": {"gamma": 0.04}},
    {"friction_asymmetry": CATALOGUE["friction_asymmetry"].defaults()},
    {"friction_wear": {"beta": 0.3}},
    {"axis_misalignment": CATALOGUE["axis_misalignment"].defaults()},
    {"detector_nonlinearity": {"kappa": 0.25}},
    {"sensor_drift": CATALOGUE["sensor_drift"].defaults()},
    {"vibration": CATALOGUE["vibration"].defaults()},
    {"piezo_creep": {"gamma": 0.02}, "sensor_drift": {"offset": 0.0, "rate": 0.1}},
]


def main() -> None:
    print(
        "| effects on (undeclared) | selected | before [nm] | after [nm] | ratio | "
        "structured | wall [s] |"
    )
    print("|---|---|---:|---:|---:|---|---:|")
    for eff in CASES:
        m = run_virtual_lab("standard", eff, noise_std=1e-3, seed=1)
        t0 = time.perf_counter()
        r = calibrate([m], progress=None)
        wall = time.perf_counter() - t0
        print(
            f"| {', '.join(eff) or 'none (clean)'} | {', '.join(r.selected_effects) or 'none'} | "
            f"{r.error_before:.2f} | {r.error_after:.2f} | {r.error_before / r.error_after:.1f} | "
            f"{r.residual_structured} | {wall:.1f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
