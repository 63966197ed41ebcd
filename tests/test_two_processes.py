"""Work split over two processes gives the one-process result, bit for bit: ``isolate.start`` and
``isolate.fork_map``; ``Reference.query_bounded``'s chunk sweep in two processes; and a LOD cook
whose LOD 0 analysis runs beside the chains and whose levels are analysed in two processes
(``lopcook.pipeline.parallel``)."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from lopcook import isolate, pipeline
from tests.support.fixtures import unit_sphere
from lopcook.settings import Settings, SimplifySettings, parse_lods
from lopcook.simplify import reference as R
from lopcook.types import MeshPart, Scene

pytestmark = pytest.mark.skipif(not isolate._available(), reason="forked work is Linux only")


def _square_and_pid(x):
    if x == 13:
        raise ValueError(f"unlucky {x}")
    return x * x, os.getpid()


def test_fork_map_is_the_serial_map_and_uses_a_child():
    items = list(range(10))
    out = isolate.fork_map(_square_and_pid, items, weights=[1, 1, 1, 1, 1, 9, 1, 1, 1, 1], workers=2)
    assert [v for v, _ in out] == [x * x for x in items]
    pids = {p for _, p in out}
    assert os.getpid() in pids and len(pids) == 2  # the front run in a child, the rest here
    # the front run is the smallest one holding half the weight: items 0..5 (weight 14 of 18)
    assert [p == os.getpid() for _, p in out] == [False] * 6 + [True] * 4
    serial = isolate.fork_map(_square_and_pid, items, workers=1)
    assert {p for _, p in serial} == {os.getpid()}


@pytest.mark.parametrize("where", [0, 9])  # in the child's run, in the parent's
def test_fork_map_raises_the_failing_items_exception(where):
    items = list(range(10))
    items[where] = 13
    with pytest.raises(ValueError, match="unlucky 13"):
        isolate.fork_map(_square_and_pid, items, workers=2)


def _sleep_then(x):
    time.sleep(x)
    return x


def _exit_without_result():
    os._exit(3)


def test_start_result_cancel_and_a_child_that_dies():
    a = np.arange(100_000, dtype=np.float64)
    child = isolate.start(np.cumsum, a)
    assert np.array_equal(child.result(), np.cumsum(a)) and np.array_equal(child.result(), np.cumsum(a))
    t0 = time.perf_counter()
    slow = isolate.start(_sleep_then, 30.0)
    slow.cancel()
    assert time.perf_counter() - t0 < 10.0 and slow.result() is None
    with pytest.raises(isolate.ChildFailed, match="exit status 3"):
        isolate.start(_exit_without_result).result()
    with pytest.raises(ValueError, match="unlucky"):
        isolate.start(_square_and_pid, 13).result()
    # without a fork: computed at result()
    assert isolate.start(_square_and_pid, 4, fork=False).result() == (16, os.getpid())


def _bumpy_sphere(subdiv: int = 5, bump: float = 0.05) -> MeshPart:
    part = unit_sphere(subdiv)[0]
    p = part.positions.astype(np.float64)
    rng = np.random.default_rng(7)
    p *= (1.0 + bump * rng.standard_normal(p.shape[0]))[:, None]
    return MeshPart(name="bumpy", positions=p.astype(np.float32), indices=part.indices.astype(np.uint32))


def test_query_bounded_in_two_processes_is_the_serial_answer(monkeypatch):
    part = _bumpy_sphere()
    monkeypatch.setattr(R, "CHUNK_FACES", part.n_triangles // 12)  # 16 chunks
    monkeypatch.setattr(R, "PARALLEL_POINTS", 100)
    rng = np.random.default_rng(3)
    # points off the surface with a true bound: the squared distance to a LOD 0 vertex
    v = part.positions.astype(np.float64)
    pts = v[rng.integers(0, v.shape[0], 4000)] * (1.0 + 0.2 * rng.standard_normal((4000, 1)))
    pts += 0.02 * rng.standard_normal(pts.shape)
    bound = ((pts - v[rng.integers(0, v.shape[0], 4000)]) ** 2).sum(axis=1)
    bound = np.minimum(bound, ((pts - v[0]) ** 2).sum(axis=1))
    answers = {}
    for w in ("1", "2"):
        monkeypatch.setenv("LOPCOOK_LOD_WORKERS", w)
        answers[w] = R.Reference(part).query_bounded(pts, bound)
    for a, b in zip(answers["1"], answers["2"]):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    d, f, c = answers["2"]
    full_d, _, _ = R.Reference(part).query(pts)  # one tree over all faces: the exact distances
    assert np.allclose(d, full_d, rtol=1e-12, atol=1e-15)
    # the closest point lies on the face found
    ref = R.Reference(part)
    a, b_, c_ = (ref.positions[ref.faces[f, j]].astype(np.float64) for j in range(3))
    n = np.cross(b_ - a, c_ - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    assert np.abs(np.einsum("ij,ij->i", c - a, n)).max() < 1e-9


def test_a_lod_cook_in_two_processes_writes_the_one_process_bytes(monkeypatch):
    """LOD 0's analysis started beside the chains, the chunk sweeps and the levels' analyses in
    two processes: the container is the serial one."""
    scene = Scene(parts=(_bumpy_sphere(5, 0.01),), source="bumpy.obj", format="obj")
    monkeypatch.setattr(pipeline, "PARALLEL_VERTICES", 0)
    monkeypatch.setattr(R, "PARALLEL_POINTS", 100)
    monkeypatch.setattr(R, "CHUNK_FACES", 2048)
    started = []
    real_start = isolate.start

    def spy(fn, *a, **k):
        started.append(getattr(fn, "__name__", ""))
        return real_start(fn, *a, **k)

    monkeypatch.setattr(isolate, "start", spy)
    settings = Settings(simplify=SimplifySettings(lods=parse_lods("1/2,1/4"), backend="meshopt"))
    out = {}
    for w in ("1", "2"):
        monkeypatch.setenv("LOPCOOK_LOD_WORKERS", w)
        started.clear()
        result = pipeline.run(scene, settings)
        out[w] = result.container.data
        assert set(started) == ({"analyse", "_sweep", "_map"} if w == "2" else set())
        # one analysis per level: each LOD's, started as soon as its mesh existed, is kept when the
        # chain accepts that mesh
        assert started.count("analyse") == (3 if w == "2" else 0)
    assert [r["backend"] for r in result.lod_reports[0]["lods"]][1:] == ["meshopt", "meshopt"]
    assert out["1"] == out["2"]


def test_analyse_lods_uses_a_speculative_analysis_only_on_its_own_grid_and_parts(monkeypatch):
    from lopcook.grid import Grid

    part = _bumpy_sphere(3, 0.01)
    scene = Scene(parts=(part,), source="bumpy.obj", format="obj")
    half = MeshPart(name="bumpy", positions=part.positions, indices=part.indices[::2].copy())
    big = MeshPart(name="bumpy", positions=part.positions * np.float32(1.5), indices=part.indices)
    monkeypatch.setenv("LOPCOOK_LOD_WORKERS", "1")
    settings = pipeline.DEFAULTS

    def check(chain, spec):
        want = pipeline.analyse_lods(scene, chain)
        got = pipeline.analyse_lods(scene, chain, first=spec)
        assert got[0] == want[0] and got[3] == want[3]
        for a, b in zip(got[2][0], want[2][0]):
            assert np.array_equal(a, b)
        for ga, wa in zip(got[1], want[1]):
            for x, y in zip(ga.parts, wa.parts):
                assert np.array_equal(x.quantized, y.quantized) and np.array_equal(x.min_level, y.min_level)
                assert np.array_equal(x.reason, y.reason)
        return want

    own = Grid.fit([part.positions])
    # LOD 1 inside LOD 0's box: both levels taken from the children
    spec = pipeline.Speculation(scene, settings, own)
    spec.started(1, half)
    child = spec._children[1][1]
    spec.started(1, half)  # the same part again: the same child goes on
    assert spec._children[1][1] is child
    took = []
    real_take = pipeline.Speculation.take

    def spy(self, k, parts, grid):
        got = real_take(self, k, parts, grid)
        took.append(got is not None)
        return got

    monkeypatch.setattr(pipeline.Speculation, "take", spy)
    assert check([[part, half]], spec)[0] == own and took == [True, True]
    # another LOD 1 object than the one started on: LOD 1 analysed in place
    spec, took[:] = pipeline.Speculation(scene, settings, own), []
    spec.started(1, MeshPart(name="bumpy", positions=part.positions, indices=half.indices))
    check([[part, half]], spec)
    assert took == [True, False]
    # LOD 1 outside LOD 0's box: another grid, nothing taken
    spec, took[:] = pipeline.Speculation(scene, settings, own), []
    spec.started(1, big)
    assert check([[part, big]], spec)[0] != own and took == [False, False]


def test_parallel_needs_two_workers_enough_vertices_and_memory(monkeypatch):
    import lopcook.memory as M

    scene = Scene(parts=(_bumpy_sphere(3, 0.01),), source="bumpy.obj", format="obj")
    n = scene.parts[0].n_vertices
    monkeypatch.setattr(pipeline, "PARALLEL_VERTICES", n)
    monkeypatch.setenv("LOPCOOK_LOD_WORKERS", "2")
    monkeypatch.setattr(M, "available_bytes", lambda: pipeline.PARALLEL_BYTES_PER_VERTEX * n)
    assert pipeline.parallel(scene)
    monkeypatch.setattr(M, "available_bytes", lambda: pipeline.PARALLEL_BYTES_PER_VERTEX * n - 1)
    assert not pipeline.parallel(scene)
    monkeypatch.setattr(M, "available_bytes", lambda: None)
    assert pipeline.parallel(scene)
    monkeypatch.setattr(pipeline, "PARALLEL_VERTICES", n + 1)
    assert not pipeline.parallel(scene)
    monkeypatch.setattr(pipeline, "PARALLEL_VERTICES", n)
    monkeypatch.setenv("LOPCOOK_LOD_WORKERS", "1")
    assert not pipeline.parallel(scene)
