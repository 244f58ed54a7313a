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
in the standardised coordinates, on the 3-D model (``fidelity``).

The posterior is multi-modal: the stick–slip figures are piecewise smooth in the
parameters, and some optima sit on knife edges (a contact mode tuned to the flyback, where
1 % of presliding moves the step by a third). A single optimum is therefore not a result
that survives another machine's rounding. Each hypothesis is fitted from several perturbed
starts; the optima are merged into modes (within :data:`SAME_MODE` prior σ of each other)
and each mode is scored on the 3-D model; the hypotheses — and each discrete choice, over
the hypotheses with that option — are compared by their best log posterior
(:func:`calibrate_rig`). A choice is *decided* only when it leads by :data:`DECISIVE_NATS`
even after the leader loses whichever single start helped it most (a jackknife over the
starts); otherwise it is *undecided*, and the option of larger prior probability is kept —
a rule that does not depend on which optima a machine happened to find. Starts are spent
where the decision is close: every hypothesis gets :data:`FIRST_STARTS`, those within
:data:`PRUNE_NATS` of the best get :data:`STARTS` and the 3-D model.

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
from .summary_problem import SummaryProblem
from .thesis_data import SummaryTarget

__all__ = [
    "MODEL_ERROR",
    "PRIORS",
    "Hypothesis",
    "RigFit",
    "RigResult",
    "calibrate_rig",
    "describe_decision",
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
STARTS = 5  # best grid points, perturbed, refined by least squares
FIRST_STARTS = 2  # starts every hypothesis gets before the close ones get the rest
PRUNE_NATS = 6.0  # a hypothesis this far behind after its first starts is not refined
START_JITTER = 0.5  # σ of a start's perturbation in every standardised coordinate
DECISIVE_NATS = 3.0  # a choice must lead by this much (Kass & Raftery's "strong": ln B > 3)
SAME_MODE = 0.25  # optima this close in every standardised coordinate are one mode
POLISHED_MODES = 2  # a refined hypothesis's best modes moved onto the 3-D optimum
FINAL_POLISHED = 4  # the kept hypothesis's best modes moved onto it before reporting


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

    def key(self) -> tuple[int, int, int]:
        """Integers naming the hypothesis (its random stream's key)."""
        return (
            int(self.drive_mode == "symmetric"),
            int(self.axial_strain_sign > 0),
            round(1000 * self.mirror_tilt),
        )

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
        figures); modes: every distinct optimum the starts reached (values, log
        posterior, the model it was scored on, the starts), best first; starts_agree: how many
        starts reached the best; n_starts; best_low: the best log posterior left when the
        start that helped most is left out (the jackknife); refined: whether it had all
        its starts and the 3-D model (else it was left behind by more than
        :data:`PRUNE_NATS` after the first starts);
        correlation: (p, p) matrix over ``FIT_PARAMETERS``; errors: target →
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
    modes: list[dict[str, Any]] = field(default_factory=list)
    starts_agree: int = 1
    n_starts: int = 1
    best_low: float = math.nan
    refined: bool = True
    axis_log_posterior: float = math.nan
    axis_best_low: float = math.nan
    raw_modes: list[Any] = field(repr=False, default_factory=list)
    exploration: Any = field(repr=False, default=None)

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
            "modes": self.modes,
            "starts_agree": self.starts_agree,
            "starts": self.n_starts,
            "log_posterior_jackknife_low": self.best_low,
            "per_axis_log_posterior": self.axis_log_posterior,
            "per_axis_log_posterior_jackknife_low": self.axis_best_low,
            "refined": self.refined,
        }


def _stepping_targets(targets: Sequence[SummaryTarget]) -> list[SummaryTarget]:
    return [t for t in targets if t.unit != "V/s"]


