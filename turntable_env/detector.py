"""Laser and quadrant photodiode (§4.1.1, §4.1.3): table angle ↔ detector voltage.

Eq. 4.1: x_spot = V·S, θ = ½·arctan(x_spot/L) — the reflected beam turns by 2θ.
Eq. 4.2: x_table = θ·R_table, the displacement at the contact radius.
S = 9.9e-5 m/V is linear within ±0.2 mm of spot travel (Fig. 4.4); beyond it the
photodiode output saturates (modelled as a hard clip at ±0.2 mm/S = ±2.02 V).
Optional additive Gaussian voltage noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .quantities import Quantity
from .validation import check_array_finite, check_nonnegative, check_positive

__all__ = ["Detector"]


@dataclass(frozen=True)
class Detector:
    """Detector geometry and calibration.

    Args:
        sensitivity: S [m/V] (9.9e-5).
        distance: L between reflection point and detector [m] (0.175).
        linear_range: half-width of the linear spot range [m] (0.2e-3).
        table_radius: R_table for Eq. 4.2 [m].
        noise_std: standard deviation of additive voltage noise [V] (0 = noise off).
    """

    sensitivity: float = 9.9e-5
    distance: float = 0.175
    linear_range: float = 0.2e-3
    table_radius: float = 0.01
    noise_std: float = 0.0

    def __post_init__(self) -> None:
        check_positive("sensitivity", self.sensitivity)
        check_positive("distance", self.distance)
        check_positive("linear_range", self.linear_range)
        check_positive("table_radius", self.table_radius)
        check_nonnegative("noise_std", self.noise_std)

    @property
    def saturation_voltage(self) -> float:
        """Output at the edge of the linear range, linear_range/S [V] (2.02 V)."""
        return self.linear_range / self.sensitivity

    @property
    def angle_range(self) -> float:
        """Largest table angle inside the linear range, ½·arctan(range/L) [rad]."""
        return 0.5 * math.atan(self.linear_range / self.distance)

    # forward ----------------------------------------------------------------------
    def voltage(
        self, angle: np.ndarray | float, rng: np.random.Generator | None = None
    ) -> np.ndarray:
        """Detector output [V] for table angle θ [rad] (inverse of Eq. 4.1, with saturation).

        Noise (``noise_std``) is added when an ``rng`` is given; the result is clipped
        to the saturation voltage after the noise, as the photodiode electronics do.
        """
        th = check_array_finite("angle", angle)
        if (np.abs(th) >= math.pi / 4).any():
            raise ValueError(f"angle={angle!r}: |θ| must be < π/4 (beam leaves the detector plane)")
        x_spot = self.distance * np.tan(2.0 * th)
        v = x_spot / self.sensitivity
        if rng is not None and self.noise_std > 0.0:
            v = v + rng.normal(0.0, self.noise_std, size=v.shape)
        vs = self.saturation_voltage
        return np.clip(v, -vs, vs)

    def is_saturated(self, voltage: np.ndarray | float) -> np.ndarray:
        """True where a reading sits at the saturation voltage (angle not recoverable)."""
        v = check_array_finite("voltage", voltage)
        return np.abs(v) >= self.saturation_voltage * (1.0 - 1e-12)

    # inverse ----------------------------------------------------------------------
    def spot_displacement(self, voltage: np.ndarray | float) -> np.ndarray:
        """x_spot = V·S [m] (§4.1.1)."""
        return check_array_finite("voltage", voltage) * self.sensitivity

    def angle(self, voltage: np.ndarray | float) -> np.ndarray:
        """Table angle θ = ½·arctan(V·S/L) [rad], Eq. 4.1."""
        return 0.5 * np.arctan(self.spot_displacement(voltage) / self.distance)

    def table_displacement(self, voltage: np.ndarray | float) -> np.ndarray:
        """Displacement at the table radius x_table = θ·R_table [m], Eq. 4.2."""
        return self.angle(voltage) * self.table_radius

    def describe(self, prefix: str = "detector") -> list[Quantity]:
        g, d = "given", "derived"
        return [
            Quantity(f"{prefix}.S", self.sensitivity, "m/V", g, "Fig. 4.4, §4.1.3"),
            Quantity(f"{prefix}.L", self.distance, "m", g, "§4.1.1"),
            Quantity(f"{prefix}.linear_range", self.linear_range, "m", g, "±0.2 mm, Fig. 4.4"),
            Quantity(
                f"{prefix}.saturation_voltage", self.saturation_voltage, "V", d, "linear_range/S"
            ),
            Quantity(
                f"{prefix}.angle_range", self.angle_range, "rad", d, "0.5*arctan(linear_range/L)"
            ),
            Quantity(f"{prefix}.noise_std", self.noise_std, "V", g, "additive noise (0 = off)"),
        ]
