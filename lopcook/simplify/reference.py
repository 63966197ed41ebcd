"""LOD 0 as the reference its LODs are transferred from and measured against (metres, the part's units).

``Reference(part)`` holds LOD 0: its faces without the degenerate ones (unless all are), unit face
normals, connected regions, defects, seams and volume, each computed once. Its closest-point
queries return ``(squared distance (q,), face id (q,) int64, closest point (q, 3))`` for points
(q, 3) float64, exact for any mesh size: one libigl AABB tree up to ``CHUNK_FACES`` faces, above
that trees over chunks of the faces (``query_bounded``) or over the faces near the points
(``query_near``), so no tree over all of a large LOD 0 is held. Where ``lopcook.jit.use`` says so
(large meshes), every query goes to one compiled hierarchy over LOD 0 instead (``tree``,
``lopcook.simplify.kernels.Tree``: about 38 bytes per face): the same squared distances bit for
bit, and among faces equally close the lowest face id.

``samples(positions, faces)``: the referenced vertices, then the face centroids.
``SampleOrder``: vertices in a coarse-to-fine Morton order, so that a prefix of it covers the
surface evenly (deterministic; ``lopcook.simplify.error.sampled_ref_to_lod`` samples with it).
"""

from __future__ import annotations

import itertools

import numpy as np

from .. import isolate, jit
from ..mesh import components, degenerate_mask, face_normals, used_ids
from ..types import MeshPart
from .topology import SeamStats, mesh_defects, seam_stats, signed_volume
from .workers import workers


#: ``Reference.query_bounded`` builds libigl trees over chunks of at most about this many LOD 0
#: faces (a tree takes about 240 bytes per face: docs/lod.md)
CHUNK_FACES = 1 << 18

#: ``Reference.query_bounded`` groups its points by the cells of a grid of this many cells per axis
#: (at most 40, so that a cell's number fits 16 bits) to find the chunks each group can reach
CANDIDATE_GRID = 32

#: ``Reference.query_any`` searches only the faces near its points (``query_near``) when there is at
#: most one point per this many LOD 0 faces; more points: the chunk sweep (``query_bounded``),
#: whose cost is mostly building the chunks' trees (docs/performance.md)
NEAR_POINTS_PER_FACE = 256

#: ``Reference.query_bounded`` on at least this many points sweeps its chunks in two processes
PARALLEL_POINTS = 20_000

_MORTON_BITS = 21


def point_mesh(points: np.ndarray, positions: np.ndarray, faces: np.ndarray):
    """libigl closest points: (squared distance, face id, closest point); for large meshes the
    compiled hierarchy's (``lopcook.simplify.kernels``: the same distances)."""
    if jit.use(int(np.shape(faces)[0])):
        from . import kernels  # compiled kernels (numba): loaded only for large meshes
        return kernels.Tree(positions, faces).closest(points)
    import igl  # libigl (native) and scipy (below) load when LOD 0 is first queried

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