@dataclass
class _Mode:
    """One local optimum in standardised coordinates: ``z``, ``cost`` = ½Σr² on the model
    it was fitted on (the negative log posterior up to a constant), the Jacobian there, the
    starts that reached it, and — once evaluated — the 3-D model's cost and prediction."""

    z: np.ndarray
    cost: float
    jac: np.ndarray
    starts: list[int]
    full_cost: float | None = None
    full_pred: np.ndarray | None = None
    correction: np.ndarray | None = None

    @property
    def score(self) -> float:
        """The log posterior up to the constant every mode shares: on the 3-D model where
        the mode was evaluated there."""
        return -(self.full_cost if self.full_cost is not None else self.cost)

    def same(self, z: np.ndarray) -> bool:
        """Whether ``z`` lies within :data:`SAME_MODE` prior σ of this mode in every
        parameter."""
        return bool(np.max(np.abs(z - self.z)) <= SAME_MODE)


class _Objective:
    """The MAP objective of one hypothesis (module docstring) with its per-figure
    3-D-minus-reduced ``correction``."""

    def __init__(self, targets, hypothesis, effects, drive_amplifier, fidelity):
        self.tl = _stepping_targets(targets)
        self.hypothesis = hypothesis
        self.effects = {k: dict(v) for k, v in effects.items()}
        kw = {"rig": hypothesis.rig(), "drive_amplifier": drive_amplifier}
        self.fidelity = fidelity
        self.fit_on = SummaryProblem(
            self.tl, fidelity="full" if fidelity == "full" else "reduced", **kw
        )
        self.full = SummaryProblem(self.tl, fidelity="full", **kw) if fidelity == "corrected" \
            else None  # fmt: skip
        self.sigma = np.array(
            [math.hypot(t.resolution, MODEL_ERROR * t.reference) for t in self.tl]
        )
        self.measured = np.array([t.value for t in self.tl])
        self.lo = np.array([_to_z(n, PRIORS[n][0]) for n in FIT_PARAMETERS])
        self.hi = np.array([_to_z(n, PRIORS[n][1]) for n in FIT_PARAMETERS])
        self.correction = np.zeros(len(self.tl))
        self.evals = 0

    def values(self, z: np.ndarray) -> dict[str, float]:
        return {n: _to_value(n, float(v)) for n, v in zip(FIT_PARAMETERS, z, strict=True)}

    def clip(self, z: np.ndarray) -> np.ndarray:
        return np.clip(z, self.lo + 1e-9, self.hi - 1e-9)

    def residual(self, z: np.ndarray) -> np.ndarray:
        self.evals += 1
        pred = self.fit_on.predict(self.values(z), self.effects) + self.correction
        return np.concatenate([(pred - self.measured) / self.sigma, z])

    def local(self, z0: np.ndarray, max_nfev: int, start: int) -> _Mode:
        res = scipy.optimize.least_squares(
            self.residual, self.clip(z0), bounds=(self.lo, self.hi), diff_step=0.05,
            max_nfev=max_nfev, x_scale=1.0,
        )  # fmt: skip
        return _Mode(res.x, float(res.cost), res.jac, [start])

    def starts(self, n: int, seed: int) -> list[np.ndarray]:
        """The ``n`` best points of the grid over friction, preload and d₃₁, each moved by
        a normal draw of σ :data:`START_JITTER` in every coordinate (``seed``)."""
        grid = []
        idx = [FIT_PARAMETERS.index(k) for k in ("friction", "preload", "d31_factor")]
        for point in itertools.product(GRID, GRID, GRID):
            zz = np.zeros(len(FIT_PARAMETERS))
            zz[idx] = point
            zz = self.clip(zz)
            r = self.residual(zz)
            grid.append((float(r @ r), tuple(zz)))
        rng = np.random.default_rng([seed, *self.hypothesis.key()])
        return [
            self.clip(np.array(x) + rng.normal(0.0, START_JITTER, len(FIT_PARAMETERS)))
            for _c, x in sorted(grid)[:n]
        ]

    def evaluate_full(self, mode: _Mode) -> None:
        """The 3-D model's prediction and cost at the mode (one 3-D run)."""
        assert self.full is not None
        pred = self.full.predict(self.values(mode.z), self.effects)
        r = np.concatenate([(pred - self.measured) / self.sigma, mode.z])
        mode.full_pred, mode.full_cost = pred, 0.5 * float(r @ r)


