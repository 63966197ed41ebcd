"""Clustered position buffers (lopcook.lop.clusters, cook --clusters N): the decode at every level
equals the unclustered (global grid) decode exactly, pack/decode and add/remove plane round-trip,
the prefix property holds, co-located vertices decode identically, clusters collapse to their
anchor's cell at B <= k, and bad --clusters values are usage errors."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from conftest import FIXTURES, REPO
from lopcook.cli import main as cli_main
from lopcook.lop import bitplane as bp
from lopcook.lop import clusters as C
from lopcook.lop.binning import LEVELS, make_bins, table_bit_id, vertex_widths
from lopcook.lop.container import from_bytes
from lopcook.lop.reader import clustered_gpu_buffer, decode_positions, top_values
from lopcook.errors import LopcookError

SIZES = [16, 64, 1024]


def random_mesh(rng, n=3000, spread=1 << 24, levels=(1, 24)):
    """Random grid integers in a box of ``spread`` cells and random minimum levels."""
    base = rng.integers(0, (1 << 24) - spread + 1, 3)
    q = (base + rng.integers(0, spread, (n, 3))).astype(np.uint32)
    return q, rng.integers(levels[0], levels[1] + 1, n)


def surface_mesh(rng, n=4000):
    """Corpus-like: points on a sphere of radius 0.4 grid extents (a closed surface), levels
    clustered around 10-14 as the analysis gives, a few at 1."""
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    q = np.clip((0.5 + 0.4 * v) * (1 << 24), 0, (1 << 24) - 1).astype(np.uint32)
    lv = np.clip(np.round(rng.normal(12, 2, n)), 1, 24).astype(np.int64)
    lv[rng.random(n) < 0.05] = 1
    return q, lv


def clustered(q, lv, size):
    bins = C.cluster_order(q, lv)
    qb = q[bins.order]
    return bins, qb, C.make_clusters(qb, bins.vertex_id, size)


MESHES = {"random": lambda rng: random_mesh(rng), "tight": lambda rng: random_mesh(rng, spread=1 << 9),
          "surface": surface_mesh, "one_level": lambda rng: random_mesh(rng, levels=(7, 7))}


@pytest.mark.parametrize("mesh", sorted(MESHES))
@pytest.mark.parametrize("size", SIZES)
def test_decode_equals_global_grid_at_every_level(mesh, size):
    rng = np.random.default_rng(hash((mesh, size)) % 2**32)
    q, lv = MESHES[mesh](rng)
    bins, qb, cl = clustered(q, lv, size)
    vid = bins.vertex_id
    for level in range(1, LEVELS + 1):
        widths = vertex_widths(vid, level)
        values = bp.top_bits(qb, widths)
        words = C.pack_clustered(values, cl, level)
        assert words.size == C.words_at(cl, level)
        got, got_w = C.decode_clustered(words, cl, level)
        ref, ref_w = bp.decode(bp.pack(values, vid, level), vid, table_bit_id(vid, level), level)
        np.testing.assert_array_equal(got_w, ref_w)
        np.testing.assert_array_equal(bp.to_grid(got, got_w), bp.to_grid(ref, ref_w))
        np.testing.assert_array_equal(got_w, np.maximum(bins.levels, level))
        np.testing.assert_array_equal(got.astype(np.int64), qb.astype(np.int64) >> (LEVELS - got_w[:, None]))
        pick = rng.integers(0, qb.shape[0], 50)  # random access to single vertices
        sub, sub_w = C.decode_clustered(words, cl, level, pick)
        np.testing.assert_array_equal(sub, got[pick])
        np.testing.assert_array_equal(sub_w, got_w[pick])


def test_clusters_follow_the_contract(rng):
    q, lv = surface_mesh(rng, 2000)
    bins, qb, cl = clustered(q, lv, 64)
    vid, cid = bins.vertex_id, cl.cluster_id
    counts = np.diff(vid, prepend=0)
    assert cid[0] == 0 and np.array_equal(np.diff(cid, prepend=0)[1:], -(-counts[1:] // 64))
    _, c, l = C.vertex_clusters(cl)
    assert np.all(cl.m[c] == bins.levels)  # a cluster never spans two bins
    assert np.all(l < cl.count[c]) and cl.count.sum() == qb.shape[0] and np.all(cl.count <= 64)
    for i in rng.integers(0, cl.n_clusters, 20):  # k: the longest common prefix, a: that prefix
        block = qb[cl.start[i]:cl.start[i] + cl.count[i]].astype(np.int64)
        for t in range(3):
            k = int(cl.k[i, t])
            assert np.all(block[:, t] >> (24 - k) == int(cl.anchor[i, t]))
            if k < 24:
                assert len(np.unique(block[:, t] >> (24 - k - 1))) > 1
    # Morton order inside a bin, index order among equal codes
    codes = C.morton_codes(qb)
    same_bin = bins.levels[1:] == bins.levels[:-1]
    assert np.all(codes[1:][same_bin] >= codes[:-1][same_bin])
    # records: anchors and k in words 0-2, ClusterBit in word 3
    rec = C.records(cl, 9)
    np.testing.assert_array_equal(rec[:, 3], C.cluster_bit(cl, 9)[:-1])
    np.testing.assert_array_equal(rec[:, :3] >> 24, cl.k)
    np.testing.assert_array_equal(rec[:, :3] & 0xFFFFFF, cl.anchor)
    back = C.from_header(cl.header_words(), vid, 64)
    assert np.array_equal(back.k, cl.k) and np.array_equal(back.anchor, cl.anchor)
    assert C.clustered_bytes(cl, 9) == 4 * C.words_at(cl, 9) + 16 * cl.n_clusters + 128


@pytest.mark.parametrize("mesh", ["random", "surface", "one_level"])
def test_packing_in_blocks_gives_the_words_of_one_pass(mesh, monkeypatch):
    # blocks that cut clusters, bins and words anywhere (1, 7 and 1000 vertices) against one block
    # over every vertex; the values' bins and clusters span the block boundaries
    rng = np.random.default_rng(7)
    q, lv = MESHES[mesh](rng)
    bins, qb, cl = clustered(q, lv, 64)
    for level in (1, 9, 17, 24):
        values = bp.top_bits(qb, vertex_widths(bins.vertex_id, level))
        monkeypatch.setattr(C, "PACK_BLOCK", qb.shape[0] + 1)
        whole = C.pack_clustered(values, cl, level)
        for block in (1, 7, 1000):
            monkeypatch.setattr(C, "PACK_BLOCK", block)
            np.testing.assert_array_equal(C.pack_clustered(values, cl, level), whole)
        bad = values.copy()
        bad[-1, 0] |= np.uint32(1 << 24)  # wider than any field, in the last block only
        monkeypatch.setattr(C, "PACK_BLOCK", 1000)
        with pytest.raises(ValueError, match="exceed"):
            C.pack_clustered(bad, cl, level)


def test_morton_code_interleaves_x_lowest():
    q = np.array([[1 << 3, 0, 0], [0, 1 << 3, 0], [0, 0, 1 << 3], [(1 << 24) - 1] * 3], np.uint32)
    np.testing.assert_array_equal(C.morton_codes(q), np.array([1, 2, 4, (1 << 63) - 1], np.uint64))


@pytest.mark.parametrize("size", [16, 256])
def test_add_and_remove_plane_equal_packing_from_scratch(size):
    rng = np.random.default_rng(size)
    q, lv = surface_mesh(rng, 3000)
    _, qb, cl = clustered(q, lv, size)
    vid = cl.vertex_id
    words = C.pack_clustered(bp.top_bits(qb, vertex_widths(vid, 1)), cl, 1)
    for level in range(1, LEVELS):
        words = C.add_plane_clustered(words, cl, level, C.plane_bits_clustered(qb, cl, level + 1))
        np.testing.assert_array_equal(words, C.pack_clustered(bp.top_bits(qb, vertex_widths(vid, level + 1)), cl,
                                                              level + 1))
    for level in range(LEVELS, 1, -1):
        words = C.remove_plane_clustered(words, cl, level)
        np.testing.assert_array_equal(words, C.pack_clustered(bp.top_bits(qb, vertex_widths(vid, level - 1)), cl,
                                                              level - 1))


def test_planes_skip_exactly_the_anchor_implied_bits(rng):
    q, lv = random_mesh(rng, 2000, spread=1 << 12)
    _, qb, cl = clustered(q, lv, 32)
    for p in range(2, LEVELS + 1):
        stream = C.plane_bits_clustered(qb, cl, p)
        pb = C.plane_bit(cl, p)
        assert stream.size == pb[-1]
        g = int(cl.vertex_id[p - 1])
        implied = int((cl.count[:, None] * (cl.k >= p))[cl.m < p].sum())
        assert stream.size == 3 * g - implied


def test_pack_refuses_values_that_disagree_with_the_anchor(rng):
    q, lv = random_mesh(rng, 200, spread=1 << 10)
    _, qb, cl = clustered(q, lv, 16)
    values = bp.top_bits(qb, vertex_widths(cl.vertex_id, 24))
    bad = values.copy()
    bad[0, 0] ^= np.uint32(1 << 23)  # a top bit the cluster's anchor holds
    with pytest.raises(ValueError, match="anchor"):
        C.pack_clustered(bad, cl, 24)
    with pytest.raises(ValueError, match="cluster size"):
        C.make_clusters(qb, cl.vertex_id, 15)


def test_a_cluster_at_b_at_most_k_collapses_to_its_anchors_cell():
    rng = np.random.default_rng(7)
    base = rng.integers(0, 1 << 18, 3) << 6  # every point in one aligned box of 64 cells: k >= 18
    q = (base + rng.integers(0, 64, (500, 3))).astype(np.uint32)
    lv = rng.integers(1, 5, 500)
    _, qb, cl = clustered(q, lv, 64)
    assert cl.k.min() >= 18
    for level in range(1, 19):
        got, w = C.decode_clustered(C.pack_clustered(bp.top_bits(qb, vertex_widths(cl.vertex_id, level)), cl, level),
                                    cl, level)
        _, c, _ = C.vertex_clusters(cl)
        b = w[:, None]
        small = np.all(b <= cl.k[c], axis=1)  # every vertex of such a cluster: the anchor's cell at b bits
        assert small.any()
        want = cl.anchor[c].astype(np.int64) >> (cl.k[c].astype(np.int64) - b)
        np.testing.assert_array_equal(got[small].astype(np.int64), want[small])
        if level <= cl.k.min():  # AP at a level B <= k: stride 0, P holds no bits at all
            assert C.cluster_bit(cl, level)[-1] == 0 and C.words_at(cl, level) == 1


# ---- cooked containers ----------------------------------------------------------------------------

def cook(path, *flags, tmp_path, name="out.lop"):
    """Cook with the CLI; an explicit ``--clusters N`` (N > 0) clusters every buffer (``--cluster-all``):
    the small fixtures would otherwise be written unclustered by the per-buffer choice."""
    out = tmp_path / name
    if "--clusters" in flags and flags[list(flags).index("--clusters") + 1] != "0":
        flags = (*flags, "--cluster-all")
    assert cli_main(["cook", str(path), "-o", str(out), "-q", *flags]) == 0
    return out


@pytest.mark.parametrize("fixture", ["two_plates.glb", "unit_sphere.glb", "seamed_cube.glb"])
def test_cooked_clustered_decodes_like_unclustered(fixture, tmp_path):
    plain = from_bytes((cook(FIXTURES / fixture, "--clusters", "0", tmp_path=tmp_path, name="a.lop")).read_bytes())
    clus = from_bytes((cook(FIXTURES / fixture, "--clusters", "16", tmp_path=tmp_path, name="b.lop")).read_bytes())
    data = (tmp_path / "b.lop").read_bytes()
    assert struct.unpack_from("<HH", data, 4) == (3, 0) and struct.unpack_from("<HH", (tmp_path / "a.lop").read_bytes(),
                                                                               4) == (2, 0)
    assert clus.manifest["options"]["clusters"] == 16
    for i, part in enumerate(plain.manifest["parts"]):
        assert clus.manifest["parts"][i]["lods"][0]["cluster_size"] == 16
        for level in (1, 5, 12, 24):
            ga, wa, pa = decode_positions(plain, i, 0, level)
            gb, wb, pb = decode_positions(clus, i, 0, level)
            ka, kb = np.lexsort(np.c_[ga, wa].T), np.lexsort(np.c_[gb, wb].T)  # same vertices, other order
            np.testing.assert_array_equal(ga[ka], gb[kb])
            np.testing.assert_array_equal(pa[ka].view(np.uint32), pb[kb].view(np.uint32))
            buf = clustered_gpu_buffer(clus, i, 0, level)
            assert buf.words.size == clus.manifest["parts"][i]["lods"][0]["cluster_p_words"][level - 1]
        assert clus.entries.parts[i].lods[0].cap_bytes(12) == (
            4 * C.words_at(buf.clusters, 12) + 16 * buf.clusters.n_clusters + 128)
        assert clus.entries.parts[i].lods[0].unclustered_cap_bytes(12) == plain.entries.parts[i].lods[0].cap_bytes(12)


def test_prefix_of_a_clustered_file_decodes_at_the_available_level(tmp_path):
    path = cook(FIXTURES / "unit_sphere.glb", "--clusters", "32", tmp_path=tmp_path)
    data = path.read_bytes()
    full = from_bytes(data)
    msize = struct.unpack_from("<I", data, 12)[0]
    table = {s["name"]: s for s in full.manifest["sections"]}
    def end_of(level):
        s = table["positions/mandatory" if level == 1 else f"positions/plane{level:02d}"]
        return 32 + msize + s["offset"] + s["length"]

    cuts = sorted({end_of(level) for level in range(1, LEVELS)})
    assert len(cuts) > 5
    for end in cuts:
        prefix = from_bytes(data[:end], allow_prefix=True)
        level = max(b for b in range(1, LEVELS + 1) if end_of(b) <= end)  # empty planes come for free
        assert prefix.available_level == level
        g1, w1, p1 = decode_positions(prefix, 0, 0, level)
        g2, w2, p2 = decode_positions(full, 0, 0, level)
        np.testing.assert_array_equal(g1, g2)
        np.testing.assert_array_equal(p1.view(np.uint32), p2.view(np.uint32))
        with pytest.raises(LopcookError, match="not in this file"):
            decode_positions(prefix, 0, 0, level + 1)
    # cut inside the cluster headers: no level decodes
    start = 32 + msize + table["positions/clusters"]["offset"]
    with pytest.raises(LopcookError):
        from_bytes(data[:start + 4], allow_prefix=True)


def test_co_located_vertices_decode_identically_across_lods_and_clusters(tmp_path):
    """seamed_cube: 24 vertices at 8 positions in 2 clusters of 16; unit_sphere: 3 LODs sharing 63
    positions (co-located parts are the pipeline's shared grid, the same rule)."""
    from lopcook.lop.container import read

    for fixture, flags in (("seamed_cube.glb", ()), ("unit_sphere.glb", ("--lods", "1/2,1/4"))):
        c = read(str(cook(FIXTURES / fixture, "--clusters", "16", *flags, tmp_path=tmp_path, name=f"{fixture}.lop")))
        bufs = [(i, k) for i, p in enumerate(c.manifest["parts"]) for k in range(len(p["lods"]))]
        assert sum(C.vertex_clusters(clustered_gpu_buffer(c, *b, 1).clusters)[1].max() + 1 for b in bufs) > 1
        q24 = {b: bp.to_grid(*top_values(c, *b, 24)) for b in bufs}
        for level in (3, 8, 14, 24):
            seen: dict = {}
            shared = 0
            for b in bufs:
                g, w, pos = decode_positions(c, *b, level)
                for key, got in zip(map(bytes, q24[b]), zip(map(bytes, pos), w.tolist())):
                    if key in seen:
                        shared += 1
                        assert seen[key] == got  # same float32 bits and bits per component
                    seen[key] = got
            assert shared > 0


def test_corrupt_cluster_headers_and_old_versions_are_refused(tmp_path):
    path = cook(FIXTURES / "two_plates.glb", "--clusters", "16", tmp_path=tmp_path)
    data = bytearray(path.read_bytes())
    c = from_bytes(bytes(data))
    msize = struct.unpack_from("<I", data, 12)[0]
    sec = next(s for s in c.manifest["sections"] if s["name"] == "positions/clusters")
    at = 32 + msize + sec["offset"]
    bad = bytearray(data)
    bad[at + 3] = 25  # k_x = 25 > 24
    # keep the section CRC right: the check must be semantic
    import json

    m = json.loads(bytes(data[32:32 + msize]))
    for s in m["sections"]:
        if s["name"] == "positions/clusters":
            s["crc32"] = zlib.crc32(bytes(bad[at:at + sec["length"]]))
    mb = json.dumps(m, sort_keys=True, separators=(",", ":")).encode()
    assert len(mb) == msize
    bad[32:32 + msize] = mb
    bad[16:20] = struct.pack("<I", zlib.crc32(mb))
    bad[28:32] = struct.pack("<I", zlib.crc32(bytes(bad[:28])))
    with pytest.raises(LopcookError, match="cluster"):
        from_bytes(bytes(bad))
    old = bytearray(data)  # the same file labelled 2.0: a 2.x reader must not take it
    old[4:6] = struct.pack("<H", 2)
    old[28:32] = struct.pack("<I", zlib.crc32(bytes(old[:28])))
    with pytest.raises(LopcookError, match="must not hold clustered"):
        from_bytes(bytes(old))


def test_clustered_manifest_matches_the_schema(tmp_path):
    import json

    from jsonschema import Draft202012Validator

    schema = json.loads((REPO / "schema" / "container.schema.json").read_text())
    c = from_bytes(cook(FIXTURES / "seamed_cube.glb", "--clusters", "64", tmp_path=tmp_path).read_bytes())
    Draft202012Validator(schema).validate(c.manifest)
    broken = json.loads(json.dumps(c.manifest))
    del broken["parts"][0]["lods"][0]["cluster_words"]
    assert list(Draft202012Validator(schema).iter_errors(broken))


@pytest.mark.parametrize("value", ["8", "15", "1025", "abc", "64.5", "-64"])
def test_bad_clusters_value_is_a_usage_error(value, tmp_path, capsys):
    out = tmp_path / "x.lop"
    assert cli_main(["cook", str(FIXTURES / "seamed_cube.glb"), "-o", str(out), "--clusters", value]) == 2
    err = capsys.readouterr().err
    assert "--clusters" in err and "[16, 1024]" in err and "Traceback" not in err
    assert not out.exists()


def test_inspect_json_counts_records_and_shows_the_k_histogram(tmp_path, capsys):
    import json

    path = cook(FIXTURES / "unit_sphere.glb", "--clusters", "32", tmp_path=tmp_path)
    capsys.readouterr()
    assert cli_main(["inspect", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    cs = d["clusters"]
    c = from_bytes(path.read_bytes())
    n_c = sum(e.n_clusters for p in c.entries.parts for e in p.lods)
    assert cs["clusters"] == n_c and sum(cs["k_histogram"]) == 3 * n_c and cs["record_bytes"] == 16 * n_c
    for r in d["memory"]:
        cl = clustered_gpu_buffer(c, 0, 0, r["level"]).clusters
        assert r["cap_bytes"] == C.clustered_bytes(cl, r["level"])
        assert r["unclustered_cap_bytes"] == 4 * ((3 * sum(max(k, r["level"]) * int(n) for k, n in
                                                          enumerate(np.diff(cl.vertex_id, prepend=0)) if k) + 31) // 32)


@pytest.mark.parametrize("name", ["fandisk.obj", "CesiumMilkTruck.glb"])
def test_corpus_asset_clustered_equals_unclustered_at_every_level(corpus, name):
    from lopcook.analyse import analyse
    from lopcook.emit import build
    from lopcook.ingest import load

    scene = load(str(corpus / name))
    an = analyse(scene)
    plain, clus = from_bytes(build(scene, an)), from_bytes(build(scene, an, cluster_size=64, cluster_all=True))
    for i, (part, pa) in enumerate(zip(scene.parts, an.parts)):
        bins = C.cluster_order(pa.quantized, pa.min_level)
        ref = make_bins(pa.min_level)
        for level in range(1, LEVELS + 1):
            g, w, pos = decode_positions(clus, i, 0, level)
            np.testing.assert_array_equal(w, np.maximum(bins.levels, level))
            np.testing.assert_array_equal(g.astype(np.int64), (pa.quantized[bins.order].astype(np.int64)
                                                               >> (24 - w[:, None])) << (24 - w[:, None]))
            g0, w0, pos0 = decode_positions(plain, i, 0, level)  # the same vertex, read from both files
            np.testing.assert_array_equal(pos[bins.inverse].view(np.uint32), pos0[ref.inverse].view(np.uint32))


def test_default_cook_is_clustered_and_clusters_0_is_not(tmp_path):
    """The default cook uses clusters of DEFAULTS.emit.clusters (64) vertices where they make a
    buffer smaller (``clustering_wins``); forced with --cluster-all every buffer is clustered,
    version 3.0, and records it; --clusters 0 writes the unclustered 2.0 file, which reads back
    as unclustered settings; all decode to the same grid integers and float32 positions."""
    from lopcook.emit import clustering_wins
    from lopcook.lop.reader import buffer_clusters
    from lopcook.settings import DEFAULTS, Settings

    assert DEFAULTS.emit.clusters == 64
    a = cook(FIXTURES / "unit_sphere.glb", tmp_path=tmp_path, name="a.lop")
    d = cook(FIXTURES / "unit_sphere.glb", "--clusters", "64", tmp_path=tmp_path, name="d.lop")
    u = cook(FIXTURES / "unit_sphere.glb", "--clusters", "0", tmp_path=tmp_path, name="u.lop")
    assert struct.unpack_from("<HH", d.read_bytes(), 4) == (3, 0) and struct.unpack_from("<HH", u.read_bytes(), 4) == (2, 0)
    cd, cu, ca = from_bytes(d.read_bytes()), from_bytes(u.read_bytes()), from_bytes(a.read_bytes())
    assert cd.manifest["options"]["clusters"] == 64 and "clusters" not in cu.manifest["options"]
    assert cd.manifest["options"]["cluster_all"] is True and "cluster_all" not in ca.manifest["options"]
    assert all(e["cluster_size"] == 64 for p in cd.manifest["parts"] for e in p["lods"])
    assert not any("cluster_size" in e for p in cu.manifest["parts"] for e in p["lods"])
    # the default: clustered exactly where the forced clustering wins, the same vertices otherwise
    for i, p in enumerate(cd.manifest["parts"]):
        for k, e in enumerate(p["lods"]):
            wins = clustering_wins(buffer_clusters(cd, i, k), e["vertex_id"])
            assert ("cluster_size" in ca.manifest["parts"][i]["lods"][k]) == wins
    assert struct.unpack_from("<HH", a.read_bytes(), 4) == ((3, 0) if ca.entries.clustered else (2, 0))
    assert Settings.from_manifest(cd.manifest).emit == DEFAULTS.emit.__class__(clusters=64, cluster_all=True)
    assert Settings.from_manifest(ca.manifest).emit == DEFAULTS.emit
    assert Settings.from_manifest(cu.manifest).emit.clusters is None
    for level in (1, 9, 24):
        ga, wa, pa = decode_positions(cd, 0, 0, level)
        gb, wb, pb = decode_positions(cu, 0, 0, level)
        ka, kb = np.lexsort(np.c_[ga, wa].T), np.lexsort(np.c_[gb, wb].T)
        np.testing.assert_array_equal(ga[ka], gb[kb])
        np.testing.assert_array_equal(pa[ka].view(np.uint32), pb[kb].view(np.uint32))


def test_report_section_shows_clustered_against_unclustered_and_the_k_histogram(tmp_path):
    from lopcook.lop.summary import describe_container
    from lopcook.report.sections import clusters_html

    c = from_bytes(cook(FIXTURES / "unit_sphere.glb", "--clusters", "16", tmp_path=tmp_path).read_bytes())
    d = describe_container(c)
    html = "".join(clusters_html({"clusters": d["clusters"], "memory": d["memory"], "available_level": 24}))
    r12 = next(r for r in d["memory"] if r["level"] == 12)
    assert "<h2>Clusters</h2>" in html and f"<td>{r12['cap_bytes']:,}</td>" in html
    assert f"<td>{r12['unclustered_cap_bytes']:,}</td>" in html
    assert " ".join(f"{k}:{v}" for k, v in enumerate(d["clusters"]["k_histogram"]) if v) in html
    plain = from_bytes(cook(FIXTURES / "unit_sphere.glb", "--clusters", "0", tmp_path=tmp_path, name="p.lop").read_bytes())
    assert describe_container(plain)["clusters"] is None and clusters_html({"clusters": None}) == []


def test_clusters_with_hierarchy_lods_and_dropped_planes(tmp_path):
    """--hierarchy sections go before positions/clusters; with --nearest the planes no view needs
    are dropped and the savings record still balances; every LOD is clustered."""
    path = cook(FIXTURES / "unit_sphere.glb", "--clusters", "16", "--hierarchy", "--lods", "1/2", "--nearest", "2",
                tmp_path=tmp_path)
    c = from_bytes(path.read_bytes())
    names = [s["name"] for s in c.manifest["sections"]]
    at = names.index("positions/clusters")
    assert names[at + 1] == "positions/mandatory" and all(not n.startswith("positions/") for n in names[:at])
    assert "part0/lod0/hierarchy" in names[:at]
    assert c.manifest["positions"]["max_level"] < 24 and c.manifest["savings"]["bytes_saved"] > 0
    lods = c.manifest["parts"][0]["lods"]
    assert len(lods) == 2 and all(e["cluster_size"] == 16 for e in lods)
    plain = from_bytes(cook(FIXTURES / "unit_sphere.glb", "--hierarchy", "--lods", "1/2", "--nearest", "2",
                            tmp_path=tmp_path, name="plain.lop").read_bytes())
    assert plain.available_level == c.available_level
    for k in range(2):  # the same vertices decode the same (in another order)
        g, w, pos = decode_positions(c, 0, k, c.available_level)
        g0, w0, pos0 = decode_positions(plain, 0, k, c.available_level)
        a, b = np.lexsort(np.c_[g, w].T), np.lexsort(np.c_[g0, w0].T)
        np.testing.assert_array_equal(pos[a].view(np.uint32), pos0[b].view(np.uint32))


@pytest.mark.parametrize("mesh", sorted(MESHES))
def test_position_sizer_equals_the_encoded_buffers_bytes(mesh, rng):
    """``PositionSizer.bytes_at(B)`` (the byte-budget fit's candidate size) is the ``cap_bytes(B)``
    the manifest gives the buffer ``encode_buffer(buf, B, N)`` writes: every vertex clamped to B,
    the per-buffer clustered/unclustered choice included, for N = None, 16, 64 and cluster_all."""
    from lopcook.emit import BufferInput, PositionSizer, encode_buffer
    from lopcook.lop.manifest import Manifest

    q, lv = MESHES[mesh](rng)
    buf = BufferInput(quantized=q, min_level=lv, indices=np.zeros((0, 3), np.int64))
    chosen = set()
    for size, every in ((None, False), (16, False), (64, False), (64, True)):
        sizer = PositionSizer(buf, size, cluster_all=every)
        for b in (1, 3, 6, 9, 12, 16, 20, 24):
            e = encode_buffer(buf, b, size, cluster_all=every)
            entry = Manifest.of({"parts": [{"name": "p", "lods": [e.entry]}], "positions": {"max_level": b}}).parts[0].lods[0]
            assert sizer.bytes_at(b) == entry.cap_bytes(b), (size, every, b)
            chosen.add(e.clusters is not None)
            if size is None:
                assert sizer.bytes_at(b) == entry.ap_bytes(b)  # unclustered: AP at B
    assert True in chosen  # the clustered layout was exercised
