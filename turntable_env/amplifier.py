"""High-voltage amplifier (RHK HVA 900, §4.1.1–4.1.2) driving the capacitive piezo quadrants.

Measured behaviour (§4.1.2): gain 45, input ±10 V, at most 25 mA output; the
time to reach the end value is the same for every step, so the slew rate is
proportional to the step: 0.9 V/µs for a 1 V input step (45 V out), 2.7 V/µs
for 3 V; the datasheet's 12 V/µs holds only at the full 900 V swing.

Model: a linear first-order stage — the linear system whose settling time does
not depend on the step — followed by two saturations:

    dV_out/dt = clip((G·u − V_out)/τ, −R, +R),   R = min(SR_max, I_max/C_load)

τ is derived from the measured 0.9 V/µs, slew rate taken, as on a datasheet,
between 10 % and 90 % of the transition: SR₁₀₋₉₀ = 0.8·ΔV/(τ ln 9), hence
τ = 0.8·G·(1 V)/(0.9 V/µs · ln 9) = 18.2 µs. SR_max = 12 V/µs (datasheet);
the current limit I_max/C_load enters through the quadrants' capacitance
ε₁₁A_e/h (Eq. 2.2). The input is clipped to ±10 V. ``ideal=True`` gives the
instant source the thesis's simulation assumed (V_out = G·u).

The slew-adapted input (Fig. 4.3) jumps past the end value, to
V_end − k·(V_start − V_end), and back to V_end when the output gets there;
:meth:`Amplifier.adapted_hold_time` is that time.

**Fast path** (``fast_fraction`` a > 0, ``fast_time`` τ_f): the four figures of §4.1.2 are
not one first-order stage — 0.9 and 2.7 V/µs for 1 V and 3 V steps (linear: "divide the
3 V response by three"), 8.0 V/µs for the adapted flyback, where a first-order stage with
the same settling time gives 3.6 V/µs, and 12 V/µs at the full 900 V swing. A linear
amplifier whose step response has a fast partial rise before the slow tail, followed by
the output's rate limit, gives all four: the output follows

    V_lin = V_s + V_f,   dV_s/dt = clip(((1 − a)·G·u − V_s)/τ, ±R),   dV_f/dt = (a·G·u − V_f)/τ_f,
    dV/dt = clip towards V_lin at ±R (a slew-limited output stage),

with τ derived so that the 1 V step's 10–90 % slew rate stays the measured 0.9 V/µs
(unloaded, R = 12 V/µs). a = 0 is exactly the first-order model above.

**Output lag** (``lag_ratio`` r > 0): a second pole after the stage — an output stage that
follows the stage above through its own first-order lag, τ_o = r·τ, under the same rate
limit:

    dV/dt = clip((V_s + V_f − V)/τ_o, −R, +R).

An amplifier driving a capacitive load through its output resistance, or any feedback
amplifier with a second pole, has such a response: its step starts with zero slope (an S
shape) where a first-order stage starts at its steepest. τ is again derived so that the
1 V step's 10–90 % slew rate stays the measured one, so r changes the response's shape,
not its speed. r = 0 is exactly the model without it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numba import njit

from .kernel_cache import CACHE
from .quantities import Quantity
from .validation import (
    check_array_finite,
    check_finite,
    check_nonnegative,
    check_positive,
    check_time_array,
)

__all__ = [
    "Amplifier",
    "AmplifierResponse",
    "adapted_hold_core",
    "amplifier_step",
    "amplifier_step_decayed",
    "measure_slew_rate",
    "ramp_step",
]

LN9 = math.log(9.0)
LAG_RATIO_MAX = 1.0  # largest output lag τ_o/τ [-]: the linear response is symmetric in
# the two poles (r and 1/r give the same τ and τ_o swapped), so r ≤ 1 covers every pair of
# them (under the rate limit, or with a fast path, the two orders differ slightly)


@njit(cache=CACHE)
def slew_step(v, target, dt, tau, rate):
    """Exact step of dV/dt = clip((target − V)/τ, ±rate) over dt [s] for a constant target [V]."""
    e = target - v
    ae = abs(e)
    sgn = 1.0 if e >= 0.0 else -1.0
    if ae > rate * tau:
        t_lin = (ae - rate * tau) / rate
        if dt <= t_lin:
            return v + sgn * rate * dt
        return target - sgn * rate * tau * math.exp(-(dt - t_lin) / tau)
    return target - e * math.exp(-dt / tau)


@njit(cache=CACHE)
def ramp_step(v0, u0, u1, h, gain, tau, rate):
    """Output of the slew-limited first-order stage after h [s] for a target input ramping
    u0 → u1 [V] (§4.1.2 stage).

    Exact first-order response to the ramp when the stage is linear over the step
    (error and ramp both inside the slew limit); otherwise the slew-limited step with
    the mid-step input held (:func:`slew_step`)."""
    return _ramp_step(v0, u0, u1, h, gain, tau, rate, math.exp(-h / tau))


@njit(cache=CACHE)
def _ramp_step(v0, u0, u1, h, gain, tau, rate, e_tau):
    """:func:`ramp_step` with its decay e_tau = exp(−h/τ) given."""
    slope = gain * (u1 - u0) / h  # V/s of the target
    lag = slope * tau
    e0 = gain * u0 - lag - v0  # distance from the ramp's steady response
    if abs(gain * u0 - v0) <= rate * tau and abs(slope) < rate:
        return gain * u1 - lag - e0 * e_tau
    return slew_step(v0, gain * 0.5 * (u0 + u1), h, tau, rate)


@njit(cache=CACHE)
def _ramp_follower(v0, w0, w1, slope, tc, decay):
    """State [V] after a step of dV/dt = (w − V)/t_c from v0 while its target w ramps
    w0 → w1 [V] at ``slope`` [V/s]: exact, with decay = exp(−step/t_c) (the fast path, the
    output lag)."""
    return w1 - slope * tc + (v0 - w0 + slope * tc) * decay


@njit(cache=CACHE)
def _output_stage(v0, w0, w1, h, to, rate):
    """Output [V] after h [s] from v0 while its input w (the paths' sum) ramps w0 → w1 [V]:
    with an output lag τ_o = ``to`` > 0 [s] the lag's exact response, else w1; either way
    moved by at most ``rate``·h (the slew-limited output stage)."""
    v1 = _ramp_follower(v0, w0, w1, (w1 - w0) / h, to, math.exp(-h / to)) if to != 0.0 else w1
    lim = rate * h
    return min(v0 + lim, max(v0 - lim, v1))


@njit(cache=CACHE)
def amplifier_step(v0, vs0, vf0, u0, u1, h, row):
    """(output, slow path, fast path) [V] after h [s] of an input ramping u0 → u1 [V] for the
    amplifier ``row`` (:meth:`Amplifier.kernel_row`; module docstring). Without a fast path
    (a = 0) the slow path is :func:`ramp_step`, and the output unless an output lag trails
    it. With one, the fast path is exact for the ramp, the slow path as :func:`ramp_step`
    with gain (1 − a)G, and the output moves towards their sum by at most R·h. An output lag
    τ_o = ``row[7]`` > 0 follows the paths' sum, taken as a ramp over the step (exact for
    one), by at most R·h."""
    e_tf = math.exp(-h / row[6]) if row[5] != 0.0 else 0.0
    return amplifier_step_decayed(v0, vs0, vf0, u0, u1, h, row, math.exp(-h / row[1]), e_tf)


@njit(cache=CACHE)
def amplifier_step_decayed(v0, vs0, vf0, u0, u1, h, row, e_tau, e_tf):
    """:func:`amplifier_step` with the step's decays given: e_tau = exp(−h/τ) of the slow
    path and e_tf = exp(−h/τ_f) of the fast one (a ladder of steps tabulates them once)."""
    gain, tau, rate, a, tf, to = row[0], row[1], row[4], row[5], row[6], row[7]
    if a == 0.0:
        vs1 = _ramp_step(vs0, u0, u1, h, gain, tau, rate, e_tau)
        if to == 0.0:
            return vs1, vs1, 0.0
        return _output_stage(v0, vs0, vs1, h, to, rate), vs1, 0.0
    vs1 = _ramp_step(vs0, u0, u1, h, (1.0 - a) * gain, tau, rate, e_tau)
    slope = a * gain * (u1 - u0) / h
    vf1 = _ramp_follower(vf0, a * gain * u0, a * gain * u1, slope, tf, e_tf)
    return _output_stage(v0, vs0 + vf0, vs1 + vf1, h, to, rate), vs1, vf1


@njit(cache=CACHE)
def amplifier_hold_step(v0, vs0, vf0, u, dt, gain, tau, rate, a, tf, to=0.0):
    """The amplifier after dt [s] under a constant input u [V] (zero-order hold): the
    compiled 3-D integrator's and :meth:`Amplifier.simulate`'s update; ``to`` [s] is the
    output lag τ_o (0: none; module docstring)."""
    if a == 0.0:
        vs1 = slew_step(vs0, gain * u, dt, tau, rate)
        if to == 0.0:
            return vs1, vs1, 0.0
        return _output_stage(v0, vs0, vs1, dt, to, rate), vs1, 0.0
    vs1 = slew_step(vs0, (1.0 - a) * gain * u, dt, tau, rate)
    vf1 = a * gain * u + (vf0 - a * gain * u) * math.exp(-dt / tf)
    return _output_stage(v0, vs0 + vf0, vs1 + vf1, dt, to, rate), vs1, vf1


@njit(cache=CACHE)
def adapted_hold_core(v_start, v_end, k, gain, tau, rate, ideal, a=0.0, tf=1.0, to=0.0):
    """Time [s] the Fig. 4.3 adapted input stays past the end value (see
    :meth:`Amplifier.adapted_hold_time`, which validates the arguments): the output of the
    slew-limited first-order stage (gain G, τ [s], rate limit [V/s]) covers G·|v_start −
    v_end| [V] from an error G·|v_start − u_over|, u_over = v_end − k(v_start − v_end);
    with a fast path (a > 0) or an output lag (τ_o = ``to`` > 0 [s]) the output is
    integrated in steps of min(τ, τ_f)/200."""
    if ideal or v_start == v_end:
        return 0.0
    if k == 0.0:
        return math.inf
    u_over = v_end - k * (v_start - v_end)
    if a > 0.0 or to > 0.0:
        return _hold_numerical(v_start, v_end, u_over, gain, tau, rate, a, tf, to)
    dist = gain * abs(v_start - v_end)  # output travel to the end value [V]
    e0 = gain * abs(v_start - u_over)  # initial error [V]
    left = dist * k  # e0 − dist [V], the error left at the end value, exact for any k > 0
    if e0 > rate * tau:
        d_lin = e0 - rate * tau
        if dist <= d_lin:
            return dist / rate
        return d_lin / rate + tau * math.log(rate * tau / left)
    return tau * math.log1p(1.0 / k)  # τ·ln(e0/(e0 − dist)), e0/left = (1 + k)/k


@njit(cache=CACHE)
def _hold_numerical(v_start, v_end, u_over, gain, tau, rate, a, tf, to=0.0):
    """Time [s] until the output, settled at G·v_start, reaches G·v_end under the constant
    input u_over (linear interpolation at the crossing; inf if it never does)."""
    target = gain * v_end
    v = gain * v_start
    vs = (1.0 - a) * v
    vf = a * v
    sgn = 1.0 if target > v else -1.0
    dt = min(tf, tau) / 200.0  # the lag's step is exact for a ramp: τ_o need not be resolved
    t = 0.0
    while t < 20.0 * (tau + tf + to):
        v1, vs, vf = amplifier_hold_step(v, vs, vf, u_over, dt, gain, tau, rate, a, tf, to)
        if (v1 - target) * sgn >= 0.0:
            return t + dt * (target - v) / (v1 - v)
        v = v1
        t += dt
    return math.inf


@njit(cache=CACHE)
def _first_order_slew(t, u, v0, row):
    """Response of the amplifier ``row`` to a zero-order-hold input u [V] from the settled
    output v0 [V] (exact for the first-order stage; :func:`amplifier_hold_step`)."""
    n = t.shape[0]
    out = np.empty(n)
    gain, tau, rate, a, tf, to = row[0], row[1], row[4], row[5], row[6], row[7]
    v = v0
    vs = (1.0 - a) * v0
    vf = a * v0
    out[0] = v
    for i in range(n - 1):
        v, vs, vf = amplifier_hold_step(
            v, vs, vf, u[i], t[i + 1] - t[i], gain, tau, rate, a, tf, to
        )
        out[i + 1] = v
    return out


@dataclass(frozen=True)
class AmplifierResponse:
    """Amplifier time response; time is axis 0.

    Attributes:
        time: [s]; input: commanded input [V]; output: output voltage [V];
        current: output current C_load·dV/dt [A] (per output).
    """

    time: np.ndarray
    input: np.ndarray
    output: np.ndarray
    current: np.ndarray

    def to_pandas(self) -> Any:
        import pandas as pd

        return pd.DataFrame(
            {"input_V": self.input, "output_V": self.output, "current_A": self.current},
            index=pd.Index(self.time, name="time_s"),
        )

    def plot(self, ax: Any = None) -> Any:
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots()
        ax.plot(self.time * 1e6, self.output, label="output [V]")
        ax.set_xlabel("time [µs]")
        ax.set_ylabel("amplifier output [V]")
        ax.legend()
        return ax


@dataclass(frozen=True)
class Amplifier:
    """HVA 900 model (see module docstring).

    Args:
        gain: voltage gain G [-] (45).
        input_limit: |u| limit [V] (10).
        current_limit: I_max [A] (25 mA).
        slew_per_input_volt: measured 10–90 % slew rate for a 1 V input step [V/s] (0.9 V/µs).
        slew_rate_max: datasheet slew rate at full swing [V/s] (12 V/µs).
        ideal: instant source V_out = G·u (the thesis's simulation).
        fast_fraction: a, the share of a step the fast path covers (module docstring) [-];
            0: the first-order model.
        fast_time: τ_f of the fast path [s].
        lag_ratio: r, the output lag's time constant over the stage's, τ_o/τ [-] (module
            docstring); 0: no output lag.
    """

    gain: float = 45.0
    input_limit: float = 10.0
    current_limit: float = 25e-3
    slew_per_input_volt: float = 0.9e6
    slew_rate_max: float = 12e6
    ideal: bool = False
    fast_fraction: float = 0.0
    fast_time: float = 1e-6
    lag_ratio: float = 0.0

    def __post_init__(self) -> None:
        check_positive("gain", self.gain)
        check_positive("input_limit", self.input_limit)
        check_positive("current_limit", self.current_limit)
        check_positive("slew_per_input_volt", self.slew_per_input_volt)
        check_positive("slew_rate_max", self.slew_rate_max)
        if not isinstance(self.ideal, bool):
            raise ValueError(f"ideal={self.ideal!r}: must be a bool")
        if not 0.0 <= check_nonnegative("fast_fraction", self.fast_fraction) < 1.0:
            raise ValueError(f"fast_fraction={self.fast_fraction!r}: must be in [0, 1)")
        check_positive("fast_time", self.fast_time)
        if not 0.0 <= check_nonnegative("lag_ratio", self.lag_ratio) <= LAG_RATIO_MAX:
            raise ValueError(f"lag_ratio={self.lag_ratio!r}: must be in [0, {LAG_RATIO_MAX:g}]")

    @property
    def tau(self) -> float:
        """Time constant τ [s] of the slow (first-order) stage: 0.8·G/(SR₁V·ln 9) = 18.2 µs
        without a fast path or an output lag; with either, the τ that keeps the 1 V step's
        10–90 % slew rate at ``slew_per_input_volt`` (unloaded), found numerically."""
        tau0 = 0.8 * self.gain / (self.slew_per_input_volt * LN9)
        if self.fast_fraction == 0.0 and self.lag_ratio == 0.0:
            return tau0
        return _slow_tau(self.gain, self.slew_per_input_volt, self.slew_rate_max,
                         self.fast_fraction, self.fast_time, tau0, self.lag_ratio)  # fmt: skip

    @property
    def output_lag(self) -> float:
        """τ_o = r·τ [s], the output lag's time constant (0 without one)."""
        return self.lag_ratio * self.tau if self.lag_ratio > 0.0 else 0.0

    def rate_limit(self, load_capacitance: float) -> float:
        """R = min(SR_max, I_max/C_load) [V/s]; C_load = 0 means unloaded."""
        c = check_nonnegative("load_capacitance", load_capacitance)
        if c == 0.0:
            return self.slew_rate_max
        return min(self.slew_rate_max, self.current_limit / c)

    def simulate(
        self,
        time: np.ndarray,
        input_voltage: np.ndarray,
        load_capacitance: float = 0.0,
        initial_output: float | None = None,
    ) -> AmplifierResponse:
        """Output voltage for a zero-order-hold input sampled at ``time`` [s].

        Args:
            time: strictly increasing sample times [s].
            input_voltage: commanded input [V], same length (clipped to ±input_limit).
            load_capacitance: capacitance on this output [F] (driven quadrants + cable).
            initial_output: output at time[0] [V]; defaults to G·u[0] (settled).
        """
        t = check_time_array("time", time)
        u = check_array_finite("input_voltage", input_voltage)
        if u.shape != t.shape:
            raise ValueError(f"input_voltage: shape {u.shape} must equal time's {t.shape}")
        c = check_nonnegative("load_capacitance", load_capacitance)
        uc = np.clip(u, -self.input_limit, self.input_limit)
        if self.ideal:
            out = self.gain * uc
        else:
            v0 = (
                self.gain * uc[0]
                if initial_output is None
                else check_finite("initial_output", initial_output)
            )
            out = _first_order_slew(t, uc, v0, self.kernel_row(c))
        current = c * np.gradient(out, t) if t.size > 1 else np.zeros_like(out)
        return AmplifierResponse(t, u, out, current)

    def step_response(
        self,
        step_from: float,
        step_to: float,
        duration: float = 200e-6,
        dt: float = 1e-8,
        load_capacitance: float = 0.0,
    ) -> AmplifierResponse:
        """Response to an input step from ``step_from`` to ``step_to`` [V] at t = 0 [s]."""
        a = check_finite("step_from", step_from)
        b = check_finite("step_to", step_to)
        t = np.arange(0.0, check_positive("duration", duration), check_positive("dt", dt))
        u = np.full(t.shape, b)
        return self.simulate(
            t,
            u,
            load_capacitance,
            initial_output=self.gain * np.clip(a, -self.input_limit, self.input_limit),
        )

    def adapted_hold_time(
        self, v_start: float, v_end: float, k: float, load_capacitance: float = 0.0
    ) -> float:
        """Time [s] the adapted input stays past the end value (Fig. 4.3).

        The input jumps from ``v_start`` to v_end − k(v_start − v_end) [V input]; the output
        reaches G·v_end after this time, when the input steps to ``v_end``. k = 0 (no
        adaptation) gives ``inf``; an ideal amplifier gives 0.
        """
        a = check_finite("v_start", v_start)
        b = check_finite("v_end", v_end)
        kk = check_nonnegative("k", k)
        u_over = b - kk * (a - b)
        if not self.ideal and a != b and kk > 0.0 and abs(u_over) > self.input_limit:
            raise ValueError(
                f"k={k!r}: the adapted input {u_over:.3g} V exceeds the input limit "
                f"±{self.input_limit} V"
            )
        return adapted_hold_core(
            a, b, kk, self.gain, self.tau, self.rate_limit(load_capacitance), self.ideal,
            self.fast_fraction, self.fast_time, self.output_lag,
        )  # fmt: skip

    def scaled(self, slew: float = 1.0, current: float = 1.0) -> Amplifier:
        """This amplifier with its slew per input volt × ``slew`` (settling time τ ÷) and its
        current limit × ``current`` (unit scatter, calibration, amplifier_dynamics)."""
        return replace(
            self,
            slew_per_input_volt=self.slew_per_input_volt * check_positive("slew", slew),
            current_limit=self.current_limit * check_positive("current", current),
        )

    def kernel_row(self, load_capacitance: float) -> np.ndarray:
        """The amplifier as the compiled kernels read it: (gain G, τ [s], ideal (1/0),
        input limit [V], rate limit R [V/s] on ``load_capacitance`` [F], fast fraction a,
        τ_f [s], output lag τ_o [s])."""
        return np.array(
            [
                self.gain,
                self.tau,
                1.0 if self.ideal else 0.0,
                self.input_limit,
                self.rate_limit(load_capacitance),
                self.fast_fraction,
                self.fast_time,
                self.output_lag,
            ]
        )

    def describe(self, prefix: str = "amplifier") -> list[Quantity]:
        g, d = "given", "derived"
        return [
            Quantity(f"{prefix}.gain", self.gain, "-", g, "HVA 900, §4.1.1"),
            Quantity(f"{prefix}.input_limit", self.input_limit, "V", g, "±10 V input, §4.1.1"),
            Quantity(f"{prefix}.current_limit", self.current_limit, "A", g, "25 mA, §4.1.1"),
            Quantity(
                f"{prefix}.slew_per_input_volt",
                self.slew_per_input_volt,
                "V/s",
                g,
                "0.9 V/us for a 1 V input step, §4.1.2 (10-90 %)",
            ),
            Quantity(
                f"{prefix}.slew_rate_max",
                self.slew_rate_max,
                "V/s",
                g,
                "12 V/us datasheet at 900 V, §4.1.2",
            ),
            Quantity(f"{prefix}.tau", self.tau, "s", d, "0.8*G/(SR_1V*ln 9)"),
            Quantity(f"{prefix}.ideal", self.ideal, "-", g, "instant source if true"),
            Quantity(
                f"{prefix}.fast_fraction", self.fast_fraction, "-", g,
                "share of a step the fast path covers (0: first order)",
            ),
            Quantity(f"{prefix}.fast_time", self.fast_time, "s", g, "fast path tau_f"),
            Quantity(
                f"{prefix}.lag_ratio", self.lag_ratio, "-", g, "output lag tau_o/tau (0: none)"
            ),
            Quantity(f"{prefix}.output_lag", self.output_lag, "s", d, "lag_ratio*tau"),
        ]


@functools.lru_cache(maxsize=256)
def _slow_tau(
    gain: float, sr_1v: float, rate: float, a: float, tf: float, tau0: float, r: float = 0.0
) -> float:
    """τ [s] at which the 1 V step's 10–90 % slew rate equals ``sr_1v`` (brentq over the
    compiled step response, sampled at τ_f/20 with a fast path, else at τ0/40), with the
    output lag τ_o = r·τ."""
    import scipy.optimize

    dt = tf / 20.0 if a > 0.0 else tau0 / 40.0

    def slew(tau: float) -> float:
        t = np.arange(0.0, 12.0 * tau * (1.0 + r) + 10.0 * tf, dt)
        row = np.array([gain, tau, 0.0, 10.0, rate, a, tf, r * tau])
        out = _first_order_slew(t, np.ones(t.size), 0.0, row)
        return measure_slew_rate(t, out, 0.0, gain) - sr_1v

    low = 0.5 * tau0 if r == 0.0 else 0.05 * tau0  # a lag shortens τ
    return float(scipy.optimize.brentq(slew, low, 5.0 * tau0, xtol=1e-4 * tau0))


def measure_slew_rate(
    time: np.ndarray,
    output: np.ndarray,
    v_from: float,
    v_to: float,
    low: float = 0.1,
    high: float = 0.9,
) -> float:
    """Slew rate [V/s] of one transition from ``v_from`` to ``v_to`` between the
    ``low`` and ``high`` fractions of the swing (10–90 % by default), from the first
    crossings, linearly interpolated. Raises ValueError if a level is never reached."""
    t = check_time_array("time", time)
    y = check_array_finite("output", output)
    a = check_finite("v_from", v_from)
    b = check_finite("v_to", v_to)
    if a == b:
        raise ValueError(f"v_to={v_to!r}: must differ from v_from")
    s = (y - a) / (b - a)  # normalised progress 0 → 1

    def crossing(level: float) -> float:
        idx = np.nonzero(s >= level)[0]
        if idx.size == 0:
            raise ValueError(f"output never reaches {level:.0%} of the swing {a} -> {b} V")
        i = int(idx[0])
        if i == 0:
            return float(t[0])
        f = (level - s[i - 1]) / (s[i] - s[i - 1])
        return float(t[i - 1] + f * (t[i] - t[i - 1]))

    t_lo, t_hi = crossing(low), crossing(high)
    return (high - low) * abs(b - a) / (t_hi - t_lo)
