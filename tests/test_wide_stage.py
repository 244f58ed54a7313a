"""The nominal fit's second, wider global stage (:func:`trace_fit._wide_stage`), on a
landscape like a current limit's: the objective is flat around the datasheet and changes
only once the limit binds, in a basin past the first design's ±``GLOBAL_BOX`` prior σ.
The contract: the second design spans ±``WIDE_BOX`` σ with twice the first's points; it
runs only when the nominal fit stays above its target; it is kept only when it lowers
the cost by ``HOP_TOL``; and it reaches a basin the first design cannot."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from turntable_env.calibration import trace_fit
from turntable_env.calibration.trace_fit import (
    GLOBAL_BOX,
    HOP_TOL,
    HOPS,
    TRACE_NOMINAL,
    WIDE_BOX,
    LocalFit,
)

N = len(TRACE_NOMINAL)  # the real model's dimension: twelve ln-factors, prior σ 1 here
BINDS = -2.8  # the limit binds below this ln-factor (past the first design's box)
PLATEAU, DEEP = 1.0, 0.2  # costs on the flat datasheet side and in the binding basin


def _cost(x: np.ndarray) -> float:
    x = np.asarray(x, dtype=float)
    if x[0] < BINDS:  # the binding basin, lowest at x0 = −3.1
        return DEEP + 0.5 * (x[0] + 3.1) ** 2 + 0.01 * float(np.sum(x[1:] ** 2))
    return PLATEAU + 0.01 * float(np.sum(x[1:] ** 2))  # flat in x0: the limit never binds


def _fit(x: np.ndarray) -> LocalFit:
    """Least squares descends within the basin it starts in (flat in x0 on the plateau)."""
    x = np.asarray(x, dtype=float).copy()
    x[1:] = 0.0
    if x[0] < BINDS:
        x[0] = -3.1
    c = _cost(x)
    return LocalFit(x, {}, np.full(N, 0.1), {}, c, c, c, 1)


@pytest.fixture
def landscape(monkeypatch):
    problem = SimpleNamespace(model=_Model())
    seen: dict[str, list] = {"designs": []}

    def objectives(_p, pts, _w, _b, *_e):
        seen["designs"].append(np.asarray(pts))
        return np.array([_cost(x) for x in pts])

    monkeypatch.setattr(trace_fit, "_objectives", objectives)
    monkeypatch.setattr(trace_fit, "_local_fits",
                        lambda _p, starts, *_a: [_fit(x) for x in starts])  # fmt: skip
    return problem, seen


class _Model:
    """A nominal model stand-in: prior σ 1 and bounds ±5 on every ln-factor."""

    sigma, low, high = np.ones(N), np.full(N, -5.0), np.full(N, 5.0)

    def __len__(self) -> int:
        return N


def test_the_first_design_cannot_reach_the_binding_basin(landscape):
    problem, _seen = landscape
    pts, vals = trace_fit.global_stage(problem, 64, 1, 0, None)
    assert np.all(np.abs(pts) <= GLOBAL_BOX + 1e-12)
    assert np.all(vals >= PLATEAU)  # every point on the plateau: no start can bind


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_wide_stage_reaches_the_basin_past_the_first_box_and_keeps_it(landscape, seed):
    problem, seen = landscape
    best = _fit(np.zeros(N))  # the first stage's optimum, flat on the datasheet side
    kept, row = trace_fit._wide_stage(problem, best, 0.5, (64, 3), 1, seed, None,
                                      lambda _m: None, HOPS)  # fmt: skip
    design = seen["designs"][0]
    assert len(design) == 2 * 64 == row["points"]
    assert np.all(np.abs(design) <= WIDE_BOX + 1e-12)
    assert design[:, 0].min() < -GLOBAL_BOX  # the box is wider than the first
    assert row["kept"] and kept.x[0] < BINDS
    assert kept.cost == pytest.approx(DEEP) and kept.cost < (1.0 - HOP_TOL) * best.cost
    assert row["heldout_rms"] == kept.heldout_rms and row["cost_before"] == best.cost


def test_a_wide_stage_that_finds_nothing_better_is_not_kept(landscape):
    problem, _seen = landscape
    best = _fit(np.r_[-3.1, np.zeros(N - 1)])  # already in the binding basin
    kept, row = trace_fit._wide_stage(problem, best, 0.1, (64, 3), 1, 0, None,
                                      lambda _m: None, HOPS)  # fmt: skip
    assert kept is best and not row["kept"] and row["hops"] == []
    assert min(row["costs"]) >= (1.0 - HOP_TOL) * best.cost


@pytest.mark.parametrize(("target", "runs"), [(2.0, False), (0.5, True)])
def test_the_nominal_fit_searches_wider_only_above_its_target(landscape, monkeypatch,
                                                              target, runs):  # fmt: skip
    """The prior (x = 0) and the first design's starts all end on the plateau (cost 1):
    with a target above that, no second stage; below it, the second stage runs and its
    basin is the nominal model."""
    problem, _seen = landscape
    monkeypatch.setattr(trace_fit, "_reweight", lambda *_a: None)
    monkeypatch.setattr(trace_fit, "local_fit", lambda _p, x, *_a, **_k: _fit(x))
    nominal, spread = trace_fit._fit_nominal(problem, np.zeros(N), (0.01, target), 64, 3, 1,
                                             0, None, lambda _m: None)  # fmt: skip
    assert (spread["wide"] is not None) is runs
    assert nominal.cost == pytest.approx(DEEP if runs else PLATEAU)


@pytest.mark.parametrize("kept", [True, False])
def test_report_states_the_second_stage_and_whether_it_was_kept(kept):
    """report.md: the second stage's line (its design, the costs its starts reached
    against the first stage's, kept or not) and its hops' table; nothing without it."""
    from turntable_env.calibration.calibrate import _md_wide

    hop = {"radius_sigma": 0.5, "cost_before": 30.2, "costs": [29.0], "accepted": True,
           "heldout_rms": 18.5}  # fmt: skip
    row = {"points": 128, "box_sigma": WIDE_BOX, "cost_before": 41.7, "heldout_before": 21.3,
           "costs": [30.2, 44.0], "kept": kept, "hops": [hop] if kept else [],
           "heldout_rms": 18.5 if kept else 21.3}  # fmt: skip
    text = "\n".join(_md_wide(row, "nm"))
    assert "21.3 nm, stayed above the target): 128 Sobol points over ±3.5 prior σ" in text
    assert "costs 30.2, 44 against 41.7" in text
    assert ("; kept (held-out 18.5 nm)" in text) is kept
    assert ("not kept (held-out 21.3 nm)" in text) is not kept
    assert ("Basin hopping from the second stage's best start" in text) is kept
    assert _md_wide(None, "nm") == []
