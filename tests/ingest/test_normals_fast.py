"""The fast computed-normals path is bit-identical to the direct formulation it replaced.

``reference_normals`` below is that formulation, kept here only as the reference (it is not used by
lopcook): welded half-edges sorted with argsort, corner groups by scipy connected components, new
vertices numbered through np.unique. The container bytes depend on the normals, so every output
array must match exactly, on corpus meshes, fixtures and constructed edge cases (inconsistent
orientation, bowtie vertices, degenerate and duplicated triangles, non-manifold edges, unused
vertices) at several crease angles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from lopcook.ingest import load
from lopcook.ingest.normals import compute_normals
from lopcook.mesh import face_normals
from lopcook import mesh as mesh_module
from lopcook.mesh import weld_exact

REPO = Path(__file__).resolve().parents[2]
ANGLES = (0.0, 30.0, 60.0, 89.5, 179.0, 180.0)


# ---- reference: the previous implementation, verbatim apart from names ------------------------

def _ref_face_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(m, 3) float64 cross products (p1 - p0) x (p2 - p0): direction = normal, length = 2 * area."""
    p0 = positions[indices[:, 0]]  # three (m, 3) gathers: no (m, 3, 3) temporary
    return np.cross(positions[indices[:, 1]] - p0, positions[indices[:, 2]] - p0)


def _ref_group_sum(group: np.ndarray, face_values: np.ndarray, size: int) -> np.ndarray:
    """(size, 3) sums per group id of the values of each corner's face: corner c (of face c // 3)
    adds ``face_values[c // 3]`` (m, 3) to ``group[c]``. One bincount per column, corners in
    order (the summation order of a (3m, 3) array of repeated rows, without building it)."""
    return np.stack([np.bincount(group, weights=np.repeat(face_values[:, k], 3), minlength=size)
                     for k in range(3)], axis=1)


# half-edge pairs handled per step of the dihedral test ((k, 3) float64 temporaries)
_REF_CHUNK = 1 << 18


