"""Shared fixtures, the virtual-lab calibrations two test files share, and the slow tier's
schedule under pytest-xdist (.ci/run: ``-n 2 --dist loadgroup``)."""

import fcntl
import functools
import hashlib
import json
import os
import pickle
import sys
from pathlib import Path

import pytest

from turntable_env.effects import CATALOGUE
from turntable_env.params import real_parameters, thesis_parameters


@pytest.fixture(scope="session")
def real():
    return real_parameters()


@pytest.fixture(scope="session")
def thesis():
    return thesis_parameters()


def scan_angles(env, offsets):
    """(true angle [rad], measured angle [rad]) after each control interval of an unwrapped
    PiezoTurntable env reset at 0 with the generator idle at scan levels ``offsets`` [V]."""
    import numpy as np

    from turntable_env.envs import ActionScaling

    scale = ActionScaling()
    env.reset(seed=0, options={"start_angle": 0.0, "target_angle": 0.0})
    out = []
    for off in offsets:
        obs, *_, info = env.step(scale.encode(0.0, 100.0, 0.9, 0.0, off))
        out.append((info["angle_rad"], float(obs[0])))
    return np.array(out)



# the effects of the virtual-lab calibrations tests/test_calibrate.py judges, each at one
# setting; tests/test_chain.py runs the same ones in the env (one run serves both: equal keys)
VIRTUAL_LAB_CASES = {
    "amplifier_dynamics": CATALOGUE["amplifier_dynamics"].defaults(),
    "piezo_hysteresis": CATALOGUE["piezo_hysteresis"].defaults(),
    "piezo_creep": {"gamma": 0.04},
    "friction_asymmetry": CATALOGUE["friction_asymmetry"].defaults(),
    "friction_wear": {"beta": 0.3},
    "axis_misalignment": CATALOGUE["axis_misalignment"].defaults(),
    "sensor_drift": CATALOGUE["sensor_drift"].defaults(),
    # 13 Hz, off the 100 Hz control interval's Nyquist line, so the env can read it
    "vibration": {"amplitude": 5e-6, "frequency": 13.0, "phase": 0.3},
    "detector_nonlinearity": {"kappa": 0.25},
}

_SHARED: dict[str, Path | None] = {"dir": None}  # the run's directory all workers share


@pytest.fixture(scope="session", autouse=True)
def _shared_run_directory(tmp_path_factory):
    """Under pytest-xdist, the run's temporary directory every worker sees (the parent of
    the workers' own ``popen-gwN``); without xdist, none (one process: memory serves)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        _SHARED["dir"] = tmp_path_factory.getbasetemp().parent / "virtual-lab"
        _SHARED["dir"].mkdir(exist_ok=True)


@functools.cache
def _virtual_lab_calibration(effects: str):
    from turntable_env.calibration.calibrate import calibrate
    from turntable_env.calibration.virtual_lab import run_virtual_lab

    def run():
        m = run_virtual_lab("standard", json.loads(effects), noise_std=1e-3, seed=1)
        return calibrate([m], progress=None)

    shared = _SHARED["dir"]
    if shared is None:
        return run()
    path = shared / (hashlib.sha256(effects.encode()).hexdigest()[:16] + ".pickle")
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # a second worker waits for the first one's run
        if path.exists():
            return pickle.loads(path.read_bytes())
        res = run()
        tmp = path.with_suffix(".part")
        tmp.write_bytes(pickle.dumps(res))
        tmp.replace(path)
        return res


def virtual_lab_calibration(effects: dict):
    """The calibration of the ``standard`` virtual-lab protocol (1 mV noise, seed 1) with
    ``effects`` on, computed once per test run: tests/test_calibrate.py and
    tests/test_chain.py judge the same run. Under pytest-xdist the workers share it
    through the run's temporary directory (whichever worker asks first runs it, under a
    file lock); without, through memory."""
    return _virtual_lab_calibration(json.dumps(effects, sort_keys=True))


def pytest_collection_modifyitems(config, items):
    """Longest first: a test marked ``slow(seconds=N)`` (its time on the CI machine) is
    scheduled before the others, in order of N, so that under xdist a long one does not
    start last on one worker while the other idles. The order of the rest is kept."""
    def seconds(item) -> float:
        mark = item.get_closest_marker("slow")
        return float(mark.kwargs.get("seconds", 0.0)) if mark is not None else 0.0

    items.sort(key=lambda item: -seconds(item))


def experiment(name: str):
    """The script ``experiments/<name>.py`` as a module (its functions, not its main)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / f"{name}.py"
    if str(path.parent) not in sys.path:  # its imports of the scripts beside it, as when run
        sys.path.append(str(path.parent))
    key = f"experiments.{name}"  # registered, as importlib's recipe does: dataclasses
    spec = importlib.util.spec_from_file_location(key, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[key] = mod  # (a fresh module on every call) look their module up there
    spec.loader.exec_module(mod)
    return mod


def smoke_hyperparams(algo: str, tmp_path: Path, env_id: str | None = None, source=None):
    """(hyperparameter file, training file) in ``tmp_path`` for a training run of a few
    hundred steps: ``source`` (default ``agents/hyperparams/<algo>.yml``) with 2 rows,
    20-interval episodes and small batches, evaluated and checkpointed every 200 steps."""
    import yaml

    from agents.interface import AGENT_ENV_ID
    from agents.train import load_hyperparams

    env_id = env_id or AGENT_ENV_ID
    cfg = load_hyperparams(algo, source, env_id=env_id)
    cfg.update(n_envs=2)
    cfg["env_kwargs"]["max_episode_steps"] = 20
    if algo == "ppo":
        cfg.update(n_steps=64, batch_size=64, n_epochs=2)
    else:
        cfg.update(learning_starts=50, batch_size=32, buffer_size=1000)
    p = tmp_path / f"{algo}.yml"
    p.write_text(yaml.safe_dump({env_id: cfg}))
    t = tmp_path / "training.yml"
    t.write_text(yaml.safe_dump({algo: {"eval": {"freq": 200, "n_envs": 2, "episodes": 2},
                                        "checkpoint_freq": 200}}))  # fmt: skip
    return p, t
