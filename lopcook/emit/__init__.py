"""Emit: a Scene and its Analysis -> the bytes of a .lop container.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 5.3 and 6 (binned adaptive precision buffers). Steps: (1) one buffer per part and LOD,
vertices binned by minimum level and indices remapped, (2) attribute sections (indices and one
packed attribute record per vertex at the bits chosen per part: ``lopcook.lop.record``),
(3) position sections: every buffer's mandatory bits (its packed buffer at level 1), then
refinement planes 2..max_level, (4) manifest + header (``lopcook.lop.container``). Emit decides
what to write; ``lopcook.lop`` writes the bytes. Layout and order: docs/format.md.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field

import numpy as np

from ..analyse.attribute_bits import part_default_bits
from ..lop.binning import LEVELS, buffer_bytes, make_bins, table_vertex_id, vertex_widths
from ..lop.bitplane import pack, plane_bits, top_bits
from ..lop.clusters import (Clusters, cluster_order, clustered_bytes, make_clusters, morton_codes, pack_clustered,
                            plane_bit, plane_bits_clustered, words_at)
from ..lop.codecs import AttributeBits, bits_for
from ..lop.container import to_bytes
from ..lop.indices import encode_indices
from ..lop.manifest import FORMAT
from ..lop.record import attribute_specs, pack_record, record_codes
from ..version import __version__
from ..viewing import Viewing


@dataclass
class BufferInput:
    """One GPU buffer to emit: a part's LOD. quantized (n, 3) uint32 grid integers, min_level (n,)
    ints in [1, 24], indices (m, 3) into these vertices, attributes: ``{codec name: (n, k) float32}``
    (``MeshPart.attributes``; absent ones have no key),
    geometric_error_m: the LOD's deviation from LOD 0 in metres (0 for LOD 0); min_distance_m: the
    smallest camera distance (metres) at which a runtime selects this LOD (``lopcook.selection``; 0.0
    for LOD 0), written to the manifest only when given (None: the field is left out)."""

    quantized: np.ndarray
    min_level: np.ndarray
    indices: np.ndarray
    attributes: dict = field(default_factory=dict)
    geometric_error_m: float = 0.0
    min_distance_m: float | None = None
    attribute_bits: AttributeBits | None = None

    def bits(self) -> AttributeBits:
        """The attribute bits this buffer is packed with: ``attribute_bits`` when given (it must
        match which attributes are present), else each present codec's ``default_bits``."""
        if self.attribute_bits is not None:
            return self.attribute_bits
        return bits_for(k for k, v in self.attributes.items() if v is not None)


