"""RL agents: training smoke tests, save/reload, the shipped agents, the SB3 vector env."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from conftest import smoke_hyperparams

import turntable_env  # noqa: F401
from agents import AgentController, AgentWrapper, InterfaceConfig, load_agent, pretrained
from agents.controller import interface_of
from agents.interface import AGENT_ENV_ID, RAW, RAW_ENV_ID
from agents.train import HYPERPARAMS_DIR, load_hyperparams, load_training, train
from agents.vec_env import NativeVecEnv, domain_kwargs, domain_sizes
from controllers import make
from controllers.base import ControllerContext
from controllers.lab import LabBrief
from turntable_env.envs.config import OBS

FIXED_OBS = np.random.default_rng(7).uniform(-2.0, 2.0, size=(16, 8)).astype(np.float32)


@pytest.mark.parametrize(
    ("algo", "env_id"), [("ppo", AGENT_ENV_ID), ("sac", AGENT_ENV_ID), ("sac", RAW_ENV_ID)]
)
def test_train_save_reload_gives_identical_actions(algo, env_id, tmp_path):
    hp, tr = smoke_hyperparams(algo, tmp_path, env_id)
    res = train(
        algo, env_id=env_id, timesteps=300, seed=1, out=tmp_path / "run",
        hyperparams=hp, training=tr, progress=False,
    )  # fmt: skip
    for name in ("model.zip", "vecnormalize.pkl", "config.yml", "learning_curve.png"):
        assert (res.run / name).stat().st_size > 0
    assert (res.run / "logs" / "progress.csv").is_file()
    assert (res.run / "eval" / "evaluations.npz").is_file()
    assert any((res.run / "checkpoints").iterdir())
    model, vecnorm, cfg = load_agent(res.run)
    assert cfg["run"]["seed"] == 1 and cfg["run"]["timesteps"] == 300
    assert cfg["run"]["env_id"] == env_id
    # the interface the run records is the one it was trained through
    assert model.action_space.shape == ((5,) if env_id == RAW_ENV_ID else (3,))
    assert (interface_of(cfg) == RAW) == (env_id == RAW_ENV_ID)
    obs_a = res.vecnormalize.normalize_obs(FIXED_OBS)
    obs_b = vecnorm.normalize_obs(FIXED_OBS)
    np.testing.assert_array_equal(obs_a, obs_b)
    act_a, _ = res.model.predict(obs_a, deterministic=True)
    act_b, _ = model.predict(obs_b, deterministic=True)
    np.testing.assert_array_equal(act_a, act_b)
    space = model.action_space
    assert all(space.contains(a.astype(np.float32)) for a in act_b)


def test_frame_stacked_agent_sees_what_sb3_stacked_in_training(tmp_path):
    """An agent trained with rl-zoo3's frame_stack acts in the benchmark on the last k
    normalised features as SB3's VecFrameStack stacked them in training (zeros before the
    episode's first), and its actions depend on the history, not only the last features.
    It identifies (``identify``): each interval's features carry the step gains learned
    from every interval before it, the reset observation's none."""
    from stable_baselines3.common.vec_env.stacked_observations import StackedObservations

    hp, tr = smoke_hyperparams("ppo", tmp_path)
    cfg = yaml.safe_load(hp.read_text())
    cfg[AGENT_ENV_ID]["frame_stack"] = 3
    cfg[AGENT_ENV_ID]["env_kwargs"]["interface"]["identify"] = True
    hp.write_text(yaml.safe_dump(cfg))
    res = train("ppo", timesteps=128, seed=2, out=tmp_path / "run", hyperparams=hp,
                training=tr, progress=False)  # fmt: skip
    assert res.model.observation_space.shape == (42,)
    env = gym.make("PiezoTurntable-v0", noise=True, move_range=(5e-5, 1e-4))
    ctl = AgentController(ControllerContext.from_env(env), res.run, shield=False)
    ref = StackedObservations(1, 3, ctl.interface.observation_space)
    ident = ctl.interface.identifier()  # the training env's per-turntable state
    obs, info = env.reset(seed=4)
    ctl.reset(obs, LabBrief(float(info["target_rad"])))
    ident.reset(obs)
    for t in range(6):
        if t:
            ident.update(obs)
        f = res.vecnormalize.normalize_obs(ctl.interface.features(obs, ident)[None, :])
        seen = ref.reset(f) if t == 0 else ref.update(f, np.array([False]), [{}])[0]
        want, _ = res.model.predict(seen, deterministic=True)
        got = ctl.policy_action(obs)
        np.testing.assert_array_equal(got, want[0])
        # the env is driven by 5 V steps towards the target (the untrained policy idles)
        err = obs[OBS.target_angle_rad] - obs[OBS.measured_angle_rad]
        drive = np.array([0.5 * np.sign(err), -1.0, 0.0])
        obs = env.step(ctl.interface.env_action(drive if t % 2 else got, obs))[0]
    assert ident.features().any()  # the episode's steps were measured
    fresh = AgentController(ControllerContext.from_env(env), res.run, shield=False)
    fresh.reset(obs, LabBrief(float(info["target_rad"])))
    assert not np.array_equal(fresh.policy_action(obs), ctl.policy_action(obs))


