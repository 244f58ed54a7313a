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
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats

from ..effects import CATALOGUE
from ..plant import Plant
from ..threads import one_blas_thread
from .result import (
    NOMINAL,
    CalibrationResult,
    Fit,
    fit_spec,
    parameter_table,
    spec_of,
)
from .rig import calibrate_rig
from .summary_problem import (
    ERROR_UNIT,
    SummaryProblem,
    _slew,
    predict_targets,
    summary_protocol,
)
from .thesis_data import SummaryTarget, thesis_targets

__all__ = [
    "SummaryProblem",
    "calibrate_summary",
    "predict_targets",
    "slew_scale_needed",
    "summary_protocol",
    "summary_sections",
]

def _loo(problem: Any, fit: Fit, max_nfev: int = 10, only: str | None = None) -> np.ndarray:
    """Leave-one-out errors: refit without each target (from ``fit``; every parameter, or
    effect ``only``'s), predict it. ``problem``: a :class:`SummaryProblem` or a wrapper."""
    spec = spec_of(fit.nominal, fit.effects)
    free = None if only is None else [i for i, s_ in enumerate(spec) if s_[0] == only]
    out = np.empty(len(problem.targets))
    try:
        for j in range(out.size):
            problem.hold = j
            out[j] = fit_spec(problem, spec, max_nfev=max_nfev, free=free).heldout[0]
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


def _best_start(problem: SummaryProblem, nominal: Mapping[str, float]) -> dict[str, float]:
    """Best nominal factors on the training targets over :func:`_nominal_starts`."""
    best, out = math.inf, dict(nominal)
    for nom in _nominal_starts(nominal):
        r = problem.residual(nom, {}, "fit")
        if float(r @ r) < best:
            best, out = float(r @ r), nom
    return out


PRIOR_FRACTION = 0.25  # an effect parameter's prior σ, as a fraction of its range


class _MapProblem:
    """The amplifier candidates' objective (stage 2): the training figures' errors in units
    of their quoted resolution, and effect ``name``'s parameters as a prior centred on
    neutral (the effect off), σ = :data:`PRIOR_FRACTION` of each range. The four figures fix
    only some combinations of an effect's parameters (the adapted flyback fixes one of the
    fast path's two); the prior settles the rest on the values nearest to neutral, so the
    optimum is one point, not a ridge that a start or a rounding slides along.
    ``"heldout"`` residuals stay the plain relative errors."""

    def __init__(self, problem: SummaryProblem, name: str):
        self.problem = problem
        self.name = name
        self.targets = problem.targets
        self.sigma = np.array([t.resolution / abs(t.value) for t in problem.targets])
        self.params = CATALOGUE[name].parameters

    @property
    def hold(self) -> int | None:
        return self.problem.hold

    @hold.setter
    def hold(self, j: int | None) -> None:
        self.problem.hold = j

    def chi2(self, nominal: Mapping[str, float], effects: Mapping[str, Any]) -> float:
        """Σ(eᵢ/σᵢ)² over the training figures (no prior)."""
        e = self.problem.residual(nominal, effects, "fit")
        s = self.sigma if self.hold is None else np.delete(self.sigma, self.hold)
        return float(np.sum((e / s) ** 2))

    def residual(
        self, nominal: Mapping[str, float], effects: Mapping[str, Any], portion: str
    ) -> np.ndarray:
        e = self.problem.residual(nominal, effects, portion)
        if portion != "fit":
            return e
        s = self.sigma if self.hold is None else np.delete(self.sigma, self.hold)
        vals = effects.get(self.name, CATALOGUE[self.name].neutral())
        z = [(vals[p.name] - p.neutral) / (PRIOR_FRACTION * (p.high - p.low))
             for p in self.params]  # fmt: skip
        return np.concatenate([e / s, z])


@dataclass(frozen=True)
class CandidateResult:
    """One amplifier candidate fitted from several starts (module docstring, stage 2).

    ``best``: the maximum a posteriori fit (:class:`_MapProblem`) over the starts;
    ``loo``: its leave-one-out errors; ``starts``: per start, its start and fitted values
    and objective; ``agree``: how many starts end where the best does (every parameter
    within its posterior standard error); ``z``: the likelihood-ratio distance from
    neutral, √(χ²(neutral) − χ²(best)) — infinite where the effect changes the model at
    neutral, as the amplifier does on an ideal source; ``std``: the posterior standard
    errors (Laplace)."""

    name: str
    best: Fit
    loo: np.ndarray
    starts: list[dict[str, Any]]
    agree: int
    z: float
    std: dict[str, float]

    @property
    def heldout_rms(self) -> float:
        return _rms(self.loo)


