"""Feed-forward controller: invert the step-size map, then finish in scan mode.

The thesis (§5.2) proposes "a feed-forward controller which uses knowledge of the model".
:class:`MapPlanner` turns the map (:mod:`controllers.step_map`) into the moves one
control interval can make: for every frequency f = m/Δt and amplitude of a waveform
family (default a = 0.9, k = 1, the slew-adapted flyback of Fig. 4.3, whose step grows
monotonically with the amplitude at every swept frequency), the displacement of one
interval, m·s (running) or s_first + (m − 1)·s (from rest). Each interval it picks the
largest move that does not pass the target (and among moves within 10 % of that, the
one with the least C·V² energy, ∝ m·A²) until the residual is inside ½ of the scan
range; the number of intervals and the amplitudes follow.

:class:`FeedForwardController` plans from the start it believes — the reading, or beyond
the detector the lab's dead-reckoned start (:class:`~controllers.lab.LabBrief`) — with
the nominal map and ignores the detector while stepping; the scan PID then finishes on
the detector. Should the residual still exceed the scan range (a plant that differs
from the model), it re-plans from the reading, at most ``max_replans`` times.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import ControllerContext, Move, StepScanController
from .lab import LabBrief
from .step_map import StepMap

__all__ = ["FeedForwardController", "MapPlanner"]


class MapPlanner:
    """The moves of one interval from a step map (see the module docstring).

    Args:
        step_map: the map (its control interval must equal the context's).
        ctx: the plant context (axis, Δt, input limit).
        a, k: the waveform family.
        min_step: smallest useful |step| per period [rad] (below it a setting is not used).
    """

    def __init__(
        self,
        step_map: StepMap,
        ctx: ControllerContext,
        *,
        a: float = 0.9,
        k: float = 1.0,
        min_step: float = 1e-6,
    ) -> None:
        if abs(step_map.control_interval - ctx.control_interval) > 1e-12:
            raise ValueError(
                f"step_map.control_interval={step_map.control_interval!r}: the controller "
                f"runs at {ctx.control_interval!r} s"
            )
        self.a, self.k = a, k
        moves: dict[int, list[tuple[float, float, float, float, float]]] = {1: [], -1: []}
        for f in np.unique(step_map.frequency):
            m = round(f * ctx.control_interval)
            for d in (1, -1):
                for i in step_map.family(ctx.axis, float(f), a, k, d):
                    s = float(step_map.step[i])
                    if s * d < min_step:
                        continue
                    run = m * s
                    rest = float(step_map.first[i]) + (m - 1) * s
                    amp = float(step_map.amplitude[i])
                    moves[d].append((amp, float(f), run, rest, m * amp * amp))
        self.moves = {d: np.array(v) for d, v in moves.items()}
        if any(v.size == 0 for v in self.moves.values()):
            raise ValueError("step_map: no usable step in one of the directions")

    def plan(
        self,
        remaining: float,
        tolerance: float,
        *,
        from_rest: bool,
        gain: float = 1.0,
        amplitude_limit: float = np.inf,
    ) -> Move | None:
        """The largest move towards ``remaining`` [rad] that does not pass the target, or
        None when |remaining| ≤ ``tolerance`` [rad] (the scan finishes) or no move fits.

        ``gain`` scales the map's displacements (an online estimate of the plant)."""
        if abs(remaining) <= tolerance:
            return None
        d = 1 if remaining > 0 else -1
        mv = self.moves[d]
        disp = np.abs(mv[:, 3] if from_rest else mv[:, 2]) * gain
        ok = (disp <= abs(remaining)) & (np.abs(mv[:, 0]) <= amplitude_limit)
        if not ok.any():
            return None
        best = disp[ok].max()
        near = ok & (disp >= 0.9 * best)
        i = int(np.flatnonzero(near)[np.argmin(mv[near, 4])])
        return Move(float(mv[i, 0]), float(mv[i, 1]), self.a, self.k, d * float(disp[i]))


class FeedForwardController(StepScanController):
    """Step-map inversion + scan-mode PID (module docstring).

    Args:
        ctx: plant context; step_map: map (default: the shipped one);
        max_replans: re-plans from the detector allowed per episode.
    """

    name = "feedforward"

    def __init__(
        self,
        ctx: ControllerContext,
        step_map: StepMap | None = None,
        *,
        max_replans: int = 3,
        **kwargs: Any,
    ) -> None:
        super().__init__(ctx, **kwargs)
        self.planner = MapPlanner(step_map if step_map is not None else StepMap.load(), ctx)
        self.max_replans = max_replans

    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        super().reset(obs, brief)
        self.plans = 0  # stepping sequences started (the first plan + re-plans)

    def choose_move(self, remaining: float, measured: float, saturated: bool) -> Move | None:
        new_sequence = self.last_move is None
        if new_sequence and self.plans > self.max_replans:
            return None
        move = self.planner.plan(
            remaining,
            self.scan_fraction * self.ctx.scan_range,
            from_rest=new_sequence,
            amplitude_limit=self.ctx.input_limit - abs(self.offset),
        )
        if move is not None and new_sequence:
            self.plans += 1
        return move