def test_shipped_agents_load_and_act():
    shipped = pretrained()
    assert {"ppo", "sac"} <= set(shipped)
    env = gym.make("PiezoTurntable-v0", randomize=True)
    for name, run in shipped.items():
        size = sum(f.stat().st_size for f in Path(run).rglob("*") if f.is_file())
        assert size < 5e6, f"{name}: {size} bytes"
        ctl = make(name, env)
        obs, info = env.reset(seed=0)
        with pytest.raises(ValueError, match="LabBrief"):  # ground truth is refused
            ctl.reset(obs, info)
        ctl.reset(obs, LabBrief(float(info["target_rad"])))
        for _ in range(3):
            action = ctl.act(obs)
            assert env.action_space.contains(action)
            obs, *_ = env.step(action)


@pytest.mark.parametrize(
    ("iface", "width"),
    [
        (InterfaceConfig(), 8),
        (InterfaceConfig(identify=True), 14),
        (InterfaceConfig(base="closed_loop"), 10),
        (InterfaceConfig(base="fuzzy", scale_max=1.5, action_cost=0.05), 10),
    ],
)
def test_native_vec_env_equals_the_wrapped_single_env(iface, width):
    """Same seed and actions: NativeVecEnv (N = 1) and AgentWrapper see the same features
    (with ``identify``, the step identifier's too, reset with the episode; a residual
    agent's, from its base controller, one per turntable, reset with the episode). The
    episode runs to its time limit (a base reaches the band before it)."""
    kwargs = {"noise": True, "randomize": True, "move_range": (1e-6, 1e-3),
              "terminate_on_success": False}  # fmt: skip
    venv = NativeVecEnv(1, max_episode_steps=5, interface=iface, **kwargs)
    venv.seed(3)
    single = AgentWrapper(gym.make("PiezoTurntable-v0", max_episode_steps=5, **kwargs), iface)
    f_vec = venv.reset()
    f_one, _ = single.reset(seed=3)
    np.testing.assert_array_equal(f_vec[0], f_one)
    rng = np.random.default_rng(0)
    assert f_vec.shape == (1, width)
    learned = False
    for _ in range(5):
        a = rng.uniform(-1, 1, size=single.action_space.shape).astype(np.float32)
        f_vec, r_vec, done, infos = venv.step(a[None, :])
        f_one, r_one, term, trunc, _ = single.step(a)
        if done[0]:  # finished: SB3 gets the last features as terminal_observation
            np.testing.assert_array_equal(infos[0]["terminal_observation"], f_one)
            assert term or trunc
        else:
            np.testing.assert_array_equal(f_vec[0], f_one)
            learned |= bool(np.any(f_one[8:] != 0.0))
        assert r_vec[0] == pytest.approx(r_one, rel=1e-6)
    assert done[0]  # the time limit of 5 steps ended the episode
    # the gains were learned within the episode and forgotten with it (a new turntable)
    assert learned == (width > 8)
    assert not np.any(f_vec[0, 8:])


