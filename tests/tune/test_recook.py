"""``lopcook.tune.recook``: re-cooking a container from its source with the recorded options
gives the same bytes (the report's determinism check and stage timings)."""

from __future__ import annotations

from dataclasses import asdict

from conftest import FIXTURES
from lopcook.cli import main
from lopcook.lop.container import read
from lopcook.ingest import load
from lopcook.settings import AnalyseSettings
from lopcook.settings import Settings
from lopcook.tune.recook import recook, recorded_settings
from lopcook.viewing import Viewing


def test_recorded_settings_round_trip():
    s = AnalyseSettings(eps=0.002, ks=0.25, shininess=8.0, depth="fixed", depth_level=9, depth_threshold=0.01,
                        depth_ceiling=12, edges=False, edge_eps=0.25, edge_level=10)
    full = Settings(analyse=s, viewing=Viewing(viewport=(640, 480), nearest_m=0.5))
    back = recorded_settings(full.to_manifest())
    assert back == full and asdict(back.analyse) == asdict(s)


def test_unreadable_record_is_a_clear_error():
    import pytest

    from lopcook.errors import LopcookError

    m = Settings().to_manifest()
    m["options"]["analyse"]["depth"] = "sideways"
    with pytest.raises(LopcookError, match="recorded cook options do not parse"):
        recorded_settings(m)
    del m["options"]["analyse"]
    with pytest.raises(LopcookError, match="missing 'analyse'"):
        recorded_settings(m)


def _cook(tmp_path, src, *flags):
    out = tmp_path / "x.lop"
    assert main(["-q", "cook", str(src), "-o", str(out), *flags]) == 0
    return read(str(out)), load(str(src))


def test_recook_default_is_identical(tmp_path):
    c, scene = _cook(tmp_path, FIXTURES / "two_plates.glb")
    r = recook(c, scene, ingest_s=0.5)
    assert r["status"] == "identical" and r["bytes"] == len(open(c.path, "rb").read())
    t = r["timings_s"]
    assert t["ingest"] == 0.5 and {"analyse", "emit", "analyse.depth"} <= set(t)
    assert r["analysis"].parts[0].min_level.size == scene.parts[0].n_vertices


def test_recook_with_lods_and_viewing_is_identical(tmp_path):
    c, scene = _cook(tmp_path, FIXTURES / "unit_sphere.glb", "--lods", "1/2,1/4", "--lod-backend", "fast",
                     "--nearest", "2m", "--eps", "0.01", "--no-edges")
    r = recook(c, scene)
    assert r["status"] == "identical", r["detail"]
    assert "lod" in r["timings_s"] and len(r["lod_reports"]) == 1


def test_recook_prefix_and_differs(tmp_path):
    c, scene = _cook(tmp_path, FIXTURES / "glossy_crease.glb")
    data = open(c.path, "rb").read()
    assert recook(c, scene, file_bytes=data[:len(data) // 2])["status"] == "prefix"
    other = bytearray(data)
    other[-1] ^= 1
    r = recook(c, scene, file_bytes=bytes(other))
    assert r["status"] == "differs" and "differ" in r["detail"]


def test_recook_from_another_source_differs(tmp_path):
    c, _ = _cook(tmp_path, FIXTURES / "two_plates.glb")
    moved = load(str(FIXTURES / "two_plates.glb"))
    from dataclasses import replace

    parts = tuple(replace(p, positions=p.positions + 0.25) for p in moved.parts)
    assert recook(c, replace(moved, parts=parts))["status"] == "differs"
