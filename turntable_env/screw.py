"""Screw theory on SE(3) (§3.2.1): homogeneous matrices, twists, wrenches, adjoints.

Conventions follow the thesis (Stramigioli): a twist is the 6-vector
T = (ω, v) [rad/s, m/s] and a wrench W = (m, f) [N·m, N], so that the power
is the pairing WᵀT [W]. For H = (R, p) ∈ SE(3) mapping coordinates of frame a
into frame b (x_b = R x_a + p), twists and wrenches change frame as

    T_b = Ad_H T_a,   W_a = Ad_Hᵀ W_b,   Ad_H = [[R, 0], [p̃R, R]]   (Eq. 3.5, 3.13),

so the power W_bᵀT_b = W_aᵀT_a does not depend on the frame. A 6×6 stiffness
expressed in frame b is moved to frame a by Eq. 3.18, K_a = Ad_Hᵀ K_b Ad_H;
:func:`merge_stiffness` sums such contributions (the four quadrant springs of a
tube merged into one, Eq. 3.17–3.18).

The compiled helpers (``*_nb``) are used inside the simulator's inner loop.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernel_cache import CACHE
from .validation import check_array_finite

__all__ = [
    "adjoint",
    "exp_so3",
    "homogeneous",
    "log_so3",
    "merge_stiffness",
    "skew",
]


def skew(w: np.ndarray) -> np.ndarray:
    """w̃: the 3×3 matrix with w̃x = w × x."""
    x, y, z = (float(c) for c in check_array_finite("w", w).reshape(3))
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def homogeneous(rotation: np.ndarray, position: np.ndarray) -> np.ndarray:
    """H = [[R, p], [0, 1]] (Eq. 3.10)."""
    r = check_array_finite("rotation", rotation).reshape(3, 3)
    p = check_array_finite("position", position).reshape(3)
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0.0:
        raise ValueError(f"rotation={rotation!r}: must be a proper rotation matrix")
    h = np.eye(4)
    h[:3, :3] = r
    h[:3, 3] = p
    return h


def adjoint(h: np.ndarray) -> np.ndarray:
    """Ad_H = [[R, 0], [p̃R, R]] for twists ordered (ω, v)."""
    hh = check_array_finite("h", h).reshape(4, 4)
    r, p = hh[:3, :3], hh[:3, 3]
    ad = np.zeros((6, 6))
    ad[:3, :3] = r
    ad[3:, 3:] = r
    ad[3:, :3] = skew(p) @ r
    return ad


def merge_stiffness(stiffnesses: list[np.ndarray], transforms: list[np.ndarray]) -> np.ndarray:
    """Σ_q Ad_{H_q}ᵀ K_q Ad_{H_q}: springs in parallel expressed in one frame (Eq. 3.18).

    Args:
        stiffnesses: 6×6 stiffness of each spring in its own frame [(N·m/rad, N/m) blocks].
        transforms: H_q ∈ SE(3), mapping the common frame's coordinates into spring q's
            frame (H^{qc}_{0c} of Eq. 3.17).
    """
    if len(stiffnesses) != len(transforms) or not stiffnesses:
        raise ValueError(
            f"stiffnesses: {len(stiffnesses)} matrices for {len(transforms)} transforms"
        )
    out = np.zeros((6, 6))
    for i, (k, h) in enumerate(zip(stiffnesses, transforms, strict=True)):
        kk = check_array_finite(f"stiffnesses[{i}]", k).reshape(6, 6)
        if not np.allclose(kk, kk.T, rtol=1e-12, atol=0.0):
            raise ValueError(f"stiffnesses[{i}]: must be symmetric")
        ad = adjoint(h)
        out += ad.T @ kk @ ad
    return out


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix exp(w̃) for a rotation vector w [rad] (Rodrigues)."""
    return _exp_so3_nb(check_array_finite("w", w).reshape(3).astype(float))


def log_so3(r: np.ndarray) -> np.ndarray:
    """Rotation vector [rad] of a rotation matrix (inverse of :func:`exp_so3`, |w| < π)."""
    rr = check_array_finite("r", r).reshape(3, 3).astype(float)
    return log_so3_nb(rr)


