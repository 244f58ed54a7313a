"""Compliant contact between a tube's ball and the table (§3.3): parameters and elastic theory.

The thesis models each contact with a 1-D normal spring ``f_z = k_z x_z`` that
exists only while the bodies overlap, GMS friction in the average tangent plane
(Eq. 3.24–3.26) and no spin friction (ω_z of the contact twist is not an input
of the friction model, §3.3.2 — the tubes cannot exert torsion on the table).

Table D.2 gives the contact parameters of the scaled model. The real turntable's
are not in the thesis; :class:`HertzContact` derives them from elasticity:

* Hertz (normal): F = K_H δ^{3/2}, K_H = (4/3)E*√R*, contact radius
  a = (3FR*/4E*)^{1/3}, tangent stiffness dF/dδ = 2E*a.
* Mindlin (tangential, constant normal force): initial stiffness 8G*a and the
  tangential displacement at gross slip δ_slip = 3μF/(16G*a) — the GMS
  presliding distance of §4.2.1.

with 1/E* = (1−ν₁²)/E₁ + (1−ν₂²)/E₂, 1/G* = (2−ν₁)/G₁ + (2−ν₂)/G₂ and
1/R* = 1/R₁ + 1/R₂ (two convex spheres). Reference: K.L. Johnson, *Contact
Mechanics* (1985), §4.2 and §7.2 (Eq. 7.42).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .quantities import Quantity
from .validation import check_finite, check_in_open, check_nonnegative, check_positive

__all__ = ["ContactParams", "ElasticMaterial", "HertzContact"]


@dataclass(frozen=True)
class ElasticMaterial:
    """Isotropic elastic solid.

    Args:
        name: label used in printed sources.
        youngs_modulus: E [Pa].
        poisson: ν [-].
    """

    name: str
    youngs_modulus: float
    poisson: float

    def __post_init__(self) -> None:
        check_positive("youngs_modulus", self.youngs_modulus)
        check_in_open("poisson", self.poisson, -1.0, 0.5)

    @property
    def shear_modulus(self) -> float:
        """G = E/(2(1+ν)) [Pa]."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson))

    @property
    def contact_modulus(self) -> float:
        """E/(1−ν²) [Pa]: the body's stiffness against indentation (its weight in Eq. 3.24)."""
        return self.youngs_modulus / (1.0 - self.poisson**2)


