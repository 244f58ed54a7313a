"""Laser and quadrant photodiode (§4.1.1, §4.1.3): table angle ↔ detector voltage.

Eq. 4.1: x_spot = V·S, θ = ½·arctan(x_spot/L) — the reflected beam turns by 2θ.
Eq. 4.2: x_table = θ·R_table, the displacement at the contact radius.
S = 9.9e-5 m/V is linear within ±0.2 mm of spot travel (Fig. 4.4); beyond it the
photodiode output saturates (modelled as a hard clip at ±0.2 mm/S = ±2.02 V).
Optional additive Gaussian voltage noise.

Two properties of the rig, not of Eq. 4.1 (the laboratory's conversion knows neither):

* the beam reads the tilt of the *mirror*, not the table's rotation: a rotation θ about
  axis u tilts a mirror of normal m by θ·|u × m| (``tilt_factor``). A mirror lying on
  the table's flat face (m vertical) under a rotation about a tube axis (35.26° below
  the horizon, Eq. 3.2) tilts by θ·cos 35.26° = 0.8165·θ; one facing the axis's
  perpendicular tilts by θ (the default, as the thesis reads Eq. 4.1);
* the photodiode's volts per metre of spot travel may differ from the calibrated 1/S
  (``gain``: true over calibrated, Fig. 4.4).

:meth:`Detector.voltage` is what the photodiode outputs for a table angle; :meth:`angle`
is the laboratory's Eq. 4.1 reading of a voltage; :meth:`table_angle` the table angle behind
a reading for a lab that knows its rig (a calibration's mirror tilt and gain).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .quantities import Quantity
from .validation import check_array_finite, check_nonnegative, check_positive

__all__ = ["Detector", "mirror_tilt_factor"]


@dataclass(frozen=True)
class Detector:
    """Detector geometry and calibration.

    Args:
        sensitivity: S [m/V] (9.9e-5).
        distance: L between reflection point and detector [m] (0.175).
        linear_range: half-width of the linear spot range [m] (0.2e-3).
        table_radius: R_table for Eq. 4.2 [m].
        noise_std: standard deviation of additive voltage noise [V] (0 = noise off).
        tilt_factor: mirror tilt per table rotation about the watched axis, |u × m| [-]
            (module docstring; :func:`mirror_tilt_factor`).
        gain: photodiode volts per metre of spot travel, times S [-] (1: Fig. 4.4 exact).
    """

    sensitivity: float = 9.9e-5
    distance: float = 0.175
    linear_range: float = 0.2e-3
    table_radius: float = 0.01
    noise_std: float = 0.0
    tilt_factor: float = 1.0
    gain: float = 1.0

    def __post_init__(self) -> None:
        check_positive("sensitivity", self.sensitivity)
        check_positive("distance", self.distance)
        check_positive("linear_range", self.linear_range)
        check_positive("table_radius", self.table_radius)
        check_nonnegative("noise_std", self.noise_std)
        if not 0.0 < check_positive("tilt_factor", self.tilt_factor) <= 1.0:
            raise ValueError(f"tilt_factor={self.tilt_factor!r}: must be in (0, 1]")
        check_positive("gain", self.gain)

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
        v = self.unclipped_voltage(th)
        if rng is not None and self.noise_std > 0.0:
            v = v + rng.normal(0.0, self.noise_std, size=v.shape)
        vs = self.saturation_voltage
        return np.clip(v, -vs, vs)

    def unclipped_voltage(self, angle: np.ndarray) -> np.ndarray:
        """Photodiode output [V] for table angle θ [rad] before saturation (Eq. 4.1 inverted
        for the mirror's tilt, times the gain; no validation: the compiled-path helper)."""
        th = 2.0 * angle if self.tilt_factor == 1.0 else 2.0 * self.tilt_factor * angle
        v = self.distance * np.tan(th) / self.sensitivity
        return v if self.gain == 1.0 else self.gain * v

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

    def table_angle(self, reading: np.ndarray | float) -> np.ndarray | float:
        """The table angle θ [rad] behind a laboratory reading r = :meth:`angle` [rad]: Eq. 4.1
        inverted for this rig's mirror tilt t and gain g, tan 2r = g·tan(2t·θ), so
        θ = arctan(tan(2r)/g)/(2t) (the identity for t = g = 1; what a lab that calibrated its
        rig converts its readings with). Unclipped: a saturated reading gives the edge."""
        if self.tilt_factor == 1.0 and self.gain == 1.0:
            return reading
        return np.arctan(np.tan(2.0 * np.asarray(reading)) / self.gain) / (2.0 * self.tilt_factor)

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
            Quantity(
                f"{prefix}.tilt_factor", self.tilt_factor, "-", g,
                "mirror tilt per table rotation |u x m| (1: as Eq. 4.1 is read)",
            ),
            Quantity(f"{prefix}.gain", self.gain, "-", g, "photodiode V per m of spot, times S"),
        ]


def mirror_tilt_factor(axis_unit: np.ndarray, mirror_normal: np.ndarray) -> float:
    """|u × m|: the tilt of a mirror of normal ``mirror_normal`` per unit table rotation
    about ``axis_unit`` (both in the table frame; normalised here) [-]. A horizontal mirror
    (m = z) under a rotation about a tube axis at α = 35.26° below the horizon gives
    cos α = 0.8165."""
    u = np.asarray(axis_unit, dtype=float)
    m = np.asarray(mirror_normal, dtype=float)
    u = u / np.linalg.norm(u)
    m = m / np.linalg.norm(m)
    return float(np.linalg.norm(np.cross(u, m)))
