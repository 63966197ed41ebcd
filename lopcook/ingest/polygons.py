"""Polygon triangulation shared by the OBJ, USD and PLY loaders.

Triangles pass through, quads are split vectorised along the diagonal that keeps both halves
facing the polygon's normal (so concave quads come out right), and n-gons (5+ corners) are
triangulated in the plane of their Newell normal: convex and zero-area ones fanned in O(k),
concave ones of at most ``EAR_CLIP_MAX_CORNERS`` corners ear-clipped (kept for those so their
triangles, and the containers cooked from them, stay as they were), larger concave ones by
earcut (Mapbox's ear clipper with z-order hashing, PyPI ``mapbox-earcut``) up to
``MAX_CONCAVE_CORNERS``. A polygon of more than ``REPEAT_CHECK_CORNERS`` corners must list at
least half as many distinct positions as corners (``check_distinct_corners`` checks vertex ids
before positions are gathered). Only n-gons take a Python loop, one iteration per n-gon;
triangle and quad meshes (the common case) never do. Costs measured: docs/ingest.md, "Polygons".

Winding is preserved: each output triangle turns the same way as the polygon it came from.

earcut drops a corner that repeats its neighbour's position (and may drop collinear ones), so
such a concave polygon gets fewer than k - 2 triangles, covering its area exactly. When earcut's triangles do not tile the
polygon (sum of their unsigned areas differs from the shoelace area: a self-intersecting
polygon), the polygon is fanned from corner 0 instead: k - 2 triangles whose signed areas still
sum to the polygon's.
"""

from __future__ import annotations

import mapbox_earcut
import numpy as np


#: largest concave polygon ear-clipped by the Python clipper (worst case quadratic to cubic in
#: the corners); larger ones go to earcut
EAR_CLIP_MAX_CORNERS = 16

#: largest concave polygon triangulated at all: earcut's time grows about quadratically on stars
#: and faster on self-intersecting polygons (at most about 0.3 s at 10,000 corners, 6 s at 30,000,
#: 7 s for a 100,000-corner star); convex and zero-area polygons of any size are fanned in O(k)
MAX_CONCAVE_CORNERS = 10_000

#: a polygon of more corners than this must list at least half as many distinct positions as
#: corners: a simple polygon lists each corner once (twice where a bridge joins a hole), so one
#: that goes round a few positions again and again (a 10 MB face line over 4 vertices) describes
#: no surface, only millions of overlapping triangles, and is refused before they are made
REPEAT_CHECK_CORNERS = 64

_REPEAT_HINT = "list each corner of the polygon once, or triangulate it in the exporter"

#: relative tolerance of the check that earcut's triangles tile the polygon
_AREA_RTOL = 1e-9


class PolygonTooComplex(ValueError):
    """A polygon lopcook does not triangulate: a concave one with more than
    ``MAX_CONCAVE_CORNERS`` corners, or one of more than ``REPEAT_CHECK_CORNERS`` corners that lists
    fewer distinct positions than half its corners (the loaders turn it into one LopcookError
    naming the file). ``face`` is the polygon's index in ``triangulate``'s ``counts`` (None from
    ``triangulate_polygon``); ``hint`` says what to do."""

    def __init__(self, message: str, face: int | None = None, hint: str | None = None):
        super().__init__(message)
        self.face = face
        self.hint = hint or "split the polygon into smaller ones, or triangulate it, in the exporter"


def _newell(pts: np.ndarray) -> np.ndarray:
    """(k, 3) polygon -> (3,) Newell normal (length = 2 * projected area)."""
    nxt = np.roll(pts, -1, axis=0)
    return np.array([
        np.sum((pts[:, 1] - nxt[:, 1]) * (pts[:, 2] + nxt[:, 2])),
        np.sum((pts[:, 2] - nxt[:, 2]) * (pts[:, 0] + nxt[:, 0])),
        np.sum((pts[:, 0] - nxt[:, 0]) * (pts[:, 1] + nxt[:, 1])),
    ])


def _point_in_triangle(p: np.ndarray, a, b, c) -> np.ndarray:
    """p: (k, 2); a, b, c: (2,) counter-clockwise -> (k,) bool, boundary counts as inside."""
    def cross(o, u, v):
        return (u[..., 0] - o[..., 0]) * (v[..., 1] - o[..., 1]) - (u[..., 1] - o[..., 1]) * (v[..., 0] - o[..., 0])

    return (cross(a, b, p) >= 0) & (cross(b, c, p) >= 0) & (cross(c, a, p) >= 0)


