"""Welding and unique-row helpers (lopcook.mesh): the fast paths equal numpy's definitions."""

import numpy as np

from lopcook.mesh import sorted_unique, unique_rows, used_ids, weld_exact


def _reference_unique_rows(keys):
    """unique_rows by its definition: first occurrences (increasing), ids by first appearance."""
    rows = [tuple(r) for r in keys.tolist()]
    ids, first, inverse = {}, [], []
    for i, r in enumerate(rows):
        if r not in ids:
            ids[r] = len(first)
            first.append(i)
        inverse.append(ids[r])
    return np.array(first), np.array(inverse)


def test_sorted_unique_and_used_ids_equal_np_unique(rng):
    x = rng.integers(-50, 50, size=2000)
    assert np.array_equal(sorted_unique(x), np.unique(x))
    assert sorted_unique(np.zeros(0, np.int64)).size == 0
    faces = rng.integers(0, 300, size=(500, 3))
    assert np.array_equal(used_ids(faces, 400), np.unique(faces))


def test_unique_rows_packed_and_void_paths_match_the_definition(rng):
    small = rng.integers(0, 4, size=(3000, 3))  # ranges fit one int64 key: packed path
    wide = np.c_[rng.integers(0, 4, size=3000), rng.integers(0, 3, size=(3000, 2)) * (1 << 40)]  # void path
    for keys in (small, wide, small.astype(np.uint32), -small):
        first, inverse = unique_rows(keys)
        ref_first, ref_inverse = _reference_unique_rows(keys)
        assert np.array_equal(first, ref_first) and np.array_equal(inverse, ref_inverse)


def test_weld_exact_numbers_groups_by_first_appearance():
    p = np.array([[1.0, 0, 0], [0, 0, 0], [1.0, 0, 0], [-0.0, 0, 0]])
    inverse, n = weld_exact(p)
    assert n == 2 and inverse.tolist() == [0, 1, 0, 1]


def test_icosahedron_is_regular_and_outward():
    from lopcook.mesh import icosahedron

    v, f = icosahedron()
    assert v.shape == (12, 3) and v.dtype == np.float64 and f.shape == (20, 3) and f.dtype == np.int64
    r = np.linalg.norm(v, axis=1)
    np.testing.assert_allclose(r, np.sqrt(1 + ((1 + 5**0.5) / 2) ** 2), rtol=1e-15)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    assert len(unique) == 30 and np.all(counts == 2)  # closed: every edge in two faces
    np.testing.assert_allclose(np.linalg.norm(v[unique[:, 0]] - v[unique[:, 1]], axis=1), 2.0, rtol=1e-15)
    t = v[f]
    normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    assert np.all(np.einsum("ij,ij->i", normal, t.mean(axis=1)) > 0)  # counter-clockwise from outside
