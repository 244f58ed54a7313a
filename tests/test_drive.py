"""Drive signals: Fig. 3.14 sawtooth, Fig. 4.5 inputs, Fig. 4.3 slew-adapted input."""

import itertools

import numpy as np
import pytest

from turntable_env.amplifier import Amplifier
from turntable_env.drive import (
    DriveSignal,
    one_directional,
    sawtooth,
    slew_adapted,
    two_directional,
)


def test_fig_3_14_example():
    """100 V, 1 Hz, start 1 s, stop 4 s, maximum at a = 0.95."""
    t = np.array([0.5, 1.0, 1.475, 1.95, 1.975, 2.0, 2.95, 3.95, 4.0, 4.5])
    y = sawtooth(t, 100.0, 1.0, 0.95, start=1.0, stop=4.0)
    assert y[0] == 0.0 and y[1] == 0.0
    assert y[2] == pytest.approx(50.0)  # halfway up the slow flank
    assert y[3] == pytest.approx(100.0)  # maximum at a
    assert y[4] == pytest.approx(50.0)  # halfway down the flyback
    assert y[5] == pytest.approx(0.0, abs=1e-9)
    assert y[6] == pytest.approx(100.0) and y[7] == pytest.approx(100.0)
    assert y[8] == 0.0 and y[9] == 0.0


@pytest.mark.parametrize(("a", "f"), [(0.5, 10.0), (0.95, 100.0), (0.99, 2000.0)])
def test_sawtooth_periodic_and_bounded(a, f):
    t = np.linspace(0, 5 / f, 5001)
    y = sawtooth(t, 2.0, f, a)
    y2 = sawtooth(t + 1 / f, 2.0, f, a)
    assert np.allclose(y, y2, atol=1e-9)
    assert y.min() >= 0.0 and y.max() <= 2.0 + 1e-12
    # slow flank slope A f / a, flyback slope −A f/(1−a)
    assert np.max(np.diff(y) / np.diff(t)) == pytest.approx(2.0 * f / a, rel=1e-6)
    assert np.min(np.diff(y) / np.diff(t)) == pytest.approx(-2.0 * f / (1 - a), rel=0.05)


def test_one_directional_counts_periods_and_sign_sets_direction():
    t = np.arange(0, 0.2, 1e-6)
    y = one_directional(t, -2.0, 100.0, 0.95, n_periods=9)
    peaks = np.sum((y[1:-1] < y[:-2]) & (y[1:-1] <= y[2:]) & (y[1:-1] < -1.99))
    assert peaks == 9
    assert y.max() <= 0.0
    assert np.all(y[t >= 0.09] == 0.0)


@pytest.mark.parametrize("reverse", ["sign", "mirror"])
def test_two_directional_goes_forward_then_back(reverse):
    f, n = 100.0, 5
    t = (np.arange(50000) + 0.5) * 1e-6  # the first n periods, sampled between grid points
    fwd = two_directional(t, 2.0, f, 0.95, n_per_direction=n, reverse=reverse)
    back = two_directional(t + n / f, 2.0, f, 0.95, n_per_direction=n, reverse=reverse)
    assert np.all(two_directional(t + 2 * n / f, 2.0, f, 0.95, n_per_direction=n) == 0.0)
    if reverse == "sign":
        assert fwd.min() >= 0.0 and back.max() <= 0.0
        assert np.allclose(back, -fwd, atol=1e-9)
    else:
        assert fwd.min() >= 0.0 and back.min() >= 0.0
        # the way back has the slow flank falling: mean slope sign inverted
        d = np.diff(back)
        assert np.sum(d < 0) > np.sum(d > 0)


def test_slew_adapted_overshoots_then_settles():
    f, a, k, hold = 100.0, 0.95, 1.0, 15e-6
    t = np.array([0.0095 - 1e-7, 0.0095 + 1e-6, 0.0095 + 14e-6, 0.0095 + 16e-6, 0.0099])
    y = slew_adapted(t, 2.0, f, a, k, hold)
    assert y[0] == pytest.approx(2.0, rel=1e-4)
    assert y[1] == -2.0 and y[2] == -2.0  # Fig. 4.3: 1 V → −1 V …
    assert y[3] == 0.0 and y[4] == 0.0  # … → 0 V


def test_drive_signal_uses_amplifier_hold_time():
    amp = Amplifier()
    d = DriveSignal(amplitude=2.0, frequency=100.0, a=0.95, n_periods=3, slew_adaptation=1.0)
    hold = amp.adapted_hold_time(2.0, 0.0, 1.0)
    assert hold == pytest.approx(amp.tau * np.log(2.0))  # no slew limit: τ ln((1+k)/k)
    t = 0.0095 + np.array([0.5, 0.999, 1.001]) * hold
    u = d.input_voltage(t, amp)
    assert list(u) == [-2.0, -2.0, 0.0]
    assert d.duration == pytest.approx(0.03)
    two = DriveSignal(amplitude=2.0, n_periods=2, pattern="two")
    assert two.duration == pytest.approx(0.04)
    assert two.input_voltage(np.array([0.0295]))[0] == pytest.approx(-2.0, rel=1e-3)


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: sawtooth(np.zeros(3), 1.0, 1.0, a=1.0), "a"),
        (lambda: sawtooth(np.zeros(3), 1.0, 1.0, a=0.0), "a"),
        (lambda: sawtooth(np.zeros(3), 1.0, -5.0), "frequency"),
        (lambda: sawtooth(np.zeros(3), float("nan"), 1.0), "amplitude"),
        (lambda: sawtooth(np.array([0.0, np.inf]), 1.0, 1.0), "t"),
        (lambda: sawtooth(np.zeros(3), 1.0, 1.0, start=2.0, stop=1.0), "stop"),
        (lambda: one_directional(np.zeros(3), 1.0, 1.0, n_periods=0), "n_periods"),
        (lambda: two_directional(np.zeros(3), 1.0, 1.0, reverse="up"), "reverse"),
        (lambda: slew_adapted(np.zeros(3), 1.0, 100.0, 0.95, hold_time=1e-3), "hold_time"),
        (lambda: DriveSignal(pattern="three"), "pattern"),
        (lambda: DriveSignal(slew_adaptation=-1.0), "slew_adaptation"),
        (lambda: DriveSignal(a=1.2), "a"),
    ],
)
def test_drive_rejects_bad_input(call, field):
    with pytest.raises(ValueError, match=field):
        call()


