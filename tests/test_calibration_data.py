"""Measurement file format (loader contract) and the thesis's summary-level data."""

import numpy as np
import pytest

from turntable_env.calibration import (
    Measurement,
    load_measurement,
    thesis_detector,
    thesis_targets,
)
from turntable_env.calibration.measurement import MIN_SAMPLES
from turntable_env.detector import Detector
from turntable_env.params import real_parameters

GOOD = """# axis: B
# amplifier_gain: 45
# detector_sensitivity_m_per_V: 9.9e-5
# detector_distance_m: 0.175
# table_radius_m: 0.01
# operator: lab notebook 12
t_s,drive_B_V,detector_V,detector_y_V
0.0,0.0,0.010,0.001
0.001,0.5,0.012,0.001
0.002,1.0,0.015,0.002
0.003,-2.0,0.020,0.002
0.004,0.0,0.020,0.002
0.005,0.0,0.020,0.002
0.006,0.0,0.020,0.002
0.007,0.0,0.020,0.002
0.008,0.0,0.020,0.002
0.009,0.0,0.020,0.002
0.010,0.0,0.020,0.002
0.011,0.0,0.020,0.002
0.012,0.0,0.020,0.002
0.013,0.0,0.020,0.002
0.014,0.0,0.020,0.002
0.015,0.0,0.020,0.002
"""  # 16 samples: MIN_SAMPLES


def _write(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _refused_at(tmp_path, text: str, line: int, match: str) -> None:
    """The file ``text`` is refused with a message matching ``match`` that names the
    file and ``line``."""
    p = _write(tmp_path, text)
    with pytest.raises(ValueError, match=match) as exc:
        load_measurement(p)
    assert f"{p}:{line}" in str(exc.value)


def test_loads_every_field(tmp_path):
    m = load_measurement(_write(tmp_path, GOOD))
    assert m.axis == "B" and m.amplifier_gain == 45.0
    assert m.detector.sensitivity == 9.9e-5 and m.detector.table_radius == 0.01
    np.testing.assert_array_equal(m.time[:4], [0.0, 0.001, 0.002, 0.003])
    np.testing.assert_array_equal(m.drives["B"][:4], [0.0, 0.5, 1.0, -2.0])
    np.testing.assert_array_equal(m.detector_y_v[:4], [0.001, 0.001, 0.002, 0.002])
    assert m.time.size == MIN_SAMPLES
    assert m.meta == {"operator": "lab notebook 12"}
    # Eq. 4.1: θ = ½·arctan(V·S/L)
    assert m.angle()[2] == pytest.approx(0.5 * np.arctan(0.015 * 9.9e-5 / 0.175), rel=1e-12)


def test_save_and_load_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(1e-6, 1e-5, 50))
    m = Measurement(
        axis="C", amplifier_gain=45.0, detector=Detector(table_radius=0.012),
        time=t, drives={"A": rng.uniform(-10, 10, 50), "C": rng.uniform(-1, 1, 50)},
        detector_v=rng.normal(0, 0.5, 50), meta={"protocol": "steps"},
    )  # fmt: skip
    back = load_measurement(m.save(tmp_path / "rt.csv"))
    np.testing.assert_array_equal(back.time, m.time)
    for k in ("A", "C"):
        np.testing.assert_array_equal(back.drives[k], m.drives[k])
    np.testing.assert_array_equal(back.detector_v, m.detector_v)
    assert back.detector_y_v is None and back.meta == {"protocol": "steps"}
    assert back.detector == m.detector and back.axis == "C"


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"axis": "Q"}, "axis"),
        ({"amplifier_gain": 0.0}, "amplifier_gain"),
        ({"amplifier_gain": float("nan")}, "amplifier_gain"),
        ({"drives": {"C": np.full(50, 50.0)}}, "drive_C_V"),  # beyond the ±10 V input
        ({"detector_v": np.full(50, 150.0)}, "detector_V"),
        ({"time": np.linspace(1e-3, 0.0, 50)}, "t_s"),  # time reversed
    ],
)
def test_save_refuses_what_the_loader_would_and_writes_nothing(tmp_path, change, match):
    """Measurement.save promises a file load_measurement reads back: a measurement the
    loader would refuse is refused before any file exists (and an old file is kept)."""
    from dataclasses import replace

    t = np.linspace(0.0, 49e-5, 50)
    good = Measurement(axis="C", amplifier_gain=45.0, detector=Detector(), time=t,
                       drives={"C": np.sin(t * 1e3)}, detector_v=np.cos(t * 1e3))  # fmt: skip
    path = good.save(tmp_path / "m.csv")
    before = path.read_bytes()
    with pytest.raises(ValueError, match=match):
        replace(good, **change).save(path)
    assert path.read_bytes() == before
    with pytest.raises(ValueError, match=match):
        replace(good, **change).save(tmp_path / "new.csv")
    assert not (tmp_path / "new.csv").exists()


