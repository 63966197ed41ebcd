"""The bits of each part's attributes: the bound-based default and the worst-case bound.

This work is based on: Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex Compression
Using Quantization and Simplification", Graphics Hardware 2005, section 3 (bits per attribute
from the image error they cause); Meyer et al. 2011, section 5.1 (the per-vertex bound eps).

Each codec names an ``error_model`` (``lopcook.lop.codecs``); this module turns a model's error
at b bits into a change of a pixel's colour and picks, per attribute, the fewest bits in the
codec's range within ``eps`` (colour units; the largest allowed when none is). Derivation and
measurements: docs/attributes.md.

Bound-based default (:func:`default_bits`): the **root-mean-square** change of a pixel's colour,
the quantity the verify harness's PSNR sees (vertex errors independent, interpolated with
barycentric weights w: E[sum w_i^2] = 1/2 over a triangle, hence a factor sqrt(1/2)):

* ``direction`` (normals, tangents): ``0.5 * slope_rms * rms_angle(b)``, the codec's RMS angle in
  radians, ``slope_rms`` the shading's RMS slope per radian (0.693 with ks 0.5, n 32; the 0.5 is
  sqrt(1/2) for the error's direction in the tangent plane times sqrt(1/2) for the
  interpolation). 1/255 gives 8 bits.
* ``texcoord`` (UVs): ``lighting_rms * sqrt(1/2) * sqrt(((g_u s_u)^2 + (g_v s_v)^2) / 12)``, s the
  step over the part's range (rounding uniform in +-s/2), g the texture's RMS derivative per UV
  unit (``attribute_bound.texture_gradient_rms``), lighting_rms = 0.603 the diffuse factor.
  An untextured part has g = 0: the fewest bits.
* ``color``: the worst case below.

Worst-case bound (:func:`worst_case_bits`): every vertex at its largest error at the steepest point
of the shading: ``direction_kf * radians(max_angle(b))``, ``texcoord_kf * |error_bound(b)|``,
``color_kf * max_error(b)``, each ``<= eps``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from ..lop.codecs import CODECS, AttributeBits, Codec
from ..lop.codecs.base import F4, float_input
from ..lop.codecs.normals_oct import NORMALS
from ..lop.codecs.uvs_range import UVS, uv_error_bound, uv_step
from .attribute_bound import shading_rms, texture_gradient_rms
from .bitlevel import attribute_kf


@dataclass(frozen=True)
class ImageModel:
    """What an attribute error costs in the image, per error model.

    eps : colour units, the largest allowed change. slope_rms : RMS colour per radian of a
    direction's tilt; direction_kf : its worst case, colour per unit vector change.
    gradient_rms : (g_u, g_v) RMS texture derivative, colour per UV unit; texcoord_kf : its worst
    case, the texture's slope. lighting_rms : the factor a base-colour change is multiplied by.
    color_kf : colour per unit of a vertex colour."""

    eps: float
    slope_rms: float = 0.0
    direction_kf: float = 0.0
    gradient_rms: tuple[float, float] = (0.0, 0.0)
    texcoord_kf: float = 0.0
    lighting_rms: float = 1.0
    color_kf: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.eps) and self.eps > 0):
            raise LopcookError("usage", None, f"eps must be a finite number > 0, got {self.eps}")


def normal_pixel_rms(bits: int, slope_rms: float, codec: Codec = NORMALS) -> float:
    """RMS change of a pixel's colour (colour units) caused by ``bits``-bit directions of
    ``codec`` under a shading of RMS slope ``slope_rms``: ``0.5 * slope_rms * rms_angle``."""
    return 0.5 * float(slope_rms) * codec.rms_error(codec.check(bits))


def uv_pixel_rms(lo, hi, bits: int, gradient_rms, lighting_rms: float) -> float:
    """RMS change of a pixel's colour (colour units) caused by ``bits``-bit UVs over [lo, hi] on a
    texture of RMS derivatives ``gradient_rms`` = (g_u, g_v) lit by ``lighting_rms``."""
    b = UVS.check(bits)
    step = uv_step(np.asarray(lo, dtype=F4).astype(np.float64), np.asarray(hi, dtype=F4).astype(np.float64), b)
    g = np.asarray(gradient_rms, dtype=np.float64).reshape(2)
    return float(lighting_rms) * math.sqrt(0.5 * float(np.sum((g * step.astype(np.float64)) ** 2)) / 12.0)


def _uv_range(uvs) -> tuple[np.ndarray, np.ndarray]:
    """(2,) per-component minimum and maximum of (n, 2) UVs (zeros for no vertices)."""
    u = float_input(uvs, 2, "uvs")
    return (u.min(axis=0), u.max(axis=0)) if u.shape[0] else (np.zeros(2), np.zeros(2))


def _fewest(codec: Codec, ok) -> int:
    """The smallest b in the codec's range with ``ok(b)``; its largest when none has."""
    lo, hi = codec.bits
    return next((b for b in range(lo, hi + 1) if ok(b)), hi)


