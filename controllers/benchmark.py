"""The controller benchmark: every registered controller on one fixed task suite.

Tasks (:func:`task_suite`): a small, medium and large move — 50 nm, 2 µm and 50 µm at
the table radius (Eq. 4.2: θ = x/R_table; 5 µrad, 200 µrad, 5 mrad) — about each of
the axes A, B and C, direction alternating. Targets lie inside the detector's linear
range (a seeded draw within ±½θ_lin); the start is the target less the move, so the
large moves start far beyond the detector (its reading saturates) and the controller
knows the start only as the commanded move (the reset info's ``angle_rad``).

Plants (:data:`CONDITIONS`): ``nominal`` (Table D.1 with the repository's unlisted
values; detector noise 1 mV, the environment's level) and ``randomized`` (per episode:
friction coefficients ×U(0.7, 1.3), preload ×U(0.7, 1.3), amplifier slew and current
limit ×U(0.8, 1.2), detector noise at its nominal level), ``seeds`` plants per task.
Seeds are fixed, so every controller meets the same plants.

Each episode runs the registered ``PiezoTurntable-v0`` for ``horizon`` control intervals
(2 s) with ``terminate_on_success=False``: a controller must also hold the target.
Metrics per episode (:meth:`~controllers.episode.EpisodeResult.metrics`): final error
[nm at R_table], time to settle inside ±10 nm (the time after which the error stays
inside to the end; never → ∞), stick–slip steps, overshoot [nm], electrical energy
[J], success (final error within ±10 nm).

Outputs of :func:`write_outputs`: ``episodes.csv`` (one row per episode),
``summary.csv`` and ``summary.md`` (per controller, plant and move size),
``summary.json`` and trajectory plots ``trajectories_<controller>.png``.
"""

from __future__ import annotations

import csv
import json
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from turntable_env.detector import Detector
from turntable_env.params import real_parameters

from .episode import EpisodeResult, run_episode
from .registry import available, load_plugins, make

__all__ = [
    "CONDITIONS",
    "MOVES",
    "BenchmarkResult",
    "Task",
    "run_benchmark",
    "task_suite",
    "write_outputs",
]

MOVES = {"small": 50e-9, "medium": 2e-6, "large": 50e-6}  # m at the table radius
CONDITIONS: dict[str, dict[str, Any]] = {
    "nominal": {"randomize": False},
    "randomized": {
        "randomize": {
            "friction": (0.7, 1.3),
            "preload": (0.7, 1.3),
            "amplifier": (0.8, 1.2),
            "sensor_noise": (1.0, 1.0),
        }
    },
}
BAND = 10e-9  # m, settling band at the table radius
SUITE_SEED = 2026


@dataclass(frozen=True)
class Task:
    """One move: axis, size name, move at the table radius [m] (signed), start and
    target angles [rad]."""

    axis: str
    size: str
    move_m: float
    start_rad: float
    target_rad: float


def task_suite(detector: Detector | None = None, seed: int = SUITE_SEED) -> list[Task]:
    """The nine tasks (module docstring) for a detector (default: the real set's), whose
    table radius [m] converts the moves and whose linear range [rad] bounds the targets."""
    det = detector if detector is not None else real_parameters().detector
    table_radius, angle_range = det.table_radius, det.angle_range
    rng = np.random.default_rng(seed)
    tasks = []
    for i, axis in enumerate("ABC"):
        for j, (size, x) in enumerate(MOVES.items()):
            sign = 1.0 if (i + j) % 2 == 0 else -1.0
            move = sign * x / table_radius  # rad
            # target inside ±½θ_lin, on the side that keeps a medium move's start in range
            target = -sign * rng.uniform(0.0, 0.5) * angle_range
            tasks.append(Task(axis, size, sign * x, target - move, target))
    return tasks


