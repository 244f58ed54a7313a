"""The controller benchmark (issue 21): every registered controller × plant set × task.

Same run as ``turntable benchmark --out experiments/results/benchmark``: point moves that
need stepping, tracking tasks and a knock on the nominal, randomized, held_out,
calibrated, full_3d and independent plant sets, 20 paired seeds per cell (3 and 5 on the
last two); writes benchmark.json, episodes.csv, leaderboard.md/.html and trajectory plots,
then prints the summary.

    python experiments/controller_benchmark.py [--seeds 20] [--out DIR] [--backend processes]
    python experiments/controller_benchmark.py --summarize [--out DIR]    (from the files)

The summary: the leaderboard, the mean success over each plant set's tasks, the pairs
the benchmark tells apart, the paired differences the README quotes, each plant set's
scan range and detector noise floor, the held-out episodes each controller fails by the
seed's effect, and every run-away beyond the benchmark's bound with its plant draw.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from controllers.base import ControllerContext
    from turntable_env.envs.config import EnvConfig

DEFAULT_OUT = Path(__file__).parent / "results" / "benchmark"
QUOTED = [  # (plant set, task, pair, metric): the paired differences the README quotes
    ("nominal", "point_2um", "closed_loop - sac", "settle_time_s"),
    ("nominal", "point_50um", "feedforward - closed_loop", "settle_time_s"),
    ("nominal", "point_50um", "fuzzy - closed_loop", "settle_time_s"),
    ("nominal", "point_200um", "fuzzy - closed_loop", "settle_time_s"),
    ("nominal", "point_200um", "fuzzy - closed_loop", "energy_per_um_mJ"),
    ("nominal", "back_forth", "feedforward - closed_loop", "tracking_rms_nm"),
    ("nominal", "knock", "fuzzy - closed_loop", "settle_time_s"),
    ("randomized", "scan_ramp", "closed_loop - sac", "success"),
    ("held_out", "scan_ramp", "closed_loop - sac", "success"),
    ("held_out", "edge_5um", "fuzzy - closed_loop", "success"),
    ("nominal", "scan_ramp", "closed_loop - ppo", "tracking_rms_nm"),
    ("nominal", "point_50um", "ppo - sac", "settle_time_s"),
    ("randomized", "scan_ramp", "ppo - sac", "success"),
    ("randomized", "edge_5um", "ppo - sac", "success"),
    ("calibrated", "point_50um", "ppo - sac", "success"),
]


def simulated_scan_range(
    cfg: EnvConfig, ctx: ControllerContext, intervals: int = 5
) -> float:
    """The table's turn [rad] after ``intervals`` control intervals with the scan offset at
    +u_max and the generator idle, from rest at 0, on the config's plant (any fidelity,
    noise-free): the plant's own K·u_max, which its controllers do not know."""
    import numpy as np

    from turntable_env.envs.core import TurntableTask

    sim = TurntableTask(cfg, 1)
    rng = np.random.default_rng(0)
    sim.reset_row(0, rng, {"start_angle": 0.0}, plant=cfg.plant.replace(sensor_noise=0.0))
    action = ctx.scaling.encode(0.0, 100.0, 0.9, 0.0, ctx.input_limit)[None, :]
    for _ in range(intervals):
        sim.step(action, rng)
    return float(sim.angle[0])


