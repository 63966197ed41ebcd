"""Report images: one crop shared by every image of a level, nearest-neighbour enlargement, the
zoom window where the error is worst, the depth-order error mask, PNG ``data:`` URIs.

Images are numpy arrays, top row first: RGBA ``(h, w, 4) uint8`` (alpha > 0 = object pixel), part-ID
``(h, w) uint32`` (0 = background), heat maps ``(h, w, 3) uint8``. At level 6 an object is some 37
pixels tall whatever the frame size (``lopcook.verify.cameras``), so small crops are enlarged by an
integer factor until their larger side reaches ``CROP_TARGET_PX`` (at most ``CROP_MAX_SCALE``), even
beyond the frame's own size; the box and factor are recorded in ``report.json``
(``images.per_level[i].crop``).
"""

from __future__ import annotations

import base64
import io
import math

import numpy as np

#: report images are cropped to the object's box plus this margin (pixels, at least) ...
CROP_MARGIN_PX = 8
#: ... or this fraction of the box's larger side, whichever is larger
CROP_MARGIN_FRACTION = 0.1
#: small crops are upscaled (nearest neighbour, integer factor) until the larger side reaches this ...
CROP_TARGET_PX = 480
#: ... by at most this factor
CROP_MAX_SCALE = 8
#: the zoom window's side in frame pixels: a quarter of the crop's smaller side, clamped to this range ...
ZOOM_SIDE_PX = (16, 64)
#: ... shown enlarged (integer factor, at least 2) to about this many pixels
ZOOM_TARGET_PX = 256


