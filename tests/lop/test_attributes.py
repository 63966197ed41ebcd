"""Attribute encodings (lopcook.lop.codecs, lopcook.lop.record): variable-bit normals, UVs and colours with
float32 decodes, their error bounds per bit count, the packed per-vertex record (fields crossing
32-bit words), indices; exact round trips, determinism, bad input."""

import json

import numpy as np
import pytest

from lopcook.lop.codecs import AttributeBits
from lopcook.lop.codecs.colors_unorm import color_error_bound, decode_colors, encode_colors
from lopcook.lop.codecs.normals_oct import CIGOLLE_MAX_ERROR_DEG, decode_normals, encode_normals, normal_error_deg
from lopcook.lop.codecs.uvs_range import decode_uvs, encode_uvs, uv_error_bound, uv_step
from lopcook.lop.indices import decode_indices, encode_indices, index_width
from lopcook.lop.record import aligned_waste, attribute_specs, decode_record, encode_record, pack_record, record_fields, record_waste, record_words, unpack_record
from lopcook.errors import LopcookError

F32 = np.float32


def angle_deg(a, b):
    """Angle between rows of a and b in degrees (atan2 form: accurate for tiny angles)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), (a * b).sum(axis=1)))


def random_units(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def oct_to_dir(p):
    """float64 octahedral map of points p (n, 2) in [-1, 1]^2 to unit directions."""
    x, y = p[:, 0], p[:, 1]
    z = 1 - np.abs(x) - np.abs(y)
    neg = z < 0
    sx, sy = np.where(x >= 0, 1.0, -1.0), np.where(y >= 0, 1.0, -1.0)
    x, y = np.where(neg, (1 - np.abs(p[:, 1])) * sx, x), np.where(neg, (1 - np.abs(p[:, 0])) * sy, y)
    v = np.stack([x, y, z], axis=1)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def hard_directions(rng, bits):
    """Random directions, the centres of the code cells (the worst case of rounding), the fold
    z = 0, face centres, diagonals and axes."""
    m = (1 << (bits - 1)) - 1
    cells = (rng.integers(-m, m, size=(60000, 2)) + 0.5) / m
    fold = rng.uniform(-1, 1, 5000)
    fold = np.stack([fold, (1 - np.abs(fold)) * np.where(rng.random(5000) < 0.5, 1, -1), np.zeros(5000)], axis=1)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float64)
    fixed = np.concatenate([signs, signs * [1, 1, 0], signs * [1, 0, 1], signs * [0, 1, 1], np.eye(3), -np.eye(3)])
    fixed = fixed[np.abs(fixed).sum(1) > 0]
    return np.concatenate([random_units(rng, 100000), oct_to_dir(cells), fold / np.linalg.norm(fold, axis=1,
                           keepdims=True), fixed / np.linalg.norm(fixed, axis=1, keepdims=True)])


def ref_normal_decode(cx, cy, bits):
    """The spec's float32 decode, one numpy float32 scalar operation at a time."""
    h = 1 << (bits - 1)
    r = F32(1.0 / (h - 1))
    px = max(F32(cx - h) * r, F32(-1.0))
    py = max(F32(cy - h) * r, F32(-1.0))
    z = (F32(1) - abs(px)) - abs(py)
    if z < 0:
        sx = F32(1) if px >= 0 else F32(-1)
        sy = F32(1) if py >= 0 else F32(-1)
        px, py = (F32(1) - abs(py)) * sx, (F32(1) - abs(px)) * sy
    return [px, py, z]


# --------------------------------------------------------------------------------- normals

@pytest.mark.parametrize("bits", sorted(CIGOLLE_MAX_ERROR_DEG))
def test_normal_error_within_cigolle_table(bits):
    rng = np.random.default_rng(bits)
    d = hard_directions(rng, bits)
    err = angle_deg(d, decode_normals(encode_normals(d, bits), bits)).max()
    # the table gives two significant digits: within it to that precision (2 %)
    assert err <= CIGOLLE_MAX_ERROR_DEG[bits] * 1.02
    assert err <= normal_error_deg(bits)
    # and not far below it: the bound describes the codec, the error halves per bit
    assert err >= 0.9 * CIGOLLE_MAX_ERROR_DEG[bits]