def _start_points(name: str, n: int, seed: int) -> list[dict[str, float]]:
    """``n`` starting values of effect ``name``'s parameters: the 5-point grid over its
    first parameter (the others at their defaults) first, then scrambled-Sobol points over
    its whole box (``seed`` picks the scramble: the perturbed starts)."""
    e = CATALOGUE[name]
    p0 = e.parameters[0]
    out = [{**e.defaults(), p0.name: float(v)} for v in np.linspace(p0.low, p0.high, 5)]
    if n > 1:
        u = scipy.stats.qmc.Sobol(len(e.parameters), scramble=True, seed=seed).random(8)
        for row in u[: n - 1]:
            out.append({p.name: p.low + float(x) * (p.high - p.low)
                        for p, x in zip(e.parameters, row, strict=True)})  # fmt: skip
    return out


def _fit_candidate(
    problem: SummaryProblem, current: Fit, name: str, starts: int, seed: int
) -> CandidateResult:
    """Fit effect ``name`` on top of the current model from ``starts`` starts: the best
    point of the first parameter's grid and ``starts − 1`` scrambled-Sobol points; only the
    effect's parameters move (the amplifier figures do not depend on friction or preload)."""
    mp = _MapProblem(problem, name)
    points = _start_points(name, starts, seed)
    grid, others = points[:5], points[5:]

    def cost(vals: Mapping[str, float]) -> float:
        r = mp.residual(current.nominal, {**current.effects, name: dict(vals)}, "fit")
        return float(r @ r)

    chosen = [min(grid, key=cost), *others]
    fits = []
    for vals in chosen:
        spec = spec_of(current.nominal, {**current.effects, name: vals})
        free = [i for i, s_ in enumerate(spec) if s_[0] == name]
        fits.append(fit_spec(mp, spec, free=free, max_nfev=60, diff_step=1e-3,
                             covariance="unscaled"))  # fmt: skip
    # the least objective; equal ones (to 1e-9 of a χ² unit) go to the earlier start
    order = sorted(range(len(fits)), key=lambda i: (round(fits[i].sse_fit, 9), i))
    best = fits[order[0]]
    params = CATALOGUE[name].parameters
    col = {s_[1]: i for i, s_ in enumerate(best.spec) if s_[0] == name}
    std = {p.name: float(best.std[col[p.name]]) for p in params}
    tol = {p.name: max(std[p.name], 1e-3 * (p.high - p.low)) for p in params}
    agree = sum(
        all(abs(f.effects[name][p.name] - best.effects[name][p.name]) <= tol[p.name]
            for p in params)
        for f in fits
    )  # fmt: skip
    if name == "amplifier_dynamics" and "amplifier_dynamics" not in current.effects:
        z = math.inf  # switches the amplifier on: a change at its neutral value
    else:
        off = {**current.effects, name: CATALOGUE[name].neutral()}
        gain = mp.chi2(current.nominal, off) - mp.chi2(best.nominal, best.effects)
        z = math.sqrt(max(gain, 0.0))
    rows = [
        {"start": dict(v), "fitted": dict(f.effects[name]), "objective": f.sse_fit}
        for v, f in zip(chosen, fits, strict=True)
    ]
    return CandidateResult(name, best, _loo(mp, best, only=name), rows, agree, z, std)


SIGNIFICANCE_Z = 3.0  # likelihood-ratio distance from neutral, √Δχ², for an effect to count
Z_MARGIN = 1.0  # a z-score has unit noise: within this of the threshold is undecided
HELDOUT_TOLERANCE = 0.02  # relative resolution of a held-out RMS error (rounding, refits)


