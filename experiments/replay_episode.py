"""Replay one benchmark episode of a step controller and print it interval by interval.

    python experiments/replay_episode.py CONTROLLER PLANT_SET TASK SEED [--from K] [--seeds N]
        [--suite-seed S]

The episode is the benchmark's own (``controllers.benchmark``: the same plant draw, start,
reference, brief and noise draws for that seed; ``--seeds`` is the cell's seed count, which
the noise array is drawn for: 20, or 3 for ``full_3d`` and 5 for ``independent``), run
alone (``--suite-seed``: another draw of the suite, as ``turntable benchmark --suite-seed``).
It prints the plant draw, then from interval ``--from`` on: the true error θ − r
and the reading's at R_table [µm] (the true angle is evaluation only: the controller sees
the reading), the controller's mode and action (amplitude [V], frequency [Hz], scan
offset [V]), and at the end whether the hold window was met, the scan's lost motion the
controller learnt (``StepScanController.dead_band``) and its step gains per amplitude.
Evaluation and diagnosis only; the benchmark itself is ``turntable benchmark``.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from controllers import make
from controllers.base import ControllerContext
from controllers.benchmark import SUITE_SEED
from controllers.blind import BLIND_PATH, BlindSettings
from controllers.metrics import BAND, HOLD
from controllers.plant_sets import PLANT_SETS
from controllers.tasks import TASKS
from turntable_env.envs.config import OBS, EnvConfig
from turntable_env.envs.core import TurntableTask

# the step controllers, which take a blind set (controllers.blind)
STEP = ("closed_loop", "feedforward", "fuzzy")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("controller")
    ap.add_argument("plant_set", choices=sorted(PLANT_SETS))
    ap.add_argument("task", choices=sorted(TASKS))
    ap.add_argument("seed", type=int)
    ap.add_argument("--from", dest="start", type=int, default=0, help="first interval printed")
    ap.add_argument("--seeds", type=int, default=20, help="the cell's seed count")
    ap.add_argument("--suite-seed", type=int, default=SUITE_SEED,
                    help=f"the suite's seed (default: the committed suite's {SUITE_SEED})")
    ap.add_argument("--blind", choices=("default", "first"), default="default",
                    help="the blind set a step controller steps with beyond the detector "
                         "(controllers.blind: ASYMMETRY_PATH, the default, or BLIND_PATH, "
                         "the default until stop 101)")
    args = ap.parse_args(argv)
    if not 0 <= args.seed < args.seeds:
        ap.error(f"seed={args.seed}: must lie in [0, --seeds={args.seeds})")
    pset, task = PLANT_SETS[args.plant_set](), TASKS[args.task]
    cfg = EnvConfig(plant=pset.base, axis="B", terminate_on_success=False, detector_y=True)
    ctx = ControllerContext.from_config(cfg)
    det = cfg.parameter_set.detector
    spec = task.episode(args.seed, det, args.suite_seed)
    plant, draw = pset.plant(args.seed, args.suite_seed)
    print("plant draw:", {k: (round(v, 4) if isinstance(v, float) else v) for k, v in draw.items()})
    sim = TurntableTask(cfg, 1)
    sim.reset_row(0, np.random.default_rng([args.suite_seed, args.seed, 1]), spec.options(),
                  plant=plant)  # fmt: skip
    if args.blind == "first" and args.controller not in STEP:
        ap.error(f"--blind first: controller must be one of {', '.join(STEP)}")
    ctl = make(args.controller, ctx)
    if args.blind == "first":
        ctl = type(ctl)(ctx, blind_settings=BlindSettings.load(BLIND_PATH))
    obs = sim.observation()
    ctl.reset(obs[0], spec.brief)
    # the cell's noise draws (one column per seed), as the benchmark draws them
    shape = (task.horizon, args.seeds)
    noise = np.random.default_rng([args.suite_seed, 2]).standard_normal(shape)
    noise_y = np.random.default_rng([args.suite_seed, 3]).standard_normal(shape)
    um = det.table_radius * 1e6
    t_end, err = task.horizon * cfg.control_interval, []
    for k in range(task.horizon):
        true = (sim.angle[0] - sim.target[0]) * um
        read = (float(obs[0, OBS.measured_angle_rad]) - sim.target[0]) * um
        action = ctl.act(obs[0])
        amp, freq, _a, _k, offset = cfg.scaling.decode(action)
        if k >= args.start:
            print(f"{k:4d}  θ−r {true:+9.4f}  reading−r {read:+9.4f}  {ctl.mode:4s}  "
                  f"A {amp:+6.2f} V  f {freq:6.0f} Hz  offset {offset:+6.2f} V")  # fmt: skip
        normals = np.array([[noise[k, args.seed], noise_y[k, args.seed]]])
        res = sim.step(action[None, :], np.random.default_rng(0), normals=normals)
        obs = res.obs
        err.append((res.info["angle_rad"][0] - res.info["target_rad"][0]) * um)
    t = np.arange(1, task.horizon + 1) * cfg.control_interval
    hold = np.abs(np.array(err)[t >= t_end - HOLD - 1e-12])
    print(f"hold window met: {bool((hold <= BAND * 1e6).all())} (largest |θ − r| there "
          f"{hold.max() * 1e3:.1f} nm, band {BAND * 1e9:.0f} nm)")
    if hasattr(ctl, "dead_band"):
        print("lost motion at the hand-over [V] per offset direction:",
              {d: round(v, 3) for d, v in ctl.dead_band.items()})  # fmt: skip
    if hasattr(ctl, "linearity"):
        k, sd, ok = ctl.linearity.estimate()
        print(f"detector linearity: κ̂ = {k:+.4f} ± {sd:.4f}, {'decided' if ok else 'undecided'}"
              f" ({ctl.linearity.dithers} dithers read, {ctl.linearity.rejected} not)")
        for m2, g in ctl.linearity.slopes():
            print(f"  dither at m² = {m2:.3f}: slope {g / ctx.scan_gain:.4f} × the nominal K")
    if getattr(ctl, "gains", None) is not None:
        for d in (1, -1):
            print(f"step gains, direction {d:+d}:",
                  {a: round(g, 3) for a, g in sorted(ctl.gains.gain[d].items())})  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
