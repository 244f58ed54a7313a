"""The reduced per-axis model written the plain way: a NumPy right-hand side and
``scipy.integrate.solve_ivp`` — the baseline a user would otherwise write.

Same equations and parameters as :mod:`turntable_env.reduced` (it takes a
:class:`~turntable_env.reduced.ReducedModel`), but:

* GMS stick/slip is decided inside the right-hand side from the current state
  (stick while |F_i| < ν_i|s(v)| or the element is unloading, Eq. 2.24–2.25), as a
  smooth-ODE user would write it, with no event location;
* the amplifier is dV/dt = clip((G u − V)/τ, ±slew) (ideal: V = G u);
* the integration restarts at every drive breakpoint (the input has kinks and jumps
  there) with LSODA, which switches to a stiff method when the contacts stick.

Used by ``turntable bench`` for the speed ratio; not meant for production runs.
"""

from __future__ import annotations

import itertools

import numpy as np
import scipy.integrate

from .drive import DriveSignal, Waveform
from .reduced import ReducedModel
from .validation import check_positive

__all__ = ["simulate_scipy"]


def simulate_scipy(
    model: ReducedModel,
    drive: DriveSignal | Waveform,
    duration: float,
    *,
    rtol: float = 1e-6,
    method: str = "RK45",
    output_dt: float = 1e-5,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate the reduced model with ``solve_ivp``; returns (time [s], angle [rad])."""
    dur = check_positive("duration", duration)
    check_positive("rtol", rtol)
    ar = model.packed
    ap = model.axis_params
    nu, kk = ar["nu"], ar["kk"]
    c_gms, mu_s, mu_c, v_s, delta, sigma2, beta_t, _alpha = ar["gms"]  # α: 0 in a model
    gain, tau, ideal, ulim, rate = ar["amp"][:5]
    if ar["amp"][5] != 0.0:
        raise ValueError("model: the SciPy baseline has the first-order amplifier only")
    ne = kk.size
    wave = model.full.drive_waveforms({model.axis: drive})[model.axis]
    lever = np.array(ap.lever)
    m_t = np.array(ap.tube_mass)
    k_t = np.array(ap.tube_stiffness)
    d_t = np.array(ap.tube_damping)
    g_t = np.array(ap.tube_gain)
    f_n = np.array(ap.normal_force)

    def u_at(t: float) -> float:
        return float(np.clip(wave(t)[()], -ulim, ulim))

    def rhs(t: float, s: np.ndarray) -> np.ndarray:
        th, thd = s[0], s[1]
        u = s[2:6:2]
        ud = s[3:6:2]
        volt = gain * u_at(t) if ideal > 0.5 else s[6]
        forces = s[7:].reshape(2, ne)
        xd = ud - lever * thd
        smag = f_n * (mu_c + (mu_s - mu_c) * np.exp(-((np.abs(xd) / v_s) ** delta)))
        cap = nu[None, :] * smag[:, None]
        loading = forces * xd[:, None] > 0.0
        slip = (np.abs(forces) >= cap) & loading
        dforce = np.where(
            slip,
            c_gms * (cap * np.sign(xd)[:, None] - forces) / smag[:, None],
            kk[None, :] * xd[:, None],
        )
        stuck_k = np.sum(np.where(slip, 0.0, kk[None, :]), axis=1)
        fric = forces.sum(axis=1) + (sigma2 + beta_t * stuck_k) * xd
        out = np.empty_like(s)
        out[0] = thd
        out[1] = (np.sum(lever * fric) - ap.gravity_stiffness * th) / ap.inertia
        out[2:6:2] = ud
        out[3:6:2] = (k_t * (g_t * volt - u) - d_t * ud - fric) / m_t
        out[6] = 0.0 if ideal > 0.5 else np.clip((gain * u_at(t) - s[6]) / tau, -rate, rate)
        out[7:] = dforce.reshape(-1)
        return out

    s0 = np.zeros(7 + 2 * ne)
    v0 = gain * u_at(0.0)
    s0[2:6:2] = g_t * v0
    s0[6] = v0
    atol = np.concatenate([[1e-12, 1e-8, 1e-15, 1e-9, 1e-15, 1e-9, 1e-6], np.full(2 * ne, 1e-9)])
    edges = np.unique(np.clip(np.concatenate([[0.0], wave.times, [dur]]), 0.0, dur))
    t_out = np.arange(0.0, dur + 0.5 * output_dt, output_dt)
    ts: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    for a, b in itertools.pairwise(edges):
        if b <= a:
            continue
        sel = t_out[(t_out >= a) & (t_out < b)]
        sol = scipy.integrate.solve_ivp(
            rhs, (a, b), s0, method=method, rtol=rtol, atol=atol, t_eval=np.append(sel, b)
        )
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed at t = {sol.t[-1]:.6g} s: {sol.message}")
        ts.append(sol.t[:-1])
        ys.append(sol.y[0, :-1])
        s0 = sol.y[:, -1]
    return np.concatenate(ts), np.concatenate(ys)
