"""Mesh helpers shared by every stage: co-located vertices (same position bits, possibly different
attributes: UV/normal seams), unique rows, face normals, the one degenerate-triangle test,
compaction and connected components.

Shared by every loader (normals are computed on the welded topology so seams shade smoothly) and
by ``inspect`` (duplicated positions). Exact comparison: two vertices are co-located when their
float64 coordinates are identical (``-0.0`` equals ``0.0``).
"""

from __future__ import annotations

import numpy as np


def weld_exact(positions: np.ndarray) -> tuple[np.ndarray, int]:
    """Group identical positions.

    Parameters
    ----------
    positions : (n, 3) float64

    Returns
    -------
    inverse : (n,) int64
        Group id of each vertex; groups are numbered in order of first appearance.
    n_groups : int
    """
    p = np.ascontiguousarray(positions, dtype=np.float64) + 0.0  # -0.0 -> 0.0
    rows = p.view(np.dtype((np.void, p.dtype.itemsize * 3))).ravel()
    _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
    # renumber groups by first appearance so the result does not depend on byte order of floats
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return rank[inverse.ravel()].astype(np.int64), int(first.size)


_FMIX = (np.uint64(33), np.uint64(0xFF51AFD7ED558CCD), np.uint64(0xC4CEB9FE1A85EC53))


def _fmix(h: np.ndarray) -> np.ndarray:
    """MurmurHash3's 64-bit finaliser, in place on a uint64 array (every input bit reaches every
    output bit: positions converted from float32 have 29 zero low bits per coordinate)."""
    h ^= h >> _FMIX[0]
    h *= _FMIX[1]
    h ^= h >> _FMIX[0]
    h *= _FMIX[2]
    h ^= h >> _FMIX[0]
    return h


def weld_labels(positions: np.ndarray, cid) -> tuple[np.ndarray, int]:
    """(n,) ids equal exactly for identical float64 positions (``-0.0 == 0.0``), in [0, k), and k.

    The numbering is arbitrary (the caller only compares ids): rows are sorted by a 64-bit hash of
    their bit patterns and equal neighbours compared exactly; a hash collision between different
    positions (never seen, but possible) falls back to ``weld_exact``."""
    n = positions.shape[0]
    p = np.ascontiguousarray(positions, dtype=np.float64) + 0.0  # -0.0 -> 0.0
    bits = p.view(np.uint64)
    h = _fmix(bits[:, 0].copy())
    h ^= bits[:, 1]
    h = _fmix(h)
    h ^= bits[:, 2]
    h = _fmix(h)
    order = np.argsort(h)
    hs = h[order]
    del h
    same_hash = hs[1:] == hs[:-1]
    del hs
    new = np.ones(n, dtype=bool)
    if same_hash.any():
        at = np.flatnonzero(same_hash)
        same_row = (bits[order[at]] == bits[order[at + 1]]).all(axis=1)
        if not same_row.all():  # two different positions share a hash: exact slow path
            w, k = weld_exact(positions)
            return w.astype(cid), k
        new[at + 1] = False
    lab = np.cumsum(new, dtype=cid)
    lab -= 1
    out = np.empty(n, dtype=cid)
    out[order] = lab
    return out, int(lab[-1]) + 1 if n else 0