def summarize(out: Path) -> None:
    """Print the summary of a benchmark directory (module docstring)."""
    from controllers.base import ControllerContext
    from controllers.metrics import RUNAWAY_LIMIT, noise_floor
    from controllers.plant_sets import PLANT_SETS
    from turntable_env.envs.config import EnvConfig

    doc = json.loads((out / "benchmark.json").read_text(encoding="utf-8"))
    res = doc["results"]
    print((out / "leaderboard.md").read_text(encoding="utf-8"))
    st = doc["settings"]
    slow = {k: round(v) for k, v in st["cell_wall_s"].items() if v > 60}
    print(f"benchmark {doc['version']}: {st['seeds']} seeds per cell, {st['wall_s']:.0f} s "
          f"wall on {st['cpu_count']} cores (cells over a minute: {slow})")  # fmt: skip
    print("\nmean success over each plant set's tasks:")
    for ps, tasks in res.items():
        names = list(next(iter(tasks.values()))["controllers"])
        row = {c: sum(t["controllers"][c]["success"]["mean"] for t in tasks.values()) / len(tasks)
               for c in names}  # fmt: skip
        print(f"  {ps:<11} " + "  ".join(f"{c} {v:.2f}" for c, v in row.items()))
    largest = {}  # the largest run-away of each plant set [µm]
    with (out / "episodes.csv").open(encoding="utf-8") as fh:
        for r in csv.DictReader(fh):
            largest[r["plant_set"]] = max(largest.get(r["plant_set"], 0.0), float(r["runaway_um"]))
    print("largest run-away per plant set: "
          + ", ".join(f"{ps} {v:.1f} µm" for ps, v in largest.items()))  # fmt: skip
    print("\ncells (plant set × task) where a pair's paired 95 % interval excludes 0:")
    for pair, metrics in doc["separations"].items():
        print(f"  {pair}: " + ", ".join(f"{m} {n}" for m, n in metrics.items()))
    print("\nquoted paired differences, mean [95 % interval]:")
    for ps, task, pair, metric in QUOTED:
        if pair not in res.get(ps, {}).get(task, {}).get("paired", {}):
            continue  # a run of other plant sets, tasks or controllers
        v = res[ps][task]["paired"][pair][metric]
        print(f"  {ps}/{task} {pair} {metric}: {v['mean']:+.3g} "
              f"[{v['ci_low']:+.3g}, {v['ci_high']:+.3g}]")  # fmt: skip
    print(
        "\nplant sets: scan range K·u_max the controllers are given (their model's) and the "
        "set's base plant's, simulated; detector range and noise floor at R_table"
    )
    for ps in res:
        cfg = EnvConfig(plant=PLANT_SETS[ps]().base)
        ctx = ControllerContext.from_config(cfg)
        det = cfg.parameter_set.detector
        floor = noise_floor(cfg.plant.sensor_noise, det)
        r_um = det.table_radius * 1e6
        print(f"  {ps:<11} scan range {ctx.scan_range * r_um:.2f} µm "
              f"(plant {simulated_scan_range(cfg, ctx) * r_um:.2f} µm), "
              f"detector ±{det.angle_range * r_um:.2f} µm, "
              f"noise floor {floor * 1e9:.2f} nm")  # fmt: skip
    with (out / "episodes.csv").open(encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    draws = doc["plant_draws"]
    print("\nheld-out episodes failed, by the seed's effect (each effect has 2–3 of 20 seeds):")
    held = [r for r in rows if r["plant_set"] == "held_out"]
    for c in dict.fromkeys(r["controller"] for r in held):
        fails: dict[str, int] = {}
        for r in held:
            if r["controller"] == c and float(r["success"]) < 1.0:
                effect = draws["held_out"][int(r["seed"])]["effect"]
                fails[effect] = fails.get(effect, 0) + 1
        print(f"  {c}: " + ", ".join(f"{k} {v}" for k, v in sorted(fails.items())))
    limit = RUNAWAY_LIMIT * 1e6
    print(f"\nrun-aways (farthest from the reference beyond the start) over {limit:g} µm:")
    for r in rows:
        if float(r["runaway_um"]) > limit:
            d = draws[r["plant_set"]][int(r["seed"])]
            print(f"  {r['plant_set']}/{r['task']} {r['controller']} seed {r['seed']}: "
                  f"{float(r['runaway_um']):.1f} µm; "
                  + ", ".join(f"{k} {v if isinstance(v, str) else round(v, 3)}"
                              for k, v in d.items()))  # fmt: skip
    worst = max(rows, key=lambda r: float(r["runaway_um"]))
    print(f"  largest: {float(worst['runaway_um']):.1f} µm ({worst['plant_set']}/{worst['task']} "
          f"{worst['controller']} seed {worst['seed']})")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--controllers", default=None, help="comma-separated (default: all)")
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--summarize", action="store_true", help="only print the summary of --out")
    ap.add_argument(
        "--backend",
        choices=("auto", "ray", "processes"),
        default=None,
        help="run the cells in parallel (as turntable benchmark --backend)",
    )
    ap.add_argument("--workers", type=int, default=None, help="processes for --backend processes")
    args = ap.parse_args()
    out = Path(args.out)
    if not args.summarize:
        from controllers.benchmark import run_benchmark, write_outputs
        from turntable_env.files import check_writable

        try:  # before the run, not after it: a directory it may not replace is refused now
            check_writable("out", out, directory=True)
        except ValueError as e:
            ap.error(str(e))

        names = args.controllers.split(",") if args.controllers else None
        res = run_benchmark(
            names,
            seeds=args.seeds,
            progress=args.backend is None,
            backend=args.backend,
            workers=args.workers,
        )
        write_outputs(res, out)
    summarize(out)


if __name__ == "__main__":
    main()
