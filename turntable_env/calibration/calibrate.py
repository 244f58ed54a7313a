"""Calibrate and diagnose: fit the nominal model, find the effect it lacks, report.

:func:`calibrate` takes measurement files (:mod:`.measurement`) and

1. fits the nominal model's uncertain parameters — friction (μ_s and μ_c together) and
   preload (F_N), as factors on the real set — on the **fit portion** of every trace
   (the first ``fit_fraction`` of its time) by scipy ``least_squares``;
2. computes the residual on the **held-out** rest (detector x, and y when recorded,
   converted to table displacement at R_table, Eq. 4.1–4.2: nm) and characterises it:
   Ljung–Box whiteness, spectral peak, correlation with the drive level, the direction
   and speed of motion, time and position;
3. fits every catalogue effect not yet selected together with the nominal parameters and
   the effects already selected, and ranks them by the held-out error they leave,
   penalised for their parameters with the Bayesian information criterion on the
   held-out residual, n·ln(SSE/n) + k·ln n; the best is added if it lowers the criterion
   by more than ``min_bic_gain`` and the held-out RMS by ``min_improvement``; repeat until
   the residual is white or no candidate helps;
4. reports the selected effects, the parameters with their standard errors (from the
   Jacobian at the optimum), the held-out error before and after, every candidate's
   held-out error, and — if structure remains that no candidate explains — its
   signature (:func:`write_report`: ``report.json``, ``report.md`` and plots).

Output-stage effects (misalignment, detector nonlinearity, drift, vibration) do not
change the physics, so the simulated angle is cached per physics parameter vector and
those fits cost almost nothing; starting values for them come from the residual
(regressions, the spectral peak).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats
import threadpoolctl

from ..effects import CATALOGUE, apply_output
from ..params import ParameterSet
from ..plant import Plant, calibrated_set_toml
from .measurement import Measurement, load_measurement
from .trace import simulate_trace

__all__ = ["CalibrationResult", "calibrate", "write_report"]

NOMINAL = (("friction", 0.5, 2.0, 1.0), ("preload", 0.5, 2.0, 1.0))  # factor bounds, start
ERROR_UNIT = "nm"  # residual as displacement at the table radius


def _nm_per_volt(m: Measurement) -> float:
    """Detector volts → displacement at R_table [nm], Eq. 4.1–4.2 linearised at θ = 0."""
    d = m.detector
    return d.sensitivity / (2.0 * d.distance) * d.table_radius * 1e9


@dataclass
class _Trace:
    m: Measurement
    fit: np.ndarray  # bool mask of the fit portion
    has_y: bool


@dataclass
class CalibrationResult:
    """What :func:`calibrate` found (see the module docstring); errors in ``error_unit``."""

    selected_effects: list[str]
    parameters: dict[str, dict[str, dict[str, float]]]
    error_before: float
    error_after: float
    error_unit: str
    residual_structured: bool
    candidates: list[dict[str, Any]]
    diagnosis: dict[str, Any]
    history: list[dict[str, Any]] = field(default_factory=list)
    residuals: dict[str, np.ndarray] = field(default_factory=dict)
    wall_s: float = 0.0
    plant: Plant | None = None
    sections: list[str] = field(default_factory=list)  # further report.md lines
    error_label: str = "held-out error"

    def to_json(self) -> dict[str, Any]:
        return {
            "plant": self.plant.to_dict() if self.plant is not None else None,
            "selected_effects": self.selected_effects,
            "error_before": self.error_before,
            "error_after": self.error_after,
            "error_unit": self.error_unit,
            "error_label": self.error_label,
            "residual_structured": self.residual_structured,
            "parameters": self.parameters,
            "candidates": self.candidates,
            "diagnosis": self.diagnosis,
            "history": self.history,
            "wall_s": self.wall_s,
        }


class _Problem:
    """Residuals of a model specification over the traces, with a physics cache."""

    def __init__(self, traces: list[_Trace], base: str | ParameterSet = "real") -> None:
        self.traces = traces
        self.base = base
        self._cache: dict[tuple, np.ndarray] = {}
        self.n_sims = 0

    def plant(self, nominal: Mapping[str, float], effects: Mapping[str, Any]) -> Plant:
        """The plant of a specification: nominal factors on the base set, the effects."""
        return Plant(self.base, factors=nominal, effects=effects)

    def theta(self, i: int, portion: str, nominal: Mapping[str, float], phys: dict) -> np.ndarray:
        key = (i, portion, tuple(sorted(nominal.items())), repr(sorted(phys.items())))
        if key not in self._cache:
            tr = self.traces[i]
            sel = tr.fit if portion == "fit" else np.ones(tr.m.time.size, bool)
            t = tr.m.time[sel]
            res = simulate_trace(
                self.plant(nominal, phys), tr.m.axis, t, tr.m.drives[tr.m.axis][sel]
            )
            self._cache[key] = res.theta
            self.n_sims += 1
        return self._cache[key]

    def residual(
        self, nominal: Mapping[str, float], effects: Mapping[str, Mapping[str, float]], portion: str
    ) -> np.ndarray:
        """Measured − predicted [nm at R_table] over the fit or held-out portion."""
        phys = {k: dict(v) for k, v in effects.items() if CATALOGUE[k].stage != "output"}
        out = {k: v for k, v in effects.items() if CATALOGUE[k].stage == "output"}
        parts = []
        for i, tr in enumerate(self.traces):
            th = self.theta(i, "fit" if portion == "fit" else "all", nominal, phys)
            m = tr.m
            t = m.time[: th.size]
            x, y = apply_output(t - m.time[0], th, out, m.detector)
            vs = m.detector.saturation_voltage
            x, y = np.clip(x, -vs, vs), np.clip(y, -vs, vs)
            sel = slice(None) if portion == "fit" else ~tr.fit
            scale = _nm_per_volt(m)
            parts.append((m.detector_v[: th.size] - x)[sel] * scale)
            if tr.has_y and m.detector_y_v is not None:
                parts.append((m.detector_y_v[: th.size] - y)[sel] * scale)
        return np.concatenate(parts)


def _spec_vector(spec: list[tuple[str, str, float, float, float]]) -> tuple[np.ndarray, ...]:
    x0 = np.array([s[4] for s in spec])
    lo = np.array([s[2] for s in spec])
    hi = np.array([s[3] for s in spec])
    return np.clip(x0, lo, hi), lo, hi


def _unpack(spec, x) -> tuple[dict[str, float], dict[str, dict[str, float]]]:
    nominal: dict[str, float] = {}
    effects: dict[str, dict[str, float]] = {}
    for (owner, name, *_), v in zip(spec, x, strict=True):
        if owner == "nominal":
            nominal[name] = float(v)
        else:
            effects.setdefault(owner, {})[name] = float(v)
    for name, vals in effects.items():  # parameters not fitted stay neutral
        full = CATALOGUE[name].neutral()
        full.update(vals)
        effects[name] = full
    return nominal, effects


@dataclass
class Fit:
    spec: list
    x: np.ndarray
    std: np.ndarray
    nominal: dict[str, float]
    effects: dict[str, dict[str, float]]
    heldout: np.ndarray
    sse_fit: float = math.nan  # sum of squared residuals on the fit portion [nm²]

    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.heldout**2)))

    def bic(self) -> float:
        n = self.heldout.size
        return float(n * math.log(np.mean(self.heldout**2)) + len(self.spec) * math.log(n))


def fit_spec(
    problem: _Problem,
    spec: list,
    max_nfev: int = 40,
    free: Sequence[int] | None = None,
    diff_step: float = 1e-2,
) -> Fit:
    """Least-squares fit of the spec's parameters on the fit portion; ``free`` limits the
    fit to those indices (the others stay at their start values)."""
    x_all, lo, hi = _spec_vector(spec)
    idx = np.arange(len(spec)) if free is None else np.asarray(free, dtype=int)

    def fun(xf: np.ndarray) -> np.ndarray:
        x = x_all.copy()
        x[idx] = xf
        nominal, effects = _unpack(spec, x)
        return problem.residual(nominal, effects, "fit")

    res = scipy.optimize.least_squares(
        fun, x_all[idx], bounds=(lo[idx], hi[idx]), x_scale=hi[idx] - lo[idx],
        diff_step=diff_step, max_nfev=max_nfev,
    )  # fmt: skip
    x_fit = x_all.copy()
    x_fit[idx] = res.x
    nominal, effects = _unpack(spec, x_fit)
    r = res.fun
    dof = max(r.size - idx.size, 1)
    std = np.full(len(spec), math.nan)
    try:
        cov = np.linalg.pinv(res.jac.T @ res.jac) * float(r @ r) / dof
        std[idx] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        pass
    held = problem.residual(nominal, effects, "heldout")
    return Fit(spec, x_fit, std, nominal, effects, held, float(r @ r))


def _start_values(
    name: str,
    problem: _Problem,
    nominal: Mapping[str, float],
    effects: Mapping[str, Mapping[str, float]],
) -> dict[str, float]:
    """Starting values for an effect's parameters from a model's residual."""
    e = CATALOGUE[name]
    start = e.neutral()
    if name == "piezo_hysteresis":
        start = {"h": 0.02, "width": e.defaults()["width"]}
    elif name == "piezo_creep":
        start = {"gamma": 0.005}
    elif name == "amplifier_dynamics":
        start = {"slew_scale": 0.9, "current_scale": 1.0}
    elif name in ("friction_asymmetry", "friction_wear"):
        key = e.parameters[0].name
        start = {key: 0.02}
    tr = problem.traces[0]
    m = tr.m
    r = problem.residual(nominal, effects, "fit")[: int(tr.fit.sum())]
    t = m.time[tr.fit] - m.time[0]
    scale = _nm_per_volt(m)
    if name == "sensor_drift":
        a = np.column_stack([np.ones_like(t), t])
        c, *_ = np.linalg.lstsq(a, r / scale, rcond=None)
        start = {"offset": float(c[0]), "rate": float(c[1])}
    elif name == "vibration" and t.size > 16:
        tu = np.linspace(t[0], t[-1], t.size)
        ru = np.interp(tu, t, r) / (m.detector.table_radius * 1e9)  # rad
        spec = np.abs(np.fft.rfft(ru - ru.mean()))
        freqs = np.fft.rfftfreq(tu.size, tu[1] - tu[0])
        ok = (freqs >= 1.0) & (freqs <= 1000.0)
        f = float(freqs[ok][np.argmax(spec[ok])])
        a = np.column_stack([np.sin(2 * math.pi * f * tu), np.cos(2 * math.pi * f * tu)])
        c, *_ = np.linalg.lstsq(a, ru, rcond=None)
        start = {
            "amplitude": float(np.hypot(*c)),
            "frequency": f,
            "phase": float(np.arctan2(c[1], c[0])),
        }
    elif name == "axis_misalignment" and tr.has_y and m.detector_y_v is not None:
        x, y = m.detector_v, m.detector_y_v
        start = {"phi": float(abs(np.arctan2(x @ y, x @ x)))}
    elif name == "detector_nonlinearity":
        v = m.detector_v[tr.fit]
        vs = m.detector.saturation_voltage
        basis = v * (v / vs) ** 2
        denom = float(basis @ basis)
        start = {"kappa": float((r / scale) @ basis / denom) if denom > 0 else 0.0}
    return {p.name: float(np.clip(start[p.name], p.low, p.high)) for p in e.parameters}


def _screen(problem: _Problem, current: Fit, name: str) -> Fit:
    """Fit one candidate on top of the current model.

    Output-stage effects start from the residual (:func:`_start_values`) and are fitted
    alone (they do not touch the physics); they are also fitted jointly with the nominal
    parameters from the prior ones (where the nominal fit has absorbed part of the
    effect: friction rescales the steps to mimic a detector gain), and the variant with
    the smaller fit-portion error is kept. The others start from the best point of a
    7-point grid over their first parameter, evaluated both at the current nominal
    parameters and at the prior ones (the nominal fit may have absorbed part of the
    effect: friction compensates a direction-dependent friction on average), and are
    refined by a bounded 1-D search within a grid cell, then fitted jointly with the
    nominal parameters."""
    start = _start_values(name, problem, current.nominal, current.effects)
    e = CATALOGUE[name]
    prior = {n: x0 for n, _lo, _hi, x0 in NOMINAL}
    if e.stage == "output":
        spec = spec_of(current.nominal, {**current.effects, name: start})
        free = [i for i, s_ in enumerate(spec) if s_[0] == name]
        alone = fit_spec(problem, spec, free=free, max_nfev=20)
        start = _start_values(name, problem, prior, current.effects)
        spec = spec_of(prior, {**current.effects, name: start})
        free = [i for i, s_ in enumerate(spec) if s_[0] in ("nominal", name)]
        joint = fit_spec(problem, spec, free=free, max_nfev=20)
        return joint if joint.sse_fit < alone.sse_fit else alone
    p0 = e.parameters[0]
    best_sse, nominal = math.inf, dict(current.nominal)
    for nom in (current.nominal, prior):
        for v in np.linspace(p0.low, p0.high, 7):
            trial = {**start, p0.name: float(v)}
            r = problem.residual(nom, {**current.effects, name: trial}, "fit")
            sse = float(r @ r)
            if sse < best_sse:
                best_sse, start, nominal = sse, trial, dict(nom)

    def sse_at(v: float) -> float:
        r = problem.residual(nominal, {**current.effects, name: {**start, p0.name: v}}, "fit")
        return float(r @ r)

    # refine the grid point by a bounded 1-D search over one grid cell either side
    cell = (p0.high - p0.low) / 6.0
    v0 = start[p0.name]
    lo, hi = max(p0.low, v0 - cell), min(p0.high, v0 + cell)
    line = scipy.optimize.minimize_scalar(
        sse_at, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3 * cell, "maxiter": 15}
    )
    if line.fun < best_sse:
        start = {**start, p0.name: float(line.x)}
    spec = spec_of(nominal, {**current.effects, name: start})
    free = [i for i, s_ in enumerate(spec) if s_[0] in ("nominal", name)]
    return fit_spec(problem, spec, free=free, max_nfev=25)


def _polish(problem: _Problem, fit: Fit, rounds: int = 2) -> Fit:
    """Joint refit of every parameter, restarted from its own optimum (the simulated
    objective is piecewise smooth, so a restart often moves on)."""
    for k in range(rounds):
        step = 1e-2 if k == 0 else 1e-3  # then finer differences near the optimum
        new = fit_spec(problem, spec_of(fit.nominal, fit.effects), max_nfev=50, diff_step=step)
        if new.bic() >= fit.bic() - 1.0:
            return new if new.bic() < fit.bic() else fit
        fit = new
    return fit


def is_significant(fit: Fit, name: str) -> bool:
    """At least one of the effect's parameters lies 3 standard errors from neutral."""
    neutral = CATALOGUE[name].neutral()
    for (owner, pname, *_), v, s in zip(fit.spec, fit.x, fit.std, strict=True):
        if owner == name and abs(v - neutral[pname]) > 3.0 * (s if math.isfinite(s) else 0.0):
            if math.isfinite(s):
                return True
    return False


