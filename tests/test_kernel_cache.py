"""The kernel cache is keyed by every compiled module's source (numba tracks only the
defining file's stamp, so a cached kernel could run a changed helper of another module)."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest

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


def test_an_unwritable_cache_falls_back_to_the_next_place_with_one_warning(tmp_path):
    import warnings

    from numba.core import config

    from turntable_env.kernel_cache import configure_kernel_cache

    blocker = tmp_path / "a_file"
    blocker.write_text("")  # nothing can be created below a regular file, root or not
    before = config.CACHE_DIR
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            path = configure_kernel_cache([str(blocker / "x"), str(tmp_path / "fallback")])
        assert path == str(tmp_path / "fallback" / kernel_source_hash())
        assert [str(w.message).split(";")[0] for w in caught] == [
            f"numba kernel cache: {blocker / 'x'} cannot be written"
        ]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert configure_kernel_cache([str(blocker / "x"), str(blocker / "y")]) is None
        assert len(caught) == 1 and "compile in memory" in str(caught[0].message)
    finally:
        config.CACHE_DIR = before


@pytest.mark.slow
def test_a_read_only_install_runs_the_env(tmp_path):
    """HOME and NUMBA_CACHE_DIR unwritable: gym.make, reset and step run, caching in the
    temporary directory, with one warning and no traceback."""
    import os
    import subprocess
    import sys

    blocker = tmp_path / "a_file"
    blocker.write_text("")
    env = {**os.environ, "HOME": str(blocker), "NUMBA_CACHE_DIR": str(blocker / "numba")}
    code = (
        "import warnings, gymnasium as gym, numpy as np, turntable_env\n"
        "env = gym.make('PiezoTurntable-v0'); env.reset(seed=0)\n"
        "obs = env.step(np.zeros(5, np.float32))[0]\n"
        "assert np.isfinite(obs).all()\n"
        "print(turntable_env.KERNEL_CACHE)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=900, cwd=str(tmp_path))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    assert "Traceback" not in r.stderr and r.stderr.count("RuntimeWarning") == 1
    assert r.stdout.strip().startswith(tempfile.gettempdir())


@pytest.mark.slow
def test_the_batch_and_serial_kernels_share_one_compiled_integrator(tmp_path):
    """A fresh cache after a serial and a parallel batch run of per-axis turntables holds one
    compilation of the per-turntable integrator: the per-axis form's, a literal of the
    compilation, indexed by int64 (prange's index is unsigned, and passed on as it is it
    compiled the whole integrator a second time, about 20 s at every fresh start), and not
    the translation's, which no turntable of the batch needs (an entry that held both forms
    doubled a first step's compile). The compiled code's index is numba's cache file, read in
    a fresh process."""
    import os
    import subprocess
    import sys

    code = (
        "from turntable_env import reduced_kernel as rk\n"
        "from turntable_env.reduced import ReducedModel, simulate_batch\n"
        "from turntable_env.simulation import stepping_drive\n"
        "d, ps = stepping_drive('real', amplitude=2.0, frequency=100.0, periods=1)\n"
        "m = ReducedModel(ps, 'B')\n"
        "simulate_batch([m], [d], 0.01)\n"
        "simulate_batch([m, m], [d, d], 0.01)\n"
        "index = lambda f: f._cache._cache_file._load_index()\n"
        "print(sorted((str(k[0][0]), str(k[0][-1])) for k in index(rk._run_one)))\n"
        "print(len(index(rk._moved_serial)), len(index(rk._moved_batch)))\n"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=900, cwd=str(tmp_path))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    one, moved = r.stdout.splitlines()
    assert one == "[('int64', 'Literal[bool](False)')]"
    assert moved == "0 0"
