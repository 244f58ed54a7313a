"""What a laboratory knows: the information a controller may use, apart from ground truth.

A controller receives the observations (the detector's reading, the commanded target, its
own last action, the generator phase) and, at the start of an episode, a :class:`LabBrief`
— the commanded move as a lab would know it. Everything else the simulator knows (the
true angle, the plant's parameters, the randomisation draw, the reset ``info``) is
evaluation-only: the runners (:func:`~controllers.episode.run_episode`, the benchmark)
keep it for the metrics and never hand it over, and :class:`~controllers.base.Controller`
refuses anything but a :class:`LabBrief` at reset.

The dead-reckoned start models the usual laboratory situation of a table that left the
detector's range: the lab knows roughly how far it moved it (from the steps it
commanded), with a stated relative error of the move (e.g. ±30 %), and the estimate it
is given carries such an error (the benchmark draws it per seed, the same for every
controller).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from turntable_env.validation import check_finite, check_int, check_nonnegative

__all__ = ["LabBrief", "dead_reckoned_start"]


@dataclass(frozen=True)
class LabBrief:
    """What a lab knows at the start of an episode (SI units).

    Attributes:
        target_rad: the commanded target now [rad] (also the observation's target).
        start_estimate_rad: dead-reckoned start angle [rad], or None: the lab knows the
            start only from the detector (whose reading saturates beyond ±θ_lin).
        start_error: stated relative error of the dead-reckoned move |target − start| [-]
            (0.3: the true move lies within ±30 % of the estimated one).
        reference_rad: the commanded reference, one target per control interval (index
            k: the target at time k·Δt) [rad], or None for a fixed target.
    """

    target_rad: float
    start_estimate_rad: float | None = None
    start_error: float = 0.0
    reference_rad: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "target_rad", check_finite("target_rad", self.target_rad))
        if self.start_estimate_rad is not None:
            x = check_finite("start_estimate_rad", self.start_estimate_rad)
            object.__setattr__(self, "start_estimate_rad", x)
        err = check_nonnegative("start_error", self.start_error)
        object.__setattr__(self, "start_error", err)
        if self.reference_rad is not None:
            try:
                ref = np.asarray(self.reference_rad, dtype=float)
            except (TypeError, ValueError):  # text, complex numbers
                raise ValueError(
                    f"reference_rad={self.reference_rad!r}: must be a sequence of angles [rad]"
                ) from None
            if ref.ndim != 1 or ref.size == 0 or not np.isfinite(ref).all():
                raise ValueError(
                    f"reference_rad: need a non-empty sequence of finite angles, got shape "
                    f"{ref.shape}"
                )
            object.__setattr__(self, "reference_rad", tuple(float(x) for x in ref))

    def reference_at(self, k: int) -> float:
        """The commanded target at interval k [rad] (the last value after the end)."""
        k = check_int("k", k)
        if self.reference_rad is None:
            return self.target_rad
        return self.reference_rad[min(max(k, 0), len(self.reference_rad) - 1)]


def dead_reckoned_start(
    start_rad: float, target_rad: float, error: float, rng: np.random.Generator
) -> float:
    """A dead-reckoned start [rad]: the target less the true move scaled by 1 + ε, ε drawn
    uniformly in ±``error`` (the lab's belief about a move it commanded)."""
    check_nonnegative("error", error)
    eps = float(rng.uniform(-error, error)) if error > 0.0 else 0.0
    est = target_rad - (target_rad - start_rad) * (1.0 + eps)
    return est if math.isfinite(est) else start_rad
