"""Compact encodings of the non-position vertex data stored in a .lop container.

Every encoder is vectorised numpy, deterministic (the same input gives the same bytes on every
platform: only IEEE-exact operations -- add, multiply, divide, sqrt, floor, rint -- in a fixed
order, in float64) and writes explicit little-endian dtypes, so ``codes.tobytes()`` is the
section payload. Every decoder is exact with respect to its encoder's byte layout and is the
*reference* decode (shaders may evaluate the same formula in float32 and differ by a few ulp).
The bounds below are also available as data from :func:`attribute_specs` (for the manifest).

Normals -- octahedral, 2 x 16 bits (``"<u2"``), 4 bytes per vertex
-----------------------------------------------------------------------
Cigolle, Donow, Evangelakos, Mara, McGuire, Meyer, "A Survey of Efficient Representations for
Independent Unit Vectors", JCGT 3(2), 2014, precise variant (32 bits per normal: "oct32P" in
the paper's naming, i.e. 16 bits per component).

Layout: per vertex ``[u, v]``, each ``<u2``; ``s = code - 32768`` is the snorm16 value (the code
is the int16 two's-complement value with its sign bit flipped, ``s = int16(code ^ 0x8000)``).

Encode (direction d, any non-zero length)::

    p  = (d.x, d.y) / (|d.x| + |d.y| + |d.z|)                       # onto the octahedron
    if d.z < 0: p = ((1 - |p.y|) * sgn(p.x), (1 - |p.x|) * sgn(p.y))  # fold the lower half
    s  = floor(p * 32767) + {0, 1} per component (4 candidates, clamped to [-32767, 32767]);
         keep the candidate whose decoded normal (float64, before rounding to float32) has
         the largest dot product with d
         (first of equals in the order (0,0), (1,0), (0,1), (1,1))
    code = s + 32768                                                # in [1, 65535]

``sgn(x)`` is +1 for x >= 0 (including -0.0) and -1 otherwise, so -0.0 encodes like +0.0.

Decode::

    p = clamp((code - 32768) / 32767, -1, 1)                        # code 0 reads as -1
    n = (p.x, p.y, 1 - |p.x| - |p.y|)
    if n.z < 0: (n.x, n.y) = ((1 - |p.y|) * sgn(p.x), (1 - |p.x|) * sgn(p.y))
    n = n / |n|  (float64, then rounded to float32)

Error: the axis directions +-X, +-Y, +-Z are represented exactly (s in {-32767, 0, 32767}) and
decode to exactly (0, 0, +-1) etc. The worst-case angle between d and the decoded normal is
**at most 0.0038 degrees** (:data:`NORMAL_MAX_ERROR_DEG`), by this argument: the kept code is at
least as close as plain rounding, whose error in p is at most |dp| = (sqrt(2)/2) / 32767; the
map from p to the octahedron surface is piecewise linear with Lipschitz constant sqrt(3); every
point of the octahedron |x|+|y|+|z| = 1 is at distance >= 1/sqrt(3) from the origin, so the angle
is <= 3 |dp| = 6.474e-5 rad = 0.003709 degrees, plus < 1e-5 degrees for rounding the result to
float32. The candidate search keeps the error well under that: the empirical bound
**0.00248 degrees** (:data:`NORMAL_MEASURED_MAX_ERROR_DEG`) holds over the test sets of
``docs/measurements.md`` (random directions, face centres and diagonals, the fold z = 0, cell
centres) and is checked by ``tests/test_attributes.py``.

UVs -- unorm16 over the buffer's range, 2 x 16 bits (``"<u2"``), 4 bytes per vertex + 16 bytes
--------------------------------------------------------------------------------------------------
Layout: per vertex ``[qu, qv]`` each ``<u2``; per buffer ``lo`` and ``hi``, each ``(2,) <f4``
(stored by the caller; by default ``lo``/``hi`` are the per-component min/max of the buffer).

    q = rint((u - lo) / (hi - lo) * 65535)          (float64; round half to even)
    u' = float32(lo * (1 - q / 65535) + hi * (q / 65535))      (float64, then float32)

so q = 0 decodes to ``lo`` and q = 65535 to ``hi`` exactly. Error per component:
``|u' - u| <= (hi - lo) / 131070`` (half a step of (hi - lo) / 65535) plus half a float32 ulp of
the result (``<= ulp32(max(|lo|, |hi|)) / 2``) -- e.g. 7.6e-6 for a [0, 1] range. A degenerate
range (hi == lo, e.g. one vertex or a constant coordinate) gives all codes 0 and decodes to
``lo`` exactly.

Colors -- RGBA unorm8 (``"u1"``), 4 bytes per vertex
-------------------------------------------------------
Layout: per vertex ``[r, g, b, a]``, each ``u1``, linear (no sRGB transfer).

    q = rint(clamp(c, 0, 1) * 255)          c' = float32(q / 255)

Values outside [0, 1] are clamped first (a linear colour above 1 becomes 1). Error per channel
for inputs in [0, 1]: ``|c' - c| <= 1/510`` (+ half a float32 ulp, < 3e-8).

Indices -- uint16 or uint32 (``"<u2"`` / ``"<u4"``), 6 or 12 bytes per triangle
-------------------------------------------------------------------------------------
Layout: the triangles' corners in order, ``i0 i1 i2 i0 i1 i2 ...``. The width is 2 bytes when
``n_vertices <= 65535`` (every index <= 65534: the uint16 primitive-restart value 65535, always on
in WebGL 2 and Metal, never appears) and 4 bytes otherwise. Exact.

Non-finite input (and zero-length normals) raises ``LopcookError("emit", ...)``.
"""