@pytest.mark.parametrize("bits", range(4, 17))
def test_normal_error_bound_every_bit_count(bits):
    rng = np.random.default_rng(100 + bits)
    d = hard_directions(rng, bits)
    err = angle_deg(d, decode_normals(encode_normals(d, bits), bits))
    assert err.max() <= normal_error_deg(bits)
    if bits < 16:
        assert normal_error_deg(bits + 1) < normal_error_deg(bits)


@pytest.mark.parametrize("bits", [4, 7, 8, 11, 16])
def test_normal_codes_round_trip_exactly(bits):
    h = 1 << (bits - 1)
    m = h - 1
    rng = np.random.default_rng(bits)
    c = rng.integers(1, 2 * h, size=(40000, 2))
    d = decode_normals(c, bits)
    back = encode_normals(d, bits)
    assert back.dtype == np.uint16 and back.min() >= 1 and back.max() <= 2 * h - 1
    # codes off the square's border (|s| < m) are unique directions: the exact code comes back
    inner = (np.abs(c.astype(np.int64) - h) < m).all(axis=1)
    assert inner.sum() > 1000 and np.array_equal(back[inner], c[inner])
    # on the border a code and its mirror are the same direction: the decode comes back (+-0 aside)
    assert np.array_equal(decode_normals(back, bits) + F32(0), d + F32(0))


def test_normal_decode_is_the_float32_formula_and_unnormalised():
    rng = np.random.default_rng(3)
    for bits in (4, 6, 9, 12, 16):
        c = rng.integers(0, 1 << bits, size=(300, 2))
        c[0] = [0, 0]
        d = decode_normals(c, bits)
        assert d.dtype == np.float32 and d.shape == (300, 3)
        ref = np.array([ref_normal_decode(int(a), int(b), bits) for a, b in c], np.float32)
        assert np.array_equal(d.view(np.uint32), ref.view(np.uint32))
        assert np.abs(np.abs(d).sum(axis=1) - 1).max() < 1e-6  # on the octahedron, not the sphere
    assert np.array_equal(decode_normals(np.array([[0, 8]]), 4), decode_normals(np.array([[1, 8]]), 4))


def test_normals_axes_exact_and_direction_only():
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    for bits in (4, 8, 16):
        d = decode_normals(encode_normals(axes, bits), bits)
        assert np.array_equal(d, axes.astype(np.float32))
        v = random_units(np.random.default_rng(bits), 1000)
        assert np.array_equal(encode_normals(v, bits), encode_normals(v * 3.5, bits))
        assert encode_normals(v, bits).tobytes() == encode_normals(np.asfortranarray(v), bits).tobytes()


@pytest.mark.parametrize("bad", [[[0, 0, 0]], [[np.nan, 0, 1]], [[np.inf, 0, 0]]])
def test_normals_reject_zero_and_non_finite(bad):
    with pytest.raises(LopcookError):
        encode_normals(np.array(bad, np.float32), 8)


@pytest.mark.parametrize("bits", [3, 17, 0, 8.0, True, None])
def test_bits_out_of_range_are_usage_errors(bits):
    v = np.array([[0, 0, 1]], np.float32)
    with pytest.raises(LopcookError) as e:
        encode_normals(v, bits)
    assert e.value.stage == "usage"
    with pytest.raises(LopcookError):
        decode_colors(np.zeros((1, 4), int), 9 if bits != 8.0 else 3)
    with pytest.raises(LopcookError):
        encode_uvs(np.zeros((1, 2)), 5)
    if bits is not None:  # None: the attribute is absent
        with pytest.raises(LopcookError):
            AttributeBits(normals=bits)


def test_normal_codes_must_fit_their_bits():
    with pytest.raises(LopcookError):
        decode_normals(np.array([[256, 1]]), 8)
    with pytest.raises(LopcookError):
        decode_normals(np.array([[1.0, 1.0]]), 8)


