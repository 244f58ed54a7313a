"""Rig calibration on the thesis's stepping figures: the stroke chain, the detector and the
contacts, fitted with priors on the full 3-D model (issue 18).

The measured steps (0.374 µm one-directional, 0.300 µm two-directional, §4.1.3) exceed
the free contact travel of the tubes as Table D.1 and §2.1.2 describe them (0.294 µm at
90 V, asymmetric drive): no friction or preload value can reach them. What can is the rig
— the properties the thesis does not pin down (:class:`~turntable_env.params.RigParams`,
each with a prior and its source):

* continuous, with the friction and preload factors: large-signal d₃₁, tube length, the
  photodiode's gain, the contacts' presliding distance (their tangential compliance);
* discrete hypotheses: the drive mode (asymmetric, as §2.1.2 says, or symmetric), the
  sign of the quadrants' axial strain, and the mirror (on the table's flat face, tilting
  by cos 35.26° per rotation about B, or facing the axis's perpendicular).

For every hypothesis, :func:`fit_rig` finds the maximum a posteriori parameters: it
minimises Σ(eᵢ/σᵢ)² + Σzⱼ², eᵢ the figures' errors (predicted − measured, in their units),
σᵢ = √(resolutionᵢ² + (``MODEL_ERROR``·scaleᵢ)²) and zⱼ each parameter's standardised
distance from its prior (normal, or normal in the logarithm) — by scipy ``least_squares``
in the standardised coordinates, on the 3-D model (``fidelity``). The hypotheses are
compared by their posterior: −½χ² − ½Σz² + ln P(hypothesis) (:func:`calibrate_rig`).

The uncertainties are the Laplace approximation at the optimum (the Jacobian, priors
included); a parameter the figures do not identify keeps most of its prior width (the
``shrinkage`` posterior/prior std is near 1) or is strongly correlated with another.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize

from ..params import RIG_CHOICES, RIG_PRIORS, RigParams
from .summary import SummaryProblem
from .thesis_data import SummaryTarget

__all__ = [
    "MODEL_ERROR",
    "PRIORS",
    "Hypothesis",
    "RigFit",
    "RigResult",
    "calibrate_rig",
    "fit_rig",
    "hypotheses",
]

MODEL_ERROR = 0.05  # relative error allowed the model on each figure (its σ, with the resolution)
# name: (low, high, kind, centre, σ, source) — σ of the value ("normal") or of its log
PRIORS: dict[str, tuple[float, float, str, float, float, str]] = {
    "friction": (
        0.3, 3.0, "lognormal", 1.0, 0.5,
        "μ_s and μ_c of the unlisted file (alumina on steel): a factor 1.6 either way",
    ),
    "preload": (
        0.3, 3.0, "lognormal", 1.0, 0.5,
        "F_N of the unlisted file (the preload spring is undocumented)",
    ),
    **{
        name: (lo, hi, "lognormal" if name == "presliding_factor" else "normal", mean, std, src)
        for name, (lo, hi, mean, std, src) in RIG_PRIORS.items()
    },
}  # fmt: skip
FIT_PARAMETERS = tuple(PRIORS)
GRID = (-1.0, 0.0, 1.0, 2.0)  # standardised starts of the global stage (friction, preload, d31)
GLOBAL_STARTS = 3  # best grid points refined by least squares


@dataclass(frozen=True)
class Hypothesis:
    """One combination of the discrete rig choices and its prior probability."""

    drive_mode: str
    axial_strain_sign: int
    mirror_tilt: float
    prior: float

    @property
    def label(self) -> str:
        mirror = "horizontal mirror" if self.mirror_tilt < 0.99 else "mirror ⟂ axis"
        sign = "" if self.drive_mode == "symmetric" else f", axial {self.axial_strain_sign:+d}"
        return f"{self.drive_mode}{sign}, {mirror}"

    def rig(self, **values: float) -> RigParams:
        return RigParams(
            drive_mode=self.drive_mode,  # type: ignore[arg-type]
            axial_strain_sign=self.axial_strain_sign,
            mirror_tilt=self.mirror_tilt,
            tube_inertia="physical",
            **values,
        )


def hypotheses() -> list[Hypothesis]:
    """Every combination of :data:`~turntable_env.params.RIG_CHOICES` (the axial strain's sign
    only matters in the asymmetric mode: the symmetric mode cancels the axial strain)."""
    modes, p_mode, _ = RIG_CHOICES["drive_mode"]
    signs, p_sign, _ = RIG_CHOICES["axial_strain_sign"]
    tilts, p_tilt, _ = RIG_CHOICES["mirror_tilt"]
    out = []
    mode_p = zip(modes, p_mode, strict=True)
    tilt_p = list(zip(tilts, p_tilt, strict=True))
    for (m, pm), (t, pt) in itertools.product(mode_p, tilt_p):
        if m == "symmetric":
            out.append(Hypothesis(m, 1, t, pm * pt))
            continue
        for s, ps in zip(signs, p_sign, strict=True):
            out.append(Hypothesis(m, s, t, pm * pt * ps))
    return out


def _to_value(name: str, z: float) -> float:
    _lo, _hi, kind, centre, sigma, _src = PRIORS[name]
    return centre * math.exp(sigma * z) if kind == "lognormal" else centre + sigma * z


def _to_z(name: str, x: float) -> float:
    _lo, _hi, kind, centre, sigma, _src = PRIORS[name]
    return math.log(x / centre) / sigma if kind == "lognormal" else (x - centre) / sigma


def _dvalue_dz(name: str, z: float) -> float:
    kind, sigma = PRIORS[name][2], PRIORS[name][4]
    return sigma * _to_value(name, z) if kind == "lognormal" else sigma


@dataclass
class RigFit:
    """The maximum a posteriori fit of one hypothesis (module docstring).

    Attributes:
        hypothesis; values: parameter → estimate; std: its Laplace standard error;
        shrinkage: posterior over prior standard deviation (≈ 1: not identified by the
        figures); correlation: (p, p) matrix over ``FIT_PARAMETERS``; errors: target →
        predicted − measured (its unit); sigma: target → σ; chi2: Σ(e/σ)²; prior_penalty:
        Σz²; log_posterior: −½chi2 − ½prior_penalty + ln P(hypothesis); predicted:
        target → value (the 3-D model's unless fitted on the reduced one alone);
        n_evaluations; correction: target → 3-D minus reduced prediction at the optimum
        (the correction the ``"corrected"`` fit carried).
    """

    hypothesis: Hypothesis
    values: dict[str, float]
    std: dict[str, float]
    shrinkage: dict[str, float]
    correlation: np.ndarray
    errors: dict[str, float]
    sigma: dict[str, float]
    predicted: dict[str, float]
    chi2: float
    prior_penalty: float
    n_evaluations: int
    correction: dict[str, float] = field(default_factory=dict)
    jacobian: np.ndarray = field(repr=False, default_factory=lambda: np.empty(0))

    @property
    def log_posterior(self) -> float:
        return -0.5 * self.chi2 - 0.5 * self.prior_penalty + math.log(self.hypothesis.prior)

    def to_json(self) -> dict[str, Any]:
        return {
            "hypothesis": self.hypothesis.label,
            "drive_mode": self.hypothesis.drive_mode,
            "axial_strain_sign": self.hypothesis.axial_strain_sign,
            "mirror_tilt": self.hypothesis.mirror_tilt,
            "prior_probability": self.hypothesis.prior,
            "values": self.values,
            "std": self.std,
            "shrinkage": self.shrinkage,
            "correlation": {
                a: {b: float(self.correlation[i, j]) for j, b in enumerate(FIT_PARAMETERS)}
                for i, a in enumerate(FIT_PARAMETERS)
            },
            "errors": self.errors,
            "sigma": self.sigma,
            "predicted": self.predicted,
            "chi2": self.chi2,
            "prior_penalty": self.prior_penalty,
            "log_posterior": self.log_posterior,
            "n_evaluations": self.n_evaluations,
            "correction_full_minus_reduced": self.correction,
        }


def _stepping_targets(targets: Sequence[SummaryTarget]) -> list[SummaryTarget]:
    return [t for t in targets if t.unit != "V/s"]


def fit_rig(
    targets: Sequence[SummaryTarget],
    hypothesis: Hypothesis,
    effects: Mapping[str, Mapping[str, float]],
    *,
    drive_amplifier: Any = None,
    fidelity: str = "corrected",
    max_nfev: int = 40,
    start: Mapping[str, float] | None = None,
    iterations: int = 4,
) -> RigFit:
    """The MAP fit of ``hypothesis`` to the stepping figures of ``targets`` (module
    docstring), the amplifier ``effects`` fixed (as the amplifier figures fitted them).

    ``fidelity``: ``"full"`` fits on the 3-D model; ``"reduced"`` on the per-axis model;
    ``"corrected"`` (default) on the per-axis model plus a per-figure correction, the 3-D
    model's prediction minus the reduced one's at the current optimum, refitted until the
    correction moves by less than 0.1 σ (at most ``iterations`` times). The predictions
    reported are the 3-D model's (except for ``"reduced"``)."""
    tl = _stepping_targets(targets)
    kw = {"rig": hypothesis.rig(), "drive_amplifier": drive_amplifier}
    fit_on = SummaryProblem(tl, fidelity="full" if fidelity == "full" else "reduced", **kw)
    full = SummaryProblem(tl, fidelity="full", **kw) if fidelity == "corrected" else None
    sigma = np.array([math.hypot(t.resolution, MODEL_ERROR * t.reference) for t in tl])
    measured = np.array([t.value for t in tl])
    names = FIT_PARAMETERS
    lo = np.array([_to_z(n, PRIORS[n][0]) for n in names])
    hi = np.array([_to_z(n, PRIORS[n][1]) for n in names])
    z = np.zeros(len(names)) if start is None else np.array([_to_z(n, start[n]) for n in names])
    z = np.clip(z, lo + 1e-9, hi - 1e-9)
    evals = [0]
    correction = np.zeros(len(tl))

    def values(zz: np.ndarray) -> dict[str, float]:
        return {n: _to_value(n, float(v)) for n, v in zip(names, zz, strict=True)}

    def fun(zz: np.ndarray) -> np.ndarray:
        evals[0] += 1
        pred = fit_on.predict(values(zz), dict(effects)) + correction
        return np.concatenate([(pred - measured) / sigma, zz])

    def local(z_start: np.ndarray) -> Any:
        return scipy.optimize.least_squares(
            fun, z_start, bounds=(lo, hi), diff_step=0.05, max_nfev=max_nfev, x_scale=1.0
        )

    # global stage: the stick–slip figures are piecewise smooth with local optima — a grid
    # over the parameters that move the step most (friction, preload, d31), the best
    # GLOBAL_STARTS refined locally
    starts = [z]
    if start is None:
        grid = []
        for zf, zp, zd in itertools.product(GRID, GRID, GRID):
            zz = z.copy()
            zz[[names.index("friction"), names.index("preload"), names.index("d31_factor")]] = (
                zf, zp, zd,
            )  # fmt: skip
            zz = np.clip(zz, lo + 1e-9, hi - 1e-9)
            r = fun(zz)
            grid.append((float(r @ r), tuple(zz)))
        starts = [np.array(x) for _c, x in sorted(grid)[:GLOBAL_STARTS]]
    res = min((local(zs) for zs in starts), key=lambda r: r.cost)
    z = res.x
    for _ in range(iterations - 1 if full is not None else 0):
        if full is None:
            break
        vals = values(z)
        new = full.predict(vals, dict(effects)) - fit_on.predict(vals, dict(effects))
        moved = float(np.max(np.abs(new - correction) / sigma))
        correction = new
        if moved < 0.1:
            break
        res = local(z)
        z = res.x
    jac = res.jac
    cov = np.linalg.pinv(jac.T @ jac)
    sd_z = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    corr = cov / np.outer(np.where(sd_z > 0, sd_z, 1.0), np.where(sd_z > 0, sd_z, 1.0))
    vals = values(z)
    pred = (full if full is not None else fit_on).predict(vals, dict(effects))
    err = pred - measured
    return RigFit(
        hypothesis=hypothesis,
        values=vals,
        std={n: abs(_dvalue_dz(n, float(z[i]))) * float(sd_z[i]) for i, n in enumerate(names)},
        shrinkage={n: float(sd_z[i]) for i, n in enumerate(names)},
        correlation=corr,
        errors={t.name: float(e) for t, e in zip(tl, err, strict=True)},
        sigma={t.name: float(s) for t, s in zip(tl, sigma, strict=True)},
        predicted={t.name: float(p) for t, p in zip(tl, pred, strict=True)},
        chi2=float(np.sum((err / sigma) ** 2)),
        prior_penalty=float(z @ z),
        n_evaluations=evals[0],
        correction={t.name: float(c) for t, c in zip(tl, correction, strict=True)},
        jacobian=jac[: len(tl)].copy(),
    )


@dataclass
class RigResult:
    """Every hypothesis's fit, the best one, its reading and what stays unexplained."""

    fits: list[RigFit]
    best: RigFit
    explanation: str
    unidentified: dict[str, str]
    conflicts: list[dict[str, Any]]
    wall_s: float

    @property
    def posterior(self) -> dict[str, float]:
        """Normalised posterior weight of every hypothesis (their MAP values)."""
        lp = np.array([f.log_posterior for f in self.fits])
        w = np.exp(lp - lp.max())
        w /= w.sum()
        return {f.hypothesis.label: float(x) for f, x in zip(self.fits, w, strict=True)}

    def rig(self) -> RigParams:
        """The best hypothesis's rig with its estimates."""
        v = {k: x for k, x in self.best.values.items() if k in RIG_PRIORS}
        return self.best.hypothesis.rig(**v)

    def to_json(self) -> dict[str, Any]:
        return {
            "best": self.best.hypothesis.label,
            "posterior": self.posterior,
            "explanation": self.explanation,
            "unidentified": self.unidentified,
            "conflicts": self.conflicts,
            "model_error": MODEL_ERROR,
            "priors": {
                n: {"low": lo, "high": hi, "kind": k, "centre": c, "sigma": s, "source": src}
                for n, (lo, hi, k, c, s, src) in PRIORS.items()
            },
            "fits": [f.to_json() for f in self.fits],
            "wall_s": self.wall_s,
        }


def _unidentified(fit: RigFit) -> dict[str, str]:
    """Parameters the figures leave near their prior (posterior/prior std > 0.7) or tie to
    another (|correlation| > 0.9), with the reason."""
    out = {}
    n_par = len(FIT_PARAMETERS)
    for i, n in enumerate(FIT_PARAMETERS):
        j = max((k for k in range(n_par) if k != i), key=lambda k: abs(fit.correlation[i, k]))
        reasons = []
        if fit.shrinkage[n] > 0.7:
            reasons.append(f"posterior/prior std {fit.shrinkage[n]:.2f}")
        if abs(fit.correlation[i, j]) > 0.9:
            reasons.append(f"correlation {fit.correlation[i, j]:+.2f} with {FIT_PARAMETERS[j]}")
        if reasons:
            out[n] = "; ".join(reasons)
    return out


def _conflicts(fit: RigFit, limit: float, references: Mapping[str, float]) -> list[dict]:
    """Pairs of figures the model cannot fit together (local, from the Jacobian): a figure
    off by more than ``limit`` of its reference and another whose residual has the other
    sign while the parameters move both the same way (cosine of their gradients > 0.8)."""
    names = list(fit.errors)
    rel = {n: fit.errors[n] / references[n] for n in names}
    out = []
    for a, b in itertools.combinations(range(len(names)), 2):
        na, nb = names[a], names[b]
        if max(abs(rel[na]), abs(rel[nb])) <= limit or rel[na] * rel[nb] >= 0.0:
            continue
        ga, gb = fit.jacobian[a], fit.jacobian[b]
        denom = float(np.linalg.norm(ga) * np.linalg.norm(gb))
        if denom == 0.0:
            continue
        cos = float(ga @ gb) / denom
        if cos < 0.8:
            continue
        j = int(np.argmax(np.abs(ga) + np.abs(gb)))
        out.append(
            {
                "figures": [na, nb],
                "errors_after": [rel[na], rel[nb]],
                "gradient_cosine": cos,
                "dominant_parameter": FIT_PARAMETERS[j],
                "reading": f"every parameter moves {na} and {nb} the same way (cosine "
                f"{cos:.2f}; most: {FIT_PARAMETERS[j]}), while the measurements ask for "
                f"opposite changes ({rel[na]:+.0%} vs {rel[nb]:+.0%}): within this model "
                "class one cannot be fixed without the other moving away",
            }
        )
    return out


def _explanation(best: RigFit, fits: Sequence[RigFit], posterior: Mapping[str, float]) -> str:
    h = best.hypothesis
    v = best.values
    parts = [
        f"most plausible: {h.label} (posterior {posterior[h.label]:.0%} among the hypotheses)",
        f"d31 x {v['d31_factor']:.2f} ± {best.std['d31_factor']:.2f} (prior 1.1 ± 0.1)",
        f"friction x {v['friction']:.2f}, preload x {v['preload']:.2f}, contact presliding "
        f"x {v['presliding_factor']:.2f} of Mindlin's",
    ]
    rivals = [f for f in fits if f.hypothesis.drive_mode != h.drive_mode]
    if rivals:
        r = max(rivals, key=lambda f: f.log_posterior)
        worst = max(r.errors, key=lambda n: abs(r.errors[n] / r.sigma[n]))
        parts.append(
            f"the best {r.hypothesis.drive_mode} alternative ({r.hypothesis.label}) needs "
            f"d31 x {r.values['d31_factor']:.2f} and still misses {worst} by "
            f"{abs(r.errors[worst] / r.sigma[worst]):.1f} σ"
        )
    return "; ".join(parts)


def calibrate_rig(
    targets: Sequence[SummaryTarget],
    effects: Mapping[str, Mapping[str, float]],
    *,
    drive_amplifier: Any = None,
    fidelity: str = "corrected",
    candidates: Sequence[Hypothesis] | None = None,
    max_nfev: int = 40,
    progress: Callable[[str], None] | None = print,
) -> RigResult:
    """Fit every hypothesis (:func:`fit_rig`), pick the most plausible, flag what the
    figures do not identify and which figures conflict (module docstring)."""
    t0 = time.perf_counter()
    say = progress or (lambda _m: None)
    hyps = list(candidates) if candidates is not None else hypotheses()
    fits = []
    for h in hyps:
        say(f"  rig hypothesis {h.label}")
        f = fit_rig(targets, h, effects, drive_amplifier=drive_amplifier, fidelity=fidelity,
                    max_nfev=max_nfev)  # fmt: skip
        fits.append(f)
        say(f"    chi2 {f.chi2:.2f}, prior {f.prior_penalty:.2f}, log posterior "
            f"{f.log_posterior:.2f} ({f.n_evaluations} simulations)")  # fmt: skip
    best = max(fits, key=lambda f: f.log_posterior)
    lp = np.array([f.log_posterior for f in fits])
    w = np.exp(lp - lp.max())
    posterior = {f.hypothesis.label: float(x / w.sum()) for f, x in zip(fits, w, strict=True)}
    refs = {t.name: t.reference for t in _stepping_targets(targets)}
    return RigResult(
        fits=fits,
        best=best,
        explanation=_explanation(best, fits, posterior),
        unidentified=_unidentified(best),
        conflicts=_conflicts(best, 0.10, refs),
        wall_s=time.perf_counter() - t0,
    )
