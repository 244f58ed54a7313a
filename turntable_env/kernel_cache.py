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
If the directory cannot be written numba falls back to its own ``__pycache__`` locator.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

__all__ = ["configure_kernel_cache", "kernel_source_hash"]

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


def configure_kernel_cache() -> str | None:
    """Point numba's cache at the source-keyed directory (before any kernel module is
    imported: numba binds a function's cache when it is decorated). Returns the directory,
    or None where it cannot be created (numba then uses ``__pycache__``)."""
    from numba.core import config

    if "NUMBA_THREADING_LAYER" not in os.environ:
        # the batched kernel runs turntables in parallel; GNU OpenMP, numba's first choice
        # where present, aborts a child forked after the parent used it (Gymnasium's
        # AsyncVectorEnv, process pools): pick a fork-safe layer (tbb, else workqueue)
        config.THREADING_LAYER = "forksafe"
    parent = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
        "piezo-turntable",
        "numba",
    )
    path = os.path.join(parent, kernel_source_hash())
    try:
        os.makedirs(path, exist_ok=True)
    except OSError:
        return None
    config.CACHE_DIR = path
    return path
