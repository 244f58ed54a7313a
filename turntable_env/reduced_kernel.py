"""Compiled integrator of the per-axis reduced model (:mod:`turntable_env.reduced`).

Between GMS transitions the reduced model is linear: the table angle θ and the two
tube contact points u_k are a 6-state linear system ẏ = A_c y + b V + B_f f driven by
the amplifier voltage V and by constant per-contact forces f (the stuck elements'
offsets and the slipping elements' forces). Two exact propagators serve it:

* **All elements stuck, amplifier linear** (the ramp: most of the time). The solution
  is analytic for a voltage ramp V(t) = V0 + V̇t:

      y(t) = y_p(t) + Re Σ_j v_j z_j e^{λ_j t},  y_p(t) = Q (V0 + V̇t, f1, f2) + q2 V̇,

  with Q = −A⁻¹[b B_f], q2 = A⁻¹Q[:, 0] and the eigenpairs (λ_j, v_j) of the all-stick
  A (z = W(y − y_p), W = V⁻¹). The kernel takes one step to the next breakpoint (or
  the end) unless a transition comes first, and evaluates the solution at the output
  times in between (no landing on them). Transitions are found on the analytic
  solution: a bound on the modal amplitudes certifies event-free horizons against each
  stuck element's margin (|F_i| ≤ |F_i − k_i r_k| + k_i(R_k + |ẋ_p|t) < ν_i s(v_max),
  R_k = Σ_j|c_kj z_j| the ring amplitude); where the bound cannot certify, the event
  function g = min_i ν_i|s(ẋ)| − |F_i| is sampled at a quarter period of the fastest
  ringing mode, and a crossing is located to the grid by the Illinois method.
* **Some element slipping, or the amplifier slewing**: the step matrices Φ_c(h), Γ_c(h)
  of the augmented system (scipy ``expm``, then repeated squaring), precomputed for
  every stick configuration c (stuck stiffness Σk_i of each contact) and every rung
  h = h_min·2^r of a ladder (first-order hold of V over a step):

      y(t+h) = Φ_c(h) y(t) + Γ_c(h) [V(t), V̇, f_1, f_2].

  A step whose end shows a transition (stick→slip when |F_i| reaches ν_i|s(v)| while
  loading; slip→stick when the relative velocity reverses) is rejected and retried one
  rung lower, down to h_min; after a step without one the rung grows by one; the rung is
  capped at ``r_slip`` while an element slips, at ``ring_frac`` of the fastest ringing
  mode's period while all stick, and lands on breakpoints and output times.

Time runs on the integer grid of h_min (1/16 µs by default): drive breakpoints and
outputs are rounded to it and transitions are located to it.

Slipping elements relax exactly for the step's mean relative velocity
(dF/dt = C(ν_i s(v) sgn v − F_i)/|s(v)|, Eq. 2.25); their loading rate is capped at
k_i|v| as in the 1-D kernel. Batched: ``numba.prange`` runs the N independent
turntables (own parameters and drives) on all cores; each turntable's arithmetic does
not depend on the others or on the thread count, so results equal serial runs bit for
bit. A single run is a batch of one.
"""

from __future__ import annotations

import cmath
import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .amplifier import (
    AMP_FAST,
    AMP_GAIN,
    AMP_IDEAL,
    AMP_LIMIT,
    AMP_RATE,
    AMP_T_FAST,
    AMP_TAU,
    amplifier_step,
)
from .friction.kernels import gms_element_step, stribeck_magnitude
from .integrator import advance_index as _advance
from .integrator import pwl_value as _input_at
from .kernel_cache import CACHE
from .kernel_types import GMS_C, GMS_DELTA, GMS_MU_C, GMS_MU_S, GMS_V_S

__all__ = ["N_REC", "REC_FIELDS", "run_reduced_batch", "run_reduced_serial"]

# per-record fields (rec[b, i, :])
REC_FIELDS = (
    "time_s",
    "angle_rad",
    "angular_velocity_rad_s",
    "voltage_V",
    "tube1_m",
    "tube2_m",
    "slip1_m",
    "slip2_m",
    "friction1_N",
    "friction2_N",
    "n_stick1",
    "n_stick2",
)
N_REC = len(REC_FIELDS)

# packed rows: see turntable_env.kernel_types.ReducedArrays
FAST_QUIET = 1e-3  # V: an amplifier fast-path transient above it keeps steps short
# samples of the all-stick event function per ladder ring step (ring_frac of a period):
# 1/4 → 1/16 of the ringing mode's period, so a sampled peak is ≥ cos(11.25°) = 98 % of it
SAMPLE_FRACTION = 0.25


@njit(cache=CACHE)
def _rel(y, mech, k):
    """Relative displacement and velocity (tube contact point − table point) of contact k."""
    rho = mech[2 + k]
    return y[2 + 2 * k] - rho * y[0], y[3 + 2 * k] - rho * y[1]


