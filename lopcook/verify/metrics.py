"""Image metrics of the render harness: PSNR over object pixels, max error, share of pixels off,
depth-order errors from part-ID images, and difference heatmaps.

This work is based on: Purnomo et al., "Hardware-Compatible Vertex Compression Using Quantization and
Simplification", Graphics Hardware 2005, section 4.1 (image-space error over 20 views; pixels that are
background in both renderings are excluded), and Meyer et al., "Adaptive Level-of-Precision for
GPU-Rendering", VMV 2011, section 7.3 (PSNR and heat maps of AP and CAP against floating-point vertices)
and section 3 (coverage, attribute and depth errors).

Inputs (what ``lopcook.verify.renderer`` reads back):

* colour images: ``(h, w, 4) uint8`` RGBA, the MSAA-resolved 8-bit framebuffer. RGB is the shaded
  colour in [0, 1] (code / 255) over a black background; A is the pixel's coverage (0 where no
  sample saw the object, 255 where all did; the background is cleared to alpha 0). A pixel is an
  **object pixel** of an image when its alpha is > 0.
* part-ID images: ``(h, w) uint32``, 0 for background, ``part index + 1`` otherwise (MSAA sample 0
  of the pixel, see ``lopcook.verify.renderer``).

Definitions (all colour values in [0, 1], i.e. 8-bit code / 255):

* object pixels of a pair: pixels that are object in *either* image (background in both excluded).
* ``mse``: mean over the object pixels and the three colour channels of ``(a - b)^2``.
* ``psnr``: ``10 log10(1 / mse)`` dB (peak 1.0). Identical images (mse 0), or no object pixel at all,
  give ``None`` (JSON ``null``; printed as ``inf``): PSNR is infinite, and ``None`` keeps the JSON
  valid. ``psnr_from_mse`` is the single place this is decided.
* ``max_error``: largest absolute channel difference over all pixels, in [0, 1].
* ``share_off``: fraction of object pixels whose largest channel difference exceeds 1/255 (2+ codes off).
* ``psnr_interior``: the same PSNR over the pixels fully covered (alpha 255) in both images only:
  coverage error against the background (silhouettes, holes) is left out; what remains is shading
  (attribute) error, the error k_f controls, plus occlusion edges between surfaces inside the
  object. Extra data for reports; thresholds use ``psnr``.
* ``depth_order_errors``: pixels where both images show some part, the parts differ, and the 3x3
  neighbourhood of the pixel in the *reference* ID image shows that one part only. A vertex decoded
  at the half-pixel level moves by at most half a pixel, so a coverage change (silhouettes, one
  part's outline over another) stays within one pixel of a part boundary of the reference: such
  pixels are coverage, not depth order, and are left out (they appear in ``part_mismatch``). What
  remains is a part seen through (or hidden behind) another away from any boundary: the z order
  changed (Meyer et al., Fig. 8). Depth order inside one part is not measured (same ID).
* ``part_mismatch``: every pixel covered in both images whose part differs (coverage + depth order).
"""

from __future__ import annotations

import math

import numpy as np

OFF_THRESHOLD = 1.0 / 255.0  # "off by more than one 8-bit step"
HEATMAP_VMAX = 0.25  # default full scale of heatmaps: 0.25 colour units (64 codes) or more is white


def psnr_from_mse(mse: float) -> float | None:
    """``10 log10(1 / mse)`` dB (peak 1.0); None for mse == 0 (identical: infinite PSNR)."""
    mse = float(mse)
    if not mse > 0.0:
        return None
    return 10.0 * math.log10(1.0 / mse)


def _as_float_rgb(img) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        raise ValueError(f"colour images must be (h, w, 3 or 4), got {a.shape}")
    if a.dtype == np.uint8:
        return a[..., :3].astype(np.float32) / np.float32(255.0)
    return a[..., :3].astype(np.float32)


def object_mask(img) -> np.ndarray:
    """(h, w) bool: pixels covered by the object (alpha > 0). RGB-only images: any channel > 0."""
    a = np.asarray(img)
    if a.shape[2] == 4:
        return a[..., 3] > 0
    return np.any(a > 0, axis=2)


