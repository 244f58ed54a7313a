"""Measured data: the file format, its validating loader and its writer.

A measurement file is CSV in UTF-8 — only what a laboratory records:

* leading comment lines ``# key: value`` with the metadata. Required: ``axis`` (A, B, C
  or Z: the axis the detector watches), ``amplifier_gain`` [-],
  ``detector_sensitivity_m_per_V``, ``detector_distance_m`` and ``table_radius_m``;
  any further keys are kept as text (``Measurement.meta``);
* a header row, then one sample per row:

  ==================  =====================================================  ==========
  column              meaning                                                required
  ==================  =====================================================  ==========
  ``t_s``             time [s], strictly increasing, ≥ 0                     yes
  ``drive_<X>_V``     amplifier INPUT voltage of channel X ∈ {A, B, C, Z}    at least 1
                      [V] (what the lab commands), |u| ≤ 10 V
  ``detector_V``      quadrant-photodiode output of the watched channel [V]  yes
  ``detector_y_V``    the photodiode's other output [V]                      no
  ==================  =====================================================  ==========

A column's unit is part of its name, and the loader converts to SI: time may be written
``t_ms`` or ``t_us`` (``t_µs``) and any voltage column with ``_mV`` for ``_V``
(:data:`TIME_UNITS`, :data:`VOLTAGE_UNITS`). A metadata line that declares a unit
(``# time_unit: ms``, ``# detector_unit: mV``, ``# units: V``; :func:`_declared_units`)
must agree with the columns it speaks of: one that contradicts them is refused at its
line, not kept as text beside columns read in another unit. Time from an epoch (seconds
since 1970) is refused where float64 cannot resolve its sample interval there.

Physical ranges (checked): amplifier gain 1–1000, S 1e-7–1e-2 m/V, L 1 mm–10 m,
R_table 0.1 mm–1 m, |detector| ≤ 15 V. The watched axis must have its drive column; a
metadata key appears once; numbers are plain ASCII decimals (``1.5e-3``; not ``1_0`` or
full-width digits). Bounds, checked before the work: a regular file of at most
``MAX_FILE_BYTES``, lines of at most ``MAX_LINE_CHARS``, ``MIN_SAMPLES``–``MAX_SAMPLES``
samples, no gap in time over ``MAX_GAP_FACTOR`` × the median interval. A UTF-8 byte-order
mark (as spreadsheet programs write) is dropped. Any defect — a missing key or column, an
unknown column, a non-numeric or non-finite cell, time not increasing, an unknown axis, a
value out of range — raises ValueError naming the file, the line and the column; nothing
is returned half-loaded.
"""

from __future__ import annotations

import array
import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..detector import Detector
from ..files import write_atomic
from ..inputs import read_input
from ..validation import parse_decimal
from .segments import FLYBACK_SHAPES, RECORDINGS

__all__ = ["AXES", "TIME_UNITS", "VOLTAGE_UNITS", "Measurement", "load_measurement"]

AXES = ("A", "B", "C", "Z")
INPUT_LIMIT = 10.0  # V, amplifier input range (§4.1.1: LabView signal between ±10 V)
DRIVE_FREQUENCY_RANGE = (1.0, 1e5)  # Hz, a stepping waveform's frequency a protocol may hold
DETECTOR_LIMIT = 15.0  # V, photodiode electronics supply
MAX_FILE_BYTES = 256 * 2**20  # bytes a measurement file may hold
MAX_LINE_CHARS = 4096  # characters per line
MAX_SAMPLES = 4_000_000  # samples per file
MIN_SAMPLES = 16  # samples per file: a drive segment to fit and one to hold out
MAX_GAP_FACTOR = 1000.0  # a sample interval this many times the median is a gap
# the units a column's name may end in, and their factor to SI (s, V)
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6}  # micro sign, mu
VOLTAGE_UNITS = {"V": 1.0, "mV": 1e-3}
# the words a metadata line may declare a unit by: word → (quantity, unit as a suffix)
UNIT_WORDS = {
    **{w: ("time", "s") for w in ("s", "sec", "second", "seconds")},
    **{w: ("time", "ms") for w in ("ms", "msec", "millisecond", "milliseconds")},
    **{w: ("time", "us") for w in ("us", "µs", "μs", "usec", "microsecond", "microseconds")},
    **{w: ("voltage", "V") for w in ("v", "volt", "volts")},
    **{w: ("voltage", "mV") for w in ("mv", "millivolt", "millivolts")},
}
# the float64 resolution of a time stamp allowed, as a share of the median interval
TIME_RESOLUTION = 1e-3
META_RANGES = {  # key: (low, high, unit)
    "amplifier_gain": (1.0, 1000.0, "-"),
    "detector_sensitivity_m_per_V": (1e-7, 1e-2, "m/V"),
    "detector_distance_m": (1e-3, 10.0, "m"),
    "table_radius_m": (1e-4, 1.0, "m"),
}