def spec_of(
    fit_nominal: Mapping[str, float],
    effects: Mapping[str, Mapping[str, float]],
) -> list[tuple[str, str, float, float, float]]:
    spec = [("nominal", n, lo, hi, fit_nominal.get(n, x0)) for n, lo, hi, x0 in NOMINAL]
    for name, vals in effects.items():
        for p in CATALOGUE[name].parameters:
            spec.append((name, p.name, p.low, p.high, vals[p.name]))
    return spec


def diagnose(problem: _Problem, fit: Fit) -> dict[str, Any]:
    """Held-out residual signature: Ljung–Box whiteness of the whole residual; the
    correlations of the x channel's residual with time, position, velocity, direction and
    drive level over every trace; the spectral peak of the longest trace's."""
    r = fit.heldout
    n_lags = 20
    lb = scipy.stats.chi2  # Ljung–Box Q = n(n+2) Σ ρ_k²/(n−k)
    rc = r - r.mean()
    denom = float(rc @ rc) or 1.0
    n = rc.size
    rho = np.array([float(rc[:-k] @ rc[k:]) / denom for k in range(1, n_lags + 1)])
    q = n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, n_lags + 1))))
    p_white = float(lb.sf(q, n_lags))
    # the x-channel part of every trace's held-out residual, with its regressors
    phys = {k: v for k, v in fit.effects.items() if CATALOGUE[k].stage != "output"}
    cols: dict[str, list[np.ndarray]] = {
        k: [] for k in ("residual", "time", "position", "velocity", "direction", "drive_level")
    }
    longest: tuple[np.ndarray, np.ndarray] | None = None
    offset = 0
    for i, tr in enumerate(problem.traces):
        m = tr.m
        held = ~tr.fit
        n_held = int(held.sum())
        t = m.time[held]
        x_part = r[offset : offset + n_held]
        offset += n_held * (2 if tr.has_y and m.detector_y_v is not None else 1)
        th_model = problem.theta(i, "all", fit.nominal, phys)[held]
        vel = np.gradient(th_model, t)
        cols["residual"].append(x_part)
        cols["time"].append(t - m.time[0])
        cols["position"].append(th_model)
        cols["velocity"].append(vel)
        cols["direction"].append(np.sign(vel) * (np.abs(vel) > 1e-6))
        cols["drive_level"].append(m.drives[m.axis][held])
        if longest is None or t.size > longest[0].size:
            longest = (t, x_part)
    res_x = np.concatenate(cols.pop("residual"))
    corr = {}
    for k, parts in cols.items():
        v = np.concatenate(parts)
        if np.std(v) > 0 and np.std(res_x) > 0:
            corr[k] = float(np.corrcoef(v, res_x)[0, 1])
    assert longest is not None
    t, x_part = longest  # spectrum of the longest trace's held-out x residual
    tu = np.linspace(t[0], t[-1], t.size)
    ru = np.interp(tu, t, x_part)
    spec = np.abs(np.fft.rfft(ru - ru.mean())) ** 2
    freqs = np.fft.rfftfreq(tu.size, tu[1] - tu[0])
    k = int(np.argmax(spec[1:]) + 1)
    return {
        "ljung_box_p": p_white,
        "white": p_white > 0.01,
        "rms": fit.rms(),
        "spectral_peak_Hz": float(freqs[k]),
        "spectral_peak_share": float(spec[k] / spec[1:].sum()),
        "correlation": corr,
    }


