"""Write the third independent test plant's traces and their truth file.

    python experiments/third_plant_traces.py --out DIR [--only NAME ...]

One CSV per case (see ``turntable_env.testing.third_plant.CASES``) plus ``truth.json``
with the plant's parameters, each file's effect (by its catalogue name and parameters),
protocol, axis, sample rate, noise level and seed. Files are written atomically; with
``--only`` an existing ``truth.json`` in DIR keeps its other entries.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from turntable_env.testing import third_plant as tp

NOTES = (
    "Third independent plant (turntable_env/testing/third_plant.py), written from the thesis "
    "and the file format only. Steel sphere (Table D.1 mass/inertia) rotating about the "
    "watched tube axis and translating along the two driven tubes' axes; each driven tube a "
    "shear-corrected cantilever with two bending modes (tip translation/rotation, alumina "
    "ball), piezo as a uniform bending moment plus quarter-quadrant axial elongation; Hertz "
    "normal contacts with Hunt-Crossley damping; tangential Maxwell-slip (Iwan) banks "
    "discretising Mindlin-Cattaneo partial slip, with static/kinetic strength through a "
    "frictional-lag state; Dahl spin friction at the passive contact; voltage amplifier "
    "with bandwidth, slew, current limit into the quadrant capacitance; optical lever "
    "x = L tan(2 theta) read by a quadrant detector (linear when clean). Drive columns are "
    "the generator output (amplifier input, V), one channel per driven axis wired to one "
    "quadrant of each of the two tubes that turn the table about that axis; positive drive "
    "ramps turn the table towards positive detector volts. Detector volts carry a constant "
    "offset (plant.parameters.detector_offset_V) and white noise (noise_std_V); "
    "detector_y_V is the detector's other channel. One effect per file; effects {} = clean."
)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit status 2
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


def main(argv: list[str] | None = None) -> int:
    ap = _Parser(prog="third_plant_traces", description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="case names to write")
    args = ap.parse_args(argv)
    names = list(tp.CASES)
    if args.only:
        unknown = [n for n in args.only if n not in tp.CASES]
        if unknown:
            ap.error(f"unknown case {unknown[0]!r} (known: {', '.join(names)})")
        names = list(dict.fromkeys(args.only))
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        ap.error(f"--out {args.out!r} is not a directory")
    os.makedirs(args.out, exist_ok=True)

    truth_path = os.path.join(args.out, "truth.json")
    files: dict = {}
    if args.only and os.path.exists(truth_path):
        try:
            with open(truth_path, encoding="utf-8") as fh:
                files = dict(json.load(fh).get("files", {}))
        except (OSError, ValueError):
            files = {}
    params = tp.PlantParams()
    for name in names:
        case = tp.CASES[name]
        t0 = time.perf_counter()
        trace = tp.trace_for_case(case, params)
        fname = f"{name}.csv"
        tp.write_csv_atomic(os.path.join(args.out, fname), trace, case.axis)
        files[fname] = {
            "effects": tp.effect_params(case),
            "protocol": trace["protocol"],
            "axis": case.axis,
            "sample_rate_Hz": case.sample_rate_Hz,
            "noise_std_V": case.noise_std_V,
            "seed": case.seed,
            "protocol_seed": case.protocol_seed,
            "duration_s": float(trace["t"][-1] + 1.0 / case.sample_rate_Hz),
        }
        spot = abs(trace["x_clean"] - params.detector_offset_V[0]).max()
        spot *= params.detector_sensitivity_m_per_V / params.detector_range_m
        print(
            f"{fname}: {len(trace['t'])} samples, {time.perf_counter() - t0:.1f} s, "
            f"peak spot {spot:.0%} of range",
            flush=True,
        )
    truth = {"plant": tp.plant_summary(params), "notes": NOTES, "files": files}
    tp.write_json_atomic(truth_path, truth)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
