"""experiments/calibration_stages.py: a calibration's progress lines split its wall time
into its stages (issue 31's 5-minute figure, docs/performance.md stop 81)."""

from __future__ import annotations

import pytest
from conftest import experiment

# progress lines as `turntable calibrate` prints them (trace_fit, identify), one per stage
LINES = [
    ("1 trace(s), 17 segments; noise floor 2.88 nm", "start-up and the prior model"),
    ("prior model: held-out error 124 nm", "start-up and the prior model"),
    ("global stage: 64 Sobol points on 2 process(es)", "global stage and the starts"),
    ("  start 3: held-out 5.24 nm (cost 42.63, 25 iterations)", "global stage and the starts"),
    ("  hop 0 (±0.5 σ): costs 25.75, 35.68 against 37.78 — kept", "basin hops"),
    ("nominal model: held-out error 4.29 nm", "basin hops"),
    ("  signature piezo_creep            gain     0.0 nats on relaxation", "signature round"),
    ("  candidate piezo_creep            held-out 4.29 nm", "candidates on the trace"),
    ("friction_wear: held-out 4.29 vs nominal refit 4.29 nm", "refits, verdicts and the report"),
    ("selected effects: amplifier_dynamics; held-out error 124 → 4.29 nm",
     "refits, verdicts and the report"),
]  # fmt: skip


@pytest.fixture(scope="module")
def script():
    return experiment("calibration_stages")


@pytest.mark.parametrize(("line", "stage"), LINES)
def test_each_progress_line_closes_its_stage(script, line, stage):
    assert script.stage_of(line) == stage


def test_the_stages_split_the_whole_wall_time(script):
    """Each gap goes to the stage of the line that ends it; the stages sum to the total."""
    timed = [(1.0 + 2.0 * i, line) for i, (line, _) in enumerate(LINES)]
    end = timed[-1][0] + 5.0
    seconds = script.stage_seconds(timed, end)
    assert sum(seconds.values()) == pytest.approx(end)
    assert seconds["start-up and the prior model"] == pytest.approx(1.0 + 2.0)
    assert seconds["basin hops"] == pytest.approx(4.0)
    assert seconds["refits, verdicts and the report"] == pytest.approx(2.0 * 2 + 5.0)
