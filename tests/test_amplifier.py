"""HVA 900 amplifier against the measurements of §4.1.2."""

import numpy as np
import pytest

from turntable_env.amplifier import Amplifier, measure_slew_rate
from turntable_env.drive import DriveSignal
from turntable_env.piezo import PiezoQuadrant

AMP = Amplifier()
C2 = 2 * PiezoQuadrant().capacitance  # the two quadrants driven for a rotation about one axis


@pytest.mark.parametrize(("step", "measured"), [(1.0, 0.9e6), (3.0, 2.7e6)])
def test_slew_rate_proportional_to_step(step, measured):
    r = AMP.step_response(0.0, step, load_capacitance=C2)
    sr = measure_slew_rate(r.time, r.output, 0.0, 45 * step)
    print(f"\n{step} V input step: {sr / 1e6:.2f} V/us (thesis {measured / 1e6} V/us)")
    assert sr == pytest.approx(measured, rel=0.10)


def test_time_to_end_value_is_constant():
    """§4.1.2: the 3 V response divided by three lies on the 1 V response."""
    r1 = AMP.step_response(0.0, 1.0, load_capacitance=C2)
    r3 = AMP.step_response(0.0, 3.0, load_capacitance=C2)
    assert np.max(np.abs(r3.output / 3 - r1.output)) < 1e-9 * 45


def test_full_swing_reaches_datasheet_slew():
    r = AMP.step_response(-10.0, 10.0, duration=400e-6)  # 900 V swing, datasheet load
    sr = measure_slew_rate(r.time, r.output, -450.0, 450.0)
    peak = np.max(np.diff(r.output) / np.diff(r.time))
    print(f"\n900 V swing: 10-90 % {sr / 1e6:.2f} V/us, peak {peak / 1e6:.2f} V/us (datasheet 12)")
    assert sr == pytest.approx(12e6, rel=0.10)
    assert peak == pytest.approx(12e6, rel=1e-6)


def test_adapted_input_reaches_eight_volt_per_microsecond():
    """Fig. 4.3 recipe (jump to −amplitude, then to 0) on the 2 V, 100 Hz signal."""
    d = DriveSignal(amplitude=2.0, frequency=100.0, a=0.95, n_periods=2, slew_adaptation=1.0)
    t = np.arange(0.0, 0.02, 1e-8)
    r = AMP.simulate(t, d.input_voltage(t, AMP, C2), C2)
    m = (t >= 0.0095) & (t < 0.0105)
    sr = measure_slew_rate(r.time[m], r.output[m], 90.0, 0.0)
    print(f"\nadapted flyback: {sr / 1e6:.2f} V/us (thesis 8.0 V/us)")
    assert sr == pytest.approx(8.0e6, rel=0.10)
    # and the unadapted flyback of the same signal is four times slower
    r0 = AMP.step_response(2.0, 0.0, load_capacitance=C2)
    assert measure_slew_rate(r0.time, r0.output, 90.0, 0.0) == pytest.approx(1.8e6, rel=1e-3)


def test_current_limit_caps_slew_into_large_load():
    big = 10e-9  # F
    r = AMP.step_response(-10.0, 10.0, duration=2e-3, load_capacitance=big)
    peak = np.max(np.diff(r.output) / np.diff(r.time))
    assert peak == pytest.approx(25e-3 / big, rel=1e-6)
    assert np.max(np.abs(r.current)) <= 25e-3 * (1 + 1e-6)


def test_adapted_hold_time_lands_on_end_value():
    for k in (0.5, 1.0, 3.0):
        hold = AMP.adapted_hold_time(2.0, 0.0, k, C2)
        t = np.linspace(0, hold, 20001)
        r = AMP.simulate(t, np.full(t.size, -2.0 * k), C2, initial_output=90.0)
        assert r.output[-1] == pytest.approx(0.0, abs=1e-6)
    assert AMP.adapted_hold_time(2.0, 0.0, 0.0) == np.inf
    assert Amplifier(ideal=True).adapted_hold_time(2.0, 0.0, 1.0) == 0.0


