"""Discontinuity constraint: vertices where the picture has an edge that E_v cannot see.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 4 (per-buffer level B by the half-pixel criterion) and 5.1 (E_v, the attribute error), and
extends 5.1 to jumps *between* triangles -- a hard edge (co-located vertices with split normals), a
UV or colour seam, a fold sharper than a pixel, an open boundary: no triangle's E_v holds the jump,
yet moving such an edge changes every pixel it sweeps by the whole jump (coverage error, which k_f
cannot reach; why, and what the constraint costs on the corpus: docs/analyse.md, section 2b).

The model. At per-buffer level B the camera is where a B-bit grid cell projects to ``pixel_error``
pixels (``lopcook.viewing``: dx(B) = pixel_error * s_B, s_B metres per pixel). A vertex decoded at
m > B bits moves by at most dx(m) = dx(B) 2^(B-m), i.e. ``pixel_error * 2^(B-m)`` pixels. An edge
across which the colour jumps by J (colour units) moved by d pixels changes a pixel it crosses by at
most J * d. Requiring that to stay within ``edge_eps`` for every per-buffer level up to ``B_v``:

    m_v >= B_v + ceil(log2(pixel_error * J_v / edge_eps)),   clamped to [1, 24]

(no constraint when the logarithm is <= 0: the per-buffer level alone is enough). ``edge_eps``
(colour units) is the aggregate knob ``lopcook calibrate`` measures. B_v and J_v:

* **folds** (geometry): cut space into cubes of one pixel at level B (side s_B, power-of-two cells
  of the 24-bit grid, and a second lattice shifted by half a cell). A cell whose vertex normals
  spread by more than ``edge_angle_deg`` (some normal deviates from the cell's mean normal by more
  than half of it), or that holds an open-boundary vertex, contains an edge at level B: the surface
  turns away (or ends) within a pixel, so the vertices in it can form a silhouette or a crease there.
  B_v is the highest level in [max(1, edge_level - 8), edge_level] whose cell of v is such a cell,
  and J_v = 1 (surface against background or another surface: the whole colour range). Split
  normals (co-located vertices) and open boundaries qualify at every level, so B_v = edge_level.
* **seams** (attributes at the same position): co-located vertices (same 24-bit grid point, any
  part) whose base colours differ -- base = base-colour texture at the vertex's UV (nearest texel,
  repeat) times the vertex colour, as the render harness shades -- get B_v = edge_level and J_v =
  the largest channel difference to another vertex of the group. A UV seam whose two sides sample
  the same colours costs nothing.

Open boundary: an edge of the position-welded mesh (all parts, all co-located vertices merged) used
by exactly one triangle. Levels are computed per analysed scene (each LOD is analysed as a scene of
its own); co-located vertices then share the maximum (``analyse``). Units: metres, colour in [0, 1],
levels in bits. ``PIXEL_ERROR`` is the default half-pixel criterion (``lopcook.viewing.Viewing``);
the analysis does not know the viewing conditions, ``edge_eps`` absorbs other choices.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..grid import BITS
from ..mesh import stable_argsort, stable_lexsort

#: the half-pixel criterion's pixel error (``lopcook.viewing.Viewing``), pixels per dx(B)
PIXEL_ERROR = 0.5
#: levels below edge_level examined for folds (cells of 1 pixel at levels edge_level - 8 .. edge_level)
FOLD_LEVEL_SPAN = 8
#: grey the renderer uses for a part with neither texture nor vertex colours (lopcook.verify.renderer.BASE_GREY)
BASE_GREY = 0.8


class Discontinuity(NamedTuple):
    """Per part: ``level`` (n,) int64 in [1, 24] (1 = no constraint), ``jump`` (n,) float64 colour J_v
    (0 where none), ``fold_level`` (n,) int64 B_v of folds (0 = none), ``boundary`` (n,) bool,
    ``seam`` (n,) bool."""

    level: list
    jump: list
    fold_level: list
    boundary: list
    seam: list


def colocated_groups(q: np.ndarray) -> np.ndarray:
    """(N,) int64 group id per row of ``q`` (N, 3) grid integers: equal rows, equal ids (0..G-1, in
    lexicographic order of the rows)."""
    q = np.asarray(q, dtype=np.int64)
    n = q.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    order = stable_lexsort((q[:, 2], q[:, 1], q[:, 0]))
    s = q[order]
    start = np.ones(n, dtype=bool)
    start[1:] = np.any(s[1:] != s[:-1], axis=1)
    out = np.empty(n, dtype=np.int64)
    out[order] = np.cumsum(start) - 1
    return out


def boundary_vertices(groups: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(N,) bool: vertices on an open boundary of the welded mesh. ``groups`` (N,) from
    ``colocated_groups``; ``triangles`` (M, 3) indices into the N vertices (all parts)."""
    n = groups.shape[0]
    if n == 0 or triangles.size == 0:
        return np.zeros(n, dtype=bool)
    ng = int(groups.max()) + 1
    small = np.int32 if ng < (1 << 31) - 1 else np.int64  # halves the memory traffic of the 3M edges
    g = groups.astype(small)[np.asarray(triangles)]
    a = g.ravel()  # half-edge 3f + k runs from corner k to corner (k + 1) % 3 of face f
    b = g[:, [1, 2, 0]].ravel()
    keep = a != b  # edges collapsed by welding are no edges
    a, b = a[keep], b[keep]
    key = np.minimum(a, b).astype(np.int64) * ng + np.maximum(a, b)
    key.sort()
    first = np.r_[True, key[1:] != key[:-1]]
    last = np.r_[key[1:] != key[:-1], True]
    single = key[first & last]  # keys that occur once: edges of one triangle
    on = np.zeros(ng, dtype=bool)
    on[single // ng] = True
    on[single % ng] = True
    return on[groups]


def _texels(texture, cache: dict) -> np.ndarray:
    key = texture.digest
    if key not in cache:
        img = texture.image().convert("RGB")
        cache[key] = np.asarray(img, dtype=np.float32) / np.float32(255.0)
    return cache[key]


def base_colours(parts, cache: dict | None = None) -> np.ndarray:
    """(N, 3) float64 base colour per vertex of all parts, in [0, 1]: the base-colour texture at the
    vertex's UV (nearest texel, repeat wrap, glTF origin top-left) times the vertex colour (RGB);
    either is 1 when absent, grey ``BASE_GREY`` when both are."""
    cache = {} if cache is None else cache
    out = []
    for p in parts:
        n = p.n_vertices
        has_tex = p.texture is not None and p.uvs is not None
        c = np.ones((n, 3)) if (has_tex or p.colors is not None) else np.full((n, 3), BASE_GREY)
        if has_tex:
            img = _texels(p.texture, cache)
            h, w = img.shape[:2]
            uv = np.nan_to_num(np.asarray(p.uvs, dtype=np.float64))
            x = np.floor(uv[:, 0] * w).astype(np.int64) % w
            y = np.floor(uv[:, 1] * h).astype(np.int64) % h
            c = c * img[y, x]
        if p.colors is not None:
            c = c * np.asarray(p.colors, dtype=np.float64)[:, :3]
        out.append(c)
    return np.concatenate(out) if out else np.zeros((0, 3))


def seam_jumps(groups: np.ndarray, colours: np.ndarray) -> np.ndarray:
    """(N,) float64: per vertex the largest channel difference of its base colour to another vertex
    of its co-located group (0 when alone). Per channel the largest difference to any member is the
    one to the group's smallest or largest value (rounded subtraction is monotone), so one pass of
    group minima and maxima gives it, whatever the group sizes."""
    n = groups.shape[0]
    out = np.zeros(n)
    if n == 0:
        return out
    order, gs = stable_argsort(groups)
    starts = np.flatnonzero(np.r_[True, gs[1:] != gs[:-1]])
    counts = np.diff(starts, append=n)
    c = np.asarray(colours, dtype=np.float64)[order]
    lo = np.repeat(np.minimum.reduceat(c, starts, axis=0), counts, axis=0)
    hi = np.repeat(np.maximum.reduceat(c, starts, axis=0), counts, axis=0)
    np.subtract(c, lo, out=lo)
    np.subtract(hi, c, out=hi)
    out[order] = np.maximum(lo, hi).max(axis=1)
    return out


def _cell_shift(level: int) -> int:
    """log2 of the side, in 24-bit grid units, of a cube one pixel wide at per-buffer level ``level``
    (s_B = dx(B) / pixel_error = sqrt(3) extent 2^-(B+1) / pixel_error), rounded to a power of two."""
    k = round(math.log2(math.sqrt(3.0) / PIXEL_ERROR)) + BITS - 1 - int(level)
    return int(min(max(k, 0), BITS))


def _spread3(x: np.ndarray) -> np.ndarray:
    """(N,) int64 with the low 21 bits of ``x`` moved to every third bit (bit i -> bit 3i)."""
    x = np.asarray(x, dtype=np.int64) & 0x1FFFFF
    x = (x | (x << 32)) & 0x1F00000000FFFF
    x = (x | (x << 16)) & 0x1F0000FF0000FF
    x = (x | (x << 8)) & 0x100F00F00F00F00F
    x = (x | (x << 4)) & 0x10C30C30C30C30C3
    x = (x | (x << 2)) & 0x1249249249249249
    return x


def _morton(c: np.ndarray) -> np.ndarray:
    """(N,) int64 Morton code of (N, 3) integers in [0, 2^21): cells of any coarser power-of-two
    lattice (``c >> k``) are contiguous runs in this order (``morton >> 3k``)."""
    return (_spread3(c[:, 0]) << 2) | (_spread3(c[:, 1]) << 1) | _spread3(c[:, 2])


class _Fields(NamedTuple):
    """Per-vertex inputs of the fold test, in one sorted order: weighted normals (N, 3), unit
    normals (N, 3), has_normal (N,) bool (None where every vertex has a normal: then the weighted
    normals are the normals), boundary (N,) bool."""

    weighted: np.ndarray
    normals: np.ndarray
    has_normal: np.ndarray | None
    boundary: np.ndarray


_ROW = np.dtype((np.void, 24))  # one row of an (N, 3) float64 array


def _take_rows(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``a[rows]`` for a C-contiguous (N, 3) float64 ``a``, gathered as 24-byte items (several
    times faster than fancy indexing of the rows)."""
    return np.take(a.view(_ROW).reshape(-1), rows).view(np.float64).reshape(-1, 3)


def _sorted_fields(order: np.ndarray, normals, has_normal, boundary) -> _Fields:
    n = _take_rows(normals, order)
    b = np.take(boundary, order)
    if has_normal is None:  # n * 1.0 is n bit for bit: the product is skipped
        return _Fields(n, n, None, b)
    h = np.take(has_normal, order)
    return _Fields(n * h[:, None], n, h, b)


def _take_fields(f: _Fields, rows: np.ndarray) -> _Fields:
    """The rows ``rows`` of ``f``."""
    n = _take_rows(f.normals, rows)
    if f.has_normal is None:
        return _Fields(n, n, None, np.take(f.boundary, rows))
    return _Fields(_take_rows(f.weighted, rows), n, np.take(f.has_normal, rows), np.take(f.boundary, rows))


def _any_runs(flag: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(C,) bool: whether each run (first indices ``starts``) of the (N,) bool ``flag`` holds a True."""
    at = np.flatnonzero(flag)
    if 8 * at.size > flag.size:
        return np.logical_or.reduceat(flag, starts)
    edge = np.zeros(starts.size, dtype=bool)
    edge[np.searchsorted(starts, at, side="right") - 1] = True
    return edge


def _edge_runs(starts: np.ndarray, counts: np.ndarray, f: _Fields, cos_half: float) -> np.ndarray:
    """(C,) bool per cell, in the sorted order of ``f``: the cell holds an open-boundary vertex or a
    normal deviating from the cell's mean normal by more than the angle whose cosine is
    ``cos_half``. ``starts``: first sorted index of every cell (cells are contiguous runs),
    ``counts``: the cell's number of vertices."""
    mean = np.add.reduceat(f.weighted, starts, axis=0)
    length = np.linalg.norm(mean, axis=1)
    mean /= np.where(length > 0, length, 1.0)[:, None]
    dots = np.einsum("ij,ij->i", f.normals, np.repeat(mean, counts, axis=0))
    if f.has_normal is not None:
        dots = np.where(f.has_normal, dots, 1.0)
    if np.isnan(dots).any():  # the smallest dot of a cell holding a NaN is NaN: no fold
        edge = np.minimum.reduceat(dots, starts) < cos_half
        edge |= np.logical_or.reduceat(f.boundary, starts)
        return edge
    flag = dots < cos_half  # without NaNs, the smallest dot is below it exactly when one dot is
    flag |= f.boundary
    return _any_runs(flag, starts)


def _alone_edges(f: _Fields, cos_half: float) -> np.ndarray:
    """(N,) bool: ``_edge_runs`` of a cell holding only that vertex (its mean normal is its own)."""
    length = np.linalg.norm(f.weighted, axis=1)
    mean = f.weighted / np.where(length > 0, length, 1.0)[:, None]
    dots = np.einsum("ij,ij->i", f.normals, mean)
    if f.has_normal is not None:
        dots = np.where(f.has_normal, dots, 1.0)
    edge = dots < cos_half
    edge |= f.boundary
    return edge


def _lattice_edges(order: np.ndarray, starts: np.ndarray, fields: _Fields | None, source: tuple,
                   alone: np.ndarray, cos_half: float) -> np.ndarray:
    """(N,) bool in the order ``order`` (vertex ids, cells contiguous from ``starts``): ``_edge_runs``
    of the vertex's cell. ``fields``: the fields in that order, or None to gather them from
    ``source`` (normals, has_normal, boundary). ``alone`` (N,) bool, vertex order: ``_alone_edges``.
    Where most vertices are alone in their cell, only the cells of several vertices are reduced."""
    size = order.size
    counts = np.diff(starts, append=size)
    several = counts > 1
    n_several = size - starts.size + int(np.count_nonzero(several))
    if 2 * n_several > size:
        if fields is None:
            fields = _sorted_fields(order, *source)
        return np.repeat(_edge_runs(starts, counts, fields, cos_half), counts)
    edge = np.take(alone, np.take(order, starts))
    if n_several:
        rows = np.flatnonzero(np.repeat(several, counts))
        sub_counts = counts[several]
        sub_starts = np.cumsum(sub_counts) - sub_counts
        sub = _sorted_fields(np.take(order, rows), *source) if fields is None else _take_fields(fields, rows)
        edge[several] = _edge_runs(sub_starts, sub_counts, sub, cos_half)
    return np.repeat(edge, counts)


def _run_starts(sorted_keys: np.ndarray) -> np.ndarray:
    """First index of every run of equal values in a sorted (N,) array."""
    return np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])


