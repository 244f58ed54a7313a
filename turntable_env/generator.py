"""The one drive generator: compiled period templates and a free-running generator for N turntables.

Every stepping waveform of the project is built here, in compiled code, from one period
template (Fig. 3.14 / Fig. 4.3, amplifier input [V] against time in the period [s]):

========  ============================================================================
mode      one period of amplitude A, frequency f = 1/T, ramp ratio a, overshoot k, hold
========  ============================================================================
0 ramp    0 → A over aT, A → 0 over (1 − a)T: the sawtooth of Fig. 3.14
1 step    0 → A over aT, a step back to 0 at aT: the laboratory's function generator with
          the flyback left to the amplifier (§4.1.2, "unadapted")
2 adapted 0 → A over aT, a step to −kA at aT, held ``hold`` (the time the HVA 900 needs
          to arrive at 0 V, :func:`adapted_hold`), then 0 until T (Fig. 4.3)
========  ============================================================================

:func:`generate_interval` is the free-running, phase-continuous generator of the
environment: for N turntables at once it finishes each running period, latches the
pending setting at the next period start (where every template is 0, so a change never
makes the input jump), adds the scan offset ramp, clips to the amplifier's input range,
rounds the breakpoints to the integration grid and returns, per turntable, the flybacks it
started and the electrical energy C∫|V dV| of the interval (§4.1.2). No Python runs per
turntable. :mod:`turntable_env.drive` wraps the same functions for single signals
(:class:`~turntable_env.drive.StepSetting`, :class:`~turntable_env.drive.DriveSignal`).

Settings cross into the compiled code as rows of :data:`SETTING_FIELDS`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .amplifier import adapted_hold_core
from .kernel_cache import CACHE

__all__ = [
    "MODE_ADAPTED",
    "MODE_RAMP",
    "MODE_STEP",
    "SETTING_FIELDS",
    "GeneratorState",
    "adapted_hold",
    "capacitive_energy_nb",
    "flybacks_nb",
    "generate_interval",
    "grid_points_nb",
    "interval_capacity",
    "segment_nb",
    "template_nb",
]

MODE_RAMP, MODE_STEP, MODE_ADAPTED = 0, 1, 2
# a setting row: amplitude [V input], frequency [Hz], ramp ratio a, overshoot k, hold [s], mode
SETTING_FIELDS = ("amplitude", "frequency", "a", "k", "hold", "mode")
TEMPLATE_POINTS = 6  # most breakpoints of one period


@njit(cache=CACHE)
def template_nb(s, out_t, out_v):
    """One period of setting row ``s`` (:data:`SETTING_FIELDS`) as breakpoints from 0 to
    T = 1/f [s] into out_t, out_v [V]; returns their count (module table)."""
    T = 1.0 / s[1]
    ta = s[2] * T
    amp = s[0]
    k = s[3]
    mode = int(s[5])
    out_t[0] = 0.0
    out_v[0] = 0.0
    out_t[1] = ta
    out_v[1] = amp
    if mode == MODE_RAMP:
        out_t[2] = T
        out_v[2] = 0.0
        return 3
    if mode == MODE_STEP:
        out_t[2] = ta
        out_v[2] = 0.0
        out_t[3] = T
        out_v[3] = 0.0
        return 4
    hold = min(s[4], T - ta)
    out_t[2] = ta
    out_v[2] = -k * amp
    if hold < T - ta:
        out_t[3] = ta + hold
        out_v[3] = -k * amp
        out_t[4] = ta + hold
        out_v[4] = 0.0
        out_t[5] = T
        out_v[5] = 0.0
        return 6
    out_t[3] = T
    out_v[3] = -k * amp
    out_t[4] = T
    out_v[4] = 0.0
    return 5


@njit(cache=CACHE)
def adapted_hold(amp, amplitude, frequency, a, k):
    """(k, hold [s]) of the Fig. 4.3 adapted flyback of a sawtooth of ``amplitude`` [V input]:
    the overshoot k capped so that −k·A stays inside the input range, the time the amplifier
    (``amp`` row, :meth:`~turntable_env.amplifier.Amplifier.kernel_row`) needs to
    reach 0 V (:meth:`~turntable_env.amplifier.Amplifier.adapted_hold_time`), capped at the
    flyback interval (1 − a)/f. k = 0 or A = 0: (k, 0)."""
    if k <= 0.0 or amplitude == 0.0:
        return k, 0.0
    k = min(k, amp[3] / abs(amplitude))
    hold = adapted_hold_core(
        abs(amplitude), 0.0, k, amp[0], amp[1], amp[4], amp[2] > 0.5, amp[5], amp[6], amp[7]
    )
    return k, min(hold, (1.0 - a) / frequency)


@njit(cache=CACHE)
def _interp(x, tp, vp, n):
    """np.interp(x, tp[:n], vp[:n]) for one x, right-continuous at repeated times."""
    if x <= tp[0]:
        return vp[0] if x < tp[0] or n == 1 else _interp_at(x, tp, vp, n)
    if x >= tp[n - 1]:
        return vp[n - 1]
    return _interp_at(x, tp, vp, n)


@njit(cache=CACHE)
def _interp_at(x, tp, vp, n):
    j = 0
    lo = 0
    hi = n
    while lo < hi:  # last index with tp[j] <= x
        mid = lo + ((hi - lo) >> 1)
        if x >= tp[mid]:
            lo = mid + 1
        else:
            hi = mid
    j = lo - 1
    if j >= n - 1 or tp[j] == x:
        return vp[j]
    slope = (vp[j + 1] - vp[j]) / (tp[j + 1] - tp[j])
    return slope * (x - tp[j]) + vp[j]


@njit(cache=CACHE)
def _window(tp, vp, n, lo, hi, out_t, out_v, m):
    """Append the breakpoints of (tp, vp)[:n] restricted to [lo, hi] to out at m: the value at
    ``lo`` is the right limit, at ``hi`` the left limit (windows join seamlessly)."""
    i0 = 0
    while i0 < n and tp[i0] <= lo:  # searchsorted(side="right")
        i0 += 1
    i1 = 0
    while i1 < n and tp[i1] < hi:  # searchsorted(side="left")
        i1 += 1
    if i0 == 0 or tp[i0 - 1] < lo:
        v_lo = _interp(lo, tp, vp, n)
    else:
        v_lo = vp[i0 - 1]
    if i1 < n and tp[i1] == hi:
        v_hi = vp[i1]
    else:
        v_hi = _interp(hi, tp, vp, n)
    out_t[m] = lo
    out_v[m] = v_lo
    m += 1
    for i in range(i0, max(i1, i0)):
        out_t[m] = tp[i]
        out_v[m] = vp[i]
        m += 1
    out_t[m] = hi
    out_v[m] = v_hi
    return m + 1


@njit(cache=CACHE)
def _periods(s, t_start, n_per, buf_t, buf_v):
    """n_per consecutive periods of setting s from t_start into the buffers; returns count."""
    tpl_t = np.empty(TEMPLATE_POINTS)
    tpl_v = np.empty(TEMPLATE_POINTS)
    nt = template_nb(s, tpl_t, tpl_v)
    T = 1.0 / s[1]
    m = 0
    for p in range(n_per):
        start = t_start + T * p
        for i in range(nt):
            buf_t[m] = start + tpl_t[i]
            buf_v[m] = tpl_v[i]
            m += 1
    return m


@njit(cache=CACHE)
def segment_nb(t0, t1, phase, running, pending, out_t, out_v, buf_t, buf_v):
    """Generator output over [t0, t1] [s] as breakpoints (out_t, out_v [V]).

    ``running`` finishes its period (from ``phase`` ∈ [0, 1)), then ``pending`` takes over
    at the period start; an idle (A = 0) running setting lets ``pending`` start at once, an
    idle pending one stops the generator at the end of the running period.

    Returns (count, phase at t1, True if ``pending`` runs at t1)."""
    m = 0
    t_latch = t0
    if running[0] != 0.0 and phase > 0.0:
        T = 1.0 / running[1]
        p_start = t0 - phase * T
        nb = _periods(running, p_start, 1, buf_t, buf_v)
        t_end = min(p_start + T, t1)
        m = _window(buf_t, buf_v, nb, t0, t_end, out_t, out_v, m)
        if p_start + T > t1:  # the running period outlasts the interval
            return m, (t1 - p_start) / T, False
        t_latch = p_start + T
    if t_latch < t1:
        if pending[0] == 0.0:
            out_t[m] = t_latch
            out_v[m] = 0.0
            out_t[m + 1] = t1
            out_v[m + 1] = 0.0
            return m + 2, 0.0, True
        T = 1.0 / pending[1]
        n = max(math.ceil((t1 - t_latch) / T - 1e-12), 1)
        nb = _periods(pending, t_latch, n, buf_t, buf_v)
        m = _window(buf_t, buf_v, nb, t_latch, t1, out_t, out_v, m)
        ph = (t1 - t_latch) / T - (n - 1)
        return m, (0.0 if ph >= 1.0 - 1e-12 else ph), True
    return m, 0.0, True


@njit(cache=CACHE)
def flybacks_nb(t0, t1, phase, running, pending):
    """Flybacks (stick–slip steps) the generator starts in [t0, t1), with the same
    latching as :func:`segment_nb`: a period's flyback starts at the fraction a."""
    count = 0
    t_latch = t0
    if running[0] != 0.0 and phase > 0.0:
        T = 1.0 / running[1]
        p_start = t0 - phase * T
        if phase <= running[2] and p_start + running[2] * T < t1:
            count += 1
        if p_start + T > t1:
            return count
        t_latch = p_start + T
    if t_latch < t1 and pending[0] != 0.0:
        # periods j = 0, 1, ... from t_latch flyback at t_latch + (j + a)T < t1
        span = (t1 - t_latch) * pending[1] - pending[2]
        count += max(math.ceil(span - 1e-9), 0)
    return count