@pytest.mark.parametrize(
    ("edit", "line", "match"),
    [
        (lambda t: t.replace("# axis: B\n", ""), 1, "'# axis: ...' missing"),
        (lambda t: t.replace("# axis: B", "# axis: Q"), 1, "axis"),
        (
            lambda t: t.replace("# amplifier_gain: 45", "# amplifier_gain: 4.5e4"),
            2,
            "amplifier_gain",
        ),
        (
            lambda t: t.replace("# table_radius_m: 0.01", "# table_radius_m: ten"),
            5,
            "table_radius_m",
        ),
        (lambda t: t.replace(",detector_V,", ",det_V,"), 7, "'det_V'"),
        (
            lambda t: t.replace("t_s,drive_B_V,detector_V,", "t_s,drive_Q_V,detector_V,"),
            7,
            "'drive_Q_V'",
        ),
        (lambda t: t.replace("t_s,drive_B_V,", "t_s,"), 7, "drive"),
        (lambda t: t.replace("0.001,0.5,", "0.001,abc,"), 9, "'drive_B_V' = 'abc'"),
        (lambda t: t.replace("0.001,0.5,", "0.001,nan,"), 9, "not finite"),
        (lambda t: t.replace("0.002,1.0,", "0.0005,1.0,"), 10, "'t_s'.*not increasing"),
        # a stamp far too late is named beside the one it stops (the cell that is wrong)
        (lambda t: t.replace("0.001,0.5,", "1e300,0.5,"), 10,
         r"'t_s' = '0.002' is not increasing \(line 9 before it: '1e300'\)"),
        (lambda t: t.replace("0.003,-2.0,", "0.003,-12.0,"), 11, "'drive_B_V'.*±10"),
        (lambda t: t.replace("0.003,-2.0,0.020,0.002", "0.003,-2.0,0.020"), 11, "3 cells"),
        # digits of other scripts are not ASCII decimals (full-width 4, Arabic-Indic 5)
        (lambda t: t.replace("# amplifier_gain: 45", "# amplifier_gain: \uff145"), 2, "gain"),
        (lambda t: t.replace("0.001,0.5,", "0.001,\u0665,"), 9, "'drive_B_V'"),
        # a form feed or U+2028 inside a cell ends no line: the bad cell keeps its number
        (lambda t: t.replace("0.0,0.0,0.010,", "0.0,0.0,0.010\x0c,").replace(
            "0.001,0.5,", "0.001,nan,"), 9, "'drive_B_V' = 'nan'"),
        (lambda t: t.replace("0.0,0.0,0.010,", "0.0,0.0,0.010\u2028,").replace(
            "0.001,0.5,", "0.001,nan,"), 9, "'drive_B_V' = 'nan'"),
    ],
)
def test_malformed_file_names_file_line_and_column(tmp_path, edit, line, match):
    _refused_at(tmp_path, edit(GOOD), line, match)


def test_unreadable_or_empty_files(tmp_path):
    p = tmp_path / "latin1.csv"
    p.write_bytes(GOOD.replace("operator: lab", "operator: l\xe4b").encode("latin-1"))
    with pytest.raises(ValueError, match="not UTF-8"):
        load_measurement(p)
    header_only = GOOD.split("0.0,0.0")[0]
    with pytest.raises(ValueError, match=f"at least {MIN_SAMPLES} samples"):
        load_measurement(_write(tmp_path, header_only, "h.csv"))


# --- the thesis's data ----------------------------------------------------------------------
def test_thesis_targets_are_the_chapter_4_figures():
    t = {x.name: x for x in thesis_targets()}
    assert t["amplifier_slew_1V"].value == 0.9e6 and t["amplifier_slew_3V"].value == 2.7e6
    assert t["amplifier_slew_900V"].value == 12e6 and t["amplifier_slew_adapted"].value == 8.0e6
    two, one = t["detector_dV_two_directional"], t["detector_dV_one_directional"]
    assert (two.value, two.drive["steps"]) == (0.53, 5)
    assert (one.value, one.drive["steps"]) == (1.19, 9)
    assert two.drive["axis"] == "B" and two.drive["amplitude_V"] == 2.0
    assert t["return_two_directional"].value == 0.0
    assert t["net_rotation_unadapted"].drive["amplifier"] == "unadapted"
    assert all(x.source.startswith("§4.1") for x in t.values())


@pytest.mark.parametrize(
    ("dv", "steps", "x_um", "step_um"), [(0.53, 5, 1.5, 0.30), (1.19, 9, 3.4, 0.37)]
)
def test_eq_4_1_and_4_2_reproduce_the_thesis_displacements(dv, steps, x_um, step_um):
    """0.53 V → 1.5 µm (0.30 µm per step), 1.19 V → 3.4 µm (0.37), §4.1.3."""
    x = float(thesis_detector().table_displacement(dv))
    assert x * 1e6 == pytest.approx(x_um, abs=0.05)
    assert x / steps * 1e6 == pytest.approx(step_um, abs=0.005)


