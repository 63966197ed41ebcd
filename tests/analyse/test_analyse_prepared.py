"""lopcook.analyse.prepared: the analysis split for the calibration's probes gives exactly the
minimum levels, reasons and attribute levels of a fresh ``analyse`` at every (eps, edge_eps), in any
probe order (the depth distances it reuses are those of a lower floor), for depth auto / fixed /
off and with edges on and off."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import FIXTURES
from tests.support import fixtures as fx
from lopcook.analyse import analyse
from lopcook.analyse.prepared import LOOKAHEAD, PreparedAnalysis
from lopcook.emit import build
from lopcook.ingest import load
from lopcook.settings import AnalyseSettings
from lopcook.types import MeshPart, Scene

#: (log2 sigma, edge strictness x_e) in the orders a calibration visits them: down, up, mixed
SEQUENCE = [(0.0, 0.0), (-2.0, 0.0), (-5.25, 0.0), (-1.0, -3.0), (-8.0, -7.0), (-3.0, 1.0), (3.0, 2.0),
            (-8.0, -7.0), (0.0, 0.0)]


def clustered_scene(rng) -> Scene:
    """Spheres of different radii, some overlapping, some nearly touching, one far away, with
    normals, colours or nothing: every depth case (binding radius, capped, empty neighbourhood)."""
    base = fx.unit_sphere(2)[0]
    centres = [(0, 0, 0), (2.05, 0, 0), (0, 1.5, 0), (0.5, 0.3, 0.2), (40, 0, 0)]
    radii = [1.0, 1.0, 0.4, 0.3, 1.0]
    parts = []
    for k, (c, r) in enumerate(zip(centres, radii)):
        v = base.positions * r + np.asarray(c, float) + rng.normal(scale=1e-3 * r, size=base.positions.shape)
        normals = base.normals if k % 3 == 0 else None
        colors = rng.random((v.shape[0], 4)).astype(np.float32) if k % 3 == 1 else None
        parts.append(MeshPart(f"s{k}", v, base.indices, normals=normals, colors=colors))
    return Scene(parts=tuple(parts), source="clustered", format="obj").validate()


def assert_same(a, b):
    assert len(a.parts) == len(b.parts)
    for pa, pb in zip(a.parts, b.parts):
        np.testing.assert_array_equal(pa.min_level, pb.min_level)
        np.testing.assert_array_equal(pa.reason, pb.reason)
        np.testing.assert_array_equal(pa.attribute_level, pb.attribute_level)
        np.testing.assert_array_equal(pa.quantized, pb.quantized)
        assert pa.kf == pb.kf and sorted(pa.e_v) == sorted(pb.e_v)
        for k in pa.e_v:
            np.testing.assert_array_equal(pa.e_v[k], pb.e_v[k])
    assert a.colocated_raised == b.colocated_raised


def check_sequence(scene, settings):
    prep = PreparedAnalysis(scene, settings)
    for x, e in SEQUENCE:
        eps, edge_eps = settings.eps / 2.0**x, min(1.0, settings.edge_eps / 2.0**e)
        got = prep.analyse(eps, edge_eps)
        want = analyse(scene, replace(settings, eps=eps, edge_eps=edge_eps))
        assert_same(got, want)
    return prep


@pytest.mark.parametrize("name", ["two_plates.glb", "seamed_cube.glb", "glossy_crease.glb",
                                  "nested_transforms.gltf"])
def test_fixtures_match_a_fresh_analysis(name):
    check_sequence(load(FIXTURES / name), AnalyseSettings())


@pytest.mark.parametrize("settings", [AnalyseSettings(), AnalyseSettings(edges=False),
                                      AnalyseSettings(depth="off"),
                                      AnalyseSettings(depth="fixed", depth_threshold=0.05, depth_level=14)],
                         ids=["auto", "no-edges", "depth-off", "depth-fixed"])
def test_clustered_parts_match_in_every_depth_mode(rng, settings):
    scene = clustered_scene(rng)
    prep = check_sequence(scene, settings)
    if settings.depth == "auto":
        assert prep.depth_queries > 0  # the parts are close: depth distances were looked up


def test_depth_is_only_queried_again_below_the_floors_seen(rng):
    scene = clustered_scene(rng)
    prep = PreparedAnalysis(scene, AnalyseSettings())
    prep.analyse(AnalyseSettings().eps / 2.0**-4)
    n = prep.depth_queries
    prep.analyse(AnalyseSettings().eps)  # higher floors everywhere: every distance is known
    assert prep.depth_queries == n
    # floors down to LOOKAHEAD levels lower were looked up with the first probe
    prep.analyse(AnalyseSettings().eps / 2.0**(-4 - LOOKAHEAD))
    assert prep.depth_queries == n
    prep.analyse(AnalyseSettings().eps / 2.0**(-6 - LOOKAHEAD))  # lower floors: more look-ups
    assert prep.depth_queries > n


def test_the_built_buffers_are_the_same_bytes(rng):
    scene = clustered_scene(rng)
    s = AnalyseSettings()
    prep = PreparedAnalysis(scene, s)
    for x in (-3.0, 0.0):
        t = replace(s, eps=s.eps / 2.0**x)
        opts = {"analyse": t.to_record()}
        assert build(scene, prep.analyse(t.eps, t.edge_eps), options=opts) == build(scene, analyse(scene, t),
                                                                                       options=opts)


def test_a_cook_with_a_prepared_analysis_writes_the_same_bytes(rng):
    """``pipeline.run(..., analysis=...)`` (the attribute search's probes): the container of a fresh
    cook, byte for byte, for eps, edge_eps and per-part attribute bits a search moves, clustered
    or not; refused off the plain path."""
    from lopcook.pipeline import run
    from lopcook.settings import AttributeSettings, EmitSettings, Settings, SimplifySettings, parse_lods

    scene = clustered_scene(rng)
    base = Settings()
    prep = PreparedAnalysis(scene, base.analyse)
    bits = tuple((9, None, 6) if p.normals is not None else (None, None, 5 if p.colors is not None else None)
                 for p in scene.parts)
    for x, e, clusters in ((0.0, 0.0, 64), (-3.0, -2.0, None), (2.0, 1.0, 16)):
        s = base.with_(analyse={"eps": base.analyse.eps / 2.0**x,
                                "edge_eps": min(1.0, base.analyse.edge_eps / 2.0**e)},
                       attributes=AttributeSettings(parts=bits), emit=EmitSettings(clusters=clusters))
        fresh = run(scene, s).container.data
        assert run(scene, s, analysis=prep.analyse(s.analyse.eps, s.analyse.edge_eps)).container.data == fresh
    # copies stored once take it too (tests/emit/test_instances_stored_once.py); LODs are analysed per LOD
    with pytest.raises(ValueError):
        run(scene, base.with_(simplify=SimplifySettings(lods=parse_lods("1/2"))), analysis=prep.analyse(base.analyse.eps))
