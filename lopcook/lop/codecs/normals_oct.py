"""Normals: octahedral, ``b`` bits per component, 4 <= b <= 16 (docs/format.md section 7.3).

This work is based on: Cigolle, Donow, Evangelakos, Mara, McGuire, Meyer, "A Survey of Efficient
Representations for Independent Unit Vectors", JCGT 3(2), 2014, the *precise* variant.
``h = 2^(b - 1)``, ``m = h - 1``; the signed value ``s`` is in [-m, m] and **code = s + h** (in
[1, 2^b - 1]; code 0 reads as s = -h and is clamped to -1).

Decode (float32; ``R = float32(1 / m)``, rounded once)::

    p  = max(float32(code - h) * R, -1.0)                     # per component
    z  = (1 - |p.x|) - |p.y|
    if z < 0: (x, y) = ((1 - |p.y|) * sgn(p.x), (1 - |p.x|) * sgn(p.y))   else (x, y) = p
    n  = (x, y, z)                                             # UNNORMALISED float32

``sgn(x)`` is +1 for x >= 0 (including -0.0), -1 otherwise. The unnormalised vector is the
bit-exact result; the renderer (fragment shader) normalises it.

Encode (direction d, any non-zero length; float64)::

    p  = (d.x, d.y) / (|d.x| + |d.y| + |d.z|)                        # onto the octahedron
    if d.z < 0: p = ((1 - |p.y|) * sgn(p.x), (1 - |p.x|) * sgn(p.y))  # fold the lower half
    s  = clip(floor(p * m) + {0, 1}, -m, m) per component: of the 4 candidates keep the one
         whose normalised decode has the largest dot product with d (first of equals in the
         order (0,0), (1,0), (0,1), (1,1))

Error: the angle between d and the decode is at most :func:`normal_error_deg` ``(b) = 2.7 *
2^(6 - b)`` degrees for b >= 6 (11.65 at 4 bits, 5.45 at 5): 3 % above the largest angle measured
over random directions, code-cell centres, the fold and the face centres, and above Cigolle et
al.'s maxima (:data:`CIGOLLE_MAX_ERROR_DEG`). ±X, ±Y, ±Z are exact. The shared octahedral
functions (:func:`oct_encode`, :func:`oct_decode32`) also serve the tangents' codec.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import LopcookError
from .base import F32, Codec, codes_input, float_input

#: Cigolle et al. 2014, precise octahedral encoding: maximum angle (degrees) at b bits per component.
CIGOLLE_MAX_ERROR_DEG = {6: 2.6, 8: 0.64, 10: 0.16, 12: 0.039, 16: 0.0025}

#: root-mean-square angle (degrees) of the precise octahedral encoding at b bits per component,
#: measured over 20000 directions of a Fibonacci sphere (about 86 * 2^-b for b >= 8: 0.53 x the
#: maximum); tests/analyse/test_attribute_bound.py re-measures it on other directions
NORMAL_RMS_ERROR_DEG = {4: 6.081, 5: 2.855, 6: 1.384, 7: 0.6806, 8: 0.3378, 9: 0.1687, 10: 0.08388,
                        11: 0.04197, 12: 0.02096, 13: 0.01048, 14: 0.005258, 15: 0.002626, 16: 0.001311}

#: below 6 bits the error grows faster than 2^-b: measured maxima 11.42 and 5.34 degrees over the
#: test sets (random directions, code-cell centres, the fold, face centres), with a 2 % margin
SMALL_NORMAL_ERROR_DEG = {4: 11.65, 5: 5.45}

NORMAL_BITS = (4, 16)


def _sgn64(x: np.ndarray) -> np.ndarray:
    return np.where(x >= 0.0, 1.0, -1.0)


def _sgn32(x: np.ndarray) -> np.ndarray:
    return np.where(x >= F32(0.0), F32(1.0), F32(-1.0)).astype(np.float32)


def oct_decode32(cx: np.ndarray, cy: np.ndarray, bits: int) -> np.ndarray:
    """float32 decode of integer codes (any shape) -> (..., 3) unnormalised float32."""
    h = 1 << (bits - 1)
    r = F32(1.0 / (h - 1))
    one = F32(1.0)
    px = np.maximum((cx - h).astype(np.float32) * r, F32(-1.0))
    py = np.maximum((cy - h).astype(np.float32) * r, F32(-1.0))
    ax, ay = np.abs(px), np.abs(py)
    z = (one - ax) - ay
    neg = z < F32(0.0)
    x = np.where(neg, (one - ay) * _sgn32(px), px).astype(np.float32)
    y = np.where(neg, (one - ax) * _sgn32(py), py).astype(np.float32)
    return np.stack([x, y, z.astype(np.float32)], axis=-1)


def oct_encode(d: np.ndarray, b: int, what: str = "normals") -> np.ndarray:
    """Precise octahedral codes ``(n, 2) uint16`` of ``(n, 3)`` float64 directions ``d`` (finite,
    any non-zero length) at ``b`` bits; LopcookError("emit") for a zero-length vector."""
    h = 1 << (b - 1)
    m = h - 1
    if d.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.uint16)
    dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
    l1 = np.abs(dx) + np.abs(dy) + np.abs(dz)
    if not (l1 > 0.0).all():
        raise LopcookError("emit", None, f"{int((l1 <= 0.0).sum())} {what} have zero length",
                           hint=f"recompute {what} for degenerate vertices before emitting")
    px, py = dx / l1, dy / l1
    neg = dz < 0.0
    px, py = (np.where(neg, (1.0 - np.abs(py)) * _sgn64(px), px),
              np.where(neg, (1.0 - np.abs(px)) * _sgn64(py), py))
    fx = np.floor(px * m).astype(np.int64)
    fy = np.floor(py * m).astype(np.int64)
    best_x = best_y = best_dot = None
    for ox, oy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        cx = np.clip(fx + ox, -m, m) + h
        cy = np.clip(fy + oy, -m, m) + h
        v = oct_decode32(cx, cy, b).astype(np.float64)
        dot = (v[:, 0] * dx + v[:, 1] * dy + v[:, 2] * dz) / np.sqrt((v * v).sum(axis=1))
        if best_dot is None:
            best_x, best_y, best_dot = cx, cy, dot
        else:
            better = dot > best_dot
            best_x = np.where(better, cx, best_x)
            best_y = np.where(better, cy, best_y)
            best_dot = np.where(better, dot, best_dot)
    return np.stack([best_x, best_y], axis=1).astype(np.uint16)


def oct_error_deg(bits: int) -> float:
    """Worst-case angle (degrees) of the precise octahedral encoding at ``bits`` (4..16)."""
    return SMALL_NORMAL_ERROR_DEG.get(bits, 2.7 * 2.0 ** (6 - bits))


def normal_error_deg(bits: int) -> float:
    """Worst-case angle (degrees) of the precise octahedral encoding at ``bits`` per component:
    ``2.7 * 2^(6 - bits)`` for bits >= 6 (11.65 at 4 bits, 5.45 at 5); the error halves per bit."""
    return oct_error_deg(NORMALS.check(bits))


def normal_rms_error_deg(bits: int) -> float:
    """Root-mean-square angle (degrees) between directions and their precise octahedral decode at
    ``bits`` per component (:data:`NORMAL_RMS_ERROR_DEG`, measured)."""
    return NORMAL_RMS_ERROR_DEG[NORMALS.check(bits)]


def encode_normals(normals, bits: int = 16) -> np.ndarray:
    """Precise octahedral codes ``(n, 2) uint16`` (values in [1, 2^bits - 1]) of ``(n, 3)``
    directions (any non-zero length). Angle to the decoded normal <= :func:`normal_error_deg`.
    Raises LopcookError for NaN/Inf or zero-length vectors, or bits outside [4, 16]."""
    b = NORMALS.check(bits)
    return oct_encode(float_input(normals, 3, "normals"), b)


def decode_normals(codes, bits: int = 16) -> np.ndarray:
    """``(n, 3) float32`` UNNORMALISED octahedral normals from ``(n, 2)`` integer codes of
    ``bits`` bits; normalise where a unit vector is needed."""
    b = NORMALS.check(bits)
    c = codes_input(codes, 2, b, "normals")
    return oct_decode32(c[:, 0], c[:, 1], b).reshape(-1, 3)


def unit_rows(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` scaled to unit length (rows of zero length kept as they are)."""
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(length > 0, v / np.where(length > 0, length, 1), v).astype(v.dtype)


