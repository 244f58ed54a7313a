"""Library entry point of the full model: parameters + drive + duration → response.

>>> from turntable_env.simulation import simulate, stepping_drive
>>> drive, params = stepping_drive("real", amplitude=2.0, frequency=100.0, periods=3)
>>> r = simulate(params, {"B": drive}, axis="B")          # doctest: +SKIP
>>> r.step_size, r.to_pandas(), r.plot()                  # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Literal

import numpy as np

from .drive import DriveSignal, Waveform
from .effects import CATALOGUE, apply_input, input_active
from .model import AXES, TurntableModel
from .params import ParameterSet
from .plant import Plant, as_plant, parameter_set, reduced_model
from .reduced import REDUCED_AXES, AxisResponse, simulate_batch
from .response import ENERGY_TERMS, TurntableResponse
from .validation import check_nonnegative, check_positive

MAX_DURATION = 1000.0  # s of turntable time one simulate run may cover
MAX_STEPS = 1e10  # fine integration steps (duration·ω_max/dt_factor, or duration/dt) of a 3-D run
MAX_OUTPUT_SAMPLES = 20_000_000  # samples one run may record (≈ 1 GB of response arrays)


def check_output_samples(
    duration: float, output_dt: float, n_runs: int = 1, name: str = "output_dt"
) -> None:
    """ValueError naming ``name`` (the sample interval's, ``output_dt`` [s]) where ``n_runs``
    runs over ``duration`` [s] would record more than :data:`MAX_OUTPUT_SAMPLES` samples,
    before any array is allocated."""
    n = check_positive("duration", duration) / check_positive(name, output_dt) * n_runs
    if n > MAX_OUTPUT_SAMPLES:
        raise ValueError(
            f"{name}={output_dt:g} s over {duration:g} s would record {n:.3g} samples, "
            f"more than {MAX_OUTPUT_SAMPLES:g}: raise {name}"
        )

__all__ = [
    "AMPLIFIER_MODES",
    "MAX_DURATION",
    "MAX_OUTPUT_SAMPLES",
    "MAX_STEPS",
    "TWO_DIRECTIONAL_CYCLES",
    "check_output_samples",
    "cycle_minima",
    "simulate",
    "simulate_axes",
    "stepping_drive",
]

AMPLIFIER_MODES = ("adapted", "unadapted", "ideal")
TWO_DIRECTIONAL_CYCLES = 3  # Fig. 4.6's forward-and-back cycles (its block is the last's)


def stepping_drive(
    params: ParameterSet | Literal["real", "thesis"] = "real",
    *,
    amplitude: float = 2.0,
    frequency: float | None = None,
    periods: int = 10,
    signal: Literal["one", "two"] = "one",
    amplifier: Literal["adapted", "unadapted", "ideal"] | None = None,
    a: float | None = None,
    slew_adaptation: float = 1.0,
    cycles: int | None = None,
) -> tuple[DriveSignal, ParameterSet]:
    """The §4.1.3 stepping input and the amplifier mode, as (drive, parameter set).

    With the HVA 900 model the flyback is an input step at a/f, as in the laboratory
    (§4.1.2–4.1.3): ``"adapted"`` adds the Fig. 4.3 overshoot (k = ``slew_adaptation``);
    ``"unadapted"`` is the plain step, slewing at the amplifier's natural 0.9 V/µs per
    input volt. ``"ideal"`` is an instant source (the thesis's simulations) with the set's
    nominal flyback. Defaults come from the set: ``amplifier`` "ideal" if its amplifier
    is ideal (thesis) else "adapted"; ``frequency`` its nominal frequency; ``a`` its ramp
    ratio. ``amplitude`` is the amplifier input [V] (2 V → 90 V on the tubes); ``cycles``
    of a two-directional signal default to ``TWO_DIRECTIONAL_CYCLES`` (Fig. 4.6 is read on
    the last, after a reversal: :meth:`~turntable_env.response.SteppingMetrics.figure_step`).
    """
    ps = parameter_set(params) if isinstance(params, str) else params
    if amplifier is None:
        amplifier = "ideal" if ps.amplifier.ideal else "adapted"
    if amplifier not in AMPLIFIER_MODES:
        raise ValueError(f"amplifier={amplifier!r}: must be one of {', '.join(AMPLIFIER_MODES)}")
    k = check_nonnegative("slew_adaptation", slew_adaptation) if amplifier == "adapted" else 0.0
    ps = replace(ps, amplifier=replace(ps.amplifier, ideal=(amplifier == "ideal")))
    drive = DriveSignal(
        amplitude=amplitude,
        frequency=ps.nominal_frequency if frequency is None else frequency,
        a=ps.ramp_ratio if a is None else a,
        n_periods=periods,
        pattern=signal,
        slew_adaptation=k,
        flyback=ps.nominal_flyback if amplifier == "ideal" else "step",
        n_cycles=(TWO_DIRECTIONAL_CYCLES if signal == "two" else 1) if cycles is None else cycles,
    )
    return drive, ps


def simulate(
    plant: Plant | ParameterSet | str,
    drive: Mapping[str, DriveSignal | Waveform] | DriveSignal,
    duration: float | None = None,
    *,
    axis: str = "B",
    settle: float = 0.0,
    dt_factor: float = 0.05,
    dt: float | None = None,
    coarse_factor: float | None = None,
    output_dt: float = 1e-5,
    model: TurntableModel | None = None,
) -> TurntableResponse:
    """Run the full 3-D model of a plant from static equilibrium.

    The plant's stages run as in :class:`~turntable_env.plant.PlantStepper`: its parameter
    set (base × factors, parameter-stage effects), the input stage (piezo hysteresis and
    creep, :func:`~turntable_env.effects.apply_input`) on each channel's input, and the
    output stage (:func:`~turntable_env.effects.detector_stage`) in the response's
    detector voltage. The friction stage updates μ from the motion segment by segment,
    which only the stepper does: a plant with such an effect is refused here.

    Args:
        plant: a :class:`~turntable_env.plant.Plant`, a parameter set (the plant on it,
            :func:`~turntable_env.plant.as_plant`) or a name (``"calibrated"``: the
            store's plant, whole).
        drive: channel → signal, or one :class:`DriveSignal` applied to ``axis``.
        duration: simulated time [s]; default: the drive's duration plus ``settle``.
        axis: the axis under test (A, B, C or Z): detector and steps refer to it.
        settle: extra time after the drive when ``duration`` is not given [s].
        dt_factor: integration step as a fraction of 1/ω_max (see :class:`TurntableModel`).
        dt: explicit integration step [s] (overrides ``dt_factor``).
        coarse_factor: adaptive step — coarse_factor/ω_max while the turntable is quiet,
            the fine step otherwise (see :meth:`TurntableModel.run`); None: fixed step.
        output_dt: sample interval of the response [s].
        model: a prebuilt :class:`TurntableModel` for the plant's parameter set.

    Raises:
        ValueError: invalid arguments (naming the field).
        SimulationError: the state diverged (naming the time and the state variable).
    """
    pl = _runnable(plant)
    ps = pl.params
    if axis not in AXES:
        raise ValueError(f"axis={axis!r}: must be one of {', '.join(AXES)}")
    drives = {axis: drive} if isinstance(drive, DriveSignal | Waveform) else dict(drive)
    _check_amplitudes(drives.values(), pl)
    check_nonnegative("settle", settle)
    if duration is None:
        duration = _drive_end(drives.values()) + settle
    dur = check_positive("duration", duration)
    if dur > MAX_DURATION:
        raise ValueError(f"duration={dur!r}: more than {MAX_DURATION:g} s of turntable time")
    check_output_samples(dur, output_dt)
    if model is not None and not isinstance(model, TurntableModel):
        raise ValueError(f"model={type(model).__name__}: must be a TurntableModel (or None)")
    mdl = model if model is not None else TurntableModel(ps)
    if mdl.params is not ps and model is not None:
        raise ValueError("model: was built for another parameter set")
    if dt is not None:
        step = check_positive("dt", dt)  # s
    else:
        step = check_positive("dt_factor", dt_factor) / mdl.omega_max  # s
    if dur / step > MAX_STEPS:  # refused before the run, which would not end for hours
        raise ValueError(
            f"dt={dt!r}, dt_factor={dt_factor!r}: {dur / step:.3g} integration steps over "
            f"{dur:g} s (ω_max = {mdl.omega_max:.4g} rad/s), more than {MAX_STEPS:g}"
        )
    given = drives  # the drive as commanded (its periods give the step detection)
    if bool(input_active(pl.effect_row)):  # the piezo's input stage on each channel's input
        drives = {k: _input_staged(w, pl, dur) for k, w in mdl.drive_waveforms(drives).items()}
    wall0 = time.perf_counter()
    raw = mdl.run(
        drives, dur, dt_factor=dt_factor, dt_max=dt, coarse_factor=coarse_factor,
        output_dt=output_dt,
    )  # fmt: skip
    wall = time.perf_counter() - wall0
    st, ct, en = raw["state"], raw["contact"], raw["energy"]
    main = given.get(axis)
    starts = main.period_starts(st[-1, 0]) if isinstance(main, DriveSignal) else np.empty(0)
    return TurntableResponse(
        time=st[:, 0].copy(),
        centre_displacement=st[:, 1:4].copy(),
        rotation_vector=st[:, 4:7].copy(),
        angular_velocity=st[:, 7:10].copy(),
        channel_voltage=st[:, 10:14].copy(),
        normal_force=ct[:, :, 0].copy(),
        friction_force=ct[:, :, 1:3].copy(),
        slip_speed=ct[:, :, 3].copy(),
        n_stick=ct[:, :, 4].astype(np.int64),
        overlap=ct[:, :, 5].copy(),
        tube_displacement=raw["xi"].copy(),
        energy={name: en[:, i].copy() for i, name in enumerate(ENERGY_TERMS)},
        axis_units=mdl.layout.axis_units.copy(),
        axis=axis,
        detector=ps.detector,
        table_radius=ps.table.radius,
        period_starts=starts,
        effect_row=pl.effect_row if _output_effects(pl) else None,
        info={
            "params": ps.name,
            "plant": repr(pl if pl.fidelity == "full" else replace(pl, fidelity="full")),
            "drive": {k: repr(v) for k, v in given.items()},
            "dt": raw["dt"],
            "n_steps": raw["n_steps"],
            "n_coarse": raw["n_coarse"],
            "wall_s": wall,
        },
    )


def simulate_axes(
    plants: Sequence[Plant | ParameterSet | str],
    drives: Sequence[DriveSignal | Waveform],
    duration: float | None = None,
    *,
    axis: str = "B",
    settle: float = 0.0,
    output_dt: float = 1e-5,
) -> list[AxisResponse]:
    """Run N plants' reduced models about ``axis`` together, from rest, in one compiled call
    (:func:`~turntable_env.reduced.simulate_batch`): the batched form of :func:`simulate`,
    with the plants' stages as there (parameters, input stage on the drive, output stage in
    each response's detector voltage; friction-stage effects refused).

    Args:
        plants: one plant per turntable (:func:`~turntable_env.plant.as_plant`).
        drives: one channel input per turntable (DriveSignal or Waveform, starting at 0).
        duration: simulated time [s]; default: the longest drive plus ``settle``.
        axis: A, B or C.
        settle: extra time after the drives when ``duration`` is not given [s].
        output_dt: sample interval [s], a multiple of the reduced model's grid.

    Raises:
        ValueError: mismatched lengths, a bad plant or axis (naming it).
    """
    if len(plants) != len(drives) or not plants:
        raise ValueError(
            f"plants/drives: need equal, non-zero lengths ({len(plants)}, {len(drives)})"
        )
    if axis not in REDUCED_AXES:
        raise ValueError(f"axis={axis!r}: the reduced model covers {', '.join(REDUCED_AXES)}")
    resolved = [_runnable(p) for p in plants]
    for p, d in zip(resolved, drives, strict=True):
        _check_amplitudes([d], p)
    check_nonnegative("settle", settle)
    if duration is None:
        duration = _drive_end(drives) + settle
    check_output_samples(duration, output_dt, len(resolved))
    models = [reduced_model(p.params, axis, p.fidelity == "translation") for p in resolved]
    inputs: list[DriveSignal | Waveform] = []
    for p, m, d in zip(resolved, models, drives, strict=True):
        if bool(input_active(p.effect_row)):  # the piezo's input stage on the channel input
            inputs.append(_input_staged(m.full.drive_waveforms({axis: d})[axis], p, duration))
        else:
            inputs.append(d)
    runs = simulate_batch(models, inputs, check_positive("duration", duration), output_dt=output_dt)
    out = []
    for p, d, r in zip(resolved, drives, runs, strict=True):
        starts = d.period_starts(r.time[-1]) if isinstance(d, DriveSignal) else r.period_starts
        row = p.effect_row if _output_effects(p) else None
        info = {**r.info, "plant": repr(p)}
        out.append(replace(r, period_starts=starts, effect_row=row, info=info))
    return out


def _drive_end(drives: Iterable[DriveSignal | Waveform]) -> float:
    """The end of the longest drive [s] (0 for none)."""
    ends = [d.start + d.duration if isinstance(d, DriveSignal) else d.end for d in drives]
    return max([*ends, 0.0])


def _check_amplitudes(drives: Iterable[object], plant: Plant) -> None:
    """ValueError where a stepping drive's amplitude [V] exceeds the plant's amplifier
    input limit (§4.1.1: ±10 V): the amplifier would clip its sawtooth into another one."""
    limit = plant.params.amplifier.input_limit  # V
    for d in drives:
        if isinstance(d, DriveSignal) and abs(d.amplitude) > limit:
            raise ValueError(
                f"amplitude={d.amplitude!r}: beyond the amplifier's ±{limit:g} V input"
            )


def _input_staged(wave: Waveform, plant: Plant, end: float) -> Waveform:
    """The plant's input stage on a channel's input, held to ``end`` [s] so that states
    with memory (creep) go on after the last breakpoint."""
    t, u = wave.times, wave.values
    if t[-1] < end:
        t, u = np.append(t, end), np.append(u, u[-1])
    return Waveform(*apply_input(t, u, plant.effects))


def _runnable(plant: Plant | ParameterSet | str) -> Plant:
    """The plant, refused where it has a friction-stage effect (only the stepper runs it)."""
    pl = as_plant(plant)
    for name in pl.effects:
        if CATALOGUE[name].stage == "friction":
            raise ValueError(
                f"plant.effects[{name!r}]: a friction-stage effect runs only through "
                "PlantStepper (the env), not simulate()"
            )
    return pl


def _output_effects(plant: Plant) -> bool:
    return any(CATALOGUE[name].stage == "output" for name in plant.effects)


def cycle_minima(response: TurntableResponse, drive: DriveSignal) -> tuple[list[float], float]:
    """The smallest angle [rad] in each forward-and-back cycle of a two-directional drive
    (Fig. 4.10: "the differences between the minimum values of cycles", §4.3), and the
    whole excursion max θ − min θ [rad]."""
    if drive.pattern != "two":
        raise ValueError(f"drive.pattern={drive.pattern!r}: cycle minima need a two-way drive")
    a, t = response.angle(), response.time
    period = 2 * drive.n_periods / drive.frequency  # s per cycle
    mins = [
        float(a[(t >= c * period) & (t < (c + 1) * period)].min()) for c in range(drive.n_cycles)
    ]
    return mins, float(a.max() - a.min())
