"""The typed view of a container manifest: parts, LODs and the one definition of every byte count.

The full contract is ``schema/container.schema.json`` (JSON Schema 2020-12, used by the tests);
``lopcook.lop.validate.validate_manifest`` checks a manifest before this view is built, so the
classes here index it without further checks. Byte counts: ``LodEntry`` (one buffer) and
``Manifest`` (sums over a LOD of every part, each distinct buffer once at its resident level).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .binning import buffer_bytes
from .clusters import CLUSTER_ID_BYTES, RECORD_WORDS

FORMAT = "lopcook.lop"
LEVELS = 24
FLOAT32_BYTES_PER_VERTEX = 12  # three float32 components


@dataclass(frozen=True)
class LodEntry:
    """One buffer (a part's LOD) of a container.

    vertices, triangles : counts; vertex_id : (25,) the VertexId table (vertex_id[k] = vertices
    with minimum level < k+1 ... see docs/format.md); geometric_error_m : metres from LOD 0;
    min_distance_m : camera distance (metres) from which a runtime selects it, or None;
    index_width : 2 or 4 bytes; section_bytes : stored bytes of its ``indices`` and
    ``attributes`` sections (0 when absent); attribute_bits : ``{"normals", "uvs", "colors"}``
    bits per component (None when absent); record_bits : S, bits per vertex of its attributes.
    """

    vertices: int
    triangles: int
    vertex_id: tuple
    geometric_error_m: float
    min_distance_m: float | None
    index_width: int
    section_bytes: dict
    mandatory_words: int = 0
    attribute_bits: dict | None = None
    record_bits: int = 0
    cluster_size: int | None = None
    cluster_p_words: tuple | None = None
    cluster_plane_bits: tuple | None = None

    @property
    def clustered(self) -> bool:
        return self.cluster_size is not None

    @property
    def n_clusters(self) -> int:
        """Clusters of a clustered buffer (bins cut into runs of N), 0 when unclustered."""
        if self.cluster_size is None:
            return 0
        counts = np.diff(np.asarray(self.vertex_id, dtype=np.int64))
        return int((-(-counts // int(self.cluster_size))).sum())

    def cap_bytes(self, level: int) -> int:
        """GPU-resident bytes of the binned (CAP) position buffer at per-buffer level B: every
        vertex at max(B, m_v) bits per component, whole uint32 words (Meyer et al. 2011, 5.3).
        A clustered buffer (``lopcook.lop.clusters``) counts its words of P, 16 B per cluster
        record and the 128-byte ClusterId table."""
        if self.cluster_size is not None:
            return (4 * int(self.cluster_p_words[int(level) - 1]) + 4 * RECORD_WORDS * self.n_clusters
                    + CLUSTER_ID_BYTES)
        return self.unclustered_cap_bytes(level)

    def unclustered_cap_bytes(self, level: int) -> int:
        """Bytes the same vertices take in the unclustered binned layout at level B (for comparison)."""
        return buffer_bytes(np.asarray(self.vertex_id, dtype=np.int64), int(level))

    @property
    def cluster_header_bytes(self) -> int:
        """Stored bytes of its cluster headers (12 per cluster in ``positions/clusters``), 0 when unclustered."""
        return 12 * self.n_clusters

    def ap_bytes(self, level: int) -> int:
        """GPU-resident bytes of the uniform (AP) position buffer at level B: B bits per component
        for every vertex, whole uint32 words."""
        return 4 * ((3 * int(level) * self.vertices + 31) // 32)

    @property
    def float32_bytes(self) -> int:
        """Bytes of the same positions as float32 (12 per vertex)."""
        return FLOAT32_BYTES_PER_VERTEX * self.vertices

    @property
    def mandatory_bytes(self) -> int:
        """Stored bytes of its mandatory bits (the packed buffer at level 1: ``cap_bytes(1)`` for
        every container the reader accepts)."""
        return 4 * self.mandatory_words

    def plane_bytes(self, max_level: int) -> int:
        """Stored bits of its refinement planes 2..max_level, in bytes rounded up per plane (the
        planes of all buffers are packed together; this is this buffer's share)."""
        if self.cluster_plane_bits is not None:
            return sum((int(self.cluster_plane_bits[p - 2]) + 7) // 8 for p in range(2, int(max_level) + 1))
        return sum((3 * int(self.vertex_id[p - 1]) + 7) // 8 for p in range(2, int(max_level) + 1))

    @property
    def index_bytes(self) -> int:
        """Stored bytes of its index section."""
        return int(self.section_bytes.get("indices", 0))

    @property
    def attribute_bytes(self) -> int:
        """Stored bytes of its vertex attributes (the packed normal/UV/colour record section,
        ``4 ceil(n S / 32)``); indices not included."""
        return int(self.section_bytes.get("attributes", 0))


@dataclass(frozen=True)
class PartEntry:
    """One part of a container: its name, source path and LODs (LOD 0 first); for a placement
    (``cook --instances``) the part owning its buffers and its level shift (``placement_of`` None
    for a part on the scene grid)."""

    name: str
    source: str
    lods: tuple
    placement_of: int | None = None
    level_shift: int = 0

    def lod(self, k: int) -> LodEntry:
        """LOD k, or the coarsest when the chain is shorter (as a renderer draws it)."""
        return self.lods[min(int(k), len(self.lods) - 1)]


@dataclass(frozen=True)
class Manifest:
    """The typed view of a validated manifest (``Manifest.of(container.manifest)``)."""

    parts: tuple
    max_level: int

    @classmethod
    def of(cls, m: dict) -> "Manifest":
        sizes = {s["name"]: int(s["length"]) for s in m.get("sections", [])}
        parts = []
        for p in m["parts"]:
            lods = tuple(LodEntry(vertices=int(e["vertices"]), triangles=int(e["triangles"]),
                                  vertex_id=tuple(int(v) for v in e["vertex_id"]),
                                  geometric_error_m=float(e.get("geometric_error_m", 0.0)),
                                  min_distance_m=e.get("min_distance_m"), index_width=int(e.get("index_width") or 0),
                                  section_bytes={k: sizes.get(e.get(k) or "", 0) for k in ("indices", "attributes")},
                                  mandatory_words=int((e.get("mandatory_words") or [0, 0])[1]),
                                  attribute_bits=e.get("attribute_bits"), record_bits=int(e.get("record_bits") or 0),
                                  cluster_size=e.get("cluster_size"),
                                  cluster_p_words=None if e.get("cluster_p_words") is None
                                  else tuple(e["cluster_p_words"]),
                                  cluster_plane_bits=None if e.get("cluster_plane_bits") is None
                                  else tuple(e["cluster_plane_bits"]))
                         for e in p["lods"])
            pl = p.get("placement")
            parts.append(PartEntry(name=str(p["name"]), source=str(p.get("source", "")), lods=lods,
                                   placement_of=None if pl is None else int(pl["of"]),
                                   level_shift=0 if pl is None else int(pl["level_shift"])))
        return cls(parts=tuple(parts), max_level=int(m["positions"]["max_level"]))

    @property
    def has_placements(self) -> bool:
        """Whether any part is a placement of shared buffers (``cook --instances``)."""
        return any(p.placement_of is not None for p in self.parts)

    def part_level(self, i: int, level: int) -> int:
        """The per-buffer level part ``i`` decodes its buffer at when the scene asks for ``level``:
        ``level`` on the scene grid, ``clamp(level + level_shift, 1, 24)`` for a placement
        (``lopcook.lop.placement.local_level``)."""
        p = self.parts[i]
        return int(level) if p.placement_of is None else int(min(max(int(level) + p.level_shift, 1), LEVELS))

    def resident(self, level: int, lod: int = 0) -> list[tuple[LodEntry, int]]:
        """Every distinct buffer of LOD ``lod`` once, with the level it is resident at when every
        part asks for ``level``: a part on the scene grid at ``level``, a shared buffer at the
        maximum ``part_level`` over its placements (``placement.resident_level``)."""
        out, owners = [], {}
        for i, p in enumerate(self.parts):
            if p.placement_of is None:
                out.append((p.lod(lod), int(level)))
                continue
            j = p.placement_of
            if j not in owners:
                owners[j] = len(out)
                out.append((self.parts[j].lod(lod), self.part_level(i, level)))
            else:
                e, b = out[owners[j]]
                out[owners[j]] = (e, max(b, self.part_level(i, level)))
        return out

    def buffers(self, lod: int = 0) -> list[LodEntry]:
        """LOD ``lod`` of every part (a part's coarsest when its chain is shorter)."""
        return [p.lod(lod) for p in self.parts]

    def cap_bytes(self, level: int, lod: int = 0) -> int:
        """GPU-resident CAP position bytes at scene level ``level``: each distinct buffer once, at
        its resident level (``resident``; without placements every part at ``level``)."""
        return sum(e.cap_bytes(b) for e, b in self.resident(level, lod))

    def ap_bytes(self, level: int, lod: int = 0) -> int:
        """As ``cap_bytes`` for the uniform (AP) buffers."""
        return sum(e.ap_bytes(b) for e, b in self.resident(level, lod))

    def cap_bytes_all_copies(self, level: int, lod: int = 0) -> int:
        """CAP bytes if every placement had a buffer of its own (each at its ``part_level``): what
        storing each copy separately on its mesh grid would cost; equals ``cap_bytes`` without
        placements."""
        return sum(p.lod(lod).cap_bytes(self.part_level(i, level)) for i, p in enumerate(self.parts))

    def ap_bytes_all_copies(self, level: int, lod: int = 0) -> int:
        """As ``cap_bytes_all_copies`` for AP."""
        return sum(p.lod(lod).ap_bytes(self.part_level(i, level)) for i, p in enumerate(self.parts))

    def unclustered_cap_bytes(self, level: int, lod: int = 0) -> int:
        """As ``cap_bytes`` with every buffer in the unclustered layout (each distinct buffer once,
        at its resident level), for comparison."""
        return sum(e.unclustered_cap_bytes(b) for e, b in self.resident(level, lod))

    @property
    def clustered(self) -> bool:
        return any(e.clustered for p in self.parts for e in p.lods)

    def float32_bytes(self, lod: int = 0) -> int:
        """float32 position bytes of LOD ``lod`` of every part, every placement counted (as a
        scene without instancing stores them): the baseline its percentages use."""
        return sum(e.float32_bytes for e in self.buffers(lod))

    @property
    def float32_bytes_all_lods(self) -> int:
        """float32 position bytes of every buffer the container holds (all parts, all LODs)."""
        return sum(e.float32_bytes for p in self.parts for e in p.lods)


def recorded_source_path(source: str, container: str) -> str:
    """The manifest's ``source.path`` for a cook of ``source`` into ``container`` (both as given):
    the source relative to the container's folder, ``/``-separated (``../assets/x.gltf`` for
    ``assets/x.gltf`` cooked into ``build/x.lop``). Both are made absolute against the current
    directory and compared as text (``os.path.relpath``: ``..`` is not resolved through
    symlinks), so the same relative layout gives the same bytes wherever it lies. Only where no
    relative path exists (Windows: another drive) is the absolute path recorded, ``/``-separated."""
    src = os.path.abspath(source)
    try:
        rel = os.path.relpath(src, os.path.dirname(os.path.abspath(container)))
    except ValueError:  # another drive: no relative path leads there
        rel = src
    return rel.replace(os.sep, "/")
