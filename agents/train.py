"""Train a stable-baselines3 agent on ``PiezoTurntable-v0`` from a hyperparameter file.

:func:`train` reads the ``env_id`` entry of ``agents/hyperparams/<algo>.yml`` (rl-zoo3's
layout: ``PiezoTurntableAgent-v0``, the structured interface, or ``PiezoTurntable-v0``, the
env's own spaces) and the project's callback settings (``training.yml``), builds
the native batched vector env (:class:`~agents.vec_env.NativeVecEnv`, domain
randomisation on) under ``VecMonitor`` and ``VecNormalize``, seeds everything, and
learns with an ``EvalCallback`` (a separate, differently seeded set of randomised
turntables, deterministic policy), a ``CheckpointCallback`` (with the VecNormalize
statistics) and SB3's progress bar. Logs: CSV (``logs/progress.csv``), optional
TensorBoard. The run directory receives

* ``model.zip`` and ``vecnormalize.pkl`` — the agent (:func:`agents.load_agent`);
* ``config.yml`` — the effective hyperparameters, seed, timesteps and versions;
* ``eval/evaluations.npz``, ``checkpoints/``, ``learning_curve.png``.

``python experiments/train_rl.py --algo ppo --timesteps N --seed S --out DIR`` is the
command line.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .interface import AGENT_ENV_ID, RAW, RAW_ENV_ID, interface_config

__all__ = [
    "ALGOS",
    "ENV_IDS",
    "HYPERPARAMS_DIR",
    "TrainedAgent",
    "apply_overrides",
    "frame_stack",
    "load_hyperparams",
    "load_training",
    "make_vec_env",
    "parse_policy_kwargs",
    "run_config",
    "ship",
    "train",
]

HYPERPARAMS_DIR = Path(__file__).parent / "hyperparams"
TRAINING_FILE = HYPERPARAMS_DIR / "training.yml"
ENV_ID = AGENT_ENV_ID  # the default: the shipped agents' structured interface
ENV_IDS = (AGENT_ENV_ID, RAW_ENV_ID)
# rl-zoo3's keys, not SB3 arguments. frame_stack: the policy sees the last k normalised
# observations (VecFrameStack over VecNormalize, zoo's order; AgentController stacks alike)
ZOO_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs", "frame_stack")
DEFAULT_TRAINING: dict[str, Any] = {
    "eval": {"freq": 10_000, "n_envs": 4, "episodes": 16},
    "checkpoint_freq": 100_000,
    "domains": None,  # one domain: the entry's env_kwargs (NativeVecEnv's ``domains``)
}


@dataclass
class TrainedAgent:
    """What :func:`train` returns: the run directory, the model and its VecNormalize."""

    run: Path
    model: Any
    vecnormalize: Any


def _algos() -> dict[str, Any]:
    from stable_baselines3 import PPO, SAC, TD3

    return {"ppo": PPO, "sac": SAC, "td3": TD3}


ALGOS = ("ppo", "sac", "td3")


def load_hyperparams(
    algo: str, path: str | Path | None = None, env_id: str = ENV_ID
) -> dict[str, Any]:
    """The ``env_id`` entry of ``<algo>.yml`` (or of ``path``), rl-zoo3's layout."""
    if algo not in ALGOS:
        raise ValueError(f"algo={algo!r}: must be one of {', '.join(ALGOS)}")
    if env_id not in ENV_IDS:
        raise ValueError(f"env_id={env_id!r}: must be one of {', '.join(ENV_IDS)}")
    p = Path(path) if path is not None else HYPERPARAMS_DIR / f"{algo}.yml"
    if not p.is_file():
        raise ValueError(f"hyperparameters: {p} does not exist")
    data = yaml.safe_load(p.read_text(encoding="utf-8"))
    if not isinstance(data, dict) or env_id not in data:
        raise ValueError(f"{p}: no '{env_id}' entry")
    cfg = copy.deepcopy(dict(data[env_id]))
    for key in ("n_envs", "n_timesteps", "policy", "env_kwargs"):
        if key not in cfg:
            raise ValueError(f"{p}: '{env_id}.{key}' missing")
    if env_id == RAW_ENV_ID and "interface" in cfg["env_kwargs"]:
        raise ValueError(f"{p}: '{env_id}.env_kwargs.interface': the raw env has none")
    return cfg


ACTIVATIONS = ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU")  # torch.nn classes


