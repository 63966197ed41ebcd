"""lopcook.settings: one frozen Settings, enums, DEFAULTS as data, an exact manifest round trip and
one clear error for a record that does not parse."""

from __future__ import annotations

import dataclasses

import pytest

from lopcook.cli.parser import build_parser
from lopcook.errors import LopcookError
from lopcook.lop.codecs import CODECS
from lopcook.settings import (DEFAULTS, AnalyseSettings, AttributeSettings, DepthMode, IngestSettings, LodBackend,
                              LodSpec, Settings, SeamMode, SimplifySettings, TextureSlope, halvings, parse_lods)
from lopcook.viewing import Viewing


def test_defaults_are_frozen_data():
    assert Settings() == DEFAULTS
    with pytest.raises(dataclasses.FrozenInstanceError):
        DEFAULTS.analyse.eps = 0.5  # type: ignore[misc]
    assert DEFAULTS.analyse.depth is DepthMode.AUTO and DEFAULTS.analyse.texture_kf is TextureSlope.IMAGE
    # chosen by measurement (docs/lod.md): meshoptimizer with pymeshlab on small inputs, seams
    # collapsed along themselves with the position-welded mesh where that stops short
    assert DEFAULTS.simplify.backend is LodBackend.AUTO and DEFAULTS.simplify.lods is None
    assert DEFAULTS.simplify.seams is SeamMode.AUTO


def test_containers_without_a_seam_record_were_cooked_with_locked_seams():
    record = Settings(simplify=SimplifySettings(lods=LodSpec(), backend="meshopt", seams="simplify")).to_manifest()
    assert record["options"]["lods"] == {"ratios": "auto", "backend": "meshopt", "seams": "simplify"}
    del record["options"]["lods"]["seams"]
    assert Settings.from_manifest(record).simplify.seams is SeamMode.LOCK


@pytest.mark.parametrize("settings", [
    Settings(),
    Settings(analyse=AnalyseSettings(eps=0.002, depth="fixed", depth_level=9, depth_threshold=0.01, texture_kf=3.5,
                                     kf=2.0, edges=False, edge_level=10),
             ingest=IngestSettings(crease_angle_deg=30.0),
             simplify=SimplifySettings(lods=LodSpec(auto=False, ratios=(0.5, 0.25)), backend="fast"),
             viewing=Viewing(viewport=(640, 480), fov_y_deg=45.0, nearest_m=0.5, pixel_error=1.0)),
    Settings(analyse=AnalyseSettings(position_margin=16.0)),
    Settings(simplify=SimplifySettings(lods=LodSpec()), analyse=AnalyseSettings(depth="off", texture_kf="off")),
    Settings(attributes=AttributeSettings.of(normal=9, uv=None, color=4)),
    Settings(attributes=AttributeSettings.of(uv=12, parts=((8, None, 5), (None, 16, None), (16, 6, 8)))),
    Settings(simplify=SimplifySettings(instances=True)),
    Settings(simplify=SimplifySettings(instances=False)),
])
def test_manifest_round_trip_is_exact(settings):
    record = settings.to_manifest()
    assert Settings.from_manifest(record) == settings
    # the default (None: stored once where the scene has copies) writes no record
    assert record["options"].get("instances") is settings.simplify.instances
    # the record is plain JSON data: enums appear as their strings
    import json

    assert json.loads(json.dumps(record)) == record


def test_containers_without_a_position_margin_were_cooked_with_the_worst_case_bound():
    # the default (1) is not written, so a default cook's bytes did not change with the field
    assert DEFAULTS.analyse.position_margin == 1.0
    assert "position_margin" not in Settings().to_manifest()["options"]["analyse"]
    record = Settings(analyse=AnalyseSettings(position_margin=16.0)).to_manifest()
    assert record["options"]["analyse"]["position_margin"] == 16.0
    assert Settings.from_manifest(record).analyse.position_margin == 16.0
    del record["options"]["analyse"]["position_margin"]
    assert Settings.from_manifest(record).analyse.position_margin == 1.0


def test_record_matches_the_cli_spelling():
    rec = AnalyseSettings(depth="fixed", depth_level=9, depth_threshold=0.01).to_record()
    assert rec["depth"] == "fixed:9" and rec["depth_threshold_m"] == 0.01 and rec["texture_kf"] == "image"
    assert LodSpec(auto=False, ratios=(0.5, 0.25, 0.125)).text == "1/2,1/4,1/8" and LodSpec().text == "auto"


