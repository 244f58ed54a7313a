"""What every calibration returns and the fitting pieces the calibrators share.

:class:`CalibrationResult` is the result of :func:`~.calibrate.calibrate` (traces,
:mod:`.trace_fit`) and of :func:`~.summary.calibrate_summary` (summary-level figures);
:func:`fit_spec` fits a specification (nominal factors and effect parameters) by least
squares in range-normalised coordinates; :func:`parameter_table` and
:func:`fitted_plant` turn a fit into the report's table and the calibrated plant.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize

from ..effects import CATALOGUE
from ..plant import Plant

__all__ = [
    "NOMINAL",
    "CalibrationResult",
    "Fit",
    "fit_spec",
    "fitted_plant",
    "parameter_table",
    "spec_of",
]

# summary-level fits (.summary): friction and preload factors — (name, low, high, start)
NOMINAL = (("friction", 0.5, 2.0, 1.0), ("preload", 0.5, 2.0, 1.0))


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
    problem: Any,  # has residual(nominal, effects, portion) (.summary)
    spec: list,
    max_nfev: int = 40,
    free: Sequence[int] | None = None,
    diff_step: float = 1e-2,
    covariance: str = "scaled",
) -> Fit:
    """Least-squares fit of the spec's parameters on the fit portion; ``free`` limits the
    fit to those indices (the others stay at their start values). The standard errors are
    the Gauss–Newton covariance (JᵀJ)⁻¹ scaled by the residual variance (``"scaled"``), or
    unscaled where the residuals are already in units of their standard deviation
    (``"unscaled"``: a maximum a posteriori objective).

    The fit runs in coordinates normalised to each parameter's range, u = (x − low)/(high −
    low): the finite-difference step is ``diff_step`` of the range whatever the parameter's
    unit and value (a time constant of 1e-6 s and a factor of 1 alike, and a parameter
    whose neutral value is 0), and the standard errors come back in its unit."""
    x_all, lo, hi = _spec_vector(spec)
    idx = np.arange(len(spec)) if free is None else np.asarray(free, dtype=int)
    span = hi[idx] - lo[idx]

    def to_x(u: np.ndarray) -> np.ndarray:
        x = x_all.copy()
        x[idx] = lo[idx] + u * span
        return x

    def fun(u: np.ndarray) -> np.ndarray:
        nominal, effects = _unpack(spec, to_x(u))
        return problem.residual(nominal, effects, "fit")

    u0 = (x_all[idx] - lo[idx]) / span
    res = scipy.optimize.least_squares(
        fun, u0, bounds=(0.0, 1.0), diff_step=diff_step, max_nfev=max_nfev
    )
    x_fit = to_x(res.x)
    nominal, effects = _unpack(spec, x_fit)
    r = res.fun
    dof = max(r.size - idx.size, 1)
    std = np.full(len(spec), math.nan)
    try:
        cov = np.linalg.pinv(res.jac.T @ res.jac)
        if covariance == "scaled":
            cov *= float(r @ r) / dof
        std[idx] = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * span
    except np.linalg.LinAlgError:
        pass
    held = problem.residual(nominal, effects, "heldout")
    return Fit(spec, x_fit, std, nominal, effects, held, float(r @ r))


def spec_of(
    fit_nominal: Mapping[str, float],
    effects: Mapping[str, Mapping[str, float]],
) -> list[tuple[str, str, float, float, float]]:
    spec = [("nominal", n, lo, hi, fit_nominal.get(n, x0)) for n, lo, hi, x0 in NOMINAL]
    for name, vals in effects.items():
        for p in CATALOGUE[name].parameters:
            spec.append((name, p.name, p.low, p.high, vals[p.name]))
    return spec


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


