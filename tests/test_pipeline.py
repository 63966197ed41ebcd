"""lopcook.pipeline.run: LOD chains on one grid, cross-LOD co-located levels, selection
thresholds, and the "no more than a scene needs" savings (issue 7, parts 3 and 5)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from jsonschema import Draft202012Validator

from conftest import FIXTURES, REPO
from lopcook import pipeline
from lopcook.analyse import analyse
from lopcook.emit import build
from lopcook.lop.binning import make_bins
from lopcook.lop.clusters import cluster_order
from lopcook.lop.container import from_bytes
from lopcook.lop.reader import decode_positions
from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.settings import DEFAULT_ANALYSE
from lopcook.viewing import Viewing, required_level


def cook_bytes(scene, viewing=Viewing(), *, lod_ratios=None, lod_backend="fast", keep_buffers=False):
    """The stages through ``pipeline.run`` with LOD ratios and viewing conditions: (bytes, CookResult)."""
    from lopcook.settings import LodSpec, Settings, SimplifySettings

    simplify = SimplifySettings() if lod_ratios is None else SimplifySettings(
        lods=LodSpec(auto=False, ratios=tuple(r for r in lod_ratios if r != 1.0)), backend=lod_backend)
    result = pipeline.run(scene, Settings(simplify=simplify, viewing=viewing), keep_buffers=keep_buffers)
    return result.data, result


RATIOS = [1.0, 1 / 2, 1 / 4, 1 / 8]


@pytest.fixture(scope="module")
def validator() -> Draft202012Validator:
    schema = json.loads((REPO / "schema" / "container.schema.json").read_text())
    Draft202012Validator.check_schema(schema)
    return Draft202012Validator(schema)


@pytest.fixture(scope="module")
def bunny(corpus):
    return load(corpus / "stanford-bunny.obj")


@pytest.fixture(scope="module")
def bunny_lods(bunny):
    data, info = cook_bytes(bunny, Viewing(), lod_ratios=RATIOS, lod_backend="fast",
                            keep_buffers=True)
    return data, info, from_bytes(data)


@pytest.fixture(scope="module")
def bunny_near(bunny):
    data, info = cook_bytes(bunny, Viewing(nearest_m=1.0), lod_ratios=RATIOS,
                            lod_backend="fast")
    return data, info, from_bytes(data)


def _errors(schema_validator, manifest) -> list[str]:
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in schema_validator.iter_errors(manifest)]


@pytest.mark.parametrize("name", ["two_plates.glb", "seamed_cube.glb", "unit_sphere.glb"])
def test_without_lods_bytes_equal_build(name):
    scene = load(FIXTURES / name)
    data, info = cook_bytes(scene, Viewing())
    assert data == build(scene, analyse(scene, DEFAULT_ANALYSE), options=pipeline.DEFAULTS.to_manifest()["options"],
                         cluster_size=pipeline.DEFAULTS.emit.clusters)
    assert info.bytes_saved == 0 and info.max_level == 24
    assert "savings" not in from_bytes(data).manifest


def test_without_lods_bytes_equal_build_bunny(bunny):
    data, _ = cook_bytes(bunny, Viewing())
    assert data == build(bunny, analyse(bunny), options=pipeline.DEFAULTS.to_manifest()["options"],
                         cluster_size=pipeline.DEFAULTS.emit.clusters)


def test_bunny_lods_structure(bunny_lods, validator):
    data, info, c = bunny_lods
    lods = c.manifest["parts"][0]["lods"]
    assert len(lods) == 4  # ratio 1 is LOD 0 itself
    tri = [e["triangles"] for e in lods]
    err = [e["geometric_error_m"] for e in lods]
    dist = [e["min_distance_m"] for e in lods]
    assert tri[0] == bunny_lods[1].lods[0][0].triangles and all(a > b for a, b in zip(tri, tri[1:]))
    assert err[0] == 0.0 and all(a <= b for a, b in zip(err, err[1:])) and err[-1] > 0
    assert dist[0] == 0.0 and all(a <= b for a, b in zip(dist, dist[1:]))
    assert abs(tri[1] / tri[0] - 0.5) < 0.05 and abs(tri[3] / tri[0] - 0.125) < 0.05
    assert c.manifest["positions"]["max_level"] == 24 and info.view_level is None
    assert info.lods_dropped == 0 and "savings" not in c.manifest
    assert _errors(validator, c.manifest) == []


def stored_order(c, part, lod, quantized, min_level):
    """``Bins`` of buffer (part, lod) in the container's vertex order: the cluster order (minimum
    level, Morton code) for a clustered buffer (the default cook), the binned order otherwise."""
    if "cluster_size" in c.manifest["parts"][part]["lods"][lod]:
        return cluster_order(np.asarray(quantized), np.asarray(min_level, dtype=np.int64))
    return make_bins(np.asarray(min_level, dtype=np.int64))


def test_every_lod_decodes_to_its_quantized_positions(bunny_lods):
    _, info, c = bunny_lods
    for i, bufs in enumerate(info.buffers):
        assert len(bufs) == len(c.manifest["parts"][i]["lods"])
        for k, buf in enumerate(bufs):
            bins = stored_order(c, i, k, buf.quantized, buf.min_level)
            q, widths, _ = decode_positions(c, i, k, 24)
            np.testing.assert_array_equal(q, np.asarray(buf.quantized)[bins.order])
            _, w1, _ = decode_positions(c, i, k, 1)
            np.testing.assert_array_equal(w1, bins.levels)  # the min levels that were passed


def test_colocated_vertices_share_one_level_across_lods(bunny_lods):
    _, info, c = bunny_lods
    qs, levels, lod_of = [], [], []
    for i, part in enumerate(c.manifest["parts"]):
        for k in range(len(part["lods"])):
            q, _, _ = decode_positions(c, i, k, 24)
            _, w1, _ = decode_positions(c, i, k, 1)  # widths at level 1 = each vertex's minimum level
            qs.append(q)
            levels.append(w1)
            lod_of.append(np.full(q.shape[0], k))
    q = np.concatenate(qs)
    lv = np.concatenate(levels)
    lod = np.concatenate(lod_of)
    _, inverse = np.unique(q, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    lo = np.full(inverse.max() + 1, 99)
    hi = np.zeros(inverse.max() + 1, dtype=np.int64)
    np.minimum.at(lo, inverse, lv)
    np.maximum.at(hi, inverse, lv)
    assert np.array_equal(lo, hi), "co-located vertices with different minimum levels"
    # the check is not vacuous: locked boundary vertices appear in several LODs
    lmin = np.full(inverse.max() + 1, 99)
    lmax = np.zeros(inverse.max() + 1, dtype=np.int64)
    np.minimum.at(lmin, inverse, lod)
    np.maximum.at(lmax, inverse, lod)
    assert np.count_nonzero(lmax > lmin) > 100
    assert info.colocated_raised_across_lods > 0


def test_nearest_drops_planes_without_clamping(bunny_near, bunny_lods, validator):
    data, info, c = bunny_near
    m = c.manifest
    extent = m["grid"]["extent"]
    view = int(required_level(1.0, extent, Viewing(nearest_m=1.0)))
    assert info.view_level == view
    assert info.max_level == max(view, info.highest_min_level) == m["positions"]["max_level"] < 24
    assert m["stats"]["vertices_clamped_to_max_level"] == 0 == info.vertices_clamped_to_max_level
    assert m["savings"]["planes_dropped"] == list(range(info.max_level + 1, 25))
    assert len(data) < len(bunny_lods[0])
    assert info.bytes == len(data) and info.bytes_saved == info.bytes_without_savings - len(data) > 0
    assert m["savings"]["bytes_saved"] == info.bytes_saved
    assert _errors(validator, m) == []
    for k in range(len(m["parts"][0]["lods"])):
        q, _, _ = decode_positions(c, 0, k, info.max_level)
        full, _, _ = decode_positions(bunny_lods[2], 0, k, 24)
        s = np.uint32(24 - info.max_level)
        np.testing.assert_array_equal(q >> s, full >> s)
    with pytest.raises(LopcookError):
        decode_positions(c, 0, 0, info.max_level + 1)


def test_nearest_on_a_small_scene(validator):
    scene = load(FIXTURES / "unit_sphere.glb")
    base, _ = cook_bytes(scene, Viewing())
    data, info = cook_bytes(scene, Viewing(nearest_m=50.0))
    c = from_bytes(data)
    assert info.max_level < 24 and info.max_level >= info.highest_min_level
    assert len(data) < len(base)
    assert c.manifest["stats"]["vertices_clamped_to_max_level"] == 0
    an = analyse(scene)
    for i, pa in enumerate(an.parts):
        bins = stored_order(c, i, 0, pa.quantized, pa.min_level)
        q, widths, _ = decode_positions(c, i, 0, info.max_level)
        np.testing.assert_array_equal(widths, np.maximum(bins.levels, info.max_level))
        s = (24 - widths)[:, None].astype(np.uint32)
        np.testing.assert_array_equal(q >> s, pa.quantized[bins.order] >> s)
    assert _errors(validator, c.manifest) == []


def test_lod_with_empty_selection_range_is_dropped(monkeypatch, validator):
    """A LOD whose error equals the next one's is never strictly better: it is not written."""
    real = pipeline.lod_chain

    def fake(part, **kw):
        lods, report = real(part, **kw)
        assert len(lods) == 4
        lods[1].error_m = lods[2].error_m
        return lods, report

    monkeypatch.setattr(pipeline, "lod_chain", fake)
    scene = load(FIXTURES / "unit_sphere.glb")
    data, info = cook_bytes(scene, Viewing(), lod_ratios=[1 / 2, 1 / 4, 1 / 8], lod_backend="fast")
    m = from_bytes(data).manifest
    assert info.lods_dropped == len(scene.parts)
    for p, rows in zip(m["parts"], info.lods):
        assert len(p["lods"]) == 3 and [r.kept for r in rows] == [True, False, True, True]
        assert [e["triangles"] for e in p["lods"]] == [r.triangles for r in rows if r.kept]
    assert m["savings"]["lods_dropped"] == len(scene.parts) and m["savings"]["planes_dropped"] == []
    assert m["savings"]["bytes_saved"] == info.bytes_saved > 0
    assert _errors(validator, m) == []