def crop_box(images: dict | None) -> dict | None:
    """The one crop shared by every image of a view at one level: the box around the union of object
    pixels (alpha > 0 in any RGBA image, part ID > 0 in any ID image) plus a margin (``CROP_MARGIN_PX``
    or ``CROP_MARGIN_FRACTION`` of the box's larger side), clipped to the frame, and the integer
    nearest-neighbour upscale factor: the largest that keeps the larger side at most ``CROP_TARGET_PX``,
    at most ``CROP_MAX_SCALE``, at least 1 (a 48-pixel object is shown 8x, 384 pixels, whatever the
    frame size).

    Returns ``{"frame": [w, h], "box": [x0, y0, x1, y1]`` (pixels, top row 0, end exclusive),
    ``"scale": s, "size": [(x1 - x0) * s, (y1 - y0) * s]}``, or None without images. No object
    pixel anywhere: the whole frame at scale 1."""
    if not images:
        return None
    frames = [np.asarray(a) for k, a in images.items() if isinstance(a, np.ndarray) and a.ndim in (2, 3)]
    if not frames:
        return None
    h, w = frames[0].shape[:2]
    mask = np.zeros((h, w), dtype=bool)
    for a in frames:
        if a.shape[:2] != (h, w):
            continue
        if a.ndim == 3 and a.shape[2] == 4:
            mask |= a[..., 3] > 0
        elif a.ndim == 2:
            mask |= a > 0
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return {"frame": [int(w), int(h)], "box": [0, 0, int(w), int(h)], "scale": 1, "size": [int(w), int(h)]}
    y0, y1, x0, x1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    m = max(CROP_MARGIN_PX, int(math.ceil(CROP_MARGIN_FRACTION * max(x1 - x0, y1 - y0))))
    x0, y0, x1, y1 = max(0, x0 - m), max(0, y0 - m), min(w, x1 + m), min(h, y1 + m)
    cw, ch = x1 - x0, y1 - y0
    s = max(1, min(CROP_MAX_SCALE, CROP_TARGET_PX // max(cw, ch)))
    return {"frame": [int(w), int(h)], "box": [x0, y0, x1, y1], "scale": int(s), "size": [cw * s, ch * s]}


def apply_crop(a: np.ndarray, crop: dict | None) -> np.ndarray:
    """``a`` ((h, w) or (h, w, c), the frame's size) cut to ``crop["box"]`` and repeated
    ``crop["scale"]`` times along both axes (nearest neighbour)."""
    a = np.asarray(a)
    if not crop:
        return a
    x0, y0, x1, y1 = crop["box"]
    s = int(crop["scale"])
    a = a[y0:y1, x0:x1]
    return np.repeat(np.repeat(a, s, axis=0), s, axis=1) if s > 1 else a


def squared_error(reference: np.ndarray, test: np.ndarray) -> np.ndarray:
    """(h, w) float64: the squared RGB difference per pixel, summed over the three channels, in colour
    units (0..1) of two RGBA ``(h, w, 4) uint8`` renders; 0 where both are background (alpha 0). The
    per-pixel term of ``lopcook.verify.metrics.image_metrics``' ``sum_sq``."""
    ref, tst = np.asarray(reference), np.asarray(test)
    d = (ref[..., :3].astype(np.float64) - tst[..., :3].astype(np.float64)) / 255.0
    e = np.einsum("ijk,ijk->ij", d, d)
    e[(ref[..., 3] == 0) & (tst[..., 3] == 0)] = 0.0
    return e


def worst_window(error: np.ndarray, crop: dict) -> dict | None:
    """The square window of the frame where ``error`` ((h, w) per-pixel squared error, ``squared_error``)
    sums highest, inside ``crop["box"]``: side ``clamp(min(box side) // 4, *ZOOM_SIDE_PX)`` frame pixels
    (at most the box's smaller side), the first (top-most, then left-most) of equal sums, found with a
    summed-area table. Returns ``{"box": [x0, y0, x1, y1]`` (frame pixels, end exclusive), ``"scale"``
    (integer >= 2: about ``ZOOM_TARGET_PX`` shown), ``"size": [w, h]`` shown, ``"sum_sq"`` (the window's
    summed squared error), ``"share"`` (its share of the whole frame's error, 0..1)}``, or None when the
    error is zero everywhere."""
    err = np.asarray(error, dtype=np.float64)
    total = float(err.sum())
    if not total > 0.0:
        return None
    bx0, by0, bx1, by1 = crop["box"]
    bw, bh = bx1 - bx0, by1 - by0
    side = int(min(max(min(bw, bh) // 4, ZOOM_SIDE_PX[0]), ZOOM_SIDE_PX[1], bw, bh))
    sub = err[by0:by1, bx0:bx1]
    sat = np.zeros((bh + 1, bw + 1))
    sat[1:, 1:] = sub.cumsum(axis=0).cumsum(axis=1)
    sums = sat[side:, side:] - sat[:-side, side:] - sat[side:, :-side] + sat[:-side, :-side]
    iy, ix = np.unravel_index(int(np.argmax(sums)), sums.shape)
    x0, y0 = bx0 + int(ix), by0 + int(iy)
    s = max(2, ZOOM_TARGET_PX // side)
    best = float(err[y0:y0 + side, x0:x0 + side].sum())
    return {"box": [x0, y0, x0 + side, y0 + side], "scale": int(s), "size": [side * s, side * s],
            "sum_sq": best, "share": min(1.0, best / total)}


def depth_overlay(rgba: np.ndarray, mask: np.ndarray, colour=(255, 0, 255)) -> np.ndarray:
    """(h, w, 3) uint8: ``rgba`` (the float render) greyed and darkened, on white where it is background,
    with the ``mask`` pixels in ``colour`` (magenta): where the depth-order errors are."""
    a = np.asarray(rgba)
    grey = (a[..., :3].astype(np.float64) @ np.array([0.299, 0.587, 0.114])) * 0.6 + 60.0
    out = np.repeat(np.clip(grey, 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    out[a[..., 3] == 0] = 255
    out[np.asarray(mask, dtype=bool)] = np.asarray(colour, dtype=np.uint8)
    return out


def png_data_uri(a: np.ndarray) -> str:
    """``a`` ((h, w) grey, (h, w, 3) RGB or (h, w, 4) RGBA uint8, top row first) as a
    ``data:image/png;base64,`` URI; the same array gives the same string."""
    from PIL import Image  # Pillow loads only when a page embeds an image

    a = np.ascontiguousarray(np.asarray(a, dtype=np.uint8))
    mode = "L"
    if a.ndim == 3 and a.shape[2] == 3:
        mode = "RGB"
    elif a.ndim == 3 and a.shape[2] == 4:
        mode = "RGBA"
    buf = io.BytesIO()
    Image.fromarray(a, mode).save(buf, format="PNG", optimize=False)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


__all__ = ["CROP_MARGIN_PX", "CROP_MARGIN_FRACTION", "CROP_TARGET_PX", "CROP_MAX_SCALE", "ZOOM_SIDE_PX",
           "ZOOM_TARGET_PX", "crop_box", "apply_crop", "squared_error", "worst_window",
           "depth_overlay", "png_data_uri"]
