"""The settings a map controller may step with blind: those whose direction does not
depend on the plant.

A move made with the reading saturated (the table beyond the detector) cannot be checked,
and a setting that steps backwards on the plant at hand runs the table away until the
safety monitor's blind budget is spent (:mod:`controllers.base`). Whether a setting keeps
its direction is a property of the stick–slip dynamics, not of one plant: at 9.5 V and
2 kHz the flyback (50 µs) is under three time constants of the nominal amplifier, and a
plant with more friction and preload, or a slower amplifier, steps backwards there.

``experiments/blind_settings.py`` surveys the step map's waveforms over a plant family and
writes, per (frequency, amplitude, a, k), the worst steady step over the map's across the
plants and both directions. A setting is *robust* when that worst ratio is at least
−``BLIND_TOLERANCE``: blind, it can run the table backwards by at most that share of the
travel the controller believes it made.

``ASYMMETRY_PATH`` (``controllers/data/blind_asymmetry.csv``; the default since stop 101)
is the survey on the env's default model (the per-axis model with the sphere's
translation) over 32 plants, friction and preload ×0.5–2 and amplifier ×0.5–1.5 around
Table D.1 with the catalogue's friction asymmetry |α| <= 0.3, of the planner's waveform
(a = 0.9, k = 1) and of a = 0.6, k = 1. In the planner's waveform only 2–3 V at
100–500 Hz keep their direction there; with a = 0.6 also 2.5–4.5 V at 2 kHz, the blind
set's fastest by far (5 V there steps backwards on a surveyed plant). A blind move may use
either waveform; every other move keeps the planner's.

``BLIND_PATH`` (``controllers/data/blind_settings.csv``, the default until stop 101) is the
first survey: the planner's waveform on the per-axis model without effects over 160
plants (a grid and 60 drawn in the same box). Its fastest, 6–6.5 V at 1 kHz, steps
backwards on held-out seed 18 (α = 0.24) of the benchmark; ``experiments/blind_tradeoff.py``
runs every controller with both sets side by side.
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

BLIND_PATH = Path(__file__).parent / "data" / "blind_settings.csv"  # the first survey
# the survey on the env's default model with the catalogue's friction asymmetry (|α| <= 0.3)
# and two waveforms (a = 0.6, 0.9): the default
ASYMMETRY_PATH = Path(__file__).parent / "data" / "blind_asymmetry.csv"
BLIND_TOLERANCE = 0.05  # largest backward step a blind setting may take, × the map's
COLUMNS = ("frequency_hz", "amplitude_v", "a", "k", "worst_ratio", "backward_share")
# the columns before the survey covered other waveforms: a file with them is of the map
# planner's own family
FAMILY_COLUMNS = ("frequency_hz", "amplitude_v", "worst_ratio", "backward_share")
FAMILY = (0.9, 1.0)  # the map planner's waveform (a, k) (controllers.feedforward.MapPlanner)


class BlindSettings:
    """The survey's worst step ratio per setting (module docstring).

    Args:
        worst: (frequency [Hz], amplitude [V], a [-], k [-]) → worst steady step over the
            map's [-]; a key of (frequency, amplitude) alone is the planner's family
            (a = 0.9, k = 1: ``FAMILY``).
    """

    def __init__(self, worst: Mapping[tuple[float, ...], float]) -> None:
        if not isinstance(worst, Mapping):
            raise ValueError(f"worst={describe(worst)}: must be a mapping (Hz, V, a, k) → ratio")
        self.worst: dict[tuple[float, float, float, float], float] = {}
        for key, ratio in worst.items():
            if not (isinstance(key, tuple) and len(key) in (2, 4)):
                raise ValueError(
                    f"worst[{describe(key)}]: a key must be (frequency [Hz], amplitude [V]"
                    "[, a, k])"
                )
            f = check_positive("worst: frequency", key[0])
            amp = check_positive("worst: amplitude", key[1])
            a, k = FAMILY if len(key) == 2 else key[2:]
            if not (isinstance(a, int | float) and 0.5 <= a <= 0.99):
                raise ValueError(f"worst[{key!r}]: ramp ratio a={a!r} must lie in 0.5–0.99")
            k = check_finite(f"worst[{key!r}]: k", k)
            self.worst[_key(f, amp, a, k)] = check_finite(f"worst[{key!r}]", ratio)

    def robust(
        self,
        amplitude: np.ndarray,
        frequency: np.ndarray,
        tolerance: float = BLIND_TOLERANCE,
        *,
        a: np.ndarray | float = FAMILY[0],
        k: np.ndarray | float = FAMILY[1],
    ) -> np.ndarray:
        """Mask of the settings (|amplitude| [V], frequency [Hz], ramp ratio ``a``, slew
        adaptation ``k``) whose worst ratio is at least −``tolerance``; a setting the
        survey did not cover is not robust."""
        amps = np.abs(np.asarray(amplitude, dtype=float))
        freqs, ratios, slews = np.broadcast_arrays(
            np.asarray(frequency, dtype=float), np.asarray(a, dtype=float),
            np.asarray(k, dtype=float), amps)[:3]  # fmt: skip
        out = np.zeros(amps.shape, dtype=bool)
        for i, cell in enumerate(zip(freqs.ravel(), amps.ravel(), ratios.ravel(),
                                     slews.ravel(), strict=True)):  # fmt: skip
            out.flat[i] = self.worst.get(_key(*cell), -math.inf) >= -tolerance
        return out

    def families(self) -> list[tuple[float, float]]:
        """The waveforms (a, k) the survey covers, sorted."""
        return sorted({(a, k) for _f, _amp, a, k in self.worst})

    @classmethod
    @functools.cache
    def load(cls, path: str | Path = ASYMMETRY_PATH) -> BlindSettings:
        """Read the survey's file (``COLUMNS``, or ``FAMILY_COLUMNS`` for a survey of the
        planner's family alone); a defect raises ValueError naming file, line and column."""
        p = Path(path)
        try:
            columns, rows = COLUMNS, read_table(p, COLUMNS)[1]
        except ValueError as exc:
            if "header" not in str(exc):
                raise
            columns, rows = FAMILY_COLUMNS, read_table(p, FAMILY_COLUMNS)[1]
        worst: dict[tuple[float, ...], float] = {}
        for row in rows:
            ln = row[-1]
            vals = {}
            for col, cell in zip(columns, row[:-1], strict=True):
                try:
                    v = float(cell)
                except ValueError:
                    v = math.nan
                if not math.isfinite(v):
                    raise ValueError(f"{p}:{ln}: column {col!r} = {cell!r}, not a number")
                vals[col] = v
            f, amp = vals["frequency_hz"], vals["amplitude_v"]
            if f <= 0.0 or amp <= 0.0:
                raise ValueError(f"{p}:{ln}: frequency {f!r} Hz and amplitude {amp!r} V "
                                 "must be positive")  # fmt: skip
            a, k = vals.get("a", FAMILY[0]), vals.get("k", FAMILY[1])
            if not 0.5 <= a <= 0.99:
                raise ValueError(f"{p}:{ln}: column 'a' = {a!r}: must lie in 0.5–0.99")
            worst[(f, amp, a, k)] = vals["worst_ratio"]
        return cls(worst)

    def save(self, path: str | Path, shares: Mapping[tuple[float, ...], float],
             comment: str) -> Path:  # fmt: skip
        """Write the table (``shares``: the backward share per setting, keyed as
        :attr:`worst`) with ``# comment`` lines, atomically."""
        from turntable_env.files import write_atomic

        share = {_key(*(key if len(key) == 4 else (*key, *FAMILY))): v
                 for key, v in shares.items()}  # fmt: skip
        lines = [f"# {c}" for c in comment.splitlines()]
        lines.append(",".join(COLUMNS))
        for key, w in sorted(self.worst.items()):
            f, amp, a, k = key
            lines.append(f"{f:g},{amp:g},{a:g},{k:g},{w:.4f},{share[key]:.4f}")
        return write_atomic(path, "\n".join(lines) + "\n")


def _key(f: float, amp: float, a: float, k: float) -> tuple[float, float, float, float]:
    """A setting's key in :attr:`BlindSettings.worst` (rounded, so a file's text and the
    map's floats meet)."""
    return (round(float(f), 6), round(float(amp), 6), round(float(a), 6), round(float(k), 6))


def check_blind_settings(value: object) -> BlindSettings | None:
    """``value`` if it is a :class:`BlindSettings` or None (the caller's default); else a
    ValueError naming its type (every public ``blind_settings=`` argument)."""
    if value is not None and not isinstance(value, BlindSettings):
        raise ValueError(f"blind_settings={type(value).__name__}: must be a BlindSettings or None")
    return value