def _rms_ok(codec: Codec, values, m: ImageModel):
    if codec.error_model == "direction":
        return lambda b: normal_pixel_rms(b, m.slope_rms, codec) <= m.eps
    if codec.error_model == "texcoord":
        lo, hi = _uv_range(values)
        return lambda b: uv_pixel_rms(lo, hi, b, m.gradient_rms, m.lighting_rms) <= m.eps
    return _worst_ok(codec, values, m)


def _worst_ok(codec: Codec, values, m: ImageModel):
    if codec.error_model == "direction":
        return lambda b: float(m.direction_kf) * math.radians(codec.max_error(b)) <= m.eps
    if codec.error_model == "texcoord":
        lo, hi = _uv_range(values)
        return lambda b: float(m.texcoord_kf) * float(np.linalg.norm(uv_error_bound(lo, hi, b))) <= m.eps
    return lambda b: float(m.color_kf) * codec.max_error(b) <= m.eps


def default_bits(attrs: Mapping, model: ImageModel) -> AttributeBits:
    """The bound-based bits of one part's attributes ``{codec name: (n, k) values or None}``: per
    present attribute the fewest bits whose RMS pixel change stays within ``model.eps``."""
    return AttributeBits(**{c.name: _fewest(c, _rms_ok(c, attrs[c.name], model))
                            for c in CODECS if attrs.get(c.name) is not None})


def worst_case_bits(attrs: Mapping, model: ImageModel) -> AttributeBits:
    """The worst-case bound's bits (module doc; kept for comparison with the default)."""
    return AttributeBits(**{c.name: _fewest(c, _worst_ok(c, attrs[c.name], model))
                            for c in CODECS if attrs.get(c.name) is not None})


def part_model(part, analyse_settings, kf: dict | None = None) -> ImageModel:
    """The ImageModel of a MeshPart under AnalyseSettings (eps, ks, shininess, kf, texture_kf):
    the harness's Phong shading (``attribute_bound.shading_rms``), the part's texture gradient at
    the design view (0 without a texture). An explicit k_f (``analyse_settings.kf``, or a numeric
    ``texture_kf`` for UVs) is taken as the RMS slope instead (the gradient's length split
    equally between u and v). ``kf``: a PartAnalysis's k_f (its colour entry), else
    ``attribute_kf``."""
    st = analyse_settings
    kf = attribute_kf(part, st) if kf is None else kf
    slope_rms, lighting_rms = shading_rms(st.ks, st.shininess)
    if st.kf is not None:
        slope_rms = float(st.kf)
    grad = (0.0, 0.0)
    if part.uvs is not None:
        explicit = float(st.kf) if st.kf is not None else (
            float(st.texture_kf) if isinstance(st.texture_kf, (int, float)) else None)
        grad = (explicit / math.sqrt(2.0),) * 2 if explicit is not None else texture_gradient_rms(part)
    return ImageModel(eps=float(st.eps), slope_rms=slope_rms, gradient_rms=grad, lighting_rms=lighting_rms,
                      color_kf=float(kf.get("color", 0.0)))


def part_default_bits(part, analyse_settings, kf: dict | None = None) -> AttributeBits:
    """:func:`default_bits` of a MeshPart's attributes under its :func:`part_model`."""
    return default_bits(part.attributes, part_model(part, analyse_settings, kf))


def part_bits(settings, index: int, part, part_analysis=None) -> AttributeBits:
    """The attribute bits of scene part ``index`` (a MeshPart) under ``settings`` (a Settings):
    ``settings.attributes.requested(index)`` where it gives a number, else
    :func:`part_default_bits` (with the k_f of ``part_analysis``, its PartAnalysis, when given)."""
    try:
        req = settings.attributes.requested(index)
    except ValueError as exc:
        raise LopcookError("usage", None, str(exc), hint="give one entry of bits per part") from None
    present = [c.name for c in CODECS if part.attributes.get(c.name) is not None]
    if any(req.get(name) is None for name in present):
        d = part_default_bits(part, settings.analyse, None if part_analysis is None else part_analysis.kf)
        req = {name: d.get(name) if req.get(name) is None else req[name] for name in present}
    return AttributeBits(**{name: req[name] for name in present})
