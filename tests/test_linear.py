"""The small-signal stick plant (python-control) against the nonlinear simulators."""

import math

import control as ct
import numpy as np
import pytest

from turntable_env.linear import scan_plant, sine_sweep, stick_plant


@pytest.fixture(scope="module")
def plant():
    return stick_plant("real", "B")


def test_dc_gain_is_amplifier_gain_times_free_tube_travel_over_lever(plant):
    """θ/u at DC = G·g/ρ (amplifier gain, free contact travel per volt, lever), less the
    tiny pendulum share; the detector output is 2L/S times the angle (Eq. 4.1)."""
    from turntable_env.model import TurntableModel
    from turntable_env.params import real_parameters
    from turntable_env.reduced import AxisParameters

    ap = AxisParameters.from_model(TurntableModel(real_parameters()), "B")
    k_free = 45.0 * ap.tube_gain[0] / ap.lever[0]
    dc = ct.dcgain(plant)
    assert dc[0, 0] == pytest.approx(k_free, rel=2e-3)
    assert dc[1, 0] / dc[0, 0] == pytest.approx(2 * 0.175 / 9.9e-5, rel=1e-12)


@pytest.mark.parametrize("fidelity", ["reduced", "full"])
def test_low_frequency_gain_matches_the_simulator_within_5_percent(plant, fidelity):
    """Issue 6: python-control's small-signal gain equals the simulator's at 20 Hz."""
    sw = sine_sweep("real", "B", np.array([20.0]), fidelity=fidelity, settle=0.03, periods=1)
    pred = float(
        np.abs(ct.frequency_response(plant[0, 0], [2 * math.pi * 20.0]).complex).ravel()[0]
    )
    assert sw.all_stuck
    assert sw.magnitude[0] == pytest.approx(pred, rel=0.05)


def test_sweep_up_to_the_first_resonance_within_10_percent(plant):
    """Reduced simulator, sine sweep to 0.95 of the first resonance: |H| within 10 %."""
    poles = ct.poles(plant[0, 0])
    f_res = np.min(np.abs(poles[np.abs(poles.imag) > 0])) / (2 * math.pi)
    assert 4000.0 < f_res < 5500.0  # the 4.7 kHz table-on-tubes mode (README item 16)
    freqs = np.array([100.0, 1000.0, 3000.0, 0.95 * f_res])
    sw = sine_sweep("real", "B", freqs, settle=0.06)
    pred = np.abs(ct.frequency_response(plant[0, 0], 2 * math.pi * freqs).complex).ravel()
    assert sw.all_stuck
    np.testing.assert_allclose(sw.magnitude, pred, rtol=0.10)
    assert sw.magnitude[-1] > 3 * sw.magnitude[0]  # the resonance is really approached


def test_scan_plant_is_one_sample_delay_of_the_dc_gain(plant):
    """The environment's ramped offset: y_{k+1} = K·u_k (quasi-static at 100 Hz)."""
    pd = scan_plant(plant, 0.01)[0, 0]
    resp = ct.forced_response(pd, T=np.arange(6) * 0.01, U=np.array([0, 1, 1, 1, 1, 1.0]))
    k = float(ct.dcgain(plant[0, 0]))
    np.testing.assert_allclose(np.asarray(resp.outputs).ravel(), [0, 0, k, k, k, k], rtol=2e-3)


def test_scan_plant_matches_the_environment():
    """One interval with a scan offset u moves the env's table by K·u (within 1 %)."""
    import gymnasium as gym

    import turntable_env  # noqa: F401
    from turntable_env.envs import ActionScaling

    env = gym.make("PiezoTurntable-v0", noise=False)
    env.reset(seed=0, options={"start_angle": 0.0, "target_angle": 0.0})
    info = env.step(ActionScaling().encode(0.0, 100.0, 0.9, 0.0, offset=4.0))[4]
    k = float(ct.dcgain(scan_plant(stick_plant("real", "B"), 0.01)[0, 0]))
    assert info["angle_rad"] == pytest.approx(4.0 * k, rel=0.01)


def test_bad_sweep_arguments_raise():
    with pytest.raises(ValueError, match="fidelity"):
        sine_sweep(frequencies=np.array([10.0]), fidelity="exact")
    with pytest.raises(ValueError, match="amplitude"):
        sine_sweep(frequencies=np.array([10.0]), amplitude=-1.0)
    with pytest.raises(ValueError, match="control_interval"):
        scan_plant(stick_plant(), 0.0)


def test_output_lag_is_a_second_pole_in_series():
    """With an output lag the amplifier is G/((τs + 1)(τ_o s + 1)), τ re-derived: the plant's
    response over the lag-free one's is (τ₁s + 1)/((τs + 1)(τ_o s + 1)) at every frequency
    (τ₁ the first-order stage's), and the DC gain is unchanged."""
    from dataclasses import replace

    from turntable_env.params import real_parameters

    ps = real_parameters()
    lagged = replace(ps, amplifier=replace(ps.amplifier, lag_ratio=0.7))
    p0, p1 = stick_plant(ps, "B"), stick_plant(lagged, "B")
    assert p1.nstates == p0.nstates + 1 and p1.state_labels[0] == "V_stage"
    w = np.array([1e2, 1e4, 3e4, 1e5])  # rad/s
    h0, h1 = p0(1j * w)[0, 0], p1(1j * w)[0, 0]
    t1, t, to = ps.amplifier.tau, lagged.amplifier.tau, lagged.amplifier.output_lag
    expected = (1j * w * t1 + 1) / ((1j * w * t + 1) * (1j * w * to + 1))
    np.testing.assert_allclose(h1 / h0, expected, rtol=1e-8)
    assert float(ct.dcgain(p1[0, 0])) == pytest.approx(float(ct.dcgain(p0[0, 0])), rel=1e-9)
