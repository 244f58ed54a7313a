"""The friction models of §2.2 as immutable parameter objects over one state-space interface.

Static models: Stribeck curve (Eq. 2.13–2.14), classical (Eq. 2.15), Karnopp,
Breedveld with preslip velocity (Eq. 2.16–2.17). Dynamic models: Dahl (Eq.
2.18), LuGre (Eq. 2.19–2.20), elasto-plastic (Eq. 2.21–2.22), Leuven (Eq. 2.23),
Generalized Maxwell Slip (Eq. 2.24–2.26; the §4.2.1 parameter rules in
:meth:`GMS.from_rules`).

Every model offers the same interface (see :mod:`.kernels`): ``initial_state()``,
``force(state, v, normal_force, applied_force)``, ``rates(...)``, ``update(...)``,
and two test rigs, ``simulate_velocity`` (prescribed sliding velocity) and
``simulate_mass`` (a block pushed by a force), which return a
:class:`FrictionResponse`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..quantities import Quantity
from ..validation import (
    check_array_finite,
    check_finite,
    check_in_open,
    check_nonnegative,
    check_positive,
    check_positive_array,
    check_sums_to_one,
)
from . import kernels as K
from .gms2d import run_gms2d_velocity_driven

__all__ = [
    "GMS",
    "Breedveld",
    "Classical",
    "Dahl",
    "ElastoPlastic",
    "FrictionModel",
    "FrictionResponse",
    "FrictionState",
    "Karnopp",
    "Leuven",
    "LuGre",
    "StribeckCurve",
    "StribeckParams",
]


@dataclass(frozen=True)
class StribeckParams:
    """Stribeck curve and viscous term shared by every model (Eq. 2.13–2.14).

    Attributes:
        mu_s: static friction coefficient μ_st [-] (F_s = μ_s F_N).
        mu_c: Coulomb (dynamic) coefficient μ_c [-] (F_c = μ_c F_N), 0 < μ_c ≤ μ_s.
        v_s: Stribeck velocity v_S [m/s].
        delta: Stribeck shape factor δ_vS [-].
        sigma2: viscous coefficient σ₂ (Table D.2's R_viscous) [N·s/m].
    """

    mu_s: float = 0.3
    mu_c: float = 0.05
    v_s: float = 0.8
    delta: float = 2.0
    sigma2: float = 0.0

    def __post_init__(self) -> None:
        check_positive("mu_s", self.mu_s)
        check_positive("mu_c", self.mu_c)
        if self.mu_c > self.mu_s:
            raise ValueError(f"mu_c={self.mu_c!r}: must be <= mu_s={self.mu_s!r}")
        check_positive("v_s", self.v_s)
        check_positive("delta", self.delta)
        check_nonnegative("sigma2", self.sigma2)

    def as_array(self) -> np.ndarray:
        return np.array([self.mu_s, self.mu_c, self.v_s, self.delta, self.sigma2])

    def curve(self, velocity: np.ndarray | float, normal_force: float) -> np.ndarray:
        """s(v) [N] of Eq. 2.13, vectorised over ``velocity`` [m/s] (viscous term excluded)."""
        v = check_array_finite("velocity", velocity)
        fn = check_positive("normal_force", normal_force)
        f_s, f_c = self.mu_s * fn, self.mu_c * fn
        return np.sign(v) * (f_c + (f_s - f_c) * np.exp(-(np.abs(v / self.v_s) ** self.delta)))

    def describe(self, prefix: str) -> list[Quantity]:
        g = "given"
        return [
            Quantity(f"{prefix}.mu_st", self.mu_s, "-", g, "static friction coefficient"),
            Quantity(f"{prefix}.mu_c", self.mu_c, "-", g, "Coulomb friction coefficient"),
            Quantity(f"{prefix}.v_s", self.v_s, "m/s", g, "Stribeck velocity"),
            Quantity(f"{prefix}.delta_vs", self.delta, "-", g, "Stribeck shape factor"),
            Quantity(f"{prefix}.R_viscous", self.sigma2, "N*s/m", g, "viscous coefficient sigma2"),
        ]


@dataclass
class FrictionState:
    """Mutable state of one friction interface: continuous ``x`` and logic ``flags``."""

    x: np.ndarray
    flags: np.ndarray

    def copy(self) -> FrictionState:
        return FrictionState(self.x.copy(), self.flags.copy())


@dataclass(frozen=True)
class FrictionResponse:
    """Time response of a friction rig. Time is axis 0 of every array.

    Attributes:
        time: [s], shape (N+1,).
        velocity: sliding velocity [m/s].
        displacement: sliding displacement [m].
        force: friction force [N].
        applied_force: external force on the block [N] (zeros for velocity-driven rigs).
        states: continuous friction states, shape (N+1, nx).
        flags: logic flags, shape (N+1, nf).
        model: name of the model.
    """

    time: np.ndarray
    velocity: np.ndarray
    displacement: np.ndarray
    force: np.ndarray
    applied_force: np.ndarray
    states: np.ndarray
    flags: np.ndarray
    model: str

    def to_pandas(self) -> Any:
        """DataFrame indexed by time [s]."""
        import pandas as pd

        df = pd.DataFrame(
            {
                "velocity_m_per_s": self.velocity,
                "displacement_m": self.displacement,
                "friction_force_N": self.force,
                "applied_force_N": self.applied_force,
            },
            index=pd.Index(self.time, name="time_s"),
        )
        for j in range(self.states.shape[1]):
            df[f"state_{j}"] = self.states[:, j]
        for j in range(self.flags.shape[1]):
            df[f"flag_{j}"] = self.flags[:, j]
        return df

    def plot(self, ax: Any = None, x: str = "time") -> Any:
        """Plot friction force against ``"time"`` or ``"displacement"``; returns the axes."""
        import matplotlib.pyplot as plt

        if x not in ("time", "displacement"):
            raise ValueError(f"x={x!r}: must be 'time' or 'displacement'")
        if ax is None:
            _, ax = plt.subplots()
        xs = self.time if x == "time" else self.displacement
        ax.plot(xs, self.force, label=f"{self.model} friction force")
        ax.set_xlabel("time [s]" if x == "time" else "displacement [m]")
        ax.set_ylabel("force [N]")
        ax.legend()
        return ax


@dataclass(frozen=True)
class FrictionModel:
    """Base class: a friction law with Stribeck parameters and the common interface."""

    stribeck: StribeckParams = field(default_factory=StribeckParams)
    model_id: ClassVar[int] = -1
    n_states: ClassVar[int] = 0
    n_flags: ClassVar[int] = 1

    # -- packing ---------------------------------------------------------------------
    def _extra(self) -> list[float]:
        return []

    def pack(self) -> np.ndarray:
        """Packed float64 parameter vector for the compiled kernels."""
        return np.concatenate([self.stribeck.as_array(), np.asarray(self._extra(), dtype=float)])

    def state_size(self) -> int:
        return self.n_states

    def initial_state(self) -> FrictionState:
        """Unloaded, sticking interface."""
        return FrictionState(np.zeros(self.state_size()), self._initial_flags())

    def _initial_flags(self) -> np.ndarray:
        return np.zeros(self.n_flags, dtype=np.int64)

    # -- the interface -------------------------------------------------------------
    def force(
        self, state: FrictionState, velocity: float, normal_force: float, applied_force: float = 0.0
    ) -> float:
        """Friction force [N] in ``state`` at sliding velocity [m/s] and normal force [N]."""
        v, fa, fn = self._check_inputs(velocity, normal_force, applied_force)
        return float(K.kernel_force(self.model_id, self.pack(), state.x, state.flags, v, fa, fn))

    def rates(
        self, state: FrictionState, velocity: float, normal_force: float, applied_force: float = 0.0
    ) -> np.ndarray:
        """dx/dt of the continuous states."""
        v, fa, fn = self._check_inputs(velocity, normal_force, applied_force)
        dx = np.zeros(state.x.shape[0])
        K.kernel_rates(self.model_id, self.pack(), state.x, state.flags, v, fa, fn, dx)
        return dx

    def update(
        self, state: FrictionState, velocity: float, normal_force: float, applied_force: float = 0.0
    ) -> None:
        """Apply the discrete transitions (stick/slip, saturation) in place."""
        v, fa, fn = self._check_inputs(velocity, normal_force, applied_force)
        K.kernel_update(self.model_id, self.pack(), state.x, state.flags, v, fa, fn)

    @staticmethod
    def _check_inputs(velocity: float, normal_force: float, applied_force: float):
        return (
            check_finite("velocity", velocity),
            check_finite("applied_force", applied_force),
            check_positive("normal_force", normal_force),
        )

    # -- rigs ------------------------------------------------------------------------
    def simulate_velocity(
        self,
        velocity: np.ndarray,
        dt: float,
        normal_force: float,
        state: FrictionState | None = None,
    ) -> FrictionResponse:
        """Prescribed sliding velocity ``velocity[i]`` [m/s] held over steps of ``dt`` [s]."""
        v = check_array_finite("velocity", velocity)
        if v.ndim != 1 or v.size == 0:
            raise ValueError(f"velocity: must be a non-empty 1-D array (got shape {v.shape})")
        dt = check_positive("dt", dt)
        fn = check_positive("normal_force", normal_force)
        st = state.copy() if state is not None else self.initial_state()
        force, xs, fls = K.run_velocity_driven(
            self.model_id, self.pack(), st.x, st.flags, v, dt, fn
        )
        vel = np.concatenate([[v[0]], v])
        disp = np.concatenate([[0.0], np.cumsum(v) * dt])
        t = np.arange(v.size + 1) * dt
        return FrictionResponse(
            t, vel, disp, force, np.zeros_like(force), xs, fls, type(self).__name__
        )

    def simulate_mass(
        self,
        applied_force: np.ndarray,
        dt: float,
        mass: float,
        normal_force: float,
        initial_velocity: float = 0.0,
    ) -> FrictionResponse:
        """A block of ``mass`` [kg] pushed by ``applied_force[i]`` [N] over steps of ``dt`` [s]."""
        fa = check_array_finite("applied_force", applied_force)
        if fa.ndim != 1 or fa.size == 0:
            raise ValueError(f"applied_force: must be a non-empty 1-D array (got shape {fa.shape})")
        dt = check_positive("dt", dt)
        m = check_positive("mass", mass)
        fn = check_positive("normal_force", normal_force)
        v0 = check_finite("initial_velocity", initial_velocity)
        st = self.initial_state()
        pos, vel, ff, xs, fls = K.run_mass(
            self.model_id, self.pack(), st.x, st.flags, fa, m, dt, fn, v0
        )
        t = np.arange(fa.size + 1) * dt
        fapp = np.concatenate([fa, [fa[-1]]])
        return FrictionResponse(t, vel, pos, ff, fapp, xs, fls, type(self).__name__)


@dataclass(frozen=True)
class StribeckCurve(FrictionModel):
    """Static map F = s(v) + σ₂v (Eq. 2.13 as a friction law; zero force at rest)."""

    model_id: ClassVar[int] = K.STRIBECK


@dataclass(frozen=True)
class Classical(FrictionModel):
    """Classical static model, Eq. 2.15. ``zero_band`` [m/s] is the |v| treated as v = 0."""

    zero_band: float = 1e-9
    model_id: ClassVar[int] = K.CLASSICAL

    def __post_init__(self) -> None:
        check_positive("zero_band", self.zero_band)

    def _extra(self) -> list[float]:
        return [self.zero_band]


@dataclass(frozen=True)
class Karnopp(FrictionModel):
    """Karnopp model: inside |v| < ``dv`` [m/s] the force balances the applied force up to F_s."""

    dv: float = 1e-4
    model_id: ClassVar[int] = K.KARNOPP

    def __post_init__(self) -> None:
        check_positive("dv", self.dv)

    def _extra(self) -> list[float]:
        return [self.dv]


@dataclass(frozen=True)
class Breedveld(FrictionModel):
    """Breedveld's port-based model with preslip velocity, Eq. 2.16–2.17 (flag 0: slip)."""

    v_preslip: float = 1e-3
    model_id: ClassVar[int] = K.BREEDVELD

    def __post_init__(self) -> None:
        check_positive("v_preslip", self.v_preslip)

    def _extra(self) -> list[float]:
        return [self.v_preslip]


@dataclass(frozen=True)
class Dahl(FrictionModel):
    """Dahl model, Eq. 2.18: dF/dx = σ₀|1 − F sgn(v)/F_c|^δ_d sgn(1 − F sgn(v)/F_c)."""

    sigma0: float = 1e4
    delta_d: float = 1.0
    model_id: ClassVar[int] = K.DAHL
    n_states: ClassVar[int] = 1

    def __post_init__(self) -> None:
        check_positive("sigma0", self.sigma0)
        check_positive("delta_d", self.delta_d)

    def _extra(self) -> list[float]:
        return [self.sigma0, self.delta_d]


@dataclass(frozen=True)
class LuGre(FrictionModel):
    """LuGre model, Eq. 2.19–2.20 (bristle deflection z [m])."""

    sigma0: float = 1e4
    sigma1: float = 10.0
    model_id: ClassVar[int] = K.LUGRE
    n_states: ClassVar[int] = 1

    def __post_init__(self) -> None:
        check_positive("sigma0", self.sigma0)
        check_nonnegative("sigma1", self.sigma1)

    def _extra(self) -> list[float]:
        return [self.sigma0, self.sigma1]


@dataclass(frozen=True)
class ElastoPlastic(LuGre):
    """Elasto-plastic model, Eq. 2.21–2.22.

    ``z_ba_ratio`` in (0, 1) sets the breakaway deflection z_ba as a fraction of the
    smallest steady deflection F_c/σ₀, which guarantees 0 < z_ba < z_ss(v) for all v.
    """

    z_ba_ratio: float = 0.5
    model_id: ClassVar[int] = K.ELASTOPLASTIC

    def __post_init__(self) -> None:
        super().__post_init__()
        check_in_open("z_ba_ratio", self.z_ba_ratio, 0.0, 1.0)

    def _extra(self) -> list[float]:
        return [self.sigma0, self.sigma1, self.z_ba_ratio]


def _check_elements(nu: Any, k: Any) -> tuple[np.ndarray, np.ndarray]:
    nu_a = check_sums_to_one("nu", nu)
    k_a = check_positive_array("k", k)
    if nu_a.ndim != 1 or k_a.shape != nu_a.shape:
        raise ValueError(
            f"k={k_a.tolist()!r}: must have one stiffness per element of nu ({nu_a.size})"
        )
    return nu_a, k_a


@dataclass(frozen=True)
class Leuven(FrictionModel):
    """Leuven model, Eq. 2.23, with a Maxwell-slip hysteresis force F_h(z) (nonlocal memory).

    F_h is the sum of elasto-slip elements (stiffness k_j, limit ν_j F_s); F_b is F_h
    at the last velocity reversal; F = F_h(z) + σ₁ż + σ₂v.
    """

    nu: tuple[float, ...] = (0.2, 0.2, 0.2, 0.2, 0.2)
    k: tuple[float, ...] = (1e4, 2e4, 3e4, 4e4, 5e4)
    sigma1: float = 0.0
    delta_l: float = 2.0
    model_id: ClassVar[int] = K.LEUVEN

    def __post_init__(self) -> None:
        _check_elements(self.nu, self.k)
        check_nonnegative("sigma1", self.sigma1)
        check_positive("delta_l", self.delta_l)

    def state_size(self) -> int:
        return 2 + len(self.nu)

    def _initial_flags(self) -> np.ndarray:
        return np.ones(1, dtype=np.int64)

    def _extra(self) -> list[float]:
        return [self.sigma1, self.delta_l, float(len(self.nu)), *self.nu, *self.k]


@dataclass(frozen=True)
class GMS(FrictionModel):
    """Generalized Maxwell Slip, Eq. 2.24–2.26 (Table D.2 defaults).

    Attributes:
        nu: fractions ν_i, positive, summing to 1.
        k: element stiffnesses k_i [N/m].
        C: attraction parameter [N/s] of Eq. 2.25.
    Flags: 1 = element sticks, 0 = slips.
    """

    nu: tuple[float, ...] = (0.06, 0.15, 0.21, 0.27, 0.31)
    k: tuple[float, ...] = (400.0, 643.0, 1260.0, 1350.0, 1233.0)
    C: float = 200.0
    model_id: ClassVar[int] = K.GMS

    def __post_init__(self) -> None:
        _check_elements(self.nu, self.k)
        check_positive("C", self.C)

    @property
    def n_elements(self) -> int:
        return len(self.nu)

    def state_size(self) -> int:
        return self.n_elements

    def _initial_flags(self) -> np.ndarray:
        return np.ones(self.n_elements, dtype=np.int64)

    def _extra(self) -> list[float]:
        return [self.C, float(self.n_elements), *self.nu, *self.k]

    @property
    def stiffness(self) -> float:
        """Initial presliding stiffness Σk_i [N/m]."""
        return float(np.sum(self.k))

    def stored_energy(self, state: FrictionState) -> float:
        """Elastic energy in the asperity springs, Σ F_i²/(2k_i) [J]."""
        return float(np.sum(state.x**2 / (2.0 * np.asarray(self.k))))

    @classmethod
    def from_rules(
        cls,
        stribeck: StribeckParams,
        normal_force: float,
        n_elements: int,
        presliding_distance: float,
        noise_level: float,
        C: float,
    ) -> GMS:
        """The §4.2.1 rules for GMS parameters.

        ν_i equally spaced in (0, 1] and summing to 1 (ν_i = 2i/(n(n+1))); W_i = ν_i F_st
        with F_st = μ_st F_N; δ_i equally spaced from ``noise_level`` to
        ``presliding_distance`` [m]; k_i = W_i/δ_i.
        """
        fn = check_positive("normal_force", normal_force)
        if not isinstance(n_elements, int | np.integer) or n_elements < 1:
            raise ValueError(f"n_elements={n_elements!r}: must be a positive integer")
        d_tot = check_positive("presliding_distance", presliding_distance)
        d_0 = check_positive("noise_level", noise_level)
        if d_0 > d_tot:
            raise ValueError(
                f"noise_level={noise_level!r}: must be <= "
                f"presliding_distance={presliding_distance!r}"
            )
        i = np.arange(1, n_elements + 1, dtype=float)
        nu = i / i.sum()
        w = nu * stribeck.mu_s * fn
        delta = np.linspace(d_0, d_tot, n_elements) if n_elements > 1 else np.array([d_tot])
        k = w / delta
        return cls(stribeck=stribeck, nu=tuple(nu.tolist()), k=tuple(k.tolist()), C=C)

    def simulate_velocity_2d(
        self,
        velocity: np.ndarray,
        dt: float,
        normal_force: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """2-D GMS (§3.3.2) under prescribed plane velocities ``velocity[i] = (v_x, v_y)`` [m/s].

        Returns (force [N], shape (N+1, 2); element forces (N+1, n, 2); stick flags (N+1, n)).
        """
        vel = check_velocity_history("velocity", velocity)
        dt = check_positive("dt", dt)
        fn = check_positive("normal_force", normal_force)
        s = self.stribeck
        return run_gms2d_velocity_driven(
            np.zeros((self.n_elements, 2)),
            np.ones(self.n_elements, dtype=np.int64),
            vel,
            dt,
            fn,
            np.asarray(self.nu, dtype=float),
            np.asarray(self.k, dtype=float),
            self.C,
            s.mu_s,
            s.mu_c,
            s.v_s,
            s.delta,
            s.sigma2,
        )

    def describe(self, prefix: str = "friction") -> list[Quantity]:
        g = "given"
        return [
            *self.stribeck.describe(prefix),
            Quantity(f"{prefix}.C", self.C, "N/s", g, "GMS attraction parameter, Eq. 2.25"),
            Quantity(f"{prefix}.nu_i", list(self.nu), "-", g, "GMS fractions, sum to 1"),
            Quantity(f"{prefix}.k_i", list(self.k), "N/m", g, "GMS element stiffnesses"),
            Quantity(f"{prefix}.k_total", self.stiffness, "N/m", "derived", "sum k_i"),
        ]


def check_velocity_history(name: str, values: Any) -> np.ndarray:
    """Validated 2-D plane-velocity history, shape (N, 2) [m/s]."""
    arr = check_array_finite(name, values)
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] == 0:
        raise ValueError(f"{name}: must have shape (N, 2) with N > 0 (got {arr.shape})")
    return arr
