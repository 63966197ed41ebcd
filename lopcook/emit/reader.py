"""Read buffers back out of a Container: the CPU side of what a renderer uploads.

``gpu_buffer(container, part, lod, B)`` rebuilds the packed buffer P at per-buffer level B from
the mandatory bits and refinement planes 2..B, exactly as the paper lays it out (binned order,
VertexId/BitId tables); ``decode_positions`` decodes it with the reference decoder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from . import attributes as attr
from .binning import LEVELS, table_bit_id, vertex_widths
from .bitplane import decode, pack, reconstruct_float32, reconstruct_float64, to_grid
from .container import Container


@dataclass
class GpuBuffer:
    """words (w,) uint32: packed P; vertex_id, bit_id (25,) int64 tables; level: per-buffer B."""

    words: np.ndarray
    vertex_id: np.ndarray
    bit_id: np.ndarray
    level: int


def lod_entry(c: Container, part: int, lod: int) -> dict:
    parts = c.manifest["parts"]
    if not 0 <= part < len(parts):
        raise LopcookError("usage", c.path, f"part {part} does not exist (0..{len(parts) - 1})")
    lods = parts[part]["lods"]
    if not 0 <= lod < len(lods):
        raise LopcookError("usage", c.path, f"part {part} has no LOD {lod} (0..{len(lods) - 1})")
    return lods[lod]


def _buffer_order(c: Container):
    """(part, lod, entry) in manifest order: the order buffers appear inside plane sections."""
    for i, p in enumerate(c.manifest["parts"]):
        for k, e in enumerate(p["lods"]):
            yield i, k, e


def top_values(c: Container, part: int, lod: int, level: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) uint32 top bits and (n,) widths of every vertex at per-buffer level B (binned order)."""
    if not 1 <= level <= LEVELS:
        raise LopcookError("usage", c.path, f"level {level} is outside [1, 24]")
    if level > c.available_level:
        raise LopcookError("usage", c.path, f"level {level} is not in this file (it holds levels up to "
                           f"{c.available_level})", hint="use a lower --level or the complete file")
    e = lod_entry(c, part, lod)
    vid = np.asarray(e["vertex_id"], dtype=np.int64)
    off, count = e["mandatory_words"]
    mandatory = np.frombuffer(c.section(c.manifest["positions"]["mandatory"]), dtype="<u4")
    if off + count > mandatory.size:
        raise LopcookError("emit", c.path, "mandatory position words out of range")
    words = mandatory[off:off + count]
    values, widths = decode(words, vid, table_bit_id(vid, 1), 1)
    values = values.astype(np.uint32)
    for p in range(2, level + 1):
        stream = np.unpackbits(np.frombuffer(c.section(c.manifest["positions"]["planes"][str(p)]), np.uint8),
                               bitorder="little")
        start = 0
        for i, k, other in _buffer_order(c):
            count_p = 3 * int(other["vertex_id"][p - 1])
            if (i, k) == (part, lod):
                if start + count_p > stream.size:
                    raise LopcookError("emit", c.path, f"plane {p} is shorter than its buffers")
                bits = stream[start:start + count_p].reshape(-1, 3).astype(np.uint32)
                g = bits.shape[0]
                values[:g] = (values[:g] << np.uint32(1)) | bits
                break
            start += count_p
    return values, vertex_widths(vid, level)


def gpu_buffer(c: Container, part: int, lod: int, level: int) -> GpuBuffer:
    """The packed buffer P (uint32 words) at per-buffer level B with its VertexId/BitId tables."""
    values, _ = top_values(c, part, lod, level)
    vid = np.asarray(lod_entry(c, part, lod)["vertex_id"], dtype=np.int64)
    return GpuBuffer(words=pack(values, vid, level), vertex_id=vid, bit_id=table_bit_id(vid, level), level=level)


def decode_positions(c: Container, part: int, lod: int, level: int, *, float32: bool = True):
    """Decode a buffer at level B with the reference decoder.

    Returns (grid (n, 3) uint32 24-bit integers with dropped bits zero, widths (n,), positions
    (n, 3) float32 as the shaders compute them, or float64 block centres with float32=False)."""
    buf = gpu_buffer(c, part, lod, level)
    values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
    g = c.manifest["grid"]
    cell = g["extent"] / float(1 << LEVELS)
    recon = reconstruct_float32 if float32 else reconstruct_float64
    return to_grid(values, widths), widths, recon(values, widths, g["origin"], cell)


def lod_attributes(c: Container, part: int, lod: int) -> dict:
    """Decoded indices (m, 3) uint32 and normals / uvs / colors (float32 or None), binned order."""
    e = lod_entry(c, part, lod)
    dtype = "<u2" if e["index_width"] == 2 else "<u4"
    raw = np.frombuffer(c.section(e["indices"]), dtype)
    if raw.size < 3 * e["triangles"]:
        raise LopcookError("emit", c.path, f"part {part} LOD {lod}: index section is too short")
    out = {"indices": attr.decode_indices(raw[: 3 * e["triangles"]], e["index_width"], e["triangles"])}
    n = e["vertices"]
    out["normals"] = None if e.get("normals") is None else attr.decode_normals(
        np.frombuffer(c.section(e["normals"]), "<u2")[: 2 * n])
    out["uvs"] = None if e.get("uvs") is None else attr.decode_uvs(
        np.frombuffer(c.section(e["uvs"]), "<u2")[: 2 * n], np.float32(e["uv_range"][0]), np.float32(e["uv_range"][1]))
    out["colors"] = None if e.get("colors") is None else attr.decode_colors(
        np.frombuffer(c.section(e["colors"]), np.uint8)[: 4 * n])
    if int(out["indices"].max(initial=0)) >= n:
        raise LopcookError("emit", c.path, f"part {part} LOD {lod}: index out of range")
    return out