@njit(cache=CACHE)
def _amp_linear(v0, vs0, vf0, u0, slope, row, ideal):
    """True when the amplifier output [V] is linear in time (to FAST_QUIET) while its input
    ramps from u0 [V] at ``slope`` [V/s]: inside the slew limit and with the first-order
    transients of both paths settled (:func:`~turntable_env.amplifier.ramp_step`'s exact
    branch with e0 ≈ 0)."""
    if ideal:
        return True
    gain, tau, rate, a, tf = row[0], row[1], row[4], row[5], row[6]
    if abs(gain * slope) >= rate:
        return False
    if a == 0.0:
        return (
            abs(gain * u0 - v0) <= rate * tau and abs(gain * (u0 - slope * tau) - v0) <= FAST_QUIET
        )
    gs = (1.0 - a) * gain
    if abs(gs * u0 - vs0) > rate * tau or abs(gs * (u0 - slope * tau) - vs0) > FAST_QUIET:
        return False
    if abs(a * gain * (u0 - slope * tf) - vf0) > FAST_QUIET:
        return False
    return abs(vs0 + vf0 - v0) <= FAST_QUIET


@njit(cache=CACHE)
def _modal_at(t, z0, lam, ez):
    """Modal amplitudes z_j e^{λ_j t} at t [s] from the segment start into ez."""
    for j in range(z0.shape[0]):
        ez[j] = z0[j] * cmath.exp(lam[j] * t)


class _Analytic(NamedTuple):
    """One all-stick analytic step of one turntable (module docstring): modal amplitudes
    z0 at its start, eigenvalues ``lam``, the contacts' modal projections ``mc``, the
    particular relative displacement ``xq0`` and its rate ``xrate``, the relative
    displacement ``x0`` and element forces ``f0`` at the start, the elements' stiffness
    ``kk`` and shares ``nu``, the normal forces ``fn``, the GMS row ``gms``; scratch ``ez``
    (modal terms), ``xs``, ``vs`` (relative motion at a sample)."""

    z0: np.ndarray
    lam: np.ndarray
    mc: np.ndarray
    xq0: np.ndarray
    xrate: np.ndarray
    x0: np.ndarray
    f0: np.ndarray
    kk: np.ndarray
    nu: np.ndarray
    fn: np.ndarray
    gms: np.ndarray
    ez: np.ndarray
    xs: np.ndarray
    vs: np.ndarray


@njit(cache=CACHE)
def _stick_check(t, an):
    """Relative motion of both contacts at t [s] on the all-stick analytic solution
    (into an.xs [m], an.vs [m/s]) and the GMS breakaway test of the stuck elements there.

    Returns (event, g): event as the ladder's test (|F_i| ≥ ν_i|s(ẋ)| while loading); g
    [N] = min over elements of ν_i|s(ẋ)| − |F_i| (the event function)."""
    z0, lam, mc, xq0, xrate, x0, f0 = an.z0, an.lam, an.mc, an.xq0, an.xrate, an.x0, an.f0
    kk, nu, fn, gms, ez, xs, vs = an.kk, an.nu, an.fn, an.gms, an.ez, an.xs, an.vs
    _modal_at(t, z0, lam, ez)
    ne = f0.shape[1]
    event = False
    g = math.inf
    for k in range(2):
        sx = 0.0
        sv = 0.0
        for j in range(ez.shape[0]):
            c = mc[k, j] * ez[j]
            sx += c.real
            sv += (c * lam[j]).real
        xs[k] = xq0[k] + xrate[k] * t + sx
        vs[k] = xrate[k] + sv
        s1 = stribeck_magnitude(vs[k], fn[k], gms[GMS_MU_S], gms[GMS_MU_C], gms[GMS_V_S],
                                gms[GMS_DELTA])  # fmt: skip
        for i in range(ne):
            fi = f0[k, i] + kk[i] * (xs[k] - x0[k])
            gi = nu[i] * s1 - abs(fi)
            if gi < g:
                g = gi
            if gi <= 0.0 and fi * vs[k] > 0.0:
                event = True
    return event, g


@njit(cache=CACHE)
def _fast_modes(k, an, k_max, m_now):
    """(ω of the fastest mode that could break contact k on its own [rad/s] — 0 when none,
    the summed force amplitude of the faster ones [N]): the fastest modes whose summed
    force amplitude k_max Σ 2|c_kj z_j| stays below half the present margin are skipped."""
    lam, mc, ez = an.lam, an.mc, an.ez
    nm = ez.shape[0]
    budget = 0.5 * max(m_now, 0.0)
    used = 0.0
    om_prev = math.inf
    while True:
        om_j = -1.0
        a_j = 0.0
        for j in range(nm):
            w = abs(lam[j])
            if w < om_prev and w > om_j:
                om_j = w
        if om_j <= 0.0:
            break
        for j in range(nm):
            if abs(lam[j]) == om_j:
                a_j += abs(mc[k, j] * ez[j])
        used += k_max * a_j
        if used > budget:
            return om_j, used
        om_prev = om_j
    return 0.0, used


