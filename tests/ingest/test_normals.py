"""Computed normals (lopcook.ingest.normals): analytic sphere, crease splits, seams, degenerates."""

import numpy as np
import pytest
import trimesh

from lopcook.ingest.normals import compute_normals


def test_cube_splits_at_creases_and_is_smooth_at_180():
    box = trimesh.creation.box()
    sharp = compute_normals(box.vertices, box.faces, 60.0)
    assert len(sharp.source_vertex) == 24  # 8 corners x 3 faces
    # every new vertex's normal is one of the 6 axis directions
    assert np.allclose(np.abs(sharp.normals).max(axis=1), 1.0)
    smooth = compute_normals(box.vertices, box.faces, 180.0)
    assert len(smooth.source_vertex) == 8
    assert np.all(np.abs(smooth.normals).min(axis=1) > 0.2)  # blended across faces


def test_sphere_normals_converge_to_radial():
    errs = []
    for sub in (3, 4, 5):
        s = trimesh.creation.icosphere(sub)
        r = compute_normals(s.vertices, s.faces, 60.0)
        assert len(r.source_vertex) == len(s.vertices)  # no creases on a sphere
        radial = s.vertices[r.source_vertex] / np.linalg.norm(s.vertices[r.source_vertex], axis=1)[:, None]
        errs.append(np.abs(r.normals - radial).max())
    assert errs[0] > errs[1] > errs[2] and errs[2] < 5e-3


def test_uv_seam_duplicates_share_the_normal():
    s = trimesh.creation.icosphere(3)
    # duplicate every vertex of the first 40 faces (as a UV seam would), positions identical
    v = np.vstack([s.vertices, s.vertices])
    f = s.faces.copy()
    f[:40] += len(s.vertices)
    r = compute_normals(v, f, 60.0)
    ref = compute_normals(s.vertices, s.faces, 60.0)
    used = np.unique(f)
    # each used original vertex keeps one copy, with the normal of the welded mesh
    got = {int(sv): n for sv, n in zip(r.source_vertex, r.normals)}
    for u in used:
        np.testing.assert_allclose(got[int(u)], ref.normals[int(u) % len(s.vertices)], atol=1e-6)


def test_degenerate_triangles_give_finite_unit_directions():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [2, 0, 0]], float)
    f = np.array([[0, 1, 2], [1, 3, 4]])  # second triangle has zero area
    r = compute_normals(v, f, 60.0)
    assert np.isfinite(r.normals).all()
    np.testing.assert_allclose(np.linalg.norm(r.normals, axis=1), 1.0, atol=1e-6)
    assert r.fallback == 2  # vertices 3 and 4 touch only the zero-area triangle
    assert len(r.source_vertex) == 5  # the sliver does not split vertex 1


@pytest.mark.parametrize("angle", [10.0, 60.0, 100.0])
def test_crease_threshold(angle):
    # two triangles folded by 45 degrees along the shared edge (0,1)
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -np.cos(np.pi / 4), -np.sin(np.pi / 4)]], float)
    f = np.array([[0, 1, 2], [1, 0, 3]])
    r = compute_normals(v, f, angle)
    expect = 6 if angle < 45 else 4
    assert len(r.source_vertex) == expect
