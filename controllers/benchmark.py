"""The controller benchmark: every registered controller × plant set × task, seeds paired.

Tasks (:mod:`controllers.tasks`): point-to-point moves that need stepping (2 µm, 50 µm and
200 µm, the last two from beyond the detector with a ±30 % dead-reckoned start; 5 µm to
the detector's edge), tracking (a constant-velocity scan, waypoints, back and forth) and
a knock. Plant sets (:mod:`controllers.plant_sets`): ``nominal``, ``randomized`` (the RL
training distribution), ``held_out`` (outside the training ranges, one catalogue effect
each), ``calibrated``, ``full_3d`` and ``independent`` (the independent test plant, a
formulation no controller was designed or trained on).

How a cell (plant set × task) runs: one :class:`~turntable_env.envs.core.TurntableTask`
holds every controller × seed as a row, so the plants advance in one compiled batched call
per control interval (prange over the rows). Seed s is the same episode (start, reference,
knock, dead-reckoned start), the same plant draw and the same detector noise sequence for
every controller (common random numbers), so the differences between controllers are
paired per seed. A controller receives only the observation and its
:class:`~controllers.lab.LabBrief`; the true angle, the plant and its draw stay with the
runner for the metrics (:mod:`controllers.metrics`). Since benchmark 2.3 the observation
has the quadrant photodiode's y channel too (``EnvConfig(detector_y=True)``, its own noise
sequence per seed): what a lab's detector gives, and what an axis misalignment shows on
(the agents, trained on the default 8 components, read those and ignore it).

Output (:class:`BenchmarkResult`): per episode the metrics and the plant draw
(``episodes.csv``); per controller × plant set × task each metric's mean with a 95 %
bootstrap interval, and the paired differences between controllers with theirs
(``benchmark.json``, versioned); a leaderboard (``leaderboard.md``/``.html``) and
trajectory plots per plant set.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from turntable_env.envs.config import OBS, EnvConfig
from turntable_env.envs.core import TurntableTask
from turntable_env.files import output_directory, plain_json, write_atomic
from turntable_env.provenance import provenance
from turntable_env.scale import map_tasks, resolve_backend

from .base import ControllerContext
from .metrics import (
    BAND,
    HOLD,
    METRICS,
    episode_metrics,
    mean_ci,
    noise_floor,
    paired_difference,
)
from .plant_sets import PLANT_SETS, PlantSet
from .registry import available, load_plugins, make, register, spec
from .tasks import TASKS, EpisodeSpec, Task

__all__ = [
    "BENCHMARK_VERSION",
    "DEFAULT_PLANT_SETS",
    "PRIMARY",
    "QUICK",
    "BenchmarkResult",
    "run_benchmark",
    "write_outputs",
]

BENCHMARK_VERSION = "2.4"  # tasks, plant sets and metrics of this protocol; bump on change
SUITE_SEED = 2026
DEFAULT_PLANT_SETS = (
    "nominal", "randomized", "held_out", "calibrated", "full_3d", "independent"
)  # fmt: skip
# the 3-D model runs at ≈ 0.1–0.3× real time (turntable bench): every task at its full
# horizon, but fewer seeds (issue 32: 3 seeds × 6 controllers ≈ 11 min of the run)
FULL_3D_SEEDS = 3
# the independent plant integrates at a fixed 0.25 µs in Python-driven calls per interval
# (≈ 3 ms of CPU per turntable and interval): every task, fewer seeds
INDEPENDENT_SEEDS = 5
PRIMARY = {"point": "settle_time_s", "tracking": "tracking_rms_nm", "disturbance": "settle_time_s"}
QUICK: dict[str, Any] = {
    "seeds": 4,
    "plant_sets": ("nominal", "held_out"),
    "tasks": ("point_2um", "scan_ramp", "knock"),
}


@dataclass(frozen=True)
class Cell:
    """One controller on one plant set × task: per-seed metrics (name → (seeds,)), the
    episodes' records (time (K,), angle/measured/reference (seeds, K), evaluation only)."""

    controller: str
    plant_set: str
    task: str
    metrics: dict[str, np.ndarray]
    time: np.ndarray
    angle: np.ndarray
    measured: np.ndarray
    reference: np.ndarray
    radius: float


