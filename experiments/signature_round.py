"""The first signature round again, from a calibration's report (issue 31): each candidate
fitted to the features it must explain on top of the nominal model the report fitted, in
minutes instead of the calibration's quarter hour.

A calibration's first round of identification by signature
(:meth:`~turntable_env.calibration.identify.SignatureSearch.fit_candidate` over the
searched catalogue, then :func:`~turntable_env.calibration.identify.decide`) depends only
on the trace and on the fitted nominal model. This script rebuilds that model from
``report.json``'s nominal parameters (x = ln of each factor, as
:class:`~turntable_env.calibration.nominal.NominalModel` holds them) and reruns the round
with this checkout's features and rules. It is for studying a change to the signatures on
the tables' rows without rerunning their calibrations; the calibration itself (nominal fit,
joint refit, trace test) is what the tables report. Where the calibration named an effect
(beyond the amplifier's, which is nominal), report.json's parameters are the final model's,
refitted with it: the round then runs on that model without the effect, not on the
nominal fit the first round saw (the first line printed says which).

    python experiments/signature_round.py REPORT_DIR TRACE.csv [--candidates NAME ...]
        [--show GROUP [--effect NAME PARAMETER=V ...]]

REPORT_DIR holds the report.json of ``turntable calibrate TRACE.csv --report REPORT_DIR``.
With ``--show`` it first prints one feature group on the data (with its noise) and on the
model, and on the model with ``--effect``'s values. Then per candidate its gain on its
declared groups, the least with one feature left out, the gain over all signature groups,
whether it is significant, and the round's decision.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from turntable_env.calibration.identify import decide, free_parameters, significance_nats
from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.nominal import NominalModel
from turntable_env.calibration.signatures import GROUPS
from turntable_env.calibration.trace_fit import (
    SEARCHED,
    TRACE_NOMINAL,
    TraceProblem,
    on_base,
    signature_search,
)
from turntable_env.effects import CATALOGUE
from turntable_env.plant import Plant


def nominal_x(report: dict, model: NominalModel) -> np.ndarray:
    """x = ln(factor) of each of ``model``'s parameters from a report's parameter table."""
    table = report["parameters"]["nominal"]
    missing = [n for n in model.names if n not in table]
    if missing:
        raise ValueError(f"report.json: parameters.nominal lacks {', '.join(missing)}")
    return np.array([math.log(float(table[n]["value"])) for n in model.names])


def rebuild(report: dict, trace: Path) -> tuple[TraceProblem, np.ndarray]:
    """The trace problem of a report's trace and the report's nominal fit x on it (its
    base plant and nominal factors; report.json's ``plant.base`` and
    ``parameters.nominal``)."""
    base = Plant(report["plant"]["base"], fidelity="reduced")
    td, _ = on_base(load_measurement(trace), base)
    model = NominalModel(base, tuple(n for n in TRACE_NOMINAL
                                     if n in report["parameters"]["nominal"]))  # fmt: skip
    return TraceProblem([td], model), nominal_x(report, model)


def _variants(ap: argparse.ArgumentParser, spec: list[str] | None) -> list[dict]:
    """[{}] and one effects mapping per ``PARAMETER=V`` of ``--effect NAME ...``; a bad
    name, parameter or value is the parser's error (exit 2, one line)."""
    if not spec:
        return [{}]
    name, *pairs = spec
    if name not in CATALOGUE:
        ap.error(f"--effect {name!r}: not a catalogue effect ({', '.join(CATALOGUE)})")
    out: list[dict] = [{}]
    for pv in pairs:
        par, _, val = pv.partition("=")
        try:
            out.append({name: CATALOGUE[name].check({par: float(val)})})
        except ValueError as exc:
            ap.error(f"--effect {name} {pv!r}: {exc}")
    return out


def _show(search, x: np.ndarray, group: str, variants: list[dict]) -> None:  # type: ignore[no-untyped-def]
    """Each feature of ``group``: the data's value and noise, then each variant model's."""
    d = search.data
    models = [search.features(x, v) for v in variants]
    heads = ["nominal"] + [", ".join(f"{k}={w:g}" for e in v.values() for k, w in e.items())
                           for v in variants[1:]]  # fmt: skip
    print(f"  {group}: data ± noise | " + " | ".join(heads))
    for i in np.flatnonzero(d.group(group)):
        vals = " | ".join(f"{m.value[i]:+.4g}" for m in models)
        print(f"    {d.names[i]}: {d.value[i]:+.4g} ± {d.noise[i]:.2g} | {vals}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("report_dir", type=Path)
    ap.add_argument("trace", type=Path)
    ap.add_argument("--candidates", nargs="+", default=None,
                    help="catalogue effects (default: the searched ones)")  # fmt: skip
    ap.add_argument("--show", metavar="GROUP", default=None,
                    help="also print this feature group on the data and the models")  # fmt: skip
    ap.add_argument("--effect", nargs="+", default=None, metavar=("NAME", "PARAMETER=V"),
                    help="with --show: models with this effect at these values, e.g. "
                    "friction_asymmetry alpha=-0.15 alpha=0.15")  # fmt: skip
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if args.show is not None and args.show not in GROUPS:
        ap.error(f"--show {args.show!r}: not a feature group ({', '.join(GROUPS)})")
    variants = _variants(ap, args.effect)
    path = args.report_dir / "report.json"
    if not path.is_file():
        ap.error(f"{path}: no such file")
    if not args.trace.is_file():
        ap.error(f"{args.trace}: no such file")
    bad = [n for n in args.candidates or [] if n not in CATALOGUE]
    if bad:
        ap.error(f"--candidates {bad[0]!r}: not a catalogue effect ({', '.join(CATALOGUE)})")
    try:
        report = json.loads(path.read_text())
        for keys in (("plant", "base"), ("parameters", "nominal"), ("selected_effects",)):
            part = report
            for k in keys:
                part = part[k]
    except (ValueError, KeyError, TypeError) as exc:
        ap.error(f"{path}: not a calibration report ({type(exc).__name__}: {exc})")
    problem, x = rebuild(report, args.trace)
    search = signature_search(problem)
    search.find_lines(x, {})
    base_features = search.features(x, {})
    names = args.candidates or [n for n in SEARCHED if n != "amplifier_dynamics"]
    print(f"{args.trace.name}: held-out {problem.rms(x, {}, 'heldout'):.3g} nm at the report's "
          f"nominal parameters without effects (its nominal fit: "
          f"{report['diagnosis']['error_nominal']:.3g} nm; effects named: "
          f"{', '.join(report['selected_effects']) or 'none'})")  # fmt: skip
    groups = base_features.groups
    counts = ", ".join(f"{g} {groups.count(g)}" for g in sorted(set(groups)))
    print(f"  features per group: {counts}")
    if args.show is not None:
        _show(search, x, args.show, variants)
    fits = []
    for n in names:
        f = search.fit_candidate(n, x, {}, base_features)
        fits.append(f)
        level = significance_nats(len(free_parameters(n)))
        print(f"  {n:<22} gain {f.declared_nats:7.1f}  loo {f.declared_nats_loo:7.1f}  all "
              f"{f.total_nats:7.1f}  level {level:4.1f}  significant {f.significant!s:<5}  "
              f"{ {k: round(v, 4) for k, v in f.values.items()} }  {f.note}")  # fmt: skip
    dec = decide(fits)
    print(f"  decision: {dec.to_json()}; wall {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
