"""How visible each injected effect is, against the nearest effect-free plant of the same
structure (issue 31, stop 88).

A calibrator can name an effect from a trace's error only where the effect changes the
trace by more than its nominal model's structure misses it by anyway. This script measures
the first of the two on the second and third independent plants, whose code is in the
repository (``turntable_env.testing.second_plant`` and ``third_plant``). For each of a
plant's traces with one injected effect, the plant is simulated noise-free at the trace's
own samples with the effect (the trace without its noise) and without it; the effect-free
plant's friction level (both coefficients × one factor) and stroke (d31 ×) are refitted
within ×1/3–3 by Nelder–Mead and its detector gain by least squares, so that it comes as
close to the effect as the parameters a calibration fits first allow. The *visibility* is
the RMS left [nm at R_table], measured as the calibrator measures its held-out error: each
channel (x, and y where recorded) anchored per segment, on the trace's held-out portion
(:class:`~turntable_env.calibration.residual.Anchoring`).

The *feature gap* is half the χ² of the two signals' protocol features per group
(:mod:`~turntable_env.calibration.signatures`) against the detector noise alone, an upper
bound on what a group can show (a model's own misfit only adds to the noise); the table
prints the largest signature group's.

With ``--rows DIR...`` (``experiments/independent_calibration.py --out DIR``, a clean row
among them), beside each trace: its own row's nominal fit's structured residual
√(error² − floor²), and the visibility over the clean row's structured residual, what the
model's structure leaves with no effect at all. An effect visible at less than that
changes the trace by less than the model's structure misses the clean trace by.

    python experiments/effect_visibility.py [--plant second|third] [--only NAME ...]
        [--rows DIR ...] [--json OUT]

The nuisance set is three parameters; a calibration fits twelve, so the visibility is an
upper bound on what a nominal refit leaves of the effect in the plant's own structure.
About 30 simulations per trace; the third plant's are several times slower than the
second's.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.optimize

from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.residual import structured_rms
from turntable_env.calibration.signatures import GROUPS, SIGNATURE_GROUPS, SignatureLayout
from turntable_env.calibration.trace_fit import trace_data
from turntable_env.testing import second_plant as sp
from turntable_env.testing import third_plant as tp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from second_plant_traces import CASES as SECOND_CASES  # the script that wrote the traces

# the nuisance factors' range (friction level, stroke): the calibrator's stroke range
# (``params.RIG_LIMITS["d31_factor"]``, 0.3–3); unbounded, a plant that hardly moves can
# come nearer a trace's anchored held-out samples than one that steps wrongly
FACTOR_RANGE = 3.0


class _Second:
    """The second plant: its trace script's cases, a simulation at the trace's samples."""

    traces = Path("experiments/results/second_plant_traces")

    def cases(self) -> dict[str, Any]:
        return {n: c for n, c in SECOND_CASES.items() if len(c.effects.truth()) == 1}

    def effects(self, case: Any) -> list[str]:
        return sorted(case.effects.truth())

    def channels(self, case: Any, t: np.ndarray, factors: tuple[float, float] | None) -> np.ndarray:
        """(2, n) detector volts (x, y) at ``t``, no noise: with the case's effect
        (``factors`` None), or without it, friction and stroke × ``factors``."""
        p, eff = sp.PlantParams(), case.effects
        if factors is not None:
            fr, st = factors
            eff = replace(eff, **dict.fromkeys(eff.truth(), None))
            mu_s, mu_c = p.static_friction_coefficient * fr, p.coulomb_friction_coefficient * fr
            p = replace(p, d31_m_per_V=p.d31_m_per_V * st, static_friction_coefficient=mu_s,
                        coulomb_friction_coefficient=mu_c)  # fmt: skip
        sim = sp.simulate(p, sp.build_drive(sp.PROTOCOLS[case.protocol]), t, effects=eff,
                          axis=case.axis)  # fmt: skip
        return np.array(sp.detector_outputs(p, t, sim.mirror_angle_rad, effects=eff))


@functools.cache
def _third_protocol(name: str) -> list[Any]:
    """A third-plant case's protocol as its trace drew it (against the plant with its
    effect; each draw simulates a pretest, so it is drawn once per case)."""
    case = tp.CASES[name]
    return tp.lab_protocol(case.protocol_seed, tp.PlantParams(), effects=case.effects)


class _Third:
    """The third plant: its cases (each protocol drawn against the plant with its effect)."""

    traces = Path("experiments/results/third_plant_traces")

    def cases(self) -> dict[str, Any]:
        return {n: c for n, c in tp.CASES.items() if c.effect is not None}

    def effects(self, case: Any) -> list[str]:
        return [case.effect]

    def channels(self, case: Any, t: np.ndarray, factors: tuple[float, float] | None) -> np.ndarray:
        p, eff = tp.PlantParams(), case.effects
        segs = _third_protocol(case.name)  # the trace's drive
        if factors is not None:
            fr, st = factors
            eff = tp.Effects()  # every default neutral
            p = replace(p, d31_m_per_V=p.d31_m_per_V * st, mu_static=p.mu_static * fr,
                        mu_kinetic=p.mu_kinetic * fr)  # fmt: skip
        sim = tp.simulate(tp.render_drive(segs), case.sample_rate_Hz, tp.protocol_duration(segs),
                          params=p, effects=eff, axis=case.axis)  # fmt: skip
        vx, vy, _ = tp.detector_signals(sim, params=p, effects=eff)
        if vx.size != t.size:
            raise ValueError(f"{case.name}: {vx.size} simulated samples, the trace has {t.size}")
        return np.array([vx, vy])


PLANTS = {"second": _Second(), "third": _Third()}


def visibility(plant: Any, name: str, traces: Path) -> dict:
    """The effect's visibility on trace ``name`` [nm] and the nuisance fit that reaches it."""
    case = plant.cases()[name]
    m = load_measurement(traces / f"{name}.csv")
    td = trace_data(m)
    t = m.time - m.time[0]
    chans = [0, 1] if td.has_y and m.detector_y_v is not None else [0]
    anch = td.anchoring

    def anchored(v: np.ndarray) -> np.ndarray:
        return np.concatenate([anch.apply(v[c] * td.scale)[anch.heldout] for c in chans])

    target = anchored(plant.channels(case, t, None))
    cache: dict[tuple[float, float], tuple[float, float]] = {}

    def left(z: np.ndarray) -> float:
        key = (round(float(z[0]), 6), round(float(z[1]), 6))
        if key not in cache:
            v = anchored(plant.channels(case, t, (math.exp(key[0]), math.exp(key[1]))))
            g = float(v @ target) / max(float(v @ v), 1e-300)  # detector gain
            cache[key] = (float(np.sqrt(np.mean((target - g * v) ** 2))), g)
        return cache[key][0]

    untouched = left(np.zeros(2))
    simplex = [[0.0, 0.0], [0.15, 0.0], [0.0, 0.1]]  # ln factors: friction, stroke
    box = [(-math.log(FACTOR_RANGE), math.log(FACTOR_RANGE))] * 2
    scipy.optimize.minimize(left, np.zeros(2), method="Nelder-Mead", bounds=box,
                            options={"xatol": 2e-3, "fatol": 1e-3, "initial_simplex": simplex,
                                     "maxfev": 60})  # fmt: skip
    best = min(cache, key=lambda k: cache[k][0])
    nearest = cache[best][1] * plant.channels(case, t, (math.exp(best[0]), math.exp(best[1])))
    gaps = _feature_gaps(td, plant.channels(case, t, None), nearest)
    return {"trace": name, "effects": plant.effects(case), "feature_gap_nats": gaps,
            "visibility_nm": cache[best][0], "without_refit_nm": untouched,
            "friction_factor": math.exp(best[0]), "stroke_factor": math.exp(best[1]),
            "detector_gain": cache[best][1], "floor_nm": td.floor,
            "simulations": len(cache)}  # fmt: skip


