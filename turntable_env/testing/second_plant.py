"""A second, independent test plant: elasto-plastic contacts, two table modes, a slewing amplifier.

This module simulates measurement files of the piezo stick–slip turntable from the thesis
(Schepers, *Modeling a Piezoelectric Inertial Stepping Turntable Using Bond Graphs*) with a
formulation the package's calibrator was not built from. It shares no model code with the
rest of the package: it uses only the measurement file writer
(:class:`~turntable_env.calibration.measurement.Measurement`), the
:class:`~turntable_env.detector.Detector` record it holds, and the kernel cache directory.

Model (one rotation axis, SI units throughout)
------------------------------------------------
*Amplifier* (HVA 900, thesis §4.1.1–4.1.2). Input ``u`` [V] (±10 V), gain ``G`` = 45. The
small-signal response is second order, ``ÿ = ω_a²(G·u − y) − 2ζ_a·ω_a·ẏ``, with ``ω_a``
chosen so that the steepest slope of a step response is ``r_a·ΔV``; Fig. 4.2 gives
2.7 V/µs for a 135 V step, ``r_a`` = 2.0e4 1/s (the time to the end value does not depend
on the step height). The output rate is limited to the data-sheet slew rate 12 V/µs and the
output to ±``G``·10 V.

*Piezo tube* (Eqs. 2.10–2.12, Appendix B, C, Table D.1). In the asymmetric mode the tube
bends with curvature ``1/R_bending = 2√2·|d31|·V/(π·D·h)`` (Eq. 2.12) with ``D`` the mean
diameter ``R_o + R_i`` (this reproduces Table D.1's ``R_bending`` = 1.570e4 m at 1 V). The
contact point on the alumina ball sits ``ℓ = R_o + √(R_o² − R_i²)`` above the tube end (a
ball of radius ``R_o`` seated on the bore), so its free stroke is
``s = (L/R_bending)·(L/2 + ℓ)`` [m/V], Eq. 2.11 plus the tip slope times ``ℓ``. The
tube's bending stiffness at that point is ``E·I_x/(L³/3 + L²ℓ + Lℓ²)`` (Eq. B.6 for a load
above the free end); its tip carries the ball plus 33/140 of the tube mass (Eq. C.2).

*Contacts* (Eqs. 2.13, 2.14, 2.21, 2.22). Each driven tube touches the sphere at lever
``R_c`` from the axis: ``R_table`` for the tube axes A, B, C (the contact points lie on
three orthogonal radii, Eq. 3.1) with the two tubes off the axis driven; ``R_contact =
R_table·√(2/3)`` for Z with all three tubes driven. The contact on the watched axis
carries no torque (spin is not a friction input, §3.3.2). Friction at a contact is the
elasto-plastic model of Dupont et al. (thesis ref. [9], Eqs. 2.21–2.22):
``ż = v − α(z, v)·|v|·z/z_ss(v)``, ``F = σ0·z + σ1·ż + σ2·v`` with ``v`` the velocity of
the tube tip relative to the table surface, ``z_ss(v) = s(v)/σ0``, the Stribeck curve
``s(v) = F_c + (F_s − F_c)·exp(−|v/v_s|^δ)`` (Eq. 2.13), ``F_s = μ_s·F_N``,
``F_c = μ_c·F_N`` (Eq. 2.14) and ``α`` the sine blend of Eq. 2.22 between the break-away
deflection ``z_ba`` and ``z_ss`` (with ``|z|``, as in Dupont's paper). The normal force per
contact is ``F_N = κ·m_table·g``; ``κ`` = 100 N / (15 kg · g) is the ratio of normal force
to table weight of the thesis's simulation (Table D.2). The real preload is not given.

*Table* (Appendix C): a half sphere, ``I = 2/5·m·R²`` (Eq. C.8). Mode 1 is the table's
rotation on the series compliance of the contacts and the tubes (≈2.5 kHz for the default
``σ0``); mode 2 is a rocking mode of the mirror on its mount, a spring–damper between the
table and the mirror with its own frequency (9.5 kHz) and damping; the mirror's angle is
what the detector sees.

*Detector* (Eq. 4.1, §4.1.3): spot travel ``x = L·tan(2φ)``, output ``x/S`` with
S = 9.9e-5 m/V, L = 0.175 m, Gaussian noise on both channels, clipped at the linear range
±0.2 mm/S.

Integration
-----------
Fixed step ``h`` (1 µs) with semi-implicit (symplectic) Euler for the mechanics and the
amplifier: forces from the old positions, then velocities, then positions. It is stable for
``ω·h < 2`` for every undamped mode and ``c·h/m < 2`` for every damper; the stiffest pair is
the tube tip (mass ≈0.64 g) on the tube plus the contact (≈5.8e6 N/m), ω ≈ 9.5e4 rad/s
(15 kHz), so ``ω·h`` ≈ 0.1 and the tip resonance gets ≈66 steps a period;
``σ1·h/m_tip`` ≈ 0.013 and ``ω_a·h`` ≈ 0.04. Halving ``h`` changes the step per period
by < 0.3 % (tests). The bristle state is advanced by the exact solution of its linear ODE for
the step's frozen ``v`` and ``α`` (an exponential approach to ``±z_ss/α``), which is stable
for any step, however fast the slip. Steps end exactly on every output time; the drive is
the piecewise-linear generator evaluated at each step.

Effects (each off by default; :class:`Effects`)
-----------------------------------------------
``creep`` (piezo strain, multi-time-constant logarithmic creep), ``hysteresis`` (piezo,
Prandtl–Ishlinskii play operators), ``floor_vibration`` (tube mounts shaken tangentially),
``friction_asymmetry`` (friction higher for negative relative sliding), ``slow_amplifier``
(lower slew limit and bandwidth), ``sensor_drift`` (detector offset ramp),
``detector_nonlinearity`` (gain falling off to the edge), ``axis_misalignment`` (detector
axes rotated: the motion leaks into ``detector_y_V``), and three outside that catalogue:
``mains_pickup`` (50 Hz on the amplifier input, not in the recorded drive),
``contact_wear`` (friction falls with the accumulated sliding distance, §4.3) and
``mirror_play`` (play between the table and the mirror mount).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from ..calibration.measurement import Measurement
from ..detector import Detector
from ..kernel_cache import CACHE

__all__ = [
    "AXES",
    "EFFECT_NAMES",
    "FLYBACK_S",
    "PROTOCOLS",
    "AxisMisalignment",
    "Burst",
    "ContactWear",
    "Creep",
    "DetectorNonlinearity",
    "Effects",
    "FloorVibration",
    "FrictionAsymmetry",
    "Hold",
    "Hysteresis",
    "MainsPickup",
    "MirrorPlay",
    "PlantParams",
    "Protocol",
    "Ramp",
    "Scan",
    "SensorDrift",
    "SimResult",
    "SlowAmplifier",
    "build_drive",
    "detector_outputs",
    "drive_at",
    "params_truth",
    "simulate",
    "step_per_period",
    "write_trace",
]

GRAVITY_M_PER_S2 = 9.81
INPUT_LIMIT_V = 10.0  # amplifier input range, §4.1.1
AXES = ("A", "B", "C", "Z")


def _bad(name: str, value: Any, why: str) -> ValueError:
    return ValueError(f"{name}={value!r}: {why}")


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
        raise _bad(name, value, "must be a finite number > 0")


def _nonnegative(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
        raise _bad(name, value, "must be a finite number ≥ 0")


def _within(name: str, value: float, lo: float, hi: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
        raise _bad(name, value, f"must lie in [{lo:g}, {hi:g}]")


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class PlantParams:
    """Physical parameters of the plant (SI units; sources in brackets).

    Table and tube dimensions, densities, ``E`` and ``d31`` are Table D.1; friction
    coefficients and the Stribeck exponent Table D.2; amplifier §4.1.1–4.1.2 and Fig. 4.2;
    detector §4.1.1 and §4.1.3. The contact stiffness and damping, the Stribeck velocity,
    the tube damping and the mirror mode are this plant's own (the thesis gives the real
    turntable's values for none of them).
    """

    table_radius_m: float = 0.01  # R_table [D.1]
    table_density_kg_per_m3: float = 8.0e3  # ρ_table [D.1]
    tube_outer_radius_m: float = 3.175e-3  # R_o [D.1]
    tube_inner_radius_m: float = 2.667e-3  # R_i [D.1]
    tube_length_m: float = 6.35e-3  # L [D.1]
    tube_youngs_modulus_Pa: float = 5.263e10  # E [D.1]
    tube_density_kg_per_m3: float = 7.8e3  # ρ_tube [D.1]
    ball_density_kg_per_m3: float = 3.98e3  # ρ_ball, Al2O3 [D.1]
    d31_m_per_V: float = -210e-12  # [D.1]
    tube_damping_ratio: float = 0.02  # tube bending mode (own)
    amplifier_gain: float = 45.0  # HVA 900 [§4.1.1]
    amplifier_rate_per_s: float = 2.7e6 / 135.0  # steepest slope / step [Fig. 4.2]
    amplifier_damping_ratio: float = 0.7  # small-signal response shape (own)
    amplifier_slew_limit_V_per_s: float = 12e6  # data sheet [§4.1.2]
    normal_to_weight_ratio: float = 100.0 / (15.0 * GRAVITY_M_PER_S2)  # F_N/(m g) [D.2]
    static_friction_coefficient: float = 0.3  # μ_st [D.2]
    coulomb_friction_coefficient: float = 0.05  # μ_c [D.2]
    stribeck_velocity_m_per_s: float = 1.0e-3  # v_s (own: D.2's 0.8 m/s is the scaled model)
    stribeck_exponent: float = 2.0  # δ_vs [D.2]
    contact_stiffness_N_per_m: float = 1.0e6  # σ0 per contact (own)
    contact_damping_N_s_per_m: float = 8.0  # σ1 (own)
    viscous_friction_N_s_per_m: float = 0.0  # σ2 [D.2: R_viscous = 0]
    breakaway_fraction: float = 0.5  # z_ba = this × F_c/σ0 (< z_ss for every v)
    mirror_mode_frequency_Hz: float = 9.5e3  # mode 2 (own)
    mirror_mode_damping_ratio: float = 0.03  # mode 2 (own)
    mirror_inertia_fraction: float = 0.02  # mirror inertia / table inertia (own)
    detector_sensitivity_m_per_V: float = 9.9e-5  # S [§4.1.3]
    detector_distance_m: float = 0.175  # L [§4.1.1]
    detector_linear_range_m: float = 0.2e-3  # [§4.1.3]
    time_step_s: float = 1.0e-6  # integration step h

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "d31_m_per_V":
                if not (isinstance(v, (int, float)) and math.isfinite(v) and v != 0.0):
                    raise _bad(f.name, v, "must be a finite non-zero number")
            elif f.name in ("viscous_friction_N_s_per_m",):
                _nonnegative(f.name, v)
            else:
                _positive(f.name, v)
        if self.tube_inner_radius_m >= self.tube_outer_radius_m:
            raise _bad("tube_inner_radius_m", self.tube_inner_radius_m, "must be < R_o")
        _within("amplifier_damping_ratio", self.amplifier_damping_ratio, 0.05, 0.99)
        _within("tube_damping_ratio", self.tube_damping_ratio, 0.0, 1.0)
        _within("mirror_mode_damping_ratio", self.mirror_mode_damping_ratio, 0.0, 1.0)
        _within("mirror_inertia_fraction", self.mirror_inertia_fraction, 1e-6, 1.0)
        _within("breakaway_fraction", self.breakaway_fraction, 1e-3, 0.99)
        if self.coulomb_friction_coefficient > self.static_friction_coefficient:
            raise _bad(
                "coulomb_friction_coefficient",
                self.coulomb_friction_coefficient,
                f"must be ≤ static_friction_coefficient={self.static_friction_coefficient!r}",
            )
        _within("amplifier_gain", self.amplifier_gain, 1.0, 1000.0)
        _within("time_step_s", self.time_step_s, 1e-8, 1e-5)
        if self.time_step_s * self.tip_mode_rad_per_s >= 0.5:
            raise _bad("time_step_s", self.time_step_s, "too long for the tube tip mode")

    # --- derived (Appendix B, C; Eqs. 2.12, 3.1, 3.2) ---
    @property
    def table_mass_kg(self) -> float:
        """Half sphere, Eq. C.1."""
        return self.table_density_kg_per_m3 * 2.0 / 3.0 * math.pi * self.table_radius_m**3

    @property
    def table_inertia_kg_m2(self) -> float:
        """About an axis through the sphere centre, Eq. C.8."""
        return 0.4 * self.table_mass_kg * self.table_radius_m**2

    @property
    def tube_wall_m(self) -> float:
        """Wall thickness h = R_o − R_i."""
        return self.tube_outer_radius_m - self.tube_inner_radius_m

    @property
    def bending_curvature_per_V(self) -> float:
        """1/R_bending at 1 V in the asymmetric mode, Eq. 2.12 with D = R_o + R_i [1/(m V)]."""
        d = self.tube_outer_radius_m + self.tube_inner_radius_m
        return 2.0 * math.sqrt(2.0) * abs(self.d31_m_per_V) / (math.pi * d * self.tube_wall_m)

    @property
    def ball_lever_m(self) -> float:
        """Height of the contact point above the tube end: ball radius R_o seated on the bore."""
        ro, ri = self.tube_outer_radius_m, self.tube_inner_radius_m
        return ro + math.sqrt(ro * ro - ri * ri)

    @property
    def stroke_m_per_V(self) -> float:
        """Free tangential stroke of the contact point per tube volt, Eq. 2.11 + tip slope."""
        length = self.tube_length_m
        return self.bending_curvature_per_V * length * (0.5 * length + self.ball_lever_m)

    @property
    def tube_area_moment_m4(self) -> float:
        """I_x, Eq. B.4."""
        return math.pi * (self.tube_outer_radius_m**4 - self.tube_inner_radius_m**4) / 4.0

    @property
    def tube_stiffness_N_per_m(self) -> float:
        """Bending stiffness at the contact point (Eq. B.6 for a load ℓ above the end)."""
        length, ell = self.tube_length_m, self.ball_lever_m
        ei = self.tube_youngs_modulus_Pa * self.tube_area_moment_m4
        return ei / (length**3 / 3.0 + length**2 * ell + length * ell**2)

    @property
    def tip_mass_kg(self) -> float:
        """Ball plus 33/140 of the piezo tube (Eq. C.2 split into its two parts)."""
        ro, ri = self.tube_outer_radius_m, self.tube_inner_radius_m
        m_tube = self.tube_density_kg_per_m3 * math.pi * (ro * ro - ri * ri) * self.tube_length_m
        m_ball = self.ball_density_kg_per_m3 * 4.0 / 3.0 * math.pi * ro**3
        return m_ball + 33.0 / 140.0 * m_tube

    @property
    def normal_force_N(self) -> float:
        """Normal force per contact, F_N = κ·m_table·g."""
        return self.normal_to_weight_ratio * self.table_mass_kg * GRAVITY_M_PER_S2

    @property
    def static_friction_N(self) -> float:
        """F_s = μ_s F_N, Eq. 2.14."""
        return self.static_friction_coefficient * self.normal_force_N

    @property
    def coulomb_friction_N(self) -> float:
        """F_c = μ_c F_N, Eq. 2.14."""
        return self.coulomb_friction_coefficient * self.normal_force_N

    @property
    def amplifier_natural_rad_per_s(self) -> float:
        """ω_a with max step slope ω_a·exp(−ζ·acos ζ/√(1−ζ²)) = amplifier_rate_per_s."""
        z = self.amplifier_damping_ratio
        return self.amplifier_rate_per_s / math.exp(-z * math.acos(z) / math.sqrt(1 - z * z))

    @property
    def series_contact_stiffness_N_per_m(self) -> float:
        """Tube and contact in series [N/m]."""
        k1, k2 = self.tube_stiffness_N_per_m, self.contact_stiffness_N_per_m
        return k1 * k2 / (k1 + k2)

    @property
    def tip_mode_rad_per_s(self) -> float:
        """Tube tip on tube + contact, table held: the stiffest mode [rad/s]."""
        k = self.tube_stiffness_N_per_m + self.contact_stiffness_N_per_m
        return math.sqrt(k / self.tip_mass_kg)

    def lever_m(self, axis: str) -> float:
        """Distance of the driven contacts from the rotation axis, Eq. 3.1."""
        return self.table_radius_m * (math.sqrt(2.0 / 3.0) if axis == "Z" else 1.0)

    def rotation_mode_Hz(self, axis: str = "A") -> float:
        """Mode 1: the table on the contact+tube compliance (mirror and tip mass ignored)."""
        n = 3 if axis == "Z" else 2
        k_rot = n * self.series_contact_stiffness_N_per_m * self.lever_m(axis) ** 2
        return math.sqrt(k_rot / self.table_inertia_kg_m2) / (2.0 * math.pi)

    @property
    def detector_clip_V(self) -> float:
        """Output at the edge of the linear range [V]."""
        return self.detector_linear_range_m / self.detector_sensitivity_m_per_V

    def derived(self) -> dict[str, float]:
        """Derived values (for the truth file and reports)."""
        return {
            "table_mass_kg": self.table_mass_kg,
            "table_inertia_kg_m2": self.table_inertia_kg_m2,
            "bending_radius_at_1V_m": 1.0 / self.bending_curvature_per_V,
            "ball_lever_m": self.ball_lever_m,
            "stroke_m_per_V": self.stroke_m_per_V,
            "tube_stiffness_N_per_m": self.tube_stiffness_N_per_m,
            "tip_mass_kg": self.tip_mass_kg,
            "normal_force_N": self.normal_force_N,
            "static_friction_N": self.static_friction_N,
            "coulomb_friction_N": self.coulomb_friction_N,
            "amplifier_natural_Hz": self.amplifier_natural_rad_per_s / (2 * math.pi),
            "rotation_mode_Hz_ABC": self.rotation_mode_Hz("A"),
            "rotation_mode_Hz_Z": self.rotation_mode_Hz("Z"),
            "tip_mode_Hz": self.tip_mode_rad_per_s / (2 * math.pi),
            "detector_clip_V": self.detector_clip_V,
        }


# --------------------------------------------------------------------------- effects


@dataclass(frozen=True)
class Creep:
    """Piezo strain creep: a step ΔV grows by ``fraction_per_decade`` per decade of time
    (one first-order term per time constant, each of weight fraction_per_decade)."""

    fraction_per_decade: float = 0.07
    time_constants_s: tuple[float, ...] = (0.03, 0.3, 3.0, 30.0)

    def __post_init__(self) -> None:
        _within("fraction_per_decade", self.fraction_per_decade, 0.0, 0.3)
        if len(self.time_constants_s) == 0:
            raise _bad("time_constants_s", self.time_constants_s, "must not be empty")
        for tau in self.time_constants_s:
            _positive("time_constants_s", tau)


@dataclass(frozen=True)
class Hysteresis:
    """Piezo hysteresis, Prandtl–Ishlinskii: ``w0·V + Σ w·play_r(V)`` with thresholds
    ``r_i = i/(2n)·reference_V``; the loop at ±reference_V is ``loop_width_fraction`` of
    the stroke wide and its end points are the nominal ones."""

    loop_width_fraction: float = 0.13
    reference_V: float = 360.0
    operators: int = 5

    def __post_init__(self) -> None:
        _within("loop_width_fraction", self.loop_width_fraction, 0.0, 0.3)
        _positive("reference_V", self.reference_V)
        if not (isinstance(self.operators, int) and 1 <= self.operators <= 50):
            raise _bad("operators", self.operators, "must be an int in 1…50")

    def weights(self) -> tuple[np.ndarray, np.ndarray, float]:
        """(thresholds [V], weights [-], linear weight w0 [-])."""
        n = self.operators
        frac = np.arange(1, n + 1) / (2.0 * n)
        r = frac * self.reference_V
        w = np.full(n, self.loop_width_fraction / frac.sum())
        w0 = 1.0 - float(np.sum(w * (1.0 - frac)))
        return r, w, w0


@dataclass(frozen=True)
class FloorVibration:
    """Floor vibration: the tube mounts move tangentially, ``a·sin(2π f t + φ)`` [m]."""

    amplitude_m: float = 30e-9
    frequency_Hz: float = 147.0
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        _within("amplitude_m", self.amplitude_m, 0.0, 1e-5)
        _positive("frequency_Hz", self.frequency_Hz)
        _within("phase_rad", self.phase_rad, -10.0, 10.0)


@dataclass(frozen=True)
class FrictionAsymmetry:
    """Friction (F_s, F_c, z_ba) ×(1 + fraction) when the tip slides backwards (v < 0)."""

    fraction: float = 0.3

    def __post_init__(self) -> None:
        _within("fraction", self.fraction, -0.9, 2.0)


@dataclass(frozen=True)
class SlowAmplifier:
    """An amplifier slower than nominal: slew limit [V/s] and bandwidth × factor."""

    slew_limit_V_per_s: float = 0.6e6
    bandwidth_factor: float = 0.4

    def __post_init__(self) -> None:
        _positive("slew_limit_V_per_s", self.slew_limit_V_per_s)
        _within("bandwidth_factor", self.bandwidth_factor, 1e-3, 1.0)


@dataclass(frozen=True)
class SensorDrift:
    """Thermal drift of the photodiode offsets: ``offset + rate·t`` on each channel [V]."""

    rate_V_per_s: float = 8e-3
    y_rate_V_per_s: float = 0.0
    offset_V: float = 0.0

    def __post_init__(self) -> None:
        _within("rate_V_per_s", self.rate_V_per_s, -1.0, 1.0)
        _within("y_rate_V_per_s", self.y_rate_V_per_s, -1.0, 1.0)
        _within("offset_V", self.offset_V, -1.0, 1.0)


@dataclass(frozen=True)
class DetectorNonlinearity:
    """Gain falling off to the edge: ``V = V_lin·(1 − loss·(V_lin/V_clip)²)``."""

    edge_gain_loss: float = 0.2

    def __post_init__(self) -> None:
        _within("edge_gain_loss", self.edge_gain_loss, 0.0, 0.6)


@dataclass(frozen=True)
class AxisMisalignment:
    """Detector axes rotated by ``angle_deg``: y = −sin·x_true, x = cos·x_true."""

    angle_deg: float = 4.0

    def __post_init__(self) -> None:
        _within("angle_deg", self.angle_deg, -45.0, 45.0)


@dataclass(frozen=True)
class MainsPickup:
    """Mains pickup added to the amplifier input (not to the recorded drive) [V]."""

    amplitude_V: float = 0.15
    frequency_Hz: float = 50.0

    def __post_init__(self) -> None:
        _within("amplitude_V", self.amplitude_V, 0.0, 2.0)
        _positive("frequency_Hz", self.frequency_Hz)


@dataclass(frozen=True)
class ContactWear:
    """Friction falls with sliding distance s: ×(1 − loss·(1 − exp(−s/distance)))."""

    friction_loss: float = 0.35
    distance_m: float = 8e-6

    def __post_init__(self) -> None:
        _within("friction_loss", self.friction_loss, 0.0, 0.9)
        _positive("distance_m", self.distance_m)


@dataclass(frozen=True)
class MirrorPlay:
    """Play (backlash) of total width ``play_rad`` between table and mirror mount."""

    play_rad: float = 1.5e-5

    def __post_init__(self) -> None:
        _within("play_rad", self.play_rad, 0.0, 1e-3)


EFFECT_NAMES = (
    "creep",
    "hysteresis",
    "floor_vibration",
    "friction_asymmetry",
    "slow_amplifier",
    "sensor_drift",
    "detector_nonlinearity",
    "axis_misalignment",
    "mains_pickup",
    "contact_wear",
    "mirror_play",
)
_EFFECT_TYPES: dict[str, type] = {
    "creep": Creep,
    "hysteresis": Hysteresis,
    "floor_vibration": FloorVibration,
    "friction_asymmetry": FrictionAsymmetry,
    "slow_amplifier": SlowAmplifier,
    "sensor_drift": SensorDrift,
    "detector_nonlinearity": DetectorNonlinearity,
    "axis_misalignment": AxisMisalignment,
    "mains_pickup": MainsPickup,
    "contact_wear": ContactWear,
    "mirror_play": MirrorPlay,
}


@dataclass(frozen=True)
class Effects:
    """The effects switched on (None = off); the field names are the truth-file keys."""

    creep: Creep | None = None
    hysteresis: Hysteresis | None = None
    floor_vibration: FloorVibration | None = None
    friction_asymmetry: FrictionAsymmetry | None = None
    slow_amplifier: SlowAmplifier | None = None
    sensor_drift: SensorDrift | None = None
    detector_nonlinearity: DetectorNonlinearity | None = None
    axis_misalignment: AxisMisalignment | None = None
    mains_pickup: MainsPickup | None = None
    contact_wear: ContactWear | None = None
    mirror_play: MirrorPlay | None = None

    def __post_init__(self) -> None:
        for name, typ in _EFFECT_TYPES.items():
            v = getattr(self, name)
            if v is not None and not isinstance(v, typ):
                raise _bad(name, v, f"must be a {typ.__name__} or None")

    def truth(self) -> dict[str, dict[str, Any]]:
        """{effect name: its parameters} for the effects switched on."""
        out: dict[str, dict[str, Any]] = {}
        for name in EFFECT_NAMES:
            v = getattr(self, name)
            if v is not None:
                out[name] = {
                    k: (list(x) if isinstance(x, tuple) else x) for k, x in asdict(v).items()
                }
        return out


# --------------------------------------------------------------------------- protocols


@dataclass(frozen=True)
class Hold:
    """Hold the drive at ``level_V`` for ``duration_s``."""

    duration_s: float
    level_V: float = 0.0

    def __post_init__(self) -> None:
        _positive("duration_s", self.duration_s)
        _within("level_V", self.level_V, -INPUT_LIMIT_V, INPUT_LIMIT_V)

    def points(self) -> list[tuple[float, float]]:
        return [(0.0, self.level_V), (self.duration_s, self.level_V)]


@dataclass(frozen=True)
class Ramp:
    """Linear move from ``start_V`` to ``end_V`` over ``duration_s``."""

    start_V: float
    end_V: float
    duration_s: float

    def __post_init__(self) -> None:
        _within("start_V", self.start_V, -INPUT_LIMIT_V, INPUT_LIMIT_V)
        _within("end_V", self.end_V, -INPUT_LIMIT_V, INPUT_LIMIT_V)
        _positive("duration_s", self.duration_s)

    def points(self) -> list[tuple[float, float]]:
        return [(0.0, self.start_V), (self.duration_s, self.end_V)]


@dataclass(frozen=True)
class Scan:
    """Slow triangle: offset → offset+A → offset−A → offset, ``cycles`` times."""

    amplitude_V: float
    frequency_Hz: float
    cycles: int = 1
    offset_V: float = 0.0

    def __post_init__(self) -> None:
        _positive("amplitude_V", self.amplitude_V)
        _positive("frequency_Hz", self.frequency_Hz)
        if not (isinstance(self.cycles, int) and self.cycles >= 1):
            raise _bad("cycles", self.cycles, "must be an int ≥ 1")
        for lv in (self.offset_V + self.amplitude_V, self.offset_V - self.amplitude_V):
            if abs(lv) > INPUT_LIMIT_V:
                raise _bad("amplitude_V", self.amplitude_V, "drive beyond ±10 V")

    def points(self) -> list[tuple[float, float]]:
        q = 0.25 / self.frequency_Hz
        o, a = self.offset_V, self.amplitude_V
        pts = [(0.0, o)]
        for c in range(self.cycles):
            t0 = 4 * q * c
            pts += [(t0 + q, o + a), (t0 + 3 * q, o - a), (t0 + 4 * q, o)]
        return pts


@dataclass(frozen=True)
class Burst:
    """``periods`` sawtooth periods between ``offset_V`` and ``offset_V + amplitude_V``.

    direction +1: slow ramp up over ``ramp_fraction`` of the period, fast flyback down;
    direction −1: fast rise, slow ramp down (the table moves the other way).
    """

    amplitude_V: float
    frequency_Hz: float
    periods: int
    direction: int = 1
    ramp_fraction: float = 0.95
    offset_V: float = 0.0

    def __post_init__(self) -> None:
        _positive("amplitude_V", self.amplitude_V)
        _positive("frequency_Hz", self.frequency_Hz)
        if not (isinstance(self.periods, int) and self.periods >= 1):
            raise _bad("periods", self.periods, "must be an int ≥ 1")
        if self.direction not in (1, -1):
            raise _bad("direction", self.direction, "must be +1 or −1")
        _within("ramp_fraction", self.ramp_fraction, 0.5, 0.9999)
        for lv in (self.offset_V, self.offset_V + self.amplitude_V):
            if abs(lv) > INPUT_LIMIT_V:
                raise _bad("amplitude_V", self.amplitude_V, "drive beyond ±10 V")

    def points(self) -> list[tuple[float, float]]:
        period = 1.0 / self.frequency_Hz
        lo, hi = self.offset_V, self.offset_V + self.amplitude_V
        corner = (self.ramp_fraction if self.direction > 0 else 1.0 - self.ramp_fraction) * period
        pts = [(0.0, lo)]
        for k in range(self.periods):
            pts += [(k * period + corner, hi), ((k + 1) * period, lo)]
        return pts


Segment = Hold | Ramp | Scan | Burst


@dataclass(frozen=True)
class Protocol:
    """A named drive built from segments, played one after another (each starts where
    the previous ended)."""

    name: str
    segments: tuple[Segment, ...]

    def __post_init__(self) -> None:
        if not self.segments:
            raise _bad("segments", self.segments, "must not be empty")
        level = None
        for k, s in enumerate(self.segments):
            if not isinstance(s, (Hold, Ramp, Scan, Burst)):
                raise _bad(f"segments[{k}]", s, "must be a Hold, Ramp, Scan or Burst")
            start = s.points()[0][1]
            if level is not None and abs(start - level) > 1e-12:
                raise _bad(f"segments[{k}]", s, f"starts at {start} V, previous ends at {level} V")
            level = s.points()[-1][1]

    @property
    def duration_s(self) -> float:
        return float(build_drive(self)[0][-1])


def build_drive(protocol: Protocol) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints (time [s], amplifier input [V]) of the piecewise-linear drive."""
    ts: list[float] = []
    us: list[float] = []
    t0 = 0.0
    for seg in protocol.segments:
        pts = seg.points()
        if ts:
            pts = pts[1:]
        for t, u in pts:
            ts.append(t0 + t)
            us.append(u)
        t0 = ts[-1]
    t = np.asarray(ts, dtype=np.float64)
    u = np.asarray(us, dtype=np.float64)
    if np.any(np.diff(t) <= 0.0):
        raise ValueError(f"protocol {protocol.name!r}: breakpoint times not increasing")
    if np.max(np.abs(u)) > INPUT_LIMIT_V:
        raise ValueError(f"protocol {protocol.name!r}: drive beyond ±{INPUT_LIMIT_V} V")
    return t, u


