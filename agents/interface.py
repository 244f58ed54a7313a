"""What an RL agent sees and does: features of the env observation and a reduced action.

The agents act on ``PiezoTurntable-v0`` through :class:`AgentInterface`, the same in
training (:class:`AgentWrapper`, :class:`NativeVecEnv`) and in the benchmark
(:class:`~agents.controller.AgentController`).

Observation (8 features, from the env's observation o and the plant context):

====  ==============================================================================
0     e/θ_lin, clipped at ±2: the error e = θ* − θ_measured in detector ranges
1     sign(e)·ln(1 + |e|/tol)/ln(1 + θ_lin/tol): the error in decades of the tolerance
2     e/(K·u_max), clipped at ±2: the error in scan ranges
3     saturation of the reading: +1 / −1 at the detector's edges, else 0
4     last scan offset (``last_scan_offset``, fraction of u_max)
5     last amplitude — 6  last frequency — 7  generator phase (``generator_phase``)
====  ==============================================================================

With ``identify`` (:class:`InterfaceConfig`), 6 more: the online step gains of the plant
the agent is on, log₁₀ γ[d, A] for d = +1, −1 at 2, 6 and 10 V
(:class:`~agents.identification.StepIdentifier`, one per turntable, updated from every
observation): what the closed-loop baseline learns, so that one policy can tell plants
that step differently for the same action apart.

Action (3 values in [-1, 1]):

====  ==============================================================================
0     amplitude: |a| < ``deadzone`` → generator idle; otherwise sign(a)·(A_min + (A_max −
      A_min)·(|a| − deadzone)/(1 − deadzone)) [V] input
1     steps per interval m = 1 … ``max_steps`` (frequency m/Δt, whole periods)
2     scan-offset change: u ← clip(u + a·``offset_step``, ±u_max) [V]
====  ==============================================================================

The waveform is the slew-adapted flyback (a = ``ramp_ratio``, k = ``slew_adaptation``),
whose step grows with the amplitude at every frequency (``controllers/data/step_map.csv``).

With a ``base`` (:class:`InterfaceConfig`), the agent is a residual one
(:mod:`agents.residual`): a baseline controller plans every interval and the agent's one
action scales the error that plan aims at; 10 features, 1-D action.

Every interface keeps one state per turntable (:meth:`AgentInterface.row_state`: the step
identifier, a residual agent's base, or None), which its caller passes to ``observe`` and
``env_action``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from controllers.base import SATURATION_FRACTION, ControllerContext
from controllers.lab import LabBrief
from turntable_env.envs.config import (
    A_MAX,
    A_MIN,
    F_MAX,
    MAX_CONTROL_INTERVAL,
    OBS,
    OBSERVATION_NAMES,
    check_action,
)
from turntable_env.validation import check_finite, check_positive, describe

from .identification import StepIdentifier
from .residual import ResidualInterface, check_residual

__all__ = [
    "AGENT_ENV_ID",
    "RAW",
    "RAW_ENV_ID",
    "AgentInterface",
    "AgentWrapper",
    "InterfaceConfig",
    "RawInterface",
    "interface_config",
    "make_agent_env",
    "make_interface",
]

AGENT_ENV_ID = "PiezoTurntableAgent-v0"  # the env seen through AgentInterface (registered)
RAW_ENV_ID = "PiezoTurntable-v0"  # the env itself: 8-D observation, 5-D action
RAW = "raw"  # the interface setting of agents trained on RAW_ENV_ID


@dataclass(frozen=True)
class InterfaceConfig:
    """Parameters of the agent's action map (SI units; see the module docstring)."""

    deadzone: float = 0.2
    amplitude_min: float = 2.0  # V input
    amplitude_max: float = 10.0  # V input
    max_steps: int = 20
    offset_step: float = 2.0  # V per interval
    ramp_ratio: float = 0.9
    slew_adaptation: float = 1.0
    identify: bool = False  # append the online step gains (StepIdentifier) to the features
    # a residual agent (agents/residual.py): the base controller that plans, and the largest
    # factor on the error it aims at; the fields above but ``identify`` are then unused
    base: str | None = None
    scale_max: float = 2.0
    # a residual agent's cost of leaving its base, λ·a² per interval [reward units]: the
    # reward's ``reward_action`` term (agents/residual.py)
    action_cost: float = 0.0

    def __post_init__(self) -> None:
        # every field a finite real number within the range its use gives it, here (the
        # amplifier's input limit and the control interval, which bound amplitude_max,
        # offset_step and max_steps further, when the plant is known: AgentInterface)
        if not 0.0 <= check_finite("deadzone", self.deadzone) < 1.0:
            raise ValueError(f"deadzone={describe(self.deadzone)}: must be in [0, 1)")
        lo = check_positive("amplitude_min", self.amplitude_min)
        if check_positive("amplitude_max", self.amplitude_max) < lo:
            raise ValueError(
                f"amplitude_min={describe(self.amplitude_min)}, "
                f"amplitude_max={describe(self.amplitude_max)}: need 0 < min <= max"
            )
        m = check_finite("max_steps", self.max_steps)
        if m != int(m) or m < 1:
            raise ValueError(f"max_steps={describe(self.max_steps)}: must be a positive integer")
        most = F_MAX * MAX_CONTROL_INTERVAL  # the generator's 2 kHz over the longest interval
        if m > most:
            raise ValueError(
                f"max_steps={describe(self.max_steps)}: must be <= {most:g} "
                f"({F_MAX:g} Hz over at most {MAX_CONTROL_INTERVAL:g} s)"
            )
        check_positive("offset_step", self.offset_step)
        if not A_MIN <= check_finite("ramp_ratio", self.ramp_ratio) <= A_MAX:
            raise ValueError(
                f"ramp_ratio={describe(self.ramp_ratio)}: must be in [{A_MIN}, {A_MAX}] "
                "(the env's ramp_ratio action range)"
            )
        if not 0.0 <= check_finite("slew_adaptation", self.slew_adaptation) <= 1.0:
            raise ValueError(
                f"slew_adaptation={describe(self.slew_adaptation)}: must be in [0, 1] "
                "(the env's slew_adaptation action range; 0: plain sawtooth)"
            )
        if not isinstance(self.identify, bool):
            raise ValueError(f"identify={self.identify!r}: must be true or false")
        if self.base is not None and not isinstance(self.base, str):
            raise ValueError(f"base={describe(self.base)}: must be a base controller's name")
        if self.base is not None:
            check_residual(self.base, self.scale_max, self.action_cost)
            if self.identify:
                raise ValueError("identify=True with a base: the base's step gains are features")
        elif self.action_cost != 0.0:
            raise ValueError(f"action_cost={self.action_cost!r}: only a residual agent's (base)")