def _signed_areas(pts: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(k, 2) corners, (T, 3) indices -> (T,) signed areas (positive: counter-clockwise)."""
    a, b, c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _ear_clip(pts: np.ndarray) -> np.ndarray:
    """(k, 2) counter-clockwise simple polygon -> (k - 2, 3) int64 corner indices, each triangle
    counter-clockwise; a remainder no ear can be clipped from (collinear or self-intersecting
    corners) is fanned, keeping the count k - 2."""
    k = pts.shape[0]
    ring = list(range(k))
    tris: list[tuple[int, int, int]] = []
    guard = 0
    while len(ring) > 3 and guard < 4 * k * k:
        guard += 1
        m = len(ring)
        clipped = False
        for j in range(m):
            i0, i1, i2 = ring[j - 1], ring[j], ring[(j + 1) % m]
            a, b, c = pts[i0], pts[i1], pts[i2]
            turn = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
            if turn <= 0:
                continue  # reflex or collinear corner: not an ear
            others = [r for r in ring if r not in (i0, i1, i2)]
            if others:
                inside = _point_in_triangle(pts[others], a, b, c)
                # a vertex that coincides with a corner of the ear does not block it
                same = (np.all(pts[others] == a, axis=1) | np.all(pts[others] == b, axis=1)
                        | np.all(pts[others] == c, axis=1))
                if np.any(inside & ~same):
                    continue
            tris.append((i0, i1, i2))
            ring.pop(j)
            clipped = True
            break
        if not clipped:
            # degenerate (collinear or self-intersecting) remainder: fan it, keeping the count k-2
            for j in range(1, len(ring) - 1):
                tris.append((ring[0], ring[j], ring[j + 1]))
            ring = ring[:0]
            break
    if len(ring) == 3:
        tris.append((ring[0], ring[1], ring[2]))
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def _earcut(pts: np.ndarray, fan: np.ndarray) -> np.ndarray:
    """(k, 2) counter-clockwise polygon -> (T, 3) int64 counter-clockwise triangles by earcut,
    T <= k - 2 (repeated corners dropped); ``fan`` when earcut's triangles do not
    tile the polygon (module docstring)."""
    k = pts.shape[0]
    tris = mapbox_earcut.triangulate_float64(np.ascontiguousarray(pts, dtype=np.float64),
                                             np.array([k], dtype=np.uint32))
    tris = tris.astype(np.int64).reshape(-1, 3)
    areas = _signed_areas(pts, tris)
    if areas.sum() < 0:  # earcut's own orientation: turn its triangles like the polygon
        tris, areas = tris[:, ::-1], -areas
    shoelace = 0.5 * float(np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1]))
    if tris.shape[0] == 0 or abs(float(np.abs(areas).sum()) - shoelace) > _AREA_RTOL * abs(shoelace):
        return fan
    return np.ascontiguousarray(tris)


def _check_distinct(pts3: np.ndarray) -> None:
    """Raise ``PolygonTooComplex`` when the (k, 3) corners hold fewer than k / 2 distinct
    positions. O(k log k): distinct values of one projection are distinct positions, so the exact
    row count is only taken when the projection has too few."""
    k = pts3.shape[0]
    need = (k + 1) // 2
    if np.unique(pts3 @ np.array([1.0, 0.7548776662466927, 0.5698402909980532])).size >= need:
        return
    rows = pts3[np.lexsort(pts3.T[::-1])]
    distinct = 1 + int(np.count_nonzero(np.any(rows[1:] != rows[:-1], axis=1)))
    if distinct < need:
        raise PolygonTooComplex(f"a polygon has {k:,} corners but only {distinct:,} distinct positions; lopcook "
                                f"triangulates polygons of more than {REPEAT_CHECK_CORNERS} corners only when "
                                "at least half their corners are distinct",
                                hint=_REPEAT_HINT)


def triangulate_polygon(pts3: np.ndarray) -> np.ndarray:
    """Triangulate one polygon (possibly concave).

    Parameters
    ----------
    pts3 : (k, 3) float64, k >= 3, corners in order

    Returns
    -------
    (T, 3) int64 local corner indices, same turning direction as the input. T = k - 2 except for
    a concave polygon of more than ``EAR_CLIP_MAX_CORNERS`` corners with a corner repeating its
    neighbour (fewer; module docstring). A polygon without area (coincident or collinear corners)
    and a convex one are fanned from corner 0 in O(k); a concave one with more than
    ``MAX_CONCAVE_CORNERS`` corners, and one of more than ``REPEAT_CHECK_CORNERS`` corners with
    fewer distinct positions than half its corners, raise ``PolygonTooComplex``.
    """
    k = pts3.shape[0]
    if k > REPEAT_CHECK_CORNERS:
        _check_distinct(pts3)
    normal = _newell(pts3)
    axis = int(np.argmax(np.abs(normal)))
    keep = [(axis + 1) % 3, (axis + 2) % 3]  # cyclic, so (a, b) x-ed gives +axis (right-handed)
    pts = pts3[:, keep].astype(np.float64)
    if normal[axis] < 0:  # make the 2-D projection counter-clockwise
        pts = pts[:, ::-1]
    fan = np.stack([np.zeros(k - 2, np.int64), np.arange(1, k - 1), np.arange(2, k)], axis=1)
    size = float(np.max(np.ptp(pts3, axis=0))) if k else 0.0
    if not np.abs(normal).max() > 1e-12 * size * size:
        return fan  # no area (all corners coincide or are collinear): any triangulation is as good
    nxt, prv = np.roll(pts, -1, axis=0), np.roll(pts, 1, axis=0)
    turns = (pts[:, 0] - prv[:, 0]) * (nxt[:, 1] - prv[:, 1]) - (pts[:, 1] - prv[:, 1]) * (nxt[:, 0] - prv[:, 0])
    if np.all(turns > 0):
        return fan  # convex (every corner turns left): the fan is exact, O(k)
    if k > MAX_CONCAVE_CORNERS:
        raise PolygonTooComplex(f"a concave polygon has {k:,} corners; lopcook triangulates concave polygons of "
                                f"at most {MAX_CONCAVE_CORNERS:,} (convex and zero-area ones of any size)")
    if k <= EAR_CLIP_MAX_CORNERS:
        return _ear_clip(pts)
    return _earcut(pts, fan)


def check_distinct_corners(counts: np.ndarray, corner_ids: np.ndarray) -> None:
    """Raise ``PolygonTooComplex`` (with ``face``) for the first polygon of more than
    ``REPEAT_CHECK_CORNERS`` corners whose (C,) int ``corner_ids`` (the vertex record of each
    corner, polygon after polygon) name fewer distinct records than half its corners. A loader
    that has the ids calls this before gathering corner positions, so such a polygon is refused
    before any per-corner position is made; ``triangulate`` checks the positions again."""
    counts = np.asarray(counts, dtype=np.int64)
    start = np.cumsum(counts) - counts
    for f in np.flatnonzero(counts > REPEAT_CHECK_CORNERS):  # large polygons are rare: one step each
        s, k = int(start[f]), int(counts[f])
        distinct = np.unique(corner_ids[s:s + k]).size
        if distinct < (k + 1) // 2:
            raise PolygonTooComplex(f"a polygon has {k:,} corners but only {distinct:,} distinct vertices; "
                                    f"lopcook triangulates polygons of more than {REPEAT_CHECK_CORNERS} corners "
                                    "only when at least half their corners are distinct", face=int(f),
                                    hint=_REPEAT_HINT)


def triangulate(counts: np.ndarray, corner_positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate polygons given per-corner positions.

    Parameters
    ----------
    counts : (F,) int
        Corners per polygon (OBJ ``f`` length, USD ``faceVertexCounts``). Polygons with fewer than
        3 corners produce no triangles.
    corner_positions : (C, 3) float64, C = counts.sum()
        Position of every corner, polygon after polygon.

    Returns
    -------
    tri_corners : (T, 3) int64
        Indices into the corner array (so per-corner attributes map directly); T = sum(max(k-2, 0))
        but for large concave polygons with repeated corners (``triangulate_polygon``).
    tri_face : (T,) int64
        Polygon each triangle came from. Output is ordered by polygon.

    Raises ``PolygonTooComplex`` (with ``face``) for a polygon ``triangulate_polygon`` refuses.
    """
    counts = np.asarray(counts, dtype=np.int64)
    start = np.zeros(counts.size, dtype=np.int64)
    if counts.size:
        np.cumsum(counts[:-1], out=start[1:])
    pieces: list[tuple[np.ndarray, np.ndarray]] = []

    tri_f = np.flatnonzero(counts == 3)
    if tri_f.size:
        s = start[tri_f]
        pieces.append((np.stack([s, s + 1, s + 2], axis=1), tri_f))

    quad_f = np.flatnonzero(counts == 4)
    if quad_f.size:
        s = start[quad_f]
        a, b, c, d = (corner_positions[s + i] for i in range(4))
        # Newell normal of the quad = cross of its diagonals
        n = np.cross(c - a, d - b)
        ok_ac = (np.einsum("ij,ij->i", np.cross(b - a, c - a), n) >= 0) & (
            np.einsum("ij,ij->i", np.cross(c - a, d - a), n) >= 0)
        t1 = np.where(ok_ac[:, None], np.stack([s, s + 1, s + 2], 1), np.stack([s, s + 1, s + 3], 1))
        t2 = np.where(ok_ac[:, None], np.stack([s, s + 2, s + 3], 1), np.stack([s + 1, s + 2, s + 3], 1))
        tris = np.stack([t1, t2], axis=1).reshape(-1, 3)
        pieces.append((tris, np.repeat(quad_f, 2)))

    big_f = np.flatnonzero(counts >= 5)
    for f in big_f:  # n-gons are rare: one loop iteration each
        s, k = int(start[f]), int(counts[f])
        try:
            local = triangulate_polygon(corner_positions[s:s + k])
        except PolygonTooComplex as exc:
            raise PolygonTooComplex(str(exc), face=int(f), hint=exc.hint) from None
        pieces.append((local + s, np.full(local.shape[0], f, dtype=np.int64)))

    if not pieces:
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    tris = np.concatenate([p[0] for p in pieces])
    face = np.concatenate([p[1] for p in pieces])
    order = np.argsort(face, kind="stable")
    return tris[order], face[order]
