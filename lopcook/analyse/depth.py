"""Depth-critical vertices: the precision that keeps every part on its own side of every other part.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 5.2 (depth error; the paper scans all vertex/triangle pairs, O(n^2), and gives
vertices closer than a threshold a fixed user level).

Rule (``auto`` mode). For a vertex v of part i let ``d(v)`` be the distance (metres) to the
nearest surface of any *other* part. Two surfaces at distance d cannot swap depth order when
each moves by less than d/2, so v needs the smallest level b with

    2 * dx(b) < d(v)            (dx(b) = sqrt(3) * extent * 2^-(b+1), see grid.py)

When ``d(v) <= 2 * dx(ceiling)`` the parts touch or intersect there and no affordable precision
separates them: v gets ``ceiling`` (default 16) and is counted as *capped*, and the pair of parts
is reported (never a silent 24-bit blow-up). Parts with a vertex behind the face of another part
it is nearest to (inside a closed part: e.g. chess pieces sunk into the board) are reported as
intersecting.

Guarantees (``depth_levels``). The binding radius of a vertex is ``2 * dx(floor)`` (``floor`` the
level it already has, e.g. from its attribute error): beyond it the exact distance cannot change
m_v. For a vertex v of part i, S(v) are the other parts whose bounding box lies within the binding
radius of v (box distance ``bd``). The distance reported for v is the exact minimum over S(v) of
its distance to their surfaces (inf if S(v) is empty); the nearest part is the one reaching it (on
equal distances, the first in i's visiting order: other parts by box-to-box distance, nearest
first, then by index). For each part i: (1) the (vertex, part) pairs of S, found block by block
(``_Blocks``); (2) every vertex queries first the part of S(v) whose box is nearest to it; (3) then
every other part of S(v) whose ``bd`` is not above the running best. At most
``TREE_BUDGET_TRIANGLES`` triangles' distance trees are kept at once, which changes no distance.
The levels equal those of ``depth_levels_reference``, the paper's O(n*m) scan (tests compare
them). Why the search is exact, its cost, and which intersections it can miss: docs/analyse.md,
"The spatial search of depth_levels".
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ..grid import BITS, dx

DEFAULT_CEILING = 16

#: the most triangles whose distance trees ``depth_levels`` keeps at once, to begin with (a libigl
#: AABB tree and its int64 triangles: a few hundred bytes per triangle, docs/performance.md); the
#: least recently used go first, and one needed again is built again, with the same distances. Each
#: tree built again raises the budget by its triangles, so at most 2 n + T / t trees are built (n
#: parts, T triangles in all, t in the smallest part queried) and a scene whose neighbourhoods do
#: not fit the budget soon stops rebuilding. Trees the current part's step 3 (module doc) may still
#: query are never evicted: the budget can be exceeded.
TREE_BUDGET_TRIANGLES = 1 << 19


@dataclass
class DepthResult:
    """Per part, per vertex: ``level`` (n,) int64 in [1, ceiling] (1 = no depth constraint),
    ``distance`` (n,) float64 metres to the nearest other part (``inf`` where it is farther than the
    binding radius and so was not needed; exact wherever finite: the minimum over the parts whose
    bounding box is within the binding radius, see module doc), ``nearest`` (n,) int64 index of
    that part (-1 if none), ``capped`` (n,) bool. ``touching``: sorted list of (part i, part j) pairs
    with capped vertices; ``intersecting``: pairs (i < j) where a vertex of one lies behind the
    nearest face of the other (inside it, when it is closed). ``queries``: number of exact
    point-to-part distance queries made (a cost measure); ``trees_built``: distance trees built
    (one per queried part, more where ``TREE_BUDGET_TRIANGLES`` evicted one that was needed again)."""

    level: list[np.ndarray]
    distance: list[np.ndarray]
    nearest: list[np.ndarray]
    capped: list[np.ndarray]
    touching: list[tuple[int, int]] = field(default_factory=list)
    intersecting: list[tuple[int, int]] = field(default_factory=list)
    queries: int = 0
    trees_built: int = 0


def level_from_distance(distance: np.ndarray, extent: float) -> np.ndarray:
    """Smallest b in [1, 24] with 2*dx(b) < distance; 25 where even 24 bits are not enough.

    Exact: compares with the thresholds ``2 * dx(b)`` themselves (binary search over the 24 of
    them) rather than taking a logarithm; NaN gives 25 (no level is known to be safe)."""
    d = np.asarray(distance, dtype=np.float64)
    thresholds = 2.0 * dx(np.arange(BITS, 0, -1, dtype=np.float64), extent)  # ascending: b = 24 .. 1
    # the number of b with 2*dx(b) < d is the number of thresholds below d; they are b = 25-k .. 24
    level = (BITS + 1) - np.searchsorted(thresholds, d, side="left").astype(np.int64)
    return np.where(np.isnan(d), BITS + 1, level)


def _bbox_distance(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(n,) Euclidean distance from each point to the axis-aligned box [lo, hi] (0 inside)."""
    gap = np.maximum(np.maximum(lo - points, points - hi), 0.0)
    return np.sqrt(np.einsum("ij,ij->i", gap, gap))


