"""lopcook.simplify.backends: both simplifiers reach their targets, keep what they are told to
keep (open boundaries, the collapse map, wedge UVs), ``prepare`` welds per seam mode, and
``check_result`` rejects every unusable result with BackendFailure."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support import fixtures as F
from lopcook.simplify import backends as B
from lopcook.simplify.topology import mesh_defects, seam_stats
from lopcook.types import MeshPart


@pytest.fixture(scope="module")
def ico():
    """Icosphere r = 0.5, 1280 triangles, 642 vertices (closed, one vertex per position)."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    return np.asarray(s.vertices, dtype=np.float64), np.asarray(s.faces, dtype=np.int64)


@pytest.fixture(scope="module")
def plate() -> MeshPart:
    """two_plates' lower plate: 8 x 8 quads, 81 vertices, 128 triangles, 32 boundary edges."""
    return F.two_plates()[0].as_mesh_part()


def _boundary_vertices(faces: np.ndarray) -> np.ndarray:
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    u, c = np.unique(e, axis=0, return_counts=True)
    return np.unique(u[c == 1])


def _run(backend, positions, faces, target, **kw):
    fn = B.simplify_fast if backend == "fast" else B.simplify_pymeshlab
    return fn(positions, faces, target, **kw)


@pytest.mark.parametrize("backend", B.BACKENDS)
@pytest.mark.parametrize("target", [640, 320, 160])
def test_backend_reaches_target_on_an_icosphere(ico, backend, target):
    v, f = ico
    res = _run(backend, v, f, target)
    m = res.faces.shape[0]
    assert abs(m - target) <= 0.05 * target
    assert res.positions.dtype == np.float64 and res.faces.dtype == np.int64
    # a closed genus-0 surface stays one: closed, manifold, Euler characteristic 2
    d = mesh_defects(res.positions, res.faces)
    assert d["closed"] and d["nonmanifold_edges"] == 0 and d["nonmanifold_vertices"] == 0
    assert res.positions.shape[0] - 3 * m // 2 + m == 2
    # and passes the result check unchanged
    out, dropped = B.check_result(res, target, f.shape[0])
    assert dropped == 0 and out.faces.shape == res.faces.shape


def test_fast_collapse_map_names_distinct_input_vertices(ico):
    v, f = ico
    res = B.simplify_fast(v, f, 320)
    src = res.vertex_source
    assert src is not None and src.shape == (res.positions.shape[0],)
    assert np.all(np.diff(src) > 0) and src.min() >= 0 and src.max() < v.shape[0]


@pytest.mark.parametrize("backend", B.BACKENDS)
def test_lock_border_keeps_the_open_boundary_exactly(plate, backend):
    v, f = plate.positions, plate.indices.astype(np.int64)
    boundary = {tuple(p) for p in v[_boundary_vertices(f)]}
    assert len(boundary) == 32
    res = _run(backend, v, f, 32, lock_border=True)
    out_b = _boundary_vertices(res.faces)
    assert res.faces.shape[0] == 32
    assert {tuple(p) for p in res.positions[out_b]} == boundary  # every boundary vertex, unmoved
    if backend == "fast":  # a locked vertex is its source vertex, bit for bit
        src = res.vertex_source
        np.testing.assert_array_equal(res.positions[out_b], v[src[out_b]])
    free = B.simplify_fast(v, f, 32, lock_border=False)
    assert len(_boundary_vertices(free.faces)) < 32  # without the lock the boundary is simplified too


@pytest.mark.parametrize("weld", [False, True])
def test_pymeshlab_wedge_uvs_follow_a_linear_parametrisation(plate, weld):
    # the plate's UVs are u = x + 0.5, v = z + 0.5: any collapse on the plane keeps that map at
    # every corner of the result
    res = B.simplify_pymeshlab(plate.positions, plate.indices.astype(np.int64), 32, uvs=plate.uvs, weld=weld)
    assert res.wedge_uvs is not None and res.wedge_uvs.shape == (res.faces.shape[0], 3, 2)
    corners = res.positions[res.faces]
    np.testing.assert_allclose(res.wedge_uvs[..., 0], corners[..., 0] + 0.5, atol=1e-12)
    np.testing.assert_allclose(res.wedge_uvs[..., 1], corners[..., 2] + 0.5, atol=1e-12)


