"""Shared fixtures."""

import pytest

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



def experiment(name: str):
    """The script ``experiments/<name>.py`` as a module (its functions, not its main)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
