"""One plant layer: the turntable every consumer runs — env, virtual lab, calibrator, benchmark.

A :class:`Plant` is what a laboratory would call "the turntable as we know it": a
parameter set (Table D.1, D.2 or a calibrated one) with multiplicative factors on its
uncertain values (friction, preload, amplifier), a fidelity (``"reduced"`` per-axis
model or ``"full"`` 3-D model), the effects of the catalogue (:mod:`turntable_env.effects`)
with their parameters, the detector noise and the amplifier setting. It is immutable,
hashable and picklable; :meth:`Plant.from_report` reads the plant a calibration report
describes, :meth:`Plant.sample` draws a randomised one.

:class:`PlantStepper` runs N plants about one axis, together, and is the only way the
physics is run by the environment (:mod:`turntable_env.envs`), the calibrator and the
virtual lab (:mod:`turntable_env.calibration`) and the controller benchmark. The data
path runs one way; for the drive amplitude of an env action it is:

1. **action → config**: :class:`~turntable_env.envs.config.ActionScaling` turns the
   normalised action into a generator setting (amplitude u_A [V input], f, a, k, scan
   offset u_0);
2. **config → plant stepper**: :meth:`PlantStepper.advance` takes the N settings;
3. **generator** (compiled, :func:`~turntable_env.generator.generate_interval`): the
   free-running generator turns them into piecewise-linear amplifier inputs for the
   interval (Fig. 3.14 / Fig. 4.3 periods, the Fig. 4.3 hold from the amplifier, the scan
   offset ramp, the ±10 V input clip, the integration grid), the flybacks and the energy;
4. **input stage** (compiled, :func:`~turntable_env.effects.input_stage_nb`): the piezo's
   hysteresis and creep, where a plant has them;
5. **kernel**: the reduced integrator (:func:`~turntable_env.reduced_kernel.run_reduced_batch`,
   one compiled call for all N) or the 3-D one (:func:`~turntable_env.integrator.run_full_model`,
   one call per turntable) with the amplifier (§4.1.2), the tubes (Eq. 2.11), the GMS
   contacts (Eq. 2.24–2.26) and the table; friction-stage effects rescale μ between
   segments of ``FRICTION_SEGMENT``;
6. **output stage** (:meth:`PlantStepper.observe`): the detector (Eq. 4.1) with the
   output-stage effects, noise and saturation.

Nothing flows back up: the stepper never reads the env, the kernels never read the
stepper. Explicit drives (a measured trace) enter at step 4 (:meth:`PlantStepper.run_waveform`).

Which effects each fidelity supports: all of them. Parameter, input and output stages are
independent of the mechanics; the friction stage rescales μ_s and μ_c of the reduced
model's 1-D GMS or of the 3-D model's three 2-D GMS contacts.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import time as _time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
from numba import njit

from .drive import Waveform
from .effects import (
    CATALOGUE,
    EFFECT_FIELDS,
    FRICTION_SEGMENT,
    apply_parameters,
    check_effects,
    detector_stage,
    friction_active,
    friction_scale,
    input_active,
    input_capacity,
    input_rest,
    input_stage_nb,
    pack_effects,
)
from .generator import (
    MODE_ADAPTED,
    MODE_RAMP,
    generate_interval,
    grid_points_nb,
    interval_capacity,
)
from .inputs import Fields, load_json, show
from .kernel_cache import CACHE
from .kernel_types import DriveArrays
from .model import TurntableModel
from .params import ParameterSet, RigParams, get_parameter_set
from .reduced import H_MIN, REDUCED_AXES, ReducedBatch, ReducedModel
from .reduced_kernel import N_REC
from .screw import exp_so3, log_so3
from .validation import check_finite, check_nonnegative

__all__ = [
    "CALIBRATED_FILE",
    "DEFAULT_RANDOMIZATION",
    "FACTORS",
    "FIDELITIES",
    "IntervalResult",
    "Plant",
    "PlantStepper",
    "Records",
    "calibrated_parameters",
    "calibrated_set_toml",
    "load_capacitance",
    "output_capacitance",
    "reduced_model",
    "turntable_model",
]

FIDELITIES = ("reduced", "full")
# multiplicative factors on a parameter set's uncertain values, with their physical bounds
FACTORS: dict[str, tuple[float, float, str]] = {
    "friction": (0.1, 10.0, "μ_s and μ_c together (dry-contact scatter)"),
    "preload": (0.1, 10.0, "normal force F_N of the preload spring (not documented)"),
    "amplifier": (0.1, 10.0, "HVA 900 slew rate per input volt and current limit"),
    "coulomb": (0.1, 10.0, "μ_c alone, on top of friction (μ_c ≤ μ_s)"),
    "stribeck_velocity": (0.01, 100.0, "Stribeck velocity v_S of the contact"),
    "contact_damping": (0.01, 1000.0, "tangential micro-slip damping β_t of the contact"),
    "tube_damping": (0.01, 100.0, "tube loss 1/Q_m"),
}
# Domain randomisation: multiplicative factors drawn uniformly per episode.
DEFAULT_RANDOMIZATION: dict[str, tuple[float, float]] = {
    "friction": (0.8, 1.2),  # µ_s and µ_c together (dry-contact scatter, ±20 %)
    "preload": (0.8, 1.2),  # normal force F_N of the preload spring (unmeasured, ±20 %)
    "amplifier": (0.9, 1.1),  # slew rate per input volt and current limit (±10 %)
    "sensor_noise": (0.5, 2.0),  # detector noise standard deviation
}
SENSOR_NOISE = 1e-3  # V, default detector noise (the env's; the thesis gives none)
ANGLE_SAFE = 0.7  # rad, |θ| passed to the detector (< π/4, where the beam leaves it)
_OUTPUT_COLUMNS = [
    i for i, f in enumerate(EFFECT_FIELDS) if CATALOGUE[f.split(".")[0]].stage == "output"
]


class _Frozen(Mapping):
    """An immutable, hashable mapping (sorted items); nested mappings are frozen too."""

    __slots__ = ("_items",)

    def __init__(self, data: Mapping[str, Any] | None = None) -> None:
        items = []
        for k, v in dict(data or {}).items():
            items.append((str(k), _Frozen(v) if isinstance(v, Mapping) else float(v)))
        self._items = tuple(sorted(items))

    def __getitem__(self, key: str) -> Any:
        for k, v in self._items:
            if k == key:
                return v
        raise KeyError(key)

    def __iter__(self) -> Iterator[str]:
        return (k for k, _ in self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __hash__(self) -> int:
        return hash(self._items)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Mapping) and dict(self) == dict(other)

    def __repr__(self) -> str:
        return "{" + ", ".join(f"{k!r}: {v!r}" for k, v in self._items) + "}"

    def __reduce__(self) -> tuple:
        return (_Frozen, (self.to_dict(),))

    def to_dict(self) -> dict[str, Any]:
        return {k: (v.to_dict() if isinstance(v, _Frozen) else v) for k, v in self._items}


@dataclass(frozen=True)
class Plant:
    """A turntable as a consumer runs it (see the module docstring).

    Args:
        base: the parameter set, ``"real"`` (Table D.1), ``"thesis"`` (Table D.2) or a
            :class:`~turntable_env.params.ParameterSet`.
        factors: multiplicative factors on the base's uncertain values (:data:`FACTORS`):
            ``friction`` (μ_s, μ_c), ``preload`` (F_N), ``amplifier`` (slew, current limit).
        effects: catalogue effect name → {parameter: value} (validated; missing parameters
            take their typical values).
        fidelity: ``"reduced"`` (per-axis model) or ``"full"`` (3-D model).
        sensor_noise: detector voltage noise standard deviation [V].
        ideal_amplifier: run an instant source V = G·u instead of the set's amplifier model
            (the thesis's simulations, §3.4).
        uncertainty: standard deviations of factors (``"friction"``) and effect parameters
            (``"piezo_creep.gamma"``) from a calibration; :meth:`sample` draws from them.
        rig: the laboratory rig's properties (:class:`~turntable_env.params.RigParams`:
            large-signal d₃₁, drive mode, mirror tilt, ...) the base set is built for;
            None keeps the base set's own.
        source: where the plant came from (a report path), for the record.
    """

    base: str | ParameterSet = "real"
    factors: Mapping[str, float] = field(default_factory=dict)
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    fidelity: Literal["reduced", "full"] = "reduced"
    sensor_noise: float = SENSOR_NOISE
    ideal_amplifier: bool = False
    uncertainty: Mapping[str, float] = field(default_factory=dict)
    rig: RigParams | None = None
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if isinstance(self.base, str):
            get_parameter_set(self.base)  # validates the name (ValueError otherwise)
        elif not isinstance(self.base, ParameterSet):
            raise ValueError(f"base={self.base!r}: must be 'real', 'thesis' or a ParameterSet")
        if self.fidelity not in FIDELITIES:
            raise ValueError(f"fidelity={self.fidelity!r}: must be 'reduced' or 'full'")
        if not isinstance(self.ideal_amplifier, bool):
            raise ValueError(f"ideal_amplifier={self.ideal_amplifier!r}: must be a bool")
        check_nonnegative("sensor_noise", self.sensor_noise)
        if isinstance(self.rig, Mapping):
            try:
                object.__setattr__(self, "rig", RigParams(**self.rig))
            except TypeError as exc:
                raise ValueError(f"rig={dict(self.rig)!r}: {exc}") from None
        elif self.rig is not None and not isinstance(self.rig, RigParams):
            raise ValueError(f"rig={self.rig!r}: must be a RigParams, a mapping or None")
        factors = _check_factors(self.factors)
        effects = check_effects(_mapping("effects", self.effects))
        unc = {}
        for name, std in _mapping("uncertainty", self.uncertainty).items():
            if name not in FACTORS and _effect_parameter(name) is None:
                raise ValueError(f"uncertainty[{name!r}]: not a factor or an effect parameter")
            s = check_finite(f"uncertainty[{name!r}]", std)
            if s < 0.0:
                raise ValueError(f"uncertainty[{name!r}]={std!r}: must be >= 0")
            unc[name] = s
        object.__setattr__(self, "factors", _Frozen(factors))
        object.__setattr__(self, "effects", _Frozen(effects))
        object.__setattr__(self, "uncertainty", _Frozen(unc))
        object.__setattr__(self, "sensor_noise", float(self.sensor_noise))

    def __repr__(self) -> str:
        base = self.base if isinstance(self.base, str) else f"<ParameterSet {self.base.name!r}>"
        parts = [f"base={base!r}", f"fidelity={self.fidelity!r}"]
        if self.factors:
            parts.append(f"factors={self.factors!r}")
        if self.effects:
            parts.append(f"effects={self.effects!r}")
        parts.append(f"sensor_noise={self.sensor_noise:g}")
        if self.ideal_amplifier:
            parts.append("ideal_amplifier=True")
        if self.uncertainty:
            parts.append(f"uncertainty={self.uncertainty!r}")
        if self.rig is not None:
            parts.append(f"rig={self.rig!r}")
        return f"Plant({', '.join(parts)})"

    # --- derived -------------------------------------------------------------------------
    @property
    def base_parameters(self) -> ParameterSet:
        """The base parameter set (built for ``rig`` when given), before factors and effects."""
        ps = get_parameter_set(self.base) if isinstance(self.base, str) else self.base
        return ps if self.rig is None else ps.with_rig(self.rig)

    @functools.cached_property
    def params(self) -> ParameterSet:
        """The parameter set the physics runs: base × factors, parameter-stage effects,
        then the amplifier setting."""
        ps = self.base_parameters.with_factors(self.factors)
        ps = apply_parameters(ps, self.effects)
        if self.ideal_amplifier and not ps.amplifier.ideal:
            ps = replace(ps, amplifier=replace(ps.amplifier, ideal=True))
        return ps

    @functools.cached_property
    def effect_row(self) -> np.ndarray:
        """The effects as one row of :data:`~turntable_env.effects.EFFECT_FIELDS`."""
        row = pack_effects(self.effects)
        row.setflags(write=False)
        return row

    @property
    def nominal(self) -> Plant:
        """This plant without effects, factors or uncertainty (the base set as it is)."""
        return replace(self, factors={}, effects={}, uncertainty={})

    def replace(self, **changes: Any) -> Plant:
        """A copy with fields changed (dataclasses.replace)."""
        return replace(self, **changes)

    # --- randomisation -------------------------------------------------------------------
    def sample(
        self,
        rng: np.random.Generator,
        spread: float = 1.0,
        ranges: Mapping[str, tuple[float, float]] | None = None,
    ) -> tuple[Plant, dict[str, float]]:
        """A randomised plant and the values drawn.

        From the calibration's uncertainties when the plant has them and no ``ranges`` are
        given: every factor and effect parameter with a standard error σ is drawn from
        N(estimate, (spread·σ)²), clipped to its bounds. Otherwise factors are drawn
        uniformly from ``ranges`` (default :data:`DEFAULT_RANDOMIZATION`; keys
        ``friction``, ``preload``, ``amplifier``, ``sensor_noise``), widened about 1 by
        ``spread``, and multiply the plant's own factors and noise.
        """
        s = check_nonnegative("spread", spread)
        if ranges is None and self.uncertainty:
            return self._sample_posterior(rng, s)
        r = DEFAULT_RANDOMIZATION if ranges is None else ranges
        draw: dict[str, float] = {}
        for key, (lo, hi) in r.items():
            if key not in DEFAULT_RANDOMIZATION:
                raise ValueError(
                    f"ranges[{key!r}]: unknown (choose from {', '.join(DEFAULT_RANDOMIZATION)})"
                )
            if s != 1.0:
                lo, hi = 1.0 + s * (lo - 1.0), 1.0 + s * (hi - 1.0)
            draw[key] = float(rng.uniform(lo, hi))
        factors = dict(self.factors)
        for key in FACTORS:
            if key in draw:
                factors[key] = factors.get(key, 1.0) * draw[key]
        noise = self.sensor_noise * draw.get("sensor_noise", 1.0)
        return replace(self, factors=factors, sensor_noise=noise, uncertainty={}), draw

    def _sample_posterior(self, rng: np.random.Generator, spread: float) -> tuple[Plant, dict]:
        factors = dict(self.factors)
        effects = {k: dict(v) for k, v in self.effects.items()}
        draw: dict[str, float] = {}
        for name in sorted(self.uncertainty):
            std = spread * self.uncertainty[name]
            if name in FACTORS:
                lo, hi, _ = FACTORS[name]
                x = float(np.clip(rng.normal(factors.get(name, 1.0), std), lo, hi))
                factors[name] = x
            else:
                eff, par = name.split(".")
                p = _effect_parameter(name)
                assert p is not None
                mean = effects.get(eff, CATALOGUE[eff].neutral()).get(par, p.neutral)
                x = float(np.clip(rng.normal(mean, std), p.low, p.high))
                if eff in effects:
                    effects[eff][par] = x
            draw[name] = x
        return replace(self, factors=factors, effects=effects, uncertainty={}), draw

    # --- serialisation -------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (base by name); :meth:`from_dict` reads it back."""
        if not isinstance(self.base, str):
            raise ValueError(
                f"base: a custom ParameterSet ({self.base.name!r}) cannot be written by name"
            )
        return {
            "base": self.base,
            "fidelity": self.fidelity,
            "factors": dict(self.factors),
            "effects": self.effects.to_dict(),  # type: ignore[attr-defined]
            "sensor_noise": self.sensor_noise,
            "ideal_amplifier": self.ideal_amplifier,
            "uncertainty": dict(self.uncertainty),
            "rig": None if self.rig is None else dataclasses.asdict(self.rig),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "") -> Plant:
        """The plant of :meth:`to_dict`'s output; ValueError naming the bad key."""
        if not isinstance(data, Mapping):
            raise ValueError(f"{source or 'plant'}: must be a mapping, got {type(data).__name__}")
        names = {f.name for f in fields(cls)} - {"source"}
        unknown = set(data) - names
        if unknown:
            raise ValueError(f"{source or 'plant'}: unknown key(s) {sorted(unknown)}")
        try:
            return cls(**dict(data), source=source)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{source or 'plant'}: {exc}") from None

    @classmethod
    def from_report(cls, path: str | os.PathLike[str]) -> Plant:
        """The plant a calibration ``report.json`` describes: its nominal estimates, its
        selected effects with their parameters, their standard errors (for :meth:`sample`).

        Raises ValueError naming the file when it cannot be read or does not describe one."""
        p = Path(path)
        if p.is_dir():
            p = p / "report.json"
        data = load_json(p, "calibration report (JSON)")
        if not isinstance(data, dict):
            raise ValueError(f"{p}: not a calibration report (a JSON object expected)")
        if "plant" in data:
            return cls.from_dict(data["plant"], source=str(p))
        if "parameters" not in data or "selected_effects" not in data:
            raise ValueError(f"{p}: not a calibration report (no 'plant' or 'parameters' key)")
        return cls.from_dict(_legacy_plant(data, str(p)), source=str(p))


