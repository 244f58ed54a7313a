"""A third independent test plant for the calibrator: Maxwell-slip contacts on a sphere.

This module produces measurement files (traces) for testing the project's calibrator
from a model that shares no code or formulation with the rest of the package. It was
written from the thesis (Schepers, *Modeling a piezoelectric inertial stepping turntable
using bond graphs*, chapters 2–4 and Table D.1), textbook contact mechanics and the
measurement file format only.

Formulation (one line each):

* Table: the steel sphere (Table D.1 mass and inertia) rotating about the watched tube
  axis (one rotation ``theta``) and translating along the two driven tubes' axes (two
  coordinates), so each tangential contact force also loads the other contact's Hertz
  spring and the passive contact's friction; the three tube axes are orthogonal and meet
  at the sphere's centre, contacts at R e_A, R e_B, R e_C.
* Tubes: each driving tube is a Timoshenko-corrected cantilever reduced to its tip
  translation and rotation (two bending modes, modal coordinates, modal damping), with
  the alumina ball on top; the piezo acts as a uniform bending moment and an axial
  (quarter-quadrant) elongation that changes the Hertz penetration.
* Contacts: normal force through a Hertz law with Hunt–Crossley damping; tangential force
  through a Maxwell-slip (Iwan) bank whose element stiffnesses/strengths discretise the
  Mindlin–Cattaneo partial-slip curve; the strength moves between static and kinetic
  (Stribeck in the sliding speed) through a first-order frictional-lag state; the passive
  contact on the rotation axis adds a Dahl spin-friction torque.
* Amplifier: voltage amplifier with finite gain–bandwidth, slew-rate limit, current limit
  into the quadrant capacitances, rails; piezo strain through optional Coleman–Hodgdon
  hysteresis and a creep chain.
* Detector: optical lever (mirror doubles the angle), quadrant photodiode linear in the
  clean case (erf response of a Gaussian spot as an effect); offsets, drift, noise.

Everything is in SI units. Integration: fixed step (default 0.1 µs) semi-implicit Euler in
one numba kernel; the drive comes from a 1 MS/s arbitrary waveform generator (zero-order
hold) and the file records that generator's output at the file's sample rate.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numba import njit
from scipy.linalg import eigh
from scipy.special import erf

__all__ = [
    "AWG_RATE_HZ",
    "CASES",
    "EFFECT_NAMES",
    "Burst",
    "Case",
    "Effects",
    "Hold",
    "PlantParams",
    "Scan",
    "derived",
    "detector_signals",
    "lab_protocol",
    "protocol_duration",
    "protocol_text",
    "render_drive",
    "simulate",
    "trace_for_case",
    "write_csv_atomic",
    "write_json_atomic",
]

AWG_RATE_HZ = 1_000_000  # function generator update rate (zero-order hold)
EPS0 = 8.8541878128e-12
G_ACC = 9.81


# --------------------------------------------------------------------------------------
# parameters
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlantParams:
    """Physical parameters of the clean plant (SI units).

    Table and tube geometry/material follow the thesis's Table D.1; contact, amplifier
    and detector values are ordinary lab/handbook values (documented per field).
    """

    # table (steel half sphere), Table D.1
    table_radius_m: float = 0.01
    table_density_kg_m3: float = 8.0e3
    # Table D.1 lists m = 0.0335 kg and I = 1.340e-6 kg m^2 (= 2/5 m R^2): the values of a
    # full steel sphere of that radius, although eq. C.1 describes a half sphere. The
    # table's values are used (mirror, holder and preload cap add mass to a half sphere).
    table_mass_kg: float = 0.0335
    table_inertia_kgm2: float = 1.340e-6
    table_youngs_Pa: float = 200e9  # steel
    table_poisson: float = 0.29
    # piezo tubes (PIC 151), Table D.1
    tube_outer_radius_m: float = 3.175e-3
    tube_inner_radius_m: float = 2.667e-3
    tube_length_m: float = 6.35e-3
    tube_youngs_Pa: float = 5.263e10
    tube_poisson: float = 0.31
    tube_density_kg_m3: float = 7.8e3
    tube_shear_coefficient: float = 0.5  # Timoshenko shear factor of a thin-walled tube
    d31_m_per_V: float = -210e-12
    eps11_rel: float = 2400.0
    tube_modal_damping: float = 0.02  # damping ratio of both bending modes
    # alumina balls on the tubes (radius = tube outer radius, seated in the bore)
    ball_density_kg_m3: float = 3.98e3
    ball_youngs_Pa: float = 370e9
    ball_poisson: float = 0.22
    # manufacturing spread per tube A, B, C: d31 factor and friction-coefficient factor
    tube_d31_factor: tuple[float, float, float] = (1.00, 0.97, 1.03)
    contact_mu_factor: tuple[float, float, float] = (1.00, 1.06, 0.95)
    # preload and friction
    preload_N: float = 1.5  # spring on top of the table, along the symmetry axis
    mu_static: float = 0.20  # steel on alumina, dry
    mu_kinetic: float = 0.16
    stribeck_velocity_m_s: float = 5e-4
    # static strength heals/weakens with this lag: mu = mu_k + (mu_s-mu_k)*phi,
    # dphi/dt = (exp(-(v_slip/v_s)^2) - phi)/lag  (frictional lag / contact ageing)
    friction_lag_s: float = 1e-4
    n_elements: int = 8  # Maxwell-slip elements per contact direction
    element_damping_s: float = 6e-6  # stiffness-proportional damping of stuck asperities
    hertz_damping_s_m: float = 120.0  # Hunt–Crossley coefficient (normal mode damping ~9 %)
    # amplifier (HVA 900 as used in the thesis: gain 45, 25 mA)
    amplifier_gain: float = 45.0
    # gain-bandwidth product; closed-loop -3 dB = GBW / gain = 10 kHz (first-order response;
    # the thesis's 'same time to reach the end value for any step' of section 4.1.2)
    amplifier_gain_bandwidth_Hz: float = 450e3
    amplifier_slew_V_per_s: float = 12e6
    amplifier_current_A: float = 25e-3
    amplifier_rail_V: float = 450.0
    cable_capacitance_F: float = 150e-12
    # floor / mount (rocking of the base on its mounts; used by floor_vibration)
    mount_frequency_Hz: float = 95.0
    mount_damping: float = 0.05
    mount_lever_per_m: float = 16.0  # (CoM height above mounts) / (radius of gyration)^2
    mount_projection_xy: tuple[float, float] = (0.8, 0.6)
    # detector (laser + quadrant photodiode), thesis section 4.1
    # the thesis's detector (S = 9.9e-5 m/V, linear within +-0.2 mm), placed closer to the
    # table than the thesis's 0.175 m so that a run of bursts fits the linear range
    detector_distance_m: float = 0.12
    detector_sensitivity_m_per_V: float = 9.9e-5
    detector_range_m: float = 0.2e-3  # half range of linear spot travel
    detector_offset_V: tuple[float, float] = (0.011, -0.007)  # residual after centring
    # numerics
    dt_s: float = 1e-7


@dataclass(frozen=True)
class Effects:
    """Switchable effects. Every default is the neutral value (reproduces the clean plant).

    creep_gains / creep_taus_s: extra strain fractions that arrive with these time
        constants after a voltage change (piezo creep); neutral: all gains 0.
    hysteresis_eta / hysteresis_alpha_per_V: Coleman–Hodgdon dy = a|du|(u-y) + (1-eta)du
        on the strain-equivalent voltage; neutral: eta = 0 (then y = u exactly).
    friction_asymmetry: relative difference of the friction coefficient between the two
        sliding directions, mu(1 +- r/2); neutral 0.
    drift_*: detector offset drift A(1-exp(-t/tau)) + rate t (x), y gets y_fraction of it.
    spot_radius_m: 1/e^2 radius of the Gaussian spot; inf = linear detector (neutral).
    misalignment_deg: rotation of the detector's axes about the beam; neutral 0.
    amplifier_*: the amplifier; None = the plant's value (neutral); slow_amplifier lowers
        the gain-bandwidth, slew rate and current limit.
    floor_*: floor acceleration (sinusoid) rocking the base on its mounts: the tilt adds to
        the angle the detector sees and its angular acceleration acts on the table.
    wear_fraction / wear_distance_m: mu falls by this fraction over the sliding distance
        scale; neutral fraction 0.
    crosstalk_ac / crosstalk_tau_s / crosstalk_dc: HV drive coupling into the detector
        (high-passed dV_out, V per V, plus a DC leak); neutral 0.
    preload_loss / preload_tau_s: relaxation of the preload spring after seating the table.
    """

    creep_gains: tuple[float, float, float] = (0.0, 0.0, 0.0)
    creep_taus_s: tuple[float, float, float] = (4e-3, 40e-3, 0.4)
    hysteresis_eta: float = 0.0
    hysteresis_alpha_per_V: float = 0.04
    friction_asymmetry: float = 0.0
    drift_amplitude_V: float = 0.0
    drift_tau_s: float = 1.5
    drift_rate_V_s: float = 0.0
    drift_y_fraction: float = 0.6
    floor_accel_m_s2: float = 0.0
    floor_frequency_Hz: float = 80.0
    spot_radius_m: float = math.inf
    misalignment_deg: float = 0.0
    amplifier_gain_bandwidth_Hz: float | None = None
    amplifier_slew_V_per_s: float | None = None
    amplifier_current_A: float | None = None
    wear_fraction: float = 0.0
    wear_distance_m: float = 40e-6
    crosstalk_ac: float = 0.0
    crosstalk_tau_s: float = 3e-4
    crosstalk_dc: float = 0.0
    crosstalk_y_fraction: float = 0.4
    preload_loss: float = 0.0
    preload_tau_s: float = 0.9


EFFECT_NAMES = (
    "creep",
    "hysteresis",
    "friction_asymmetry",
    "sensor_drift",
    "floor_vibration",
    "detector_nonlinearity",
    "axis_misalignment",
    "slow_amplifier",
    "contact_wear",
    "drive_crosstalk",
    "preload_creep",
)

# which Effects fields belong to which named effect (for truth.json)
EFFECT_FIELDS = {
    "creep": ("creep_gains", "creep_taus_s"),
    "hysteresis": ("hysteresis_eta", "hysteresis_alpha_per_V"),
    "friction_asymmetry": ("friction_asymmetry",),
    "sensor_drift": ("drift_amplitude_V", "drift_tau_s", "drift_rate_V_s", "drift_y_fraction"),
    "floor_vibration": ("floor_accel_m_s2", "floor_frequency_Hz"),
    "detector_nonlinearity": ("spot_radius_m",),
    "axis_misalignment": ("misalignment_deg",),
    "slow_amplifier": (
        "amplifier_gain_bandwidth_Hz",
        "amplifier_slew_V_per_s",
        "amplifier_current_A",
    ),
    "contact_wear": ("wear_fraction", "wear_distance_m"),
    "drive_crosstalk": ("crosstalk_ac", "crosstalk_tau_s", "crosstalk_dc", "crosstalk_y_fraction"),
    "preload_creep": ("preload_loss", "preload_tau_s"),
}

# driven tubes (p, q) and passive tube r per rotation axis, (e_p, e_r, e_q) right-handed
_AXIS_TUBES = {"A": (2, 1, 0), "B": (0, 2, 1), "C": (1, 0, 2)}  # (p, q, r) as 0=A,1=B,2=C


def derived(p: PlantParams) -> dict[str, float]:
    """Quantities computed from the parameters (masses, stiffnesses, modes, contacts)."""
    ro, ri, L = p.tube_outer_radius_m, p.tube_inner_radius_m, p.tube_length_m
    h = ro - ri
    d_mean = ro + ri
    area = math.pi * (ro**2 - ri**2)
    ei = p.tube_youngs_Pa * math.pi * (ro**4 - ri**4) / 4.0
    g_tube = p.tube_youngs_Pa / (2.0 * (1.0 + p.tube_poisson))
    # asymmetric (one quadrant) bending: R_bend = pi D h / (2 sqrt2 |d31| V)  (eq. 2.12)
    r_bend_Vm = math.pi * d_mean * h / (2.0 * math.sqrt(2.0) * abs(p.d31_m_per_V))
    m_table = p.table_mass_kg
    i_table = p.table_inertia_kgm2
    m_ball = p.ball_density_kg_m3 * 4.0 / 3.0 * math.pi * ro**3
    j_ball = 0.4 * m_ball * ro**2
    e_ball = math.sqrt(ro**2 - ri**2)  # ball centre above the tube end (seated in bore)
    h_contact = e_ball + ro  # contact point above the tube end
    # tip flexibility (translation, rotation) of a shear-deformable cantilever
    flex = np.array(
        [
            [L**3 / (3 * ei) + L / (p.tube_shear_coefficient * g_tube * area), L**2 / (2 * ei)],
            [L**2 / (2 * ei), L / ei],
        ]
    )
    k_tip = np.linalg.inv(flex)
    m_beam = p.tube_density_kg_m3 * area * L
    m_tip = (
        m_beam / 420.0 * np.array([[156.0, -22.0 * L], [-22.0 * L, 4.0 * L**2]])
        + m_ball * np.array([[1.0, e_ball], [e_ball, e_ball**2]])
        + j_ball * np.diag([0.0, 1.0])
    )
    w2, phi = eigh(k_tip, m_tip)  # mass-normalised: phi.T m phi = I
    cvec = np.array([1.0, h_contact])
    c_quad = p.eps11_rel * EPS0 * (math.pi * d_mean * L / 4.0) / h
    # Hertz contact, steel sphere on alumina ball
    r_star = p.table_radius_m * ro / (p.table_radius_m + ro)
    e_star = 1.0 / (
        (1 - p.table_poisson**2) / p.table_youngs_Pa + (1 - p.ball_poisson**2) / p.ball_youngs_Pa
    )
    g1 = p.table_youngs_Pa / (2 * (1 + p.table_poisson))
    g2 = p.ball_youngs_Pa / (2 * (1 + p.ball_poisson))
    k_hertz = 4.0 / 3.0 * e_star * math.sqrt(r_star)
    f_ext0 = (p.preload_N + m_table * G_ACC) / math.sqrt(3.0)  # per contact, along its axis
    delta0 = (f_ext0 / k_hertz) ** (2.0 / 3.0)
    a0 = math.sqrt(r_star * delta0)
    compliance_t = (2 - p.table_poisson) / g1 + (2 - p.ball_poisson) / g2
    k_t = 8.0 * a0 / compliance_t  # Mindlin tangential stiffness
    k_spin = 16.0 / 3.0 * a0**3 / (1.0 / g1 + 1.0 / g2)
    return {
        "wall_thickness_m": h,
        "mean_diameter_m": d_mean,
        "bending_EI_Nm2": ei,
        "bending_radius_times_V_m": r_bend_Vm,
        "table_mass_kg": m_table,
        "table_inertia_kgm2": i_table,
        "ball_mass_kg": m_ball,
        "ball_inertia_kgm2": j_ball,
        "ball_centre_above_tube_m": e_ball,
        "contact_above_tube_m": h_contact,
        "tube_tip_stiffness_N_m": float(1.0 / (cvec @ flex @ cvec)),
        "tube_mode_frequencies_Hz": [float(x) for x in np.sqrt(w2) / (2 * math.pi)],
        "mode_shapes": phi,
        "mode_omega": np.sqrt(w2),
        "contact_gain": cvec @ phi,  # contact displacement per modal coordinate
        "moment_gain": phi[1, :].copy(),  # modal force per unit tip moment
        "contact_disp_per_output_V_m": L / r_bend_Vm * (L / 2.0 + h_contact),
        "axial_per_output_V_m": p.d31_m_per_V * L / (4.0 * h),
        "quadrant_capacitance_F": c_quad,
        "load_capacitance_F": 2.0 * c_quad + p.cable_capacitance_F,
        "hertz_constant_N_m1_5": k_hertz,
        "normal_force_N": f_ext0,
        "hertz_penetration_m": delta0,
        "contact_radius_m": a0,
        "tangential_stiffness_N_m": k_t,
        "mindlin_slip_displacement_m": 3.0 * p.mu_static * f_ext0 / (2.0 * k_t),
        "spin_stiffness_Nm_rad": k_spin,
    }


def _iwan_bank(n: int, k_t: float) -> tuple[np.ndarray, np.ndarray]:
    """Element stiffnesses and strength fractions reproducing Mindlin's loading curve.

    Virgin curve F/(mu N) = 1 - (1 - d/d*)^(3/2); slope k_t sqrt(1 - d/d*). Element i
    breaks at d* i/n and carries the slope drop across it.
    """
    edges = np.arange(n + 1) / n
    slope = np.sqrt(1.0 - edges)
    k = k_t * (slope[:-1] - slope[1:])
    w = k * edges[1:]
    return k, w / w.sum()


# --------------------------------------------------------------------------------------
# protocol
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Hold:
    duration_s: float


@dataclass(frozen=True)
class Scan:
    duration_s: float
    to_V: float  # base level at the end (amplifier input volts)


@dataclass(frozen=True)
class Burst:
    frequency_Hz: float
    amplitude_V: float
    ramp_ratio: float
    direction: int  # +1: slow rise/fast fall above base; -1: mirrored below base
    periods: int

    @property
    def duration_s(self) -> float:
        return self.periods / self.frequency_Hz


Segment = Hold | Scan | Burst


def protocol_duration(segments: list[Segment]) -> float:
    return float(sum(s.duration_s for s in segments))


def render_drive(segments: list[Segment], rate_hz: float = AWG_RATE_HZ) -> np.ndarray:
    """Generator output (amplifier input volts) at ``rate_hz``, sample k at t = k/rate.

    The output runs 10 ms past the protocol's end (holding the last level).
    """
    n_total = round((protocol_duration(segments) + 0.01) * rate_hz) + 1
    out = np.zeros(n_total)
    base = 0.0
    t0 = 0.0
    for seg in segments:
        k0 = round(t0 * rate_hz)
        k1 = round((t0 + seg.duration_s) * rate_hz)
        tl = (np.arange(k0, k1) / rate_hz) - t0
        if isinstance(seg, Hold):
            out[k0:k1] = base
        elif isinstance(seg, Scan):
            out[k0:k1] = base + (seg.to_V - base) * tl / seg.duration_s
            base = seg.to_V
        else:
            ph = np.mod(tl * seg.frequency_Hz, 1.0)
            a = seg.ramp_ratio
            shape = np.where(ph < a, ph / a, (1.0 - ph) / (1.0 - a))
            out[k0:k1] = base + seg.direction * seg.amplitude_V * shape
        t0 += seg.duration_s
    out[round(t0 * rate_hz) :] = base
    return out


def protocol_text(segments: list[Segment]) -> str:
    parts = []
    for s in segments:
        if isinstance(s, Hold):
            parts.append(f"hold {s.duration_s * 1e3:.0f}ms")
        elif isinstance(s, Scan):
            parts.append(f"scan->{s.to_V:+.2f}V/{s.duration_s * 1e3:.0f}ms")
        else:
            d = "fwd" if s.direction > 0 else "bwd"
            parts.append(
                f"burst {d} {s.amplitude_V:g}V {s.frequency_Hz:g}Hz a={s.ramp_ratio:g} x{s.periods}"
            )
    return "; ".join(parts)


def pretest_step(
    p: PlantParams,
    amp: float,
    freq: float,
    ratio: float,
    direction: int,
    effects: Effects | None = None,
) -> float:
    """Rim displacement per period of a short burst from rest (the lab's quick pre-test)."""
    e = mechanical_effects(effects)
    key = (p, e, amp, freq, ratio, direction)
    if key not in _PRETEST:
        n = 4 if freq >= 200 else 2
        segs: list[Segment] = [Hold(0.001), Burst(freq, amp, ratio, direction, n), Hold(0.004)]
        sim = simulate(render_drive(segs), 100_000.0, protocol_duration(segs), params=p,
                       effects=e)  # fmt: skip
        r = sim["rim_m"]
        _PRETEST[key] = float((r[-100:].mean() - r[:50].mean()) / n)
    return _PRETEST[key]


def mechanical_effects(effects: Effects | None) -> Effects:
    """The effects that change how the table moves (detector-side ones set neutral)."""
    e = effects or Effects()
    neutral = Effects()
    return replace(
        e,
        drift_amplitude_V=neutral.drift_amplitude_V,
        drift_rate_V_s=neutral.drift_rate_V_s,
        floor_accel_m_s2=neutral.floor_accel_m_s2,
        spot_radius_m=neutral.spot_radius_m,
        misalignment_deg=neutral.misalignment_deg,
        crosstalk_ac=neutral.crosstalk_ac,
        crosstalk_dc=neutral.crosstalk_dc,
    )


_PRETEST: dict[tuple, float] = {}


def lab_protocol(
    seed: int,
    params: PlantParams | None = None,
    pretest: bool = True,
    effects: Effects | None = None,
) -> list[Segment]:
    """A characterisation run as a lab would script it (2.35–2.65 s).

    Baseline hold; a slow scan up, down through zero and back (tube bending in stick);
    then stepping bursts that cycle through amplitudes 2–6 V and frequencies 50 Hz–2 kHz
    in shuffled orders, with ramp ratios 0.6–0.99 (three in four with a flyback of at most
    60 µs where the list allows), separated by holds of
    15–130 ms (the first one 90 ms); directions are random, flipped only when the expected
    position would leave 50 % of the detector range; a block of bursts at a scanned
    offset; a closing scan pair and a final hold that pads the total. The expected
    position uses each setting's step from a short pre-test on the stage (``pretest``;
    the plant with ``effects`` that change the motion), as an operator would know it
    from the scope, or else the ideal step (tube stroke, no back-slip) with the drive's
    sign. The same seed and the same mechanical effects give the same protocol.
    """
    p = params or PlantParams()
    rng = np.random.default_rng(seed)
    d = derived(p)
    step_per_V = d["contact_disp_per_output_V_m"] * p.amplifier_gain  # rim metres / input V
    rim_range = p.detector_range_m / (2.0 * p.detector_distance_m) * p.table_radius_m
    limit = 0.5 * rim_range

    def expected(a: float, f: float, r: float, direction: int) -> float:
        if pretest:
            return pretest_step(p, a, f, r, direction, effects)
        return direction * a * step_per_V

    target = float(rng.uniform(2.35, 2.65))

    segs: list[Segment] = [Hold(0.06)]
    up = float(rng.choice([2.0, 2.5, 3.0]))
    rate = float(rng.choice([30.0, 40.0]))  # V/s
    segs += [Scan(up / rate, up), Hold(0.05), Scan(2 * up / rate, -up), Hold(0.04)]
    segs += [Scan(up / rate, 0.0), Hold(0.07)]
    end = float(rng.choice([1.5, 2.0]))
    closing: list[Segment] = [Scan(end / rate, -end), Hold(0.04), Scan(end / rate, 0.0)]
    offset = float(rng.choice([-1.5, 1.5]))
    offset_cost = 2 * (abs(offset) / rate) + 0.05 + 0.06

    amps = [2.0, 3.0, 4.5, 6.0]
    freqs = [50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0]
    ratios = [0.6, 0.75, 0.9, 0.95, 0.97, 0.98, 0.99]
    holds = [0.015, 0.025, 0.04, 0.06, 0.09, 0.13]
    amp_seq = [a for _ in range(8) for a in rng.permutation(amps)]
    freq_seq = [f for _ in range(6) for f in rng.permutation(freqs)]
    pos = 0.0
    base = 0.0
    j = 0
    offset_at = int(rng.integers(5, 8))
    offset_left = 0
    reserve = protocol_duration(closing) + offset_cost + 0.06
    while True:
        a, f = float(amp_seq[j]), float(freq_seq[j])
        if rng.uniform() < 0.75:
            # usually a ratio whose flyback is short enough to step (<= 60 us if possible)
            fast = [x for x in ratios if (1.0 - x) / f <= 60e-6]
            r = float(rng.choice(fast)) if fast else max(ratios)
        else:
            r = float(rng.choice(ratios))
        n = int(np.clip(round(f * rng.uniform(0.005, 0.05)), 3, 25))
        hold = 0.09 if j == 0 else float(rng.choice(holds))
        cost = n / f + hold
        if protocol_duration(segs) + cost + reserve > target:
            break
        if j == offset_at:
            base = offset
            segs += [Scan(abs(base) / rate, base), Hold(0.05)]
            offset_left = 4
            reserve -= offset_cost - 0.06 - abs(offset) / rate
        direction = int(rng.choice([-1, 1]))
        if abs(pos + n * expected(a, f, r, direction)) > limit:
            direction = -direction
        move = expected(a, f, r, direction)
        if abs(pos + n * move) > limit:
            # neither direction fits: take the one towards the centre, fewer periods
            move_back = expected(a, f, r, -direction)
            if abs(pos + n * move_back) < abs(pos + n * move):
                direction, move = -direction, move_back
            if move != 0.0:
                n = max(1, min(n, int((limit - np.sign(move) * pos) / abs(move))))
        pos += n * move
        segs += [Burst(f, a, r, direction, n), Hold(hold)]
        j += 1
        if offset_left:
            offset_left -= 1
            if offset_left == 0:
                segs += [Scan(abs(base) / rate, 0.0), Hold(0.06)]
                base = 0.0
                reserve = protocol_duration(closing) + 0.06
    if base != 0.0:
        segs += [Scan(abs(base) / rate, 0.0), Hold(0.06)]
    segs += closing
    segs.append(Hold(round(max(0.06, target - protocol_duration(segs)), 3)))
    return segs


# --------------------------------------------------------------------------------------
# kernel
# --------------------------------------------------------------------------------------
PNAMES = (
    "gain", "tau_amp", "slew", "imax", "cload", "rail",
    "hyst_eta", "hyst_alpha", "cg0", "cg1", "cg2", "ct0", "ct1", "ct2",
    "curv_p", "curv_q", "axial_p", "axial_q", "ei",
    "radius", "inertia", "mass", "fext_table", "fpre", "pre_loss", "pre_tau",
    "k_hertz", "hc_chi", "delta0",
    "mu_s", "mu_k", "v_s", "tau_lag", "mu_fac_p", "mu_fac_q", "mu_fac_r", "asym", "beta_el",
    "wear_frac", "wear_dist",
    "k_spin", "a_coef",
    "zeta_t",
    "mount_w", "mount_z", "mount_lever", "proj_x", "proj_y", "floor_acc", "floor_w",
    "xt_ac", "xt_tau",
    "init_thd", "init_eta",
)  # fmt: skip
NOUT = 12  # theta, phi_x, phi_y, v_out, crosstalk, v_eff, y_p, y_q, n_p, n_q, energy, slid


@njit(cache=True)
def _iwan_step(z, kel, wel, du, dt, normal, mu, asym, beta):
    """Advance one Maxwell-slip bank by the displacement increment du.

    Element i is a spring kel[i] in series with a Coulomb slider of strength
    wel[i]*mu*normal (times 1 +- asym by the sign of the element's load). Returns the
    force and the strength-weighted slider travel of this step.
    """
    force = 0.0
    slid = 0.0
    for i in range(kel.shape[0]):
        zi = z[i] + du
        cap = wel[i] * mu * normal
        if zi > 0.0:
            cap *= 1.0 + asym
        else:
            cap *= 1.0 - asym
        lim = cap / kel[i]
        if zi > lim:
            slid += wel[i] * (zi - lim)
            zi = lim
        elif zi < -lim:
            slid += wel[i] * (-lim - zi)
            zi = -lim
        force += kel[i] * zi + beta * kel[i] * (zi - z[i]) / dt
        z[i] = zi
    return force, slid


# The kernel's phases below are inlined into it (inline="always") and pass the state as
# tuples where they can: numba reference-counts every array argument at each call, and
# with arrays for all the state and no inlining the kernel ran 2x slower. The tuples:
#   amp = (v_out, v_h, v_eff, crosstalk)        amplifier output, hysteresis, piezo, xtalk
#   q = (th, thd, x1, x1d, x2, x2d, phx, phxd, phy, phyd)   table and mount
#   nf = (d1, d2, n1, n2, fext)                 Hertz penetrations and normal forces
# P is the parameter tuple (PNAMES order); modal = (omega, cgain, mgain), two modes each.
_PHI, _SLIP_RATE, _U_PREV, _U_NOW, _FORCE = range(5)  # rows of the per-contact array


@njit(cache=True, inline="always")
def _drive_step(P, amp, wc, cdec, vin, dt):
    """Generator -> amplifier -> hysteresis -> creep for one step.

    wc holds the creep chain's states and cdec their per-step decay factors. Returns the
    new amp and wc and the rate of v_eff over the step.
    """
    gain, tau_amp, slew, imax, cload, rail, hyst_eta, hyst_alpha, cg0, cg1, cg2 = P[0:11]
    xt_ac, xt_tau = P[50:52]
    v_out, v_h, v_eff, xt = amp
    slew_lim = min(slew, imax / cload)
    inv_tau = 1.0 / tau_amp
    dv = (gain * vin - v_out) * inv_tau
    if dv > slew_lim:
        dv = slew_lim
    elif dv < -slew_lim:
        dv = -slew_lim
    v_new = v_out + dv * dt
    if v_new > rail:
        v_new = rail
    elif v_new < -rail:
        v_new = -rail
    d_out = v_new - v_out
    if hyst_eta != 0.0:
        v_h += hyst_alpha * abs(d_out) * (v_out - v_h) + (1.0 - hyst_eta) * d_out
    else:
        v_h = v_new
    xt += xt_ac * d_out - xt * dt / xt_tau
    v_eff_new = v_h
    if cg0 != 0.0 or cg1 != 0.0 or cg2 != 0.0:
        w0, w1, w2 = wc
        w0 += (v_h - w0) * cdec[0]
        v_eff_new += cg0 * w0
        w1 += (v_h - w1) * cdec[1]
        v_eff_new += cg1 * w1
        w2 += (v_h - w2) * cdec[2]
        v_eff_new += cg2 * w2
        wc = (w0, w1, w2)
    return (v_new, v_h, v_eff_new, xt), wc, (v_eff_new - v_eff) / dt


@njit(cache=True, inline="always")
def _contact_displacements(P, q, eta, modal, con):
    """Tangential displacement at each contact into con[_U_NOW]; returns the tube tips'
    deflections y1, y2."""
    radius, delta0 = P[19], P[28]
    cgain = modal[1]
    th, x1, x2 = q[0], q[2], q[4]
    y1 = cgain[0] * eta[0, 0] + cgain[1] * eta[0, 1]
    y2 = cgain[0] * eta[1, 0] + cgain[1] * eta[1, 1]
    con[_U_NOW, 0] = y1 + (x2 - delta0) - radius * th
    con[_U_NOW, 1] = y2 - (x1 - delta0) - radius * th
    con[_U_NOW, 2] = x1 - delta0
    con[_U_NOW, 3] = x2 - delta0
    return y1, y2


@njit(cache=True, inline="always")
def _normal_forces(P, q, v_eff, v_eff_rate, t):
    """Hertz + Hunt-Crossley normal forces of the driven contacts and the preload's share
    along each translation axis: nf = (d1, d2, n1, n2, fext)."""
    axial_p, axial_q = P[16:18]
    fext_table, fpre, pre_loss, pre_tau, k_hertz, hc_chi = P[22:28]
    x1, x1d, x2, x2d = q[2:6]
    eps1 = axial_p * v_eff
    eps2 = axial_q * v_eff
    d1 = x1 + eps1
    d2 = x2 + eps2
    n1 = 0.0
    if d1 > 0.0:
        n1 = k_hertz * d1 * math.sqrt(d1) * (1.0 + hc_chi * (x1d + axial_p * v_eff_rate))
        if n1 < 0.0:
            n1 = 0.0
    n2 = 0.0
    if d2 > 0.0:
        n2 = k_hertz * d2 * math.sqrt(d2) * (1.0 + hc_chi * (x2d + axial_q * v_eff_rate))
        if n2 < 0.0:
            n2 = 0.0
    fpre_t = fpre
    if pre_loss != 0.0:
        fpre_t = fpre * (1.0 - pre_loss * (1.0 - math.exp(-t / pre_tau)))
    fext = (fpre_t + fext_table) * 0.5773502691896258
    return d1, d2, n1, n2, fext


@njit(cache=True, inline="always")
def _tangential_forces(P, z, con, s_wear, kel, wel, nf, dt):
    """Maxwell-slip forces of the four contacts (into con[_FORCE]) with frictional lag and
    wear. s_wear is the driven contacts' slid distances; returns it updated and this
    step's slider travel of the driven contacts."""
    mu_s, mu_k, v_s, tau_lag, mu_fac_p, mu_fac_q, mu_fac_r, asym, beta_el = P[29:38]
    wear_frac, wear_dist = P[38:40]
    n1, n2, fext = nf[2:5]
    lag = dt / tau_lag
    wear1 = 1.0
    wear2 = 1.0
    if wear_frac != 0.0:
        wear1 = 1.0 - wear_frac * (1.0 - math.exp(-s_wear[0] / wear_dist))
        wear2 = 1.0 - wear_frac * (1.0 - math.exp(-s_wear[1] / wear_dist))
    sl1 = 0.0
    sl2 = 0.0
    normals = (n1, n2, fext, fext)
    mu_fac = (mu_fac_p * wear1, mu_fac_q * wear2, mu_fac_r, mu_fac_r)
    for c in range(4):
        phi = con[_PHI, c]
        phi += (math.exp(-((con[_SLIP_RATE, c] / v_s) ** 2)) - phi) * lag
        con[_PHI, c] = phi
        mu_c = (mu_k + (mu_s - mu_k) * phi) * mu_fac[c]
        asym_c = asym if c < 2 else 0.0
        du = con[_U_NOW, c] - con[_U_PREV, c]
        con[_FORCE, c], sl_c = _iwan_step(z[c], kel, wel, du, dt, normals[c], mu_c, asym_c,
                                          beta_el)  # fmt: skip
        con[_SLIP_RATE, c] = sl_c / dt
        con[_U_PREV, c] = con[_U_NOW, c]
        if c == 0:
            sl1 = sl_c
        elif c == 1:
            sl2 = sl_c
    return (s_wear[0] + sl1, s_wear[1] + sl2), sl1 + sl2


@njit(cache=True, inline="always")
def _spin_torque(P, m_spin, dth, fext):
    """Dahl spin-friction torque of the passive contact after a rotation step dth."""
    mu_s, mu_fac_r, k_spin, a_coef = P[29], P[35], P[40], P[41]
    m_cap = a_coef * mu_s * mu_fac_r * fext * (fext ** (1.0 / 3.0))
    if dth != 0.0:
        sg = 1.0 if dth > 0.0 else -1.0
        m_spin += k_spin * dth * (1.0 - m_spin / m_cap * sg)
        if m_spin > m_cap:
            m_spin = m_cap
        elif m_spin < -m_cap:
            m_spin = -m_cap
    return m_spin


@njit(cache=True, inline="always")
def _energy(P, q, eta, etad, modal, z, kel, nf, m_spin):
    """The plant's mechanical energy (kinetic, modal, Hertz, preload work, slip springs)."""
    inertia, mass, k_hertz, k_spin = P[20], P[21], P[26], P[40]
    omega = modal[0]
    d1, d2, fext = nf[0], nf[1], nf[4]
    thd, x1, x1d, x2, x2d = q[1:6]
    en = 0.5 * inertia * thd * thd + 0.5 * mass * (x1d * x1d + x2d * x2d)
    for tb in range(2):
        for m in range(2):
            en += 0.5 * etad[tb, m] ** 2 + 0.5 * (omega[m] * eta[tb, m]) ** 2
    if d1 > 0.0:
        en += 0.4 * k_hertz * d1 * d1 * math.sqrt(d1)
    if d2 > 0.0:
        en += 0.4 * k_hertz * d2 * d2 * math.sqrt(d2)
    en -= fext * (x1 + x2)
    for c in range(4):
        for i in range(kel.shape[0]):
            en += 0.5 * kel[i] * z[c, i] ** 2
    en += 0.5 * m_spin * m_spin / k_spin
    return en


@njit(cache=True, inline="always")
def _tube_step(P, eta, etad, modal, con, v_eff, dt):
    """Semi-implicit Euler step of the two driven tubes' bending modes (eta, etad)."""
    curv_p, curv_q, _, _, ei = P[14:19]
    zeta_t = P[42]
    omega, cgain, mgain = modal
    f1 = con[_FORCE, 0]
    f2 = con[_FORCE, 1]
    mp1 = ei * curv_p * v_eff
    mp2 = ei * curv_q * v_eff
    for m in range(2):
        a0 = (mgain[m] * mp1 - cgain[m] * f1 - 2.0 * zeta_t * omega[m] * etad[0, m]
              - omega[m] * omega[m] * eta[0, m])  # fmt: skip
        a1 = (mgain[m] * mp2 - cgain[m] * f2 - 2.0 * zeta_t * omega[m] * etad[1, m]
              - omega[m] * omega[m] * eta[1, m])  # fmt: skip
        etad[0, m] += a0 * dt
        etad[1, m] += a1 * dt
        eta[0, m] += etad[0, m] * dt
        eta[1, m] += etad[1, m] * dt


@njit(cache=True, inline="always")
def _table_step(P, q, con, nf, m_spin, t, dt):
    """Semi-implicit Euler step of the table (rotation, two translations) and the mount
    tilt; returns the new q."""
    radius, inertia, mass = P[19:22]
    mount_w, mount_z, mount_lever, proj_x, proj_y, floor_acc, floor_w = P[43:50]
    n1, n2, fext = nf[2:5]
    th, thd, x1, x1d, x2, x2d, phx, phxd, phy, phyd = q
    f1, f2, fb1, fb2 = con[_FORCE, 0], con[_FORCE, 1], con[_FORCE, 2], con[_FORCE, 3]
    mount_acc_x = 0.0
    mount_acc_y = 0.0
    if floor_acc != 0.0:
        af = floor_acc * math.sin(floor_w * t)
        mount_acc_x = (-2.0 * mount_z * mount_w * phxd - mount_w * mount_w * phx
                       - mount_lever * proj_x * af)  # fmt: skip
        mount_acc_y = (-2.0 * mount_z * mount_w * phyd - mount_w * mount_w * phy
                       - mount_lever * proj_y * af)  # fmt: skip
    thdd = (radius * (f1 + f2) - m_spin) / inertia - mount_acc_x
    x1dd = (fext - n1 + f2 - fb1) / mass
    x2dd = (fext - n2 - f1 - fb2) / mass
    thd += thdd * dt
    th += thd * dt
    x1d += x1dd * dt
    x1 += x1d * dt
    x2d += x2dd * dt
    x2 += x2d * dt
    phxd += mount_acc_x * dt
    phx += phxd * dt
    phyd += mount_acc_y * dt
    phy += phyd * dt
    return (th, thd, x1, x1d, x2, x2d, phx, phxd, phy, phyd)


@njit(cache=True)
def _kernel(awg, n_per_awg, dt, n_samples, n_sub, P, kel, wel, modal, out):
    """Integrate n_samples * n_sub steps of dt, recording the NOUT outputs into out every
    n_sub steps (the state at t = step*dt)."""
    ct0, ct1, ct2 = P[11:14]
    delta0, init_thd, init_eta = P[28], P[52], P[53]
    amp = (0.0, 0.0, 0.0, 0.0)
    wc = (0.0, 0.0, 0.0)  # creep chain
    cdec = (1.0 - math.exp(-dt / ct0), 1.0 - math.exp(-dt / ct1), 1.0 - math.exp(-dt / ct2))
    q = (0.0, init_thd, delta0, 0.0, delta0, 0.0, 0.0, 0.0, 0.0, 0.0)
    eta = np.zeros((2, 2))  # modal coordinates of the two driven tubes
    etad = np.zeros((2, 2))
    eta[0, 0] = init_eta
    z = np.zeros((4, kel.shape[0]))  # Maxwell-slip element deflections per contact
    con = np.zeros((5, 4))  # per contact: age state, slip rate, u_prev, u_now, force
    con[_PHI, :] = 1.0  # contact age: 1 = fully static (healed), -> kinetic in slip
    s_wear = (0.0, 0.0)
    slid_tot = 0.0
    m_spin = 0.0
    th_prev = 0.0
    for step in range(n_samples * n_sub):
        t = step * dt
        amp, wc, v_eff_rate = _drive_step(P, amp, wc, cdec, awg[step // n_per_awg], dt)
        y1, y2 = _contact_displacements(P, q, eta, modal, con)
        nf = _normal_forces(P, q, amp[2], v_eff_rate, t)
        s_wear, sl = _tangential_forces(P, z, con, s_wear, kel, wel, nf, dt)
        slid_tot += sl
        m_spin = _spin_torque(P, m_spin, q[0] - th_prev, nf[4])
        th_prev = q[0]
        if step % n_sub == 0:  # record the state at t
            k = step // n_sub
            en = _energy(P, q, eta, etad, modal, z, kel, nf, m_spin)
            out[k, 0], out[k, 1], out[k, 2] = q[0], q[6], q[8]  # theta, phi_x, phi_y
            out[k, 3], out[k, 4], out[k, 5] = amp[0], amp[3], amp[2]  # v_out, xtalk, v_eff
            out[k, 6], out[k, 7], out[k, 8], out[k, 9] = y1, y2, nf[2], nf[3]
            out[k, 10], out[k, 11] = en, slid_tot
        _tube_step(P, eta, etad, modal, con, amp[2], dt)
        q = _table_step(P, q, con, nf, m_spin, t, dt)


# --------------------------------------------------------------------------------------
# simulation front end
# --------------------------------------------------------------------------------------
def _param_vector(
    p: PlantParams, e: Effects, axis: str, init_thd: float, init_eta: float
) -> np.ndarray:
    d = derived(p)
    ip, iq, ir = _AXIS_TUBES[axis]
    bw = (
        e.amplifier_gain_bandwidth_Hz
        if e.amplifier_gain_bandwidth_Hz is not None
        else p.amplifier_gain_bandwidth_Hz
    )
    slew = (
        e.amplifier_slew_V_per_s
        if e.amplifier_slew_V_per_s is not None
        else (p.amplifier_slew_V_per_s)
    )
    imax = e.amplifier_current_A if e.amplifier_current_A is not None else p.amplifier_current_A
    curv = 1.0 / d["bending_radius_times_V_m"]
    vals = {
        "gain": p.amplifier_gain,
        "tau_amp": p.amplifier_gain / (2.0 * math.pi * bw),
        "slew": slew,
        "imax": imax,
        "cload": d["load_capacitance_F"],
        "rail": p.amplifier_rail_V,
        "hyst_eta": e.hysteresis_eta,
        "hyst_alpha": e.hysteresis_alpha_per_V,
        "cg0": e.creep_gains[0],
        "cg1": e.creep_gains[1],
        "cg2": e.creep_gains[2],
        "ct0": e.creep_taus_s[0],
        "ct1": e.creep_taus_s[1],
        "ct2": e.creep_taus_s[2],
        "curv_p": curv * p.tube_d31_factor[ip],
        "curv_q": curv * p.tube_d31_factor[iq],
        "axial_p": d["axial_per_output_V_m"] * p.tube_d31_factor[ip],
        "axial_q": d["axial_per_output_V_m"] * p.tube_d31_factor[iq],
        "ei": d["bending_EI_Nm2"],
        "radius": p.table_radius_m,
        "inertia": d["table_inertia_kgm2"],
        "mass": d["table_mass_kg"],
        "fext_table": d["table_mass_kg"] * G_ACC,
        "fpre": p.preload_N,
        "pre_loss": e.preload_loss,
        "pre_tau": e.preload_tau_s,
        "k_hertz": d["hertz_constant_N_m1_5"],
        "hc_chi": p.hertz_damping_s_m,
        "delta0": d["hertz_penetration_m"],
        "mu_s": p.mu_static,
        "mu_k": p.mu_kinetic,
        "v_s": p.stribeck_velocity_m_s,
        "tau_lag": p.friction_lag_s,
        "mu_fac_p": p.contact_mu_factor[ip],
        "mu_fac_q": p.contact_mu_factor[iq],
        "mu_fac_r": p.contact_mu_factor[ir],
        "asym": 0.5 * e.friction_asymmetry,
        "beta_el": p.element_damping_s,
        "wear_frac": e.wear_fraction,
        "wear_dist": e.wear_distance_m,
        "k_spin": d["spin_stiffness_Nm_rad"],
        # spin strength 3*pi/16 * mu * N * a, with a = a0 (N/N0)^(1/3)
        "a_coef": 3.0 * math.pi / 16.0 * d["contact_radius_m"] / d["normal_force_N"] ** (1 / 3),
        "zeta_t": p.tube_modal_damping,
        "mount_w": 2.0 * math.pi * p.mount_frequency_Hz,
        "mount_z": p.mount_damping,
        "mount_lever": p.mount_lever_per_m,
        "proj_x": p.mount_projection_xy[0],
        "proj_y": p.mount_projection_xy[1],
        "floor_acc": e.floor_accel_m_s2,
        "floor_w": 2.0 * math.pi * e.floor_frequency_Hz,
        "xt_ac": e.crosstalk_ac,
        "xt_tau": e.crosstalk_tau_s,
        "init_thd": init_thd,
        "init_eta": init_eta,
    }
    assert set(vals) == set(PNAMES)
    return np.array([float(vals[n]) for n in PNAMES])


def simulate(
    drive_awg: np.ndarray,
    sample_rate_hz: float,
    duration_s: float,
    *,
    params: PlantParams | None = None,
    effects: Effects | None = None,
    axis: str = "B",
    dt_s: float | None = None,
    init_table_rate_rad_s: float = 0.0,
    init_tube_mode: float = 0.0,
) -> dict[str, np.ndarray]:
    """Integrate the plant for ``duration_s`` and return signals at ``sample_rate_hz``.

    ``drive_awg`` is the generator output at :data:`AWG_RATE_HZ` (amplifier input volts);
    it must cover the duration. The sample rate must divide the generator rate, and the
    step ``dt_s`` must divide the generator's period.
    """
    p = params or PlantParams()
    e = effects or Effects()
    if axis not in _AXIS_TUBES:
        raise ValueError(f"axis must be A, B or C, not {axis!r}")
    dt = p.dt_s if dt_s is None else dt_s
    n_per_awg = round(1.0 / (AWG_RATE_HZ * dt))
    if n_per_awg < 1 or abs(n_per_awg * dt * AWG_RATE_HZ - 1.0) > 1e-9:
        raise ValueError("dt must divide the generator period")
    n_sub = round(1.0 / (sample_rate_hz * dt))
    if abs(n_sub * dt * sample_rate_hz - 1.0) > 1e-9:
        raise ValueError("the sample period must be a multiple of dt")
    if AWG_RATE_HZ % round(sample_rate_hz) != 0:
        raise ValueError("the sample rate must divide the generator rate")
    n_samples = math.floor(duration_s * sample_rate_hz + 1e-6)
    need = (n_samples * n_sub - 1) // n_per_awg + 1
    awg = np.ascontiguousarray(drive_awg, dtype=np.float64)
    if awg.shape[0] < need:
        raise ValueError("drive shorter than the requested duration")
    d = derived(p)
    kel, wel = _iwan_bank(p.n_elements, d["tangential_stiffness_N_m"])
    pv = _param_vector(p, e, axis, init_table_rate_rad_s, init_tube_mode)
    out = np.zeros((n_samples, NOUT))
    # the kernel takes its constants as tuples: values, not arrays, for its inlined phases
    modal = tuple(
        tuple(float(x) for x in d[k]) for k in ("mode_omega", "contact_gain", "moment_gain")
    )
    _kernel(awg, n_per_awg, dt, n_samples, n_sub, tuple(pv.tolist()), kel, wel, modal, out)
    t = np.arange(n_samples) / sample_rate_hz
    # the generator sample applied at each recorded instant (what the file's drive shows)
    idx = (np.arange(n_samples) * n_sub) // n_per_awg
    names = ("theta", "phi_x", "phi_y", "v_out", "crosstalk", "v_eff", "y_p", "y_q",
             "normal_p", "normal_q", "energy", "slid")  # fmt: skip
    res = {n: out[:, i].copy() for i, n in enumerate(names)}
    res["t"] = t
    res["drive_V"] = awg[idx]
    res["rim_m"] = res["theta"] * p.table_radius_m
    return res


def detector_signals(
    sim: dict[str, np.ndarray],
    *,
    params: PlantParams | None = None,
    effects: Effects | None = None,
    noise_std_V: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detector x and y volts (and the noise-free x) from a simulation's angles."""
    p = params or PlantParams()
    e = effects or Effects()
    t = sim["t"]
    L = p.detector_distance_m
    sx = L * np.tan(2.0 * (sim["theta"] + sim["phi_x"]))
    sy = L * np.tan(2.0 * sim["phi_y"])
    if e.misalignment_deg != 0.0:
        ang = math.radians(e.misalignment_deg)
        c, s = math.cos(ang), math.sin(ang)
        sx, sy = c * sx + s * sy, -s * sx + c * sy
    if math.isfinite(e.spot_radius_m):
        w = e.spot_radius_m
        k = math.sqrt(math.pi) * w / (2.0 * math.sqrt(2.0))  # unit slope at the centre
        sx = k * erf(math.sqrt(2.0) * sx / w)
        sy = k * erf(math.sqrt(2.0) * sy / w)
    vx = sx / p.detector_sensitivity_m_per_V + p.detector_offset_V[0]
    vy = sy / p.detector_sensitivity_m_per_V + p.detector_offset_V[1]
    if e.drift_amplitude_V != 0.0 or e.drift_rate_V_s != 0.0:
        dr = e.drift_amplitude_V * (1.0 - np.exp(-t / e.drift_tau_s)) + e.drift_rate_V_s * t
        vx = vx + dr
        vy = vy + e.drift_y_fraction * dr
    if e.crosstalk_ac != 0.0 or e.crosstalk_dc != 0.0:
        ct = sim["crosstalk"] + e.crosstalk_dc * sim["v_out"]
        vx = vx + ct
        vy = vy + e.crosstalk_y_fraction * ct
    clean = vx.copy()
    if noise_std_V > 0.0:
        rng = np.random.default_rng(seed)
        vx = vx + rng.normal(0.0, noise_std_V, vx.shape)
        vy = vy + rng.normal(0.0, noise_std_V, vy.shape)
    return vx, vy, clean


# --------------------------------------------------------------------------------------
# cases and files
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Case:
    name: str
    effect: str | None
    effects: Effects = field(default_factory=Effects)
    axis: str = "B"
    sample_rate_Hz: float = 25_000.0
    noise_std_V: float = 0.002
    seed: int = 0
    protocol_seed: int = 7


CASES: dict[str, Case] = {
    c.name: c
    for c in (
        Case("clean", None, seed=101),
        Case("clean_axis_A_10kHz", None, axis="A", sample_rate_Hz=10_000.0, noise_std_V=0.003,
             seed=102, protocol_seed=11),
        Case("creep", "creep", Effects(creep_gains=(0.03, 0.035, 0.04),
                                       creep_taus_s=(5e-3, 50e-3, 0.5)), seed=103),
        Case("hysteresis", "hysteresis", Effects(hysteresis_eta=0.45,
                                                 hysteresis_alpha_per_V=0.03), seed=104),
        Case("friction_asymmetry", "friction_asymmetry", Effects(friction_asymmetry=0.3),
             seed=105),
        Case("sensor_drift", "sensor_drift",
             Effects(drift_amplitude_V=0.03, drift_tau_s=1.5, drift_rate_V_s=0.008), seed=106),
        Case("floor_vibration", "floor_vibration",
             Effects(floor_accel_m_s2=0.03, floor_frequency_Hz=80.0), seed=107),
        Case("detector_nonlinearity", "detector_nonlinearity",
             Effects(spot_radius_m=0.5e-3), seed=108),
        Case("axis_misalignment", "axis_misalignment", Effects(misalignment_deg=4.0),
             seed=109),
        Case("slow_amplifier", "slow_amplifier",
             Effects(amplifier_gain_bandwidth_Hz=135e3, amplifier_slew_V_per_s=1.5e6,
                     amplifier_current_A=4e-3), seed=110),
        Case("contact_wear", "contact_wear",
             Effects(wear_fraction=0.3, wear_distance_m=40e-6), seed=111),
        Case("drive_crosstalk", "drive_crosstalk",
             Effects(crosstalk_ac=1.2e-4, crosstalk_tau_s=3e-4, crosstalk_dc=2e-5), seed=112),
        Case("preload_creep", "preload_creep", Effects(preload_loss=0.35, preload_tau_s=0.9),
             seed=113),
    )
}  # fmt: skip


def effect_params(case: Case) -> dict[str, dict[str, Any]]:
    if case.effect is None:
        return {}
    names = EFFECT_FIELDS[case.effect]
    return {case.effect: {f: _jsonable(getattr(case.effects, f)) for f in names}}


def _jsonable(v: Any) -> Any:
    if isinstance(v, tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.floating):
        return float(v)
    return v


def plant_summary(p: PlantParams | None = None) -> dict[str, Any]:
    p = p or PlantParams()
    d = {k: _jsonable(v) for k, v in asdict(p).items()}
    der = {
        k: _jsonable(v)
        for k, v in derived(p).items()
        if k not in ("mode_shapes", "mode_omega", "contact_gain", "moment_gain")
    }
    return {"parameters": d, "derived": der}


def trace_for_case(
    case: Case,
    params: PlantParams | None = None,
    duration_s: float | None = None,
    segments: list[Segment] | None = None,
) -> dict[str, Any]:
    """Simulate a case; returns the columns, metadata and protocol.

    ``segments`` replaces the case's lab protocol (short runs in tests).
    """
    p = params or PlantParams()
    if segments is None:
        segs = lab_protocol(case.protocol_seed, p, effects=case.effects)
    else:
        segs = list(segments)
    awg = render_drive(segs)
    dur = protocol_duration(segs) if duration_s is None else duration_s
    sim = simulate(awg, case.sample_rate_Hz, dur, params=p, effects=case.effects, axis=case.axis)
    vx, vy, clean = detector_signals(
        sim, params=p, effects=case.effects, noise_std_V=case.noise_std_V, seed=case.seed
    )
    meta = {
        "axis": case.axis,
        "amplifier_gain": f"{p.amplifier_gain:g}",
        "detector_sensitivity_m_per_V": f"{p.detector_sensitivity_m_per_V:g}",
        "detector_distance_m": f"{p.detector_distance_m:g}",
        "table_radius_m": f"{p.table_radius_m:g}",
        "sample_rate_Hz": f"{case.sample_rate_Hz:g}",
        "source": "third independent test plant (turntable_env.testing.third_plant)",
        "detector_linear_range_m": f"{p.detector_range_m:g}",
        "drive_note": "function generator output = HV amplifier input (V)",
        "columns": "t_s, drive, detector x (V), detector y (V)",
    }
    return {
        "meta": meta,
        "t": sim["t"],
        "drive": sim["drive_V"],
        "x": vx,
        "y": vy,
        "x_clean": clean,
        "sim": sim,
        "protocol": protocol_text(segs),
        "segments": segs,
    }


def _atomic_write_text(path: str, text: str) -> None:
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp_", suffix=".part", dir=directory)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp's 0600 would survive the rename
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_csv_atomic(path: str, trace: dict[str, Any], axis: str) -> None:
    lines = [f"# {k}: {v}" for k, v in trace["meta"].items()]
    lines.append(f"t_s,drive_{axis}_V,detector_V,detector_y_V")
    body = np.column_stack([trace["t"], trace["drive"], trace["x"], trace["y"]])
    rows = [f"{a:.6f},{b:.6f},{c:.6f},{d:.6f}" for a, b, c, d in body]
    _atomic_write_text(path, "\n".join(lines + rows) + "\n")


def write_json_atomic(path: str, obj: Any) -> None:
    _atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=False) + "\n")


def with_dt(p: PlantParams, dt_s: float) -> PlantParams:
    return replace(p, dt_s=dt_s)