@dataclass(frozen=True, eq=False)
class Measurement:
    """One measurement file's content (SI units; time is axis 0 of every array).

    Attributes:
        axis: the axis the detector watches; amplifier_gain: [-]; detector: sensitivity,
        distance and table radius as a :class:`~turntable_env.detector.Detector`;
        time [s]; drives: channel → amplifier input [V]; detector_v [V];
        detector_y_v [V] or None; meta: the other metadata (text); source: file path.
    """

    axis: str
    amplifier_gain: float
    detector: Detector
    time: np.ndarray
    drives: dict[str, np.ndarray]
    detector_v: np.ndarray
    detector_y_v: np.ndarray | None = None
    meta: dict[str, str] = field(default_factory=dict)
    source: str = ""

    def __post_init__(self) -> None:
        """The content's contract, checked as the loader checks a file (ValueError naming
        the field, or the sample and the file's column): a known axis with its drive, a
        gain > 0, a Detector, ≥ 2 times strictly increasing, every signal 1-D of time's
        length and finite, text metadata. Ranges (the ±10 V input, the detector's ±15 V)
        are :meth:`save`'s and the loader's."""
        if self.axis not in AXES:
            raise ValueError(f"axis={self.axis!r}: must be one of {', '.join(AXES)}")
        g = self.amplifier_gain
        if isinstance(g, bool) or not isinstance(g, int | float) or not (
                math.isfinite(g) and g > 0.0):  # fmt: skip
            raise ValueError(f"amplifier_gain={g!r}: must be a finite number > 0")
        if not isinstance(self.detector, Detector):
            raise ValueError(f"detector={self.detector!r}: must be a Detector")
        if not isinstance(self.drives, dict) or self.axis not in self.drives:
            raise ValueError(f"drives: need a dict holding the watched axis {self.axis!r}")
        for k in self.drives:
            if k not in AXES:
                raise ValueError(f"drives: unknown channel {k!r} ({', '.join(AXES)})")
        cols = {"t_s": self.time, **{f"drive_{k}_V": v for k, v in self.drives.items()},
                "detector_V": self.detector_v}  # fmt: skip
        if self.detector_y_v is not None:
            cols["detector_y_V"] = self.detector_y_v
        n = np.shape(self.time)
        for name, v in cols.items():
            a = np.asarray(v)
            if a.ndim != 1 or a.shape != n or a.size < 2 or a.dtype.kind not in "fiu":
                raise ValueError(f"column {name!r}: shape {a.shape}: need >= 2 numbers, "
                                 f"one per time {n}")  # fmt: skip
            if not np.isfinite(a).all():
                r = int(np.flatnonzero(~np.isfinite(a))[0])
                raise ValueError(f"sample {r}, column {name!r} = {float(a[r])!r}: not finite")
        d = np.diff(np.asarray(self.time, dtype=float))
        if np.any(d <= 0.0):
            k = int(np.argmax(d <= 0.0)) + 1
            raise ValueError(f"column 't_s': not increasing at sample {k}")
        texts = isinstance(self.meta, dict) and all(
            isinstance(k, str) and isinstance(v, str) for k, v in self.meta.items())
        if not texts:
            raise ValueError("meta: must be a dict of text keys and text values")

    def angle(self) -> np.ndarray:
        """Table angle from the detector, Eq. 4.1 [rad]."""
        return self.detector.angle(self.detector_v)

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    def to_pandas(self) -> Any:
        import pandas as pd

        cols: dict[str, np.ndarray] = {f"drive_{k}_V": v for k, v in self.drives.items()}
        cols["detector_V"] = self.detector_v
        if self.detector_y_v is not None:
            cols["detector_y_V"] = self.detector_y_v
        return pd.DataFrame(cols, index=pd.Index(self.time, name="t_s"))

    def plot(self, axes: Any = None) -> Any:
        """Drives and detector voltage vs time."""
        import matplotlib.pyplot as plt

        if axes is None:
            _fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
        for k, v in self.drives.items():
            axes[0].plot(self.time, v, label=f"drive {k}")
        axes[0].set_ylabel("amplifier input [V]")
        axes[0].legend()
        axes[1].plot(self.time, self.detector_v)
        axes[1].set_ylabel(f"detector ({self.axis}) [V]")
        axes[1].set_xlabel("time [s]")
        return axes

    def save(self, path: str | Path) -> Path:
        """Write in the format above (full float precision), atomically (a temporary file
        renamed into place); :func:`load_measurement` reads it back unchanged. ValueError
        for what the loader would refuse, before anything is written: extra metadata that
        collides with a required key or holds a line break, a non-finite sample, and every
        check of the loader (the text is read back through it: an axis, a gain or a drive
        out of its range, time that does not increase, too few samples, ...)."""
        p = Path(path)
        det = self.detector
        for k, v in self.meta.items():
            if k in ("axis", *META_RANGES) or not isinstance(k, str) or not k.strip():
                raise ValueError(f"meta key {k!r}: reserved or empty")
            if any(ch in f"{k}{v}" for ch in "\r\n") or ":" in k or k != k.strip():
                raise ValueError(f"meta[{k!r}] = {v!r}: keys and values are single lines")
        meta = {
            "axis": self.axis,
            "amplifier_gain": repr(self.amplifier_gain),
            "detector_sensitivity_m_per_V": repr(det.sensitivity),
            "detector_distance_m": repr(det.distance),
            "table_radius_m": repr(det.table_radius),
            **{k: str(v) for k, v in self.meta.items()},
        }
        cols = ["t_s", *(f"drive_{k}_V" for k in self.drives), "detector_V"]
        data = [self.time, *self.drives.values(), self.detector_v]
        if self.detector_y_v is not None:
            cols.append("detector_y_V")
            data.append(self.detector_y_v)
        table = np.column_stack(data)
        if not np.isfinite(table).all():
            r, c = (int(x) for x in np.argwhere(~np.isfinite(table))[0])
            raise ValueError(f"sample {r}, column {cols[c]!r} = {table[r, c]!r}: not finite")
        lines = [f"# {k}: {v}\n" for k, v in meta.items()]
        lines.append(",".join(cols) + "\n")
        lines += [",".join(repr(float(x)) for x in row) + "\n" for row in table]
        text = "".join(lines)
        _parse(text, p)  # what the loader would refuse is refused here, the file unwritten
        write_atomic(p, text)
        return p