# --- free-running generator (environment drive) ----------------------------------------------
def _segments(settings, dt=0.01):
    """Chain generator_segment over consecutive intervals; returns the pieces."""
    from turntable_env.drive import StepSetting, generator_segment

    phase, running, out = 0.0, StepSetting(), []
    for i, s in enumerate(settings):
        t, v, phase, running = generator_segment(i * dt, (i + 1) * dt, phase, running, s)
        out.append((t, v, phase, running))
    return out


def test_generator_pieces_join_without_jumps_and_keep_phase():
    from turntable_env.drive import StepSetting

    a = StepSetting(2.0, 150.0, 0.9)
    b = StepSetting(-1.0, 400.0, 0.6, slew_adaptation=0.5, hold_time=1e-4)
    pieces = _segments([a, b, b])
    for (t0, v0, *_), (t1, v1, *_) in itertools.pairwise(pieces):
        assert t0[-1] == t1[0] and v0[-1] == pytest.approx(v1[0], abs=1e-12)
    # 150 Hz over 10 ms: 1.5 periods, so the first interval ends mid-period at phase 0.5
    assert pieces[0][2] == pytest.approx(0.5)
    # the new setting waits for the running period to end (t = 2/150 s), then takes over
    t, v, _ph, running = pieces[1]
    assert running == b
    i_end = int(np.nonzero(np.isclose(t, 2 / 150, rtol=0, atol=1e-12))[0][0])
    assert v[i_end] == pytest.approx(0.0, abs=1e-12)
    assert (v[:i_end] >= 0).all()  # a's period (0 → 2 → 0) completes
    assert v[i_end:].min() == -1.0 and v[i_end:].max() == 0.5  # b: −1 V, overshoot +k·1 V


def test_idle_generator_starts_at_once_and_idle_setting_stops():
    from turntable_env.drive import StepSetting, generator_segment

    s = StepSetting(1.0, 100.0, 0.5)
    t, v, ph, run = generator_segment(0.0, 0.005, 0.0, StepSetting(), s)
    assert run == s and ph == pytest.approx(0.5) and v[-1] == pytest.approx(1.0)
    t, v, ph, run = generator_segment(0.005, 0.02, ph, run, StepSetting())
    assert run.idle and ph == 0.0 and v[-1] == 0.0
    assert t[np.argmax(v == 0.0)] == pytest.approx(0.01)  # running period finished first


def test_grid_breakpoints_keep_at_most_two_per_time():
    from turntable_env.drive import grid_breakpoints

    g, v = grid_breakpoints(
        np.array([0.0, 1.0, 1.0 + 1e-12, 1.0 + 2e-12, 2.0, 2.0]),
        np.array([0.0, 1.0, 0.5, -1.0, 0.0, 0.0]),
        0.5,
    )
    np.testing.assert_array_equal(g, [0.0, 2.0, 2.0, 4.0])
    np.testing.assert_array_equal(v, [0.0, 1.0, -1.0, 0.0])


def _drops(t, v, t0, t1):
    """Flybacks in a chain of breakpoints: starts of falling pieces in [t0, t1)."""
    dv = np.diff(v)
    falling = dv < 0
    start = np.concatenate([[True], ~falling[:-1]]) & falling  # first piece of each fall
    return int(np.sum(start & (t[:-1] >= t0 - 1e-15) & (t[:-1] < t1 - 1e-15)))


@pytest.mark.parametrize(
    "settings",
    [
        [(2.0, 150.0, 0.9, 0.0)] * 3,
        [(1.0, 400.0, 0.6, 0.5), (2.0, 100.0, 0.95, 1.0), (0.0, 100.0, 0.9, 0.0)],
        [(3.0, 2000.0, 0.99, 0.0), (1.0, 70.0, 0.5, 1.0), (1.0, 70.0, 0.5, 1.0)],
        [(-2.0, 300.0, 0.9, 1.0), (-2.0, 300.0, 0.9, 1.0)],
    ],
)
def test_generator_flybacks_count_the_falls_of_the_segment(settings):
    """generator_flybacks equals the falls of generator_segment's own waveform."""
    from turntable_env.drive import StepSetting, generator_flybacks, generator_segment

    dt, phase, running = 0.01, 0.0, StepSetting()
    tt, vv, counts = [], [], []
    for i, (amp, f, a, k) in enumerate(settings):
        s = StepSetting(amp, f, a, k, hold_time=5e-6 if k else 0.0)
        counts.append(generator_flybacks(i * dt, (i + 1) * dt, phase, running, s))
        t, v, phase, running = generator_segment(i * dt, (i + 1) * dt, phase, running, s)
        tt.append(t)
        vv.append(v)
    t, v = np.concatenate(tt), np.concatenate(vv)
    v = v * np.sign(settings[0][0])  # flybacks are the falls of a forward sawtooth
    expect = [_drops(t, v, i * dt, (i + 1) * dt) for i in range(len(settings))]
    assert counts == expect
    assert sum(counts) > 0
