"""Library entry point of the full model: parameters + drive + duration → response.

>>> from turntable_env.simulation import simulate, stepping_drive
>>> drive, params = stepping_drive("real", amplitude=2.0, frequency=100.0, periods=3)
>>> r = simulate(params, {"B": drive}, axis="B")          # doctest: +SKIP
>>> r.step_size, r.to_pandas(), r.plot()                  # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import replace
from typing import Literal

import numpy as np

from .drive import DriveSignal, Waveform
from .model import AXES, TurntableModel
from .params import ParameterSet
from .plant import parameter_set
from .response import ENERGY_TERMS, TurntableResponse
from .validation import check_nonnegative, check_positive

__all__ = [
    "AMPLIFIER_MODES",
    "TWO_DIRECTIONAL_CYCLES",
    "cycle_minima",
    "simulate",
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
    params: ParameterSet | Literal["real", "thesis"],
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
    """Run the full 3-D model from static equilibrium.

    Args:
        params: parameter set or its name.
        drive: channel → signal, or one :class:`DriveSignal` applied to ``axis``.
        duration: simulated time [s]; default: the drive's duration plus ``settle``.
        axis: the axis under test (A, B, C or Z): detector and steps refer to it.
        settle: extra time after the drive when ``duration`` is not given [s].
        dt_factor: integration step as a fraction of 1/ω_max (see :class:`TurntableModel`).
        dt: explicit integration step [s] (overrides ``dt_factor``).
        coarse_factor: adaptive step — coarse_factor/ω_max while the turntable is quiet,
            the fine step otherwise (see :meth:`TurntableModel.run`); None: fixed step.
        output_dt: sample interval of the response [s].
        model: a prebuilt :class:`TurntableModel` for ``params`` (saves the packing).

    Raises:
        ValueError: invalid arguments (naming the field).
        SimulationError: the state diverged (naming the time and the state variable).
    """
    ps = parameter_set(params) if isinstance(params, str) else params
    if axis not in AXES:
        raise ValueError(f"axis={axis!r}: must be one of {', '.join(AXES)}")
    drives = {axis: drive} if isinstance(drive, DriveSignal | Waveform) else dict(drive)
    check_nonnegative("settle", settle)
    if duration is None:
        ends = [
            d.start + d.duration if isinstance(d, DriveSignal) else d.end for d in drives.values()
        ]
        duration = max([*ends, 0.0]) + settle
    dur = check_positive("duration", duration)
    mdl = model if model is not None else TurntableModel(ps)
    if mdl.params is not ps and model is not None:
        raise ValueError("model: was built for another parameter set")
    wall0 = time.perf_counter()
    raw = mdl.run(
        drives, dur, dt_factor=dt_factor, dt_max=dt, coarse_factor=coarse_factor,
        output_dt=output_dt,
    )  # fmt: skip
    wall = time.perf_counter() - wall0
    st, ct, en = raw["state"], raw["contact"], raw["energy"]
    main = drives.get(axis)
    if isinstance(main, DriveSignal):
        n_total = main.total_periods
        starts = main.start + np.arange(n_total + 1) / main.frequency
        starts = starts[starts <= st[-1, 0] + 1e-12]
    else:
        starts = np.empty(0)
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
        info={
            "params": ps.name,
            "drive": {k: repr(v) for k, v in drives.items()},
            "dt": raw["dt"],
            "n_steps": raw["n_steps"],
            "n_coarse": raw["n_coarse"],
            "wall_s": wall,
        },
    )


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