def test_prepare_welds_per_seam_mode():
    cube = F.seamed_cube()[0].as_mesh_part()  # 24 vertices: 8 corners x 3 faces
    # ignore: weld by position -> the 8 corners
    work, dropped = B.prepare(cube, "ignore")
    assert dropped == 0 and work.positions.shape == (8, 3) and work.faces.shape == (12, 3) and work.uvs is None
    assert mesh_defects(work.positions, work.faces)["closed"]
    # lock: weld by (position, UV) -> the unfolded cross net, a disc: V = 1 + E - F with the 12
    # cube edges plus one copy of each of the 7 seam edges, 6 quads -> 1 + 19 - 6 = 14 vertices
    stats = seam_stats(cube)
    assert stats.seam_edges == 7 and stats.uv_islands == 1
    work, _ = B.prepare(cube, "lock")
    assert work.positions.shape == (1 + 12 + stats.seam_edges - 6, 3)
    assert np.unique(work.region).size == stats.uv_islands
    # every work corner keeps its input position and UV
    np.testing.assert_array_equal(work.positions[work.faces], cube.positions[cube.indices.astype(np.int64)])
    np.testing.assert_array_equal(work.uvs[work.faces], cube.uvs[cube.indices.astype(np.int64)])
    # simplify: pymeshlab welds itself, the input is only compacted
    work, _ = B.prepare(cube, "simplify")
    np.testing.assert_array_equal(work.positions, cube.positions)
    np.testing.assert_array_equal(work.uvs, cube.uvs)


def test_prepare_drops_zero_area_faces():
    cube = F.seamed_cube()[0].as_mesh_part()
    idx = np.r_[cube.indices, [[0, 0, 1], [2, 2, 2]]].astype(np.uint32)
    part = MeshPart(name="cube", positions=cube.positions, indices=idx, normals=cube.normals, uvs=cube.uvs)
    for mode in ("ignore", "lock", "simplify"):
        work, dropped = B.prepare(part, mode)
        assert dropped == 2 and work.faces.shape == (12, 3)


def _ok(ico, target=320):
    v, f = ico
    return B.simplify_fast(v, f, target), f.shape[0]


def test_check_result_cleans_degenerate_faces_and_unused_vertices(ico):
    res, n_in = _ok(ico)
    k = res.positions.shape[0]
    extra_v = np.r_[res.positions, [[9.0, 9.0, 9.0]]]  # an unreferenced vertex
    faces = np.r_[res.faces, [[0, 0, 1], [2, 3, 2]]]  # two zero-area faces
    src = np.r_[res.vertex_source, [0]]
    out, dropped = B.check_result(B.BackendResult(extra_v, faces, vertex_source=src), 320, n_in)
    assert dropped == 2
    np.testing.assert_array_equal(out.faces, res.faces)
    np.testing.assert_array_equal(out.positions, res.positions)
    assert out.positions.shape[0] == k
    np.testing.assert_array_equal(out.vertex_source, res.vertex_source)


def test_check_result_rejects_unusable_results(ico):
    res, n_in = _ok(ico)
    p, f = res.positions, res.faces

    def fails(result, target=320, match=""):
        with pytest.raises(B.BackendFailure, match=match):
            B.check_result(result, target, n_in)

    fails(B.BackendResult(p[:, :2], f), match="shape")
    fails(B.BackendResult(p, f[:0]), match="no triangles")
    fails(B.BackendResult(p, np.r_[f, [[0, 1, p.shape[0]]]]), match="out-of-range")
    nan = p.copy()
    nan[5] = np.nan
    fails(B.BackendResult(nan, f), match="NaN")
    fails(B.BackendResult(p, np.tile([[0, 0, 1]], (320, 1))), match="only degenerate")
    fails(B.BackendResult(p, f), target=100, match="2x off")  # 320 triangles for 100
    fails(B.BackendResult(p, f), target=700, match="2x off")  # 320 for 700: less than half
    v, full = ico
    fails(B.BackendResult(v, full), target=1200, match="did not reduce")