@njit(cache=CACHE)
def _certified(t, an):
    """(horizon [s], sampling ω [rad/s], drift time [s]) from t on the all-stick solution.

    The horizon is event-free by a bound: with the ring r_k(t) = x_k − x_p,k (modal
    part, |r_k| ≤ R_k = Σ_j|c_kj z_j| for stable modes), |F_i(t+τ)| ≤ |F_i(t) − k_i r_k(t)|
    + k_i(R_k + |ẋ_p,k|τ) must stay below ν_i min(|s(0)|, |s(v_max)|), v_max = |ẋ_p,k| +
    Σ_j|c_kj λ_j z_j|. Beyond it the event function is sampled: the fastest modes whose
    summed force amplitude k_max Σ 2|c_kj z_j| stays below half the smallest present margin
    m = min_i ν_i|s(ẋ)| − |F_i| cannot cause a transition alone, so the samples resolve
    the fastest remaining mode (ω; 0 when none remains) — and the drift time m/(k_max|ẋ_p|)
    [s] bounds how far a sample may go when none rings."""
    z0, lam, mc, xq0, xrate, x0, f0 = an.z0, an.lam, an.mc, an.xq0, an.xrate, an.x0, an.f0
    kk, nu, fn, gms, ez = an.kk, an.nu, an.fn, an.gms, an.ez
    mu_s, mu_c, v_s, delta = gms[GMS_MU_S], gms[GMS_MU_C], gms[GMS_V_S], gms[GMS_DELTA]
    _modal_at(t, z0, lam, ez)
    ne = f0.shape[1]
    nm = ez.shape[0]
    horizon = math.inf
    om_fast = 0.0
    drift = math.inf
    k_max = 0.0
    for i in range(ne):
        k_max = max(k_max, kk[i])
    for k in range(2):
        ring = 0.0
        ring_v = 0.0
        amp = 0.0
        vamp = 0.0
        for j in range(nm):
            c = mc[k, j] * ez[j]
            ring += c.real
            ring_v += (c * lam[j]).real
            amp += abs(c)
            vamp += abs(c) * abs(lam[j])
        x = xq0[k] + xrate[k] * t + ring
        v = xrate[k] + ring_v
        s0 = stribeck_magnitude(0.0, fn[k], mu_s, mu_c, v_s, delta)
        s_hi = stribeck_magnitude(abs(xrate[k]) + vamp, fn[k], mu_s, mu_c, v_s, delta)
        s_now = stribeck_magnitude(v, fn[k], mu_s, mu_c, v_s, delta)
        s_lo = min(s0, s_hi)
        m_now = math.inf
        for i in range(ne):
            fi = f0[k, i] + kk[i] * (x - x0[k])
            m_now = min(m_now, nu[i] * s_now - abs(fi))
            margin = nu[i] * s_lo - abs(fi - kk[i] * ring) - kk[i] * amp
            if margin <= 0.0:
                horizon = 0.0
            rate = kk[i] * abs(xrate[k])
            if rate > 0.0 and margin > 0.0 and margin / rate < horizon:
                horizon = margin / rate
        # modes from the fastest down: skip those whose summed amplitude stays small
        om_k, used = _fast_modes(k, an, k_max, m_now)
        om_fast = max(om_fast, om_k)
        budget = 0.5 * max(m_now, 0.0)
        if k_max * abs(xrate[k]) > 0.0:
            drift = min(drift, (max(m_now, 0.0) - min(used, budget)) / (k_max * abs(xrate[k])))
    return horizon, om_fast, drift


@njit(cache=CACHE)
def _finite(volt, yb):
    """Whether the amplifier output and every state of one turntable are finite."""
    chk = volt
    for j in range(yb.shape[0]):
        chk += yb[j]
    return math.isfinite(chk)


@njit(cache=CACHE)
def _modal_y(t, z0, vmat, lam, yp0, yp1, ez, out):
    """State at t [s] on the all-stick analytic solution: y_p(t) + Re Σ_j v_j z_j e^{λ_j t}."""
    _modal_at(t, z0, lam, ez)
    for a in range(out.shape[0]):
        s = yp0[a] + yp1[a] * t
        for j in range(ez.shape[0]):
            s += (vmat[a, j] * ez[j]).real
        out[a] = s


@njit(cache=CACHE)
def _write_record(row, t, yv, volt, mech, f0, kk, x0, ne):
    """One record (fields :data:`REC_FIELDS`) of an all-stick state yv at t [s]."""
    row[0] = t
    row[1] = yv[0]
    row[2] = yv[1]
    row[3] = volt
    for k in range(2):
        x, _xd = _rel(yv, mech, k)
        row[4 + k] = yv[2 + 2 * k]
        row[6 + k] = x
        fk = 0.0
        for i in range(ne):
            fk += f0[k, i] + kk[i] * (x - x0[k])
        row[8 + k] = fk
        row[10 + k] = ne


@njit(cache=CACHE)
def _locate(lo, hi, g_lo, g_hi, h_min, an):
    """First grid offset in (lo, hi] with a breakaway (none at lo, one at hi): the Illinois
    method on the event function g, bisection where its signs do not bracket."""
    side = 0
    while hi - lo > 1:
        if g_lo > 0.0 and g_hi < 0.0:
            m = lo + int((hi - lo) * (g_lo / (g_lo - g_hi)))
            m = min(hi - 1, max(lo + 1, m))
        else:
            m = (lo + hi) // 2
        ev, g = _stick_check(m * h_min, an)
        if ev:
            hi = m
            g_hi = g
            if side == -1:
                g_lo *= 0.5
            side = -1
        else:
            lo = m
            g_lo = g
            if side == 1:
                g_hi *= 0.5
            side = 1
    return hi


