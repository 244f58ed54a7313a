"""Monotonic basin hopping of the nominal trace fit (:func:`trace_fit._basin_hops`), on a
landscape of many close basins like the stick–slip objective's (a step gained or lost):
least squares descends to the bottom of the basin it starts in, and only a hop finds a
lower one. The contract: the cost never rises, a hop is kept only when it lowers the cost
by ``HOP_TOL``, two failed hops in a row end the search, and from a start some basins
away it reaches the lowest one."""

from __future__ import annotations

import itertools
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from turntable_env.calibration import trace_fit
from turntable_env.calibration.trace_fit import HOP_TOL, HOPS, LocalFit

PERIOD = 0.3  # ln-units between basin bottoms (the prior σ is 1)
CENTRE = np.array([0.35, -0.8, 0.1])  # the lowest basin is the grid point nearest to it


def _bottom(x: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(x) / PERIOD) * PERIOD


def _cost(x: np.ndarray) -> float:
    """Terraced bowl: flat-bottomed basins of width PERIOD around a quadratic trend."""
    b = _bottom(x)
    return float(np.sum((b - CENTRE) ** 2) + 0.5 * np.sum((np.asarray(x) - b) ** 2))


def _fit(x: np.ndarray) -> LocalFit:
    b = _bottom(x)
    n = b.size
    return LocalFit(b, {}, np.ones(n), {}, _cost(b), _cost(b), _cost(b), 1)


@pytest.fixture
def landscape(monkeypatch):
    n = CENTRE.size
    problem = SimpleNamespace(model=_Model(np.ones(n), np.full(n, -5.0), np.full(n, 5.0)))
    runs = {"local": 0}

    def local_fits(_problem, starts, _workers, _nfev, *_effects):
        runs["local"] += len(starts)
        return [_fit(x) for x in starts]

    monkeypatch.setattr(trace_fit, "_objectives",
                        lambda _p, pts, _w, _b, *_e: np.array([_cost(x) for x in pts]))  # fmt: skip
    monkeypatch.setattr(trace_fit, "_local_fits", local_fits)
    return problem, runs


