"""lopcook.jit: compiled kernels are cached on disk where numba's cache can be written, and still
compile (in memory) and give the same answer where no cache location is writable (a read-only
install and home). Each case runs in a fresh interpreter, as a first cook would."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from lopcook import jit
from conftest import REPO

pytestmark = pytest.mark.skipif(not jit.available(), reason="numba not installed: the kernels are off")

#: one small kernel call; prints its result
CALL = """
import numpy as np
from lopcook.analyse import kernels
print(kernels.vertex_max(np.array([[0, 1, 2], [1, 2, 3]]), np.array([2.0, 5.0]), 5).tolist())
"""

#: every cache location of numba refuses to be written (what a read-only install and home give)
READ_ONLY = """
import numba.core.caching as caching
def refuse(self):
    raise PermissionError("read-only")
caching._CacheLocator.ensure_cache_path = refuse
"""


def _run(code: str, **env) -> str:
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "LOPCOOK_KERNELS": "on", **env})
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_a_kernel_is_cached_in_numba_cache_dir(tmp_path):
    assert _run(CALL, NUMBA_CACHE_DIR=str(tmp_path)) == "[2.0, 5.0, 5.0, 5.0, 0.0]"
    cached = [p.name for p in tmp_path.rglob("*") if p.suffix in (".nbi", ".nbc")]
    assert any("_vertex_max" in name and name.endswith(".nbc") for name in cached), cached


def test_a_kernel_compiles_in_memory_without_a_writable_cache(tmp_path):
    assert _run(READ_ONLY + CALL, NUMBA_CACHE_DIR=str(tmp_path)) == "[2.0, 5.0, 5.0, 5.0, 0.0]"
    assert not any(tmp_path.rglob("*.nbc"))


def test_auto_waits_for_pays_from_until_numba_is_loaded():
    code = """
import sys
from lopcook import jit
n = jit.MIN_ELEMENTS
print(jit.use(n, pays_from=4 * n), jit.use(4 * n, pays_from=4 * n), "numba" in sys.modules)
"""
    assert _run(code, LOPCOOK_KERNELS="auto") == "False True True"
    code = """
from lopcook import jit
n = jit.MIN_ELEMENTS
print(jit.use(n), jit.use(n, pays_from=4 * n), jit.use(n - 1))
"""
    assert _run(code, LOPCOOK_KERNELS="auto") == "True True False"


def test_a_forked_child_runs_threaded_kernels():
    # the parent's thread pool does not survive a fork: the child must start its own, not wait on it
    code = """
import numpy as np
from lopcook import isolate, jit
from lopcook.simplify import kernels
rng = np.random.default_rng(0)
p = rng.normal(size=(3000, 3))
tree = kernels.Tree(p, rng.integers(0, 3000, size=(5000, 3)))
q = rng.normal(size=(2 * jit.PARALLEL_ROWS, 3))
here = tree.closest(q)[0]
child = isolate.start(lambda: tree.closest(q)[0]).result()
print(child.shape == here.shape and bool((child == here).all()), isolate.start(lambda: 1).forked)
"""
    assert _run(code, LOPCOOK_THREADS="2") == "True True"
