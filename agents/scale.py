"""Several training runs at once: Ray tasks when Ray is installed, local processes otherwise.

:func:`train_seeds` trains one run per seed (the same algorithm, env id and budget) and
returns their run directories, through :func:`turntable_env.scale.map_tasks`: with Ray
(``pip install -e ".[scale]"``) every run is a Ray task of one CPU on a local instance by
default or on the cluster ``address`` names (``"auto"`` on a cluster node,
``"ray://head:10001"`` from outside); without Ray — or with ``backend="processes"`` — a
``concurrent.futures.ProcessPoolExecutor`` of ``workers`` processes. Either way each run
is :func:`agents.train.train` in its own process, seeded, writing its own directory
``<out>/<algo>[_raw]_seed<S>``.

:func:`seed_curves` reads the runs' evaluations and gives the learning curve across seeds
(mean and 95 % interval at each evaluation step, the runs' own evaluation means as the
samples); :func:`plot_seed_curves` draws it. :func:`validate_seeds` runs every seed's
final policy on one set of validation episodes, the same for all, and picks the seed to
ship by their paired returns: each run's own evaluation draws its episodes from its own
seed, so their last values differ by the episodes as much as by the policies.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from turntable_env.scale import BACKENDS, map_tasks, resolve_backend

from .interface import RAW_ENV_ID
from .train import ENV_ID

__all__ = [
    "BACKENDS",
    "VALIDATION_SEED",
    "check_validation",
    "plot_seed_curves",
    "run_name",
    "seed_curves",
    "train_seeds",
    "validate_seeds",
]

# the validation episodes' env seed: no training row's (seed + row, seeds < 10 000) and no
# training evaluation's (seed + 10 000)
VALIDATION_SEED = 20_000


def run_name(algo: str, env_id: str, seed: int) -> str:
    """The run directory's name: ``<algo>[_raw]_seed<S>``."""
    return f"{algo}{'_raw' if env_id == RAW_ENV_ID else ''}_seed{seed}"


def _train_one(kwargs: dict[str, Any]) -> str:
    import torch

    from .train import train

    torch.set_num_threads(1)
    return str(train(**kwargs, progress=False).run)


def train_seeds(
    algo: str,
    seeds: Sequence[int],
    *,
    env_id: str = ENV_ID,
    timesteps: int | None = None,
    out: str | Path = "runs",
    hyperparams: str | Path | None = None,
    training: str | Path | None = None,
    backend: str = "auto",
    address: str | None = None,
    workers: int | None = None,
    trained_agent: str | None = None,
) -> list[Path]:
    """Train ``algo`` once per seed (module docstring); the run directories, in seed order.

    Args:
        trained_agent: each seed continues this run directory, ``{seed}`` replaced by its
            seed (:func:`agents.train.train`'s ``trained_agent``).
        backend: ``"auto"`` (Ray if installed), ``"ray"`` or ``"processes"``.
        address: a Ray cluster to join (None: a local one).
        workers: parallel runs for the process backend (default: the CPUs this process may use).
    """
    resolve_backend(backend, address)
    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds={seeds!r}: need distinct seeds")
    root = Path(out)
    jobs = [
        {
            "algo": algo, "env_id": env_id, "timesteps": timesteps, "seed": s,
            "out": str(root / run_name(algo, env_id, s)), "hyperparams": hyperparams,
            "training": training,
            "trained_agent": None if trained_agent is None else trained_agent.format(seed=s),
        }
        for s in seeds
    ]  # fmt: skip
    runs = map_tasks(_train_one, jobs, backend=backend, address=address, workers=workers)
    return [Path(p) for p in runs]


def seed_curves(runs: Sequence[str | Path]) -> dict[str, np.ndarray]:
    """Learning curve across runs: ``timesteps`` (the evaluation steps all runs share),
    ``mean``, ``ci_low``, ``ci_high`` (95 % bootstrap interval of the mean over runs) and
    ``per_run`` (runs × steps) of the runs' mean evaluation returns."""
    from controllers.metrics import mean_ci

    data = []
    for r in runs:
        p = Path(r) / "eval" / "evaluations.npz"
        if not p.is_file():
            raise ValueError(f"run {r}: {p.name} missing")
        d = np.load(p)
        data.append((d["timesteps"], d["results"].mean(axis=1)))
    if len(data) < 2:
        raise ValueError(f"runs: need at least 2 for an interval, got {len(data)}")
    common = sorted(set.intersection(*(set(t.tolist()) for t, _ in data)))
    if not common:
        raise ValueError("runs: no evaluation step in common")
    per_run = np.array([[m[list(t).index(s)] for s in common] for t, m in data])
    cis = [mean_ci(per_run[:, j], seed=j) for j in range(len(common))]
    return {
        "timesteps": np.array(common),
        "mean": np.array([c["mean"] for c in cis]),
        "ci_low": np.array([c["ci_low"] for c in cis]),
        "ci_high": np.array([c["ci_high"] for c in cis]),
        "per_run": per_run,
    }