_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)


def _meta_float(path: Path, line: int, key: str, text: str) -> float:
    lo, hi, unit = META_RANGES[key]
    v = parse_decimal(text)
    if v is None:
        raise ValueError(f"{path}:{line}: metadata {key!r} = {text!r} is not a number")
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ValueError(
            f"{path}:{line}: metadata {key!r} = {text!r} outside {lo:g}…{hi:g}"
            + (f" {unit}" if unit != "-" else "")
        )
    return v


def _read_text(p: Path) -> str:
    """The file's text (UTF-8, a leading BOM dropped), refused before reading when it is
    not a regular file or larger than :data:`MAX_FILE_BYTES`
    (:func:`~turntable_env.inputs.read_input`)."""
    return read_input(p, "measurement file", MAX_FILE_BYTES)


def load_measurement(path: str | Path) -> Measurement:
    """Read and validate a measurement file (module docstring)."""
    p = Path(path)
    return _parse(_read_text(p), p)


def _near_miss(lines: list[str], n_meta: int, key: str) -> str:
    """A hint for a missing metadata key that a line near the top nearly gives (another
    separator than ':', another case, a comment mark other than '#'), or ""."""
    for k, line in enumerate(lines[: max(n_meta, 1) + 20]):
        lead = next((c for c in ("#", "%", "//", ";") if line.startswith(c)), "")
        body = line[len(lead) :].strip() if lead else ""
        name = body.replace("=", ":").partition(":")[0].strip()
        if name.lower() == key and (name != key or ":" not in body or lead != "#"):
            return (
                f" (line {k + 1} reads {line.strip()!r}: a metadata line is '# {key}: value', "
                "its key in lower case)"
            )
    return ""


