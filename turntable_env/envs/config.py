"""Configuration of the PiezoTurntable task and the action scaling (SI units throughout).

:class:`EnvConfig` holds every constructor argument of the environments, validated;
:class:`ActionScaling` maps the normalised action Box [-1, 1]^5 to the physical
generator setting (§4.1.2 amplifier input, Fig. 3.14 / Fig. 4.3 waveforms).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from ..params import ParameterSet, get_parameter_set, real_parameters
from ..validation import check_nonnegative, check_positive

__all__ = [
    "ACTION_NAMES",
    "DEFAULT_RANDOMIZATION",
    "OBSERVATION_NAMES",
    "ActionScaling",
    "EnvConfig",
    "check_action",
    "sample_parameters",
]

ACTION_NAMES = ("amplitude", "frequency", "ramp_ratio", "slew_adaptation", "scan_offset")
OBSERVATION_NAMES = (
    "measured_angle_rad",
    "target_angle_rad",
    "generator_phase",
    *(f"last_{n}" for n in ACTION_NAMES),
)

# Domain randomisation: multiplicative factors drawn uniformly per episode.
DEFAULT_RANDOMIZATION: dict[str, tuple[float, float]] = {
    "friction": (0.8, 1.2),  # µ_s and µ_c together (dry-contact scatter, ±20 %)
    "preload": (0.8, 1.2),  # normal force F_N of the preload spring (unmeasured, ±20 %)
    "amplifier": (0.9, 1.1),  # slew rate per input volt and current limit (±10 %)
    "sensor_noise": (0.5, 2.0),  # detector noise standard deviation
}

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

    def decode(self, action: np.ndarray) -> tuple[float, float, float, float, float]:
        """(amplitude [V], frequency [Hz], a [-], k [-], offset [V]) of one clipped action."""
        a0, a1, a2, a3, a4 = (float(x) for x in action)
        return (
            a0 * self.input_limit,
            F_MIN * (F_MAX / F_MIN) ** (0.5 * (a1 + 1.0)),
            A_MIN + (A_MAX - A_MIN) * 0.5 * (a2 + 1.0),
            max(a3, 0.0),
            a4 * self.input_limit,
        )

    def encode(
        self, amplitude: float, frequency: float, a: float, k: float = 0.0, offset: float = 0.0
    ) -> np.ndarray:
        """The action (float32) that decodes to this setting (inverse of :meth:`decode`)."""
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


def check_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """The action as float64, clipped to [-1, 1]; NaN/inf or a wrong shape → ValueError."""
    a = np.asarray(action, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"action={action!r}: shape {a.shape}, expected {shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"action={action!r}: must be finite (NaN or inf found)")
    return np.clip(a, -1.0, 1.0)


@dataclass(frozen=True)
class EnvConfig:
    """Every constructor argument of the PiezoTurntable environments (SI units).

    Args:
        params: ``"real"`` (Table D.1, default), ``"thesis"`` (Table D.2) or a ParameterSet.
        fidelity: ``"reduced"`` (per-axis model, default) or ``"full"`` (3-D model;
            ``turntable bench`` compares the two real-time factors).
        axis: rotation axis under control, ``"A"``, ``"B"`` (default) or ``"C"``.
        control_interval: time per env step [s] (0.01: one period of the 100 Hz nominal drive).
        randomize: domain randomisation: False, True (:data:`DEFAULT_RANDOMIZATION`) or a
            mapping of some of its keys to (low, high) factor ranges.
        noise: detector noise on (True) or off.
        sensor_noise: detector voltage noise standard deviation [V] when ``noise`` (1 mV).
        tolerance: |target − angle| that ends the episode successfully [rad].
        terminate_on_success: end the episode when the tolerance is reached (True, default);
            False keeps it running to the time limit, so a controller must also hold the
            target (the controller benchmark measures settling this way).
        energy_weight: weight of the electrical-energy cost in the reward [-].
        start_range, target_range: start and target angles are drawn uniformly within
            ±range·θ_lin, θ_lin the detector's linear angle range [-].
        move_range: (smallest, largest) move [rad]: when given, the start is the target
            less a move of log-uniform size in this range and random sign (moves may start
            beyond the detector range, as the controller benchmark's do); ``start_range``
            is then unused.
        reward: ``"linear"`` (default): distance term −|θ* − θ|/θ_lin; ``"log"``:
            −ln(1 + d/tol)/ln(1 + θ_lin/tol), which resolves every decade from the
            tolerance up (d = |θ* − θ|, tol = ``tolerance``).
        success_bonus: reward added in every interval that ends within ``tolerance`` [-]
            (0: none; a training aid for holding the target).
        angle_limit: |θ| beyond which the episode is truncated (the table leaves the
            small-angle workspace the model covers) [rad].
    """

    params: str | ParameterSet = "real"
    fidelity: Literal["reduced", "full"] = "reduced"
    axis: str = "B"
    control_interval: float = 0.01
    randomize: bool | Mapping[str, tuple[float, float]] = False
    noise: bool = True
    sensor_noise: float = 1e-3
    tolerance: float = 1e-6
    terminate_on_success: bool = True
    energy_weight: float = 0.01
    start_range: float = 0.8
    target_range: float = 0.8
    angle_limit: float = 0.05
    move_range: tuple[float, float] | None = None
    reward: Literal["linear", "log"] = "linear"
    success_bonus: float = 0.0
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        if isinstance(self.params, str) and self.params not in ("real", "thesis"):
            raise ValueError(f"params={self.params!r}: must be 'real', 'thesis' or a ParameterSet")
        if not isinstance(self.params, str | ParameterSet):
            raise ValueError(f"params={self.params!r}: must be 'real', 'thesis' or a ParameterSet")
        if self.fidelity not in ("reduced", "full"):
            raise ValueError(f"fidelity={self.fidelity!r}: must be 'reduced' or 'full'")
        if self.axis not in ("A", "B", "C"):
            raise ValueError(f"axis={self.axis!r}: must be 'A', 'B' or 'C'")
        check_positive("control_interval", self.control_interval)
        if not isinstance(self.noise, bool):
            raise ValueError(f"noise={self.noise!r}: must be a bool")
        check_nonnegative("sensor_noise", self.sensor_noise)
        check_positive("tolerance", self.tolerance)
        if not isinstance(self.terminate_on_success, bool):
            raise ValueError(f"terminate_on_success={self.terminate_on_success!r}: must be a bool")
        check_nonnegative("energy_weight", self.energy_weight)
        for name in ("start_range", "target_range"):
            v = check_nonnegative(name, getattr(self, name))
            if v > 1.0:
                raise ValueError(f"{name}={v!r}: must be <= 1 (fraction of the detector range)")
        check_positive("angle_limit", self.angle_limit)
        if self.move_range is not None:
            try:
                lo, hi = (check_positive("move_range", float(x)) for x in self.move_range)
            except TypeError:
                raise ValueError(f"move_range={self.move_range!r}: must be (low, high)") from None
            if lo > hi or hi >= self.angle_limit:
                raise ValueError(f"move_range={self.move_range!r}: need low <= high < angle_limit")
            object.__setattr__(self, "move_range", (lo, hi))
        check_nonnegative("success_bonus", self.success_bonus)
        if self.reward not in ("linear", "log"):
            raise ValueError(f"reward={self.reward!r}: must be 'linear' or 'log'")
        object.__setattr__(self, "ranges", _randomization_ranges(self.randomize))
        if self.ranges and self.parameter_set.name != "real":
            raise ValueError(
                "randomize: defined for the real parameter set (its friction and preload are "
                "derived through Hertz–Mindlin from data/real_unlisted.toml)"
            )

    @property
    def parameter_set(self) -> ParameterSet:
        return get_parameter_set(self.params) if isinstance(self.params, str) else self.params

    @property
    def scaling(self) -> ActionScaling:
        return ActionScaling(self.parameter_set.amplifier.input_limit)


def _randomization_ranges(
    spec: bool | Mapping[str, tuple[float, float]],
) -> dict[str, tuple[float, float]]:
    if spec is False or spec is None:
        return {}
    if spec is True:
        return dict(DEFAULT_RANDOMIZATION)
    if not isinstance(spec, Mapping):
        raise ValueError(f"randomize={spec!r}: must be a bool or a mapping of factor ranges")
    out = {}
    for key, rng in spec.items():
        if key not in DEFAULT_RANDOMIZATION:
            raise ValueError(
                f"randomize[{key!r}]: unknown (choose from {', '.join(DEFAULT_RANDOMIZATION)})"
            )
        try:
            lo, hi = (check_positive(f"randomize[{key!r}]", x) for x in rng)
        except TypeError:
            raise ValueError(f"randomize[{key!r}]={rng!r}: must be (low, high)") from None
        if lo > hi:
            raise ValueError(f"randomize[{key!r}]={rng!r}: low must be <= high")
        out[key] = (lo, hi)
    return out


def sample_parameters(
    base: ParameterSet, ranges: Mapping[str, tuple[float, float]], rng: np.random.Generator
) -> tuple[ParameterSet, dict[str, float]]:
    """A randomised real parameter set and the factors drawn (keys of ``ranges``).

    Friction and preload go through :func:`~turntable_env.params.real_parameters`
    overrides, so the GMS elements, presliding distance and contact damping are
    re-derived (Hertz–Mindlin); the amplifier factor scales its slew rate per input
    volt and its current limit; ``sensor_noise`` is applied by the environment.
    """
    factors = {k: float(rng.uniform(*r)) for k, r in ranges.items()}
    u = base.unlisted
    assert u is not None
    over: dict[str, float] = {}
    if "friction" in factors:
        over["mu_static"] = u.mu_static * factors["friction"]
        over["mu_coulomb"] = u.mu_coulomb * factors["friction"]
    if "preload" in factors:
        over["normal_force"] = u.normal_force * factors["preload"]
    ps = real_parameters(overrides=over) if over else base
    if "amplifier" in factors:
        amp = ps.amplifier
        s = factors["amplifier"]
        ps = replace(
            ps,
            amplifier=replace(
                amp,
                slew_per_input_volt=amp.slew_per_input_volt * s,
                current_limit=amp.current_limit * s,
            ),
        )
    return ps, factors