def test_ideal_amplifier_and_input_clipping():
    ideal = Amplifier(ideal=True)
    t = np.linspace(0, 1e-3, 11)
    u = np.linspace(-12, 12, 11)
    r = ideal.simulate(t, u)
    assert np.allclose(r.output, 45 * np.clip(u, -10, 10))
    df = r.to_pandas()
    assert df.index.name == "time_s" and list(df.columns) == ["input_V", "output_V", "current_A"]


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: Amplifier(gain=0.0), "gain"),
        (lambda: Amplifier(current_limit=float("nan")), "current_limit"),
        (lambda: Amplifier(ideal="yes"), "ideal"),  # type: ignore[arg-type]
        (lambda: AMP.simulate(np.array([0.0, 0.0]), np.zeros(2)), "time"),
        (lambda: AMP.simulate(np.array([0.0, 1.0]), np.zeros(3)), "input_voltage"),
        (lambda: AMP.simulate(np.array([0.0, 1.0]), np.zeros(2), -1.0), "load_capacitance"),
        (lambda: AMP.adapted_hold_time(2.0, 0.0, 6.0), "k"),
        (lambda: Amplifier(lag_ratio=-0.1), "lag_ratio"),
        (lambda: Amplifier(lag_ratio=1.5), "lag_ratio"),
        (lambda: Amplifier(lag_ratio=float("nan")), "lag_ratio"),
        (
            lambda: measure_slew_rate(np.array([0.0, 1.0]), np.array([0.0, 0.1]), 0.0, 1.0),
            "reaches",
        ),
    ],
)
def test_amplifier_rejects_bad_input(call, field):
    with pytest.raises(ValueError, match=field):
        call()


# --- the output lag (amplifier_lag): a second pole ----------------------------------------
@pytest.mark.parametrize("r", [0.25, 0.5, 1.0])
def test_output_lag_keeps_the_measured_slew_and_starts_the_step_flat(r):
    """τ is re-derived so the 1 V step's 10–90 % slew stays §4.1.2's 0.9 V/µs; the second
    pole makes the step start with zero slope (an S shape), where the first-order stage
    starts at its steepest."""
    lag = Amplifier(lag_ratio=r)
    r_lag = lag.step_response(0.0, 1.0, duration=400e-6, dt=1e-8)
    r_one = AMP.step_response(0.0, 1.0, duration=400e-6, dt=1e-8)
    assert measure_slew_rate(r_lag.time, r_lag.output, 0.0, 45.0) == pytest.approx(0.9e6, rel=2e-3)
    assert lag.output_lag == pytest.approx(r * lag.tau, rel=1e-12) and lag.tau < AMP.tau
    s_lag, s_one = np.diff(r_lag.output) / 1e-8, np.diff(r_one.output) / 1e-8
    assert s_lag[0] < 0.01 * s_lag.max() and s_one[0] == pytest.approx(s_one.max(), rel=1e-6)


@pytest.mark.parametrize("r", [0.3, 1.0])
def test_output_lag_is_the_two_pole_step_response(r):
    """Inside the rate limit the amplifier is H(s) = G/((1 + sτ)(1 + sτ_o)): its small step
    follows G·(1 − (τe^{−t/τ} − τ_o e^{−t/τ_o})/(τ − τ_o)), and for τ_o = τ the double pole's
    G·(1 − (1 + t/τ)e^{−t/τ}). The lag stage is exact for a ramping input, so the error is
    the slow stage's zero-order hold of a moving target, O(dt)."""
    lag = Amplifier(lag_ratio=r)
    tau, to = lag.tau, lag.output_lag
    resp = lag.step_response(0.0, 0.1, duration=300e-6, dt=1e-9)  # 4.5 V: linear
    t = resp.time
    if r == 1.0:
        exact = 4.5 * (1.0 - (1.0 + t / tau) * np.exp(-t / tau))
    else:
        exact = 4.5 * (1.0 - (tau * np.exp(-t / tau) - to * np.exp(-t / to)) / (tau - to))
    assert np.max(np.abs(resp.output - exact)) < 1e-3 * 4.5


@pytest.mark.parametrize("r", [0.5, 1.0])
def test_adapted_hold_time_with_an_output_lag_lands_on_end_value(r):
    """The Fig. 4.3 hold, integrated numerically with the lag, ends where the output reaches
    the end value; the lag's S-shaped start makes it longer than the first-order hold."""
    lag = Amplifier(lag_ratio=r)
    hold = lag.adapted_hold_time(2.0, 0.0, 1.0, C2)
    t = np.linspace(0.0, hold, 40001)
    out = lag.simulate(t, np.full(t.size, -2.0), C2, initial_output=90.0).output
    assert out[-1] == pytest.approx(0.0, abs=0.02)  # V of a 90 V swing
    assert hold > AMP.adapted_hold_time(2.0, 0.0, 1.0, C2)
