"""Clustered position buffers (issue 16) on the GPU: the GLSL and HLSL vertex decoders and
adaption kernels with ``LOP_CLUSTERED`` against the CPU reference of the layout contract
(lopcook.lop.clusters), bit for bit.

The vertex path runs through transform feedback (lopcook.verify.gpu.decode_clustered), the kernels
through SSBOs (lopcook.verify.gpu.ClusteredAdapter). Every decode must equal the unclustered (global
grid) decode at max(B, m_v) bits exactly; every level change must give the bytes of packing the new
level from scratch. Tests skip when EGL, glslangValidator or spirv-cross is missing, except under
CI=true, where they fail.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import require

from lopcook.lop.binning import LEVELS
from lopcook.lop.bitplane import reconstruct_float32, to_grid, top_bits
from lopcook.lop.clusters import (
    CLUSTER_ID_BYTES,
    add_plane_clustered,
    cluster_bit,
    cluster_order,
    clustered_bytes,
    decode_clustered,
    make_clusters,
    pack_clustered,
    plane_bit,
    plane_bits_clustered,
    records,
    remove_plane_clustered,
    vertex_clusters,
)
from lopcook.verify import gpu
from lopcook.verify.decoders import (
    decode_crack_free,
    verify_clustered_adapt,
    verify_clustered_decode,
    view_tables,
)
from lopcook.viewing import Viewing

SIZES = (16, 37, 64, 256)
SEQUENCE = (6, 12, 8, 24, 1, 10)
ORIGIN, CELL = (1000.3, -52.7, 3.1e-3), 0.37 / 2**24


@pytest.fixture(params=gpu.LANGUAGES)
def language(request, gl):
    if request.param == "hlsl":
        require(gpu.hlsl_tools_available())
    return request.param


def random_data(rng, n=2500):
    """Every bin populated, random grid integers over the whole range (k mostly small)."""
    levels = np.concatenate([np.arange(1, 25), rng.integers(1, 25, n - 24)])
    q = rng.integers(0, 2**24, (n, 3)).astype(np.uint32)
    q[:3] = [[0, 0, 0], [2**24 - 1] * 3, [2**23, 2**23 - 1, 2**23 + 1]]
    return q, levels


def analytic_data(rng, size):
    """Spatially coherent points (a quantised sphere shell: large k) plus crafted bins: bin 3 holds
    2N + 1 copies of one point (k = 24, the last cluster a single vertex), bin 5 spans the whole grid
    in x (k_x = 0), bin 10 a single vertex, bin 17 exactly N vertices, bins 2, 4, 6-9, 11-16, 18-23
    empty, bin 24 the sphere."""
    u = rng.normal(size=(1500, 3))
    sphere = (u / np.linalg.norm(u, axis=1, keepdims=True) * 0.45 + 0.5) * (2**24 - 1)
    parts = [(np.full((2 * size + 1, 3), [12345, 2**23 + 7, 2**24 - 1]), 3),
             (np.column_stack([np.linspace(0, 2**24 - 1, 40), np.full(40, 5), np.arange(40) * 3]), 5),
             (np.array([[7, 8, 9]]), 10),
             (sphere[:size], 17),
             (sphere, 24)]
    q = np.concatenate([p for p, _ in parts]).astype(np.uint32)
    levels = np.concatenate([np.full(len(p), m) for p, m in parts])
    return q, levels


def prepared(q, levels, size):
    bins = cluster_order(q, levels)
    qb = q[bins.order]
    return qb, bins, make_clusters(qb, bins.vertex_id, size)


def datasets(rng):
    for size in SIZES:
        yield f"random N={size}", prepared(*random_data(rng), size)
        yield f"analytic N={size}", prepared(*analytic_data(rng, size), size)


def reference_decode(qb, clusters, level):
    widths = np.maximum(np.repeat(np.arange(1, LEVELS + 1), np.diff(clusters.vertex_id)), level)
    return top_bits(qb, widths), widths


def gpu_decode(language, qb, clusters, level, view=None):
    words = pack_clustered(reference_decode(qb, clusters, level)[0], clusters, level)
    got = gpu.decode_clustered(language, words, records(clusters, level), clusters.cluster_id, clusters.vertex_id,
                               clusters.size, level, ORIGIN, np.float32(CELL / 2), view=view)
    return words, got


# ---- the reference itself (CPU only) --------------------------------------------------------------

def test_reference_layout_round_trips(rng):
    """lopcook.lop.clusters decodes what it packs to the global grid's top max(B, m) bits; the crafted data
    has the cluster kinds the tests rely on; a prefix of planes rebuilds every level."""
    qb, bins, cl = prepared(*analytic_data(rng, 16), 16)
    assert {24, 0} <= set(cl.k.ravel().tolist()) and 1 in cl.count.tolist()
    assert np.any(np.diff(cl.cluster_id) == 0)  # empty bins
    assert np.all(np.diff(bins.levels.astype(int)) >= 0)
    for size in (16, 37):
        qb, bins, cl = prepared(*random_data(rng, 600), size)
        words = pack_clustered(reference_decode(qb, cl, 1)[0], cl, 1)
        for level in range(1, LEVELS + 1):
            values, widths = reference_decode(qb, cl, level)
            scratch = pack_clustered(values, cl, level)
            np.testing.assert_array_equal(words, scratch)
            got, w = decode_clustered(scratch, cl, level)
            np.testing.assert_array_equal(got, values)
            np.testing.assert_array_equal(w, widths)
            assert clustered_bytes(cl, level) == 4 * len(scratch) + 16 * len(cl.count) + CLUSTER_ID_BYTES
            if level < LEVELS:
                words = add_plane_clustered(words, cl, level, plane_bits_clustered(qb, cl, level + 1))
        for level in range(LEVELS, 1, -1):
            words = remove_plane_clustered(words, cl, level)
            np.testing.assert_array_equal(words, pack_clustered(reference_decode(qb, cl, level - 1)[0], cl, level - 1))


# ---- vertex decoding ------------------------------------------------------------------------------

def test_vertex_decode_every_level(language, rng):
    """Every level 1..24, four cluster sizes, random and analytic data: grid integers, float32 bits and
    widths equal the reference and the unclustered decode at max(B, m_v) bits."""
    for name, (qb, bins, cl) in datasets(rng):
        for level in range(1, LEVELS + 1):
            words, got = gpu_decode(language, qb, cl, level)
            values, widths = reference_decode(qb, cl, level)
            ref_v, ref_w = decode_clustered(words, cl, level)
            np.testing.assert_array_equal(ref_v, values)
            np.testing.assert_array_equal(ref_w, widths)
            np.testing.assert_array_equal(got.grid, to_grid(values, widths), err_msg=f"grid {name} B={level}")
            ref = reconstruct_float32(values, widths, ORIGIN, CELL)
            np.testing.assert_array_equal(got.position.view(np.uint32), ref.view(np.uint32),
                                          err_msg=f"float bits {name} B={level}")
            np.testing.assert_array_equal(got.level, widths, err_msg=f"bits {name} B={level}")
            if level == LEVELS:
                np.testing.assert_array_equal(got.grid, qb)


def test_decode_reads_the_anchor(language, rng):
    """At a level at or below a cluster's k_t the stored field is empty: the component comes from the
    anchor alone. Zeroing P changes only the stored bits, so the anchor-implied components still
    decode right (and a wrong anchor would show)."""
    qb, _, cl = prepared(*analytic_data(rng, 16), 16)
    level = 4
    values, widths = reference_decode(qb, cl, level)
    words = pack_clustered(values, cl, level)
    got = gpu.decode_clustered(language, np.zeros_like(words), records(cl, level), cl.cluster_id, cl.vertex_id,
                               cl.size, level, ORIGIN, np.float32(CELL / 2))
    _, c, _ = vertex_clusters(cl, np.arange(len(qb)))
    implied = cl.k[c].astype(np.int64) >= widths[:, None]
    assert implied.sum() > 100 and not implied.all()
    np.testing.assert_array_equal(got.grid[implied], to_grid(values, widths)[implied])
    assert np.any(got.grid[~implied] != to_grid(values, widths)[~implied])


def test_empty_buffer_and_single_cluster(language):
    q = np.array([[5, 6, 7]], np.uint32)
    _, _, one = prepared(q, np.array([9]), 16)
    for level in (1, 9, 24):
        words, got = gpu_decode(language, q, one, level)
        assert len(words) == 1 and (level < LEVELS or words[0] == 0)  # all bits implied: one zero word
        np.testing.assert_array_equal(got.grid, to_grid(*reference_decode(q, one, level)))
    _, _, empty = prepared(np.zeros((0, 3), np.uint32), np.zeros(0, np.int64), 16)
    assert gpu_decode(language, np.zeros((0, 3), np.uint32), empty, 5)[1].grid.shape == (0, 3)


_DIV_GLSL = """
layout(std430, binding = 5) readonly buffer LopDivIn { uint lop_div_in[]; };
out uint lop_out_q;
void main()
{
    uint i = uint(gl_VertexID);
    lop_out_q = lop_div(lop_div_in[2u * i], lop_div_in[2u * i + 1u]);
}
"""

_DIV_HLSL = """
ByteAddressBuffer lop_div_in : register(t5);
struct LopDivOut { nointerpolation uint q : LOP_Q; };
LopDivOut lop_div_vs(uint i : SV_VertexID)
{
    LopDivOut o;
    o.q = lop_div(lop_div_in.Load((2u * i) << 2), lop_div_in.Load((2u * i + 1u) << 2));
    return o;
}
"""


def test_division_is_exact_over_the_contract_range(language, rng):
    """lop_div(r, n) == r // n for every cluster size n in [16, 1024] and r up to 2^26 - 1 (the
    decoder's vertex limit): multiples of n and their neighbours, random values, the largest r."""
    import moderngl

    n = np.arange(gpu.CLUSTER_SIZES[0], gpu.CLUSTER_SIZES[1] + 1, dtype=np.int64)
    top = 2**26 - 1
    r = [np.minimum(top, (top // n) * n + d) for d in (-1, 0, 1)]
    for q in rng.integers(0, top // 16, 12):
        r += [np.clip(q % (top // n) * n + d, 0, top) for d in (-1, 0, 1)]
    r += [rng.integers(0, top + 1, n.size), np.full(n.size, top), n - 1, n, np.zeros(n.size, np.int64)]
    pairs = np.stack(np.broadcast_arrays(np.stack(r), n[None, :]), axis=-1).reshape(-1, 2).astype("<u4")
    if language == "glsl":
        src = ("#version 450\n#define LOP_NO_VIEW\n#define LOP_CLUSTERED\n" + gpu.shader_source("decode_bitplanes.glsl")
               + _DIV_GLSL)
    else:
        src = gpu.hlsl_to_glsl(gpu.shader_source("decode_bitplanes.hlsl") + _DIV_HLSL, "vert", "lop_div_vs",
                               defines=("LOP_NO_VIEW", "LOP_CLUSTERED"), rename_outputs=("lop_out_q",))
    ctx = gpu.context()
    prog = ctx.program(vertex_shader=src, varyings=("lop_out_q",))
    vao = ctx.vertex_array(prog, [])
    data, out = ctx.buffer(pairs.tobytes()), ctx.buffer(reserve=4 * len(pairs))
    try:
        data.bind_to_storage_buffer(5)
        vao.transform(out, mode=moderngl.POINTS, vertices=len(pairs))
        got = np.frombuffer(out.read(), "<u4")
    finally:
        for x in (data, out, vao, prog):
            x.release()
    want = pairs[:, 0].astype(np.int64) // pairs[:, 1]
    bad = np.flatnonzero(got != want)
    assert bad.size == 0, f"{bad.size} wrong quotients, e.g. {pairs[bad[:3]].tolist()} -> {got[bad[:3]].tolist()}"


def test_crack_free_decode_equals_the_cpu_rule(language, rng):
    """The crack-free decode of a clustered buffer equals lopcook.verify.decoders.decode_crack_free on
    the reference's values, from near and far cameras."""
    extent = CELL * 2**24
    viewing = Viewing()
    level_dist, radius = view_tables(extent, viewing, ORIGIN)
    for name, (qb, bins, cl) in list(datasets(rng))[::3]:
        for trial in range(6):
            cam = np.asarray(ORIGIN) + extent * (0.5 + rng.uniform(-1, 1, 3) * 10.0 ** rng.uniform(-2, 2))
            level = int(rng.integers(1, 25))
            _, got = gpu_decode(language, qb, cl, level, view=(cam, level_dist, radius))
            values, widths = reference_decode(qb, cl, level)
            g, p, lv = decode_crack_free(values, widths, bins.levels, level, ORIGIN, CELL, cam, level_dist, radius)
            np.testing.assert_array_equal(got.grid, g, err_msg=name)
            np.testing.assert_array_equal(got.position.view(np.uint32), p.view(np.uint32), err_msg=name)
            np.testing.assert_array_equal(got.level, lv, err_msg=name)


def test_verify_clustered_decode_counts_mismatches(gl, rng):
    qb, _, cl = prepared(*random_data(rng, 500), 37)
    level = 7
    values, widths = reference_decode(qb, cl, level)
    words = pack_clustered(values, cl, level)
    args = (words, records(cl, level), cl.cluster_id, cl.vertex_id, cl.size, level, ORIGIN, CELL)
    ok = verify_clustered_decode(*args, values, widths, languages=("glsl",))
    assert ok["glsl"] == {"decoded_vertices": 500, "grid_mismatches": 0, "float_mismatches": 0, "level_mismatches": 0,
                          "max_float_ulp": 0}
    bad = values.copy()
    bad[10, 1] ^= 1
    got = verify_clustered_decode(*args, bad, widths, languages=("glsl",))["glsl"]
    assert got["grid_mismatches"] == 1 and got["float_mismatches"] == 1


def test_bad_cluster_tables_are_refused():
    q = np.arange(60, dtype=np.uint32).reshape(20, 3)
    _, _, cl = prepared(q, np.full(20, 4), 16)
    rec = records(cl, 4)
    with pytest.raises(ValueError, match="ClusterId\\[24\\]"):
        gpu.check_cluster_tables(rec[:1], cl.cluster_id, cl.vertex_id, 16)
    with pytest.raises(ValueError, match="runs of the cluster size"):
        gpu.check_cluster_tables(rec, cl.cluster_id, cl.vertex_id, 32)
    with pytest.raises(ValueError, match="outside"):
        gpu.check_cluster_tables(rec, cl.cluster_id, cl.vertex_id, 0)
    broken = rec.copy()
    broken[0, 0] = (3 << 24) | 9  # anchor of 4 bits with k = 3
    with pytest.raises(ValueError, match="anchor"):
        gpu.check_cluster_tables(broken, cl.cluster_id, cl.vertex_id, 16)


def test_decode_block_layout():
    vid = np.arange(LEVELS + 1) * 10
    cid = np.arange(LEVELS + 1)
    block = gpu.cluster_decode_block(vid, cid, 7, (1.0, 2.0, 3.0), 0.25, 99, 37)
    assert len(block) == gpu.CLUSTER_DECODE_BLOCK_BYTES == 416
    u = np.frombuffer(block, "<u4")
    np.testing.assert_array_equal(u[:25], vid)
    assert np.all(u[32:57] == 0) and np.all(u[57:64] == 0xFFFFFFFF) and tuple(u[68:72]) == (7, 99, 37, 0)
    np.testing.assert_array_equal(u[72:97], cid)
    assert np.all(u[97:104] == 0xFFFFFFFF)
    assert block[:256] == gpu.decode_block(vid, np.zeros(25), 7, (1.0, 2.0, 3.0), 0.25, 99)[:256]


def test_unclustered_shaders_do_not_see_the_clustered_code(gl):
    """Without LOP_CLUSTERED the preprocessed shaders hold nothing of the clustered layout (the
    unclustered code is what it was before issue 16); with it they do."""
    import shutil
    import subprocess

    require(gpu.hlsl_tools_available())
    glslang = shutil.which("glslangValidator")
    for name, stage, hlsl in (("decode_bitplanes.glsl", "vert", False), ("decode_bitplanes.hlsl", "vert", True),
                              ("adapt_bitplanes.comp.glsl", "comp", False), ("adapt_bitplanes.comp.hlsl", "comp", True)):
        path = gpu.shader_dir() / name
        for define, present in (([], False), (["-DLOP_CLUSTERED"], True)):
            head = ["-D", "-e", "lop_pack_cs"] if hlsl else []
            src = ("" if hlsl else "#version 450\n") + path.read_text()  # GLSL needs its #version first
            res = subprocess.run([glslang, "-E", "--stdin", "-S", stage, *head, *define, "-DLOP_KERNEL_PACK"], check=False,
                                 input=src, capture_output=True, text=True)
            assert res.returncode == 0 and "bin_start(" in res.stdout, res.stdout + res.stderr
            assert ("lop_cluster" in res.stdout) == present, (name, define)


# ---- adaption (compute shaders) --------------------------------------------------------------------

def _adapt_walk(language, qb, cl, sequence, offset=37):
    """Plane by plane through ``sequence``; after each plane: P, U (the decoded grid), every record's
    word 3, BitId and the PlaneBit of an added plane equal the CPU's from scratch."""
    ad = gpu.clustered_adapter(language)

    def scratch(level):
        return pack_clustered(reference_decode(qb, cl, level)[0], cl, level)

    def plane(p):  # this buffer's slice at bit ``offset`` of a larger section, foreign bits around it
        bits = np.concatenate([np.ones(offset, np.uint8), plane_bits_clustered(qb, cl, p)])
        bits = np.concatenate([bits, np.ones(-bits.size % 32 + 32, np.uint8)])
        return np.packbits(bits, bitorder="little").view("<u4"), offset

    buf = ad.upload(scratch(sequence[0]), records(cl, sequence[0]), cl.cluster_id, cl.vertex_id, cl.size,
                    sequence[0])
    try:
        ad.unpack(buf)
        values, widths = reference_decode(qb, cl, sequence[0])
        np.testing.assert_array_equal(buf.read_unpacked(), to_grid(values, widths))
        steps = 0
        for target in sequence[1:]:
            while buf.level != target:
                up = target > buf.level
                ad.adapt(buf, buf.level + (1 if up else -1), plane)
                steps += 1
                level = buf.level
                np.testing.assert_array_equal(buf.read_words(), scratch(level), err_msg=f"P at level {level}")
                np.testing.assert_array_equal(buf.read_unpacked(), to_grid(*reference_decode(qb, cl, level)),
                                              err_msg=f"U at level {level}")  # anchor-implied bits included
                np.testing.assert_array_equal(buf.read_records(), records(cl, level), err_msg=f"records at {level}")
                vid, bid, cid = buf.read_tables()
                np.testing.assert_array_equal(bid[:25], cluster_bit(cl, level)[cl.cluster_id])
                assert np.all(bid[25:] == 0xFFFFFFFF) and np.all(vid[25:] == 0xFFFFFFFF)
                np.testing.assert_array_equal(vid[:25], cl.vertex_id)
                np.testing.assert_array_equal(cid[:25], cl.cluster_id)
                assert buf.bits(level) == (int(cluster_bit(cl, level)[-1]), int(plane_bit(cl, level)[-1]))
                if up:
                    np.testing.assert_array_equal(buf.read_plane_bit(), plane_bit(cl, level))
        return steps
    finally:
        buf.release()


def test_adapt_sequence(language, rng):
    """6 -> 12 -> 8 -> 24 -> 1 -> 10 plane by plane, random and analytic data, four cluster sizes."""
    steps = 0
    for name, (qb, bins, cl) in datasets(rng):
        steps += _adapt_walk(language, qb, cl, SEQUENCE)
    assert steps == len(SIZES) * 2 * sum(abs(b - a) for a, b in itertools.pairwise(SEQUENCE))


def test_adapt_many_clusters_per_thread(language, rng):
    """More clusters than the tables kernel has threads (64), several per thread with a ragged end,
    and a pack dispatch of several groups: 9 000 vertices in clusters of 16."""
    u = rng.normal(size=(9000, 3))
    q = ((u / np.linalg.norm(u, axis=1, keepdims=True) * 0.4 + 0.5) * (2**24 - 1)).astype(np.uint32)
    qb, _, cl = prepared(q, rng.integers(1, 25, 9000), 16)
    assert len(cl.count) > 64 * 4
    _adapt_walk(language, qb, cl, (1, 5, 3, 24, 20))


def test_memory_reference_counts_records(rng):
    _, _, cl = prepared(*random_data(rng, 400), 64)
    assert clustered_bytes(cl, 24) == (4 * math.ceil(cluster_bit(cl, 24)[-1] / 32) + 16 * len(cl.count)
                                     + CLUSTER_ID_BYTES)


def test_verify_clustered_adapt(gl, rng):
    qb, _, cl = prepared(*analytic_data(rng, 16), 16)

    def words_at(level):
        return pack_clustered(reference_decode(qb, cl, level)[0], cl, level)

    def plane(p):
        bits = plane_bits_clustered(qb, cl, p)
        return np.packbits(np.concatenate([bits, np.zeros(-bits.size % 32 + 32, np.uint8)]), bitorder="little").view("<u4"), 0

    rep = verify_clustered_adapt(words_at, lambda b: records(cl, b), cl.cluster_id, cl.vertex_id, cl.size,
                                 [3, 6, 9], plane, languages=("glsl",))
    assert rep == {"glsl": {"adapt_steps": 12, "adapt_mismatches": 0}}
    rep = verify_clustered_adapt(words_at, lambda b: records(cl, b), cl.cluster_id, cl.vertex_id, cl.size,
                                 [9, 11], lambda p: (plane(p)[0] ^ np.uint32(1), 0), languages=("glsl",))
    assert rep["glsl"]["adapt_mismatches"] >= 1  # a corrupted plane is caught


@pytest.mark.parametrize("name", ["fixtures/unit_sphere.glb", "fixtures/two_plates.glb", "stanford-bunny.obj"])
def test_cooked_buffers_decode_as_the_unclustered_container(language, request, name):
    """The invariant across layouts, on cooked buffers: every buffer of the container, re-ordered and
    cut into clusters of 64, decodes at every level 1..24 to exactly the grid integers and float32
    positions that the container's own (unclustered) buffer decodes to, vertex for vertex."""
    from conftest import FIXTURES

    from lopcook.analyse import analyse
    from lopcook.emit import build
    from lopcook.lop.bitplane import decode
    from lopcook.lop.container import from_bytes
    from lopcook.lop.reader import gpu_buffer
    from lopcook.ingest import load

    path = FIXTURES / name.split("/", 1)[1] if name.startswith("fixtures/") else request.getfixturevalue("corpus") / name
    scene = load(path)
    c = from_bytes(build(scene, analyse(scene)), str(path))
    g = c.manifest["grid"]
    cell = g["extent"] / 2**24
    for part, p in enumerate(c.manifest["parts"]):
        for lod in range(len(p["lods"])):
            full = gpu_buffer(c, part, lod, LEVELS)
            q = to_grid(*decode(full.words, full.vertex_id, full.bit_id, LEVELS))
            levels = np.repeat(np.arange(1, LEVELS + 1), np.diff(np.asarray(full.vertex_id, dtype=np.int64)))
            bins = cluster_order(q, levels)
            qb = q[bins.order]
            cl = make_clusters(qb, bins.vertex_id, 64)
            np.testing.assert_array_equal(bins.vertex_id, full.vertex_id)  # the bins do not change
            for level in range(1, LEVELS + 1):
                buf = gpu_buffer(c, part, lod, level)
                values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
                words = pack_clustered(reference_decode(qb, cl, level)[0], cl, level)
                got = gpu.decode_clustered(language, words, records(cl, level), cl.cluster_id, cl.vertex_id, 64, level,
                                           g["origin"], np.float32(cell / 2))
                np.testing.assert_array_equal(got.grid, to_grid(values, widths)[bins.order], err_msg=f"{name} B={level}")
                ref = reconstruct_float32(values, widths, g["origin"], cell)[bins.order]
                np.testing.assert_array_equal(got.position.view(np.uint32), ref.view(np.uint32))
                np.testing.assert_array_equal(got.level, widths[bins.order])


# ---- lopcook verify --decoders on cooked clustered containers ----------------------------------------

@pytest.fixture(scope="module")
def clustered_lop(tmp_path_factory):
    """unit_sphere cooked with --clusters 64 and one LOD below it: two clustered buffers, the second
    one's plane slices at a non-zero bit offset."""
    from conftest import FIXTURES

    from lopcook.cli import main

    out = tmp_path_factory.mktemp("clustered") / "sphere64.lop"
    assert main(["cook", str(FIXTURES / "unit_sphere.glb"), "-o", str(out), "--clusters", "64", "--cluster-all",
                 "--lods", "0.5", "-q"]) == 0
    return out


@pytest.fixture(scope="module")
def plain_lop(tmp_path_factory):
    """The same cook as ``clustered_lop`` without clusters (``--clusters 0``)."""
    from conftest import FIXTURES

    from lopcook.cli import main

    out = tmp_path_factory.mktemp("plain") / "sphere.lop"
    assert main(["cook", str(FIXTURES / "unit_sphere.glb"), "-o", str(out), "--lods", "0.5", "--clusters", "0",
                 "-q"]) == 0
    return out


def test_cli_verify_decoders_on_a_clustered_container(gl, clustered_lop, capsys):
    """``verify --decoders`` decodes every clustered buffer with the LOP_CLUSTERED vertex shader and
    adapts it with the LOP_CLUSTERED kernels, in both languages, at every level: 0 mismatches."""
    import json

    from lopcook.cli import main
    from lopcook.lop.container import read

    require(gpu.hlsl_tools_available())
    c = read(str(clustered_lop))
    assert c.manifest["options"]["clusters"] == 64
    assert all(e["cluster_size"] == 64 for p in c.manifest["parts"] for e in p["lods"])
    assert main(["verify", str(clustered_lop), "--decoders", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)["decoders"]
    n = rep["vertices"]
    assert rep["ok"] is True and rep["buffers"] == rep["clustered_buffers"] == 2 and n > 642
    assert rep["levels"] == list(range(1, 25)) and set(rep["languages"]) == {"glsl", "hlsl"}
    for s in rep["languages"].values():
        assert s["decoded_vertices"] == s["clustered_decoded_vertices"] == 24 * n
        assert s["adapt_steps"] == s["clustered_adapt_steps"] == 2 * 46
        assert s["crack_free_vertices"] == 3 * n
        assert s["grid_mismatches"] == s["float_mismatches"] == s["level_mismatches"] == s["max_float_ulp"] == 0
        assert s["crack_free_mismatches"] == s["adapt_mismatches"] == 0
        assert sorted(s["per_level"], key=int) == [str(b) for b in range(1, 25)]
        for per in s["per_level"].values():  # every level decoded, and arrived at once per buffer by adaption
            assert per == {"decoded_vertices": n, "decode_mismatches": 0, "adapt_checks": 2, "adapt_mismatches": 0}
    assert rep["clustered_cpu"] == {"decoded_vertices": 24 * n, "mismatches": 0}
    assert main(["verify", str(clustered_lop), "--decoders", "--levels", "3,9", "--languages", "glsl"]) == 0
    text = capsys.readouterr().out
    assert "clustered buffers: 2 of 2, decoded by the LOP_CLUSTERED shaders" in text and "bit-exact" in text


def _wrong_anchor_vertices(c, levels):
    """{level: vertex decodes that go wrong at it (summed over buffers)} when bit 0 of every x
    anchor with k_x >= 1 is flipped: those with b = max(m, B) >= k_x (below k_x the bit is shifted
    out)."""
    from lopcook.lop.reader import buffer_clusters

    total = dict.fromkeys(levels, 0)
    for part, p in enumerate(c.manifest["parts"]):
        for lod in range(len(p["lods"])):
            cl = buffer_clusters(c, part, lod)
            kx = cl.k[:, 0].astype(np.int64)
            for level in levels:
                hit = (kx >= 1) & (np.maximum(cl.m, level) >= kx)
                total[level] += int(cl.count[hit].sum())
    return total


def test_cli_verify_catches_a_corrupted_cluster_record(gl, clustered_lop, monkeypatch, capsys):
    """A cluster record whose anchor is wrong on the GPU (bit 0 of every x anchor with k_x >= 1
    flipped in the records the renderer uploads; the file and so the CPU reference untouched)
    fails with exit 1, in both languages exactly the vertices whose decode reads that bit."""
    import json

    from lopcook.cli import main
    from lopcook.lop import reader
    from lopcook.lop.container import read

    require(gpu.hlsl_tools_available())
    real = reader.records

    def corrupted(clusters, level):
        rec = real(clusters, level).copy()
        flip = (rec[:, 0] >> np.uint32(24)) >= 1
        rec[flip, 0] ^= np.uint32(1)
        return rec

    monkeypatch.setattr(reader, "records", corrupted)
    levels = [1, 6, 12, 18, 24]
    by_level = _wrong_anchor_vertices(read(str(clustered_lop)), levels)
    want = sum(by_level.values())
    assert want > 100
    assert main(["verify", str(clustered_lop), "--decoders", "--levels", "1,6,12,18,24", "--no-adapt",
                 "--json"]) == 1
    rep = json.loads(capsys.readouterr().out)["decoders"]
    assert rep["ok"] is False and rep["clustered_cpu"]["mismatches"] == 0
    for s in rep["languages"].values():
        assert s["grid_mismatches"] == want and s["float_mismatches"] == want and s["level_mismatches"] == 0
        assert {int(b): v["decode_mismatches"] for b, v in s["per_level"].items()} == by_level
    e = rep["examples"][0]
    assert e["kind"] == "decode" and e["clustered"] is True and e["expected_grid"] != e["got_grid"]


def _broken_shaders(tmp_path):
    """A copy of the shaders whose GLSL clustered decode drops bit 0 of every anchor (the
    unclustered code untouched)."""
    broken = tmp_path / "shaders"
    broken.mkdir()
    for f in gpu.shader_dir().iterdir():
        (broken / f.name).write_text(f.read_text())
    src = (broken / "decode_bitplanes.glsl").read_text()
    line = "uvec3 a = rec.xyz & 0xFFFFFFu;"
    assert src.count(line) == 1
    (broken / "decode_bitplanes.glsl").write_text(src.replace(line, "uvec3 a = rec.xyz & 0xFFFFFEu;"))
    return broken


def test_cli_verify_catches_a_broken_clustered_decoder(gl, clustered_lop, plain_lop, tmp_path, monkeypatch, capsys):
    """A GLSL decoder whose clustered code drops bit 0 of every anchor fails the clustered container
    (exit 1, exactly the vertices whose decode reads an odd anchor's bit 0) and passes the same
    asset cooked unclustered: the clustered container is decoded by the LOP_CLUSTERED code."""
    import json

    from lopcook.cli import main
    from lopcook.lop.container import read
    from lopcook.lop.reader import buffer_clusters

    monkeypatch.setenv("LOPCOOK_SHADERS", str(_broken_shaders(tmp_path)))
    c = read(str(clustered_lop))
    want = 0
    for part, p in enumerate(c.manifest["parts"]):
        for lod in range(len(p["lods"])):
            cl = buffer_clusters(c, part, lod)
            k, odd = cl.k.astype(np.int64), (cl.anchor & 1).astype(bool)
            for level in range(1, LEVELS + 1):
                b = np.maximum(cl.m, level)[:, None]
                want += int(cl.count[np.any(odd & (k >= 1) & (b >= k), axis=1)].sum())
    assert want > 0
    assert main(["verify", str(clustered_lop), "--decoders", "--languages", "glsl", "--no-adapt", "--json"]) == 1
    rep = json.loads(capsys.readouterr().out)["decoders"]
    assert rep["languages"]["glsl"]["grid_mismatches"] == want and rep["examples"][0]["clustered"] is True
    assert main(["verify", str(plain_lop), "--decoders", "--languages", "glsl", "--no-adapt", "-q"]) == 0


def test_render_harness_draws_clustered_buffers_with_the_clustered_decoder(gl, clustered_lop, plain_lop, tmp_path,
                                                                          monkeypatch):
    """The harness uploads a clustered container's CAP buffers in their clustered layout
    (``cap_buffer``) and draws them with the LOP_CLUSTERED decoder: the images and PSNR equal those
    of the same cook unclustered, pixel for pixel, and a clustered decoder that drops an anchor bit
    changes the clustered CAP image (not AP's, not the unclustered container's)."""
    from conftest import FIXTURES

    from lopcook.lop.container import read
    from lopcook.lop.reader import ClusteredGpuBuffer, GpuBuffer
    from lopcook.ingest import load
    from lopcook.verify.buffers import cap_buffer
    from lopcook.verify.evaluate import evaluate

    scene = load(FIXTURES / "unit_sphere.glb")
    clus, plain = read(str(clustered_lop)), read(str(plain_lop))
    assert isinstance(cap_buffer(clus, 0, 0, 8), ClusteredGpuBuffer) and isinstance(cap_buffer(plain, 0, 0, 8), GpuBuffer)
    kw = {"levels": [12, 16], "views": 2, "resolution": (160, 120), "keep_images": True, "image_view": 0}

    def run(c):
        r = evaluate(c, scene, **kw)
        return [(row["level"], row["cap"]["psnr_mean"], row["ap"]["psnr_mean"]) for row in r["levels"]], r["images"]

    rows_c, img_c = run(clus)
    rows_p, img_p = run(plain)
    assert rows_c == rows_p
    for v in ("cap", "ap", "cap_ids"):
        np.testing.assert_array_equal(img_c[v], img_p[v])
    monkeypatch.setenv("LOPCOOK_SHADERS", str(_broken_shaders(tmp_path)))
    rows_b, img_b = run(clus)
    assert np.any(img_b["cap"] != img_c["cap"]) and rows_b[0][1] != rows_c[0][1]
    np.testing.assert_array_equal(img_b["ap"], img_c["ap"])
    rows_pb, img_pb = run(plain)
    assert rows_pb == rows_p
    np.testing.assert_array_equal(img_pb["cap"], img_p["cap"])


def test_cli_verify_refuses_a_container_with_a_bad_cluster_record(clustered_lop, tmp_path, capsys):
    """A stored cluster header with k_x = 25 (CRCs kept right): exit 2 with one container error
    naming the clusters, no traceback."""
    import json
    import struct
    import zlib

    from lopcook.cli import main
    from lopcook.lop.container import from_bytes

    data = bytearray(clustered_lop.read_bytes())
    c = from_bytes(bytes(data))
    msize = struct.unpack_from("<I", data, 12)[0]
    sec = next(s for s in c.manifest["sections"] if s["name"] == "positions/clusters")
    at = 32 + msize + sec["offset"]
    data[at + 3] = 25
    m = json.loads(bytes(data[32:32 + msize]))
    next(s for s in m["sections"] if s["name"] == "positions/clusters")["crc32"] = zlib.crc32(
        bytes(data[at:at + sec["length"]]))
    mb = json.dumps(m, sort_keys=True, separators=(",", ":")).encode()
    assert len(mb) == msize
    data[32:32 + msize] = mb
    data[16:20] = struct.pack("<I", zlib.crc32(mb))
    data[28:32] = struct.pack("<I", zlib.crc32(bytes(data[:28])))
    bad = tmp_path / "bad.lop"
    bad.write_bytes(bytes(data))
    assert main(["verify", str(bad), "--decoders", "--languages", "glsl"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lopcook: error: container") and "cluster" in err and "Traceback" not in err
