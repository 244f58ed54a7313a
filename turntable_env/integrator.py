"""Compiled time integration of the assembled turntable (the full 3-D model).

One ``numba.njit(cache=CACHE)`` loop advances the table (rigid body, full SO(3)
orientation), the three tube tops (small displacement twists about their nominal
pose), the 2-D GMS elements of the three contacts and the four amplifier
channels. No Python runs per step.

Scheme (velocity Verlet, second order, symplectic for the conservative part):

1. half kick of every momentum with the forces at t_n;
2. drift: positions with the half-step velocities, the table orientation by the
   exponential map R ← exp(Δt ω̃)R (so R stays in SO(3) however far it turns);
3. contact kinematics at t_{n+1}; GMS elements advanced with the half-step slip
   velocity (stick: F_i += k_i Δx exactly, so a sticking contact is a spring);
4. amplifier channels advanced exactly (first-order stage, slew limit) with the
   input at mid-step;
5. forces at t_{n+1}; second half kick.

Steps end exactly on drive breakpoints and output times, so flyback edges are
resolved at their instant. Positions are kept as displacements from the nominal
pose (table centre, tube tops), and contact overlaps are computed without
cancellation, so nanometre motions keep full double precision at any rotation.

Energy bookkeeping per step (§ "energy balance"): electrical work Σ V̄ Δq,
damping dissipation, and the contact-interface work F̄·Δx from which the GMS
dissipation follows as work minus the change of the elements' stored energy.

Status codes returned: 0 finished, 1 non-finite state, 2 state out of bounds
(diverging), 3 a contact reached the rim of the half sphere.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .amplifier import amplifier_hold_step
from .friction.gms2d import gms2d_rates, gms2d_update
from .friction.kernels import stribeck_magnitude
from .kernel_cache import CACHE
from .screw import log_so3_nb, rotate_left_inplace

__all__ = ["STATUS_NAMES", "run_full_model"]

STATUS_NAMES = {0: "ok", 1: "non-finite", 2: "diverging", 3: "rim"}

# layout of the packed scalar arrays (documented here, filled by turntable_env.model)
# table_p: [m, g, P, R_table, R_ball, r_nom, k_c, e, d_c, w_ball, w_table, bound_u, bound_delta]
# gms_p:   [C, mu_s, mu_c, v_s, delta, sigma2, beta_t, alpha, axis_x, axis_y, axis_z]
# amp_p:   [gain, tau, ideal, input_limit, fast_fraction, fast_time, output_lag]
# energy accumulators acc: [W_elec, W_interface, D_tube, D_contact, gross |W_elec|]


@njit(cache=CACHE)
def pwl_value(wt, wv, n, idx, t):
    """Piecewise-linear value at t (right-continuous); idx = last breakpoint index <= t."""
    if n == 1 or t <= wt[0]:
        return wv[0] if t < wt[0] or n == 1 else wv[idx]
    i = idx
    if i >= n - 1:
        return wv[n - 1]
    span = wt[i + 1] - wt[i]
    if span <= 0.0:
        return wv[i + 1]
    return wv[i] + (t - wt[i]) / span * (wv[i + 1] - wv[i])


@njit(cache=CACHE)
def advance_index(wt, n, idx, t):
    """Move idx forward to the last breakpoint with time <= t."""
    while idx + 1 < n and wt[idx + 1] <= t:
        idx += 1
    return idx


@njit(cache=CACHE)
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=CACHE)
def contact_kinematics(
    xi, pt_disp, d_nom, r0, basis_ref, table_p, xid, vt, omega, cinfo, cn, cx, cy, crc, crt, scr
):
    """Contact geometry and velocities at the current positions.

    Fills per contact k: cinfo[k] = (overlap δ [m], δ̇ [m/s], v_x, v_y in the plane [m/s],
    table lever ρ [m]); cn[k] = normal n (table centre → ball); cx, cy = plane basis
    (Eq. 3.26); crc[k] = tube-top → contact point; crt[k] = table centre → contact point.
    ``scr`` is scratch (rows 0–3 used), so no step allocates.
    """
    r_ball = table_p[4]
    r_nom = table_p[5]
    w_ball = table_p[9]
    w_table = table_p[10]
    wb = w_table / (w_ball + w_table)  # p_c = p1 + wb·δ·n  (Eq. 3.24)
    th_x_r = scr[0]
    e = scr[1]
    tmp = scr[2]
    vrel = scr[3]
    for k in range(3):
        _cross(xi[k, 0:3], r0[k], th_x_r)
        for j in range(3):
            e[j] = xi[k, 3 + j] + th_x_r[j] - pt_disp[j]
        de = 0.0
        ee = 0.0
        for j in range(3):
            de += d_nom[k, j] * e[j]
            ee += e[j] * e[j]
        dist2_excess = 2.0 * r_nom * de + ee  # |Δ|² − r_nom²
        dist = math.sqrt(r_nom * r_nom + dist2_excess)
        overlap = -dist2_excess / (dist + r_nom)  # r_nom − |Δ|, no cancellation
        for j in range(3):
            cn[k, j] = (r_nom * d_nom[k, j] + e[j]) / dist
        # plane basis: reference tangent projected on the plane, y = n × x
        dot = 0.0
        for j in range(3):
            dot += basis_ref[k, j] * cn[k, j]
        nx = 0.0
        for j in range(3):
            cx[k, j] = basis_ref[k, j] - dot * cn[k, j]
            nx += cx[k, j] * cx[k, j]
        nx = math.sqrt(nx)
        for j in range(3):
            cx[k, j] /= nx
        _cross(cn[k], cx[k], tmp)
        for j in range(3):
            cy[k, j] = tmp[j]
        # contact point offsets (linearised tube kinematics use the nominal ball offset r0)
        rho_t = r_nom - r_ball - (1.0 - wb) * overlap  # table centre → contact point [m]
        for j in range(3):
            crc[k, j] = r0[k, j] - (r_ball - wb * overlap) * cn[k, j]
            crt[k, j] = rho_t * cn[k, j]
        # relative velocity at the contact point: ball − table
        _cross(xid[k, 0:3], crc[k], tmp)
        for j in range(3):
            vrel[j] = xid[k, 3 + j] + tmp[j]
        _cross(omega, crt[k], tmp)
        for j in range(3):
            vrel[j] -= vt[j] + tmp[j]
        vn = 0.0
        vx = 0.0
        vy = 0.0
        for j in range(3):
            vn += vrel[j] * cn[k, j]
            vx += vrel[j] * cx[k, j]
            vy += vrel[j] * cy[k, j]
        cinfo[k, 0] = overlap
        cinfo[k, 1] = -vn
        cinfo[k, 2] = vx
        cinfo[k, 3] = vy
        cinfo[k, 4] = rho_t


@njit(cache=CACHE)
def _asymmetry(gms_p, crt_k, cx_k, cy_k, vx, vy):
    """Friction-level factor [-] of one contact for the sliding-direction asymmetry α =
    gms_p[7] about the unit axis a = gms_p[8:11]: 1 + α·c with c = −(v·t)/(|v|·ρ), v = (vx,
    vy) the tube-minus-table sliding velocity in the contact plane, t the plane projection
    of a × ρ (the table's motion there under a positive turn), ρ = |crt_k|; ±1 for a tube
    driving the axis, 0 for one on the axis (the per-axis model's 1 + α·sgn(−v))."""
    alpha = gms_p[7]
    speed = math.sqrt(vx * vx + vy * vy)
    if alpha == 0.0 or speed == 0.0:
        return 1.0
    ax, ay, az = gms_p[8], gms_p[9], gms_p[10]
    tx = ay * crt_k[2] - az * crt_k[1]
    ty = az * crt_k[0] - ax * crt_k[2]
    tz = ax * crt_k[1] - ay * crt_k[0]
    rho = math.sqrt(crt_k[0] ** 2 + crt_k[1] ** 2 + crt_k[2] ** 2)
    dx = tx * cx_k[0] + ty * cx_k[1] + tz * cx_k[2]
    dy = tx * cy_k[0] + ty * cy_k[1] + tz * cy_k[2]
    if rho == 0.0:
        return 1.0
    return 1.0 - alpha * (vx * dx + vy * dy) / (speed * rho)


@njit(cache=CACHE)
def _normal_force(table_p, overlap, rate):
    """(total, elastic, damping) normal force [N]; zero when separated, never pulling."""
    if overlap <= 0.0:
        return 0.0, 0.0, 0.0
    fe = table_p[6] * overlap ** table_p[7]
    fd = table_p[8] * rate
    if fe + fd < 0.0:
        fd = -fe
    return fe + fd, fe, fd


@njit(cache=CACHE)
def contact_forces(
    xi,
    xid,
    vq,
    ktop,
    dtop,
    bcoup,
    cinfo,
    cn,
    cx,
    cy,
    crc,
    crt,
    gf,
    gst,
    gk,
    table_p,
    gms_p,
    rot,
    c_body,
    w_tube,
    f_table,
    tau_com,
    fn_out,
    ff_out,
    scr,
):
    """Wrenches on the tube tops (world, about the top) and force / torque (about the CoM)
    on the table. ``vq[k, q]`` are the quadrant voltages [V]; ``scr`` scratch rows 4–8."""
    m = table_p[0]
    g = table_p[1]
    preload = table_p[2]
    sigma2 = gms_p[5]
    tmp = scr[4]
    fw = scr[5]
    tau_c = scr[6]  # torque about the table centre
    for j in range(3):
        tau_c[j] = 0.0
        f_table[j] = 0.0
    f_table[2] = -m * g - preload
    for k in range(3):
        for a in range(6):
            s = 0.0
            for b in range(6):
                s -= ktop[k, a, b] * xi[k, b] + dtop[k, a, b] * xid[k, b]
            for q in range(4):
                s += bcoup[k, a, q] * vq[k, q]
            w_tube[k, a] = s
        fn, _fe, _fd = _normal_force(table_p, cinfo[k, 0], cinfo[k, 1])
        fn_out[k] = fn
        # friction force on the table, in the plane (sum of GMS elements + viscous)
        c_t = sigma2  # viscous + micro-damping of the sticking elements [N·s/m]
        for i in range(gf.shape[1]):
            if gst[k, i] == 1:
                c_t += gms_p[6] * gk[i]
        fx = c_t * cinfo[k, 2]
        fy = c_t * cinfo[k, 3]
        for i in range(gf.shape[1]):
            fx += gf[k, i, 0]
            fy += gf[k, i, 1]
        ff_out[k, 0] = fx
        ff_out[k, 1] = fy
        for j in range(3):
            fw[j] = fx * cx[k, j] + fy * cy[k, j]
        # on the ball: +fn·n (pushed away from the table), −friction
        for j in range(3):
            w_tube[k, 3 + j] += fn * cn[k, j] - fw[j]
        _cross(crc[k], fw, tmp)
        for j in range(3):
            w_tube[k, j] -= tmp[j]
        # ball-centre lever for the normal force: r0 = crc + (r_ball − wb δ) n  → r0 × n
        # equals crc × n, so use crc
        _cross(crc[k], cn[k], tmp)
        for j in range(3):
            w_tube[k, j] += fn * tmp[j]
        # on the table: −fn·n through the centre, +friction at the contact point
        for j in range(3):
            f_table[j] += -fn * cn[k, j] + fw[j]
        _cross(crt[k], fw, tmp)
        for j in range(3):
            tau_c[j] += tmp[j]
    # torque about the CoM: τ_c − (p_com − p_centre) × F_total, p_com − p_centre = R c
    rc = scr[7]
    for j in range(3):
        rc[j] = rot[j, 0] * c_body[0] + rot[j, 1] * c_body[1] + rot[j, 2] * c_body[2]
    # gravity acts at the CoM (no torque there); remove it from the lever term
    f_nog = scr[8]
    for j in range(3):
        f_nog[j] = f_table[j]
    f_nog[2] += m * g
    _cross(rc, f_nog, tmp)
    for j in range(3):
        tau_com[j] = tau_c[j] - tmp[j]


@njit(cache=CACHE)
def quadrant_voltages(vch, qchan, qsign, vq):
    """Quadrant voltages [V] from the channel voltages (sign −1: the symmetric mode's
    opposite quadrant)."""
    for k in range(3):
        for q in range(4):
            c = qchan[k, q]
            vq[k, q] = qsign[k, q] * vch[c] if c >= 0 else 0.0


@njit(cache=CACHE)
def _charges(xi, vq, bcoup, cs, out):
    """q = C_s V + Bᵀξ per quadrant [C]."""
    for k in range(3):
        for q in range(4):
            s = 0.0
            for p in range(4):
                s += cs[k, q, p] * vq[k, p]
            for a in range(6):
                s += bcoup[k, a, q] * xi[k, a]
            out[k, q] = s


@njit(cache=CACHE)
def _omega(rot, jinv, lam, out, scr):
    """ω = R J⁻¹ Rᵀ L (world); ``scr`` scratch rows 9–10."""
    lb = scr[9]
    for a in range(3):
        lb[a] = rot[0, a] * lam[0] + rot[1, a] * lam[1] + rot[2, a] * lam[2]
    wb = scr[10]
    for a in range(3):
        wb[a] = jinv[a, 0] * lb[0] + jinv[a, 1] * lb[1] + jinv[a, 2] * lb[2]
    for a in range(3):
        out[a] = rot[a, 0] * wb[0] + rot[a, 1] * wb[1] + rot[a, 2] * wb[2]


@njit(cache=CACHE)
def _table_centre(pc_disp, rot, c_body, out):
    """Table-centre displacement = CoM displacement + (I − R)c [m]."""
    for j in range(3):
        out[j] = pc_disp[j] + c_body[j]
        for a in range(3):
            out[j] -= rot[j, a] * c_body[a]


@njit(cache=CACHE)
def _kinematics(
    pc_disp, vc, rot, omega, c_body, xi, xid, d_nom, r0, basis_ref, table_p, pt_disp, vt, cinfo,
    cn, cx, cy, crc, crt, scr,
):  # fmt: skip
    """Table-centre displacement and velocity, then the contacts (:func:`contact_kinematics`);
    ``scr`` scratch rows 0–3 and 11–12."""
    rc = scr[11]
    tmp = scr[12]
    _table_centre(pc_disp, rot, c_body, pt_disp)
    for j in range(3):
        rc[j] = rot[j, 0] * c_body[0] + rot[j, 1] * c_body[1] + rot[j, 2] * c_body[2]
    _cross(omega, rc, tmp)
    for j in range(3):
        vt[j] = vc[j] - tmp[j]  # v_centre = v_CoM + ω × (p_centre − p_CoM)
    contact_kinematics(
        xi, pt_disp, d_nom, r0, basis_ref, table_p, xid, vt, omega, cinfo, cn, cx, cy, crc, crt,
        scr,
    )  # fmt: skip


@njit(cache=CACHE)
def _kick(h, m, f_table, tau_com, minv, w_tube, vc, lam, xid):
    """Half kick over h [s]: table momentum and angular momentum, tube-top velocities."""
    for j in range(3):
        vc[j] += h * f_table[j] / m
        lam[j] += h * tau_com[j]
    for k in range(3):
        for a in range(6):
            s = 0.0
            for b in range(6):
                s += minv[k, a, b] * w_tube[k, b]
            xid[k, a] += h * s


@njit(cache=CACHE)
def _stored_energies(
    pc_disp,
    vc,
    lam,
    omega,
    xi,
    xid,
    vq,
    mtube,
    ktop,
    cs,
    cinfo,
    gf,
    gk,
    table_p,
    pt_disp,
    out,
):
    """out = (kinetic, tube elastic, piezo electric, contact normal, GMS, gravity+preload) [J]."""
    m = table_p[0]
    ke = 0.5 * m * (vc[0] ** 2 + vc[1] ** 2 + vc[2] ** 2)
    ke += 0.5 * (omega[0] * lam[0] + omega[1] * lam[1] + omega[2] * lam[2])
    el = 0.0
    pz = 0.0
    for k in range(3):
        for a in range(6):
            sm = 0.0
            sk = 0.0
            for b in range(6):
                sm += mtube[k, a, b] * xid[k, b]
                sk += ktop[k, a, b] * xi[k, b]
            ke += 0.5 * xid[k, a] * sm
            el += 0.5 * xi[k, a] * sk
        for q in range(4):
            for p in range(4):
                pz += 0.5 * vq[k, q] * cs[k, q, p] * vq[k, p]
    ec = 0.0
    eg = 0.0
    e_exp = table_p[7]
    for k in range(3):
        d = cinfo[k, 0]
        if d > 0.0:
            ec += table_p[6] * d ** (e_exp + 1.0) / (e_exp + 1.0)
        for i in range(gf.shape[1]):
            eg += (gf[k, i, 0] ** 2 + gf[k, i, 1] ** 2) / (2.0 * gk[i])
    pot = m * table_p[1] * pc_disp[2] + table_p[2] * pt_disp[2]
    out[0] = ke
    out[1] = el
    out[2] = pz
    out[3] = ec
    out[4] = eg
    out[5] = pot


@njit(cache=CACHE)
def _first_bad(pc_disp, vc, lam, xi, xid, gf, vch, table_p, cinfo, rot, c_body, d_rim):
    """(status, variable index) of the first non-finite or out-of-bound state, or (0, -1).

    Variable indices: 0–2 table CoM displacement, 3–5 table velocity, 6–8 angular
    momentum, 9 + 12k + a tube k displacement (a < 6) / velocity (a ≥ 6),
    45 + k contact k GMS forces, 48 + c amplifier channel c, 52 + k contact k overlap,
    55 + k contact k at the rim.
    """
    for j in range(3):
        if not math.isfinite(pc_disp[j]):
            return 1, j
        if not math.isfinite(vc[j]):
            return 1, 3 + j
        if not math.isfinite(lam[j]):
            return 1, 6 + j
    for k in range(3):
        for a in range(6):
            if not math.isfinite(xi[k, a]):
                return 1, 9 + 12 * k + a
            if not math.isfinite(xid[k, a]):
                return 1, 9 + 12 * k + 6 + a
        for i in range(gf.shape[1]):
            if not (math.isfinite(gf[k, i, 0]) and math.isfinite(gf[k, i, 1])):
                return 1, 45 + k
    for c in range(4):
        if not math.isfinite(vch[c]):
            return 1, 48 + c
    bu = table_p[11]
    for j in range(3):
        if abs(pc_disp[j]) > bu:
            return 2, j
    for k in range(3):
        for a in range(3, 6):
            if abs(xi[k, a]) > bu:
                return 2, 9 + 12 * k + a
        if cinfo[k, 0] > table_p[12]:
            return 2, 52 + k
    # rim: the contact direction in the body frame must stay below the flat face
    for k in range(3):
        zb = 0.0
        for j in range(3):
            zb += rot[j, 2] * d_rim[k, j]
        if zb > 0.0:
            return 3, 55 + k
    return 0, -1


@njit(cache=CACHE)
def _is_quiet(
    t, f_table, tau_com, w_tube, minv, jinv, rot, m, lever_t, lever_b, gf, gst, gnu, gk, fn,
    cinfo, table_p, gms_p, vch, vslow, vfast, wt, wv, wn, widx, amp_p, quiet_acc, quiet_load,
    quiet_volt, dt_coarse, scr,
):  # fmt: skip
    """True if a coarse step is safe now: every GMS element sticks with a margin to its static
    capacity ν_i μ_s F_N that lasts ``quiet_load`` coarse steps at its present loading rate
    k_i|v|, no body accelerates faster than ``quiet_acc`` [m/s²]
    (table rotation and tube-top rotation times their levers), and no amplifier channel
    would move more than ``quiet_volt`` [V] in a coarse step, nor its fast path or output
    lag still be settling by more than that."""
    mu_s = gms_p[1] * (1.0 - abs(gms_p[7]))  # the asymmetry's weaker direction
    kn_tangent = table_p[6] * table_p[7]  # × δ^(e−1) below: normal stiffness [N/m]
    for k in range(3):
        if table_p[7] != 1.0 and cinfo[k, 0] > 0.0:
            kn_tangent = table_p[6] * table_p[7] * cinfo[k, 0] ** (table_p[7] - 1.0)
        vrel = math.sqrt(cinfo[k, 2] ** 2 + cinfo[k, 3] ** 2)
        fn_rate = abs(kn_tangent * cinfo[k, 1])  # |dF_N/dt| [N/s]
        for i in range(gf.shape[1]):
            if gst[k, i] == 0:
                return False
            # margin to breakaway must outlast quiet_load coarse steps at the present rates
            # of the element's load (k_i|v|) and of its capacity (ν_i μ_s |dF_N/dt|)
            margin = gnu[i] * mu_s * fn[k] - math.sqrt(gf[k, i, 0] ** 2 + gf[k, i, 1] ** 2)
            rate = gk[i] * vrel + gnu[i] * mu_s * fn_rate
            if margin < quiet_load * rate * dt_coarse:
                return False
    a2 = (f_table[0] ** 2 + f_table[1] ** 2 + f_table[2] ** 2) / (m * m)
    if a2 > quiet_acc * quiet_acc:
        return False
    # angular acceleration of the table: R J⁻¹ Rᵀ τ (body inverse inertia), times the radius
    tb = scr[13]
    for a in range(3):
        tb[a] = rot[0, a] * tau_com[0] + rot[1, a] * tau_com[1] + rot[2, a] * tau_com[2]
    al2 = 0.0
    for a in range(3):
        s = jinv[a, 0] * tb[0] + jinv[a, 1] * tb[1] + jinv[a, 2] * tb[2]
        al2 += s * s
    if al2 * lever_t * lever_t > quiet_acc * quiet_acc:
        return False
    for k in range(3):
        ar2 = 0.0
        at2 = 0.0
        for a in range(6):
            s = 0.0
            for b in range(6):
                s += minv[k, a, b] * w_tube[k, b]
            if a < 3:
                ar2 += s * s
            else:
                at2 += s * s
        if math.sqrt(at2) + math.sqrt(ar2) * lever_b > quiet_acc:
            return False
    gain = amp_p[0]
    tau = amp_p[1]
    ideal = amp_p[2] > 0.5
    ulim = amp_p[3]
    for c in range(4):
        i = widx[c]
        u = pwl_value(wt[c], wv[c], wn[c], i, t)
        if i + 1 < wn[c]:  # input change over the coarse step
            u1 = pwl_value(wt[c], wv[c], wn[c], advance_index(wt[c], wn[c], i, t + dt_coarse),
                            t + dt_coarse)  # fmt: skip
            u1 = min(ulim, max(-ulim, u1))
            if gain * abs(u1 - u) > quiet_volt:
                return False
        u = min(ulim, max(-ulim, u))
        if not ideal and abs(gain * u - vch[c]) * dt_coarse / tau > quiet_volt:
            return False
        if not ideal and abs(amp_p[4] * gain * u - vfast[c]) > quiet_volt:
            return False
        if not ideal and amp_p[6] > 0.0 and abs(vslow[c] + vfast[c] - vch[c]) > quiet_volt:
            return False  # the output lag's transient
    return True


@njit(cache=CACHE, nogil=True)
def run_full_model(state, model, drive, t0, t_end, step_p, recording, cancel):
    """Integrate from t0 to t_end [s] (see module docstring); records at recording.t_out.
    Runs without the GIL and returns status 4 within 4096 steps of ``cancel[0]`` becoming
    non-zero (another thread's Ctrl-C: :func:`turntable_env.interrupt.call_interruptibly`).

    Args (:mod:`turntable_env.kernel_types`):
        state: :class:`~turntable_env.kernel_types.FullState`, modified in place.
        model: :class:`~turntable_env.kernel_types.FullArrays`.
        drive: :class:`~turntable_env.kernel_types.DriveArrays`, one row per channel
            (A, B, C, Z), breakpoint times in s.
        step_p: (dt_fine, dt_coarse, quiet_len, quiet_load, quiet_volt, hold) selects the
            step (see "Adaptive step" in the module docstring).
        recording: :class:`~turntable_env.kernel_types.FullRecording`:

            state[i]   = (t, table-centre displacement (3), rotation vector (3), ω (3),
                          channel voltages (4))
            contact[i] = per contact k: (normal force, friction x, y, slip speed, n stick,
                          overlap)
            energy[i]  = (kinetic, tube elastic, piezo, contact, GMS, gravity+preload,
                          W_elec, D_friction, D_tube, D_contact, gross electrical |W|)
            xi[i]      = tube-top displacements (3, 6)

    Returns (status, t, variable index, records written, steps taken, coarse steps).
    """
    pc_disp, vc, rot, lam, xi, xid = (
        state.pc_disp, state.vc, state.rot, state.lam, state.xi, state.xid
    )  # fmt: skip
    gf, gst, vch, acc = state.gf, state.gst, state.vch, state.acc
    vslow, vfast = state.amp_slow, state.amp_fast
    table_p, jinv, c_body = model.table_p, model.jinv, model.c_body
    d_nom, r0 = model.d_nom, model.r0
    basis_ref, mtube, minv, ktop, dtop = (
        model.basis_ref, model.mtube, model.minv, model.ktop, model.dtop
    )  # fmt: skip
    bcoup, cs, qchan, gnu, gk = model.bcoup, model.cs, model.qchan, model.gnu, model.gk
    qsign = model.qsign
    gms_p, amp_p, amp_rate = model.gms_p, model.amp_p, model.amp_rate
    wt, wv, wn = drive.times, drive.values, drive.count
    t_out, rec_state, rec_contact = recording.t_out, recording.state, recording.contact
    rec_energy, rec_xi = recording.energy, recording.xi
    ne = gf.shape[1]
    n_out = t_out.shape[0]
    omega = np.empty(3)
    pt_disp = np.empty(3)
    vt = np.empty(3)
    tmp = np.empty(3)
    scr = np.zeros((16, 3))  # scratch rows of the helpers (no allocation per step)
    rot_scr = np.empty((3, 3))
    cinfo = np.zeros((3, 5))
    cn = np.zeros((3, 3))
    cx = np.zeros((3, 3))
    cy = np.zeros((3, 3))
    crc = np.zeros((3, 3))
    crt = np.zeros((3, 3))
    w_tube = np.zeros((3, 6))
    f_table = np.zeros(3)
    tau_com = np.zeros(3)
    fn = np.zeros(3)
    ff = np.zeros((3, 2))
    vq = np.zeros((3, 4))
    qch = np.zeros((3, 4))
    qch_new = np.zeros((3, 4))
    vq_new = np.zeros((3, 4))
    df = np.zeros((ne, 2))
    was = np.zeros(ne, dtype=np.int64)
    energies = np.zeros(6)
    widx = np.zeros(4, dtype=np.int64)
    m = table_p[0]
    tau_amp = amp_p[1]
    gain = amp_p[0]
    ideal = amp_p[2] > 0.5
    ulim = amp_p[3]
    a_fast = amp_p[4]
    t_fast = amp_p[5]
    t_lag = amp_p[6]
    d_rim = d_nom  # the rim check uses the nominal contact directions
    dt_fine = step_p[0]
    dt_coarse = step_p[1]
    quiet_acc = step_p[2] / (dt_coarse * dt_coarse)  # largest quiet acceleration [m/s²]
    quiet_load = step_p[3]
    quiet_volt = step_p[4]
    hold = step_p[5]
    lever_t = table_p[3]  # table radius: angular → contact acceleration [m]
    lever_b = 0.0  # tube top → ball centre (seat height) [m]
    for j in range(3):
        lever_b += r0[0, j] * r0[0, j]
    lever_b = math.sqrt(lever_b)
    fine_until = t0
    n_coarse = 0

    t = t0
    for c in range(4):
        widx[c] = advance_index(wt[c], wn[c], 0, t)
    quadrant_voltages(vch, qchan, qsign, vq)
    _charges(xi, vq, bcoup, cs, qch)

    # kinematics and forces at t0
    _omega(rot, jinv, lam, omega, scr)
    _kinematics(
        pc_disp, vc, rot, omega, c_body, xi, xid, d_nom, r0, basis_ref, table_p, pt_disp, vt,
        cinfo, cn, cx, cy, crc, crt, scr,
    )  # fmt: skip
    contact_forces(
        xi, xid, vq, ktop, dtop, bcoup, cinfo, cn, cx, cy, crc, crt, gf, gst, gk, table_p,
        gms_p, rot, c_body, w_tube, f_table, tau_com, fn, ff, scr,
    )  # fmt: skip
    i_out = 0
    n_steps = 0
    while True:
        # ---- record ------------------------------------------------------------------
        while i_out < n_out and t_out[i_out] <= t + 1e-15:
            _stored_energies(
                pc_disp,
                vc,
                lam,
                omega,
                xi,
                xid,
                vq,
                mtube,
                ktop,
                cs,
                cinfo,
                gf,
                gk,
                table_p,
                pt_disp,
                energies,
            )
            rv = log_so3_nb(rot)
            rec_state[i_out, 0] = t
            for j in range(3):
                rec_state[i_out, 1 + j] = pt_disp[j]
                rec_state[i_out, 4 + j] = rv[j]
                rec_state[i_out, 7 + j] = omega[j]
            for c in range(4):
                rec_state[i_out, 10 + c] = vch[c]
            for k in range(3):
                nst = 0
                for i in range(ne):
                    nst += gst[k, i]
                rec_contact[i_out, k, 0] = fn[k]
                rec_contact[i_out, k, 1] = ff[k, 0]
                rec_contact[i_out, k, 2] = ff[k, 1]
                rec_contact[i_out, k, 3] = math.sqrt(cinfo[k, 2] ** 2 + cinfo[k, 3] ** 2)
                rec_contact[i_out, k, 4] = nst
                rec_contact[i_out, k, 5] = cinfo[k, 0]
                for a in range(6):
                    rec_xi[i_out, k, a] = xi[k, a]
            for a in range(6):
                rec_energy[i_out, a] = energies[a]
            e_gms = energies[4]
            rec_energy[i_out, 6] = acc[0]
            rec_energy[i_out, 7] = acc[1] - e_gms  # interface work − stored = dissipated
            rec_energy[i_out, 8] = acc[2]
            rec_energy[i_out, 9] = acc[3]
            rec_energy[i_out, 10] = acc[4]
            i_out += 1
        if t >= t_end - 1e-15:
            break
        # ---- step size: coarse while quiet, fine otherwise; land on breakpoints -------
        quiet = dt_coarse > dt_fine and t >= fine_until
        if quiet:
            quiet = _is_quiet(
                t, f_table, tau_com, w_tube, minv, jinv, rot, m, lever_t, lever_b, gf, gst,
                gnu, gk, fn, cinfo, table_p, gms_p, vch, vslow, vfast, wt, wv, wn, widx, amp_p,
                quiet_acc, quiet_load, quiet_volt, dt_coarse, scr,
            )  # fmt: skip
            if not quiet:
                fine_until = t + hold
        dt_max = dt_coarse if quiet else dt_fine
        n_coarse += 1 if quiet else 0
        t_next = min(t + dt_max, t_end)
        if i_out < n_out and t_out[i_out] < t_next:
            t_next = t_out[i_out]
        for c in range(4):
            i = widx[c]
            if i + 1 < wn[c] and wt[c, i + 1] < t_next and wt[c, i + 1] > t:
                t_next = wt[c, i + 1]
        dt = t_next - t
        if dt <= 0.0:
            # a jump sits exactly at t: step past it by moving the indices
            for c in range(4):
                widx[c] = advance_index(wt[c], wn[c], widx[c], t)
            t_next = min(t + dt_max, t_end)
            if i_out < n_out and t_out[i_out] < t_next:
                t_next = t_out[i_out]
            for c in range(4):
                i = widx[c]
                if i + 1 < wn[c] and wt[c, i + 1] < t_next:
                    t_next = wt[c, i + 1]
            dt = t_next - t
            if dt <= 0.0:
                break
        h = 0.5 * dt
        # ---- 1. half kick ---------------------------------------------------------------
        _kick(h, m, f_table, tau_com, minv, w_tube, vc, lam, xid)
        # ---- 2. drift -------------------------------------------------------------------
        _omega(rot, jinv, lam, omega, scr)
        for j in range(3):
            pc_disp[j] += dt * vc[j]
            tmp[j] = dt * omega[j]
        rotate_left_inplace(rot, tmp, rot_scr)
        _omega(rot, jinv, lam, omega, scr)
        for k in range(3):
            for a in range(6):
                xi[k, a] += dt * xid[k, a]
        # dissipation in the tube dampers with the half-step velocities
        for k in range(3):
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += dtop[k, a, b] * xid[k, b]
                acc[2] += dt * xid[k, a] * s
        # ---- 3. contacts at t_{n+1} with half-step velocities ------------------------
        _kinematics(
            pc_disp, vc, rot, omega, c_body, xi, xid, d_nom, r0, basis_ref, table_p, pt_disp, vt,
            cinfo, cn, cx, cy, crc, crt, scr,
        )  # fmt: skip
        for k in range(3):
            vx = cinfo[k, 2]
            vy = cinfo[k, 3]
            fn_k, _fe_k, fd_k = _normal_force(table_p, cinfo[k, 0], cinfo[k, 1])
            acc[3] += dt * fd_k * cinfo[k, 1]
            # interface work with the old element forces (first half of F̄·Δx)
            fx_old = 0.0
            fy_old = 0.0
            c_t = gms_p[5]
            for i in range(ne):
                fx_old += gf[k, i, 0]
                fy_old += gf[k, i, 1]
                if gst[k, i] == 1:
                    c_t += gms_p[6] * gk[i]
            if fn_k <= 0.0:
                for i in range(ne):  # contact lost: the elements let go
                    gf[k, i, 0] = 0.0
                    gf[k, i, 1] = 0.0
                    gst[k, i] = 1
            else:
                m_k = _asymmetry(gms_p, crt[k], cx[k], cy[k], vx, vy)
                gms2d_rates(
                    gf[k],
                    gst[k],
                    vx,
                    vy,
                    fn_k,
                    gnu,
                    gk,
                    gms_p[0],
                    gms_p[1] * m_k,
                    gms_p[2] * m_k,
                    gms_p[3],
                    gms_p[4],
                    df,
                )
                for i in range(ne):
                    gf[k, i, 0] += dt * df[i, 0]
                    gf[k, i, 1] += dt * df[i, 1]
                for i in range(ne):
                    was[i] = gst[k, i]
                gms2d_update(gf[k], gst[k], vx, vy, fn_k, gnu, gms_p[1] * m_k, gms_p[2] * m_k,
                             gms_p[3], gms_p[4])  # fmt: skip
                # no element holds more than its share ν_i|s(v)|: a sticking one when F_N
                # drops, and one that broke away inside this step (its overshoot k_i v Δt
                # past the breakaway instant would be a first-order error in Δt)
                smag = stribeck_magnitude(math.sqrt(vx * vx + vy * vy), fn_k, gms_p[1] * m_k,
                                          gms_p[2] * m_k, gms_p[3], gms_p[4])  # fmt: skip
                for i in range(ne):
                    if gst[k, i] == 1 or was[i] == 1:
                        fm = math.sqrt(gf[k, i, 0] ** 2 + gf[k, i, 1] ** 2)
                        cap = gnu[i] * smag
                        if fm > cap:
                            gf[k, i, 0] *= cap / fm
                            gf[k, i, 1] *= cap / fm
            fx_new = 0.0
            fy_new = 0.0
            for i in range(ne):
                fx_new += gf[k, i, 0]
                fy_new += gf[k, i, 1]
            acc[1] += dt * (
                (0.5 * (fx_old + fx_new) + c_t * vx) * vx
                + (0.5 * (fy_old + fy_new) + c_t * vy) * vy
            )
        # ---- 4. amplifier ---------------------------------------------------------------
        t_mid = t + h
        for c in range(4):
            widx[c] = advance_index(wt[c], wn[c], widx[c], t_mid)
            u = pwl_value(wt[c], wv[c], wn[c], widx[c], t_mid)
            if ideal:
                ie = advance_index(wt[c], wn[c], widx[c], t_next)
                u = pwl_value(wt[c], wv[c], wn[c], ie, t_next)
            u = min(ulim, max(-ulim, u))
            if ideal:
                vch[c] = gain * u
                vslow[c] = vch[c]  # kept equal: no stale path for a later amplifier
            else:
                vch[c], vslow[c], vfast[c] = amplifier_hold_step(
                    vch[c], vslow[c], vfast[c], u, dt, gain, tau_amp, amp_rate[c], a_fast, t_fast,
                    t_lag,
                )
        quadrant_voltages(vch, qchan, qsign, vq_new)
        _charges(xi, vq_new, bcoup, cs, qch_new)
        for k in range(3):
            for q in range(4):
                dw = 0.5 * (vq[k, q] + vq_new[k, q]) * (qch_new[k, q] - qch[k, q])
                acc[0] += dw
                acc[4] += abs(dw)
                vq[k, q] = vq_new[k, q]
                qch[k, q] = qch_new[k, q]
        # ---- 5. forces at t_{n+1}, second half kick -------------------------------------
        contact_forces(
            xi, xid, vq, ktop, dtop, bcoup, cinfo, cn, cx, cy, crc, crt, gf, gst, gk, table_p,
            gms_p, rot, c_body, w_tube, f_table, tau_com, fn, ff, scr,
        )  # fmt: skip
        _kick(h, m, f_table, tau_com, minv, w_tube, vc, lam, xid)
        _omega(rot, jinv, lam, omega, scr)
        t = t_next
        n_steps += 1
        for c in range(4):
            widx[c] = advance_index(wt[c], wn[c], widx[c], t)
        chk = 0.0  # NaN/inf propagate into this sum: a cheap test every step
        for j in range(3):
            chk += vc[j] + lam[j] + pc_disp[j]
        for k in range(3):
            for a in range(6):
                chk += xid[k, a] + xi[k, a]
            for i in range(ne):
                chk += gf[k, i, 0] + gf[k, i, 1]
        if not math.isfinite(chk) or n_steps % 64 == 0 or t >= t_end - 1e-15:
            st, var = _first_bad(
                pc_disp, vc, lam, xi, xid, gf, vch, table_p, cinfo, rot, c_body, d_rim
            )
            if st != 0:
                return st, t, var, i_out, n_steps, n_coarse
        if n_steps % 4096 == 0 and cancel[0] != 0:
            return 4, t, -1, i_out, n_steps, n_coarse
    return 0, t, -1, i_out, n_steps, n_coarse
