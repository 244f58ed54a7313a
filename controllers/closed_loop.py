"""Closed-loop step-count controller that re-estimates the step size online.

Same planner as the feed-forward controller (:class:`~controllers.feedforward.MapPlanner`),
but it replans from the detector every interval, with the map's displacements scaled by
the online step gains (:class:`~controllers.step_gain.StepGains`): per direction d and
amplitude A, after every stepping interval whose start and end readings are both inside
the linear range and whose map move exceeds ``min_learn`` (well above the detector noise),

    ρ = (Δθ_measured − K·Δu_scan) / D_map,      γ[d, A] ← γ[d, A] + λ·(clip(ρ) − γ[d, A]),

a recursive estimate with forgetting factor 1 − λ (λ = 0.5), the first measurement of an
amplitude replacing the prior 1. No move may pass the target at its gain's upper bound
(``caution``× the map with nothing measured, ``spread``× the estimate for an amplitude not
yet measured). The angle estimate is the reading whenever it is valid, the expected move
(γ·D) otherwise; a saturated reading places the table beyond the edge on its side, and a
lost spot is searched for (:class:`~controllers.base.StepScanController`). So the
controller meets a plant whose friction, preload, amplifier or rig differ from the model.
"""

from __future__ import annotations

from typing import Any

from .base import MIN_LEARN, ControllerContext, Move, StepScanController
from .blind import BlindSettings
from .feedforward import MapPlanner
from .step_gain import StepGains
from .step_map import StepMap

__all__ = ["ClosedLoopStepController"]


class ClosedLoopStepController(StepScanController):
    """Step counting on the detector with an online step-size estimate (module docstring).

    Args:
        ctx: plant context; step_map: map (default: the shipped one);
        learning_rate: λ [-]; min_learn: smallest map move that updates γ [rad];
        caution, spread: the gains' upper bounds (:class:`~controllers.step_gain.StepGains`);
        blind_settings: the settings it may step with blind
            (:class:`~controllers.feedforward.MapPlanner`).
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
        blind_settings: BlindSettings | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(ctx, **kwargs)
        self.planner = MapPlanner(step_map if step_map is not None else StepMap.load(), ctx,
                                  blind_settings=blind_settings)  # fmt: skip
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
            blind=self.blind_approach(saturated),
            room=self.room_behind(remaining, measured, saturated),
        )

    def search_move(self, direction: int, saturated: bool = False) -> Move | None:
        return self.planner.smallest(
            direction,
            gains=self.gains,
            amplitude_limit=self.ctx.input_limit - abs(self.offset),
            blind=self.blind_approach(saturated),
        )
