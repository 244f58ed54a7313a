"""Benchmark metrics of an episode, and bootstrap confidence intervals over seeds.

Every metric is computed from the evaluation-only record of an episode (the true angle θ,
which no controller sees) against the commanded reference r (the target at each sample);
distances are at the table radius R (Eq. 4.2: x = R·θ). :data:`METRICS` lists them with
their units and meaning; :func:`episode_metrics` computes them for a batch of episodes at
once. Censoring: a controller that never enters (or never settles in) the band gets the
length of its window, so means stay finite and a failure costs the most time there is.

Aggregation (:func:`mean_ci`, :func:`paired_difference`): the mean over seeds with a 95 %
bootstrap confidence interval (scipy.stats.bootstrap, BCa; percentile where BCa is
degenerate; the interval collapses to the value when every seed agrees). Controllers
meet the same plants, tasks and detector noise per seed (common random numbers), so
differences between two controllers are paired per seed and their interval is that of
the mean paired difference.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.stats

__all__ = [
    "BAND",
    "HOLD",
    "METRICS",
    "RUNAWAY_LIMIT",
    "Metric",
    "episode_metrics",
    "mean_ci",
    "noise_floor",
    "paired_difference",
]

BAND = 30e-9  # m at R_table: settling band, ≈ 10× the nominal detector noise floor (2.8 nm)
RUNAWAY_LIMIT = 50e-6  # m at R_table: the largest run-away a controller may show (issue 32)
HOLD = 0.2  # s, the hold window at the end of every episode (tracking: 0.1 s to settle)
CONFIDENCE = 0.95
N_RESAMPLES = 2000


@dataclass(frozen=True)
class Metric:
    """One metric: name, unit, whether lower is better, and its meaning."""

    name: str
    unit: str
    lower_is_better: bool
    meaning: str


METRICS: dict[str, Metric] = {
    m.name: m
    for m in (
        Metric("success", "-", False, "1 if |θ − r|·R ≤ band over the whole hold window"),
        Metric(
            "time_to_band_s", "s", True,
            "time from the task's event (start, or the knock) to the first sample with "
            "|θ − r|·R ≤ band (censored: the window length)",
        ),
        Metric(
            "settle_time_s", "s", True,
            "time from the event after which |θ − r|·R stays ≤ band to the end (censored: "
            "the window length)",
        ),
        Metric(
            "tracking_rms_nm", "nm", True,
            "RMS of (θ − r)·R over every sample after the first interval: tracking error, "
            "for point-to-point moves the transient's integral measure",
        ),
        Metric("hold_rms_nm", "nm", True, "RMS of (θ − r)·R over the hold window"),
        Metric(
            "hold_rms_rel", "-", True,
            "hold RMS over the detector's noise floor σ_θ·R of that plant (≈ 1: holds as well "
            "as the detector reads)",
        ),
        Metric(
            "overshoot_nm", "nm", True,
            "largest travel past the final reference value in the direction of the last "
            "approach, after the first entry into the band",
        ),
        Metric(
            "runaway_um", "µm", True,
            "largest distance from the reference beyond the start's, max(0, max|θ − r| − "
            "|θ₀ − r₀|)·R: how far a controller ran the table away (a lost spot); the "
            "benchmark's bound is RUNAWAY_LIMIT",
        ),
        Metric(
            "slips_per_um", "1/µm", True,
            "stick–slip periods run per µm of commanded travel (reference path plus the "
            "initial distance)",
        ),
        Metric(
            "energy_per_um_mJ", "mJ/µm", True,
            "electrical energy C∫|V dV| per µm of commanded travel",
        ),
    )
}  # fmt: skip


def episode_metrics(
    time: np.ndarray,
    angle: np.ndarray,
    reference: np.ndarray,
    steps: np.ndarray,
    energy: np.ndarray,
    *,
    radius: float,
    noise_floor: np.ndarray,
    event: int = 0,
    band: float = BAND,
    hold: float = HOLD,
) -> dict[str, np.ndarray]:
    """Metrics (:data:`METRICS`) of N episodes sampled at the same K times.

    Args:
        time: (K,) sample times [s], time[0] = 0 the reset.
        angle: (N, K) true angles [rad] (evaluation only).
        reference: (N, K) commanded target at each sample [rad].
        steps, energy: (N, K) stick–slip periods and electrical energy [J] of the interval
            ending at each sample (column 0: 0).
        radius: R_table [m]; noise_floor: (N,) detector angle noise σ_θ·R [m].
        event: sample index from which entry and settling times count (a knock's).
        band: settling band [m]; hold: hold window [s].

    Returns:
        name → (N,) values.
    """
    t = np.asarray(time, dtype=float)
    th, ref = np.atleast_2d(angle), np.atleast_2d(reference)
    err = np.abs(th - ref) * radius  # m
    n, k = err.shape
    window = t[-1] - t[event]
    inside = err <= band
    after = inside[:, event:]
    # first entry
    first = np.where(after.any(axis=1), after.argmax(axis=1), -1)
    t_enter = np.where(first >= 0, t[event + np.maximum(first, 0)] - t[event], window)
    # settling: the sample after the last one outside (0 if never outside; the window if
    # the end is outside)
    outside = ~after
    last_out = np.where(
        outside.any(axis=1), after.shape[1] - 1 - outside[:, ::-1].argmax(axis=1), -1
    )
    settle_at = np.minimum(event + last_out + 1, k - 1)  # (only used where the end is inside)
    t_settle = np.where(after[:, -1], t[settle_at] - t[event], window)
    hold_mask = t >= t[-1] - hold - 1e-12
    hold_err = err[:, hold_mask]
    hold_rms = np.sqrt(np.mean(hold_err**2, axis=1))
    track = np.sqrt(np.mean(err[:, 1:] ** 2, axis=1))
    # overshoot past the final reference, in the direction of the last approach
    final = ref[:, -1]
    last_change = np.array([_last_approach(th[i], ref[i]) for i in range(n)])
    past = (th - final[:, None]) * last_change[:, None] * radius
    first_all = np.where(inside.any(axis=1), inside.argmax(axis=1), k)  # first entry
    entered = np.arange(k)[None, :] >= first_all[:, None]
    overshoot = np.where(entered, past, 0.0).max(axis=1, initial=0.0)
    travel = np.abs(ref[:, 0] - th[:, 0]) + np.abs(np.diff(ref, axis=1)).sum(axis=1)
    travel_um = np.maximum(travel * radius * 1e6, 1e-3)  # µm (a floor for hold-only tasks)
    return {
        "success": (hold_err <= band).all(axis=1).astype(float),
        "time_to_band_s": t_enter,
        "settle_time_s": t_settle,
        "tracking_rms_nm": track * 1e9,
        "hold_rms_nm": hold_rms * 1e9,
        "hold_rms_rel": hold_rms / np.maximum(np.asarray(noise_floor, dtype=float), 1e-15),
        "overshoot_nm": np.maximum(overshoot, 0.0) * 1e9,
        "runaway_um": np.maximum(err.max(axis=1) - err[:, 0], 0.0) * 1e6,
        "slips_per_um": steps.sum(axis=1) / travel_um,
        "energy_per_um_mJ": energy.sum(axis=1) * 1e3 / travel_um,
    }


def noise_floor(sensor_noise: float, detector: Any) -> float:
    """Detector angle noise at the table radius [m] for a voltage noise [V] (Eq. 4.1–4.2)."""
    return abs(detector.angle(sensor_noise) - detector.angle(0.0)) * detector.table_radius


def _last_approach(angle: np.ndarray, ref: np.ndarray) -> float:
    """Direction (±1) of the last approach to the final reference value: the sign of its
    last change, or of the initial distance for a fixed target (0 if none)."""
    d = np.diff(ref)
    nz = np.flatnonzero(np.abs(d) > 0.0)
    if nz.size:
        return float(np.sign(d[nz[-1]]))
    return float(np.sign(ref[-1] - angle[0]))


def mean_ci(x: np.ndarray, seed: int = 0) -> dict[str, float]:
    """Mean and its 95 % bootstrap interval over seeds (module docstring)."""
    v = np.asarray(x, dtype=float)
    m = float(np.mean(v))
    if v.size < 2 or np.ptp(v) == 0.0:
        return {"mean": m, "ci_low": m, "ci_high": m}
    lo, hi = _bootstrap(v, seed)
    return {"mean": m, "ci_low": lo, "ci_high": hi}


def paired_difference(a: np.ndarray, b: np.ndarray, seed: int = 0) -> dict[str, Any]:
    """Mean of a − b over paired seeds with its 95 % bootstrap interval, and whether the
    interval excludes 0 (``separated``)."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    out: dict[str, Any] = mean_ci(d, seed)
    out["separated"] = bool(out["ci_low"] > 0.0 or out["ci_high"] < 0.0)
    return out


def _bootstrap(v: np.ndarray, seed: int) -> tuple[float, float]:
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for method in ("BCa", "percentile"):
            res = scipy.stats.bootstrap(
                (v,), np.mean, confidence_level=CONFIDENCE, n_resamples=N_RESAMPLES,
                method=method, random_state=rng,
            )  # fmt: skip
            lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
            if math.isfinite(lo) and math.isfinite(hi):
                return lo, hi
    return float(v.min()), float(v.max())
