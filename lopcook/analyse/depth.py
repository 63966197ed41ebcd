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

Implementation (``depth_levels``): one libigl AABB tree per part, built on demand; for each part
pair, only vertices whose distance to the other part's bounding box is below both their current
best distance and their *binding radius* are queried. The binding radius is ``2 * dx(floor)``:
beyond it the depth level would not exceed the level the vertex already has (``floor``, e.g. from
its attribute error), so the exact distance there cannot change m_v. Cost O(n log n) for scenes
whose parts are spatially separated; ``depth_levels_reference`` is the paper's O(n*m) scan and
gives identical levels (tests compare them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .grid import BITS, dx, smallest_level

DEFAULT_CEILING = 16


@dataclass
class DepthResult:
    """Per part, per vertex: ``level`` (n,) int64 in [1, ceiling] (1 = no depth constraint),
    ``distance`` (n,) float64 metres to the nearest other part (``inf`` where it is farther than the
    binding radius and so was not needed), ``nearest`` (n,) int64 index of that part (-1 if none),
    ``capped`` (n,) bool. ``touching``: sorted list of (part i, part j) pairs with capped vertices;
    ``intersecting``: pairs (i < j) where a vertex of one lies behind the nearest face of the other
    (inside it, when it is closed)."""

    level: list[np.ndarray]
    distance: list[np.ndarray]
    nearest: list[np.ndarray]
    capped: list[np.ndarray]
    touching: list[tuple[int, int]] = field(default_factory=list)
    intersecting: list[tuple[int, int]] = field(default_factory=list)
    queries: int = 0


def level_from_distance(distance: np.ndarray, extent: float) -> np.ndarray:
    """Smallest b in [1, 24] with 2*dx(b) < distance; 25 where even 24 bits are not enough."""
    d = np.asarray(distance, dtype=np.float64)
    return smallest_level(lambda b: 2.0 * dx(b, extent) < d[..., None], d.shape)


def _bbox_distance(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(n,) Euclidean distance from each point to the axis-aligned box [lo, hi] (0 inside)."""
    gap = np.maximum(np.maximum(lo - points, points - hi), 0.0)
    return np.sqrt(np.einsum("ij,ij->i", gap, gap))


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
    import igl

    n_parts = len(positions)
    pos = [np.ascontiguousarray(p, dtype=np.float64) for p in positions]
    tris = [np.ascontiguousarray(t, dtype=np.int64) for t in indices]
    lo = np.array([p.min(axis=0) for p in pos])
    hi = np.array([p.max(axis=0) for p in pos])
    if threshold is not None:
        radius = [np.full(p.shape[0], float(threshold)) for p in pos]
    else:
        fl = floors if floors is not None else [np.ones(p.shape[0], np.int64) for p in pos]
        # beyond 2*dx(floor) the depth level is <= floor: no need to know the distance exactly
        radius = [2.0 * dx(np.maximum(np.asarray(f), 1), extent) for f in fl]
    best = [np.full(p.shape[0], np.inf) for p in pos]
    nearest = [np.full(p.shape[0], -1, dtype=np.int64) for p in pos]
    trees: dict[int, object] = {}
    unit_normals: dict[int, np.ndarray] = {}
    inside_pairs: set[tuple[int, int]] = set()
    queries = 0
    rmax = np.array([r.max() if r.size else 0.0 for r in radius])
    for i in range(n_parts):
        if n_parts < 2:
            break
        # other parts ordered by box-to-box distance, nearest first (best shrinks fast)
        gap = np.maximum(np.maximum(lo - hi[i], lo[i] - hi), 0.0)
        box_d = np.sqrt((gap * gap).sum(axis=1))
        box_d[i] = np.inf
        for j in np.argsort(box_d, kind="stable"):
            if not box_d[j] <= rmax[i]:
                break
            limit = np.minimum(best[i], radius[i])
            cand = np.flatnonzero(_bbox_distance(pos[i], lo[j], hi[j]) <= limit)
            if cand.size == 0:
                continue
            tree = trees.get(j)
            if tree is None:
                tree = igl.AABB()
                tree.init(pos[j], tris[j])
                trees[j] = tree
            d2, face, closest = tree.squared_distance(pos[j], tris[j], pos[i][cand])
            queries += cand.size
            d = np.sqrt(d2)
            better = d < best[i][cand]
            best[i][cand[better]] = d[better]
            nearest[i][cand[better]] = j
            if detect_intersections and (min(i, int(j)), max(i, int(j))) not in inside_pairs:
                if j not in unit_normals:
                    unit_normals[j] = _unit_face_normals(pos[j], tris[j])
                if _any_inside(pos[i][cand], face, closest, pos[j], tris[j], unit_normals[j]):
                    inside_pairs.add((min(i, int(j)), max(i, int(j))))

    if threshold is not None:
        raw = [np.where(b < threshold, 2, 1).astype(np.int64) for b in best]
        level = [r - 1 for r in raw]  # 1 = critical, 0 = not
        capped = [np.zeros(p.shape[0], bool) for p in pos]
        return DepthResult(level, best, nearest, capped, [], sorted(inside_pairs), queries)
    raw = [level_from_distance(b, extent) for b in best]
    level, capped, touching, inter = _finish(raw, best, nearest, ceiling, n_parts, inside_pairs)
    return DepthResult(level, best, nearest, capped, touching, inter, queries)


def _unit_face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(m, 3) unit face normals (zero for zero-area triangles)."""
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(n, axis=1)
    return n / np.where(length > 0, length, 1.0)[:, None]


def _any_inside(points, face, closest, v, f, unit_n, margin=1e-9) -> bool:
    """True if some point lies behind the face it is nearest to, with the nearest point strictly
    inside that face (barycentric coordinates > 1e-6), by more than ``margin`` x the face size.

    Restricting to face-interior nearest points avoids the sign ambiguity at edges and corners,
    so this reports a vertex of one part sunk inside another closed part (no false positives on
    sharp edges; it can miss an intersection whose every sunk vertex is nearest an edge)."""
    if points.shape[0] == 0:
        return False
    tri = v[f[face]]
    n = unit_n[face]
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