CALIBRATED_FILE = Path(__file__).with_name("data") / "calibrated.toml"


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    return repr(float(v)) if isinstance(v, float) else str(v)


def _toml_tables(prefix: str, data: Mapping[str, Any], out: list[str]) -> None:
    scalars = {k: v for k, v in data.items() if not isinstance(v, Mapping) and v is not None}
    out.append(f"[{prefix}]")
    out += [f"{k} = {_toml_value(v)}" for k, v in scalars.items()]
    out.append("")
    for k, v in data.items():
        if isinstance(v, Mapping):
            _toml_tables(f"{prefix}.{k}", v, out)


def calibrated_set_toml(plant: Plant, source: str, name: str = "calibrated") -> str:
    """The file of a calibrated parameter set (``data/calibrated.toml``): the plant a
    calibration found, by name (base set, rig, factors, effects, uncertainties)."""
    lines = [
        f"# The parameter set {name!r}: the plant {source} found.",
        "# Read by turntable_env.params.get_parameter_set(" + repr(name) + ") and",
        "# `turntable simulate --params " + name + "`; `turntable calibrate --thesis --report DIR`",
        "# writes DIR/calibrated.toml, of which this file is a copy.",
        "",
    ]
    _toml_tables("set", {"name": name, "source": source}, lines)
    _toml_tables("plant", plant.to_dict(), lines)
    return "\n".join(lines)


