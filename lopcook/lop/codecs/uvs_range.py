"""UVs: ``b`` bits per component over the buffer's range, 6 <= b <= 16 (docs/format.md 7.4).

``lo``, ``hi``: float32 per component (the buffer's min/max, the LOD entry's ``uv_range``);
``N = 2^b - 1``; ``step = float32((hi - lo) / N)`` (computed in float64 from the float32 lo, hi,
rounded once; the LOD entry's ``uv_step``)::

    q  = clip(rint((u - lo) / step), 0, N), then the best of q - 1, q, q + 1 (clipped) by decoded
         error, first of equals the lowest q                                      (float64)
    u' = lo + float32(q) * step                      (float32: one rounded product, one rounded sum)

A degenerate range (hi == lo) gives step 0, all codes 0, and decodes to lo exactly. Error per
component: :func:`uv_error_bound` ``= step / 2 + (hi - lo) * 2^-24 + ulp32(max(|lo|, |hi|))``
(half a step, the rounding of ``step`` accumulated over N steps, the float32 rounding of the
result). glTF convention: origin at the top-left of the image.
"""

from __future__ import annotations

import numpy as np

from ...errors import LopcookError
from .base import F4, F32, Codec, codes_input, float_input

UV_BITS = (6, 16)


def uv_step(lo, hi, bits: int) -> np.ndarray:
    """``float32((hi - lo) / (2^bits - 1))`` per component, computed in float64 from the float32
    ``lo``, ``hi`` and rounded once; (2,) float32."""
    b = UVS.check(bits)
    lo64 = np.asarray(lo, dtype=F4).astype(np.float64).reshape(-1)
    hi64 = np.asarray(hi, dtype=F4).astype(np.float64).reshape(-1)
    return ((hi64 - lo64) / float((1 << b) - 1)).astype(np.float32)


def uv_error_bound(lo, hi, bits: int) -> np.ndarray:
    """Per-component bound on ``|u' - u|`` (UV units) for values in [lo, hi]:
    ``step / 2 + (hi - lo) * 2^-24 + ulp32(max(|lo|, |hi|))`` (float64, shape (2,))."""
    b = UVS.check(bits)
    lo64 = np.asarray(lo, dtype=F4).astype(np.float64)
    hi64 = np.asarray(hi, dtype=F4).astype(np.float64)
    step = uv_step(lo64, hi64, b).astype(np.float64)
    big = np.maximum(np.abs(lo64), np.abs(hi64)).astype(F4)
    return step / 2.0 + (hi64 - lo64) * 2.0 ** -24 + np.spacing(big).astype(np.float64)


def _uv_decode32(q: np.ndarray, lo32: np.ndarray, step32: np.ndarray) -> np.ndarray:
    return (lo32 + q.astype(np.float32) * step32).astype(np.float32)


def _outward(u: np.ndarray, low: bool) -> np.ndarray:
    """The float32 at or below the minimum (``low``) or at or above the maximum of each column
    (float64 input may lie between float32 values); zeros for no rows."""
    if not u.shape[0]:
        return np.zeros(2, dtype=F4)
    m = u.min(axis=0) if low else u.max(axis=0)
    r = m.astype(F4)
    off = r.astype(np.float64) > m if low else r.astype(np.float64) < m
    return np.where(off, np.nextafter(r, F32(-np.inf if low else np.inf)), r).astype(F4)


