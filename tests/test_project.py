"""Project contract: README set-up commands and CI agree."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    m = re.search(r"```bash\n(.*?)```", text, re.S)
    assert m is not None, "README must open with a bash block"
    assert text.index("```bash") < text.index("\n## "), "the set-up block must come first"
    return [line for line in m.group(1).splitlines() if line.strip()]


def test_readme_opens_with_two_setup_commands():
    cmds = _readme_commands()
    assert len(cmds) == 2
    for c in cmds:
        assert c.startswith("pip install torch==2.13.0 && ")  # CPU torch first, always
    assert "pytest" in cmds[1] and "pytest" not in cmds[0]


def test_readme_welcomes_before_the_commands_and_stays_short():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    intro = text[: text.index("```bash")]
    prose = [p for p in intro.split("\n\n") if p.strip() and not p.startswith("#")]
    assert prose and len(prose[0].split()) >= 60  # what it is and whom it serves, first
    assert len(text.splitlines()) <= 250
    assert "Schepers" in text and "University of Twente" in text  # the thesis cited


def test_project_files_and_docs_site_are_present():
    import yaml

    for name in ("LICENSE", "CITATION.cff", "CHANGELOG.md", "mkdocs.yml"):
        assert (ROOT / name).is_file(), name
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["references"][0]["authors"][0]["family-names"] == "Schepers"
    assert "## [Unreleased]" in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))["nav"]
    for entry in nav:
        (page,) = entry.values()
        assert (ROOT / "docs" / page).is_file(), page


@pytest.mark.slow  # .ci/run builds the site strictly too; 3 s of the default tier's CPU
def test_docs_site_builds_strict(tmp_path):
    """`mkdocs build --strict` (as .ci/run): every page, API reference and link resolves."""
    import os
    import shutil
    import subprocess

    if shutil.which("mkdocs") is None:
        import pytest

        pytest.skip("mkdocs not installed (the docs extra)")
    r = subprocess.run(["mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, timeout=600,
                       env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "site" / "api" / "index.html").is_file()


def test_ci_runs_the_readme_test_command_verbatim():
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert _readme_commands()[1] in ci


def test_torch_pin_admits_no_newer_release():
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    for spec in re.findall(r'"torch([^"]*)"', pyproject):
        assert spec == "==2.13.0", spec
