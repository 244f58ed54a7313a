"""``experiments/drive_reading.py`` (issue 31, stop 71): a reading's fingerprint follows the
model's drive — equal readings give equal digests, a level moved by a microvolt or a
jump moved by a nanosecond does not — and its command line refuses a missing trace with
exit 2, one line."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import experiment

from turntable_env.calibration.segments import read_drive, segment_trace


@pytest.fixture(scope="module")
def script():
    return experiment("drive_reading")


def _sampled(fs=10e3, f=2000.0, periods=6, hold=0.0201234):
    t = np.arange(0.0, 2 * hold + periods / f, 1.0 / fs)
    ph = (t - hold) * f
    return t, np.where((ph >= 0) & (ph < periods), 3.0 * (ph % 1.0) / 0.98, 0.0).clip(0, 3.0)


def test_the_fingerprint_follows_the_models_drive(script):
    t, u = _sampled()
    r = read_drive(t, u)
    segs = segment_trace(r, t[-1])
    assert script.fingerprint(r, segs) == script.fingerprint(read_drive(t, u.copy()), segs)
    moved = replace(r, level=r.level + 1e-6)
    later = replace(r, jumps=r.jumps + 1e-9)
    assert script.fingerprint(moved, segs) != script.fingerprint(r, segs)
    assert script.fingerprint(later, segs) != script.fingerprint(r, segs)
    # the fit's drive where it is not the reading's (a declared linear flyback's corners)
    cornered = (np.append(r.time, r.time[-1] + 1e-6), np.append(r.level, r.level[-1]))
    assert script.fingerprint(r, segs, cornered) != script.fingerprint(r, segs)


def test_a_missing_trace_is_refused_with_exit_2(script, tmp_path, capsys):
    assert script.main([str(tmp_path / "absent.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("drive_reading:") and "absent.csv" in err and "\n" not in err


def test_floors_prints_the_noise_floor_the_fit_reads(script, tmp_path, capsys):
    """``--floors`` prints each file's noise floor as the calibration's own reading of the
    file gives it (`trace_fit.trace_data`), so two commits' floors can be compared."""
    from turntable_env.calibration.measurement import load_measurement
    from turntable_env.calibration.trace_fit import trace_data
    from turntable_env.cli import main as cli

    p = tmp_path / "lab.csv"
    assert cli(["virtual-lab", "--protocol", "standard", "--out", str(p)]) == 0
    capsys.readouterr()
    assert script.main(["--floors", str(p)]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if "noise floor" in ln)
    td = trace_data(load_measurement(p))
    assert f"noise floor {td.floor:.6g} nm ({td.floor_source})" in line
