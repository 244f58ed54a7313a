"""RL protocol: rl-zoo3 reads the shipped hyperparameter files, the agent interface is an
env id, runs for several seeds go to Ray (or local processes), curves across seeds."""

import inspect
import re
import shutil
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
import yaml

import agents  # noqa: F401  (registers PiezoTurntableAgent-v0)
from agents.interface import AGENT_ENV_ID, RAW_ENV_ID
from agents.scale import seed_curves, train_seeds, validate_seeds
from agents.train import HYPERPARAMS_DIR, ZOO_KEYS, _algos, load_training


@pytest.mark.parametrize(
    ("algo", "name"),
    [
        ("ppo", "ppo"),
        ("sac", "sac"),
        ("ppo", "ppo_history"),
        ("ppo", "ppo_identify"),
        ("ppo", "ppo_residual"),
        ("ppo", "ppo_residual_tracking"),
        ("ppo", "ppo_residual_fuzzy"),
        ("ppo", "ppo_residual_fuzzy_cost"),
    ],
)
def test_hyperparameter_files_hold_only_zoo_keys_and_sb3_arguments(algo, name):
    """rl-zoo3 passes every key it does not know to the algorithm: so every key must be a
    zoo key or an argument of the SB3 class (the project's own settings live elsewhere)."""
    data = yaml.safe_load((HYPERPARAMS_DIR / f"{name}.yml").read_text(encoding="utf-8"))
    params = set(inspect.signature(_algos()[algo].__init__).parameters)
    for env_id, entry in data.items():
        assert env_id in (AGENT_ENV_ID, RAW_ENV_ID)
        unknown = set(entry) - set(ZOO_KEYS) - params
        assert not unknown, (env_id, unknown)
        env = gym.make(env_id, **entry["env_kwargs"])  # the zoo makes the env this way
        assert env.spec.max_episode_steps == entry["env_kwargs"]["max_episode_steps"]
        env.close()
    assert load_training(algo)["eval"]["episodes"] > 0


@pytest.mark.parametrize(
    ("interface", "width", "actions"),
    [
        ({"max_steps": 10}, 8, 3),
        ({"max_steps": 10, "identify": True}, 14, 3),
        ({"base": "closed_loop"}, 10, 1),
        ({"base": "fuzzy", "scale_max": 1.5, "action_cost": 0.05}, 10, 1),
    ],
)
def test_agent_interface_is_an_env_id_that_passes_gymnasiums_checker(interface, width, actions):
    """The agent env (with ``identify``: the step gains appended; with a ``base``: the
    residual agent's) passes Gymnasium's checker: spaces, seeded resets (the residual
    agent's base reset with them), observations within the space."""
    from gymnasium.utils.env_checker import check_env

    env = gym.make(AGENT_ENV_ID, interface=interface, randomize=True)
    assert env.action_space.shape == (actions,) and env.observation_space.shape == (width,)
    with warnings.catch_warnings():  # the agent env is a wrapper by design: check the stack
        warnings.filterwarnings("ignore", message=".*different from the unwrapped version")
        check_env(env, skip_render_check=True)


def _zoo(args, tmp_path):
    cmd = [sys.executable, "-m", "rl_zoo3.train", *args, "--log-folder", str(tmp_path),
           "--seed", "0", "--eval-freq", "-1", "--device", "cpu"]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    return res


@pytest.mark.slow
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


def test_validation_gives_every_seed_the_same_episodes_and_calls_a_tie(tmp_path):
    """validate_seeds: a run against itself meets the same episodes, return for return,
    and its margin, 0, is a tie; two seeds' policies differ on those episodes; a run of
    another config cannot be compared, nor a count of episodes the envs cannot share."""
    from conftest import smoke_hyperparams

    from agents.train import train

    hp, tr = smoke_hyperparams("ppo", tmp_path, source=HYPERPARAMS_DIR / "ppo_residual.yml")
    runs = [train("ppo", timesteps=128, seed=s, out=tmp_path / f"s{s}", hyperparams=hp,
                  training=tr, progress=False).run for s in (0, 1)]  # fmt: skip
    same = validate_seeds([runs[0], runs[0]], episodes=8, n_envs=4)
    assert same["returns"].shape == (2, 8) and same["paired"]
    np.testing.assert_array_equal(*same["returns"])
    assert same["margin"] == 0.0 and not same["decided"]
    two = validate_seeds(runs, episodes=8, n_envs=4)
    assert two["paired"]  # every episode ran its 20 intervals: episode k is one draw
    assert not np.array_equal(*two["returns"])
    assert two["mean"][two["best"]] >= two["mean"][two["runner_up"]]
    lo, hi = two["margin_ci"]
    assert lo <= two["margin"] <= hi and two["decided"] == (lo > 0.0)
    other = tmp_path / "other"
    shutil.copytree(runs[1], other)
    cfg = yaml.safe_load((other / "config.yml").read_text())
    cfg["PiezoTurntableAgent-v0"]["env_kwargs"]["target_range"] = 0.3
    (other / "config.yml").write_text(yaml.safe_dump(cfg))
    with pytest.raises(ValueError, match="another env entry"):
        validate_seeds([runs[0], other], episodes=8, n_envs=4)
    del cfg["run"]["env_id"]  # a run made before the env ids: its entry is elsewhere
    (other / "config.yml").write_text(yaml.safe_dump(cfg))
    with pytest.raises(ValueError, match=r"no run\.env_id"):
        validate_seeds([runs[0], other], episodes=8, n_envs=4)
    with pytest.raises(ValueError, match="episodes=6"):
        validate_seeds(runs, episodes=6, n_envs=4)


