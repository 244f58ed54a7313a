"""The per-axis model with the sphere's translation and the contacts' normal forces: a
fixed-step reference for the per-axis kernel's translation (issue 32 item 1).

The per-axis model (:mod:`turntable_env.reduced`) keeps the table's rotation about one axis
and the two driving tubes' bending, at the static normal force F_N. The 3-D model steps
asymmetrically (+154 / −225 nm per period at ±90 V, 100 Hz, a = 0.95) where the per-axis
model steps 202 nm both ways (``python experiments/axial_stroke.py``). Three things the
per-axis model leaves out are kept here, all derived from the 3-D model, nothing fitted
(:class:`~turntable_env.reduced.TranslationParameters`, which ``ReducedModel(translation=
True)`` integrates exactly between transitions, holding the axis contact stuck):

* the sphere's translation x in the plane normal to the axis n, along the driving tubes'
  axes d_1, d_2 (orthonormal with n: §3.1's orthogonal tubes). Tube 1's friction acts
  along e_1 = n × d_1 = ±d_2, so a tangential force at one driving contact pushes the
  sphere along the other's normal, and the translation moves the table's contact points
  tangentially (slip s_k = u_k − ρθ − e_k·x);
* each driving contact's normal force, F_N + k_n (d_k·x − s_ax V) + d_c (d_k·ẋ − s_ax V̇),
  with k_n the Hertz stiffness at F_N (Eq. 3.21's k_c δ^e linearised, 1.5 F_N/δ_0) in
  series with the tube's axial stiffness, and s_ax the tube's axial stroke per channel
  volt (the quadrant wiring, §3.1). It scales the contact's Stribeck level (Eq. 2.13);
* the contact on the axis (tube n), which the translation slides tangentially: tube n's
  bending at its contact point (condensed as the driving tubes') and two 1-D GMS
  contacts along d_1 and d_2 at its static F_N (the 2-D law of Eq. 3.27 taken per
  direction).

The table's inertia couples rotation and translation through the centre of mass, 3R/8
below the centre (App. C): T = ½J_nθ̇² + m θ̇ (n × c)·ẋ + ½m|ẋ|².

Integration: semi-implicit Euler at a fixed step (default 5 ns) with the per-axis
kernel's GMS law (``gms_element_step``, Eq. 2.24–2.25) and transition rules; the channel
voltage is the per-axis model's own amplifier output, interpolated linearly. With the
translation held (``--variant frozen``) it is the per-axis model, which checks the
prototype; ``--variant axis_contact_stuck`` holds the axis contact stuck, as the kernel
does; ``no_stroke`` removes the axial stroke (from the 3-D model too).

    python experiments/sphere_translation.py [--variant translation|no_stroke|frozen]
        [--amplitude 20 90 200] [--frequency 100 2000] [--a 0.95] [--dt 5e-9]

prints, for each case both ways, the 3-D model's step, the prototype's, the per-axis
model's and the per-axis kernel's with the translation, their differences, and the median
and largest |difference| over the cases.
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
from turntable_env.friction.kernels import gms_element_step, stribeck_magnitude
from turntable_env.reduced import ReducedModel, simulate_reduced
from turntable_env.simulation import simulate, stepping_drive

# generalised coordinates q: θ, u_1, u_2, x_1, x_2, b_1, b_2 (rad, then m)
# contacts: 0, 1 the driving tubes (along e_1, e_2), 2, 3 tube n's contact along d_1, d_2


class Arrays(NamedTuple):
    """What crosses into :func:`_run` (SI units; q as in the module's coordinates)."""

    minv: np.ndarray  # (7, 7) inverse mass matrix [1/kg, 1/(kg m²) ...]
    kq: np.ndarray  # (7, 7) stiffness of the springs other than the normal ones [N/m ...]
    cq: np.ndarray  # (7, 7) their damping [N s/m ...]
    bq: np.ndarray  # (7,) the tubes' bending force per channel volt [N/V]
    slip: np.ndarray  # (4, 7) each contact's slip (tube point − table point) over q
    kn: float  # a driving contact's normal stiffness [N/m]
    dc: float  # its normal damping [N s/m]
    s_ax: float  # the tubes' axial stroke per channel volt, ball along d_k [m/V]
    fn0: float  # static normal force F_N [N]
    fn_axis: float  # normal force of the contact on the axis [N] (huge: it never slips)
    nu: np.ndarray  # GMS element fractions ν_i [-]
    kk: np.ndarray  # GMS element stiffnesses k_i [N/m]
    gms: np.ndarray  # C [N/s], μ_s, μ_c, v_s [m/s], δ of Eq. 2.13–2.25
    beta_t: float  # micro-damping of the sticking elements [s]


@njit(cache=False)  # its argument type lives in this script, loaded under two module names
def _run(t_v, v_v, dt, n_steps, arr, frozen, out_every):
    """Fixed-step integration; returns (times, q records, normal forces)."""
    minv, kq, cq, bq, slip_rows = arr.minv, arr.kq, arr.cq, arr.bq, arr.slip
    kn, dc, s_ax, fn0, nu, kk, gms = arr.kn, arr.dc, arr.s_ax, arr.fn0, arr.nu, arr.kk, arr.gms
    beta_t = arr.beta_t
    nq = minv.shape[0]
    q = np.zeros(nq)
    qd = np.zeros(nq)
    ne = nu.shape[0]
    f = np.zeros((4, ne))
    st = np.ones((4, ne), dtype=np.int64)
    n_out = n_steps // out_every + 1
    rec_t = np.empty(n_out)
    rec_q = np.empty((n_out, nq))
    rec_fn = np.empty((n_out, 2))
    force = np.empty(nq)
    slip_prev = np.zeros(4)
    fn = np.empty(4)
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
        # normal forces [N]: driving contacts from the translation and the axial stroke
        for k in range(2):
            if frozen:
                fn[k] = fn0
            else:
                fn[k] = fn0 + kn * (q[3 + k] - s_ax * volt) + dc * (qd[3 + k] - s_ax * vdot)
                if fn[k] < 0.0:
                    fn[k] = 0.0
        fn[2] = arr.fn_axis
        fn[3] = arr.fn_axis
        if step % out_every == 0:
            rec_t[j] = t
            for a in range(nq):
                rec_q[j, a] = q[a]
            rec_fn[j, 0] = fn[0]
            rec_fn[j, 1] = fn[1]
            j += 1
        if step == n_steps:
            break
        # elastic, damping and drive forces
        for a in range(nq):
            s = bq[a] * volt
            for c in range(nq):
                s -= kq[a, c] * q[c] + cq[a, c] * qd[c]
            force[a] = s
        if not frozen:  # normal forces on the table along d_k (the ball pushes it away)
            for k in range(2):
                force[3 + k] -= fn[k] - fn0
        # friction: slip (tube point − table point) and its rate per contact
        for c in range(4):
            if frozen and c >= 2:
                continue
            x = 0.0
            xd = 0.0
            for a in range(nq):
                x += slip_rows[c, a] * q[a]
                xd += slip_rows[c, a] * qd[a]
            dx = x - slip_prev[c]
            slip_prev[c] = x
            lvl = stribeck_magnitude(xd, fn[c], gms[1], gms[2], gms[3], gms[4])
            decay = math.exp(-gms[0] * dt / lvl) if lvl > 0.0 else 0.0
            sg = 1.0 if xd > 0.0 else (-1.0 if xd < 0.0 else 0.0)
            ftot = 0.0
            ct = 0.0
            for i in range(ne):
                fi = gms_element_step(f[c, i], st[c, i], kk[i], dx, nu[i] * lvl * sg, decay)
                if st[c, i] == 1:
                    if abs(fi) >= nu[i] * lvl and fi * xd > 0.0:
                        st[c, i] = 0
                        cap = nu[i] * lvl
                        fi = cap if fi > 0.0 else -cap
                    else:
                        ct += beta_t * kk[i]
                elif fi * xd <= 0.0:
                    st[c, i] = 1
                f[c, i] = fi
                ftot += fi
            ftot += ct * xd
            for a in range(nq):  # F on the table, −F on the tube: −F ∂slip/∂q
                force[a] -= ftot * slip_rows[c, a]
        for a in range(nq):  # semi-implicit Euler
            acc = 0.0
            for c in range(nq):
                acc += minv[a, c] * force[c]
            qd[a] += dt * acc
        if frozen:
            for a in range(3, nq):
                qd[a] = 0.0
        for a in range(nq):
            q[a] += dt * qd[a]
    return rec_t[:j], rec_q[:j], rec_fn[:j]


def build(rm: ReducedModel) -> dict:
    """The prototype's matrices for ``rm``'s axis: the kernel's linear part
    (:meth:`~turntable_env.reduced.ReducedModel.translation_matrices`, from the 3-D model)
    less what the prototype integrates itself, the normal springs and the axis contact.
    Returns the mass matrix ``mass``, the :class:`Arrays` ``arrays`` (``minv`` that of
    ``mass``), ``fn0`` and the translation's parameters ``translation``."""
    ps, ap = rm.params, rm.axis_params
    moved = ReducedModel(ps, rm.axis, model=rm.full, translation=True)
    tr = moved.translation_params
    mass, kq, cq, bq, _bvd = moved.translation_matrices()
    nq = mass.shape[0]
    # the driving contacts' normal springs act in _run (they also set the Stribeck level),
    # and the contact on the axis is a GMS contact there (the kernel holds it stuck)
    for i in range(2):
        kq[3 + i, 3 + i] -= tr.normal_stiffness
        cq[3 + i, 3 + i] -= tr.normal_damping
        bq[3 + i] = 0.0
        sb = np.zeros(nq)
        sb[5 + i], sb[3 + i] = 1.0, -1.0
        kq -= tr.axis_contact_stiffness * np.outer(sb, sb)
        cq -= tr.axis_contact_damping * np.outer(sb, sb)
    slip = np.zeros((4, nq))
    for i in range(2):
        slip[i, 0] = -ap.lever[i]
        slip[i, 1 + i] = 1.0
        slip[i, 3] = -tr.direction[i][0]
        slip[i, 4] = -tr.direction[i][1]
        slip[2 + i, 5 + i] = 1.0
        slip[2 + i, 3 + i] = -1.0
    fr = ps.friction
    gms = np.array([fr.C, fr.stribeck.mu_s, fr.stribeck.mu_c, fr.stribeck.v_s,
                    fr.stribeck.delta])  # fmt: skip
    fn0 = float(ps.contact.preload)
    arrays = Arrays(np.linalg.inv(mass), kq, cq, bq, slip, tr.normal_stiffness,
                    tr.normal_damping, tr.stroke, fn0, fn0, np.asarray(fr.nu, float),
                    np.asarray(fr.k, float), gms,
                    float(ps.contact.tangential_damping))  # fmt: skip
    return {"mass": mass, "arrays": arrays, "fn0": fn0, "translation": tr}


VARIANTS = ("translation", "no_stroke", "frozen", "axis_contact_stuck")
GRID_V = (20.0, 90.0, 200.0)  # tube volts [V]
GRID_F = (100.0, 2000.0)  # [Hz]


def run(amplitude: float, frequency: float, a: float, *, variant: str = "translation",
        dt: float = 5e-9, periods: int = 3) -> dict:  # fmt: skip
    """Mean |step| per period [nm] of the prototype (``variant``: with the translation,
    the same without the axial stroke, or the translation held, which is the per-axis
    model) and of the per-axis model, and the prototype's mean normal force of each
    driving contact at the ramps' ends [N] (amplitude in tube volts, adapted amplifier)."""
    if variant not in VARIANTS:
        raise ValueError(f"variant={variant!r}: one of {', '.join(VARIANTS)}")
    drive, ps = stepping_drive("real", amplitude=amplitude / 45.0, frequency=frequency,
                               periods=periods, a=a, amplifier="adapted")  # fmt: skip
    rm = ReducedModel(ps, "B")
    ref = simulate_reduced(ps, drive, model=rm, output_dt=1e-7)
    kernel = simulate_reduced(ps, drive, model=ReducedModel(ps, "B", translation=True),
                              output_dt=1e-7)  # fmt: skip
    p = build(rm)
    mass = p["mass"].copy()
    frozen = variant == "frozen"
    if frozen:  # the translation held: the rotation's inertia alone, J_n
        mass[0, 3:5] = mass[3:5, 0] = 0.0
    arr = p["arrays"]._replace(
        minv=np.linalg.inv(mass),
        s_ax=0.0 if variant == "no_stroke" else p["arrays"].s_ax,
        fn_axis=1e9 if variant == "axis_contact_stuck" else p["fn0"],
    )
    n_steps = round(drive.duration / dt)
    out_every = max(1, round(1e-6 / dt))
    t, qrec, fnrec = _run(ref.time, ref.voltage, dt, n_steps, arr, frozen, out_every)
    proto = replace(ref, time=t, angle_rad=qrec[:, 0])
    ends = ref.period_starts[1:] - (1.0 - a) / frequency  # ramp ends [s]
    fn_end = [float(np.mean(np.interp(ends, t, fnrec[:, k]))) for k in range(2)]
    return {"prototype_nm": 1e9 * proto.step_size, "per_axis_nm": 1e9 * ref.step_size,
            "kernel_nm": 1e9 * kernel.step_size,
            "ramp_end_normal_N": fn_end, "translation": p["translation"]}  # fmt: skip


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


def full_step(amplitude: float, frequency: float, a: float, *, no_stroke: bool = False,
              periods: int = 3) -> float:  # fmt: skip
    """The 3-D model's mean |step| per period [nm] (adapted amplifier, axis B, as
    ``turntable bench``'s sweep runs it); ``no_stroke``: the tubes' axial part of their
    free displacement per volt removed, bending kept (``experiments/axial_stroke.py``)."""
    drive, ps = stepping_drive("real", amplitude=amplitude / 45.0, frequency=frequency,
                               periods=periods, a=a, amplifier="adapted")  # fmt: skip
    rm = ReducedModel(ps, "B")
    if no_stroke:
        remove_axial_stroke(rm.full)
    return 1e9 * simulate(ps, drive, axis="B", model=rm.full, coarse_factor=FULL_COARSE,
                          output_dt=min(1e-5, 0.01 / frequency)).step_size  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--amplitude", type=float, nargs="+", default=list(GRID_V),
                    help="tube volts [V], each run both ways")  # fmt: skip
    ap.add_argument("--frequency", type=float, nargs="+", default=list(GRID_F), help="[Hz]")
    ap.add_argument("--a", type=float, default=0.95, help="ramp ratio, 0.5 <= a < 1")
    ap.add_argument("--dt", type=float, default=5e-9, help="fixed step [s], <= 1e-8")
    ap.add_argument("--variant", choices=VARIANTS, default="translation")
    args = ap.parse_args(argv)
    bad = [f"--amplitude {v!r}" for v in args.amplitude if not 0.0 < v <= 200.0]
    bad += [f"--frequency {v!r}" for v in args.frequency if not 1.0 <= v <= 5000.0]
    bad += [f"--a {args.a!r}"] if not 0.5 <= args.a < 1.0 else []
    bad += [f"--dt {args.dt!r}"] if not 0.0 < args.dt <= 1e-8 else []
    if bad:
        ap.error(f"{bad[0]}: out of range (amplitude 0-200 V, frequency 1-5000 Hz)")
    rows = []
    for f, v, sign in itertools.product(args.frequency, args.amplitude, (1.0, -1.0)):
        try:
            r = run(sign * v, f, args.a, variant=args.variant, dt=args.dt)
        except ValueError as exc:  # the adapted flyback does not fit the period
            print(f"{sign * v:+5.0f} {f:6.0f}  skipped, the adapted flyback does not fit the "
                  f"period ({str(exc)[:50]})")  # fmt: skip
            continue
        full = full_step(sign * v, f, args.a, no_stroke=args.variant == "no_stroke")
        rows.append((sign * v, f, r, full))
        if len(rows) == 1:
            print(r["translation"])
            print(
                f"variant {args.variant}, a = {args.a:g}, dt = {args.dt:g} s; "
                "steps [nm] per period, differences against the 3-D model"
            )
            if args.variant != "translation":
                print("(the kernel column is the kernel's translation as the env runs it, "
                      "stroke included, whatever the variant)")  # fmt: skip
            print("   V     Hz   3-D  prototype  (diff)  per-axis  (diff)    kernel  (diff)"
                  "  ramp-end F_N [N]")  # fmt: skip
        e_p, e_r = r["prototype_nm"] / full - 1.0, r["per_axis_nm"] / full - 1.0
        e_k = r["kernel_nm"] / full - 1.0
        fn = r["ramp_end_normal_N"]
        print(
            f"{sign * v:+5.0f} {f:6.0f} {full:6.1f} {r['prototype_nm']:9.1f} {e_p:+7.3f} "
            f"{r['per_axis_nm']:9.1f} {e_r:+7.3f} {r['kernel_nm']:9.1f} {e_k:+7.3f}  "
            f"{fn[0]:.3f}, {fn[1]:.3f}",
            flush=True,
        )
    if not rows:
        print("no case ran")
        return 0
    for name, key in (("prototype", "prototype_nm"), ("per-axis", "per_axis_nm"),
                      ("kernel, translation", "kernel_nm")):  # fmt: skip
        d = np.abs([r[key] / full - 1.0 for _v, _f, r, full in rows])
        print(
            f"{name}: median |diff| {100 * np.median(d):.1f} %, max {100 * d.max():.1f} %, "
            f"within 5 % {int(np.sum(d <= 0.05))} of {d.size}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
