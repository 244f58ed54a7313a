"""Output files that are complete or absent: atomic writes and report directories.

:func:`write_atomic` writes through a temporary file in the target's directory and renames
it into place (``os.replace``), so a reader never sees half a file and a failure leaves the
old file as it was. It replaces only a regular file: a symbolic link is written through
(its target, a regular file or nothing yet, is what gets replaced; the link stays), and a
device node, FIFO, socket or directory is refused.

:func:`output_directory` builds a report directory as a temporary sibling and swaps it in
whole when everything was written — an atomic exchange of the two directories
(``renameat2(RENAME_EXCHANGE)`` on Linux; two renames elsewhere), then the old one is
removed — so no file of an earlier report survives beside the new ones and a failure leaves
the old directory as it was. It replaces only a directory this project wrote (it holds
:data:`MARKER`) or an empty one: a directory of other files is refused rather than emptied,
even one with an ``index.html`` or a ``report.json`` in it (a web site, another tool's
report). SIGTERM is turned into the same clean-up as Ctrl-C
(:func:`terminate_cleanly`).

:func:`check_writable` refuses, before any work starts, an output path whose directory does
not exist or cannot be written, that names something other than what will be written, or
that is or holds a file the run reads (a report directory replaced whole would delete the
measurement copied into it) (ValueError naming the option and the path).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import shutil
import signal
import stat
import sys
import tempfile
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Literal

__all__ = [
    "MARKER",
    "Terminated",
    "check_writable",
    "output_directory",
    "plain_json",
    "terminate_cleanly",
    "write_atomic",
    "write_target",
]

MARKER = ".turntable-output"  # written into every output directory: "ours to replace"


def plain_json(x: Any, nonfinite: Literal["null", "string"] = "null") -> Any:
    """``x`` in plain JSON types: mappings with string keys, lists for tuples and arrays,
    Python numbers for NumPy scalars; NaN and infinities as null or as their string."""
    import math

    import numpy as np

    if isinstance(x, dict):
        return {str(k): plain_json(v, nonfinite) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [plain_json(v, nonfinite) for v in x]
    if isinstance(x, np.ndarray):
        return plain_json(x.tolist(), nonfinite)
    if isinstance(x, np.generic):
        return plain_json(x.item(), nonfinite)
    if isinstance(x, float) and not math.isfinite(x):
        return None if nonfinite == "null" else str(x)
    return x


def write_target(name: str, path: str | Path) -> Path:
    """The file an output path will replace: the path itself, or the final target of a
    symbolic link. ValueError naming ``name`` when that is an existing non-regular file
    (a device, FIFO, socket or directory) or the path is empty."""
    if not str(path).strip():
        raise ValueError(f"{name}={str(path)!r}: empty path")
    p = Path(path)
    target = Path(os.path.realpath(p)) if p.is_symlink() else p
    try:
        st = os.stat(target)
    except FileNotFoundError:
        return target
    except OSError as exc:
        raise ValueError(f"{name}={str(p)!r}: {exc.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{name}={str(p)!r}: is a directory, not a file")
    if not stat.S_ISREG(st.st_mode):
        what = "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else (
            "a FIFO" if stat.S_ISFIFO(st.st_mode) else "not a regular file"
        )  # fmt: skip
        via = f" (through the link to {str(target)!r})" if target != p else ""
        raise ValueError(f"{name}={str(p)!r}: {what}{via}; give a regular file")
    return target


def check_writable(
    name: str, path: str | Path, *, directory: bool = False, reads: Sequence[str | Path] = ()
) -> Path:
    """``path`` as a Path if a file (``directory=False``) or a directory can be written
    there; ValueError naming ``name`` otherwise (module docstring). ``reads``: the files
    and directories the run reads; an output directory that holds one of them (or an
    output file that is one) is refused, since it is replaced whole."""
    if not str(path).strip():
        raise ValueError(f"{name}={str(path)!r}: empty path")
    p = Path(path)
    out = Path(os.path.realpath(p))
    for r in reads:
        src = Path(os.path.realpath(r))
        if src == out or (directory and out in src.parents):
            raise ValueError(
                f"{name}={str(p)!r}: {'holds' if src != out else 'is'} {str(r)!r}, which this "
                f"run reads; the output is replaced whole: give another {name}"
            )
    if directory:
        if p.is_symlink():  # replaced whole, the link would go and its target stay
            raise ValueError(f"{name}={str(p)!r}: a symbolic link (to "
                             f"{os.readlink(p)!r}): give the directory itself")  # fmt: skip
        if p.exists() and not p.is_dir():
            raise ValueError(f"{name}={str(p)!r}: exists and is not a directory")
        if p.is_dir():
            _check_replaceable(name, p)
        parent = p if p.is_dir() else _existing_ancestor(name, p)
    else:
        target = write_target(name, p)
        parent = target.parent
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


def _check_replaceable(name: str, d: Path) -> None:
    """A directory :func:`output_directory` may replace: empty, or written by this project."""
    try:
        entries = [e.name for e in os.scandir(d)]
    except OSError as exc:
        raise ValueError(f"{name}={str(d)!r}: cannot be read ({exc.strerror})") from None
    if entries and MARKER not in entries:  # a file name alone (index.html) proves nothing
        raise ValueError(
            f"{name}={str(d)!r}: holds {len(entries)} entries and no {MARKER}: not an earlier "
            "output of this project; give a new or an empty directory"
        )


def _existing_ancestor(name: str, p: Path) -> Path:
    for q in p.absolute().parents:
        if q.exists():
            if not q.is_dir():
                raise ValueError(f"{name}={str(p)!r}: {str(q)!r} is not a directory")
            return q
    return Path("/")


def write_atomic(path: str | Path, content: str | bytes) -> Path:
    """Write ``content`` (text as UTF-8) to ``path`` — or, for a symbolic link, to its
    target — through a temporary file renamed into place; ValueError if the directory
    cannot be written or the path names something other than a regular file
    (:func:`write_target`). Returns the file written."""
    p = write_target("path", path)
    try:
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
    except OSError as exc:
        raise ValueError(f"{p}: cannot be written ({exc.strerror})") from None
    try:
        data = content.encode("utf-8") if isinstance(content, str) else content
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's 0600 → what open() would have given
        write_target("path", p)  # still a regular file or nothing: never replace a device
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_RENAME_EXCHANGE = 2  # linux/fs.h
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two directory entries atomically (Linux renameat2); False where unsupported."""
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (38, 22, 95):  # ENOSYS, EINVAL, EOPNOTSUPP: the file system cannot exchange
        return False
    raise OSError(err, os.strerror(err), str(b))


