"""What other cluster layouts would save on position memory (issue 16, item 1: "or whatever you
measure to be best"), against the layout ``cook --clusters N`` writes.

Not a test. Usage::

    .venv/bin/python -m lopcook cook ASSET -o OUT.lop --clusters 0
    .venv/bin/python benchmarks/bench_cluster_layouts.py OUT.lop [OUT2.lop ...] [--size 64] [--level 6]

For LOD 0 of every part (its 24-bit grid integers and minimum levels, as the container stores
them), the position bits per vertex at per-buffer level B (every vertex decoded at max(B, m_v)),
as % of float32 (96 bits), for:

* ``unclustered``: 3 max(B, m_v) bits per vertex (the 2.0 layout, no table words);
* ``morton prefix``: what ``lopcook.lop.clusters`` writes: runs of N vertices in Morton order
  inside each bin, each component's longest common prefix stored once (checked against
  ``clustered_bytes`` of the real encoder, records included, to within its padding to words);
* ``hilbert prefix``: the same runs cut from a Hilbert order inside each bin (no jumps between
  consecutive vertices, so a run is more compact);
* ``hilbert offset``: those runs with a DGF-style anchor: per component the best k <= the bin's
  level with a j-bit offset from the cluster's minimum at k bits, saving k - j bits (the prefix
  anchor is the j = 0 case);
* ``octree cells``: clusters that are octree cells of at most N vertices, ignoring the bins
  (a cell at depth d shares d bits per component, limited by its lowest level), one 128-bit
  record per cell.

Every layout but the first adds 128 bits of record per cluster (the same ``RECORD_WORDS``), the
per-buffer ClusterId table is left out of all of them (128 B per buffer). All layouts decode the
same positions (the global grid at max(B, m_v) bits), so only memory differs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

RECORD_BITS = 128


def hilbert_codes(q: np.ndarray, bits: int = 21) -> np.ndarray:
    """(n,) uint64 Hilbert indices of (n, 3) integers < 2^bits (Skilling's transpose, vectorised)."""
    x = [np.asarray(q[:, i], dtype=np.uint64).copy() for i in range(3)]
    top = np.uint64(1) << np.uint64(bits - 1)
    bit = top
    while bit > 1:
        low = bit - np.uint64(1)
        for i in range(3):
            hit = (x[i] & bit) != 0
            if i == 0:
                x[0] = np.where(hit, x[0] ^ low, x[0])
            else:
                t = (x[0] ^ x[i]) & low
                x[0], x[i] = np.where(hit, x[0] ^ low, x[0] ^ t), np.where(hit, x[i], x[i] ^ t)
        bit >>= np.uint64(1)
    for i in range(1, 3):
        x[i] ^= x[i - 1]
    t = np.zeros_like(x[0])
    bit = top
    while bit > 1:
        t = np.where((x[2] & bit) != 0, t ^ (bit - np.uint64(1)), t)
        bit >>= np.uint64(1)
    h = np.zeros_like(x[0])
    for b in range(bits - 1, -1, -1):
        for i in range(3):
            h = (h << np.uint64(1)) | (((x[i] ^ t) >> np.uint64(b)) & np.uint64(1))
    return h


def prefix_bits(c: np.ndarray) -> np.ndarray:
    """(n_c,) longest common prefix of each row of (n_c, N) 24-bit integers."""
    x = np.bitwise_or.reduce(c ^ c[:, :1], axis=1).astype(np.int64)
    return np.where(x == 0, 24, 23 - np.floor(np.log2(np.maximum(x, 1))).astype(np.int64))


def offset_saving(c: np.ndarray, level: np.ndarray) -> np.ndarray:
    """(n_c,) best k - j over k <= level: a j-bit offset from the minimum at k bits."""
    lo, hi = c.min(axis=1).astype(np.int64), c.max(axis=1).astype(np.int64)
    best = np.zeros(c.shape[0], dtype=np.int64)
    for k in range(25):
        span = (hi >> (24 - k)) - (lo >> (24 - k))
        j = np.where(span == 0, 0, np.floor(np.log2(np.maximum(span, 1))).astype(np.int64) + 1)
        best = np.maximum(best, np.where(k <= level, k - j, 0))
    return best


def runs(q: np.ndarray, m: np.ndarray, codes: np.ndarray, size: int, level: int):
    """Runs of ``size`` in (m, code) order inside each bin: yields (rows (n_c, size, 3), counts, b)."""
    order = np.lexsort((codes, m))
    qs, ms = q[order], m[order]
    for lev in np.unique(ms):
        rows = qs[ms == lev]
        n_c = -(-rows.shape[0] // size)
        pad = n_c * size - rows.shape[0]
        block = np.concatenate([rows, np.repeat(rows[-1:], pad, axis=0)]).reshape(n_c, size, 3)
        counts = np.full(n_c, size)
        counts[-1] = size - pad
        yield block, counts, max(int(lev), level)


def octree_depth(codes: np.ndarray, size: int) -> np.ndarray:
    """(n,) depth of each vertex's cluster: the coarsest octree cell holding at most ``size``."""
    depth = np.full(codes.size, 21)
    free = np.ones(codes.size, dtype=bool)
    for d in range(22):
        cell = codes >> np.uint64(63 - 3 * d) if d else np.zeros_like(codes)
        _, inv, cnt = np.unique(cell, return_inverse=True, return_counts=True)
        take = free & (cnt[inv.ravel()] <= size)
        depth[take] = d
        free &= ~take
        if not free.any():
            break
    return depth


def layouts(path: str, size: int, level: int) -> dict:
    from lopcook.lop.binning import LEVELS
    from lopcook.lop.bitplane import to_grid
    from lopcook.lop.clusters import cluster_order, clustered_bytes, make_clusters, morton_codes
    from lopcook.lop.container import read
    from lopcook.lop.reader import top_values

    c = read(path)
    bits = dict.fromkeys(["unclustered", "morton prefix", "hilbert prefix", "hilbert offset", "octree cells"], 0.0)
    real = 0
    n_all = 0
    for i, part in enumerate(c.manifest["parts"]):
        q = to_grid(*top_values(c, i, 0, c.available_level)).astype(np.uint32)
        vid = np.asarray(part["lods"][0]["vertex_id"], np.int64)
        m = np.repeat(np.arange(LEVELS + 1), np.diff(vid, prepend=0))
        b = np.maximum(m, level)
        n_all += m.size
        bits["unclustered"] += 3 * b.sum()
        morton = morton_codes(q)
        bins = cluster_order(q, m, morton)
        cl = make_clusters(q[bins.order], bins.vertex_id, size)
        real += 8 * (clustered_bytes(cl, level) - 128)  # without the per-buffer ClusterId table
        hilbert = hilbert_codes(q >> np.uint32(3))
        for name, codes in (("morton", morton), ("hilbert", hilbert)):
            for block, counts, bl in runs(q, m, codes, size, level):
                bits[f"{name} prefix"] += RECORD_BITS * counts.size
                if name == "hilbert":
                    bits["hilbert offset"] += RECORD_BITS * counts.size
                for t in range(3):
                    bits[f"{name} prefix"] += (counts * (bl - np.minimum(prefix_bits(block[:, :, t]), bl))).sum()
                    if name == "hilbert":
                        bits["hilbert offset"] += (counts * (bl - offset_saving(block[:, :, t], bl))).sum()
        depth = octree_depth(morton, size)
        key = np.where(depth > 0, morton >> (np.uint64(63) - np.uint64(3) * depth.astype(np.uint64)), 0)
        _, cell = np.unique((depth.astype(np.uint64) << np.uint64(58)) | key, return_inverse=True)
        cell = cell.ravel()
        lowest = np.full(cell.max() + 1, LEVELS)
        np.minimum.at(lowest, cell, b)
        bits["octree cells"] += 3 * (b - np.minimum(depth, lowest[cell])).sum() + RECORD_BITS * lowest.size
    return {"vertices": n_all, "parts": len(c.manifest["parts"]), "real_morton_bits": real,
            **{k: v / n_all for k, v in bits.items()}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("containers", nargs="+")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--level", type=int, default=6)
    args = ap.parse_args()
    print(f"| container | vertices | unclustered | morton prefix (written) | hilbert prefix | hilbert offset "
          f"| octree cells |  (bits per vertex at level {args.level}, N = {args.size}; % of float32)")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for path in args.containers:
        r = layouts(path, args.size, args.level)
        written = r["real_morton_bits"] / r["vertices"]
        # the encoder's own bytes: the same bits, padded to whole 32-bit words per buffer
        assert 0 <= written - r["morton prefix"] <= 32 * r["parts"] / r["vertices"], (written, r["morton prefix"])
        cells = " | ".join(f"{r[k]:.2f} ({100 * r[k] / 96:.1f} %)" for k in
                           ("unclustered", "morton prefix", "hilbert prefix", "hilbert offset", "octree cells"))
        print(f"| {Path(path).name} | {r['vertices']:,} | {cells} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
