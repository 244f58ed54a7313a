"""``experiments/flyback_reading.py`` (issue 31, stop 72): its generator's sawtooth ramps to
the amplitude and flies back within (1 − a)/f, its staircase puts one jump per flyback
sample and leaves the ramp alone, and its command line refuses bad rates with exit 2, one
line."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import experiment


@pytest.fixture(scope="module")
def script():
    return experiment("flyback_reading")


@pytest.mark.parametrize(
    ("fs", "f", "a", "samples"), [(10e3, 50.0, 0.99, 2), (25e3, 50.0, 0.99, 5)]
)
def test_the_staircase_has_a_jump_per_flyback_sample(script, fs, f, a, samples):
    t = np.arange(0.0, 2 * script.HOLD + script.PERIODS / f, 1.0 / fs)
    u = script.sawtooth(t, f, a, 6.0)
    assert u.max() == pytest.approx(6.0, abs=6.0 * f / (a * fs))  # the ramp's last sample
    bt, bu = script.staircase(t, u)
    jumps = np.flatnonzero(np.diff(bt) < 1e-8)
    # each flyback falls on `samples` or `samples` + 1 intervals (its phase on the clock)
    assert script.PERIODS * samples <= jumps.size <= script.PERIODS * (samples + 1)
    assert np.all(np.diff(bu)[jumps] < 0.0)  # only the flyback's changes are jumps
    assert bu[-1] == u[-1] and bt[-1] == t[-1]


@pytest.mark.parametrize("rates", ["fast", "10", "1e7", ""])
def test_bad_rates_are_refused_with_exit_2(script, capsys, rates):
    assert script.main(["--rates", rates]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--rates" in err


def test_the_held_reading_jumps_by_the_samples_change(script):
    """``held`` (the reading before stop 89) keeps each sample's level to the interval's
    middle: its jump is the samples' change, one ramp interval short of the span that
    ``read_drive`` runs the ramp on to."""
    f, a, fs, amp = 2000.0, 0.98, 10e3, 6.0
    t = np.arange(0.0, 2 * script.HOLD + script.PERIODS / f, 1.0 / fs)
    u = script.sawtooth(t, f, a, amp)
    jumps = script.read_drive(t, u).jumps
    bt, bu = script.held(t, u, jumps)
    at = np.flatnonzero(np.diff(bt) < 1e-8)
    assert at.size == jumps.size
    i = np.searchsorted(t, jumps) - 1
    np.testing.assert_allclose(np.diff(bu)[at], u[i + 1] - u[i])


@pytest.mark.parametrize("phases", ["-1", "1001"])
def test_bad_phase_counts_are_refused_with_exit_2(script, capsys, phases):
    assert script.main(["--phases", phases]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--phases" in err