#: vertices per block of the candidate search (see module doc)
_BLOCK = 128


def _bounds(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3,) min and max corner of (n, 3) points (n > 0); per column, much faster than axis=0."""
    return (np.array([points[:, k].min() for k in range(3)]),
            np.array([points[:, k].max() for k in range(3)]))


def _spread_bits_table() -> np.ndarray:
    """(1024,) uint64: the 10 bits of the index moved to every third bit (Morton interleave)."""
    x = np.arange(1024, dtype=np.uint64)
    out = np.zeros(1024, dtype=np.uint64)
    for bit in range(10):
        out |= ((x >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit)
    return out


_SPREAD = _spread_bits_table()


def _morton_code(columns: np.ndarray) -> np.ndarray:
    """(n,) uint64 Morton (Z-order) code of points given as (3, n) coordinate rows, on a 1024^3
    lattice over their bounds."""
    if not np.isfinite(columns).all():
        columns = np.nan_to_num(columns, nan=0.0, posinf=0.0, neginf=0.0)  # only an ordering
    lo = columns.min(axis=1, keepdims=True)
    span = columns.max(axis=1, keepdims=True) - lo
    scale = np.where(span > 0, 1023.0 / np.where(span > 0, span, 1.0), 0.0)
    q = np.clip((columns - lo) * scale, 0, 1023).astype(np.intp)
    return _SPREAD[q[0]] | (_SPREAD[q[1]] << np.uint64(1)) | (_SPREAD[q[2]] << np.uint64(2))


class _Blocks:
    """The vertices of one part in blocks of ``_BLOCK``, sorted by binding radius (largest first, by
    its binary exponent), then in Morton order, each with its bounding box and its largest radius
    (see module doc). The order only affects speed, never which vertices are found."""

    def __init__(self, points: np.ndarray, radius: np.ndarray):
        n = points.shape[0]
        self.n = n
        nb = -(-n // _BLOCK)
        columns = np.ascontiguousarray(points.T)  # (3, n): contiguous rows reduce fast
        exponent = np.frexp(radius)[1].astype(np.int64)  # larger radius, larger exponent
        if n:
            key = ((exponent.max() - exponent) << 30) | _morton_code(columns).astype(np.int64)
        else:
            key = exponent
        self.perm = np.argsort(key)
        # pad to whole blocks by repeating the last vertex (does not change a block's box or radius)
        padded = np.concatenate([self.perm, np.full(nb * _BLOCK - n, self.perm[-1] if n else 0)])
        p = columns.take(padded, axis=1).reshape(3, nb, _BLOCK)  # C-contiguous (fancy indexing is not)
        self.lo = np.ascontiguousarray(np.fmin.reduce(p, axis=2).T)  # fmin/fmax: NaN coordinates
        self.hi = np.ascontiguousarray(np.fmax.reduce(p, axis=2).T)  # do not hide a block
        # squared, with a relative margin: a block may be opened needlessly, never skipped wrongly
        self.r2 = np.fmax.reduce(radius[padded].reshape(nb, _BLOCK), axis=1) ** 2 * (1.0 + 1e-6)

    def near(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Vertex indices (unsorted) of the blocks within their largest radius of the box [lo, hi]."""
        gap = np.maximum(np.maximum(lo - self.hi, self.lo - hi), 0.0)
        rel = np.flatnonzero(np.einsum("ij,ij->i", gap, gap) <= self.r2)
        if rel.size == 0:
            return rel
        starts = rel * _BLOCK
        lens = np.minimum(_BLOCK, self.n - starts)
        offsets = np.cumsum(lens) - lens
        return self.perm[np.arange(int(lens.sum())) + np.repeat(starts - offsets, lens)]


