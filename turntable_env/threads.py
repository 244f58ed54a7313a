"""One BLAS thread for the small dense linear algebra of building a model.

OpenBLAS splits even a 10×10 product across its worker threads. Where the machine's cores
are busy (a calibration's workers, pytest-xdist, a vector env beside a trainer), a thread
can wait for a core: building a per-axis model (scipy's ``expm`` ladders of
:class:`~turntable_env.reduced.ReducedModel`) took 603 ms instead of 15 ms beside two
calibration runs on a 2-core machine, and 5.9 ms either way on the quiet machine
(``python experiments/blas_threads.py``; docs/performance.md, stop 74). The results are the
same bit for bit (``tests/test_threads.py``). The trace calibrations run under it too
(:func:`~turntable_env.calibration.calibrate.calibrate`, the summary fit), and so do the
env's randomised resets, the batched simulations and the controllers' plants.
"""

from __future__ import annotations

import functools
from contextlib import AbstractContextManager
from typing import Any

import threadpoolctl

__all__ = ["one_blas_thread"]


@functools.cache
def _controller() -> threadpoolctl.ThreadpoolController:
    """The BLAS libraries loaded with numpy and scipy, found once: a new scan of the
    process's libraries at every build would cost more than the limit saves when quiet."""
    return threadpoolctl.ThreadpoolController()


def one_blas_thread() -> AbstractContextManager[Any]:
    """A context in which BLAS (OpenBLAS, MKL, BLIS) runs on one thread; the caller's
    setting is restored on exit."""
    return _controller().limit(limits=1, user_api="blas")
