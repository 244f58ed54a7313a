"""The plant's store: named plants kept as TOML files, and calibration reports read back.

A named plant (``"calibrated"``: the thesis rig as ``turntable calibrate --thesis`` found
it, ``data/calibrated.toml``) is a file of two tables, ``[set]`` (its name and where it came
from) and ``[plant]`` (everything :meth:`~turntable_env.plant.Plant.to_dict` writes: base
set, fidelity, factors, effects, detector noise, amplifier setting, uncertainties, rig).
This module reads and writes those files as dictionaries and knows where each named plant
lives; :mod:`.value` turns them into :class:`~turntable_env.plant.Plant` objects, so the
store sits below the plant value and the parameter layer (:mod:`turntable_env.params`)
below both. Every file goes through :mod:`turntable_env.inputs` (regular files, bounds,
one-line errors naming the file).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..inputs import Fields, load_json, load_toml, show
from ..validation import check_path

__all__ = [
    "CALIBRATED_FILE",
    "NAMED_PLANTS",
    "named_plant_dict",
    "plant_toml",
    "report_plant_dict",
]

CALIBRATED_FILE = Path(__file__).resolve().parent.parent / "data" / "calibrated.toml"
NAMED_PLANTS: dict[str, Path] = {"calibrated": CALIBRATED_FILE}


def _toml_value(v: Any, key: str = "") -> str:
    """One TOML value; ValueError for a number that is not finite or a type TOML's writer
    here does not know (a plant's fields are text, booleans, numbers and lists of them)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, int | float):
        if not math.isfinite(v):
            raise ValueError(f"{key}={v!r}: must be finite")
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x, key) for x in v) + "]"
    raise ValueError(f"{key}={v!r}: not a value a plant file holds")


def _toml_tables(prefix: str, data: Mapping[str, Any], out: list[str]) -> None:
    scalars = {k: v for k, v in data.items() if not isinstance(v, Mapping) and v is not None}
    out.append(f"[{prefix}]")
    out += [f"{k} = {_toml_value(v, f'{prefix}.{k}')}" for k, v in scalars.items()]
    out.append("")
    for k, v in data.items():
        if isinstance(v, Mapping):
            _toml_tables(f"{prefix}.{k}", v, out)


def plant_toml(plant: Mapping[str, Any], source: str, name: str = "calibrated") -> str:
    """The file of a named plant (``data/calibrated.toml``): ``plant`` is
    :meth:`~turntable_env.plant.Plant.to_dict`'s output, ``source`` where it came from.
    ValueError for a ``name`` or ``source`` that is not one line of text (both are written
    into comment lines: a line break there would write keys into the file)."""
    for field_name, text in (("name", name), ("source", source)):
        if not isinstance(text, str) or not text.strip() or not text.isprintable():
            raise ValueError(f"{field_name}={text!r}: must be one line of printable text")
    if not isinstance(plant, Mapping):
        raise ValueError(f"plant={type(plant).__name__}: must be a dictionary (Plant.to_dict)")
    lines = [
        f"# The parameter set {name!r}: the plant {source} found.",
        "# Read by turntable_env.plant.parameter_set(" + repr(name) + ") and",
        "# `turntable simulate --params " + name + "`; `turntable calibrate --thesis --report DIR`",
        "# writes DIR/calibrated.toml, of which this file is a copy.",
        "",
    ]
    _toml_tables("set", {"name": name, "source": source}, lines)
    _toml_tables("plant", plant, lines)
    return "\n".join(lines)


def named_plant_dict(path: str | os.PathLike[str]) -> tuple[str, dict[str, Any]]:
    """(name, plant dictionary) of a :func:`plant_toml` file; ValueError naming the file."""
    p = check_path("plant file", path)
    data = Fields(load_toml(p, "plant file (TOML)", max_bytes=2**20), str(p)).known("set", "plant")
    name = data.sub("set").text("name")
    plant = data.sub("plant").table
    return name, dict(plant)


def report_plant_dict(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The plant dictionary a calibration ``report.json`` (or its directory) describes:
    its ``plant`` entry, or for reports written before it, the nominal factors and the
    selected effects with their standard errors. ValueError naming the file."""
    p = check_path("report", path)
    if p.is_dir():
        p = p / "report.json"
    data = load_json(p, "calibration report (JSON)")
    if not isinstance(data, dict):
        raise ValueError(f"{p}: not a calibration report (a JSON object expected)")
    if "plant" in data:
        if not isinstance(data["plant"], Mapping):
            raise ValueError(f"{p}: plant = {show(data['plant'])}: must be an object")
        return dict(data["plant"])
    if "parameters" not in data or "selected_effects" not in data:
        raise ValueError(f"{p}: not a calibration report (no 'plant' or 'parameters' key)")
    return _legacy_plant(data, str(p))


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
