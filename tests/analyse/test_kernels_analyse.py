"""lopcook.analyse.kernels against the numpy code of lopcook.analyse.attribute_error (the oracle):
triangle frames, E_t of attributes of 1 to 7 components and E_v equal bit for bit on random
meshes (degenerate, sliver and non-finite triangles included) and on the corpus bunny; the
threaded kernels equal one thread."""

from __future__ import annotations

import numpy as np
import pytest

from lopcook import jit
from lopcook.analyse import attribute_error as A
from lopcook.ingest import load

pytestmark = [pytest.mark.skipif(not jit.available(), reason="numba not installed: the kernels are off"),
              pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")]  # the NaN and inf inputs


def _random(rng, n=3000, m=8000):
    p = rng.normal(size=(n, 3)) * rng.uniform(1e-3, 1e3)
    t = rng.integers(0, n, size=(m, 3))
    t[:20, 2] = t[:20, 0]  # repeated corner: zero area
    p[-10:] = p[:10] + 1e-9 * rng.normal(size=(10, 3))  # near-duplicates: slivers
    p[5] = [np.inf, 0.0, 0.0]  # a non-finite corner
    return p, t


def _both(monkeypatch, fn):
    monkeypatch.setenv("LOPCOOK_KERNELS", "off")
    want = fn()
    monkeypatch.setenv("LOPCOOK_KERNELS", "on")
    got = fn()
    return got, want


def _all(positions, indices, attributes):
    f = A.triangle_frames(positions, indices)
    e_ts, deg = A.triangle_gradient_norms(positions, indices, attributes, f)
    e_vs = [A.vertex_max(f.tri, e, positions.shape[0]) for e in e_ts]
    return [f.m11, f.m12, f.m22, f.degenerate, deg, *e_ts, *e_vs]


def _assert_same(got, want):
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and g.shape == w.shape
        np.testing.assert_array_equal(g, w)  # NaN where NaN, bit-equal values elsewhere
        assert (np.signbit(g) == np.signbit(w)).all()


def test_kernels_equal_numpy_on_random_meshes(monkeypatch):
    rng = np.random.default_rng(4)
    for _ in range(3):
        p, t = _random(rng)
        attrs = [rng.normal(size=(p.shape[0], k)) for k in range(1, 8)]
        attrs[2][7] = np.nan  # a NaN attribute reaches E_t and E_v as numpy's does
        got, want = _both(monkeypatch, lambda: _all(p, t, attrs))
        _assert_same(got, want)


def test_kernels_equal_numpy_on_the_bunny(corpus, monkeypatch):
    part = load(corpus / "stanford-bunny.obj").parts[0]
    uv = np.random.default_rng(1).random((part.n_vertices, 2)).astype(np.float32)
    attrs = [part.normals, uv]
    got, want = _both(monkeypatch, lambda: _all(part.positions, part.indices, attrs))
    _assert_same(got, want)
    assert got[-1].max() > 0


def test_the_kernels_themselves_equal_numpy(monkeypatch):
    from lopcook.analyse import kernels  # numba: only where it is installed (pytestmark)

    rng = np.random.default_rng(6)
    p, t = _random(rng)
    attr = rng.normal(size=(p.shape[0], 3))
    monkeypatch.setenv("LOPCOOK_KERNELS", "off")
    f = A.triangle_frames(p, t)
    (e_t,), _ = A.triangle_gradient_norms(p, t, [attr], f)
    e_v = A.vertex_max(t, e_t, p.shape[0])
    _assert_same(kernels.triangle_frames(p, t.astype(np.int64), A.DEGENERATE_TOL), [f.m11, f.m12, f.m22, f.degenerate])
    _assert_same(kernels.gradient_norms(attr, [3], f), [e_t])
    _assert_same([kernels.vertex_max(t.astype(np.int64), e_t, p.shape[0])], [e_v])


def test_threads_do_not_change_e_t(monkeypatch):
    rng = np.random.default_rng(8)
    p, t = _random(rng, n=20000, m=3 * jit.PARALLEL_ROWS)
    attrs = [rng.normal(size=(p.shape[0], 3))]
    monkeypatch.setenv("LOPCOOK_KERNELS", "on")
    monkeypatch.setenv("LOPCOOK_THREADS", "1")
    one = _all(p, t, attrs)
    monkeypatch.setenv("LOPCOOK_THREADS", "2")
    _assert_same(_all(p, t, attrs), one)


def test_wide_attributes_stay_on_numpy(monkeypatch):
    rng = np.random.default_rng(2)
    p, t = _random(rng, n=500, m=900)
    wide = [rng.normal(size=(p.shape[0], 9))]
    got, want = _both(monkeypatch, lambda: _all(p, t, wide))
    _assert_same(got, want)
