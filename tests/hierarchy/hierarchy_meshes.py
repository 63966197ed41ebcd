"""Small analytic meshes shared by the hierarchy tests."""

from __future__ import annotations

import numpy as np

from lopcook.mesh import canonical_triangles as canonical  # noqa: F401 (re-exported for the tests)


def icosphere(subdivisions: int = 2):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def tetra(offset=(0.0, 0.0, 0.0)):
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float64) + np.asarray(offset)
    t = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]], np.int64)
    return p, t


def two_tetras_and_a_point():
    p1, t1 = tetra()
    p2, t2 = tetra((3.0, 0.0, 0.0))
    p = np.concatenate([p1, p2, [[9.0, 9.0, 9.0]]])
    return p, np.concatenate([t1, t2 + 4])


def book(pages: int = 5):
    """Non-manifold: ``pages`` triangles sharing the edge (0, 1), plus duplicated triangles."""
    ang = np.linspace(0, np.pi, pages)
    spine = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    tips = np.stack([np.cos(ang), np.sin(ang), np.full(pages, 0.5)], axis=1)
    p = np.concatenate([spine, tips])
    t = np.array([[0, 1, 2 + k] for k in range(pages)] + [[1, 0, 2], [0, 1, 3]], np.int64)
    return p, t


def grid(n: int = 12):
    """An open n x n vertex grid (boundary everywhere around)."""
    x, y = np.meshgrid(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64))
    p = np.stack([x.ravel(), y.ravel(), 0.1 * np.sin(x.ravel()) * np.cos(y.ravel())], axis=1)
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    t = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    return p, t.astype(np.int64)


def net_edges(tri) -> dict:
    """Oriented edge chain of a triangle set: {(p, q): count(p->q) - count(q->p)} for p < q, nonzero."""
    t = np.asarray(tri, np.int64).reshape(-1, 3)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    e = e[e[:, 0] != e[:, 1]]
    sign = np.where(e[:, 0] < e[:, 1], 1, -1)
    key = np.sort(e, axis=1)
    u, inv = np.unique(key, axis=0, return_inverse=True)
    net = np.bincount(inv.reshape(-1), weights=sign, minlength=u.shape[0]).astype(np.int64)
    return {tuple(k): int(v) for k, v in zip(u.tolist(), net.tolist()) if v}
