"""The scene grid (lopcook.grid): quantization, reconstruction bound dx(b), exactness."""

import numpy as np
import pytest

from lopcook.grid import BITS, CELLS, Grid, dx


def test_fit_is_a_cube_on_the_min_corner():
    g = Grid.fit([np.array([[0.0, 1.0, 2.0], [4.0, 2.0, 3.0]]), np.array([[-1.0, 0.0, 2.5]])])
    assert g.origin == (-1.0, 0.0, 2.0)
    assert g.extent == 5.0
    assert g.cell == 5.0 / 2**24


def test_quantize_range_and_corners():
    g = Grid(origin=(0.0, 0.0, 0.0), extent=1.0)
    q = g.quantize(np.array([[0.0, 0.5, 1.0], [1e-12, 0.999999, -1.0]]))
    assert q.dtype == np.uint32
    assert q[0].tolist() == [0, CELLS // 2, CELLS - 1]
    assert q[1].tolist() == [0, int(np.floor(0.999999 * CELLS)), 0]


@pytest.mark.parametrize("level", [1, 2, 5, 8, 11, 16, 23, 24])
def test_reconstruction_within_dx(rng, level):
    pts = rng.uniform(-3.0, 7.0, size=(5000, 3))
    g = Grid.fit([pts])
    q = g.quantize(pts)
    rec = g.reconstruct(q, level)
    err = np.linalg.norm(rec - pts, axis=1)
    slack = 1e-13 * g.extent  # float64 rounding of origin + centre * cell
    assert err.max() <= g.dx(level) + slack
    # per component at most extent * 2^-(b+1)
    assert np.abs(rec - pts).max() <= g.extent * 2.0 ** -(level + 1) + slack


def test_reconstruction_keeps_top_bits_at_block_centre():
    g = Grid(origin=(0.0, 0.0, 0.0), extent=float(CELLS))  # cell = 1 m: integers are metres
    q = np.array([[0b1011 << 20, 7, CELLS - 1]], dtype=np.uint32)
    # level 4 keeps 0b1011 and the centre of 2^20 dropped cells is at +2^19
    np.testing.assert_array_equal(g.reconstruct(q, 4), [[(0b1011 << 20) + 2**19, 2**19, (0b1111 << 20) + 2**19]])
    np.testing.assert_array_equal(g.reconstruct(q, 24), q + 0.5)


def test_dx_formula():
    assert dx(1, 2.0) == pytest.approx(np.sqrt(3) * 2.0 / 4)
    np.testing.assert_allclose(dx(np.arange(1, 25), 1.0), np.sqrt(3) * 2.0 ** -(np.arange(1, 25) + 1.0))


def test_level_for_displacement_is_smallest():
    g = Grid(origin=(0.0, 0.0, 0.0), extent=1.0)
    d = np.array([10.0, g.dx(5), g.dx(5) * 0.999, g.dx(24) * 0.5])
    np.testing.assert_array_equal(g.level_for_displacement(d), [1, 5, 6, BITS + 1])
