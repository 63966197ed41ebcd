"""Attribute transfer from LOD 0 to a simplified mesh: closest-point barycentric interpolation of
normals, UVs and colours, with corners re-split where LOD 0 has a crease or seam
(see ``lopcook.simplify.chain`` for the contract)."""

from __future__ import annotations

import itertools

import numpy as np

from ..lop.codecs import BY_NAME, CODECS
from ..mesh import components, degenerate_mask, face_normals, stable_argsort, unique_rows, used_ids, weld_labels
from ..types import MeshPart
from .backends import BackendFailure, BackendResult, Work
from .error import point_mesh, samples
from .topology import SeamStats, mesh_defects, seam_stats, signed_volume


#: a face whose normal is more than 120 degrees from LOD 0's nearby faces is flipped
FLIP_COS = -0.5

#: corners look for their side of a seam this fraction of the way towards the face centroid
NUDGE = 0.25


#: ``Reference.query_bounded`` builds libigl trees over chunks of at most about this many LOD 0
#: faces (a tree over 1.1M faces takes about 265 MB)
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


def _workers() -> int:
    from .parallel import workers

    return workers()


#: corners per step of the transfer's side test (bounds its (k, 3, 3) temporaries)
TRANSFER_CHUNK = 1 << 17


def barycentric(points: np.ndarray, tri: np.ndarray, clamp: bool) -> np.ndarray:
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

    def query_any(self, points: np.ndarray):
        """``query``'s (squared distance, face, point) for any ``points`` (q, 3), without a tree
        over all of LOD 0 above ``CHUNK_FACES`` faces (there a tree takes about 240 bytes a face:
        about 1 GB at 4.4M faces). Each point's distance is at most its distance to the nearest
        vertex of LOD 0's faces (a point of the surface), found in ``near_index``'s KD-tree; with
        that bound ``query_bounded`` (``query_near`` for at most one point per
        ``NEAR_POINTS_PER_FACE`` faces) gives the exact closest distance and point (the face may
        differ where several are equally close). At most ``CHUNK_FACES`` faces: ``query``."""
        if self.faces.shape[0] <= CHUNK_FACES:
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
        and freed in turn (memory: one chunk's tree, 1/8 of the whole one's at 1.1M faces). The
        chunks are swept once, in order; a point is queried in every chunk whose bounding box is
        within its best distance so far (its bound before its first query). The chunk that holds
        its closest face is always within that distance, so the distance is the exact closest one,
        as ``query``'s (the face may differ where several are equally close). ``closest=False``:
        the third value is None (the closest points are neither kept nor returned).

        With two LOD workers (``lopcook.simplify.parallel.workers``) and at least
        ``PARALLEL_POINTS`` points, a forked child sweeps the first half of the chunks while this
        process sweeps the second (starting from ``bound2``, a superset of what the serial sweep
        searches); the sweep is then replayed in chunk order with the serial rule on those
        results, so the answer is the serial one, bit for bit."""
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
        if pts.shape[0] >= PARALLEL_POINTS and n >= 2 and _workers() >= 2:
            from .. import isolate

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
        import igl

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
        queried with ``query_bounded``."""
        import igl

        pts = np.ascontiguousarray(points, dtype=np.float64)
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
            from scipy.spatial import cKDTree

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
        measurement after the transfer: built here it would add its arrays to the transfer's peak.)"""
        if self.faces.shape[0] > CHUNK_FACES:
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
        """``error.SampleOrder`` of the referenced vertices (``sample_vertices``), built once."""
        if self._sample_order is None:
            from .error import SampleOrder

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