@njit(cache=CACHE, parallel=True)
def run_reduced_batch(state, model, drive, h_min, recording):
    """Advance every turntable b of the batch from grid time state.n[b] to recording.n_end[b].

    Args (:mod:`turntable_env.kernel_types`):
        state: :class:`~turntable_env.kernel_types.ReducedState`, modified in place:
            y[b] = (θ, θ̇, u1, u̇1, u2, u̇2) [rad, rad/s, m, m/s]; volt[b] amplifier output
            [V]; f[b, k, i] GMS element forces [N]; st[b, k, i] 1 stick / 0 slip; n[b] grid
            time.
        model: :class:`~turntable_env.kernel_types.ReducedArrays` of the N turntables.
        drive: :class:`~turntable_env.kernel_types.DriveArrays`, breakpoints in grid units.
        h_min: the grid [s].
        recording: :class:`~turntable_env.kernel_types.ReducedRecording`: records every
            ``out_every`` grid units into rec[b, i] (fields :data:`REC_FIELDS`), n_rec[b]
            counts them; counters[b] = (accepted steps, rejected steps, status, evaluations
            of the analytic solution). Status 0 ok, 1 non-finite state.
    """
    for b in prange(state.y.shape[0]):
        _run_one(b, state, model, drive, h_min, recording)


@njit(cache=CACHE)
def run_reduced_serial(state, model, drive, h_min, recording):
    """:func:`run_reduced_batch` on one thread (a batch of one: no thread launch)."""
    for b in range(state.y.shape[0]):
        _run_one(b, state, model, drive, h_min, recording)


class _Row(NamedTuple):
    """Turntable b's model (views of :class:`~turntable_env.kernel_types.ReducedArrays`'
    rows) and the constants the integrator derives from it."""

    mech: np.ndarray
    gms: np.ndarray
    nu: np.ndarray
    kk: np.ndarray
    amp: np.ndarray
    lvl: np.ndarray
    nlvl: np.ndarray
    phi_small: np.ndarray
    gam_small: np.ndarray
    phi_big: np.ndarray
    gam_big: np.ndarray
    qs: np.ndarray
    modal_w: np.ndarray
    modal_c: np.ndarray
    modal_om: np.ndarray
    q2: np.ndarray
    modal_v: np.ndarray
    modal_lam: np.ndarray
    modal_om_max: float
    ring_frac: float
    use_modal: bool
    gain: float
    tau: float
    ideal: bool
    ulim: float
    rate: float
    a_fast: float
    r_fast: int  # largest rung short against the amplifier's fast path (τ_f/8)
    r_tau: int  # largest rung short against the amplifier's lag (τ/8)
    quiet_len: float
    r_slip: int
    mu_s: float
    h_min: float
    r_big: int
    ne: int


class _Work(NamedTuple):
    """Scratch of one turntable's integration (allocated once per call): the state, forces
    and amplifier saved for a rejected step; the new stick flags; the deviation from the
    quasi-static state; relative displacement and velocity at the step start [m, m/s]; the
    constant force inputs [N]; the Stribeck level at the step's end and start [N]; the
    analytic step's particular solution and rate, modal amplitudes and terms, state; the
    particular relative displacement and rate; relative motion at a sample; normal forces."""

    y0: np.ndarray
    f0: np.ndarray
    st_new: np.ndarray
    dev: np.ndarray
    x0: np.ndarray
    xd0: np.ndarray
    fin: np.ndarray
    s_end: np.ndarray
    s_start: np.ndarray
    yp0: np.ndarray
    yp1: np.ndarray
    z0: np.ndarray
    ez: np.ndarray
    yv: np.ndarray
    xq0: np.ndarray
    xrate: np.ndarray
    xs: np.ndarray
    vs: np.ndarray
    fnk: np.ndarray


@njit(cache=CACHE)
def _row(model, b, h_min, ne):
    """Turntable b's :class:`_Row`."""
    amp = model.amp[b]
    r_fast = 0
    while (1 << (r_fast + 1)) * h_min <= amp[AMP_T_FAST] / 8.0:
        r_fast += 1
    r_tau = 0
    while (1 << (r_tau + 1)) * h_min <= amp[AMP_TAU] / 8.0:
        r_tau += 1
    return _Row(
        model.mech[b], model.gms[b], model.nu[b], model.kk[b], amp, model.lvl[b],
        model.nlvl[b], model.phi_small[b], model.gam_small[b], model.phi_big[b],
        model.gam_big[b], model.qs[b], model.modal_w[b], model.modal_c[b], model.modal_om[b],
        model.q2[b], model.modal_v[b], model.modal_lam[b], model.modal_om_max[b],
        model.ring_frac, model.use_modal, amp[AMP_GAIN], amp[AMP_TAU], amp[AMP_IDEAL] > 0.5,
        amp[AMP_LIMIT], amp[AMP_RATE], amp[AMP_FAST], r_fast, r_tau, model.ctl[b, 0],
        int(model.ctl[b, 1]), model.gms[b, GMS_MU_S], h_min, model.phi_big.shape[1],
        ne,
    )  # fmt: skip


@njit(cache=CACHE)
def _work(ne):
    """A zero-cost :class:`_Work` (np.empty)."""
    return _Work(
        np.empty(6), np.empty((2, ne)), np.empty((2, ne), dtype=np.int64), np.empty(6),
        np.empty(2), np.empty(2), np.empty(2), np.empty(2), np.empty(2), np.empty(6),
        np.empty(6), np.empty(6, dtype=np.complex128), np.empty(6, dtype=np.complex128),
        np.empty(6), np.empty(2), np.empty(2), np.empty(2), np.empty(2), np.empty(2),
    )  # fmt: skip


