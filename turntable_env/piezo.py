"""Piezoelectric tube quadrant: the 2-port C element and asymmetric-mode bending.

Implements thesis Eq. 2.1–2.3 and App. A (constitutive relations in
power-conjugate variables and the co-energy), and Eq. 2.8–2.12 (neutral plane,
radius of curvature and tip deflection of a bending tube).

Conventions (SI throughout):

* ``F``  tensile force on the quadrant along the tube axis [N]
* ``V``  voltage across the wall [V]
* ``z``  elongation of the quadrant along the tube axis [m]
* ``q``  charge on the quadrant electrode [C]

The diameter that enters A_e, A_m and Eq. 2.10–2.12 is a documented choice:
Table D.1's R_bending·V = 1.570e4 V·m is reproduced only with the *mean*
diameter D = R_o + R_i (= 2·(R_o + R_i)/2); the outer diameter 2R_o gives
1.706e4 V·m. Both are exposed (``diameter_convention``), the mean is default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .validation import check_finite, check_in_open, check_positive

__all__ = [
    "EPSILON_0",
    "PiezoMaterial",
    "PiezoQuadrant",
]

EPSILON_0 = 8.8541878128e-12  # F/m, vacuum permittivity


@dataclass(frozen=True)
class PiezoMaterial:
    """PZT material constants (Table D.1, PIC 151).

    Attributes:
        d31: piezoelectric charge constant [m/V] (negative for PZT: a field along
            the poling direction shortens the element).
        s33E: compliance at constant field [m²/N].
        eps11T_rel: relative permittivity at constant stress (ε₁₁ᵀ/ε₀) [-].
        poisson: Poisson's ratio ν (App. B.3) [-].
    """

    d31: float = -210e-12
    s33E: float = 19.0e-12
    eps11T_rel: float = 2400.0
    poisson: float = 0.31

    def __post_init__(self) -> None:
        d31 = check_finite("d31", self.d31)
        if d31 == 0.0:
            raise ValueError(f"d31={self.d31!r}: must be non-zero")
        check_positive("s33E", self.s33E)
        check_positive("eps11T_rel", self.eps11T_rel)
        check_in_open("poisson", self.poisson, -1.0, 0.5)
        if self.coupling_k2 >= 1.0:
            raise ValueError(
                f"d31={self.d31!r}: coupling d31²/(s33E·ε11T) = {self.coupling_k2:.3g} must be < 1 "
                "(otherwise the stored energy is indefinite)"
            )

    @property
    def eps11T(self) -> float:
        """Permittivity at constant stress ε₁₁ᵀ [F/m]."""
        return self.eps11T_rel * EPSILON_0

    @property
    def youngs_modulus(self) -> float:
        """E = 1/s₃₃ᴱ [N/m²] (Table D.1 lists 5.263e10, which is exactly this)."""
        return 1.0 / self.s33E

    @property
    def shear_modulus(self) -> float:
        """G = E / (2(1+ν)) [N/m²] (App. B.3)."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson))

    @property
    def coupling_k2(self) -> float:
        """Squared electromechanical coupling k² = d₃₁²/(s₃₃ᴱ ε₁₁ᵀ) of Eq. 2.2 [-]."""
        return self.d31**2 / (self.s33E * self.eps11T)


