"""The GL pass of ``lopcook report``: every render the page shows, in one render harness.

* **Every level**: the container is evaluated one level at a time (``harness_evaluate`` with one
  level; the rows are those of one evaluation over all levels), keeping the images of one view at
  each level, the same view at every level so a reader compares like with like: a view a person
  recognises (``choose_view``): a front or three-quarter view (the eye at most 45 degrees above the
  horizon, never below it, on the +Z side: glTF's front), the one with the largest projected area
  at the coarsest level, after the most parts seen (a chess set shows its pieces).
* **The worst view**: the (level, view) with the lowest CAP PSNR (``lopcook.report.verdict``),
  rendered again with its images when it is not the shown view at that level; its largest share of
  squared error names the worst part.
* **Every LOD** at its selection distance (``lod_plan``), LOD 0 where the object fills the frame or,
  when nearer, where LOD 1 takes over: CAP against the float source, one view (the shown one).
* **Depth order**: the (level, view) with the most depth-order errors (CAP, else AP) is rendered
  again with its part-ID images when it is not the images' view, so the page can show where they are.
* **Uniform 16-bit** baseline at the same cameras, one level at a time, right after the container's
  evaluation at that level: both (and the view choice's part count) use that level's float renders
  once (``Harness`` float cache, emptied after each level: at most one level's views are held).
* **Minimum levels** (Meyer et al. 2011, Fig. 7): the source coloured by each vertex's minimum level,
  rendered from the images' view at the distance where the object fills the frame (image kind
  ``levels``, cropped on its own); the histogram bars use the same colours.

Progress: one ``render`` stage (``lopcook.progress``) counting evaluations: one per level for the
container, one per level for the 16-bit baseline, then one each for the worst view, the LOD
renders, the depth-order view and the level image.
"""

from __future__ import annotations

import math
import zlib

import numpy as np

from ..progress import NONE
from ..tune.budget import frame_distance
from ..verify.baselines import level_scene, uniform_quantized_scene
from ..verify.cameras import icosahedron_directions, make_camera, render_viewing, select_views
from ..verify.renderer import Harness, Shading, trim_heap
from ..viewing import required_level
from ..verify.evaluate import harness_evaluate, harness_evaluate_scene
from .verdict import worst_part, worst_view

#: the float-render cache's uncompressed share in the report's harness (the rest zlib-compressed:
#: about 2 ms per megabyte to expand; ``lopcook.verify.renderer.Harness``)
REPORT_RAW_BYTES = 16 << 20

#: the report's draws finish the GL queue after this many triangles (``Renderer.finish_triangles``;
#: the default is 2^18): fewer, larger batches for llvmpipe's rasteriser cost time less, and the
#: binned scene (about 140 bytes a triangle) fits beside the report's other memory now that the
#: levels' images are kept compressed (docs/performance.md)
REPORT_FINISH_TRIANGLES = 1 << 20

#: a view a person recognises looks from at most this many degrees above the horizon (+Y up) and
#: never from below it (``choose_view``)
MAX_ELEVATION_DEG = 45.0

#: LOD 0 is rendered this much (relative) short of where the next LOD takes over (``lod_plan``)
LOD0_MARGIN = 2.0**-20


def _merge(parts: list[dict], levels: list[int]) -> dict:
    """One evaluation from single-level evaluations ``parts`` (coarsest first): the rows in the order
    of ``levels``, per-stage seconds summed, the rest from the first."""
    ev = dict(parts[0])
    by_level = {p["levels"][0]["level"]: p["levels"][0] for p in parts}
    ev["levels"] = [by_level[int(b)] for b in levels]
    secs: dict = {}
    for p in parts:
        for k, v in (p.get("seconds") or {}).items():
            secs[k] = round(secs.get(k, 0.0) + v, 4)
    ev["seconds"] = secs
    return ev