def _sha256_file(path: str) -> str | None:
    try:
        h = hashlib.sha256()
        with open(path, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
        return h.hexdigest()
    except OSError:
        return None


def _pack_bits(bits: np.ndarray) -> bytes:
    """uint8 0/1 stream -> bytes, least significant bit first."""
    return np.packbits(bits, bitorder="little").tobytes()


@dataclass
class EncodedBuffer:
    """One buffer binned and encoded at a highest plane ``max_level``: its manifest entry (without
    ``mandatory_words``, which depend on the buffers before it), its attribute sections (name
    suffix, payload), its mandatory words (the packed buffer at level 1), its VertexId table and
    grid integers in binned order, its bin counts and how many vertices were clamped."""

    entry: dict
    attributes: list
    mandatory: np.ndarray
    vertex_id: np.ndarray
    q: np.ndarray
    counts: np.ndarray
    clamped: int
    clusters: Clusters | None = None


#: per-buffer levels over which clustering must save GPU-resident bytes (``clustering_wins``)
CHOICE_LEVELS = range(6, 13)


def clustering_wins(clusters: Clusters, vertex_id) -> bool:
    """Whether the clustered layout of a buffer is smaller than its unclustered one: the sum over
    per-buffer levels 6-12 (``CHOICE_LEVELS``) of its clustered GPU-resident bytes (P's words,
    16 B per cluster record, the 128-byte ClusterId table: ``clusters.clustered_bytes``) against
    the unclustered binned buffer's (``binning.buffer_bytes``; same bins). Ties stay unclustered."""
    vid = np.asarray(vertex_id, dtype=np.int64)
    return sum(clustered_bytes(clusters, b) for b in CHOICE_LEVELS) < sum(buffer_bytes(vid, b) for b in CHOICE_LEVELS)


def encode_buffer(buf: BufferInput, max_level: int = LEVELS, cluster_size: int | None = None, *,
                  cluster_all: bool = False) -> EncodedBuffer:
    """Bins, remapped indices and attribute payloads of one buffer (steps (1)-(3a) of the module
    doc). Levels above ``max_level`` are stored at ``max_level`` and counted in ``clamped``.
    ``cluster_size`` N: the clustered layout (``lopcook.lop.clusters``: vertices in cluster order,
    per-cluster anchors, the entry's ``cluster_size``) when it is smaller (``clustering_wins``),
    else the unclustered layout, chosen per buffer and deterministically (``cluster_all``: always
    clustered); None: unclustered."""
    codes = None
    bits = buf.bits()
    if bits.record_bits:  # the attribute codes in source order, for either layout's order
        codes = record_codes(buf.attributes, bits)
    if cluster_size is not None:
        e = _encode_buffer(buf, max_level, cluster_size, codes)
        if cluster_all or clustering_wins(e.clusters, e.vertex_id):
            return e
    return _encode_buffer(buf, max_level, None, codes)


class PositionSizer:
    """GPU-resident position bytes of one buffer encoded at highest plane B, without encoding it.

    ``bytes_at(B)`` = the ``cap_bytes(B)`` that ``encode_buffer(buf, B, cluster_size,
    cluster_all=cluster_all)`` gives the manifest: every minimum level clamped to B, so every
    vertex at B bits per component; the clustered layout's words of P, records and ClusterId table
    where that encoding would choose it (``clustering_wins``, the same bins and clusters), else the
    unclustered binned buffer's words. The Morton codes are computed once per buffer."""

    def __init__(self, buf: BufferInput, cluster_size: int | None = None, *, cluster_all: bool = False):
        self.q = np.asarray(buf.quantized, dtype=np.uint32)
        self.levels = np.asarray(buf.min_level, dtype=np.int64)
        self.size, self.every = cluster_size, bool(cluster_all)
        self._top = int(self.levels.max()) if self.levels.size else 1
        self._codes = None
        self._layouts: dict = {}  # clamp level -> (VertexId, Clusters or None)

    def _layout(self, clamp: int):
        if clamp not in self._layouts:
            lv = np.minimum(self.levels, clamp)
            vid, cl = table_vertex_id(lv), None
            if self.size is not None:
                if self._codes is None:
                    self._codes = morton_codes(self.q)
                bins = cluster_order(self.q, lv, self._codes)
                cl = make_clusters(self.q[bins.order], bins.vertex_id, self.size)
                if not (self.every or clustering_wins(cl, bins.vertex_id)):
                    cl = None
            self._layouts[clamp] = (vid, cl)
        return self._layouts[clamp]

    def bytes_at(self, level: int) -> int:
        b = int(level)
        vid, cl = self._layout(min(b, self._top))  # at or above the highest m_v nothing is clamped
        return int(buffer_bytes(vid, b)) if cl is None else int(clustered_bytes(cl, b))


def _encode_buffer(buf: BufferInput, max_level: int, cluster_size: int | None, codes) -> EncodedBuffer:
    """``encode_buffer`` in the layout asked for (no choice); ``codes``: ``record_codes`` of the
    buffer's attributes in source order (None when it stores no record)."""
    raw_levels = np.asarray(buf.min_level, dtype=np.int64)
    clamped = int(np.count_nonzero(raw_levels > max_level))
    if cluster_size is None:
        bins = make_bins(np.minimum(raw_levels, max_level))
    else:
        bins = cluster_order(buf.quantized, np.minimum(raw_levels, max_level))
    q = np.asarray(buf.quantized, dtype=np.uint32)[bins.order]
    indices = bins.remap_indices(buf.indices)
    n, m = q.shape[0], indices.shape[0]
    entry = {"vertices": n, "triangles": m, "vertex_id": [int(v) for v in bins.vertex_id],
             "geometric_error_m": float(buf.geometric_error_m)}
    if buf.min_distance_m is not None:
        entry["min_distance_m"] = float(buf.min_distance_m)
    data, width = encode_indices(indices, n)
    attributes = [("indices", data.tobytes())]
    entry["index_width"] = int(width)
    bits = buf.bits()
    entry["attributes"] = None
    entry["attribute_bits"] = bits.as_dict()
    entry["record_bits"] = bits.record_bits
    if bits.record_bits:
        # the codes in source order (memoised by content inside a ``code_memo``), then binned:
        # every code depends on its own vertex alone (``record_codes``)
        codes, meta = codes
        words = pack_record({k: v[bins.order] for k, v in codes.items()}, n, bits)
        attributes.append(("attributes", words.tobytes()))
        entry.update(meta["lod"])
    top = top_bits(q, vertex_widths(bins.vertex_id, 1))
    clusters = None
    if cluster_size is None:
        words = pack(top, bins.vertex_id, 1)
    else:
        clusters = make_clusters(q, bins.vertex_id, cluster_size)
        words = pack_clustered(top, clusters, 1)
        entry["cluster_size"] = int(clusters.size)
        entry["cluster_p_words"] = [words_at(clusters, b) for b in range(1, LEVELS + 1)]
        entry["cluster_plane_bits"] = [int(plane_bit(clusters, p)[-1]) for p in range(2, LEVELS + 1)]
    return EncodedBuffer(entry=entry, attributes=attributes, mandatory=words, vertex_id=bins.vertex_id, q=q,
                         counts=bins.counts(), clamped=clamped, clusters=clusters)


def _plane_of(e: EncodedBuffer, plane: int) -> np.ndarray:
    if e.clusters is None:
        return plane_bits(e.q, e.vertex_id, plane).ravel()
    return plane_bits_clustered(e.q, e.clusters, plane)


def plane_payload(encoded: list[EncodedBuffer], plane: int) -> bytes:
    """Refinement plane ``plane`` of the buffers ``encoded`` (manifest order), packed LSB first
    (a clustered buffer's slice skips the components its anchors imply)."""
    return _pack_bits(np.concatenate([_plane_of(e, plane) for e in encoded] or [np.zeros(0, np.uint8)]))


def assemble(scene, grid, parts: list[list[EncodedBuffer]], *, max_level: int, options: dict | None,
             viewing: Viewing, savings: dict | None = None, planes: dict | None = None) -> tuple[dict, list]:
    """The manifest (without its section table) and the sections of a container holding
    ``parts`` (per part, its encoded buffers, LOD 0 first) with planes 2..``max_level``.
    ``planes``: plane payloads already packed for exactly these buffers (plane -> bytes); the
    others are packed here."""
    sections: list[tuple[str, bytes]] = []
    parts_manifest = []
    hist = np.zeros(LEVELS + 1, dtype=np.int64)
    word_offset, clamped, header_offset, headers = 0, 0, 0, []
    for i, (part, encoded) in enumerate(zip(scene.parts, parts)):
        lod_entries = []
        for k, e in enumerate(encoded):
            prefix = f"part{i}/lod{k}"
            entry = dict(e.entry)
            for kind, payload in e.attributes:
                sections.append((f"{prefix}/{kind}", payload))
                entry[kind] = f"{prefix}/{kind}"
            entry["mandatory_words"] = [word_offset, int(e.mandatory.size)]
            word_offset += int(e.mandatory.size)
            if e.clusters is not None:
                head = e.clusters.header_words()
                entry["cluster_words"] = [header_offset, int(head.size)]
                header_offset += int(head.size)
                headers.append(head)
            hist += e.counts
            clamped += e.clamped
            lod_entries.append(entry)
        parts_manifest.append({
            "name": part.name, "source": part.source, "mesh_key": part.mesh_key,
            "texture": None if part.texture is None else {"name": part.texture.name, "sha256": part.texture.digest},
            "normals_computed": bool(part.normals_computed),
            "attribute_bits": lod_entries[0]["attribute_bits"] if lod_entries else None, "lods": lod_entries,
        })
    flat = [e for encoded in parts for e in encoded]
    clustered = any(e.clusters is not None for e in flat)
    if clustered:  # the anchors come first: a prefix holding the mandatory words holds them too
        sections.append(("positions/clusters", np.concatenate(headers + [np.zeros(0, np.uint32)]).astype("<u4").tobytes()))
    sections.append(("positions/mandatory", np.concatenate([e.mandatory for e in flat]).astype("<u4").tobytes()))
    plane_names = {}
    for p in range(2, max_level + 1):
        name = f"positions/plane{p:02d}"
        sections.append((name, planes[p] if planes and p in planes else plane_payload(flat, p)))
        plane_names[str(p)] = name
    total_vertices = int(hist.sum())
    source = {"file": os.path.basename(scene.source), "format": scene.format, "sha256": _sha256_file(scene.source),
              "unit_scale_m": float(scene.unit_scale), "up_axis": scene.up_axis}
    if scene.recorded_path is not None:  # a cook that knows where the container goes (lopcook.cookjob)
        source["path"] = scene.recorded_path
    manifest = {
        "format": FORMAT,
        "generator": f"lopcook {__version__}",
        "source": source,
        "options": options or {},
        "grid": {"origin": [float(v) for v in grid.origin], "extent": float(grid.extent), "bits": LEVELS},
        "viewing": viewing.as_dict(),
        "encodings": attribute_specs([AttributeBits.of(p["attribute_bits"] or {}) for p in parts_manifest]),
        "parts": parts_manifest,
        "positions": {"mandatory": "positions/mandatory", "planes": plane_names, "max_level": int(max_level),
                      "plane_order": "buffers in manifest order (parts, then LODs), vertices in binned order, "
                                     "bits x, y, z; least significant bit first"},
        "stats": {"vertices": total_vertices, "triangles": int(sum(e["triangles"] for p in parts_manifest for e in p["lods"])),
                  "histogram": [int(v) for v in hist], "float32_position_bytes": 12 * total_vertices,
                  "vertices_clamped_to_max_level": clamped},
    }
    if clustered:
        manifest["positions"]["clusters"] = "positions/clusters"
        manifest["positions"]["plane_order"] += ("; a clustered buffer (cluster_size) skips the components its "
                                                 "cluster's anchor implies (k_t >= plane)")
    if savings is not None:
        manifest["savings"] = savings
    return manifest, sections


def default_buffers(scene, analysis) -> list[list[BufferInput]]:
    """LOD 0 of every part as its only buffer, from the scene and its analysis; attribute bits the
    bound-based default of each part (``analyse.attribute_bits.part_default_bits`` with the
    analysis's settings and k_f), as ``lopcook.pipeline`` chooses them without attribute settings."""
    return [[BufferInput(quantized=pa.quantized, min_level=pa.min_level, indices=p.indices,
                         attributes=dict(p.attributes),
                         attribute_bits=part_default_bits(p, analysis.settings, pa.kf))]
            for p, pa in zip(scene.parts, analysis.parts)]


def build(scene, analysis, *, options: dict | None = None, viewing: Viewing | None = None,
          lods: list[list[BufferInput]] | None = None, max_level: int = LEVELS,
          savings: dict | None = None, cluster_size: int | None = None, cluster_all: bool = False) -> bytes:
    """Container bytes for ``scene`` analysed by ``analysis``.

    ``lods``: per part, the list of buffers (LOD 0 first). Default: LOD 0 only, taken from the
    scene and the analysis. ``max_level``: highest refinement plane written (planes above it are
    never needed by any view, see lopcook.viewing); vertices whose minimum level is higher are
    stored at ``max_level`` and counted in ``stats.vertices_clamped_to_max_level``. ``options``
    are recorded verbatim. ``savings``: recorded as the optional manifest field ``savings``.
    ``cluster_size``: N vertices per cluster (clustered position buffers), None: unclustered.
    """
    viewing = viewing or Viewing()
    lods = lods if lods is not None else default_buffers(scene, analysis)
    parts = [[encode_buffer(buf, max_level, cluster_size, cluster_all=cluster_all) for buf in part_lods]
             for part_lods in lods]
    manifest, sections = assemble(scene, analysis.grid, parts, max_level=max_level, options=options,
                                  viewing=viewing, savings=savings)
    return to_bytes(manifest, sections)
