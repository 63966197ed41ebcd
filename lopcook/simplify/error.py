"""Geometric error of a LOD against LOD 0: the measured symmetric Hausdorff distance, metres.

Distances are libigl point-to-mesh queries (AABB tree) from the vertices and face centroids of
each mesh to the other mesh, max over both directions. Sampled at vertices and centroids the
value is a lower bound of the continuous Hausdorff distance (the distance to the other surface may
peak inside a face); what the recorded error guarantees is stated in docs/lod.md.
"""

from __future__ import annotations

import numpy as np

from .. import jit
from ..types import MeshPart
from .reference import Reference, point_mesh, samples


class _LodTree:
    """Squared distances of points to a LOD's surface: libigl's AABB tree, or for large LODs
    (``lopcook.jit.use``) the compiled hierarchy (``lopcook.simplify.kernels.Tree``), which gives
    the same values bit for bit."""

    def __init__(self, lod: MeshPart):
        self.pos = np.ascontiguousarray(lod.positions, dtype=np.float64)
        self.fac = np.ascontiguousarray(lod.indices, dtype=np.int64)
        if jit.use(int(self.fac.shape[0])):
            from . import kernels  # compiled kernels (numba): loaded only for large meshes
            self.kernel, self.igl = kernels.Tree(self.pos, self.fac), None
        else:
            import igl  # libigl (native) loads when a LOD is first measured
            self.kernel, self.igl = None, igl.AABB()
            self.igl.init(self.pos, self.fac)

    def squared(self, points: np.ndarray) -> np.ndarray:
        """(q,) squared distances of ``points`` (q, 3) to the LOD."""
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if self.kernel is not None:
            return self.kernel.closest(pts, point=False)[0]
        return np.asarray(self.igl.squared_distance(self.pos, self.fac, pts)[0])


def hausdorff(a: MeshPart, b: MeshPart) -> tuple[float, float, float]:
    """(symmetric, a -> b, b -> a) Hausdorff distance in metres, sampled at the vertices and face
    centroids of each mesh (a lower bound of the continuous distance)."""
    fa, fb = a.indices.astype(np.int64), b.indices.astype(np.int64)
    dab = float(np.sqrt(point_mesh(samples(a.positions, fa), b.positions, fb)[0].max()))
    dba = float(np.sqrt(point_mesh(samples(b.positions, fb), a.positions, fa)[0].max()))
    return max(dab, dba), dab, dba


def measure_ref_to_lod(ref: Reference, lod: MeshPart) -> float:
    """max over LOD 0's samples (``ref.samples``: vertices, then face centroids) of the distance to
    ``lod``, metres: the same value as querying every sample, with fewer queries.

    The distance to a surface is 1-Lipschitz, so a centroid c of face (v0, v1, v2) is at most
    ``min_i d(v_i) + |c - v_i|`` from the LOD. The vertices are queried first; a centroid is
    queried only when that bound (plus a 1e-9 relative slack for rounding) reaches the largest
    vertex distance, so the maximum is unchanged. Queries go to one libigl AABB tree over the LOD
    (how few centroids that queries: docs/lod.md; ``_LodTree``)."""
    tree = _LodTree(lod)
    samples, used = ref.samples, ref.sample_vertices
    nv = used.size
    d2v = tree.squared(samples[:nv])
    best = float(d2v.max()) if nv else 0.0
    centroids = samples[nv:]
    if centroids.shape[0] == 0:
        return float(np.sqrt(best))
    dv = np.zeros(ref.positions.shape[0])
    dv[used] = np.sqrt(d2v)
    bound = np.full(centroids.shape[0], np.inf)
    for k in range(3):  # per corner: (m,) temporaries only
        v = ref.faces[:, k]
        gap = centroids - ref.positions[v]
        np.minimum(bound, dv[v] + np.sqrt(np.einsum("ij,ij->i", gap, gap)), out=bound)
    need = np.flatnonzero(bound * (1.0 + 1e-9) >= np.sqrt(best) * (1.0 - 1e-9))
    if need.size:
        d2c = tree.squared(centroids[need])
        best = max(best, float(d2c.max()))
    return float(np.sqrt(best))


#: the sampled LOD 0 -> LOD direction queries at least this many of LOD 0's vertices (all of them
#: on smaller meshes) ...
MIN_SAMPLES = 1 << 16