@njit(cache=CACHE)
def _record(state, b, r, recording, n):
    """Record the present state at grid time n when it falls on the output grid."""
    y, f, st, rec = state.y, state.f, state.st, recording.rec
    n_rec = recording.n_rec
    if n % recording.out_every[b] == 0 and n_rec[b] < rec.shape[1]:
        row = rec[b, n_rec[b]]
        row[0] = n * r.h_min
        row[1] = y[b, 0]
        row[2] = y[b, 1]
        row[3] = state.volt[b]
        for k in range(2):
            x, _xd = _rel(y[b], r.mech, k)
            row[4 + k] = y[b, 2 + 2 * k]
            row[6 + k] = x
            fk = 0.0
            ns = 0
            for i in range(r.ne):
                fk += f[b, k, i]
                ns += st[b, k, i]
            row[8 + k] = fk
            row[10 + k] = ns
        n_rec[b] += 1


@njit(cache=CACHE)
def _landing_rung(b, r, drive, recording, idx, n):
    """The largest rung that does not pass the step's landing point: the end, the next
    output time or the next drive breakpoint."""
    wg, wn, out_every = drive.times, drive.count, recording.out_every
    target = recording.n_end[b]
    nxt_out = (n // out_every[b] + 1) * out_every[b]
    if nxt_out < target:
        target = nxt_out
    if idx + 1 < wn[b] and wg[b, idx + 1] < target:
        target = wg[b, idx + 1]
    span = target - n
    r_land = 0
    while r_land + 1 < r.r_big and (1 << (r_land + 1)) <= span:
        r_land += 1
    return r_land


@njit(cache=CACHE)
def _force_inputs(state, b, r, w):
    """Relative motion at the step start and the constant force inputs over the step (both
    contacts): the stuck elements' offsets F_i − k_i x and the slipping elements' forces
    [N]; returns whether any element slips."""
    y, f, st, kk = state.y, state.f, state.st, r.kk
    any_slip = False
    for k in range(2):
        for i in range(r.ne):
            if st[b, k, i] == 0:
                any_slip = True
    for k in range(2):
        w.x0[k], w.xd0[k] = _rel(y[b], r.mech, k)
        w.fin[k] = 0.0
        for i in range(r.ne):
            w.fin[k] += f[b, k, i] - (kk[i] * w.x0[k] if st[b, k, i] == 1 else 0.0)
    return any_slip


@njit(cache=CACHE)
def _event_search(an, m_seg, r):
    """The first grid offset in (0, m_seg] with a breakaway on the analytic solution (-1
    when none): certified horizons, then samples at the resolution the ringing needs, and
    the crossing located by :func:`_locate`; and the evaluations spent."""
    h_min = r.h_min
    n_eval = 0
    m_a = 0
    m_hit = -1
    while m_a < m_seg:
        t_a = m_a * h_min
        hor, om_fast, drift = _certified(t_a, an)
        n_eval += 1
        if t_a + hor >= m_seg * h_min:
            break
        d_s = hor / h_min
        if om_fast > 0.0:  # resolve the ringing mode that could break a contact
            period = 2.0 * math.pi / om_fast / h_min  # grid units
            d_s = max(d_s, SAMPLE_FRACTION * r.ring_frac * period)
        else:  # nothing rings enough: the drift decides
            d_s = max(d_s, min(drift / h_min, float(m_seg)))
        m_b = m_a + max(1, int(min(d_s, m_seg)))
        if m_b > m_seg:
            m_b = m_seg
        ev, g_b = _stick_check(m_b * h_min, an)
        n_eval += 1
        if ev:
            _e, g_a = _stick_check(t_a, an)
            m_hit = _locate(m_a, m_b, g_a, g_b, h_min, an)
            break
        m_a = m_b
    return m_hit, n_eval


@njit(cache=CACHE)
def _analytic_prepare(state, b, r, w, v0, vsl):
    """The analytic step's particular solution y_p(t) = Q (V0 + V̇t, f1, f2) + q2 V̇ and
    its rate, the modal amplitudes z = W(y − y_p), the contacts' particular relative
    motion, normal forces and element forces at the start: its :class:`_Analytic`."""
    y, f, qs, q2, modal_w = state.y, state.f, r.qs, r.q2, r.modal_w
    for a in range(6):
        w.yp0[a] = (
            qs[a, 0] * v0 + qs[a, 1] * w.fin[0] + qs[a, 2] * w.fin[1] + q2[a] * vsl
        )  # fmt: skip
        w.yp1[a] = qs[a, 0] * vsl
    for j in range(6):
        zj = 0.0j
        for c in range(6):
            zj += modal_w[j, c] * (y[b, c] - w.yp0[c])
        w.z0[j] = zj
    for k in range(2):
        rho = r.mech[2 + k]
        w.xq0[k] = w.yp0[2 + 2 * k] - rho * w.yp0[0]
        w.xrate[k] = w.yp1[2 + 2 * k] - rho * w.yp1[0]
        w.fnk[k] = r.mech[12 + k]
        for i in range(r.ne):
            w.f0[k, i] = f[b, k, i]
    return _Analytic(w.z0, r.modal_lam, r.modal_c, w.xq0, w.xrate, w.x0, w.f0, r.kk, r.nu,
                     w.fnk, r.gms, w.ez, w.xs, w.vs)  # fmt: skip


@njit(cache=CACHE)
def _analytic_outputs(b, r, w, an, recording, n, m_step, v0, vsl):
    """The records inside an analytic step, evaluated on the solution."""
    out_every, n_rec, rec = recording.out_every, recording.n_rec, recording.rec
    n_o = (n // out_every[b] + 1) * out_every[b]
    while n_o < n + m_step and n_rec[b] < rec.shape[1]:
        t_o = (n_o - n) * r.h_min
        _modal_y(t_o, an.z0, r.modal_v, an.lam, w.yp0, w.yp1, an.ez, w.yv)
        _write_record(rec[b, n_rec[b]], n_o * r.h_min, w.yv, v0 + vsl * t_o, r.mech, an.f0,
                      r.kk, w.x0, r.ne)  # fmt: skip
        n_rec[b] += 1
        n_o += out_every[b]


@njit(cache=CACHE)
def _analytic_end(state, b, r, w, an, t_e, volt_end):
    """State at the analytic step's end t_e [s]: the solution there, the amplifier's output
    ``volt_end`` (V, vslow, vfast), the elements' forces and a breakaway's cap."""
    y, f, st, kk, nu, gms = state.y, state.f, state.st, r.kk, r.nu, r.gms
    _modal_y(t_e, an.z0, r.modal_v, an.lam, w.yp0, w.yp1, an.ez, w.yv)
    state.volt[b], state.vslow[b], state.vfast[b] = volt_end
    for j in range(6):
        y[b, j] = w.yv[j]
    for k in range(2):
        x1, xd1 = _rel(y[b], r.mech, k)
        s1 = stribeck_magnitude(xd1, w.fnk[k], r.mu_s, gms[GMS_MU_C], gms[GMS_V_S],
                                gms[GMS_DELTA])  # fmt: skip
        for i in range(r.ne):
            fi = w.f0[k, i] + kk[i] * (x1 - w.x0[k])
            if abs(fi) >= nu[i] * s1 and fi * xd1 > 0.0:
                st[b, k, i] = 0  # broke away: no overshoot past capacity
                capf = nu[i] * s1
                fi = capf if fi > 0.0 else -capf
            f[b, k, i] = fi


@njit(cache=CACHE)
def _analytic_step(state, b, r, w, drive, recording, idx, n):
    """One all-stick analytic step to the next breakpoint, the end or the first breakaway,
    when the amplifier stays linear over it: (grid units stepped, the breakaway's offset or
    -1, analytic evaluations); (-1, -1, 0) when it does not apply."""
    wg, wv, wn = drive.times, drive.values, drive.count
    h_min, ulim, gain, ideal = r.h_min, r.ulim, r.gain, r.ideal
    seg = recording.n_end[b]
    if idx + 1 < wn[b] and wg[b, idx + 1] < seg:
        seg = wg[b, idx + 1]
    m_seg = seg - n
    u0r = _input_at(wg[b], wv[b], wn[b], idx, n)
    u1r = _input_at(wg[b], wv[b], wn[b], idx, seg)
    u0 = min(ulim, max(-ulim, u0r))
    u1 = min(ulim, max(-ulim, u1r))
    inside = abs(u0r) <= ulim and abs(u1r) <= ulim
    slope = (u1 - u0) / (m_seg * h_min)
    volt, vslow, vfast = state.volt, state.vslow, state.vfast
    if not ((inside or u0 == u1) and _amp_linear(
        volt[b], vslow[b], vfast[b], u0, slope, r.amp, ideal
    )):  # fmt: skip
        return -1, -1, 0
    v0 = gain * u0 if ideal else volt[b]  # V (ideal: right after a jump)
    vsl = gain * slope  # V/s, the output's slope
    an = _analytic_prepare(state, b, r, w, v0, vsl)
    m_hit, n_eval = _event_search(an, m_seg, r)
    m_step = m_hit if m_hit > 0 else m_seg
    _analytic_outputs(b, r, w, an, recording, n, m_step, v0, vsl)
    t_e = m_step * h_min
    u_e = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], idx, n + m_step)))
    if ideal:
        volt_end = (gain * u_e, vslow[b], vfast[b])
    else:
        volt_end = amplifier_step(v0, vslow[b], vfast[b], u0, u_e, t_e, r.amp)
    _analytic_end(state, b, r, w, an, t_e, volt_end)
    return m_step, m_hit, n_eval + 1


