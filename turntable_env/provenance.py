"""Which code and machine produced a result: a report's provenance.

A calibration's figures depend on the calibrator's commit (an integrator rule, a screen's
grid) and, through the fits' basins, on the machine's floating point (processor, BLAS,
library versions). The independent tables mix rows run at different commits, so each row
says where it ran.

:func:`code_version` reads the package's own checkout: its commit and whether tracked files
differ from it (``git``; None for both outside a git checkout, an installed wheel, or
without ``git``). :func:`machine` lists the processor, Python and the numerical libraries
with their BLAS (threadpoolctl). :func:`provenance` is both, as ``report.json`` holds it.
"""

from __future__ import annotations

import platform
import subprocess
from pathlib import Path
from typing import Any

__all__ = ["code_label", "code_version", "machine", "provenance"]

PACKAGE_ROOT = Path(__file__).resolve().parent.parent  # the checkout holding turntable_env
GIT_TIMEOUT_S = 10.0


def _git(root: Path, *args: str) -> str | None:
    """``git -C root args`` stdout, stripped; None where git is missing or fails."""
    try:
        r = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                           timeout=GIT_TIMEOUT_S, check=False)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return r.stdout.strip() if r.returncode == 0 else None


def code_version(root: str | Path | None = None) -> dict[str, Any]:
    """The package version and the checkout ``root`` (default: the one this package is
    imported from) as ``{"package", "commit", "modified"}``: the commit's full hash and
    whether tracked files differ from it, both None where ``root`` is not the top of a git
    checkout (an installed wheel: a repository further up is not this package's)."""
    from . import __version__

    top = Path(root) if root is not None else PACKAGE_ROOT
    commit = modified = None
    if (top / ".git").exists():  # a directory, or a file in a worktree
        commit = _git(top, "rev-parse", "HEAD")
        status = _git(top, "status", "--porcelain", "--untracked-files=no")
        if commit is not None and status is not None:
            modified = bool(status)
        else:
            commit = None
    return {"package": __version__, "commit": commit, "modified": modified}


def code_label(code: dict[str, Any] | None) -> str:
    """A commit as tables print it: seven hex digits, ``+`` where tracked files differed
    from it, ``—`` where it is not known."""
    if not code or not code.get("commit"):
        return "—"
    return code["commit"][:7] + ("+" if code.get("modified") else "")


def machine() -> dict[str, Any]:
    """The processor, Python, numpy, scipy and numba versions and the BLAS libraries in use
    (threadpoolctl: internal API, version, architecture)."""
    import numba
    import numpy as np
    import scipy
    from threadpoolctl import threadpool_info

    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    blas = [{k: i.get(k) for k in ("internal_api", "version", "architecture")}
            for i in threadpool_info()]  # fmt: skip
    return {"cpu": cpu, "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "numba": numba.__version__, "blas": blas}  # fmt: skip


def provenance() -> dict[str, Any]:
    """``{"code": code_version(), "machine": machine()}``."""
    return {"code": code_version(), "machine": machine()}
