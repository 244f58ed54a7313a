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
the map scaled by the step gains its stepping intervals measured so far
(:class:`~controllers.step_gain.StepGains`: per direction and amplitude; before any
measurement its moves are small enough for a plant stepping 4× the map), and ignores
the detector while stepping (its angle is dead-reckoned, unless a valid reading shows the
table inside the detector while the estimate has it beyond); the scan PID then finishes on
the detector. Should the residual still exceed the scan range, it re-plans from the
reading with what it has learned, at most ``max_replans`` times per commanded target (a
tracking task's new set point is a new plan, not a re-plan). A saturated reading
with no planned move left starts the safety monitor's search back
(:meth:`~controllers.base.StepScanController.search_move`).
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from .base import ControllerContext, Move, StepScanController
from .blind import FAMILY, BlindSettings, check_blind_settings
from .lab import LabBrief
from .step_gain import StepGains
from .step_map import StepMap

__all__ = ["REVERSAL", "FeedForwardController", "MapPlanner"]

# the backward step an unconfirmed move is sized for, × the map's forward one [-]: the cases
# that step backwards in ``experiments/blind_settings.py --check translation --asymmetry 0.3``
# go back 0.50–0.62 of it at the median and 0.85–1.49 at the 90th percentile, per frequency;
# a larger reversal loses the spot behind, and the safety monitor then holds
REVERSAL = 1.0


class MapPlanner:
    """The moves of one interval from a step map (see the module docstring).

    Args:
        step_map: the map (its control interval must equal the context's).
        ctx: the plant context (axis, Δt, input limit).
        a, k: the waveform family.
        min_step: smallest useful |step| per period [rad] (below it a setting is not used).
        min_amplitude: smallest amplitude used [V]: near the stick–slip onset the step is
            most sensitive to the plant (at 1 V the nominal plant steps under 1 nm per period
            at 500 Hz and 2 kHz: ``experiments/step_gain_survey.py``), and another plant's
            step there has no bounded ratio to the map's, so no plan relies on it.
        blind_settings: the survey of settings whose direction does not depend on the
            plant (default: ``ASYMMETRY_PATH``'s, :mod:`controllers.blind`); with none robust in
            a direction a blind plan there finds no move. A blind move may take a robust
            setting of any waveform the survey and the map both hold (the default's a = 0.6
            at 2 kHz); every other move keeps the family (a, k).
    """

    def __init__(
        self,
        step_map: StepMap,
        ctx: ControllerContext,
        *,
        a: float = FAMILY[0],
        k: float = FAMILY[1],
        min_step: float = 1e-6,
        min_amplitude: float = 2.0,
        blind_settings: BlindSettings | None = None,
    ) -> None:
        if abs(step_map.control_interval - ctx.control_interval) > 1e-12:
            raise ValueError(
                f"step_map.control_interval={step_map.control_interval!r}: the controller "
                f"runs at {ctx.control_interval!r} s"
            )
        self.a, self.k = a, k
        survey = check_blind_settings(blind_settings) or BlindSettings.load()
        # the planner's own family, then the survey's other waveforms the map holds: those
        # serve only blind moves (the reading saturated), where the robust ones are used
        families = [(a, k)] + [fam for fam in survey.families() if fam in step_map.families()
                               and not np.allclose(fam, (a, k))]  # fmt: skip
        moves: dict[int, list[tuple[float, ...]]] = {1: [], -1: []}
        for (fa, fk), f in itertools.product(families, np.unique(step_map.frequency)):
            m = round(f * ctx.control_interval)
            for d in (1, -1):
                for i in step_map.family(ctx.axis, float(f), fa, fk, d):
                    s = float(step_map.step[i])
                    if s * d < min_step or abs(step_map.amplitude[i]) < min_amplitude - 1e-9:
                        continue
                    run = m * s
                    rest = float(step_map.first[i]) + (m - 1) * s
                    amp = float(step_map.amplitude[i])
                    moves[d].append((amp, float(f), run, rest, m * amp * amp, fa, fk))
        # rows: amplitude [V] (signed), frequency [Hz], map travel per interval running and
        # from rest [rad], energy ∝ m·A², the waveform's a and k
        self.moves = {d: np.array(v) for d, v in moves.items()}
        self.own = {d: np.isclose(v[:, 5], a) & np.isclose(v[:, 6], k) if v.size else
                    np.zeros(0, bool) for d, v in self.moves.items()}  # fmt: skip
        if any(not own.any() for own in self.own.values()):
            raise ValueError("step_map: no usable step in one of the directions")
        # the moves a blind interval may make (robust direction; controllers.blind)
        self.robust = {d: survey.robust(v[:, 0], v[:, 1], a=v[:, 5], k=v[:, 6])
                       for d, v in self.moves.items()}  # fmt: skip

    def plan(
        self,
        remaining: float,
        tolerance: float,
        *,
        from_rest: bool,
        gains: StepGains | None = None,
        amplitude_limit: float = np.inf,
        blind: bool = False,
        room: float = np.inf,
    ) -> Move | None:
        """The largest move towards ``remaining`` [rad] that does not pass the target, or
        None when |remaining| ≤ ``tolerance`` [rad] (the scan finishes) or no move fits.

        ``gains``, when given, scales each amplitude's map displacement by its own
        estimate, no move may pass the target at its upper bound, stalled amplitudes and
        settings measured stepping backwards are not used, and a setting whose direction
        is not confirmed (:class:`~controllers.step_gain.StepGains`) only where
        ``REVERSAL`` × its map displacement fits in ``room`` [rad], the reading's distance
        to the detector's edge behind the move (a reversal keeps the spot in view); without
        it, the map as it is. ``blind`` (the reading saturated) restricts the moves to the
        settings whose direction does not depend on the plant (:mod:`controllers.blind`)."""
        if abs(remaining) <= tolerance:
            return None
        d = 1 if remaining > 0 else -1
        mv = self.moves[d]
        nominal = np.abs(mv[:, 3] if from_rest else mv[:, 2])
        usable = (np.abs(mv[:, 0]) <= amplitude_limit) & (self.robust[d] if blind
                                                           else self.own[d])  # fmt: skip
        if gains is not None:
            allowed = ~gains.stalled(d, mv[:, 0]) & ~gains.reversed(d, mv[:, 0], mv[:, 1])
            if gains.backward[d] and not (usable & allowed).any():
                gains.forget_reversals(d)  # no move left at all: try the reversed ones again
                allowed = ~gains.stalled(d, mv[:, 0])
            g, upper = gains.estimate(d, mv[:, 0], mv[:, 1])
            usable &= allowed
            safe = REVERSAL * nominal <= room
            usable &= safe | gains.confirmed(d, mv[:, 0], mv[:, 1])
        else:
            g = upper = np.ones(nominal.shape)
        disp, reach = nominal * g, nominal * upper
        ok = (reach <= abs(remaining)) & usable
        if not ok.any():
            return None
        best = disp[ok].max()
        near = ok & (disp >= 0.9 * best)
        i = int(np.flatnonzero(near)[np.argmin(mv[near, 4])])
        return self._move(i, d, float(disp[i]), float(nominal[i]))

    def smallest(
        self,
        direction: int,
        *,
        gains: StepGains | None = None,
        amplitude_limit: float = np.inf,
        blind: bool = False,
    ) -> Move | None:
        """The move of least map displacement from rest in ``direction`` (±1) within the
        amplitude limit (``blind``: among the robust settings, as :meth:`plan`): the safety
        monitor's search step (None if none fits)."""
        d = 1 if direction > 0 else -1
        mv = self.moves[d]
        ok = (np.abs(mv[:, 0]) <= amplitude_limit) & (self.robust[d] if blind else self.own[d])
        if gains is not None and (ok & ~gains.reversed(d, mv[:, 0], mv[:, 1])).any():
            ok &= ~gains.reversed(d, mv[:, 0], mv[:, 1])  # never a setting that stepped back
        if gains is not None and (ok & ~gains.stalled(d, mv[:, 0])).any():
            ok &= ~gains.stalled(d, mv[:, 0])  # skip amplitudes that barely step here
        if not ok.any():
            return None
        nominal = np.abs(mv[:, 3])
        i = int(np.flatnonzero(ok)[np.argmin(nominal[ok])])
        g = 1.0 if gains is None else float(gains.estimate(d, mv[i, 0])[0][0])
        return self._move(i, d, float(nominal[i]) * g, float(nominal[i]))

    def blind_rows(self, d: int) -> np.ndarray:
        """(n, 7) rows of :attr:`moves` in direction ``d`` whose setting may step blind
        (amplitude [V] and map travel per interval [rad] signed as ``d``, the waveform's a
        and k in the last two columns); ValueError when the blind set has none there."""
        rows = self.moves[d][self.robust[d]]
        if not len(rows):
            raise ValueError(f"blind_settings: no robust setting in direction {d:+d}")
        return rows

    def blind_within(self, d: int, travel: float) -> Move:
        """The blind move in direction ``d`` (±1) of the largest running map travel within
        ``travel`` [rad] per interval (a move its caller sized: a rule's step count, a
        policy's setting), or the smallest blind move where none is within it."""
        rows = self.blind_rows(d)
        run = np.abs(rows[:, 2])
        below = run <= abs(travel)
        i = int(np.argmax(np.where(below, run, -np.inf))) if below.any() else int(np.argmin(run))
        amp, f, step, _rest, _energy, a, k = rows[i]
        return Move(float(amp), float(f), float(a), float(k), float(step), float(step))

    def _move(self, i: int, d: int, disp: float, nominal: float) -> Move:
        mv = self.moves[d]
        return Move(float(mv[i, 0]), float(mv[i, 1]), float(mv[i, 5]), float(mv[i, 6]),
                    d * disp, d * nominal)  # fmt: skip


class FeedForwardController(StepScanController):
    """Step-map inversion + scan-mode PID (module docstring).

    Args:
        ctx: plant context; step_map: map (default: the shipped one);
        max_replans: re-plans from the detector allowed per commanded target;
        blind_settings: the settings it may step with blind (:class:`MapPlanner`).
    """

    name = "feedforward"

    def __init__(
        self,
        ctx: ControllerContext,
        step_map: StepMap | None = None,
        *,
        max_replans: int = 3,
        blind_settings: BlindSettings | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(ctx, **kwargs)
        self.planner = MapPlanner(step_map if step_map is not None else StepMap.load(), ctx,
                                  blind_settings=blind_settings)  # fmt: skip
        self.max_replans = max_replans
        self.gains = StepGains()

    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        super().reset(obs, brief)
        self.plans = 0  # stepping sequences started for this target (first plan + re-plans)
        self._planned_for = self.target  # rad, the target they were started for

    def observe(self, measured: float, saturated: bool) -> None:
        """Dead reckoning while stepping, except that a valid reading contradicting it — the
        estimate beyond the detector, the reading inside — replaces it (the spot reached
        early on a plant stepping more than the map)."""
        super().observe(measured, saturated)
        if not saturated and abs(self.estimate) > self.ctx.angle_range:
            self.estimate = measured

    def choose_move(self, remaining: float, measured: float, saturated: bool) -> Move | None:
        new_sequence = self.last_move is None
        if self.target != self._planned_for:  # a new set point: a new plan
            self.plans, self._planned_for = 0, self.target
        if new_sequence and self.plans > self.max_replans:
            return None
        move = self.planner.plan(
            remaining,
            self.scan_fraction * self.ctx.scan_range,
            from_rest=new_sequence,
            gains=self.gains,
            amplitude_limit=self.ctx.input_limit - abs(self.offset),
            blind=self.blind_approach(saturated),
            room=self.room_behind(remaining, measured, saturated),
        )
        if move is not None and new_sequence:
            self.plans += 1
        return move

    def search_move(self, direction: int, saturated: bool = False) -> Move | None:
        return self.planner.smallest(
            direction,
            gains=self.gains,
            amplitude_limit=self.ctx.input_limit - abs(self.offset),
            blind=self.blind_approach(saturated),
        )
