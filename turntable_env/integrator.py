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

from numba import njit

from .amplifier import (
    AMP_FAST,
    AMP_GAIN,
    AMP_IDEAL,
    AMP_LIMIT,
    AMP_T_FAST,
    AMP_TAU,
    amplifier_hold_step,
)
from .friction.gms2d import gms2d_rates, gms2d_update
from .friction.kernels import stribeck_magnitude
from .kernel_cache import CACHE
from .kernel_types import (
    ACC_D_CONTACT,
    ACC_D_TUBE,
    ACC_W_ELEC,
    ACC_W_GROSS,
    ACC_W_INTERFACE,
    GMS_BETA_T,
    GMS_DELTA,
    GMS_MU_C,
    GMS_MU_S,
    GMS_SIGMA2,
    GMS_V_S,
    TP_BOUND_DELTA,
    TP_BOUND_U,
    TP_D_C,
    TP_EXPONENT,
    TP_G,
    TP_K_C,
    TP_MASS,
    TP_PRELOAD,
    TP_R_BALL,
    TP_R_NOM,
    TP_W_BALL,
    TP_W_TABLE,
)
from .screw import log_so3_nb, rotate_left_inplace

__all__ = ["STATUS_NAMES", "run_full_model"]

STATUS_NAMES = {0: "ok", 1: "non-finite", 2: "diverging", 3: "rim"}

# packed rows are read through the named columns of turntable_env.kernel_types (table_p,
# gms_p, acc) and turntable_env.amplifier (amp_p: Amplifier.kernel_row's layout)


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
def contact_kinematics(model, xi, xid, w):
    """Contact geometry and velocities at the tube-top twists ``xi`` and rates ``xid``,
    the table-centre displacement ``w.pt_disp``, velocity ``w.vt`` and rotation rate
    ``w.omega`` (Eq. 3.24–3.26).

    Fills per contact k: w.cinfo[k] = (overlap δ [m], δ̇ [m/s], v_x, v_y in the plane [m/s],
    table lever ρ [m]); w.cn[k] = normal n (table centre → ball); w.cx, w.cy = plane basis
    (Eq. 3.26); w.crc[k] = tube-top → contact point; w.crt[k] = table centre → contact point.
    Scratch rows 0–3 of ``w.scr``.
    """
    table_p, d_nom, r0, basis_ref = model.table_p, model.d_nom, model.r0, model.basis_ref
    pt_disp, vt, omega = w.pt_disp, w.vt, w.omega
    cinfo, cn, cx, cy, crc, crt, scr = w.cinfo, w.cn, w.cx, w.cy, w.crc, w.crt, w.scr
    r_ball = table_p[TP_R_BALL]
    r_nom = table_p[TP_R_NOM]
    w_ball = table_p[TP_W_BALL]
    w_table = table_p[TP_W_TABLE]
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
def _normal_force(table_p, overlap, rate):
    """(total, elastic, damping) normal force [N]; zero when separated, never pulling."""
    if overlap <= 0.0:
        return 0.0, 0.0, 0.0
    fe = table_p[TP_K_C] * overlap ** table_p[TP_EXPONENT]
    fd = table_p[TP_D_C] * rate
    if fe + fd < 0.0:
        fd = -fe
    return fe + fd, fe, fd


@njit(cache=CACHE)
def _tube_wrenches(model, xi, xid, w):
    """Spring, damper and piezo wrenches on the tube tops (Eq. 2.11), before the contacts."""
    ktop, dtop, bcoup = model.ktop, model.dtop, model.bcoup
    for k in range(3):
        for a in range(6):
            s = 0.0
            for b in range(6):
                s -= ktop[k, a, b] * xi[k, b] + dtop[k, a, b] * xid[k, b]
            for q in range(4):
                s += bcoup[k, a, q] * w.vq[k, q]
            w.w_tube[k, a] = s


