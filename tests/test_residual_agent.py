"""The residual agent (agents/residual.py): a base controller plans, the agent scales its aim.

Contracts: at a = 0 the agent is its base controller, action for action; the scale moves
the base's plan monotonically; training and benchmark run the same chain (the base reset
with the lab's brief in the benchmark, no shield over the base's own safety monitor)."""

import copy

import gymnasium as gym
import numpy as np
import pytest
from conftest import smoke_hyperparams

from agents import AgentController, AgentWrapper, InterfaceConfig
from agents.residual import BASES
from agents.train import HYPERPARAMS_DIR, train
from controllers import make
from controllers.base import ControllerContext
from controllers.lab import LabBrief
from turntable_env.envs.config import OBS


def _target(env, obs):
    return float(ControllerContext.from_env(env).lab_observation(obs)[OBS.target_angle_rad])


@pytest.mark.parametrize("base", sorted(BASES))
@pytest.mark.parametrize(
    "plant", [{"params": "real"}, {"plant": "calibrated", "fidelity": "reduced"}]
)
def test_a_residual_agent_at_zero_is_its_base_controller(base, plant, seed=4):
    """a = 0 (s = 1): the env actions, rewards and readings equal the base controller's own
    on a twin env, every interval, from a start the detector may not see (moves of 0.2–3
    mrad, beyond its ±0.57 mrad; these seeds draw 1.8 and 1.0 mrad)."""
    kw = {**plant, "noise": True, "randomize": True, "move_range": (2e-4, 3e-3),
          "max_episode_steps": 40, "terminate_on_success": False}  # fmt: skip
    agent = AgentWrapper(gym.make("PiezoTurntable-v0", **kw), InterfaceConfig(base=base))
    twin = gym.make("PiezoTurntable-v0", **kw)
    agent.reset(seed=seed)
    obs, _ = twin.reset(seed=seed)
    ctl = make(base, twin)
    ctl.reset(obs, LabBrief(_target(twin, obs)))
    moved = 0
    for _ in range(40):
        want = ctl.act(obs)
        _, r_agent, *_, info_agent = agent.step(np.zeros(1, np.float32))
        obs, r_twin, *_, info_twin = twin.step(want)
        assert r_agent == r_twin
        assert info_agent["angle_rad"] == info_twin["angle_rad"]
        moved += info_twin["steps"] > 0
    assert moved >= 2  # the base stepped: the case is not idle


@pytest.mark.parametrize(
    ("base", "target"),
    [(b, t) for b in ("closed_loop", "feedforward") for t in (2e-4, 4e-4)] + [("fuzzy", 4e-4)],
)
def test_the_scale_moves_the_base_plan_monotonically(base, target):
    """From one state, the base's planned move grows with s = 2^a: s = 1/2 plans a
    shorter move than the base's own, s = 2 a longer one. The fuzzy base counts whole
    steps (its rules see s·e) and takes at least one, so its move grows, not strictly:
    0.4 mrad is 1 step at s ≤ 1, 3 at s = 2, its cap at the unmeasured gain's bound."""
    env = gym.make("PiezoTurntable-v0", noise=False)
    iface = AgentWrapper(env, InterfaceConfig(base=base)).interface
    obs, _ = env.reset(seed=0, options={"start_angle": 0.0, "target_angle": target})
    ctl = iface.row_state()
    iface.observe(obs, ctl, first=True)
    # past the base's quiet intervals and dithers before its first step (a target beyond
    # ControllerContext.dither_from reads the reading's noise and the detector's slope at
    # the start, controllers/detector_linearity.py): to that step
    from controllers.base import NOISE_MIN, PROBES

    for _ in range(NOISE_MIN + 1 + 2 * PROBES + 2):
        trial = copy.deepcopy(ctl)
        action = iface.env_action(np.zeros(1, np.float32), obs, trial)
        if trial.last_move is not None:
            break
        ctl = trial
        obs, *_ = env.step(action)
        iface.observe(obs, ctl)
    moves = []
    for a in (-1.0, 0.0, 1.0):
        c = copy.deepcopy(ctl)
        iface.env_action(np.array([a], np.float32), obs, c)
        assert c.remaining_scale == pytest.approx(2.0**a)
        moves.append(c.last_move.expected)
    assert 0.0 < moves[0] <= moves[1] <= moves[2]
    assert moves[0] < moves[2]
    if base != "fuzzy":
        assert moves[0] < moves[1] < moves[2]