def calibrate(
    files: Sequence[str | Path | Measurement],
    *,
    fit_fraction: float = 0.6,
    candidates: Sequence[str] | None = None,
    max_effects: int = 3,
    min_improvement: float = 0.05,
    min_bic_gain: float = 20.0,
    progress: Callable[[str], None] | None = print,
) -> CalibrationResult:
    """Fit, diagnose and select effects (module docstring) for measurement files.

    Runs with one BLAS thread: its linear algebra is small and dense, where OpenBLAS's
    worker threads only spin and slow every simulation down."""
    with threadpoolctl.threadpool_limits(limits=1, user_api="blas"):
        return _calibrate(
            files,
            fit_fraction=fit_fraction,
            candidates=candidates,
            max_effects=max_effects,
            min_improvement=min_improvement,
            min_bic_gain=min_bic_gain,
            progress=progress,
        )


def _calibrate(
    files: Sequence[str | Path | Measurement],
    *,
    fit_fraction: float,
    candidates: Sequence[str] | None,
    max_effects: int,
    min_improvement: float,
    min_bic_gain: float,
    progress: Callable[[str], None] | None,
) -> CalibrationResult:
    t_start = time.perf_counter()
    if not 0.2 <= fit_fraction <= 0.9:
        raise ValueError(f"fit_fraction={fit_fraction!r}: must be in [0.2, 0.9]")
    say = progress or (lambda _msg: None)
    traces = []
    for f in files:
        m = f if isinstance(f, Measurement) else load_measurement(f)
        if m.axis not in ("A", "B", "C"):
            raise ValueError(f"{m.source}: axis {m.axis!r}: the calibrator models A, B and C")
        t_split = m.time[0] + fit_fraction * (m.time[-1] - m.time[0])
        traces.append(_Trace(m, m.time <= t_split, m.detector_y_v is not None))
    problem = _Problem(traces, "real")
    names = list(candidates) if candidates is not None else list(CATALOGUE)
    say(f"fitting the nominal model (friction, preload) on {len(traces)} trace(s)")
    current = _polish(problem, fit_spec(problem, spec_of({}, {}), max_nfev=60))
    before = current.rms()
    history = [{"effects": [], "heldout_rms": before, "bic": current.bic()}]
    say(f"  held-out error {before:.2f} {ERROR_UNIT}")
    candidates_out: list[dict[str, Any]] = []
    selected: list[str] = []
    diag = diagnose(problem, current)
    while len(selected) < max_effects:
        if diag["white"] and selected:
            break
        results = []
        for name in names:
            if name in selected:
                continue
            cand = _screen(problem, current, name)
            results.append((name, cand))
            say(f"  candidate {name:<22} held-out {cand.rms():.2f} {ERROR_UNIT}")
        if not results:
            break
        for name, cand in results:
            candidates_out.append(
                {
                    "round": len(selected) + 1,
                    "effect": name,
                    "heldout_error": cand.rms(),
                    "bic": cand.bic(),
                    "parameters": len(cand.spec),
                }
            )
        ranked = sorted(results, key=lambda nc: nc[1].bic())[:2]
        refits = [(n, _polish(problem, c)) for n, c in ranked]
        name, best = min(refits, key=lambda nc: nc[1].bic())  # joint refit of the top two
        gain = current.bic() - best.bic()
        significant = is_significant(best, name)
        if (
            gain < min_bic_gain
            or best.rms() > (1.0 - min_improvement) * current.rms()
            or not significant
        ):
            say(
                f"  no candidate helps enough (best {name}: BIC gain {gain:.1f}, "
                f"significant {significant})"
            )
            # the joint refit may have found a better optimum of the selected effects:
            # refit them alone from there and keep it if it is better
            spec = spec_of(best.nominal, {k: best.effects[k] for k in selected})
            alt = fit_spec(problem, spec, max_nfev=50)
            if alt.bic() < current.bic():
                current = alt
                diag = diagnose(problem, current)
                say(f"  refit of the selected effects: held-out error {current.rms():.2f} nm")
            break
        selected.append(name)
        current = best
        diag = diagnose(problem, current)
        history.append(
            {"effects": list(selected), "heldout_rms": current.rms(), "bic": current.bic()}
        )
        say(
            f"selected {name}: held-out error {current.rms():.2f} {ERROR_UNIT}, "
            f"white={diag['white']}"
        )
    params = parameter_table(current)
    structured = not diag["white"]
    if structured:
        diag["signature"] = _describe(diag)
    return CalibrationResult(
        selected_effects=selected,
        parameters=params,
        error_before=before,
        error_after=current.rms(),
        error_unit=ERROR_UNIT,
        residual_structured=structured,
        candidates=candidates_out,
        diagnosis=diag,
        history=history,
        residuals={"after": current.heldout},
        wall_s=time.perf_counter() - t_start,
        plant=fitted_plant(problem.plant(current.nominal, current.effects), current),
    )


