"""The trace calibrator's reading of a lab file (issue 19): drive, segments, portions,
noise floor, anchoring, identifiability and argument checks — on synthetic data whose
answer is known by construction."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from turntable_env.calibration.calibrate import calibrate
from turntable_env.calibration.identify import main_at_bound
from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.residual import Anchoring, condition_shares, noise_floor
from turntable_env.calibration.segments import (
    flyback_corners,
    holds_by_motion,
    one_sided,
    read_drive,
    segment_trace,
    split_portions,
)
from turntable_env.calibration.trace import simulate_trace
from turntable_env.calibration.trace_fit import (
    correlation_length,
    identifiable_effects,
    trace_data,
)
from turntable_env.calibration.virtual_lab import protocol_drive, run_virtual_lab
from turntable_env.params import get_parameter_set
from turntable_env.plant import Plant


def _sampled_sawtooth(fs=20e3, f=100.0, amp=2.0, a=0.95, periods=6, hold=0.02, lsb=None):
    """A function generator's sawtooth sampled at fs: rise over a/f, drop within one
    sample, holds before and after."""
    t = np.arange(0.0, 2 * hold + periods / f, 1.0 / fs)
    ph = ((t - hold) * f) % 1.0
    u = np.where((t >= hold) & (t < hold + periods / f), amp * np.minimum(ph / a, 1.0), 0.0)
    u = np.where(ph > a, 0.0, u) * (t < hold + periods / f)
    if lsb is not None:
        u = np.round(u / lsb) * lsb
    return t, u


@pytest.mark.parametrize("lsb", [None, 20.0 / 4096])  # ideal, and a 12-bit ±10 V DAQ
def test_single_sample_drops_are_read_as_steps_with_their_timing_uncertainty(lsb):
    t, u = _sampled_sawtooth(lsb=lsb)
    r = read_drive(t, u)
    assert r.recording == "sampled"
    assert r.jumps.size == 6  # one flyback per period
    assert r.timing_uncertainty == pytest.approx(0.5 / 20e3)
    # the model's drive drops within 1 ns, not over a 50 µs sample interval
    tj = r.jumps[0]
    before, after = np.interp([tj - 2e-9, tj + 1e-9], r.time, r.level)
    assert before == pytest.approx(2.0, abs=0.05) and after == pytest.approx(0.0, abs=0.01)


def _linear_flyback_sawtooth(f, a, periods, fs=20e3, amp=3.0, hold=0.0201234, sign=1.0):
    """A sawtooth whose flyback falls linearly over (1 − a)/f, sampled at fs with the
    flybacks at an arbitrary phase of the samples (as a generator's clock runs), between
    two holds; ``sign`` −1 runs it backwards (ramp down, fly back up)."""
    t = np.arange(0.0, 2 * hold + periods / f, 1.0 / fs)
    ph = (t - hold) * f
    on = (ph >= 0) & (ph < periods)
    x = ph % 1.0
    u = np.where(x < a, x / a, (1.0 - x) / (1.0 - a)) * amp
    return t, np.where(on, sign * u, 0.0)


@pytest.mark.parametrize(
    ("f", "a", "periods"),
    [
        (200.0, 0.99, 4),  # a flyback of one sample interval
        (200.0, 0.97, 4),  # three: the third independent plant mixes these two at 200 Hz
        (200.0, 0.90, 3),
        (100.0, 0.95, 5),
        (2000.0, 0.99, 20),  # a tenth of a sample: read as one interval
        (200.0, 0.6, 4),  # resolved: read as a ramp flyback from the slower half
        (100.0, 0.99, 1),  # one period: its flyback of two samples is one flyback
    ],
)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_bursts_ramp_ratio_is_read_within_one_sample_of_flyback(f, a, periods, sign):
    """The ramp ratio a as read from a sampled drive: within one sample interval × f of
    the generator's (to a tenth of that where the flyback holds a whole sample, ≥ two
    intervals), the direction, frequency and amplitude right (the amplitude to the ramp's
    rise over a sample: the peak falls between samples), also for a single period."""
    t, u = _linear_flyback_sawtooth(f, a, periods, sign=sign)
    steps = [s for s in segment_trace(read_drive(t, u), t[-1]) if s.kind == "steps"]
    assert len(steps) == 1, steps
    s = steps[0]
    assert s.flyback_resolution == pytest.approx(s.frequency / 20e3)
    assert abs(s.ramp_ratio - a) <= s.flyback_resolution + 1e-9, (s.ramp_ratio, a)
    if (1.0 - a) / f >= 2.0 / 20e3 and s.flyback != "ramp":
        assert s.ramp_ratio == pytest.approx(a, abs=0.1 * s.flyback_resolution)
    assert s.direction == sign
    assert s.amplitude == pytest.approx(3.0, rel=0.01 + f / 20e3 / a)
    assert s.frequency == pytest.approx(f, rel=0.05) and s.periods == periods


def _jumps_read(r) -> np.ndarray:
    """The model drive's change across each jump the reading put in [V]."""
    before = np.interp(r.jumps - 2e-9, r.time, r.level)
    after = np.interp(r.jumps + 1e-9, r.time, r.level)
    return after - before


