"""Calibration with measured data (issue 8).

* :mod:`.measurement` — the measurement file format, its validating loader and writer;
* :mod:`.thesis_data` — the thesis's chapter-4 measurements as summary-level targets;
* the catalogue of switchable model augmentations lives in :mod:`turntable_env.effects`;
* :mod:`.trace` — a measured trace simulated with effects on;
* :mod:`.virtual_lab` — drive protocols and measurement files from the simulator;
* :mod:`.result` — the result every calibration returns and the shared fitting pieces;
* :mod:`.calibrate` — the entry point on traces (:mod:`.trace_fit`) and the report;
* :mod:`.summary` — the same loop on summary-level figures (the thesis's chapter 4).
"""

from .measurement import AXES, Measurement, load_measurement
from .thesis_data import THESIS_DATA_FILE, SummaryTarget, thesis_detector, thesis_targets

__all__ = [
    "AXES",
    "THESIS_DATA_FILE",
    "Measurement",
    "SummaryTarget",
    "load_measurement",
    "thesis_detector",
    "thesis_targets",
]
