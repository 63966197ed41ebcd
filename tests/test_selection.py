"""lopcook.selection: LOD and per-buffer level for a camera distance; monotone in distance."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lopcook.lop.container import from_bytes
from lopcook import pipeline
from lopcook.ingest import load
from lopcook.selection import lod_threshold_m, select, selection_ranges, viewing_of
from lopcook.settings import DEFAULT_ANALYSE
from lopcook.viewing import Viewing, required_level


def cook_bytes(scene, viewing=Viewing(), *, lod_ratios=None, lod_backend="fast", keep_buffers=False):
    """The stages through ``pipeline.run`` with LOD ratios and viewing conditions: (bytes, CookResult)."""
    from lopcook.settings import LodSpec, Settings, SimplifySettings

    simplify = SimplifySettings() if lod_ratios is None else SimplifySettings(
        lods=LodSpec(auto=False, ratios=tuple(r for r in lod_ratios if r != 1.0)), backend=lod_backend)
    result = pipeline.run(scene, Settings(simplify=simplify, viewing=viewing), keep_buffers=keep_buffers)
    return result.data, result



@pytest.fixture(scope="module")
def bunny_container(corpus):
    scene = load(corpus / "stanford-bunny.obj")
    data, _ = cook_bytes(scene, Viewing(nearest_m=0.3), lod_ratios=[1 / 2, 1 / 4, 1 / 8],
                         lod_backend="fast")
    return from_bytes(data)


def test_selection_ranges():
    v = Viewing()
    per_metre = v.pixel_error * float(v.pixel_size(1.0))
    assert lod_threshold_m(0.0, v) == 0.0
    assert lod_threshold_m(0.002, v) == pytest.approx(0.002 / per_metre)
    r = selection_ranges([0.0, 0.001, 0.001, 0.002], [100, 50, 25, 10], v)
    assert r == [0.0, None, lod_threshold_m(0.001, v), lod_threshold_m(0.002, v)]
    # a LOD with more triangles than a finer one is never picked either
    assert selection_ranges([0.0, 0.001, 0.002], [100, 40, 60], v)[2] is None


def test_small_distance_picks_lod0_and_max_level(bunny_container):
    c = bunny_container
    max_level = c.manifest["positions"]["max_level"]
    for d in (0.0, 1e-6, 1e-3):
        assert select(c, d) == [(0, min(int(required_level(d, c.manifest["grid"]["extent"])), max_level))]
    assert select(c, 0.0) == [(0, max_level)]
    assert select(c.manifest, 0.3) == select(c, 0.3)  # manifest dict or container


def test_thresholds_match_min_distance(bunny_container):
    m = bunny_container.manifest
    v = viewing_of(m)
    lods = m["parts"][0]["lods"]
    assert len(lods) == 4
    for k, e in enumerate(lods):
        assert e["min_distance_m"] == lod_threshold_m(e["geometric_error_m"], v)
        assert select(m, e["min_distance_m"])[0][0] == k
        if k:
            assert select(m, e["min_distance_m"] * (1 - 1e-9))[0][0] == k - 1
    assert select(m, 1e9)[0] == (3, 1)


def test_explicit_viewing_overrides_manifest(bunny_container):
    m = bunny_container.manifest
    d = m["parts"][0]["lods"][1]["min_distance_m"]
    assert select(m, d)[0][0] == 1
    assert select(m, d, Viewing(pixel_error=0.25))[0][0] == 0  # stricter: needs twice the distance
    with pytest.raises(ValueError):
        select(m, -1.0)


@settings(max_examples=200, deadline=None)
@given(st.floats(0, 20), st.floats(0, 20))
def test_monotone_in_distance(bunny_container, a, b):
    near, far = min(a, b), max(a, b)
    m = bunny_container.manifest
    for (lod_n, lvl_n), (lod_f, lvl_f), part in zip(select(m, near), select(m, far), m["parts"]):
        assert part["lods"][lod_f]["triangles"] <= part["lods"][lod_n]["triangles"]
        assert lod_f >= lod_n
        assert lvl_f <= lvl_n
