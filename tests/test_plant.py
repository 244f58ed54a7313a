"""The plant layer: Plant as a value, its stages in the stepper, and the env running it."""

from __future__ import annotations

import json
import math
import pickle
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
from conftest import scan_angles as _scan

import turntable_env  # noqa: F401  (registers the envs)
from turntable_env.effects import (
    CATALOGUE,
    CREEP_TAUS,
    N_PLAY,
    apply_input,
)
from turntable_env.envs import ActionScaling, PiezoTurntableVectorEnv
from turntable_env.params import real_parameters
from turntable_env.plant import DEFAULT_RANDOMIZATION, Plant, PlantStepper

SCALE = ActionScaling()
HOME = {"start_angle": 0.0, "target_angle": 0.0}
ALL_EFFECTS = {name: e.defaults() for name, e in CATALOGUE.items()}


# --- Plant as a value ------------------------------------------------------------------------
def test_plant_is_immutable_hashable_picklable_and_readable():
    p = Plant(factors={"friction": 1.2}, effects={"piezo_creep": {"gamma": 0.03}})
    assert p == pickle.loads(pickle.dumps(p)) and hash(p) == hash(pickle.loads(pickle.dumps(p)))
    assert {p: 1}[Plant(effects={"piezo_creep": {"gamma": 0.03}}, factors={"friction": 1.2})] == 1
    with pytest.raises(AttributeError):
        p.fidelity = "full"  # type: ignore[misc]
    with pytest.raises(TypeError):
        p.effects["vibration"] = {}  # type: ignore[index]
    text = repr(p)
    assert "piezo_creep" in text and "gamma" in text and "friction" in text and "reduced" in text
    assert dict(p.effects["piezo_creep"]) == {"gamma": 0.03}


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"effects": {"gremlins": {}}}, "gremlins"),
        ({"effects": {"piezo_creep": {"gamma": 0.5}}}, "piezo_creep.gamma"),
        ({"factors": {"stiffness": 1.1}}, "stiffness"),
        ({"factors": {"friction": 0.0}}, "friction"),
        ({"fidelity": "medium"}, "fidelity"),
        ({"base": "imaginary"}, "imaginary"),
        ({"sensor_noise": -1e-3}, "sensor_noise"),
        ({"uncertainty": {"piezo_creep.speed": 0.1}}, "piezo_creep.speed"),
    ],
)
def test_plant_rejects_bad_fields_naming_them(kwargs, field):
    with pytest.raises(ValueError, match=field):
        Plant(**kwargs)


def test_factors_and_parameter_effects_reach_the_parameter_set():
    """Preload ×1.3 re-derives F_N (Hertz–Mindlin inputs); amplifier_dynamics and the
    amplifier factor scale the HVA 900's slew; the base set is untouched."""
    base = real_parameters()
    p = Plant(
        factors={"preload": 1.3, "amplifier": 0.8},
        effects={"amplifier_dynamics": {"slew_scale": 0.5, "current_scale": 1.0}},
    )
    ps = p.params
    assert ps.contact.preload == pytest.approx(1.3 * base.contact.preload, rel=1e-12)
    assert ps.amplifier.slew_per_input_volt == pytest.approx(
        0.8 * 0.5 * base.amplifier.slew_per_input_volt, rel=1e-12
    )
    assert ps.amplifier.current_limit == pytest.approx(0.8 * base.amplifier.current_limit)
    assert Plant().params == base
    assert Plant(ideal_amplifier=True).params.amplifier.ideal


def test_sample_draws_default_ranges_and_multiplies_the_plants_factors():
    rng = np.random.default_rng(0)
    plant = Plant(factors={"friction": 1.5}, sensor_noise=2e-3)
    for _ in range(20):
        drawn, draw = plant.sample(rng)
        assert set(draw) == set(DEFAULT_RANDOMIZATION)
        for key, (lo, hi) in DEFAULT_RANDOMIZATION.items():
            assert lo <= draw[key] <= hi
        assert drawn.factors["friction"] == pytest.approx(1.5 * draw["friction"])
        assert drawn.sensor_noise == pytest.approx(2e-3 * draw["sensor_noise"])
        assert not drawn.uncertainty


