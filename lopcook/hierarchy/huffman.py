"""Bounded canonical Huffman codes and the bit I/O of the hierarchy coder.

This work is based on the view-dependent connectivity coding paper, section 4.2: the table holds
the ``size - 1`` most frequent values plus one escape code; a value outside the table is written
as the escape code followed by the value in the number of bits its context allows (the decoder
knows that range). Codes are canonical (D. Huffman 1952; canonical ordering as in DEFLATE, RFC
1951 section 3.2.2) and limited to :data:`MAX_LEN` bits so one table lookup decodes a symbol.

Bit order: most significant bit first within the stream, bytes in stream order.
"""

from __future__ import annotations

import heapq

import numpy as np

from ..errors import LopcookError

MAX_LEN = 15
ESCAPE = None  # the symbol a decoding table returns for the escape code


def bitlen(x) -> np.ndarray:
    """Number of bits needed to write any integer in [0, x] (0 for x <= 0), vectorised."""
    x = np.asarray(x, dtype=np.int64)
    out = np.zeros(x.shape, np.int64)
    pos = x > 0
    out[pos] = np.floor(np.log2(x[pos])).astype(np.int64) + 1
    # guard float rounding at powers of two
    fix = pos & ((np.int64(1) << np.minimum(out, 62)) <= x)
    out[fix] += 1
    fix = pos & (out > 0) & ((np.int64(1) << np.maximum(out - 1, 0)) > x)
    out[fix] -= 1
    return out


def _huffman_lengths(counts: np.ndarray) -> np.ndarray:
    n = counts.shape[0]
    if n == 1:
        return np.ones(1, np.int64)
    heap = [(int(c), i, (i,)) for i, c in enumerate(counts)]
    heapq.heapify(heap)
    lengths = np.zeros(n, np.int64)
    tag = n
    while len(heap) > 1:
        c1, _, s1 = heapq.heappop(heap)
        c2, _, s2 = heapq.heappop(heap)
        for s in s1:
            lengths[s] += 1
        for s in s2:
            lengths[s] += 1
        heapq.heappush(heap, (c1 + c2, tag, s1 + s2))
        tag += 1
    return lengths


def limited_lengths(counts: np.ndarray, max_len: int = MAX_LEN) -> np.ndarray:
    """Huffman code lengths, flattened (counts halved, kept >= 1) until none exceeds ``max_len``."""
    c = np.maximum(np.asarray(counts, np.int64), 1)
    while True:
        lengths = _huffman_lengths(c)
        if lengths.max() <= max_len:
            return lengths
        c = (c >> 1) + 1


