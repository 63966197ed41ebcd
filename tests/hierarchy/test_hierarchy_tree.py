"""lopcook.hierarchy.tree: the vertex forest, triangle ownership, error, spheres and cones."""

from __future__ import annotations

import numpy as np
import pytest

from hierarchy_meshes import book, grid, icosphere, tetra, two_tetras_and_a_point
from lopcook.errors import LopcookError
from lopcook.hierarchy.tree import build_tree, drop_degenerate, quantize


def _ancestors(T, x):
    out = []
    p = int(T.parent[x])
    while p >= 0:
        out.append(p)
        p = int(T.parent[p])
    return out


def _leaves(T, node):
    if T.left[node] < 0:
        return [node]
    return _leaves(T, int(T.left[node])) + _leaves(T, int(T.right[node]))


@pytest.mark.parametrize("mesh", [icosphere, tetra, two_tetras_and_a_point, book, grid])
def test_forest_shape_and_ownership(mesh):
    p, t = mesh()
    T = build_tree(p, t)
    n = p.shape[0]
    assert T.n_leaves == n
    # one tree per connected component (an unreferenced vertex is its own component)
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]]])
    g = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    k, _ = connected_components(g, directed=False)
    assert T.roots.shape[0] == k
    assert T.n_nodes == 2 * n - k
    internal = np.flatnonzero(T.left >= 0)
    assert np.all(T.left[internal] < internal) and np.all(T.right[internal] < internal)
    for i, tri in enumerate(t.tolist()):
        v = int(T.owner[i])
        L, R = set(_leaves(T, int(T.left[v]))), set(_leaves(T, int(T.right[v])))
        inL = [c in L for c in tri]
        inR = [c in R for c in tri]
        assert sum(inL) == 1 and sum(inR) == 1, (i, tri)
        ext = [c for c in tri if c not in L and c not in R]
        assert len(ext) == 1
        # the owner is where the triangle first degenerates: no descendant holds two corners
        for child in (int(T.left[v]), int(T.right[v])):
            assert sum(c in set(_leaves(T, child)) for c in tri) == 1


def test_error_sphere_and_cone_bound_their_subtree():
    p, t = icosphere(2)
    T = build_tree(p, t)
    pos = T.positions.astype(np.float64)
    npos = T.node_positions.astype(np.float64)
    fn = np.cross(pos[t[:, 1]] - pos[t[:, 0]], pos[t[:, 2]] - pos[t[:, 0]])
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    for leaf in range(T.n_leaves):
        for a in _ancestors(T, leaf):
            d = np.linalg.norm(pos[leaf] - npos[a])
            assert d <= T.radius[a] + 1e-6
            assert T.error[a] >= T.radius[a] - 1e-6
            assert T.error[a] >= T.error[T.left[a]] and T.error[a] >= T.error[T.right[a]]
    for f in range(t.shape[0]):
        for corner in t[f]:
            for a in [int(corner)] + _ancestors(T, int(corner)):
                ang = np.arccos(np.clip(fn[f] @ T.cone_axis[a], -1, 1))
                assert ang <= T.cone_angle[a] + 1e-6


def test_closed_sphere_root_cone_spans_everything():
    p, t = icosphere(1)
    T = build_tree(p, t)
    assert T.cone_angle[T.roots[0]] >= np.pi / 2


def test_quantize_places_points_in_their_cells():
    p, _ = icosphere(1)
    q, origin, step = quantize(p)
    back = origin + (q + 0.5) * step
    assert q.dtype == np.uint32
    assert np.abs(back - p).max() <= step


def test_grid_input_is_used_as_is():
    p, t = tetra()
    q = (p * 1000).astype(np.uint32)
    T = build_tree(q, t, grid=(np.zeros(3), 0.001))
    assert np.array_equal(T.positions, q)
    assert T.step == 0.001


def test_bad_input_is_a_lopcook_error():
    p, t = tetra()
    with pytest.raises(LopcookError, match="repeat a corner"):
        build_tree(p, np.array([[0, 0, 1]]))
    with pytest.raises(LopcookError, match="outside"):
        build_tree(p, np.array([[0, 1, 7]]))
    with pytest.raises(LopcookError, match=r"\(n, 3\)"):
        build_tree(p[:, :2], t)
    with pytest.raises(LopcookError, match="NaN"):
        build_tree(np.full((4, 3), np.nan), t)
    assert drop_degenerate(np.array([[0, 0, 1], [0, 1, 2]])).tolist() == [[0, 1, 2]]


def test_corpus_bunny_tree(corpus):
    import lopcook

    part = lopcook.load(corpus / "stanford-bunny.obj").parts[0]
    T = build_tree(part.positions, drop_degenerate(part.indices))
    assert T.triangles.shape[0] == 69451
    depth = T.depth()
    assert 15 <= depth.max() <= 40
    counts = np.bincount(T.owner, minlength=T.n_nodes)[T.n_leaves:]
    # mostly manifold vertex splits: two subtris per internal node
    assert (counts == 2).mean() > 0.95
