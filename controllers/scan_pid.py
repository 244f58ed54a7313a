"""Scan-mode PID for the last nanometres, designed with python-control.

In scan mode the generator is idle and the scan offset u [V] (amplifier input, action
index 4) bends the tubes while every contact sticks: the table follows as the linear
stick plant of :mod:`turntable_env.linear`. Sampled the way the environment applies the
offset (ramp over the control interval), that plant is :func:`~turntable_env.linear.scan_plant`,
P(z) ≈ K·z⁻¹ with K = G·g/ρ = 14.7 µrad/V for the real turntable: the mechanics (first
resonance 4.7 kHz) is quasi-static at a 100 Hz control rate.

The discrete PID (error e = θ* − θ_measured [rad] → offset u [V])

    C(z) = k_p + k_i·Δt·z/(z − 1) + k_d·(z − 1)/(Δt·z)

is designed by :func:`design_scan_pid`: it maximises the crossover frequency of the loop
L = C·P subject to a phase margin and a stability margin min|1 + L| (python-control's
``stability_margins``), which bounds the detector-noise amplification as well. It runs
in incremental form (Δu from the last three errors), clipped at the amplifier's input
limit, so saturation never winds it up.

**The hold** (:meth:`ScanPID.hold`): a PID designed for crossover answers every reading,
the detector's noise and a floor vibration that rocks the reading but not the table
included, and moves the table with them (held-out seed 4's 61.6 Hz vibration, 26 nm at
R, aliased to 38 Hz by the 100 Hz control rate, moved it by more than half its amplitude
in a 2 µm move's hold: ``tests/test_controllers.py -k vibrating`` fails without the
hold). Within ``hold_error`` of the
target (:meth:`ScanPID.update`; the controllers pass 3 σ of the reading's noise, estimated
online) the offset follows the integrator u_k = u_{k−1} + g·e_k/K instead, g =
``HOLD_GAIN``: on P(z) = K·z⁻¹ the table obeys x_{k+1} = (1 − g)·x_k + g·(r − n_k), which
passes √(g/(2 − g)) = 0.38 of a white reading noise and g/|e^{jω} − (1 − g)| of a line at
ω (0.14 at Nyquist, 0.15 at 38 Hz), and settles an error within about 1/g = 4 intervals.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import control as ct
import numpy as np
import scipy.optimize

from turntable_env.validation import check_positive

HOLD_GAIN = 0.25  # the hold's integrator gain per interval [-] (ScanPID.hold)

__all__ = ["PIDGains", "ScanPID", "design_scan_pid", "loop_margins", "pid_transfer_function"]


@dataclass(frozen=True)
class PIDGains:
    """Gains of the discrete scan PID (error [rad] → offset [V]).

    Attributes:
        kp: proportional [V/rad]; ki: integral [V/(rad·s)]; kd: derivative [V·s/rad];
        dt: sample time [s]; phase_margin: [deg]; gain_margin: [-] (linear);
        stability_margin: min|1 + L| [-]; crossover: loop crossover frequency [rad/s];
        noise_gain: Σ t_k², the variance of the angle per unit variance of the
        detector's angle noise (closed loop T = L/(1 + L)); plant_gain: K, the plant's
        DC gain [rad/V] (the hold's integrator, :meth:`ScanPID.hold`).
    """

    kp: float
    ki: float
    kd: float
    dt: float
    phase_margin: float = math.nan
    gain_margin: float = math.nan
    stability_margin: float = math.nan
    crossover: float = math.nan
    noise_gain: float = math.nan
    plant_gain: float = math.nan


def pid_transfer_function(gains: PIDGains) -> ct.TransferFunction:
    """C(z) = k_p + k_i·Δt·z/(z − 1) + k_d·(z − 1)/(Δt·z) as a python-control TF."""
    dt = gains.dt
    z = ct.tf([1.0, 0.0], [1.0], dt)
    return gains.kp + gains.ki * dt * z / (z - 1) + gains.kd * (z - 1) / (dt * z)


def loop_margins(loop: ct.LTI) -> dict[str, float]:
    """Margins of a discrete loop L: phase margin [deg], stability margin min|1 + L| and
    crossover [rad/s] from python-control's ``stability_margins``; the gain margin from
    the negative-real-axis crossings of L(e^{jωΔt}) for 0 < ω ≤ π/Δt (python-control
    counts the integrator's ω → 0 limit as a crossing, and misses the one at Nyquist)."""
    _gm, pm, sm, _wpc, wgc, _wms = ct.stability_margins(loop)
    dt = float(loop.dt)
    w = np.logspace(-4.0, 0.0, 800) * math.pi / dt
    resp = np.asarray(ct.frequency_response(loop, w).complex).ravel()
    cross = np.nonzero(np.sign(resp.imag[:-1]) != np.sign(resp.imag[1:]))[0]
    gms = [
        -1.0 / r.real
        for i in cross
        for r in [
            resp[i] - resp[i].imag * (resp[i + 1] - resp[i]) / (resp[i + 1].imag - resp[i].imag)
        ]
        if r.real < 0.0
    ]
    if resp[-1].real < 0.0 and abs(resp[-1].imag) <= 1e-9 * abs(resp[-1]):
        gms.append(-1.0 / resp[-1].real)
    return {
        "gain_margin": min(gms) if gms else math.inf,
        "phase_margin_deg": float(pm),
        "stability_margin": float(sm),
        "crossover_rad_s": float(wgc),
    }


def _noise_gain(loop: ct.LTI) -> float:
    """Σ t_k² of the closed loop T = L/(1 + L) (inf when unstable)."""
    t = ct.feedback(loop, 1)
    if np.any(np.abs(ct.poles(t)) >= 1.0):
        return math.inf
    imp = ct.impulse_response(t, T=np.arange(200) * loop.dt)
    pulse = np.asarray(imp.outputs).ravel() * loop.dt  # python-control's pulse is 1/dt high
    return float(np.sum(pulse**2))


# the design's starts, normalised (k_p·K, k_i·K·Δt, k_d·K/Δt): integral action from a
# fifth to all of the error per interval, with and without proportional and derivative parts
_GRID = tuple(
    (kp, ki, kd) for kp in (0.0, 0.1) for ki in (0.2, 0.4, 0.6, 0.8, 1.0) for kd in (0.0, 0.02)
)


def _minimal(plant: ct.LTI) -> ct.LTI:
    """``plant`` as its minimal transfer function where that keeps its frequency response
    (to 1e-6 relative from 10⁻⁴ of Nyquist up to it), else ``plant`` itself: the same loop,
    cheaper margins."""
    small = ct.minreal(ct.tf(plant), 1e-6, verbose=False)
    w = np.logspace(-4.0, 0.0, 200) * math.pi / float(plant.dt)
    full = np.asarray(ct.frequency_response(plant, w).complex).ravel()
    red = np.asarray(ct.frequency_response(small, w).complex).ravel()
    return small if np.all(np.abs(red - full) <= 1e-6 * np.abs(full)) else plant


def design_scan_pid(
    plant: ct.LTI,
    *,
    phase_margin: float = 60.0,
    stability_margin: float = 0.6,
    derivative: bool = True,
    starts: Sequence[tuple[float, float, float]] | None = None,
) -> PIDGains:
    """PID gains that maximise the crossover of L = C·P with PM ≥ ``phase_margin`` [deg]
    and min|1 + L| ≥ ``stability_margin`` (0.6: sensitivity peak ≤ 1.67, which also
    guarantees GM ≥ 1/(1 − 0.6) = 2.5 and PM ≥ 35°); ValueError naming the plant's
    slowest poles where no PID meets them (the thesis's scaled set: a 6 Hz mode at
    |z| = 0.996 on the 10 ms interval).

    Args:
        plant: discrete SISO plant, offset [V] → angle [rad] (``scan_plant(...)[0, 0]``).
        derivative: include k_d in the search (False: PI).
        starts: normalised points (k_p·K, k_i·K·Δt, k_d·K/Δt) the search starts from the
            best of (default: :data:`_GRID`).

    The search runs in units normalised by the plant's DC gain K (k_p·K, k_i·K·Δt,
    k_d·K/Δt) with scipy's Nelder–Mead on a penalty for violated margins, started from the
    best point of a coarse grid (:data:`_GRID`): the penalised landscape has terraces,
    and from one fixed start the search stopped at half the crossover on the calibrated
    plant (ω_c·Δt 0.41 against 0.82), on some machines and not on others. The plant is
    first reduced to its minimal transfer function (python-control's ``minreal``; the
    sampled stick plant's poles at z ≈ 0 cancel), checked against the full one's
    frequency response.
    """
    dt = plant.dt
    if not isinstance(dt, float | int) or isinstance(dt, bool) or dt <= 0:
        raise ValueError(f"plant.dt={dt!r}: need a discrete plant with a sample time")
    check_positive("phase_margin", phase_margin)
    check_positive("stability_margin", stability_margin)
    grid = _GRID if starts is None else tuple(starts)
    if not grid:
        raise ValueError("starts: must not be empty")
    for i, x in enumerate(grid):
        if np.shape(x) != (3,) or not all(math.isfinite(v) and v >= 0.0 for v in x):
            raise ValueError(f"starts[{i}]={x!r}: must be three finite gains >= 0")
    k = float(np.real(ct.dcgain(plant)))
    if k == 0.0 or not math.isfinite(k):
        raise ValueError(f"plant: DC gain {k!r} must be finite and non-zero")

    plant = _minimal(plant)

    def gains(x: np.ndarray) -> PIDGains:
        x = np.abs(x)  # non-negative gains
        kd = x[2] if derivative else 0.0
        return PIDGains(x[0] / k, x[1] / (k * dt), kd * dt / k, float(dt))

    def cost(x: np.ndarray) -> float:
        loop = ct.series(pid_transfer_function(gains(x)), plant)
        if np.any(np.abs(ct.poles(ct.feedback(loop, 1))) >= 1.0):
            return 1e3
        _gm, pm, sm, _wpc, wgc, _wms = ct.stability_margins(loop)
        if not math.isfinite(wgc) or wgc <= 0.0:
            return 1e3
        pen = max(phase_margin - pm, 0.0) / 10.0 + max(stability_margin - sm, 0.0) * 10.0
        return -wgc * dt + 100.0 * pen

    x0 = min(grid, key=lambda x: cost(np.array(x, dtype=float)))
    res = scipy.optimize.minimize(
        cost, np.array(x0), method="Nelder-Mead", options={"xatol": 1e-5}
    )
    g = gains(res.x)
    loop = ct.series(pid_transfer_function(g), plant)
    m, noise = loop_margins(loop), _noise_gain(loop)
    pm, sm = m["phase_margin_deg"], m["stability_margin"]
    if pm < phase_margin - 0.5 or sm < stability_margin - 0.01:
        raise ValueError(
            f"plant: no PID meets PM >= {phase_margin:g} deg and min|1 + L| >= "
            f"{stability_margin:g} on it (best: PM {pm:.1f} deg, SM {sm:.2f}); its poles "
            f"{_slowest_poles(plant)} (a lightly damped mode near the crossover needs a "
            "notch, not a PID)"
        )
    return PIDGains(
        float(g.kp), float(g.ki), float(g.kd), g.dt, pm, m["gain_margin"], sm,
        m["crossover_rad_s"], noise, k,
    )  # fmt: skip


def _slowest_poles(plant: ct.LTI) -> str:
    """The discrete plant's two poles nearest the unit circle, as z = |z|∠θ text."""
    z = sorted(np.atleast_1d(ct.poles(plant)), key=lambda p: -abs(p))[:2]
    return ", ".join(f"|z| {abs(p):.4f} at {abs(np.angle(p)) / plant.dt / (2 * np.pi):.3g} Hz"
                     for p in z)  # fmt: skip


class ScanPID:
    """The scan PID in incremental form, u_k = clip(u_{k−1} + Δu_k, ±u_max) [V].

    Args:
        gains: from :func:`design_scan_pid`.
        limit: |u| bound [V] (amplifier input limit).
    """

    def __init__(self, gains: PIDGains, limit: float) -> None:
        self.gains = gains
        self.limit = check_positive("limit", limit)
        self.reset(0.0)

    def reset(self, u: float = 0.0) -> None:
        """Restart from offset u [V] with no error history."""
        self.u = float(u)
        self._e1: float | None = None
        self._e2: float | None = None

    def update(self, error: float, hold_error: float = 0.0) -> float:
        """New offset [V] for the error e = θ* − θ_measured [rad]: the PID, or inside
        ``hold_error`` [rad] the hold's integrator (:meth:`hold`)."""
        if abs(error) < hold_error and math.isfinite(self.gains.plant_gain):
            return self.hold(error)
        g = self.gains
        e1 = error if self._e1 is None else self._e1
        e2 = e1 if self._e2 is None else self._e2
        du = g.kp * (error - e1) + g.ki * g.dt * error + g.kd / g.dt * (error - 2.0 * e1 + e2)
        self.u = float(np.clip(self.u + du, -self.limit, self.limit))
        self._e2, self._e1 = e1, error
        return self.u

    def jump(self, error: float, fraction: float, extra: float = 0.0) -> float:
        """One dead-beat step on the scan plant P(z) = K·z⁻¹: u_k = u_{k−1} + fraction·e_k/K
        + ``extra`` [V] (K the plant's DC gain; ``extra`` the offset a dead band the plant
        shows will absorb), the error history cleared so the PID takes over from the next
        reading without a derivative kick (a hand-over from stepping, whose residual error
        the PID's first, integral-only update would close slowly)."""
        self._integrate(fraction * error + extra * self.gains.plant_gain, "jump")
        self._e1 = self._e2 = None
        return self.u

    def hold(self, error: float) -> float:
        """The hold's integrator, u_k = u_{k−1} + g·e_k/K [V] (g = ``HOLD_GAIN``, K the
        plant's DC gain): an error within the reading's noise is averaged over about 1/g
        intervals instead of answered at once. On the scan plant P(z) = K·z⁻¹ it passes
        √(g/(2 − g)) = 0.38 of a white reading noise to the table and at most g/(2 − g) =
        0.14 of a line at the Nyquist frequency (a floor vibration aliased by the control
        rate), where the PID, designed for crossover, passes about all of it."""
        self._integrate(HOLD_GAIN * error, "hold")
        self._e2 = self._e1 = error  # no derivative kick when the PID takes over again
        return self.u

    def _integrate(self, error: float, what: str) -> None:
        """u ← clip(u + e/K) [V]: the offset that moves the scan plant (DC gain K) by
        ``error`` [rad]; ``what`` names the caller when the design left K unknown."""
        k = self.gains.plant_gain
        if not (math.isfinite(k) and k != 0.0):
            raise ValueError(
                f"gains.plant_gain={k!r}: the {what} needs the plant's DC gain (design_scan_pid)"
            )
        self.u = float(np.clip(self.u + error / k, -self.limit, self.limit))

    @property
    def saturated(self) -> bool:
        return abs(self.u) >= self.limit * (1.0 - 1e-9)

    def state(self) -> dict[str, Any]:
        return {"u": self.u, "e1": self._e1, "e2": self._e2}
