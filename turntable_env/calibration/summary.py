"""Calibrate on summary-level data: measured figures without traces (thesis chapter 4).

:func:`calibrate_summary` runs the loop of :mod:`.calibrate` on
:class:`~.thesis_data.SummaryTarget` lists instead of traces:

1. **Nominal model as the thesis simulated it**: the real parameter set (Table D.1)
   with an *ideal source*, V_out = G·u (the 20-sim model of §3.4 had no amplifier).
   Friction and preload factors are fitted to the targets by scipy ``least_squares``.
   The drives are what the laboratory commanded (§4.1.2–4.1.3): 2 V, 100 Hz, a = 0.95;
   the adapted flyback of Fig. 4.3 (jump to −2 V, back to 0 V when the HVA 900's output
   arrives) for the stepping measurements, the plain step for the unadapted observation.
2. **Residual** per target, relative: (predicted − measured)/reference for figures
   (``SummaryTarget.reference``), and measured/predicted − 1 for slew rates — the
   relative error of the 10–90 % transition time, so an ideal source (no transition
   time) is off by −100 % rather than infinitely.
3. **Held-out error** by leave-one-out cross-validation over the targets: refit without
   target j, predict j; the RMS over j is the held-out error. Candidates (every catalogue
   effect) are ranked by it — a parameter that only fits the target it is fitted to
   does not lower it — and the best is added while it lowers it by ``min_improvement``.
   The loop stops when every target is within 3× its quoted resolution (the summary
   analogue of a white residual) or no candidate helps.
4. **Report**: selected effects, parameters with standard errors, held-out error
   before and after, the per-target table, and which targets stay outside their
   resolution (their signature) — plus :func:`step_ratio_analysis`, the
   one- vs two-directional question (0.37 vs 0.30 µm per step).

On the ideal-source nominal, ``amplifier_dynamics`` switches the HVA 900 model of
:mod:`turntable_env.amplifier` on (first-order, τ from the measured 0.9 V/µs per input
volt, 12 V/µs and 25 mA limits), with its ``slew_scale`` and ``current_scale``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.optimize
import threadpoolctl

from ..amplifier import Amplifier, measure_slew_rate
from ..effects import CATALOGUE
from ..params import ParameterSet
from ..plant import Plant, load_capacitance
from .calibrate import (
    NOMINAL,
    CalibrationResult,
    Fit,
    fit_spec,
    fitted_plant,
    is_significant,
    parameter_table,
    spec_of,
)
from .thesis_data import SummaryTarget, thesis_targets
from .trace import simulate_trace
from .virtual_lab import protocol_blocks, protocol_drive

__all__ = [
    "SummaryProblem",
    "calibrate_summary",
    "predict_targets",
    "slew_scale_needed",
    "step_ratio_analysis",
    "summary_protocol",
]

ERROR_UNIT = "% (RMS relative error, leave-one-out)"
HOLD = 0.02  # s of rest before and after each stepping block
UNADAPTED_PERIODS = 5  # periods simulated for the no-net-movement observation
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
    from them, and the axis they watch."""
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
            first = len(blocks)
            blocks.append(_step_block(d, 1.0, n, a))
            if pattern == "two_directional":
                blocks.append(_step_block(d, -1.0, n, a))
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

    def __init__(self, targets: Sequence[SummaryTarget], base: ParameterSet | None = None):
        if not targets:
            raise ValueError("targets: empty")
        self.targets = list(targets)
        self.base: str | ParameterSet = base if base is not None else "real"
        self.lab = Plant(self.base).params  # the parameters the laboratory drove with
        self.blocks, self.measures, self.axis = summary_protocol(self.targets, self.lab.ramp_ratio)
        self.spans = protocol_blocks(self.blocks)
        self.time, self.drive = protocol_drive(self.blocks, self.lab, self.axis)
        self.c_load = load_capacitance(self.lab, self.axis)
        self.hold: int | None = None
        self._cache: dict[tuple, np.ndarray] = {}
        self.n_sims = 0

    def plant(self, nominal: Mapping[str, float], effects: Mapping[str, Any]) -> Plant:
        """The plant of a specification: the base set with the friction and preload factors,
        the effects, and an ideal source unless ``amplifier_dynamics`` is on (module
        docstring)."""
        return Plant(
            self.base,
            factors=nominal,
            effects=effects,
            ideal_amplifier="amplifier_dynamics" not in effects,
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


def _loo(problem: SummaryProblem, fit: Fit, max_nfev: int = 10) -> np.ndarray:
    """Leave-one-out errors: refit without each target (from ``fit``), predict it."""
    spec = spec_of(fit.nominal, fit.effects)
    out = np.empty(len(problem.targets))
    try:
        for j in range(out.size):
            problem.hold = j
            out[j] = fit_spec(problem, spec, max_nfev=max_nfev).heldout[0]
    finally:
        problem.hold = None
    return out


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)) * 100.0)


