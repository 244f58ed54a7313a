"""The controller interface (observation → action) and the step-then-scan machinery.

Every controller answers :meth:`Controller.act` with an action of ``PiezoTurntable-v0``'s
Box and is told about a new episode by :meth:`Controller.reset` (the reset observation
and a :class:`~controllers.lab.LabBrief`: what a lab knows; never the env's info).
:class:`ControllerContext` carries what a controller may know about the plant
it was designed for: the nominal parameters, the axis, the control interval, the action
scaling, the detector range and the scan gain of the linear stick plant.

:class:`StepScanController` is the common two-mode skeleton of the baselines:

* **step** mode: each interval a whole number of stick–slip periods at one setting
  (frequency m/Δt, so every interval holds m periods and the generator's phase is 0 at
  each interval start); a subclass chooses the setting (:meth:`StepScanController.choose_move`).
  The scan offset ramps back to 0 during a stepping interval, and the move accounts for it.
* **scan** mode (generator idle): the python-control-designed PID of
  :mod:`controllers.scan_pid` drives the scan offset from the detector reading. It hands
  back to step mode when the error leaves the scan range K·u_max (or the reading
  saturates). On a target that stays, an error within ``HOLD_SIGMAS`` × the reading's
  noise goes to the scan's hold integrator instead (:meth:`ScanPID.hold`): the noise σ is
  estimated online, robustly, from the error's changes between scan intervals less the
  change the scan's own offset step made (K·Δu; median |Δe| = 0.954 σ for Gaussian
  noise), so a floor vibration that rocks the reading widens the hold and is averaged,
  not chased, while a PID still converging does not; the first ``SETTLING`` scan
  intervals on a target (after a step or a new target) go to the PID whatever the band,
  their error being its transient, not noise. The first scan interval after
  stepping closes ``HANDOVER_GAIN`` of the error through the scan plant's inverse
  (:meth:`ScanPID.jump`), plus the offset the table did not follow at the last such
  hand-over in that direction (:attr:`StepScanController.dead_band`: lost motion after
  stepping, 1.0–1.5 V on held-out plants with piezo creep and hysteresis, where the
  first offset step moved the table by nothing), and a scan whose offset is saturated is
  left for stepping only when the error exceeds the hold band (stepping would first
  unwind the offset).

The target: with a reference in the brief (:class:`~controllers.lab.LabBrief`, a tracking
task's), the action read at interval k aims at r[k+1], the set point at the end of the
interval it acts over (the metrics judge θ[k+1] against r[k+1]); a set point that changes
at k+1 is stepped towards from k. Without one, or where the observation's commanded
target contradicts it, the commanded target r[k].

The reading: the x channel converted with the rig's calibration
(:meth:`ControllerContext.lab_observation`) and, where the observation carries the
photodiode's y channel (``EnvConfig(detector_y=True)``, the benchmark's since 2.3),
corrected for the axis misalignment learned from both (:mod:`controllers.misalignment`).

The safety monitor: a saturated reading against a belief inside the detector is a lost
spot, searched with a doubling believed excess beyond the edge; a search step is taken
when no planned move fits; and the believed travel with the reading saturated is bounded
(``BLIND_FACTOR`` × the lab's dead-reckoned distance to the detector with its stated
error, or ``LOST_SEARCH`` θ_lin after a loss): past it the controller holds, since its
steps are not going where it believes (a plant stepping backwards beyond the detector). A
step move that loses the spot on the side against its own direction spends the budget at
once: that setting steps backwards on this plant, and every blind step would add to it.
On the way in from beyond the detector (no valid reading yet in the episode: the longest
blind travel) a map controller steps only with the settings whose direction a survey of
plants far from the map's found independent of the plant (:mod:`controllers.blind`); a
spot lost after it was seen is searched near the edge with the small moves of the whole map.
Inside the detector a map controller moves with a setting whose direction it has not yet
seen on this plant only as far as a reversal would keep the spot in view
(:meth:`StepScanController.room_behind`; the step gains' direction record,
:mod:`controllers.step_gain`): a friction asymmetry can make the fast settings step
backwards.

The reading of a bent detector: an odd cubic of the photodiode (the catalogue's
``detector_nonlinearity``) leaves a table held on a target near the edge κ·θ³/θ_lin² off it,
and no reading alone tells. The controller's own offset does: in scan mode the table
follows it, K·Δu, so an offset dither out and back reads the detector's local slope
(:mod:`controllers.detector_linearity`). Where a cubic of the largest κ planned for
(``KAPPA_PRIOR``) would move the reading by more than ``DITHER_SHARE`` of the tolerance
(beyond :attr:`ControllerContext.dither_from`, 0.18 θ_lin on the real turntable): an
episode whose target lies beyond it, or whose known reference holds a set point beyond it
long enough to dither there, first measures the reading's noise over ``NOISE_MIN`` idle
intervals (a floor vibration's too: a dither's slope is weighed by it) and dithers
``PROBES`` times before its first step; a settled target beyond it dithers up to
``DITHERS`` times, back to back while the corrected reading holds it on the target, where
a dither read at an m² at most half or at least twice its own pairs with it. A known
reference whose last value needs κ but whose own places pair with none of it (a ramp from
−4 to +4 µm) first visits the detector's centre for ``VISIT_DITHERS`` dithers; and a place
near the centre is dithered on where it pairs with such a last value. The first dither at
each place conditions the contacts and is not read. Once κ̂ is decided the reading is
inverted through the cubic, and a target that then reads beyond the clip (κ̂ > 0 near the
edge) is held open loop from an anchor inside it (``ANCHOR_FRACTION``), the offset stepped
by the rest over the fitted scan gain.
"""