def test_an_unpaired_margin_interval_brackets_the_difference_of_the_means():
    """Where an episode ended early in one run the returns are not paired: the interval is
    the two samples' bootstrap, around the difference of means (1 here), and a sample
    against a shuffled copy of itself is a tie."""
    from agents.scale import _unpaired_ci

    rng = np.random.default_rng(0)
    a, b = rng.normal(1.0, 1.0, 200), rng.normal(0.0, 1.0, 200)
    lo, hi = _unpaired_ci(a, b)
    assert 0.0 < lo < a.mean() - b.mean() < hi
    lo, hi = _unpaired_ci(a, rng.permutation(a))
    assert lo < 0.0 < hi


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
@pytest.mark.parametrize(  # one local Ray instance at a time (xdist: one worker for "ray")
    "backend", [pytest.param("ray", marks=pytest.mark.xdist_group("ray")), "processes"]
)
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


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("dict(net_arch=[64, 64], activation_fn=nn.Tanh)", {"net_arch": [64, 64], "act": "Tanh"}),
        ("dict(net_arch=dict(pi=[32], vf=[32]), log_std_init=-2)",
         {"net_arch": {"pi": [32], "vf": [32]}, "log_std_init": -2}),
        ({"net_arch": [8], "activation_fn": "nn.ReLU"}, {"net_arch": [8], "act": "ReLU"}),
    ],
)  # fmt: skip
def test_policy_kwargs_read_as_rl_zoo3_writes_them_and_round_trip(value, expected):
    from agents.train import parse_policy_kwargs, zoo_policy_kwargs

    got = parse_policy_kwargs(value)
    act = expected.pop("act", None)
    assert (got.pop("activation_fn").__name__ if act else None) == act
    assert got == expected
    full = parse_policy_kwargs(value)
    assert parse_policy_kwargs(zoo_policy_kwargs(full)) == full


@pytest.mark.parametrize(
    "value",
    [
        "__import__('os').system('true')",
        "dict(activation_fn=nn.Softmax)",
        "dict(net_arch=os.environ)",
        "dict(**x)",
        "[64, 64]",
        "dict(net_arch=[64",
        3,
    ],
)
def test_policy_kwargs_strings_are_parsed_not_evaluated(value):
    from agents.train import parse_policy_kwargs

    with pytest.raises(ValueError, match="policy_kwargs"):
        parse_policy_kwargs(value)


def test_overrides_replace_sb3_arguments_and_merge_policy_kwargs():
    from agents.train import apply_overrides, load_hyperparams, parse_policy_kwargs

    base = load_hyperparams("ppo")
    got = apply_overrides(base, {"learning_rate": 1e-4,
                                 "policy_kwargs": "dict(net_arch=[16], activation_fn=nn.ReLU)"})
    pk = parse_policy_kwargs(got["policy_kwargs"])
    assert got["learning_rate"] == 1e-4 and pk["net_arch"] == [16]
    assert pk["log_std_init"] == base["policy_kwargs"]["log_std_init"]  # gSDE's start kept
    assert yaml.safe_load(yaml.safe_dump(got)) == got  # YAML-safe
    with pytest.raises(ValueError, match="n_envs"):
        apply_overrides(base, {"n_envs": 4})


@pytest.mark.parametrize("form", ["127.0.0.1:{port}", "ray://127.0.0.1:{port}"])
def test_a_cluster_address_nobody_answers_is_refused_before_any_job(form):
    """ray.init retries an unreachable address for minutes: the address is refused at
    once, named, before a job starts (a port just freed, so nothing listens on it)."""
    pytest.importorskip("ray")
    import socket

    from turntable_env.scale import map_tasks

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = form.format(port=port)
    ran = []
    with pytest.raises(ValueError, match=rf"address='{re.escape(address)}': no Ray cluster"):
        map_tasks(ran.append, [1], backend="ray", address=address)
    assert not ran


