"""The chain measured data → calibrated plant → environment (issue 17's acceptance).

Virtual-lab data with an effect nobody declared is calibrated; the env built from the
report runs the plant the data described, and shows the effect's signature where a
controller would meet it: creep under a held scan offset, a hysteresis loop under a slow
scan, a periodic reading at rest — while the nominal env shows none.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import VIRTUAL_LAB_CASES, virtual_lab_calibration
from conftest import scan_angles as _scan

import turntable_env  # noqa: F401  (registers the envs)
from turntable_env.calibration.calibrate import write_report
from turntable_env.effects import CATALOGUE
from turntable_env.envs import ActionScaling

SCALE = ActionScaling()
HOME = {"start_angle": 0.0, "target_angle": 0.0}


def _calibrated_env(tmp_path, effects):
    res = virtual_lab_calibration(effects)
    write_report(res, tmp_path / "cal")
    return gym.make("PiezoTurntable-v0", plant=str(tmp_path / "cal" / "report.json"),
                    noise=False, terminate_on_success=False).unwrapped  # fmt: skip


def _nominal_env():
    return gym.make("PiezoTurntable-v0", noise=False, terminate_on_success=False).unwrapped


def _creep_signature(env) -> float:
    """Angle change between 0.1 s and 0.6 s of a held 5 V scan offset [rad]."""
    a = _scan(env, [5.0] * 60)[:, 0]
    return float(a[-1] - a[10])


def _loop_height(env) -> float:
    """At 0 V: falling branch − rising branch of a ±5 V scan [rad]."""
    prog = np.concatenate([np.linspace(0, 5, 10), np.linspace(5, -5, 21), np.linspace(-5, 0, 10)])
    a = _scan(env, prog)[:, 0]
    return float(a[20] - a[-1])


def _vibration_amplitude(env, frequency: float) -> float:
    """Amplitude [rad] of the measured angle at ``frequency`` at rest (least squares)."""
    m = _scan(env, [0.0] * 100)[:, 1]
    t = 0.01 * np.arange(1, 101)
    basis = np.column_stack([np.sin(2 * math.pi * frequency * t),
                             np.cos(2 * math.pi * frequency * t), np.ones_like(t)])  # fmt: skip
    c, *_ = np.linalg.lstsq(basis, m, rcond=None)
    return float(np.hypot(c[0], c[1]))


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",  # the runs tests/test_calibrate.py judges (one cached run, one worker)
    [pytest.param(n, marks=pytest.mark.xdist_group(f"virtual-lab-{n}"))
     for n in ("piezo_creep", "piezo_hysteresis", "vibration")],
)
def test_effect_found_by_the_full_calibration_runs_in_the_env(tmp_path, name):
    """The whole catalogue competes; the env from the report shows the effect's signature
    and the nominal env does not."""
    truth = VIRTUAL_LAB_CASES[name]
    env = _calibrated_env(tmp_path, {name: truth})
    assert name in env.plant.effects
    nominal = _nominal_env()
    if name == "piezo_creep":
        assert env.plant.effects["piezo_creep"]["gamma"] == pytest.approx(truth["gamma"], rel=0.3)
        assert abs(_creep_signature(nominal)) < 1e-11
        assert _creep_signature(env) > 0.05e-6
    elif name == "piezo_hysteresis":
        k_scan = _scan(nominal, [5.0] * 3)[-1, 0] / 5.0  # rad per input volt
        # every play saturated: 2·h·mean(r_i)·K
        expect = 2 * truth["h"] * truth["width"] * 9 / 16 * k_scan
        # the nominal env's own loop (its contacts' presliding) is not the effect's: bounded
        # with a margin, not at 0.1 % of the scan (1e-3·5·k_scan), where it sits: .ci/run's
        # failure at d42c8bf printed 7.378e-8 rad against that bound's 7.341e-8 rad (0.1005 %;
        # its summation order varies with the CPU, stop 94), which is 1.9 % of ``expect``
        # (2·0.12·2.0·9/16·k_scan = 3.96e-6 rad); the message prints both on any machine
        loop0 = abs(_loop_height(nominal))
        assert loop0 < 0.05 * expect, (
            f"nominal loop {loop0:.4g} rad = {100 * loop0 / expect:.2f} % of the effect's "
            f"{expect:.4g} rad ({100 * loop0 / (5 * k_scan):.4f} % of a 5 V scan)")
        assert _loop_height(env) == pytest.approx(expect, rel=0.3)
    else:
        f = env.plant.effects["vibration"]["frequency"]
        assert f == pytest.approx(truth["frequency"], rel=0.02)
        assert _vibration_amplitude(nominal, f) < 1e-9
        assert _vibration_amplitude(env, f) == pytest.approx(truth["amplitude"], rel=0.2)
    assert set(env.plant.effects) <= set(CATALOGUE)
