"""One BLAS thread for model building (turntable_env/threads.py): the thread setting is
the caller's again afterwards, and a model built under it is the same bit for bit."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
import threadpoolctl

from turntable_env import reduced
from turntable_env.plant import Plant
from turntable_env.reduced import ReducedModel
from turntable_env.threads import one_blas_thread


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"]


def test_one_thread_inside_and_the_callers_setting_after():
    before = _blas_threads()
    assert before, "numpy and scipy load a BLAS library"
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        outer = _blas_threads()
        with one_blas_thread():
            assert _blas_threads() == [1] * len(outer)
        assert _blas_threads() == outer
    assert _blas_threads() == before


@pytest.mark.parametrize("translation", [False, True])
def test_a_model_is_the_same_whatever_threads_the_caller_allows(translation, monkeypatch):
    """The ladders exp(A·h·2^r) and the modal data are built on one BLAS thread: a model
    built where the caller allows two threads is the same bit for bit as one built where
    it allows one, so the env, the benchmark and the tables do not depend on the caller's
    thread setting. Built without the limit on two threads, the model may differ in its
    last bits: how BLAS splits a product changes the order of its sums (on an AMD EPYC
    with OpenBLAS's Haswell kernels the translation form's ladders moved, stop 79; on the
    machine that added the limit they did not), and it agrees within 1e-9 of each array's
    scale, kernel_golden's tolerance."""
    ps = Plant("real", factors={"friction": 1.07, "preload": 0.93}).params
    with threadpoolctl.threadpool_limits(limits=1, user_api="blas"):
        one = ReducedModel(ps, "B", translation=translation)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        limited = ReducedModel(ps, "B", translation=translation)
    monkeypatch.setattr(reduced, "one_blas_thread", contextlib.nullcontext)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        free = ReducedModel(ps, "B", translation=translation)
    arrays = [k for k, v in limited.packed.items() if isinstance(v, np.ndarray)]
    assert len(arrays) >= 5
    for k in arrays:
        assert np.array_equal(limited.packed[k], one.packed[k]), k
        scale = float(np.max(np.abs(limited.packed[k]), initial=0.0))
        assert np.max(np.abs(limited.packed[k] - free.packed[k]), initial=0.0) <= 1e-9 * scale, k
