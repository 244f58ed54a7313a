"""Where a test run's numba compiling goes: a pytest plugin that listens to numba's
``numba:compile`` events and prints, at the end of the run, the seconds each jitted function
took to compile in the main process, its callees' compiles taken out (exclusive), and the
total.

    PYTHONPATH=experiments NUMBA_CACHE_DIR=$(mktemp -d) python -m pytest -q -p compile_events

Compiles in worker processes (process pools, subprocesses) are not seen; a kernel loaded
from numba's cache is not a compile. The figures are wall seconds on the machine it runs on.
"""

from __future__ import annotations

import time
from collections import defaultdict

from numba.core import event

__all__ = ["CompileTimes"]

TOP = 15  # functions printed


class CompileTimes(event.Listener):
    """Exclusive compile seconds per function (module.qualname), callees' compiles out."""

    def __init__(self) -> None:
        self.stack: list[list[float]] = []  # [start, callees' seconds] of the open compiles
        self.seconds: dict[str, float] = defaultdict(float)
        self.count: dict[str, int] = defaultdict(int)

    def on_start(self, ev: event.Event) -> None:
        self.stack.append([time.perf_counter(), 0.0])

    def on_end(self, ev: event.Event) -> None:
        start, callees = self.stack.pop()
        took = time.perf_counter() - start
        if self.stack:
            self.stack[-1][1] += took
        f = ev.data["dispatcher"].py_func
        name = f"{f.__module__}.{f.__qualname__}"
        self.seconds[name] += took - callees
        self.count[name] += 1


_TIMES = CompileTimes()
event.register("numba:compile", _TIMES)


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    tr = terminalreporter
    total = sum(_TIMES.seconds.values())
    tr.section("numba compile (main process, exclusive seconds)")
    tr.write_line(f"{total:8.1f} s in {sum(_TIMES.count.values())} compiles")
    for name, s in sorted(_TIMES.seconds.items(), key=lambda kv: -kv[1])[:TOP]:
        tr.write_line(f"{s:8.1f} s  {_TIMES.count[name]:3d}  {name}")