@dataclass
class BenchmarkResult:
    """Every cell, the per-seed plant draws and the settings (see the module docstring)."""

    cells: list[Cell]
    draws: dict[str, list[dict[str, Any]]]
    settings: dict[str, Any]
    _summary: dict[str, Any] | None = field(default=None, repr=False)

    def cell(self, plant_set: str, task: str, controller: str) -> Cell:
        for c in self.cells:
            if (c.plant_set, c.task, c.controller) == (plant_set, task, controller):
                return c
        raise ValueError(f"no cell {plant_set}/{task}/{controller}")

    @property
    def controllers(self) -> list[str]:
        return list(dict.fromkeys(c.controller for c in self.cells))

    def groups(self) -> dict[tuple[str, str], list[Cell]]:
        """(plant set, task) → its cells, one per controller."""
        out: dict[tuple[str, str], list[Cell]] = {}
        for c in self.cells:
            out.setdefault((c.plant_set, c.task), []).append(c)
        return out

    def summary(self) -> dict[str, Any]:
        """plant set → task → {"controllers": {name: {metric: {mean, ci_low, ci_high}}},
        "paired": {"a - b": {metric: {mean, ci_low, ci_high, separated}}}}."""
        if self._summary is not None:
            return self._summary
        out: dict[str, Any] = {}
        for (ps, task), cells in self.groups().items():
            entry: dict[str, Any] = {"controllers": {}, "paired": {}}
            for c in cells:
                entry["controllers"][c.controller] = {
                    m: mean_ci(v, seed=i) for i, (m, v) in enumerate(c.metrics.items())
                }
            for a, b in itertools.combinations(cells, 2):
                entry["paired"][f"{a.controller} - {b.controller}"] = {
                    m: paired_difference(a.metrics[m], b.metrics[m], seed=i)
                    for i, m in enumerate(a.metrics)
                }
            out.setdefault(ps, {})[task] = entry
        self._summary = out
        return out

    def separations(self) -> dict[str, dict[str, int]]:
        """Pair → metric → number of (plant set, task) cells whose paired 95 % interval
        excludes 0 (the benchmark tells the two apart there)."""
        out: dict[str, dict[str, int]] = {}
        for tasks in self.summary().values():
            for entry in tasks.values():
                for pair, metrics in entry["paired"].items():
                    d = out.setdefault(pair, {m: 0 for m in metrics})
                    for m, v in metrics.items():
                        d[m] += int(v["separated"])
        return out

    def to_json(self) -> dict[str, Any]:
        """The benchmark.json document (non-finite numbers as null)."""
        return plain_json({
            "version": BENCHMARK_VERSION,
            "settings": self.settings,
            "metrics": {m.name: {"unit": m.unit, "lower_is_better": m.lower_is_better,
                                 "meaning": m.meaning} for m in METRICS.values()},
            "results": self.summary(),
            "separations": self.separations(),
            "plant_draws": self.draws,
        })  # fmt: skip

    def to_pandas(self) -> Any:
        """One row per episode: controller, plant_set, task, seed and every metric."""
        import pandas as pd

        rows = []
        for c in self.cells:
            n = next(iter(c.metrics.values())).size
            for s in range(n):
                row = {"controller": c.controller, "plant_set": c.plant_set, "task": c.task}
                row["seed"] = s
                row.update({m: float(v[s]) for m, v in c.metrics.items()})
                rows.append(row)
        return pd.DataFrame(rows)

    def leaderboard(self, fmt: str = "markdown") -> str:
        """Per plant set: controllers × tasks, each cell the success rate and the task's
        primary metric (:data:`PRIMARY`) as mean [95 % interval]; best mean in bold."""
        summ = self.summary()
        blocks = []
        for ps, tasks in summ.items():
            names = list(next(iter(tasks.values()))["controllers"])
            header = ["controller"] + [f"{t} ({_short(PRIMARY[TASKS[t].kind])})" for t in tasks]
            body = []
            for name in names:
                row = [name]
                for t, entry in tasks.items():
                    metric = PRIMARY[TASKS[t].kind]
                    v = entry["controllers"][name][metric]
                    best = min(e[metric]["mean"] for e in entry["controllers"].values())
                    succ = entry["controllers"][name]["success"]["mean"]
                    txt = f"{_g(v['mean'])} [{_g(v['ci_low'])}, {_g(v['ci_high'])}]"
                    if v["mean"] == best:
                        txt = f"**{txt}**" if fmt == "markdown" else f"<b>{txt}</b>"
                    row.append(f"{succ:.0%} · {txt}")
                body.append(row)
            blocks.append((ps, header, body))
        if fmt == "html":
            return _html(blocks, self.settings)
        out = []
        for ps, header, body in blocks:
            out.append(f"### {ps}\n")
            out.append("| " + " | ".join(header) + " |")
            out.append("|" + "---|" * len(header))
            out.extend("| " + " | ".join(r) + " |" for r in body)
            out.append("")
        return "\n".join(out)

    def plot(self, plant_set: str, ax: Any = None) -> Any:
        """Error (θ − r)·R [nm] vs time of the first seed, every task and controller."""
        import matplotlib.pyplot as plt

        groups = {k[1]: v for k, v in self.groups().items() if k[0] == plant_set}
        if ax is None:
            n = len(groups)
            cols = min(4, n)
            _fig, axes = plt.subplots(
                math.ceil(n / cols), cols, figsize=(4.2 * cols, 3.2 * math.ceil(n / cols)),
                squeeze=False,
            )  # fmt: skip
            ax = axes.ravel()
        for a, (task, cells) in zip(ax, groups.items(), strict=False):
            for c in cells:
                err = (c.angle[0] - c.reference[0]) * c.radius * 1e9
                a.plot(c.time, err, label=c.controller, lw=1.0)
            a.set_yscale("symlog", linthresh=10.0)
            a.axhspan(-BAND * 1e9, BAND * 1e9, color="0.9")
            a.set_title(f"{task} ({plant_set})", fontsize=9)
            a.set_xlabel("time [s]")
            a.set_ylabel("(θ − r)·R [nm]")
        ax[0].legend(fontsize=7)
        return ax