from __future__ import annotations

import copy

import numpy as np

from ..errors import LopcookError

__all__ = [
    "NORMAL_MAX_ERROR_DEG",
    "NORMAL_MEASURED_MAX_ERROR_DEG",
    "UV_MAX_ERROR_FRACTION",
    "COLOR_MAX_ERROR",
    "UV_RANGE_BYTES",
    "BYTES_PER_VERTEX",
    "encode_normals",
    "decode_normals",
    "encode_uvs",
    "decode_uvs",
    "encode_colors",
    "decode_colors",
    "encode_indices",
    "decode_indices",
    "index_width",
    "encoded_nbytes",
    "attribute_specs",
]

#: Guaranteed worst-case angle (degrees) between a normal and its decoded normal (see above).
NORMAL_MAX_ERROR_DEG = 0.0038
#: Largest angle (degrees) measured over the test sets of docs/measurements.md (an empirical bound).
NORMAL_MEASURED_MAX_ERROR_DEG = 0.00248
#: UV error per component as a fraction of the buffer's range (hi - lo), before float32 rounding.
UV_MAX_ERROR_FRACTION = 1.0 / 131070.0
#: Colour error per channel (linear [0, 1] units) for inputs in [0, 1], before float32 rounding.
COLOR_MAX_ERROR = 1.0 / 510.0
#: Bytes per buffer for the UV range: lo (2 x <f4) then hi (2 x <f4).
UV_RANGE_BYTES = 16
#: Encoded bytes per vertex of each per-vertex attribute.
BYTES_PER_VERTEX = {"normals": 4, "uvs": 4, "colors": 4}

_SNORM16 = 32767
_OFFSET16 = 32768
_UNORM16 = 65535
_UNORM8 = 255
_U2 = np.dtype("<u2")
_U4 = np.dtype("<u4")
_U1 = np.dtype("u1")
_F4 = np.dtype("<f4")

_SPECS = {
    "normals": {
        "encoding": "oct32P: octahedral, snorm16 per component stored as uint16 (code = s + 32768), "
                    "precise (best of 4 neighbouring codes); Cigolle et al. 2014",
        "dtype": "<u2", "components": 2, "bits": 16, "bytes_per": 4, "per": "vertex",
        "max_error": NORMAL_MAX_ERROR_DEG, "measured_max_error": NORMAL_MEASURED_MAX_ERROR_DEG,
        "unit": "degrees",
    },
    "uvs": {
        "encoding": "unorm16 over the buffer range: u = float32(lo * (1 - q / 65535) + hi * (q / 65535)) "
                    "computed in float64; lo, hi are float32 values kept beside the codes (in a .lop "
                    "file: the manifest's uv_range)",
        "dtype": "<u2", "components": 2, "bits": 16, "bytes_per": 4, "per": "vertex",
        "range_bytes": UV_RANGE_BYTES,
        "max_error": UV_MAX_ERROR_FRACTION,
        "unit": "fraction of the buffer's range (hi - lo) per component, plus float32 rounding",
    },
    "colors": {
        "encoding": "RGBA unorm8, linear, inputs clamped to [0, 1]: c = q / 255",
        "dtype": "u1", "components": 4, "bits": 8, "bytes_per": 4, "per": "vertex",
        "max_error": COLOR_MAX_ERROR,
        "unit": "linear [0, 1] per channel, plus float32 rounding",
    },
    "indices": {
        "encoding": "uint16 when n_vertices <= 65535 (so 65535, the primitive-restart value, never appears), else uint32; i0 i1 i2 per triangle",
        "dtype": "<u2 or <u4", "components": 3, "bits": 16, "bits_large": 32,
        "bytes_per": 6, "bytes_per_large": 12, "per": "triangle",
        "max_error": 0, "unit": "exact",
    },
}


