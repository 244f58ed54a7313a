"""The thesis's two parameter sets (App. D) as immutable objects in SI units.

* ``"real"`` — Table D.1, the real turntable. Everything derivable is derived:
  stiffnesses (App. B), masses and inertias (App. C), geometry (Eq. 3.1–3.3),
  R_bending (Eq. 2.12), quadrant capacitance (Eq. 2.2), E = 1/s₃₃ᴱ.
* ``"thesis"`` — Table D.2, the scaled parameters the thesis simulated. Per App.
  D, values not listed in D.2 are taken from D.1. D.2 gives some quantities
  directly (table and tube masses, tube stiffnesses, R_bending); those are kept
  as *given* and the formula value is printed beside them where one exists.

Thesis inconsistencies, kept visible (``turntable params --json`` prints both sides):

1. R_bending·V = 1.570e4 V·m (Table D.1) needs D = R_o + R_i in Eq. 2.12; 2R_o gives 1.706e4.
2. m_table = 0.0335 kg (Table D.1) is twice Eq. C.1's half sphere (0.01676 kg); the
   default uses Eq. C.1 (``TableParams.mass_convention``).
3. Eq. C.13's parallel-axis shift (7/12·mL²) treats the CoM offset as (L/2, L/2, 0);
   the default reproduces Table D.1, ``parallel_axis="physical"`` gives 1/3·mL².
4. Table D.2's "R_bending = 2 m" is a constant length (the lever of Eq. 3.16,
   πD/(2√2) = 2.04 m for the scaled tube), not the voltage-dependent Eq. 2.12.
5. Table D.2's "R_contact = 2 m" differs from Eq. 3.1 (√(2/3)·3.15 = 2.57 m), which
   orthogonal tubes require; the geometry uses Eq. 3.1, the listed value is printed.

The scaled tube's wall is not in Table D.2: R_i is set so that h/R_o equals the real
tube's (0.16), which reproduces D.2's R_bending lever to 2 % — evidence for reading 4.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Literal

from .amplifier import Amplifier
from .detector import Detector
from .friction import GMS, StribeckParams
from .geometry import TurntableGeometry, com_stability
from .quantities import Quantity
from .table import TableParams
from .tube import TubeParams, TubeStiffness
from .validation import check_in_open, check_nonnegative, check_positive

__all__ = [
    "ContactParams",
    "ParameterSet",
    "get_parameter_set",
    "real_parameters",
    "thesis_parameters",
]


@dataclass(frozen=True)
class ContactParams:
    """Contact parameters (Table D.2; the real values are derived with the 3D model).

    Args:
        normal_stiffness: k_c of the 1-D normal contact spring [N/m].
        normal_damping: d_c [N·s/m].
        compressibility_tube, compressibility_table: k₁, k₂ of Eq. 3.24–3.25 [N/m].
        preload: normal force F_N [N].
        listed_contact_radius: Table D.2's "R_contact" [m] (printed, see module docstring).
    """

    normal_stiffness: float = 2000.0
    normal_damping: float = 10.0
    compressibility_tube: float = 1000.0
    compressibility_table: float = 1000.0
    preload: float = 100.0
    listed_contact_radius: float | None = 2.0

    def __post_init__(self) -> None:
        check_positive("normal_stiffness", self.normal_stiffness)
        check_nonnegative("normal_damping", self.normal_damping)
        check_positive("compressibility_tube", self.compressibility_tube)
        check_positive("compressibility_table", self.compressibility_table)
        check_positive("preload", self.preload)
        if self.listed_contact_radius is not None:
            check_positive("listed_contact_radius", self.listed_contact_radius)

    def describe(self, prefix: str = "contact") -> list[Quantity]:
        g = "given"
        out = [
            Quantity(f"{prefix}.k_c", self.normal_stiffness, "N/m", g, "Table D.2"),
            Quantity(f"{prefix}.d_c", self.normal_damping, "N*s/m", g, "Table D.2"),
            Quantity(f"{prefix}.k_1", self.compressibility_tube, "N/m", g, "Table D.2, Eq. 3.24"),
            Quantity(f"{prefix}.k_2", self.compressibility_table, "N/m", g, "Table D.2, Eq. 3.24"),
            Quantity(f"{prefix}.F_N", self.preload, "N", g, "Table D.2"),
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


@dataclass(frozen=True)
class ParameterSet:
    """A complete, immutable parameter set.

    Args:
        name: ``"real"`` or ``"thesis"`` (or a user label).
        table, tube: structural parameters.
        friction: GMS contact friction (None until derived for the real set).
        contact: contact parameters (None until derived for the real set).
        amplifier, detector: §4.1 hardware.
        ramp_ratio: default position of the sawtooth maximum a (Table D.1: 0.95).
    """

    name: str
    table: TableParams
    tube: TubeParams
    friction: GMS | None = None
    contact: ContactParams | None = None
    amplifier: Amplifier = field(default_factory=Amplifier)
    detector: Detector = field(default_factory=Detector)
    ramp_ratio: float = 0.95

    def __post_init__(self) -> None:
        check_in_open("ramp_ratio", self.ramp_ratio, 0.0, 1.0)
        if self.detector.table_radius != self.table.radius:
            raise ValueError(
                f"detector.table_radius={self.detector.table_radius!r}: must equal "
                f"table.radius={self.table.radius!r}"
            )

    @property
    def geometry(self) -> TurntableGeometry:
        return TurntableGeometry(self.table.radius, self.tube.length)

    def describe(self) -> list[Quantity]:
        """Every given and derived quantity, with unit and source."""
        out: list[Quantity] = []
        out += self.table.describe()
        out += self.tube.describe()
        m = self.tube.material
        out += [
            Quantity("piezo.d31", m.d31, "m/V", "given", "Table D.1"),
            Quantity("piezo.s33E", m.s33E, "m^2/N", "given", "Table D.1"),
            Quantity("piezo.eps11T_rel", m.eps11T_rel, "-", "given", "Table D.1 (2400 eps0)"),
            Quantity("piezo.eps11T", m.eps11T, "F/m", "derived", "2400*eps0"),
            Quantity("piezo.poisson", m.poisson, "-", "given", "App. B.3"),
            Quantity(
                "piezo.E", m.youngs_modulus, "N/m^2", "derived", "1/s33E (Table D.1: 5.263e10)"
            ),
            Quantity("piezo.G", m.shear_modulus, "N/m^2", "derived", "E/(2(1+nu)), App. B.3"),
            Quantity("piezo.k31_squared", m.coupling_k2, "-", "derived", "d31^2/(s33E*eps11T)"),
            Quantity("drive.a", self.ramp_ratio, "-", "given", "Table D.1"),
        ]
        out += self.geometry.describe()
        cs = com_stability(self.table.radius)
        out += [
            Quantity(
                "geometry.com_stable",
                cs.stable,
                "-",
                "derived",
                "§3.1: stable iff R_CoM < R_contact",
            ),
            Quantity(
                "geometry.com_margin",
                cs.margin,
                "m",
                "derived",
                "CoM depth - contact-plane depth (< 0: CoM above the plane)",
            ),
        ]
        if self.friction is not None:
            out += self.friction.describe()
        if self.contact is not None:
            out += self.contact.describe()
        out += self.amplifier.describe()
        out += self.detector.describe()
        names = [q.name for q in out]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise RuntimeError(f"duplicate parameter names: {sorted(dup)}")
        return out

    def to_dict(self) -> dict:
        return {"set": self.name, "parameters": {q.name: q.to_dict() for q in self.describe()}}

    def to_json(self, indent: int = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)


def real_parameters() -> ParameterSet:
    """Table D.1: the real turntable (friction and contact come with the 3D model)."""
    table = TableParams(radius=0.01, density=8.0e3)
    return ParameterSet(
        name="real", table=table, tube=TubeParams(), detector=Detector(table_radius=table.radius)
    )


def thesis_parameters() -> ParameterSet:
    """Table D.2: the scaled parameters of the thesis's simulations (D.1 where D.2 is silent)."""
    table = TableParams(radius=3.15, density=None, mass_given=15.0)
    r_tube = 1.0
    h_ratio = (3.175e-3 - 2.667e-3) / 3.175e-3  # real tube's h/R_o, see module docstring
    tube = TubeParams(
        outer_radius=r_tube,
        inner_radius=r_tube * (1.0 - h_ratio),
        length=2.0,
        mass_given=0.5,
        stiffness_given=TubeStiffness(
            translational=(1e5, 1e5, 1e5), rotational=(100.0, 100.0, 1e5)
        ),
        bending_lever_given=2.0,
        source="Table D.2 (R_tube, L); R_i from the real tube's h/R_o; densities from D.1 (unused)",
    )
    friction = GMS(
        stribeck=StribeckParams(mu_s=0.3, mu_c=0.05, v_s=0.8, delta=2.0, sigma2=0.0),
        nu=(0.06, 0.15, 0.21, 0.27, 0.31),
        k=(400.0, 643.0, 1260.0, 1350.0, 1233.0),
        C=200.0,
    )
    return ParameterSet(
        name="thesis",
        table=table,
        tube=tube,
        friction=friction,
        contact=ContactParams(),
        detector=Detector(table_radius=table.radius),
    )


def get_parameter_set(name: Literal["real", "thesis"]) -> ParameterSet:
    """``"real"`` (Table D.1) or ``"thesis"`` (Table D.2)."""
    if name == "real":
        return real_parameters()
    if name == "thesis":
        return thesis_parameters()
    raise ValueError(f"set={name!r}: must be 'real' or 'thesis'")
