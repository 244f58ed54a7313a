"""Effect identification by signature: which catalogue effect explains what the fitted
nominal model leaves, judged on the protocol features it must change (:mod:`.signatures`).

For every candidate effect, on top of the current model (the fitted nominal model and the
effects already named):

1. **Start values from the data**: the line's amplitude and phase (vibration), the y/x
   slope (misalignment), the relaxation's rate (drift); the middle of the range else.
2. **A profile** of its main parameter over its whole range (its neutral value and
   1 %…100 % of the way to each end, :func:`_profile_grid`), the objective being the
   features' misfit Σ_g RSS_g / w_g (whitened by the detector noise, each group weighted
   by the current model's misfit per feature, so no group dominates by its count; the
   direction pairs by the noise plus the current model's common misfit variance, so the
   settings weigh alike, as in :func:`~.signatures.group_scores`).
3. **A bounded Powell search** (:func:`scipy.optimize.minimize`) over all its parameters
   from the profile's best point, in range-normalised coordinates. An effect that moves a
   level the nominal fit set to the trace's average (:data:`CONFOUNDED_NOMINAL`: wear and
   the friction level) is searched with that level free, and scored against the current
   model with the level refitted to the features alone, so the two differ by the effect.
4. **Scores**: :func:`~.signatures.group_scores` against the current model per feature
   group, in nats. A candidate is *significant* when it gains ≥ :func:`significance_nats`
   of its number of free parameters (4.5 for one, 5.91 for two: the same 3σ level)
   in the groups it declares (:data:`~.signatures.EFFECT_GROUPS`) — also with any one
   feature of a declared group of ``JACKKNIFE_GROUPS`` left out (one quantity repeated
   over the settings, the direction pairs: a gain that rests on one pair is that
   setting's misfit, which a model of another structure leaves somewhere, not a
   friction effect's signature) — and over all the
   signature groups (:data:`~.signatures.SIGNATURE_GROUPS`: not the step sizes and scan
   gains the nominal model is fitted to, which a refit restores); the profile and the
   search minimise the misfit of those groups alone (what a candidate does to the other
   groups is reported, and the joint refit on the trace settles the nominal model),
   and it changes the predicted trace by at least the noise floor (RMS; an effect too
   small to see in the trace is not a finding, whatever its features say). A main
   parameter at a bound of its range is noted, not disqualifying. A candidate whose
   profile is best at its neutral value is reported so (``at_neutral``), never silently
   equal to the nominal model.

:func:`decide` names the significant candidate with the largest gain over the signature
groups (an effect explains what it must and what follows from it: creep relaxes the holds
and opens the scan's loop, hysteresis only the loop) when it leads
the runner-up by ``TIE_NATS``; otherwise the round is undecided between them and nothing
is named (a selection that flips with the start or the rounding is not a result).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats

from ..effects import CATALOGUE, WEAR_RUN_IN_START
from .signatures import (
    EFFECT_GROUPS,
    GROUPS,
    REPEATED_GROUPS,
    REPEATED_MIN,
    SIGNATURE_GROUPS,
    STEP_SCALE_MIN,
    Features,
    SignatureLayout,
    coverage,
    group_scores,
    misfit_variance,
    step_misfit_sd,
)

__all__ = [
    "CONFOUNDED_NOMINAL",
    "JACKKNIFE_GROUPS",
    "JACKKNIFE_MIN",
    "LEVEL_SPAN",
    "LINE_P_VALUE",
    "P_SIGNIFICANT",
    "SIGNIFICANT_NATS",
    "SUPPORT_NATS",
    "TIE_NATS",
    "CandidateFit",
    "Decision",
    "SignatureSearch",
    "decide",
    "declared_gain",
    "free_parameters",
    "leave_one_out",
    "main_at_bound",
    "significance_nats",
    "supports",
]

P_SIGNIFICANT = 2.0 * float(scipy.stats.norm.sf(3.0))  # two-sided 3σ: 0.0027


def significance_nats(k: int, m: int = 1) -> float:
    """The gain [nats] a candidate that moves k parameters needs on its groups and over
    all: half the χ²_k quantile at 1 − :data:`P_SIGNIFICANT` (Wilks: the gain's χ² =
    2·nats has k degrees of freedom when the candidate adds nothing,
    :func:`~.signatures.group_scores`). 4.5 for one parameter (3², the 3σ of one normal
    deviate), −ln P = 5.91 for two; until stop 64 every candidate was held to 4.5, a
    false-alarm rate of e^−4.5 = 1.1 % for a two-parameter one (hysteresis, vibration, the
    amplifier's fast path) instead of 0.27 %. ``m`` > 1: the level at P/m, Bonferroni's
    over m candidates (reported by ``experiments/table_reports.py``, not applied)."""
    for name, v in (("k", k), ("m", m)):
        if not (isinstance(v, int | np.integer) and v >= 1):
            raise ValueError(f"{name}={v!r}: must be an integer ≥ 1")
    return 0.5 * float(scipy.stats.chi2.isf(P_SIGNIFICANT / m, int(k)))


SIGNIFICANT_NATS = significance_nats(1)  # 4.5: χ² of 9, 3σ for one parameter
TIE_NATS = 2.0  # a lead under this over the runner-up is a tie (likelihood ratio e² ≈ 7)
# the least a signature must favour an effect the held-out trace error names (with any one
# direction pair left out): the likelihood ratio of a tie's margin, e² ≈ 7, not significance
SUPPORT_NATS = TIE_NATS
LINE_P_VALUE = 1e-3  # false-alarm probability of a spectral line over the whole search
POWELL_EVALS = 40  # objective evaluations of the bounded search per candidate
JACKKNIFE_MIN = REPEATED_MIN  # features a group needs for its leave-one-out check
# groups whose features repeat one quantity over the protocol's settings, so an effect's
# signature must show in more than one of them: the direction pairs (a friction level
# changes every setting's ratio). Not the scan shapes (a detector's cubic shows in the
# widest scan), the holds (creep follows the move before each) or the steps (an amplifier
# effect shows in the fastest bursts).
JACKKNIFE_GROUPS = REPEATED_GROUPS
# nominal levels an effect is searched with (its signature here, its screen on the trace,
# :mod:`.trace_fit`): wear moves the friction from the level the nominal fit set to the
# trace's average, so with that level held a true wear only adds to it (the third plant's
# contact wear gains 1.0 nats on its features here, the nominal model held but for the
# level, and 5.7 on the two refits the trace compares, trace_fit._refit_backing)
CONFOUNDED_NOMINAL: dict[str, tuple[str, ...]] = {"friction_wear": ("friction",)}
LEVEL_SPAN = 0.5  # the most a searched level moves, in its ln-factor (×0.61 … ×1.65)
LEVEL_EVALS = 12  # objective evaluations refitting the levels at each profile point
# the parameter profiled (else an effect's first)
MAIN_PARAMETER = {"sensor_drift": "rate", "vibration": "amplitude"}
# held at their start: the line's frequency (found by the line search), the drift's offset
# (the features are level differences)
HELD_PARAMETERS = {"vibration": ("frequency",), "sensor_drift": ("offset",)}

Effects = Mapping[str, Mapping[str, float]]


@dataclass
class CandidateFit:
    """One candidate's search: its parameter ``values``, the ``profile`` [(first
    parameter, objective)], the objective at the optimum and at neutral, whether the
    optimum is at neutral, per-group ``scores`` against the current model (nats), the
    gains on its declared groups and over all, ``significant``, a ``note`` on why not,
    and ``size``: the RMS change of the predicted trace over the noise floor."""

    name: str
    values: dict[str, float]
    profile: list[tuple[float, float]]
    objective: float
    objective_neutral: float
    at_neutral: bool
    scores: dict[str, dict[str, float]]
    declared_nats: float
    total_nats: float
    significant: bool
    note: str = ""
    size: float = 0.0  # RMS change of the predicted trace over the noise floor
    # the declared gain with the feature it rests on most left out, and that feature
    declared_nats_loo: float = math.nan
    weakest_feature: str = ""
    # the nominal levels searched with it (:data:`CONFOUNDED_NOMINAL`): name → ln-factor
    # shift from the current model's (the model it is scored against has its own)
    level_shift: dict[str, float] = field(default_factory=dict)

    @property
    def n_free(self) -> int:
        """The F-test's degrees of freedom: the effect's free parameters (its levels are
        refitted in the model it is compared with as well)."""
        return len(free_parameters(self.name))

    def to_json(self) -> dict[str, Any]:
        return {
            "effect": self.name,
            "values": self.values,
            "profile": [[float(a), float(b)] for a, b in self.profile],
            "objective": self.objective,
            "objective_neutral": self.objective_neutral,
            "at_neutral": self.at_neutral,
            "declared_groups": list(EFFECT_GROUPS.get(self.name, ())),
            "n_free": self.n_free,
            "level_shift": self.level_shift,
            "declared_nats": self.declared_nats,
            "total_nats": self.total_nats,
            "group_nats": {g: s["nats"] for g, s in self.scores.items()},
            "significant": self.significant,
            "significance_nats": significance_nats(self.n_free),
            "declared_nats_leave_one_out": self.declared_nats_loo,
            "rests_on": self.weakest_feature,
            "size_over_floor": self.size,
            "note": self.note,
        }


@dataclass
class Decision:
    """A round's outcome: the ``named`` effect (or None), its lead over the runner-up in
    nats (``margin``; inf when it is the only significant one), and the candidates it
    is ``undecided`` between when the lead is under :data:`TIE_NATS`."""

    named: str | None
    margin: float
    undecided: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"named": self.named, "margin_nats": self.margin, "undecided": self.undecided}


def decide(fits: Sequence[CandidateFit]) -> Decision:
    """The significant candidate with the largest gain over the signature groups, if it
    leads the runner-up by TIE_NATS."""
    sig = sorted((f for f in fits if f.significant), key=lambda f: -f.total_nats)
    if not sig:
        return Decision(None, 0.0)
    if len(sig) == 1:
        return Decision(sig[0].name, math.inf)
    margin = sig[0].total_nats - sig[1].total_nats
    if margin < TIE_NATS:
        tied = [f.name for f in sig if sig[0].total_nats - f.total_nats < TIE_NATS]
        return Decision(None, margin, tied)
    return Decision(sig[0].name, margin)


def supports(fit: CandidateFit) -> tuple[bool, str]:
    """Whether an effect's own signature backs it where the held-out trace error would name
    it: (backed, why not). An effect whose declared groups are all the nominal model's
    (:data:`~.signatures.NOMINAL_GROUPS`: the amplifier's, whose signature is the step
    sizes a refit restores) has no signature to ask and is judged by the trace alone.
    Any other must gain at least :data:`SUPPORT_NATS` on its declared groups, also with
    the direction pair its gain rests on most left out, away from its neutral value: an
    improvement of the trace's prediction that its signature does not show is a misfit
    of another structure that the effect's parameters happen to bend (the independent
    plants' clean sampled drives, where friction wear's signature gain rested on one
    pair, 2.9 nats and −0.7 without it), not that effect — unless it explains most of
    the trace's structure, which the calibration checks (features can miss an effect
    the trace shows plainly)."""
    if not any(g in SIGNATURE_GROUPS for g in EFFECT_GROUPS.get(fit.name, ())):
        return True, ""
    if fit.at_neutral:
        return False, f"its signature is best at neutral ({fit.note or 'no gain'})"
    gain = min(fit.declared_nats, fit.declared_nats_loo)
    if not gain >= SUPPORT_NATS:  # nan (not searched) is no support either
        loo = f", {fit.declared_nats_loo:.1f} without {fit.weakest_feature}" if (
            fit.weakest_feature) else ""  # fmt: skip
        return False, (f"its signature gains {fit.declared_nats:.1f} nats{loo}, under "
                       f"{SUPPORT_NATS:.1f}")  # fmt: skip
    return True, ""


def free_parameters(name: str) -> list[Any]:
    """The parameters of an effect its signature search moves (their number is the
    F-test's degrees of freedom, :func:`~.signatures.group_scores`)."""
    held = HELD_PARAMETERS.get(name, ())
    return [p for p in CATALOGUE[name].parameters if p.high > p.low and p.name not in held]


def main_at_bound(name: str, values: Mapping[str, float], parameter: str | None = None) -> str:
    """``name.parameter = value`` when an effect's main parameter (``parameter``, default
    its first) sits at a bound of its range (within 0.1 % of the range) away from
    neutral, else "". After a
    joint refit with the nominal model, an effect that still asks for more than its range
    stands in for a structure it cannot be (a true one of the catalogue's size ends
    inside)."""
    ps = CATALOGUE[name].parameters
    p = next(q for q in ps if q.name == parameter) if parameter else ps[0]
    v = float(values[p.name])
    tol = 1e-3 * (p.high - p.low)
    if abs(v - p.neutral) > tol and min(v - p.low, p.high - v) < tol:
        return f"{name}.{p.name} = {v:.4g}"
    return ""


class SignatureSearch:
    """Features of the data and of models on a set of traces.

    Args:
        signals: (x, effects) → per trace the model's detector channels (x, y) [V].
        traces: per trace (time [s], drive [V], segments, detector x [V], detector y [V]
            or None, nm per volt, noise floor [nm], table radius [m]).
        nominal_names: the names of x's ln-factors (the levels of
            :data:`CONFOUNDED_NOMINAL` are searched where x has them).
    """

    def __init__(
        self,
        signals: Callable[[np.ndarray, Effects], list[tuple[np.ndarray, np.ndarray]]],
        traces: Sequence[tuple[Any, ...]],
        nominal_names: Sequence[str] = (),
    ) -> None:
        self._signals = signals
        self.traces = list(traces)
        self.nominal_names = tuple(nominal_names)
        self.layouts = [
            SignatureLayout(t - t[0], u, segs, floor)
            for t, u, segs, _x, _y, _s, floor, _r in self.traces
        ]
        self.data = self._concat(
            [
                lay.measure(x * s, None if y is None else y * s)
                for lay, (_t, _u, _g, x, y, s, _f, _r) in zip(
                    self.layouts, self.traces, strict=True
                )
            ]
        )
        self.lines: list[dict[str, float]] = []

    @staticmethod
    def _concat(parts: list[Features]) -> Features:
        names = tuple(f"trace {k}: {n}" for k, p in enumerate(parts) for n in p.names)
        groups = tuple(g for p in parts for g in p.groups)
        return Features(
            names, groups,
            np.concatenate([p.value for p in parts]) if parts else np.zeros(0),
            np.concatenate([p.noise for p in parts]) if parts else np.zeros(0),
        )  # fmt: skip

    def counts(self) -> dict[str, int]:
        """The data's features per group over every trace, ``line`` the traces whose holds
        can be searched for one (:attr:`~.signatures.SignatureLayout.line_searchable`)."""
        counts = {g: int(self.data.group(g).sum()) for g in GROUPS}
        counts["line"] = sum(lay.line_searchable for lay in self.layouts)
        return counts

    def coverage(self, effects: Sequence[str]) -> dict[str, dict]:
        """What the traces' protocols can test of ``effects`` (:func:`.signatures.coverage`
        of :meth:`counts`)."""
        return coverage(self.counts(), tuple(effects))

    def find_lines(self, x: np.ndarray, effects: Effects) -> list[dict[str, float]]:
        """Search each trace's holds for a spectral line in data − model; a line counts
        when its χ² beats the false-alarm level :data:`LINE_P_VALUE` over all the searched
        frequencies (2 ln(N/p)); the layouts then measure it. Re-reads the data's
        features."""
        self.lines = []
        for lay, sig, tr in zip(self.layouts, self._signals(x, effects), self.traces, strict=True):
            _t, _u, _g, xv, _y, s, _f, _r = tr
            found = lay.find_line((xv - sig[0]) * s)
            thr = 2.0 * math.log(max(found["searched"], 1) / LINE_P_VALUE)
            found["threshold_chi2"] = thr
            if not found["chi2"] >= thr:
                lay.line_frequency = math.nan
            self.lines.append(found)
        self.data = self._concat(
            [
                lay.measure(x_ * s, None if y is None else y * s)
                for lay, (_t, _u, _g, x_, y, s, _f, _r) in zip(
                    self.layouts, self.traces, strict=True
                )
            ]
        )
        return self.lines

    def features(self, x: np.ndarray, effects: Effects) -> Features:
        """The model's features at (x, effects)."""
        parts = []
        for lay, (xv, yv), tr in zip(self.layouts, self._signals(x, effects), self.traces,
                                     strict=True):  # fmt: skip
            s, has_y = tr[5], tr[4] is not None
            parts.append(lay.measure(xv * s, yv * s if has_y else None))
        return self._concat(parts)

    # --- one candidate ----------------------------------------------------------------------
    def _start(self, name: str, model: Features) -> dict[str, float]:
        e = CATALOGUE[name]
        start = e.defaults()
        if name == "sensor_drift":
            start["offset"] = 0.0  # the features are level differences: no offset in them
        elif name == "friction_wear":
            start["saturation"] = WEAR_RUN_IN_START  # running in; the search may end at 0
        d, m = self.data, model
        if name == "vibration":
            ln = [k for k, g in enumerate(d.groups) if g == "line"]
            lay = next((lay for lay in self.layouts if math.isfinite(lay.line_frequency)), None)
            if len(ln) >= 2 and lay is not None:
                s_c = d.value[ln[:2]] - m.value[ln[:2]]
                radius = self.traces[self.layouts.index(lay)][7]
                start = {"amplitude": float(np.hypot(*s_c)) / (radius * 1e9),
                         "frequency": lay.line_frequency,
                         "phase": float(np.arctan2(s_c[1], s_c[0]))}  # fmt: skip
        elif name == "axis_misalignment":
            k = [i for i, g in enumerate(d.groups) if g == "y"]
            if k:
                start = {"phi": float(math.atan(d.value[k[0]]))}  # signed: y leans either way
        return {p.name: float(np.clip(start.get(p.name, p.typical), p.low, p.high))
                for p in e.parameters}  # fmt: skip

    def fit_candidate(
        self, name: str, x: np.ndarray, effects: Effects, model: Features | None = None
    ) -> CandidateFit:
        """Profile, bounded search and scores of one candidate (module docstring)."""
        e = CATALOGUE[name]
        base = self.features(x, effects) if model is None else model
        d = self.data
        declared = EFFECT_GROUPS.get(name, ())
        w = self._weights(base, declared)
        levels = [lv for lv in CONFOUNDED_NOMINAL.get(name, ()) if lv in self.nominal_names]
        null_shift: dict[str, float] = {}
        objective = self._objective(name, x, effects, w, levels)
        if name == "vibration" and not any(math.isfinite(ly.line_frequency) for ly in self.layouts):
            return self.not_run(name, "no spectral line in the holds above the false-alarm level")
        start = self._start(name, base)
        neutral = e.neutral()
        if levels:
            # the null model refits its levels to the features too, so the F-test's models
            # differ by the effect's parameters alone: a level alone moves the steps the
            # nominal fit set on the trace, and that is no effect's signature
            lk = [f"level:{lv}" for lv in levels]
            _j0, at_null = _with_levels(objective, {**start, **neutral}, levels,
                                        POWELL_EVALS // 2)  # fmt: skip
            null_shift = {lv: at_null[k] for lv, k in zip(levels, lk, strict=True)}
            # the null: the current model with its levels refitted
            x = _shift_levels(x, self.nominal_names, levels, at_null)
            start = {**start, **{k: 0.0 for k in lk}}
            base = self.features(x, effects)
            w = self._weights(base, declared)
            objective = self._objective(name, x, effects, w, levels)
        p0 = next(p for p in e.parameters if p.name == MAIN_PARAMETER.get(name, p.name))
        j_neutral = objective({**start, **neutral}) if name != "vibration" else objective(
            {**start, "amplitude": 0.0})  # fmt: skip
        grid = _profile_grid(p0.low, p0.high, p0.neutral, start[p0.name])
        points = [_with_levels(objective, {**start, p0.name: float(v)}, levels) for v in grid]
        profile = [(float(v), j) for v, (j, _vals) in zip(grid, points, strict=True)]
        k_best = int(np.argmin([j for _v, j in profile]))
        j_best, best = points[k_best]
        # bounded Powell in range-normalised coordinates over the parameters that move, and
        # the levels searched with them (a shift of ±LEVEL_SPAN in the ln-factor)
        free = free_parameters(name)
        keys = [p.name for p in free] + [f"level:{lv}" for lv in levels]
        lo = np.array([p.low for p in free] + [-LEVEL_SPAN] * len(levels))
        span = np.array([p.high - p.low for p in free] + [2.0 * LEVEL_SPAN] * len(levels))

        def from_unit(z: np.ndarray) -> dict[str, float]:
            return {**best, **{k: float(lo[i] + span[i] * z[i]) for i, k in enumerate(keys)}}

        z0 = np.array([(best[k] - lo[i]) / span[i] for i, k in enumerate(keys)])
        res = scipy.optimize.minimize(
            lambda z: objective(from_unit(np.clip(z, 0.0, 1.0))), z0, method="Powell",
            bounds=[(0.0, 1.0)] * len(keys),
            options={"maxfev": POWELL_EVALS, "xtol": 1e-3, "ftol": 1e-4},
        )  # fmt: skip
        if res.fun < j_best:
            best, j_best = from_unit(np.clip(res.x, 0.0, 1.0)), float(res.fun)
        at_neutral = j_best >= j_neutral - 1e-9 or all(
            abs(best[p.name] - p.neutral) <= 1e-3 * (p.high - p.low) for p in (p0,)
        )
        # each level's shift from the current model's: the null's and the candidate's own
        shift = {lv: null_shift[lv] + float(best[f"level:{lv}"]) for lv in levels}
        xb = _shift_levels(x, self.nominal_names, levels, best)
        best = _own(name, best)
        n_free = len(free)
        feats = self.features(xb, {**effects, name: best})
        scores, gain, loo, weakest = declared_gain(d, base, feats, declared, n_free)
        total = sum(s["nats"] for g, s in scores.items() if g in SIGNATURE_GROUPS)
        size = self._effect_size(x, effects, {**effects, name: best}, xb)  # x: the null's
        notes = []
        if main_at_bound(name, best, p0.name):
            notes.append(f"{p0.name} at its bound with the nominal model held (the joint "
                         "refit decides)")  # fmt: skip
        if size < 1.0:
            notes.append(f"changes the trace by {size:.2f}× the noise floor only")
        for g in declared:
            if g in scores and not scores[g]["scored"]:
                notes.append(f"{g}: {scores[g]['n']} setting(s), not scored (fewer than "
                             f"{REPEATED_MIN} cannot tell it from one setting's misfit, and "
                             f"fewer than {STEP_SCALE_MIN} bursts bound that misfit)")
            elif g in scores and scores[g].get("misfit_from") == "steps":
                notes.append(f"{g}: {scores[g]['n']} setting(s), each allowed a misfit of "
                             f"{scores[g]['misfit_sd']:.3g} (the step sizes' misfit, "
                             "fewer settings than estimate their own)")
        level = significance_nats(n_free)
        if shift:
            notes.append("searched with " + ", ".join(
                f"the nominal {lv} ×{math.exp(v):.3g} (×{math.exp(null_shift[lv]):.3g} "
                "without it)" for lv, v in shift.items()))
        if gain >= level > loo:
            notes.append(f"its gain rests on one feature: {loo:.1f} nats without {weakest}")
        # at a bound is reported, not disqualifying: with the nominal model held at its fit
        # (itself a compromise without the effect) a true effect can ask for more
        ok = not at_neutral and size >= 1.0
        return CandidateFit(
            name, best, profile, j_best, j_neutral, bool(at_neutral), scores, float(gain),
            float(total),
            bool(ok and min(gain, loo) >= level and total >= level),
            "; ".join(notes), float(size), float(loo), weakest, shift,
        )  # fmt: skip

    def _objective(
        self, name: str, x: np.ndarray, effects: Effects, w: np.ndarray, levels: Sequence[str]
    ) -> Callable[[Mapping[str, float]], float]:
        """A candidate's objective over its values (its parameters and "level:NAME" shifts
        of x): Σ z²/w over the features (z the data's misfit in its noise, w
        :meth:`_weights`); inf where the model diverges or the sum is not finite."""
        d = self.data

        def objective(vals: Mapping[str, float]) -> float:
            try:
                f = self.features(_shift_levels(x, self.nominal_names, levels, vals),
                                  {**effects, name: _own(name, vals)})  # fmt: skip
            except Exception:  # a diverging corner of the range is a bad point
                return math.inf
            j = float(np.sum(((d.value - f.value) / d.noise) ** 2 / w))
            return j if math.isfinite(j) else math.inf

        return objective

    def _weights(self, base: Features, declared: Sequence[str]) -> np.ndarray:
        """Per feature the factor on its noise variance in a candidate's objective: the
        current model's misfit per feature of its group (at least 1), so no group
        dominates by its count; in a group of :data:`~.signatures.REPEATED_GROUPS` with
        :data:`JACKKNIFE_MIN` features, (σ² + τ²)/σ² with τ² the current model's common
        misfit variance (:func:`~.signatures.misfit_variance`), so the settings weigh alike
        as in :func:`~.signatures.group_scores`, with fewer (σ² + b²)/σ², b the bound from
        the step sizes (:func:`~.signatures.step_misfit_sd`) where there is one; inf
        outside the ``declared`` groups (a candidate is fitted to its signature; what it
        does elsewhere is reported, and the joint trace refit settles the rest)."""
        d = self.data
        w = np.full(len(d.groups), np.inf)
        for g in set(d.groups) & set(declared):
            mk = d.group(g)
            n = int(mk.sum())
            r, sd = d.value[mk] - base.value[mk], d.noise[mk]
            if g in REPEATED_GROUPS and n >= JACKKNIFE_MIN:
                w[mk] = 1.0 + misfit_variance(r, sd, n) / sd**2
            elif g in REPEATED_GROUPS and (bound := step_misfit_sd(d, base)) is not None:
                w[mk] = 1.0 + bound**2 / sd**2  # too few settings: the step sizes' bound
            else:
                w[mk] = max(1.0, float(np.sum((r / sd) ** 2)) / n)
        return w

    def _effect_size(
        self, x: np.ndarray, without: Effects, with_: Effects, x_with: np.ndarray | None = None
    ) -> float:
        """How much a candidate changes the predicted detector channels: the largest RMS
        change [nm] of a trace's x or y channel over that trace's noise floor (``x_with``:
        the candidate's ln-factors where its levels moved them)."""
        size = 0.0
        xw = x if x_with is None else x_with
        for (xa, ya), (xb, yb), tr in zip(self._signals(x, without), self._signals(xw, with_),
                                          self.traces, strict=True):  # fmt: skip
            s, floor = tr[5], tr[6]
            chans = [(xa, xb)] + ([(ya, yb)] if tr[4] is not None else [])
            for a, b in chans:
                rms = float(np.sqrt(np.mean(((b - a) * s) ** 2)))
                size = max(size, rms / max(floor, 1e-12))
        return size

    @staticmethod
    def not_run(name: str, why: str) -> CandidateFit:
        """A candidate that was not searched, with the reason."""
        return CandidateFit(name, CATALOGUE[name].neutral(), [], math.nan, math.nan, True, {},
                            0.0, 0.0, False, why)  # fmt: skip


def declared_gain(
    data: Features, a: Features, b: Features, declared: Sequence[str], n_free: int
) -> tuple[dict[str, dict[str, float]], float, float, str]:
    """Model b against model a on the data's features: the per-group scores
    (:func:`~.signatures.group_scores`), the gain on the ``declared`` groups [nats], the
    least of it with one feature left out and that feature (:func:`leave_one_out`)."""
    scores = group_scores(data, a, b, n_free=n_free)
    gain = sum(scores[g]["nats"] for g in declared if g in scores)
    loo, weakest = leave_one_out(data, a, b, declared, n_free)
    return scores, float(gain), float(loo), weakest


def _shift_levels(
    x: np.ndarray, names: Sequence[str], levels: Sequence[str], vals: Mapping[str, float]
) -> np.ndarray:
    """ln-factors x (named ``names``) with each of ``levels`` shifted by
    ``vals["level:NAME"]`` (0 where absent)."""
    xs = np.array(x, dtype=float)
    for lv in levels:
        xs[list(names).index(lv)] += vals.get(f"level:{lv}", 0.0)
    return xs


def _with_levels(
    objective: Callable[[Mapping[str, float]], float], vals: dict[str, float],
    levels: Sequence[str], maxfev: int = LEVEL_EVALS,
) -> tuple[float, dict[str, float]]:  # fmt: skip
    """(objective, values) at ``vals`` with the ``levels`` ("level:NAME" shifts) refitted
    there by a bounded search of ``maxfev`` evaluations: a profile over an effect's main
    parameter along the valley it forms with the level (wear lowers the friction the level
    raises), and the null model's levels (the effect at neutral)."""
    if not levels:
        return objective(vals), vals
    lk = [f"level:{lv}" for lv in levels]
    z0 = np.array([vals.get(k, 0.0) for k in lk])
    res = scipy.optimize.minimize(
        lambda z: objective({**vals, **dict(zip(lk, z, strict=True))}), z0, method="Powell",
        bounds=[(-LEVEL_SPAN, LEVEL_SPAN)] * len(lk),
        options={"maxfev": maxfev, "xtol": 1e-3, "ftol": 1e-4},
    )  # fmt: skip
    out = {**vals, **{k: float(v) for k, v in zip(lk, res.x, strict=True)}}
    j = float(res.fun)
    return (j, out) if math.isfinite(j) else (math.inf, out)


def _own(name: str, vals: Mapping[str, float]) -> dict[str, float]:
    """An effect's own parameters from a search's values (without its levels)."""
    return {p.name: float(vals[p.name]) for p in CATALOGUE[name].parameters}


def leave_one_out(
    data: Features, a: Features, b: Features, declared: Sequence[str], n_free: int = 1
) -> tuple[float, str]:
    """Model b's gain over model a on the ``declared`` groups with each feature of a declared
    group of :data:`JACKKNIFE_GROUPS` with at least :data:`JACKKNIFE_MIN` features left out
    in turn: (the smallest, the feature left out there); (the whole gain, "") when no such
    group has that many."""
    counts = {g: sum(1 for x in data.groups if x == g) for g in declared}
    worst = (math.inf, "")
    for k, g in enumerate(data.groups):
        if g not in declared or g not in JACKKNIFE_GROUPS or counts[g] < JACKKNIFE_MIN:
            continue
        keep = np.ones(len(data.groups), bool)
        keep[k] = False
        s = group_scores(data.subset(keep), a.subset(keep), b.subset(keep), n_free)
        gain = sum(s[x]["nats"] for x in declared if x in s)
        if gain < worst[0]:
            worst = (gain, data.names[k])
    if math.isinf(worst[0]):
        s = group_scores(data, a, b, n_free)
        return sum(s[x]["nats"] for x in declared if x in s), ""
    return float(worst[0]), worst[1]


def _profile_grid(low: float, high: float, neutral: float, start: float) -> np.ndarray:
    """Values of a parameter for its profile: its neutral value, then on each side of it
    that the range has, distances of 1 %, 3 %, 10 %, 30 % and 100 % of that side (an
    effect may be small: a linear grid would step over it), and the start value."""
    pts = [neutral, start, low, high]
    for edge in (low, high):
        if abs(edge - neutral) > 0:
            pts += [neutral + f * (edge - neutral) for f in (0.01, 0.03, 0.1, 0.3)]
    return np.unique(np.clip(pts, low, high))
