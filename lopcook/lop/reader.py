"""Read buffers back out of a Container: the CPU side of what a renderer uploads.

``gpu_buffer(container, part, lod, B)`` rebuilds the packed buffer P at per-buffer level B from
the mandatory bits and refinement planes 2..B, exactly as the paper lays it out (binned order,
VertexId/BitId tables); ``decode_positions`` decodes it with the reference decoder.

A clustered buffer (``cluster_size`` in its entry, ``lopcook.lop.clusters``) is read from its
cluster headers, its clustered mandatory words and its plane slices (which skip the components
its anchors imply); ``clustered_gpu_buffer`` gives its clustered P and cluster records, and
``decode_positions`` decodes that with ``clusters.decode_clustered``. ``gpu_buffer`` of a clustered
buffer still gives the unclustered P of the same vertices (for the unclustered shaders).

Position sections are found through the container's layout (``lopcook.lop.layout``): the default
layout's ``positions/mandatory`` and planes, or in the streaming layout the sections of the
buffer's stage; a buffer decodes up to its own level (``Container.level_of``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from .binning import LEVELS, table_bit_id, vertex_widths
from .bitplane import decode, pack, reconstruct_float32, reconstruct_float64, to_grid
from .clusters import Clusters, decode_clustered, from_header, pack_clustered, records, vertex_clusters
from .codecs import CODECS, AttributeBits
from .codecs.normals_oct import NORMALS
from .container import Container
from .indices import decode_indices
from .layout import plane_bytes
from .placement import split, to_world
from .record import decode_record


@dataclass
class GpuBuffer:
    """words (w,) uint32: packed P; vertex_id, bit_id (25,) int64 tables; level: per-buffer B;
    decoded: None, or (values (n, 3) uint32, widths (n,)), the values the words were packed from,
    which is what the reference decoder (``bitplane.decode``) gives for them at B."""

    words: np.ndarray
    vertex_id: np.ndarray
    bit_id: np.ndarray
    level: int
    decoded: tuple | None = None


@dataclass
class ClusteredGpuBuffer:
    """A clustered buffer as a renderer uploads it at level B: words (w,) uint32 clustered P,
    clusters (its ``Clusters``: VertexId, ClusterId, anchors), records (n_c, 4) uint32 (the
    ``LopClusters`` SSBO at B), level B; decoded: None, or (values, widths) as ``GpuBuffer``'s
    (what ``clusters.decode_clustered`` gives for the words)."""

    words: np.ndarray
    clusters: Clusters
    records: np.ndarray
    level: int
    decoded: tuple | None = None


def lod_entry(c: Container, part: int, lod: int) -> dict:
    parts = c.manifest["parts"]
    if not 0 <= part < len(parts):
        raise LopcookError("usage", c.path, f"part {part} does not exist (0..{len(parts) - 1})")
    lods = parts[part]["lods"]
    if not 0 <= lod < len(lods):
        raise LopcookError("usage", c.path, f"part {part} has no LOD {lod} (0..{len(lods) - 1})")
    return lods[lod]


def owner(c: Container, part: int) -> int:
    """The part whose bytes hold part ``part``'s buffers: itself, or for a placement
    (``cook --instances``) its ``placement.of``."""
    pl = c.manifest["parts"][part].get("placement")
    return part if pl is None else int(pl["of"])


def part_grid(c: Container, part: int) -> tuple[list, float]:
    """``(origin, extent)`` of the grid part ``part``'s buffers are quantised on: its own ``grid``
    record for a placement (the mesh grid), else the scene grid."""
    g = c.manifest["parts"][part].get("grid") or c.manifest["grid"]
    return g["origin"], float(g["extent"])


def placement_transform(c: Container, part: int) -> list | None:
    """Part ``part``'s 3 x 4 row-major local-to-world transform, None on the scene grid."""
    pl = c.manifest["parts"][part].get("placement")
    return None if pl is None else pl["transform"]