@dataclass(frozen=True)
class HertzContact:
    """Hertz–Mindlin contact of two convex elastic spheres (see module docstring).

    Args:
        radius_1, material_1: body 1 (the tube's ball) [m].
        radius_2, material_2: body 2 (the table) [m].
    """

    radius_1: float
    material_1: ElasticMaterial
    radius_2: float
    material_2: ElasticMaterial

    def __post_init__(self) -> None:
        check_positive("radius_1", self.radius_1)
        check_positive("radius_2", self.radius_2)

    @property
    def effective_radius(self) -> float:
        """R* = (1/R₁ + 1/R₂)⁻¹ [m]."""
        return 1.0 / (1.0 / self.radius_1 + 1.0 / self.radius_2)

    @property
    def effective_modulus(self) -> float:
        """E* = ((1−ν₁²)/E₁ + (1−ν₂²)/E₂)⁻¹ [Pa]."""
        return 1.0 / (1.0 / self.material_1.contact_modulus + 1.0 / self.material_2.contact_modulus)

    @property
    def effective_shear_modulus(self) -> float:
        """G* = ((2−ν₁)/G₁ + (2−ν₂)/G₂)⁻¹ [Pa] (Mindlin)."""
        m1, m2 = self.material_1, self.material_2
        return 1.0 / ((2.0 - m1.poisson) / m1.shear_modulus + (2.0 - m2.poisson) / m2.shear_modulus)

    @property
    def hertz_constant(self) -> float:
        """K_H = (4/3)E*√R* [N/m^1.5] in F = K_H δ^{3/2}."""
        return 4.0 / 3.0 * self.effective_modulus * math.sqrt(self.effective_radius)

    def contact_radius(self, normal_force: float) -> float:
        """a = (3FR*/(4E*))^{1/3} [m]."""
        f = check_positive("normal_force", normal_force)
        return (3.0 * f * self.effective_radius / (4.0 * self.effective_modulus)) ** (1.0 / 3.0)

    def approach(self, normal_force: float) -> float:
        """Normal approach δ = a²/R* = (F/K_H)^{2/3} [m]."""
        return self.contact_radius(normal_force) ** 2 / self.effective_radius

    def normal_stiffness(self, normal_force: float) -> float:
        """Tangent normal stiffness dF/dδ = 2E*a [N/m]."""
        return 2.0 * self.effective_modulus * self.contact_radius(normal_force)

    def tangential_stiffness(self, normal_force: float) -> float:
        """Mindlin's initial tangential stiffness 8G*a [N/m]."""
        return 8.0 * self.effective_shear_modulus * self.contact_radius(normal_force)

    def slip_displacement(self, normal_force: float, mu: float) -> float:
        """Tangential displacement at gross slip, 3μF/(16G*a) [m] (Johnson Eq. 7.42, Q = μF)."""
        m = check_positive("mu", mu)
        f = check_positive("normal_force", normal_force)
        return 3.0 * m * f / (16.0 * self.effective_shear_modulus * self.contact_radius(f))

    def describe(self, normal_force: float, mu: float, prefix: str = "hertz") -> list[Quantity]:
        d = "derived"
        f = normal_force
        return [
            Quantity(f"{prefix}.R_star", self.effective_radius, "m", d, "1/R* = 1/R_o + 1/R_table"),
            Quantity(f"{prefix}.E_star", self.effective_modulus, "Pa", d, "Johnson §4.2"),
            Quantity(f"{prefix}.G_star", self.effective_shear_modulus, "Pa", d, "Mindlin"),
            Quantity(f"{prefix}.K_H", self.hertz_constant, "N/m^1.5", d, "(4/3)E* sqrt(R*)"),
            Quantity(f"{prefix}.a", self.contact_radius(f), "m", d, "(3 F R*/4E*)^(1/3) at F_N"),
            Quantity(f"{prefix}.approach", self.approach(f), "m", d, "a^2/R* at F_N"),
            Quantity(f"{prefix}.k_normal", self.normal_stiffness(f), "N/m", d, "2E*a at F_N"),
            Quantity(
                f"{prefix}.k_tangential", self.tangential_stiffness(f), "N/m", d, "8G*a at F_N"
            ),
            Quantity(
                f"{prefix}.slip_displacement",
                self.slip_displacement(f, mu),
                "m",
                d,
                "3 mu_s F/(16 G* a), Johnson Eq. 7.42: the GMS presliding distance",
            ),
        ]


