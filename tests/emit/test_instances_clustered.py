"""``cook --instances`` with clustered buffers (issue 16 items 1-5 together): the shared
mesh-grid buffers may be clustered, placements decode through the clustered decode exactly,
memory counts each distinct buffer once with its cluster records, and the GPU decoders agree."""

from __future__ import annotations

import numpy as np
import pytest
from test_instances_stored_once import _reference_world, procedural_scene

from lopcook.emit import clustering_wins
from lopcook.lop.clusters import clustered_bytes
from lopcook.lop.container import CLUSTERED_VERSION, READABLE_MAJORS, from_bytes
from lopcook.lop.placement import resident_level
from lopcook.lop.reader import buffer_clusters, clustered_gpu_buffer, decode_positions, owner
from lopcook.pipeline import run
from lopcook.settings import EmitSettings, Settings, SimplifySettings

FORCED = Settings(simplify=SimplifySettings(instances=True), emit=EmitSettings(clusters=64, cluster_all=True))
DEFAULT_INSTANCES = Settings(simplify=SimplifySettings(instances=True))
UNCLUSTERED = Settings(simplify=SimplifySettings(instances=True), emit=EmitSettings(clusters=None))


@pytest.fixture(scope="module")
def cooked():
    scene = procedural_scene()
    return scene, run(scene, FORCED).container, run(scene, UNCLUSTERED).container, run(scene, DEFAULT_INSTANCES).container


def test_placements_decode_exactly_through_the_clustered_decode(cooked):
    """Every placement of the clustered shared buffer decodes, at every level, to the float32
    reference (the unclustered decode of the same vertices on the mesh grid, then the transform's
    rows in float32, written out in the test), and to the unclustered instanced cook's positions."""
    scene, c, u, _ = cooked
    assert tuple(int.from_bytes(c.data[k:k + 2], "little") for k in (4, 6)) == CLUSTERED_VERSION
    assert tuple(int.from_bytes(u.data[k:k + 2], "little") for k in (4, 6)) == CLUSTERED_VERSION  # placements alone
    placed = [i for i, p in enumerate(c.manifest["parts"]) if "placement" in p]
    assert len(placed) == 4
    j = owner(c, placed[0])
    assert c.manifest["parts"][j]["lods"][0]["cluster_size"] == 64
    for i in placed:  # each placement names the owner's clusters, stored once
        assert c.manifest["parts"][i]["lods"][0]["cluster_words"] == c.manifest["parts"][j]["lods"][0]["cluster_words"]
    for i in range(len(scene.parts)):
        for level in range(1, 25):
            g, w, pos = decode_positions(c, i, 0, level)
            gu, wu, posu = decode_positions(u, i, 0, level)
            if i in placed:
                assert np.array_equal(pos.view(np.uint32), _reference_world(c, i, level).view(np.uint32))
            # the same vertices in both files (cluster order vs binned order): equal as multisets
            ka, kb = np.lexsort(np.c_[pos.view(np.uint32), w].T), np.lexsort(np.c_[posu.view(np.uint32), wu].T)
            assert np.array_equal(pos[ka].view(np.uint32), posu[kb].view(np.uint32))
            assert np.array_equal(g[ka], gu[kb]) and np.array_equal(w[ka], wu[kb])


def test_memory_counts_each_distinct_clustered_buffer_once_with_its_records(cooked):
    scene, c, u, _ = cooked
    m = c.entries
    owners = sorted({owner(c, i) for i in range(len(scene.parts))})
    shifts = [m.parts[i].level_shift for i in range(len(scene.parts)) if m.parts[i].placement_of is not None]
    for level in range(1, 25):
        want = 0
        for j in owners:
            b = level if m.parts[j].placement_of is None else resident_level(level, shifts)
            cl = buffer_clusters(c, j, 0)
            assert cl is not None  # forced: every buffer clustered
            want += clustered_bytes(cl, b)
            assert clustered_gpu_buffer(c, j, 0, b).words.size * 4 + 16 * cl.n_clusters + 128 == clustered_bytes(cl, b)
        assert m.cap_bytes(level) == want
        assert m.cap_bytes(level) < m.cap_bytes_all_copies(level)
    from lopcook.lop.summary import cluster_stats, memory_rows

    # inspect's rows: the unclustered comparison is the unclustered instanced cook's CAP bytes
    for r, ru in zip(memory_rows(c), memory_rows(u)):
        assert r["unclustered_cap_bytes"] == ru["cap_bytes"] and r["cap_bytes_all_copies"] > r["cap_bytes"]
        assert r["cap_bytes"] == m.cap_bytes(r["level"])

    cs = cluster_stats(c)
    assert cs["buffers"] == len(owners)  # placements' entries are not counted again
    assert cs["clusters"] == sum(buffer_clusters(c, j, 0).n_clusters for j in owners)


