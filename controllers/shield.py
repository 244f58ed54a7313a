"""A blind-travel shield: what a lab puts between any controller and the rig while the
detector cannot see the table.

The step controllers carry their own safety monitor (:mod:`controllers.base`); a learned
policy has none, and beyond the detector it can step for the whole episode with a setting
that runs the table backwards (PPO ran 87 and 128 µm away on the 200 µm move of two
held-out draws). :class:`BlindShield` filters a controller's env actions with the same
rules, from what a lab sees (the reading, the brief, the action itself):

* **robust direction**: on the way in from beyond the detector (no valid reading yet in
  the episode), a stepping action is replaced by the setting of the blind set
  (:mod:`controllers.blind`: direction independent of the plant across a survey's
  plants, of any waveform it holds) in the same direction whose map travel per interval
  comes nearest below the one asked for (the smallest, if none is below:
  :meth:`~controllers.feedforward.MapPlanner.blind_within`); a spot lost after it was seen is left
  to the controller's own moves near the edge, as the step controllers do;
* **no stepping away**: a stepping action away from the detector, while the target lies
  inside it, idles the generator;
* **blind budget**: the map travel of the moves made with the reading saturated is
  summed, and once it exceeds ``BLIND_FACTOR`` × the dead-reckoned distance to the
  detector with its stated error (``LOST_SEARCH`` θ_lin for a spot lost after it was
  seen, or with no start estimate), the generator idles and the scan offset stays: the
  steps are not going where they should (the step controllers' constants,
  :mod:`controllers.base`).

A valid reading resets the budget; the controller's actions pass unchanged while it
lasts. This is shielding in the sense of safe RL (Alshiekh et al., AAAI 2018): a monitor
that corrects only the actions that would leave the safe set, here the actions a lab
cannot check.
"""

from __future__ import annotations

import numpy as np

from turntable_env.envs.config import OBS

from .base import LOST_SEARCH, SATURATION_FRACTION, ControllerContext, blind_budget
from .blind import BlindSettings, check_blind_settings
from .feedforward import MapPlanner
from .lab import LabBrief
from .step_map import StepMap

__all__ = ["BlindShield"]


class BlindShield:
    """The blind-travel shield (module docstring).

    Args:
        ctx: the plant context (axis, Δt, action scaling, detector range, rig reading).
        step_map: the map whose travel the budget counts (default: the shipped one).
        blind_settings: the survey of direction-robust settings (default:
            ``controllers.blind.ASYMMETRY_PATH``'s).
    """

    def __init__(
        self,
        ctx: ControllerContext,
        step_map: StepMap | None = None,
        blind_settings: BlindSettings | None = None,
    ) -> None:
        if not isinstance(ctx, ControllerContext):
            raise ValueError(f"ctx={type(ctx).__name__}: must be a ControllerContext")
        if step_map is not None and not isinstance(step_map, StepMap):
            raise ValueError(f"step_map={type(step_map).__name__}: must be a StepMap or None")
        check_blind_settings(blind_settings)
        self.ctx = ctx
        self.map = step_map if step_map is not None else StepMap.load()
        self.freqs = np.unique(self.map.frequency)  # Hz, the map's
        amps = np.abs(self.map.amplitude)
        self.amp_range = (float(amps.min()), float(amps.max()))  # V, the map's
        # the blind set as the map planner has it (its direction-robust moves)
        self.planner = MapPlanner(self.map, ctx, blind_settings=blind_settings)
        self._sat = SATURATION_FRACTION * ctx.angle_range
        self.reset_state(saturated=False, brief=None)

    def reset_state(self, *, saturated: bool, brief: LabBrief | None) -> None:
        """A new episode: the budget from the brief's dead-reckoned start when the first
        reading is ``saturated``."""
        lim = self.ctx.angle_range
        self.seen = not saturated
        self.travel = 0.0  # rad, map travel of the blind moves since the last valid reading
        self.budget = LOST_SEARCH * lim
        est = None if brief is None else brief.start_estimate_rad
        if saturated and est is not None:
            self.budget = blind_budget(est, brief.start_error, lim)

    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        meas = float(self.ctx.lab_observation(obs)[OBS.measured_angle_rad])
        self.reset_state(saturated=abs(meas) >= self._sat, brief=brief)

    def _asked(self, d: int, amplitude: float, frequency: float) -> float:
        """Map travel per interval [rad] of |amplitude| [V] at ``frequency`` [Hz]: the
        step per period at the nearest map frequency, × the periods of one interval."""
        f_map = float(self.freqs[np.argmin(np.abs(np.log(self.freqs / frequency)))])
        amp = float(np.clip(abs(amplitude), *self.amp_range))
        step = self.map.step_size(self.ctx.axis, d * amp, f_map, 0.9, 1.0)  # rad per period
        return abs(step) * frequency * self.ctx.control_interval

    def filter(self, obs: np.ndarray, action: np.ndarray) -> np.ndarray:
        """The env action to apply for the controller's ``action`` answering ``obs``."""
        lab = self.ctx.lab_observation(obs)
        meas = float(lab[OBS.measured_angle_rad])
        if abs(meas) < self._sat:
            self.seen, self.travel = True, 0.0
            self.budget = LOST_SEARCH * self.ctx.angle_range
            return action
        sc = self.ctx.scaling
        amp, freq, _a, _k, offset = sc.decode(np.asarray(action, dtype=float))
        if amp == 0.0:
            return action
        if self.travel >= self.budget:  # the budget is spent: idle, keep the offset
            return sc.encode(0.0, 100.0, 0.9, 0.0, offset)
        d = 1 if amp > 0 else -1
        side = 1 if meas > 0 else -1  # the table's side of the detector
        target = float(lab[OBS.target_angle_rad])
        if d == side and abs(target) < self.ctx.angle_range:  # away from a target inside
            return sc.encode(0.0, 100.0, 0.9, 0.0, offset)
        asked = self._asked(d, amp, freq)
        if self.seen:  # a spot lost near the edge: the controller's own moves, budgeted
            self.travel += asked
            return action
        move = self.planner.blind_within(d, asked)
        self.travel += abs(move.expected)
        return sc.encode(move.amplitude, move.frequency, move.a, move.k, offset)