def sorted_unique(values: np.ndarray) -> np.ndarray:
    """``np.unique(values)`` (sorted distinct values, 1-D) through one ``np.sort``: numpy 2's
    hash-based ``np.unique`` without return arrays is much slower on millions of integers."""
    s = np.sort(np.asarray(values).ravel())
    if s.size == 0:
        return s
    keep = np.empty(s.size, dtype=bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


_BLOCK = 1 << 20  # rows per block where a pass is split to keep (n,) temporaries out of a peak


def stable_argsort(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(order, key[order])`` with ``order`` exactly ``np.argsort(key, kind="stable")`` (int64) for
    a 1-D integer array ``key``.

    Where the key's range and the row index fit together in 63 bits, the pairs (key, index) are
    packed into one int64 and sorted with ``np.sort`` (several times faster than a stable argsort:
    the packed values are distinct, so an unstable sort orders them as the stable one orders the
    keys); otherwise the stable argsort itself."""
    key = np.asarray(key).ravel()
    n = key.size
    if n == 0 or key.dtype.kind not in "iu":
        order = np.argsort(key, kind="stable").astype(np.int64)
        return order, key[order]
    lo, hi = int(key.min()), int(key.max())
    ib = max(1, (n - 1).bit_length())
    if (hi - lo).bit_length() + ib > 63:
        order = np.argsort(key, kind="stable").astype(np.int64)
        return order, key[order]
    if key.dtype.kind == "u":
        packed = (key - key.dtype.type(lo)).astype(np.int64)
    else:
        packed = key.astype(np.int64)
        packed -= np.int64(lo)
    packed <<= np.int64(ib)
    for a in range(0, n, _BLOCK):  # the row index, a block at a time (no (n,) arange)
        packed[a:a + _BLOCK] |= np.arange(a, min(n, a + _BLOCK), dtype=np.int64)
    packed.sort()
    order = packed & np.int64((1 << ib) - 1)
    packed >>= np.int64(ib)
    if key.dtype.kind == "u":
        return order, packed.astype(key.dtype) + key.dtype.type(lo)
    packed += np.int64(lo)
    return order, packed.astype(key.dtype, copy=False)


def stable_lexsort(keys) -> np.ndarray:
    """``np.lexsort(keys)`` (int64; the last key is the primary one) for 1-D integer keys, as one
    ``stable_argsort`` per key from the least significant (a stable sort by each key in turn
    orders by all of them, ties by index)."""
    keys = [np.asarray(k).ravel() for k in keys]
    order = stable_argsort(keys[0])[0]
    for k in keys[1:]:
        order = order[stable_argsort(k[order])[0]]
    return order


def unique_first_inverse(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(values, return_index=True, return_inverse=True)[1:]`` for a 1-D integer array:
    ``first`` (u,) int64, the index of the first occurrence of each distinct value in increasing
    value order, and ``inverse`` (n,) int64, the rank of each value among them (one
    ``stable_argsort``)."""
    order, s = stable_argsort(values)
    n = s.size
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    new = np.empty(n, dtype=bool)
    new[0] = True
    np.not_equal(s[1:], s[:-1], out=new[1:])
    del s  # (n,) freed before the (n,) inverse
    inverse = np.empty(n, dtype=np.int64)
    first = order[new]
    # the ranks (cumsum(new) - 1) scattered a block at a time: no second (n,) array
    done = -1
    for a in range(0, n, _BLOCK):
        rank = np.cumsum(new[a:a + _BLOCK], dtype=np.int64)
        rank += done
        inverse[order[a:a + _BLOCK]] = rank
        done = int(rank[-1])
    return first, inverse


def used_ids(indices: np.ndarray, n: int) -> np.ndarray:
    """(k,) int64 sorted distinct vertex ids referenced by ``indices`` (any shape, values in [0, n));
    the same as ``np.unique(indices)``, by a mask."""
    used = np.zeros(n, dtype=bool)
    used[np.asarray(indices).ravel()] = True
    return np.flatnonzero(used)


def _pack_int_columns(k: np.ndarray) -> np.ndarray | None:
    """(c,) int64 key equal for equal rows of the integer array ``k`` (c, w) and different for
    different rows (mixed radix over each column's range), or None when the ranges do not fit in
    63 bits."""
    if k.dtype.kind not in "iu" or k.shape[0] == 0:
        return None
    lo = k.min(axis=0).astype(np.int64)
    span = k.max(axis=0).astype(np.int64) - lo + 1
    total = 1
    for s_ in span.tolist():
        total *= int(s_)
    if total >= 1 << 63:
        return None
    key = np.zeros(k.shape[0], dtype=np.int64)
    for j in range(k.shape[1]):
        key *= span[j]
        key += k[:, j].astype(np.int64) - lo[j]
    return key


def unique_rows(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of a 2-D array, numbered in order of first appearance.

    Parameters
    ----------
    keys : (c, k) array of any fixed-size dtype (e.g. int64 ids and float bit patterns)

    Returns
    -------
    first : (u,) int64  index of the first row of each unique row, increasing
    inverse : (c,) int64  unique id of each row
    """
    k = np.ascontiguousarray(keys)
    if k.shape[1] == 1:  # one column: sort its values directly
        if k.dtype.kind in "iu":
            first, inverse = unique_first_inverse(k[:, 0])
        else:
            _, first, inverse = np.unique(k[:, 0], return_index=True, return_inverse=True)
    else:
        rows = _pack_int_columns(k)  # one int64 per row where the column ranges allow: a faster sort
        if rows is None:
            rows = k.view(np.dtype((np.void, k.dtype.itemsize * k.shape[1]))).ravel()
            _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
        else:
            first, inverse = unique_first_inverse(rows)
        del rows
    # renumber from value order to order of first appearance
    order = stable_argsort(first)[0]
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return first[order].astype(np.int64, copy=False), rank[inverse.ravel()].astype(np.int64, copy=False)


def duplicated_positions(positions: np.ndarray) -> int:
    """Number of vertices whose position repeats an earlier vertex's (n - distinct positions)."""
    _, n_groups = weld_exact(positions)
    return int(positions.shape[0] - n_groups)


def canonical_triangles(tri) -> np.ndarray:
    """(m, 3) int64: triangles rotated to start at their smallest index, then sorted: equal for two
    index buffers that hold the same oriented triangles in any order and rotation."""
    t = np.asarray(tri, np.int64).reshape(-1, 3)
    k = np.argmin(t, axis=1)
    r = np.arange(t.shape[0])
    c = np.stack([t[r, k], t[r, (k + 1) % 3], t[r, (k + 2) % 3]], axis=1)
    return c[np.lexsort(c.T[::-1])] if c.shape[0] else c


def degenerate_triangles(positions: np.ndarray, indices: np.ndarray, rel_tol: float = 1e-12) -> int:
    """Number of degenerate triangles: ``degenerate_mask(positions, indices, rel_tol).sum()``."""
    return int(np.count_nonzero(degenerate_mask(positions, np.asarray(indices).astype(np.int64), rel_tol)))


def face_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m, 3) float64 cross products (p1 - p0) x (p2 - p0): direction = normal, length = 2 * area."""
    p0 = positions[faces[:, 0]]  # three (m, 3) gathers: no (m, 3, 3) temporary
    return np.cross(positions[faces[:, 1]] - p0, positions[faces[:, 2]] - p0)


def degenerate_mask(positions: np.ndarray, faces: np.ndarray, rel_tol: float = 1e-12) -> np.ndarray:
    """(m,) bool: the degenerate triangles, the one definition lopcook uses (``inspect`` counts
    them, ``simplify`` drops them).

    A triangle is degenerate when it repeats an index, its longest edge is 0, or twice its area is
    <= ``rel_tol * (longest edge)^2`` (``rel_tol`` is dimensionless: roughly the squared sine of
    its smallest angle). positions (n, 3) float64, faces (m, 3) integer ids.
    """
    if faces.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    rep = (f0 == f1) | (f1 == f2) | (f0 == f2)
    # per coordinate (1-D gathers and (m,) temporaries), in the operation order of np.cross and
    # np.linalg.norm / .sum(1) over rows of 3: the same bits as the (m, 3) form
    pt = np.ascontiguousarray(np.asarray(positions, dtype=np.float64).T)
    e0, e1, e2 = [], [], []
    for c in range(3):
        a, b, d = pt[c][f0], pt[c][f1], pt[c][f2]
        e0.append(b - a)
        e1.append(d - a)
        d -= b
        e2.append(d)
    del a, b, d, pt
    area2 = e0[1] * e1[2]
    area2 -= e0[2] * e1[1]
    area2 *= area2
    cy = e0[2] * e1[0]
    cy -= e0[0] * e1[2]
    cy *= cy
    area2 += cy
    cz = e0[0] * e1[1]
    cz -= e0[1] * e1[0]
    cz *= cz
    area2 += cz
    del cy, cz
    np.sqrt(area2, out=area2)

    def length2(e: list) -> np.ndarray:
        s = e[0] * e[0]
        s += e[1] * e[1]
        s += e[2] * e[2]
        return s

    longest2 = np.maximum(np.maximum(length2(e0), length2(e1)), length2(e2))
    return rep | (longest2 == 0) | (area2 <= rel_tol * longest2)


def compact(positions: np.ndarray, faces: np.ndarray):
    """Drop unreferenced vertices: (positions, faces, kept vertex ids)."""
    used = np.zeros(positions.shape[0], dtype=bool)
    used[faces.ravel()] = True
    keep = np.flatnonzero(used)
    remap = np.full(positions.shape[0], -1, dtype=np.int64)
    remap[keep] = np.arange(keep.size)
    return positions[keep], remap[faces], keep


def edge_groups(a: np.ndarray, b: np.ndarray, n: int):
    """Sort half-edges (a_i, b_i) by undirected key: (order, group starts, group sizes)."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * np.int64(max(n, 1)) + hi
    order, ks = stable_argsort(key)
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]]) if ks.size else np.zeros(0, np.int64)
    sizes = np.diff(np.r_[starts, ks.size])
    return order, starts, sizes