def _finish(levels_raw, distance, nearest, ceiling, n_parts, inside_pairs):
    level, capped, touching = [], [], set()
    for i in range(n_parts):
        raw = levels_raw[i]
        cap = raw > ceiling
        level.append(np.where(cap, ceiling, raw).astype(np.int64))
        capped.append(cap)
        for j in np.unique(nearest[i][cap]):
            touching.add((min(i, int(j)), max(i, int(j))))
    return level, capped, sorted(touching), sorted(inside_pairs)


def _binding_radius(pos: list, extent: float, floors, threshold) -> list:
    """Per part (n_i,) float64 metres: the distance beyond which a vertex's exact distance cannot
    change its level: ``threshold`` (paper mode), else ``2 * dx(floor)`` (floors None: 1)."""
    if threshold is not None:
        return [np.full(p.shape[0], float(threshold)) for p in pos]
    fl = floors if floors is not None else [np.ones(p.shape[0], np.int64) for p in pos]
    # beyond 2*dx(floor) the depth level is <= floor: no need to know the distance exactly
    return [2.0 * dx(np.maximum(np.asarray(f), 1), extent) for f in fl]


def _box_distances(lo: np.ndarray, hi: np.ndarray, i: int) -> np.ndarray:
    """(P,) distance from part i's bounding box to every part's box (lo, hi (P, 3)); inf at i."""
    gap = np.maximum(np.maximum(lo - hi[i], lo[i] - hi), 0.0)
    box_d = np.sqrt((gap * gap).sum(axis=1))
    box_d[i] = np.inf
    return box_d


