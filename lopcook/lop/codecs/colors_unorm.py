"""Colours: RGBA linear, ``b`` bits per channel, 4 <= b <= 8 (docs/format.md section 7.4).

``N = 2^b - 1``: ``q = rint(clip(c, 0, 1) * N)`` (float64, half to even); decode
``c' = float32(q) * float32(1 / N)`` (float32). Values outside [0, 1] are clamped first, and no
sRGB transfer is applied. Error per channel for inputs in [0, 1]: ``1 / (2 N)`` plus float32
rounding (:func:`color_error_bound`).
"""

from __future__ import annotations

import numpy as np

from .base import F32, Codec, codes_input, float_input

COLOR_BITS = (4, 8)


def color_error_bound(bits: int) -> float:
    """Bound on ``|c' - c|`` per channel for c in [0, 1]: ``1 / (2 (2^b - 1))`` plus 2^-24
    (float32 rounding of the decode)."""
    b = COLORS.check(bits)
    return 1.0 / (2.0 * ((1 << b) - 1)) + 2.0 ** -24


def encode_colors(colors, bits: int = 8) -> np.ndarray:
    """RGBA codes ``(n, 4) uint16`` in [0, 2^bits - 1]; inputs clamped to [0, 1]; error <=
    :func:`color_error_bound`."""
    b = COLORS.check(bits)
    c = float_input(colors, 4, "colors")
    return np.rint(np.clip(c, 0.0, 1.0) * float((1 << b) - 1)).astype(np.uint16)


def decode_colors(codes, bits: int = 8) -> np.ndarray:
    """``(n, 4) float32`` linear RGBA ``float32(q) * float32(1 / (2^bits - 1))``."""
    b = COLORS.check(bits)
    c = codes_input(codes, 4, b, "colors")
    return (c.astype(np.float32) * F32(1.0 / ((1 << b) - 1))).astype(np.float32)


class Colors(Codec):
    name, singular, components = "colors", "color", 4
    bits, default_bits = COLOR_BITS, 8
    shader = "lop_decode_color"
    ubo = {"bits": "bits.z", "scale": "scale.y"}
    error_model = "color"
    short = "c"
    label = "colours"
    description = "bits per vertex-colour channel"

    def field_widths(self, b: int) -> tuple[int, ...]:
        return (b, b, b, b)

    def encode(self, values, b: int) -> tuple[np.ndarray, dict]:
        return encode_colors(values, b), {}

    def decode(self, codes, b: int, entry: dict) -> np.ndarray:
        return decode_colors(codes, b)

    def max_error(self, b: int) -> float:
        return color_error_bound(b)


    def ubo_values(self, b: int, entry: dict) -> dict:
        return {"bits.z": b, "scale.y": float(F32(1.0 / ((1 << b) - 1)))}

    def spec(self) -> dict:
        return {"encoding": "RGBA linear, b bits per channel, inputs clamped to [0, 1]: q = rint(c (2^b - 1)); "
                            "decode float32: c = float32(q) * float32(1 / (2^b - 1))",
                "components": 4, "bits": list(self.bits), "per": "vertex", "record": "attributes",
                "max_error": "1 / (2 (2^b - 1)) + 2^-24", "unit": "linear [0, 1] per channel"}


COLORS = Colors()