def encode_uvs(uvs, bits: int = 16, lo=None, hi=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Codes over the buffer's range: ``(codes (n, 2) uint16, lo (2,) float32, hi (2,) float32,
    step (2,) float32)``.

    ``lo``/``hi`` default to the per-component min/max of ``uvs`` (rounded outwards to float32;
    zeros for an empty buffer); when given they must be finite, ``lo <= hi``, and contain every
    value. Error per component <= :func:`uv_error_bound`."""
    b = UVS.check(bits)
    top = (1 << b) - 1
    u = float_input(uvs, 2, "uvs")
    lo32 = _outward(u, True) if lo is None else np.asarray(lo, dtype=F4).reshape(2)
    hi32 = _outward(u, False) if hi is None else np.asarray(hi, dtype=F4).reshape(2)
    lo32, hi32 = (lo32 + F32(0)).astype(np.float32), (hi32 + F32(0)).astype(np.float32)  # -0.0 -> +0.0
    lo64, hi64 = lo32.astype(np.float64), hi32.astype(np.float64)
    if not (np.isfinite(lo64).all() and np.isfinite(hi64).all() and (lo64 <= hi64).all()):
        raise LopcookError("emit", None, f"uv range must be finite with lo <= hi, got lo={lo64}, hi={hi64}")
    if u.shape[0] and ((u < lo64).any() or (u > hi64).any()):
        raise LopcookError("emit", None, f"uvs fall outside the given range lo={lo64}, hi={hi64}",
                           hint="omit lo/hi to use the buffer's own range")
    step32 = uv_step(lo32, hi32, b)
    step64 = step32.astype(np.float64)
    safe = np.where(step64 > 0.0, step64, 1.0)
    q0 = np.where(step64 > 0.0, np.clip(np.rint((u - lo64) / safe), 0, top), 0.0).astype(np.int64)
    best_q, best_err = None, None
    for off in (-1, 0, 1):
        q = np.where(step64 > 0.0, np.clip(q0 + off, 0, top), 0)
        err = np.abs(_uv_decode32(q, lo32, step32).astype(np.float64) - u)
        if best_q is None:
            best_q, best_err = q, err
        else:
            better = err < best_err
            best_q = np.where(better, q, best_q)
            best_err = np.where(better, err, best_err)
    return best_q.astype(np.uint16), lo32, hi32, step32


def decode_uvs(codes, lo, step, bits: int = 16) -> np.ndarray:
    """``(n, 2) float32`` uvs ``lo + float32(q) * step`` (float32) from ``(n, 2)`` integer codes."""
    b = UVS.check(bits)
    c = codes_input(codes, 2, b, "uvs")
    lo32 = np.asarray(lo, dtype=F4).reshape(2).astype(np.float32)
    step32 = np.asarray(step, dtype=F4).reshape(2).astype(np.float32)
    return _uv_decode32(c, lo32, step32)


def _is_f32_pair(v) -> bool:
    return (isinstance(v, list) and len(v) == 2
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
                    and abs(x) <= 3.4028234663852886e38 for x in v))


class Uvs(Codec):
    name, singular, components = "uvs", "uv", 2
    bits, default_bits = UV_BITS, 16
    shader = "lop_decode_uv"
    ubo = {"bits": "bits.y", "lo": "uv.xy", "step": "uv.zw"}
    error_model = "texcoord"
    lod_keys = ("uv_range", "uv_step")
    short = "uv"
    label = "UVs"
    description = "bits per UV component over each buffer's range"

    def field_widths(self, b: int) -> tuple[int, ...]:
        return (b, b)

    def encode(self, values, b: int) -> tuple[np.ndarray, dict]:
        q, lo, hi, step = encode_uvs(values, b)
        return q, {"uv_range": [[float(lo[0]), float(lo[1])], [float(hi[0]), float(hi[1])]],
                   "uv_step": [float(step[0]), float(step[1])]}

    def decode(self, codes, b: int, entry: dict) -> np.ndarray:
        if entry.get("uv_range") is None or entry.get("uv_step") is None:
            raise LopcookError("emit", None, "uv codes need their uv_range and uv_step")
        return decode_uvs(codes, np.asarray(entry["uv_range"][0], F4), np.asarray(entry["uv_step"], F4), b)

    def error_bound(self, b: int, entry: dict) -> np.ndarray:
        """Per-component bound (UV units) for the buffer whose entry holds ``uv_range``."""
        return uv_error_bound(entry["uv_range"][0], entry["uv_range"][1], b)

    def ubo_values(self, b: int, entry: dict) -> dict:
        lo = np.asarray(entry["uv_range"][0], dtype=np.float32).reshape(2)
        step = np.asarray(entry["uv_step"], dtype=np.float32).reshape(2)
        return {"bits.y": b, "uv.xy": [float(v) for v in lo], "uv.zw": [float(v) for v in step]}

    def check_entry(self, entry: dict, b, fail, where: str) -> None:
        if b is None:
            super().check_entry(entry, b, fail, where)
            return
        for key in self.lod_keys:
            if not isinstance(entry.get(key), list):
                fail(f"{where}: missing {key!r}" if key not in entry else f"{where}.{key} has the wrong type")
        rng, step = entry["uv_range"], entry["uv_step"]
        if not (isinstance(rng, list) and len(rng) == 2 and all(_is_f32_pair(r) for r in rng)):
            fail(f"{where}.uv_range must be [[lo_u, lo_v], [hi_u, hi_v]] of finite float32 numbers")
        if not (rng[0][0] <= rng[1][0] and rng[0][1] <= rng[1][1]):
            fail(f"{where}.uv_range has lo above hi")
        if not _is_f32_pair(step):
            fail(f"{where}.uv_step must be [step_u, step_v] of finite float32 numbers")
        want = ((np.asarray(rng[1], np.float32).astype(np.float64) - np.asarray(rng[0], np.float32))
                / float((1 << b) - 1)).astype(np.float32)
        if not np.array_equal(np.asarray(step, np.float64), want.astype(np.float64)):
            fail(f"{where}.uv_step is not float32((hi - lo) / (2^b_u - 1)) of its uv_range")

    def spec(self) -> dict:
        return {"encoding": "b bits per component over the buffer range (uv_range): step = float32((hi - lo) / "
                            "(2^b - 1)) (uv_step); decode float32: u = lo + float32(q) * step",
                "components": 2, "bits": list(self.bits), "per": "vertex", "record": "attributes",
                "max_error": "step / 2 + (hi - lo) * 2^-24 + ulp32(max(|lo|, |hi|))",
                "unit": "UV units per component"}


UVS = Uvs()