@njit(cache=CACHE)
def grid_points_nb(t, v, n, grid, out_g, out_v):
    """Breakpoints rounded to the integration grid [s] (grid units as floats), exact repeats
    dropped, at most two per grid time (the first and the last value there); returns count."""
    m = 0
    for i in range(n):
        g = np.rint(t[i] / grid)
        if m > 0 and g == out_g[m - 1] and v[i] == out_v[m - 1]:
            continue
        if m > 1 and g == out_g[m - 1] and g == out_g[m - 2]:
            out_v[m - 1] = v[i]  # a third point at this time replaces the middle one
            continue
        out_g[m] = g
        out_v[m] = v[i]
        m += 1
    return m


@njit(cache=CACHE)
def capacitive_energy_nb(v, n, gain, capacitance):
    """C∫|V dV| [J] along the piecewise-linear amplifier output G·v[:n] (capacitive load
    C [F]): C|V1² − V0²|/2 per segment without a sign change, C(V0² + V1²)/2 through zero."""
    s = 0.0
    for i in range(n - 1):
        v0 = v[i] * gain
        v1 = v[i + 1] * gain
        if v0 * v1 >= 0.0:
            s += abs(v1 * v1 - v0 * v0)
        else:
            s += v0 * v0 + v1 * v1
    return 0.5 * capacitance * s