def test_an_address_that_answered_is_not_dialled_again():
    """The caller, map_tasks and session each resolve the backend: one connection."""
    pytest.importorskip("ray")
    import socket

    from turntable_env.scale import resolve_backend

    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen(4)
        srv.settimeout(1.0)
        address = f"127.0.0.1:{srv.getsockname()[1]}"
        assert [resolve_backend("ray", address) for _ in range(3)] == ["ray"] * 3
        srv.accept()[0].close()  # the one connection
        with pytest.raises(TimeoutError):
            srv.accept()


def test_map_tasks_keeps_the_jobs_order_in_processes():
    import math

    from turntable_env.scale import map_tasks

    jobs = [7, 3, 5, 1]
    assert map_tasks(math.factorial, jobs, backend="processes", workers=2) == [5040, 6, 120, 1]


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"algo": "td3"}, "algo"),
        ({"trials": 0}, "trials"),
        ({"parallel": True}, "parallel"),
        ({"timesteps": 2.5}, "timesteps"),
        ({"backend": "slurm"}, "backend"),
        ({"backend": "processes", "address": "auto"}, "address"),
        ({"seed": -1}, "seed"),
    ],
)
def test_search_refuses_bad_arguments_before_any_work(kw, match, tmp_path):
    from agents.tune import search

    args = {"algo": "sac", "trials": 2, **kw}
    out = tmp_path / "study"
    with pytest.raises(ValueError, match=match):
        search(args.pop("algo"), args.pop("trials"), out=out, **args)
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.xdist_group("ray")  # one local Ray instance at a time
def test_hyperparameter_search_runs_trials_as_ray_tasks_and_resumes(tmp_path):
    """2 trials × 300 steps as Ray tasks on a local instance, then one more on the same
    journal: the study holds all three, the best is the highest return, and best.yml is
    the base entry with the best trial's sampled arguments (readable by the trainer)."""
    pytest.importorskip("ray")
    from agents.train import apply_overrides, load_hyperparams
    from agents.tune import search

    hp, _ = _tiny(tmp_path)
    kw = {"timesteps": 300, "eval_episodes": 2, "out": tmp_path / "study", "hyperparams": hp}
    first = search("sac", 2, parallel=2, backend="ray", **kw)
    res = search("sac", 1, parallel=1, backend="ray", **kw)
    df = res.to_pandas()
    assert len(df) == 3 and first.journal == res.journal
    done = df[df["state"] == "COMPLETE"]
    assert res.best_value == pytest.approx(done["value"].max())
    entry = load_hyperparams("sac", res.best_file)
    assert entry == apply_overrides(load_hyperparams("sac", hp), res.best_overrides)


ORPHAN_SCRIPT = """
import os, sys, time
from pathlib import Path
from turntable_env.scale import map_tasks

def job(d):
    Path(d, "worker.pid").write_text(str(os.getpid()))
    time.sleep(float(sys.argv[2]))
    Path(d, "done").write_text("a job that outlived its run")

if __name__ == "__main__":
    map_tasks(job, [sys.argv[1]], backend="processes", workers=1)
"""


def test_a_killed_runs_process_workers_end_with_it(tmp_path):
    """map_tasks' process workers watch their parent: SIGKILL the run mid-job and its
    worker ends too, before the job could write its result (stop 107's orphaned
    calibration rewrote a row's report.json); a run left alone finishes its job."""
    import os
    import signal
    import subprocess
    import sys
    import time

    script = tmp_path / "run.py"
    script.write_text(ORPHAN_SCRIPT)
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    whole = tmp_path / "whole"
    whole.mkdir()
    subprocess.run([sys.executable, str(script), str(whole), "0"], check=True, env=env,
                   timeout=120)  # fmt: skip
    assert (whole / "done").exists()  # the harness does reach its write
    killed = tmp_path / "killed"
    killed.mkdir()
    run = subprocess.Popen([sys.executable, str(script), str(killed), "20"], env=env)
    pid_file = killed / "worker.pid"
    deadline = time.monotonic() + 120
    while not pid_file.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert pid_file.exists(), "the worker never started"
    worker = int(pid_file.read_text())
    run.send_signal(signal.SIGKILL)
    run.wait(timeout=30)
    deadline = time.monotonic() + 15  # a liveness bound, far under the job's 20 s
    while time.monotonic() < deadline:
        try:
            os.kill(worker, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        os.kill(worker, signal.SIGKILL)
        raise AssertionError("the orphaned worker still ran 15 s after its run was killed")
    time.sleep(0.5)
    assert not (killed / "done").exists()
