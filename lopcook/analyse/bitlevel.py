"""Per-vertex minimum bit level from the attribute error bound, and texture slopes for k_f.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 5.1: a vertex moved by dx changes the shaded colour by at most k_f * E_v * dx, so it
needs the smallest level b with

    k_f * E_v * dx(b) <= eps          (dx(b) = sqrt(3) * extent * 2^-(b+1), metres)

k_f is the slope of the shader with respect to the attribute (colour per attribute unit): for
Phong-shaded normals ``k_s * n`` (specular coefficient times exponent), for texture coordinates
the texture's maximum slope (colour per UV unit), for vertex colours 1. ``eps`` is in colour
units (1/255 = one 8-bit step). A vertex that even 24 bits cannot satisfy gets 24 and is counted.
"""

from __future__ import annotations

import numpy as np

from ..settings import AnalyseSettings
from ..types import Texture
from ..grid import BITS, dx, smallest_level
from .attribute_bound import clear_gradient_cache


def attribute_level(e_v: np.ndarray, kf: float, eps: float, extent: float) -> np.ndarray:
    """(n,) int64: smallest b in [1, 24] with kf * e_v * dx(b) <= eps; 25 if none (caller clamps).

    e_v in attribute units per metre, kf in colour per attribute unit, eps colour, extent metres.
    Evaluated in chunks of ``_CHUNK`` vertices (the predicate is (chunk, 24): bounded temporaries)."""
    slope = float(kf) * np.asarray(e_v, dtype=np.float64)
    if slope.ndim != 1 or slope.size <= _CHUNK:
        return smallest_level(lambda b: slope[..., None] * dx(b, extent) <= eps, slope.shape)
    out = np.empty(slope.shape, dtype=np.int64)
    for s0 in range(0, slope.size, _CHUNK):
        part = slope[s0:s0 + _CHUNK]
        out[s0:s0 + _CHUNK] = smallest_level(lambda b: part[..., None] * dx(b, extent) <= eps, part.shape)
    return out


#: vertices per chunk of ``attribute_level``
_CHUNK = 1 << 16


_SLOPE_CACHE: dict[str, float] = {}


def texture_slope(texture: Texture) -> float:
    """Maximum slope of a texture in colour per UV unit (colour in [0, 1] as stored, 8-bit / 255).

    Forward differences between neighbouring texels along u and v (wrapping, as a repeating
    texture does), scaled by the texture size to UV units, combined as the gradient norm
    sqrt(d/du^2 + d/dv^2) per channel; the maximum over texels and channels (alpha included)."""
    key = texture.digest
    if key in _SLOPE_CACHE:
        return _SLOPE_CACHE[key]
    img = texture.image()
    if img.mode not in ("RGB", "RGBA", "L", "LA"):
        img = img.convert("RGBA")
    a = np.asarray(img, dtype=np.float32) / 255.0
    if a.ndim == 2:
        a = a[:, :, None]
    h, w = a.shape[:2]
    du = (np.roll(a, -1, axis=1) - a) * w
    dv = (np.roll(a, -1, axis=0) - a) * h
    slope = float(np.sqrt(du * du + dv * dv).max())
    _SLOPE_CACHE[key] = slope
    return slope


def clear_slope_cache() -> None:
    """Forget the texture slopes computed so far in this process (``texture_slope`` caches them by
    texture digest) and the gradient images of the attribute bound (``attribute_bound``), so
    that the next analysis pays what a fresh cook pays."""
    _SLOPE_CACHE.clear()
    clear_gradient_cache()


def attribute_kf(part, settings: AnalyseSettings) -> dict:
    """k_f per attribute present on ``part`` (colour per attribute unit); 0 means ignored."""
    kf = {}
    if part.normals is not None:
        kf["normal"] = settings.normal_kf
    if part.uvs is not None and settings.texture_kf != "off":
        if settings.kf is not None:
            kf["uv"] = float(settings.kf)
        elif isinstance(settings.texture_kf, (int, float)):
            kf["uv"] = float(settings.texture_kf)
        elif part.texture is not None:
            kf["uv"] = texture_slope(part.texture)
        else:
            kf["uv"] = float(settings.untextured_uv_kf)
    if part.colors is not None:
        kf["color"] = float(settings.kf) if settings.kf is not None else settings.color_kf
    return kf


__all__ = ["attribute_level", "attribute_kf", "texture_slope", "clear_slope_cache", "BITS"]
