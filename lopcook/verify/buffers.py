"""The position buffers the render harness draws, built from a container without GL: AP and CAP at a
per-buffer level, the binned-to-source vertex order, and the LOD rendered per part.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 4 (AP: one level B for every vertex of a buffer) and 5 (CAP: vertices of bin k > B keep k
bits), Table 1 (levels 6 to 11 and memory relative to float32).

* **AP** at level B (``ap_buffer``): every vertex with exactly B bits per component (the top B of
  its 24-bit grid integers), packed as one bin (VertexId = [0, n, ..., n]) so that the shipped
  decoder reads B bits for each.
* **CAP** at level B: the container's binned buffer (``lopcook.lop.reader.gpu_buffer``).
* ``source_order``: container vertex j (binned order) -> source vertex, so that source normals,
  UVs and colours can be drawn with decoded positions (only positions differ).
* ``position_bytes``: GPU-resident position bytes at level B, AP and CAP, as
  ``lopcook.lop.summary.memory_rows`` counts them.
"""

from __future__ import annotations

import numpy as np

from ..lop.binning import LEVELS, table_bit_id
from ..lop.bitplane import pack
from ..lop.placement import float32_slack, split
from ..lop.reader import (GpuBuffer, buffer_clusters, clustered_gpu_buffer, gpu_buffer, lod_attributes, lod_entry,
                          owner, part_grid, top_values)
from ..errors import LopcookError
from ..settings import DEFAULTS

#: per-buffer levels B rendered by default (the range of the paper's Table 1, plus 12)
DEFAULT_LEVELS = DEFAULTS.render.levels
#: the decoded variants: AP (every vertex B bits) and CAP (the container's bins)
VARIANTS = ("ap", "cap")
#: the LOD rendered by default
LOD = 0


def ap_buffer(c, part: int, lod: int, level: int) -> GpuBuffer:
    """AP at per-buffer level B: every vertex with exactly B bits per component (its top B bits of
    the container's grid integers), packed as one bin (VertexId = [0, n, n, ..., n]), decoded by the
    same ``lop_decode`` (bin level 1, width max(1, B) = B)."""
    values, widths = top_values(c, part, lod, level)
    shift = (widths.astype(np.int64) - int(level)).astype(np.uint32)[:, None]
    values = (values >> shift).astype(np.uint32)
    n = values.shape[0]
    vid = np.full(LEVELS + 1, n, dtype=np.int64)
    vid[0] = 0
    return GpuBuffer(words=pack(values, vid, level), vertex_id=vid, bit_id=table_bit_id(vid, level), level=int(level),
                     decoded=(values, np.full(n, int(level), dtype=np.int64)))


def cap_buffer(c, part: int, lod: int, level: int):
    """CAP at per-buffer level B as a renderer uploads it: the container's buffer in its own layout,
    ``lopcook.lop.reader.clustered_gpu_buffer`` (clustered P and cluster records, decoded by the
    ``LOP_CLUSTERED`` shader) for a clustered buffer, else ``gpu_buffer`` (binned P, VertexId/BitId).
    Both decode to the same grid integers at max(B, m_v) bits."""
    if buffer_clusters(c, part, lod) is not None:
        return clustered_gpu_buffer(c, part, lod, level)
    return gpu_buffer(c, part, lod, level)


def source_order(c, scene, lod: int = LOD) -> list[np.ndarray]:
    """Per part: ``order`` (n,) int64 with ``order[j]`` = the source vertex of container vertex j
    (binned order), recovered from the index buffers (emit keeps the triangle order and only remaps
    indices) and checked against the quantized positions (the top bits of both must agree).
    Raises LopcookError (exit 2) when the container was not cooked from this source. The result is
    kept on the container for this scene object and LOD (a report evaluates one container level
    by level): a second call with the same ``scene`` returns it without reading the planes again."""
    memo = c.__dict__.setdefault("_source_orders", {})
    held = memo.get((id(scene), int(lod)))
    if held is not None and held[0] is scene:
        return held[1]
    out = _source_order(c, scene, lod)
    memo[(id(scene), int(lod))] = (scene, out)
    return out