class AgentInterface:
    """Feature and action maps for one plant context (module docstring)."""

    action_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
    monitors = False  # no safety monitor of its own (the benchmark's shield filters it)

    def __init__(self, ctx: ControllerContext, config: InterfaceConfig | None = None) -> None:
        self.ctx = ctx
        self.config = config or InterfaceConfig()
        width = 8 + (StepIdentifier.n_features if self.config.identify else 0)
        self.observation_space = gym.spaces.Box(-3.0, 3.0, (width,), np.float32)
        if self.config.max_steps / ctx.control_interval > F_MAX + 1e-9:
            raise ValueError(
                f"max_steps={self.config.max_steps!r}: above 2 kHz at Δt = {ctx.control_interval}"
            )
        # amplitudes the amplifier's input takes (±u_max), offset steps up to a full swing
        if self.config.amplitude_max > ctx.input_limit:
            raise ValueError(
                f"amplitude_max={self.config.amplitude_max!r}: must be <= the amplifier's "
                f"input limit, {ctx.input_limit:g} V"
            )
        if self.config.offset_step > 2.0 * ctx.input_limit:
            raise ValueError(
                f"offset_step={self.config.offset_step!r}: must be <= {2.0 * ctx.input_limit:g} V "
                "(a full swing of the amplifier's input, ±u_max)"
            )
        self._log_norm = math.log1p(ctx.angle_range / ctx.tolerance)

    def identifier(self) -> StepIdentifier | None:
        """A new per-turntable state for :meth:`features` (None without ``identify``)."""
        if not self.config.identify:
            return None
        return StepIdentifier(self.ctx, self.config.ramp_ratio, self.config.slew_adaptation)

    def row_state(self) -> StepIdentifier | None:
        """Each turntable's own state, kept by the caller and passed to :meth:`observe` and
        :meth:`env_action` (every interface has one): here the :meth:`identifier`."""
        return self.identifier()

    def features(self, obs: np.ndarray, ident: StepIdentifier | None = None) -> np.ndarray:
        """(8,) float32 features of one env observation; with ``identify``, (14,): ``ident``
        (this turntable's :meth:`identifier`, already updated with ``obs``) appended."""
        if self.config.identify:
            if ident is None:
                raise ValueError("identify=True: features need the turntable's StepIdentifier")
            return np.concatenate([self._features(obs), ident.features()])
        return self._features(obs)

    def observe(
        self,
        obs: np.ndarray,
        ident: StepIdentifier | None,
        first: bool = False,
        brief: LabBrief | None = None,
    ) -> np.ndarray:
        """The features of ``obs`` for the turntable whose :meth:`identifier` is ``ident``
        (None without ``identify``), which first learns from the interval ``obs`` closes,
        or, for the episode's ``first`` observation, is reset by it: the one order of
        training (:class:`AgentWrapper`, :class:`~agents.vec_env.NativeVecEnv`) and
        benchmark (:class:`~agents.controller.AgentController`). ``brief`` (what the lab
        knows at the start) is for interfaces whose state is a controller; unused here."""
        if ident is not None and first:
            ident.reset(obs)
        elif ident is not None:
            ident.update(obs)
        return self.features(obs, ident)

    def _features(self, obs: np.ndarray) -> np.ndarray:
        c = self.ctx
        obs = c.lab_observation(obs)  # the reading as the table angle, by the rig's calibration
        meas, target = float(obs[OBS.measured_angle_rad]), float(obs[OBS.target_angle_rad])
        e = target - meas
        sat = 0.0
        if abs(meas) >= c.angle_range * SATURATION_FRACTION:
            sat = math.copysign(1.0, meas)
        return np.array(
            [
                np.clip(e / c.angle_range, -2.0, 2.0),
                math.copysign(math.log1p(abs(e) / c.tolerance) / self._log_norm, e),
                np.clip(e / c.scan_range, -2.0, 2.0),
                sat,
                obs[OBS.last_scan_offset],
                obs[OBS.last_amplitude],
                obs[OBS.last_frequency],
                obs[OBS.generator_phase],
            ],
            dtype=np.float32,
        )

    def cost(self, action: np.ndarray) -> float:
        """The reward's action term for ``action`` (every interface has one): 0 here, a
        residual agent's λ·a² (:meth:`~agents.residual.ResidualInterface.cost`)."""
        return 0.0

    def env_action(self, action: np.ndarray, obs: np.ndarray, state: Any = None) -> np.ndarray:
        """The env action for an agent action, given the env observation it answered (and
        the turntable's :meth:`row_state`, unused here); ValueError for anything but 3
        finite real numbers (as ``PiezoTurntable-v0``'s own check:
        :func:`~turntable_env.envs.config.check_action`)."""
        cfg, c = self.config, self.ctx
        a = check_action(action, (3,))
        mag = abs(a[0])
        amp = 0.0
        if mag >= cfg.deadzone:
            frac = (mag - cfg.deadzone) / (1.0 - cfg.deadzone) if cfg.deadzone < 1.0 else 1.0
            amp = math.copysign(
                cfg.amplitude_min + (cfg.amplitude_max - cfg.amplitude_min) * frac, a[0]
            )
        m = 1 + round((cfg.max_steps - 1) * 0.5 * (a[1] + 1.0))
        offset = float(obs[OBS.last_scan_offset]) * c.input_limit + a[2] * cfg.offset_step
        offset = float(np.clip(offset, -c.input_limit, c.input_limit))
        return c.scaling.encode(
            amp, m / c.control_interval, cfg.ramp_ratio, cfg.slew_adaptation, offset
        )