def _nominal_starts(current: Mapping[str, float]) -> list[dict[str, float]]:
    """Starting nominal factors: the current ones, the prior ones and a coarse grid (the
    targets are piecewise-smooth in friction and preload, with local optima)."""
    starts = [dict(current), {n: x0 for n, _lo, _hi, x0 in NOMINAL}]
    starts += [{"friction": f, "preload": p} for f in (0.6, 0.8, 1.3, 1.7) for p in (0.7, 1.4)]
    return starts


def _best_start(
    problem: SummaryProblem, nominal: Mapping[str, float], effects: Mapping[str, Any], name: str
) -> tuple[dict[str, float], dict[str, dict[str, float]]]:
    """Best (nominal, effects) on the training targets over :func:`_nominal_starts` and a
    5-point grid over the first parameter of effect ``name`` (if given)."""
    grid = [dict(effects)]
    if name:
        e = CATALOGUE[name]
        p0 = e.parameters[0]
        grid = [
            {**effects, name: {**e.defaults(), p0.name: float(v)}}
            for v in np.linspace(p0.low, p0.high, 5)
        ]
    best, out = math.inf, (dict(nominal), grid[0])
    for nom in _nominal_starts(nominal):
        for eff in grid:
            r = problem.residual(nom, eff, "fit")
            if float(r @ r) < best:
                best, out = float(r @ r), (nom, eff)
    return out


def _candidate(problem: SummaryProblem, current: Fit, name: str) -> Fit:
    """Fit one effect with the nominal factors on top of the current model, from the best
    start of :func:`_best_start`."""
    nominal, effects = _best_start(problem, current.nominal, current.effects, name)
    spec = spec_of(nominal, effects)
    free = [i for i, s in enumerate(spec) if s[0] in ("nominal", name)]
    return fit_spec(problem, spec, free=free, max_nfev=30)


def _within_resolution(problem: SummaryProblem, pred: np.ndarray) -> np.ndarray:
    return np.array(
        [abs(p - t.value) <= 3.0 * t.resolution for t, p in zip(problem.targets, pred, strict=True)]
    )


def _table(problem: SummaryProblem, before: Fit, after: Fit, loo_b, loo_a) -> list[dict]:
    pb = problem.predict(before.nominal, before.effects)
    pa = problem.predict(after.nominal, after.effects)
    eb = problem.errors(before.nominal, before.effects)
    ea = problem.errors(after.nominal, after.effects)
    ok = _within_resolution(problem, pa)
    return [
        {
            "target": t.name,
            "quantity": t.quantity,
            "unit": t.unit,
            "measured": t.value,
            "resolution": t.resolution,
            "predicted_before": float(pb[i]),
            "predicted_after": float(pa[i]),
            "error_before": float(eb[i]),
            "error_after": float(ea[i]),
            "heldout_error_before": float(loo_b[i]),
            "heldout_error_after": float(loo_a[i]),
            "within_resolution": bool(ok[i]),
            "source": t.source,
        }
        for i, t in enumerate(problem.targets)
    ]


def calibrate_summary(
    targets: Sequence[SummaryTarget] | str | Path | None = None,
    *,
    candidates: Sequence[str] | None = None,
    max_effects: int = 3,
    min_improvement: float = 0.10,
    progress: Callable[[str], None] | None = print,
) -> CalibrationResult:
    """The calibration loop on summary-level targets (module docstring). ``targets``: a
    list, or a TOML file in the format of ``data/thesis_measurements.toml`` (default:
    that file). Runs with one BLAS thread, as :func:`~.calibrate.calibrate` does."""
    with threadpoolctl.threadpool_limits(limits=1, user_api="blas"):
        return _calibrate_summary(targets, candidates, max_effects, min_improvement, progress)