def drive_at(bp_t: np.ndarray, bp_u: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The piecewise-linear drive at times ``t`` [V] (held outside the breakpoints)."""
    return np.interp(t, bp_t, bp_u)


FLYBACK_S = 30e-6  # duration of the sawtooth's fast edge in the named protocols [s]


def _bidirectional(amp: float, freq: float, periods: int, hold: float) -> list[Segment]:
    """A forward burst, a hold, the reverse burst, a hold (fast edge FLYBACK_S)."""
    a = 1.0 - FLYBACK_S * freq
    return [
        Burst(amp, freq, periods, 1, a),
        Hold(hold),
        Burst(amp, freq, periods, -1, a),
        Hold(hold),
    ]


PROTOCOLS: dict[str, Protocol] = {
    # scan, a move-and-hold, then bursts at several amplitudes/frequencies in both
    # directions with holds between them
    "scan_and_bursts": Protocol(
        "scan_and_bursts",
        (
            Hold(0.05),
            Scan(8.0, 2.0, 1),
            Hold(0.1),
            Ramp(0.0, 6.0, 0.05),
            Hold(0.2, 6.0),
            Ramp(6.0, 0.0, 0.05),
            Hold(0.15),
            *_bidirectional(2.0, 20.0, 3, 0.1),
            *_bidirectional(4.0, 100.0, 6, 0.1),
            *_bidirectional(1.0, 500.0, 20, 0.1),
            *_bidirectional(2.0, 2000.0, 8, 0.1),
            *_bidirectional(0.5, 1000.0, 40, 0.1),
            Hold(0.05),
        ),
    ),
    # stepping only, no scan
    "stepping_bursts": Protocol(
        "stepping_bursts",
        (
            Hold(0.05),
            *_bidirectional(1.5, 20.0, 5, 0.12),
            *_bidirectional(4.4, 200.0, 5, 0.12),
            *_bidirectional(0.8, 800.0, 25, 0.12),
            *_bidirectional(2.2, 2000.0, 10, 0.12),
            *_bidirectional(2.0, 50.0, 8, 0.12),
            *_bidirectional(0.44, 1500.0, 50, 0.12),
            Hold(0.05),
        ),
    ),
    # slow triangles and a staircase with holds (gain, hysteresis, creep), short bursts
    "scan_holds": Protocol(
        "scan_holds",
        (
            Hold(0.05),
            Scan(9.0, 2.0, 1),
            Hold(0.1),
            Ramp(0.0, 7.0, 0.1),
            Hold(0.3, 7.0),
            Ramp(7.0, -7.0, 0.2),
            Hold(0.3, -7.0),
            Ramp(-7.0, 0.0, 0.1),
            Hold(0.2),
            Scan(5.0, 4.0, 1),
            Hold(0.1),
            *_bidirectional(2.0, 300.0, 10, 0.12),
            Hold(0.05),
        ),
    ),
}


# --------------------------------------------------------------------------- kernel

# indices into the kernel's parameter vector
(
    _P_DT,
    _P_GAIN,
    _P_WA,
    _P_ZA,
    _P_SLEW,
    _P_VMAX,
    _P_MAINS_A,
    _P_MAINS_F,
    _P_STROKE,
    _P_BASE_A,
    _P_BASE_F,
    _P_BASE_PH,
    _P_MTIP,
    _P_KTUBE,
    _P_CTUBE,
    _P_LEVER,
    _P_INERTIA,
    _P_NC,
    _P_SIG0,
    _P_SIG1,
    _P_SIG2,
    _P_FS,
    _P_FC,
    _P_VS,
    _P_DVS,
    _P_BETA,
    _P_ASYM,
    _P_WEAR_LOSS,
    _P_WEAR_DIST,
    _P_IM,
    _P_KM,
    _P_CM,
    _P_PLAY,
    _P_HW0,
    _P_CREEP_GAMMA,
    _P_N,
) = range(36)

_OUT_MIRROR, _OUT_TABLE, _OUT_ENERGY, _OUT_AMP, _OUT_PIEZO, _OUT_N = range(6)


@njit(cache=CACHE)
def _stribeck(v_abs: float, fs: float, fc: float, vs: float, dvs: float) -> float:
    """s(|v|), Eq. 2.13 [N]."""
    return fc + (fs - fc) * math.exp(-((v_abs / vs) ** dvs))


@njit(cache=CACHE)
def _kernel(
    bp_t: np.ndarray,
    bp_u: np.ndarray,
    out_t: np.ndarray,
    p: np.ndarray,
    hyst_r: np.ndarray,
    hyst_w: np.ndarray,
    creep_tau: np.ndarray,
    rate0: float,
) -> np.ndarray:
    """Integrate the plant; one row per output time (_OUT_* columns)."""
    dt_max = p[_P_DT]
    gain = p[_P_GAIN]
    wa = p[_P_WA]
    za = p[_P_ZA]
    slew = p[_P_SLEW]
    vmax = p[_P_VMAX]
    mains_a = p[_P_MAINS_A]
    mains_w = 2.0 * math.pi * p[_P_MAINS_F]
    stroke = p[_P_STROKE]
    base_a = p[_P_BASE_A]
    base_w = 2.0 * math.pi * p[_P_BASE_F]
    base_ph = p[_P_BASE_PH]
    m_t = p[_P_MTIP]
    k_t = p[_P_KTUBE]
    c_t = p[_P_CTUBE]
    lever = p[_P_LEVER]
    inertia = p[_P_INERTIA]
    nc = int(p[_P_NC])
    sig0 = p[_P_SIG0]
    sig1 = p[_P_SIG1]
    sig2 = p[_P_SIG2]
    fs0 = p[_P_FS]
    fc0 = p[_P_FC]
    vs = p[_P_VS]
    dvs = p[_P_DVS]
    beta = p[_P_BETA]
    asym = p[_P_ASYM]
    wear_loss = p[_P_WEAR_LOSS]
    wear_dist = p[_P_WEAR_DIST]
    i_m = p[_P_IM]
    k_m = p[_P_KM]
    c_m = p[_P_CM]
    half_play = 0.5 * p[_P_PLAY]
    hw0 = p[_P_HW0]
    gamma = p[_P_CREEP_GAMMA]
    n_h = hyst_r.size
    n_c = creep_tau.size
    nb = bp_t.size

    # initial state: the drive has been at its first value for ever, all at rest
    u0 = bp_u[0]
    y = gain * u0
    yd = 0.0
    plays = np.empty(n_h)
    vh = hw0 * y
    for i in range(n_h):
        plays[i] = max(y - hyst_r[i], min(y + hyst_r[i], 0.0))
        vh += hyst_w[i] * plays[i]
    wc = np.full(n_c, vh)
    creep_sum = 0.0
    for i in range(n_c):
        creep_sum += wc[i]
    up = stroke * (vh + gamma * creep_sum) + base_a * math.sin(base_ph)
    x = np.full(nc, up)
    xd = np.zeros(nc)
    z = np.zeros(nc)
    theta = 0.0
    omega = rate0
    phi = 0.0
    phid = rate0
    carrier = 0.0
    slid = 0.0

    res = np.empty((out_t.size, 6))
    t = 0.0
    j = 0
    for k in range(out_t.size):
        t_end = out_t[k]
        while t < t_end - 1e-13:
            h = min(dt_max, t_end - t)
            tn = t + h
            # generator (piecewise linear) + mains pickup
            while j < nb - 2 and bp_t[j + 1] <= tn:
                j += 1
            if tn <= bp_t[0]:
                u = bp_u[0]
            elif tn >= bp_t[nb - 1]:
                u = bp_u[nb - 1]
            else:
                u = bp_u[j] + (bp_u[j + 1] - bp_u[j]) * (tn - bp_t[j]) / (bp_t[j + 1] - bp_t[j])
            if mains_a != 0.0:
                u += mains_a * math.sin(mains_w * tn)
            # amplifier: 2nd order small signal, slew and output limits
            yd += h * (wa * wa * (gain * u - y) - 2.0 * za * wa * yd)
            if yd > slew:
                yd = slew
            elif yd < -slew:
                yd = -slew
            y += h * yd
            if y > vmax:
                y = vmax
                yd = 0.0
            elif y < -vmax:
                y = -vmax
                yd = 0.0
            # piezo: Prandtl–Ishlinskii hysteresis, then creep
            vh = hw0 * y
            for i in range(n_h):
                pl = plays[i]
                if y - hyst_r[i] > pl:
                    pl = y - hyst_r[i]
                elif y + hyst_r[i] < pl:
                    pl = y + hyst_r[i]
                plays[i] = pl
                vh += hyst_w[i] * pl
            creep_sum = 0.0
            for i in range(n_c):
                wc[i] += (vh - wc[i]) * (1.0 - math.exp(-h / creep_tau[i]))
                creep_sum += wc[i]
            up_new = stroke * (vh + gamma * creep_sum)
            if base_a != 0.0:
                up_new += base_a * math.sin(base_w * tn + base_ph)
            upd = (up_new - up) / h
            up = up_new
            # friction level (wear)
            wear = 1.0
            if wear_loss != 0.0:
                wear = 1.0 - wear_loss * (1.0 - math.exp(-slid / wear_dist))
            # contacts: elasto-plastic friction, tube tips
            v_tab = lever * omega
            f_sum = 0.0
            for i in range(nc):
                v = xd[i] - v_tab
                scale = wear
                if v < 0.0:
                    scale *= 1.0 + asym
                elif v == 0.0 and z[i] < 0.0:
                    scale *= 1.0 + asym
                fs = fs0 * scale
                fc = fc0 * scale
                zss = _stribeck(abs(v), fs, fc, vs, dvs) / sig0
                zba = beta * fc / sig0
                zi = z[i]
                az = abs(zi)
                if v == 0.0 or az <= zba or (v > 0.0) != (zi > 0.0):
                    alpha = 0.0
                elif az >= zss:
                    alpha = 1.0
                else:
                    alpha = 0.5 * math.sin(math.pi * (az - 0.5 * (zss + zba)) / (zss - zba)) + 0.5
                if alpha > 0.0:
                    lam = alpha * abs(v) / zss
                    zeq = v / lam
                    zn = zeq + (zi - zeq) * math.exp(-lam * h)
                else:
                    zn = zi + v * h
                zdot = (zn - zi) / h
                z[i] = zn
                if wear_loss != 0.0:
                    slid += abs(v * h - (zn - zi))
                force = sig0 * zn + sig1 * zdot + sig2 * v
                xd[i] += h * (k_t * (up - x[i]) + c_t * (upd - xd[i]) - force) / m_t
                f_sum += force
            # mirror mount (with play: the mount's carrier follows the table with play)
            if theta - carrier > half_play:
                carrier = theta - half_play
            elif carrier - theta > half_play:
                carrier = theta + half_play
            torque_m = k_m * (phi - carrier) + c_m * (phid - omega)
            omega += h * (lever * f_sum + torque_m) / inertia
            phid -= h * torque_m / i_m
            for i in range(nc):
                x[i] += h * xd[i]
            theta += h * omega
            phi += h * phid
            t = tn
        energy = 0.5 * inertia * omega * omega + 0.5 * i_m * phid * phid
        energy += 0.5 * k_m * (phi - carrier) ** 2
        for i in range(nc):
            energy += 0.5 * m_t * xd[i] * xd[i] + 0.5 * k_t * (x[i] - up) ** 2
            energy += 0.5 * sig0 * z[i] * z[i]
        res[k, _OUT_MIRROR] = phi
        res[k, _OUT_TABLE] = theta
        res[k, _OUT_ENERGY] = energy
        res[k, _OUT_AMP] = y
        res[k, _OUT_PIEZO] = up
    return res


def _pack(params: PlantParams, effects: Effects, axis: str) -> tuple[np.ndarray, ...]:
    p = np.zeros(_P_N)
    slow = effects.slow_amplifier
    p[_P_DT] = params.time_step_s
    p[_P_GAIN] = params.amplifier_gain
    p[_P_WA] = params.amplifier_natural_rad_per_s * (slow.bandwidth_factor if slow else 1.0)
    p[_P_ZA] = params.amplifier_damping_ratio
    p[_P_SLEW] = slow.slew_limit_V_per_s if slow else params.amplifier_slew_limit_V_per_s
    p[_P_VMAX] = params.amplifier_gain * INPUT_LIMIT_V
    if effects.mains_pickup:
        p[_P_MAINS_A] = effects.mains_pickup.amplitude_V
        p[_P_MAINS_F] = effects.mains_pickup.frequency_Hz
    p[_P_STROKE] = params.stroke_m_per_V
    if effects.floor_vibration:
        p[_P_BASE_A] = effects.floor_vibration.amplitude_m
        p[_P_BASE_F] = effects.floor_vibration.frequency_Hz
        p[_P_BASE_PH] = effects.floor_vibration.phase_rad
    p[_P_MTIP] = params.tip_mass_kg
    p[_P_KTUBE] = params.tube_stiffness_N_per_m
    p[_P_CTUBE] = (
        2.0
        * params.tube_damping_ratio
        * math.sqrt(params.tube_stiffness_N_per_m * params.tip_mass_kg)
    )
    p[_P_LEVER] = params.lever_m(axis)
    p[_P_INERTIA] = params.table_inertia_kg_m2
    p[_P_NC] = 3 if axis == "Z" else 2
    p[_P_SIG0] = params.contact_stiffness_N_per_m
    p[_P_SIG1] = params.contact_damping_N_s_per_m
    p[_P_SIG2] = params.viscous_friction_N_s_per_m
    p[_P_FS] = params.static_friction_N
    p[_P_FC] = params.coulomb_friction_N
    p[_P_VS] = params.stribeck_velocity_m_per_s
    p[_P_DVS] = params.stribeck_exponent
    p[_P_BETA] = params.breakaway_fraction
    if effects.friction_asymmetry:
        p[_P_ASYM] = effects.friction_asymmetry.fraction
    if effects.contact_wear:
        p[_P_WEAR_LOSS] = effects.contact_wear.friction_loss
        p[_P_WEAR_DIST] = effects.contact_wear.distance_m
    else:
        p[_P_WEAR_DIST] = 1.0
    i_m = params.mirror_inertia_fraction * params.table_inertia_kg_m2
    w_m = 2.0 * math.pi * params.mirror_mode_frequency_Hz
    p[_P_IM] = i_m
    p[_P_KM] = i_m * w_m * w_m
    p[_P_CM] = 2.0 * params.mirror_mode_damping_ratio * i_m * w_m
    if effects.mirror_play:
        p[_P_PLAY] = effects.mirror_play.play_rad
    if effects.hysteresis:
        r, w, w0 = effects.hysteresis.weights()
        p[_P_HW0] = w0
    else:
        r, w = np.zeros(0), np.zeros(0)
        p[_P_HW0] = 1.0
    if effects.creep:
        tau = np.asarray(effects.creep.time_constants_s, dtype=np.float64)
        p[_P_CREEP_GAMMA] = effects.creep.fraction_per_decade
    else:
        tau = np.zeros(0)
    return p, r.astype(np.float64), w.astype(np.float64), tau


@dataclass(frozen=True, eq=False)
class SimResult:
    """Simulated signals at the output times (SI units).

    Attributes: time_s; mirror_angle_rad (what the detector sees); table_angle_rad;
    energy_J (stored mechanical energy: kinetic + tube, contact and mount springs);
    amplifier_V (amplifier output); piezo_m (free tube-tip displacement incl. mount motion).
    """

    time_s: np.ndarray
    mirror_angle_rad: np.ndarray
    table_angle_rad: np.ndarray
    energy_J: np.ndarray
    amplifier_V: np.ndarray
    piezo_m: np.ndarray


def simulate(
    params: PlantParams,
    drive: Protocol | tuple[np.ndarray, np.ndarray],
    times_s: np.ndarray,
    *,
    effects: Effects | None = None,
    axis: str = "A",
    initial_rate_rad_per_s: float = 0.0,
) -> SimResult:
    """Simulate the plant from rest (drive held at its first value before t = 0) and
    return its signals at ``times_s`` (strictly increasing, ≥ 0)."""
    if axis not in AXES:
        raise _bad("axis", axis, f"must be one of {', '.join(AXES)}")
    effects = effects or Effects()
    bp_t, bp_u = build_drive(drive) if isinstance(drive, Protocol) else drive
    bp_t = np.ascontiguousarray(bp_t, dtype=np.float64)
    bp_u = np.ascontiguousarray(bp_u, dtype=np.float64)
    if bp_t.size < 2 or np.any(np.diff(bp_t) <= 0.0):
        raise _bad("drive", "breakpoints", "need ≥ 2 breakpoints at increasing times")
    times = np.ascontiguousarray(times_s, dtype=np.float64)
    if times.size == 0 or times[0] < 0.0 or np.any(np.diff(times) <= 0.0):
        raise _bad("times_s", f"{times.size} samples", "must be increasing and ≥ 0")
    p, r, w, tau = _pack(params, effects, axis)
    res = _kernel(bp_t, bp_u, times, p, r, w, tau, float(initial_rate_rad_per_s))
    return SimResult(
        time_s=times,
        mirror_angle_rad=res[:, _OUT_MIRROR],
        table_angle_rad=res[:, _OUT_TABLE],
        energy_J=res[:, _OUT_ENERGY],
        amplifier_V=res[:, _OUT_AMP],
        piezo_m=res[:, _OUT_PIEZO],
    )


def step_per_period(
    params: PlantParams,
    amplitude_V: float,
    frequency_Hz: float,
    *,
    direction: int = 1,
    ramp_fraction: float = 0.95,
    periods: int = 6,
    settle_periods: int = 2,
    effects: Effects | None = None,
    axis: str = "A",
) -> float:
    """Mean table displacement per sawtooth period at the table radius [m] (angle at the
    period boundaries × R_table), skipping the first ``settle_periods``."""
    burst = Burst(amplitude_V, frequency_Hz, periods, direction, ramp_fraction)
    proto = Protocol("step", (Hold(1e-3), burst))
    period = 1.0 / frequency_Hz
    times = 1e-3 + period * np.arange(settle_periods, periods + 1)
    sim = simulate(params, proto, times, effects=effects, axis=axis)
    th = sim.table_angle_rad
    return float((th[-1] - th[0]) / (periods - settle_periods) * params.table_radius_m)


# --------------------------------------------------------------------------- detector + file


def detector_outputs(
    params: PlantParams,
    time_s: np.ndarray,
    mirror_angle_rad: np.ndarray,
    *,
    effects: Effects | None = None,
    noise_std_V: float = 0.0,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Quadrant-photodiode outputs (x, y) [V] for a mirror angle: Eq. 4.1 inverted,
    nonlinearity, axis rotation, offset drift, Gaussian noise, clipping at the linear range."""
    effects = effects or Effects()
    _nonnegative("noise_std_V", noise_std_V)
    clip = params.detector_clip_V
    vx = (
        params.detector_distance_m
        * np.tan(2.0 * mirror_angle_rad)
        / params.detector_sensitivity_m_per_V
    )
    vy = np.zeros_like(vx)
    if effects.detector_nonlinearity:
        loss = effects.detector_nonlinearity.edge_gain_loss
        vx = vx * (1.0 - loss * np.minimum((vx / clip) ** 2, 1.0))
    if effects.axis_misalignment:
        g = math.radians(effects.axis_misalignment.angle_deg)
        vx, vy = math.cos(g) * vx + math.sin(g) * vy, -math.sin(g) * vx + math.cos(g) * vy
    if effects.sensor_drift:
        d = effects.sensor_drift
        vx = vx + d.offset_V + d.rate_V_per_s * time_s
        vy = vy + d.y_rate_V_per_s * time_s
    if noise_std_V > 0.0:
        rng = rng if rng is not None else np.random.default_rng()
        vx = vx + rng.normal(0.0, noise_std_V, vx.shape)
        vy = vy + rng.normal(0.0, noise_std_V, vy.shape)
    return np.clip(vx, -clip, clip), np.clip(vy, -clip, clip)


def _row_times(bp_t: np.ndarray, sample_rate_Hz: float, with_breakpoints: bool) -> np.ndarray:
    n = math.floor(bp_t[-1] * sample_rate_Hz + 1e-9) + 1
    grid = np.arange(n) / sample_rate_Hz
    if not with_breakpoints:
        return grid
    merged = np.union1d(grid, bp_t[bp_t <= grid[-1] + 0.5 / sample_rate_Hz])
    keep = np.concatenate(([True], np.diff(merged) > 1e-9))
    return merged[keep]


def write_trace(
    path: str | Path,
    params: PlantParams,
    protocol: Protocol,
    *,
    effects: Effects | None = None,
    axis: str = "B",
    sample_rate_Hz: float = 20e3,
    noise_std_V: float = 1e-3,
    seed: int = 0,
    drive_recording: str = "breakpoints",
) -> Path:
    """Simulate ``protocol`` and write a measurement file.

    ``drive_recording``: "breakpoints" — rows at the sample times and at every drive
    breakpoint (the recorded drive, linearly interpolated, is the applied one exactly);
    "sampled" — rows at the sample times only (the generator's corners between samples
    are not in the file). The metadata holds only the keys the format requires.
    """
    if axis not in AXES:
        raise _bad("axis", axis, f"must be one of {', '.join(AXES)}")
    _within("sample_rate_Hz", sample_rate_Hz, 100.0, 1e6)
    _nonnegative("noise_std_V", noise_std_V)
    if drive_recording not in ("breakpoints", "sampled"):
        raise _bad("drive_recording", drive_recording, "must be 'breakpoints' or 'sampled'")
    effects = effects or Effects()
    bp_t, bp_u = build_drive(protocol)
    rows = _row_times(bp_t, sample_rate_Hz, drive_recording == "breakpoints")
    sim = simulate(params, (bp_t, bp_u), rows, effects=effects, axis=axis)
    rng = np.random.default_rng(seed)
    vx, vy = detector_outputs(
        params, rows, sim.mirror_angle_rad, effects=effects, noise_std_V=noise_std_V, rng=rng
    )
    det = Detector(
        sensitivity=params.detector_sensitivity_m_per_V,
        distance=params.detector_distance_m,
        linear_range=params.detector_linear_range_m,
        table_radius=params.table_radius_m,
    )
    m = Measurement(
        axis=axis,
        amplifier_gain=params.amplifier_gain,
        detector=det,
        time=rows,
        drives={axis: drive_at(bp_t, bp_u, rows)},
        detector_v=vx,
        detector_y_v=vy,
    )
    return m.save(path)


def params_truth(params: PlantParams) -> dict[str, Any]:
    """The plant's parameters as a JSON-ready dict."""
    return asdict(params)