@pytest.mark.parametrize("mutate, match", [
    (lambda m: m["options"].pop("analyse"), "missing 'analyse'"),
    (lambda m: m["options"]["analyse"].update(depth="sideways"), "do not parse"),
    (lambda m: m["options"]["analyse"].update(eps=-1.0), "eps"),
    (lambda m: m["options"]["analyse"].update(colour="red"), "unknown analyse options"),
    (lambda m: m["options"].update(lods={"ratios": "1/2,2", "backend": "fast"}), "do not parse"),
    (lambda m: m["viewing"].update(fov_y_deg="wide"), "do not parse"),
    (lambda m: m["options"].update(attributes={"normal_bits": 3, "uv_bits": None, "color_bits": None, "parts": []}),
     "normal bits"),
    (lambda m: m["options"].update(attributes={"normal_bits": 8}), "do not parse"),
    (lambda m: m["options"].update(attributes={"normal_bits": None, "uv_bits": None, "color_bits": None,
                                               "parts": [[8, 8]]}), "do not parse"),
])
def test_a_record_that_does_not_parse_is_one_clear_error(mutate, match):
    m = Settings().to_manifest()
    mutate(m)
    with pytest.raises(LopcookError, match=match) as err:
        Settings.from_manifest(m, "x.lop")
    assert err.value.path == "x.lop" and "\n" not in str(err.value)


@pytest.mark.parametrize("bad", [dict(eps=float("inf")), dict(eps=0.0), dict(ks=-1.0), dict(kf=float("nan")),
                                 dict(texture_kf=-1.0), dict(texture_kf="sometimes"), dict(depth="fixed"),
                                 dict(depth="off", depth_level=3), dict(depth_threshold=-1.0), dict(edge_eps=2.0),
                                 dict(depth_ceiling=25), dict(position_margin=0.0),
                                 dict(position_margin=float("nan")), dict(position_margin=8192.0)])
def test_out_of_range_analyse_values_are_refused(bad):
    with pytest.raises(ValueError):
        AnalyseSettings(**bad)


def test_lod_spec():
    assert parse_lods("auto").resolved() == halvings()
    assert parse_lods("1/2, 1/4").resolved() == [0.5, 0.25]
    assert parse_lods("1,1/2").resolved() == [0.5]  # ratio 1 is LOD 0
    assert parse_lods(None) is None
    for bad in ("1/4,1/2", "2", "0", "half"):
        with pytest.raises(LopcookError):
            parse_lods(bad)
    assert halvings(5, triangles=40, min_triangles=4) == [0.5, 0.25, 0.125]


def test_cli_help_shows_the_defaults():
    cook = build_parser()._subparsers._group_actions[0].choices["cook"]
    text = cook.format_help()
    for shown in (f"{DEFAULTS.render.views} views", DEFAULTS.tune.calibration.resolution_text,
                  f"default {DEFAULTS.analyse.depth_ceiling}", f"default {DEFAULTS.simplify.backend.value}",
                  f"{DEFAULTS.viewing.viewport[0]}x{DEFAULTS.viewing.viewport[1]}"):
        assert shown in " ".join(text.split()), shown


@pytest.mark.parametrize("bad", [dict(normal=3), dict(normal=17), dict(uv=5), dict(uv=17),
                                 dict(color=3), dict(color=9), dict(normal=8.0), dict(uv=True),
                                 dict(parts=((8,) * (len(CODECS) + 1),)), dict(parts=((8, 5, None),)),
                                 dict(normals=8)])
def test_out_of_range_attribute_bits_are_refused(bad):
    with pytest.raises(ValueError):
        AttributeSettings.of(**bad)


def test_attribute_requests_per_part():
    a = AttributeSettings.of(normal=10, color=6, parts=((8, None, None), (None, 12, 4)))
    assert a.requested(0) == {"normals": 8, "uvs": None, "colors": 6, **{c.name: None for c in CODECS[3:]}}
    assert a.requested(1) == {"normals": 10, "uvs": 12, "colors": 4, **{c.name: None for c in CODECS[3:]}}
    assert AttributeSettings().requested(5) == {c.name: None for c in CODECS}
    assert AttributeSettings(parts=((8,),)).parts == ((8,) + (None,) * (len(CODECS) - 1),)  # padded
    with pytest.raises(ValueError):
        a.requested(2)
    assert "attributes" not in Settings().to_manifest()["options"]  # default containers keep their options
