"""``experiments/amplifier_profile.py`` (issue 31): the base it calibrates on is the
``real`` base with only its amplifier changed — the measured 1 V slew (§4.1.2) × s, so the
first-order settling time τ ÷ s, and the current limit × c, so the rate limit on a
quadrant's capacitance (Eq. 2.2) × c where the current bounds it — and its command line
refuses bad scales and files with exit 2 before any fit."""

from __future__ import annotations

from dataclasses import replace

import pytest
from conftest import experiment

from turntable_env.plant import Plant
from turntable_env.plant.models import output_capacitance


@pytest.fixture(scope="module")
def script():
    return experiment("amplifier_profile")


@pytest.mark.parametrize(("slew", "current"), [(0.2, 1.0), (0.3, 0.1), (1.5, 2.0)])
def test_only_the_amplifier_is_scaled(script, slew, current):
    ref = Plant("real", fidelity="reduced").params
    ps = script.base_with_amplifier(slew, current).params
    amp, ref_amp = ps.amplifier, ref.amplifier
    assert amp.slew_per_input_volt == pytest.approx(slew * ref_amp.slew_per_input_volt)
    assert ps.amplifier.current_limit == pytest.approx(current * ref.amplifier.current_limit)
    c = output_capacitance(ref, "B")
    want = min(ref.amplifier.slew_rate_max, current * ref.amplifier.current_limit / c)
    assert ps.amplifier.rate_limit(c) == pytest.approx(want)
    if ps.amplifier.fast_fraction == 0.0:  # first order: τ ∝ 1/slew below the rate limit
        assert ps.amplifier.tau == pytest.approx(ref.amplifier.tau / slew, rel=0.02)
    assert replace(ps, amplifier=ref.amplifier) == ref


def test_the_lag_keeps_the_amplifier_speed(script):
    """``--lag R``: the base amplifier gets the output lag τ_o = R·τ, its 1 V step's 10–90 %
    slew still the scaled one (τ re-derived), nothing else changed."""
    from turntable_env.amplifier import measure_slew_rate

    plain = script.base_with_amplifier(0.3, 0.1).params.amplifier
    amp = script.base_with_amplifier(0.3, 0.1, 1.0).params.amplifier
    assert amp.lag_ratio == 1.0 and replace(amp, lag_ratio=0.0) == plain
    r = amp.step_response(0.0, 1.0, duration=600e-6, dt=2e-8)
    assert measure_slew_rate(r.time, r.output, 0.0, 45.0) == pytest.approx(0.3 * 0.9e6, rel=3e-3)


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["missing.csv"], "missing.csv"),
        (["{csv}"], "bad.csv:1"),  # the file's line
        (["{csv}", "--slew", "1,x"], "--slew"),
        (["{csv}", "--slew", "0"], "--slew"),
        (["{csv}", "--current", "0.5,0.2"], "--current"),
        (["{csv}", "--workers", "0"], "--workers"),
        (["{csv}", "--lag", "1.5"], "--lag"),
        (["{csv}", "--lag", "-0.1"], "--lag"),
    ],
)
def test_bad_input_exits_2_before_any_fit(script, tmp_path, capsys, argv, names):
    csv = tmp_path / "bad.csv"
    csv.write_text("a,b\n1,2\n")
    try:
        code = script.main([a.replace("{csv}", str(csv)) for a in argv])
    except SystemExit as exc:  # argparse's own refusal
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert names in err[-1]


def test_a_point_reports_the_fitted_factors_of_the_held_amplifier_fit(script, monkeypatch):
    """``profile_point``: the calibration frees every nominal factor but the amplifier's
    two (held at the point, on the base), and the point's ``factors`` are that fit's
    nominal factors as report.json gives them (``parameters.nominal``, each ``value``)."""
    from types import SimpleNamespace

    from turntable_env.calibration.trace_fit import AMPLIFIER_SCALES

    seen = {}
    fitted = {n: 0.5 + 0.1 * k for k, n in enumerate(script.PROFILE_NOMINAL)}

    def calibrate(files, *, base, nominal, **kw):
        seen.update(base=base, nominal=nominal, **kw)
        return SimpleNamespace(
            parameters={"nominal": {n: {"value": v, "std": 0.01} for n, v in fitted.items()}},
            diagnosis={"error_nominal": 11.1, "error_fit_portion": 19.2, "noise_floor": 2.82,
                       "target": 18.6})  # fmt: skip

    monkeypatch.setattr(script, "calibrate_traces", calibrate)
    row = script.profile_point("trace.csv", 0.3, 0.1, 1, 2)
    assert seen["nominal"] == script.PROFILE_NOMINAL
    assert not set(AMPLIFIER_SCALES) & set(seen["nominal"]) and seen["seed"] == 2
    assert seen["base"].params == script.base_with_amplifier(0.3, 0.1).params
    assert row["factors"] == fitted
    assert (row["heldout_nm"], row["fit_portion_nm"]) == (11.1, 19.2)