@contextlib.contextmanager
def output_directory(out: str | Path) -> Iterator[Path]:
    """Yield a temporary directory beside ``out`` to write into; on success it replaces
    ``out`` whole (module docstring), on any exception it is removed and ``out`` is left
    as it was."""
    d = check_writable("out", out, directory=True)
    d.parent.mkdir(parents=True, exist_ok=True)
    try:
        tmp = Path(tempfile.mkdtemp(dir=d.parent, prefix=f".{d.name}.", suffix=".tmp"))
    except OSError as exc:
        raise ValueError(f"{d}: cannot be written ({exc.strerror})") from None
    old: Path | None = None
    try:
        with terminate_cleanly():
            yield tmp
        (tmp / MARKER).write_text("written by piezo-turntable; replaced whole by its next run\n")
        os.chmod(tmp, 0o777 & ~_umask())
        if d.exists():
            _check_replaceable("out", d)
            if _exchange(tmp, d):
                old = tmp  # tmp now holds the old directory
            else:
                old = Path(tempfile.mkdtemp(dir=d.parent, prefix=f".{d.name}.", suffix=".old"))
                os.rmdir(old)
                os.rename(d, old)
                try:
                    os.rename(tmp, d)
                except BaseException:
                    os.rename(old, d)
                    raise
        else:
            os.rename(tmp, d)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


REDELIVER_S = 0.05  # s after a swallowed SIGTERM at which it is delivered again


class Terminated(SystemExit):
    """SIGTERM, raised where the program is so that clean-ups run (exit status 143)."""


@contextlib.contextmanager
def terminate_cleanly() -> Iterator[None]:
    """While inside, SIGTERM raises :class:`Terminated` (a SystemExit with status 143) in the
    main thread instead of killing the process at once, so ``finally`` blocks — the
    temporary directories of :func:`output_directory` — run as they do for Ctrl-C. A no-op
    outside the main thread or where another handler is installed."""
    try:
        previous = signal.getsignal(signal.SIGTERM)
    except ValueError:  # pragma: no cover - not the main interpreter
        yield
        return
    if previous not in (signal.SIG_DFL, None):
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise Terminated(128 + signum)

    hook = sys.unraisablehook

    def unraisable(args: Any) -> None:
        """A Terminated raised inside a C callback (numba's compile calls Python through
        ctypes: ``_raw_object_cache_notify``) is swallowed there and the run went on to the
        end (stop 109's probe): SIGTERM is delivered again once the callback has returned
        (:data:`REDELIVER_S` later, from a timer thread: at once it would be raised inside
        this hook, still in the callback), so the handler raises it where it propagates."""
        if isinstance(args.exc_value, Terminated):
            timer = threading.Timer(REDELIVER_S, os.kill, (os.getpid(), signal.SIGTERM))
            timer.daemon = True
            timer.start()
            return
        hook(args)

    try:
        signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        yield
        return
    sys.unraisablehook = unraisable
    try:
        yield
    finally:
        sys.unraisablehook = hook
        signal.signal(signal.SIGTERM, previous)