@njit(cache=CACHE)
def _input_slope(drive, b, idx, h_min):
    """The input's slope over the present drive segment [V/s] (0 on a jump or the last)."""
    wg, wv, wn = drive.times, drive.values, drive.count
    if idx + 1 < wn[b] and wg[b, idx + 1] > wg[b, idx]:
        return (wv[b, idx + 1] - wv[b, idx]) / ((wg[b, idx + 1] - wg[b, idx]) * h_min)
    return 0.0


@njit(cache=CACHE)
def _ringing_rung(state, b, r, w, drive, idx, n):
    """The largest rung the all-stick ringing allows: the fastest mode whose amplitude in
    the contacts' relative motion exceeds the quiet length (modal amplitudes of the
    deviation from the quasi-static state y_qs = −A⁻¹(b_V V + B_f f)), or the fastest mode
    while the amplifier slews; a large rung when nothing rings."""
    y, volt, qs, modal_w, modal_c = state.y, state.volt, r.qs, r.modal_w, r.modal_c
    for j in range(6):
        w.dev[j] = y[b, j] - (qs[j, 0] * volt[b] + qs[j, 1] * w.fin[0] + qs[j, 2] * w.fin[1])
    om_fast = 0.0
    for j in range(6):
        zj = 0.0j
        for c in range(6):
            zj += modal_w[j, c] * w.dev[c]
        for k in range(2):
            if abs(modal_c[k, j] * zj) > r.quiet_len and r.modal_om[j] > om_fast:
                om_fast = r.modal_om[j]
    if not r.ideal:
        u_now = min(r.ulim, max(-r.ulim, _input_at(drive.times[b], drive.values[b],
                                                   drive.count[b], idx, n)))  # fmt: skip
        if abs(r.gain * u_now - volt[b]) > r.rate * r.tau:
            om_fast = max(om_fast, r.modal_om_max)
    r_dyn = 1 << 30
    if om_fast > 0.0:
        r_dyn = 0
        lim = r.ring_frac * 2.0 * math.pi / om_fast / r.h_min
        while (1 << (r_dyn + 1)) <= lim:
            r_dyn += 1
    return r_dyn


