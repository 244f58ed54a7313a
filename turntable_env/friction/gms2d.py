"""Two-dimensional GMS friction in a contact plane (§3.3.2).

The thesis extends Eq. 2.24–2.26 to the contact's average tangent plane: the
element force F_i and the velocity v become 2-vectors. This module uses the
isotropic vector form: the Stribeck curve acts along the sliding direction,
s(v) = |s|(‖v‖)·v/‖v‖, so that

* stick (Eq. 2.24):  dF_i/dt = k_i v
* slip  (Eq. 2.25):  dF_i/dt = C (ν_i s(v) − F_i) / |s|(‖v‖)

which reduces exactly to the 1-D law for collinear motion. An element slips
when ‖F_i‖ reaches ν_i|s|(‖v‖) while being loaded (F_i·v > 0) and returns to
stick when the relative velocity reverses against it (F_i·v ≤ 0). As in the
1-D kernel, the radial loading rate of a slipping element is capped at
k_i (F̂_i·v), which keeps every element passive.

Arrays: ``f`` has shape (n, 2) [N], ``stick`` shape (n,) int (1 stick, 0 slip).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernel_cache import CACHE
from .kernels import stribeck_magnitude

__all__ = ["gms2d_force", "gms2d_rates", "gms2d_update", "run_gms2d_velocity_driven"]


@njit(cache=CACHE)
def gms2d_force(f, vx, vy, sigma2):
    """Total friction force (Eq. 2.26 in the plane): Σ F_i + σ₂ v [N], as (fx, fy)."""
    fx = sigma2 * vx
    fy = sigma2 * vy
    for i in range(f.shape[0]):
        fx += f[i, 0]
        fy += f[i, 1]
    return fx, fy


@njit(cache=CACHE)
def gms2d_rates(f, stick, vx, vy, fn, nu, k, c, mu_s, mu_c, v_s, delta, df):
    """Write dF_i/dt [N/s] of every element into ``df`` (shape (n, 2))."""
    speed = math.sqrt(vx * vx + vy * vy)
    smag = stribeck_magnitude(speed, fn, mu_s, mu_c, v_s, delta)
    for i in range(f.shape[0]):
        if stick[i] == 1 or f[i, 0] * vx + f[i, 1] * vy <= 0.0:  # stick, or reversed
            df[i, 0] = k[i] * vx
            df[i, 1] = k[i] * vy
            continue
        tx = nu[i] * smag * vx / speed
        ty = nu[i] * smag * vy / speed
        rx = c * (tx - f[i, 0]) / smag
        ry = c * (ty - f[i, 1]) / smag
        fm = math.sqrt(f[i, 0] ** 2 + f[i, 1] ** 2)
        if fm > 0.0:
            ux = f[i, 0] / fm
            uy = f[i, 1] / fm
            radial = rx * ux + ry * uy
            cap = k[i] * (vx * ux + vy * uy)
            if radial > 0.0 and radial > cap:
                rx -= (radial - cap) * ux
                ry -= (radial - cap) * uy
        df[i, 0] = rx
        df[i, 1] = ry


@njit(cache=CACHE)
def gms2d_update(f, stick, vx, vy, fn, nu, mu_s, mu_c, v_s, delta):
    """Stick/slip transitions after a step; returns the number of sticking elements."""
    speed = math.sqrt(vx * vx + vy * vy)
    smag = stribeck_magnitude(speed, fn, mu_s, mu_c, v_s, delta)
    n_stick = 0
    for i in range(f.shape[0]):
        load = f[i, 0] * vx + f[i, 1] * vy
        if stick[i] == 0:
            if load <= 0.0:
                stick[i] = 1
        else:
            fm = math.sqrt(f[i, 0] ** 2 + f[i, 1] ** 2)
            if fm >= nu[i] * smag and load > 0.0:
                stick[i] = 0
        n_stick += stick[i]
    return n_stick


@njit(cache=CACHE)
def run_gms2d_velocity_driven(f0, stick0, vel, dt, fn, nu, k, c, mu_s, mu_c, v_s, delta, sigma2):
    """Integrate 2-D GMS under prescribed plane velocities vel[N, 2] (explicit Euler).

    Returns (force[N+1, 2], f_elements[N+1, n, 2], stick[N+1, n]).
    """
    n = vel.shape[0]
    ne = f0.shape[0]
    f = f0.copy()
    stick = stick0.copy()
    df = np.zeros((ne, 2))
    force = np.empty((n + 1, 2))
    fs = np.empty((n + 1, ne, 2))
    sts = np.empty((n + 1, ne), dtype=np.int64)
    force[0, 0], force[0, 1] = gms2d_force(f, vel[0, 0], vel[0, 1], sigma2)
    fs[0] = f
    sts[0] = stick
    for i in range(n):
        vx = vel[i, 0]
        vy = vel[i, 1]
        gms2d_rates(f, stick, vx, vy, fn, nu, k, c, mu_s, mu_c, v_s, delta, df)
        for j in range(ne):
            f[j, 0] += dt * df[j, 0]
            f[j, 1] += dt * df[j, 1]
        gms2d_update(f, stick, vx, vy, fn, nu, mu_s, mu_c, v_s, delta)
        force[i + 1, 0], force[i + 1, 1] = gms2d_force(f, vx, vy, sigma2)
        fs[i + 1] = f
        sts[i + 1] = stick
    return force, fs, sts