def parse_policy_kwargs(value: Any) -> dict[str, Any]:
    """``policy_kwargs`` as SB3 takes them, from a hyperparameter entry: a mapping, or
    rl-zoo3's string form ``"dict(net_arch=[64, 64], activation_fn=nn.Tanh)"`` — read
    without ``eval``: literals, nested ``dict(...)`` and ``nn.<activation>`` only."""
    import ast

    if isinstance(value, dict):
        out = dict(value)
        act = out.get("activation_fn")
        if isinstance(act, str):  # "nn.Tanh" or "Tanh" in a YAML mapping
            out["activation_fn"] = _activation(act.removeprefix("nn."), value)
        return out
    if not isinstance(value, str):
        raise ValueError(
            f"policy_kwargs={value!r}: must be a mapping or rl-zoo3's dict(...) string"
        )

    def conv(node: ast.AST) -> Any:
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id == "dict"
        ):
            if node.args or any(k.arg is None for k in node.keywords):
                raise ValueError(f"policy_kwargs={value!r}: dict(...) takes keywords only")
            return {k.arg: conv(k.value) for k in node.keywords}
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            if node.value.id == "nn":
                return _activation(node.attr, value)
        try:
            return ast.literal_eval(node)
        except ValueError:
            raise ValueError(
                f"policy_kwargs={value!r}: {ast.unparse(node)!r} is neither a literal nor "
                f"nn.<{'|'.join(ACTIVATIONS)}>"
            ) from None

    try:
        tree = ast.parse(value.strip(), mode="eval").body
    except SyntaxError as e:
        raise ValueError(f"policy_kwargs={value!r}: not a dict(...) expression ({e.msg})") from None
    out = conv(tree)
    if not isinstance(out, dict):
        raise ValueError(f"policy_kwargs={value!r}: must be dict(...)")
    return out


def _activation(name: str, value: Any) -> Any:
    import torch

    if name not in ACTIVATIONS:
        raise ValueError(f"policy_kwargs={value!r}: activation {name!r} not in {ACTIVATIONS}")
    return getattr(torch.nn, name)


def zoo_policy_kwargs(kwargs: dict[str, Any]) -> dict[str, Any] | str:
    """The inverse of :func:`parse_policy_kwargs` for a YAML file: the mapping itself, or
    rl-zoo3's ``dict(...)`` string when it holds an activation class."""
    if not any(isinstance(v, type) for v in kwargs.values()):
        return kwargs
    parts = [
        f"{k}=nn.{v.__name__}" if isinstance(v, type) else f"{k}={v!r}" for k, v in kwargs.items()
    ]
    return f"dict({', '.join(parts)})"


def apply_overrides(cfg: dict[str, Any], overrides: dict[str, Any] | None) -> dict[str, Any]:
    """A hyperparameter entry with SB3 arguments replaced (``policy_kwargs`` merged key by
    key, so a sampled ``net_arch`` keeps the entry's ``log_std_init``); YAML-safe."""
    out = copy.deepcopy(cfg)
    for key, value in (overrides or {}).items():
        if key in ZOO_KEYS:
            raise ValueError(f"overrides: {key!r} is an rl-zoo3 key, not an SB3 argument")
        if key == "policy_kwargs":
            merged = parse_policy_kwargs(out.get("policy_kwargs", {}))
            merged.update(parse_policy_kwargs(value))
            value = zoo_policy_kwargs(merged)
        out[key] = value
    return out


def load_training(algo: str, path: str | Path | None = None) -> dict[str, Any]:
    """The project's settings for ``algo`` (evaluation, checkpoints, training domains)
    from training.yml."""
    p = Path(path) if path is not None else TRAINING_FILE
    if not p.is_file():
        raise ValueError(f"training settings: {p} does not exist")
    data = yaml.safe_load(p.read_text(encoding="utf-8")) or {}
    out = copy.deepcopy(DEFAULT_TRAINING)
    entry = data.get(algo, {})
    unknown = set(entry) - set(out)
    if unknown:
        raise ValueError(f"{p}: '{algo}' has unknown keys {sorted(unknown)}")
    out.update(entry)
    if out["domains"] is not None:
        from .vec_env import domain_kwargs

        try:  # a bad entry: ValueError naming the file, before any work
            domain_kwargs({}, out["domains"])
        except ValueError as e:
            raise ValueError(f"{p}: '{algo}': {e}") from None
    return out


def frame_stack(cfg: dict[str, Any]) -> int:
    """The entry's ``frame_stack`` (rl-zoo3's key; 1: none); ValueError for a bad value."""
    k = cfg.get("frame_stack", 1)
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ValueError(f"frame_stack={k!r}: must be an integer >= 1")
    return k


def make_vec_env(
    cfg: dict[str, Any], n_envs: int, seed: int, env_id: str = ENV_ID,
    domains: list[dict[str, Any]] | None = None,
) -> Any:  # fmt: skip
    """The monitored native vector env of a hyperparameter entry, seeded: the structured
    interface for ``PiezoTurntableAgent-v0``, the env's own spaces for ``PiezoTurntable-v0``;
    ``domains`` (training.yml): the rows' plant distributions (:class:`NativeVecEnv`)."""
    from stable_baselines3.common.vec_env import VecMonitor

    from .vec_env import NativeVecEnv

    kwargs = dict(cfg["env_kwargs"])
    steps = int(kwargs.pop("max_episode_steps", 100))
    iface = kwargs.pop("interface", None)
    interface = RAW if env_id == RAW_ENV_ID else interface_config(iface)
    env = NativeVecEnv(n_envs, steps, interface, domains, **kwargs)
    env.seed(seed)
    return VecMonitor(env)