# --------------------------------------------------------------------------------- uvs

RANGES = [((0.0, 0.0), (1.0, 1.0)), ((-3.7, 0.25), (12.1, 0.26)), ((1000.0, -2.0), (1003.5, 5.0))]


@pytest.mark.parametrize("bits", range(6, 17))
def test_uv_error_bound_per_bit_count(bits):
    rng = np.random.default_rng(bits)
    for lo, hi in RANGES:
        uv = rng.uniform(lo, hi, size=(20000, 2)).astype(np.float32).astype(np.float64)
        uv[0], uv[1] = lo, hi
        codes, lo32, hi32, step = encode_uvs(uv, bits)
        assert codes.max() <= (1 << bits) - 1
        assert np.array_equal(step, uv_step(lo32, hi32, bits))
        d = decode_uvs(codes, lo32, step, bits)
        assert d.dtype == np.float32
        err = np.abs(d.astype(np.float64) - uv)
        bound = uv_error_bound(lo32, hi32, bits)
        assert (err <= bound).all()
        # half a step is the dominant term and is nearly reached (where float32 can hold it)
        coarse = step.astype(np.float64) > 16 * np.spacing(np.maximum(np.abs(lo32), np.abs(hi32)))
        assert (err.max(axis=0)[coarse] >= 0.4 * step.astype(np.float64)[coarse]).all()
        assert (bound <= step.astype(np.float64) / 2 * 1.01 + np.spacing(np.float32(1e4))).all()


def test_uv_decode_is_the_float32_formula_and_codes_round_trip():
    rng = np.random.default_rng(5)
    for bits in (6, 10, 16):
        lo, hi = np.array([-3.7, 0.25], np.float32), np.array([12.1, 0.26], np.float32)
        step = uv_step(lo, hi, bits)
        assert step.dtype == np.float32
        assert np.array_equal(step, ((hi.astype(np.float64) - lo) / ((1 << bits) - 1)).astype(np.float32))
        q = rng.integers(0, 1 << bits, size=(500, 2))
        q[0] = 0
        d = decode_uvs(q, lo, step, bits)
        ref = np.array([[lo[c] + F32(int(q[i, c])) * step[c] for c in range(2)] for i in range(500)], np.float32)
        assert np.array_equal(d, ref)
        # decoded values encode back to their codes (the range held fixed; the top code may
        # decode a rounding above hi, so it is left out here)
        inner = (q < (1 << bits) - 1).all(axis=1)
        back, _, _, _ = encode_uvs(d[inner], bits, lo=lo, hi=hi)
        assert np.array_equal(back, q[inner])


def test_uv_degenerate_range_and_empty():
    line = np.array([[0.5, 0.1], [0.5, 0.7]], np.float32)
    codes, lo, hi, step = encode_uvs(line, 8)
    assert step[0] == 0 and (codes[:, 0] == 0).all()
    assert np.array_equal(decode_uvs(codes, lo, step, 8)[:, 0], line[:, 0])
    codes, lo, hi, step = encode_uvs(np.zeros((0, 2)), 12)
    assert codes.shape == (0, 2) and decode_uvs(codes, lo, step, 12).shape == (0, 2)
    with pytest.raises(LopcookError):
        encode_uvs(np.array([[2.0, 0.0]]), 8, lo=[0, 0], hi=[1, 1])
    with pytest.raises(LopcookError):
        encode_uvs(np.array([[np.nan, 0.0]]), 8)


# --------------------------------------------------------------------------------- colors

@pytest.mark.parametrize("bits", range(4, 9))
def test_color_bound_and_exact_codes(bits):
    n = (1 << bits) - 1
    rng = np.random.default_rng(bits)
    c = rng.random((20000, 4))
    q = encode_colors(c, bits)
    d = decode_colors(q, bits)
    assert d.dtype == np.float32
    err = np.abs(d.astype(np.float64) - c)
    assert err.max() <= color_error_bound(bits) and color_error_bound(bits) == 1 / (2 * n) + 2 ** -24
    assert err.max() >= 0.95 / (2 * n)
    allq = np.arange(n + 1)[:, None].repeat(4, axis=1)
    dq = decode_colors(allq, bits)
    assert np.array_equal(dq, (allq.astype(np.float32) * F32(1.0 / n)))
    assert np.array_equal(encode_colors(dq, bits), allq)
    assert dq[0, 0] == 0 and dq[-1, 0] == pytest.approx(1.0, abs=2 ** -23)
    assert np.array_equal(encode_colors([[-1, 2, 0.5, 1]], bits)[0, :2], [0, n])  # clamped


