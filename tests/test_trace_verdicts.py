"""The held-out trace error's rules on a round's best candidates (:func:`trace_fit._accept_one`)
are recorded, one verdict per rule, so a report says why a candidate that lowered the
held-out error was not named (the second independent plant's friction asymmetry screened
at 10.6 nm against the nominal 15.0 nm at stop 56, and its report did not say why it was
not named). The contract: a candidate is named only when it gains ``min_improvement``
over the model without it, lies 3 σ from neutral, agrees between portions and keeps its
main parameter off its bound — the first such candidate, the rest not tried."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from turntable_env.calibration import trace_fit
from turntable_env.calibration.calibrate import _md_trace_verdicts
from turntable_env.calibration.trace_fit import LocalFit


def _fit(heldout: float, effects: dict | None = None) -> LocalFit:
    return LocalFit(np.zeros(2), effects or {}, np.ones(2), {}, heldout, heldout, heldout, 1)


@pytest.fixture
def rules(monkeypatch):
    """Each candidate's fate on each rule, set by the test; the current model's refit
    (no free effect) stays at 15 nm."""
    fate: dict[str, dict] = {}

    def local_fit(_p, _x, effects, free_effects=(), **_k):
        new = [n for n in free_effects if n in fate]
        return _fit(fate[new[-1]]["joint"] if new else 15.0, effects)

    monkeypatch.setattr(trace_fit, "local_fit", local_fit)
    monkeypatch.setattr(trace_fit, "is_significant", lambda f, n: fate[n]["sig"])
    monkeypatch.setattr(trace_fit, "consistent",
                        lambda _p, f, n, _pool: (fate[n]["ok"], f" {n}: portions"))  # fmt: skip
    monkeypatch.setattr(trace_fit, "main_at_bound", lambda n, _v: fate[n].get("pinned", ""))
    monkeypatch.setattr(trace_fit, "_at_bounds_effect", lambda _c, _n: [])
    monkeypatch.setattr(trace_fit, "_from_neutral", lambda _f, n: f"{n} σ")
    return fate


def _accept(fate, names):
    verdicts: list[dict] = []
    top = [(n, _fit(fate[n]["screen"], {n: {"p": 0.1}})) for n in names]
    out = trace_fit._accept_one(SimpleNamespace(), _fit(15.0), top, [], 0.05, [],
                                lambda _m: None, None, verdicts)  # fmt: skip
    return out, verdicts


@pytest.mark.parametrize(
    ("rule", "value"),
    [("gain", 14.5), ("sig", False), ("ok", False), ("pinned", "alpha at 1")],
)
def test_a_candidate_failing_one_rule_is_not_named_and_the_rule_is_recorded(rules, rule,
                                                                            value):  # fmt: skip
    fate = {"screen": 10.6, "joint": 10.5, "sig": True, "ok": True}
    if rule == "gain":  # screened and refitted at 14.5 nm
        fate.update(screen=value, joint=value)
    else:
        fate[rule] = value
    rules["friction_asymmetry"] = fate
    out, (v,) = _accept(rules, ["friction_asymmetry"])
    assert out is None and not v["named"]
    assert v["baseline_rms"] == 15.0
    if rule == "gain":  # 14.5 against 15.0: a 3.3 % gain, under the 5 %
        assert v["gain"] == pytest.approx(1 - 14.5 / 15.0) and v["gain"] < v["min_improvement"]
    elif rule == "sig":
        assert v["three_sigma"] is False and v["consistent"] is None  # not tested past it
        assert v["from_neutral"] == "friction_asymmetry σ"
    elif rule == "ok":
        assert v["three_sigma"] and v["consistent"] is False
    else:
        assert v["pinned"] == "alpha at 1"


def test_the_first_candidate_passing_every_rule_is_named_and_the_rest_not_tried(rules):
    rules["friction_wear"] = {"screen": 10.0, "joint": 9.9, "sig": False, "ok": True}
    rules["friction_asymmetry"] = {"screen": 10.6, "joint": 10.5, "sig": True, "ok": True}
    rules["vibration"] = {"screen": 11.0, "joint": 9.0, "sig": True, "ok": True}
    out, verdicts = _accept(rules, ["friction_wear", "friction_asymmetry", "vibration"])
    assert out is not None and out[0] == "friction_asymmetry"
    assert [v["effect"] for v in verdicts] == ["friction_wear", "friction_asymmetry"]
    assert [v["named"] for v in verdicts] == [False, True]
    assert verdicts[1]["heldout_rms"] == 10.5  # the joint refit, better than the screen


def test_report_tables_each_rule_per_candidate():
    rows = [
        {"effect": "friction_wear", "heldout_rms": 9.9, "baseline_rms": 15.0, "gain": 0.34,
         "min_improvement": 0.05, "three_sigma": False, "consistent": None, "note": "",
         "pinned": "", "named": False, "from_neutral": "beta 1.2 σ from neutral"},
        {"effect": "friction_asymmetry", "heldout_rms": 10.5, "baseline_rms": 15.0,
         "gain": 0.3, "min_improvement": 0.05, "three_sigma": True, "consistent": False,
         "note": " alpha: fit 0.08 ± 0.01, held-out -0.02 ± 0.03", "pinned": "",
         "named": False},
    ]  # fmt: skip
    text = "\n".join(_md_trace_verdicts(rows, "nm"))
    assert ("| friction_wear | 9.9 | 15 | +34.0% (≥ 5%) | no (beta 1.2 σ from neutral) | — | "
            "no | no |") in text
    assert ("| friction_asymmetry | 10.5 | 15 | +30.0% (≥ 5%) | yes | no (alpha: fit 0.08 ± "
            "0.01, held-out -0.02 ± 0.03) | no | no |") in text
    assert _md_trace_verdicts(None, "nm") == [] and _md_trace_verdicts([], "nm") == []
