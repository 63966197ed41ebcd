"""The streaming layout's writer: a default-layout container rewritten stage by stage.

docs/format.md section 14 (version 4.0, ``cook --stream``). ``to_stream(container, stages,
levels)`` keeps every vertex, its bins, its attribute record and its position bits, and changes
where they lie: each stage (its buffers given by the caller; stage 0 must hold every part's
coarsest LOD) holds its buffers' index and attribute sections followed by its own position
sections, and the planes above a stage's level L_s at the end of the file. Which buffers form
which stage, and the levels, are the cook's decision (``lopcook.emit.stages``).

Index sections get the vertex-cache triangle order of meshoptimizer and the triangle codec's
rotations; every section is encoded where that saves ``encoding.MIN_SAVING`` (docs/format.md
15). The result decodes, buffer for buffer and level for level, to the same vertices as the input,
and its triangles are the input's (same winding) in another order and rotation.
"""

from __future__ import annotations

import numpy as np

import meshoptimizer

from ..errors import LopcookError
from .container import Container, built
from .encoding import encode_index_section, encode_section
from .layout import slice_bits, stage_name

PLANE_ORDER = ("per stage: buffers of the stage in manifest order (parts, then LODs), vertices in binned order, "
               "bits x, y, z; least significant bit first; a clustered buffer skips the components its "
               "cluster's anchor implies; planes above the stage's level concatenated in its deferred section")


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


def to_stream(c: Container, order: list, levels: list) -> Container:
    """The container ``c`` (a complete file in the default layout) in the streaming layout
    (module doc; docs/format.md 14). ``order``: per stage its stored buffers (part, lod) in
    manifest order; ``levels``: per stage its level L_s (1 .. max_level)."""
    m = c.manifest
    if c.available_level < int(m["positions"]["max_level"]) or c.stream:
        raise LopcookError("container", c.path, "only a complete file in the default layout can be rewritten in "
                           "the streaming layout", hint="read the whole file")
    old, max_level = c.layout, int(m["positions"]["max_level"])
    stage_of = {b: s for s, buffers in enumerate(order) for b in buffers}
    stages = [[(i, k, m["parts"][i]["lods"][k]) for i, k in buffers] for buffers in order]
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
    manifest = _stream_manifest(m, levels, moved, stage_of, max_level)
    return built(manifest, sections + tail, path=c.path)


def _stream_manifest(m: dict, levels: list, moved: dict, stage_of: dict, max_level: int) -> dict:
    """The manifest of the streaming file: ``positions.stages``, every LOD entry's ``stage`` and
    words counted in its stage (a placement's entries repeat its owner's), ``options.stream``."""
    parts = []
    for i, part in enumerate(m["parts"]):
        pl = part.get("placement")
        own = int(pl["of"]) if isinstance(pl, dict) else i
        lods = [dict(e, stage=stage_of[(own, k)], **moved[(own, k)]) for k, e in enumerate(part["lods"])]
        parts.append(dict(part, lods=lods))
    out = {key: v for key, v in m.items() if key != "sections"}
    out["parts"] = parts
    out["options"] = dict(m.get("options") or {}, stream=True)
    out["positions"] = {"max_level": max_level, "plane_order": PLANE_ORDER,
                        "stages": [{"level": int(v)} for v in levels]}
    return out
