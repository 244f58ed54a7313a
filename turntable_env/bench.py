"""``turntable bench``: speed and accuracy of every simulator path on one scenario.

Standard scenario (issue "fast simulation"): real parameters, axis B, one-directional
input of 2 V (90 V on the tubes) at 100 Hz, a = 0.95, adapted amplifier, 1 s simulated.

For each path — full 3-D model (adaptive step), reduced per-axis model, the reduced
model batched (N turntables in one call), and a plain ``scipy.integrate.solve_ivp``
implementation of the reduced model — it measures, in one process:

* the real-time factor (simulated s / wall s), after a warm-up call;
* the step-size error: mean |step| of the first ``REF_PERIODS`` periods against a
  converged reference of the same equations (the step halved until the step size
  changes by < 0.1 %; the SciPy path, which integrates the reduced equations, is
  compared with the reduced model's converged reference over its own window);
* peak traced memory (``tracemalloc``: NumPy and Python allocations) in a separate call
  (full model: the reference window; SciPy: its first 1 ms);
* the JIT compile (or cache-load) time of the compiled kernels, separately;
* environment throughput (:func:`env_throughput`): ``PiezoTurntable-v0`` steps per second
  at the default 10 ms control interval, single env and native vector env (N = 64),
  reduced model, for uniformly random actions and for the nominal drive;
* the per-axis model's step against the 3-D model's over a drive sweep
  (:func:`reduced_vs_full_sweep`), as it is (``reduced_vs_full_*``) and with the sphere's
  translation and tilts (``reduced_translation_vs_full_*``, the ``"translation"`` fidelity);
  ``env_vs_full*`` and ``env_rtf`` repeat the figures of the env's default model
  (``env_fidelity``, :data:`~turntable_env.envs.config.DEFAULT_FIDELITY`).
"""

from __future__ import annotations

import dataclasses
import itertools
import time
import tracemalloc
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .baseline import simulate_scipy
from .envs.config import DEFAULT_FIDELITY
from .reduced import ReducedModel, simulate_batch
from .simulation import simulate, stepping_drive
from .validation import check_int, check_positive

__all__ = [
    "STANDARD",
    "SWEEP",
    "accuracy_sweep",
    "converge",
    "env_throughput",
    "full_reference_steps",
    "period_step",
    "reduced_vs_full_sweep",
    "run_bench",
    "sweep_drive",
    "vs_full_summary",
]

STANDARD = {"amplitude": 2.0, "frequency": 100.0, "a": 0.95, "amplifier": "adapted"}
REF_PERIODS = 10  # periods over which step errors are measured
# s: the simulated time a bench may take, from one drive period of the standard scenario
# (its kernel profile counts steps per period: a shorter run has none to count) to a minute
DURATION_RANGE = (1.0 / STANDARD["frequency"], 60.0)
FULL_FINE, FULL_COARSE = 0.05, 0.5  # full model's adaptive step (fractions of 1/ω_max)
SCIPY_RTOL = 1e-4
OUTPUT_DT = 1e-4  # s, output interval of the timed reduced runs and of their step errors
REPEATS = 3  # timed runs of the reduced paths; the best counts (the machine is shared)
# the accuracy sweep: one factor at a time about the standard scenario, both directions
SWEEP = {
    "amplitude": (20.0 / 45.0, 2.0, 200.0 / 45.0),  # V input: 20, 90, 200 V on the tubes
    "frequency": (10.0, 100.0, 2000.0),  # Hz
    "a": (0.5, 0.95, 0.99),  # ramp ratio
    "amplifier": ("ideal", "adapted", "unadapted"),
}
SWEEP_PERIODS = 3  # periods per case (the mean |step| of the last two)
SWEEP_HALVINGS = 5  # at most; the reference is the last halving
SCIPY_WINDOW = 0.011  # s simulated by the SciPy baseline (one flyback)
# reduced vs 3-D over the drive range (issue 32): every combination, both directions
VS_FULL = {
    "amplifier": ("adapted", "unadapted", "ideal"),
    "amplitude_V": (20.0, 90.0, 200.0),  # on the tubes (input × 45)
    "frequency_Hz": (10.0, 100.0, 2000.0),
    "a": (0.5, 0.95, 0.99),
}
VS_FULL_QUICK = {"amplifier": ("adapted",), "amplitude_V": (90.0,), "frequency_Hz": (100.0,),
                 "a": (0.95,)}  # fmt: skip
