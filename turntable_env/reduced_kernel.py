"""Compiled integrator of the per-axis reduced model (:mod:`turntable_env.reduced`).

Between GMS transitions the reduced model is linear: the table angle θ and the two
tube contact points u_k are a 6-state linear system driven by the amplifier
voltage V (first-order hold over a step) and by constant per-contact forces (the
stuck elements' offsets and the slipping elements' forces, held over a step). The
kernel therefore steps it *exactly* (exponential integrator):

    y(t+h) = Φ_c(h) y(t) + Γ_c(h) [V(t), V̇, f_1, f_2]

with Φ_c, Γ_c precomputed (scipy ``expm`` of the augmented matrix, then repeated
squaring) for every stick configuration c (which elements stick, i.e. the stuck
stiffness Σk_i on each contact) and every rung h = h_min·2^r of a step ladder.
Time runs on the integer grid of h_min (1/16 µs by default): drive breakpoints
and outputs are rounded to it and every step lands on them.

Step control (no Python per step):

* a step whose end shows a GMS transition (stick→slip when |F_i| reaches
  ν_i|s(v)| while loading; slip→stick when the relative velocity reverses) is
  rejected and retried one rung lower, down to h_min: the transition is located
  to the grid (event location by bisection);
* after an accepted step without a transition the rung grows by one;
* while an element slips the rung is capped at ``r_slip`` (the slipping
  elements' forces and the amplifier's slewing are held / linearised over a
  step); while the contacts ring — a stick mode whose amplitude in the relative
  motion (deviation from the quasi-static state, in modal coordinates) exceeds
  ``quiet_len`` — at ``ring_frac`` of that fastest ringing mode's period, so no
  transition hides inside a step; otherwise up to the next breakpoint or output.

Slipping elements relax exactly for the step's mean relative velocity
(dF/dt = C(ν_i s(v) sgn v − F_i)/|s(v)|, Eq. 2.25); their loading rate is capped at
k_i|v| as in the 1-D kernel. Batched: the loop runs over N independent turntables
with their own parameters and drives; a single run is a batch of one.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .amplifier import amplifier_step
from .friction.kernels import stribeck_magnitude
from .integrator import advance_index as _advance
from .integrator import pwl_value as _input_at

__all__ = ["N_REC", "REC_FIELDS", "run_reduced_batch"]

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


@njit(cache=True)
def _rel(y, mech, k):
    """Relative displacement and velocity (tube contact point − table point) of contact k."""
    rho = mech[2 + k]
    return y[2 + 2 * k] - rho * y[0], y[3 + 2 * k] - rho * y[1]


@njit(cache=True)
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
            counts them; counters[b] = (accepted steps, rejected steps, status). Status 0
            ok, 1 non-finite state.
    """
    y, volt, f, st, n_now = state.y, state.volt, state.f, state.st, state.n
    vslow, vfast = state.vslow, state.vfast
    mech, gms, nu, kk, amp, ctl = model.mech, model.gms, model.nu, model.kk, model.amp, model.ctl
    lvl, nlvl = model.lvl, model.nlvl
    phi_small, gam_small, phi_big, gam_big = (
        model.phi_small, model.gam_small, model.phi_big, model.gam_big
    )  # fmt: skip
    qs, modal_w, modal_c, modal_om = model.qs, model.modal_w, model.modal_c, model.modal_om
    modal_om_max, ring_frac = model.modal_om_max, model.ring_frac
    wg, wv, wn = drive.times, drive.values, drive.count
    n_end, out_every, rec = recording.n_end, recording.out_every, recording.rec
    n_rec, counters = recording.n_rec, recording.counters
    nb = y.shape[0]
    ne = f.shape[2]
    r_big = phi_big.shape[1]
    y0 = np.empty(6)
    f0 = np.empty((2, ne))
    st_new = np.empty((2, ne), dtype=np.int64)
    dev = np.empty(6)
    x0 = np.empty(2)  # relative displacement [m] and velocity [m/s] at the step start
    xd0 = np.empty(2)
    fin = np.empty(2)  # constant force inputs [N]
    s_end = np.empty(2)  # Stribeck level |s(v)| at the step end [N]
    for b in range(nb):
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
        quiet_len = ctl[b, 0]
        r_slip = int(ctl[b, 1])
        mu_s = gms[b, 1]
        n_acc = 0
        n_rej = 0
        status = 0
        while True:
            # ---- record ---------------------------------------------------------------
            if n % out_every[b] == 0 and n_rec[b] < rec.shape[1]:
                i_r = n_rec[b]
                rec[b, i_r, 0] = n * h_min
                rec[b, i_r, 1] = y[b, 0]
                rec[b, i_r, 2] = y[b, 1]
                rec[b, i_r, 3] = volt[b]
                for k in range(2):
                    x, _xd = _rel(y[b], mech[b], k)
                    rec[b, i_r, 4 + k] = y[b, 2 + 2 * k]
                    rec[b, i_r, 6 + k] = x
                    fk = 0.0
                    ns = 0
                    for i in range(ne):
                        fk += f[b, k, i]
                        ns += st[b, k, i]
                    rec[b, i_r, 8 + k] = fk
                    rec[b, i_r, 10 + k] = ns
                n_rec[b] += 1
            if n >= n_end[b]:
                break
            # ---- rung caps ------------------------------------------------------------------
            target = n_end[b]
            nxt_out = (n // out_every[b] + 1) * out_every[b]
            if nxt_out < target:
                target = nxt_out
            if idx + 1 < wn[b] and wg[b, idx + 1] < target:
                target = wg[b, idx + 1]
            span = target - n
            r_land = 0
            while r_land + 1 < r_big and (1 << (r_land + 1)) <= span:
                r_land += 1
            any_slip = False
            for k in range(2):
                for i in range(ne):
                    if st[b, k, i] == 0:
                        any_slip = True
            # constant force inputs over the step (both contacts): the stuck elements'
            # offsets F_i − k_i x and the slipping elements' forces [N]
            for k in range(2):
                x0[k], xd0[k] = _rel(y[b], mech[b], k)
                fin[k] = 0.0
                for i in range(ne):
                    fin[k] += f[b, k, i] - (kk[b, i] * x0[k] if st[b, k, i] == 1 else 0.0)
            cap = r_land
            if any_slip:
                cap = min(cap, r_slip)
            else:
                # ringing: modal amplitudes of the deviation from the quasi-static state
                # (y − y_qs, y_qs = −A⁻¹(b_V V + B_f f)); the fastest mode whose amplitude in
                # the contacts' relative motion exceeds quiet_len sets the largest step
                for j in range(6):
                    dev[j] = y[b, j] - (
                        qs[b, j, 0] * volt[b] + qs[b, j, 1] * fin[0] + qs[b, j, 2] * fin[1]
                    )
                om_fast = 0.0
                for j in range(6):
                    zj = 0.0j
                    for c in range(6):
                        zj += modal_w[b, j, c] * dev[c]
                    for k in range(2):
                        if abs(modal_c[b, k, j] * zj) > quiet_len and modal_om[b, j] > om_fast:
                            om_fast = modal_om[b, j]
                if not ideal:
                    u_now = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], idx, n)))
                    if abs(gain * u_now - volt[b]) > rate * tau:
                        om_fast = max(om_fast, modal_om_max[b])
                if om_fast > 0.0:
                    r_dyn = 0
                    lim = ring_frac * 2.0 * math.pi / om_fast / h_min
                    while (1 << (r_dyn + 1)) <= lim:
                        r_dyn += 1
                    cap = min(cap, r_dyn)
            if a_fast > 0.0 and not ideal:  # the fast path settling: short steps
                u_now = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], idx, n)))
                slope = 0.0  # input slope of the present segment [V/s]: the path lags it
                if idx + 1 < wn[b] and wg[b, idx + 1] > wg[b, idx]:
                    slope = (wv[b, idx + 1] - wv[b, idx]) / ((wg[b, idx + 1] - wg[b, idx]) * h_min)
                steady = a_fast * gain * (u_now - slope * amp[b, 6])
                if abs(vfast[b] - steady) > FAST_QUIET:
                    cap = min(cap, r_fast)
            if rung > cap:
                rung = cap
            # configuration: stuck stiffness level of each contact
            m0 = 0
            m1 = 0
            for i in range(ne):
                m0 |= st[b, 0, i] << i
                m1 |= st[b, 1, i] << i
            cfg = lvl[b, 0, m0] * nlvl[b, 1] + lvl[b, 1, m1]
            all_stick = not any_slip
            # save for a rejected step
            for j in range(6):
                y0[j] = y[b, j]
            for k in range(2):
                for i in range(ne):
                    f0[k, i] = f[b, k, i]
            v0 = volt[b]
            vs0 = vslow[b]
            vf0 = vfast[b]
            vs1 = vs0
            vf1 = vf0
            u0 = min(ulim, max(-ulim, _input_at(wg[b], wv[b], wn[b], idx, n)))
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
                    v1, vs1, vf1 = amplifier_step(v0, vs0, vf0, u0, u1, h, amp[b])
                    v0e = v0
                vslope = (v1 - v0e) / h
                if all_stick:  # every rung of the all-stick configuration
                    ph = phi_big[b, rung]
                    gm = gam_big[b, rung]
                else:  # partial slip: rung ≤ r_slip
                    ph = phi_small[b, cfg, rung]
                    gm = gam_small[b, cfg, rung]
                for a in range(6):
                    s = gm[a, 0] * v0e + gm[a, 1] * vslope + gm[a, 2] * fin[0] + gm[a, 3] * fin[1]
                    for c in range(6):
                        s += ph[a, c] * y0[c]
                    y[b, a] = s
                # elements
                event = False
                for k in range(2):
                    x1, xd1 = _rel(y[b], mech[b], k)
                    dx = x1 - x0[k]
                    vbar = 0.5 * (xd0[k] + xd1)
                    fn_k = mech[b, 12 + k]
                    sbar = stribeck_magnitude(vbar, fn_k, mu_s, gms[b, 2], gms[b, 3], gms[b, 4])
                    s1 = stribeck_magnitude(xd1, fn_k, mu_s, gms[b, 2], gms[b, 3], gms[b, 4])
                    s_end[k] = s1
                    for i in range(ne):
                        fi = f0[k, i]
                        if st[b, k, i] == 1:
                            fi += kk[b, i] * dx
                        else:
                            sg = 1.0 if vbar > 0.0 else (-1.0 if vbar < 0.0 else 0.0)
                            tgt = nu[b, i] * sbar * sg
                            fnew = tgt + (fi - tgt) * math.exp(-gms[b, 0] * h / sbar)
                            d = fnew - fi
                            lim = kk[b, i] * dx
                            if fi != 0.0 and d * fi > 0.0 and d * fi > lim * fi:
                                fnew = fi + lim  # loading no faster than the element spring
                            fi = fnew
                        f[b, k, i] = fi
                        # transitions (as the 1-D GMS kernel)
                        if st[b, k, i] == 1:
                            if abs(fi) >= nu[b, i] * s1 and fi * xd1 > 0.0:
                                st_new[k, i] = 0
                                event = True
                            else:
                                st_new[k, i] = 1
                        else:
                            if fi * xd1 <= 0.0:
                                st_new[k, i] = 1
                                event = True
                            else:
                                st_new[k, i] = 0
                if event and rung > 0:
                    rung -= 1
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
                            if abs(f[b, k, i]) > capf:
                                f[b, k, i] = capf if f[b, k, i] > 0.0 else -capf
                        st[b, k, i] = st_new[k, i]
                n = n1
                idx = _advance(wg[b], wn[b], idx, n)
                n_acc += 1
                if not event:
                    rung += 1
                break
            chk = volt[b]
            for j in range(6):
                chk += y[b, j]
            if not math.isfinite(chk):
                status = 1
                break
        n_now[b] = n
        counters[b, 0] += n_acc
        counters[b, 1] += n_rej
        counters[b, 2] = status
