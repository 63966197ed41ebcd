"""lopcook.lop.manifest: the typed Manifest / PartEntry / LodEntry own the byte accounting, one
definition each, and agree with the bytes actually written."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FIXTURES
from lopcook.lop.binning import buffer_bytes
from lopcook.lop.container import from_bytes
from lopcook.lop.manifest import Manifest
from lopcook.lop.reader import gpu_buffer
from lopcook.lop.summary import memory_rows
from lopcook.ingest import load
from lopcook.pipeline import run
from lopcook.settings import LodSpec, Settings, SimplifySettings


@pytest.fixture(scope="module")
def sphere_lods():
    scene = load(FIXTURES / "unit_sphere.glb")
    settings = Settings(simplify=SimplifySettings(lods=LodSpec(auto=False, ratios=(0.5, 0.25)), backend="fast"))
    return scene, run(scene, settings)


def test_cap_and_ap_bytes_are_the_gpu_buffers(sphere_lods):
    _, result = sphere_lods
    c = result.container
    m = c.entries
    for i, part in enumerate(m.parts):
        for k, e in enumerate(part.lods):
            for level in (1, 6, 12, 24):
                words = gpu_buffer(c, i, k, level).words
                assert e.cap_bytes(level) == 4 * words.size == buffer_bytes(np.asarray(e.vertex_id), level)
                assert e.ap_bytes(level) == 4 * ((3 * level * e.vertices + 31) // 32)
            assert e.float32_bytes == 12 * e.vertices


def test_section_bytes_sum_to_the_file(sphere_lods):
    _, result = sphere_lods
    c = result.container
    m = c.entries
    by_name = {s["name"]: s["length"] for s in c.manifest["sections"]}
    attrs = sum(e.attribute_bytes + e.index_bytes for p in m.parts for e in p.lods)
    named = sum(v for k, v in by_name.items() if not k.startswith("positions/"))
    assert attrs == named  # every attribute section belongs to one buffer, indices counted once
    mandatory = sum(e.mandatory_bytes for p in m.parts for e in p.lods)
    assert by_name["positions/mandatory"] == mandatory
    for e in (e for p in m.parts for e in p.lods):
        # the sphere has normals only: one record of 2 b_n bits per vertex, whole words
        assert e.attribute_bits["uvs"] is None and e.attribute_bits["colors"] is None
        assert e.record_bits == 2 * e.attribute_bits["normals"]
        assert e.attribute_bytes == 4 * -(-e.vertices * e.record_bits // 32)
        assert e.index_bytes >= 3 * e.triangles * e.index_width


def test_cook_rows_use_the_same_accounting(sphere_lods):
    _, result = sphere_lods
    m = result.container.entries
    for part, rows in zip(m.parts, result.lods):
        kept = [r for r in rows if r.kept]
        assert len(kept) == len(part.lods) == 3
        for r, e in zip(kept, part.lods):
            assert (r.attribute_bytes, r.index_bytes, r.mandatory_position_bytes) == \
                   (e.attribute_bytes, e.index_bytes, e.mandatory_bytes)
            assert r.plane_position_bytes == e.plane_bytes(m.max_level)


def test_percentages_use_the_float32_size_they_name(sphere_lods):
    """With LODs the memory table is LOD 0's, against LOD 0's float32 size (not all LODs')."""
    _, result = sphere_lods
    c = result.container
    m = c.entries
    rows = memory_rows(c)
    assert m.float32_bytes(0) < m.float32_bytes_all_lods == c.manifest["stats"]["float32_position_bytes"]
    for r in rows:
        assert r["float32_bytes"] == m.float32_bytes(0)
        assert r["cap_percent"] == pytest.approx(100 * r["cap_bytes"] / m.float32_bytes(0))
    coarse = memory_rows(c, lod=2)
    assert coarse[0]["float32_bytes"] == m.float32_bytes(2) < m.float32_bytes(0)


def test_manifest_of_reads_back(sphere_lods):
    _, result = sphere_lods
    again = from_bytes(result.container.data)
    assert Manifest.of(again.manifest) == result.container.entries


def test_mandatory_bytes_are_the_packed_buffer_at_level_1(sphere_lods):
    _, result = sphere_lods
    for p in result.container.entries.parts:
        for e in p.lods:
            assert e.mandatory_bytes == e.cap_bytes(1) > 0
