"""Catalogue of switchable model augmentations: effects the nominal model may lack.

Each :class:`Effect` has named parameters with units, bounds and a typical value, a
documented physical basis, and acts at one stage of the measurement chain that
:func:`~turntable_env.calibration.trace.simulate_trace` runs:

======================  ==========  =============================================================
effect                  stage       model (parameters)
======================  ==========  =============================================================
amplifier_dynamics      parameters  HVA 900 slower or faster than measured: slew per input volt
                                    (settling time τ ∝ 1/slew, slew ∝ step, §4.1.2) and current
                                    limit scaled (``slew_scale``, ``current_scale``)
piezo_hysteresis        input       Prandtl–Ishlinskii operator on the drive: (1 − h)·u + h·mean of
                                    8 play operators with thresholds up to ``width``; PZT shows
                                    10–15 % of stroke (``h``, ``width`` [V])
piezo_creep             input       logarithmic creep, ``gamma`` per decade of time (1–2 % typical):
                                    u + γ·Σ_i LP_τi(u − u0), τ_i = 1 ms … 10 s, one per decade
friction_asymmetry      friction    μ_s, μ_c × (1 + ``alpha``·sign of the table's motion): surface
                                    texture / lay makes sliding one way harder (``alpha``)
friction_wear           friction    μ_s, μ_c × (1 + ``beta``·travel/10 µm) (at least ×0.2): the
                                    contacts flatten or roughen with use (§4.3 mentions wear)
axis_misalignment       output      the axes are not perpendicular (§4.3): the detector's x channel
                                    sees θ·cos φ, its y channel θ·sin φ (``phi`` [rad])
detector_nonlinearity   output      photodiode response: V·(1 + κ·(V/V_sat)²) (``kappa``)
sensor_drift            output      laser/photodiode drift: offset + rate·t (``offset`` [V],
                                    ``rate`` [V/s])
vibration               output      floor vibration rocking the table under the beam: θ +
                                    A·sin(2πft + φ) (``amplitude`` [rad], ``frequency`` [Hz],
                                    ``phase`` [rad]) (§4.3: "very sensitive to vibrations")
======================  ==========  =============================================================

An effect with its parameters at their ``neutral`` values changes nothing (tested).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numba
import numpy as np

from ..params import ParameterSet

__all__ = ["CATALOGUE", "Effect", "EffectParameter", "check_effects", "parse_effects"]


@dataclass(frozen=True)
class EffectParameter:
    """One parameter: name, unit, bounds, neutral value (effect off) and typical value."""

    name: str
    unit: str
    low: float
    high: float
    neutral: float
    typical: float
    description: str


@dataclass(frozen=True)
class Effect:
    """A catalogue entry (module docstring): name, stage, parameters, physical basis."""

    name: str
    stage: str
    parameters: tuple[EffectParameter, ...]
    basis: str

    def defaults(self) -> dict[str, float]:
        return {p.name: p.typical for p in self.parameters}

    def neutral(self) -> dict[str, float]:
        return {p.name: p.neutral for p in self.parameters}

    def check(self, values: Mapping[str, float]) -> dict[str, float]:
        """Validated full parameter dict (missing ones take the typical value)."""
        names = {p.name for p in self.parameters}
        unknown = set(values) - names
        if unknown:
            raise ValueError(
                f"{self.name}: unknown parameter(s) {sorted(unknown)} (has {sorted(names)})"
            )
        out = {}
        for p in self.parameters:
            v = float(values.get(p.name, p.typical))
            if not (math.isfinite(v) and p.low <= v <= p.high):
                raise ValueError(
                    f"{self.name}.{p.name}={v!r}: outside {p.low:g}…{p.high:g} {p.unit}"
                )
            out[p.name] = v
        return out


def _P(name, unit, low, high, neutral, typical, desc) -> EffectParameter:
    return EffectParameter(name, unit, low, high, neutral, typical, desc)


CATALOGUE: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "amplifier_dynamics",
            "parameters",
            (
                _P("slew_scale", "-", 0.3, 2.0, 1.0, 0.6, "slew per input volt × (τ ÷)"),
                _P("current_scale", "-", 0.3, 2.0, 1.0, 1.0, "current limit ×"),
            ),
            "§4.1.2: the HVA 900's output reaches its end value in a fixed time, so the "
            "slew rate is proportional to the step; its 25 mA limit caps the slew on the "
            "quadrants' capacitance. Aged or different units settle slower or faster.",
        ),
        Effect(
            "piezo_hysteresis",
            "input",
            (
                _P("h", "-", 0.0, 0.3, 0.0, 0.12, "hysteretic share of the stroke"),
                _P("width", "V", 0.1, 10.0, 2.0, 2.0, "largest play threshold (input volts)"),
            ),
            "PZT ferroelectric domain switching: strain lags voltage on a rate-independent "
            "loop, 10–15 % of stroke; Prandtl–Ishlinskii (weighted play operators) is the "
            "standard phenomenological model.",
        ),
        Effect(
            "piezo_creep",
            "input",
            (_P("gamma", "-", 0.0, 0.05, 0.0, 0.015, "creep per decade of time"),),
            "After a voltage change PZT strain keeps growing roughly logarithmically in "
            "time (domain relaxation), 1–2 % per decade.",
        ),
        Effect(
            "friction_asymmetry",
            "friction",
            (_P("alpha", "-", -0.4, 0.4, 0.0, 0.2, "relative μ difference by direction"),),
            "Machined or worn surfaces have a lay: friction differs with the sliding "
            "direction, so forward and backward steps differ.",
        ),
        Effect(
            "friction_wear",
            "friction",
            (
                _P(
                    "beta",
                    "1/(10 µm)",
                    -0.5,
                    0.5,
                    0.0,
                    0.1,
                    "relative μ change per 10 µm of travel",
                ),
            ),
            "§4.3: table and tube surfaces are not hard; with travel they flatten (or "
            "roughen), changing the friction and the step size over time.",
        ),
        Effect(
            "axis_misalignment",
            "output",
            (_P("phi", "rad", 0.0, 0.3, 0.0, 0.1, "tilt of the turning axis to the detector's"),),
            "§4.3: the axes are not perpendicular, so rotations are not about the expected "
            "axis: the detector's channel sees θ·cos φ and the other channel θ·sin φ.",
        ),
        Effect(
            "detector_nonlinearity",
            "output",
            (_P("kappa", "-", -0.3, 0.3, 0.0, 0.1, "cubic gain change at the range edge"),),
            "A quadrant photodiode's difference signal is linear only near the centre "
            "(Fig. 4.4); towards the edges the gain changes.",
        ),
        Effect(
            "sensor_drift",
            "output",
            (
                _P("offset", "V", -0.5, 0.5, 0.0, 0.05, "detector offset"),
                _P("rate", "V/s", -1.0, 1.0, 0.0, 0.1, "detector drift rate"),
            ),
            "Laser pointing and photodiode electronics drift thermally: a slowly varying "
            "offset on the detector output.",
        ),
        Effect(
            "vibration",
            "output",
            (
                _P("amplitude", "rad", 0.0, 5e-5, 0.0, 5e-6, "angle amplitude"),
                _P("frequency", "Hz", 1.0, 1000.0, 50.0, 50.0, "disturbance frequency"),
                _P("phase", "rad", -math.pi, math.pi, 0.0, 0.0, "phase at t = 0"),
            ),
            "§4.3: the setup is very sensitive to vibrations from the environment: a "
            "periodic rocking of the table under the laser beam.",
        ),
    )
}


def check_effects(effects: Mapping[str, Mapping[str, float]]) -> dict[str, dict[str, float]]:
    """Validate {effect name: {parameter: value}} against the catalogue."""
    out = {}
    for name, vals in effects.items():
        if name not in CATALOGUE:
            raise ValueError(f"effect {name!r}: not in the catalogue ({', '.join(CATALOGUE)})")
        out[name] = CATALOGUE[name].check(vals)
    return out


def parse_effects(spec: str) -> dict[str, dict[str, float]]:
    """``"piezo_creep=0.02,sensor_drift.rate=0.1,vibration"`` → validated effects.

    ``name=value`` sets the effect's first parameter, ``name.param=value`` any one (the
    effect's other parameters stay neutral); a bare ``name`` switches it on at its typical
    values."""
    raw: dict[str, dict[str, float]] = {}
    for item in filter(None, (s.strip() for s in spec.split(","))):
        key, sep, val = item.partition("=")
        name, _, param = key.partition(".")
        if name not in CATALOGUE:
            raise ValueError(
                f"--effects: {name!r} is not in the catalogue ({', '.join(CATALOGUE)})"
            )
        if not sep:
            raw.setdefault(name, CATALOGUE[name].defaults())
            continue
        entry = raw.setdefault(name, CATALOGUE[name].neutral())
        try:
            x = float(val)
        except ValueError:
            raise ValueError(f"--effects: {item!r}: {val!r} is not a number") from None
        entry[param or CATALOGUE[name].parameters[0].name] = x
    return check_effects(raw)


# --- stage implementations --------------------------------------------------------------------
def apply_parameters(ps: ParameterSet, effects: Mapping[str, Mapping[str, float]]) -> ParameterSet:
    """Parameter-stage effects (amplifier_dynamics)."""
    if "amplifier_dynamics" in effects:
        v = effects["amplifier_dynamics"]
        amp = ps.amplifier
        ps = replace(
            ps,
            amplifier=replace(
                amp,
                slew_per_input_volt=amp.slew_per_input_volt * v["slew_scale"],
                current_limit=amp.current_limit * v["current_scale"],
            ),
        )
    return ps


@numba.njit(cache=True)
def _play(u: np.ndarray, r: float) -> np.ndarray:
    """Play (backlash) operator of threshold r on a sampled signal (exact at breakpoints)."""
    out = np.empty_like(u)
    y = u[0]
    for i, x in enumerate(u):
        y = min(max(y, x - r), x + r)
        out[i] = y
    return out


@numba.njit(cache=True)
def _lowpass_pwl(t: np.ndarray, u: np.ndarray, tau: float) -> np.ndarray:
    """First-order low-pass (unit gain) of a piecewise-linear signal, exact per segment."""
    y = np.empty_like(u)
    y[0] = u[0]
    for i in range(1, u.size):
        dt = t[i] - t[i - 1]
        if dt <= 0.0:
            y[i] = y[i - 1]
            continue
        s = (u[i] - u[i - 1]) / dt
        e = math.exp(-dt / tau)
        y[i] = u[i] - s * tau + (y[i - 1] - u[i - 1] + s * tau) * e
    return y


WEAR_LENGTH = 10e-6  # m of travel at the table radius per unit of friction_wear.beta
CREEP_TAUS = (1e-3, 1e-2, 1e-1, 1.0, 10.0)  # s, one first-order mode per decade


def apply_input(
    t: np.ndarray, u: np.ndarray, effects: Mapping[str, Mapping[str, float]]
) -> np.ndarray:
    """Input-stage effects on the drive breakpoints (time [s], input [V])."""
    out = np.asarray(u, dtype=float)
    if "piezo_hysteresis" in effects:
        v = effects["piezo_hysteresis"]
        if v["h"] > 0.0:
            r = v["width"] * np.arange(1, 9) / 8.0
            plays = np.mean([_play(out, float(ri)) for ri in r], axis=0)
            out = (1.0 - v["h"]) * out + v["h"] * plays
    if "piezo_creep" in effects:
        g = effects["piezo_creep"]["gamma"]
        if g > 0.0:
            base = out - out[0]
            out = out + g * sum(_lowpass_pwl(t, base, tau) for tau in CREEP_TAUS)
    return out


def friction_factor(
    effects: Mapping[str, Mapping[str, float]], direction: float, travel: float
) -> float:
    """Friction-stage multiplier on μ_s, μ_c for the table's recent direction of motion
    (sign) and its travel so far at the table radius [m]."""
    k = 1.0
    if "friction_asymmetry" in effects:
        k *= 1.0 + effects["friction_asymmetry"]["alpha"] * float(np.sign(direction))
    if "friction_wear" in effects:
        k *= max(1.0 + effects["friction_wear"]["beta"] * travel / WEAR_LENGTH, 0.2)
    return k


def apply_output(
    t: np.ndarray, theta: np.ndarray, effects: Mapping[str, Mapping[str, float]], detector: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Output-stage effects: (x, y) detector voltages [V] before noise and saturation."""
    th = np.asarray(theta, dtype=float)
    if "vibration" in effects:
        v = effects["vibration"]
        th = th + v["amplitude"] * np.sin(2.0 * math.pi * v["frequency"] * t + v["phase"])
    phi = effects.get("axis_misalignment", {}).get("phi", 0.0)
    x = detector.distance * np.tan(2.0 * th * math.cos(phi)) / detector.sensitivity
    y = detector.distance * np.tan(2.0 * th * math.sin(phi)) / detector.sensitivity
    if "detector_nonlinearity" in effects:
        kappa = effects["detector_nonlinearity"]["kappa"]
        vs = detector.saturation_voltage
        x = x * (1.0 + kappa * (x / vs) ** 2)
    if "sensor_drift" in effects:
        v = effects["sensor_drift"]
        x = x + v["offset"] + v["rate"] * t
    return x, y