@njit(cache=CACHE)
def _rung_cap(state, b, r, w, drive, idx, n, r_land, any_slip):
    """The largest rung of the next ladder step: the landing point's, ``r_slip`` while an
    element slips or the ringing's while all stick, and short steps while the amplifier's
    fast path or its first-order lag settles (V is held linear over a step)."""
    volt, vslow, vfast = state.volt, state.vslow, state.vfast
    cap = r_land
    if any_slip:
        cap = min(cap, r.r_slip)
    else:
        cap = min(cap, _ringing_rung(state, b, r, w, drive, idx, n))
    if r.a_fast > 0.0 and not r.ideal:  # the fast path settling: short steps
        u_now = min(r.ulim, max(-r.ulim, _input_at(drive.times[b], drive.values[b],
                                                   drive.count[b], idx, n)))  # fmt: skip
        slope = _input_slope(drive, b, idx, r.h_min)  # the path lags it
        steady = r.a_fast * r.gain * (u_now - slope * r.amp[AMP_T_FAST])
        if abs(vfast[b] - steady) > FAST_QUIET:
            cap = min(cap, r.r_fast)
    if not r.ideal:  # the first-order lag settling: short steps (V is held linear)
        u_now = min(r.ulim, max(-r.ulim, _input_at(drive.times[b], drive.values[b],
                                                   drive.count[b], idx, n)))  # fmt: skip
        slope = _input_slope(drive, b, idx, r.h_min)
        if not _amp_linear(volt[b], vslow[b], vfast[b], u_now, slope, r.amp, r.ideal):
            cap = min(cap, r.r_tau)
    return cap


@njit(cache=CACHE)
def _propagate(state, b, r, w, rung, cfg, all_stick, v0e, vslope):
    """y(t+h) = Φ_c(h) y(t) + Γ_c(h) [V(t), V̇, f_1, f_2] from the saved start state."""
    if all_stick:  # every rung of the all-stick configuration
        ph = r.phi_big[rung]
        gm = r.gam_big[rung]
    else:  # partial slip: rung ≤ r_slip
        ph = r.phi_small[cfg, rung]
        gm = r.gam_small[cfg, rung]
    y, y0, fin = state.y, w.y0, w.fin
    for a in range(6):
        s = gm[a, 0] * v0e + gm[a, 1] * vslope + gm[a, 2] * fin[0] + gm[a, 3] * fin[1]
        for c in range(6):
            s += ph[a, c] * y0[c]
        y[b, a] = s


@njit(cache=CACHE)
def _elements(state, b, r, w, h):
    """The GMS elements of both contacts over the step just propagated (Eq. 2.24–2.25,
    :func:`~turntable_env.friction.kernels.gms_element_step`) and their transitions into
    ``w.st_new``: (any transition, the earliest crossing's fraction of the step by linear
    interpolation of the event function)."""
    y, f, st, gms, kk, nu = state.y, state.f, state.st, r.gms, r.kk, r.nu
    mu_s, mu_c, v_s, delta = r.mu_s, gms[GMS_MU_C], gms[GMS_V_S], gms[GMS_DELTA]
    event = False
    frac = 1.0
    for k in range(2):
        x1, xd1 = _rel(y[b], r.mech, k)
        dx = x1 - w.x0[k]
        vbar = 0.5 * (w.xd0[k] + xd1)
        fn_k = r.mech[12 + k]
        sbar = stribeck_magnitude(vbar, fn_k, mu_s, mu_c, v_s, delta)
        s1 = stribeck_magnitude(xd1, fn_k, mu_s, mu_c, v_s, delta)
        w.s_end[k] = s1
        decay = math.exp(-gms[GMS_C] * h / sbar)  # slipping elements' relaxation
        sg = 1.0 if vbar > 0.0 else (-1.0 if vbar < 0.0 else 0.0)
        for i in range(r.ne):
            fi = gms_element_step(w.f0[k, i], st[b, k, i], kk[i], dx, nu[i] * sbar * sg, decay)
            f[b, k, i] = fi
            # transitions (as the 1-D GMS kernel)
            if st[b, k, i] == 1:
                if abs(fi) >= nu[i] * s1 and fi * xd1 > 0.0:
                    w.st_new[k, i] = 0
                    event = True
                    g0 = nu[i] * w.s_start[k] - abs(w.f0[k, i])
                    g1 = nu[i] * s1 - abs(fi)
                else:
                    w.st_new[k, i] = 1
                    continue
            else:
                if fi * xd1 <= 0.0:
                    w.st_new[k, i] = 1
                    event = True
                    g0 = w.f0[k, i] * w.xd0[k]
                    g1 = fi * xd1
                else:
                    w.st_new[k, i] = 0
                    continue
            if g0 > 0.0 and g1 < g0:
                frac = min(frac, g0 / (g0 - g1))
            else:
                frac = 0.0
    return event, frac


