"""The native batched vector env as a stable-baselines3 ``VecEnv``.

:class:`NativeVecEnv` runs N turntables in one compiled call per step
(:class:`~turntable_env.envs.PiezoTurntableVectorEnv`) and shows SB3 the agent's
features and actions (:class:`~agents.interface.AgentInterface`). SB3 expects a finished
turntable to be reset within the same step, with the last observation in
``info["terminal_observation"]``: rows that end are reset at once through the vector
env's ``reset_mask`` (so its own next-step autoreset never fires).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from controllers.base import ControllerContext
from turntable_env.envs import PiezoTurntableVectorEnv

from .interface import InterfaceConfig, make_interface

__all__ = ["NativeVecEnv"]


class NativeVecEnv(VecEnv):
    """N turntables for SB3 (module docstring).

    Args:
        num_envs: N; max_episode_steps: time limit; interface: action-map parameters
        (:class:`~agents.interface.InterfaceConfig`), or ``"raw"``: the env's own
        observation and 5-D action;
        **env_kwargs: :class:`~turntable_env.envs.config.EnvConfig` arguments.
    """

    def __init__(
        self,
        num_envs: int,
        max_episode_steps: int = 100,
        interface: InterfaceConfig | str | None = None,
        **env_kwargs: Any,
    ) -> None:
        self.venv = PiezoTurntableVectorEnv(num_envs, max_episode_steps, **env_kwargs)
        ctx = ControllerContext.from_config(self.venv.config)
        self.interface = make_interface(ctx, interface)
        super().__init__(num_envs, self.interface.observation_space, self.interface.action_space)
        self._seed: int | None = None
        self._raw = np.zeros((num_envs, 8), dtype=np.float32)
        self._actions = np.zeros((num_envs, self.interface.action_space.shape[0]))

    def _features(self, raw: np.ndarray) -> np.ndarray:
        return np.stack([self.interface.features(o) for o in raw])

    def reset(self) -> np.ndarray:
        obs, _info = self.venv.reset(seed=self._seed)
        self._seed = None
        self._raw = obs
        return self._features(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        env_act = np.stack(
            [self.interface.env_action(a, o) for a, o in zip(self._actions, self._raw, strict=True)]
        )
        obs, reward, term, trunc, info = self.venv.step(env_act)
        dones = term | trunc
        feats = self._features(obs)
        infos: list[dict[str, Any]] = [
            {k: v[i].item() for k, v in info.items()} for i in range(self.num_envs)
        ]
        if dones.any():
            for i in np.flatnonzero(dones):
                infos[i]["terminal_observation"] = feats[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
            new_obs, _ = self.venv.reset(options={"reset_mask": dones})
            obs = obs.copy()
            obs[dones] = new_obs[dones]
            feats[dones] = self._features(new_obs[dones])
        self._raw = obs
        return feats, reward.astype(np.float32), dones, infos

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        self._seed = seed
        return [seed] * self.num_envs

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.venv, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list:
        return [getattr(self.venv, method_name)(*args, **kwargs)] * len(self._indices(indices))

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def _indices(self, indices: Any) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)