VS_FULL_PERIODS = 3
STEP_FLOOR_NM = 1.0  # nm per period: below it a relative difference measures nothing
# the 3-D reference's fixed step (fraction of 1/ω_max): the fine step throughout, where
# the adaptive step's coarse quiet stretches move a 1–2 nm step by up to 5 %
FULL_REFERENCE_DT_FACTOR = FULL_FINE


def converge(
    step_size: Callable[[float], float], h0: float, tol: float = 1e-3, max_halvings: int = 6
) -> tuple[float, list[tuple[float, float]]]:
    """Halve the step parameter from h0 until the step size changes by < tol (relative).

    Returns (converged step size, [(step parameter, step size), ...])."""
    hist = [(h0, step_size(h0))]
    for _ in range(max_halvings):
        h = hist[-1][0] / 2
        hist.append((h, step_size(h)))
        if abs(hist[-1][1] - hist[-2][1]) < tol * abs(hist[-1][1]):
            break
    return hist[-1][1], hist


def _timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    """(result, wall s)."""
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _peak(fn: Callable[[], Any]) -> tuple[Any, float]:
    """(result, peak traced MiB); a separate call, since tracing slows Python code."""
    tracemalloc.start()
    out = fn()
    _cur, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return out, peak / 2**20


def _best(fn: Callable[[], Any], repeats: int = REPEATS) -> float:
    """Shortest wall time [s] of ``repeats`` calls."""
    return min(_timed(fn)[1] for _ in range(repeats))


def sweep_cases(quick: bool = False) -> list[dict[str, Any]]:
    """The accuracy sweep's scenarios: each factor of :data:`SWEEP` varied alone about
    :data:`STANDARD`, both directions (``quick``: the standard and the unadapted case)."""
    cases: list[dict[str, Any]] = []
    for key, values in SWEEP.items():
        for v in values:
            case = {**STANDARD, key: v}
            if case not in cases and (not quick or (key == "amplifier" and v == "unadapted")):
                cases.append(case)
    if quick:
        cases.insert(0, dict(STANDARD))
    return [{**c, "amplitude": sign * c["amplitude"]} for c in cases for sign in (1.0, -1.0)]


def accuracy_sweep(ps: Any, full: Any, quick: bool = False) -> list[dict[str, Any]]:
    """Step error of the reduced model at the timed output setting (:data:`OUTPUT_DT`)
    against its converged reference (:func:`converge` on ``step_scale``, at most
    :data:`SWEEP_HALVINGS` halvings) for every case of :func:`sweep_cases`.

    Returns rows: the case, ``step_um``, ``reference_um``, ``error`` (relative),
    ``converged`` (the last halving changed the step by < 0.1 %)."""
    rows = []
    for case in sweep_cases(quick):
        periods = SWEEP_PERIODS
        drv, ps_case = stepping_drive(ps, periods=periods, **case)  # type: ignore[arg-type]
        dur = periods / case["frequency"]

        def step(scale: float, drv=drv, dur=dur, p=ps_case) -> float:  # type: ignore[no-untyped-def]
            m = ReducedModel(p, "B", step_scale=scale, model=full)
            r = simulate_batch([m], [drv], dur, output_dt=min(OUTPUT_DT, dur / 10))[0]
            return float(np.mean(np.abs(r.steps[1:])))

        fast = step(1.0)
        ref, hist = converge(step, 0.5, max_halvings=SWEEP_HALVINGS - 1)
        rows.append({
            **case,
            "amplitude_V": case["amplitude"] * ps_case.amplifier.gain,
            "step_um": fast * 1e6,
            "reference_um": ref * 1e6,
            "error": abs(fast - ref) / ref,
            "converged": abs(hist[-1][1] - hist[-2][1]) < 1e-3 * abs(hist[-1][1])
            if len(hist) > 1 else False,
        })  # fmt: skip
    return rows


def period_step(steps: np.ndarray, settle: int = 0) -> float:
    """A run's step per period [its unit] from its per-period steps: with ``settle`` = 0
    the mean |step| over every period (``turntable bench``'s measure, the start from rest
    included); with ``settle`` = k, |mean step| over the periods after the first k, the
    steady step (a table that settles after a start-up slip, as under a 20 V triangle,
    steps 0 there). nan without periods after ``settle``."""
    s = np.asarray(steps, dtype=float)[settle:]
    if not s.size:
        return float("nan")
    return float(np.mean(np.abs(s))) if settle == 0 else float(abs(np.mean(s)))


