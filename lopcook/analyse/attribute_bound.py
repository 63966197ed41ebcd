"""Inputs of the average-case (screen-space) bound on the bits of normals and UVs.

The bit choice itself is ``lopcook.analyse.attribute_bits.default_bits``; this module measures what it
needs from the scene and the shading: how strongly the harness's lighting responds to a normal
error and to a change of the base colour, and how steep a part's texture is where the surface
samples it. Derivation and measurements: docs/attributes.md, "The average-case bound".

Lighting model (the verify harness's, ``lopcook.verify.glsl.FS``; the constants are repeated here
because analyse precedes verify, and ``tests/analyse/test_attribute_bound.py`` checks they agree): Phong
with a headlight (light direction = view direction), base colour ``c`` in [0, 1]::

    s(theta) = c (a + d cos theta) + ks cos^n(2 theta)   (the specular term only where 2 theta < 90)

theta the angle between the normal and the light (= the eye: the reflection is 2 theta off the eye).
Over the pixels of a convex object whose surface normals are spread uniformly over directions, the
facing normals have the projected-area density ``p(theta) = sin(2 theta)`` on [0, pi/2]
(``_THETA_WEIGHTS``). Two averages of the shading over that density (``shading_rms``):

* ``slope_rms = sqrt(E[(ds/dtheta)^2])`` with c = 1 (white: the largest diffuse slope), colour per
  radian of normal tilt. A normal error of angle delta tilts theta by ``delta cos(phi)``, phi the
  error's direction in the tangent plane, so the mean square colour change is
  ``slope_rms^2 * delta^2 / 2``.
* ``lighting_rms = sqrt(E[(a + d cos theta)^2])``: what a change of the base colour is multiplied by.

Texture gradient (``texture_gradient_rms``): the root mean square, over the part's surface area
(7 fixed barycentric samples per triangle weighted by its area, the density of the pixels the
surface covers on screen), of the forward-difference derivative of the texture along u and along v
(colour per UV unit, averaged over the RGB channels, nearest texel, wrapping) at the mip level the
harness samples at the design view (``view_mip_level``). The mip level: at per-buffer level B a
camera of the harness sees the scene's bounding box at the distance where it spans about
``2^B / sqrt(3)`` pixels (``lopcook.verify.cameras``); the part's own largest box side is used for
the extent, which can only overestimate the pixels per metre (a part is at most as large as the
scene), so the mip level can only be too fine and the gradient too large (conservative). Texels
per pixel ``rho = R sqrt(A_uv / A) / (2^B / (sqrt(3) extent))`` (R the texture's larger side,
A_uv the part's UV area, A its surface area in square metres); the mip level is
``max(0, floor(log2(rho)))``, the finer of the two levels the trilinear filter blends (again the
larger gradient). Design level ``VIEW_LEVEL = 11``: the per-buffer level at which bits per vertex
and quality targets are stated. slope_rms and lighting_rms at the harness's defaults (0.693 per
radian, 0.603) and their derivation: docs/attributes.md.
"""

from __future__ import annotations

import math

import numpy as np

from ..types import Texture

#: the verify harness's Phong ambient and diffuse weights (lopcook.verify.renderer.AMBIENT / DIFFUSE)
HARNESS_AMBIENT = 0.15
HARNESS_DIFFUSE = 0.65
#: per-buffer level of the design view (the level bits per vertex and PSNR targets are stated at)
VIEW_LEVEL = 11
#: barycentric sample points per triangle for the area-weighted texture statistics
_BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.2, 0.6],
                  [0.45, 0.45, 0.1], [0.45, 0.1, 0.45], [0.1, 0.45, 0.45]])
#: integration grid over theta in [0, pi/2] (midpoints)
_N_THETA = 8192

_GRAD_CACHE: dict[tuple[str, int], tuple[np.ndarray, np.ndarray]] = {}


def shading_rms(ks: float, shininess: float, ambient: float = HARNESS_AMBIENT,
                diffuse: float = HARNESS_DIFFUSE) -> tuple[float, float]:
    """(slope_rms, lighting_rms) of the headlight Phong shading (module doc): slope_rms in colour
    per radian of normal tilt (white base), lighting_rms dimensionless; both the root mean square
    over the projected-area density ``sin(2 theta)`` of facing normals (midpoint rule, 8192 steps:
    deterministic, relative error < 1e-6 for shininess <= 1000)."""
    ks, n, a, d = float(ks), float(shininess), float(ambient), float(diffuse)
    if not all(math.isfinite(v) and v >= 0 for v in (ks, n, a, d)):
        raise ValueError(f"ks, shininess, ambient, diffuse must be finite numbers >= 0, got {ks, n, a, d}")
    th = (np.arange(_N_THETA, dtype=np.float64) + 0.5) * (0.5 * math.pi / _N_THETA)
    w = np.sin(2.0 * th)
    w /= w.sum()
    c2 = np.cos(2.0 * th)
    lobe = c2 > 0.0
    dspec = np.zeros_like(th)
    if n > 0:
        dspec[lobe] = -2.0 * n * ks * c2[lobe] ** (n - 1.0) * np.sin(2.0 * th[lobe])
    slope = -d * np.sin(th) + dspec
    light = a + d * np.cos(th)
    return float(math.sqrt((w * slope * slope).sum())), float(math.sqrt((w * light * light).sum()))