from __future__ import annotations

import abc
import functools
import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from turntable_env.detector import Detector
from turntable_env.envs.config import OBS, OBS_Y, ActionScaling, EnvConfig
from turntable_env.linear import scan_plant, stick_plant
from turntable_env.params import ParameterSet

from .detector_linearity import KAPPA_MIN, DetectorLinearity
from .lab import LabBrief
from .misalignment import AxisMisalignment
from .scan_pid import PIDGains, ScanPID, design_scan_pid
from .step_gain import StepGains

__all__ = ["Controller", "ControllerContext", "Move", "StepScanController", "blind_budget"]

SATURATION_FRACTION = 0.995  # of θ_lin: readings beyond it count as saturated
UNWIND_FRACTION = 0.5  # of u_max: a larger scan offset is ramped to 0 before stepping
LOST_EXCESS = 0.05  # of θ_lin: first guess of a lost spot's distance beyond the edge (doubles)
# the blind-travel budget: believed travel with the reading saturated before the safety
# monitor stops stepping (a plant that steps backwards there would otherwise run away)
BLIND_FACTOR = 3.0  # × the dead-reckoned distance to the detector, with its stated error
LOST_SEARCH = 8.0  # of θ_lin: search allowed for a spot lost inside the episode
# the hold: a scan error within HOLD_SIGMAS × the reading's noise, on a target that stays,
# goes to the scan's slow integrator (ScanPID.hold), not to the PID that would answer it
HOLD_SIGMAS = 3.0
# scan intervals on one target, after a step or a new target, in which the PID converges:
# their error changes are no noise sample, and their errors go to the PID, not the hold
SETTLING = 3
NOISE_WINDOW = 12  # scan intervals whose error changes estimate the reading's noise
NOISE_MIN = 4  # error changes measured before a dither is read (its slope is weighed by them)
MIN_LEARN = 5e-6  # rad: smallest map move the step gains learn from (50 nm at R = 10 mm)
# the share of the error the first scan interval after stepping closes through K⁻¹ [-]:
# below 1, so a plant whose scan gain is up to 25 % above the model's does not overshoot
HANDOVER_GAIN = 0.8
# the smallest hand-over offset step [V] whose response measures the scan's dead band after
# stepping (lost motion: on some plants the offset's first volts after the flybacks move
# the table by nothing)
DEAD_MIN = 0.3
# the detector's linearity (controllers.detector_linearity), read from offset dithers out
# and back over two scan intervals: PROBES before the first step of an episode that starts
# inside the detector, up to DITHERS on a settled target beyond ControllerContext.dither_from
DITHER_FRACTION = 0.4  # of u_max: the dither's offset step, towards the detector's centre
# (8 V made low-friction held-out plants slip in scratch trials: their way back fell short)
# the largest |κ| a dither plan prepares for [-] (the held-out draws' 0.05–0.15, the
# catalogue's typical 0.1): a target is dithered where a cubic of it would move the reading
# by more than DITHER_SHARE of the env's tolerance, KAPPA_PRIOR·m³·θ_lin > DITHER_SHARE·tol
# (m ≥ 0.18 for the 1 µrad tolerance and θ_lin = 571 µrad; ControllerContext.dither_from)
KAPPA_PRIOR = 0.15
DITHER_SHARE = 0.5
DITHERS = 8  # dithers per target at most (the first after stepping conditions the contacts)
FAR_HOLD = SETTLING + 4  # intervals a far set point must hold for two dithers after settling
PROBES = 6  # dithers before the first step (the first conditions the contacts)
# the last seconds of a known reference (a tracking task's brief) are not dithered: the set
# point is then held for use, and a dither with the PID's settling takes 5 intervals
QUIET_END_S = 0.3
# a known reference whose last level needs κ (beyond ControllerContext.dither_from) but
# whose levels give no dither site at an m² at most half or at least twice its own (a ramp
# from −4 to +4 µm, back and forth about the centre) first visits the detector's centre:
# the controller aims at θ = 0 for VISIT_DITHERS dithers there (the first conditions the
# contacts), at most until VISIT_SHARE of the reference before its quiet end has passed
VISIT_DITHERS = PROBES
VISIT_SHARE = 0.5
# a target whose reading through the decided cubic lies beyond the clip (κ > 0.09 reads the
# edge move's 0.93 θ_lin above θ_lin) is held open loop from an anchor inside it: the PID
# settles on the angle that reads ANCHOR_FRACTION of the saturation's, then the offset
# steps by the rest over K̂, the fitted scan gain (the stick plant follows it, K·Δu)
ANCHOR_FRACTION = 0.97


def blind_budget(estimate: float, error: float, angle_range: float) -> float:
    """The believed travel [rad] allowed with the reading saturated from a dead-reckoned
    start ``estimate`` [rad] with relative ``error``: ``BLIND_FACTOR`` × (1 + error) × its
    distance to the detector's edge ``angle_range`` [rad] (at least one detector range)."""
    dist = max(abs(estimate) - angle_range, angle_range)
    return BLIND_FACTOR * (1.0 + error) * dist