@dataclass
class BenchmarkResult:
    """Per-episode rows and the summaries (see :func:`run_benchmark`)."""

    rows: list[dict[str, Any]]
    episodes: dict[tuple[str, str, str], EpisodeResult]  # first seed's trajectory per task
    settings: dict[str, Any]

    def summary(self) -> dict[str, Any]:
        """Per controller: ``success_rate``, ``median_final_error_nm``,
        ``median_settle_time_s`` over all episodes (failures settle at ∞; JSON null when
        the median is not finite), and the same per plant condition and per move size."""
        out: dict[str, Any] = {}
        for ctl in dict.fromkeys(r["controller"] for r in self.rows):
            rows = [r for r in self.rows if r["controller"] == ctl]
            entry = _aggregate(rows)
            entry["conditions"] = {}
            for cond in dict.fromkeys(r["condition"] for r in rows):
                sub = [r for r in rows if r["condition"] == cond]
                entry["conditions"][cond] = _aggregate(sub)
                entry["conditions"][cond]["sizes"] = {
                    size: _aggregate([r for r in sub if r["size"] == size])
                    for size in dict.fromkeys(r["size"] for r in sub)
                }
            out[ctl] = entry
        return out

    def markdown(self) -> str:
        """Table: controller × plant × move size (medians over episodes)."""
        head = (
            "| controller | plant | move | success | final error [nm] | settle [s] | "
            "steps | overshoot [nm] | energy [mJ] |\n|---|---|---|---:|---:|---:|---:|---:|---:|"
        )
        lines = [head]
        for ctl, entry in self.summary().items():
            for cond, ce in entry["conditions"].items():
                for size, se in ce["sizes"].items():
                    lines.append(
                        f"| {ctl} | {cond} | {size} | {se['success_rate']:.0%} | "
                        f"{_fmt(se['median_final_error_nm'])} | "
                        f"{_fmt(se['median_settle_time_s'])} | {se['median_steps']:.0f} | "
                        f"{_fmt(se['median_overshoot_nm'])} | "
                        f"{se['median_energy_J'] * 1e3:.3g} |"
                    )
        return "\n".join(lines)


def _fmt(x: float | None) -> str:
    if x is None or not math.isfinite(x):
        return "∞"
    return f"{x:.3g}"


def _median(values: Sequence[float]) -> float | None:
    m = float(np.median(np.asarray(values, dtype=float)))
    return m if math.isfinite(m) else None


def _aggregate(rows: list[dict[str, Any]]) -> dict[str, Any]:
    settle = [r["settle_time_s"] if math.isfinite(r["settle_time_s"]) else math.inf for r in rows]
    return {
        "episodes": len(rows),
        "success_rate": float(np.mean([r["success"] for r in rows])),
        "median_final_error_nm": _median([r["final_error_nm"] for r in rows]),
        "median_settle_time_s": _median(settle),
        "median_steps": float(np.median([r["steps"] for r in rows])),
        "median_overshoot_nm": _median([r["overshoot_nm"] for r in rows]),
        "median_energy_J": float(np.median([r["energy_J"] for r in rows])),
    }


