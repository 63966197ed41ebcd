"""lopcook.simplify.transfer: barycentric coordinates, the LOD 0 reference, and attribute transfer
onto a mesh: an unsimplified mesh gets its own attributes back per corner (seams and creases
re-split), a simplified plate keeps its linear UVs, and inside-out results are rejected."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support import fixtures as F
from lopcook.simplify import backends as B
from lopcook.simplify import transfer as X
from lopcook.simplify import reference as R
from lopcook.simplify.reference import samples
from lopcook.types import MeshPart

TRI = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _parts():
    return {"seamed_cube": F.seamed_cube()[0].as_mesh_part(), "two_plates": F.two_plates()[0].as_mesh_part(),
            "unit_sphere": F.unit_sphere()[0].as_mesh_part()}


def test_barycentric_at_corners_centroid_and_inside(rng):
    tri = np.repeat(TRI[None], 5, axis=0)
    pts = np.r_[TRI, [TRI.mean(0)], [[0.5, 0.25, 0.0]]]
    bary = X.barycentric(pts, tri, clamp=False)
    np.testing.assert_allclose(bary[:3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(bary[3], [1 / 3] * 3, atol=1e-15)
    np.testing.assert_allclose(bary @ TRI, pts, atol=1e-15)  # reproduces points in the plane
    # a point above the plane gets the coordinates of its projection
    np.testing.assert_allclose(X.barycentric(pts + [0, 0, 3.0], tri, clamp=False), bary, atol=1e-15)
    # random triangles: the weights sum to 1 and rebuild the projected point
    t = rng.normal(size=(100, 3, 3))
    w = rng.dirichlet([1, 1, 1], 100)
    p = np.einsum("qk,qkd->qd", w, t)
    np.testing.assert_allclose(X.barycentric(p, t, clamp=False), w, atol=1e-9)


def test_barycentric_clamps_outside_points_and_handles_degenerate_triangles():
    tri = np.repeat(TRI[None], 2, axis=0)
    outside = np.array([[-1.0, -1.0, 0.0], [3.0, 0.5, 0.0]])
    raw = X.barycentric(outside, tri, clamp=False)
    assert (raw < 0).any(axis=1).all()
    c = X.barycentric(outside, tri, clamp=True)
    assert np.all(c >= 0) and np.allclose(c.sum(1), 1.0)
    np.testing.assert_allclose(c[0], [1, 0, 0])  # below-left of the right angle: its corner
    flat = np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0]]], dtype=np.float64)  # collinear
    np.testing.assert_allclose(X.barycentric(np.array([[0.5, 0.5, 0.0]]), flat, clamp=True), [[1 / 3] * 3])


def test_reference_leaves_zero_area_faces_out():
    cube = _parts()["seamed_cube"]
    idx = np.r_[cube.indices, [[0, 0, 1]]].astype(np.uint32)
    part = MeshPart(name="cube", positions=cube.positions, indices=idx, normals=cube.normals, uvs=cube.uvs)
    ref = R.Reference(part)
    assert ref.degenerate.sum() == 1 and ref.faces.shape == (12, 3) and ref.faces_all.shape == (13, 3)
    assert ref.defects["degenerate_faces"] == 1 and ref.defects["closed"]
    assert ref.volume == pytest.approx(1.0, rel=1e-15)
    np.testing.assert_allclose(np.linalg.norm(ref.face_unit, axis=1), 1.0, rtol=1e-15)
    np.testing.assert_array_equal(ref.samples, samples(cube.positions, cube.indices.astype(np.int64)))
    # six faces, each its own set of 4 vertices: six vertex-connected regions
    assert np.unique(ref.region).size == 6


# seam modes differ only for parts with UVs (the sphere has none)
@pytest.mark.parametrize("name, mode", [(n, m) for n in ("seamed_cube", "two_plates") for m in ("ignore", "lock", "simplify")]
                         + [("unit_sphere", "ignore")])
def test_transfer_onto_the_unsimplified_mesh_reproduces_its_attributes(name, mode):
    part = _parts()[name]
    ref = R.Reference(part)
    work, _ = B.prepare(part, mode)
    res = B.BackendResult(part.positions.copy(), part.indices.astype(np.int64))
    out, info = X.transfer_attributes(res, ref, part, work, mode, 0.02)
    assert info["flipped"] == 0 and info["lod_to_ref"] < 1e-15
    # the same vertices (a cube corner is three vertices again: the crease and seams re-split) ...
    assert out.n_vertices == part.n_vertices and out.n_triangles == part.n_triangles
    np.testing.assert_array_equal(out.positions[out.indices], part.positions[part.indices])
    # ... with the same attributes per corner: exactly, except that normals are renormalised in
    # float32 (the sphere's float32 unit normals move by at most an ulp)
    for attr in ("normals", "uvs", "colors"):
        src, got = getattr(part, attr), getattr(out, attr)
        assert (src is None) == (got is None), attr
        if src is not None:
            tol = 2.0**-24 if attr == "normals" and name == "unit_sphere" else 0.0
            np.testing.assert_allclose(got[out.indices], src[part.indices], rtol=0, atol=tol)


def test_transfer_onto_a_simplified_plate_keeps_linear_uvs_and_normals():
    plate = _parts()["two_plates"]
    ref = R.Reference(plate)
    work, _ = B.prepare(plate, "ignore")
    res, _ = B.check_result(B.simplify_fast(work.positions, work.faces, 32, lock_border=True), 32, 128)
    out, info = X.transfer_attributes(res, ref, plate, work, "ignore", 0.02)
    assert out.n_triangles == res.faces.shape[0] and info["flipped"] == 0
    # UVs are u = x + 0.5, v = z + 0.5 on LOD 0, a linear field: interpolation keeps it
    np.testing.assert_allclose(out.uvs[:, 0], out.positions[:, 0] + 0.5, atol=1e-6)
    np.testing.assert_allclose(out.uvs[:, 1], out.positions[:, 2] + 0.5, atol=1e-6)
    np.testing.assert_array_equal(out.normals, np.tile(np.float32([0, 1, 0]), (out.n_vertices, 1)))


def test_inside_out_result_is_a_backend_failure():
    cube = _parts()["seamed_cube"]
    ref = R.Reference(cube)
    work, _ = B.prepare(cube, "ignore")
    res = B.BackendResult(cube.positions.copy(), cube.indices.astype(np.int64)[:, ::-1].copy())
    with pytest.raises(B.BackendFailure, match="flipped"):
        X.transfer_attributes(res, ref, cube, work, "ignore", 0.02)
    # allowed to flip every face, the closed mesh's volume sign still rejects it
    with pytest.raises(B.BackendFailure, match="inside out"):
        X.transfer_attributes(res, ref, cube, work, "ignore", 1.0)


def test_chunks_partition_the_faces_and_box_them_and_candidates_hold_every_reach(monkeypatch):
    """``Reference.chunks``: every face in exactly one chunk, each chunk's box holding its faces'
    corners exactly (min and max attained); ``_candidates`` holds every point whose distance bound
    reaches a chunk's box, and few others where the chunks are spatially apart."""
    s = F.unit_sphere(5)[0]
    rng = np.random.default_rng(11)
    pos = s.positions * (1.0 + 0.03 * rng.standard_normal(s.positions.shape[0]))[:, None]
    part = MeshPart("bumpy", pos.astype(np.float32), s.indices.astype(np.uint32))
    monkeypatch.setattr(R, "CHUNK_FACES", part.n_triangles // 7)  # 8 chunks
    ref = R.Reference(part)
    chunks = ref.chunks
    assert len(chunks) == 8
    owner = np.full(ref.faces.shape[0], -1)
    for c, (ids, lo, hi) in enumerate(chunks):
        assert (owner[ids] == -1).all()
        owner[ids] = c
        corners = ref.positions[ref.faces[ids].ravel()]
        assert np.array_equal(lo, corners.min(axis=0)) and np.array_equal(hi, corners.max(axis=0))
    assert (owner >= 0).all()
    # points around the sphere, some far off it, with bounds from tiny to the whole sphere
    pts = rng.standard_normal((5000, 3)) * rng.uniform(0.2, 3.0, (5000, 1))
    best = rng.uniform(0.0, 1.0, 5000) ** 4
    for scale in (4.0, 1e-3):  # balls up to the sphere's size, then small ones
        b = best * scale
        cand = ref._candidates(pts, b)
        for c, (_, lo, hi) in enumerate(chunks):
            gap = np.maximum(np.maximum(lo - pts, pts - hi), 0.0)
            reach = np.flatnonzero((gap ** 2).sum(axis=1) <= b)
            assert np.isin(reach, cand[c]).all() and np.unique(cand[c]).size == cand[c].size
    # a flat 128 x 128 grid in 8 chunks, points just above it with small balls: a point is a
    # candidate of its own chunk and at most its neighbours'
    k = 129
    gx, gy = np.meshgrid(np.arange(k, dtype=np.float64), np.arange(k, dtype=np.float64))
    grid_pos = np.stack([gx.ravel(), gy.ravel(), np.zeros(k * k)], axis=1)
    v = (np.arange(k - 1)[None, :] + k * np.arange(k - 1)[:, None]).ravel()
    quads = np.stack([v, v + 1, v + k + 1, v + k], axis=1)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    flat = R.Reference(MeshPart("flat", grid_pos.astype(np.float32), tris.astype(np.uint32)))
    monkeypatch.setattr(R, "CHUNK_FACES", tris.shape[0] // 7)
    assert len(flat.chunks) == 8
    q = np.concatenate([rng.uniform(0, k - 1, (5000, 2)), rng.uniform(0, 0.5, (5000, 1))], axis=1)
    cand = flat._candidates(q, np.ones(5000))
    for c, (_, lo, hi) in enumerate(flat.chunks):
        gap = np.maximum(np.maximum(lo - q, q - hi), 0.0)
        assert np.isin(np.flatnonzero((gap ** 2).sum(axis=1) <= 1.0), cand[c]).all()
    assert sum(x.size for x in cand) <= 1.5 * q.shape[0]


def test_query_any_equals_the_whole_tree_without_building_it(monkeypatch):
    """``Reference.query_any`` above ``CHUNK_FACES``: the same squared distances and closest points
    as ``query``'s tree over all of LOD 0, for points on, near and far from the surface, with no
    whole tree built; at most ``CHUNK_FACES`` faces it is ``query`` itself."""
    s = F.unit_sphere(5)[0]
    rng = np.random.default_rng(5)
    pos = s.positions * (1.0 + 0.03 * rng.standard_normal(s.positions.shape[0]))[:, None]
    part = MeshPart("bumpy", pos.astype(np.float32), s.indices.astype(np.uint32))
    pts = np.concatenate([rng.standard_normal((3000, 3)) * rng.uniform(0.2, 3.0, (3000, 1)),
                          part.positions[:500].astype(np.float64)])  # vertices: distance 0
    monkeypatch.setenv("LOPCOOK_KERNELS", "off")  # the libigl trees (the kernels' oracle)
    d_all, f_all, c_all = R.Reference(part).query(pts)
    monkeypatch.setattr(R, "CHUNK_FACES", part.n_triangles // 7)  # 8 chunks
    ref = R.Reference(part)
    calls = {"near": 0, "bounded": 0}
    for name in calls:
        method = getattr(R.Reference, f"query_{name}")
        monkeypatch.setattr(R.Reference, f"query_{name}",
                            lambda self, *a, _m=method, _n=name, **k: (calls.__setitem__(_n, calls[_n] + 1), _m(self, *a, **k))[1])
    # many points: the chunk sweep; one per NEAR_POINTS_PER_FACE faces or fewer: the faces near them
    for sel in (slice(None), slice(2900, 2900 + part.n_triangles // R.NEAR_POINTS_PER_FACE)):
        d, f, c = ref.query_any(pts[sel])
        assert ref._tree is None  # no tree over all faces
        assert np.array_equal(d, d_all[sel]) and np.array_equal(c, c_all[sel])
        # another face only where it is as close: the same closest point lies on it
        tie = np.flatnonzero(f != f_all[sel])
        tri = ref.positions[ref.faces[f[tie]]].astype(np.float64)
        bary = X.barycentric(c[tie], tri, clamp=False)
        assert (bary > -1e-6).all()
        assert tie.size == 0 or np.abs(np.einsum("qk,qkd->qd", bary, tri) - c[tie]).max() < 1e-9
    assert calls["near"] == 1 and calls["bounded"] >= 1
    monkeypatch.setattr(R, "CHUNK_FACES", part.n_triangles)
    small = R.Reference(part)
    assert all(np.array_equal(u, v) for u, v in zip(small.query_any(pts), (d_all, f_all, c_all)))
    assert small._tree is not None
