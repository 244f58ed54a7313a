"""The nominal fit's second global stage (:func:`trace_fit._second_stage`), on a landscape
with a narrow basin: the objective is flat but for a small region of two factors. The
contract: the second stage doubles the first design (the same Sobol sequence and box,
only the new half evaluated) and runs the nominal fit's search again on it; it runs only
when the nominal fit stays above its target and the doubled design's best starts include
a new point; it is kept only when it lowers the cost by ``HOP_TOL`` under the same data
weight."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from turntable_env.calibration import trace_fit
from turntable_env.calibration.trace_fit import (
    GLOBAL_BOX,
    HOP_TOL,
    HOPS,
    TRACE_NOMINAL,
    LocalFit,
)

N = len(TRACE_NOMINAL)  # the real model's dimension: twelve ln-factors, prior σ 1 here
N_FIRST = 64  # the first design's points
PLATEAU, DEEP = 1.0, 0.2  # costs off and in the narrow basin
W_PRIOR, W_DATA = 1.0, 3.0  # the data weights before any fit and after the re-weighting


class _Model:
    """A nominal model stand-in: prior σ 1 and bounds ±5 on every ln-factor."""

    sigma, low, high = np.ones(N), np.full(N, -5.0), np.full(N, 5.0)
    names = tuple(f"x{k}" for k in range(N))

    def __len__(self) -> int:
        return N


def _design(n: int, seed: int) -> np.ndarray:
    return trace_fit.global_stage(SimpleNamespace(model=_Model(), weight=W_PRIOR), n, 1, seed,
                                  None)[0]  # fmt: skip


class _Basin:
    """A square basin in (x0, x1) around one point of the doubled design's ``half`` (0:
    the first design, 1: the new half), far from the prior (|x| > 1.6 σ, beyond the hops'
    ±1 σ) and narrower than its distance from every point of the other half; flat
    elsewhere, so only a start in it descends into it."""

    def __init__(self, seed: int, half: int = 1):
        full = _design(2 * N_FIRST, seed)[:, :2]
        own, other = (full[N_FIRST:], full[:N_FIRST]) if half else (full[:N_FIRST], full[N_FIRST:])
        gaps = [np.min(np.max(np.abs(other - p), axis=1)) for p in own]
        far = [k for k in range(len(own)) if np.max(np.abs(own[k])) > 1.6]
        k = max(far, key=lambda i: gaps[i])
        self.centre, self.radius = own[k], min(0.9 * gaps[k], 0.3)

    def inside(self, x: np.ndarray) -> bool:
        return bool(np.max(np.abs(np.asarray(x)[:2] - self.centre)) < self.radius)

    def cost(self, x: np.ndarray) -> float:
        x = np.asarray(x, dtype=float)
        if self.inside(x):
            return DEEP + float(np.sum((x[:2] - self.centre) ** 2)) + 0.01 * float(
                np.sum(x[2:] ** 2))  # fmt: skip
        return PLATEAU + 0.01 * float(np.sum(x[2:] ** 2))

    def fit(self, x: np.ndarray) -> LocalFit:
        """Least squares descends within the basin it starts in (flat in x0, x1 outside)."""
        x = np.asarray(x, dtype=float).copy()
        x[2:] = 0.0
        if self.inside(x):
            x[:2] = self.centre
        c = self.cost(x)
        return LocalFit(x, {}, np.full(N, 0.1), {}, c, c, c, 1)


def _landscape(monkeypatch, seed: int, half: int = 1):
    basin = _Basin(seed, half)
    seen: dict[str, Any] = {"designs": [], "weights": [], "fits": 0}

    def objectives(p, pts, _w, _b, *_e):
        """The design's costs scale with the data weight in force, as the trace's do."""
        seen["designs"].append(np.asarray(pts))
        seen["weights"].append(p.weight)
        return p.weight**2 * np.array([basin.cost(x) for x in pts])

    def reweight(p, *_a):
        p.weight = W_DATA

    def local_fits(_p, starts, *_a):
        seen["fits"] += len(starts)
        return [basin.fit(x) for x in starts]

    monkeypatch.setattr(trace_fit, "_objectives", objectives)
    monkeypatch.setattr(trace_fit, "_local_fits", local_fits)
    monkeypatch.setattr(trace_fit, "_reweight", reweight)
    monkeypatch.setattr(trace_fit, "local_fit", lambda _p, x, *_a, **_k: basin.fit(x))
    problem = SimpleNamespace(model=_Model(), weight=W_PRIOR,
                              objective=lambda x, *_e: basin.cost(x))  # fmt: skip
    return problem, basin, seen


@pytest.fixture(params=[0, 1, 2], ids=lambda s: f"seed{s}")
def landscape(request, monkeypatch):
    return (*_landscape(monkeypatch, request.param), request.param)


def _first(problem, seed: int) -> trace_fit._Design:
    pts, vals = trace_fit.global_stage(problem, N_FIRST, 1, seed, None)
    return trace_fit._Design(np.zeros(N), W_PRIOR, pts, vals, 3)


def _quiet(_m: str) -> None:
    return None


@pytest.mark.parametrize("seed", [0, 7])
def test_the_two_stages_together_are_the_doubled_design(seed):
    full = _design(2 * N_FIRST, seed)
    problem = SimpleNamespace(model=_Model(), weight=W_PRIOR)
    second = trace_fit.global_stage(problem, 2 * N_FIRST, 1, seed, None, first=N_FIRST)[0]
    np.testing.assert_array_equal(_design(N_FIRST, seed), full[:N_FIRST])
    np.testing.assert_array_equal(second, full[N_FIRST:])
    assert np.all(np.abs(full) <= GLOBAL_BOX + 1e-12)


def test_the_first_stages_search_misses_the_basin(landscape):
    """The landscape's premise, and the first stage's whole search on it: no point of the
    first design lies in the basin, and its starts, passes and hops (±1 σ at most) all end
    on the plateau, so only another design can find the basin."""
    problem, basin, _seen, seed = landscape
    first = _first(problem, seed)
    assert not any(basin.inside(x) for x in first.pts)
    assert np.all(first.vals >= PLATEAU)  # every point on the plateau: no start descends
    fits, best, hops = trace_fit._search_design(problem, first, 0.01, 1, seed, _quiet, HOPS)
    assert len(fits) == 1 + first.starts and not basin.inside(best.x)
    assert best.cost == pytest.approx(PLATEAU) and not any(h["accepted"] for h in hops)


def test_the_second_stage_reaches_the_basin_and_keeps_it(landscape):
    problem, basin, seen, seed = landscape
    first = _first(problem, seed)
    best = basin.fit(np.zeros(N))  # the first stage's optimum, on the plateau
    problem.weight = W_DATA  # as the first stage leaves it
    n_seen = len(seen["designs"])
    found, row = trace_fit._second_stage(problem, best, first, (0.01, 0.5), 1, (seed, HOPS),
                                         None, _quiet)  # fmt: skip
    np.testing.assert_array_equal(seen["designs"][n_seen],
                                  _design(2 * N_FIRST, seed)[N_FIRST:])  # fmt: skip
    assert seen["weights"][n_seen] == W_PRIOR, "the new half ranked with the first's weight"
    assert row["points"] == 2 * N_FIRST and row["box_sigma"] == GLOBAL_BOX
    assert row["new_starts"] >= 1 and len(row["costs"]) == 1 + first.starts  # and the prior
    _fits, kept, hops = found
    assert row["kept"] and basin.inside(kept.x) and row["hops"] == hops
    assert kept.cost == pytest.approx(DEEP) == row["cost_after"]
    assert row["cost_before"] == pytest.approx(best.cost)
    assert kept.cost < (1.0 - HOP_TOL) * row["cost_before"]
    assert row["heldout_rms"] == kept.heldout_rms


def test_a_second_stage_that_finds_nothing_better_is_not_kept(landscape):
    """The first stage already sits in the basin: the second stage finds it again, at the
    same cost, and is not kept."""
    problem, basin, _seen, seed = landscape
    best = basin.fit(np.r_[basin.centre, np.zeros(N - 2)])
    found, row = trace_fit._second_stage(problem, best, _first(problem, seed), (0.01, 0.1), 1,
                                         (seed, HOPS), None, _quiet)  # fmt: skip
    assert found is not None and not row["kept"] and row["heldout_rms"] == best.heldout_rms
    assert row["cost_after"] >= (1.0 - HOP_TOL) * row["cost_before"]


@pytest.mark.parametrize("seed", [0, 1])
def test_the_search_is_not_repeated_where_the_best_starts_are_the_first_designs(monkeypatch,
                                                                                 seed):  # fmt: skip
    """The basin lies at a point of the first design: the doubled design's best start (one
    here) is the first's, so the search would repeat itself, and no fit runs."""
    problem, basin, seen = _landscape(monkeypatch, seed, half=0)
    first = _first(problem, seed)._replace(starts=1)
    best = basin.fit(np.r_[basin.centre, np.zeros(N - 2)])
    found, row = trace_fit._second_stage(problem, best, first, (0.01, 0.1), 1, (seed, HOPS),
                                         None, _quiet)  # fmt: skip
    assert found is None and row["new_starts"] == 0 and seen["fits"] == 0
    assert not row["kept"] and row["heldout_rms"] == best.heldout_rms