CALIBRATED_DOMAIN = {"plant": "calibrated", "fidelity": "reduced", "randomize": True}


def test_training_domains_run_each_plant_as_its_own_env():
    """Two domains in one NativeVecEnv: each group's rows are the env of its own kwargs,
    seeded s + row (the same features, rewards and plant draws as that env alone), and the
    calibrated group's features use the calibrated plant's detector range and scan gain."""
    base = {"noise": True, "randomize": {"friction": (0.7, 1.3)}, "move_range": (1e-6, 1e-3)}
    domains = [{"share": 1}, {"share": 1, "env_kwargs": CALIBRATED_DOMAIN}]
    mixed = NativeVecEnv(4, 5, None, domains, **base)
    alone = [NativeVecEnv(2, 5, None, **base),
             NativeVecEnv(2, 5, None, **{**base, **CALIBRATED_DOMAIN})]  # fmt: skip
    mixed.seed(11)
    alone[0].seed(11)
    alone[1].seed(13)  # the second group's rows are 2 and 3
    f = mixed.reset()
    np.testing.assert_array_equal(f, np.concatenate([a.reset() for a in alone]))
    ctx = [i.ctx for i in mixed.interfaces]
    assert ctx[1].scan_gain > 1.5 * ctx[0].scan_gain  # the calibrated rig's symmetric drive
    assert ctx[1].angle_range != ctx[0].angle_range
    draws = mixed.venvs[1].task.draws
    assert set(draws[0]) == {"friction", "preload"}  # the posterior: the calibration's σ
    rng = np.random.default_rng(0)
    for k in range(6):
        a = rng.uniform(-1, 1, size=(4, 3)).astype(np.float32)
        f, r, done, _ = mixed.step(a)
        parts = [alone[0].step(a[:2]), alone[1].step(a[2:])]
        np.testing.assert_array_equal(f, np.concatenate([p[0] for p in parts]))
        np.testing.assert_array_equal(r, np.concatenate([p[1] for p in parts]))
        np.testing.assert_array_equal(done, np.concatenate([p[2] for p in parts]))
        assert done.all() == (k == 4)  # the 5-step limit ends every row, which is reset
    assert mixed.get_attr("num_envs") == [2, 2, 2, 2]


def test_env_plant_by_name_is_the_stored_plant_and_refuses_an_ambiguous_path(tmp_path,
                                                                           monkeypatch):
    """EnvConfig(plant="calibrated") is Plant.named("calibrated") whole (its posterior is
    what randomize=True draws from); a report directory of that name in the working
    directory makes the name ambiguous: a ValueError, not a silent choice."""
    from turntable_env.envs.config import EnvConfig
    from turntable_env.plant import Plant

    cfg = EnvConfig(plant="calibrated", fidelity="reduced", randomize=True)
    assert cfg.plant == Plant.named("calibrated").replace(fidelity="reduced")
    assert set(cfg.plant.uncertainty) == {"friction", "preload"}
    monkeypatch.chdir(tmp_path)
    (tmp_path / "calibrated").mkdir()
    with pytest.raises(ValueError, match=r"plant='calibrated': both a stored plant and a path"):
        EnvConfig(plant="calibrated")