def _column_hint(column: str) -> str:
    """Why a header cell may not be a column name: another separator, or an empty name."""
    for sep, name in ((";", "semicolons"), ("\t", "tabs")):
        if sep in column:
            return f" (the format separates its columns by commas; this header by {name})"
    if not column:
        return (
            " (an empty column name: a comma at the end of the header, or an index column "
            "such as pandas' to_csv writes without index=False)"
        )
    if parse_decimal(column) is not None:
        return (
            " (a number where the header belongs: the line after the metadata names the "
            "columns, t_s,drive_<X>_V,detector_V)"
        )
    low = column.lower()
    names = ["t_s", "t_ms", "t_us", "detector_V", "detector_mV", "detector_y_V",
             "detector_y_mV", *(f"drive_{a}_{u}" for a in AXES for u in ("V", "mV"))]  # fmt: skip
    for name in names:
        if low == name.lower():
            return f" (did you mean {name!r}? column names are case-sensitive)"
    return (
        " (its columns: t_s, t_ms or t_us; drive_<A|B|C|Z>_V, detector_V and detector_y_V,"
        " each voltage also as _mV; delete any other column)"
    )


def _epoch_hint(t: float, always: bool = False) -> str:
    """A hint for a time that float64 resolves coarsely (seconds since an epoch), or ""."""
    if not always and t < 1e5:
        return ""
    return (
        f" (time stamps {t:.4g} s from their zero, resolved to {np.spacing(t):.2g} s: write "
        "time from the record's start, as t − t[0])"
    )


def _canonical(column: str) -> tuple[str, float]:
    """A header cell's name in SI (``t_s``, ``<stem>_V``) and the factor to SI
    (``("t_s", 1e-3)`` for ``t_ms``); the cell itself and 1.0 where its name carries no
    unit the format reads."""
    stem, _, unit = column.rpartition("_")
    if stem == "t" and unit in TIME_UNITS:
        return "t_s", TIME_UNITS[unit]
    if (stem in ("detector", "detector_y") or stem.startswith("drive_")) and unit in VOLTAGE_UNITS:
        return f"{stem}_V", VOLTAGE_UNITS[unit]
    return column, 1.0


# the words a unit key's subject may be (its words other than "unit", "units", "base"):
# the columns it declares; any other subject (a trigger time, a distance) is kept as text
UNIT_SUBJECTS = {
    **{w: "time" for w in ("t", "time", "timestamp", "timestamps", "clock")},
    **{w: "detector" for w in ("detector", "detector_v", "detector_voltage", "detector_y",
                               "photodiode")},
    **{w: "drive" for w in ("drive", "drive_v", "drive_voltage", "drives", "input",
                            "amplifier_input")},
    **{w: "voltage" for w in ("voltage", "voltages", "volt", "signal", "signals")},
    "": "any",
}
_UNIT_WORDS_IN_KEY = ("unit", "units", "base")


def _unit_key(key: str) -> tuple[str, bool] | None:
    """A metadata key as a unit declaration: (its subject, whether it says "unit"), or
    None. "time_unit", "Time unit", "timeunit", "unit_time", "time_base" and "units" are
    declarations; "time" is one only with a unit word for value (the caller's check)."""
    words = [w for w in re.split(r"[\s_-]+", key.strip().lower()) if w]
    split: list[str] = []
    for w in words:  # "timeunit", "timebase": a subject glued to its unit word
        glued = next((u for u in _UNIT_WORDS_IN_KEY if w.endswith(u) and w != u), None)
        split += [w[: -len(glued)], glued] if glued and w[: -len(glued)] in UNIT_SUBJECTS else [w]
    says = any(w in _UNIT_WORDS_IN_KEY for w in split)
    subject = "_".join(w for w in split if w not in _UNIT_WORDS_IN_KEY)
    return (subject, says) if subject in UNIT_SUBJECTS else None


def _unit_word(text: str) -> tuple[str, str] | None:
    """(quantity, unit suffix) of a unit word (:data:`UNIT_WORDS`), or None."""
    t = text.strip()
    return UNIT_WORDS.get(t if t in ("µs", "μs") else t.lower())