@pytest.mark.parametrize(
    ("fs", "f", "a"),
    [
        (10e3, 2000.0, 0.98),  # 5 samples a period (the third plant's axis-A trace)
        (25e3, 2000.0, 0.995),  # 12.5
        (20e3, 1250.0, 0.995),  # 16
        (10e3, 500.0, 0.995),  # 20: the run-on a sample's rise, 5 % of the span
    ],
)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_ramp_runs_on_to_a_flyback_between_samples(fs, f, a, sign):
    """A flyback within one sample interval is the generator's full span, not the samples'
    change: the ramp fills the interval but for the flyback's own (1 − a)/f, so the step
    read is the samples' change plus one interval of ramp, the span to within the share
    (1 − a)/a (`segments._ramp_on`; no sample falls within a flyback in these cases).
    Held flat to the middle, a 6 V, 2 kHz, a = 0.98 burst on a 10 kHz DAQ read as 4.9 V;
    the burst's amplitude is read from the same levels."""
    amp = 3.0
    t, u = _linear_flyback_sawtooth(f, a, 6, fs=fs, amp=amp, sign=sign)
    r = read_drive(t, u)
    spans = -sign * _jumps_read(r)
    samples = -sign * np.array([u[i + 1] - u[i] for i in np.searchsorted(t, r.jumps) - 1])
    inside = (r.jumps > 0.0201234 + 0.5 / f) & (r.jumps < 0.0201234 + 5.5 / f)
    assert inside.sum() == 5
    # the samples alone fall a ramp interval short; the reading is the span
    assert np.all(samples[inside] < amp * (1.0 - 0.9 * f / fs))
    assert spans[inside] == pytest.approx(amp, rel=(1.0 - a) / a + 1e-6)
    s = next(s for s in segment_trace(r, t[-1]) if s.kind == "steps")
    assert s.amplitude == pytest.approx(amp, rel=(1.0 - a) / a + 0.01)


def _generator_flybacks(f, a, periods, hold):
    """The generator's flybacks as (start, end) times [s] of each period's drop."""
    n = np.arange(periods)
    return hold + (n + a) / f, hold + (n + 1) / f


@pytest.mark.parametrize(
    ("fs", "f", "a", "periods"),
    [
        (10e3, 2000.0, 0.98, 4),  # the third plant's axis-A trace: 5 samples a period
        (10e3, 1000.0, 0.99, 6),
        (25e3, 2000.0, 0.99, 8),  # 12.5 samples a period: the phase moves each period
        (20e3, 500.0, 0.995, 3),
    ],
)
# the generator's start after a sample [intervals]
@pytest.mark.parametrize("offset", [0.0, 0.3, 0.75])
@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("lsb", [None, 20.0 / 4096])  # ideal, and a 12-bit ±10 V DAQ
def test_a_sawtooths_flybacks_are_read_where_they_land(fs, f, a, periods, offset, sign, lsb):
    """Every flyback of a burst lands on the level of the hold after it (the sawtooth's
    bottom, its offset): the ramp after each, run back to that level, says where the
    flyback ended, and the last one falls where the ramp before it reaches the level plus
    the span (`segments.landing_phase`). Each step is read within the generator's flyback
    (to the ramp's rise over it), where the interval's middle is up to half an interval
    off, and lands on the hold's level; at offset 0 every flyback ends on a sample (the
    third independent plant's clocks); a quantised drive's levels move the steps by the
    least significant bit over the ramp's rise in a sample."""
    hold = 0.02 + offset / fs
    t, u = _linear_flyback_sawtooth(f, a, periods, fs=fs, hold=hold, sign=sign)
    start, end = _generator_flybacks(f, a, periods, hold)
    assert not np.any((t[:, None] > start + 1e-12) & (t[:, None] < end - 1e-12))  # none inside
    rise = 3.0 / a * f / fs  # the ramp's rise in one sample interval [V]
    q = 0.0
    if lsb is not None:
        u, q = np.round(u / lsb) * lsb, lsb
    r = read_drive(t, u)
    assert r.jumps.size == periods
    tol = (2e-3 + 2.0 * q / rise) / fs  # segments.LANDING_EDGE, and the quantisation's share
    assert np.all(r.jumps >= start - tol) and np.all(r.jumps <= end + tol), (r.jumps - end) * fs
    after = np.interp(r.jumps + 1e-9, r.time, r.level)
    np.testing.assert_allclose(after, 0.0, atol=rise * tol * fs + q)  # the ramp over the edge
    before = sign * np.interp(r.jumps - 2e-9, r.time, r.level)
    assert np.all(before >= 3.0 - 2 * q - 1e-9) and np.all(before <= 3.0 / a + 2 * q + 1e-9)
    mid = read_drive(t, u, landing=False)  # each step at its interval's middle
    assert np.max(np.abs(mid.jumps - end)) >= np.max(np.abs(r.jumps - end))