class RawInterface:
    """The env's own observation and 5-D action, unchanged: the raw baseline's interface
    (same methods as :class:`AgentInterface`)."""

    action_space = gym.spaces.Box(-1.0, 1.0, (5,), np.float32)
    monitors = False

    def __init__(self, ctx: ControllerContext) -> None:
        from turntable_env.envs.piezo_turntable import observation_space

        self.ctx = ctx
        self.observation_space = observation_space(ctx.angle_range)

    def row_state(self) -> None:
        return None

    def observe(
        self, obs: np.ndarray, ident: None, first: bool = False, brief: LabBrief | None = None
    ) -> np.ndarray:
        return self.features(obs)

    def features(self, obs: np.ndarray, ident: None = None) -> np.ndarray:
        # the default env's 8 components (an env with ``detector_y`` appends the y channel)
        return np.asarray(obs[..., : len(OBSERVATION_NAMES)], dtype=np.float32)

    def cost(self, action: np.ndarray) -> float:
        return 0.0

    def env_action(self, action: np.ndarray, obs: np.ndarray, state: None = None) -> np.ndarray:
        return check_action(action, (5,)).astype(np.float32)


def interface_config(value: Any, name: str = "interface") -> InterfaceConfig:
    """An :class:`InterfaceConfig` from ``value``: None (the defaults), an InterfaceConfig,
    or a mapping of its fields; anything else, or an unknown key, is a ValueError naming
    ``name`` and the key or the type (a field's bad value: its own ValueError, after
    ``name``)."""
    if value is None:
        return InterfaceConfig()
    if isinstance(value, InterfaceConfig):
        return value
    if not isinstance(value, Mapping):
        raise ValueError(
            f"{name}={describe(value)}: must be a mapping of InterfaceConfig fields, "
            f"not a {type(value).__name__}"
        )
    known = [f.name for f in dataclasses.fields(InterfaceConfig)]
    unknown = [k for k in value if k not in known]
    if unknown:
        raise ValueError(
            f"{name}: unknown key {describe(unknown[0])} (the fields: {', '.join(known)})"
        )
    try:
        return InterfaceConfig(**value)
    except ValueError as e:  # a field's value: where it was given, e.g. in a config.yml
        raise ValueError(f"{name}: {e}") from None


