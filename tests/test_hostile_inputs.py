"""Reliability, second pass (issue 34): outputs never replace what they should not, report
directories are complete or untouched, every input path is bounded, and data without
information gets no confident answer. Each test is one of the issue's numbered items."""

from __future__ import annotations

import json
import math
import os
import signal
import stat
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import turntable_env  # noqa: F401  (registers the envs)
from turntable_env.calibration.measurement import load_measurement
from turntable_env.calibration.nominal import NominalModel
from turntable_env.calibration.thesis_data import THESIS_DATA_FILE
from turntable_env.calibration.trace_fit import (
    TRACE_NOMINAL,
    TraceProblem,
    check_information,
    clipped_stretch,
    on_base,
    signature_search,
    trace_data,
)
from turntable_env.cli import main
from turntable_env.envs.config import MAX_NUM_ENVS
from turntable_env.files import MARKER, output_directory, write_atomic
from turntable_env.plant import Plant

ROOT = Path(__file__).resolve().parents[1]


def _one_line_exit_2(capsys, rc: int, *needles: str) -> str:
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert "\n" not in err and "Traceback" not in err, err
    for n in needles:
        assert n in err, (n, err)
    return err


# --- 1. --out never replaces a link, a device or a FIFO -----------------------------------
def test_out_through_a_symlink_writes_its_target_and_keeps_the_link(tmp_path, capsys):
    target = tmp_path / "real.csv"
    target.write_text("old\n")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    rc = main(["virtual-lab", "--protocol", "standard", "--out", str(link)])
    assert rc == 0, capsys.readouterr().err
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text().startswith("#") and load_measurement(link).time.size > 16