def _calibrate_summary(
    targets: Sequence[SummaryTarget] | str | Path | None,
    candidates: Sequence[str] | None,
    max_effects: int,
    min_improvement: float,
    progress: Callable[[str], None] | None,
) -> CalibrationResult:
    t0 = time.perf_counter()
    if targets is None or isinstance(targets, str | Path):
        tl = thesis_targets() if targets is None else thesis_targets(targets)
    else:
        tl = list(targets)
    say = progress or (lambda _m: None)
    problem = SummaryProblem(tl)
    names = list(candidates) if candidates is not None else list(CATALOGUE)
    for n in names:
        if n not in CATALOGUE:
            raise ValueError(f"candidates: unknown effect {n!r}")
    say(f"fitting the nominal model (ideal source; friction, preload) to {len(tl)} targets")
    start, _ = _best_start(problem, {n: x0 for n, _lo, _hi, x0 in NOMINAL}, {}, "")
    nominal = fit_spec(problem, spec_of(start, {}), max_nfev=40)
    loo_nominal = _loo(problem, nominal)
    current, loo_current = nominal, loo_nominal
    say(f"  held-out (leave-one-out) error {_rms(loo_current):.1f} %")
    selected: list[str] = []
    cands_out: list[dict[str, Any]] = []
    history = [{"effects": [], "heldout_rms": _rms(loo_current)}]
    while len(selected) < max_effects:
        pred = problem.predict(current.nominal, current.effects)
        if _within_resolution(problem, pred).all():
            break
        round_results = []
        for name in names:
            if name in selected:
                continue
            cand = _candidate(problem, current, name)
            loo = _loo(problem, cand)
            round_results.append((name, cand, loo))
            cands_out.append(
                {
                    "round": len(selected) + 1,
                    "effect": name,
                    "heldout_error": _rms(loo),
                    "fit_error": _rms(cand.heldout),
                    "parameters": len(cand.spec),
                }
            )
            say(f"  candidate {name:<22} held-out {_rms(loo):.1f} %")
        if not round_results:
            break
        name, best, loo = min(round_results, key=lambda r: _rms(r[2]))
        # a parameter 3 standard errors from neutral, unless the effect changes the model
        # at neutral (the amplifier on an ideal source)
        significant = name == "amplifier_dynamics" or is_significant(best, name)
        if _rms(loo) > (1.0 - min_improvement) * _rms(loo_current) or not significant:
            say(
                f"  no candidate helps enough (best {name}: {_rms(loo):.1f} %, "
                f"significant {significant})"
            )
            break
        selected.append(name)
        current, loo_current = best, loo
        history.append({"effects": list(selected), "heldout_rms": _rms(loo)})
        say(f"selected {name}: held-out error {_rms(loo):.1f} %")
    table = _table(problem, nominal, current, loo_nominal, loo_current)
    params = parameter_table(current)
    off = [r for r in table if not r["within_resolution"]]
    diag: dict[str, Any] = {
        "targets": table,
        "amplifier_slew_scale_needed": slew_scale_needed(problem),
        "step_ratio": step_ratio_analysis(problem, current, names),
        "simulations": problem.n_sims,
    }
    if off:
        diag["signature"] = "targets outside 3× their quoted resolution: " + "; ".join(
            f"{r['target']} {r['error_after']:+.0%}" for r in off
        )
    say(f"  {problem.n_sims} simulations, {time.perf_counter() - t0:.1f} s")
    return CalibrationResult(
        selected_effects=selected,
        parameters=params,
        error_before=_rms(loo_nominal),
        error_after=_rms(loo_current),
        error_unit=ERROR_UNIT,
        residual_structured=bool(off),
        candidates=cands_out,
        diagnosis=diag,
        history=history,
        residuals={"before": loo_nominal * 100.0, "after": loo_current * 100.0},
        wall_s=time.perf_counter() - t0,
        plant=fitted_plant(problem.plant(current.nominal, current.effects), current),
    )


