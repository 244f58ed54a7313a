"""The nominal fit's amplifier profile (:func:`trace_fit._amplifier_profile`), on a landscape
whose only deep basin lies at a slower amplifier than the global design's box admits. The
contract: the amplifier's two ln-factors are held at each pair of ``AMPLIFIER_PROFILE``
(prior σ) while every other nominal factor is fitted; the lowest ``HOP_STARTS`` of those
fits are freed; the best is kept only when it lowers the cost by ``HOP_TOL`` under the
same data weight; the profile runs only where the nominal fit stays above its target and
the model fits the amplifier."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from turntable_env.calibration import trace_fit
from turntable_env.calibration.trace_fit import (
    AMPLIFIER_PROFILE,
    AMPLIFIER_SCALES,
    GLOBAL_BOX,
    HOP_STARTS,
    HOP_TOL,
    HOPS,
    TRACE_NOMINAL,
    LocalFit,
)

N = len(TRACE_NOMINAL)
SIGMA = 0.7  # the amplifier's prior σ (nominal.py), every factor's here
IA = [TRACE_NOMINAL.index(n) for n in AMPLIFIER_SCALES]
PLATEAU, DEEP = 30.0, 0.2  # the data's cost off and in the basin: deeper than its prior


class _Model:
    """The real model's names, prior σ 0.7 and bounds ±5 on every ln-factor."""

    names = TRACE_NOMINAL
    sigma, low, high = np.full(N, SIGMA), np.full(N, -5.0), np.full(N, 5.0)

    def __len__(self) -> int:
        return N


class _Slow:
    """The data's cost: a basin around the amplifier's ln-factors ``centre`` [prior σ], of
    half-width ``radius`` σ, flat elsewhere in them; plus a quadratic bowl in the other
    factors. A fit's cost adds the prior rows (x/σ)² of the factors it frees, as
    :func:`trace_fit.local_fit`'s does. A fit that holds the amplifier keeps it; a free fit
    descends to the basin's centre only from inside it."""

    def __init__(self, centre: tuple[float, float], radius: float = 0.6):
        self.centre = np.asarray(centre) * SIGMA
        self.radius = radius * SIGMA

    def inside(self, x: np.ndarray) -> bool:
        return bool(np.max(np.abs(np.asarray(x)[IA] - self.centre)) < self.radius)

    def data(self, x: np.ndarray) -> float:
        x = np.asarray(x, dtype=float)
        rest = 0.01 * float(np.sum(np.delete(x, IA) ** 2))
        if self.inside(x):
            return DEEP + float(np.sum((x[IA] - self.centre) ** 2)) + rest
        return PLATEAU + rest

    def cost(self, x: np.ndarray) -> float:
        """The data's cost and every factor's prior row (TraceProblem.objective)."""
        return self.data(x) + float(np.sum((np.asarray(x) / SIGMA) ** 2))

    def fit(self, x: np.ndarray, free: Any = True) -> LocalFit:
        x = np.asarray(x, dtype=float).copy()
        mask = np.ones(N, bool)
        mask[IA] = False
        x[mask] = 0.0
        if free is True and self.inside(x):
            x[IA] = self.centre
        c = self.cost(x) if free is True else self.data(x)  # held: no rows for the amplifier
        return LocalFit(x, {}, np.full(N, 0.1), {}, c, c, c, 1)


def _at(basin: _Slow) -> np.ndarray:
    """The basin's centre: the amplifier there, every other factor at the prior."""
    x = np.zeros(N)
    x[IA] = basin.centre
    return x


def _landscape(monkeypatch, centre):
    basin = _Slow(centre)
    seen: dict[str, Any] = {"calls": []}

    def local_fits(_p, starts, _w, _n, *_a, free_nominal=True, **_k):
        seen["calls"].append(([np.asarray(s).copy() for s in starts], free_nominal))
        return [basin.fit(x, free_nominal) for x in starts]

    monkeypatch.setattr(trace_fit, "_local_fits", local_fits)
    monkeypatch.setattr(trace_fit, "_objectives",
                        lambda p, pts, *_a: np.array([basin.cost(x) for x in pts]))  # fmt: skip
    problem = SimpleNamespace(model=_Model(), weight=1.0, objective=lambda x, *_e: basin.cost(x))
    return problem, basin, seen


def _quiet(_m: str) -> None:
    return None