def parameter_table(fit: Fit) -> dict[str, dict[str, dict[str, float]]]:
    """owner → parameter → {value, std} of a fit (owner "nominal" for the factors)."""
    params: dict[str, dict[str, dict[str, float]]] = {}
    for (owner, pname, *_), v, s in zip(fit.spec, fit.x, fit.std, strict=True):
        params.setdefault(owner, {})[pname] = {"value": float(v), "std": float(s)}
    return params


def fitted_plant(plant: Plant, fit: Fit) -> Plant:
    """``plant`` with the fit's standard errors as its uncertainty (finite ones), so
    :meth:`Plant.sample` draws from the calibration's posterior."""
    unc = {}
    for (owner, pname, *_), s in zip(fit.spec, fit.std, strict=True):
        if math.isfinite(s):
            unc[pname if owner == "nominal" else f"{owner}.{pname}"] = float(s)
    return plant.replace(uncertainty=unc)


def _describe(diag: Mapping[str, Any]) -> str:
    corr = diag.get("correlation", {})
    strongest = max(corr.items(), key=lambda kv: abs(kv[1])) if corr else ("none", 0.0)
    return (
        f"residual not white (Ljung–Box p = {diag['ljung_box_p']:.2g}); spectral peak at "
        f"{diag['spectral_peak_Hz']:.1f} Hz holding {diag['spectral_peak_share']:.0%} of the "
        f"power; strongest correlation with {strongest[0]} ({strongest[1]:+.2f})"
    )


