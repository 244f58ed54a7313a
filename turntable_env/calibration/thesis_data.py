"""The thesis's measurements as summary-level targets (``data/thesis_measurements.toml``).

No traces of the real turntable exist; chapter 4 gives figures. Each becomes a
:class:`SummaryTarget` — a named quantity with its value, unit, the resolution the
thesis quotes it to, the drive that produced it and its section — which the calibration
tools accept next to measured traces.

Targets (SI units):

* ``amplifier_slew_1V``, ``amplifier_slew_3V`` — 0.9 and 2.7 V/µs for 1 and 3 V input
  steps (§4.1.2, Fig. 4.2); ``amplifier_slew_900V`` — 12 V/µs at the full 900 V swing;
  ``amplifier_slew_adapted`` — 8.0 V/µs with the adapted 1 V input (Fig. 4.3);
* ``detector_dV_two_directional`` — 0.53 V in 5 steps about B at 2 V, 100 Hz (Fig. 4.6),
  and ``return_two_directional`` — 0 V: the table returns to its start;
* ``detector_dV_one_directional`` — 1.19 V in 9 steps (Fig. 4.7);
* ``net_rotation_unadapted`` — 0 rad per period: with the unadapted slew the table
  follows the input with no net movement (§4.1.2–4.1.3); the thesis gives no figure, so
  its resolution is taken as one tenth of the adapted step, and relative errors refer to
  the adapted step (``scale``).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..detector import Detector

__all__ = [
    "THESIS_DATA_FILE",
    "SummaryTarget",
    "thesis_detector",
    "thesis_step_sizes",
    "thesis_targets",
]

THESIS_DATA_FILE = Path(__file__).resolve().parent.parent / "data" / "thesis_measurements.toml"


@dataclass(frozen=True)
class SummaryTarget:
    """A measured figure without a trace.

    Attributes:
        name: identifier; quantity: what is measured; value and unit (SI);
        resolution: half the last quoted digit (same unit); drive: the input that
        produced it (amplitude_V, frequency_Hz, amplifier, steps, pattern, …);
        source: thesis section and figure; scale: the magnitude a relative error
        refers to (default |value|; zero-valued targets name the figure they compare
        with).
    """

    name: str
    quantity: str
    value: float
    unit: str
    resolution: float
    drive: dict[str, Any] = field(default_factory=dict)
    source: str = ""
    scale: float | None = None

    @property
    def reference(self) -> float:
        """|value|, or ``scale`` where given: the denominator of relative errors."""
        return abs(self.value) if self.scale is None else abs(self.scale)


def _load(path: Path) -> dict[str, Any]:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: {exc}") from None


def thesis_detector(path: str | Path = THESIS_DATA_FILE) -> Detector:
    """The detector of §4.1.1 (S, L, linear range, R_table) from the data file."""
    d = _load(Path(path))["detector"]
    return Detector(
        sensitivity=d["sensitivity_m_per_V"],
        distance=d["distance_m"],
        linear_range=d["linear_range_m"],
        table_radius=d["table_radius_m"],
    )


def thesis_step_sizes(path: str | Path = THESIS_DATA_FILE) -> dict[str, float]:
    """The per-step table displacements the thesis quotes (§4.1.3) [m], by input:
    ``{"one_directional": 0.37e-6, "two_directional": 0.30e-6}``."""
    p = Path(path)
    try:
        return {s["name"]: s["step_um"] * 1e-6 for s in _load(p)["stepping"]}
    except KeyError as exc:
        raise ValueError(f"{p}: entry {exc.args[0]!r} missing") from None


def thesis_targets(path: str | Path = THESIS_DATA_FILE) -> list[SummaryTarget]:
    """Every summary-level target of the data file (module docstring)."""
    p = Path(path)
    data = _load(p)
    out: list[SummaryTarget] = []
    try:
        for s in data["amplifier_step"]:
            if "output_swing_V" in s:
                name = f"amplifier_slew_{s['output_swing_V']:.0f}V"
                drive = {"output_swing_V": s["output_swing_V"]}
            elif s.get("adapted", False):
                name = "amplifier_slew_adapted"
                drive = {"input_step_V": s["input_step_V"], "amplifier": "adapted"}
            else:
                name = f"amplifier_slew_{s['input_step_V']:.0f}V"
                drive = {"input_step_V": s["input_step_V"], "amplifier": "unadapted"}
            out.append(
                SummaryTarget(
                    name,
                    "amplifier output slew rate, 10–90 %",
                    s["slew_V_per_us"] * 1e6,
                    "V/s",
                    s["resolution_V_per_us"] * 1e6,
                    drive,
                    s["source"],
                )
            )
        for s in data["stepping"]:
            drive = {k: s[k] for k in ("axis", "amplitude_V", "frequency_Hz", "amplifier", "steps")}
            drive["pattern"] = s["name"]
            out.append(
                SummaryTarget(
                    f"detector_dV_{s['name']}",
                    "net detector voltage over the steps",
                    s["detector_dV"],
                    "V",
                    s["resolution_V"],
                    drive,
                    s["source"],
                )
            )
            if s.get("returns_to_start", False):
                out.append(
                    SummaryTarget(
                        f"return_{s['name']}",
                        "detector voltage after the cycle minus before",
                        0.0,
                        "V",
                        s["resolution_V"],
                        drive,
                        s["source"],
                        scale=s["detector_dV"],
                    )
                )
        adapted_step = min(
            s["step_um"] * 1e-6 / thesis_detector(p).table_radius for s in data["stepping"]
        )
        for s in data["observation"]:
            drive = {k: s[k] for k in ("axis", "amplitude_V", "frequency_Hz", "amplifier")}
            out.append(
                SummaryTarget(
                    "net_rotation_unadapted",
                    f"net rotation per period: {s['text']}",
                    0.0,
                    "rad",
                    0.1 * adapted_step,
                    drive,
                    s["source"],
                    scale=adapted_step,
                )
            )
    except KeyError as exc:
        raise ValueError(f"{p}: entry {exc.args[0]!r} missing") from None
    return out
