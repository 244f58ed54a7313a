"""Piezo tube as a structural element: stiffness (App. B) and mass properties (App. C.1–C.2).

Implements Eq. B.3–B.4 (area moments), B.6 (bending stiffness K_x = K_y),
B.8 (elongation stiffness K_z), B.10 (torsional stiffness K_φ), C.2 (mass of the
tube with its Al₂O₃ ball) and C.11–C.14 (mass moment of inertia lumped at the
tube top). The variable spatial spring that uses these numbers (Eq. 3.4–3.18)
belongs to the assembled model.

Thesis inconsistency kept visible: Eq. C.12–C.13 move the cylinder's inertia to
the top with R_par = (L/2, L/2, 0), i.e. |R_par|² = L²/2 and a factor 7/12·mL²;
the tube's centre of mass is L/2 *along the axis* from the top, which gives
1/3·mL². ``parallel_axis="thesis"`` (default) reproduces Table D.1's
I_tube = (1.500e-8, 1.500e-8, 6.121e-9) kg·m²; ``"physical"`` gives the latter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .piezo import PiezoMaterial, PiezoQuadrant
from .quantities import Quantity
from .screw import homogeneous, merge_stiffness
from .validation import check_nonnegative, check_positive

__all__ = ["TubeParams", "TubeStiffness"]


@dataclass(frozen=True)
class TubeStiffness:
    """Diagonal stiffnesses of a tube at its top (the thesis uses diagonal matrices, App. D).

    Attributes:
        translational: (K_x, K_y, K_z) [N/m] — bending, bending, elongation.
        rotational: (K_ox, K_oy, K_oz) [N·m/rad] — about x, y (bending) and z (torsion, K_φ).
    """

    translational: tuple[float, float, float]
    rotational: tuple[float, float, float]

    def __post_init__(self) -> None:
        for i, k in enumerate(self.translational):
            check_positive(f"translational[{i}]", k)
        for i, k in enumerate(self.rotational):
            check_positive(f"rotational[{i}]", k)

    def matrix(self) -> np.ndarray:
        """6×6 diagonal stiffness diag(K_ox, K_oy, K_oz, K_x, K_y, K_z) in (ω, v) twist order."""
        return np.diag([*self.rotational, *self.translational])


@dataclass(frozen=True)
class TubeParams:
    """Geometry and material of one piezo tube with the ball on its top (Table D.1).

    Args:
        outer_radius: R_o [m]; the Al₂O₃ ball on top has the same radius (App. C.1).
        inner_radius: R_i [m].
        length: L [m].
        density: ρ_tube of the PZT [kg/m³].
        ball_density: ρ_ball of the Al₂O₃ ball [kg/m³].
        material: piezo constants (E = 1/s₃₃ᴱ, ν).
        diameter_convention: the D of Eq. 2.12 (see :mod:`turntable_env.piezo`).
        parallel_axis: ``"thesis"`` (Eq. C.13, reproduces Table D.1) or ``"physical"``.
        mass_given: if set, a total mass [kg] given by a table instead of Eq. C.2 (Table D.2).
        stiffness_given: if set, stiffnesses given by a table instead of App. B (Table D.2).
        bending_lever_given: if set, the Eq. 3.16 radius given by a table [m] (Table D.2's
            "R_bending = 2 m") instead of πD/(2√2).
        ball_seat_height: distance from the tube's end face to the ball centre [m]; None
            derives it for a ball of radius R_o resting on the bore's inner edge,
            √(R_o² − R_i²).
        quality_factor: mechanical quality factor Q_m of the tube (None: undamped).
        axial_coupling: include the quadrants' mean axial strain in the rest twist.
        axial_strain_sign: +1 if a quadrant whose voltage turns the tip towards its side
            shortens (a field along the poling, d₃₁ < 0: what the tube equations assume),
            −1 if it lengthens (the opposite poling relative to the electrode wiring; the
            bending is the same, the mean axial strain flips).
        stroke_scale: factor on d₃₁ (and on ε₁₁ by its square, so the coupling k² is
            unchanged); 1 for the real tube (see ``thesis_parameters``).
        source: where the given geometry comes from (printed by ``describe``).
    """

    outer_radius: float = 3.175e-3
    inner_radius: float = 2.667e-3
    length: float = 6.35e-3
    density: float = 7.8e3
    ball_density: float = 3.98e3
    material: PiezoMaterial = field(default_factory=PiezoMaterial)
    diameter_convention: Literal["mean", "outer"] = "mean"
    parallel_axis: Literal["thesis", "physical"] = "thesis"
    mass_given: float | None = None
    stiffness_given: TubeStiffness | None = None
    bending_lever_given: float | None = None
    ball_seat_height: float | None = None
    quality_factor: float | None = None
    axial_coupling: bool = True
    axial_strain_sign: int = 1
    stroke_scale: float = 1.0
    source: str = "Table D.1"

    def __post_init__(self) -> None:
        check_positive("outer_radius", self.outer_radius)
        check_positive("inner_radius", self.inner_radius)
        check_positive("length", self.length)
        check_positive("density", self.density)
        check_positive("ball_density", self.ball_density)
        if self.inner_radius >= self.outer_radius:
            raise ValueError(
                f"inner_radius={self.inner_radius!r}: must be < outer_radius={self.outer_radius!r}"
            )
        if self.parallel_axis not in ("thesis", "physical"):
            raise ValueError(
                f"parallel_axis={self.parallel_axis!r}: must be 'thesis' or 'physical'"
            )
        if self.mass_given is not None:
            check_positive("mass_given", self.mass_given)
        if self.bending_lever_given is not None:
            check_positive("bending_lever_given", self.bending_lever_given)
        if self.ball_seat_height is not None:
            check_nonnegative("ball_seat_height", self.ball_seat_height)
        if self.quality_factor is not None:
            check_positive("quality_factor", self.quality_factor)
        if not isinstance(self.axial_coupling, bool):
            raise ValueError(f"axial_coupling={self.axial_coupling!r}: must be a bool")
        s = self.axial_strain_sign  # an int: True and 1.0 equal 1 but are not a sign
        if isinstance(s, bool) or not isinstance(s, int) or s not in (1, -1):
            raise ValueError(f"axial_strain_sign={s!r}: must be +1 or -1")
        check_positive("stroke_scale", self.stroke_scale)
        # constructing the quadrant validates diameter_convention
        _ = self.quadrant

    # --- piezo ---------------------------------------------------------------------
    @property
    def quadrant(self) -> PiezoQuadrant:
        """The 2-port C element of one electrode quadrant (Eq. 2.2)."""
        m = self.material
        if self.stroke_scale != 1.0:
            s = self.stroke_scale
            m = PiezoMaterial(m.d31 * s, m.s33E, m.eps11T_rel * s * s, m.poisson)
        return PiezoQuadrant(
            material=m,
            length=self.length,
            outer_radius=self.outer_radius,
            inner_radius=self.inner_radius,
            diameter_convention=self.diameter_convention,
        )

    @property
    def bending_lever(self) -> float:
        """Radius used in Eq. 3.16 to turn quadrant elongation into tip rotation [m]."""
        if self.bending_lever_given is not None:
            return self.bending_lever_given
        return self.quadrant.bending_lever

    # --- App. B --------------------------------------------------------------------
    @property
    def wall_thickness(self) -> float:
        """h = R_o − R_i [m]."""
        return self.outer_radius - self.inner_radius

    @property
    def polar_area_moment(self) -> float:
        """I_p = π(R_o⁴ − R_i⁴)/2, Eq. B.3 [m⁴]."""
        return math.pi * (self.outer_radius**4 - self.inner_radius**4) / 2.0

    @property
    def area_moment(self) -> float:
        """I_x = I_y = I_p/2, Eq. B.4 [m⁴]."""
        return 0.5 * self.polar_area_moment

    @property
    def K_bending(self) -> float:
        """K_x = K_y = 3EI_x/L³, Eq. B.6 [N/m] (Table D.1: 2.471e7)."""
        return 3.0 * self.material.youngs_modulus * self.area_moment / self.length**3

    @property
    def K_axial(self) -> float:
        """K_z = EA/L = πE(R_o² − R_i²)/L, Eq. B.8 [N/m] (Table D.1: 7.728e7)."""
        area = math.pi * (self.outer_radius**2 - self.inner_radius**2)
        return self.material.youngs_modulus * area / self.length

    @property
    def K_torsion(self) -> float:
        """K_φ = GI_p/L, Eq. B.10 [N·m/rad] (Table D.1: 253.6)."""
        return self.material.shear_modulus * self.polar_area_moment / self.length

    @property
    def K_rot_bending(self) -> float:
        """Rotational bending stiffness at the tip under a pure moment, EI_x/L [N·m/rad].

        Not in the thesis (Table D.1 gives only K_x, K_z, K_φ); Euler–Bernoulli.
        """
        return self.material.youngs_modulus * self.area_moment / self.length

    @property
    def stiffness(self) -> TubeStiffness:
        """Tip stiffnesses: given (Table D.2) or from App. B."""
        if self.stiffness_given is not None:
            return self.stiffness_given
        kb = self.K_bending
        kr = self.K_rot_bending
        return TubeStiffness((kb, kb, self.K_axial), (kr, kr, self.K_torsion))

    # --- §3.2: the variable spatial spring ------------------------------------------
    @property
    def seat_height(self) -> float:
        """Tube end face → ball centre [m]: given, or √(R_o² − R_i²) (ball on the bore edge)."""
        if self.ball_seat_height is not None:
            return self.ball_seat_height
        return math.sqrt(self.outer_radius**2 - self.inner_radius**2)

    @property
    def stiffness_centre_offset(self) -> float:
        """Distance from the top (end face) down the axis to the centre of stiffness [m]:
        L/2 for the derived Euler–Bernoulli spring, 0 for given (tip) stiffnesses."""
        return 0.0 if self.stiffness_given is not None else 0.5 * self.length

    @property
    def centre_stiffness(self) -> np.ndarray:
        """6×6 stiffness at the centre of stiffness (mid-length), tube frame, (ω, v) order.

        Derived: diag(EI/L, EI/L, GI_p/L, 12EI/L³, 12EI/L³, EA/L), the Euler–Bernoulli
        cantilever seen from its centre of compliance (gives K_x = 3EI/L³ at the top).
        Given (Table D.2): the listed diagonal, at the top (see the module docstring).
        """
        if self.stiffness_given is not None:
            return self.stiffness_given.matrix()
        ei = self.material.youngs_modulus * self.area_moment
        L = self.length
        return np.diag(
            [ei / L, ei / L, self.K_torsion, 12.0 * ei / L**3, 12.0 * ei / L**3, self.K_axial]
        )

    @staticmethod
    def quadrant_directions() -> np.ndarray:
        """Unit bending directions b_q (tube frame) of quadrants q = 0..3: +x, +y, −x, −y.

        A positive voltage moves the free tip towards b_q (asymmetric mode, Eq. 2.11).
        """
        return np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])

    def quadrant_springs(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The four quadrant springs (stiffness in own frame, H from the centre frame).

        Quadrant q's frame is the centre frame turned by 90°·q about the tube axis; each
        carries a quarter of :attr:`centre_stiffness` (Eq. 3.17).
        """
        kq = 0.25 * self.centre_stiffness
        hs = []
        for q in range(4):
            c, s = math.cos(q * math.pi / 2), math.sin(q * math.pi / 2)
            rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # centre → quadrant
            hs.append(homogeneous(rot, np.zeros(3)))
        return [kq] * 4, hs

    @property
    def spring_stiffness(self) -> np.ndarray:
        """The merged spring at the tube centre, Σ Ad_Hᵀ K_q Ad_H (Eq. 3.18) [tube frame]."""
        ks, hs = self.quadrant_springs()
        return merge_stiffness(ks, hs)

    @property
    def rest_twist_per_volt(self) -> np.ndarray:
        """G: 6×4 matrix, column q = rest displacement twist of the centre spring per volt on
        quadrant q (Eq. 3.16) [rad/V, m/V], tube frame."""
        quad = self.quadrant
        z_per_v = quad.free_elongation(1.0)  # signed, negative for d31 < 0 [m/V]
        g_theta = abs(z_per_v) / self.bending_lever  # rad/V
        g_axial = 0.0
        if self.axial_coupling:  # mean strain × L [m/V]
            g_axial = 0.25 * z_per_v * self.axial_strain_sign
        ez = np.array([0.0, 0.0, 1.0])
        g = np.zeros((6, 4))
        for q, b in enumerate(self.quadrant_directions()):
            g[:3, q] = g_theta * np.cross(ez, b)
            g[5, q] = g_axial
        return g

    @property
    def blocked_capacitance_matrix(self) -> np.ndarray:
        """C_s = C_free·I − GᵀKG [F], 4×4: the quadrants' capacitance at fixed deflection.

        Raises ValueError if it is not positive definite (coupling too strong to be passive).
        """
        g = self.rest_twist_per_volt
        cs = self.quadrant.capacitance * np.eye(4) - g.T @ self.spring_stiffness @ g
        if np.linalg.eigvalsh(cs).min() <= 0.0:
            raise ValueError(
                f"stroke_scale={self.stroke_scale!r}: the quadrant coupling G^T K G exceeds the "
                "free capacitance (stored energy indefinite)"
            )
        return cs

    @property
    def first_bending_frequency(self) -> float:
        """ω₁ = √(K_x/m_tube) [rad/s] of the lumped tube (App. B stiffness, App. C mass)."""
        return math.sqrt(self.stiffness.translational[0] / self.mass)

    @property
    def damping_coefficient(self) -> float:
        """β = 1/(Q_m ω₁) [s] of the stiffness-proportional damping D = βK (0 if undamped)."""
        if self.quality_factor is None:
            return 0.0
        return 1.0 / (self.quality_factor * self.first_bending_frequency)

    # --- App. C --------------------------------------------------------------------
    @property
    def mass_cylinder(self) -> float:
        """ρ_tube π(R_o² − R_i²)L, first term of Eq. C.2 [kg]."""
        return self.density * math.pi * (self.outer_radius**2 - self.inner_radius**2) * self.length

    @property
    def mass_ball(self) -> float:
        """ρ_ball (4/3)πR_o³, second term of Eq. C.2 [kg]."""
        return self.ball_density * 4.0 / 3.0 * math.pi * self.outer_radius**3

    @property
    def mass(self) -> float:
        """m_tube,tot, Eq. C.2 (Table D.1: 9.954e-4 kg), or the given mass."""
        if self.mass_given is not None:
            return self.mass_given
        return self.mass_cylinder + self.mass_ball

    @property
    def inertia(self) -> np.ndarray:
        """(I_xx, I_yy, I_zz) lumped at the tube top, Eq. C.14 [kg·m²].

        Table D.1: (1.500e-8, 1.500e-8, 6.121e-9). With ``mass_given`` (no ball,
        no wall data in Table D.2) the cylinder terms of C.13 use the given mass.
        """
        ro2, ri2, L = self.outer_radius**2, self.inner_radius**2, self.length
        if self.mass_given is not None:
            mc, mb = self.mass_given, 0.0
        else:
            mc, mb = self.mass_cylinder, self.mass_ball
        shift = 7.0 / 12.0 if self.parallel_axis == "thesis" else 1.0 / 3.0
        i_ball = 0.4 * mb * ro2
        ixx = 0.25 * mc * (ro2 + ri2) + shift * mc * L**2 + i_ball
        izz = 0.5 * mc * (ro2 + ri2) + i_ball
        return np.array([ixx, ixx, izz])

    def describe(self, prefix: str = "tube") -> list[Quantity]:
        """Every given and derived tube quantity."""
        g, d = "given", "derived"
        q = self.quadrant
        out = [
            Quantity(f"{prefix}.R_o", self.outer_radius, "m", g, self.source),
            Quantity(f"{prefix}.R_i", self.inner_radius, "m", g, self.source),
            Quantity(f"{prefix}.L", self.length, "m", g, self.source),
            Quantity(f"{prefix}.rho_tube", self.density, "kg/m^3", g, self.source),
            Quantity(f"{prefix}.rho_ball", self.ball_density, "kg/m^3", g, self.source),
            Quantity(
                f"{prefix}.h", self.wall_thickness, "m", d, "h = R_o - R_i (Table D.1: 0.508e-3)"
            ),
            Quantity(
                f"{prefix}.D",
                q.diameter,
                "m",
                d,
                f"diameter in Eq. 2.12, convention '{self.diameter_convention}'",
            ),
            Quantity(f"{prefix}.I_area", self.area_moment, "m^4", d, "Eq. B.4"),
            Quantity(f"{prefix}.I_polar", self.polar_area_moment, "m^4", d, "Eq. B.3"),
            Quantity(
                f"{prefix}.K_x_eqB6", self.K_bending, "N/m", d, "Eq. B.6 (Table D.1: 2.471e7)"
            ),
            Quantity(f"{prefix}.K_z_eqB8", self.K_axial, "N/m", d, "Eq. B.8 (Table D.1: 7.728e7)"),
            Quantity(
                f"{prefix}.K_phi_eqB10", self.K_torsion, "N*m/rad", d, "Eq. B.10 (Table D.1: 253.6)"
            ),
            Quantity(
                f"{prefix}.K_rot_bending_EI_over_L",
                self.K_rot_bending,
                "N*m/rad",
                d,
                "EI/L, Euler-Bernoulli (not in thesis)",
            ),
            Quantity(
                f"{prefix}.stiffness_translational",
                list(self.stiffness.translational),
                "N/m",
                g if self.stiffness_given else d,
                "Table D.2 (K_t)" if self.stiffness_given else "Eq. B.6, B.6, B.8",
            ),
            Quantity(
                f"{prefix}.stiffness_rotational",
                list(self.stiffness.rotational),
                "N*m/rad",
                g if self.stiffness_given else d,
                "Table D.2 (K_o)" if self.stiffness_given else "EI/L, EI/L, Eq. B.10",
            ),
            Quantity(f"{prefix}.m_cylinder", self.mass_cylinder, "kg", d, "Eq. C.2, first term"),
            Quantity(f"{prefix}.m_ball", self.mass_ball, "kg", d, "Eq. C.2, second term"),
            Quantity(
                f"{prefix}.m_tube",
                self.mass,
                "kg",
                g if self.mass_given is not None else d,
                "Table D.2" if self.mass_given is not None else "Eq. C.2 (Table D.1: 9.954e-4)",
            ),
            Quantity(
                f"{prefix}.I_tube",
                self.inertia.tolist(),
                "kg*m^2",
                d,
                f"Eq. C.14, parallel axis '{self.parallel_axis}' "
                "(Table D.1: 1.500e-8, 1.500e-8, 6.121e-9)",
            ),
            Quantity(f"{prefix}.C_quadrant", q.capacitance, "F", d, "eps11T*A_e/h, Eq. 2.2"),
            Quantity(
                f"{prefix}.C_quadrant_blocked",
                q.blocked_capacitance,
                "F",
                d,
                "C*(1 - k^2), Eq. 2.2 at z = 0",
            ),
            Quantity(
                f"{prefix}.R_bending_times_V",
                q.bending_radius_times_voltage,
                "V*m",
                d,
                "Eq. 2.12 (Table D.1: 1.570e4)",
            ),
            Quantity(
                f"{prefix}.R_bending_times_V_outer_D",
                PiezoQuadrant(
                    self.material, self.length, self.outer_radius, self.inner_radius, "outer"
                ).bending_radius_times_voltage,
                "V*m",
                d,
                "Eq. 2.12 with D = 2R_o (does not match Table D.1)",
            ),
            Quantity(
                f"{prefix}.bending_lever_eq212",
                q.bending_lever,
                "m",
                d,
                "pi*D/(2*sqrt(2)) = R_bending*V*|d31|/h",
            ),
            Quantity(
                f"{prefix}.bending_lever",
                self.bending_lever,
                "m",
                g if self.bending_lever_given is not None else d,
                "Table D.2 R_bending"
                if self.bending_lever_given is not None
                else "pi*D/(2*sqrt(2)); radius of Eq. 3.16",
            ),
            Quantity(
                f"{prefix}.free_elongation_per_V",
                q.free_elongation(1.0),
                "m/V",
                d,
                "d31*L/h, Eq. 2.2 at F = 0",
            ),
            Quantity(
                f"{prefix}.tip_deflection_per_V",
                q.tip_deflection(1.0),
                "m/V",
                d,
                "Eq. 2.11 asymmetric (half of symmetric)",
            ),
        ]
        return out
