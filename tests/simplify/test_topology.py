"""lopcook.simplify.topology: UV seam counts of known meshes, mesh defects (open, fin, bow-tie,
zero-area faces) and the signed volume, on the position-welded mesh."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support import fixtures as F
from lopcook.simplify import topology as T
from lopcook.types import MeshPart


def _part(positions, indices, name="crafted", **kw) -> MeshPart:
    return MeshPart(name=name, positions=np.asarray(positions, dtype=np.float64),
                    indices=np.asarray(indices, dtype=np.uint32), **kw)


@pytest.fixture(scope="module")
def cube() -> MeshPart:
    return F.seamed_cube()[0].as_mesh_part()


def test_seam_stats_of_the_seamed_cube(cube):
    # the cross atlas joins 5 of the 12 cube edges (-X|+Z, +Z|+X, +X|-Z in the row, +Y and -Y above
    # and below +Z): 7 seam edges, which touch all 8 corners; one island
    assert T.seam_stats(cube) == T.SeamStats(seam_edges=7, seam_vertices=8, uv_islands=1)


def test_seam_stats_with_every_face_its_own_island(cube):
    face = np.arange(cube.n_vertices) // 4  # 4 vertices per face, faces in order
    uvs = (cube.uvs + 2.0 * face[:, None]).astype(np.float32)
    got = T.seam_stats(_part(cube.positions, cube.indices, uvs=uvs))
    assert got == T.SeamStats(seam_edges=12, seam_vertices=8, uv_islands=6)


def test_seam_stats_of_a_seamless_plate_and_of_no_uvs():
    plate = F.two_plates()[0].as_mesh_part()
    assert T.seam_stats(plate) == T.SeamStats(seam_edges=0, seam_vertices=0, uv_islands=1)
    assert T.seam_stats(F.unit_sphere()[0].as_mesh_part()) is None
    assert T.seam_stats(plate).as_dict() == {"seam_edges": 0, "seam_vertices": 0, "uv_islands": 1}


def test_seam_stats_crafted():
    # a quad split along its diagonal, the two triangles in different UV islands
    p = _part([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [3, 4, 5]],
              uvs=np.array([[0, 0], [1, 0], [0, 1], [0.5, 0.5], [1, 1], [0.2, 0.9]], dtype=np.float32))
    assert T.seam_stats(p) == T.SeamStats(seam_edges=1, seam_vertices=2, uv_islands=2)
    q = _part(p.positions, p.indices, uvs=np.array([[0, 0], [1, 0], [0, 1], [1, 0], [1, 1], [0, 1]], np.float32))
    assert T.seam_stats(q) == T.SeamStats(seam_edges=0, seam_vertices=0, uv_islands=1)
    assert T.seam_stats(_part(p.positions, p.indices)) is None


def test_negative_zero_uv_is_not_a_seam():
    p = _part([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [3, 4, 5]],
              uvs=np.array([[0, 0], [1, 0], [0, 1], [1, -0.0], [1, 1], [-0.0, 1]], dtype=np.float32))
    assert T.seam_stats(p).seam_edges == 0


def test_defects_of_closed_and_open_meshes(cube):
    closed = {"degenerate_faces": 0, "boundary_edges": 0, "nonmanifold_edges": 0, "nonmanifold_vertices": 0,
              "closed": True}
    assert T.mesh_defects(cube.positions, cube.indices) == closed  # 24 split vertices weld to 8
    plate = F.two_plates()[0].as_mesh_part()
    d = T.mesh_defects(plate.positions, plate.indices)
    assert d == {**closed, "boundary_edges": 4 * 8, "closed": False}


def test_defects_fin_bowtie_and_zero_area():
    # three triangles on edge (0, 1): a fin; triangles (5, 6, 7) and (5, 9, 8) meet at vertex 5 only
    p = [[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1],
         [2, 0, 0], [3, 1, 0], [3, -1, 0], [1.2, 1, 0.2], [1.2, -1, 0.2]]
    f = [[0, 1, 2], [1, 0, 3], [0, 1, 4], [5, 6, 7], [5, 9, 8]]
    d = T.mesh_defects(np.asarray(p, float), np.asarray(f))
    assert d["nonmanifold_edges"] == 1 and d["nonmanifold_vertices"] == 1 and not d["closed"]
    # the fin's 6 outer edges and both bow-tie triangles' 3 edges each are used once
    assert d["boundary_edges"] == 6 + 6
    # a zero-area face is counted and left out of the edge counts
    f2 = f + [[0, 0, 1]]
    d2 = T.mesh_defects(np.asarray(p, float), np.asarray(f2))
    assert d2 == {**d, "degenerate_faces": 1}
    only = T.mesh_defects(np.asarray(p, float), np.array([[0, 0, 1], [2, 2, 2]]))
    assert only == {"degenerate_faces": 2, "boundary_edges": 0, "nonmanifold_edges": 0,
                    "nonmanifold_vertices": 0, "closed": False}


def _fans_direct(positions, faces) -> int:
    """Bow-tie vertices counted directly: per welded vertex, its non-degenerate faces joined when
    they share an edge at that vertex (a union-find per vertex); more than one group is a bow-tie."""
    _, key = np.unique(np.asarray(positions), axis=0, return_inverse=True)
    w = key.ravel()[np.asarray(faces)]
    area = np.linalg.norm(np.cross(positions[faces[:, 1]] - positions[faces[:, 0]],
                                   positions[faces[:, 2]] - positions[faces[:, 0]]), axis=1)
    faces_at: dict = {}
    for f, tri in enumerate(w.tolist()):
        if area[f] > 0 and len(set(tri)) == 3:
            for v in tri:
                faces_at.setdefault(v, []).append(f)
    bowties = 0
    for v, fs in faces_at.items():
        parent = {f: f for f in fs}

        def root(f):
            while parent[f] != f:
                f = parent[f]
            return f
        for i, f in enumerate(fs):
            for g in fs[i + 1:]:
                if len(set(w[f].tolist()) & set(w[g].tolist())) >= 2:  # an edge at v
                    parent[root(f)] = root(g)
        bowties += len({root(f) for f in fs}) > 1
    return bowties


def test_bowties_of_closed_fans_and_random_soups_match_a_direct_count():
    # two tetrahedra touching at one vertex: every edge has two oppositely oriented faces, yet the
    # shared vertex has two closed fans (the walk around it comes back after half its corners)
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float)
    two = np.concatenate([tet, np.array([[0, 4, 5], [0, 6, 4], [4, 6, 5], [0, 5, 6]])])
    assert T.mesh_defects(p, tet)["nonmanifold_vertices"] == 0
    d = T.mesh_defects(p, two)
    assert d == {"degenerate_faces": 0, "boundary_edges": 0, "nonmanifold_edges": 0, "nonmanifold_vertices": 1,
                 "closed": True}
    rng = np.random.default_rng(7)
    seen = 0
    for _ in range(200):
        n, m = int(rng.integers(4, 30)), int(rng.integers(1, 60))
        pos = rng.integers(0, 3, size=(n, 3)).astype(float)
        fac = rng.integers(0, n, size=(m, 3))
        want = _fans_direct(pos, fac)
        assert T.mesh_defects(pos, fac)["nonmanifold_vertices"] == want
        seen += want > 0
    assert seen > 50  # the soups do have bow-ties


def test_signed_volume(cube):
    f = cube.indices.astype(np.int64)
    assert T.signed_volume(cube.positions, f) == pytest.approx(1.0, rel=1e-15)
    assert T.signed_volume(cube.positions, f[:, ::-1]) == pytest.approx(-1.0, rel=1e-15)  # inside out
    box = cube.positions * [2.0, 3.0, 4.0] + [10.0, -5.0, 100.0]  # scaled and moved far off the origin
    assert T.signed_volume(box, f) == pytest.approx(24.0, rel=1e-12)
    plate = F.two_plates()[0].as_mesh_part()
    assert T.signed_volume(plate.positions, plate.indices.astype(np.int64)) == 0.0  # a flat sheet