def _radix_argsort(key: np.ndarray, bits: int) -> np.ndarray:
    """``np.argsort(key, kind="stable")`` for a 1-D integer ``key`` in [0, 2^bits): one stable sort
    per digit of at most 16 bits, the least significant first (numpy radix-sorts 8- and 16-bit
    integers)."""
    passes = max(1, -(-bits // 16))
    width = -(-bits // passes)
    order = None
    for p in range(passes):
        k = key if order is None else np.take(key, order)
        if p:
            k = k >> (p * width)
        if p < passes - 1:
            k = k & ((1 << width) - 1)
        o = np.argsort(k.astype(np.uint8 if width <= 8 else np.uint16), kind="stable")
        order = o if order is None else np.take(order, o)
    return order


def _cell_runs(c: np.ndarray, bits: int) -> tuple[np.ndarray, np.ndarray]:
    """(order, starts) grouping the rows of ``c`` (N, 3) cell integers of ``bits`` bits: ``order``
    sorts equal rows together (stable: vertex order within a cell), ``starts`` is the first sorted
    index of every cell. Morton order where the code fits 63 bits, else lexicographic."""
    if bits <= 21:
        order, key_sorted = stable_argsort(_morton(c))
        return order, _run_starts(key_sorted)
    order = stable_lexsort((c[:, 2], c[:, 1], c[:, 0]))
    s = c[order]
    return order, np.flatnonzero(np.r_[True, np.any(s[1:] != s[:-1], axis=1)])


def _lattice_runs(q: np.ndarray, cols: list | None, lo: list, hi: list, shift: int,
                  offset: int) -> tuple[np.ndarray, np.ndarray]:
    """(order, starts) grouping the rows of ``q`` (N, 3) by their cell ``(q + offset) >> shift``, as
    ``_cell_runs`` does (vertex order within a cell; the order of the cells differs, which no
    per-cell result depends on). ``cols``: the columns of ``q`` as int32, None where ``q`` is off
    the grid (``_cell_runs`` itself groups those); ``lo``, ``hi``: their bounds. The key is the
    cell's row-major index in the cells' bounding box, sorted by ``_radix_argsort``."""
    c_lo = [(a + offset) >> shift for a in lo]
    ext = [((b + offset) >> shift) - a + 1 for a, b in zip(c_lo, hi)]
    span = ext[0] * ext[1] * ext[2]
    if cols is None or span > 1 << 62:
        return _cell_runs((q + offset) >> shift, BITS + int(offset > 0) - shift)
    wide = span > (1 << 31) - 1
    key = None
    for ax in range(3):
        c = cols[ax] + offset if offset else cols[ax].copy()
        c >>= shift
        c -= c_lo[ax]
        if key is None:
            key = c.astype(np.int64) if wide else c
        else:
            key *= ext[ax]
            key += c
    order = _radix_argsort(key, max(1, (span - 1).bit_length()))
    return order, _run_starts(np.take(key, order))


def fold_levels(q: np.ndarray, normals: np.ndarray, has_normal: np.ndarray, boundary: np.ndarray, top: int,
                angle_deg: float) -> np.ndarray:
    """(N,) int64 B_v of folds (module doc): the highest level in [max(1, top - FOLD_LEVEL_SPAN), top]
    at which the vertex's one-pixel cell (either lattice) holds an edge; 0 when none does.

    q (N, 3) grid integers, normals (N, 3) unit, has_normal (N,) bool, boundary (N,) bool.

    Cells are grouped by sorting: the unshifted lattices of all levels share one sort by the Morton
    code of the finest one (a coarser cell is a run of finer ones); each shifted lattice sorts its
    own cells (a radix sort of the cell's index in their bounding box). A cell's vertices are
    reduced in that order: the Morton order of the finest cells in the unshifted lattices, vertex
    order in the shifted ones. Per cell: the mean normal (``np.add.reduceat``), whether a dot
    product with it is below the cosine of half the angle and whether a boundary vertex is inside.
    A vertex alone in its cell has its own result, computed once for all lattices."""
    n = q.shape[0]
    out = np.zeros(n, dtype=np.int64)
    if n == 0:
        return out
    q = np.asarray(q, dtype=np.int64)
    normals = np.ascontiguousarray(normals, dtype=np.float64)
    has_normal = np.asarray(has_normal, dtype=bool)
    boundary = np.asarray(boundary, dtype=bool)
    source = (normals, None if has_normal.all() else has_normal, boundary)
    cos_half = math.cos(math.radians(float(angle_deg)) / 2.0)
    levels = list(range(int(top), max(1, int(top) - FOLD_LEVEL_SPAN) - 1, -1))
    finest = _cell_shift(levels[0])  # the finest cells: the highest level
    morton_ok = BITS - finest <= 21
    if morton_ok:
        order0, code_sorted = stable_argsort(_morton(q >> finest))
        fields0 = _sorted_fields(order0, *source)
    lo, hi = [int(v) for v in q.min(axis=0)], [int(v) for v in q.max(axis=0)]
    on_grid = min(lo) >= 0 and max(hi) < 1 << BITS  # then q + 2^23 fits int32
    cols = [np.ascontiguousarray(q[:, ax], dtype=np.int32) for ax in range(3)] if on_grid else None
    alone = _alone_edges(_Fields(normals if source[1] is None else normals * has_normal[:, None], normals,
                                 source[1], boundary), cos_half)
    pending = np.ones(n, dtype=bool)
    hit = np.empty(n, dtype=bool)
    shifted = np.empty(n, dtype=bool)
    for level in levels:
        shift = _cell_shift(level)
        if morton_ok:
            order, starts, fields = order0, _run_starts(code_sorted >> (3 * (shift - finest))), fields0
        else:
            (order, starts), fields = _lattice_runs(q, cols, lo, hi, shift, 0), None
        hit[order] = _lattice_edges(order, starts, fields, source, alone, cos_half)
        if shift > 0:  # the lattice moved by half a cell
            order, starts = _lattice_runs(q, cols, lo, hi, shift, 1 << (shift - 1))
            shifted[order] = _lattice_edges(order, starts, None, source, alone, cos_half)
            hit |= shifted
        hit &= pending
        out[hit] = level
        pending ^= hit
        if not pending.any():
            break
    return out


def required_level(fold_or_top: np.ndarray, jump: np.ndarray, edge_eps: float) -> np.ndarray:
    """(N,) int64: ``B_v + ceil(log2(PIXEL_ERROR * J_v / edge_eps))`` clamped to [1, 24]; 1 where
    B_v == 0, J_v == 0 or the logarithm is <= 0 (no constraint)."""
    b = np.asarray(fold_or_top, dtype=np.int64)
    j = np.asarray(jump, dtype=np.float64)
    ratio = PIXEL_ERROR * j / float(edge_eps)
    with np.errstate(divide="ignore"):
        extra = np.ceil(np.log2(np.where(ratio > 0, ratio, 1.0)) - 1e-9).astype(np.int64)
    level = np.where((b > 0) & (extra > 0), b + extra, 1)
    return np.clip(level, 1, BITS)


def discontinuity_levels(parts, quantized, *, edge_eps: float, edge_level: int, edge_angle_deg: float,
                         texture_cache: dict | None = None) -> Discontinuity:
    """The discontinuity constraint of every vertex of every part (module doc).

    Parameters
    ----------
    parts : list of MeshPart (positions, indices, normals, uvs, colors, texture)
    quantized : list of (n_k, 3) uint32 24-bit grid integers, parallel to ``parts``
    edge_eps : colour units (0, 1]: the largest change of a pixel an edge may cause at ``edge_level``
    edge_level : int in [1, 24], the highest per-buffer level the bound is kept at (B_v <= it)
    edge_angle_deg : degrees (0, 180]: normal spread in a one-pixel cell that makes a fold
    """
    sizes = [p.n_vertices for p in parts]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    if offsets[-1] == 0:
        empty = [np.zeros(s, dtype=np.int64) for s in sizes]
        return Discontinuity(empty, [np.zeros(s) for s in sizes], empty, [np.zeros(s, bool) for s in sizes],
                             [np.zeros(s, bool) for s in sizes])
    # (1) co-located groups and the welded mesh's open boundary
    q = np.concatenate([np.asarray(x, dtype=np.int64).reshape(-1, 3) for x in quantized])
    groups = colocated_groups(q)
    tris = np.concatenate([np.asarray(p.indices, dtype=np.int64).reshape(-1, 3) + offsets[k]
                           for k, p in enumerate(parts)])
    boundary = boundary_vertices(groups, tris)
    # (2) folds: one-pixel cells holding a normal spread or a boundary
    normals = np.concatenate([np.zeros((p.n_vertices, 3)) if p.normals is None
                              else np.asarray(p.normals, dtype=np.float64) for p in parts])
    has_normal = np.concatenate([np.full(p.n_vertices, p.normals is not None) for p in parts])
    fold = fold_levels(q, normals, has_normal, boundary, edge_level, edge_angle_deg)
    fold_level = required_level(fold, np.ones(q.shape[0]), edge_eps)
    # (3) seams: co-located vertices with different base colours
    jump = seam_jumps(groups, base_colours(parts, texture_cache))
    seam = jump > 0
    seam_level = required_level(np.where(seam, int(edge_level), 0), jump, edge_eps)
    level = np.maximum(fold_level, seam_level)
    jump_all = np.where(fold > 0, 1.0, jump)

    def split(a):
        return [a[offsets[k]:offsets[k + 1]] for k in range(len(parts))]

    return Discontinuity(split(level), split(jump_all), split(fold), split(boundary), split(seam))


__all__ = ["PIXEL_ERROR", "FOLD_LEVEL_SPAN", "Discontinuity", "colocated_groups", "boundary_vertices",
           "base_colours", "seam_jumps", "fold_levels", "required_level", "discontinuity_levels"]
