"""Report images (lopcook.report.images): the shared crop, nearest-neighbour enlargement and PNG
data URIs. No GL."""

from __future__ import annotations

import base64
import io

import numpy as np
import pytest

from lopcook.verify.metrics import depth_error_mask
from lopcook.report.images import (CROP_MARGIN_PX, CROP_TARGET_PX, ZOOM_TARGET_PX, apply_crop, crop_box,
                                   depth_overlay, png_data_uri, squared_error, worst_window)


def test_crop_box_rules():
    frame = np.zeros((720, 1280, 4), np.uint8)
    frame[300:337, 600:630] = (10, 20, 30, 255)  # a 30 x 37 pixel object
    ids = np.zeros((720, 1280), np.uint32)
    ids[340, 640] = 1  # one more object pixel seen only by the ID image
    heat = np.full((720, 1280, 3), 7, np.uint8)  # heat maps have no alpha: they do not widen the box
    c = crop_box({"float": frame, "float_ids": ids, "ap_heatmap": heat, "level": 6, "view": 3})
    m = CROP_MARGIN_PX
    assert c["frame"] == [1280, 720]
    assert c["box"] == [600 - m, 300 - m, 641 + m, 341 + m]
    w, h = 41 + 2 * m, 41 + 2 * m
    assert c["scale"] == min(8, 480 // max(w, h)) and c["size"] == [w * c["scale"], h * c["scale"]]
    a = apply_crop(frame, c)
    assert a.shape == (c["size"][1], c["size"][0], 4)
    assert np.array_equal(a[::c["scale"], ::c["scale"]], frame[300 - m:341 + m, 600 - m:641 + m])
    assert apply_crop(heat, c).shape[:2] == a.shape[:2]
    # clipped at the frame edge; a small frame is still enlarged towards CROP_TARGET_PX (legible at
    # level 6 whatever --resolution), a crop already that large is not
    big = np.zeros((90, 160, 4), np.uint8)
    big[0:80, 5:150, 3] = 255
    c = crop_box({"float": big})
    assert c["box"] == [0, 0, 160, 90] and c["scale"] == CROP_TARGET_PX // 160 == 3 and c["size"] == [480, 270]
    small = np.zeros((90, 160, 4), np.uint8)
    small[40:52, 70:80, 3] = 255  # 10 x 12 pixels in a 160 x 90 frame
    c = crop_box({"float": small})
    assert c["scale"] == 8 and c["size"][1] > 90  # shown larger than the frame itself
    huge = np.zeros((720, 1280, 4), np.uint8)
    huge[10:700, 10:1270, 3] = 255
    assert crop_box({"float": huge})["scale"] == 1
    # nothing rendered: the whole frame at 1x
    assert crop_box({"float": np.zeros((90, 160, 4), np.uint8)})["box"] == [0, 0, 160, 90]
    assert crop_box(None) is None


def test_png_data_uri_round_trips_every_mode():
    from PIL import Image

    rng = np.random.default_rng(7)
    for shape in ((5, 7), (5, 7, 3), (5, 7, 4)):
        a = rng.integers(0, 256, shape, dtype=np.uint8)
        uri = png_data_uri(a)
        assert uri.startswith("data:image/png;base64,")
        back = np.asarray(Image.open(io.BytesIO(base64.b64decode(uri.split(",", 1)[1]))))
        np.testing.assert_array_equal(back, a)
    assert png_data_uri(a) == png_data_uri(a.copy())  # deterministic bytes


def test_worst_window_finds_the_largest_error_sum():
    h, w = 90, 160
    ref = np.zeros((h, w, 4), np.uint8)
    ref[20:70, 30:130] = (100, 100, 100, 255)
    tst = ref.copy()
    tst[25, 40] = (110, 100, 100, 255)  # a small error on the left
    tst[50:54, 100:104] = (200, 100, 100, 255)  # a large one on the right
    err = squared_error(ref, tst)
    assert err[25, 40] == (10 / 255) ** 2 and err[0, 0] == 0.0
    assert err.sum() == pytest.approx((10 / 255) ** 2 + 16 * (100 / 255) ** 2, rel=1e-12)
    crop = crop_box({"float": ref, "cap": tst})
    z = worst_window(err, crop)
    x0, y0, x1, y1 = z["box"]
    side = x1 - x0
    assert crop["box"] == [20, 10, 140, 80]  # 100 x 50 object, 10-pixel margin
    assert side == y1 - y0 == 70 // 4  # a quarter of the crop's smaller side
    assert x0 <= 100 and x1 >= 104 and y0 <= 50 and y1 >= 54  # the large error is inside the window
    assert crop["box"][0] <= x0 and x1 <= crop["box"][2] and crop["box"][1] <= y0 and y1 <= crop["box"][3]
    assert z["scale"] == ZOOM_TARGET_PX // 17 and z["size"] == [17 * z["scale"]] * 2
    assert z["sum_sq"] == float(err[y0:y1, x0:x1].sum()) and 0.99 < z["share"] < 1.0
    # brute force over every window of that side agrees on the best sum
    bx0, by0, bx1, by1 = crop["box"]
    best = max(err[y:y + side, x:x + side].sum()
               for y in range(by0, by1 - side + 1) for x in range(bx0, bx1 - side + 1))
    assert z["sum_sq"] == pytest.approx(float(best), rel=1e-12)
    assert worst_window(squared_error(ref, ref), crop) is None  # no error: no zoom


def test_depth_error_mask_counts_what_the_metric_counts(rng):
    from lopcook.verify.metrics import depth_order_errors

    ref = np.zeros((40, 60), np.uint32)
    ref[5:30, 5:30], ref[10:35, 25:55] = 1, 2
    tst = ref.copy()
    tst[12:20, 26:29] = 1  # part 1 drawn in front of part 2 near their boundary
    tst[rng.integers(0, 40, 30), rng.integers(0, 60, 30)] = 3
    mask = depth_error_mask(ref, tst)
    assert int(mask.sum()) == depth_order_errors(ref, tst)["depth_order_errors"] > 0
    assert not mask[ref == 0].any()
    over = depth_overlay(np.dstack([np.full((40, 60, 3), 200, np.uint8), np.where(ref > 0, 255, 0).astype(np.uint8)]),
                         mask)
    assert over.shape == (40, 60, 3)
    assert (over[mask] == (255, 0, 255)).all() and (over[ref == 0] == 255).all()


def test_packed_images_round_trip_exactly(rng):
    """The report keeps later levels' images compressed while it renders: unpacked, every array is
    the same values, dtype and shape, and other values pass through."""
    from lopcook.report.render import _Packed, pack_images, unpack_images

    images = {"level": 7, "view": 3, "float": rng.integers(0, 256, (9, 13, 4), dtype=np.uint8),
              "float_ids": rng.integers(0, 300, (9, 13)).astype(np.uint16),
              "cap_ids": rng.integers(0, 2 ** 31, (9, 13)).astype(np.uint32),
              "x": rng.normal(size=(5, 2)).astype(np.float32)[:, ::-1], "empty": np.zeros((0, 4), np.uint8)}
    packed = pack_images(images)
    assert not any(isinstance(v, np.ndarray) for v in packed.values())
    assert all(isinstance(packed[k], _Packed) for k in images if isinstance(images[k], np.ndarray))
    back = unpack_images(packed)
    assert back.keys() == images.keys()
    for k, v in images.items():
        if isinstance(v, np.ndarray):
            assert back[k].dtype == v.dtype and back[k].shape == v.shape and np.array_equal(back[k], v)
            assert back[k].flags.writeable
        else:
            assert back[k] == v
    assert pack_images(None) is None and unpack_images({}) == {}
