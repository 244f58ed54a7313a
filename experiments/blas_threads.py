"""Building the per-axis model with BLAS on one thread or on its default threads, side by
side in one run, on a quiet machine or beside ``--busy N`` processes that keep N cores
busy (as a calibration's workers, pytest-xdist or a trainer do).

    python experiments/blas_threads.py [--busy 2] [--builds 10]

Prints the median wall time of one :class:`~turntable_env.reduced.ReducedModel` build
(a randomised env reset builds one) each way, their ratio, and whether the two models are
the same bit for bit. The build limits itself to one thread (:mod:`turntable_env.threads`);
the default-threads row switches that off.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing as mp
import statistics
import time

import numpy as np

from turntable_env import reduced
from turntable_env.plant import Plant
from turntable_env.threads import one_blas_thread


def _spin(stop: mp.synchronize.Event) -> None:
    """A busy neighbour as a scientific process is one: small products on its own BLAS
    threads, back to back."""
    a = np.random.default_rng(0).random((64, 64))
    while not stop.is_set():
        a = np.tanh(a @ a)


def _builds(n: int, limited: bool) -> tuple[float, reduced.ReducedModel]:
    reduced.one_blas_thread = one_blas_thread if limited else contextlib.nullcontext
    times, model = [], None
    for i in range(n):
        ps = Plant("real", factors={"friction": 1.0 + 0.01 * i}).params  # a new plant each
        t0 = time.perf_counter()
        model = reduced.ReducedModel(ps, "B")
        times.append(time.perf_counter() - t0)
    reduced.one_blas_thread = one_blas_thread
    assert model is not None
    return statistics.median(times), model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--busy", type=int, default=0, help="busy processes beside the builds")
    ap.add_argument("--builds", type=int, default=10, help="builds each way (median)")
    args = ap.parse_args()
    if not 0 <= args.busy <= 64 or not 1 <= args.builds <= 1000:
        ap.error("--busy must lie in 0-64 and --builds in 1-1000")
    _builds(1, True)  # compile and cache what the first build would
    stop = mp.Event()
    procs = [mp.Process(target=_spin, args=(stop,), daemon=True) for _ in range(args.busy)]
    for p in procs:
        p.start()
    try:
        t_one, m_one = _builds(args.builds, True)
        t_dft, m_dft = _builds(args.builds, False)
    finally:
        stop.set()
        for p in procs:
            p.join()
    same = all(
        np.array_equal(v, m_dft.packed[k])
        for k, v in m_one.packed.items()
        if isinstance(v, np.ndarray)
    )
    print(f"busy processes: {args.busy}; builds each way: {args.builds}")
    print(f"one BLAS thread:      {t_one * 1e3:9.1f} ms per build (median)")
    print(f"default BLAS threads: {t_dft * 1e3:9.1f} ms per build (median)")
    print(f"ratio default / one:  {t_dft / t_one:9.1f}x; same bit for bit: {same}")


if __name__ == "__main__":
    main()
