"""Native vector environment: N turntables in one compiled call per step."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .config import EnvConfig
from .core import TurntableTask
from .piezo_turntable import action_space, observation_space

__all__ = ["PiezoTurntableVectorEnv"]


class PiezoTurntableVectorEnv(VectorEnv):
    """``PiezoTurntable-v0`` × ``num_envs`` as one batched simulation (the registration's
    ``vector_entry_point``).

    Same task, spaces, rewards and arguments as
    :class:`~turntable_env.envs.PiezoTurntableEnv`; every step advances all turntables
    with one call of the compiled reduced integrator (each keeps its own parameters
    under ``randomize``). Episodes end as in the single env, with the time limit
    ``max_episode_steps`` applied here; autoreset is Gymnasium's ``NEXT_STEP`` mode (the
    step after an episode end resets that turntable and returns its first observation,
    reward 0). ``reset(options={"reset_mask": mask, ...})`` resets only the masked ones.

    Args:
        num_envs: number of turntables N.
        max_episode_steps: time limit in steps (None: no limit).
        render_mode: None or ``"rgb_array"`` (a tuple of N frames).
        **kwargs: :class:`~turntable_env.envs.config.EnvConfig` arguments.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array"],
        "render_fps": 100,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = 200,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
            raise ValueError(f"num_envs={num_envs!r}: must be a positive integer")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps={max_episode_steps!r}: must be >= 1 or None")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r}: must be None or 'rgb_array'")
        self.config = EnvConfig(**kwargs)
        self.num_envs = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.config.control_interval}
        self.task = TurntableTask(self.config, self.num_envs)
        self.single_action_space = action_space()
        self.single_observation_space = observation_space(self.task)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._renderer: Any = None

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if isinstance(seed, list):
            seed = seed[0]
        super().reset(seed=seed)
        opts = dict(options or {})
        mask = np.asarray(opts.pop("reset_mask", np.ones(self.num_envs, bool)), dtype=bool)
        if mask.shape != (self.num_envs,):
            raise ValueError(
                f"options['reset_mask']: shape {mask.shape}, expected ({self.num_envs},)"
            )
        for b in np.nonzero(mask)[0]:
            self.task.reset_row(int(b), self.np_random, opts)
        self._autoreset[mask] = False
        t = self.task
        info = {
            "angle_rad": t.angle.copy(),
            "target_rad": t.target.copy(),
            "detector_V": t.detector_v.copy(),
        }
        return t.observation(), info

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        res = self.task.step(np.asarray(actions, dtype=np.float64), self.np_random)
        truncated = res.truncated.copy()
        if self.max_episode_steps is not None:
            truncated |= self.task.step_index >= self.max_episode_steps
        terminated = res.terminated.copy()
        reward = res.reward.copy()
        obs = res.obs
        info = res.info
        done_before = np.nonzero(self._autoreset)[0]
        for b in done_before:
            self.task.reset_row(int(b), self.np_random)
        if done_before.size:
            obs = self.task.observation()
            reward[done_before] = 0.0
            terminated[done_before] = False
            truncated[done_before] = False
        self._autoreset = terminated | truncated
        return obs, reward, terminated, truncated, info

    def render(self) -> tuple[np.ndarray, ...] | None:
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            from .render import TurntableRenderer

            self._renderer = TurntableRenderer(self.task)
        return tuple(self._renderer.draw(b) for b in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
