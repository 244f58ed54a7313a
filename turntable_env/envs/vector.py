"""Native vector environment: N turntables in one compiled call per step."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..validation import check_int
from .config import MAX_NUM_ENVS, make_config
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
    ``max_episode_steps`` applied here.

    Seeds and noise: every turntable has its own random generator, so row i is bit for bit
    the single env seeded the same way — its episodes, plant draws and detector noise
    (tested, noise on). ``reset(seed=s)`` seeds row i with ``s + i`` (Gymnasium's
    convention for its vector envs), ``reset(seed=[s0, s1, ...])`` row by row (None: fresh
    entropy); ``reset()`` continues each row's stream.

    Autoreset: Gymnasium's ``NEXT_STEP`` mode. The step after an episode end resets that
    turntable and returns its first observation, reward 0, ``terminated`` and ``truncated``
    False, and an ``info`` whose entries for that row describe the new episode at its
    start (angle, target, detector, time 0; no steps, energy or reward yet), as the
    single env's ``reset`` info does. ``reset(options={"reset_mask": mask, ...})``
    resets only the masked ones.

    Args:
        num_envs: number of turntables N, 1 … :data:`~.config.MAX_NUM_ENVS` (8192).
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
        if num_envs > MAX_NUM_ENVS:  # before anything is allocated (~62 kB a turntable)
            raise ValueError(f"num_envs={num_envs!r}: must be <= {MAX_NUM_ENVS}")
        if max_episode_steps is not None:
            check_int("max_episode_steps", max_episode_steps, 1)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r}: must be None or 'rgb_array'")
        self.config = make_config(kwargs)
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
        self._rngs = [np.random.default_rng() for _ in range(self.num_envs)]
        self._renderer: Any = None
        self._reset_done = False

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        seeds = self._row_seeds(seed)
        super().reset(seed=seeds[0] if seeds is not None else None)
        if seeds is not None:
            self._rngs = [np.random.default_rng(s) for s in seeds]
        if options is not None and not isinstance(options, Mapping):
            raise ValueError(f"options={options!r}: must be a dict (or None)")
        opts = dict(options or {})
        mask = np.asarray(opts.pop("reset_mask", np.ones(self.num_envs, bool)))
        if mask.shape != (self.num_envs,) or mask.dtype != bool:
            raise ValueError(
                f"options['reset_mask']: shape {mask.shape} of {mask.dtype}, expected "
                f"({self.num_envs},) of bool"
            )
        for b in np.nonzero(mask)[0]:
            self.task.reset_row(int(b), self._rngs[b], opts)
        self._autoreset[mask] = False
        self._reset_done = True
        t = self.task
        info = {
            "angle_rad": t.angle.copy(),
            "target_rad": t.target.copy(),
            "detector_V": t.detector_v.copy(),
        }
        return t.observation(), info

    def _row_seeds(self, seed: Any) -> list[int | None] | None:
        """One seed per row: ``s + i`` for an int, the list as given, or None."""
        if seed is None:
            return None
        if isinstance(seed, list | tuple):
            if len(seed) != self.num_envs:
                raise ValueError(f"seed: {len(seed)} seeds for {self.num_envs} envs")
            return [None if s is None else check_int("seed", s, 0) for s in seed]
        s = check_int("seed", seed, 0)
        return [s + i for i in range(self.num_envs)]

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if not self._reset_done:
            raise ResetNeeded("PiezoTurntableVectorEnv: call reset() before step()")
        # simulate and observe: each row's detector noise from its own generator (none
        # drawn for a row about to be reset: its observation is discarded)
        normals = np.array(
            [0.0 if done else g.normal(0.0, 1.0, size=1)[0]
             for g, done in zip(self._rngs, self._autoreset, strict=True)]
        )  # fmt: skip
        res = self.task.step(actions, self._rngs[0], normals=normals)
        truncated = res.truncated.copy()
        if self.max_episode_steps is not None:
            truncated |= self.task.step_index >= self.max_episode_steps
        terminated = res.terminated.copy()
        reward = res.reward.copy()
        obs = res.obs
        info = {k: np.array(v, copy=True) for k, v in res.info.items()}
        # autoreset (NEXT_STEP): the rows that ended last step start a new episode
        done_before = np.nonzero(self._autoreset)[0]
        for b in done_before:
            self.task.reset_row(int(b), self._rngs[b])
        if done_before.size:
            t = self.task
            obs = t.observation()
            reward[done_before] = 0.0
            terminated[done_before] = False
            truncated[done_before] = False
            start = {"angle_rad": t.angle, "target_rad": t.target, "detector_V": t.detector_v}
            for k, v in info.items():
                v[done_before] = start[k][done_before] if k in start else 0
            info["distance_rad"][done_before] = np.abs(t.angle - t.target)[done_before]
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
