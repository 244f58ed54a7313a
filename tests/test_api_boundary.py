"""The Python API's boundary (stop 73, from a hostile-input audit of the env and the
library): bad input is a ValueError naming the field before any work, a valid input near
its edge gives a finite result, and no written file can carry injected keys."""

from __future__ import annotations

import math
import re
import tomllib
import tracemalloc

import gymnasium as gym
import numpy as np
import pytest

import turntable_env  # noqa: F401  (registers the envs)
from controllers import LabBrief, make
from controllers.blind import BlindSettings
from controllers.closed_loop import ClosedLoopStepController
from controllers.fuzzy import FuzzyStepController
from controllers.registry import register
from controllers.shield import BlindShield
from turntable_env.amplifier import Amplifier
from turntable_env.calibration.virtual_lab import PROTOCOLS, check_protocol, protocol_drive
from turntable_env.drive import DriveSignal, Waveform
from turntable_env.envs.config import ActionScaling
from turntable_env.params import get_parameter_set
from turntable_env.plant import Plant, calibrated_set_toml
from turntable_env.plant.store import plant_toml
from turntable_env.simulation import MAX_STEPS, simulate, simulate_axes

NAN = float("nan")


@pytest.fixture(scope="module")
def env():
    e = gym.make("PiezoTurntable-v0")
    obs, _ = e.reset(seed=0)
    return e, obs


@pytest.mark.parametrize("k", [1e-300, 1e-17, 1e-16, 1e-9])
def test_a_tiny_slew_adaptation_holds_long_but_finite(k):
    """Eq. of Fig. 4.3's adapted hold: the error left at the end value is G·|Δu|·k, so the
    hold time τ·ln((1 + k)/k) grows without bound as k → 0 but is finite for any k > 0
    (it was 0/0 below k ≈ 1e-16: a ZeroDivisionError on a valid action)."""
    amp = Amplifier()
    for c_load in (0.0, 1e-8):  # the first-order stage alone, and under the current limit
        t_k = amp.adapted_hold_time(1.0, 0.0, k, c_load)
        t_more = amp.adapted_hold_time(1.0, 0.0, 10.0 * k, c_load)
        assert math.isfinite(t_k) and t_k > t_more > 0.0
        if c_load == 0.0:  # unloaded: the first-order stage's law exactly
            assert t_k == pytest.approx(amp.tau * math.log1p(1.0 / k), rel=1e-12)


def test_the_env_steps_with_a_tiny_slew_adaptation(env):
    e, _ = env
    for k in (1e-17, 1e-16):
        obs, reward, *_ = e.step(np.array([1.0, 0.0, 0.0, k, 0.0], dtype=np.float32))
        assert np.isfinite(obs).all() and math.isfinite(reward)


@pytest.mark.parametrize("name", ["feedforward", "fuzzy", "closed_loop", "scan_pid"])
@pytest.mark.parametrize(
    "bad", [np.full(8, NAN), np.full(8, np.inf), np.zeros(3), np.array(["a"] * 8), None]
)
def test_a_controller_refuses_an_observation_that_is_not_a_finite_reading(env, name, bad):
    e, obs = env
    c = make(name, e)
    c.reset(obs, LabBrief(2e-4))
    with pytest.raises(ValueError, match="obs: shape"):
        c.act(bad)
    with pytest.raises(ValueError, match="obs: shape"):
        c.reset(bad, LabBrief(2e-4))
    assert np.isfinite(c.act(obs)).all()


@pytest.mark.parametrize(
    "call",
    [
        lambda s: s.decode(np.full(5, NAN)),
        lambda s: s.decode(np.zeros(4)),
        lambda s: s.decode_batch(np.full((2, 5), NAN)),
        lambda s: s.decode_batch(np.zeros(5)),
        lambda s: s.encode(NAN, 100.0, 0.9),
        lambda s: s.encode(1.0, 100.0, NAN),
        lambda s: s.encode(1.0, 0.0, 0.9),
        lambda s: s.encode("1", 100.0, 0.9),
    ],
)
def test_action_scaling_refuses_what_is_not_a_finite_setting(call):
    with pytest.raises(ValueError):
        call(ActionScaling())