def _source_order(c, scene, lod: int) -> list[np.ndarray]:
    """``source_order`` without the memo."""
    parts = c.manifest["parts"]
    if len(parts) != len(scene.parts):
        raise LopcookError("verify", c.path, f"the container has {len(parts)} parts, the source "
                           f"{scene.source!r} has {len(scene.parts)}",
                           hint="give the source the container was cooked from")
    g = c.manifest["grid"]
    origin = np.asarray(g["origin"], np.float64)
    cell = float(g["extent"]) / float(1 << LEVELS)
    level = min(LEVELS, int(c.available_level))
    out = []
    for i, (pm, sp) in enumerate(zip(parts, scene.parts)):
        e = lod_entry(c, i, lod)
        if e["triangles"] != sp.n_triangles or e["vertices"] != sp.n_vertices:
            raise LopcookError("verify", c.path, f"part {pm['name']!r}: {e['vertices']} vertices and "
                               f"{e['triangles']} triangles in the container, {sp.n_vertices} and "
                               f"{sp.n_triangles} in the source", hint="give the source the container was cooked from")
        idx = lod_attributes(c, i, lod)["indices"].astype(np.int64).ravel()
        src = np.asarray(sp.indices, np.int64).ravel()
        order = np.zeros(e["vertices"], dtype=np.int64)
        order[idx] = src
        if not np.array_equal(order[idx], src):
            raise LopcookError("verify", c.path, f"part {pm['name']!r}: the triangles differ from the source's",
                               hint="give the source the container was cooked from")
        values, widths = top_values(c, i, lod, level)
        used = np.zeros(e["vertices"], dtype=bool)
        used[idx] = True
        if pm.get("placement") is not None:
            # a placement: the source positions mapped back to the mesh grid (float64 inverse of
            # its float32 transform) lie within one cell of the decoded cell per component, plus
            # the cells the float32 rounding of the transform can move them (placement.float32_slack)
            a, t = split(pm["placement"]["transform"])
            local = (sp.positions[order] - t.astype(np.float64)) @ np.linalg.inv(a.astype(np.float64)).T
            p_origin, p_extent = part_grid(c, i)
            p_cell = p_extent / float(1 << LEVELS)
            q = np.clip(np.floor((local - np.asarray(p_origin, np.float64)) / p_cell), 0,
                        (1 << LEVELS) - 1).astype(np.int64)
            shift = (LEVELS - widths.astype(np.int64))[:, None]
            top = q >> shift
            slack = float(np.abs(float32_slack(pm["placement"]["transform"], p_extent)).max())
            slack_local = slack * float(np.linalg.norm(np.linalg.inv(a.astype(np.float64)), 2))
            allowed = 1 + np.ceil(slack_local / (p_cell * np.exp2(shift.astype(np.float64))))
            same = bool(np.all(np.abs(top - values.astype(np.int64)) <= allowed, where=used[:, None]))
        else:
            q = np.clip(np.floor((sp.positions[order] - origin) / cell), 0, (1 << LEVELS) - 1).astype(np.int64)
            top = q >> (LEVELS - widths.astype(np.int64))[:, None]
            same = np.array_equal(top[used], values.astype(np.int64)[used])
        if not same:
            raise LopcookError("verify", c.path, f"part {pm['name']!r}: the positions differ from the source's",
                               hint="give the source the container was cooked from")
        out.append(order)
    return out


def lod_indices(c, lod: int) -> list[int]:
    """Per part of container ``c``: the LOD index rendered for LOD ``lod`` -- ``lod`` itself, or the
    part's last (coarsest) LOD when its chain is shorter (a part that stopped simplifying)."""
    if int(lod) < 0:
        raise LopcookError("usage", c.path, f"LOD must be >= 0, got {lod}")
    out = [min(int(lod), len(p["lods"]) - 1) for p in c.manifest["parts"]]
    if int(lod) > 0 and max(out, default=0) < int(lod):
        raise LopcookError("usage", c.path, f"no part has a LOD {lod} (the deepest has "
                           f"{max(out, default=0) + 1} LODs)")
    return out


def lod0_is_source(c) -> bool:
    """Whether LOD 0 of container ``c`` holds the source's own vertices (True unless the container
    was written by the byte-budget fit with a simplified LOD as its only LOD:
    ``options.budget.chosen.lod`` > 0, see ``lopcook.tune.budget``)."""
    chosen = (((c.manifest.get("options") or {}).get("budget") or {}).get("chosen") or {})
    return int(chosen.get("lod", 0) or 0) == 0


def position_bytes(c, lods: list[int], level: int) -> dict:
    """GPU-resident position bytes at per-buffer level B over all parts (part i's LOD ``lods[i]``):
    ``cap`` (binned buffers, ``buffer_bytes``) and ``ap`` (every vertex B bits, whole words per
    buffer), as ``lopcook.lop.summary.memory_rows`` counts them for LOD 0."""
    m = c.entries
    parts = m.parts
    if not m.has_placements:
        cap = sum(parts[i].lods[k].cap_bytes(level) for i, k in enumerate(lods))
        ap = sum(parts[i].lods[k].ap_bytes(level) for i, k in enumerate(lods))
        return {"cap": int(cap), "ap": int(ap)}
    cap = ap = cap_all = ap_all = 0
    for (i, k), b in resident_levels(c, lods, level).items():
        cap += parts[i].lods[k].cap_bytes(b)
        ap += parts[i].lods[k].ap_bytes(b)
    for i, k in enumerate(lods):
        b = m.part_level(i, level)
        cap_all += parts[i].lods[k].cap_bytes(b)
        ap_all += parts[i].lods[k].ap_bytes(b)
    return {"cap": int(cap), "ap": int(ap), "cap_all_copies": int(cap_all), "ap_all_copies": int(ap_all)}


def resident_levels(c, lods: list[int], level: int) -> dict:
    """``{(owner part, lod): level}``: every distinct buffer drawn when part i draws LOD ``lods[i]``
    at scene level ``level``, with the level it is resident at (the maximum over the placements
    that draw it of ``Manifest.part_level``; a part on the scene grid at ``level``). Each placement
    decodes its shared buffer at this level."""
    m = c.entries
    out: dict = {}
    for i, k in enumerate(lods):
        key = (owner(c, i), k)
        out[key] = max(out.get(key, 0), m.part_level(i, level))
    return out


__all__ = ["DEFAULT_LEVELS", "VARIANTS", "LOD", "ap_buffer", "cap_buffer", "source_order", "lod_indices",
           "lod0_is_source", "position_bytes", "resident_levels"]
