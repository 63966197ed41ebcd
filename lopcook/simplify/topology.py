"""Mesh topology a simplifier must respect: defects (degenerate faces, open and non-manifold edges,
bow-tie vertices) and UV seams, counted on the mesh welded by exact position.

``seam_stats`` is the check of the seam modes in ``lopcook.simplify.chain``: with ``seams="lock"``
a LOD's ``SeamStats`` equal its input's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import jit
from ..mesh import (components, degenerate_mask, edge_groups, fan_successors, graph_components, next_corner,
                    single_fans, sorted_unique, unique_rows, weld_exact, weld_labels)
from ..types import MeshPart


@dataclass(frozen=True)
class SeamStats:
    """UV seams of a mesh, on the mesh welded by exact position.

    seam_edges : edges with exactly two faces whose UVs differ at either end across the edge
        (non-manifold edges are left out: overlapping sheets are counted by ``mesh_defects``)
    seam_vertices : distinct positions on a seam edge
    uv_islands : connected components of faces through corners with the same position and UV
    """

    seam_edges: int
    seam_vertices: int
    uv_islands: int

    def as_dict(self) -> dict:
        return {"seam_edges": self.seam_edges, "seam_vertices": self.seam_vertices,
                "uv_islands": self.uv_islands}


def mesh_defects(positions: np.ndarray, indices: np.ndarray, degenerate: np.ndarray | None = None) -> dict:
    """Counts on the position-welded mesh: ``degenerate_faces``, ``boundary_edges``,
    ``nonmanifold_edges`` (more than two faces), ``nonmanifold_vertices`` (bow-ties: faces around
    the vertex form more than one edge-connected fan) and ``closed`` (every edge has two faces).
    Large meshes (``lopcook.jit.use``): the same counts from ``kernels.defect_counts``."""
    faces = np.asarray(indices)
    if degenerate is None:
        degenerate = degenerate_mask(positions, faces.astype(np.int64))
    if jit.use(int(faces.shape[0])):
        return _defects_kernel(positions, faces, degenerate)
    w, n = weld_labels(positions, np.int64)  # the counts below do not depend on the numbering
    # int32 ids where they fit: this runs on every LOD input (memory: ~60 bytes per triangle)
    cid = np.int32 if max(3 * faces.shape[0], n) < (1 << 31) - 1 else np.int64
    good = w.astype(cid)[faces[~degenerate]]
    del w
    m = good.shape[0]
    if m == 0:
        return {"degenerate_faces": int(degenerate.sum()), "boundary_edges": 0, "nonmanifold_edges": 0,
                "nonmanifold_vertices": 0, "closed": False}
    a = good.ravel()  # half-edge h = 3f + k runs from corner h to corner cb(h) of face f
    order, starts, sizes = edge_groups(a, good[:, [1, 2, 0]].ravel(), n)
    # link consecutive half-edges of one edge: corners at the same vertex
    same = np.ones(order.size, dtype=bool)
    same[starts] = False
    pair_size = np.repeat(sizes, sizes)[same]  # the size of each link's edge group
    del starts
    h2 = order[same].astype(cid)
    h1 = order[np.flatnonzero(same) - 1].astype(cid)
    del order, same
    same_dir = a[h1] == a[h2]
    # around a vertex whose every half-edge in and out has one oppositely oriented twin, its
    # corners form cycles (succ: the next corner around); one cycle is one fan (mesh.single_fans)
    twin = np.flatnonzero((pair_size == 2) & ~same_dir)
    del pair_size
    succ, clean = fan_successors(h1[twin], h2[twin], a, n, cid)
    del twin
    fan = np.bincount(a, minlength=n)
    one_fan = single_fans(succ, a, fan, clean, cid)
    del succ, clean, fan
    # the other vertices' corners (open, non-manifold, inconsistently oriented, several cycles):
    # their fans are the connected components of the links between their corners
    cplx = np.flatnonzero(~one_fan[a]).astype(cid, copy=False)
    del one_fan
    bowties = 0
    if cplx.size:
        cb1 = next_corner(h1)
        cb2 = next_corner(h2)
        u = np.concatenate([h1, cb1])
        v = np.concatenate([np.where(same_dir, h2, cb2), np.where(same_dir, cb2, h2)])
        del h1, h2, cb1, cb2, same_dir
        at = np.zeros(3 * m, dtype=bool)
        at[cplx] = True
        keep = at[u]  # a link joins two corners of one vertex: both complex or neither
        del at
        u, v = u[keep], v[keep]
        del keep
        n_fans, lab = graph_components(np.searchsorted(cplx, u), np.searchsorted(cplx, v), cplx.size)
        del u, v
        # every link joins two corners at one vertex, so each fan (component) lies at one vertex: the
        # fans per vertex are a count of the fans' vertices (no sort of (vertex, fan) pairs)
        fan_vertex = np.empty(n_fans, dtype=a.dtype)
        fan_vertex[lab] = a[cplx]
        del lab
        bowties = int((np.bincount(fan_vertex, minlength=n) > 1).sum())
    return {
        "degenerate_faces": int(degenerate.sum()),
        "boundary_edges": int((sizes == 1).sum()),
        "nonmanifold_edges": int((sizes > 2).sum()),
        "nonmanifold_vertices": bowties,
        "closed": bool((sizes == 2).all()),
    }


def _defects_kernel(positions: np.ndarray, faces: np.ndarray, degenerate: np.ndarray) -> dict:
    """``mesh_defects`` through the compiled kernels (``lopcook.simplify.kernels``)."""
    from . import kernels  # compiled kernels (numba): loaded only for large meshes

    bits = (np.ascontiguousarray(positions, dtype=np.float64) + 0.0).view(np.int64)  # -0.0 -> 0.0
    w, nw = kernels.weld_first(bits)
    del bits
    one, many, bowties, two, edges = kernels.defect_counts(w, nw, np.ascontiguousarray(faces), np.asarray(degenerate))
    return {"degenerate_faces": int(np.count_nonzero(degenerate)), "boundary_edges": int(one),
            "nonmanifold_edges": int(many), "nonmanifold_vertices": int(bowties),
            "closed": bool(edges > 0 and two == edges)}


def seam_stats(part: MeshPart) -> SeamStats | None:
    """UV seam counts of ``part`` (None when it has no UVs). See ``SeamStats``."""
    if part.uvs is None:
        return None
    faces = part.indices.astype(np.int64)
    w, n = weld_exact(part.positions)
    wf = w[faces]
    m = faces.shape[0]
    uv = np.ascontiguousarray(part.uvs, dtype=np.float32) + np.float32(0.0)  # -0.0 -> 0.0
    cu = uv[faces]  # (m, 3, 2)
    a, b = wf.ravel(), wf[:, [1, 2, 0]].ravel()
    ua, ub = cu.reshape(-1, 2), cu[:, [1, 2, 0]].reshape(-1, 2)
    flip = (a > b)[:, None]
    ulo, uhi = np.where(flip, ub, ua), np.where(flip, ua, ub)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    ekey = lo * np.int64(max(n, 1)) + hi
    # an edge is a seam when its faces do not all agree on the UVs at both of its ends
    first, _ = unique_rows(np.concatenate([ekey[:, None], ulo.view(np.int32).astype(np.int64),
                                           uhi.view(np.int32).astype(np.int64)], axis=1))
    ek, cnt = np.unique(ekey[first], return_counts=True)
    ek_all, faces_per_edge = np.unique(ekey, return_counts=True)  # both sorted by key
    manifold = faces_per_edge[np.searchsorted(ek_all, ek)] == 2
    seam_key = ek[(cnt > 1) & manifold]
    seam_vertices = sorted_unique(np.r_[seam_key // max(n, 1), seam_key % max(n, 1)]) if seam_key.size else seam_key
    keys = np.concatenate([wf.reshape(-1, 1), cu.reshape(-1, 2).view(np.int32).astype(np.int64)], axis=1)
    _, inv = unique_rows(keys)
    islands = components(m, inv.reshape(m, 3), int(inv.max()) + 1 if inv.size else 0)
    return SeamStats(seam_edges=int(seam_key.size), seam_vertices=int(seam_vertices.size),
                     uv_islands=int(islands.max()) + 1 if islands.size else 0)


def signed_volume(positions: np.ndarray, faces: np.ndarray) -> float:
    t = positions[faces] - positions[faces].reshape(-1, 3).mean(axis=0)
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)
