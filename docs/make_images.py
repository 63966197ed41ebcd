"""Make the README's picture: a corpus asset with each vertex coloured by its minimum level.

This is the report's "minimum level per vertex" image (``lopcook report``, paper Fig. 7:
Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011), made by the same
functions: the asset is cooked with default settings (``lopcook.cook``), every vertex of LOD 0
gets its minimum level m_v read back from the container's bins on the report's blue-to-red
ramp (``lopcook.verify.baselines.level_scene``), and the render harness draws it with float
positions, diffuse shading only, from one of the 20 icosahedron views at the distance where the
object fills the frame. Under the render, a legend: one swatch per level from the lowest to the
highest level present, with the share of vertices at that level.

Usage, from the repository root (corpus at ../shared/corpus or $LOPCOOK_CORPUS)::

    .venv/bin/python docs/make_images.py                 # writes docs/img/levels_bunny.png
    .venv/bin/python docs/make_images.py SOURCE -o OUT.png [--view V] [--resolution WxH]

Deterministic: the same source, options and software (Mesa's llvmpipe, Pillow) give the same
PNG bytes.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

import lopcook
from lopcook.report.images import apply_crop, crop_box
from lopcook.report.svg import level_fill
from lopcook.tune.budget import frame_distance
from lopcook.verify.baselines import level_scene
from lopcook.verify.cameras import render_viewing
from lopcook.verify.evaluate import harness_evaluate_scene
from lopcook.verify.renderer import Harness, Shading

REPO = Path(__file__).resolve().parent.parent
#: the default asset, its view (icosahedron direction index, 0..19) and the render size (pixels)
DEFAULT_ASSET = "stanford-bunny.obj"
DEFAULT_VIEW = 0
DEFAULT_RESOLUTION = (1280, 960)
DEFAULT_OUT = REPO / "docs" / "img" / "levels_bunny.png"
#: legend geometry in pixels: swatch height, gap under the render, label band height
SWATCH_PX, GAP_PX, LABEL_PX = 18, 6, 30


def corpus_path(name: str) -> Path:
    """``name`` in the corpus: ``$LOPCOOK_CORPUS`` or ``../shared/corpus`` beside the repository."""
    root = Path(os.environ.get("LOPCOOK_CORPUS", REPO.parent / "shared" / "corpus"))
    return root / name


def level_render(source: Path, view: int, resolution: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Cook ``source`` with default settings and render its minimum levels.

    Returns (image, histogram): ``image`` (h, w, 4) uint8 RGBA, top row first, cropped to the
    object (alpha 0 = background); ``histogram`` (25,) int64 vertex counts of LOD 0 per level."""
    scene = lopcook.load(source)
    container = lopcook.cook(scene, lopcook.Settings())
    m = container.manifest
    hist = np.asarray(m["stats"]["histogram"], dtype=np.int64)
    present = [b for b, c in enumerate(hist) if c and b > 0]
    coloured, _, _ = level_scene(container, scene, present[0], present[-1])
    viewing = render_viewing(m, resolution)
    lo, hi = scene.bounds()
    with Harness(scene, resolution) as h:
        ev = harness_evaluate_scene(h, coloured, levels=[present[0]], views=[view], extent=float(m["grid"]["extent"]),
                                    viewing=viewing, shading=Shading(ks=0.0), keep_images=True, image_view=view,
                                    distance_m=frame_distance(lo, hi, viewing.fov_y_deg, resolution))
    rgba = ev["images"]["scene"]
    return apply_crop(rgba, crop_box({"scene": rgba})), hist


def with_legend(rgba: np.ndarray, hist: np.ndarray) -> Image.Image:
    """The render on white with a legend under it: one swatch per level from the lowest to the
    highest level in ``hist`` (the report's histogram colours, ``level_fill``), labelled with the level and, for the
    levels that hold vertices, their share in percent."""
    present = [b for b, c in enumerate(hist) if c and b > 0]
    lo, hi = present[0], present[-1]
    levels = range(lo, hi + 1)
    h, w = rgba.shape[:2]
    page = Image.new("RGB", (w, h + GAP_PX + SWATCH_PX + LABEL_PX), (255, 255, 255))
    page.paste(Image.fromarray(np.ascontiguousarray(rgba[..., :3])), (0, 0), Image.fromarray(rgba[..., 3]))
    draw, font = ImageDraw.Draw(page), ImageFont.load_default()
    step = w / len(levels)
    total = int(hist[1:].sum())
    for i, b in enumerate(levels):
        x0, x1 = round(i * step), round((i + 1) * step) - 1
        y0 = h + GAP_PX
        draw.rectangle([x0, y0, x1, y0 + SWATCH_PX - 1], fill=level_fill(b, lo, hi))
        pct = 100 * hist[b] / total
        share = "" if not hist[b] else ("<1%" if pct < 0.5 else f"{pct:.0f}%")
        draw.text(((x0 + x1) / 2, y0 + SWATCH_PX + 2), str(b), fill=(0, 0, 0), font=font, anchor="ma")
        draw.text(((x0 + x1) / 2, y0 + SWATCH_PX + 15), share, fill=(90, 90, 90), font=font, anchor="ma")
    return page


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="The README's minimum-level picture (paper Fig. 7).")
    ap.add_argument("source", nargs="?", help=f"scene to cook (default: the corpus {DEFAULT_ASSET})")
    ap.add_argument("-o", "--output", default=str(DEFAULT_OUT), help="PNG to write")
    ap.add_argument("--view", type=int, default=DEFAULT_VIEW, help="icosahedron view index, 0..19")
    ap.add_argument("--resolution", default="x".join(map(str, DEFAULT_RESOLUTION)), help="render size WxH")
    args = ap.parse_args(argv)
    source = Path(args.source) if args.source else corpus_path(DEFAULT_ASSET)
    resolution = tuple(int(v) for v in args.resolution.lower().split("x"))
    rgba, hist = level_render(source, args.view, resolution)
    with_legend(rgba, hist).save(args.output, format="PNG", optimize=False)
    print(f"{args.output}: {source.name}, view {args.view}, levels "
          + ", ".join(f"{b}: {int(c)}" for b, c in enumerate(hist) if c and b > 0))
    return 0


if __name__ == "__main__":
    sys.exit(main())