def sweep_drive(case: Mapping[str, Any], periods: int = VS_FULL_PERIODS) -> tuple[Any, Any, float]:
    """One case of :func:`reduced_vs_full_sweep` (``amplifier``, ``amplitude_V`` on the tubes,
    ``frequency_Hz``, ``a``) as its drive of ``periods`` periods, its parameter set (real,
    the case's amplifier) and its output interval [s] (10 µs, or a hundredth of a period
    where that is shorter).

    Raises:
        ValueError: the drive cannot be built (the adapted flyback does not fit the period).
    """
    f = float(case["frequency_Hz"])
    amplitude = float(case["amplitude_V"]) / 45.0  # V input (the tubes' ÷ the gain)
    drive, ps = stepping_drive("real", amplitude=amplitude, frequency=f, periods=periods,
                               a=case["a"], amplifier=case["amplifier"])  # fmt: skip
    return drive, ps, min(1e-5, 0.01 / f)


def full_reference_steps(
    rm: ReducedModel, drive: Any, output_dt: float, dt_factor: float | None = None
) -> np.ndarray:
    """The 3-D model's step in each period of ``drive`` [m] (axis B), converged: a fixed
    step of ``dt_factor`` (default :data:`FULL_REFERENCE_DT_FACTOR`) of 1/ω_max throughout,
    the reference of :func:`reduced_vs_full_sweep` (:func:`period_step` reduces it)."""
    factor = FULL_REFERENCE_DT_FACTOR if dt_factor is None else dt_factor
    r = simulate(rm.params, drive, axis="B", model=rm.full, dt_factor=factor,
                 coarse_factor=None, output_dt=output_dt)  # fmt: skip
    return np.asarray(r.steps, dtype=float)


def reduced_vs_full_sweep(
    quick: bool = False,
    translation: bool = False,
    reference: Sequence[Mapping[str, Any]] | None = None,
    periods: int = VS_FULL_PERIODS,
    settle: int = 0,
) -> list[dict[str, Any]]:
    """Step per period [nm] of the reduced and the 3-D model (real parameters, axis B,
    ``periods`` periods from rest; :func:`period_step`: the mean |step| over them, or with
    ``settle`` = k the steady step after k) for every case of :data:`VS_FULL` (``quick``:
    :data:`VS_FULL_QUICK`), both directions, and their relative difference (reduced/full −
    1; None where the full step is under :data:`STEP_FLOOR_NM` or the adapted flyback does
    not fit the period, with the note); ``translation``: the reduced model with the
    sphere's translation and tilts (:class:`~turntable_env.reduced.TranslationParameters`).
    ``turntable bench`` runs the defaults, :data:`VS_FULL_PERIODS` periods and no settling.

    The 3-D model is the reference, so it runs converged: at its fixed fine step
    (:data:`FULL_REFERENCE_DT_FACTOR` of 1/ω_max), not the adaptive step the speed figures
    time, whose coarse steps through quiet stretches move a 1–2 nm step by up to 5 %
    (``python experiments/reduced_sweep.py --check-reference N`` halves the step on the N
    worst cases). Each row carries both models' step in every period
    (``full_period_steps_nm``, ``reduced_period_steps_nm``). ``reference``: the rows of an
    earlier sweep over the same grid, whose 3-D steps are taken instead of running the 3-D
    model again (the 3-D model does not depend on the reduced model's form).

    Raises:
        ValueError: ``reference`` is not a sweep over this grid (naming the first case
            that differs); ``periods`` < 1 or ``settle`` outside 0…periods − 1.
    """
    n_periods = check_int("periods", periods, lo=1)
    n_settle = check_int("settle", settle, lo=0, hi=n_periods - 1)
    grid = VS_FULL_QUICK if quick else VS_FULL
    keys = ("amplifier", "amplitude_V", "frequency_Hz", "a", "periods", "settle")
    combos = itertools.product(*grid.values(), (1.0, -1.0))
    cases = [dict(zip(keys, (mode, sgn * amp, f, a, n_periods, n_settle), strict=True))
             for mode, amp, f, a, sgn in combos]  # fmt: skip
    if reference is not None:
        if len(reference) != len(cases):
            raise ValueError(f"reference: {len(reference)} rows, the sweep has {len(cases)}")
        for case, r in zip(cases, reference, strict=True):
            got = {k: r.get(k) for k in keys}
            if got != case:
                raise ValueError(f"reference: row {got!r} where the sweep has {case!r}")
    rows: list[dict[str, Any]] = []
    models: dict[str, ReducedModel] = {}
    for k, row in enumerate(cases):
        mode = row["amplifier"]
        try:
            drive, ps, odt = sweep_drive(row, n_periods)
            if mode not in models:
                models[mode] = ReducedModel(ps, "B", translation=translation)
            rm = models[mode]
            if reference is not None and reference[k]["full_step_nm"] is not None:
                full = 1e-9 * np.asarray(reference[k]["full_period_steps_nm"], dtype=float)
            else:
                full = full_reference_steps(rm, drive, odt)  # m per period
            red = simulate_batch([rm], [drive], drive.duration, output_dt=odt)[0].steps
        except ValueError as exc:  # the adapted flyback does not fit the period
            none = dict.fromkeys(("full_step_nm", "reduced_step_nm", "rel_diff",
                                  "full_period_steps_nm", "reduced_period_steps_nm"))  # fmt: skip
            rows.append({**row, **none, "note": str(exc)[:80]})
            continue
        s_full, s_red = period_step(full, n_settle), period_step(red, n_settle)
        ok = s_full * 1e9 >= STEP_FLOOR_NM
        rows.append({**row, "full_step_nm": 1e9 * s_full, "reduced_step_nm": 1e9 * s_red,
                     "rel_diff": s_red / s_full - 1.0 if ok else None,
                     "note": "" if ok else f"full step < {STEP_FLOOR_NM} nm",
                     "full_period_steps_nm": [1e9 * x for x in full],
                     "reduced_period_steps_nm": [1e9 * x for x in red]})  # fmt: skip
    return rows


