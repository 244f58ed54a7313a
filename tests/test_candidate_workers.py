"""The nominal fit's starts and the effect rounds' candidate searches over worker
processes (issue 31: a 2.5 s trace calibrates in under 5 minutes on 2 cores): each fit and
each search is deterministic, so what the calibration sees — optima, values, profiles,
gains, the screened held-out errors — must not depend on how many processes ran them, and
the simulations the workers ran are counted."""

from __future__ import annotations

import numpy as np
import pytest

from turntable_env.calibration.nominal import NominalModel
from turntable_env.calibration.trace_fit import (
    TRACE_NOMINAL,
    TraceProblem,
    _Candidates,
    _local_fits,
    _prepare,
    local_fit,
    signature_search,
)
from turntable_env.calibration.virtual_lab import run_virtual_lab
from turntable_env.plant import Plant

# one output-stage candidate (the cached angle) and one on the input stage (re-simulated)
NAMES = ["sensor_drift", "piezo_creep"]


@pytest.fixture(scope="module")
def trace():
    m = run_virtual_lab("standard", {"piezo_creep": {"gamma": 0.03}}, noise_std=1e-3, seed=2)
    return _prepare(m)[0]


def _rounds(trace, workers: int) -> tuple[list, list, int]:
    # a new problem each time: its cache of simulations starts empty
    problem = TraceProblem([trace], NominalModel(Plant("real", fidelity="reduced"), TRACE_NOMINAL))
    x = np.zeros(len(problem.model))
    current = local_fit(problem, x, {}, free_effects=(), max_nfev=1)
    search = signature_search(problem)
    search.find_lines(x, {})
    base = search.features(x, {})
    n0 = problem.n_sims
    with _Candidates(problem, search, workers) as pool:
        sig = pool.run([("signature", n, x, {}, base) for n in NAMES])
        scr = pool.run([("screen", n, x, current, None) for n in NAMES])
    return sig, scr, problem.n_sims - n0


@pytest.mark.slow  # the default tier's 5 CPU minutes (stop 48): process pools, 15 and 12 s
def test_candidate_searches_do_not_depend_on_the_workers(trace):
    sig1, scr1, sims1 = _rounds(trace, 1)
    sig2, scr2, sims2 = _rounds(trace, 2)
    assert [f.to_json() for f in sig1] == [f.to_json() for f in sig2]
    # the screens' least squares agree up to the last bits of a sum: a worker's BLAS runs
    # on one thread, the main process's on several (2.9379957813696906 against
    # 2.9379957813693327 nm once, beside a calibration on the other core)
    for a, b in zip(scr1, scr2, strict=True):
        assert a.heldout_rms == pytest.approx(b.heldout_rms, rel=1e-9)
        assert a.effects.keys() == b.effects.keys()
        for name, values in a.effects.items():
            assert values == pytest.approx(b.effects[name], rel=1e-9)
    # creep is found on its own signature, not at its neutral value
    creep = next(f for f in sig1 if f.name == "piezo_creep")
    assert not creep.at_neutral and creep.values["gamma"] > 0.0
    # the workers' simulations are counted: the main process runs none of the searches
    assert sims1 > 0 and sims2 > 0


@pytest.mark.slow  # the default tier's 5 CPU minutes (stop 48): process pools, 15 and 12 s
def test_nominal_starts_do_not_depend_on_the_workers(trace):
    """The nominal fit's starts over worker processes: the same optima, in order, as one
    after another, and the workers' simulations counted."""
    problem = TraceProblem([trace], NominalModel(Plant("real", fidelity="reduced"), TRACE_NOMINAL))
    n = len(problem.model)
    starts = [np.zeros(n), np.full(n, 0.2), np.full(n, -0.2)]
    one = _local_fits(problem, starts, 1, max_nfev=2)
    problem2 = TraceProblem([trace], problem.model)
    two = _local_fits(problem2, starts, 2, max_nfev=2)
    for a, b in zip(one, two, strict=True):
        # the same optimum; the last bits of a sum may differ (a worker's BLAS runs on one
        # thread)
        np.testing.assert_allclose(a.x, b.x, rtol=1e-9, atol=1e-12)
        assert a.cost == pytest.approx(b.cost, rel=1e-9)
    assert problem2.n_sims > 0
    # the starts moved: each fit is its own start's, not the first one's copied
    assert len({round(f.cost, 9) for f in two}) == len(starts)