@pytest.mark.parametrize(
    "shape",
    ["centred", "one_period"],  # a bottom that is not the hold's level; no earlier flyback
)
def test_a_flyback_whose_landing_the_samples_do_not_give_stays_at_mid_interval(shape):
    """Where the sawtooth's bottom is not the hold's level (a burst centred on it) or the
    burst has one flyback only, nothing places the step: it stays at the interval's
    middle, as read before."""
    fs, f, a = 10e3, 2000.0, 0.98
    periods = 1 if shape == "one_period" else 4
    t, u = _linear_flyback_sawtooth(f, a, periods, fs=fs, hold=0.02 + 0.3 / fs)
    if shape == "centred":
        on = (t >= 0.02 + 0.3 / fs) & (t < 0.02 + 0.3 / fs + periods / f)
        u = np.where(on, u - 1.5, 0.0)
    r = read_drive(t, u)
    i = np.searchsorted(t, r.jumps) - 1
    assert r.jumps.size >= 1
    np.testing.assert_allclose(r.jumps, 0.5 * (t[i] + t[i + 1]), atol=2e-9)


def test_a_file_with_the_generators_corners_is_not_run_on():
    """Rows off the sampling clock are the generator's corners (a file that adds a row at
    every drive breakpoint): the ramp ends there, and each step is the change the file
    records, held to the interval's middle as before."""
    t, u = _linear_flyback_sawtooth(2000.0, 0.98, 6, fs=10e3)
    hold, f, a, amp = 0.0201234, 2000.0, 0.98, 3.0
    corners = hold + (np.arange(6) + a) / f  # each ramp's top, just before its flyback
    t2 = np.concatenate([t, corners])
    u2 = np.concatenate([u, np.full(corners.size, amp)])
    order = np.argsort(t2)
    t2, u2 = t2[order], u2[order]
    r = read_drive(t2, u2)
    assert r.recording == "sampled" and r.jumps.size >= 6
    recorded = np.array([u2[i + 1] - u2[i] for i in np.searchsorted(t2, r.jumps) - 1])
    np.testing.assert_allclose(_jumps_read(r), recorded, atol=1e-9)


@pytest.mark.parametrize(
    ("fs", "f", "a", "periods"),
    [
        (10e3, 2000.0, 0.98, 4),  # 5 samples a period: the flyback 4 ramp samples' size
        (10e3, 2000.0, 0.98, 12),
        (10e3, 1250.0, 0.99, 6),  # 8 samples a period
        (20e3, 4000.0, 0.99, 10),  # 5 again, at 20 kHz
    ],
)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_sawtooth_of_few_samples_per_period_is_read_as_its_flybacks(fs, f, a, periods, sign):
    """A sampled sawtooth of 5–8 samples a period (a 2 kHz burst on a 10 kHz DAQ, the
    third independent plant's axis-A trace): each flyback is one sample's change against
    both neighbours' sense, only 4–7 times a ramp sample — read as a step, one per
    period, not as a slow flyback over a sample interval (stop 71: a 2 kHz burst of 4
    periods was read as one period at 513 Hz)."""
    t, u = _linear_flyback_sawtooth(f, a, periods, fs=fs, sign=sign)
    r = read_drive(t, u)
    assert r.recording == "sampled" and r.jumps.size == periods
    steps = [s for s in segment_trace(r, t[-1]) if s.kind == "steps"]
    assert len(steps) == 1, steps
    s = steps[0]
    assert s.flyback != "ramp" and s.periods == periods and s.direction == sign
    assert s.frequency == pytest.approx(f, rel=0.02)


