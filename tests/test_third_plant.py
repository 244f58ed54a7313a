"""Physics and contracts of the third independent test plant (turntable_env.testing.third_plant).

Short simulations only; the whole file runs in well under a minute on one core.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import fields, replace

import numpy as np
import pytest

from turntable_env.testing import third_plant as tp

P = tp.PlantParams()
D = tp.derived(P)
# rim metres of ideal (no back-slip) travel per amplifier-input volt, averaged over tubes A, C
TIP_PER_V = D["contact_disp_per_output_V_m"] * P.amplifier_gain
AVG_AC = 0.5 * (P.tube_d31_factor[0] + P.tube_d31_factor[2])


def run(segs, rate=100_000.0, effects=None, axis="B", params=None, **kw):
    awg = tp.render_drive(segs)
    return tp.simulate(awg, rate, tp.protocol_duration(segs), params=params or P,
                       effects=effects, axis=axis, **kw)  # fmt: skip


def net_step(segs, n_periods, **kw):
    r = run(segs, **kw)["rim_m"]
    return (r[-100:].mean() - r[:50].mean()) / n_periods


def burst(amp, freq, ratio, direction, n=5):
    return [tp.Hold(0.001), tp.Burst(freq, amp, ratio, direction, n), tp.Hold(0.004)]


# ---------------------------------------------------------------------- parameters
def test_derived_geometry_matches_table_d1():
    # bending radius of the asymmetric mode: R_bending = 1.570e4 / V m (Table D.1)
    assert D["bending_radius_times_V_m"] == pytest.approx(1.570e4, rel=0.005)
    # Euler-Bernoulli bending stiffness K_x = 3EI/L^3 = 2.471e7 N/m
    assert 3 * D["bending_EI_Nm2"] / P.tube_length_m**3 == pytest.approx(2.471e7, rel=0.005)
    # tube mass incl. the alumina ball: 9.954e-4 kg
    m_tube = (
        P.tube_density_kg_m3
        * math.pi
        * (P.tube_outer_radius_m**2 - P.tube_inner_radius_m**2)
        * P.tube_length_m
    )
    assert m_tube + D["ball_mass_kg"] == pytest.approx(9.954e-4, rel=0.005)
    assert D["table_inertia_kgm2"] == pytest.approx(0.4 * P.table_mass_kg * 0.01**2, rel=1e-3)
    # shear makes the tip softer than the Euler-Bernoulli value; modes well above 2 kHz
    assert D["tube_tip_stiffness_N_m"] < 2.471e7
    f1, f2 = D["tube_mode_frequencies_Hz"]
    assert 5e3 < f1 < f2 < 2e5
    # Mindlin slip displacement: tens of nanometres for ~1 N on a millimetre-scale ball
    assert 5e-9 < D["mindlin_slip_displacement_m"] < 2e-7


def test_iwan_bank_reproduces_mindlin_curve():
    k, w = tp._iwan_bank(8, 1.0)
    assert k.sum() == pytest.approx(1.0)
    assert w.sum() == pytest.approx(1.0)
    # virgin loading curve of the bank vs Mindlin 1 - (1 - d/d*)^(3/2), d* = 1.5 (k_t = 1)
    brk = w / k  # break displacements, in units where mu N = 1
    dstar = 1.5
    for d in (0.2, 0.5, 1.0, 1.4):
        f = np.sum(np.where(brk <= d, w, k * d))
        assert f == pytest.approx(1.0 - (1.0 - d / dstar) ** 1.5, abs=0.06)


# ---------------------------------------------------------------------- stick phase
def test_slow_scan_moves_table_with_tube_tips_and_back():
    segs = [tp.Hold(0.002), tp.Scan(0.04, 3.0), tp.Hold(0.01), tp.Scan(0.04, 0.0),
            tp.Hold(0.01)]  # fmt: skip
    s = run(segs, rate=10_000.0)
    i_top = int(0.051 * 10_000)
    rim = s["rim_m"][i_top]
    tips = 0.5 * (s["y_p"][i_top] + s["y_q"][i_top])
    assert rim == pytest.approx(tips, rel=0.03)
    assert rim == pytest.approx(3.0 * TIP_PER_V * AVG_AC, rel=0.05)
    # in stick the table returns with the tubes: no net slip
    assert abs(s["rim_m"][-1]) < 0.005 * rim
    # no slip during the scan: slid distance stays tiny compared with the scan
    assert s["slid"][-1] < 0.01 * rim


# ---------------------------------------------------------------------- stepping
def test_burst_steps_with_the_drive_and_reverses():
    fwd = net_step(burst(3.0, 1000.0, 0.99, +1), 5)
    bwd = net_step(burst(3.0, 1000.0, 0.99, -1), 5)
    ideal = 3.0 * TIP_PER_V
    assert fwd > 0.4 * ideal
    assert bwd < -0.4 * ideal
    # and each period steps: the staircase rises after every flyback
    s = run(burst(3.0, 1000.0, 0.99, +1, n=5), rate=100_000.0)
    ends = [s["rim_m"][int((0.001 + k * 1e-3) * 1e5) - 1] for k in range(1, 6)]
    assert np.all(np.diff(ends) > 0.3 * ideal)


def test_step_grows_with_amplitude_both_directions():
    for direction in (+1, -1):
        steps = [abs(net_step(burst(a, 1000.0, 0.99, direction), 5)) for a in (2.0, 4.0, 6.0)]
        assert steps[0] < steps[1] < steps[2]
        assert steps[2] > 2.0 * steps[0]


def test_slow_flyback_only_rocks_the_table():
    # thesis section 4.1: with a slow edge the table follows the tubes, no net motion
    step = net_step(burst(3.0, 100.0, 0.6, +1, n=2), 2)
    assert abs(step) < 0.05 * 3.0 * TIP_PER_V


# ---------------------------------------------------------------------- passivity
def test_friction_dissipates_with_drive_off():
    segs = [tp.Hold(0.006)]
    rest = run(segs, rate=100_000.0)["energy"][0]
    # table spun at 2 mm/s at the rim and tube 1 bent: slides, rings down, sticks
    s = run(segs, rate=100_000.0, init_table_rate_rad_s=0.2, init_tube_mode=2e-7)
    e = s["energy"] - rest
    assert e[0] > 0
    assert np.all(e <= e[0] * (1 + 1e-3))  # never gains energy
    # energy at later times never exceeds earlier energy by more than numerical noise
    running_min = np.minimum.accumulate(e)
    assert np.all(e - running_min <= 0.02 * e[0])
    assert e[-1] < 0.2 * e[0]
    assert s["slid"][-1] > 0  # the contacts did slide


def test_elastic_ringing_in_stick_decays():
    # a small kick stays in presliding: only material/contact damping acts
    segs = [tp.Hold(0.004)]
    rest = run(segs, rate=100_000.0)["energy"][0]
    s = run(segs, rate=100_000.0, init_table_rate_rad_s=2e-3)
    e = s["energy"] - rest
    assert s["slid"][-1] < 1e-10
    assert np.all(e <= e[0] * (1 + 1e-3))
    assert e[-1] < 0.3 * e[0]
    # over each 0.5 ms window the energy goes down
    win = e[: 400 - 400 % 50].reshape(-1, 50).max(axis=1)
    assert np.all(np.diff(win) < 0)


# ---------------------------------------------------------------------- effects
SHORT = [tp.Hold(0.001), tp.Scan(0.004, 1.5), tp.Burst(1000.0, 3.0, 0.99, 1, 4),
         tp.Hold(0.002), tp.Burst(2000.0, 4.0, 0.95, -1, 4), tp.Scan(0.004, 0.0),
         tp.Hold(0.003)]  # fmt: skip


def _pipeline(effects):
    case = tp.Case("t", None, effects=effects, sample_rate_Hz=25_000.0, seed=5)
    tr = tp.trace_for_case(case, P, segments=SHORT)
    return np.column_stack([tr["drive"], tr["x"], tr["y"]])


def _neutral(name):
    """Each effect's fields set explicitly to their neutral values."""
    n = {
        "creep": dict(creep_gains=(0.0, 0.0, 0.0), creep_taus_s=(1e-3, 1e-2, 1.0)),
        "hysteresis": dict(hysteresis_eta=0.0, hysteresis_alpha_per_V=0.1),
        "friction_asymmetry": dict(friction_asymmetry=0.0),
        "sensor_drift": dict(drift_amplitude_V=0.0, drift_rate_V_s=0.0, drift_tau_s=0.3),
        "floor_vibration": dict(floor_accel_m_s2=0.0, floor_frequency_Hz=150.0),
        "detector_nonlinearity": dict(spot_radius_m=math.inf),
        "axis_misalignment": dict(misalignment_deg=0.0),
        "slow_amplifier": dict(amplifier_gain_bandwidth_Hz=P.amplifier_gain_bandwidth_Hz,
                               amplifier_slew_V_per_s=P.amplifier_slew_V_per_s,
                               amplifier_current_A=P.amplifier_current_A),
        "contact_wear": dict(wear_fraction=0.0, wear_distance_m=1e-6),
        "drive_crosstalk": dict(crosstalk_ac=0.0, crosstalk_dc=0.0, crosstalk_tau_s=1e-3),
        "preload_creep": dict(preload_loss=0.0, preload_tau_s=0.1),
    }[name]  # fmt: skip
    return tp.Effects(**n)