@pytest.mark.parametrize(
    ("rng", "ranges", "match"),
    [
        (5, None, "rng=5"),  # a seed is not a generator
        ("a", None, "rng='a'"),
        (np.random.default_rng(0), {"friction": (0.5, 20.0)}, r"ranges\['friction'\]"),
        (np.random.default_rng(0), {"preload": (0.0, 1.0)}, r"ranges\['preload'\]"),
        (np.random.default_rng(0), {"sensor_noise": (2.0, 1.0)}, "low <= high"),
        (np.random.default_rng(0), {"gravity": (0.9, 1.1)}, "unknown"),
        (np.random.default_rng(0), {"friction": (0.9, 1.0, 1.1)}, r"must be \(low, high\)"),
        (np.random.default_rng(0), {"friction": "wide"}, r"ranges\['friction'\]='wide'"),
    ],
)
def test_sample_refuses_what_it_cannot_draw_from_before_drawing(rng, ranges, match):
    with pytest.raises(ValueError, match=match):
        Plant(factors={"friction": 1.5}).sample(rng, ranges=ranges)


def test_replace_names_an_unknown_field():
    with pytest.raises(ValueError, match="bogus: not a field of Plant"):
        Plant().replace(bogus=1)
    assert Plant().replace(sensor_noise=2e-3).sensor_noise == 2e-3


def test_sample_from_a_calibration_posterior_has_its_mean_and_spread():
    plant = Plant(
        factors={"friction": 1.2},
        effects={"piezo_creep": {"gamma": 0.02}},
        uncertainty={"friction": 0.05, "piezo_creep.gamma": 0.004},
    )
    rng = np.random.default_rng(1)
    draws = [plant.sample(rng, spread=2.0)[0] for _ in range(2000)]
    fr = np.array([d.factors["friction"] for d in draws])
    ga = np.array([d.effects["piezo_creep"]["gamma"] for d in draws])
    assert fr.mean() == pytest.approx(1.2, abs=4 * 0.1 / math.sqrt(fr.size))
    assert fr.std() == pytest.approx(2 * 0.05, rel=0.1)
    assert ga.mean() == pytest.approx(0.02, abs=4 * 0.008 / math.sqrt(ga.size))
    assert ga.std() == pytest.approx(2 * 0.004, rel=0.1)
    assert ga.min() >= 0.0  # clipped to the catalogue bounds


def test_report_round_trip_and_legacy_reports(tmp_path):
    plant = Plant(
        factors={"friction": 0.9, "preload": 1.1},
        effects={"vibration": {"amplitude": 2e-6, "frequency": 31.0, "phase": 0.2}},
        uncertainty={"friction": 0.01},
    )
    (tmp_path / "report.json").write_text(json.dumps({"plant": plant.to_dict()}))
    back = Plant.from_report(tmp_path)  # a directory reads its report.json
    assert back == plant and back.source.endswith("report.json")
    legacy = {
        "selected_effects": ["piezo_creep"],
        "parameters": {
            "nominal": {"friction": {"value": 1.1, "std": 0.02}, "preload": {"value": 0.9}},
            "piezo_creep": {"gamma": {"value": 0.03, "std": float("nan")}},
        },
    }
    (tmp_path / "old.json").write_text(json.dumps(legacy))
    old = Plant.from_report(tmp_path / "old.json")
    assert old.factors == {"friction": 1.1, "preload": 0.9}
    assert old.effects == {"piezo_creep": {"gamma": 0.03}}
    assert old.uncertainty == {"friction": 0.02}


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (None, "no such calibration report"),
        ("{not json", "line 1 column 2"),
        ("[1, 2]", "not a calibration report"),
        ('{"history": []}', "not a calibration report"),
        ('{"plant": {"base": "real", "colour": "red"}}', "colour"),
        ('{"plant": {"effects": {"piezo_creep": {"gamma": 9}}}}', "piezo_creep.gamma"),
    ],
)
def test_bad_reports_name_the_file(tmp_path, content, match):
    path = tmp_path / "report.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(ValueError, match=match) as err:
        Plant.from_report(path)
    assert "report.json" in str(err.value)


# --- input stage: exact operators ---------------------------------------------------------
def _input_stage(t, u, effects):
    return apply_input(t, u, effects)


