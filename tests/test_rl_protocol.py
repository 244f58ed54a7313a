"""RL protocol: rl-zoo3 reads the shipped hyperparameter files, the agent interface is an
env id, runs for several seeds go to Ray (or local processes), curves across seeds."""

import inspect
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
import yaml

import agents  # noqa: F401  (registers PiezoTurntableAgent-v0)
from agents.interface import AGENT_ENV_ID, RAW_ENV_ID
from agents.scale import seed_curves, train_seeds
from agents.train import HYPERPARAMS_DIR, ZOO_KEYS, _algos, load_training


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_hyperparameter_files_hold_only_zoo_keys_and_sb3_arguments(algo):
    """rl-zoo3 passes every key it does not know to the algorithm: so every key must be a
    zoo key or an argument of the SB3 class (the project's own settings live elsewhere)."""
    data = yaml.safe_load((HYPERPARAMS_DIR / f"{algo}.yml").read_text(encoding="utf-8"))
    params = set(inspect.signature(_algos()[algo].__init__).parameters)
    for env_id, entry in data.items():
        assert env_id in (AGENT_ENV_ID, RAW_ENV_ID)
        unknown = set(entry) - set(ZOO_KEYS) - params
        assert not unknown, (env_id, unknown)
        env = gym.make(env_id, **entry["env_kwargs"])  # the zoo makes the env this way
        assert env.spec.max_episode_steps == entry["env_kwargs"]["max_episode_steps"]
        env.close()
    assert load_training(algo)["eval"]["episodes"] > 0


def test_agent_interface_is_an_env_id_that_passes_gymnasiums_checker():
    from gymnasium.utils.env_checker import check_env

    env = gym.make(AGENT_ENV_ID, interface={"max_steps": 10}, randomize=True)
    assert env.action_space.shape == (3,) and env.observation_space.shape == (8,)
    with warnings.catch_warnings():  # the agent env is a wrapper by design: check the stack
        warnings.filterwarnings("ignore", message=".*different from the unwrapped version")
        check_env(env, skip_render_check=True)


def _zoo(args, tmp_path):
    cmd = [sys.executable, "-m", "rl_zoo3.train", *args, "--log-folder", str(tmp_path),
           "--seed", "0", "--eval-freq", "-1", "--device", "cpu"]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    return res


def test_rl_zoo3_trains_sac_on_the_raw_env_with_the_shipped_file(tmp_path):
    """The issue's command, with a few hundred steps."""
    pytest.importorskip("rl_zoo3")
    _zoo(["--algo", "sac", "--env", RAW_ENV_ID, "--gym-packages", "turntable_env",
          "--conf-file", str(HYPERPARAMS_DIR / "sac.yml"), "-n", "300",
          "-params", "n_envs:2", "learning_starts:50"], tmp_path)  # fmt: skip
    assert list(tmp_path.glob(f"sac/{RAW_ENV_ID}_*/{RAW_ENV_ID}.zip"))


@pytest.mark.slow
def test_rl_zoo3_trains_ppo_on_the_agent_env(tmp_path):
    pytest.importorskip("rl_zoo3")
    _zoo(["--algo", "ppo", "--env", AGENT_ENV_ID, "--gym-packages", "agents",
          "--conf-file", str(HYPERPARAMS_DIR / "ppo.yml"), "-n", "256",
          "-params", "n_envs:2", "n_steps:64", "batch_size:64"], tmp_path)  # fmt: skip
    assert list(tmp_path.glob(f"ppo/{AGENT_ENV_ID}_*/{AGENT_ENV_ID}.zip"))


def _fake_run(root, name, steps, means):
    d = root / name / "eval"
    d.mkdir(parents=True)
    res = np.repeat(np.asarray(means, float)[:, None], 4, axis=1)
    np.savez(d / "evaluations.npz", timesteps=np.asarray(steps), results=res)
    return root / name


def test_seed_curves_take_the_common_steps_and_bracket_the_mean(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", [100, 200, 300], [0.0, 1.0, 2.0]),
        _fake_run(tmp_path, "b", [100, 200], [2.0, 3.0]),
        _fake_run(tmp_path, "c", [100, 200, 300], [4.0, 5.0, 6.0]),
    ]
    c = seed_curves(runs)
    np.testing.assert_array_equal(c["timesteps"], [100, 200])
    np.testing.assert_allclose(c["mean"], [2.0, 3.0])
    assert (c["ci_low"] <= c["mean"]).all() and (c["mean"] <= c["ci_high"]).all()
    with pytest.raises(ValueError, match="at least 2"):
        seed_curves(runs[:1])


@pytest.mark.parametrize(
    ("kw", "match"),
    [({"backend": "slurm"}, "backend"), ({"seeds": [1, 1]}, "distinct")],
)
def test_train_seeds_refuses_bad_arguments(kw, match, tmp_path):
    args = {"seeds": [0, 1], **kw}
    with pytest.raises(ValueError, match=match):
        train_seeds("sac", args.pop("seeds"), out=tmp_path, **args)


def _tiny(tmp_path):
    from agents.train import load_hyperparams

    cfg = load_hyperparams("sac")
    cfg.update(n_envs=2, learning_starts=50, batch_size=32, buffer_size=1000)
    cfg["env_kwargs"]["max_episode_steps"] = 20
    hp = tmp_path / "sac.yml"
    hp.write_text(yaml.safe_dump({AGENT_ENV_ID: cfg}))
    tr = tmp_path / "training.yml"
    tr.write_text(yaml.safe_dump({"sac": {"eval": {"freq": 100, "n_envs": 2, "episodes": 2},
                                          "checkpoint_freq": 1000}}))  # fmt: skip
    return hp, tr


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["ray", "processes"])
def test_two_seeds_train_in_parallel_and_differ(backend, tmp_path):
    """2 seeds × 300 steps as Ray tasks on a local Ray instance (or local processes): one
    run directory per seed, each seeded (their evaluations differ), and a curve across them."""
    if backend == "ray":
        pytest.importorskip("ray")
    hp, tr = _tiny(tmp_path)
    runs = train_seeds("sac", [0, 1], timesteps=300, out=tmp_path / "runs", hyperparams=hp,
                       training=tr, backend=backend)  # fmt: skip
    assert [r.name for r in runs] == ["sac_seed0", "sac_seed1"]
    cfgs = [yaml.safe_load((r / "config.yml").read_text()) for r in runs]
    assert [c["run"]["seed"] for c in cfgs] == [0, 1]
    c = seed_curves(runs)
    assert c["per_run"].shape[0] == 2 and not np.array_equal(*c["per_run"])
