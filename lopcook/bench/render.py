"""Render peer outputs (float positions) against the float source with lopcook's render harness.

Cameras, shading and metrics are those of ``lopcook.verify.evaluate.evaluate``: the icosahedron
views, the camera at ``camera_distance(B, extent, viewing)`` from the source bounding box for each
level B (extent = the lopcook grid extent of the source, ``lopcook.grid.Grid.fit``),
Phong with the container's ks / shininess (defaults 0.5 / 32), 4x MSAA, masked PSNR
(``lopcook.verify.metrics.image_metrics``) and depth-order errors from the part-ID images.

Each peer output is drawn with its **own** triangles and decoded positions, but with the
**source** normals, UVs, colours and textures of the source vertex each output vertex is matched
to (``lopcook.bench.metrics.match_vertices``), as lopcook's AP and CAP renders use the source
attributes: only positions differ from the float reference. The part ID of an output part is the
source part most of its vertices match. The float reference of each (level, view) is rendered once
and every variant is compared with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from ..verify import metrics as M
from ..verify.cameras import camera_distance, make_camera, select_views
from ..verify.renderer import Coverage, Harness, Shading, attribute_buffers, attribute_vbos
from ..viewing import Viewing


@dataclass
class Variant:
    """One peer output ready to draw: parts of (positions (n, 3) float32 metres, indices (m, 3)
    uint32, source part index, source vertex per output vertex (n,) int64[, own attributes
    {"normals", "uvs", "colors"}: (n, k) float32 or None]). The own attributes are drawn by
    ``render_variants(..., own_attributes=True)`` (``lopcook bench --attributes``)."""

    key: str
    parts: list


def _global_attribute(scene, name: str, width: int):
    """(N, width) float32 of attribute ``name`` over all parts concatenated (zeros where a part has
    none), or None when no part has it."""
    arrays = [getattr(p, name) for p in scene.parts]
    if all(a is None for a in arrays):
        return None
    return np.concatenate([np.zeros((p.n_vertices, width), np.float32) if a is None else np.asarray(a, np.float32)
                           for p, a in zip(scene.parts, arrays)])


def _items(h, scene, variant: Variant, own_attributes: bool = False):
    """Draw items (as ``Harness.float_items``) of a variant, and the GL objects to release. Each
    output vertex takes the attributes of its matched source vertex (any part); with
    ``own_attributes`` the variant's own normals / UVs / colours where it has them (the source's,
    matched, for an attribute the tool dropped)."""
    ctx = h.ctx
    attrs = {n: _global_attribute(scene, n, w) for n, w in (("normals", 3), ("uvs", 2), ("colors", 4))}
    items, owned = [], []
    for entry in variant.parts:
        pos, idx, part, match = entry[:4]
        own = entry[4] if len(entry) > 4 and own_attributes else {}
        src = scene.parts[part]
        # the attributes the part's source has, taken at each matched vertex
        view = SimpleNamespace(**{n: None if getattr(src, n) is None else a for n, a in attrs.items()})
        vbo = ctx.buffer(np.ascontiguousarray(pos, dtype="<f4").tobytes())
        ibo = ctx.buffer(np.ascontiguousarray(idx, dtype="<u4").tobytes())
        if own:
            pick = {n: own.get(n) if own.get(n) is not None else (None if a is None else a[match])
                    for n, a in vars(view).items()}
            specs, bufs = attribute_vbos(ctx, pick["normals"], pick["uvs"], pick["colors"])
        else:
            specs, bufs = attribute_buffers(ctx, view, match)
        vao = ctx.vertex_array(h.renderer.float_program, [(vbo, "3f", "in_position"), *specs],
                               index_buffer=ibo, index_element_size=4)
        # the coverage cull (lopcook.verify.renderer): the same pixels, fewer triangles drawn
        cover = Coverage(ctx, h.renderer.float_program, [(vbo, "3f", "in_position"), *specs], idx, pos)
        owned += [vbo, ibo, *bufs, vao, cover]
        items.append({"vao": vao, "part": int(part), "has_normal": src.normals is not None,
                      "has_color": src.colors is not None, "texture": h.textures.get(src.texture),
                      "triangles": int(np.asarray(idx).size // 3), "cover": cover,
                      "two_sided": bool(src.double_sided)})
    return items, owned


def render_variants(scene, variants: list[Variant], *, levels, views, resolution, extent: float,
                    ks: float = 0.5, shininess: float = 32.0, fov_y_deg: float = 60.0,
                    pixel_error: float = 0.5, progress=None, own_attributes: bool = False) -> dict:
    """{variant key: {level: {"psnr_min", "psnr_mean", "psnr_views", "depth_order_errors"}}}.

    scene : the float source (``lopcook.types.Scene``); levels : camera levels B (each selects its
    distance); views : int N or view indices; resolution : (w, h) pixels; extent : grid extent,
    metres. own_attributes : draw each variant's own attributes (``_items``)."""
    view_ids = select_views(views)
    viewing = Viewing(viewport=(int(resolution[0]), int(resolution[1])), fov_y_deg=fov_y_deg,
                      pixel_error=pixel_error)
    shading = Shading(ks=ks, shininess=shininess)
    out = {v.key: {} for v in variants}
    with Harness(scene, resolution) as h:
        drawn, owned = {}, []
        try:
            for v in variants:
                items, o = _items(h, scene, v, own_attributes)
                drawn[v.key] = items
                owned += o
            for level in levels:
                distance = camera_distance(level, extent, viewing)
                per = {v.key: ([], []) for v in variants}
                for view in view_ids:
                    cam = make_camera(view, h.lo, h.hi, distance, viewing)
                    ref_rgba, ref_ids = h.render_float(cam, shading)
                    for v in variants:
                        rgba, ids = h.renderer.draw(drawn[v.key], cam, shading, decoded=False)
                        per[v.key][0].append(M.image_metrics(ref_rgba, rgba))
                        per[v.key][1].append(M.depth_order_errors(ref_ids, ids))
                for key, (ms, ds) in per.items():
                    psnrs = [m["psnr"] for m in ms]
                    finite = [p for p in psnrs if p is not None]
                    out[key][int(level)] = {
                        "psnr_min": min(finite) if finite else None,
                        "psnr_mean": M.mean_mse_psnr([m["mse"] for m in ms]),
                        "psnr_views": psnrs,
                        "depth_order_errors": int(sum(d["depth_order_errors"] for d in ds))}
                if progress is not None:
                    progress(f"rendered level {level}: {len(view_ids)} views x (1 + {len(variants)}) renders")
        finally:
            for r in owned:
                r.release()
    return out


__all__ = ["Variant", "render_variants"]