def check_validation(episodes: int, n_envs: int = 8) -> None:
    """ValueError naming the field unless ``episodes`` is a positive multiple of ``n_envs``
    (:func:`validate_seeds`' check, and ``seed_curves.py --validate``'s before any work)."""
    whole = isinstance(episodes, int) and not isinstance(episodes, bool)
    if not (whole and episodes >= n_envs and episodes % n_envs == 0):
        raise ValueError(f"episodes={episodes!r}: must be a positive multiple of n_envs={n_envs}")


def validate_seeds(
    runs: Sequence[str | Path], episodes: int = 64, n_envs: int = 8, seed: int = VALIDATION_SEED
) -> dict[str, Any]:
    """Every run's final policy on the same ``episodes`` validation episodes: the runs'
    training env (their config.yml's entry and training domains, which must be the same
    for all) seeded ``seed``, their own VecNormalize statistics frozen, deterministic
    actions (SB3's ``evaluate_policy``; returns as the env pays them, unnormalised).

    Returns ``returns`` (runs × episodes), ``mean`` (per run), ``best`` and ``runner_up``
    (indices into ``runs``), ``margin`` (the difference of their means with its 95 %
    bootstrap interval, ``margin_ci``) and ``decided``: the interval excludes 0 (otherwise
    the seeds are tied and the choice is not a result). ``paired``: every episode ran to
    the same length in every run, so episode k is the same draw in each (SB3 lists the
    returns in the order the episodes end) and the interval is that of the paired
    differences; otherwise (an episode truncated in one run) it is the two samples'
    (scipy.stats.bootstrap, unpaired). ValueError for fewer than 2 runs, runs of
    different configs, or ``episodes`` refused by :func:`check_validation`."""
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import VecFrameStack

    from controllers.metrics import paired_difference

    from .controller import load_agent
    from .train import frame_stack, make_vec_env

    if len(runs) < 2:
        raise ValueError(f"runs: need at least 2 to choose between, got {len(runs)}")
    check_validation(episodes, n_envs)
    loaded = [load_agent(r) for r in runs]

    def setting(r: str | Path, cfg: dict[str, Any]) -> tuple[str, Any, Any]:
        env_id = cfg["run"].get("env_id")
        if env_id is None:  # its entry sits where make_vec_env does not read it
            raise ValueError(f"run {r}: config.yml has no run.env_id (a run before the env ids)")
        return env_id, cfg.get(env_id), cfg.get("training", {}).get("domains")

    first = setting(runs[0], loaded[0][2])
    for r, (_, _, cfg) in zip(runs, loaded, strict=True):
        if setting(r, cfg) != first:
            raise ValueError(f"run {r}: another env entry or training domains than {runs[0]}")
    env_id, entry, domains = first
    returns, lengths = [], []
    for model, env, _ in loaded:  # each run's own VecNormalize statistics, frozen
        env.set_venv(make_vec_env(entry, n_envs, seed, env_id, domains))
        env.training, env.norm_reward = False, False
        seen = VecFrameStack(env, frame_stack(entry)) if frame_stack(entry) > 1 else env
        rew, length = evaluate_policy(model, seen, n_eval_episodes=episodes, deterministic=True,
                                      return_episode_rewards=True)  # fmt: skip
        returns.append(np.asarray(rew, dtype=float))
        lengths.append(np.asarray(length))
        env.close()
    ret = np.array(returns)
    mean = ret.mean(axis=1)
    order = np.argsort(-mean, kind="stable")
    best, runner = int(order[0]), int(order[1])
    paired = all(np.array_equal(n, lengths[0]) for n in lengths)
    if paired:
        diff = paired_difference(ret[best], ret[runner])
        ci = (float(diff["ci_low"]), float(diff["ci_high"]))
    else:
        ci = _unpaired_ci(ret[best], ret[runner])
    return {
        "returns": ret,
        "mean": mean,
        "best": best,
        "runner_up": runner,
        "margin": float(mean[best] - mean[runner]),
        "margin_ci": ci,
        "decided": bool(ci[0] > 0.0),
        "paired": paired,
    }


def _unpaired_ci(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """95 % percentile bootstrap interval of mean(a) − mean(b), the samples resampled apart."""
    import scipy.stats

    res = scipy.stats.bootstrap(
        (a, b), lambda x, y, axis: x.mean(axis=axis) - y.mean(axis=axis), paired=False,
        vectorized=True, confidence_level=0.95, method="percentile", rng=0,
    )  # fmt: skip
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def plot_seed_curves(curves: dict[str, dict[str, np.ndarray]], path: str | Path) -> Path:
    """One figure: each label's mean evaluation return with its 95 % band, vs timesteps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for label, c in curves.items():
        n = c["per_run"].shape[0]
        ax.plot(c["timesteps"], c["mean"], "o-", ms=3, label=f"{label} ({n} seeds)")
        ax.fill_between(c["timesteps"], c["ci_low"], c["ci_high"], alpha=0.25)
    ax.set_xlabel("timesteps")
    ax.set_ylabel("evaluation return (deterministic)")
    ax.set_title("mean over seeds, 95 % bootstrap interval")
    ax.legend()
    fig.tight_layout()
    p = Path(path)
    fig.savefig(p, dpi=90)
    plt.close(fig)
    return p
