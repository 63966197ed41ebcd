"""Compiled kernels of the LOD stage: closest points on a triangle mesh (the LOD error's and the
transfer's queries) and the mesh defect counts (``weld_first``, ``defect_counts``), beside
``reference.py``, ``error.py`` and ``topology.py`` whose libigl queries and numpy counts they replace.

This work is based on: Ericson, "Real-Time Collision Detection" (2005), section 5.1.5 (closest
point on a triangle), as libigl's ``point_simplex_squared_distance`` computes it, and section 6
(bounding volume hierarchies, top-down median split).

``Tree(positions, faces)``: ``LEAF`` faces per leaf; a node holding leaves [a, b) splits its
faces at the median of their centroids along the longest side of the centroids' box, the first
half of its leaves on the smaller side (a balanced tree of 2L - 1 nodes for L leaves); each
node's box is the exact float64 min and max of its faces' corners. Memory: about 38 bytes per
face (the faces' slots and corners, int32, and the nodes).

``Tree.closest(points, bound2)``: for each point (q, 3) float64 the smallest squared distance to
any face, the face (the lowest face id among faces at exactly that distance) and the closest
point on it. The squared distance of a point to one face is computed with libigl's operations in
libigl's order (``_point_triangle``), so it equals libigl's bit for bit, and the search visits
every node whose box is within that distance (with a relative slack of ``SLACK`` and an absolute
one of (``SLACK`` x the largest coordinate)^2 for rounding), so the distance is the minimum over
all faces: the value libigl's AABB tree returns (tests/test_kernels_simplify.py compares them).
Only faces within ``bound2`` (q,) (times 1 + 1e-9) count; a point with none gets face -1.
Queries run in ``lopcook.jit.threads()`` threads (the kernel releases the GIL); every point's
answer is its own, so the results do not depend on the number of threads.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, parallel_ranges

#: faces per leaf of the hierarchy
LEAF = 8

#: relative slack of the search's box test (and absolute: SLACK x the largest coordinate, squared)
SLACK = 1e-9

@njit(inline="always")
def _point_triangle(px, py, pz, V, i0, i1, i2):
    """(squared distance, closest point x, y, z) of point p to triangle (V[i0], V[i1], V[i2]):
    Ericson's regions in libigl's order and arithmetic (sums of three products left to right)."""
    ax, ay, az = V[i0, 0], V[i0, 1], V[i0, 2]
    bx, by, bz = V[i1, 0], V[i1, 1], V[i1, 2]
    cx, cy, cz = V[i2, 0], V[i2, 1], V[i2, 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    qx, qy, qz = ax, ay, az  # vertex region of a
    if not (d1 <= 0.0 and d2 <= 0.0):
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        vc = d1 * d4 - d3 * d2
        if d3 >= 0.0 and d4 <= d3:  # vertex region of b
            qx, qy, qz = bx, by, bz
        elif (ax != bx or ay != by or az != bz) and vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:  # edge ab
            v = d1 / (d1 - d3)
            qx, qy, qz = ax + v * abx, ay + v * aby, az + v * abz
        else:
            cpx, cpy, cpz = px - cx, py - cy, pz - cz
            d5 = abx * cpx + aby * cpy + abz * cpz
            d6 = acx * cpx + acy * cpy + acz * cpz
            vb = d5 * d2 - d1 * d6
            va = d3 * d6 - d5 * d4
            if d6 >= 0.0 and d5 <= d6:  # vertex region of c
                qx, qy, qz = cx, cy, cz
            elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:  # edge ac
                w = d2 / (d2 - d6)
                qx, qy, qz = ax + w * acx, ay + w * acy, az + w * acz
            elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:  # edge bc
                w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                qx, qy, qz = bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
            else:  # inside the face
                denom = 1.0 / (va + vb + vc)
                v = vb * denom
                w = vc * denom
                qx, qy, qz = ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w
    rx, ry, rz = px - qx, py - qy, pz - qz
    return rx * rx + ry * ry + rz * rz, qx, qy, qz


@njit
def point_triangle_squared(P, V, F):
    """(q,) squared distance of point P[i] (q, 3) to triangle F[i] (q, 3) of V (n, 3): the test
    hook of ``_point_triangle``."""
    out = np.empty(P.shape[0])
    for i in range(P.shape[0]):
        out[i] = _point_triangle(P[i, 0], P[i, 1], P[i, 2], V, F[i, 0], F[i, 1], F[i, 2])[0]
    return out


@njit
def _select(order, key, lo, hi, k):
    """Reorder ``order[lo:hi]`` so that ``key[order[k]]`` is the value a sort would put at k, with
    no larger key before it and no smaller one after (quickselect, median-of-three pivots)."""
    while hi - lo > 1:
        mid = (lo + hi - 1) // 2
        a, b, c = key[order[lo]], key[order[mid]], key[order[hi - 1]]
        pivot = max(min(a, b), min(max(a, b), c))
        i, j = lo, hi - 1
        while i <= j:
            while key[order[i]] < pivot:
                i += 1
            while key[order[j]] > pivot:
                j -= 1
            if i <= j:
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j + 1
        elif k >= i:
            lo = i
        else:
            return


@njit
def _build(V, F, leaf):
    """The hierarchy: ``(sid (m,) face id per slot, SF (m, 3) int32 its corners, lo (N, 3), hi (N, 3)
    node boxes, left (N,) first child (-1: leaf), first (N,), count (N,) a leaf's slots)``. Node 0
    is the root, a node's children are ``left`` and ``left + 1``. A node holding leaves [a, b)
    (``leaf`` slots each) puts the faces of the first half of its leaves on the side of the
    median of their centroids along the longest side of their centroids' box."""
    m = F.shape[0]
    cen = np.empty((3, m))
    for f in range(m):
        for a in range(3):
            cen[a, f] = (V[F[f, 0], a] + V[F[f, 1], a] + V[F[f, 2], a]) / 3.0
    order = np.arange(m)
    nl = max(1, (m + leaf - 1) // leaf)
    nn = 2 * nl - 1
    lo = np.empty((nn, 3))
    hi = np.empty((nn, 3))
    left = np.full(nn, -1, np.int64)
    first = np.zeros(nn, np.int64)
    count = np.zeros(nn, np.int64)
    s_node = np.empty(128, np.int64)
    s_a = np.empty(128, np.int64)
    s_b = np.empty(128, np.int64)
    sp = 1
    s_node[0], s_a[0], s_b[0] = 0, 0, nl
    nxt = 1
    while sp > 0:
        sp -= 1
        node, a, b = s_node[sp], s_a[sp], s_b[sp]
        f0, f1 = a * leaf, min(b * leaf, m)
        if b - a == 1:
            first[node] = f0
            count[node] = f1 - f0
            continue
        axis, span = 0, -1.0
        for ax in range(3):
            x0, x1 = np.inf, -np.inf
            for k in range(f0, f1):
                c = cen[ax, order[k]]
                x0 = min(x0, c)
                x1 = max(x1, c)
            if x1 - x0 > span:
                axis, span = ax, x1 - x0
        mid = (a + b) // 2
        _select(order, cen[axis], f0, f1, mid * leaf)
        left[node] = nxt
        s_node[sp], s_a[sp], s_b[sp] = nxt, a, mid
        s_node[sp + 1], s_a[sp + 1], s_b[sp + 1] = nxt + 1, mid, b
        sp += 2
        nxt += 2
    SF = np.empty((m, 3), np.int32)
    for k in range(m):
        for j in range(3):
            SF[k, j] = F[order[k], j]
    for node in range(nn - 1, -1, -1):  # children have larger ids than their parent
        c = left[node]
        for a in range(3):
            if c < 0:
                x0, x1 = np.inf, -np.inf
                for k in range(first[node], first[node] + count[node]):
                    for j in range(3):
                        v = V[SF[k, j], a]
                        x0 = min(x0, v)
                        x1 = max(x1, v)
            else:
                x0 = min(lo[c, a], lo[c + 1, a])
                x1 = max(hi[c, a], hi[c + 1, a])
            lo[node, a] = x0
            hi[node, a] = x1
    return order, SF, lo, hi, left, first, count


@njit(inline="always")
def _box2(lo, hi, node, px, py, pz):
    gx = max(max(lo[node, 0] - px, px - hi[node, 0]), 0.0)
    gy = max(max(lo[node, 1] - py, py - hi[node, 1]), 0.0)
    gz = max(max(lo[node, 2] - pz, pz - hi[node, 2]), 0.0)
    return gx * gx + gy * gy + gz * gz


@njit
def _closest(V, SF, sid, lo, hi, left, first, count, abs2, P, radius2, want_point, out_d2, out_face, out_pt,
             a, b):
    """Rows a..b of ``Tree.closest`` (see the module doc); ``radius2`` (q,) the largest squared
    distance that counts (inf: any)."""
    stack = np.empty(256, np.int64)
    for i in range(a, b):
        px, py, pz = P[i, 0], P[i, 1], P[i, 2]
        r = radius2[i]
        best = np.inf
        bf = -1
        bx = by = bz = 0.0
        stack[0] = 0
        sp = 1
        while sp > 0:
            sp -= 1
            node = stack[sp]
            lim = min(best, r) * (1.0 + 1e-9) + abs2
            if _box2(lo, hi, node, px, py, pz) > lim:
                continue
            c = left[node]
            if c < 0:
                for k in range(first[node], first[node] + count[node]):
                    d, qx, qy, qz = _point_triangle(px, py, pz, V, SF[k, 0], SF[k, 1], SF[k, 2])
                    if d <= r and (d < best or (d == best and sid[k] < bf)):
                        best, bf, bx, by, bz = d, sid[k], qx, qy, qz
                continue
            dl = _box2(lo, hi, c, px, py, pz)
            dr = _box2(lo, hi, c + 1, px, py, pz)
            near, far, dn, df = (c, c + 1, dl, dr) if dl <= dr else (c + 1, c, dr, dl)
            if df <= lim:
                stack[sp] = far
                sp += 1
            if dn <= lim:
                stack[sp] = near
                sp += 1
        out_d2[i] = best if bf >= 0 else np.inf
        out_face[i] = bf
        if want_point:
            out_pt[i, 0], out_pt[i, 1], out_pt[i, 2] = bx, by, bz


class Tree:
    """A bounding volume hierarchy over the faces (m, 3) of positions (n, 3) float64 (module doc)."""

    def __init__(self, positions: np.ndarray, faces: np.ndarray):
        self.V = np.ascontiguousarray(positions, dtype=np.float64)
        F = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
        self.m = F.shape[0]
        if self.m == 0:
            raise ValueError("Tree: a mesh without faces")
        if self.V.shape[0] >= 1 << 31:
            raise ValueError("Tree: more than 2^31 - 1 vertices")
        self.sid, self.SF, self.lo, self.hi, self.left, self.first, self.count = _build(self.V, F, LEAF)
        big = float(np.abs(self.V[np.isfinite(self.V).all(axis=1)]).max()) if self.V.size else 0.0
        self.abs2 = (SLACK * big) ** 2 if math.isfinite(big) else 0.0

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.sid, self.SF, self.lo, self.hi, self.left, self.first, self.count))

    def closest(self, points: np.ndarray, bound2: np.ndarray | None = None, point: bool = True):
        """``(squared distance (q,), face (q,) int64, closest point (q, 3) or None)`` (module doc).
        ``bound2``: (q,) squared distances each point's answer is known to be within (a face
        beyond ``bound2 * (1 + 1e-9) + 1e-300`` does not count), or None for any distance."""
        P = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        q = P.shape[0]
        if bound2 is None:
            radius = np.full(q, np.inf)
        else:
            radius = np.asarray(bound2, dtype=np.float64) * (1.0 + 1e-9) + 1e-300
        d2 = np.empty(q)
        face = np.empty(q, np.int64)
        pt = np.empty((q, 3)) if point else np.empty((1, 3))
        parallel_ranges(_closest, q, self.V, self.SF, self.sid, self.lo, self.hi, self.left, self.first,
                        self.count, self.abs2, P, radius, point, d2, face, pt)
        return d2, face, (pt if point else None)


