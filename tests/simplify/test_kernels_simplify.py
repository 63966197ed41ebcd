"""lopcook.simplify.kernels against the numpy and libigl code they replace (the oracles): the
closest-point hierarchy's squared distances equal libigl's bit for bit, bounded queries keep
libigl's answers within the bounds, the mesh defect counts equal ``mesh_defects``' numpy path, and
a threaded query equals a one-thread query. Random meshes and the corpus bunny."""

from __future__ import annotations

import numpy as np
import pytest

from lopcook import jit
from lopcook.ingest import load
from lopcook.simplify import error as E
from lopcook.simplify import chain as L
from lopcook.simplify import reference as R
from lopcook.simplify import topology as T
from lopcook.types import MeshPart

pytestmark = pytest.mark.skipif(not jit.available(), reason="numba not installed: the kernels are off")

igl = pytest.importorskip("igl")


def _random_mesh(rng, n=400, m=900):
    """A triangle soup with shared vertices, zero-area faces and duplicated positions."""
    p = rng.normal(size=(n, 3))
    k = min(20, n // 4)
    p[n // 2: n // 2 + k] = p[:k]  # duplicated positions (welded by the defect counts)
    f = rng.integers(0, n, size=(m, 3))
    f[:10, 1] = f[:10, 0]  # zero-area faces
    return p, f.astype(np.int64)


def _kernels():
    from lopcook.simplify import kernels  # numba: only where it is installed (pytestmark)
    return kernels


@pytest.fixture(scope="module")
def bunny(corpus) -> MeshPart:
    return load(corpus / "stanford-bunny.obj").parts[0]


def _libigl(points, p, f):
    d, i, c = igl.point_mesh_squared_distance(np.ascontiguousarray(points, dtype=np.float64), p, f)
    return np.asarray(d), np.asarray(i, dtype=np.int64).ravel(), np.asarray(c)


def _check_against_libigl(tree, points, p, f):
    d, face, c = tree.closest(points)
    di, fi, ci = _libigl(points, p, f)
    np.testing.assert_array_equal(d, di)  # bit for bit
    # the face: the lowest id among the equally close; libigl's is one of them
    np.testing.assert_array_equal(_kernels().point_triangle_squared(points, p, f[fi]), di)
    assert (face <= fi).all()
    np.testing.assert_array_equal(_kernels().point_triangle_squared(points, p, f[face]), d)
    same = face == fi
    np.testing.assert_allclose(c[same], ci[same], rtol=0, atol=1e-12)
    return d


def test_point_triangle_equals_libigl_for_every_region():
    rng = np.random.default_rng(1)
    p = rng.normal(size=(3000, 3))
    f = np.arange(3000).reshape(-1, 3)
    pts = rng.normal(size=(1000, 3)) * 2.0
    for k in range(f.shape[0]):
        one = np.repeat(f[k:k + 1], 1, axis=0)
        want = np.asarray(igl.point_mesh_squared_distance(pts[k:k + 1], p, one)[0])
        assert _kernels().point_triangle_squared(pts[k:k + 1], p, one)[0] == want[0]


def test_closest_equals_libigl_on_random_soup():
    rng = np.random.default_rng(7)
    p, f = _random_mesh(rng)
    tree = _kernels().Tree(p, f)
    pts = np.concatenate([rng.normal(size=(2000, 3)) * 1.5, p[:50], p[f[:50]].mean(axis=1)])
    _check_against_libigl(tree, pts, p, f)


def test_closest_equals_libigl_on_the_bunny(bunny):
    p = bunny.positions.astype(np.float64)
    f = bunny.indices.astype(np.int64)
    tree = _kernels().Tree(p, f)
    rng = np.random.default_rng(3)
    lo, hi = p.min(axis=0), p.max(axis=0)
    pts = np.concatenate([rng.uniform(lo, hi, size=(3000, 3)), p[::7] + rng.normal(size=p[::7].shape) * 1e-3,
                          p[f[::5]].mean(axis=1)])
    _check_against_libigl(tree, pts, p, f)


def test_bounded_queries_keep_the_answers_within_the_bounds(bunny):
    p = bunny.positions.astype(np.float64)
    f = bunny.indices.astype(np.int64)
    tree = _kernels().Tree(p, f)
    rng = np.random.default_rng(5)
    pts = p[::11] + rng.normal(size=p[::11].shape) * 2e-3
    di = _libigl(pts, p, f)[0]
    d, face, _ = tree.closest(pts, di)  # bound = the distance: every point finds its face
    np.testing.assert_array_equal(d, di)
    assert (face >= 0).all()
    d, face, _ = tree.closest(pts, di * 0.5)  # below the distance: no face counts
    assert (face < 0).all() and np.isinf(d).all()


def test_threads_do_not_change_the_answer(bunny, monkeypatch):
    p = bunny.positions.astype(np.float64)
    f = bunny.indices.astype(np.int64)
    tree = _kernels().Tree(p, f)
    pts = np.random.default_rng(9).uniform(p.min(axis=0), p.max(axis=0), size=(3 * jit.PARALLEL_ROWS, 3))
    monkeypatch.setenv("LOPCOOK_THREADS", "1")
    one = tree.closest(pts)
    monkeypatch.setenv("LOPCOOK_THREADS", "2")
    two = tree.closest(pts)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)


def test_tree_rejects_a_mesh_without_faces():
    with pytest.raises(ValueError, match="without faces"):
        _kernels().Tree(np.zeros((3, 3)), np.zeros((0, 3), np.int64))


def test_weld_first_equals_weld_exact(bunny):
    from lopcook.mesh import weld_exact

    p = bunny.positions.astype(np.float64)
    for pos in (p, np.concatenate([p, p[::-1], -0.0 * p[:5], 0.0 * p[:5]])):  # repeats, -0.0 against 0.0
        lab, n = _kernels().weld_first((pos + 0.0).view(np.int64))
        want = weld_exact(pos)[0]
        np.testing.assert_array_equal(lab, want)
        assert n == want.max() + 1


def _defects_both(positions, faces, monkeypatch):
    monkeypatch.setenv("LOPCOOK_KERNELS", "off")
    want = T.mesh_defects(positions, faces)
    monkeypatch.setenv("LOPCOOK_KERNELS", "on")
    got = T.mesh_defects(positions, faces)
    return got, want


def test_defect_counts_equal_numpy_on_random_soups(monkeypatch):
    rng = np.random.default_rng(11)
    for n, m in ((30, 60), (200, 500), (1000, 900)):
        p, f = _random_mesh(rng, n, m)
        got, want = _defects_both(p, f, monkeypatch)
        assert got == want
        assert want["nonmanifold_edges"] + want["boundary_edges"] > 0


def test_defect_counts_equal_numpy_on_crafted_defects(monkeypatch):
    v = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [1, 1, 1]]
    cases = [
        [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],  # closed tetrahedron
        [[0, 1, 2], [0, 4, 5]],  # bow-tie at vertex 0
        [[0, 1, 2], [1, 0, 3], [0, 1, 6]],  # fin: an edge with three faces
        [[0, 1, 2], [0, 1, 3]],  # inconsistent orientation
        [[0, 1, 2], [0, 0, 3]],  # zero-area face
    ]
    for faces in cases:
        got, want = _defects_both(np.asarray(v, np.float64), np.asarray(faces, np.int64), monkeypatch)
        assert got == want, faces