def train(
    algo: str,
    *,
    env_id: str = ENV_ID,
    timesteps: int | None = None,
    seed: int = 0,
    out: str | Path = "runs/agent",
    hyperparams: str | Path | None = None,
    training: str | Path | None = None,
    tensorboard: bool = False,
    progress: bool = True,
    overrides: dict[str, Any] | None = None,
    trained_agent: str | Path | None = None,
) -> TrainedAgent:
    """Train ``algo`` on ``env_id`` (module docstring); ``hyperparams``/``training``
    replace ``<algo>.yml``/``training.yml``, ``overrides`` replaces SB3 arguments of the
    entry (:func:`apply_overrides`; how :mod:`agents.tune` tries a trial).

    ``trained_agent``: a run directory to continue (rl-zoo3's ``--trained-agent``): its
    model and VecNormalize statistics go on learning for ``timesteps`` more steps (the
    step count and the evaluations' steps continue from the run's), with the entry's
    hyperparameters except ``policy_kwargs`` (the network is the run's); ValueError
    naming the directory for a missing file or another algorithm or env id."""
    import stable_baselines3
    import torch
    from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

    cfg = apply_overrides(load_hyperparams(algo, hyperparams, env_id), overrides)
    proj = load_training(algo, training)
    stack = frame_stack(cfg)
    n_steps = int(timesteps if timesteps is not None else cfg["n_timesteps"])
    if n_steps < 1:
        raise ValueError(f"timesteps={timesteps!r}: must be >= 1")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    set_random_seed(seed)
    torch.set_num_threads(1)  # the simulator takes the other core
    n_envs = int(cfg["n_envs"])
    norm = dict(cfg.get("normalize", {"norm_obs": True, "norm_reward": False}))
    gamma = float(cfg.get("gamma", 0.99))
    domains = proj["domains"]
    prev = None if trained_agent is None else _trained_run(trained_agent, algo, env_id)
    rows = make_vec_env(cfg, n_envs, seed, env_id, domains)
    if prev is None:
        venv = VecNormalize(rows, gamma=gamma, **norm)
    else:  # the run's statistics, updated on as they were
        venv = VecNormalize.load(str(prev / "vecnormalize.pkl"), rows)
        venv.training = True
    ev = dict(proj["eval"])
    eval_env = VecNormalize(
        make_vec_env(cfg, int(ev.get("n_envs", 4)), seed + 10_000, env_id, domains),
        training=False,
        norm_obs=norm.get("norm_obs", True),
        norm_reward=False,
    )
    learn_env, eval_seen = venv, eval_env
    if stack > 1:
        learn_env, eval_seen = VecFrameStack(venv, stack), VecFrameStack(eval_env, stack)
    hyper = {k: v for k, v in cfg.items() if k not in ZOO_KEYS}
    if "policy_kwargs" in hyper:
        hyper["policy_kwargs"] = parse_policy_kwargs(hyper["policy_kwargs"])
    if prev is None:
        model = _algos()[algo](
            cfg["policy"], learn_env, seed=seed, verbose=0, **copy.deepcopy(hyper)
        )
    else:
        hyper.pop("policy_kwargs", None)
        model = _algos()[algo].load(
            prev / "model.zip", env=learn_env, device="cpu", seed=seed, verbose=0,
            **copy.deepcopy(hyper),
        )  # fmt: skip
    formats = ["csv"] + (["tensorboard"] if tensorboard else [])
    model.set_logger(configure(str(out / "logs"), formats))
    callbacks = [
        EvalCallback(
            eval_seen,
            n_eval_episodes=int(ev.get("episodes", 16)),
            eval_freq=max(int(ev.get("freq", 10_000)) // n_envs, 1),
            log_path=str(out / "eval"),
            deterministic=True,
            verbose=0,
        ),
        CheckpointCallback(
            save_freq=max(int(proj["checkpoint_freq"]) // n_envs, 1),
            save_path=str(out / "checkpoints"),
            name_prefix=algo,
            save_vecnormalize=True,
        ),
    ]
    t0 = time.perf_counter()
    model.learn(
        total_timesteps=n_steps, callback=callbacks, progress_bar=progress,
        reset_num_timesteps=prev is None,
    )  # fmt: skip
    wall = time.perf_counter() - t0
    model.logger.close()  # flush and close logs/progress.csv (and TensorBoard)
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    effective = {
        env_id: cfg,
        "training": proj,
        "run": {
            "algo": algo,
            "env_id": env_id,
            "seed": seed,
            "timesteps": n_steps,
            "total_timesteps": int(model.num_timesteps),  # with the continued run's
            "trained_agent": None if prev is None else str(prev),
            "wall_s": round(wall, 1),
            "versions": {
                "stable_baselines3": stable_baselines3.__version__,
                "torch": str(torch.__version__),
                "numpy": np.__version__,
            },
        },
    }
    (out / "config.yml").write_text(yaml.safe_dump(effective, sort_keys=False), encoding="utf-8")
    plot_learning_curve(out)
    eval_env.close()
    return TrainedAgent(out, model, venv)


RUN_FILES = ("model.zip", "vecnormalize.pkl", "config.yml")  # what a run directory holds


def run_config(run: str | Path, label: str) -> dict[str, Any]:
    """A run directory's config.yml, after checking it holds :data:`RUN_FILES`
    (ValueError ``"<label>: <file> missing"``), is YAML and a mapping with a ``run``
    mapping (ValueError naming the file and what is wrong)."""
    d = Path(run)
    for name in RUN_FILES:
        if not (d / name).is_file():
            raise ValueError(f"{label}: {name} missing")
    path = "config.yml"
    try:
        cfg = yaml.safe_load((d / path).read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise ValueError(f"{label}: {path}: not UTF-8 text") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        what = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ValueError(f"{label}: {path}: not valid YAML ({what}{where})") from None
    if not isinstance(cfg, dict):
        kind = "empty" if cfg is None else f"a {type(cfg).__name__}"
        raise ValueError(
            f"{label}: {path}: must be a mapping of the run's entry and 'run', not {kind}"
        )
    if not isinstance(cfg.get("run"), dict):
        raise ValueError(
            f"{label}: {path}: no 'run' mapping (top-level keys: {sorted(map(str, cfg))})"
        )
    return cfg


def _trained_run(run: str | Path, algo: str, env_id: str) -> Path:
    """The run directory ``run`` to continue, checked (:func:`train`'s ``trained_agent``)."""
    d = Path(run)
    was = run_config(d, f"trained_agent={str(d)!r}")["run"]
    # runs made before the env ids were the structured interface's (controller.interface_of)
    if was.get("algo") != algo or was.get("env_id", AGENT_ENV_ID) != env_id:
        raise ValueError(
            f"trained_agent={str(d)!r}: a {was.get('algo')} run on {was.get('env_id')}, "
            f"not {algo} on {env_id}"
        )
    return d


SHIPPED_FILES = (
    "model.zip", "vecnormalize.pkl", "config.yml", "learning_curve.png",
    "eval/evaluations.npz", "logs/progress.csv",
)  # fmt: skip


def ship(run: str | Path, dest: str | Path) -> Path:
    """Copy a run's agent, statistics, config and logs (not the checkpoints) to ``dest``
    and redraw its learning curve there — how ``agents/pretrained/<algo>/`` is made."""
    import shutil

    src, dst = Path(run), Path(dest)
    for name in SHIPPED_FILES:
        if not (src / name).is_file():
            raise ValueError(f"ship: {src / name} missing")
    for name in SHIPPED_FILES:
        (dst / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src / name, dst / name)
    plot_learning_curve(dst)  # titled with the shipped name
    return dst


def plot_learning_curve(run: str | Path) -> Path | None:
    """``learning_curve.png``: evaluation return (mean ± std) and training episode return
    vs timesteps, from ``eval/evaluations.npz`` and ``logs/progress.csv``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = Path(run)
    fig, ax = plt.subplots(figsize=(7, 4))
    ev = run / "eval" / "evaluations.npz"
    if ev.is_file():
        d = np.load(ev)
        m, s = d["results"].mean(axis=1), d["results"].std(axis=1)
        ax.plot(d["timesteps"], m, "o-", label="evaluation (deterministic)")
        ax.fill_between(d["timesteps"], m - s, m + s, alpha=0.2)
    prog = run / "logs" / "progress.csv"
    if prog.is_file() and prog.stat().st_size > 0:
        import pandas as pd

        df = pd.read_csv(prog)
        if {"time/total_timesteps", "rollout/ep_rew_mean"} <= set(df.columns):
            ax.plot(df["time/total_timesteps"], df["rollout/ep_rew_mean"], label="training")
    ax.set_xlabel("timesteps")
    ax.set_ylabel("episode return")
    if ax.get_legend_handles_labels()[0]:  # a short run may have logged neither curve yet
        ax.legend()
    ax.set_title(run.name)
    p = run / "learning_curve.png"
    fig.tight_layout()
    fig.savefig(p, dpi=90)
    plt.close(fig)
    return p
