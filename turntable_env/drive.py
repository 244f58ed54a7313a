"""Drive signals: sawtooth (Fig. 3.14), inputs of Fig. 4.5, slew-adapted input (Fig. 4.3).

All functions are vectorised over a time array [s] and return the amplifier
*input* voltage [V] (the thesis's 2 V signals become 90 V on the tubes).

* :func:`sawtooth` — Fig. 3.14: rises linearly from 0 to the amplitude over the
  fraction ``a`` of each period, falls back over the rest (flyback), zero
  outside [start, stop).
* :func:`one_directional` — Fig. 4.5: ``n_periods`` sawtooth periods; the sign of
  the amplitude sets the direction.
* :func:`two_directional` — Fig. 4.5: ``n_per_direction`` periods one way, then
  as many back (amplitude negated, or the time-mirrored sawtooth), repeated
  ``n_cycles`` times; the table should return to its start (§4.3).
* :func:`slew_adapted` — Fig. 4.3: the flyback is an input step that first
  overshoots to −k·amplitude and returns to 0 after ``hold_time`` (from
  :meth:`turntable_env.amplifier.Amplifier.adapted_hold_time`).
* :class:`DriveSignal` — one object that composes these for the simulator.
* :class:`StepSetting` and :func:`generator_segment` — a free-running, phase-continuous
  generator for closed-loop control: each control interval gets a setting, which
  takes over at the next period start (a running period is never cut);
  :func:`generator_flybacks` counts the steps it starts in an interval.
* :class:`Waveform` — a piecewise-linear amplifier input given by breakpoints
  (jumps are two breakpoints at the same time). Every signal above is piecewise
  linear, so :meth:`DriveSignal.waveform` represents it exactly; the simulator
  lands its steps on the breakpoints, so flyback edges are never smeared.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .amplifier import Amplifier
from .generator import (
    MODE_ADAPTED,
    MODE_RAMP,
    MODE_STEP,
    TEMPLATE_POINTS,
    adapted_hold,
    capacitive_energy_nb,
    flybacks_nb,
    grid_points_nb,
    interval_capacity,
    segment_nb,
    template_nb,
)
from .validation import (
    check_array_finite,
    check_finite,
    check_in_open,
    check_nonnegative,
    check_positive,
)

__all__ = [
    "DriveSignal",
    "StepSetting",
    "Waveform",
    "capacitive_energy",
    "generator_flybacks",
    "generator_segment",
    "grid_breakpoints",
    "one_directional",
    "sawtooth",
    "slew_adapted",
    "two_directional",
]


def _common(t, amplitude, frequency, a):
    tt = check_array_finite("t", t)
    amp = check_finite("amplitude", amplitude)
    f = check_positive("frequency", frequency)
    aa = check_in_open("a", a, 0.0, 1.0)
    return tt, amp, f, aa


def _check_span(start: float, stop: float) -> tuple[float, float]:
    """Validated [start, stop) in s; ``stop`` may be ``inf``."""
    t0 = check_finite("start", start)
    t1 = float(stop)
    if math.isnan(t1) or t1 <= t0:
        raise ValueError(f"stop={stop!r}: must be > start={start!r}")
    return t0, t1


def _forward(tt: np.ndarray, start: float, frequency: float, n: int) -> np.ndarray:
    """True in the forward half of each 2n-period two-directional cycle (Fig. 4.5)."""
    period_index = np.floor((tt - start) * frequency)
    return np.mod(period_index, 2 * n) < n


def _window(tt: np.ndarray, start: float, stop: float) -> np.ndarray:
    return (tt >= start) & (tt < stop)


def sawtooth(
    t: np.ndarray,
    amplitude: float,
    frequency: float,
    a: float = 0.95,
    start: float = 0.0,
    stop: float = math.inf,
) -> np.ndarray:
    """Sawtooth of Fig. 3.14 [V]: maximum ``amplitude`` at the fraction ``a`` of each period.

    Args:
        t: time [s]. amplitude: peak [V] (signed). frequency: [Hz].
        a: position of the maximum in the period, 0 < a < 1.
        start, stop: the signal is zero outside [start, stop) [s].
    """
    tt, amp, f, aa = _common(t, amplitude, frequency, a)
    t0, t1 = _check_span(start, stop)
    phase = np.mod((tt - t0) * f, 1.0)
    y = np.where(phase < aa, phase / aa, (1.0 - phase) / (1.0 - aa))
    return np.where(_window(tt, t0, t1), amp * y, 0.0)


def one_directional(
    t: np.ndarray,
    amplitude: float,
    frequency: float,
    a: float = 0.95,
    n_periods: int = 10,
    start: float = 0.0,
) -> np.ndarray:
    """One-directional input of Fig. 4.5: ``n_periods`` sawtooth periods [V]."""
    n = _check_count("n_periods", n_periods)
    f = check_positive("frequency", frequency)
    return sawtooth(t, amplitude, f, a, start, check_finite("start", start) + n / f)


def two_directional(
    t: np.ndarray,
    amplitude: float,
    frequency: float,
    a: float = 0.95,
    n_per_direction: int = 5,
    n_cycles: int = 1,
    start: float = 0.0,
    reverse: Literal["sign", "mirror"] = "sign",
) -> np.ndarray:
    """Two-directional input of Fig. 4.5 [V].

    ``n_per_direction`` periods forward then the same number back, ``n_cycles`` times.
    ``reverse="sign"`` negates the amplitude for the way back; ``"mirror"`` keeps the
    polarity and swaps the slow and fast flanks (a → 1 − a).
    """
    tt, amp, f, aa = _common(t, amplitude, frequency, a)
    n = _check_count("n_per_direction", n_per_direction)
    c = _check_count("n_cycles", n_cycles)
    t0 = check_finite("start", start)
    if reverse not in ("sign", "mirror"):
        raise ValueError(f"reverse={reverse!r}: must be 'sign' or 'mirror'")
    fwd = sawtooth(tt, amp, f, aa, t0)
    back = (
        sawtooth(tt, -amp, f, aa, t0) if reverse == "sign" else sawtooth(tt, amp, f, 1.0 - aa, t0)
    )
    active = _window(tt, t0, t0 + 2 * n * c / f)
    return np.where(active, np.where(_forward(tt, t0, f, n), fwd, back), 0.0)


def slew_adapted(
    t: np.ndarray,
    amplitude: float,
    frequency: float,
    a: float = 0.95,
    k: float = 1.0,
    hold_time: float = 20e-6,
    start: float = 0.0,
    stop: float = math.inf,
) -> np.ndarray:
    """Slew-adapted sawtooth (Fig. 4.3) [V].

    The slow flank is the sawtooth's; at the phase ``a`` the input steps from the
    amplitude to −k·amplitude, holds for ``hold_time`` [s], then sits at 0 until the
    next period. k = 1 is the thesis's example (1 V → −1 V → 0 V).
    """
    tt, amp, f, aa = _common(t, amplitude, frequency, a)
    kk = check_nonnegative("k", k)
    th = check_nonnegative("hold_time", hold_time)
    if th > (1.0 - aa) / f:
        raise ValueError(
            f"hold_time={hold_time!r}: must fit in the flyback interval "
            f"(1-a)/f = {(1 - aa) / f:.3g} s"
        )
    t0, t1 = _check_span(start, stop)
    phase = np.mod((tt - t0) * f, 1.0)
    since_flyback = (phase - aa) / f  # s
    y = np.where(phase < aa, phase / aa, np.where(since_flyback < th, -kk, 0.0))
    return np.where(_window(tt, t0, t1), amp * y, 0.0)


@dataclass(frozen=True, eq=False)
class Waveform:
    """Piecewise-linear amplifier input [V] through breakpoints (``times`` [s], ``values`` [V]).

    Linear between breakpoints; constant before the first and after the last. Two
    breakpoints at the same time make a jump; the value is right-continuous there.

    Args:
        times: non-decreasing breakpoint times [s]; at most two equal in a row.
        values: input voltage at each breakpoint [V].
    """

    times: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        for name in ("times", "values"):
            if np.ndim(getattr(self, name)) > 1:
                raise ValueError(f"{name}: shape {np.shape(getattr(self, name))}: must be 1-D")
        t = check_array_finite("times", self.times).astype(float).reshape(-1)
        v = check_array_finite("values", self.values).astype(float).reshape(-1)
        if t.size == 0 or t.shape != v.shape:
            raise ValueError(
                f"values: {v.size} values for {t.size} times (need equal, non-zero counts)"
            )
        dt = np.diff(t)
        if (dt < 0.0).any():
            i = int(np.nonzero(dt < 0.0)[0][0]) + 1
            raise ValueError(f"times[{i}]={t[i]!r}: times must be non-decreasing")
        if t.size > 2 and ((dt[:-1] == 0.0) & (dt[1:] == 0.0)).any():
            i = int(np.nonzero((dt[:-1] == 0.0) & (dt[1:] == 0.0))[0][0]) + 1
            raise ValueError(f"times[{i}]={t[i]!r}: at most two breakpoints may share a time")
        t.setflags(write=False)
        v.setflags(write=False)
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "values", v)

    @classmethod
    def constant(cls, value: float = 0.0) -> Waveform:
        """A constant input [V]."""
        return cls(np.array([0.0]), np.array([check_finite("value", value)]))

    def __call__(self, t: np.ndarray | float) -> np.ndarray:
        """Input [V] at times ``t`` [s] (right-continuous at jumps)."""
        tt = check_array_finite("t", t).astype(float)
        tb, vb = self.times, self.values
        # index of the last breakpoint <= t (right-continuous at jumps)
        i = np.searchsorted(tb, tt, side="right") - 1
        i = np.clip(i, 0, tb.size - 1)
        j = np.minimum(i + 1, tb.size - 1)
        span = tb[j] - tb[i]
        frac = np.where(span > 0.0, (tt - tb[i]) / np.where(span > 0.0, span, 1.0), 0.0)
        frac = np.clip(frac, 0.0, 1.0)
        return vb[i] + frac * (vb[j] - vb[i])

    @property
    def end(self) -> float:
        """Time of the last breakpoint [s]."""
        return float(self.times[-1])

    def scaled(self, factor: float) -> Waveform:
        """The waveform times ``factor`` (e.g. −1 for the opposite direction)."""
        return Waveform(self.times.copy(), self.values * check_finite("factor", factor))


MAX_PERIODS = 10_000_000  # periods one drive or breakpoint list may hold (~0.6 GB of breakpoints)


def _check_count(name: str, n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or not 1 <= n <= MAX_PERIODS:
        raise ValueError(f"{name}={n!r}: must be an integer in 1…{MAX_PERIODS}")
    return int(n)


@dataclass(frozen=True)
class StepSetting:
    """One stepping waveform of the generator (amplifier input), one period of
    :mod:`turntable_env.generator`'s template.

    Each period rises over a/f; the flyback is the sawtooth's fall over (1 − a)/f
    (Fig. 3.14; ``slew_adaptation`` = 0 and ``flyback="ramp"``), a step back to 0
    (``flyback="step"``: the laboratory's input with the flyback left to the amplifier,
    §4.1.2) or the slew-adapted input of Fig. 4.3 (k > 0: step to −k·amplitude, hold
    ``hold_time``, then 0). Amplitude 0 is the idle generator.

    Args:
        amplitude: peak input [V], signed (sign = direction).
        frequency: [Hz].
        a: ramp ratio, 0 < a < 1.
        slew_adaptation: k ≥ 0 of Fig. 4.3.
        hold_time: adapted hold [s] (k > 0), clipped to the flyback interval (1 − a)/f
            (:meth:`adapted` computes it from the amplifier).
        flyback: ``"ramp"`` or ``"step"`` for k = 0; k > 0 implies a step.
    """

    amplitude: float = 0.0
    frequency: float = 100.0
    a: float = 0.95
    slew_adaptation: float = 0.0
    hold_time: float = 0.0
    flyback: Literal["ramp", "step"] = "ramp"

    def __post_init__(self) -> None:
        check_finite("amplitude", self.amplitude)
        check_positive("frequency", self.frequency)
        check_in_open("a", self.a, 0.0, 1.0)
        check_nonnegative("slew_adaptation", self.slew_adaptation)
        check_nonnegative("hold_time", self.hold_time)
        if self.flyback not in ("ramp", "step"):
            raise ValueError(f"flyback={self.flyback!r}: must be 'ramp' or 'step'")

    @classmethod
    def adapted(
        cls,
        amplitude: float,
        frequency: float,
        a: float,
        k: float,
        amplifier: Amplifier,
        load_capacitance: float = 0.0,
    ) -> StepSetting:
        """The Fig. 4.3 setting with its hold time from the amplifier driving
        ``load_capacitance`` [F] (:func:`turntable_env.generator.adapted_hold`); k = 0 gives
        the plain step flyback. Raises ValueError if −k·amplitude leaves the input range."""
        kk = check_nonnegative("k", k)
        amp = check_finite("amplitude", amplitude)
        if kk * abs(amp) > amplifier.input_limit:
            raise ValueError(
                f"k={k!r}: the adapted input {-kk * amp:.3g} V exceeds the input limit "
                f"±{amplifier.input_limit} V"
            )
        f = check_positive("frequency", frequency)
        aa = check_in_open("a", a, 0.0, 1.0)
        if kk == 0.0:
            return cls(amp, f, aa, 0.0, 0.0, "step")
        kk, hold = adapted_hold(amplifier.kernel_row(load_capacitance), amp, f, aa, kk)
        return cls(amp, f, aa, kk, hold, "step")

    @property
    def idle(self) -> bool:
        return self.amplitude == 0.0

    @property
    def mode(self) -> int:
        """Template mode of :mod:`turntable_env.generator` (ramp, step or adapted)."""
        if self.slew_adaptation > 0.0:
            return MODE_ADAPTED
        return MODE_STEP if self.flyback == "step" else MODE_RAMP

    def row(self) -> np.ndarray:
        """The setting as the compiled generator reads it (``SETTING_FIELDS``)."""
        return np.array(
            [self.amplitude, self.frequency, self.a, self.slew_adaptation, self.hold_time,
             float(self.mode)]
        )  # fmt: skip

    def template(self) -> tuple[np.ndarray, np.ndarray]:
        """One period as breakpoints: times from 0 to 1/f [s], input [V]."""
        t = np.empty(TEMPLATE_POINTS)
        v = np.empty(TEMPLATE_POINTS)
        n = template_nb(self.row(), t, v)
        return t[:n], v[:n]

    def periods(self, n: int, start: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``n`` consecutive periods from ``start`` [s] as breakpoints (each period's
        opening 0 V point shared with the previous period's end)."""
        tp, vp = self.template()
        count = _check_count("n", n)
        starts = start + (1.0 / self.frequency) * np.arange(count)  # as the generator
        t = (starts[:, None] + tp[None, 1:]).ravel()
        v = np.tile(vp[1:], count)
        return np.concatenate([[start], t]), np.concatenate([[0.0], v])