def _decide(
    cand: CandidateResult, runner_up: CandidateResult | None, current_rms: float,
    min_improvement: float,
) -> dict[str, Any]:
    """Whether the best candidate of a round is taken, with its margins: ``selected`` when
    it improves the held-out error by more than ``min_improvement`` and its parameters sit
    more than :data:`SIGNIFICANCE_Z` resolution standard errors from neutral, each by more
    than its own uncertainty; ``rejected`` when either fails by more than that;
    ``undecided`` otherwise, and also when the runner-up candidate is as good within the
    tolerance or the starts do not agree (a choice that could flip with rounding)."""
    tol = HELDOUT_TOLERANCE * current_rms
    need = (1.0 - min_improvement) * current_rms
    margin = need - cand.heldout_rms  # percentage points better than needed
    z_margin = cand.z - SIGNIFICANCE_Z
    rival = runner_up.heldout_rms - cand.heldout_rms if runner_up is not None else math.inf
    reasons = []
    if margin < -tol:
        decision = "rejected"
        reasons.append(f"held-out {cand.heldout_rms:.1f} % does not reach {need:.1f} %")
    elif z_margin < -Z_MARGIN:
        decision = "rejected"
        reasons.append(f"{cand.z:.1f} σ from neutral (< {SIGNIFICANCE_Z:g} σ)")
    elif margin <= tol or abs(z_margin) <= Z_MARGIN:
        decision = "undecided"
        reasons.append("within the uncertainty of its threshold")
    elif rival <= tol:
        decision = "undecided"
        reasons.append(f"{runner_up.name} within {rival:.1f} points")  # type: ignore[union-attr]
    elif cand.agree < 2:
        decision = "undecided"
        reasons.append(f"only {cand.agree} of {len(cand.starts)} starts reach the fit")
    else:
        decision = "selected"
    return {
        "effect": cand.name,
        "decision": decision,
        "reasons": reasons,
        "heldout_rms": cand.heldout_rms,
        "heldout_needed": need,
        "heldout_margin": margin,
        "heldout_tolerance": tol,
        "z": cand.z,
        "z_threshold": SIGNIFICANCE_Z,
        "runner_up": runner_up.name if runner_up is not None else None,
        "runner_up_margin": rival,
        "starts_agree": cand.agree,
        "starts": len(cand.starts),
    }


def _describe_decision(d: Mapping[str, Any]) -> str:
    z = "∞" if math.isinf(d["z"]) else f"{d['z']:.1f}"
    rival = (f"; runner-up {d['runner_up']} {d['runner_up_margin']:+.1f} points"
             if d["runner_up"] else "")  # fmt: skip
    why = f" ({'; '.join(d['reasons'])})" if d["reasons"] else ""
    return (
        f"{d['decision']} {d['effect']}{why}: held-out {d['heldout_rms']:.1f} % against "
        f"{d['heldout_needed']:.1f} % needed (margin {d['heldout_margin']:+.1f} ± "
        f"{d['heldout_tolerance']:.1f} points); {z} σ from neutral (√Δχ², threshold "
        f"{d['z_threshold']:g}){rival}; {d['starts_agree']}/{d['starts']} starts agree"
    )


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
    starts: int = 5,
    seed: int = 0,
    workers: int | None = None,
) -> CalibrationResult:
    """The three stages on summary-level targets (module docstring). ``targets``: a list,
    or a TOML file in the format of ``data/thesis_measurements.toml`` (default: that
    file); ``candidates``: the amplifier effects that compete in stage 2 (default: the
    catalogue's ``amplifier_*``); ``rig``: run stage 3 (``rig_hypotheses`` limits it,
    ``rig_fidelity`` as :func:`~.rig.fit_rig`'s ``fidelity``).

    Stages 2 and 3 fit every candidate and hypothesis from ``starts`` starts (``seed``
    perturbs them: a different seed, different starts) and report how many agree, each
    decision's margins, and ``undecided`` where a margin lies within its own uncertainty.
    ``workers``: processes for stage 3's hypotheses (default: the CPUs this process may
    use; the results do not depend on it). Runs with one BLAS thread, as
    :func:`~.calibrate.calibrate` does."""
    if isinstance(starts, bool) or not isinstance(starts, int) or starts < 1:
        raise ValueError(f"starts={starts!r}: must be an integer >= 1")
    if workers is None:
        workers = len(os.sched_getaffinity(0))
    elif isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r}: must be an integer >= 1")
    with one_blas_thread():
        return _calibrate_summary(
            targets, candidates, max_effects, min_improvement, rig, rig_hypotheses,
            rig_fidelity, progress, starts, seed, workers,
        )  # fmt: skip


