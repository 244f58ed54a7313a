"""A residual agent: a baseline controller plans every interval, the agent shapes its aim.

Residual policy learning (Silver et al. 2018, "Residual policy learning"; Johannink et al.
2019, "Residual reinforcement learning for robot control"): the policy acts through a
hand-designed controller instead of replacing it. Here the base is the closed-loop
step-count controller (:class:`~controllers.closed_loop.ClosedLoopStepController`, or the
feed-forward one), one per turntable, with everything a lab gives it: its online step
gains, its safety monitor (a lost spot is searched for, blind travel is budgeted), its
scan PID. Each interval the agent chooses the error the base's step plan aims at,

    remaining' = s·remaining,      s = scale_max^a,      a ∈ [−1, 1]

(:attr:`~controllers.base.StepScanController.remaining_scale`): s < 1 plans short of the
target, s > 1 past the point the base would stop at (its cap at the gain's upper bound
still applies to the scaled aim). a = 0 is the base controller itself, unchanged, so the
agent starts from the base and learns only what it adds; the base's own result is the
ablation to judge that by (the benchmark's ``closed_loop`` row).

Observation (10 features): the 8 of :class:`~agents.interface.AgentInterface`, then

====  ==============================================================================
8     1 while the base is in scan mode (the PID holds the table), else 0
9     log₁₀ γ: the base's online step gain in the error's direction at 6 V
====  ==============================================================================

both as the base stands after the previous interval (it learns from an observation when
it acts on it, after the features are read).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from controllers.base import ControllerContext, StepScanController
from controllers.closed_loop import ClosedLoopStepController
from controllers.feedforward import FeedForwardController
from controllers.lab import LabBrief
from turntable_env.envs.config import OBS, check_action

__all__ = ["BASES", "ResidualInterface", "check_residual"]

BASES: dict[str, type[StepScanController]] = {
    "closed_loop": ClosedLoopStepController,
    "feedforward": FeedForwardController,
}
GAIN_AMPLITUDE = 6.0  # V input: the amplitude whose step gain feature 9 reports


def check_residual(base: Any, scale_max: Any) -> None:
    """ValueError naming the field unless ``base`` is one of :data:`BASES` and
    ``scale_max`` a finite real number > 1 (:class:`~agents.interface.InterfaceConfig`'s
    check, and :class:`ResidualInterface`'s)."""
    if base not in BASES:
        raise ValueError(f"base={base!r}: one of {', '.join(BASES)}")
    if isinstance(scale_max, bool) or not (
        isinstance(scale_max, int | float) and 1.0 < scale_max < math.inf
    ):
        raise ValueError(f"scale_max={scale_max!r}: must be a finite number > 1")


class ResidualInterface:
    """Features and action of a residual agent (module docstring); the methods of
    :class:`~agents.interface.AgentInterface`, with the base controller as each
    turntable's :meth:`row_state`.

    Args:
        plain: the agent interface whose 8 features come first (``features(obs)``).
        base: the base controller's name (:data:`BASES`).
        scale_max: s at a = 1 (and 1/s at a = −1) [-], > 1.
    """

    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    monitors = True  # the base's safety monitor watches the spot: no shield over it

    def __init__(self, plain: Any, base: str, scale_max: float) -> None:
        check_residual(base, scale_max)
        self.ctx: ControllerContext = plain.ctx
        self.base = base
        self._plain = plain
        self.observation_space = gym.spaces.Box(-3.0, 3.0, (10,), np.float32)
        self._log_scale = math.log(scale_max)

    def row_state(self) -> StepScanController:
        """A new base controller for one turntable (reset by the episode's first
        observation in :meth:`observe`)."""
        return BASES[self.base](self.ctx)

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

    def env_action(
        self, action: np.ndarray, obs: np.ndarray, state: StepScanController | None = None
    ) -> np.ndarray:
        """The env action: the base's for ``obs``, its step plan aimed at s·remaining."""
        if state is None:
            raise ValueError("a residual agent's env action needs its turntable's base")
        state.remaining_scale = self.scale(action)
        return state.act(obs)