@pytest.mark.parametrize("centre", [(-1.2, -2.8), (-2.7, -2.7), (-2.8, -1.3)])
def test_the_profile_holds_the_amplifier_and_reaches_a_basin_beyond_the_box(monkeypatch,
                                                                            centre):  # fmt: skip
    """The basin's current (or slew) factor lies beyond the design's ±2.5 σ box and more
    than a hop's 1 σ from the datasheet: only the profile reaches it, and keeps it."""
    problem, basin, seen = _landscape(monkeypatch, centre)
    assert min(centre) < -GLOBAL_BOX
    best = basin.fit(np.zeros(N))  # the datasheet amplifier's optimum, on the plateau
    kept, row = trace_fit._amplifier_profile(problem, best, 1, (0, HOPS), _quiet)
    held, free = seen["calls"][0]
    assert free == [n for n in TRACE_NOMINAL if n not in AMPLIFIER_SCALES]
    grid = {(a, b) for a in AMPLIFIER_PROFILE for b in AMPLIFIER_PROFILE}
    assert {tuple(np.round(x[IA] / SIGMA, 12)) for x in held} == grid and len(held) == 9
    assert all(np.array_equal(np.delete(x, IA), np.delete(best.x, IA)) for x in held)
    freed, free2 = seen["calls"][1]
    assert free2 is True and len(freed) == HOP_STARTS
    assert row["kept"] and basin.inside(kept.x)
    np.testing.assert_allclose(kept.x[IA], basin.centre)
    assert kept.cost == pytest.approx(basin.cost(_at(basin))) == row["cost_after"]
    assert kept.cost < (1.0 - HOP_TOL) * row["cost_before"]
    assert row["amplifier"]["amplifier_current"] == pytest.approx(np.exp(basin.centre[1]))
    for x, point in zip(held, row["points"], strict=True):  # ranked by the whole cost,
        assert point["cost"] == pytest.approx(basin.cost(basin.fit(x, False).x))  # priors too
    inside = [basin.inside(x) for x in held]  # the held points in the basin: the lowest costs
    assert sorted(p["cost"] for p, i in zip(row["points"], inside, strict=True) if i) == sorted(
        p["cost"] for p in row["points"])[:sum(inside)]  # fmt: skip


def test_a_profile_that_finds_nothing_better_is_not_kept(monkeypatch):
    """The datasheet amplifier already sits in the basin: every profile point is on the
    plateau, and the fit is returned as it was."""
    problem, basin, _seen = _landscape(monkeypatch, (0.0, 0.0))
    best = basin.fit(np.zeros(N))
    kept, row = trace_fit._amplifier_profile(problem, best, 1, (0, HOPS), _quiet)
    assert kept is best and not row["kept"] and row["hops"] == []
    assert row["heldout_rms"] == best.heldout_rms == row["heldout_before"]


@pytest.mark.parametrize(("target", "runs"), [(40.0, False), (20.0, True)])
def test_the_nominal_fit_profiles_the_amplifier_only_above_its_target(monkeypatch, target,
                                                                      runs):  # fmt: skip
    """The prior and every design start end on the plateau (cost 1): above the target the
    profile runs (after the second stage) and its basin is the nominal model."""
    problem, basin, _seen = _landscape(monkeypatch, (-1.8, -3.2))
    monkeypatch.setattr(trace_fit, "_reweight", lambda *_a: None)
    monkeypatch.setattr(trace_fit, "local_fit", lambda _p, x, *_a, **_k: basin.fit(x))
    nominal, spread = trace_fit._fit_nominal(problem, np.zeros(N), (0.01, target), 32, 2, 1, 0,
                                             None, _quiet)  # fmt: skip
    assert (spread["amplifier_profile"] is not None) is runs
    assert nominal.cost == pytest.approx(basin.cost(_at(basin)) if runs else PLATEAU)


@pytest.mark.parametrize("kept", [True, False])
def test_report_states_the_profile_and_whether_it_was_kept(kept):
    from turntable_env.calibration.calibrate import _md_profile

    pts = [{"amplifier_slew": 0.5, "amplifier_current": 0.124, "cost": 60.2, "heldout_rms": 44.0}]
    row = {"points": pts, "freed_costs": [55.0, 61.0], "cost_before": 71.2,
           "heldout_before": 49.5, "cost_after": 55.0, "kept": kept, "hops": [],
           "heldout_rms": 42.1 if kept else 49.5,
           "amplifier": {"amplifier_slew": 0.158, "amplifier_current": 0.117}}  # fmt: skip
    text = "\n".join(_md_profile(row, "nm"))
    assert "Amplifier profile (the nominal fit, 49.5 nm, stayed above the target)" in text
    assert "| 0.5 | 0.124 | 60.2 | 44 |" in text
    assert "costs 55, 61 (best at slew 0.158, current 0.117) against the nominal fit's 71.2" in text
    assert ("; kept (held-out 42.1 nm)" in text) is kept
    assert ("not kept (held-out 49.5 nm)" in text) is not kept
    assert _md_profile(None, "nm") == []