# ---- mesh defects (``topology.mesh_defects``) -------------------------------------------------------

@njit(inline="always")
def _mix(h):
    """MurmurHash3's 64-bit finaliser (``lopcook.mesh._fmix``), on an int64 bit pattern."""
    h ^= (h >> 33) & 0x7FFFFFFF
    h *= -49064778989728563  # 0xFF51AFD7ED558CCD
    h ^= (h >> 33) & 0x7FFFFFFF
    h *= -4265267296055464877  # 0xC4CEB9FE1A85EC53
    h ^= (h >> 33) & 0x7FFFFFFF
    return h


@njit
def weld_first(bits):
    """``(labels (n,) int64, count)``: equal labels exactly for equal rows of ``bits`` (n, 3) int64
    (float64 positions + 0.0 viewed as integers), numbered by first appearance (open addressing)."""
    n = bits.shape[0]
    size = 16
    while size < 2 * n:
        size *= 2
    mask = size - 1
    table = np.full(size, -1, np.int64)
    lab = np.empty(n, np.int64)
    count = 0
    for i in range(n):
        h = _mix(_mix(_mix(bits[i, 0]) ^ bits[i, 1]) ^ bits[i, 2])
        s = h & mask
        while True:
            j = table[s]
            if j < 0:
                table[s] = i
                lab[i] = count
                count += 1
                break
            if bits[j, 0] == bits[i, 0] and bits[j, 1] == bits[i, 1] and bits[j, 2] == bits[i, 2]:
                lab[i] = lab[j]
                break
            s = (s + 1) & mask
    return lab, count


