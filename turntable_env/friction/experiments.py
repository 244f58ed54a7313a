"""The friction experiments of §2.2 as functions (Fig. 2.8, 2.9, 2.10), shared by tests and scripts.

* :func:`presliding_hysteresis` — Fig. 2.9: displacement-driven presliding with an
  inner loop; measures how closely the curve returns to the outer loop.
* :func:`drift_test` — Fig. 2.10: a block pushed into slip, then held in stick by
  an oscillating force; measures drift per oscillation cycle.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from .models import GMS, Breedveld, FrictionModel, FrictionResponse, StribeckParams

__all__ = [
    "DriftResult",
    "HysteresisResult",
    "drift_test",
    "presliding_hysteresis",
    "thesis_drift_models",
]


def _path_velocity(points: list[float], speed: float, dt: float) -> np.ndarray:
    """Piecewise-constant velocity [m/s] that visits ``points`` [m] at ``speed``."""
    segs = []
    for a, b in pairwise(points):
        n = round(abs(b - a) / (speed * dt))
        segs.append(np.full(n, np.sign(b - a) * speed))
    return np.concatenate(segs)


@dataclass(frozen=True)
class HysteresisResult:
    """Fig. 2.9 outcome. Forces in N, displacements in m."""

    with_inner_loop: FrictionResponse
    reference: FrictionResponse
    loop_closure_error: float  # |F after closing the inner loop − F before it| at x₁
    outer_curve_error: float  # max |F − F_reference| on the descending branch after the loop
    hysteresis_width: float  # |F_up − F_down| between the outer branches at x = 0
    inner_loop_slips: bool  # some element slipped inside the inner loop (memory exercised)
    force_scale: float  # F_st = μ_st F_N


def presliding_hysteresis(
    model: GMS | None = None,
    normal_force: float = 100.0,
    speed: float | None = None,
    steps_per_delta: int = 2000,
) -> HysteresisResult:
    """Fig. 2.9 on a GMS model (Table D.2 by default), sized by the largest element
    presliding distance δ_max = max ν_i F_st / k_i.

    Outer loop between ±A (A = 1.2 δ_max). From +A down to x₁ = A − 1.6 δ_max (some
    elements slip), up to x₂ = x₁ + 1.33 δ_max (some slip back), down to x₁ again (inner
    loop closed), then on to −A. Reference: the same path without the inner loop.
    """
    m = model if model is not None else GMS()
    f_st = m.stribeck.mu_s * normal_force
    d_max = float(np.max(np.asarray(m.nu) * f_st / np.asarray(m.k)))
    v = speed if speed is not None else 1e-3 * m.stribeck.v_s
    dt = d_max / v / steps_per_delta
    a = 1.2 * d_max
    x1 = a - 1.6 * d_max
    x2 = x1 + 1.33 * d_max
    head = [0.0, a, -a, a]
    ref = m.simulate_velocity(_path_velocity([*head, -a], v, dt), dt, normal_force)
    loop = m.simulate_velocity(_path_velocity([*head, x1, x2, x1, -a], v, dt), dt, normal_force)
    n_head = _path_velocity(head, v, dt).size  # index of the last +A turn
    x_ref, f_ref = ref.displacement[n_head:], ref.force[n_head:]
    x_lp, f_lp, fl_lp = loop.displacement[n_head:], loop.force[n_head:], loop.flags[n_head:]
    tol = v * dt  # one step: segment lengths are rounded to whole steps
    first = int(np.nonzero(x_lp <= x1 + tol)[0][0])
    back_up = first + int(np.nonzero(x_lp[first:] >= x2 - tol)[0][0])
    second = back_up + int(np.nonzero(x_lp[back_up:] <= x1 + tol)[0][0])
    closure = abs(f_lp[second] - f_lp[first])
    # continuation after the loop against the reference branch (x decreasing on both)
    f_ref_at = np.interp(x_lp[second:], x_ref[::-1], f_ref[::-1])
    outer_err = float(np.max(np.abs(f_lp[second:] - f_ref_at)))
    slipped = bool((fl_lp[first + 1 : second] == 0).any())
    # width between ascending (−A → +A) and descending outer branches at x = 0
    up0 = np.interp(
        0.0, ref.displacement[:n_head][-(n_head // 2) :], ref.force[:n_head][-(n_head // 2) :]
    )
    dn0 = np.interp(0.0, x_ref[::-1], f_ref[::-1])
    return HysteresisResult(
        loop, ref, float(closure), outer_err, float(abs(up0 - dn0)), slipped, f_st
    )


@dataclass(frozen=True)
class DriftResult:
    """Fig. 2.10 outcome for one model: drift per oscillation cycle in stick [m]."""

    response: FrictionResponse
    drift_per_cycle: float
    slip_displacement: float


def drift_test(
    model: FrictionModel,
    normal_force: float = 100.0,
    mass: float = 1.0,
    dt: float = 2e-6,
    t_slip: float = 0.05,
    t_total: float = 3.0,
    oscillation_hz: float = 5.0,
) -> DriftResult:
    """Fig. 2.10: push a block into slip, then oscillate the force inside the stick range.

    Force: 1.3·F_s for ``t_slip`` [s]; then F_c·(0.4 + 0.5 sin 2πft), which stops the
    block and keeps |F| < F_c < F_s. Drift per cycle is the mean position change per
    cycle over the last half of the run, cycle-averaged to remove the oscillation.
    """
    s = model.stribeck
    f_s, f_c = s.mu_s * normal_force, s.mu_c * normal_force
    t = np.arange(0.0, t_total, dt)
    force = np.where(
        t < t_slip, 1.3 * f_s, f_c * (0.4 + 0.5 * np.sin(2 * np.pi * oscillation_hz * t))
    )
    r = model.simulate_mass(force, dt, mass, normal_force)
    per = round(1.0 / (oscillation_hz * dt))
    n_cyc = (t.size - t.size // 2) // per
    start = t.size - n_cyc * per
    means = r.displacement[start : start + n_cyc * per].reshape(n_cyc, per).mean(axis=1)
    drift = float((means[-1] - means[0]) / (n_cyc - 1))
    return DriftResult(r, drift, float(r.displacement[int(t_slip / dt) * 4]))


def thesis_drift_models(sigma2: float = 20.0) -> tuple[Breedveld, GMS]:
    """Breedveld and GMS with Table D.2 friction and light viscous damping [N·s/m]."""
    st = StribeckParams(mu_s=0.3, mu_c=0.05, v_s=0.8, delta=2.0, sigma2=sigma2)
    return Breedveld(stribeck=st, v_preslip=1e-3), GMS(stribeck=st)