def calibrated_parameters(path: str | os.PathLike[str] | None = None) -> ParameterSet:
    """The calibrated parameter set of a :func:`calibrated_set_toml` file (default: the
    shipped ``data/calibrated.toml``). Raises ValueError naming the file."""
    import tomllib

    p = Path(path) if path is not None else CALIBRATED_FILE
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
        name = str(data["set"]["name"])
        plant = Plant.from_dict(data["plant"], source=str(p))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"{p}: not a calibrated parameter set: {exc}") from None
    return replace(plant.params, name=name)


def _legacy_plant(data: Mapping[str, Any], src: str) -> dict[str, Any]:
    """Reports written before the plant key: nominal factors and selected effects."""
    pars = data["parameters"]
    selected = data["selected_effects"]
    if not isinstance(pars, Mapping):
        raise ValueError(f"{src}: parameters = {show(pars)}: must be an object")
    if not isinstance(selected, list) or not all(isinstance(x, str) for x in selected):
        raise ValueError(f"{src}: selected_effects = {show(selected)}: must be a list of names")
    factors, effects, unc = {}, {}, {}
    for owner, entries in pars.items():
        f = Fields(entries, f"{src}: parameters.{owner}")
        for name in f.table:
            v = Fields(f.table[name], f"{src}: parameters.{owner}.{name}")
            value = v.number("value")
            raw = v.table.get("std")
            unknown = raw is None or (isinstance(raw, float) and math.isnan(raw))
            std = math.nan if unknown else v.number("std", low=0.0)
            key = name if owner == "nominal" else f"{owner}.{name}"
            if owner == "nominal":
                factors[name] = value
            elif owner in selected:
                effects.setdefault(owner, {})[name] = value
            else:
                continue
            if math.isfinite(std):
                unc[key] = std
    return {"factors": factors, "effects": effects, "uncertainty": unc}


