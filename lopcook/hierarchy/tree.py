"""The vertex tree of one part: a binary forest from a full vertex-pair contraction sequence.

This work is based on:

* the view-dependent connectivity coding paper (``shared/papers/view-dependent-connectivity-
  coding.txt``), section 2.1 and Figure 4: the vertex tree of VDSlib (D. Luebke, C. Erikson,
  "View-Dependent Simplification of Arbitrary Polygonal Environments", SIGGRAPH 1997), where
  every triangle is a *subtri* of the node whose unfolding makes it appear.
* M. Garland, P. Heckbert, "Surface Simplification Using Quadric Error Metrics", SIGGRAPH 1997:
  the collapse sequence comes from fast-simplification's quadric simplifier
  (``simplify(..., return_collapses=True)``).
* H. Hoppe, "View-Dependent Refinement of Progressive Meshes", SIGGRAPH 1997: per-node bounding
  sphere and normal cone for the view-dependent selection in :mod:`lopcook.hierarchy.select`.

Contract
--------
``build_tree(positions, triangles)`` returns a :class:`VertexTree` whose leaves ``0..n-1`` are the
input vertices and whose internal nodes ``n..N-1`` are contractions, numbered in contraction order
(a child always has a smaller index than its parent). The quadric simplifier collapses edges; the
vertices it leaves over are then contracted in rounds of a greedy shortest-pair matching along the
edges of the part (general vertex-pair contraction), so each connected component ends as one tree:
a part with ``k`` components (an unreferenced vertex is a component) is a forest of ``k`` trees.

Every triangle ``(a, b, c)`` with three distinct corners is owned by the node where it first
degenerates when collapsing: the deepest of ``lca(a,b)``, ``lca(b,c)``, ``lca(c,a)``. Two of its
corners lie in different children of that owner (*internal*), the third outside its subtree
(*external*), as in the paper's Figure 4. Non-manifold input and duplicate triangles are allowed;
triangles with a repeated corner have no owner and are refused with a ``LopcookError``.

Node positions are integer grid coordinates: an internal node sits on the position of one leaf of
its subtree (its representative, the vertex the simplifier kept), so positions stay on the grid.
Units of ``error`` and ``radius`` are grid cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError

GRID_BITS = 24


@dataclass(frozen=True)
class VertexTree:
    """A binary vertex forest over ``n`` leaves (input vertices) and ``N - n`` contractions.

    Attributes
    ----------
    n_leaves : int
        ``n``; leaf ``i`` is input vertex ``i``.
    left, right : (N,) int32
        Children of each node; ``-1`` for leaves. ``left[k] < k`` and ``right[k] < k``.
    parent : (N,) int32
        Parent of each node, ``-1`` for roots.
    roots : (r,) int32
        One root per tree, sorted by their smallest leaf.
    rep : (N,) int32
        Representative leaf (input vertex) of each node; ``rep[i] = i`` for leaves.
    positions : (n, 3) uint32
        Leaf positions on the integer grid.
    triangles : (m, 3) int64
        The input triangles (vertex = leaf indices), in input order and rotation.
    owner : (m,) int32
        The node owning each triangle (a subtri of that node).
    error : (N,) float64
        Geometric error in grid cells: max distance from the node position to any leaf of its
        subtree, made monotone (a parent's error is at least its children's). 0 for leaves.
    radius : (N,) float64
        Bounding-sphere radius around the node position (grid cells), covering its leaves.
    reach : (N,) float64
        Radius around the node position (grid cells) covering every triangle incident to one of
        its leaves: the region its refinement affects (Hoppe 1997, section 4.1), made monotone.
        Used by the frustum and back-face tests, so a node whose triangles reach into the view
        is refined even when its leaves lie outside it.
    cone_axis : (N, 3) float64
        Unit axis of the normal cone of the faces incident to the node's leaves (zero if none).
    cone_angle : (N,) float64
        Half-angle of that cone in radians (pi when the faces face every way or none exist).
    origin : (3,) float64, step : float
        World placement of the grid: a grid coordinate ``q`` lies at ``origin + (q + 0.5) * step``
        (metres when built from float positions; the identity-like (0, 1) for grid input unless
        ``grid=`` is given).
    open_vertex : (n,) bool
        Leaves on the part's oriented boundary chain (``boundary_vertices``): open edges, UV
        seams (where the part's own vertices are split) and orientation flips. Hoppe's back-face
        test is not applied to a node whose subtree holds one (``lopcook.hierarchy.select``).
    """

    n_leaves: int
    left: np.ndarray
    right: np.ndarray
    parent: np.ndarray
    roots: np.ndarray
    rep: np.ndarray
    positions: np.ndarray
    triangles: np.ndarray
    owner: np.ndarray
    error: np.ndarray
    radius: np.ndarray
    cone_axis: np.ndarray
    cone_angle: np.ndarray
    origin: np.ndarray
    step: float
    reach: np.ndarray | None = None
    open_vertex: np.ndarray | None = None

    @property
    def n_nodes(self) -> int:
        return int(self.left.shape[0])

    @property
    def node_positions(self) -> np.ndarray:
        """(N, 3) uint32: the grid position of every node (its representative leaf)."""
        return self.positions[self.rep]

    def depth(self) -> np.ndarray:
        """(N,) int32 depth of each node (roots at 0)."""
        return node_depth(self.parent, self.left, self.right)

    def height(self) -> np.ndarray:
        """(N,) int32 height of each node (leaves at 0)."""
        return node_height(self.left, self.right)


def quantize(positions: np.ndarray, bits: int = GRID_BITS):
    """(n, 3) float positions -> ((n, 3) uint32, origin (3,), step) on a cube grid of ``2**bits``
    cells over their bounds; a point decodes to ``origin + (q + 0.5) * step``."""
    p = np.asarray(positions, dtype=np.float64)
    if p.shape[0] == 0:
        return np.zeros((0, 3), np.uint32), np.zeros(3), 1.0
    lo = p.min(axis=0)
    extent = float((p.max(axis=0) - lo).max())
    if not np.isfinite(extent):
        raise LopcookError("analyse", None, "positions contain NaN or infinity",
                           hint="remove non-finite vertices before building a hierarchy")
    if extent <= 0.0:
        return np.zeros(p.shape, np.uint32), lo, 1.0
    cells = float(1 << bits)
    q = np.clip(np.floor((p - lo) / extent * cells), 0, cells - 1).astype(np.uint32)
    return q, lo, extent / cells


def _check_input(positions, triangles, grid=None):
    pos = np.asarray(positions)
    origin, step = (np.zeros(3), 1.0) if grid is None else (np.asarray(grid[0], np.float64),
                                                            float(grid[1]))
    tri = np.asarray(triangles)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise LopcookError("analyse", None, f"positions must be (n, 3), got {pos.shape}",
                           hint="pass one part's vertex positions")
    if tri.ndim != 2 or tri.shape[1] != 3:
        raise LopcookError("analyse", None, f"triangles must be (m, 3), got {tri.shape}",
                           hint="pass one part's triangle indices")
    if pos.dtype.kind == "f":
        pos, origin, step = quantize(pos)
    elif pos.dtype.kind in "ui":
        if pos.size and (pos.min() < 0 or pos.max() >= (1 << 32)):
            raise LopcookError("analyse", None, "grid positions outside [0, 2**32)",
                               hint="pass uint32 grid coordinates")
        pos = pos.astype(np.uint32)
    else:
        raise LopcookError("analyse", None, f"positions have dtype {pos.dtype}",
                           hint="pass float64 positions or uint32 grid coordinates")
    n = pos.shape[0]
    tri = tri.astype(np.int64)
    if tri.size and (tri.min() < 0 or tri.max() >= n):
        raise LopcookError("analyse", None, f"triangle index outside [0, {n})",
                           hint="fix the index buffer")
    degenerate = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])
    if degenerate.any():
        k = int(np.flatnonzero(degenerate)[0])
        raise LopcookError("analyse", None,
                           f"{int(degenerate.sum())} triangles repeat a corner (first: triangle {k})",
                           hint="drop degenerate triangles (lopcook.hierarchy.drop_degenerate) first")
    return pos, tri, origin, step


def drop_degenerate(triangles: np.ndarray) -> np.ndarray:
    """(m, 3) triangles without those that repeat a corner (they cover no area and own no node)."""
    t = np.asarray(triangles)
    keep = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])
    return t[keep]


def node_height(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """(N,) height of each node (leaves 0), by sweeps until stable (depth-many vector passes)."""
    N = left.shape[0]
    h = np.zeros(N, np.int32)
    internal = np.flatnonzero(left >= 0)
    L, R = left[internal], right[internal]
    while True:
        nh = np.maximum(h[L], h[R]) + 1
        if np.array_equal(nh, h[internal]):
            return h
        h[internal] = nh


def node_depth(parent: np.ndarray, left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """(N,) int32 depth of each node (roots 0), one vector pass per level."""
    return _depth_by_levels(parent, left, right)


def _depth_by_levels(parent, left, right):
    N = parent.shape[0]
    d = np.zeros(N, np.int32)
    level = np.flatnonzero(parent < 0)
    cur = 0
    while level.size:
        d[level] = cur
        ch = np.concatenate([left[level], right[level]])
        level = ch[ch >= 0]
        cur += 1
    return d


def _collapse_forest(n, tri, pos):
    """Leaves 0..n-1, internal nodes from the quadric simplifier's collapse sequence."""
    import fast_simplification  # native: loaded only when a hierarchy is built

    left = [-1] * n
    right = [-1] * n
    rep = list(range(n))
    if tri.shape[0]:
        _, _, col = fast_simplification.simplify(pos.astype(np.float64), tri.astype(np.int32),
                                                 target_count=0, return_collapses=True)
        col = np.asarray(col, dtype=np.int64).reshape(-1, 2)
    else:
        col = np.zeros((0, 2), np.int64)
    cur_l = list(range(n))  # current node of each surviving vertex
    dead = bytearray(n)
    k = n
    for i0, i1 in col.tolist():
        if i0 == i1 or dead[i0] or dead[i1]:
            raise LopcookError("analyse", None, f"simplifier reported an invalid collapse ({i0}, {i1})",
                               hint="report this mesh; the collapse history is inconsistent")
        left.append(cur_l[i0])
        right.append(cur_l[i1])
        rep.append(i0)
        cur_l[i0] = k
        dead[i1] = 1
        k += 1
    return left, right, rep, cur_l, dead


def _roots_of(parent: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    r = nodes.copy()
    while True:
        p = parent[r]
        m = p >= 0
        if not m.any():
            return r
        r[m] = p[m]


def build_tree(positions: np.ndarray, triangles: np.ndarray, grid=None) -> VertexTree:
    """Build the vertex forest of one part (see the module docstring for the contract).

    Parameters
    ----------
    positions : (n, 3) float64 (quantized here on a 24-bit cube grid over the part's bounds)
        or (n, 3) uint32 grid coordinates (used as they are).
    triangles : (m, 3) int
        Triangle corners in [0, n), counter-clockwise; no repeated corner within a triangle.
    grid : (origin (3,), step) or None
        World placement of uint32 grid input (ignored for float input, which defines its own).
    """
    pos, tri, origin, step = _check_input(positions, triangles, grid)
    n = pos.shape[0]
    left, right, rep, cur_l, dead = _collapse_forest(n, tri, pos)

    # (2) Contract the left-over vertices of each component: greedy matching rounds along edges.
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]) if tri.size else \
        np.zeros((0, 2), np.int64)
    posf = pos.astype(np.float64)
    while True:
        N = len(left)
        par = np.full(N, -1, np.int64)
        L = np.asarray(left, np.int64)
        R = np.asarray(right, np.int64)
        internal = np.flatnonzero(L >= 0)
        par[L[internal]] = internal
        par[R[internal]] = internal
        if edges.shape[0] == 0:
            break
        root_of_leaf = _roots_of(par, np.arange(n, dtype=np.int64))
        e = root_of_leaf[edges]
        e = e[e[:, 0] != e[:, 1]]
        if e.shape[0] == 0:
            break
        e = np.unique(np.sort(e, axis=1), axis=0)
        repa = np.asarray(rep, np.int64)
        d = np.linalg.norm(posf[repa[e[:, 0]]] - posf[repa[e[:, 1]]], axis=1)
        order = np.lexsort((e[:, 1], e[:, 0], d))
        used = set()
        for a, b in e[order].tolist():
            if a in used or b in used:
                continue
            used.add(a)
            used.add(b)
            left.append(a)
            right.append(b)
            rep.append(rep[a])
    N = len(left)
    L = np.asarray(left, np.int32)
    R = np.asarray(right, np.int32)
    parent = np.full(N, -1, np.int32)
    internal = np.flatnonzero(L >= 0)
    parent[L[internal]] = internal
    parent[R[internal]] = internal
    repa = np.asarray(rep, np.int32)
    roots = np.flatnonzero(parent < 0).astype(np.int32)
    # sort roots by their smallest leaf
    leaf_root = _roots_of(parent.astype(np.int64), np.arange(n, dtype=np.int64))
    first = np.full(N, n, np.int64)
    np.minimum.at(first, leaf_root, np.arange(n))
    roots = roots[np.argsort(first[roots], kind="stable")]

    owner = triangle_owner(parent, L, R, n, tri)
    error, radius = _node_error(parent, L, R, repa, pos, n)
    reach = _node_reach(parent, L, R, repa, pos, n, tri)
    axis, angle = _normal_cones(parent, L, R, pos, tri, n)
    return VertexTree(n_leaves=n, left=L, right=R, parent=parent, roots=roots, rep=repa,
                      positions=pos, triangles=tri, owner=owner, error=error, radius=radius,
                      cone_axis=axis, cone_angle=angle, origin=origin, step=step, reach=reach,
                      open_vertex=boundary_vertices(tri, n))