# --------------------------------------------------------------------------------- the record

def ref_pack(codes, n, bits):
    """Independent reference: the record as a string of bits, LSB first, cut into words."""
    stream = []
    for j in range(n):
        for name, c, _, w in record_fields(bits):
            v = int(codes[name][j, c])
            stream.extend((v >> i) & 1 for i in range(w))
    stream += [0] * (-len(stream) % 32)
    return np.array([sum(stream[32 * k + i] << i for i in range(32)) for k in range(len(stream) // 32)],
                    np.uint32)


def random_bits(rng):
    while True:
        b = AttributeBits(normals=None if rng.random() < 0.2 else int(rng.integers(4, 17)),
                          uvs=None if rng.random() < 0.3 else int(rng.integers(6, 17)),
                          colors=None if rng.random() < 0.5 else int(rng.integers(4, 9)))
        if b.record_bits:
            return b


def random_codes(rng, n, bits):
    out = {}
    for name, k in (("normals", 2), ("uvs", 2), ("colors", 4)):
        b = getattr(bits, name)
        if b is not None:
            out[name] = rng.integers(0, 1 << b, size=(n, k))
    return out


def test_record_pack_matches_reference_and_round_trips():
    rng = np.random.default_rng(11)
    crossing = 0
    for trial in range(40):
        bits = random_bits(rng)
        n = int(rng.integers(1, 60))
        codes = random_codes(rng, n, bits)
        words = pack_record(codes, n, bits)
        assert words.dtype == np.dtype("<u4") and words.size == record_words(n, bits) == -(-n * bits.record_bits // 32)
        assert np.array_equal(words, ref_pack(codes, n, bits))
        back = unpack_record(words, n, bits)
        assert set(back) == set(codes) and all(np.array_equal(back[k], codes[k]) for k in codes)
        assert 0 <= record_waste(n, bits) < 32
        assert record_waste(n, bits) == 32 * words.size - n * bits.record_bits
        off = np.arange(n)[:, None] * bits.record_bits + np.array([o for _, _, o, _ in record_fields(bits)])
        wid = np.array([w for _, _, _, w in record_fields(bits)])
        crossing += int(((off % 32) + wid > 32).sum())
    assert crossing > 100  # fields spanning two words were exercised


def test_record_layout_worked_example():
    bits = AttributeBits(normals=12, uvs=None, colors=None)  # 24-bit records: vertex 1 crosses word 0
    codes = {"normals": np.array([[0xABC, 0x123], [0xFFF, 0x001]])}
    words = pack_record(codes, 2, bits)
    assert words.tolist() == [0xFF123ABC, 0x001F]
    assert record_fields(AttributeBits(10, 12, 5)) == [
        ("normals", 0, 0, 10), ("normals", 1, 10, 10), ("uvs", 0, 20, 12), ("uvs", 1, 32, 12),
        ("colors", 0, 44, 5), ("colors", 1, 49, 5), ("colors", 2, 54, 5), ("colors", 3, 59, 5)]


def test_encode_record_decodes_like_the_attribute_decoders_and_is_deterministic():
    rng = np.random.default_rng(7)
    n = 3001
    nrm, uv, col = random_units(rng, n), rng.uniform(-2, 3, (n, 2)), rng.random((n, 4))
    for bits in (AttributeBits(8, 12, 6), AttributeBits(16, 16, 8), AttributeBits(5, None, None),
                 AttributeBits(None, 7, 4), AttributeBits(11, 9, None)):
        words, meta = encode_record(attrs(nrm if bits.normals else None, uv if bits.uvs else None,
                                          col if bits.colors else None), bits)
        assert meta["record_bits"] == bits.record_bits and meta["wasted_bits"] == record_waste(n, bits)
        json.dumps(meta)
        again, _ = encode_record(attrs(np.asfortranarray(nrm) if bits.normals else None, uv if bits.uvs else None,
                                       col if bits.colors else None), bits)
        assert words.tobytes() == again.tobytes()
        out = decode_record(np.frombuffer(words.tobytes(), "<u4"), n, bits, meta["lod"])
        if bits.normals:
            assert np.array_equal(out["normals"], decode_normals(encode_normals(nrm, bits.normals), bits.normals))
            assert angle_deg(nrm, out["normals"]).max() <= normal_error_deg(bits.normals)
        else:
            assert out["normals"] is None
        if bits.uvs:
            q, lo, hi, step = encode_uvs(uv, bits.uvs)
            assert meta["lod"]["uv_step"] == [float(step[0]), float(step[1])]
            assert np.array_equal(out["uvs"], decode_uvs(q, lo, step, bits.uvs))
            assert (np.abs(out["uvs"] - uv) <= uv_error_bound(lo, hi, bits.uvs)).all()
        if bits.colors:
            assert np.array_equal(out["colors"], decode_colors(encode_colors(col, bits.colors), bits.colors))


def test_record_bad_input():
    bits = AttributeBits(8, None, None)
    with pytest.raises(LopcookError):
        encode_record(attrs(), bits)  # bits given without the attribute
    with pytest.raises(LopcookError):
        encode_record(attrs(np.eye(3), np.zeros((3, 2))), bits)  # attribute without bits
    with pytest.raises(LopcookError):
        encode_record(attrs(np.eye(3), np.zeros((2, 2))), AttributeBits(8, 8, None))  # lengths differ
    with pytest.raises(LopcookError):
        unpack_record(np.zeros(1, np.uint32), 3, bits)  # 3 x 16 bits need 2 words
    with pytest.raises(LopcookError):
        pack_record({"normals": np.array([[256, 0]])}, 1, bits)


def test_aligned_waste_first_fit_decreasing():
    assert aligned_waste(AttributeBits(16, 16, None)) == 0
    assert aligned_waste(AttributeBits(8, 12, 8)) == 24  # bins 12+12+8, 8+8+8+8, 8
    assert aligned_waste(AttributeBits(10, 10, None)) == 24  # 10+10+10, 10
    assert aligned_waste(AttributeBits(16, 16, 8)) == 0


# --------------------------------------------------------------------------------- indices

@pytest.mark.parametrize("n_vertices,width", [(1, 2), (3, 2), (65535, 2), (65536, 4), (65537, 4), (10**7, 4)])
def test_indices_round_trip_exact(n_vertices, width):
    rng = np.random.default_rng(n_vertices)
    t = rng.integers(0, n_vertices, (5000, 3)).astype(np.uint32)
    t[0] = [0, n_vertices - 1, 0]
    data, w = encode_indices(t, n_vertices)
    assert w == width == index_width(n_vertices)
    assert data.dtype == np.dtype("<u2" if width == 2 else "<u4") and data.shape == (3 * len(t),)
    assert data.nbytes == 3 * len(t) * width
    for src in (data, data.tobytes(), bytearray(data.tobytes()), memoryview(data.tobytes()), data.view(np.uint8)):
        back = decode_indices(src, w, len(t))
        assert back.dtype == np.uint32 and np.array_equal(back, t)


def test_indices_layout_edge_cases_and_errors():
    t = np.array([[0, 1, 2], [2, 1, 65534]], np.uint32)
    data, w = encode_indices(t, 65535)
    assert w == 2 and data.tobytes() == bytes([0, 0, 1, 0, 2, 0, 2, 0, 1, 0, 0xFE, 0xFF])
    assert encode_indices(t, 65536)[1] == 4  # 65535 would be the primitive-restart value
    data4, w4 = encode_indices(t, 70000)
    assert w4 == 4 and data4.tobytes()[:8] == bytes([0, 0, 0, 0, 1, 0, 0, 0])
    empty, we = encode_indices(np.zeros((0, 3), np.uint32), 0)
    assert empty.size == 0 and decode_indices(empty, we, 0).shape == (0, 3)
    assert encode_indices(t, 65535)[0].tobytes() == data.tobytes()  # deterministic
    with pytest.raises(LopcookError):
        encode_indices(t, 65534)  # index 65534 out of range
    with pytest.raises(LopcookError):
        decode_indices(data, 2, 3)  # wrong triangle count
    with pytest.raises(LopcookError):
        decode_indices(data, 3, 2)
    with pytest.raises(LopcookError):
        decode_indices(data4, 2, 2)  # array width mismatch


# --------------------------------------------------------------------------------- specs

def test_specs_are_json_data():
    specs = attribute_specs()
    json.dumps(specs)
    assert specs["normals"]["bits"] == [4, 16] and specs["uvs"]["bits"] == [6, 16] and specs["colors"]["bits"] == [4, 8]
    specs["normals"]["bits"] = None
    assert attribute_specs()["normals"]["bits"] == [4, 16]  # a fresh copy
    assert index_width(65535) == 2 and index_width(65536) == 4


def attrs(normals=None, uvs=None, colors=None) -> dict:
    """The record encoder's attribute mapping (codec name -> values)."""
    return {"normals": normals, "uvs": uvs, "colors": colors}


def _attributes(n: int, seed: int = 5):
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(n, 3))
    uvs = rng.uniform(-0.5, 2.0, size=(n, 2))
    colors = rng.uniform(0.0, 1.0, size=(n, 4))
    return normals, uvs, colors


def test_record_codes_commute_with_a_permutation_of_the_vertices():
    """The binned record is packed from the codes of the source order permuted (emit's
    ``_encode_buffer``): every code depends on its own vertex alone and the UV range on the set
    of values, so it must equal the record of the permuted attributes."""
    from lopcook.lop.record import record_codes

    normals, uvs, colors = _attributes(997)
    bits = AttributeBits(normals=9, uvs=11, colors=5)
    order = np.random.default_rng(1).permutation(997)
    codes, meta = record_codes(attrs(normals, uvs, colors), bits)
    words, meta_p = encode_record(attrs(normals[order], uvs[order], colors[order]), bits)
    np.testing.assert_array_equal(pack_record({k: v[order] for k, v in codes.items()}, 997, bits), words)
    assert meta == meta_p


def test_code_memo_gives_the_same_codes_and_stays_bounded():
    from lopcook.lop import memo as A
    from lopcook.lop.record import record_codes

    normals, uvs, colors = _attributes(500)
    bits = AttributeBits(normals=8, uvs=10, colors=None)
    plain = record_codes(attrs(normals, uvs), bits)
    with A.code_memo(max_bytes=3 * 500 * 2 * 2):
        assert A._ACTIVE.memo is not None
        first = record_codes(attrs(normals, uvs), bits)
        again = record_codes(attrs(normals.copy(), uvs.copy()), bits)  # the same content, other arrays
        assert again[0]["normals"] is first[0]["normals"]  # taken from the memo
        changed = normals.copy()
        changed[7] = -changed[7]  # another content: encoded again
        other = record_codes(attrs(changed, uvs), bits)
        assert not np.array_equal(other[0]["normals"][7], first[0]["normals"][7])
        np.testing.assert_array_equal(np.delete(other[0]["normals"], 7, 0), np.delete(first[0]["normals"], 7, 0))
        for b in (4, 5, 6, 7):  # more codes than the memo holds: the oldest are dropped
            record_codes(attrs(normals, uvs), AttributeBits(normals=b, uvs=10, colors=None))
        memo = A._ACTIVE.memo
        assert memo.held <= memo.max_bytes
        assert memo.held == sum(v.nbytes for e in memo.entries.values() for v in e if isinstance(v, np.ndarray))
    assert A._ACTIVE.memo is None  # closed with its context
    for k in plain[0]:
        np.testing.assert_array_equal(first[0][k], plain[0][k])
    assert first[1] == plain[1]