@dataclass(frozen=True)
class ControllerContext:
    """What a controller knows about its plant (nominal model; SI units).

    Attributes:
        params: nominal parameter set; axis: "A"/"B"/"C"; control_interval: Δt [s];
        scaling: action scaling; scan_gain: K, angle per scan-offset volt of the stick
        plant [rad/V]; input_limit: amplifier input limit u_max [V]; tolerance: success
        band [rad]; detector: the detector model of the plant the controller was built for
        (what its lab's calibration knows of the rig).

    A controller reads the table angle from an observation with :meth:`lab_observation`:
    the env's ``measured_angle_rad`` is the Eq. 4.1 reading, which a rig with a tilted
    mirror or another photodiode gain scales (the thesis calibration's rig reads 0.82 of
    the table angle); the conversion is the identity for the nominal rig.
    """

    params: ParameterSet
    axis: str
    control_interval: float
    scaling: ActionScaling
    scan_gain: float
    input_limit: float
    tolerance: float
    detector: Detector

    @classmethod
    def from_config(cls, config: EnvConfig) -> ControllerContext:
        ps = config.parameter_set
        return cls(
            params=ps,
            axis=config.axis,
            control_interval=config.control_interval,
            scaling=config.scaling,
            scan_gain=_scan_design(ps, config.axis, config.control_interval)[0],
            input_limit=ps.amplifier.input_limit,
            tolerance=config.tolerance,
            detector=ps.detector,
        )

    @classmethod
    def from_env(cls, env: Any) -> ControllerContext:
        """From a ``PiezoTurntable-v0`` env (wrappers allowed)."""
        config = getattr(env.unwrapped, "config", None)
        if not isinstance(config, EnvConfig):
            raise ValueError(f"env={env!r}: not a PiezoTurntable environment")
        return cls.from_config(config)

    def lab_observation(self, obs: np.ndarray) -> np.ndarray:
        """``obs`` (…, 8) with ``measured_angle_rad`` converted from the Eq. 4.1 reading to
        the table angle [rad] with the rig's calibration (the same array for the nominal
        rig, a copy otherwise); with a y channel (…, 9) that reading too. ValueError for an
        observation that is not a finite real array of that width (a NaN reading would
        otherwise become a NaN action)."""
        a = np.asarray(obs)
        if (a.ndim == 0 or a.shape[-1] not in (OBS_Y, OBS_Y + 1) or a.dtype.kind not in "fiu"
                or not np.isfinite(a).all()):  # fmt: skip
            raise ValueError(
                f"obs: shape {a.shape}, dtype {a.dtype}: an observation is a finite real array "
                f"of {OBS_Y} values ({OBS_Y + 1} with the y channel), got {_brief(a)}"
            )
        det = self.detector
        if det.tilt_factor == 1.0 and det.gain == 1.0:
            return obs
        out = np.array(obs, dtype=float, copy=True)
        out[..., OBS.measured_angle_rad] = det.table_angle(out[..., OBS.measured_angle_rad])
        if out.shape[-1] > OBS_Y:  # the y channel (EnvConfig.detector_y), read alike
            out[..., OBS_Y] = det.table_angle(out[..., OBS_Y])
        return out

    @property
    def angle_range(self) -> float:
        """The table angle at the edge of the detector's linear range [rad]: θ_lin of
        Eq. 4.1 converted with the rig's mirror tilt and gain (:meth:`Detector.table_angle`)."""
        return float(self.detector.table_angle(self.detector.angle_range))

    @property
    def dither_from(self) -> float:
        """The target m = |θ|/θ_lin [-] from which a detector cubic of ``KAPPA_PRIOR`` would
        move the reading by more than ``DITHER_SHARE`` of the env's tolerance: κ·θ³/θ_lin²
        (the catalogue's ``detector_nonlinearity``) = DITHER_SHARE·tolerance."""
        return float(np.cbrt(DITHER_SHARE * self.tolerance / (KAPPA_PRIOR * self.angle_range)))

    @property
    def scan_range(self) -> float:
        """Largest angle the scan offset reaches, K·u_max [rad]."""
        return self.scan_gain * self.input_limit

    @property
    def pid_gains(self) -> PIDGains:
        return _scan_design(self.params, self.axis, self.control_interval)[1]


def _brief(a: np.ndarray) -> str:
    """A short text of an observation for an error message: its values, or the first bad one."""
    if a.dtype.kind not in "fiu":
        return repr(a.tolist())[:80]
    bad = np.flatnonzero(~np.isfinite(a.reshape(-1)))
    flat = a.reshape(-1)
    return f"{float(flat[bad[0]])!r} at flat index {bad[0]}" if bad.size else repr(a.tolist())[:80]


@functools.lru_cache(maxsize=16)
def _scan_design(ps: ParameterSet, axis: str, dt: float) -> tuple[float, PIDGains]:
    """Scan gain K [rad/V] and PID gains of the nominal plant (cached per plant)."""
    plant = scan_plant(stick_plant(ps, axis), dt)[0, 0]
    k = float(np.real(plant.dcgain()))
    return k, design_scan_pid(plant)


class Controller(abc.ABC):
    """Observation → action for ``PiezoTurntable-v0`` (see the module docstring).

    A controller sees only what a lab sees: the observations and, at reset, a
    :class:`~controllers.lab.LabBrief`. Every subclass's :meth:`reset` is wrapped so that
    anything else — the env's reset ``info`` with its true angle and parameter draw above
    all — is refused with a ValueError (the information boundary is in the interface, not a
    convention)."""

    name: str = "controller"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "reset" in cls.__dict__:
            cls.reset = _lab_only(cls.__dict__["reset"])  # type: ignore[method-assign]

    @abc.abstractmethod
    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        """Start an episode from the reset observation and what the lab knows."""

    @abc.abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The next action (float32, shape (5,), within [-1, 1])."""

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.act(obs)

    @classmethod
    def act_many(cls, controllers: Sequence[Controller], obs: np.ndarray) -> np.ndarray:
        """(N, 5) actions of N controllers of this class for their (N, 8) observations ((N, 9)
        with the y channel; the benchmark's batched call; subclasses may evaluate them
        together, as the agents do)."""
        return np.stack([c.act(o) for c, o in zip(controllers, obs, strict=True)])


def _lab_only(reset: Callable[..., None]) -> Callable[..., None]:
    """Wrap a controller's reset: the second argument must be a LabBrief."""

    @functools.wraps(reset)
    def checked(self: Controller, obs: np.ndarray, brief: LabBrief) -> None:
        if not isinstance(brief, LabBrief):
            raise ValueError(
                f"{type(self).__name__}.reset: brief={type(brief).__name__}: a controller gets a "
                "LabBrief (what a lab knows), never the env's info (ground truth is "
                "evaluation-only)"
            )
        reset(self, obs, brief)

    return checked


