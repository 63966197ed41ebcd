"""Pack, unpack and adapt binned adaptive precision buffers (the CPU reference decoder).

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 4, 5.3 and 6.1 (pack / unpack, add and remove bit planes, Figures 9-11).

Bit layout of a packed buffer ``P`` (what the shaders in ``shaders/`` read):

* ``P`` is an array of uint32 words (little-endian in files). Bit offset ``o`` of the buffer is
  bit ``o & 31`` (0 = least significant) of word ``o >> 5``.
* Vertices follow each other in binned order (``lopcook.lop.binning``). Vertex j of bin k stores
  ``b = max(k, B)`` bits per component at offset ``o_j = 3*b*(j - VertexId[k-1]) + BitId[k-1]``:
  component x at ``o_j``, y at ``o_j + b``, z at ``o_j + 2b``.
* A component's field holds ``v = q >> (24 - b)``, the top b bits of its 24-bit grid integer q,
  least significant bit first (so the field is read as ``(P[w] >> s | P[w+1] << (32 - s)) & mask``,
  never spanning more than two words since b <= 24).
* Unused bits at the end of the last word are zero.

``pack`` writes this layout from per-vertex values as one bit stream (independent code path);
``decode`` reads it back with the paper's formula, vertex by vertex (vectorised): it is the
reference the GLSL/HLSL decoders mirror.
"""

from __future__ import annotations

import numpy as np

from .binning import LEVELS, bin_widths, table_bit_id, vertex_widths


