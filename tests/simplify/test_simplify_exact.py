"""Exact attribute copy for LODs whose vertices are LOD 0 vertices (meshoptimizer), and the
recorded error bound (lopcook.simplify.transfer.exact_sources, exact_corner_sources)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import position_ids
from lopcook.ingest import load
from lopcook.mesh import face_normals, unique_rows
from lopcook.simplify import chain as L
from lopcook.simplify import reference as R
from lopcook.simplify import transfer as T
from lopcook.simplify.backends import check_result, prepare, run_backend
from lopcook.types import MeshPart

ATTRS = ("normals", "uvs", "colors")


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


def assert_copied(lod: MeshPart, src: MeshPart) -> int:
    """Every LOD vertex is a referenced LOD 0 vertex by position, bit for bit, and its normals,
    UVs and colours are bit for bit those of one LOD 0 vertex at that position (the only one
    where there is one). Returns the number of LOD vertices at co-located LOD 0 vertices."""
    used = np.unique(src.indices)
    ids_src, ids_lod = position_ids(src.positions[used], lod.positions)
    # every LOD position is exactly a LOD 0 vertex's
    assert np.isin(ids_lod, ids_src).all()
    order = np.argsort(ids_src, kind="stable")
    lo = np.searchsorted(ids_src[order], ids_lod, side="left")
    hi = np.searchsorted(ids_src[order], ids_lod, side="right")
    names = [n for n in ATTRS if getattr(lod, n) is not None and getattr(src, n) is not None]
    for i in range(lod.n_vertices):  # a test-side loop: the reference check, not a hot path
        cands = used[order[lo[i]:hi[i]]]
        match = np.ones(cands.size, dtype=bool)
        for n in names:
            match &= (_bits(getattr(src, n)[cands]) == _bits(getattr(lod, n)[i])).all(axis=1)
        assert match.any(), (i, cands)
    return int(((hi - lo) > 1).sum())


def assert_error_bound(lod: L.Lod, src: MeshPart):
    """``error_bound_m`` bounds the distance from every LOD vertex and face centroid to LOD 0 and
    from every LOD 0 vertex to the LOD (queried exhaustively here); the LOD -> LOD 0 distance
    recorded is the centroids' maximum, the vertices being at distance 0."""
    p, f = lod.part.positions, lod.part.indices.astype(np.int64)
    fs = src.indices.astype(np.int64)
    dv = R.point_mesh(p, src.positions, fs)[0]
    assert dv.max() <= 1e-30  # the vertices lie on LOD 0 (they are LOD 0 vertices)
    dc = np.sqrt(R.point_mesh(p[f].mean(axis=1), src.positions, fs)[0])
    d0 = np.sqrt(R.point_mesh(src.positions[np.unique(fs)], p, f)[0])
    worst = max(float(dc.max()), float(d0.max()))
    assert lod.error_bound_m >= worst * (1 - 1e-12), (lod.error_bound_m, worst)
    assert lod.hausdorff_m <= lod.error_bound_m
    assert lod.one_sided_m[0] == pytest.approx(float(dc.max()), rel=1e-9, abs=1e-15)


@pytest.mark.parametrize("name, seams", [("fandisk.obj", "auto"), ("spot.obj", "auto"), ("Duck.glb", "auto"),
                                         ("DamagedHelmet/DamagedHelmet.gltf", "auto"),
                                         ("DamagedHelmet/DamagedHelmet.gltf", "ignore"),
                                         ("stanford-bunny.obj", "auto")])
def test_meshopt_chain_copies_attributes_exactly(corpus, name, seams):
    part = load(corpus / name).parts[0]
    lods, _ = L.lod_chain(part, [0.5, 0.25, 0.125, 0.0625], backend="meshopt", seams=seams, fallback=False)
    assert len(lods) >= 4
    colocated = 0
    for lod in lods[1:]:
        assert lod.backend == "meshopt"
        colocated += assert_copied(lod.part, part)
        assert_error_bound(lod, part)
    if name in ("fandisk.obj", "DamagedHelmet/DamagedHelmet.gltf", "spot.obj"):
        assert colocated > 0  # the co-located choice was exercised (creases, UV seams)