def test_thesis_detector_is_the_parameter_sets_detector():
    d, p = thesis_detector(), real_parameters().detector
    assert (d.sensitivity, d.distance, d.linear_range) == (
        p.sensitivity,
        p.distance,
        p.linear_range,
    )


def _in_units(text: str, time_unit: str, volt_unit: str) -> str:
    """GOOD with its columns renamed to ``time_unit`` / ``volt_unit`` and their cells
    scaled to match (what a lab's logger writes in ms or mV)."""
    tf = {"s": 1.0, "ms": 1e3, "us": 1e6}[time_unit]
    vf = {"V": 1.0, "mV": 1e3}[volt_unit]
    out = []
    for line in text.splitlines():
        if line.startswith("t_s,"):
            line = ",".join(
                f"t_{time_unit}" if c == "t_s" else c[:-2] + "_" + volt_unit
                for c in line.split(",")
            )
        elif not line.startswith("#"):
            cells = [float(c) for c in line.split(",")]
            line = ",".join(repr(c * (tf if k == 0 else vf)) for k, c in enumerate(cells))
        out.append(line)
    return "\n".join(out) + "\n"


@pytest.mark.parametrize(("time_unit", "volt_unit"), [("ms", "V"), ("us", "mV"), ("s", "mV")])
def test_columns_in_other_units_load_as_si(tmp_path, time_unit, volt_unit):
    """A column's unit is part of its name: t_ms, t_us and *_mV load to the same seconds
    and volts as the SI file (to rounding of the scaled decimals)."""
    si = load_measurement(_write(tmp_path, GOOD, "si.csv"))
    m = load_measurement(_write(tmp_path, _in_units(GOOD, time_unit, volt_unit)))
    np.testing.assert_allclose(m.time, si.time, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(m.drives["B"], si.drives["B"], rtol=1e-12)
    np.testing.assert_allclose(m.detector_v, si.detector_v, rtol=1e-12)
    np.testing.assert_allclose(m.detector_y_v, si.detector_y_v, rtol=1e-12)


@pytest.mark.parametrize(
    ("edit", "line", "match"),
    [
        # a unit declared in the metadata that the columns it speaks of are not in
        (lambda t: "# time_unit: ms\n" + t, 1, "'time_unit' = 'ms', but column 't_s' is in s"),
        (lambda t: "# detector_unit: mV\n" + t, 1, "write 'detector_mV'"),
        (lambda t: "# units: mV\n" + t, 1, "column 'drive_B_V' is in V"),
        (lambda t: "# time_unit: fortnights\n" + t, 1, "not a unit of time"),
        (lambda t: "# Time unit: ms\n" + t, 1, "'Time unit' = 'ms', but column 't_s'"),
        (lambda t: "# drive_unit: ms\n" + t, 1, "not a unit of voltage"),
        # one quantity twice, in two units
        (lambda t: t.replace("t_s,drive_B_V,detector_V,detector_y_V",
                             "t_s,drive_B_V,detector_V,detector_mV"), 7,
         "'detector_V' and 'detector_mV' are one quantity"),
        # a drive in mV beyond the ±10 V input names the cell as written and its volts
        (lambda t: _in_units(t, "s", "mV").replace("-2000.0", "-12000.0"), 11,
         "'drive_B_mV' = -12000.0 = -12.0 V beyond the ±10 V"),
    ],
)
def test_declared_units_must_agree_with_the_columns(tmp_path, edit, line, match):
    """A unit in the metadata is read, not kept as text beside columns in another unit."""
    _refused_at(tmp_path, edit(GOOD), line, match)


def test_units_of_other_quantities_and_agreeing_units_are_kept_as_text(tmp_path):
    m = load_measurement(_write(tmp_path, "# temperature_unit: C\n# time_unit: ms\n"
                                + _in_units(GOOD, "ms", "V")))  # fmt: skip
    assert m.meta["temperature_unit"] == "C" and m.meta["time_unit"] == "ms"
    assert m.time[1] == pytest.approx(1e-3, rel=1e-12)


@pytest.mark.parametrize("interval", [1e-4, 5e-5])
def test_epoch_time_stamps_are_refused_naming_the_resolution(tmp_path, interval):
    """Seconds since 1970 (1.7e9 s): float64 resolves 2.4e-7 s there, 0.5 % of a 20 kHz
    interval. The file is refused with what to write (time from the record's start),
    whether its stamps still increase (10 kHz: 0.24 % of the interval) or collide (20 kHz)."""
    rows = [ln for ln in GOOD.splitlines() if ln[:1].isdigit()]
    body = [f"{1.7e9 + k * interval!r}," + ln.split(",", 1)[1] for k, ln in enumerate(rows)]
    head = [ln for ln in GOOD.splitlines() if not ln[:1].isdigit()]
    p = _write(tmp_path, "\n".join(head + body) + "\n")
    with pytest.raises(ValueError, match=r"resolved to 2\.4e-07 s: write time from the record"):
        load_measurement(p)


@pytest.mark.parametrize(
    "line",
    [
        # units of other quantities than the columns': kept as text, the file read as is
        "# trigger_time_unit: ms",
        "# exposure_time_unit: us",
        "# detector_distance_unit: m",
        "# drive_frequency_units: Hz",
        "# detector_noise_unit: mV",
        "# detector_gain_unit: V/rad",
        "# units: SI",
        "# time: 14:32",
        "# detector: PDQ80A",
    ],
)
def test_units_of_other_quantities_leave_the_columns_alone(tmp_path, line):
    m = load_measurement(_write(tmp_path, line + "\n" + GOOD))
    key, _, value = line[2:].partition(": ")
    assert m.meta[key] == value
    assert m.time[1] == 0.001


@pytest.mark.parametrize(
    "line",
    ["# time_base: ms", "# time: ms", "# unit_time: ms", "# clock_unit: ms", "# timeunit: ms",
     "# units: s, V, mV, mV"],
)
def test_every_spelling_of_a_unit_declaration_is_read(tmp_path, line):
    """Declarations a DAQ or a colleague writes (a time base, a unit list per column) are
    read and checked against the columns, not kept as text while the cells load 1000×
    off."""
    p = _write(tmp_path, line + "\n" + GOOD)
    with pytest.raises(ValueError, match=r"but column '(t_s|detector_V)' is in"):
        load_measurement(p)
    # the same declarations over columns in those units load as SI
    right = _in_units(GOOD, "ms", "V") if "s, V" not in line else GOOD.replace(
        "detector_V,detector_y_V", "detector_mV,detector_y_mV")  # fmt: skip
    m = load_measurement(_write(tmp_path, line + "\n" + right, "right.csv"))
    assert m.time[1] == pytest.approx(1e-3, rel=1e-12)


def test_a_unit_list_of_another_length_is_refused(tmp_path):
    p = _write(tmp_path, "# units: s, V, V\n" + GOOD)
    with pytest.raises(ValueError, match="lists 3 units for 4 columns"):
        load_measurement(p)


@pytest.mark.parametrize(
    ("edit", "line", "match"),
    [
        # a column name in another case, or of another vocabulary
        (lambda t: t.replace("t_s,", "T_s,"), 7, "did you mean 't_s'"),
        (lambda t: t.replace(",detector_V,", ",detector_mv,"), 7, "did you mean 'detector_mV'"),
        (lambda t: t.replace("t_s,", "Time [s],"), 7, "its columns: t_s, t_ms or t_us"),
        # no header row: the first data row read as one
        (lambda t: t.replace("t_s,drive_B_V,detector_V,detector_y_V\n", ""), 7,
         "a number where the header belongs"),
        # a comment line among the data
        (lambda t: t.replace("0.004,0.0,", "# re-armed\n0.004,0.0,"), 12,
         "a comment inside the data"),
        # a drive in millivolts under a volts name
        (lambda t: t.replace("0.003,-2.0,", "0.003,-2000.0,"), 11,
         r"beyond the ±10 V amplifier input \(in mV\? name the column drive_B_mV\)"),
    ],
)
def test_a_misnamed_or_misplaced_line_says_what_to_write(tmp_path, edit, line, match):
    _refused_at(tmp_path, edit(GOOD), line, match)


def test_metadata_under_another_comment_mark_is_named(tmp_path):
    p = _write(tmp_path, GOOD.replace("# axis: B", "% axis: B"))
    with pytest.raises(ValueError, match=r"line 1 reads '% axis: B': a metadata line is '# axis"):
        load_measurement(p)


def test_a_greek_mu_reads_as_the_micro_sign(tmp_path):
    m = load_measurement(_write(tmp_path, _in_units(GOOD, "us", "V").replace("t_us", "t_\u03bcs")))
    assert m.time[1] == pytest.approx(1e-3, rel=1e-12)


@pytest.mark.parametrize(("encoding", "name"), [("utf-16", "UTF-16"), ("cp1252", "Latin-1")])
def test_another_encoding_is_named(tmp_path, encoding, name):
    p = tmp_path / "enc.csv"
    p.write_bytes(GOOD.replace("lab notebook", "Jürgen's notebook").encode(encoding))
    with pytest.raises(ValueError, match=f"{name}.*save it so"):
        load_measurement(p)