def _short(metric: str) -> str:
    return {"settle_time_s": "settle s", "tracking_rms_nm": "RMS nm"}.get(metric, metric)


def _g(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "∞"


def _html(blocks: list[tuple[str, list[str], list[list[str]]]], settings: dict) -> str:
    import html

    parts = [
        "<!doctype html><meta charset='utf-8'><title>turntable benchmark</title>",
        "<style>table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 6px}"
        "</style>",
        f"<h1>turntable benchmark {BENCHMARK_VERSION}</h1>",
        f"<p>{html.escape(json.dumps({k: settings[k] for k in ('seeds', 'band_m', 'hold_s')}))}"
        " — cells: success rate · primary metric mean [95 % bootstrap interval]</p>",
    ]
    for ps, header, body in blocks:
        parts.append(f"<h2>{html.escape(ps)}</h2><table><tr>")
        parts.extend(f"<th>{html.escape(h)}</th>" for h in header)
        parts.append("</tr>")
        for row in body:
            cells = "".join(f"<td>{x if '<b>' in x else html.escape(x)}</td>" for x in row)
            parts.append(f"<tr>{cells}</tr>")
        parts.append("</table>")
    return "\n".join(parts)


# --- running -----------------------------------------------------------------------------
def _task(plant_set: str, name: str) -> Task:
    """The task as run on a plant set (the same on every set)."""
    return TASKS[name]


def _seeds(plant_set: str, seeds: int) -> int:
    """Episodes per cell on a plant set (at most :data:`FULL_3D_SEEDS` on the 3-D model and
    :data:`INDEPENDENT_SEEDS` on the independent plant)."""
    cap = {"full_3d": FULL_3D_SEEDS, "independent": INDEPENDENT_SEEDS}.get(plant_set, seeds)
    return min(seeds, cap)


def _run_cell(
    names: Sequence[str],
    pset: PlantSet,
    task: Task,
    seeds: int,
    axis: str,
    suite_seed: int,
    bar: Any,
) -> tuple[list[Cell], list[dict[str, Any]]]:
    """Every controller on one plant set × task (module docstring)."""
    cfg = EnvConfig(plant=pset.base, axis=axis, terminate_on_success=False, detector_y=True)
    if not math.isclose(cfg.control_interval, 0.01):
        raise ValueError("the task suite is written for a 0.01 s control interval")
    ctx = ControllerContext.from_config(cfg)
    det = cfg.parameter_set.detector
    specs: list[EpisodeSpec] = [task.episode(s, det, suite_seed) for s in range(seeds)]
    plants = [pset.plant(s, suite_seed) for s in range(seeds)]
    n_ctl = len(names)
    sim = TurntableTask(cfg, n_ctl * seeds)
    ctls = [[make(name, ctx) for _ in range(seeds)] for name in names]
    for ci in range(n_ctl):
        for s in range(seeds):
            b = ci * seeds + s
            rng = np.random.default_rng([suite_seed, s, 1])  # the reset reading's noise
            sim.reset_row(b, rng, specs[s].options(), plant=plants[s][0])
    obs = sim.observation()
    for ci in range(n_ctl):
        for s in range(seeds):
            ctls[ci][s].reset(obs[ci * seeds + s], specs[s].brief)
    k_total = task.horizon + 1
    n = n_ctl * seeds
    angle, meas, ref = np.empty((n, k_total)), np.empty((n, k_total)), np.empty((n, k_total))
    steps, energy = np.zeros((n, k_total)), np.zeros((n, k_total))
    angle[:, 0], meas[:, 0], ref[:, 0] = sim.angle, obs[:, OBS.measured_angle_rad], sim.target
    noise = np.random.default_rng([suite_seed, 2]).standard_normal((task.horizon, seeds))
    noise_y = np.random.default_rng([suite_seed, 3]).standard_normal((task.horizon, seeds))
    dummy = np.random.default_rng(0)  # unused: the noise comes from `normals`
    for k in range(task.horizon):
        actions = np.concatenate(
            [
                type(ctls[ci][0]).act_many(ctls[ci], obs[ci * seeds : (ci + 1) * seeds])
                for ci in range(n_ctl)
            ]
        )
        normals = np.stack([np.tile(noise[k], n_ctl), np.tile(noise_y[k], n_ctl)], axis=1)
        res = sim.step(actions, dummy, normals=normals)  # x and y channels
        obs = res.obs
        angle[:, k + 1] = res.info["angle_rad"]
        ref[:, k + 1] = res.info["target_rad"]
        meas[:, k + 1] = obs[:, OBS.measured_angle_rad]
        steps[:, k + 1] = res.info["steps"]
        energy[:, k + 1] = res.info["energy_J"]
        if bar is not None:
            bar.update(1)
    t = np.arange(k_total) * cfg.control_interval
    floor = np.array([noise_floor(p.sensor_noise, det) for p, _d in plants])
    radius = det.table_radius
    cells = []
    for ci, name in enumerate(names):
        rows = slice(ci * seeds, (ci + 1) * seeds)
        metrics = episode_metrics(
            t,
            angle[rows],
            ref[rows],
            steps[rows],
            energy[rows],
            radius=radius,
            noise_floor=floor,
            event=specs[0].event,
        )
        cells.append(Cell(name, pset.name, task.name, metrics, t, angle[rows], meas[rows],
                          ref[rows], radius))  # fmt: skip
    return cells, [d for _p, d in plants]


def run_benchmark(
    controllers: Sequence[str] | None = None,
    *,
    plant_sets: Sequence[str] = DEFAULT_PLANT_SETS,
    tasks: Sequence[str] | None = None,
    seeds: int = 20,
    axis: str = "B",
    suite_seed: int = SUITE_SEED,
    progress: bool = False,
    backend: str | None = None,
    address: str | None = None,
    workers: int | None = None,
) -> BenchmarkResult:
    """Run the benchmark (module docstring).

    Args:
        controllers: registered names (default: all, after :func:`load_plugins`).
        plant_sets: names from :data:`~controllers.plant_sets.PLANT_SETS`; ``full_3d`` runs
            at most :data:`FULL_3D_SEEDS` seeds per cell, ``independent`` at most
            :data:`INDEPENDENT_SEEDS`.
        tasks: names from :data:`~controllers.tasks.TASKS` (default: all).
        seeds: episodes per cell (paired across controllers).
        progress: a tqdm bar over the cells' control intervals (in this process).
        backend: None runs the cells here, one after the other; ``"auto"``, ``"ray"`` or
            ``"processes"`` runs every cell as a Ray task or a process
            (:func:`turntable_env.scale.map_tasks`; ``address`` joins a Ray cluster,
            ``workers`` bounds the processes). The results equal the serial run's: a
            cell's seeds and noise depend only on the suite seed and the cell.
    """
    load_plugins()
    names = list(controllers) if controllers is not None else available()
    known = available()
    for n in names:
        if n not in known:
            raise ValueError(f"controllers: {n!r} not registered (available: {', '.join(known)})")
    for p in plant_sets:
        if p not in PLANT_SETS:
            raise ValueError(f"plant_sets: {p!r} unknown (choose from {', '.join(PLANT_SETS)})")
    task_list = list(tasks) if tasks is not None else list(TASKS)
    for t in task_list:
        if t not in TASKS:
            raise ValueError(f"tasks: {t!r} unknown (choose from {', '.join(TASKS)})")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 2:
        raise ValueError(f"seeds={seeds!r}: must be an integer >= 2 (intervals need pairs)")
    if not names or not plant_sets or not task_list:
        raise ValueError("controllers, plant_sets and tasks must not be empty")
    jobs = [(p, t) for p in plant_sets for t in task_list]
    if backend is not None:
        resolve_backend(backend, address)
    t0 = time.perf_counter()
    if backend is not None:
        import cloudpickle  # a dependency of gymnasium; carries runtime registrations (--agent)

        factories = cloudpickle.dumps({n: spec(n).factory for n in names})
        # the longest cells first (the 3-D model's, then the long moves), so that no worker
        # is left with one of them when the others are done; results back in ``jobs`` order
        order = sorted(range(len(jobs)), key=lambda i: _cost_rank(*jobs[i]))
        remote = [(factories, names, *jobs[i], _seeds(jobs[i][0], seeds), axis, suite_seed)
                  for i in order]  # fmt: skip
        ran = map_tasks(_cell_job, remote, backend=backend, address=address, workers=workers)
        done = [ran[order.index(i)] for i in range(len(jobs))]
        return _result(names, plant_sets, task_list, seeds, axis, suite_seed, t0, jobs, done)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=sum(_task(p, t).horizon for p, t in jobs), unit="interval")
    done = []
    for p, t in jobs:
        if bar is not None:
            bar.set_description(f"{p}/{t}")
        tc = time.perf_counter()
        new, d = _run_cell(
            names, PLANT_SETS[p](), _task(p, t), _seeds(p, seeds), axis, suite_seed, bar
        )
        done.append((new, d, time.perf_counter() - tc))
    if bar is not None:
        bar.close()
    return _result(names, plant_sets, task_list, seeds, axis, suite_seed, t0, jobs, done)