@dataclass(frozen=True)
class DriveSignal:
    """A stepping drive as the simulator and the environment use it.

    Args:
        amplitude: amplifier input amplitude [V]; sign = direction. The simulations
            refuse one beyond the plant's amplifier input limit (±10 V, §4.1.1).
        frequency: [Hz].
        a: ramp ratio, position of the maximum, 0 < a < 1.
        n_periods: periods per direction.
        pattern: ``"one"`` (one-directional) or ``"two"`` (forward then back, Fig. 4.5).
        n_cycles: for ``"two"``: how many forward-and-back cycles.
        slew_adaptation: k ≥ 0 of Fig. 4.3; 0 = unadapted. k > 0 implies a step flyback.
        start: [s].
        flyback: ``"ramp"`` — the sawtooth of Fig. 3.14 falls back over (1 − a)/f;
            ``"step"`` — the input steps back to 0 at a/f, as the laboratory's function
            generator did (§4.1.2: the amplifier, not the signal, set the flyback speed).
    """

    amplitude: float = 2.0
    frequency: float = 100.0
    a: float = 0.95
    n_periods: int = 10
    pattern: Literal["one", "two"] = "one"
    slew_adaptation: float = 0.0
    start: float = 0.0
    flyback: Literal["ramp", "step"] = "ramp"
    n_cycles: int = 1

    def __post_init__(self) -> None:
        check_finite("amplitude", self.amplitude)
        check_positive("frequency", self.frequency)
        check_in_open("a", self.a, 0.0, 1.0)
        _check_count("n_periods", self.n_periods)
        if self.pattern not in ("one", "two"):
            raise ValueError(f"pattern={self.pattern!r}: must be 'one' or 'two'")
        check_nonnegative("slew_adaptation", self.slew_adaptation)
        check_nonnegative("start", self.start)
        if self.flyback not in ("ramp", "step"):
            raise ValueError(f"flyback={self.flyback!r}: must be 'ramp' or 'step'")
        _check_count("n_cycles", self.n_cycles)
        if self.total_periods > MAX_PERIODS:
            raise ValueError(
                f"n_periods={self.n_periods!r}, n_cycles={self.n_cycles!r}: "
                f"{self.total_periods} periods, more than {MAX_PERIODS}"
            )

    @property
    def stepped(self) -> bool:
        """True if the flyback is an input step (``flyback="step"`` or slew adaptation)."""
        return self.flyback == "step" or self.slew_adaptation > 0.0

    @property
    def duration(self) -> float:
        """Time from start to the end of the last period [s]."""
        return self.total_periods / self.frequency

    @property
    def total_periods(self) -> int:
        """Number of drive periods in the whole signal."""
        return self.n_periods * (2 * self.n_cycles if self.pattern == "two" else 1)

    def period_starts(self, until: float) -> np.ndarray:
        """Start times of the drive's periods up to ``until`` [s] (the last period's end
        included): where a response reads its steps."""
        starts = self.start + np.arange(self.total_periods + 1) / self.frequency
        return starts[starts <= until + 1e-12]

    def setting(
        self, amplifier: Amplifier | None = None, load_capacitance: float = 0.0, sign: float = 1.0
    ) -> StepSetting:
        """The generator setting of a forward (``sign`` = 1) or backward (−1) period."""
        amp = amplifier if amplifier is not None else Amplifier()
        if self.slew_adaptation > 0.0:
            return StepSetting.adapted(
                sign * self.amplitude, self.frequency, self.a, self.slew_adaptation, amp,
                load_capacitance,
            )  # fmt: skip
        return StepSetting(sign * self.amplitude, self.frequency, self.a, 0.0, 0.0, self.flyback)

    def hold_time(self, amplifier: Amplifier | None = None, load_capacitance: float = 0.0) -> float:
        """How long the adapted flyback input stays past zero (Fig. 4.3) [s]; 0 if unadapted."""
        return self.setting(amplifier, load_capacitance).hold_time

    def waveform(
        self, amplifier: Amplifier | None = None, load_capacitance: float = 0.0
    ) -> Waveform:
        """The drive as breakpoints: equal to :meth:`input_voltage` everywhere (jumps
        right-continuous), built from the generator's period template."""
        fwd = self.setting(amplifier, load_capacitance)
        if self.pattern == "one":
            t, v = fwd.periods(self.n_periods, self.start)
            return Waveform(t, v)
        back = self.setting(amplifier, load_capacitance, -1.0)
        tt, vv = [np.array([self.start])], [np.array([0.0])]
        block = self.n_periods / self.frequency
        for j in range(2 * self.n_cycles):
            t, v = (fwd if j % 2 == 0 else back).periods(self.n_periods, self.start + j * block)
            tt.append(t[1:])
            vv.append(v[1:])
        return Waveform(np.concatenate(tt), np.concatenate(vv))

    def input_voltage(
        self, t: np.ndarray, amplifier: Amplifier | None = None, load_capacitance: float = 0.0
    ) -> np.ndarray:
        """Amplifier input [V] at times ``t`` [s]; adapted hold time from ``amplifier``."""
        tt = check_array_finite("t", t)
        if not self.stepped:
            if self.pattern == "one":
                return one_directional(
                    tt, self.amplitude, self.frequency, self.a, self.n_periods, self.start
                )
            return two_directional(
                tt,
                self.amplitude,
                self.frequency,
                self.a,
                self.n_periods,
                self.n_cycles,
                self.start,
            )
        hold = self.hold_time(amplifier, load_capacitance)
        stop = self.start + self.duration
        fwd = slew_adapted(
            tt, self.amplitude, self.frequency, self.a, self.slew_adaptation, hold, self.start, stop
        )
        if self.pattern == "one":
            return fwd
        back = slew_adapted(
            tt,
            -self.amplitude,
            self.frequency,
            self.a,
            self.slew_adaptation,
            hold,
            self.start,
            stop,
        )
        return np.where(_forward(tt, self.start, self.frequency, self.n_periods), fwd, back)


