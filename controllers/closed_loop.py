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

from .base import MIN_LEARN, ControllerContext, Move, StepScanController
from .feedforward import MapPlanner
from .step_gain import StepGains
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
        min_learn: float = MIN_LEARN,
        caution: float = 4.0,
        spread: float = 2.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(ctx, **kwargs)
        self.planner = MapPlanner(step_map if step_map is not None else StepMap.load(), ctx)
        self.gains = StepGains(rate=learning_rate, caution=caution, spread=spread)
        self.min_learn = min_learn

    def observe(self, measured: float, saturated: bool) -> None:
        if self.last_move is not None:
            self.estimate += self.last_move.expected
        if not saturated:
            self.estimate = measured

    def choose_move(self, remaining: float, measured: float, saturated: bool) -> Move | None:
        return self.planner.plan(
            remaining,
            self.scan_fraction * self.ctx.scan_range,
            from_rest=self.last_move is None,
            gains=self.gains,
            amplitude_limit=self.ctx.input_limit - abs(self.offset),
        )

    def search_move(self, direction: int) -> Move | None:
        return self.planner.smallest(
            direction, gains=self.gains, amplitude_limit=self.ctx.input_limit - abs(self.offset)
        )
