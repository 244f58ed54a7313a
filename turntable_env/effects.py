"""Catalogue of switchable model augmentations: effects the nominal model may lack.

Each :class:`Effect` has named parameters with units, bounds and a typical value, a
documented physical basis, and acts at one stage of the measurement chain that every
plant runs (:class:`~turntable_env.plant.PlantStepper`, for both fidelities):

======================  ==========  =============================================================
effect                  stage       model (parameters)
======================  ==========  =============================================================
amplifier_dynamics      parameters  HVA 900 slower or faster than measured: slew per input volt
                                    (settling time τ ∝ 1/slew, slew ∝ step, §4.1.2) and current
                                    limit scaled (``slew_scale``, ``current_scale``)
amplifier_fast_path     parameters  the HVA 900 is not first order: its step response has a fast
                                    partial rise before the slow tail, then the output's rate
                                    limit (``fraction``, ``tau_fast`` [s],
                                    :mod:`turntable_env.amplifier`)
amplifier_lag           parameters  a second pole: the output follows the stage through a lag
                                    τ_o = ``ratio``·τ (an S-shaped step), τ re-derived so the
                                    measured 1 V slew stays (:mod:`turntable_env.amplifier`)
piezo_hysteresis        input       Prandtl–Ishlinskii operator on the drive: (1 − h)·u + h·mean of
                                    8 play operators with thresholds up to ``width``; PZT shows
                                    10–15 % of stroke (``h``, ``width`` [V])
piezo_creep             input       logarithmic creep, ``gamma`` per decade of time (1–2 % typical):
                                    u + γ·Σ_i LP_τi(u − u0), τ_i = 1 ms … 10 s, one per decade
friction_asymmetry      friction    μ_s, μ_c × (1 ± ``alpha``) as the table slides forward (+) or
                                    backward (−) over a tube, phase by phase in the integrator
                                    (a forward step's slip is the forward sliding): surface
                                    texture / lay makes sliding one way harder (``alpha``)
friction_wear           friction    μ_s, μ_c × (1 + ``beta``·w(travel)) (at least ×0.2), w = x for
                                    ``saturation`` k = 0 and (1 − e^(−k·x))/k else, x = travel /
                                    10 µm: the contacts flatten or roughen with use (§4.3 mentions
                                    wear), at first by β per 10 µm, running in towards β/k
axis_misalignment       output      the axes are not perpendicular (§4.3): the detector's x channel
                                    sees θ·cos φ, its y channel θ·sin φ (``phi`` [rad], signed:
                                    the tilt goes either way)
detector_nonlinearity   output      photodiode: V + κ·V_c³/V_sat², V_c = V clipped to ±V_sat
                                    (``kappa``)
sensor_drift            output      laser/photodiode drift: offset + rate·t (``offset`` [V],
                                    ``rate`` [V/s])
vibration               output      floor vibration rocking the table under the beam: θ +
                                    A·sin(2πft + φ) (``amplitude`` [rad], ``frequency`` [Hz],
                                    ``phase`` [rad]) (§4.3: "very sensitive to vibrations")
======================  ==========  =============================================================

An effect with its parameters at their ``neutral`` values changes nothing (tested).

Stages, in the order the plant runs them:

* **parameters** (:func:`apply_parameters`): a changed parameter set;
* **input** (:func:`input_stage_nb`, compiled): the piezo's hysteresis and creep act on
  the commanded input, piecewise linear, with their states carried from one interval to
  the next: the play operators exactly (a breakpoint at every play's turning point) and
  the creep's first-order modes exactly at breakpoints at most ``CREEP_PIECE`` apart. The
  input is the amplifier's: where the amplifier follows (scan, ramps) this is the piezo's
  voltage divided by the gain; the flyback passes through as a jump;
* **friction**: the asymmetry by each contact's sliding direction inside the
  integrator (:func:`sliding_asymmetry`; every fidelity resolves the sliding), the wear
  (:func:`friction_scale`) as μ_s and μ_c scaled for the next segment of
  ``FRICTION_SEGMENT`` by the table's travel in the previous ones;
* **output** (:func:`detector_stage`): what the laser and the quadrant photodiode report.

Effect parameters cross into the stages as one row per plant (:func:`pack_effects`,
:data:`EFFECT_FIELDS`), neutral where an effect is off, so N plants run the stages
vectorised without Python per plant.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numba import njit

from .kernel_cache import CACHE
from .params import ParameterSet
from .validation import check_finite, parse_decimal

__all__ = [
    "CATALOGUE",
    "CREEP_TAUS",
    "EFFECT_FIELDS",
    "FRICTION_SEGMENT",
    "N_PLAY",
    "WEAR_RUN_IN_START",
    "Effect",
    "EffectParameter",
    "apply_input",
    "apply_output",
    "apply_parameters",
    "check_effects",
    "detector_stage",
    "friction_active",
    "friction_scale",
    "input_active",
    "input_capacity",
    "input_rest",
    "input_stage_nb",
    "pack_effects",
    "parse_effects",
    "sliding_asymmetry",
    "stages_of",
]


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
    """A catalogue entry (module docstring): name, stage, parameters, physical basis, and
    whether a trace calibration searches it by default (``searched``; the others are model
    options a lab switches on, or profiles with the nominal fit)."""

    name: str
    stage: str
    parameters: tuple[EffectParameter, ...]
    basis: str
    searched: bool = True

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
            v = check_finite(f"{self.name}.{p.name}", values.get(p.name, p.typical))
            if not (math.isfinite(v) and p.low <= v <= p.high):
                unit = f" {p.unit}" if p.unit not in ("", "-") else ""
                raise ValueError(
                    f"{self.name}.{p.name}={v!r}: outside {p.low:g}…{p.high:g}{unit}"
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
            "amplifier_fast_path",
            "parameters",
            (
                _P("fraction", "-", 0.0, 0.6, 0.0, 0.3, "share of a step the fast path covers"),
                _P("tau_fast", "s", 0.2e-6, 5e-6, 1e-6, 1e-6, "fast path time constant"),
            ),
            "§4.1.2: 1 V and 3 V steps scale linearly (0.9, 2.7 V/µs: 'divide the 3 V response "
            "by three') while the adapted flyback reaches 8.0 V/µs, which no first-order "
            "stage with the same settling time gives (3.6 V/µs): the amplifier's step response "
            "has a fast partial rise followed by the slow tail.",
        ),
        Effect(
            "amplifier_lag",
            "parameters",
            (
                _P("ratio", "-", 0.0, 1.0, 0.0, 0.5, "output lag time constant ÷ the stage's"),
            ),
            "A high-voltage amplifier driving a capacitive load through its output stage has "
            "a second pole: its step response starts with zero slope (an S shape) where a "
            "first-order stage starts at its steepest (§4.1.2 measured only the 10–90 % "
            "slew, which the model keeps). ratio = 1 is two equal poles, the critically damped "
            "response; a well-damped second-order amplifier lies near it.",
            # not searched as an effect: held at the nominal fit, which has already set the
            # amplifier's speed without it, the candidate does not move (stop 65: 0.05 and
            # 0.1 on the second plant's slower-amplifier and clean traces, no gain); it is
            # profiled with the nominal fit instead (experiments/amplifier_profile.py --lag)
            searched=False,
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
                    "relative μ change per 10 µm of travel, at first",
                ),
                _P(
                    "saturation",
                    "1/(10 µm)",
                    0.0,
                    2.0,
                    0.0,
                    0.0,
                    "running-in: the change's decay per 10 µm of travel (0: it goes on)",
                ),
            ),
            "§4.3: table and tube surfaces are not hard; with travel they flatten (or "
            "roughen), changing the friction and the step size over time. Contacts run in: "
            "the change is fastest at first and levels off after a running-in distance "
            "10 µm / saturation (Archard wear of a Hertz contact slows as it conforms).",
        ),
        Effect(
            "axis_misalignment",
            "output",
            (_P("phi", "rad", -0.3, 0.3, 0.0, 0.1,
                "tilt of the turning axis to the detector's, either way"),),
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
    if not isinstance(effects, Mapping):
        raise ValueError(f"effects={effects!r}: must map effect names to their parameters")
    out = {}
    for name, vals in effects.items():
        if name not in CATALOGUE:
            raise ValueError(f"effect {name!r}: not in the catalogue ({', '.join(CATALOGUE)})")
        if not isinstance(vals, Mapping):
            raise ValueError(
                f"effects[{name!r}]={vals!r}: must be a table of its parameters, e.g. "
                f"{{{CATALOGUE[name].parameters[0].name!r}: value}}"
            )
        out[name] = CATALOGUE[name].check(vals)
    return out


def parse_effects(spec: str) -> dict[str, dict[str, float]]:
    """``"piezo_creep=0.02,sensor_drift.rate=0.1,vibration"`` → validated effects.

    ``name=value`` sets the effect's first parameter, ``name.param=value`` any one (the
    effect's other parameters stay neutral); a bare ``name`` switches it on at its typical
    values."""
    raw: dict[str, dict[str, float]] = {}
    items = [s.strip() for s in spec.split(",")] if spec.strip() else []
    seen: set[str] = set()
    for item in items:
        if not item:
            raise ValueError(f"--effects={spec!r}: an empty entry between commas")
        key, sep, val = item.partition("=")
        name, dot, param = key.partition(".")
        if dot and not param:
            raise ValueError(f"--effects: {item!r}: no parameter name after the dot")
        if name not in CATALOGUE:
            raise ValueError(
                f"--effects: {name!r} is not in the catalogue ({', '.join(CATALOGUE)})"
            )
        label = f"{name}.{param or CATALOGUE[name].parameters[0].name}" if sep else name
        if label in seen:  # not the last one silently
            raise ValueError(f"--effects: {key!r} given twice in {spec!r}")
        seen.add(label)
        if not sep:
            raw.setdefault(name, CATALOGUE[name].defaults())
            continue
        entry = raw.setdefault(name, CATALOGUE[name].neutral())
        x = parse_decimal(val)
        if x is None:
            raise ValueError(
                f"--effects: {item!r}: {val!r} is not a number (plain decimals: 1.5e-3)"
            )
        entry[param or CATALOGUE[name].parameters[0].name] = x
    return check_effects(raw)


# --- packed parameters -----------------------------------------------------------------------
EFFECT_FIELDS = (
    "amplifier_dynamics.slew_scale",
    "amplifier_dynamics.current_scale",
    "amplifier_fast_path.fraction",
    "amplifier_fast_path.tau_fast",
    "amplifier_lag.ratio",
    "piezo_hysteresis.h",
    "piezo_hysteresis.width",
    "piezo_creep.gamma",
    "friction_asymmetry.alpha",
    "friction_wear.beta",
    "friction_wear.saturation",
    "axis_misalignment.phi",
    "detector_nonlinearity.kappa",
    "sensor_drift.offset",
    "sensor_drift.rate",
    "vibration.amplitude",
    "vibration.frequency",
    "vibration.phase",
)
_COL = {name: i for i, name in enumerate(EFFECT_FIELDS)}
_H_COL = _COL["piezo_hysteresis.h"]  # the input stage's columns (compiled constants)
_WIDTH_COL = _COL["piezo_hysteresis.width"]
_GAMMA_COL = _COL["piezo_creep.gamma"]
N_PLAY = 8  # play operators of the Prandtl–Ishlinskii model
WEAR_LENGTH = 10e-6  # m of travel at the table radius per unit of friction_wear.beta
# friction_wear.saturation where the effect searches start: running in over 40 µm (the
# typical value stays 0, the linear form every plant set and stored model was made with)
WEAR_RUN_IN_START = 0.25
CREEP_TAUS = (1e-3, 1e-2, 1e-1, 1.0, 10.0)  # s, one first-order mode per decade
CREEP_PIECE = 0.5e-3  # s, longest piece between creep evaluations (CREEP_TAUS[0] / 2)
FRICTION_SEGMENT = 5e-3  # s, friction wear updates μ this often


def pack_effects(effects: Mapping[str, Mapping[str, float]]) -> np.ndarray:
    """One row of :data:`EFFECT_FIELDS` [SI] for validated effects; neutral where off."""
    row = np.empty(len(EFFECT_FIELDS))
    for field_name, i in _COL.items():
        name, pname = field_name.split(".")
        row[i] = effects.get(name, {}).get(pname, _NEUTRAL[field_name])
    return row


def stages_of(effects: Mapping[str, Mapping[str, float]]) -> frozenset[str]:
    """The stages at which ``effects`` act (parameters, input, friction, output)."""
    return frozenset(CATALOGUE[n].stage for n in effects)


_NEUTRAL = {
    f"{e.name}.{p.name}": p.neutral for e in CATALOGUE.values() for p in e.parameters
}
assert set(_NEUTRAL) == set(EFFECT_FIELDS), "EFFECT_FIELDS must list every catalogue parameter"


# --- parameters stage ---------------------------------------------------------------------------
def apply_parameters(ps: ParameterSet, effects: Mapping[str, Mapping[str, float]]) -> ParameterSet:
    """Parameter-stage effects: amplifier_dynamics (slew per input volt and current limit),
    amplifier_fast_path (the amplifier's fast partial response), amplifier_lag (its
    output's second pole)."""
    if "amplifier_dynamics" in effects:
        v = effects["amplifier_dynamics"]
        ps = replace(ps, amplifier=ps.amplifier.scaled(v["slew_scale"], v["current_scale"]))
    if "amplifier_fast_path" in effects:
        v = effects["amplifier_fast_path"]
        amp = replace(ps.amplifier, fast_fraction=v["fraction"], fast_time=v["tau_fast"])
        ps = replace(ps, amplifier=amp)
    if "amplifier_lag" in effects:
        lag = effects["amplifier_lag"]["ratio"]
        ps = replace(ps, amplifier=replace(ps.amplifier, lag_ratio=lag))
    return ps


# --- input stage (piezo: hysteresis, creep) --------------------------------------------------
@njit(cache=CACHE)
def _clamp_plays(plays, widths, x):
    for j in range(plays.size):
        plays[j] = min(max(plays[j], x - widths[j]), x + widths[j])


@njit(cache=CACHE)
def input_stage_nb(t, u, n, seconds, row, plays, creep, ref, out_t, out_v):
    """Input-stage effects on the piecewise-linear input (t[:n], u[:n]) (module docstring).

    Args:
        t: breakpoint times in any unit, ``seconds`` s each; u: input [V].
        row: the plant's :data:`EFFECT_FIELDS` row.
        plays: (N_PLAY,) play-operator outputs [V], carried over (updated).
        creep: (len(CREEP_TAUS),) creep modes [V], carried over (updated).
        ref: (1,) the creep's reference input [V] (the input the modes relax from).
    Writes the output breakpoints to out_t, out_v and returns their count (at most
    n·(N_PLAY + 1) + the creep pieces).
    """
    h = row[_H_COL]
    width = row[_WIDTH_COL]
    gamma = row[_GAMMA_COL]
    widths = np.empty(N_PLAY)
    for j in range(N_PLAY):
        widths[j] = width * (j + 1) / N_PLAY
    ntau = creep.size
    taus = np.empty(ntau)
    for j in range(ntau):
        taus[j] = CREEP_TAUS[j]
    fr = np.empty(N_PLAY + 1)
    m = 0
    p_prev = 0.0
    t_prev = 0.0
    for i in range(n):
        x1 = u[i]
        if i == 0:
            x0 = x1
            t0 = t[0]
        else:
            x0 = u[i - 1]
            t0 = t[i - 1]
        t1 = t[i]
        # turning points of the plays inside the segment (x linear, monotone)
        nk = 0
        if h > 0.0 and x1 != x0 and t1 > t0:
            for j in range(N_PLAY):
                thr = plays[j] + widths[j] if x1 > x0 else plays[j] - widths[j]
                f = (thr - x0) / (x1 - x0)
                if 0.0 < f < 1.0:
                    fr[nk] = f
                    nk += 1
            for a in range(1, nk):  # insertion sort (at most N_PLAY)
                v = fr[a]
                b = a - 1
                while b >= 0 and fr[b] > v:
                    fr[b + 1] = fr[b]
                    b -= 1
                fr[b + 1] = v
        n_piece = 1
        if gamma > 0.0 and t1 > t0:
            n_piece = max(math.ceil((t1 - t0) * seconds / CREEP_PIECE - 1e-9), 1)
        # merge the kinks with the creep pieces; the segment end last
        ik = 0
        ip = 1
        while True:
            if ik < nk and (ip >= n_piece or fr[ik] < ip / n_piece):
                f = fr[ik]
                ik += 1
            elif ip < n_piece:
                f = ip / n_piece
                ip += 1
            else:
                f = 1.0
            if f >= 1.0:
                tt = t1
                xx = x1
            else:
                tt = t0 + f * (t1 - t0)
                xx = x0 + f * (x1 - x0)
            p = xx
            if h > 0.0:
                _clamp_plays(plays, widths, xx)
                s = 0.0
                for j in range(N_PLAY):
                    s += plays[j]
                p = (1.0 - h) * xx + h * s / N_PLAY
            out = p
            if gamma > 0.0:
                q = p - ref[0]
                dt = (tt - t_prev) * seconds if m > 0 else 0.0
                if dt > 0.0:
                    q_prev = p_prev - ref[0]
                    slope = (q - q_prev) / dt
                    for j in range(ntau):
                        e = math.exp(-dt / taus[j])
                        creep[j] = q - slope * taus[j] + (creep[j] - q_prev + slope * taus[j]) * e
                c = 0.0
                for j in range(ntau):
                    c += creep[j]
                out = p + gamma * c
            if not (m > 0 and tt == out_t[m - 1] and out == out_v[m - 1]):
                out_t[m] = tt
                out_v[m] = out
                m += 1
            p_prev = p
            t_prev = tt
            if f >= 1.0:
                break
    return m


def apply_input(
    t: np.ndarray, u: np.ndarray, effects: Mapping[str, Mapping[str, float]]
) -> tuple[np.ndarray, np.ndarray]:
    """Input-stage effects of one plant on a piecewise-linear input from rest at its first
    value: breakpoints (t [s], u [V]) in, breakpoints out (:func:`input_stage_nb`); the
    input returned unchanged where no input-stage effect is on."""
    t = np.asarray(t, dtype=float).reshape(-1)
    u = np.asarray(u, dtype=float).reshape(-1)
    row = pack_effects(effects)
    if not bool(input_active(row)):
        return t.copy(), u.copy()
    plays, creep, ref = input_rest(u[:1], 1)
    cap = input_capacity(t.size, float(t[-1] - t[0]), row)
    out_t, out_v = np.empty(cap), np.empty(cap)
    m = input_stage_nb(t, u, t.size, 1.0, row, plays[0], creep[0], ref, out_t, out_v)
    return out_t[:m].copy(), out_v[:m].copy()


def input_capacity(n: int, span_s: float, row: np.ndarray) -> int:
    """Breakpoints :func:`input_stage_nb` may write for n inputs spanning ``span_s`` [s]."""
    pieces = math.ceil(span_s / CREEP_PIECE) + n if row[_COL["piezo_creep.gamma"]] > 0.0 else 0
    return n * (N_PLAY + 1) + pieces + 2


def input_active(rows: np.ndarray) -> np.ndarray:
    """(N,) True where a row has an input-stage effect on."""
    hyst = rows[..., _COL["piezo_hysteresis.h"]] > 0.0
    return hyst | (rows[..., _COL["piezo_creep.gamma"]] > 0.0)


def input_rest(level: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Input-stage states at rest under input ``level`` [V]: plays at the level, creep modes
    relaxed, the level the reference — ((n, N_PLAY), (n, len(CREEP_TAUS)), (n,))."""
    lv = np.broadcast_to(np.asarray(level, dtype=float), (n,))
    return (
        np.repeat(lv[:, None], N_PLAY, axis=1),
        np.zeros((n, len(CREEP_TAUS))),
        lv.copy(),
    )


# --- friction stage --------------------------------------------------------------------------
def friction_scale(rows: np.ndarray, travel: np.ndarray) -> np.ndarray:
    """Multiplier on μ_s, μ_c per row for the table's travel so far at the table radius
    [m] (``friction_wear``): max(1 + β·w, 0.2) with x = travel / 10 µm and w = x where
    the saturation k is 0, (1 − e^(−k·x))/k where it is not (the same slope β at the
    start, the change levelling off at β/k)."""
    beta = rows[..., _COL["friction_wear.beta"]]
    k = rows[..., _COL["friction_wear.saturation"]]
    x = np.asarray(travel, dtype=float) / WEAR_LENGTH
    run_in = -np.expm1(-k * x) / np.where(k > 0.0, k, 1.0)
    return np.maximum(1.0 + beta * np.where(k > 0.0, run_in, x), 0.2)


def sliding_asymmetry(rows: np.ndarray) -> np.ndarray:
    """(N,) α of ``friction_asymmetry`` per row, for the integrator: μ_s, μ_c × (1 + α)
    while the table slides forward over a tube and × (1 − α) backward, phase by phase."""
    return rows[..., _COL["friction_asymmetry.alpha"]].copy()


def friction_active(rows: np.ndarray) -> np.ndarray:
    """(N,) True where a row has a friction effect that runs in segments (wear)."""
    return rows[..., _COL["friction_wear.beta"]] != 0.0


# --- output stage (detector) -----------------------------------------------------------------
def detector_stage(
    theta: np.ndarray, t: np.ndarray, rows: np.ndarray, detector: Any
) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) detector voltages [V] before noise and saturation for table angle θ [rad] at
    times t [s] (since the plant's start) with effect rows broadcast against them:
    vibration adds A·sin(2πft + φ) to θ; the beam turns by twice the mirror's tilt
    (``detector.tilt_factor``·θ, Eq. 4.1), read as 2θ·cos φ (x) and 2θ·sin φ (y) for a
    misalignment φ, times the photodiode's ``gain``; the photodiode adds κ·V_c³/V_sat² with
    V_c = V clipped to ±V_sat (the response is monotone for |κ| < 1/3, and a table beyond
    the range reads on its own side, saturated once V passes (1 + |κ|)·V_sat) and drift
    offset + rate·t."""
    th = np.asarray(theta, dtype=float)
    c = _COL
    amp = rows[..., c["vibration.amplitude"]]
    freq = rows[..., c["vibration.frequency"]]
    th = th + amp * np.sin(2.0 * math.pi * freq * t + rows[..., c["vibration.phase"]])
    phi = rows[..., c["axis_misalignment.phi"]]
    tilt = 2.0 * detector.tilt_factor * th  # the mirror's tilt, doubled by the reflection
    x = detector.gain * detector.distance * np.tan(tilt * np.cos(phi)) / detector.sensitivity
    y = detector.gain * detector.distance * np.tan(tilt * np.sin(phi)) / detector.sensitivity
    kappa = rows[..., c["detector_nonlinearity.kappa"]]
    vs = detector.saturation_voltage
    xc = np.clip(x, -vs, vs)  # the cubic acts inside the linear range; beyond it the output
    x = x + kappa * xc * (xc / vs) ** 2  # rises on to the clip: monotone for |κ| < 1/3
    x = x + rows[..., c["sensor_drift.offset"]] + rows[..., c["sensor_drift.rate"]] * t
    return x, y


def apply_output(
    t: np.ndarray, theta: np.ndarray, effects: Mapping[str, Mapping[str, float]], detector: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Output-stage effects of one plant on a trace: (x, y) detector voltages [V] before
    noise and saturation (:func:`detector_stage`)."""
    return detector_stage(theta, np.asarray(t, dtype=float), pack_effects(effects), detector)