def _mapping(name: str, value: Any) -> Mapping:
    if not isinstance(value, Mapping):
        raise ValueError(f"{name}={value!r}: must be a mapping")
    return value


def _check_factors(factors: Any) -> dict[str, float]:
    out = {}
    for key, value in _mapping("factors", factors).items():
        if key not in FACTORS:
            raise ValueError(f"factors[{key!r}]: unknown (choose from {', '.join(FACTORS)})")
        x = check_finite(f"factors[{key!r}]", value)
        lo, hi, _ = FACTORS[key]
        if not lo <= x <= hi:
            raise ValueError(f"factors[{key!r}]={value!r}: must be within {lo:g}…{hi:g}")
        out[key] = x
    return out


def _effect_parameter(name: str) -> Any:
    eff, _, par = name.partition(".")
    if eff not in CATALOGUE:
        return None
    return next((p for p in CATALOGUE[eff].parameters if p.name == par), None)


# --- models, cached -------------------------------------------------------------------------
@functools.lru_cache(maxsize=64)
def turntable_model(ps: ParameterSet) -> TurntableModel:
    """The 3-D model of a parameter set (the last 64 are cached)."""
    return TurntableModel(ps)


_BODIES: dict[tuple[Any, Any, str], TurntableModel] = {}


def _bodies(ps: ParameterSet) -> TurntableModel:
    """A 3-D model with the table, tubes and wiring of ``ps`` (the first built for them):
    what the reduced model's condensation and the channel's load capacitance need."""
    key = (ps.table, ps.tube, ps.rig.drive_mode)
    if key not in _BODIES:
        if len(_BODIES) >= 16:
            _BODIES.pop(next(iter(_BODIES)))
        _BODIES[key] = turntable_model(ps)
    return _BODIES[key]