def _merge(modes: list[_Mode], new: _Mode) -> None:
    """Add a local optimum to the modes: into the mode it lies within one σ of (keeping the
    lower cost), or as a new one."""
    for m in modes:
        if m.same(new.z) or new.same(m.z):
            m.starts += new.starts
            if new.cost < m.cost:
                m.z, m.cost, m.jac = new.z, new.cost, new.jac
            return
    modes.append(new)


@dataclass
class _Exploration:
    """A hypothesis after its first starts: the starts, the modes, simulations run."""

    hypothesis: Hypothesis
    start_points: list[np.ndarray]
    modes: list[_Mode]
    evals: int
    shared: int = 0  # starts taken from another hypothesis's optimum (labelled after own)

    def best(self, without: int | None = None) -> float:
        """The best mode's log posterior + ln prior; ``without``: leaving that start out (a
        mode only it reached drops)."""
        scores = [m.score for m in self.modes if without is None or set(m.starts) - {without}]
        return max(scores, default=-math.inf) + math.log(self.hypothesis.prior)


def _explore(job: tuple) -> _Exploration:
    """Phase 1 of a hypothesis (a :func:`~turntable_env.scale.map_tasks` job): the grid,
    the perturbed starts, local fits from the first ``first`` of them."""
    targets, h, effects, kw = job
    obj = _Objective(targets, h, effects, kw["drive_amplifier"], kw["fidelity"])
    points = obj.starts(kw["starts"], kw["seed"])
    modes: list[_Mode] = []
    for k, z0 in enumerate(points[: kw["first"]]):
        _merge(modes, obj.local(z0, kw["max_nfev"], k))
    return _Exploration(h, points, modes, obj.evals)


def _best_mode(modes: Sequence[_Mode]) -> _Mode:
    """The best-scoring mode; equal scores (to 1e-9) go to the earliest start."""
    return max(modes, key=lambda m: (round(m.score, 9), -min(m.starts)))


def _cross(job: tuple) -> _Exploration:
    """A hypothesis refitted from another one's best optimum (a
    :func:`~turntable_env.scale.map_tasks` job): the hypotheses of one drive mode differ
    only in the mirror's factor or the axial strain's sign, and a region one search found
    is a start the others need not find by luck."""
    targets, expl, effects, kw, z0 = job
    obj = _Objective(targets, expl.hypothesis, effects, kw["drive_amplifier"], kw["fidelity"])
    obj.evals = expl.evals
    modes = [_Mode(m.z.copy(), m.cost, m.jac, list(m.starts)) for m in expl.modes]
    _merge(modes, obj.local(z0, kw["max_nfev"], len(expl.start_points) + expl.shared))
    return _Exploration(expl.hypothesis, expl.start_points, modes, obj.evals, expl.shared + 1)


def _refine(job: tuple) -> RigFit:
    """Phase 2 of a hypothesis: local fits from the remaining starts, every mode scored on
    the 3-D model, and the best :data:`POLISHED_MODES` moved onto the 3-D optimum near them
    (:func:`_polish`); or, with ``refine`` False, the modes of phase 1 scored on the 3-D
    model as they stand (a hypothesis left behind)."""
    targets, expl, effects, kw = job
    obj = _Objective(targets, expl.hypothesis, effects, kw["drive_amplifier"], kw["fidelity"])
    obj.evals = expl.evals
    modes = [_Mode(m.z.copy(), m.cost, m.jac, list(m.starts)) for m in expl.modes]
    if kw["refine"]:
        for k in range(kw["first"], len(expl.start_points)):
            _merge(modes, obj.local(expl.start_points[k], kw["max_nfev"], k))
    if obj.full is not None:
        for m in modes:
            obj.evaluate_full(m)
        if kw["refine"]:
            for m in sorted(modes, key=lambda m: (-round(m.score, 9), min(m.starts)))[
                :POLISHED_MODES
            ]:
                _polish(obj, m, kw)
    return _rig_fit(obj, expl, modes, _best_mode(modes), kw)