def attribute_specs() -> dict:
    """Encodings and documented worst-case errors as JSON-ready data (a fresh copy).

    ``name -> {"bits", "max_error", "unit", "encoding", "dtype", "components", "bytes_per",
    "per", ...}`` for ``"normals"``, ``"uvs"``, ``"colors"``, ``"indices"``. ``bits`` is per
    component; ``bytes_per`` is per ``per`` ("vertex" or "triangle"); indices also give
    ``bits_large``/``bytes_per_large`` for the uint32 case and uvs ``range_bytes`` per buffer.
    """
    return copy.deepcopy(_SPECS)


def index_width(n_vertices: int) -> int:
    """Bytes per index: 2 when ``n_vertices <= 65535`` (indices <= 65534, never the uint16
    primitive-restart value 65535), else 4."""
    if n_vertices < 0:
        raise LopcookError("emit", None, f"n_vertices must be >= 0, got {n_vertices}")
    return 2 if n_vertices <= 65535 else 4


def encoded_nbytes(n_vertices: int, n_triangles: int, *, normals: bool = True, uvs: bool = True,
                   colors: bool = False) -> dict[str, int]:
    """Encoded payload bytes of each section present: ``{"normals", "uvs", "colors", "indices"}``.

    uvs include the 16-byte range (lo, hi); indices use :func:`index_width`.
    """
    out: dict[str, int] = {}
    if normals:
        out["normals"] = BYTES_PER_VERTEX["normals"] * n_vertices
    if uvs:
        out["uvs"] = BYTES_PER_VERTEX["uvs"] * n_vertices + UV_RANGE_BYTES
    if colors:
        out["colors"] = BYTES_PER_VERTEX["colors"] * n_vertices
    out["indices"] = 3 * n_triangles * index_width(n_vertices)
    return out


# ---------------------------------------------------------------------------------------------
# helpers

def _float_input(a, width: int, name: str) -> np.ndarray:
    arr = np.asarray(a)
    if arr.ndim != 2 or arr.shape[1] != width:
        raise LopcookError("emit", None, f"{name} must be (n, {width}), got shape {arr.shape}")
    if arr.dtype.kind not in "fiu":
        raise LopcookError("emit", None, f"{name} must be numeric, got {arr.dtype}")
    arr = arr.astype(np.float64)
    if arr.size and not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr)).any(axis=1).sum())
        raise LopcookError("emit", None, f"{bad} {name} contain NaN or Inf",
                           hint="fix or drop the attribute before emitting")
    return arr


def _codes_input(codes, dtype: np.dtype, width: int, name: str) -> np.ndarray:
    """(n, width) int64 codes from an integer array ((n, width) or flat (n * width,)) of code
    values, or from bytes-like data (bytes, bytearray, memoryview, flat uint8 array) in ``dtype``."""
    if isinstance(codes, np.ndarray) and not (codes.ndim == 1 and codes.dtype == np.uint8
                                                and dtype.itemsize != 1):
        if codes.dtype.kind not in "iu":
            raise LopcookError("emit", None, f"{name} codes must be integers, got {codes.dtype}")
        if codes.ndim == 2 and codes.shape[1] != width or codes.ndim not in (1, 2) or codes.size % width:
            raise LopcookError("emit", None, f"{name} codes must be (n, {width}), got {codes.shape}")
        if codes.size and (int(codes.min()) < 0 or int(codes.max()) > np.iinfo(dtype).max):
            raise LopcookError("emit", None, f"{name} codes must be {dtype} values")
        return codes.reshape(-1, width).astype(np.int64)
    raw = np.ascontiguousarray(codes).view(np.uint8) if isinstance(codes, np.ndarray) else memoryview(codes).cast("B")
    if raw.nbytes % dtype.itemsize:
        raise LopcookError("emit", None, f"{name} data is {raw.nbytes} bytes, not a multiple of {dtype.itemsize}")
    flat = np.frombuffer(raw, dtype=dtype)
    if flat.size % width:
        raise LopcookError("emit", None, f"{name} data holds {flat.size} values, not a multiple of {width}")
    return flat.reshape(-1, width).astype(np.int64)


