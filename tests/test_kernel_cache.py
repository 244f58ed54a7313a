"""The kernel cache is keyed by every compiled module's source (numba tracks only the
defining file's stamp, so a cached kernel could run a changed helper of another module)."""

from __future__ import annotations

import shutil
from pathlib import Path

import turntable_env
from turntable_env.generator import generate_interval
from turntable_env.kernel_cache import PACKAGE, kernel_source_hash


def test_kernels_are_cached_under_the_source_keyed_directory():
    assert turntable_env.KERNEL_CACHE is not None
    assert Path(turntable_env.KERNEL_CACHE).name == kernel_source_hash()
    # the generator calls amplifier.adapted_hold_core: its cache is keyed by both files
    assert generate_interval._cache._cache_path.startswith(turntable_env.KERNEL_CACHE)


def test_a_change_to_a_callee_module_changes_the_key(tmp_path):
    root = tmp_path / "pkg"
    shutil.copytree(PACKAGE, root, ignore=shutil.ignore_patterns("__pycache__", "data"))
    before = kernel_source_hash(root)
    amp = root / "amplifier.py"
    amp.write_text(amp.read_text() + "\n# a changed helper\n")
    assert kernel_source_hash(root) != before
    docs_only = root / "params.py"  # no compiled code: not part of the key
    assert b"njit" not in docs_only.read_bytes() and b"numba" not in docs_only.read_bytes()
    h = kernel_source_hash(root)
    docs_only.write_text(docs_only.read_text() + "\n# comment\n")
    assert kernel_source_hash(root) == h
