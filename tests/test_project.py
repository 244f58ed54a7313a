"""Project contract: README set-up commands and CI agree."""

import re
from pathlib import Path

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


def test_ci_runs_the_readme_test_command_verbatim():
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert _readme_commands()[1] in ci


def test_torch_pin_admits_no_newer_release():
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    for spec in re.findall(r'"torch([^"]*)"', pyproject):
        assert spec == "==2.13.0", spec