@njit(cache=CACHE)
def contact_forces(model, xi, xid, gf, gst, rot, w):
    """Wrenches on the tube tops (world, about the top) and force / torque (about the CoM)
    on the table, from the contacts of :func:`contact_kinematics` (normal force, Hertz with
    damping; friction, the GMS elements ``gf``, ``gst`` plus viscous and micro-slip damping,
    Eq. 2.24–2.26) and the quadrant voltages ``w.vq`` [V]; scratch rows 4–8 of ``w.scr``."""
    table_p, gms_p, gk, c_body = model.table_p, model.gms_p, model.gk, model.c_body
    cinfo, cn, cx, cy, crc, crt = w.cinfo, w.cn, w.cx, w.cy, w.crc, w.crt
    w_tube, f_table, tau_com, fn_out, ff_out, scr = (
        w.w_tube, w.f_table, w.tau_com, w.fn, w.ff, w.scr
    )  # fmt: skip
    m = table_p[TP_MASS]
    g = table_p[TP_G]
    preload = table_p[TP_PRELOAD]
    sigma2 = gms_p[GMS_SIGMA2]
    tmp = scr[4]
    fw = scr[5]
    tau_c = scr[6]  # torque about the table centre
    for j in range(3):
        tau_c[j] = 0.0
        f_table[j] = 0.0
    f_table[2] = -m * g - preload
    _tube_wrenches(model, xi, xid, w)
    for k in range(3):
        fn, _fe, _fd = _normal_force(table_p, cinfo[k, 0], cinfo[k, 1])
        fn_out[k] = fn
        # friction force on the table, in the plane (sum of GMS elements + viscous)
        c_t = sigma2  # viscous + micro-damping of the sticking elements [N·s/m]
        for i in range(gf.shape[1]):
            if gst[k, i] == 1:
                c_t += gms_p[GMS_BETA_T] * gk[i]
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
def _omega(model, state, w):
    """ω = R J⁻¹ Rᵀ L (world) into ``w.omega``; scratch rows 9–10."""
    rot, lam, jinv, out, scr = state.rot, state.lam, model.jinv, w.omega, w.scr
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
def _kinematics(model, state, w):
    """Table-centre displacement and velocity, then the contacts (:func:`contact_kinematics`);
    scratch rows 0–3 and 11–12 of ``w.scr``."""
    rot, c_body, omega, scr = state.rot, model.c_body, w.omega, w.scr
    rc = scr[11]
    tmp = scr[12]
    _table_centre(state.pc_disp, rot, c_body, w.pt_disp)
    for j in range(3):
        rc[j] = rot[j, 0] * c_body[0] + rot[j, 1] * c_body[1] + rot[j, 2] * c_body[2]
    _cross(omega, rc, tmp)
    for j in range(3):
        w.vt[j] = state.vc[j] - tmp[j]  # v_centre = v_CoM + ω × (p_centre − p_CoM)
    contact_kinematics(model, state.xi, state.xid, w)


@njit(cache=CACHE)
def _forces(model, state, w):
    """Forces on every body at the present state (:func:`contact_forces`)."""
    contact_forces(model, state.xi, state.xid, state.gf, state.gst, state.rot, w)


@njit(cache=CACHE)
def _kick(model, state, w, h):
    """Half kick over h [s]: table momentum and angular momentum, tube-top velocities."""
    m, minv, vc, lam, xid = model.table_p[TP_MASS], model.minv, state.vc, state.lam, state.xid
    for j in range(3):
        vc[j] += h * w.f_table[j] / m
        lam[j] += h * w.tau_com[j]
    for k in range(3):
        for a in range(6):
            s = 0.0
            for b in range(6):
                s += minv[k, a, b] * w.w_tube[k, b]
            xid[k, a] += h * s


