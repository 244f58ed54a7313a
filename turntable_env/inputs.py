"""Validated input files: the one door every file the tools read goes through.

Measurement traces have their own loader (:mod:`turntable_env.calibration.measurement`);
everything else a user hands the tools — a summary of measured figures (TOML), a
calibration report (JSON), a parameter file (TOML) — is read here:

* only a regular file, checked before it is opened (a FIFO would block the reader, a
  device never ends), and at most ``max_bytes`` (checked on the file's size, then on what
  is read, so a file growing meanwhile is caught too);
* JSON nested at most :data:`MAX_NESTING` deep, checked on the text before parsing (a
  recursive parser would overflow the stack); TOML's parser recursing too deep is caught
  and named the same way;
* a path that is a string or a path-like object (anything else is refused, not coerced);
* every error a ValueError of one line naming the file — and the key and the value, or
  the line and column — never a traceback, and a missing file the same way.

:class:`Fields` reads one table of such a file against a schema: types, ranges and
enumerations, with the table's path in every message.
"""

from __future__ import annotations

import json
import math
import os
import stat
import tomllib
from collections.abc import Mapping, Sequence
from typing import Any

from .validation import check_path
from .validation import describe as show

__all__ = [
    "MAX_INPUT_BYTES",
    "MAX_NESTING",
    "Fields",
    "load_json",
    "load_toml",
    "read_input",
    "show",
]

MAX_INPUT_BYTES = 16 * 2**20  # a summary, a report or a parameter file: far below this
MAX_NESTING = 64  # nested JSON arrays/objects


def read_input(path: str | os.PathLike[str], what: str, max_bytes: int = MAX_INPUT_BYTES) -> str:
    """The text of an input file (UTF-8) after the checks of the module docstring."""
    p = check_path(what, path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise ValueError(f"{p}: no such {what}") from None
    except OSError as exc:
        raise ValueError(f"{p}: cannot read {what} ({exc.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise ValueError(f"{p}: {kind}; a {what} must be a regular file")
    if st.st_size > max_bytes:
        raise ValueError(f"{p}: {st.st_size} bytes, more than the {max_bytes} a {what} may have")
    try:
        with open(p, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise ValueError(f"{p}: cannot read {what} ({exc.strerror})") from None
    if len(data) > max_bytes:
        raise ValueError(f"{p}: more than the {max_bytes} bytes a {what} may have")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        enc = "UTF-16" if data[:2] in (b"\xff\xfe", b"\xfe\xff") or b"\x00" in data[:64] else (
            "Latin-1 or Windows-1252, say")  # fmt: skip
        line = data[: exc.start].count(b"\n") + 1
        raise ValueError(
            f"{p}:{line}: not UTF-8 text (byte {exc.start}; {enc}?); a {what} is text in "
            "UTF-8: save it so"
        ) from None


def _nesting(text: str) -> int:
    """The deepest nesting of JSON brackets outside strings."""
    depth = deepest = 0
    in_str = escaped = False
    for ch in text:
        if in_str:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_str = False
        elif ch == '"':
            in_str = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def load_json(path: str | os.PathLike[str], what: str, max_bytes: int = MAX_INPUT_BYTES) -> Any:
    """A JSON input file, checked (module docstring)."""
    text = read_input(path, what, max_bytes)
    depth = _nesting(text)
    if depth > MAX_NESTING:
        raise ValueError(f"{path}: nested {depth} deep, more than the {MAX_NESTING} allowed")
    try:  # NaN and Infinity are read (the reports write them); the schema checks values
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: line {exc.lineno} column {exc.colno}: {exc.msg}") from None


def load_toml(path: str | os.PathLike[str], what: str, max_bytes: int = MAX_INPUT_BYTES) -> dict:
    """A TOML input file, checked (module docstring)."""
    text = read_input(path, what, max_bytes)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: {exc}") from None
    except RecursionError:  # arrays or inline tables nested beyond the parser's stack
        raise ValueError(f"{path}: nested too deep for a {what}") from None


_MISSING = object()


class Fields:
    """One table of an input file read against a schema; ``where`` names it in messages
    (``"FILE: [[stepping]] 2"``)."""

    def __init__(self, table: Any, where: str):
        if not isinstance(table, Mapping):
            raise ValueError(f"{where}: must be a table, got {show(table)}")
        self.table = table
        self.where = where

    def known(self, *keys: str) -> Fields:
        """Refuse a key outside ``keys`` (a misspelt or misplaced entry is not ignored)."""
        unknown = [k for k in self.table if k not in keys]
        if unknown:
            raise ValueError(
                f"{self.where}: {unknown[0]} is not part of the format (expected: "
                f"{', '.join(keys)})"
            )
        return self

    def _get(self, key: str, default: Any) -> Any:
        if key in self.table:
            return self.table[key]
        if default is _MISSING:
            raise ValueError(f"{self.where}: {key} missing")
        return default

    def number(
        self, key: str, *, low: float | None = None, high: float | None = None,
        open_low: bool = False, default: Any = _MISSING,
    ) -> float:  # fmt: skip
        """A finite real number in [low, high] (low excluded with ``open_low``)."""
        v = self._get(key, default)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ValueError(f"{self.where}: {key} = {show(v)}: must be a number")
        x = float(v)
        bad = not math.isfinite(x)
        bad |= low is not None and (x < low or (open_low and x == low))
        bad |= high is not None and x > high
        if bad:
            lo = "" if low is None else f"{'>' if open_low else '>='} {low:g}"
            hi = "" if high is None else f"<= {high:g}"
            rng = " and ".join(r for r in (lo, hi) if r) or "finite"
            raise ValueError(f"{self.where}: {key} = {show(v)}: must be {rng}")
        return x

    def integer(self, key: str, *, low: int, high: int, default: Any = _MISSING) -> int:
        v = self._get(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
            raise ValueError(f"{self.where}: {key} = {show(v)}: must be an integer {low}…{high}")
        return int(v)

    def text(self, key: str, *, choices: Sequence[str] | None = None, default: Any = _MISSING
             ) -> str:  # fmt: skip
        v = self._get(key, default)
        if not isinstance(v, str):
            raise ValueError(f"{self.where}: {key} = {show(v)}: must be text")
        if choices is not None and v not in choices:
            allowed = ", ".join(choices)
            raise ValueError(f"{self.where}: {key} = {show(v)}: must be one of {allowed}")
        return v

    def flag(self, key: str, default: Any = _MISSING) -> bool:
        v = self._get(key, default)
        if not isinstance(v, bool):
            raise ValueError(f"{self.where}: {key} = {show(v)}: must be true or false")
        return v

    def tables(self, key: str, name: str | None = None) -> list[Fields]:
        """An array of tables (``[[key]]``), each as :class:`Fields`."""
        v = self._get(key, _MISSING)
        if not isinstance(v, list) or not all(isinstance(x, Mapping) for x in v):
            raise ValueError(f"{self.where}: {key} = {show(v)}: must be an array of tables")
        label = name or key
        return [Fields(x, f"{self.where} [[{label}]] {i + 1}") for i, x in enumerate(v)]

    def sub(self, key: str) -> Fields:
        """A sub-table (``[key]``)."""
        return Fields(self._get(key, _MISSING), f"{self.where} [{key}]")
