"""The reference dumps of a .lop that every reader must reproduce byte for byte (the layout of
``runtime/c/examples/lopdump``; fixtures/conformance/README.md), computed with lopcook's reader.

* ``positions(c, level, lod)``: ``lopcook.lop.reader.positions_f32`` (``lopcook decode --positions``).
* ``gpu(c, level, lod)``: per buffer owner (manifest order, LOD ``lod`` or the part's coarsest):
  the LopDecode block and P in the file's layout (plus cluster records when clustered), the block
  and P of the binned layout (clustered buffers only), the block and P of AP, then the
  LopAttributeDecode block; uint32 little-endian.
* ``attributes(c, lod)``: per buffer owner: indices as uint32, then the float32 normals
  (unnormalised), UVs, colours present.
"""

from __future__ import annotations

import numpy as np

from lopcook.lop.binning import LEVELS
from lopcook.lop.reader import (buffer_clusters, clustered_gpu_buffer, gpu_buffer, lod_attributes, owner, part_grid,
                                 positions_f32)
from lopcook.verify.buffers import ap_buffer
from lopcook.verify.attribute_gpu import attribute_block
from lopcook.verify.gpu import cluster_decode_block, decode_block


def _lod(c, i: int, lod: int) -> int:
    return min(int(lod), len(c.manifest["parts"][i]["lods"]) - 1)


def positions(c, level: int, lod: int = 0) -> bytes:
    return positions_f32(c, level, lod)


def _half(extent: float) -> np.float32:
    return np.float32(extent / float(1 << LEVELS) / 2.0)


def gpu(c, level: int, lod: int = 0) -> bytes:
    out = []
    for i, part in enumerate(c.manifest["parts"]):
        if owner(c, i) != i:
            continue
        k = _lod(c, i, lod)
        e = part["lods"][k]
        origin, extent = part_grid(c, i)
        half = _half(extent)
        cl = buffer_clusters(c, i, k)
        binned = gpu_buffer(c, i, k, level)
        if cl is not None:
            cb = clustered_gpu_buffer(c, i, k, level)
            words = np.ascontiguousarray(cb.words, "<u4")
            out += [cluster_decode_block(cl.vertex_id, cl.cluster_id, level, origin, half, words.size, cl.size),
                    words.tobytes(), np.ascontiguousarray(cb.records, "<u4").tobytes()]
        words = np.ascontiguousarray(binned.words, "<u4")
        out += [decode_block(binned.vertex_id, binned.bit_id, level, origin, half, words.size), words.tobytes()]
        ap = ap_buffer(c, i, k, level)
        words = np.ascontiguousarray(ap.words, "<u4")
        out += [decode_block(ap.vertex_id, ap.bit_id, level, origin, half, words.size), words.tobytes()]
        sec = e.get("attributes")
        nwords = len(c.section(sec)) // 4 if sec is not None else 0
        out.append(attribute_block(e["attribute_bits"], e, nwords))
    return b"".join(out)


def attributes(c, lod: int = 0) -> bytes:
    out = []
    for i, part in enumerate(c.manifest["parts"]):
        if owner(c, i) != i:
            continue
        a = lod_attributes(c, i, _lod(c, i, lod))
        out.append(np.ascontiguousarray(a["indices"], "<u4").tobytes())
        for key in ("normals", "uvs", "colors", "tangents"):
            if a.get(key) is not None:
                out.append(np.ascontiguousarray(a[key], "<f4").tobytes())
    return b"".join(out)