_SCRATCH = 64  # breakpoints per interval the wrappers below allocate beyond the need


def generator_segment(
    t0: float, t1: float, phase: float, running: StepSetting, pending: StepSetting
) -> tuple[np.ndarray, np.ndarray, float, StepSetting]:
    """Generator output over one control interval [t0, t1] [s] as breakpoints.

    The generator is free-running and phase continuous: ``running`` finishes its current
    period (from ``phase`` ∈ [0, 1)), then ``pending`` takes over at the period start
    (where every waveform is 0, so a new setting never makes the input jump); an idle
    generator starts ``pending`` at once. An idle ``pending`` stops the generator at the
    end of the running period (phase 0). (:func:`turntable_env.generator.segment_nb`, the
    generator the environment runs.)

    Returns:
        (times [s], input [V], phase at t1, the setting running at t1).
    """
    _check_interval(t0, t1, phase)
    fmax = max(running.frequency, pending.frequency)
    cap = interval_capacity(fmax, t1 - t0) + _SCRATCH
    out = [np.empty(cap) for _ in range(4)]
    m, ph, latched = segment_nb(t0, t1, phase, running.row(), pending.row(), *out)
    return out[0][:m].copy(), out[1][:m].copy(), ph, pending if latched else running


def generator_flybacks(
    t0: float, t1: float, phase: float, running: StepSetting, pending: StepSetting
) -> int:
    """Number of flybacks (stick–slip steps) the generator starts in [t0, t1): the
    same interval and latching as :func:`generator_segment`. A period's flyback starts
    at the fraction ``a`` of the period (Fig. 3.14 / Fig. 4.3)."""
    _check_interval(t0, t1, phase)
    return int(flybacks_nb(t0, t1, phase, running.row(), pending.row()))