def _feature_gaps(td: Any, with_effect: np.ndarray, without: np.ndarray) -> dict[str, float]:
    """Per feature group (:mod:`~turntable_env.calibration.signatures`): half the χ² of
    the two signals' features [nats] against the detector noise alone, which a model's own
    misfit only adds to (an upper bound on what the group can show of the effect)."""
    lay = SignatureLayout(td.m.time - td.m.time[0], td.drive, td.segments, td.floor)
    x_e, x_0 = with_effect * td.scale, without * td.scale
    lay.find_line(x_e[0])
    y = td.has_y and td.m.detector_y_v is not None
    f_e = lay.measure(x_e[0], x_e[1] if y else None)
    f_0 = lay.measure(x_0[0], x_0[1] if y else None)
    z2 = ((f_e.value - f_0.value) / f_e.noise) ** 2
    return {g: float(0.5 * np.sum(z2[f_e.group(g)])) for g in GROUPS if f_e.group(g).any()}


def _row(dirs: list[Path], name: str) -> dict | None:
    """The table row of trace ``name`` among ``dirs`` (results.json), if any."""
    for d in dirs:
        p = d / "results.json"
        if p.exists():
            for r in json.loads(p.read_text()):
                if r["trace"] == name:
                    return r
    return None


def _signature_gap(v: dict) -> str:
    """The largest signature group's feature gap, as ``group:nats``."""
    gaps = {g: n for g, n in v["feature_gap_nats"].items() if g in SIGNATURE_GROUPS}
    if not gaps:
        return "-"
    g = max(gaps, key=gaps.get)
    return f"{g[:5]}:{gaps[g]:.0f}"


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plant", choices=sorted(PLANTS), default="second")
    ap.add_argument(
        "--only",
        nargs="+",
        metavar="NAME",
        help="traces (default: every trace with one injected effect)",
    )
    ap.add_argument(
        "--rows",
        nargs="+",
        type=Path,
        default=[],
        metavar="DIR",
        help="table rows' directories (independent_calibration.py --out)",
    )
    ap.add_argument(
        "--traces",
        type=Path,
        help="the plant's traces (default: where its traces script writes them)",
    )
    ap.add_argument("--json", type=Path, help="write the rows as JSON")
    args = ap.parse_args(argv)  # fmt: skip
    plant = PLANTS[args.plant]
    traces = args.traces or plant.traces
    cases = plant.cases()
    names = args.only or list(cases)
    for n in names:
        if n not in cases:
            print(f"--only: {n!r} is not a trace with one effect ({', '.join(cases)})",
                  file=sys.stderr)  # fmt: skip
            return 2
        if not (traces / f"{n}.csv").exists():
            print(f"{traces / f'{n}.csv'}: no such trace (write it with "
                  f"experiments/{args.plant}_plant_traces.py)", file=sys.stderr)  # fmt: skip
            return 2
    for d in args.rows:
        if not (d / "results.json").exists():
            print(f"{d}: no results.json", file=sys.stderr)
            return 2
    clean = _row(args.rows, "clean")
    ref = structured_rms(clean["nominal_nm"], clean["floor_nm"]) if clean is not None else math.nan
    print(f"the clean trace's nominal fit leaves {ref:.1f} nm of structure"
          if clean is not None else "no clean row given: no reference structure")  # fmt: skip
    print(f"{'trace':22} {'visible':>8} {'floor':>6} {'unrefit':>8} {'friction':>8} "
          f"{'stroke':>7} {'features':>9} {'own row':>8} {'/clean':>7}  row")  # fmt: skip
    out = []
    for n in names:
        t0 = time.perf_counter()
        v = visibility(plant, n, traces)
        row = _row(args.rows, n)
        v["clean_structure_nm"] = ref
        v["over_clean_structure"] = v["visibility_nm"] / ref if clean is not None else math.nan
        tail = f"{'':8} {v['over_clean_structure']:7.2f}  (no row)"
        if row is not None:
            v["row_structure_nm"] = structured_rms(row["nominal_nm"], row["floor_nm"])
            v["row"] = "pass" if row["pass"] else "fail"
            v["named"] = row["selected"]
            named = ", ".join(v["named"]) or "none named"
            tail = (f"{v['row_structure_nm']:8.1f} {v['over_clean_structure']:7.2f}  "
                    f"{v['row']} ({named})")  # fmt: skip
        v["wall_s"] = time.perf_counter() - t0
        out.append(v)
        print(f"{n:22} {v['visibility_nm']:8.1f} {v['floor_nm']:6.1f} "
              f"{v['without_refit_nm']:8.1f} {v['friction_factor']:8.3f} "
              f"{v['stroke_factor']:7.3f} {_signature_gap(v):>9} {tail}", flush=True)  # fmt: skip
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        tmp = args.json.with_suffix(".tmp")
        tmp.write_text(json.dumps(out, indent=1))
        tmp.replace(args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