@pytest.mark.parametrize("limit", [NAN, -1.0, 0.0, math.inf])
def test_action_scaling_needs_a_positive_input_limit(limit):
    with pytest.raises(ValueError, match="input_limit"):
        ActionScaling(input_limit=limit)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"tolerance": 5e-324}, "tolerance"),
        ({"tolerance": 1e-13}, "tolerance"),
        ({"tolerance": 1.0}, "tolerance"),  # beyond the detector's range: done at once
        ({"angle_limit": 1e-9}, "angle_limit"),  # the reset's starts lie beyond it
    ],
)
def test_env_options_that_make_every_episode_end_at_once_are_refused(kwargs, field):
    with pytest.raises(ValueError, match=field):
        gym.make("PiezoTurntable-v0", **kwargs)


def test_the_log_reward_is_finite_at_the_smallest_tolerance():
    e = gym.make("PiezoTurntable-v0", reward="log", tolerance=1e-12)
    e.reset(seed=0, options={"start_angle": -4e-4, "target_angle": 5e-4})
    _, reward, *_ = e.step(np.array([1.0, 1.0, 0.0, 0.0, 0.0], dtype=np.float32))
    assert math.isfinite(reward)


def test_a_numpy_integer_seed_is_a_seed(env):
    e, _ = env
    a, _ = e.reset(seed=np.int64(3))
    b, _ = e.reset(seed=3)
    assert np.array_equal(a, b)


@pytest.mark.parametrize(
    ("source", "name"),
    [
        ("x\n[plant.effects.piezo_creep]\ngamma = 0.05 #", "calibrated"),
        ("src", "x\nbogus = 1"),
        ("src", 5),
        ("", "calibrated"),
    ],
)
def test_a_plant_file_cannot_carry_injected_lines(source, name):
    with pytest.raises(ValueError, match="one line of printable text"):
        calibrated_set_toml(Plant("calibrated"), source, name)


def test_a_plant_file_round_trips_and_refuses_a_value_that_is_not_finite():
    text = calibrated_set_toml(Plant("calibrated"), "a test")
    assert tomllib.loads(text)["set"] == {"name": "calibrated", "source": "a test"}
    with pytest.raises(ValueError, match=r"plant\.sensor_noise=nan"):
        plant_toml({"base": "real", "sensor_noise": NAN}, "s")


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"dt": 1e-15}, "dt"), ({"dt_factor": 1e-12}, "dt_factor")],
)
def test_a_3d_run_of_more_than_max_steps_is_refused_before_it_starts(kwargs, field):
    d = DriveSignal(frequency=1000.0, n_periods=1)
    with pytest.raises(ValueError, match=f"{field}=.*more than {re.escape(f'{MAX_STEPS:g}')}"):
        simulate("real", d, 1e-3, **kwargs)


@pytest.mark.parametrize(
    ("protocol", "sample_dt", "needle"),
    [
        ("bogus", 5e-5, "choose from"),
        (5, 5e-5, "a name or a non-empty list"),
        ([], 5e-5, "a name or a non-empty list"),
        ([("hold", 1e6)], 5e-5, r"protocol\[0\] seconds"),
        ([("hold", -1.0)], 5e-5, r"protocol\[0\] seconds"),
        ([("hold", "x")], 5e-5, "must be a number"),
        ([("hold",)], 5e-5, r"protocol\[0\]="),
        ([("steps", 1.0, 100.0, 10**9, 0.95, 0.0)], 5e-5, "periods"),
        ([("steps", 11.0, 100.0, 3, 0.95, 0.0)], 5e-5, "amplitude"),
        ([("steps", 1.0, 100.0, 3, 1.5, 0.0)], 5e-5, r"protocol\[0\] a="),
        ([("hold", 1.0)], 0.0, "sample_dt"),
        ([("hold", 1.0)], NAN, "sample_dt"),
        ([("hold", 50.0), ("hold", 60.0)], 5e-5, r"more than 100 s"),
        ([("hold", 90.0)], 1e-5, "more than a measurement file holds"),
    ],
)
def test_a_virtual_lab_protocol_is_checked_before_anything_is_allocated(
    protocol, sample_dt, needle
):
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=needle):
            protocol_drive(protocol, get_parameter_set("real"), "B", sample_dt)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 * 2**20


@pytest.mark.parametrize("name", sorted(PROTOCOLS))
def test_the_shipped_protocols_pass_their_own_check(name):
    assert check_protocol(name) == PROTOCOLS[name]


