"""One BLAS thread for the small dense linear algebra of building a model.

OpenBLAS splits even a 10×10 product across its worker threads. Where the machine's cores
are busy (a calibration's workers, pytest-xdist, a vector env beside a trainer), those
threads spin and wait for one another: scipy's ``expm`` of one of the reduced model's
10×10 matrices took 15 ms instead of 30 µs, and building a per-axis model (its transition
ladders, :class:`~turntable_env.reduced.ReducedModel`) 1.16 s instead of 0.03 s, beside two
busy processes on a 2-core machine. The results are the same bit for bit
(``tests/test_threads.py``). The trace calibration already ran with one thread
(:func:`~turntable_env.calibration.calibrate.calibrate`); this covers every other caller —
the env's randomised resets, the batched simulations, the controllers' plants.
"""

from __future__ import annotations

import functools
from contextlib import AbstractContextManager
from typing import Any

import threadpoolctl

__all__ = ["one_blas_thread"]


@functools.cache
def _controller() -> threadpoolctl.ThreadpoolController:
    """The BLAS libraries loaded with numpy and scipy, found once (a scan of the process's
    libraries costs about 2 ms; limiting through the found controller about 0.15 ms)."""
    return threadpoolctl.ThreadpoolController()


def one_blas_thread() -> AbstractContextManager[Any]:
    """A context in which BLAS (OpenBLAS, MKL, BLIS) runs on one thread; the caller's
    setting is restored on exit."""
    return _controller().limit(limits=1, user_api="blas")
