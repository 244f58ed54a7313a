"""Turntable geometry: tube placement (Eq. 3.1–3.3) and the centre-of-mass check of §3.1.

Three mutually orthogonal tubes whose axes meet at the sphere centre touch the
table at distance R_table from it; the contact points span a circle of radius
R_contact = √(2/3)·R_table (the "grey circle" of Fig. 3.2). α is the angle between
a tube axis and that circle's plane.

§3.1's stability criterion: the table is stable only if its centre of mass lies
below the plane spanned by the contact points, i.e. if R_CoM < R_contact. For the
current design R_CoM = √(55/64)·R > R_contact = √(2/3)·R: *unstable*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .quantities import Quantity
from .validation import check_positive

__all__ = ["ComStability", "TurntableGeometry", "com_stability"]

BETA = math.pi / 3.0  # rad, half the 120° angle between contact points on the circle (Fig. 3.2)


@dataclass(frozen=True)
class TurntableGeometry:
    """Derived placement of the tubes (Eq. 3.1–3.3).

    Args:
        table_radius: R_table [m].
        tube_length: L_tube [m].
    """

    table_radius: float
    tube_length: float

    def __post_init__(self) -> None:
        check_positive("table_radius", self.table_radius)
        check_positive("tube_length", self.tube_length)

    @property
    def beta(self) -> float:
        """β = 60° [rad] (Fig. 3.2)."""
        return BETA

    @property
    def tube_dist(self) -> float:
        """Distance between two contact points, √2·R_table, Eq. 3.1 [m]."""
        return math.sqrt(2.0) * self.table_radius

    @property
    def R_contact(self) -> float:
        """Radius of the circle through the contact points, tube_dist/(2 sin β), Eq. 3.1 [m]."""
        return self.tube_dist / (2.0 * math.sin(BETA))

    @property
    def alpha(self) -> float:
        """α = arccos(R_contact/R_table), Eq. 3.2 [rad] (35.26° for orthogonal tubes)."""
        return math.acos(self.R_contact / self.table_radius)

    @property
    def z_table(self) -> float:
        """Height of the table top above O, R_contact·tan α + L_tube·sin α, Eq. 3.3 [m]."""
        return self.R_contact * math.tan(self.alpha) + self.tube_length * math.sin(self.alpha)

    @property
    def contact_plane_depth(self) -> float:
        """Depth of the contact-point plane below the sphere centre, √(R² − R_contact²) [m]."""
        return math.sqrt(self.table_radius**2 - self.R_contact**2)

    def describe(self, prefix: str = "geometry") -> list[Quantity]:
        d = "derived"
        return [
            Quantity(f"{prefix}.beta", self.beta, "rad", d, "Fig. 3.2, 60 deg"),
            Quantity(f"{prefix}.tube_dist", self.tube_dist, "m", d, "Eq. 3.1, sqrt(2)*R_table"),
            Quantity(f"{prefix}.R_contact", self.R_contact, "m", d, "Eq. 3.1, sqrt(2/3)*R_table"),
            Quantity(f"{prefix}.alpha", self.alpha, "rad", d, "Eq. 3.2"),
            Quantity(f"{prefix}.z_table", self.z_table, "m", d, "Eq. 3.3"),
            Quantity(
                f"{prefix}.contact_plane_depth",
                self.contact_plane_depth,
                "m",
                d,
                "sqrt(R_table^2 - R_contact^2)",
            ),
        ]


@dataclass(frozen=True)
class ComStability:
    """Result of the §3.1 centre-of-mass check (lengths in m)."""

    R_CoM: float
    R_contact: float
    com_depth: float
    contact_plane_depth: float

    @property
    def stable(self) -> bool:
        """True if the CoM lies below the contact plane (R_CoM < R_contact)."""
        return self.R_CoM < self.R_contact

    @property
    def margin(self) -> float:
        """com_depth − contact_plane_depth [m]; negative: CoM above the contact plane."""
        return self.com_depth - self.contact_plane_depth


def com_stability(table_radius: float, com_depth: float | None = None) -> ComStability:
    """§3.1 stability check of a table resting on three orthogonal tubes.

    Args:
        table_radius: R_table [m].
        com_depth: depth of the centre of mass below the sphere centre [m]; defaults to
            the homogeneous half sphere's 3R/8 (Eq. C.16).

    Returns:
        :class:`ComStability`; ``.stable`` is False for the thesis design.
    """
    r = check_positive("table_radius", table_radius)
    h = 3.0 / 8.0 * r if com_depth is None else check_positive("com_depth", com_depth)
    if h >= r:
        raise ValueError(f"com_depth={com_depth!r}: must be < table_radius={r!r}")
    geo = TurntableGeometry(r, 1.0)
    return ComStability(
        R_CoM=math.sqrt(r * r - h * h),
        R_contact=geo.R_contact,
        com_depth=h,
        contact_plane_depth=geo.contact_plane_depth,
    )
