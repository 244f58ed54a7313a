"""Where numba keeps the compiled kernels: a directory keyed by the kernels' source.

numba's on-disk cache (``@njit(cache=True)``) checks only the stamp of the file that
defines a function, not of the files its callees live in: a kernel cached before a
compiled helper in another module changed keeps running the old helper (this hid a
changed adapted-hold time from a local test run until a fresh clone ran it). Every
compiled module of the package is therefore hashed together at import, and the cache
lives in a directory named by that hash — any change to any kernel source starts a
fresh cache. The threading layer of the parallel batch kernel is a fork-safe one unless
``NUMBA_THREADING_LAYER`` says otherwise. ``NUMBA_CACHE_DIR``, if set, is the parent of
these directories; otherwise ``$XDG_CACHE_HOME/piezo-turntable/numba`` (``~/.cache``).

Read-only installs: where that directory cannot be written (a read-only HOME, a
container), the cache goes to a per-user directory in the system's temporary directory,
with one ``RuntimeWarning``; where nothing can be written, :data:`CACHE` is False and the
kernels compile in memory at every start (slower to start, the same results). Every
kernel module decorates with ``@njit(cache=CACHE)``.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import warnings
from pathlib import Path

__all__ = ["CACHE", "CACHE_DIR", "configure_kernel_cache", "kernel_source_hash"]

PACKAGE = Path(__file__).resolve().parent


def kernel_source_hash(root: Path = PACKAGE) -> str:
    """SHA-256 (first 16 hex digits) over every module under ``root`` that compiles a
    kernel (its text contains ``njit`` or ``numba``), in path order."""
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        text = p.read_bytes()
        if b"njit" in text or b"numba" in text:
            h.update(str(p.relative_to(root)).encode())
            h.update(b"\0")
            h.update(text)
    return h.hexdigest()[:16]


def _writable(path: str) -> bool:
    """Whether files can be created in ``path`` (created if missing): a real probe."""
    try:
        os.makedirs(path, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".probe.")
        os.close(fd)
        os.unlink(probe)
    except OSError:
        return False
    return True


def configure_kernel_cache(parents: list[str] | None = None) -> str | None:
    """Point numba's cache at the source-keyed directory (before any kernel module is
    imported: numba binds a function's cache when it is decorated) under the first
    writable of ``parents`` (default: the configured one, then the temporary one).
    Returns the directory, or None where none can be written (kernels then compile in
    memory: :data:`CACHE` False)."""
    from numba.core import config

    if "NUMBA_THREADING_LAYER" not in os.environ:
        # the batched kernel runs turntables in parallel; GNU OpenMP, numba's first choice
        # where present, aborts a child forked after the parent used it (Gymnasium's
        # AsyncVectorEnv, process pools): pick a fork-safe layer (tbb, else workqueue)
        config.THREADING_LAYER = "forksafe"
    if parents is None:
        configured = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
            os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
            "piezo-turntable",
            "numba",
        )
        user = str(os.getuid()) if hasattr(os, "getuid") else "user"
        parents = [configured, os.path.join(tempfile.gettempdir(), f"piezo-turntable-{user}")]
    key = kernel_source_hash()
    for k, parent in enumerate(parents):
        path = os.path.join(parent, key)
        if _writable(path):
            if k > 0:
                warnings.warn(
                    f"numba kernel cache: {parents[0]} cannot be written; caching in {path}",
                    RuntimeWarning,
                    stacklevel=2,
                )
            config.CACHE_DIR = path
            return path
    warnings.warn(
        f"numba kernel cache: none of {parents} can be written; kernels compile in memory",
        RuntimeWarning,
        stacklevel=2,
    )
    return None


CACHE_DIR = configure_kernel_cache()  # at import: before any kernel module is decorated
CACHE = CACHE_DIR is not None  # numba's on-disk cache on (``@njit(cache=CACHE)``)