def test_hysteresis_breakpoints_are_exact_between_the_input_breakpoints():
    """The Prandtl–Ishlinskii output is piecewise linear with kinks where a play turns: the
    compiled stage inserts them, so linear interpolation of its breakpoints equals the
    operator applied to a densely sampled input."""
    t = np.array([0.0, 1.0, 2.0, 2.5, 4.0])
    u = np.array([0.0, 6.0, -4.0, 1.0, -2.0])
    h, width = 0.2, 3.0
    tt, vv = _input_stage(t, u, {"piezo_hysteresis": {"h": h, "width": width}})
    dense = np.linspace(0.0, 4.0, 40001)
    x = np.interp(dense, t, u)
    plays = np.full(N_PLAY, x[0])
    ref = np.empty_like(x)
    r = width * np.arange(1, N_PLAY + 1) / N_PLAY
    for i, xi in enumerate(x):
        plays = np.minimum(np.maximum(plays, xi - r), xi + r)
        ref[i] = (1 - h) * xi + h * plays.mean()
    np.testing.assert_allclose(np.interp(dense, tt, vv), ref, atol=1e-12)


def test_creep_mode_relaxes_exactly_after_a_step():
    """A step of the input by ΔU at t = 0 (a jump) held for 50 ms: the output is
    ΔU·(1 + γ·Σ(1 − e^{−t/τ_i})) at every breakpoint."""
    gamma, du = 0.03, 2.0
    t = np.array([0.0, 0.0, 0.05])
    u = np.array([0.0, du, du])
    tt, vv = _input_stage(t, u, {"piezo_creep": {"gamma": gamma}})
    assert np.diff(tt).max() <= 0.5e-3 + 1e-15  # creep pieces
    expect = du * (1 + gamma * sum(1 - np.exp(-tt / tau) for tau in CREEP_TAUS))
    np.testing.assert_allclose(vv[1:], expect[1:], rtol=1e-12)


# --- stepper and env --------------------------------------------------------------------------
def _env(plant, **kw):
    return gym.make(
        "PiezoTurntable-v0", plant=plant, noise=False, terminate_on_success=False, **kw
    ).unwrapped


@pytest.mark.parametrize("name", sorted(CATALOGUE))
def test_neutral_effects_leave_the_env_bit_identical(name):
    rng = np.random.default_rng(4)
    actions = rng.uniform(-1, 1, (12, 5)).astype(np.float32)
    runs = []
    for effects in ({}, {name: CATALOGUE[name].neutral()}):
        env = gym.make("PiezoTurntable-v0", plant=Plant(effects=effects))
        obs = [env.reset(seed=2)[0]]
        obs += [env.step(a)[0] for a in actions]
        runs.append(np.array(obs))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_creep_keeps_moving_under_a_held_scan_offset():
    hold = [5.0] * 60  # V: ramped in the first interval, then held 0.59 s
    nominal = _scan(_env(Plant()), hold)[:, 0]
    creep = _scan(_env(Plant(effects={"piezo_creep": {"gamma": 0.03}})), hold)[:, 0]
    assert abs(nominal[-1] - nominal[10]) < 1e-10  # stuck: nothing moves
    late = np.diff(creep[10:])
    assert (late > 0).all() and creep[-1] - creep[10] > 0.01 * nominal[-1]


def test_hysteresis_opens_a_loop_in_a_slow_scan():
    """Up to +5 V, down to −5 V, back to 0: at 0 V the falling branch lies above the rising
    one by 2·h·mean(r_i)·K (every play saturated), K the scan gain; nominal: no loop."""
    up, down, back = np.linspace(0, 5, 10), np.linspace(5, -5, 21), np.linspace(-5, 0, 10)
    prog = np.concatenate([up, down, back])
    i_fall = 10 + 10  # the 0 V point of the falling ramp
    nominal = _scan(_env(Plant()), prog)[:, 0]
    loop = _scan(_env(Plant(effects={"piezo_hysteresis": {"h": 0.15, "width": 2.0}})), prog)
    k_scan = nominal[9] / 5.0
    assert abs(nominal[i_fall] - nominal[-1]) < 1e-3 * abs(nominal[9])
    expect = 2 * 0.15 * 2.0 * (N_PLAY + 1) / (2 * N_PLAY) * k_scan
    assert loop[i_fall, 0] - loop[-1, 0] == pytest.approx(expect, rel=0.05)


