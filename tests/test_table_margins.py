"""experiments/table_reports.py --margins: how far each signature rule was from deciding a
round otherwise (a decision has a margin). The rules are identify's: ≥ SIGNIFICANT_NATS on
a candidate's own groups, with its strongest direction pair left out and over all
signature groups, a trace change of at least the noise floor, a lead of TIE_NATS over the
runner-up, and the trace's verdict (z > −Z_TRACE in the first round, z ≥ Z_TRACE after)."""

from __future__ import annotations

import math

import pytest
from conftest import experiment

from turntable_env.calibration.identify import SIGNIFICANT_NATS, TIE_NATS
from turntable_env.calibration.trace_fit import Z_HELDOUT, Z_TRACE


def _cand(effect, own, total, size, loo=None, at_neutral=False):
    return {"effect": effect, "declared_nats": own, "total_nats": total,
            "declared_nats_leave_one_out": own if loo is None else loo,
            "size_over_floor": size, "at_neutral": at_neutral, "objective": 1.0,
            "significance_nats": SIGNIFICANT_NATS}  # fmt: skip


def _report(*rounds):
    return {"diagnosis": {"signatures": {"rounds": list(rounds)}}}


@pytest.fixture(scope="module")
def tr():
    return experiment("table_reports")


def test_a_named_effect_carries_its_margin_on_every_rule_it_passed(tr):
    named = _cand("friction_asymmetry", 9.24, 9.3, 111.0, loo=5.52)
    rnd = {"round": 1, "candidates": [named, _cand("friction_wear", 1.0, 1.0, 3.0)],
           "decision": {"named": "friction_asymmetry", "margin_nats": 8.0},
           "trace_test": {"z": 3.76}}  # fmt: skip
    (r,) = tr.margins(_report(rnd))
    m = r["margins"]
    assert r["role"] == "named" and r["effect"] == "friction_asymmetry"
    assert m["own"] == pytest.approx(9.24 - SIGNIFICANT_NATS)
    assert m["loo"] == pytest.approx(5.52 - SIGNIFICANT_NATS)
    assert m["lead"] == pytest.approx(8.0 - TIE_NATS)
    assert m["z"] == pytest.approx(3.76 + Z_TRACE)  # against −Z_TRACE in the first round
    # 1.02 nats above the leave-one-out bar is within THIN of it: the verdict is thin there
    assert r["thin"] == ["loo"]


def test_a_later_round_is_judged_against_the_positive_trace_bar(tr):
    rnd = {"round": 2, "candidates": [_cand("piezo_hysteresis", 24.1, 17.7, 53.0)],
           "decision": {"named": "piezo_hysteresis", "margin_nats": math.inf,
                        "rejected": "needs 5% and z ≥ 2"},
           "trace_test": {"z": 0.33}}  # fmt: skip
    (r,) = tr.margins(_report(rnd))
    assert r["role"] == "rejected"
    assert r["margins"]["z"] == pytest.approx(0.33 - Z_TRACE)
    assert "lead" not in r["margins"]  # no runner-up: no lead to report
    assert r["thin"] == []  # rejected 1.67 z below its bar: not thin


@pytest.mark.parametrize(
    ("size", "own", "thin"),
    [
        (0.65, 6.0, ["size"]),  # kept out by the trace-size rule alone, within a factor 2
        (0.3, 6.0, []),  # … far below it
        (2.0, 3.0, ["own", "all"]),  # short of significance by 1.5 nats on every rule
        (2.0, 0.2, []),  # 4.3 nats short: out whatever the other rules say
    ],
)
def test_the_nearest_unnamed_candidate_is_thin_only_where_every_failed_rule_was_close(
    tr, size, own, thin
):
    rnd = {"round": 1, "decision": {"named": None, "margin_nats": 0.0},
           "candidates": [_cand("piezo_hysteresis", own, own, size),
                          _cand("friction_wear", -1.0, -1.0, 5.0),
                          _cand("sensor_drift", 50.0, 50.0, 9.0, at_neutral=True)]}  # fmt: skip
    (r,) = tr.margins(_report(rnd))
    # the candidate best at its neutral value is never the one a round turns on
    assert r["role"] == "nearest" and r["effect"] == "piezo_hysteresis"
    assert r["thin"] == thin


def test_a_rejection_by_the_trace_near_its_bar_is_thin(tr):
    rnd = {"round": 1, "candidates": [_cand("piezo_hysteresis", 44.1, 43.2, 120.0)],
           "decision": {"named": "piezo_hysteresis", "margin_nats": math.inf,
                        "rejected": "the trace contradicts its signature"},
           "trace_test": {"z": -2.59}}  # fmt: skip
    (r,) = tr.margins(_report(rnd))
    assert r["margins"]["z"] == pytest.approx(-2.59 + Z_TRACE) and r["thin"] == ["z"]


