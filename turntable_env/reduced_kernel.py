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
  mode's period while all stick, and lands on breakpoints and output times (a landing on
  an output time shortens only its own step, and the rung resumes after it, unless
  ``ReducedModel(resume_rung=False)``: then the landing caps the rung too; a breakpoint,
  where the input's slope changes, always caps it).

With the sphere's translation (:class:`~turntable_env.reduced.TranslationParameters`,
the ``"translation"`` fidelity) the state has 48 entries (the table's angle, the driving
contact points, the sphere's translation and tilts, and the three tube tops' twists,
each with its rate), each driving contact's GMS elements are 2-vectors in its plane (the
driving direction and the axis n, the 2-D law of §3.3.2: constant force inputs along n
beside the driving direction's, slipping toward the mean sliding direction, breaking
away on the vector's magnitude, :func:`_elements_moved`), each contact's slip is a row
over the state and its normal force F_N + k_H(approach) + d_c(its rate) a row over (y,
V, V̇) that sets its Stribeck level at a step's ends and, for the slipping elements, its
mean; where it falls under a sticking
element's load the element is held at its share ν_i|s(v)| at the step's end (the 3-D
model's rule, :mod:`turntable_env.integrator`); the ladder is unchanged and the
analytic all-stick step is not used. Each turntable runs an integrator compiled for its
form (:func:`run_reduced_batch`).

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

import numpy as np
from numba import literally, njit, prange

from .amplifier import amplifier_step, amplifier_step_decayed
from .friction.kernels import gms_element_step, gms_element_step2, stribeck_magnitude
from .integrator import advance_index as _advance
from .integrator import pwl_value as _input_at
from .kernel_cache import CACHE

__all__ = ["N_REC", "REC_FIELDS", "form_counts", "run_reduced_batch", "run_reduced_serial"]

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

N_TRANSLATION = 48  # states of the translation form: 24 coordinates and their rates

# packed rows: see turntable_env.kernel_types.ReducedArrays
FAST_QUIET = 1e-3  # V: an amplifier fast-path transient above it keeps steps short
# samples of the all-stick event function per ladder ring step (ring_frac of a period):
# 1/4 → 1/16 of the ringing mode's period, so a sampled peak is ≥ cos(11.25°) = 98 % of it
SAMPLE_FRACTION = 0.25
# the ringing cap's fraction of a period where the sphere translates, over ring_frac: the
# balls' axial ringing moves the normal forces, and with them the breakaway capacity
# ν_iμ_sF_N that each step's end checks: a quarter period misses its dips (turntable
# bench's reduced_translation_step_error, docs/performance.md stop 67)
MOVED_RING_FACTOR = 0.25
# the translation form's dot products over its 48 states may be summed in any order (the
# per-axis form's 6-state sums stay in theirs, bit for bit): a vectorised sum, not a chain
DOT_FLAGS = {"reassoc", "contract"}


@njit(cache=CACHE)
def _rel(y, mech, k):
    """Relative displacement and velocity (tube contact point − table point) of contact k."""
    rho = mech[2 + k]
    return y[2 + 2 * k] - rho * y[0], y[3 + 2 * k] - rho * y[1]


@njit(cache=CACHE, fastmath=DOT_FLAGS)
def _rel_moved(y, srow, k):
    """:func:`_rel` less e_k·x where the sphere translates: the rows ``srow[k]`` over y."""
    x = 0.0
    xd = 0.0
    for a in range(y.shape[0]):
        x += srow[k, 0, a] * y[a]
        xd += srow[k, 1, a] * y[a]
    return x, xd


@njit(cache=CACHE, fastmath=DOT_FLAGS)
def _normal(y, volt, vdot, fn0, nrow, k, moved):
    """Normal force [N] of contact k: F_N, plus the translation's k_n(x_k − sV) +
    d_c(ẋ_k − sV̇) where the sphere translates (``moved``; rows ``nrow`` over (y, V, V̇),
    V and V̇ in its last two columns), never below 0: a contact that would pull has lost
    its friction (the normal spring itself stays linear: lift-off is not modelled)."""
    if not moved:
        return fn0
    nv = nrow.shape[1] - 2
    d = nrow[k, nv] * volt + nrow[k, nv + 1] * vdot
    for a in range(nv):
        d += nrow[k, a] * y[a]
    return max(fn0 + d, 0.0)


@njit(cache=CACHE)
def _level(v, fn, gms):
    """The Stribeck level |s(v)| [N] (Eq. 2.13–2.14) of a contact whose tube point moves at
    v [m/s] relative to the table, times 1 − α·sgn v for the sliding-direction asymmetry
    α = ``gms[7]`` (``friction_asymmetry``: μ × (1 + α) while the table slides forward
    over the tube, v < 0; at v = 0 the level is symmetric)."""
    s = stribeck_magnitude(v, fn, gms[1], gms[2], gms[3], gms[4])
    a = gms[7]
    if a != 0.0 and v != 0.0:
        s *= 1.0 - a if v > 0.0 else 1.0 + a
    return s


@njit(cache=CACHE)
def _level2(v, vn, fn, gms):
    """:func:`_level` of a translating contact whose tube point moves at (v, vn) [m/s]
    relative to the table, along its driving direction and along the axis n: the
    Stribeck level at the sliding speed |(v, vn)| (the 2-D law, §3.3.2), the asymmetry
    α = ``gms[7]`` weighted by the driving direction's share, 1 − α·v/|(v, vn)| (the
    3-D model's continuous factor, :mod:`turntable_env.integrator`)."""
    speed = math.sqrt(v * v + vn * vn)
    s = stribeck_magnitude(speed, fn, gms[1], gms[2], gms[3], gms[4])
    a = gms[7]
    if a != 0.0 and speed > 0.0:
        s *= 1.0 - a * v / speed
    return s


@njit(cache=CACHE)
def _amp_linear(v0, vs0, vf0, u0, slope, row, ideal):
    """True when the amplifier output [V] is linear in time (to FAST_QUIET) while its input
    ramps from u0 [V] at ``slope`` [V/s]: inside the slew limit and with the first-order
    transients of both paths settled (:func:`~turntable_env.amplifier.ramp_step`'s exact
    branch with e0 ≈ 0)."""
    if ideal:
        return True
    gain, tau, rate, a, tf, to = row[0], row[1], row[4], row[5], row[6], row[7]
    if abs(gain * slope) >= rate:
        return False
    if to != 0.0:  # an output lag: the stage's paths settled, the output τ_o behind them
        gs = (1.0 - a) * gain
        if abs(gs * u0 - vs0) > rate * tau or abs(gs * (u0 - slope * tau) - vs0) > FAST_QUIET:
            return False
        if a != 0.0 and abs(a * gain * (u0 - slope * tf) - vf0) > FAST_QUIET:
            return False
        w_rate = gain * slope  # the paths' sum ramps at G·u̇ once settled
        return abs(vs0 + vf0 - w_rate * to - v0) <= FAST_QUIET
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
def _exceeds(z, q, q2_lo, q2_hi):
    """abs(z) > q for a complex z: decided on |z|² where it is clear by more than rounding
    (q2_lo, q2_hi = q²(1 ∓ 1e-12)), by abs(z) (a hypot) only near the edge or for non-finite
    parts — the same answer as abs(z) > q, without its cost on almost every call."""
    s = z.real * z.real + z.imag * z.imag
    if s > q2_hi:
        return True
    if s < q2_lo:
        return False
    return abs(z) > q


@njit(cache=CACHE)
def _om_key(om):
    """A mode's angular frequency [rad/s] as the ringing cap orders it (NaN below all)."""
    return om if om == om else -1.0


@njit(cache=CACHE)
def _modal_at(t, z0, lam, ez):
    """Modal amplitudes z_j e^{λ_j t} at t [s] from the segment start into ez."""
    for j in range(z0.shape[0]):
        ez[j] = z0[j] * cmath.exp(lam[j] * t)


@njit(cache=CACHE)
def _stick_check(t, z0, lam, mc, xq0, xrate, x0, f0, kk, nu, fn, gms, ez, xs, vs):
    """Relative motion of both contacts at t [s] on the all-stick analytic solution
    (into xs [m], vs [m/s]) and the GMS breakaway test of the stuck elements there.

    Returns (event, g): event as the ladder's test (|F_i| ≥ ν_i|s(ẋ)| while loading); g
    [N] = min over elements of ν_i|s(ẋ)| − |F_i| (the event function)."""
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
        s1 = _level(vs[k], fn[k], gms)
        for i in range(ne):
            fi = f0[k, i] + kk[i] * (xs[k] - x0[k])
            gi = nu[i] * s1 - abs(fi)
            if gi < g:
                g = gi
            if gi <= 0.0 and fi * vs[k] > 0.0:
                event = True
    return event, g


@njit(cache=CACHE)
def _certified(t, z0, lam, mc, xq0, xrate, x0, f0, kk, nu, fn, gms, ez):
    """(horizon [s], sampling ω [rad/s], drift time [s]) from t on the all-stick solution.

    The horizon is event-free by a bound: with the ring r_k(t) = x_k − x_p,k (modal
    part, |r_k| ≤ R_k = Σ_j|c_kj z_j| for stable modes), |F_i(t+τ)| ≤ |F_i(t) − k_i r_k(t)|
    + k_i(R_k + |ẋ_p,k|τ) must stay below ν_i min(|s(0)|, |s(v_max)|), v_max = |ẋ_p,k| +
    Σ_j|c_kj λ_j z_j|. Beyond it the event function is sampled: the fastest modes whose
    summed force amplitude k_max Σ 2|c_kj z_j| stays below half the smallest present margin
    m = min_i ν_i|s(ẋ)| − |F_i| cannot cause a transition alone, so the samples resolve
    the fastest remaining mode (ω; 0 when none remains) — and the drift time m/(k_max|ẋ_p|)
    [s] bounds how far a sample may go when none rings."""
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
        weak = 1.0 - abs(gms[7])  # the asymmetry's weaker direction bounds the capacity
        s0 = weak * stribeck_magnitude(0.0, fn[k], gms[1], gms[2], gms[3], gms[4])
        s_hi = weak * stribeck_magnitude(abs(xrate[k]) + vamp, fn[k], gms[1], gms[2], gms[3],
                                         gms[4])  # fmt: skip
        s_now = _level(v, fn[k], gms)
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
                om_fast = max(om_fast, om_j)
                break
            om_prev = om_j
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
def _locate(lo, hi, g_lo, g_hi, h_min, z0, lam, mc, xq0, xrate, x0, f0, kk, nu, fn, gms,
            ez, xs, vs):  # fmt: skip
    """First grid offset in (lo, hi] with a breakaway (none at lo, one at hi): the Illinois
    method on the event function g, bisection where its signs do not bracket."""
    side = 0
    while hi - lo > 1:
        if g_lo > 0.0 and g_hi < 0.0:
            m = lo + int((hi - lo) * (g_lo / (g_lo - g_hi)))
            m = min(hi - 1, max(lo + 1, m))
        else:
            m = (lo + hi) // 2
        ev, g = _stick_check(m * h_min, z0, lam, mc, xq0, xrate, x0, f0, kk, nu, fn, gms,
                             ez, xs, vs)  # fmt: skip
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


@njit(cache=CACHE)
def _transition(stuck, mag, cap, load, mag0, cap0, load0, frac):
    """One GMS element's transition at a step's end (the 1-D kernel's rules, Eq. 2.24–2.25,
    on the force's magnitude in the plane): a sticking element breaks away where its load
    ``mag`` [N] reaches its share ``cap`` [N] while loading (``load`` = F·v > 0), a
    slipping one sticks again where F·v ≤ 0. Returns (stick flag, event, frac): at an
    event ``frac`` is lowered to the crossing's fraction of the step, interpolated from
    the step start's ``mag0``, ``cap0``, ``load0`` (0 where they do not bracket it)."""
    if stuck == 1:
        if not (mag >= cap and load > 0.0):
            return 1, False, frac
        new, e0, e1 = 0, cap0 - mag0, cap - mag
    else:
        if load > 0.0:
            return 0, False, frac
        new, e0, e1 = 1, load0, load
    if e0 > 0.0 and e1 < e0:
        return new, True, min(frac, e0 / (e0 - e1))
    return new, True, 0.0


@njit(cache=CACHE)
def _elements_moved(b, k, y, y0, v1, v0e, vslope, mech, nrow, srow, gms, nu, kk, f, st, f0,
                    g0, x0, xd0, xn0, xdn0, slip_k, s_start, s_end, st_new, h, ne, event,
                    frac):  # fmt: skip
    """Contact k's GMS elements over a step of the translating form (the 2-D law in the
    contact plane, §3.3.2, :mod:`turntable_env.friction.gms2d`): each element a 2-vector
    along the driving direction (f[b, k]) and along the axis n (f[b, 2 + k]), loaded by
    the slips there, slipping toward ν_i s(|v̄|) v̄/|v̄| at the step's mean sliding
    velocity and normal force, breaking away when its magnitude reaches ν_i|s(|v|)|
    while loading (F·v > 0) and sticking again when F·v ≤ 0; a sticking element above
    its share where F_N fell is held at it (the 3-D model's rule). Writes f[b], st_new
    and s_end[k]; returns (event, frac) updated as the per-axis loop's."""
    x1, xd1 = _rel_moved(y[b], srow[b], k)
    xn1, xdn1 = _rel_moved(y[b], srow[b], 2 + k)
    dx = x1 - x0[k]
    dn = xn1 - xn0[k]
    fn_k = _normal(y[b], v1, vslope, mech[b, 12 + k], nrow[b], k, True)  # at the end [N]
    s1 = _level2(xd1, xdn1, fn_k, gms[b])
    s_end[k] = s1
    tx = 0.0  # the slipping elements' direction × level, and their relaxation
    tn = 0.0
    decay = 0.0
    if slip_k[k]:
        vbar = 0.5 * (xd0[k] + xd1)
        vnbar = 0.5 * (xdn0[k] + xdn1)
        fn_bar = 0.5 * (fn_k + _normal(y0, v0e, vslope, mech[b, 12 + k], nrow[b], k, True))
        sbar = _level2(vbar, vnbar, fn_bar, gms[b])
        # no level (a translating contact unloaded): the elements drop at once
        decay = math.exp(-gms[b, 0] * h / sbar) if sbar > 0.0 else 0.0
        speed = math.sqrt(vbar * vbar + vnbar * vnbar)
        if speed > 0.0:
            tx = sbar * vbar / speed
            tn = sbar * vnbar / speed
    for i in range(ne):
        fi, gi = gms_element_step2(f0[k, i], g0[k, i], st[b, k, i], kk[b, i], dx, dn,
                                   nu[b, i] * tx, nu[b, i] * tn, decay)  # fmt: skip
        f[b, k, i] = fi
        f[b, 2 + k, i] = gi
        mag = math.sqrt(fi * fi + gi * gi)
        cap = nu[b, i] * s1
        st_new[k, i], hit, frac = _transition(
            st[b, k, i], mag, cap, fi * xd1 + gi * xdn1,
            math.sqrt(f0[k, i] ** 2 + g0[k, i] ** 2), nu[b, i] * s_start[k],
            f0[k, i] * xd0[k] + g0[k, i] * xdn0[k], frac,
        )  # fmt: skip
        event = event or hit
        if st_new[k, i] == 1 and st[b, k, i] == 1 and mag > cap:
            r = cap / mag  # F_N fell under its load: held at its share
            f[b, k, i] = fi * r
            f[b, 2 + k, i] = gi * r
    return event, frac


def run_reduced_batch(state, model, drive, h_min, recording, forms=None) -> None:
    """Advance every turntable b of the batch from grid time state.n[b] to recording.n_end[b],
    the batch's turntables in parallel (``numba.prange``).

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
        forms: :func:`form_counts` of ``model.nrow`` where the caller keeps it (an env
            steps through here: no array scan per step); None computes it.

    Each turntable runs the integrator compiled for its form: the per-axis model's 6 states,
    or 48 where its sphere translates (a normal-force row is non-zero). One compiled entry
    per form runs that form's turntables and skips the others, so a batch compiles only the
    forms it holds (numba emits an entry's whole call tree into it: both forms in one entry
    doubled a first step's compile, ``python experiments/first_step_compile.py``); a mixed
    batch runs both entries, each turntable as it runs alone.
    """
    _run_forms(state, model, drive, h_min, recording, True, forms)


def run_reduced_serial(state, model, drive, h_min, recording, forms=None) -> None:
    """:func:`run_reduced_batch` on one thread (a batch of one: no thread launch)."""
    _run_forms(state, model, drive, h_min, recording, False, forms)


def form_counts(nrow: np.ndarray) -> tuple[int, int]:
    """(per-axis, translating) turntables of a batch whose normal-force rows are ``nrow``
    [b, k, :] (a non-zero row: that turntable's sphere translates; :func:`_is_moved`'s rule,
    which the compiled entries apply per turntable)."""
    moved = np.any(nrow != 0.0, axis=(1, 2))
    return int(np.sum(~moved)), int(np.sum(moved))


def _run_forms(state, model, drive, h_min, recording, parallel, forms) -> None:
    """Each form's entry over the batch; in parallel where more than one turntable has that
    form (the others are skipped: a thread launch for one turntable buys nothing)."""
    counts = form_counts(model.nrow) if forms is None else forms
    for form, count in zip((False, True), counts, strict=True):
        if count:
            _ENTRIES[form, parallel and count > 1](state, model, drive, h_min, recording)


@njit(cache=CACHE)
def _is_moved(model, b):
    """Turntable b's sphere translates: a normal-force row of its model is non-zero."""
    for k in range(2):
        for a in range(model.nrow.shape[2]):
            if model.nrow[b, k, a] != 0.0:
                return True
    return False


# the entries of each form: the form is a literal of each _run_one compilation, so the
# per-axis form's code holds no translation (a batch's y may be wider than a turntable's
# states: padded with zeros). prange's index is unsigned: cast, so the serial and parallel
# entries share one int64 compilation (an unsigned b compiled the integrator a second time)
@njit(cache=CACHE, parallel=True)
def _axis_batch(state, model, drive, h_min, recording):
    for b in prange(state.y.shape[0]):
        if not _is_moved(model, np.int64(b)):
            _run_one(np.int64(b), state, model, drive, h_min, recording, False)


@njit(cache=CACHE)
def _axis_serial(state, model, drive, h_min, recording):
    for b in range(state.y.shape[0]):
        if not _is_moved(model, b):
            _run_one(b, state, model, drive, h_min, recording, False)


@njit(cache=CACHE, parallel=True)
def _moved_batch(state, model, drive, h_min, recording):
    for b in prange(state.y.shape[0]):
        if _is_moved(model, np.int64(b)):
            _run_one(np.int64(b), state, model, drive, h_min, recording, True)


@njit(cache=CACHE)
def _moved_serial(state, model, drive, h_min, recording):
    for b in range(state.y.shape[0]):
        if _is_moved(model, b):
            _run_one(b, state, model, drive, h_min, recording, True)


# (translates, in parallel) → the compiled entry
_ENTRIES = {(False, True): _axis_batch, (False, False): _axis_serial,
            (True, True): _moved_batch, (True, False): _moved_serial}  # fmt: skip


@njit(cache=CACHE)
def _ladder(span, r_big):
    """The largest rung r < r_big whose step 2^r grid units fits in ``span`` (≥ 1)."""
    r = 0
    while r + 1 < r_big and (1 << (r + 1)) <= span:
        r += 1
    return r


@njit(cache=CACHE, fastmath=DOT_FLAGS)
def _step_fast(ph, gm, y0, v0e, vslope, fin, gin, yb, ny):
    """The translation form's exact step y = Φ y0 + Γ (V, V̇, f1, f2, g1, g2) into ``yb``
    (the discretised linear system of each stick configuration, as the per-axis loop's,
    its 48-term sums vectorised)."""
    for a in range(ny):
        s = gm[a, 0] * v0e + gm[a, 1] * vslope + gm[a, 2] * fin[0] + gm[a, 3] * fin[1]
        s += gm[a, 4] * gin[0] + gm[a, 5] * gin[1]
        acc = 0.0
        for c in range(ny):
            acc += ph[a, c] * y0[c]
        yb[a] = s + acc


@njit(cache=CACHE, fastmath=DOT_FLAGS)
def _project(w, dev, ny):
    """Modal amplitude w·dev of a real deviation ``dev`` (the translation form's, its
    real and imaginary sums vectorised)."""
    zr = 0.0
    zi = 0.0
    for c in range(ny):
        zr += w[c].real * dev[c]
        zi += w[c].imag * dev[c]
    return complex(zr, zi)


@njit(cache=CACHE)
def _twins(order, lam, w, ny):
    """Flags the modes, in the ringing check's ``order``, that are the conjugate of the
    one before them: eigenvalue conj(λ) exactly and projection row conj(w) to 1e-8 of its
    largest entry. The deviation is real, so their amplitude at the contacts is that
    one's conjugate, the same magnitude, and the check skips them. A degenerate
    eigenvalue's other modes (another row) are not flagged."""
    twin = np.zeros(ny, dtype=np.bool_)
    for jj in range(1, ny):
        i, j = order[jj - 1], order[jj]
        if twin[jj - 1] or lam[i].imag == 0.0 or lam[j] != lam[i].conjugate():
            continue
        big = 0.0
        off = 0.0
        for c in range(ny):
            big = max(big, abs(w[i, c]))
            off = max(off, abs(w[j, c] - w[i, c].conjugate()))
        twin[jj] = off <= 1e-8 * big
    return twin


@njit(cache=CACHE)
def _run_one(b, state, model, drive, h_min, recording, moved):
    """Turntable b of :func:`run_reduced_batch` (``moved``: the form, a literal)."""
    literally(moved)
    y, volt, f, st, n_now = state.y, state.volt, state.f, state.st, state.n
    vslow, vfast = state.vslow, state.vfast
    mech, gms, nu, kk, amp, ctl = model.mech, model.gms, model.nu, model.kk, model.amp, model.ctl
    lvl, nlvl = model.lvl, model.nlvl
    phi_small, gam_small, phi_big, gam_big = (
        model.phi_small, model.gam_small, model.phi_big, model.gam_big
    )  # fmt: skip
    srow, nrow = model.srow, model.nrow
    qs, modal_w, modal_c, modal_om = model.qs, model.modal_w, model.modal_c, model.modal_om
    modal_om_max, ring_frac = model.modal_om_max, model.ring_frac
    wg, wv, wn = drive.times, drive.values, drive.count
    n_end, out_every, rec = recording.n_end, recording.out_every, recording.rec
    n_rec, counters = recording.n_rec, recording.counters
    ne = f.shape[2]
    r_big = phi_big.shape[1]
    translation = moved  # this turntable's sphere translates: its normal forces move
    ny = N_TRANSLATION if moved else 6  # its states (a batch's y may be wider: padded)
    y0 = np.empty(ny)
    f0 = np.empty((2, ne))
    st_new = np.empty((2, ne), dtype=np.int64)
    dev = np.empty(ny)
    x0 = np.empty(2)  # relative displacement [m] and velocity [m/s] at the step start
    xd0 = np.empty(2)
    fin = np.empty(2)  # constant force inputs [N]
    # with the translation: the driving contacts' slip along n [m], its rate [m/s], their
    # constant force inputs there [N] and the elements' components there at the step start
    xn0 = np.zeros(2)
    xdn0 = np.zeros(2)
    gin = np.zeros(2)
    gs0 = np.zeros((2, ne))
    s_end = np.empty(2)  # Stribeck level |s(v)| at the step end [N]
    s_start = np.empty(2)  # and at its start [N]
    # the analytic all-stick step (see the module docstring)
    q2, modal_v, modal_lam = model.q2, model.modal_v, model.modal_lam
    use_modal = model.use_modal
    yp0 = np.empty(ny)  # particular solution at the step start [state units]
    yp1 = np.empty(ny)  # and its rate [state units / s]
    z0 = np.empty(ny, dtype=np.complex128)  # modal amplitudes at the step start
    ez = np.empty(ny, dtype=np.complex128)
    yv = np.empty(ny)
    xq0 = np.empty(2)  # particular relative displacement at the start [m]
    xrate = np.empty(2)  # its rate [m/s]
    xs = np.empty(2)
    vs = np.empty(2)
    fnk = np.empty(2)  # normal forces [N]
    slip_k = np.zeros(2, dtype=np.bool_)  # some element of contact k slips at the step start
    n_eval = 0
    n = n_now[b]
    idx = _advance(wg[b], wn[b], 0, n)
    rung = 0
    gain = amp[b, 0]
    tau = amp[b, 1]
    ideal = amp[b, 2] > 0.5
    ulim = amp[b, 3]
    rate = amp[b, 4]
    a_fast = amp[b, 5]
    r_fast = 0  # largest rung short against the amplifier's fast path (τ_f/8)
    while (1 << (r_fast + 1)) * h_min <= amp[b, 6] / 8.0:
        r_fast += 1
    r_tau = 0  # largest rung short against the amplifier's lag (τ/8; an output lag's step
    # is exact for the stage's ramp, so τ_o does not shorten it)
    while (1 << (r_tau + 1)) * h_min <= tau / 8.0:
        r_tau += 1
    quiet_len = ctl[b, 0]
    ql2 = quiet_len * quiet_len  # its square's decision band (see _exceeds; none if tiny)
    q2_lo, q2_hi = (ql2 * (1.0 - 1e-12), ql2 * (1.0 + 1e-12)) if ql2 > 1e-280 else (-1.0, math.inf)
    r_slip = int(ctl[b, 1])
    resume = ctl[b, 2] > 0.5  # a landing shortens its step only (ReducedModel.resume_rung)
    # the amplifier's decays over each rung's step h = h_min·2^r: exp(−h/τ), exp(−h/τ_f)
    e_tau = np.zeros(r_big)
    e_tf = np.zeros(r_big)
    if not ideal:
        for r in range(r_big):
            h_r = (1 << r) * h_min
            e_tau[r] = math.exp(-h_r / tau)
            if a_fast != 0.0:
                e_tf[r] = math.exp(-h_r / amp[b, 6])
    order = np.arange(ny)  # modes from the fastest down (the ringing cap; NaN last)
    for i in range(1, ny):
        j = i
        while j > 0 and _om_key(modal_om[b, order[j - 1]]) < _om_key(modal_om[b, order[j]]):
            order[j - 1], order[j] = order[j], order[j - 1]
            j -= 1
    twin = _twins(order, modal_lam[b], modal_w[b], ny)
    s_ok = False  # s_end holds the Stribeck levels |s(ẋ)| [N] of the present state
    n_acc = 0
    n_rej = 0
    status = 0
    while True:
        # ---- record ---------------------------------------------------------------
        if n % out_every[b] == 0 and n_rec[b] < rec.shape[1]:
            row = rec[b, n_rec[b]]
            row[0] = n * h_min
            row[1] = y[b, 0]
            row[2] = y[b, 1]
            row[3] = volt[b]
            for k in range(2):
                if translation:
                    x, _xd = _rel_moved(y[b], srow[b], k)
                else:
                    x, _xd = _rel(y[b], mech[b], k)
                row[4 + k] = y[b, 2 + 2 * k]
                row[6 + k] = x
                fk = 0.0
                ns = 0
                for i in range(ne):
                    fk += f[b, k, i]
                    ns += st[b, k, i]
                row[8 + k] = fk
                row[10 + k] = ns
            n_rec[b] += 1
        if n >= n_end[b]:
            break
        # ---- rung caps ------------------------------------------------------------------
        target = n_end[b]
        if idx + 1 < wn[b] and wg[b, idx + 1] < target:
            target = int(wg[b, idx + 1])  # breakpoints lie on the grid (integral floats)
        nxt_out = (n // out_every[b] + 1) * out_every[b]
        r_land = _ladder(min(target, nxt_out) - n, r_big)  # lands on either, the first
        any_slip = False
        for k in range(2):
            slip_k[k] = False
            for i in range(ne):
                if st[b, k, i] == 0:
                    slip_k[k] = True
                    any_slip = True
        # constant force inputs over the step (both contacts): the stuck elements'
        # offsets F_i − k_i x and the slipping elements' forces [N]
        for k in range(2):
            if translation:
                x0[k], xd0[k] = _rel_moved(y[b], srow[b], k)
            else:
                x0[k], xd0[k] = _rel(y[b], mech[b], k)
            fin[k] = 0.0
            for i in range(ne):
                fin[k] += f[b, k, i] - (kk[b, i] * x0[k] if st[b, k, i] == 1 else 0.0)
            if translation:  # the same along n (the elements are 2-vectors, §3.3.2)
                xn0[k], xdn0[k] = _rel_moved(y[b], srow[b], 2 + k)
                gin[k] = 0.0
                for i in range(ne):
                    gin[k] += f[b, 2 + k, i] - (kk[b, i] * xn0[k] if st[b, k, i] == 1 else 0.0)
        # ---- all stuck, amplifier linear: one analytic step -----------------------------
        if not any_slip and use_modal:
            seg = n_end[b]
            if idx + 1 < wn[b] and wg[b, idx + 1] < seg:
                seg = int(wg[b, idx + 1])
            m_seg = seg - n
            u0r = _input_at(wg[b], wv[b], wn[b], idx, n)
            u1r = _input_at(wg[b], wv[b], wn[b], idx, seg)
            u0 = min(ulim, max(-ulim, u0r))
            u1 = min(ulim, max(-ulim, u1r))
            inside = abs(u0r) <= ulim and abs(u1r) <= ulim
            slope = (u1 - u0) / (m_seg * h_min)
            if (inside or u0 == u1) and _amp_linear(
                volt[b], vslow[b], vfast[b], u0, slope, amp[b], ideal
            ):
                v0 = gain * u0 if ideal else volt[b]  # V (ideal: right after a jump)
                vsl = gain * slope  # V/s, the output's slope
                for a in range(ny):
                    yp0[a] = (
                        qs[b, a, 0] * v0 + qs[b, a, 1] * fin[0] + qs[b, a, 2] * fin[1]
                        + q2[b, a] * vsl
                    )  # fmt: skip
                    yp1[a] = qs[b, a, 0] * vsl
                for j in range(ny):
                    zj = 0.0j
                    for c in range(ny):
                        zj += modal_w[b, j, c] * (y[b, c] - yp0[c])
                    z0[j] = zj
                for k in range(2):
                    rho = mech[b, 2 + k]
                    xq0[k] = yp0[2 + 2 * k] - rho * yp0[0]
                    xrate[k] = yp1[2 + 2 * k] - rho * yp1[0]
                    fnk[k] = mech[b, 12 + k]
                    for i in range(ne):
                        f0[k, i] = f[b, k, i]
                lam, mc = modal_lam[b], modal_c[b]
                # event search on the analytic solution
                m_a = 0
                m_hit = -1
                while m_a < m_seg:
                    t_a = m_a * h_min
                    hor, om_fast, drift = _certified(t_a, z0, lam, mc, xq0, xrate, x0, f0,
                                                     kk[b], nu[b], fnk, gms[b], ez)  # fmt: skip
                    n_eval += 1
                    if t_a + hor >= m_seg * h_min:
                        break
                    d_s = hor / h_min
                    if om_fast > 0.0:  # resolve the ringing mode that could break a contact
                        period = 2.0 * math.pi / om_fast / h_min  # grid units
                        d_s = max(d_s, SAMPLE_FRACTION * ring_frac * period)
                    else:  # nothing rings enough: the drift decides
                        d_s = max(d_s, min(drift / h_min, float(m_seg)))
                    m_b = m_a + max(1, int(min(d_s, m_seg)))
                    if m_b > m_seg:
                        m_b = m_seg
                    ev, g_b = _stick_check(m_b * h_min, z0, lam, mc, xq0, xrate, x0, f0,
                                           kk[b], nu[b], fnk, gms[b], ez, xs, vs)  # fmt: skip
                    n_eval += 1
                    if ev:
                        _e, g_a = _stick_check(t_a, z0, lam, mc, xq0, xrate, x0, f0, kk[b],
                                               nu[b], fnk, gms[b], ez, xs, vs)  # fmt: skip
                        m_hit = _locate(m_a, m_b, g_a, g_b, h_min, z0, lam, mc, xq0, xrate,
                                        x0, f0, kk[b], nu[b], fnk, gms[b], ez, xs, vs)  # fmt: skip
                        break
                    m_a = m_b
                m_step = m_hit if m_hit > 0 else m_seg
                # outputs inside the step, evaluated on the solution
                n_o = (n // out_every[b] + 1) * out_every[b]
                while n_o < n + m_step and n_rec[b] < rec.shape[1]:
                    t_o = (n_o - n) * h_min
                    _modal_y(t_o, z0, modal_v[b], lam, yp0, yp1, ez, yv)
                    _write_record(rec[b, n_rec[b]], n_o * h_min, yv, v0 + vsl * t_o, mech[b],
                                  f0, kk[b], x0, ne)  # fmt: skip
                    n_rec[b] += 1
                    n_o += out_every[b]
                # the step's end
                t_e = m_step * h_min
                _modal_y(t_e, z0, modal_v[b], lam, yp0, yp1, ez, yv)
                n_eval += 1
                u_e = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], idx, n + m_step)))
                if ideal:
                    volt[b] = gain * u_e
                    vslow[b] = volt[b]  # kept equal: no stale path for a later amplifier
                else:
                    volt[b], vslow[b], vfast[b] = amplifier_step(
                        v0, vslow[b], vfast[b], u0, u_e, t_e, amp[b]
                    )
                for j in range(ny):
                    y[b, j] = yv[j]
                for k in range(2):
                    x1, xd1 = _rel(y[b], mech[b], k)  # no translation here
                    s1 = _level(xd1, fnk[k], gms[b])
                    for i in range(ne):
                        fi = f0[k, i] + kk[b, i] * (x1 - x0[k])
                        if abs(fi) >= nu[b, i] * s1 and fi * xd1 > 0.0:
                            st[b, k, i] = 0  # broke away: no overshoot past capacity
                            capf = nu[b, i] * s1
                            fi = capf if fi > 0.0 else -capf
                        f[b, k, i] = fi
                n += m_step
                s_ok = False
                idx = _advance(wg[b], wn[b], idx, n)
                n_acc += 1
                if m_hit > 0:
                    rung = 0
                if not _finite(volt[b], y[b]):
                    status = 1
                    break
                continue
        # the amplifier input now [V] and its present segment's slope [V/s]: the path lags it
        u_now = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], idx, n)))
        u_slope = 0.0
        if idx + 1 < wn[b] and wg[b, idx + 1] > wg[b, idx]:
            u_slope = (wv[b, idx + 1] - wv[b, idx]) / ((wg[b, idx + 1] - wg[b, idx]) * h_min)
        cap = r_land
        if resume:  # only a breakpoint caps the rung: the input's slope changes there
            cap = _ladder(target - n, r_big)
        if any_slip:
            cap = min(cap, r_slip)
        else:
            # ringing: modal amplitudes of the deviation from the quasi-static state
            # (y − y_qs, y_qs = −A⁻¹(b_V V + B_f f)); the fastest mode whose amplitude in
            # the contacts' relative motion exceeds quiet_len sets the largest step
            for j in range(ny):
                dev[j] = y[b, j] - (
                    qs[b, j, 0] * volt[b] + qs[b, j, 1] * fin[0] + qs[b, j, 2] * fin[1]
                )
                if translation:
                    dev[j] -= qs[b, j, 3] * gin[0] + qs[b, j, 4] * gin[1]
            om_fast = 0.0
            for jj in range(ny):  # from the fastest mode down: the first that rings decides
                j = order[jj]
                if not modal_om[b, j] > om_fast:
                    break  # no slower mode can raise om_fast
                if translation:
                    if twin[jj]:
                        continue  # its conjugate's amplitude, already checked
                    zj = _project(modal_w[b, j], dev, ny)
                else:
                    zj = 0.0j
                    for c in range(ny):
                        zj += modal_w[b, j, c] * dev[c]
                for k in range(2):
                    if _exceeds(modal_c[b, k, j] * zj, quiet_len, q2_lo, q2_hi):
                        om_fast = modal_om[b, j]
                        break
            if not ideal:
                if abs(gain * u_now - volt[b]) > rate * tau:
                    om_fast = max(om_fast, modal_om_max[b])
            if om_fast > 0.0:
                r_dyn = 0
                lim = ring_frac * (MOVED_RING_FACTOR if moved else 1.0) * 2.0 * math.pi
                lim /= om_fast * h_min
                while (1 << (r_dyn + 1)) <= lim:
                    r_dyn += 1
                cap = min(cap, r_dyn)
        if a_fast > 0.0 and not ideal:  # the fast path settling: short steps
            steady = a_fast * gain * (u_now - u_slope * amp[b, 6])
            if abs(vfast[b] - steady) > FAST_QUIET:
                cap = min(cap, r_fast)
        if not ideal:  # the first-order lag settling: short steps (V is held linear)
            if not _amp_linear(volt[b], vslow[b], vfast[b], u_now, u_slope, amp[b], ideal):
                cap = min(cap, r_tau)
        if rung > cap:
            rung = cap
        r_use = min(rung, r_land)  # this step's rung (rung itself where not resume)
        # configuration: stuck stiffness level of each contact
        m0 = 0
        m1 = 0
        for i in range(ne):
            m0 |= st[b, 0, i] << i
            m1 |= st[b, 1, i] << i
        cfg = lvl[b, 0, m0] * nlvl[b, 1] + lvl[b, 1, m1]
        all_stick = not any_slip
        # save for a rejected step
        for j in range(ny):
            y0[j] = y[b, j]
        for k in range(2):
            for i in range(ne):
                f0[k, i] = f[b, k, i]
                if translation:
                    gs0[k, i] = f[b, 2 + k, i]
        v0 = volt[b]
        vs0 = vslow[b]
        vf0 = vfast[b]
        vs1 = vs0
        vf1 = vf0
        u0 = u_now
        for k in range(2):  # Stribeck level at the step start [N] (event interpolation):
            # the last accepted step's end level where it ended at this state
            fn_s = mech[b, 12 + k]
            if translation:
                fn_s = _normal(y[b], volt[b], 0.0, fn_s, nrow[b], k, True)
                s_start[k] = s_end[k] if s_ok else _level2(xd0[k], xdn0[k], fn_s, gms[b])
            else:
                s_start[k] = s_end[k] if s_ok else _level(xd0[k], fn_s, gms[b])
        while True:
            dn = 1 << r_use
            h = dn * h_min
            n1 = n + dn
            # amplifier
            i1 = _advance(wg[b], wn[b], idx, n1 - 1)  # same segment (steps never cross)
            u1 = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], i1, n1)))
            if ideal:
                v1 = gain * u1
                vs1 = v1  # kept equal: no stale path for a later amplifier
                v0e = gain * u0
            else:
                v1, vs1, vf1 = amplifier_step_decayed(v0, vs0, vf0, u0, u1, h, amp[b],
                                                      e_tau[r_use], e_tf[r_use])  # fmt: skip
                v0e = v0
            vslope = (v1 - v0e) / h
            if all_stick:  # every rung of the all-stick configuration
                ph = phi_big[b, r_use]
                gm = gam_big[b, r_use]
            else:  # partial slip: rung ≤ r_slip
                ph = phi_small[b, cfg, r_use]
                gm = gam_small[b, cfg, r_use]
            if translation:
                _step_fast(ph, gm, y0, v0e, vslope, fin, gin, y[b], ny)
            else:
                for a in range(ny):
                    s = gm[a, 0] * v0e + gm[a, 1] * vslope + gm[a, 2] * fin[0] + gm[a, 3] * fin[1]
                    for c in range(ny):
                        s += ph[a, c] * y0[c]
                    y[b, a] = s
            # elements
            event = False
            frac = 1.0  # earliest crossing in the step by linear interpolation [-]
            for k in range(2):
                if translation:
                    event, frac = _elements_moved(
                        b, k, y, y0, v1, v0e, vslope, mech, nrow, srow, gms, nu, kk, f, st,
                        f0, gs0, x0, xd0, xn0, xdn0, slip_k, s_start, s_end, st_new, h, ne,
                        event, frac,
                    )  # fmt: skip
                    continue
                x1, xd1 = _rel(y[b], mech[b], k)
                dx = x1 - x0[k]
                fn_k = mech[b, 12 + k]  # the normal force [N]
                s1 = _level(xd1, fn_k, gms[b])
                s_end[k] = s1
                sbar = 0.0  # slipping elements' level, relaxation and direction (only theirs)
                decay = 0.0
                sg = 0.0
                if slip_k[k]:
                    vbar = 0.5 * (xd0[k] + xd1)
                    sbar = _level(vbar, fn_k, gms[b])
                    decay = math.exp(-gms[b, 0] * h / sbar) if sbar > 0.0 else 0.0
                    sg = 1.0 if vbar > 0.0 else (-1.0 if vbar < 0.0 else 0.0)
                for i in range(ne):  # the GMS law (Eq. 2.24–2.25), one compiled place
                    fi = gms_element_step(f0[k, i], st[b, k, i], kk[b, i], dx,
                                          nu[b, i] * sbar * sg, decay)  # fmt: skip
                    f[b, k, i] = fi
                    st_new[k, i], hit, frac = _transition(
                        st[b, k, i], abs(fi), nu[b, i] * s1, fi * xd1, abs(f0[k, i]),
                        nu[b, i] * s_start[k], f0[k, i] * xd0[k], frac,
                    )  # fmt: skip
                    event = event or hit
            if event and r_use > 0:
                # retry below the interpolated crossing (regula falsi on the ladder)
                r_new = r_use - 1
                while r_new > 0 and (1 << r_new) > frac * dn:
                    r_new -= 1
                rung = r_new
                r_use = r_new
                n_rej += 1
                continue
            # accept
            volt[b] = v1
            vslow[b] = vs1
            vfast[b] = vf1
            for k in range(2):
                for i in range(ne):
                    if st[b, k, i] == 1 and st_new[k, i] == 0:
                        capf = nu[b, i] * s_end[k]  # broke away: no overshoot past capacity
                        if translation:  # the 2-vector scaled onto its capacity
                            fm = math.sqrt(f[b, k, i] ** 2 + f[b, 2 + k, i] ** 2)
                            if fm > capf:
                                f[b, k, i] *= capf / fm
                                f[b, 2 + k, i] *= capf / fm
                        elif abs(f[b, k, i]) > capf:
                            f[b, k, i] = capf if f[b, k, i] > 0.0 else -capf
                    st[b, k, i] = st_new[k, i]
            s_ok = True  # the next step starts from this state
            n = n1
            idx = _advance(wg[b], wn[b], idx, n)
            n_acc += 1
            if event:
                rung = r_use
            elif r_use == rung:  # a full-length step: grow (a landing's keeps the rung)
                rung += 1
            break
        if not _finite(volt[b], y[b]):
            status = 1
            break
    n_now[b] = n
    counters[b, 0] += n_acc
    counters[b, 1] += n_rej
    counters[b, 2] = status
    counters[b, 3] += n_eval