def test_a_plant_no_pid_can_hold_is_named_not_a_runtime_error():
    """The thesis's scaled set carries a 6 Hz mode at |z| = 0.996 on the 10 ms interval:
    no PID meets the scan loop's margins, and the controllers say so."""
    from controllers.scan_pid import design_scan_pid
    from turntable_env.linear import scan_plant, stick_plant

    plant = scan_plant(stick_plant(get_parameter_set("thesis"), "B"), 0.01)[0, 0]
    with pytest.raises(ValueError, match=r"no PID meets .* 6\.03 Hz"):
        design_scan_pid(plant, starts=[(0.5, 0.1, 0.0)])  # one start; the default grid alike


@pytest.mark.parametrize(
    "factors",
    [{"tube_damping": 0.0}, {"friction": -1.0}, {"preload": NAN}, {"stribeck_velocity": "x"},
     {"friction": True}, None, ["friction"]],
)  # fmt: skip
def test_with_factors_refuses_what_is_not_a_positive_factor(factors):
    with pytest.raises(ValueError, match="factors"):
        get_parameter_set("real").with_factors(factors)


@pytest.mark.parametrize("angle", [10**400, "0.01", True, NAN])
def test_a_reset_angle_that_is_not_a_float_is_refused(env, angle):
    e, _ = env
    with pytest.raises(ValueError, match="start_angle"):
        e.reset(seed=0, options={"start_angle": angle})


@pytest.mark.parametrize(
    ("args", "kwargs", "needle"),
    [
        ("x.csv", {}, "files="),  # a string is not a list of files
        ([], {}, "files="),
        ([5], {}, r"files\[0\]"),
        (["x.csv"], {"starts": True}, "starts="),
        (["x.csv"], {"global_points": 10**12}, "global_points="),
        (["x.csv"], {"min_improvement": "x"}, "min_improvement="),
        (["x.csv"], {"workers": "2"}, "workers="),
        (["x.csv"], {"candidates": "piezo_creep"}, "candidates"),
    ],
)
def test_calibrate_refuses_its_arguments_before_reading_a_file(args, kwargs, needle):
    from turntable_env.calibration.calibrate import calibrate

    with pytest.raises(ValueError, match=needle):
        calibrate(args, progress=None, **kwargs)  # x.csv does not exist: never read


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda st: st.advance(np.array([[1.0, 0.0, 0.95, 0.0, 0.0]]), 0.01), "settings"),
        (lambda st: st.advance(np.array([[1.0, 1e12, 0.95, 0.0, 0.0]]), 0.01), "settings"),
        (lambda st: st.advance(np.array([[1.0, 100.0, 1.5, 0.0, 0.0]]), 0.01), "settings"),
        (lambda st: st.advance(np.full((1, 5), NAN), 0.01), "settings"),
        (lambda st: st.advance(np.zeros(5), 0.01), "shape"),
        (lambda st: st.advance(np.array([[1.0, 100.0, 0.9, 0.0, 0.0]]), -1.0), "interval"),
        (lambda st: st.advance(np.array([[1.0, 100.0, 0.9, 0.0, 0.0]]), NAN), "interval"),
        (lambda st: st.reset(5, 0.0), "b="),
        (lambda st: st.reset(1.5, 0.0), "b="),
        (lambda st: st.reset(0, NAN), "angle"),
        (lambda st: st.reset(0, 0.0, time=-1.0), "time"),
        (lambda st: st.set_plant(3, Plant()), "b="),
        (lambda st: st.set_plant(0, 5), "plant="),
        (lambda st: st.run_waveform([5], 0.01, 1e-3), r"waves\[0\]"),
        (lambda st: st.run_waveform([], 0.01, 1e-3), "waves"),
        (lambda st: st.observe_trace(0, np.array([NAN]), np.array([0.0])), "t, theta"),
        (lambda st: st.observe_trace(0, np.zeros(3), np.zeros(2)), "t, theta"),
    ],
)
def test_the_stepper_refuses_bad_calls_before_it_integrates(call, needle):
    from turntable_env.plant import PlantStepper

    st = PlantStepper([Plant()])
    st.reset(0)
    with pytest.raises(ValueError, match=needle):
        call(st)