# the amplifier effects the thesis's own figures (§4.1.2's slew rates) are fitted with: an
# output lag keeps the 10–90 % slew by construction, so those figures cannot name it
AMPLIFIER_EFFECTS = ("amplifier_dynamics", "amplifier_fast_path")


def _select_effects(
    problem: SummaryProblem,
    start: Fit,
    names: Sequence[str],
    max_effects: int,
    min_improvement: float,
    say: Callable[[str], None],
    starts: int = 5,
    seed: int = 0,
) -> tuple[Fit, np.ndarray, list[str], list[dict[str, Any]], list[dict[str, Any]]]:
    """The leave-one-out selection loop (module docstring, stage 2) from ``start``:
    (fit, its held-out errors, selected, candidates tried, history with every round's
    decision and margins)."""
    current, loo_current = start, _loo(problem, start)
    selected: list[str] = []
    cands_out: list[dict[str, Any]] = []
    history: list[dict[str, Any]] = [{"effects": [], "heldout_rms": _rms(loo_current)}]
    while len(selected) < max_effects:
        pred = problem.predict(current.nominal, current.effects)
        if _within_resolution(problem, pred).all():
            break
        results = []
        for name in names:
            if name in selected:
                continue
            c = _fit_candidate(problem, current, name, starts, seed)
            results.append(c)
            cands_out.append(
                {
                    "round": len(selected) + 1,
                    "effect": name,
                    "heldout_error": c.heldout_rms,
                    "fit_error": _rms(c.best.heldout),
                    "parameters": len(c.best.spec),
                    "z_from_neutral": c.z,
                    "starts_agree": c.agree,
                    "starts": c.starts,
                    "std": c.std,
                }
            )
            say(f"  candidate {name:<22} held-out {c.heldout_rms:.1f} % "
                f"({c.agree}/{len(c.starts)} starts agree)")  # fmt: skip
        if not results:
            break
        results.sort(key=lambda c: c.heldout_rms)
        best, runner_up = results[0], (results[1] if len(results) > 1 else None)
        decision = _decide(best, runner_up, _rms(loo_current), min_improvement)
        history[-1]["decision"] = decision
        say(f"  {_describe_decision(decision)}")
        if decision["decision"] != "selected":
            break
        selected.append(best.name)
        current, loo_current = best.best, best.loo
        history.append({"effects": list(selected), "heldout_rms": best.heldout_rms})
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
    starts: int,
    seed: int,
    workers: int,
) -> CalibrationResult:
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
    start = _best_start(problem, {n: x0 for n, _lo, _hi, x0 in NOMINAL})
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
            amp_problem, amp_start, names, max_effects, min_improvement, say, starts, seed
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
            fidelity=rig_fidelity, progress=say, starts=starts, seed=seed, workers=workers,
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
    for c in cands_out:  # the selected effects' posterior standard errors (stage 2)
        if c["effect"] in selected and c["effect"] in params:
            for par, std in c["std"].items():
                params[c["effect"]][par]["std"] = std
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
            "",
            "Each round's decision with its margins (several starts per candidate; a margin "
            "within its own uncertainty is undecided, not taken):",
            "",
            *[
                f"- round {i + 1}: {_describe_decision(h['decision'])}"
                for i, h in enumerate(diag["amplifier_selection"]["history"])
                if "decision" in h
            ],
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
            f"Decision: {rig['decision_text']}." if rig.get("decision_text") else "",
            "",
            "Each hypothesis is fitted from several perturbed starts; its distinct optima "
            "(modes) are scored by their log posterior, the best one reported. "
            "χ², Σz² and the log posterior are those of its best mode (3-D model where "
            "refined; per-axis model where it fell more than the pruning margin behind).",
            "",
            "| hypothesis | prior | χ² | prior penalty Σz² | log posterior | jackknife low "
            "| posterior | modes | starts reaching the best | refined |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
            *[
                f"| {f['hypothesis']} | {f['prior_probability']:.2f} | {f['chi2']:.2f} "
                f"| {f['prior_penalty']:.2f} | {f['log_posterior']:.2f} "
                f"| {f['log_posterior_jackknife_low']:.2f} "
                f"| {rig['posterior'][f['hypothesis']]:.3f} "
                f"| {len(f['modes'])} | {f['starts_agree']}/{f['starts']} | {f['refined']} |"
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