@pytest.mark.parametrize("kind", ["fifo", "device", "link_to_fifo", "empty"])
def test_out_refuses_what_is_not_a_regular_file(kind, tmp_path, capsys):
    p = tmp_path / "out.csv"
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "device":
        if os.geteuid() != 0:
            pytest.skip("mknod of a character device needs root")
        os.mknod(p, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # a /dev/null of our own
    elif kind == "link_to_fifo":
        os.mkfifo(tmp_path / "pipe")
        p.symlink_to(tmp_path / "pipe")
    else:
        p = Path("")
    before = os.lstat(p).st_mode if kind != "empty" else None
    rc = main(["simulate", "--model", "reduced", "--periods", "2", "--out", str(p)])
    _one_line_exit_2(capsys, rc, "--out")
    if before is not None:
        assert os.lstat(p).st_mode == before  # still the same kind of file
    with pytest.raises(ValueError):
        write_atomic(p, "x")


# --- 2. report directories: swapped in whole, or refused ---------------------------------
def test_a_new_report_replaces_the_old_one_whole(tmp_path):
    d = tmp_path / "rx"
    d.mkdir()
    (d / MARKER).write_text("")
    (d / "residual.png").write_bytes(b"old")
    (d / "report.md").mkdir()  # the hostile case: a file name taken by a directory
    with output_directory(d) as tmp:
        (tmp / "report.json").write_text("{}")
        (tmp / "report.md").write_text("new")
    assert sorted(p.name for p in d.iterdir()) == sorted([MARKER, "report.json", "report.md"])
    assert (d / "report.md").read_text() == "new"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # nothing left over


def test_a_report_directory_given_as_a_link_is_refused_as_a_link(tmp_path):
    """A report directory is replaced whole, which would replace a link and leave its
    target: refused, and the message says it is a link (not "not a directory")."""
    from turntable_env.files import check_writable

    (tmp_path / "real").mkdir()
    (tmp_path / "rep").symlink_to(tmp_path / "real")
    with pytest.raises(ValueError, match=r"--report=.*rep': a symbolic link \(to .*real'\)"):
        check_writable("--report", tmp_path / "rep", directory=True)
    assert (tmp_path / "rep").is_symlink() and not any((tmp_path / "real").iterdir())


def test_report_json_is_strict_json_with_null_for_what_was_not_computed(tmp_path):
    """A figure the calibration could not compute (a line search over no frequency gives
    NaN) is null in report.json, which any JSON parser reads; json.dumps alone writes a
    bare NaN, which strict parsers refuse."""
    from turntable_env.calibration.calibrate import write_report
    from turntable_env.calibration.result import CalibrationResult

    res = CalibrationResult(
        selected_effects=[], parameters={}, error_before=5.0, error_after=4.0,
        error_unit="nm", residual_structured=False, candidates=[],
        diagnosis={"signatures": {"lines": [{"frequency_Hz": math.nan}]},
                   "peak": np.float64(math.inf)},
        residuals={"after": np.zeros(8)},
    )  # fmt: skip

    def refuse(name):
        raise AssertionError(f"report.json holds a bare {name}")

    paths = write_report(res, tmp_path / "r")
    doc = json.loads(paths["json"].read_text(), parse_constant=refuse)
    assert doc["diagnosis"]["signatures"]["lines"][0]["frequency_Hz"] is None
    assert doc["diagnosis"]["peak"] is None and doc["error_after"] == 4.0


def test_a_failed_report_leaves_the_old_one_untouched(tmp_path):
    d = tmp_path / "rx"
    d.mkdir()
    (d / MARKER).write_text("")
    (d / "report.json").write_text("old")
    with pytest.raises(RuntimeError), output_directory(d) as tmp:
        (tmp / "report.json").write_text("half")
        raise RuntimeError("plot failed")
    assert sorted(p.name for p in d.iterdir()) == sorted([MARKER, "report.json"])
    assert (d / "report.json").read_text() == "old"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("main_file", [None, "index.html", "report.json"])
def test_a_directory_of_other_files_is_not_emptied(tmp_path, capsys, main_file):
    """Only the project's marker makes a directory its own: a web site's index.html or
    another tool's report.json beside the user's files does not."""
    d = tmp_path / "mine"
    d.mkdir()
    (d / "thesis.tex").write_text("precious")
    if main_file is not None:
        (d / main_file).write_text("theirs")
    rc = main(["calibrate", "--thesis", "--report", str(d)])
    _one_line_exit_2(capsys, rc, "--report", "not an earlier output")
    assert (d / "thesis.tex").read_text() == "precious"
    with pytest.raises(ValueError, match="not an earlier output"), output_directory(d):
        pass
    kept = ["thesis.tex"] + ([main_file] if main_file else [])
    assert sorted(p.name for p in d.iterdir()) == sorted(kept)


def test_sigterm_while_writing_leaves_no_temporary_directory(tmp_path):
    d = tmp_path / "rx"
    code = (
        "import os, signal, time\n"
        "from turntable_env.files import output_directory\n"
        f"with output_directory({str(d)!r}) as tmp:\n"
        "    (tmp / 'report.json').write_text('{}')\n"
        "    os.kill(os.getpid(), signal.SIGTERM)\n"
        "    time.sleep(30)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=120)
    assert r.returncode == 128 + signal.SIGTERM, r.stderr.decode()[-2000:]
    assert not d.exists() and list(tmp_path.iterdir()) == []


def test_sigterm_swallowed_in_a_c_callback_still_ends_the_run(tmp_path):
    """numba's compile calls Python through ctypes; a SIGTERM whose Terminated is raised
    in such a callback is swallowed by ctypes ("Exception ignored"), and ``timeout turntable
    virtual-lab`` on a cold cache ran to the end and wrote its file (stop 109's probe). It
    is delivered again once the callback returns: exit 143, the output directory's
    temporary gone, nothing printed after, no "Exception ignored" lines."""
    d = tmp_path / "rx"
    code = (
        "import ctypes, os, signal, time\n"
        "from turntable_env.files import output_directory, terminate_cleanly\n"
        "def cb():\n"
        "    os.kill(os.getpid(), signal.SIGTERM)\n"
        "    time.sleep(0.05)\n"
        "callback = ctypes.CFUNCTYPE(None)(cb)\n"
        f"with terminate_cleanly(), output_directory({str(d)!r}) as tmp:\n"
        "    (tmp / 'report.json').write_text('{}')\n"
        "    callback()\n"
        "    time.sleep(30)\n"
        "    print('finished', flush=True)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=120)
    err = r.stderr.decode()
    assert r.returncode == 128 + signal.SIGTERM, err[-2000:]
    assert b"finished" not in r.stdout and "Exception ignored" not in err, err[-2000:]
    assert not d.exists() and list(tmp_path.iterdir()) == []


def test_the_calibration_workers_die_on_sigterm_as_the_group_does():
    """The calibration's forked workers do not keep the parent's SIGTERM handler: raised
    inside a worker's wait on the task queue it left the queue's lock held, and
    ``timeout turntable calibrate …`` (SIGTERM to the group) sometimes never exited."""
    from concurrent.futures import ProcessPoolExecutor

    from turntable_env.calibration.trace_fit import _init_worker
    from turntable_env.files import terminate_cleanly

    with terminate_cleanly():
        assert signal.getsignal(signal.SIGTERM) not in (signal.SIG_DFL, None)
        with ProcessPoolExecutor(1, initializer=_init_worker, initargs=(None,)) as ex:
            in_worker = ex.submit(signal.getsignal, signal.SIGTERM).result(timeout=60)
    assert in_worker == signal.SIG_DFL


# --- 3. the summary-TOML path is validated like the CSV path ------------------------------
def _summary(tmp_path: Path, old: str, new: str) -> Path:
    text = THESIS_DATA_FILE.read_text(encoding="utf-8")
    if old == "<start>":
        text = new + "\n" + text.replace("[[stepping]]", "[[stepping_old]]")
    else:
        assert old in text, old
        text = text.replace(old, new, 1)
    p = tmp_path / "figures.toml"
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize(
    "old, new, needle",
    [
        ("frequency_Hz = 100.0", "frequency_Hz = 0.0", "frequency_Hz = 0.0"),
        ("steps = 5", "steps = 1000000000", "steps = 1000000000"),
        ("<start>", "stepping = 5", "stepping"),
        ("[[stepping]]  # Fig. 4.6", "stepping = 5\n[[stepping]]", "stepping is not part"),
        ("slew_V_per_us = 0.9", 'slew_V_per_us = "fast"', "slew_V_per_us = 'fast'"),
        ('[detector]  # §4.1.1, Fig. 4.4', 'detector = "x"\n[y]', "detector"),
        ('amplifier = "adapted"', 'amplifier = "turbo"', "amplifier = 'turbo'"),
        # the [amplifier] table is checked though the model's amplifier is the parameter set's
        ("gain = 45.0", "gain = nan", "[amplifier]: gain = nan"),
        ("current_limit_A = 0.025", "current_limit_A = -1e9", "current_limit_A"),
        ("input_limit_V = 10.0", 'input_limit_V = 10.0\nbogus = "x"', "bogus is not part"),
        # a figure its relative errors divide by (stop 109's probe: NaN residuals, 5 lines)
        ("detector_dV = 0.53", "detector_dV = 0.0", "detector_dV = 0.0"),
        # under the protocol's 1 Hz: refused by the file's key, not by a protocol block's index
        ("frequency_Hz = 100.0", "frequency_Hz = 1e-300", "frequency_Hz = 1e-300"),
        # two observations are two figures of one name, refused as two steppings of one are
        ("[[observation]]", "[[observation]]\nsource = \"x\"\naxis = \"B\"\namplitude_V = 2.0\n"
         "frequency_Hz = 100.0\namplifier = \"unadapted\"\n[[observation]]",
         "appear more than once"),
    ],
)
def test_bad_summary_files_are_refused_naming_key_and_value(old, new, needle, tmp_path, capsys):
    p = _summary(tmp_path, old, new)
    rc = main(["calibrate", str(p), "--report", str(tmp_path / "out")])
    _one_line_exit_2(capsys, rc, str(p), needle)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["missing", "fifo", "binary"])
def test_summary_files_that_are_not_text_files_are_refused(kind, tmp_path, capsys):
    p = tmp_path / "figures.toml"
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "binary":
        p.write_bytes(b"\x00\xff\xfe garbage = \x80")
    rc = main(["calibrate", str(p), "--report", str(tmp_path / "out")])
    _one_line_exit_2(capsys, rc, str(p))


# --- 4. plant=PATH reads only what a report can be ----------------------------------------
def _make(path):
    return gym.make("PiezoTurntable-v0", plant=str(path))


def test_plant_paths_are_bounded_before_reading(tmp_path):
    big = tmp_path / "big.json"
    with open(big, "wb") as fh:
        fh.truncate(2 * 2**30)  # 2 GiB, sparse: refused on its size, never read
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    for p, needle in ((big, "bytes"), (fifo, "regular file"), (deep, "nested")):
        with pytest.raises(ValueError, match=needle) as e:
            _make(p)
        assert str(p) in str(e.value)


@pytest.mark.parametrize(
    "report, needle",
    [
        ({"parameters": [1, 2], "selected_effects": []}, "parameters"),
        ({"parameters": {"nominal": {"friction": {"value": "x"}}}, "selected_effects": []},
         "value = 'x'"),
        ({"plant": {"effects": {"piezo_creep": float("nan")}}}, "must be a table"),
        ({"plant": {"effects": {"piezo_creep": {"gamma": float("nan")}}}}, "finite"),
    ],
)
def test_malformed_reports_are_refused_with_their_key(report, needle, tmp_path):
    p = tmp_path / "report.json"
    p.write_text(json.dumps(report))
    with pytest.raises(ValueError, match=needle):
        _make(p)


# --- 5–6. no confident answer from data without information ------------------------------
@pytest.fixture(scope="module")
def lab_file(tmp_path_factory):
    p = tmp_path_factory.mktemp("lab") / "lab.csv"
    assert main(["virtual-lab", "--protocol", "standard", "--out", str(p)]) == 0
    return p


def _rewrite(src: Path, dst: Path, fn) -> Path:
    """The measurement file with its data rows changed by ``fn(columns) -> columns``."""
    lines = src.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    header = lines[len(head)]
    rows = np.array([[float(x) for x in ln.split(",")] for ln in lines[len(head) + 1:]])
    cols = dict(zip(header.split(","), rows.T, strict=True))
    cols = fn(cols)
    body = "\n".join(",".join(repr(float(v)) for v in r) for r in zip(*cols.values(), strict=True))
    dst.write_text("\n".join([*head, ",".join(cols), body]) + "\n")
    return dst


@pytest.mark.parametrize(
    "case",
    ["held_drive", "zero_drive", "constant_detector", "tiny_values", "milliseconds", "short"],
)
def test_a_trace_without_information_is_refused_before_fitting(case, lab_file, tmp_path, capsys):
    def change(c):
        drive = [k for k in c if k.startswith("drive_")]
        if case == "held_drive":
            for k in drive:
                c[k] = np.full_like(c[k], 0.5)
            c["detector_V"] = np.full_like(c["detector_V"], 0.1)
        elif case == "zero_drive":
            for k in drive:
                c[k] = np.zeros_like(c[k])
        elif case == "constant_detector":
            c["detector_V"] = np.full_like(c["detector_V"], 0.2)
        elif case == "tiny_values":
            for k in c:
                if k != "t_s":
                    c[k] = c[k] * 1e-300
        elif case == "milliseconds":
            c["t_s"] = c["t_s"] * 1e3
        else:
            c = {k: v[:16] for k, v in c.items()}
        return c

    p = _rewrite(lab_file, tmp_path / f"{case}.csv", change)
    out = tmp_path / "report"
    t0 = time.perf_counter()
    rc = main(["calibrate", str(p), "--report", str(out)])
    _one_line_exit_2(capsys, rc, str(p))
    assert not out.exists()  # no report, no calibrated.toml
    assert time.perf_counter() - t0 < 120  # refused up front, not after a global stage


@pytest.mark.parametrize("steps_per_noise", [2.0, 8.0])
def test_a_quantised_detector_has_its_quantisation_noise_as_floor(
    steps_per_noise, lab_file, tmp_path
):
    """A detector read by an ADC whose step q is larger than its noise: most quiet
    samples read alike, the MAD of their differences is 0, and a floor of 0 ended a
    calibration in a ZeroDivisionError after its fit (a 12-bit ±10 V ADC, q = 4.9 mV, under
    1 mV of noise). The floor is the standard deviation of the differences, never under
    the step's quantisation noise q/√12 (``residual.noise_floor``); an unquantised record
    keeps its MAD estimate."""
    src = load_measurement(lab_file)
    plain = trace_data(src)
    q = steps_per_noise * plain.floor / plain.scale  # [V]

    def quantise(c):
        c["detector_V"] = np.round(c["detector_V"] / q) * q
        return c

    td = trace_data(load_measurement(_rewrite(lab_file, tmp_path / "adc.csv", quantise)))
    assert plain.floor_source == "first differences in quiet holds"
    assert td.floor >= q / math.sqrt(12.0) * td.scale * (1.0 - 1e-9)
    # the quantised record's noise: its own plus at most the quantisation's
    assert td.floor <= math.hypot(plain.floor, q / math.sqrt(12.0) * td.scale) * 1.25


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_clipped_detector_is_named(side, lab_file, tmp_path):
    """A detector that stays at its extreme while a burst moves the table is clipped at
    its range: the calibration warns, naming the level and where it starts, and the
    unclipped file draws no such warning."""
    src = load_measurement(lab_file)
    td = trace_data(src)
    burst = next(s for s in td.segments if s.kind == "steps")
    v = src.detector_v
    inside = (src.time >= burst.start) & (src.time < burst.end)
    level = float(np.median(v[inside]))  # half the burst beyond it

    def clip(c):
        c["detector_V"] = np.minimum(c["detector_V"], level) if side > 0 else np.maximum(
            c["detector_V"], level)  # fmt: skip
        return c

    m = load_measurement(_rewrite(lab_file, tmp_path / "clipped.csv", clip))
    msg = clipped_stretch(m.time, m.detector_v, td.segments)
    assert f"stays at {level:.6g} V" in msg and "clipped" in msg
    assert clipped_stretch(src.time, src.detector_v, td.segments) == ""


def test_a_detector_without_noise_is_refused_before_fitting(lab_file, tmp_path, capsys):
    """A held detector (one level, then another) has no noise floor to weigh the
    residuals by: refused in one line before any fit, not divided by zero after one."""

    def held(c):
        c["detector_V"] = np.where(c["t_s"] > 0.5 * c["t_s"][-1], 0.5, 0.0)
        return c

    p = _rewrite(lab_file, tmp_path / "held.csv", held)
    out = tmp_path / "report"
    rc = main(["calibrate", str(p), "--report", str(out)])
    _one_line_exit_2(capsys, rc, str(p), "shows no noise")
    assert not out.exists()


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ("# axis: B", "# axis=B", "line 1 reads '# axis=B'"),
        ("# axis: B", "# Axis: B", "its key in lower case"),
        ("t_s,", "t_s;", "by semicolons"),
        ("t_s,", ",t_s,", "an empty column name"),
    ],
)
def test_a_near_miss_of_the_format_is_named(old, new, needle, lab_file, tmp_path, capsys):
    """Files a lab writes nearly in the format (another separator, a key's case, a pandas
    index column) are refused with what is off, not only that a key or column is unknown."""
    text = lab_file.read_text()
    assert old in text
    p = tmp_path / "near.csv"
    p.write_text(text.replace(old, new, 1))
    rc = main(["calibrate", str(p), "--report", str(tmp_path / "report")])
    _one_line_exit_2(capsys, rc, str(p), needle)


