"""The command line's boundary (issue 23): every subcommand given a bad value or an
unwritable place exits 2 with one line on stderr naming the option, before any work, and
leaves no file behind."""

from __future__ import annotations

import subprocess
import sys

import pytest

from turntable_env import __version__
from turntable_env.cli import main
from turntable_env.files import MARKER

NOT_A_DIR = "/etc/hostname/x"  # below a regular file: unwritable, root or not


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's own exits
        code = int(e.code)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["simulate", "--amplitude", "nan"], "--amplitude"),
        (["simulate", "--amplitude", "11"], "--amplitude"),
        (["simulate", "--amplitude", "-11"], "--amplitude"),
        (["simulate", "--amplitude", "0"], "--amplitude"),
        (["simulate", "--frequency", "1e9"], "--frequency"),
        (["simulate", "--periods", "1e9"], "--periods"),
        (["simulate", "--periods", "0"], "--periods"),
        (["simulate", "--a", "0"], "--a"),
        (["simulate", "--a", "1"], "--a"),  # no flyback: the breakpoints would coincide
        (["simulate", "--a", "5e-324"], "--a"),
        (["simulate", "--amplitude", "5e-324"], "--amplitude"),  # 0/0 in the figures: NaN
        (["simulate", "--amplitude", "1e-4"], "--amplitude"),
        (["simulate", "--periods", "1", "--output-dt", "0.5"], "--output-dt"),  # before the run
        (["bench", "--env-only", "--duration", "5"], "--duration"),  # not silently ignored
        (["bench", "--env-only", "--quick"], "--quick"),
        (["benchmark", "--backend", "ray", "--workers", "2"], "--workers"),
        (["calibrate", "--thesis", "--base", "thesis", "--report", "rep"], "--base"),
        (["calibrate", "--thesis", "--global-points", "5", "--report", "rep"], "--global-points"),
        (["simulate", "--settle", "1e9"], "--settle"),
        (["simulate", "--output-dt", "0"], "--output-dt"),
        (["simulate", "--output-dt", "1e-15"], "--output-dt"),
        (["simulate", "--periods", "1", "--dt-factor", "1e-12"], "--dt-factor"),  # 4e15 steps
        (["simulate", "--cycles", "2"], "--cycles"),  # not silently ignored without --signal two
        (["simulate", "--frequency", "0.001", "--periods", "100000"], "--periods"),
        (["simulate", "--out", "/nonexistent/x.csv"], "--out"),
        (["simulate", "--out", "/tmp"], "--out"),
        (["simulate", "--out", NOT_A_DIR], "--out"),
        (["bench", "--duration", "nan"], "--duration"),
        (["bench", "--duration", "1e-9", "--quick"], "--duration"),  # no drive period to count
        (["bench", "--batch", "-1"], "--batch"),
        (["benchmark", "--seeds", "1"], "--seeds"),
        (["benchmark", "--suite-seed", "-1"], "--suite-seed"),
        (["benchmark", "--controllers", "nope", "--quick"], "controllers"),
        (["benchmark", "--plant-sets", "lunar"], "plant_sets"),
        (["benchmark", "--controllers", ""], "--controllers"),  # not "all of them"
        (["benchmark", "--controllers", "fuzzy,fuzzy"], "--controllers"),
        (["benchmark", "--tasks", ","], "--tasks"),
        (["benchmark", "--out", NOT_A_DIR], "--out"),
        (["benchmark", "--workers", "2"], "--workers"),
        (["benchmark", "--backend", "slurm"], "--backend"),
        (["virtual-lab", "--noise", "nan", "--out", "v.csv"], "--noise"),
        (["virtual-lab", "--noise", "-1", "--out", "v.csv"], "--noise"),
        (["virtual-lab", "--effects", "piezo_creep=5", "--out", "v.csv"], "piezo_creep"),
        (["virtual-lab", "--effects", "piezo_creep=0.02,piezo_creep=0.03", "--out", "v.csv"],
         "piezo_creep"),  # not the last one silently
        (["virtual-lab", "--effects", "piezo_creep.gamma=0.02,piezo_creep=0.03", "--out", "v.csv"],
         "twice"),
        (["virtual-lab", "--effects", ",", "--out", "v.csv"], "--effects"),
        (["virtual-lab", "--out", NOT_A_DIR], "--out"),
        (["virtual-lab", "--out", "/tmp"], "--out"),
        (["calibrate", "--thesis", "--report", NOT_A_DIR], "--report"),
        (["calibrate", "missing.csv", "--report", "rep"], "missing.csv"),
        (["calibrate", "", "--report", "rep"], "an empty path"),  # not "." (stop 109's probe)
        # a control character in a name is written escaped: still one line
        (["calibrate", "miss\ning.csv", "--report", "rep"], "miss\\ning.csv"),
        (["simulate", "--amplitude", "1\n2"], "--amplitude"),
        (["calibrate", "--thesis", "--report", "/etc/hostname/\x1b[2J"], "\\x1b[2J"),
        (["calibrate", "--global-points", "0", "--thesis"], "--global-points"),
        (["report", "--out", NOT_A_DIR], "--out"),
        (["params", "--set", "lunar"], "--set"),
        # numbers as a file's cells take them: plain ASCII decimals (stop 72's audit: these
        # ran, 1_0 as ten workers or 10 V)
        (["calibrate", "--thesis", "--workers", "1_0", "--report", "rep"], "--workers"),
        (["calibrate", "--thesis", "--workers", "\uff11", "--report", "rep"], "--workers"),
        (["simulate", "--amplitude", "1_0"], "--amplitude"),
        (["simulate", "--amplitude", "\u0665"], "--amplitude"),  # an Arabic-Indic five
        (["virtual-lab", "--effects", "piezo_creep=0_0", "--out", "v.csv"], "piezo_creep"),
        (["virtual-lab", "--effects", "piezo_creep.=0.02", "--out", "v.csv"], "after the dot"),
        (["calibrate", "--thesis", "lab.csv", "--report", "rep"], "--thesis"),  # stop 74
        # a lab's earlier calibration as the prior (stop 108): read before any work
        (["calibrate", "lab.csv", "--base", "earlier.toml", "--report", "rep"], "--base"),
        (["calibrate", "lab.csv", "--base", "earlier/", "--report", "rep"], "earlier"),
    ],
)
def test_bad_values_exit_2_with_one_line_naming_the_option(argv, names, capsys, tmp_path,
                                                            monkeypatch):  # fmt: skip
    monkeypatch.chdir(tmp_path)
    code, _out, err = _run(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert names in lines[0], lines[0]
    assert not any(tmp_path.iterdir())  # nothing written


def test_version_and_help_render(capsys):
    code, out, _ = _run(["--version"], capsys)
    assert code == 0 and out.strip() == f"turntable {__version__}"
    code, out, _ = _run(["benchmark", "--help"], capsys)
    assert code == 0 and "%%" not in out and "±30 %" in out


def test_a_closed_pipe_is_not_an_error():
    """`turntable params --json | head -1`: the reader has gone before the output is
    written (its end of the pipe closed at once); exit 0, nothing on stderr. A plain
    print to the closed pipe raises BrokenPipeError with a traceback (checked alongside)."""
    def run(argv: list[str]) -> tuple[int, str]:
        p = subprocess.Popen([sys.executable, *argv], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE)  # fmt: skip
        p.stdout.close()
        err = p.stderr.read().decode()
        return p.wait(timeout=120), err

    code, err = run(["-m", "turntable_env.cli", "params", "--json"])
    assert code == 0 and err == "", err
    plain = "import json\nprint(json.dumps(list(range(100))))"
    code, err = run(["-c", plain])
    assert code != 0 and "BrokenPipeError" in err  # the harness does reach a closed pipe


def test_a_failing_report_leaves_the_directory_untouched(tmp_path, monkeypatch):
    """A plot that fails halfway: the old report stays, no half-new one beside it."""
    from turntable_env.calibration import calibrate as cal

    out = tmp_path / "rep"
    out.mkdir()
    (out / MARKER).write_text("")  # an earlier report of this project
    (out / "report.json").write_text("old")

    def boom(*_a, **_k):
        raise RuntimeError("plot failed")

    monkeypatch.setattr(cal, "plot_overlay", boom)

    class R:  # the parts of a result the writer reads before the overlay
        def to_json(self):
            return {"new": True}

    monkeypatch.setattr(cal, "plot_residual", lambda *_a, **_k: None)
    with pytest.raises(RuntimeError, match="plot failed"):
        cal.write_report(R(), out)
    assert sorted(p.name for p in out.iterdir()) == sorted([MARKER, "report.json"])
    assert (out / "report.json").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["rep"]  # no temporary left


@pytest.mark.parametrize(
    ("argv", "inside"),
    [
        (["calibrate", "rep/data.csv", "--report", "rep"], "rep/data.csv"),
        (["calibrate", "rep/sub/data.csv", "--report", "rep"], "rep/sub/data.csv"),
        (["calibrate", "rep/data.csv", "--report", "./rep/"], "rep/data.csv"),
        (["benchmark", "--agent", "mine=rep/run", "--out", "rep"], "rep/run"),
    ],
)
def test_an_output_that_holds_an_input_is_refused_and_the_input_kept(
    argv, inside, capsys, tmp_path, monkeypatch
):
    """An earlier report directory is replaced whole: a run that reads a file inside it
    (the measurement copied into its own report, an agent's run saved under the
    benchmark's --out) would delete its own input. Refused, exit 2, one line naming the
    option and the input, and the input still there (stop 72's hostile-input audit:
    `calibrate rep/data.csv --report rep` exited 0 with the file gone)."""
    monkeypatch.chdir(tmp_path)
    rep = tmp_path / "rep"
    (rep / "sub").mkdir(parents=True)
    (rep / MARKER).write_text("")  # an earlier output of this project
    src = tmp_path / inside
    if src.suffix:
        src.write_text("t_s,drive_B_V,detector_V\n")
    else:
        src.mkdir()
    code, _out, err = _run(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert argv[-2] in lines[0] and inside in lines[0], lines[0]
    assert src.exists()
