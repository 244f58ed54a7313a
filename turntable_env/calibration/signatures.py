"""Signatures: protocol features of a trace, and the effects each one must explain.

A whole-trace error is dominated by the fast transients (the ring after a flyback), where
a model of another structure is always somewhat off; an effect the model lacks is
usually smaller there than that mismatch. Its *signature* is not: each catalogue effect
(:data:`~turntable_env.effects.CATALOGUE`) changes a few protocol features in its own
way, and those features are averages over milliseconds, robust to the transients.

Features are measured the same way on the data and on a model's output (detector volts
→ nm at R_table, Eq. 4.1–4.2 linearised), never on an anchored residual, so slow effects
(creep, drift, wear) stay visible. Each has a noise standard deviation from the data's
noise floor. The feature groups and the effects they name:

==========  ==============================================  ==================================
group       feature (one per ...)                           effects whose signature it is
==========  ==============================================  ==================================
steps       burst: net step per period, (level early in     (nominal: stroke, friction);
            the next hold − level before) / periods         friction_wear, amplifier_*
direction   pair of opposite bursts of one setting:         friction_asymmetry (constant per
            (|s₊| − |s₋|) / (|s₊| + |s₋|) of the steady     setting); friction_wear (the
            steps: time averages over two blocks of whole   pair's later burst, shrinking
            periods after the first (net step if < 3)      with the travel before it)
relaxation  hold ≥ ``MIN_HOLD_S``: late − early level (2    piezo_creep (∝ the move before,
            ms windows, the first after ``SETTLE_S``)       decaying), sensor_drift (∝ time)
scan        scan: gain over the normalised drive            (nominal: stroke, detector gain)
scan_shape  scan: 2nd and 3rd order terms over the gain;    piezo_hysteresis (bends a branch
            the loop of a scan and the next opposite one:   by its direction; a loop of one
            later − earlier branch at equal drive, over     sign), detector_nonlinearity
            the gain                                        (odd, cubic), sensor_drift (a
                                                            loop ∝ the time between scans,
                                                            alternating in sign)
scan_range  scan after the first: its gain per drive volt  detector_nonlinearity (the gain
            over the first scan's (the table has stepped   along the detector's range; a
            between them, so the scans read the detector   constant gain factor cancels)
            at other positions)
line        sine and cosine of the strongest spectral line  vibration
            in the holds (each hold's level, slope and
            curvature removed)
y           slope of the y channel on the x channel over    axis_misalignment
            the bursts' and scans' changes of level (a slow
            y drift, a vibration in the holds are not one)
==========  ==============================================  ==================================

The direction feature reads the steady step, not the net one: the first period of a burst
starts from the contacts' state in the hold before (after the scan's last direction, or
after the opposite burst), which differs between the pair's two bursts and which a model
of another friction law reproduces differently. On the second independent plant's clean
traces, whose steady steps agree by direction to 0.11 %, the net steps differ by up to
7.6 % (2 V at 2 kHz); the friction asymmetry the same plant is given shows in the steady
steps at every setting and in the net steps with the wrong sign at 2 kHz
(``python experiments/direction_steps.py``).

The loop is one group with the scan's shape: a group needs more features than a candidate
has parameters to estimate its own misfit variance (:func:`group_scores`), and one loop
per pair of scans is too few for that — judged against the detector noise alone, a model
of another structure would make any loop-shaped effect look certain.

The steps and scan gains are the nominal model's (:data:`NOMINAL_GROUPS`): a fitted
nominal model matches them as well as its structure allows, and an effect that changes
them is compensated by the joint refit; decisions are scored on the others
(:data:`SIGNATURE_GROUPS`).

:func:`group_scores` compares two models' features as a nested-model test per group:
the whitened residuals' sum of squares, with the variance inflated to the richer model's
misfit per degree of freedom where the group has enough features (an F-test: an effect
must explain a share of the misfit beyond what any free parameter would). In a group of
one quantity repeated over the protocol's settings (:data:`REPEATED_GROUPS`: the direction
pairs) the misfit is a common variance τ² added to each feature's noise variance
(:func:`misfit_variance`, the Paule–Mandel random-effects estimator of meta-analysis), not
a factor on it: the misfit of a model of another structure is of one size at every setting,
where the detector noise of a steady step falls with the samples averaged, so a factor
would weigh the pair with most samples many times the others and a gain would rest on it.
Such a group estimates its own misfit only with :data:`REPEATED_MIN` settings or more.
With one or two (since stop 105) the misfit a model of another structure can leave in a
pair is bounded from the step sizes instead (:func:`step_misfit_sd`): the robust scale of
the bursts' relative step misfits over √2, the misfit of a ratio of two steps each off by
that much independently. A model that misses the step sizes by 10 % is not trusted to a
direction ratio better than 7 %; a symmetric model's two steps of one setting share most
of their misfit, so the bound is generous. Without :data:`STEP_SCALE_MIN` bursts to bound
it from, such a group gains 0 nats, as before. On the third independent plant's traces
(one or two pairs each) the clean traces' pairs, −3.5 % and −8.8 % off the nominal fit (its
own geometry, at 4.5 V, 500 Hz and 2 V, 500 Hz), lie within bounds of 8.6 % and 10.8 %
(``python experiments/direction_bound.py``), and its 30 % friction asymmetry's +51 % at
3 V, 100 Hz gains friction asymmetry 41.6 nats against a bound of 5.5 % (docs/calibration.md,
stop 105).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.optimize

from .segments import Segment

__all__ = [
    "EFFECT_GROUPS",
    "GROUPS",
    "NOMINAL_GROUPS",
    "REPEATED_GROUPS",
    "REPEATED_MIN",
    "SIGNATURE_GROUPS",
    "Features",
    "SignatureLayout",
    "coverage",
    "group_scores",
    "misfit_variance",
    "step_misfit_sd",
]

SETTLE_S = 2e-3  # s skipped at a hold's start (the ring after a flyback)
WINDOW_S = 2e-3  # s, a level's averaging window
MIN_HOLD_S = 8e-3  # s, shortest hold whose relaxation is measured
LINE_FMIN_HZ = 5.0  # Hz, lowest line searched (below: trends)
LINE_FMAX_HZ = 1000.0  # Hz, highest (the catalogue's vibration range)
LINE_MIN_PERIODS = 0.2  # periods of the lowest line searched in the median hold
LINE_MIN_SAMPLES = 64  # hold samples (past settling) a line search needs
# the least |gain|/σ of the scan the others' gains are referred to (scan_range)
RANGE_REFERENCE_Z = 10.0
GROUPS = ("steps", "direction", "relaxation", "scan", "scan_shape", "scan_range", "line", "y")
# the groups of one quantity repeated over the protocol's settings (one unit, one misfit
# size): a model's misfit there is a variance common to every feature (:func:`group_scores`)
REPEATED_GROUPS = ("direction",)
# settings a repeated group needs to be scored at all: with fewer, one setting's misfit
# (which a model of another structure leaves somewhere) cannot be told from an effect's
# signature, nor can any feature be left out (:func:`group_scores`)
REPEATED_MIN = 3
# bursts whose relative step misfits bound a repeated group's misfit where it has fewer than
# REPEATED_MIN features (:func:`step_misfit_sd`), and the least |step|/σ a burst enters with
STEP_SCALE_MIN = 5
STEP_SCALE_Z = 10.0
# the groups no effect is needed for: the nominal model's own (stroke, friction, gain)
NOMINAL_GROUPS = ("steps", "scan")
# the groups an effect's signature lies in: decisions are scored on these
SIGNATURE_GROUPS = tuple(g for g in GROUPS if g not in NOMINAL_GROUPS)
# the feature groups an effect changes first (its signature)
EFFECT_GROUPS: dict[str, tuple[str, ...]] = {
    "amplifier_dynamics": ("steps",),
    "amplifier_fast_path": ("steps",),
    "amplifier_lag": ("steps",),
    "piezo_hysteresis": ("scan_shape",),
    "piezo_creep": ("relaxation",),
    "friction_asymmetry": ("direction",),
    # a pair's bursts run in time order: wear (μ with the travel) makes the later one differ
    "friction_wear": ("steps", "direction"),
    "axis_misalignment": ("y",),
    "detector_nonlinearity": ("scan_shape", "scan_range"),
    "sensor_drift": ("relaxation", "scan_shape"),
    "vibration": ("line",),
}


# what a protocol lacks where a group has too few features, and what a lab adds for it
MISSING = {
    "direction": f"{REPEATED_MIN} or more settings (amplitude, frequency, ramp ratio) each run "
                 "both ways, with a hold after each burst",
    "relaxation": f"holds of {MIN_HOLD_S * 1e3:g} ms or longer after the moves",
    "scan_shape": "a slow scan up and back down, with a hold but no burst between the two",
    "scan_range": "scans at two or more places of the detector's range (bursts between them)",
    "line": f"holds of {SETTLE_S * 1e3:g} ms + {LINE_MIN_SAMPLES} samples or longer in all to "
            "search for a line in",
    "y": "the detector's y channel (detector_y_V) and three moves or more",
}


def needed(group: str, bursts: int = 0) -> int:
    """The least features a group is scored with (:func:`group_scores`): for a repeated
    group :data:`REPEATED_MIN`, or one where ``bursts`` (the trace's net steps read) reach
    :data:`STEP_SCALE_MIN` to bound its misfit from (:func:`step_misfit_sd`; whether every
    one of them moves enough to enter is known only with the model); one for the others."""
    if group not in REPEATED_GROUPS:
        return 1
    return 1 if bursts >= STEP_SCALE_MIN else REPEATED_MIN


def coverage(counts: dict[str, int], effects: tuple[str, ...] | list[str]) -> dict[str, dict]:
    """What a protocol can test: per effect, the features of each of its signature groups
    (:data:`EFFECT_GROUPS` less :data:`NOMINAL_GROUPS`) that the trace has (``counts``:
    group → features read on the data; ``line``: the traces whose holds can be searched
    for one, whether or not a line was found, :attr:`SignatureLayout.line_searchable`),
    whether a group is scored (:func:`needed`: for a repeated group :data:`REPEATED_MIN`
    features, or one with :data:`STEP_SCALE_MIN` bursts; one for the others) and whether
    the effect can be named by its signature at all (one scored group). An effect without
    one cannot be named by its signature on this trace, only by the held-out trace error
    at the stricter bar (:func:`.identify.supports`); ``add`` says what protocol would give
    it one. An effect with no signature group of its own (the amplifier's: the step sizes a
    nominal refit restores) is ``testable`` None."""
    out: dict[str, dict] = {}
    for e in effects:
        groups = [g for g in EFFECT_GROUPS.get(e, ()) if g in SIGNATURE_GROUPS]
        rows = {}
        for g in groups:
            n = int(counts.get(g, 0))
            need = needed(g, int(counts.get("steps", 0)))
            rows[g] = {"features": n, "needed": need, "scored": n >= need}
        testable = any(r["scored"] for r in rows.values()) if rows else None
        add = [MISSING[g] for g, r in rows.items() if not r["scored"]] if testable is False else []
        out[e] = {"groups": rows, "testable": testable, "add": add}
    return out


class Features(NamedTuple):
    """Feature values of one trace: ``names``, ``groups`` (one per value), ``value`` [nm,
    nm per normalised volt, or − for the y slope] and ``noise`` (their standard deviation
    from the detector noise alone)."""

    names: tuple[str, ...]
    groups: tuple[str, ...]
    value: np.ndarray
    noise: np.ndarray

    def group(self, g: str) -> np.ndarray:
        return np.array([k == g for k in self.groups], bool)

    def subset(self, keep: np.ndarray) -> Features:
        """The features where the boolean mask ``keep`` is true."""
        k = np.asarray(keep, bool)
        return Features(tuple(n for n, m in zip(self.names, k, strict=True) if m),
                        tuple(g for g, m in zip(self.groups, k, strict=True) if m),
                        self.value[k], self.noise[k])  # fmt: skip


class _Span(NamedTuple):
    """A time interval [a, b) [s] and the samples inside it (i0 ≤ i < i1)."""

    a: float
    b: float
    i0: int
    i1: int


@dataclass(frozen=True, eq=False)
class _Burst:
    pre: tuple[int, int]  # sample range of the level before
    post: tuple[int, int]  # sample range of the level after (in the next hold)
    periods: int
    label: str
    direction: int
    setting: tuple[float, float, str]  # amplitude [V], frequency [Hz], flyback
    ramp_ratio: float  # a [-] as read (Segment.ramp_ratio), nan when not read
    resolution: float  # how far apart a reading of one a may fall [-]
    # the steady step: two blocks of whole periods after the first (None: fewer than 3
    # periods, or a block outside the record)
    early: _Span | None = None
    late: _Span | None = None

    @property
    def spacing(self) -> int:
        """Periods between the two blocks' centres: P − 1 − ⌊(P − 1)/2⌋."""
        return self.periods - 1 - (self.periods - 1) // 2


@dataclass(frozen=True, eq=False)
class _Hold:
    early: tuple[int, int]
    late: tuple[int, int]
    label: str


@dataclass(frozen=True, eq=False)
class _Scan:
    span: tuple[int, int]
    xi: np.ndarray  # drive normalised to −1…1 over the scan
    direction: int
    label: str
    lo: float  # drive range [V]
    hi: float
    # the table stepped since the scan before (a burst between them): no loop across them
    after_steps: bool = False


def _same_ramp(a: _Burst, b: _Burst) -> bool:
    """Whether two bursts' ramp ratios may be one: read less than the coarser reading's
    resolution (one sample interval of flyback) apart, or either not read. A ramp ratio
    of 0.97 and one of 0.99 at 200 Hz, sampled at 20 kHz, are two settings (three
    samples of flyback against one; the third independent plant's protocol mixes them,
    and there the slower flyback reverses the steps): an asymmetry read across them is
    the ramp ratio's, not friction's."""
    if not (math.isfinite(a.ramp_ratio) and math.isfinite(b.ramp_ratio)):
        return True
    return abs(a.ramp_ratio - b.ramp_ratio) < max(a.resolution, b.resolution, 1e-6)


def _window(t: np.ndarray, t0: float, t1: float) -> tuple[int, int]:
    return int(np.searchsorted(t, t0, "left")), int(np.searchsorted(t, t1, "left"))


def _mean(v: np.ndarray, w: tuple[int, int]) -> float:
    return float(np.mean(v[w[0] : w[1]]))


def _span(t: np.ndarray, a: float, b: float) -> _Span | None:
    """The interval [a, b) [s] with its samples; None where fewer than 3 lie inside or it
    reaches past the record."""
    i0, i1 = _window(t, a, b)
    if i1 - i0 < 3 or i0 == 0 or i1 >= t.size:
        return None
    return _Span(a, b, i0, i1)


def _span_mean(t: np.ndarray, v: np.ndarray, s: _Span) -> float:
    """Time average of the samples' linear interpolant over exactly [a, b): a window of
    whole periods then averages the periodic part of stick–slip motion out, whatever the
    sample rate and phase."""
    i0, i1 = s.i0, s.i1
    va = v[i0 - 1] + (v[i0] - v[i0 - 1]) * (s.a - t[i0 - 1]) / (t[i0] - t[i0 - 1])
    vb = v[i1 - 1] + (v[i1] - v[i1 - 1]) * (s.b - t[i1 - 1]) / (t[i1] - t[i1 - 1])
    tt = np.concatenate(([s.a], t[i0:i1], [s.b]))
    vv = np.concatenate(([va], v[i0:i1], [vb]))
    return float(np.sum(0.5 * (vv[1:] + vv[:-1]) * np.diff(tt)) / (s.b - s.a))


class SignatureLayout:
    """Where a trace's features are read (from its drive alone), built once per trace;
    :meth:`measure` reads them from any detector signal on the trace's samples.

    Args:
        time: sample times [s]; drive: amplifier input [V] at them; segments: the
        trace's segments (:mod:`.segments`); sigma_nm: the detector's white noise [nm];
        drive_frequencies: stepping frequencies [Hz] whose harmonics a line must avoid.
    """

    def __init__(
        self,
        time: np.ndarray,
        drive: np.ndarray,
        segments: list[Segment],
        sigma_nm: float,
    ) -> None:
        t = np.asarray(time, float)
        u = np.asarray(drive, float)
        self.time = t
        self.sigma = float(sigma_nm)
        dt = float(np.median(np.diff(t)))
        self.dt = dt
        self.bursts: list[_Burst] = []
        self.holds: list[_Hold] = []
        self.scans: list[_Scan] = []
        hold_idx: list[np.ndarray] = []
        # merge the fit/held-out halves of one burst (consecutive steps of one condition)
        runs: list[list[Segment]] = []
        for s in segments:
            if runs and s.kind == runs[-1][-1].kind and s.condition == runs[-1][-1].condition:
                runs[-1].append(s)
            else:
                runs.append([s])
        stepped = False  # a burst since the last scan kept
        for k, run in enumerate(runs):
            s0, s1 = run[0], run[-1]
            stepped |= s0.kind == "steps"
            if s0.kind == "hold" and s1.end - s0.start >= MIN_HOLD_S:
                a, b = s0.start + SETTLE_S, s1.end
                self.holds.append(
                    _Hold(_window(t, a, a + WINDOW_S), _window(t, b - WINDOW_S, b),
                          f"hold {s0.start:.3f}-{s1.end:.3f} s")
                )  # fmt: skip
                w = _window(t, a, b)
                if w[1] - w[0] > 8:
                    hold_idx.append(np.arange(*w))
            elif s0.kind == "steps" and 0 < k < len(runs) - 1:
                nxt = runs[k + 1][0]
                prev = runs[k - 1][-1]
                if nxt.kind != "hold" or nxt.duration < SETTLE_S + WINDOW_S:
                    continue
                pre = _window(t, s0.start - min(WINDOW_S, prev.duration), s0.start)
                post = _window(t, nxt.start + SETTLE_S, nxt.start + SETTLE_S + WINDOW_S)
                periods = sum(s.periods for s in run)
                if pre[1] - pre[0] < 3 or post[1] - post[0] < 3 or periods < 1:
                    continue
                # the steady step per period: the first period (how the contacts start
                # from the hold before, which depends on the history) left out, the rest
                # split into two blocks of L whole periods
                n_blk = (periods - 1) // 2
                early = late = None
                if n_blk >= 1 and s0.frequency > 0.0:
                    tp = 1.0 / s0.frequency
                    early = _span(t, s0.start + tp, s0.start + (1 + n_blk) * tp)
                    late = _span(t, s0.start + (periods - n_blk) * tp, s0.start + periods * tp)
                    if early is None or late is None:
                        early = late = None
                self.bursts.append(
                    _Burst(pre, post, periods, f"{s0.condition} at {s0.start:.3f} s",
                           s0.direction, (round(s0.amplitude, 1), round(s0.frequency), s0.flyback),
                           s0.ramp_ratio, s0.flyback_resolution, early, late)
                )  # fmt: skip
            elif s0.kind == "scan":
                w = _window(t, s0.start, s1.end)
                if w[1] - w[0] < 20:
                    continue
                us = u[w[0] : w[1]]
                lo, hi = float(us.min()), float(us.max())
                if hi - lo < 1e-3:
                    continue
                xi = (2.0 * us - (hi + lo)) / (hi - lo)
                self.scans.append(_Scan(w, xi, s0.direction, f"scan {s0.start:.3f} s", lo, hi,
                                        stepped))  # fmt: skip
                stepped = False
        # opposite bursts of one setting, in time order, each in one pair at most
        self.pairs: list[tuple[int, int]] = []
        used: set[int] = set()
        for i, a in enumerate(self.bursts):
            if i in used:
                continue
            for j in range(i + 1, len(self.bursts)):
                b = self.bursts[j]
                if (j not in used and b.setting == a.setting and b.direction == -a.direction
                        and _same_ramp(a, b)):  # fmt: skip
                    self.pairs.append((i, j) if a.direction > 0 else (j, i))
                    used |= {i, j}
                    break
        self._hold_idx = np.concatenate(hold_idx) if hold_idx else np.zeros(0, np.int64)
        # each hold its own level and slope (nuisance of the line fit)
        self._hold_of = np.concatenate(
            [np.full(h.size, k) for k, h in enumerate(hold_idx)]
        ) if hold_idx else np.zeros(0, np.int64)  # fmt: skip
        self.line_frequency = math.nan
        # the moves' level windows (before, after) [sample ranges]: bursts, then scans (the
        # y feature's, :meth:`_y_slope`)
        n_w = max(3, round(WINDOW_S / dt))
        self.moves = [(b.pre, b.post) for b in self.bursts] + [
            ((sc.span[0] - n_w, sc.span[0]), (sc.span[1] - n_w, sc.span[1]))
            for sc in self.scans if sc.span[0] >= n_w and sc.span[1] - sc.span[0] > 2 * n_w
        ]  # fmt: skip

    @property
    def line_searchable(self) -> bool:
        """Whether the holds have the samples a line search needs (:meth:`find_line`)."""
        return self._hold_idx.size >= LINE_MIN_SAMPLES

    @property
    def hold_samples(self) -> np.ndarray:
        """Indices of the samples the line is searched on (the holds past their settling)."""
        return self._hold_idx

    # --- the line -------------------------------------------------------------------------
    def _nuisance(self) -> np.ndarray:
        """Per hold: its level, slope and curvature (columns over the hold samples): a
        hold's relaxation (creep, drift) is not a line."""
        idx, of = self._hold_idx, self._hold_of
        n_h = int(of.max()) + 1 if of.size else 0
        t = self.time[idx]
        cols = np.zeros((idx.size, 3 * n_h))
        for k in range(n_h):
            m = of == k
            tc = (t[m] - t[m].mean()) / max(float(np.ptp(t[m])), 1e-9)
            cols[m, 3 * k] = 1.0
            cols[m, 3 * k + 1] = tc
            cols[m, 3 * k + 2] = tc**2 - np.mean(tc**2)
        return cols

    def find_line(self, signal_nm: np.ndarray) -> dict[str, float]:
        """The strongest sinusoid in the holds of ``signal_nm`` (each hold's level, slope and
        curvature removed): frequency [Hz] on a grid of 1/(4·span) from
        ``LINE_MIN_PERIODS`` periods per median hold (at least ``LINE_FMIN_HZ``) to
        min(``LINE_FMAX_HZ``, Nyquist/4), amplitude [nm] and its χ² (power over the noise,
        2 degrees of freedom); sets the frequency :meth:`measure` reads."""
        idx = self._hold_idx
        if idx.size < LINE_MIN_SAMPLES:
            return {"frequency_Hz": math.nan, "amplitude_nm": 0.0, "chi2": 0.0, "searched": 0}
        t = self.time[idx]
        nuis = self._nuisance()
        q, _ = np.linalg.qr(nuis)
        v = np.asarray(signal_nm, float)[idx]
        v = v - q @ (q.T @ v)
        span = float(t[-1] - t[0])
        fmax = min(LINE_FMAX_HZ, 0.25 / self.dt)
        # a fifth of a period in the median hold: a slower line is a trend there (its
        # residue after each hold's level, slope and curvature is below a cubic's third)
        durations = np.bincount(self._hold_of) * self.dt
        fmin = max(LINE_FMIN_HZ, LINE_MIN_PERIODS / float(np.median(durations)))
        freqs = np.arange(fmin, fmax, 1.0 / (4.0 * span))
        best = (math.nan, 0.0, 0.0)
        for f in freqs:
            c = np.cos(2 * math.pi * f * t)
            s = np.sin(2 * math.pi * f * t)
            c = c - q @ (q.T @ c)
            s = s - q @ (q.T @ s)
            a = np.column_stack([s, c])
            g = a.T @ a
            if np.linalg.cond(g) > 1e8:
                continue
            coef = np.linalg.solve(g, a.T @ v)
            chi2 = float(coef @ g @ coef) / self.sigma**2
            if chi2 > best[2]:
                best = (float(f), float(np.hypot(*coef)), chi2)
        self.line_frequency = best[0]
        return {"frequency_Hz": best[0], "amplitude_nm": best[1], "chi2": best[2],
                "searched": int(freqs.size), "lowest_Hz": float(fmin)}  # fmt: skip

    def _line(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f = self.line_frequency
        if not math.isfinite(f):
            return np.zeros(0), np.zeros(0)
        idx = self._hold_idx
        t = self.time[idx]
        a = np.column_stack([self._nuisance(), np.sin(2 * math.pi * f * t),
                             np.cos(2 * math.pi * f * t)])  # fmt: skip
        coef, *_ = np.linalg.lstsq(a, v[idx], rcond=None)
        cov = np.linalg.pinv(a.T @ a) * self.sigma**2
        return coef[-2:], np.sqrt(np.clip(np.diag(cov)[-2:], 0.0, None))

    # --- all features ---------------------------------------------------------------------
    def measure(self, x_nm: np.ndarray, y_nm: np.ndarray | None = None) -> Features:
        """The features of a detector signal [nm] (x channel; y channel if recorded)."""
        v = np.asarray(x_nm, float)
        names: list[str] = []
        groups: list[str] = []
        vals: list[float] = []
        noise: list[float] = []
        sig = self.sigma

        def add(name: str, group: str, value: float, sd: float) -> None:
            names.append(name)
            groups.append(group)
            vals.append(value)
            noise.append(max(sd, 1e-12))

        steps, steps_sd = [], []
        steady, steady_sd = [], []
        for b in self.bursts:
            n1, n2 = b.pre[1] - b.pre[0], b.post[1] - b.post[0]
            steps.append((_mean(v, b.post) - _mean(v, b.pre)) / b.periods)
            steps_sd.append(sig * math.sqrt(1.0 / n1 + 1.0 / n2) / b.periods)
            add(f"step per period, {b.label}", "steps", steps[-1], steps_sd[-1])
            if b.early is None or b.late is None:
                steady.append(steps[-1])
                steady_sd.append(steps_sd[-1])
            else:
                m1, m2 = b.early.i1 - b.early.i0, b.late.i1 - b.late.i0
                steady.append((_span_mean(self.time, v, b.late)
                               - _span_mean(self.time, v, b.early)) / b.spacing)  # fmt: skip
                steady_sd.append(sig * math.sqrt(1.0 / m1 + 1.0 / m2) / b.spacing)
        # (forward, backward): (|s+| − |s−|)/(|s+| + |s−|) of the steady steps: asymmetry
        # acts on every period alike, a first period set by the history does not
        for i, j in self.pairs:
            sp, sm = steady[i], steady[j]
            tot = sp - sm
            ratio = (sp + sm) / tot if abs(tot) > 1e-12 else 0.0
            sd = math.hypot(steady_sd[i], steady_sd[j]) / max(abs(tot), 1e-12)
            add(f"direction asymmetry, {self.bursts[i].label} / {self.bursts[j].label}",
                "direction", ratio, sd)  # fmt: skip
        for h in self.holds:
            n1, n2 = h.early[1] - h.early[0], h.late[1] - h.late[0]
            add(f"relaxation, {h.label}", "relaxation", _mean(v, h.late) - _mean(v, h.early),
                sig * math.sqrt(1.0 / n1 + 1.0 / n2))  # fmt: skip
        prev: tuple[_Scan, np.ndarray] | None = None
        poly = np.polynomial.polynomial.polyval
        first: tuple[float, float] | None = None  # the first scan's gain per drive volt, sd
        for s in self.scans:
            ys = v[s.span[0] : s.span[1]]
            a = np.column_stack([np.ones_like(s.xi), s.xi, s.xi**2, s.xi**3])
            coef, *_ = np.linalg.lstsq(a, ys, rcond=None)
            sd = np.sqrt(np.clip(np.diag(np.linalg.pinv(a.T @ a)), 0, None)) * sig
            gain = float(coef[1]) if abs(coef[1]) > 1e-12 else 1e-12
            add(f"scan gain, {s.label}", "scan", gain, float(sd[1]))
            # the gain per drive volt over the first scan's: a detector whose gain changes
            # along its range reads the same motion smaller (or larger) where the table
            # has stepped to, which the scans at other levels show
            per_volt = (2.0 * gain / (s.hi - s.lo), 2.0 * float(sd[1]) / (s.hi - s.lo))
            if first is None:
                if abs(per_volt[0]) >= RANGE_REFERENCE_Z * per_volt[1]:  # a gain to refer to
                    first = per_volt
            else:
                ratio = per_volt[0] / first[0]
                add(f"scan gain / the first scan's, {s.label}", "scan_range", ratio,
                    abs(ratio) * math.hypot(per_volt[1] / per_volt[0], first[1] / first[0]))
            # the shape relative to the gain: hysteresis bends a branch by its direction,
            # a photodiode's gain change is odd in the position
            add(f"scan curvature / gain, {s.label}", "scan_shape", float(coef[2]) / gain,
                float(sd[2]) / abs(gain))  # fmt: skip
            add(f"scan cubic / gain, {s.label}", "scan_shape", float(coef[3]) / gain,
                float(sd[3]) / abs(gain))  # fmt: skip
            if prev is not None and prev[0].direction == -s.direction and not s.after_steps:
                # the loop: the later branch minus the earlier at equal drive over their
                # common range, signed so a lagging loop is positive, over the gain; not
                # across a burst, whose net step would read as a loop (the third plant's
                # protocol scans between bursts: 5.27 gains of "loop" on its clean trace)
                p, pc = prev
                lo, hi = max(p.lo, s.lo), min(p.hi, s.hi)
                if hi - lo > 0.2 * (s.hi - s.lo):
                    u = np.linspace(lo, hi, 21)[1:-1]
                    d = np.mean(poly((2 * u - s.hi - s.lo) / (s.hi - s.lo), coef)
                                - poly((2 * u - p.hi - p.lo) / (p.hi - p.lo), pc))  # fmt: skip
                    add(f"scan loop / gain, {p.label} / {s.label}", "scan_shape",
                        float(-s.direction * d) / abs(gain),
                        math.sqrt(2.0) * float(sd[0]) / abs(gain))  # fmt: skip
            prev = (s, coef)
        if math.isfinite(self.line_frequency):
            c, sd = self._line(v)
            add(f"line sin {self.line_frequency:.1f} Hz", "line", float(c[0]), float(sd[0]))
            add(f"line cos {self.line_frequency:.1f} Hz", "line", float(c[1]), float(sd[1]))
        if y_nm is not None:
            slope = self._y_slope(v, np.asarray(y_nm, float))
            if slope is not None:
                add("y on x slope over the moves", "y", *slope)
        return Features(tuple(names), tuple(groups), np.array(vals), np.array(noise))

    def _y_slope(self, x: np.ndarray, y: np.ndarray) -> tuple[float, float] | None:
        """The y channel's slope on the x channel over the trace's moves [-] with its
        standard deviation: each burst's and scan's change of level (``WINDOW_S`` before
        and after; a scan's end its last window), Δy_i = b·Δx_i, b = ΣΔxΔy / ΣΔx². A
        misaligned detector moves y with every move of x (b = tan φ); a slow offset of the
        y channel (thermal drift) hardly changes over a move, where a whole-trace slope of
        y on x takes its correlation with the trace's path for one; a vibration moves both
        channels in the holds, which short increments over the whole trace would take for
        one. The three independent plants' traces, data alone (``python
        experiments/y_feature.py``, stop 73): the third plant's drifting y scores z 353.7
        over the whole trace and −0.1 over the moves, its floor vibration 4.4 and −0.2; the
        three misaligned detectors 730.6–866.2 over the moves; every other trace |z| ≤ 2.6.
        var b = ΣΔx_i²·v_i / (ΣΔx²)², v_i the larger of the windows' white noise
        and the moves' scatter about the line (what vibration or drift adds). None with
        fewer than three moves or no motion of x."""
        moves = self.moves
        if len(moves) < 3:
            return None
        dx = np.array([_mean(x, b) - _mean(x, a) for a, b in moves])
        dy = np.array([_mean(y, b) - _mean(y, a) for a, b in moves])
        sxx = float(dx @ dx)
        if sxx <= 0.0:
            return None
        slope = float(dx @ dy) / sxx
        white = np.array([self.sigma**2 * (1.0 / (a[1] - a[0]) + 1.0 / (b[1] - b[0]))
                          for a, b in moves])  # fmt: skip
        scatter = float(np.sum((dy - slope * dx) ** 2)) / (len(moves) - 1)
        var = float(np.sum(dx**2 * np.maximum(white, scatter))) / sxx**2
        return slope, math.sqrt(var)


def misfit_variance(residual: np.ndarray, noise: np.ndarray, dof: int) -> float:
    """The common misfit variance τ² ≥ 0 [feature unit²] of residuals with noise standard
    deviations ``noise``: the root of Σ r²/(σ² + τ²) = ``dof`` (the Paule–Mandel
    random-effects estimator; DerSimonian & Kacker 2007), 0 when the noise alone explains
    them (Σ r²/σ² ≤ dof). ValueError for dof < 1."""
    if dof < 1:
        raise ValueError(f"misfit_variance: dof must be ≥ 1, got {dof}")
    r2, s2 = np.asarray(residual, float) ** 2, np.asarray(noise, float) ** 2
    if not float(np.sum(r2 / s2)) > dof:
        return 0.0
    hi = float(np.sum(r2)) / dof  # Σ r²/(σ² + hi) < Σ r²/hi = dof: the root is below

    def excess(tau2: float) -> float:
        return float(np.sum(r2 / (s2 + tau2))) - dof

    return float(scipy.optimize.brentq(excess, 0.0, hi, xtol=1e-14 * hi, rtol=1e-12))


def step_misfit_sd(data: Features, model: Features) -> float | None:
    """The misfit [-] a model may leave in one direction ratio (|s₊| − |s₋|)/(|s₊| + |s₋|)
    where the pairs are too few to estimate it (:func:`group_scores`): 1.4826 × the median
    absolute deviation of the bursts' relative step misfits (data − model)/|model| (the
    steps group; bursts whose step is :data:`STEP_SCALE_Z` σ or more on both), over √2 —
    two steps each off by that much independently put their ratio off by 1/√2 of it. A
    robust scale: a burst the model misses by its sign (a ramp at its stick threshold) does
    not set it. None with fewer than :data:`STEP_SCALE_MIN` such bursts."""
    m = data.group("steps")
    d, p, s = data.value[m], model.value[m], data.noise[m]
    ok = (np.abs(p) >= STEP_SCALE_Z * s) & (np.abs(d) >= STEP_SCALE_Z * s)
    if int(ok.sum()) < STEP_SCALE_MIN:
        return None
    e = (d[ok] - p[ok]) / np.abs(p[ok])
    return float(1.4826 * np.median(np.abs(e - np.median(e))) / math.sqrt(2.0))


def group_scores(
    data: Features, model_a: Features, model_b: Features, n_free: int = 1
) -> dict[str, dict[str, float]]:
    """Per group: how much better model b explains the data's features than model a.

    Whitened residuals z = (data − model)/noise; RSS_a, RSS_b; the variance scale
    s² = max(1, RSS_b/(n − n_free)) when the group has at least
    ``n_free`` + 3 features, else 1 (an F-test's variance from the richer model: a group
    both models miss by far is judged by that misfit, not by the detector noise).

    A group of :data:`REPEATED_GROUPS` (one quantity over the protocol's settings) is
    whitened by √(noise² + τ²) instead, τ² the richer model's common misfit variance
    (:func:`misfit_variance` with max(1, n − n_free) degrees of freedom; ``misfit_sd`` =
    τ), s² = 1, whenever it has :data:`REPEATED_MIN` features or more — the rule the
    candidates' search weighs them by (:meth:`.identify.SignatureSearch._weights`), so a
    search that improves its objective is not scored by another one (stop 70: with three
    pairs, the third plant's friction asymmetry lowered its objective from 3.00 to 0.19
    and was scored −90 005.5 nats on the bare noise of its most precise pair). With fewer
    features τ is the richer model's :func:`step_misfit_sd` (``misfit_from`` "steps"): one
    or two settings cannot estimate a setting's misfit, and on the bare noise the third
    plant's clean trace gave friction asymmetry 22 593 nats for its own geometry's −3.5 %
    (stop 69); without enough bursts to bound it from, the group scores 0 (``scored``
    False). Such a group is not checked with a feature left out (:func:`.identify.
    leave_one_out`): the bound is what one setting's misfit may be.
    ``delta`` = (RSS_a − RSS_b)/s² (χ² with ``n_free`` degrees of freedom under "b adds
    nothing") and ``nats`` = delta/2."""
    out = {}
    for g in GROUPS:
        m = data.group(g)
        n = int(m.sum())
        if n == 0:
            continue
        repeated = g in REPEATED_GROUPS
        scored = n >= needed(g)
        sd = data.noise[m]
        tau2 = 0.0
        source = "pairs" if repeated else ""
        if repeated and scored:
            tau2 = misfit_variance(data.value[m] - model_b.value[m], sd, max(1, n - n_free))
        elif repeated:
            bound = step_misfit_sd(data, model_b)
            scored = bound is not None
            tau2, source = (bound**2, "steps") if scored else (0.0, "")
        if repeated and scored:
            sd = np.sqrt(sd**2 + tau2)
        za = (data.value[m] - model_a.value[m]) / sd
        zb = (data.value[m] - model_b.value[m]) / sd
        ra, rb = float(za @ za), float(zb @ zb)
        s2 = max(1.0, rb / (n - n_free)) if n >= n_free + 3 and not repeated else 1.0
        delta = (ra - rb) / s2 if scored else 0.0
        out[g] = {"n": n, "rss_a": ra, "rss_b": rb, "scale": s2, "misfit_sd": math.sqrt(tau2),
                  "misfit_from": source, "delta": delta, "nats": 0.5 * delta,
                  "scored": scored}  # fmt: skip
    return out
