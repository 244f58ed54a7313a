"""The calibration loop on summary-level data: the thesis's chapter-4 figures (issue 8)."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from turntable_env.amplifier import Amplifier
from turntable_env.calibration.calibrate import write_report
from turntable_env.calibration.summary import calibrate_summary, predict_targets
from turntable_env.calibration.thesis_data import thesis_targets
from turntable_env.cli import main

HVA = {"amplifier_dynamics": {"slew_scale": 1.0, "current_scale": 1.0}}


@pytest.fixture(scope="module")
def ideal():
    return predict_targets()


@pytest.fixture(scope="module")
def hva():
    return predict_targets(effects=HVA)


def test_ideal_source_has_no_transition_time(ideal):
    for name in ("1V", "3V", "900V", "adapted"):
        assert math.isinf(ideal[f"amplifier_slew_{name}"])


@pytest.mark.parametrize("name, measured", [("1V", 0.9e6), ("3V", 2.7e6)])
def test_hva_model_reproduces_fig_4_2(hva, name, measured):
    """§4.1.2: the HVA 900 model is built on these two figures (τ from 0.9 V/µs per V)."""
    assert hva[f"amplifier_slew_{name}"] == pytest.approx(measured, rel=0.01)


def test_adapted_slew_is_first_order_closed_form(hva):
    """Fig. 4.3 at 1 V: output 45 V → 0 V, input at −1 V: e(t) = 90·exp(−t/τ) V of error,
    so 10 → 90 % of the 45 V swing takes τ·ln(85.5/49.5) and the slew rate is
    36 V / that — 3.6 V/µs, not the measured 8.0 (the residual the report names)."""
    tau = Amplifier().tau
    expected = 36.0 / (tau * math.log(85.5 / 49.5))
    assert hva["amplifier_slew_adapted"] == pytest.approx(expected, rel=0.01)
    assert hva["amplifier_slew_adapted"] < 0.5 * 8.0e6


def test_slow_flyback_steps_less_than_ideal_source(ideal, hva):
    """§4.1.2: with the unadapted slew the table follows the input — the HVA model's net
    rotation per period is well below the ideal source's at the same parameters."""
    assert ideal["net_rotation_unadapted"] > 0.0
    assert hva["net_rotation_unadapted"] < 0.6 * ideal["net_rotation_unadapted"]


def test_zero_targets_refer_to_their_companion_figure():
    t = {x.name: x for x in thesis_targets()}
    assert t["return_two_directional"].reference == pytest.approx(0.53)
    assert t["net_rotation_unadapted"].reference == pytest.approx(0.30e-6 / 0.01)
    assert t["detector_dV_one_directional"].reference == pytest.approx(1.19)


@pytest.mark.slow
def test_recovers_an_undeclared_amplifier_on_synthetic_figures():
    """Figures made by the model with a slower amplifier (slew × 0.7), nothing declared:
    the amplifier stage names amplifier_dynamics and finds the scale."""
    truth = {"amplifier_dynamics": {"slew_scale": 0.7, "current_scale": 1.0}}
    pred = predict_targets(effects=truth)
    targets = [replace(t, value=pred[t.name]) for t in thesis_targets()]
    res = calibrate_summary(targets, candidates=["amplifier_dynamics"], rig=False, progress=None)
    assert res.selected_effects == ["amplifier_dynamics"]
    scale = res.parameters["amplifier_dynamics"]["slew_scale"]["value"]
    assert scale == pytest.approx(0.7, abs=0.02)
    slew_rows = [r for r in res.diagnosis["targets"] if r["unit"] == "V/s"]
    assert all(abs(r["error_after"]) < 0.01 for r in slew_rows)


@pytest.fixture(scope="module")
def amplifier_stage():
    """The amplifier stage from two sets of perturbed starts (seeds 0 and 5)."""
    return {s: calibrate_summary(rig=False, progress=None, seed=s) for s in (0, 5)}