def _check_interval(t0: float, t1: float, phase: float) -> None:
    if not t1 > t0:
        raise ValueError(f"t1={t1!r}: must be > t0={t0!r}")
    if not 0.0 <= phase < 1.0:
        raise ValueError(f"phase={phase!r}: must be in [0, 1)")


def capacitive_energy(values: np.ndarray, capacitance: float) -> float:
    """Energy the amplifier moves into and out of a capacitive load C [F] along a
    piecewise-linear output with breakpoint voltages ``values`` [V]: C∫|V dV| [J].

    Per linear segment V0 → V1: C|V1² − V0²|/2 without a sign change, C(V0² + V1²)/2
    through zero. A full 0 → V → 0 period costs C·V² (charge and discharge; §4.1.2's
    amplifier sources and sinks the quadrant current)."""
    v = np.asarray(values, dtype=float)
    return float(capacitive_energy_nb(v, v.size, 1.0, float(capacitance)))


def grid_breakpoints(times: np.ndarray, values: np.ndarray, grid: float) -> tuple[np.ndarray, ...]:
    """Breakpoints rounded to an integration grid [s] (grid units as floats), with exact
    repeats dropped and at most two breakpoints per grid time (the first and the last
    value there): the form the compiled integrators read."""
    t = np.asarray(times, dtype=float)
    v = np.asarray(values, dtype=float)
    g = np.empty(t.size)
    w = np.empty(t.size)
    n = grid_points_nb(t, v, t.size, float(grid), g, w)
    return g[:n], w[:n]