@njit(cache=CACHE)
def _stored_energies(model, state, w):
    """w.energies = (kinetic, tube elastic, piezo electric, contact normal, GMS,
    gravity+preload) [J]."""
    table_p, mtube, ktop, cs, gk = model.table_p, model.mtube, model.ktop, model.cs, model.gk
    vc, lam, omega, xi, xid, gf = state.vc, state.lam, w.omega, state.xi, state.xid, state.gf
    vq, cinfo, out = w.vq, w.cinfo, w.energies
    m = table_p[TP_MASS]
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
    e_exp = table_p[TP_EXPONENT]
    for k in range(3):
        d = cinfo[k, 0]
        if d > 0.0:
            ec += table_p[TP_K_C] * d ** (e_exp + 1.0) / (e_exp + 1.0)
        for i in range(gf.shape[1]):
            eg += (gf[k, i, 0] ** 2 + gf[k, i, 1] ** 2) / (2.0 * gk[i])
    pot = m * table_p[TP_G] * state.pc_disp[2] + table_p[TP_PRELOAD] * w.pt_disp[2]
    out[0] = ke
    out[1] = el
    out[2] = pz
    out[3] = ec
    out[4] = eg
    out[5] = pot


@njit(cache=CACHE)
def _first_bad(model, state, w):
    """(status, variable index) of the first non-finite or out-of-bound state, or (0, -1).

    Variable indices: 0–2 table CoM displacement, 3–5 table velocity, 6–8 angular
    momentum, 9 + 12k + a tube k displacement (a < 6) / velocity (a ≥ 6),
    45 + k contact k GMS forces, 48 + c amplifier channel c, 52 + k contact k overlap,
    55 + k contact k at the rim (the nominal contact directions).
    """
    pc_disp, vc, lam, xi, xid = state.pc_disp, state.vc, state.lam, state.xi, state.xid
    gf, table_p, cinfo, rot, d_rim = state.gf, model.table_p, w.cinfo, state.rot, model.d_nom
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
        if not math.isfinite(state.vch[c]):
            return 1, 48 + c
    bu = table_p[TP_BOUND_U]
    for j in range(3):
        if abs(pc_disp[j]) > bu:
            return 2, j
    for k in range(3):
        for a in range(3, 6):
            if abs(xi[k, a]) > bu:
                return 2, 9 + 12 * k + a
        if cinfo[k, 0] > table_p[TP_BOUND_DELTA]:
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
def _contacts_stick(model, state, w, ctl):
    """Every GMS element sticks with a margin to its static capacity ν_i μ_s F_N that
    lasts ``ctl.quiet_load`` coarse steps at its present loading rate k_i|v|."""
    table_p, gms_p, gnu, gk = model.table_p, model.gms_p, model.gnu, model.gk
    gf, gst, cinfo, fn = state.gf, state.gst, w.cinfo, w.fn
    mu_s = gms_p[GMS_MU_S]
    kn_tangent = table_p[TP_K_C] * table_p[TP_EXPONENT]  # × δ^(e−1) below: normal stiffness
    for k in range(3):
        if table_p[TP_EXPONENT] != 1.0 and cinfo[k, 0] > 0.0:
            kn_tangent = table_p[TP_K_C] * table_p[TP_EXPONENT] * cinfo[k, 0] ** (
                table_p[TP_EXPONENT] - 1.0
            )  # fmt: skip
        vrel = math.sqrt(cinfo[k, 2] ** 2 + cinfo[k, 3] ** 2)
        fn_rate = abs(kn_tangent * cinfo[k, 1])  # |dF_N/dt| [N/s]
        for i in range(gf.shape[1]):
            if gst[k, i] == 0:
                return False
            # margin to breakaway must outlast quiet_load coarse steps at the present rates
            # of the element's load (k_i|v|) and of its capacity (ν_i μ_s |dF_N/dt|)
            margin = gnu[i] * mu_s * fn[k] - math.sqrt(gf[k, i, 0] ** 2 + gf[k, i, 1] ** 2)
            rate = gk[i] * vrel + gnu[i] * mu_s * fn_rate
            if margin < ctl.quiet_load * rate * ctl.dt_coarse:
                return False
    return True