@pytest.mark.slow  # the default tier's 5 CPU minutes (stop 48): two amplifier stages, 27 s
@pytest.mark.xdist_group("amplifier-stage")  # one worker computes the module fixture
def test_amplifier_stage_selects_the_fast_path(amplifier_stage, tmp_path):
    """§4.1.2 on the ideal-source nominal: the first-order stage fits the 1 V and 3 V figures
    at scale 1 but asks for another speed for the adapted one (the residual that points to
    the fast path); the stage selects amplifier_fast_path, with margins far beyond their
    uncertainty, and every slew figure then lies within 3 %."""
    res = amplifier_stage[0]
    assert res.selected_effects[0] == "amplifier_fast_path"
    (d,) = [h["decision"] for h in res.history if "decision" in h and
            h["decision"]["decision"] == "selected"]  # fmt: skip
    assert d["heldout_margin"] > 5 * d["heldout_tolerance"] and d["z"] > 10 * d["z_threshold"]
    assert d["runner_up"] == "amplifier_dynamics" and d["runner_up_margin"] > d["heldout_tolerance"]
    need = res.diagnosis["amplifier_slew_scale_needed"]
    assert need["amplifier_slew_1V"]["slew_scale"] == pytest.approx(1.0, abs=0.01)
    assert not need["amplifier_slew_adapted"]["reproduced"]
    for row in res.diagnosis["targets"]:
        if row["unit"] == "V/s":
            assert abs(row["error_after"]) < 0.03, row["target"]
    paths = write_report(res, tmp_path)
    rep = json.loads(paths["json"].read_text())
    assert rep["error_unit"] == "%" and rep["plant"]["effects"]["amplifier_fast_path"]
    md = paths["md"].read_text()
    assert "first-order speed each slew figure asks for" in md
    assert "round 1: selected amplifier_fast_path" in md


@pytest.mark.slow  # the default tier's 5 CPU minutes (stop 48): two amplifier stages, 27 s
@pytest.mark.xdist_group("amplifier-stage")  # one worker computes the module fixture
def test_amplifier_decision_does_not_depend_on_the_starts(amplifier_stage):
    """Other perturbed starts (seed 5): the same selection, every start agreeing on the
    fit, the fast path's parameters within their posterior standard errors of seed 0's and
    every slew figure within its quoted resolution."""
    a, b = amplifier_stage[0], amplifier_stage[5]
    assert a.selected_effects == b.selected_effects == ["amplifier_fast_path"]
    for res in (a, b):
        (c,) = [c for c in res.candidates if c["effect"] == "amplifier_fast_path"]
        assert c["starts_agree"] == len(c["starts"]) == 5
    pa, pb = a.parameters["amplifier_fast_path"], b.parameters["amplifier_fast_path"]
    for name in ("fraction", "tau_fast"):
        assert abs(pa[name]["value"] - pb[name]["value"]) <= pa[name]["std"], name
    rows_b = {r["target"]: r for r in b.diagnosis["targets"]}
    for r in a.diagnosis["targets"]:
        if r["unit"] == "V/s":
            other = rows_b[r["target"]]["predicted_after"]
            assert abs(r["predicted_after"] - other) <= r["resolution"], r["target"]


def _cand(name, heldout, z=50.0, agree=5):
    from turntable_env.calibration.summary import CandidateResult

    loo = np.full(4, heldout / 100.0)
    return CandidateResult(name, None, loo, [{}] * 5, agree, z, {})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "heldout, z, rival, agree, expected",
    [
        (50.0, 50.0, 70.0, 5, "selected"),
        (95.0, 50.0, 99.0, 5, "rejected"),  # does not improve by 10 %
        (50.0, 1.5, 70.0, 5, "rejected"),  # its parameters sit at neutral
        (89.0, 50.0, 99.0, 5, "undecided"),  # 90 % needed: within the 2 % tolerance
        (50.0, 3.5, 70.0, 5, "undecided"),  # 3.5 σ: within 1 of the 3 σ threshold
        (50.0, 50.0, 50.5, 5, "undecided"),  # the runner-up as good
        (50.0, 50.0, 70.0, 1, "undecided"),  # one start of five reaches the fit
    ],
)
def test_a_selection_inside_its_uncertainty_is_undecided(heldout, z, rival, agree, expected):
    """Stage 2's decision rule: a margin within its own uncertainty is not taken either way
    (current held-out error 100 %, 10 % improvement needed)."""
    from turntable_env.calibration.summary import _decide

    d = _decide(_cand("a", heldout, z, agree), _cand("b", rival), 100.0, 0.10)
    assert d["decision"] == expected, d


def test_cli_refuses_to_mix_traces_and_figures(tmp_path, capsys):
    rc = main(["calibrate", "a.csv", "b.toml", "--report", str(tmp_path)])
    assert rc != 0
    assert "b.toml" in capsys.readouterr().err
