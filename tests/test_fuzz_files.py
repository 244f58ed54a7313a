"""Hostile measurement files (issue 23): the loader takes a file or refuses it with a
ValueError naming the file (and the line where there is one); every file it takes runs
through the calibrator on a tiny budget with no exception but a ValueError naming it."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from turntable_env.calibration.calibrate import calibrate, write_report
from turntable_env.calibration.measurement import (
    MAX_LINE_CHARS,
    MIN_SAMPLES,
    Measurement,
    load_measurement,
)
from turntable_env.calibration.trace import simulate_trace
from turntable_env.detector import Detector
from turntable_env.plant import Plant

META = {
    "axis": "B",
    "amplifier_gain": "20",
    "detector_sensitivity_m_per_V": "1e-4",
    "detector_distance_m": "0.5",
    "table_radius_m": "0.01",
}
CELLS = st.one_of(
    st.floats(-12, 12, allow_nan=False).map(repr),
    st.sampled_from(["", "nan", "inf", "-", "1_0", "１", "0x10", "1e400", " 2 ", "1,5", '"3"']),
    st.text(max_size=6),
)


def _value(kind: str, k: int, n: int, rng: np.random.Generator, dt: float, flat: bool) -> float:
    if kind == "t":
        return k * dt
    if kind == "drive":  # a sawtooth stepping drive with holds
        period = max(n // 6, 2)
        return 0.0 if (k // period) % 2 else 2.0 * ((k % period) / period)
    if flat:  # a noise-free, motionless detector: a zero noise floor
        return 0.0
    return 0.01 * math.sin(k / 7) + float(rng.normal(0, 1e-3))


@st.composite
def measurement_files(draw: st.DrawFn) -> str:
    """A measurement file: mostly well formed, with one or two defects drawn in."""
    meta = dict(META)
    if draw(st.integers(0, 4)) == 0:
        meta["axis"] = draw(st.sampled_from(["A", "C", "Z", "Q", ""]))
    n_bad = draw(st.integers(0, 5))
    for key in draw(st.lists(st.sampled_from(list(META)), max_size=1 if n_bad < 2 else 0)):
        choice = draw(st.sampled_from(["drop", "bad", "dup"]))
        if choice == "drop":
            meta.pop(key, None)
        elif choice == "bad":
            meta[key] = draw(st.sampled_from(["-1", "nan", "1e9", "x", "", "1_0"]))
    lines = [f"# {k}: {v}" for k, v in meta.items()]
    if draw(st.integers(0, 7)) == 0:
        lines.append(f"# {draw(st.sampled_from(list(META)))}: 1")  # a duplicated key
    cols = ["t_s", "drive_B_V", "detector_V"]
    cols += draw(st.lists(st.sampled_from(["drive_A_V", "drive_C_V", "detector_y_V"]),
                          max_size=2, unique=True))  # fmt: skip
    if draw(st.integers(0, 5)) == 0:
        cols.remove(draw(st.sampled_from(cols)))
    if draw(st.integers(0, 9)) == 0:
        cols.append(draw(st.sampled_from(["drive_X_V", "t_s", "junk"])))
    lines.append(",".join(cols))
    n = draw(st.one_of(st.integers(0, 20), st.integers(20, 200)))
    dt = draw(st.sampled_from([1e-4, 1e-3, 1e-5]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    kinds = ["t" if c == "t_s" else "drive" if c.startswith("drive") else "det" for c in cols]
    flat = draw(st.integers(0, 5)) == 0
    rows = [[repr(_value(kd, k, n, rng, dt, flat)) for kd in kinds] for k in range(n)]
    if rows and draw(st.integers(0, 7)) == 0:  # a gap, a repeat or a ragged row
        r = draw(st.integers(0, len(rows) - 1))
        what = draw(st.sampled_from(["gap", "repeat", "ragged"]))
        if what == "gap":
            for row in rows[r:]:
                row[0] = repr(float(row[0]) + 10.0)
        elif what == "repeat":
            rows.insert(r, list(rows[r]))
        else:
            rows[r] = rows[r][:-1]
    for _ in range(draw(st.integers(0, 2)) * (draw(st.integers(0, 2)) == 0)):  # damaged cells
        if rows:
            r = draw(st.integers(0, len(rows) - 1))
            rows[r][draw(st.integers(0, len(rows[r]) - 1))] = draw(CELLS)
    lines += [",".join(r) for r in rows]
    text = "\n".join(lines) + "\n"
    if draw(st.integers(0, 9)) == 0:
        text = "\ufeff" + text  # a byte-order mark, as spreadsheet programs write
    return text


def _names_file(exc: ValueError, path) -> None:
    msg = str(exc)
    assert msg.startswith(str(path)), msg
    assert "\n" not in msg and "Traceback" not in msg


@pytest.mark.slow  # the default tier's 5 CPU minutes (stop 48): 20 calibrations, 37 s
@settings(
    max_examples=20, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(text=measurement_files())
def test_a_file_loads_and_calibrates_or_is_refused_with_its_name(text, tmp_path):
    path = tmp_path / "m.csv"
    path.write_text(text, encoding="utf-8")
    try:
        m = load_measurement(path)
    except ValueError as exc:
        _names_file(exc, path)
        if re.match(rf"{re.escape(str(path))}:\d+:", str(exc)) is None:  # no line: whole-file
            assert re.search(r"samples|header|bytes|regular|UTF-8|jumps|segment", str(exc))
        return
    assert m.time.size >= MIN_SAMPLES and np.all(np.diff(m.time) > 0)
    assert m.axis in m.drives
    if m.axis != "Z":  # the virtual lab re-simulates the file's drive
        sim = simulate_trace(Plant("real"), m.axis, m.time, m.drives[m.axis])
        assert np.isfinite(sim.detector_v).all() and sim.detector_v.shape == m.time.shape
    try:
        res = calibrate([path], global_points=2, starts=1, hops=0, candidates=[], workers=1,
                        progress=None)  # fmt: skip
    except ValueError as exc:
        _names_file(exc, path)
        return
    assert math.isfinite(res.error_before) and math.isfinite(res.error_after)
    paths = write_report(res, tmp_path / "report")
    assert paths["json"].is_file() and paths["md"].is_file()


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("# axis: B\n# axis: C\n", r":2: metadata 'axis' given twice \(first on line 1\)"),
        ("x" * (MAX_LINE_CHARS + 1) + "\n", rf":1: {MAX_LINE_CHARS + 1} characters"),
    ],
)
def test_defects_are_named_with_their_line(text, match, tmp_path):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_measurement(p)


def _good(n: int = 40, axis: str = "B", drives: tuple[str, ...] = ("B",)) -> str:
    head = "".join(f"# {k}: {v}\n" for k, v in {**META, "axis": axis}.items())
    cols = ["t_s", *(f"drive_{d}_V" for d in drives), "detector_V"]
    rows = [",".join([repr(k * 1e-4), *["0.5"] * len(drives), repr(1e-3 * k)]) for k in range(n)]
    return head + ",".join(cols) + "\n" + "\n".join(rows) + "\n"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (_good(drives=("A",)), "'drive_B_V' missing: the watched axis"),
        (_good(n=3), f"at least {MIN_SAMPLES} samples, found 3"),
        (_good().replace("0.5\n", "1_0\n", 1).replace(",0.5,", ",1_0,", 1), "is not a number"),
        (_good().replace("\n0.0001,", "\n10.0001,"), "not increasing"),
        (_good(drives=("B", "B")), "column 'drive_B_V' appears twice"),  # which one, named
        ("# drive_recording: bogus\n" + _good(), r"m.csv:1: metadata 'drive_recording' = 'bogus'"),
        ("# drive_flybacks: ramp\n" + _good(), r"m.csv:1: metadata 'drive_flybacks' = 'ramp'"),
    ],
)
def test_the_loader_refuses_what_the_calibrator_cannot_use(text, match, tmp_path):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_measurement(p)


def test_a_time_gap_is_refused_and_a_bom_is_read(tmp_path):
    lines = _good(n=40).splitlines()
    lines[-1] = "10.0," + lines[-1].split(",", 1)[1]
    p = tmp_path / "gap.csv"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=rf"gap.csv:{len(lines)}: column 't_s' jumps .* t = \d"):
        load_measurement(p)  # the line of the sample after the gap, the time as a number
    q = tmp_path / "bom.csv"
    q.write_text("\ufeff" + _good(), encoding="utf-8")
    assert load_measurement(q).axis == "B"


@pytest.mark.parametrize("special", ["/dev/zero", "fifo"])
def test_special_files_are_refused_before_reading(special, tmp_path):
    import os

    p = special
    if special == "fifo":
        p = tmp_path / "pipe.csv"
        os.mkfifo(p)
    with pytest.raises(ValueError, match="not a regular file"):
        load_measurement(p)


def _m(**meta) -> Measurement:
    t = np.arange(20) * 1e-4
    return Measurement("B", 20.0, Detector(1e-4, 0.5, 0.01), t, {"B": np.zeros(20)},
                       np.zeros(20), meta=meta)  # fmt: skip


@pytest.mark.parametrize(
    ("meta", "match"),
    [({"axis": "C"}, "reserved"), ({"note": "a\nb"}, "single lines"), ({"a:b": "1"}, "single")],
)
def test_save_refuses_what_the_loader_would_misread(meta, match, tmp_path):
    p = tmp_path / "m.csv"
    with pytest.raises(ValueError, match=match):
        _m(**meta).save(p)
    assert not p.exists()


def test_save_refuses_non_finite_samples_and_round_trips_metadata(tmp_path):
    m = _m(operator="A. B.", note="x")
    with pytest.raises(ValueError, match="sample 5, column 'detector_V'"):  # refused when built
        bad = np.where(np.arange(20) == 5, np.nan, 0.0)
        Measurement(m.axis, m.amplifier_gain, m.detector, m.time, m.drives, bad).save(
            tmp_path / "bad.csv")  # fmt: skip
    assert not (tmp_path / "bad.csv").exists()
    back = load_measurement(m.save(tmp_path / "m.csv"))
    assert back.meta == {"operator": "A. B.", "note": "x"}