@pytest.mark.parametrize(
    ("n", "shares", "sizes"),
    [(16, [1, 1], [8, 8]), (8, [0.5, 0.25, 0.25], [4, 2, 2]), (3, [0.9, 0.05, 0.05], [1, 1, 1]),
     (5, [1, 1], [3, 2]), (7, [3, 1], [5, 2])],
)  # fmt: skip
def test_domain_sizes_split_the_rows_by_share(n, shares, sizes):
    assert domain_sizes(n, shares) == sizes


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: domain_sizes(1, [1, 1]), "fewer rows"),
        (lambda: domain_kwargs({}, []), "at least one"),
        (lambda: domain_kwargs({}, "calibrated"), "list"),
        (lambda: domain_kwargs({}, [{"share": 0}]), r"domains\[0\].share=0"),
        (lambda: domain_kwargs({}, [{"share": 1}, {"weight": 1}]), r"domains\[1\]"),
        (lambda: domain_kwargs({}, [{"env_kwargs": "x"}]), "env_kwargs='x'"),
        (lambda: NativeVecEnv(2, 5, None, [{"env_kwargs": {"plant": "nope"}}]), "nope"),
    ],
)
def test_training_domain_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_a_bad_training_domain_is_refused_naming_the_file(tmp_path):
    t = tmp_path / "bad_training.yml"
    t.write_text(yaml.safe_dump({"ppo": {"domains": [{"share": -1}]}}))
    with pytest.raises(ValueError, match=r"bad_training.yml: 'ppo': domains\[0\].share=-1"):
        load_training("ppo", t)
    hp, tr = smoke_hyperparams("ppo", tmp_path)
    cfg = yaml.safe_load(hp.read_text())
    cfg[AGENT_ENV_ID]["frame_stack"] = 0
    hp.write_text(yaml.safe_dump(cfg))
    for hyper, training in ((hp, tr), (None, t)):
        with pytest.raises(ValueError, match=r"frame_stack=0|share=-1"):
            train("ppo", timesteps=10, out=tmp_path / "run", hyperparams=hyper,
                  training=training, progress=False)  # fmt: skip
    assert not (tmp_path / "run").exists()  # refused before the run directory is made


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_training_domains_file_adds_the_calibrated_posterior(algo):
    """training_domains.yml: half the rows on the calibrated plant's posterior; training.yml
    (the shipped agents' settings) keeps one domain, so it reproduces them."""
    assert load_training(algo)["domains"] is None
    domains = load_training(algo, HYPERPARAMS_DIR / "training_domains.yml")["domains"]
    groups = domain_kwargs(load_hyperparams(algo)["env_kwargs"], domains)
    assert [share for share, _ in groups] == [0.5, 0.5]
    assert groups[0][1]["params"] == "real" and "plant" not in groups[0][1]
    assert {k: groups[1][1][k] for k in CALIBRATED_DOMAIN} == CALIBRATED_DOMAIN
    assert "params" not in groups[1][1]


@pytest.mark.parametrize(("a1", "steps"), [(-1.0, 1), (1.0, 20), (0.0, 11)])
def test_agent_action_sets_whole_steps_per_interval(a1, steps):
    env = AgentWrapper(gym.make("PiezoTurntable-v0", noise=False))
    env.reset(seed=0, options={"start_angle": 0.0, "target_angle": 0.0})
    info = env.step(np.array([0.8, a1, 0.0], dtype=np.float32))[4]
    assert info["steps"] == steps