class _Model:
    """A nominal model stand-in: its parameters' prior σ and bounds (ln-units)."""

    def __init__(self, sigma: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
        self.sigma, self.low, self.high = sigma, low, high

    def __len__(self) -> int:
        return self.sigma.size


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hops_descend_from_a_far_basin_to_the_lowest(landscape, seed):
    problem, _runs = landscape
    start = _fit(CENTRE + np.array([1.2, -0.9, 1.5]))  # several basins away on every axis
    best, rows = trace_fit._basin_hops(problem, start, 1, seed, lambda _m: None)
    lowest = _cost(_bottom(CENTRE))
    assert best.cost < 0.5 * start.cost
    assert best.cost <= lowest + 2 * PERIOD**2  # within a basin of the lowest
    # monotone: every hop starts from the best so far, and one is kept only by HOP_TOL
    before = [r["cost_before"] for r in rows]
    assert all(b2 <= b1 for b1, b2 in itertools.pairwise(before))
    for r in rows:
        if r["accepted"]:
            assert min(r["costs"]) < (1.0 - HOP_TOL) * r["cost_before"]
    assert len(rows) <= HOPS


def test_two_failed_hops_end_the_search(landscape):
    problem, runs = landscape
    start = _fit(CENTRE)  # already in the lowest basin: no hop can lower the cost
    best, rows = trace_fit._basin_hops(problem, start, 1, 0, lambda _m: None)
    assert best.cost == start.cost
    assert [r["accepted"] for r in rows] == [False, False]
    assert runs["local"] == 2 * trace_fit.HOP_STARTS


@pytest.mark.parametrize("min_hops", [3, 5, HOPS + 2])
def test_a_refit_given_a_budget_hops_that_often_before_two_failures_end_it(landscape, min_hops):
    """The current model's refit a further effect must beat hops at least as often as the
    effect's joint refit did (the same budget): two failures end it only after
    ``min_hops``, and never past ``hops``."""
    problem, runs = landscape
    start = _fit(CENTRE)
    best, rows = trace_fit._basin_hops(problem, start, 1, 0, lambda _m: None,
                                       min_hops=min_hops)  # fmt: skip
    assert best.cost == start.cost
    assert len(rows) == min(min_hops, HOPS) and not any(r["accepted"] for r in rows)
    assert runs["local"] == len(rows) * trace_fit.HOP_STARTS


def test_hops_with_effects_hold_them_in_the_cloud_and_fit_the_free_ones(monkeypatch):
    """With named effects (the joint refit of an effect round), the cloud moves the nominal
    factors only and is evaluated with the fit's effects at their values; the least squares
    from its best points fit the free effects too, and a kept hop carries its effects."""
    n = CENTRE.size
    problem = SimpleNamespace(model=_Model(np.ones(n), np.full(n, -5.0), np.full(n, 5.0)))
    seen: dict[str, list] = {"objective": [], "local": []}
    effects = {"piezo_hysteresis": {"h": 0.1, "width": 2.0}}

    def objectives(_p, pts, _w, _b, eff=None):
        seen["objective"].append(eff)
        return np.array([_cost(x) for x in pts])

    def local_fits(_p, starts, _w, _nfev, eff=None, free=()):
        seen["local"].append((eff, tuple(free)))
        return [replace(_fit(x), effects={"piezo_hysteresis": {"h": 0.12, "width": 2.0}})
                for x in starts]  # fmt: skip

    monkeypatch.setattr(trace_fit, "_objectives", objectives)
    monkeypatch.setattr(trace_fit, "_local_fits", local_fits)
    start = replace(_fit(CENTRE + np.array([1.2, -0.9, 1.5])), effects=effects)
    best, rows = trace_fit._basin_hops(problem, start, 1, 0, lambda _m: None,
                                       free_effects=["piezo_hysteresis"])  # fmt: skip
    assert seen["objective"][0] == effects  # the first cloud: the start's effects held
    assert all(free == ("piezo_hysteresis",) for _eff, free in seen["local"])
    assert any(r["accepted"] for r in rows)
    assert best.effects["piezo_hysteresis"]["h"] == 0.12  # the kept hop's effects
    # after a kept hop the clouds are evaluated with the effects it reached
    assert seen["objective"][-1] == best.effects


def test_report_shows_the_hops_of_an_effect_round():
    """report.md: an effect round's hops (the named effect's joint refit, and the current
    model's refit a further effect must beat) are tabled under their round, one row per
    hop with its costs and whether it was kept."""
    from turntable_env.calibration.calibrate import _md_signatures

    hop = {"radius_sigma": 0.5, "cost_before": 21.16, "costs": [21.07, 19.73],
           "accepted": True, "heldout_rms": 21.38}  # fmt: skip
    miss = {**hop, "costs": [24.3], "accepted": False}
    decision = {"named": "piezo_hysteresis", "margin_nats": 9.0, "undecided": []}
    hops = {"joint_refit": [hop, miss], "current_refit": [miss]}
    rnd = {"round": 2, "decision": decision, "candidates": [], "hops": hops}
    text = "\n".join(_md_signatures({"lines": [], "rounds": [rnd]}, "nm"))
    joint = text.index("Basin hopping from piezo_hysteresis's joint refit")
    current = text.index("Basin hopping from the current model's refit")
    assert text.index("Round 2") < joint < current
    assert "| 0 | 0.5 | 21.16 | 21.07, 19.73 | yes | 21.4 |" in text[joint:current]
    assert "| 1 | 0.5 | 21.16 | 24.3 | no | 21.4 |" in text[joint:current]
    assert text[current:].count("| no |") == 1


@pytest.mark.parametrize("rejected", [None, "held-out 3.22 against 3.19 nm without it"])
def test_report_gives_the_named_effects_margin_on_the_trace(rejected):
    """report.md's round line carries the decision's margin on the trace (the held-out
    errors with and without the effect, the signed-rank z and the veto's bar) and each
    parameter's distance from neutral in its standard errors, once: a rejection's text
    has them."""
    from turntable_env.calibration.calibrate import _md_signatures

    decision = {"named": "friction_asymmetry", "margin_nats": 234.9, "undecided": [],
                **({"rejected": rejected} if rejected else {})}  # fmt: skip
    test = {"rms_with": 3.22, "rms_without": 3.54, "gain": 0.09, "z": 1.04, "blocks": 14,
            "block": 300, "z_min": -2.0}  # fmt: skip
    rnd = {"round": 1, "decision": decision, "candidates": [], "hops": {},
           "on_trace": "alpha 0.9 σ from neutral", "trace_test": test}  # fmt: skip
    line = next(t for t in _md_signatures({"lines": [], "rounds": [rnd]}, "nm")
                if t.startswith("Round 1"))  # fmt: skip
    if rejected:
        assert line.startswith("Round 1: led by friction_asymmetry") and rejected in line
        assert "alpha 0.9" not in line and "z +1.0" not in line
    else:
        assert line == ("Round 1: named friction_asymmetry (lead 234.9 nats); on the held-out "
                        "trace 3.22 against 3.54 nm without it, z +1.0 over 14 blocks (vetoed "
                        "at ≤ -2); parameters alpha 0.9 σ from neutral.")  # fmt: skip