def _areas_and_uv_areas(part) -> tuple[np.ndarray, float]:
    p = np.asarray(part.positions, dtype=np.float64)
    t = np.asarray(part.indices, dtype=np.int64)
    a = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    u = np.asarray(part.uvs, dtype=np.float64)
    e1, e2 = u[t[:, 1]] - u[t[:, 0]], u[t[:, 2]] - u[t[:, 0]]
    return a, float(0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())


def view_mip_level(part, level: int = VIEW_LEVEL) -> int:
    """Mip level (int >= 0) the harness's trilinear filter samples ``part``'s texture at, seen at
    per-buffer level ``level`` (module doc: ``max(0, floor(log2(rho)))``, rho texels per pixel at
    the nearest point, the part's extent standing for the scene's). 0 without texture, UVs or area."""
    if part.texture is None or part.uvs is None or len(part.indices) == 0:
        return 0
    a, a_uv = _areas_and_uv_areas(part)
    area = float(a.sum())
    pos = np.asarray(part.positions, dtype=np.float64)
    extent = float((pos.max(axis=0) - pos.min(axis=0)).max())
    if not (area > 0 and a_uv > 0 and extent > 0):
        return 0
    w, h = part.texture.image().size
    rho = max(w, h) * math.sqrt(a_uv / area) / (2.0 ** int(level) / (math.sqrt(3.0) * extent))
    return max(0, int(math.floor(math.log2(rho)))) if rho > 0 else 0


def _gradient_images(texture: Texture, mip: int) -> tuple[np.ndarray, np.ndarray]:
    """(h, w) float32 squared forward-difference derivatives along u and v (colour per UV unit,
    squared, mean over RGB) of the texture's mip level ``mip`` (2x2 box filter per level)."""
    key = (texture.digest, int(mip))
    if key in _GRAD_CACHE:
        return _GRAD_CACHE[key]
    a = np.asarray(texture.image().convert("RGB"), dtype=np.float32) / np.float32(255.0)
    for _ in range(int(mip)):
        h, w = a.shape[:2]
        if h < 2 or w < 2:
            break
        h2, w2 = h // 2 * 2, w // 2 * 2
        a = 0.25 * (a[0:h2:2, 0:w2:2] + a[1:h2:2, 0:w2:2] + a[0:h2:2, 1:w2:2] + a[1:h2:2, 1:w2:2])
    h, w = a.shape[:2]
    du = (np.roll(a, -1, axis=1) - a) * np.float32(w)
    dv = (np.roll(a, -1, axis=0) - a) * np.float32(h)
    out = ((du * du).mean(axis=2), (dv * dv).mean(axis=2))
    _GRAD_CACHE.clear()  # one texture's images at a time (2048^2: 32 MB)
    _GRAD_CACHE[key] = out
    return out


def texture_gradient_rms(part, level: int = VIEW_LEVEL) -> tuple[float, float]:
    """(g_u, g_v): root mean square over the part's surface area of the texture's derivative along
    u and along v, colour per UV unit, at ``view_mip_level(part, level)`` (module doc). (0, 0)
    for a part without texture or UVs (a UV set with no texture cannot change a colour)."""
    if part.texture is None or part.uvs is None or len(part.indices) == 0:
        return 0.0, 0.0
    mip = view_mip_level(part, level)
    gu2, gv2 = _gradient_images(part.texture, mip)
    h, w = gu2.shape
    a, _ = _areas_and_uv_areas(part)
    if not a.sum() > 0:
        return 0.0, 0.0
    u = np.asarray(part.uvs, dtype=np.float64)[np.asarray(part.indices, dtype=np.int64)]  # (m, 3, 2)
    s = np.einsum("kj,tjc->tkc", _BARY, u).reshape(-1, 2)
    x = np.floor(np.mod(s[:, 0], 1.0) * w).astype(np.int64) % w
    y = np.floor(np.mod(s[:, 1], 1.0) * h).astype(np.int64) % h
    wt = np.repeat(a, len(_BARY))
    tot = float(wt.sum())
    return (float(math.sqrt(float((gu2[y, x] * wt).sum()) / tot)),
            float(math.sqrt(float((gv2[y, x] * wt).sum()) / tot)))


def clear_gradient_cache() -> None:
    """Forget the cached gradient images (``texture_gradient_rms``)."""
    _GRAD_CACHE.clear()


__all__ = ["HARNESS_AMBIENT", "HARNESS_DIFFUSE", "VIEW_LEVEL", "shading_rms", "view_mip_level",
           "texture_gradient_rms", "clear_gradient_cache"]