def reference_normals(positions, indices, crease_angle_deg=60.0):
    """The direct formulation (lopcook before the fast path): scipy components, np.unique."""
    n = positions.shape[0]
    tri = np.asarray(indices, dtype=np.int64)
    m = tri.shape[0]
    c = 3 * m
    small = max(c, n) < (1 << 31) - 1
    cid = np.int32 if small else np.int64  # corner / vertex ids
    weld, _ = weld_exact(positions)
    wtri = weld.astype(cid)[tri]  # (m, 3) welded vertex per corner
    del weld
    fn = _ref_face_normals(positions, tri)
    flen = np.linalg.norm(fn, axis=1)
    degenerate = flen <= 1e-300
    unit = np.where(degenerate[:, None], 0.0, fn / np.where(degenerate, 1.0, flen)[:, None])
    del flen

    # half-edges: corner h = 3f + k of face f goes from wtri[f, k] to wtri[f, (k+1) % 3]
    a = wtri.ravel()
    b = wtri[:, [1, 2, 0]].ravel()
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    del b
    valid = np.flatnonzero(lo != hi)
    # sort half-edges by undirected key (lo, hi); order within a key does not matter (links are
    # symmetric), so the faster unstable sort is fine and the result is still deterministic
    key = lo[valid].astype(np.int64) * np.int64(max(int(a.max()) + 1 if c else 1, 1)) + hi[valid]
    del lo, hi
    srt = np.argsort(key)
    key = key[srt]
    order = valid[srt].astype(cid)
    del srt, valid
    same_next = key[:-1] == key[1:]
    del key
    # manifold edges: exactly two half-edges with this key
    starts = np.flatnonzero(np.r_[True, ~same_next])
    del same_next
    sizes = np.diff(np.r_[starts, order.size])
    pair = starts[sizes == 2]
    del starts, sizes
    h1, h2 = order[pair], order[pair + 1]
    del order, pair
    f1, f2 = h1 // 3, h2 // 3
    cos_limit = np.cos(np.radians(crease_angle_deg))
    if crease_angle_deg >= 180.0:
        smooth = np.ones(h1.size, dtype=bool)
    else:
        smooth = np.empty(h1.size, dtype=bool)
        for s0 in range(0, h1.size, _REF_CHUNK):  # (k, 3) gathers, not (pairs, 3)
            g1, g2 = f1[s0:s0 + _REF_CHUNK], f2[s0:s0 + _REF_CHUNK]
            smooth[s0:s0 + _REF_CHUNK] = ((np.einsum("ij,ij->i", unit[g1], unit[g2]) >= cos_limit - 1e-12)
                                      | degenerate[g1] | degenerate[g2])
    del unit, f1, f2, degenerate
    h1, h2 = h1[smooth], h2[smooth]
    del smooth
    # link the corners at the same welded vertex: corner of h1 at a matches the corner of h2 at a
    same_dir = a[h1] == a[h2]  # consistently oriented neighbours have opposite half-edges
    cb1 = h1 - h1 % 3 + (h1 % 3 + 1) % 3  # corner at the other end of half-edge h1
    cb2 = h2 - h2 % 3 + (h2 % 3 + 1) % 3
    link_u = np.concatenate([h1, cb1])
    link_v = np.concatenate([np.where(same_dir, h2, cb2), np.where(same_dir, cb2, h2)])
    del h1, h2, cb1, cb2, same_dir
    graph = coo_matrix((np.ones(link_u.size, dtype=np.int8), (link_u, link_v)), shape=(c, c))
    del link_u, link_v
    _, group = connected_components(graph, directed=False)
    del graph
    n_groups = int(group.max()) + 1 if group.size else 0

    # a group made only of zero-area triangles has no direction: merge its corners into another
    # group of the same welded vertex that has one (so degenerate slivers do not split vertices)
    gsum = _ref_group_sum(group, fn, n_groups)
    good = (np.linalg.norm(gsum, axis=1) > 1e-300)[group]
    if not good.all():
        wv = a
        donor = np.full(int(wv.max()) + 1 if m else 0, np.iinfo(np.int64).max, dtype=np.int64)
        np.minimum.at(donor, wv[good], group[good])
        take = ~good & (donor[wv] != np.iinfo(np.int64).max)
        if take.any():
            group = np.where(take, donor[wv], group)
            gsum = _ref_group_sum(group, fn, int(group.max()) + 1)
        del donor, take
    del good, a, wtri, fn

    # new vertex = (original vertex, corner group); number them by first corner appearance
    ov = tri.ravel()
    key = ov * np.int64(c + 1) + group
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    del key
    ovf = ov[first]
    order_new = np.argsort(ovf * np.int64(c + 1) + first, kind="stable")
    rank = np.empty_like(order_new)
    rank[order_new] = np.arange(order_new.size)
    new_index = rank[inverse.ravel()]
    del inverse, rank
    source_vertex = ovf[order_new]

    # area-weighted normals per group, then per new vertex
    first_corner = first[order_new]
    normals = gsum[group[first_corner]]
    del gsum, group

    # unused vertices keep a copy (so indices of used vertices and counts stay explainable)
    used = np.zeros(n, dtype=bool)
    used[ov] = True
    unused = np.flatnonzero(~used)
    if unused.size:
        source_vertex = np.concatenate([source_vertex, unused])
        normals = np.concatenate([normals, np.zeros((unused.size, 3))])
    length = np.linalg.norm(normals, axis=1)
    bad = length <= 1e-300
    normals = np.where(bad[:, None], np.array([0.0, 1.0, 0.0]), normals / np.where(bad, 1.0, length)[:, None])
    return dict(
        indices=new_index.reshape(m, 3).astype(np.uint32),
        source_vertex=source_vertex.astype(np.int64),
        normals=normals.astype(np.float32),
        fallback=int(np.count_nonzero(bad)),
    )


# ---- comparison -------------------------------------------------------------------------------

def assert_identical(positions, indices, angle):
    ref = reference_normals(positions, indices, angle)
    got = compute_normals(positions, indices, angle)
    assert got.indices.dtype == ref["indices"].dtype and got.indices.shape == ref["indices"].shape
    assert np.array_equal(got.indices, ref["indices"])
    assert got.source_vertex.dtype == ref["source_vertex"].dtype
    assert np.array_equal(got.source_vertex, ref["source_vertex"])
    assert got.normals.dtype == np.float32 and got.normals.tobytes() == ref["normals"].tobytes()
    assert got.fallback == ref["fallback"]
    return got


CORPUS_MESHES = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
                 "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd"]


@pytest.mark.parametrize("name", CORPUS_MESHES)
def test_corpus_meshes_bit_identical(corpus, name):
    # the ingested parts (positions already split at seams and creases: many co-located vertices)
    scene = load(corpus / name)
    for part in scene.parts:
        for angle in ANGLES:
            assert_identical(part.positions, part.indices, angle)


def test_corpus_obj_raw_topology_bit_identical(corpus):
    # the files' own vertices, before any split (one vertex per position on the scans)
    for name in ("stanford-bunny.obj", "fandisk.obj", "spot.obj"):
        mesh = trimesh.load(corpus / name, process=False, force="mesh")
        for angle in ANGLES:
            assert_identical(np.asarray(mesh.vertices, float), np.asarray(mesh.faces), angle)


def test_chess_pieces_bit_identical(corpus):
    scene = load(corpus / "chess_set_flat.usdc")
    parts = sorted(scene.parts, key=lambda p: p.name)[:6]
    for part in parts:
        for angle in (30.0, 60.0, 180.0):
            assert_identical(part.positions, part.indices, angle)


