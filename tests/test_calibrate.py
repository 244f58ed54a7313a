"""The calibrator on virtual-lab data with effects nobody declared (issue 8).

Each dataset is the ``standard`` protocol with detector noise at 1 mV; the calibrator is
not told which effect is on. It must name it and cut the held-out error at least 3×.
"""

import json

import pytest
from conftest import VIRTUAL_LAB_CASES, virtual_lab_calibration

from turntable_env.calibration.calibrate import calibrate, write_report
from turntable_env.calibration.virtual_lab import run_virtual_lab

pytestmark = pytest.mark.slow  # each case is a full calibration (20-70 s)

CASES = VIRTUAL_LAB_CASES


def _run(effects):
    return virtual_lab_calibration(effects)


@pytest.mark.parametrize(
    "name",  # tests/test_chain.py judges the same runs of creep and hysteresis
    [pytest.param(n, marks=pytest.mark.xdist_group(f"virtual-lab-{n}")) for n in CASES],
)
def test_undeclared_effect_is_named_and_the_error_drops(name):
    res = _run({name: CASES[name]})
    assert name in res.selected_effects
    assert res.error_before >= 3.0 * res.error_after
    assert res.error_unit == "nm"


def test_a_misalignment_the_other_way_is_named():
    """The tilt goes either way: a y channel leaning against x (φ < 0, as the second
    independent plant's rotated axes) is named, with its sign, and the error drops 3×."""
    res = _run({"axis_misalignment": {"phi": -0.1}})
    assert "axis_misalignment" in res.selected_effects
    phi = res.parameters["axis_misalignment"]["phi"]
    assert phi["value"] == pytest.approx(-0.1, abs=5 * phi["std"] + 0.01)
    assert res.error_before >= 3.0 * res.error_after


def test_clean_data_selects_nothing_and_is_white():
    res = _run({})
    assert res.selected_effects == []
    assert not res.residual_structured
    # the held-out error is the detector noise: 1 mV → S/(2L)·R = 2.83 nm at R_table
    assert res.error_after == pytest.approx(1e-3 * 9.9e-5 / (2 * 0.175) * 0.01 * 1e9, rel=0.05)


@pytest.mark.slow(seconds=320)  # CI, stop 47
def test_two_effects_at_once_are_both_found(tmp_path):
    res = _run({"piezo_creep": {"gamma": 0.02}, "sensor_drift": {"offset": 0.0, "rate": 0.1}})
    assert {"piezo_creep", "sensor_drift"} <= set(res.selected_effects)
    assert res.error_before >= 3.0 * res.error_after
    paths = write_report(res, tmp_path)
    rep = json.loads(paths["json"].read_text())
    for key in ("selected_effects", "error_before", "error_after", "error_unit",
                "residual_structured", "parameters", "candidates"):  # fmt: skip
        assert key in rep
    assert all("heldout_error" in c for c in rep["candidates"])
    drift = rep["parameters"]["sensor_drift"]["rate"]
    assert drift["value"] == pytest.approx(0.1, abs=5 * drift["std"] + 1e-3)
    assert paths["md"].read_text().startswith("# Calibration report")


def test_several_files_are_fitted_together():
    """Two short files (the §4.1.3 thesis protocol, different noise realisations), a
    drift in both: found from both, the held-out error over both drops 3×."""
    eff = {"sensor_drift": {"offset": 0.02, "rate": 0.3}}
    files = [run_virtual_lab("thesis", eff, noise_std=1e-3, seed=s) for s in (2, 3)]
    res = calibrate(files, progress=None)
    assert res.selected_effects[:1] == ["sensor_drift"]
    assert res.error_before >= 3.0 * res.error_after
    rate = res.parameters["sensor_drift"]["rate"]
    assert rate["value"] == pytest.approx(0.3, abs=5 * rate["std"] + 0.01)