def _sgn(x: np.ndarray) -> np.ndarray:
    """+1 for x >= 0 (including -0.0), -1 otherwise."""
    return np.where(x >= 0.0, 1.0, -1.0)


# ---------------------------------------------------------------------------------------------
# normals

def _oct_decode64(sx: np.ndarray, sy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """snorm16 values (int, any range) -> unit vector components, float64."""
    px = np.clip(sx / float(_SNORM16), -1.0, 1.0)
    py = np.clip(sy / float(_SNORM16), -1.0, 1.0)
    ax, ay = np.abs(px), np.abs(py)
    z = 1.0 - ax - ay
    neg = z < 0.0
    x = np.where(neg, (1.0 - ay) * _sgn(px), px)
    y = np.where(neg, (1.0 - ax) * _sgn(py), py)
    inv = 1.0 / np.sqrt(x * x + y * y + z * z)
    return x * inv, y * inv, z * inv


def encode_normals(normals) -> np.ndarray:
    """Octahedral oct32P codes ``(n, 2) "<u2"`` of ``(n, 3)`` normals (direction only).

    Angular error <= :data:`NORMAL_MAX_ERROR_DEG` (0.0038 degrees); axis directions are exact.
    Raises LopcookError for NaN/Inf or zero-length vectors.
    """
    d = _float_input(normals, 3, "normals")
    n = d.shape[0]
    if n == 0:
        return np.zeros((0, 2), dtype=_U2)
    dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
    l1 = np.abs(dx) + np.abs(dy) + np.abs(dz)
    if not (l1 > 0.0).all():
        raise LopcookError("emit", None, f"{int((l1 <= 0.0).sum())} normals have zero length",
                           hint="recompute normals for degenerate vertices before emitting")
    px, py = dx / l1, dy / l1
    neg = dz < 0.0
    px, py = (np.where(neg, (1.0 - np.abs(py)) * _sgn(px), px),
              np.where(neg, (1.0 - np.abs(px)) * _sgn(py), py))
    fx = np.floor(px * _SNORM16)
    fy = np.floor(py * _SNORM16)
    best_x = best_y = best_dot = None
    for ox, oy in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)):
        cx = np.clip(fx + ox, -_SNORM16, _SNORM16)
        cy = np.clip(fy + oy, -_SNORM16, _SNORM16)
        x, y, z = _oct_decode64(cx, cy)
        dot = x * dx + y * dy + z * dz
        if best_dot is None:
            best_x, best_y, best_dot = cx, cy, dot
        else:
            better = dot > best_dot
            best_x = np.where(better, cx, best_x)
            best_y = np.where(better, cy, best_y)
            best_dot = np.where(better, dot, best_dot)
    out = np.empty((n, 2), dtype=_U2)
    out[:, 0] = (best_x + _OFFSET16).astype(np.int64)
    out[:, 1] = (best_y + _OFFSET16).astype(np.int64)
    return out


def decode_normals(codes) -> np.ndarray:
    """Unit normals ``(n, 3) float32`` from oct32P codes (an ``(n, 2)`` array or ``<u2`` bytes)."""
    c = _codes_input(codes, _U2, 2, "normals")
    x, y, z = _oct_decode64(c[:, 0] - _OFFSET16, c[:, 1] - _OFFSET16)
    return np.stack([x, y, z], axis=1).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# uvs

