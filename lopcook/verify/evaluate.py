"""Render a container against its float source and measure AP and CAP: the render check of
``lopcook verify --source`` and ``lopcook report``.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 4 (per-buffer level by the half-pixel criterion), 5 (CAP) and 7 (Table 1: levels 6 to 11,
memory relative to float32; Fig. 13: PSNR and heat maps against floating-point vertices); and
Purnomo et al., "Hardware-Compatible Vertex Compression Using Quantization and Simplification",
Graphics Hardware 2005, section 4.1 (20 views on an icosahedron, error over object pixels,
background excluded).

What is rendered (``evaluate``), for every per-buffer level B and every view:

* **float**: the source scene (``lopcook.types.Scene``), positions float64 rounded to float32, each
  part with its own index buffer (the same triangles, in the same order, as the container's).
* **AP** (paper section 4): every vertex decoded with B bits (``lopcook.verify.buffers.ap_buffer``).
* **CAP** (section 5): the container's binned buffer at B (``lopcook.lop.reader.gpu_buffer``):
  vertices of bin k > B keep k bits. A clustered buffer (``cook --clusters N``) is uploaded in its
  clustered layout and drawn by the ``LOP_CLUSTERED`` decoder (``lopcook.verify.buffers.cap_buffer``);
  it decodes to the same positions.

Positions of AP and CAP are decoded on the GPU by the shipped decoder, with the container's own
decoded normals, UVs and colours (``lopcook.lop.reader.lod_attributes``: the packed attribute
record, normals normalised per vertex) and the source's textures (``lopcook.verify.renderer``):
the error counts positions and attribute quantisation. ``evaluate(..., lod=k)`` renders the
container's LOD k against the same float LOD-0 source, with the LOD's own index buffer.
``evaluate_scene`` renders any float-position scene (e.g. a simplified mesh: "simplify only")
against the source with the same cameras and metrics.

Cameras (``lopcook.verify.cameras``): for level B, every view's eye is at the distance from the
scene's bounding box where the half-pixel criterion selects B (``camera_distance``);
``camera_levels`` lets the decode level and the camera level differ (e.g. decode at 24 from the
level-8 distance: the harness sanity check), ``distance_m`` fixes one distance for every row.

Metrics: ``lopcook.verify.metrics`` (PSNR over object pixels, max error, share > 1/255, depth-order
errors from the part-ID images), per view in one pass (``metrics.view_metrics``).

Cost: every (level, view) renders float, AP and CAP once; a (level, view) drawn before on the same
harness takes its recorded metrics (docs/verify.md, "Reuse"). ``evaluate`` and ``evaluate_scene``
open a ``Harness`` of their own; ``harness_evaluate`` and ``harness_evaluate_scene`` use an open one.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..lop.binning import LEVELS
from ..lop.reader import lod_entry
from ..errors import LopcookError
from ..grid import Grid
from ..viewing import Viewing, required_level
from . import gpu
from . import metrics as M
from .buffers import (DEFAULT_LEVELS, LOD, VARIANTS, ap_buffer, cap_buffer, lod0_is_source, lod_indices,
                      position_bytes, source_order)
from .cameras import VIEW_COUNT, camera_distance, icosahedron_directions, make_camera, render_viewing, select_views
from .renderer import RESOLUTION, SAMPLES, Harness, Shading, _expand, decoded_items, digest, float_items, trim_heap

#: where LOD 0's normals, UVs and colours come from in a render: the container's own, or the source's
ATTRIBUTE_SOURCES = ("container", "source")


def parse_levels(levels, camera_levels, available: int, path) -> tuple[list[int], list[int]]:
    """(decode levels, camera levels), one of each per row: ``levels`` ints in [1, 24] and at most
    ``available`` (the file's levels); ``camera_levels`` None (= levels), one int, or one per level.
    Raises LopcookError (usage, exit 2) otherwise; ``path`` names the container in the message."""
    lv = [int(b) for b in levels]
    if not lv:
        raise LopcookError("usage", path, "no levels to render")
    if min(lv) < 1 or max(lv) > LEVELS:
        raise LopcookError("usage", path, f"levels must be in [1, {LEVELS}], got {lv}")
    if max(lv) > available:
        raise LopcookError("usage", path, f"level {max(lv)} is not in this file (it holds levels up to {available})",
                           hint=f"use --levels up to {available}")
    if camera_levels is None:
        cl = list(lv)
    elif isinstance(camera_levels, (int, np.integer)):
        cl = [int(camera_levels)] * len(lv)
    else:
        cl = [int(b) for b in camera_levels]
        if len(cl) != len(lv):
            raise LopcookError("usage", path, "camera_levels must be one level or one per level")
    if min(cl) < 1 or max(cl) > LEVELS:
        raise LopcookError("usage", path, f"camera levels must be in [1, {LEVELS}], got {cl}")
    return lv, cl


def levels_in_file(levels, available: int) -> list[int]:
    """The default levels of a render check a file can give: those of ``levels`` (e.g.
    ``DEFAULTS.render.levels``, 6..12) up to ``available`` (the file's highest level), or
    ``[available]`` when it holds none of them (a file cut short, or fitted to a byte budget)."""
    kept = [int(b) for b in levels if int(b) <= int(available)]
    return kept or [int(available)]


def summarise(per_view: list[dict], depth: list[dict], nbytes: int, f32: int) -> dict:
    """One variant's row entry (the keys documented in ``evaluate``) from its per-view
    ``metrics.image_metrics`` and ``metrics.depth_order_errors`` dicts, its position bytes
    ``nbytes`` and the float32 position bytes ``f32`` of LOD 0."""
    mses = [m["mse"] for m in per_view]
    psnrs = [m["psnr"] for m in per_view]
    finite = [p for p in psnrs if p is not None]
    obj = sum(m["object_pixels"] for m in per_view)
    off = sum(m["pixels_off"] for m in per_view)
    return {
        "bytes": int(nbytes),
        "percent_of_float32": 100.0 * nbytes / max(f32, 1),
        "psnr_views": psnrs,
        "psnr_min": min(finite) if finite else None,
        "psnr_mean": M.mean_mse_psnr(mses),
        "psnr_pooled": M.pooled_psnr(sum(m["sum_sq"] for m in per_view), obj),
        "psnr_interior_min": min((m["psnr_interior"] for m in per_view if m["psnr_interior"] is not None),
                                 default=None),
        "psnr_interior_mean": M.mean_mse_psnr([m["interior_mse"] for m in per_view]),
        "max_error": max((m["max_error"] for m in per_view), default=0.0),
        "share_off": off / obj if obj else 0.0,
        "pixels_off": int(off),
        "object_pixels": int(obj),
        "depth_order_errors": int(sum(d["depth_order_errors"] for d in depth)),
        "depth_order_errors_views": [int(d["depth_order_errors"]) for d in depth],
        "part_mismatch": int(sum(d["part_mismatch"] for d in depth)),
    }


def camera_rows(lv, cl, distance_m, extent, viewing) -> list[tuple[int, int, float]]:
    """(decode level, camera level, camera distance m) per row; a fixed ``distance_m`` replaces the
    level distances and its camera level is the level selected there."""
    if distance_m is None:
        return [(b, cb, camera_distance(cb, extent, viewing)) for b, cb in zip(lv, cl)]
    d = float(distance_m)
    if not d > 0.0 or not math.isfinite(d):
        raise LopcookError("usage", None, f"camera distance must be a positive number of metres, got {distance_m}")
    sel = int(np.asarray(required_level(d, extent, viewing)))
    return [(b, sel, d) for b in lv]


def render_rows(h: Harness, *, plan, view_ids, viewing, extent, shading, draws, variants, keep_images,
                 image_view, seconds, stop=None, stop_view=None) -> tuple[list, dict | None]:
    """The per-level render loop shared by ``evaluate`` and ``evaluate_scene``.

    plan : [(level, camera level, distance m)]; draws(level) -> ({variant: (items, decoded)}, owned
    GL objects released after the level); stop(per_view) -> bool, called after each level with the
    first variant's per-view ``metrics.image_metrics`` dicts: True ends the loop there (the rows
    rendered so far are returned); stop_view(metrics) -> bool, called after each view with the first
    variant's ``image_metrics`` dict: True ends that level's views there (the row holds the views
    rendered; ``stop`` is then called as after any level, and must end the loop). Returns (rows
    without the variants' bytes: per variant ``(per_view metrics, depth metrics)`` under ``"_raw"``,
    images or None).
    """
    rows = []
    images = None
    coarsest = min(b for b, _, _ in plan)
    best_score = -1.0
    memo = getattr(h, "view_memo", None)
    for level, cam_level, distance in plan:
        t0 = time.perf_counter()
        drawn, owned_all = draws(level)
        seconds["upload"] += time.perf_counter() - t0
        per_view = {v: [] for v in variants}
        depth = {v: [] for v in variants}
        cams, float_pixels = [], []
        images_here = keep_images and level == coarsest
        # content keys of the variants' draws (None: not memoised, e.g. float-position scenes)
        vkeys = {v: (None if memo is None else variant_key(drawn[v][0], drawn[v][1], shading)) for v in variants}
        try:
            for view in view_ids:
                cam = _camera(h, view, distance, viewing)
                cams.append(cam)
                t0 = time.perf_counter()
                key = (cam.mvp.tobytes(), cam.eye.tobytes(), shading)
                hits = {v: memo.get((vkeys[v], key)) for v in variants if vkeys[v] is not None}
                if not images_here and len(hits) == len(variants) and all(x is not None for x in hits.values()):
                    # every variant drew exactly this before, from this camera: its numbers, no render
                    float_pixels.append(hits[variants[0]][2])
                    for v in variants:
                        per_view[v].append(hits[v][0])
                        depth[v].append(hits[v][1])
                    if stop_view is not None and stop_view(per_view[variants[0]][-1]):
                        break
                    continue
                ref, fbox, outs, boxes = _draw_view(h, drawn, variants, vkeys, cam, shading, key)
                seconds["render"] += time.perf_counter() - t0
                t0 = time.perf_counter()
                float_pixels.append(int(np.count_nonzero(ref[0][..., 3])))
                for v in variants:
                    # the pass over the pixels either render drew (outside: background in both)
                    colour, order = _crop_metrics(h.renderer.size, ref, fbox, outs[v], boxes[v],
                                                  h.__dict__.setdefault("_metric_scratch", {}))
                    per_view[v].append(colour)
                    depth[v].append(order)
                    if vkeys[v] is not None:
                        memo[(vkeys[v], key)] = (colour, order, float_pixels[-1])
                if stop_view is not None and stop_view(per_view[variants[0]][-1]):
                    break
                seconds["metrics"] += time.perf_counter() - t0
                if images_here:
                    score = per_view[variants[0]][-1]["sum_sq"]
                    chosen = view == image_view if image_view is not None else score > best_score
                    if chosen:
                        best_score = score
                        images = _view_images(h.renderer.size, level, view, ref, fbox, outs, boxes, variants)
            if images_here and images is not None and images["level"] == level:
                # the heatmaps of the view kept (once, not for every view that led on the way)
                for v in variants:
                    images[f"{v}_heatmap"] = M.difference_heatmap(images["float"], images[v])
        finally:
            for r in owned_all:
                r.release()
            del drawn, owned_all
            trim_heap()  # the level's buffers and decoded positions: back to the system before the next
        rows.append(_level_row(level, cam_level, distance, extent, viewing, cams, float_pixels,
                               {v: (per_view[v], depth[v]) for v in variants}))
        if stop is not None and stop(per_view[variants[0]]):
            break
    return rows, images


def _draw_view(h: Harness, drawn: dict, variants, vkeys: dict, cam, shading, key) -> tuple:
    """The float source and every variant drawn from ``cam`` as the regions drawn (no whole-image
    arrays): ``((float rgba, float ids), float box, {variant: (rgba, ids)}, {variant: box})``. A
    variant whose draws equal an earlier one's (same ``vkeys`` entry) gives that one's images."""
    ref_rgba, ref_ids = h.render_float(cam, shading, key=key, crop=True)
    fbox = h.last_float_box
    outs, boxes = {}, {}
    for v in variants:
        same = next((u for u in outs if vkeys[u] is not None and vkeys[u] == vkeys[v]), None)
        if same is not None:
            outs[v], boxes[v] = outs[same], boxes[same]
        else:
            outs[v] = h.renderer.draw(drawn[v][0], cam, shading, decoded=drawn[v][1], crop=True)
            boxes[v] = h.renderer.last_box
    return (ref_rgba, ref_ids), fbox, outs, boxes


def _view_images(size, level: int, view: int, ref, fbox, outs: dict, boxes: dict, variants) -> dict:
    """``evaluate``'s ``images`` of one view: the float and variant renders as whole images of ``size``."""
    ref_whole = _expand((fbox, *ref), size)
    images = {"level": level, "view": int(view), "float": ref_whole[0], "float_ids": ref_whole[1]}
    for v in variants:
        images[v], images[f"{v}_ids"] = _expand((boxes[v], *outs[v]), size)
    return images


def _level_row(level: int, cam_level: int, distance: float, extent: float, viewing, cams, float_pixels,
               raw: dict) -> dict:
    """One level's row of ``render_rows`` (``raw``: per variant (per-view metrics, depth metrics))."""
    return {
        "level": int(level),
        "camera_level": int(cam_level),
        "camera_distance_m": float(distance),
        "selected_level": int(required_level(distance, extent, viewing)),
        "eye_distance_m": [float(np.linalg.norm(cm.eye - cm.centre)) for cm in cams],
        "near_far_m": [[cm.near, cm.far] for cm in cams],
        "float_object_pixels": float_pixels,
        "_raw": raw,
    }


def _crop_metrics(size, ref, ref_box, test, test_box, scratch: dict | None = None) -> tuple[dict, dict]:
    """``metrics.view_metrics`` of two whole images given as the regions drawn: ``ref`` and
    ``test`` are (rgba, ids) crops of an image of ``size`` (w, h) at ``ref_box`` and ``test_box``
    ((row0, row1, col0, col1); background outside). The same numbers as ``view_metrics`` of the
    whole images with ``box`` = the union of the two: its pass over that union widened by one
    pixel is made on arrays of that size, the crops pasted in. ``scratch``: a dict kept by the
    caller whose whole-image buffers those arrays reuse (no fresh pages for every view)."""
    w, h = size
    r0, r1, c0, c1 = _union(ref_box, test_box)
    if r1 <= r0 or c1 <= c0:  # nothing drawn in either: background everywhere
        r0 = r1 = c0 = c1 = 0
    else:
        r0, r1, c0, c1 = max(0, r0 - 1), min(h, r1 + 1), max(0, c0 - 1), min(w, c1 + 1)
    shape = (max(r1 - r0, 1), max(c1 - c0, 1))
    pixels = shape[0] * shape[1]
    if scratch is None or scratch.get("pixels", 0) < pixels:
        buffers = [(np.empty(max(pixels, w * h) * 4, np.uint8), np.empty(max(pixels, w * h), np.uint32))
                   for _ in range(2)]
        if scratch is not None:
            scratch.update(pixels=max(pixels, w * h), buffers=buffers)
    else:
        buffers = scratch["buffers"]
    out = []
    for ((rgba, ids), (b0, b1, b2, b3)), (flat_rgba, flat_ids) in zip(((ref, ref_box), (test, test_box)), buffers):
        full_rgba = flat_rgba[:pixels * 4].reshape(shape + (4,))  # C-contiguous views of the buffers
        full_ids = flat_ids[:pixels].reshape(shape)
        full_rgba.fill(0)
        full_ids.fill(0)
        if b1 > b0 and b3 > b2:
            full_rgba[b0 - r0:b1 - r0, b2 - c0:b3 - c0] = rgba
            full_ids[b0 - r0:b1 - r0, b2 - c0:b3 - c0] = ids
        out.append((full_rgba, full_ids))
    return M.view_metrics(out[0][0], out[1][0], out[0][1], out[1][1])


def _union(a, b) -> tuple:
    """The smallest (row0, row1, col0, col1) holding two such boxes (an empty one adds nothing)."""
    boxes = [x for x in (a, b) if x[1] > x[0] and x[3] > x[2]]
    if not boxes:
        return (0, 0, 0, 0)
    return (min(x[0] for x in boxes), max(x[1] for x in boxes), min(x[2] for x in boxes), max(x[3] for x in boxes))


def _camera(h: Harness, view: int, distance: float, viewing):
    """``make_camera(view, h.lo, h.hi, distance, viewing)``, made once per harness (a camera is a
    pure function of these: the searches evaluate the same (level, view) cameras many times)."""
    cache = h.__dict__.setdefault("_cameras", {})
    key = (int(view), float(distance), viewing)
    if key not in cache:
        cache[key] = make_camera(view, h.lo, h.hi, distance, viewing)
    return cache[key]


def variant_key(items, decoded: bool, shading) -> bytes | None:
    """The content key of one variant's draw at one level: the program (decoded or float), the
    shading and every item's ``digest`` in draw order (``renderer.decoded_items``); None when an
    item has no digest. With a camera key it names a render exactly (``Harness.view_memo``)."""
    keys = [it.get("digest") for it in items]
    if any(k is None for k in keys):
        return None
    return digest(bool(decoded), shading, *keys)


def view_header(h: Harness, view_ids, viewing, extent, shading, variants, f32, seconds) -> dict:
    """The top-level keys shared by ``evaluate`` and ``evaluate_scene`` (source, resolution,
    samples, views and their directions, viewing, grid extent m, box m, shading, variants, parts,
    vertices, float32 bytes, seconds rounded to 0.1 ms, GL device)."""
    return {
        "source": str(h.scene.source),
        "resolution": [int(h.renderer.size[0]), int(h.renderer.size[1])],
        "samples": int(h.renderer.samples),
        "views": view_ids,
        "view_directions": [[float(x) for x in icosahedron_directions()[v]] for v in view_ids],
        "viewing": viewing.as_dict(),
        "grid_extent_m": extent,
        "box_m": [[float(x) for x in h.lo], [float(x) for x in h.hi]],
        "shading": shading.as_dict(),
        "variants": list(variants),
        "parts": len(h.scene.parts),
        "vertices": int(f32 // 12),
        "float32_bytes": int(f32),
        "seconds": {k: round(v, 4) for k, v in seconds.items()},
        "device": gpu.context_info(),
    }


def _checked_request(c, scene, variants, levels, camera_levels, views, image_view, lod, attributes) -> tuple:
    """``harness_evaluate``'s arguments checked against container ``c`` and its source ``scene``:
    ``(variants, levels, camera levels, view ids, LOD per part)``; LopcookError otherwise."""
    if attributes not in ATTRIBUTE_SOURCES:
        raise LopcookError("usage", c.path, f"attributes={attributes!r}: expected one of {ATTRIBUTE_SOURCES}")
    variants = tuple(variants)
    for v in variants:
        if v not in VARIANTS:
            raise LopcookError("usage", c.path, f"unknown variant {v!r} (expected ap and/or cap)")
    lv, cl = parse_levels(levels, camera_levels, int(c.available_level), c.path)
    view_ids = select_views(views)
    if image_view is not None and int(image_view) not in view_ids:
        raise LopcookError("usage", c.path, f"image view {image_view} is not among the rendered views {view_ids}")
    lods = lod_indices(c, lod)
    if len(c.manifest["parts"]) != len(scene.parts):
        raise LopcookError("verify", c.path, f"the container has {len(c.manifest['parts'])} parts, the source "
                           f"{scene.source!r} has {len(scene.parts)}",
                           hint="give the source the container was cooked from")
    return variants, lv, cl, view_ids, lods


def harness_evaluate(h: Harness, c, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, camera_levels=None,
                     variants=VARIANTS, ks: float | None = None, shininess: float | None = None,
                     keep_images: bool = False, image_view: int | None = None, lod: int = LOD,
                     distance_m: float | None = None, stop=None, attributes: str = "container", stop_view=None,
                     cooked_from=None) -> dict:
    """``evaluate`` on an open harness ``h`` (its scene is the source): same arguments and result.

    ``stop(per_view) -> bool`` after each level ends the render early (``render_rows``: only the
    levels rendered are in the result, in order); ``stop_view(metrics) -> bool`` after each view
    ends that level's views (and, with a ``stop`` that sees the miss, the render).
    ``cooked_from``: the scene the caller cooked ``c`` from itself (a search's probe); when it is
    ``h``'s scene, the check that the container comes from it (``source_order``, which reads every
    plane) is skipped where nothing else needs the vertex order."""
    t_start = time.perf_counter()
    scene = h.scene
    variants, lv, cl, view_ids, lods = _checked_request(c, scene, variants, levels, camera_levels, views,
                                                        image_view, lod, attributes)
    # every decoded variant draws the container's own attributes (lod_attributes: normals, UVs,
    # colours at their packed bits), so its PSNR includes their quantisation;
    # attributes="source": LOD 0 with the source's (only positions differ)
    orders = [None] * len(lods)
    if lod0_is_source(c) and any(k == 0 for k in lods) and (cooked_from is not scene or attributes == "source"):
        src_orders = source_order(c, scene)  # the container must have been cooked from this source (LopcookError)
        if attributes == "source":
            orders = [o if k == 0 else None for o, k in zip(src_orders, lods)]
    shading = Shading.from_manifest(c.manifest, ks, shininess)
    viewing = render_viewing(c.manifest, h.renderer.size)
    g = c.manifest["grid"]
    extent = float(g["extent"])
    origin = g["origin"]
    half_cell = np.float32(extent / float(1 << LEVELS) / 2.0)
    f32 = 12 * sum(int(lod_entry(c, i, 0)["vertices"]) for i in range(len(c.manifest["parts"])))
    builders = {"ap": ap_buffer, "cap": cap_buffer}  # CAP in the buffer's own layout (clustered or binned)
    ctx = h.ctx
    # a harness that keeps attributes (``Harness.keep_attributes``: the report evaluates one container
    # level by level) reuses the last evaluation's when it drew the same container object the same way
    attr_cache = h.attribute_cache(c, (tuple(lods), attributes, tuple(o is None for o in orders)))
    seconds = {"upload": 0.0, "render": 0.0, "metrics": 0.0}
    plan = camera_rows(lv, cl, distance_m, extent, viewing)

    def draws(level):
        drawn, owned_all = {}, []
        for v in variants:
            items, owned = decoded_items(ctx, h.renderer.decode_program, c, scene, lods, orders, h.textures,
                                          builders[v], level, origin, half_cell, attr_cache,
                                          cluster_program=_cluster_program(h.renderer, c))
            drawn[v] = (items, True)
            owned_all += owned
        return drawn, owned_all

    try:
        rows, images = render_rows(h, plan=plan, view_ids=view_ids, viewing=viewing, extent=extent,
                                    shading=shading, draws=draws, variants=variants, keep_images=keep_images,
                                    image_view=image_view, seconds=seconds, stop=stop, stop_view=stop_view)
    finally:
        h.release_attribute_cache(attr_cache)
        trim_heap()
    for row in rows:
        raw = row.pop("_raw")
        row["float32_bytes"] = int(f32)
        mem = position_bytes(c, lods, row["level"])
        if "cap_all_copies" in mem:  # placements (cook --instances): each copy stored separately, for comparison
            row["all_copies_bytes"] = {v: int(mem[f"{v}_all_copies"]) for v in variants}
        for v in variants:
            row[v] = summarise(raw[v][0], raw[v][1], mem[v], f32)
    seconds["total"] = time.perf_counter() - t_start
    out = view_header(h, view_ids, viewing, extent, shading, variants, f32, seconds)
    out.update({"container": None if c.path is None else str(c.path), "lod": int(lod), "lods": lods,
                "lod_vertices": int(sum(int(lod_entry(c, i, k)["vertices"]) for i, k in enumerate(lods))),
                "levels": rows})
    if keep_images:
        out["images"] = images
    return out


def _cluster_program(renderer, c):
    """The renderer's ``LOP_CLUSTERED`` decode program when container ``c`` holds a clustered buffer
    (compiled on first use), else None."""
    clustered = any("cluster_size" in e for p in c.manifest["parts"] for e in p["lods"])
    return renderer.cluster_decode_program if clustered else None


def harness_evaluate_scene(h: Harness, test, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, camera_levels=None,
                           distance_m: float | None = None, extent: float | None = None,
                           viewing: Viewing | None = None, shading: Shading | None = None,
                           keep_images: bool = False, image_view: int | None = None) -> dict:
    """Render ``test`` (a ``lopcook.types.Scene`` with **float** positions, e.g. a simplified
    LOD chain level: "simplify only") against ``h``'s source scene, with the cameras
    ``evaluate`` uses, and measure it like a decoded variant.

    Parameters
    ----------
    test : Scene whose part i stands for source part i (same order: part-ID depth-order
        errors compare part indices); positions float64 metres (rendered as float32), its own
        indices, normals, UVs, colours; textures: each test part's own ``texture``.
    levels : per-buffer levels B (ints in [1, 24]) whose camera distances to use: one row per
        level, the camera where the half-pixel criterion selects B (``camera_distance``); nothing
        is decoded. ``camera_levels`` overrides the camera level per row as in ``evaluate``.
    views : int N in [1, 20] or a list of icosahedron view indices (as ``evaluate``).
    distance_m : when given, every row's camera sits this many metres from the nearest point
        of the source's bounding box instead (its ``camera_level`` is then the level selected there).
    extent : grid extent in metres for the distances (default: ``Grid.fit`` over the source
        positions, the extent a container cooked without LODs has; pass a container's
        ``manifest["grid"]["extent"]`` to use exactly its cameras).
    viewing : field of view and pixel error (default ``Viewing()``: 60 degrees, half a pixel);
        the viewport is always the render resolution (``render_viewing``).
    shading : Phong parameters (default ``Shading()``: ks 0.5, shininess 32).
    keep_images, image_view : as ``evaluate`` (image keys ``float``, ``scene``, ``float_ids``,
        ``scene_ids``, ``scene_heatmap``).

    Returns the dict ``evaluate`` returns (same top-level keys; ``container`` None, ``lod`` None,
    ``variants`` ["scene"]) whose level rows hold one variant, ``"scene"``, with the same metrics
    as ``"ap"``/``"cap"`` (``psnr_mean`` etc.); its ``bytes`` are the test scene's float32
    positions (12 per vertex) and ``percent_of_float32`` is relative to the source's float32
    positions (``float32_bytes``). Also ``test_source``, ``test_vertices``, ``test_triangles``.
    """
    t_start = time.perf_counter()
    lv, cl = parse_levels(levels, camera_levels, LEVELS, None)
    view_ids = select_views(views)
    if image_view is not None and int(image_view) not in view_ids:
        raise LopcookError("usage", None, f"image view {image_view} is not among the rendered views {view_ids}")
    if not test.parts:
        raise LopcookError("usage", test.source, "the test scene has no parts")
    base = viewing or Viewing()
    viewing = Viewing(viewport=h.renderer.size, fov_y_deg=base.fov_y_deg, pixel_error=base.pixel_error)
    shading = shading or Shading()
    if extent is None:
        extent = float(Grid.fit([p.positions for p in h.scene.parts]).extent)
    extent = float(extent)
    f32 = 12 * sum(p.n_vertices for p in h.scene.parts)
    test_bytes = 12 * sum(p.n_vertices for p in test.parts)
    seconds = {"upload": 0.0, "render": 0.0, "metrics": 0.0}
    plan = camera_rows(lv, cl, distance_m, extent, viewing)
    t0 = time.perf_counter()
    # the source's index and attribute buffers where the test scene shares those arrays
    items, owned = float_items(h.ctx, h.renderer.float_program, test, h.textures, like=(h.scene, h.float_items))
    h.link_culls(test, items)  # after Harness.share_culls(test): the float draws' culls serve these
    seconds["upload"] += time.perf_counter() - t0
    try:
        rows, images = render_rows(h, plan=plan, view_ids=view_ids, viewing=viewing, extent=extent,
                                    shading=shading, draws=lambda level: ({"scene": (items, False)}, []),
                                    variants=("scene",), keep_images=keep_images, image_view=image_view,
                                    seconds=seconds)
    finally:
        for r in owned:
            r.release()
    for row in rows:
        raw = row.pop("_raw")
        row["float32_bytes"] = int(f32)
        row["scene"] = summarise(raw["scene"][0], raw["scene"][1], test_bytes, f32)
    seconds["total"] = time.perf_counter() - t_start
    out = view_header(h, view_ids, viewing, extent, shading, ("scene",), f32, seconds)
    out.update({"container": None, "lod": None, "test_source": str(test.source),
                "test_vertices": int(sum(p.n_vertices for p in test.parts)),
                "test_triangles": int(sum(p.n_triangles for p in test.parts)), "levels": rows})
    if keep_images:
        out["images"] = images
    return out


def evaluate(container, scene, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, resolution=RESOLUTION,
             keep_images: bool = False, camera_levels=None, variants=VARIANTS, samples: int = SAMPLES,
             ks: float | None = None, shininess: float | None = None, image_view: int | None = None,
             lod: int = LOD, distance_m: float | None = None, attributes: str = "container") -> dict:
    """Render ``container`` (a ``lopcook.lop.container.Container``) against its float ``scene``
    (``lopcook.types.Scene``, the source it was cooked from) and measure AP and CAP.

    Parameters
    ----------
    levels : per-buffer levels B to decode (default 6..12); each must be in the file.
    views : int N in [1, 20] (N icosahedron views spread over the 20) or a list of view indices.
    resolution : (width, height) pixels (default 1280 x 720).
    keep_images : also return images of one view at the coarsest level (``images`` below).
    camera_levels : None (camera at the distance of each level), one level for all, or one per level.
    variants : subset of ("ap", "cap") to render (the float source is always rendered).
    samples : MSAA samples (default 4). ks, shininess : override the manifest's Phong parameters.
    image_view : the view kept with ``keep_images`` (default: the view with the largest AP error,
        or CAP when AP is not rendered).
    lod : the container's LOD to render (default 0), always against the float **source** (LOD 0).
        A part with fewer LODs renders its last one (``lod_indices``). Every LOD is drawn with the
        container's own decoded attributes (normals, UVs, colours at their packed bits) and index
        buffer (``lopcook.lop.reader.lod_attributes``), and the source part's texture, so the
        PSNR counts attribute quantisation as well as positions'. Part IDs are part indices, so depth-order errors work at every LOD.
    distance_m : None (camera at each level's distance, see the module doc), or one camera
        distance in metres (eye to the nearest point of the source's bounding box) for every row;
        each row's ``camera_level`` is then the level the half-pixel criterion selects there.
    attributes : "container" (default: every LOD drawn with the container's own decoded normals,
        UVs and colours, as above) or "source": LOD 0 drawn with the source's attributes (permuted
        to the binned order, ``source_order``), so that only positions differ.

    Returns a JSON-ready dict (``images`` excepted):

    * ``container``, ``source`` (paths), ``lod`` (the LOD asked for), ``lods`` [per part, the LOD
      index rendered], ``lod_vertices`` (vertices of those buffers), ``resolution`` [w, h],
      ``samples``, ``views`` [indices], ``view_directions`` [[x, y, z]] (unit, scene centre to eye),
      ``viewing`` (the Viewing the distances use: render resolution, container fov and pixel error),
      ``grid_extent_m``, ``box_m`` [[lo], [hi]] (the scene's bounding box, metres),
      ``shading`` (Phong parameters), ``variants``, ``parts``, ``vertices``, ``float32_bytes``
      (12 bytes per vertex of LOD 0), ``device`` (GL renderer), ``seconds`` (upload, render,
      metrics, total).
    * ``levels``: one dict per level, in the order given:
      ``level`` (decode level B), ``camera_level``, ``camera_distance_m`` (eye to nearest box point),
      ``selected_level`` (``required_level`` at that distance: equals camera_level),
      ``eye_distance_m`` [per view] (eye to box centre), ``near_far_m`` [[near, far] per view],
      ``float_object_pixels`` [per view], ``float32_bytes``, and for each variant ``"ap"`` / ``"cap"``:

      - ``bytes``: GPU-resident position bytes at B over all parts of the rendered LOD
        (as ``lopcook.lop.summary.memory_rows`` counts LOD 0), ``percent_of_float32`` (of LOD 0's);
      - ``psnr_views`` [dB or None per view], ``psnr_min`` (min over views; None when every view is
        identical), ``psnr_mean`` (PSNR of the view-averaged MSE), ``psnr_pooled`` (PSNR of the
        squared errors pooled over all object pixels of all views); ``psnr_interior_min``,
        ``psnr_interior_mean``: the same over pixels fully covered in both images (shading error
        without coverage error, ``metrics.image_metrics``);
      - ``max_error`` (largest channel difference, [0, 1]), ``share_off`` (object pixels off by more
        than 1/255, pooled over views), ``pixels_off``, ``object_pixels`` (summed over views);
      - ``depth_order_errors`` (pixels, summed over views), ``depth_order_errors_views`` [per view],
        ``part_mismatch`` (pixels whose visible part differs, coverage included).

      PSNR, errors and pixel classes are defined in ``lopcook.verify.metrics``.
    * ``images`` (only with ``keep_images``; None if nothing was rendered): ``level`` (the coarsest),
      ``view``, ``float``, ``ap``, ``cap`` ((h, w, 4) uint8 RGBA, top row first, alpha = coverage),
      ``float_ids``, ``ap_ids``, ``cap_ids`` ((h, w) uint32 part index + 1, 0 = background),
      ``ap_heatmap``, ``cap_heatmap`` ((h, w, 3) uint8, ``metrics.difference_heatmap``, full scale
      0.25). Keys of variants not rendered are absent.

    Raises LopcookError: no EGL context (exit 2), levels not in the file, bad views or a LOD no
    part has (usage, exit 2), a source that does not match the container (exit 2).
    """
    with Harness(scene, resolution, samples) as h:
        return harness_evaluate(h, container, levels=levels, views=views, camera_levels=camera_levels,
                                variants=variants, ks=ks, shininess=shininess, keep_images=keep_images,
                                image_view=image_view, lod=lod, distance_m=distance_m, attributes=attributes)


def evaluate_scene(test_scene, scene, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, resolution=RESOLUTION,
                   samples: int = SAMPLES, **kw) -> dict:
    """``harness_evaluate_scene`` on a ``Harness(scene, resolution, samples)`` of its own: a
    float-position ``test_scene`` rendered against the float source ``scene`` with ``evaluate``'s
    cameras."""
    with Harness(scene, resolution, samples) as h:
        return harness_evaluate_scene(h, test_scene, levels=levels, views=views, **kw)


__all__ = ["evaluate", "evaluate_scene", "harness_evaluate", "harness_evaluate_scene", "parse_levels", "levels_in_file",
           "camera_rows", "render_rows", "summarise", "variant_key", "view_header"]
