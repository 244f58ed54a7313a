"""Boundary validation shared by every constructor and public function.

Nothing in this package lets a bad number travel into a compiled loop: each
public entry point calls these helpers, which raise ``ValueError`` naming the
field and the offending value.
"""

from __future__ import annotations

import math
import numbers
import os
import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np

__all__ = [
    "check_array_finite",
    "check_finite",
    "check_in_open",
    "check_int",
    "check_nonnegative",
    "check_path",
    "check_positive",
    "check_positive_array",
    "check_sums_to_one",
    "check_time_array",
    "describe",
    "parse_decimal",
]


def describe(value: object) -> str:
    """A value as an error message shows it: numpy scalars as plain numbers (``0.00495``,
    not ``np.float64(0.00495)``), on one line (a long or 2-D array's repr spans many),
    at most 60 characters."""
    if isinstance(value, np.generic) and not isinstance(value, np.bool_):
        value = value.item()
    text = " ".join(line.strip() for line in repr(value).splitlines())
    return text if len(text) <= 60 else text[:57] + "..."


_describe = describe

_DECIMAL = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)  # \d: 0-9 only


def parse_decimal(text: str) -> float | None:
    """A plain ASCII decimal number (``1.5e-3``; surrounding blanks allowed), or None:
    Python's ``float`` and ``int`` also take ``1_0``, full-width and other scripts' digits,
    ``nan`` and ``inf``, which a file's cell and a command-line option both refuse."""
    t = text.strip()
    return float(t) if _DECIMAL.fullmatch(t) else None


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as float; raise ValueError if it is NaN, infinite or not a real
    number (a bool, a string, a complex number, a container or an integer beyond float
    are refused, not converted)."""
    if type(value) is float and math.isfinite(value):  # the common case, without ABC checks
        return value
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    real = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
    if not real:
        raise ValueError(f"{name}={_describe(value)}: must be a real number")
    try:
        x = float(value)
    except OverflowError:
        raise ValueError(f"{name}={_describe(value)}: must be finite") from None
    if not math.isfinite(x):
        raise ValueError(f"{name}={_describe(value)}: must be finite")
    return x


def check_int(name: str, value: int, lo: int | None = None, hi: int | None = None) -> int:
    """An integer (not a bool, not a float) within [lo, hi] where given."""
    if isinstance(value, np.integer):
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{name}={_describe(value)}: must be an integer")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        bounds = f"{lo if lo is not None else '-inf'}…{hi if hi is not None else 'inf'}"
        raise ValueError(f"{name}={_describe(value)}: must lie in {bounds}")
    return value


def check_path(name: str, value: str | os.PathLike[str]) -> Path:
    """A file system path from a string or a path-like object; anything else (a number,
    None, bytes) is refused, not coerced."""
    if isinstance(value, str | os.PathLike) and not isinstance(value, bytes):
        path = os.fspath(value)
        if isinstance(path, str) and path and "\0" not in path:
            return Path(path)
    raise ValueError(f"{name}={_describe(value)}: must be a path (a string or a path-like)")


def check_positive(name: str, value: float) -> float:
    """Finite and strictly positive."""
    x = check_finite(name, value)
    if x <= 0.0:
        raise ValueError(f"{name}={_describe(value)}: must be > 0")
    return x


def check_nonnegative(name: str, value: float) -> float:
    """Finite and >= 0."""
    x = check_finite(name, value)
    if x < 0.0:
        raise ValueError(f"{name}={_describe(value)}: must be >= 0")
    return x


def check_in_open(name: str, value: float, lo: float, hi: float) -> float:
    """Finite and inside the open interval (lo, hi)."""
    x = check_finite(name, value)
    if not lo < x < hi:
        raise ValueError(f"{name}={_describe(value)}: must lie in the open interval ({lo}, {hi})")
    return x


def check_array_finite(name: str, values: Iterable[float] | np.ndarray) -> np.ndarray:
    """Return a float64 array; raise if any element is NaN or infinite."""
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={_describe(values)}: must be an array of real numbers") from None
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{name}[{idx[0] if len(idx) == 1 else idx}]={arr[idx]!r}: must be finite")
    return arr


def check_positive_array(name: str, values: Iterable[float] | np.ndarray) -> np.ndarray:
    """Finite, non-empty, every element strictly positive."""
    arr = check_array_finite(name, values)
    if arr.size == 0:
        raise ValueError(f"{name}={arr!r}: must not be empty")
    bad = arr <= 0.0
    if bad.any():
        i = int(np.argwhere(bad.ravel())[0][0])
        raise ValueError(f"{name}[{i}]={arr.ravel()[i]!r}: must be > 0")
    return arr


def check_sums_to_one(
    name: str, values: Iterable[float] | np.ndarray, rtol: float = 1e-9
) -> np.ndarray:
    """Positive fractions that sum to one (the GMS ν_i, Eq. 2.24)."""
    arr = check_positive_array(name, values)
    total = float(arr.sum())
    if abs(total - 1.0) > rtol * max(1.0, arr.size):
        raise ValueError(f"{name}={arr.tolist()!r}: must sum to 1 (sums to {total!r})")
    return arr


def check_time_array(name: str, t: Iterable[float] | np.ndarray) -> np.ndarray:
    """A finite 1-D time array in seconds, strictly increasing."""
    arr = check_array_finite(name, t)
    if arr.ndim != 1:
        raise ValueError(f"{name}: must be one-dimensional (got shape {arr.shape})")
    if arr.size >= 2:
        d = np.diff(arr)
        if (d <= 0).any():
            i = int(np.argwhere(d <= 0)[0][0]) + 1
            raise ValueError(
                f"{name}[{i}]={arr[i]!r}: time must be strictly increasing "
                f"(previous {arr[i - 1]!r})"
            )
    return arr
