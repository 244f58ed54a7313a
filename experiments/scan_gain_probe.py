"""Can a controller learn the detector's nonlinearity from its own scan? The scan gain's
dependence on the contacts' history, beside the slope change a nonlinear detector makes.

Issue 32 asks for controllers that learn the plant they are on, the scan gain among it.
The held-out plant set's detector nonlinearity (reading θ·(1 + κ·(θ/θ_s)²), |κ| 0.05–0.15)
costs the step controllers their hold band near the detector's edge: at 0.93·θ_s a κ of
0.08 moves the reading by 0.08·0.80·5.7 µm ≈ 370 nm against a 30 nm band. A lab could
measure the detector's local slope with the scan piezo as its ruler — a scan-offset move
Δu turns the stuck table by K·Δu wherever it stands — and fit κ from slopes at two
positions. To hold 30 nm at the edge, κ must be known to about 0.0065, so the slope
to about 1.7 % (D' = 1 + 3κz², 3·0.865 = 2.6 per unit κ).

This script measures the scan gain (angle change ÷ K·Δu) of a probe pair — a scan-offset
move of ``--probe`` V towards the centre, then back, the second leg measured — at three
places on each plant:

* ``fresh z=0.05``: the episode's start, contacts never slipped;
* ``fresh z=0.84``: reset there, contacts never slipped;
* ``stepped z≈0.84``: after stick–slip steps outwards from z = 0.05 to beyond 0.84.

It prints the true table's gain (evaluation-only truth) and the reading's (what a lab has,
noise included), and κ̂ from the two readings' slopes of fresh z=0.05 and stepped z≈0.84,
as a controller arriving at the edge would get it, with the hold error that κ̂ leaves at
0.93·θ_s. Usage: ``python experiments/scan_gain_probe.py [--probe 4] [--seeds 7 15 0 1]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from controllers.base import ControllerContext
from controllers.benchmark import SUITE_SEED
from controllers.plant_sets import PLANT_SETS
from turntable_env.envs.config import OBS, EnvConfig
from turntable_env.envs.core import TurntableTask


def probe_pair(sim, b, scaling, du, n):
    """Second-leg (true, read) angle change per scan volt of a probe pair on row b [rad/V]."""
    out = []
    for u in (du, 0.0):  # towards the centre, then back
        acts = np.tile(scaling.encode(0.0, 100.0, 0.9, 0.0, 0.0), (n, 1))
        acts[b] = scaling.encode(0.0, 100.0, 0.9, 0.0, u)
        res = sim.step(acts, np.random.default_rng([b, len(out)]))
        out.append((res.info["angle_rad"][b], res.obs[b, OBS.measured_angle_rad]))
    (t0, y0), (t1, y1) = out
    return (t1 - t0) / -du, (y1 - y0) / -du


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--probe", type=float, default=4.0, help="probe leg [V] (default 4)")
    ap.add_argument(
        "--seeds", type=int, nargs="+", default=[7, 15, 0, 1],
        help="held-out seeds (default 7 15 0 1: two detector nonlinearities, creep, hysteresis)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    pset = PLANT_SETS["held_out"]()
    cfg = EnvConfig(plant=pset.base, axis="B", terminate_on_success=False)
    ctx = ControllerContext.from_config(cfg)
    k, ths, sc = ctx.scan_gain, ctx.angle_range, ctx.scaling
    rows = [("nominal", pset.base, None)]
    for s in args.seeds:
        plant, draw = pset.plant(s, SUITE_SEED)
        rows.append((f"held_out {s}", plant, draw.get("detector_nonlinearity.kappa")))
    print(f"K = {k:.4g} rad/V, θ_s = {ths:.4g} rad, probe {args.probe:g} V")
    print(
        "| plant | κ drawn | fresh z=0.05 true / read | fresh z=0.84 true / read | "
        "stepped z true / read | κ̂ | hold error at 0.93 θ_s [nm] |\n"
        "|---|---:|---|---|---|---:|---:|"
    )
    radius = ctx.detector.table_radius
    for name, plant, kappa in rows:
        sim = TurntableTask(cfg, 3)
        rng = np.random.default_rng(0)
        for b, z in enumerate((0.05, 0.84, 0.05)):
            sim.reset_row(b, rng, {"start_angle": z * ths, "reference": np.array([z * ths])},
                          plant=plant)  # fmt: skip
        g = [probe_pair(sim, b, sc, -args.probe, 3) for b in (0, 1)]
        # row 2: step outwards (one 4 V period per interval, a = 0.9) until the reading passes 0.80
        z = 0.05
        for _ in range(200):
            acts = np.tile(sc.encode(0.0, 100.0, 0.9, 0.0, 0.0), (3, 1))
            acts[2] = sc.encode(4.0, 100.0, 0.9, 1.0, 0.0)
            res = sim.step(acts, rng)
            z = res.obs[2, OBS.measured_angle_rad] / ths
            if z >= 0.80:
                break
        g.append(probe_pair(sim, 2, sc, -args.probe, 3))
        # κ̂ from the readings' slopes: g_read = K_eff·(1 + 3κ·z²), fresh z=0.05 and stepped z
        z_lo, z_hi = 0.05, z
        ratio = g[2][1] / g[0][1]
        kh = (ratio - 1.0) / (3.0 * (z_hi**2 - ratio * z_lo**2))
        k_true = kappa or 0.0
        th = 0.93 * ths
        err = abs((kh - k_true) * th * (th / ths) ** 2) * radius * 1e9  # first order
        cells = " | ".join(f"{a / k:.4f} / {r / k:.4f}" for a, r in g)
        print(f"| {name} | {k_true:.3f} | {cells} (z={z:.2f}) | {kh:+.4f} | {err:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
