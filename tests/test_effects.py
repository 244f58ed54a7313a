"""Effect catalogue, trace simulation and the virtual lab: each effect's signature."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from turntable_env.calibration import load_measurement
from turntable_env.calibration.trace import simulate_trace
from turntable_env.calibration.virtual_lab import (
    PROTOCOLS,
    protocol_blocks,
    protocol_drive,
    run_virtual_lab,
)
from turntable_env.effects import (
    CATALOGUE,
    WEAR_LENGTH,
    check_effects,
    detector_stage,
    friction_scale,
    pack_effects,
    parse_effects,
)
from turntable_env.params import real_parameters
from turntable_env.plant import Plant

REQUIRED = {
    "amplifier_dynamics", "amplifier_lag", "piezo_hysteresis", "piezo_creep", "sensor_drift",
    "axis_misalignment", "detector_nonlinearity", "friction_asymmetry", "friction_wear",
    "vibration",
}  # fmt: skip


@pytest.fixture(scope="module")
def ps():
    return real_parameters()


@pytest.fixture(scope="module")
def drive(ps):
    return protocol_drive("standard", ps, "B")


def _trace(ps, drive, effects):
    return simulate_trace(Plant(ps, effects=effects), "B", *drive)


@pytest.fixture(scope="module")
def clean(ps, drive):
    return _trace(ps, drive, {})


def test_catalogue_names_bounds_and_basis():
    assert REQUIRED <= set(CATALOGUE)
    for e in CATALOGUE.values():
        assert e.basis and e.stage in ("parameters", "input", "friction", "output")
        for p in e.parameters:
            assert p.low <= p.neutral <= p.high and p.low <= p.typical <= p.high and p.unit


@pytest.mark.parametrize("name", sorted(REQUIRED))
def test_neutral_parameters_change_nothing(ps, drive, clean, name):
    """Neutral values reproduce the nominal trace; friction-stage effects integrate in
    5 ms segments, whose step boundaries move the result by < 5 % of the 1 mV noise."""
    res = _trace(ps, drive, {name: CATALOGUE[name].neutral()})
    tol = 5e-5 if CATALOGUE[name].stage == "friction" else 1e-12
    np.testing.assert_allclose(res.detector_v, clean.detector_v, rtol=0, atol=tol)


@pytest.mark.parametrize("name", sorted(REQUIRED))
def test_typical_parameters_leave_a_trace_above_the_noise(ps, drive, clean, name):
    """Each effect at its typical value moves the detector's x or y channel by more than
    the thesis-level noise (1 mV) somewhere in the standard protocol."""
    res = _trace(ps, drive, {name: CATALOGUE[name].defaults()})
    dx = np.abs(res.detector_v - clean.detector_v).max()
    dy = np.abs(res.detector_y_v - clean.detector_y_v).max()
    assert max(dx, dy) > 5e-3


def test_sensor_drift_is_offset_plus_rate_times_time(ps, drive, clean):
    res = _trace(ps, drive, {"sensor_drift": {"offset": 0.02, "rate": 0.1}})
    np.testing.assert_allclose(res.detector_v - clean.detector_v, 0.02 + 0.1 * drive[0], atol=1e-12)


def test_vibration_adds_a_sinusoidal_angle(ps, drive, clean):
    v = {"amplitude": 4e-6, "frequency": 37.0, "phase": 0.3}
    res = _trace(ps, drive, {"vibration": v})
    det = ps.detector
    dth = det.angle(res.detector_v) - det.angle(clean.detector_v)
    expect = 4e-6 * np.sin(2 * math.pi * 37.0 * drive[0] + 0.3)
    np.testing.assert_allclose(dth, expect, atol=2e-8)


@pytest.mark.parametrize("phi", [0.1, -0.1])  # the tilt goes either way
def test_misalignment_moves_the_other_channel_by_tan_phi(ps, drive, clean, phi):
    res = _trace(ps, drive, {"axis_misalignment": {"phi": phi}})
    big = np.abs(res.detector_v) > 0.2
    ratio = res.detector_y_v[big] / res.detector_v[big]
    np.testing.assert_allclose(ratio, math.tan(phi), rtol=2e-3)
    assert np.abs(clean.detector_y_v).max() < 1e-12


def test_detector_nonlinearity_is_cubic_in_the_reading(ps, drive, clean):
    res = _trace(ps, drive, {"detector_nonlinearity": {"kappa": 0.2}})
    vs = ps.detector.saturation_voltage
    v = clean.detector_v
    np.testing.assert_allclose(res.detector_v, v * (1 + 0.2 * (v / vs) ** 2), atol=1e-12)


@given(kappa=st.floats(-0.3, 0.3), angle=st.floats(-0.05, 0.05))
def test_detector_nonlinearity_is_monotone_and_reads_on_the_tables_side(ps, kappa, angle):
    """The photodiode's response stays monotone in the table angle for every κ of the
    catalogue, inside and far beyond the linear range; a table beyond the range reads on
    its own side (a folded cubic read −V_sat for a table far out at κ < 0), and saturated
    once the linear reading passes (1 + |κ|)·V_sat."""
    det = ps.detector
    rows = pack_effects({"detector_nonlinearity": {"kappa": kappa}})
    th = angle + np.array([0.0, 1e-6])
    x, _y = detector_stage(th, np.zeros(2), rows, det)
    assert x[1] > x[0]
    vs = det.saturation_voltage
    linear, _ = detector_stage(th, np.zeros(2), pack_effects({}), det)
    read = np.clip(x[0], -vs, vs)
    if abs(linear[0]) > vs:
        assert np.sign(read) == np.sign(angle)
    if abs(linear[0]) >= (1.0 + abs(kappa)) * vs:
        assert abs(read) == pytest.approx(vs)


def _block(kind, *args):
    """(start, end) [s] of the first standard-protocol block of this kind and arguments."""
    for start, end, blk in protocol_blocks("standard"):
        if blk[0] == kind and blk[1 : 1 + len(args)] == args:
            return start, end
    raise AssertionError(f"no block {kind} {args}")


def test_hysteresis_opens_a_loop_in_the_scan_ramps(ps, drive, clean):
    """Standard protocol: scan to +4 V, down to −4 V, back to 0 V. At the same input (0 V)
    the falling pass (middle of the −4 V ramp) lies above the rising one (end of the ramp
    back to 0) by the Prandtl–Ishlinskii loop height."""
    t, u = drive
    res = _trace(ps, drive, {"piezo_hysteresis": {"h": 0.15, "width": 2.0}})
    up0, up1 = _block("scan", 4.0)
    down0, down1 = _block("scan", -4.0)
    _back0, back1 = _block("scan", 0.0)
    i_fall = np.searchsorted(t, 0.5 * (down0 + down1))
    i_rise = np.searchsorted(t, back1)
    assert abs(u[i_fall]) < 0.05 and abs(u[i_rise]) < 1e-12
    assert abs(clean.theta[i_fall] - clean.theta[i_rise]) < 0.5e-6  # nominal: no loop
    # after a swing beyond every threshold r_i = width·i/8 each play sits at ±r_i: the
    # effective input differs by 2·h·mean(r_i) = 2·h·width·9/16, times the scan gain K
    i0 = np.searchsorted(t, up0)
    k_scan = (clean.theta[np.searchsorted(t, up1)] - clean.theta[i0]) / 4.0
    expect = 2 * 0.15 * 2.0 * 9 / 16 * k_scan
    assert res.theta[i_fall] - res.theta[i_rise] == pytest.approx(expect, rel=0.05)


def test_creep_keeps_moving_after_a_scan_ramp(ps, drive, clean):
    t, _ = drive
    res = _trace(ps, drive, {"piezo_creep": {"gamma": 0.02}})
    _up0, up1 = _block("scan", 4.0)
    i0, i1 = np.searchsorted(t, [up1 + 0.005, up1 + 0.035])  # the hold after the +4 V ramp
    drift = res.theta[i1] - res.theta[i0]
    drift_clean = clean.theta[i1] - clean.theta[i0]
    assert abs(drift_clean) < 0.1e-6
    assert drift > 0.3e-6  # creeping on in the ramp's direction


def _block_steps(ps, drive, res):
    """Net angle change over the first forward and backward 2 V, 100 Hz blocks (each
    measured to 15 ms after its end, when the ring has settled)."""
    f0, f1 = _block("steps", 2.0, 100.0)
    b0, b1 = _block("steps", -2.0, 100.0)
    th = np.interp([f0, f1 + 0.015, b0, b1 + 0.015], drive[0], res.theta)
    return th[1] - th[0], th[3] - th[2]


def test_amplifier_slew_scale_shrinks_the_adapted_steps(ps, drive, clean):
    res = _trace(ps, drive, {"amplifier_dynamics": {"slew_scale": 0.5, "current_scale": 1.0}})
    fwd, _ = _block_steps(ps, drive, res)
    fwd0, _ = _block_steps(ps, drive, clean)
    assert 0.0 < fwd < 0.8 * fwd0


def test_only_the_amplifier_lag_is_left_out_of_the_default_search():
    """A trace calibration searches every catalogue effect but the output lag, a model
    option profiled with the nominal fit (:mod:`turntable_env.effects`, ``searched``): the
    calibration's default candidates are the catalogue less it, in the catalogue's order."""
    from turntable_env.calibration.trace_fit import SEARCHED

    assert list(SEARCHED) == [n for n in CATALOGUE if n != "amplifier_lag"]
    assert not CATALOGUE["amplifier_lag"].searched


@pytest.mark.parametrize("alpha", [0.25, -0.25])
def test_friction_asymmetry_makes_forward_and_backward_steps_differ(ps, drive, clean, alpha):
    """By the sliding direction: α > 0 raises μ while the table slides forward over the
    tubes — a forward step's slip, when the tubes fly back under it — so forward steps
    shrink and backward ones grow (the independent plants' asymmetry, phase by phase)."""
    res = _trace(ps, drive, {"friction_asymmetry": {"alpha": alpha}})
    fwd, back = _block_steps(ps, drive, res)
    f0, b0 = _block_steps(ps, drive, clean)
    assert abs(f0 + b0) < 0.05 * f0  # the nominal model is symmetric
    assert abs(fwd + back) > 0.1 * abs(fwd)
    assert np.sign(abs(fwd) - abs(f0)) == -np.sign(alpha)
    assert np.sign(abs(back) - abs(b0)) == np.sign(alpha)
    res_flip = _trace(ps, drive, {"friction_asymmetry": {"alpha": -alpha}})
    ff, bf = _block_steps(ps, drive, res_flip)
    assert np.sign(fwd + back) == -np.sign(ff + bf)


def test_friction_wear_changes_the_steps_with_travel(ps, drive, clean):
    """The later (backward) block over the earlier (forward) one: friction growing with
    travel (β > 0) shrinks it, falling friction (β < 0) enlarges it; nominal ≈ 1. Each
    change exceeds twice the nominal model's own departure from 1 (what the protocol and
    the integration leave without wear; :func:`_wear_floor`)."""
    ratio = {}
    for beta in (-0.3, 0.0, 0.3):
        res = _trace(ps, drive, {"friction_wear": {"beta": beta}}) if beta else clean
        fwd, back = _block_steps(ps, drive, res)
        ratio[beta] = abs(back) / abs(fwd)
    assert abs(ratio[0.0] - 1.0) < 0.01
    floor = _wear_floor(ratio[0.0])
    assert ratio[0.3] < ratio[0.0] - floor and ratio[-0.3] > ratio[0.0] + floor


def _wear_floor(r0: float) -> float:
    """The smallest change of the backward/forward block ratio the wear tests count as an
    effect: twice the nominal model's own departure of that ratio from 1 (its symmetry is
    exact, so the departure is the protocol's and the integrator's), at least 0.2 %."""
    return max(2.0 * abs(r0 - 1.0), 0.002)


@pytest.mark.parametrize("beta", [-0.3, 0.1])
@pytest.mark.parametrize("k", [0.1, 0.5, 2.0])
def test_friction_wear_runs_in(beta, k):
    """The running-in form: the same slope β per 10 µm at the start as the linear form,
    levelling off at 1 + β/k, monotone in the travel, and the linear form as k → 0."""
    row = pack_effects(check_effects({"friction_wear": {"beta": beta, "saturation": k}}))
    lin = pack_effects(check_effects({"friction_wear": {"beta": beta}}))
    dx = 1e-4 * WEAR_LENGTH
    slope = (friction_scale(row, np.array(dx)) - 1.0) / (dx / WEAR_LENGTH)
    assert slope == pytest.approx(beta, rel=1e-3)
    far = friction_scale(row, np.array(200.0 * WEAR_LENGTH / k))
    assert far == pytest.approx(max(1.0 + beta / k, 0.2), rel=1e-9)
    travel = np.linspace(0.0, 50.0 * WEAR_LENGTH, 400)
    s = friction_scale(np.broadcast_to(row, (travel.size, row.size)), travel)
    assert np.all(np.sign(np.diff(s)) * np.sign(beta) >= 0.0)
    # running in: never more change than the linear form
    s_lin = friction_scale(np.broadcast_to(lin, (travel.size, lin.size)), travel)
    assert np.all(np.abs(s - 1.0) <= np.abs(s_lin - 1.0) + 1e-12)
    tiny = pack_effects(check_effects({"friction_wear": {"beta": beta, "saturation": 1e-9}}))
    np.testing.assert_allclose(
        friction_scale(np.broadcast_to(tiny, (travel.size, tiny.size)), travel), s_lin,
        rtol=1e-7,
    )  # fmt: skip


def test_friction_wear_that_runs_in_changes_the_later_steps_less(ps, drive, clean):
    """With falling friction (β < 0) the later (backward) block outgrows the earlier one;
    contacts that have run in (saturation 2: most of the change within the first 5 µm)
    change the later block less than the linear form with the same start."""
    ratio = {}
    for k in (0.0, 2.0):
        res = _trace(ps, drive, {"friction_wear": {"beta": -0.3, "saturation": k}})
        fwd, back = _block_steps(ps, drive, res)
        ratio[k] = abs(back) / abs(fwd)
    fwd0, back0 = _block_steps(ps, drive, clean)
    r0 = abs(back0) / abs(fwd0)
    assert ratio[0.0] > r0 + _wear_floor(r0)
    assert 0.0 < ratio[2.0] - r0 < 0.8 * (ratio[0.0] - r0)


def test_parse_effects_spec():
    e = parse_effects("piezo_creep=0.02,sensor_drift.rate=0.1,vibration")
    assert e["piezo_creep"] == {"gamma": 0.02}
    assert e["sensor_drift"] == {"offset": 0.0, "rate": 0.1}
    assert e["vibration"] == CATALOGUE["vibration"].defaults()
    for bad, match in [
        ("magic=1", "not in the catalogue"),
        ("piezo_creep=abc", "not a number"),
        ("piezo_creep=0.5", r"piezo_creep.gamma=0.5: outside"),
        ("sensor_drift.speed=1", "unknown parameter"),
    ]:
        with pytest.raises(ValueError, match=match):
            parse_effects(bad)
    with pytest.raises(ValueError, match="catalogue"):
        check_effects({"gremlins": {}})


def test_virtual_lab_file_reproduces_its_own_simulation(tmp_path, ps):
    """The written file holds the drive the simulator ran: simulating the loaded drive
    with the same effects (noise off) reproduces the detector trace."""
    eff = {"piezo_creep": {"gamma": 0.02}, "friction_asymmetry": {"alpha": 0.2}}
    m = run_virtual_lab("thesis", eff, noise_std=0.0, out=tmp_path / "lab.csv")
    back = load_measurement(tmp_path / "lab.csv")
    assert back.meta == {"protocol": "thesis"} and back.axis == "B"
    res = simulate_trace(Plant(ps, effects=eff), "B", back.time, back.drives["B"])
    np.testing.assert_allclose(res.detector_v, m.detector_v, atol=1e-9)
    assert np.abs(back.drives["B"]).max() <= 10.0


@pytest.mark.parametrize("name", sorted(PROTOCOLS))
def test_protocols_drive_both_directions_inside_the_detector_range(ps, name):
    m = run_virtual_lab(name, {}, noise_std=0.0)
    u = m.drives["B"]
    assert u.max() > 1.0 and u.min() < -1.0
    assert np.abs(m.detector_v).max() < 0.9 * ps.detector.saturation_voltage