def slew_scale_needed(problem: SummaryProblem) -> dict[str, dict[str, float | bool]]:
    """The ``amplifier_dynamics.slew_scale`` each slew target alone asks for (the root, or
    the bound nearer to it), whether that value reproduces the target within 3× its
    resolution, and the HVA model's figure at scale 1: one value for all means the
    first-order HVA model fits them together."""
    p = CATALOGUE["amplifier_dynamics"].parameters[0]
    nominal = {n: x0 for n, _lo, _hi, x0 in NOMINAL}
    out: dict[str, dict[str, float | bool]] = {}
    for t in problem.targets:
        if problem.measures[t.name].kind != "slew":
            continue

        def gap(s: float, t: SummaryTarget = t) -> float:  # model − measured slew [V/s]
            eff = {"amplifier_dynamics": {"slew_scale": s, "current_scale": 1.0}}
            amp = problem.plant(nominal, eff).params.amplifier
            return _slew(amp, t, problem.c_load) - t.value

        lo, hi = gap(p.low), gap(p.high)
        if lo * hi < 0.0:
            v = float(scipy.optimize.brentq(gap, p.low, p.high, xtol=1e-4))
        else:
            v = p.low if abs(lo) < abs(hi) else p.high
        out[t.name] = {
            "model_at_scale_1_V_per_s": gap(1.0) + t.value,
            "slew_scale": v,
            "reproduced": bool(abs(gap(v)) <= 3.0 * t.resolution),
        }
    return out


def _per_step(problem: SummaryProblem, theta: np.ndarray, block: int) -> list[float]:
    """Table displacement of every period of a stepping block [m at R_table]."""
    start, end, blk = problem.spans[block]
    n = int(blk[3])
    edges = np.linspace(start, end, n + 1)
    th = np.interp(edges, problem.time, theta)
    return (np.diff(th) * problem.lab.table.radius).tolist()


def step_ratio_analysis(
    problem: SummaryProblem, fit: Fit, names: Sequence[str] = tuple(CATALOGUE)
) -> dict[str, Any]:
    """One- vs two-directional step (0.37 vs 0.30 µm, §4.1.3): the measured ratio, the
    calibrated model's, each period's step in both sequences, and the range of the ratio
    every catalogue effect can produce within its bounds (on top of the calibrated model)."""
    det = problem.lab.detector
    tv = {t.name: t for t in problem.targets}
    one, two = tv.get("detector_dV_one_directional"), tv.get("detector_dV_two_directional")
    if one is None or two is None:
        return {}
    step = {
        k: float(det.table_displacement(t.value)) / int(t.drive["steps"])
        for k, t in (("one", one), ("two", two))
    }
    measured = step["one"] / step["two"]
    # resolution of the ratio from the quoted digits of both voltages
    r_res = measured * (one.resolution / one.value + two.resolution / two.value)

    def ratio(nominal, effects) -> float:
        pred = problem.predict(nominal, effects)
        i1 = problem.targets.index(one)
        i2 = problem.targets.index(two)
        return float((pred[i1] / one.drive["steps"]) / (pred[i2] / two.drive["steps"]))

    theta, _ = problem.simulate(fit.nominal, fit.effects)
    m1, m2 = problem.measures[one.name], problem.measures[two.name]
    model_ratio = ratio(fit.nominal, fit.effects)
    effects_range = {}
    explains = []
    for name in names:
        e = CATALOGUE[name]
        if name in fit.effects:
            continue
        vals = []
        p0 = e.parameters[0]
        for v in np.linspace(p0.low, p0.high, 5):
            vals.append(
                ratio(fit.nominal, {**fit.effects, name: {**e.defaults(), p0.name: float(v)}})
            )
        lo, hi = float(min(vals)), float(max(vals))
        effects_range[name] = {"parameter": p0.name, "ratio_min": lo, "ratio_max": hi}
        if lo - r_res <= measured <= hi + r_res:
            explains.append(name)
    # equal steady steps s and a different first step s1: s1 + (n1−1)s = n1·step_one, …
    n1, n2 = int(one.drive["steps"]), int(two.drive["steps"])
    s_steady = (n1 * step["one"] - n2 * step["two"]) / (n1 - n2) if n1 != n2 else math.nan
    s_first = n2 * step["two"] - (n2 - 1) * s_steady
    return {
        "measured_step_one_um": step["one"] * 1e6,
        "implied_first_step_um": s_first * 1e6,
        "implied_steady_step_um": s_steady * 1e6,
        "measured_step_two_um": step["two"] * 1e6,
        "measured_ratio": measured,
        "measured_ratio_resolution": r_res,
        "model_ratio": model_ratio,
        "model_steps_one_um": [s * 1e6 for s in _per_step(problem, theta, m1.first)],
        "model_steps_two_um": [s * 1e6 for s in _per_step(problem, theta, m2.first)],
        "effect_ratio_range": effects_range,
        "effects_that_reach_measured_ratio": explains,
    }
