"""Buffers drawn by the render harness (lopcook.verify.buffers): AP at a level, the binned-to-source
order, the LOD per part and the position bytes. The GPU check decodes an AP buffer with the shipped
GLSL decoder (GL: skipped without EGL, a failure under CI=true)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FIXTURES
from lopcook.analyse import analyse
from lopcook.lop.binning import LEVELS, buffer_bytes
from lopcook.lop.bitplane import decode, reconstruct_float32
from lopcook.lop.reader import top_values
from lopcook.lop.summary import memory_rows
from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.settings import AnalyseSettings
from lopcook.types import MeshPart, Scene
from lopcook.verify import buffers as B
from lopcook.verify import gpu


def test_ap_buffer_holds_b_bits_for_every_vertex(crease):
    _, c = crease
    for level in (1, 6, 12, 24):
        buf = B.ap_buffer(c, 0, 0, level)
        values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
        assert np.all(widths == level)
        top, w = top_values(c, 0, 0, 24)
        np.testing.assert_array_equal(values, top >> np.uint32(24 - level))
        n = int(buf.vertex_id[LEVELS])
        assert buf.words.size * 4 == 4 * ((3 * level * n + 31) // 32)


def test_source_order_maps_binned_vertices_to_source_vertices(crease):
    s, c = crease
    (order,) = B.source_order(c, s)
    assert sorted(order.tolist()) == list(range(s.parts[0].n_vertices))
    an = analyse(s, AnalyseSettings())
    from lopcook.lop.binning import make_bins

    np.testing.assert_array_equal(order, make_bins(an.parts[0].min_level).order)


def test_source_order_rejects_another_source(crease):
    _, c = crease
    other = load(str(FIXTURES / "unit_sphere.glb"))
    with pytest.raises(LopcookError, match="source"):
        B.source_order(c, other)
    s, _ = crease
    p = s.parts[0]
    moved = Scene((MeshPart(p.name, p.positions + 0.01, p.indices, normals=p.normals),), "moved", "glb")
    with pytest.raises(LopcookError, match="positions differ"):
        B.source_order(c, moved)


def test_ap_decoded_by_the_shipped_glsl_decoder_matches_the_cpu(gl, crease):
    _, c = crease
    g = c.manifest["grid"]
    cell = g["extent"] / float(1 << LEVELS)
    for level in (6, 11):
        buf = B.ap_buffer(c, 0, 0, level)
        got = gpu.vertex_decoder("glsl").decode(buf.words, buf.vertex_id, buf.bit_id, level, g["origin"],
                                                np.float32(cell / 2.0))
        values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
        ref = reconstruct_float32(values, widths, g["origin"], cell)
        np.testing.assert_array_equal(got.position.view(np.uint32), ref.view(np.uint32))



def test_position_bytes_are_the_memory_rows(crease):
    _, c = crease
    rows = {m["level"]: m for m in memory_rows(c, levels=[1, 6, 12, 24])}
    n = c.manifest["parts"][0]["lods"][0]["vertices"]
    for b in (1, 6, 12, 24):
        got = B.position_bytes(c, [0], b)
        assert got == {"ap": rows[b]["ap_bytes"], "cap": rows[b]["cap_bytes"]}
        assert got["ap"] == 4 * ((3 * b * n + 31) // 32)
        assert got["cap"] == buffer_bytes(np.asarray(c.manifest["parts"][0]["lods"][0]["vertex_id"]), b)


class _Fake:
    """The two attributes ``lod_indices`` and ``lod0_is_source`` read from a container."""

    def __init__(self, lods_per_part, options=None):
        self.path = "fake.lop"
        self.manifest = {"parts": [{"lods": [{}] * k} for k in lods_per_part], "options": options or {}}


def test_lod_indices_clamp_to_each_parts_last_lod():
    c = _Fake([3, 1, 2])
    assert B.lod_indices(c, 0) == [0, 0, 0]
    assert B.lod_indices(c, 1) == [1, 0, 1]
    assert B.lod_indices(c, 2) == [2, 0, 1]
    with pytest.raises(LopcookError, match="no part has a LOD 3"):
        B.lod_indices(c, 3)
    with pytest.raises(LopcookError, match=">= 0"):
        B.lod_indices(c, -1)


def test_lod0_is_source_unless_the_budget_chose_a_simplified_lod():
    assert B.lod0_is_source(_Fake([1]))
    assert B.lod0_is_source(_Fake([1], {"budget": {"chosen": {"lod": 0, "level": 9}}}))
    assert not B.lod0_is_source(_Fake([1], {"budget": {"chosen": {"lod": 2, "level": 9}}}))


def test_source_order_is_kept_on_the_container_per_scene_object(crease):
    """A report evaluates one container level by level: the order (and its check against the
    source, which reads every plane) is computed once per scene object."""
    s, c = crease
    first = B.source_order(c, s)
    assert B.source_order(c, s) is first
    same = Scene(s.parts, "same parts", "glb")  # another scene object: checked again, the same order
    again = B.source_order(c, same)
    assert again is not first
    np.testing.assert_array_equal(again[0], first[0])


@pytest.mark.parametrize("cluster_all", [False, True])
def test_buffers_carry_what_the_reference_decoder_gives(crease, cluster_all):
    """The render harness projects a buffer's positions for the coverage cull and names its draws
    by them: the ``decoded`` values a buffer carries must be the reference decode of its words."""
    from lopcook.emit import build
    from lopcook.lop.clusters import decode_clustered
    from lopcook.lop.container import from_bytes
    from lopcook.lop.reader import ClusteredGpuBuffer

    s, c = crease
    if cluster_all:
        an = analyse(s, AnalyseSettings())
        c = from_bytes(build(s, an, options={"analyse": AnalyseSettings().to_record()}, cluster_size=16,
                             cluster_all=True), None)
    for level in (1, 6, 11, 17, 24):
        for make in (B.ap_buffer, B.cap_buffer):
            buf = make(c, 0, 0, level)
            assert isinstance(buf, ClusteredGpuBuffer) == (cluster_all and make is B.cap_buffer)
            if isinstance(buf, ClusteredGpuBuffer):
                want = decode_clustered(buf.words, buf.clusters, level)
            else:
                want = decode(buf.words, buf.vertex_id, buf.bit_id, level)
            np.testing.assert_array_equal(buf.decoded[0], want[0])
            np.testing.assert_array_equal(np.asarray(buf.decoded[1], np.int64), np.asarray(want[1], np.int64))