class Table:
    """One bounded canonical Huffman table.

    Attributes
    ----------
    values : (k,) int64, sorted ascending: the integer symbols in the table.
    lengths : (k,) int64 code length of each value.
    esc_len : int, length of the escape code (``0`` when the table has no escape).
    """

    def __init__(self, values: np.ndarray, lengths: np.ndarray, esc_len: int):
        self.values = np.asarray(values, np.int64)
        self.lengths = np.asarray(lengths, np.int64)
        self.esc_len = int(esc_len)
        # canonical codes: sort by (length, value); escape sorts after all values of its length
        keys_len = np.concatenate([self.lengths, [self.esc_len]]) if self.esc_len else self.lengths
        keys_val = np.arange(keys_len.shape[0])
        order = np.lexsort((keys_val, keys_len))
        codes = np.zeros(keys_len.shape[0], np.int64)
        code = 0
        prev = 0
        for i in order.tolist():
            ln = int(keys_len[i])
            code <<= ln - prev
            codes[i] = code
            code += 1
            prev = ln
        if keys_len.shape[0] and code > (1 << prev):
            raise LopcookError("decode", None, "Huffman table code lengths are over-subscribed",
                               hint="the data is corrupt; re-encode it")
        self.codes = codes[: self.values.shape[0]]
        self.esc_code = int(codes[-1]) if self.esc_len else 0
        self.maxlen = int(keys_len.max()) if keys_len.shape[0] else 0
        self._lut = None

    @classmethod
    def build(cls, values: np.ndarray, size: int, force=()) -> "Table":
        """Table of the ``size - 1`` most frequent of ``values`` (plus ``force``d ones) and an escape."""
        v = np.asarray(values, np.int64)
        u, c = np.unique(v, return_counts=True)
        forced = np.asarray(sorted(set(force)), np.int64)
        keep = size - 1
        order = np.lexsort((u, -c))
        top = order[:keep]
        rest = order[keep:]
        tv, tc = u[top], c[top]
        for f in forced.tolist():
            if f not in set(tv.tolist()):
                tv = np.concatenate([tv, [f]])
                tc = np.concatenate([tc, [1]])
        esc_count = int(c[rest].sum())
        allc = np.concatenate([tc, [max(esc_count, 1)]])
        lengths = limited_lengths(allc)
        s = np.argsort(tv, kind="stable")
        return cls(tv[s], lengths[:-1][s], int(lengths[-1]))

    # ---- encoding -------------------------------------------------------------------------
    def encode(self, values: np.ndarray, esc_bits: np.ndarray):
        """Codes for ``values``: (bits (t,) uint64, nbits (t,) int64); escapes append raw bits."""
        v = np.asarray(values, np.int64)
        eb = np.broadcast_to(np.asarray(esc_bits, np.int64), v.shape)
        i = np.searchsorted(self.values, v)
        i = np.minimum(i, max(self.values.shape[0] - 1, 0))
        hit = (self.values.shape[0] > 0) & (self.values[i] == v) if self.values.shape[0] else \
            np.zeros(v.shape, bool)
        code = np.where(hit, self.codes[i] if self.values.shape[0] else 0, self.esc_code)
        ln = np.where(hit, self.lengths[i] if self.values.shape[0] else 0, self.esc_len)
        miss = ~hit
        if miss.any():
            if not self.esc_len:
                raise LopcookError("encode", None, "value outside a table without escape")
            bad = miss & ((v < 0) | ((eb < 63) & (v >= (np.int64(1) << np.minimum(eb, 62)))))
            if bad.any():
                raise LopcookError("encode", None,
                                   f"escaped value {int(v[bad][0])} does not fit {int(eb[bad][0])} bits")
            code = np.where(miss, (code << eb) | v, code)
            ln = np.where(miss, ln + eb, ln)
        return code.astype(np.uint64), ln.astype(np.int64)

    def cost(self, values: np.ndarray, esc_bits: np.ndarray) -> int:
        return int(self.encode(values, esc_bits)[1].sum())

    # ---- decoding -------------------------------------------------------------------------
    def lut(self):
        """(symbol list, length list) indexed by the next ``maxlen`` bits; escape is ``None``."""
        if self._lut is None:
            L = self.maxlen
            sym = [0] * (1 << L)
            ln = [0] * (1 << L)  # 0 marks an invalid prefix
            for v, c, l in zip(self.values.tolist(), self.codes.tolist(), self.lengths.tolist()):
                lo = c << (L - l)
                for j in range(lo, lo + (1 << (L - l))):
                    sym[j] = v
                    ln[j] = l
            if self.esc_len:
                lo = self.esc_code << (L - self.esc_len)
                for j in range(lo, lo + (1 << (L - self.esc_len))):
                    sym[j] = ESCAPE
                    ln[j] = self.esc_len
            self._lut = (sym, ln, L)
        return self._lut

    # ---- serialisation --------------------------------------------------------------------
    def to_bytes(self) -> bytes:
        """varint count, varint escape length, then per value (ascending): varint delta, u4 length."""
        out = bytearray()
        put_varint(out, self.values.shape[0])
        put_varint(out, self.esc_len)
        prev = None
        for v in self.values.tolist():
            put_varint(out, zigzag(v) if prev is None else v - prev)
            prev = v
        nib = self.lengths.astype(np.uint8)
        if nib.shape[0] % 2:
            nib = np.concatenate([nib, [0]]).astype(np.uint8)
        packed = (nib[0::2] << 4) | nib[1::2]
        out += packed.astype(np.uint8).tobytes()
        return bytes(out)

    @classmethod
    def from_bytes(cls, buf: bytes, pos: int, what: str = "table"):
        k, pos = get_varint(buf, pos, what)
        esc, pos = get_varint(buf, pos, what)
        if k > 1 << 16 or esc > MAX_LEN + 1:
            raise LopcookError("decode", None, f"{what}: implausible Huffman table ({k} entries)",
                               hint="the data is corrupt; re-encode it")
        vals = []
        prev = None
        for _ in range(k):
            d, pos = get_varint(buf, pos, what)
            prev = unzigzag(d) if prev is None else prev + d
            vals.append(prev)
        nb = (k + 1) // 2
        if pos + nb > len(buf):
            raise LopcookError("decode", None, f"{what}: truncated Huffman table",
                               hint="the data is truncated; re-encode it")
        packed = np.frombuffer(buf[pos:pos + nb], np.uint8)
        lengths = np.empty(nb * 2, np.int64)
        lengths[0::2] = packed >> 4
        lengths[1::2] = packed & 15
        lengths = lengths[:k]
        if k and (lengths.min() < 1 or lengths.max() > MAX_LEN):
            raise LopcookError("decode", None, f"{what}: invalid Huffman code length",
                               hint="the data is corrupt; re-encode it")
        return cls(np.asarray(vals, np.int64), lengths, esc), pos + nb