@njit(cache=CACHE)
def _exp_so3_into(w, r):
    """Fill ``r`` (3, 3) with exp(w̃) (Rodrigues)."""
    th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    if th2 < 1e-8:  # Taylor series, exact to double precision below 1e-4 rad
        a = 1.0 - th2 / 6.0 + th2 * th2 / 120.0
        b = 0.5 - th2 / 24.0 + th2 * th2 / 720.0
    else:
        th = math.sqrt(th2)
        a = math.sin(th) / th
        b = (1.0 - math.cos(th)) / th2
    x, y, z = w[0], w[1], w[2]
    r[0, 0] = 1.0 - b * (y * y + z * z)
    r[1, 1] = 1.0 - b * (x * x + z * z)
    r[2, 2] = 1.0 - b * (x * x + y * y)
    r[0, 1] = -a * z + b * x * y
    r[1, 0] = a * z + b * x * y
    r[0, 2] = a * y + b * x * z
    r[2, 0] = -a * y + b * x * z
    r[1, 2] = -a * x + b * y * z
    r[2, 1] = a * x + b * y * z


@njit(cache=CACHE)
def _exp_so3_nb(w):
    r = np.empty((3, 3))
    _exp_so3_into(w, r)
    return r


@njit(cache=CACHE)
def log_so3_nb(r):
    c = 0.5 * (r[0, 0] + r[1, 1] + r[2, 2] - 1.0)
    c = min(1.0, max(-1.0, c))
    vx = 0.5 * (r[2, 1] - r[1, 2])
    vy = 0.5 * (r[0, 2] - r[2, 0])
    vz = 0.5 * (r[1, 0] - r[0, 1])
    s = math.sqrt(vx * vx + vy * vy + vz * vz)  # = sin θ
    th = math.atan2(s, c)
    if th < 1e-4:
        f = 1.0 + th * th / 6.0  # θ/sin θ
    else:
        f = th / s
    out = np.empty(3)
    out[0] = f * vx
    out[1] = f * vy
    out[2] = f * vz
    return out


@njit(cache=CACHE)
def rotate_left_inplace(r, w, e):
    """R ← exp(w̃)·R, re-orthonormalised (keeps R in SO(3) over millions of steps);
    ``e`` is a (3, 3) scratch array, so the step allocates nothing."""
    _exp_so3_into(w, e)
    # columns 0, 1 of exp(w̃)R, then one Gram–Schmidt pass; column 2 = c0 × c1
    p00 = e[0, 0] * r[0, 0] + e[0, 1] * r[1, 0] + e[0, 2] * r[2, 0]
    p10 = e[1, 0] * r[0, 0] + e[1, 1] * r[1, 0] + e[1, 2] * r[2, 0]
    p20 = e[2, 0] * r[0, 0] + e[2, 1] * r[1, 0] + e[2, 2] * r[2, 0]
    p01 = e[0, 0] * r[0, 1] + e[0, 1] * r[1, 1] + e[0, 2] * r[2, 1]
    p11 = e[1, 0] * r[0, 1] + e[1, 1] * r[1, 1] + e[1, 2] * r[2, 1]
    p21 = e[2, 0] * r[0, 1] + e[2, 1] * r[1, 1] + e[2, 2] * r[2, 1]
    n0 = math.sqrt(p00 * p00 + p10 * p10 + p20 * p20)
    p00 /= n0
    p10 /= n0
    p20 /= n0
    d = p00 * p01 + p10 * p11 + p20 * p21
    p01 -= d * p00
    p11 -= d * p10
    p21 -= d * p20
    n1 = math.sqrt(p01 * p01 + p11 * p11 + p21 * p21)
    p01 /= n1
    p11 /= n1
    p21 /= n1
    r[0, 0], r[1, 0], r[2, 0] = p00, p10, p20
    r[0, 1], r[1, 1], r[2, 1] = p01, p11, p21
    r[0, 2] = p10 * p21 - p20 * p11
    r[1, 2] = p20 * p01 - p00 * p21
    r[2, 2] = p00 * p11 - p10 * p01
