"""Geometric error of a LOD against LOD 0: the measured symmetric Hausdorff distance, metres.

Distances are libigl point-to-mesh queries (AABB tree) from the vertices and face centroids of
each mesh to the other mesh, max over both directions. Sampled at vertices and centroids the
value is a lower bound of the continuous Hausdorff distance (the distance to the other surface may
peak inside a face); what the recorded error guarantees is stated in docs/lod.md.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..mesh import used_ids
from ..types import MeshPart

if TYPE_CHECKING:
    from .transfer import Reference


def point_mesh(points: np.ndarray, positions: np.ndarray, faces: np.ndarray):
    """libigl closest points: (squared distance, face id, closest point)."""
    import igl

    d, i, c = igl.point_mesh_squared_distance(np.ascontiguousarray(points, dtype=np.float64),
                                              np.ascontiguousarray(positions, dtype=np.float64),
                                              np.ascontiguousarray(faces, dtype=np.int64))
    return np.asarray(d), np.asarray(i, dtype=np.int64), np.asarray(c)


def samples(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Referenced vertices and face centroids."""
    used = used_ids(faces, positions.shape[0])
    out = np.empty((used.size + faces.shape[0], 3), dtype=np.float64)
    out[:used.size] = positions[used]
    cen = out[used.size:]  # centroids in place: no (m, 3, 3) temporary
    np.add(positions[faces[:, 0]], positions[faces[:, 1]], out=cen)
    cen += positions[faces[:, 2]]
    cen /= 3.0
    return out


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
    (how few centroids that queries: docs/lod.md)."""
    import igl

    pos = np.ascontiguousarray(lod.positions, dtype=np.float64)
    fac = np.ascontiguousarray(lod.indices, dtype=np.int64)
    tree = igl.AABB()
    tree.init(pos, fac)
    samples, used = ref.samples, ref.sample_vertices
    nv = used.size
    d2v = np.asarray(tree.squared_distance(pos, fac, np.ascontiguousarray(samples[:nv]))[0])
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
        d2c = np.asarray(tree.squared_distance(pos, fac, np.ascontiguousarray(centroids[need]))[0])
        best = max(best, float(d2c.max()))
    return float(np.sqrt(best))