class _NearestParts:
    """The running nearest-part search of :func:`depth_levels` (module doc, steps 1 to 3).

    ``best[i]`` (n_i,) float64 metres and ``nearest[i]`` (n_i,) int64 hold each vertex's nearest
    other part so far. Distance trees (one libigl AABB and its (m, 3) int64 triangles per part)
    are kept in ``trees``, least recently used first, within ``budget`` triangles except those
    ``pinned`` (the current part's step 3 may still query them); ``queries`` counts the exact
    point-to-part distances, ``builds`` the trees built, ``inside_pairs`` the intersecting pairs."""

    def __init__(self, pos: list, tris: list, detect_intersections: bool):
        self.pos, self.tris = pos, tris
        self.detect_intersections = detect_intersections
        self.best = [np.full(p.shape[0], np.inf) for p in pos]
        self.nearest = [np.full(p.shape[0], -1, dtype=np.int64) for p in pos]
        # part -> (igl.AABB, its (m, 3) int64 triangles), least recently used first
        self.trees: OrderedDict[int, tuple] = OrderedDict()
        self.builds = 0
        self.pinned: set[int] = set()  # parts whose trees the current part's pass (c) may still query
        self.evicted: set[int] = set()  # parts whose trees were evicted before their last user
        self.budget = TREE_BUDGET_TRIANGLES
        self.inside_pairs: set[tuple[int, int]] = set()
        self.queries = 0

    def free_before(self, last_user: np.ndarray, i: int) -> None:
        """Free the trees of the parts no part from i on may query (``last_user`` (P,) < i)."""
        for j in [j for j in self.trees if last_user[j] <= i - 1]:
            del self.trees[j]

    def _tree(self, j: int) -> tuple:
        """Part j's (AABB tree, int64 triangles), built if needed. Least recently used trees go
        first while the new one would pass the budget, except those this part's pass (c) may
        still query (evicting them would build them again). A tree built again raises the
        budget by its size, so a scene whose neighbourhoods do not fit the budget stops
        rebuilding."""
        trees = self.trees
        if j in trees:
            trees.move_to_end(j)
            return trees[j]
        size_j = self.tris[j].shape[0]
        if j in self.evicted:
            self.budget += size_j
        alive = sum(t[1].shape[0] for t in trees.values())
        for k in [k for k in trees if k not in self.pinned]:
            if alive + size_j <= self.budget:
                break
            alive -= trees.pop(k)[1].shape[0]
            self.evicted.add(k)
        tj = np.ascontiguousarray(self.tris[j], dtype=np.int64)
        # imported here: a scene whose parts never come near each other builds no tree
        # (docs/performance.md, "Start-up")
        import igl

        tree = igl.AABB()
        tree.init(self.pos[j], tj)
        trees[j] = (tree, tj)
        self.builds += 1
        return trees[j]

    def query(self, i: int, j: int, cand: np.ndarray, rank: np.ndarray) -> None:
        """Exact distances from vertices ``cand`` of part i to part j; keep the smaller (equal
        distances: the part earliest in i's visiting order ``rank`` (P,) wins)."""
        tree, tj = self._tree(j)
        pos = self.pos
        best, nearest = self.best[i], self.nearest[i]
        points = pos[i][cand]
        d2, face, closest = tree.squared_distance(pos[j], tj, points)
        self.queries += cand.size
        d = np.sqrt(d2)
        cur = best[cand]
        better = d < cur
        # equal distances: the part earliest in i's visiting order wins (as if visited in that order)
        tie = (d == cur) & (nearest[cand] >= 0)
        if tie.any():
            better |= tie & (rank[j] < rank[nearest[cand]])
        best[cand[better]] = d[better]
        nearest[cand[better]] = j
        pair = (min(i, j), max(i, j))
        if self.detect_intersections and pair not in self.inside_pairs:
            if _any_inside(points, face, closest, pos[j], tj):
                self.inside_pairs.add(pair)

    def part(self, i: int, order: np.ndarray, rank: np.ndarray, lo: np.ndarray, hi: np.ndarray,
             radius: np.ndarray) -> None:
        """The nearest other part of every vertex of part i among the parts ``order`` (nearest
        box first), with binding radii ``radius`` (n_i,) metres (module doc, steps 1 to 3)."""
        pos_i = self.pos[i]
        # (a) the (vertex, part) pairs whose box distance is within the vertex's binding radius
        blocks = _Blocks(pos_i, radius)
        pairs = []
        for j in order:
            verts = blocks.near(lo[j], hi[j])
            if verts.size == 0:
                continue
            bd = _bbox_distance(pos_i[verts], lo[j], hi[j])
            keep = bd <= radius[verts]
            if keep.any():
                pairs.append((int(j), verts[keep], bd[keep]))
        # (b) every vertex first queries the part whose box is nearest to it (usually the nearest
        # surface, so best is tight from the start) ...
        first = np.full(pos_i.shape[0], -1, dtype=np.int64)
        first_bd = np.full(pos_i.shape[0], np.inf)
        for j, verts, bd in pairs:
            closer = bd < first_bd[verts]
            first_bd[verts[closer]] = bd[closer]
            first[verts[closer]] = j
        best = self.best[i]
        self.pinned.clear()
        for j, verts, bd in pairs:
            cand = verts[first[verts] == j]
            if cand.size:
                self.query(i, j, cand, rank)
                # pass (c) queries j only where bd <= best, and best only falls: if no vertex is
                # there now, none will be, and j's tree may be evicted
                if np.any((bd <= best[verts]) & (first[verts] != j)):
                    self.pinned.add(j)
        # (c) ... then every other part whose box is not farther than the best distance so far
        for j, verts, bd in pairs:
            cand = verts[(bd <= best[verts]) & (first[verts] != j)]
            if cand.size:
                self.query(i, j, cand, rank)
            self.pinned.discard(j)


