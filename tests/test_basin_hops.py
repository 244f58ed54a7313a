"""Monotonic basin hopping of the nominal trace fit (:func:`trace_fit._basin_hops`), on a
landscape of many close basins like the stick–slip objective's (a step gained or lost):
least squares descends to the bottom of the basin it starts in, and only a hop finds a
lower one. The contract: the cost never rises, a hop is kept only when it lowers the cost
by ``HOP_TOL``, two failed hops in a row end the search, and from a start some basins
away it reaches the lowest one."""

from __future__ import annotations

import itertools
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

    def local_fits(_problem, starts, _workers, _nfev):
        runs["local"] += len(starts)
        return [_fit(x) for x in starts]

    monkeypatch.setattr(trace_fit, "_objectives",
                        lambda _p, pts, _w, _b: np.array([_cost(x) for x in pts]))  # fmt: skip
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