def load_capacitance(ps: ParameterSet, axis: str) -> float:
    """Capacitance channel ``axis`` drives [F]: its quadrants (Eq. 2.2) in parallel (the
    electrical energy's load)."""
    return _bodies(ps).load_capacitance(axis)


def output_capacitance(ps: ParameterSet, axis: str) -> float:
    """Capacitance on one amplifier output of channel ``axis`` [F] (its current limit's
    load; half the channel's in the symmetric drive mode)."""
    return _bodies(ps).output_capacitance(axis)


@functools.lru_cache(maxsize=128)
def reduced_model(ps: ParameterSet, axis: str) -> ReducedModel:
    """The reduced model of ``ps`` about ``axis``, condensed from a cached 3-D model of its
    table and tubes (friction, preload and amplifier come from ``ps``); cached."""
    return ReducedModel(ps, axis, model=_bodies(ps))


# --- the stepper ------------------------------------------------------------------------------
class IntervalResult(NamedTuple):
    """What one control interval of :meth:`PlantStepper.advance` produced (arrays over N).

    Attributes:
        angle: true table angle at the interval's end [rad]; flybacks: stick–slip steps the
        generator started; energy: electrical energy C∫|V dV| [J]; phase: generator phase.
    """

    angle: np.ndarray
    flybacks: np.ndarray
    energy: np.ndarray
    phase: np.ndarray


class Records(NamedTuple):
    """Recorded true angles of one turntable: time [s], angle [rad]."""

    time: np.ndarray
    angle: np.ndarray


