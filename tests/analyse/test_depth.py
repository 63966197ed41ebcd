"""Depth-critical levels (lopcook.analyse.depth): closed form, spatial index == O(n^2) reference."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support import fixtures as fx
from lopcook.analyse.depth import (depth_levels, depth_levels_reference, level_from_distance,
                                   point_triangle_distance)
from lopcook.grid import dx


def closed_form_level(gap, extent):
    """Smallest b with 2 * sqrt(3) * extent * 2^-(b+1) < gap, i.e. b > log2(sqrt(3) * extent / gap)."""
    b = int(np.floor(np.log2(np.sqrt(3) * extent / gap))) + 1
    assert 2 * dx(b, extent) < gap <= 2 * dx(b - 1, extent)
    return b


@pytest.mark.parametrize("gap", [2.0**-10, 0.003, 0.05])
def test_two_plates_closed_form(gap):
    parts = fx.two_plates(gap=gap)
    pos = [p.positions for p in parts]
    idx = [p.indices for p in parts]
    extent = 1.0  # plates are 1 m x 1 m, gap << 1
    res = depth_levels(pos, idx, extent)
    expect = closed_form_level(gap, extent)
    for lv, d in zip(res.level, res.distance):
        assert np.all(lv == expect)
        np.testing.assert_allclose(d, gap, rtol=1e-9)
    assert not res.touching


def test_point_triangle_distance_regions():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    p = np.array([[0.2, 0.2, 3.0], [-1.0, -1.0, 0.0], [0.5, -2.0, 0.0], [2.0, 2.0, 0.0], [0.25, 0.25, 0.0]])
    d = point_triangle_distance(p, a, b, c)
    np.testing.assert_allclose(d, [3.0, np.sqrt(2), 2.0, np.sqrt(2 * 1.5**2), 0.0], atol=1e-12)


def _random_scene(seed, n_parts):
    rng = np.random.default_rng(seed)
    pos, idx = [], []
    for k in range(n_parts):
        m = trimesh.creation.icosphere(1, radius=rng.uniform(0.05, 0.3))
        v = np.asarray(m.vertices) + rng.uniform(-0.5, 0.5, 3)
        v = v + rng.normal(scale=0.01, size=v.shape)
        pos.append(v)
        idx.append(np.asarray(m.faces))
    return pos, idx


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.integers(2, 4))
def test_spatial_index_equals_reference(seed, n_parts):
    pos, idx = _random_scene(seed, n_parts)
    extent = float(np.max(np.max([p.max(0) for p in pos], 0) - np.min([p.min(0) for p in pos], 0)))
    ref_levels, ref_d = depth_levels_reference(pos, idx, extent, ceiling=24)
    res = depth_levels(pos, idx, extent, ceiling=24)
    for a, b, da, db in zip(res.level, ref_levels, res.distance, ref_d):
        np.testing.assert_array_equal(a, b)
        finite = np.isfinite(da)
        np.testing.assert_allclose(da[finite], db[finite], rtol=1e-9, atol=1e-12)
    # with floors: wherever the depth level matters (> floor) it is exact
    rng = np.random.default_rng(seed)
    floors = [rng.integers(1, 12, size=p.shape[0]) for p in pos]
    res_f = depth_levels(pos, idx, extent, floors=floors, ceiling=24)
    for a, b, f in zip(res_f.level, ref_levels, floors):
        np.testing.assert_array_equal(np.maximum(a, f), np.maximum(b, f))


@pytest.mark.parametrize("seed", [3, 11])
def test_tree_budget_changes_no_result(monkeypatch, seed):
    """Trees evicted under a small budget and built again give the same levels, distances, nearest
    parts, touching and intersecting pairs; uint32 indices (the ingest's dtype) as int64 ones."""
    import lopcook.analyse.depth as depth

    pos, idx = _random_scene(seed, 8)
    pos.append(pos[0] + [0.0, 0.0, 0.01])  # a near copy: touching and intersecting pairs
    idx.append(idx[0])
    extent = float(np.max(np.max([p.max(0) for p in pos], 0) - np.min([p.min(0) for p in pos], 0)))
    full = depth_levels(pos, idx, extent, ceiling=24)
    assert full.trees_built <= len(pos)
    monkeypatch.setattr(depth, "TREE_BUDGET_TRIANGLES", 1)  # every tree not pinned is evicted at first
    small = depth_levels(pos, [i.astype(np.uint32) for i in idx], extent, ceiling=24)
    assert small.trees_built > full.trees_built
    for name in ("level", "distance", "nearest", "capped"):
        for a, b in zip(getattr(full, name), getattr(small, name)):
            np.testing.assert_array_equal(a, b)
    assert (full.touching, full.intersecting, full.queries) == (small.touching, small.intersecting, small.queries)
    assert full.intersecting


def _tiles(k, n):
    """k x k square tiles of n x n quads on a wavy height field, each a part, touching at borders."""
    parts = []
    for ix in range(k):
        for iy in range(k):
            xs, ys = np.linspace(ix, ix + 1, n + 1), np.linspace(iy, iy + 1, n + 1)
            x, y = np.meshgrid(xs, ys, indexing="ij")
            p = np.stack([x.ravel(), y.ravel(), (0.02 * np.sin(7 * x) * np.cos(5 * y)).ravel()], 1)
            a = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
            f = np.concatenate([np.stack([a, a + n + 1, a + 1], 1), np.stack([a + 1, a + n + 1, a + n + 2], 1)])
            parts.append((p, f.astype(np.uint32)))
    return [p for p, _ in parts], [f for _, f in parts]


@pytest.mark.parametrize("k,n", [(3, 20), (5, 8)])
def test_tree_budget_rebuilds_are_bounded(monkeypatch, k, n):
    """Touching tiles whose neighbourhoods do not fit the budget: the same result, and the rebuilds
    raise the budget, so at most 2 n + T / t trees are built (here 3 per tile)."""
    import lopcook.analyse.depth as depth

    pos, idx = _tiles(k, n)
    floors = [np.full(p.shape[0], 12) for p in pos]
    full = depth_levels(pos, idx, float(k), floors=floors)
    monkeypatch.setattr(depth, "TREE_BUDGET_TRIANGLES", 1)
    small = depth_levels(pos, idx, float(k), floors=floors)
    assert len(pos) < small.trees_built <= 3 * len(pos)
    assert full.trees_built == len(pos)
    for a, b in zip(full.level + full.distance + full.nearest, small.level + small.distance + small.nearest):
        np.testing.assert_array_equal(a, b)
    assert full.touching == small.touching and full.touching


def test_touching_parts_are_capped_and_reported():
    parts = fx.two_plates(gap=1e-9)
    res = depth_levels([p.positions for p in parts], [p.indices for p in parts], 1.0, ceiling=16)
    assert all(np.all(lv == 16) for lv in res.level)
    assert all(c.all() for c in res.capped)
    assert res.touching == [(0, 1)]


def test_intersecting_closed_parts_are_reported():
    big = trimesh.creation.box(extents=(1, 1, 1))
    small = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    small_v = np.asarray(small.vertices) + [0, 0.5, 0]  # half sunk into the big box's top face
    res = depth_levels([np.asarray(big.vertices), small_v], [big.faces, small.faces], 1.0)
    assert res.intersecting == [(0, 1)]


def test_level_from_distance_edges():
    extent = 1.0
    d = np.array([np.inf, 2 * dx(1, extent) * 1.0000001, 2 * dx(1, extent), 0.0])
    np.testing.assert_array_equal(level_from_distance(d, extent), [1, 1, 2, 25])
