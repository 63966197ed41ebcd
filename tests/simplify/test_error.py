"""lopcook.simplify.error: the sampled Hausdorff distance on analytic cases (a mesh and itself, a
translated copy, a sheet inside a larger one), its samples, and the pruned LOD 0 -> LOD query,
which must equal querying every sample."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.support import fixtures as F
from lopcook.simplify import chain as L
from lopcook.simplify import error as E
from lopcook.simplify import reference as R
from lopcook.ingest import load
from lopcook.types import MeshPart


def _part(positions, indices, name="crafted", **kw) -> MeshPart:
    return MeshPart(name=name, positions=np.asarray(positions, dtype=np.float64),
                    indices=np.asarray(indices, dtype=np.uint32), **kw)


def _moved(part: MeshPart, offset=(0.0, 0.0, 0.0), scale=1.0) -> MeshPart:
    return _part(part.positions * scale + np.asarray(offset), part.indices, name=part.name + "'")


@pytest.fixture(scope="module")
def plate() -> MeshPart:
    return F.two_plates()[0].as_mesh_part()  # x, z in [-0.5, 0.5] at y = 0


@pytest.mark.parametrize("name", ["seamed_cube", "two_plates", "unit_sphere"])
def test_distance_of_a_mesh_to_itself_is_zero_to_rounding(name):
    part = getattr(F, name)()[0].as_mesh_part()
    # vertices are found exactly; a face centroid is off its own face by float rounding only
    assert max(E.hausdorff(part, part)) <= 1e-15


@pytest.mark.parametrize("d", [2.0**-10, 0.25, 3.0])
def test_translated_copy_along_the_normal_is_the_translation(plate, d):
    h, ab, ba = E.hausdorff(plate, _moved(plate, (0.0, d, 0.0)))
    assert h == pytest.approx(d, rel=1e-12) and ab == pytest.approx(d, rel=1e-12) and ba == pytest.approx(d, rel=1e-12)


def test_translated_copy_in_the_plane_is_the_translation(plate):
    # the strip the copy no longer covers is t wide: its far edge is t from the copy
    t = 0.125
    h, ab, ba = E.hausdorff(plate, _moved(plate, (t, 0.0, 0.0)))
    assert h == pytest.approx(t, rel=1e-12) and ab == pytest.approx(t, rel=1e-12) and ba == pytest.approx(t, rel=1e-12)


def test_one_sided_distances_of_a_sheet_inside_a_larger_one(plate):
    small = _moved(plate, scale=0.5)  # x, z in [-0.25, 0.25], on the plate
    h, small_to_plate, plate_to_small = E.hausdorff(small, plate)
    assert small_to_plate <= 1e-15
    # the plate's corner (0.5, 0.5) is a sample; the small sheet's nearest point is its corner
    assert plate_to_small == pytest.approx(0.25 * math.sqrt(2.0), rel=1e-12) and h == plate_to_small


def test_samples_are_referenced_vertices_then_centroids():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [7, 7, 7], [1, 1, 0]], dtype=np.float64)  # vertex 3 unused
    f = np.array([[0, 1, 2], [1, 4, 2]], dtype=np.int64)
    s = R.samples(p, f)
    np.testing.assert_array_equal(s[:4], p[[0, 1, 2, 4]])
    np.testing.assert_allclose(s[4:], [p[[0, 1, 2]].mean(0), p[[1, 4, 2]].mean(0)], rtol=0, atol=1e-15)


def test_point_mesh_projects_onto_the_nearest_face():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    f = np.array([[0, 1, 2]], dtype=np.int64)
    d2, fid, c = R.point_mesh(np.array([[0.25, 0.25, 0.5], [2.0, 0.0, 0.0]]), p, f)
    np.testing.assert_allclose(d2, [0.25, 1.0], rtol=1e-12)
    np.testing.assert_array_equal(fid, [0, 0])
    np.testing.assert_allclose(c, [[0.25, 0.25, 0.0], [1.0, 0.0, 0.0]], atol=1e-12)


# ------------------------------------------------------------------- the pruned LOD 0 -> LOD query


def _brute_ref_to_lod(ref, part):
    return float(np.sqrt(R.point_mesh(ref.samples, part.positions, part.indices.astype(np.int64))[0].max()))


def test_ref_to_lod_pruned_measurement_equals_querying_every_sample(corpus):
    bunny = load(corpus / "stanford-bunny.obj").parts[0]
    ref = R.Reference(bunny)
    for ratio in (1 / 2, 1 / 8):
        lod = L.simplify(bunny, ratio, backend="fast")
        assert E.measure_ref_to_lod(ref, lod.part) == _brute_ref_to_lod(ref, lod.part)


def test_ref_to_lod_on_a_fixture_equals_the_one_sided_hausdorff():
    sphere = F.unit_sphere()[0].as_mesh_part()
    ref = R.Reference(sphere)
    lod = L.simplify(sphere, 0.25, backend="fast")
    d = E.measure_ref_to_lod(ref, lod.part)
    assert d > 0 and d == _brute_ref_to_lod(ref, lod.part)
    assert d == pytest.approx(E.hausdorff(sphere, lod.part)[1], rel=1e-12)


def test_ref_to_lod_finds_a_maximum_at_a_centroid():
    # the same four vertices, the non-planar quad split along the other diagonal: every vertex lies
    # on the LOD (distance 0), the deviation is at the face centroids only
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 1], [0, 1, 0]]
    ref = R.Reference(_part(v, [[0, 1, 2], [0, 2, 3]]))
    lod = _part(v, [[0, 1, 3], [1, 2, 3]])
    d = E.measure_ref_to_lod(ref, lod)
    assert d > 0.1 and d == _brute_ref_to_lod(ref, lod)


# ------------------------------------------------------------ the sampled LOD 0 -> LOD direction


def _brute_vertex_max(ref, part):
    pts = ref.positions[ref.sample_vertices]
    return float(np.sqrt(R.point_mesh(pts, part.positions, part.indices.astype(np.int64))[0].max()))


def test_sample_order_takes_one_vertex_of_every_cell_of_the_complete_levels(corpus):
    pts = load(corpus / "stanford-bunny.obj").parts[0].positions
    order = R.SampleOrder(pts)
    assert np.array_equal(np.sort(order.order), np.arange(pts.shape[0]))
    lo, ext = pts.min(0), (pts.max(0) - pts.min(0)).max()
    for count in (1, 100, 5000, 20000, pts.shape[0] + 5):
        pick = order.take(count)
        assert pick.sum() == min(count, pts.shape[0])
        full = int(order.level[pick].max()) - (0 if pick.all() else 1)
        if full < 1 or pick.all():
            continue
        # every occupied cell of level `full` (8**full cells over the box) holds a sampled vertex
        cell = np.floor((pts - lo) / ext * ((1 << 21) - 1)).astype(np.int64) >> (21 - full)
        key = (cell[:, 0] << 42) | (cell[:, 1] << 21) | cell[:, 2]
        occupied = np.unique(key)
        sampled = np.unique(key[order.order[pick]])
        assert np.array_equal(occupied, sampled), (count, full)
    np.testing.assert_array_equal(R.SampleOrder(pts).take(777), order.take(777))  # deterministic


def test_sampled_ref_to_lod_brackets_the_vertex_maximum(corpus):
    bunny = load(corpus / "stanford-bunny.obj").parts[0]
    ref = R.Reference(bunny)
    for ratio in (1 / 2, 1 / 8, 1 / 32):
        lod = L.simplify(bunny, ratio, backend="fast").part
        exact = _brute_vertex_max(ref, lod)
        for count in (500, 4000):
            measured, bound, queried = E.sampled_ref_to_lod(ref, lod, count)
            assert count <= queried < ref.sample_vertices.size
            assert measured <= exact <= bound
        # every vertex queried: the vertex maximum itself
        assert E.sampled_ref_to_lod(ref, lod, 10**9)[:2] == (exact, exact)


def test_sampled_bound_in_blocks_equals_one_pass(corpus, monkeypatch):
    # the bound is computed a block of rows at a time: blocks of 1, 777 rows and one block over
    # every vertex give the same (measured, bound, queried), bit for bit
    bunny = load(corpus / "stanford-bunny.obj").parts[0]
    ref = R.Reference(bunny)
    lod = L.simplify(bunny, 1 / 8, backend="fast").part
    monkeypatch.setattr(E, "_BOUND_BLOCK", bunny.n_vertices + 1)
    whole = E.sampled_ref_to_lod(ref, lod, 2000)
    assert whole[1] > whole[0]  # a bound above the sampled maximum: the blocks matter
    for block in (1, 777):
        monkeypatch.setattr(E, "_BOUND_BLOCK", block)
        assert E.sampled_ref_to_lod(ref, lod, 2000) == whole


def test_vertices_on_the_lod_need_no_query_and_change_nothing(corpus, monkeypatch):
    # meshoptimizer's LOD vertices are LOD 0 vertices: the transfer marks the ones it copied, and
    # the sampled measurement gives them 0 without a query -- the values of querying them
    bunny = load(corpus / "stanford-bunny.obj").parts[0]
    seen = []
    real = E.sampled_ref_to_lod

    def spy(ref, part, count=None, on_ref=None):
        seen.append((ref, part, on_ref))
        return real(ref, part, count, on_ref=on_ref)

    monkeypatch.setattr(L, "sampled_ref_to_lod", spy)
    L.simplify(bunny, 1 / 4, backend="meshopt", seams="ignore")
    ref, lod, on_ref = seen[-1]
    assert on_ref is not None and on_ref.shape == (bunny.n_vertices,)
    on_lod = {tuple(p) for p in lod.positions.tolist()}
    marked = np.flatnonzero(on_ref)
    assert marked.size >= lod.n_vertices // 2
    assert all(tuple(p) in on_lod for p in ref.positions[marked].tolist())
    for count in (500, 4000, 10**9):
        assert E.sampled_ref_to_lod(ref, lod, count, on_ref=on_ref) == E.sampled_ref_to_lod(ref, lod, count)


def test_sampled_bound_covers_a_spike_the_sample_misses():
    # LOD 0: a 65 x 65 grid in z = 0 with one vertex raised by 0.2; the LOD: the flat square
    n = 65
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    pos = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    spike = 37 * n + 23
    pos[spike, 2] = 0.2
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    faces = np.concatenate([np.stack([a, a + n, a + 1], 1), np.stack([a + 1, a + n, a + n + 1], 1)])
    ref = R.Reference(_part(pos, faces))
    flat = _part([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    order = ref.sample_order
    count = 16  # levels 0-2 of the sample order; the spike is first in its cell at level 3
    assert not order.take(count)[np.flatnonzero(order.order == spike)[0]]  # the sample misses it
    measured, bound, _ = E.sampled_ref_to_lod(ref, flat, count)
    assert measured == 0.0 and bound >= 0.2
    assert E.sampled_ref_to_lod(ref, flat, n * n)[:2] == (0.2, 0.2)
