"""A trained agent behind the common controller interface (observation → action).

:func:`load_agent` reads a run directory (``model.zip``, ``vecnormalize.pkl``,
``config.yml``); :class:`AgentController` applies the agent's feature map, the saved
VecNormalize observation statistics, the deterministic policy and the action map to the
env's raw observation — the same chain as in training, so ``turntable benchmark``
judges the agent like any other controller. Its actions pass the lab's blind-travel
shield (:class:`~controllers.shield.BlindShield`) by default: while the detector cannot see
the table, stepping only with direction-robust settings and within a travel budget; with a
valid reading the policy's actions pass unchanged (``shield=False``: the bare policy).
"""

from __future__ import annotations

import pickle
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from controllers.base import Controller, ControllerContext
from controllers.blind import BlindSettings
from controllers.lab import LabBrief
from controllers.shield import BlindShield

from .interface import (
    AGENT_ENV_ID,
    RAW,
    RAW_ENV_ID,
    InterfaceConfig,
    interface_config,
    make_interface,
)
from .train import ALGOS, _algos, frame_stack, run_config

__all__ = ["AgentController", "check_run_config", "interface_of", "load_agent"]


def load_agent(run: str | Path) -> tuple[Any, Any, dict[str, Any]]:
    """(SB3 model, VecNormalize with its statistics, effective config) of a run directory.

    Raises ValueError naming the missing file, or config.yml and what is wrong in it
    (:func:`check_run_config`), before the model is loaded."""
    d = Path(run)
    cfg = run_config(d, f"agent {d}")
    check_run_config(cfg, f"agent {d}: config.yml")
    algo = cfg["run"]["algo"]
    model = _algos()[algo].load(d / "model.zip", device="cpu")
    with (d / "vecnormalize.pkl").open("rb") as fh:
        vecnorm = pickle.load(fh)
    vecnorm.training = False
    return model, vecnorm, cfg


def check_run_config(cfg: dict[str, Any], path: str = "config.yml") -> None:
    """ValueError naming ``path`` (a run's config.yml as :func:`~agents.train.run_config`
    read it; :func:`load_agent` gives ``"agent DIR: config.yml"``) and what is wrong,
    unless what :class:`AgentController` reads of it is there and valid: ``run.algo``, the
    run's entry (``run.env_id``'s; ``PiezoTurntable-v0`` for a run before the env ids),
    its ``frame_stack`` and interface (:func:`interface_of`)."""
    run = cfg["run"]
    algo = run.get("algo")
    if not isinstance(algo, str) or algo not in ALGOS:
        raise ValueError(f"{path}: run.algo={algo!r}: must be one of {', '.join(ALGOS)}")
    env_id = run.get("env_id")
    if env_id is not None and env_id not in (AGENT_ENV_ID, RAW_ENV_ID):
        raise ValueError(
            f"{path}: run.env_id={env_id!r}: must be {AGENT_ENV_ID!r} or {RAW_ENV_ID!r}"
        )
    entry_id = env_id or RAW_ENV_ID  # where a run before the env ids keeps its entry
    if not isinstance(cfg.get(entry_id), dict):
        why = f"run.env_id={env_id!r}" if env_id else "no run.env_id: a run before the env ids"
        raise ValueError(
            f"{path}: no {entry_id!r} entry mapping ({why}); top-level keys: "
            f"{sorted(map(str, cfg))}"
        )
    entry = cfg[entry_id]
    try:
        frame_stack(entry)
        interface_of(cfg)
    except ValueError as e:
        raise ValueError(f"{path}: {str(e).removeprefix('config.yml: ')}") from None


def interface_of(cfg: dict[str, Any]) -> InterfaceConfig | str:
    """The interface a run was trained through, from its config.yml: ``"raw"`` for
    ``PiezoTurntable-v0``; the ``interface`` env kwarg for ``PiezoTurntableAgent-v0``; runs
    made before the env ids (no ``run.env_id``) kept it at the entry's top level.
    ValueError for a missing entry or a bad interface (:func:`interface_config`)."""
    env_id = cfg["run"].get("env_id")
    if env_id is None:
        entry = cfg.get(RAW_ENV_ID)
        if not isinstance(entry, dict):
            raise ValueError(f"config.yml: no {RAW_ENV_ID!r} entry (a run with no run.env_id)")
        return interface_config(entry.get("interface"), f"{RAW_ENV_ID}.interface")
    if env_id == RAW_ENV_ID:
        return RAW
    if env_id != AGENT_ENV_ID:
        raise ValueError(f"config.yml: run.env_id={env_id!r} unknown")
    entry = cfg.get(env_id)
    kwargs = entry.get("env_kwargs", {}) if isinstance(entry, dict) else None
    if not isinstance(kwargs, dict):
        raise ValueError(f"config.yml: {env_id}.env_kwargs: must be a mapping")
    return interface_config(kwargs.get("interface"), f"{env_id}.env_kwargs.interface")


