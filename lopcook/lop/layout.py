"""Where a buffer's position bits lie: the default layout and the streaming layout's stages.

docs/format.md sections 6.4-6.5 (default layout: one ``positions/mandatory``, one section per
refinement plane, every stored buffer in each) and section 14 (streaming layout, version 4.0: each
LOD entry names its ``stage``, stage 0 holding every part's coarsest LOD; each stage has its own
``positions/stageS/clusters``, ``mandatory``, ``planePP`` for the planes up to its level L_s that
hold bits, and ``deferred`` for planes L_s + 1 .. max_level). Both are a list of ``Stage``\\ s (the
default layout is one stage at level ``max_level``), so the readers, the validator and the
streaming writer share one description: which buffers a stage holds in which order, the bits of
each plane, where plane p of a stage is (section, byte offset) and where a buffer's slice starts,
the section list of a streaming file, and a stage's level in a prefix.

Built from a manifest whose LOD entries are sound (``validate.check_lod`` has run): the plane bit
counts come from ``vertex_id`` and ``cluster_plane_bits``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

LEVELS = 24


def is_stream(manifest: dict) -> bool:
    """Whether the manifest describes the streaming layout (``positions.stages`` present)."""
    pos = manifest.get("positions") if isinstance(manifest, dict) else None
    return isinstance(pos, dict) and "stages" in pos


def stage_name(s: int, kind: str) -> str:
    """The name of stage ``s``'s position section ``kind`` (``clusters``, ``mandatory``,
    ``deferred`` or ``planePP``)."""
    return f"positions/stage{s}/{kind}"


def plane_bytes(bits: int) -> int:
    """Bytes of a plane section holding ``bits`` bits: whole uint32 words."""
    return 4 * ((int(bits) + 31) // 32)


def slice_bits(entry: dict, p: int) -> int:
    """Bits of one buffer's slice of plane p: 3 VertexId[p-1], or a clustered buffer's
    ``cluster_plane_bits[p-2]``."""
    if "cluster_size" in entry:
        return int(entry["cluster_plane_bits"][p - 2])
    return 3 * int(entry["vertex_id"][p - 1])


@dataclass
class Stage:
    """One stage: ``buffers`` ((part, lod, entry), stored buffers in manifest order), ``level``
    L_s (the highest plane stored before the deferred region; ``max_level`` in the default
    layout), the section names ``mandatory`` and ``clusters`` (None when no buffer is
    clustered), ``planes`` {p: section name} of the planes stored as sections of their own, and
    ``deferred`` (the section of planes L_s + 1 .. max_level, None when absent); ``bits`` {p: bits
    of plane p over the stage's buffers} for p = 2 .. max_level; ``required``: the other sections
    that must be complete before any level of the stage decodes (its buffers' indices, attribute
    records and hierarchies; in the default layout every section that is not a position section)."""

    index: int
    buffers: list
    level: int
    mandatory: str
    clusters: str | None
    planes: dict
    deferred: str | None
    bits: dict
    required: list = field(default_factory=list)
    _starts: dict = field(default_factory=dict, repr=False)

    def plane_location(self, p: int) -> tuple[str, int] | None:
        """(section name, byte offset) of plane p's bytes, None when the plane holds no bits."""
        if self.bits[p] == 0:
            return None
        if p in self.planes:
            return self.planes[p], 0
        offset = sum(plane_bytes(self.bits[q]) for q in range(self.level + 1, p))
        return self.deferred, offset

    def slice_start(self, part: int, lod: int, p: int) -> int:
        """Bit offset of stored buffer (part, lod)'s slice of plane p (the earlier buffers' slices)."""
        if p not in self._starts:
            starts, at = {}, 0
            for i, k, e in self.buffers:
                starts[(i, k)] = at
                at += slice_bits(e, p)
            self._starts[p] = starts
        return self._starts[p][(part, lod)]

    def sections(self) -> list[str]:
        """The position sections of the stage in file order (the deferred one excluded)."""
        head = [self.clusters] if self.clusters else []
        return head + [self.mandatory] + [self.planes[p] for p in sorted(self.planes)]

    def available(self, present, max_level: int) -> int:
        """The stage's level given the set of complete section names ``present`` (docs/format.md
        8 and 14.4): 0 unless every section its buffers name, its clusters and mandatory are
        present; else the highest B with every stored plane up to B present (and the deferred
        planes when B > L_s)."""
        for name in self.required + ([self.clusters] if self.clusters else []) + [self.mandatory]:
            if name not in present:
                return 0
        level = 1
        for p in range(2, self.level + 1):
            if p in self.planes and self.planes[p] not in present:
                return level
            level = p
        if self.level < max_level and (self.deferred is None or self.deferred in present):
            return max_level
        return level



@dataclass
class Layout:
    """Every stage of a container and which stage each (part, lod) reads from (a placement reads
    its owner's)."""

    stream: bool
    stages: list
    max_level: int
    stage_of: dict

    def stage(self, part: int, lod: int) -> Stage:
        return self.stages[self.stage_of[(part, lod)]]

    def expected_sections(self) -> list[str]:
        """The section list of a streaming file, in order (docs/format.md 14.3)."""
        names: list[str] = []
        for st in self.stages:
            names += st.required + st.sections()
        return names + [st.deferred for st in self.stages if st.deferred]

    def levels(self, present) -> list[int]:
        """Every stage's level given the complete sections ``present``."""
        return [st.available(present, self.max_level) for st in self.stages]


def _owner(part: dict, i: int) -> int:
    pl = part.get("placement")
    return i if not isinstance(pl, dict) else int(pl["of"])


def _plane_bits(buffers: list, max_level: int) -> dict:
    return {p: sum(slice_bits(e, p) for _, _, e in buffers) for p in range(2, max_level + 1)}


def _buffer_sections(manifest: dict, buffers: list) -> list[str]:
    """The sections a stage's buffers name, in file order: per buffer its indices, its attribute
    record, and for a LOD 0 its part's hierarchy."""
    names: list[str] = []
    for i, k, e in buffers:
        names += [e["indices"]] + ([e["attributes"]] if e.get("attributes") else [])
        h = manifest["parts"][i].get("hierarchy")
        if k == 0 and isinstance(h, dict):
            names.append(h["section"])
    return names


def layout_of(manifest: dict) -> Layout:
    """The Layout of a manifest whose LOD entries are sound (module doc)."""
    pos, parts = manifest["positions"], manifest["parts"]
    max_level = int(pos["max_level"])
    stream = is_stream(manifest)
    count = len(pos["stages"]) if stream else 1
    buffers: list = [[] for _ in range(count)]
    stage_of: dict = {}
    for i, part in enumerate(parts):
        for k, e in enumerate(part["lods"]):
            s = int(e["stage"]) if stream else 0
            stage_of[(i, k)] = s
            if _owner(part, i) == i and 0 <= s < count:
                buffers[s].append((i, k, e))
    stages = []
    for s in range(count):
        bits = _plane_bits(buffers[s], max_level)
        clustered = any("cluster_size" in e for _, _, e in buffers[s])
        if stream:
            level = int(pos["stages"][s]["level"])
            stages.append(Stage(s, buffers[s], level, stage_name(s, "mandatory"),
                                stage_name(s, "clusters") if clustered else None,
                                {p: stage_name(s, f"plane{p:02d}") for p in range(2, level + 1) if bits[p]},
                                stage_name(s, "deferred") if any(bits[p] for p in range(level + 1, max_level + 1))
                                else None, bits, _buffer_sections(manifest, buffers[s])))
        else:
            others = [t["name"] for t in manifest["sections"] if not t["name"].startswith("positions/")]
            stages.append(Stage(0, buffers[0], max_level, pos["mandatory"], pos.get("clusters"),
                                {p: pos["planes"][str(p)] for p in range(2, max_level + 1)}, None, bits, others))
    return Layout(stream=stream, stages=stages, max_level=max_level, stage_of=stage_of)