def test_vibration_is_a_periodic_reading_at_rest():
    v = {"amplitude": 5e-6, "frequency": 13.0, "phase": 0.4}
    env = _env(Plant(effects={"vibration": v}))
    a = _scan(env, [0.0] * 100)
    t = 0.01 * np.arange(1, 101)
    np.testing.assert_allclose(a[:, 0], a[0, 0], atol=1e-12)  # the table itself is at rest
    expect = v["amplitude"] * np.sin(2 * math.pi * v["frequency"] * t + v["phase"])
    np.testing.assert_allclose(a[:, 1] - a[0, 0], expect, atol=2e-8)


def test_friction_asymmetry_makes_the_steps_depend_on_direction():
    def steps(plant):
        env = _env(plant)
        env.reset(seed=0, options=HOME)
        ang = [0.0]
        for sign in (1.0, 1.0, 1.0, -1.0, -1.0, -1.0):
            *_, info = env.step(SCALE.encode(sign * 2.0, 100.0, 0.95, 1.0))
            ang.append(info["angle_rad"])
        d = np.diff(ang)
        return d[1:3].mean(), d[4:6].mean()

    f0, b0 = steps(Plant())
    f1, b1 = steps(Plant(effects={"friction_asymmetry": {"alpha": 0.25}}))
    assert abs(f0 + b0) < 0.05 * f0  # nominal: symmetric
    assert abs(f1 + b1) > 0.1 * f1


@pytest.mark.slow  # the default tier's 5 CPU minutes (stop 48): 17 s
def test_every_effect_runs_in_the_vector_env_under_random_actions():
    """10⁴ random env steps with every catalogue effect on: no exception, nothing
    non-finite, observations inside the space."""
    vec = PiezoTurntableVectorEnv(
        num_envs=16, max_episode_steps=100, plant=Plant(effects=ALL_EFFECTS), randomize=True
    )
    vec.action_space.seed(0)
    obs, _ = vec.reset(seed=0)
    for _ in range(625):
        obs, reward, _term, _trunc, info = vec.step(vec.action_space.sample())
        assert np.isfinite(obs).all() and np.isfinite(reward).all()
        assert np.isfinite(info["angle_rad"]).all() and np.isfinite(info["energy_J"]).all()
        assert vec.single_observation_space.contains(obs[0])


@pytest.mark.parametrize("name", ["piezo_creep", "friction_asymmetry", "sensor_drift"])
def test_full_fidelity_runs_the_effects_stages(name):
    """The 3-D model runs the same plant stages: an effect changes its final reading the way
    it changes the reduced model's — same sign, within a factor 2 (the two models' steps
    differ by up to 30 %, README "reduced vs full"; output stages are identical)."""
    effect = {name: CATALOGUE[name].defaults()}
    change = {}
    for fid in ("reduced", "full"):
        readings = []
        for effects in ({}, effect):
            env = _env(Plant(effects=effects, fidelity=fid))
            env.reset(seed=0, options=HOME)
            for action in (SCALE.encode(0, 100, 0.9, 0, 3.0), SCALE.encode(2.0, 100, 0.95, 1.0)):
                obs, *_ = env.step(action)
            readings.append(float(obs[0]))
        change[fid] = readings[1] - readings[0]
    assert 0.5 < change["full"] / change["reduced"] < 2.0


@pytest.mark.parametrize("fidelity", ["full", "independent"])
def test_every_fidelity_turns_the_sliding_asymmetry_the_same_way(fidelity):
    """friction_asymmetry acts on each contact's sliding direction in every integrator:
    with α > 0 (μ up while the table slides forward over a tube) a forward stepping
    interval moves the table less than without it and a backward one more, in the 3-D
    model (its own per-contact form) and in the independent plant (its own asymmetry,
    ε = −α) as in the reduced model."""
    alpha = {"friction_asymmetry": {"alpha": 0.2}}
    for fid in ("reduced", fidelity):
        for sign in (1.0, -1.0):
            moved = []
            for effects in ({}, alpha):
                env = _env(Plant(effects=effects, fidelity=fid))
                _obs, info0 = env.reset(seed=0, options=HOME)
                for _ in range(3):  # three 100 Hz periods of 90 V, flybacks at full slew
                    *_, info = env.step(SCALE.encode(sign * 2.0, 100, 0.95, 1.0))
                moved.append(abs(float(info["angle_rad"]) - float(info0["angle_rad"])))
            assert moved[0] > 0.0
            # forward: less with α > 0; backward: more
            assert np.sign(moved[1] - moved[0]) == -sign, (fid, sign, moved)