def vs_full_summary(rows: list[dict[str, Any]], prefix: str = "reduced") -> dict[str, Any]:
    """``turntable bench``'s figures of a :func:`reduced_vs_full_sweep`: the worst |relative
    difference| (``reduced_vs_full_max``) with its case, the median, the share within 5 %
    (``prefix``: the keys' first word, ``"reduced_translation"`` for the translation's)."""
    ok = [r for r in rows if r["rel_diff"] is not None]
    worst = max(ok, key=lambda r: abs(r["rel_diff"]))
    diffs = np.abs([r["rel_diff"] for r in ok])
    return {
        f"{prefix}_vs_full_max": float(abs(worst["rel_diff"])),
        f"{prefix}_vs_full_worst_case": worst,
        f"{prefix}_vs_full_median": float(np.median(diffs)),
        f"{prefix}_vs_full_within_5pct": float(np.mean(diffs <= 0.05)),
        f"{prefix}_vs_full_cases": len(ok),
        f"{prefix}_vs_full_sweep": rows,
    }


def _kernel_profile(info: dict[str, Any], periods: int, wall: float) -> dict[str, float]:
    """A reduced run's steps per drive period and cost per step evaluation [ns] (from its
    ``info``), and the share of the call's ``wall`` [s] spent outside the kernel."""
    evals = info["steps"] + info["rejected"] + info["analytic_evaluations"]
    return {
        "steps_per_period": info["steps"] / periods,
        "rejected_per_period": info["rejected"] / periods,
        "analytic_evaluations_per_period": info["analytic_evaluations"] / periods,
        "ns_per_step_evaluation": 1e9 * info["wall_s"] / evals,
        "python_fraction": 1.0 - info["wall_s"] / wall,
    }