def _finalise(job: tuple) -> RigFit:
    """The kept hypothesis with its best :data:`FINAL_POLISHED` modes (by the 3-D score)
    moved onto the 3-D optimum (those not polished yet), the best of them reported."""
    targets, fit, effects, kw = job
    obj = _Objective(targets, fit.hypothesis, effects, kw["drive_amplifier"], kw["fidelity"])
    obj.evals = fit.n_evaluations
    modes = fit.raw_modes
    if obj.full is not None:
        for m in sorted(modes, key=lambda m: (-round(m.score, 9), min(m.starts)))[
            :FINAL_POLISHED
        ]:
            if m.correction is None and m.full_cost is not None:
                _polish(obj, m, kw)
    return _rig_fit(obj, fit.exploration, modes, _best_mode(modes), kw)


def _polish(obj: _Objective, mode: _Mode, kw: Mapping[str, Any]) -> None:
    """Move a mode onto the 3-D model's optimum near it: the per-axis fit plus the
    3-D-minus-per-axis correction at the mode, refitted until the correction moves by less
    than 0.1 σ (at most ``iterations`` − 1 times), each step kept only while the 3-D
    model's cost falls."""
    assert mode.full_cost is not None and mode.full_pred is not None
    obj.correction = np.zeros(len(obj.tl))
    for _ in range(kw["iterations"] - 1):
        new = mode.full_pred - obj.fit_on.predict(obj.values(mode.z), obj.effects)
        moved = float(np.max(np.abs(new - obj.correction) / obj.sigma))
        obj.correction = new
        if moved < 0.1:
            break
        step = obj.local(mode.z, kw["max_nfev"], min(mode.starts))
        obj.evaluate_full(step)
        if step.full_cost >= mode.full_cost:  # type: ignore[operator]
            break
        mode.z, mode.cost, mode.jac = step.z, step.cost, step.jac
        mode.full_cost, mode.full_pred = step.full_cost, step.full_pred
    mode.correction = obj.correction.copy()
    obj.correction = np.zeros(len(obj.tl))


def _rig_fit(obj: _Objective, expl: _Exploration, modes: list[_Mode], best: _Mode,
             kw: Mapping[str, Any]) -> RigFit:  # fmt: skip
    """The :class:`RigFit` of a hypothesis's modes, reported at the best."""
    z = best.z
    cov = np.linalg.pinv(best.jac.T @ best.jac)
    sd_z = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    corr = cov / np.outer(np.where(sd_z > 0, sd_z, 1.0), np.where(sd_z > 0, sd_z, 1.0))
    vals = obj.values(z)
    refined = bool(kw["refine"])
    pred = best.full_pred if best.full_pred is not None else obj.fit_on.predict(vals, obj.effects)
    err = pred - obj.measured
    n_starts = (len(expl.start_points) if refined else min(kw["first"], len(expl.start_points))
                ) + expl.shared  # fmt: skip
    mode_rows = sorted(
        (
            {
                "values": obj.values(m.z),
                "log_posterior": m.score + math.log(obj.hypothesis.prior),
                "on": "3-D" if m.full_cost is not None else "per-axis",
                "starts": sorted(m.starts),
            }
            for m in modes
        ),
        key=lambda r: -r["log_posterior"],
    )
    return RigFit(
        hypothesis=obj.hypothesis,
        values=vals,
        std={n: abs(_dvalue_dz(n, float(z[i]))) * float(sd_z[i])
             for i, n in enumerate(FIT_PARAMETERS)},
        shrinkage={n: float(sd_z[i]) for i, n in enumerate(FIT_PARAMETERS)},
        correlation=corr,
        errors={t.name: float(e) for t, e in zip(obj.tl, err, strict=True)},
        sigma={t.name: float(s) for t, s in zip(obj.tl, obj.sigma, strict=True)},
        predicted={t.name: float(p) for t, p in zip(obj.tl, pred, strict=True)},
        chi2=float(np.sum((err / obj.sigma) ** 2)),
        prior_penalty=float(z @ z),
        n_evaluations=obj.evals,
        correction={t.name: float(c) for t, c in zip(
            obj.tl, best.correction if best.correction is not None else obj.correction,
            strict=True)},
        jacobian=best.jac[: len(obj.tl)].copy(),
        modes=mode_rows,
        starts_agree=len(best.starts),
        n_starts=n_starts,
        best_low=_jackknife_low(modes, lambda m: m.score) + math.log(obj.hypothesis.prior),
        refined=refined,
        axis_log_posterior=max(-m.cost for m in modes) + math.log(obj.hypothesis.prior),
        axis_best_low=_jackknife_low(modes, lambda m: -m.cost) + math.log(obj.hypothesis.prior),
        raw_modes=modes,
        exploration=expl,
    )


