"""Independent jobs at once: Ray tasks when Ray is installed, local processes otherwise.

Every scale-out in the project goes through :func:`map_tasks`: training seeds and
hyperparameter trials (:mod:`agents.scale`, :mod:`agents.tune`), benchmark cells
(:func:`controllers.benchmark.run_benchmark` with ``backend``) and calibration sweeps
(``experiments/independent_calibration.py``). No scheduler of our own: with Ray
(``pip install -e ".[scale]"``) each job is a Ray task of ``num_cpus`` CPUs — ``ray.init()``
starts a local instance on this machine by default, ``address`` joins a cluster
(``"auto"`` on a cluster node, ``"ray://head:10001"`` from outside); without Ray, or with
``backend="processes"``, the jobs go to a ``concurrent.futures.ProcessPoolExecutor`` of
spawned processes (``fn`` must be importable, or defined in a script that guards its
``main()``), each of which ends itself once the process that started it has gone
(:func:`_watch_parent`: a run killed, even by SIGKILL, leaves no worker finishing a job and
writing its results after it).
The results come back in the jobs' order, so a parallel run equals the serial one.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import multiprocessing
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

__all__ = ["BACKENDS", "has_ray", "map_tasks", "resolve_backend", "session"]

BACKENDS = ("auto", "ray", "processes")

T = TypeVar("T")
R = TypeVar("R")


def has_ray() -> bool:
    """Whether Ray (the ``scale`` extra) is importable."""
    return importlib.util.find_spec("ray") is not None


def resolve_backend(backend: str, address: str | None = None) -> str:
    """``"ray"`` or ``"processes"`` for a requested backend; ValueError (naming the
    option) when it cannot be had — checked before any job starts."""
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r}: must be one of {', '.join(BACKENDS)}")
    ray = has_ray()
    if backend == "ray" and not ray:
        raise ValueError('backend="ray": Ray is not installed (pip install -e ".[scale]")')
    if address is not None:
        if not isinstance(address, str) or not address.strip():
            raise ValueError(f"address={address!r}: must be a non-empty string")
        if not ray:
            raise ValueError(f"address={address!r}: joining a cluster needs Ray (the scale extra)")
        if backend == "processes":
            raise ValueError(f"address={address!r}: a cluster needs backend 'ray' or 'auto'")
        _check_reachable(address)
    return "ray" if ray and backend != "processes" else "processes"


# seconds a cluster's head may take to accept a connection before its address is refused
CONNECT_TIMEOUT = 5.0


@functools.lru_cache(maxsize=8)
def _check_reachable(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """A cluster address ``host:port`` or ``ray://host:port`` must accept a TCP connection
    within ``timeout`` s: ``ray.init`` retries an address nobody answers for minutes,
    with SIGTERM held off meanwhile, so the address is refused here, before any job
    starts (ValueError naming it and the socket's error). ``"auto"``, ``"local"`` and
    forms without a numeric port are left to Ray. An address that answered is not
    dialled again in this process (the caller's check, :func:`map_tasks` and
    :func:`session` each resolve the backend); a refusal is not cached."""
    host, sep, port = address.strip().removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit():
        return
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            pass
    except (OSError, OverflowError) as exc:
        why = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise ValueError(f"address={address!r}: no Ray cluster answers at {host}:{port} "
                         f"({why})") from None  # fmt: skip


def map_tasks(
    fn: Callable[[T], R],
    jobs: Sequence[T],
    *,
    backend: str = "auto",
    address: str | None = None,
    workers: int | None = None,
    num_cpus: float = 1.0,
) -> list[R]:
    """``[fn(j) for j in jobs]``, each call a Ray task or a process (module docstring).

    Args:
        fn: a module-level function (pickled by reference) of one picklable argument.
        backend: ``"auto"`` (Ray if installed), ``"ray"`` or ``"processes"``.
        address: a Ray cluster to join (None: a local instance, shut down afterwards).
        workers: processes for the process backend (default: the CPUs this process may use).
        num_cpus: CPUs Ray reserves for each task.
    """
    kind = resolve_backend(backend, address)
    bad_workers = isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    if workers is not None and bad_workers:
        raise ValueError(f"workers={workers!r}: must be an integer >= 1")
    if not num_cpus > 0:
        raise ValueError(f"num_cpus={num_cpus!r}: must be > 0")
    jobs = list(jobs)
    if not jobs:
        return []
    if kind == "ray":
        return _with_ray(fn, jobs, address, num_cpus)
    n = workers or len(os.sched_getaffinity(0))
    # spawn, not fork: a fork after torch, the kernels or BLAS started threads can deadlock
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(n, len(jobs)), mp_context=spawn,
                             initializer=_watch_parent, initargs=(os.getpid(),)) as pool:
        return list(pool.map(fn, jobs))


PARENT_POLL_S = 0.5  # s between a process worker's checks that its parent still runs


def _watch_parent(parent: int) -> None:
    """Initializer of :func:`map_tasks`' process workers: a daemon thread ends the worker
    (exit status 143) once its parent ``parent`` (a PID) is gone and it has been re-parented.
    Without it a worker whose parent was killed runs its job to the end and writes what a
    later run of the same command may already have written (stop 107: an orphaned
    calibration rewrote a row's report.json)."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(143)

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


@contextlib.contextmanager
def session(backend: str = "auto", address: str | None = None) -> Iterator[str]:
    """Hold one Ray instance (local, or the cluster ``address`` names) across several
    :func:`map_tasks` calls — a search's rounds — instead of one per call; shut down on
    exit if this call started it. Yields the resolved backend; no-op for processes."""
    kind = resolve_backend(backend, address)
    started = False
    if kind == "ray":
        import ray

        if not ray.is_initialized():
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
            started = True
    try:
        yield kind
    finally:
        if started:
            import ray

            ray.shutdown()


def _with_ray(fn: Callable[[Any], Any], jobs: list[Any], address: str | None, cpus: float) -> list:
    import ray

    with session("ray", address):
        task = ray.remote(num_cpus=cpus)(fn)
        return ray.get([task.remote(j) for j in jobs])
