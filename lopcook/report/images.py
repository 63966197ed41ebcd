"""Report images: one crop shared by every image of the shown view, nearest-neighbour enlargement,
PNG ``data:`` URIs.

Images are numpy arrays, top row first: RGBA ``(h, w, 4) uint8`` (alpha > 0 = object pixel), part-ID
``(h, w) uint32`` (0 = background), heat maps ``(h, w, 3) uint8``. At level 6 an object is some 37
pixels tall whatever the frame size (``lopcook.verify.cameras``), so small crops are enlarged by an
integer factor to stay legible; the box and factor are recorded in ``report.json`` (``images.crop``).
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
#: ... by at most this factor, and never beyond the frame's size
CROP_MAX_SCALE = 8


def crop_box(images: dict | None) -> dict | None:
    """The one crop shared by every image of a view: the box around the union of object pixels
    (alpha > 0 in any RGBA image, part ID > 0 in any ID image) plus a margin (``CROP_MARGIN_PX`` or
    ``CROP_MARGIN_FRACTION`` of the box's larger side), clipped to the frame, and the integer
    nearest-neighbour upscale factor: the largest that keeps the larger side at most ``CROP_TARGET_PX``
    and the image within the frame, at most ``CROP_MAX_SCALE``, at least 1.

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
    s = max(1, min(CROP_MAX_SCALE, CROP_TARGET_PX // max(cw, ch), w // cw, h // ch))
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


def png_data_uri(a: np.ndarray) -> str:
    """``a`` ((h, w) grey, (h, w, 3) RGB or (h, w, 4) RGBA uint8, top row first) as a
    ``data:image/png;base64,`` URI; the same array gives the same string."""
    from PIL import Image

    a = np.ascontiguousarray(np.asarray(a, dtype=np.uint8))
    mode = "L"
    if a.ndim == 3 and a.shape[2] == 3:
        mode = "RGB"
    elif a.ndim == 3 and a.shape[2] == 4:
        mode = "RGBA"
    buf = io.BytesIO()
    Image.fromarray(a, mode).save(buf, format="PNG", optimize=False)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


__all__ = ["CROP_MARGIN_PX", "CROP_MARGIN_FRACTION", "CROP_TARGET_PX", "CROP_MAX_SCALE", "crop_box", "apply_crop",
           "png_data_uri"]
