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

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..detector import Detector
from ..inputs import Fields, load_toml
from .measurement import DRIVE_FREQUENCY_RANGE

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


MAX_STEPS = 1000  # steps of one stepping figure (the thesis's: 5 and 9)
AXES = ("A", "B", "C")
AMPLIFIER_MODES = ("adapted", "unadapted")
PATTERNS = ("one_directional", "two_directional")


def _load(path: Path) -> Fields:
    """The summary file as :class:`~turntable_env.inputs.Fields` (read and bounded by
    :func:`~turntable_env.inputs.load_toml`), its tables known."""
    f = Fields(load_toml(path, "summary file (TOML)", max_bytes=2**20), str(path))
    f.known("detector", "amplifier", "amplifier_step", "stepping", "observation")
    if "amplifier" in f.table:  # the rig's amplifier (§4.1.1), checked though the model's
        # own comes from the parameter set: a wrong entry is refused, not ignored
        a = f.sub("amplifier").known("source", "gain", "input_limit_V", "current_limit_A")
        a.text("source", default="")
        a.number("gain", low=0.0, high=1e4, open_low=True, default=1.0)
        a.number("input_limit_V", low=0.0, high=1e3, open_low=True, default=1.0)
        a.number("current_limit_A", low=0.0, high=100.0, open_low=True, default=1.0)
    return f


def thesis_detector(path: str | Path = THESIS_DATA_FILE) -> Detector:
    """The detector of §4.1.1 (S, L, linear range, R_table) from the data file."""
    d = _load(Path(path)).sub("detector").known(
        "source", "sensitivity_m_per_V", "linear_range_m", "distance_m", "table_radius_m"
    )
    return Detector(
        sensitivity=d.number("sensitivity_m_per_V", low=0.0, high=1.0, open_low=True),
        distance=d.number("distance_m", low=0.0, high=100.0, open_low=True),
        linear_range=d.number("linear_range_m", low=0.0, high=1.0, open_low=True),
        table_radius=d.number("table_radius_m", low=0.0, high=10.0, open_low=True),
    )


def thesis_step_sizes(path: str | Path = THESIS_DATA_FILE) -> dict[str, float]:
    """The per-step table displacements the thesis quotes (§4.1.3) [m], by input:
    ``{"one_directional": 0.37e-6, "two_directional": 0.30e-6}``."""
    return {
        s.text("name", choices=PATTERNS): s.number("step_um", low=0.0, high=1e6, open_low=True)
        * 1e-6
        for s in _load(Path(path)).tables("stepping")
    }


def _drive(s: Fields, keys: tuple[str, ...]) -> dict[str, Any]:
    """A figure's drive, each entry checked: axis, input amplitude (0, 10] V, frequency
    1 Hz–100 kHz (:data:`~.measurement.DRIVE_FREQUENCY_RANGE`, a protocol's), amplifier mode,
    steps 1…:data:`MAX_STEPS`."""
    out: dict[str, Any] = {}
    for k in keys:
        if k == "axis":
            out[k] = s.text(k, choices=AXES)
        elif k == "amplitude_V":
            out[k] = s.number(k, low=0.0, high=10.0, open_low=True)
        elif k == "frequency_Hz":
            out[k] = s.number(k, low=DRIVE_FREQUENCY_RANGE[0], high=DRIVE_FREQUENCY_RANGE[1])
        elif k == "amplifier":
            out[k] = s.text(k, choices=AMPLIFIER_MODES)
        elif k == "steps":
            out[k] = s.integer(k, low=1, high=MAX_STEPS)
    return out


def thesis_targets(path: str | Path = THESIS_DATA_FILE) -> list[SummaryTarget]:
    """Every summary-level target of the data file (module docstring); ValueError naming
    the file, the entry, the key and the value for anything outside the format."""
    p = Path(path)
    data = _load(p)
    out: list[SummaryTarget] = []
    for s in data.tables("amplifier_step"):
        s.known("source", "input_step_V", "output_swing_V", "adapted", "slew_V_per_us",
                "resolution_V_per_us")  # fmt: skip
        slew = s.number("slew_V_per_us", low=0.0, high=1e4, open_low=True) * 1e6
        res = s.number("resolution_V_per_us", low=0.0, high=1e4, open_low=True) * 1e6
        if "output_swing_V" in s.table:
            swing = s.number("output_swing_V", low=0.0, high=1e4, open_low=True)
            name = f"amplifier_slew_{swing:.0f}V"
            drive: dict[str, Any] = {"output_swing_V": swing}
        else:
            step = s.number("input_step_V", low=0.0, high=10.0, open_low=True)
            adapted = s.flag("adapted", default=False)
            name = "amplifier_slew_adapted" if adapted else f"amplifier_slew_{step:.0f}V"
            drive = {"input_step_V": step, "amplifier": "adapted" if adapted else "unadapted"}
        out.append(SummaryTarget(name, "amplifier output slew rate, 10–90 %", slew, "V/s", res,
                                 drive, s.text("source", default="")))  # fmt: skip
    steppings = data.tables("stepping")
    for s in steppings:
        s.known("source", "name", "axis", "amplitude_V", "frequency_Hz", "amplifier", "steps",
                "detector_dV", "resolution_V", "x_table_um", "step_um",
                "returns_to_start")  # fmt: skip
        pattern = s.text("name", choices=PATTERNS)
        drive = _drive(s, ("axis", "amplitude_V", "frequency_Hz", "amplifier", "steps"))
        drive["pattern"] = pattern
        dv = s.number("detector_dV", low=-100.0, high=100.0)
        res = s.number("resolution_V", low=0.0, high=100.0, open_low=True)
        if abs(dv) < res:  # the relative errors of this figure (and its return) divide by it
            raise ValueError(f"{s.where}: detector_dV = {dv!r}: its magnitude must be at least "
                             f"resolution_V = {res!r} (the figure's relative error refers to it)")
        src = s.text("source", default="")
        s.number("step_um", low=0.0, high=1e6, open_low=True)
        out.append(SummaryTarget(f"detector_dV_{pattern}", "net detector voltage over the steps",
                                 dv, "V", res, drive, src))  # fmt: skip
        if s.flag("returns_to_start", default=False):
            out.append(
                SummaryTarget(f"return_{pattern}", "detector voltage after the cycle minus "
                              "before", 0.0, "V", res, drive, src, scale=dv)
            )
    observations = data.tables("observation") if "observation" in data.table else []
    if observations:
        if not steppings:
            raise ValueError(f"{p}: [[observation]] needs a [[stepping]] figure to refer to")
        radius = thesis_detector(p).table_radius
        adapted_step = min(s.number("step_um") * 1e-6 / radius for s in steppings)
        for s in observations:
            s.known("source", "name", "axis", "amplitude_V", "frequency_Hz", "amplifier", "text")
            drive = _drive(s, ("axis", "amplitude_V", "frequency_Hz", "amplifier"))
            out.append(
                SummaryTarget(
                    "net_rotation_unadapted",
                    f"net rotation per period: {s.text('text', default='')}",
                    0.0, "rad", 0.1 * adapted_step, drive, s.text("source", default=""),
                    scale=adapted_step,
                )
            )
    if not out:
        raise ValueError(f"{p}: no figure ([[amplifier_step]], [[stepping]], [[observation]])")
    names = [t.name for t in out]  # observations included: each is one figure
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"{p}: figures {dup} appear more than once")
    return out
