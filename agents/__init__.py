"""Reinforcement-learning agents (stable-baselines3) for ``PiezoTurntable-v0``.

* :mod:`.interface` — the agent's observation features and reduced action;
* :mod:`.identification` — the plant's online step gains as features (``identify``);
* :mod:`.residual` — a residual agent: a baseline plans, the agent scales its aim (``base``);
* :mod:`.vec_env` — the native batched vector env as an SB3 ``VecEnv``;
* :mod:`.train` — training from ``hyperparams/<algo>.yml`` (rl-baselines3-zoo layout);
* :mod:`.controller` — a trained agent behind the common controller interface.

Importing the package registers the env id ``PiezoTurntableAgent-v0`` (the env seen
through :class:`AgentInterface`: 8 features (14 with ``identify``), 3-D structured
action; with a ``base``, a residual agent's 10 features and 1-D action; kwargs: the env's
and ``interface``) and every shipped agent in
``agents/pretrained/<algo>/`` as a controller named after its algorithm, so
``turntable benchmark`` includes it.
"""

from pathlib import Path

import gymnasium as gym

from controllers.registry import available, register

from .controller import AgentController, load_agent
from .interface import AGENT_ENV_ID, AgentInterface, AgentWrapper, InterfaceConfig

__all__ = [
    "AGENT_ENV_ID",
    "PRETRAINED_DIR",
    "AgentController",
    "AgentInterface",
    "AgentWrapper",
    "InterfaceConfig",
    "load_agent",
    "pretrained",
    "register_run",
]

PRETRAINED_DIR = Path(__file__).parent / "pretrained"


def pretrained() -> dict[str, Path]:
    """Shipped agents: algorithm → run directory."""
    if not PRETRAINED_DIR.is_dir():
        return {}
    return {
        d.name: d
        for d in sorted(PRETRAINED_DIR.iterdir())
        if d.is_dir() and (d / "model.zip").is_file()
    }


def _factory(run: Path, name: str):
    return lambda ctx: AgentController(ctx, run, name)


def register_run(name: str, run: str | Path) -> None:
    """Register the agent of a run directory (``python experiments/train_rl.py``) as the
    controller ``name``, e.g. every seed of a multi-seed run for ``turntable benchmark
    --agent``; ValueError if the directory lacks the agent's files."""
    load_agent(run)  # validates: model.zip, vecnormalize.pkl, config.yml
    register(name, _factory(Path(run), name), f"stable-baselines3 agent ({run})")


if AGENT_ENV_ID not in gym.registry:  # the structured-action interface as its own env id
    gym.register(AGENT_ENV_ID, entry_point="agents.interface:make_agent_env",
                 max_episode_steps=100)  # fmt: skip

for _name, _run in pretrained().items():
    if _name not in available():
        register(_name, _factory(_run, _name), f"stable-baselines3 {_name.upper()} agent ({_run})")