def depth_target(rows: list[dict]) -> tuple[int, int, str, int] | None:
    """(level, view, variant, errors) of the rendered view with the most depth-order error pixels:
    CAP's worst (level, view) when CAP has any, else AP's; the first of equal counts (levels in
    ``rows`` order, views in render order). None when no view of any level has one. ``rows``: the
    evaluation's ``levels`` (each variant with ``depth_order_errors_views``), views ``views``."""
    for variant in ("cap", "ap"):
        best = None
        for r in rows:
            v = r.get(variant)
            if not v:
                continue
            for i, n in enumerate(v["depth_order_errors_views"]):
                if n > 0 and (best is None or n > best[3]):
                    best = (int(r["level"]), i, variant, int(n))
        if best is not None:
            return best
    return None


def view_angles(view_ids) -> list[tuple[float, float]]:
    """Per icosahedron view (``lopcook.verify.cameras.icosahedron_directions``): (elevation, azimuth)
    in degrees of the eye seen from the scene centre; elevation above the XZ plane (+Y up), azimuth
    from +Z (the front of a glTF asset) towards +X."""
    d = icosahedron_directions()
    return [(math.degrees(math.asin(max(-1.0, min(1.0, float(d[v][1]))))),
             math.degrees(math.atan2(float(d[v][0]), float(d[v][2])))) for v in view_ids]


def choose_view(angles: list, pixels: list, visible: list | None = None) -> int:
    """Index (into the rendered views) of the view the report shows first: a view a person recognises.

    Candidates, the first non-empty of: front or three-quarter views (elevation in [0,
    ``MAX_ELEVATION_DEG``], azimuth within 90 degrees of +Z), views at such an elevation from any
    side, views from above, every view. Among them the views seeing the most distinct parts
    (``visible``, per view; None: not counted), then the largest projected area (``pixels``: object
    pixels of the float render per view at the coarsest level), the first on ties. ``angles``:
    (elevation, azimuth) degrees per view (``view_angles``)."""
    n = len(angles)
    tiers = ([i for i, (e, a) in enumerate(angles) if 0.0 <= e <= MAX_ELEVATION_DEG and abs(a) < 90.0],
             [i for i, (e, _) in enumerate(angles) if 0.0 <= e <= MAX_ELEVATION_DEG],
             [i for i, (e, _) in enumerate(angles) if e >= 0.0], list(range(n)))
    cand = next(t for t in tiers if t)
    if visible is not None:
        most = max(visible[i] for i in cand)
        cand = [i for i in cand if visible[i] == most]
    return max(cand, key=lambda i: (int(pixels[i]), -i))


def compact_ids(images: dict | None) -> dict | None:
    """``images`` with every part-ID image (keys ending ``_ids``) in the smallest unsigned dtype that
    holds its values (uint8 below 256 parts): the same values, a quarter of the memory of the
    renderer's uint32 for the report's seven levels of kept images."""
    if not images:
        return images
    out = dict(images)
    for k, a in images.items():
        if k.endswith("_ids") and isinstance(a, np.ndarray) and a.size:
            top = int(a.max())
            dt = np.uint8 if top < 1 << 8 else np.uint16 if top < 1 << 16 else None
            if dt is not None:
                out[k] = a.astype(dt)
    return out


class _Packed:
    """One kept image, zlib-compressed while later levels render (``render_for_report``): the page
    needs every level's images, but only after the renders, when llvmpipe's memory is back."""

    __slots__ = ("shape", "dtype", "data")

    def __init__(self, a: np.ndarray):
        a = np.ascontiguousarray(a)
        self.shape, self.dtype, self.data = a.shape, a.dtype, zlib.compress(a.tobytes(), 1)

    def array(self) -> np.ndarray:
        return np.frombuffer(zlib.decompress(self.data), self.dtype).reshape(self.shape).copy()


def pack_images(images: dict | None) -> dict | None:
    """``images`` with every array compressed (``_Packed``); ``unpack_images`` gives them back."""
    if not images:
        return images
    return {k: _Packed(v) if isinstance(v, np.ndarray) else v for k, v in images.items()}


def unpack_images(images: dict | None) -> dict | None:
    """The arrays ``pack_images`` compressed, as they were (the same values, dtypes and shapes)."""
    if not images:
        return images
    return {k: v.array() if isinstance(v, _Packed) else v for k, v in images.items()}


