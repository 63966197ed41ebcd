"""``mesh.stable_argsort`` and ``mesh.unique_first_inverse`` equal numpy's stable argsort and
``np.unique(return_index, return_inverse)`` exactly, on both the packed path and the fallback."""

import numpy as np
import pytest

from lopcook.mesh import stable_argsort, unique_first_inverse, unique_rows


@pytest.mark.parametrize("dtype", [np.int64, np.int32, np.uint64, np.uint32, np.int16, np.uint8])
@pytest.mark.parametrize("n", [0, 1, 2, 7, 4099])
@pytest.mark.parametrize("span", [1, 3, 100, 1 << 7])
def test_equals_numpy(dtype, n, span):
    rng = np.random.default_rng(n * 31 + span)
    k = rng.integers(0, span, n)
    if np.dtype(dtype).kind == "i":
        k = k - span // 2
    k = k.astype(dtype)
    order, s = stable_argsort(k)
    ref = np.argsort(k, kind="stable")
    assert order.dtype == np.int64 and s.dtype == k.dtype
    np.testing.assert_array_equal(order, ref)
    np.testing.assert_array_equal(s, k[ref])
    first, inv = unique_first_inverse(k)
    _, f2, i2 = np.unique(k, return_index=True, return_inverse=True)
    np.testing.assert_array_equal(first, f2)
    np.testing.assert_array_equal(inv, i2.ravel())


def test_wide_keys_fall_back_and_agree():
    """Keys whose range leaves no room for the index (the stable argsort itself) and uint64 keys
    above 2**63 (offset before packing)."""
    rng = np.random.default_rng(5)
    wide = rng.integers(-(1 << 62), 1 << 62, 5000)
    wide[::7] = wide[0]  # ties keep index order
    np.testing.assert_array_equal(stable_argsort(wide)[0], np.argsort(wide, kind="stable"))
    big = (np.uint64(1 << 63) + rng.integers(0, 50, 3000).astype(np.uint64))
    order, s = stable_argsort(big)
    np.testing.assert_array_equal(order, np.argsort(big, kind="stable"))
    np.testing.assert_array_equal(s, np.sort(big))


def test_unique_rows_first_appearance():
    rows = np.array([[5, 1], [2, 2], [5, 1], [0, 9], [2, 2]], dtype=np.int64)
    first, inv = unique_rows(rows)
    np.testing.assert_array_equal(first, [0, 1, 3])
    np.testing.assert_array_equal(inv, [0, 1, 0, 2, 1])
    first, inv = unique_rows(np.array([[7], [3], [7], [-1]], dtype=np.int64))
    np.testing.assert_array_equal(first, [0, 1, 3])
    np.testing.assert_array_equal(inv, [0, 1, 0, 2])
