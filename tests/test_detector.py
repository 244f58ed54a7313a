"""Detector (Eq. 4.1–4.2) against the measured numbers of §4.1.3."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from turntable_env.detector import Detector

DET = Detector()


@pytest.mark.parametrize(
    ("volts", "steps", "x_um", "per_step_um"),
    [(0.53, 5, 1.5, 0.30), (1.19, 9, 3.4, 0.37)],
    ids=["two-directional", "one-directional"],
)
def test_thesis_stepping_measurements(volts, steps, x_um, per_step_um):
    x = float(DET.table_displacement(volts))
    assert x * 1e6 == pytest.approx(x_um, abs=0.05)
    assert x / steps * 1e6 == pytest.approx(per_step_um, abs=0.005)


@given(angle=st.floats(min_value=-5e-4, max_value=5e-4, allow_nan=False))
def test_forward_inverse_roundtrip_in_linear_range(angle):
    v = DET.voltage(angle)
    assert float(DET.angle(v)) == pytest.approx(angle, rel=1e-9, abs=1e-15)


def test_saturation_beyond_linear_range():
    assert DET.saturation_voltage == pytest.approx(0.2e-3 / 9.9e-5)
    big = 2 * DET.angle_range
    assert float(DET.voltage(big)) == pytest.approx(DET.saturation_voltage)
    assert float(DET.voltage(-big)) == pytest.approx(-DET.saturation_voltage)
    assert bool(DET.is_saturated(DET.voltage(big)))
    assert not bool(DET.is_saturated(DET.voltage(0.5 * DET.angle_range)))


def test_noise_is_seeded_and_sized():
    noisy = Detector(noise_std=1e-3)
    a = noisy.voltage(np.zeros(20000), rng=np.random.default_rng(1))
    b = noisy.voltage(np.zeros(20000), rng=np.random.default_rng(1))
    assert np.array_equal(a, b)
    assert np.std(a) == pytest.approx(1e-3, rel=0.03)
    assert np.all(noisy.voltage(np.zeros(5)) == 0.0)  # no rng: noise off


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: Detector(sensitivity=0.0), "sensitivity"),
        (lambda: Detector(noise_std=-1.0), "noise_std"),
        (lambda: DET.voltage(np.array([np.nan])), "angle"),
        (lambda: DET.voltage(1.0), "angle"),
        (lambda: DET.angle(np.inf), "voltage"),
    ],
)
def test_detector_rejects_bad_input(call, field):
    with pytest.raises(ValueError, match=field):
        call()


@given(
    angle=st.floats(min_value=-5e-4, max_value=5e-4, allow_nan=False),
    tilt=st.floats(min_value=0.5, max_value=1.0),
    gain=st.floats(min_value=0.5, max_value=2.0),
)
def test_table_angle_inverts_the_labs_reading_for_a_known_rig(angle, tilt, gain):
    """A lab that knows its rig's mirror tilt and photodiode gain recovers the table angle
    from its Eq. 4.1 reading (the thesis calibration's rig reads 0.82 of it)."""
    det = Detector(tilt_factor=tilt, gain=gain)
    reading = det.angle(det.unclipped_voltage(np.array(angle)))
    assert float(det.table_angle(reading)) == pytest.approx(angle, rel=1e-9, abs=1e-15)
    assert DET.table_angle(reading) is reading  # the nominal rig: the reading itself