def _declared_units(
    p: Path, meta: dict[str, tuple[int, str]], written: list[str], canon: list[str]
) -> None:
    """Refuse a metadata line that declares a unit the columns it speaks of are not in
    (``# time_unit: ms`` above ``t_s``), or a unit word the format does not read for
    them. A declaration's key is a subject (:data:`UNIT_SUBJECTS`: time, the detector,
    the drives, voltages, or none) with "unit", "units" or "base" (:func:`_unit_key`),
    or a bare subject with a unit word for value (``# time: ms``); ``# units: s, V, mV``
    lists one unit per column, in the header's order. Other keys, a trigger time's unit
    or a distance's, are kept as text."""
    cols_of = {
        "time": [k for k, c in enumerate(canon) if c == "t_s"],
        "detector": [k for k, c in enumerate(canon) if c in ("detector_V", "detector_y_V")],
        "drive": [k for k, c in enumerate(canon) if c.startswith("drive_")],
    }
    cols_of["voltage"] = sorted(cols_of["detector"] + cols_of["drive"])
    for key, (ln, val) in meta.items():
        parsed = _unit_key(key)
        if parsed is None:
            continue
        subject, says = parsed
        items = re.split(r"[,;]", val) if "," in val or ";" in val else [val]
        if subject == "" and len(items) > 1:  # one unit per column, in order
            if len(items) != len(written):
                raise ValueError(
                    f"{p}:{ln}: metadata {key!r} = {val!r} lists {len(items)} units for "
                    f"{len(written)} columns ({', '.join(written)})"
                )
            for c, item in enumerate(items):
                quantity = "time" if canon[c] == "t_s" else "voltage"
                _agree(p, ln, key, val, _unit_word(item), quantity, [c], written)
            continue
        word = _unit_word(val)
        if not says and word is None:
            continue  # "# time: 14:32", "# detector: PDQ80A": text
        kind = UNIT_SUBJECTS[subject]
        if kind == "any":
            if word is None:
                continue  # "# units: SI": text
            kind = "time" if word[0] == "time" else "voltage"
        quantity = "time" if kind == "time" else "voltage"
        _agree(p, ln, key, val, word, quantity, cols_of[kind], written)


def _agree(
    p: Path, ln: int, key: str, val: str, word: tuple[str, str] | None, quantity: str,
    cols: list[int], written: list[str],
) -> None:
    """ValueError unless ``word`` is a unit of ``quantity`` that every column ``cols``
    (indices into ``written``) is written in."""
    table = TIME_UNITS if quantity == "time" else VOLTAGE_UNITS
    if word is None or word[0] != quantity:
        raise ValueError(
            f"{p}:{ln}: metadata {key!r} = {val!r}: not a unit of {quantity} the format "
            f"reads ({', '.join(table)}; a column's unit is part of its name)"
        )
    for c in cols:
        stem, _, unit = written[c].rpartition("_")
        if table[unit] != table[word[1]]:
            raise ValueError(
                f"{p}:{ln}: metadata {key!r} = {val!r}, but column {written[c]!r} is in "
                f"{unit}: a column's unit is part of its name (write "
                f"'{stem}_{word[1]}' if it holds {word[1]})"
            )


def _header(
    p: Path, text: str, header_line: int, meta: dict[str, tuple[int, str]]
) -> tuple[list[str], list[str], tuple[float, ...], list[str]]:
    """The header row ``text`` (line ``header_line``) validated: the columns in SI
    (``t_s``, ``detector_V``, ``drive_<X>_V``), as written, each one's factor to SI, and
    the drive columns; the metadata's declared units checked against them."""
    written = [c.strip() for c in next(csv.reader([text]))]
    canon, factor = zip(*map(_canonical, written), strict=True) if written else ((), ())
    header = list(canon)  # the columns in SI: t_s, detector_V, drive_<X>_V
    drive_cols = [c for c in header if c.startswith("drive_") and c.endswith("_V")]
    for c in drive_cols:
        if c[6:-2] not in AXES:
            w = written[header.index(c)]
            raise ValueError(f"{p}:{header_line}: column {w!r}: unknown channel {c[6:-2]!r}")
    known = {"t_s", "detector_V", "detector_y_V", *drive_cols}
    for c, w in zip(header, written, strict=True):
        if c not in known:
            raise ValueError(
                f"{p}:{header_line}: column {w!r} is not part of the format{_column_hint(w)}"
            )
    for c, alt in (("t_s", " (or t_ms, t_us)"), ("detector_V", " (or detector_mV)")):
        if c not in header:
            raise ValueError(f"{p}:{header_line}: column {c!r}{alt} missing")
    if not drive_cols:
        raise ValueError(f"{p}:{header_line}: no drive_<axis>_V column")
    twice = [k for k, c in enumerate(header) if c in header[:k]]
    if twice:
        k = twice[0]
        first = written[header.index(header[k])]
        raise ValueError(
            f"{p}:{header_line}: column {written[k]!r} appears twice" if first == written[k]
            else f"{p}:{header_line}: columns {first!r} and {written[k]!r} are one quantity"
        )
    _declared_units(p, meta, written, header)
    return header, written, factor, drive_cols