def run_benchmark(
    controllers: Sequence[str] | None = None,
    *,
    seeds: int = 20,
    horizon: int = 200,
    conditions: Sequence[str] = tuple(CONDITIONS),
    axes: Sequence[str] = ("A", "B", "C"),
    sizes: Sequence[str] = tuple(MOVES),
    progress: bool = False,
) -> BenchmarkResult:
    """Run the suite (module docstring).

    Args:
        controllers: registered names (default: all, after :func:`load_plugins`).
        seeds: randomised plants per task (the nominal plant runs once per task).
        horizon: control intervals per episode.
        conditions, axes, sizes: subsets of the suite.
    """
    load_plugins()
    names = list(controllers) if controllers is not None else available()
    for c in conditions:
        if c not in CONDITIONS:
            raise ValueError(f"conditions: {c!r} unknown (choose from {', '.join(CONDITIONS)})")
    if seeds < 1 or horizon < 1:
        raise ValueError(f"seeds={seeds!r}, horizon={horizon!r}: must be >= 1")
    import turntable_env  # noqa: F401  (registers the env)

    rows: list[dict[str, Any]] = []
    episodes: dict[tuple[str, str, str], EpisodeResult] = {}
    jobs = []
    run_tasks: dict[str, Task] = {}
    for cond in conditions:
        for axis in axes:
            env = gym.make(
                "PiezoTurntable-v0",
                axis=axis,
                terminate_on_success=False,
                max_episode_steps=horizon,
                **CONDITIONS[cond],
            )
            cfg = env.unwrapped.config
            det = cfg.parameter_set.detector
            tasks = [t for t in task_suite(det) if t.axis == axis and t.size in sizes]
            run_tasks.update({f"{t.axis}-{t.size}": t for t in tasks})
            n_seeds = 1 if cond == "nominal" else seeds
            jobs.append((cond, axis, env, tasks, n_seeds))
    total = len(names) * sum(len(j[3]) * j[4] for j in jobs)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total, desc="benchmark", unit="episode")
    t0 = time.perf_counter()
    for name in names:
        for cond, axis, env, tasks, n_seeds in jobs:
            ctl = make(name, env)
            for task in tasks:
                for s in range(n_seeds):
                    seed = 1000 * s + 17
                    res = run_episode(
                        env,
                        ctl,
                        seed=seed,
                        options={"start_angle": task.start_rad, "target_angle": task.target_rad},
                    )
                    m = res.metrics(BAND)
                    rows.append(
                        {
                            "controller": name,
                            "condition": cond,
                            "axis": axis,
                            "size": task.size,
                            "move_nm": task.move_m * 1e9,
                            "seed": seed,
                            **m,
                        }
                    )
                    if s == 0:
                        episodes[(name, cond, f"{axis}-{task.size}")] = res
                    if bar is not None:
                        bar.update()
    if bar is not None:
        bar.close()
    for _c, _a, env, _t, _n in jobs:
        env.close()
    settings = {
        "controllers": names,
        "seeds": seeds,
        "horizon": horizon,
        "conditions": {c: CONDITIONS[c] for c in conditions},
        "band_m": BAND,
        "tasks": [asdict(t) for t in run_tasks.values()],
        "wall_s": time.perf_counter() - t0,
    }
    return BenchmarkResult(rows, episodes, settings)


def write_outputs(result: BenchmarkResult, out: str | Path) -> dict[str, Path]:
    """Write episodes.csv, summary.csv, summary.md, summary.json and trajectory plots."""
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    paths = {}
    p = d / "episodes.csv"
    with p.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(result.rows[0]))
        w.writeheader()
        w.writerows(result.rows)
    paths["episodes"] = p
    summ = result.summary()
    p = d / "summary.csv"
    with p.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        keys = [k for k in _aggregate(result.rows[:1])]
        w.writerow(["controller", "condition", "size", *keys])
        for ctl, entry in summ.items():
            for cond, ce in entry["conditions"].items():
                for size, se in ce["sizes"].items():
                    w.writerow([ctl, cond, size, *(se[k] for k in keys)])
    paths["summary_csv"] = p
    p = d / "summary.md"
    p.write_text(result.markdown() + "\n", encoding="utf-8")
    paths["summary_md"] = p
    p = d / "summary.json"
    p.write_text(json.dumps({"controllers": summ, "settings": result.settings}, indent=2))
    paths["summary_json"] = p
    paths.update(plot_trajectories(result, d))
    return paths


def plot_trajectories(result: BenchmarkResult, out: Path) -> dict[str, Path]:
    """One figure per controller: error vs time of each task (first seed), per plant."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = {}
    for ctl in dict.fromkeys(k[0] for k in result.episodes):
        conds = list(dict.fromkeys(k[1] for k in result.episodes if k[0] == ctl))
        fig, axes = plt.subplots(1, len(conds), figsize=(6 * len(conds), 4), squeeze=False)
        for ax, cond in zip(axes[0], conds, strict=True):
            for (c, cd, task), ep in result.episodes.items():
                if c == ctl and cd == cond:
                    ep.plot(ax=ax, label=task)
            ax.set_title(f"{ctl}, {cond} plant")
            ax.legend(fontsize=7, ncol=3)
        fig.tight_layout()
        p = out / f"trajectories_{ctl}.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths[f"trajectories_{ctl}"] = p
    return paths
