"""Why the trace's verdict on an effect ranks its blocks (issue 31, stop 58).

    python experiments/trace_test_power.py [--effect friction_wear] [--value beta=0.3]
        [--seed 1]

Runs the virtual lab's ``standard`` protocol (1 mV noise) with one effect on and compares
two models' predictions of its held-out samples: the prior model without the effect and
with it at its true values. Prints the held-out errors and three statistics of the
squared-error difference d = r_without² − r_with²:

* the t statistic of d's batch means over the whole record (blocks of five correlation
  lengths; the first form of ``residual.compare_predictions`` at stop 58),
* the t statistic of d's means over the segment blocks (``TraceProblem.units``),
* the signed-rank z over the same blocks (``residual.compare_predictions``, what the
  calibrator uses).

A t statistic is held down by the largest block when the error sits in a few segments by
amounts that differ by orders of magnitude, as a worn contact's does.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from turntable_env.calibration.nominal import NominalModel
from turntable_env.calibration.residual import (
    BLOCK_LENGTHS,
    compare_predictions,
    correlation_length,
)
from turntable_env.calibration.trace_fit import TRACE_NOMINAL, TraceProblem, _prepare
from turntable_env.calibration.virtual_lab import run_virtual_lab
from turntable_env.effects import CATALOGUE
from turntable_env.plant import Plant


def _t(means: np.ndarray) -> float:
    """The t statistic of block means (0 with fewer than two)."""
    if means.size < 2 or np.std(means, ddof=1) == 0:
        return 0.0
    return float(np.mean(means) / (np.std(means, ddof=1) / math.sqrt(means.size)))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--effect", default="friction_wear", choices=sorted(CATALOGUE))
    ap.add_argument("--value", nargs="*", default=["beta=0.3"], help="name=value pairs")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    values = {}
    for kv in a.value:
        k, sep, v = kv.partition("=")
        if not sep:
            ap.error(f"--value {kv!r}: expected name=value")
        values[k] = float(v)
    effects = {a.effect: {**CATALOGUE[a.effect].defaults(), **values}}
    td = _prepare(run_virtual_lab("standard", effects, noise_std=1e-3, seed=a.seed))[0]
    problem = TraceProblem([td], NominalModel(Plant("real", fidelity="reduced"), TRACE_NOMINAL))
    x = np.zeros(len(problem.model))
    r_with = problem.residual(x, effects, "heldout")
    r_without = problem.residual(x, {}, "heldout")
    units = problem.units("heldout")
    d = r_without**2 - r_with**2
    block = max(1, math.ceil(BLOCK_LENGTHS * correlation_length(d)))
    whole = d[: d.size // block * block].reshape(-1, block).mean(axis=1)
    seg = np.array([d[units == u].mean() for u in np.unique(units)])
    ranks = compare_predictions(r_with, r_without, units)
    print(f"{a.effect} {values}: held-out {ranks.rms_without:.3g} nm without it, "
          f"{ranks.rms_with:.3g} nm with it")  # fmt: skip
    print(f"  t of batch means over the record: {_t(whole):+.2f} ({whole.size} blocks of {block})")
    print(f"  t of segment means:               {_t(seg):+.2f} ({seg.size} segments)")
    print(f"  signed ranks over segment blocks: {ranks.z:+.2f} ({ranks.blocks} blocks that differ)")


if __name__ == "__main__":
    main()