def image_metrics(reference, test) -> dict:
    """Colour metrics of ``test`` against ``reference`` (both (h, w, 4) uint8 RGBA, see module doc).

    Returns ``{"object_pixels", "sum_sq", "mse", "psnr", "max_error", "pixels_off", "share_off",
    "interior_pixels", "interior_mse", "psnr_interior"}``: object_pixels (int), sum_sq (float, sum of
    squared channel differences over object pixels, for pooling over views), mse, psnr (dB or None),
    max_error in [0, 1], pixels_off (int) and share_off in [0, 1] (0 when there are no object
    pixels); interior_pixels, interior_mse and psnr_interior over the pixels covered fully in both.
    """
    ref, tst = np.asarray(reference), np.asarray(test)
    if ref.shape != tst.shape:
        raise ValueError(f"image shapes differ: {ref.shape} vs {tst.shape}")
    mask = object_mask(ref) | object_mask(tst)
    box = _bbox(mask)
    if box is None:
        return {"object_pixels": 0, "sum_sq": 0.0, "mse": 0.0, "psnr": None, "max_error": 0.0, "pixels_off": 0,
                "share_off": 0.0, "interior_pixels": 0, "interior_mse": 0.0, "psnr_interior": None}
    if not np.array_equal(ref[~mask], tst[~mask]):  # background pixels differ: include them in max_error
        full = np.abs(_as_float_rgb(ref) - _as_float_rgb(tst)).max(axis=2)
        bg_max = float(full[~mask].max())
    else:
        bg_max = 0.0
    ref, tst, mask = ref[box], tst[box], mask[box]  # everything else happens inside the object's box
    diff = np.abs(_as_float_rgb(ref) - _as_float_rgb(tst))
    n = int(np.count_nonzero(mask))
    d = diff[mask].astype(np.float64)
    sum_sq = float(np.sum(d * d))
    mse = sum_sq / (3.0 * n) if n else 0.0
    per_pixel = diff.max(axis=2)
    off = int(np.count_nonzero(per_pixel[mask] > OFF_THRESHOLD + 1e-7))
    full = (ref[..., 3] == 255) & (tst[..., 3] == 255) if ref.shape[2] == 4 else mask
    ni = int(np.count_nonzero(full))
    di = diff[full].astype(np.float64)
    interior_mse = float(np.sum(di * di)) / (3.0 * ni) if ni else 0.0
    return {"object_pixels": n, "sum_sq": sum_sq, "mse": mse, "psnr": psnr_from_mse(mse),
            "max_error": max(float(per_pixel.max()) if per_pixel.size else 0.0, bg_max),
            "pixels_off": off, "share_off": off / n if n else 0.0,
            "interior_pixels": ni, "interior_mse": interior_mse, "psnr_interior": psnr_from_mse(interior_mse)}