@pytest.mark.parametrize(("target", "runs"), [(2.0, False), (0.5, True)])
def test_the_nominal_fit_searches_further_only_above_its_target(landscape, target, runs):
    """The prior (x = 0) and the first design's starts all end on the plateau (cost 1):
    with a target above that, no second stage; below it, the second stage runs and its
    basin is the nominal model."""
    problem, _basin, seen, seed = landscape
    nominal, spread = trace_fit._fit_nominal(problem, np.zeros(N), (0.01, target), N_FIRST,
                                             3, 1, seed, None, _quiet)  # fmt: skip
    assert (spread["second"] is not None) is runs
    assert nominal.cost == pytest.approx(DEEP if runs else PLATEAU)
    designs = [w for d, w in zip(seen["designs"], seen["weights"], strict=True)
               if len(d) == N_FIRST]  # the global stages (a hop's cloud has 16 points)
    assert designs == [W_PRIOR] * (2 if runs else 1)


@pytest.mark.parametrize("kept", [True, False])
def test_report_states_the_second_stage_and_whether_it_was_kept(kept):
    """report.md: the second stage's line (its design, the costs its starts reached, its
    hopped optimum against the first stage's, kept or not) and its hops' table; a line
    saying it did not run where its starts were the first's; nothing without it."""
    from turntable_env.calibration.calibrate import _md_second

    hop = {"radius_sigma": 0.5, "cost_before": 30.2, "costs": [29.0], "accepted": kept,
           "heldout_rms": 18.5}  # fmt: skip
    row = {"points": 128, "box_sigma": GLOBAL_BOX, "new_starts": 2, "cost_before": 41.7,
           "cost_after": 29.0 if kept else 41.5, "heldout_before": 21.3,
           "costs": [30.2, 44.0], "kept": kept, "hops": [hop],
           "heldout_rms": 18.5 if kept else 21.3}  # fmt: skip
    text = "\n".join(_md_second(row, "nm"))
    assert ("21.3 nm, stayed above the target): the design doubled to 128 Sobol points "
            "over ±2.5 prior σ, 2 of its best starts new") in text  # fmt: skip
    after = 29 if kept else 41.5
    assert f"costs 30.2, 44, hopped to {after} against the first stage's 41.7" in text
    assert ("; kept (held-out 18.5 nm)" in text) is kept
    assert ("not kept (held-out 21.3 nm)" in text) is not kept
    assert "Basin hopping from the second stage's best start" in text
    none = "\n".join(_md_second({**row, "new_starts": 0}, "nm"))
    assert "0 of its best starts new: the search would repeat the first stage's" in none
    assert _md_second(None, "nm") == []