@pytest.mark.parametrize("plants", [[5], ["real"], [], Plant()])
def test_the_stepper_takes_a_list_of_plants(plants):
    from turntable_env.plant import PlantStepper

    with pytest.raises(ValueError, match="plants"):
        PlantStepper(plants)


@pytest.mark.parametrize(
    ("make_it", "needle"),
    [
        (lambda: DriveSignal(n_periods=10**9), "n_periods"),
        (lambda: DriveSignal(n_periods=10**6, pattern="two", n_cycles=100), "periods, more than"),
        (lambda: DriveSignal(start=-1.0), "start"),
        (lambda: Waveform(np.zeros((2, 2)), np.zeros((2, 2))), "1-D"),
    ],
)
def test_a_drive_too_long_to_hold_or_of_the_wrong_shape_is_refused(make_it, needle):
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=needle):
            make_it()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 * 2**20


@pytest.mark.parametrize(
    ("make_it", "needle"),
    [
        (lambda: LabBrief(0.0, reference_rad=[1j]), "reference_rad"),
        (lambda: LabBrief(0.0, reference_rad="abc"), "reference_rad"),
        (lambda: LabBrief(NAN), "target_rad"),
        (lambda: LabBrief(0.0, reference_rad=[0.0, 1e-4]).reference_at("x"), "k="),
    ],
)
def test_a_lab_brief_refuses_what_is_not_an_angle(make_it, needle):
    with pytest.raises(ValueError, match=needle):
        make_it()


def _ctx():
    from controllers.base import ControllerContext
    from turntable_env.envs.config import EnvConfig

    return ControllerContext.from_config(EnvConfig())


# --- stop 74: the audit's rest (wrong types, deep TOML, an amplitude beyond the input) ----
@pytest.mark.parametrize(
    "call, needle",
    [
        (lambda: Plant.named(5), "plant 5"),
        (lambda: Plant.named([1]), "plant [1]"),
        (lambda: Plant.from_report(5), "report=5"),
        (lambda: Plant.from_report(None), "report=None"),
        (lambda: Plant.from_toml(b"x.toml"), "plant file=b'x.toml'"),
        (lambda: BlindSettings(5), "worst=5"),
        (lambda: BlindSettings({(100.0, 2.0): "x"}), "worst[(100.0, 2.0)]"),
        (lambda: BlindSettings({(0.0, 2.0): -0.1}), "frequency"),
        (lambda: BlindSettings({100.0: -0.1}), "worst[100.0]"),
        (lambda: BlindShield(5), "ctx=int"),
        (lambda: ClosedLoopStepController(_ctx(), blind_settings=5), "blind_settings=int"),
        (lambda: FuzzyStepController(_ctx(), blind_settings="x"), "blind_settings=str"),
        (lambda: register("xx_not_kept", 5, "d"), "factory=5"),
        (lambda: register("xx_not_kept", lambda c: None, 5), "description=5"),
    ],
)
def test_a_wrong_type_at_a_public_call_is_a_value_error_naming_it(call, needle):
    with pytest.raises(ValueError, match=re.escape(needle)):
        call()


def test_a_plant_file_nested_beyond_the_parser_is_named(tmp_path):
    """TOML's parser recurses per nested array; 5000 levels overflowed the stack."""
    p = tmp_path / "deep.toml"
    p.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(ValueError, match=re.escape(f"{p}: nested too deep")):
        Plant.from_toml(p)


@pytest.mark.parametrize("amplitude", [10.5, -50.0])
def test_a_drive_beyond_the_amplifier_input_is_refused_before_the_run(amplitude):
    """§4.1.1: the HVA 900 takes ±10 V; a larger sawtooth would be clipped into another
    waveform than the one commanded."""
    drive = DriveSignal(amplitude=amplitude, n_periods=1)
    with pytest.raises(ValueError, match=r"amplitude=.*±10 V input"):
        simulate("real", drive)
    with pytest.raises(ValueError, match=r"amplitude=.*±10 V input"):
        simulate_axes(["real"], [drive])


def test_a_3d_response_records_the_plant_as_it_ran():
    """simulate() runs the 3-D model whatever the plant's fidelity; its record said
    fidelity='reduced' for the default plant (a new user's report, stop 74)."""
    r = simulate(Plant(factors={"friction": 1.1}), DriveSignal(n_periods=1), axis="B")
    assert "fidelity='full'" in r.info["plant"] and "'friction': 1.1" in r.info["plant"]