def interval_capacity(max_frequency: float, interval: float) -> int:
    """Breakpoints one interval of :func:`generate_interval` may need."""
    periods = math.ceil(max(max_frequency, 1e-9) * interval) + 2
    return TEMPLATE_POINTS * (periods + 2) + 8


class GeneratorState(NamedTuple):
    """The free-running generator of N turntables (rows), carried from one interval to the
    next: ``phase`` (N,) position in the running period [0, 1); ``running`` (N, 6) the
    setting it runs (:data:`SETTING_FIELDS`); ``offset`` (N,) the scan level at the last
    interval's end [V input]."""

    phase: np.ndarray
    running: np.ndarray
    offset: np.ndarray


@njit(cache=CACHE)
def generate_interval(n0, interval, grid, gen, pending, offset1, amp, c_load, drive, flybacks,
                      energy):  # fmt: skip
    """One control interval of the free-running generator for N turntables (module docstring).

    Args (row b per turntable):
        n0: grid time of the interval start; interval: its length Δt [s]; grid: the
        integration grid [s];
        gen: :class:`GeneratorState` (updated: the phase, the running setting when pending
            latches; its ``offset`` is the scan level at the interval's start [V input]);
        pending: setting rows (N, 6) asked for; its k and hold are filled in here for
            adapted flybacks (:func:`adapted_hold`);
        offset1: scan level at the interval's end [V input] (ramped linearly from
            ``gen.offset``; the caller stores it as the next start);
        amp: (N, 8) amplifier rows (:meth:`~turntable_env.amplifier.Amplifier.kernel_row`);
        c_load: capacitance of the driven channel [F].
    Outputs: drive: :class:`~turntable_env.kernel_types.DriveArrays`, the amplifier input as
    grid breakpoints (grid units, V, count); flybacks: steps started; energy: C∫|V dV| of
    the amplifier output [J].
    """
    phase, running, offset0 = gen.phase, gen.running, gen.offset
    wg, wv, wn = drive.times, drive.values, drive.count
    nb = running.shape[0]
    cap = wg.shape[1]
    seg_t = np.empty(cap)
    seg_v = np.empty(cap)
    buf_t = np.empty(cap)
    buf_v = np.empty(cap)
    for b in range(nb):
        if pending[b, 5] == MODE_ADAPTED:
            p = pending[b]
            k, hold = adapted_hold(amp[b], p[0], p[1], p[2], p[3])
            pending[b, 3] = k
            pending[b, 4] = hold
        t0 = float(n0[b]) * grid
        t1 = t0 + interval
        flybacks[b] = flybacks_nb(t0, t1, phase[b], running[b], pending[b])
        m, ph, latched = segment_nb(t0, t1, phase[b], running[b], pending[b], seg_t, seg_v,
                                    buf_t, buf_v)  # fmt: skip
        if latched:
            for j in range(6):
                running[b, j] = pending[b, j]
        if running[b, 0] != 0.0:
            period = 1.0 / running[b, 1]
            if ph * period < grid or (1.0 - ph) * period < grid:  # on a period start (grid)
                ph = 0.0
        phase[b] = ph
        ulim = amp[b, 3]
        d_off = offset1[b] - offset0[b]
        for i in range(m):
            x = seg_v[i] + offset0[b] + d_off * (seg_t[i] - t0) / interval
            seg_v[i] = min(ulim, max(-ulim, x))
        wn[b] = grid_points_nb(seg_t, seg_v, m, grid, wg[b], wv[b])
        energy[b] = capacitive_energy_nb(wv[b], wn[b], amp[b, 0], c_load[b])
    return None