class Normals(Codec):
    name, singular, components = "normals", "normal", 3
    bits, default_bits = NORMAL_BITS, 16
    shader = "lop_decode_normal"
    ubo = {"bits": "bits.x", "scale": "scale.x"}
    error_model = "direction"
    short = "n"
    label = "normals"
    description = "octahedral bits per normal component"

    def field_widths(self, b: int) -> tuple[int, ...]:
        return (b, b)

    def encode(self, values, b: int) -> tuple[np.ndarray, dict]:
        return encode_normals(values, b), {}

    def decode(self, codes, b: int, entry: dict) -> np.ndarray:
        return decode_normals(codes, b)

    def max_error(self, b: int) -> float:
        return normal_error_deg(b)

    def rms_error(self, b: int) -> float:
        """Root-mean-square angle in radians (the bound-based bit choice's input)."""
        return math.radians(normal_rms_error_deg(b))

    def problem(self, values: np.ndarray) -> str | None:
        off = float(np.abs(np.linalg.norm(values, axis=1) - 1.0).max()) if values.size else 0.0
        return f"are not unit length (max |len-1| = {off:.3g})" if off > 1e-3 else None


    placed = True

    def unit(self, values: np.ndarray) -> np.ndarray:
        v = values.astype(np.float64)
        return (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)

    def to_world(self, values: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Normals mapped by the inverse transpose of ``a`` and normalised, float32 (computed in
        float64)."""
        m = np.asarray(values, np.float64) @ np.linalg.inv(a)  # n @ A^-1 == (A^-T n^T)^T
        ln = np.linalg.norm(m, axis=1, keepdims=True)
        return (m / np.where(ln > 0, ln, 1.0)).astype(np.float32)

    def ubo_values(self, b: int, entry: dict) -> dict:
        return {"bits.x": b, "scale.x": float(F32(1.0 / ((1 << (b - 1)) - 1)))}

    def spec(self) -> dict:
        return {"encoding": "octahedral, precise (best of 4 neighbouring codes; Cigolle et al. 2014), b bits per "
                            "component: h = 2^(b-1), m = h - 1, code = s + h; decode float32: "
                            "p = max(float32(code - h) * float32(1/m), -1); z = (1 - |p.x|) - |p.y|; "
                            "if z < 0: (x, y) = ((1 - |p.y|) sgn(p.x), (1 - |p.x|) sgn(p.y)); (x, y, z) unnormalised",
                "components": 2, "bits": list(self.bits), "per": "vertex", "record": "attributes",
                "max_error": "2.7 * 2^(6 - b) (b >= 6); 11.65 (b = 4); 5.45 (b = 5)", "unit": "degrees"}


NORMALS = Normals()
