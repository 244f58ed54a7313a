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
def test_a_model_built_on_one_thread_is_the_same_bit_for_bit(translation, monkeypatch):
    """The ladders exp(A·h·2^r) and the modal data do not depend on how BLAS splits its
    work: a model built on two BLAS threads (the limit switched off) equals the one built
    on one, so limiting changed no result of the env, the benchmark or the tables."""
    ps = Plant("real", factors={"friction": 1.07, "preload": 0.93}).params
    limited = ReducedModel(ps, "B", translation=translation)
    monkeypatch.setattr(reduced, "one_blas_thread", contextlib.nullcontext)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        free = ReducedModel(ps, "B", translation=translation)
    arrays = [k for k, v in limited.packed.items() if isinstance(v, np.ndarray)]
    assert len(arrays) >= 5
    for k in arrays:
        assert np.array_equal(limited.packed[k], free.packed[k]), k
