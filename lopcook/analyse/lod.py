"""LOD chains: simplify each part to a chain of coarser meshes and measure each one's error.

A chain for one part is LOD 0 (the part itself, error 0) followed by simplifications to target
triangle counts ``round(ratio * n0)`` for ratios 1/2, 1/4, 1/8, ... (or the ratios given). It stops
at the first LOD whose error exceeds ``max_error_m`` (the error the farthest view can still show:
no distance would select a coarser LOD, so it is not kept), when a target falls below
``min_triangles``, or when a LOD cannot be produced (see *Failures*).

Backends
--------
``"pymeshlab"``
    MeshLab's quadric edge collapse (``meshing_decimation_quadric_edge_collapse``; with UVs the
    texture-aware ``..._with_texture`` variant, whose quadrics include the texture coordinates).
    Boundary-aware (``preserveboundary``: open-boundary vertices are locked), normal-aware
    (``preservenormal``: no collapse may flip a face), ``planarquadric`` and, without UVs,
    ``preservetopology``. About 1 s per 70k input triangles.
``"fast"``
    fast-simplification (a quadric collapse on positions only; the backend call is 10-25x faster
    than pymeshlab's). Its collapse map (``return_collapses``) tells which input vertex every
    output vertex is. Open borders are locked (``preserve_border``) like pymeshlab's with
    ``preserve_boundary=True`` (the default): boundary vertices keep their exact positions, so
    parts that share a boundary do not crack apart at any LOD.

Both run on the mesh welded by position (or split only at UV seams, see below), so attribute seams
never tear the surface. Normals, colours (and UVs where the backend does not supply them) are
carried over by *closest-point transfer* from LOD 0: each LOD vertex takes the barycentric
interpolation of LOD 0's attributes at its closest point on LOD 0. This is more accurate than
copying the collapse-map representative's attributes, whose position has moved. A face corner
whose own side of the surface (LOD 0's face nearest to the LOD face's centroid, refined by a query
a quarter of the way from the corner to the centroid) extrapolates to clearly different values at
the vertex (normals more than 30 degrees apart, UVs 5e-3, colours 0.02: another side of a crease
or seam) takes that side's values instead, so hard edges and seams split LOD vertices again while
smooth fields keep one vertex per position. Normals are renormalised; colours clipped to [0, 1].

UV seams (``seams=``)
---------------------
``"lock"`` (default)
    The mesh is split along UV seams (vertices unique by (position, uv)) so that every seam is an
    open boundary, and the backend locks boundary vertices: every seam edge, seam vertex and UV
    island of the source survives exactly (``SeamStats`` equal), seam vertices keep their exact
    positions on both sides (no cracks) and the source texture stays valid. The price: faces
    touching a seam cannot be simplified, so a densely seamed mesh stops reducing early
    (DamagedHelmet: at about 58% of its triangles). A backend driven into that wall makes forced,
    bad collapses, so a LOD that misses its target is redone at 1.1x the count reached and the
    clearly better of the two kept (DamagedHelmet 1/2: 8944 triangles at 0.18 m error, or 9838
    at 0.014 m), with a note; one that misses by more than 2x is a failure, and a result whose
    ``SeamStats`` differ from its input's is a failure too. pymeshlab's texture-aware quadric
    supplies the UVs of interior vertices; with ``fast`` the collapse map gives each output
    vertex's UV island and UVs are interpolated inside that island (unmoved vertices keep theirs
    bit for bit).
``"simplify"`` (pymeshlab only)
    The texture-aware quadric on the position-welded mesh with per-wedge UVs: seams are simplified
    along with the mesh (fewer seam edges; islands may merge, vanish or split); the UVs are
    MeshLab's. Reaches targets where ``"lock"`` cannot. With ``fast`` it means ``"ignore"``.
``"ignore"``
    Geometry ignores UVs; UVs come from the closest-point transfer. Triangles that straddle a
    source seam get UVs from two islands and smear the texture along the seam (the loss is
    reported through ``SeamStats``).
``"xatlas"``
    As ``"ignore"``, then every LOD gets a fresh xatlas atlas. The source texture does **not**
    match the new atlas: ``Lod.part.texture`` is set to None and a note says the texture must be
    re-baked (lopcook does not bake textures).

``parametrise(part)`` gives a part without UVs an xatlas atlas (for a texture-space analysis);
``lod_chain(..., parametrise=True)`` does this to LOD 0 first, so the whole chain shares one atlas
(kept by ``"lock"``). There is no texture to carry in that case.

Error
-----
``Lod.hausdorff_m`` is the symmetric Hausdorff distance between the LOD and LOD 0 in metres,
*measured*: libigl point-to-mesh distances (AABB tree) from the vertices and face centroids of
each mesh to the other mesh, max over both directions. Sampled at vertices and centroids it is a
lower bound of the continuous Hausdorff distance (the distance to the other surface may peak
anywhere inside a face; centroids catch faces that bridge a concavity or cut a corner, which
vertices alone miss). The LOD 0 -> LOD direction needs only the maximum, so it queries LOD 0's
vertices first and then only the centroids whose Lipschitz bound (vertex distance + distance to
that vertex) could reach it: the same value, about a third of the queries on a dense mesh
(``_measure_ref_to_lod``). ``Lod.error_m`` is the monotone envelope along the chain,
``max(hausdorff_m, previous error_m)``: the value to select LODs by, non-decreasing by
construction (the LOD is kept and a note says when the measured value dropped). Chains simplify
each LOD from the previous one (``chain="previous"``, default) or from LOD 0 (``chain="source"``);
error is always measured against LOD 0. On the bunny ``"previous"`` was both faster and more
accurate for both backends (1/64: 2.2 mm vs 6.7 mm pymeshlab, 3.1 vs 5.1 mm fast); on a
1.1M-triangle subdivided bunny fast's chained LODs were worse (1/64: 4.2 vs 1.2 mm), so a chained
LOD that misses its target by more than 5% is redone from LOD 0 and the closer one kept.

Failures (never raised for mesh-quality reasons; each is a note)
----------------------------------------------------------------
* parts under 4 triangles: not simplified (LOD 0 only);
* zero-area and repeated-index faces: dropped before simplification and from every result;
* non-manifold input (edges with more than two faces, bow-tie vertices): counted in the notes; the
  backends handle it (pymeshlab's ``preservetopology`` is turned off for it);
* a backend that raises, returns NaN/out-of-range data, flipped faces (more than
  ``max_flipped_fraction`` of faces facing more than 120 degrees away from LOD 0's nearest face
  at the centroid and at two of three points half-way to the corners, or a closed mesh whose
  signed volume changes sign) or a count more than 2x off its target: the other backend is tried;
  if it fails too the LOD is not produced (``Lod.failed``) and the chain keeps the previous LODs;
* a backend that crashes the process: inputs of ``isolate.MIN_FACES`` faces or more are simplified
  in a forked child (``lopcook.analyse.isolate``), so a segmentation fault is a failure like the
  others and the backend's memory (pymeshlab peaks ~500 MB at 1.1M triangles; fast-simplification
  keeps ~320 MB until the process ends) is freed when the result is back.

Copies of one mesh in a scene are simplified once (``lopcook.analyse.instances``, used by
``lopcook.pipeline``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..ingest.weld import sorted_unique, unique_rows, used_ids, weld_exact
from ..memory import release_free_memory
from . import isolate
from ..types import MeshPart

BACKENDS = ("pymeshlab", "fast")
SEAM_MODES = ("lock", "simplify", "ignore", "xatlas")
#: a LOD whose triangle count is off its target by more than this fraction gets a note
TARGET_TOLERANCE = 0.05
#: a backend result more than this factor off its target counts as a failure
TARGET_FAIL_FACTOR = 2.0
#: with locked seams, a LOD that runs into them is redone at this many times the count reached
_SHORT_OF_WALL = 1.1
#: parts with fewer triangles are never simplified
MIN_SIMPLIFY_TRIANGLES = 4
#: a result with more flipped faces than this fraction counts as a failure
MAX_FLIPPED_FRACTION = 0.02
#: a face whose normal is more than 120 degrees from LOD 0's nearby faces is flipped
_FLIP_COS = -0.5
#: corners look for their side of a seam this fraction of the way towards the face centroid
_NUDGE = 0.25
#: corners per step of the transfer's side test (bounds its (k, 3, 3) temporaries)
_TRANSFER_CHUNK = 1 << 17


# --------------------------------------------------------------------------------------------
# results


@dataclass
class Lod:
    """One level of detail of a part.

    part : MeshPart  the simplified mesh (positions float64, indices uint32 CCW, attributes
        carried over); for LOD 0 the input part itself
    target_ratio : float  requested fraction of LOD 0's triangles
    target_triangles : int  ``round(target_ratio * n0)``
    triangles : int  triangles actually produced
    hausdorff_m : float  measured symmetric Hausdorff distance to LOD 0, metres (a lower bound of
        the continuous distance; see the module doc)
    error_m : float  monotone envelope along the chain (``max`` with the previous LOD's error_m)
    backend : str  ``"pymeshlab"``, ``"fast"``, ``"source"`` (LOD 0 / not simplified) or ``"none"``
        (every backend failed)
    seams : str  the seam mode actually used (``"lock"``, ``"simplify"``, ``"ignore"``,
        ``"xatlas"``; ``"-"`` without UVs)
    seconds : float  wall time of simplification, transfer and measurement
    notes : list[str]  fallbacks, warnings, missed targets
    one_sided_m : (float, float)  (LOD -> LOD 0, LOD 0 -> LOD) distances, metres
    flipped : int  faces facing away from LOD 0's nearby faces (kept when under the threshold)
    failed : bool  no backend produced this LOD; ``part`` is then the input it started from
    seam_stats : SeamStats or None  UV seams of the result (None without UVs)
    """

    part: MeshPart
    target_ratio: float
    target_triangles: int
    triangles: int
    hausdorff_m: float
    error_m: float
    backend: str
    seams: str
    seconds: float
    notes: list = field(default_factory=list)
    one_sided_m: tuple = (0.0, 0.0)
    flipped: int = 0
    failed: bool = False
    seam_stats: "SeamStats | None" = None

    def summary(self) -> dict:
        """JSON-friendly description (no arrays)."""
        return {
            "target_ratio": self.target_ratio, "target_triangles": self.target_triangles,
            "triangles": self.triangles, "vertices": self.part.n_vertices,
            "hausdorff_m": self.hausdorff_m, "error_m": self.error_m,
            "one_sided_m": list(self.one_sided_m), "backend": self.backend, "seams": self.seams,
            "seconds": round(self.seconds, 6), "flipped": self.flipped, "failed": self.failed,
            "seam_stats": None if self.seam_stats is None else self.seam_stats.as_dict(),
            "notes": list(self.notes),
        }


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


@dataclass
class LodReport:
    """What ``lod_chain`` did for one part."""

    part: str
    backend: str
    seams: str
    chain: str
    triangles: int
    max_error_m: float | None
    stop_reason: str = ""
    fallbacks: int = 0
    seconds: float = 0.0
    defects: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    lods: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"part": self.part, "backend": self.backend, "seams": self.seams, "chain": self.chain,
                "triangles": self.triangles, "max_error_m": self.max_error_m,
                "stop_reason": self.stop_reason, "fallbacks": self.fallbacks,
                "seconds": round(self.seconds, 6), "defects": dict(self.defects),
                "notes": list(self.notes), "lods": list(self.lods)}


# --------------------------------------------------------------------------------------------
# mesh helpers (vectorised)


def _face_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p0 = positions[faces[:, 0]]  # three (m, 3) gathers: no (m, 3, 3) temporary
    return np.cross(positions[faces[:, 1]] - p0, positions[faces[:, 2]] - p0)


def _degenerate(positions: np.ndarray, faces: np.ndarray, rel_tol: float = 1e-12) -> np.ndarray:
    """(m,) bool: repeated index or zero area (same criterion as ``ingest.weld.degenerate_triangles``)."""
    if faces.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    rep = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    p0, p1, p2 = positions[faces[:, 0]], positions[faces[:, 1]], positions[faces[:, 2]]
    e0, e1, e2 = p1 - p0, p2 - p0, p2 - p1
    del p0, p1
    area2 = np.linalg.norm(np.cross(e0, e1), axis=1)
    longest2 = np.maximum(np.maximum((e0 * e0).sum(1), (e1 * e1).sum(1)), (e2 * e2).sum(1))
    return rep | (longest2 == 0) | (area2 <= rel_tol * longest2)


def _compact(positions: np.ndarray, faces: np.ndarray):
    """Drop unreferenced vertices: (positions, faces, kept vertex ids)."""
    used = np.zeros(positions.shape[0], dtype=bool)
    used[faces.ravel()] = True
    keep = np.flatnonzero(used)
    remap = np.full(positions.shape[0], -1, dtype=np.int64)
    remap[keep] = np.arange(keep.size)
    return positions[keep], remap[faces], keep


def _edge_groups(a: np.ndarray, b: np.ndarray, n: int):
    """Sort half-edges (a_i, b_i) by undirected key: (order, group starts, group sizes)."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * np.int64(max(n, 1)) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]]) if ks.size else np.zeros(0, np.int64)
    sizes = np.diff(np.r_[starts, ks.size])
    return order, starts, sizes


def _components(n_faces: int, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(m,) component label of each face, faces connected through shared vertex ids (labels by
    first face)."""
    if n_faces == 0:
        return np.zeros(0, dtype=np.int64)
    size = n_faces + n_vertices
    cid = np.int32 if size < (1 << 31) - 1 else np.int64  # node ids of the face-vertex graph
    f = np.repeat(np.arange(n_faces, dtype=cid), 3)
    v = faces.ravel().astype(cid) + cid(n_faces)
    g = coo_matrix((np.ones(f.size, dtype=np.int8), (f, v)), shape=(size, size))
    _, lab = connected_components(g, directed=False)
    lab = lab[:n_faces]
    # renumber by first appearance for determinism
    _, first, inv = np.unique(lab, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[inv.ravel()]


def mesh_defects(positions: np.ndarray, indices: np.ndarray, degenerate: np.ndarray | None = None) -> dict:
    """Counts on the position-welded mesh: ``degenerate_faces``, ``boundary_edges``,
    ``nonmanifold_edges`` (more than two faces), ``nonmanifold_vertices`` (bow-ties: faces around
    the vertex form more than one edge-connected fan) and ``closed`` (every edge has two faces)."""
    faces = np.asarray(indices)
    w, n = weld_exact(positions)
    if degenerate is None:
        degenerate = _degenerate(positions, faces.astype(np.int64))
    # int32 ids where they fit: this runs on every LOD input (memory: ~60 bytes per triangle)
    cid = np.int32 if max(3 * faces.shape[0], n) < (1 << 31) - 1 else np.int64
    good = w.astype(cid)[faces[~degenerate]]
    del w
    m = good.shape[0]
    if m == 0:
        return {"degenerate_faces": int(degenerate.sum()), "boundary_edges": 0, "nonmanifold_edges": 0,
                "nonmanifold_vertices": 0, "closed": False}
    a = good.ravel()  # half-edge h = 3f + k runs from corner h to corner cb(h) of face f
    order, starts, sizes = _edge_groups(a, good[:, [1, 2, 0]].ravel(), n)
    # link consecutive half-edges of one edge: corners at the same vertex
    same = np.ones(order.size, dtype=bool)
    same[starts] = False
    del starts
    h2 = order[same].astype(cid)
    h1 = order[np.flatnonzero(same) - 1].astype(cid)
    del order, same
    cb1 = h1 - h1 % 3 + (h1 % 3 + 1) % 3
    cb2 = h2 - h2 % 3 + (h2 % 3 + 1) % 3
    same_dir = a[h1] == a[h2]
    u = np.concatenate([h1, cb1])
    v = np.concatenate([np.where(same_dir, h2, cb2), np.where(same_dir, cb2, h2)])
    del h1, h2, cb1, cb2, same_dir
    g = coo_matrix((np.ones(u.size, dtype=np.int8), (u, v)), shape=(3 * m, 3 * m))
    del u, v
    _, lab = connected_components(g, directed=False)
    del g
    fans = sorted_unique(a.astype(np.int64) * np.int64(3 * m) + lab)
    del lab
    per_vertex = np.bincount(fans // np.int64(3 * m), minlength=n)
    return {
        "degenerate_faces": int(degenerate.sum()),
        "boundary_edges": int((sizes == 1).sum()),
        "nonmanifold_edges": int((sizes > 2).sum()),
        "nonmanifold_vertices": int((per_vertex > 1).sum()),
        "closed": bool((sizes == 2).all()),
    }


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
    islands = _components(m, inv.reshape(m, 3), int(inv.max()) + 1 if inv.size else 0)
    return SeamStats(seam_edges=int(seam_key.size), seam_vertices=int(seam_vertices.size),
                     uv_islands=int(islands.max()) + 1 if islands.size else 0)


def _point_mesh(points: np.ndarray, positions: np.ndarray, faces: np.ndarray):
    """libigl closest points: (squared distance, face id, closest point)."""
    import igl

    d, i, c = igl.point_mesh_squared_distance(np.ascontiguousarray(points, dtype=np.float64),
                                              np.ascontiguousarray(positions, dtype=np.float64),
                                              np.ascontiguousarray(faces, dtype=np.int64))
    return np.asarray(d), np.asarray(i, dtype=np.int64), np.asarray(c)


def _samples(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
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
    dab = float(np.sqrt(_point_mesh(_samples(a.positions, fa), b.positions, fb)[0].max()))
    dba = float(np.sqrt(_point_mesh(_samples(b.positions, fb), a.positions, fa)[0].max()))
    return max(dab, dba), dab, dba


def _barycentric(points: np.ndarray, tri: np.ndarray, clamp: bool) -> np.ndarray:
    """(q, 3) barycentric coordinates of ``points`` projected on triangles ``tri`` (q, 3, 3);
    clamped to the triangle (negative weights set to 0, renormalised) when ``clamp``. Degenerate
    triangles get (1/3, 1/3, 1/3)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00 = (v0 * v0).sum(1)
    d01 = (v0 * v1).sum(1)
    d11 = (v1 * v1).sum(1)
    d20 = (v2 * v0).sum(1)
    d21 = (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    ok = den > 1e-30 * np.maximum(d00 * d11, 1e-300)
    safe = np.where(ok, den, 1.0)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    bary = np.stack([1.0 - v - w, v, w], axis=1)
    bary = np.where(ok[:, None], bary, 1.0 / 3.0)
    if clamp:
        bary = np.clip(bary, 0.0, None)
        s = bary.sum(1, keepdims=True)
        bary = np.where(s > 0, bary / np.where(s > 0, s, 1.0), 1.0 / 3.0)
    return bary


# --------------------------------------------------------------------------------------------
# reference (LOD 0), prepared once per chain


class _Reference:
    """LOD 0 with what every LOD's transfer and measurement needs (computed once)."""

    def __init__(self, part: MeshPart):
        self.part = part
        self.positions = part.positions
        faces = part.indices.astype(np.int64)
        self.faces_all = faces
        self.degenerate = _degenerate(part.positions, faces)
        # zero-area faces carry no surface and no trustworthy normal; keep them only if nothing else
        self.faces = faces[~self.degenerate] if (~self.degenerate).any() and self.degenerate.any() else faces
        fn = _face_normals(part.positions, self.faces)
        ln = np.linalg.norm(fn, axis=1)
        self.face_unit = fn / np.where(ln > 0, ln, 1.0)[:, None]
        self.region = _components(self.faces.shape[0], self.faces, part.n_vertices)
        self._samples = None
        self._sample_vertices = None
        self._tree = None
        self._defects = None
        self._seams = None
        self._volume = None

    def query(self, points: np.ndarray):
        """Closest points on LOD 0 (libigl AABB tree built once): (squared distance, face, point)."""
        import igl

        if self._tree is None:
            self._pos = np.ascontiguousarray(self.positions, dtype=np.float64)
            self._fac = np.ascontiguousarray(self.faces, dtype=np.int64)
            self._tree = igl.AABB()
            self._tree.init(self._pos, self._fac)
        d, i, c = self._tree.squared_distance(self._pos, self._fac, np.ascontiguousarray(points, dtype=np.float64))
        return np.asarray(d), np.asarray(i, dtype=np.int64), np.asarray(c)

    @property
    def samples(self) -> np.ndarray:
        """(len(sample_vertices) + len(faces), 3): the referenced vertices, then the face centroids."""
        if self._samples is None:
            self._samples = _samples(self.positions, self.faces)
        return self._samples

    @property
    def sample_vertices(self) -> np.ndarray:
        """(k,) int64 sorted ids of the vertices in ``samples`` (the first k rows)."""
        if self._sample_vertices is None:
            self._sample_vertices = used_ids(self.faces, self.positions.shape[0])
        return self._sample_vertices

    @property
    def defects(self) -> dict:
        if self._defects is None:
            self._defects = mesh_defects(self.positions, self.faces_all, self.degenerate)
        return self._defects

    @property
    def seams(self) -> SeamStats | None:
        if self._seams is None and self.part.uvs is not None:
            self._seams = seam_stats(self.part)
        return self._seams

    @property
    def volume(self) -> float:
        if self._volume is None:
            self._volume = _signed_volume(self.positions, self.faces)
        return self._volume


def _signed_volume(positions: np.ndarray, faces: np.ndarray) -> float:
    t = positions[faces] - positions[faces].reshape(-1, 3).mean(axis=0)
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)


# --------------------------------------------------------------------------------------------
# backends (module-level so that tests can replace them)


@dataclass
class _BackendResult:
    positions: np.ndarray            # (k, 3) float64
    faces: np.ndarray                # (m, 3) int64
    wedge_uvs: np.ndarray | None = None    # (m, 3, 2) per-corner UVs (pymeshlab texture variants)
    vertex_source: np.ndarray | None = None  # (k,) input vertex each output vertex is (fast)


def _simplify_fast(positions, faces, target, *, lock_border=False) -> _BackendResult:
    """fast-simplification to ``target`` triangles; the collapse map gives ``vertex_source``."""
    import fast_simplification

    p_out, f_out, collapses = fast_simplification.simplify(
        np.ascontiguousarray(positions, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int32),
        target_count=int(target), agg=7.0, return_collapses=True, preserve_border=bool(lock_border))
    n = positions.shape[0]
    rep = np.arange(n, dtype=np.int64)
    collapses = np.asarray(collapses, dtype=np.int64).reshape(-1, 2)
    if collapses.size:
        rep[collapses[:, 1]] = collapses[:, 0]
        for _ in range(64):  # pointer jumping: log2(chain length) rounds
            nxt = rep[rep]
            if np.array_equal(nxt, rep):
                break
            rep = nxt
    used = np.zeros(n, dtype=bool)
    used[np.asarray(faces, dtype=np.int64).ravel()] = True
    survivors = sorted_unique(rep[used])
    source = survivors if survivors.size == p_out.shape[0] else None
    return _BackendResult(np.asarray(p_out, dtype=np.float64), np.asarray(f_out, dtype=np.int64).reshape(-1, 3),
                          vertex_source=source)


def _simplify_pymeshlab(positions, faces, target, *, uvs=None, weld=False, lock_border=True,
                        topology=True) -> _BackendResult:
    """MeshLab quadric edge collapse. With ``uvs`` (per vertex) the texture-aware variant runs on
    per-wedge UVs; ``weld`` first merges vertices with identical positions (seams become
    per-wedge UV discontinuities instead of boundaries)."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    p = np.ascontiguousarray(positions, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    common = dict(targetfacenum=int(target), preserveboundary=bool(lock_border), preservenormal=True,
                  planarquadric=True, optimalplacement=True)
    if uvs is not None:
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=p, face_matrix=f,
                                   v_tex_coords_matrix=np.ascontiguousarray(uvs, dtype=np.float64)))
        ms.compute_texcoord_transfer_vertex_to_wedge()
        if weld:
            ms.meshing_remove_duplicate_vertices()
        ms.meshing_decimation_quadric_edge_collapse_with_texture(**common)
    else:
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=p, face_matrix=f))
        ms.meshing_decimation_quadric_edge_collapse(preservetopology=bool(topology), autoclean=True, **common)
    m = ms.current_mesh()
    out_f = np.asarray(m.face_matrix(), dtype=np.int64).reshape(-1, 3)
    wedge = None
    if uvs is not None and m.has_wedge_tex_coord():
        wedge = np.asarray(m.wedge_tex_coord_matrix(), dtype=np.float64).reshape(-1, 3, 2)
    return _BackendResult(np.asarray(m.vertex_matrix(), dtype=np.float64), out_f, wedge_uvs=wedge)


def _parametrise_xatlas(positions: np.ndarray, indices: np.ndarray):
    """xatlas: (vertex mapping into the input vertices, new indices, uvs float32)."""
    import xatlas

    vmap, ind, uv = xatlas.parametrize(np.ascontiguousarray(positions, dtype=np.float32),
                                       np.ascontiguousarray(indices, dtype=np.uint32))
    return np.asarray(vmap, dtype=np.int64), np.asarray(ind, dtype=np.int64).reshape(-1, 3), np.asarray(uv, np.float32)


# --------------------------------------------------------------------------------------------
# one simplification


class _Failure(Exception):
    """A backend result that must not be used (reason in the message)."""


@dataclass
class _Work:
    """The mesh handed to a backend."""

    positions: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None      # per work vertex (lock: split mesh) or per input vertex (simplify)
    mode: str                   # seam mode
    region: np.ndarray | None = None  # lock: UV island of every work vertex


def _prepare(part: MeshPart, mode: str, degenerate: np.ndarray | None = None) -> tuple[_Work, int]:
    """Clean (drop zero-area faces) and weld/split the input for a backend; returns the work mesh
    and the number of faces dropped. ``degenerate``: ``_degenerate`` of the part if known."""
    faces = part.indices.astype(np.int64)
    bad = _degenerate(part.positions, faces) if degenerate is None else degenerate
    faces = faces[~bad]
    if mode == "simplify":  # pymeshlab welds by position itself and keeps per-wedge UVs
        p, f, keep = _compact(part.positions, faces)
        return _Work(p, f, part.uvs[keep].astype(np.float64), mode), int(bad.sum())
    w, _ = weld_exact(part.positions)
    if mode == "lock":
        uvbits = (np.ascontiguousarray(part.uvs, dtype=np.float32) + np.float32(0.0)).view(np.int32).astype(np.int64)
        first, inv = unique_rows(np.concatenate([w[:, None], uvbits], axis=1))
        f = inv[faces]
        p, f, keep = _compact(part.positions[first], f)
        uv = part.uvs[first][keep].astype(np.float64)
        comp = _components(f.shape[0], f, p.shape[0])
        region = np.zeros(p.shape[0], dtype=np.int64)
        region[f.ravel()] = np.repeat(comp, 3)
        return _Work(p, f, uv, mode, region), int(bad.sum())
    _, first = np.unique(w, return_index=True)  # w is numbered by first appearance
    p, f, _ = _compact(part.positions[first], w[faces])
    return _Work(p, f, None, mode), int(bad.sum())


def _run_backend(backend: str, work: _Work, target: int, lock_border: bool, topology: bool) -> _BackendResult:
    if backend == "fast":
        lock = lock_border if work.mode not in ("lock",) else True
        return _simplify_fast(work.positions, work.faces, target, lock_border=lock)
    simplifier = _simplify_pymeshlab
    if backend == "meshopt":  # pymeshlab's arguments (lopcook.simplify_meshopt)
        from ..simplify_meshopt import simplify_meshopt as simplifier
    if work.mode == "lock":
        return simplifier(work.positions, work.faces, target, uvs=work.uvs, lock_border=True)
    if work.mode == "simplify":
        return simplifier(work.positions, work.faces, target, uvs=work.uvs, weld=True, lock_border=lock_border)
    return simplifier(work.positions, work.faces, target, lock_border=lock_border, topology=topology)


def _check_result(res: _BackendResult, target: int, n_in: int) -> tuple[_BackendResult, int]:
    """Validate and clean a backend result (drop degenerate faces, unreferenced vertices); raise
    _Failure for unusable output. Returns (result, degenerate faces dropped)."""
    p, f = res.positions, res.faces
    if p.ndim != 2 or p.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise _Failure(f"returned arrays of shape {p.shape} / {f.shape}")
    if f.shape[0] == 0:
        raise _Failure("returned no triangles")
    if f.min() < 0 or f.max() >= p.shape[0]:
        raise _Failure("returned out-of-range indices")
    if not np.isfinite(p).all():
        raise _Failure("returned NaN/Inf positions")
    bad = _degenerate(p, f)
    if bad.all():
        raise _Failure("returned only degenerate triangles")
    f = f[~bad]
    wedge = None if res.wedge_uvs is None else res.wedge_uvs[~bad]
    if wedge is not None and not np.isfinite(wedge).all():
        wedge = None
    p2, f2, keep = _compact(p, f)
    source = None if res.vertex_source is None else res.vertex_source[keep]
    m = f2.shape[0]
    if m > TARGET_FAIL_FACTOR * max(target, 1) or m * TARGET_FAIL_FACTOR < target:
        raise _Failure(f"returned {m} triangles for a target of {target} (more than "
                       f"{TARGET_FAIL_FACTOR:g}x off)")
    if m >= n_in and target < n_in:
        raise _Failure(f"did not reduce the mesh ({m} of {n_in} triangles)")
    return _BackendResult(p2, f2, wedge, source), int(bad.sum())


def _interpolate(values: np.ndarray, ref: _Reference, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    corners = ref.faces[face]  # (q, 3) vertex ids
    return np.einsum("qk,qkd->qd", bary, values[corners].astype(np.float64))


#: corner values farther than this from their vertex's value belong to another side of a seam or
#: crease: (normal angle in degrees, UV distance, colour distance)
_SPLIT_NORMAL_DEG = 30.0
_SPLIT_UV = 5e-3
_SPLIT_COLOR = 0.02


def _attributes_at(ref: _Reference, names: list, face: np.ndarray, bary: np.ndarray,
                   fallback_normal: np.ndarray) -> dict:
    """LOD 0's attributes ``names`` interpolated at (face, bary): normals unit (LOD 0's face normal
    where the interpolation vanishes), colours clipped."""
    out = {}
    src = ref.part
    for name in names:
        val = _interpolate(getattr(src, name), ref, face, bary)
        if name == "normals":
            ln = np.linalg.norm(val, axis=1)
            val = np.where((ln > 1e-6)[:, None], val / np.where(ln > 1e-6, ln, 1.0)[:, None], fallback_normal)
        elif name == "colors":
            val = np.clip(val, 0.0, 1.0)
        out[name] = val
    return out


def _differs(a: dict, b: dict) -> np.ndarray:
    bad = None
    for name, va in a.items():
        vb = b[name]
        if name == "normals":
            d = np.einsum("ij,ij->i", va, vb) < np.cos(np.radians(_SPLIT_NORMAL_DEG))
        elif name == "uvs":
            d = np.abs(va - vb).max(axis=1) > _SPLIT_UV
        else:
            d = np.abs(va - vb).max(axis=1) > _SPLIT_COLOR
        bad = d if bad is None else bad | d
    return bad


def _transfer(res: _BackendResult, ref: _Reference, input_part: MeshPart, work: _Work, mode: str,
              max_flipped_fraction: float) -> tuple[MeshPart, dict]:
    """Attributes for the cleaned backend result; flip check; LOD -> LOD 0 distance.

    Every LOD vertex takes LOD 0's attributes at its closest point. A face corner whose own side
    (LOD 0's face nearest to the face centroid, refined by a query pulled ``_NUDGE`` of the way from
    the corner towards the centroid) gives clearly different values at the vertex (beyond the
    ``_SPLIT_*`` tolerances: another side of a seam or crease) gets those values instead; corners
    of one vertex that land in the same LOD 0 region share one value."""
    P, F = res.positions, res.faces
    m, k = F.shape[0], P.shape[0]
    tri = P[F]
    centroid = tri.mean(axis=1)
    d2, fid, closest = ref.query(np.concatenate([P, centroid]))
    fv, fc = fid[:k], fid[k:]
    lod_to_ref = float(np.sqrt(d2.max()))

    # flipped faces: facing away (more than 120 degrees) from LOD 0's nearest face at the centroid
    # and at 2 of the 3 points half-way to the corners (one sample alone is fooled where a coarse
    # face cuts a sharp edge or lies between two sheets)
    fn = _face_normals(P, F)
    fl = np.linalg.norm(fn, axis=1)
    unit = fn / np.where(fl > 0, fl, 1.0)[:, None]
    cand = np.flatnonzero(np.einsum("ij,ij->i", unit, ref.face_unit[fc]) < _FLIP_COS)
    flipped = 0
    if cand.size:
        half = 0.5 * (tri[cand] + centroid[cand][:, None, :])  # (c, 3, 3)
        fh = ref.query(half.reshape(-1, 3))[1].reshape(-1, 3)
        votes = (np.einsum("ij,ikj->ik", unit[cand], ref.face_unit[fh]) < _FLIP_COS).sum(axis=1)
        flipped = int((votes >= 2).sum())
    if flipped > max_flipped_fraction * m and flipped > 0:
        raise _Failure(f"{flipped} of {m} faces are flipped against the source surface")
    if ref.defects["closed"] and abs(ref.volume) > 0:
        vol = _signed_volume(P, F)
        if np.sign(vol) != np.sign(ref.volume):
            raise _Failure("the closed mesh's signed volume changed sign (inside out)")

    src = ref.part
    names = [n for n in ("normals", "colors") if getattr(src, n) is not None]
    uv_from_ref = src.uvs is not None and mode != "xatlas" and res.wedge_uvs is None and not (
        mode == "lock" and res.vertex_source is not None and work.region is not None)
    if uv_from_ref:
        names.append("uvs")
    vid = F.ravel()
    corner_attr = {}
    if names:
        face_of_corner = np.repeat(np.arange(m), 3)
        bary_v = _barycentric(closest[:k], ref.positions[ref.faces[fv]], clamp=True)
        at_v = _attributes_at(ref, names, fv, bary_v, ref.face_unit[fv])
        # phase 1: the corner's side = LOD 0's face nearest to the LOD face's centroid. That face's
        # attribute field, extrapolated linearly to the vertex, matches the vertex's own value on a
        # smooth field and differs across a seam or crease.
        g = fc[face_of_corner]
        split = np.empty(vid.size, dtype=bool)
        for s0 in range(0, vid.size, _TRANSFER_CHUNK):  # row-wise: (chunk, 3, 3) temporaries only
            sl = slice(s0, s0 + _TRANSFER_CHUNK)
            gs, vs = g[sl], vid[sl]
            ext = _attributes_at(ref, names, gs, _barycentric(P[vs], ref.positions[ref.faces[gs]], clamp=False),
                                 ref.face_unit[gs])
            split[sl] = _differs({n: at_v[n][vs] for n in names}, ext)
            del ext
        cs = np.flatnonzero(split)
        at2 = {}
        if cs.size:
            # phase 2: only for corners that look split, find their side near the corner itself
            q = P[vid[cs]]
            q = q + _NUDGE * (centroid[face_of_corner[cs]] - q)
            g2 = ref.query(q)[1]
            g[cs] = g2
            pv_cs = P[vid[cs]]
            tri2 = ref.positions[ref.faces[g2]]
            ext2 = _attributes_at(ref, names, g2, _barycentric(pv_cs, tri2, clamp=False), ref.face_unit[g2])
            split[cs] = _differs({n: at_v[n][vid[cs]] for n in names}, ext2)
            # the value of a split corner: its side's field at the vertex, kept inside that face
            at2 = _attributes_at(ref, names, g2, _barycentric(pv_cs, tri2, clamp=True), ref.face_unit[g2])
        # corners that agree with their vertex share its value; the others group by LOD 0 region
        region = np.where(split, ref.region[g], -1)
        first, group = unique_rows(np.stack([vid, region], axis=1))
        own = ~split[first]
        not_own = np.flatnonzero(~own)
        at_split = np.searchsorted(cs, first[not_own])  # a corner still split after phase 2 is in cs
        for n in names:
            val = at_v[n][vid[first]]
            if not_own.size:
                val[not_own] = at2[n][at_split]
            if n == "normals":
                val = val / np.linalg.norm(val, axis=1, keepdims=True)
            corner_attr[n] = val.astype(np.float32)  # per group; per corner: [group]
    per_group = bool(names)  # every attribute so far is a function of the corner's group
    if src.uvs is not None and mode != "xatlas" and not uv_from_ref:
        if per_group:
            corner_attr = {n: v[group] for n, v in corner_attr.items()}
            per_group = False
        if res.wedge_uvs is not None:
            corner_attr["uvs"] = res.wedge_uvs.reshape(-1, 2).astype(np.float32)
        else:
            corner_attr["uvs"] = _lock_uvs(res, input_part, work)[vid]

    def unique_vertices(row_vid: np.ndarray):
        keys = [row_vid.reshape(-1, 1).astype(np.int64)]
        for name in ("uvs", "normals", "colors"):
            if name in corner_attr:
                keys.append((np.ascontiguousarray(corner_attr[name]) + np.float32(0.0)).view(np.int32)
                            .astype(np.int64))
        return unique_rows(np.concatenate(keys, axis=1))

    if per_group:
        # corners of one group share their row, and groups are numbered by first appearance, so
        # the unique rows of the groups, numbered by first appearance, are those of the corners
        gfirst, ginv = unique_vertices(vid[first])
        vfirst, vinv, pick = first[gfirst], ginv[group], gfirst
    else:
        vfirst, vinv = unique_vertices(vid)
        pick = vfirst
    out = MeshPart(
        name=input_part.name,
        positions=np.ascontiguousarray(P[vid[vfirst]], dtype=np.float64),
        indices=vinv.reshape(m, 3).astype(np.uint32),
        normals=corner_attr["normals"][pick] if "normals" in corner_attr else None,
        uvs=corner_attr["uvs"][pick] if "uvs" in corner_attr else None,
        colors=corner_attr["colors"][pick] if "colors" in corner_attr else None,
        source=input_part.source,
        normals_computed=input_part.normals_computed,
        texture=input_part.texture,
        mesh_key=input_part.mesh_key,
    )
    return out, {"lod_to_ref": lod_to_ref, "flipped": flipped}


def _lock_uvs(res: _BackendResult, input_part: MeshPart, work: _Work) -> np.ndarray:
    """Per output vertex UVs for ``fast`` with locked seams: interpolate the input's UVs at the
    closest point when that point lies in the vertex's own UV island (known from the collapse map),
    else copy the UV of the input vertex it came from."""
    src = res.vertex_source
    P = res.positions
    d2, fid, closest = _point_mesh(P, work.positions, work.faces)
    island_of_face = work.region[work.faces[:, 0]]
    own = work.region[src]
    ok = island_of_face[fid] == own
    bary = _barycentric(closest, work.positions[work.faces[fid]], clamp=True)
    interp = np.einsum("qk,qkd->qd", bary, work.uvs[work.faces[fid]])
    # a vertex that did not move (seam and border vertices are locked) keeps its UV bit for bit
    unmoved = (P == work.positions[src]).all(axis=1)
    return np.where((ok & ~unmoved)[:, None], interp, work.uvs[src]).astype(np.float32)


def _measure_ref_to_lod(ref: _Reference, lod: MeshPart) -> float:
    """max over LOD 0's samples (``ref.samples``: vertices, then face centroids) of the distance to
    ``lod``, metres: the same value as querying every sample, with fewer queries.

    The distance to a surface is 1-Lipschitz, so a centroid c of face (v0, v1, v2) is at most
    ``min_i d(v_i) + |c - v_i|`` from the LOD. The vertices are queried first; a centroid is
    queried only when that bound (plus a 1e-9 relative slack for rounding) reaches the largest
    vertex distance, so the maximum is unchanged (1.1M-triangle bunny, fast to 1/2: 648 of
    1,111,216 centroids are queried). Queries go to one libigl AABB tree over the LOD.
    (Bounding vertices the same way, through edges to a queried quarter of them, still had to
    query 46% of the others there -- edges are about as long as the error -- and was slower.)"""
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


def _xatlas_part(part: MeshPart) -> MeshPart:
    vmap, ind, uv = _parametrise_xatlas(part.positions, part.indices)
    return replace(part, positions=np.ascontiguousarray(part.positions[vmap]), indices=ind.astype(np.uint32),
                   normals=None if part.normals is None else part.normals[vmap], uvs=uv,
                   colors=None if part.colors is None else part.colors[vmap], texture=None)


def parametrise(part: MeshPart) -> MeshPart:
    """``part`` with a fresh xatlas atlas as its UVs (vertices split at the atlas seams; normals and
    colours copied). Any texture is dropped: it does not match the new atlas (re-bake it)."""
    return _xatlas_part(part)


def _unchanged(part: MeshPart, ref: _Reference, ratio: float, target: int, t0: float, notes: list,
               seams: str, failed: bool = False, backend: str = "source") -> Lod:
    if part is ref.part:
        h = (0.0, 0.0, 0.0)
    else:
        h = hausdorff(part, ref.part)
    mode = "-" if part.uvs is None else seams
    return Lod(part=part, target_ratio=ratio, target_triangles=target, triangles=part.n_triangles,
               hausdorff_m=h[0], error_m=h[0], backend=backend, seams=mode, seconds=time.perf_counter() - t0,
               notes=notes, one_sided_m=(h[1], h[2]), failed=failed,
               seam_stats=seam_stats(part) if part.uvs is not None else None)


def _simplify(part: MeshPart, ratio: float, target: int, backend: str, seams: str, ref: _Reference,
              preserve_boundary: bool, fallback: bool, max_flipped_fraction: float,
              _retry: bool = False) -> tuple[Lod, int]:
    """One LOD; returns (lod, fallbacks used)."""
    t0 = time.perf_counter()
    notes: list = []
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if seams not in SEAM_MODES:
        raise ValueError(f"seams must be one of {SEAM_MODES}, got {seams!r}")
    if part.n_triangles < MIN_SIMPLIFY_TRIANGLES:
        notes.append(f"{part.n_triangles} triangles (< {MIN_SIMPLIFY_TRIANGLES}): not simplified")
        return _unchanged(part, ref, ratio, target, t0, notes, seams), 0
    if target >= part.n_triangles:
        notes.append(f"target {target} >= {part.n_triangles} input triangles: not simplified")
        return _unchanged(part, ref, ratio, target, t0, notes, seams), 0
    attempts = [backend] + ([b for b in BACKENDS if b != backend] if fallback else [])
    defects = mesh_defects(part.positions, part.indices) if part is not ref.part else ref.defects
    nonmanifold = defects["nonmanifold_edges"] > 0 or defects["nonmanifold_vertices"] > 0
    if nonmanifold:
        notes.append(f"non-manifold input: {defects['nonmanifold_edges']} edges with more than two faces, "
                     f"{defects['nonmanifold_vertices']} bow-tie vertices (topology preservation off)")
    used_fallbacks = 0
    input_seams = None
    for i, name in enumerate(attempts):
        mode = seams if part.uvs is not None else "-"
        if mode == "simplify" and name == "fast":
            notes.append("fast cannot simplify seams with the mesh: seams='ignore' used")
            mode = "ignore"
        work_mode = "ignore" if mode in ("-", "xatlas") else mode
        try:
            work, dropped = _prepare(part, work_mode, ref.degenerate if part is ref.part else None)
            msg = f"{dropped} zero-area faces dropped before simplification"
            if dropped and msg not in notes:
                notes.append(msg)
            if work.faces.shape[0] < MIN_SIMPLIFY_TRIANGLES:
                raise _Failure(f"only {work.faces.shape[0]} non-degenerate triangles")
            tgt = min(target, work.faces.shape[0] - 1)
            # large inputs: in a child process (its memory is freed on return; a crash is a failure)
            raw = isolate.call(_run_backend, name, work, tgt, preserve_boundary, topology=not nonmanifold,
                               faces=work.faces.shape[0])
            res, dropped_out = _check_result(raw, tgt, work.faces.shape[0])
            if dropped_out:
                notes.append(f"{name}: {dropped_out} degenerate faces dropped from its result")
            lod_part, info = _transfer(res, ref, part, work, mode, max_flipped_fraction)
            if mode == "xatlas":
                try:
                    lod_part = _xatlas_part(lod_part)
                    notes.append("xatlas atlas: the source texture does not match it (texture dropped; re-bake)")
                except Exception as exc:  # noqa: BLE001 - a parametriser failure keeps transferred UVs
                    notes.append(f"xatlas failed ({type(exc).__name__}: {exc}); UVs transferred instead")
            lod_part.validate()
            stats = seam_stats(lod_part)
            if mode == "lock":
                if input_seams is None:
                    input_seams = ref.seams if part is ref.part else seam_stats(part)
                if stats != input_seams:
                    raise _Failure(f"UV seams not kept with seams='lock' ({input_seams.as_dict()} -> "
                                   f"{stats.as_dict()})")
        except Exception as exc:  # noqa: BLE001 - any backend failure falls back, never raises
            what = str(exc) if isinstance(exc, _Failure) else f"{type(exc).__name__}: {exc}"
            nxt = attempts[i + 1] if i + 1 < len(attempts) else None
            notes.append(f"{name} failed: {what}; " + (f"falling back to {nxt}" if nxt else "keeping the previous LOD"))
            used_fallbacks += 1 if nxt else 0
            continue
        if info["flipped"]:
            notes.append(f"{info['flipped']} faces face against the source surface (under the "
                         f"{max_flipped_fraction:.0%} threshold; kept)")
        ref_to_lod = _measure_ref_to_lod(ref, lod_part)
        release_free_memory()  # the transfer's and the LOD tree's temporaries
        h = max(info["lod_to_ref"], ref_to_lod)
        tri = lod_part.n_triangles
        if abs(tri - target) > TARGET_TOLERANCE * target:
            why = " (seams locked: faces touching a UV seam cannot be simplified)" if mode == "lock" else ""
            notes.append(f"{tri} triangles for a target of {target} ({(tri - target) / target:+.1%}){why}")
        if stats is not None and ref.seams is not None and stats != ref.seams and mode != "xatlas":
            notes.append(f"UV seams changed ({mode}): {ref.seams.as_dict()} -> {stats.as_dict()}")
        lod = Lod(part=lod_part, target_ratio=ratio, target_triangles=target, triangles=tri, hausdorff_m=h,
                  error_m=h, backend=name, seams=mode, seconds=time.perf_counter() - t0, notes=notes,
                  one_sided_m=(info["lod_to_ref"], ref_to_lod), flipped=info["flipped"], seam_stats=stats)
        short = int(round(tri * _SHORT_OF_WALL))
        if mode == "lock" and tri > (1 + TARGET_TOLERANCE) * target and short < part.n_triangles and not _retry:
            # the locked seams stopped the backend: its last collapses were forced ones. Stop short of
            # that wall and keep whichever is clearly better.
            alt, _ = _simplify(part, ratio, short, name, seams, ref, preserve_boundary, False,
                               max_flipped_fraction, _retry=True)
            if not alt.failed and alt.hausdorff_m < 0.5 * lod.hausdorff_m:
                miss = " triangles for a target of "
                alt.notes = ([n for n in notes if miss not in n and " faces face against " not in n]
                             + [f"seams locked: the backend stopped at {tri} triangles with error {h:.3g} m; "
                                f"stopping short at {alt.triangles} triangles gives {alt.hausdorff_m:.3g} m (kept); "
                                f"{alt.triangles} triangles for a target of {target} "
                                f"({(alt.triangles - target) / target:+.1%})"]
                             + [n for n in alt.notes if n not in notes and miss not in n])
                alt.target_triangles = target
                alt.seconds = time.perf_counter() - t0
                return alt, used_fallbacks
        return lod, used_fallbacks
    lod = _unchanged(part, ref, ratio, target, t0, notes, seams, failed=True, backend="none")
    return lod, used_fallbacks


def simplify(part: MeshPart, ratio: float, backend: str = "pymeshlab", *, seams: str = "lock",
             reference: MeshPart | None = None, preserve_boundary: bool = True, fallback: bool = True,
             max_flipped_fraction: float = MAX_FLIPPED_FRACTION) -> Lod:
    """Simplify ``part`` to ``round(ratio * reference.n_triangles)`` triangles (``reference``
    defaults to ``part``; it is LOD 0 for error measurement and attribute transfer).

    Never raises for mesh-quality reasons: failures fall back to the other backend (when
    ``fallback``) and are recorded in ``Lod.notes``; when nothing works ``Lod.failed`` is True
    and ``Lod.part`` is ``part``. ``preserve_boundary`` locks open-boundary vertices in both
    backends (always on with ``seams="lock"``, where seams are boundaries). ``seams`` is one of
    ``SEAM_MODES`` (see the module doc); it matters only for parts with UVs.
    """
    ref = _Reference(reference if reference is not None else part)
    target = int(round(ratio * ref.part.n_triangles))
    return _simplify(part, float(ratio), target, backend, seams, ref, preserve_boundary, fallback,
                     max_flipped_fraction)[0]


def lod_chain(part: MeshPart, ratios=None, backend: str = "pymeshlab", *, max_error_m: float | None = None,
              min_triangles: int = MIN_SIMPLIFY_TRIANGLES, seams: str = "lock", chain: str = "previous",
              parametrise: bool = False, preserve_boundary: bool = True, fallback: bool = True,
              max_flipped_fraction: float = MAX_FLIPPED_FRACTION, max_levels: int = 24):
    """A LOD chain for one part: ``(lods, report)`` with ``lods[0]`` = LOD 0 (the part, error 0).

    ratios : fractions of LOD 0's triangles in decreasing order (default 1/2, 1/4, 1/8, ... while
        the target is at least ``min_triangles``; at most ``max_levels`` LODs)
    max_error_m : the largest error any kept LOD may have (metres): the error the farthest view
        can still show. The first LOD above it is dropped and ends the chain. None: no limit.
    chain : ``"previous"`` simplifies each LOD from the one before, ``"source"`` from LOD 0
    parametrise : give a part without UVs an xatlas atlas first (LOD 0 then has UVs)
    Other arguments as for ``simplify``. ``error_m`` is non-decreasing along the returned chain.
    """
    if chain not in ("previous", "source"):
        raise ValueError(f"chain must be 'previous' or 'source', got {chain!r}")
    t0 = time.perf_counter()
    report = LodReport(part=part.name, backend=backend, seams=seams, chain=chain, triangles=part.n_triangles,
                       max_error_m=max_error_m)
    if parametrise and part.uvs is None:
        try:
            part = _xatlas_part(part)
            report.notes.append("no UVs: LOD 0 parametrised with xatlas (no texture to carry)")
        except Exception as exc:  # noqa: BLE001
            report.notes.append(f"xatlas parametrisation failed ({type(exc).__name__}: {exc}); no UVs")
    ref = _Reference(part)
    report.defects = dict(ref.defects)
    lod0 = Lod(part=part, target_ratio=1.0, target_triangles=part.n_triangles, triangles=part.n_triangles,
               hausdorff_m=0.0, error_m=0.0, backend="source", seams="-" if part.uvs is None else seams,
               seconds=0.0, seam_stats=ref.seams)
    lods = [lod0]
    n0 = part.n_triangles
    if n0 < MIN_SIMPLIFY_TRIANGLES:
        report.stop_reason = f"{n0} triangles (< {MIN_SIMPLIFY_TRIANGLES}): LOD 0 only"
        report.notes.append(report.stop_reason)
    else:
        if ratios is None:
            ratios, r = [], 0.5
            while len(ratios) < max_levels and round(r * n0) >= min_triangles:
                ratios.append(r)
                r /= 2
            if not ratios:
                report.stop_reason = f"no target of at least {min_triangles} triangles"
        ratios = sorted({float(r) for r in ratios if 0 < float(r) < 1}, reverse=True)
        for ratio in ratios:
            target = int(round(ratio * n0))
            if target < min_triangles:
                report.stop_reason = f"target {target} below min_triangles {min_triangles}"
                break
            start = lods[-1].part if chain == "previous" else part
            lod, used = _simplify(start, ratio, target, backend, seams, ref, preserve_boundary, fallback,
                                  max_flipped_fraction)
            report.fallbacks += used
            if start is not part and (lod.failed or abs(lod.triangles - target) > TARGET_TOLERANCE * target):
                # the previous LOD's collapses may block this target: try again from LOD 0
                again, used2 = _simplify(part, ratio, target, backend, seams, ref, preserve_boundary, fallback,
                                         max_flipped_fraction)
                report.fallbacks += used2
                if not again.failed and (lod.failed or abs(again.triangles - target) < abs(lod.triangles - target)):
                    again.notes.insert(0, f"simplified from LOD 0: from the previous LOD it "
                                          f"{'failed' if lod.failed else f'gave {lod.triangles} triangles'}")
                    lod = again
            if lod.failed:
                report.stop_reason = f"LOD {ratio:g} could not be produced; previous LODs kept"
                report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
                break
            if lod.triangles >= lods[-1].triangles:
                report.stop_reason = (f"LOD {ratio:g} has {lod.triangles} triangles, no fewer than the previous "
                                      f"LOD's {lods[-1].triangles}; dropped")
                report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
                break
            if lod.hausdorff_m < lods[-1].error_m:
                lod.notes.append(f"measured error {lod.hausdorff_m:.3g} m below the previous LOD's "
                                 f"{lods[-1].error_m:.3g} m: error_m raised to keep the chain monotone")
            lod.error_m = max(lod.hausdorff_m, lods[-1].error_m)
            if max_error_m is not None and lod.error_m > max_error_m:
                report.stop_reason = (f"LOD {ratio:g} error {lod.error_m:.3g} m exceeds max_error_m "
                                      f"{max_error_m:.3g} m; dropped")
                report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
                break
            if lod.triangles < min_triangles:
                report.stop_reason = f"LOD {ratio:g} has {lod.triangles} triangles (< {min_triangles}); dropped"
                break
            lods.append(lod)
            report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
        else:
            if not report.stop_reason:
                report.stop_reason = "all ratios done"
    report.lods = [lod.summary() for lod in lods]
    report.seconds = time.perf_counter() - t0
    return lods, report


__all__ = ["Lod", "LodReport", "SeamStats", "simplify", "lod_chain", "hausdorff", "seam_stats",
           "mesh_defects", "parametrise", "BACKENDS", "SEAM_MODES"]