def lod_plan(manifest: dict, resolution, frame_m: float, available: int | None = None) -> list[dict]:
    """Where each LOD index of a container is rendered: per k in 0..(longest chain - 1),
    ``{"lod", "selection_distance_m", "distance_m", "level"}``.

    ``selection_distance_m``: the smallest camera distance at which ``lopcook.selection.select`` picks
    LOD k for some part (its ``min_distance_m`` under the container's viewing); None for LOD 0 (its
    range starts at 0 m) and for a LOD no distance selects (not rendered: ``distance_m`` None).
    ``distance_m``: the render's camera distance, metres from the bounding box: the selection
    distance times render height / the container's viewport height, so that the LOD covers the
    pixels it covers when selected in the container's viewport; for LOD 0 ``frame_m`` (the object
    fills the frame), or, when nearer, just short of where the next LOD rendered takes over (LOD 0
    is never seen farther). ``level``: the per-buffer level the half-pixel criterion selects at
    that distance under the render's viewing, clamped to the file's levels (``available``, default
    the manifest's ``positions.max_level``: a file cut short holds fewer)."""
    viewing = render_viewing(manifest, resolution)
    height = int((manifest.get("viewing") or {}).get("viewport", [0, resolution[1]])[1]) or int(resolution[1])
    extent = float(manifest["grid"]["extent"])
    top = max(1, int(available if available is not None else manifest["positions"].get("max_level", 24)))
    deepest = max(len(p["lods"]) for p in manifest["parts"])
    out = []
    for k in range(deepest):
        sel = None
        if k > 0:
            starts = [p["lods"][k].get("min_distance_m") for p in manifest["parts"] if len(p["lods"]) > k]
            starts = [float(s) for s in starts if s is not None]
            sel = min(starts) if starts else None
        d = None if sel is None else sel * int(resolution[1]) / height
        out.append({"lod": k, "selection_distance_m": sel, "distance_m": d, "level": None})
    later = [p["distance_m"] for p in out[1:] if p["distance_m"] is not None]
    out[0]["distance_m"] = min([frame_m] + [d * (1.0 - LOD0_MARGIN) for d in later[:1]])
    for p in out:
        if p["distance_m"] is not None:
            p["level"] = int(min(top, max(1, int(np.asarray(required_level(p["distance_m"], extent, viewing))))))
    return out


def _first_level(h, c, scene, level, views, view_ids, resolution):
    """The coarsest level's evaluation with the images of the view ``choose_view`` picks (rendered
    again when it is not the evaluation's own image view), and the view record: ``visible`` (parts
    seen per view, None when not counted: one part or one view), ``pixels`` and ``angles`` per view."""
    first = harness_evaluate(h, c, levels=[level], views=views, keep_images=True)
    imgs = first.get("images")
    row = first["levels"][0]
    record = {"pixels": [int(x) for x in row["float_object_pixels"]], "angles": view_angles(view_ids),
              "visible": None}
    if not imgs:
        return first, record
    if len(scene.parts) > 1 and len(view_ids) > 1:
        viewing, shading = render_viewing(c.manifest, resolution), Shading.from_manifest(c.manifest)
        cams = [make_camera(v, h.lo, h.hi, row["camera_distance_m"], viewing) for v in view_ids]
        record["visible"] = [int(np.unique(h.render_float(cam, shading, key=(cam.mvp.tobytes(), cam.eye.tobytes(),
                                                                             shading))[1]).size) for cam in cams]
    pick = view_ids[choose_view(record["angles"], record["pixels"], record["visible"])]
    if pick != imgs["view"]:
        imgs = harness_evaluate(h, c, levels=[level], views=[pick], keep_images=True, image_view=pick)["images"]
        first = dict(first, images=imgs)
    return first, record


def _extra_view(h, c, level: int, view: int, kept: dict) -> dict:
    """The images of ``view`` at ``level``: ``kept`` (the shown view's images per level, packed) when
    it is that view, else rendered again (one view, kept packed)."""
    mine = kept.get(level)
    if mine is not None and (mine.get("view") == view):
        return mine
    return pack_images(compact_ids(harness_evaluate(h, c, levels=[level], views=[view], keep_images=True,
                                              image_view=view)["images"]))


