"""Physics tests of the independent test-bench plant (turntable_env.testing)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from turntable_env.calibration.measurement import load_measurement
from turntable_env.testing.independent_plant import (
    EFFECT_NAMES,
    PROTOCOLS,
    Burst,
    Effects,
    Hold,
    PlantParams,
    Protocol,
    Ramp,
    adapted_hold_time,
    build_drive,
    simulate,
    simulate_detailed,
    write_trace,
)

P = PlantParams()


def _run(proto: Protocol, dt_out: float = 2e-5, **kw):
    tb, ub = build_drive(proto, P)
    t = np.union1d(tb, np.arange(0.0, tb[-1], dt_out))
    return t, simulate_detailed(P, t, np.interp(t, tb, ub), **kw)


def _step_per_period(amp: float, f: float, flyback: str, n: int = 5, **kw) -> float:
    """Mean contact displacement per period [m] over periods 2…n (first one settles)."""
    t0 = 0.002
    proto = Protocol("t", (Hold(t0), Burst(amp, f, n, flyback=flyback), Hold(0.002)))  # type: ignore[arg-type]
    t, r = _run(proto, **kw)
    x = np.interp(t0 + np.arange(n + 1) / f, t, r.theta_rad) * P.contact_arm_m
    return float((x[-1] - x[1]) / (n - 1))


def test_amplitude_sign_sets_direction():
    fwd = _step_per_period(2.0, 100.0, "adapted")
    bwd = _step_per_period(-2.0, 100.0, "adapted")
    assert 0.2e-6 < fwd < 0.5e-6  # thesis: 0.30–0.37 µm per period at 2 V, 100 Hz
    assert -0.5e-6 < bwd < -0.2e-6
    assert abs(fwd + bwd) < 0.02 * fwd  # symmetric plant without asymmetry


def test_adapted_flyback_steps_more_than_step_and_slow_ramp():
    adapted = _step_per_period(2.0, 100.0, "adapted")
    step = _step_per_period(2.0, 100.0, "step")
    ramp = _step_per_period(2.0, 100.0, "ramp")
    assert adapted > step > 0.0
    assert abs(ramp) < 0.1 * adapted  # slow flyback: the table follows the tips back


def test_adapted_hold_ends_at_output_zero():
    tb, ub = build_drive(Protocol("t", (Burst(2.0, 100.0, 1), Hold(1e-3))), P)
    hold = adapted_hold_time(P, 2.0, 100.0, 0.95)
    assert 10e-6 < hold < 0.05 / 100.0
    t = np.union1d(tb, np.linspace(0.0095, 0.0095 + 2 * hold, 2001))
    r = simulate_detailed(P, t, np.interp(t, tb, ub))
    k = np.argmin(np.abs(t - (0.0095 + hold)))
    assert abs(r.amplifier_output_V[k]) < 1.0  # within 1 V of 0 out of 90 V


def test_slow_scan_ramp_sticks_and_moves_by_stroke_times_lever():
    proto = Protocol("s", (Hold(0.005), Ramp(0.08, 4.0), Hold(0.01), Ramp(0.08, 0.0), Hold(0.01)))
    tb, ub = build_drive(proto, P)
    t = np.linspace(0.0, tb[-1], 2001)
    theta, vx, _ = simulate(P, t, np.interp(t, tb, ub))
    top = np.interp(0.09, t, theta) * P.table_radius_m
    expected = P.free_stroke_m(4.0) * P.lever
    assert top == pytest.approx(expected, rel=0.01)
    assert abs(theta[-1]) * P.table_radius_m < 0.01 * expected  # stuck: comes back
    # the detector reads it through Eq. 4.1
    v_expected = P.detector_distance_m * math.tan(2 * expected / P.table_radius_m)
    assert np.interp(0.09, t, vx) == pytest.approx(
        v_expected / P.detector_sensitivity_m_per_V, rel=0.01
    )


@pytest.mark.parametrize(("amp", "f", "flyback"), [(2.0, 100.0, "adapted"), (2.0, 200.0, "step")])
def test_halving_the_step_changes_step_size_below_one_percent(amp, f, flyback):
    a = _step_per_period(amp, f, flyback, n=4, max_step_s=0.25e-6)
    b = _step_per_period(amp, f, flyback, n=4, max_step_s=0.125e-6)
    assert abs(a - b) < 0.01 * abs(b)


def test_passivity_work_in_covers_stored_energy():
    """W_in(t) − (E(t) − E(0)) is the energy dissipated by friction and damping: it must be
    ≥ 0 and (up to round-off) non-decreasing."""
    proto = Protocol(
        "e", (Hold(0.002), Burst(3.0, 200.0, 4), Hold(0.003), Burst(-2.0, 100.0, 2, flyback="step"))
    )
    _, r = _run(proto, dt_out=1e-5)
    e0 = r.stored_energy_J[0]
    dissipated = r.work_in_J - (r.stored_energy_J - e0)
    scale = r.stored_energy_J.max()
    assert scale > 0.0
    assert dissipated.min() >= -1e-6 * scale
    assert np.diff(dissipated).min() >= -1e-6 * scale
    assert dissipated[-1] > 0.1 * scale  # stick–slip dissipates


def _effects_protocol() -> Protocol:
    return Protocol(
        "fx",
        (
            Hold(0.01),
            Ramp(0.04, 4.0),
            Hold(0.08),
            Ramp(0.04, 0.0),
            Hold(0.01),
            Burst(2.0, 100.0, 6),
            Hold(0.02),
            Burst(3.0, 300.0, 6),
            Hold(0.02),
            Burst(-2.0, 100.0, 6),
            Hold(0.03),
        ),
    )


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_each_effect_changes_the_trace_above_noise(name):
    noise = 1e-3
    proto = _effects_protocol()
    tb, ub = build_drive(proto, P)
    t = np.union1d(tb, np.arange(0.0, tb[-1], 5e-5))
    u = np.interp(t, tb, ub)
    _, x0, y0 = simulate(P, t, u, None, noise, np.random.default_rng(1))
    _, x1, y1 = simulate(P, t, u, Effects.with_defaults(name), noise, np.random.default_rng(1))
    # same noise draws: the difference is the effect alone
    d = x1 - x0 if np.abs(x1 - x0).max() >= np.abs(y1 - y0).max() else y1 - y0
    rms, peak = np.sqrt(np.mean(d**2)), np.abs(d).max()
    assert rms > 1.5 * noise and peak > 5.0 * noise, (
        f"{name}: rms {rms * 1e3:.2f} mV, peak {peak * 1e3:.2f} mV"
    )


def test_hysteresis_loop_and_creep_magnitudes():
    tri = Protocol("h", (Hold(0.005), Ramp(0.05, 2.0), Ramp(0.05, 0.0), Hold(0.005)))
    tb, ub = build_drive(tri, P)
    t = np.linspace(0.0, tb[-1], 2201)
    u = np.interp(t, tb, ub)
    th, _, _ = simulate(P, t, u, Effects.with_defaults("hysteresis"))
    up, dn = (t > 0.005) & (t <= 0.055), (t > 0.055) & (t < 0.105)
    g = np.linspace(0.1, 1.9, 60)
    width = np.interp(g, u[dn][::-1], th[dn][::-1]) - np.interp(g, u[up], th[up])
    assert 0.05 < width.max() / th.max() < 0.15  # ~10 % of the stroke
    step = Protocol("c", (Hold(0.001), Ramp(0.001, 3.0), Hold(0.3)))
    tb, ub = build_drive(step, P)
    t = np.linspace(0.0, tb[-1], 3021)
    th, _, _ = simulate(P, t, np.interp(t, tb, ub), Effects.with_defaults("creep"))
    x = np.interp([0.005, 0.302], t, th) * P.contact_arm_m / P.free_stroke_m(3.0)
    per_decade = (x[1] - x[0]) / math.log10(0.3 / 0.003)
    assert 0.015 < per_decade < 0.05  # a few % per decade


def test_written_file_loads_and_holds_what_was_simulated(tmp_path):
    proto = Protocol("w", (Hold(0.003), Burst(2.0, 100.0, 2), Ramp(0.01, -1.0), Hold(0.002)))
    path = write_trace(tmp_path / "w.csv", P, proto, noise_std=0.0, sample_rate_Hz=20e3)
    m = load_measurement(path)
    assert m.axis == "B" and m.amplifier_gain == 45.0 and m.meta == {}
    assert set(m.drives) == {"B"} and m.detector_y_v is not None
    tb, ub = build_drive(proto, P)
    # every breakpoint is in the file, with its value; the drive is linear in between
    assert np.isin(tb, m.time).all()
    np.testing.assert_allclose(m.drives["B"], np.interp(m.time, tb, ub), atol=1e-12)
    grid = np.arange(int(tb[-1] * 20e3 + 1e-9) + 1) / 20e3
    on_grid = np.isclose(m.time[:, None], grid[None, :], atol=1e-12, rtol=0).any(axis=1)
    assert on_grid.sum() == grid.size
    _, vx, _ = simulate(P, m.time, m.drives["B"])
    np.testing.assert_allclose(m.detector_v[on_grid], vx[on_grid], atol=1e-12)
    # the recorded y channel is zero without misalignment and noise
    assert np.abs(m.detector_y_v).max() == 0.0


def test_sampled_recording_has_single_sample_jumps_and_quantised_drive(tmp_path):
    proto = Protocol("q", (Hold(0.002), Burst(2.0, 100.0, 3, flyback="step"), Hold(0.002)))
    fs = 20e3
    path = write_trace(
        tmp_path / "q.csv", P, proto, sample_rate_Hz=fs, drive_recording="sampled", daq_bits=12
    )
    m = load_measurement(path)
    np.testing.assert_allclose(np.diff(m.time), 1.0 / fs, rtol=1e-9)
    u = m.drives["B"]
    lsb = 20.0 / 4096
    np.testing.assert_allclose(u / lsb, np.round(u / lsb), atol=1e-9)
    drops = np.flatnonzero(np.diff(u) < -1.0)
    assert drops.size == 3
    for k in drops:
        assert u[k] > 1.8 and abs(u[k + 1]) <= lsb  # the whole flyback inside one sample


def test_protocols_are_well_formed():
    for name, proto in PROTOCOLS.items():
        tb, ub = build_drive(name, P)
        assert (np.diff(tb) > 0).all() and np.abs(ub).max() <= 10.0
        assert tb[-1] == pytest.approx(proto.duration_s)
    standard, long = PROTOCOLS["standard"].duration_s, PROTOCOLS["long"].duration_s  # s
    assert standard >= 1.0 and standard <= 2.5
    assert long >= 2.2 and long <= 2.6
    so = PROTOCOLS["stepping_only"].segments
    assert not any(isinstance(s, Ramp) for s in so)
    assert all(s.duration_s <= 0.01 for s in so if isinstance(s, Hold))


def test_bad_input_raises_naming_the_field():
    with pytest.raises(ValueError, match="normal_force_N"):
        PlantParams(normal_force_N=-1.0)
    with pytest.raises(ValueError, match="time"):
        simulate(P, np.array([0.0, 1e-3, 1e-3]), np.zeros(3))
    with pytest.raises(ValueError, match="flyback"):
        Burst(2.0, 100.0, 3, flyback="fast")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="amplitude_V"):
        Burst(12.0, 100.0, 3)
    with pytest.raises(ValueError, match="protocol"):
        build_drive("nonsense")
    with pytest.raises(ValueError, match="effect name"):
        Effects.with_defaults("gremlins")
    with pytest.raises(ValueError, match="ramp_ratio"):
        build_drive(Protocol("x", (Burst(2.0, 5000.0, 2, ramp_ratio=0.98),)))