class _ReducedBackend:
    """N reduced per-axis models integrated together (:class:`~.reduced.ReducedBatch`)."""

    def __init__(self, params: Sequence[ParameterSet], axis: str) -> None:
        if axis not in REDUCED_AXES:
            raise ValueError(f"axis={axis!r}: the reduced model covers {', '.join(REDUCED_AXES)}")
        self.axis = axis
        self.batch = ReducedBatch([reduced_model(ps, axis) for ps in params])
        self.grid = self.batch.grid

    def set_params(self, b: int, ps: ParameterSet) -> None:
        if ps != self.batch.models[b].params:
            self.batch.set_model(b, reduced_model(ps, self.axis))

    def reset(self, b: int, angle: float, time: float, voltage: float) -> None:
        self.batch.set_state(b, self.batch.models[b].rest_state(angle, voltage), time)

    def displace(self, b: int, delta: float) -> None:
        st = self.batch.state
        rest = self.batch.models[b].rest_state(
            float(self.batch.angle[b]) + delta, float(st.volt[b])
        )
        st.y[b], st.f[b], st.st[b] = rest["y"], rest["f"], rest["st"]  # amplifier state kept

    def grid_time(self) -> np.ndarray:
        return self.batch.state.n

    def set_friction_scale(self, rows: np.ndarray, scale: np.ndarray) -> None:
        self.batch.set_friction_scale(rows, scale)

    def advance(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        nb = n_end.size
        if out_every <= 0:  # no records
            rec = np.zeros((nb, 0, N_REC))
            self.batch.advance(drive, n_end, np.maximum(n_end, 1), rec, np.zeros(nb, np.int64))
            return []
        n0 = self.batch.state.n
        n_out = int(np.max((n_end - n0) // out_every)) + 2
        rec = np.zeros((nb, n_out, N_REC))
        n_rec = np.zeros(nb, dtype=np.int64)
        self.batch.advance(drive, n_end, np.full(nb, out_every, np.int64), rec, n_rec)
        out = []
        for b in range(nb):  # the records, and the end where it is off the record grid
            t, a = rec[b, : n_rec[b], 0], rec[b, : n_rec[b], 1]
            t_end = n_end[b] * self.grid
            if t.size == 0 or t[-1] < t_end - 1e-15:
                t, a = np.append(t, t_end), np.append(a, self.batch.angle[b])
            out.append(Records(t.copy(), a.copy()))
        return out

    def angles(self) -> np.ndarray:
        return self.batch.angle.copy()

    def snapshot(self, b: int) -> dict[str, Any]:
        st = self.batch.stick[b]
        return {
            "tube_deflection": self.batch.tube_displacement[b].copy(),
            "stick_fraction": st.sum(axis=1) / st.shape[1],
            "voltage": float(self.batch.volt[b]),
            "tubes": self.batch.models[b].axis_params.tubes,
            "axis": self.axis,
            "axis_stick_fraction": None,  # the axis tube's contact only spins: not modelled
        }


class _FullBackend:
    """The 3-D model, one turntable after another (each resumed from its final state)."""

    def __init__(self, params: Sequence[ParameterSet], axis: str) -> None:
        if axis not in REDUCED_AXES:
            raise ValueError(f"axis={axis!r}: the env and the plant layer turn about A, B or C")
        self.axis = axis
        self.c = "ABC".index(axis)
        self.models = [turntable_model(ps) for ps in params]
        self.unit = self.models[0].layout.axis_units[self.c]
        self.states = [m.rest_state() for m in self.models]
        self.n = np.zeros(len(params), dtype=np.int64)
        self.grid = H_MIN  # s, breakpoint grid shared with the reduced model
        self.scale = np.ones(len(params))

    def set_params(self, b: int, ps: ParameterSet) -> None:
        if ps != self.models[b].params:
            self.models[b] = turntable_model(ps)

    def reset(self, b: int, angle: float, time: float, voltage: float) -> None:
        vch = np.zeros(4)
        vch[self.c] = voltage
        st = self.models[b].rest_state(vch)
        st.rot[:] = exp_so3(angle * self.unit)
        self.states[b] = st
        self.n[b] = round(time / self.grid)

    def displace(self, b: int, delta: float) -> None:
        volt = float(self.states[b].vch[self.c])
        self.reset(b, self.angle(b) + delta, self.n[b] * self.grid, volt)

    def grid_time(self) -> np.ndarray:
        return self.n

    def set_friction_scale(self, rows: np.ndarray, scale: np.ndarray) -> None:
        self.scale[rows] = scale

    def advance(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        out = []
        for b in range(n_end.size):
            t0, t1 = self.n[b] * self.grid, float(n_end[b]) * self.grid
            if t1 <= t0:
                out.append(Records(np.array([t0]), np.array([self.angle(b)])))
                continue
            nw = drive.count[b]
            wave = Waveform(drive.times[b, :nw] * self.grid, drive.values[b, :nw])
            odt = out_every * self.grid if out_every > 0 else t1 - t0
            raw = self.models[b].run(
                {self.axis: wave}, t1 - t0, start=t0, initial_state=self.states[b],
                coarse_factor=0.5, output_dt=odt, friction_scale=float(self.scale[b]),
            )  # fmt: skip
            self.states[b] = raw["final"]
            self.n[b] = n_end[b]
            if out_every > 0:
                st = raw["state"]
                out.append(Records(st[:, 0].copy(), st[:, 4:7] @ self.unit))
        return out

    def angle(self, b: int) -> float:
        return float(log_so3(self.states[b].rot) @ self.unit)

    def angles(self) -> np.ndarray:
        return np.array([self.angle(b) for b in range(len(self.states))])

    def snapshot(self, b: int) -> dict[str, Any]:
        model = self.models[b]
        ar = model.packed
        r_ball = model.params.tube.outer_radius  # m
        st = self.states[b]
        defl, frac, tubes = [], [], []
        for k in range(3):
            if k == self.c:
                continue
            d = ar["d_nom"][k]
            e = np.cross(self.unit, d)
            e /= np.linalg.norm(e)
            r_c = ar["r0"][k] - r_ball * d  # tube top → contact point [m]
            defl.append(float(st.xi[k, :3] @ np.cross(r_c, e) + st.xi[k, 3:6] @ e))  # u_c = aᵀξ
            frac.append(float(st.gst[k].mean()))
            tubes.append("ABC"[k])
        return {
            "tube_deflection": np.array(defl),
            "stick_fraction": np.array(frac),
            "voltage": float(st.vch[self.c]),
            "tubes": tuple(tubes),
            "axis": self.axis,
            "axis_stick_fraction": float(st.gst[self.c].mean()),
        }


@njit(cache=CACHE)
def _input_stage_batch(drive, rows, active, plays, creep, ref, grid, out, scr_t, scr_v):
    """The input stage on every active row of a grid-unit drive, re-gridded into ``out``."""
    for b in range(drive.count.shape[0]):
        n = drive.count[b]
        if not active[b]:
            for i in range(n):
                out.times[b, i] = drive.times[b, i]
                out.values[b, i] = drive.values[b, i]
            out.count[b] = n
            continue
        m = input_stage_nb(drive.times[b], drive.values[b], n, grid, rows[b], plays[b],
                           creep[b], ref[b:b + 1], scr_t, scr_v)  # fmt: skip
        out.count[b] = grid_points_nb(scr_t, scr_v, m, 1.0, out.times[b], out.values[b])


class PlantStepper:
    """N plants about one axis, advanced together (see the module docstring).

    Args:
        plants: one :class:`Plant` per turntable, all of one fidelity.
        axis: "A", "B" or "C".
        noise: detector noise on (each plant's ``sensor_noise``) or off.

    Attributes:
        plants: the plants in use; kernel_seconds: wall time spent in the compiled
        integrator so far [s] (``turntable bench`` reports its share).
    """

    def __init__(self, plants: Sequence[Plant], axis: str = "B", *, noise: bool = True) -> None:
        if not plants:
            raise ValueError("plants: need at least one plant")
        fid = {p.fidelity for p in plants}
        if len(fid) > 1:
            raise ValueError(f"plants: one fidelity per stepper, got {sorted(fid)}")
        self.plants = list(plants)
        self.axis = axis
        self.noise = bool(noise)
        n = len(plants)
        params = [p.params for p in plants]
        backend = _ReducedBackend if plants[0].fidelity == "reduced" else _FullBackend
        self._physics = backend(params, axis)
        self.grid = self._physics.grid
        self.kernel_seconds = 0.0
        # per-plant constants
        self._rows = np.stack([p.effect_row for p in plants])
        self._neutral_row = pack_effects({})
        self._amp = np.empty((n, 7))
        self._c_load = np.empty(n)
        self._radius = np.empty(n)
        self._noise_std = np.empty(n)
        self._detector = params[0].detector
        for b, p in enumerate(plants):
            self._constants(b, p)
        self._refresh_flags()
        # per-plant state
        self._phase = np.zeros(n)  # generator phase in the running period
        self._running = np.zeros((n, 6))  # running setting (idle)
        self._running[:, 1] = 100.0
        self._offset = np.zeros(n)  # V, scan level at the last interval's end
        self._n_start = np.zeros(n, dtype=np.int64)  # grid time of the last reset
        self._plays, self._creep, self._ref = input_rest(np.zeros(n), n)
        self._direction = np.zeros(n)  # sign of the table's last motion (friction stage)
        self._travel = np.zeros(n)  # m travelled at the table radius (friction stage)

    def __len__(self) -> int:
        return len(self.plants)

    def _refresh_flags(self) -> None:
        """Which rows have input- and friction-stage effects, whether any has an output one."""
        self._input_on = input_active(self._rows)
        self._friction_on = friction_active(self._rows)
        out = _OUTPUT_COLUMNS
        self._output_on = bool((self._rows[:, out] != self._neutral_row[out]).any())

    def _constants(self, b: int, plant: Plant) -> None:
        ps = plant.params
        if ps.detector != self._detector:
            raise ValueError(f"plants[{b}]: its detector differs from the others'")
        self._rows[b] = plant.effect_row
        self._c_load[b] = load_capacitance(ps, self.axis)  # the energy's load
        self._amp[b] = ps.amplifier.kernel_row(output_capacitance(ps, self.axis))
        self._radius[b] = ps.table.radius
        self._noise_std[b] = plant.sensor_noise if self.noise else 0.0

    # --- per-turntable setup ---------------------------------------------------------------
    def set_plant(self, b: int, plant: Plant) -> None:
        """Replace turntable b's plant (domain randomisation); call :meth:`reset` after."""
        if plant.fidelity != self.plants[0].fidelity:
            raise ValueError(f"plant: fidelity {plant.fidelity!r} differs from the stepper's")
        self._physics.set_params(b, plant.params)
        self._constants(b, plant)
        self.plants[b] = plant
        self._refresh_flags()

    def reset(self, b: int, angle: float = 0.0, time: float = 0.0, level: float = 0.0) -> None:
        """Turntable b at rest at ``angle`` [rad] and ``time`` [s] with the amplifier input at
        ``level`` [V] (tubes bent by it, every element stuck), the generator idle, the
        effects' states at rest and the detector's time origin here."""
        amp = self._amp[b]
        lv = float(np.clip(level, -amp[3], amp[3]))
        self._physics.reset(b, float(angle), float(time), lv * amp[0])
        self._phase[b] = 0.0
        self._running[b] = (0.0, 100.0, 0.95, 0.0, 0.0, MODE_RAMP)
        self._offset[b] = lv
        self._n_start[b] = round(time / self.grid)
        plays, creep, ref = input_rest(np.array([lv]), 1)
        self._plays[b], self._creep[b], self._ref[b] = plays[0], creep[0], ref[0]
        self._direction[b] = 0.0
        self._travel[b] = 0.0

    def displace(self, b: int, delta: float) -> None:
        """A knock: turntable b's table jumps by ``delta`` [rad] now and every contact sticks
        again at the new angle; the tubes keep the bend of the present amplifier voltage, the
        generator, the amplifier and the effects' states run on (a disturbance for the
        controller benchmark)."""
        self._physics.displace(b, check_finite("delta", delta))

    # --- stepping --------------------------------------------------------------------------
    @property
    def time(self) -> np.ndarray:
        """(N,) simulated time [s]."""
        return self._physics.grid_time() * self.grid

    @property
    def angle(self) -> np.ndarray:
        """(N,) true table angles [rad] (evaluation only: a controller sees :meth:`observe`)."""
        return self._physics.angles()

    def advance(self, settings: np.ndarray, interval: float) -> IntervalResult:
        """Advance every turntable one control interval of ``interval`` [s] (a multiple of
        the grid) under its generator setting.

        Args:
            settings: (N, 5) amplitude [V input] (signed; 0 idles the generator), frequency
                [Hz], ramp ratio a, slew adaptation k (> 0: the Fig. 4.3 adapted flyback), scan
                offset at the interval's end [V input] (ramped from the last one).
        """
        s = np.asarray(settings, dtype=float)
        n = len(self)
        n_steps = round(interval / self.grid)
        pending = np.empty((n, 6))
        pending[:, :4] = s[:, :4]
        pending[:, 4] = 0.0
        pending[:, 5] = np.where(s[:, 3] > 0.0, MODE_ADAPTED, MODE_RAMP)
        cap = interval_capacity(float(max(s[:, 1].max(), self._running[:, 1].max())), interval)
        drive = DriveArrays(np.zeros((n, cap)), np.zeros((n, cap)), np.zeros(n, np.int64))
        flybacks = np.zeros(n, dtype=np.int64)
        energy = np.zeros(n)
        n0 = self._physics.grid_time().copy()
        offset1 = s[:, 4].copy()
        generate_interval(
            n0, n_steps, float(interval), self.grid, self._phase, self._running, pending,
            self._offset, offset1, self._amp, self._c_load, drive.times, drive.values,
            drive.count, flybacks, energy,
        )  # fmt: skip
        self._offset[:] = offset1
        drive = self._input_stage(drive, float(interval))
        self._integrate(drive, n0 + n_steps, 0)
        return IntervalResult(self.angle, flybacks, energy, self._phase.copy())

    def run_waveform(
        self, waves: Sequence[Waveform], duration: float, output_dt: float
    ) -> list[Records]:
        """Drive every turntable with an explicit input (``waves``, times from its current
        time [s], values [V]) for ``duration`` [s]; the true angle every ``output_dt`` [s]
        (the last record at the end)."""
        n = len(self)
        if len(waves) != n:
            raise ValueError(f"waves: {len(waves)} for {n} plants")
        nbp = max(w.times.size for w in waves) * 2
        drive = DriveArrays(np.zeros((n, nbp)), np.zeros((n, nbp)), np.zeros(n, np.int64))
        n0 = self._physics.grid_time().copy()
        for b, w in enumerate(waves):
            t = w.times / self.grid + n0[b]  # the kernel clips to the input range
            drive.count[b] = grid_points_nb(t, w.values, t.size, 1.0, drive.times[b],
                                            drive.values[b])  # fmt: skip
        drive = self._input_stage(drive, duration)
        out_every = max(round(output_dt / self.grid), 1)
        return self._integrate(drive, n0 + round(duration / self.grid), out_every)

    def _input_stage(self, drive: DriveArrays, span: float) -> DriveArrays:
        active = self._input_on
        if not active.any():
            return drive
        cap = max(
            input_capacity(int(drive.count[b]), span, self._rows[b]) for b in np.flatnonzero(active)
        )
        n = len(self)
        cap = max(cap, drive.times.shape[1])
        out = DriveArrays(np.zeros((n, cap)), np.zeros((n, cap)), np.zeros(n, np.int64))
        _input_stage_batch(drive, self._rows, active, self._plays, self._creep, self._ref,
                           self.grid, out, np.empty(cap), np.empty(cap))  # fmt: skip
        return out

    def _integrate(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        """The kernel to grid time n_end, in friction segments where friction effects act."""
        fric = self._friction_on
        phys = self._physics
        if not fric.any():
            return self._kernel(drive, n_end, out_every)
        seg = max(round(FRICTION_SEGMENT / self.grid), 1)
        if out_every > 0:
            seg = out_every * max(round(seg / out_every), 1)
        rows = np.flatnonzero(fric)
        parts: list[list[Records]] = []
        while True:
            n_now = phys.grid_time()
            if (n_now >= n_end).all():
                break
            k = (n_now - self._n_start) // seg + 1
            seg_end = np.where(fric, np.minimum(n_end, self._n_start + k * seg), n_end)
            phys.set_friction_scale(rows, friction_scale(self._rows[rows], self._direction[rows],
                                                         self._travel[rows]))  # fmt: skip
            before = self.angle
            parts.append(self._kernel(drive, seg_end, out_every))
            dth = self.angle - before
            moved = fric & (np.abs(dth) > 1e-9)
            self._direction[moved] = np.sign(dth[moved])
            self._travel[fric] += np.abs(dth[fric]) * self._radius[fric]
        if out_every <= 0:
            return []
        return [_join([p[b] for p in parts]) for b in range(len(self))]

    def _kernel(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        t = _time.perf_counter()
        out = self._physics.advance(drive, n_end, out_every)
        self.kernel_seconds += _time.perf_counter() - t
        return out

    # --- detector ----------------------------------------------------------------------------
    def observe(
        self,
        rng: np.random.Generator | None = None,
        rows: np.ndarray | None = None,
        normals: np.ndarray | None = None,
    ) -> np.ndarray:
        """Detector x voltage [V] of turntables ``rows`` (default all) now: the output-stage
        effects (time since the last reset), then noise (one standard normal draw per row,
        times the plant's ``sensor_noise``; ``normals`` gives the draws instead of ``rng``,
        for common random numbers across runs) and saturation (Eq. 4.1, §4.1.3)."""
        r = np.arange(len(self)) if rows is None else np.asarray(rows)
        th = np.clip(self.angle[r], -ANGLE_SAFE, ANGLE_SAFE)
        det = self._detector
        if self._output_on:
            t = (self._physics.grid_time()[r] - self._n_start[r]) * self.grid
            x, _y = detector_stage(th, t, self._rows[r], det)
        else:  # Eq. 4.1, as detector_stage gives it with every output effect neutral
            x = det.unclipped_voltage(th)
        vs = det.saturation_voltage
        x = np.clip(x, -vs, vs)  # the photodiode saturates, its electronics add the noise
        if normals is not None:
            z = np.asarray(normals, dtype=float)
            if z.shape != (r.size,) or not np.isfinite(z).all():
                raise ValueError(f"normals: shape {z.shape}, expected ({r.size},), finite")
            x = np.clip(x + z * self._noise_std[r], -vs, vs)
        elif rng is not None:
            x = np.clip(x + rng.normal(0.0, 1.0, size=r.size) * self._noise_std[r], -vs, vs)
        return x

    def observe_trace(
        self, b: int, t: np.ndarray, theta: np.ndarray, rng: np.random.Generator | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Detector (x, y) voltages [V] of a recorded angle trace of turntable b at times t
        [s] since its reset: output-stage effects, noise on both channels, saturation."""
        x, y = detector_stage(theta, t, self._rows[b], self._detector)
        vs = self._detector.saturation_voltage
        x, y = np.clip(x, -vs, vs), np.clip(y, -vs, vs)
        std = self._noise_std[b]
        if rng is not None and std > 0.0:
            x = np.clip(x + rng.normal(0.0, 1.0, size=x.shape) * std, -vs, vs)
            y = np.clip(y + rng.normal(0.0, 1.0, size=y.shape) * std, -vs, vs)
        return x, y

    def snapshot(self, b: int) -> dict[str, Any]:
        """Render data of turntable b: the driving tubes' contact deflections along their
        bending directions e_k = n × d_k [m] and sticking fractions, channel voltage [V],
        the driving tubes' names, the rotation axis (the third tube's name) and that tube's
        sticking fraction (None where the fidelity does not model its spinning contact)."""
        return self._physics.snapshot(b)


def _join(parts: list[Records]) -> Records:
    """Records of consecutive segments, repeated boundary times dropped."""
    t = np.concatenate([p.time for p in parts])
    a = np.concatenate([p.angle for p in parts])
    keep = np.ones(t.size, dtype=bool)
    keep[1:] = t[1:] > t[:-1] + 1e-15
    return Records(t[keep], a[keep])
