"""The streaming layout's writer: a default-layout container rewritten coarse to fine.

docs/format.md section 14 (version 4.0, ``cook --stream``). ``to_stream(container)`` keeps every
vertex, its bins, its attribute record and its position bits, and changes where they lie: stage s
holds the LOD n - 1 - s of every part with n LODs (so stage 0 is every part's coarsest LOD), each
stage its buffers' index and attribute sections followed by its own position sections, and the
planes above a stage's level L_s (``stage_levels``) at the end of the file. Index sections get the
vertex-cache triangle order of meshoptimizer and the triangle codec's rotations; every section is
encoded where that saves ``encoding.MIN_SAVING`` (docs/format.md 15). The result decodes, buffer
for buffer and level for level, to the same vertices as the input, and its triangles are the
input's (same winding) in another order and rotation.

Stage levels: LOD k is drawn from its selection distance ``min_distance_m`` outward, where the
half-pixel criterion asks for ``required_level(min_distance_m)`` bits at most (Meyer et al. 2011,
section 4; ``lopcook.viewing``); a shared buffer (placements) takes the most any placement asks
for after its level shift.
"""

from __future__ import annotations

import numpy as np

import meshoptimizer

from ..errors import LopcookError
from ..selection import viewing_of
from ..viewing import required_level
from .container import Container, built
from .encoding import encode_index_section, encode_section
from .layout import slice_bits, stage_name

LEVELS = 24
PLANE_ORDER = ("per stage: buffers of the stage in manifest order (parts, then LODs), vertices in binned order, "
               "bits x, y, z; least significant bit first; a clustered buffer skips the components its "
               "cluster's anchor implies; planes above the stage's level concatenated in its deferred section")


def buffer_level(manifest: dict, i: int, k: int) -> int:
    """The highest level stored buffer (part i, LOD k) is drawn at by a viewer that selects LODs
    by distance (module doc), clamped to ``positions.max_level``."""
    m, max_level = manifest, int(manifest["positions"]["max_level"])
    viewing, extent = viewing_of(m), float(m["grid"]["extent"])
    best = 0
    for j, part in enumerate(m["parts"]):
        pl = part.get("placement")
        if j != i and not (isinstance(pl, dict) and pl["of"] == i):
            continue
        d = part["lods"][k].get("min_distance_m")
        if d is None:
            return max_level
        level = int(np.asarray(required_level(float(d), extent, viewing)))
        shift = int(pl["level_shift"]) if isinstance(pl, dict) else 0
        best = max(best, min(max(level + shift, 1), LEVELS))
    return min(best, max_level)


def stage_levels(manifest: dict) -> list[int]:
    """L_s of every stage of the streaming layout of a default-layout manifest: the largest
    ``buffer_level`` over the stage's buffers."""
    longest = max(len(p["lods"]) for p in manifest["parts"])
    levels = [1] * longest
    for i, part in enumerate(manifest["parts"]):
        pl = part.get("placement")
        if isinstance(pl, dict) and pl["of"] != i:
            continue
        n = len(part["lods"])
        for k in range(n):
            levels[n - 1 - k] = max(levels[n - 1 - k], buffer_level(manifest, i, k))
    return levels


def _bits(data: bytes) -> np.ndarray:
    return np.unpackbits(np.frombuffer(data, np.uint8), bitorder="little")


def _pack(bits: np.ndarray) -> bytes:
    out = np.packbits(bits, bitorder="little").tobytes()
    return out + b"\0" * (-len(out) % 4)


def _vertex_cache_order(c: Container, e: dict) -> np.ndarray:
    """The LOD's triangles (m, 3) uint32 in meshoptimizer's vertex-cache order (vertex indices
    unchanged)."""
    raw = np.frombuffer(c.sections[e["indices"]], "<u2" if e["index_width"] == 2 else "<u4")
    idx = np.ascontiguousarray(raw[:3 * e["triangles"]].astype(np.uint32))
    out = np.zeros_like(idx)
    meshoptimizer.optimize_vertex_cache(out, idx, idx.size, e["vertices"])
    return out.reshape(-1, 3)


def _buffer_sections(c: Container, i: int, k: int, e: dict) -> list:
    """The index, attribute and (for LOD 0) hierarchy sections of buffer (i, k), encoded."""
    fields, stored, _ = encode_index_section(_vertex_cache_order(c, e), e["index_width"])
    out = [(e["indices"], stored, fields)]
    names = ([e["attributes"]] if e.get("attributes") else [])
    h = c.manifest["parts"][i].get("hierarchy")
    names += [h["section"]] if k == 0 and isinstance(h, dict) else []
    for name in names:
        fields, stored = encode_section(c.sections[name])
        out.append((name, stored, fields))
    return out


