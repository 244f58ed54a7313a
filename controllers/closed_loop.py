"""Closed-loop step-count controller that re-estimates the step size online.

Same planner as the feed-forward controller (:class:`~controllers.feedforward.MapPlanner`),
but the map's displacements are scaled by a gain γ_d per direction d, estimated from the
detector: after every stepping interval whose start and end readings are both inside
the linear range and whose expected move exceeds ``min_learn`` (well above the
detector noise),

    ρ = (Δθ_measured − K·Δu_scan) / D_map,      γ_d ← γ_d + λ·(clip(ρ, 0, 3) − γ_d),

a recursive estimate with forgetting factor 1 − λ (λ = 0.5). γ starts at 1 (the
nominal plant). The angle estimate is the reading whenever it is valid, the expected
move (γ·D) otherwise; a saturated reading places the table beyond the edge on its side.
So the controller survives a plant whose friction, preload or amplifier differ from the
model: it replans every interval from what it measures.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import ControllerContext, Move, StepScanController
from .feedforward import MapPlanner
from .lab import LabBrief
from .step_map import StepMap

__all__ = ["ClosedLoopStepController"]


class ClosedLoopStepController(StepScanController):
    """Step counting on the detector with an online step-size estimate (module docstring).

    Args:
        ctx: plant context; step_map: map (default: the shipped one);
        learning_rate: λ [-]; min_learn: smallest expected move that updates γ [rad].
    """

    name = "closed_loop"

    def __init__(
        self,
        ctx: ControllerContext,
        step_map: StepMap | None = None,
        *,
        learning_rate: float = 0.5,
        min_learn: float = 5e-6,
        **kwargs: Any,
    ) -> None:
        super().__init__(ctx, **kwargs)
        self.planner = MapPlanner(step_map if step_map is not None else StepMap.load(), ctx)
        self.learning_rate = learning_rate
        self.min_learn = min_learn

    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        super().reset(obs, brief)
        self.gain = {1: 1.0, -1: 1.0}
        self._map_move = 0.0  # rad, the map's displacement of the last move (γ = 1)
        self._offset_before = 0.0

    def observe(self, measured: float, saturated: bool) -> None:
        mv = self.last_move
        if mv is not None and not saturated and self.last_measured is not None:
            if abs(self._map_move) >= self.min_learn:
                d = 1 if self._map_move > 0 else -1
                scan = -self.ctx.scan_gain * self._offset_before  # offset ramped to 0
                rho = (measured - self.last_measured - scan) / self._map_move
                g = self.gain[d]
                self.gain[d] = g + self.learning_rate * (float(np.clip(rho, 0.0, 3.0)) - g)
        if mv is not None:
            self.estimate += mv.expected
        if not saturated:
            self.estimate = measured

    def choose_move(self, remaining: float, measured: float, saturated: bool) -> Move | None:
        d = 1 if remaining > 0 else -1
        gain = max(self.gain[d], 0.1)
        move = self.planner.plan(
            remaining,
            self.scan_fraction * self.ctx.scan_range,
            from_rest=self.last_move is None,
            gain=gain,
            amplitude_limit=self.ctx.input_limit - abs(self.offset),
        )
        self._offset_before = self.offset
        self._map_move = 0.0 if move is None else move.expected / gain
        return move
