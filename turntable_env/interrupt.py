"""Ctrl-C that stops a compiled run: a kernel in a worker thread, cancelled cooperatively.

A numba kernel holds the interpreter until it returns, so a KeyboardInterrupt waits for
it — 20 s of a long 3-D run. :func:`call_interruptibly` runs a kernel compiled with
``nogil=True`` that polls a one-element ``cancel`` array in a worker thread while the main
thread waits in short joins; Ctrl-C there sets ``cancel[0] = 1``, the kernel returns within
milliseconds, and the KeyboardInterrupt goes on from the caller (what the kernel computed
is discarded). Outside the main thread the kernel is simply called.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

__all__ = ["call_interruptibly"]

R = TypeVar("R")
POLL_S = 0.05  # s between the main thread's checks for a signal


def call_interruptibly(fn: Callable[..., R], cancel: np.ndarray, *args: Any) -> R:
    """``fn(*args)``, interruptible by Ctrl-C through ``cancel`` (module docstring)."""
    if threading.current_thread() is not threading.main_thread():
        return fn(*args)
    box: dict[str, Any] = {}

    def work() -> None:
        try:
            box["out"] = fn(*args)
        except BaseException as exc:  # re-raised in the caller's thread
            box["err"] = exc

    worker = threading.Thread(target=work, name="turntable-kernel", daemon=True)
    worker.start()
    try:
        while worker.is_alive():
            worker.join(POLL_S)
    except BaseException:
        cancel[0] = 1
        worker.join()
        raise
    if "err" in box:
        raise box["err"]
    return box["out"]
