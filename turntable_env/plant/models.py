"""The models of a parameter set, built once and cached: the 3-D model, the reduced
per-axis model (condensed from a 3-D model of the same bodies) and the channel loads."""

from __future__ import annotations

import functools
from typing import Any

from ..model import TurntableModel
from ..params import ParameterSet
from ..reduced import ReducedModel

__all__ = ["load_capacitance", "output_capacitance", "reduced_model", "turntable_model"]


@functools.lru_cache(maxsize=64)
def turntable_model(ps: ParameterSet) -> TurntableModel:
    """The 3-D model of a parameter set (the last 64 are cached)."""
    return TurntableModel(ps)


_BODIES: dict[tuple[Any, Any, str], TurntableModel] = {}


def _bodies(ps: ParameterSet) -> TurntableModel:
    """A 3-D model with the table, tubes and wiring of ``ps`` (the first built for them):
    what the reduced model's condensation and the channel's load capacitance need — the
    bodies only (``size_preload=False``: the static solves sizing the preload spring are
    skipped, a calibration builds one per evaluation)."""
    key = (ps.table, ps.tube, ps.rig.drive_mode)
    if key not in _BODIES:
        if len(_BODIES) >= 16:
            _BODIES.pop(next(iter(_BODIES)))
        _BODIES[key] = TurntableModel(ps, size_preload=False)
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
def reduced_model(ps: ParameterSet, axis: str, translation: bool = False) -> ReducedModel:
    """The reduced model of ``ps`` about ``axis``, condensed from a cached 3-D model of its
    table and tubes (friction, preload and amplifier come from ``ps``), with the sphere's
    translation where ``translation`` (the ``"translation"`` fidelity); cached."""
    return ReducedModel(ps, axis, model=_bodies(ps), translation=translation)