def _lod_renders(h, c, scene, view: int, resolution) -> list[dict]:
    """Every LOD of ``lod_plan`` rendered (CAP against the float source, the shown ``view``): per
    LOD the plan's record plus ``psnr`` (dB, None: identical), ``object_pixels`` (the float render's)
    and ``images`` (packed), or ``images`` None for a LOD no distance selects."""
    lo, hi = scene.bounds()
    fov = float((c.manifest.get("viewing") or {}).get("fov_y_deg", 60.0))
    out = []
    for p in lod_plan(c.manifest, resolution, frame_distance(lo, hi, fov, resolution), c.available_level):
        rec = dict(p, psnr=None, object_pixels=None, images=None)
        if p["distance_m"] is not None:
            e = harness_evaluate(h, c, levels=[p["level"]], views=[view], variants=("cap",), keep_images=True,
                           image_view=view, lod=p["lod"], distance_m=p["distance_m"])
            row = e["levels"][0]
            rec.update(psnr=row["cap"]["psnr_views"][0], object_pixels=int(row["float_object_pixels"][0]),
                       images=pack_images(compact_ids(e.get("images"))))
            h.clear_float_cache()
        out.append(rec)
    return out


def _level_image(h, c, scene, imgs, viewing, extent, resolution):
    """The minimum-level image (Fig. 7) from the shown view at the frame distance, and its ramp (lo, hi)."""
    hist = [b for b, n in enumerate(c.manifest["stats"]["histogram"]) if n and b > 0]
    coloured, lo, hi = level_scene(c, scene, hist[0], hist[-1])
    box = scene.bounds()
    ev = harness_evaluate_scene(h, coloured, levels=[imgs["level"]], views=[imgs["view"]], extent=extent, viewing=viewing,
                          shading=Shading(ks=0.0), keep_images=True, image_view=imgs["view"],
                          distance_m=frame_distance(box[0], box[1], viewing.fov_y_deg, resolution))
    return ev["images"]["scene"], (lo, hi)


def _extras(h, c, scene, imgs: dict, rows: list, view_ids: list, per_level: dict, resolution, st):
    """The renders after the levels', into ``imgs``: the worst view (``worst``), every LOD
    (``lods``), the depth-order view (``depth``) and the level image (``levels``), one progress step
    each. Returns the level image's ramp (lo, hi)."""
    worst = worst_view(rows, view_ids)
    imgs["worst"] = None if worst is None else dict(
        worst, images=_extra_view(h, c, worst["level"], worst["view"], per_level))
    h.clear_float_cache()
    st.advance()
    imgs["lods"] = _lod_renders(h, c, scene, imgs["view"], resolution)
    st.advance()
    target = depth_target(rows)
    imgs["depth"] = None
    if target is not None:
        lv, vi, variant, n = target
        imgs["depth"] = {"level": lv, "view": int(view_ids[vi]), "variant": variant, "errors": n,
                         "images": _extra_view(h, c, lv, int(view_ids[vi]), per_level)}
    st.advance()
    viewing = render_viewing(c.manifest, resolution)
    imgs["levels"], ramp = _level_image(h, c, scene, imgs, viewing, float(c.manifest["grid"]["extent"]), resolution)
    st.advance()
    return ramp