def test_stepper_requires_one_fidelity_and_one_detector():
    with pytest.raises(ValueError, match="fidelity"):
        PlantStepper([Plant(), Plant(fidelity="full")])
    with pytest.raises(ValueError, match="detector"):
        PlantStepper([Plant(), Plant("thesis")])


def test_env_takes_a_plant_or_a_report_and_refuses_both_params_and_plant(tmp_path):
    plant = Plant(effects={"piezo_creep": {"gamma": 0.01}})
    (tmp_path / "report.json").write_text(json.dumps({"plant": plant.to_dict()}))
    env = gym.make("PiezoTurntable-v0", plant=str(tmp_path / "report.json"))
    assert env.unwrapped.plant == plant
    env = gym.make("PiezoTurntable-v0", plant=plant, fidelity="full", sensor_noise=2e-3)
    assert env.unwrapped.plant == plant.replace(fidelity="full", sensor_noise=2e-3)
    with pytest.raises(ValueError, match="give one"):
        gym.make("PiezoTurntable-v0", plant=plant, params="real")


def test_registered_variants():
    assert gym.make("PiezoTurntableFull-v0").unwrapped.plant.fidelity == "full"
    env = gym.make("PiezoTurntableRandomized-v0")
    _, info = env.reset(seed=0)
    assert set(info["parameter_factors"]) == set(DEFAULT_RANDOMIZATION)


# --- the store: named plants round-trip whole (issue 33) -----------------------------------
def test_the_calibrated_plant_round_trips_whole_through_its_file(tmp_path):
    """data/calibrated.toml → Plant → TOML → Plant keeps everything: base, rig, factors,
    effects, fidelity, detector noise and the calibration's uncertainties (the old road
    through a ParameterSet dropped the last three)."""
    from turntable_env.plant import calibrated_set_toml, parameter_set

    plant = Plant.named("calibrated")
    assert plant.fidelity == "full" and plant.uncertainty and plant.rig is not None
    path = tmp_path / "again.toml"
    path.write_text(calibrated_set_toml(plant, source="test"), encoding="utf-8")
    back = Plant.from_toml(path)
    assert back == plant
    assert back.fidelity == plant.fidelity and back.sensor_noise == plant.sensor_noise
    assert dict(back.uncertainty) == dict(plant.uncertainty)
    assert back.params == replace(parameter_set("calibrated"), name=back.params.name)


def test_the_calibrated_plants_uncertainty_reaches_sample():
    """The benchmark's calibrated plant keeps the calibration's uncertainties, and
    Plant.sample draws from them: the draws scatter about the estimates by their errors."""
    from controllers.plant_sets import FIDELITY, PLANT_SETS

    plant = PLANT_SETS["calibrated"]().base
    assert plant.uncertainty and plant.fidelity == FIDELITY
    rng = np.random.default_rng(0)
    draws = np.array([[d[k] for k in ("friction", "preload")]
                      for _p, d in (plant.sample(rng) for _ in range(400))])  # fmt: skip
    for j, k in enumerate(("friction", "preload")):
        assert draws[:, j].mean() == pytest.approx(plant.factors[k], abs=0.2 * plant.uncertainty[k])
        assert draws[:, j].std() == pytest.approx(plant.uncertainty[k], rel=0.25)


def test_named_plants_and_sets_are_refused_by_an_unknown_name():
    from turntable_env.plant import parameter_set

    with pytest.raises(ValueError, match="named plants: calibrated"):
        Plant.named("wishful")
    with pytest.raises(ValueError, match="must be one of real, thesis, calibrated"):
        parameter_set("wishful")


def test_load_reads_a_set_a_plant_file_or_a_report_and_names_what_it_refuses(
    tmp_path, monkeypatch
):
    """Plant.load (``turntable calibrate --base``): a set's name is the set's plant, a
    ``*.toml`` a calibration's plant file, anything else a report; a missing path, a bad
    file and a set's name that is also a path here are refused by name."""
    from turntable_env.plant import calibrated_set_toml

    monkeypatch.chdir(tmp_path)
    assert Plant.load("real") == Plant("real")
    assert Plant.load("calibrated") == Plant.named("calibrated")
    plant = Plant(factors={"friction": 0.3, "preload": 0.25}, uncertainty={"friction": 0.02})
    (tmp_path / "lab.toml").write_text(calibrated_set_toml(plant, source="test"))
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "report.json").write_text(json.dumps({"plant": plant.to_dict()}))
    for source in ("lab.toml", tmp_path / "lab.toml", "rep", "rep/report.json"):
        back = Plant.load(source)
        assert back == plant and back.factors == plant.factors and back.source
    with pytest.raises(ValueError, match=r"'missing\.toml': no such file"):
        Plant.load("missing.toml")
    (tmp_path / "bad.toml").write_text("[plant\n")
    with pytest.raises(ValueError, match=r"bad\.toml"):
        Plant.load("bad.toml")
    (tmp_path / "thesis").mkdir()
    with pytest.raises(ValueError, match="both a parameter set and a path"):
        Plant.load("thesis")
    with pytest.raises(ValueError, match="plant=3"):
        Plant.load(3)


