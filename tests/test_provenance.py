"""Where a result ran (turntable_env.provenance): the checkout's commit and whether tracked
files differed from it, read by git on a repository built here, and carried into a
calibration report and the independent tables' rows."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import experiment

from turntable_env.provenance import code_label, code_version, machine

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="needs git")


def _git(root: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                          check=True).stdout.strip()  # fmt: skip


@pytest.fixture
def repo(tmp_path):
    root = tmp_path / "checkout"
    root.mkdir()
    _git(root, "init", "-q")
    (root / "kernel.py").write_text("A = 1\n")
    _git(root, "add", "kernel.py")
    _git(root, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "one")
    return root


def test_a_clean_checkout_gives_its_commit_unmodified(repo):
    code = code_version(repo)
    assert code["commit"] == _git(repo, "rev-parse", "HEAD") and code["modified"] is False
    assert code_label(code) == code["commit"][:7]


@pytest.mark.parametrize(
    ("change", "modified"),
    [("edit", True), ("untracked", False)],
)
def test_only_a_change_to_a_tracked_file_marks_the_commit(repo, change, modified):
    """An edited kernel is not the commit's code; a stray output file beside it is."""
    if change == "edit":
        (repo / "kernel.py").write_text("A = 2\n")
    else:
        (repo / "results.json").write_text("[]")
    code = code_version(repo)
    assert code["modified"] is modified
    assert code_label(code).endswith("+") is modified


def test_a_directory_inside_a_repository_is_not_a_checkout_of_its_own(repo):
    """An installed package sits inside some other tree (a venv in a project): the project's
    commit is not the package's, so nothing is claimed."""
    inner = repo / "venv" / "site-packages"
    inner.mkdir(parents=True)
    code = code_version(inner)
    assert code["commit"] is None and code["modified"] is None
    assert code_label(code) == code_label(None) == "—"


def test_the_package_reports_the_checkout_it_is_imported_from():
    import turntable_env

    root = Path(turntable_env.__file__).resolve().parent.parent
    if not (root / ".git").exists():
        pytest.skip("the package is not imported from a git checkout (an installed wheel)")
    assert code_version()["commit"] == _git(root, "rev-parse", "HEAD")


def test_a_report_says_where_it_ran(tmp_path):
    """report.json carries the commit and the machine; report.md a line of both."""
    from turntable_env.calibration.calibrate import write_report
    from turntable_env.calibration.result import CalibrationResult

    res = CalibrationResult(
        selected_effects=[], parameters={}, error_before=5.0, error_after=4.0,
        error_unit="nm", residual_structured=False, candidates=[], diagnosis={},
        residuals={"after": np.zeros(8)},
    )  # fmt: skip
    paths = write_report(res, tmp_path / "r")
    prov = json.loads(paths["json"].read_text())["provenance"]
    assert prov["code"] == code_version()
    assert prov["machine"]["numpy"] == np.__version__ == machine()["numpy"]
    md = (tmp_path / "r" / "report.md").read_text()
    assert f"commit {code_label(prov['code'])};" in md


def test_a_table_row_without_a_record_takes_its_reports(tmp_path, capsys):
    """Rows made before stop 85 record no commit: --rows prints their report's, or —."""
    table_reports = experiment("table_reports")
    row = {"trace": "clean", "injected": [], "expected": ["none"], "selected": [],
           "decided_by": [], "before_nm": 9.0, "nominal_nm": 3.0, "after_nm": 3.0,
           "floor_nm": 1.0, "target_nm": 4.0, "met": True, "structured": False,
           "flagged": False, "wall_s": 1.0}  # fmt: skip
    old, new = tmp_path / "old", tmp_path / "new"
    for d, trace in ((old, "clean"), (new, "creep")):
        (d / trace).mkdir(parents=True)
        (d / "results.json").write_text(json.dumps([{**row, "trace": trace}]))
    code = {"package": "0.1.0", "commit": "ab" * 20, "modified": True}
    (new / "creep" / "report.json").write_text(json.dumps({"provenance": {"code": code}}))
    assert table_reports.main([str(old), str(new), "--rows"]) == 0
    out = capsys.readouterr().out
    assert "| 1 | — |" in out and "| 1 | abababa+ |" in out
    assert "abababa+ × 1" in out and "— × 1" in out


def test_bench_json_names_the_code_and_machine_its_figures_were_measured_on(monkeypatch, capsys):
    """Speed figures are absolute only with the machine stated: `turntable bench --json`
    prints them with the provenance (the figures themselves stubbed here: bench's own
    tests time them)."""
    import turntable_env.bench
    from turntable_env.cli import main

    monkeypatch.setattr(turntable_env.bench, "run_bench",
                        lambda **kw: {"reduced_rtf": 25.0, "duration_s": kw["duration"]})
    assert main(["bench", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["reduced_rtf"] == 25.0 and doc["duration_s"] == 1.0
    assert doc["provenance"]["code"] == code_version()
    assert doc["provenance"]["machine"]["cpu"] == machine()["cpu"]
