"""The settings a map controller may step with blind: those whose direction does not
depend on the plant.

A move made with the reading saturated (the table beyond the detector) cannot be checked,
and a setting that steps backwards on the plant at hand runs the table away until the
safety monitor's blind budget is spent (:mod:`controllers.base`). Whether a setting keeps
its direction is a property of the stick–slip dynamics, not of one plant: at 9.5 V and
2 kHz the flyback (50 µs) is under three time constants of the nominal amplifier, and a
plant with more friction and preload, or a slower amplifier, steps backwards there.

``experiments/blind_settings.py`` surveys the map planner's family (a = 0.9, k = 1) over
160 plants, friction and preload ×0.5–2 and amplifier ×0.5–1.5 around Table D.1, and
writes, per (frequency, amplitude), the worst steady step over the map's across the plants
and both directions (``controllers/data/blind_settings.csv``). A setting is *robust* when
that worst ratio is at least −``BLIND_TOLERANCE``: blind, it can run the table backwards
by at most that share of the travel the controller believes it made.

``ASYMMETRY_PATH`` (``controllers/data/blind_asymmetry.csv``) is the same survey on the env's
default model (the per-axis model with the sphere's translation) with the catalogue's
friction asymmetry, |α| <= 0.3: only 2–3 V at 100–500 Hz keep their direction there. The
step controllers and the agents take it as ``blind_settings=``; it is not their default,
since those slow settings miss the long moves in time on plants that step far under the map
(``experiments/blind_tradeoff.py``, docs/controllers.md).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from turntable_env.validation import check_finite, check_positive, describe

from .step_map import read_table

__all__ = [
    "ASYMMETRY_PATH",
    "BLIND_PATH",
    "BLIND_TOLERANCE",
    "BlindSettings",
    "check_blind_settings",
]

BLIND_PATH = Path(__file__).parent / "data" / "blind_settings.csv"
# the same survey on the env's default model with the catalogue's friction asymmetry
# (|α| <= 0.3): its robust settings keep their direction there, and are the slowest ones
ASYMMETRY_PATH = Path(__file__).parent / "data" / "blind_asymmetry.csv"
BLIND_TOLERANCE = 0.05  # largest backward step a blind setting may take, × the map's
COLUMNS = ("frequency_hz", "amplitude_v", "worst_ratio", "backward_share")


class BlindSettings:
    """The survey's worst step ratio per setting (module docstring).

    Args:
        worst: (frequency [Hz], amplitude [V]) → worst steady step over the map's [-].
    """

    def __init__(self, worst: Mapping[tuple[float, float], float]) -> None:
        if not isinstance(worst, Mapping):
            raise ValueError(f"worst={describe(worst)}: must be a mapping (Hz, V) → ratio")
        self.worst: dict[tuple[float, float], float] = {}
        for key, ratio in worst.items():
            if not (isinstance(key, tuple) and len(key) == 2):
                raise ValueError(
                    f"worst[{describe(key)}]: a key must be (frequency [Hz], amplitude [V])"
                )
            f = check_positive("worst: frequency", key[0])
            a = check_positive("worst: amplitude", key[1])
            self.worst[(round(f, 6), round(a, 6))] = check_finite(f"worst[{key!r}]", ratio)

    def robust(
        self, amplitude: np.ndarray, frequency: np.ndarray, tolerance: float = BLIND_TOLERANCE
    ) -> np.ndarray:
        """Mask of the settings (|amplitude| [V], frequency [Hz]) whose worst ratio is at
        least −``tolerance``; a setting the survey did not cover is not robust."""
        amps = np.abs(np.asarray(amplitude, dtype=float))
        freqs = np.asarray(frequency, dtype=float)
        out = np.zeros(amps.shape, dtype=bool)
        for i, (a, f) in enumerate(zip(amps.ravel(), freqs.ravel(), strict=True)):
            w = self.worst.get((round(float(f), 6), round(float(a), 6)), -math.inf)
            out.flat[i] = w >= -tolerance
        return out

    @classmethod
    @functools.cache
    def load(cls, path: str | Path = BLIND_PATH) -> BlindSettings:
        """Read the survey's file; a defect raises ValueError naming file, line and column."""
        p = Path(path)
        worst: dict[tuple[float, float], float] = {}
        for row in read_table(p, COLUMNS)[1]:
            ln = row[-1]
            vals = []
            for col, cell in zip(COLUMNS, row[:-1], strict=True):
                try:
                    v = float(cell)
                except ValueError:
                    v = math.nan
                if not math.isfinite(v):
                    raise ValueError(f"{p}:{ln}: column {col!r} = {cell!r}, not a number")
                vals.append(v)
            f, a, w, _share = vals
            if f <= 0.0 or a <= 0.0:
                raise ValueError(f"{p}:{ln}: frequency {f!r} Hz and amplitude {a!r} V "
                                 "must be positive")  # fmt: skip
            worst[(round(f, 6), round(a, 6))] = w
        return cls(worst)

    def save(self, path: str | Path, shares: dict[tuple[float, float], float],
             comment: str) -> Path:  # fmt: skip
        """Write the table (``shares``: the backward share per setting) with ``# comment``
        lines, atomically."""
        from turntable_env.files import write_atomic

        lines = [f"# {c}" for c in comment.splitlines()]
        lines.append(",".join(COLUMNS))
        for (f, a), w in sorted(self.worst.items()):
            lines.append(f"{f:g},{a:g},{w:.4f},{shares[(f, a)]:.4f}")
        return write_atomic(path, "\n".join(lines) + "\n")


def check_blind_settings(value: object) -> BlindSettings | None:
    """``value`` if it is a :class:`BlindSettings` or None (the caller's default); else a
    ValueError naming its type (every public ``blind_settings=`` argument)."""
    if value is not None and not isinstance(value, BlindSettings):
        raise ValueError(f"blind_settings={type(value).__name__}: must be a BlindSettings or None")
    return value