def depth_levels(positions: list[np.ndarray], indices: list[np.ndarray], extent: float, *,
                 floors: list[np.ndarray] | None = None, ceiling: int = DEFAULT_CEILING,
                 threshold: float | None = None, detect_intersections: bool = True) -> DepthResult:
    """Depth levels for every vertex of every part (spatial index; see module doc).

    Parameters
    ----------
    positions : list of (n_i, 3) float64, metres
    indices : list of (m_i, 3) integer triangles
    extent : float, metres, the scene grid's extent
    floors : list of (n_i,) int levels the vertices already need (None: 1). The exact distance is
        only looked up where it could raise a vertex above its floor.
    ceiling : int in [1, 24]: the highest level a depth constraint may impose.
    threshold : float or None. Paper mode: if given, only vertices closer than ``threshold``
        metres are depth-critical; ``level`` is then 1/0-valued "critical" (the caller assigns
        the user's fixed level), and floors are ignored.
    """
    n_parts = len(positions)
    pos = [np.ascontiguousarray(p, dtype=np.float64) for p in positions]
    tris = list(indices)  # int64 copies are made per part with its tree, and freed with it
    bounds = [_bounds(p) for p in pos]
    lo = np.array([b[0] for b in bounds]).reshape(n_parts, 3)
    hi = np.array([b[1] for b in bounds]).reshape(n_parts, 3)
    radius = _binding_radius(pos, extent, floors, threshold)
    search = _NearestParts(pos, tris, detect_intersections)
    rmax = np.array([r.max() if r.size else 0.0 for r in radius])
    # the last part whose loop may query part j (its box within that part's largest radius): part
    # j's tree and int64 triangles are freed once that part is done, the same distances either way
    last_user = np.full(n_parts, -1, dtype=np.int64)
    for i in range(n_parts if n_parts >= 2 else 0):
        last_user[_box_distances(lo, hi, i) <= rmax[i]] = i
    for i in range(n_parts if n_parts >= 2 else 0):
        # other parts ordered by box-to-box distance, nearest first (the tie-break for `nearest`)
        box_d = _box_distances(lo, hi, i)
        order = np.argsort(box_d, kind="stable")
        order = order[box_d[order] <= rmax[i]]
        search.free_before(last_user, i)
        if order.size == 0:
            continue
        rank = np.empty(n_parts, dtype=np.int64)
        rank[order] = np.arange(order.size)
        search.part(i, order, rank, lo, hi, radius[i])
    best, nearest = search.best, search.nearest
    inside_pairs = search.inside_pairs
    if threshold is not None:
        raw = [np.where(b < threshold, 2, 1).astype(np.int64) for b in best]
        level = [r - 1 for r in raw]  # 1 = critical, 0 = not
        capped = [np.zeros(p.shape[0], bool) for p in pos]
        return DepthResult(level, best, nearest, capped, [], sorted(inside_pairs), search.queries, search.builds)
    raw = [level_from_distance(b, extent) for b in best]
    level, capped, touching, inter = _finish(raw, best, nearest, ceiling, n_parts, inside_pairs)
    return DepthResult(level, best, nearest, capped, touching, inter, search.queries, search.builds)


