"""Typed contracts of the compiled kernels: what crosses into them and back.

Each kernel takes a few NamedTuples of arrays instead of dozens of positional arguments
(as stable-baselines3's ``type_aliases.py`` names what its buffers pass around); numba
compiles them as records, so the fields are read by name inside the kernels too.

* :class:`DriveArrays` — piecewise-linear amplifier inputs, one row per turntable or
  channel (both integrators);
* :class:`ReducedState`, :class:`ReducedArrays`, :class:`ReducedRecording` — the reduced
  per-axis integrator (:func:`turntable_env.reduced_kernel.run_reduced_batch`);
* :class:`FullState`, :class:`FullArrays`, :class:`FullRecording` — the 3-D integrator
  (:func:`turntable_env.integrator.run_full_model`).

Units are SI; the packed scalar rows are documented where they are filled
(:mod:`turntable_env.reduced`, :mod:`turntable_env.model`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = [
    "DriveArrays",
    "FullArrays",
    "FullRecording",
    "FullState",
    "ReducedArrays",
    "ReducedRecording",
    "ReducedState",
]


class DriveArrays(NamedTuple):
    """Breakpoints of piecewise-linear inputs, one row each.

    Attributes:
        times: (rows, n) breakpoint times — grid units (reduced kernel) or s (3-D kernel).
        values: (rows, n) amplifier input at the breakpoints [V].
        count: (rows,) breakpoints used in each row.
    """

    times: np.ndarray
    values: np.ndarray
    count: np.ndarray


class ReducedState(NamedTuple):
    """State of N reduced turntables (modified in place by the kernel).

    Attributes:
        y: (N, n_y) θ [rad], θ̇ [rad/s], u1 [m], u̇1 [m/s], u2 [m], u̇2 [m/s] (table angle and
            the two driving tubes' contact-point displacements); n_y = 48 with the sphere's
            translation: the 24 coordinates of
            :meth:`~turntable_env.reduced.ReducedModel.translation_matrices` (θ, u1, u2,
            the table's translation and tilts, the three tube tops' twists), each with
            its rate (:class:`~turntable_env.reduced.TranslationParameters`).
        volt: (N,) amplifier output on the channel [V].
        f: (N, 4, n_e) GMS element forces [N]: the two driving contacts' along their
            driving directions, then (with the translation) their components along the
            axis n, each element a 2-vector in its contact plane (§3.3.2); zero in the
            per-axis form.
        st: (N, 2, n_e) 1 stick / 0 slip.
        n: (N,) time in grid units.
        vslow, vfast: (N,) the amplifier's slow and fast paths [V]
            (:mod:`turntable_env.amplifier`; without a fast path vfast = 0, and vslow = volt
            unless an output lag trails it).
    """

    y: np.ndarray
    volt: np.ndarray
    f: np.ndarray
    st: np.ndarray
    n: np.ndarray
    vslow: np.ndarray
    vfast: np.ndarray


class ReducedArrays(NamedTuple):
    """Model arrays of N reduced turntables, stacked along axis 0 (see
    :meth:`turntable_env.reduced.ReducedModel` for each field's derivation).

    ``mech`` [J, k_g, ρ1, ρ2, M1, M2, K1, K2, D1, D2, g1, g2, F_N1, F_N2]; ``gms`` [C, μ_s,
    μ_c, v_s, δ, σ2, β_t, α (sliding-direction asymmetry)]; ``amp`` [gain, τ, ideal, input
    limit, rate, fast fraction, τ_f, output lag τ_o] (as
    :meth:`~turntable_env.amplifier.Amplifier.kernel_row`); ``ctl`` [quiet length
    [m], largest rung while an element slips, 1 where a landing keeps the rung
    (``ReducedModel.resume_rung``) else 0]; ``nu``, ``kk`` the GMS elements; ``lvl``,
    ``nlvl`` stick-configuration levels; ``phi_*``, ``gam_*`` exact step matrices per
    configuration and rung; ``qs``, ``modal_*`` the quasi-static and modal projections of
    the all-stick system; ``q2`` = A⁻¹Q[:, 0], ``modal_v``, ``modal_lam`` its eigenvectors and
    eigenvalues (the analytic all-stick step); ``ring_frac`` the largest step as a fraction
    of the fastest ringing mode's period; ``use_modal`` whether all-stick phases take the
    analytic step (else the ladder, as a check); ``gam_*`` and ``qs`` take the inputs
    (V, V̇, f1, f2) of the per-axis form, (V, V̇, f1, f2, g1, g2) with the translation (the
    driving contacts' constant forces along n after theirs; ``qs`` without V̇); ``srow``
    (2, 2, n_y) each driving contact's slip and slip rate as rows over the state, (4, 2,
    n_y) with the translation (rows 2 and 3: the slips along n), ``nrow`` (2, n_y + 2) its normal
    force less F_N as a row over (y, V, V̇) (zero without the sphere's translation).
    """

    mech: np.ndarray
    gms: np.ndarray
    nu: np.ndarray
    kk: np.ndarray
    amp: np.ndarray
    ctl: np.ndarray
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
    modal_om_max: np.ndarray
    q2: np.ndarray
    modal_v: np.ndarray
    modal_lam: np.ndarray
    srow: np.ndarray
    nrow: np.ndarray
    ring_frac: float
    use_modal: bool


class ReducedRecording(NamedTuple):
    """Where the reduced kernel stops and what it records.

    Attributes:
        n_end: (N,) grid time to advance to.
        out_every: (N,) record every this many grid units.
        rec: (N, n_out, N_REC) records (fields ``turntable_env.reduced_kernel.REC_FIELDS``).
        n_rec: (N,) records written.
        counters: (N, 4) accepted steps, rejected steps, status of the last call,
            evaluations of the all-stick analytic solution.
    """

    n_end: np.ndarray
    out_every: np.ndarray
    rec: np.ndarray
    n_rec: np.ndarray
    counters: np.ndarray


class FullState(NamedTuple):
    """State of the 3-D model (modified in place by the kernel).

    Attributes:
        pc_disp: CoM displacement from the nominal pose [m] (the table centre's is
        pc_disp + (I − R)c); vc: CoM velocity [m/s]; rot: (3, 3) table orientation; lam:
        angular momentum about the CoM [kg·m²/s]; xi, xid: (3, 6) tube-top twists [rad, m]
        and rates; gf: (3, n_e, 2) GMS element forces [N]; gst: (3, n_e) 1 stick / 0 slip;
        vch: (4,) channel voltages [V]; acc: (5,) energy accumulators [J] (W_elec,
        W_interface, D_tube, D_contact, gross |W_elec|); amp_slow, amp_fast: (4,) each
        channel amplifier's slow and fast paths [V] (:mod:`turntable_env.amplifier`).
    """

    pc_disp: np.ndarray
    vc: np.ndarray
    rot: np.ndarray
    lam: np.ndarray
    xi: np.ndarray
    xid: np.ndarray
    gf: np.ndarray
    gst: np.ndarray
    vch: np.ndarray
    acc: np.ndarray
    amp_slow: np.ndarray
    amp_fast: np.ndarray

    def copy(self) -> FullState:
        """A deep copy (the kernel modifies the arrays in place)."""
        return FullState(*(np.array(a, copy=True) for a in self))


class FullArrays(NamedTuple):
    """Packed model of the 3-D turntable (filled by :class:`turntable_env.model.TurntableModel`).

    ``table_p`` [m, g, P, R_table, R_ball, r_nom, k_c, e, d_c, w_ball, w_table, bound_u,
    bound_δ]; ``gms_p`` [C, μ_s, μ_c, v_s, δ, σ2, β_t, α, axis (3)] (α, axis: the sliding-direction
    asymmetry, :meth:`~turntable_env.model.TurntableModel.run`); ``amp_p`` [gain, τ, ideal, input
    limit, fast fraction, τ_f, output lag τ_o]; ``amp_rate`` (4,) slew limit per channel
    [V/s]; the rest are the bodies' and tubes' matrices in the world frame.
    """

    table_p: np.ndarray
    jinv: np.ndarray
    c_body: np.ndarray
    d_nom: np.ndarray
    r0: np.ndarray
    basis_ref: np.ndarray
    mtube: np.ndarray
    minv: np.ndarray
    ktop: np.ndarray
    dtop: np.ndarray
    bcoup: np.ndarray
    cs: np.ndarray
    qchan: np.ndarray
    qsign: np.ndarray
    gnu: np.ndarray
    gk: np.ndarray
    gms_p: np.ndarray
    amp_p: np.ndarray
    amp_rate: np.ndarray


class FullRecording(NamedTuple):
    """Output times and record arrays of the 3-D kernel (n_out rows each).

    Attributes:
        t_out: record times [s]; state: (n_out, 14) (t, centre displacement, rotation
        vector, ω, channel voltages); contact: (n_out, 3, 6) per contact (normal force,
        friction x, y, slip speed, sticking elements, overlap); energy: (n_out, 11);
        xi: (n_out, 3, 6) tube-top displacements.
    """

    t_out: np.ndarray
    state: np.ndarray
    contact: np.ndarray
    energy: np.ndarray
    xi: np.ndarray
