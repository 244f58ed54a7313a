"""The table: a steel half sphere, its mass, inertia and centre of mass (App. C.1, C.2.1, C.3).

Implements Eq. C.1 (mass), C.8 (inertia about axes through the sphere centre),
C.15–C.17 (depth of the centre of mass h = 3R/8 below the flat face and the
cross-section radius R_CoM there).

Thesis inconsistency kept visible: Table D.1 lists m_table = 0.0335 kg, which is
(4/3)πR³ρ — a *full* sphere — while Eq. C.1 gives (2/3)πR³ρ = 0.01676 kg for the
half sphere; Table D.1's I_table = 1.340e-6 kg·m² is 2/5·0.0335·R². The default
``mass_convention="eq_C1"`` uses the half sphere (consistent with R, ρ and the
CoM of App. C.3); ``"table_D1"`` reproduces the table's numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from .quantities import Quantity
from .validation import check_positive

__all__ = ["TableParams"]


@dataclass(frozen=True)
class TableParams:
    """The half-sphere table.

    Args:
        radius: R_table [m].
        density: ρ_table [kg/m³] (None when the mass is given, Table D.2).
        mass_convention: ``"eq_C1"`` (half sphere) or ``"table_D1"`` (twice that).
        mass_given: a mass [kg] given by a table (Table D.2: 15 kg), overriding both.
    """

    radius: float = 0.01
    density: float | None = 8.0e3
    mass_convention: Literal["eq_C1", "table_D1"] = "eq_C1"
    mass_given: float | None = None

    def __post_init__(self) -> None:
        check_positive("radius", self.radius)
        if self.mass_convention not in ("eq_C1", "table_D1"):
            raise ValueError(
                f"mass_convention={self.mass_convention!r}: must be 'eq_C1' or 'table_D1'"
            )
        if self.mass_given is not None:
            check_positive("mass_given", self.mass_given)
        elif self.density is None:
            raise ValueError("density=None: a density is required when mass_given is not set")
        if self.density is not None:
            check_positive("density", self.density)

    @property
    def mass_half_sphere(self) -> float:
        """(2/3)πR³ρ, Eq. C.1 [kg] (0.01676 kg for Table D.1)."""
        if self.density is None:
            return math.nan
        return self.density * 2.0 / 3.0 * math.pi * self.radius**3

    @property
    def mass(self) -> float:
        """Mass used by the model [kg]."""
        if self.mass_given is not None:
            return self.mass_given
        m = self.mass_half_sphere
        return m if self.mass_convention == "eq_C1" else 2.0 * m

    @property
    def inertia(self) -> float:
        """I_xx = I_yy = I_zz = (2/5)·m·R² about the sphere centre, Eq. C.8 [kg·m²]."""
        return 0.4 * self.mass * self.radius**2

    @property
    def com_depth(self) -> float:
        """h = 3R/8: distance of the centre of mass below the sphere centre, Eq. C.16 [m]."""
        return 3.0 / 8.0 * self.radius

    @property
    def R_CoM(self) -> float:
        """√(R² − h²) = √(55/64)·R, Eq. C.17 [m]."""
        return math.sqrt(self.radius**2 - self.com_depth**2)

    def describe(self, prefix: str = "table") -> list[Quantity]:
        g, d = "given", "derived"
        out = [Quantity(f"{prefix}.R_table", self.radius, "m", g, "Table D.1/D.2")]
        if self.density is not None:
            out += [
                Quantity(f"{prefix}.rho_table", self.density, "kg/m^3", g, "Table D.1"),
                Quantity(f"{prefix}.m_half_sphere_eqC1", self.mass_half_sphere, "kg", d, "Eq. C.1"),
                Quantity(
                    f"{prefix}.m_table_D1_listed",
                    2.0 * self.mass_half_sphere,
                    "kg",
                    d,
                    "Table D.1 lists 0.0335 = (4/3)*pi*R^3*rho, twice Eq. C.1",
                ),
            ]
        out += [
            Quantity(
                f"{prefix}.m_table",
                self.mass,
                "kg",
                g if self.mass_given is not None else d,
                "Table D.2"
                if self.mass_given is not None
                else f"mass convention '{self.mass_convention}'",
            ),
            Quantity(
                f"{prefix}.I_table",
                self.inertia,
                "kg*m^2",
                d,
                "Eq. C.8, 2/5*m*R^2 (Table D.1: 1.340e-6 with m = 0.0335)",
            ),
            Quantity(f"{prefix}.h_CoM", self.com_depth, "m", d, "Eq. C.16, 3R/8 below the centre"),
            Quantity(f"{prefix}.R_CoM", self.R_CoM, "m", d, "Eq. C.17, sqrt(55/64)*R"),
        ]
        return out