def world_attributes(c: Container, part: int, attrs: dict) -> dict:
    """Part ``part``'s decoded attributes ``{name: values or None}`` in world space: unchanged on
    the scene grid; for a placement each codec's ``to_world`` by the float64 of its float32
    ``A`` (normals: ``A^-T n`` normalised). Other keys are passed through."""
    tf = placement_transform(c, part)
    if tf is None:
        return dict(attrs)
    a = split(tf)[0].astype(np.float64)
    by_name = {x.name: x for x in CODECS}
    return {k: v if v is None or k not in by_name else by_name[k].to_world(v, a) for k, v in attrs.items()}


def world_normals(c: Container, part: int, normals):
    """Part ``part``'s decoded normals (n, 3) float32 in world space (``world_attributes``)."""
    return world_attributes(c, part, {NORMALS.name: normals})[NORMALS.name]


def plane_slice(c: Container, part: int, lod: int, p: int) -> tuple[np.ndarray, int]:
    """``(bytes, start)``: the uint8 bytes of refinement plane p of the stage holding buffer
    (part, lod) (its own section, or its part of the stage's deferred section) and the bit offset
    of the buffer's slice in them (the earlier buffers of the stage, in manifest order). A
    placement reads its owner's slice."""
    part = owner(c, part)
    stage = c.layout.stage(part, lod)
    loc = stage.plane_location(p)
    if loc is None:
        return np.zeros(0, np.uint8), 0
    name, offset = loc
    data = np.frombuffer(c.section(name), np.uint8)[offset:offset + plane_bytes(stage.bits[p])]
    return data, stage.slice_start(part, lod, p)


def _plane_bits(c: Container, part: int, lod: int, p: int) -> tuple[np.ndarray, int]:
    """Plane p of buffer (part, lod)'s stage as a 0/1 uint8 stream (cached on the container per
    stage) and the buffer's bit offset in it."""
    cache = c.__dict__.setdefault("_plane_cache", {})
    key = (c.layout.stage_of[(owner(c, part), lod)], p)
    data, start = plane_slice(c, part, lod, p)
    if key not in cache:
        cache[key] = np.unpackbits(data, bitorder="little")
    return cache[key], start


def plane_slice_bits(entry: dict, p: int) -> int:
    """Bits of one buffer's slice of refinement plane p: 3 VertexId[p-1], or for a clustered buffer
    its ``cluster_plane_bits`` (the components its anchors imply are not stored)."""
    if "cluster_size" in entry:
        return int(entry["cluster_plane_bits"][p - 2])
    return 3 * int(entry["vertex_id"][p - 1])


def buffer_clusters(c: Container, part: int, lod: int) -> Clusters | None:
    """The Clusters of a clustered buffer from its stored headers (cached), None when unclustered."""
    part = owner(c, part)  # a placement's entries equal its owner's: one Clusters per distinct buffer
    e = lod_entry(c, part, lod)
    if "cluster_size" not in e:
        return None
    cache = c.__dict__.setdefault("_cluster_cache", {})
    if (part, lod) not in cache:
        off, count = e["cluster_words"]
        head = np.frombuffer(c.section(c.layout.stage(part, lod).clusters or "positions/clusters"), dtype="<u4")
        if off + count > head.size:
            raise LopcookError("container", c.path, "cluster header words out of range")
        try:
            cache[(part, lod)] = from_header(head[off:off + count], np.asarray(e["vertex_id"], np.int64),
                                             e["cluster_size"])
        except ValueError as exc:
            raise LopcookError("container", c.path, f"part {part} LOD {lod}: {exc}") from None
    return cache[(part, lod)]