@njit(cache=CACHE)
def _accept(state, b, r, w, v1, vs1, vf1):
    """Take the step: the amplifier's new output, the transitions (a breakaway capped at
    its capacity: no overshoot past it)."""
    f, st = state.f, state.st
    state.volt[b] = v1
    state.vslow[b] = vs1
    state.vfast[b] = vf1
    for k in range(2):
        for i in range(r.ne):
            if st[b, k, i] == 1 and w.st_new[k, i] == 0:
                capf = r.nu[i] * w.s_end[k]
                if abs(f[b, k, i]) > capf:
                    f[b, k, i] = capf if f[b, k, i] > 0.0 else -capf
            st[b, k, i] = w.st_new[k, i]


@njit(cache=CACHE)
def _ladder_step(state, b, r, w, drive, idx, n, rung, any_slip):
    """One accepted ladder step from grid time n at rung ``rung`` or below (a step whose
    end shows a transition is retried below the interpolated crossing): (new n, rung after
    it, steps rejected on the way)."""
    wg, wv, wn = drive.times, drive.values, drive.count
    y, f, st = state.y, state.f, state.st
    ulim, gain, ideal, h_min = r.ulim, r.gain, r.ideal, r.h_min
    # configuration: stuck stiffness level of each contact
    m0 = 0
    m1 = 0
    for i in range(r.ne):
        m0 |= st[b, 0, i] << i
        m1 |= st[b, 1, i] << i
    cfg = r.lvl[0, m0] * r.nlvl[1] + r.lvl[1, m1]
    all_stick = not any_slip
    # save for a rejected step
    for j in range(6):
        w.y0[j] = y[b, j]
    for k in range(2):
        for i in range(r.ne):
            w.f0[k, i] = f[b, k, i]
    v0 = state.volt[b]
    vs0 = state.vslow[b]
    vf0 = state.vfast[b]
    vs1 = vs0
    vf1 = vf0
    u0 = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], idx, n)))
    for k in range(2):  # Stribeck level at the step start [N] (event interpolation)
        w.s_start[k] = stribeck_magnitude(w.xd0[k], r.mech[12 + k], r.mu_s, r.gms[GMS_MU_C],
                                          r.gms[GMS_V_S], r.gms[GMS_DELTA])  # fmt: skip
    n_rej = 0
    while True:
        dn = 1 << rung
        h = dn * h_min
        n1 = n + dn
        # amplifier
        i1 = _advance(wg[b], wn[b], idx, n1 - 1)  # same segment (steps never cross)
        u1 = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], i1, n1)))
        if ideal:
            v1 = gain * u1
            v0e = gain * u0
        else:
            v1, vs1, vf1 = amplifier_step(v0, vs0, vf0, u0, u1, h, r.amp)
            v0e = v0
        vslope = (v1 - v0e) / h
        _propagate(state, b, r, w, rung, cfg, all_stick, v0e, vslope)
        event, frac = _elements(state, b, r, w, h)
        if event and rung > 0:
            # retry below the interpolated crossing (regula falsi on the ladder)
            r_new = rung - 1
            while r_new > 0 and (1 << r_new) > frac * dn:
                r_new -= 1
            rung = r_new
            n_rej += 1
            continue
        _accept(state, b, r, w, v1, vs1, vf1)
        return n1, rung if event else rung + 1, n_rej


@njit(cache=CACHE)
def _run_one(b, state, model, drive, h_min, recording):
    """Turntable b of :func:`run_reduced_batch`: record, then one step — the analytic one
    while every element sticks and the amplifier is linear, else a ladder step — until
    the end."""
    r = _row(model, b, h_min, state.f.shape[2])
    w = _work(r.ne)
    n = state.n[b]
    idx = _advance(drive.times[b], drive.count[b], 0, n)
    rung = 0
    n_acc = 0
    n_rej = 0
    n_eval = 0
    status = 0
    while True:
        _record(state, b, r, recording, n)
        if n >= recording.n_end[b]:
            break
        r_land = _landing_rung(b, r, drive, recording, idx, n)
        any_slip = _force_inputs(state, b, r, w)
        if not any_slip and r.use_modal:  # all stuck, amplifier linear: one analytic step
            m_step, m_hit, evals = _analytic_step(state, b, r, w, drive, recording, idx, n)
            n_eval += evals
            if m_step >= 0:
                n += m_step
                idx = _advance(drive.times[b], drive.count[b], idx, n)
                n_acc += 1
                if m_hit > 0:
                    rung = 0
                if not _finite(state.volt[b], state.y[b]):
                    status = 1
                    break
                continue
        cap = _rung_cap(state, b, r, w, drive, idx, n, r_land, any_slip)
        if rung > cap:
            rung = cap
        n, rung, rej = _ladder_step(state, b, r, w, drive, idx, n, rung, any_slip)
        idx = _advance(drive.times[b], drive.count[b], idx, n)
        n_acc += 1
        n_rej += rej
        if not _finite(state.volt[b], state.y[b]):
            status = 1
            break
    state.n[b] = n
    recording.counters[b, 0] += n_acc
    recording.counters[b, 1] += n_rej
    recording.counters[b, 2] = status
    recording.counters[b, 3] += n_eval
