"""The GL pass of ``lopcook report``: every render the page shows, in one render harness.

Minimum levels (Meyer et al. 2011, Fig. 7): the source coloured by each vertex's minimum level,
rendered from the other images' view at the distance where the object fills the frame (image kind
``levels``, cropped on its own); the histogram bars use the same colours, so the histogram is its
legend.
"""

from __future__ import annotations


def render_for_report(container, scene, *, levels, views, resolution) -> tuple[dict, dict, tuple[int, int] | None]:
    """All renders of a report in one GL harness: ``evaluate`` of the container with images of one
    view at the coarsest level, the uniform 16-bit scene at the same cameras
    (``baselines.uniform_quantized_scene``), and the level-coloured source (``baselines.level_scene``)
    from the images' view at the frame distance (the object fills the frame: legible at any level;
    ``lopcook.tune.budget.frame_distance``), added to the images as ``levels`` (not cropped with them).
    Returns (evaluation, uniform16 evaluation, (lo, hi) of the level ramp or None)."""
    from ..tune.budget import frame_distance
    from ..verify.baselines import level_scene, uniform_quantized_scene
    from ..verify.cameras import render_viewing
    from ..verify.renderer import Harness, Shading

    m = container.manifest
    with Harness(scene, resolution) as h:
        ev = h.evaluate(container, levels=levels, views=views, keep_images=True)
        viewing = render_viewing(m, resolution)
        shading = Shading.from_manifest(m)
        extent = float(m["grid"]["extent"])
        u16 = h.evaluate_scene(uniform_quantized_scene(scene), levels=levels, views=views, extent=extent,
                               viewing=viewing, shading=shading)
        level_range = None
        imgs = ev.get("images")
        if imgs:
            hist = [b for b, c in enumerate(m["stats"]["histogram"]) if c and b > 0]
            coloured, lo, hi = level_scene(container, scene, hist[0], hist[-1])
            box = scene.bounds()
            lv = h.evaluate_scene(coloured, levels=[imgs["level"]], views=[imgs["view"]], extent=extent,
                                  viewing=viewing, shading=Shading(ks=0.0), keep_images=True,
                                  image_view=imgs["view"],
                                  distance_m=frame_distance(box[0], box[1], viewing.fov_y_deg, resolution))
            imgs["levels"] = lv["images"]["scene"]
            level_range = (lo, hi)
    return ev, u16, level_range


__all__ = ["render_for_report"]