@pytest.mark.parametrize(
    ("f", "a"),
    [(500.0, 0.5), (2000.0, 0.5), (500.0, 0.75), (1000.0, 0.6)],
)
def test_a_resolved_flyback_stays_a_ramp_on_a_slow_daq(f, a):
    """The sawtooth rule reads no jump where the flyback spans several samples of one
    size (a triangle, a = 0.75 at 20 samples a period): those flybacks are resolved and
    the drive is read as it was sampled."""
    t, u = _linear_flyback_sawtooth(f, a, 6, fs=10e3)
    r = read_drive(t, u)
    inside = r.jumps[(r.jumps > 0.0201234 + 0.5 / f) & (r.jumps < 0.0201234 + 5.5 / f)]
    assert inside.size == 0, inside


@pytest.mark.parametrize(
    ("fs", "f", "a", "periods", "phase"),
    [
        (10e3, 500.0, 0.75, 24, 0.37),  # the third independent plant's axis-A burst
        (10e3, 500.0, 0.75, 3, 0.71),
        (10e3, 200.0, 0.9, 12, 0.0),  # five samples of flyback, the last into the hold
        (10e3, 1000.0, 0.9, 12, 0.37),  # a flyback of one sample, falling on two
        (20e3, 1000.0, 0.75, 12, 0.37),
        (20e3, 2000.0, 0.9, 12, 0.0),
        (25e3, 2000.0, 0.9, 12, 0.0),  # 1.25 samples: one flyback a jump, the next not
    ],
)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_burst_whose_flybacks_are_partly_resolved_keeps_its_periods(
    fs, f, a, periods, phase, sign
):
    """A burst whose flybacks span one to five samples, so that only some of them (or only
    the last, into the hold) are read as jumps, is described by the flybacks its drive's
    sense shows: its periods, frequency and direction as generated (stop 72: the third
    plant's 24-period −2 V, 500 Hz, a = 0.75 burst at 10 kHz was read as one period of
    −0.4 V at 21 Hz). Its amplitude is read within 30 %: a flyback read as a jump leaves
    out the part of its drop that falls on the samples beside it."""
    hold = 0.0201234 + phase / fs  # the generator's clock at a phase of the DAQ's
    t, u = _linear_flyback_sawtooth(f, a, periods, fs=fs, hold=hold, sign=sign)
    steps = [s for s in segment_trace(read_drive(t, u), t[-1]) if s.kind == "steps"]
    assert len(steps) == 1, steps
    s = steps[0]
    assert s.periods == periods and s.direction == sign, s
    assert s.frequency == pytest.approx(f, rel=0.02)
    assert s.amplitude == pytest.approx(3.0, rel=0.3)


@pytest.mark.parametrize(
    ("fs", "f", "amp", "tol"),
    [
        (10e3, 50.0, 6.0, 1e-6),  # 200 µs of flyback, two samples: two 3 V jumps slipped
        (25e3, 100.0, 4.5, 0.01),  # 100 µs, 2.5 samples (0.15 read linear, before stop 91)
        (20e3, 100.0, 4.5, 0.03),  # 100 µs, 2 samples
    ],
)
def test_a_flyback_the_samples_resolve_is_read_linear_and_steps_as_generated(fs, f, amp, tol):
    """A flyback spanning two or more sample intervals (a = 0.99 at 50–100 Hz) is the
    generator's ramp as sampled: read linear between the samples, not as a staircase of
    one jump per sample. The per-axis model then steps as under the generator's own drive
    (1 MS/s); under the staircase each jump slipped it (stop 72: 31 µrad against 0.4 µrad
    over three periods of 6 V at 50 Hz on a 10 kHz DAQ, the third plant's axis-A trace).
    ``tol``: absolute [rad] where the generator's drive barely steps, else relative."""
    a, periods, hold = 0.99, 3, 0.0201234
    t_end = 2 * hold + periods / f
    t_gen = np.arange(0.0, t_end, 1e-6)
    _, u_gen = _linear_flyback_sawtooth(f, a, periods, fs=1e6, amp=amp, hold=hold)
    t, u = _linear_flyback_sawtooth(f, a, periods, fs=fs, amp=amp, hold=hold)
    r = read_drive(t, u)
    assert r.jumps.size == 0, r.jumps
    plant = Plant("real", fidelity="reduced")
    gen = simulate_trace(plant, "B", t_gen[: u_gen.size], u_gen).theta[-1]
    drive = flyback_corners(r, segment_trace(r, float(t[-1])))
    read = simulate_trace(plant, "B", t, u, breakpoints=drive).theta[-1]
    bound = tol if tol < 1e-3 else tol * abs(gen)
    assert abs(read - gen) <= bound, (read, gen)