def make_interface(
    ctx: ControllerContext,
    config: InterfaceConfig | Mapping[str, Any] | str | None = None,
    blind_settings: Any = None,
) -> AgentInterface | RawInterface | ResidualInterface:
    """:class:`RawInterface` for ``config == RAW``; a residual agent's
    (:class:`~agents.residual.ResidualInterface`, its base stepping blind with
    ``blind_settings``, a :class:`~controllers.blind.BlindSettings` or None for the base's
    default) for a config with a ``base``; else :class:`AgentInterface` (a mapping:
    :func:`interface_config`'s)."""
    if isinstance(config, Mapping):
        config = interface_config(config)
    if isinstance(config, str):
        if config != RAW:
            raise ValueError(f"interface={config!r}: an InterfaceConfig, None or {RAW!r}")
        return RawInterface(ctx)
    if config is not None and config.base is not None:
        return ResidualInterface(
            AgentInterface(ctx), config.base, config.scale_max, config.action_cost,
            blind_settings=blind_settings,
        )
    return AgentInterface(ctx, config)


def make_agent_env(
    interface: Mapping[str, Any] | InterfaceConfig | None = None, **env_kwargs: Any
) -> gym.Env:
    """``PiezoTurntableAgent-v0``: ``PiezoTurntable-v0`` (``env_kwargs``) seen through
    :class:`AgentInterface` with ``interface`` (:class:`InterfaceConfig` fields): the
    8 features and the 3-D structured action the shipped agents use (with a ``base``, a
    residual agent's 10 features and 1-D action: :mod:`agents.residual`)."""
    from turntable_env.envs import PiezoTurntableEnv

    cfg = interface_config(interface)  # checked before the env is built
    return AgentWrapper(PiezoTurntableEnv(**env_kwargs), cfg)


class AgentWrapper(gym.Wrapper):
    """``PiezoTurntable-v0`` seen through :class:`AgentInterface` (single env)."""

    def __init__(self, env: gym.Env, config: InterfaceConfig | None = None) -> None:
        super().__init__(env)
        self.interface = make_interface(ControllerContext.from_env(env), config)
        self.observation_space = self.interface.observation_space
        self.action_space = self.interface.action_space
        self._raw: np.ndarray | None = None
        self._state = self.interface.row_state()

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._raw = obs
        return self.interface.observe(obs, self._state, first=True), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._raw is None:
            raise gym.error.ResetNeeded("PiezoTurntableAgent-v0: call reset() before step()")
        act = self.interface.env_action(action, self._raw, self._state)
        cost = self.interface.cost(action)
        obs, r, term, trunc, info = self.env.step(act)
        self._raw = obs
        # the reward's action term: the interface's cost of the action (0 but a residual
        # agent's with an action_cost), a component in info as the env's own are
        info = {**info, "reward_action": 0.0 - cost}
        return self.interface.observe(obs, self._state), r - cost, term, trunc, info
