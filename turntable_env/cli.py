"""Command line: ``turntable <subcommand>``.

Subcommands:
    params     print a parameter set (Table D.1 ``real`` or D.2 ``thesis``), given and derived
    simulate   run the full 3-D model with a stepping drive and print its figures
    bench      speed and accuracy of every simulation path; env throughput
    benchmark  every registered controller on the fixed task suite (controllers package)
    virtual-lab  write a measurement file from the simulator with effects switched on
    calibrate  fit measurement files, find the effects the model lacks, write a report
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

from . import __version__
from .files import Terminated, check_writable, plain_json, terminate_cleanly, write_atomic
from .plant import MAX_SENSOR_NOISE, PARAMETER_SETS, parameter_set, set_or_plant
from .scale import BACKENDS
from .validation import parse_decimal

__all__ = ["main"]

MIN_AMPLITUDE = 1e-3  # V of amplifier input: below a DAQ's least bit, and the figures' 0/0
RAMP_RATIO_RANGE = (0.01, 0.999)  # ramp and flyback each at least 0.1 % of a period


def one_line(text: object) -> str:
    """``text`` as one printable line: a control character (a newline in a file name, a
    tab, an escape) written as Python writes it in a string literal (\\n, \\t, \\x1b), so
    an error is one line on stderr whatever the input it names."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