@pytest.mark.parametrize(("fs", "f", "a"), [(25e3, 100.0, 0.99), (20e3, 200.0, 0.97),
                                            (10e3, 500.0, 0.75), (25e3, 50.0, 0.99)])  # fmt: skip
@pytest.mark.parametrize("phase", [0.0, 0.37, 0.81])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_resolved_flyback_is_the_line_through_its_samples(fs, f, a, phase, sign):
    """The model's drive of a flyback with two or more samples on it is the generator's
    (`segments.flyback_corners`): the line through those samples meets the ramp on either
    side at its corners, where read linear from the ramp's last sample to its next first
    one the flyback lasts up to one interval more and the drive misses the generator's by
    up to the ramp's span over the flyback's last interval. The burst's description is the
    samples' and does not change."""
    hold = 0.0201234 + phase / fs
    t, u = _linear_flyback_sawtooth(f, a, 3, fs=fs, hold=hold, sign=sign)
    r = read_drive(t, u)
    segs = segment_trace(r, float(t[-1]))
    bt, bu = flyback_corners(r, segs)
    assert np.all(np.diff(bt) > 0.0)
    tg, ug = _linear_flyback_sawtooth(f, a, 3, fs=1e6, hold=hold, sign=sign)
    inside = (tg > hold + 0.5 / f) & (tg < hold + 3.5 / f)  # from the first flyback on
    # but for the samples around a change read as a jump (the last flyback into the hold
    # may be), which the landing places (`segments.landing_phase`)
    near = np.abs(tg[:, None] - r.jumps[None, :]).min(axis=1, initial=np.inf) < 2.0 / fs
    inside &= ~near
    off = np.abs(np.interp(tg, bt, bu) - ug)[inside]
    linear = np.abs(np.interp(tg, r.time, r.level) - ug)[inside]
    assert off.max() <= 1e-6 * 3.0, off.max()
    assert linear.max() >= 0.01 * 3.0  # what the corners mend
    assert segment_trace(r, float(t[-1])) == segs


@pytest.mark.parametrize("declared", [None, "as_sampled", "linear"])
def test_the_fit_runs_through_the_corners_where_the_file_declares_linear_flybacks(
    declared, tmp_path
):
    """`# drive_flybacks: linear` (stop 91, not yet the default) makes the fit's drive
    (`TraceData.breakpoints`) the reading through its resolved flybacks' corners; without
    it, or with ``as_sampled``, the fit's drive is the reading."""
    fs, f, a = 25e3, 100.0, 0.99
    t, u = _linear_flyback_sawtooth(f, a, 3, fs=fs, amp=4.5)
    x = 0.02 * u + np.random.default_rng(0).normal(0.0, 1e-3, t.size)  # a spot that moves
    head = "# axis: B\n# amplifier_gain: 20\n# detector_sensitivity_m_per_V: 1e-4\n"
    head += "# detector_distance_m: 0.5\n# table_radius_m: 0.01\n"
    if declared:
        head += f"# drive_flybacks: {declared}\n"
    rows = "\n".join(f"{ti:.9g},{ui:.9g},{xi:.9g}" for ti, ui, xi in zip(t, u, x, strict=True))
    path = tmp_path / "m.csv"
    path.write_text(head + "t_s,drive_B_V,detector_V\n" + rows + "\n")
    td = trace_data(load_measurement(path))
    bt, bu = td.breakpoints
    corners = flyback_corners(td.reading, td.segments)
    assert corners[0].size == td.reading.time.size + 6  # three flybacks, two corners each
    assert np.all(np.diff(corners[0]) > 0.0)  # once each, the burst cut between the portions
    want = corners if declared == "linear" else (td.reading.time, td.reading.level)
    np.testing.assert_array_equal(bt, want[0])
    np.testing.assert_array_equal(bu, want[1])


