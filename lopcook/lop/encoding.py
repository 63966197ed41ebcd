"""Encoded sections: compressed on the wire, decoded once on arrival (docs/format.md section 15).

A section-table entry with ``encoding`` and ``size`` stores an encoded stream plus 0-3 zero bytes;
``length`` and ``crc32`` cover those stored bytes, and the section's decoded bytes (``size`` of
them) are what every other rule of the format reads.

* ``deflate``: raw DEFLATE (RFC 1951), zlib at level 9, window 2^15, memory level 9.
* ``meshopt-deflate`` (index sections only): raw DEFLATE of an EXT_meshopt_compression triangle
  stream (mode 1, "TRIANGLES", bitstream version 1: header byte 0xE1; meshoptimizer's
  ``meshopt_encodeIndexBuffer``). The codec may rotate a triangle's indices (same winding).

Readers decode with bounded memory: DEFLATE never produces more than ``size`` bytes (and
``size <= DEFLATE_MAX_RATIO * length`` is checked before anything is allocated), a triangle stream
is at most ``DEFLATE_MAX_RATIO * length`` bytes and at least ``1 + m + 16``. ``decode_section``
raises one ``LopcookError("container", ...)`` naming the section for anything else.
The writer (``encode_section``) keeps an encoding only when it saves ``MIN_SAVING`` of the bytes.
A 4.x manifest may be stored encoded too (``encode_manifest``: a 0x00 byte, its size, DEFLATE).
"""

from __future__ import annotations

import struct
import zlib

import meshoptimizer
import numpy as np

#: the encodings a section-table entry may name
DEFLATE, MESHOPT = "deflate", "meshopt-deflate"
ENCODINGS = (DEFLATE, MESHOPT)
#: DEFLATE expands at most this many times (two 1-bit codes per 258-byte match), so a stored
#: stream of L bytes never decodes to more than 1032 L: a larger ``size`` is refused unread
DEFLATE_MAX_RATIO = 1032
#: an encoding is written only when it saves at least this fraction of the section's bytes
MIN_SAVING = 0.05
#: zlib parameters of every stream lopcook writes (determinism: docs/format.md section 10)
LEVEL, WBITS, MEM_LEVEL = 9, -15, 9
#: EXT_meshopt_compression triangle stream: header byte of bitstream version 1, table bytes
TRIANGLES_HEADER, TABLE_BYTES = 0xE1, 16
#: the first byte of an encoded manifest: no JSON text starts with it
MANIFEST_MARK = 0x00


class EncodingError(ValueError):
    """A stored stream that does not decode as docs/format.md section 15 says (the message says why)."""


def deflate(data: bytes) -> bytes:
    """Raw DEFLATE of ``data`` with lopcook's fixed zlib parameters."""
    z = zlib.compressobj(LEVEL, zlib.DEFLATED, WBITS, MEM_LEVEL)
    return z.compress(bytes(data)) + z.flush()