def _bbox(mask: np.ndarray):
    """(row slice, column slice) of the True pixels of a 2-D mask, or None when there are none."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)


def uniform_neighbourhood(ids: np.ndarray) -> np.ndarray:
    """(h, w) bool: the 3x3 neighbourhood (clipped at the border) holds one value only."""
    ids = np.asarray(ids)
    pad = np.pad(ids, 1, mode="edge")
    h, w = ids.shape
    same = np.ones((h, w), dtype=bool)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            same &= pad[dy:dy + h, dx:dx + w] == ids
    return same


def depth_order_errors(reference_ids, test_ids) -> dict:
    """Depth-order metrics of part-ID images (module doc): ``{"depth_order_errors", "part_mismatch",
    "covered_both"}``, pixel counts (int)."""
    ref, tst = np.asarray(reference_ids), np.asarray(test_ids)
    if ref.shape != tst.shape:
        raise ValueError(f"ID image shapes differ: {ref.shape} vs {tst.shape}")
    box = _bbox((ref != 0) | (tst != 0))
    if box is None:
        return {"depth_order_errors": 0, "part_mismatch": 0, "covered_both": 0}
    # one pixel of margin, so the neighbourhood test sees the same pixels as on the full image
    h, w = ref.shape
    box = (slice(max(box[0].start - 1, 0), min(box[0].stop + 1, h)),
           slice(max(box[1].start - 1, 0), min(box[1].stop + 1, w)))
    ref, tst = ref[box], tst[box]
    both = (ref != 0) & (tst != 0)
    differ = both & (ref != tst)
    interior = uniform_neighbourhood(ref)
    return {"depth_order_errors": int(np.count_nonzero(differ & interior)),
            "part_mismatch": int(np.count_nonzero(differ)),
            "covered_both": int(np.count_nonzero(both))}


def depth_error_mask(reference_ids, test_ids) -> np.ndarray:
    """(h, w) bool: the pixels ``depth_order_errors`` counts (both renders cover the pixel, with
    different parts, and the reference's 3x3 neighbourhood, clipped at the border, holds one part
    only), so ``mask.sum()`` equals its ``depth_order_errors``."""
    ref, tst = np.asarray(reference_ids), np.asarray(test_ids)
    return (ref != 0) & (tst != 0) & (ref != tst) & uniform_neighbourhood(ref)


def pooled_psnr(sum_sq: float, object_pixels: int) -> float | None:
    """PSNR of squared errors pooled over several images: ``10 log10(3 N / sum_sq)``."""
    return psnr_from_mse(sum_sq / (3.0 * object_pixels)) if object_pixels else None


def mean_mse_psnr(mses) -> float | None:
    """PSNR of the mean of per-image MSEs (Purnomo et al. average the per-view errors)."""
    mses = [float(m) for m in mses]
    return psnr_from_mse(sum(mses) / len(mses)) if mses else None


def max_finite_psnr(width: int, height: int, views: int = 1) -> float:
    """The highest finite PSNR (dB) the harness can report for renders of ``width`` x ``height``
    pixels: one 8-bit colour code off in one channel of one pixel, every pixel an object pixel,
    ``10 log10(3 W H 255^2)`` (112.8 dB at 1280 x 720). ``views`` > 1: the PSNR of the mean MSE
    over that many views (``mean_mse_psnr``), whose floor is that error in one view alone, so
    ``+ 10 log10(views)``. A target above it is met only by renders identical to the float32
    reference at every level (infinite PSNR), which no quantized level gives in practice."""
    return 10.0 * math.log10(3.0 * int(width) * int(height) * int(views) * 255.0 ** 2)


# ---- heatmaps -------------------------------------------------------------------------------------

# black -> blue -> magenta -> orange -> yellow -> white, at 0, .2, .4, .6, .8, 1
_STOPS = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
_COLOURS = np.array([[0, 0, 0], [40, 40, 200], [200, 40, 160], [250, 120, 30], [250, 230, 40], [255, 255, 255]],
                    dtype=np.float64)


def colormap(values) -> np.ndarray:
    """Map values in [0, 1] (clipped) to (…, 3) uint8 RGB (black, blue, magenta, orange, yellow, white)."""
    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0)
    out = np.stack([np.interp(v, _STOPS, _COLOURS[:, c]) for c in range(3)], axis=-1)
    return np.round(out).astype(np.uint8)


def difference_heatmap(reference, test, vmax: float = HEATMAP_VMAX, background=(24, 24, 24)) -> np.ndarray:
    """(h, w, 3) uint8 heatmap of the largest channel difference per pixel, ``vmax`` colour units
    (default 0.25) at full scale (``colormap``); pixels that are background in both images are
    drawn in ``background`` (dark grey), so an error-free object shows black on grey."""
    ref, tst = np.asarray(reference), np.asarray(test)
    if ref.dtype == np.uint8 and tst.dtype == np.uint8 and ref.shape == tst.shape and ref.ndim == 3 \
            and ref.shape[2] in (3, 4):
        # 8-bit codes: the largest channel difference is one of 256 x 256 float32 values, so the
        # colours come from a table over their ranks (the same colour for the same value, bit for bit)
        ranks, colours = _heatmap_tables(float(vmax))
        r = None
        for ch in range(3):
            code = ref[..., ch].astype(np.uint16)
            code <<= 8
            code |= tst[..., ch]
            k = np.take(ranks, code)
            r = k if r is None else np.maximum(r, k, out=r)
        out = np.take(colours, r, axis=0)
    else:
        diff = np.abs(_as_float_rgb(ref) - _as_float_rgb(tst)).max(axis=2)
        out = colormap(diff / float(vmax))
    mask = object_mask(ref) | object_mask(tst)
    out[~mask] = np.asarray(background, dtype=np.uint8)
    return out


_HEATMAP_TABLES: dict = {}


def _heatmap_tables(vmax: float) -> tuple[np.ndarray, np.ndarray]:
    """(ranks, colours) for ``difference_heatmap`` of 8-bit images at full scale ``vmax``: ranks
    (65536,) uint16, the rank of ``_ABS_DIFF[a * 256 + b]`` among its distinct values (the same order
    as the values); colours (distinct values, 3) uint8, ``colormap(value / vmax)`` of each, computed
    as the float path does (float32 / float)."""
    got = _HEATMAP_TABLES.get(vmax)
    if got is None:
        values, ranks = np.unique(_ABS_DIFF, return_inverse=True)
        got = _HEATMAP_TABLES[vmax] = (ranks.astype(np.uint16).reshape(-1), colormap(values / vmax))
    return got


__all__ = ["OFF_THRESHOLD", "HEATMAP_VMAX", "psnr_from_mse", "object_mask", "image_metrics", "depth_order_errors",
           "pooled_psnr", "mean_mse_psnr", "max_finite_psnr", "colormap", "difference_heatmap", "view_metrics"]


# ---- the harness's fused pass -------------------------------------------------------------------
#
# ``view_metrics`` computes what ``image_metrics`` and ``depth_order_errors`` compute, from the
# pixels that differ only. Decoded positions move a vertex by at most about half a pixel, so most
# object pixels of a test render equal the reference's bit for bit; those add exact zeros to every
# sum. Per-channel differences come from 256 x 256 tables built with the same float32 arithmetic as
# ``_as_float_rgb`` (code / 255 in float32, absolute difference in float32, squared in float64).

_CODES = np.arange(256, dtype=np.float32) / np.float32(255.0)
_ABS_DIFF = np.abs(_CODES[:, None] - _CODES[None, :]).ravel()  # float32, index a * 256 + b
_SQ_DIFF = _ABS_DIFF.astype(np.float64) ** 2


def view_metrics(reference, test, reference_ids, test_ids, box=None) -> tuple[dict, dict]:
    """``(image_metrics(reference, test), depth_order_errors(reference_ids, test_ids))`` in one pass
    over the pixels where the two renders differ (module doc: same definitions; every count, the
    maximum error and the share off are identical; ``sum_sq`` is the same sum of the same float64
    terms without its zero terms, so it agrees to the last bits of a double).

    reference, test : (h, w, 4) uint8 RGBA, C-contiguous; reference_ids, test_ids : (h, w) uint32.
    box : (row0, row1, col0, col1) outside which both renders are background (RGBA 0, part ID 0),
    e.g. the union of the regions the renderer drew (``Renderer.last_box``); the pass is then
    limited to it, widened by one pixel so that every 3 x 3 neighbourhood of the depth-order test
    sees what it sees in the whole frame: the same numbers."""
    ref, tst = np.asarray(reference), np.asarray(test)
    rid, tid = np.asarray(reference_ids), np.asarray(test_ids)
    words = (ref.ndim == 3 and ref.shape == tst.shape and ref.shape[2:] == (4,) and ref.dtype == np.uint8
             and tst.dtype == np.uint8)
    r32 = t32 = None
    if words:  # RGBA pixels as little-endian uint32 words of the whole frame (a view), cropped below
        ref, tst = np.ascontiguousarray(ref), np.ascontiguousarray(tst)
        r32, t32 = ref.view("<u4")[..., 0], tst.view("<u4")[..., 0]
    if box is not None and ref.ndim == 3 and ref.shape == tst.shape and rid.shape == tid.shape == ref.shape[:2]:
        ref, tst, rid, tid, r32, t32 = _crop(box, ref, tst, rid, tid, r32, t32, words)
    if not words:
        return image_metrics(ref, tst), depth_order_errors(rid, tid)
    if rid.shape != tid.shape:
        raise ValueError(f"ID image shapes differ: {rid.shape} vs {tid.shape}")
    h, w = ref.shape[:2]
    return _word_colour_metrics(ref, tst, r32, t32, w), _id_metrics(rid, tid, h, w)


def _crop(box, ref, tst, rid, tid, r32, t32, words: bool) -> tuple:
    """``view_metrics``'s images cut to ``box`` (row0, row1, col0, col1) widened by one pixel and
    clipped to the frame: (ref, tst, rid, tid, r32, t32), views of the inputs. An empty box (nothing
    drawn) gives 1 x 1 background images (RGBA 0, ID 0, word 0): the same metrics as the frame's.
    ``r32``/``t32`` (the RGBA words) are cut only when ``words``."""
    hh, ww = ref.shape[:2]
    r0, r1, c0, c1 = (int(v) for v in box)
    if r1 <= r0 or c1 <= c0:  # nothing drawn in either: background everywhere
        r0 = r1 = c0 = c1 = 0
    else:
        r0, r1, c0, c1 = max(0, r0 - 1), min(hh, r1 + 1), max(0, c0 - 1), min(ww, c1 + 1)
    ref, tst = ref[r0:r1, c0:c1], tst[r0:r1, c0:c1]
    rid, tid = rid[r0:r1, c0:c1], tid[r0:r1, c0:c1]
    if words:
        r32, t32 = r32[r0:r1, c0:c1], t32[r0:r1, c0:c1]
    if ref.size == 0:
        ref, tst = np.zeros((1, 1, 4), np.uint8), np.zeros((1, 1, 4), np.uint8)
        rid, tid = np.zeros((1, 1), np.uint32), np.zeros((1, 1), np.uint32)
        r32 = t32 = np.zeros((1, 1), "<u4")
    return ref, tst, rid, tid, r32, t32


def _word_colour_metrics(ref, tst, r32, t32, w: int) -> dict:
    """``image_metrics``'s dict from the pixels whose RGBA words differ. ref, tst : (h, w, 4) uint8;
    r32, t32 : (h, w) ``<u4`` views of the same pixels (alpha in the top byte); ``w`` the row length."""
    # alpha is the top byte of a word: covered in either (alpha != 0), fully covered in both (255)
    n = int(np.count_nonzero((r32 | t32) > np.uint32(0x00FFFFFF)))
    ni = int(np.count_nonzero((r32 & t32) >= np.uint32(0xFF000000)))
    where = np.flatnonzero(r32 != t32)  # row-major, as boolean indexing of the box visits them
    rf = ref.reshape(-1, 4)[where] if ref.flags.c_contiguous else ref[np.divmod(where, w)]
    tf = tst.reshape(-1, 4)[where] if tst.flags.c_contiguous else tst[np.divmod(where, w)]
    obj = (rf[:, 3] | tf[:, 3]) != 0
    full = (rf[:, 3] == 255) & (tf[:, 3] == 255)
    idx = rf[:, :3].astype(np.intp) * 256 + tf[:, :3]
    per_pixel = _ABS_DIFF[idx].max(axis=1) if where.size else np.zeros(0, np.float32)
    if n == 0:
        return {"object_pixels": 0, "sum_sq": 0.0, "mse": 0.0, "psnr": None, "max_error": 0.0, "pixels_off": 0,
                "share_off": 0.0, "interior_pixels": 0, "interior_mse": 0.0, "psnr_interior": None}
    sq = _SQ_DIFF[idx]
    sum_sq = float(np.sum(sq[obj]))
    mse = sum_sq / (3.0 * n)
    off = int(np.count_nonzero(per_pixel[obj] > OFF_THRESHOLD + 1e-7))
    interior_mse = float(np.sum(sq[full])) / (3.0 * ni) if ni else 0.0
    return {"object_pixels": n, "sum_sq": sum_sq, "mse": mse, "psnr": psnr_from_mse(mse),
            "max_error": float(per_pixel.max()) if per_pixel.size else 0.0,
            "pixels_off": off, "share_off": off / n, "interior_pixels": ni, "interior_mse": interior_mse,
            "psnr_interior": psnr_from_mse(interior_mse)}


def _id_metrics(rid, tid, h: int, w: int) -> dict:
    """``depth_order_errors``'s dict from part-ID images rid, tid (h, w) uint32, visiting only the
    pixels covered in both whose part differs: of those, the ones whose reference 3x3 neighbourhood
    (clipped at the border) holds one part only are depth-order errors."""
    covered = (rid != 0) & (tid != 0)
    covered_both = int(np.count_nonzero(covered))
    covered &= rid != tid
    cand = np.flatnonzero(covered)
    del covered
    mismatch = int(cand.size)
    depth_errors = 0
    if cand.size:
        y, x = np.divmod(cand, w)
        centre = rid[y, x]
        uniform = np.ones(cand.size, dtype=bool)
        for dy in (-1, 0, 1):
            yy = np.clip(y + dy, 0, h - 1)
            for dx in (-1, 0, 1):
                uniform &= rid[yy, np.clip(x + dx, 0, w - 1)] == centre
        depth_errors = int(np.count_nonzero(uniform))
    return {"depth_order_errors": depth_errors, "part_mismatch": mismatch, "covered_both": covered_both}