def test_declared_recording_is_honoured_and_a_bad_one_is_named():
    t, u = _sampled_sawtooth()
    assert read_drive(t, u, {"drive_recording": "breakpoints"}).recording == "breakpoints"
    with pytest.raises(ValueError, match="drive_recording"):
        read_drive(t, u, {"drive_recording": "analog"})


def test_portions_interleave_every_drive_condition():
    """Every condition the held-out portion holds was also seen in the fit portion."""
    m = run_virtual_lab("standard", {}, noise_std=0.0, seed=0)
    segs = split_portions(segment_trace(read_drive(m.time, m.drives[m.axis]), m.time[-1]))
    fit = {s.condition for s in segs if s.portion == "fit"}
    held = {s.condition for s in segs if s.portion == "heldout"}
    assert held and held <= fit
    kinds = {s.kind for s in segs}
    assert kinds == {"hold", "scan", "steps"}


# forward burst, hold, reverse burst, hold, … (the second independent plant's protocol):
# alternating the holds as one condition gives one portion the holds after forward bursts
# and the other those after reverse ones
_ALTERNATING = [("hold", 0.01)] + 3 * [
    ("steps", 2.0, 100.0, 3, 0.95, 1.0),
    ("hold", 0.02),
    ("steps", -2.0, 100.0, 3, 0.95, 1.0),
    ("hold", 0.02),
]


@pytest.mark.parametrize("protocol", ["thesis", "alternating"])
def test_each_portion_holds_the_holds_after_both_directions(protocol):
    """Stop 63's confound: the held-out error must not judge the model on holds of a kind
    (after one direction of motion) that the fit never saw."""
    blocks = _ALTERNATING if protocol == "alternating" else protocol
    t, u = protocol_drive(blocks, get_parameter_set("real"), "B")
    segs = split_portions(segment_trace(read_drive(t, u), t[-1]))
    counts = holds_by_motion(segs)
    assert not one_sided(counts)
    for portion in ("fit", "heldout"):
        assert counts[portion][1] > 0 and counts[portion][-1] > 0, (portion, counts)
    fit = {s.condition for s in segs if s.portion == "fit"}
    held = {s.condition for s in segs if s.portion == "heldout"}
    assert held == fit
    # the segments still tile the trace in time order
    assert all(a.end == pytest.approx(b.start) for a, b in itertools.pairwise(segs))


@pytest.mark.parametrize("protocol", ["standard", "long"])
def test_a_balanced_protocol_keeps_one_hold_condition(protocol):
    """Where the holds already fall into both portions after both directions, every hold
    is one condition, "hold", as before stop 87."""
    t, u = protocol_drive(protocol, get_parameter_set("real"), "B")
    segs = split_portions(segment_trace(read_drive(t, u), t[-1]))
    assert {s.condition for s in segs if s.kind == "hold"} == {"hold"}
    assert not one_sided(holds_by_motion(segs))


def test_noise_floor_recovers_white_noise_despite_ringing_holds():
    rng = np.random.default_rng(3)
    t, u = _sampled_sawtooth(periods=2, hold=0.05)
    segs = segment_trace(read_drive(t, u), t[-1])
    sigma = 1e-3
    v = rng.normal(0.0, sigma, t.size)
    # a lightly damped ring (4.7 kHz) through the first hold only
    first = segs[0]
    ring = (t < first.end) * 5e-3 * np.sin(2 * np.pi * 4.7e3 * t)
    holds = [s for s in segs if s.kind == "hold"]
    assert len(holds) >= 2
    est, source, n = noise_floor(t, v + ring, segs)
    assert est == pytest.approx(sigma, rel=0.15) and n >= 50 and "hold" in source


def test_anchoring_removes_each_segments_offset():
    t, u = _sampled_sawtooth()
    segs = split_portions(segment_trace(read_drive(t, u), t[-1]))
    an = Anchoring.of(t, segs)
    # an error that is a different constant in every segment re-reads to zero
    offsets = np.where(an.unit >= 0, 7.0 * an.unit + 3.0, 0.0)
    out = an.apply(offsets + 0.0)
    inner = np.zeros(t.size, bool)
    for k in range(len(segs)):
        idx = np.flatnonzero(an.unit == k)
        if idx.size and an.anchor_start[k] >= idx[0]:  # anchored on its own start
            inner[idx] = True
    assert np.allclose(out[inner], 0.0)
    assert an.fit.any() and an.heldout.any() and not (an.fit & an.heldout).any()