def _jackknife_low(modes: Sequence[_Mode], score: Callable[[_Mode], float]) -> float:
    """The best score left when the start that helped most is left out (a mode only that
    start reached drops out)."""
    labels = {k for m in modes for k in m.starts}
    return min(
        (max((score(m) for m in modes if set(m.starts) - {k}), default=-math.inf)
         for k in labels),
        default=-math.inf,
    )  # fmt: skip


def fit_rig(
    targets: Sequence[SummaryTarget],
    hypothesis: Hypothesis,
    effects: Mapping[str, Mapping[str, float]],
    *,
    drive_amplifier: Any = None,
    fidelity: str = "corrected",
    max_nfev: int = 40,
    iterations: int = 4,
    starts: int = STARTS,
    seed: int = 0,
) -> RigFit:
    """The fit of ``hypothesis`` to the stepping figures of ``targets`` (module
    docstring) from ``starts`` perturbed starts (``seed``), the amplifier ``effects`` fixed
    (as the amplifier figures fitted them).

    ``fidelity``: ``"full"`` fits on the 3-D model; ``"reduced"`` on the per-axis model;
    ``"corrected"`` (default) on the per-axis model, every mode then scored on the 3-D
    model, and the best :data:`POLISHED_MODES` moved onto the 3-D optimum by a per-figure
    correction (the 3-D model's prediction minus the reduced one's), refitted until the
    correction moves by less than 0.1 σ (at most ``iterations`` times). The predictions
    reported are the 3-D model's (except for ``"reduced"``)."""
    kw = {"drive_amplifier": drive_amplifier, "fidelity": fidelity, "max_nfev": max_nfev,
          "starts": starts, "seed": seed, "first": starts, "iterations": iterations,
          "refine": True}  # fmt: skip
    expl = _explore((targets, hypothesis, effects, kw))
    return _refine((targets, expl, effects, kw))


@dataclass
class RigResult:
    """Every hypothesis's fit, the best one, its reading and what stays unexplained."""

    fits: list[RigFit]
    best: RigFit
    explanation: str
    unidentified: dict[str, str]
    conflicts: list[dict[str, Any]]
    wall_s: float
    decision: dict[str, Any] = field(default_factory=dict)

    @property
    def posterior(self) -> dict[str, float]:
        """Normalised posterior weight of every hypothesis (their best log posterior)."""
        return _posterior(self.fits)

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
            "decision": self.decision,
            "decision_text": describe_decision(self.decision) if self.decision else "",
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


def _posterior(fits: Sequence[RigFit]) -> dict[str, float]:
    lp = np.array([f.log_posterior for f in fits])
    w = np.exp(lp - lp.max())
    w /= w.sum()
    return {f.hypothesis.label: float(x) for f, x in zip(fits, w, strict=True)}