def _cost_rank(plant_set: str, task: str) -> tuple[int, int]:
    """Sort key of a cell, the most expensive first: the 3-D model's cells, then the
    independent plant's, then the rest; within each, the long moves and tracking tasks
    (horizon) first."""
    kind = {"full_3d": 0, "independent": 1}.get(plant_set, 2)
    return kind, -_task(plant_set, task).horizon


def _cell_job(job: tuple) -> tuple[list[Cell], list[dict[str, Any]], float]:
    """One cell in a Ray task or a worker process: register the controllers it runs (the
    driver's factories, so runtime registrations travel too), run it, time it. The
    compiled kernels run on one thread: the cells are the parallelism, one worker a core
    (the rows' results do not depend on the thread count: each row is its own turntable)."""
    import cloudpickle
    import numba

    numba.set_num_threads(1)

    blob, names, p, t, seeds, axis, suite_seed = job
    load_plugins()
    for name, factory in cloudpickle.loads(blob).items():
        register(name, factory, "from the benchmark's driver", overwrite=True)
    tc = time.perf_counter()
    new, d = _run_cell(names, PLANT_SETS[p](), _task(p, t), seeds, axis, suite_seed, None)
    return new, d, time.perf_counter() - tc


def _result(
    names: list[str],
    plant_sets: Sequence[str],
    task_list: list[str],
    seeds: int,
    axis: str,
    suite_seed: int,
    t0: float,
    jobs: list[tuple[str, str]],
    done: list[tuple[list[Cell], list[dict[str, Any]], float]],
) -> BenchmarkResult:
    """The result of the cells ``done`` (in ``jobs``' order) with the run's settings."""
    cells: list[Cell] = []
    draws: dict[str, list[dict[str, Any]]] = {}
    cell_wall: dict[str, float] = {}
    for (p, t), (new, d, wall) in zip(jobs, done, strict=True):
        cell_wall[f"{p}/{t}"] = wall
        cells.extend(new)
        draws.setdefault(p, d)
    settings = {
        "version": BENCHMARK_VERSION,
        "controllers": names,
        "plant_sets": list(plant_sets),
        "tasks": {
            t: {
                "kind": TASKS[t].kind,
                "horizon_s": TASKS[t].horizon * 0.01,
                "description": TASKS[t].description,
            }
            for t in task_list
        },
        "full_3d_seeds": FULL_3D_SEEDS,
        "independent_seeds": INDEPENDENT_SEEDS,
        "seeds": seeds,
        "axis": axis,
        "suite_seed": suite_seed,
        "band_m": BAND,
        "hold_s": HOLD,
        "primary_metric": PRIMARY,
        "wall_s": time.perf_counter() - t0,
        "cell_wall_s": cell_wall,
        "cpu_count": os.cpu_count(),
    }
    return BenchmarkResult(cells, draws, settings)


