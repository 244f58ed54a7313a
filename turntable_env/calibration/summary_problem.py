"""The thesis's summary-level figures as a fitting problem (:mod:`.summary` and :mod:`.rig`
fit it): the drive protocol that reproduces the measurements, how each figure is read from
the simulated protocol, and :class:`SummaryProblem`, the relative residuals of a model
specification over the figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..amplifier import Amplifier, measure_slew_rate
from ..effects import CATALOGUE
from ..params import ParameterSet, RigParams
from ..plant import Plant, output_capacitance
from ..simulation import TWO_DIRECTIONAL_CYCLES
from .result import NOMINAL
from .thesis_data import SummaryTarget, thesis_targets
from .trace import simulate_trace
from .virtual_lab import protocol_blocks, protocol_drive

__all__ = ["ADAPTED_K", "ERROR_UNIT", "SummaryProblem", "predict_targets", "summary_protocol"]

ERROR_UNIT = "%"
HOLD = 0.02  # s of rest before and after each stepping block
UNADAPTED_PERIODS = 5  # periods simulated for the no-net-movement observation
TWO_DIR_CYCLES = TWO_DIRECTIONAL_CYCLES  # Fig. 4.6's cycles; the last one is read
ADAPTED_K = 1.0  # Fig. 4.3: the jump goes as far past 0 V as it started above it


@dataclass(frozen=True)
class _Measure:
    """How one target is read from the simulated protocol: kind, first and last block,
    periods (for a rotation per period)."""

    kind: str  # "dV" | "return" | "rotation" | "slew"
    first: int = 0
    last: int = 0
    periods: int = 1


def _step_block(drive: Mapping[str, Any], sign: float, n: int, a: float) -> tuple:
    amp = sign * float(drive["amplitude_V"])
    f = float(drive["frequency_Hz"])
    if drive.get("amplifier", "adapted") == "adapted":
        return ("steps", amp, f, n, a, ADAPTED_K)
    return ("steps", amp, f, n, a, 0.0, "step")


def summary_protocol(
    targets: Sequence[SummaryTarget], a: float
) -> tuple[list[tuple], dict[str, _Measure], str]:
    """The drive blocks that reproduce the targets' measurements, how to read each target
    from them, and the axis they watch.

    Fig. 4.6 is read as the figure reads it: two-directional stepping runs
    ``TWO_DIR_CYCLES`` forward-and-back cycles, and t₁ → t₂ is the last cycle's forward
    block — n steps after a reversal — with its return t₁ → t₃ at the end of the cycle's
    backward block. Fig. 4.7's one-directional block starts from rest."""
    blocks: list[tuple] = [("hold", HOLD)]
    measures: dict[str, _Measure] = {}
    axes = {t.drive["axis"] for t in targets if "axis" in t.drive}
    if len(axes) > 1:
        raise ValueError(f"targets: stepping on several axes {sorted(axes)}; one at a time")
    axis = axes.pop() if axes else "B"
    done: dict[tuple, tuple[int, int]] = {}
    for t in targets:
        d = t.drive
        if t.unit == "V/s":
            measures[t.name] = _Measure("slew")
            continue
        pattern = d.get("pattern", "observation")
        n = int(d.get("steps", UNADAPTED_PERIODS))
        key = (pattern, d["amplitude_V"], d["frequency_Hz"], n, d.get("amplifier"))
        if key not in done:
            if pattern == "two_directional":
                for _ in range(TWO_DIR_CYCLES):
                    blocks += [_step_block(d, 1.0, n, a), _step_block(d, -1.0, n, a)]
                first = len(blocks) - 2  # the last cycle's forward block
            else:
                first = len(blocks)
                blocks.append(_step_block(d, 1.0, n, a))
            blocks.append(("hold", HOLD))
            done[key] = (first, len(blocks) - 2)
        first, last = done[key]
        if t.name.startswith("return_"):
            measures[t.name] = _Measure("return", first, last)
        elif t.unit == "V":
            measures[t.name] = _Measure("dV", first, first)
        elif t.unit == "rad":
            measures[t.name] = _Measure("rotation", first, first, n)
        else:
            raise ValueError(f"target {t.name!r}: unit {t.unit!r} has no simulated reading")
    return blocks, measures, axis


def _slew(amp: Amplifier, target: SummaryTarget, c_load: float) -> float:
    """The amplifier model's 10–90 % slew rate [V/s] for a slew target's drive (§4.1.2)."""
    if amp.ideal:
        return math.inf
    d = target.drive
    if "output_swing_V" in d:  # data-sheet figure: full swing, no load
        half = 0.5 * d["output_swing_V"] / amp.gain
        r = amp.step_response(-half, half, duration=400e-6)
        return measure_slew_rate(r.time, r.output, -half * amp.gain, half * amp.gain)
    v = float(d["input_step_V"])
    if d.get("amplifier") == "adapted":  # Fig. 4.3: from v, jump to −v, to 0 on arrival
        hold = amp.adapted_hold_time(v, 0.0, ADAPTED_K, c_load)
        t = np.arange(0.0, max(4.0 * hold, 100e-6), 1e-8)
        u = np.where(t < hold, -ADAPTED_K * v, 0.0)
        r = amp.simulate(t, u, c_load, initial_output=amp.gain * v)
        return measure_slew_rate(r.time, r.output, amp.gain * v, 0.0)
    r = amp.step_response(0.0, v, load_capacitance=c_load)
    return measure_slew_rate(r.time, r.output, 0.0, amp.gain * v)