#: ... and otherwise this many per vertex of the LOD: the cost follows the LOD's size, like the
#: transfer's queries of the LOD's own vertices and centroids
SAMPLES_PER_LOD_VERTEX = 1.0

#: unsampled vertices next to a sample (after it in the order) whose distance is at least this
#: fraction of the sampled maximum are queried too
REFINE_FRACTION = 0.5

#: rows per block of ``sampled_ref_to_lod``'s queries and bound (its (n, 3) arrays, a block at a time)
_BOUND_BLOCK = 1 << 18


def sampled_ref_to_lod(ref: Reference, lod: MeshPart, count: int | None = None,
                       on_ref: np.ndarray | None = None) -> tuple[float, float, int]:
    """LOD 0 -> LOD distance measured at a deterministic sample of LOD 0's vertices, metres:
    ``(measured, bound, samples)``.

    ``count`` vertices (default ``max(MIN_SAMPLES, SAMPLES_PER_LOD_VERTEX * lod vertices)``; every
    vertex when LOD 0 has no more) are taken coarse to fine from ``ref.sample_order``, so they
    cover LOD 0 evenly, and queried against one libigl AABB tree over the LOD. ``measured`` is
    their largest distance: a lower bound of the largest distance of any LOD 0 vertex. ``bound``
    is an upper bound of it: the distance to a surface is 1-Lipschitz, so a vertex v that was not
    queried is at most ``d(s) + |v - s|`` from the LOD, s being the sampled vertex before it in
    the order (in v's cell of the finest complete level); ``bound`` is the largest such value,
    computed for every vertex (no query). With every vertex queried, both equal the vertex
    maximum. What sampling can miss is at most ``bound - measured`` (docs/lod.md).

    ``on_ref``: (LOD 0 vertices,) bool or None; where True the vertex is known to be a vertex of
    the LOD (``transfer_attributes``' ``info["on_ref"]``): its distance is 0 and is not queried.
    The values are those of querying it. Queries: ``_LodTree``."""
    order = ref.sample_order
    pts = order.points
    if count is None:
        count = max(MIN_SAMPLES, int(SAMPLES_PER_LOD_VERTEX * lod.n_vertices))
    pick = order.take(int(count))
    sel = order.order[pick]
    tree = _LodTree(lod)

    def distances(rows: np.ndarray) -> np.ndarray:
        """Distances of the sample points ``rows`` (indices into ``pts``): 0 without a query for
        vertices ``on_ref`` marks (a point at a vertex of the LOD, where the query gives 0 too).
        Queried ``_BOUND_BLOCK`` points at a time (libigl returns each point's closest point too:
        (block, 3) arrays, not (rows, 3))."""
        out = np.zeros(rows.size)
        ask = np.arange(rows.size) if on_ref is None else np.flatnonzero(~on_ref[ref.sample_vertices[rows]])
        for s in range(0, ask.size, _BOUND_BLOCK):
            at = ask[s:s + _BOUND_BLOCK]
            out[at] = np.sqrt(tree.squared(pts[rows[at]]))
        return out

    d = distances(sel)
    measured = float(d.max()) if d.size else 0.0
    if sel.size == order.n:
        return measured, measured, int(sel.size)
    dist = np.zeros(order.n)
    dist[pick] = d  # in sorted order
    owner = np.maximum.accumulate(np.where(pick, np.arange(order.n), 0))  # sampled vertex at or before
    # errors are spatially coherent: also query the vertices next to the samples of large distance
    near = np.flatnonzero(~pick & (dist[owner] >= REFINE_FRACTION * measured) & (dist[owner] > 0))
    queried = int(sel.size)
    if near.size:
        d2 = distances(order.order[near])
        measured = max(measured, float(d2.max()))
        queried += int(near.size)
    del tree  # (about 120 bytes per LOD face) before the bound's temporaries
    bound = np.empty(order.n)
    for s in range(0, order.n, _BOUND_BLOCK):  # (block, 3) temporaries: the same values as one pass
        own = owner[s:s + _BOUND_BLOCK]
        gap = pts[order.order[s:s + own.size]] - pts[order.order[own]]
        bound[s:s + own.size] = dist[own] + np.sqrt(np.einsum("ij,ij->i", gap, gap))
    del gap, own
    if near.size:
        bound[near] = d2  # measured
    bound[pick] = d
    return measured, max(float(bound.max()), measured), queried
