"""One road in: every simulation entry point takes a Plant, and runs its stages as the
plant layer does (parameters, input, output; friction refused outside the stepper)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from turntable_env.drive import Waveform
from turntable_env.effects import detector_stage, pack_effects
from turntable_env.params import real_parameters
from turntable_env.plant import Plant, as_plant, parameter_set, reduced_model
from turntable_env.reduced import simulate_batch
from turntable_env.simulation import simulate, simulate_axes

# a slow scan to 2 V input (90 V on the tubes) in 5 ms, then a 45 ms hold: the table sticks
# to the tubes and follows them
SCAN = Waveform(np.array([0.0, 5e-3]), np.array([0.0, 2.0]))
DURATION = 50e-3  # s


def test_a_parameter_set_is_the_plant_on_it_unchanged():
    ps = real_parameters()
    assert as_plant(ps).params is ps
    assert as_plant("calibrated") == Plant.named("calibrated")
    named = as_plant("calibrated")  # whole: rig, factors, effects, uncertainty
    assert named.uncertainty and named.effects
    assert replace(named.params, name="calibrated") == parameter_set("calibrated")
    with pytest.raises(ValueError, match="plant='nominal'"):
        as_plant("nominal")
    with pytest.raises(ValueError, match="plant=3"):
        as_plant(3)  # type: ignore[arg-type]


def test_the_plant_road_is_the_model_road_for_a_plant_without_effects():
    """simulate_axes on a bare plant gives the compiled batch's numbers, bit for bit."""
    ps = real_parameters()
    (a,) = simulate_axes([ps], [SCAN], DURATION, output_dt=1e-4)
    (b,) = simulate_batch([reduced_model(ps, "B")], [SCAN], DURATION, output_dt=1e-4)
    np.testing.assert_array_equal(a.angle(), b.angle())
    np.testing.assert_array_equal(a.detector_voltage(), b.detector_voltage())


def test_creep_keeps_the_table_moving_during_the_hold():
    """Logarithmic creep (γ per decade of time): after the scan stops, the tubes — and the
    table, which sticks to them — keep going the same way, by about γ per decade of the
    hold (6 → 50 ms: 0.92 decades, ≈ 4.6 % of the scan at γ = 0.05); the plant without
    creep settles within 1 %."""
    nominal, creep = Plant("real"), Plant("real", effects={"piezo_creep": {"gamma": 0.05}})
    a, b = simulate_axes([nominal, creep], [SCAN, SCAN], DURATION, output_dt=1e-4)
    drift_nominal, drift_creep, ramp = _hold_drift(a, 6e-3), _hold_drift(b, 6e-3), _ramp(a, 6e-3)
    assert abs(drift_nominal) < 0.01 * abs(ramp)
    assert 0.025 * ramp < (drift_creep - drift_nominal) < 0.1 * ramp  # ramp > 0 (+2 V)


def _ramp(r, t_hold):
    return r.angle()[np.searchsorted(r.time, t_hold)] - r.angle()[0]


def _hold_drift(r, t_hold):
    return r.angle()[-1] - r.angle()[np.searchsorted(r.time, t_hold)]


def test_output_effects_reach_the_detector_not_the_table():
    """Sensor drift is in the detector voltage (offset + rate·t, Eq. 4.1 otherwise) and
    nowhere in the table's angle."""
    eff = {"sensor_drift": {"offset": 0.05, "rate": 0.5}}
    a, b = simulate_axes([Plant("real"), Plant("real", effects=eff)], [SCAN, SCAN], DURATION,
                         output_dt=1e-4)  # fmt: skip
    np.testing.assert_array_equal(a.angle(), b.angle())
    t = b.time - b.time[0]
    x, _y = detector_stage(a.angle(), t, pack_effects(eff), a.detector)
    vs = a.detector.saturation_voltage
    np.testing.assert_allclose(b.detector_voltage(), np.clip(x, -vs, vs), rtol=0, atol=1e-12)
    inside = np.abs(x) < vs
    np.testing.assert_allclose((b.detector_voltage() - a.detector_voltage())[inside],
                               (0.05 + 0.5 * t)[inside], rtol=1e-9, atol=1e-12)  # fmt: skip


@pytest.mark.parametrize("effect", ["friction_asymmetry", "friction_wear"])
def test_friction_stage_effects_are_refused_outside_the_stepper(effect):
    from turntable_env.effects import CATALOGUE

    plant = Plant("real", effects={effect: CATALOGUE[effect].defaults()})
    with pytest.raises(ValueError, match=f"plant.effects\\['{effect}'\\]"):
        simulate_axes([plant], [SCAN], DURATION)
    with pytest.raises(ValueError, match=f"plant.effects\\['{effect}'\\]"):
        simulate(plant, SCAN, DURATION)


def test_the_3d_road_runs_the_input_stage():
    """The 3-D model of a creeping plant moves on during the hold, as the reduced one:
    2.5 → 8 ms is 0.5 decades, ≈ 2.5 % of the scan at γ = 0.05."""
    creep = Plant("real", effects={"piezo_creep": {"gamma": 0.05}})
    short = Waveform(np.array([0.0, 2e-3]), np.array([0.0, 2.0]))
    a = simulate(Plant("real"), short, 8e-3, output_dt=1e-4, coarse_factor=0.5)
    b = simulate(creep, short, 8e-3, output_dt=1e-4, coarse_factor=0.5)
    ramp = _ramp(a, 2.5e-3)
    assert ramp > 0.0
    assert 0.01 * ramp < _hold_drift(b, 2.5e-3) - _hold_drift(a, 2.5e-3) < 0.1 * ramp
    assert b.info["plant"].startswith("Plant(")


def test_one_result_out_signals_by_name_on_both_fidelities():
    """Both responses give their signals by name, with the same names for what both record
    (the angle about the axis under test and the detector), and ``to_pandas`` is that."""
    (red,) = simulate_axes(["real"], [SCAN], 6e-3, output_dt=1e-4)
    full = simulate("real", SCAN, 6e-3, output_dt=1e-4, coarse_factor=0.5)
    for r in (red, full):
        df = r.to_pandas()
        assert list(df.columns) == list(r.signals())
        np.testing.assert_array_equal(r.signal("angle_rad"), r.angle())
        np.testing.assert_array_equal(r.signal("detector_V"), r.detector_voltage())
        np.testing.assert_array_equal(df["angle_rad"].to_numpy(), r.angle())
        with pytest.raises(ValueError, match="signal 'angle_deg': not recorded"):
            r.signal("angle_deg")
    # the two fidelities agree on a slow scan (the table sticks to the tubes), by name
    i = np.searchsorted(full.time, 5e-3)
    j = np.searchsorted(red.time, 5e-3)
    assert red.signal("angle_rad")[j] == pytest.approx(full.signal("angle_rad")[i], rel=0.1)
