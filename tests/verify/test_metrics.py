"""lopcook.verify.metrics on synthetic images (no GL): PSNR over object pixels, max error, share of
pixels off, depth-order errors from part-ID images, heatmaps. Closed forms throughout."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lopcook.verify import metrics as M


def _img(h=4, w=4, rgb=(100, 150, 200), alpha=255) -> np.ndarray:
    a = np.zeros((h, w, 4), np.uint8)
    a[..., :3] = rgb
    a[..., 3] = alpha
    return a


def test_psnr_from_mse_closed_form_and_identical_is_none():
    assert M.psnr_from_mse(0.0) is None
    assert M.psnr_from_mse(1e-4) == pytest.approx(40.0)
    assert M.psnr_from_mse(1.0) == pytest.approx(0.0)


def test_identical_images_have_no_error():
    a = _img()
    m = M.image_metrics(a, a.copy())
    assert m["psnr"] is None and m["mse"] == 0.0 and m["max_error"] == 0.0
    assert m["pixels_off"] == 0 and m["share_off"] == 0.0 and m["object_pixels"] == 16


def test_one_pixel_off_closed_form():
    ref = _img()
    tst = ref.copy()
    tst[1, 2, 0] += 51  # 0.2 in one channel of one of 16 object pixels
    m = M.image_metrics(ref, tst)
    mse = 0.2**2 / (3 * 16)
    assert m["mse"] == pytest.approx(mse, rel=1e-6)
    assert m["psnr"] == pytest.approx(10 * math.log10(1 / mse), rel=1e-6)
    assert m["max_error"] == pytest.approx(0.2, abs=1e-6)
    assert m["pixels_off"] == 1 and m["share_off"] == pytest.approx(1 / 16)
    assert m["sum_sq"] == pytest.approx(0.04, rel=1e-6)


def test_interior_psnr_leaves_coverage_out():
    ref = _img()
    tst = ref.copy()
    tst[0, 0] = (50, 75, 100, 128)  # a silhouette pixel: half covered
    tst[2, 2, 0] += 51  # a shading error inside
    m = M.image_metrics(ref, tst)
    assert m["object_pixels"] == 16 and m["interior_pixels"] == 15
    assert m["interior_mse"] == pytest.approx(0.2**2 / (3 * 15), rel=1e-6)
    assert m["psnr_interior"] > m["psnr"]
    same = M.image_metrics(ref, ref)
    assert same["psnr_interior"] is None


def test_background_in_both_images_is_excluded():
    ref = _img(alpha=0)
    ref[..., :3] = 0
    ref[0, 0] = (255, 255, 255, 255)
    ref[0, 1] = (128, 128, 128, 255)
    tst = ref.copy()
    tst[0, 1, 2] = 128 + 51
    m = M.image_metrics(ref, tst)
    assert m["object_pixels"] == 2
    assert m["mse"] == pytest.approx(0.2**2 / 6, rel=1e-6)


def test_pixel_object_in_one_image_only_counts():
    ref = _img(rgb=(0, 0, 0), alpha=0)
    tst = ref.copy()
    tst[3, 3] = (255, 0, 0, 255)  # coverage error: background in the reference, object in the test
    m = M.image_metrics(ref, tst)
    assert m["object_pixels"] == 1
    assert m["mse"] == pytest.approx(1 / 3)
    assert m["psnr"] == pytest.approx(10 * math.log10(3))


def test_no_object_pixels_gives_none():
    a = _img(rgb=(0, 0, 0), alpha=0)
    m = M.image_metrics(a, a)
    assert m["object_pixels"] == 0 and m["psnr"] is None and m["share_off"] == 0.0


def test_share_off_threshold_is_more_than_one_step():
    ref = _img()
    tst = ref.copy()
    tst[0, 0, 1] += 1  # exactly 1/255: not "more than"
    tst[0, 1, 1] += 2  # 2/255: off
    m = M.image_metrics(ref, tst)
    assert m["pixels_off"] == 1


def test_shape_mismatch_raises():
    with pytest.raises(ValueError):
        M.image_metrics(_img(4, 4), _img(4, 5))
    with pytest.raises(ValueError):
        M.depth_order_errors(np.zeros((3, 3), np.uint32), np.zeros((3, 4), np.uint32))


def test_depth_order_error_inside_a_part_is_counted():
    ref = np.ones((9, 9), np.uint32)
    tst = ref.copy()
    tst[4, 4] = 2  # another part shows through, far from any boundary
    d = M.depth_order_errors(ref, tst)
    assert d == {"depth_order_errors": 1, "part_mismatch": 1, "covered_both": 81}


def test_coverage_shift_at_a_part_boundary_is_not_depth_order():
    ref = np.ones((8, 8), np.uint32)
    ref[:, 4:] = 2
    tst = np.ones((8, 8), np.uint32)
    tst[:, 5:] = 2  # the boundary moved by one pixel
    d = M.depth_order_errors(ref, tst)
    assert d["part_mismatch"] == 8 and d["depth_order_errors"] == 0


def test_background_pixels_are_not_depth_order_errors():
    ref = np.ones((6, 6), np.uint32)
    tst = ref.copy()
    tst[2, 2] = 0  # a hole: coverage, not order
    d = M.depth_order_errors(ref, tst)
    assert d["depth_order_errors"] == 0 and d["part_mismatch"] == 0 and d["covered_both"] == 35


def test_pooled_and_mean_psnr():
    assert M.pooled_psnr(0.0, 10) is None
    assert M.pooled_psnr(3e-4, 1) == pytest.approx(40.0)
    assert M.mean_mse_psnr([1e-4, 3e-4]) == pytest.approx(10 * math.log10(1 / 2e-4))
    assert M.mean_mse_psnr([]) is None
    assert M.mean_mse_psnr([0.0, 0.0]) is None


def test_heatmap():
    ref = _img()
    ref[0, :] = (0, 0, 0, 0)  # background row in both
    tst = ref.copy()
    tst[2, 2, 0] = 100 + 64  # 0.25 = full scale
    hm = M.difference_heatmap(ref, tst)
    assert hm.shape == (4, 4, 3) and hm.dtype == np.uint8
    assert tuple(hm[0, 0]) == (24, 24, 24)  # background
    assert tuple(hm[1, 1]) == (0, 0, 0)  # object, no error
    assert tuple(hm[2, 2]) == (255, 255, 255)  # full scale
    assert tuple(M.colormap(np.array([0.0]))[0]) == (0, 0, 0)


@pytest.mark.parametrize("vmax", [0.25, 1.0, 0.05])
def test_heatmap_of_8bit_images_equals_the_float_path(vmax):
    """Every (reference, test) code pair in every channel: the table over ranks gives the colours of
    the float32 differences (``colormap(max |a - b| / vmax)``), background where both are."""
    pairs = np.arange(1 << 16)
    ref = np.zeros((256, 256, 4), np.uint8)
    tst = np.zeros_like(ref)
    for ch in range(3):  # every pair in each channel, shifted: the max is a mix ...
        ref[..., ch] = np.roll(pairs >> 8, 4099 * ch).reshape(256, 256)
        tst[..., ch] = np.roll(pairs & 255, 4099 * ch).reshape(256, 256)
    tst[128:, :, 1:] = ref[128:, :, 1:]  # ... and in the bottom half the first channel's alone
    ref[..., 3] = 255
    ref[:3, :, 3] = 0  # three rows of background in both
    want = M.colormap(np.abs(M._as_float_rgb(ref) - M._as_float_rgb(tst)).max(axis=2) / vmax)
    want[:3] = 24
    got = M.difference_heatmap(ref, tst, vmax)
    assert np.array_equal(got, want)
    assert len(np.unique(got.reshape(-1, 3), axis=0)) > 10  # many colours, not one
    # images that are not 8-bit take the float path
    assert np.array_equal(M.difference_heatmap(ref.astype(np.float32) / 255, tst.astype(np.float32) / 255, vmax), want)