def test_default_instances_cook_chooses_per_buffer_and_is_deterministic(cooked):
    """Without --cluster-all each distinct buffer is clustered exactly where clustering makes it
    smaller (levels 6-12); the bytes are the same on a second cook."""
    scene, c, _, d = cooked
    for j in {owner(c, i) for i in range(len(scene.parts))}:
        e = c.manifest["parts"][j]["lods"][0]
        assert ("cluster_size" in d.manifest["parts"][j]["lods"][0]) == clustering_wins(buffer_clusters(c, j, 0),
                                                                                       e["vertex_id"])
    assert run(scene, DEFAULT_INSTANCES).data == d.data
    assert from_bytes(d.data).manifest == d.manifest


def test_verify_decoders_on_clustered_placements(gl, cooked, tmp_path, capsys):
    """``verify --decoders`` of the clustered instanced container: the shared buffer once, on its
    mesh grid, with the LOP_CLUSTERED decoder and kernels, 0 mismatches at every level."""
    import json


    from lopcook.cli import main
    from lopcook.verify import gpu

    _, c, _, _ = cooked
    path = tmp_path / "inst.lop"
    path.write_bytes(c.data)
    languages = "glsl,hlsl" if gpu.hlsl_tools_available() else "glsl"
    assert main(["verify", str(path), "--decoders", "--languages", languages, "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)["decoders"]
    assert rep["ok"] is True and rep["buffers"] == rep["clustered_buffers"] == 3  # sphere group, touching, plate
    assert rep["levels"] == list(range(1, 25))
    for s in rep["languages"].values():
        assert s["decoded_vertices"] == s["clustered_decoded_vertices"] == 24 * rep["vertices"]
        assert s["grid_mismatches"] == s["float_mismatches"] == s["level_mismatches"] == 0
        assert s["crack_free_mismatches"] == s["adapt_mismatches"] == 0
    assert rep["clustered_cpu"]["mismatches"] == 0


def test_render_harness_draws_clustered_placements_like_unclustered(gl, cooked):
    """The harness draws each placement of the clustered shared buffer with the LOP_CLUSTERED
    decoder and its transform: PSNR rows and images equal, pixel for pixel, those of the same
    scene cooked with --instances unclustered."""
    from lopcook.lop.reader import ClusteredGpuBuffer, GpuBuffer
    from lopcook.verify.buffers import cap_buffer
    from lopcook.verify.evaluate import evaluate

    scene, c, u, _ = cooked
    placed = next(i for i, p in enumerate(c.manifest["parts"]) if "placement" in p and p["placement"]["of"] != i)
    assert isinstance(cap_buffer(c, placed, 0, 8), ClusteredGpuBuffer) and isinstance(cap_buffer(u, placed, 0, 8), GpuBuffer)
    kw = {"levels": [8, 14], "views": 2, "resolution": (160, 120), "keep_images": True, "image_view": 0}
    rc, ru = evaluate(c, scene, **kw), evaluate(u, scene, **kw)
    assert [(r["level"], r["cap"]["psnr_mean"], r["ap"]["psnr_mean"]) for r in rc["levels"]] == \
        [(r["level"], r["cap"]["psnr_mean"], r["ap"]["psnr_mean"]) for r in ru["levels"]]
    for v in ("cap", "ap", "cap_ids"):
        np.testing.assert_array_equal(rc["images"][v], ru["images"][v])


def _relabel(data: bytes, major: int, minor: int) -> bytes:
    import struct
    import zlib

    head = bytearray(data[:32])
    head[4:8] = struct.pack("<HH", major, minor)
    head[28:32] = struct.pack("<I", zlib.crc32(bytes(head[:28])))
    return bytes(head) + data[32:]


def test_version_rule_clusters_or_placements_make_3_0(cooked):
    """3.0 = may hold clusters and/or placements: a 3.0 label on a file with neither is read;
    placements under 2.1 (an earlier lopcook's label) are read, under 2.0 refused; clusters under
    any 2.x are refused; an unknown major is refused."""
    import struct

    from lopcook.errors import LopcookError
    from lopcook.pipeline import run as cook

    scene, c, u, _ = cooked
    plain = cook(procedural_scene(), Settings(simplify=SimplifySettings(instances=False),
                                              emit=EmitSettings(clusters=None))).data
    assert struct.unpack_from("<HH", plain, 4) == (2, 0)
    assert from_bytes(_relabel(plain, 3, 0)).manifest == from_bytes(plain).manifest
    assert from_bytes(_relabel(u.data, 2, 1)).manifest == u.manifest
    for data, major, minor, words in ((u.data, 2, 0, "must not hold placements"),
                                      (c.data, 2, 1, "must not hold clustered"),
                                      (c.data, max(READABLE_MAJORS) + 1, 0, "is not supported")):
        with pytest.raises(LopcookError, match=words):
            from_bytes(_relabel(data, major, minor))
