"""Tangents: octahedral xyz at ``b`` bits per component plus one sign bit, 4 <= b <= 16.

A glTF ``TANGENT`` (or USD ``tangents`` primvar) is a unit vector ``t`` in the surface and a
handedness ``w = +-1`` (the bitangent is ``w * cross(n, t)``). The record holds three fields:
``tangent.u``, ``tangent.v`` (the precise octahedral code of ``t`` at b bits, exactly as normals:
``lopcook.lop.codecs.normals_oct``, Cigolle et al. 2014) and ``tangent.sign`` (1 bit: 1 for
``w < 0``). Decode (float32): ``(x, y, z)`` the unnormalised octahedral decode, ``w = -1.0`` when
the sign bit is set, else ``+1.0``. The angle between ``t`` and the normalised decode is at most
``normal_error_deg(b)``; ``w`` is exact.

A placement maps tangents by its matrix ``A`` (tangents are directions in the surface, not
normals): ``xyz -> A xyz`` normalised, ``w -> w * sign(det A)``.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import LopcookError
from .base import F32, Codec, codes_input, float_input
from .normals_oct import NORMAL_BITS, NORMAL_RMS_ERROR_DEG, oct_decode32, oct_encode, oct_error_deg, unit_rows


def encode_tangents(tangents, bits: int = 16) -> np.ndarray:
    """Codes ``(n, 3) uint16``: the octahedral code of each ``(n, 4)`` tangent's xyz (any non-zero
    length) and its sign bit (1 when w < 0)."""
    b = TANGENTS.check(bits)
    t = float_input(tangents, 4, "tangents")
    oct_codes = oct_encode(t[:, :3], b, "tangents")
    return np.concatenate([oct_codes, (t[:, 3:] < 0.0).astype(np.uint16)], axis=1)


def decode_tangents(codes, bits: int = 16) -> np.ndarray:
    """``(n, 4) float32``: the UNNORMALISED octahedral xyz and w = +-1.0 of ``(n, 3)`` codes."""
    b = TANGENTS.check(bits)
    c = codes_input(codes, 3, b, "tangents")
    if c.size and int(c[:, 2].max()) > 1:
        raise LopcookError("emit", None, "tangent sign codes must be 0 or 1")
    xyz = oct_decode32(c[:, 0], c[:, 1], b).reshape(-1, 3)
    w = np.where(c[:, 2:] == 1, F32(-1.0), F32(1.0)).astype(np.float32)
    return np.concatenate([xyz, w], axis=1)


class Tangents(Codec):
    name, singular, label, components = "tangents", "tangent", "tangents", 4
    short = "t"
    bits, default_bits = NORMAL_BITS, 16
    format_major = 4
    shader = "lop_decode_tangent"
    ubo = {"bits": "params.y", "scale": "scale.z"}
    error_model = "direction"
    placed = True
    description = "octahedral bits per tangent component (plus its sign bit)"

    def field_widths(self, b: int) -> tuple[int, ...]:
        return (b, b, 1)

    def encode(self, values, b: int) -> tuple[np.ndarray, dict]:
        return encode_tangents(values, b), {}

    def decode(self, codes, b: int, entry: dict) -> np.ndarray:
        return decode_tangents(codes, b)

    def max_error(self, b: int) -> float:
        return oct_error_deg(self.check(b))

    def rms_error(self, b: int) -> float:
        """Root-mean-square angle in radians (the octahedral codec's, as normals)."""
        return math.radians(NORMAL_RMS_ERROR_DEG[self.check(b)])

    def problem(self, values: np.ndarray) -> str | None:
        off = float(np.abs(np.linalg.norm(values[:, :3], axis=1) - 1.0).max()) if values.size else 0.0
        if off > 1e-3:
            return f"are not unit length (max |len-1| = {off:.3g})"
        if values.size and not np.isin(values[:, 3], (-1.0, 1.0)).all():
            return "have a handedness w other than +1 or -1"
        return None


    def unit(self, values: np.ndarray) -> np.ndarray:
        v = values[:, :3].astype(np.float64)
        xyz = (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)
        return np.concatenate([xyz, values[:, 3:].astype(np.float32)], axis=1)

    def to_world(self, values: np.ndarray, a: np.ndarray) -> np.ndarray:
        m = np.asarray(values[:, :3], np.float64) @ np.asarray(a, np.float64).T  # A t
        ln = np.linalg.norm(m, axis=1, keepdims=True)
        w = np.asarray(values[:, 3:], np.float64) * (1.0 if np.linalg.det(a) > 0 else -1.0)
        return np.concatenate([m / np.where(ln > 0, ln, 1.0), w], axis=1).astype(np.float32)

    def ubo_values(self, b: int, entry: dict) -> dict:
        return {"params.y": b, "scale.z": float(F32(1.0 / ((1 << (b - 1)) - 1)))}

    def spec(self) -> dict:
        return {"encoding": "tangent xyz octahedral, precise, b bits per component, as normals (code = s + h, "
                            "h = 2^(b-1)); then 1 sign bit: w = -1 when set, else +1; decode float32: "
                            "(x, y, z) unnormalised as normals, w",
                "components": 3, "bits": list(self.bits), "per": "vertex", "record": "attributes",
                "max_error": "2.7 * 2^(6 - b) (b >= 6); 11.65 (b = 4); 5.45 (b = 5); w exact",
                "unit": "degrees"}


TANGENTS = Tangents()