def test_the_heldout_error_is_split_by_drive_condition():
    """condition_shares: the held-out squared error per condition adds up to the whole; a
    hold's error counts under the motion before it; an error in one burst's held-out
    samples (and the hold after it) is that burst's condition alone."""
    t, u = _sampled_sawtooth()
    segs = split_portions(segment_trace(read_drive(t, u), t[-1]))
    an = Anchoring.of(t, segs)
    r = np.random.default_rng(0).normal(0.0, 1.0, t.size)
    rows = condition_shares(segs, an, r, top=50)
    assert sum(row["share"] for row in rows) == pytest.approx(1.0)
    assert sum(row["samples"] for row in rows) == np.count_nonzero(an.heldout)
    whole = float(np.sqrt(np.mean(r[an.heldout] ** 2)))
    pooled = np.sqrt(sum(row["rms"] ** 2 * row["samples"] for row in rows) / an.heldout.sum())
    assert pooled == pytest.approx(whole)
    # every label is a steps or scan condition, or a hold under the motion before it
    conds = {s.condition for s in segs if s.kind != "hold"}
    for row in rows:
        c = row["condition"]
        assert c in conds or c == "hold" or c.removeprefix("hold after ") in conds, c
    # a burst that is off by 10 nm in its held-out samples, and in the hold after it
    k = next(i for i, s in enumerate(segs[:-1]) if s.kind == "steps" and s.portion == "heldout"
             and segs[i + 1].kind == "hold" and segs[i + 1].portion == "heldout")  # fmt: skip
    bad = np.zeros(t.size)
    bad[an.unit == k] = 10.0
    bad[an.unit == k + 1] = 10.0
    top = condition_shares(segs, an, bad + 1e-3 * r)
    names = [row["condition"] for row in top]
    assert set(names[:2]) == {segs[k].condition, f"hold after {segs[k].condition}"}
    assert sum(row["share"] for row in top[:2]) > 0.99
    with pytest.raises(ValueError, match="residual"):
        condition_shares(segs, an, r[:-1])


@pytest.mark.parametrize("phi", [0.0, 0.5, 0.8])
def test_correlation_length_of_an_ar1_residual(phi):
    """AR(1): integrated autocorrelation (1 + φ)/(1 − φ) samples."""
    rng = np.random.default_rng(1)
    e = rng.normal(size=200_000)
    r = np.empty_like(e)
    r[0] = e[0]
    for i in range(1, e.size):
        r[i] = phi * r[i - 1] + e[i]
    # the sum stops where ρ < 0.05: the truncated tail is Σ_{k≥K} φ^k
    expect = (1 + phi) / (1 - phi)
    assert correlation_length(r) == pytest.approx(expect, rel=0.15)


def test_a_protocol_without_holds_or_y_channel_cannot_identify_creep_or_misalignment():
    from dataclasses import replace

    from turntable_env.calibration.trace_fit import _prepare

    m = run_virtual_lab("standard", {}, noise_std=1e-3, seed=0)
    td, _w = _prepare(m)
    why = identifiable_effects([td])
    assert why["piezo_creep"] == "" and why["piezo_hysteresis"] == ""
    assert why["axis_misalignment"] == ""  # the file records the y channel
    td, _w = _prepare(replace(m, detector_y_v=None))
    assert identifiable_effects([td])["axis_misalignment"] == "no y channel"
    # a y column that never changes (not even by its noise) is a channel not connected:
    # not read as a perfectly aligned detector, and said so
    for level in (0.0, 0.37):
        td, w = _prepare(replace(m, detector_y_v=np.full_like(m.detector_v, level)))
        assert identifiable_effects([td])["axis_misalignment"] == "no y channel"
        assert any("'detector_y_V' is constant" in x for x in w), w
    td_noholds = type(td)(**{**td.__dict__, "segments": [s for s in td.segments
                                                          if s.kind != "hold"]})  # fmt: skip
    why = identifiable_effects([td_noholds])
    assert "hold" in why["piezo_creep"] and "hold" in why["vibration"]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"min_improvement": 1.5}, "min_improvement"),
        ({"candidates": ["wobble"]}, "candidates"),
        ({"global_points": -1}, "global_points"),
        ({"hops": -1}, "hops"),
        ({"hops": 1.5}, "hops"),
        ({"workers": 0}, "workers"),
    ],
)
def test_bad_arguments_are_named_before_any_work(kwargs, field):
    m = run_virtual_lab("thesis", {}, noise_std=1e-3, seed=0)
    with pytest.raises(ValueError, match=field):
        calibrate([m], progress=None, **kwargs)