@njit(cache=CACHE)
def _bodies_calm(model, state, w, ctl):
    """No body accelerates faster than ``ctl.quiet_acc`` [m/s²]: the table, its rotation
    times its radius, each tube top's translation and rotation times its lever."""
    m, jinv, minv, rot = model.table_p[TP_MASS], model.jinv, model.minv, state.rot
    f_table, tau_com, w_tube = w.f_table, w.tau_com, w.w_tube
    quiet_acc = ctl.quiet_acc
    a2 = (f_table[0] ** 2 + f_table[1] ** 2 + f_table[2] ** 2) / (m * m)
    if a2 > quiet_acc * quiet_acc:
        return False
    # angular acceleration of the table: R J⁻¹ Rᵀ τ (body inverse inertia), times the radius
    tb = w.scr[13]
    for a in range(3):
        tb[a] = rot[0, a] * tau_com[0] + rot[1, a] * tau_com[1] + rot[2, a] * tau_com[2]
    al2 = 0.0
    for a in range(3):
        s = jinv[a, 0] * tb[0] + jinv[a, 1] * tb[1] + jinv[a, 2] * tb[2]
        al2 += s * s
    if al2 * ctl.lever_table * ctl.lever_table > quiet_acc * quiet_acc:
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
        if math.sqrt(at2) + math.sqrt(ar2) * ctl.lever_ball > quiet_acc:
            return False
    return True


@njit(cache=CACHE)
def _amplifier_calm(model, state, w, drive, t, ctl):
    """No amplifier channel would move more than ``ctl.quiet_volt`` [V] in a coarse step,
    nor its fast path still be settling by more than that."""
    amp_p, wt, wv, wn, widx = model.amp_p, drive.times, drive.values, drive.count, w.widx
    gain = amp_p[AMP_GAIN]
    tau = amp_p[AMP_TAU]
    ideal = amp_p[AMP_IDEAL] > 0.5
    ulim = amp_p[AMP_LIMIT]
    dt_coarse, quiet_volt = ctl.dt_coarse, ctl.quiet_volt
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
        if not ideal and abs(gain * u - state.vch[c]) * dt_coarse / tau > quiet_volt:
            return False
        if not ideal and abs(amp_p[AMP_FAST] * gain * u - state.amp_fast[c]) > quiet_volt:
            return False
    return True


@njit(cache=CACHE)
def _is_quiet(model, state, w, drive, t, ctl):
    """True if a coarse step is safe now (the adaptive step of the module docstring):
    :func:`_contacts_stick`, :func:`_bodies_calm` and :func:`_amplifier_calm`."""
    if not _contacts_stick(model, state, w, ctl):
        return False
    if not _bodies_calm(model, state, w, ctl):
        return False
    return _amplifier_calm(model, state, w, drive, t, ctl)


@njit(cache=CACHE)
def _record(model, state, w, rec, i, t):
    """Row i of the recording at time t [s] (:class:`~.kernel_types.FullRecording`)."""
    _stored_energies(model, state, w)
    energies, acc, gst, xi, cinfo = w.energies, state.acc, state.gst, state.xi, w.cinfo
    rv = log_so3_nb(state.rot)
    rec.state[i, 0] = t
    for j in range(3):
        rec.state[i, 1 + j] = w.pt_disp[j]
        rec.state[i, 4 + j] = rv[j]
        rec.state[i, 7 + j] = w.omega[j]
    for c in range(4):
        rec.state[i, 10 + c] = state.vch[c]
    for k in range(3):
        nst = 0
        for e in range(gst.shape[1]):
            nst += gst[k, e]
        rec.contact[i, k, 0] = w.fn[k]
        rec.contact[i, k, 1] = w.ff[k, 0]
        rec.contact[i, k, 2] = w.ff[k, 1]
        rec.contact[i, k, 3] = math.sqrt(cinfo[k, 2] ** 2 + cinfo[k, 3] ** 2)
        rec.contact[i, k, 4] = nst
        rec.contact[i, k, 5] = cinfo[k, 0]
        for a in range(6):
            rec.xi[i, k, a] = xi[k, a]
    for a in range(6):
        rec.energy[i, a] = energies[a]
    e_gms = energies[4]
    rec.energy[i, 6] = acc[ACC_W_ELEC]
    rec.energy[i, 7] = acc[ACC_W_INTERFACE] - e_gms  # interface work − stored = dissipated
    rec.energy[i, 8] = acc[ACC_D_TUBE]
    rec.energy[i, 9] = acc[ACC_D_CONTACT]
    rec.energy[i, 10] = acc[ACC_W_GROSS]


