"""Output files that are complete or absent: atomic writes and report directories.

:func:`write_atomic` writes through a temporary file in the target's directory and renames
it into place (``os.replace``), so a reader never sees half a file and a failure leaves the
old file as it was. :func:`output_directory` builds a directory's files in a temporary
sibling and moves them in only when everything was written, so a report directory is
either complete or untouched. :func:`check_writable` refuses, before any work starts, an
output path whose directory does not exist or cannot be written, or that names a
directory (ValueError naming the option and the path).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["check_writable", "output_directory", "write_atomic"]


def check_writable(name: str, path: str | Path, *, directory: bool = False) -> Path:
    """``path`` as a Path if a file (``directory=False``) or a directory can be written
    there; ValueError naming ``name`` otherwise."""
    p = Path(path)
    if not str(path).strip():
        raise ValueError(f"{name}={str(path)!r}: empty path")
    if directory:
        if p.exists() and not p.is_dir():
            raise ValueError(f"{name}={str(p)!r}: exists and is not a directory")
        parent = p if p.is_dir() else _existing_ancestor(name, p)
    else:
        if p.is_dir():
            raise ValueError(f"{name}={str(p)!r}: is a directory, not a file")
        parent = p.parent
        if not parent.is_dir():
            raise ValueError(f"{name}={str(p)!r}: directory {str(parent)!r} does not exist")
    try:  # a real probe: permissions, read-only file systems and /proc alike
        fd, probe = tempfile.mkstemp(dir=parent, prefix=".probe.")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ValueError(
            f"{name}={str(p)!r}: {str(parent)!r} is not writable ({exc.strerror})"
        ) from None
    return p


def _existing_ancestor(name: str, p: Path) -> Path:
    for q in p.absolute().parents:
        if q.exists():
            if not q.is_dir():
                raise ValueError(f"{name}={str(p)!r}: {str(q)!r} is not a directory")
            return q
    return Path("/")


def write_atomic(path: str | Path, content: str | bytes) -> Path:
    """Write ``content`` (text as UTF-8) to ``path`` through a temporary file renamed into
    place; ValueError if the directory cannot be written."""
    p = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
    except OSError as exc:
        raise ValueError(f"{p}: cannot be written ({exc.strerror})") from None
    try:
        data = content.encode("utf-8") if isinstance(content, str) else content
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's 0600 → what open() would have given
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def output_directory(out: str | Path) -> Iterator[Path]:
    """Yield a temporary directory beside ``out`` to write into; on success its files move
    into ``out`` (created if needed), on any exception it is removed and ``out`` is left
    as it was."""
    d = check_writable("out", out, directory=True)
    d.parent.mkdir(parents=True, exist_ok=True)
    try:
        tmp = Path(tempfile.mkdtemp(dir=d.parent, prefix=f".{d.name}.", suffix=".tmp"))
    except OSError as exc:
        raise ValueError(f"{d}: cannot be written ({exc.strerror})") from None
    try:
        yield tmp
        d.mkdir(exist_ok=True)
        for f in sorted(tmp.rglob("*")):
            if f.is_file():
                dest = d / f.relative_to(tmp)
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(f, dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