def _folded_sheet(n: int = 24):
    """Two unit squares meeting at a right angle along x = 0 (z = 0 and x = 0 planes), the crease
    vertices split: each side has its own normal, as ingest's crease split gives."""
    t = np.linspace(0.0, 1.0, n + 1)
    gy, gx = np.meshgrid(t, t, indexing="ij")
    flat = np.stack([-gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)  # x <= 0, z = 0
    wall = np.stack([np.zeros(gx.size), gy.ravel(), gx.ravel()], axis=1)    # x = 0, z >= 0
    idx = np.arange(gx.size).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    quads = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    f_flat = quads[:, ::-1]  # faces up (+z)
    f_wall = quads + gx.size
    positions = np.concatenate([flat, wall])
    faces = np.concatenate([f_flat, f_wall])
    fn = face_normals(positions, faces)
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    normals = np.zeros_like(positions)
    np.add.at(normals, faces.ravel(), np.repeat(fn, 3, axis=0))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return MeshPart(name="fold", positions=positions, indices=faces.astype(np.uint32),
                    normals=normals.astype(np.float32))


def test_colocated_corners_take_their_own_side():
    part = _folded_sheet()
    lods, _ = L.lod_chain(part, [0.5, 0.25, 0.125], backend="meshopt", seams="auto", fallback=False)
    assert len(lods) == 4
    for lod in lods[1:]:
        assert assert_copied(lod.part, part) > 0
        p, f = lod.part.positions, lod.part.indices.astype(np.int64)
        fn = face_normals(p, f)
        fn /= np.linalg.norm(fn, axis=1, keepdims=True)
        corner_n = lod.part.normals[f.ravel()].astype(np.float64)
        # the two sides are 90 degrees apart: every corner has its own face's side normal
        np.testing.assert_allclose(np.einsum("ij,ij->i", corner_n, np.repeat(fn, 3, axis=0)), 1.0, atol=1e-6)
        assert_error_bound(lod, part)


def test_exact_vertex_key_equals_generic_key(corpus):
    # the two-column key gives the same vertices, numbered alike, as the generic per-corner bit rows
    part = load(corpus / "fandisk.obj").parts[0]
    ref = R.Reference(part)
    work, _ = prepare(part, "ignore")
    target = part.n_triangles // 4
    res, _ = check_result(run_backend("meshopt", work, target, True, True), target, work.faces.shape[0])
    found = T.exact_sources(ref, res.positions)
    assert found is not None and (found[0] > 1).any()
    cen = res.positions[res.faces].mean(axis=1)
    srcv = T.exact_corner_sources(ref, ["normals"], res.positions, res.faces, cen, found)
    vid = res.faces.ravel()
    attr = {"normals": part.normals[srcv]}
    first, inv = T._exact_vertex_key(vid, srcv, found, attr, ["normals"])
    g_first, g_inv = unique_rows(np.concatenate([vid.reshape(-1, 1).astype(np.int64), T._bits(attr["normals"])],
                                                axis=1))
    np.testing.assert_array_equal(first, g_first)
    np.testing.assert_array_equal(inv, g_inv)


def test_moved_vertices_keep_the_closest_point_transfer(corpus):
    # fast-simplification moves vertices: no exact sources, and exact=True changes nothing
    part = load(corpus / "stanford-bunny.obj").parts[0]
    ref = R.Reference(part)
    work, _ = prepare(part, "ignore")
    target = part.n_triangles // 4
    res, _ = check_result(run_backend("fast", work, target, True, True), target, work.faces.shape[0])
    assert T.exact_sources(ref, res.positions) is None
    a, ia = T.transfer_attributes(res, ref, part, work, "-", L.MAX_FLIPPED_FRACTION, exact=True)
    b, ib = T.transfer_attributes(res, ref, part, work, "-", L.MAX_FLIPPED_FRACTION, exact=False)
    assert ia == ib
    for n in ("positions", "indices", "normals"):
        np.testing.assert_array_equal(getattr(a, n), getattr(b, n))


def test_exact_sources_rejects_a_moved_vertex():
    part = _folded_sheet(4)
    ref = R.Reference(part)
    p = part.positions[np.unique(part.indices)].copy()
    found = T.exact_sources(ref, p)
    assert found is not None
    assert found[0].max() == 2 and found[0].min() == 1  # crease vertices: two copies
    p[3, 0] = np.nextafter(p[3, 0], 1.0)  # one ulp off: not a LOD 0 vertex
    assert T.exact_sources(ref, p) is None


def test_query_bounded_equals_query(corpus, monkeypatch):
    # chunked trees give the closest distances of the one tree over all of LOD 0
    part = load(corpus / "stanford-bunny.obj").parts[0]
    monkeypatch.setenv("LOPCOOK_KERNELS", "off")  # the libigl trees (the kernels' oracle)
    monkeypatch.setattr(R, "CHUNK_FACES", 4096)  # 17 chunks
    ref = R.Reference(part)
    assert len(ref.chunks) == 2 ** int(np.ceil(np.log2(ref.faces.shape[0] / 4096)))  # 32 chunks
    assert np.array_equal(np.sort(np.concatenate([c[0] for c in ref.chunks])), np.arange(ref.faces.shape[0]))
    rng = np.random.default_rng(3)
    v = rng.integers(0, part.n_vertices, 20000)
    pts = part.positions[v] + rng.normal(0.0, 2e-3, (v.size, 3))
    bound = ((pts - part.positions[v]) ** 2).sum(axis=1)  # the vertex is on LOD 0
    d, f, c = ref.query_bounded(pts, bound)
    d0, f0, c0 = ref.query(pts)
    np.testing.assert_allclose(d, d0, rtol=1e-12, atol=1e-30)
    np.testing.assert_allclose(c, c0, atol=1e-12)
    # the point found lies on the face found, at the distance returned
    tri = part.positions[ref.faces[f]]
    bary = T.barycentric(c, tri, clamp=False)
    assert bary.min() >= -1e-6
    np.testing.assert_allclose(np.einsum("qk,qkd->qd", bary, tri), c, atol=1e-12)
    np.testing.assert_allclose(((pts - c) ** 2).sum(axis=1), d, rtol=1e-9, atol=1e-30)
    with pytest.raises(ValueError):
        ref.query_bounded(pts[:100], np.zeros(100) - 1.0)


def test_query_near_equals_query(corpus, monkeypatch):
    # the faces around the vertices within reach hold the closest point: same distances
    part = load(corpus / "stanford-bunny.obj").parts[0]
    monkeypatch.setenv("LOPCOOK_KERNELS", "off")  # the libigl trees (the kernels' oracle)
    monkeypatch.setattr(R, "CHUNK_FACES", 4096)
    ref = R.Reference(part)
    rng = np.random.default_rng(5)
    v = rng.integers(0, part.n_vertices, 3000)
    pts = part.positions[v] + rng.normal(0.0, 1e-3, (v.size, 3))
    bound = ((pts - part.positions[v]) ** 2).sum(axis=1)
    import igl

    groups = []
    whole = igl.point_mesh_squared_distance

    def counted(q, p, f):
        assert f.shape[0] <= 4096  # each group's faces within the chunk size
        groups.append(q.shape[0])
        return whole(q, p, f)

    def no_sweep(*_a, **_k):
        raise AssertionError("query_near fell back to the chunked sweep")

    monkeypatch.setattr(igl, "point_mesh_squared_distance", counted)
    monkeypatch.setattr(ref, "query_bounded", no_sweep)
    d, f, c = ref.query_near(pts, bound)
    monkeypatch.undo()
    # 3000 points' faces are more than 4096: split into groups, every point in exactly one
    assert len(groups) > 1 and sum(groups) == pts.shape[0]
    d0, _, _ = ref.query(pts)
    np.testing.assert_allclose(d, d0, rtol=1e-12, atol=1e-30)
    tri = part.positions[ref.faces[f]]
    np.testing.assert_allclose(np.einsum("qk,qkd->qd", T.barycentric(c, tri, clamp=False), tri), c, atol=1e-12)
    assert ref._near is not None  # the KD-tree path ran (not the chunked fallback)


@pytest.mark.parametrize("name", ["fandisk.obj", "DamagedHelmet/DamagedHelmet.gltf", "spot.obj"])
def test_weld_first_equals_weld_exact(corpus, name):
    from lopcook.mesh import weld_exact
    from lopcook.simplify.backends import weld_first

    p = load(corpus / name).parts[0].positions
    for pos in (p, np.concatenate([p, p[::-1], -0.0 * p[:5]])):  # repeats, and -0.0 against 0.0
        np.testing.assert_array_equal(weld_first(pos), weld_exact(pos)[0])
    assert weld_first(np.zeros((0, 3))).size == 0
