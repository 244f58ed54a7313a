"""The nominal fit's held search at slower amplifiers (``trace_fit._held_search``) replayed
alone on one trace, from a calibration report's nominal fit (stop 107, issue 31: does a
search with the amplifier held at the profile's slower units reach a basin the profile's
held fits, which start from that fit, do not?).

    python experiments/held_search.py TRACE.csv REPORT.json [--seed S]

The nominal fit is read from report.json (``parameters.nominal``, its factors' values),
the data weight set at it (σ_r, correlation length), the first global design (64 scrambled
Sobol points, ``--seed``) drawn, and the held search run with the calibration's rules under
the prior residual's weight. Prints the search's progress and its report row as JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from turntable_env.calibration import trace_fit as tf
from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.nominal import NominalModel
from turntable_env.plant import Plant


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trace", type=Path, help="a measurement CSV")
    ap.add_argument("report", type=Path, help="its calibration's report.json")
    ap.add_argument("--seed", type=int, default=0, help="the design's Sobol seed (default 0)")
    a = ap.parse_args(argv)
    try:
        m = load_measurement(a.trace)
        par = json.loads(a.report.read_text())["parameters"]["nominal"]
        base = Plant("real", fidelity="reduced")
        model = NominalModel(base, tuple(tf.TRACE_NOMINAL))
        x = np.array([math.log(float(par[n]["value"])) for n in model.names])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"error: {exc!r}", file=sys.stderr)
        return 2
    td, _w = tf.on_base(m, base)
    problem = tf.TraceProblem([td], model)
    r0 = problem.portions(np.zeros(len(x)), {})["fit"]  # the prior residual's weight
    w_prior = 1.0 / (max(tf._rms(r0), td.floor) * math.sqrt(tf.correlation_length(r0)))
    por = problem.portions(x, {})
    best = tf.LocalFit(x, {}, np.zeros_like(x), {}, math.nan, tf._rms(por["heldout"]),
                       tf._rms(por["fit"]), 0)  # fmt: skip
    tf._reweight(problem, best, td.floor)
    best.cost = problem.objective(x)
    print(f"nominal fit: cost {best.cost:.4g}, held-out {best.heldout_rms:.3g} nm, fit "
          f"portion {best.fit_rms:.3g} nm", flush=True)  # fmt: skip
    pts, vals = tf.global_stage(problem, 64, 1, a.seed, None)
    design = tf._Design(np.zeros(len(x)), w_prior, pts, vals, 3)
    _fit, row = tf._held_search(problem, best, design, td.floor, 1, (a.seed, tf.HOPS), 0.05,
                                lambda msg: print(msg, flush=True))  # fmt: skip
    print(json.dumps({k: v for k, v in row.items() if k != "hops"}, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