@dataclass(frozen=True)
class Move:
    """One stepping interval: input amplitude [V] (signed), frequency [Hz] (m/Δt), ramp
    ratio a, slew adaptation k, the displacement the controller expects [rad] and the one
    its nominal step map predicts [rad] (0: none; what the online step gains learn from)."""

    amplitude: float
    frequency: float
    a: float
    k: float
    expected: float
    nominal: float = 0.0


class StepScanController(Controller):
    """Step mode to get within the scan range, then scan-mode PID (module docstring).

    Args:
        ctx: the plant context.
        scan_fraction: |error| below which stepping stops, as a fraction of the scan
            range K·u_max [-]; scan mode hands back to step mode above ``scan_exit``.
    """

    steps: bool = True  # the controller steps (False: scan mode only)

    def __init__(
        self, ctx: ControllerContext, *, scan_fraction: float = 0.5, scan_exit: float = 0.9
    ) -> None:
        self.ctx = ctx
        self.scan_fraction = scan_fraction
        self.scan_exit = scan_exit
        self.pid = ScanPID(ctx.pid_gains, ctx.input_limit)
        self.gains: StepGains | None = None  # online step gains (set by map-based subclasses)
        self.min_learn = MIN_LEARN
        # the error a step plan aims at, as a multiple of the remaining one [-] (1: the
        # controller's own plan; a residual agent sets it each interval, agents/residual.py)
        self.remaining_scale = 1.0
        self.misalignment = AxisMisalignment()  # learned from the y channel, where observed
        det = ctx.detector  # the reading's noise the lab expects [rad], a floor on the scatter
        noise = det.noise_std / det.saturation_voltage * ctx.angle_range
        self.linearity = DetectorLinearity(ctx.angle_range, noise)  # learned from dithers
        # a saturated reading sits at the edge plus the detector's noise (1 mV ≈ 0.3 µrad)
        self._sat = ctx.angle_range * SATURATION_FRACTION

    # --- episode ----------------------------------------------------------------------
    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        obs = self.ctx.lab_observation(obs)
        self._brief = brief
        self._interval = 0  # k, the index of the observation the next act() reads
        self._dithered: dict[float, int] = {}  # dithers made per target [rad]
        self._visit = self._plans_visit()  # aims at the centre until its dithers are done
        self.misalignment.reset()
        self.linearity.reset()
        self._beyond: tuple[float, float] | None = None  # (target [rad], offset [V]) held
        self.target = self._anchored(self._aim(float(obs[OBS.target_angle_rad])))
        meas = float(obs[OBS.measured_angle_rad])
        sat = self.saturated(meas)
        # a dither under way: (phase 1 out / 2 back, offset before [V], its step [V],
        # readings before and after the way out [rad])
        self._cycle: tuple[int, float, float, float, float] | None = None
        self._site = 0  # dithers made since the last step (the first only conditions)
        self._probes = 0  # dithers made before the first step (up to PROBES)
        self._idle_raw: float | None = None  # the last idle start interval's raw reading
        self._dither_target: float | None = None  # the target the last dither began on
        if not sat:
            meas = self._read(obs, meas)
        self.estimate = meas  # rad, believed angle: the reading where it is valid, ...
        if sat:  # ... beyond the detector the dead-reckoned start, ...
            edge = math.copysign(self.ctx.angle_range * 1.05, meas)
            est = brief.start_estimate_rad
            # ... unless it contradicts the reading (it lies on the other side or inside)
            ok = est is not None and np.sign(est) == np.sign(meas) and abs(est) > abs(edge)
            self.estimate = float(est) if ok else edge
        self.mode = "step"
        self.offset = 0.0  # V, scan offset commanded for the interval now ending
        self.last_move: Move | None = None
        self.last_measured: float | None = None if sat else meas
        self._offset_before = 0.0  # V, the scan offset a stepping interval ramped from
        self._excess = LOST_EXCESS  # of θ_lin: the lost spot's believed distance beyond the edge
        self.seen = not sat  # a valid reading has placed the table in this episode
        self._blind = 0.0  # rad, believed travel of the moves made with the reading saturated
        self._blind_budget = LOST_SEARCH * self.ctx.angle_range  # rad
        if sat:  # beyond the detector from the start: dead-reckon to it
            lim = self.ctx.angle_range
            self._blind_budget = blind_budget(self.estimate, brief.start_error, lim)
        if self.gains is not None:
            self.gains.reset()
        self.pid.reset(0.0)
        self._noise: deque[float] = deque(maxlen=NOISE_WINDOW)  # |Δe| [rad] in the holds
        self._scan_err: float | None = None  # the last scan interval's error [rad]
        self._scan_target: float | None = None
        self._scan_streak = 0  # consecutive scan intervals on one target
        self._scan_offset = 0.0  # V, the offset before the last scan interval's update
        self._hold_band = 0.0  # rad, the hold's error band at the last scan interval
        self._dead = {1: 0.0, -1: 0.0}  # V, the scan's dead band after stepping, per direction
        self._handover: tuple[float, float] | None = None  # (Δu [V], reading [rad]) of it

    def _aim(self, commanded: float) -> float:
        """The target [rad] an action read at interval k aims at: the commanded one at the
        end of the interval it acts over, r[k+1] from the brief's reference (a set point
        that changes at k+1 is stepped towards during k → k+1, as the metrics judge θ[k+1]
        against r[k+1]); the observation's ``commanded`` r[k] where the brief has no
        reference or disagrees with it (another reference than the brief's)."""
        brief, k = self._brief, self._interval
        if self._visit:
            deadline = VISIT_SHARE * (len(brief.reference_rad) - self._quiet())
            if self._dithered.get(0.0, 0) >= VISIT_DITHERS or k >= deadline:
                self._visit = False  # (the reference goes on from where it is now)
            else:
                return 0.0
        if brief.reference_rad is None or np.float32(brief.reference_at(k)) != np.float32(
            commanded
        ):
            return commanded
        return brief.reference_at(k + 1)

    def _anchored(self, target: float) -> float:
        """The angle [rad] aimed at for ``target``: the target itself, or where its reading
        through the decided cubic lies beyond ``ANCHOR_FRACTION`` of the saturation's,
        the anchor inside that reads it (``_far_target`` keeps the target)."""
        self._far_target: float | None = None
        lin, edge = self.linearity, ANCHOR_FRACTION * self._sat
        if lin.kappa <= 0.0 or abs(lin.reading(target)) < edge:
            return target
        self._far_target = target
        return lin.table_angle(math.copysign(edge, target))

    def saturated(self, measured: float) -> bool:
        return abs(measured) >= self._sat

    @property
    def dead_band(self) -> dict[int, float]:
        """The scan's dead band after stepping [V] per offset direction (±1), as the last
        hand-over in that direction measured it (:meth:`_learn_dead_band`; 0 before any)."""
        return dict(self._dead)

    def blind_approach(self, saturated: bool) -> bool:
        """Whether a move now is part of the way in from beyond the detector: the reading
        is ``saturated`` and no valid one has placed the table yet in this episode."""
        return saturated and not self.seen

    def room_behind(self, remaining: float, measured: float, saturated: bool) -> float:
        """The reading's distance [rad] to the detector's edge behind a move towards
        ``remaining`` [rad]: how far a move that steps backwards may go with the spot still
        in view (infinite with the reading saturated, where no move can be checked)."""
        if saturated:
            return math.inf
        return max(self._sat + math.copysign(1.0, remaining) * measured, 0.0)

    def _read(self, obs: np.ndarray, x: float) -> float:
        """The table angle [rad] behind an unsaturated x reading ``x``: with the y channel
        in ``obs``, corrected for the axis misalignment learned from both
        (:class:`~controllers.misalignment.AxisMisalignment`); x itself without it."""
        if obs.shape[-1] <= OBS_Y:
            return x
        y = float(obs[OBS_Y])
        if not self.saturated(y):
            self.misalignment.update(x, y)
        return self.misalignment.table_angle(x)

    # --- hooks ------------------------------------------------------------------------
    def observe(self, measured: float, saturated: bool) -> None:
        """Update the angle estimate after an interval (default: the model's expectation
        while stepping; the reading when it is valid and no move was made)."""
        if self.last_move is not None:
            self.estimate += self.last_move.expected
        elif not saturated:
            self.estimate = measured

    def learn(self, measured: float, saturated: bool, backwards: bool = False) -> None:
        """Update the online step gains (:mod:`controllers.step_gain`) from the interval
        just ended: ρ = (Δθ_measured − K·Δu_scan)/D_map and the setting's direction
        (:meth:`StepGains.record`) when both readings are valid and the map's move exceeds
        ``min_learn``; a move that ran past the detector's edge in its own direction sets a
        lower bound (it went at least to the edge), one that left it behind (``backwards``,
        :meth:`went_the_wrong_way`) is a reversal."""
        mv = self.last_move
        if (
            self.gains is None
            or mv is None
            or self.last_measured is None
            or abs(mv.nominal) < self.min_learn
        ):
            return
        d = 1 if mv.nominal > 0 else -1
        scan = -self.ctx.scan_gain * self._offset_before  # the offset ramped to 0
        if not saturated:
            # a move that went backwards is no gain to scale the map by: the amplitude is
            # stalled, and a clear reversal rules out the stronger settings of its direction
            self.gains.record(d, mv.amplitude, mv.frequency, measured - self.last_measured - scan,
                              mv.nominal)  # fmt: skip
        elif backwards:  # at least to the edge behind
            moved = math.copysign(self.ctx.angle_range, measured) - self.last_measured - scan
            self.gains.record(d, mv.amplitude, mv.frequency, moved, mv.nominal)
        elif measured * d > 0.0:
            lower = (d * self.ctx.angle_range - self.last_measured - scan) / mv.nominal
            if lower > float(self.gains.estimate(d, mv.amplitude)[0][0]):
                self.gains.update(d, mv.amplitude, lower, mv.frequency)

    def went_the_wrong_way(self, measured: float, saturated: bool) -> bool:
        """Whether the interval just ended was a step move that left the detector on the
        side against its own direction, further than its scan offset's ramp explains: the
        plant steps backwards at that setting (a friction asymmetry reverses the steps)."""
        mv = self.last_move
        if not saturated or mv is None or self.last_measured is None:
            return False
        d = 1 if mv.nominal > 0 else -1
        scan = -self.ctx.scan_gain * self._offset_before  # the offset ramped to 0
        # at least to the edge on the reading's side, from the reading before
        moved = math.copysign(self.ctx.angle_range, measured) - self.last_measured - scan
        return measured * d < 0.0 and moved * d < 0.0

    def search_move(self, direction: int, saturated: bool = False) -> Move | None:
        """The safety monitor's step towards the target (``direction`` ±1) when no planned
        move fits but the table must move: the reading is ``saturated`` (the spot is lost),
        or the error lies beyond the scan's reach. Default: None (the subclass has no map)."""
        return None

    @abc.abstractmethod
    def choose_move(self, remaining: float, measured: float, saturated: bool) -> Move | None:
        """The setting for the next interval, to cover ``remaining`` [rad] (None: scan)."""

    # --- control law ------------------------------------------------------------------
    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self.ctx.lab_observation(obs)
        meas = float(obs[OBS.measured_angle_rad])
        self.target = self._anchored(self._aim(float(obs[OBS.target_angle_rad])))
        self._interval += 1
        if self._beyond is not None:  # held open loop beyond the clip, on the same target
            if self._beyond[0] == self._far_target:
                return self._idle(self._beyond[1], meas)
            self._beyond = None
        sat = self.saturated(meas)
        if not sat:  # the table angle behind the x reading (a misaligned detector's)
            meas = self._read(obs, meas)
        self._raw = meas  # the reading before the linearity's correction [rad]
        if not sat:  # (a bent detector's, where the dithers have decided κ)
            meas = self.linearity.table_angle(meas)
        backwards = self.went_the_wrong_way(meas, sat)
        if backwards:  # the safety monitor: no blind travel at all
            self._blind_budget = 0.0
        self.learn(meas, sat, backwards)
        self.observe(meas, sat)
        k_scan = self.ctx.scan_gain
        lim = self.ctx.angle_range
        if sat:  # beyond the detector: at least at its edge on the reading's side; a belief
            # the reading contradicts is a lost spot: search on with a doubling excess
            if abs(self.estimate) < lim * (1.0 + LOST_EXCESS) or self.estimate * meas <= 0.0:
                self.estimate = math.copysign(lim * (1.0 + self._excess), meas)
                self._excess = min(2.0 * self._excess, self._blind_budget / lim)
            if self._blind >= self._blind_budget:  # the safety monitor: stop, do not run away
                return self._hold()
        else:  # a valid reading: a later loss gets the lost spot's budget
            self._blind, self._blind_budget = 0.0, LOST_SEARCH * lim
            self._excess = LOST_EXCESS
            self.seen = True
        if self._cycle is not None:  # a dither runs out and back before anything else
            dither = self._dither_on(meas, sat)
            if dither is not None:
                return dither
        if (self._probes < PROBES and not sat and self.steps and self.last_move is None
                and self.mode == "step" and self._site == self._probes
                and self._reaches_edge()):
            if len(self._noise) < NOISE_MIN:  # the reading's noise first (a vibration's too)
                return self._quiet_start(meas)
            dither = self._dither_start(meas)  # the centre's slope, before the first step
            if dither is not None:
                self._probes += 1
                return dither
        if self.mode == "scan":
            err = self.target - meas
            # leave the scan when the error leaves its range, or when the offset is saturated
            # and the table still short of the target by more than the hold band (the scan
            # cannot reach it; within the band, stepping would first unwind the offset, K·u
            # of travel, to correct an error the hold can live with)
            stuck = (self.pid.saturated and err * self.offset > 0.0
                     and abs(err) > max(self.ctx.tolerance, self._hold_band))  # fmt: skip
            if sat or abs(err) > self.scan_exit * self.ctx.scan_range or (stuck and self.steps):
                self.mode = "step"
                self.estimate = meas if not sat else self.estimate
            else:
                return self._scan(err, meas)
        # step mode: the offset ramps to 0 during the interval (the table follows it back)
        remaining = self.target - self.estimate + k_scan * self.offset
        move = None
        if abs(remaining) > self.scan_fraction * self.ctx.scan_range or sat:
            if self.steps and abs(self.offset) > UNWIND_FRACTION * self.ctx.input_limit:
                return self._unwind()
            move = self.choose_move(remaining * self.remaining_scale, meas, sat)
            if move is None and (sat or abs(remaining) > self.scan_exit * self.ctx.scan_range):
                move = self.search_move(1 if remaining > 0 else -1, sat)  # the safety monitor
        if move is None:
            # the hand-over: a stepping interval just ended (not a hold or an unwind) with
            # the error within the scan's reach (beyond it the next interval steps again)
            handover = (self.mode == "step" and self.last_move is not None and not sat
                        and abs(self.target - meas) <= self.scan_exit * self.ctx.scan_range)
            self.mode = "scan"
            self.pid.reset(self.offset)
            return self._scan(self.target - meas if not sat else 0.0, meas, handover)
        self.last_move = move
        self._site, self._probes = 0, PROBES  # (no probe after stepping)
        self._scan_err, self._scan_streak = None, 0  # not a scan interval
        self._handover = None  # (its response is not measured across a step)
        if sat:
            self._blind += abs(move.expected)
        self.estimate -= k_scan * self.offset
        self._offset_before = self.offset
        self.offset = 0.0
        self.last_measured = None if sat else meas
        return self.ctx.scaling.encode(move.amplitude, move.frequency, move.a, move.k, 0.0)

    def _hold(self) -> np.ndarray:
        """One interval with the generator idle and the scan offset kept: the blind-travel
        budget is spent without the spot appearing, so the steps do not go where the
        controller believes (a plant stepping backwards): it stops rather than run away."""
        self.mode = "scan"
        self.last_move = None
        self._scan_err, self._scan_streak = None, 0  # not a scan interval
        self._handover = None
        self.last_measured = None
        return self.ctx.scaling.encode(0.0, 100.0, 0.9, 0.0, self.offset)

    def _unwind(self) -> np.ndarray:
        """One interval with the generator idle and the scan offset ramped to 0 (the table
        follows it back, K·u): a saturated offset would leave no amplitude to step with."""
        self.estimate -= self.ctx.scan_gain * self.offset
        self.offset = 0.0
        self.last_move = None
        self._scan_err, self._scan_streak = None, 0  # not a scan interval
        self._handover = None
        self.last_measured = None
        return self.ctx.scaling.encode(0.0, 100.0, 0.9, 0.0, 0.0)

    def _learn_dead_band(self, meas: float) -> None:
        """The scan's dead band after stepping [V] in the direction of the last hand-over's
        offset step Δu, from its response: the table followed Δθ/K of it; the rest, clipped
        to [0, |Δu|], is lost (whatever its cause: a hysteresis branch or a creep after
        the flybacks; about 0 on a plant without)."""
        if self._handover is None:
            return
        du, before = self._handover
        self._handover = None
        if abs(du) >= DEAD_MIN and not self.saturated(meas):
            s = 1 if du > 0.0 else -1
            lost = s * du - s * (meas - before) / self.ctx.scan_gain
            self._dead[s] = float(np.clip(lost, 0.0, abs(du)))

    def _dither_start(self, meas: float) -> np.ndarray | None:
        """The way out of an offset dither: ``DITHER_FRACTION`` u_max towards the
        detector's centre from the present offset (None where the input limit leaves
        under 0.5 V of room that way)."""
        s = -1.0 if self._raw > 0.0 else 1.0
        lim = self.ctx.input_limit
        u = float(np.clip(self.offset + s * DITHER_FRACTION * lim, -lim, lim))
        if abs(u - self.offset) < 0.5:
            return None
        self._cycle = (1, self.offset, u - self.offset, self._raw, math.nan)
        self._dither_target = self.target  # (a next one follows at once only on it)
        return self._idle(u, meas)

    def _dither_on(self, meas: float, saturated: bool) -> np.ndarray | None:
        """The dither's next interval: after the way out, the way back to the offset
        before; after the way back, its three readings go to the linearity and None lets
        the interval run as it would have (a saturated reading ends it unread)."""
        if self._cycle is None:
            return None
        phase, before, du, r0, r1 = self._cycle
        if saturated:
            self._cycle = None
            return None
        if phase == 1:
            self._cycle = (2, before, du, r0, self._raw)
            return self._idle(before, meas)
        self._cycle = None
        self._site += 1
        if self._site > 1:  # the first loop after stepping (or at rest) is no steady one
            sigma = float(np.median(self._noise)) / 0.954 if len(self._noise) >= NOISE_MIN else 0.0
            self.linearity.add(du, (r0, r1, self._raw), sigma)
        # a settled target's next dither follows at once where the reading, corrected by
        # the κ̂ decided so far, still puts the table on it (the way back left it where it
        # was); else the dither's changes are no noise sample, and the PID settles again
        on_target = abs(self.target - meas) <= max(self.ctx.tolerance, self._hold_band)
        if (self.mode == "scan" and self.target == self._dither_target and on_target
                and self._wants_dither()):
            dither = self._dither_start(meas)
            if dither is not None:
                self._dithered[self.target] = self._dithered.get(self.target, 0) + 1
                return dither
        self._scan_err, self._scan_streak = None, 0
        return None

    def _quiet_start(self, meas: float) -> np.ndarray:
        """An idle interval before the probes: the change of the raw reading between two
        idle intervals is the reading's noise (and a floor vibration's), which the dithers'
        slopes are weighed with (the scan's holds measure it later)."""
        if self._idle_raw is not None:
            self._noise.append(abs(self._raw - self._idle_raw))
        self._idle_raw = self._raw
        return self._idle(self.offset, meas)

    def _idle(self, u: float, meas: float) -> np.ndarray:
        """One interval with the generator idle at scan offset ``u`` [V] (a dither's)."""
        self.last_move = None
        self.offset = u
        self.last_measured = meas
        self._scan_err = None
        return self.ctx.scaling.encode(0.0, 100.0, 0.9, 0.0, u)

    def _quiet(self) -> int:
        """The intervals at the end of a known reference that are not dithered."""
        return round(QUIET_END_S / self.ctx.control_interval)

    def _levels(self) -> list[float]:
        """A known reference's start and the values it holds for ``FAR_HOLD`` intervals
        before its last ``QUIET_END_S`` [rad] (where a dither can be made)."""
        ref = self._brief.reference_rad
        if ref is None:
            return []
        r = np.asarray(ref, dtype=np.float32)  # as the targets are compared (reference_at)
        r = r[: max(r.size - self._quiet(), 0)]
        cuts = np.flatnonzero(np.diff(r) != 0.0) + 1  # where a hold of one value ends
        held = [float(run[0]) for run in np.split(r, cuts) if run.size >= FAR_HOLD]
        return [float(ref[0]), *held]

    def _plans_visit(self) -> bool:
        """Whether the episode first visits the detector's centre for its dithers: a known
        reference whose last value lies beyond ``dither_from`` θ_lin, none of whose
        :meth:`_levels` pairs with it (m² at most half or at least twice its own)."""
        ref = self._brief.reference_rad
        if ref is None or not self.steps:
            return False
        lim = self.ctx.angle_range
        end = (float(ref[-1]) / lim) ** 2
        if end < self.ctx.dither_from**2:
            return False
        pairs = [(v / lim) ** 2 <= 0.5 * end or (v / lim) ** 2 >= 2.0 * end
                 for v in self._levels()]  # fmt: skip
        return not any(pairs)

    def _reaches_edge(self) -> bool:
        """Whether the episode will dither beyond ``dither_from`` θ_lin, where the
        detector's cubic matters, so that a probe near the start is worth its intervals (it
        reads the slope the far dithers are compared with): a target beyond it, a known
        reference that holds a value beyond it for ``FAR_HOLD`` intervals before its last
        ``QUIET_END_S``, or one that visits the centre (the start is then the far place;
        a ramp's set points never settle, and the hold after it lies in the quiet end)."""
        edge = self.ctx.dither_from * self.ctx.angle_range
        if self._brief.reference_rad is None:
            return abs(self.target) >= edge
        if self._visit:  # the start is the far place the centre's dithers pair with
            return True
        return any(abs(v) >= edge for v in self._levels()[1:])

    def _wants_dither(self) -> bool:
        """Whether a settled scan on the present target should dither for the detector's
        linearity: the centre while a visit lasts; otherwise not on an anchor, and only
        where the target lies beyond ``dither_from`` θ_lin (or nearer the centre, pairing
        with a known reference's last value beyond it) and has had fewer than ``DITHERS``,
        a known reference does not end within ``QUIET_END_S``, κ̂ is neither decided
        precisely enough (its error at the target within a quarter of the tolerance) nor
        clearly under ``KAPPA_MIN`` (|κ̂| + 2σ), and a dither read elsewhere pairs with
        this place (:meth:`DetectorLinearity.lever`)."""
        if self._visit:  # the centre's dithers (their count ends the visit)
            return True
        if self._far_target is not None:  # an anchor: κ̂ is decided, the hold goes beyond
            return False
        lim, edge = self.ctx.angle_range, self.ctx.dither_from**2
        m2 = (self.target / lim) ** 2
        if self._dithered.get(self.target, 0) >= DITHERS:
            return False
        ref = self._brief.reference_rad
        if ref is not None and len(ref) - self._interval <= self._quiet():
            return False
        # a target near the centre is worth dithering on where it pairs with a known
        # reference's last value that needs κ (the slope there is the fit's intercept)
        end = (float(ref[-1]) / lim) ** 2 if ref is not None else 0.0
        if m2 < edge and not (end >= edge and m2 <= 0.5 * end):
            return False
        k, sd, decided = self.linearity.estimate()
        # decided, the target's error from κ's uncertainty within a quarter of the band
        precise = decided and sd * m2 * abs(self.target) <= 0.25 * self.ctx.tolerance
        # or clearly under KAPPA_MIN (a linear detector: nothing more to learn)
        linear = abs(k) + 2.0 * sd < KAPPA_MIN
        return not (precise or linear) and self.linearity.lever(m2)

    def _scan(self, err: float, meas: float, handover: bool = False) -> np.ndarray:
        # the reading's noise: robust σ of the error's change between scan intervals on a
        # target that stays, once the PID's first corrections after a step are past
        steady = self._scan_target == self.target
        self._scan_streak = self._scan_streak + 1 if steady else 0
        if self._scan_streak >= SETTLING and self._scan_err is not None:
            # the error's change less the change the last offset step made, K·Δu (the scan
            # plant P(z) = K·z⁻¹): a PID still converging is not counted as noise
            moved = self.ctx.scan_gain * (self.offset - self._scan_offset)
            self._noise.append(abs(err - self._scan_err + moved))
        self._scan_err, self._scan_target, self._scan_offset = err, self.target, self.offset
        hold = 0.0
        settled = self._scan_streak >= SETTLING  # (a hand-over's transient is no noise)
        if settled and len(self._noise) >= NOISE_MIN:  # median |Δe| = 0.954 σ (Gaussian)
            hold = HOLD_SIGMAS * float(np.median(self._noise)) / 0.954
        self._hold_band = hold  # rad
        if settled and not handover and len(self._noise) >= NOISE_MIN and self._wants_dither():
            dither = self._dither_start(meas)
            if dither is not None:
                self._dithered[self.target] = self._dithered.get(self.target, 0) + 1
                return dither
        gain = self.linearity.scan_gain
        if (settled and not handover and self._far_target is not None and gain is not None
                and abs(err) <= max(self.ctx.tolerance, hold)):  # on the anchor: beyond it
            u = self.pid.u + (self._far_target - self.target) / gain
            if abs(u) <= self.ctx.input_limit:
                self._beyond = (self._far_target, u)
                return self._idle(u, meas)
        # after stepping, the scan plant's inverse closes HANDOVER_GAIN of the error at once
        # (P(z) = K·z⁻¹: the PID's first, integral-only update would take about four
        # intervals); the PID goes on from there
        self._learn_dead_band(meas)
        if handover:  # the dead band last measured added in the error's direction
            before = self.pid.u
            s = 1 if err > 0.0 else -1
            u = self.pid.jump(err, HANDOVER_GAIN, s * self._dead[s])
            self._handover = (u - before, meas)
        else:
            u = self.pid.update(err, hold)
        self.last_move = None
        self.offset = u
        self.last_measured = meas
        return self.ctx.scaling.encode(0.0, 100.0, 0.9, 0.0, u)
