"""The table as a rigid body on three contacts, linearised: a fixed-step reference for
the per-axis kernel's ``"translation"`` fidelity (issue 32 item 1).

The per-axis model (:mod:`turntable_env.reduced`) keeps the table's rotation about one
axis and the two driving tubes' bending at the static normal force F_N. Against the 3-D
model it steps 31 % too far forward at ±90 V, 100 Hz, a = 0.95, and 6.5× too far on the
small steps at ±20 V, 100 Hz, a = 0.5 (1.7 nm). Stop 66 added the sphere's translation in
the plane normal to the axis (``--variant no_tilt`` here): +13.9 % and 3.6× remained.
Most of the rest is the sphere's tilts: with the 3-D model's tilts held (``--variant
tilts_held``) or its centre of mass at the centre (``--variant no_com``), the 3-D model
steps as the translation does, since the centre of mass, 3R/8 below the centre, couples
the translation to the tilts. On the fast flybacks the balls' axial mass matters too
(``--variant series`` holds it massless). This reference keeps the table's six rigid-body
coordinates and each tube condensed at its contact point in three directions (its
tangent plane's two and its axis), linearised about the rest state, all derived from the
3-D model, nothing fitted:

* the table: the centre's translation x and the rotation vector φ (world frame); kinetic
  energy ½m|ẋ + φ̇ × c|² + ½φ̇ᵀJ_com φ̇ (App. C: c the centre of mass), gravity's pendulum
  stiffness m g h (I − ẑẑᵀ) on φ (Eq. C.16's h = 3R/8); the angle read is n·φ;
* each tube's contact point (the ball) in its tangent directions and along its axis d_k,
  condensed from the 3-D model's tube top (mass, stiffness and drive per volt, as the
  per-axis model condenses its driving direction); the drive along d_k is the stroke;
* each contact's normal force F_N + k_H(d_k·x − a_k) + d_c(d_k·ẋ − ȧ_k) (k_H: Eq. 3.21's
  Hertz law linearised at F_N, a_k the ball along d_k), which sets its Stribeck level;
* friction in each tangent direction (six 1-D GMS contacts, the 2-D law of Eq. 3.27 taken
  per direction), slip = tube point − table point, the table point x + φ × R d_k; a
  sticking element holds no more than its share ν_i|s(v)|: where the stroke's ringing
  drops F_N under its load it is clipped there, as the 3-D model clips it (stop 67's
  reference and kernel cut an element only at breakaway and stepped 12–16 % short on the
  forward flybacks of the ideal amplifier, ``--variant unclipped``).

It is built in the world frame from the 3-D model's packed arrays, independently of the
kernel's :meth:`~turntable_env.reduced.ReducedModel.translation_matrices` (which hold the
axis contact stuck; since stop 93 the kernel keeps the 3-D model's tube tops, and its
driving contacts are under the 2-D law, ``--variant tube_tops_2d`` here, where stop
67–92's kernel condensed the tubes at their contact points and held the driving
contacts' directions along the axis stuck, ``--variant side_stuck``). Variants:
``series`` (the ball's axial motion massless: Hertz's spring in series with the tube's
axial one, s V in the normal force), ``no_tilt`` (series, x normal to n, φ along n: stop
66's translation), ``tilts_held`` (the same against the 3-D model with its tilts held by
its inertia across n ×10⁴), ``frozen`` (θ and the driving tubes alone, F_N fixed: the
per-axis model), ``no_stroke`` (the stroke removed, from the 3-D model too), ``no_com``
(the centre of mass at the centre, in the 3-D model too), ``friction_2d`` (each contact's
two directions under the 2-D law), ``hertz``, ``nonlinear`` (series with Hertz's
curvature, the latter with the 2-D law too), ``hertz_axial`` (Hertz's curvature on the
ball's axial coordinate), ``tube_tops`` (each tube top's six coordinates, not
condensed), ``tube_tops_2d`` (that with every contact under the 2-D law: the kernel's
structure since stop 93),
``unclipped`` (a sticking element cut only at breakaway), ``shared`` (the non-driving
directions stuck, as the kernel holds them, but each element's share in a driving
direction what the other direction's load leaves of it, √((ν_i|s|)² − F_i,n²): the 2-D
law's bound on a contact the kernel treats per direction).
Integration: semi-implicit Euler at a fixed step (default 5 ns), the per-axis kernel's GMS
law (``gms_element_step``, Eq. 2.24–2.25); the channel voltage is the per-axis model's
amplifier output, interpolated linearly.

    python experiments/sphere_tilt.py [--variant rigid|series|no_tilt|tilts_held|frozen|
        no_stroke|no_com|side_stuck|friction_2d|hertz|nonlinear|hertz_axial|tube_tops|
        tube_tops_2d|unclipped|shared]
        [--amplitude 20 90 200] [--frequency 100 2000] [--a 0.95] [--amplifier adapted]
        [--dt 5e-9] [--full-dt-factor F]

prints, per case both ways, the 3-D model's step, this reference's, the kernel's with
the translation and the per-axis model's, their differences, and the median and largest
|difference| (cases with a 3-D step of 1 nm or more).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from dataclasses import replace
from typing import NamedTuple

import numpy as np
from numba import njit

from turntable_env.bench import FULL_COARSE
from turntable_env.friction.gms2d import gms2d_rates, gms2d_update
from turntable_env.friction.kernels import gms_element_step, stribeck_magnitude
from turntable_env.model import axis_index
from turntable_env.reduced import ReducedModel, TranslationParameters, simulate_reduced
from turntable_env.simulation import simulate, stepping_drive


class Arrays(NamedTuple):
    """What crosses into :func:`_run` (SI units; q: the table's x, φ, then the tubes')."""

    minv: np.ndarray  # (nq, nq) inverse mass matrix
    kq: np.ndarray  # (nq, nq) stiffness: the tubes', gravity on φ [N/m, N m/rad]
    cq: np.ndarray  # (nq, nq) the tubes' damping
    bq: np.ndarray  # (nq,) the tubes' force per channel volt [N/V]
    slip: np.ndarray  # (6, nq) each tangent direction's slip over q [m]
    normal: np.ndarray  # (3, nq) each contact's approach over q [m]
    stroke: np.ndarray  # (3,) each tube's axial stroke per channel volt [m/V]
    kn: float  # normal stiffness [N/m]
    dc: float  # normal damping [N s/m]
    fn0: float  # static normal force [N]
    nu: np.ndarray  # GMS fractions [-]
    kk: np.ndarray  # GMS stiffnesses [N/m]
    gms: np.ndarray  # C [N/s], μ_s, μ_c, v_s [m/s], δ, σ₂ [N s/m]
    beta_t: float  # micro-damping of the sticking elements [s]
    held: np.ndarray  # (6,) 1 where a tangent direction's contact never slips
    two_d: int  # 1: each contact's two directions under the 2-D GMS law (Eq. 3.27)
    clip: int  # 1: a sticking element clipped at its share where F_N falls (3-D model's)
    shared: int  # 1: a direction's element share is what the other direction leaves
    hertz: np.ndarray  # k_c [N/m^e], e, the tube's axial stiffness [N/m]; k_c = 0: linear


@njit(cache=False)
def _hertz_series(hz, fn0, approach, guess):
    """The Hertz overlap δ [m] where k_c δ^e in series with the axial spring k_a carries
    the contact's approach beyond rest (``approach`` [m], positive: closer): δ + k_cδ^e/k_a
    = δ_0 + F_N/k_a + approach (Newton from ``guess``); 0 where the contact opens."""
    kc, ex, ka = hz[0], hz[1], hz[2]
    d0 = (fn0 / kc) ** (1.0 / ex)
    total = d0 + fn0 / ka + approach
    if total <= 0.0:
        return 0.0
    d = guess if guess > 0.0 else d0
    for _ in range(50):
        g = d + kc * d**ex / ka - total
        dg = 1.0 + ex * kc * d ** (ex - 1.0) / ka
        dn = d - g / dg
        if dn <= 0.0:
            dn = 0.5 * d
        if abs(dn - d) < 1e-15:
            return dn
        d = dn
    return d


@njit(cache=False)
def _friction_1d(q, qd, slip_rows, fn, f, st, slip_prev, dt, arr, force):
    """Each tangent direction under the 1-D GMS law (the per-axis kernel's element step,
    Eq. 2.24–2.26); adds the friction's generalised forces to ``force``. A sticking
    element holds no more than its share ν_i|s(v)| (as the 3-D model: where F_N falls under
    its load it is clipped) unless ``arr.clip`` is 0; with ``arr.shared`` an element's share
    in a direction that can slip is what the contact's other direction leaves of it,
    √((ν_i|s|)² − F_i,other²) (the isotropic 2-D law's bound, Eq. 3.27)."""
    gms, nu, kk, beta_t = arr.gms, arr.nu, arr.kk, arr.beta_t
    nq = q.shape[0]
    ne = nu.shape[0]
    for c in range(slip_rows.shape[0]):
        x = 0.0
        xd = 0.0
        for a in range(nq):
            x += slip_rows[c, a] * q[a]
            xd += slip_rows[c, a] * qd[a]
        dx = x - slip_prev[c]
        slip_prev[c] = x
        lvl = stribeck_magnitude(xd, fn[c // 2], gms[1], gms[2], gms[3], gms[4])
        if arr.held[c] == 1:
            lvl = 1e12  # never slips: its elements stay stuck, a linear spring
        decay = math.exp(-gms[0] * dt / lvl) if lvl > 0.0 else 0.0
        sg = 1.0 if xd > 0.0 else (-1.0 if xd < 0.0 else 0.0)
        ftot = 0.0
        ct = 0.0
        for i in range(ne):
            cap = nu[i] * lvl
            if arr.shared == 1 and arr.held[c] == 0:
                cap = math.sqrt(max(cap * cap - f[c ^ 1, i] ** 2, 0.0))
            fi = gms_element_step(f[c, i], st[c, i], kk[i], dx, cap * sg, decay)
            if st[c, i] == 1:
                if abs(fi) >= cap and fi * xd > 0.0:
                    st[c, i] = 0
                    fi = cap if fi > 0.0 else -cap
                else:
                    ct += beta_t * kk[i]
            elif fi * xd <= 0.0:
                st[c, i] = 1
            if arr.clip == 1 and st[c, i] == 1 and abs(fi) > cap:  # F_N fell under its load
                fi = cap if fi > 0.0 else -cap
            f[c, i] = fi
            ftot += fi
        ftot += (ct + gms[5]) * xd  # micro-damping and viscous σ₂ (Eq. 2.26)
        for a in range(nq):  # F on the table, −F on the tube: −F ∂slip/∂q
            force[a] -= ftot * slip_rows[c, a]


@njit(cache=False)
def _friction_2d(q, qd, slip_rows, fn, f2, st2, df2, dt, arr, force):
    """Each contact's two tangent directions under the 2-D GMS law (Eq. 3.27 in the
    isotropic vector form of :mod:`turntable_env.friction.gms2d`), explicit over the step;
    adds the friction's generalised forces to ``force``."""
    gms, nu, kk = arr.gms, arr.nu, arr.kk
    nq = q.shape[0]
    ne = nu.shape[0]
    for k in range(3):
        v = np.zeros(2)
        for j in range(2):
            for a in range(nq):
                v[j] += slip_rows[2 * k + j, a] * qd[a]
        if fn[k] <= 0.0:  # unloaded: no friction, the elements released
            f2[k, :, :] = 0.0
            st2[k, :] = 1
            continue
        gms2d_rates(f2[k], st2[k], v[0], v[1], fn[k], nu, kk, gms[0], gms[1], gms[2], gms[3],
                    gms[4], df2)  # fmt: skip
        for i in range(ne):
            f2[k, i, 0] += dt * df2[i, 0]
            f2[k, i, 1] += dt * df2[i, 1]
        was = st2[k].copy()
        gms2d_update(f2[k], st2[k], v[0], v[1], fn[k], nu, gms[1], gms[2], gms[3], gms[4])
        lvl = stribeck_magnitude(math.sqrt(v[0] ** 2 + v[1] ** 2), fn[k], gms[1], gms[2],
                                 gms[3], gms[4])  # fmt: skip
        ct = 0.0
        for i in range(ne):
            fm = math.sqrt(f2[k, i, 0] ** 2 + f2[k, i, 1] ** 2)
            if (was[i] == 1 or st2[k, i] == 1) and fm > nu[i] * lvl:  # as the 3-D model
                f2[k, i, 0] *= nu[i] * lvl / fm
                f2[k, i, 1] *= nu[i] * lvl / fm
            if st2[k, i] == 1:
                ct += arr.beta_t * kk[i]
        for j in range(2):
            ftot = (ct + gms[5]) * v[j]
            for i in range(ne):
                ftot += f2[k, i, j]
            for a in range(nq):
                force[a] -= ftot * slip_rows[2 * k + j, a]


@njit(cache=False)
def _run(t_v, v_v, dt, n_steps, arr, out_every):
    """Semi-implicit Euler at a fixed step; returns (times, q records)."""
    minv, kq, cq, bq, slip_rows, nrow = arr.minv, arr.kq, arr.cq, arr.bq, arr.slip, arr.normal
    nu = arr.nu
    nq = minv.shape[0]
    nc = slip_rows.shape[0]
    ne = nu.shape[0]
    q = np.zeros(nq)
    qd = np.zeros(nq)
    f = np.zeros((nc, ne))
    st = np.ones((nc, ne), dtype=np.int64)
    n_out = n_steps // out_every + 1
    rec_t = np.empty(n_out)
    rec_q = np.empty((n_out, nq))
    force = np.empty(nq)
    f2 = np.zeros((3, ne, 2))  # the 2-D law's element forces [N] per contact
    st2 = np.ones((3, ne), dtype=np.int64)
    df2 = np.zeros((ne, 2))
    slip_prev = np.zeros(nc)
    fn = np.empty(3)
    d_el = np.full(3, -1.0)  # the Hertz overlaps [m] (the last solution; −1: none yet)
    j = 0
    iv = 0
    nv = t_v.shape[0]
    for step in range(n_steps + 1):
        t = step * dt
        while iv < nv - 2 and t_v[iv + 1] <= t:
            iv += 1
        w = (t - t_v[iv]) / (t_v[iv + 1] - t_v[iv])
        volt = v_v[iv] + w * (v_v[iv + 1] - v_v[iv])
        vdot = (v_v[iv + 1] - v_v[iv]) / (t_v[iv + 1] - t_v[iv])
        if step % out_every == 0:
            rec_t[j] = t
            for a in range(nq):
                rec_q[j, a] = q[a]
            j += 1
        if step == n_steps:
            break
        for a in range(nq):
            s = bq[a] * volt
            for c in range(nq):
                s -= kq[a, c] * q[c] + cq[a, c] * qd[c]
            force[a] = s
        for k in range(3):  # normal forces: the ball pushes the table along −d_k
            xn = 0.0
            vn = 0.0
            for a in range(nq):
                xn += nrow[k, a] * q[a]
                vn += nrow[k, a] * qd[a]
            if arr.hertz[0] > 0.0:  # Eq. 3.21's k_c δ^e in series with the tube's axial spring
                d_el[k] = _hertz_series(arr.hertz, arr.fn0, xn - arr.stroke[k] * volt, d_el[k])
                df = arr.hertz[0] * d_el[k] ** arr.hertz[1] - arr.fn0
                df += arr.dc * (vn - arr.stroke[k] * vdot)
            else:
                df = arr.kn * (xn - arr.stroke[k] * volt) + arr.dc * (vn - arr.stroke[k] * vdot)
            if arr.fn0 + df < 0.0:
                df = -arr.fn0
            fn[k] = arr.fn0 + df
            for a in range(nq):
                force[a] -= df * nrow[k, a]
        if arr.two_d == 1:
            _friction_2d(q, qd, slip_rows, fn, f2, st2, df2, dt, arr, force)
        else:
            _friction_1d(q, qd, slip_rows, fn, f, st, slip_prev, dt, arr, force)
        for a in range(nq):
            acc = 0.0
            for c in range(nq):
                acc += minv[a, c] * force[c]
            qd[a] += dt * acc
        for a in range(nq):
            q[a] += dt * qd[a]
    return rec_t[:j], rec_q[:j]


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _table(model, nq: int, no_com: bool = False) -> tuple[np.ndarray, ...]:  # type: ignore[no-untyped-def]
    """(M, K, C, b) over nq coordinates, the table's six first (x, φ; world frame): its
    kinetic energy ½m|ẋ + φ̇ × c|² + ½φ̇ᵀJ_com φ̇ and gravity's pendulum m g h (I − ẑẑᵀ)."""
    ar = model.packed
    m = float(ar["table_p"][0])
    cb = np.zeros(3) if no_com else np.asarray(ar["c_body"], float)
    j_com = np.linalg.inv(ar["jinv"])
    if no_com:  # the inertia about the centre, J_com + m(|c|²I − ccᵀ), now about the CoM
        c0 = np.asarray(ar["c_body"], float)
        j_com = j_com + m * (c0 @ c0 * np.eye(3) - np.outer(c0, c0))
    mass = np.zeros((nq, nq))
    bmap = np.hstack([np.eye(3), -_skew(cb)])  # v_com = ẋ + φ̇ × c
    mass[:6, :6] = m * bmap.T @ bmap
    mass[3:6, 3:6] += j_com
    kq = np.zeros((nq, nq))
    kq[3:6, 3:6] = m * float(model.gravity) * -float(cb[2]) * np.diag([1.0, 1.0, 0.0])
    return mass, kq, np.zeros((nq, nq)), np.zeros(nq)


def _directions(ar, k: int, c_ax: int, n: np.ndarray) -> tuple[np.ndarray, ...]:  # type: ignore[no-untyped-def]
    """Tube k's axis d and the two tangent directions of its contact: e = n × d and d × e
    for a driving tube, the driving tubes' axes for the tube on the axis."""
    d = np.asarray(ar["d_nom"][k], float)
    if k == c_ax:
        t1, t2 = (np.asarray(ar["d_nom"][j], float) for j in range(3) if j != c_ax)
    else:
        t1 = np.cross(n, d)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(d, t1)
    return d, t1, t2


def _build_tops(rm: ReducedModel, tr: TranslationParameters, variant: str = "tube_tops") -> dict:
    """``tube_tops``: each tube top's six coordinates (rotation, translation; the 3-D
    model's mass, stiffness, damping and drive per quadrant volt) instead of its contact
    point condensed; the normal springs are Hertz's, the stroke the tops' drive
    (``tube_tops_2d``: every contact under the 2-D law too, the kernel's structure since
    stop 93 but for the axis contact, which the kernel holds stuck)."""
    ps, model = rm.params, rm.full
    ar = model.packed
    c_ax = axis_index(rm.axis)
    n = np.asarray(model.layout.axis_units[c_ax], float)
    nq = 24
    mass, kq, cq, bq = _table(model, nq)
    slip = np.zeros((6, nq))
    normal = np.zeros((3, nq))
    for k in range(3):
        d, t1, t2 = _directions(ar, k, c_ax, n)
        r_c = ar["r0"][k] - ps.tube.outer_radius * d  # tube top → contact point [m]
        sl = slice(6 + 6 * k, 12 + 6 * k)
        mass[sl, sl], kq[sl, sl], cq[sl, sl] = ar["mtube"][k], ar["ktop"][k], ar["dtop"][k]
        bq[sl] = ar["bcoup"][k] @ ((ar["qchan"][k] == c_ax) * ar["qsign"][k])
        normal[k, :3] = d  # approach: d·x − d·(u + θ × r_c) of the ball's contact point
        normal[k, sl] = -np.concatenate([np.cross(r_c, d), d])
        for j, t in enumerate((t1, t2)):
            _table_side(slip[2 * k + j], t, d, float(ps.table.radius))
            slip[2 * k + j, sl] = np.concatenate([np.cross(r_c, t), t])
    arrays = _arrays(rm, tr, (mass, kq, cq, bq), slip, normal, np.zeros(3), variant)
    return {"arrays": arrays, "angle_row": np.concatenate([np.zeros(3), n, np.zeros(18)])}


def _table_side(row: np.ndarray, t: np.ndarray, d: np.ndarray, radius: float) -> None:
    """The table point's part of a slip row (tube point − table point) along t at the
    contact radius·d: −t·(x + φ × radius d)."""
    row[:3] = -t
    row[3:6] = -radius * np.cross(d, t)


def _arrays(rm: ReducedModel, tr: TranslationParameters, mkcb: tuple, slip: np.ndarray,
            normal: np.ndarray, stroke: np.ndarray, variant: str) -> Arrays:  # fmt: skip
    """The :class:`Arrays` of (M, K, C, b) ``mkcb`` and the rows, for ``variant``."""
    ps = rm.params
    fr = ps.friction
    gms = np.array([fr.C, fr.stribeck.mu_s, fr.stribeck.mu_c, fr.stribeck.v_s,
                    fr.stribeck.delta, fr.stribeck.sigma2])  # fmt: skip
    hertz = np.zeros(3)
    if variant in ("hertz", "nonlinear", "hertz_axial"):
        hertz[:] = ps.contact.normal_stiffness, ps.contact.normal_exponent, tr.axial_stiffness
        if variant == "hertz_axial":  # the ball's axial coordinate takes the tube's spring
            hertz[2] = 1e30
    held = np.zeros(6, dtype=np.int64)
    if variant in ("side_stuck", "shared"):  # only the two driving directions slip
        held[:] = 1
        held[[2 * k for k in range(3) if k != axis_index(rm.axis)]] = 0
    series = variant in SERIES
    mass, kq, cq, bq = mkcb
    return Arrays(np.linalg.inv(mass), kq, cq, bq, slip, normal, stroke,
                  tr.normal_stiffness if series else tr.hertz_stiffness, tr.normal_damping,
                  float(ps.contact.preload), np.asarray(fr.nu, float),
                  np.asarray(fr.k, float), gms, float(ps.contact.tangential_damping), held,
                  int(variant in ("friction_2d", "nonlinear", "tube_tops_2d")),
                  int(variant != "unclipped"),
                  int(variant == "shared"), hertz)  # fmt: skip


def build(rm: ReducedModel, variant: str = "rigid") -> dict:
    """The reference's arrays for ``rm``'s axis and parameter set (see the module
    docstring and :data:`VARIANTS`) and the row that reads the angle about the axis."""
    if variant not in VARIANTS:
        raise ValueError(f"variant={variant!r}: one of {', '.join(VARIANTS)}")
    ps, model = rm.params, rm.full
    ar = model.packed
    c_ax = axis_index(rm.axis)
    n = np.asarray(model.layout.axis_units[c_ax], float)
    tr = TranslationParameters.from_model(model, rm.axis, ps)
    if variant in ("tube_tops", "tube_tops_2d"):
        return _build_tops(rm, tr, variant)
    # each tube condensed at its contact point along its tangent directions, and along its
    # axis too (the ball's own coordinate) unless the normal spring is the series one
    ndir = 2 if variant in SERIES else 3
    nq = 6 + 3 * ndir
    mass, kq, cq, bq = _table(model, nq, variant == "no_com")
    slip = np.zeros((6, nq))
    normal = np.zeros((3, nq))
    stroke = np.zeros(3)
    for k in range(3):
        d, t1, t2 = _directions(ar, k, c_ax, n)
        r_c = ar["r0"][k] - ps.tube.outer_radius * d  # tube top → contact point [m]
        dirs = (t1, t2, d)[:ndir]
        amap = np.stack([np.concatenate([np.cross(r_c, t), t]) for t in dirs], axis=1)
        kinv = np.linalg.inv(ar["ktop"][k])
        k_eff = np.linalg.inv(amap.T @ kinv @ amap)  # [N/m]
        psi = kinv @ amap @ k_eff
        qv = (ar["qchan"][k] == c_ax) * ar["qsign"][k]  # quadrant volts per channel volt
        sl = slice(6 + ndir * k, 6 + ndir * (k + 1))
        mass[sl, sl] = psi.T @ ar["mtube"][k] @ psi
        kq[sl, sl] = k_eff
        cq[sl, sl] = ps.tube.damping_coefficient * k_eff
        bq[sl] = k_eff @ (amap.T @ kinv @ ar["bcoup"][k] @ qv)  # free deflection's force
        normal[k, :3] = d
        if ndir == 3:  # approach d·x − a_k; the stroke drives a_k
            normal[k, sl.start + 2] = -1.0
            if variant == "no_stroke":
                bq[sl.start + 2] = 0.0
        else:  # the ball's axial stroke in series with Hertz's and the tube's springs
            a_d = np.concatenate([np.cross(r_c, d), d])
            stroke[k] = float(a_d @ kinv @ ar["bcoup"][k] @ qv)
        for j, t in enumerate((t1, t2)):  # slip = u − t·(x + φ × R d)
            slip[2 * k + j, sl.start + j] = 1.0
            _table_side(slip[2 * k + j], t, d, float(ps.table.radius))
    # coordinates p = (x1, x2, x_n, φ1, φ2, θ, the tubes') over (d1, d2, n): q = T p, and a
    # variant keeps some of them (the others held at 0)
    basis = [np.asarray(ar["d_nom"][j], float) for j in range(3) if j != c_ax] + [n]
    tmat = np.zeros((nq, nq))
    for i, v in enumerate(basis):
        tmat[:3, i], tmat[3:6, 3 + i] = v, v
    tmat[6:, 6:] = np.eye(nq - 6)
    side = [6 + ndir * k + 1 for k in range(3) if k != c_ax]  # driving tubes along n
    axis_tube = list(range(6 + ndir * c_ax, 6 + ndir * (c_ax + 1)))
    drop = {"no_tilt": [2, 3, 4, *side], "tilts_held": [2, 3, 4, *side],
            "frozen": [0, 1, 2, 3, 4, *side, *axis_tube]}.get(variant, [])  # fmt: skip
    keep = [i for i in range(nq) if i not in drop]
    tmat = tmat[:, keep]
    mkcb = (tmat.T @ mass @ tmat, tmat.T @ kq @ tmat, tmat.T @ cq @ tmat, tmat.T @ bq)
    if variant == "frozen":  # F_N fixed
        stroke[:] = 0.0
    angle_row = np.zeros(len(keep))
    angle_row[keep.index(5)] = 1.0
    arrays = _arrays(rm, tr, mkcb, slip @ tmat, normal @ tmat, stroke, variant)
    return {"arrays": arrays, "angle_row": angle_row}


# the variants whose normal spring is Hertz's in series with the tube's massless axial one
SERIES = ("series", "no_tilt", "tilts_held", "frozen", "hertz", "nonlinear")
VARIANTS = ("rigid", "series", "no_tilt", "tilts_held", "frozen", "no_stroke", "no_com",
            "side_stuck", "friction_2d", "hertz", "nonlinear", "hertz_axial", "tube_tops",
            "tube_tops_2d", "unclipped", "shared")


def remove_axial_stroke(model) -> None:  # type: ignore[no-untyped-def]
    """Remove, in place, the translation along each tube's axis from its free twist per
    quadrant volt (bending kept) of a 3-D model built for this use alone (its packed
    ``bcoup``); ``experiments/axial_stroke.py`` uses it too."""
    ar = model.packed
    for k in range(3):
        d = ar["d_nom"][k]
        xi = np.linalg.solve(ar["ktop"][k], ar["bcoup"][k])
        xi[3:] -= np.outer(d, d @ xi[3:])
        ar["bcoup"][k][:] = ar["ktop"][k] @ xi


def _centre_of_mass_at_the_centre(model) -> None:  # type: ignore[no-untyped-def]
    """Put, in place, a 3-D model's centre of mass at the sphere's centre, its inertia about
    the centre kept (a model built for this use alone)."""
    ar = model.packed
    c0 = ar["c_body"].copy()
    m = float(ar["table_p"][0])
    j_o = np.linalg.inv(ar["jinv"]) + m * (c0 @ c0 * np.eye(3) - np.outer(c0, c0))
    ar["c_body"][:] = 0.0
    ar["jinv"][:] = np.linalg.inv(j_o)


def _tilts_held(model, axis: int) -> None:  # type: ignore[no-untyped-def]
    """Hold, in effect, a 3-D model's tilts: its inertia about the centre of mass across the
    axis n multiplied by 10⁴, n·J·n kept (a model built for this use alone)."""
    ar = model.packed
    n = np.asarray(model.layout.axis_units[axis], float)
    j = np.linalg.inv(ar["jinv"])
    across = np.eye(3) - np.outer(n, n)
    ar["jinv"][:] = np.linalg.inv(float(n @ j @ n) * np.outer(n, n) + 1e4 * float(j.max()) * across)


def run(amplitude: float, frequency: float, a: float, *, variant: str = "rigid",
        amplifier: str = "adapted", dt: float = 5e-9, periods: int = 3,
        full: bool = True, full_dt_factor: float | None = None) -> dict:  # fmt: skip
    """Mean |step| per period [nm] of this reference (``variant``), the per-axis model,
    the per-axis kernel with the translation (``"translation"`` fidelity) and, with
    ``full``, the 3-D model (amplitude in tube volts; the 3-D model with the variant's
    change where it has one: no stroke, the centre of mass at the centre, the tilts held;
    the kernel is built before that change, but for the centre of mass)."""
    drive, ps = stepping_drive("real", amplitude=amplitude / 45.0, frequency=frequency,
                               periods=periods, a=a, amplifier=amplifier)  # fmt: skip
    rm = ReducedModel(ps, "B")
    if variant == "no_com":
        _centre_of_mass_at_the_centre(rm.full)
    p = build(rm, variant)
    ref = simulate_reduced(ps, drive, model=rm, output_dt=1e-7)
    kt = ReducedModel(ps, "B", model=rm.full, translation=True)
    kernel = simulate_reduced(ps, drive, model=kt, output_dt=1e-7)
    n_steps = round(drive.duration / dt)
    out_every = max(1, round(1e-6 / dt))
    t, qrec = _run(ref.time, ref.voltage, dt, n_steps, p["arrays"], out_every)
    proto = replace(ref, time=t, angle_rad=qrec @ p["angle_row"])
    out = {"reference_nm": 1e9 * proto.step_size, "per_axis_nm": 1e9 * ref.step_size,
           "kernel_nm": 1e9 * kernel.step_size}  # fmt: skip
    if full:
        if variant == "no_stroke":
            remove_axial_stroke(rm.full)
        if variant == "tilts_held":
            _tilts_held(rm.full, axis_index("B"))
        fine = {} if full_dt_factor is None else {"dt_factor": full_dt_factor,
                                                  "coarse_factor": None}  # fmt: skip
        out["full_nm"] = 1e9 * simulate(ps, drive, axis="B", model=rm.full,
                                        **{"coarse_factor": FULL_COARSE, **fine},
                                        output_dt=min(1e-5, 0.01 / frequency)).step_size
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--amplitude", type=float, nargs="+", default=[20.0, 90.0, 200.0],
                    help="tube volts [V], each run both ways")  # fmt: skip
    ap.add_argument("--frequency", type=float, nargs="+", default=[100.0, 2000.0],
                    help="[Hz]")  # fmt: skip
    ap.add_argument("--a", type=float, default=0.95, help="ramp ratio, 0.5 <= a < 1")
    ap.add_argument("--amplifier", choices=("adapted", "unadapted", "ideal"),
                    default="adapted")  # fmt: skip
    ap.add_argument("--dt", type=float, default=5e-9, help="fixed step [s], <= 1e-8")
    ap.add_argument("--variant", choices=VARIANTS, default="rigid")
    ap.add_argument("--full-dt-factor", type=float, default=None,
                    help="the 3-D model's fixed step as a fraction of 1/ω_max, 0 < f <= 0.05 "
                    "(default: its adaptive step, as turntable bench runs it)")  # fmt: skip
    args = ap.parse_args(argv)
    bad = [f"--amplitude {v!r}" for v in args.amplitude if not 0.0 < v <= 200.0]
    bad += [f"--frequency {v!r}" for v in args.frequency if not 1.0 <= v <= 5000.0]
    bad += [f"--a {args.a!r}"] if not 0.5 <= args.a < 1.0 else []
    bad += [f"--dt {args.dt!r}"] if not 0.0 < args.dt <= 1e-8 else []
    f_dt = args.full_dt_factor
    bad += [f"--full-dt-factor {f_dt!r}"] if f_dt is not None and not 0.0 < f_dt <= 0.05 else []
    if bad:
        ap.error(f"{bad[0]}: out of range (amplitude 0-200 V, frequency 1-5000 Hz, "
                 "a 0.5-1, dt 0-1e-8 s, full-dt-factor 0-0.05)")  # fmt: skip
    print(f"variant {args.variant}, a = {args.a:g}, {args.amplifier} amplifier, "
          f"dt = {args.dt:g} s; steps [nm] per period, differences against the 3-D model")
    print("   V     Hz     3-D  reference (diff)  translation  (diff)  per-axis  (diff)")
    rows = []
    for f, v, sign in itertools.product(args.frequency, args.amplitude, (1.0, -1.0)):
        try:
            r = run(sign * v, f, args.a, variant=args.variant, amplifier=args.amplifier,
                    dt=args.dt, full_dt_factor=f_dt)  # fmt: skip
        except ValueError as exc:  # the adapted flyback does not fit the period
            print(f"{sign * v:+5.0f} {f:6.0f}  skipped ({str(exc)[:60]})")
            continue
        rows.append(r)
        full = r["full_nm"]
        print(f"{sign * v:+5.0f} {f:6.0f} {full:7.2f} {r['reference_nm']:9.2f} "
              f"{r['reference_nm'] / full - 1:+7.3f} {r['kernel_nm']:12.2f} "
              f"{r['kernel_nm'] / full - 1:+7.3f} {r['per_axis_nm']:9.2f} "
              f"{r['per_axis_nm'] / full - 1:+7.3f}", flush=True)  # fmt: skip
    for name, key in (("reference", "reference_nm"), ("translation (kernel)", "kernel_nm"),
                      ("per-axis", "per_axis_nm")):  # fmt: skip
        d = np.abs([r[key] / r["full_nm"] - 1.0 for r in rows if r["full_nm"] >= 1.0])
        if d.size:
            print(f"{name}: median |diff| {100 * np.median(d):.1f} %, max "
                  f"{100 * d.max():.1f} %, within 5 % {int(np.sum(d <= 0.05))} of {d.size}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