def test_the_sampling_intervals_range_holds_its_ends(lab_file, tmp_path):
    """A 1 kHz file with decimal times (0.001 apart, 0.0010000000000000009 in binary) is
    at the range's end, not outside it ("0.001 s, outside 1e-06…0.001 s" before)."""
    m = load_measurement(lab_file)
    keep = np.flatnonzero(np.diff(np.floor(m.time * 1e3), prepend=-1.0) > 0)

    def decimate(c):
        c = {k: v[keep] for k, v in c.items()}
        c["t_s"] = np.round(c["t_s"], 3)
        return c

    d = load_measurement(_rewrite(lab_file, tmp_path / "1kHz.csv", decimate))
    assert float(np.median(np.diff(d.time))) > 1e-3
    check_information(d)  # no ValueError



@pytest.mark.slow  # a whole calibration (12 s of CPU): the default tier's budget
def test_a_trace_that_identifies_no_parameter_is_untested(lab_file, tmp_path, capsys):
    """A millisecond of the lab's file (21 samples, the window with most motion) passes
    the information check and meets its target at any parameters: the report and the
    command line say the fit is untested (the data identify no nominal parameter), not
    only "met", and do not flag the model as lacking a structure."""
    m = load_measurement(lab_file)
    n = round(1e-3 / float(np.median(np.diff(m.time)))) + 1
    k0 = max(range(0, m.time.size - n, n // 2), key=lambda k: np.ptp(m.detector_v[k : k + n]))

    def cut(c):
        c = {k: v[k0 : k0 + n] for k, v in c.items()}
        c["t_s"] = c["t_s"] - c["t_s"][0]
        return c

    p = _rewrite(lab_file, tmp_path / "1ms.csv", cut)
    out = tmp_path / "report"
    assert main(["calibrate", str(p), "--report", str(out)]) == 0
    assert "; untested: the data identify no nominal parameter" in capsys.readouterr().out
    diag = json.loads((out / "report.json").read_text())["diagnosis"]
    assert diag["identified"] == 0
    assert any(w.startswith("untested:") for w in diag["warnings"])
    # too little data is not a model defect: no "unexplained" flag, met or not
    assert not diag["unexplained"]
    assert not any(w.startswith("unexplained:") for w in diag["warnings"])
    assert ": met, but untested: the data identify no nominal parameter" in (
        out / "report.md").read_text()  # fmt: skip


@pytest.mark.parametrize(
    ("meta", "factor", "needle"),
    [
        # the lab's angles on a detector 200× weaker (S ×20, L ÷10), logged in mV and
        # written as V: the file's numbers are 5× the lab's, its detector 1000× the prior's
        ({"detector_sensitivity_m_per_V": "0.00198", "detector_distance_m": "0.0175"}, 5.0,
         "the detector moves 1e+03× (RMS"),
        # S in m/mV read as m/V: the detector moves a thousandth of the prior's
        ({"detector_sensitivity_m_per_V": "1e-7"}, 1.0, "the detector moves 0.001"),
    ],
)
def test_a_detector_off_by_a_unit_is_refused_before_fitting(
    meta, factor, needle, lab_file, tmp_path, capsys
):
    """A detector whose motion is 100× the prior model's or a hundredth of it (RMS and
    range both) is refused at once, naming the file and the likely unit; the three
    independent plants' traces read 0.44–3.5× (experiments/detector_scale.py)."""

    def scaled(c):
        c["detector_V"] = c["detector_V"] * factor
        c["detector_y_V"] = c["detector_y_V"] * factor
        return c

    p = _rewrite(lab_file, tmp_path / "unit.csv", scaled)
    text = p.read_text()
    for k, v in meta.items():
        old = next(ln for ln in text.splitlines() if ln.startswith(f"# {k}:"))
        text = text.replace(old, f"# {k}: {v}")
    p.write_text(text)
    out = tmp_path / "report"
    rc = main(["calibrate", str(p), "--report", str(out)])
    _one_line_exit_2(capsys, rc, str(p), needle, "detector_mV")
    assert not out.exists()


@pytest.mark.parametrize(  # a trigger delay, a clock's reading (slow: the default tier's CPU)
    "offset", [pytest.param(0.05, marks=pytest.mark.slow), 10.0]
)
def test_time_from_any_start_is_read_from_the_first_sample(offset, lab_file, tmp_path):
    """A record whose time starts at a trigger delay (50 ms) or a clock's reading (10 s)
    is read as one from 0: the same segments, shifted, and the same signature features to
    within their noise (stop 90: the segments were in the file's time and the features'
    windows in time from the first sample, so every window missed and the calibration
    ended in a ZeroDivisionError after its fit)."""
    base = Plant("real", fidelity="reduced")
    model = NominalModel(base, tuple(TRACE_NOMINAL))

    def shifted(c):
        c["t_s"] = c["t_s"] + offset
        return c

    traces = []
    for p in (lab_file, _rewrite(lab_file, tmp_path / "late.csv", shifted)):
        td, warns = on_base(load_measurement(p), base)
        traces.append((td, warns))
    (td0, w0), (td1, w1) = traces
    assert td1.m.time[0] == 0.0
    assert any("time starts at" in w for w in w1) and not any("time starts at" in w for w in w0)
    assert [s.kind for s in td1.segments] == [s.kind for s in td0.segments]
    np.testing.assert_allclose([s.start for s in td1.segments],
                               [s.start for s in td0.segments], atol=1e-9)  # fmt: skip
    x0 = np.zeros(len(model))
    feats = []
    for td in (td0, td1):
        search = signature_search(TraceProblem([td], model))
        search.find_lines(x0, {})
        feats.append(search.data)
    assert feats[0].names == feats[1].names
    # to within their noise: t + offset − offset differs from t in the last bits, and a
    # window's end that falls on a sample may take or leave it
    assert np.all(np.abs(feats[1].value - feats[0].value) <= 0.5 * feats[0].noise)

# --- 7. Ctrl-C stops a compiled run -------------------------------------------------------
def _as_a_shell_would() -> None:
    """The child's SIGINT as a terminal's shell starts a command: delivered, default action.
    A process inherits its parent's signal mask and ignored signals; after other tests the
    pytest process may carry either (the default tier once timed out here, alone it passed)."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow  # the default tier's 5 CPU minutes (stop 48): the 3-D model, 11 s
def test_ctrl_c_stops_a_long_3d_run(tmp_path):
    """A 3-D run of 5000 periods (about two and a half minutes) interrupted after it
    started: it exits 130 and says so, long before the run would have ended. A one-period
    run first compiles the 3-D kernels into numba's cache (with an empty cache the long run
    would still be compiling when the signal arrives, and a compilation is not
    interruptible). The exit may take up to a minute on a loaded machine (the default tier
    beside another job once needed more than 15 s); a run that ignored the signal would
    still be running then, or exit 0."""
    cmd = [sys.executable, "-m", "turntable_env.cli", "simulate", "--model", "full"]
    subprocess.run([*cmd, "--periods", "1", "--output-dt", "1e-3"], check=True,
                   capture_output=True, timeout=600)  # fmt: skip
    p = subprocess.Popen(
        [sys.executable, "-m", "turntable_env.cli", "simulate", "--model", "full",
         "--periods", "5000", "--output-dt", "1e-3"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_as_a_shell_would,
    )  # fmt: skip
    time.sleep(8.0)  # imports and the model's build; the kernel is running by now
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 130, err[-2000:]
    assert "interrupted" in err and out == ""


# --- 8. the agent env and the vector env check their actions and their order --------------
@pytest.mark.parametrize(
    "action", [np.zeros(5), [np.inf, 0, 0], [1j, 0, 0], [np.nan, 0, 0], 0.5, None, "abc"]
)
def test_agent_env_refuses_bad_actions(action):
    import agents  # noqa: F401  (registers PiezoTurntableAgent-v0)

    env = gym.make("PiezoTurntableAgent-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(action)


def test_step_before_reset_is_refused():
    from gymnasium.error import ResetNeeded

    import agents  # noqa: F401
    from agents.interface import AgentWrapper
    from turntable_env.envs import PiezoTurntableVectorEnv

    with pytest.raises(ResetNeeded):
        AgentWrapper(gym.make("PiezoTurntable-v0").unwrapped).step(np.zeros(3))
    venv = PiezoTurntableVectorEnv(num_envs=2)
    with pytest.raises(ResetNeeded):
        venv.step(np.zeros((2, 5)))
    with pytest.raises(ResetNeeded):  # the base env too: not a terminated dummy step
        gym.make("PiezoTurntable-v0").unwrapped.step(np.zeros(5))


def test_a_refused_reset_leaves_the_episode_as_it_was():
    """reset() with an option it refuses (a NaN target) changes nothing: not the plant
    drawn for the episode, not its step count, not the state; the episode goes on."""
    env = gym.make("PiezoTurntableRandomized-v0").unwrapped
    env.reset(seed=3)
    for _ in range(3):
        env.step(np.array([0.5, 0.3, 0.9, 0.5, 0.0]))
    t = env.task
    before = (dict(t.draws[0]), env.plant, int(t.step_index[0]), float(t.angle[0]),
              float(t.target[0]), env.np_random.bit_generator.state)  # fmt: skip
    with pytest.raises(ValueError, match="target_angle"):
        env.reset(options={"target_angle": float("nan")})
    after = (dict(t.draws[0]), env.plant, int(t.step_index[0]), float(t.angle[0]),
             float(t.target[0]), env.np_random.bit_generator.state)  # fmt: skip
    assert after == before  # the generator too: no plant drawn and thrown away


# --- 9. smaller -----------------------------------------------------------------------------
def test_the_same_file_twice_is_refused(lab_file, tmp_path, capsys):
    rc = main(["calibrate", str(lab_file), str(lab_file), "--report", str(tmp_path / "r")])
    _one_line_exit_2(capsys, rc, "twice")


def test_messages_show_plain_numbers():
    from turntable_env.validation import check_positive

    with pytest.raises(ValueError) as e:
        check_positive("x", np.float64(-0.00495))
    assert "np.float64" not in str(e.value) and "-0.00495" in str(e.value)


@pytest.mark.parametrize("model", ["full", "reduced"])
def test_simulate_refuses_an_output_interval_that_would_exhaust_memory(model):
    """The Python API bounds the recorded samples as the CLI does (a 1 ms run at 1 fs
    asked numpy for 7.28 TiB): a ValueError naming output_dt, before any allocation."""
    from turntable_env.drive import Waveform
    from turntable_env.simulation import simulate, simulate_axes

    w = Waveform(np.array([0.0, 1e-3]), np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match="output_dt=1e-15"):
        if model == "full":
            simulate("real", {"B": w}, duration=1e-3, output_dt=1e-15)
        else:
            simulate_axes(["real"], [w], duration=1e-3, output_dt=1e-15)


# --- 10. every config checked at make, naming the field: never a TypeError at make or a
# --- failure (or a silent NaN) at the first step -------------------------------------------
_NAN, _INF = float("nan"), float("inf")


@pytest.mark.parametrize(
    ("interface", "needle"),
    [
        ({"bogus": 1}, "unknown key 'bogus'"),
        ([1, 2], r"interface=\[1, 2\]: must be a mapping"),
        ("raw", "interface='raw'"),
        ({"max_steps": _INF}, "max_steps=inf"),
        ({"max_steps": _NAN}, "max_steps=nan"),
        ({"max_steps": 2.5}, "max_steps=2.5"),
        ({"max_steps": 10**400}, "max_steps"),
        ({"deadzone": "0.2"}, "deadzone='0.2'"),
        ({"amplitude_max": 100.0}, "amplitude_max=100.0"),  # above the amplifier's 10 V input
        ({"amplitude_max": _INF}, "amplitude_max=inf"),
        ({"amplitude_min": _NAN}, "amplitude_min=nan"),
        ({"offset_step": _NAN}, "offset_step=nan"),
        ({"offset_step": _INF}, "offset_step=inf"),
        ({"offset_step": 25.0}, "offset_step=25.0"),  # beyond a full ±10 V swing
        ({"ramp_ratio": _NAN}, "ramp_ratio=nan"),
        ({"ramp_ratio": 2}, "ramp_ratio=2"),
        ({"ramp_ratio": -1}, "ramp_ratio=-1"),
        ({"ramp_ratio": 0.4}, "ramp_ratio=0.4"),  # below the action range's 0.5
        ({"slew_adaptation": _INF}, "slew_adaptation=inf"),
        ({"slew_adaptation": _NAN}, "slew_adaptation=nan"),  # was taken as 0, silently
        ({"slew_adaptation": -5}, "slew_adaptation=-5"),  # likewise
        ({"slew_adaptation": 1.5}, "slew_adaptation=1.5"),
        ({"base": ["fuzzy"]}, "base"),
    ],
)
def test_agent_env_refuses_a_bad_interface_at_make(interface, needle):
    import agents  # noqa: F401  (registers PiezoTurntableAgent-v0)

    with pytest.raises(ValueError, match=needle):
        gym.make("PiezoTurntableAgent-v0", interface=interface)


@pytest.mark.parametrize(
    "interface",
    [
        {"amplitude_max": 10.0, "max_steps": 20.0},  # an integral float, as YAML may give it
        {"ramp_ratio": 0.5, "slew_adaptation": 0.0, "offset_step": 20.0},
        {"ramp_ratio": 0.99, "slew_adaptation": 1.0, "amplitude_min": 10.0},
    ],
)
def test_agent_env_takes_the_interface_ranges_ends_and_steps_finitely(interface):
    import agents  # noqa: F401

    env = gym.make("PiezoTurntableAgent-v0", interface=interface)
    env.reset(seed=0)
    for a in ([1.0, 1.0, 1.0], [-1.0, -1.0, -1.0], [0.5, 0.0, 0.0]):
        obs, r, *_ = env.step(np.array(a, dtype=np.float32))
        assert math.isfinite(r) and np.isfinite(obs).all()


def test_the_largest_reward_weights_keep_the_reward_finite():
    env = gym.make("PiezoTurntable-v0", energy_weight=1e6, success_bonus=1e6, tolerance=5e-4,
                   terminate_on_success=False)  # fmt: skip
    env.reset(seed=0, options={"start_angle": 0.0, "target_angle": 0.0})  # the bonus at once
    for _ in range(3):  # full amplitude at 2 kHz: the most energy an interval takes
        _, r, *_ = env.step(np.array([1.0, 1.0, 1.0, 1.0, 0.0]))
        assert math.isfinite(r)


def test_retarget_legs_up_to_the_reference_length_reset():
    env = gym.make("PiezoTurntable-v0", retarget_legs=(1, 1000), retarget_share=1.0)
    env.reset(seed=0)


@pytest.mark.parametrize("num_envs", [10**6, MAX_NUM_ENVS + 1])
def test_num_envs_is_bounded_before_anything_is_allocated(num_envs):
    tracemalloc.start()  # numpy reports its buffers to tracemalloc
    try:
        with pytest.raises(ValueError, match=f"num_envs={num_envs}: must be <= {MAX_NUM_ENVS}"):
            gym.make_vec(
                "PiezoTurntable-v0", num_envs=num_envs, vectorization_mode="vector_entry_point"
            )
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 64 * 2**20  # refused, not built: 62 kB a turntable, 0.5 GB at the bound


def _agent_run(tmp_path: Path, text: str | bytes) -> Path:
    """A copy of the shipped PPO agent's run directory with ``text`` as its config.yml."""
    d = tmp_path / "run"
    d.mkdir()
    for name in ("model.zip", "vecnormalize.pkl"):
        (d / name).write_bytes((ROOT / "agents/pretrained/ppo" / name).read_bytes())
    cfg = d / "config.yml"
    cfg.write_bytes(text) if isinstance(text, bytes) else cfg.write_text(text, encoding="utf-8")
    return d


def _shipped_ppo_config() -> str:
    return (ROOT / "agents/pretrained/ppo/config.yml").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda t: "junk: [\n", "not valid YAML"),
        (lambda t: "[1, 2]\n", "not a list"),
        (lambda t: "", "not empty"),
        (lambda t: b"\xff\xfe\x00junk", "not UTF-8"),
        (lambda t: t.replace("run:\n", "runs:\n"), "no 'run' mapping"),
        (lambda t: t.replace("PiezoTurntable-v0:", "Bogus-v0:"), "no 'PiezoTurntable-v0' entry"),
        (lambda t: t.replace("algo: ppo", "algo: a2c"), "run.algo='a2c'"),
        (lambda t: t.replace("  seed: 0\n", "  seed: 0\n  env_id: Bogus-v0\n"), "run.env_id"),
        (lambda t: t.replace("max_steps: 20", "max_steps: .nan"), "max_steps=nan"),
        (lambda t: t.replace("max_steps: 20", "maxsteps: 20"), "unknown key 'maxsteps'"),
        (lambda t: t.replace("  interface:\n", "  interface: [1]\n  x:\n"), "interface=[1]:"),
        (lambda t: t.replace("n_envs: 16", "n_envs: 16\n  frame_stack: 0"), "frame_stack=0"),
    ],
)
def test_a_bad_agent_run_config_is_refused_before_the_benchmark(change, needle, tmp_path, capsys):
    """``turntable benchmark --agent NAME=DIR``: a config.yml that does not parse, is not a
    mapping, or lacks (or spoils) what the agent is built from is refused when the run is
    read, exit 2 with one line naming the file: not a traceback, not a KeyError in the
    benchmark's first seconds."""
    d = _agent_run(tmp_path, change(_shipped_ppo_config()))
    t0 = time.perf_counter()
    rc = main(["benchmark", "--agent", f"bad_run={d}", "--quick", "--out", str(tmp_path / "o")])
    _one_line_exit_2(capsys, rc, "config.yml", needle)
    assert time.perf_counter() - t0 < 30.0  # refused when read, not once the benchmark ran
    assert not (tmp_path / "o").exists()


def test_every_shipped_run_config_passes_the_check():
    from agents import pretrained
    from agents.controller import check_run_config, interface_of
    from agents.train import run_config

    runs = pretrained()
    assert {"ppo", "sac", "ppo_residual"} <= set(runs)
    for d in runs.values():
        cfg = run_config(d, str(d))
        check_run_config(cfg)
        interface_of(cfg)


@pytest.mark.parametrize("duration", [1e-9, 0.0099, 60.5, float("nan")])
def test_a_bench_shorter_than_one_drive_period_is_refused(duration):
    """``run_bench`` counts steps per drive period and ns per step evaluation: a run shorter
    than one period of the standard scenario's drive has none (stop 109's probe: a
    ZeroDivisionError traceback from ``turntable bench --duration 1e-300``), so the duration
    is refused, naming it, before anything is simulated."""
    from turntable_env.bench import DURATION_RANGE, STANDARD, run_bench

    assert DURATION_RANGE[0] == pytest.approx(1.0 / STANDARD["frequency"])
    with pytest.raises(ValueError, match="duration"):
        run_bench(duration=duration, quick=True)
