"""Calibrate on summary-level data: measured figures without traces (thesis chapter 4).

:func:`calibrate_summary` runs three stages on :class:`~.thesis_data.SummaryTarget` lists:

1. **Nominal model as the thesis simulated it** (the "before"): the real parameter set
   (Table D.1) with an *ideal source*, V_out = G·u (the 20-sim model of §3.4 had no
   amplifier), friction and preload factors fitted to every target by scipy
   ``least_squares``, its held-out error by leave-one-out. The drives are what the
   laboratory commanded (§4.1.2–4.1.3): 2 V, 100 Hz, a = 0.95; the adapted flyback of
   Fig. 4.3 (jump to −2 V, back to 0 V when the amplifier's output arrives) for the
   stepping measurements, the plain step for the unadapted observation.
2. **The amplifier** on its own figures (§4.1.2): the catalogue's amplifier effects
   compete by leave-one-out held-out error, as :mod:`.calibrate`'s loop does on traces —
   ``amplifier_dynamics`` switches the HVA 900 model on, ``amplifier_fast_path`` gives it
   the fast partial response the first-order stage lacks. The residual that points to
   the latter is :func:`slew_scale_needed`: each figure alone asks for another first-order
   speed.
3. **The rig** on the stepping figures (:mod:`.rig`): drive mode, mirror, large-signal
   d₃₁, contacts, friction and preload with their priors, on the 3-D model, with the
   amplifier of stage 2 (the laboratory tuned its adapted holds to it).

Residuals are relative per target: (predicted − measured)/reference for figures
(``SummaryTarget.reference``), and measured/predicted − 1 for slew rates — the relative
error of the 10–90 % transition time, so an ideal source (no transition time) is off by
−100 % rather than infinitely. The report gives, per figure, measured, before, after and
error; the amplifier's selection; the rig's hypotheses, estimates, uncertainties,
unidentified parameters and conflicting figures; and the calibrated plant.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.optimize
import threadpoolctl

from ..amplifier import Amplifier, measure_slew_rate
from ..effects import CATALOGUE
from ..params import ParameterSet, RigParams
from ..plant import Plant, output_capacitance
from ..simulation import TWO_DIRECTIONAL_CYCLES
from .calibrate import (
    NOMINAL,
    CalibrationResult,
    Fit,
    fit_spec,
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
    "summary_protocol",
    "summary_sections",
]

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


def calibrate_summary(
    targets: Sequence[SummaryTarget] | str | Path | None = None,
    *,
    candidates: Sequence[str] | None = None,
    max_effects: int = 2,
    min_improvement: float = 0.10,
    rig: bool = True,
    rig_hypotheses: Sequence[Any] | None = None,
    rig_fidelity: str = "corrected",
    progress: Callable[[str], None] | None = print,
) -> CalibrationResult:
    """The three stages on summary-level targets (module docstring). ``targets``: a list,
    or a TOML file in the format of ``data/thesis_measurements.toml`` (default: that
    file); ``candidates``: the amplifier effects that compete in stage 2 (default: the
    catalogue's ``amplifier_*``); ``rig``: run stage 3 (``rig_hypotheses`` limits it,
    ``rig_fidelity`` as :func:`~.rig.fit_rig`'s ``fidelity``).
    Runs with one BLAS thread, as :func:`~.calibrate.calibrate` does."""
    with threadpoolctl.threadpool_limits(limits=1, user_api="blas"):
        return _calibrate_summary(
            targets, candidates, max_effects, min_improvement, rig, rig_hypotheses,
            rig_fidelity, progress,
        )  # fmt: skip


AMPLIFIER_EFFECTS = tuple(n for n in CATALOGUE if n.startswith("amplifier_"))


def _select_effects(
    problem: SummaryProblem,
    start: Fit,
    names: Sequence[str],
    max_effects: int,
    min_improvement: float,
    say: Callable[[str], None],
) -> tuple[Fit, np.ndarray, list[str], list[dict[str, Any]], list[dict[str, Any]]]:
    """The leave-one-out selection loop (module docstring, stage 2) from ``start``:
    (fit, its held-out errors, selected, candidates tried, history)."""
    current, loo_current = start, _loo(problem, start)
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
    return current, loo_current, selected, cands_out, history


def _calibrate_summary(
    targets: Sequence[SummaryTarget] | str | Path | None,
    candidates: Sequence[str] | None,
    max_effects: int,
    min_improvement: float,
    run_rig: bool,
    rig_hypotheses: Sequence[Any] | None,
    rig_fidelity: str,
    progress: Callable[[str], None] | None,
) -> CalibrationResult:
    from .rig import calibrate_rig

    t0 = time.perf_counter()
    if targets is None or isinstance(targets, str | Path):
        tl = thesis_targets() if targets is None else thesis_targets(targets)
    else:
        tl = list(targets)
    say = progress or (lambda _m: None)
    names = list(candidates) if candidates is not None else list(AMPLIFIER_EFFECTS)
    for n in names:
        if n not in CATALOGUE:
            raise ValueError(f"candidates: unknown effect {n!r}")
    # --- 1. the nominal model as the thesis simulated it -------------------------------
    problem = SummaryProblem(tl)
    say(f"fitting the nominal model (ideal source; friction, preload) to {len(tl)} targets")
    start, _ = _best_start(problem, {n: x0 for n, _lo, _hi, x0 in NOMINAL}, {}, "")
    nominal = fit_spec(problem, spec_of(start, {}), max_nfev=40)
    loo_nominal = _loo(problem, nominal)
    err_nominal = problem.errors(nominal.nominal, nominal.effects)
    say(f"  held-out (leave-one-out) error {_rms(loo_nominal):.1f} %")
    # --- 2. the amplifier on its own figures -----------------------------------------------
    amp_targets = [t for t in tl if t.unit == "V/s"]
    effects: dict[str, dict[str, float]] = {}
    selected: list[str] = []
    cands_out: list[dict[str, Any]] = []
    history: list[dict[str, Any]] = []
    amp_fit = None
    need: dict[str, Any] = {}
    if amp_targets:
        amp_problem = SummaryProblem(amp_targets)
        say(f"stage 2: the amplifier on its {len(amp_targets)} figures")
        amp_start = fit_spec(amp_problem, spec_of(nominal.nominal, {}), max_nfev=5)
        amp_fit, _loo_amp, selected, cands_out, history = _select_effects(
            amp_problem, amp_start, names, max_effects, min_improvement, say
        )
        effects = {k: dict(v) for k, v in amp_fit.effects.items()}
        need = slew_scale_needed(amp_problem)
    # --- 3. the rig on the stepping figures -------------------------------------------
    rig_result = None
    stepping = [t for t in tl if t.unit != "V/s"]
    final = Plant(problem.base, factors=nominal.nominal, effects=effects,
                  ideal_amplifier=not effects)  # fmt: skip
    if run_rig and stepping and Plant(problem.base).params.unlisted is not None:
        say("stage 3: the rig on the stepping figures (3-D model, corrected per-axis fits)")
        rig_result = calibrate_rig(
            tl, effects, drive_amplifier=final.params.amplifier, candidates=rig_hypotheses,
            fidelity=rig_fidelity, progress=say,
        )  # fmt: skip
        best = rig_result.best
        final = final.replace(
            factors={k: best.values[k] for k in ("friction", "preload")},
            rig=rig_result.rig(),
            fidelity="full",
        )
        say(f"  {rig_result.explanation}")
    # --- the table: before (stage 1) and after (stages 2 and 3) ---------------------------
    pred_before = problem.predict(nominal.nominal, nominal.effects)
    after = _final_predictions(tl, amp_fit, rig_result, problem, nominal)
    err_after = _relative_errors(tl, after)
    table = []
    for i, t in enumerate(tl):
        table.append(
            {
                "target": t.name,
                "quantity": t.quantity,
                "unit": t.unit,
                "measured": t.value,
                "resolution": t.resolution,
                "predicted_before": float(pred_before[i]),
                "predicted_after": float(after[i]),
                "error_before": float(err_nominal[i]),
                "error_after": float(err_after[i]),
                "heldout_error_before": float(loo_nominal[i]),
                "within_resolution": bool(abs(after[i] - t.value) <= 3.0 * t.resolution),
                "within_10_percent": bool(abs(err_after[i]) <= 0.10),
                "source": t.source,
            }
        )
    params = parameter_table(nominal if amp_fit is None else amp_fit)
    params["nominal"] = parameter_table(nominal)["nominal"]
    if amp_fit is not None:  # standard errors from the figures' quoted resolution
        for name, std in _resolution_std(SummaryProblem(amp_targets), amp_fit).items():
            eff, par = name.split(".")
            params[eff][par]["std"] = std
    if rig_result is not None:
        b = rig_result.best
        est = {k: {"value": v, "std": b.std[k]} for k, v in b.values.items()}
        params["nominal"] = {k: est.pop(k) for k in ("friction", "preload")}
        params["rig"] = est
    off = [r for r in table if not r["within_10_percent"]]
    diag: dict[str, Any] = {
        "targets": table,
        "amplifier_slew_scale_needed": need,
        "amplifier_selection": {"selected": selected, "history": history},
        "simulations": problem.n_sims,
    }
    if rig_result is not None:
        diag["rig"] = rig_result.to_json()
        diag["step_ratio"] = _step_ratio(tl, after)
    if off:
        diag["signature"] = "figures outside ±10 %: " + "; ".join(
            f"{r['target']} {r['error_after']:+.0%}" for r in off
        )
    say(f"  {time.perf_counter() - t0:.1f} s")
    uncertainty = {}
    if rig_result is not None:
        uncertainty = {k: rig_result.best.std[k] for k in ("friction", "preload")}
    return CalibrationResult(
        selected_effects=selected,
        parameters=params,
        error_before=_rms(err_nominal),
        error_after=_rms(err_after),
        error_unit=ERROR_UNIT,
        residual_structured=bool(off),
        candidates=cands_out,
        diagnosis=diag,
        history=history,
        residuals={"before": err_nominal * 100.0, "after": err_after * 100.0},
        wall_s=time.perf_counter() - t0,
        plant=final.replace(uncertainty=uncertainty),
        sections=summary_sections(diag),
        error_label="RMS relative error over the figures",
    )


def summary_sections(diag: Mapping[str, Any]) -> list[str]:
    """report.md sections of a summary-level calibration: per-target table, the
    amplifier's selection and the rig's fit."""
    rows = diag.get("targets", [])
    out = [
        "",
        "## Figures (relative error; slew rates as transition time)",
        "",
        "| figure | measured | unit | before | after | error before | error after "
        "| within ±10 % | source |",
        "|---|---:|---|---:|---:|---:|---:|---|---|",
        *[
            f"| {r['target']} | {r['measured']:.4g} | {r['unit']} | {r['predicted_before']:.4g} "
            f"| {r['predicted_after']:.4g} | {r['error_before']:+.1%} | {r['error_after']:+.1%} "
            f"| {r['within_10_percent']} | {r['source']} |"
            for r in rows
        ],
    ]
    need = diag.get("amplifier_slew_scale_needed", {})
    if need:
        out += [
            "",
            "## Amplifier: the first-order speed each slew figure asks for alone",
            "",
            "amplifier_dynamics.slew_scale that reproduces each figure (the root, or the bound",
            "nearest to one): a first-order stage fits them together only if they agree.",
            "",
            *[
                f"- {k}: {v['slew_scale']:.3g} (reproduced: {v['reproduced']}; first-order model "
                f"at scale 1: {v['model_at_scale_1_V_per_s'] / 1e6:.2f} V/µs)"
                for k, v in need.items()
            ],
            "",
            "selected: " + (", ".join(diag["amplifier_selection"]["selected"]) or "none"),
        ]
    rig = diag.get("rig")
    if rig:
        best = next(f for f in rig["fits"] if f["hypothesis"] == rig["best"])
        out += [
            "",
            "## The rig (stepping figures; 3-D model)",
            "",
            f"{rig['explanation']}.",
            "",
            "| hypothesis | prior | χ² | prior penalty Σz² | log posterior | posterior |",
            "|---|---:|---:|---:|---:|---:|",
            *[
                f"| {f['hypothesis']} | {f['prior_probability']:.2f} | {f['chi2']:.2f} "
                f"| {f['prior_penalty']:.2f} | {f['log_posterior']:.2f} "
                f"| {rig['posterior'][f['hypothesis']]:.3f} |"
                for f in rig["fits"]
            ],
            "",
            f"Estimates ({rig['best']}); posterior/prior std near 1: the figures do not "
            "identify the parameter:",
            "",
            "| parameter | estimate | std | prior | posterior/prior std |",
            "|---|---:|---:|---|---:|",
            *[
                f"| {n} | {v:.4g} | {best['std'][n]:.2g} | {p['centre']:g} ({p['kind']}, σ "
                f"{p['sigma']:g}) | {best['shrinkage'][n]:.2f} |"
                for n, v in best["values"].items()
                for p in [rig["priors"][n]]
            ],
            "",
            "not identified by the figures: "
            + ("; ".join(f"{k} ({v})" for k, v in rig["unidentified"].items()) or "none"),
            "",
            "3-D minus per-axis prediction at the optimum (the correction of the per-axis "
            "fits): "
            + ", ".join(f"{k} {v:+.3g}" for k, v in best["correction_full_minus_reduced"].items()),
        ]
        for c in rig["conflicts"]:
            out.append(f"- conflict: {c['reading']}")
    sr = diag.get("step_ratio", {})
    if sr:
        out += [
            "",
            f"One- vs two-directional step per step: measured ratio {sr['measured_ratio']:.3f} "
            f"± {sr['measured_ratio_resolution']:.3f}, calibrated {sr['model_ratio']:.3f}.",
        ]
    return out


def _resolution_std(problem: SummaryProblem, fit: Fit) -> dict[str, float]:
    """Standard errors of a fit's effect parameters [their units] from the targets' quoted
    resolutions: (JᵀWJ)⁻¹, J the relative errors' finite-difference Jacobian (1 % of each
    parameter's range), W the inverse squared relative resolutions."""
    sig = np.array([t.resolution / abs(t.value) for t in problem.targets])
    cols, names = [], []
    for owner, pname, lo, hi, _x0 in fit.spec:
        if owner == "nominal":
            continue
        h = 0.01 * (hi - lo)
        x = fit.effects[owner][pname]
        up = {**fit.effects, owner: {**fit.effects[owner], pname: min(x + h, hi)}}
        dn = {**fit.effects, owner: {**fit.effects[owner], pname: max(x - h, lo)}}
        e_up = problem.errors(fit.nominal, up)
        e_dn = problem.errors(fit.nominal, dn)
        cols.append((e_up - e_dn) / (min(x + h, hi) - max(x - h, lo)) / sig)
        names.append(f"{owner}.{pname}")
    if not cols:
        return {}
    jac = np.column_stack(cols)
    cov = np.linalg.pinv(jac.T @ jac)
    return {n: float(np.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(names)}


def _final_predictions(tl, amp_fit, rig_result, problem, nominal) -> np.ndarray:
    """Every target's prediction after stages 2 and 3: amplifier figures from the
    amplifier's fit, stepping figures from the rig's (3-D model); stages not run keep
    the nominal model's."""
    base = problem.predict(nominal.nominal, nominal.effects)
    out = base.copy()
    if amp_fit is not None:
        amp_targets = [t for t in tl if t.unit == "V/s"]
        amp_pred = SummaryProblem(amp_targets).predict(amp_fit.nominal, amp_fit.effects)
        for t, v in zip(amp_targets, amp_pred, strict=True):
            out[tl.index(t)] = v
    if rig_result is not None:
        for name, v in rig_result.best.predicted.items():
            out[[t.name for t in tl].index(name)] = v
    return out


def _relative_errors(tl: Sequence[SummaryTarget], pred: np.ndarray) -> np.ndarray:
    """Relative errors (module docstring) of predictions ``pred``."""
    return np.array(
        [
            (t.value / p - 1.0) if t.unit == "V/s" else (p - t.value) / t.reference
            for t, p in zip(tl, pred, strict=True)
        ]
    )


def _step_ratio(tl: Sequence[SummaryTarget], pred: np.ndarray) -> dict[str, Any]:
    """One- vs two-directional step per step (0.37 vs 0.30 µm, §4.1.3): measured and
    calibrated."""
    tv = {t.name: (t, p) for t, p in zip(tl, pred, strict=True)}
    one, two = tv.get("detector_dV_one_directional"), tv.get("detector_dV_two_directional")
    if one is None or two is None:
        return {}
    n1, n2 = int(one[0].drive["steps"]), int(two[0].drive["steps"])
    measured = (one[0].value / n1) / (two[0].value / n2)
    resolution = measured * (one[0].resolution / one[0].value + two[0].resolution / two[0].value)
    return {
        "measured_ratio": measured,
        "measured_ratio_resolution": resolution,
        "model_ratio": (one[1] / n1) / (two[1] / n2),
    }


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