def top_values(c: Container, part: int, lod: int, level: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) uint32 top bits and (n,) widths of every vertex at per-buffer level B (binned order):
    the mandatory bits (the buffer packed at level 1), then one bit per refinement plane 2..B for
    the vertices whose minimum level is below that plane."""
    if not 1 <= level <= LEVELS:
        raise LopcookError("usage", c.path, f"level {level} is outside [1, 24]", reason="level")
    e = lod_entry(c, part, lod)
    have = c.level_of(part, lod)
    if level > have and not c.stream:
        raise LopcookError("usage", c.path, f"level {level} is not in this file (it holds levels up to {have})",
                           hint="use a lower --level or the complete file", reason="level")
    if level > have:
        raise LopcookError("usage", c.path, f"level {level} of part {part} LOD {lod} is not in this file ("
                           + (f"its stage holds levels up to {have})" if have else "its stage has not arrived)"),
                           hint="use a lower --level, a coarser --lod or the complete file", reason="level")
    vid = np.asarray(e["vertex_id"], dtype=np.int64)
    off, count = e["mandatory_words"]
    mandatory = np.frombuffer(c.section(c.layout.stage(owner(c, part), lod).mandatory), dtype="<u4")
    if off + count > mandatory.size:
        raise LopcookError("container", c.path, "mandatory position words out of range")
    words = mandatory[off:off + count]
    cl = buffer_clusters(c, part, lod)
    if cl is not None:
        return _clustered_top_values(c, part, lod, level, words, cl)
    values, widths = decode(words, vid, table_bit_id(vid, 1), 1)
    values = values.astype(np.uint32)
    for p in range(2, level + 1):
        g = int(vid[p - 1])
        if g == 0:
            continue
        stream, start = _plane_bits(c, part, lod, p)
        if start + 3 * g > stream.size:
            raise LopcookError("container", c.path, f"plane {p} is shorter than its buffers")
        bits = stream[start:start + 3 * g].reshape(g, 3).astype(np.uint32)
        values[:g] = (values[:g] << np.uint32(1)) | bits
    return values, vertex_widths(vid, level)


def _clustered_top_values(c: Container, part: int, lod: int, level: int, words: np.ndarray,
                          cl: Clusters) -> tuple[np.ndarray, np.ndarray]:
    """``top_values`` of a clustered buffer: the level-1 decode, then per plane p the stored bit of
    every component with k_t < p and the anchor's bit of every other (vertices with m_v < p)."""
    values = decode_clustered(words, cl, 1)[0].astype(np.int64)
    vid = cl.vertex_id
    for p in range(2, level + 1):
        g = int(vid[p - 1])
        if g == 0:
            continue
        _, ci, _ = vertex_clusters(cl, np.arange(g, dtype=np.int64))
        kt = cl.k[ci].astype(np.int64)
        bit = (cl.anchor[ci].astype(np.int64) >> np.maximum(kt - p, 0)) & 1
        keep = kt < p
        want = int(keep.sum())
        stream, start = _plane_bits(c, part, lod, p)  # a placement reads its owner's slice
        if start + want > stream.size:
            raise LopcookError("container", c.path, f"plane {p} is shorter than its buffers")
        bit[keep] = stream[start:start + want]
        values[:g] = (values[:g] << 1) | bit
    return values.astype(np.uint32), vertex_widths(vid, level)


def gpu_buffer(c: Container, part: int, lod: int, level: int) -> GpuBuffer:
    """The packed buffer P (uint32 words) at per-buffer level B with its VertexId/BitId tables."""
    values, widths = top_values(c, part, lod, level)
    vid = np.asarray(lod_entry(c, part, lod)["vertex_id"], dtype=np.int64)
    return GpuBuffer(words=pack(values, vid, level), vertex_id=vid, bit_id=table_bit_id(vid, level), level=level,
                     decoded=(values, widths))


def clustered_gpu_buffer(c: Container, part: int, lod: int, level: int) -> ClusteredGpuBuffer:
    """The clustered P (uint32 words) at level B with its clusters and records. LopcookError
    ("usage") when the buffer is not clustered."""
    cl = buffer_clusters(c, part, lod)
    if cl is None:
        raise LopcookError("usage", c.path, f"part {part} LOD {lod} is not clustered",
                           hint="cook with --clusters N")
    values, widths = top_values(c, part, lod, level)
    return ClusteredGpuBuffer(words=pack_clustered(values, cl, level), clusters=cl, records=records(cl, level),
                              level=level, decoded=(values, widths))