# --- the independent plant behind the plant layer (issue 32, item 5) -------------------------
def _sawtooth(periods=6, f=500.0, amplitude=3.0):
    """Breakpoints on the 62.5 ns grid: a ramp to ``amplitude`` [V input] over 0.9 of each
    period, then back to 0 V within one grid step."""
    g = 62.5e-9
    n_per = round(1.0 / f / g)
    t, u = [0.0], [0.0]
    for k in range(periods):
        top = k * n_per + round(0.9 * n_per)
        t += [top * g, (top + 1) * g, (k + 1) * n_per * g]
        u += [amplitude, 0.0, 0.0]
    return np.array(t), np.array(u)


def test_the_independent_fidelity_is_the_independent_plant_resumed():
    """``Plant(fidelity="independent")`` runs :mod:`turntable_env.testing.independent_plant`:
    resumed after two of six periods, the stepper's records equal the plant's own run from
    rest on the same samples (to 1e-12: the drive passes the stepper's 62.5 ns grid); a
    knock at rest moves the table and the contacts hold it there (within 1e-9 rad)."""
    from turntable_env.drive import Waveform
    from turntable_env.plant.independent import independent_params
    from turntable_env.testing.independent_plant import simulate

    plant = Plant("real", fidelity="independent")
    t, u = _sawtooth()
    odt, split = 1e-4, 0.004  # s; the split falls on a period's start
    st = PlantStepper([plant], noise=False)
    head, tail = t <= split + 1e-12, t >= split - 1e-12
    parts = [
        st.run_waveform([Waveform(t[head], u[head])], split, odt)[0],
        st.run_waveform([Waveform(t[tail] - split, u[tail])], 0.006 - split, odt)[0],
    ]
    g = st.grid
    n = np.unique(np.round(np.concatenate([t, np.arange(0, 0.006, odt)]) / g))
    ref, _x, _y = simulate(independent_params(plant.params), n * g, np.interp(n * g, t, u))
    for rec in parts:
        at = np.isin(n, np.round(rec.time / g))
        assert at.sum() == rec.time.size
        np.testing.assert_allclose(rec.angle, ref[at], rtol=1e-12, atol=1e-18)
    assert parts[1].angle[-1] > 1e-4  # it stepped (0.1 mrad in six periods)
    hold = [Waveform(np.array([0.0, 0.02]), np.zeros(2))]  # 0 V: amplifier and ring settle
    st.run_waveform(hold, 0.02, 1e-3)
    st.displace(0, 2e-3)
    knocked = st.angle[0]
    rest = st.run_waveform(hold, 0.02, 1e-3)[0]
    np.testing.assert_allclose(rest.angle, knocked, rtol=0, atol=1e-9)


def test_the_independent_plant_takes_the_plants_factors():
    """Friction, preload and amplifier factors scale the independent plant's own values."""
    from turntable_env.plant.independent import independent_params
    from turntable_env.testing.independent_plant import PlantParams

    p0 = PlantParams()
    p = independent_params(
        Plant("real", factors={"friction": 0.8, "preload": 1.25, "amplifier": 0.5}).params
    )
    assert p.static_friction_coefficient == pytest.approx(0.8 * p0.static_friction_coefficient)
    assert p.coulomb_friction_coefficient == pytest.approx(0.8 * p0.coulomb_friction_coefficient)
    assert p.normal_force_N == pytest.approx(1.25 * p0.normal_force_N)
    assert p.amplifier_current_limit_A == pytest.approx(0.5 * p0.amplifier_current_limit_A)
    assert p.tube_mass_kg == p0.tube_mass_kg  # not an uncertain value