@pytest.fixture(scope="module")
def clean_short():
    return _pipeline(tp.Effects())


@pytest.mark.parametrize("name", tp.EFFECT_NAMES)
def test_neutral_effect_reproduces_clean_and_active_effect_changes_it(name, clean_short):
    assert np.array_equal(_pipeline(_neutral(name)), clean_short)
    case = next(c for c in tp.CASES.values() if c.effect == name)
    active = _pipeline(case.effects)
    assert np.array_equal(active[:, 0], clean_short[:, 0])  # same drive
    assert np.max(np.abs(active[:, 1:] - clean_short[:, 1:])) > 1e-4  # visible in volts


def test_cases_cover_the_catalogue_once():
    effects = [c.effect for c in tp.CASES.values() if c.effect]
    assert sorted(effects) == sorted(tp.EFFECT_NAMES)
    assert len(set(effects)) == len(effects)
    assert {"clean", "clean_axis_A_10kHz"} <= set(tp.CASES)
    for c in tp.CASES.values():
        assert 0.001 <= c.noise_std_V <= 0.005
        assert c.sample_rate_Hz in (10_000.0, 25_000.0)
        # every effect field not named by the case's effect is neutral
        own = set(tp.EFFECT_FIELDS.get(c.effect, ())) if c.effect else set()
        for f in fields(tp.Effects):
            if f.name not in own and not f.name.endswith(
                ("_tau_s", "_taus_s", "alpha_per_V", "frequency_Hz", "distance_m", "y_fraction")
            ):
                assert getattr(c.effects, f.name) == getattr(tp.Effects(), f.name), (c.name, f.name)


