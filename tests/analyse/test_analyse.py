"""analyse(): minimum levels m_v from attributes and depth, co-located sharing, reasons, settings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.support import fixtures as fx
from lopcook.analyse import analyse
from lopcook.analyse.result import REASON_CODE
from lopcook.settings import AnalyseSettings
from lopcook.types import MeshPart, Scene


def scene_of(parts):
    return Scene(parts=tuple(parts), source="test", format="obj").validate()


def exact_sphere_part(radius):
    s = fx.unit_sphere(3)[0]
    v = s.positions / np.linalg.norm(s.positions, axis=1)[:, None] * radius
    n = (v / radius).astype(np.float32)
    return MeshPart("sphere", v, s.indices, normals=n)


@pytest.mark.parametrize("radius", [0.1, 1.0, 40.0])
@pytest.mark.parametrize("ks,shininess,eps", [(0.5, 32, 1 / 255), (1.0, 8, 1 / 255), (0.2, 100, 0.01)])
def test_sphere_level_closed_form(radius, ks, shininess, eps):
    # E_v = 1/r, extent = 2r: ks*n/r * sqrt(3)*2r*2^-(b+1) <= eps  <=>  b >= log2(ks*n*sqrt(3)/eps)
    an = analyse(scene_of([exact_sphere_part(radius)]), AnalyseSettings(ks=ks, shininess=shininess, eps=eps, depth="off"))
    p = an.parts[0]
    expect = int(np.ceil(np.log2(ks * shininess * np.sqrt(3) / eps)))
    extent = an.grid.extent
    assert extent == pytest.approx(2 * radius, rel=1e-6)
    # (the grid's extent is the bounding box, a hair under 2r; none of these cases sits near an
    # integer log2, so the closed form with 2r holds exactly)
    assert np.all(p.min_level == expect)
    assert np.all(p.reason == REASON_CODE["normal"])
    np.testing.assert_allclose(p.e_v["normal"] * radius, 1.0, rtol=1e-5)


def test_flat_plane_gets_level_one():
    plate = fx.two_plates()[0].as_mesh_part()
    an = analyse(scene_of([plate]), AnalyseSettings(edges=False))  # its rim is an edge: test_discontinuity
    assert np.all(an.parts[0].min_level == 1)
    assert np.all(an.parts[0].reason == REASON_CODE["none"])
    assert an.histogram()[1] == plate.n_vertices


def test_two_plates_depth_level_and_reason():
    parts = [p.as_mesh_part() for p in fx.two_plates(gap=2.0**-10)]
    an = analyse(scene_of(parts), AnalyseSettings(edges=False))  # depth alone (the rims are edges)
    # extent 1 m: smallest b with sqrt(3) * 2^-b < 2^-10 -> b = 11
    for p in an.parts:
        assert np.all(p.min_level == 11)
        assert np.all(p.reason == REASON_CODE["depth"])
    off = analyse(scene_of(parts), AnalyseSettings(depth="off", edges=False))
    assert all(np.all(p.min_level == 1) for p in off.parts)
    fixed = analyse(scene_of(parts), AnalyseSettings(depth="fixed", depth_level=9, depth_threshold=0.01, edges=False))
    assert all(np.all(p.min_level == 9) for p in fixed.parts)
    far = analyse(scene_of(parts), AnalyseSettings(depth="fixed", depth_level=9, depth_threshold=1e-4, edges=False))
    assert all(np.all(p.min_level == 1) for p in far.parts)


def test_seamed_cube_colocated_vertices_share_level(rng):
    cube = fx.seamed_cube()[0]
    colors = rng.uniform(0, 1, size=(cube.positions.shape[0], 4)).astype(np.float32)
    part = MeshPart("cube", cube.positions, cube.indices, normals=cube.normals, uvs=cube.uvs, colors=colors)
    an = analyse(scene_of([part]), AnalyseSettings(edges=False))  # else every corner is a 14-bit hard edge
    p = an.parts[0]
    q = p.quantized
    _, inv = np.unique(q, axis=0, return_inverse=True)
    for g in range(inv.max() + 1):
        assert len(set(p.min_level[inv.ravel() == g])) == 1
    # at least one copy was raised by a co-located sibling (random colours differ per face)
    assert an.colocated_raised > 0
    assert np.any(p.reason == REASON_CODE["co-located"])


def test_colocated_across_parts():
    a = fx.seamed_cube()[0]
    shifted = a.positions + [1.0, 0, 0]  # shares the face x = 0.5 with the first cube
    colors = np.zeros((a.positions.shape[0], 4), np.float32)
    colors[:, 0] = np.linspace(0, 1, a.positions.shape[0])
    p1 = MeshPart("left", a.positions, a.indices, colors=colors)
    p2 = MeshPart("right", shifted, a.indices)
    an = analyse(scene_of([p1, p2]), AnalyseSettings(depth="off"))
    q1, q2 = an.parts[0].quantized, an.parts[1].quantized
    for i in range(len(q2)):
        same = np.all(q1 == q2[i], axis=1)
        if same.any():
            assert an.parts[1].min_level[i] == an.parts[0].min_level[same].max()


def test_degenerate_triangles_counted_and_finite():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0]], float)
    f = np.array([[0, 1, 2], [1, 3, 4]], np.uint32)
    n = np.array([[0, 0, 1], [0, 0.6, 0.8], [0, 0, 1], [0, 1, 0], [1, 0, 0]], np.float32)
    an = analyse(scene_of([MeshPart("p", v, f, normals=n)]), AnalyseSettings(edges=False))  # open: all rim
    p = an.parts[0]
    assert p.degenerate_triangles == 1
    assert np.isfinite(p.e_v["normal"]).all()
    assert p.min_level[3] == 1 and p.min_level[4] == 1  # only on the degenerate triangle


def test_unsatisfiable_attribute_clamped_to_24_and_counted():
    s = exact_sphere_part(1.0)
    an = analyse(scene_of([s]), AnalyseSettings(kf=1e9, depth="off"))
    p = an.parts[0]
    assert np.all(p.min_level == 24)
    assert p.attribute_unsatisfied == s.n_vertices


def test_invariant_3_on_fixture_sphere_with_uv_texture_kf():
    s = exact_sphere_part(1.0)
    uv = (s.positions[:, :2] * 0.5 + 0.5).astype(np.float32)
    part = MeshPart("s", s.positions, s.indices, normals=s.normals, uvs=uv)
    st = AnalyseSettings(texture_kf=3.0, depth="off")
    an = analyse(scene_of([part]), st)
    p = an.parts[0]
    d = an.grid.dx(p.min_level.astype(np.int64))
    assert np.all(p.kf["normal"] * p.e_v["normal"] * d <= st.position_eps)
    assert np.all(3.0 * p.e_v["uv"] * d <= st.position_eps)
    # and one level lower would violate one of them wherever the level is > 1 and not co-located
    lower = an.grid.dx(np.maximum(p.min_level.astype(np.int64) - 1, 1))
    tight = (p.min_level > 1) & (p.reason != REASON_CODE["co-located"])
    worst = np.maximum(p.kf["normal"] * p.e_v["normal"], 3.0 * p.e_v["uv"])
    assert np.all(worst[tight] * lower[tight] > st.position_eps)


@pytest.mark.parametrize("margin", [2.0, 4.0, 16.0, 0.25])
def test_position_margin_moves_attribute_levels_by_its_log2(margin):
    # dx(b) halves per level, so eps x 2^k lowers every attribute level by exactly k (clamped to
    # [1, 24]); the attribute bits' eps is unchanged
    s = exact_sphere_part(1.0)
    base = analyse(scene_of([s]), AnalyseSettings(depth="off", edges=False, position_margin=1.0))
    an = analyse(scene_of([s]), AnalyseSettings(depth="off", edges=False, position_margin=margin))
    k = int(round(math.log2(margin)))
    want = np.clip(base.parts[0].min_level.astype(np.int64) - k, 1, 24)
    assert np.any(want != base.parts[0].min_level)  # the sphere's levels are high enough to move
    assert an.grid.extent == base.grid.extent
    np.testing.assert_array_equal(an.parts[0].min_level, want)
    assert an.settings.position_eps == pytest.approx(an.settings.eps * margin)


def test_edge_reason_in_counts_and_schema():
    import json
    from pathlib import Path

    import jsonschema

    from lopcook.analyse.result import REASON_CLASS
    from lopcook.analyse.summary import describe_analysis

    cube = fx.seamed_cube()[0].as_mesh_part()  # 24 corners, split normals: all on hard edges
    an = analyse(scene_of([cube]), AnalyseSettings(depth="off"))
    assert an.reason_counts()["edge"] == 24 and REASON_CLASS["edge"] == "attribute"
    assert np.all(an.parts[0].min_level == 14) and np.all(an.parts[0].attribute_level == 14)
    d = describe_analysis(an, "cube")
    schema = json.loads((Path(__file__).resolve().parents[2] / "schema" / "analysis.schema.json").read_text())
    jsonschema.validate(json.loads(json.dumps(d)), schema)
    assert d["settings"]["edges"] is True and d["settings"]["edge_level"] == 12


@pytest.mark.parametrize("span", [1 << 24, 1 << 30], ids=["24-bit", "wider"])
def test_colocated_groups_give_the_maximum_of_each_group_for_any_values(span):
    """``ColocatedGroups(q).max(values)`` equals the maximum over each set of equal rows, by a plain
    dictionary, for several value arrays on one grouping (the 24-bit path and the row sort)."""
    from lopcook.analyse import ColocatedGroups, colocated_max

    rng = np.random.default_rng(7)
    distinct = rng.integers(0, span, size=(300, 3), dtype=np.int64)
    distinct[:40, :2] = distinct[40:80, :2]  # rows that share x and y (and z's top bits) but not z
    distinct[:40, 2] = distinct[40:80, 2] ^ 1
    q = distinct[rng.integers(0, 300, size=2000)].astype(np.uint32)
    groups = ColocatedGroups(q)
    for _ in range(3):
        values = rng.integers(1, 25, size=2000)
        best: dict = {}
        for row, v in zip(map(tuple, q.tolist()), values.tolist()):
            best[row] = max(best.get(row, 0), v)
        want = np.array([best[row] for row in map(tuple, q.tolist())])
        np.testing.assert_array_equal(groups.max(values), want)
        np.testing.assert_array_equal(colocated_max(q, values), want)
    with pytest.raises(ValueError):
        groups.max(values[:-1])
    assert ColocatedGroups(np.zeros((0, 3), np.uint32)).max(np.zeros(0)).shape == (0,)
