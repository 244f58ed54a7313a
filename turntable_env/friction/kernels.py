"""Compiled friction kernels: one state-space interface for every model of §2.2.

Every model is a packed parameter vector ``p`` and a model id. Its state is a
float vector ``x`` (continuous states) and an int vector ``fl`` (logic flags:
stick/slip per GMS element, Breedveld's slip flag, Leuven's last velocity sign).
Three functions, all ``numba.njit(cache=CACHE)``, make the interface:

* ``kernel_force(mid, p, x, fl, v, fa, fn)`` → friction force [N]
* ``kernel_rates(mid, p, x, fl, v, fa, fn, dx)`` → writes dx/dt into ``dx``
* ``kernel_update(mid, p, x, fl, v, fa, fn)`` → discrete transitions after a step

Inputs: relative sliding velocity ``v`` [m/s]; ``fa`` the external force that
would keep the interface at rest during this step [N] (only the static models
of Eq. 2.15 and Karnopp use it); ``fn`` the normal force [N]. The friction force
opposes sliding: it has the sign of ``v`` in steady sliding.

Packed layout: ``p[0:5] = (μ_s, μ_c, v_S, δ_vS, σ₂)``, then model-specific
entries documented beside each model id below.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernel_cache import CACHE

__all__ = [
    "BREEDVELD",
    "CLASSICAL",
    "DAHL",
    "ELASTOPLASTIC",
    "GMS",
    "KARNOPP",
    "LEUVEN",
    "LUGRE",
    "STRIBECK",
    "gms_element_step",
    "gms_element_step2",
    "kernel_force",
    "kernel_rates",
    "kernel_update",
    "stribeck_magnitude",
    "stribeck_signed",
]

STRIBECK = 0  # Eq. 2.13 + viscous: F = s(v) + σ₂v. No state.
CLASSICAL = 1  # Eq. 2.15. p[5] = zero-velocity detection band [m/s].
KARNOPP = 2  # Karnopp. p[5] = DV, half-width of the zero-velocity interval [m/s].
BREEDVELD = 3  # Eq. 2.16–2.17. p[5] = v_preslip [m/s]. fl[0] = slip flag.
DAHL = 4  # Eq. 2.18. p[5] = σ₀ [N/m], p[6] = δ_d. x[0] = F.
LUGRE = 5  # Eq. 2.19–2.20. p[5] = σ₀ [N/m], p[6] = σ₁ [N·s/m]. x[0] = z.
ELASTOPLASTIC = 6  # Eq. 2.21–2.22. p[5] = σ₀, p[6] = σ₁, p[7] = z_ba/z_ss,min. x[0] = z.
LEUVEN = 7  # Eq. 2.23. p[5] = σ₁, p[6] = δ_l, p[7] = n, p[8:8+n] = ν, p[8+n:8+2n] = k.
#              x = (z, F_b, e_1..e_n); fl[0] = sign of v at the last reversal.
GMS = 8  # Eq. 2.24–2.26. p[5] = C [N/s], p[6] = n, p[7:7+n] = ν, p[7+n:7+2n] = k [N/m].
#           x = (F_1..F_n); fl[i] = 1 stick, 0 slip.


@njit(cache=CACHE)
def stribeck_magnitude(speed, fn, mu_s, mu_c, v_s, delta):
    """|s(v)| = F_c + (F_s − F_c)·exp(−|v/v_S|^δ), F_s = μ_s F_N, F_c = μ_c F_N (Eq. 2.13–2.14)."""
    f_s = mu_s * fn
    f_c = mu_c * fn
    r = abs(speed) / v_s
    p = r * r if delta == 2.0 else r**delta  # the Gaussian case without a pow call
    return f_c + (f_s - f_c) * math.exp(-p)


@njit(cache=CACHE)
def gms_element_step(f, stuck, k, dx, target, decay):
    """One GMS element over a step in which the contact's relative displacement changes
    by dx [m] (the per-axis model's exact step): stuck, F + k·dx (Eq. 2.24); slipping, the
    exact relaxation toward ``target`` = ν_i s(v̄) sgn(v̄) [N] of Eq. 2.25 over the step,
    F = target + (F − target)·decay (decay = exp(−C h/|s(v̄)|)), loading no faster than
    the element spring (k·dx) — the same cap as the 2-D law's (:mod:`.gms2d`)."""
    if stuck == 1:
        return f + k * dx
    fnew = target + (f - target) * decay
    d = fnew - f
    lim = k * dx
    if f != 0.0 and d * f > 0.0 and d * f > lim * f:
        fnew = f + lim  # loading no faster than the element spring
    return fnew


@njit(cache=CACHE)
def gms_element_step2(f, g, stuck, k, dx, dn, tx, tn, decay):
    """:func:`gms_element_step` for an element whose force is a 2-vector (f, g) [N] in its
    contact plane (the 2-D law of :mod:`.gms2d`, §3.3.2): stuck, (f, g) + k·(dx, dn)
    (Eq. 2.24); slipping, the exact relaxation toward the target (tx, tn) = ν_i s(|v̄|)
    v̄/|v̄| [N] over the step (Eq. 2.25 along the mean sliding direction), its radial
    part loading no faster than the element spring along the force, k·(dx, dn)·F̂."""
    if stuck == 1:
        return f + k * dx, g + k * dn
    fx = tx + (f - tx) * decay
    fy = tn + (g - tn) * decay
    fm = math.sqrt(f * f + g * g)
    if fm > 0.0:
        ux = f / fm
        uy = g / fm
        radial = (fx - f) * ux + (fy - g) * uy
        lim = k * (dx * ux + dn * uy)
        if radial > 0.0 and radial > lim:
            fx -= (radial - lim) * ux
            fy -= (radial - lim) * uy
    return fx, fy


@njit(cache=CACHE)
def stribeck_signed(v, fn, mu_s, mu_c, v_s, delta):
    """s(v) = sgn(v)·|s(v)| of Eq. 2.13 (zero at v = 0)."""
    if v == 0.0:
        return 0.0
    m = stribeck_magnitude(v, fn, mu_s, mu_c, v_s, delta)
    return m if v > 0.0 else -m


@njit(cache=CACHE)
def _sgn(a):
    if a > 0.0:
        return 1.0
    if a < 0.0:
        return -1.0
    return 0.0


@njit(cache=CACHE)
def _leuven_fh(p, x):
    n = int(p[7])
    fh = 0.0
    for j in range(n):
        fh += p[8 + n + j] * x[2 + j]
    return fh


@njit(cache=CACHE)
def _leuven_zdot(p, x, v, fn):
    s = stribeck_signed(v, fn, p[0], p[1], p[2], p[3])
    fb = x[1]
    den = s - fb
    if abs(den) < 1e-300:
        return v
    ratio = (_leuven_fh(p, x) - fb) / den
    return v * (1.0 - _sgn(ratio) * abs(ratio) ** p[6])


@njit(cache=CACHE)
def _lugre_zdot(p, x, v, fn, with_elastoplastic):
    sigma0 = p[5]
    z = x[0]
    if v == 0.0:
        return 0.0
    smag = stribeck_magnitude(v, fn, p[0], p[1], p[2], p[3])
    alpha = 1.0
    if with_elastoplastic:
        z_ss = smag / sigma0
        z_ba = p[7] * (p[1] * fn) / sigma0  # fraction of the smallest z_ss = F_c/σ₀
        az = abs(z)
        if az <= z_ba or _sgn(v) != _sgn(z):
            alpha = 0.0
        elif az < z_ss:
            alpha = 0.5 * math.sin(math.pi * (az - 0.5 * (z_ss + z_ba)) / (z_ss - z_ba)) + 0.5
    return v - alpha * sigma0 * abs(v) / smag * z


@njit(cache=CACHE)
def kernel_force(mid, p, x, fl, v, fa, fn):
    """Friction force [N] of model ``mid`` in state (x, fl) at sliding velocity v."""
    mu_s, mu_c, v_s, delta, sigma2 = p[0], p[1], p[2], p[3], p[4]
    if mid == STRIBECK:
        return stribeck_signed(v, fn, mu_s, mu_c, v_s, delta) + sigma2 * v
    if mid == CLASSICAL or mid == KARNOPP:
        if abs(v) <= p[5]:
            f_s = mu_s * fn
            if abs(fa) < f_s:
                return fa
            return f_s * _sgn(fa)
        return stribeck_signed(v, fn, mu_s, mu_c, v_s, delta) + sigma2 * v
    if mid == BREEDVELD:
        v_pre = p[5]
        if abs(v) < v_pre and fl[0] == 0:
            return mu_s * fn * v / v_pre
        return mu_c * fn * _sgn(v) + sigma2 * v
    if mid == DAHL:
        return x[0] + sigma2 * v
    if mid == LUGRE or mid == ELASTOPLASTIC:
        zdot = _lugre_zdot(p, x, v, fn, mid == ELASTOPLASTIC)
        return p[5] * x[0] + p[6] * zdot + sigma2 * v
    if mid == LEUVEN:
        zdot = _leuven_zdot(p, x, v, fn)
        return _leuven_fh(p, x) + p[5] * zdot + sigma2 * v
    if mid == GMS:
        n = int(p[6])
        f = sigma2 * v
        for i in range(n):
            f += x[i]
        return f
    return math.nan


@njit(cache=CACHE)
def kernel_rates(mid, p, x, fl, v, fa, fn, dx):
    """Write dx/dt of the continuous states into ``dx``."""
    mu_s, mu_c, v_s, delta = p[0], p[1], p[2], p[3]
    if mid == DAHL:
        f_c = mu_c * fn  # Dahl's single force level (the text's "F_s equals F_c")
        u = 1.0 - x[0] * _sgn(v) / f_c
        dx[0] = p[5] * v * abs(u) ** p[6] * _sgn(u)
    elif mid == LUGRE or mid == ELASTOPLASTIC:
        dx[0] = _lugre_zdot(p, x, v, fn, mid == ELASTOPLASTIC)
    elif mid == LEUVEN:
        n = int(p[7])
        zdot = _leuven_zdot(p, x, v, fn)
        dx[0] = zdot
        dx[1] = 0.0
        for j in range(n):
            dx[2 + j] = zdot
    elif mid == GMS:
        n = int(p[6])
        c = p[5]
        smag = stribeck_magnitude(v, fn, mu_s, mu_c, v_s, delta)
        s = smag * _sgn(v)
        for i in range(n):
            nu = p[7 + i]
            k = p[7 + n + i]
            if fl[i] == 1 or v * x[i] <= 0.0:
                # Eq. 2.24, stick (a slipping element whose velocity has reversed sticks)
                dx[i] = k * v
            else:
                # Eq. 2.25, slip: sgn(v)·ν·C·(1 − F/(ν s)) = C (ν s − F)/|s|
                r = c * (nu * s - x[i]) / smag
                # passivity guard: a slipping asperity cannot load faster than a sticking one
                if r * x[i] > 0.0 and abs(r) > k * abs(v):
                    r = k * abs(v) * _sgn(r)
                dx[i] = r
    else:
        for i in range(dx.shape[0]):
            dx[i] = 0.0


@njit(cache=CACHE)
def kernel_update(mid, p, x, fl, v, fa, fn):
    """Discrete logic after an integration step: stick/slip flags, saturations, reversal memory."""
    mu_s, mu_c, v_s, delta = p[0], p[1], p[2], p[3]
    if mid == BREEDVELD:
        v_pre = p[5]
        if abs(v) > v_pre:
            fl[0] = 1  # Eq. 2.17: slip
        elif abs(v) < 0.1 * v_pre:
            fl[0] = 0
    elif mid == GMS:
        n = int(p[6])
        smag = stribeck_magnitude(v, fn, mu_s, mu_c, v_s, delta)
        for i in range(n):
            if fl[i] == 0:
                if v * x[i] <= 0.0:
                    fl[i] = 1  # velocity reversed (or stopped): back to stick
            elif abs(x[i]) >= p[7 + i] * smag and v * x[i] > 0.0:
                fl[i] = 0  # force reached ν_i·s(v) while loading: slip
    elif mid == LEUVEN:
        n = int(p[7])
        sv = _sgn(v)
        if sv != 0.0 and sv != fl[0]:
            x[1] = _leuven_fh(p, x)  # F_b: hysteresis force at the reversal point
            fl[0] = int(sv)
        f_s = mu_s * fn
        for j in range(n):
            k = p[8 + n + j]
            w = p[8 + j] * f_s
            if k * x[2 + j] > w:
                x[2 + j] = w / k
            elif k * x[2 + j] < -w:
                x[2 + j] = -w / k


@njit(cache=CACHE)
def run_velocity_driven(mid, p, x0, fl0, v, dt, fn):
    """Integrate a friction model under a prescribed sliding velocity (explicit Euler).

    Returns (force[N+1], x[N+1, nx], fl[N+1, nf]) for velocities v[N] held over dt [s].
    Force sample i is evaluated with v[i-1] (v[0] for i = 0).
    """
    n = v.shape[0]
    nx = x0.shape[0]
    nf = fl0.shape[0]
    x = x0.copy()
    fl = fl0.copy()
    dx = np.zeros(nx)
    force = np.empty(n + 1)
    xs = np.empty((n + 1, nx))
    fls = np.empty((n + 1, nf), dtype=np.int64)
    force[0] = kernel_force(mid, p, x, fl, v[0], 0.0, fn)
    xs[0] = x
    fls[0] = fl
    for i in range(n):
        vi = v[i]
        kernel_rates(mid, p, x, fl, vi, 0.0, fn, dx)
        for j in range(nx):
            x[j] += dt * dx[j]
        kernel_update(mid, p, x, fl, vi, 0.0, fn)
        force[i + 1] = kernel_force(mid, p, x, fl, vi, 0.0, fn)
        xs[i + 1] = x
        fls[i + 1] = fl
    return force, xs, fls


@njit(cache=CACHE)
def run_mass(mid, p, x0, fl0, f_applied, mass, dt, fn, v0):
    """A block of ``mass`` [kg] pushed by f_applied[N] [N] on a surface with friction.

    Semi-implicit (symplectic) Euler: the velocity is advanced with the friction
    force of the current state, then the friction states with the new velocity.
    The external force handed to static models is the one that stops the block in
    this step, f_applied + m·v/dt. Returns (position, velocity, friction, x, fl).
    """
    n = f_applied.shape[0]
    nx = x0.shape[0]
    nf = fl0.shape[0]
    x = x0.copy()
    fl = fl0.copy()
    dx = np.zeros(nx)
    pos = np.empty(n + 1)
    vel = np.empty(n + 1)
    ff = np.empty(n + 1)
    xs = np.empty((n + 1, nx))
    fls = np.empty((n + 1, nf), dtype=np.int64)
    xp = 0.0
    vv = v0
    pos[0] = xp
    vel[0] = vv
    xs[0] = x
    fls[0] = fl
    ff[0] = kernel_force(mid, p, x, fl, vv, f_applied[0] + mass * vv / dt, fn)
    for i in range(n):
        fa = f_applied[i] + mass * vv / dt
        f = kernel_force(mid, p, x, fl, vv, fa, fn)
        vv = vv + dt * (f_applied[i] - f) / mass
        xp += dt * vv
        kernel_rates(mid, p, x, fl, vv, fa, fn, dx)
        for j in range(nx):
            x[j] += dt * dx[j]
        kernel_update(mid, p, x, fl, vv, fa, fn)
        pos[i + 1] = xp
        vel[i + 1] = vv
        ff[i + 1] = f
        xs[i + 1] = x
        fls[i + 1] = fl
    return pos, vel, ff, xs, fls
