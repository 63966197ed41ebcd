"""Vertex normals for sources that have none: area-weighted and crease-aware.

Method: the mesh is welded by exact position (so UV seams do not break shading), each corner of a
triangle is linked to the matching corner of its neighbour across every manifold edge whose
dihedral angle is at most ``crease_angle_deg`` (edges touching a zero-area triangle count as
smooth), and the corners of a vertex split into the connected groups of that graph. A vertex
with several groups (a vertex on a crease, e.g. fandisk's feature lines) is split into one vertex
per group. Each group's normal is the sum of its triangles' cross products (area weighting),
normalised. A group whose triangles all have zero area gets the normal of the nearest
non-degenerate direction available: +Y as a last resort (counted in ``NormalResult.fallback``).

Implementation: corner and vertex ids are int32 while they fit. The undirected edges are found by
one ``np.sort`` of packed int64 values (edge key, half-edge id). A vertex whose incident edges are
all smooth manifold edges between consistently oriented triangles has one corner group when the
walk around its fan from one corner visits every corner (a bowtie of two closed fans does not):
that is checked for all such vertices at once, one step per fan position. Only the corners of the
other vertices (creases, boundaries, bowties) go through the general grouping: pointer doubling on
the "next corner around the vertex" map, or scipy's connected components when some neighbours are
inconsistently oriented. The output is bit-identical to the direct formulation
(tests/ingest/test_normals_fast.py keeps it as the reference): same groups, same numbering of the new
vertices, and every sum in the same order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh import fan_successors, graph_components, next_corner as _next_corner, single_fans, weld_labels


@dataclass(frozen=True)
class NormalResult:
    """indices (m, 3) uint32 into the new vertices; source_vertex (n', ) int64 original vertex of
    each new vertex (n' >= n only grows at creases); normals (n', 3) float32 unit;
    fallback: number of new vertices whose normal could not be computed (all-degenerate)."""

    indices: np.ndarray
    source_vertex: np.ndarray
    normals: np.ndarray
    fallback: int


def _group_sum(group: np.ndarray, face_values: np.ndarray, size: int) -> np.ndarray:
    """(size, 3) sums per group id of the values of each corner's face: corner c (of face c // 3)
    adds ``face_values[c // 3]`` (m, 3) to ``group[c]``. One bincount per column, corners in
    order (the summation order of a (3m, 3) array of repeated rows, without building it)."""
    group = group.astype(np.intp, copy=False)  # bincount's index type: converted once, not per column
    return np.stack([np.bincount(group, weights=np.repeat(face_values[:, k], 3), minlength=size)
                     for k in range(3)], axis=1)


#: half-edge pairs handled per step of the dihedral test ((k, 3) float64 temporaries)
_CHUNK = 1 << 18

def _norm(v: np.ndarray) -> np.ndarray:
    """Row lengths of (k, 3) float64: ``np.linalg.norm(v, axis=1)``'s bits ((x*x + y*y) + z*z,
    then sqrt), from columns instead of a reduction over rows of three."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    s = x * x
    s += y * y
    s += z * z
    return np.sqrt(s, out=s)


def _prev_corner(h: np.ndarray) -> np.ndarray:
    """Start corner of the half-edge that ends at corner h (3f + (k + 2) % 3)."""
    prv = h - 1
    prv[h - 3 * (h // 3) == 0] += 3
    return prv


def _orbit_min(succ: np.ndarray, pred: np.ndarray, rounds: int) -> np.ndarray:
    """Smallest node of each node's component in a graph of paths and cycles given by an
    injective successor map (``succ[i] == i`` at a path's end, ``pred`` its inverse, ``pred[i]
    == i`` at a path's start). Pointer doubling: after ``rounds`` with ``2**rounds`` >= the
    largest component, ``low[i]`` is the minimum of i's forward orbit, and the path's start (or
    any node of a cycle) carries the component's minimum."""
    low = np.arange(succ.size, dtype=succ.dtype)
    ahead = succ.copy()
    head = pred.copy()
    for _ in range(rounds):
        np.minimum(low, low[ahead], out=low)
        ahead = ahead[ahead]
        head = head[head]
    return low[head]


#: bits of a packed sort key (int64 without its sign); wider keys fall back to an argsort
_PACK_BITS = 63

#: fans with more corners than this go through the general grouping (``mesh.single_fans``)
_MAX_WALK = 64


def _face_normals(positions: np.ndarray, tri: np.ndarray):
    """Face cross products of (m, 3) triangles ``tri`` over (n, 3) float64 ``positions``.

    Returns ``(fn, unit, degenerate, any_degenerate)``: fn (m, 3) float64 cross products (twice
    the area, the operations of ``np.cross`` in its order: ``mesh.face_normals`` gives the same
    bits); unit (m, 3) float64 unit normals (zero for zero-area faces); degenerate (m,) bool
    (length <= 1e-300); any_degenerate: whether any face is."""
    m = tri.shape[0]
    fn = np.empty((m, 3))
    p0 = np.take(positions, tri[:, 0], axis=0)
    e1 = np.take(positions, tri[:, 1], axis=0)
    e1 -= p0
    e2 = np.take(positions, tri[:, 2], axis=0)
    e2 -= p0
    del p0
    np.multiply(e1[:, 1], e2[:, 2], out=fn[:, 0])
    fn[:, 0] -= e1[:, 2] * e2[:, 1]
    np.multiply(e1[:, 2], e2[:, 0], out=fn[:, 1])
    fn[:, 1] -= e1[:, 0] * e2[:, 2]
    np.multiply(e1[:, 0], e2[:, 1], out=fn[:, 2])
    fn[:, 2] -= e1[:, 1] * e2[:, 0]
    del e1, e2
    flen = _norm(fn)
    degenerate = flen <= 1e-300
    any_degenerate = bool(degenerate.any())
    if any_degenerate:
        unit = np.where(degenerate[:, None], 0.0, fn / np.where(degenerate, 1.0, flen)[:, None])
    else:
        unit = fn / flen[:, None]
    return fn, unit, degenerate, any_degenerate


def _manifold_pairs(a: np.ndarray, nw: int, cid):
    """The two half-edges of every manifold edge of the welded mesh.

    ``a`` (3m,) welded vertex per corner (ids < ``nw``, dtype ``cid``); half-edge h = corner
    3f + k goes from ``a[h]`` to the next corner's vertex. Returns ``(forward, h1, h2)``: forward
    (3m,) bool, whether half-edge h runs from the smaller to the larger vertex id; h1, h2 (p,)
    ``cid`` the half-edges of each edge used by exactly two half-edges (h1 < h2), edges in order
    of (smaller id, larger id)."""
    m = a.size // 3
    c = a.size
    b = a.reshape(m, 3)[:, [1, 2, 0]].ravel()
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    forward = a < b
    del b
    valid = np.flatnonzero(lo != hi).astype(cid, copy=False)
    hbits = max(c - 1, 1).bit_length()
    if nw.bit_length() * 2 + hbits <= _PACK_BITS:
        # one np.sort of (edge key << hbits | half-edge): no argsort, no int64 permutation
        packed = lo[valid].astype(np.int64)
        packed *= nw
        packed += hi[valid]
        packed <<= hbits
        packed |= valid
        del lo, hi, valid
        packed.sort()
        order = (packed & ((1 << hbits) - 1)).astype(cid)
        packed >>= hbits
        key = packed
    else:
        key = lo[valid].astype(np.int64) * np.int64(nw) + hi[valid]
        del lo, hi
        srt = np.argsort(key)
        key = key[srt]
        order = valid[srt]
        del srt, valid
    # manifold edges: exactly two half-edges with this key
    eq = np.zeros(key.size + 1, dtype=bool)
    np.equal(key[1:], key[:-1], out=eq[1:-1])
    del key
    pair = np.flatnonzero(eq[1:-1] & ~eq[:-2] & ~eq[2:])
    del eq
    return forward, order[pair], order[pair + 1]


def _smooth_pairs(h1: np.ndarray, h2: np.ndarray, unit: np.ndarray, degenerate: np.ndarray,
                  any_degenerate: bool, crease_angle_deg: float):
    """The half-edge pairs (h1, h2) whose faces' unit normals ``unit`` (m, 3) are at most
    ``crease_angle_deg`` degrees apart (cosine >= cos(angle) - 1e-12), or where either face is
    ``degenerate``; tested ``_CHUNK`` pairs at a time."""
    cos_limit = np.cos(np.radians(crease_angle_deg))
    f1, f2 = h1 // 3, h2 // 3
    smooth = np.empty(h1.size, dtype=bool)
    for s0 in range(0, h1.size, _CHUNK):  # (k, 3) gathers, not (pairs, 3)
        g1, g2 = f1[s0:s0 + _CHUNK], f2[s0:s0 + _CHUNK]
        ok = np.einsum("ij,ij->i", np.take(unit, g1, axis=0), np.take(unit, g2, axis=0)) >= cos_limit - 1e-12
        if any_degenerate:
            ok |= degenerate[g1] | degenerate[g2]
        smooth[s0:s0 + _CHUNK] = ok
    del f1, f2
    return h1[smooth], h2[smooth]


def _fan_groups(a: np.ndarray, h1: np.ndarray, h2: np.ndarray, fan: np.ndarray, nw: int, cid):
    """Corner groups when every smooth pair is consistently oriented (h2 runs from the end of h1
    to its start).

    ``a`` (3m,) welded vertex per corner; ``fan`` (nw,) corners per welded vertex. Returns
    ``(simple_v, cplx, low)``: simple_v (nw,) bool, vertices whose corners form one group (the
    walk around the fan visits them all); cplx (k,) ascending corners of the other vertices;
    low (k,) local index into ``cplx`` of the smallest corner of each one's group (pointer
    doubling on the "next corner around the vertex" map)."""
    # next corner around the vertex (-1 at a break: a half-edge without a smooth twin)
    succ, clean = fan_successors(h1, h2, a, nw, cid)
    del h1, h2
    simple_v = single_fans(succ, a, fan, clean, cid, _MAX_WALK)
    del clean
    cplx = np.flatnonzero(~simple_v[a]).astype(cid, copy=False)  # corners of the other vertices
    if cplx.size:
        nx = succ[cplx]
        nx = np.where(nx >= 0, nx, cplx)
        # the corner before y around its vertex: twin of y's incoming half-edge, where
        # twin(x) = prev(succ[x])
        pv = succ[_prev_corner(cplx)]
        pv = np.where(pv >= 0, _prev_corner(np.maximum(pv, 0)), cplx)
        nx = np.searchsorted(cplx, nx).astype(cid, copy=False)
        pv = np.searchsorted(cplx, pv).astype(cid, copy=False)
        rounds = max(int(fan[a[cplx]].max()) - 1, 1).bit_length()
        low = _orbit_min(nx, pv, rounds)  # local index of the group's smallest corner
        del nx, pv
    else:
        low = np.zeros(0, dtype=cid)
    return simple_v, cplx, low


def _graph_groups(h1: np.ndarray, h2: np.ndarray, same_dir: np.ndarray, c: int, nw: int, cid):
    """Corner groups when some smooth pair is inconsistently oriented: connected components of
    the corner links over all ``c`` corners (same result form as :func:`_fan_groups`, with every
    vertex treated as complex: simple_v all False, cplx = all corners)."""
    cb1 = _next_corner(h1)  # corner at the other end of half-edge h1
    cb2 = _next_corner(h2)
    link_u = np.concatenate([h1, cb1])
    link_v = np.concatenate([np.where(same_dir, h2, cb2), np.where(same_dir, cb2, h2)])
    del h1, h2, cb1, cb2, same_dir
    _, lab = graph_components(link_u, link_v, c)  # (scipy.sparse, imported only on this branch)
    del link_u, link_v
    _, first = np.unique(lab, return_index=True)  # labels are numbered by smallest corner
    low = first.astype(cid)[lab]
    del lab, first
    return np.zeros(nw, dtype=bool), np.arange(c, dtype=cid), low


def _group_labels(a: np.ndarray, cplx: np.ndarray, low: np.ndarray, nw: int, cid):
    """Group label per corner: the welded vertex ``a`` for single-group vertices, ``nw + j`` for
    the j-th group (in order of smallest corner) of the corners ``cplx``. Returns ``(label (3m,),
    croot (g,) smallest corner of complex group j, n_labels = nw + g)``."""
    is_root = low == np.arange(low.size, dtype=cid)
    number = np.cumsum(is_root, dtype=cid)
    n_cplx = int(number[-1]) if number.size else 0
    number -= 1
    label = a.copy()
    label[cplx] = nw + number[low]
    croot = cplx[is_root]
    return label, croot, nw + n_cplx


def _merge_directionless(label: np.ndarray, fn: np.ndarray, a: np.ndarray, cplx: np.ndarray,
                         croot: np.ndarray, nw: int, n_labels: int, c: int, cid) -> np.ndarray:
    """(n_labels, 3) float64 sums of the face cross products ``fn`` per group, after merging each
    group made only of zero-area triangles into the group of the same welded vertex that has a
    direction and the smallest first corner (so degenerate slivers do not split vertices; a
    single-group vertex has no other group to merge into). Updates ``label`` in place."""
    gsum = _group_sum(label, fn, n_labels)
    if cplx.size:
        clab = label[cplx] - nw
        good = np.linalg.norm(gsum[nw:], axis=1)[clab] > 1e-300
        if not good.all():
            wv = a[cplx]
            big = np.iinfo(cid).max
            donor = np.full(nw, big, dtype=cid)
            np.minimum.at(donor, wv[good], croot[clab[good]])
            take = ~good & (donor[wv] != big)
            if take.any():
                j_of_root = np.full(c, -1, dtype=cid)
                j_of_root[croot] = np.arange(croot.size, dtype=cid)
                label[cplx[take]] = nw + j_of_root[donor[wv[take]]]
                gsum = _group_sum(label, fn, n_labels)
    return gsum


def _complex_vertices(ov: np.ndarray, label: np.ndarray, cplx: np.ndarray, n_labels: int, c: int, cid):
    """The distinct (original vertex, group) pairs of the corners ``cplx``.

    Returns ``(p_ov, p_label, rank, pinv)``: per pair (p,) its original vertex, its group label
    and its rank among the pairs of the same original vertex (ordered by first corner); pinv
    (k,) the pair of each corner of ``cplx``."""
    clab = label[cplx]
    cov = ov[cplx]
    pkey = cov.astype(np.int64) * np.int64(n_labels) + clab
    _, pfirst, pinv = np.unique(pkey, return_index=True, return_inverse=True)
    del pkey
    pinv = pinv.ravel()
    p_ov = cov[pfirst]
    p_label = clab[pfirst]
    p_first = cplx[pfirst]
    del clab, cov, pfirst
    porder = np.argsort(p_ov.astype(np.int64) * np.int64(c) + p_first)
    s_ov = p_ov[porder]
    rank = np.empty(porder.size, dtype=cid)
    rank[porder] = np.arange(porder.size, dtype=cid) - np.searchsorted(s_ov, s_ov).astype(cid)
    return p_ov, p_label, rank, pinv


def _new_vertices(n: int, c: int, ov, weld, used, simple_v, label, cplx, n_labels: int, cid):
    """Number the new vertices: one per (original vertex, group), ordered by original vertex,
    then first corner; the original vertices of a single-group welded vertex have one each.

    ``used`` (n,) bool original vertices referenced by a corner; ``simple_v`` (nw,) single-group
    welded vertices. Returns ``(new_index (3m,) cid, row (n',) group label of each new vertex,
    source_vertex (n',) int64)``."""
    count = used.astype(cid)
    cplx_v = ~simple_v[weld]  # original vertices at welded vertices with several groups
    count[cplx_v] = 0
    if cplx.size:
        p_ov, p_label, rank, pinv = _complex_vertices(ov, label, cplx, n_labels, c, cid)
        count += np.bincount(p_ov, minlength=n).astype(cid)
    offset = np.cumsum(count, dtype=np.int64) - count
    total = int(offset[-1] + count[-1]) if n else 0
    new_index = offset.astype(cid)[ov]
    row = np.empty(total, dtype=cid)
    simple_used = np.flatnonzero(used & ~cplx_v)
    row[offset[simple_used]] = weld[simple_used]
    if cplx.size:
        at = offset[p_ov] + rank
        row[at] = p_label
        new_index[cplx] = at[pinv]
    source_vertex = np.repeat(np.arange(n, dtype=np.int64), count)
    return new_index, row, source_vertex


def _result(new_index, source_vertex, normals, used, m: int) -> NormalResult:
    """Append one copy of each unused vertex (normal zero), normalise the (n', 3) float64 group
    sums ``normals`` (+Y where the length is <= 1e-300, counted as fallback), pack the result."""
    unused = np.flatnonzero(~used)
    if unused.size:
        source_vertex = np.concatenate([source_vertex, unused])
        normals = np.concatenate([normals, np.zeros((unused.size, 3))])
    length = _norm(normals)
    bad = length <= 1e-300
    normals = np.where(bad[:, None], np.array([0.0, 1.0, 0.0]), normals / np.where(bad, 1.0, length)[:, None])
    return NormalResult(
        indices=new_index.reshape(m, 3).astype(np.uint32),
        source_vertex=source_vertex.astype(np.int64),
        normals=normals.astype(np.float32),
        fallback=int(np.count_nonzero(bad)),
    )


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
    New vertices are numbered by (original vertex, first corner of the group); each normal is the
    float64 sum of its group's face cross products in corner order, normalised, then float32:
    the result is deterministic and does not depend on the sort or graph algorithms used.

    Memory: int32 corner ids where 3m < 2^31; the largest temporaries are (m, 3) float64 arrays
    and one int64 per half-edge (docs/performance.md has the measured peak).
    """
    n = positions.shape[0]
    m = int(np.shape(indices)[0])
    c = 3 * m
    small = max(c, n) < (1 << 31) - 1
    cid = np.int32 if small else np.int64  # corner / vertex ids
    tri = np.asarray(indices).astype(cid, copy=False).reshape(m, 3)
    if m == 0:
        return NormalResult(indices=np.zeros((0, 3), np.uint32), source_vertex=np.arange(n, dtype=np.int64),
                            normals=np.tile(np.array([0.0, 1.0, 0.0], np.float32), (n, 1)), fallback=n)
    # (1) weld by exact position: ``a`` the welded vertex of each corner
    ov = tri.ravel()  # original vertex per corner
    weld, nw = weld_labels(positions, cid)
    seams = nw < n
    if seams:
        a = weld[ov]
    else:
        weld = np.arange(n, dtype=cid)
        a = ov
    # (2) face cross products; (3) the smooth manifold edges
    fn, unit, degenerate, any_degenerate = _face_normals(positions, tri)
    forward, h1, h2 = _manifold_pairs(a, nw, cid)
    if crease_angle_deg < 180.0:
        h1, h2 = _smooth_pairs(h1, h2, unit, degenerate, any_degenerate, crease_angle_deg)
    del unit, degenerate
    # (4) corners of one vertex are linked across its smooth manifold edges; consistently oriented
    # neighbours have opposite half-edges (h2 runs from b[h1] to a[h1])
    same_dir = forward[h1] == forward[h2]
    del forward
    fan = np.bincount(a, minlength=nw).astype(cid, copy=False)  # corners per welded vertex
    if not same_dir.any():
        del same_dir
        simple_v, cplx, low = _fan_groups(a, h1, h2, fan, nw, cid)
    else:  # inconsistently oriented neighbours: every vertex through the general grouping
        simple_v, cplx, low = _graph_groups(h1, h2, same_dir, c, nw, cid)
        del same_dir
    del h1, h2
    # (5) group labels and sums; (6) new vertices, each with its group's sum, then normalised
    label, croot, n_labels = _group_labels(a, cplx, low, nw, cid)
    del low
    gsum = _merge_directionless(label, fn, a, cplx, croot, nw, n_labels, c, cid)
    del fn
    if seams:
        used = np.zeros(n, dtype=bool)
        used[ov] = True
    else:
        used = fan > 0
    new_index, row, source_vertex = _new_vertices(n, c, ov, weld, used, simple_v, label, cplx, n_labels, cid)
    normals = np.take(gsum, row, axis=0)
    del gsum, row
    return _result(new_index, source_vertex, normals, used, m)
