"""Calibrate and diagnose: the entry point, the shared fitting pieces and the report.

:func:`calibrate` fits measurement files (:mod:`.measurement`): the nominal model first
(global stage, then least squares with priors), effects only after it fits, judged on
held-out segments interleaved by drive condition and against the data's noise floor —
:mod:`.trace_fit` says how. Summary-level figures (the thesis's chapter 4) go through
:mod:`.summary`, which shares :func:`fit_spec` and :class:`CalibrationResult` from here.
:func:`write_report` writes what a lab engineer acts on: ``report.json``, ``report.md``
(the noise floor beside every error, parameters with uncertainties and flags, warnings),
``overlay.png`` (measured and model over time with the drive) and ``residual.png``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats
import threadpoolctl

from ..effects import CATALOGUE
from ..files import output_directory
from ..plant import Plant, calibrated_set_toml
from .measurement import Measurement

__all__ = ["CalibrationResult", "calibrate", "write_report"]

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


def calibrate(files: Sequence[str | Path | Measurement], **options: Any) -> CalibrationResult:
    """Calibrate measurement files: :func:`~.trace_fit.calibrate_traces` with its keyword
    arguments (base, candidates, max_effects, min_improvement, global_points, starts,
    workers, seed, progress).

    Runs with one BLAS thread: its linear algebra is small and dense, where OpenBLAS's
    worker threads only spin and slow every simulation down."""
    from .trace_fit import calibrate_traces

    with threadpoolctl.threadpool_limits(limits=1, user_api="blas"):
        return calibrate_traces(files, **options)


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


def plot_residual(result: CalibrationResult, path: Path) -> None:
    """Held-out residual over samples with the noise floor (traces), or per-target
    relative errors before and after (summary-level data)."""
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
        ax.plot(result.residuals["after"], lw=0.5, label="held-out residual")
        floor = result.diagnosis.get("noise_floor")
        if floor:
            for sgn in (-3, 3):
                ax.axhline(sgn * floor, color="r", lw=0.6, ls="--")
            ax.plot([], [], color="r", ls="--", label="±3× noise floor")
        ax.set_xlabel("held-out sample")
        ax.set_ylabel(f"residual [{result.error_unit}]")
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_overlay(result: CalibrationResult, path: Path) -> bool:
    """Measured and model traces [nm at R_table] over time with the drive [V] below
    (held-out segments shaded); False when the result has no trace to show."""
    r = result.residuals
    if "overlay_time" not in r:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = r["overlay_time"] - r["overlay_time"][0]
    fig, (ax, axd) = plt.subplots(
        2, 1, figsize=(8, 4.6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    held = r["overlay_heldout"]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], held.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        ax.axvspan(t[a], t[min(b, t.size - 1)], color="0.92", lw=0)
    ax.plot(t, r["overlay_measured"], lw=0.6, label="measured")
    ax.plot(t, r["overlay_model"], lw=0.6, label="model (re-anchored per segment)")
    ax.set_ylabel(f"displacement [{result.error_unit}]")
    ax.legend(fontsize=7, title="grey: held-out segments", title_fontsize=7)
    axd.plot(t, r["overlay_drive"], lw=0.6, color="k")
    axd.set_ylabel("drive [V]")
    axd.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def _ratio(x: float, floor: float) -> str:
    """x / floor to one decimal; "—" for a noise-free trace (floor 0)."""
    return f"{x / floor:.1f}" if floor > 0 else "—"


def _md_trace_sections(result: CalibrationResult) -> list[str]:
    """report.md lines of a trace calibration: floor, starts, parameters, diagnosis."""
    d = result.diagnosis
    if "noise_floor" not in d:
        return []
    u = result.error_unit
    floor = d["noise_floor"]
    lines = [
        "",
        f"## Errors beside the noise floor ({floor:.3g} {u}, {d['noise_floor_source']})",
        "",
        f"| model | held-out error [{u}] | × floor |",
        "|---|---:|---:|",
        f"| prior (before) | {result.error_before:.3g} | {_ratio(result.error_before, floor)} |",
        f"| nominal fit | {d['error_nominal']:.3g} | {_ratio(d['error_nominal'], floor)} |",
        f"| final | {result.error_after:.3g} | {_ratio(result.error_after, floor)} |",
        "",
        f"Target max(3× floor, 2 % of the RMS motion {d['rms_motion']:.4g} {u}) = "
        f"{d['target']:.3g} {u}: {'met' if result.error_after <= d['target'] else 'not met'}.",
        "",
        f"## Global stage: {d['starts']['agreeing']} of {d['starts']['total']} local fits "
        "reach the optimum (within 2σ or 1 % of its cost)",
        "",
        f"| start | cost | held-out [{u}] | max distance [σ] |",
        "|---:|---:|---:|---:|",
        *[
            f"| {k} | {f['cost']:.5g} | {f['heldout_rms']:.3g} | {f['max_distance_sigma']:.2g} |"
            for k, f in enumerate(d["starts"]["fits"])
        ],
        "",
        "## Parameters",
        "",
        "| owner | parameter | value | std | identified | at bound | meaning |",
        "|---|---|---:|---:|---|---|---|",
    ]
    for o, ps in result.parameters.items():
        for p, v in ps.items():
            unit = f" {v['unit']}" if v.get("unit") else ""
            lines.append(
                f"| {o} | {p} | {v['value']:.4g}{unit} | {v['std']:.2g} | "
                f"{'yes' if v.get('identified', True) else 'no (prior)'} | "
                f"{'**yes**' if v.get('at_bound') else 'no'} | {v.get('meaning', '')} |"
            )
    lines += ["", "## Effects the protocol can identify", ""]
    lines += [f"- {k}: {v}" for k, v in d["identifiability"].items()]
    lines += ["", "## Residual", ""]
    lines.append(d.get("signature", f"at the noise floor ({result.error_after:.3g} {u})"))
    if d["warnings"]:
        lines += ["", "## Warnings", "", *[f"- {w}" for w in d["warnings"]]]
    return lines


def write_report(result: CalibrationResult, out: str | Path) -> dict[str, Path]:
    """``report.json``, ``report.md``, ``residual.png`` (and ``overlay.png`` for traces)
    in ``out``; with a rig fit also ``calibrated.toml``, the calibrated parameter set
    (:func:`~turntable_env.plant.calibrated_set_toml`). The directory is complete or
    untouched (:func:`~turntable_env.files.output_directory`)."""
    final = Path(out)
    with output_directory(final) as d:
        names = _write_report_files(result, d, final)
    return {k: final / v for k, v in names.items()}


def _write_report_files(result: CalibrationResult, d: Path, final: Path) -> dict[str, str]:
    pj = d / "report.json"
    pj.write_text(json.dumps(result.to_json(), indent=2))
    plot_residual(result, d / "residual.png")
    has_overlay = plot_overlay(result, d / "overlay.png")
    floor = result.diagnosis.get("noise_floor")
    fl = f" (noise floor {floor:.3g} {result.error_unit})" if floor else ""
    lines = [
        "# Calibration report",
        "",
        f"- selected effects: {', '.join(result.selected_effects) or 'none'}",
        f"- {result.error_label} before: {result.error_before:.3g} {result.error_unit}, after: "
        f"{result.error_after:.3g} {result.error_unit}{fl}",
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
    ]
    trace_lines = _md_trace_sections(result)
    if trace_lines:
        lines += trace_lines
    else:
        lines += [
            "",
            "| owner | parameter | value | std |",
            "|---|---|---:|---:|",
            *[
                f"| {o} | {p} | {v['value']:.4g} | {v['std']:.2g} |"
                for o, ps in result.parameters.items()
                for p, v in ps.items()
            ],
        ]
    lines += [*result.sections, ""]
    if has_overlay:
        lines += ["![measured and model](overlay.png)", ""]
    lines.append("![residual](residual.png)")
    pm = d / "report.md"
    pm.write_text("\n".join(lines) + "\n", encoding="utf-8")
    paths = {"json": pj.name, "md": pm.name, "png": "residual.png"}
    if has_overlay:
        paths["overlay"] = "overlay.png"
    if result.plant is not None and result.plant.rig is not None:
        paths["parameters"] = "calibrated.toml"
        (d / "calibrated.toml").write_text(
            calibrated_set_toml(result.plant, source=f"turntable calibrate --report {final}"),
            encoding="utf-8",
        )
    return paths