@njit(cache=CACHE)
def _step_end(drive, w, t, t_end, dt_max, t_out, i_out):
    """The next step's end: t + dt_max, cut at t_end, at the next output time and at the
    next drive breakpoint (steps land on them)."""
    wt, wn, widx = drive.times, drive.count, w.widx
    t_next = min(t + dt_max, t_end)
    if i_out < t_out.shape[0] and t_out[i_out] < t_next:
        t_next = t_out[i_out]
    for c in range(4):
        i = widx[c]
        if i + 1 < wn[c] and wt[c, i + 1] < t_next and wt[c, i + 1] > t:
            t_next = wt[c, i + 1]
    if t_next - t > 0.0:
        return t_next
    # a jump sits exactly at t: step past it by moving the indices
    for c in range(4):
        widx[c] = advance_index(wt[c], wn[c], widx[c], t)
    t_next = min(t + dt_max, t_end)
    if i_out < t_out.shape[0] and t_out[i_out] < t_next:
        t_next = t_out[i_out]
    for c in range(4):
        i = widx[c]
        if i + 1 < wn[c] and wt[c, i + 1] < t_next:
            t_next = wt[c, i + 1]
    return t_next


@njit(cache=CACHE)
def _drift(model, state, w, dt):
    """Phase 2: positions with the half-step velocities, the table orientation by the
    exponential map R ← exp(Δt ω̃)R, and the tube dampers' dissipation."""
    pc_disp, vc, xi, xid, acc, dtop = (
        state.pc_disp, state.vc, state.xi, state.xid, state.acc, model.dtop
    )  # fmt: skip
    _omega(model, state, w)
    for j in range(3):
        pc_disp[j] += dt * vc[j]
        w.tmp[j] = dt * w.omega[j]
    rotate_left_inplace(state.rot, w.tmp, w.rot_scr)
    _omega(model, state, w)
    for k in range(3):
        for a in range(6):
            xi[k, a] += dt * xid[k, a]
    # dissipation in the tube dampers with the half-step velocities
    for k in range(3):
        for a in range(6):
            s = 0.0
            for b in range(6):
                s += dtop[k, a, b] * xid[k, b]
            acc[ACC_D_TUBE] += dt * xid[k, a] * s


@njit(cache=CACHE)
def _gms_contact(model, state, w, k, fn_k, dt):
    """One contact's GMS elements over dt [s] with the half-step slip velocity (Eq.
    2.24–2.26; stick: F_i += k_i Δx exactly), the transitions, the elements' caps; returns
    the interface work F̄·Δx [J]."""
    gms_p, gnu, gk = model.gms_p, model.gnu, model.gk
    gf, gst, df, was = state.gf, state.gst, w.df, w.was
    ne = gf.shape[1]
    vx = w.cinfo[k, 2]
    vy = w.cinfo[k, 3]
    # interface work with the old element forces (first half of F̄·Δx)
    fx_old = 0.0
    fy_old = 0.0
    c_t = gms_p[GMS_SIGMA2]
    for i in range(ne):
        fx_old += gf[k, i, 0]
        fy_old += gf[k, i, 1]
        if gst[k, i] == 1:
            c_t += gms_p[GMS_BETA_T] * gk[i]
    if fn_k <= 0.0:
        for i in range(ne):  # contact lost: the elements let go
            gf[k, i, 0] = 0.0
            gf[k, i, 1] = 0.0
            gst[k, i] = 1
    else:
        gms2d_rates(gf[k], gst[k], vx, vy, fn_k, gnu, gk, gms_p, df)
        for i in range(ne):
            gf[k, i, 0] += dt * df[i, 0]
            gf[k, i, 1] += dt * df[i, 1]
        for i in range(ne):
            was[i] = gst[k, i]
        gms2d_update(gf[k], gst[k], vx, vy, fn_k, gnu, gms_p)
        # no element holds more than its share ν_i|s(v)|: a sticking one when F_N
        # drops, and one that broke away inside this step (its overshoot k_i v Δt
        # past the breakaway instant would be a first-order error in Δt)
        smag = stribeck_magnitude(
            math.sqrt(vx * vx + vy * vy), fn_k, gms_p[GMS_MU_S], gms_p[GMS_MU_C],
            gms_p[GMS_V_S], gms_p[GMS_DELTA],
        )  # fmt: skip
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
    return dt * (
        (0.5 * (fx_old + fx_new) + c_t * vx) * vx + (0.5 * (fy_old + fy_new) + c_t * vy) * vy
    )