def _spread3(v: np.ndarray) -> np.ndarray:
    """21-bit integers with two zero bits inserted after every bit (Morton interleave helper)."""
    x = v.astype(np.uint64) & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                        (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def _high_bit(x: np.ndarray) -> np.ndarray:
    """Index of the highest set bit of each uint64 (0 for 0)."""
    x = x.copy()
    hb = np.zeros(x.shape, dtype=np.int64)
    for s in (32, 16, 8, 4, 2, 1):
        big = x >= (np.uint64(1) << np.uint64(s))
        hb += s * big
        x = np.where(big, x >> np.uint64(s), x)
    return hb


class SampleOrder:
    """LOD 0's vertices in a coarse-to-fine spatial order, for deterministic, evenly spread samples.

    The vertices are sorted by Morton code (21 bits per axis over their bounding box, ties by
    index). Level L cuts the box into 8**L cells; a vertex's ``level`` is the first L at which it
    is the first sorted vertex of its cell (level 0: the first vertex; co-located repeats: 22, never
    a cell's first). Taking every vertex of level <= L therefore takes one vertex of every occupied
    level-L cell. Computed once per LOD 0 (one sort)."""

    def __init__(self, points: np.ndarray):
        p = np.asarray(points, dtype=np.float64)
        self.points = p
        self.n = p.shape[0]
        if self.n == 0:
            self.order = np.zeros(0, dtype=np.int64)
            self.level = np.zeros(0, dtype=np.int64)
            return
        lo = p.min(axis=0)
        ext = float((p.max(axis=0) - lo).max())
        scale = ((1 << _MORTON_BITS) - 1) / ext if ext > 0 else 0.0
        q = np.clip(np.floor((p - lo) * scale), 0, (1 << _MORTON_BITS) - 1).astype(np.uint64)
        code = (_spread3(q[:, 0]) << np.uint64(2)) | (_spread3(q[:, 1]) << np.uint64(1)) | _spread3(q[:, 2])
        self.order = np.argsort(code, kind="stable")
        c = code[self.order]
        level = np.empty(self.n, dtype=np.int64)
        level[0] = 0
        diff = c[1:] ^ c[:-1]
        # first in its level-L cell iff the codes differ in their top 3L bits (of 63)
        level[1:] = np.where(diff == 0, _MORTON_BITS + 1, (62 - _high_bit(diff)) // 3 + 1)
        self.level = level

    def take(self, count: int) -> np.ndarray:
        """(n,) bool over the sorted order: about ``count`` vertices, every vertex of the complete
        levels and an evenly spaced part of the next one (all when ``count >= n``)."""
        pick = np.zeros(self.n, dtype=bool)
        if count >= self.n:
            pick[:] = True
            return pick
        per = np.bincount(self.level, minlength=_MORTON_BITS + 2)
        total = np.cumsum(per)
        full = int(np.searchsorted(total, count, side="right")) - 1  # last level wholly taken
        pick |= self.level <= full
        rest = count - (int(total[full]) if full >= 0 else 0)
        if rest > 0:
            nxt = np.flatnonzero(self.level == full + 1)
            pick[nxt[np.linspace(0, nxt.size - 1, rest).round().astype(np.int64)]] = True
        return pick


class Reference:
    """LOD 0 with what every LOD's transfer and measurement needs (computed once)."""

    def __init__(self, part: MeshPart):
        self.part = part
        self.positions = part.positions
        faces = part.indices.astype(np.int64)
        self.faces_all = faces
        self.degenerate = degenerate_mask(part.positions, faces)
        # zero-area faces carry no surface and no trustworthy normal; keep them only if nothing else
        self.faces = faces[~self.degenerate] if (~self.degenerate).any() and self.degenerate.any() else faces
        fn = face_normals(part.positions, self.faces)
        ln = np.linalg.norm(fn, axis=1)
        self.face_unit = fn / np.where(ln > 0, ln, 1.0)[:, None]
        self._region = None
        self._samples = None
        self._sample_vertices = None
        self._sample_order = None
        self._tree = None
        self._kernel_tree = None
        self._chunks = None
        self._near = None
        self._defects = None
        self._seams = None
        self._volume = None

    @property
    def region(self) -> np.ndarray:
        """(faces,) connected component of each face of ``faces`` (through shared vertex ids:
        seams and creases split LOD 0 into regions), computed on first use."""
        if self._region is None:
            self._region = components(self.faces.shape[0], self.faces, self.part.n_vertices)
        return self._region

    @property
    def kernel(self) -> bool:
        """Whether the queries go to the compiled hierarchy (``tree``; ``lopcook.jit.use``)."""
        return jit.use(int(self.faces.shape[0]))

    @property
    def tree(self):
        """The compiled hierarchy over LOD 0's faces (``lopcook.simplify.kernels.Tree``), built once."""
        if self._kernel_tree is None:
            from . import kernels  # compiled kernels (numba): loaded only for large meshes
            self._kernel_tree = kernels.Tree(self.positions, self.faces)
        return self._kernel_tree

    def _bounded(self, points: np.ndarray, bound2: np.ndarray, closest: bool = True):
        """The hierarchy's answer within ``bound2``; ValueError where a bound is below the distance."""
        d, f, c = self.tree.closest(points, bound2, point=closest)
        if (f < 0).any():
            raise ValueError("query_bounded: a bound below the distance to LOD 0")
        return d, f, c

    def query(self, points: np.ndarray):
        """Closest points on LOD 0 (libigl AABB tree built once): (squared distance, face, point)."""
        if self.kernel:
            return self.tree.closest(points)
        import igl  # libigl (native) loads when LOD 0 is first queried

        if self._tree is None:
            self._pos = np.ascontiguousarray(self.positions, dtype=np.float64)
            self._fac = np.ascontiguousarray(self.faces, dtype=np.int64)
            self._tree = igl.AABB()
            self._tree.init(self._pos, self._fac)
        d, i, c = self._tree.squared_distance(self._pos, self._fac, np.ascontiguousarray(points, dtype=np.float64))
        return np.asarray(d), np.asarray(i, dtype=np.int64), np.asarray(c)

    def query_any(self, points: np.ndarray):
        """``query``'s (squared distance, face, point) for any ``points`` (q, 3), without a tree
        over all of LOD 0 above ``CHUNK_FACES`` faces (a tree takes about 240 bytes a face). Each
        point's distance is at most its distance to the nearest vertex of LOD 0's faces (a point
        of the surface), found in ``near_index``'s KD-tree; with that bound ``query_bounded``
        (``query_near`` for at most one point per ``NEAR_POINTS_PER_FACE`` faces) gives the exact
        closest distance and point (the face may differ where several are equally close). At most
        ``CHUNK_FACES`` faces: ``query``."""
        if self.faces.shape[0] <= CHUNK_FACES or self.kernel:
            return self.query(points)
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if pts.shape[0] == 0:
            return np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 3))
        kd, _, _ = self.near_index
        dist = np.asarray(kd.query(pts, k=1)[0], dtype=np.float64)
        if pts.shape[0] * NEAR_POINTS_PER_FACE <= self.faces.shape[0]:  # few points: the faces near them
            return self.query_near(pts, dist * dist)
        return self.query_bounded(pts, dist * dist)

    def query_bounded(self, points: np.ndarray, bound2: np.ndarray, closest: bool = True):
        """``query``'s (squared distance, face, point) for ``points`` (q, 3) whose squared distance
        to LOD 0 is known to be at most ``bound2`` (q,), without a tree over all of LOD 0.

        Meshes of at most ``CHUNK_FACES`` faces use ``query``'s tree. Larger ones: LOD 0's faces
        cut into chunks by median splits (``chunks``); one libigl tree per chunk is built, queried
        and freed in turn (memory: one chunk's tree, not the whole one's). The
        chunks are swept once, in order; a point is queried in every chunk whose bounding box is
        within its best distance so far (its bound before its first query). The chunk that holds
        its closest face is always within that distance, so the distance is the exact closest one,
        as ``query``'s (the face may differ where several are equally close). ``closest=False``:
        the third value is None (the closest points are neither kept nor returned).

        With two LOD workers (``lopcook.simplify.workers.workers``) and at least
        ``PARALLEL_POINTS`` points, a forked child sweeps the first half of the chunks while this
        process sweeps the second (starting from ``bound2``, a superset of what the serial sweep
        searches); the sweep is then replayed in chunk order with the serial rule on those
        results, so the answer is the serial one, bit for bit. With the compiled hierarchy
        (``kernel``): its answer within the bounds."""
        if self.kernel:
            return self._bounded(points, bound2, closest)
        if self.faces.shape[0] <= CHUNK_FACES:
            return self.query(points)
        pts = np.ascontiguousarray(points, dtype=np.float64)
        # slack for rounding: a bound equal to the distance must not lose the closest face
        best = np.asarray(bound2, dtype=np.float64) * (1.0 + 1e-9) + 1e-300
        face = np.full(pts.shape[0], -1, dtype=np.int64)
        near = np.zeros_like(pts) if closest else None
        chunks = self.chunks
        n = len(chunks)
        cand = self._candidates(pts, best)
        if pts.shape[0] >= PARALLEL_POINTS and n >= 2 and workers() >= 2:
            half = n // 2
            front = isolate.start(self._sweep, pts, best.copy(), cand, range(half), closest)
            try:
                records = self._sweep(pts, best.copy(), cand, range(half, n), closest)
            except BaseException:
                front.cancel()
                raise
            records = front.result() + records
        else:
            records = self._sweep(pts, best.copy(), cand, range(n), closest)
        records.reverse()
        while records:  # the serial sweep, replayed on the queried distances (each freed after use)
            c, sel_q, d, f, cp = records.pop()
            at = np.flatnonzero(self._reaches(c, pts[sel_q], best[sel_q]))  # the serial rule's subset
            if at.size == 0:
                continue
            sel = sel_q[at]
            dd = d[at]
            better = dd <= best[sel]
            hit = sel[better]
            best[hit] = dd[better]
            face[hit] = f[at[better]]
            if closest:
                near[hit] = cp[at[better]]
            del sel_q, d, f, cp
        if (face < 0).any():  # a bound below the true distance: not a caller of this contract
            raise ValueError("query_bounded: a bound below the distance to LOD 0")
        return best, face, near

    def _reaches(self, c: int, q: np.ndarray, best: np.ndarray) -> np.ndarray:
        """(len(q),) bool: whether each point's best squared distance reaches chunk ``c``'s box."""
        lo, hi = self.chunks[c][1], self.chunks[c][2]
        gap = np.maximum(np.maximum(lo - q, q - hi), 0.0)
        return np.einsum("ij,ij->i", gap, gap) <= best

    def _sweep(self, pts: np.ndarray, best: np.ndarray, cand: list, cs, closest: bool = True) -> list:
        """For the chunks ``cs`` in order: ``(c, points, squared distance, face, closest point or
        None)`` of the points whose ``best`` reaches the chunk's box (tested among the chunk's
        ``cand``), ``best`` (this call's own copy) lowered as they are found."""
        import igl  # libigl (native) loads when LOD 0 is first queried

        pos = np.ascontiguousarray(self.positions, dtype=np.float64)
        out = []
        for c in cs:
            if self.chunks[c][0].size == 0:
                continue
            sel = cand[c][self._reaches(c, pts[cand[c]], best[cand[c]])]
            if sel.size == 0:
                continue
            ch = self.chunks[c][0]
            fc = np.ascontiguousarray(self.faces[ch])
            tree = igl.AABB()
            tree.init(pos, fc)
            d, i, cp = tree.squared_distance(pos, fc, np.ascontiguousarray(pts[sel]))
            del tree, fc
            d = np.asarray(d)
            best[sel] = np.minimum(best[sel], d)  # sel is distinct
            out.append((c, sel, d, ch[np.asarray(i, dtype=np.int64)], np.asarray(cp) if closest else None))
            del cp
        return out

    def query_near(self, points: np.ndarray, bound2: np.ndarray):
        """``query_bounded`` for a few points with small bounds: only the LOD 0 faces that can
        hold a closest point are put in a libigl tree.

        The closest point p* of q lies on a face T* whose nearest vertex to p* is at most
        ``max_edge`` from p*, so within ``sqrt(bound2) + max_edge`` of q: the faces around the LOD 0
        vertices in that ball (a KD-tree over the vertices, built once) hold T*, and the distance
        is the exact closest one. Where the points' faces are more than ``CHUNK_FACES``, the points
        are split in two at the median of their longest axis, again until each group's faces are
        at most ``CHUNK_FACES`` (one tree per group); a single point with more faces than that is
        queried with ``query_bounded``. With the compiled hierarchy (``kernel``): its answer within
        the bounds."""
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if self.kernel and pts.shape[0]:
            return self._bounded(pts, bound2)
        import igl  # libigl (native) loads when LOD 0 is first queried

        if pts.shape[0] == 0 or self.faces.shape[0] <= CHUNK_FACES:
            return self.query_bounded(pts, bound2)
        bound2 = np.asarray(bound2, dtype=np.float64)
        kd, used, max_edge = self.near_index
        r = np.sqrt(bound2) * (1.0 + 1e-9) + max_edge * (1.0 + 1e-9)
        hits = kd.query_ball_point(pts, r)
        pos = np.ascontiguousarray(self.positions, dtype=np.float64)
        d = np.empty(pts.shape[0])
        face = np.empty(pts.shape[0], dtype=np.int64)
        near_pt = np.empty_like(pts)
        near = np.zeros(self.positions.shape[0], dtype=bool)
        todo = [np.arange(pts.shape[0])]
        while todo:
            idx = todo.pop()
            near[:] = False
            near[used[np.fromiter(itertools.chain.from_iterable(hits[i] for i in idx.tolist()),
                                  dtype=np.int64)]] = True
            faces = np.flatnonzero(near[self.faces].any(axis=1))  # the faces around those vertices
            if faces.size > CHUNK_FACES and idx.size > 1:
                q = pts[idx]
                axis = int(np.argmax(q.max(axis=0) - q.min(axis=0)))
                order = np.argsort(q[:, axis], kind="stable")
                half = idx.size // 2
                todo += [idx[order[half:]], idx[order[:half]]]
                continue
            if faces.size > CHUNK_FACES or faces.size == 0:
                d[idx], face[idx], near_pt[idx] = self.query_bounded(pts[idx], bound2[idx])
                continue
            sub = np.ascontiguousarray(self.faces[faces])
            dd, i, c = igl.point_mesh_squared_distance(np.ascontiguousarray(pts[idx]), pos, sub)
            d[idx], face[idx], near_pt[idx] = np.asarray(dd), faces[np.asarray(i, dtype=np.int64)], np.asarray(c)
        return d, face, near_pt

    @property
    def near_index(self):
        """``(KD-tree over the referenced vertices, their ids, longest edge)`` for ``query_near``,
        built once."""
        if self._near is None:
            from scipy.spatial import cKDTree  # scipy loads only for a LOD 0 above CHUNK_FACES faces

            f, p = self.faces, self.positions
            # one contiguous 1-D array per axis and corner ((m,) temporaries; strided (m, 3) gathers
            # are several times slower); the longest edge within a rounding of an (m, 3) einsum's
            # (its sum order may differ), far inside query_near's relative slack of 1e-9
            corner = [np.ascontiguousarray(f[:, j]) for j in range(3)]
            cols = [np.ascontiguousarray(p[:, axis]) for axis in range(3)]
            max_edge = 0.0
            for a, b in ((0, 1), (1, 2), (2, 0)):
                e2 = None
                for col in cols:
                    d = col[corner[b]] - col[corner[a]]
                    d *= d
                    e2 = d if e2 is None else e2 + d
                max_edge = max(max_edge, float(e2.max()))
            del corner, cols, e2, d
            used = self.sample_vertices
            # unbalanced, uncompacted: several times faster to build, and a ball query finds the
            # same vertices (query_near uses them as a set)
            self._near = (cKDTree(p[used], balanced_tree=False, compact_nodes=False), used, float(np.sqrt(max_edge)))
        return self._near

    def warm(self) -> None:
        """Build now the search structures a LOD's transfer will use (the chunks and
        ``near_index``, above ``CHUNK_FACES`` faces): the chain calls this while a backend runs in
        its child process, when this process would only wait. (``sample_order`` is left to the
        measurement after the transfer: built here it would add its arrays to the transfer's peak.)
        With the compiled hierarchy: that hierarchy."""
        if self.kernel:
            _ = self.tree
        elif self.faces.shape[0] > CHUNK_FACES:
            _ = self.chunks, self.near_index

    @property
    def chunks(self) -> list:
        """[(face ids, box min, box max)]: LOD 0's faces cut by median splits of their centroids
        (each along the longest side of its cell, ``2**L`` leaves of at most about ``CHUNK_FACES``
        faces), so that neighbouring chunks' boxes overlap only by about a face's size; built once
        (for ``query_bounded``)."""
        if self._chunks is None:
            p, f = self.positions, self.faces
            # one contiguous 1-D array per axis (gathers and reductions along (n, 3) columns are
            # strided and several times slower); the same values as the (n, 3) forms
            cols = [np.ascontiguousarray(p[:, a]) for a in range(3)]
            cen = []
            for col in cols:  # the centroids, an axis at a time ((m,) temporaries)
                c = col[f[:, 0]] + col[f[:, 1]]
                c += col[f[:, 2]]
                c /= 3.0
                cen.append(c)
            n_levels = max(1, int(np.ceil(np.log2(f.shape[0] / CHUNK_FACES))))
            level = [np.arange(f.shape[0], dtype=np.int64)]
            for _ in range(n_levels):
                nxt = []
                for ids in level:
                    half = ids.size // 2
                    if ids.size:
                        cs = [cen[a][ids] for a in range(3)]
                        axis = int(np.argmax([c.max() - c.min() for c in cs]))
                        c = cs[axis]
                        part = np.argpartition(c, half - 1 if half else 0)
                        value = float(c[part[max(half - 1, 0)]])
                        left = c <= value  # ties at the median go to the left cell
                    else:
                        left = np.zeros(0, dtype=bool)
                    nxt += [ids[left], ids[~left]]
                level = nxt
            del cen
            out = []
            for ids in level:  # each chunk's box from its own faces' corners (no per-face boxes kept)
                if ids.size:
                    fc = f[ids]
                    corner = [[col[fc[:, j]] for j in range(3)] for col in cols]
                    out.append((ids, np.array([min(x.min() for x in c) for c in corner], dtype=p.dtype),
                                np.array([max(x.max() for x in c) for c in corner], dtype=p.dtype)))
                    del fc, corner
                else:
                    out.append((ids, np.full(3, np.inf), np.full(3, -np.inf)))
            del cols
            self._chunks = out
        return self._chunks

    def _candidates(self, pts: np.ndarray, best: np.ndarray) -> list:
        """[(point ids, distinct, grouped by cell)] per chunk: a superset of the points whose
        ``best`` reaches the chunk's box. The points are grouped by the cell of a
        ``CANDIDATE_GRID``^3 grid over their box that holds them: the box of a group's points
        widened by the group's largest ``sqrt(best)`` holds each of their balls, so a group is a
        candidate only for the chunks whose boxes meet that widened box (one or a few)."""
        chunks = self.chunks
        n = len(chunks)
        g = CANDIDATE_GRID
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        scale = np.where(hi > lo, g / np.where(hi > lo, hi - lo, 1.0), 0.0)
        key = np.zeros(pts.shape[0], dtype=np.uint16)
        for a in range(3):
            cell = np.minimum(((pts[:, a] - lo[a]) * scale[a]).astype(np.int64), g - 1)
            key = key * np.uint16(g) + cell.astype(np.uint16)
        order = np.argsort(key, kind="stable")  # a radix sort of 16-bit keys
        key = key[order]
        at = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
        del key
        reach = np.sqrt(np.maximum(np.maximum.reduceat(best[order], at), 0.0)) * (1.0 + 1e-9)
        grouped = pts[order]
        group_lo = np.minimum.reduceat(grouped, at, axis=0) - reach[:, None]
        group_hi = np.maximum.reduceat(grouped, at, axis=0) + reach[:, None]
        del grouped
        ends = np.append(at[1:], pts.shape[0])
        out = []
        for c in range(n):
            meet = np.flatnonzero(((group_lo <= chunks[c][2]) & (group_hi >= chunks[c][1])).all(axis=1))
            out.append(np.concatenate([order[at[h]:ends[h]] for h in meet.tolist()]) if meet.size
                       else np.zeros(0, dtype=np.int64))
        return out

    @property
    def samples(self) -> np.ndarray:
        """(len(sample_vertices) + len(faces), 3): the referenced vertices, then the face centroids."""
        if self._samples is None:
            self._samples = samples(self.positions, self.faces)
        return self._samples

    @property
    def sample_vertices(self) -> np.ndarray:
        """(k,) int64 sorted ids of the vertices in ``samples`` (the first k rows)."""
        if self._sample_vertices is None:
            self._sample_vertices = used_ids(self.faces, self.positions.shape[0])
        return self._sample_vertices

    @property
    def sample_order(self):
        """``SampleOrder`` of the referenced vertices (``sample_vertices``), built once."""
        if self._sample_order is None:
            used = self.sample_vertices
            # every vertex referenced (the usual case): the positions themselves, not a copy
            whole = used.size == self.positions.shape[0]
            self._sample_order = SampleOrder(self.positions if whole else self.positions[used])
        return self._sample_order

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
            self._volume = signed_volume(self.positions, self.faces)
        return self._volume


__all__ = ["CHUNK_FACES", "CANDIDATE_GRID", "NEAR_POINTS_PER_FACE", "PARALLEL_POINTS", "Reference", "SampleOrder",
           "point_mesh", "samples"]
