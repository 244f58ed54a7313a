"""docs/thesis.md's ledger is what ``experiments/thesis_reproduction.py`` prints, and its
verdicts follow from its numbers (slow: about 25 s of full-model runs)."""

from pathlib import Path

import pytest
from conftest import experiment

ROOT = Path(__file__).resolve().parents[1]


def _script():
    return experiment("thesis_reproduction")


@pytest.mark.slow
def test_the_docs_ledger_is_what_the_script_prints():
    mod = _script()
    rows = mod.ledger()
    page = (ROOT / "docs" / "thesis.md").read_text(encoding="utf-8")
    block = page.split("<!-- ledger:begin -->\n", 1)[1].split("\n<!-- ledger:end -->", 1)[0]
    assert block.strip() == mod.markdown(rows).strip()
    by = {(r["figure"], r["thesis"]): r for r in rows}
    # the thesis's own numbers that the model must meet (§4.1.2, §4.1.3)
    for key, quoted in (("slew_1V_step_V_per_s", 0.9e6), ("slew_3V_step_V_per_s", 2.7e6)):
        (r,) = [r for r in rows if key in r["numbers"]]
        assert r["numbers"][key] == pytest.approx(quoted, rel=0.01) and r["agrees"] == "yes"
    cal = [r for r in rows if any(k.startswith("calibrated_") for k in r["numbers"])]
    assert len(cal) == 3 and all(r["agrees"] == "yes" for r in cal)
    for r in rows:  # a step's verdict follows from its ratio to the measured step
        steps = {k: v for k, v in r["numbers"].items() if k.endswith("_step_m")}
        for k, v in steps.items():
            ratio = v / (0.37e-6 if "_one_" in k else 0.30e-6)
            assert (r["agrees"] == "yes") == (abs(ratio - 1.0) < 0.1), (k, ratio, r["agrees"])
    assert by[("Eq. 4.1–4.2", "0.53 V → x_table = 1.5 µm")]["agrees"] == "yes"