@njit(cache=CACHE)
def _contacts(model, state, w, dt):
    """Phase 3: the contacts at t_{n+1} with the half-step velocities — kinematics, the
    normal damping's dissipation and every contact's GMS elements (:func:`_gms_contact`)."""
    _kinematics(model, state, w)
    acc, cinfo = state.acc, w.cinfo
    for k in range(3):
        fn_k, _fe_k, fd_k = _normal_force(model.table_p, cinfo[k, 0], cinfo[k, 1])
        acc[ACC_D_CONTACT] += dt * fd_k * cinfo[k, 1]
        acc[ACC_W_INTERFACE] += _gms_contact(model, state, w, k, fn_k, dt)


@njit(cache=CACHE)
def _amplifier(model, state, w, drive, t, dt, t_next):
    """Phase 4: each channel advanced exactly with its input at mid-step (first-order stage
    with its fast path and the slew limit, §4.1.2; the instant source takes the input at
    the step's end), the quadrant voltages and charges, and the electrical work Σ V̄ Δq."""
    amp_p, wt, wv, wn, widx = model.amp_p, drive.times, drive.values, drive.count, w.widx
    vch, vslow, vfast, acc = state.vch, state.amp_slow, state.amp_fast, state.acc
    gain = amp_p[AMP_GAIN]
    ideal = amp_p[AMP_IDEAL] > 0.5
    ulim = amp_p[AMP_LIMIT]
    t_mid = t + 0.5 * dt
    for c in range(4):
        widx[c] = advance_index(wt[c], wn[c], widx[c], t_mid)
        u = pwl_value(wt[c], wv[c], wn[c], widx[c], t_mid)
        if ideal:
            ie = advance_index(wt[c], wn[c], widx[c], t_next)
            u = pwl_value(wt[c], wv[c], wn[c], ie, t_next)
        u = min(ulim, max(-ulim, u))
        if ideal:
            vch[c] = gain * u
        else:
            vch[c], vslow[c], vfast[c] = amplifier_hold_step(
                vch[c], vslow[c], vfast[c], u, dt, gain, amp_p[AMP_TAU], model.amp_rate[c],
                amp_p[AMP_FAST], amp_p[AMP_T_FAST],
            )  # fmt: skip
    quadrant_voltages(vch, model.qchan, model.qsign, w.vq_new)
    _charges(state.xi, w.vq_new, model.bcoup, model.cs, w.qch_new)
    for k in range(3):
        for q in range(4):
            dw = 0.5 * (w.vq[k, q] + w.vq_new[k, q]) * (w.qch_new[k, q] - w.qch[k, q])
            acc[ACC_W_ELEC] += dw
            acc[ACC_W_GROSS] += abs(dw)
            w.vq[k, q] = w.vq_new[k, q]
            w.qch[k, q] = w.qch_new[k, q]


@njit(cache=CACHE)
def _diverged(state, n_steps, t, t_end):
    """Whether the state needs the full check now: a NaN/inf anywhere (they propagate into
    one sum, a cheap test every step), every 64th step, and at the end."""
    chk = 0.0
    for j in range(3):
        chk += state.vc[j] + state.lam[j] + state.pc_disp[j]
    gf = state.gf
    for k in range(3):
        for a in range(6):
            chk += state.xid[k, a] + state.xi[k, a]
        for i in range(gf.shape[1]):
            chk += gf[k, i, 0] + gf[k, i, 1]
    return not math.isfinite(chk) or n_steps % 64 == 0 or t >= t_end - 1e-15


