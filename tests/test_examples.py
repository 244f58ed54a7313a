"""The examples run as a user would run them (on a small budget) and print what they say."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(script: str, *args: str, cwd: Path = ROOT) -> str:
    r = subprocess.run([sys.executable, str(ROOT / "examples" / script), *args], cwd=cwd,
                       capture_output=True, text=True, timeout=900)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stdout


@pytest.mark.slow  # a second interpreter importing the stack: the default tier's CPU
def test_controller_example_reaches_the_target():
    out = _run("controller_on_env.py", "--steps", "100")
    m = re.search(r"success (True|False), final error ([\d.]+) nm", out)
    assert m is not None, out
    assert m.group(1) == "True" and float(m.group(2)) <= 10.0  # the env's 10 nm tolerance


@pytest.mark.slow(seconds=280)  # CI, stop 47
def test_virtual_lab_example_finds_the_undeclared_creep():
    out = _run("virtual_lab_calibration.py", "--global-points", "4", "--hops", "0",
               "--candidates", "piezo_creep,sensor_drift")  # fmt: skip
    m = re.search(r"selected (.+); held-out error ([\d.]+) → ([\d.]+)", out)
    assert m is not None, out
    assert "piezo_creep" in m.group(1) and float(m.group(3)) < float(m.group(2))


def test_virtual_lab_example_refuses_a_negative_budget_before_any_work():
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "virtual_lab_calibration.py"),
                        "--hops", "-1"], capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 2
    last = r.stderr.strip().splitlines()[-1]
    assert last.endswith("argument --hops: '-1': must be an integer ≥ 0")


@pytest.mark.slow
def test_training_example_runs_the_pipeline(tmp_path):
    out = _run("train_agent.py", "--timesteps", "300", "--out", str(tmp_path / "run"))
    assert "trained 300 steps" in out and (tmp_path / "run" / "model.zip").is_file()
