"""``lopcook.isolate``: a backend call in a forked child returns the same result, re-raises
the child's exception, and turns a crash into ``ChildFailed``, which the LOD chain falls back from."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from lopcook import isolate
from lopcook.simplify import backends as B
from lopcook.simplify import chain as L
from lopcook.simplify import error as E
from lopcook.simplify import topology as T
from lopcook.simplify import transfer as X
from tests.support.fixtures import unit_sphere
from lopcook.types import MeshPart

pytestmark = pytest.mark.skipif(not isolate._available(), reason="backends are isolated on Linux only")


def _pid_and_sum(a):
    return os.getpid(), float(np.asarray(a).sum()), np.asarray(a) * 2


def test_result_comes_back_from_a_child():
    a = np.arange(300_000, dtype=np.float64)
    pid, total, doubled = isolate.call(_pid_and_sum, a, faces=isolate.MIN_FACES)
    assert pid != os.getpid() and total == float(a.sum()) and np.array_equal(doubled, 2 * a)
    # small inputs stay in this process
    assert isolate.call(_pid_and_sum, a, faces=isolate.MIN_FACES - 1)[0] == os.getpid()


def _raise():
    raise ValueError("bad input, said the child")


def _crash():
    os.kill(os.getpid(), signal.SIGSEGV)


def test_exception_and_crash():
    with pytest.raises(ValueError, match="said the child"):
        isolate.call(_raise, faces=isolate.MIN_FACES)
    with pytest.raises(isolate.ChildFailed, match="signal 11"):
        isolate.call(_crash, faces=isolate.MIN_FACES)


def test_a_fresh_interpreter_returns_raises_and_reports_a_crash():
    """``call_fresh`` (USD once its thread pool may run here): another process, the same result,
    the child's exception re-raised, a crash as ChildFailed with its signal."""
    a = np.arange(1000, dtype=np.float64)
    pid, total, doubled = isolate.call_fresh(_pid_and_sum, a)
    assert pid != os.getpid() and total == float(a.sum()) and np.array_equal(doubled, 2 * a)
    with pytest.raises(ValueError, match="said the child"):
        isolate.call_fresh(_raise)
    with pytest.raises(isolate.ChildFailed, match="signal 11"):
        isolate.call_fresh(_crash)


def test_usd_after_usd_ran_in_this_process_does_not_hang(tmp_path):
    """The hang this guards against: USD used in this process (its TBB workers started), then a
    USD load forked a child that waited forever. Both loads must finish and agree."""
    from pxr import Usd, UsdGeom

    path = str(tmp_path / "tri.usda")
    stage = Usd.Stage.CreateNew(path)
    mesh = UsdGeom.Mesh.Define(stage, "/m")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    stage.GetRootLayer().Save()
    Usd.Stage.Open(path).Traverse()  # USD's parallel composition runs in this process
    from lopcook.ingest import load

    a, b = load(path), load(path)
    assert a.n_triangles == b.n_triangles == 1
    assert np.array_equal(a.parts[0].positions, b.parts[0].positions)


@pytest.mark.parametrize("backend", B.BACKENDS)
def test_a_crashing_backend_falls_back(monkeypatch, backend):
    s = unit_sphere(3)[0]
    part = MeshPart("s", s.positions, s.indices, normals=s.normals)
    func = {"pymeshlab": "simplify_pymeshlab", "fast": "simplify_fast"}[backend]
    monkeypatch.setattr(B, func, lambda *a, **k: _crash())
    monkeypatch.setattr(isolate, "MIN_FACES", 0)  # isolate even this small mesh
    lod = L.simplify(part, 0.25, backend)
    assert not lod.failed and lod.backend != backend
    assert any(f"{backend} failed" in n and "signal 11" in n and "falling back" in n for n in lod.notes)