def test_agent_deadzone_idles_and_offset_accumulates():
    # the per-axis form, whose scan is linear to the 10 V limit (K·u, every contact stuck);
    # the translation form's reads 5 % less at 10 V
    env = AgentWrapper(gym.make("PiezoTurntable-v0", noise=False, fidelity="reduced"))
    env.reset(seed=0, options={"start_angle": 0.0, "target_angle": 0.0})
    k = env.interface.ctx.scan_gain
    for n in range(1, 4):
        info = env.step(np.array([0.1, 0.0, 0.5], dtype=np.float32))[4]
        assert info["steps"] == 0
        assert info["angle_rad"] == pytest.approx(n * 1.0 * k, rel=0.01)  # +1 V per step
    for _ in range(10):  # the offset saturates at the amplifier's 10 V input limit
        info = env.step(np.array([0.0, 0.0, 1.0], dtype=np.float32))[4]
    assert info["angle_rad"] == pytest.approx(10.0 * k, rel=0.01)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: load_hyperparams("dqn"), "algo"),
        (lambda: load_hyperparams("ppo", "/nonexistent.yml"), "does not exist"),
        (lambda: InterfaceConfig(deadzone=1.0), "deadzone"),
        (lambda: InterfaceConfig(max_steps=0), "max_steps"),
        (lambda: InterfaceConfig(base="scan_pid"), "base='scan_pid'"),
        (lambda: InterfaceConfig(base="closed_loop", identify=True), "identify"),
        (lambda: InterfaceConfig(base="closed_loop", scale_max=1.0), "scale_max=1.0"),
        (lambda: InterfaceConfig(base="closed_loop", scale_max=float("nan")), "scale_max=nan"),
        (lambda: InterfaceConfig(action_cost=0.1), "action_cost=0.1: only a residual"),
        (lambda: InterfaceConfig(base="fuzzy", action_cost=-0.1), "action_cost=-0.1"),
        (lambda: InterfaceConfig(base="fuzzy", action_cost=float("inf")), "action_cost=inf"),
        (lambda: load_agent("/nonexistent"), "model.zip missing"),
    ],
)
def test_agent_configuration_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.fixture(scope="module")
def nominal_ctx():
    from turntable_env.envs.config import EnvConfig

    return ControllerContext.from_config(EnvConfig())


def _obs(ctx, angle, amplitude=0.0, frequency=100.0, offset=0.0):
    """An env observation: reading ``angle`` [rad] after an interval of this setting."""
    o = np.zeros(8, dtype=np.float32)
    o[OBS.measured_angle_rad] = angle
    o[OBS.last_amplitude :] = ctx.scaling.encode(amplitude, frequency, 0.9, 1.0, offset)
    return o


@pytest.mark.parametrize("gain", [0.4, 1.0, 3.0])
@pytest.mark.parametrize("direction", [1, -1])
def test_step_identifier_measures_how_far_the_plant_steps_against_the_map(
    nominal_ctx, gain, direction
):
    """ρ = (Δθ − K·Δu)/(m·s_map): a plant stepping ``gain`` × the map, with the scan offset
    moved in the same interval, gives log₁₀ gain in its direction's features (the other
    direction stays at the map's 0); a saturated reading, the interval after it and an idle
    generator teach nothing; a reset forgets."""
    from agents.identification import StepIdentifier
    from controllers.step_map import StepMap

    ctx, smap = nominal_ctx, StepMap.load()
    ident = StepIdentifier(ctx, 0.9, 1.0, smap)
    amp, freq = 5.0 * direction, 300.0  # m = 3 periods per 10 ms interval
    # between the map's 200 and 500 Hz: linear in ln f; on its grid, the map itself
    s = ident.nominal_step(amp, freq)
    lo, hi = (smap.step_size("B", amp, f, 0.9, 1.0) for f in (200.0, 500.0))
    w = np.log(300.0 / 200.0) / np.log(500.0 / 200.0)
    assert s == pytest.approx(lo + w * (hi - lo), rel=1e-12)
    assert ident.nominal_step(amp, 500.0) == pytest.approx(hi, rel=1e-12)
    theta0, u0, u1 = 1e-4, 1.0, -2.0
    ident.reset(_obs(ctx, theta0, offset=u0))
    theta1 = theta0 + gain * 3 * s + ctx.scan_gain * (u1 - u0)
    ident.update(_obs(ctx, theta1, amp, freq, u1))
    f = ident.features()
    own, other = (f[:3], f[3:]) if direction > 0 else (f[3:], f[:3])
    np.testing.assert_allclose(own, np.log10(gain), atol=2e-6)
    assert not other.any()
    before = f.copy()
    edge = ctx.detector.angle_range  # the Eq. 4.1 reading at the detector's edge
    ident.update(_obs(ctx, edge, amp, freq, u1))  # saturated
    ident.update(_obs(ctx, theta1, amp, freq, u1))  # after a saturated reading
    ident.update(_obs(ctx, theta1 + 1e-5, 0.0, freq, u1))  # generator idle: a scan interval
    np.testing.assert_array_equal(ident.features(), before)
    ident.reset(_obs(ctx, theta0))
    assert not ident.features().any()


