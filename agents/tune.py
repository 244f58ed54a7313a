"""Hyperparameter search: Optuna over rl-zoo3's search spaces, every trial a Ray task.

:func:`search` asks an Optuna study (TPE sampler, seeded, ``constant_liar`` so that trials
asked together spread out) for ``parallel`` trials at a time. Each trial's SB3 arguments
come from rl-zoo3's own sampler for the algorithm (``rl_zoo3.hyperparams_opt``: the
zoo's search space, PPO and SAC), laid over the ``env_id`` entry of
``agents/hyperparams/<algo>.yml`` (:func:`agents.train.apply_overrides`: gSDE and
``log_std_init`` stay). The trials run through :func:`turntable_env.scale.map_tasks` — Ray
tasks on a local instance, or on the cluster ``address`` names, or local processes
without Ray — each one :func:`agents.train.train` with ``timesteps`` steps; the objective
is the mean return of its last evaluation (deterministic policy, ``eval_episodes``
episodes on randomised turntables seeded apart from training). A trial that raises is
told to the study as failed, with its error kept.

The study lives in an Optuna journal file (``<out>/study.log``, no database needed), so a
search can be resumed or extended with more trials, and several drivers may share it.
``<out>/best.yml`` is the best trial's entry in rl-zoo3's layout: ``experiments/train_rl.py
--hyperparams <out>/best.yml`` (or the zoo) trains it at full budget.

    python experiments/tune_rl.py --algo ppo --trials 16 --timesteps 100000 --parallel 2
    python experiments/tune_rl.py --algo sac --trials 64 --parallel 32 --address auto
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from turntable_env.scale import map_tasks, resolve_backend, session

from .interface import RAW_ENV_ID
from .train import (
    ENV_ID,
    ENV_IDS,
    apply_overrides,
    load_hyperparams,
    load_training,
    zoo_policy_kwargs,
)

__all__ = ["TUNABLE", "TuneResult", "sample_overrides", "search"]

TUNABLE = ("ppo", "sac")  # rl-zoo3 samplers whose output is all YAML (TD3's has noise objects)


@dataclass(frozen=True)
class TuneResult:
    """What :func:`search` returns: the study's name and journal, the best trial's number,
    objective (mean evaluation return) and SB3 overrides, and ``best.yml``'s path."""

    study_name: str
    journal: Path
    best_number: int
    best_value: float
    best_overrides: dict[str, Any]
    best_file: Path

    def to_pandas(self) -> Any:
        """Every trial of the study: number, state, value, parameters (Optuna's frame)."""
        return _load_study(self.study_name, self.journal).trials_dataframe()


def sample_overrides(trial: Any, algo: str, n_actions: int, n_envs: int) -> dict[str, Any]:
    """One trial's SB3 arguments from rl-zoo3's sampler for ``algo``, YAML-safe
    (``policy_kwargs`` in the zoo's ``dict(...)`` form when it holds an activation)."""
    from rl_zoo3.hyperparams_opt import HYPERPARAMS_SAMPLER

    params = HYPERPARAMS_SAMPLER[algo](trial, n_actions, n_envs, {"using_her_replay_buffer": False})
    if "policy_kwargs" in params:
        params["policy_kwargs"] = zoo_policy_kwargs(params["policy_kwargs"])
    return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in params.items()}


def _trial(job: dict[str, Any]) -> dict[str, Any]:
    """One trial in its own process: train, return the last evaluation's mean return."""
    import torch

    from .train import train

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    try:
        run = train(**job, progress=False).run
        d = np.load(run / "eval" / "evaluations.npz")
        value = float(d["results"][-1].mean())
        error = None if np.isfinite(value) else "non-finite evaluation return"
    except Exception as e:  # a trial's failure is data for the study, not the end of it
        value, error = float("nan"), f"{type(e).__name__}: {e}"
    return {"value": value, "error": error, "wall_s": time.perf_counter() - t0}


def _journal(path: Path) -> Any:
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    return JournalStorage(JournalFileBackend(str(path)))


def _load_study(name: str, journal: Path, sampler: Any = None) -> Any:
    import optuna

    return optuna.create_study(
        study_name=name, storage=_journal(journal), sampler=sampler,
        direction="maximize", load_if_exists=True,
    )  # fmt: skip