@pytest.mark.slow  # the default tier's 5 CPU minutes: a process pool
def test_a_fits_finite_differences_over_workers_give_the_same_fit(trace):
    """local_fit(pool=...) evaluates the Jacobian's perturbed points in the workers (the
    polish, the effect rounds' refits): the same fit number for number as in one process
    — every evaluation is the one this process would make — with the workers'
    simulations counted."""
    from concurrent.futures import ProcessPoolExecutor

    from turntable_env.calibration.trace_fit import _init_worker

    model = NominalModel(Plant("real", fidelity="reduced"), TRACE_NOMINAL)
    x0 = np.full(len(model), 0.1)
    eff = {"piezo_creep": {"gamma": 0.01}}
    serial_pb = TraceProblem([trace], model)
    one = local_fit(serial_pb, x0, eff, free_effects=("piezo_creep",), max_nfev=2)
    pooled_pb = TraceProblem([trace], model)
    with ProcessPoolExecutor(2, initializer=_init_worker, initargs=(pooled_pb,)) as ex:
        two = local_fit(pooled_pb, x0, eff, free_effects=("piezo_creep",), max_nfev=2, pool=ex)
    np.testing.assert_array_equal(one.x, two.x)
    assert one.effects == two.effects and one.cost == two.cost and one.nfev == two.nfev
    np.testing.assert_array_equal(one.std_x, two.std_x)
    assert one.std_effects == two.std_effects
    # the optimum's errors, which the worker that evaluated it returns with its residual
    assert (one.heldout_rms, one.fit_rms) == (two.heldout_rms, two.fit_rms)
    # the fit moved (its Jacobian was used), and every simulation is counted where it ran
    assert not np.array_equal(one.x, x0)
    assert pooled_pb.n_sims == serial_pb.n_sims


def test_a_problem_counts_from_threads_and_travels_without_its_caches(trace):
    """The fits driven side by side by threads (:func:`_local_fits`) count the workers'
    simulations into one problem: no count is lost between threads; a copy sent to a
    worker carries the weight and no cache (it simulates again) and a lock of its own."""
    import pickle
    import threading

    problem = TraceProblem([trace], NominalModel(Plant("real", fidelity="reduced"), TRACE_NOMINAL))
    problem.weight = 0.37
    x = np.zeros(len(problem.model))
    cost = problem.objective(x)
    assert problem.n_sims == 1
    copy = pickle.loads(pickle.dumps(problem))
    assert copy.weight == 0.37 and copy.n_sims == 1
    assert copy.objective(x) == cost and copy.n_sims == 2  # simulated again: no cache
    assert problem.objective(x) == cost and problem.n_sims == 1  # the original's cache

    def add() -> None:
        for _ in range(2000):
            problem.count(1)

    threads = [threading.Thread(target=add) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert problem.n_sims == 1 + 8 * 2000


def test_a_fit_frees_only_the_named_nominal_parameters(trace):
    """local_fit(free_nominal=names): those ln-factors move, the others stay where they
    were, bit for bit, with their prior σ; every name is the whole model; an unknown name
    is a ValueError naming it (wear's screen frees the friction level alone)."""
    problem = TraceProblem([trace], NominalModel(Plant("real", fidelity="reduced"), TRACE_NOMINAL))
    mdl = problem.model
    x = np.full(len(mdl), 0.05)
    f = local_fit(problem, x, {}, free_nominal=("friction",), max_nfev=3)
    i = mdl.names.index("friction")
    others = np.arange(len(mdl)) != i
    assert f.x[i] != x[i]
    np.testing.assert_array_equal(f.x[others], x[others])
    np.testing.assert_array_equal(f.std_x[others], mdl.sigma[others])
    a = local_fit(problem, x, {}, free_nominal=mdl.names, max_nfev=1)
    b = local_fit(problem, x, {}, free_nominal=True, max_nfev=1)
    np.testing.assert_array_equal(a.x, b.x)
    with pytest.raises(ValueError, match="'friction_level'"):
        local_fit(problem, x, {}, free_nominal=("friction_level",), max_nfev=1)
