"""Shared fixtures, the virtual-lab calibrations two test files share, and the slow tier's
schedule under pytest-xdist (.ci/run: ``-n 2 --dist loadgroup``)."""

import functools
import json

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



@functools.cache
def _virtual_lab_calibration(effects: str, candidates: tuple[str, ...] | None):
    from turntable_env.calibration.calibrate import calibrate
    from turntable_env.calibration.virtual_lab import run_virtual_lab

    m = run_virtual_lab("standard", json.loads(effects), noise_std=1e-3, seed=1)
    return calibrate([m], candidates=None if candidates is None else list(candidates),
                     progress=None)  # fmt: skip


def virtual_lab_calibration(effects: dict, candidates: list[str] | None = None):
    """The calibration of the ``standard`` virtual-lab protocol (1 mV noise, seed 1) with
    ``effects`` on, computed once per test process: tests/test_calibrate.py and
    tests/test_chain.py judge the same run (the same xdist_group puts them on one worker)."""
    key = json.dumps(effects, sort_keys=True)
    return _virtual_lab_calibration(key, None if candidates is None else tuple(candidates))


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
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