@njit(cache=CACHE, nogil=True)
def run_full_model(state, model, drive, t0, t_end, ctl, recording, w, cancel):
    """Integrate from t0 to t_end [s] (see module docstring); records at recording.t_out.
    Runs without the GIL and returns status 4 within 4096 steps of ``cancel[0]`` becoming
    non-zero (another thread's Ctrl-C: :func:`turntable_env.interrupt.call_interruptibly`).

    Args (:mod:`turntable_env.kernel_types`):
        state: :class:`~turntable_env.kernel_types.FullState`, modified in place.
        model: :class:`~turntable_env.kernel_types.FullArrays`.
        drive: :class:`~turntable_env.kernel_types.DriveArrays`, one row per channel
            (A, B, C, Z), breakpoint times in s.
        ctl: :class:`~turntable_env.kernel_types.StepControl` (see "Adaptive step" in the
            module docstring).
        recording: :class:`~turntable_env.kernel_types.FullRecording`:

            state[i]   = (t, table-centre displacement (3), rotation vector (3), ω (3),
                          channel voltages (4))
            contact[i] = per contact k: (normal force, friction x, y, slip speed, n stick,
                          overlap)
            energy[i]  = (kinetic, tube elastic, piezo, contact, GMS, gravity+preload,
                          W_elec, D_friction, D_tube, D_contact, gross electrical |W|)
            xi[i]      = tube-top displacements (3, 6)
        w: :class:`~turntable_env.kernel_types.FullWork` (zeroed).
        cancel: (1,) int64, non-zero to stop.

    Returns (status, t, variable index, records written, steps taken, coarse steps).
    """
    wt, wn, widx, t_out = drive.times, drive.count, w.widx, recording.t_out
    fine_until = t0
    n_coarse = 0
    t = t0
    for c in range(4):
        widx[c] = advance_index(wt[c], wn[c], 0, t)
    quadrant_voltages(state.vch, model.qchan, model.qsign, w.vq)
    _charges(state.xi, w.vq, model.bcoup, model.cs, w.qch)
    # kinematics and forces at t0
    _omega(model, state, w)
    _kinematics(model, state, w)
    _forces(model, state, w)
    i_out = 0
    n_steps = 0
    while True:
        # ---- record -------------------------------------------------------------------
        while i_out < t_out.shape[0] and t_out[i_out] <= t + 1e-15:
            _record(model, state, w, recording, i_out, t)
            i_out += 1
        if t >= t_end - 1e-15:
            break
        # ---- step size: coarse while quiet, fine otherwise; land on breakpoints --------
        quiet = ctl.dt_coarse > ctl.dt_fine and t >= fine_until
        if quiet:
            quiet = _is_quiet(model, state, w, drive, t, ctl)
            if not quiet:
                fine_until = t + ctl.hold
        dt_max = ctl.dt_coarse if quiet else ctl.dt_fine
        n_coarse += 1 if quiet else 0
        t_next = _step_end(drive, w, t, t_end, dt_max, t_out, i_out)
        dt = t_next - t
        if dt <= 0.0:
            break
        h = 0.5 * dt
        _kick(model, state, w, h)  # ---- 1. half kick
        _drift(model, state, w, dt)  # ---- 2. drift
        _contacts(model, state, w, dt)  # ---- 3. contacts at t_{n+1}, half-step velocities
        _amplifier(model, state, w, drive, t, dt, t_next)  # ---- 4. amplifier
        _forces(model, state, w)  # ---- 5. forces at t_{n+1}, second half kick
        _kick(model, state, w, h)
        _omega(model, state, w)
        t = t_next
        n_steps += 1
        for c in range(4):
            widx[c] = advance_index(wt[c], wn[c], widx[c], t)
        if _diverged(state, n_steps, t, t_end):
            st, var = _first_bad(model, state, w)
            if st != 0:
                return st, t, var, i_out, n_steps, n_coarse
        if n_steps % 4096 == 0 and cancel[0] != 0:
            return 4, t, -1, i_out, n_steps, n_coarse
    return 0, t, -1, i_out, n_steps, n_coarse