def test_the_z_axis_is_refused_with_the_reason(tmp_path):
    from dataclasses import replace

    m = run_virtual_lab("thesis", {}, noise_std=1e-3, seed=0)
    z = replace(m, axis="Z", drives={"Z": m.drives[m.axis]})
    with pytest.raises(ValueError, match="axis 'Z'"):
        calibrate([z], progress=None, global_points=0)


@pytest.mark.parametrize(
    "name, values, pinned",
    [
        ("friction_wear", {"beta": -0.5}, True),  # at the lower end of its range
        ("friction_wear", {"beta": 0.5}, True),  # at the upper end
        ("friction_wear", {"beta": 0.3}, False),  # inside
        ("vibration", {"amplitude": 0.0, "frequency": 50.0, "phase": -np.pi}, False),  # off
        ("piezo_creep", {"gamma": 0.05}, True),
    ],
)
def test_an_effect_pinned_at_its_bound_is_told_apart(name, values, pinned):
    """After the joint refit, a main parameter at a bound of its range away from neutral
    marks an effect standing in for something else; at neutral (off) it does not, nor do
    the other parameters (a phase at ±π)."""
    assert bool(main_at_bound(name, values)) is pinned


@pytest.mark.parametrize("gain", [22.5, 90.0])
def test_a_files_amplifier_gain_reaches_the_tubes(gain):
    """The file's ``amplifier_gain`` is not the base set's: its drive u becomes the base
    amplifier's input k·u, k = G_file/G_base, so the tubes see G_file·u (the tubes' voltage,
    not the input, moves the table). A file at G_file with input u·G_base/G_file is then the
    base set's own file, sample for sample; a drive that would need more than the base
    amplifier's input limit is refused, naming the file."""
    from dataclasses import replace

    from turntable_env.calibration.measurement import Measurement
    from turntable_env.calibration.trace_fit import at_base_gain
    from turntable_env.detector import Detector
    from turntable_env.plant import Plant

    amp = Plant("real").params.amplifier
    t, u = _sampled_sawtooth(amp=2.0)
    own = Measurement("B", amp.gain, Detector(), t, {"B": u}, np.zeros_like(t), source="own")
    assert at_base_gain(own, amp) == (own, [])  # the base's gain: the file as it is
    lab = replace(own, amplifier_gain=gain, drives={"B": u * amp.gain / gain}, source="lab")
    seen, warning = at_base_gain(lab, amp)
    np.testing.assert_allclose(seen.drives["B"], u, rtol=1e-12, atol=1e-15)
    assert "lab" in warning[0] and f"{gain:g}" in warning[0]
    loud = replace(lab, drives={"B": 6.0 * np.ones_like(t) * amp.gain / gain * 2.0})
    with pytest.raises(ValueError, match=r"lab: amplifier_gain .* beyond the base amplifier"):
        at_base_gain(loud, amp)  # 12 V of base input: G_base·12 V on the tubes


def test_a_drive_too_small_for_the_tubes_is_refused_in_the_files_own_terms():
    """A drive that moves nothing is refused before any work, and where the file's
    ``amplifier_gain`` is not the base's the message quotes the file's own span and gain
    beside the base amplifier's input (stop 72's audit: 0.36 V at gain 1 was reported as
    "spans 0.008 V", a number the file does not hold)."""
    from turntable_env.calibration.measurement import Measurement
    from turntable_env.detector import Detector

    t, u = _sampled_sawtooth(amp=0.36)
    noise = np.random.default_rng(0).normal(0.0, 1e-3, t.size)
    det = np.cumsum(np.abs(np.diff(u, prepend=0.0))) * 1e-2 + noise
    m = Measurement("B", 1.0, Detector(), t, {"B": u}, det, source="lab.csv")
    with pytest.raises(ValueError, match=r"lab\.csv: .* spans 0\.36 V at amplifier_gain 1, "
                                         r"0\.008 V as the base amplifier's input"):  # fmt: skip
        calibrate([m], global_points=1, workers=1)
