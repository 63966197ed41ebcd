"""E_t / E_v (lopcook.analyse.attribute_error) against analytic cases and an independent SVD."""

import numpy as np
import pytest
import trimesh

from lopcook.analyse.attribute_error import triangle_gradient_norm, vertex_attribute_error


def paper_e_t(positions, indices, attribute):
    """Independent: build A and M exactly as the paper (section 5.1) and take the spectral norm."""
    out = np.zeros(len(indices))
    for k, (i0, i1, i2) in enumerate(indices):
        v0, v1, v2 = positions[[i0, i1, i2]]
        a0, a1, a2 = attribute[[i0, i1, i2]].astype(np.float64)
        l1, l2 = np.linalg.norm(v1 - v0), np.linalg.norm(v2 - v0)
        cosphi = np.dot(v1 - v0, v2 - v0) / (l1 * l2)
        phi = np.arccos(np.clip(cosphi, -1, 1))
        M = np.array([[l1, l2 * np.cos(phi)], [0.0, l2 * np.sin(phi)]])
        A = np.stack([a1 - a0, a2 - a0], axis=1)
        out[k] = np.linalg.norm(A @ np.linalg.inv(M), 2)
    return out


@pytest.mark.parametrize("radius", [0.25, 1.0, 3.0])
def test_sphere_with_exact_normals_has_ev_one_over_r(radius):
    s = trimesh.creation.icosphere(3, radius=radius)
    v = np.asarray(s.vertices, dtype=np.float64)
    v = v / np.linalg.norm(v, axis=1)[:, None] * radius  # exactly on the sphere (to 1 ulp)
    n64 = v / radius
    # exact (float64) radial normals: the interpolated normal is p / r on the flat triangle, whose
    # in-plane gradient has spectral norm exactly 1/r; only rounding remains
    ev, deg = vertex_attribute_error(v, s.faces, n64)
    assert deg == 0
    np.testing.assert_allclose(ev * radius, 1.0, rtol=1e-12)
    # float32 normals: |delta a| <= 2^-24 per component; ||delta A M^-1|| <= 2*sqrt(3)*2^-24 / h_min
    # (h_min = smallest altitude), relative to 1/r:
    tri = v[s.faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    longest = np.max([np.linalg.norm(tri[:, i] - tri[:, (i + 1) % 3], axis=1) for i in range(3)], axis=0)
    h_min = (area2 / longest).min()
    tol = 2 * 2 * np.sqrt(3) * 2.0**-24 * radius / h_min
    ev32, _ = vertex_attribute_error(v, s.faces, n64.astype(np.float32))
    assert np.abs(ev32 * radius - 1.0).max() <= tol


def test_flat_plane_has_zero_error():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], float)
    f = np.array([[0, 2, 1], [0, 3, 2]])
    n = np.tile([0.0, 1.0, 0.0], (4, 1))
    ev, deg = vertex_attribute_error(v, f, n)
    assert deg == 0 and np.all(ev == 0.0)


@pytest.mark.parametrize("s", [0.01, 1.0, 250.0])
def test_uv_quad_scaled_by_s(s):
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * s
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = (np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) * [1.0, 3.0]).astype(np.float32)
    ev, _ = vertex_attribute_error(v, f, uv)
    # uv = (x/s, 3y/s): gradient diag(1/s, 3/s), spectral norm 3/s
    np.testing.assert_allclose(ev, 3.0 / s, rtol=1e-12)


def test_matches_paper_construction_on_random_triangles(rng):
    v = rng.normal(size=(60, 3))
    f = rng.integers(0, 60, size=(200, 3))
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    a = rng.normal(size=(60, 4))
    e_t, deg = triangle_gradient_norm(v, f, a)
    assert not deg.any()
    np.testing.assert_allclose(e_t, paper_e_t(v, f, a), rtol=1e-9)


def test_degenerate_triangles_are_excluded_and_counted():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [5, 5, 5]], float)
    f = np.array([[0, 1, 2], [1, 3, 4], [5, 5, 5], [0, 1, 1]])  # collinear, a point, a repeated index
    a = np.array([[0.0], [1.0], [0.0], [100.0], [-100.0], [7.0]])
    ev, deg = vertex_attribute_error(v, f, a)
    assert deg == 3
    assert np.isfinite(ev).all()
    assert ev[3] == 0 and ev[4] == 0 and ev[5] == 0
    assert ev[0] == pytest.approx(1.0)
