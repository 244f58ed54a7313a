"""A residual agent: a baseline controller plans every interval, the agent shapes its aim.

Residual policy learning (Silver et al. 2018, "Residual policy learning"; Johannink et al.
2019, "Residual reinforcement learning for robot control"): the policy acts through a
hand-designed controller instead of replacing it. Here the base is one of the step-count
controllers (:data:`BASES`: the closed-loop one, :class:`~controllers.closed_loop.
ClosedLoopStepController`, the fuzzy one of the thesis's §5.2, or the feed-forward one),
one per turntable, with everything a lab gives it: its online step gains, its safety
monitor (a lost spot is searched for, blind travel is budgeted), its scan PID. Each
interval the agent chooses the error the base's step plan aims at,

    remaining' = s·remaining,      s = scale_max^a,      a ∈ [−1, 1]

(:attr:`~controllers.base.StepScanController.remaining_scale`): s < 1 plans short of the
target, s > 1 past the point the base would stop at (its cap at the gain's upper bound
still applies to the scaled aim). For the fuzzy base s is the input scaling factor of its
rules: they see s·e, in nominal steps (:meth:`~controllers.fuzzy.FuzzyStepController.
choose_move`), the classic tuning knob of a fuzzy controller, set here each interval.
a = 0 is the base controller itself, unchanged, so the agent starts from the base and
learns only what it adds; the base's own result is the ablation to judge that by (the
benchmark's row of the base's name).

Observation (10 features): the 8 of :class:`~agents.interface.AgentInterface`, then

====  ==============================================================================
8     1 while the base is in scan mode (the PID holds the table), else 0
9     log₁₀ γ: the base's online step gain in the error's direction at 6 V
====  ==============================================================================

both as the base stands after the previous interval (it learns from an observation when
it acts on it, after the features are read).

Reward: the env's, less an action cost λ·a² per interval (``action_cost``, default 0;
``reward_action`` in info), the usual regulariser of a residual policy toward its base.
The action matters only while the base steps: while its scan PID holds the table, a
changes nothing, and without a cost the policy's output there is whatever training left,
which a new target then meets (docs/rl.md, result 5).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from controllers.base import ControllerContext, StepScanController
from controllers.blind import BlindSettings, check_blind_settings
from controllers.closed_loop import ClosedLoopStepController
from controllers.feedforward import FeedForwardController
from controllers.fuzzy import FuzzyStepController
from controllers.lab import LabBrief
from turntable_env.envs.config import OBS, check_action

__all__ = ["BASES", "ResidualInterface", "check_residual"]

BASES: dict[str, type[StepScanController]] = {
    "closed_loop": ClosedLoopStepController,
    "feedforward": FeedForwardController,
    "fuzzy": FuzzyStepController,
}
GAIN_AMPLITUDE = 6.0  # V input: the amplitude whose step gain feature 9 reports


def _real(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def check_residual(base: Any, scale_max: Any, action_cost: Any = 0.0) -> None:
    """ValueError naming the field unless ``base`` is one of :data:`BASES`, ``scale_max`` a
    finite real number > 1 and ``action_cost`` a finite real number ≥ 0
    (:class:`~agents.interface.InterfaceConfig`'s check, and :class:`ResidualInterface`'s)."""
    if base not in BASES:
        raise ValueError(f"base={base!r}: one of {', '.join(BASES)}")
    if not (_real(scale_max) and 1.0 < scale_max < math.inf):
        raise ValueError(f"scale_max={scale_max!r}: must be a finite number > 1")
    if not (_real(action_cost) and 0.0 <= action_cost < math.inf):
        raise ValueError(f"action_cost={action_cost!r}: must be a finite number >= 0")


class ResidualInterface:
    """Features and action of a residual agent (module docstring); the methods of
    :class:`~agents.interface.AgentInterface`, with the base controller as each
    turntable's :meth:`row_state`.

    Args:
        plain: the agent interface whose 8 features come first (``features(obs)``).
        base: the base controller's name (:data:`BASES`).
        scale_max: s at a = 1 (and 1/s at a = −1) [-], > 1.
        action_cost: λ of the reward's action term −λ·a² per interval [reward units], ≥ 0
            (:meth:`cost`).
        blind_settings: the base's blind set (:mod:`controllers.blind`; None: the base's
            default).
    """

    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    monitors = True  # the base's safety monitor watches the spot: no shield over it

    def __init__(self, plain: Any, base: str, scale_max: float, action_cost: float = 0.0,
                 blind_settings: BlindSettings | None = None) -> None:  # fmt: skip
        check_residual(base, scale_max, action_cost)
        self.blind_settings = check_blind_settings(blind_settings)
        self.action_cost = float(action_cost)
        self.ctx: ControllerContext = plain.ctx
        self.base = base
        self._plain = plain
        self.observation_space = gym.spaces.Box(-3.0, 3.0, (10,), np.float32)
        self._log_scale = math.log(scale_max)

    def row_state(self) -> StepScanController:
        """A new base controller for one turntable (reset by the episode's first
        observation in :meth:`observe`)."""
        if self.blind_settings is None:
            return BASES[self.base](self.ctx)
        return BASES[self.base](self.ctx, blind_settings=self.blind_settings)

    def observe(
        self,
        obs: np.ndarray,
        state: StepScanController,
        first: bool = False,
        brief: LabBrief | None = None,
    ) -> np.ndarray:
        """The features of ``obs``; the episode's ``first`` observation resets the base
        with ``brief`` (what the lab knows; None: only the commanded target, as in
        training, whose starts the detector may not see)."""
        if first:
            if brief is None:
                target = float(self.ctx.lab_observation(obs)[OBS.target_angle_rad])
                brief = LabBrief(target)
            state.reset(obs, brief)
        return self.features(obs, state)

    def features(self, obs: np.ndarray, state: StepScanController) -> np.ndarray:
        """(10,) float32 features of one env observation and its turntable's base."""
        lab = self.ctx.lab_observation(obs)
        meas = float(lab[OBS.measured_angle_rad])
        err = float(lab[OBS.target_angle_rad]) - meas
        d = 1 if err >= 0.0 else -1
        g = 1.0 if state.gains is None else float(state.gains.estimate(d, GAIN_AMPLITUDE)[0][0])
        extra = np.array([float(state.mode == "scan"), math.log10(g)], dtype=np.float32)
        return np.concatenate([self._plain.features(obs), extra])

    def scale(self, action: np.ndarray) -> float:
        """s = scale_max^a of an agent action (ValueError unless 1 finite real number)."""
        a = float(check_action(action, (1,))[0])  # clipped to [-1, 1]
        return math.exp(a * self._log_scale)

    def cost(self, action: np.ndarray) -> float:
        """λ·a² of an agent action (a clipped to [−1, 1]): the price of leaving the base,
        subtracted from the reward in training (``reward_action`` in info). Where the
        action changes nothing (the base holds the target by its scan PID) only this term
        sees it, so the policy learns a = 0 there and leaves the base alone wherever
        training showed no gain (module docstring)."""
        if self.action_cost == 0.0:
            return 0.0
        a = float(check_action(action, (1,))[0])
        return self.action_cost * a * a

    def env_action(
        self, action: np.ndarray, obs: np.ndarray, state: StepScanController | None = None
    ) -> np.ndarray:
        """The env action: the base's for ``obs``, its step plan aimed at s·remaining."""
        if state is None:
            raise ValueError("a residual agent's env action needs its turntable's base")
        state.remaining_scale = self.scale(action)
        return state.act(obs)
