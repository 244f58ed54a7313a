"""An independent simulator of the piezo stick–slip turntable, for testing calibrators.

Written from the thesis's physics (chapters 2–4, Table D.1) and the measurement file
format only (:mod:`turntable_env.calibration.measurement`); it shares no model code with
the rest of the package. One rotation axis, SI units throughout.

Model (state per contact i = 1, 2; the third tube's contact lies on the axis):

* amplifier: input clip ±u_max, gain G, two real poles (τ₁ main loop, τ₂ output stage)
  and an output-rate limit min(SR, I_max/C_load) (slew rate and current into the
  quadrant + cable capacitance)::

      τ₁·ẏ₁ = G·clip(u) − y₁,   ẏ = clip((y₁ − y)/τ₂, ±min(SR, I_max/C))

* piezo: free contact displacement X_i = d_i·(V_h + Σ_k c_k·w_k) with V_h = y − h
  (h: Bouc–Wen hysteresis state, 0 when off) and Kelvin–Voigt creep states
  τ_k·ẇ_k = V_h − w_k (weights c_k = 0 when off);
* tube i: mass–spring–damper at the contact point (base frame)::

      m_t·ẍ_i = −k_t·(x_i − X_i) − c_t·(ẋ_i − Ẋ_i) − F_i − m_t·r_c·φ̈_b

* LuGre friction at each contact, relative velocity v_i = ẋ_i − r_c·θ̇::

      ż = v − σ₀·|v|·z/g(v),   g(v) = (F_N(t)/F_N)·a(v)·(F_c + (F_s − F_c)·exp(−(v/v_s)²))
      F_i = σ₀·z + σ₁·exp(−(v/v_d)²)·ż + σ₂·v

  (a(v) = 1 ± ε: friction asymmetry; σ₀ scales with (F_N(t)/F_N)^⅓, Hertz–Mindlin);
* table (relative to its base)::

      J·θ̈ = r_c·(F_1 + F_2) − k_g·θ − J·φ̈_b

* base rocking on its feet driven by floor acceleration a_f(t) (floor vibration)::

      φ̈_b + 2ζ_b·ω_b·φ̇_b + ω_b²·φ_b = −a_f(t)/ℓ_b

* mirror-mount mode ψ (mount resonance): ψ̈ + 2ζ_m·ω_m·ψ̇ + ω_m²·ψ = −κ·(θ̈ + φ̈_b);
* detector (Eq. 4.1 inverted): the beam sees Θ = θ + φ_b + ψ; V_x = L·tan(2Θ·cos γ)/S,
  V_y = L·tan(2Θ·sin γ)/S (γ: axis misalignment), optional smooth gain loss towards the
  range edge, offset + drift on V_x, Gaussian noise, clip at ±linear_range/S.

Integration: fixed sub-steps of at most ``max_step_s`` (0.25 µs) between the sample
times, drive linear within each sample interval. Mechanics by semi-implicit (symplectic)
Euler, the amplifier poles, creep elements and the LuGre bristle state by their exact
exponential update for a frozen input (stable at any step). The fastest mechanical mode
is a tube tip on its bending spring plus the stuck bristle, √((k_t+σ₀)/m_t) ≈ 2.2e5 rad/s
(35 kHz); 0.25 µs gives ω·h ≈ 0.055 (≈ 115 steps per period). The test suite checks that
halving the step changes the step size per period by < 1 %.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Literal

import numpy as np
from numba import njit

from ..kernel_cache import CACHE

__all__ = [
    "DEFAULT_STEP_S",
    "EFFECT_NAMES",
    "JUMP_WIDTH_S",
    "PROTOCOLS",
    "STATE_LAYOUT",
    "AxisMisalignment",
    "Burst",
    "Creep",
    "DetectorNonlinearity",
    "Effects",
    "FloorVibration",
    "FrictionAsymmetry",
    "Hold",
    "Hysteresis",
    "MountResonance",
    "PlantParams",
    "PreloadRelaxation",
    "Protocol",
    "Ramp",
    "SensorDrift",
    "SimulationResult",
    "SlowAmplifier",
    "adapted_hold_time",
    "build_drive",
    "rest_state",
    "simulate",
    "simulate_detailed",
    "simulate_from",
    "write_trace",
]

DEFAULT_STEP_S = 0.25e-6
JUMP_WIDTH_S = 1e-9  # a drive jump is two breakpoints this far apart
GRAVITY_M_PER_S2 = 9.81


# ---------------------------------------------------------------------------------------
# validation helpers
# ---------------------------------------------------------------------------------------
def _positive(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name}={value!r}: must be a finite number > 0")


def _nonnegative(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name}={value!r}: must be a finite number >= 0")


def _finite(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value)):
        raise ValueError(f"{name}={value!r}: must be a finite number")


def _in_range(name: str, value: float, lo: float, hi: float) -> None:
    _finite(name, value)
    if not lo <= value <= hi:
        raise ValueError(f"{name}={value!r}: must lie in [{lo:g}, {hi:g}]")


# ---------------------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlantParams:
    """Parameters of the one-axis turntable (SI units; derivations in the field notes).

    Table: a steel half sphere (ρ = 8000 kg/m³, R = 10 mm, Table D.1) has m = ⅔πR³ρ =
    16.8 g (Table D.1's 33.5 g is the full sphere) and J = ⅖·m·R² = 6.7e-7 kg m² about any
    axis through the sphere centre; with the mirror, J = 7.0e-7 kg m². The centre of mass
    sits 3R/8 below the centre (Eq. C.16); about a tube axis inclined by 35.26° the
    pendulum stiffness is m·g·(3R/8)·(1 − sin²35.26°) = 4.1e-4 N m/rad.

    Contacts: the tube axes are mutually orthogonal radii (tube_dist = √2·R_table, Eq.
    3.1), so the two driving contacts lie at R_table from the watched axis: contact arm
    r_c = 10 mm and Eq. 4.2's R_table/r_c lever is 1.

    Tube at the contact (PZT tube of Table D.1, E = 5.263e10 Pa, ball of radius R_o on
    top, contact R_o beyond the tube end): cantilever tip stiffness 3EI/L³ = 2.47e7 N/m,
    reduced by (1 + 3e/L + 3e²/L²) = 3.25 at e = R_o → 7.6e6 N/m; Rayleigh mass at the
    contact (tube 0.24·m_tube, ball mass and rotary inertia, shape factors of the static
    deflection) ≈ 2.3e-4 kg; damping ratio ≈ 3 % → c_t = 2.5 N s/m.

    Stroke: Eq. 2.11 halved (asymmetric mode) gives 1.18e-9 m/V at the tube end, the
    ball's lever doubles it at the contact (2.4e-9 m/V, 0.21 µm at 90 V). The rig stepped
    0.30–0.37 µm per period at 90 V, more than this small-signal figure; soft PZT's d31
    grows by about 2× at 180 V/mm, so d = 4.8e-9 m/V (0.43 µm free travel at 90 V). The
    second tube is 6 % weaker (manufacturing spread).

    Friction (steel on alumina, preload spring plus weight, 0.8 N per contact): μ_s =
    0.25, μ_c = 0.18; Hertz contact radius (R* = 2.4 mm, E* = 140 GPa) 22 µm, Mindlin
    tangential stiffness 8·G*·a = 5.2e6 N/m = σ₀ (pre-sliding range F_s/σ₀ ≈ 38 nm);
    σ₁ = 30 N s/m switched off above v_d = 1 mm/s (keeps LuGre dissipative); σ₂ = 0.5
    N s/m; Stribeck velocity 1 mm/s.

    Amplifier (HVA 900, §4.1.2): gain 45, input ±10 V, 25 mA. Two poles τ₁ = 39 µs,
    τ₂ = 4 µs give a peak slope of 0.9 V/µs for a 45 V step and 2.7 V/µs for 135 V (Fig.
    4.2: the slew rate is proportional to the jump); the output rate is capped at the
    12 V/µs slew spec and at I_max/C_load: two tube quadrants (ε₁₁·A_e/h = 1.33 nF each)
    plus ≈ 0.5 nF of cable = 3.2 nF → 7.8 V/µs, about the 8 V/µs the adapted signal
    reached.

    Detector: Eq. 4.1 with S = 9.9e-5 m/V, L = 0.175 m, linear range ±0.2 mm,
    R_table = 0.01 m (§4.1).
    """

    table_inertia_kg_m2: float = 7.0e-7
    gravity_stiffness_N_m_per_rad: float = 4.1e-4
    contact_arm_m: float = 0.010
    tube_mass_kg: float = 2.3e-4
    tube_stiffness_N_per_m: float = 7.6e6
    tube_damping_N_s_per_m: float = 2.5
    stroke_per_volt_m_per_V: float = 4.8e-9
    second_tube_stroke_ratio: float = 0.94
    normal_force_N: float = 0.8
    static_friction_coefficient: float = 0.25
    coulomb_friction_coefficient: float = 0.18
    stribeck_velocity_m_per_s: float = 1.0e-3
    bristle_stiffness_N_per_m: float = 5.2e6
    bristle_damping_N_s_per_m: float = 30.0
    bristle_damping_cutoff_m_per_s: float = 1.0e-3
    viscous_friction_N_s_per_m: float = 0.5
    amplifier_gain: float = 45.0
    amplifier_input_limit_V: float = 10.0
    amplifier_main_pole_s: float = 39e-6
    amplifier_output_pole_s: float = 4e-6
    amplifier_slew_rate_V_per_s: float = 12e6
    amplifier_current_limit_A: float = 25e-3
    load_capacitance_F: float = 3.2e-9
    detector_sensitivity_m_per_V: float = 9.9e-5
    detector_distance_m: float = 0.175
    detector_linear_range_m: float = 0.2e-3
    table_radius_m: float = 0.010

    def __post_init__(self) -> None:
        for f in fields(self):
            _positive(f.name, getattr(self, f.name))
        _in_range("second_tube_stroke_ratio", self.second_tube_stroke_ratio, 0.5, 1.5)
        if self.coulomb_friction_coefficient > self.static_friction_coefficient:
            raise ValueError(
                f"coulomb_friction_coefficient={self.coulomb_friction_coefficient!r}: must "
                f"not exceed static_friction_coefficient={self.static_friction_coefficient!r}"
            )
        if self.amplifier_output_pole_s >= self.amplifier_main_pole_s:
            raise ValueError(
                f"amplifier_output_pole_s={self.amplifier_output_pole_s!r}: must be shorter "
                f"than amplifier_main_pole_s={self.amplifier_main_pole_s!r}"
            )

    # derived -------------------------------------------------------------------------
    @property
    def output_rate_limit_V_per_s(self) -> float:
        """min(slew rate, I_max/C_load) [V/s]."""
        return min(
            self.amplifier_slew_rate_V_per_s,
            self.amplifier_current_limit_A / self.load_capacitance_F,
        )

    @property
    def lever(self) -> float:
        """Eq. 4.2 displacement per contact displacement, R_table/r_c [-]."""
        return self.table_radius_m / self.contact_arm_m

    @property
    def saturation_voltage_V(self) -> float:
        """Detector output at the edge of its linear range [V]."""
        return self.detector_linear_range_m / self.detector_sensitivity_m_per_V

    def free_stroke_m(self, input_V: float) -> float:
        """Mean quasi-static free travel of the two contacts for an amplifier input [m]."""
        return (
            self.stroke_per_volt_m_per_V
            * 0.5
            * (1.0 + self.second_tube_stroke_ratio)
            * self.amplifier_gain
            * input_V
        )

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


# ---------------------------------------------------------------------------------------
# effects
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Creep:
    """Logarithmic-type piezo creep: a Kelvin–Voigt chain of first-order lags τ_k·ẇ_k =
    V_h − w_k, log-spaced (``per_decade`` per decade) from ``shortest_time_s`` to
    ``longest_time_s``, each weighted fraction_per_decade/per_decade; the strain grows by
    about ``fraction_per_decade`` of the instantaneous stroke per decade of time."""

    fraction_per_decade: float = 0.03
    shortest_time_s: float = 1e-3
    longest_time_s: float = 10.0
    per_decade: int = 2

    def __post_init__(self) -> None:
        _in_range("fraction_per_decade", self.fraction_per_decade, 0.0, 0.5)
        _positive("shortest_time_s", self.shortest_time_s)
        _positive("longest_time_s", self.longest_time_s)
        if self.longest_time_s < self.shortest_time_s:
            raise ValueError(f"longest_time_s={self.longest_time_s!r}: must be >= shortest_time_s")
        if not (isinstance(self.per_decade, int) and 1 <= self.per_decade <= 10):
            raise ValueError(f"per_decade={self.per_decade!r}: must be an integer in 1…10")

    def elements(self) -> tuple[np.ndarray, np.ndarray]:
        """(time constants [s], weights [-])."""
        decades = math.log10(self.longest_time_s / self.shortest_time_s)
        n = max(1, round(decades * self.per_decade) + 1)
        tau = np.geomspace(self.shortest_time_s, self.longest_time_s, n)
        w = np.full(n, self.fraction_per_decade / self.per_decade)
        return tau, w


@dataclass(frozen=True)
class Hysteresis:
    """Bouc–Wen hysteresis of the piezo (rate-independent, n = 1) on the quadrant voltage
    V [V]: ḣ = α·V̇ − β·|V̇|·h − γ·V̇·|h|; the strain follows V − h. The defaults open a
    loop of about 10 % of the stroke for 0 → 90 V → 0."""

    alpha: float = 0.2
    beta_per_V: float = 0.012
    gamma_per_V: float = 0.004

    def __post_init__(self) -> None:
        _in_range("alpha", self.alpha, 0.0, 0.9)
        _nonnegative("beta_per_V", self.beta_per_V)
        _finite("gamma_per_V", self.gamma_per_V)
        if self.beta_per_V + self.gamma_per_V <= 0.0:
            raise ValueError(
                f"beta_per_V + gamma_per_V = {self.beta_per_V + self.gamma_per_V!r}: must be > 0"
            )


@dataclass(frozen=True)
class FloorVibration:
    """Floor acceleration a_f(t) = Σ A_j·sin(2π·f_j·t + p_j) [m/s²] rocking the turntable's
    base on its feet (mode ``base_frequency_Hz``, ``base_damping_ratio``, equivalent
    pendulum length ℓ_b = J_base/(m_base·h_base) [m]); the table rides on the base (and
    feels its angular acceleration as an inertial torque), the laser and detector stand
    on the floor."""

    amplitudes_m_per_s2: tuple[float, ...] = (4e-3, 3e-3)
    frequencies_Hz: tuple[float, ...] = (23.0, 50.0)
    phases_rad: tuple[float, ...] = (0.3, 1.9)
    base_frequency_Hz: float = 31.0
    base_damping_ratio: float = 0.06
    equivalent_length_m: float = 0.05

    def __post_init__(self) -> None:
        n = len(self.amplitudes_m_per_s2)
        if n == 0 or len(self.frequencies_Hz) != n or len(self.phases_rad) != n:
            raise ValueError(
                f"amplitudes_m_per_s2/frequencies_Hz/phases_rad lengths "
                f"{n}/{len(self.frequencies_Hz)}/{len(self.phases_rad)}: must be equal, >= 1"
            )
        for a in self.amplitudes_m_per_s2:
            _nonnegative("amplitudes_m_per_s2", a)
        for f in self.frequencies_Hz:
            _positive("frequencies_Hz", f)
        for p in self.phases_rad:
            _finite("phases_rad", p)
        _positive("base_frequency_Hz", self.base_frequency_Hz)
        _in_range("base_damping_ratio", self.base_damping_ratio, 1e-4, 2.0)
        _positive("equivalent_length_m", self.equivalent_length_m)


@dataclass(frozen=True)
class FrictionAsymmetry:
    """Friction levels (F_s, F_c) times 1 + ``asymmetry`` for positive relative sliding
    velocity (tip faster than table in +θ) and 1 − ``asymmetry`` for negative."""

    asymmetry: float = 0.1

    def __post_init__(self) -> None:
        _in_range("asymmetry", self.asymmetry, -0.9, 0.9)


@dataclass(frozen=True)
class SlowAmplifier:
    """A slower amplifier: both poles lengthened by 1/``bandwidth_factor`` and the output
    rate limit scaled by ``rate_limit_factor``."""

    bandwidth_factor: float = 0.5
    rate_limit_factor: float = 0.5

    def __post_init__(self) -> None:
        _in_range("bandwidth_factor", self.bandwidth_factor, 0.01, 1.0)
        _in_range("rate_limit_factor", self.rate_limit_factor, 0.01, 1.0)


@dataclass(frozen=True)
class SensorDrift:
    """Photodiode offset [V] plus a linear drift [V/s] on the watched channel."""

    offset_V: float = 4e-3
    rate_V_per_s: float = 6e-3

    def __post_init__(self) -> None:
        _in_range("offset_V", self.offset_V, -1.0, 1.0)
        _in_range("rate_V_per_s", self.rate_V_per_s, -1.0, 1.0)


@dataclass(frozen=True)
class DetectorNonlinearity:
    """Smooth gain loss towards the range edge: V → V·(1 − κ·(V/V_sat)²), κ =
    ``edge_gain_loss`` (gain 1 at the centre, 1 − κ at the edge)."""

    edge_gain_loss: float = 0.1

    def __post_init__(self) -> None:
        _in_range("edge_gain_loss", self.edge_gain_loss, 0.0, 0.3)


@dataclass(frozen=True)
class AxisMisalignment:
    """The rotation axis is tilted by ``angle_rad`` from the detector's x axis: the x
    channel sees Θ·cos γ, the y channel Θ·sin γ."""

    angle_rad: float = 0.05

    def __post_init__(self) -> None:
        _in_range("angle_rad", self.angle_rad, -0.5 * math.pi, 0.5 * math.pi)


@dataclass(frozen=True)
class PreloadRelaxation:
    """The preload spring relaxes: F_N(t) = F_N·(1 − δ·(1 − exp(−t/τ))) with δ =
    ``fraction`` and τ = ``time_constant_s``; friction levels follow F_N, the bristle
    stiffness follows F_N^⅓ (Hertz–Mindlin)."""

    fraction: float = 0.35
    time_constant_s: float = 0.5

    def __post_init__(self) -> None:
        _in_range("fraction", self.fraction, 0.0, 0.9)
        _positive("time_constant_s", self.time_constant_s)


@dataclass(frozen=True)
class MountResonance:
    """The mirror sits on a compliant mount: a rotational mode ψ (``frequency_Hz``,
    ``damping_ratio``) excited by the table's angular acceleration times ``coupling``
    (1 for a mount whose own inertia is all in the mirror); the beam sees θ + ψ."""

    frequency_Hz: float = 380.0
    damping_ratio: float = 0.03
    coupling: float = 0.5

    def __post_init__(self) -> None:
        _positive("frequency_Hz", self.frequency_Hz)
        _in_range("damping_ratio", self.damping_ratio, 1e-4, 2.0)
        _in_range("coupling", self.coupling, 0.0, 10.0)


EFFECT_NAMES = (
    "creep",
    "hysteresis",
    "floor_vibration",
    "friction_asymmetry",
    "slow_amplifier",
    "sensor_drift",
    "detector_nonlinearity",
    "axis_misalignment",
    "preload_relaxation",
    "mount_resonance",
)
_EFFECT_TYPES = {
    "creep": Creep,
    "hysteresis": Hysteresis,
    "floor_vibration": FloorVibration,
    "friction_asymmetry": FrictionAsymmetry,
    "slow_amplifier": SlowAmplifier,
    "sensor_drift": SensorDrift,
    "detector_nonlinearity": DetectorNonlinearity,
    "axis_misalignment": AxisMisalignment,
    "preload_relaxation": PreloadRelaxation,
    "mount_resonance": MountResonance,
}


@dataclass(frozen=True)
class Effects:
    """Switchable effects; ``None`` = off. :meth:`with_defaults` switches some on."""

    creep: Creep | None = None
    hysteresis: Hysteresis | None = None
    floor_vibration: FloorVibration | None = None
    friction_asymmetry: FrictionAsymmetry | None = None
    slow_amplifier: SlowAmplifier | None = None
    sensor_drift: SensorDrift | None = None
    detector_nonlinearity: DetectorNonlinearity | None = None
    axis_misalignment: AxisMisalignment | None = None
    preload_relaxation: PreloadRelaxation | None = None
    mount_resonance: MountResonance | None = None

    def __post_init__(self) -> None:
        for name, typ in _EFFECT_TYPES.items():
            v = getattr(self, name)
            if v is not None and not isinstance(v, typ):
                raise ValueError(f"{name}={v!r}: must be None or a {typ.__name__}")

    @classmethod
    def with_defaults(cls, *names: str) -> Effects:
        """Effects with the named ones on at their default magnitudes."""
        for n in names:
            if n not in _EFFECT_TYPES:
                raise ValueError(f"effect name {n!r}: must be one of {', '.join(EFFECT_NAMES)}")
        return cls(**{n: _EFFECT_TYPES[n]() for n in names})

    def active(self) -> tuple[str, ...]:
        return tuple(n for n in EFFECT_NAMES if getattr(self, n) is not None)

    def to_dict(self) -> dict[str, dict[str, object]]:
        """Active effects → their parameters (JSON-ready)."""
        out: dict[str, dict[str, object]] = {}
        for n in self.active():
            d = asdict(getattr(self, n))
            out[n] = {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}
        return out


# ---------------------------------------------------------------------------------------
# compiled kernels
# ---------------------------------------------------------------------------------------
# mech: J, k_g, r_c, m_t, k_t, c_t, d1, d2, F_N, mu_s, mu_c, v_s, sigma0, sigma1, v_d, sigma2
# amp:  gain, input limit, tau1, tau2, rate limit
@njit(cache=CACHE)
def _amp_step(u, y1, y, amp, h):
    uc = min(max(u, -amp[1]), amp[1])
    r = amp[0] * uc
    y1 = r + (y1 - r) * math.exp(-h / amp[2])
    dy = (y1 - y) * (1.0 - math.exp(-h / amp[3]))
    lim = amp[4] * h
    if dy > lim:
        dy = lim
    elif dy < -lim:
        dy = -lim
    return y1, y + dy


@njit(cache=CACHE)
def _amp_crossing(amplitude, t_ramp, overshoot, amp, h, t_max):
    """Time after the flyback jump (input +A → −k·A, after a ramp 0 → A over t_ramp from
    rest) at which the amplifier output crosses 0; −1 if not within t_max."""
    y1 = 0.0
    y = 0.0
    n = math.ceil(t_ramp / h)
    hh = t_ramp / n
    for i in range(n):
        y1, y = _amp_step(amplitude * (i + 1) / n, y1, y, amp, hh)
    target = -overshoot * amplitude
    t = 0.0
    while t < t_max:
        y_old = y
        y1, y = _amp_step(target, y1, y, amp, h)
        t += h
        if (amplitude > 0.0 and y <= 0.0) or (amplitude < 0.0 and y >= 0.0):
            return t - h * y / (y - y_old)
    return -1.0


@njit(cache=CACHE)
def _integrate(
    t,
    u,
    mech,
    amp,
    creep_tau,
    creep_w,
    hyst,
    vib_a,
    vib_f,
    vib_p,
    base,
    mirror,
    preload,
    asym,
    h_max,
    state,
    out,
):
    J = mech[0]
    kg = mech[1]
    rc = mech[2]
    mt = mech[3]
    kt = mech[4]
    ct = mech[5]
    fn0 = mech[8]
    fs0 = mech[9] * fn0
    fc0 = mech[10] * fn0
    vs = mech[11]
    s0n = mech[12]
    s1 = mech[13]
    vd = mech[14]
    s2 = mech[15]
    d = np.empty(2)
    d[0] = mech[6]
    d[1] = mech[7]
    nc = creep_tau.shape[0]
    nv = vib_a.shape[0]
    vib_on = base[2] > 0.0
    mir_on = mirror[2] > 0.0
    pre_on = preload[0] > 0.0
    hyst_on = hyst[0] != 0.0 or hyst[1] != 0.0 or hyst[2] != 0.0

    # the state (STATE_LAYOUT): resumed where the last call left it
    y, y1, hb, th, om = state[0], state[1], state[2], state[3], state[4]
    pb, qb, ps, qs, work = state[5], state[6], state[7], state[8], state[9]
    x = state[10:12].copy()
    vx = state[12:14].copy()
    xf = state[14:16].copy()
    z = state[16:18].copy()
    w = state[18 : 18 + nc].copy()
    dec = np.empty(nc)
    xf_new = np.empty(2)
    force = np.empty(2)

    n = t.shape[0]
    for j in range(n):
        if j > 0:
            dt = t[j] - t[j - 1]
            ns = math.ceil(dt / h_max - 1e-9)
            if ns < 1:
                ns = 1
            h = dt / ns
            for k in range(nc):
                dec[k] = 1.0 - math.exp(-h / creep_tau[k])
            u0 = u[j - 1]
            du = u[j] - u0
            for s in range(ns):
                frac = (s + 1.0) / ns
                ts = t[j - 1] + frac * dt
                # amplifier
                y_old = y
                y1, y = _amp_step(u0 + frac * du, y1, y, amp, h)
                # piezo: hysteresis, creep
                if hyst_on:
                    dv = y - y_old
                    hb += hyst[0] * dv - hyst[1] * abs(dv) * hb - hyst[2] * dv * abs(hb)
                vh = y - hb
                cs = 0.0
                for k in range(nc):
                    w[k] += (vh - w[k]) * dec[k]
                    cs += creep_w[k] * w[k]
                for i in range(2):
                    xf_new[i] = d[i] * (vh + cs)
                # preload
                fnf = 1.0
                if pre_on:
                    fnf = 1.0 - preload[0] * (1.0 - math.exp(-ts / preload[1]))
                s0 = s0n * fnf ** (1.0 / 3.0)
                # base rocking
                ab = 0.0
                if vib_on:
                    af = 0.0
                    for m in range(nv):
                        af += vib_a[m] * math.sin(2.0 * math.pi * vib_f[m] * ts + vib_p[m])
                    qb_new = qb + h * (
                        -2.0 * base[1] * base[0] * qb - base[0] * base[0] * pb - af * base[2]
                    )
                    ab = (qb_new - qb) / h
                    qb = qb_new
                    pb += h * qb
                # friction (LuGre) with the old velocities
                for i in range(2):
                    v = vx[i] - rc * om
                    av = abs(v)
                    if av > 0.0:
                        g = fc0 + (fs0 - fc0) * math.exp(-((v / vs) ** 2))
                        if v > 0.0:
                            g *= 1.0 + asym[0]
                        else:
                            g *= 1.0 - asym[0]
                        g *= fnf
                        zss = g / s0
                        if v < 0.0:
                            zss = -zss
                        znew = zss + (z[i] - zss) * math.exp(-s0 * av * h / g)
                    else:
                        znew = z[i]
                    zd = (znew - z[i]) / h
                    z[i] = znew
                    force[i] = s0 * znew + s1 * math.exp(-((v / vd) ** 2)) * zd + s2 * v
                # tubes
                for i in range(2):
                    xfd = (xf_new[i] - xf[i]) / h
                    fa = kt * (xf_new[i] - x[i]) + ct * (xfd - vx[i])
                    work += fa * (xf_new[i] - xf[i])
                    vx[i] += h * ((fa - force[i]) / mt - rc * ab)
                    xf[i] = xf_new[i]
                # table
                acc = (rc * (force[0] + force[1]) - kg * th) / J - ab
                om += h * acc
                th += h * om
                for i in range(2):
                    x[i] += h * vx[i]
                # mirror mount
                if mir_on:
                    qs += h * (
                        -2.0 * mirror[1] * mirror[0] * qs
                        - mirror[0] * mirror[0] * ps
                        - mirror[2] * (acc + ab)
                    )
                    ps += h * qs
        e = 0.5 * J * om * om + 0.5 * kg * th * th
        for i in range(2):
            e += 0.5 * mt * vx[i] * vx[i] + 0.5 * kt * (x[i] - xf[i]) ** 2
            e += 0.5 * s0n * z[i] * z[i]
        out[j, 0] = th
        out[j, 1] = th + pb + ps
        out[j, 2] = work
        out[j, 3] = e
        out[j, 4] = y
    state[0], state[1], state[2], state[3], state[4] = y, y1, hb, th, om
    state[5], state[6], state[7], state[8], state[9] = pb, qb, ps, qs, work
    state[10:12] = x
    state[12:14] = vx
    state[14:16] = xf
    state[16:18] = z
    state[18 : 18 + nc] = w
    return out


STATE_LAYOUT = (
    "amplifier output y [V]", "amplifier main-loop y1 [V]", "hysteresis h [V]",
    "table angle θ [rad]", "table rate [rad/s]", "base angle [rad]", "base rate [rad/s]",
    "mirror angle [rad]", "mirror rate [rad/s]", "drive work [J]",
    "tube contacts x (2) [m]", "their velocities (2) [m/s]", "free strokes X (2) [m]",
    "bristles z (2) [m]", "creep states w (n) [V]",
)  # fmt: skip


def rest_state(
    params: PlantParams, effects: Effects | None = None, input_V: float = 0.0,
    angle_rad: float = 0.0,
) -> np.ndarray:
    """The integrator state (:data:`STATE_LAYOUT`) at rest: the amplifier settled on the input
    ``input_V`` [V], every creep element and the tubes in equilibrium with it, the table at
    ``angle_rad`` [rad] held by the bristles against the pendulum torque (k_g·θ shared by the
    two contacts, r_c·σ₀·(z₁ + z₂) = k_g·θ, each tube bent back by its contact force).
    Raises ValueError if that torque exceeds the contacts' static friction."""
    eff = Effects() if effects is None else effects
    _finite("input_V", input_V)
    _finite("angle_rad", angle_rad)
    p = params
    amp = _amp_array(p, eff)
    creep_w = eff.creep.elements()[1] if eff.creep is not None else np.zeros(0)
    y = amp[0] * min(max(input_V, -amp[1]), amp[1])
    vh = y
    cs = 0.0
    for wk in creep_w:  # in the integrator's order (bit for bit)
        cs += wk * vh
    d = np.array([1.0, p.second_tube_stroke_ratio]) * p.stroke_per_volt_m_per_V
    xf = d * (vh + cs)
    force = p.gravity_stiffness_N_m_per_rad * angle_rad / (2.0 * p.contact_arm_m)  # N each
    if abs(force) >= p.static_friction_coefficient * p.normal_force_N:
        raise ValueError(f"angle_rad={angle_rad!r}: friction cannot hold the table there")
    z = np.full(2, force / p.bristle_stiffness_N_per_m)
    x = xf - force / p.tube_stiffness_N_per_m
    st = np.zeros(18 + creep_w.size)
    st[0] = st[1] = y
    st[3] = angle_rad
    st[10:12], st[14:16], st[16:18] = x, xf, z
    st[18:] = vh
    return st


def simulate_from(
    params: PlantParams, state: np.ndarray, time: np.ndarray, drive: np.ndarray,
    effects: Effects | None = None, *, max_step_s: float = DEFAULT_STEP_S,
) -> np.ndarray:
    """Continue from ``state`` (:func:`rest_state` or an earlier call's; updated in place) at
    ``time[0]`` [s] under the amplifier input ``drive`` [V] (linear between the strictly
    increasing sample times); the table angle θ [rad] at every sample time."""
    t, u = _check_series(time, drive)
    eff = Effects() if effects is None else effects
    args = _kernel_arrays(params, eff)
    nc = args[2].size
    if state.shape != (18 + nc,) or state.dtype != np.float64:
        raise ValueError(f"state: need a float array of {18 + nc} (rest_state), got {state.shape}")
    out = np.empty((t.size, 5))
    _integrate(t, u, *args, float(max_step_s), state, out)
    return out[:, 0].copy()


# ---------------------------------------------------------------------------------------
# simulation
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Everything one run produces, at the sample times.

    theta_rad: table angle relative to its base; optical_angle_rad: the mirror angle the
    beam sees (θ + base rocking + mount mode); detector_x_V, detector_y_V; work_in_J:
    cumulative work done by the piezo actuators on the tubes; stored_energy_J: kinetic +
    elastic (tubes, bristles, pendulum) energy; amplifier_output_V.
    """

    time_s: np.ndarray
    theta_rad: np.ndarray
    optical_angle_rad: np.ndarray
    detector_x_V: np.ndarray
    detector_y_V: np.ndarray
    work_in_J: np.ndarray
    stored_energy_J: np.ndarray
    amplifier_output_V: np.ndarray


def _amp_array(params: PlantParams, effects: Effects) -> np.ndarray:
    tau1 = params.amplifier_main_pole_s
    tau2 = params.amplifier_output_pole_s
    rate = params.output_rate_limit_V_per_s
    if effects.slow_amplifier is not None:
        tau1 /= effects.slow_amplifier.bandwidth_factor
        tau2 /= effects.slow_amplifier.bandwidth_factor
        rate *= effects.slow_amplifier.rate_limit_factor
    return np.array(
        [params.amplifier_gain, params.amplifier_input_limit_V, tau1, tau2, rate], dtype=float
    )


def _check_series(time: np.ndarray, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # contiguous: a strided slice would compile the integrator a second time (numba types
    # array layouts apart)
    t = np.ascontiguousarray(time, dtype=float)
    u = np.ascontiguousarray(drive, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"time: shape {t.shape}, must be 1-D with >= 2 samples")
    if u.shape != t.shape:
        raise ValueError(f"drive: shape {u.shape}, must match time's {t.shape}")
    if not (np.isfinite(t).all() and np.isfinite(u).all()):
        raise ValueError("time/drive: must be finite")
    if (np.diff(t) <= 0.0).any():
        k = int(np.argmax(np.diff(t) <= 0.0))
        raise ValueError(f"time[{k + 1}]={t[k + 1]!r}: time must be strictly increasing")
    return t, u


def _kernel_arrays(params: PlantParams, eff: Effects) -> tuple[np.ndarray, ...]:
    """The compiled integrator's arrays: mech, amp, creep τ and weights, hysteresis, floor
    vibration (amplitudes, frequencies, phases, base), mirror mount, preload, asymmetry."""
    p = params
    mech = np.array(
        [
            p.table_inertia_kg_m2,
            p.gravity_stiffness_N_m_per_rad,
            p.contact_arm_m,
            p.tube_mass_kg,
            p.tube_stiffness_N_per_m,
            p.tube_damping_N_s_per_m,
            p.stroke_per_volt_m_per_V,
            p.stroke_per_volt_m_per_V * p.second_tube_stroke_ratio,
            p.normal_force_N,
            p.static_friction_coefficient,
            p.coulomb_friction_coefficient,
            p.stribeck_velocity_m_per_s,
            p.bristle_stiffness_N_per_m,
            p.bristle_damping_N_s_per_m,
            p.bristle_damping_cutoff_m_per_s,
            p.viscous_friction_N_s_per_m,
        ],
        dtype=float,
    )
    amp = _amp_array(p, eff)
    if eff.creep is not None:
        creep_tau, creep_w = eff.creep.elements()
    else:
        creep_tau, creep_w = np.ones(0), np.zeros(0)
    hy = eff.hysteresis
    hyst = np.array([hy.alpha, hy.beta_per_V, hy.gamma_per_V] if hy else [0.0, 0.0, 0.0])
    fv = eff.floor_vibration
    if fv is not None:
        vib_a = np.array(fv.amplitudes_m_per_s2, dtype=float)
        vib_f = np.array(fv.frequencies_Hz, dtype=float)
        vib_p = np.array(fv.phases_rad, dtype=float)
        base = np.array(
            [
                2 * math.pi * fv.base_frequency_Hz,
                fv.base_damping_ratio,
                1.0 / fv.equivalent_length_m,
            ]
        )
    else:
        vib_a = vib_f = vib_p = np.zeros(0)
        base = np.array([1.0, 1.0, 0.0])
    mr = eff.mount_resonance
    mirror = (
        np.array([2 * math.pi * mr.frequency_Hz, mr.damping_ratio, mr.coupling])
        if mr
        else np.array([1.0, 1.0, 0.0])
    )
    pr = eff.preload_relaxation
    preload = np.array([pr.fraction, pr.time_constant_s] if pr else [0.0, 1.0])
    asym = np.array([eff.friction_asymmetry.asymmetry if eff.friction_asymmetry else 0.0])
    return (mech, amp, creep_tau, creep_w, hyst, vib_a, vib_f, vib_p, base, mirror, preload,
            asym)  # fmt: skip


def simulate_detailed(
    params: PlantParams,
    time: np.ndarray,
    drive: np.ndarray,
    effects: Effects | None = None,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
    *,
    max_step_s: float = DEFAULT_STEP_S,
) -> SimulationResult:
    """Simulate the plant for an amplifier input ``drive`` [V] given at ``time`` [s]
    (strictly increasing; linear between samples); the state starts at rest in
    equilibrium with drive[0]. Returns every signal at the sample times."""
    t, u = _check_series(time, drive)
    if not isinstance(params, PlantParams):
        raise ValueError(f"params={params!r}: must be a PlantParams")
    eff = Effects() if effects is None else effects
    if not isinstance(eff, Effects):
        raise ValueError(f"effects={effects!r}: must be an Effects or None")
    _nonnegative("noise_std", noise_std)
    _positive("max_step_s", max_step_s)
    if max_step_s > 2e-6:
        raise ValueError(f"max_step_s={max_step_s!r}: must be <= 2e-6 s (contact dynamics)")
    p = params
    out = np.empty((t.size, 5))
    state = rest_state(p, eff, float(u[0]))
    _integrate(t, u, *_kernel_arrays(p, eff), float(max_step_s), state, out)
    vx, vy = _detector(p, eff, t, out[:, 1], noise_std, rng)
    return SimulationResult(
        time_s=t,
        theta_rad=out[:, 0].copy(),
        optical_angle_rad=out[:, 1].copy(),
        detector_x_V=vx,
        detector_y_V=vy,
        work_in_J=out[:, 2].copy(),
        stored_energy_J=out[:, 3].copy(),
        amplifier_output_V=out[:, 4].copy(),
    )


def _detector(
    p: PlantParams,
    eff: Effects,
    t: np.ndarray,
    angle: np.ndarray,
    noise_std: float,
    rng: np.random.Generator | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Photodiode outputs (x, y) [V] for the mirror angle [rad] (module docstring)."""
    gm = eff.axis_misalignment.angle_rad if eff.axis_misalignment else 0.0
    vsat = p.saturation_voltage_V
    chans = []
    for ang in (angle * math.cos(gm), angle * math.sin(gm)):
        if (np.abs(ang) >= 0.25 * math.pi).any():
            raise ValueError("mirror angle beyond ±π/4: the beam leaves the detector plane")
        v = p.detector_distance_m * np.tan(2.0 * ang) / p.detector_sensitivity_m_per_V
        if eff.detector_nonlinearity is not None:
            vc = np.clip(v, -vsat, vsat)
            v = vc * (1.0 - eff.detector_nonlinearity.edge_gain_loss * (vc / vsat) ** 2)
        chans.append(v)
    vx, vy = chans
    if eff.sensor_drift is not None:
        vx = vx + eff.sensor_drift.offset_V + eff.sensor_drift.rate_V_per_s * (t - t[0])
    if noise_std > 0.0:
        g = np.random.default_rng(0) if rng is None else rng
        vx = vx + g.normal(0.0, noise_std, vx.shape)
        vy = vy + g.normal(0.0, noise_std, vy.shape)
    return np.clip(vx, -vsat, vsat), np.clip(vy, -vsat, vsat)


def simulate(
    params: PlantParams,
    time: np.ndarray,
    drive: np.ndarray,
    effects: Effects | None = None,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
    *,
    max_step_s: float = DEFAULT_STEP_S,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(table angle θ [rad], detector x [V], detector y [V]) at the sample ``time`` [s]
    for the amplifier input ``drive`` [V] (linear between samples). ``noise_std`` [V]:
    Gaussian noise on both channels, drawn from ``rng`` (default: a generator seeded 0).
    """
    r = simulate_detailed(params, time, drive, effects, noise_std, rng, max_step_s=max_step_s)
    return r.theta_rad, r.detector_x_V, r.detector_y_V


# ---------------------------------------------------------------------------------------
# drives and protocols
# ---------------------------------------------------------------------------------------
Flyback = Literal["ramp", "step", "adapted"]


@dataclass(frozen=True)
class Hold:
    """Keep the current input level for ``duration_s`` [s]."""

    duration_s: float

    def __post_init__(self) -> None:
        _positive("duration_s", self.duration_s)


@dataclass(frozen=True)
class Ramp:
    """Scan ramp: the input goes linearly to ``target_V`` over ``duration_s``."""

    duration_s: float
    target_V: float

    def __post_init__(self) -> None:
        _positive("duration_s", self.duration_s)
        _in_range("target_V", self.target_V, -10.0, 10.0)


@dataclass(frozen=True)
class Burst:
    """Stepping burst from input level 0: ``periods`` sawtooth periods of amplitude
    ``amplitude_V`` (signed, amplifier input) at ``frequency_Hz``; the ramp rises over
    ramp_ratio/f, then the flyback: "ramp" falls back over (1 − a)/f, "step" jumps to 0,
    "adapted" (Fig. 4.3) jumps to −overshoot·A and holds until the amplifier's output
    crosses 0, then jumps to 0."""

    amplitude_V: float
    frequency_Hz: float
    periods: int
    ramp_ratio: float = 0.95
    flyback: Flyback = "adapted"
    overshoot: float = 1.0

    def __post_init__(self) -> None:
        _in_range("amplitude_V", self.amplitude_V, -10.0, 10.0)
        if self.amplitude_V == 0.0:
            raise ValueError("amplitude_V=0.0: must be nonzero")
        _in_range("frequency_Hz", self.frequency_Hz, 0.1, 20e3)
        if not (isinstance(self.periods, int) and self.periods >= 1):
            raise ValueError(f"periods={self.periods!r}: must be an integer >= 1")
        _in_range("ramp_ratio", self.ramp_ratio, 0.5, 0.999)
        if self.flyback not in ("ramp", "step", "adapted"):
            raise ValueError(f"flyback={self.flyback!r}: must be 'ramp', 'step' or 'adapted'")
        _in_range("overshoot", self.overshoot, 0.1, 5.0)
        if abs(self.overshoot * self.amplitude_V) > 10.0:
            raise ValueError(
                f"overshoot={self.overshoot!r}: −overshoot·amplitude_V must stay within ±10 V"
            )


Segment = Hold | Ramp | Burst


@dataclass(frozen=True)
class Protocol:
    """A named sequence of drive segments, starting at input 0 V and t = 0."""

    name: str
    segments: tuple[Segment, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if not self.segments:
            raise ValueError(f"segments={self.segments!r}: must not be empty")
        for s in self.segments:
            if not isinstance(s, Hold | Ramp | Burst):
                raise ValueError(f"segments: {s!r} is not a Hold, Ramp or Burst")

    @property
    def duration_s(self) -> float:
        return sum(
            s.periods / s.frequency_Hz if isinstance(s, Burst) else s.duration_s
            for s in self.segments
        )


def adapted_hold_time(
    params: PlantParams,
    amplitude_V: float,
    frequency_Hz: float,
    ramp_ratio: float,
    overshoot: float = 1.0,
) -> float:
    """How long the adapted flyback holds −overshoot·A: until the amplifier output
    (started at rest, after one ramp) crosses 0 [s]."""
    amp = _amp_array(params, Effects())
    t_max = (1.0 - ramp_ratio) / frequency_Hz
    th = float(
        _amp_crossing(
            float(amplitude_V), ramp_ratio / frequency_Hz, float(overshoot), amp, 1e-8, t_max
        )
    )
    if th < 0.0:
        raise ValueError(
            f"ramp_ratio={ramp_ratio!r} at frequency_Hz={frequency_Hz!r}: the amplifier "
            f"output does not reach 0 within the flyback time {t_max:.3g} s"
        )
    return th


class _Builder:
    def __init__(self) -> None:
        self.t = [0.0]
        self.u = [0.0]

    def line_to(self, t: float, u: float) -> None:
        if t <= self.t[-1] + 0.5 * JUMP_WIDTH_S:
            if u != self.u[-1]:
                raise ValueError(f"drive breakpoint at t={t!r} s collides with the previous")
            return
        self.t.append(t)
        self.u.append(u)

    def jump_to(self, u: float) -> None:
        self.t.append(self.t[-1] + JUMP_WIDTH_S)
        self.u.append(u)


def build_drive(
    protocol: Protocol | str, params: PlantParams | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints (time [s], amplifier input [V]) of a protocol; the drive is linear
    between them, a jump is two breakpoints ``JUMP_WIDTH_S`` apart. Adapted flybacks are
    timed with the nominal amplifier of ``params`` (as designed in the lab)."""
    proto = _protocol(protocol)
    p = PlantParams() if params is None else params
    b = _Builder()
    hold_cache: dict[tuple[float, float, float, float], float] = {}
    t0 = 0.0
    for seg in proto.segments:
        if isinstance(seg, Hold):
            t0 += seg.duration_s
            b.line_to(t0, b.u[-1])
        elif isinstance(seg, Ramp):
            t0 += seg.duration_s
            b.line_to(t0, seg.target_V)
        else:
            if b.u[-1] != 0.0:
                raise ValueError(
                    f"Burst {seg!r} must start at input 0 V (level is {b.u[-1]!r} V): "
                    "add a Ramp to 0 first"
                )
            a, f, amp_v = seg.ramp_ratio, seg.frequency_Hz, seg.amplitude_V
            hold = 0.0
            if seg.flyback == "adapted":
                key = (amp_v, f, a, seg.overshoot)
                if key not in hold_cache:
                    hold_cache[key] = adapted_hold_time(p, amp_v, f, a, seg.overshoot)
                hold = hold_cache[key]
            for _ in range(seg.periods):
                b.line_to(t0 + a / f, amp_v)
                if seg.flyback == "ramp":
                    b.line_to(t0 + 1.0 / f, 0.0)
                elif seg.flyback == "step":
                    b.jump_to(0.0)
                    b.line_to(t0 + 1.0 / f, 0.0)
                else:
                    b.jump_to(-seg.overshoot * amp_v)
                    b.line_to(t0 + a / f + hold, -seg.overshoot * amp_v)
                    b.jump_to(0.0)
                    b.line_to(t0 + 1.0 / f, 0.0)
                t0 += 1.0 / f
    return np.array(b.t), np.array(b.u)


def _bursts_pair(amp: float, f: float, n: int, gap: float, **kw: object) -> tuple[Segment, ...]:
    return (
        Burst(amp, f, n, **kw),  # type: ignore[arg-type]
        Hold(gap),
        Burst(-amp, f, n, **kw),  # type: ignore[arg-type]
        Hold(gap),
    )


def _standard() -> Protocol:
    segs: tuple[Segment, ...] = (
        Hold(0.05),
        Ramp(0.12, 4.0),
        Hold(0.04),
        Ramp(0.24, -4.0),
        Hold(0.04),
        Ramp(0.12, 0.0),
        Hold(0.05),
        *_bursts_pair(2.0, 100.0, 8, 0.05),
        *_bursts_pair(3.0, 500.0, 6, 0.03),
        *_bursts_pair(5.0, 1000.0, 3, 0.03),
        Burst(2.0, 100.0, 5, flyback="ramp"),
        Hold(0.03),
        *_bursts_pair(2.0, 200.0, 5, 0.03, flyback="step"),
        *_bursts_pair(4.0, 300.0, 4, 0.03, overshoot=1.5),
        Hold(0.05),
    )
    return Protocol("standard", segs)


def _stepping_only() -> Protocol:
    segs: tuple[Segment, ...] = (
        Hold(0.01),
        *_bursts_pair(2.0, 100.0, 6, 0.01),
        *_bursts_pair(3.0, 400.0, 8, 0.005),
        *_bursts_pair(5.0, 1000.0, 4, 0.005),
        *_bursts_pair(2.5, 250.0, 6, 0.005, flyback="step"),
        Burst(2.0, 100.0, 4, flyback="ramp"),
        Hold(0.005),
        *_bursts_pair(4.0, 700.0, 5, 0.005),
        *_bursts_pair(2.0, 100.0, 6, 0.01),
    )
    return Protocol("stepping_only", segs)


def _long() -> Protocol:
    segs: tuple[Segment, ...] = (
        Hold(0.1),
        Ramp(0.2, 5.0),
        Hold(0.2),
        Ramp(0.1, 0.0),
        Hold(0.1),
        *_bursts_pair(2.0, 100.0, 10, 0.06),
        Ramp(0.05, -3.0),
        Hold(0.15),
        Ramp(0.3, 3.0),
        Ramp(0.05, 0.0),
        Hold(0.05),
        *_bursts_pair(3.0, 200.0, 6, 0.04),
        *_bursts_pair(5.0, 1000.0, 4, 0.03),
        *_bursts_pair(2.0, 100.0, 6, 0.04, flyback="step"),
        Burst(3.0, 100.0, 5, flyback="ramp"),
        Hold(0.04),
        *_bursts_pair(3.5, 500.0, 6, 0.03, overshoot=2.0),
        Hold(0.1),
    )
    return Protocol("long", segs)


PROTOCOLS: dict[str, Protocol] = {p.name: p for p in (_standard(), _stepping_only(), _long())}


def _protocol(protocol: Protocol | str) -> Protocol:
    if isinstance(protocol, Protocol):
        return protocol
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol={protocol!r}: must be a Protocol or one of {list(PROTOCOLS)}")
    return PROTOCOLS[protocol]


# ---------------------------------------------------------------------------------------
# measurement files
# ---------------------------------------------------------------------------------------
def _merge_times(grid: np.ndarray, bp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Union of the uniform grid and the breakpoints (breakpoints within 1e-12 s of a
    grid time replace it); returns (times, index of each grid sample in the union)."""
    idx = np.searchsorted(bp, grid)
    near = np.zeros(grid.size, dtype=bool)
    for off in (-1, 0):
        k = np.clip(idx + off, 0, bp.size - 1)
        near |= np.abs(bp[k] - grid) < 1e-12
    tu = np.concatenate([grid[~near], bp])
    order = np.argsort(tu, kind="stable")
    tu = tu[order]
    pos = np.searchsorted(tu, grid - 1e-12)
    return tu, pos


def write_trace(
    path: str | Path,
    params: PlantParams,
    protocol: Protocol | str,
    *,
    effects: Effects | None = None,
    axis: str = "B",
    sample_rate_Hz: float = 20e3,
    noise_std: float = 1e-3,
    drive_recording: Literal["breakpoints", "sampled"] = "breakpoints",
    daq_bits: int | None = None,
    seed: int = 0,
) -> Path:
    """Simulate ``protocol`` and write a measurement file (format of
    :mod:`turntable_env.calibration.measurement`).

    The detector is sampled at ``sample_rate_Hz`` on a uniform grid from t = 0 with
    Gaussian noise ``noise_std`` [V]. ``drive_recording``: "breakpoints" — the file holds
    every drive breakpoint as well, the detector linearly interpolated between its
    samples there; "sampled" — only the grid, the drive read at the grid times like a DAQ
    watching the function generator, quantised to ``daq_bits`` over ±10 V if given. The
    plant is always driven by the true (breakpoint) signal. The metadata holds only the
    format's required keys.
    """
    from ..calibration.measurement import AXES, Measurement
    from ..detector import Detector

    if axis not in AXES:
        raise ValueError(f"axis={axis!r}: must be one of {', '.join(AXES)}")
    _in_range("sample_rate_Hz", sample_rate_Hz, 100.0, 1e6)
    _nonnegative("noise_std", noise_std)
    if drive_recording not in ("breakpoints", "sampled"):
        raise ValueError(f"drive_recording={drive_recording!r}: must be 'breakpoints' or 'sampled'")
    if daq_bits is not None and not (isinstance(daq_bits, int) and 4 <= daq_bits <= 24):
        raise ValueError(f"daq_bits={daq_bits!r}: must be None or an integer in 4…24")
    if daq_bits is not None and drive_recording != "sampled":
        raise ValueError(f"daq_bits={daq_bits!r}: only with drive_recording='sampled'")
    tb, ub = build_drive(protocol, params)
    n = math.floor(tb[-1] * sample_rate_Hz + 1e-9) + 1
    grid = np.arange(n) / sample_rate_Hz
    tu, pos = _merge_times(grid, tb)
    uu = np.interp(tu, tb, ub)
    # exact breakpoint values (np.interp at a jump's first time is already the pre-jump one)
    r = simulate_detailed(params, tu, uu, effects, 0.0)
    rng = np.random.default_rng(seed)
    eff = Effects() if effects is None else effects
    vx, vy = _detector(params, eff, tu[pos], r.optical_angle_rad[pos], noise_std, rng)
    if drive_recording == "breakpoints":
        t_out = tu
        u_out = uu
        dx = np.interp(tu, tu[pos], vx)
        dy = np.interp(tu, tu[pos], vy)
    else:
        t_out = tu[pos]
        u_out = np.interp(t_out, tb, ub)
        if daq_bits is not None:
            lsb = 20.0 / 2**daq_bits
            u_out = np.clip(np.round(u_out / lsb), -(2 ** (daq_bits - 1)), 2 ** (daq_bits - 1) - 1)
            u_out = u_out * lsb
        dx, dy = vx, vy
    det = Detector(
        sensitivity=params.detector_sensitivity_m_per_V,
        distance=params.detector_distance_m,
        table_radius=params.table_radius_m,
    )
    m = Measurement(
        axis=axis,
        amplifier_gain=params.amplifier_gain,
        detector=det,
        time=t_out,
        drives={axis: u_out},
        detector_v=dx,
        detector_y_v=dy,
    )
    return m.save(path)
