"""The second independent plant: physics and contracts (short protocols: fast)."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from turntable_env.calibration.measurement import load_measurement
from turntable_env.testing.second_plant import (
    EFFECT_NAMES,
    PROTOCOLS,
    AxisMisalignment,
    Burst,
    ContactWear,
    Creep,
    DetectorNonlinearity,
    Effects,
    FloorVibration,
    FrictionAsymmetry,
    Hold,
    Hysteresis,
    MainsPickup,
    MirrorPlay,
    PlantParams,
    Protocol,
    Ramp,
    Scan,
    SensorDrift,
    SlowAmplifier,
    build_drive,
    detector_outputs,
    drive_at,
    simulate,
    step_per_period,
    write_trace,
)

P = PlantParams()
FLYBACK = 30e-6  # s


def _a(freq: float) -> float:
    return 1.0 - FLYBACK * freq


def _line(signal: np.ndarray, rate: float, freq: float) -> float:
    """Amplitude of the sinusoid at ``freq`` in ``signal`` (least squares with an offset
    and a trend)."""
    t = np.arange(signal.size) / rate
    w = 2 * np.pi * freq * t
    basis = np.column_stack([np.sin(w), np.cos(w), np.ones_like(t), t])
    coef = np.linalg.lstsq(basis, signal, rcond=None)[0]
    return float(np.hypot(coef[0], coef[1]))


# ------------------------------------------------------------------ derived values


def test_bending_radius_and_stroke_follow_the_thesis():
    # Table D.1: R_bending = 1.570e4 m at 1 V (Eq. 2.12 with D = R_o + R_i)
    assert 1.0 / P.bending_curvature_per_V == pytest.approx(1.570e4, rel=2e-3)
    # stroke = Eq. 2.11 (L²/2R) plus the tip slope (L/R) times the ball lever
    c, length = P.bending_curvature_per_V, P.tube_length_m
    assert P.stroke_m_per_V == pytest.approx(c * length**2 / 2 + c * length * P.ball_lever_m)
    # Eq. B.6 at the tube end is Table D.1's K_x; the contact point above it is softer
    ei = P.tube_youngs_modulus_Pa * P.tube_area_moment_m4
    assert 3 * ei / length**3 == pytest.approx(2.471e7, rel=2e-3)
    assert P.tube_stiffness_N_per_m < 3 * ei / length**3
    # two table modes well apart: rotation on the contacts 2–3 kHz, mirror mode 9.5 kHz
    assert 2e3 < P.rotation_mode_Hz("B") < 3e3 < P.mirror_mode_frequency_Hz


# ------------------------------------------------------------------ stepping


@pytest.mark.parametrize(("amp", "freq"), [(1.0, 100.0), (2.0, 500.0)])
def test_step_converges_with_the_integration_step(amp, freq):
    fine = dataclasses.replace(P, time_step_s=P.time_step_s / 2)
    s1 = step_per_period(P, amp, freq, ramp_fraction=_a(freq), periods=5)
    s2 = step_per_period(fine, amp, freq, ramp_fraction=_a(freq), periods=5)
    assert abs(s1 - s2) < 0.01 * abs(s2)


@pytest.mark.parametrize(("amp", "freq"), [(0.44, 10.0), (1.0, 500.0), (4.4, 100.0)])
def test_sawtooth_steps_and_reverse_sawtooth_reverses(amp, freq):
    periods = 4 if freq < 50 else 6
    fwd = step_per_period(P, amp, freq, ramp_fraction=_a(freq), periods=periods)
    rev = step_per_period(P, amp, freq, ramp_fraction=_a(freq), periods=periods, direction=-1)
    stroke = P.stroke_m_per_V * P.amplifier_gain * amp
    assert 20e-9 < fwd < stroke * 1.05  # tens to hundreds of nm, not more than the stroke
    assert fwd > 0.6 * stroke
    assert rev == pytest.approx(-fwd, rel=0.02)


def test_slow_flyback_gives_no_useful_step():
    # thesis §4.1.2: with too low a slew rate the table follows the drive
    slow = step_per_period(P, 2.0, 10.0, ramp_fraction=0.99, periods=3, settle_periods=1)
    fast = step_per_period(P, 2.0, 10.0, ramp_fraction=_a(10.0), periods=3, settle_periods=1)
    assert abs(slow) < 0.2 * fast


def test_no_drive_no_motion():
    sim = simulate(P, Protocol("rest", (Hold(0.01),)), np.linspace(0.0, 0.01, 201))
    assert np.all(sim.mirror_angle_rad == 0.0)
    assert np.all(sim.energy_J == 0.0)


@pytest.mark.parametrize("axis", ["A", "Z"])
def test_passive_without_drive(axis):
    t = np.linspace(0.0, 0.02, 801)
    sim = simulate(P, Protocol("rest", (Hold(0.02),)), t, axis=axis, initial_rate_rad_per_s=2e-3)
    e = sim.energy_J
    assert e[0] > 0
    assert e.max() <= e[0] * (1 + 1e-3)  # never gains energy
    assert e[-1] < 1e-3 * e[0]  # and dissipates what it had


def _scan(effects: Effects | None = None, amp: float = 8.0):
    proto = Protocol("scan", (Hold(0.01), Scan(amp, 5.0, 1), Hold(0.01)))
    bt, bu = build_drive(proto)
    t = np.arange(0.0, bt[-1], 1e-4)
    sim = simulate(P, proto, t, effects=effects)
    return t, drive_at(bt, bu, t), sim


def _loop_width(t, u, angle):
    """(descending − ascending branch at u = 0) / peak-to-peak, over the scan (the drive
    crosses 0 V going down at 0.11 s and going up at 0.21 s)."""
    m = (t > 0.01) & (t < 0.21)
    a_dn = np.interp(0.11, t, angle)
    a_up = np.interp(0.21, t, angle)
    return (a_dn - a_up) / np.ptp(angle[m])


def test_stuck_table_scan_is_reversible_and_has_the_stroke_range():
    t, u, sim = _scan()
    angle = sim.mirror_angle_rad
    assert abs(_loop_width(t, u, angle)) < 0.01
    expected = 2 * 8.0 * P.amplifier_gain * P.stroke_m_per_V / P.table_radius_m
    assert np.ptp(angle) == pytest.approx(expected, rel=0.02)
    assert abs(angle[-1]) < 1e-3 * expected  # back where it started: no slip


def test_hysteresis_opens_the_scan_loop():
    h = Hysteresis(loop_width_fraction=0.13, reference_V=360.0)
    t, u, sim = _scan(Effects(hysteresis=h))
    assert 0.08 < _loop_width(t, u, sim.mirror_angle_rad) < 0.2


def test_mirror_play_opens_a_loop_of_the_play_width():
    t, u, sim = _scan(Effects(mirror_play=MirrorPlay(play_rad=1.5e-5)))
    m = (t > 0.01) & (t < 0.21)
    width = _loop_width(t, u, sim.mirror_angle_rad) * np.ptp(sim.mirror_angle_rad[m])
    assert width == pytest.approx(1.5e-5, rel=0.2)


# ------------------------------------------------------------------ effects


def _move_and_hold(effects: Effects | None):
    proto = Protocol("mh", (Hold(0.01), Ramp(0.0, 6.0, 0.02), Hold(0.4, 6.0)))
    t = np.arange(0.0, 0.43, 1e-3)
    return t, simulate(P, proto, t, effects=effects).mirror_angle_rad


def test_creep_relaxes_during_a_hold_after_a_move():
    t, clean = _move_and_hold(None)
    _, crept = _move_and_hold(Effects(creep=Creep(fraction_per_decade=0.07)))
    hold = t >= 0.05
    assert np.ptp(clean[hold]) < 1e-3 * clean[-1]  # the stuck table stays put
    early = crept[(t >= 0.05) & (t < 0.15)]
    late = crept[(t >= 0.33)]
    assert crept[-1] - crept[np.argmax(hold)] > 0.03 * clean[-1]  # it keeps moving …
    assert np.ptp(early) > np.ptp(late)  # … ever more slowly (logarithmic)


def test_sensor_drift_makes_the_hold_levels_trend():
    t = np.linspace(0.0, 2.0, 2001)
    angle = np.full_like(t, 1e-5)
    drift = SensorDrift(rate_V_per_s=8e-3)
    vx, _ = detector_outputs(P, t, angle, effects=Effects(sensor_drift=drift))
    slope = np.polyfit(t, vx, 1)[0]
    assert slope == pytest.approx(8e-3, rel=1e-6)


@pytest.mark.parametrize("fraction", [0.3, -0.25])
def test_friction_asymmetry_makes_steps_differ_by_direction(fraction):
    eff = Effects(friction_asymmetry=FrictionAsymmetry(fraction=fraction))
    kw = {"ramp_fraction": _a(100.0), "periods": 5}
    fwd = step_per_period(P, 2.0, 100.0, effects=eff, **kw)
    rev = -step_per_period(P, 2.0, 100.0, effects=eff, direction=-1, **kw)
    cf = step_per_period(P, 2.0, 100.0, **kw)
    cr = -step_per_period(P, 2.0, 100.0, direction=-1, **kw)
    assert abs(cf / cr - 1) < 0.005
    # forward steps slip backwards (v < 0) in the flyback: more friction there, smaller step
    ratio = fwd / rev
    assert (ratio < 0.95) if fraction > 0 else (ratio > 1.03)
    assert abs(ratio - 1) < abs(fraction)  # the step changes less than the friction


def test_floor_vibration_shows_a_line_at_its_frequency():
    t = np.arange(0.0, 0.5, 1e-4)
    proto = Protocol("rest", (Hold(0.5),))
    vib = FloorVibration(amplitude_m=30e-9, frequency_Hz=147.0)
    sim = simulate(P, proto, t, effects=Effects(floor_vibration=vib))
    # the stuck table follows its mounts: angle amplitude = mount amplitude / lever
    line = _line(sim.mirror_angle_rad, 1e4, 147.0)
    assert line == pytest.approx(30e-9 / P.table_radius_m, rel=0.1)
    assert _line(sim.mirror_angle_rad, 1e4, 120.0) < 0.05 * line


def test_mains_pickup_moves_the_table_at_50_Hz_but_not_the_recorded_drive():
    t = np.arange(0.0, 0.4, 1e-4)
    proto = Protocol("rest", (Hold(0.4),))
    sim = simulate(P, proto, t, effects=Effects(mains_pickup=MainsPickup(0.15, 50.0)))
    expected = 0.15 * P.amplifier_gain * P.stroke_m_per_V / P.table_radius_m
    assert _line(sim.mirror_angle_rad, 1e4, 50.0) == pytest.approx(expected, rel=0.1)


def test_axis_misalignment_leaks_x_into_y_proportionally():
    t = np.linspace(0.0, 1.0, 1001)
    angle = 2e-4 * np.sin(2 * np.pi * 3 * t)
    g = 4.0
    vx, vy = detector_outputs(P, t, angle, effects=Effects(axis_misalignment=AxisMisalignment(g)))
    assert np.polyfit(vx, vy, 1)[0] == pytest.approx(-math.tan(math.radians(g)), rel=1e-6)
    _, vy0 = detector_outputs(P, t, angle)
    assert np.all(vy0 == 0.0)


def test_detector_nonlinearity_loses_gain_towards_the_edge():
    t = np.linspace(0.0, 1.0, 11)
    angle = np.linspace(0.0, 0.9, 11) * P.detector_clip_V * P.detector_sensitivity_m_per_V
    angle = 0.5 * np.arctan(angle / P.detector_distance_m)  # Eq. 4.1
    lin, _ = detector_outputs(P, t, angle)
    nl, _ = detector_outputs(
        P, t, angle, effects=Effects(detector_nonlinearity=DetectorNonlinearity(0.2))
    )
    gain = nl[1:] / lin[1:]
    assert np.all(np.diff(gain) < 0)  # falls off monotonically
    assert gain[-1] == pytest.approx(1 - 0.2 * 0.9**2, rel=1e-6)
    assert lin[-1] == pytest.approx(0.9 * P.detector_clip_V, rel=1e-9)


def test_detector_clips_at_its_linear_range():
    t = np.linspace(0.0, 1.0, 5)
    vx, _ = detector_outputs(P, t, np.full(5, 1e-2), noise_std_V=1e-3)
    assert np.all(vx == P.detector_clip_V)


def test_slow_amplifier_limits_the_slew_and_shrinks_the_step():
    slow = Effects(slow_amplifier=SlowAmplifier(slew_limit_V_per_s=0.6e6, bandwidth_factor=0.4))
    proto = Protocol("edge", (Hold(1e-3), Ramp(0.0, 4.0, 1e-6), Hold(1e-3, 4.0)))
    t = np.arange(0.0, 2e-3, 1e-6)
    amp = simulate(P, proto, t, effects=slow).amplifier_V
    assert np.max(np.diff(amp)) / 1e-6 <= 0.6e6 * (1 + 1e-9)
    nominal = simulate(P, proto, t).amplifier_V
    assert np.max(np.diff(nominal)) / 1e-6 > 2e6
    kw = {"ramp_fraction": _a(100.0), "periods": 5}
    assert step_per_period(P, 4.0, 100.0, effects=slow, **kw) < 0.85 * step_per_period(
        P, 4.0, 100.0, **kw
    )


def test_contact_wear_lowers_the_friction_that_holds_the_table():
    # a flyback just too slow to slip on a fresh contact slips on a worn one
    kw = {"ramp_fraction": 0.998, "periods": 4, "settle_periods": 2}
    worn = Effects(contact_wear=ContactWear(friction_loss=0.5, distance_m=1e-9))
    fresh = step_per_period(P, 4.0, 10.0, **kw)
    assert step_per_period(P, 4.0, 10.0, effects=worn, **kw) != pytest.approx(fresh, abs=5e-9)


_ALL = {
    "creep": Creep(),
    "hysteresis": Hysteresis(),
    "floor_vibration": FloorVibration(),
    "friction_asymmetry": FrictionAsymmetry(),
    "slow_amplifier": SlowAmplifier(),
    "sensor_drift": SensorDrift(),
    "detector_nonlinearity": DetectorNonlinearity(),
    "axis_misalignment": AxisMisalignment(),
    "mains_pickup": MainsPickup(),
    "contact_wear": ContactWear(),
    "mirror_play": MirrorPlay(),
}


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_each_effect_shows_above_the_noise(name):
    proto = Protocol(
        "short",
        (
            Hold(0.02),
            Ramp(0.0, 5.0, 0.02),
            Hold(0.1, 5.0),
            Ramp(5.0, 0.0, 0.02),
            Burst(2.0, 200.0, 6, 1, _a(200.0)),
            Hold(0.05),
            Burst(2.0, 200.0, 6, -1, _a(200.0)),
            Hold(0.2),
        ),
    )
    bt, _ = build_drive(proto)
    t = np.arange(0.0, bt[-1], 5e-5)
    eff = Effects(**{name: _ALL[name]})
    clean = detector_outputs(P, t, simulate(P, proto, t).mirror_angle_rad)
    on = detector_outputs(P, t, simulate(P, proto, t, effects=eff).mirror_angle_rad, effects=eff)
    diff = np.hypot(on[0] - clean[0], on[1] - clean[1])
    assert np.max(diff) > 3e-3  # > 3× the 1 mV noise of the files
    assert set(eff.truth()) == {name}


# ------------------------------------------------------------------ contracts


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: PlantParams(contact_stiffness_N_per_m=-1.0), "contact_stiffness_N_per_m"),
        (lambda: PlantParams(tube_inner_radius_m=4e-3), "tube_inner_radius_m"),
        (lambda: PlantParams(amplifier_damping_ratio=1.5), "amplifier_damping_ratio"),
        (lambda: PlantParams(coulomb_friction_coefficient=0.5), "coulomb_friction_coefficient"),
        (lambda: PlantParams(time_step_s=float("nan")), "time_step_s"),
        (lambda: PlantParams(d31_m_per_V=0.0), "d31_m_per_V"),
        (lambda: Creep(fraction_per_decade=2.0), "fraction_per_decade"),
        (lambda: Hysteresis(operators=0), "operators"),
        (lambda: FloorVibration(frequency_Hz=0.0), "frequency_Hz"),
        (lambda: MirrorPlay(play_rad=-1.0), "play_rad"),
        (lambda: Burst(6.0, 100.0, 3, offset_V=5.0), "amplitude_V"),
        (lambda: Burst(1.0, 100.0, 3, direction=0), "direction"),
        (lambda: Scan(11.0, 1.0), "amplitude_V"),
        (lambda: Hold(-1.0), "duration_s"),
        (lambda: Effects(creep=Hysteresis()), "creep"),
        (lambda: Protocol("gap", (Hold(0.1, 1.0), Hold(0.1, 2.0))), "segments[1]"),
    ],
)
def test_bad_parameters_raise_naming_the_field(make, name):
    with pytest.raises(ValueError, match="^" + re.escape(f"{name}=")):
        make()


def test_write_trace_refuses_bad_arguments(tmp_path):
    proto = Protocol("p", (Hold(0.01),))
    with pytest.raises(ValueError, match=r"^drive_recording="):
        write_trace(tmp_path / "x.csv", P, proto, drive_recording="dense")
    with pytest.raises(ValueError, match=r"^axis="):
        write_trace(tmp_path / "x.csv", P, proto, axis="Q")
    with pytest.raises(ValueError, match=r"^noise_std_V="):
        write_trace(tmp_path / "x.csv", P, proto, noise_std_V=-1.0)


@pytest.mark.parametrize("recording", ["breakpoints", "sampled"])
def test_written_file_loads_and_reveals_nothing(tmp_path, recording):
    proto = Protocol(
        "short",
        (Hold(0.005), Burst(2.0, 700.0, 5, 1, _a(700.0)), Hold(0.005), Scan(3.0, 50.0, 1)),
    )
    eff = Effects(creep=Creep(), axis_misalignment=AxisMisalignment())
    path = write_trace(
        tmp_path / "t.csv", P, proto, effects=eff, axis="C", sample_rate_Hz=10e3,
        noise_std_V=1e-3, seed=3, drive_recording=recording,
    )  # fmt: skip
    m = load_measurement(path)
    assert m.meta == {}  # only the required keys
    header = [ln for ln in path.read_text().splitlines() if ln.startswith("#")]
    assert [h.split(":")[0][2:] for h in header] == [
        "axis",
        "amplifier_gain",
        "detector_sensitivity_m_per_V",
        "detector_distance_m",
        "table_radius_m",
    ]
    assert m.axis == "C" and m.amplifier_gain == P.amplifier_gain
    assert m.detector.sensitivity == P.detector_sensitivity_m_per_V
    assert m.detector.distance == P.detector_distance_m
    assert m.detector.table_radius == P.table_radius_m
    assert set(m.drives) == {"C"} and m.detector_y_v is not None
    bt, bu = build_drive(proto)
    np.testing.assert_allclose(m.drives["C"], drive_at(bt, bu, m.time), atol=1e-12)
    on_grid = np.isclose(m.time * 10e3, np.round(m.time * 10e3), rtol=0, atol=1e-6)
    corners = bt[bt <= m.time[-1]]
    has_all = np.all(np.min(np.abs(m.time[:, None] - corners[None, :]), axis=0) < 1e-9)
    if recording == "sampled":
        assert on_grid.all() and not has_all
    else:
        assert has_all and not on_grid.all()
    # same seed, same file
    again = write_trace(
        tmp_path / "u.csv", P, proto, effects=eff, axis="C", sample_rate_Hz=10e3,
        noise_std_V=1e-3, seed=3, drive_recording=recording,
    )  # fmt: skip
    assert again.read_bytes() == path.read_bytes()


def test_named_protocols():
    assert {"stepping_bursts", "scan_and_bursts"} <= set(PROTOCOLS)
    for name, proto in PROTOCOLS.items():
        bt, bu = build_drive(proto)
        assert np.max(np.abs(bu)) <= 10.0
        assert 2.0 <= bt[-1] <= 3.0, name
        dirs = {s.direction for s in proto.segments if isinstance(s, Burst)}
        assert dirs == {1, -1}, name
        assert any(isinstance(s, Hold) for s in proto.segments)
    assert not any(isinstance(s, Scan) for s in PROTOCOLS["stepping_bursts"].segments)
    assert any(isinstance(s, Scan) for s in PROTOCOLS["scan_and_bursts"].segments)

