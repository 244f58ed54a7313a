"""Where the 3-D model's direction asymmetry comes from (issue 32, item 1).

Each channel drives one quadrant of two tubes (§3.1, the quadrant wiring), so besides
bending them it lengthens them: 0.656 nm per channel volt along each tube, into the
sphere. This script steps the 3-D model both ways (90 V on the tubes, 100 Hz, a = 0.95,
adapted amplifier, 3 periods, the reduced model's standard case) as it is and with that
axial part of every tube's free displacement per volt removed (bending kept), and prints
the mean |step| per period of each direction beside the reduced model's.

    python experiments/axial_stroke.py
"""

from __future__ import annotations

import sys

import numpy as np
from sphere_tilt import remove_axial_stroke  # this directory is on sys.path

from turntable_env.reduced import ReducedModel, simulate_reduced
from turntable_env.simulation import simulate, stepping_drive


def steps_nm(model, ps) -> list[float]:  # type: ignore[no-untyped-def]
    out = []
    for sign in (1.0, -1.0):
        drive, _ = stepping_drive(ps, amplitude=2.0 * sign, frequency=100.0, periods=3, a=0.95,
                                  amplifier="adapted")  # fmt: skip
        r = simulate(ps, drive, axis="B", model=model, coarse_factor=0.5, output_dt=1e-5)
        out.append(1e9 * r.step_size)
    return out


def ramp_end_normal_forces(model, ps) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    """Normal forces [N] of the driving contacts (tubes A, C) at 0.94 of the second period,
    the end of the ramp, for +90 V and −90 V."""
    out = []
    for sign in (1.0, -1.0):
        drive, _ = stepping_drive(ps, amplitude=2.0 * sign, frequency=100.0, periods=3, a=0.95,
                                  amplifier="adapted")  # fmt: skip
        raw = model.run({"B": drive}, 0.03, coarse_factor=0.5, output_dt=1e-5)
        i = int(np.searchsorted(raw["state"][:, 0], 0.0194))
        out.append(raw["contact"][i, [0, 2], 0])
    return out


def main() -> int:
    drive, ps = stepping_drive("real", amplitude=2.0, frequency=100.0, periods=3, a=0.95,
                               amplifier="adapted")  # fmt: skip
    rm = ReducedModel(ps, "B")
    reduced = 1e9 * simulate_reduced(ps, drive, model=rm, output_dt=1e-5).step_size
    ar = rm.full.packed
    axial = []
    for k in range(3):
        d = ar["d_nom"][k]
        q = (ar["qchan"][k] == 1) * ar["qsign"][k]  # channel B's quadrants on tube k
        xi = np.linalg.solve(ar["ktop"][k], ar["bcoup"][k] @ q)
        axial.append(1e9 * float(d @ xi[3:]))
    print("axial stroke per channel-B volt [nm/V], tubes A, B, C: "
          + ", ".join(f"{a:.3f}" for a in axial))  # fmt: skip
    s_as_is = steps_nm(rm.full, ps)
    fn_pos, fn_neg = ramp_end_normal_forces(rm.full, ps)
    remove_axial_stroke(rm.full)  # the translation along each tube, bending kept
    s_bend = steps_nm(rm.full, ps)
    proxy = []  # the per-axis model with each direction's ramp-end normal force as its preload
    for sign, fn in ((1.0, fn_pos), (-1.0, fn_neg)):
        psf = ps.with_factors({"preload": float(np.mean(fn)) / ps.contact.preload})
        drv, psf = stepping_drive(psf, amplitude=2.0 * sign, frequency=100.0, periods=3, a=0.95,
                                  amplifier="adapted")  # fmt: skip
        proxy.append(1e9 * simulate_reduced(psf, drv, model=ReducedModel(psf, "B"),
                                            output_dt=1e-5).step_size)  # fmt: skip
    print(f"3-D model as it is:           +{s_as_is[0]:.1f} nm, -{s_as_is[1]:.1f} nm per period")
    print(f"  normal forces of contacts A, C at the ramp's end (preload "
          f"{ps.contact.preload:g} N): +90 V {fn_pos[0]:.3f}, {fn_pos[1]:.3f} N; "
          f"-90 V {fn_neg[0]:.3f}, {fn_neg[1]:.3f} N")  # fmt: skip
    print(f"3-D model, no axial stroke:   +{s_bend[0]:.1f} nm, -{s_bend[1]:.1f} nm per period")
    print(f"reduced model (symmetric):     {reduced:.1f} nm per period "
          f"({100 * (reduced / np.mean(s_bend) - 1):+.1f} % against the second)")  # fmt: skip
    print(f"reduced model, each direction's mean ramp-end normal force as its preload: "
          f"+{proxy[0]:.1f} nm, -{proxy[1]:.1f} nm per period")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