def decode_positions(c: Container, part: int, lod: int, level: int, *, float32: bool = True):
    """Decode a buffer at level B with the reference decoder (``clusters.decode_clustered`` for a
    clustered buffer, ``bitplane.decode`` otherwise).

    Returns (grid (n, 3) uint32 24-bit integers with dropped bits zero, widths (n,), positions
    (n, 3) float32 as the shaders compute them, or float64 block centres with float32=False).
    The grid integers are on the part's grid (``part_grid``); the positions are world metres: for
    a placement the local decode mapped by its transform (``placement.to_world``)."""
    if buffer_clusters(c, part, lod) is not None:
        cbuf = clustered_gpu_buffer(c, part, lod, level)
        values, widths = decode_clustered(cbuf.words, cbuf.clusters, level)
    else:
        buf = gpu_buffer(c, part, lod, level)
        values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
    origin, extent = part_grid(c, part)
    cell = extent / float(1 << LEVELS)
    recon = reconstruct_float32 if float32 else reconstruct_float64
    pos = recon(values, widths, origin, cell)
    tf = placement_transform(c, part)
    if tf is not None:
        pos = _placed(pos, tf, float32)
    return to_grid(values, widths), widths, pos


def positions_f32(c: Container, level: int, lod: int = 0) -> bytes:
    """``lopcook decode --positions``: the float32 xyz (little-endian) of every vertex of every part
    and placement in manifest order (part, then its LOD's binned vertex order), world metres
    (``decode_positions``: a placement's transform applied), each part at LOD ``lod`` or its
    coarsest when its chain is shorter (as ``decode`` draws it), every buffer at level B. The
    layout every reader's dump reproduces byte for byte (``runtime/c/examples/lopdump``)."""
    out = []
    for i, part in enumerate(c.manifest["parts"]):
        k = min(int(lod), len(part["lods"]) - 1)
        out.append(np.ascontiguousarray(decode_positions(c, i, k, level)[2], dtype="<f4").tobytes())
    return b"".join(out)


def _placed(pos, tf, float32: bool):
    """Local positions -> world: the float32 reference order (``placement.to_world``), or float64
    ``A p + t`` with the same float32 values of A and t."""
    if float32:
        return to_world(pos, tf)
    a, t = split(tf)
    return np.asarray(pos, np.float64) @ a.astype(np.float64).T + t.astype(np.float64)


def lod_attributes(c: Container, part: int, lod: int, *, unit_directions: bool = False) -> dict:
    """Decoded ``indices`` (m, 3) uint32 and every codec's attribute (float32 or None; normals,
    uvs, colors, ...), binned order, from the LOD's index section and its packed attribute record
    (``record.decode_record``): normals (and other directions) are the UNNORMALISED float32
    octahedral decode (normalise where a unit vector is needed, or pass ``unit_directions=True``:
    each codec's ``unit``, float32 of the float64 normalisation), the others the float32 decodes,
    exactly as the shaders compute them."""
    e = lod_entry(c, part, lod)
    dtype = "<u2" if e["index_width"] == 2 else "<u4"
    raw = np.frombuffer(c.section(e["indices"]), dtype)
    if raw.size < 3 * e["triangles"]:
        raise LopcookError("container", c.path, f"part {part} LOD {lod}: index section is too short")
    out = {"indices": decode_indices(raw[: 3 * e["triangles"]], e["index_width"], e["triangles"])}
    n = e["vertices"]
    bits = AttributeBits.of(e.get("attribute_bits") or {})
    out.update({x.name: None for x in CODECS})
    if e.get("attributes") is not None:
        words = np.frombuffer(c.section(e["attributes"]), "<u4")
        out.update(decode_record(words, n, bits, e))
        if unit_directions:
            for x in CODECS:
                if x.error_model == "direction" and out[x.name] is not None:
                    out[x.name] = x.unit(out[x.name])
    if int(out["indices"].max(initial=0)) >= n:
        raise LopcookError("container", c.path, f"part {part} LOD {lod}: index out of range")
    return out
