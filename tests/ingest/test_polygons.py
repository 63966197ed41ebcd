"""Triangulation (lopcook.ingest.polygons): analytic areas, winding, concave polygons."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from lopcook.ingest.polygons import PolygonTooComplex, check_distinct_corners, triangulate, triangulate_polygon


def signed_areas(pts2, tris):
    a, b, c = pts2[tris[:, 0]], pts2[tris[:, 1]], pts2[tris[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


L_SHAPE = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]], float)


def test_concave_l_hexagon_area_and_winding():
    tris, face = triangulate(np.array([6]), L_SHAPE)
    assert tris.shape == (4, 3)
    assert np.all(face == 0)
    areas = signed_areas(L_SHAPE[:, :2], tris)
    assert np.all(areas > 0)  # same (CCW) turn as the polygon
    assert areas.sum() == pytest.approx(3.0, abs=1e-15)


def test_clockwise_polygon_stays_clockwise():
    cw = L_SHAPE[::-1].copy()
    tris, _ = triangulate(np.array([6]), cw)
    areas = signed_areas(cw[:, :2], tris)
    assert np.all(areas < 0) and areas.sum() == pytest.approx(-3.0)


@pytest.mark.parametrize("reflex", range(4))
def test_concave_quad_any_reflex_corner(reflex):
    dart = np.array([[0.5, 0.5, 0], [1, 0, 0], [0.5, 2, 0], [0, 0, 0]], float)
    # dart is CCW? make it CCW then rotate so the reflex corner is at position `reflex`
    quad = np.roll(dart[[0, 3, 1, 2]] if signed_areas(dart[:, :2], np.array([[0, 1, 2]]))[0] < 0 else dart,
                   reflex, axis=0)
    total = 0.5 * np.sum(quad[:, 0] * np.roll(quad[:, 1], -1) - np.roll(quad[:, 0], -1) * quad[:, 1])
    tris, _ = triangulate(np.array([4]), quad)
    areas = signed_areas(quad[:, :2], tris)
    assert np.all(np.sign(areas) == np.sign(total))
    assert areas.sum() == pytest.approx(total)


def test_mixed_counts_ordered_by_face_and_degenerate_faces_skipped():
    counts = np.array([3, 2, 4, 5])
    pts = np.vstack([
        [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
        [[0, 0, 0], [1, 1, 0]],
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
        [[0, 0, 0], [2, 0, 0], [2, 2, 0], [1, 3, 0], [0, 2, 0]],
    ]).astype(float)
    tris, face = triangulate(counts, pts)
    assert face.tolist() == [0, 2, 2, 3, 3, 3]
    assert tris.max() < pts.shape[0]


@settings(max_examples=60, deadline=None)
@given(st.integers(5, 24), st.integers(0, 2**31 - 1))
def test_star_polygons_tile_exactly(k, seed):
    """Random star-shaped (mostly concave) polygons: k-2 triangles turning like the polygon (CCW),
    areas summing exactly to its shoelace area."""
    rng = np.random.default_rng(seed)
    ang = np.sort(rng.uniform(0, 2 * np.pi, k))
    gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
    # only polygons star-shaped around the origin are guaranteed simple: reject the others
    assume(gaps.min() >= 1e-3 and gaps.max() < np.pi - 1e-3)
    r = rng.uniform(0.2, 1.0, k)
    pts2 = np.stack([r * np.cos(ang), r * np.sin(ang)], 1)
    pts = np.c_[pts2, np.zeros(k)]
    tris = triangulate_polygon(pts)
    assert tris.shape == (k - 2, 3)
    shoelace = 0.5 * np.sum(pts2[:, 0] * np.roll(pts2[:, 1], -1) - np.roll(pts2[:, 0], -1) * pts2[:, 1])
    areas = signed_areas(pts2, tris)
    assert shoelace > 0 and np.all(areas > -1e-12)
    assert areas.sum() == pytest.approx(shoelace, rel=1e-9)


@pytest.mark.parametrize("distinct, refused", [(50, False), (49, True)])
def test_large_polygon_must_list_half_its_corners_distinct(distinct, refused):
    """A 100-corner polygon going round a convex `distinct`-gon: accepted (fanned) with 50 distinct
    positions, refused with 49, whether the positions or the vertex ids show the repeats."""
    k = 100
    ang = 2 * np.pi * (np.arange(k) % distinct) / distinct
    pts = np.stack([np.cos(ang), np.sin(ang), np.zeros(k)], axis=1)
    ids = np.arange(k) % distinct
    if refused:
        with pytest.raises(PolygonTooComplex, match=f"100 corners but only {distinct} distinct positions") as info:
            triangulate(np.array([3, k]), np.vstack([pts[:3], pts]))
        assert info.value.face == 1 and "once" in info.value.hint
        with pytest.raises(PolygonTooComplex, match=f"only {distinct} distinct vertices"):
            check_distinct_corners(np.array([3, k]), np.r_[0, 1, 2, ids])
    else:
        assert triangulate_polygon(pts).shape == (k - 2, 3)
        check_distinct_corners(np.array([k]), ids)


def test_small_polygon_with_repeated_corners_is_still_fanned():
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0]] * 20, float)  # 60 corners, 3 positions
    assert triangulate_polygon(pts).shape == (58, 3)


def comb2(k):
    """(k, 2) counter-clockwise comb: base edge (0, 0)-(k-3, 0), then k - 2 teeth corners."""
    x = np.arange(k - 3, -1, -1)
    return np.vstack([[[0, 0], [k - 3, 0]], np.stack([x, np.where(np.arange(k - 2) % 2 == 0, 4, 2)], 1)]).astype(float)


def shoelace(p):
    return 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])


@pytest.mark.parametrize("at, extra, n_tris", [(1, (18.0, 0.0), 39), (2, (37.0, 0.0), 38)])
def test_earcut_with_a_collinear_or_repeated_corner_covers_the_area(at, extra, n_tris):
    """41 corners: one in the middle of the comb's base edge is used (k - 2 triangles); one
    repeating its neighbour (37, 0) is dropped by earcut (k - 3). Either way: counter-clockwise,
    exact area."""
    ring = comb2(40)
    ring = np.vstack([ring[:at], [extra], ring[at:]])
    tris = triangulate_polygon(np.c_[ring, np.zeros(len(ring))])
    areas = signed_areas(ring, tris)
    assert tris.shape[0] == n_tris
    assert np.all(areas > 0) and areas.sum() == pytest.approx(shoelace(ring), rel=1e-12)


def test_self_intersecting_large_polygon_is_fanned():
    """earcut covers only part of a self-intersecting polygon: the fan is used (k - 2 triangles
    whose signed areas sum to the polygon's)."""
    ring = np.random.default_rng(7).uniform(0, 1, (40, 2))
    if shoelace(ring) < 0:
        ring = ring[::-1].copy()
    tris = triangulate_polygon(np.c_[ring, np.zeros(40)])
    fan = np.stack([np.zeros(38, int), np.arange(1, 39), np.arange(2, 40)], 1)
    assert np.array_equal(tris, fan)
    assert signed_areas(ring, tris).sum() == pytest.approx(shoelace(ring), rel=1e-12)
