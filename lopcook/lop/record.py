"""The packed attribute record: one per vertex, fields LSB first (docs/format.md section 7.2).

This work is based on: Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex Compression
Using Quantization and Simplification", Graphics Hardware 2005, sections 3-5 (per-attribute bit
widths, one packed record per vertex).

Fields, each present attribute only, in the codecs' record order (``lopcook.lop.codecs.CODECS``):
``normal.u, normal.v`` (b_n bits each), ``uv.u, uv.v`` (b_u each), ``color.r, g, b, a`` (b_c
each), then any later codec's fields. Record bits ``S = AttributeBits.record_bits``. Vertex j's
record starts at bit ``j * S`` of the section, its fields consecutive, least significant bit
first (bit i of the section is bit ``i & 31`` of word ``i >> 5``), so a field may span two 32-bit
words: the decoder reads word ``w = o >> 5`` and word ``min(w + 1, words - 1)``. This lifts
Purnomo's no-crossing rule (section 4) at the cost of a second word read. The section holds
``ceil(n S / 32)`` little-endian uint32 words: at most 31 bits are wasted per buffer
(:func:`record_waste`), against ``32 ceil(S/32) - S`` per vertex for word-aligned records
(:func:`aligned_waste`, first-fit decreasing bins of whole components).

Attribute arrays are passed as ``{codec name: (n, components) array or None}``; codes as
``{codec name: (n, fields) integers}``. Non-finite input raises ``LopcookError("emit", ...)``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import LopcookError
from .codecs import CODECS, AttributeBits
from .memo import memoised

_U4 = np.dtype("<u4")


def record_fields(bits: AttributeBits) -> list[tuple[str, int, int, int]]:
    """``(attribute, field, bit offset in the record, width)`` of every field, in record order."""
    out, off = [], 0
    for codec, b in bits.present():
        for k, w in enumerate(codec.field_widths(b)):
            out.append((codec.name, k, off, int(w)))
            off += int(w)
    return out


def record_words(n: int, bits: AttributeBits) -> int:
    """uint32 words of a buffer's attributes section: ``ceil(n S / 32)``."""
    return (int(n) * bits.record_bits + 31) // 32


def record_waste(n: int, bits: AttributeBits) -> int:
    """Bits of the section not holding a field: ``32 words - n S`` (< 32 per buffer)."""
    return 32 * record_words(n, bits) - int(n) * bits.record_bits


def aligned_waste(bits: AttributeBits) -> int:
    """Wasted bits per vertex when no component may cross a 32-bit word (Purnomo 2005, section 4):
    the components packed first-fit decreasing into 32-bit bins, ``32 * bins - S``."""
    widths = sorted((w for _, _, _, w in record_fields(bits)), reverse=True)
    bins: list[int] = []
    for w in widths:
        for i, used in enumerate(bins):
            if used + w <= 32:
                bins[i] += w
                break
        else:
            bins.append(w)
    return 32 * len(bins) - bits.record_bits


def _vertex_count(attrs: Mapping, bits: AttributeBits) -> int:
    """The common length of the present attributes; errors when presence and bits disagree."""
    n = None
    for codec in CODECS:
        a, b = attrs.get(codec.name), bits.get(codec.name)
        if (a is None) != (b is None):
            raise LopcookError("emit", None, f"{codec.name}: attribute {'absent' if a is None else 'present'} "
                               f"but bits {b!r}")
        if a is not None:
            k = np.asarray(a).shape[0]
            if n is not None and k != n:
                raise LopcookError("emit", None, f"attribute lengths differ ({n} and {k} vertices)")
            n = k
    return n or 0


def record_codes(attrs: Mapping, bits: AttributeBits) -> tuple[dict, dict]:
    """The integer codes of one buffer's attributes and the record's meta: ``({name: (n, fields)
    uint16}`` (present attributes only), ``{"record_bits": S, "wasted_bits", "lod": the codecs'
    LOD-entry fields (uv_range, uv_step)}``). Every code depends on its own vertex alone (and the
    UVs' range on the set of values), so the codes of a permutation of the vertices are the same
    permutation of these: ``pack_record(codes[order])`` is ``encode_record(attrs[order])``'s words.
    Memoised inside a ``lopcook.lop.memo.code_memo``."""
    n = _vertex_count(attrs, bits)
    codes, lod = {}, {}
    for codec, b in bits.present():
        a = attrs[codec.name]
        q, meta = memoised(codec.name, b, a, lambda c=codec, a=a, b=b: c.encode(a, b))
        codes[codec.name] = q
        lod.update(meta)
    return codes, {"record_bits": bits.record_bits, "wasted_bits": record_waste(n, bits), "lod": lod}


def encode_record(attrs: Mapping, bits: AttributeBits) -> tuple[np.ndarray, dict]:
    """Pack one buffer's attributes (binned order) into its record section: ``(words
    (ceil(n S / 32),) "<u4", meta)`` with meta as :func:`record_codes` gives it.
    ``words.tobytes()`` is the section payload. An attribute given with bits None, or bits given
    without the attribute, is an error."""
    codes, meta = record_codes(attrs, bits)
    return pack_record({k: v.astype(np.int64) for k, v in codes.items()}, _vertex_count(attrs, bits), bits), meta


