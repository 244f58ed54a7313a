"""The native batched vector env as a stable-baselines3 ``VecEnv``.

:class:`NativeVecEnv` runs N turntables in one compiled call per step
(:class:`~turntable_env.envs.PiezoTurntableVectorEnv`) and shows SB3 the agent's
features and actions (:class:`~agents.interface.AgentInterface`). SB3 expects a finished
turntable to be reset within the same step, with the last observation in
``info["terminal_observation"]``: rows that end are reset at once through the vector
env's ``reset_mask`` (so its own next-step autoreset never fires).

Training domains: the N turntables may be split into groups that each run their own
plant distribution (``domains``), e.g. the nominal turntable randomised about Table D.1
beside the calibrated plant drawn from its calibration's posterior (``plant:
calibrated``, ``randomize: true``). Each group is its own batched vector env with its own
:class:`~controllers.base.ControllerContext` (detector range, scan gain), so an agent's
features are computed as the benchmark computes them on that plant.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from controllers.base import ControllerContext
from turntable_env.envs import PiezoTurntableVectorEnv

from .interface import InterfaceConfig, make_interface

__all__ = ["NativeVecEnv", "domain_kwargs", "domain_sizes"]


class NativeVecEnv(VecEnv):
    """N turntables for SB3 (module docstring).

    Args:
        num_envs: N; max_episode_steps: time limit; interface: action-map parameters
        (:class:`~agents.interface.InterfaceConfig`), or ``"raw"``: the env's own
        observation and 5-D action;
        domains: None (one group: ``env_kwargs``), or the groups as
            ``[{"share": s, "env_kwargs": {...}}, ...]``: each group's rows run
            ``env_kwargs`` updated by its own (a group's ``plant`` replaces ``params``);
            the rows are split by the shares (:func:`domain_sizes`), in order;
        **env_kwargs: :class:`~turntable_env.envs.config.EnvConfig` arguments.
    """

    def __init__(
        self,
        num_envs: int,
        max_episode_steps: int = 100,
        interface: InterfaceConfig | str | None = None,
        domains: Sequence[Mapping[str, Any]] | None = None,
        **env_kwargs: Any,
    ) -> None:
        groups = domain_kwargs(env_kwargs, domains)
        sizes = domain_sizes(num_envs, [share for share, _ in groups])
        self.venvs = [
            PiezoTurntableVectorEnv(n, max_episode_steps, **kw)
            for n, (_, kw) in zip(sizes, groups, strict=True)
        ]
        self.interfaces = [
            make_interface(ControllerContext.from_config(v.config), interface) for v in self.venvs
        ]
        self.rows = np.cumsum([0, *sizes])  # group g holds rows rows[g]:rows[g + 1]
        # the agent interface's spaces are the same on every plant (the raw interface's
        # observation bounds are the first group's detector range: SB3 reads only the shape)
        spaces = self.interfaces[0]
        super().__init__(num_envs, spaces.observation_space, spaces.action_space)
        # per row: the turntable's own interface state (the online step gains, where the
        # interface identifies; a residual agent's base controller)
        self._states = [
            self.interfaces[g].row_state()
            for g, n in enumerate(sizes)
            for _ in range(n)
        ]
        self._seed: int | None = None
        self._raw = np.zeros((num_envs, 8), dtype=np.float32)
        self._actions = np.zeros((num_envs, spaces.action_space.shape[0]))

    def _slices(self) -> list[slice]:
        return [slice(int(a), int(b)) for a, b in zip(self.rows[:-1], self.rows[1:], strict=True)]

    def _features(
        self, raw: np.ndarray, g: int, rows: Sequence[int], new: bool = False
    ) -> np.ndarray:
        """Group g's features of rows ``rows`` (their raw observations ``raw``; ``new``:
        each the first of its episode), through :meth:`AgentInterface.observe`."""
        iface = self.interfaces[g]
        return np.stack(
            [iface.observe(o, self._states[i], new) for o, i in zip(raw, rows, strict=True)]
        )

    def reset(self) -> np.ndarray:
        feats, raws = [], []
        for g, (v, sl) in enumerate(zip(self.venvs, self._slices(), strict=True)):
            rows = range(sl.start, sl.stop)  # row i is seeded s + i, as with one domain
            seeds = None if self._seed is None else [self._seed + i for i in rows]
            obs, _ = v.reset(seed=seeds)
            raws.append(obs)
            feats.append(self._features(obs, g, rows, new=True))
        self._seed = None
        self._raw = np.concatenate(raws)
        return np.concatenate(feats)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        parts = [self._step_group(g, sl) for g, sl in enumerate(self._slices())]
        self._raw = np.concatenate([p[0] for p in parts])
        feats = np.concatenate([p[1] for p in parts])
        reward = np.concatenate([p[2] for p in parts])
        dones = np.concatenate([p[3] for p in parts])
        infos = [i for p in parts for i in p[4]]
        return feats, reward, dones, infos

    def _step_group(self, g: int, sl: slice) -> tuple:
        """Group g's step: its rows' env actions, one batched step, its finished rows reset."""
        iface, venv = self.interfaces[g], self.venvs[g]
        rows = range(sl.start, sl.stop)
        acts, raws = self._actions[sl], self._raw[sl]
        env_act = np.stack(
            [
                iface.env_action(a, o, self._states[i])
                for a, o, i in zip(acts, raws, rows, strict=True)
            ]
        )
        cost = np.array([iface.cost(a) for a in acts])  # the reward's action term (wrapper's)
        obs, reward, term, trunc, info = venv.step(env_act)
        reward = reward - cost
        dones = term | trunc
        rows = np.arange(sl.start, sl.stop)  # as an array, for the finished rows' mask
        feats = self._features(obs, g, rows)
        infos: list[dict[str, Any]] = [
            {**{k: v[i].item() for k, v in info.items()}, "reward_action": 0.0 - cost[i].item()}
            for i in range(venv.num_envs)
        ]
        if dones.any():
            for i in np.flatnonzero(dones):
                infos[i]["terminal_observation"] = feats[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
            new_obs, _ = venv.reset(options={"reset_mask": dones})
            obs = obs.copy()
            obs[dones] = new_obs[dones]
            feats[dones] = self._features(new_obs[dones], g, rows[dones], new=True)
        return obs, feats, reward.astype(np.float32), dones, infos

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        self._seed = seed
        return [seed] * self.num_envs

    def close(self) -> None:
        for v in self.venvs:
            v.close()

    def _group(self, i: int) -> PiezoTurntableVectorEnv:
        """The batched env that holds row i."""
        return self.venvs[int(np.searchsorted(self.rows, i, side="right")) - 1]

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self._group(i), attr_name) for i in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        for i in self._indices(indices):  # on the row's group (a group's rows share it)
            setattr(self._group(i), attr_name, value)

    def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list:
        return [
            getattr(self._group(i), method_name)(*args, **kwargs) for i in self._indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def _indices(self, indices: Any) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)


def domain_kwargs(
    env_kwargs: Mapping[str, Any], domains: Sequence[Mapping[str, Any]] | None
) -> list[tuple[float, dict[str, Any]]]:
    """(share, env kwargs) of each training domain (:class:`NativeVecEnv`); ValueError
    naming the domain and key for a bad entry."""
    if domains is None:
        return [(1.0, dict(env_kwargs))]
    if isinstance(domains, str | bytes | Mapping) or not isinstance(domains, Sequence):
        raise ValueError(f"domains={domains!r}: must be a list of {{share, env_kwargs}}")
    if not domains:
        raise ValueError("domains=[]: give at least one domain (or None)")
    out = []
    for k, d in enumerate(domains):
        if not isinstance(d, Mapping) or set(d) - {"share", "env_kwargs"}:
            raise ValueError(f"domains[{k}]={d!r}: must be a mapping of share and env_kwargs")
        share = d.get("share", 1.0)
        if isinstance(share, bool) or not isinstance(share, int | float) or not share > 0:
            raise ValueError(f"domains[{k}].share={share!r}: must be a positive number")
        own = d.get("env_kwargs", {}) or {}
        if not isinstance(own, Mapping):
            raise ValueError(f"domains[{k}].env_kwargs={own!r}: must be a mapping")
        kw = dict(env_kwargs)
        if "plant" in own:
            kw.pop("params", None)
        kw.update(own)
        out.append((float(share), kw))
    return out


def domain_sizes(num_envs: int, shares: Sequence[float]) -> list[int]:
    """Rows per domain: ``num_envs`` split in proportion to ``shares`` by largest
    remainders, at least one row each; ValueError if there are fewer rows than domains."""
    if num_envs < len(shares):
        raise ValueError(f"num_envs={num_envs}: fewer rows than the {len(shares)} domains")
    w = np.asarray(shares, float) / float(np.sum(shares))
    sizes = np.maximum(np.floor(w * num_envs).astype(int), 1)
    while sizes.sum() > num_envs:  # the floors of one-row minimums overshot
        sizes[np.argmax(sizes)] -= 1
    order = np.argsort(-(w * num_envs - np.floor(w * num_envs)), kind="stable")
    for i in order[: num_envs - sizes.sum()]:
        sizes[i] += 1
    return [int(x) for x in sizes]
