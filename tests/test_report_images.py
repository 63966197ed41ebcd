"""Report images (lopcook.report.images): the shared crop, nearest-neighbour enlargement and PNG
data URIs. No GL."""

from __future__ import annotations

import base64
import io

import numpy as np

from lopcook.report.images import CROP_MARGIN_PX, apply_crop, crop_box, png_data_uri


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
    # clipped at the frame edge; a large object is not enlarged beyond the frame
    big = np.zeros((90, 160, 4), np.uint8)
    big[0:80, 5:150, 3] = 255
    c = crop_box({"float": big})
    assert c["box"] == [0, 0, 160, 90] and c["scale"] == 1 and c["size"] == [160, 90]
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
