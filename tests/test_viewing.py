"""Level selection (lopcook.viewing): half-pixel criterion, Hao & Varshney, crack-free per-vertex levels."""

import math

import numpy as np
import pytest

from lopcook.grid import Grid, dx
from lopcook.viewing import (Viewing, distance_for_level, hao_varshney_level, nearest_box_distance,
                             per_vertex_level, required_level)


def test_half_pixel_criterion_closed_form():
    v = Viewing(viewport=(1280, 720), fov_y_deg=60.0, pixel_error=0.5)
    extent = 2.0
    for d in (0.3, 1.0, 7.5, 40.0, 1000.0):
        b = int(required_level(d, extent, v))
        pixel = 2 * d * math.tan(math.radians(30)) / 720
        assert dx(b, extent) <= 0.5 * pixel
        if b > 1:
            assert dx(b - 1, extent) > 0.5 * pixel  # the smallest such level


def test_levels_fall_monotonically_with_distance():
    d = np.geomspace(1e-6, 1e4, 400)
    lv = required_level(d, 1.0)
    assert np.all(np.diff(lv) <= 0) and lv[0] == 24 and lv[-1] == 1


def test_distance_for_level_inverts_required_level():
    extent = 3.0
    for b in range(2, 24):
        d = distance_for_level(b, extent)
        assert required_level(d * (1 + 1e-9), extent) <= b
        assert required_level(d * 0.999, extent) >= b


def test_one_more_doubling_of_distance_drops_one_level():
    extent = 1.0
    lv = [int(required_level(d, extent)) for d in (1.0, 2.0, 4.0, 8.0)]
    assert np.all(np.diff(lv) == -1)


def test_hao_varshney_paper_example():
    # 1024 x 1024 window, pixel accuracy (n = 10), vertex half way across the view volume:
    # m = 10 + 3 + ceil(log2(1 + 2)) = 15 (Hao & Varshney 2001, section 3.5)
    v = Viewing(viewport=(1024, 1024), pixel_error=1.0)
    assert int(hao_varshney_level(0.5, far=1.0, viewing=v)) == 15
    # four bits of sub-pixel accuracy add four bits
    assert int(hao_varshney_level(0.5, far=1.0, viewing=Viewing(viewport=(1024, 1024), pixel_error=1 / 16))) == 19


def test_nearest_box_distance():
    assert nearest_box_distance(np.array([0.0, 0.0, 5.0]), np.array([-1, -1, -1]), np.array([1, 1, 1])) == 4.0
    assert nearest_box_distance(np.zeros(3), np.array([-1, -1, -1]), np.array([1, 1, 1])) == 0.0


def test_crack_free_per_vertex_levels_across_buffers(rng):
    """Two buffers share boundary vertices; whatever their per-buffer levels (each at least what its
    nearest point needs), the shared vertices decode to the same point from any camera."""
    pts = rng.uniform(-1, 1, (200, 3))
    grid = Grid.fit([pts])
    q = grid.quantize(pts)
    min_level = rng.integers(1, 8, 200)  # shared vertices share m_v (co-located sharing)
    for _ in range(50):
        cam = rng.uniform(-20, 20, 3)
        d_near = np.linalg.norm(pts - cam, axis=1).min()
        need = int(required_level(d_near, grid.extent))
        b1, b2 = need + int(rng.integers(0, 5)), need + int(rng.integers(0, 5))
        b1, b2 = min(b1, 24), min(b2, 24)
        l1 = per_vertex_level(pts, cam, grid.extent, b1, min_level)
        l2 = per_vertex_level(pts, cam, grid.extent, b2, min_level)
        np.testing.assert_array_equal(l1, l2)
        np.testing.assert_array_equal(grid.reconstruct(q, l1), grid.reconstruct(q, l2))


def test_viewing_validation():
    for kw in ({"viewport": (0, 10)}, {"fov_y_deg": 180.0}, {"nearest_m": 0.0}, {"pixel_error": 0.0}):
        with pytest.raises(ValueError):
            Viewing(**kw)