class _Parser(argparse.ArgumentParser):
    """argparse with one line on stderr and exit code 2 for a bad command line."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")


def _real(
    lo: float | None = None, hi: float | None = None, *, open_lo: bool = False,
    min_abs: float = 0.0,
):  # fmt: skip
    """argparse type: a finite decimal number in [lo, hi] (lo excluded with ``open_lo``)
    whose magnitude is at least ``min_abs`` (> 0: zero refused too)."""

    def parse(text: str) -> float:
        v = parse_decimal(text)
        if v is None:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number (plain decimals: 1.5e-3)")
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{text!r}: must be finite")
        if lo is not None and (v < lo or (open_lo and v == lo)):
            raise argparse.ArgumentTypeError(f"{text!r}: must be {'>' if open_lo else '>='} {lo:g}")
        if hi is not None and v > hi:
            raise argparse.ArgumentTypeError(f"{text!r}: must be <= {hi:g}")
        if abs(v) < min_abs:
            raise argparse.ArgumentTypeError(f"{text!r}: its magnitude must be >= {min_abs:g}")
        return v

    return parse


def _int(lo: int, hi: int):
    """argparse type: an integer in [lo, hi]."""

    def parse(text: str) -> int:
        if not re.fullmatch(r"\s*[+-]?[0-9]+\s*", text):  # ASCII digits: int() takes more
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer (plain decimals: 12)")
        v = int(text)
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{text!r}: must lie in {lo}…{hi}")
        return v

    return parse


def _fmt(value: object) -> str:
    if isinstance(value, bool) or isinstance(value, str):
        return str(value)
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}"


def _cmd_params(args: argparse.Namespace) -> int:
    ps = parameter_set(args.set)
    if args.json:
        print(ps.to_json())
        return 0
    print(f"parameter set '{ps.name}'")
    rows = ps.describe()
    w = max(len(q.name) for q in rows)
    for q in rows:
        print(f"  {q.name:<{w}}  {_fmt(q.value):>40} {q.unit:<9} {q.kind:<8} {q.source}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from .model import SimulationError
    from .plant import as_plant
    from .simulation import (
        MAX_DURATION,
        MAX_STEPS,
        check_output_samples,
        simulate,
        simulate_axes,
        stepping_drive,
    )

    if args.cycles is not None and args.signal != "two":
        raise ValueError(f"--cycles={args.cycles}: only with --signal two (forward-back cycles)")
    if args.out is not None:
        check_writable("--out", args.out)
    named = as_plant(args.params)  # a named plant whole: factors, rig and every effect
    drive, ps = stepping_drive(
        parameter_set(args.params),  # = named.params, under the plant's name
        amplitude=args.amplitude,
        frequency=args.frequency,
        periods=args.periods,
        signal=args.signal,
        amplifier=args.amplifier,
        a=args.a,
        cycles=args.cycles,
    )
    plant = named.on_parameters(ps)  # with the amplifier mode of --amplifier
    settle = args.settle if args.settle is not None else 0.0
    output_dt = args.output_dt if args.output_dt is not None else min(1e-5, 0.01 / drive.frequency)
    duration = drive.duration + settle  # s simulated
    if output_dt > 1.0 / drive.frequency:  # the step figure reads every period's start
        raise ValueError(
            f"--output-dt={output_dt:g} s: more than one drive period ({1.0 / drive.frequency:g} "
            "s at --frequency); the steps are read at each period's start"
        )
    if duration > MAX_DURATION:
        raise ValueError(
            f"--periods/--cycles/--frequency/--settle: {duration:.6g} s to simulate, more than "
            f"{MAX_DURATION:g} s"
        )
    check_output_samples(duration, output_dt, name="--output-dt")  # drive and --settle
    if args.model == "full":  # the 3-D model's fine step is dt-factor/ω_max
        from .plant.models import turntable_model

        omega = turntable_model(plant.params).omega_max  # rad/s
        if duration * omega / args.dt_factor > MAX_STEPS:
            raise ValueError(
                f"--dt-factor={args.dt_factor:g}: {duration * omega / args.dt_factor:.3g} "
                f"integration steps over {duration:g} s (step = factor/ω_max, ω_max = "
                f"{omega:.4g} rad/s), more than {MAX_STEPS:g}: raise --dt-factor"
            )
    try:
        if args.model == "reduced":
            (r,) = simulate_axes([plant], [drive], axis=args.axis, settle=settle,
                                 output_dt=output_dt)  # fmt: skip
            wall = r.info["wall_s"]
            out = {
                "model": "reduced",
                "mean_abs_step_um": r.step_size * 1e6,
                "steps_um": [float(x) * 1e6 for x in r.steps],
                "net_rotation_rad": r.net_rotation,
                "detector_V_net": r.detector_V_net,
                "wall_s": wall,
                "realtime_factor": float(r.time[-1] - r.time[0]) / wall,
            }
        else:
            r = simulate(
                plant, drive, axis=args.axis, settle=settle, dt_factor=args.dt_factor,
                coarse_factor=args.coarse_factor or None, output_dt=output_dt,
            )  # fmt: skip
            out = {"model": "full", **r.summary()}
            out["mean_abs_step_um"] = out.pop("step_um")
    except SimulationError as exc:
        print(f"turntable: error: {one_line(exc)}", file=sys.stderr)
        return 3
    two = drive.pattern == "two"
    fig = r.figure_step(drive.n_periods, two)  # from the angle where the detector saturates
    how = (
        "read from the detector with Eq. 4.1-4.2"
        if fig["source"] == "detector"
        else "read from the angle, x = theta*R_table (Eq. 4.2): the detector saturates"
    )
    lab = args.params != "thesis"  # Figs. 4.6/4.7 measured; 4.10/4.8 the thesis's simulations
    fig_two, fig_one = ("Fig. 4.6", "Fig. 4.7") if lab else ("Fig. 4.10", "Fig. 4.8")
    out = {
        "step_um": fig["step"] * 1e6,
        "figure": (
            f"{fig_two}: t1 -> t2 = the last forward block ({drive.n_periods} steps after a "
            f"reversal when cycles > 1), {how}; return t3 - t1 over its cycle"
            if two
            else f"{fig_one}: t1 -> t2 over {drive.n_periods} periods from rest, {how}"
        ),
        "read_from": fig["source"],
        "excursion_um": fig["excursion"] * 1e6,
        **({"return_um": fig["return"] * 1e6,
            "return_fraction": fig["return"] / fig["excursion"] if fig["excursion"] else None}
           if two else {}),
        **out,
    }  # fmt: skip
    out["drive"] = {
        "amplitude_V_input": drive.amplitude,
        "amplitude_V_tubes": drive.amplitude * ps.amplifier.gain,
        "frequency_Hz": drive.frequency,
        "a": drive.a,
        "periods": drive.n_periods,
        "signal": drive.pattern,
        "cycles": drive.n_cycles,
        "amplifier": args.amplifier or ("ideal" if ps.amplifier.ideal else "adapted"),
        "flyback": drive.flyback,
    }
    if args.params in ("real", "calibrated") and args.axis == "B":
        from .calibration.thesis_data import thesis_step_sizes

        measured = thesis_step_sizes()["one_directional" if not two else "two_directional"]
        out["measured_step_um"] = measured * 1e6
    if args.json:
        print(json.dumps(plain_json(out), indent=2, default=float, allow_nan=False))
    else:
        for k, v in out.items():
            if k == "steps_um":
                v = "[" + ", ".join(f"{x:.4f}" for x in v) + "]"
            elif isinstance(v, float) and math.isfinite(v):
                v = f"{v:.6g}"
            print(f"  {k:<32} {v}")
    if args.out is not None:  # after the summary: a failing write does not lose it
        write_atomic(args.out, r.to_pandas().to_csv())
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from .bench import DURATION_RANGE, env_throughput, format_env_table, format_table, run_bench

    if args.env_only:
        if args.duration is not None or args.quick:  # not silently ignored
            raise ValueError("--duration/--quick: not with --env-only (it times env steps only)")
        res, table = env_throughput(num_envs=args.batch), format_env_table
    else:
        duration = args.duration if args.duration is not None else 1.0  # s
        if duration < DURATION_RANGE[0]:  # one drive period at least, before any work
            raise ValueError(f"--duration={duration:g}: must be >= {DURATION_RANGE[0]:g} s "
                             f"(one period of the standard scenario's drive)")
        res = run_bench(duration=duration, batch=args.batch, quick=args.quick)
        table = format_table
    if args.json:  # with the commit and the machine the figures were measured on
        from .provenance import provenance

        doc = {**res, "provenance": provenance()}
        print(json.dumps(plain_json(doc), indent=2, default=float, allow_nan=False))
    else:
        print(table(res))
    return 0


def _cmd_benchmark(args: argparse.Namespace) -> int:
    from controllers.benchmark import QUICK, run_benchmark, write_outputs

    def split(option: str, x: str | None) -> list[str] | None:
        """A comma-separated list of names; empty entries or a name twice → ValueError."""
        if x is None:
            return None
        names = [v.strip() for v in x.split(",")]
        if not all(names):
            raise ValueError(f"{option}={x!r}: an empty name")
        twice = sorted({v for v in names if names.count(v) > 1})
        if twice:
            raise ValueError(f"{option}={x!r}: {twice[0]!r} given twice")
        return names

    runs = [spec.partition("=")[2] for spec in args.agent or []]
    check_writable("--out", args.out, directory=True, reads=[r for r in runs if r])
    kw: dict[str, object] = dict(QUICK) if args.quick else {}
    if args.seeds is not None:
        kw["seeds"] = args.seeds
    if args.plant_sets is not None:
        kw["plant_sets"] = split("--plant-sets", args.plant_sets)
    if args.tasks is not None:
        kw["tasks"] = split("--tasks", args.tasks)
    if args.suite_seed is not None:
        kw["suite_seed"] = args.suite_seed
    names = split("--controllers", args.controllers)
    if args.agent:
        from agents import register_run

        for spec in args.agent:
            name, sep, run = spec.partition("=")
            if not sep or not name or not run:
                raise ValueError(f"--agent {spec!r}: must be NAME=RUN_DIR")
            register_run(name, run)
        if names is not None:
            names += [s.partition("=")[0] for s in args.agent]
    if args.backend == "ray" and args.workers is not None:
        raise ValueError("--workers: for --backend processes (Ray uses the cluster's CPUs)")
    if args.backend is not None:
        kw.update(backend=args.backend, address=args.address, workers=args.workers)
    elif args.address is not None or args.workers is not None:
        raise ValueError("--address/--workers: need --backend (ray, processes or auto)")
    res = run_benchmark(names, progress=not args.json and args.backend is None, **kw)
    paths = write_outputs(res, args.out)
    if args.json:
        print(json.dumps(plain_json(res.to_json()), indent=1, allow_nan=False))
    else:
        print(res.leaderboard())
        print(f"{res.settings['wall_s']:.1f} s; files in {paths['json'].parent}")
    return 0


def _cmd_virtual_lab(args: argparse.Namespace) -> int:
    from .calibration.virtual_lab import run_virtual_lab
    from .effects import parse_effects

    check_writable("--out", args.out)
    effects = parse_effects(args.effects or "")
    m = run_virtual_lab(
        args.protocol, effects, axis=args.axis, noise_std=args.noise, seed=args.seed, out=args.out
    )
    print(
        f"{args.out}: {m.time.size} samples over {m.duration:.3f} s, protocol {args.protocol}, "
        f"axis {args.axis}, detector noise {args.noise:g} V; effects (not in the file): "
        + (", ".join(f"{k}{v}" for k, v in effects.items()) or "none")
    )
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from .calibration.calibrate import calibrate, write_report
    from .calibration.summary import calibrate_summary
    from .calibration.thesis_data import THESIS_DATA_FILE

    files = list(args.files) + ([str(THESIS_DATA_FILE)] if args.thesis else [])
    check_writable("--report", args.report, directory=True, reads=files)
    if not files:
        raise ValueError("files: give measurement files (CSV), a summary file (TOML) or --thesis")
    seen: dict[str, str] = {}
    for f in files:
        if not f.strip():  # "" would read as the working directory
            raise ValueError(f"files: {f!r}: an empty path; give a measurement or summary file")
        key = os.path.realpath(f)
        if key in seen:
            raise ValueError(f"files: {f!r} given twice (as {seen[key]!r} too)")
        seen[key] = f
    summary = [f for f in files if f.endswith(".toml")]
    if summary and len(summary) != len(files):
        what = "--thesis (the thesis's summary file)" if args.thesis else f"files: {summary}"
        raise ValueError(
            f"{what}: summary-level figures (TOML) are calibrated apart from measurement "
            "traces (CSV); give one or the other"
        )
    if len(summary) > 1:
        raise ValueError(f"files: one summary file at a time, got {summary}")
    if summary:
        if args.base is not None or args.global_points is not None:  # not silently ignored
            raise ValueError(
                "--base/--global-points: for measurement files (CSV); the summary-level fit "
                "(TOML, --thesis) takes neither"
            )
        res = calibrate_summary(summary[0], seed=args.seed, workers=args.workers)
    else:
        try:  # a set, or a lab's earlier calibration of the rig (read before any work)
            base = set_or_plant(args.base) if args.base is not None else "real"
        except ValueError as exc:
            raise ValueError(f"--base: {exc}") from None
        res = calibrate(
            files, base=base, workers=args.workers,
            global_points=args.global_points or 64, seed=args.seed,
        )  # fmt: skip
    paths = write_report(res, args.report)
    print(
        f"selected effects: {', '.join(res.selected_effects) or 'none'}; {res.error_label} "
        f"{res.error_before:.3g} → {res.error_after:.3g} {res.error_unit}; residual structured: "
        f"{res.residual_structured}; {res.wall_s:.1f} s; report: {paths['json']}"
        + ("; untested: the data identify no nominal parameter (a longer trace, with scans "
           "and bursts)" if res.diagnosis.get("identified", 1) == 0 else "")
    )  # fmt: skip
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from .report import build_report

    check_writable("--out", args.out, directory=True)
    paths = build_report(args.out, quick=args.quick, progress=not args.no_progress)
    summary = json.loads(paths["json"].read_text())
    print(f"report: {paths['html']} ({summary['wall_s']:.0f} s); numbers: {paths['json']}")
    return 0


def _add_params(sub: Any) -> None:
    """The ``params`` subcommand."""
    pp = sub.add_parser("params", help="print a parameter set with every given and derived value")
    pp.add_argument(
        "--set",
        choices=list(PARAMETER_SETS),
        default="real",
        help="Table D.1 (real), Table D.2 (thesis) or the calibrated real turntable",
    )
    pp.add_argument("--json", action="store_true", help="print JSON")
    pp.set_defaults(func=_cmd_params)


def _add_simulate(sub: Any) -> None:
    """The ``simulate`` subcommand."""
    ps = sub.add_parser(
        "simulate",
        help="run the full 3-D model with a stepping drive",
        description="Full 3-D model from static equilibrium; prints the mean step at the table "
        "radius (Eq. 4.2), every step, the net rotation, the detector's net voltage, the "
        "energy closure and the real-time factor.",
    )
    ps.add_argument("--params", choices=list(PARAMETER_SETS), default="real")
    ps.add_argument("--axis", choices=["A", "B", "C", "Z"], default="B")
    ps.add_argument("--signal", choices=["one", "two"], default="one")
    ps.add_argument(
        "--amplitude", type=_real(-10.0, 10.0, min_abs=MIN_AMPLITUDE), default=2.0,
        help="amplifier input [V] (x45), 1 mV <= |A| <= 10 V; the sign is the direction "
        "(negative: the reverse step)",
    )  # fmt: skip
    ps.add_argument(
        "--frequency",
        type=_real(0.0, 1e5, open_lo=True),
        default=None,
        help="[Hz] up to 100 kHz (default: the set's, 100 / 2)",
    )
    ps.add_argument("--periods", type=_int(1, 100_000), default=10, help="periods (per direction)")
    ps.add_argument(
        "--cycles", type=_int(1, 1000), default=None,
        help="forward-back cycles (--signal two; default 3: Fig. 4.6 is read on the last)",
    )  # fmt: skip
    ps.add_argument(
        "--a", type=_real(*RAMP_RATIO_RANGE), default=None,
        help=f"ramp ratio a, the ramp's share of a period, {RAMP_RATIO_RANGE[0]:g} <= a <= "
        f"{RAMP_RATIO_RANGE[1]:g} (default: 0.95)",
    )  # fmt: skip
    ps.add_argument(
        "--amplifier",
        choices=["adapted", "unadapted", "ideal"],
        default=None,
        help="HVA 900 with the Fig. 4.3 input, without it, or an instant source "
        "(default: adapted for real, ideal for thesis)",
    )
    ps.add_argument(
        "--settle", type=_real(0.0, 100.0), default=None, help="time after the drive [s], <= 100"
    )
    ps.add_argument(
        "--model", choices=["full", "reduced"], default="full",
        help="full 3-D model or the per-axis reduced model (axes A, B, C)",
    )  # fmt: skip
    ps.add_argument(
        "--dt-factor", type=_real(0.0, 1.0, open_lo=True), default=0.05,
        help="step = factor/omega_max",
    )  # fmt: skip
    ps.add_argument(
        "--coarse-factor", type=_real(0.0, 10.0), default=0.5,
        help="adaptive full-model step while quiet = factor/omega_max (default 0.5; 0: the "
        "fixed step that simulate() takes by default)",
    )  # fmt: skip
    ps.add_argument(
        "--output-dt", type=_real(0.0, 1.0, open_lo=True), default=None,
        help="sample interval [s] (default: min(10 µs, 1 %% of a period))",
    )  # fmt: skip
    ps.add_argument("--out", default=None, help="write the response as CSV here")
    ps.add_argument("--json", action="store_true", help="print JSON")
    ps.set_defaults(func=_cmd_simulate)


def _add_bench(sub: Any) -> None:
    """The ``bench`` subcommand."""
    pb = sub.add_parser(
        "bench",
        help="speed and accuracy of the full, reduced, batched and SciPy paths",
        description="Standard scenario: real set, axis B, one-directional 2 V (90 V) 100 Hz "
        "a = 0.95, adapted amplifier. Real-time factors, step errors against converged "
        "references, peak memory, compile time; PiezoTurntable-v0 env steps per second.",
    )
    pb.add_argument(
        "--duration", type=_real(0.0, 60.0, open_lo=True), default=None,
        help="simulated time [s], <= 60 (default 1)",
    )  # fmt: skip
    pb.add_argument("--batch", type=_int(1, 4096), default=64, help="turntables in the batched run")
    pb.add_argument("--quick", action="store_true", help="short references (smoke runs only)")
    pb.add_argument("--json", action="store_true",
                    help="print JSON, with the commit and the machine (provenance)")
    pb.add_argument(
        "--env-only", action="store_true", help="only the environment throughput (about 30 s)"
    )
    pb.set_defaults(func=_cmd_bench)


def _add_benchmark(sub: Any) -> None:
    """The ``benchmark`` subcommand."""
    pk = sub.add_parser(
        "benchmark",
        help="every registered controller × plant set × task, seeds paired, 95 %% intervals",
        description="Point-to-point moves that need stepping (2, 50, 200 µm; the long ones "
        "from beyond the detector with a ±30 % dead-reckoned start; to the detector's edge), "
        "tracking (constant-velocity scan, waypoints, back and forth) and a knock, on the "
        "nominal, randomized (RL training), held_out, calibrated, full_3d and independent "
        "plant sets. "
        "Controllers see only observations and what a lab knows. Writes benchmark.json "
        "(versioned; means with 95 % bootstrap intervals and paired differences), "
        "episodes.csv, leaderboard.md/.html and trajectory plots.",
    )
    pk.add_argument("--controllers", default=None, help="comma-separated names (default: all)")
    pk.add_argument("--plant-sets", default=None,
                    help="comma-separated (default: all but calibrated_per_axis)")  # fmt: skip
    pk.add_argument("--tasks", default=None, help="comma-separated (default: all)")
    pk.add_argument(
        "--seeds", type=_int(2, 1000), default=None, help="episodes per cell (default 20)"
    )
    pk.add_argument("--quick", action="store_true", help="4 seeds, 2 plant sets, 3 tasks")
    pk.add_argument(
        "--suite-seed", type=_int(0, 2**32 - 1), default=None,
        help="seed of every draw (episodes, plants, noise; default: the committed suite's 2026)",
    )  # fmt: skip
    pk.add_argument("--out", default="benchmark_results", help="output directory")
    pk.add_argument("--json", action="store_true", help="print benchmark.json")
    pk.add_argument(
        "--agent",
        action="append",
        default=[],
        metavar="NAME=RUN_DIR",
        help="also run the agent of a training run directory as controller NAME (repeatable)",
    )
    pk.add_argument(
        "--backend",
        choices=BACKENDS,
        default=None,
        help="run the cells in parallel: Ray tasks (auto: when installed) or processes",
    )
    pk.add_argument("--address", default=None, help="Ray cluster to join (default: local)")
    pk.add_argument(
        "--workers", type=_int(1, 1024), default=None, help="processes for --backend processes"
    )
    pk.set_defaults(func=_cmd_benchmark)


def _add_virtual_lab(sub: Any) -> None:
    """The ``virtual-lab`` subcommand."""
    pv = sub.add_parser(
        "virtual-lab",
        help="write a measurement file from the simulator with effects switched on",
        description="Runs a drive protocol on the reduced model with catalogue effects and "
        "detector noise and writes the measurement file (CSV with # key: value metadata). "
        "Effects: name=value (first parameter), name.param=value, or a bare name (typical "
        "values), comma-separated.",
    )
    pv.add_argument("--effects", default="", help="e.g. piezo_creep=0.02,sensor_drift.rate=0.1")
    pv.add_argument("--protocol", default="standard", choices=["standard", "long", "thesis"])
    pv.add_argument("--axis", default="B", choices=["A", "B", "C"])
    pv.add_argument(
        "--noise", type=_real(0.0, MAX_SENSOR_NOISE), default=1e-3,
        help=f"detector noise std [V], 0…{MAX_SENSOR_NOISE:g}"
    )
    pv.add_argument("--seed", type=_int(0, 2**63 - 1), default=0)
    pv.add_argument("--out", required=True, help="measurement file to write")
    pv.set_defaults(func=_cmd_virtual_lab)


def _add_calibrate(sub: Any) -> None:
    """The ``calibrate`` subcommand."""
    pc = sub.add_parser(
        "calibrate",
        help="fit measurement files and find the effects the model lacks",
        description="Reads each trace's drive (breakpoints or sampled; single-sample drops "
        "are steps), cuts it into segments with fit and held-out portions interleaved by "
        "drive condition, estimates the noise floor, fits the nominal model (stroke, "
        "detector gain, friction levels, Stribeck velocity, preload, presliding, damping, "
        "inertia, the amplifier's slew and current limit; priors, a parallel Sobol global "
        "stage, least squares, basin hopping; amplifier_dynamics is named when the "
        "amplifier lies 3 sigma from the datasheet), then names catalogue effects by the "
        "protocol features they must explain, or by the held-out error; writes "
        "report.json, report.md, an overlay and a residual plot. A TOML file of "
        "summary-level figures (the format of "
        "turntable_env/data/thesis_measurements.toml; --thesis for that file) runs the same "
        "loop on figures: ideal-source nominal, leave-one-out held-out error.",
    )
    pc.add_argument("files", nargs="*", help="measurement files (CSV) or one summary file (TOML)")
    pc.add_argument("--thesis", action="store_true", help="the thesis's chapter-4 figures")
    pc.add_argument("--report", required=True, help="output directory")
    pc.add_argument(
        "--base", default=None, metavar="SET|FILE",
        help="the plant the nominal factors scale and the priors centre on: a set (real, "
        "the default; thesis; calibrated, the thesis rig's) or a lab's earlier calibration "
        "of the same rig (its calibrated.toml, report.json or report directory); "
        "measurement files only",
    )  # fmt: skip
    pc.add_argument(
        "--workers", type=_int(1, 1024), default=None,
        help="worker processes (traces: the global stage, the fits, the effect candidates; "
        "figures: the rig hypotheses); default: the CPUs this process may use",
    )
    pc.add_argument(
        "--global-points", type=_int(1, 100_000), default=None,
        help="Sobol points of the global stage (default 64); measurement files only",
    )
    pc.add_argument(
        "--seed", type=_int(0, 2**63 - 1), default=0,
        help="scrambling seed of the Sobol design (figures: the perturbation of every start)",
    )
    pc.set_defaults(func=_cmd_calibrate)


def _add_report(sub: Any) -> None:
    """The ``report`` subcommand."""
    pr = sub.add_parser(
        "report",
        help="the main job: thesis figures, speed, benchmark and calibration as one HTML page",
        description="Recreates the thesis's figures with the simulator, runs turntable bench, "
        "the controller benchmark and the calibration loop on the thesis's figures; writes "
        "OUT/index.html (self-contained) and OUT/summary.json (every number shown).",
    )
    pr.add_argument("--out", default="report", help="output directory (default: report)")
    pr.add_argument("--quick", action="store_true", help="shortened run (for tests)")
    pr.add_argument("--no-progress", action="store_true", help="no progress bar")
    pr.set_defaults(func=_cmd_report)


def build_parser() -> argparse.ArgumentParser:
    """The command line: one subcommand per ``_add_*`` below."""
    p = _Parser(prog="turntable", description="piezo stick-slip turntable tools")
    p.add_argument("--version", action="version", version=f"turntable {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for add in (_add_params, _add_simulate, _add_bench, _add_benchmark, _add_virtual_lab,
                _add_calibrate, _add_report):  # fmt: skip
        add(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run a subcommand. Exit codes: 0 done, 2 bad input (one line on stderr, before any
    work where it can be known), 3 a simulation that failed, 1 an operating-system error
    while working (one line), 130 interrupted."""
    args = build_parser().parse_args(argv)
    try:
        with terminate_cleanly():  # SIGTERM runs the clean-ups Ctrl-C runs
            return int(args.func(args))
    except Terminated:
        print("turntable: terminated", file=sys.stderr)
        return 143
    except ValueError as exc:
        print(f"turntable: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `turntable params --json | head`: the reader has gone
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"turntable: error: {one_line(f'{where}{exc.strerror or exc}')}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("turntable: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
