"""Indices: uint16 or uint32 (``"<u2"`` / ``"<u4"``), 6 or 12 bytes per triangle (docs/format.md 7.1).

Layout: the triangles' corners in order, ``i0 i1 i2 i0 i1 i2 ...``, counter-clockwise front
faces. The width is 2 bytes when ``n_vertices <= 65535`` (every index <= 65534: the uint16
primitive-restart value 65535, always on in WebGL 2 and Metal, never appears) and 4 bytes
otherwise. Exact.
"""

from __future__ import annotations

import numpy as np

from ..errors import LopcookError

_U2 = np.dtype("<u2")
_U4 = np.dtype("<u4")


def index_width(n_vertices: int) -> int:
    """Bytes per index: 2 when ``n_vertices <= 65535`` (indices <= 65534, never the uint16
    primitive-restart value 65535), else 4."""
    if n_vertices < 0:
        raise LopcookError("emit", None, f"n_vertices must be >= 0, got {n_vertices}")
    return 2 if n_vertices <= 65535 else 4


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