def top_bits(q: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """(n, 3) uint32 24-bit grid integers, (n,) bits per component -> (n, 3) uint32 top bits."""
    s = (LEVELS - np.asarray(widths, dtype=np.int64))[:, None]
    return (np.asarray(q, dtype=np.int64) >> s).astype(np.uint32)


def pack(values: np.ndarray, vertex_id: np.ndarray, level: int) -> np.ndarray:
    """Pack per-vertex top-bit values into words at per-buffer level B.

    Parameters
    ----------
    values : (n, 3) uint32, binned order; vertex j holds max(k, B) significant bits per component
    vertex_id : (25,) VertexId table
    level : per-buffer level B in [1, 24]

    Returns
    -------
    (ceil(bits / 32),) uint32 words.
    """
    values = np.asarray(values, dtype=np.uint32)
    widths_by_bin = bin_widths(level)
    segments = []
    for k in range(1, LEVELS + 1):  # at most 24 groups of equal width; vectorised inside
        lo, hi = int(vertex_id[k - 1]), int(vertex_id[k])
        if hi == lo:
            continue
        w = int(widths_by_bin[k])
        v = values[lo:hi]
        if np.any(v >> np.uint32(w)):
            raise ValueError(f"bin {k}: values exceed {w} bits")
        bits = ((v[:, :, None] >> np.arange(w, dtype=np.uint32)) & 1).astype(np.uint8)  # (g, 3, w)
        segments.append(bits.ravel())
    stream = np.concatenate(segments) if segments else np.zeros(0, np.uint8)
    total = int(table_bit_id(vertex_id, level)[LEVELS])
    assert stream.size == total
    nwords = (total + 31) // 32
    padded = np.zeros(nwords * 32, dtype=np.uint8)
    padded[:total] = stream
    return np.packbits(padded, bitorder="little").view("<u4").astype(np.uint32)


def read_fields(words: np.ndarray, offsets: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """Read fields of ``widths`` bits (<= 32) starting at bit ``offsets`` (both (k,) int64)."""
    w = np.asarray(words, dtype=np.uint64)
    w = np.concatenate([w, np.zeros(1, np.uint64)])  # a field may end in the last word
    offsets = np.asarray(offsets, dtype=np.int64)
    idx = offsets >> 5
    shift = (offsets & 31).astype(np.uint64)
    both = w[idx] | (w[np.minimum(idx + 1, w.size - 1)] << np.uint64(32))
    mask = (np.uint64(1) << np.asarray(widths, dtype=np.uint64)) - np.uint64(1)
    return ((both >> shift) & mask).astype(np.uint32)


def decode(words: np.ndarray, vertex_id: np.ndarray, bit_id: np.ndarray, level: int,
           vertices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The paper's random access: vertex j of bin b is read at 3*b*(j - VertexId[b-1]) + BitId[b-1].

    Parameters
    ----------
    words : (w,) uint32 packed buffer P at per-buffer level B
    vertex_id, bit_id : (25,) tables (bit_id for level B)
    level : B
    vertices : (k,) indices j to decode (default all)

    Returns
    -------
    values : (k, 3) uint32 top bits of each component
    widths : (k,) int64 bits per component (max(bin, B))
    """
    vertex_id = np.asarray(vertex_id, dtype=np.int64)
    n = int(vertex_id[LEVELS])
    j = np.arange(n, dtype=np.int64) if vertices is None else np.asarray(vertices, dtype=np.int64)
    # bin of vertex j: the k with VertexId[k-1] <= j < VertexId[k]  (the shader's binary search)
    k = np.searchsorted(vertex_id, j, side="right")
    b = np.maximum(k, int(level))
    base = 3 * b * (j - vertex_id[k - 1]) + np.asarray(bit_id, dtype=np.int64)[k - 1]
    comps = [read_fields(words, base + c * b, b) for c in range(3)]
    return np.stack(comps, axis=1), b


def to_grid(values: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """Top-bit values -> (n, 3) uint32 24-bit integers with the dropped bits zero (v << (24 - b))."""
    s = (LEVELS - np.asarray(widths, dtype=np.int64))[:, None]
    return (np.asarray(values, dtype=np.int64) << s).astype(np.uint32)


def reconstruct_float32(values: np.ndarray, widths: np.ndarray, origin, cell: float) -> np.ndarray:
    """Float32 positions exactly as the shaders compute them (metres).

    ``c = ((2 v + 1) << (24 - b))`` is the block centre in half cells (an integer < 2^25);
    ``p = origin + float(c) * (cell / 2)``, each operation rounded to float32 (no fused
    multiply-add). ``origin`` and ``cell / 2`` are first rounded to float32. The float64 value of the
    same centre lies within dx(b) of the source position; the float32 result adds at most the
    float32 rounding of the conversion, product and sum (documented in docs/format.md).
    """
    s = (LEVELS - np.asarray(widths, dtype=np.int64))[:, None]
    c = ((2 * np.asarray(values, dtype=np.int64) + 1) << s).astype(np.uint32)
    half = np.float32(cell / 2.0)
    return (np.asarray(origin, dtype=np.float32) + c.astype(np.float32) * half).astype(np.float32)


def reconstruct_float64(values: np.ndarray, widths: np.ndarray, origin, cell: float) -> np.ndarray:
    """(n, 3) float64 block centres in metres (within dx(b) of the source)."""
    s = (LEVELS - np.asarray(widths, dtype=np.int64))[:, None]
    c = (2 * np.asarray(values, dtype=np.int64) + 1) << s
    return np.asarray(origin, dtype=np.float64) + c.astype(np.float64) * (cell / 2.0)


def add_plane(words: np.ndarray, vertex_id: np.ndarray, level: int, plane: np.ndarray) -> np.ndarray:
    """Per-buffer level B -> B + 1: merge one uploaded bit plane (paper section 6.1, Fig. 10c).

    ``plane`` is (VertexId[B], 3) uint8: the next bit (bit 24 - (B + 1) of q) of x, y, z for every
    vertex of bins k <= B, the only vertices that gain a bit. Returns the words at level B + 1."""
    if not 1 <= level < LEVELS:
        raise ValueError(f"cannot add a plane above level {level}")
    values, _ = decode(words, vertex_id, table_bit_id(vertex_id, level), level)
    grow = int(vertex_id[level])
    plane = np.asarray(plane, dtype=np.uint32).reshape(grow, 3)
    values[:grow] = (values[:grow] << np.uint32(1)) | plane
    return pack(values, vertex_id, level + 1)


def remove_plane(words: np.ndarray, vertex_id: np.ndarray, level: int) -> np.ndarray:
    """Per-buffer level B -> B - 1: drop the lowest bit of every vertex of bins k <= B - 1
    (bins at their minimum level keep all their bits; paper Fig. 10b). Returns the words."""
    if not 1 < level <= LEVELS:
        raise ValueError(f"cannot remove a plane below level {level}")
    values, _ = decode(words, vertex_id, table_bit_id(vertex_id, level), level)
    shrink = int(vertex_id[level - 1])
    values[:shrink] >>= np.uint32(1)
    return pack(values, vertex_id, level - 1)


def plane_bits(q: np.ndarray, vertex_id: np.ndarray, plane: int) -> np.ndarray:
    """Refinement plane p (2..24) of a buffer: (VertexId[p-1], 3) uint8 bit (24 - p) of x, y, z of the
    vertices whose minimum level is below p (the only vertices whose mandatory bits lack it)."""
    count = int(vertex_id[plane - 1])
    return ((np.asarray(q[:count], dtype=np.uint32) >> np.uint32(LEVELS - plane)) & 1).astype(np.uint8)


def buffer_from_planes(mandatory: np.ndarray, planes: list[np.ndarray], vertex_id: np.ndarray) -> np.ndarray:
    """Rebuild P at level B = 1 + len(planes) from the mandatory words (P at level 1) and planes 2..B."""
    words = np.asarray(mandatory, dtype=np.uint32)
    for i, plane in enumerate(planes):
        words = add_plane(words, vertex_id, 1 + i, plane)
    return words


__all__ = ["pack", "decode", "read_fields", "top_bits", "to_grid", "reconstruct_float32",
           "reconstruct_float64", "add_plane", "remove_plane", "plane_bits", "buffer_from_planes",
           "vertex_widths"]