def zigzag(v: int) -> int:
    return (v << 1) if v >= 0 else ((-v << 1) - 1)


def unzigzag(z: int) -> int:
    return (z >> 1) if not (z & 1) else -((z + 1) >> 1)


def put_varint(out: bytearray, v: int) -> None:
    if v < 0:
        raise LopcookError("encode", None, f"negative varint {v}")
    while True:
        b = v & 0x7F
        v >>= 7
        if v:
            out.append(b | 0x80)
        else:
            out.append(b)
            return


def get_varint(buf, pos: int, what: str = "data"):
    v = 0
    shift = 0
    while True:
        if pos >= len(buf):
            raise LopcookError("decode", None, f"{what}: truncated (varint runs past the end)",
                               hint="the data is truncated; re-encode it")
        b = buf[pos]
        pos += 1
        v |= (b & 0x7F) << shift
        if not b & 0x80:
            return v, pos
        shift += 7
        if shift > 63:
            raise LopcookError("decode", None, f"{what}: varint longer than 64 bits",
                               hint="the data is corrupt; re-encode it")


def pack_bits(codes: np.ndarray, nbits: np.ndarray) -> tuple[bytes, int]:
    """Concatenate tokens (code, nbits), MSB first, into bytes; returns (bytes, total bits)."""
    nbits = np.asarray(nbits, np.int64)
    codes = np.asarray(codes, np.uint64)
    total = int(nbits.sum())
    if total == 0:
        return b"", 0
    keep = nbits > 0
    codes, nbits = codes[keep], nbits[keep]
    starts = np.cumsum(nbits) - nbits
    idx = np.repeat(np.arange(nbits.shape[0]), nbits)
    j = np.arange(total) - starts[idx]
    shift = (nbits[idx] - 1 - j).astype(np.uint64)
    bits = ((codes[idx] >> shift) & np.uint64(1)).astype(np.uint8)
    return np.packbits(bits).tobytes(), total


def get_varints(buf, pos: int, count: int, what: str = "data"):
    """``count`` consecutive varints from ``pos`` (as :func:`get_varint`, vectorised):
    ((count,) int64 values, position after the last). A varint of more than 9 bytes (a value
    of 2**63 or more) or one that runs past the end raises ``LopcookError``."""
    if count <= 0:
        return np.zeros(0, np.int64), pos
    a = np.frombuffer(buf, np.uint8, min(len(buf) - pos, 10 * count), pos) if pos < len(buf) \
        else np.zeros(0, np.uint8)
    term = np.flatnonzero(a < 0x80)
    if term.shape[0] < count:
        raise LopcookError("decode", None, f"{what}: truncated (varint runs past the end)",
                           hint="the data is truncated; re-encode it")
    term = term[:count]
    first = np.r_[0, term[:-1] + 1]
    nbytes = term - first + 1
    if nbytes.max() > 9:
        raise LopcookError("decode", None, f"{what}: varint longer than 63 bits",
                           hint="the data is corrupt; re-encode it")
    seg = a[:term[-1] + 1].astype(np.int64)
    k = np.arange(seg.shape[0]) - np.repeat(first, nbytes)
    vals = np.add.reduceat((seg & 0x7F) << (7 * k), first)
    return vals.astype(np.int64), pos + int(term[-1]) + 1
