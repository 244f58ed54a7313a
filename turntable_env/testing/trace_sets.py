"""The three independent plants' trace sets as the experiment scripts find them.

``python experiments/independent_traces.py``, ``second_plant_traces.py`` and
``third_plant_traces.py`` write them under ``experiments/results/``; the scripts that read
every trace (``experiments/drive_reading.py``, ``experiments/y_feature.py``) take the CSV
files given, or all of these.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..calibration.measurement import Measurement, load_measurement

__all__ = ["RESULTS", "TRACE_SETS", "load_traces", "trace_paths"]

RESULTS = Path("experiments/results")
TRACE_SETS = ("independent_traces", "second_plant_traces", "third_plant_traces")


def trace_paths(given: Sequence[str]) -> list[Path]:
    """The CSV files ``given``, or every CSV of the three trace sets (sorted by set and
    name); empty where neither exists."""
    return [Path(p) for p in given] or sorted(
        p for d in TRACE_SETS for p in (RESULTS / d).glob("*.csv")
    )


def load_traces(given: Sequence[str]) -> list[tuple[Path, Measurement]]:
    """(path, measurement) of every trace :func:`trace_paths` finds, all loaded before any
    is used; ValueError naming the file (or that there is none) otherwise."""
    paths = trace_paths(given)
    if not paths:
        raise ValueError("no traces (write them with experiments/*_traces.py)")
    try:
        return [(p, load_measurement(p)) for p in paths]
    except OSError as exc:
        raise ValueError(str(exc)) from None