def run_bench(duration: float = 1.0, batch: int = 64, quick: bool = False) -> dict[str, Any]:
    """Run every path on the standard scenario; returns the figures (see module docstring).

    ``quick`` shortens the runs (for tests of the command, not for reported figures)."""
    lo, hi = DURATION_RANGE
    if not lo <= check_positive("duration", duration) <= hi:
        raise ValueError(f"duration={duration!r}: must lie in {lo:g}…{hi:g} s (one drive "
                         f"period of the standard scenario at least)")
    check_int("batch", batch, 1, 4096)
    periods = max(round(duration * STANDARD["frequency"]), 1)
    ref_periods = 2 if quick else REF_PERIODS
    drive, ps = stepping_drive("real", periods=periods, **STANDARD)  # type: ignore[arg-type]
    ref_drive, _ = stepping_drive("real", periods=ref_periods, **STANDARD)  # type: ignore[arg-type]
    t_ref = ref_periods / STANDARD["frequency"]
    out: dict[str, Any] = {"scenario": {**STANDARD, "axis": "B", "duration_s": duration}}

    # --- compile / cache load ----------------------------------------------------------
    t0 = time.perf_counter()
    reduced = ReducedModel(ps, "B")
    simulate_batch([reduced], [ref_drive], 1e-3)  # the serial kernel
    simulate_batch([reduced] * 2, [ref_drive] * 2, 1e-3)  # the parallel one
    simulate(ps, ref_drive, 1e-4, axis="B", model=reduced.full)
    out["compile_s"] = time.perf_counter() - t0

    # --- full model ------------------------------------------------------------------
    full = reduced.full

    def full_run(dur: float, fine: float, coarse: float | None, drv=drive) -> Any:  # type: ignore[no-untyped-def]
        return simulate(
            ps, drv, dur, axis="B", model=full, dt_factor=fine, coarse_factor=coarse,
            output_dt=1e-4,
        )  # fmt: skip

    r, wall = _timed(lambda: full_run(duration, FULL_FINE, FULL_COARSE))
    out["full_rtf"] = duration / wall
    out["full_step_um"] = r.step_size * 1e6
    out["full_profile"] = {
        "steps_per_period": r.info["n_steps"] / periods,
        "coarse_fraction": r.info["n_coarse"] / r.info["n_steps"],
        "us_per_step": 1e6 * r.info["wall_s"] / r.info["n_steps"],
        "python_fraction": 1.0 - r.info["wall_s"] / wall,
    }
    short, out["full_peak_MiB"] = _peak(lambda: full_run(t_ref, FULL_FINE, FULL_COARSE, ref_drive))
    fast = short.step_size
    ref, hist = converge(lambda f: full_run(t_ref, f, None, ref_drive).step_size, FULL_FINE)
    out["full_step_error"] = abs(fast - ref) / ref
    out["full_reference"] = {"dt_factor": hist[-1][0], "step_um": ref * 1e6}

    # --- reduced model: the ladder (default), and the analytic all-stick step ----------
    analytic = ReducedModel(ps, "B", model=full, analytic=True)
    for name, dt in (("", OUTPUT_DT), ("_no_output", duration)):
        out[f"reduced_rtf_analytic{name}"] = duration / _best(
            lambda dt=dt: simulate_batch([analytic], [drive], duration, output_dt=dt)
        )
        out[f"reduced_rtf{name}"] = duration / _best(
            lambda dt=dt: simulate_batch([reduced], [drive], duration, output_dt=dt)
        )
    one_run = lambda: simulate_batch([reduced], [drive], duration, output_dt=OUTPUT_DT)[0]  # noqa: E731
    r, wall = _timed(one_run)
    out["reduced_axis_parameters"] = dataclasses.asdict(reduced.axis_params)
    out["reduced_profile"] = _kernel_profile(r.info, periods, wall)
    _r, out["reduced_peak_MiB"] = _peak(one_run)
    out["reduced_step_um"] = r.step_size * 1e6
    out["reduced_output_dt_s"] = OUTPUT_DT

    def red_step(scale: float, dur: float = t_ref, drv=ref_drive) -> float:  # type: ignore[no-untyped-def]
        m = reduced if scale == 1.0 else ReducedModel(ps, "B", step_scale=scale, model=full)
        return simulate_batch([m], [drv], dur, output_dt=OUTPUT_DT)[0].step_size

    fast = red_step(1.0)
    ref, hist = converge(red_step, 1.0)
    out["reduced_step_error"] = abs(fast - ref) / ref
    fast_an = simulate_batch([analytic], [ref_drive], t_ref, output_dt=OUTPUT_DT)[0].step_size
    out["reduced_step_error_analytic"] = abs(fast_an - ref) / ref
    out["reduced_reference"] = {"step_scale": hist[-1][0], "step_um": ref * 1e6}
    out["reduced_vs_full"] = out["reduced_step_um"] / out["full_step_um"] - 1.0

    # --- the reduced model with the sphere's translation (the "translation" fidelity) ----
    moved = ReducedModel(ps, "B", model=full, translation=True)
    for name, dt in (("", OUTPUT_DT), ("_no_output", duration)):
        out[f"reduced_translation_rtf{name}"] = duration / _best(
            lambda dt=dt: simulate_batch([moved], [drive], duration, output_dt=dt)
        )
    r, wall = _timed(lambda: simulate_batch([moved], [drive], duration, output_dt=OUTPUT_DT)[0])
    out["reduced_translation_step_um"] = 1e6 * r.step_size
    out["reduced_translation_profile"] = _kernel_profile(r.info, periods, wall)

    def moved_step(scale: float) -> float:
        m = moved if scale == 1.0 else ReducedModel(ps, "B", step_scale=scale, model=full,
                                                     translation=True)  # fmt: skip
        return simulate_batch([m], [ref_drive], t_ref, output_dt=OUTPUT_DT)[0].step_size

    fast = moved_step(1.0)
    ref, hist = converge(moved_step, 1.0)
    out["reduced_translation_step_error"] = abs(fast - ref) / ref
    out["reduced_translation_vs_full"] = (
        out["reduced_translation_step_um"] / out["full_step_um"] - 1.0
    )
    plain_rows = reduced_vs_full_sweep(quick)
    out.update(vs_full_summary(plain_rows))
    out.update(vs_full_summary(reduced_vs_full_sweep(quick, translation=True,
                                                     reference=plain_rows),
                               "reduced_translation"))  # fmt: skip
    # the env's default model (issue 32's ``reduced_vs_full``: the model the env runs)
    form = {"reduced": "reduced", "translation": "reduced_translation"}[DEFAULT_FIDELITY]
    out["env_fidelity"] = DEFAULT_FIDELITY
    for key in ("vs_full", "vs_full_max", "vs_full_median", "vs_full_within_5pct", "rtf"):
        out[f"env_{key}"] = out[f"{form}_{key}"]
    sweep = accuracy_sweep(ps, full, quick=quick)
    out["reduced_step_error_sweep"] = sweep
    worst = max(sweep, key=lambda row: row["error"])
    out["reduced_step_error_max"] = worst["error"]
    out["reduced_step_error_worst_case"] = worst

    # --- batched ---------------------------------------------------------------------
    models = [reduced] * batch
    batch_run = lambda: simulate_batch(models, [drive] * batch, duration, output_dt=1e-4)  # noqa: E731
    _rs, wall = _timed(batch_run)
    out["batch"] = batch
    out["batched_rtf_per_turntable"] = duration / wall
    out["batched_rtf_aggregate"] = batch * duration / wall
    _rs, out["batched_peak_MiB"] = _peak(batch_run)

    # --- SciPy baseline --------------------------------------------------------------
    win = min(SCIPY_WINDOW, duration)
    one, _ = stepping_drive("real", periods=1, **STANDARD)  # type: ignore[arg-type]
    (ts, th), wall = _timed(lambda: simulate_scipy(reduced, one, win, rtol=SCIPY_RTOL))
    out["scipy_rtf"] = win / wall
    _sp, out["scipy_peak_MiB"] = _peak(lambda: simulate_scipy(reduced, one, 1e-3, rtol=SCIPY_RTOL))
    out["scipy_window_s"] = win
    step_sp = abs(np.interp(1.0 / STANDARD["frequency"], ts, th) - th[0]) * ps.table.radius
    ref1, _ = converge(lambda s: red_step(s, win, one), 1.0)
    out["scipy_step_error"] = abs(step_sp - ref1) / ref1
    for key in ("full", "reduced", "batched"):
        rtf = out["batched_rtf_aggregate"] if key == "batched" else out[f"{key}_rtf"]
        out[f"{key}_vs_scipy"] = rtf / out["scipy_rtf"]
    out.update(env_throughput(num_envs=batch))
    # the env's default model beside it (``_default`` keys; fewer steps: it is slower)
    default = env_throughput(n_steps=300 if quick else 1000, num_envs=batch,
                             fidelity=DEFAULT_FIDELITY)  # fmt: skip
    out.update({f"{k}_default": v for k, v in default.items() if "steps_per_s" in k})
    return out


