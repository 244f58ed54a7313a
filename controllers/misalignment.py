"""The detector's axis misalignment learned online from its two channels.

A quadrant photodiode reads the spot's travel on two axes. When its x axis is not the
watched rotation's (§4.3: the axes are not perpendicular; the catalogue's
``axis_misalignment``), a rotation θ reads θ·cos φ on x and θ·sin φ on y (Eq. 4.1 on each
channel), so a controller that holds x on the target θ* leaves the table at θ*/cos φ:
70 nm beyond a target at 0.93·θ_lin for φ = 0.16 rad, outside the benchmark's 30 nm band,
and no controller that reads x alone can tell (``experiments/observability_bound.py``).

With both channels the slope t = tan φ is the least-squares slope of y on x through the
origin over the episode's valid readings,

    t̂ = Σ x·y / (Σ x² + θ₀²)

(θ₀ = ``PRIOR_SPREAD``: a prior of zero slope worth one reading at 10 µrad, so the first
readings near zero, whose y is all noise, do not tilt it), and the table angle is
x·√(1 + t̂²) = x / cos φ̂. The correction is of second order in φ̂, so the estimate's noise
(σ_y / √Σx²) costs nothing measurable where the rig is aligned; a y channel that reads
something else (another axis turning, an offset) shows as a slope only in so far as it
correlates with x.
"""

from __future__ import annotations

import math

__all__ = ["PRIOR_SPREAD", "AxisMisalignment"]

PRIOR_SPREAD = 1e-5  # rad, θ₀ (module docstring; 100 nm at R = 10 mm, 30× a reading's σ)


class AxisMisalignment:
    """Online tan φ from (x, y) readings and the table angle behind an x reading (module
    docstring). Angles in rad."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the readings (a new episode: another plant may be behind the env)."""
        self._sxy = 0.0
        self._sxx = 0.0

    def update(self, x: float, y: float) -> None:
        """One pair of valid (unsaturated) readings [rad]."""
        if math.isfinite(x) and math.isfinite(y):
            self._sxy += x * y
            self._sxx += x * x

    @property
    def slope(self) -> float:
        """t̂ = tan φ̂ [-] (0 before any reading)."""
        return self._sxy / (self._sxx + PRIOR_SPREAD**2)

    def table_angle(self, x: float) -> float:
        """The table angle [rad] behind the x reading ``x`` [rad]: x·√(1 + t̂²)."""
        return x * math.sqrt(1.0 + self.slope**2)