def encode_uvs(uvs, lo=None, hi=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """unorm16 codes over the buffer's range: ``(codes (n, 2) "<u2", lo (2,) "<f4", hi (2,) "<f4")``.

    ``lo``/``hi`` default to the per-component min/max of ``uvs`` (zeros for an empty buffer);
    when given (e.g. to share one range across buffers) they must be finite, ``lo <= hi``, and
    contain every value. Error per component <= (hi - lo) / 131070 + float32 rounding.
    """
    u = _float_input(uvs, 2, "uvs")
    if lo is None:
        lo32 = u.min(axis=0).astype(_F4) if u.shape[0] else np.zeros(2, dtype=_F4)
    else:
        lo32 = np.asarray(lo, dtype=_F4).reshape(2)
    if hi is None:
        hi32 = u.max(axis=0).astype(_F4) if u.shape[0] else np.zeros(2, dtype=_F4)
    else:
        hi32 = np.asarray(hi, dtype=_F4).reshape(2)
    lo32, hi32 = lo32 + _F4.type(0), hi32 + _F4.type(0)  # -0.0 -> +0.0: same bytes for +-0 input
    lo64, hi64 = lo32.astype(np.float64), hi32.astype(np.float64)
    if not (np.isfinite(lo64).all() and np.isfinite(hi64).all() and (lo64 <= hi64).all()):
        raise LopcookError("emit", None, f"uv range must be finite with lo <= hi, got lo={lo64}, hi={hi64}")
    if u.shape[0] and ((u < lo64).any() or (u > hi64).any()):
        raise LopcookError("emit", None, f"uvs fall outside the given range lo={lo64}, hi={hi64}",
                           hint="omit lo/hi to use the buffer's own range")
    span = hi64 - lo64
    safe = np.where(span > 0.0, span, 1.0)
    q = np.rint((u - lo64) / safe * _UNORM16)
    q = np.where(span > 0.0, np.clip(q, 0, _UNORM16), 0.0)
    return q.astype(_U2), lo32, hi32


def decode_uvs(codes, lo, hi) -> np.ndarray:
    """``(n, 2) float32`` uvs: ``lo * (1 - q/65535) + hi * (q/65535)`` in float64, rounded to float32."""
    c = _codes_input(codes, _U2, 2, "uvs")
    lo64 = np.asarray(lo, dtype=_F4).reshape(2).astype(np.float64)
    hi64 = np.asarray(hi, dtype=_F4).reshape(2).astype(np.float64)
    t = c / float(_UNORM16)
    return (lo64 * (1.0 - t) + hi64 * t).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# colors

def encode_colors(colors) -> np.ndarray:
    """RGBA unorm8 codes ``(n, 4) "u1"``; inputs clamped to [0, 1]; error <= 1/510 per channel."""
    c = _float_input(colors, 4, "colors")
    return np.rint(np.clip(c, 0.0, 1.0) * _UNORM8).astype(_U1)


def decode_colors(codes) -> np.ndarray:
    """``(n, 4) float32`` linear RGBA ``q / 255`` from unorm8 codes (an array or bytes)."""
    c = _codes_input(codes, _U1, 4, "colors")
    return (c / float(_UNORM8)).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# indices

def encode_indices(indices, n_vertices: int) -> tuple[np.ndarray, int]:
    """Flat index buffer ``(3m,)`` in ``"<u2"`` or ``"<u4"`` and its width in bytes (2 or 4).

    The width is :func:`index_width` ``(n_vertices)``; every index must be in [0, n_vertices).
    """
    t = np.asarray(indices)
    if t.ndim != 2 or t.shape[1] != 3 or (t.size and t.dtype.kind not in "iu"):
        raise LopcookError("emit", None, f"indices must be (m, 3) integers, got {t.dtype} {t.shape}")
    width = index_width(int(n_vertices))
    if t.size and (int(t.min()) < 0 or int(t.max()) >= n_vertices):
        raise LopcookError("emit", None,
                           f"index range [{int(t.min())}, {int(t.max())}] not within [0, {n_vertices})")
    return t.reshape(-1).astype(_U2 if width == 2 else _U4), width


def decode_indices(data, width: int, m: int) -> np.ndarray:
    """``(m, 3) uint32`` triangles from an encoded index buffer: an integer array of ``width``-byte
    index values, or bytes-like data (bytes, bytearray, memoryview, uint8 array) in ``"<u2"``/``"<u4"``."""
    if width not in (2, 4):
        raise LopcookError("emit", None, f"index width must be 2 or 4 bytes, got {width}")
    dtype = _U2 if width == 2 else _U4
    if isinstance(data, np.ndarray) and data.dtype != np.uint8:
        if data.dtype.kind not in "iu" or data.dtype.itemsize != width:
            raise LopcookError("emit", None, f"index array dtype {data.dtype} does not match width {width}")
        flat = data.reshape(-1)
    else:
        raw = np.ascontiguousarray(data).reshape(-1) if isinstance(data, np.ndarray) else memoryview(data).cast("B")
        if raw.nbytes % width:
            raise LopcookError("emit", None, f"index data is {raw.nbytes} bytes, not a multiple of {width}")
        flat = np.frombuffer(raw, dtype=dtype)
    if flat.size != 3 * m:
        raise LopcookError("emit", None, f"index data holds {flat.size} indices, expected {3 * m}")
    return flat.reshape(m, 3).astype(np.uint32)
