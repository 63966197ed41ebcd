"""lopcook.analyse.bitlevel: the minimum level of Meyer et al. 2011, section 5.1
(k_f * E_v * dx(b) <= eps, smallest such b) and the texture slope that gives UVs their k_f."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from lopcook.analyse import bitlevel as BL
from lopcook.grid import dx
from lopcook.types import Texture

EPS = 1 / 255


def _closed_form(e_v, kf, eps, extent):
    """b = ceil(log2(sqrt(3) * extent * kf * E_v / eps) - 1), at least 1; 25 when above 24."""
    with np.errstate(divide="ignore"):
        b = np.ceil(np.log2(np.sqrt(3.0) * extent * kf * np.asarray(e_v, np.float64) / eps) - 1.0)
    return np.clip(np.nan_to_num(b, neginf=1.0), 1, 25).astype(np.int64)


@pytest.mark.parametrize("n", [1000, BL._CHUNK + 4321])  # one predicate, and the chunked path
def test_attribute_level_is_the_smallest_level_meeting_the_bound(rng, n):
    kf, extent = 0.5 * 32, 2.5
    e_v = np.exp(rng.uniform(np.log(1e-3), np.log(1e7), n))
    e_v[:3] = 0.0  # attributes that do not vary: level 1
    b = BL.attribute_level(e_v, kf, EPS, extent)
    assert b.shape == (n,) and b.dtype == np.int64
    assert np.all(b[:3] == 1) and b.min() >= 1 and b.max() <= 25
    ok = b <= 24
    # the bound holds at the level given ...
    assert np.all(kf * e_v[ok] * dx(b[ok], extent) <= EPS)
    # ... and fails one level lower (minimality), unless the level is 1
    lower = ok & (b > 1)
    assert np.all(kf * e_v[lower] * dx(b[lower] - 1, extent) > EPS)
    # 25 ("none", the caller clamps and counts) exactly where even 24 bits are not enough
    np.testing.assert_array_equal(~ok, kf * e_v * dx(24, extent) > EPS)
    assert (~ok).any() and lower.any()
    # the closed form agrees except where the logarithm rounds across an integer
    cf = _closed_form(e_v, kf, EPS, extent)
    assert np.mean(cf == b) > 0.999 and np.all(np.abs(cf - b) <= 1)


def test_attribute_level_boundary_is_inclusive():
    extent, b = 1.7, 10
    d = float(dx(b, extent))
    e = EPS / d
    while e * d > EPS:  # the largest E_v whose product, as computed, is still <= eps
        e = float(np.nextafter(e, 0.0))
    assert BL.attribute_level(np.array([e]), 1.0, EPS, extent)[0] == b
    assert BL.attribute_level(np.array([e * (1 + 1e-9)]), 1.0, EPS, extent)[0] == b + 1


def test_doubling_kf_is_exactly_one_more_bit(rng):
    # dx halves exactly per level (a power of two), so k_f * 2 at level b + 1 is the same test as
    # k_f at level b: every level above 1 moves up by exactly one; halving eps does the same
    e_v = np.exp(rng.uniform(np.log(1e-2), np.log(1e6), 5000))
    base = BL.attribute_level(e_v, 1.0, EPS, 1.0)
    doubled = BL.attribute_level(e_v, 2.0, EPS, 1.0)
    up = base >= 2
    assert up.sum() > 1000
    np.testing.assert_array_equal(doubled[up], np.minimum(base[up] + 1, 25))
    assert np.all((doubled[~up] == 1) | (doubled[~up] == 2))
    np.testing.assert_array_equal(doubled, BL.attribute_level(e_v, 1.0, EPS / 2, 1.0))
    assert np.all(BL.attribute_level(e_v, 0.0, EPS, 1.0) == 1)  # no slope: nothing to keep


def _png(array: np.ndarray, mode: str) -> Texture:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(array.astype(np.uint8), mode).save(buf, format="PNG")
    return Texture(name=f"gradient-{mode}-{array.shape}", data=buf.getvalue())


def _triangle_wave(n: int, step: int) -> np.ndarray:
    """step * min(x, n - x): periodic over n texels, every forward difference (wrap included) is
    +-step."""
    x = np.arange(n)
    return step * np.minimum(x, n - x)


def test_texture_slope_of_an_analytic_gradient():
    """Texel values are float32 (code / 255), so slopes match to float32 rounding (rel 1e-5)."""
    BL.clear_slope_cache()
    w, h = 64, 32
    # one channel: 3 codes per texel along u, 2 along v -> |grad| = sqrt((3 w)^2 + (2 h)^2) / 255 per UV unit
    img = _triangle_wave(w, 3)[None, :] + _triangle_wave(h, 2)[:, None]
    assert img.max() <= 255
    assert BL.texture_slope(_png(img, "L")) == pytest.approx(math.hypot(3 * w, 2 * h) / 255, rel=1e-5)
    # per channel, the maximum over channels (not the norm across channels)
    rgb = np.zeros((h, w, 3))
    rgb[..., 0] = _triangle_wave(w, 7)[None, :]
    rgb[..., 1] = _triangle_wave(h, 5)[:, None]
    assert BL.texture_slope(_png(rgb, "RGB")) == pytest.approx(max(7 * w, 5 * h) / 255, rel=1e-5)
    # a constant texture has no slope
    assert BL.texture_slope(_png(np.full((8, 8), 77), "L")) == 0.0


def test_texture_slope_wraps_like_a_repeating_texture():
    BL.clear_slope_cache()
    w = 16
    ramp = np.tile(np.arange(w) * 16, (4, 1))  # 0..240: the wrap from 240 back to 0 is the steepest step
    assert BL.texture_slope(_png(ramp, "L")) == pytest.approx(240 * w / 255, rel=1e-5)


def test_texture_slope_is_cached_by_digest_and_the_cache_clears():
    BL.clear_slope_cache()
    tex = _png(_triangle_wave(32, 4)[None, :].repeat(4, 0), "L")
    s = BL.texture_slope(tex)
    assert BL._SLOPE_CACHE == {tex.digest: s}
    BL.clear_slope_cache()
    assert BL._SLOPE_CACHE == {}
    assert BL.texture_slope(tex) == s
