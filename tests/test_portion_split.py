"""Each portion's holds counted by the direction of the motion before them, and a portion
that holds one direction only named (issue 31, stop 63; ``segments.holds_by_motion`` and
``segments.one_sided`` since stop 87, when the split began to use them);
``experiments/portion_split.py`` counts the scans by sense too, and its command line
refuses a missing trace with exit 2."""

from __future__ import annotations

import pytest
from conftest import experiment

from turntable_env.calibration.segments import Segment, holds_by_motion, one_sided


@pytest.fixture(scope="module")
def script():
    return experiment("portion_split")


def _protocol(portions: str) -> list[Segment]:
    """hold, then (+burst, hold, −burst, hold) per pair; the holds' portions in order."""
    segs = [Segment(0.0, 1.0, "hold", portion="fit")]
    k = 1
    for q_plus, q_minus in zip(portions[::2], portions[1::2], strict=True):
        for direction, q in ((1, q_plus), (-1, q_minus)):
            segs.append(Segment(k, k + 1.0, "steps", direction, 2.0, 100.0))
            segs.append(Segment(k + 1.0, k + 2.0, "hold", portion="fit" if q == "f" else "heldout"))
            k += 2
    return segs


@pytest.mark.parametrize(
    ("portions", "fit", "heldout", "sided"),
    [
        ("fhfhfh", {1: 3, 0: 1}, {-1: 3}, True),  # one "hold" condition, alternating
        ("fhhffh", {1: 2, -1: 1, 0: 1}, {1: 1, -1: 2}, False),  # each direction alternating
    ],
)
def test_holds_are_counted_by_the_motion_before_them(portions, fit, heldout, sided):
    c = holds_by_motion(_protocol(portions))
    assert dict(c["fit"]) == fit and dict(c["heldout"]) == heldout
    assert one_sided(c) is sided


def test_a_trace_with_holds_after_one_direction_only_is_not_one_sided():
    c = holds_by_motion(_protocol("ff")[:3])  # hold, +burst, hold
    assert not one_sided(c)


def test_scans_are_counted_by_their_sense(script):
    """Up, down, up alternated as one condition: the fit portion scans up only."""
    segs = [
        Segment(float(k), k + 1.0, "scan", d, 3.0, portion=q)
        for k, (d, q) in enumerate(((1, "fit"), (-1, "heldout"), (1, "fit")))
    ]
    c = script.scan_counts(segs)
    assert dict(c["fit"]) == {1: 2} and dict(c["heldout"]) == {-1: 1}
    assert one_sided(c)


def test_a_missing_trace_exits_2(script, tmp_path, capsys):
    assert script.main([str(tmp_path / "absent.csv")]) == 2
    err = capsys.readouterr().err
    assert "absent.csv: no such trace" in err and err.count("\n") == 1
