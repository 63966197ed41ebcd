"""Binned adaptive precision buffers: vertices sorted by minimum level, VertexId / BitId tables.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 5.3 (binned adaptive precision buffers) and Figures 9-10.

Vertices of one buffer (a part's LOD) are sorted stably by their minimum level ``m_v`` in [1, 24].
Bin k (level k) holds the vertices with ``m_v = k``. Tables, 25 entries each (index 0..24):

* ``VertexId[k]`` = number of vertices with ``m_v <= k``. Bin k spans vertices
  ``[VertexId[k-1], VertexId[k])``; ``VertexId[0] = 0``, ``VertexId[24] = n``. An empty bin has
  ``VertexId[k-1] == VertexId[k]``.
* At per-buffer level ``B`` every vertex of bin k stores ``b_k = max(k, B)`` bits per component,
  3 components (x, y, z) one after the other. ``BitId[k]`` = bit offset of the first vertex after
  bin k, i.e. bin k starts at ``BitId[k-1]``: ``BitId[k] = sum_{i<=k} 3 * b_i * |bin i|``.

The paper's random access then reads vertex j of bin b at bit offset
``3 * b_b * (j - VertexId[b-1]) + BitId[b-1]`` (``lopcook.lop.bitplane.decode``).
Memory of the GPU-resident buffer at level B: ``ceil(BitId[24] / 32)`` uint32 words.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEVELS = 24
FLOAT32_BYTES_PER_VERTEX = 12  # three float32 components


@dataclass(frozen=True)
class Bins:
    """order (n,) int64: new position -> original vertex; inverse (n,) int64: original -> new;
    levels (n,) uint8 sorted ascending; vertex_id (25,) int64 (see module doc)."""

    order: np.ndarray
    inverse: np.ndarray
    levels: np.ndarray
    vertex_id: np.ndarray

    @property
    def n(self) -> int:
        return int(self.order.size)

    def counts(self) -> np.ndarray:
        """(25,) vertices per bin (index = level, 0 unused)."""
        return np.diff(self.vertex_id, prepend=0)

    def remap_indices(self, indices: np.ndarray) -> np.ndarray:
        """(m, 3) triangle indices into original vertices -> indices into the binned order."""
        return self.inverse[np.asarray(indices, dtype=np.int64)].astype(np.uint32)


def make_bins(min_level: np.ndarray) -> Bins:
    """Stable sort of vertices by ``min_level`` ((n,) ints in [1, 24])."""
    lv = np.asarray(min_level, dtype=np.int64)
    if lv.size and (lv.min() < 1 or lv.max() > LEVELS):
        raise ValueError(f"minimum levels must be in [1, {LEVELS}], got [{lv.min()}, {lv.max()}]")
    order = np.argsort(lv, kind="stable")
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.size)
    vertex_id = table_vertex_id(lv)
    return Bins(order=order, inverse=inverse, levels=lv[order].astype(np.uint8), vertex_id=vertex_id)


def table_vertex_id(min_level: np.ndarray) -> np.ndarray:
    """(25,) int64: VertexId[k] = number of vertices with level <= k."""
    counts = np.bincount(np.asarray(min_level, dtype=np.int64), minlength=LEVELS + 1)[: LEVELS + 1]
    counts[0] = 0
    return np.cumsum(counts).astype(np.int64)


def bin_widths(level: int) -> np.ndarray:
    """(25,) bits per component of each bin at per-buffer level B: max(k, B); index 0 unused (0)."""
    k = np.arange(LEVELS + 1)
    w = np.maximum(k, int(level))
    w[0] = 0
    return w


def table_bit_id(vertex_id: np.ndarray, level: int) -> np.ndarray:
    """(25,) int64: BitId[k] = bit offset just after bin k at per-buffer level B (BitId[0] = 0)."""
    if not 1 <= int(level) <= LEVELS:
        raise ValueError(f"per-buffer level must be in [1, {LEVELS}], got {level}")
    counts = np.diff(np.asarray(vertex_id, dtype=np.int64), prepend=0)
    counts[0] = 0
    return np.cumsum(3 * bin_widths(level) * counts).astype(np.int64)


def vertex_widths(vertex_id: np.ndarray, level: int) -> np.ndarray:
    """(n,) bits per component of every vertex (binned order) at per-buffer level B."""
    counts = np.diff(np.asarray(vertex_id, dtype=np.int64), prepend=0)
    counts[0] = 0
    return np.repeat(bin_widths(level), counts)


def buffer_bits(vertex_id: np.ndarray, level: int) -> int:
    """Total bits of the packed buffer at per-buffer level B."""
    return int(table_bit_id(vertex_id, level)[LEVELS])


def buffer_bytes(vertex_id: np.ndarray, level: int) -> int:
    """Bytes of the GPU-resident packed buffer at level B (whole uint32 words)."""
    return 4 * ((buffer_bits(vertex_id, level) + 31) // 32)


def memory_table(vertex_id: np.ndarray, levels=range(1, LEVELS + 1)) -> list[dict]:
    """Bytes at each per-buffer level and as a percentage of float32 positions (12 bytes/vertex)."""
    n = int(vertex_id[LEVELS])
    rows = []
    for b in levels:
        nbytes = buffer_bytes(vertex_id, b)
        rows.append({"level": int(b), "bytes": nbytes,
                     "percent_of_float32": 100.0 * nbytes / max(FLOAT32_BYTES_PER_VERTEX * n, 1)})
    return rows
