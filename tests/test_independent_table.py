"""experiments/independent_calibration.py runs a table in parts: a run into an ``--out``
that holds an earlier run's results.json keeps that run's rows of the other traces, and
replaces the rows of the traces it calibrates (the calibration itself is stubbed here)."""

from __future__ import annotations

import json

import pytest
from conftest import experiment


def _row(trace: str, after: float) -> dict:
    return {"trace": trace, "injected": [], "expected": ["none"], "selected": [],
            "decided_by": [], "before_nm": 100.0, "nominal_nm": after, "after_nm": after,
            "floor_nm": 3.0, "target_nm": 20.0, "met": after <= 20.0, "structured": False,
            "flagged": False, "wall_s": 1.0}  # fmt: skip


@pytest.fixture
def table(tmp_path, monkeypatch):
    mod = experiment("independent_calibration")
    traces = tmp_path / "traces"
    traces.mkdir()
    files = {f"{n}.csv": {"effects": {}} for n in ("a", "b", "c")}
    (traces / "truth.json").write_text(json.dumps({"files": files}))
    monkeypatch.setattr(mod, "_calibrate_one", lambda job: _row(job["name"], 5.0))
    return mod, traces, tmp_path / "out"


def _run(mod, traces, out, *only):
    return mod.main(["--traces", str(traces), "--out", str(out), "--only", *only])


def test_a_table_run_in_parts_keeps_every_parts_rows(table):
    mod, traces, out = table
    out.mkdir()
    (out / "results.json").write_text(json.dumps([_row("a", 30.0), _row("b", 30.0)]))
    assert _run(mod, traces, out, "b", "c") == 0
    rows = {r["trace"]: r for r in json.loads((out / "results.json").read_text())}
    assert set(rows) == {"a", "b", "c"}
    assert rows["a"]["after_nm"] == 30.0  # not rerun: the earlier run's row
    assert rows["b"]["after_nm"] == rows["c"]["after_nm"] == 5.0  # rerun: this run's


@pytest.mark.parametrize(
    ("text", "why"),
    [("[{\"trace\": \"a\"}", "line 1 column"), ("{\"trace\": \"a\"}", "not a list of table rows")],
)
def test_a_broken_results_file_is_refused_before_any_work(table, capsys, text, why):
    mod, traces, out = table
    out.mkdir()
    (out / "results.json").write_text(text)
    with pytest.raises(SystemExit) as e:
        _run(mod, traces, out, "a")
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "results.json" in err and why in err
    assert (out / "results.json").read_text() == text  # untouched


@pytest.mark.parametrize("selected", [[], ["friction_asymmetry"]])
def test_a_row_says_when_its_protocol_gives_the_effect_no_signature(capsys, selected):
    """A row whose expected effect the trace's protocol gives no signature says so beside
    what was named, where it was not named; the verdict is the acceptance's either way
    (an effect not named fails its row)."""
    mod = experiment("independent_calibration")
    row = {**_row("asym", 5.0), "injected": ["friction_asymmetry"],
           "expected": ["friction_asymmetry"], "selected": selected,
           "decided_by": ["signature"] * len(selected), "untestable": ["friction_asymmetry"]}
    assert mod.print_row(row)["pass"] is bool(selected)
    out = capsys.readouterr().out
    assert ("(friction_asymmetry: no signature on this protocol)" in out) is not selected
