"""Residual statistics judged against the data's own noise: anchoring, noise floor,
structure, spectral peaks, ringing after flybacks, correlations.

* **Anchored residual.** A stick–slip positioner integrates its steps, so a model whose
  step is 1 % short drifts away from the measurement for ever. The calibrator compares
  each segment (:mod:`.segments`) as a prediction from where the table *was*: the error
  e = measured − model (detector volts → nm at R_table, Eq. 4.1–4.2 linearised) minus
  its mean over the ``ANCHOR`` window just before the segment starts. The model itself
  runs the whole drive once, so every segment starts from the state the drive history
  left it in; only the position offset is re-read, as a lab re-reads its encoder. The
  offset is re-read only where stepping has happened since the last reading (a steps
  segment, or the first segment after one): holds and scans that follow holds and
  scans continue their predecessor's anchor — multiple shooting with continuity where
  the model's position error cannot have grown — so slow effects (creep, drift) are
  judged over the whole stretch, not only by their slope within one segment.
* **Noise floor.** From the data, never assumed: the detector's white noise σ from the
  first differences in quiet holds (robust: 1.4826·MAD(Δv)/√2, insensitive to slow drift
  or creep), or from the residual's first differences where the file has no holds; the
  floor of an anchored error is σ·√(1 + 1/n_anchor).
* **Structure.** The residual's excess over the floor, √(max(0, RMS² − floor²)); a
  whiteness test is not used (on 10⁴ samples any model error fails it).
* **Where the error is.** The held-out squared error split by drive condition
  (:func:`condition_shares`): each steps or scan segment under its own condition, each
  hold under the motion before it (the settling after a burst is that burst's error),
  so a report says which settings the model fails on.
* **Signatures.** Spectral peaks above ``PEAK_MIN_HZ`` (Welch, each at least
  ``PEAK_FACTOR`` times the local median level), ringing after flybacks (the residual's
  RMS in the ``RING_WINDOW`` after each step vs elsewhere, its dominant frequency from
  the synchronous average), and correlations with time, position, velocity, direction
  and drive level.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import scipy.signal
import scipy.stats

from .segments import Segment, motion_before, quantisation_step

__all__ = [
    "ANCHOR",
    "Anchoring",
    "PredictiveComparison",
    "compare_predictions",
    "condition_shares",
    "correlation_length",
    "correlation_tests",
    "noise_floor",
    "own_ring",
    "ringing",
    "spectral_peaks",
    "structured_rms",
]

ANCHOR = 1e-3  # s, window before a segment whose mean error re-reads the position
ANCHOR_MIN = 10  # samples in the anchor window at least
SETTLE = 5e-3  # s, start of a hold skipped for the noise estimate (settling, creep)
PEAK_MIN_HZ = 5.0  # Hz, lowest frequency searched for peaks (below: trends)
PEAK_FACTOR = 8.0  # a peak's PSD over the local median PSD
RING_WINDOW = 5e-3  # s, after a flyback searched for ringing
MAD_SCALE = 1.4826  # MAD → σ of a normal distribution


@dataclass(frozen=True, eq=False)
class Anchoring:
    """Sample structure of one trace's anchored residual.

    Attributes:
        unit: (n,) index of the segment each sample belongs to (−1: not compared).
        fit: (n,) True on fit-portion samples; heldout: (n,) True on held-out ones.
        anchor_start, anchor_end: (n_segments,) sample range of each segment's anchor.
        mean_anchor: mean anchor length [samples].
    """

    unit: np.ndarray
    fit: np.ndarray
    heldout: np.ndarray
    anchor_start: np.ndarray
    anchor_end: np.ndarray
    mean_anchor: float

    @classmethod
    def of(cls, time: np.ndarray, segments: list[Segment]) -> Anchoring:
        t = np.asarray(time, float)
        n = t.size
        dt = float(np.median(np.diff(t)))
        n_a = max(ANCHOR_MIN, round(ANCHOR / dt))
        unit = np.full(n, -1, np.int64)
        fit = np.zeros(n, bool)
        a0 = np.zeros(len(segments), np.int64)
        a1 = np.zeros(len(segments), np.int64)
        for k, s in enumerate(segments):
            i0 = int(np.searchsorted(t, s.start, "left"))
            i1 = int(np.searchsorted(t, s.end, "left")) if k + 1 < len(segments) else n
            if i1 <= i0:
                a0[k], a1[k] = i0, min(i0 + 1, n)
                continue
            if k > 0 and s.kind != "steps" and segments[k - 1].kind != "steps" and a1[k - 1] > 0:
                # no stepping since the last anchor: the model's position error has not
                # grown, so the segment continues its predecessor's anchor (creep and drift
                # stay visible across holds and scans)
                a0[k], a1[k] = a0[k - 1], a1[k - 1]
            elif i0 >= n_a:
                a0[k], a1[k] = i0 - n_a, i0
            else:  # the trace's first segment: anchored on its own start
                a0[k], a1[k] = i0, min(i0 + n_a, i1)
            unit[i0:i1] = k
            fit[i0:i1] = s.portion == "fit"
        heldout = (unit >= 0) & ~fit
        return cls(unit, fit, heldout, a0, a1, float(np.mean(a1 - a0)) if a1.size else 1.0)

    def apply(self, error: np.ndarray) -> np.ndarray:
        """The anchored error: each segment's error minus its anchor window's mean (0 on
        samples no segment covers)."""
        e = np.asarray(error, float)
        cs = np.concatenate([[0.0], np.cumsum(e)])
        anchor = (cs[self.anchor_end] - cs[self.anchor_start]) / np.maximum(
            self.anchor_end - self.anchor_start, 1
        )
        out = np.zeros_like(e)
        ok = self.unit >= 0
        out[ok] = e[ok] - anchor[self.unit[ok]]
        return out


def condition_shares(
    segments: list[Segment], anchoring: Anchoring, residual: np.ndarray, top: int = 6
) -> list[dict[str, Any]]:
    """The held-out squared error of one anchored residual [nm] by drive condition, largest
    share first: per condition its held-out ``samples``, ``rms`` [nm] and ``share`` of the
    held-out sum of squares (the shares add up to 1). A steps or scan segment counts under
    its own :attr:`~.segments.Segment.condition`; a hold under "hold after" the last steps
    or scan before it (its settling is that motion's), or "hold" where none came before.
    Beyond the ``top`` largest, the rest are pooled as "others"."""
    r = np.asarray(residual, float)
    held = anchoring.heldout
    if r.shape != held.shape:
        raise ValueError(f"residual: {r.size} samples, the anchoring has {held.size}")
    labels = [
        s.condition if s.kind != "hold" else "hold" if m is None else f"hold after {m.condition}"
        for s, m in zip(segments, motion_before(segments), strict=True)
    ]
    sums: dict[str, list[float]] = {}
    for k in np.unique(anchoring.unit[held]):
        m = held & (anchoring.unit == k)
        acc = sums.setdefault(labels[int(k)], [0.0, 0.0])
        acc[0] += float(r[m] @ r[m])
        acc[1] += float(np.count_nonzero(m))
    total = sum(v[0] for v in sums.values())
    rows = sorted(sums.items(), key=lambda kv: -kv[1][0])
    if len(rows) > top + 1:
        rest = rows[top:]
        rows = [*rows[:top], ("others", [sum(v[0] for _, v in rest), sum(v[1] for _, v in rest)])]
    return [{"condition": c, "samples": int(n), "rms": math.sqrt(sq / max(n, 1.0)),
             "share": sq / total if total > 0 else 0.0} for c, (sq, n) in rows]  # fmt: skip


def _mad_sigma(d: np.ndarray) -> float:
    return MAD_SCALE * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0)


def _std_sigma(d: np.ndarray) -> float:
    return float(np.std(d)) / math.sqrt(2.0)


def noise_floor(
    time: np.ndarray, signal: np.ndarray, segments: list[Segment]
) -> tuple[float, str, int]:
    """White-noise σ of a detector signal [its unit] from its first differences in the
    quiet holds: (σ, source, samples used); (nan, "", 0) with fewer than 50 quiet samples
    (the caller then uses another estimate).

    Each hold's second half (past ``SETTLE``) gives an estimate; a lightly damped table
    still rings in some holds, so only the holds within 1.5× of the lower quartile of
    the estimates are pooled (robust MAD of their differences). A signal quantised by a
    step q (an ADC's) is estimated by the standard deviation of its differences instead,
    and never under its quantisation noise q/√12: a 12-bit ±10 V ADC under 1 mV of noise
    reads most quiet samples alike, the MAD of their differences is 0 (a floor of 0
    divided the feature misfits by zero), and a hold near a step's edge toggles. In an
    unquantised record a hold whose differences are all but zero (a detector clipped at
    its range) gives no estimate."""
    t = np.asarray(time, float)
    v = np.asarray(signal, float)
    step = quantisation_step(v)
    sigma = _mad_sigma if step == 0.0 else _std_sigma
    diffs, est = [], []
    for s in segments:
        if s.kind != "hold" or s.duration < 2 * SETTLE:
            continue
        sel = (t >= max(s.start + SETTLE, 0.5 * (s.start + s.end))) & (t < s.end)
        if sel.sum() > 30:
            d = np.diff(v[sel])
            e = sigma(d)
            if e > 0.0 or step > 0.0:
                diffs.append(d)
                est.append(e)
    pooled, source, n = math.nan, "", 0
    if est:
        q = float(np.quantile(est, 0.25))
        d = np.concatenate([d for d, e in zip(diffs, est, strict=True) if e <= 1.5 * q])
        if d.size >= 50:
            pooled, source, n = sigma(d), "first differences in quiet holds", int(d.size)
    adc = step / math.sqrt(12.0)
    if adc > 0.0 and not pooled >= adc:
        return adc, f"the signal's quantisation step {step:.3g} over √12", n
    return pooled, source, n


def residual_sigma(residual: np.ndarray) -> float:
    """White-noise σ of a residual from its first differences (robust)."""
    r = np.asarray(residual, float)
    return _mad_sigma(np.diff(r)) if r.size > 10 else math.nan


def structured_rms(rms: float, floor: float) -> float:
    """The residual's RMS beyond the noise floor: √(max(0, rms² − floor²))."""
    return math.sqrt(max(0.0, rms**2 - floor**2))


def spectral_peaks(
    time: np.ndarray, residual: np.ndarray, *, max_peaks: int = 3
) -> list[dict[str, float]]:
    """Peaks of the residual's Welch spectrum above ``PEAK_MIN_HZ``: each
    ``{"frequency_Hz", "share", "prominence"}`` (share: of the residual's power in the
    searched band; prominence: PSD over the local median), strongest first."""
    t = np.asarray(time, float)
    r = np.asarray(residual, float)
    if t.size < 64:
        return []
    dt = float(np.median(np.diff(t)))
    tu = np.arange(t[0], t[-1], dt)
    ru = np.interp(tu, t, r)
    nper = int(min(tu.size, max(256, round(1.0 / (PEAK_MIN_HZ * dt)))))
    f, p = scipy.signal.welch(ru, fs=1.0 / dt, nperseg=nper, detrend="linear")
    band = f >= PEAK_MIN_HZ
    if band.sum() < 8:
        return []
    fb, pb = f[band], p[band]
    base = _running_median(pb)
    prom = pb / np.maximum(base, 1e-300)
    idx, _ = scipy.signal.find_peaks(prom, height=PEAK_FACTOR)
    total = float(np.sum(pb)) or 1.0
    out = []
    for i in sorted(idx, key=lambda i: -pb[i])[:max_peaks]:
        lo, hi = max(i - 1, 0), min(i + 2, pb.size)
        out.append(
            {
                "frequency_Hz": float(fb[i]),
                "share": float(np.sum(pb[lo:hi]) / total),
                "prominence": float(prom[i]),
            }
        )
    return out


def _running_median(p: np.ndarray, half: int = 10) -> np.ndarray:
    pad = np.concatenate([np.full(half, np.nan), p, np.full(half, np.nan)])
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1)
    return np.nanmedian(win, axis=1)


def ringing(
    time: np.ndarray, residual: np.ndarray, jumps: np.ndarray, compared: np.ndarray
) -> dict[str, float] | None:
    """Residual after the flybacks: RMS in the ``RING_WINDOW`` after each step over the
    RMS elsewhere (``ratio``), and the dominant frequency of their synchronous average
    [Hz]; None without steps."""
    t = np.asarray(time, float)
    r = np.asarray(residual, float)
    dt, n_w, starts = _flyback_windows(t, jumps)
    if starts.size == 0:
        return None
    mask = np.zeros(t.size, bool)
    windows = []
    for i in starts:
        if compared[i : i + n_w].all():
            mask[i : i + n_w] = True
            w = r[i : i + n_w]
            windows.append(w - w.mean())
    if not windows or (compared & ~mask).sum() < 10:
        return None
    rms_in = float(np.sqrt(np.mean(r[mask] ** 2)))
    rms_out = float(np.sqrt(np.mean(r[compared & ~mask] ** 2)))
    # the dominant frequency of the windows' power spectra (phase-independent)
    spec = np.mean([np.abs(np.fft.rfft(w, 4 * n_w)) ** 2 for w in windows], axis=0)
    freqs = np.fft.rfftfreq(4 * n_w, dt)
    ok = freqs > 1.0 / RING_WINDOW
    f_peak = float(freqs[ok][np.argmax(spec[ok])]) if ok.any() else math.nan
    return {
        "ratio": rms_in / max(rms_out, 1e-300),
        "rms_after_flyback": rms_in,
        "rms_elsewhere": rms_out,
        "frequency_Hz": f_peak,
        "flybacks": len(windows),
    }


def _flyback_windows(t: np.ndarray, jumps: np.ndarray) -> tuple[float, int, np.ndarray]:
    """(sample interval [s], window length [samples], first sample of each window): one
    ``RING_WINDOW`` after each flyback within the trace (an overshoot's two jumps are one
    flyback)."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    n_w = max(round(RING_WINDOW / dt), 8)
    starts = np.searchsorted(t, np.asarray(jumps, float))
    starts = starts[starts + n_w < t.size]
    if starts.size:
        starts = starts[np.concatenate([[True], np.diff(starts) > n_w // 4])]
    return dt, n_w, starts


def own_ring(time: np.ndarray, signal: np.ndarray, jumps: np.ndarray) -> float:
    """The dominant frequency [Hz] a signal rings at after the drive's jumps: in the
    ``RING_WINDOW`` after each flyback, a quadratic (the table's own motion) removed, the
    peak of the mean power spectrum above 1/``RING_WINDOW``; nan without a flyback. Read
    on the data and on the model alike, it says whose mode a ring in the residual is."""
    t = np.asarray(time, float)
    v = np.asarray(signal, float)
    dt, n_w, starts = _flyback_windows(t, jumps)
    if starts.size == 0 or t.size < 16:
        return math.nan
    x = np.linspace(-1.0, 1.0, n_w)
    basis = np.column_stack([np.ones(n_w), x, x**2])
    q, _ = np.linalg.qr(basis)
    spec = np.zeros(2 * n_w + 1)
    for i in starts:
        w = v[i : i + n_w]
        w = w - q @ (q.T @ w)
        spec += np.abs(np.fft.rfft(w, 4 * n_w)) ** 2
    freqs = np.fft.rfftfreq(4 * n_w, dt)
    ok = freqs > 1.0 / RING_WINDOW
    return float(freqs[ok][np.argmax(spec[ok])]) if ok.any() else math.nan


CORR_LAG = 10e-3  # s, largest lag of the residual correlation tests


def _xcorr(a: np.ndarray, b: np.ndarray, max_lag: int) -> np.ndarray:
    """Normalised cross-correlation of a and b (means removed) at lags −max_lag…max_lag."""
    a = a - a.mean()
    b = b - b.mean()
    den = math.sqrt(float(a @ a) * float(b @ b))
    if den == 0.0:
        return np.zeros(2 * max_lag + 1)
    n = a.size
    fa = np.fft.rfft(a, 2 * n)
    fb = np.fft.rfft(b, 2 * n)
    c = np.fft.irfft(fa * np.conj(fb), 2 * n)
    return np.concatenate([c[-max_lag:], c[: max_lag + 1]]) / den


def correlation_tests(
    time: np.ndarray, residual: np.ndarray, drive: np.ndarray
) -> dict[str, dict[str, float]]:
    """Billings and Voon's correlation tests of a nonlinear model's residual ε against its
    input u (Billings & Voon 1986, "Structure detection and model validity tests in the
    identification of nonlinear systems"): a model that leaves no predictable structure has
    φ_εε(τ) = δ(τ), φ_uε(τ) = 0, φ_u²'ε(τ) = 0, φ_u²'ε²(τ) = 0 and φ_ε(εu)(τ) = 0 for
    τ ≥ 0 (u²' = u² − mean). Per test over |τ| ≤ ``CORR_LAG`` (τ ≠ 0 for the
    autocorrelation): the largest |φ|, the 95 % band 1.96/√N, their ratio and the share
    of lags outside the band (about 5 % for a white residual; the largest of hundreds of
    lags reaches 1.5–2 bands by chance); a test far outside says which dependence is
    left: on the input (linear dynamics), on its square (an even nonlinearity such as a
    direction-independent loss), on the residual itself
    (unmodelled dynamics or a slow effect)."""
    t = np.asarray(time, float)
    e = np.asarray(residual, float)
    u = np.asarray(drive, float)
    n = e.size
    if n < 64:
        return {}
    dt = float(np.median(np.diff(t)))
    lag = int(min(max(round(CORR_LAG / dt), 1), n // 4))
    u2 = u**2 - np.mean(u**2)
    ec = e - e.mean()
    tests = {
        "residual_autocorrelation": _xcorr(e, e, lag),
        "input": _xcorr(u, e, lag),
        "input_squared": _xcorr(u2, e, lag),
        "input_squared_residual_squared": _xcorr(u2, ec**2, lag),
        "residual_residual_input": _xcorr(e, ec * (u - u.mean()), lag)[lag:],
    }
    tests["residual_autocorrelation"][lag] = 0.0  # φ_εε(0) = 1 by definition
    band = 1.96 / math.sqrt(n)
    return {
        k: {"max_abs": float(np.max(np.abs(v))), "band": band,
            "ratio": float(np.max(np.abs(v)) / band),
            "share_outside": float(np.mean(np.abs(v) > band))}
        for k, v in tests.items()
    }  # fmt: skip


def correlation_length(r: np.ndarray, max_lag: int = 2000) -> float:
    """Integrated autocorrelation length of a residual [samples]: 1 + 2Σρ_k up to the
    first lag where ρ falls below 0.05 (≥ 1)."""
    r = np.asarray(r, float) - np.mean(r)
    n = r.size
    if n < 20:
        return 1.0
    f = np.fft.rfft(r, 2 * n)
    ac = np.fft.irfft(f * np.conj(f))[: min(max_lag, n // 4)]
    if ac[0] <= 0:
        return 1.0
    rho = ac / ac[0]
    below = np.nonzero(rho < 0.05)[0]
    k = int(below[0]) if below.size else rho.size
    return float(max(1.0, 1.0 + 2.0 * np.sum(rho[1:k])))


class PredictiveComparison(NamedTuple):
    """Two models' predictions of the same held-out samples compared
    (:func:`compare_predictions`).

    Attributes:
        rms_with: the candidate model's RMS error [nm]; rms_without: the model without
            the candidate's addition [nm].
        gain: 1 − rms_with / rms_without (positive: the candidate predicts better).
        z: the signed-rank statistic of the squared-error difference over blocks
            (positive: the candidate predicts better; ≈ N(0, 1) when both predict
            equally well).
        blocks: the blocks it rests on (segments, long ones split; those where the two
            agree exactly left out); block: the length a long segment is split into
            [samples] (5 correlation lengths of the loss difference).
    """

    rms_with: float
    rms_without: float
    gain: float
    z: float
    blocks: int
    block: int

    def to_json(self) -> dict[str, Any]:
        return dict(self._asdict())

    def text(self, unit: str = "nm") -> str:
        """"held-out 3.37 against 3.31 nm (+1.8 %, z −0.6 over 14 blocks)"."""
        return (f"held-out {self.rms_with:.3g} against {self.rms_without:.3g} {unit} "
                f"({-self.gain:+.1%}, z {self.z:+.1f} over {self.blocks} blocks)")  # fmt: skip


MIN_BLOCKS = 5  # blocks below which a comparison is not made (z = 0: undecided)
BLOCK_LENGTHS = 5.0  # a block spans this many correlation lengths of the loss difference


def _blocks(n: int, block: int, units: np.ndarray | None) -> np.ndarray:
    """First sample index of each block: each run of equal ``units`` (a segment) split into
    pieces of at least ``block`` samples (a segment shorter than that is one block; the
    split of ``np.array_split``: the first pieces one sample longer); without units, the
    whole record is one run. The blocks cover the n samples in order."""
    if units is None:
        bounds = np.array([0, n])
    else:
        bounds = np.concatenate([[0], np.flatnonzero(np.diff(units)) + 1, [n]])
    starts = []
    for s, e in itertools.pairwise(bounds):
        k = max(1, int(e - s) // block)  # pieces of this run
        pieces, extra = divmod(int(e - s), k)
        sizes = np.full(k, pieces)
        sizes[:extra] += 1
        starts.append(s + np.concatenate([[0], np.cumsum(sizes)[:-1]]))
    return np.concatenate(starts).astype(np.int64)


def compare_predictions(
    r_with: np.ndarray, r_without: np.ndarray, units: np.ndarray | None = None
) -> PredictiveComparison:
    """Equal predictive accuracy of two models on the same held-out samples: Wilcoxon's
    signed-rank test of the squared-error difference d = r_without² − r_with² over
    blocks, one of the tests of Diebold & Mariano (1995, §3.2) for loss differentials
    that are not normal. The blocks are the segments the samples belong to (``units``:
    the anchored residual is re-read at each segment, :class:`Anchoring`), a segment
    longer than ``BLOCK_LENGTHS`` correlation lengths of d (:func:`correlation_length`)
    split into pieces that long, so the block means are nearly independent; z is the
    signed rank sum's normal approximation (scipy.stats.wilcoxon; blocks where the two
    agree exactly are dropped), positive when ``r_with`` is the smaller error. A model
    residual is correlated over hundreds of samples, so counting samples as independent
    would make any difference significant; the blocks keep z ≈ N(0, 1) when the two
    predict equally well (``tests/test_trace_verdicts.py``). Ranks, not the block means
    themselves: an effect's error is concentrated in a few segments (a worn contact's
    shrinking steps: the t statistic of its block means stayed at 1.9 for a held-out
    error cut from 51 to 2.9 nm, held down by its largest block). With fewer than
    ``MIN_BLOCKS`` blocks that differ, z is 0 (undecided); B blocks bound |z| by
    √(3B(B+1)/(2B+1)). Residuals [nm]; raises ValueError on unequal or non-finite
    inputs."""
    a = np.asarray(r_with, float).ravel()
    b = np.asarray(r_without, float).ravel()
    if a.shape != b.shape:
        raise ValueError(f"residuals: {a.size} samples against {b.size}")
    if units is not None and np.shape(units) != a.shape:
        raise ValueError(f"units: {np.size(units)} labels for {a.size} samples")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("residuals: not finite")
    if a.size == 0:
        raise ValueError("residuals: empty")
    rms_a, rms_b = float(np.sqrt(np.mean(a**2))), float(np.sqrt(np.mean(b**2)))
    gain = 1.0 - rms_a / rms_b if rms_b > 0 else 0.0
    d = b**2 - a**2
    block = max(1, math.ceil(BLOCK_LENGTHS * correlation_length(d)))
    starts = _blocks(d.size, block, units)  # block means, in one pass over the samples
    means = np.add.reduceat(d, starts) / np.diff(np.append(starts, d.size))
    means = means[means != 0.0]
    z = 0.0
    if means.size >= MIN_BLOCKS:
        test = scipy.stats.wilcoxon(means, zero_method="wilcox", correction=False,
                                    method="approx")  # fmt: skip
        ranks = scipy.stats.rankdata(np.abs(means))
        lead = float(ranks[means > 0].sum() - ranks[means < 0].sum())
        z = math.copysign(abs(float(test.zstatistic)), lead) if lead != 0 else 0.0
    return PredictiveComparison(rms_a, rms_b, gain, float(z), int(means.size), int(block))