def interpolate(values: np.ndarray, ref: Reference, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    corners = ref.faces[face]  # (q, 3) vertex ids
    return np.einsum("qk,qkd->qd", bary, values[corners].astype(np.float64))


#: corner values farther than this from their vertex's value belong to another side of a seam or
#: crease: (normal angle in degrees, UV distance, colour distance)
SPLIT_NORMAL_DEG = 30.0


SPLIT_UV = 5e-3


SPLIT_COLOR = 0.02


def _direction_fix(val: np.ndarray, fallback_normal: np.ndarray) -> np.ndarray:
    """A blended direction made unit again (``fallback_normal``, LOD 0's face normal, where the
    blend vanishes); components after the third (a handedness) snapped to +-1."""
    xyz = val[:, :3]
    ln = np.linalg.norm(xyz, axis=1)
    xyz = np.where((ln > 1e-6)[:, None], xyz / np.where(ln > 1e-6, ln, 1.0)[:, None], fallback_normal)
    if val.shape[1] == 3:
        return xyz
    return np.concatenate([xyz, np.where(val[:, 3:] >= 0.0, 1.0, -1.0)], axis=1)


def attributes_at(ref: Reference, names: list, face: np.ndarray, bary: np.ndarray,
                   fallback_normal: np.ndarray) -> dict:
    """LOD 0's attributes ``names`` interpolated at (face, bary), made valid by their codec's
    error model: directions unit (LOD 0's face normal where the interpolation vanishes), colours
    clipped."""
    out = {}
    src = ref.part
    for name in names:
        val = interpolate(src.attributes[name], ref, face, bary)
        model = BY_NAME[name].error_model
        if model == "direction":
            val = _direction_fix(val, fallback_normal)
        elif model == "color":
            val = np.clip(val, 0.0, 1.0)
        out[name] = val
    return out


def _extra_differs(va: np.ndarray, vb: np.ndarray) -> np.ndarray:
    """Rows whose components after the third (a direction's handedness) differ."""
    return (va[:, 3:] != vb[:, 3:]).any(axis=1) if va.shape[1] > 3 else np.zeros(va.shape[0], dtype=bool)


def differs(a: dict, b: dict) -> np.ndarray:
    """Rows where any attribute of ``a`` and ``b`` is beyond its split tolerance: directions more
    than ``SPLIT_NORMAL_DEG`` apart (or of another handedness), texture coordinates ``SPLIT_UV``,
    colours ``SPLIT_COLOR`` (largest component difference)."""
    bad = None
    for name, va in a.items():
        vb = b[name]
        model = BY_NAME[name].error_model
        if model == "direction":
            d = np.einsum("ij,ij->i", va[:, :3], vb[:, :3]) < np.cos(np.radians(SPLIT_NORMAL_DEG))
            d |= _extra_differs(va, vb)
        elif model == "texcoord":
            d = np.abs(va - vb).max(axis=1) > SPLIT_UV
        else:
            d = np.abs(va - vb).max(axis=1) > SPLIT_COLOR
        bad = d if bad is None else bad | d
    return bad


def key_order(names) -> list:
    """Attribute names in the order their bits key vertices: texture coordinates first, then the
    others in record order (``CODECS``)."""
    return sorted(names, key=lambda n: (BY_NAME[n].error_model != "texcoord", CODECS.index(BY_NAME[n])))


def exact_sources(ref: Reference, points: np.ndarray):
    """LOD 0 vertices at exactly the positions ``points`` (k, 3), or None when some point is not
    exactly a vertex of LOD 0.

    Only vertices that LOD 0's (non-degenerate) faces reference count. Returns ``(count, start,
    order)``: point i is bit for bit the position of the ``count[i] >= 1`` LOD 0 vertices
    ``order[start[i]:start[i] + count[i]]`` (more than one where LOD 0 has a seam or crease there:
    co-located vertices with different attributes). meshoptimizer's output vertices are input
    vertices, so along a chain of meshoptimizer LODs every LOD vertex is a LOD 0 vertex; positions
    moved by pymeshlab or fast-simplification are not, and those results take the closest-point
    transfer."""
    used = ref.sample_vertices
    k = points.shape[0]
    lab, n_lab = weld_labels(np.concatenate([ref.positions[used], points]), np.int64)
    lab_ref, lab_q = lab[:used.size], lab[used.size:]
    count_of = np.bincount(lab_ref, minlength=n_lab)
    count = count_of[lab_q]
    if k and int(count.min()) == 0:
        return None
    order = used[stable_argsort(lab_ref)[0]]
    first_of = np.zeros(n_lab, dtype=np.int64)
    np.cumsum(count_of[:-1], out=first_of[1:])
    return count, first_of[lab_q], order


#: candidate scores of a co-located LOD 0 vertex: attribute distances in units of the split
#: tolerances (a normal 30 degrees off, a UV 5e-3 off, a colour 0.02 off each score 1)
def _attribute_distance(names: list, cand: dict, ext: dict) -> np.ndarray:
    score = None
    for name in names:
        a, b = cand[name].astype(np.float64), ext[name]
        model = BY_NAME[name].error_model
        if model == "direction":
            d = (1.0 - np.einsum("ij,ij->i", a[:, :3], b[:, :3])) / (1.0 - np.cos(np.radians(SPLIT_NORMAL_DEG)))
            if a.shape[1] > 3:
                d = d + _extra_differs(a, b)
        else:
            d = np.abs(a - b).max(axis=1) / (SPLIT_UV if model == "texcoord" else SPLIT_COLOR)
        score = d if score is None else score + d
    return score


def exact_corner_sources(ref: Reference, names: list, P: np.ndarray, F: np.ndarray, centroid: np.ndarray,
                         found, corner_uvs: np.ndarray | None = None) -> np.ndarray:
    """(3m,) the LOD 0 vertex whose attributes each face corner of (P, F) copies, for a result
    whose every vertex is a LOD 0 vertex (``found = exact_sources(ref, P)``).

    A vertex with one LOD 0 vertex at its position: that one, for all its corners. Where several
    LOD 0 vertices share the position (a seam or crease of LOD 0), the corner's side is LOD 0's
    face nearest to the point ``NUDGE`` of the way from the vertex towards the LOD face's centroid
    (one closest-point query per such corner): a candidate that is a corner of that face, else the
    candidate whose attributes are nearest to that face's attribute field extrapolated to the
    vertex (ties: the lowest LOD 0 index). ``corner_uvs`` (3m, 2): the UVs the corners already
    have (the backend's, copied from the input vertex they are): only a candidate with the same
    UV bits is then chosen where one exists, so all of a corner's attributes come from one LOD 0
    vertex."""
    count, start, order = found
    vid = F.ravel()
    src = order[start[vid]]  # the only candidate, or the first of several
    amb = np.flatnonzero(count[vid] > 1)
    if amb.size == 0 or not names:
        return src
    face_of_corner = amb // 3
    pv = P[vid[amb]]
    g2 = ref.query_near(pv + NUDGE * (centroid[face_of_corner] - pv),
                           (NUDGE ** 2) * np.einsum("ij,ij->i", centroid[face_of_corner] - pv,
                                                    centroid[face_of_corner] - pv))[1]
    ext = attributes_at(ref, names, g2, barycentric(pv, ref.positions[ref.faces[g2]], clamp=False),
                        ref.face_unit[g2])
    c = count[vid[amb]]
    pair = np.repeat(np.arange(amb.size), c)  # (corner, candidate) pairs
    offs = np.arange(pair.size) - np.repeat(np.cumsum(c) - c, c)
    cand = order[start[vid[amb]][pair] + offs]
    score = _attribute_distance(names, {n: ref.part.attributes[n][cand] for n in names},
                                {n: v[pair] for n, v in ext.items()})
    incident = (ref.faces[g2[pair]] == cand[:, None]).any(axis=1)
    score = np.where(incident, -1.0, score)
    if corner_uvs is not None and ref.part.uvs is not None:
        same_uv = (_bits(ref.part.uvs[cand]) == _bits(corner_uvs[amb][pair])).all(axis=1)
        score = score + np.where(same_uv, 0.0, 1e6)
    best = np.lexsort((cand, score, pair))  # per corner: lowest score, then lowest id
    head = np.r_[True, pair[best][1:] != pair[best][:-1]]
    src[amb] = cand[best[head]]
    return src


def _bits(values: np.ndarray) -> np.ndarray:
    """int64 columns of float32 bit patterns (``-0.0`` as ``0.0``), the vertex keys' form."""
    return (np.ascontiguousarray(values, dtype=np.float32) + np.float32(0.0)).view(np.int32).astype(np.int64)


def _exact_vertex_key(vid: np.ndarray, srcv, found, corner_attr: dict, names: list):
    """``unique_rows`` of the corners' (vertex, attribute bits) rows for an exact copy, through a
    two-column integer key: ``(first, inverse)`` equal to the generic key's, or None when it does
    not apply (per-corner UVs that are not a function of the vertex).

    Corners of a vertex with one LOD 0 vertex at its position copy the same values; at co-located
    vertices the copied LOD 0 vertex is replaced by the first one of the same vertex with the same
    attribute bits, so equal rows get equal keys."""
    if "uvs" in corner_attr and "uvs" not in names:  # the backend's per-corner UVs
        uvb = _bits(corner_attr["uvs"])
        per_vertex = np.zeros((int(vid.max()) + 1, 2), dtype=np.int64)
        per_vertex[vid] = uvb
        if not (per_vertex[vid] == uvb).all():
            return None
    if srcv is None:
        return unique_rows(vid.reshape(-1, 1).astype(np.int64))
    count = found[0]
    canon = srcv.copy()
    amb = np.flatnonzero(count[vid] > 1)
    if amb.size:
        first, inv = unique_rows(np.concatenate([vid[amb].reshape(-1, 1).astype(np.int64)]
                                                + [_bits(corner_attr[n][amb]) for n in names], axis=1))
        canon[amb] = srcv[amb][first][inv]
    key = vid.astype(np.int64)
    key *= int(canon.max()) + 1
    key += canon
    del canon
    return unique_rows(key.reshape(-1, 1))


def transfer_attributes(res: BackendResult, ref: Reference, input_part: MeshPart, work: Work, mode: str,
              max_flipped_fraction: float, exact: bool = True) -> tuple[MeshPart, dict]:
    """Attributes for the cleaned backend result; flip check; LOD -> LOD 0 distance.

    **Exact copy** (``exact`` and every result vertex bit for bit a LOD 0 vertex, as with
    meshoptimizer: ``exact_sources``): each face corner copies the normals, colours and
    (transferred) UVs of one LOD 0 vertex at its position, bit for bit (``exact_corner_sources``
    picks among co-located LOD 0 vertices); the LOD -> LOD 0 distance is exactly 0 at the vertices,
    so only the face centroids are queried and ``lod_to_ref`` is their largest distance.
    ``info["on_ref"]``: (LOD 0 vertices,) bool, True at LOD 0 vertices known to be vertices of the
    LOD (those the exact copy read; ``error.sampled_ref_to_lod`` needs no query for them), None
    for the closest-point transfer.

    **Closest-point transfer** (otherwise; ``exact=False`` forces it, for comparisons): every LOD
    vertex takes LOD 0's attributes at its closest point. A face corner whose own side
    (LOD 0's face nearest to the face centroid, refined by a query pulled ``NUDGE`` of the way from
    the corner towards the centroid) gives clearly different values at the vertex (beyond the
    ``_SPLIT_*`` tolerances: another side of a seam or crease) gets those values instead; corners
    of one vertex that land in the same LOD 0 region share one value."""
    P, F = res.positions, res.faces
    m, k = F.shape[0], P.shape[0]
    found = exact_sources(ref, P) if exact else None
    if found is not None:
        # every vertex is a LOD 0 vertex (meshoptimizer): at distance 0, attributes copied; only
        # the face interiors (centroids) are queried. Row-wise temporaries only ((m, 3), no (m, 3, 3)).
        centroid = P[F[:, 0]] + P[F[:, 1]]
        centroid += P[F[:, 2]]
        centroid /= 3.0
        # a vertex of the face lies on LOD 0: its distance bounds the centroid's
        bound = np.full(m, np.inf)
        for j in range(3):
            gap = centroid - P[F[:, j]]
            np.minimum(bound, np.einsum("ij,ij->i", gap, gap), out=bound)
        del gap
        d2, fc, _ = ref.query_bounded(centroid, bound, closest=False)
        del bound, _
    else:
        tri = P[F]
        centroid = tri.mean(axis=1)
        d2, fid, closest = ref.query_any(np.concatenate([P, centroid]))
        fv, fc = fid[:k], fid[k:]
        del tri
    lod_to_ref = float(np.sqrt(d2.max()))
    del d2

    # flipped faces: facing away (more than 120 degrees) from LOD 0's nearest face at the centroid
    # and at 2 of the 3 points half-way to the corners (one sample alone is fooled where a coarse
    # face cuts a sharp edge or lies between two sheets)
    unit = face_normals(P, F)
    fl = np.linalg.norm(unit, axis=1)
    unit /= np.where(fl > 0, fl, 1.0)[:, None]
    del fl
    cand = np.flatnonzero(np.einsum("ij,ij->i", unit, ref.face_unit[fc]) < FLIP_COS)
    flipped = 0
    if cand.size:
        tri_c = P[F[cand]]
        half = 0.5 * (tri_c + centroid[cand][:, None, :])  # (c, 3, 3)
        if found is not None:  # half-way to a corner that lies on LOD 0
            hb = 0.25 * ((tri_c - centroid[cand][:, None, :]) ** 2).sum(axis=2)
            fh = ref.query_near(half.reshape(-1, 3), hb.reshape(-1))[1].reshape(-1, 3)
        else:
            fh = ref.query_any(half.reshape(-1, 3))[1].reshape(-1, 3)
        votes = (np.einsum("ij,ikj->ik", unit[cand], ref.face_unit[fh]) < FLIP_COS).sum(axis=1)
        flipped = int((votes >= 2).sum())
    if flipped > max_flipped_fraction * m and flipped > 0:
        raise BackendFailure(f"{flipped} of {m} faces are flipped against the source surface")
    if ref.defects["closed"] and abs(ref.volume) > 0:
        vol = signed_volume(P, F)
        if np.sign(vol) != np.sign(ref.volume):
            raise BackendFailure("the closed mesh's signed volume changed sign (inside out)")

    src = ref.part
    names = [c.name for c in CODECS if c.error_model != "texcoord" and c.name in src.attributes]
    uv_from_ref = src.uvs is not None and mode != "xatlas" and res.wedge_uvs is None and not (
        mode == "lock" and res.vertex_source is not None and work.region is not None)
    if uv_from_ref:
        names.append("uvs")
    vid = F.ravel()
    corner_attr = {}
    srcv = None
    if found is not None:
        if names:
            wedge = (res.wedge_uvs.reshape(-1, 2).astype(np.float32) if res.wedge_uvs is not None
                     and src.uvs is not None and not uv_from_ref and mode != "xatlas" else None)
            srcv = exact_corner_sources(ref, names, P, F, centroid, found, wedge)
            corner_attr = {n: np.ascontiguousarray(src.attributes[n][srcv], dtype=np.float32) for n in names}
    elif names:
        face_of_corner = np.repeat(np.arange(m), 3)
        bary_v = barycentric(closest[:k], ref.positions[ref.faces[fv]], clamp=True)
        at_v = attributes_at(ref, names, fv, bary_v, ref.face_unit[fv])
        # phase 1: the corner's side = LOD 0's face nearest to the LOD face's centroid. That face's
        # attribute field, extrapolated linearly to the vertex, matches the vertex's own value on a
        # smooth field and differs across a seam or crease.
        g = fc[face_of_corner]
        split = np.empty(vid.size, dtype=bool)
        for s0 in range(0, vid.size, TRANSFER_CHUNK):  # row-wise: (chunk, 3, 3) temporaries only
            sl = slice(s0, s0 + TRANSFER_CHUNK)
            gs, vs = g[sl], vid[sl]
            ext = attributes_at(ref, names, gs, barycentric(P[vs], ref.positions[ref.faces[gs]], clamp=False),
                                 ref.face_unit[gs])
            split[sl] = differs({n: at_v[n][vs] for n in names}, ext)
            del ext
        cs = np.flatnonzero(split)
        at2 = {}
        if cs.size:
            # phase 2: only for corners that look split, find their side near the corner itself
            q = P[vid[cs]]
            q = q + NUDGE * (centroid[face_of_corner[cs]] - q)
            g2 = ref.query_any(q)[1]
            g[cs] = g2
            pv_cs = P[vid[cs]]
            tri2 = ref.positions[ref.faces[g2]]
            ext2 = attributes_at(ref, names, g2, barycentric(pv_cs, tri2, clamp=False), ref.face_unit[g2])
            split[cs] = differs({n: at_v[n][vid[cs]] for n in names}, ext2)
            # the value of a split corner: its side's field at the vertex, kept inside that face
            at2 = attributes_at(ref, names, g2, barycentric(pv_cs, tri2, clamp=True), ref.face_unit[g2])
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
            if BY_NAME[n].error_model == "direction":
                val = val.copy()
                val[:, :3] = val[:, :3] / np.linalg.norm(val[:, :3], axis=1, keepdims=True)
            corner_attr[n] = val.astype(np.float32)  # per group; per corner: [group]
    per_group = bool(names) and found is None  # every attribute so far is a function of the corner's group
    if src.uvs is not None and mode != "xatlas" and not uv_from_ref:
        if per_group:
            corner_attr = {n: v[group] for n, v in corner_attr.items()}
            per_group = False
        if res.wedge_uvs is not None:
            corner_attr["uvs"] = res.wedge_uvs.reshape(-1, 2).astype(np.float32)
        else:
            corner_attr["uvs"] = lock_uvs(res, input_part, work)[vid]

    def unique_vertices(row_vid: np.ndarray):
        keys = [row_vid.reshape(-1, 1).astype(np.int64)]
        for name in key_order(corner_attr):
            if name in corner_attr:
                keys.append((np.ascontiguousarray(corner_attr[name]) + np.float32(0.0)).view(np.int32)
                            .astype(np.int64))
        return unique_rows(np.concatenate(keys, axis=1))

    exact_key = _exact_vertex_key(vid, srcv, found, corner_attr, names) if found is not None else None
    if exact_key is not None:
        vfirst, vinv = exact_key
        pick = vfirst
    elif per_group:
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
        attributes={n: v[pick] for n, v in corner_attr.items()},
        source=input_part.source,
        normals_computed=input_part.normals_computed,
        texture=input_part.texture,
        mesh_key=input_part.mesh_key,
        double_sided=input_part.double_sided,
    )
    on_ref = None
    if found is not None:  # the LOD 0 vertices the corners copy lie on the LOD: at distance 0
        on_ref = np.zeros(ref.positions.shape[0], dtype=bool)
        on_ref[srcv if srcv is not None else found[2][found[1][vid]]] = True
    return out, {"lod_to_ref": lod_to_ref, "flipped": flipped, "on_ref": on_ref}


def lock_uvs(res: BackendResult, input_part: MeshPart, work: Work) -> np.ndarray:
    """Per output vertex UVs for ``fast`` with locked seams: interpolate the input's UVs at the
    closest point when that point lies in the vertex's own UV island (known from the collapse map),
    else copy the UV of the input vertex it came from."""
    src = res.vertex_source
    P = res.positions
    d2, fid, closest = point_mesh(P, work.positions, work.faces)
    island_of_face = work.region[work.faces[:, 0]]
    own = work.region[src]
    ok = island_of_face[fid] == own
    bary = barycentric(closest, work.positions[work.faces[fid]], clamp=True)
    interp = np.einsum("qk,qkd->qd", bary, work.uvs[work.faces[fid]])
    # a vertex that did not move (seam and border vertices are locked) keeps its UV bit for bit
    unmoved = (P == work.positions[src]).all(axis=1)
    return np.where((ok & ~unmoved)[:, None], interp, work.uvs[src]).astype(np.float32)