@pytest.mark.parametrize("path", sorted((REPO / "fixtures").glob("*.glb")) + sorted((REPO / "fixtures").glob("*.obj")),
                         ids=lambda p: p.name)
def test_fixtures_bit_identical(path):
    for part in load(path).parts:
        for angle in ANGLES:
            assert_identical(part.positions, part.indices, angle)


def test_inconsistent_orientation_takes_the_general_path_and_matches():
    s = trimesh.creation.icosphere(4)
    f = np.array(s.faces)
    f[::5] = f[::5, ::-1]  # flipped neighbours: same-direction half-edges
    for angle in ANGLES:
        assert_identical(np.asarray(s.vertices), f, angle)


def test_bowtie_vertex_splits_and_matches():
    # two closed cones sharing their apex (vertex 0): every apex edge is smooth and manifold,
    # yet the apex corners form two fans, so the apex gets two vertices
    k = 7
    ring = np.linspace(0, 2 * np.pi, k, endpoint=False)
    top = np.c_[np.cos(ring), np.full(k, 1.0), np.sin(ring)]
    bot = np.c_[np.cos(ring), np.full(k, -1.0), np.sin(ring)]
    v = np.vstack([[0.0, 0.0, 0.0], top, bot, [0.0, 2.0, 0.0], [0.0, -2.0, 0.0]])
    faces = []
    for i in range(k):
        j = (i + 1) % k
        faces += [[0, 1 + j, 1 + i], [1 + i, 1 + j, 2 * k + 1]]  # upper cone, closed by a cap apex
        faces += [[0, 1 + k + i, 1 + k + j], [1 + k + j, 1 + k + i, 2 * k + 2]]  # lower cone
    f = np.array(faces)
    for angle in (60.0, 100.0, 180.0):
        got = assert_identical(v, f, angle)
        assert np.count_nonzero(got.source_vertex == 0) == 2


def test_degenerate_duplicated_and_nonmanifold_match():
    rng = np.random.default_rng(7)
    s = trimesh.creation.icosphere(3)
    v = np.asarray(s.vertices)
    f = np.array(s.faces)
    extra = np.array([[0, 0, 1], [2, 3, 3], f[10], f[11][::-1], [f[20][0], f[20][1], f[30][2]]])
    f = np.vstack([f, extra])  # repeated indices, a duplicated face, a flipped copy, non-manifold edges
    v2 = np.vstack([v, v[:5], v[5:6] * 1.0])  # unused and co-located vertices
    f2 = f.copy()
    f2[rng.integers(0, len(f), 30), 0] = len(v) + rng.integers(0, 5, 30)
    for angle in ANGLES:
        assert_identical(v, f, angle)
        assert_identical(v2, f2, angle)
    # zero-area triangles only on one side of a crease (the sliver groups merge into a donor)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [2, 0, 0], [0, 0, 1]], float)
    ff = np.array([[0, 1, 2], [1, 3, 4], [0, 5, 1], [1, 4, 2]])
    for angle in ANGLES:
        assert_identical(flat, ff, angle)


def test_random_soups_and_open_patches_match():
    rng = np.random.default_rng(11)
    for trial in range(4):
        grid = trimesh.creation.box().subdivide().subdivide() if trial % 2 else trimesh.creation.cylinder(1.0, 2.0, 24)
        v = np.asarray(grid.vertices) + rng.normal(scale=0.02, size=grid.vertices.shape)
        f = np.asarray(grid.faces)
        keep = rng.random(len(f)) > 0.1  # holes: boundary vertices and open fans
        for angle in (10.0, 45.0, 60.0, 120.0):
            assert_identical(v, f[keep], angle)


def test_empty_and_unused_vertices_match():
    v = np.random.default_rng(3).normal(size=(6, 3))
    for angle in (0.0, 60.0, 180.0):
        assert_identical(v, np.zeros((0, 3), np.int64), angle)
        assert_identical(v, np.array([[0, 1, 2]]), angle)


def test_face_normals_unchanged():
    s = trimesh.creation.icosphere(3)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    assert np.array_equal(face_normals(v, f), _ref_face_normals(v, f))


def test_fallbacks_match(monkeypatch):
    # the exact weld after a hash collision, the argsort when packed keys would not fit in 63
    # bits, and the general grouping for long fans: forced on small meshes, same bits
    import lopcook.ingest.normals as N

    s = trimesh.creation.icosphere(3)
    v, f = np.vstack([s.vertices, s.vertices[:20]]), np.array(s.faces)
    f[:15] = np.where(f[:15] < 20, f[:15] + len(s.vertices), f[:15])  # co-located duplicates
    monkeypatch.setattr(mesh_module, "_fmix", lambda h: h * np.uint64(0))  # every position collides
    monkeypatch.setattr(N, "_PACK_BITS", 0)
    monkeypatch.setattr(N, "_MAX_WALK", 2)
    for angle in (30.0, 60.0, 180.0):
        assert_identical(v, f, angle)