class SummaryProblem:
    """Relative residuals of a model specification over summary targets.

    ``hold``: index of the target left out (leave-one-out), or None. ``residual(...,
    "fit")`` gives the training targets' errors, ``"heldout"`` the left-out one's (all of
    them when nothing is left out). Simulations are cached per specification."""

    def __init__(
        self,
        targets: Sequence[SummaryTarget],
        base: ParameterSet | None = None,
        *,
        rig: RigParams | None = None,
        fidelity: str = "reduced",
        drive_amplifier: Amplifier | None = None,
    ):
        if not targets:
            raise ValueError("targets: empty")
        self.targets = list(targets)
        self.base: str | ParameterSet = base if base is not None else "real"
        self.rig = rig
        self.fidelity = fidelity
        lab = Plant(self.base, rig=rig).params  # the parameters the laboratory drove with
        # the lab tuned its adapted holds to its amplifier: the best model of it, if known
        self.lab = lab if drive_amplifier is None else replace(lab, amplifier=drive_amplifier)
        self.blocks, self.measures, self.axis = summary_protocol(self.targets, self.lab.ramp_ratio)
        self.spans = protocol_blocks(self.blocks)
        self.time, self.drive = protocol_drive(self.blocks, self.lab, self.axis)
        self.c_load = output_capacitance(self.lab, self.axis)  # one amplifier output's load
        self.hold: int | None = None
        self._cache: dict[tuple, np.ndarray] = {}
        self.n_sims = 0

    def plant(self, nominal: Mapping[str, float], effects: Mapping[str, Any]) -> Plant:
        """The plant of a specification: the base set built for the rig (``nominal``'s rig
        entries on top of the problem's rig), the friction and preload factors, the
        effects, and an ideal source unless ``amplifier_dynamics`` is on (module docstring)."""
        factors = {k: v for k, v in nominal.items() if k in ("friction", "preload")}
        rig_values = {k: v for k, v in nominal.items() if k not in factors}
        rig = self.rig
        if rig_values:
            rig = replace(rig if rig is not None else RigParams(), **rig_values)
        return Plant(
            self.base,
            factors=factors,
            effects=effects,
            ideal_amplifier=not any(k.startswith("amplifier_") for k in effects),
            rig=rig,
            fidelity=self.fidelity,  # type: ignore[arg-type]
        )

    def simulate(self, nominal: Mapping[str, float], effects: Mapping[str, Any]):
        """Simulated protocol: (theta [rad], detector [V]) at the drive samples."""
        res = simulate_trace(self.plant(nominal, effects), self.axis, self.time, self.drive)
        self.n_sims += 1
        return res.theta, res.detector_v

    def predict(self, nominal: Mapping[str, float], effects: Mapping[str, Any]) -> np.ndarray:
        """Predicted value of every target (its unit)."""
        key = (
            tuple(sorted(nominal.items())),
            repr(sorted((k, sorted(v.items())) for k, v in effects.items())),
        )
        if key in self._cache:
            return self._cache[key]
        amp = self.plant(nominal, effects).params.amplifier
        sim = None
        out = np.empty(len(self.targets))
        for i, t in enumerate(self.targets):
            m = self.measures[t.name]
            if m.kind == "slew":
                out[i] = _slew(amp, t, self.c_load)
                continue
            if sim is None:
                sim = self.simulate(nominal, effects)
            theta, det = sim
            start = self.spans[m.first][0]
            end = self.spans[m.last][1]
            if m.kind in ("dV", "return"):
                out[i] = float(np.interp(end, self.time, det) - np.interp(start, self.time, det))
            else:
                out[i] = (
                    float(np.interp(end, self.time, theta) - np.interp(start, self.time, theta))
                    / m.periods
                )
        self._cache[key] = out
        return out

    def errors(self, nominal: Mapping[str, float], effects: Mapping[str, Any]) -> np.ndarray:
        """Relative error of every target (module docstring, step 2)."""
        pred = self.predict(nominal, effects)
        e = np.empty(pred.size)
        for i, t in enumerate(self.targets):
            if self.measures[t.name].kind == "slew":
                e[i] = t.value / pred[i] - 1.0
            else:
                e[i] = (pred[i] - t.value) / t.reference
        return e

    def residual(
        self, nominal: Mapping[str, float], effects: Mapping[str, Any], portion: str
    ) -> np.ndarray:
        e = self.errors(nominal, effects)
        if self.hold is None:
            return e
        mask = np.arange(e.size) == self.hold
        return e[~mask] if portion == "fit" else e[mask]


def predict_targets(
    nominal: Mapping[str, float] | None = None,
    effects: Mapping[str, Mapping[str, float]] | None = None,
    targets: Sequence[SummaryTarget] | None = None,
) -> dict[str, float]:
    """Predicted value of every target (its unit) for nominal factors and effects."""
    problem = SummaryProblem(targets if targets is not None else thesis_targets())
    nom = {n: x0 for n, _lo, _hi, x0 in NOMINAL} | dict(nominal or {})
    pred = problem.predict(nom, {k: CATALOGUE[k].check(v) for k, v in (effects or {}).items()})
    return {t.name: float(p) for t, p in zip(problem.targets, pred, strict=True)}