def test_a_strict_json_report_reads_its_nulls_as_not_computed(tr):
    """report.json writes NaN and infinities as null (stop 69): a candidate that was not
    searched (objective null) is left out, a lead over no runner-up (null) is none, and a
    null size is not a number, not a crash."""
    named = {**_cand("piezo_creep", 12.0, 12.0, None), "significant": True}
    unrun = {**_cand("vibration", 0.0, 0.0, 0.0), "objective": None, "significant": False}
    rnd = {"round": 1, "candidates": [named, unrun],
           "decision": {"named": "piezo_creep", "margin_nats": None},
           "trace_test": {"z": 1.0}}  # fmt: skip
    (r,) = tr.margins(_report(rnd))
    assert r["effect"] == "piezo_creep" and "lead" not in r["margins"]
    assert math.isnan(r["margins"]["size"])
    (row,) = tr.rounds(_report(rnd))
    assert row["m"] == 1 and math.isnan(row["size"])


def _verdict(z, gain, named=False, **kw):
    return {"effect": "friction_wear", "z": z, "z_min": 3.0, "gain": gain,
            "min_improvement": 0.05, "named": named, "consistent": None, "pinned": "",
            "refit_backing": "", "undecided": False, **kw}  # fmt: skip


@pytest.mark.parametrize(
    ("verdict", "role", "blocked", "thin"),
    [
        # named by the trace, 0.4 z above its bar: the name rests on a thin margin
        (_verdict(3.4, 0.131, named=True, consistent=True), "named", [], ["z"]),
        (_verdict(5.0, 0.131, named=True, consistent=True), "named", [], []),
        # the third plant's contact wear (stop 85): +13.1 %, z +2.7 — nearly named
        (_verdict(2.7, 0.131), "not named", [], ["z"]),
        (_verdict(0.5, 0.131), "not named", [], []),  # 2.5 z short: out
        (_verdict(2.7, 0.035), "not named", [], ["gain", "z"]),  # short on both, in reach
        (_verdict(2.7, 0.0), "not named", [], []),  # no gain at all: not nearly named
        # a yes/no rule blocked it: not nearly named whatever z says
        (_verdict(3.2, 0.131, consistent=False), "not named", ["portions disagree"], []),
        (_verdict(2.9, 0.131, refit_backing="gain 0.4 nats, under 2.0: not backed"),
         "not named", ["features not backed"], []),
        (_verdict(2.9, 0.131, pinned="beta at its bound"), "not named",
         ["main parameter at a bound"], []),
    ],
)
def test_the_trace_routes_verdicts_carry_their_margins(tr, verdict, role, blocked, thin):
    """The held-out trace route's graded rules (gain ≥ its bar, z ≥ its bar) get margins as
    the signature route's do; a candidate blocked by a yes/no rule is not 'nearly named'."""
    rnd = {"round": 1, "candidates": [], "decision": {"named": None},
           "trace_verdicts": [verdict]}  # fmt: skip
    (r,) = tr.trace_margins(_report(rnd))
    assert r["role"] == role and r["blocked"] == blocked and r["thin"] == thin
    assert r["margins"]["z"] == pytest.approx(verdict["z"] - 3.0)
    assert r["margins"]["gain"] == pytest.approx(verdict["gain"] - 0.05)


def test_a_report_before_the_trace_route_has_no_trace_margins(tr):
    rnd = {"round": 1, "candidates": [_cand("piezo_creep", 12.0, 12.0, 4.0)],
           "decision": {"named": "piezo_creep", "margin_nats": 5.0}}  # fmt: skip
    assert tr.trace_margins(_report(rnd)) == []


def test_a_trace_verdict_without_its_bar_is_judged_against_the_held_out_one(tr):
    """The trace route's z bar is Z_HELDOUT (the signature route's trace check uses
    Z_TRACE): a verdict that does not record its bar is measured against Z_HELDOUT."""
    v = {k: x for k, x in _verdict(2.7, 0.131).items() if k != "z_min"}
    rnd = {"round": 1, "candidates": [], "decision": {"named": None}, "trace_verdicts": [v]}
    (r,) = tr.trace_margins(_report(rnd))
    assert r["margins"]["z"] == pytest.approx(2.7 - Z_HELDOUT) and r["thin"] == ["z"]