@pytest.mark.parametrize("cost", [0.05, 0.5])
def test_the_action_cost_is_the_reward_term_lambda_a_squared(cost):
    """With ``action_cost`` λ the reward is the env's less λ·a² (a clipped to [−1, 1]),
    ``reward_action`` = −λ·a² in info; the plant, the base and the features are the
    cost-free agent's, interval for interval."""
    kw = {"noise": True, "randomize": True, "move_range": (2e-4, 3e-3), "max_episode_steps": 12,
          "terminate_on_success": False}  # fmt: skip
    envs = [AgentWrapper(gym.make("PiezoTurntable-v0", **kw),
                         InterfaceConfig(base="fuzzy", scale_max=1.5, action_cost=c))
            for c in (0.0, cost)]  # fmt: skip
    first = [e.reset(seed=5)[0] for e in envs]
    np.testing.assert_array_equal(*first)
    actions = np.linspace(-1.4, 1.4, 12)  # beyond the bounds too: a is clipped
    for a in actions:
        (f0, r0, *_, i0), (f1, r1, *_, i1) = (e.step(np.array([a], np.float32)) for e in envs)
        np.testing.assert_array_equal(f0, f1)
        assert i0["angle_rad"] == i1["angle_rad"]
        a_c = float(np.clip(np.float32(a), -1.0, 1.0))
        assert i0["reward_action"] == 0.0
        assert i1["reward_action"] == pytest.approx(-cost * a_c**2, rel=1e-12)
        assert r1 == pytest.approx(r0 - cost * a_c**2, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize(
    ("action", "match"), [(np.zeros(3), r"expected \(1,\)"), (np.array([np.nan]), "finite")]
)
def test_a_residual_action_is_one_finite_number(action, match):
    env = AgentWrapper(gym.make("PiezoTurntable-v0"), InterfaceConfig(base="closed_loop"))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_the_benchmark_runs_a_residual_agent_as_it_was_trained(tmp_path):
    """A residual run behind the controller interface: no shield over the base's own
    monitor; each action is the base, reset with the lab's brief, aimed by the policy's
    scale, as the training env computes it."""
    hp, tr = smoke_hyperparams("ppo", tmp_path, source=HYPERPARAMS_DIR / "ppo_residual.yml")
    res = train("ppo", timesteps=128, seed=0, out=tmp_path / "run", hyperparams=hp,
                training=tr, progress=False)  # fmt: skip
    assert res.model.action_space.shape == (1,)
    env = gym.make("PiezoTurntable-v0", noise=True, move_range=(1e-3, 2e-3))
    ctl = AgentController(ControllerContext.from_env(env), res.run)
    assert ctl.shield is None
    obs, info = env.reset(seed=2)
    # a start beyond the detector, with the lab's dead-reckoned estimate of it
    start = float(info["angle_rad"]) * 1.05  # the lab's dead reckoning, 5 % off
    brief = LabBrief(_target(env, obs), start_estimate_rad=start, start_error=0.1)
    ctl.reset(obs, brief)
    base = ctl.interface.row_state()
    base.reset(obs, brief)
    scales = set()
    for _ in range(8):
        a = ctl.policy_action(obs)
        base.remaining_scale = ctl.interface.scale(a)
        scales.add(round(base.remaining_scale, 6))
        want = base.act(obs)
        got = ctl.act(obs)
        np.testing.assert_array_equal(got, want)
        obs = env.step(got)[0]
    assert scales != {1.0}  # the policy's scale, not the base alone



@pytest.mark.parametrize("base", sorted(BASES))
def test_a_residual_agents_base_steps_blind_with_the_blind_set_it_is_given(base):
    """make_interface(..., blind_settings=) hands the blind set to the residual agent's base
    controller (AgentController passes its own there, as the shield's for other agents):
    with the first blind set (controllers/data/blind_settings.csv) its blind moves go up to
    6.5 V (at 1 kHz), with the asymmetry-robust set (controllers/data/blind_asymmetry.csv),
    which is also the default, up to 4.5 V (at 2 kHz, a = 0.6); anything but a
    BlindSettings is refused by name."""
    from agents.interface import make_interface
    from controllers.blind import ASYMMETRY_PATH, BLIND_PATH, BlindSettings

    ctx = ControllerContext.from_env(gym.make("PiezoTurntable-v0"))
    config = InterfaceConfig(base=base)
    asym = BlindSettings.load(ASYMMETRY_PATH)
    for survey, top in ((asym, 4.5), (None, 4.5), (BlindSettings.load(BLIND_PATH), 6.5)):
        p = make_interface(ctx, config, blind_settings=survey).row_state().planner
        amps = [a for d in (1, -1) for a in p.blind_rows(d)[:, 0]]
        assert max(abs(a) for a in amps) == pytest.approx(top)
    with pytest.raises(ValueError, match="blind_settings=int"):
        make_interface(ctx, config, blind_settings=5)