def _unit_face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(m, 3) unit face normals (zero for zero-area triangles)."""
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(n, axis=1)
    return n / np.where(length > 0, length, 1.0)[:, None]


def _any_inside(points, face, closest, v, f, unit_n=None, margin=1e-9) -> bool:
    """True if some point lies behind the face it is nearest to, with the nearest point strictly
    inside that face (barycentric coordinates > 1e-6), by more than ``margin`` x the face size.

    ``unit_n``: (m, 3) unit normals of all faces of ``f``, or None to compute them for the faces in
    ``face`` only (same values).

    Restricting to face-interior nearest points avoids the sign ambiguity at edges and corners,
    so this reports a vertex of one part sunk inside another closed part (no false positives on
    sharp edges; it can miss an intersection whose every sunk vertex is nearest an edge)."""
    if points.shape[0] == 0:
        return False
    tri = v[f[face]]
    n = unit_n[face] if unit_n is not None else _unit_face_normals(v, f[face])
    behind = np.einsum("ij,ij->i", points - closest, n) < -margin * np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1)
    if not behind.any():
        return False
    sel = np.flatnonzero(behind)
    t = tri[sel]
    c = closest[sel]
    # barycentric coordinates of the closest point
    e0, e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], c - t[:, 0]
    d00 = np.einsum("ij,ij->i", e0, e0)
    d01 = np.einsum("ij,ij->i", e0, e1)
    d11 = np.einsum("ij,ij->i", e1, e1)
    d20 = np.einsum("ij,ij->i", e2, e0)
    d21 = np.einsum("ij,ij->i", e2, e1)
    den = d00 * d11 - d01 * d01
    ok = den > 0
    den = np.where(ok, den, 1.0)
    bv = (d11 * d20 - d01 * d21) / den
    bw = (d00 * d21 - d01 * d20) / den
    bu = 1.0 - bv - bw
    interior = ok & (bu > 1e-6) & (bv > 1e-6) & (bw > 1e-6)
    return bool(interior.any())


# --- the paper's O(n^2) reference ------------------------------------------------------------

def point_triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Euclidean distance from points p to triangles (a, b, c), all (k, 3) broadcastable -> (k,).

    Closest-point regions after Ericson, Real-Time Collision Detection, 5.1.5; degenerate
    triangles fall back to the nearest of their three edges."""
    p, a, b, c = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (p, a, b, c)))

    def seg(p, u, v):
        e = v - u
        ee = np.einsum("...j,...j->...", e, e)
        t = np.where(ee > 0, np.einsum("...j,...j->...", p - u, e) / np.where(ee > 0, ee, 1.0), 0.0)
        t = np.clip(t, 0.0, 1.0)
        q = u + t[..., None] * e
        return np.sqrt(np.einsum("...j,...j->...", p - q, p - q))

    edge = np.minimum(np.minimum(seg(p, a, b), seg(p, b, c)), seg(p, c, a))
    n = np.cross(b - a, c - a)
    nn = np.einsum("...j,...j->...", n, n)
    ok = nn > 0
    nn_safe = np.where(ok, nn, 1.0)
    # barycentric test of the projection onto the plane
    w = p - a
    s_ab = np.einsum("...j,...j->...", np.cross(b - a, w), n)
    s_bc = np.einsum("...j,...j->...", np.cross(c - b, p - b), n)
    s_ca = np.einsum("...j,...j->...", np.cross(a - c, p - c), n)
    inside = ok & (s_ab >= 0) & (s_bc >= 0) & (s_ca >= 0)
    plane = np.abs(np.einsum("...j,...j->...", w, n)) / np.sqrt(nn_safe)
    return np.where(inside, plane, edge)


def depth_levels_reference(positions: list[np.ndarray], indices: list[np.ndarray], extent: float, *,
                           ceiling: int = DEFAULT_CEILING) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The paper's scan: every vertex against every triangle of every other part, O(n * m).

    Returns (levels, distances) per part, levels capped at ``ceiling`` like ``depth_levels``."""
    levels, dists = [], []
    for i, p in enumerate(positions):
        others = [np.asarray(positions[j])[np.asarray(indices[j], dtype=np.int64)]
                  for j in range(len(positions)) if j != i]
        if not others:
            d = np.full(p.shape[0], np.inf)
        else:
            t = np.concatenate(others)  # (m, 3, 3)
            d = np.empty(p.shape[0])
            for k in range(p.shape[0]):  # reference only: one vertex at a time, all triangles at once
                d[k] = point_triangle_distance(p[k][None], t[:, 0], t[:, 1], t[:, 2]).min()
        raw = level_from_distance(d, extent)
        levels.append(np.minimum(raw, ceiling))
        dists.append(d)
    return levels, dists


__all__ = ["depth_levels", "depth_levels_reference", "level_from_distance", "point_triangle_distance",
           "DepthResult", "DEFAULT_CEILING", "BITS"]
