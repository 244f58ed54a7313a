"""Every seed of every agent on the benchmark, and the aggregate across seeds (rliable style).

    python experiments/agent_seeds.py --runs ppo=DIR,DIR,DIR --runs sac=DIR,DIR,DIR \
        [--plant-sets randomized,held_out] [--out experiments/results/agent_seeds]
        [--baselines closed_loop,fuzzy] [--backend auto|ray|processes [--address auto]]

Each run directory becomes a controller ``<label>_s<seed>`` (``turntable benchmark
--agent``); the benchmark runs them on the plant sets (20 paired seeds per cell, every
task) and writes its files to ``--out``. Printed per label and plant set: each seed's
mean success over the tasks, and the interquartile mean (IQM) of the seed × task success
scores with a 95 % interval from a bootstrap over seeds (as rliable recommends for few
runs: the IQM is robust to one outlying seed, the interval says how few there are).
``--baselines`` runs registered controllers beside them on the same plants and seeds, so
the benchmark's paired differences (``separations`` in benchmark.json) compare each seed
with them, e.g. a residual agent with its own base; printed: each baseline's mean success.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import scipy.stats

from agents import register_run
from agents.train import run_config
from controllers.benchmark import run_benchmark, write_outputs
from controllers.registry import spec as controller_spec
from turntable_env.scale import BACKENDS

DEFAULT_OUT = Path(__file__).parent / "results" / "agent_seeds"


def iqm_ci(scores: np.ndarray, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """IQM of a (seeds, tasks) score matrix and its 95 % interval, seeds resampled."""
    rng = np.random.default_rng(seed)
    iqm = float(scipy.stats.trim_mean(scores.ravel(), 0.25))
    boots = [
        scipy.stats.trim_mean(scores[rng.integers(0, scores.shape[0], scores.shape[0])].ravel(),
                              0.25)
        for _ in range(n_boot)
    ]  # fmt: skip
    lo, hi = np.percentile(boots, [2.5, 97.5])
    return iqm, float(lo), float(hi)


PAIRED_METRICS = ("success", "settle_time_s", "tracking_rms_nm", "runaway_um")


def paired_against(cells: dict, a: str, b: str) -> dict:
    """Controller ``a`` against ``b`` on one plant set's tasks (``cells``: the summary's
    task entries): the mean success difference over the tasks, and each task and metric
    whose paired difference's 95 % interval excludes 0 (``separated``), with its mean."""
    success = float(np.mean([c["paired"][f"{a} - {b}"]["success"]["mean"] for c in cells.values()]))
    sep = []
    for task, c in cells.items():
        for metric in PAIRED_METRICS:
            d = c["paired"][f"{a} - {b}"][metric]
            if d["separated"]:
                sep.append(f"{task}: {metric} {d['mean']:+.3g}")
    return {"success": success, "separated": sep}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", action="append", required=True, help="LABEL=DIR,DIR,...")
    ap.add_argument("--plant-sets", default="randomized,held_out")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--baselines", default="",
                    help="registered controllers run beside the agents (paired), comma-separated")
    ap.add_argument("--suite-seed", type=int, default=None,
                    help="another draw of the episodes, plants and noise than the committed "
                         "suite's (a validation draw; turntable benchmark --suite-seed)")
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--backend", choices=BACKENDS, default=None,
                    help="the benchmark's cells as Ray tasks (auto: when installed) or processes")
    ap.add_argument("--address", default=None, help="Ray cluster to join (default: local)")
    args = ap.parse_args()
    if args.suite_seed is not None and not 0 <= args.suite_seed < 2**32:
        ap.error(f"--suite-seed {args.suite_seed}: must be in [0, 2**32)")
    groups: dict[str, list[str]] = {}
    for spec in args.runs:
        label, _, dirs = spec.partition("=")
        for d in (x for x in dirs.split(",") if x):
            try:  # the run's files, checked and named, before any work
                s = run_config(d, f"--runs {label}: {d}")["run"]["seed"]
            except ValueError as exc:
                ap.error(str(exc))
            name = f"{label}_s{s}"
            register_run(name, d)
            groups.setdefault(label, []).append(name)
    baselines = [b for b in args.baselines.split(",") if b]
    for b in baselines:
        try:
            controller_spec(b)  # an unregistered controller, named, before any work
        except ValueError as exc:
            ap.error(f"--baselines: {exc}")
    names = [n for v in groups.values() for n in v] + baselines
    sets = [p for p in args.plant_sets.split(",") if p]
    suite = {} if args.suite_seed is None else {"suite_seed": args.suite_seed}
    res = run_benchmark(names, plant_sets=sets, seeds=args.seeds, progress=args.backend is None,
                        backend=args.backend, address=args.address, **suite)  # fmt: skip
    write_outputs(res, args.out)
    summ = res.summary()
    out: dict[str, dict] = {}
    for label, members in groups.items():
        for ps in sets:
            tasks = list(summ[ps])
            scores = np.array([[summ[ps][t]["controllers"][m]["success"]["mean"] for t in tasks]
                               for m in members])  # fmt: skip
            iqm, lo, hi = iqm_ci(scores)
            per_seed = dict(zip(members, scores.mean(axis=1).round(3).tolist(), strict=True))
            entry = {"iqm": iqm, "ci_low": lo, "ci_high": hi, "per_seed_mean": per_seed}
            out.setdefault(label, {})[ps] = entry
            print(f"{label} on {ps}: IQM success {iqm:.2f} [{lo:.2f}, {hi:.2f}] over "
                  f"{len(members)} seeds × {len(tasks)} tasks; per seed {per_seed}")  # fmt: skip
    for b in baselines:
        for ps in sets:
            cells = [summ[ps][t]["controllers"][b]["success"]["mean"] for t in summ[ps]]
            mean = float(np.mean(cells))
            out.setdefault(b, {})[ps] = {"mean": mean}
            print(f"{b} on {ps}: mean success {mean:.3f}")
            for m in names[: len(names) - len(baselines)]:
                diff = paired_against(summ[ps], m, b)
                out[b][ps][m] = diff
                print(f"  {m} - {b}: success {diff['success']:+.3f}; separated (task: metric "
                      f"difference) {diff['separated'] or 'none'}")  # fmt: skip
    Path(args.out, "aggregate.json").write_text(json.dumps(out, indent=1), encoding="utf-8")
    print(f"{res.settings['wall_s']:.0f} s; files in {args.out}")


if __name__ == "__main__":
    main()