def _parse(text: str, p: Path) -> Measurement:
    """The measurement ``text`` holds, validated; errors name ``p`` and the line."""
    # lines end at LF, CRLF or CR only: str.splitlines would also end one at a form feed,
    # a vertical tab or U+2028 inside a cell, and every later line number would be off
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    for k, line in enumerate(lines):
        if len(line) > MAX_LINE_CHARS:
            raise ValueError(f"{p}:{k + 1}: {len(line)} characters, more than {MAX_LINE_CHARS}")
    meta: dict[str, tuple[int, str]] = {}
    i = 0
    while i < len(lines) and (lines[i].startswith("#") or not lines[i].strip()):
        key, sep, val = lines[i][1:].partition(":")
        if lines[i].startswith("#") and sep:
            key = key.strip()
            if key in meta:
                raise ValueError(
                    f"{p}:{i + 1}: metadata {key!r} given twice (first on line {meta[key][0]})"
                )
            meta[key] = (i + 1, val.strip())
        i += 1
    for key in ("axis", *META_RANGES):
        if key not in meta:
            raise ValueError(f"{p}:1: metadata '# {key}: ...' missing{_near_miss(lines, i, key)}")
    ln, axis = meta["axis"]
    if axis not in AXES:
        raise ValueError(f"{p}:{ln}: metadata 'axis' = {axis!r}, must be one of {', '.join(AXES)}")
    values = {k: _meta_float(p, meta[k][0], k, meta[k][1]) for k in META_RANGES}
    for key, allowed in (("drive_recording", RECORDINGS), ("drive_flybacks", FLYBACK_SHAPES)):
        if key in meta and meta[key][1] not in allowed:
            ln, val = meta[key]
            raise ValueError(
                f"{p}:{ln}: metadata '{key}' = {val!r}, must be one of {', '.join(allowed)}"
            )
    if i >= len(lines):
        raise ValueError(f"{p}: no header row")
    header_line = i + 1
    header, written, factor, drive_cols = _header(p, lines[i], header_line, meta)
    if f"drive_{axis}_V" not in header:
        raise ValueError(
            f"{p}:{header_line}: column 'drive_{axis}_V' missing: the watched axis "
            f"({axis}, line {ln}) must be driven"
        )
    t_col = header.index("t_s")
    tw = written[t_col]

    def _mv_hint(c: str, v: float, limit: float) -> str:
        """A hint where the column, read as millivolts, would be in range."""
        k = header.index(c)
        if factor[k] != 1.0 or abs(v) * 1e-3 > limit:
            return ""
        return f" (in mV? name the column {c[:-2]}_mV)"

    def _as_written(c: str) -> str:
        """'name' = (the cell as written, and its SI value's) prefix of a range message."""
        k = header.index(c)
        return f"{written[k]!r} = {cells[k].strip()} = " if factor[k] != 1.0 else f"{c!r} = "

    buf = array.array("d")  # the samples, row by row: 8 bytes a number, no list of rows
    n_rows = 0
    prev_t, prev_at = -math.inf, (0, "")  # the last time stamp [s]; its line and cell as written
    for j in range(i + 1, len(lines)):
        if not lines[j].strip():
            continue
        cells = next(csv.reader([lines[j]]))
        if len(cells) != len(header):
            where = (
                " (a comment inside the data: metadata lines go above the header)"
                if lines[j].lstrip().startswith(("#", "%")) else ""
            )  # fmt: skip
            raise ValueError(
                f"{p}:{j + 1}: {len(cells)} cells, the header has {len(header)}{where}"
            )
        row = []
        for name, cell, f in zip(written, cells, factor, strict=True):
            v = parse_decimal(cell)
            if v is None and _NONFINITE.fullmatch(cell.strip()):
                raise ValueError(f"{p}:{j + 1}: column {name!r} = {cell!r} is not finite")
            if v is None:
                raise ValueError(f"{p}:{j + 1}: column {name!r} = {cell!r} is not a number")
            if not math.isfinite(v):
                raise ValueError(f"{p}:{j + 1}: column {name!r} = {cell!r} is not finite")
            row.append(v * f)
        if n_rows >= MAX_SAMPLES:
            raise ValueError(f"{p}:{j + 1}: more than {MAX_SAMPLES} samples")
        buf.extend(row)
        n_rows += 1
        rec = dict(zip(header, row, strict=True))
        if rec["t_s"] < 0.0:
            raise ValueError(f"{p}:{j + 1}: column {tw!r} = {cells[t_col]!r} is negative")
        if rec["t_s"] <= prev_t:
            raise ValueError(
                f"{p}:{j + 1}: column {tw!r} = {cells[t_col]!r} is not increasing (line "
                f"{prev_at[0]} before it: {prev_at[1]!r})" + _epoch_hint(rec["t_s"])
            )
        prev_t, prev_at = rec["t_s"], (j + 1, cells[t_col])
        for c in drive_cols:
            if abs(rec[c]) > INPUT_LIMIT:
                raise ValueError(
                    f"{p}:{j + 1}: column {_as_written(c)}{rec[c]!r} V beyond the "
                    f"±{INPUT_LIMIT:g} V amplifier input{_mv_hint(c, rec[c], INPUT_LIMIT)}"
                )
        for c in ("detector_V", "detector_y_V"):
            if c in rec and abs(rec[c]) > DETECTOR_LIMIT:
                raise ValueError(
                    f"{p}:{j + 1}: column {_as_written(c)}{rec[c]!r} V beyond "
                    f"±{DETECTOR_LIMIT:g} V{_mv_hint(c, rec[c], DETECTOR_LIMIT)}"
                )
    if n_rows < MIN_SAMPLES:
        raise ValueError(f"{p}: need at least {MIN_SAMPLES} samples, found {n_rows}")
    data = np.frombuffer(buf, dtype=np.float64).reshape(n_rows, len(header)).copy()
    t = data[:, t_col]
    dt = np.diff(t)
    k = int(np.argmax(dt))
    if dt[k] > MAX_GAP_FACTOR * float(np.median(dt)):
        raise ValueError(
            f"{p}:{header_line + k + 2}: column 't_s' jumps {dt[k]:.6g} s after "
            f"t = {float(t[k]):.6g} s, more than "
            f"{MAX_GAP_FACTOR:g}× the median interval {float(np.median(dt)):.6g} s (a record "
            "with a gap: split it into files)"
        )
    worst = float(np.spacing(np.max(np.abs(t))))
    if worst > TIME_RESOLUTION * float(np.median(dt)):
        raise ValueError(
            f"{p}:{header_line + 1}: column {tw!r} reaches {float(t[-1]):.6g} s, where a "
            f"number resolves only {worst:.2g} s, over {TIME_RESOLUTION:g} of the median "
            f"interval {float(np.median(dt)):.3g} s{_epoch_hint(float(t[-1]), always=True)}"
        )
    col = {c: data[:, k] for k, c in enumerate(header)}
    det = Detector(
        sensitivity=values["detector_sensitivity_m_per_V"],
        distance=values["detector_distance_m"],
        table_radius=values["table_radius_m"],
    )
    extra = {k: v for k, (_ln, v) in meta.items() if k not in ("axis", *META_RANGES)}
    return Measurement(
        axis=axis,
        amplifier_gain=values["amplifier_gain"],
        detector=det,
        time=col["t_s"],
        drives={c[6:-2]: col[c] for c in drive_cols},
        detector_v=col["detector_V"],
        detector_y_v=col.get("detector_y_V"),
        meta=extra,
        source=str(p),
    )