@dataclass(frozen=True)
class PiezoQuadrant:
    """One electrode quadrant of a piezo tube as a 2-port C element (Eq. 2.2).

    Args:
        material: PZT constants.
        length: tube length L [m].
        outer_radius: R_o [m].
        inner_radius: R_i [m]; the wall thickness is h = R_o − R_i.
        diameter_convention: ``"mean"`` (D = R_o + R_i, reproduces Table D.1) or
            ``"outer"`` (D = 2R_o).
    """

    material: PiezoMaterial = field(default_factory=PiezoMaterial)
    length: float = 6.35e-3
    outer_radius: float = 3.175e-3
    inner_radius: float = 2.667e-3
    diameter_convention: Literal["mean", "outer"] = "mean"

    def __post_init__(self) -> None:
        check_positive("length", self.length)
        check_positive("outer_radius", self.outer_radius)
        check_positive("inner_radius", self.inner_radius)
        if self.inner_radius >= self.outer_radius:
            raise ValueError(
                f"inner_radius={self.inner_radius!r}: must be < outer_radius={self.outer_radius!r}"
            )
        if self.diameter_convention not in ("mean", "outer"):
            raise ValueError(
                f"diameter_convention={self.diameter_convention!r}: must be 'mean' or 'outer'"
            )

    # --- geometry -----------------------------------------------------------------
    @property
    def wall_thickness(self) -> float:
        """h = R_o − R_i [m]."""
        return self.outer_radius - self.inner_radius

    @property
    def diameter(self) -> float:
        """D used in A_e, A_m and Eq. 2.10–2.12 [m] (see module docstring)."""
        if self.diameter_convention == "mean":
            return self.outer_radius + self.inner_radius
        return 2.0 * self.outer_radius

    @property
    def electrode_area(self) -> float:
        """A_e = πDL/4, the actuated (electrode) surface of one quadrant [m²]."""
        return math.pi * self.diameter * self.length / 4.0

    @property
    def section_area(self) -> float:
        """A_m = πDh/4, the cross-section of one quadrant [m²]."""
        return math.pi * self.diameter * self.wall_thickness / 4.0

    # --- Eq. 2.2 -------------------------------------------------------------------
    @property
    def compliance_matrix(self) -> np.ndarray:
        """The symmetric 2×2 matrix of Eq. 2.2: (z, q) = M · (F, V).

        M = [[s₃₃ᴱL/A_m, d₃₁L/h], [d₃₁L/h, ε₁₁ᵀA_e/h]] in [m/N, m/V; C/N, F].
        """
        m, h, L = self.material, self.wall_thickness, self.length
        a11 = m.s33E * L / self.section_area
        a12 = m.d31 * L / h
        a22 = m.eps11T * self.electrode_area / h
        return np.array([[a11, a12], [a12, a22]])

    @property
    def capacitance(self) -> float:
        """Free (constant-force) capacitance ε₁₁ᵀA_e/h of one quadrant [F]."""
        return float(self.compliance_matrix[1, 1])

    @property
    def blocked_capacitance(self) -> float:
        """Capacitance at zero elongation, C(1 − k²) [F]."""
        return self.capacitance * (1.0 - self.material.coupling_k2)

    def displacement_charge(self, force: float, voltage: float) -> tuple[float, float]:
        """Eq. 2.2: (z [m], q [C]) for a force F [N] and voltage V [V]."""
        f = check_finite("force", force)
        v = check_finite("voltage", voltage)
        zq = self.compliance_matrix @ np.array([f, v])
        return float(zq[0]), float(zq[1])

    def force_voltage(self, elongation: float, charge: float) -> tuple[float, float]:
        """Inverse of Eq. 2.2: efforts (F [N], V [V]) for a state (z [m], q [C])."""
        z = check_finite("elongation", elongation)
        q = check_finite("charge", charge)
        fv = np.linalg.solve(self.compliance_matrix, np.array([z, q]))
        return float(fv[0]), float(fv[1])

    def coenergy(self, force: float, voltage: float) -> float:
        """Co-energy E*(F, V) of Eq. 2.3 / A.4–A.5 [J].

        E* = s₃₃ᴱL/(2A_m)·F² + ε₁₁ᵀA_e/(2h)·V² + d₃₁L/h·F·V; its gradient is (z, q).
        """
        f = check_finite("force", force)
        v = check_finite("voltage", voltage)
        a = self.compliance_matrix
        return float(0.5 * a[0, 0] * f * f + 0.5 * a[1, 1] * v * v + a[0, 1] * f * v)

    def energy(self, elongation: float, charge: float) -> float:
        """Stored energy E(z, q) = Fz + Vq − E* (Legendre transform, Eq. A.2) [J]."""
        f, v = self.force_voltage(elongation, charge)
        return f * elongation + v * charge - self.coenergy(f, v)

    def free_elongation(self, voltage: float) -> float:
        """Unloaded elongation z = d₃₁L/h · V (Eq. 2.2 with F = 0) [m]."""
        return self.displacement_charge(0.0, voltage)[0]

    # --- Eq. 2.8–2.12: bending ------------------------------------------------------
    @property
    def neutral_plane_offset(self) -> float:
        """y₀ = πD/(4√2) ≈ 0.555D, Eq. 2.8 (symmetric mode) [m]."""
        return math.pi * self.diameter / (4.0 * math.sqrt(2.0))

    @property
    def bending_radius_times_voltage(self) -> float:
        """R_bending·|V| = πDh/(2√2|d₃₁|), asymmetric mode, Eq. 2.12 [V·m].

        Table D.1 lists 1.570e4 V·m; the sign of d₃₁ only sets the bending direction.
        """
        return (
            math.pi
            * self.diameter
            * self.wall_thickness
            / (2.0 * math.sqrt(2.0) * abs(self.material.d31))
        )

    def radius_of_curvature(
        self, voltage: float, mode: Literal["asymmetric", "symmetric"] = "asymmetric"
    ) -> float:
        """Radius of curvature R_bending [m] for one quadrant at ``voltage`` (Eq. 2.10/2.12).

        Symmetric mode (±V on opposite quadrants, Eq. 2.10) bends twice as much:
        its radius is half the asymmetric one. Returns ``inf`` at V = 0.
        """
        v = check_finite("voltage", voltage)
        if mode not in ("asymmetric", "symmetric"):
            raise ValueError(f"mode={mode!r}: must be 'asymmetric' or 'symmetric'")
        if v == 0.0:
            return math.inf
        r = self.bending_radius_times_voltage / abs(v)
        return r if mode == "asymmetric" else 0.5 * r

    def tip_deflection(
        self, voltage: float, mode: Literal["asymmetric", "symmetric"] = "asymmetric"
    ) -> float:
        """Lateral tip deflection Δy = L²/(2R_bending) (Eq. 2.11), signed with V [m]."""
        v = check_finite("voltage", voltage)
        if v == 0.0:
            return 0.0
        return math.copysign(self.length**2 / (2.0 * self.radius_of_curvature(v, mode)), v)

    def tip_angle(
        self, voltage: float, mode: Literal["asymmetric", "symmetric"] = "asymmetric"
    ) -> float:
        """Tip rotation θ = L/R_bending [rad], signed with V (small-angle arc of Eq. 2.9)."""
        v = check_finite("voltage", voltage)
        if v == 0.0:
            return 0.0
        return math.copysign(self.length / self.radius_of_curvature(v, mode), v)

    @property
    def bending_lever(self) -> float:
        """Lever y_eff [m] that turns quadrant elongation into tip rotation: θ = |z|/y_eff.

        From Eq. 2.2 (z = d₃₁LV/h) and Eq. 2.12 (θ = L/R_bending):
        y_eff = R_bending·V·|d₃₁|/h = πD/(2√2) = 2y₀. This is the constant radius the
        piezo velocity is divided by in Eq. 3.16; Table D.2's "R_bending = 2 m" is
        this lever for the scaled tube, not the voltage-dependent Eq. 2.12.
        """
        return self.bending_radius_times_voltage * abs(self.material.d31) / self.wall_thickness
