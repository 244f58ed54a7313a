"""``experiments/y_feature.py`` (issue 31, stop 73): on a virtual-lab trace the y feature
over the moves reads a misaligned detector's tan φ and leaves a clean one at |z| < 3, and
the command line refuses a missing trace with exit 2, one line."""

from __future__ import annotations

import math

import pytest
from conftest import experiment

from turntable_env.calibration.virtual_lab import run_virtual_lab


@pytest.fixture(scope="module")
def script():
    return experiment("y_feature")


@pytest.mark.parametrize("phi", [0.0, 0.05])
def test_the_feature_reads_the_misalignment_of_a_virtual_lab_trace(script, tmp_path, capsys,
                                                                   phi):  # fmt: skip
    effects = {"axis_misalignment": {"phi": phi}} if phi else {}
    path = tmp_path / "m.csv"
    run_virtual_lab("standard", effects, out=path, seed=3)
    assert script.main([str(path)]) == 0
    row = capsys.readouterr().out.strip().splitlines()[-1].split()
    slope, z = float(row[2]), float(row[3])
    if phi:
        assert slope == pytest.approx(math.tan(phi), rel=0.02) and z > 100.0
    else:
        assert abs(z) < 3.0


def test_a_missing_trace_is_refused_with_exit_2(script, tmp_path, capsys):
    assert script.main([str(tmp_path / "absent.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("y_feature:") and "absent.csv" in err and "\n" not in err