@njit(inline="always")
def _find(parent, x):
    r = x
    while parent[r] != r:
        r = parent[r]
    while parent[x] != r:  # path compression
        parent[x], x = r, parent[x]
    return r


@njit(inline="always")
def _union(parent, x, y):
    rx, ry = _find(parent, x), _find(parent, y)
    if rx != ry:
        if rx < ry:
            parent[ry] = rx
        else:
            parent[rx] = ry


@njit
def _edge_pass(a, nw, parent):
    """Every undirected edge of the corners' vertices ``a`` (3m,) (half-edge h = corner h to the
    next corner of its face): its half-edges' corners at each end joined in ``parent`` (union-find
    over corners); returns (edges with one half-edge, with more than two, with exactly two).
    Half-edges are bucketed by their smaller end and sorted by the other within a bucket."""
    c = a.size
    start = np.zeros(nw + 1, np.int64)
    for h in range(c):
        b = a[h + 1 if (h + 1) % 3 else h - 2]
        start[min(a[h], b) + 1] += 1
    for v in range(nw):
        start[v + 1] += start[v]
    bucket = np.empty(c, np.int64)
    other = np.empty(c, np.int64)
    fill = start[:-1].copy()
    for h in range(c):
        b = a[h + 1 if (h + 1) % 3 else h - 2]
        lo = min(a[h], b)
        bucket[fill[lo]] = h
        other[fill[lo]] = a[h] + b - lo
        fill[lo] += 1
    one = many = two = 0
    for v in range(nw):
        s, e = start[v], start[v + 1]
        if e - s > 32:
            srt = np.argsort(other[s:e], kind="mergesort")
            bucket[s:e] = bucket[s:e][srt]
            other[s:e] = other[s:e][srt]
        else:
            for i in range(s + 1, e):  # insertion sort by the other end
                o, h = other[i], bucket[i]
                j = i - 1
                while j >= s and other[j] > o:
                    other[j + 1], bucket[j + 1] = other[j], bucket[j]
                    j -= 1
                other[j + 1], bucket[j + 1] = o, h
        k = s
        while k < e:
            j = k + 1
            x = bucket[k]
            cbx = x + 1 if (x + 1) % 3 else x - 2
            while j < e and other[j] == other[k]:
                y = bucket[j]
                cby = y + 1 if (y + 1) % 3 else y - 2
                if a[x] == a[y]:  # same direction: corners at the same ends
                    _union(parent, x, y)
                    _union(parent, cbx, cby)
                else:
                    _union(parent, x, cby)
                    _union(parent, cbx, y)
                j += 1
            size = j - k
            if size == 1:
                one += 1
            elif size == 2:
                two += 1
            else:
                many += 1
            k = j
    return one, many, two


@njit
def defect_counts(w, nw, faces, degenerate):
    """``(boundary_edges, nonmanifold_edges, nonmanifold_vertices, edges with two faces, edges)``
    of the faces (m, 3) not ``degenerate`` (m,) on welded vertices ``w`` (n,) in [0, nw): the
    counts of ``lopcook.simplify.topology.mesh_defects`` (bow-ties: vertices whose corners fall in
    more than one group of corners joined across the edges at them)."""
    m = faces.shape[0]
    good = 0
    for f in range(m):
        if not degenerate[f]:
            good += 1
    a = np.empty(3 * good, np.int64)
    g = 0
    for f in range(m):
        if not degenerate[f]:
            for k in range(3):
                a[3 * g + k] = w[faces[f, k]]
            g += 1
    parent = np.arange(3 * good)
    one, many, two = _edge_pass(a, nw, parent)
    fans = np.zeros(nw, np.int64)
    for h in range(3 * good):
        if _find(parent, h) == h:
            fans[a[h]] += 1
    bowties = 0
    for v in range(nw):
        if fans[v] > 1:
            bowties += 1
    return one, many, bowties, two, one + many + two


__all__ = ["LEAF", "SLACK", "Tree", "point_triangle_squared", "weld_first", "defect_counts"]
