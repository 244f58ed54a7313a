"""Reading a measured drive: its recording, its segments and their drive conditions.

A laboratory records the amplifier input either as **breakpoints** (the function
generator's corners, a jump as two samples at nearly the same time) or as **samples** of
the generator's output at the detector rate (10–100 kHz), where the sawtooth's flyback —
a step that the amplifier shapes (§4.1.2, Fig. 4.2) — falls between two samples.
:func:`read_drive` finds such single-sample drops and rises and turns each into a step at
the middle of its sample interval (timing uncertainty ± half an interval), the ramp on
either side running on to it at its slope on a uniform sampling clock (the step is the
generator's span, not the samples' change; :func:`_ramp_on`), or, in a burst that lands
on the hold after it, where that level places it (:func:`landing_phase`): read as
piecewise linear, a 2 V drop over 50 µs is a slow flyback after which the model barely
steps. A flyback the samples resolve is read linear between them, and the model's drive
runs through its corners, where the line through its samples meets the ramps
(:func:`flyback_corners`). A single-sample change is a step where it is several times
its neighbours' typical change, or, in a sawtooth of few samples per period (a 2 kHz
burst on a 10 kHz DAQ: five samples, the flyback four ramp samples' size), where it runs
against both neighbours' sense at :data:`SAWTOOTH_RATIO` times their size; a flyback
spread over several samples of one size (a triangle, a resolved ramp) is neither. A file may declare
its recording with the metadata key ``drive_recording`` (``breakpoints`` or
``sampled``); otherwise it is detected.

:func:`segment_trace` cuts the drive into **segments** — ``hold`` (constant input),
``scan`` (monotonic ramp without jumps) and ``steps`` (a burst of sawtooth periods) —
and gives each its drive condition (kind, direction, amplitude, frequency, flyback): a
burst by its jumps where they mark every flyback, else by the flybacks its drive's sense
shows (runs against the ramp; a flyback of one to a few samples is read as a jump at one
phase of the DAQ's clock and over samples at another, and the last one into a hold alone
can be a jump), else, with no jumps, by its turning points. Its
segments are then split into a fit and a held-out portion **interleaved by condition**:
every condition's occurrences alternate between the portions, and a condition that occurs
once is cut in two (a burst at a period boundary), so the held-out error measures
prediction at drive conditions the fit has seen, not extrapolation. Every hold is one
condition unless that alternation leaves a portion whose holds after motion all follow one
direction while the trace has holds after both (a protocol of forward burst, hold, reverse
burst, hold, …): then a hold's condition is the direction of the motion before it, so each
portion holds both kinds (:func:`holds_by_motion`, :func:`one_sided`).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

__all__ = [
    "DriveReading",
    "Segment",
    "flyback_corners",
    "holds_by_motion",
    "landing_phase",
    "motion_before",
    "one_sided",
    "quantisation_step",
    "read_drive",
    "segment_trace",
    "split_portions",
]

RECORDINGS = ("breakpoints", "sampled")
# metadata ``drive_flybacks``: a resolved flyback read linear between its samples (the
# default), or declared a linear ramp, whose corners the model's drive runs through
FLYBACK_SHAPES = ("as_sampled", "linear")
JUMP_GAP = 1e-3  # a sample interval under this fraction of the median one is a jump [-]
JUMP_RATIO = 6.0  # a single-sample change this many times the local typical one is a step
JUMP_MIN = 0.05  # V, smallest input change read as a step
SAWTOOTH_RATIO = 2.5  # a change against both neighbours this many times their size is a step
QUIET_MIN = 2e-3  # s, shortest constant stretch that separates two segments
QUIET_TOL = 0.02  # V, input variation still read as constant (DAQ resolution, noise)
RESOLVED_SAMPLES = 1.9  # a flyback of two sample intervals (less the ramp's rise within its partial
# ones) or more is resolved by the samples and read linear between them (the model's drive
# then through the flyback's corners, :func:`flyback_corners`)
SINGLE_FLYBACK = 0.1  # a lone return within this share of its stretch is a flyback (a ≥ 0.9)
FLYBACK_MERGE = 0.2  # jumps closer than this fraction of the burst period form one flyback
LANDING_TOL = 0.25  # a flyback's landing read this far outside its interval [intervals]: the
# burst's sawtooth does not share the hold's level, and its steps stay at mid-interval
LANDING_EDGE = 1e-3  # a step read at an interval's edge is put this far inside it [intervals]
HOLD_SAMPLES = 3  # samples within QUIET_TOL after a burst's last flyback: it lands on a hold


@dataclass(frozen=True, eq=False)
class DriveReading:
    """The drive as the model reads it.

    Attributes:
        time, level: breakpoints of the piecewise-linear amplifier input [s], [V] (a jump
            as two breakpoints 1 ns apart).
        recording: ``"breakpoints"`` or ``"sampled"``.
        jumps: times of the drive's steps [s] (explicit or read from single-sample changes).
        timing_uncertainty: ± the steps' time [s] (half the sample interval when read
            from samples, else 0).
        sample_interval: median interval between the file's drive samples [s].
        declared: whether the file declared its recording (metadata ``drive_recording``).
        warnings: what a lab engineer should know about the reading.
    """

    time: np.ndarray
    level: np.ndarray
    recording: Literal["breakpoints", "sampled"]
    jumps: np.ndarray
    timing_uncertainty: float
    sample_interval: float
    declared: bool = False
    warnings: tuple[str, ...] = ()


def _local_typical(du: np.ndarray, half: int = 5) -> np.ndarray:
    """Median |Δu| over ±``half`` neighbouring intervals (the interval itself excluded)."""
    a = np.abs(du)
    n = a.size
    pad = np.concatenate([np.full(half, np.nan), a, np.full(half, np.nan)])
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1)
    win = np.delete(win, half, axis=1)
    with np.errstate(all="ignore"):
        out = np.nanmedian(win, axis=1)
    return np.nan_to_num(out[:n], nan=0.0)


def read_drive(
    time: np.ndarray,
    drive: np.ndarray,
    meta: Mapping[str, str] | None = None,
    *,
    landing: bool = True,
) -> DriveReading:
    """How the model reads a recorded drive (module docstring).

    Args:
        time: sample times [s], strictly increasing; drive: amplifier input [V].
        meta: the file's metadata; ``drive_recording`` = ``breakpoints`` | ``sampled``
            overrides the detection (ValueError for another value); ``drive_flybacks`` =
            ``as_sampled`` | ``linear`` is checked here and read by the fit
            (:func:`flyback_corners`).
        landing: place a sampled sawtooth's steps where its burst's landing level says
            (:func:`landing_phase`); False puts each at its interval's middle (the
            reading before stop 91, for comparison).
    """
    t = np.asarray(time, float)
    u = np.asarray(drive, float)
    dt = np.diff(t)
    dt_med = float(np.median(dt)) if dt.size else 0.0
    declared = (meta or {}).get("drive_recording")
    if declared is not None and declared not in RECORDINGS:
        raise ValueError(
            f"metadata 'drive_recording' = {declared!r}: must be 'breakpoints' or 'sampled'"
        )
    shape = (meta or {}).get("drive_flybacks")
    if shape is not None and shape not in FLYBACK_SHAPES:
        raise ValueError(
            f"metadata 'drive_flybacks' = {shape!r}: must be 'as_sampled' or 'linear' (the "
            "generator's flybacks linear: the model's drive through their corners)"
        )
    explicit = dt < JUMP_GAP * dt_med
    du = np.diff(u)
    # a single-sample change much larger than its neighbours' typical change
    typical = _local_typical(du)
    lsb = quantisation_step(u)
    big = ~explicit & (np.abs(du) > max(JUMP_MIN, 3.0 * lsb))
    # a sawtooth's flyback between two of its ramp's samples: against both neighbours'
    # sense and SAWTOOTH_RATIO times their size (a sawtooth of few samples per period,
    # whose ramp samples make the local typical change large: 5 samples per period read
    # a flyback of 4 ramp samples' size)
    prev = np.concatenate([[0.0], du[:-1]])
    nxt = np.concatenate([du[1:], [0.0]])
    reversed_ = (du * prev <= 0.0) & (du * nxt <= 0.0) & ((prev != 0.0) | (nxt != 0.0))
    sawtooth = reversed_ & (
        np.abs(du) > SAWTOOTH_RATIO * np.maximum(np.maximum(np.abs(prev), np.abs(nxt)), lsb)
    )
    single = big & ((np.abs(du) > JUMP_RATIO * np.maximum(typical, lsb)) | sawtooth)
    single = _resolved_flybacks_sampled(single, du)
    uniform = dt.size > 0 and np.ptp(dt) < 0.01 * dt_med  # one sampling clock
    if declared is not None:
        recording = declared
    elif explicit.any():
        recording = "breakpoints"
    elif single.any() or uniform:
        recording = "sampled"
    else:
        recording = "breakpoints"
    warnings: list[str] = []
    if recording == "breakpoints":
        jumps = t[1:][explicit & (np.abs(du) > JUMP_MIN)]
        bt, bu = t, u
        unc = 0.0
        if single.any() and declared is None:
            warnings.append(
                f"{int(single.sum())} single-interval changes read as ramps between "
                "breakpoints (the file's drive has explicit jumps elsewhere)"
            )
    else:
        idx = np.flatnonzero(single)
        # where in its interval each step falls [-]: the middle, or where the level its
        # burst lands on says (:func:`landing_phase`), on a uniform sampling clock
        phase = landing_phase(single, t, u) if uniform and landing else np.full(du.size, 0.5)
        mids = t[idx] + phase[idx] * dt[idx]
        unc = 0.5 * dt_med
        before, after = _ramp_on(single, t, du, phase) if uniform else (np.zeros(t.size),) * 2
        bt_list, bu_list = (
            [t[: idx[0] + 1]] if idx.size else [t],
            [u[: idx[0] + 1]] if idx.size else [u],
        )
        for j, i in enumerate(idx):
            nxt = idx[j + 1] if j + 1 < idx.size else t.size - 1
            # the ramp on to the interval's middle, the jump, the ramp on to the next sample
            bt_list.append(np.array([mids[j], mids[j] + 1e-9]))
            bu_list.append(np.array([u[i] + before[i], u[i + 1] - after[i]]))
            bt_list.append(t[i + 1 : nxt + 1])
            bu_list.append(u[i + 1 : nxt + 1])
        bt, bu = np.concatenate(bt_list), np.concatenate(bu_list)
        jumps = mids + 1e-9
        if idx.size:
            placed = int(np.count_nonzero(phase[idx] != 0.5))
            where = (f"{placed} where their burst's landing level places them, the rest at "
                     "mid-interval" if placed else "at mid-interval")  # fmt: skip
            warnings.append(
                f"drive sampled every {dt_med * 1e6:.3g} µs: {idx.size} single-sample changes "
                f"read as steps ({where}; timing ± {unc * 1e6:.3g} µs); flyback "
                f"shapes shorter than {dt_med * 1e6:.3g} µs (the Fig. 4.3 adapted hold) are "
                "not resolved — declare the drive as breakpoints if you have them"
            )
    return DriveReading(
        time=bt,
        level=bu,
        recording=recording,  # type: ignore[arg-type]
        jumps=np.asarray(jumps, float),
        timing_uncertainty=unc,
        sample_interval=dt_med,
        declared=declared is not None,
        warnings=tuple(warnings),
    )


def _ramp_on(
    single: np.ndarray, t: np.ndarray, du: np.ndarray, phase: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """How far the ramp runs on into each single-sample step's interval [V], before the
    step (``before``, from the sample before it) and after it (``after``, to the sample
    after it), the step at the interval's middle.

    A sawtooth's ramp does not stop at the last sample before its flyback: it runs on at
    its slope until the flyback, and starts again at its bottom before the next sample.
    Held flat to the middle, a 6 V, 2 kHz, a = 0.98 sawtooth on a 10 kHz DAQ (five
    samples a period) was read as 4.9 V, its flyback four ramp samples' size where the
    generator's is nearly five. Wherever the flyback falls in the interval, the ramp
    fills the interval but for the flyback's own duration, so the step is the samples'
    change plus one interval of ramp; put at the middle, half of it lies on each side. The
    slope on each side is that of the neighbouring interval where that is a ramp against
    the step's sense and not itself a step. For a uniform sampling clock only (the
    caller's test): a file with rows off the clock holds the generator's corners, where
    the ramp ends (the second independent plant's traces add a row at every drive
    breakpoint).
    """
    n = du.size
    before, after = np.zeros(n + 1), np.zeros(n + 1)
    dt = np.diff(t)
    ph = np.full(n, 0.5) if phase is None else phase
    slope_b, slope_a = _ramp_slopes(single, t, du)
    for i in np.flatnonzero(single):
        before[i] = slope_b[i] * ph[i] * dt[i]
        after[i] = slope_a[i] * (1.0 - ph[i]) * dt[i]
    return before, after


def _ramp_slopes(
    single: np.ndarray, t: np.ndarray, du: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The ramp's slope [V/s] in the interval before (``slope_b``) and after (``slope_a``)
    each single-sample step, where that interval is a ramp against the step's sense and not
    itself a step; 0 elsewhere."""
    n = du.size
    dt = np.diff(t)
    slope_b, slope_a = np.zeros(n), np.zeros(n)
    for i in np.flatnonzero(single):
        if i >= 1 and not single[i - 1] and du[i - 1] * du[i] < 0.0:
            slope_b[i] = du[i - 1] / dt[i - 1]
        if i + 1 < n and not single[i + 1] and du[i + 1] * du[i] < 0.0:
            slope_a[i] = du[i + 1] / dt[i + 1]
    return slope_b, slope_a