def render_for_report(container, scene, *, levels, views, resolution,
                      progress=NONE) -> tuple[dict, dict, tuple[int, int] | None]:
    """All renders of a report in one GL harness (module doc). Returns (evaluation, uniform16
    evaluation, (lo, hi) of the level ramp or None).

    The evaluation is that of ``harness_evaluate(h, container, levels=levels, views=views)`` (rows in the
    order of ``levels``) with ``images``: the coarsest level's images of the shown view (``level``,
    ``view``, ``float``, ``ap``, ``cap``, heat maps, ID images, as ``evaluate``'s ``keep_images``),
    plus ``per_level`` (the same dict for every level, in row order), ``worst`` (None, or ``{"level",
    "view", "psnr", "part", "images"}``: the lowest CAP PSNR, ``verdict.worst_view``; ``part``:
    ``verdict.worst_part``), ``lods`` (``_lod_renders``), ``depth`` (None, or ``{"level", "view",
    "variant", "errors", "images"}``: the view with the most depth-order errors, ``depth_target``),
    ``levels`` (the minimum-level image), ``view_parts`` (parts seen per rendered view at the
    coarsest level, or None when not counted: one part or one view), ``view_pixels`` and
    ``view_angles`` (per rendered view: object pixels at the coarsest level, (elevation, azimuth)
    degrees). ``progress``: a ``lopcook.progress.Progress``."""
    m = container.manifest
    order = sorted(int(b) for b in levels)
    view_ids = select_views(views)
    viewing = render_viewing(m, resolution)
    shading = Shading.from_manifest(m)
    extent = float(m["grid"]["extent"])
    u16_scene = uniform_quantized_scene(scene)
    u16_parts = []
    # one level at a time: the container and the uniform 16-bit baseline share that level's float
    # renders (the same cameras and shading: the cache gives the same arrays a fresh render would),
    # and the cache holds one level's views only
    # (a level's float renders are read twice, so all but the first REPORT_RAW_BYTES are kept
    # compressed: the close-up levels of a large scene fill the frame, some 5 MB a view)
    with Harness(scene, resolution, cache_float=True, raw_bytes=REPORT_RAW_BYTES) as h, \
            progress.stage("render", total=2 * len(order) + 4) as st:
        h.renderer.finish_triangles = REPORT_FINISH_TRIANGLES
        h.keep_attributes = True  # the container's attributes are uploaded once, not once per level
        h.share_culls(u16_scene)  # the baseline draws the float renders' coverage culls

        def baseline(b: int) -> None:
            u16_parts.append(harness_evaluate_scene(h, u16_scene, levels=[b], views=views, extent=extent,
                                                    viewing=viewing, shading=shading))
            h.clear_float_cache()
            st.advance()

        first, record = _first_level(h, container, scene, order[0], views, view_ids, resolution)
        parts = [first]
        imgs = compact_ids(first.get("images"))
        first["images"] = imgs  # parts[0] is first: the uint32 IDs are not kept alongside
        st.advance()
        baseline(order[0])
        per_level = {order[0]: pack_images(imgs)}
        for b in order[1:]:
            e = harness_evaluate(h, container, levels=[b], views=views, keep_images=True, image_view=imgs and imgs["view"])
            # kept compressed until the renders end; the evaluation itself keeps none
            per_level[b] = pack_images(compact_ids(e.pop("images", None)))
            e["images"] = None
            parts.append(e)
            st.advance()
            baseline(b)
        ev = _merge(parts, levels)
        u16 = _merge(u16_parts, levels)
        level_range = None
        if imgs:
            imgs = dict(imgs, per_level=None, view_parts=None if record["visible"] is None else
                        [n - 1 for n in record["visible"]],  # the background is not a part
                        view_pixels=record["pixels"], view_angles=[list(a) for a in record["angles"]])
            level_range = _extras(h, container, scene, imgs, ev["levels"], view_ids, per_level, resolution, st)
            ev["images"] = imgs
        else:
            st.advance(4)
    trim_heap()  # the harness's GL buffers and llvmpipe's scenes, freed: back to the system first
    if ev.get("images"):
        _unpack_all(ev["images"], per_level, levels, [p.name for p in scene.parts])
    return ev, u16, level_range


def _unpack_all(images: dict, per_level: dict, levels, names: list[str]) -> None:
    """Once the harness is gone (llvmpipe's memory with it): every kept image as arrays again, in
    place, and the worst view's part (``verdict.worst_part``)."""
    kept = {b: unpack_images(x) for b, x in per_level.items()}
    images["per_level"] = [kept[int(b)] for b in levels]
    for key in ("depth", "worst"):
        d = images.get(key)
        if d is not None:
            d["images"] = unpack_images(d["images"])
    for rec in images.get("lods") or []:
        rec["images"] = unpack_images(rec["images"])
    w = images.get("worst")
    if w is not None:
        w["part"] = worst_part(w["images"], names)


__all__ = ["render_for_report", "depth_target", "choose_view", "view_angles", "lod_plan", "MAX_ELEVATION_DEG"]
