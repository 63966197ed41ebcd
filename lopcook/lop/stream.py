"""The streaming layout's writer: a default-layout container rewritten coarse to fine.

docs/format.md section 14 (version 4.0, ``cook --stream``). ``to_stream(container)`` keeps every
vertex, its bins, its attribute record and its position bits, and changes where they lie: stage 0
holds every part's coarsest LOD, and the other buffers follow in the order a camera coming closer
needs them (``stage_keys``), each stage its buffers' index and attribute sections followed by its
own position sections, and the planes above a stage's level L_s (``stage_levels``) at the end of
the file. Index sections get the
vertex-cache triangle order of meshoptimizer and the triangle codec's rotations; every section is
encoded where that saves ``encoding.MIN_SAVING`` (docs/format.md 15). The result decodes, buffer
for buffer and level for level, to the same vertices as the input, and its triangles are the
input's (same winding) in another order and rotation.

Stages: LOD k of a part is selected for camera distances in [t_k, t_{k+1}) (``min_distance_m`` of
it and of the next coarser LOD; ``lopcook.selection``), so a camera at distance d needs exactly the
buffers with t_{k+1} > d. A buffer's key is ``required_level(t_{k+1})``, the level of the farthest
camera that selects it (0 for a coarsest LOD), and stages are the distinct keys in ascending order:
a camera at level B needs the stages up to key B, and a prefix never holds a finer LOD before a
coarser one of the same part. Stage levels: LOD k is drawn from t_k outward, where the half-pixel
criterion asks for ``required_level(t_k)`` bits at most (Meyer et al. 2011, section 4;
``lopcook.viewing``); a shared buffer (placements) takes the most any placement asks for after its
level shift, and the earliest key of its placements.
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


def stage_keys(manifest: dict) -> dict:
    """{(part, lod): key} of every stored buffer (module doc): ``required_level`` of the next
    coarser LOD's ``min_distance_m`` (0 for the coarsest LOD; 24 where it is not recorded), the
    least over a shared buffer's placements, made non-decreasing from a part's coarsest LOD to
    its finest."""
    m = manifest
    viewing, extent = viewing_of(m), float(m["grid"]["extent"])
    keys: dict = {}
    for j, part in enumerate(m["parts"]):
        pl = part.get("placement")
        owner = int(pl["of"]) if isinstance(pl, dict) else j
        n, key = len(part["lods"]), 0
        for k in range(n - 2, -1, -1):  # coarse to fine
            d = part["lods"][k + 1].get("min_distance_m")
            key = max(key, LEVELS if d is None else int(np.asarray(required_level(float(d), extent, viewing))))
            keys[(owner, k)] = min(keys.get((owner, k), key), key)
        keys[(owner, n - 1)] = 0
    return keys


def stage_levels(manifest: dict, stages: list) -> list[int]:
    """L_s of every stage (``stages``: per stage its (part, lod) buffers): the largest
    ``buffer_level`` over the stage's buffers."""
    return [max(buffer_level(manifest, i, k) for i, k in buffers) for buffers in stages]


def assign_stages(manifest: dict) -> tuple[list, dict]:
    """``(stages, stage_of)``: per stage its stored buffers (part, lod) in manifest order, and the
    stage of each: the rank of its key among the distinct keys (``stage_keys``)."""
    keys = stage_keys(manifest)
    rank = {key: s for s, key in enumerate(sorted(set(keys.values())))}
    stages: list = [[] for _ in rank]
    for (i, k) in sorted(keys):
        stages[rank[keys[(i, k)]]].append((i, k))
    return stages, {b: rank[key] for b, key in keys.items()}


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
    order, stage_of = assign_stages(m)
    levels = stage_levels(m, order)
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
