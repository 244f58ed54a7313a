"""Is a slower amplifier identifiable on a trace once the nominal model is refitted with it?
(issue 31: the slower-amplifier rows of the independent tables).

    python experiments/amplifier_profile.py FILE.csv [--slew 1,0.35,0.2] [--current 1]
        [--lag R] [--workers N] [--seed S] [--json OUT]

For each slew scale s (and the current scale c), the nominal calibration of ``turntable
calibrate`` (the global stage, the starts, the basin hops; no effects) runs on a base whose
HVA 900 model has its slew per input volt × s (settling time τ ÷ s, §4.1.2) and its current
limit × c, and with ``--lag`` an output lag τ_o = R·τ (the second pole of ``amplifier_lag``,
τ re-derived so the speed stays s's): the profile of the nominal fit over the amplifier's
speed, each point fitted with the same budget. The catalogue's ``amplifier_dynamics`` screen
instead holds the nominal model at its fit (or at the prior) while it moves the slew scale,
and a slower amplifier's smaller steps are what friction, preload and stroke already
absorbed there. Prints one line per point: the held-out error of the nominal fit [nm] and
the fit portion's, the noise floor and the wall time; ``--json`` writes the same, with each
point's fitted nominal factors (on the scaled base).

The amplifier scales are the base's, not the catalogue effect's, so a point may lie
outside the effect's range (slew ≥ 0.3, current ≥ 0.3). Since stop 56 the calibration's
nominal stage fits the amplifier's two scales itself; the profile holds them at each
point (``PROFILE_NOMINAL``: the nominal parameters less the amplifier's).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.trace_fit import AMPLIFIER_SCALES, TRACE_NOMINAL, calibrate_traces
from turntable_env.files import write_atomic
from turntable_env.plant import Plant


def _scales(text: str) -> list[float]:
    try:
        out = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: not comma-separated numbers") from None
    if not out or any(not 0.0 < v < 100.0 for v in out):
        raise argparse.ArgumentTypeError(f"{text!r}: every scale must lie in (0, 100)")
    return out


# the nominal parameters a profile point frees: all but the amplifier, which the point fixes
PROFILE_NOMINAL = tuple(n for n in TRACE_NOMINAL if n not in AMPLIFIER_SCALES)


def base_with_amplifier(slew: float, current: float, lag: float = 0.0) -> Plant:
    """The calibration's ``real`` base (per-axis model) with its amplifier scaled and its
    output lag ratio ``lag``."""
    base = Plant("real", fidelity="reduced")
    ps = base.params
    amp = replace(ps.amplifier.scaled(slew, current), lag_ratio=lag)
    return base.on_parameters(replace(ps, amplifier=amp))


def profile_point(
    path: Path, slew: float, current: float, workers: int, seed: int, lag: float = 0.0
) -> dict:
    """The nominal calibration of ``path`` on the base with the amplifier scaled."""
    t0 = time.perf_counter()
    res = calibrate_traces([path], base=base_with_amplifier(slew, current, lag), candidates=[],
                           max_effects=0, workers=workers, seed=seed, progress=None,
                           nominal=PROFILE_NOMINAL)  # fmt: skip
    d = res.diagnosis
    return {
        "slew_scale": slew,
        "current_scale": current,
        "lag_ratio": lag,
        "heldout_nm": float(d["error_nominal"]),
        "fit_portion_nm": float(d["error_fit_portion"]),
        "floor_nm": float(d["noise_floor"]),
        "target_nm": float(d["target"]),
        "wall_s": time.perf_counter() - t0,
        # the fitted nominal factors on the scaled base (report.json parameters.nominal)
        "factors": {n: float(v["value"]) for n, v in res.parameters["nominal"].items()},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", type=Path, help="a measurement CSV")
    ap.add_argument("--slew", type=_scales, default=[1.0, 0.35, 0.2],
                    help="slew scales, comma-separated (default 1,0.35,0.2)")  # fmt: skip
    ap.add_argument("--current", type=_scales, default=[1.0], help="current scale (one)")
    ap.add_argument("--lag", type=float, default=0.0,
                    help="the base amplifier's output lag τ_o/τ, 0…1 (default 0)")  # fmt: skip
    ap.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--seed", type=int, default=0, help="the Sobol design's seed")
    ap.add_argument("--json", type=Path, help="write the points here")
    a = ap.parse_args(argv)
    if len(a.current) != 1 or a.workers < 1:
        print(f"error: --current takes one scale, --workers ≥ 1 (got {a.current}, {a.workers})",
              file=sys.stderr)  # fmt: skip
        return 2
    if not 0.0 <= a.lag <= 1.0:
        print(f"error: --lag={a.lag!r}: must lie in [0, 1]", file=sys.stderr)
        return 2
    try:  # the file is read and checked before any fit starts
        load_measurement(a.file)
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:  # the output's directory made, and the file checked writable, before any fit
        if a.json:
            a.json.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(a.json, json.dumps({"file": str(a.file), "points": []}))
    except (OSError, ValueError) as exc:
        print(f"error: --json {a.json}: {exc}", file=sys.stderr)
        return 2
    rows = []
    print("| slew scale | current scale | lag ratio | held-out [nm] | fit portion [nm] | "
          "floor [nm] | target [nm] | wall [s] |\n|---:|---:|---:|---:|---:|---:|---:|---:|",
          flush=True)  # fmt: skip
    for s in a.slew:
        r = profile_point(a.file, s, a.current[0], a.workers, a.seed, a.lag)
        rows.append(r)
        print(f"| {s:g} | {r['current_scale']:g} | {a.lag:g} | {r['heldout_nm']:.1f} | "
              f"{r['fit_portion_nm']:.1f} | {r['floor_nm']:.2f} | {r['target_nm']:.1f} | "
              f"{r['wall_s']:.0f} |", flush=True)  # fmt: skip
        if a.json:
            write_atomic(a.json, json.dumps({"file": str(a.file), "points": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