def graph_components(u: np.ndarray, v: np.ndarray, n: int) -> tuple[int, np.ndarray]:
    """(count, (n,) label per node) of the connected components of the undirected graph on ``n``
    nodes with edges ``u[k]`` -- ``v[k]`` (scipy's ``connected_components``)."""
    # imported here: a cook without LODs never needs scipy.sparse (docs/performance.md, "Start-up")
    from scipy.sparse import coo_matrix, csgraph

    g = coo_matrix((np.ones(np.asarray(u).size, dtype=np.int8), (u, v)), shape=(n, n))
    return csgraph.connected_components(g, directed=False)


def next_corner(h: np.ndarray) -> np.ndarray:
    """Corner at the end of half-edge h (corner h = 3f + k goes to corner 3f + (k + 1) % 3)."""
    nxt = h + 1
    nxt[nxt - 3 * (nxt // 3) == 0] -= 3
    return nxt


def fan_successors(h1: np.ndarray, h2: np.ndarray, a: np.ndarray, nv: int, cid) -> tuple[np.ndarray, np.ndarray]:
    """``(succ, clean)`` around the vertices of a triangle mesh, from its twin half-edges:
    ``h1[k]``, ``h2[k]`` are the two oppositely oriented half-edges (corner ids, h = 3f + k) of one
    edge, ``a`` (3m,) the vertex of each corner. ``succ`` (3m,) ``cid``: the next corner around a
    corner's vertex across its outgoing half-edge (the twin's corner at that vertex), -1 where the
    half-edge has no twin; ``clean`` (nv,) bool: the vertices all of whose half-edges in and out
    have one (``single_fans`` walks those)."""
    succ = np.full(a.size, -1, dtype=cid)
    succ[h1] = next_corner(h2)
    succ[h2] = next_corner(h1)
    broken = np.flatnonzero(succ < 0).astype(cid, copy=False)
    clean = np.ones(nv, dtype=bool)
    clean[a[broken]] = False
    clean[a[next_corner(broken)]] = False
    return succ, clean


def single_fans(succ: np.ndarray, a: np.ndarray, fan: np.ndarray, clean: np.ndarray, cid,
                max_walk: int = 64) -> np.ndarray:
    """(nv,) bool: the ``clean`` vertices whose corners form one cycle around them (one fan).

    ``a`` (3m,): the vertex of each corner; ``fan`` (nv,): corners per vertex; ``succ`` (3m,): the
    next corner around a corner's vertex (across its outgoing half-edge to the twin's face), defined
    at every corner of a clean vertex (the caller marks a vertex clean only when every half-edge
    into and out of it has a twin). From one corner of each clean vertex with at most ``max_walk``
    corners the walk must come back after exactly ``fan[v]`` steps, not before; a vertex that is
    not walked is False (its corners go to the caller's general grouping). Vertices are walked in
    blocks of equal fan size (no per-step compaction: one gather per corner in all)."""
    nw = fan.size
    start = np.empty(nw, dtype=cid)
    start[a] = np.arange(a.size, dtype=cid)  # any corner of each vertex (which one does not matter)
    cand = clean & (fan > 0) & (fan <= max_walk)
    out = np.zeros(nw, dtype=bool)
    sizes = np.bincount(fan[cand], minlength=max_walk + 1)
    for k in np.flatnonzero(sizes).tolist():
        verts = np.flatnonzero(cand & (fan == k))
        s0 = start[verts]
        cur = s0
        early = np.zeros(verts.size, dtype=bool)
        for _ in range(k - 1):
            cur = succ[cur]
            early |= cur == s0
        cur = succ[cur]
        out[verts[(cur == s0) & ~early]] = True
    return out


def components(n_faces: int, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(m,) component label of each face, faces connected through shared vertex ids (labels by
    first face)."""
    if n_faces == 0:
        return np.zeros(0, dtype=np.int64)
    size = n_faces + n_vertices
    cid = np.int32 if size < (1 << 31) - 1 else np.int64  # node ids of the face-vertex graph
    f = np.repeat(np.arange(n_faces, dtype=cid), 3)
    v = faces.ravel().astype(cid) + cid(n_faces)
    _, lab = graph_components(f, v, size)
    lab = lab[:n_faces]
    # renumber by first appearance for determinism
    _, first, inv = np.unique(lab, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[inv.ravel()]


def icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """The regular icosahedron shared by the icosphere fixture and the render harness's 20 views.

    Returns
    -------
    vertices : (12, 3) float64, (±1, ±φ, 0) and its cyclic permutations (φ = (1 + √5) / 2), not
        normalised (length √(1 + φ²) ≈ 1.902), in a fixed order.
    faces : (20, 3) int64 indices into ``vertices``, counter-clockwise seen from outside (outward
        normals), in a fixed order.
    """
    t = (1.0 + 5.0**0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], np.float64)
    f = np.array([
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
        [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
        [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], np.int64)
    return v, f