def test_defect_counts_equal_numpy_on_the_bunny_and_its_lods(bunny, monkeypatch):
    got, want = _defects_both(bunny.positions, bunny.indices, monkeypatch)
    assert got == want
    for ratio in (1 / 4, 1 / 16):
        lod = L.simplify(bunny, ratio, backend="fast").part
        got, want = _defects_both(lod.positions, lod.indices, monkeypatch)
        assert got == want


def test_lod_error_equal_with_and_without_kernels(bunny, monkeypatch):
    lod = L.simplify(bunny, 1 / 8, backend="fast").part
    out = {}
    for m in ("off", "on"):
        monkeypatch.setenv("LOPCOOK_KERNELS", m)
        ref = R.Reference(bunny)
        out[m] = (E.measure_ref_to_lod(ref, lod), E.sampled_ref_to_lod(ref, lod, 3000),
                  ref.query(lod.positions)[0])
        out[m] += (ref.query_bounded(lod.positions, out[m][2])[0],)
    assert out["on"][:2] == out["off"][:2]
    np.testing.assert_array_equal(out["on"][2], out["off"][2])
    np.testing.assert_array_equal(out["on"][3], out["off"][3])


def test_mode_reads_the_environment(monkeypatch):
    monkeypatch.delenv("LOPCOOK_KERNELS", raising=False)
    assert jit.mode() == "off" and not jit.use(10**9)  # opt-in: unset is off
    for value, want in (("off", "off"), ("0", "off"), ("on", "on"), ("1", "on"), ("auto", "auto"), ("x", "auto")):
        monkeypatch.setenv("LOPCOOK_KERNELS", value)
        assert jit.mode() == want
    monkeypatch.setenv("LOPCOOK_KERNELS", "off")
    assert not jit.use(10**9)
    monkeypatch.setenv("LOPCOOK_KERNELS", "auto")
    assert not jit.use(jit.MIN_ELEMENTS - 1) and jit.use(jit.MIN_ELEMENTS)