def plot_residual(result: CalibrationResult, path: Path) -> None:
    """Held-out residual over samples (traces), or per-target relative errors before and
    after (summary-level data)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result.diagnosis.get("targets")
    if rows:
        fig, ax = plt.subplots(figsize=(7, 3.2))
        y = np.arange(len(rows))
        ax.barh(y - 0.2, [100 * r["error_before"] for r in rows], 0.4, label="before")
        ax.barh(y + 0.2, [100 * r["error_after"] for r in rows], 0.4, label="after")
        ax.set_yticks(y, [r["target"] for r in rows], fontsize=7)
        ax.axvline(0.0, color="k", lw=0.5)
        ax.set_xlabel("relative error [%]")
        ax.legend(fontsize=7)
    else:
        fig, ax = plt.subplots(figsize=(7, 3))
        ax.plot(result.residuals["after"], lw=0.5)
        ax.set_xlabel("held-out sample")
        ax.set_ylabel(f"residual [{result.error_unit}]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_report(result: CalibrationResult, out: str | Path) -> dict[str, Path]:
    """``report.json``, ``report.md`` and ``residual.png`` in ``out``; with a rig fit also
    ``calibrated.toml``, the calibrated parameter set
    (:func:`~turntable_env.plant.calibrated_set_toml`)."""
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    pj = d / "report.json"
    pj.write_text(json.dumps(result.to_json(), indent=2))
    plot_residual(result, d / "residual.png")
    lines = [
        "# Calibration report",
        "",
        f"- selected effects: {', '.join(result.selected_effects) or 'none'}",
        f"- {result.error_label} before: {result.error_before:.3g} {result.error_unit}, after: "
        f"{result.error_after:.3g} {result.error_unit}",
        f"- residual structured: {result.residual_structured}"
        + (f" — {result.diagnosis.get('signature', '')}" if result.residual_structured else ""),
        f"- wall time: {result.wall_s:.1f} s",
        "",
        "| round | candidate | held-out error |",
        "|---:|---|---:|",
        *[
            f"| {c['round']} | {c['effect']} | {c['heldout_error']:.3g} |"
            for c in result.candidates
        ],
        "",
        "| owner | parameter | value | std |",
        "|---|---|---:|---:|",
        *[
            f"| {o} | {p} | {v['value']:.4g} | {v['std']:.2g} |"
            for o, ps in result.parameters.items()
            for p, v in ps.items()
        ],
        *result.sections,
        "",
        "![residual](residual.png)",
    ]
    pm = d / "report.md"
    pm.write_text("\n".join(lines) + "\n", encoding="utf-8")
    paths = {"json": pj, "md": pm, "png": d / "residual.png"}
    if result.plant is not None and result.plant.rig is not None:
        paths["parameters"] = d / "calibrated.toml"
        paths["parameters"].write_text(
            calibrated_set_toml(result.plant, source=f"turntable calibrate --report {d}"),
            encoding="utf-8",
        )
    return paths