def inflate(stored: bytes, limit: int, *, exact: bool, padded: bool = True) -> bytes:
    """Inflate the raw DEFLATE stream at the start of ``stored`` (a section's stored bytes, padding
    included). ``limit``: the most bytes it may give (``size``); ``exact``: it must give exactly
    ``limit``. The stream must end inside ``stored``, whose remaining bytes must be the section's
    zero padding (fewer than 4, all zero; none without ``padded``). EncodingError otherwise."""
    z = zlib.decompressobj(WBITS)
    try:
        out = z.decompress(stored, limit + 1)
    except zlib.error as exc:
        raise EncodingError(f"the deflate stream is corrupt ({exc})") from None
    if len(out) > limit:
        raise EncodingError(f"the deflate stream expands beyond its {limit} bytes")
    if not z.eof:
        raise EncodingError("the deflate stream ends before its final block")
    if exact and len(out) != limit:
        raise EncodingError(f"the deflate stream gives {len(out)} bytes, not the {limit} its size says")
    tail = z.unused_data
    end = len(stored) - len(tail)
    if not padded and tail:
        raise EncodingError(f"the deflate stream ends at byte {end} of its {len(stored)} bytes")
    if padded and (len(stored) != 4 * -(-end // 4) or tail.count(0) != len(tail)):
        raise EncodingError(f"the deflate stream ends at byte {end}, not in the last word of its "
                            f"{len(stored)} stored bytes with zero padding after it")
    return out


def encode_manifest(text: bytes) -> bytes:
    """The stored bytes of an encoded manifest (docs/format.md 4): ``MANIFEST_MARK``, the JSON
    text's size (uint32 little-endian), the raw DEFLATE stream of the text."""
    return bytes([MANIFEST_MARK]) + struct.pack("<I", len(text)) + deflate(text)


def decode_manifest(stored: bytes) -> bytes:
    """The JSON text of an encoded manifest (``encode_manifest``): the stream must give exactly
    its size (at most ``DEFLATE_MAX_RATIO`` times its bytes) and end at the manifest's last byte.
    EncodingError otherwise."""
    if len(stored) < 5 or stored[0] != MANIFEST_MARK:
        raise EncodingError("an encoded manifest starts with 0x00 and its 4-byte size")
    (size,) = struct.unpack_from("<I", stored, 1)
    if size > DEFLATE_MAX_RATIO * (len(stored) - 5):
        raise EncodingError(f"the encoded manifest claims {size} bytes, more than {DEFLATE_MAX_RATIO} times its "
                            f"{len(stored) - 5} stored bytes")
    return inflate(stored[5:], size, exact=True, padded=False)


def _table_ok(table: bytes) -> bool:
    """The 16-byte table ending a triangle stream: bytes 14 and 15 zero, no nibble 0xF before."""
    return table[14] == 0 and table[15] == 0 and all((b >> 4) != 15 and (b & 15) != 15 for b in table[:14])


def decode_triangles(stream: bytes, triangles: int) -> np.ndarray:
    """The 3 m indices (uint32, before any range check) of an EXT_meshopt_compression triangle
    stream of version 1 (docs/format.md 15.2), through meshoptimizer's decoder after the header,
    size and table checks it does not make. EncodingError when the stream is not one."""
    m = int(triangles)
    if len(stream) < 1 + m + TABLE_BYTES:
        raise EncodingError(f"the triangle stream is {len(stream)} bytes, too short for {m} triangles")
    if stream[0] != TRIANGLES_HEADER:
        raise EncodingError(f"the triangle stream starts with 0x{stream[0]:02x}, not 0x{TRIANGLES_HEADER:02x}")
    if not _table_ok(stream[-TABLE_BYTES:]):
        raise EncodingError("the triangle stream's table has a nibble 0xF or its last two bytes are not 0")
    try:
        return meshoptimizer.decode_index_buffer(3 * m, 4, stream).astype(np.uint32)
    except (RuntimeError, ValueError) as exc:
        raise EncodingError(f"the triangle stream does not decode ({exc})") from None


def encode_triangles(indices) -> tuple[bytes, np.ndarray]:
    """An EXT_meshopt_compression triangle stream (version 1) of ``indices`` ((m, 3) or (3m,)
    ints) and the (m, 3) uint32 triangles it decodes to (the codec may rotate a triangle)."""
    flat = np.ascontiguousarray(np.asarray(indices, dtype=np.uint32).ravel())
    meshoptimizer.encode_index_version(1)  # process-wide: set on every call, the format reads version 1 only
    n = int(flat.max()) + 1 if flat.size else 0
    stream = meshoptimizer.encode_index_buffer(flat, flat.size, n)
    return stream, decode_triangles(stream, flat.size // 3).reshape(-1, 3)


def decoded_index_bytes(indices, width: int) -> bytes:
    """The decoded bytes of an index section: ``indices`` as ``width``-byte little-endian integers,
    zero bytes to a multiple of 4 (docs/format.md 7.1)."""
    data = np.asarray(indices).ravel().astype("<u2" if width == 2 else "<u4").tobytes()
    return data + b"\0" * (-len(data) % 4)


def decode_section(entry: dict, stored: bytes, lod: tuple[int, int, int] | None = None) -> bytes:
    """The decoded bytes of an encoded section (``entry``: its table entry with ``encoding`` and
    ``size``; ``stored``: its stored bytes). ``lod``: ``(m, index_width, n)`` of the LOD whose
    ``indices`` it is (required for ``meshopt-deflate``: every index must be below n before it is
    narrowed to the index width). EncodingError when it does not decode."""
    size, length = int(entry["size"]), len(stored)
    if entry["encoding"] == DEFLATE:
        return inflate(stored, size, exact=True)
    m, width, n = lod
    stream = inflate(stored, DEFLATE_MAX_RATIO * length, exact=False)
    idx = decode_triangles(stream, m)
    if idx.size and int(idx.max()) >= n:
        raise EncodingError(f"index {int(idx.max())} is out of range for {n} vertices")
    return decoded_index_bytes(idx, width)


def _pad4(data: bytes) -> bytes:
    return data + b"\0" * (-len(data) % 4)


def _choose(payload: bytes, candidates) -> tuple[dict, bytes]:
    """The smallest of ``payload`` as it is and each ``(encoding, stored stream)`` that saves at
    least ``MIN_SAVING``: ``(table fields, stored bytes padded to 4)``."""
    best: tuple[dict, bytes] = ({}, payload)
    budget = (1.0 - MIN_SAVING) * len(payload)
    for name, stored in candidates:
        if len(stored) <= budget and len(_pad4(stored)) < len(best[1]):
            best = ({"encoding": name, "size": len(payload)}, stored)
    return best[0], _pad4(best[1])


def encode_section(payload: bytes) -> tuple[dict, bytes]:
    """What the writer stores for a section of decoded bytes ``payload`` (a multiple of 4 bytes):
    ``({}, payload)`` when ``deflate`` does not save ``MIN_SAVING``, else ``({"encoding",
    "size"}, stored stream padded to 4)``."""
    payload = bytes(payload)
    return _choose(payload, [(DEFLATE, deflate(payload))])


def encode_index_section(triangles, width: int) -> tuple[dict, bytes, bytes]:
    """An index section of ``triangles`` ((m, 3) ints below n) and index width 2 or 4:
    ``(table fields, stored bytes, decoded bytes)``. The decoded bytes are the triangles as the
    triangle codec returns them (each perhaps rotated), whichever encoding is kept:
    ``meshopt-deflate``, ``deflate`` or none (``encode_section``'s rule)."""
    stream, decoded = encode_triangles(triangles)
    payload = decoded_index_bytes(decoded, width)
    fields, stored = _choose(payload, [(DEFLATE, deflate(payload)), (MESHOPT, deflate(stream))])
    return fields, stored, payload
