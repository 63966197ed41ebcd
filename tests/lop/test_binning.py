"""Bins and tables (lopcook.lop.binning) on the paper's small example and on random data.

The paper's Figures 9/10 show a 2-D buffer of 5 vertices with minimum levels 1..4. We keep the
same 5 vertices with minimum levels [2, 1, 4, 2, 3] (input order), adapted to 3 components.
Sorted stably by level: original vertices [1, 0, 3, 4, 2] with levels [1, 2, 2, 3, 4].
VertexId[k] = number of vertices with level <= k: [0, 1, 3, 4, 5, 5, ..., 5].
At per-buffer level B each vertex of bin k stores max(k, B) bits per component (3 components):
  B = 1: widths 1,2,2,3,4 -> BitId = [0, 3, 15, 24, 36, 36, ...]
  B = 2: widths 2,2,2,3,4 -> BitId = [0, 6, 18, 27, 39, ...]
  B = 3: widths 3,3,3,3,4 -> BitId = [0, 9, 27, 36, 48, ...]
  B = 4: widths 4,4,4,4,4 -> BitId = [0, 12, 36, 48, 60, ...]
Vertex j = 3 (bin 3) at B = 2 is read at 3*3*(3 - VertexId[2]) + BitId[2] = 0 + 18 = 18.
"""

import numpy as np
import pytest

from lopcook.lop.binning import (buffer_bits, buffer_bytes, make_bins, memory_table, table_bit_id,
                                  vertex_widths)

LEVELS = [2, 1, 4, 2, 3]


def test_paper_example_tables():
    bins = make_bins(np.array(LEVELS))
    assert bins.order.tolist() == [1, 0, 3, 4, 2]
    assert bins.levels.tolist() == [1, 2, 2, 3, 4]
    assert bins.vertex_id.tolist() == [0, 1, 3, 4] + [5] * 21
    expect = {1: [0, 3, 15, 24, 36], 2: [0, 6, 18, 27, 39], 3: [0, 9, 27, 36, 48], 4: [0, 12, 36, 48, 60]}
    for b, head in expect.items():
        bit_id = table_bit_id(bins.vertex_id, b)
        assert bit_id.tolist() == head + [head[-1]] * (25 - len(head))
        assert buffer_bits(bins.vertex_id, b) == head[-1]
    assert buffer_bytes(bins.vertex_id, 1) == 8  # 36 bits -> 2 words
    # the paper's read offset for vertex j = 3 (bin 3) at B = 2
    vid, bit_id = bins.vertex_id, table_bit_id(bins.vertex_id, 2)
    b = max(3, 2)
    assert 3 * b * (3 - vid[2]) + bit_id[2] == 18
    assert vertex_widths(vid, 2).tolist() == [2, 2, 2, 3, 4]


def test_remap_indices_follow_the_sort():
    bins = make_bins(np.array(LEVELS))
    tri = np.array([[0, 1, 2], [2, 3, 4]])
    remapped = bins.remap_indices(tri)
    np.testing.assert_array_equal(bins.order[remapped], tri)


def test_memory_table_percentages(rng):
    lv = rng.integers(1, 25, 1000)
    bins = make_bins(lv)
    rows = memory_table(bins.vertex_id, [24])
    assert rows[0]["bytes"] == buffer_bytes(bins.vertex_id, 24) == 9000  # 72 bits x 1000 = 9000 bytes
    assert rows[0]["percent_of_float32"] == pytest.approx(75.0)


def test_levels_out_of_range_rejected():
    with pytest.raises(ValueError):
        make_bins(np.array([0, 3]))
    with pytest.raises(ValueError):
        table_bit_id(make_bins(np.array([1])).vertex_id, 25)