def pack_record(codes: Mapping, n: int, bits: AttributeBits) -> np.ndarray:
    """Pack integer codes (``{name: (n, fields)}``, each field below 2^width) into
    ``ceil(n S / 32)`` uint32 words, LSB first, vertex j at bit j S."""
    s = bits.record_bits
    nwords = record_words(n, bits)
    if nwords == 0:
        return np.zeros(0, dtype=_U4)
    base = np.arange(n, dtype=np.int64) * s
    idx, val = [], []
    for name, c, off, w in record_fields(bits):
        v = np.asarray(codes[name])[:, c].astype(np.int64)
        if v.size and (int(v.min()) < 0 or int(v.max()) >= (1 << w)):
            raise LopcookError("emit", None, f"{name} codes exceed {w} bits")
        pos = base + off
        wi, sh = pos >> 5, pos & 31
        idx.append(wi)
        val.append((v << sh) & 0xFFFFFFFF)
        cross = sh + w > 32
        idx.append(wi[cross] + 1)
        val.append(v[cross] >> (32 - sh[cross]))
    # the fields' bits are disjoint, so the sum per word is their OR (exact in float64: < 2^32)
    total = np.bincount(np.concatenate(idx), weights=np.concatenate(val).astype(np.float64), minlength=nwords)
    return total.astype(np.uint64).astype(_U4)


def unpack_record(words, n: int, bits: AttributeBits) -> dict:
    """Integer codes ``{name: (n, fields)}`` (int64, present attributes only) of a record section:
    the word reads of the shaders' ``lop_attr_read_field`` (second word index clamped to the last)."""
    w = np.asarray(words)
    if w.dtype.kind not in "iu" or w.ndim != 1:
        raise LopcookError("emit", None, f"attribute words must be a 1-D integer array, got {w.dtype} {w.shape}")
    need = record_words(n, bits)
    if w.size < need:
        raise LopcookError("emit", None, f"attribute section holds {w.size} words, {n} vertices need {need}")
    w = w.astype(np.uint64)
    last = max(w.size - 1, 0)
    base = np.arange(n, dtype=np.int64) * bits.record_bits
    out: dict = {}
    for name, c, off, width in record_fields(bits):
        pos = base + off
        wi, sh = pos >> 5, (pos & 31).astype(np.uint64)
        lo = w[wi] >> sh
        hi = ((w[np.minimum(wi + 1, last)] << np.uint64(1)) << (np.uint64(31) - sh)) & np.uint64(0xFFFFFFFF)
        out.setdefault(name, []).append(((lo | hi) & np.uint64((1 << width) - 1)).astype(np.int64))
    return {k: np.stack(v, axis=1) for k, v in out.items()}


def decode_record(words, n: int, bits: AttributeBits, entry: Mapping | None = None) -> dict:
    """``{name: float32 (n, components) decode or None}`` for every codec (normals unnormalised)
    of a record section of ``n`` vertices. ``entry``: the LOD entry (or any mapping) holding the
    codecs' ``lod_keys`` (``uv_range`` and ``uv_step`` when ``bits.uvs`` is set)."""
    codes = unpack_record(words, n, bits)
    out = {c.name: None for c in CODECS}
    for codec, b in bits.present():
        out[codec.name] = codec.decode(codes[codec.name], b, entry or {})
    return out


_LAYOUT = {
    "attributes": {
        "encoding": "one record per vertex (binned order) of the present fields normal.u, normal.v, uv.u, uv.v, "
                    "color.r, g, b, a; S = 2 b_n + 2 b_u + 4 b_c bits; vertex j at bit j S; fields "
                    "consecutive, least significant bit first, a field may span two 32-bit words",
        "dtype": "<u4", "per": "buffer", "words": "ceil(n S / 32)",
    },
    "indices": {
        "encoding": "uint16 when n_vertices <= 65535 (so 65535, the primitive-restart value, never appears), "
                    "else uint32; i0 i1 i2 per triangle",
        "dtype": "<u2 or <u4", "components": 3, "bits": 16, "bits_large": 32,
        "bytes_per": 6, "bytes_per_large": 12, "per": "triangle",
        "max_error": 0, "unit": "exact",
    },
}


def attribute_specs(bits: list[AttributeBits] | None = None) -> dict:
    """The manifest's ``encodings``: each codec's ``spec()`` (``bits`` the allowed [min, max],
    ``max_error`` the bound as a formula of b), ``"attributes"`` (the record layout) and
    ``"indices"``. A codec newer than the first format is listed only when some buffer of
    ``bits`` holds it."""
    used = {c.name for ab in (bits or []) for c, _ in ab.present()}
    out = {c.name: c.spec() for c in CODECS if c.format_major == 2 or c.name in used}
    out.update({k: dict(v) for k, v in _LAYOUT.items()})
    return out
