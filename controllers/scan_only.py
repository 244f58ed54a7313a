"""Scan mode alone: the PID on the scan offset, no stepping (reference controller).

Reaches targets within the scan range K·u_max (±147 µrad, ±1.47 µm at the table radius,
for the real turntable) and nothing beyond: the benchmark row that shows what stepping
adds.
"""

from __future__ import annotations

from .base import Move, StepScanController

__all__ = ["ScanOnlyController"]


class ScanOnlyController(StepScanController):
    """The scan PID of :mod:`controllers.scan_pid` without any stepping."""

    name = "scan_pid"
    steps = False

    def choose_move(self, remaining: float, measured: float, saturated: bool) -> Move | None:
        return None
