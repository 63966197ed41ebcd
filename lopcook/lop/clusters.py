"""Clustered position buffers: per-cluster anchors store the top bits that a cluster's vertices share once.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 5.3 (binned adaptive precision buffers, VertexId/BitId random access) and section 6.1
(adding and removing bit planes). The anchors: spatially close vertices share the top bits of
their grid coordinates; Nanite, AMD's Dense Geometry Format and meshoptimizer's
shared cluster exponent store those bits once per cluster. Here every vertex keeps its own
adaptive level (its bin) and the decode stays exactly the global grid's decode, so no crack opens
between clusters, parts or LODs.

Layout (the contract with the shaders, docs/format.md section 6.6):

* Order: vertices sorted by (m_v ascending, Morton code ascending, original index). The Morton
  code interleaves the top 21 bits of the 24-bit grid integers q (x in the lowest bit of each
  triple). Bins and ``VertexId[0..24]`` keep their meaning (``lopcook.lop.binning``).
* Clusters: bin k's vertices ``[VertexId[k-1], VertexId[k])`` are cut into runs of N (the last
  run of a bin may be shorter); a cluster never spans two bins, so its vertices share m. The
  table ``ClusterId[0..24]`` counts the clusters in bins <= k. Vertex j of bin k is in cluster
  ``c = ClusterId[k-1] + (j - VertexId[k-1]) // N`` at local index ``l = (j - VertexId[k-1]) % N``.
* Anchor: per cluster and component t, ``k_t`` = length of the longest common prefix of the
  cluster's 24-bit q_t in [0, 24], ``a_t = q_t >> (24 - k_t)``.
* Packed buffer P at per-buffer level B: ``b = max(m, B)``, stored widths ``w_t = max(0, b - k_t)``,
  stride ``s_c = w_x + w_y + w_z``; vertex j at ``ClusterBit[c] + l * s_c``, x then y then z,
  least significant bit first. ``ClusterBit[c] = sum_{c' < c} count_c' * s_c'``. Decoded top b bits:
  ``a_t >> (k_t - b)`` if ``b <= k_t`` else ``(a_t << (b - k_t)) | field_t``: exactly
  ``q_t >> (24 - b)``, the unclustered (global grid) value at max(B, m_v) bits.
* Cluster records (GPU resident, 4 uint32 per cluster): ``a_t | k_t << 24`` for x, y, z, then
  ``ClusterBit[c]`` at the current level.
* Refinement plane p: for every cluster with m_c < p, in order, for every vertex, for every
  component with ``k_t < p``: bit (24 - p) of q_t (components the anchor implies are skipped).

Every function is vectorised over vertices and clusters (loops run over at most 24 bins or bit
positions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .binning import LEVELS, Bins, table_vertex_id
from .bitplane import read_fields

MIN_CLUSTER_SIZE = 16
MAX_CLUSTER_SIZE = 1024
MORTON_BITS = 21  # top bits of each 24-bit component that enter the Morton code (63 bits in all)
RECORD_WORDS = 4  # uint32 words per cluster record on the GPU
HEADER_WORDS = 3  # of which the file stores the first 3 (the anchors); word 3 is recomputed
CLUSTER_ID_BYTES = 128  # the ClusterId table in the per-buffer uniform block (uvec4[8])


@dataclass(frozen=True)
class Clusters:
    """The clusters of one buffer (a part's LOD), vertices in cluster order.

    size : N, vertices per cluster (the last cluster of a bin may hold fewer)
    vertex_id : (25,) int64 VertexId table
    cluster_id : (25,) int64 ClusterId table (ClusterId[k] = clusters in bins <= k, [0] = 0)
    k : (n_c, 3) uint8 common-prefix bits per component, in [0, 24]
    anchor : (n_c, 3) uint32 anchors, ``a_t < 2^k_t``
    count : (n_c,) int64 vertices per cluster
    m : (n_c,) int64 bin level of each cluster (its vertices' minimum level)
    start : (n_c,) int64 first vertex of each cluster
    """

    size: int
    vertex_id: np.ndarray
    cluster_id: np.ndarray
    k: np.ndarray
    anchor: np.ndarray
    count: np.ndarray
    m: np.ndarray
    start: np.ndarray

    @property
    def n_clusters(self) -> int:
        return int(self.count.size)

    @property
    def n(self) -> int:
        return int(self.vertex_id[LEVELS])

    def header_words(self) -> np.ndarray:
        """(n_c * 3,) uint32: words 0-2 of every record (``a_t | k_t << 24``), as the file stores them."""
        return (self.anchor.astype(np.uint32) | (self.k.astype(np.uint32) << np.uint32(24))).ravel()


def check_size(size: int) -> int:
    """N as an int, or ValueError unless it is an integer in [16, 1024]."""
    if isinstance(size, bool) or int(size) != size or not MIN_CLUSTER_SIZE <= int(size) <= MAX_CLUSTER_SIZE:
        raise ValueError(f"cluster size must be an integer in [{MIN_CLUSTER_SIZE}, {MAX_CLUSTER_SIZE}], got {size!r}")
    return int(size)


def _spread3(v: np.ndarray) -> np.ndarray:
    """(n,) uint64 values < 2^21 -> their bits at positions 0, 3, 6, ... (the Morton spread)."""
    x = v.astype(np.uint64) & np.uint64(0x1FFFFF)
    x = (x | (x << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x1249249249249249)
    return x


def morton_codes(q: np.ndarray) -> np.ndarray:
    """(n, 3) uint32 24-bit grid integers -> (n,) uint64 Morton codes of their top 21 bits (x lowest)."""
    top = np.asarray(q, dtype=np.uint64).reshape(-1, 3) >> np.uint64(LEVELS - MORTON_BITS)
    return _spread3(top[:, 0]) | (_spread3(top[:, 1]) << np.uint64(1)) | (_spread3(top[:, 2]) << np.uint64(2))


def cluster_order(q: np.ndarray, min_level: np.ndarray, codes: np.ndarray | None = None) -> Bins:
    """The cluster order of a buffer as ``Bins``: sorted by (m_v, Morton code, original index).

    q : (n, 3) uint32 grid integers (original order); min_level : (n,) ints in [1, 24];
    codes : their ``morton_codes`` when already computed (the same order either way).
    ``order``/``inverse``/``levels``/``vertex_id`` mean what they mean for ``binning.make_bins``."""
    lv = np.asarray(min_level, dtype=np.int64)
    if lv.size and (lv.min() < 1 or lv.max() > LEVELS):
        raise ValueError(f"minimum levels must be in [1, {LEVELS}], got [{lv.min()}, {lv.max()}]")
    codes = morton_codes(q) if codes is None else codes
    order = np.lexsort((np.arange(lv.size), codes, lv)).astype(np.int64)
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.size)
    return Bins(order=order, inverse=inverse, levels=lv[order].astype(np.uint8), vertex_id=table_vertex_id(lv))


def _bit_length(x: np.ndarray) -> np.ndarray:
    """(...) non-negative integers < 2^53 -> their bit lengths (0 for 0), int64."""
    return np.frexp(np.asarray(x, dtype=np.float64))[1].astype(np.int64)


def _shape(vertex_id: np.ndarray, size: int):
    """(N, VertexId, ClusterId, m, start, count) of the clusters of a buffer's bins (no grid data)."""
    size = check_size(size)
    vid = np.asarray(vertex_id, dtype=np.int64)
    counts = np.diff(vid, prepend=0)
    counts[0] = 0
    per_bin = -(-counts // size)  # clusters per bin
    cid = np.cumsum(per_bin).astype(np.int64)
    m = np.repeat(np.arange(LEVELS + 1, dtype=np.int64), per_bin)
    first = cid[m - 1]
    start = vid[m - 1] + (np.arange(m.size, dtype=np.int64) - first) * size
    count = np.minimum(size, vid[m] - start)
    return size, vid, cid, m, start.astype(np.int64), count.astype(np.int64)


def make_clusters(q_binned: np.ndarray, vertex_id: np.ndarray, size: int) -> Clusters:
    """Cut a buffer in cluster order into clusters of ``size`` vertices and compute their anchors.

    q_binned : (n, 3) uint32 grid integers in cluster (or any binned) order; vertex_id : (25,)."""
    size, vid, cid, m, start, count = _shape(vertex_id, size)
    n_c = int(cid[LEVELS])
    q = np.asarray(q_binned, dtype=np.int64).reshape(-1, 3)
    if q.shape[0] != int(vid[LEVELS]):
        raise ValueError(f"{q.shape[0]} grid integers for {int(vid[LEVELS])} vertices")
    if n_c:
        lo = np.minimum.reduceat(q, start, axis=0)
        hi = np.maximum.reduceat(q, start, axis=0)
        k = LEVELS - _bit_length(lo ^ hi)  # the common prefix of all = that of the smallest and largest
        anchor = lo >> (LEVELS - k)
    else:
        k = np.zeros((0, 3), np.int64)
        anchor = np.zeros((0, 3), np.int64)
    return Clusters(size=size, vertex_id=vid, cluster_id=cid, k=k.astype(np.uint8), anchor=anchor.astype(np.uint32),
                    count=count.astype(np.int64), m=m, start=start.astype(np.int64))


def vertex_clusters(clusters: Clusters, vertices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(bin k, cluster c, local index l) of vertices j (default all), each (k,) int64: the random
    access of the module doc (a binary search in VertexId, then one division)."""
    vid = clusters.vertex_id
    j = np.arange(clusters.n, dtype=np.int64) if vertices is None else np.asarray(vertices, dtype=np.int64)
    k = np.searchsorted(vid, j, side="right")
    rel = j - vid[k - 1]
    return k, clusters.cluster_id[k - 1] + rel // clusters.size, rel % clusters.size


def stored_widths(clusters: Clusters, level: int) -> np.ndarray:
    """(n_c, 3) int64 stored bits per component ``w_t = max(0, max(m_c, B) - k_t)`` at level B."""
    b = np.maximum(clusters.m, int(level))[:, None]
    return np.maximum(0, b - clusters.k.astype(np.int64))


def cluster_bit(clusters: Clusters, level: int) -> np.ndarray:
    """(n_c + 1,) int64 ClusterBit at per-buffer level B: bit offset of each cluster in P; the last
    entry is P's total bits."""
    _check_level(level)
    bits = clusters.count * stored_widths(clusters, level).sum(axis=1)
    return np.concatenate([np.zeros(1, np.int64), np.cumsum(bits)]).astype(np.int64)


def words_at(clusters: Clusters, level: int) -> int:
    """uint32 words of P at level B: ``ceil(bits / 32)``, at least 1."""
    return max(1, (int(cluster_bit(clusters, level)[-1]) + 31) // 32)


#: vertices per block of ``pack_clustered`` (its temporaries are a few int64 arrays of this many rows)
PACK_BLOCK = 1 << 18


def pack_clustered(values: np.ndarray, clusters: Clusters, level: int) -> np.ndarray:
    """Pack per-vertex top-bit values into the clustered layout at per-buffer level B.

    values : (n, 3) uint32, cluster order, vertex j holding max(m_v, B) significant bits per
    component (``bitplane.top_bits(q, vertex_widths(vertex_id, B))``). Raises ValueError when a
    value exceeds its bits or disagrees with its cluster's anchor. Returns (words_at(B),) uint32.

    An independent code path from ``decode_clustered``: one bit stream built from the running sum
    of every field's width (vertex after vertex, x, y, z), not from ClusterBit."""
    _check_level(level)
    values = np.asarray(values).reshape(-1, 3)
    n = clusters.n
    if values.shape[0] != n:
        raise ValueError(f"{values.shape[0]} values for {n} vertices")
    # a block of vertices at a time (temporaries of PACK_BLOCK rows: the whole buffer's (n, 3)
    # int64 arrays were the encode's peak); each block's words are summed into the whole stream
    # at its first word, so the words are those of one pass over all vertices
    pieces = []
    total = 0
    for s in range(0, n, PACK_BLOCK):
        rows = np.arange(s, min(n, s + PACK_BLOCK), dtype=np.int64)
        v = values[s:s + rows.size].astype(np.int64)
        kv = np.searchsorted(clusters.vertex_id, rows, side="right")  # bin of each vertex
        b = np.maximum(kv, int(level))[:, None]
        c = np.searchsorted(clusters.start, rows, side="right") - 1  # cluster of each vertex
        kt = clusters.k[c].astype(np.int64)
        at = clusters.anchor[c].astype(np.int64)
        del kv, c
        if np.any(v >> b):
            raise ValueError(f"values exceed max(m_v, {level}) bits")
        w = np.maximum(0, b - kt)
        if np.any((v >> w) != np.where(b <= kt, at >> np.maximum(kt - b, 0), at)):  # the bits the anchor holds
            raise ValueError("values disagree with their cluster's anchor")
        del b, kt, at
        fields = (v & ((np.int64(1) << w) - 1)).ravel()
        widths = w.ravel()
        del v, w
        offsets = np.cumsum(widths)
        offsets += total - widths
        total += int(widths.sum())
        # a field (at most 24 bits) at bit offset o lands in word o // 32 and, past its end, in the
        # next one. The fields' bits are disjoint, so a word is the sum of its pieces: each piece is
        # below 2^32, and so is each word's sum, which float64 sums exactly.
        shifted = fields.astype(np.uint64) << (offsets & 31).astype(np.uint64)
        word = offsets >> 5
        first = int(word[0]) if word.size else 0
        word -= first
        span = int(word[-1]) + 2 if word.size else 0
        low = np.bincount(word, weights=(shifted & np.uint64(0xFFFFFFFF)).astype(np.float64), minlength=span)
        low += np.bincount(word + 1, weights=(shifted >> np.uint64(32)).astype(np.float64), minlength=span)
        pieces.append((first, low))
    n_words = max(1, (total + 31) // 32)
    # (an empty field at the very end may sit one word past the last: it adds 0 there)
    out = np.zeros(n_words + 2, dtype=np.float64)
    for first, low in pieces:
        out[first:first + low.size] += low
    return out[:n_words].astype(np.uint32)


def decode_clustered(words: np.ndarray, clusters: Clusters, level: int,
                     vertices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Random access into a clustered P at level B (what the shaders mirror).

    words : P at level B; vertices : (k,) indices j (default all). Returns (values (k, 3) uint32
    top max(B, m_v) bits, widths (k,) int64 max(B, m_v)): the same as ``bitplane.decode`` of the
    unclustered buffer of the same vertices."""
    _check_level(level)
    k, c, l = vertex_clusters(clusters, vertices)
    b = np.maximum(k, int(level))
    kt = clusters.k[c].astype(np.int64)
    at = clusters.anchor[c].astype(np.int64)
    w = np.maximum(0, b[:, None] - kt)
    base = cluster_bit(clusters, level)[c] + l * w.sum(axis=1)
    out = np.empty((b.size, 3), dtype=np.int64)
    off = base
    for t in range(3):
        field = read_fields(words, off, w[:, t]).astype(np.int64)
        off = off + w[:, t]
        below = b <= kt[:, t]
        out[:, t] = np.where(below, at[:, t] >> np.maximum(kt[:, t] - b, 0),
                             (at[:, t] << np.maximum(b - kt[:, t], 0)) | field)
    return out.astype(np.uint32), b


def records(clusters: Clusters, level: int) -> np.ndarray:
    """(n_c, 4) uint32 GPU cluster records at level B: ``a_t | k_t << 24`` (x, y, z), ClusterBit[c]."""
    cb = cluster_bit(clusters, level)[:-1]
    if cb.size and int(cb.max()) > 0xFFFFFFFF:
        raise ValueError("cluster bit offsets exceed 32 bits (a buffer over 4 Gbit)")
    out = np.empty((clusters.n_clusters, RECORD_WORDS), dtype=np.uint32)
    out[:, :3] = clusters.header_words().reshape(-1, 3)
    out[:, 3] = cb.astype(np.uint32)
    return out


def from_header(header: np.ndarray, vertex_id: np.ndarray, size: int) -> Clusters:
    """The Clusters of a buffer from its stored header words (n_c * 3 uint32, ``header_words``) and
    its VertexId table. Raises ValueError when the words do not fit the table (wrong count,
    k > 24, an anchor wider than k bits)."""
    size, vid, cid, m, start, count = _shape(vertex_id, size)
    h = np.asarray(header, dtype=np.uint32)
    if h.size != HEADER_WORDS * m.size:
        raise ValueError(f"{h.size} cluster header words, expected {HEADER_WORDS * m.size}")
    h = h.reshape(-1, 3)
    k = (h >> np.uint32(24)).astype(np.int64)
    a = (h & np.uint32(0xFFFFFF)).astype(np.int64)
    if np.any(k > LEVELS) or np.any(a >> np.minimum(k, LEVELS)):
        raise ValueError("a cluster header has k > 24 or an anchor wider than k bits")
    return Clusters(size=size, vertex_id=vid, cluster_id=cid, k=k.astype(np.uint8), anchor=a.astype(np.uint32),
                    count=count, m=m, start=start)


def plane_bit(clusters: Clusters, plane: int) -> np.ndarray:
    """(n_c + 1,) int64 PlaneBit_p: bit offset of each cluster inside the buffer's slice of
    refinement plane p (clusters with m_c >= p contribute nothing); the last entry is the slice's bits."""
    active = (clusters.m < int(plane)) * (clusters.k.astype(np.int64) < int(plane)).sum(axis=1)
    return np.concatenate([np.zeros(1, np.int64), np.cumsum(clusters.count * active)]).astype(np.int64)


def plane_bits_clustered(q: np.ndarray, clusters: Clusters, plane: int) -> np.ndarray:
    """Refinement plane p (2..24) of a clustered buffer as a 0/1 uint8 stream: for the vertices of
    clusters with m_c < p (the first VertexId[p-1]), in order, bit (24 - p) of each component
    with k_t < p (``plane_bit(clusters, p)[-1]`` bits)."""
    g = int(clusters.vertex_id[int(plane) - 1])
    _, c, _ = vertex_clusters(clusters, np.arange(g, dtype=np.int64))
    keep = clusters.k[c].astype(np.int64) < int(plane)
    bits = (np.asarray(q[:g], dtype=np.uint32).reshape(-1, 3) >> np.uint32(LEVELS - int(plane))) & 1
    return bits[keep].astype(np.uint8)


def add_plane_clustered(words: np.ndarray, clusters: Clusters, level: int, plane: np.ndarray) -> np.ndarray:
    """Per-buffer level B -> B + 1 (paper section 6.1, clustered): ``plane`` is the stream of
    ``plane_bits_clustered(q, clusters, B + 1)``; components the anchor implies take their bit
    from the anchor. Returns P at level B + 1 (the CPU reference of the GPU kernel)."""
    if not 1 <= level < LEVELS:
        raise ValueError(f"cannot add a plane above level {level}")
    p = level + 1
    values, _ = decode_clustered(words, clusters, level)
    v = values.astype(np.int64)
    g = int(clusters.vertex_id[level])
    _, c, _ = vertex_clusters(clusters, np.arange(g, dtype=np.int64))
    kt = clusters.k[c].astype(np.int64)
    at = clusters.anchor[c].astype(np.int64)
    keep = kt < p
    stream = np.asarray(plane, dtype=np.int64).ravel()
    if stream.size != int(keep.sum()):
        raise ValueError(f"plane {p} holds {stream.size} bits, expected {int(keep.sum())}")
    bit = (at >> np.maximum(kt - p, 0)) & 1  # the anchor's bit where it implies the component
    bit[keep] = stream
    v[:g] = (v[:g] << 1) | bit
    return pack_clustered(v.astype(np.uint32), clusters, p)


def remove_plane_clustered(words: np.ndarray, clusters: Clusters, level: int) -> np.ndarray:
    """Per-buffer level B -> B - 1: drop the lowest bit of every vertex of bins k <= B - 1.
    Returns P at level B - 1."""
    if not 1 < level <= LEVELS:
        raise ValueError(f"cannot remove a plane below level {level}")
    values, _ = decode_clustered(words, clusters, level)
    shrink = int(clusters.vertex_id[level - 1])
    values[:shrink] >>= np.uint32(1)
    return pack_clustered(values, clusters, level - 1)


def clustered_bytes(clusters: Clusters, level: int) -> int:
    """GPU-resident bytes of a clustered buffer at level B: P's words, 16 B per cluster record and
    the 128-byte ClusterId table of its uniform block."""
    return 4 * words_at(clusters, level) + 4 * RECORD_WORDS * clusters.n_clusters + CLUSTER_ID_BYTES


def k_histogram(clusters: Clusters) -> np.ndarray:
    """(25,) int64: clusters-components with each k (0..24), over x, y, z."""
    return np.bincount(clusters.k.astype(np.int64).ravel(), minlength=LEVELS + 1)[: LEVELS + 1]


def _check_level(level: int) -> None:
    if not 1 <= int(level) <= LEVELS:
        raise ValueError(f"per-buffer level must be in [1, {LEVELS}], got {level}")


__all__ = ["Clusters", "MIN_CLUSTER_SIZE", "MAX_CLUSTER_SIZE", "check_size", "morton_codes", "cluster_order",
           "make_clusters", "vertex_clusters", "stored_widths", "cluster_bit", "words_at", "pack_clustered",
           "decode_clustered", "records", "from_header", "plane_bit", "plane_bits_clustered",
           "add_plane_clustered", "remove_plane_clustered", "clustered_bytes", "k_histogram"]
