"""Turntable controllers: observation → action for ``PiezoTurntable-v0``.

The thesis (§5.2) asks for a feed-forward controller built on model knowledge and a
fuzzy controller. Registered here (:mod:`controllers.registry`):

* ``feedforward`` — inverts the simulator's step-size map (:mod:`.step_map`), then
  scan-mode PID (:mod:`.feedforward`);
* ``fuzzy`` — Mamdani step-count rules on error and error change (scikit-fuzzy), then
  scan-mode PID (:mod:`.fuzzy`);
* ``closed_loop`` — step counting on the detector with an online step-size estimate
  (:mod:`.closed_loop`);
* ``scan_pid`` — the python-control-designed scan PID alone (:mod:`.scan_pid`).

A controller sees only what a lab sees: its observations and, at reset, a
:class:`~controllers.lab.LabBrief` (never the env's info). ``turntable benchmark``
(:mod:`.benchmark`) judges every registered controller on the tasks of :mod:`.tasks` and
the plant sets of :mod:`.plant_sets` with the metrics of :mod:`.metrics`.
"""

from .base import Controller, ControllerContext, Move, StepScanController
from .blind import BlindSettings
from .closed_loop import ClosedLoopStepController
from .episode import EpisodeResult, run_episode
from .feedforward import FeedForwardController, MapPlanner
from .fuzzy import FuzzyStepController
from .lab import LabBrief
from .registry import available, make, register
from .scan_only import ScanOnlyController
from .shield import BlindShield
from .step_map import StepMap

__all__ = [
    "BlindSettings",
    "BlindShield",
    "ClosedLoopStepController",
    "Controller",
    "ControllerContext",
    "EpisodeResult",
    "FeedForwardController",
    "FuzzyStepController",
    "LabBrief",
    "MapPlanner",
    "Move",
    "ScanOnlyController",
    "StepMap",
    "StepScanController",
    "available",
    "make",
    "register",
    "run_episode",
]

register("feedforward", FeedForwardController, "step-map inversion + scan-mode PID")
register("fuzzy", FuzzyStepController, "Mamdani step count (scikit-fuzzy) + scan-mode PID")
register("closed_loop", ClosedLoopStepController, "online step-size estimate + scan-mode PID")
register("scan_pid", ScanOnlyController, "scan-mode PID alone (no stepping)")
