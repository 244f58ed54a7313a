"""experiments/landing_accuracy.py: bad arguments end in exit 2 and one line naming the
argument and its value, before any simulation (docs/performance.md, stop 82)."""

from __future__ import annotations

import pytest
from conftest import experiment


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["--repeats", "0"], "--repeats=0"),
        (["--bounds", "1"], "--bounds=1.0"),
        (["--bounds", "0.5"], "--bounds=0.5"),
        (["no_such_trace.csv"], "no_such_trace.csv"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(argv, names, capsys):
    script = experiment("landing_accuracy")
    assert script.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and names in err[0]
