"""Fast paths of ``lopcook.mesh`` equal the plain numpy forms exactly: ``stable_argsort`` and
``unique_first_inverse`` (numpy's stable argsort and ``np.unique(return_index, return_inverse)``, on
both the packed path and the fallback), ``stable_lexsort`` (``np.lexsort``), ``degenerate_mask`` (the (m, 3) cross-product form)."""

import numpy as np
import pytest

from lopcook.mesh import degenerate_mask, stable_argsort, stable_lexsort, unique_first_inverse, unique_rows


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


def _degenerate_rows(p, f, rel_tol=1e-12):
    """The (m, 3) form of the definition (``degenerate_mask``'s docstring)."""
    rep = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    e0, e1, e2 = p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 1]]
    area2 = np.linalg.norm(np.cross(e0, e1), axis=1)
    longest2 = np.maximum(np.maximum((e0 * e0).sum(1), (e1 * e1).sum(1)), (e2 * e2).sum(1))
    return rep | (longest2 == 0) | (area2 <= rel_tol * longest2)


@pytest.mark.parametrize("seed", range(4))
def test_degenerate_mask_equals_row_form(seed):
    """Random scales, near-collinear triangles (a corner on the opposite edge, nudged by about the
    threshold), repeated indices and coincident corners."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(3000, 3)) * 10.0 ** rng.uniform(-6, 6)
    f = rng.integers(0, 3000, (30000, 3))
    line = f[::3]
    t = rng.uniform(0, 1, (line.shape[0], 1))
    p[line[:, 2]] = p[line[:, 0]] + (p[line[:, 1]] - p[line[:, 0]]) * t + rng.normal(size=(line.shape[0], 3)) * (
        np.abs(p[line[:, 0]]).max() * 10.0 ** rng.uniform(-9, -3))
    f[::11, 1] = f[::11, 0]
    p[f[::13, 2]] = p[f[::13, 1]]
    got = degenerate_mask(p, f)
    want = _degenerate_rows(p, f)
    assert 0 < want.sum() < want.size
    np.testing.assert_array_equal(got, want)
    assert degenerate_mask(p, f[:0]).shape == (0,)


@pytest.mark.parametrize("span", [2, 50, 1 << 24, 1 << 40])
def test_stable_lexsort_equals_numpy(span):
    """Three columns of grid integers (many equal rows at small spans; 1 << 40 takes the unpacked
    argsort for each key)."""
    rng = np.random.default_rng(span % 97)
    q = rng.integers(0, span, (20000, 3))
    q[::5] = q[0]
    np.testing.assert_array_equal(stable_lexsort((q[:, 2], q[:, 1], q[:, 0])),
                                  np.lexsort((q[:, 2], q[:, 1], q[:, 0])))
    np.testing.assert_array_equal(stable_lexsort((q[:, 0],)), np.lexsort((q[:, 0],)))


@pytest.mark.parametrize("block", [1, 3, 7])
def test_blocked_passes_equal_numpy_across_block_boundaries(monkeypatch, block):
    # the passes split a block of rows at a time (mesh._BLOCK, 2^20) give the unsplit results
    import lopcook.mesh as M

    monkeypatch.setattr(M, "_BLOCK", block)
    rng = np.random.default_rng(block)
    for n in (0, 1, block - 1, block, block + 1, 5 * block + 2, 50):
        for dtype in (np.int64, np.uint32):
            k = rng.integers(0, max(2, n // 2), n).astype(dtype)
            order, s = M.stable_argsort(k)
            assert np.array_equal(order, np.argsort(k, kind="stable")) and np.array_equal(s, k[order])
            first, inv = M.unique_first_inverse(k)
            _, f2, i2 = np.unique(k, return_index=True, return_inverse=True)
            assert np.array_equal(first, f2) and np.array_equal(inv, i2.ravel())