def landing_phase(single: np.ndarray, t: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Where in its sample interval each single-sample step of a sampled sawtooth falls,
    as a fraction of the interval [-] (0.5, the middle, where the samples do not say).

    A sawtooth's periods share one bottom: every flyback of a burst lands on the level its
    last flyback lands on, the hold after the burst (a generator's burst superimposed on
    its offset). The ramp after each earlier flyback, run back at its slope, reaches that
    level where the flyback ended; the generator's span (the ramp before it, run on to
    there, less the level) is then known, and the last flyback falls where the ramp before
    it runs on to the level plus that span. Between two samples this is the flyback's
    place to the drive samples' resolution, where the middle of the interval is up to
    half an interval off: the third independent plant's generator ends each flyback on a
    DAQ sample, and a 6 V, 2 kHz, a = 0.98 burst at 10 kHz read at the middle lands its
    last flyback half an interval of ramp (0.61 V), a tenth, short of the generator's
    span. A burst of one flyback, one that does not end in a hold, or one whose flybacks'
    landings fall outside their intervals by more than :data:`LANDING_TOL` of one (a
    sawtooth whose bottom is not the hold's level) keeps the middle.
    """
    du = np.diff(u)
    n = du.size
    dt = np.diff(t)
    phase = np.full(n, 0.5)
    slope_b, slope_a = _ramp_slopes(single, t, du)
    for burst in _bursts(single, du, u):
        last = burst[-1]
        level = u[last + 1]  # the hold's level, where every flyback lands
        inner = burst[:-1]
        if inner.size == 0 or np.any(slope_a[inner] == 0.0) or slope_b[last] == 0.0:
            continue
        ph = 1.0 - (u[inner + 1] - level) / (slope_a[inner] * dt[inner])
        ok = slope_b[inner] != 0.0
        if not ok.any():
            continue
        span = float(np.median(u[inner][ok] + slope_b[inner][ok] * ph[ok] * dt[inner][ok] - level))
        ph_last = (level + span - u[last]) / (slope_b[last] * dt[last])
        both = np.append(ph, ph_last)
        if np.any(both < -LANDING_TOL) or np.any(both > 1.0 + LANDING_TOL):
            continue
        phase[burst] = np.clip(both, LANDING_EDGE, 1.0 - LANDING_EDGE)
    return phase


def _bursts(single: np.ndarray, du: np.ndarray, u: np.ndarray) -> list[np.ndarray]:
    """The single-sample steps grouped by burst: runs of steps of one sense whose
    intervals between are ramps against it, each ending in a step onto a hold (its next
    :data:`HOLD_SAMPLES` samples within :data:`QUIET_TOL`)."""
    idx = np.flatnonzero(single)
    out: list[np.ndarray] = []
    start = 0
    for k in range(idx.size):
        i = idx[k]
        nxt = idx[k + 1] if k + 1 < idx.size else None
        sgn = np.sign(du[i])
        if nxt is not None and np.sign(du[nxt]) == sgn:
            between = du[i + 1 : nxt] * sgn
            if between.size and np.all(between <= 0.0) and np.mean(between < 0.0) > 0.5:
                continue  # the next step is this burst's next flyback
        stop = i + 1 + HOLD_SAMPLES
        if stop <= u.size and np.ptp(u[i + 1 : stop]) <= QUIET_TOL:
            out.append(idx[start : k + 1])
        start = k + 1
    return out


def _resolved_flybacks_sampled(single: np.ndarray, du: np.ndarray) -> np.ndarray:
    """``single`` less the changes of flybacks the samples resolve: a run of consecutive
    single-sample steps of one sense whose drop spans :data:`RESOLVED_SAMPLES` or more of
    its largest change (a linear flyback of that many sample intervals, as
    :func:`_flyback_duration` reads it) is the generator's ramp as sampled, and is read
    linear between the samples. A staircase of jumps, one per sample, slips the model on
    every jump where the generator's flyback, slower than the tubes' period, may not slip
    it at all (6 V, 50 Hz, a = 0.99 on a 10 kHz DAQ: two 3 V jumps, 31 µrad of steps in
    the per-axis model over three periods, against 0.4 µrad under the generator's
    200 µs flyback and 0.3 µrad linear between the samples)."""
    out = single.copy()
    idx = np.flatnonzero(single)
    if idx.size < 2:
        return out
    # runs of consecutive indices with one sense
    brk = np.flatnonzero((np.diff(idx) != 1) | (np.sign(du[idx[1:]]) != np.sign(du[idx[:-1]])))
    for run in np.split(idx, brk + 1):
        if run.size < 2:
            continue
        a = np.abs(du[run])
        if float(a.sum()) >= RESOLVED_SAMPLES * float(a.max()):
            out[run] = False
    return out


def quantisation_step(u: np.ndarray) -> float:
    """A recorded signal's quantisation step (its ADC's or DAQ's least significant bit,
    in the signal's unit; 0 for an unquantised record): the smallest common non-zero
    change, when the changes are multiples of it."""
    d = np.abs(np.diff(u))
    d = d[d > 1e-12]
    if d.size < 10:
        return 0.0
    q = float(np.percentile(d, 5))
    if q <= 0.0:
        return 0.0
    ratio = d[:2000] / q
    return q if np.mean(np.abs(ratio - np.round(ratio)) < 0.02) > 0.9 else 0.0


# --- segments -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Segment:
    """A stretch of the trace under one drive condition.

    Attributes:
        start, end: [s] (file time).
        kind: ``"hold"``, ``"scan"`` or ``"steps"``.
        direction: +1 / −1 (the steps' or the scan's sense of the input; 0 for a hold).
        amplitude: sawtooth amplitude or scan excursion [V] (0 for a hold).
        frequency: stepping frequency [Hz] (0 otherwise).
        flyback: ``"jump"``, ``"overshoot"`` (jump past zero and back, Fig. 4.3),
            ``"ramp"`` (a resolved slow flyback) or ``""``.
        periods: sawtooth periods in a burst.
        portion: ``"fit"`` or ``"heldout"``.
        ramp_ratio: a burst's ramp ratio a [-] as read (the share of a period not in its
            flyback: 1 − the median flyback's duration × frequency, a jump read from
            samples lasting one sample interval; the slower half's share of a period
            for resolved flybacks); nan otherwise. Not part of :attr:`condition`: two
            readings within a sample interval of flyback cannot be told apart (see
            :attr:`flyback_resolution`).
        flyback_resolution: how far apart two bursts' ``ramp_ratio`` may be read for one
            setting [-]: one sample interval × frequency (0 for breakpoints).
    """

    start: float
    end: float
    kind: Literal["hold", "scan", "steps"]
    direction: int = 0
    amplitude: float = 0.0
    frequency: float = 0.0
    flyback: str = ""
    periods: int = 0
    portion: Literal["fit", "heldout"] = "fit"
    ramp_ratio: float = math.nan
    flyback_resolution: float = 0.0

    @property
    def condition(self) -> str:
        """The drive condition (segments of one condition are compared)."""
        if self.kind == "hold":
            return "hold"
        if self.kind == "scan":
            return "scan"
        f = f"{self.frequency:.4g}"
        return (
            f"steps {'+' if self.direction > 0 else '-'}{self.amplitude:.1f} V {f} Hz "
            f"{self.flyback}"
        )

    @property
    def duration(self) -> float:
        return self.end - self.start


def _quiet_runs(t: np.ndarray, u: np.ndarray) -> list[tuple[float, float]]:
    """Maximal stretches [s] where the input stays within QUIET_TOL for ≥ QUIET_MIN."""
    runs = []
    i, n = 0, t.size
    while i < n:
        j = i
        lo = hi = u[i]
        while j + 1 < n:
            lo2, hi2 = min(lo, u[j + 1]), max(hi, u[j + 1])
            if hi2 - lo2 > QUIET_TOL:
                break
            lo, hi = lo2, hi2
            j += 1
        if t[j] - t[i] >= QUIET_MIN:
            runs.append((float(t[i]), float(t[j])))
        i = j + 1 if j > i else i + 1
    return runs


def _flyback_duration(group: list[float], t: np.ndarray, u: np.ndarray, jump_s: float) -> float:
    """How long a flyback read as the jumps ``group`` [s] lasts [s]: ``jump_s`` (one sample
    interval) × its whole drop over its largest jump's. A sampled linear flyback of D ≥ 2
    intervals has a sample wholly inside it, so D is read exactly; a shorter one reads
    between one and two intervals (how the drop falls on the samples); 0 for breakpoints."""
    j = np.asarray(group)
    drops = np.interp(j - 1e-8, t, u) - np.interp(j + 2e-9, t, u)
    big = float(np.max(np.abs(drops)))
    return jump_s * abs(float(np.sum(drops))) / big if big > 0.0 else jump_s


def _flyback_runs(ts: np.ndarray, us: np.ndarray) -> tuple[int, list[tuple[float, float, float]]]:
    """A burst's flybacks read from the drive's sense alone: maximal runs of changes
    against the ramp's sense (the sense the drive spends the longer time in; a flat stretch
    does not end a run) that drop by at least a quarter of the burst's span and
    :data:`JUMP_MIN` [V]. A jump read from samples is such a run of 1 ns, a resolved or
    partly resolved flyback one of several samples, so both count. (the ramp's sense ±1,
    [(start [s], end [s], drop [V])] per flyback)."""
    du, dt = np.diff(us), np.diff(ts)
    sense = 1 if dt[du > 1e-9].sum() >= dt[du < -1e-9].sum() else -1
    floor = max(JUMP_MIN, 0.25 * float(np.ptp(us))) if us.size else JUMP_MIN
    runs: list[tuple[float, float, float]] = []
    start, end, drop = math.nan, math.nan, 0.0
    for k, d in enumerate(du * sense):
        if d < -1e-9:
            if drop == 0.0:
                start = float(ts[k])
            drop -= d
            end = float(ts[k + 1])
        elif d > 1e-9:  # the ramp again: the run, if any, has ended
            if drop >= floor:
                runs.append((start, end, drop))
            drop = 0.0
    if drop >= floor:
        runs.append((start, end, drop))
    return sense, runs


def _describe_active(
    t0: float, t1: float, t: np.ndarray, u: np.ndarray, jumps: np.ndarray, jump_s: float
) -> Segment:
    """Kind and condition of an active stretch [t0, t1] of the drive (``jump_s``: how
    long a jump read from samples lasts [s], the sample interval; 0 for breakpoints).
    A burst is described by its jumps where they mark all its flybacks, else (some of its
    flybacks resolved over samples: a partly resolved flyback falls on one sample or on
    two as the generator's clock drifts past the DAQ's) by its flyback runs; a stretch
    without jumps by its turning points."""
    sel = (t >= t0) & (t <= t1)
    ts, us = t[sel], u[sel]
    js = jumps[(jumps > t0) & (jumps <= t1)]
    u_start = float(np.interp(t0, t, u))
    if js.size >= 1:
        # merge jumps of one flyback (overshoot then return), then the period
        gaps = np.diff(js)
        # the period from the long gaps (an overshooting flyback adds a short one; one read
        # over several samples, a jump per sample): a single period has none
        far = gaps[gaps > 1.5 * jump_s]
        period = float(np.median(far[far > 0.3 * far.max()])) if far.size else (t1 - t0)
        groups = [[js[0]]]
        for a, g in zip(js[1:], gaps, strict=True):
            if g < FLYBACK_MERGE * period:
                groups[-1].append(a)
            else:
                groups.append([a])
        # where the jumps, all flybacks of one ramp's sense, are fewer than the flybacks
        # the drive's sense shows, the others are resolved over samples (a burst read by
        # its jumps alone would be its last flyback's sample into the hold: one period)
        sense, runs = _flyback_runs(ts, us)
        drops = [np.interp(g[0] - 1e-8, t, u) - np.interp(g[-1] + 2e-9, t, u) for g in groups]
        if len(groups) >= len(runs) or any(d * sense <= 0.0 for d in drops):
            return _describe_by_jumps(t0, t1, t, u, groups, jump_s)
        return _describe_by_runs(t0, t1, sense, runs, jump_s)
    ends = (u_start, float(np.interp(t1, t, u)))
    return _describe_by_turns(t0, t1, ts, us, ends, jump_s)


def _describe_by_jumps(
    t0: float, t1: float, t: np.ndarray, u: np.ndarray, groups: list[list[float]],
    jump_s: float,
) -> Segment:  # fmt: skip
    """A burst whose every flyback is read as a jump or a group of them (one flyback)."""
    starts = np.array([g[0] for g in groups])
    period = float(np.median(np.diff(starts))) if starts.size > 1 else (t1 - t0)
    before = np.interp(starts - 1e-8, t, u)
    after = np.interp(np.array([g[-1] for g in groups]) + 2e-9, t, u)
    drop = float(np.median(before - after))
    direction = 1 if drop > 0 else -1
    amplitude = abs(drop)
    overshoot = any(len(g) > 1 for g in groups)
    freq = 1.0 / period if period > 0 else 0.0
    fly = float(np.median([_flyback_duration(g, t, u, jump_s) for g in groups]))
    return Segment(
        t0, t1, "steps", direction, round(amplitude, 3), freq,
        "overshoot" if overshoot else "jump", len(groups),
        ramp_ratio=max(0.0, 1.0 - fly * freq), flyback_resolution=jump_s * freq,
    )  # fmt: skip


def _describe_by_runs(
    t0: float, t1: float, sense: int, runs: list[tuple[float, float, float]], jump_s: float
) -> Segment:
    """A burst whose jumps mark only some of its flybacks (the others resolved over a few
    samples): described by its flyback runs (:func:`_flyback_runs`), labelled ``ramp``."""
    starts = np.array([r[0] for r in runs])
    # the mean spacing: a run starts on a sample, so at 12.5 samples a period the
    # spacings are 12 and 13 samples and their median is one of them
    period = float(starts[-1] - starts[0]) / (starts.size - 1) if starts.size > 1 else t1 - t0
    freq = 1.0 / period if period > 0 else 0.0
    fly = float(np.median([max(r[1] - r[0], jump_s) for r in runs]))
    return Segment(
        t0, t1, "steps", sense, round(float(np.median([r[2] for r in runs])), 3), freq,
        "ramp", len(runs), ramp_ratio=max(0.0, 1.0 - fly * freq),
        flyback_resolution=jump_s * freq,
    )  # fmt: skip


def _describe_by_turns(
    t0: float, t1: float, ts: np.ndarray, us: np.ndarray, ends: tuple[float, float],
    jump_s: float,
) -> Segment:  # fmt: skip
    """A stretch by its turning points: a scan if monotonic, else a burst whose flybacks
    (some or all resolved) are the faster half of each period. ``ends``: the input at t0
    and t1 [V]."""
    u_start, u_end = ends
    du = np.diff(us)
    sig = np.sign(du[np.abs(du) > 1e-9])
    turns = int(np.sum(sig[1:] != sig[:-1])) if sig.size > 1 else 0
    if turns <= 2:
        # one sawtooth period whose flyback the samples resolve: a fast return, not a
        # scan out and back
        sense, runs = _flyback_runs(ts, us)
        if len(runs) == 1 and runs[0][1] - runs[0][0] < SINGLE_FLYBACK * (t1 - t0):
            return _describe_by_runs(t0, t1, sense, runs, jump_s)
        return Segment(
            t0, t1, "scan", int(np.sign(u_end - u_start)) or 1, round(abs(u_end - u_start), 3)
        )
    # periodic triangle: its up/down turning points
    k = np.flatnonzero(sig[1:] != sig[:-1])
    tt = ts[1:][k]
    down = tt[sig[1:][k] < 0] if sig.size else tt
    period = float(np.median(np.diff(down))) if down.size > 1 else (t1 - t0)
    amp = float(np.ptp(us))
    # the slower half of each period is the stepping ramp
    up_time = float(np.sum(np.diff(ts)[du > 0]))
    dn_time = float(np.sum(np.diff(ts)[du < 0]))
    direction = 1 if up_time >= dn_time else -1
    freq = 1.0 / period if period > 0 else 0.0
    return Segment(
        t0, t1, "steps", direction, round(amp, 3), freq,
        "ramp", max(round((t1 - t0) / period), 1) if period > 0 else 1,
        ramp_ratio=max(up_time, dn_time) / (up_time + dn_time) if up_time + dn_time > 0
        else math.nan, flyback_resolution=jump_s * freq,
    )  # fmt: skip


def flyback_corners(
    reading: DriveReading, segments: list[Segment]
) -> tuple[np.ndarray, np.ndarray]:
    """The model's drive [s], [V]: the reading's breakpoints with the corners of each
    flyback the samples resolve, in a sampled drive's bursts.

    A flyback with two or more samples on it (a = 0.99 at 100 Hz on a 25 kHz DAQ: 2.5
    samples) is a line through them; read linear from the ramp's last sample to its next
    first one, it lasts up to one interval more than the generator's, and the model,
    slipping on the flyback's speed, steps differently (4.5 V, 100 Hz at 25 kHz: −84.7
    µrad over three periods against the generator's −73.4). The line through the samples
    between its first and last change meets the ramp before it and the ramp after it, each
    the line through the sample one further out and its outer interval's slope (the sample
    next to the flyback may lie on it already, its interval's ramp outweighing the drop):
    each corner is put where it falls between those samples (stop 91). The segments'
    descriptions stay those of the samples (:func:`segment_trace`). The fit's drive where
    a file declares ``drive_flybacks: linear`` (:attr:`~.trace_fit.TraceData.breakpoints`);
    not yet the default.
    """
    t, u = reading.time, reading.level
    if reading.recording != "sampled" or t.size < 4:
        return t, u
    dt = reading.sample_interval
    add_t: list[float] = []
    add_u: list[float] = []
    for seg in segments:
        if seg.kind != "steps" or not seg.direction:
            continue
        i0, i1 = np.searchsorted(t, [seg.start, seg.end])
        i0, i1 = max(i0 - 3, 0), min(i1 + 4, t.size)  # three samples of the holds beside it
        ts, us = t[i0:i1], u[i0:i1]
        du, dts = np.diff(us), np.diff(ts)
        against = du * seg.direction < 0.0
        k = 0
        while k < du.size:
            if not against[k]:
                k += 1
                continue
            j = k
            while j + 1 < du.size and against[j + 1]:
                j += 1
            # changes k..j against the ramp: samples k+1..j lie on the flyback; the samples
            # beside it, k and j + 1, may lie on it too, with the ramp's rise in their
            # interval outweighing its share of the drop: each ramp is the line through the
            # sample next to them and its outer interval's slope
            on = slice(k + 1, j + 1)
            if j - k >= 2 and np.all(dts[k + 1 : j] > 0.5 * dt):  # two samples on it
                slope, icpt = np.polyfit(ts[on] - ts[k + 1], us[on], 1)
                # (anchor sample, its ramp interval, the corner's interval), each side on
                # the sampling clock (not beside a change read as a jump)
                ends = ((k - 1, k - 2, k - 1, k + 1), (j + 2, j + 2, j, j + 2))
                for anchor, nb, lo, hi in ends:
                    if not (0 <= min(nb, lo) and max(nb, hi) < du.size) or np.any(
                        dts[min(nb, lo) : max(nb, hi) + 1] < 0.5 * dt
                    ):
                        continue
                    s_r = du[nb] / dts[nb]
                    if du[nb] * seg.direction < 0.0 or s_r == slope:
                        continue  # not a ramp (or the hold) beside the flyback
                    x = (icpt - us[anchor] + s_r * ts[anchor] - slope * ts[k + 1]) / (s_r - slope)
                    if ts[lo] < x < ts[hi] and not np.any(np.isclose(x, ts[lo : hi + 1])):
                        add_t.append(float(x))
                        add_u.append(float(us[anchor] + s_r * (x - ts[anchor])))
            k = j + 1
    if not add_t:
        return t, u
    # a burst cut between the portions at a flyback finds that flyback's corners twice
    _, first = np.unique(np.round(add_t, 12), return_index=True)  # to 1 ps
    add_t = np.asarray(add_t)[first]
    at = np.concatenate([t, add_t])
    order = np.argsort(at, kind="stable")
    return at[order], np.concatenate([u, np.asarray(add_u)[first]])[order]


def segment_trace(reading: DriveReading, t_end: float | None = None) -> list[Segment]:
    """Cut the drive into hold, scan and steps segments (module docstring); they cover
    [first breakpoint, ``t_end``] without gaps, in time order."""
    t, u = reading.time, reading.level
    t_end = float(t[-1]) if t_end is None else float(t_end)
    quiet = _quiet_runs(t, u)
    jump_s = reading.sample_interval if reading.recording == "sampled" else 0.0
    segs: list[Segment] = []
    cursor = float(t[0])
    for q0, q1 in quiet:
        if q0 > cursor + 1e-12:
            segs.append(_describe_active(cursor, q0, t, u, reading.jumps, jump_s))
        segs.append(Segment(q0, q1, "hold"))
        cursor = q1
    if t_end > cursor + 1e-12:
        segs.append(_describe_active(cursor, t_end, t, u, reading.jumps, jump_s))
    return [s for s in segs if s.end > s.start]


def _halves(seg: Segment) -> tuple[Segment, Segment]:
    """A segment cut in two: a burst at a period boundary, else at its middle."""
    if seg.kind == "steps" and seg.periods >= 2 and seg.frequency > 0:
        cut = seg.start + math.ceil(seg.periods / 2) / seg.frequency
        cut = min(max(cut, seg.start), seg.end)
        n1 = math.ceil(seg.periods / 2)
        return (
            replace(seg, end=cut, periods=n1),
            replace(seg, start=cut, periods=seg.periods - n1),
        )
    mid = 0.5 * (seg.start + seg.end)
    return replace(seg, end=mid), replace(seg, start=mid)


def motion_before(segments: list[Segment]) -> list[Segment | None]:
    """The last motion (scan or burst) before each segment; None where none came before.
    ``segments`` in time order."""
    out: list[Segment | None] = []
    before = None
    for s in segments:
        out.append(before)
        if s.kind != "hold":
            before = s
    return out


def _motion_before(segments: list[Segment]) -> list[int]:
    """The direction of the last motion before each segment (:func:`motion_before`); 0
    where none came before."""
    return [m.direction if m is not None else 0 for m in motion_before(segments)]


def holds_by_motion(segments: list[Segment]) -> dict[str, Counter]:
    """portion → Counter of the direction of the motion before each of its holds (+1, −1;
    0 where no motion came before). ``segments`` in time order, their portions set; a
    hold cut in two counts in each portion it reaches."""
    out: dict[str, Counter] = {"fit": Counter(), "heldout": Counter()}
    for s, before in zip(segments, _motion_before(segments), strict=True):
        if s.kind == "hold":
            out[s.portion][before] += 1
    return out


def one_sided(counts: dict[str, Counter]) -> bool:
    """Whether a portion's counted segments all go one way while the trace has both
    (``counts``: portion → Counter over +1 / −1, 0 not counted; from
    :func:`holds_by_motion`, the holds after motion, or the scans by their sense)."""
    both = {d for c in counts.values() for d in c if d != 0} == {-1, 1}
    return both and any(c[1] + c[-1] > 0 and not (c[1] and c[-1]) for c in counts.values())


def _interleave(segments: list[Segment], conditions: list[str]) -> list[Segment]:
    """Each condition's occurrences alternate fit, held-out, fit, …; a condition that
    occurs once is cut in two (first half fit)."""
    by_cond: dict[str, list[int]] = {}
    for i, c in enumerate(conditions):
        by_cond.setdefault(c, []).append(i)
    out: list[Segment] = []
    portion: dict[int, str] = {}
    single: set[int] = set()
    for idx in by_cond.values():
        if len(idx) == 1:
            single.add(idx[0])
        for k, i in enumerate(idx):
            portion[i] = "fit" if k % 2 == 0 else "heldout"
    for i, s in enumerate(segments):
        if i in single:
            a, b = _halves(s)
            out += [replace(a, portion="fit"), replace(b, portion="heldout")]
        else:
            out.append(replace(s, portion=portion[i]))  # type: ignore[arg-type]
    return [s for s in out if s.end > s.start]


def split_portions(segments: list[Segment]) -> list[Segment]:
    """Fit and held-out portions interleaved by drive condition (module docstring): the
    occurrences of each condition alternate fit, held-out, fit, …; a condition that occurs
    once is cut in two (first half fit). Where that leaves a portion with holds after one
    direction only (:func:`one_sided`), each hold's condition is the direction of the
    motion before it."""
    conditions = [s.condition for s in segments]
    out = _interleave(segments, conditions)
    if one_sided(holds_by_motion(out)):
        conditions = [
            f"hold after {'+' if b > 0 else '-' if b < 0 else 'none'}" if s.kind == "hold" else c
            for s, b, c in zip(segments, _motion_before(segments), conditions, strict=True)
        ]
        out = _interleave(segments, conditions)
    return out
