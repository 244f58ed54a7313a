"""Configuration of the PiezoTurntable task and the action scaling (SI units throughout).

:class:`EnvConfig` holds every constructor argument of the environments, validated, and
resolves the :class:`~turntable_env.plant.Plant` they run; :class:`ActionScaling` maps the
normalised action Box [-1, 1]^5 to the physical generator setting (§4.1.2 amplifier
input, Fig. 3.14 / Fig. 4.3 waveforms); :data:`OBS` names the observation's components.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import numpy as np

from ..params import ParameterSet
from ..plant import DEFAULT_RANDOMIZATION, FIDELITIES, NAMED_PLANTS, PARAMETER_SETS, Plant
from ..plant.stepper import MAX_PLANTS
from ..validation import check_nonnegative, check_positive, describe

__all__ = [
    "ACTION_NAMES",
    "DEFAULT_FIDELITY",
    "DEFAULT_RANDOMIZATION",
    "MAX_NUM_ENVS",
    "MAX_REWARD_WEIGHT",
    "OBS",
    "OBSERVATION_NAMES",
    "OBSERVATION_NAMES_Y",
    "OBS_Y",
    "ActionScaling",
    "EnvConfig",
    "ObservationIndex",
    "check_action",
    "make_config",
]

# The model a plant given by ``params`` runs (issue 32): the per-axis model with the
# sphere's translation and tilts and the contacts' normal forces, within 5 % of the 3-D
# model's step over ``turntable bench``'s sweep (``env_vs_full_max``); the per-axis form
# without them (``"reduced"``, about 7× faster per env step) differs by up to 8.6×.
DEFAULT_FIDELITY: Literal["translation"] = "translation"

ACTION_NAMES = ("amplitude", "frequency", "ramp_ratio", "slew_adaptation", "scan_offset")


class ObservationIndex(NamedTuple):
    """Index of each observation component: ``obs[..., OBS.target_angle_rad]``."""

    measured_angle_rad: int
    target_angle_rad: int
    generator_phase: int
    last_amplitude: int
    last_frequency: int
    last_ramp_ratio: int
    last_slew_adaptation: int
    last_scan_offset: int


OBS = ObservationIndex(*range(len(ObservationIndex._fields)))
OBSERVATION_NAMES = ObservationIndex._fields
assert OBSERVATION_NAMES[3:] == tuple(f"last_{n}" for n in ACTION_NAMES)
# with EnvConfig(detector_y=True): the quadrant photodiode's y channel as the last component
OBS_Y = len(OBSERVATION_NAMES)  # index of ``measured_y_rad``
OBSERVATION_NAMES_Y = (*OBSERVATION_NAMES, "measured_y_rad")

F_MIN, F_MAX = 10.0, 2000.0  # Hz, generator frequency range (log scale)
A_MIN, A_MAX = 0.5, 0.99  # ramp ratio range


@dataclass(frozen=True)
class ActionScaling:
    """Normalised action a ∈ [-1, 1]^5 → generator setting (amplifier input).

    ======  ================  ===========================================================
    index   name              physical value
    ======  ================  ===========================================================
    0       amplitude         u_A = a0·u_max [V] (u_max = amplifier input limit, 10 V);
                              sign = direction, 0 = generator idle
    1       frequency         f = 10 Hz·200^((a1 + 1)/2): 10 Hz … 2 kHz, log scale
    2       ramp_ratio        a = 0.5 + 0.49·(a2 + 1)/2: 0.5 … 0.99 (Fig. 3.14)
    3       slew_adaptation   k = max(a3, 0): a3 ≤ 0 plain sawtooth (flyback ramp over
                              (1 − a)/f); a3 > 0 slew-adapted step flyback, overshoot k
                              (Fig. 4.3)
    4       scan_offset       u_0 = a4·u_max [V]: the level the sawtooth sits on, reached by
                              a linear ramp over the control interval (tubes bend, table
                              sticks and follows: sub-step "scan" positioning)
    ======  ================  ===========================================================

    The amplifier clips u_0 + sawtooth at ±u_max (its input stage).
    """

    input_limit: float = 10.0  # V

    def __post_init__(self) -> None:
        if not (isinstance(self.input_limit, int | float) and math.isfinite(self.input_limit)
                and self.input_limit > 0.0):  # fmt: skip
            raise ValueError(f"input_limit={self.input_limit!r}: must be a finite number > 0 V")

    def decode(self, action: np.ndarray) -> tuple[float, float, float, float, float]:
        """(amplitude [V], frequency [Hz], a [-], k [-], offset [V]) of one action, clipped to
        [-1, 1] (:func:`check_action`: ValueError for anything but 5 finite real numbers)."""
        a0, a1, a2, a3, a4 = (float(x) for x in check_action(action, (len(ACTION_NAMES),)))
        return (
            a0 * self.input_limit,
            F_MIN * (F_MAX / F_MIN) ** (0.5 * (a1 + 1.0)),
            A_MIN + (A_MAX - A_MIN) * 0.5 * (a2 + 1.0),
            max(a3, 0.0),
            a4 * self.input_limit,
        )

    def decode_batch(self, actions: np.ndarray) -> np.ndarray:
        """(N, 5) settings of N clipped actions, as :meth:`decode` row by row (ValueError for
        another shape or a value that is not finite)."""
        a = np.asarray(actions, dtype=float)
        if a.ndim != 2 or a.shape[1] != len(ACTION_NAMES) or not np.isfinite(a).all():
            raise ValueError(
                f"actions: shape {a.shape}: must be (N, {len(ACTION_NAMES)}) finite numbers"
            )
        out = np.empty_like(a)
        out[:, 0] = a[:, 0] * self.input_limit
        out[:, 1] = F_MIN * (F_MAX / F_MIN) ** (0.5 * (a[:, 1] + 1.0))
        out[:, 2] = A_MIN + (A_MAX - A_MIN) * 0.5 * (a[:, 2] + 1.0)
        out[:, 3] = np.maximum(a[:, 3], 0.0)
        out[:, 4] = a[:, 4] * self.input_limit
        return out

    def encode(
        self, amplitude: float, frequency: float, a: float, k: float = 0.0, offset: float = 0.0
    ) -> np.ndarray:
        """The action (float32) that decodes to this setting (inverse of :meth:`decode`);
        ValueError for a value that is not a finite real number, or a frequency ≤ 0 Hz."""
        named = {"amplitude": amplitude, "frequency": frequency, "a": a, "k": k, "offset": offset}
        for name, v in named.items():
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating) \
                    or not math.isfinite(v):
                raise ValueError(f"{name}={v!r}: must be a finite real number")
        if frequency <= 0.0:
            raise ValueError(f"frequency={frequency!r}: must be > 0 Hz")
        x = np.array(
            [
                amplitude / self.input_limit,
                2.0 * math.log(frequency / F_MIN) / math.log(F_MAX / F_MIN) - 1.0,
                2.0 * (a - A_MIN) / (A_MAX - A_MIN) - 1.0,
                k if k > 0.0 else 0.0,
                offset / self.input_limit,
            ]
        )
        bad = np.nonzero((x < -1.0 - 1e-9) | (x > 1.0 + 1e-9))[0]
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"{ACTION_NAMES[i]}: {x[i]:.4g} outside the action range [-1, 1]")
        return np.clip(x, -1.0, 1.0).astype(np.float32)


def make_config(options: Mapping[str, Any]) -> EnvConfig:
    """An :class:`EnvConfig` from keyword options (``gym.make``'s); an unknown option is a
    ValueError naming it and the ones there are."""
    known = {f.name for f in dataclasses.fields(EnvConfig) if f.init}  # not the derived ranges
    unknown = sorted(set(options) - known)
    if unknown:
        raise ValueError(f"{unknown[0]}: not an option of the env ({', '.join(sorted(known))})")
    return EnvConfig(**options)


def check_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """The action as float64, clipped to [-1, 1]; anything but real numbers (complex,
    strings, mappings, integers beyond float), NaN/inf or a wrong shape → ValueError, one
    line naming the value (shortened) and what is wrong."""
    if isinstance(action, Mapping | str | bytes):
        raise ValueError(f"action={describe(action)}: must be an array of real numbers")
    try:
        raw = np.asarray(action)
        if raw.dtype.kind not in "biuf":
            raise TypeError
        a = raw.astype(np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"action={describe(action)}: must be an array of real numbers") from None
    if a.shape != shape:
        raise ValueError(f"action={describe(action)}: shape {a.shape}, expected {shape}")
    if not np.isfinite(a).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise ValueError(f"action={describe(action)}: must be finite ({a[bad]} at index "
                         f"{bad[0] if len(bad) == 1 else bad})")  # fmt: skip
    return np.clip(a, -1.0, 1.0)


MIN_TOLERANCE = 1e-12  # rad, the smallest success tolerance (the detector's noise is ~1e-7)
MAX_CONTROL_INTERVAL = 10.0  # s: one env step at most (a frozen env below one grid step)
RETARGET_HORIZON = 1000  # control intervals of a retargeting episode's legs (the last holds)
# a reward term's weight (energy_weight, success_bonus) at most: the energy term is
# w·E/E_ref, E/E_ref (in full-amplitude periods) of order 10⁴ at most in an interval
# (2 kHz × 10 s), so no reward can overflow; 10⁶ is far beyond any useful weight (0.01, 1)
MAX_REWARD_WEIGHT = 1e6
# turntables of one vector env at most, checked before anything is allocated: the plant
# stepper's own bound (~62 kB a turntable in its arrays alone, ~0.5 GB at 2¹³), more than
# any machine here trains on
MAX_NUM_ENVS = MAX_PLANTS


def _pair(name: str, value: Any) -> tuple[Any, Any]:
    """A (low, high) pair: a sequence of exactly two items (not a string)."""
    if isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence | np.ndarray):
        raise ValueError(f"{name}={value!r}: must be (low, high)")
    if len(value) != 2:
        raise ValueError(f"{name}={value!r}: must be (low, high), got {len(value)} values")
    return value[0], value[1]


@dataclass(frozen=True)
class EnvConfig:
    """Every constructor argument of the PiezoTurntable environments (SI units).

    Args:
        plant: the :class:`~turntable_env.plant.Plant` to run, the name of a stored plant
            (``"calibrated"``: the thesis calibration's plant whole, with its
            uncertainties, :meth:`~turntable_env.plant.Plant.named`; ValueError when a
            path of that name exists too), or the path of a
            calibration ``report.json`` (or its directory) whose plant to run
            (:meth:`~turntable_env.plant.Plant.from_report`): its parameter set, effects,
            fidelity and detector noise. Default: the plant of ``params`` on
            :data:`DEFAULT_FIDELITY`.
        params: ``"real"`` (Table D.1, the default plant), ``"thesis"`` (Table D.2),
            ``"calibrated"`` (the real turntable with the rig the thesis's figures ask for)
            or a ParameterSet, without effects; give ``plant`` or ``params``, not both.
        fidelity: ``"reduced"`` (per-axis model), ``"translation"`` (it with the sphere's
            translation and tilts and the contacts' normal forces), ``"full"`` (3-D model;
            ``turntable bench`` compares the two real-time factors) or ``"independent"`` (the
            independent test plant, :mod:`turntable_env.plant.independent`); default: a
            ``plant``'s own, and :data:`DEFAULT_FIDELITY` (``"translation"``) for the plant
            of ``params``.
        axis: rotation axis under control, ``"A"``, ``"B"`` (default) or ``"C"``.
        control_interval: time per env step [s] (0.01: one period of the 100 Hz nominal drive).
        randomize: domain randomisation per episode (:meth:`Plant.sample`): False; True —
            from the plant's calibration uncertainties when it has them (a report's plant,
            or the stored ``"calibrated"`` one: its posterior), otherwise
            :data:`DEFAULT_RANDOMIZATION`; or a mapping of some of its keys to (low, high)
            factor ranges.
        noise: detector noise on (True) or off.
        detector_y: also observe the quadrant photodiode's y channel, read by Eq. 4.1 like
            the x channel (``measured_y_rad``, the observation's last component,
            :data:`OBS_Y`): what a lab's photodiode gives besides x. A rotation about the
            watched axis reads on it through an axis misalignment φ (θ·sin φ, while x reads
            θ·cos φ). False (default) keeps the 8 components the agents were trained on.
        sensor_noise: detector voltage noise standard deviation [V] when ``noise``;
            default: the plant's (1 mV).
        tolerance: |target − angle| that ends the episode successfully [rad].
        terminate_on_success: end the episode when the tolerance is reached (True, default);
            False keeps it running to the time limit, so a controller must also hold the
            target (the controller benchmark measures settling this way).
        energy_weight: weight of the electrical-energy cost in the reward [-], 0 …
            :data:`MAX_REWARD_WEIGHT`.
        start_range: start angles are drawn uniformly within ±start_range·θ_lin, θ_lin the
            detector's linear angle range [-].
        target_range: target angles likewise, within ±target_range·θ_lin [-].
        move_range: (smallest, largest) move [rad]: when given, the start is the target
            less a move of log-uniform size in this range and random sign (moves may start
            beyond the detector range, as the controller benchmark's do); ``start_range``
            is then unused.
        reward: ``"linear"`` (default): distance term −|θ* − θ|/θ_lin; ``"log"``:
            −ln(1 + d/tol)/ln(1 + θ_lin/tol), which resolves every decade from the
            tolerance up (d = |θ* − θ|, tol = ``tolerance``).
        success_bonus: reward added in every interval that ends within ``tolerance`` [-]
            (0: none; a training aid for holding the target), 0 … :data:`MAX_REWARD_WEIGHT`.
        retarget_share: share of episodes whose target jumps [-] (0, the default: every
            target fixed): such an episode holds each target for a leg of
            ``retarget_legs`` control intervals (integers drawn uniformly, both ends
            included) and then jumps to a new one within ±``target_range``·θ_lin, as the
            controller benchmark's tracking tasks do (waypoints, back and forth), so
            training meets a controller holding one target when the next is commanded.
            The legs are a ``reference`` (reset option) of :data:`RETARGET_HORIZON`
            intervals; an episode given a reference or a target keeps it.
        retarget_legs: (shortest, longest) leg [control intervals], 1 <= low <= high <=
            :data:`RETARGET_HORIZON`.
        angle_limit: |θ| beyond which the episode is truncated (the table leaves the
            small-angle workspace the model covers) [rad].
    """

    plant: Plant | str | os.PathLike[str] | None = None
    params: str | ParameterSet | None = None
    fidelity: Literal["reduced", "translation", "full", "independent"] | None = None
    axis: str = "B"
    control_interval: float = 0.01
    randomize: bool | Mapping[str, tuple[float, float]] = False
    noise: bool = True
    detector_y: bool = False
    sensor_noise: float | None = None
    tolerance: float = 1e-6
    terminate_on_success: bool = True
    energy_weight: float = 0.01
    start_range: float = 0.8
    target_range: float = 0.8
    angle_limit: float = 0.05
    move_range: tuple[float, float] | None = None
    reward: Literal["linear", "log"] = "linear"
    success_bonus: float = 0.0
    retarget_share: float = 0.0
    retarget_legs: tuple[int, int] = (15, 40)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        if self.fidelity is not None and self.fidelity not in FIDELITIES:
            raise ValueError(f"fidelity={self.fidelity!r}: must be one of {', '.join(FIDELITIES)}")
        if self.sensor_noise is not None:
            check_nonnegative("sensor_noise", self.sensor_noise)
        object.__setattr__(self, "plant", self._resolve_plant())
        if self.axis not in ("A", "B", "C"):
            raise ValueError(f"axis={self.axis!r}: must be 'A', 'B' or 'C'")
        if check_positive("control_interval", self.control_interval) > MAX_CONTROL_INTERVAL:
            raise ValueError(
                f"control_interval={self.control_interval!r}: must be <= {MAX_CONTROL_INTERVAL} s"
            )
        if not isinstance(self.noise, bool):
            raise ValueError(f"noise={self.noise!r}: must be a bool")
        if not isinstance(self.detector_y, bool):
            raise ValueError(f"detector_y={self.detector_y!r}: must be a bool")
        if check_positive("tolerance", self.tolerance) < MIN_TOLERANCE:
            raise ValueError(
                f"tolerance={self.tolerance!r}: must be >= {MIN_TOLERANCE:g} rad (far below "
                "the detector's noise; a smaller one overflows the log reward)"
            )
        if not isinstance(self.terminate_on_success, bool):
            raise ValueError(f"terminate_on_success={self.terminate_on_success!r}: must be a bool")
        for name in ("energy_weight", "success_bonus"):
            if check_nonnegative(name, getattr(self, name)) > MAX_REWARD_WEIGHT:
                raise ValueError(
                    f"{name}={describe(getattr(self, name))}: must be <= {MAX_REWARD_WEIGHT:g} "
                    "(a reward weight)"
                )
        for name in ("start_range", "target_range"):
            v = check_nonnegative(name, getattr(self, name))
            if v > 1.0:
                raise ValueError(f"{name}={v!r}: must be <= 1 (fraction of the detector range)")
        check_positive("angle_limit", self.angle_limit)
        if self.move_range is not None:
            lo, hi = (check_positive("move_range", x) for x in _pair("move_range", self.move_range))
            if lo > hi or hi >= self.angle_limit:
                raise ValueError(f"move_range={self.move_range!r}: need low <= high < angle_limit")
            object.__setattr__(self, "move_range", (lo, hi))
        share = check_nonnegative("retarget_share", self.retarget_share)
        if share > 1.0:
            raise ValueError(f"retarget_share={share!r}: must be <= 1 (a share of episodes)")
        legs = _pair("retarget_legs", self.retarget_legs)
        if not all(isinstance(x, int | np.integer) and not isinstance(x, bool) for x in legs):
            raise ValueError(f"retarget_legs={self.retarget_legs!r}: must be two integers")
        if not 1 <= legs[0] <= legs[1] <= RETARGET_HORIZON:
            raise ValueError(
                f"retarget_legs={self.retarget_legs!r}: need 1 <= low <= high <= "
                f"{RETARGET_HORIZON} (the reference's intervals)"
            )
        object.__setattr__(self, "retarget_legs", (int(legs[0]), int(legs[1])))
        if self.reward not in ("linear", "log"):
            raise ValueError(f"reward={self.reward!r}: must be 'linear' or 'log'")
        # every draw of a reset within the factors' bounds, checked now (Plant.check_ranges)
        ranges = self.plant.check_ranges(_randomization_ranges(self.randomize), name="randomize")
        if self.randomize is True and not self.plant.uncertainty:  # the default ranges
            self.plant.check_ranges(DEFAULT_RANDOMIZATION, name="randomize")
        object.__setattr__(self, "ranges", ranges)
        needs_unlisted = {"friction", "preload"} & set(
            self.ranges or (DEFAULT_RANDOMIZATION if not self.plant.uncertainty else ())
        )
        if self.randomized and needs_unlisted and self.plant.base_parameters.unlisted is None:
            raise ValueError(
                f"randomize: {sorted(needs_unlisted)} need a parameter set with unlisted "
                f"inputs (the real set's friction and preload are derived through "
                f"Hertz–Mindlin); {self.plant.base_parameters.name!r} has none"
            )

    def _resolve_plant(self) -> Plant:
        """The plant: ``plant`` (a Plant or a report path) or the plant of ``params``, with
        ``fidelity`` and ``sensor_noise`` where given."""
        plant = self.plant
        if plant is not None and self.params is not None:
            raise ValueError(f"params={self.params!r}, plant={plant!r}: give one of them")
        if plant is None:
            params = "real" if self.params is None else self.params
            if isinstance(params, str) and params not in PARAMETER_SETS:
                raise ValueError(
                    f"params={params!r}: must be one of {', '.join(PARAMETER_SETS)} or a "
                    "ParameterSet"
                )
            if not isinstance(params, str | ParameterSet):
                raise ValueError(f"params={params!r}: must be a set's name or a ParameterSet")
            plant = Plant(params, fidelity=DEFAULT_FIDELITY)
        elif isinstance(plant, str) and plant in NAMED_PLANTS:
            if os.path.exists(plant):  # a report directory of that name: say which is meant
                raise ValueError(
                    f"plant={plant!r}: both a stored plant and a path here; give "
                    f"Plant.named({plant!r}) or the path as './{plant}'"
                )
            plant = Plant.named(plant)
        elif isinstance(plant, str | os.PathLike):
            plant = Plant.from_report(plant)
        elif not isinstance(plant, Plant):
            raise ValueError(f"plant={plant!r}: must be a Plant or a calibration report path")
        changes: dict[str, Any] = {}
        if self.fidelity is not None:
            changes["fidelity"] = self.fidelity
        if self.sensor_noise is not None:
            changes["sensor_noise"] = float(self.sensor_noise)
        return plant.replace(**changes) if changes else plant

    @property
    def randomized(self) -> bool:
        """True if each episode draws its plant (:meth:`Plant.sample`)."""
        return self.randomize is True or bool(self.ranges)

    @property
    def parameter_set(self) -> ParameterSet:
        """The plant's parameter set (nominal: before any randomisation)."""
        return self.plant.params  # type: ignore[union-attr]

    @property
    def observation_names(self) -> tuple[str, ...]:
        """The observation's components in order (:data:`OBSERVATION_NAMES`, and
        ``measured_y_rad`` with ``detector_y``)."""
        return OBSERVATION_NAMES_Y if self.detector_y else OBSERVATION_NAMES

    @property
    def scaling(self) -> ActionScaling:
        return ActionScaling(self.parameter_set.amplifier.input_limit)


def _randomization_ranges(
    spec: bool | Mapping[str, tuple[float, float]],
) -> dict[str, tuple[float, float]]:
    """The factor ranges of a ``randomize`` mapping; {} for False and True (True: the
    plant's own — its calibration uncertainties or :data:`DEFAULT_RANDOMIZATION`)."""
    if spec is False or spec is None or spec is True:
        return {}
    if not isinstance(spec, Mapping):
        raise ValueError(f"randomize={spec!r}: must be a bool or a mapping of factor ranges")
    out = {}
    for key, rng in spec.items():  # keys, order and the factors' bounds: Plant.check_ranges
        name = f"randomize[{key!r}]"
        out[key] = tuple(check_positive(name, x) for x in _pair(name, rng))
    return out