def test_step_identifier_tells_the_calibrated_plant_from_the_nominal_one():
    """On the thesis calibration's plant the same 5 V, 100 Hz steps measure a gain at
    least 1.24× the nominal plant's (the survey's smallest ratio from 2 V up,
    experiments/step_gain_survey.py), while the nominal plant steps near its own map."""
    domains = [{"share": 1}, {"share": 1, "env_kwargs": CALIBRATED_DOMAIN | {"randomize": False}}]
    venv = NativeVecEnv(4, 10, InterfaceConfig(identify=True), domains, noise=True,
                        move_range=(5e-5, 1e-4))  # fmt: skip
    venv.seed(0)
    f = venv.reset()
    for _ in range(4):
        a = np.zeros((4, 3), np.float32)
        a[:, 0] = 0.5 * np.sign(f[:, 0])  # 5 V towards the target, one period per interval
        a[:, 1] = -1.0
        f = venv.step(a)[0]
    gains = 10.0 ** f[:, 8:]
    learned = gains != 1.0
    assert learned.any(axis=1).all()  # every turntable measured its gain in a direction
    nominal, calibrated = gains[:2][learned[:2]], gains[2:][learned[2:]]
    assert 0.5 < nominal.min() and nominal.max() < 1.1
    assert calibrated.min() > 1.24 * nominal.max()


def test_a_trained_agent_continues_where_its_run_ended(tmp_path):
    """rl-zoo3's --trained-agent: the run's model and VecNormalize statistics learn on, the
    step count continues, and the new run records what it continued; a run of another
    algorithm or a directory without the agent is refused, naming it."""
    hp, tr = smoke_hyperparams("ppo", tmp_path)
    first = train("ppo", timesteps=128, seed=0, out=tmp_path / "a", hyperparams=hp,
                  training=tr, progress=False)  # fmt: skip
    count = first.vecnormalize.obs_rms.count
    res = train("ppo", timesteps=128, seed=1, out=tmp_path / "b", hyperparams=hp,
                training=tr, progress=False, trained_agent=first.run)  # fmt: skip
    assert res.model.num_timesteps == 2 * 128
    # the statistics go on: 128 steps more and the new env's reset of its 2 rows
    assert res.vecnormalize.obs_rms.count == pytest.approx(count + 128 + 2)
    cfg = load_agent(res.run)[2]["run"]
    assert cfg["total_timesteps"] == 256 and cfg["trained_agent"] == str(first.run)
    # the learning went on from the run's weights, not from a new network
    w0, w1 = (dict(m.policy.named_parameters()) for m in (first.model, res.model))
    assert all(w0[k].shape == w1[k].shape for k in w0)
    assert any(not np.array_equal(w0[k].detach(), w1[k].detach()) for k in w0)
    with pytest.raises(ValueError, match=r"trained_agent=.*model.zip missing"):
        train("ppo", timesteps=8, out=tmp_path / "c", hyperparams=hp, training=tr,
              progress=False, trained_agent=tmp_path / "none")  # fmt: skip
    hs, ts = smoke_hyperparams("sac", tmp_path)
    with pytest.raises(ValueError, match=r"a ppo run on PiezoTurntableAgent-v0, not sac"):
        train("sac", timesteps=8, out=tmp_path / "d", hyperparams=hs, training=ts,
              progress=False, trained_agent=first.run)  # fmt: skip
