"""The GL pass of ``lopcook report``: every render the page shows, in one render harness.

* **Every level**: the container is evaluated one level at a time (``harness_evaluate`` with one
  level; the rows are those of one evaluation over all levels), keeping the images of one view at
  each level, the same view at every level so a reader compares like with like: the view that
  shows the most parts at the coarsest level (distinct part IDs in its float render: a chess set
  seen from above, not from under the board), among those the one with the largest AP error
  (``choose_view``).
* **Depth order**: the (level, view) with the most depth-order errors (CAP, else AP) is rendered
  again with its part-ID images when it is not the images' view, so the page can show where they are.
* **Uniform 16-bit** baseline at the same cameras, one level at a time, right after the container's
  evaluation at that level: both (and the view choice's part count) use that level's float renders
  once (``Harness`` float cache, emptied after each level: at most one level's views are held).
* **Minimum levels** (Meyer et al. 2011, Fig. 7): the source coloured by each vertex's minimum level,
  rendered from the images' view at the distance where the object fills the frame (image kind
  ``levels``, cropped on its own); the histogram bars use the same colours.

Progress: one ``render`` stage (``lopcook.progress``) counting evaluations: one per level for the
container, one per level for the 16-bit baseline, one for the depth-order view, one for the level
image.
"""

from __future__ import annotations

import zlib

import numpy as np

from ..progress import NONE
from ..verify.evaluate import harness_evaluate, harness_evaluate_scene

#: the float-render cache's uncompressed share in the report's harness (the rest zlib-compressed:
#: about 2 ms per megabyte to expand; ``lopcook.verify.renderer.Harness``)
REPORT_RAW_BYTES = 16 << 20

#: the report's draws finish the GL queue after this many triangles (``Renderer.finish_triangles``;
#: the default is 2^18): fewer, larger batches for llvmpipe's rasteriser cost time less, and the
#: binned scene (about 140 bytes a triangle) fits beside the report's other memory now that the
#: levels' images are kept compressed (docs/performance.md)
REPORT_FINISH_TRIANGLES = 1 << 20


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


def choose_view(visible: list[int], ap_psnr: list, worst: int) -> int:
    """Index (into the rendered views) of the view the report shows: among the views whose float
    render shows the most distinct parts (``visible``, per view), the one with the lowest AP PSNR
    (``ap_psnr``, per view; None = identical = last), the first on ties; ``worst`` (the view with
    the largest AP squared error, ``evaluate``'s own choice) when it is among them."""
    most = max(visible)
    best = [i for i, n in enumerate(visible) if n == most]
    if worst in best:
        return worst
    return min(best, key=lambda i: (float("inf") if ap_psnr[i] is None else ap_psnr[i], i))


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