@dataclass(frozen=True)
class ContactParams:
    """Normal contact law, Eq. 3.24 weights and the preload of one ball–table contact.

    Normal force while the bodies overlap by δ > 0 [m]:
    F = k_c δ^e + d_c δ̇, never negative (contact loss when separated, §3.3.1).

    Args:
        normal_stiffness: k_c [N/m^e] (Table D.2: 2000 N/m with e = 1; real: Hertz K_H).
        normal_exponent: e (1: the thesis's linear spring; 1.5: Hertz).
        normal_damping: d_c [N·s/m].
        compressibility_tube, compressibility_table: the weights k₁, k₂ of Eq. 3.24–3.25
            [Table D.2: N/m; real: each body's E/(1−ν²), Pa]. The plane sits nearer the
            stiffer body's undeformed surface.
        preload: static normal force of each contact F_N [N]; the preload spring on top
            of the table is sized to give it (:meth:`preload_spring_force`).
        tangential_damping: β_t [s]: each *sticking* GMS element i adds a damper β_t·k_i in
            parallel (presliding micro-damping, the role of LuGre's σ₁); a slipping element
            adds none. 0 in Table D.2 (the thesis has no tangential damping).
        listed_contact_radius: Table D.2's "R_contact" [m] (printed, not used).
        source: where the values come from (printed).
    """

    normal_stiffness: float = 2000.0
    normal_exponent: float = 1.0
    normal_damping: float = 10.0
    compressibility_tube: float = 1000.0
    compressibility_table: float = 1000.0
    preload: float = 100.0
    listed_contact_radius: float | None = 2.0
    tangential_damping: float = 0.0
    source: str = "Table D.2"

    def __post_init__(self) -> None:
        check_positive("normal_stiffness", self.normal_stiffness)
        e = check_finite("normal_exponent", self.normal_exponent)
        if not 1.0 <= e <= 2.0:
            raise ValueError(f"normal_exponent={self.normal_exponent!r}: must be in [1, 2]")
        check_nonnegative("normal_damping", self.normal_damping)
        check_positive("compressibility_tube", self.compressibility_tube)
        check_positive("compressibility_table", self.compressibility_table)
        check_positive("preload", self.preload)
        check_nonnegative("tangential_damping", self.tangential_damping)
        if self.listed_contact_radius is not None:
            check_positive("listed_contact_radius", self.listed_contact_radius)

    def normal_force(self, overlap: float) -> float:
        """Elastic normal force k_c δ^e [N] for an overlap δ [m] (0 when separated)."""
        d = check_finite("overlap", overlap)
        return self.normal_stiffness * d**self.normal_exponent if d > 0.0 else 0.0

    @property
    def static_overlap(self) -> float:
        """Overlap at the preload, (F_N/k_c)^{1/e} [m]."""
        return (self.preload / self.normal_stiffness) ** (1.0 / self.normal_exponent)

    @property
    def static_stiffness(self) -> float:
        """Tangent normal stiffness at the preload, e·F_N/δ₀ [N/m]."""
        return self.normal_exponent * self.preload / self.static_overlap

    def preload_spring_force(self, table_weight: float, sin_alpha: float) -> float:
        """Force of the preload spring on top of the table [N] for F_N per contact.

        Three contact normals point at the sphere centre, each at α below the horizon:
        3·F_N·sin α = P + m g. Raises ValueError if P would have to pull.
        """
        w = check_nonnegative("table_weight", table_weight)
        p = 3.0 * self.preload * check_positive("sin_alpha", sin_alpha) - w
        if p < 0.0:
            raise ValueError(
                f"preload={self.preload!r}: three contacts carry {3 * self.preload * sin_alpha:.4g}"
                f" N upwards, less than the table weight {w:.4g} N"
            )
        return p

    def describe(self, prefix: str = "contact") -> list[Quantity]:
        g = "given"
        unit_k = "N/m" if self.normal_exponent == 1.0 else f"N/m^{self.normal_exponent:g}"
        out = [
            Quantity(f"{prefix}.k_c", self.normal_stiffness, unit_k, g, self.source),
            Quantity(f"{prefix}.exponent", self.normal_exponent, "-", g, self.source),
            Quantity(f"{prefix}.d_c", self.normal_damping, "N*s/m", g, self.source),
            Quantity(f"{prefix}.k_1", self.compressibility_tube, "-", g, "Eq. 3.24 weight, ball"),
            Quantity(f"{prefix}.k_2", self.compressibility_table, "-", g, "Eq. 3.24 weight, table"),
            Quantity(f"{prefix}.F_N", self.preload, "N", g, self.source),
            Quantity(
                f"{prefix}.beta_t",
                self.tangential_damping,
                "s",
                g,
                f"{self.source}; damper beta_t*k_i on each sticking GMS element",
            ),
            Quantity(
                f"{prefix}.static_overlap", self.static_overlap, "m", "derived", "(F_N/k_c)^(1/e)"
            ),
            Quantity(
                f"{prefix}.static_stiffness",
                self.static_stiffness,
                "N/m",
                "derived",
                "e*F_N/overlap",
            ),
        ]
        if self.listed_contact_radius is not None:
            out.append(
                Quantity(
                    f"{prefix}.R_contact_listed",
                    self.listed_contact_radius,
                    "m",
                    g,
                    "Table D.2 (not Eq. 3.1; not used for the geometry)",
                )
            )
        return out