class AgentController(Controller):
    """An SB3 agent as a controller (module docstring).

    Args:
        ctx: plant context of the env it will act on.
        run: the agent's run directory.
        name: controller name (default: the algorithm).
        shield: filter the actions through the blind-travel shield (module docstring).
        blind_settings: the blind set of the shield, or of a residual agent's base (default:
            the shipped one, :mod:`controllers.blind`).
    """

    def __init__(
        self,
        ctx: ControllerContext,
        run: str | Path,
        name: str | None = None,
        *,
        shield: bool = True,
        blind_settings: BlindSettings | None = None,
    ) -> None:
        self.model, self.vecnorm, cfg = load_agent(run)
        self.name = name or cfg["run"]["algo"]
        self.interface = make_interface(ctx, interface_of(cfg), blind_settings=blind_settings)
        # a residual agent's base has its own safety monitor, which the shield would blind
        self.shield = (BlindShield(ctx, blind_settings=blind_settings)
                       if shield and not self.interface.monitors else None)  # fmt: skip
        entry = cfg.get(cfg["run"].get("env_id") or RAW_ENV_ID, {})
        width = self.interface.observation_space.shape[0]
        # the last k normalised features, oldest first, zeros before the episode's first
        # (SB3's VecFrameStack, as in training: rl-zoo3's frame_stack)
        self._stack = np.zeros((frame_stack(entry), width), dtype=np.float32)
        # the turntable's interface state: the plant's step gains (``identify``), a residual
        # agent's base controller
        self._state = self.interface.row_state()
        self._fresh = True  # the next observation is the episode's first
        self._brief: LabBrief | None = None

    @property
    def state(self) -> Any:
        """This turntable's interface state (:meth:`AgentInterface.row_state`): the step
        identifier, a residual agent's base controller, or None; for inspection."""
        return self._state

    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        # the policy sees the observation (and, with frame_stack, the episode's last ones);
        # the shield takes the brief's dead-reckoned start for its blind budget
        self._stack[:] = 0.0
        self._fresh = True
        self._brief = brief
        if self.shield is not None:
            self.shield.reset(obs, brief)

    def _features(self, obs: np.ndarray) -> np.ndarray:
        """This interval's features, in training's order (:meth:`AgentInterface.observe`):
        the episode's first observation resets the step identifier (a residual agent's base,
        with the lab's brief), a later one updates it."""
        first, self._fresh = self._fresh, False
        return self.interface.observe(obs, self._state, first, self._brief)

    def _seen(self, normalized: np.ndarray) -> np.ndarray:
        """What the policy sees of this interval's normalised features: the features
        themselves, or with frame_stack the last k, flattened oldest first."""
        if self._stack.shape[0] == 1:
            return normalized
        self._stack[:-1] = self._stack[1:]
        self._stack[-1] = normalized
        return self._stack.reshape(-1).copy()

    def _shielded(self, obs: np.ndarray, action: np.ndarray) -> np.ndarray:
        return action if self.shield is None else self.shield.filter(obs, action)

    def policy_action(self, obs: np.ndarray) -> np.ndarray:
        """The agent's own action for an env observation ((3,); a residual agent's (1,))."""
        feats = self.vecnorm.normalize_obs(self._features(obs)[None, :])
        action, _ = self.model.predict(self._seen(feats[0])[None, :], deterministic=True)
        return np.asarray(action[0])

    def act(self, obs: np.ndarray) -> np.ndarray:
        action = self.interface.env_action(self.policy_action(obs), obs, self._state)
        return self._shielded(obs, action)

    @classmethod
    def act_many(cls, controllers: Sequence[Controller], obs: np.ndarray) -> np.ndarray:
        """One policy evaluation for every row that shares a model (the benchmark's batch)."""
        first = controllers[0]
        if not all(isinstance(c, AgentController) and c.model is first.model for c in controllers):
            return super().act_many(controllers, obs)
        feats = np.stack([c._features(o) for c, o in zip(controllers, obs, strict=True)])
        normalized = first.vecnorm.normalize_obs(feats)
        seen = np.stack([c._seen(f) for c, f in zip(controllers, normalized, strict=True)])
        actions, _ = first.model.predict(seen, deterministic=True)
        return np.stack(
            [
                c._shielded(o, c.interface.env_action(a, o, c._state))
                for c, a, o in zip(controllers, actions, obs, strict=True)
            ]
        )
