"""Vertex normals for sources that have none: area-weighted and crease-aware.

Method: the mesh is welded by exact position (so UV seams do not break shading), each corner of a
triangle is linked to the matching corner of its neighbour across every manifold edge whose
dihedral angle is at most ``crease_angle_deg`` (edges touching a zero-area triangle count as
smooth), and the corners of a vertex split into the connected groups of that graph. A vertex
with several groups (a vertex on a crease, e.g. fandisk's feature lines) is split into one vertex
per group. Each group's normal is the sum of its triangles' cross products (area weighting),
normalised. A group whose triangles all have zero area gets the normal of the nearest
non-degenerate direction available: +Y as a last resort (counted in ``NormalResult.fallback``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .weld import weld_exact


@dataclass(frozen=True)
class NormalResult:
    """indices (m, 3) uint32 into the new vertices; source_vertex (n', ) int64 original vertex of
    each new vertex (n' >= n only grows at creases); normals (n', 3) float32 unit;
    fallback: number of new vertices whose normal could not be computed (all-degenerate)."""

    indices: np.ndarray
    source_vertex: np.ndarray
    normals: np.ndarray
    fallback: int


def face_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(m, 3) float64 cross products (p1 - p0) x (p2 - p0): direction = normal, length = 2 * area."""
    t = positions[indices]
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def _group_sum(group: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(G, 3) sums of (c, 3) ``values`` per group id (bincount per column: much faster than add.at)."""
    size = int(group.max()) + 1 if group.size else 0
    return np.stack([np.bincount(group, weights=values[:, k], minlength=size) for k in range(3)], axis=1)


def compute_normals(positions: np.ndarray, indices: np.ndarray, crease_angle_deg: float = 60.0) -> NormalResult:
    """Area-weighted, crease-aware vertex normals.

    Parameters
    ----------
    positions : (n, 3) float64
    indices : (m, 3) integer, counter-clockwise
    crease_angle_deg : float, degrees in [0, 180]; 180 = smooth everywhere

    Returns
    -------
    NormalResult (see class doc). Vertices used by no triangle keep one copy with normal +Y.
    """
    n = positions.shape[0]
    tri = np.asarray(indices, dtype=np.int64)
    m = tri.shape[0]
    weld, _ = weld_exact(positions)
    wtri = weld[tri]  # (m, 3) welded vertex per corner
    fn = face_normals(positions, tri)
    flen = np.linalg.norm(fn, axis=1)
    degenerate = flen <= 1e-300
    unit = np.where(degenerate[:, None], 0.0, fn / np.where(degenerate, 1.0, flen)[:, None])

    # half-edges: corner k of face f goes from wtri[f,k] to wtri[f,(k+1)%3]
    corner = np.arange(3 * m, dtype=np.int64).reshape(m, 3)
    a = wtri.ravel()
    b = wtri[:, [1, 2, 0]].ravel()
    ca = corner.ravel()                # corner at a
    cb = corner[:, [1, 2, 0]].ravel()  # corner at b
    face = np.repeat(np.arange(m, dtype=np.int64), 3)
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    valid = lo != hi
    # sort half-edges by undirected key (lo, hi); order within a key does not matter (links are
    # symmetric), so the faster unstable sort is fine and the result is still deterministic
    order = np.argsort(lo * np.int64(max(int(weld.max()) + 1, 1)) + hi)
    order = order[valid[order]]
    lo_s, hi_s = lo[order], hi[order]
    same_next = (lo_s[:-1] == lo_s[1:]) & (hi_s[:-1] == hi_s[1:])
    # manifold edges: exactly two half-edges with this key
    starts = np.flatnonzero(np.r_[True, ~same_next])
    sizes = np.diff(np.r_[starts, order.size])
    pair = starts[sizes == 2]
    h1, h2 = order[pair], order[pair + 1]
    f1, f2 = face[h1], face[h2]
    cos_limit = np.cos(np.radians(crease_angle_deg))
    smooth = (np.einsum("ij,ij->i", unit[f1], unit[f2]) >= cos_limit - 1e-12) | degenerate[f1] | degenerate[f2]
    if crease_angle_deg >= 180.0:
        smooth[:] = True
    h1, h2 = h1[smooth], h2[smooth]
    # link the corners at the same welded vertex: corner of h1 at a matches the corner of h2 at a
    a1, a2 = a[h1], a[h2]
    same_dir = a1 == a2  # consistently oriented neighbours have opposite half-edges
    ca1, cb1, ca2, cb2 = ca[h1], cb[h1], ca[h2], cb[h2]
    link_u = np.concatenate([ca1, cb1])
    link_v = np.concatenate([np.where(same_dir, ca2, cb2), np.where(same_dir, cb2, ca2)])
    graph = coo_matrix((np.ones(link_u.size, dtype=np.int8), (link_u, link_v)), shape=(3 * m, 3 * m))
    _, group = connected_components(graph, directed=False)

    # a group made only of zero-area triangles has no direction: merge its corners into another
    # group of the same welded vertex that has one (so degenerate slivers do not split vertices)
    corner_fn = np.repeat(fn, 3, axis=0)
    gsum = _group_sum(group, corner_fn)
    good = np.linalg.norm(gsum, axis=1)[group] > 1e-300
    wv = wtri.ravel()
    donor = np.full(int(wv.max()) + 1 if m else 0, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(donor, wv[good], group[good])
    take = ~good & (donor[wv] != np.iinfo(np.int64).max)
    group = np.where(take, donor[wv], group)

    # new vertex = (original vertex, corner group); number them by first corner appearance
    ov = tri.ravel()
    key = ov * np.int64(3 * m + 1) + group
    uniq, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    order_new = np.argsort(ov[first] * np.int64(3 * m + 1) + first, kind="stable")
    rank = np.empty_like(order_new)
    rank[order_new] = np.arange(order_new.size)
    new_index = rank[inverse.ravel()]
    source_vertex = ov[first][order_new]

    # accumulate area-weighted normals per group, then per new vertex
    gsum = _group_sum(group, corner_fn)
    first_corner = first[order_new]
    normals = gsum[group[first_corner]]

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
    return NormalResult(
        indices=new_index.reshape(m, 3).astype(np.uint32),
        source_vertex=source_vertex.astype(np.int64),
        normals=normals.astype(np.float32),
        fallback=int(np.count_nonzero(bad)),
    )