def _positive_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{name}={value!r}: must be an integer >= 1")
    return value


def search(
    algo: str,
    trials: int,
    *,
    env_id: str = ENV_ID,
    timesteps: int = 50_000,
    parallel: int = 2,
    eval_episodes: int = 16,
    seed: int = 0,
    out: str | Path = "runs/tune",
    study_name: str | None = None,
    hyperparams: str | Path | None = None,
    backend: str = "auto",
    address: str | None = None,
) -> TuneResult:
    """Run ``trials`` more trials of the study (module docstring) and write ``best.yml``.

    Args:
        trials: trials to add to the study (a resumed study keeps its earlier ones).
        timesteps: environment steps per trial.
        parallel: trials asked and run at a time (Ray tasks or processes).
        seed: the sampler's seed and every trial's training seed.
        out: the study's directory: ``study.log``, ``trial_<n>/``, ``best.yml``.
        study_name: default ``<algo>_<env_id>``.
        hyperparams: the base file (default ``agents/hyperparams/<algo>.yml``).
    """
    import optuna

    if algo not in TUNABLE:
        raise ValueError(f"algo={algo!r}: the search covers {', '.join(TUNABLE)}")
    if env_id not in ENV_IDS:
        raise ValueError(f"env_id={env_id!r}: must be one of {', '.join(ENV_IDS)}")
    for name, v in (("trials", trials), ("timesteps", timesteps), ("parallel", parallel)):
        _positive_int(name, v)
    _positive_int("eval_episodes", eval_episodes)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed={seed!r}: must be an integer >= 0")
    resolve_backend(backend, address)
    base = load_hyperparams(algo, hyperparams, env_id)
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    training = root / "training.yml"  # evaluate twice per trial, the last one is the objective
    every = {"freq": max(timesteps // 2, 1), "n_envs": 8, "episodes": eval_episodes}
    domains = load_training(algo)["domains"]  # the trials train on the algo's domains
    training.write_text(yaml.safe_dump(
        {algo: {"eval": every, "checkpoint_freq": 10**12, "domains": domains}}
    ))  # fmt: skip
    name = study_name or f"{algo}_{env_id}"
    journal = root / "study.log"
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    sampler = optuna.samplers.TPESampler(seed=seed, constant_liar=True, n_startup_trials=4)
    study = _load_study(name, journal, sampler)
    n_actions = 5 if env_id == RAW_ENV_ID else 3
    with session(backend, address):  # one Ray instance for every round
        done = 0
        while done < trials:
            asked = [study.ask() for _ in range(min(parallel, trials - done))]
            jobs = []
            for tr in asked:
                over = sample_overrides(tr, algo, n_actions, int(base["n_envs"]))
                tr.set_user_attr("overrides", over)
                jobs.append({
                    "algo": algo, "env_id": env_id, "timesteps": timesteps, "seed": seed,
                    "out": str(root / f"trial_{tr.number}"), "training": str(training),
                    "overrides": over, "hyperparams": hyperparams,
                })  # fmt: skip
            results = map_tasks(_trial, jobs, backend=backend, address=address)
            for tr, res in zip(asked, results, strict=True):
                tr.set_user_attr("wall_s", round(res["wall_s"], 1))
                if res["error"] is None:
                    study.tell(tr, res["value"])
                else:
                    tr.set_user_attr("error", res["error"])
                    study.tell(tr, state=optuna.trial.TrialState.FAIL)
            done += len(asked)
    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    if not complete:
        errors = {t.number: t.user_attrs.get("error") for t in study.trials}
        raise ValueError(f"search: no trial completed ({errors})")
    best = study.best_trial
    over = best.user_attrs["overrides"]
    best_file = root / "best.yml"
    tmp = best_file.with_suffix(".yml.tmp")
    header = (
        f"# {algo} on {env_id}: trial {best.number} of study {name!r} ({journal}), "
        f"mean evaluation return {best.value:.3f} after {timesteps} steps\n"
    )
    body = yaml.safe_dump({env_id: apply_overrides(base, over)}, sort_keys=False)
    tmp.write_text(header + body, encoding="utf-8")
    tmp.replace(best_file)
    return TuneResult(name, journal, best.number, float(best.value), over, best_file)