def env_throughput(
    n_steps: int = 3000, num_envs: int = 64, seed: int = 0, fidelity: str = "reduced"
) -> dict[str, Any]:
    """Env steps per second of ``PiezoTurntable-v0`` (default kwargs but ``fidelity``: the
    per-axis model by default, whose figures the docs track; ``"translation"`` is the env's
    default, :data:`~turntable_env.envs.config.DEFAULT_FIDELITY`).

    Two action streams: ``random`` — uniform in the action Box (seeded; frequencies are
    log-uniform 10 Hz–2 kHz, 3.7 periods per 10 ms step on average) and ``nominal`` — the
    real turntable's 100 Hz slew-adapted 2 V drive (one stick–slip period per step).
    Episodes are reset when they end (resets included in the time). The vector figure is
    the aggregate over ``num_envs`` turntables of the native vector env.
    """
    import gymnasium as gym

    from .envs import ActionScaling, PiezoTurntableVectorEnv

    nominal = ActionScaling().encode(2.0, 100.0, 0.95, 1.0)
    check_int("n_steps", n_steps, 1)
    check_int("num_envs", num_envs, 1, 4096)
    out: dict[str, Any] = {"env_num_envs": num_envs, "env_throughput_fidelity": fidelity}
    for stream in ("random", "nominal"):
        env = gym.make("PiezoTurntable-v0", fidelity=fidelity)
        env.action_space.seed(seed)
        env.reset(seed=seed)
        acts = [
            env.action_space.sample() if stream == "random" else nominal for _ in range(n_steps)
        ]
        env.step(acts[0])  # warm-up (compile or cache load)
        t0 = time.perf_counter()
        for a in acts:
            _o, _r, term, trunc, _i = env.step(a)
            if term or trunc:
                env.reset()
        out[f"env_steps_per_s_{stream}"] = n_steps / (time.perf_counter() - t0)
        vec = PiezoTurntableVectorEnv(num_envs=num_envs, fidelity=fidelity)
        vec.action_space.seed(seed)
        vec.reset(seed=seed)
        n_vec = max(n_steps // num_envs, 5)
        batch = [
            vec.action_space.sample() if stream == "random" else np.tile(nominal, (num_envs, 1))
            for _ in range(n_vec)
        ]
        vec.step(batch[0])
        stepper = vec.task.stepper
        k0 = stepper.kernel_seconds  # s spent in the compiled integrator so far
        t0 = time.perf_counter()
        for a in batch:
            vec.step(a)
        wall = time.perf_counter() - t0
        in_kernel = stepper.kernel_seconds - k0
        out[f"vector_env_steps_per_s_{stream}"] = num_envs * n_vec / wall
        out[f"vector_env_integrator_fraction_{stream}"] = in_kernel / wall
    out["env_single_steps_per_s"] = out["env_steps_per_s_random"]  # the target keys
    out["env_vector_steps_per_s"] = out["vector_env_steps_per_s_random"]
    return out


def format_env_table(res: dict[str, Any]) -> str:
    """Env throughput as a markdown table (see :func:`env_throughput`)."""
    lines = [
        f"| env steps/s (10 ms interval, {res.get('env_throughput_fidelity', 'reduced')}) | "
        "random actions | nominal 100 Hz drive |",
        "|---|---:|---:|",
        f"| single env | {res['env_steps_per_s_random']:.0f} | "
        f"{res['env_steps_per_s_nominal']:.0f} |",
        f"| native vector env N={res['env_num_envs']} (aggregate) | "
        f"{res['vector_env_steps_per_s_random']:.0f} | "
        f"{res['vector_env_steps_per_s_nominal']:.0f} |",
        f"| vector env: share of time in the compiled integrator | "
        f"{100 * res['vector_env_integrator_fraction_random']:.0f} % | "
        f"{100 * res['vector_env_integrator_fraction_nominal']:.0f} % |",
    ]
    return "\n".join(lines)


def format_table(res: dict[str, Any]) -> str:
    """The bench figures as a markdown table."""
    rows = [
        ("full 3-D (adaptive)", res["full_rtf"], res["full_step_error"], res["full_peak_MiB"],
         res["full_vs_scipy"]),
        ("reduced", res["reduced_rtf"], res["reduced_step_error"], res["reduced_peak_MiB"],
         res["reduced_vs_scipy"]),
        ("reduced with translation", res["reduced_translation_rtf"],
         res["reduced_translation_step_error"], float("nan"),
         res["reduced_translation_rtf"] / res["scipy_rtf"]),
        ("reduced, analytic all-stick steps", res["reduced_rtf_analytic"],
         res["reduced_step_error_analytic"], float("nan"),
         res["reduced_rtf_analytic"] / res["scipy_rtf"]),
        (f"reduced batched N={res['batch']} (aggregate)", res["batched_rtf_aggregate"],
         res["reduced_step_error"], res["batched_peak_MiB"], res["batched_vs_scipy"]),
        ("SciPy solve_ivp (reduced eqs.)", res["scipy_rtf"], res["scipy_step_error"],
         res["scipy_peak_MiB"], 1.0),
    ]  # fmt: skip
    lines = [
        "| path | real-time factor | step error | peak MiB | × SciPy |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, rtf, err, mem, ratio in rows:
        lines.append(f"| {name} | {rtf:.3g} | {100 * err:.2f} % | {mem:.1f} | {ratio:.3g} |")
    fp, rp = res["full_profile"], res["reduced_profile"]
    lines.append(
        f"\nfull: {fp['steps_per_period']:.0f} steps/period ({100 * fp['coarse_fraction']:.0f} % "
        f"coarse), {fp['us_per_step']:.2f} µs/step, Python {100 * fp['python_fraction']:.0f} %; "
        f"reduced: {rp['steps_per_period']:.0f} steps + {rp['rejected_per_period']:.0f} rejected "
        f"per period, {rp['ns_per_step_evaluation']:.0f} ns each, Python "
        f"{100 * rp['python_fraction']:.0f} %"
    )
    worst = res["reduced_step_error_worst_case"]
    lines.append(
        f"reduced step error over the sweep ({len(res['reduced_step_error_sweep'])} cases, "
        f"output every {1e6 * res['reduced_output_dt_s']:.0f} µs): max "
        f"{100 * res['reduced_step_error_max']:.2f} % ({worst['amplitude_V']:+.0f} V, "
        f"{worst['frequency']:g} Hz, a = {worst['a']}, {worst['amplifier']}); without "
        f"output: ladder {res['reduced_rtf_no_output']:.3g}, analytic "
        f"{res['reduced_rtf_analytic_no_output']:.3g}"
    )
    lines.append(
        f"compile/cache load {res['compile_s']:.2f} s; batched per turntable "
        f"{res['batched_rtf_per_turntable']:.3g}; reduced vs full step "
        f"{100 * res['reduced_vs_full']:+.1f} %, with translation "
        f"{100 * res['reduced_translation_vs_full']:+.1f} % (without output: "
        f"{res['reduced_translation_rtf_no_output']:.3g})"
    )
    for pre, name in (("reduced", "reduced"), ("reduced_translation", "with translation")):
        w = res[f"{pre}_vs_full_worst_case"]
        lines.append(
            f"{name} vs full over {res[f'{pre}_vs_full_cases']} cases (full step ≥ "
            f"{STEP_FLOOR_NM:g} nm): median |difference| "
            f"{100 * res[f'{pre}_vs_full_median']:.1f} %, "
            f"{100 * res[f'{pre}_vs_full_within_5pct']:.0f} % within 5 %, max "
            f"{100 * res[f'{pre}_vs_full_max']:.1f} % ({w['amplitude_V']:+.0f} V, "
            f"{w['frequency_Hz']:g} Hz, a = {w['a']}, {w['amplifier']}: full "
            f"{w['full_step_nm']:.3g} nm, reduced {w['reduced_step_nm']:.3g} nm)"
        )
    lines.append(
        f"the env's default model ({res['env_fidelity']!r}) vs full: max "
        f"{100 * res['env_vs_full_max']:.1f} % (env_vs_full_max)"
    )
    if "env_steps_per_s_random" in res:
        lines.append("\n" + format_env_table(res))
    if "env_steps_per_s_random_default" in res:
        lines.append(
            f"default model ({res['env_fidelity']!r}): single env "
            f"{res['env_steps_per_s_random_default']:.0f} / "
            f"{res['env_steps_per_s_nominal_default']:.0f} steps/s (random / nominal), vector "
            f"{res['vector_env_steps_per_s_random_default']:.0f} / "
            f"{res['vector_env_steps_per_s_nominal_default']:.0f}"
        )
    return "\n".join(lines)