def test_friction_asymmetry_favours_one_direction():
    e = tp.Effects(friction_asymmetry=0.3)
    fwd0 = net_step(burst(3.0, 1000.0, 0.99, +1), 5)
    bwd0 = net_step(burst(3.0, 1000.0, 0.99, -1), 5)
    fwd = net_step(burst(3.0, 1000.0, 0.99, +1), 5, effects=e)
    bwd = net_step(burst(3.0, 1000.0, 0.99, -1), 5, effects=e)
    assert fwd / fwd0 - abs(bwd) / abs(bwd0) > 0.08


def test_slow_amplifier_shrinks_fast_steps():
    e = tp.CASES["slow_amplifier"].effects
    fast = net_step(burst(4.0, 2000.0, 0.99, +1), 5)
    slow = net_step(burst(4.0, 2000.0, 0.99, +1), 5, effects=e)
    assert 0 < slow < 0.8 * fast


# ---------------------------------------------------------------------- detector
def _fake_sim(theta, phi_y=None):
    n = len(theta)
    z = np.zeros(n)
    return {"t": np.arange(n) * 1e-4, "theta": theta, "phi_x": z, "phi_y": z if phi_y is None
            else phi_y, "crosstalk": z, "v_out": z}  # fmt: skip


def test_detector_linear_misaligned_and_erf():
    L, S = P.detector_distance_m, P.detector_sensitivity_m_per_V
    theta = np.linspace(-4e-4, 4e-4, 9)
    vx, vy, _ = tp.detector_signals(_fake_sim(theta), params=P)
    np.testing.assert_allclose(vx - P.detector_offset_V[0], L * np.tan(2 * theta) / S)
    np.testing.assert_allclose(vy, P.detector_offset_V[1])
    # misalignment: y sees sin(angle) of the motion
    e = tp.Effects(misalignment_deg=4.0)
    _, vy2, _ = tp.detector_signals(_fake_sim(theta), params=P, effects=e)
    np.testing.assert_allclose(
        vy2 - P.detector_offset_V[1], -math.sin(math.radians(4)) * (vx - P.detector_offset_V[0])
    )
    # erf response: small error near the centre, several percent at 80 % of the range
    e = tp.CASES["detector_nonlinearity"].effects
    spot = np.array([0.1, 0.8]) * P.detector_range_m
    th = 0.5 * np.arctan(spot / L)
    vn, _, _ = tp.detector_signals(_fake_sim(th), params=P, effects=e)
    rel = 1 - (vn - P.detector_offset_V[0]) / (spot / S)
    assert rel[0] < 0.005
    assert 0.02 < rel[1] < 0.15


