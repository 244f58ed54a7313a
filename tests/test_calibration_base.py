"""A lab's earlier calibration as the prior (``turntable calibrate --base FILE``, stop 108).

The nominal factors scale the base plant and their priors centre on it
(:class:`~turntable_env.calibration.nominal.NominalModel`), so with the rig's own earlier
calibration as the base the prior model *is* that calibration: on data from that plant
its held-out error is the noise floor before any fit, where the datasheet's prior is far
off; the limits of every factor stay the absolute ones whatever the base.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from turntable_env.calibration.calibrate import calibrate
from turntable_env.calibration.nominal import NominalModel
from turntable_env.calibration.trace_fit import trace_base
from turntable_env.calibration.virtual_lab import run_virtual_lab
from turntable_env.params import FACTORS
from turntable_env.plant import Plant, calibrated_set_toml

LAB = Plant(factors={"friction": 0.5, "preload": 0.6, "amplifier_slew": 1.3})


@pytest.fixture(scope="module")
def lab_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("lab") / "calibrated.toml"
    path.write_text(calibrated_set_toml(LAB, source="an earlier calibration"), encoding="utf-8")
    return path


def test_the_prior_centres_on_the_base_and_the_limits_stay_absolute(lab_file):
    base = Plant.load(lab_file).replace(fidelity="reduced")
    model = NominalModel(base)
    centre = model.plant(np.zeros(len(model)))
    assert centre.params == base.params  # x = 0 is the lab's plant
    for p, lo, hi in zip(model.parameters, model.low, model.high, strict=True):
        if p.target != "factor" or p.key == "coulomb":  # coulomb: capped by µ_s/µ_c too
            continue
        f = base.factors.get(p.key, 1.0)
        assert f * math.exp(lo) == pytest.approx(FACTORS[p.key][0], rel=1e-12)
        assert f * math.exp(hi) == pytest.approx(FACTORS[p.key][1], rel=1e-12)


def test_the_labs_calibration_as_base_starts_at_the_noise_floor(lab_file):
    m = run_virtual_lab("thesis", plant=LAB, noise_std=1e-3, seed=4)
    kw = {"global_points": 1, "starts": 1, "hops": 0, "candidates": [], "workers": 1,
          "progress": None}  # fmt: skip
    on_lab = calibrate([m], base=Plant.load(lab_file), **kw)
    on_sheet = calibrate([m], base="real", **kw)
    floor = on_lab.diagnosis["noise_floor"]
    assert on_lab.error_before <= 1.2 * floor  # the prior model is the plant: noise only
    assert on_sheet.error_before >= 5.0 * on_lab.error_before
    assert on_lab.diagnosis["base"] == str(lab_file) and on_sheet.diagnosis["base"] == "real"
    for k in ("friction", "preload"):  # the fit stays at the lab's values (absolute)
        assert on_lab.plant.factors[k] == pytest.approx(LAB.factors[k], rel=0.03)


def test_a_base_with_an_ideal_source_gets_its_amplifier_back_with_a_warning():
    """A summary-level fit's plant may run an ideal source; as a trace calibration's base
    its amplifier model comes back (the fitted slew and current must act), said in a
    warning; the factors are kept, and a named set is the reduced model, unwarned."""
    warnings: list[str] = []
    ideal = LAB.replace(ideal_amplifier=True)
    base = trace_base(ideal, warnings)
    assert not base.ideal_amplifier and base.fidelity == "reduced"
    assert base.factors == LAB.factors
    assert len(warnings) == 1 and "ideal source" in warnings[0]
    model = NominalModel(base, ("amplifier_slew",))
    slow, fast = (model.plant(np.array([v])).params.amplifier for v in (-1.0, 1.0))
    assert slow != fast  # the amplifier's factor reaches the plant that runs
    quiet: list[str] = []
    assert trace_base("real", quiet) == Plant("real", fidelity="reduced") and not quiet
