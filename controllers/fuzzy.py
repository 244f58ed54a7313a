"""Fuzzy step-count controller (Mamdani, scikit-fuzzy's control API), the thesis's §5.2.

Inputs, from the detector each control interval:

* error e = θ* − θ_measured [µrad], universe ±1200 (the reading spans ±571 µrad and the
  targets ±457 µrad, so |e| < 1030 µrad; a saturated reading gives the largest error);
* error change Δe = e_k − e_{k−1} [µrad per interval], universe ±1200.

Output: n, signed stick–slip steps per interval, universe ±``max_steps`` (10); the
generator runs |n| periods per interval at f = |n|/Δt with the fixed waveform
``amplitude`` (6 V), a = 0.9, k = 1, sign(n) the direction. Mamdani inference (min for
AND, max aggregation), centroid defuzzification; n is rounded, and n = 0 inside the scan
range hands over to the scan PID (:mod:`controllers.scan_pid`).

Membership functions (µrad for e and Δe, steps for n; L = the universe bound):

======  ==================================  ======================================
set     e (trapezoid / triangle)             n
======  ==================================  ======================================
NL      (−L, −L, −500, −250)                 (−N, −N, −0.8N, −0.5N)
NM      (−500, −250, −90)                    (−0.8N, −0.5N, −0.2N)
NS      (−250, −90, 0)                       (−0.5N, −0.2N, 0)
ZE      (−90, 0, 90)                         (−0.2N, 0, 0.2N)
PS/PM/PL  mirror images                      mirror images
======  ==================================  ======================================

Δe has three sets: N (−L, −L, −300, 0), Z (−300, 0, 300), P (0, 300, L, L).

Rule base (rows e, columns Δe; Δe < 0 means the error shrinks when e > 0):

======  ====  ====  ====
e \\ Δe  N     Z     P
======  ====  ====  ====
NL      NL    NL    NL
NM      NM    NM    NM
NS      NS    NS    ZE
ZE      ZE    ZE    ZE
PS      ZE    PS    PS
PM      PM    PM    PM
PL      PL    PL    PL
======  ====  ====  ====

Every column is non-decreasing from NL to PL, so the output is monotone in the error
(tested). Near the target a shrinking error (Δe against e) stops the stepping early and
a growing one keeps the small step count: a larger count there would overshoot by more
than the band it came from and ring (a limit cycle between NS and PS).

For speed the control surface is tabulated once per process on ``grid`` × ``grid``
points by one vectorised scikit-fuzzy ``ControlSystemSimulation`` run, and interpolated
bilinearly.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import ControllerContext, Move, StepScanController
from .blind import BlindSettings
from .feedforward import MapPlanner
from .lab import LabBrief
from .step_gain import StepGains
from .step_map import StepMap

__all__ = ["FuzzyStepController", "control_surface", "fuzzy_system"]

E_MAX = 1200.0  # µrad, error universe bound
DE_MAX = 1200.0  # µrad per interval, error-change universe bound
RULES = {  # (e set, Δe set) → n set, see the module docstring
    "NL": ("NL", "NL", "NL"),
    "NM": ("NM", "NM", "NM"),
    "NS": ("NS", "NS", "ZE"),
    "ZE": ("ZE", "ZE", "ZE"),
    "PS": ("ZE", "PS", "PS"),
    "PM": ("PM", "PM", "PM"),
    "PL": ("PL", "PL", "PL"),
}


def fuzzy_system(max_steps: float = 10.0) -> Any:
    """The Mamdani system as a scikit-fuzzy ``ControlSystem`` (inputs ``error``,
    ``error_change`` [µrad], output ``steps``)."""
    import skfuzzy as fuzz
    from skfuzzy import control as ctrl

    n_max = float(max_steps)
    e = ctrl.Antecedent(np.linspace(-E_MAX, E_MAX, 241), "error")
    de = ctrl.Antecedent(np.linspace(-DE_MAX, DE_MAX, 121), "error_change")
    n = ctrl.Consequent(np.linspace(-n_max, n_max, 201), "steps", defuzzify_method="centroid")
    L = E_MAX
    e["NL"] = fuzz.trapmf(e.universe, [-L, -L, -500, -250])
    e["NM"] = fuzz.trimf(e.universe, [-500, -250, -90])
    e["NS"] = fuzz.trimf(e.universe, [-250, -90, 0])
    e["ZE"] = fuzz.trimf(e.universe, [-90, 0, 90])
    e["PS"] = fuzz.trimf(e.universe, [0, 90, 250])
    e["PM"] = fuzz.trimf(e.universe, [90, 250, 500])
    e["PL"] = fuzz.trapmf(e.universe, [250, 500, L, L])
    D = DE_MAX
    de["N"] = fuzz.trapmf(de.universe, [-D, -D, -300, 0])
    de["Z"] = fuzz.trimf(de.universe, [-300, 0, 300])
    de["P"] = fuzz.trapmf(de.universe, [0, 300, D, D])
    N = n_max
    n["NL"] = fuzz.trapmf(n.universe, [-N, -N, -0.8 * N, -0.5 * N])
    n["NM"] = fuzz.trimf(n.universe, [-0.8 * N, -0.5 * N, -0.2 * N])
    n["NS"] = fuzz.trimf(n.universe, [-0.5 * N, -0.2 * N, 0])
    n["ZE"] = fuzz.trimf(n.universe, [-0.2 * N, 0, 0.2 * N])
    n["PS"] = fuzz.trimf(n.universe, [0, 0.2 * N, 0.5 * N])
    n["PM"] = fuzz.trimf(n.universe, [0.2 * N, 0.5 * N, 0.8 * N])
    n["PL"] = fuzz.trapmf(n.universe, [0.5 * N, 0.8 * N, N, N])
    rules = [
        ctrl.Rule(e[es] & de[ds], n[out])
        for es, outs in RULES.items()
        for ds, out in zip(("N", "Z", "P"), outs, strict=True)
    ]
    return ctrl.ControlSystem(rules)


def control_surface(system: Any, errors: np.ndarray, changes: np.ndarray) -> np.ndarray:
    """Defuzzified output n on the grid errors × changes [µrad]: one vectorised
    scikit-fuzzy ``ControlSystemSimulation`` run over every grid point."""
    from skfuzzy import control as ctrl

    e, d = np.meshgrid(errors, changes, indexing="ij")
    sim = ctrl.ControlSystemSimulation(system, flush_after_run=e.size + 1)
    sim.input["error"] = e.ravel()
    sim.input["error_change"] = d.ravel()
    sim.compute()
    return np.asarray(sim.output["steps"], dtype=float).reshape(e.shape)


class FuzzyStepController(StepScanController):
    """Fuzzy choice of the step count per interval, scan PID at the end (module docstring).

    Args:
        ctx: plant context; amplitude: input amplitude of the steps [V]; max_steps: |n|
        bound; grid: points per axis of the tabulated control surface; step_map: the map
        whose step per period at ``amplitude`` (mean over f ≤ max_steps/Δt) the online
        step gain is measured against (default: the shipped one); caution: the gain's
        upper bound before anything is measured (:class:`~controllers.step_gain.StepGains`);
        blind_settings: the blind set (:mod:`controllers.blind`; default: the
            asymmetry-robust one, ``ASYMMETRY_PATH``): on the way in from beyond the
            detector each interval steps with its setting of the largest map travel
            within the rules' move (n periods of the fixed waveform), not with the fixed
            waveform.

    The plant it is on: the error enters the rules divided by the learned step gain γ_d
    (input scaling, a plant that steps 2× the map sees half the error), and no interval
    runs more periods than could pass the target at the gain's upper bound.
    """

    name = "fuzzy"

    def __init__(
        self,
        ctx: ControllerContext,
        *,
        amplitude: float = 6.0,
        max_steps: int = 10,
        grid: int = 61,
        step_map: StepMap | None = None,
        caution: float = 4.0,
        blind_settings: BlindSettings | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(ctx, **kwargs)
        if max_steps < 1 or max_steps * 1.0 / ctx.control_interval > 2000.0:
            raise ValueError(f"max_steps={max_steps!r}: need 1 ≤ n and n/Δt ≤ 2 kHz")
        self.amplitude = amplitude
        self.max_steps = max_steps
        self.errors = np.linspace(-E_MAX, E_MAX, grid)
        self.changes = np.linspace(-DE_MAX, DE_MAX, grid)
        self.surface = _surface(max_steps, grid)
        smap = step_map if step_map is not None else StepMap.load()
        freqs = np.unique(smap.frequency)
        freqs = freqs[freqs * ctx.control_interval <= max_steps + 1e-9]
        # the nominal step per period at the fixed waveform, by direction [rad]
        self.reference_step = {
            d: float(np.mean([smap.step_size(ctx.axis, d * amplitude, f, 0.9, 1.0) for f in freqs]))
            for d in (1, -1)
        }
        if any(self.reference_step[d] * d <= 0.0 for d in (1, -1)):
            raise ValueError(f"amplitude={amplitude!r}: the step map has no forward step there")
        self.gains = StepGains(caution=caution)
        # the way in from beyond the detector steps with the blind set's setting nearest
        # under the rules' own move (the thesis's rules do not know the direction can
        # reverse there: controllers.blind)
        self.planner = MapPlanner(smap, ctx, blind_settings=blind_settings)

    def reset(self, obs: np.ndarray, brief: LabBrief) -> None:
        super().reset(obs, brief)
        self.last_error: float | None = None

    def _move(self, n: int) -> Move:
        """n signed periods at the fixed waveform, with the displacement the map predicts."""
        d = 1 if n > 0 else -1
        f = abs(n) / self.ctx.control_interval
        amp = min(self.amplitude, self.ctx.input_limit - abs(self.offset))
        nominal = abs(n) * self.reference_step[d]
        g = float(self.gains.estimate(d, amp)[0][0])
        return Move(d * amp, f, 0.9, 1.0, nominal * g, nominal)

    def search_move(self, direction: int, saturated: bool = False) -> Move | None:
        return self._move(1 if direction > 0 else -1)

    def steps(self, error: float, change: float) -> float:
        """Defuzzified n for e, Δe [rad] (bilinear in the tabulated surface)."""
        e = float(np.clip(error * 1e6, -E_MAX, E_MAX))
        d = float(np.clip(change * 1e6, -DE_MAX, DE_MAX))
        i = int(np.clip(np.searchsorted(self.errors, e) - 1, 0, self.errors.size - 2))
        j = int(np.clip(np.searchsorted(self.changes, d) - 1, 0, self.changes.size - 2))
        te = (e - self.errors[i]) / (self.errors[i + 1] - self.errors[i])
        td = (d - self.changes[j]) / (self.changes[j + 1] - self.changes[j])
        s = self.surface
        return float(
            (1 - te) * (1 - td) * s[i, j]
            + te * (1 - td) * s[i + 1, j]
            + (1 - te) * td * s[i, j + 1]
            + te * td * s[i + 1, j + 1]
        )

    def observe(self, measured: float, saturated: bool) -> None:
        self.estimate = measured  # the fuzzy controller believes the detector only

    def choose_move(self, remaining: float, measured: float, saturated: bool) -> Move | None:
        # the error the rules see, × the aim's scale (1 here; a residual agent's s: agents.residual)
        err = (self.target - measured) * self.remaining_scale
        d = 1 if err > 0 else -1
        g, upper = self.gains.estimate(d, self.amplitude)
        # input scaling by the learned step gain: the rules see the error in nominal steps
        scaled = err / float(g[0])
        fresh = self.last_error is None or self.last_move is None  # first stepping interval
        change = 0.0 if fresh else scaled - self.last_error
        self.last_error = scaled
        n = round(self.steps(scaled, change))
        if n == 0:
            return None
        if self.blind_approach(saturated):  # the rules' travel, with a robust setting
            return self.planner.blind_within(d, abs(n) * self.reference_step[d])
        if not saturated:  # no more periods than could pass the target at the gain's bound
            cap = int(abs(err) / (abs(self.reference_step[d]) * float(upper[0])))
            n = int(np.sign(n)) * max(1, min(abs(n), cap))
        return self._move(n)


_SURFACES: dict[tuple[int, int], np.ndarray] = {}


def _surface(max_steps: int, grid: int) -> np.ndarray:
    """The tabulated control surface, computed once per (max_steps, grid)."""
    key = (max_steps, grid)
    if key not in _SURFACES:
        e = np.linspace(-E_MAX, E_MAX, grid)
        d = np.linspace(-DE_MAX, DE_MAX, grid)
        _SURFACES[key] = control_surface(fuzzy_system(max_steps), e, d)
    return _SURFACES[key]
