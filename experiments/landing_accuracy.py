"""The per-axis integrator at a trace's own sample spacing, against its converged
reference: how fast, and how far off.

    python experiments/landing_accuracy.py [TRACE.csv ...] [--repeats 3] [--json]

For each trace file (default: the second independent plant's axis-C trace at 20 kHz and
axis-A trace at 10 kHz, and the third plant's clean axis-A trace at 10 kHz; regenerate
them with ``experiments/second_plant_traces.py`` / ``third_plant_traces.py``), its drive
[V at the amplifier's input, piecewise linear between its corners, as
:func:`~turntable_env.calibration.trace.simulate_trace` reads it] runs the nominal per-axis
model (:class:`~turntable_env.reduced.ReducedModel` of the ``"real"`` parameter set, the
calibration's base) from rest, recording at the trace's sample spacing, as a calibration
records it (:func:`~turntable_env.calibration.trace.simulate_trace`). Each recording
stops the integrator: its steps land on every output time.

Printed per trace and per landing rule (``restart``, the default until stop 84,
``ReducedModel(resume_rung=False)``: a step that lands on an output time caps the step
controller's rung, which then grows again by one a step; ``resume``, the default since:
the landing shortens only its own step):
the spacing [µs], the integrator's accepted steps, the kernel's wall time [s] (best of
``--repeats``, compiled before, the two rules alternating), and the angle's difference from the
converged reference (``step_scale`` 1/16: every step bound and the grid a sixteenth,
recording at a quarter of the spacing), at the trace's samples, as a length on the
table's rim [nm] (angle × R_table, the calibration's error unit): RMS, 99th percentile of
|·| and at the end. The reference's own uncertainty is printed beside it (``step_scale``
1/4 against 1/16). Beside them, the restart rule's steps and kernel time recorded once,
at the end: the integrator's steps without the landings. The reference runs and the
``--bounds`` runs take the restart rule too (as before stop 84).

``--bounds F`` (a diagnostic) runs the restart rule again with one step bound at a time
divided by F — the slip step (``reduced.SLIP_STEP``), the ringing step
(``RING_FRACTION``) and the quiet length (``QUIET_LENGTH``), each patched while its model
is built — and prints each one's steps and error, to say which bound the error comes from.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from unittest import mock

import numpy as np

import turntable_env.reduced as reduced
from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.trace import drive_corners
from turntable_env.drive import Waveform
from turntable_env.reduced import ReducedModel, simulate_reduced

ROOT = Path(__file__).resolve().parents[1]
TRACES = (
    ROOT / "experiments" / "results" / "second_plant_traces" / "axis_C_20kHz.csv",
    ROOT / "experiments" / "results" / "second_plant_traces" / "axis_A_10kHz.csv",
    ROOT / "experiments" / "results" / "third_plant_traces" / "clean_axis_A_10kHz.csv",
)
REFERENCE_SCALE = 1.0 / 16.0  # step_scale of the converged reference
CHECK_SCALE = 0.25  # … and of its check


RULES = {"restart": False, "resume": True}  # ReducedModel's resume_rung
BOUNDS = ("SLIP_STEP", "RING_FRACTION", "QUIET_LENGTH")  # reduced's step bounds (--bounds)


def _run(wave: Waveform, axis: str, duration: float, dt: float, scale: float,
         resume: bool = False):  # fmt: skip
    mdl = ReducedModel("real", axis, step_scale=scale, resume_rung=resume)
    return simulate_reduced("real", wave, duration, axis=axis, output_dt=dt, model=mdl)


def _at(resp, t: np.ndarray) -> np.ndarray:
    """The response's angle at times t [s], as a length on the table's rim [nm]."""
    return np.interp(t, resp.time, resp.angle_rad) * resp.table_radius * 1e9


def _stats(d: np.ndarray) -> dict[str, float]:
    return {"rms_nm": float(np.sqrt(np.mean(d**2))),
            "p99_nm": float(np.percentile(np.abs(d), 99)), "end_nm": float(d[-1])}  # fmt: skip


def measure(path: Path, repeats: int, bound_factor: float | None = None) -> dict:
    """One trace's row (module docstring)."""
    m = load_measurement(path)
    t = m.time - m.time[0]
    (drive,) = m.drives.values() if isinstance(m.drives, dict) else (m.drives[0],)
    u = np.asarray(drive, dtype=float)
    keep = drive_corners(t, u)  # as a calibration reads it: breakpoints at the corners
    wave = Waveform(t[keep], u[keep])
    dt = float(np.median(np.diff(t)))
    dur = float(t[-1])
    runs = {rule: [] for rule in RULES}
    once = []  # the restart rule recorded once, at the end: the steps without landings
    for _ in range(repeats + 1):  # the first of each compiles; the rules alternate
        for rule, resume in RULES.items():
            runs[rule].append(_run(wave, m.axis, dur, dt, 1.0, resume))
        once.append(_run(wave, m.axis, dur, dur, 1.0))
    ref = _run(wave, m.axis, dur, dt / 4.0, REFERENCE_SCALE)
    check = _run(wave, m.axis, dur, dt / 4.0, CHECK_SCALE)
    a_ref = _at(ref, t)
    name = str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)
    bounds = {}
    for bound in BOUNDS if bound_factor else ():
        with mock.patch.object(reduced, bound, getattr(reduced, bound) / bound_factor):
            r = _run(wave, m.axis, dur, dt, 1.0)
        bounds[bound] = {"steps": r.info["steps"], "error": _stats(_at(r, t) - a_ref)}
    return {"trace": name, "spacing_us": dt * 1e6,
            "rules": {rule: {"steps": rs[-1].info["steps"],
                             "kernel_s": min(r.info["wall_s"] for r in rs[1:]),
                             "error": _stats(_at(rs[-1], t) - a_ref)}
                      for rule, rs in runs.items()},
            "reference_uncertainty": _stats(_at(check, t) - a_ref),
            "bounds": bounds, "bound_factor": bound_factor,
            "recorded_once": {"steps": once[-1].info["steps"],
                              "kernel_s": min(r.info["wall_s"] for r in once[1:])}}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("traces", nargs="*", type=Path, default=list(TRACES))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    ap.add_argument("--bounds", type=float, default=None, metavar="F",
                    help="also each step bound divided by F, one at a time (a diagnostic)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        print(f"--repeats={args.repeats}: must be >= 1", file=sys.stderr)
        return 2
    if args.bounds is not None and not args.bounds > 1.0:
        print(f"--bounds={args.bounds}: must be > 1", file=sys.stderr)
        return 2
    for p in args.traces:
        if not p.is_file():
            print(f"{p}: no such trace file (see the module docstring)", file=sys.stderr)
            return 2
    rows = [measure(p, args.repeats, args.bounds) for p in args.traces]
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print(f"{'trace':<56} {'rule':<8} {'µs':>5} {'steps':>8} {'kernel s':>9}  "
          "error vs reference [nm]: rms / p99 / end")  # fmt: skip
    for r in rows:
        for rule, v in r["rules"].items():
            e = v["error"]
            print(f"{r['trace']:<56} {rule:<8} {r['spacing_us']:5.1f} {v['steps']:8d} "
                  f"{v['kernel_s']:9.4f}  {e['rms_nm']:.3f} / {e['p99_nm']:.3f} / "
                  f"{e['end_nm']:+.3f}")  # fmt: skip
        o = r["recorded_once"]
        print(f"{'':<56} {'(restart, recorded once)':<14} {o['steps']:8d} "
              f"{o['kernel_s']:9.4f}")  # fmt: skip
        u = r["reference_uncertainty"]
        print(f"{'':<56} {'(reference step_scale 1/4 against 1/16)':<43}  {u['rms_nm']:.3f} / "
              f"{u['p99_nm']:.3f} / {u['end_nm']:+.3f}")  # fmt: skip
        for bound, v in r["bounds"].items():
            e = v["error"]
            print(f"{'':<56} {bound + ' / ' + format(r['bound_factor'], 'g'):<22} "
                  f"{v['steps']:8d} {'':9}  {e['rms_nm']:.3f} / {e['p99_nm']:.3f} / "
                  f"{e['end_nm']:+.3f}")  # fmt: skip
        ratio = r["rules"]["restart"]["kernel_s"] / r["rules"]["resume"]["kernel_s"]
        print(f"{'':<56} resume faster by {ratio:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