# ---------------------------------------------------------------------- protocol
def test_lab_protocol_shape():
    segs = tp.lab_protocol(7, pretest=False)
    assert segs == tp.lab_protocol(7, pretest=False)  # deterministic
    assert 2.3 <= tp.protocol_duration(segs) <= 2.7
    bursts = [s for s in segs if isinstance(s, tp.Burst)]
    scans = [s for s in segs if isinstance(s, tp.Scan)]
    assert {b.direction for b in bursts} == {-1, 1}
    dirs = [b.direction for b in bursts]
    assert any(a == b for a, b in itertools.pairwise(dirs))  # not strictly alternating
    assert len({b.amplitude_V for b in bursts}) >= 3
    assert len({b.frequency_Hz for b in bursts}) >= 4
    assert len({b.ramp_ratio for b in bursts}) >= 3
    assert all(2.0 <= b.amplitude_V <= 8.0 and 10 <= b.frequency_Hz <= 2000 for b in bursts)
    assert all(0.5 <= b.ramp_ratio <= 0.99 for b in bursts)
    levels = [s.to_V for s in scans]
    assert max(levels) > 0 > min(levels)
    long_holds = [h for prev, h in itertools.pairwise(segs)
                  if isinstance(prev, tp.Burst) and isinstance(h, tp.Hold)
                  and h.duration_s >= 0.05]  # fmt: skip
    assert len(long_holds) >= 3
    drive = tp.render_drive(segs)
    assert np.abs(drive).max() <= 10.0
    # a burst returns to its base level and its shape is slow ramp / fast flyback
    b = tp.Burst(100.0, 4.0, 0.9, 1, 1)
    w = tp.render_drive([b])
    assert w[0] == 0.0 and w[10_000] == 0.0
    assert np.argmax(w) == pytest.approx(9000, abs=1)


# ---------------------------------------------------------------------- files
def test_trace_file_loads_with_required_keys(tmp_path):
    from turntable_env.calibration.measurement import load_measurement

    case = replace(tp.CASES["axis_misalignment"], sample_rate_Hz=10_000.0)
    tr = tp.trace_for_case(case, P, segments=SHORT)
    path = str(tmp_path / "m.csv")
    tp.write_csv_atomic(path, tr, case.axis)
    assert os.listdir(tmp_path) == ["m.csv"]  # no temporary left behind
    text = open(path, encoding="utf-8").read()
    for key in ("axis", "amplifier_gain", "detector_sensitivity_m_per_V",
                "detector_distance_m", "table_radius_m"):  # fmt: skip
        assert f"# {key}: " in text
    m = load_measurement(path)
    assert m.axis == "B"
    assert m.amplifier_gain == pytest.approx(P.amplifier_gain)
    assert list(m.drives) == ["B"]
    assert np.all(np.diff(m.time) > 0)
    np.testing.assert_allclose(m.drives["B"], tr["drive"], atol=1e-6)
    np.testing.assert_allclose(m.detector_v, tr["x"], atol=1e-6)
    assert m.detector_y_v is not None
    np.testing.assert_allclose(m.detector_y_v, tr["y"], atol=1e-6)
    assert np.abs(m.drives["B"]).max() <= 10.0


def test_script_rejects_unknown_case(tmp_path, capsys):
    import importlib.util
    import pathlib

    spec = importlib.util.spec_from_file_location(
        "third_plant_traces",
        pathlib.Path(__file__).resolve().parents[1] / "experiments" / "third_plant_traces.py",
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    with pytest.raises(SystemExit) as exc:
        mod.main(["--out", str(tmp_path), "--only", "clean", "no_such_case"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no_such_case" in err
    assert os.listdir(tmp_path) == []


# ---------------------------------------------------------------------- numerics
def test_step_halving_converges():
    segs = [tp.Hold(0.001), tp.Scan(0.005, 2.0), tp.Burst(2000.0, 6.0, 0.99, 1, 6),
            tp.Hold(0.003), tp.Burst(1000.0, 4.5, 0.98, -1, 6), tp.Hold(0.003),
            tp.Burst(500.0, 3.0, 0.95, 1, 4), tp.Scan(0.005, 0.0), tp.Hold(0.004)]  # fmt: skip
    a = run(segs, rate=25_000.0)["rim_m"]
    b = run(segs, rate=25_000.0, params=replace(P, dt_s=P.dt_s / 2))["rim_m"]
    motion = np.sqrt(np.mean((a - a.mean()) ** 2))
    ratio = np.sqrt(np.mean((a - b) ** 2)) / motion
    assert motion > 1e-6  # the excerpt moves the table by microns
    assert ratio < 0.02
