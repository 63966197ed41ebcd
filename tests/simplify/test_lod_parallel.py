"""lopcook.simplify.parallel: LOD chains of independent parts in worker processes give exactly
the serial chains (and the same container bytes), with LOD 0 and textures the input's own."""

from __future__ import annotations

import numpy as np
import pytest

from lopcook import pipeline
from lopcook.ingest import load
from lopcook.settings import LodSpec, Settings, SimplifySettings
from lopcook.simplify import parallel as P
from lopcook.simplify import workers as W


@pytest.fixture(scope="module")
def truck(corpus):
    return load(corpus / "CesiumMilkTruck.glb")


def _same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.triangles == y.triangles and x.error_m == y.error_m and x.hausdorff_m == y.hausdorff_m
        assert x.backend == y.backend and x.seams == y.seams and x.notes == y.notes
        for name in ("positions", "indices", "normals", "uvs", "colors"):
            u, v = getattr(x.part, name), getattr(y.part, name)
            assert (u is None) == (v is None) and (u is None or (u.dtype == v.dtype and np.array_equal(u, v)))


def test_parallel_chains_are_the_serial_chains(truck, monkeypatch):
    monkeypatch.setattr(P, "MIN_TRIANGLES", 0)
    parts = list(truck.parts)
    kw = dict(backend="auto", seams="auto")
    serial = P.run_chains(parts, 1, **kw)
    ticks = []
    par = P.run_chains(parts, 2, progress=lambda: ticks.append(1), **kw)
    assert len(ticks) == len(parts)
    for part, (ls, rs), (lp, rp) in zip(parts, serial, par):
        _same(ls, lp)
        untimed = lambda rows: [{k: v for k, v in r.items() if k != "seconds"} for r in rows]  # noqa: E731
        assert untimed(rs.lods) == untimed(rp.lods) and rs.stop_reason == rp.stop_reason
        assert lp[0].part is part  # LOD 0 is the input itself, as in-process
        for lod in lp[1:]:
            assert lod.part.texture is part.texture  # not a pickled copy
    assert any(len(ls) > 2 for ls, _ in serial)  # not vacuous: real chains


def test_cook_bytes_do_not_depend_on_the_worker_count(truck, monkeypatch):
    monkeypatch.setattr(P, "MIN_TRIANGLES", 0)
    settings = Settings(simplify=SimplifySettings(lods=LodSpec(auto=True)))
    data = {}
    for w in ("1", "2"):
        monkeypatch.setenv("LOPCOOK_LOD_WORKERS", w)
        assert W.workers() == int(w)
        data[w] = pipeline.run(truck, settings).data
    assert data["1"] == data["2"]


def test_workers_setting(monkeypatch):
    monkeypatch.setenv("LOPCOOK_LOD_WORKERS", "0")
    assert W.workers() == 1
    monkeypatch.setenv("LOPCOOK_LOD_WORKERS", "many")
    assert W.workers() == 1
    monkeypatch.delenv("LOPCOOK_LOD_WORKERS")
    assert 1 <= W.workers() <= W.MAX_WORKERS


def _dies(part, **kw):
    import os
    import signal

    if part.name.endswith("1"):  # one worker is killed, as the memory killer would
        os.kill(os.getpid(), signal.SIGKILL)
    return [], None


def test_a_worker_that_dies_is_an_error_not_a_hang(monkeypatch):
    from tests.support import fixtures as fx
    from lopcook.errors import LopcookError
    from lopcook.types import MeshPart

    monkeypatch.setattr(P, "MIN_TRIANGLES", 0)
    base = fx.unit_sphere(3)[0]
    parts = [MeshPart(f"s{k}", base.positions + [3.0 * k, 0.0, 0.0], base.indices) for k in range(3)]
    with pytest.raises(LopcookError, match="worker process died") as exc:
        P.run_chains(parts, 2, chain=_dies)
    assert exc.value.exit_code == 2 and "LOPCOOK_LOD_WORKERS=1" in exc.value.hint
