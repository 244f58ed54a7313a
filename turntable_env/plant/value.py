"""The plant value: :class:`Plant`, a turntable as every consumer runs it (see
:mod:`turntable_env.plant`), its factor table and the named parameter sets it resolves.

Immutable, hashable and picklable. Base sets ``"real"`` and ``"thesis"`` come from the
parameter layer; named plants (``"calibrated"``) from the store (:mod:`.store`), whole
(:meth:`Plant.named`) or as a parameter set (:func:`parameter_set`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, Literal

import numpy as np

from ..effects import CATALOGUE, apply_parameters, check_effects, pack_effects
from ..params import FACTORS, ParameterSet, RigParams, get_parameter_set
from ..params import PARAMETER_SETS as BASE_SETS
from ..validation import check_finite, check_nonnegative, check_path
from ..validation import describe as show
from .store import NAMED_PLANTS, named_plant_dict, report_plant_dict

__all__ = [
    "DEFAULT_RANDOMIZATION",
    "FACTORS",
    "FIDELITIES",
    "MAX_SENSOR_NOISE",
    "PARAMETER_SETS",
    "SENSOR_NOISE",
    "Plant",
    "as_plant",
    "calibrated_parameters",
    "parameter_set",
    "set_or_plant",
]

FIDELITIES = ("reduced", "translation", "full", "independent")
# Domain randomisation: multiplicative factors drawn uniformly per episode.
DEFAULT_RANDOMIZATION: dict[str, tuple[float, float]] = {
    "friction": (0.8, 1.2),  # µ_s and µ_c together (dry-contact scatter, ±20 %)
    "preload": (0.8, 1.2),  # normal force F_N of the preload spring (unmeasured, ±20 %)
    "amplifier": (0.9, 1.1),  # slew rate per input volt and current limit (±10 %)
    "sensor_noise": (0.5, 2.0),  # detector noise standard deviation
}
SENSOR_NOISE = 1e-3  # V, default detector noise (the env's; the thesis gives none)
MAX_SENSOR_NOISE = 15.0  # V, largest detector noise std: beyond the detector's ±10 V range


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
        fidelity: ``"reduced"`` (per-axis model), ``"translation"`` (the per-axis model
            with the sphere's translation and tilts and the contacts' normal forces,
            :class:`~turntable_env.reduced.TranslationParameters`), ``"full"`` (3-D model)
            or ``"independent"`` (the independent test plant).
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
    fidelity: Literal["reduced", "translation", "full", "independent"] = "reduced"
    sensor_noise: float = SENSOR_NOISE
    ideal_amplifier: bool = False
    uncertainty: Mapping[str, float] = field(default_factory=dict)
    rig: RigParams | None = None
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if isinstance(self.base, str):
            if self.base not in PARAMETER_SETS:
                raise ValueError(
                    f"base={self.base!r}: must be one of {', '.join(PARAMETER_SETS)} or a "
                    "ParameterSet"
                )
        elif not isinstance(self.base, ParameterSet):
            raise ValueError(f"base={self.base!r}: must be 'real', 'thesis' or a ParameterSet")
        if self.fidelity not in FIDELITIES:
            raise ValueError(f"fidelity={self.fidelity!r}: must be one of {', '.join(FIDELITIES)}")
        if not isinstance(self.ideal_amplifier, bool):
            raise ValueError(f"ideal_amplifier={self.ideal_amplifier!r}: must be a bool")
        if check_nonnegative("sensor_noise", self.sensor_noise) > MAX_SENSOR_NOISE:
            raise ValueError(
                f"sensor_noise={self.sensor_noise!r}: must be <= {MAX_SENSOR_NOISE:g} V"
            )
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
        ps = parameter_set(self.base) if isinstance(self.base, str) else self.base
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

    def on_parameters(self, ps: ParameterSet) -> Plant:
        """This plant's other stages (input, friction and output effects, detector noise,
        fidelity) on the parameter set ``ps``, which stands for base, rig, factors and
        parameter-stage effects — e.g. ``self.params`` with another amplifier mode
        (:func:`~turntable_env.simulation.stepping_drive`)."""
        kept = {k: v for k, v in self.effects.items() if CATALOGUE[k].stage != "parameters"}
        return replace(self, base=ps, rig=None, factors={}, effects=kept,
                       ideal_amplifier=False, uncertainty={})  # fmt: skip

    def replace(self, **changes: Any) -> Plant:
        """A copy with fields changed (dataclasses.replace); an unknown field is a
        ValueError naming it and the fields there are."""
        known = [f.name for f in fields(self) if f.init]
        for name in changes:
            if name not in known:
                raise ValueError(f"{name}: not a field of Plant ({', '.join(known)})")
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
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng={rng!r}: must be a numpy.random.Generator")
        if ranges is None and self.uncertainty:
            return self._sample_posterior(rng, s)
        r = self.check_ranges(DEFAULT_RANDOMIZATION if ranges is None else ranges, s)
        draw = {key: float(rng.uniform(lo, hi)) for key, (lo, hi) in r.items()}
        factors = dict(self.factors)
        for key in FACTORS:
            if key in draw:
                factors[key] = factors.get(key, 1.0) * draw[key]
        noise = self.sensor_noise * draw.get("sensor_noise", 1.0)
        return replace(self, factors=factors, sensor_noise=noise, uncertainty={}), draw

    def check_ranges(
        self, ranges: Mapping[str, tuple[float, float]], spread: float = 1.0,
        name: str = "ranges",
    ) -> dict[str, tuple[float, float]]:  # fmt: skip
        """``ranges`` widened by ``spread`` (:meth:`sample`), checked before any draw: known
        keys, positive finite bounds, low ≤ high, and this plant's own factor times either
        bound within the factor's physical bounds (:data:`FACTORS`), so no later draw fails.
        ValueError naming ``name``, the key and the range otherwise."""
        out = {}
        for key, rng in ranges.items():
            if key not in DEFAULT_RANDOMIZATION:
                raise ValueError(
                    f"{name}[{key!r}]: unknown (choose from {', '.join(DEFAULT_RANDOMIZATION)})"
                )
            try:
                lo, hi = (float(x) for x in rng)
            except (TypeError, ValueError):
                raise ValueError(f"{name}[{key!r}]={rng!r}: must be (low, high)") from None
            if spread != 1.0:
                lo, hi = 1.0 + spread * (lo - 1.0), 1.0 + spread * (hi - 1.0)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo <= hi):
                raise ValueError(f"{name}[{key!r}]=({lo:g}, {hi:g}): need 0 < low <= high")
            if key == "sensor_noise" and self.sensor_noise * hi > MAX_SENSOR_NOISE:
                raise ValueError(
                    f"{name}[{key!r}]=({lo:g}, {hi:g}): times the plant's noise "
                    f"{self.sensor_noise:g} V it exceeds {MAX_SENSOR_NOISE:g} V"
                )
            if key in FACTORS:
                own = self.factors.get(key, 1.0)
                b_lo, b_hi, _ = FACTORS[key]
                if own * lo < b_lo or own * hi > b_hi:
                    raise ValueError(
                        f"{name}[{key!r}]=({lo:g}, {hi:g}): times the plant's factor {own:g} "
                        f"it leaves the factor's bounds {b_lo:g}…{b_hi:g}"
                    )
            out[key] = (lo, hi)
        return out

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
        """The plant a calibration ``report.json`` (or its directory) describes: its
        nominal estimates, its selected effects with their parameters, their standard
        errors (for :meth:`sample`). Raises ValueError naming the file when it cannot be
        read or does not describe one (:func:`.store.report_plant_dict`)."""
        p = check_path("report", path)
        p = p / "report.json" if p.is_dir() else p
        return cls.from_dict(report_plant_dict(p), source=str(p))

    @classmethod
    def load(cls, source: str | os.PathLike[str]) -> Plant:
        """The plant ``source`` names: a parameter set or a named plant
        (:data:`PARAMETER_SETS`, as :func:`as_plant`), a named-plant file
        (``*.toml``, :meth:`from_toml`: a calibration's ``calibrated.toml``) or a
        calibration report (``report.json`` or its directory, :meth:`from_report`).
        ValueError naming ``source`` for anything else — a missing file, a bad file, or a
        set's name that is also a path here (``./NAME`` for the path)."""
        if isinstance(source, str) and source in PARAMETER_SETS:
            if os.path.exists(source):  # both: say which is meant, never guess
                raise ValueError(
                    f"plant {source!r}: both a parameter set and a path here; give the path "
                    f"as './{source}'"
                )
            return as_plant(source)
        p = check_path("plant", source)
        if not p.exists():
            raise ValueError(
                f"plant {str(p)!r}: no such file or directory (a set: {', '.join(PARAMETER_SETS)};"
                " or a calibration's calibrated.toml, report.json or report directory)"
            )
        return cls.from_toml(p) if p.suffix.lower() == ".toml" else cls.from_report(p)

    @classmethod
    def named(cls, name: str) -> Plant:
        """A named plant of the store, whole — base set, rig, factors, effects, fidelity,
        detector noise and the calibration's uncertainties (``"calibrated"``:
        ``data/calibrated.toml``). ValueError for an unknown name or a bad file."""
        if not isinstance(name, str) or name not in NAMED_PLANTS:
            raise ValueError(
                f"plant {show(name)}: unknown (named plants: {', '.join(NAMED_PLANTS)})"
            )
        return _named_plant(name)

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> Plant:
        """The plant of a named-plant file (:func:`.store.plant_toml`'s format)."""
        p = check_path("plant file", path)
        _name, data = named_plant_dict(p)
        return cls.from_dict(data, source=str(p))


@functools.lru_cache(maxsize=8)
def _named_plant(name: str) -> Plant:
    _n, data = named_plant_dict(NAMED_PLANTS[name])
    return Plant.from_dict(data, source=str(NAMED_PLANTS[name]))


PARAMETER_SETS = (*BASE_SETS, *NAMED_PLANTS)


@functools.lru_cache(maxsize=8)
def parameter_set(name: str) -> ParameterSet:
    """A named parameter set: ``"real"`` (Table D.1), ``"thesis"`` (Table D.2)
    (:func:`turntable_env.params.get_parameter_set`), or a named plant of the store
    (``"calibrated"``) with its factors and parameter-stage effects applied; cached."""
    if name in BASE_SETS:
        return get_parameter_set(name)  # type: ignore[arg-type]
    if name in NAMED_PLANTS:
        return replace(_named_plant(name).params, name=name)
    raise ValueError(f"set={name!r}: must be one of {', '.join(PARAMETER_SETS)}")


def as_plant(plant: Plant | ParameterSet | str) -> Plant:
    """The plant a simulation runs: a :class:`Plant` as it is; a name as the store's named
    plant, whole (``"calibrated"``), or as the base set (``"real"``, ``"thesis"``); a
    :class:`~turntable_env.params.ParameterSet` as the plant on it, without factors or
    effects (``Plant(base=ps).params`` is ``ps``). ValueError for anything else."""
    if isinstance(plant, Plant):
        return plant
    if isinstance(plant, ParameterSet):
        return Plant(base=plant)
    if isinstance(plant, str):
        if plant in NAMED_PLANTS:
            return Plant.named(plant)
        if plant in BASE_SETS:
            return Plant(plant)
        raise ValueError(f"plant={plant!r}: must be one of {', '.join(PARAMETER_SETS)}")
    raise ValueError(f"plant={plant!r}: must be a Plant, a ParameterSet or a set name")


def set_or_plant(source: str | os.PathLike[str]) -> str | Plant:
    """A base as the calibrator takes it (``turntable calibrate --base``): a set's name as
    the name (``Plant(name, fidelity=...)`` builds it), anything else the plant
    :meth:`Plant.load` reads — a lab's earlier calibration. ValueError as there."""
    if isinstance(source, str) and source in PARAMETER_SETS and not os.path.exists(source):
        return source
    return Plant.load(source)


def calibrated_parameters(path: str | os.PathLike[str] | None = None) -> ParameterSet:
    """The calibrated parameter set of a named-plant file (default: the shipped
    ``data/calibrated.toml``). Raises ValueError naming the file."""
    if path is None:
        return parameter_set("calibrated")
    name, data = named_plant_dict(path)
    return replace(Plant.from_dict(data, source=str(path)).params, name=name)


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
