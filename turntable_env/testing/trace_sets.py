"""The three independent plants' trace sets as the experiment scripts find them.

``python experiments/independent_traces.py``, ``second_plant_traces.py`` and
``third_plant_traces.py`` write them under ``experiments/results/``; the scripts that read
every trace (``experiments/drive_reading.py``, ``experiments/y_feature.py``) take the CSV
files given, or all of these.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

__all__ = ["RESULTS", "TRACE_SETS", "trace_paths"]

RESULTS = Path("experiments/results")
TRACE_SETS = ("independent_traces", "second_plant_traces", "third_plant_traces")


def trace_paths(given: Sequence[str]) -> list[Path]:
    """The CSV files ``given``, or every CSV of the three trace sets (sorted by set and
    name); empty where neither exists."""
    return [Path(p) for p in given] or sorted(
        p for d in TRACE_SETS for p in (RESULTS / d).glob("*.csv")
    )