def _stage_positions(c: Container, old, planes: dict, buffers: list, level: int, max_level: int, s: int):
    """Stage s's position sections (clusters, mandatory, early planes) and its deferred payload,
    and the new ``mandatory_words`` / ``cluster_words`` of its buffers. ``planes``: {p: the
    default layout's plane p as a 0/1 stream}."""
    old0 = old.stages[0]
    mand = np.frombuffer(c.sections[old0.mandatory], "<u4")
    head = np.frombuffer(c.sections[old0.clusters], "<u4") if old0.clusters else None
    words, headers, moved = [], [], {}
    for i, k, e in buffers:
        off, count = e["mandatory_words"]
        moved[(i, k)] = {"mandatory_words": [sum(w.size for w in words), count]}
        words.append(mand[off:off + count])
        if "cluster_words" in e:
            off, count = e["cluster_words"]
            moved[(i, k)]["cluster_words"] = [sum(h.size for h in headers), count]
            headers.append(head[off:off + count])
    sections = []
    if headers:
        sections.append((stage_name(s, "clusters"), np.concatenate(headers).astype("<u4").tobytes()))
    sections.append((stage_name(s, "mandatory"), np.concatenate(words).astype("<u4").tobytes()))
    deferred = []
    for p in range(2, max_level + 1):
        if not any(slice_bits(e, p) for _, _, e in buffers):
            continue  # a plane without bits has no bytes
        data = planes[p]
        bits = np.concatenate([data[old0.slice_start(i, k, p):old0.slice_start(i, k, p) + slice_bits(e, p)]
                               for i, k, e in buffers])
        if p <= level:
            sections.append((stage_name(s, f"plane{p:02d}"), _pack(bits)))
        else:
            deferred.append(_pack(bits))
    return sections, b"".join(deferred), moved


def to_stream(c: Container) -> Container:
    """The container ``c`` (a complete file in the default layout) in the streaming layout
    (module doc; docs/format.md 14)."""
    m = c.manifest
    if c.stream:
        return c
    if c.available_level < int(m["positions"]["max_level"]):
        raise LopcookError("container", c.path, "only a complete file can be rewritten in the streaming layout",
                           hint="read the whole file")
    old, max_level = c.layout, int(m["positions"]["max_level"])
    levels = stage_levels(m)
    stages = [[] for _ in levels]
    for i, part in enumerate(m["parts"]):
        pl = part.get("placement")
        if isinstance(pl, dict) and pl["of"] != i:
            continue  # a placement of another part's buffers stores none
        n = len(part["lods"])
        for k, e in enumerate(part["lods"]):
            stages[n - 1 - k].append((i, k, e))
    planes = {p: _bits(c.sections[name]) for p, name in old.stages[0].planes.items()}
    sections, tail, moved = [], [], {}
    for s, buffers in enumerate(stages):
        for i, k, e in buffers:
            sections += _buffer_sections(c, i, k, e)
        pos, deferred, mv = _stage_positions(c, old, planes, buffers, levels[s], max_level, s)
        moved.update(mv)
        for name, data in pos:
            fields, stored = encode_section(data)
            sections.append((name, stored, fields))
        if deferred:
            fields, stored = encode_section(deferred)
            tail.append((stage_name(s, "deferred"), stored, fields))
    manifest = _stream_manifest(m, levels, moved, max_level)
    return built(manifest, sections + tail, path=c.path)


def _stream_manifest(m: dict, levels: list, moved: dict, max_level: int) -> dict:
    """The manifest of the streaming file: ``positions.stages``, every LOD entry's words counted
    in its stage (a placement's entries repeat its owner's), ``options.stream``."""
    parts = []
    for i, part in enumerate(m["parts"]):
        pl = part.get("placement")
        own = int(pl["of"]) if isinstance(pl, dict) else i
        lods = [dict(e, **moved[(own, k)]) for k, e in enumerate(part["lods"])]
        parts.append(dict(part, lods=lods))
    out = {key: v for key, v in m.items() if key != "sections"}
    out["parts"] = parts
    out["options"] = dict(m.get("options") or {}, stream=True)
    out["positions"] = {"max_level": max_level, "plane_order": PLANE_ORDER,
                        "stages": [{"level": int(v)} for v in levels]}
    return out