def render_for_report(container, scene, *, levels, views, resolution,
                      progress=NONE) -> tuple[dict, dict, tuple[int, int] | None]:
    """All renders of a report in one GL harness (module doc). Returns (evaluation, uniform16
    evaluation, (lo, hi) of the level ramp or None).

    The evaluation is that of ``harness_evaluate(h, container, levels=levels, views=views)`` (rows in the
    order of ``levels``) with ``images``: the coarsest level's images (``level``, ``view``, ``float``,
    ``ap``, ``cap``, heat maps, ID images, as ``evaluate``'s ``keep_images``), plus ``per_level`` (the
    same dict for every level, in row order), ``depth`` (None, or ``{"level", "view", "variant",
    "errors", "images"}``: the images of the view with the most depth-order errors, ``depth_target``)
    ``levels`` (the minimum-level image) and ``view_parts`` (parts seen per rendered view at the
    coarsest level, or None when not counted: one part or one view). ``progress``: a ``lopcook.progress.Progress``."""
    from ..tune.budget import frame_distance
    from ..verify.baselines import level_scene, uniform_quantized_scene
    from ..verify.cameras import render_viewing, select_views
    from ..verify.renderer import Harness, Shading, trim_heap

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
            progress.stage("render", total=2 * len(order) + 2) as st:
        h.renderer.finish_triangles = REPORT_FINISH_TRIANGLES
        h.keep_attributes = True  # the container's attributes are uploaded once, not once per level
        h.share_culls(u16_scene)  # the baseline draws the float renders' coverage culls

        def baseline(b: int) -> None:
            u16_parts.append(harness_evaluate_scene(h, u16_scene, levels=[b], views=views, extent=extent,
                                                    viewing=viewing, shading=shading))
            h.clear_float_cache()
            st.advance()

        first = harness_evaluate(h, container, levels=[order[0]], views=views, keep_images=True)
        parts = [first]
        imgs = first.get("images")
        image_view = imgs["view"] if imgs else None
        visible = None
        if imgs and len(scene.parts) > 1 and len(view_ids) > 1:
            from ..verify.cameras import make_camera

            row = first["levels"][0]
            viewing0 = render_viewing(m, resolution)
            shading0 = Shading.from_manifest(m)
            cams = [make_camera(v, h.lo, h.hi, row["camera_distance_m"], viewing0) for v in view_ids]
            visible = [int(np.unique(h.render_float(cam, shading0, key=(cam.mvp.tobytes(), cam.eye.tobytes(),
                                                                         shading0))[1]).size) for cam in cams]
            pick = view_ids[choose_view(visible, row["ap"]["psnr_views"] if "ap" in row else [None] * len(view_ids),
                                        view_ids.index(image_view))]
            if pick != image_view:
                image_view = pick
                imgs = harness_evaluate(h, container, levels=[order[0]], views=[pick], keep_images=True,
                                  image_view=pick)["images"]
                first = dict(first, images=imgs)
                parts = [first]
        st.advance()
        baseline(order[0])
        imgs = compact_ids(imgs)
        if imgs is not None:
            first["images"] = imgs  # parts[0] is first: the uint32 IDs are not kept alongside
        per_level = {order[0]: imgs}
        for b in order[1:]:
            e = harness_evaluate(h, container, levels=[b], views=views, keep_images=True, image_view=image_view)
            # kept compressed until the renders end (the first level's stay as they are: choose_view
            # and the page's crops read them); the evaluation itself keeps none
            per_level[b] = pack_images(compact_ids(e.pop("images", None)))
            e["images"] = None
            parts.append(e)
            st.advance()
            baseline(b)
        ev = _merge(parts, levels)
        u16 = _merge(u16_parts, levels)
        level_range = None
        if imgs:
            imgs = dict(imgs)
            imgs["per_level"] = None  # (every level's, once the renders are done: below)
            imgs["view_parts"] = None if visible is None else [n - 1 for n in visible]  # background is not a part
            target = depth_target(ev["levels"])
            imgs["depth"] = None
            if target is not None:
                lv, vi, variant, n = target
                vid = view_ids[vi]
                if vid == image_view:
                    dimgs = None  # that level's kept images (below)
                else:
                    dimgs = harness_evaluate(h, container, levels=[lv], views=[vid], keep_images=True,
                                       image_view=vid)["images"]
                imgs["depth"] = {"level": lv, "view": int(vid), "variant": variant, "errors": n, "images": dimgs}
            st.advance()
            hist = [b for b, c in enumerate(m["stats"]["histogram"]) if c and b > 0]
            coloured, lo, hi = level_scene(container, scene, hist[0], hist[-1])
            box = scene.bounds()
            lv_ev = harness_evaluate_scene(h, coloured, levels=[imgs["level"]], views=[imgs["view"]], extent=extent,
                                     viewing=viewing, shading=Shading(ks=0.0), keep_images=True,
                                     image_view=imgs["view"],
                                     distance_m=frame_distance(box[0], box[1], viewing.fov_y_deg, resolution))
            imgs["levels"] = lv_ev["images"]["scene"]
            level_range = (lo, hi)
            ev["images"] = imgs
            st.advance()
        else:
            st.advance(2)
    trim_heap()  # the harness's GL buffers and llvmpipe's scenes, freed: back to the system first
    if ev.get("images"):
        # the harness is gone (llvmpipe's memory with it): every level's images as arrays again
        kept = {b: unpack_images(x) for b, x in per_level.items()}
        ev["images"]["per_level"] = [kept[int(b)] for b in levels]
        depth = ev["images"]["depth"]
        if depth is not None and depth["images"] is None:
            depth["images"] = kept[depth["level"]]
    return ev, u16, level_range


__all__ = ["render_for_report", "depth_target", "choose_view"]
