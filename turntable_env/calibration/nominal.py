"""The nominal model a trace calibration fits: the quantities that set a stick–slip step
and its transients, as factors on a base plant, with priors and physical bounds.

Every parameter is a multiplicative factor on the base plant's value (the shipped
``calibrated`` set by default, :mod:`turntable_env.params`), fitted as its natural
logarithm with a normal prior N(0, σ²) — a factor e^{±σ} is one standard deviation —
and bounds from the physics — a factor's from the one factor table
(:data:`turntable_env.params.FACTORS`), a rig field's from ``RIG_LIMITS``:

=================  ===================================================  =====  ============
name               what it scales (where)                               σ(ln)  bounds
=================  ===================================================  =====  ============
stroke             piezo stroke per volt: large-signal d₃₁, the drive   0.3    RIG_LIMITS
                   gain and lever of the rig (rig ``d31_factor``)
detector_gain      photodiode volts per metre of spot (rig)             0.05   RIG_LIMITS
friction           μ_s and μ_c together (factor)                        0.5    FACTORS
coulomb            μ_c alone, μ_c ≤ μ_s (factor)                        0.2    FACTORS, μ_s/μ_c
stribeck_velocity  v_S of the Stribeck curve (factor)                   1.0    FACTORS
preload            normal force F_N (factor; Hertz stiffness follows)   0.5    FACTORS
presliding         presliding distance, i.e. the GMS element            0.7    RIG_LIMITS
                   stiffnesses k_i = ν_iμ_sF_N/δ_i (rig)
contact_damping    tangential micro-slip damping β_t (bristle σ₁)      1.5    FACTORS
tube_damping       the tubes' loss 1/Q_m (factor)                       0.7    FACTORS
inertia            table mass and inertia, mirror and mount (rig)       0.3    RIG_LIMITS
amplifier_slew     the amplifier's slew per input volt (settling time   0.7    FACTORS
                   τ ÷, §4.1.2; factor ``amplifier_slew``)
amplifier_current  the amplifier's current limit, which caps its slew   0.7    FACTORS
                   on the quadrant's capacitance (``amplifier_current``)
=================  ===================================================  =====  ============

The amplifier is structure, not an effect: every lab's unit is not the datasheet's HVA 900
(§4.1.2), and a slower one makes smaller steps that friction, preload and stroke would
otherwise absorb, so its two scales are fitted with the rest. The calibration names the
catalogue's ``amplifier_dynamics`` when they end away from the datasheet
(:func:`~turntable_env.calibration.trace_fit.amplifier_finding`). The detector offset is
not fitted: the anchored residual (:mod:`.residual`) does not see it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from ..params import FACTORS, RIG_LIMITS
from ..plant import Plant

__all__ = ["NOMINAL_PARAMETERS", "NominalModel", "NominalParameter"]


@dataclass(frozen=True)
class NominalParameter:
    """One nominal parameter: a factor on the base plant (module docstring). Its bounds are
    not its own: a factor's are the one factor table's (:data:`~turntable_env.params.
    FACTORS`), a rig field's the rig's limits (:data:`~turntable_env.params.RIG_LIMITS`),
    both relative to the base plant's value.

    Attributes:
        name: its name in reports; target: ``"factor"`` (Plant.factors) or ``"rig"``
        (a RigParams field); key: the factor's or field's name; sigma: prior standard
        deviation of ln(factor); meaning: text.
    """

    name: str
    target: Literal["factor", "rig"]
    key: str
    sigma: float
    meaning: str


NOMINAL_PARAMETERS: tuple[NominalParameter, ...] = (
    NominalParameter("stroke", "rig", "d31_factor", 0.3,
                     "piezo stroke per volt (d31, drive gain, lever)"),
    NominalParameter("detector_gain", "rig", "detector_gain", 0.05,
                     "photodiode volts per metre of spot"),
    NominalParameter("friction", "factor", "friction", 0.5,
                     "friction coefficients mu_s and mu_c"),
    NominalParameter("coulomb", "factor", "coulomb", 0.2,
                     "Coulomb level mu_c alone (mu_c <= mu_s)"),
    NominalParameter("stribeck_velocity", "factor", "stribeck_velocity", 1.0,
                     "Stribeck velocity v_S"),
    NominalParameter("preload", "factor", "preload", 0.5,
                     "normal force F_N (Hertz stiffness follows)"),
    NominalParameter("presliding", "rig", "presliding_factor", 0.7,
                     "presliding distance (GMS stiffness 1/delta)"),
    NominalParameter("contact_damping", "factor", "contact_damping", 1.5,
                     "tangential micro-slip damping of the contact (bristle damping)"),
    NominalParameter("tube_damping", "factor", "tube_damping", 0.7,
                     "tube loss 1/Q_m"),
    NominalParameter("inertia", "rig", "inertia_factor", 0.3,
                     "table mass and inertia (mirror and mount)"),
    NominalParameter("amplifier_slew", "factor", "amplifier_slew", 0.7,
                     "amplifier slew per input volt (settling time 1/x)"),
    NominalParameter("amplifier_current", "factor", "amplifier_current", 0.7,
                     "amplifier current limit (slew cap on the quadrant)"),
)  # fmt: skip


class NominalModel:
    """Plants of a nominal parameter vector x = ln(factors) on a base plant.

    Args:
        base: the base plant (its set, rig, effects and amplifier; fidelity as given).
        names: the parameters to fit (default: all of :data:`NOMINAL_PARAMETERS`).
    """

    def __init__(self, base: Plant, names: tuple[str, ...] | None = None) -> None:
        table = {p.name: p for p in NOMINAL_PARAMETERS}
        names = tuple(table) if names is None else tuple(names)
        for n in names:
            if n not in table:
                raise ValueError(f"nominal parameter {n!r}: choose from {', '.join(table)}")
        self.base = base
        self.parameters = tuple(table[n] for n in names)
        self.base_rig = base.base_parameters.rig
        ps = base.params
        lo, hi = [], []
        for p in self.parameters:
            if p.target == "rig":
                r_lo, r_hi = RIG_LIMITS[p.key]
                v = getattr(self.base_rig, p.key)
            else:
                r_lo, r_hi, _ = FACTORS[p.key]
                v = base.factors.get(p.key, 1.0)
            low, high = r_lo / v, r_hi / v
            if p.key == "coulomb" and ps.unlisted is not None:
                high = min(high, ps.unlisted.mu_static / ps.unlisted.mu_coulomb)
            lo.append(math.log(low))
            hi.append(math.log(high))
        self.low = np.array(lo)
        self.high = np.array(hi)
        self.sigma = np.array([p.sigma for p in self.parameters])

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def __len__(self) -> int:
        return len(self.parameters)

    def factors(self, x: np.ndarray) -> dict[str, float]:
        """name → factor of a vector x (ln factors)."""
        return {p.name: float(math.exp(v)) for p, v in zip(self.parameters, x, strict=True)}

    def plant(
        self, x: np.ndarray, effects: Mapping[str, Mapping[str, float]] | None = None
    ) -> Plant:
        """The base plant with the factors of x and, on top of its own, ``effects``."""
        factors = dict(self.base.factors)
        rig: dict[str, Any] = {}
        for p, v in zip(self.parameters, x, strict=True):
            f = math.exp(float(v))
            if p.target == "factor":
                factors[p.key] = factors.get(p.key, 1.0) * f
            else:  # within the rig's limits (exp∘log may round past a bound)
                r_lo, r_hi = RIG_LIMITS[p.key]
                rig[p.key] = min(max(getattr(self.base_rig, p.key) * f, r_lo), r_hi)
        return self.base.replace(
            factors=factors,
            rig=replace(self.base_rig, **rig) if rig else self.base.rig,
            effects={**self.base.effects, **(effects or {})},
        )
