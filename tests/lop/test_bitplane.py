"""Pack / decode / add / remove (lopcook.lop.bitplane) against an independent bit-by-bit reader."""

import numpy as np
import pytest

from lopcook.lop.binning import make_bins, table_bit_id, vertex_widths
from lopcook.lop.bitplane import (add_plane, decode, pack, plane_bits, reconstruct_float32,
                                   reconstruct_float64, remove_plane, to_grid, top_bits)


def slow_read(words, vertex_id, level, j):
    """Independent re-implementation of the paper's formula: one bit at a time, plain Python."""
    k = next(k for k in range(1, 25) if vertex_id[k - 1] <= j < vertex_id[k])
    b = max(k, level)
    bit_id = 0
    for kk in range(1, k):
        bit_id += 3 * max(kk, level) * (vertex_id[kk] - vertex_id[kk - 1])
    start = 3 * b * (j - vertex_id[k - 1]) + bit_id
    out = []
    for c in range(3):
        v = 0
        for i in range(b):
            pos = start + c * b + i
            v |= ((int(words[pos // 32]) >> (pos % 32)) & 1) << i
        out.append(v)
    return out, b


@pytest.fixture
def buffer(rng):
    lv = rng.integers(1, 25, 300)
    q = rng.integers(0, 2**24, (300, 3)).astype(np.uint32)
    bins = make_bins(lv)
    return bins, q[bins.order]


@pytest.mark.parametrize("level", [1, 2, 7, 12, 23, 24])
def test_pack_then_decode_matches_slow_reader(buffer, level):
    bins, q = buffer
    w = vertex_widths(bins.vertex_id, level)
    v = top_bits(q, w)
    words = pack(v, bins.vertex_id, level)
    got, widths = decode(words, bins.vertex_id, table_bit_id(bins.vertex_id, level), level)
    np.testing.assert_array_equal(got, v)
    np.testing.assert_array_equal(widths, w)
    for j in range(0, 300, 7):
        vals, b = slow_read(words, bins.vertex_id, level, j)
        assert vals == got[j].tolist() and b == widths[j]


def test_level_24_is_the_quantized_source(buffer):
    bins, q = buffer
    words = pack(q, bins.vertex_id, 24)
    got, w = decode(words, bins.vertex_id, table_bit_id(bins.vertex_id, 24), 24)
    np.testing.assert_array_equal(to_grid(got, w), q)


def test_plane_sequence_equals_packing_from_scratch(buffer):
    bins, q = buffer

    def scratch(b):
        return pack(top_bits(q, vertex_widths(bins.vertex_id, b)), bins.vertex_id, b)

    words = scratch(6)
    for target in (12, 8, 24, 1, 10):
        cur = int(np.argmax([np.array_equal(words, scratch(b)) for b in range(1, 25)])) + 1
        while cur < target:
            words = add_plane(words, bins.vertex_id, cur, plane_bits(q, bins.vertex_id, cur + 1))
            cur += 1
        while cur > target:
            words = remove_plane(words, bins.vertex_id, cur)
            cur -= 1
        np.testing.assert_array_equal(words, scratch(target))


def test_float_reconstruction_within_dx(rng):
    from lopcook.grid import Grid

    pts = rng.uniform(-2, 3, (2000, 3))
    grid = Grid.fit([pts])
    q = grid.quantize(pts)
    for b in (1, 6, 11, 17, 24):
        w = np.full(2000, b)
        v = top_bits(q, w)
        p64 = reconstruct_float64(v, w, grid.origin, grid.cell)
        np.testing.assert_allclose(p64, grid.reconstruct(q, b), rtol=0, atol=1e-12)
        assert np.linalg.norm(p64 - pts, axis=1).max() <= grid.dx(b) + 1e-12
        p32 = reconstruct_float32(v, w, grid.origin, grid.cell)
        # float32: conversion, product and sum each round to nearest (<= 2^-24 relative)
        tol = 4 * 2.0**-24 * (np.abs(grid.origin).max() + grid.extent)
        assert np.abs(p32.astype(np.float64) - p64).max() <= tol


def test_pack_rejects_values_wider_than_their_bin():
    bins = make_bins(np.array([1, 2]))
    with pytest.raises(ValueError):
        pack(np.array([[2, 0, 0], [0, 0, 0]], np.uint32), bins.vertex_id, 1)