def boundary_vertices(triangles: np.ndarray, n: int) -> np.ndarray:
    """(n,) bool: the vertices of every edge on the oriented boundary chain of ``triangles``.

    An undirected edge is on the chain when its two directions occur a different number of
    times: an open edge (one triangle), a seam where the part's vertices are split (each side is
    an open edge of its own), or an edge between two triangles of opposite orientation. Elsewhere
    every edge is shared by oppositely oriented triangles, as on a closed, consistently oriented
    surface. Hoppe's back-face test (1997, section 4.2) assumes such a surface: there a region
    that faces away is hidden behind the part's front. Where the chain runs, coarsening a
    back-facing region moves the chain away from the surface that continues it, which opens
    cracks and shows at silhouettes."""
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    out = np.zeros(int(n), bool)
    if not t.size:
        return out
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    lo, hi = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    sign = np.where(e[:, 0] < e[:, 1], 1, -1)
    key = lo * np.int64(n) + hi
    u, inv = np.unique(key, return_inverse=True)
    net = np.bincount(inv.reshape(-1), weights=sign, minlength=u.shape[0])
    on = u[net != 0]
    out[on // n] = True
    out[on % n] = True
    return out


class Lifting:
    """Binary-lifting ancestor table for vectorised LCA queries."""

    def __init__(self, parent: np.ndarray, left: np.ndarray, right: np.ndarray):
        self.depth = _depth_by_levels(parent, left, right).astype(np.int64)
        N = parent.shape[0]
        p = np.where(parent >= 0, parent, np.arange(N)).astype(np.int64)
        self.up = [p]
        span = int(self.depth.max()) if N else 0
        while (1 << len(self.up)) <= span:
            q = self.up[-1]
            self.up.append(q[q])

    def ancestor(self, x: np.ndarray, k: np.ndarray) -> np.ndarray:
        x = x.copy()
        for j, up in enumerate(self.up):
            m = ((k >> j) & 1).astype(bool)
            x[m] = up[x[m]]
        return x

    def lca(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Lowest common ancestor, or -1 when a and b lie in different trees."""
        a = np.asarray(a, np.int64)
        b = np.asarray(b, np.int64)
        da, db = self.depth[a], self.depth[b]
        swap = da < db
        a, b = np.where(swap, b, a), np.where(swap, a, b)
        a = self.ancestor(a, np.abs(da - db))
        for up in reversed(self.up):
            m = up[a] != up[b]
            a[m] = up[a[m]]
            b[m] = up[b[m]]
        same = a == b
        joined = (~same) & (self.up[0][a] == self.up[0][b]) & (self.up[0][a] != a)
        return np.where(same, a, np.where(joined, self.up[0][a], -1))


def triangle_owner(parent, left, right, n, tri) -> np.ndarray:
    """(m,) int32 owner node of each triangle: the deepest pairwise LCA of its corners."""
    if tri.shape[0] == 0:
        return np.zeros(0, np.int32)
    lift = Lifting(parent, left, right)
    c = [lift.lca(tri[:, i], tri[:, (i + 1) % 3]) for i in range(3)]
    if any((x < 0).any() for x in c):
        raise LopcookError("analyse", None, "a triangle spans two trees of the vertex forest",
                           hint="report this mesh")
    d = np.stack([lift.depth[x] for x in c])
    k = np.argmax(d, axis=0)
    return np.choose(k, c).astype(np.int32)


def _leaf_ancestors(parent, n):
    """Yield ``(leaf, ancestor)`` id arrays level by level: every leaf paired with its parent,
    then its grandparent, ... up to its root (one vectorised step per tree level)."""
    leaf = np.arange(n, dtype=np.int64)
    cur = parent[leaf].astype(np.int64)
    while True:
        m = cur >= 0
        if not m.any():
            return
        leaf, cur = leaf[m], cur[m]
        yield leaf, cur
        cur = parent[cur].astype(np.int64)


def _node_error(parent, left, right, rep, pos, n):
    N = parent.shape[0]
    posf = pos.astype(np.float64)
    err = np.zeros(N)
    for leaf, cur in _leaf_ancestors(parent, n):
        np.maximum.at(err, cur, np.linalg.norm(posf[leaf] - posf[rep[cur]], axis=1))
    radius = err.copy()
    # monotone: parent >= children, bottom-up by height
    h = node_height(left, right)
    internal = np.flatnonzero(left >= 0)
    order = internal[np.argsort(h[internal], kind="stable")]
    hs = h[order]
    for grp in np.split(order, np.flatnonzero(np.diff(hs)) + 1):
        err[grp] = np.maximum(err[grp], np.maximum(err[left[grp]], err[right[grp]]))
    return err, radius


def _node_reach(parent, left, right, rep, pos, n, tri):
    """(N,) grid cells: max over the node's leaves l of |p_l - p_node| + (longest edge at l)."""
    posf = pos.astype(np.float64)
    ring = np.zeros(n)
    if tri.shape[0]:
        e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
        length = np.linalg.norm(posf[e[:, 0]] - posf[e[:, 1]], axis=1)
        np.maximum.at(ring, e[:, 0], length)
        np.maximum.at(ring, e[:, 1], length)
    N = parent.shape[0]
    reach = np.zeros(N)
    reach[:n] = ring
    for leaf, cur in _leaf_ancestors(parent, n):
        np.maximum.at(reach, cur, np.linalg.norm(posf[leaf] - posf[rep[cur]], axis=1) + ring[leaf])
    return reach


def _normal_cones(parent, left, right, pos, tri, n):
    N = parent.shape[0]
    axis = np.zeros((N, 3))
    angle = np.full(N, np.pi)
    if tri.shape[0] == 0:
        return axis, angle
    p = pos.astype(np.float64)
    fn = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    ln = np.linalg.norm(fn, axis=1)
    good = ln > 0
    unit = np.zeros_like(fn)
    unit[good] = fn[good] / ln[good, None]
    corners = tri[good].reshape(-1)
    fnc = np.repeat(fn[good], 3, axis=0)
    unc = np.repeat(unit[good], 3, axis=0)
    s = np.zeros((N, 3))
    np.add.at(s, corners, fnc)
    # sums bottom-up
    h = node_height(left, right)
    internal = np.flatnonzero(left >= 0)
    order = internal[np.argsort(h[internal], kind="stable")]
    groups = np.split(order, np.flatnonzero(np.diff(h[order])) + 1)
    for grp in groups:
        s[grp] = s[left[grp]] + s[right[grp]]
    ls = np.linalg.norm(s, axis=1)
    has = ls > 0
    axis[has] = s[has] / ls[has, None]
    # leaves: exact max angle over incident faces
    cosang = np.einsum("ij,ij->i", unc, axis[corners])
    mincos = np.full(N, 2.0)
    np.minimum.at(mincos, corners, cosang)
    leafhas = (mincos <= 1.0) & has
    angle[leafhas] = np.arccos(np.clip(mincos[leafhas], -1, 1))
    # internal: cone union bound
    for grp in groups:
        res = np.zeros(grp.shape[0])
        ok = has[grp]
        for ch in (left[grp], right[grp]):
            chas = has[ch] & (angle[ch] < np.pi)
            c = np.arccos(np.clip(np.einsum("ij,ij->i", axis[grp], axis[ch]), -1, 1)) + angle[ch]
            c = np.where(has[ch], np.where(chas, c, np.pi), 0.0)
            res = np.maximum(res, c)
        angle[grp] = np.where(ok, np.minimum(res, np.pi), np.pi)
    return axis, angle
