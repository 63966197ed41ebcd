"""Attribute encodings (lopcook.emit.attributes): round trips within the documented bounds,
exact axes and indices, determinism, little-endian byte layouts, edge cases."""

import itertools

import numpy as np
import pytest
import trimesh

from lopcook.emit.attributes import (
    BYTES_PER_VERTEX,
    COLOR_MAX_ERROR,
    NORMAL_MAX_ERROR_DEG,
    NORMAL_MEASURED_MAX_ERROR_DEG,
    UV_MAX_ERROR_FRACTION,
    UV_RANGE_BYTES,
    attribute_specs,
    decode_colors,
    decode_indices,
    decode_normals,
    decode_uvs,
    encode_colors,
    encode_indices,
    encode_normals,
    encode_uvs,
    encoded_nbytes,
    index_width,
)
from lopcook.errors import LopcookError


def angle_deg(a, b):
    """Angle between rows of a and b in degrees (atan2 form: accurate for tiny angles)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), (a * b).sum(axis=1)))


def random_units(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def ulp32(x):
    return np.spacing(np.float32(np.abs(x)).astype(np.float32)).astype(np.float64)


# --------------------------------------------------------------------------------- normals

AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float32)


def test_documented_bound_is_the_analytic_one():
    analytic = np.degrees(3 * (np.sqrt(2) / 2) / 32767)  # 3 |dp|, see the module docstring
    assert analytic == pytest.approx(0.003709, abs=1e-6)
    assert analytic < NORMAL_MAX_ERROR_DEG < analytic + 1e-4
    assert NORMAL_MEASURED_MAX_ERROR_DEG <= NORMAL_MAX_ERROR_DEG


def test_normals_random_within_measured_bound():
    rng = np.random.default_rng(1234)
    v = random_units(rng, 1_000_000)
    codes = encode_normals(v.astype(np.float32))
    assert codes.dtype == np.dtype("<u2") and codes.shape == (len(v), 2)
    d = decode_normals(codes)
    assert d.dtype == np.float32 and d.shape == v.shape
    err = angle_deg(v, d)
    assert err.max() <= NORMAL_MEASURED_MAX_ERROR_DEG
    assert 0.0005 < err.mean() < 0.002  # sanity: the encoding is not trivially exact
    assert np.abs(np.linalg.norm(d.astype(np.float64), axis=1) - 1).max() < 1e-6


def test_normals_worst_region_face_centres():
    # the measured worst case lies near (+-1, +-1, +-1)/sqrt(3); probe densely around one of
    # each octant's face centres
    rng = np.random.default_rng(7)
    centres = np.array(list(itertools.product([-1, 1], repeat=3)), np.float64) / np.sqrt(3)
    v = (centres[:, None, :] + rng.normal(size=(8, 20_000, 3)) * 1e-3).reshape(-1, 3)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    err = angle_deg(v, decode_normals(encode_normals(v)))
    assert err.max() <= NORMAL_MEASURED_MAX_ERROR_DEG
    assert err.max() > 0.002  # this really is the bad region


def test_normals_axis_aligned_exact():
    d = decode_normals(encode_normals(AXES))
    assert np.array_equal(d, AXES)
    codes = encode_normals(AXES)
    assert set(np.unique(codes).tolist()) <= {1, 32768, 65535}


def test_normals_diagonals_and_corners():
    dirs = np.array([p for p in itertools.product([-1, 0, 1], repeat=3) if any(p)], np.float64)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    err = angle_deg(dirs, decode_normals(encode_normals(dirs.astype(np.float32))))
    assert len(dirs) == 26
    assert err.max() <= NORMAL_MEASURED_MAX_ERROR_DEG
    # symmetric: every sign/permutation of a direction class has the same error
    on_axis = (np.abs(dirs) > 0).sum(axis=1)
    for k in (1, 2, 3):
        assert np.ptp(err[on_axis == k]) < 1e-9


def test_normals_on_the_fold_and_signed_zero():
    th = np.linspace(0, 2 * np.pi, 100_001)
    fold = np.stack([np.cos(th), np.sin(th), np.zeros_like(th)], axis=1)
    err = angle_deg(fold, decode_normals(encode_normals(fold)))
    assert err.max() <= NORMAL_MEASURED_MAX_ERROR_DEG
    # -0.0 anywhere encodes exactly like +0.0
    pos = np.array([[0.6, 0.8, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.6, 0.8]], np.float32)
    neg = pos.copy()
    neg[pos == 0] = -0.0
    assert np.signbit(neg).any()
    assert encode_normals(neg).tobytes() == encode_normals(pos).tobytes()
    # just below the fold stays close (continuity across z = 0)
    eps = np.float32(1e-7)
    below = np.array([[0.6, 0.8, -eps], [-0.8, 0.6, -eps]], np.float32)
    assert angle_deg(below, decode_normals(encode_normals(below))).max() <= NORMAL_MEASURED_MAX_ERROR_DEG


def test_normals_unit_sphere_mesh():
    s = trimesh.creation.icosphere(5)
    n = np.asarray(s.vertex_normals, np.float32)
    err = angle_deg(n, decode_normals(encode_normals(n)))
    assert err.max() <= NORMAL_MEASURED_MAX_ERROR_DEG


def test_normals_direction_only_and_bytes_input():
    rng = np.random.default_rng(3)
    v = random_units(rng, 1000)
    a = encode_normals(v)
    b = encode_normals(v * 3.5)
    # scaling by 3.5 changes rounding of d/|d|_1 by at most an ulp: allow 1 code of difference
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 1
    ref = decode_normals(a)
    raw = a.tobytes()
    for src in (raw, bytearray(raw), memoryview(raw), np.frombuffer(raw, np.uint8),  # bytes
                np.frombuffer(raw, "<u2"), a.astype(">u2"), a.astype(np.int64), a[::1]):  # values
        assert np.array_equal(decode_normals(src), ref)
    strided = np.repeat(a, 2, axis=0)[::2]  # a non-contiguous view of the same codes
    assert not strided.flags.c_contiguous
    assert np.array_equal(decode_normals(strided), ref)
    assert np.array_equal(decode_normals(strided.reshape(-1)[::1]), ref)
    with pytest.raises(LopcookError):
        decode_normals(a.astype(np.float32))  # codes must be integers
    with pytest.raises(LopcookError):
        decode_normals(a.astype(np.int64) + 70000)  # not uint16 values


def test_normals_deterministic_and_little_endian():
    rng = np.random.default_rng(99)
    v = random_units(rng, 10_000).astype(np.float32)
    a = encode_normals(v).tobytes()
    b = encode_normals(v.copy()).tobytes()
    c = encode_normals(np.asfortranarray(v)).tobytes()
    assert a == b == c
    # +X: s = (32767, 0) -> codes (65535, 32768) -> bytes ff ff 00 80
    assert encode_normals(np.array([[1, 0, 0]], np.float32)).tobytes() == bytes([0xFF, 0xFF, 0x00, 0x80])
    # golden values pin the algorithm (fold and precise candidate choice included);
    # (0.6, 0, 0.8): p.x = 0.6 / 1.4, 0.6 / 1.4 * 32767 = 14043.0 -> code 46811
    x = np.array([[0.267261, 0.534522, -0.801784], [0.6, 0.0, 0.8], [-0.48, 0.6, -0.64]], np.float32)
    assert encode_normals(x).tolist() == [[54613, 60074], [46811, 32768], [11431, 56391]]
    assert encode_normals(x.astype(np.float64)).tolist() == encode_normals(x).tolist()


def test_normals_empty_and_single():
    e = encode_normals(np.zeros((0, 3), np.float32))
    assert e.shape == (0, 2) and e.dtype == np.dtype("<u2")
    assert decode_normals(e).shape == (0, 3)
    assert decode_normals(b"").shape == (0, 3)
    one = np.array([[0.0, 0.0, -1.0]], np.float32)
    assert np.array_equal(decode_normals(encode_normals(one)), one)


def test_normals_code_zero_reads_as_minus_one():
    # code 0 (s = -32768) is never written but decodes like code 1 (s = -32767)
    assert np.array_equal(decode_normals(np.array([[0, 32768]], np.uint16)),
                          decode_normals(np.array([[1, 32768]], np.uint16)))


def test_precise_is_no_worse_than_plain_rounding():
    from lopcook.emit.attributes import _oct_decode64

    rng = np.random.default_rng(5)
    v = random_units(rng, 200_000)
    l1 = np.abs(v).sum(axis=1)
    px, py = v[:, 0] / l1, v[:, 1] / l1
    sg = lambda a: np.where(a >= 0, 1.0, -1.0)  # noqa: E731
    neg = v[:, 2] < 0
    px, py = np.where(neg, (1 - abs(py)) * sg(px), px), np.where(neg, (1 - abs(px)) * sg(py), py)
    plain = np.stack(_oct_decode64(np.rint(px * 32767), np.rint(py * 32767)), axis=1)
    e_plain = angle_deg(v, plain)
    codes = encode_normals(v).astype(np.int64) - 32768
    e_prec64 = angle_deg(v, np.stack(_oct_decode64(codes[:, 0], codes[:, 1]), axis=1))
    assert (e_prec64 <= e_plain + 1e-12).all()  # plain rounding's code is one of the 4 candidates
    e_prec = angle_deg(v, decode_normals(encode_normals(v)))
    assert (e_prec <= e_plain + 1e-5).all()  # + float32 rounding of the decoded normal
    assert e_plain.max() <= NORMAL_MAX_ERROR_DEG
    assert e_prec.max() < 0.75 * e_plain.max()


@pytest.mark.parametrize("bad", [[[0.0, 0.0, 0.0]], [[np.nan, 0.0, 1.0]], [[np.inf, 0.0, 0.0]]])
def test_normals_reject_zero_and_non_finite(bad):
    with pytest.raises(LopcookError) as e:
        encode_normals(np.array(bad, np.float32))
    assert e.value.stage == "emit"


def test_normals_reject_wrong_shape():
    with pytest.raises(LopcookError):
        encode_normals(np.zeros((4, 2), np.float32))
    with pytest.raises(LopcookError):
        decode_normals(b"\x00\x00\x00")  # not a whole number of <u2 pairs


# --------------------------------------------------------------------------------- uvs

def uv_bound(lo, hi):
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    return (hi - lo) * UV_MAX_ERROR_FRACTION + 0.5 * ulp32(np.maximum(np.abs(lo), np.abs(hi)))


def test_uvs_random_within_bound():
    rng = np.random.default_rng(11)
    uv = np.stack([rng.uniform(-3.0, 5.0, 500_000), rng.uniform(0.25, 0.75, 500_000)], 1).astype(np.float32)
    codes, lo, hi = encode_uvs(uv)
    assert codes.dtype == np.dtype("<u2") and codes.shape == uv.shape
    assert lo.dtype == np.dtype("<f4") and hi.dtype == np.dtype("<f4") and lo.shape == hi.shape == (2,)
    assert np.array_equal(lo, uv.min(axis=0)) and np.array_equal(hi, uv.max(axis=0))
    d = decode_uvs(codes, lo, hi)
    assert d.dtype == np.float32
    err = np.abs(d.astype(np.float64) - uv)
    assert (err <= uv_bound(lo, hi)).all()
    # the bound is essentially attained (it is not loose)
    assert (err.max(axis=0) > 0.95 * (hi.astype(np.float64) - lo) * UV_MAX_ERROR_FRACTION).all()
    # the extremes decode exactly
    assert np.array_equal(d.min(axis=0), lo) and np.array_equal(d.max(axis=0), hi)


def test_uvs_grid():
    # a 257 x 257 grid over [0, 1]: every point is i/256, and q = i * 65535/256 is not integral,
    # so check the bound; a grid with 65536 points per axis lands exactly on codes
    g = np.linspace(0, 1, 257, dtype=np.float64)
    uv = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2).astype(np.float32)
    codes, lo, hi = encode_uvs(uv)
    assert np.array_equal(lo, [0, 0]) and np.array_equal(hi, [1, 1])
    err = np.abs(decode_uvs(codes, lo, hi).astype(np.float64) - uv)
    assert err.max() <= 1 / 131070 + 2 ** -25
    k = np.arange(0, 65536, 255, dtype=np.float64) / 65535
    line = np.stack([k, k], 1).astype(np.float32)
    c2, lo2, hi2 = encode_uvs(line)
    assert np.array_equal(c2[:, 0], np.arange(0, 65536, 255))
    assert np.array_equal(decode_uvs(c2, lo2, hi2), line)


def test_uvs_degenerate_range_and_single():
    uv = np.array([[0.3, 0.7], [0.3, 0.1], [0.3, 0.4]], np.float32)  # u constant
    codes, lo, hi = encode_uvs(uv)
    assert lo[0] == hi[0] == np.float32(0.3)
    assert (codes[:, 0] == 0).all()
    d = decode_uvs(codes, lo, hi)
    assert (d[:, 0] == np.float32(0.3)).all()
    one = np.array([[-2.5, 1e6]], np.float32)
    c1, lo1, hi1 = encode_uvs(one)
    assert c1.tolist() == [[0, 0]]
    assert np.array_equal(decode_uvs(c1, lo1, hi1), one)


def test_uvs_empty():
    codes, lo, hi = encode_uvs(np.zeros((0, 2), np.float32))
    assert codes.shape == (0, 2) and codes.dtype == np.dtype("<u2")
    assert np.array_equal(lo, [0, 0]) and np.array_equal(hi, [0, 0])
    assert decode_uvs(codes, lo, hi).shape == (0, 2)


def test_uvs_given_range_and_bytes_input():
    rng = np.random.default_rng(12)
    uv = rng.uniform(0, 1, (1000, 2)).astype(np.float32)
    codes, lo, hi = encode_uvs(uv, lo=[0, 0], hi=[1, 1])
    assert np.array_equal(lo, [0, 0]) and np.array_equal(hi, [1, 1])
    assert np.array_equal(decode_uvs(codes.tobytes(), lo, hi), decode_uvs(codes, lo, hi))
    assert np.abs(decode_uvs(codes, lo, hi) - uv).max() <= 1 / 131070 + 2 ** -25
    with pytest.raises(LopcookError):
        encode_uvs(uv * 2, lo=[0, 0], hi=[1, 1])  # outside the given range
    with pytest.raises(LopcookError):
        encode_uvs(uv, lo=[1, 1], hi=[0, 0])  # lo > hi
    with pytest.raises(LopcookError):
        encode_uvs(np.array([[np.nan, 0]], np.float32))


def test_uvs_signed_zero_and_determinism():
    uv = np.array([[0.0, 0.5], [1.0, 1.0], [0.25, 0.0]], np.float32)
    neg = uv.copy()
    neg[uv == 0] = -0.0
    a = encode_uvs(uv)
    b = encode_uvs(neg)
    assert all(x.tobytes() == y.tobytes() for x, y in zip(a, b))  # lo/hi too: no -0.0 stored
    assert not np.signbit(b[1]).any()
    rng = np.random.default_rng(13)
    r = rng.uniform(-1, 1, (10_000, 2)).astype(np.float32)
    x, y = encode_uvs(r), encode_uvs(r.copy())
    assert all(p.tobytes() == q.tobytes() for p, q in zip(x, y))
    # layout: little-endian u16 per component
    c, _, _ = encode_uvs(np.array([[0.0, 0.0], [1.0, 1.0]], np.float32))
    assert c.tobytes() == bytes([0, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF])


# --------------------------------------------------------------------------------- colors

def test_colors_round_trip_bound_and_clamp():
    rng = np.random.default_rng(21)
    c = rng.uniform(0, 1, (200_000, 4)).astype(np.float32)
    q = encode_colors(c)
    assert q.dtype == np.uint8 and q.shape == c.shape
    d = decode_colors(q)
    assert d.dtype == np.float32
    err = np.abs(d.astype(np.float64) - c)
    assert err.max() <= COLOR_MAX_ERROR + 2 ** -25
    assert err.max() > 0.99 * COLOR_MAX_ERROR
    # every code is a fixed point
    levels = (np.arange(256) / 255).astype(np.float32)
    exact = np.repeat(levels[:, None], 4, axis=1)
    assert np.array_equal(encode_colors(exact)[:, 0], np.arange(256))
    assert np.array_equal(decode_colors(encode_colors(exact)), exact)
    # clamping: below 0 -> 0, above 1 -> 255
    out = np.array([[-0.5, 1.5, -0.0, 2.0]], np.float32)
    assert encode_colors(out).tolist() == [[0, 255, 0, 255]]
    assert np.array_equal(decode_colors(encode_colors(out)), [[0, 1, 0, 1]])


def test_colors_edge_cases_and_determinism():
    assert encode_colors(np.zeros((0, 4), np.float32)).shape == (0, 4)
    assert decode_colors(b"").shape == (0, 4)
    one = np.array([[0.2, 0.4, 0.6, 1.0]], np.float32)
    b = encode_colors(one).tobytes()
    assert b == bytes([51, 102, 153, 255]) == encode_colors(one.copy()).tobytes()
    assert np.array_equal(decode_colors(b), decode_colors(encode_colors(one)))
    with pytest.raises(LopcookError):
        encode_colors(np.array([[np.nan, 0, 0, 1]], np.float32))
    with pytest.raises(LopcookError):
        encode_colors(np.zeros((2, 3), np.float32))


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


# --------------------------------------------------------------------------------- sizes, specs

def test_sizes_match_encoded_bytes():
    rng = np.random.default_rng(31)
    n, m = 70_000, 1000
    normals = random_units(rng, n).astype(np.float32)
    uvs = rng.uniform(0, 1, (n, 2)).astype(np.float32)
    colors = rng.uniform(0, 1, (n, 4)).astype(np.float32)
    tris = rng.integers(0, n, (m, 3)).astype(np.uint32)
    sizes = encoded_nbytes(n, m, normals=True, uvs=True, colors=True)
    codes, lo, hi = encode_uvs(uvs)
    assert sizes["normals"] == encode_normals(normals).nbytes == n * BYTES_PER_VERTEX["normals"]
    assert sizes["uvs"] == codes.nbytes + lo.nbytes + hi.nbytes == 4 * n + UV_RANGE_BYTES
    assert sizes["colors"] == encode_colors(colors).nbytes
    assert sizes["indices"] == encode_indices(tris, n)[0].nbytes == 12 * m
    assert encoded_nbytes(100, 10, uvs=False) == {"normals": 400, "indices": 60}


def test_specs_are_json_data_and_match_constants():
    import json

    specs = attribute_specs()
    assert set(specs) == {"normals", "uvs", "colors", "indices"}
    for name, s in specs.items():
        assert {"bits", "max_error", "unit"} <= set(s), name
    assert json.loads(json.dumps(specs)) == specs
    assert specs["normals"]["max_error"] == NORMAL_MAX_ERROR_DEG and specs["normals"]["unit"] == "degrees"
    assert specs["uvs"]["max_error"] == UV_MAX_ERROR_FRACTION == 1 / 131070
    assert specs["colors"]["max_error"] == COLOR_MAX_ERROR == 1 / 510
    assert specs["indices"]["max_error"] == 0
    assert (specs["normals"]["bits"], specs["uvs"]["bits"], specs["colors"]["bits"]) == (16, 16, 8)
    specs["normals"]["max_error"] = 1.0  # a copy: the module's data is unchanged
    assert attribute_specs()["normals"]["max_error"] == NORMAL_MAX_ERROR_DEG
