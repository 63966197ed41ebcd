"""The average-case bound behind the default attribute bits:
``lopcook.analyse.attribute_bound`` (shading averages, texture gradients, mip level) and
``lopcook.analyse.attribute_bits.default_bits`` / ``normal_pixel_rms`` / ``uv_pixel_rms`` on analytic
cases: closed-form integrals, the codec's measured error at b bits, monotonicity in b, and the
untextured minimum."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from lopcook.analyse import attribute_bound as AB
from lopcook.analyse import bitlevel as BL
from types import SimpleNamespace

from lopcook.analyse import attribute_bits as AT
from lopcook.lop.codecs import AttributeBits
from lopcook.lop.codecs import normals_oct as NO
from lopcook.lop.codecs import uvs_range as UR
from lopcook.settings import DEFAULT_ANALYSE, AnalyseSettings
from lopcook.types import MeshPart, Texture


def _present(normals, uvs, colors) -> dict:
    """The attribute mapping of a part with normals / these UVs / colours (only the UVs' values
    matter to the bound)."""
    return {"normals": np.ones((1, 3)) if normals else None, "uvs": uvs, "colors": np.ones((1, 4)) if colors else None}


def _default_bits(*, normals=False, uvs=None, colors=False, eps, normal_slope_rms=0.0, uv_gradient_rms=(0.0, 0.0),
                  lighting_rms=1.0, color_kf=0.0):
    return AT.default_bits(_present(normals, uvs, colors),
                           AT.ImageModel(eps=eps, slope_rms=normal_slope_rms, gradient_rms=uv_gradient_rms,
                                         lighting_rms=lighting_rms, color_kf=color_kf))


def _worst_case_bits(*, normals=False, uvs=None, colors=False, eps, normal_kf=0.0, uv_kf=0.0, color_kf=0.0):
    return AT.worst_case_bits(_present(normals, uvs, colors),
                              AT.ImageModel(eps=eps, direction_kf=normal_kf, texcoord_kf=uv_kf, color_kf=color_kf))


#: the functions these tests use, by their short names
A = SimpleNamespace(decode_normals=NO.decode_normals, encode_normals=NO.encode_normals,
                    normal_rms_error_deg=NO.normal_rms_error_deg, normal_error_deg=NO.normal_error_deg,
                    normal_pixel_rms=AT.normal_pixel_rms, uv_pixel_rms=AT.uv_pixel_rms, encode_uvs=UR.encode_uvs,
                    decode_uvs=UR.decode_uvs, uv_step=UR.uv_step, default_bits=_default_bits,
                    worst_case_bits=_worst_case_bits, part_default_bits=AT.part_default_bits,
                    AttributeBits=AttributeBits)


def _png(array: np.ndarray, mode: str = "L") -> Texture:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(array.astype(np.uint8), mode).save(buf, format="PNG")
    return Texture(name=f"t-{mode}-{array.shape}-{int(array.sum())}", data=buf.getvalue())


def _square(side=1.0, uv_lo=0.1, uv_hi=0.6, texture=None, normals=True) -> MeshPart:
    """Two triangles: a side x side square in the xy plane, UVs the square [uv_lo, uv_hi]^2."""
    p = np.array([[0, 0, 0], [side, 0, 0], [side, side, 0], [0, side, 0]], dtype=np.float64)
    uv = np.array([[uv_lo, uv_lo], [uv_hi, uv_lo], [uv_hi, uv_hi], [uv_lo, uv_hi]], dtype=np.float32)
    n = np.tile(np.array([[0, 0, 1]], dtype=np.float32), (4, 1)) if normals else None
    return MeshPart(name="sq", positions=p, indices=np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32),
                    normals=n, uvs=uv, texture=texture)


def test_harness_lighting_constants_match_the_renderer():
    from lopcook.verify.renderer import AMBIENT, DIFFUSE, Shading

    assert (AB.HARNESS_AMBIENT, AB.HARNESS_DIFFUSE) == (AMBIENT, DIFFUSE)
    assert (Shading().ks, Shading().shininess) == (DEFAULT_ANALYSE.ks, DEFAULT_ANALYSE.shininess)


@pytest.mark.parametrize("a,d", [(0.15, 0.65), (0.0, 1.0), (0.3, 0.2)])
def test_shading_rms_without_specular_is_the_closed_form(a, d):
    # density sin(2 theta): E[sin^2] = 1/2, E[cos] = 2/3, E[cos^2] = 1/2
    slope, light = AB.shading_rms(0.0, 32.0, a, d)
    assert slope == pytest.approx(d / math.sqrt(2.0), rel=1e-6)
    assert light == pytest.approx(math.sqrt(a * a + 2 * a * d * 2 / 3 + d * d / 2), rel=1e-6)


def test_shading_rms_with_the_default_phong_is_far_below_the_worst_case_kf():
    slope, light = AB.shading_rms(0.5, 32.0)
    # numeric reference on a finer grid (trapezoid, 2e6 steps)
    th = np.linspace(0.0, math.pi / 2, 2_000_001)
    c2 = np.cos(2 * th)
    ds = -0.65 * np.sin(th) - np.where(c2 > 0, 2 * 32 * 0.5 * np.maximum(c2, 0) ** 31 * np.sin(2 * th), 0.0)
    w = np.sin(2 * th)
    ref = math.sqrt(np.trapezoid(ds * ds * w, th) / np.trapezoid(w, th))
    assert slope == pytest.approx(ref, rel=1e-4)
    assert 0.69 < slope < 0.70 < DEFAULT_ANALYSE.normal_kf  # ks * n = 16 is the worst case
    assert light == pytest.approx(0.6031, abs=1e-4)
    # a sharp highlight alone: cos^n(2 theta) ~ exp(-2 n theta^2), density ~ 2 theta, so
    # E[(ds/dtheta)^2] -> 32 n^2 ks^2 * integral theta^3 exp(-4 n theta^2) = ks^2, whatever n
    for n in (200.0, 1000.0):
        assert AB.shading_rms(0.5, n, 0.0, 0.0)[0] == pytest.approx(0.5, rel=0.02)


def _fibonacci(n):
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = i * math.pi * (3 - math.sqrt(5))
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


@pytest.mark.parametrize("bits", [4, 6, 8, 10, 12, 16])
def test_normal_rms_table_is_the_codecs_error(rng, bits):
    d = rng.normal(size=(20000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dec = A.decode_normals(A.encode_normals(d, bits), bits).astype(np.float64)
    dec /= np.linalg.norm(dec, axis=1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip((dec * d).sum(axis=1), -1.0, 1.0)))
    assert A.normal_rms_error_deg(bits) == pytest.approx(math.sqrt(float((ang * ang).mean())), rel=0.03)
    assert A.normal_rms_error_deg(bits) < A.normal_error_deg(bits)  # below the maximum


def test_normal_pixel_rms_at_b_bits_and_monotone():
    slope = AB.shading_rms(0.5, 32.0)[0]
    # 8 bits: 0.3378 degrees RMS -> 0.5 * 0.693 * 0.005896 = 0.00204 colour
    assert A.normal_pixel_rms(8, slope) == pytest.approx(0.5 * slope * math.radians(0.3378), rel=1e-12)
    assert A.normal_pixel_rms(8, slope) == pytest.approx(0.002044, rel=1e-3)
    errs = [A.normal_pixel_rms(b, slope) for b in range(4, 17)]
    assert all(e1 > e2 for e1, e2 in zip(errs, errs[1:]))  # strictly falling in b
    assert all(1.9 < e1 / e2 < 2.3 for e1, e2 in zip(errs[2:], errs[3:]))  # halves per bit from 6 on


@pytest.mark.parametrize("eps", [1 / 255, 1 / 100, 0.05, 1e-5])
def test_default_normal_bits_are_the_smallest_meeting_the_rms_bound(eps):
    slope = AB.shading_rms(0.5, 32.0)[0]
    b = A.default_bits(normals=True, uvs=None, colors=False, eps=eps, normal_slope_rms=slope).normals
    ok = [x for x in range(4, 17) if A.normal_pixel_rms(x, slope) <= eps]
    assert b == (ok[0] if ok else 16)
    if ok and b > 4:
        assert A.normal_pixel_rms(b - 1, slope) > eps


def test_default_bits_of_the_default_shading():
    slope = AB.shading_rms(0.5, 32.0)[0]
    # 1/255: 8 bits (0.00204 colour); 7 bits gives 0.00412 > 0.00392
    assert A.default_bits(normals=True, uvs=None, colors=False, eps=1 / 255, normal_slope_rms=slope).normals == 8
    assert A.normal_pixel_rms(7, slope) > 1 / 255
    # a flat shading (slope 0) needs the minimum
    assert A.default_bits(normals=True, uvs=None, colors=False, eps=1 / 255, normal_slope_rms=0.0).normals == 4
    # the worst-case bound of the same shading asks for 14
    assert A.worst_case_bits(normals=True, uvs=None, colors=False, eps=1 / 255, normal_kf=16.0).normals == 14


def test_uv_rounding_error_is_step_over_sqrt12(rng):
    # the variance the bound assumes: rounding to the nearest code, uniform in +-step/2
    u = rng.uniform(0.0, 1.0, size=(200000, 2))
    u[0], u[1] = 0.0, 1.0
    for bits in (6, 9, 12):
        codes, lo, _, step = A.encode_uvs(u, bits)
        dec = A.decode_uvs(codes, lo, step, bits).astype(np.float64)
        rms = np.sqrt(((dec - u) ** 2).mean(axis=0))
        assert rms == pytest.approx(step.astype(np.float64) / math.sqrt(12.0), rel=0.02)


def test_uv_pixel_rms_closed_form_and_monotone():
    lo, hi = np.array([0.0, 0.0]), np.array([1.0, 0.5])
    g, light = (30.0, 50.0), 0.6
    for bits in range(6, 17):
        s = A.uv_step(lo, hi, bits).astype(np.float64)
        want = light * math.sqrt(0.5 * ((g[0] * s[0]) ** 2 + (g[1] * s[1]) ** 2) / 12.0)
        assert A.uv_pixel_rms(lo, hi, bits, g, light) == pytest.approx(want, rel=1e-12)
    errs = [A.uv_pixel_rms(lo, hi, b, g, light) for b in range(6, 17)]
    assert all(e1 > e2 for e1, e2 in zip(errs, errs[1:]))
    assert A.uv_pixel_rms(lo, hi, 10, (0.0, 0.0), light) == 0.0


def test_default_uv_bits_untextured_minimum_and_monotone_in_the_gradient():
    uv = np.array([[0.0, 0.0], [1.0, 1.0], [0.3, 0.7]])
    kw = dict(normals=False, colors=False, eps=1 / 255, lighting_rms=0.603)
    assert A.default_bits(uvs=uv, uv_gradient_rms=(0.0, 0.0), **kw).uvs == 6  # untextured
    bits = [A.default_bits(uvs=uv, uv_gradient_rms=(g, g), **kw).uvs for g in (1, 3, 10, 30, 100, 300, 1e5)]
    assert bits == sorted(bits) and bits[-1] == 16 and bits[0] < bits[-2]
    for g, b in zip((1, 3, 10, 30, 100, 300), bits):
        assert A.uv_pixel_rms([0, 0], [1, 1], b, (g, g), 0.603) <= 1 / 255 or b == 16
        if b > 6:
            assert A.uv_pixel_rms([0, 0], [1, 1], b - 1, (g, g), 0.603) > 1 / 255
    # a smaller UV range (fewer texels to address) needs fewer bits
    assert A.default_bits(uvs=uv * 0.1, uv_gradient_rms=(100, 100), **kw).uvs < \
        A.default_bits(uvs=uv, uv_gradient_rms=(100, 100), **kw).uvs


def test_texture_gradient_of_an_analytic_ramp():
    BL.clear_slope_cache()
    w = h = 64
    img = np.tile((np.arange(w) * 3)[None, :], (h, 1))  # 3/255 per texel along u, constant along v
    part = _square(texture=_png(img))  # samples UVs in [0.1, 0.6]: the wrap column is never read
    gu, gv = AB.texture_gradient_rms(part)
    assert gu == pytest.approx(3 / 255 * w, rel=1e-5) and gv == 0.0
    assert AB.view_mip_level(part) == 0
    assert AB.texture_gradient_rms(_square(texture=None)) == (0.0, 0.0)  # untextured
    BL.clear_slope_cache()
    assert AB._GRAD_CACHE == {}


def test_mip_level_from_the_projected_size():
    # unit square, UV area 1, 64 texels: rho = 64 * sqrt(3) / 2^L texels per pixel at level L
    img = np.tile((np.arange(64) * 3)[None, :], (64, 1))
    part = _square(uv_lo=0.0, uv_hi=1.0, texture=_png(img))
    for level in (3, 4, 5, 6, 7, 11):
        rho = 64 * math.sqrt(3.0) / 2.0 ** level
        assert AB.view_mip_level(part, level) == max(0, math.floor(math.log2(rho)))
    assert AB.view_mip_level(part, 5) == 1
    # a coarser mip of a ramp keeps its slope per UV unit (box filter of a linear function),
    # except at the wrap: the interior samples agree
    small = _square(uv_lo=0.1, uv_hi=0.6, texture=_png(img))
    assert AB.texture_gradient_rms(small, 4)[0] == pytest.approx(AB.texture_gradient_rms(small, 11)[0], rel=1e-5)


def test_part_default_bits_textured_untextured_and_explicit_kf():
    img = (np.indices((64, 64)).sum(axis=0) % 2) * 255  # a checkerboard: the steepest texture
    textured = A.part_default_bits(_square(texture=_png(img)), DEFAULT_ANALYSE)
    plain = A.part_default_bits(_square(texture=None), DEFAULT_ANALYSE)
    assert plain == A.AttributeBits(normals=8, uvs=6, colors=None)
    assert textured.normals == 8 and textured.uvs > plain.uvs
    # an explicit texture k_f is the gradient's length
    st = AnalyseSettings(texture_kf=0.0)
    assert A.part_default_bits(_square(texture=_png(img)), st).uvs == 6
    # a larger eps never needs more bits
    loose = A.part_default_bits(_square(texture=_png(img)), AnalyseSettings(eps=4 / 255))
    assert loose.normals <= textured.normals and loose.uvs <= textured.uvs
