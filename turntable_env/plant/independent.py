"""The independent test plant behind the plant layer: a fidelity the controllers never saw.

:mod:`turntable_env.testing.independent_plant` was written from the thesis alone (LuGre
friction, lumped tubes, two-pole amplifier with a rate limit; it shares no model code with
the package). :class:`IndependentBackend` runs it as a :class:`~.stepper.Backend` so the env,
the controllers and the benchmark meet it through the same interface as the reduced and
3-D models (``Plant(fidelity="independent")``).

Its parameters are its own (:class:`~turntable_env.testing.independent_plant.PlantParams`,
derived apart from Table D.1), scaled by the plant's factors, read off the parameter set
against Table D.1's (``real``): μ_s and μ_c, the normal force, the Stribeck velocity, the
tubes' loss 1/Q_m, the contact damping, and the amplifier's slew rate and current limit.
The rig, the detector and the catalogue's input, friction and output stages stay the
plant layer's (:mod:`turntable_env.plant.stepper`). One axis: the plant turns about the
axis the stepper names.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any, NamedTuple

import numpy as np

from ..kernel_types import DriveArrays
from ..params import ParameterSet, get_parameter_set
from ..reduced import H_MIN
from ..testing.independent_plant import (
    JUMP_WIDTH_S,
    Effects,
    FrictionAsymmetry,
    PlantParams,
    rest_state,
    simulate_from,
)

__all__ = ["IndependentBackend", "Records", "independent_params"]

GRID = H_MIN  # s, the breakpoint grid the stepper shares with the reduced model


class Records(NamedTuple):
    """Recorded true angles of one turntable: time [s], angle [rad] (what every backend's
    ``advance`` returns, :class:`~.stepper.Backend`)."""

    time: np.ndarray
    angle: np.ndarray


def independent_params(ps: ParameterSet) -> PlantParams:
    """The independent plant's parameters for the parameter set ``ps``: its own defaults ×
    the ratios of ps's uncertain values to Table D.1's (module docstring)."""
    real = get_parameter_set("real")
    u, u0 = ps.unlisted, real.unlisted
    p = PlantParams()
    if u is None or u0 is None:
        raise ValueError(f"params: set {ps.name!r} has no unlisted inputs to scale by")
    mu_s = p.static_friction_coefficient * u.mu_static / u0.mu_static
    mu_c = min(p.coulomb_friction_coefficient * u.mu_coulomb / u0.mu_coulomb, mu_s)
    c, c0 = ps.contact, real.contact
    a, a0 = ps.amplifier, real.amplifier
    assert c is not None and c0 is not None
    return replace(
        p,
        static_friction_coefficient=mu_s,
        coulomb_friction_coefficient=mu_c,
        normal_force_N=p.normal_force_N * u.normal_force / u0.normal_force,
        stribeck_velocity_m_per_s=p.stribeck_velocity_m_per_s
        * u.stribeck_velocity
        / u0.stribeck_velocity,
        tube_damping_N_s_per_m=p.tube_damping_N_s_per_m
        * u0.tube_quality_factor
        / u.tube_quality_factor,
        bristle_damping_N_s_per_m=p.bristle_damping_N_s_per_m
        * c.tangential_damping
        / c0.tangential_damping,
        amplifier_slew_rate_V_per_s=p.amplifier_slew_rate_V_per_s
        * a.slew_per_input_volt
        / a0.slew_per_input_volt,
        amplifier_current_limit_A=p.amplifier_current_limit_A * a.current_limit / a0.current_limit,
    )


def _strict(times: np.ndarray) -> np.ndarray:
    """Breakpoint grid times with a jump's second point (same time) moved on by
    :data:`~turntable_env.testing.independent_plant.JUMP_WIDTH_S`: the plant's input is linear
    between strictly increasing samples."""
    t = np.array(times, dtype=float)
    for i in range(1, t.size):
        if t[i] <= t[i - 1]:
            t[i] = t[i - 1] + JUMP_WIDTH_S / GRID
    return t


class IndependentBackend:
    """N independent plants, one after another (each resumed from its state)."""

    def __init__(self, params: Sequence[ParameterSet], axis: str) -> None:
        if axis not in ("A", "B", "C"):
            raise ValueError(f"axis={axis!r}: the env and the plant layer turn about A, B or C")
        self.axis = axis
        self.grid = GRID
        self.params = [independent_params(ps) for ps in params]
        self.friction = list(self.params)  # with the friction stage's scale applied
        self.effects: list[Effects | None] = [None] * len(self.params)  # its asymmetry
        self.states = [rest_state(p) for p in self.params]
        self.n = np.zeros(len(params), dtype=np.int64)

    def set_params(self, b: int, ps: ParameterSet) -> None:
        self.params[b] = self.friction[b] = independent_params(ps)
        self.states[b] = rest_state(self.params[b])

    def reset(self, b: int, angle: float, time: float, voltage: float) -> None:
        # voltage is the amplifier output [V]; the plant settles its own amplifier on the input
        p = self.params[b]
        self.states[b] = rest_state(p, input_V=voltage / p.amplifier_gain, angle_rad=angle)
        self.n[b] = round(time / self.grid)

    def displace(self, b: int, delta: float) -> None:
        st = self.states[b]
        p = self.params[b]
        knocked = rest_state(p, input_V=st[0] / p.amplifier_gain, angle_rad=st[3] + delta)
        st[3], st[4] = knocked[3], 0.0  # the table at the new angle, at rest
        # every contact sticks again, holding the pendulum; the tubes keep their free stroke
        st[10:12] = st[14:16] - (knocked[14:16] - knocked[10:12])
        st[12:14] = 0.0
        st[16:18] = knocked[16:18]

    def grid_time(self) -> np.ndarray:
        return self.n

    def set_friction_asymmetry(self, rows: np.ndarray, alpha: np.ndarray) -> None:
        # its own sliding asymmetry: ×(1 + ε) for tip-minus-table sliding v > 0, so ε = −α
        for b, a in zip(np.atleast_1d(rows), np.atleast_1d(alpha), strict=True):
            self.effects[b] = (
                Effects(friction_asymmetry=FrictionAsymmetry(asymmetry=-float(a))) if a else None
            )

    def set_friction_scale(self, rows: np.ndarray, scale: np.ndarray) -> None:
        for b, s in zip(np.atleast_1d(rows), np.atleast_1d(scale), strict=True):
            p = self.params[b]
            self.friction[b] = replace(
                p,
                static_friction_coefficient=p.static_friction_coefficient * float(s),
                coulomb_friction_coefficient=p.coulomb_friction_coefficient * float(s),
            )

    def advance(self, drive: DriveArrays, n_end: np.ndarray, out_every: int) -> list[Records]:
        out = []
        for b in range(n_end.size):
            n0, n1 = int(self.n[b]), int(n_end[b])
            if n1 <= n0:
                out.append(Records(np.array([n0 * self.grid]), np.array([self.angle(b)])))
                continue
            nw = int(drive.count[b])
            tk, vk = _strict(drive.times[b, :nw]), drive.values[b, :nw]
            pts = [tk[(tk > n0) & (tk < n1)], np.array([n0, n1], dtype=float)]
            if out_every > 0:
                pts.append(np.arange(n0, n1, out_every, dtype=float))
            n = np.unique(np.concatenate(pts))  # grid times, strictly increasing
            u = np.interp(n, tk, vk) if nw else np.zeros(n.size)
            theta = simulate_from(self.friction[b], self.states[b], n * self.grid, u,
                                  self.effects[b])  # fmt: skip
            self.n[b] = n1
            if out_every > 0:
                keep = ((n - n0) % out_every == 0) | (n == n1)
                out.append(Records(n[keep] * self.grid, theta[keep]))
        return out

    def angle(self, b: int) -> float:
        return float(self.states[b][3])

    def angles(self) -> np.ndarray:
        return np.array([self.angle(b) for b in range(len(self.states))])

    def snapshot(self, b: int) -> dict[str, Any]:
        st = self.states[b]
        p = self.friction[b]
        cap = p.static_friction_coefficient * p.normal_force_N / p.bristle_stiffness_N_per_m
        return {
            "tube_deflection": st[10:12].copy(),
            "stick_fraction": (np.abs(st[16:18]) < cap).astype(float),
            "voltage": float(st[0]),
            "tubes": tuple(a for a in "ABC" if a != self.axis),
            "axis": self.axis,
            "axis_stick_fraction": None,
        }