# --- outputs -----------------------------------------------------------------------------
def write_outputs(result: BenchmarkResult, out: str | Path) -> dict[str, Path]:
    """Write benchmark.json (with its ``provenance``: the commit and the machine,
    :func:`~turntable_env.provenance.provenance`), episodes.csv, leaderboard.md/.html and
    trajectory plots; the directory is complete or untouched
    (:func:`~turntable_env.files.output_directory`)."""
    final = Path(out)
    with output_directory(final) as d:
        paths = _write_files(result, d)
    return {k: final / p.name for k, p in paths.items()}


def _write_files(result: BenchmarkResult, d: Path) -> dict[str, Path]:
    import io

    paths: dict[str, Path] = {}
    p = d / "benchmark.json"
    doc = {**result.to_json(), "provenance": provenance()}  # the commit, the machine
    write_atomic(p, json.dumps(doc, indent=1, allow_nan=False))
    paths["json"] = p
    df = result.to_pandas()
    buf = io.StringIO()
    df.to_csv(buf, index=False, quoting=csv.QUOTE_MINIMAL)
    p = d / "episodes.csv"
    write_atomic(p, buf.getvalue())
    paths["episodes"] = p
    p = d / "leaderboard.md"
    write_atomic(p, result.leaderboard("markdown") + "\n")
    paths["leaderboard_md"] = p
    p = d / "leaderboard.html"
    write_atomic(p, result.leaderboard("html") + "\n")
    paths["leaderboard_html"] = p
    paths.update(plot_trajectories(result, d))
    return paths


def plot_trajectories(result: BenchmarkResult, out: Path) -> dict[str, Path]:
    """One figure per plant set: every task's first-seed error trajectories."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = {}
    for ps in dict.fromkeys(c.plant_set for c in result.cells):
        ax = result.plot(ps)
        fig = ax[0].figure
        fig.tight_layout()
        p = Path(out) / f"trajectories_{ps}.png"
        fig.savefig(p, dpi=80)
        plt.close(fig)
        paths[f"trajectories_{ps}"] = p
    return paths
