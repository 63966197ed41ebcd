"""Scenes rendered beside AP and CAP in ``lopcook report``: the uniform 16-bit quantization users
ship instead, and the source coloured by each vertex's minimum level (Meyer et al. 2011, Fig. 7).

Uniform 16-bit (``uniform_quantized_scene``): what KHR_mesh_quantization tools write by default
(glTF-Transform ``quantize``: quantization volume per mesh; gltfpack ``-vp 16``): each part's
positions in a cube around its own bounding box (centre ``c``, half-side ``h`` = half the largest
box side: one uniform scale, as a node transform can undo), stored as normalized SHORT
``q = round((p - c) / h * 32767)`` and decoded by the spec's ``max(q / 32767, -1) * h + c``.
Per axis the error is at most ``h / 32767 / 2`` metres. On the GPU: VEC3 SHORT padded to 8 bytes
per vertex (vertex attributes are 4-byte aligned), 66.7 % of float32. Parts are quantized in world
space (lopcook's scene model), so instances of one mesh get one volume each.

Level colours (``level_colours``, ``level_scene``): every vertex of LOD 0 coloured by its minimum
level m_v (read back from the container's bins, ``lopcook.lop.reader``), on a turbo-like ramp
from the lowest to the highest level present, textures removed; rendered with float positions.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..lop.reader import decode_positions, lod_attributes, lod_entry
from ..types import MeshPart, Scene
from .buffers import lod0_is_source, source_order

#: bytes per vertex of VEC3 SHORT positions on the GPU (4-byte aligned attribute)
UNIFORM16_BYTES_PER_VERTEX = 8


def uniform_quantize(positions: np.ndarray, bits: int = 16) -> np.ndarray:
    """(n, 3) float64 metres -> the (n, 3) float64 positions a normalized signed ``bits``-bit
    quantization over the part's bounding cube decodes to (module doc). ``bits`` in [2, 16]."""
    if not 2 <= int(bits) <= 16:
        raise ValueError(f"bits must be in [2, 16], got {bits}")
    top = float((1 << (int(bits) - 1)) - 1)
    p = np.asarray(positions, dtype=np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * float((hi - lo).max())
    if half <= 0.0:
        return p.copy()
    q = np.clip(np.rint((p - centre) / half * top), -top, top)
    return np.maximum(q / top, -1.0) * half + centre


def uniform_quantized_scene(scene: Scene, bits: int = 16) -> Scene:
    """``scene`` with every part's positions replaced by their ``uniform_quantize`` decode; all
    other attributes, textures and triangles unchanged."""
    parts = tuple(replace(p, positions=uniform_quantize(p.positions, bits)) for p in scene.parts)
    return replace(scene, parts=parts, source=f"{scene.source} (uniform {bits}-bit)")


def level_colours(levels: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """(n,) minimum levels -> (n, 4) float32 linear RGBA in [0, 1] on a turbo-like ramp, ``lo`` blue
    to ``hi`` red (Mikhailov's polynomial fit of Google's Turbo colormap over [0.1, 0.9]: its dark
    ends would read as shadow on a shaded render)."""
    t = 0.1 + 0.8 * np.clip((np.asarray(levels, dtype=np.float64) - lo) / max(hi - lo, 1), 0.0, 1.0)
    r = 0.13572138 + t * (4.61539260 + t * (-42.66032258 + t * (132.13108234 + t * (-152.94239396 + t * 59.28637943))))
    g = 0.09140261 + t * (2.19418839 + t * (4.84296658 + t * (-14.18503333 + t * (4.27729857 + t * 2.82956604))))
    b = 0.10667330 + t * (12.64194608 + t * (-60.58204836 + t * (110.36276771 + t * (-89.90310912 + t * 27.34824973))))
    rgb = np.clip(np.stack([r, g, b], axis=1), 0.0, 1.0)
    return np.concatenate([rgb, np.ones((rgb.shape[0], 1))], axis=1).astype(np.float32)


def container_levels(c, part: int, lod: int = 0) -> np.ndarray:
    """(n,) uint8 minimum level of every vertex of ``part``'s LOD ``lod``, in the container's
    binned order (bin k spans ``[VertexId[k-1], VertexId[k])``)."""
    vid = np.asarray(lod_entry(c, part, lod)["vertex_id"], dtype=np.int64)
    return np.repeat(np.arange(1, 25, dtype=np.uint8), np.diff(vid))


def level_scene(c, scene: Scene, lo: int | None = None, hi: int | None = None) -> tuple[Scene, int, int]:
    """LOD 0 of container ``c`` with vertex colours by minimum level and no UVs or textures; the
    ramp runs from ``lo`` to ``hi`` (default: the lowest and highest level of LOD 0). When LOD 0
    holds the source's vertices, the source ``scene``'s positions and normals are used (vertices
    matched by ``render.source_order``); otherwise (a ``cook --target-bytes`` container whose only
    LOD is simplified) the container's own LOD 0 decoded at its highest level. Returns (scene, lo, hi)."""
    geometry, per_part = [], []
    if lod0_is_source(c):
        for i, (part, order) in enumerate(zip(scene.parts, source_order(c, scene))):
            lv = np.ones(part.n_vertices, dtype=np.uint8)
            lv[order] = container_levels(c, i)
            geometry.append((part.positions, part.indices, part.normals))
            per_part.append(lv)
    else:
        level = min(24, int(c.available_level))
        for i in range(len(c.manifest["parts"])):
            _, _, pos = decode_positions(c, i, 0, level, float32=False)
            a = lod_attributes(c, i, 0, unit_directions=True)
            geometry.append((np.asarray(pos, np.float64), a["indices"], a["normals"]))
            per_part.append(container_levels(c, i))
    allv = np.concatenate(per_part)
    lo = int(allv.min()) if lo is None else int(lo)
    hi = int(allv.max()) if hi is None else int(hi)
    parts = tuple(MeshPart(name=p.name, positions=pos, indices=np.asarray(ind, np.uint32),
                           attributes={"normals": nrm, "colors": level_colours(lv, lo, hi)},
                           source=p.source, normals_computed=p.normals_computed,
                           texture=None, mesh_key=p.mesh_key, double_sided=p.double_sided)
                  for p, (pos, ind, nrm), lv in zip(scene.parts, geometry, per_part))
    return replace(scene, parts=parts, source=f"{scene.source} (minimum levels)"), lo, hi


__all__ = ["UNIFORM16_BYTES_PER_VERTEX", "uniform_quantize", "uniform_quantized_scene", "level_colours",
           "container_levels", "level_scene"]