def _explanation(best: RigFit, fits: Sequence[RigFit], posterior: Mapping[str, float]) -> str:
    h = best.hypothesis
    v = best.values
    parts = [
        f"calibrated rig: {h.label} (posterior {posterior[h.label]:.0%} among the hypotheses)",
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


CHOICES = (
    ("drive_mode", lambda h: h.drive_mode),
    ("axial_strain_sign", lambda h: h.axial_strain_sign),
    ("mirror_tilt", lambda h: h.mirror_tilt),
)


def _option_label(choice: str, value: Any) -> str:
    if choice == "mirror_tilt":
        return "mirror ⟂ axis" if value > 0.99 else "horizontal mirror"
    if choice == "axial_strain_sign":
        return f"axial {value:+d}"
    return str(value)


def _margins(
    groups: Mapping[Any, list[RigFit]],
    best: Callable[[RigFit], float],
    low_of: Callable[[RigFit], float],
) -> tuple[Any, Any, float, float]:
    """(leader, runner-up, margin, margin with one start of the leader's left out) of a
    choice's options, each scored by its hypotheses' best ``best``."""
    ev = {k: max(best(f) for f in g) for k, g in groups.items()}
    leader = max(ev, key=lambda k: ev[k])
    rival = max((k for k in ev if k != leader), key=lambda k: ev[k])
    g = groups[leader]
    low = min(max(best(x) if x is not f else low_of(f) for x in g) for f in g)
    return leader, rival, ev[leader] - ev[rival], low - ev[rival]


def _choose(fits: Sequence[RigFit]) -> tuple[RigFit, list[dict[str, Any]]]:
    """The calibrated hypothesis, one discrete choice at a time (drive mode, then the axial
    sign, then the mirror), each over the hypotheses the earlier ones left: the option
    whose best log posterior leads by :data:`DECISIVE_NATS` even at its jackknife low, on
    the 3-D model the modes were scored on and on the per-axis model they were searched
    with alike, is *decided*; otherwise the choice is *undecided* and the option of larger
    prior probability is kept — a rule that does not depend on which optima a machine
    found, nor on how one model's optimum lands on the other."""
    left = list(fits)
    out = []
    for name, key in CHOICES:
        groups: dict[Any, list[RigFit]] = {}
        for f in left:
            groups.setdefault(key(f.hypothesis), []).append(f)
        if len(groups) < 2:
            continue
        leader, rival, margin, margin_low = _margins(
            groups, lambda f: f.log_posterior, lambda f: f.best_low
        )
        a_leader, _a_rival, a_margin, a_low = _margins(
            groups, lambda f: f.axis_log_posterior, lambda f: f.axis_best_low
        )
        prior = {k: sum(f.hypothesis.prior for f in g) for k, g in groups.items()}
        decided = (margin_low > DECISIVE_NATS and a_low > DECISIVE_NATS
                   and a_leader == leader)  # fmt: skip
        kept = leader if decided else max(prior, key=lambda k: prior[k])
        out.append(
            {
                "choice": name,
                "decision": "decided" if decided else "undecided",
                "leader": _option_label(name, leader),
                "runner_up": _option_label(name, rival),
                "margin_nats": margin,
                "margin_nats_jackknife_low": margin_low,
                "per_axis_leader": _option_label(name, a_leader),
                "per_axis_margin_nats": a_margin,
                "per_axis_margin_nats_jackknife_low": a_low,
                "needed_nats": DECISIVE_NATS,
                "kept": _option_label(name, kept),
                "kept_value": kept,
                "prior": {_option_label(name, k): v for k, v in prior.items()},
            }
        )
        left = groups[kept]
    return max(left, key=lambda f: f.log_posterior), out


def describe_decision(d: Mapping[str, Any]) -> str:
    """One line per discrete choice: decided or undecided, with its margin."""
    parts = []
    for c in d.get("choices", []):
        s = (
            f"{c['choice']} {c['decision']}: {c['leader']} leads {c['runner_up']} by "
            f"{c['margin_nats']:.2f} nats of log posterior on the 3-D model "
            f"({c['margin_nats_jackknife_low']:.2f} with the most helpful start left out), "
            f"{c['per_axis_margin_nats']:.2f} ({c['per_axis_margin_nats_jackknife_low']:.2f}) "
            f"on the per-axis model led by {c['per_axis_leader']}; needs {c['needed_nats']:g} "
            "on both"
        )
        if c["decision"] == "undecided":
            s += f", the prior's {c['kept']} kept"
        parts.append(s)
    parts.append(f"{d['starts_agree']}/{d['starts']} starts reach the kept fit's mode")
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
    starts: int = STARTS,
    seed: int = 0,
    workers: int = 1,
) -> RigResult:
    """Fit every hypothesis from perturbed starts (``starts``; ``seed`` picks the
    perturbations; module docstring), score them by their best log posterior, decide each
    choice with its margin, flag what the figures do not identify and which figures
    conflict. ``workers`` > 1 fits the hypotheses in that many processes
    (:func:`~turntable_env.scale.map_tasks`; the same results as one)."""
    from ..scale import map_tasks

    t0 = time.perf_counter()
    say = progress or (lambda _m: None)
    hyps = list(candidates) if candidates is not None else hypotheses()
    if isinstance(starts, bool) or not isinstance(starts, int) or starts < 1:
        raise ValueError(f"starts={starts!r}: must be an integer >= 1")
    kw = {"drive_amplifier": drive_amplifier, "fidelity": fidelity, "max_nfev": max_nfev,
          "starts": starts, "seed": seed, "first": min(FIRST_STARTS, starts), "iterations": 4,
          "refine": True}  # fmt: skip
    eff = {k: dict(v) for k, v in effects.items()}

    def run(fn: Callable[[tuple], Any], jobs: list[tuple]) -> list[Any]:
        if workers > 1 and len(jobs) > 1:
            return map_tasks(fn, jobs, backend="processes", workers=workers)
        return [fn(j) for j in jobs]

    say(f"  {len(hyps)} rig hypotheses, {kw['first']} starts each"
        + (f", {workers} processes" if workers > 1 else ""))  # fmt: skip
    expl = run(_explore, [(list(targets), h, eff, kw) for h in hyps])
    # each hypothesis also starts from the best optimum its drive mode's other hypotheses
    # found (they differ in the mirror's factor or the axial sign alone), before any pruning
    sibling = []
    for i, e in enumerate(expl):
        others = [x for j, x in enumerate(expl)
                  if j != i and x.hypothesis.drive_mode == e.hypothesis.drive_mode]  # fmt: skip
        sibling.append(max(others, key=lambda x: x.best()) if others else None)
    crossed = run(_cross, [(list(targets), e, eff, kw, _best_mode(o.modes).z)
                           for e, o in zip(expl, sibling, strict=True)
                           if o is not None])  # fmt: skip
    it = iter(crossed)
    expl = [next(it) if o is not None else e for e, o in zip(expl, sibling, strict=True)]
    top = max(e.best() for e in expl)
    close = [e.best() >= top - PRUNE_NATS for e in expl]
    for e, c in zip(expl, close, strict=True):
        say(f"    {e.hypothesis.label}: log posterior {e.best():.2f} after {kw['first']} "
            f"starts and {e.shared} shared" + ("" if c else
            f" — more than {PRUNE_NATS:g} nats behind, not refined"))  # fmt: skip
    say(f"  refining {sum(close)} hypotheses: {starts} starts each and the 3-D model")
    jobs = [(list(targets), e, eff, {**kw, "refine": c}) for e, c in zip(expl, close, strict=True)]
    fits = run(_refine, jobs)
    for f in fits:
        if f.refined:
            say(f"    {f.hypothesis.label}: log posterior {f.log_posterior:.2f} ({len(f.modes)} "
                f"modes; {f.starts_agree}/{f.n_starts} starts reach the best; chi2 {f.chi2:.2f}; "
                f"{f.n_evaluations} simulations)")  # fmt: skip
    best, choices = _choose(fits)
    if best.refined:
        say(f"  {best.hypothesis.label}: {FINAL_POLISHED} best modes onto the 3-D optimum")
        kept = _finalise((list(targets), best, eff, kw))
        fits = [kept if f is best else f for f in fits]
        best = kept
    posterior = _posterior(fits)
    refs = {t.name: t.reference for t in _stepping_targets(targets)}
    decision = {
        "choices": choices,
        "kept": best.hypothesis.label,
        "starts_agree": best.starts_agree,
        "starts": best.n_starts,
    }
    say(f"  {describe_decision(decision)}")
    return RigResult(
        fits=fits,
        best=best,
        explanation=_explanation(best, fits, posterior),
        unidentified=_unidentified(best),
        conflicts=_conflicts(best, 0.10, refs),
        wall_s=time.perf_counter() - t0,
        decision=decision,
    )
