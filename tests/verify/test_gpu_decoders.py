"""GLSL and HLSL decoders of shaders/ against the CPU reference, on a headless moderngl context.

The vertex path runs through transform feedback (lopcook.verify.gpu.VertexDecoder), the adaption
kernels through SSBOs (lopcook.verify.gpu.Adapter). Everything must be bit-exact: grid integers,
float32 bits, bits per component, packed words and tables. Tests skip when EGL, glslangValidator or
spirv-cross is missing, except under CI=true, where they fail.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import FIXTURES, require
from lopcook.analyse import analyse
from lopcook.emit import build
from lopcook.lop.binning import LEVELS, make_bins, table_bit_id, vertex_widths
from lopcook.lop.bitplane import decode, pack, plane_bits, reconstruct_float32, to_grid, top_bits
from lopcook.lop.reader import gpu_buffer
from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.verify import gpu
from lopcook.verify.decoders import (buffer_level, decode_crack_free, plane_source, verify_decoders,
                                     view_tables)
from lopcook.viewing import Viewing, required_level

CORPUS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
          "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd", "chess_set_flat.usdc"]
FIXTURE_FILES = ["seamed_cube.glb", "two_plates.glb", "unit_sphere.glb", "concave_ngon.gltf",
                 "nested_transforms.gltf", "zup_cm.usda", "point_instancer.usda"]
SEQUENCE = (6, 12, 8, 24, 1, 10)


@pytest.fixture(params=gpu.LANGUAGES)
def language(request, gl):
    if request.param == "hlsl":
        require(gpu.hlsl_tools_available())
    return request.param


@pytest.fixture(scope="session")
def both_languages(gl):
    require(gpu.hlsl_tools_available())
    return gpu.LANGUAGES


def _analysed(cooks, path):
    """(scene, analysis, container) from the suite's cook cache (``cooks.analysed``)."""
    scene, an, _, c = cooks.analysed(path)
    return scene, an, c


@pytest.fixture(scope="module")
def cooked(corpus, cooks):
    """``cooked(name)``: (scene, analysis, container) of a corpus asset."""
    return lambda name: _analysed(cooks, corpus / name)


@pytest.fixture(scope="module")
def cooked_fixture(cooks):
    """``cooked_fixture(name)``: (scene, analysis, container) of ``fixtures/NAME``."""
    return lambda name: _analysed(cooks, FIXTURES / name)


def synthetic_buffer(rng, n=3000):
    """Every bin populated, grid integers across the whole range (0 and 2^24 - 1 included) and an
    origin far from zero, so that the float additions round."""
    levels = np.concatenate([np.arange(1, 25), rng.integers(1, 25, n - 24)])
    q = rng.integers(0, 2**24, (n, 3)).astype(np.uint32)
    q[:5] = [[0, 0, 0], [2**24 - 1] * 3, [2**23, 2**23 - 1, 2**23 + 1], [1, 2**24 - 2, 3], [2**22, 7, 2**24 - 3]]
    bins = make_bins(levels)
    return bins, q[bins.order], (1000.3, -52.7, 3.1e-3), 0.37 / 2**24


def assert_decoded_equal(got: gpu.Decoded, values, widths, origin, cell, where=""):
    np.testing.assert_array_equal(got.grid, to_grid(values, widths), err_msg=f"grid {where}")
    ref = reconstruct_float32(values, widths, origin, cell)
    bad = np.flatnonzero(np.any(got.position.view(np.uint32) != ref.view(np.uint32), axis=1))
    assert bad.size == 0, f"float bits differ {where} at vertices {bad[:5]}: {got.position[bad[:3]]} vs {ref[bad[:3]]}"
    np.testing.assert_array_equal(got.level, widths, err_msg=f"bits {where}")


# ---- vertex decoding --------------------------------------------------------------------------------

def test_synthetic_buffer_every_level(language, rng):
    bins, q, origin, cell = synthetic_buffer(rng)
    dec = gpu.vertex_decoder(language)
    for level in range(1, LEVELS + 1):
        vid = bins.vertex_id
        words = pack(top_bits(q, vertex_widths(vid, level)), vid, level)
        bid = table_bit_id(vid, level)
        values, widths = decode(words, vid, bid, level)
        got = dec.decode(words, vid, bid, level, origin, np.float32(cell / 2))
        assert_decoded_equal(got, values, widths, origin, cell, f"{language} B={level}")
        if level == LEVELS:
            np.testing.assert_array_equal(got.grid, q)  # level 24 is the quantized source


@pytest.mark.parametrize("name", FIXTURE_FILES)
def test_fixtures_every_level(language, cooked_fixture, name):
    scene, an, c = cooked_fixture(name)
    g = c.manifest["grid"]
    cell = g["extent"] / 2**24
    dec = gpu.vertex_decoder(language)
    for part in range(len(c.manifest["parts"])):
        for level in range(1, LEVELS + 1):
            buf = gpu_buffer(c, part, 0, level)
            values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
            got = dec.decode(buf.words, buf.vertex_id, buf.bit_id, level, g["origin"], np.float32(cell / 2))
            assert_decoded_equal(got, values, widths, g["origin"], cell, f"{name} part {part} B={level}")


@pytest.mark.parametrize("name", CORPUS)
def test_corpus_every_level_both_languages(both_languages, cooked, name):
    """Every part/LOD at every level 1..24, both languages (the chess set: 49 buffers, 774K vertices);
    the adaption kernels walk every buffer up 1 -> 24 and back to 1, except on the chess set
    (test_adapt_sequence_corpus covers its largest parts)."""
    scene, an, c = cooked(name)
    report = verify_decoders(c, range(1, LEVELS + 1), both_languages, adapt=not name.startswith("chess"))
    n = sum(e["vertices"] for p in c.manifest["parts"] for e in p["lods"])
    for lang in both_languages:
        s = report["languages"][lang]
        assert s["decoded_vertices"] == LEVELS * n
        assert (s["grid_mismatches"], s["float_mismatches"], s["level_mismatches"], s["max_float_ulp"]) == (0, 0, 0, 0)
        assert s["adapt_mismatches"] == s["crack_free_mismatches"] == 0 and s["crack_free_vertices"] == 3 * n
    assert report["ok"] and report["examples"] == []


def test_hlsl_translation_keeps_precise(both_languages):
    """llvmpipe never fuses a multiply-add (even an explicit fma() gives the unfused result), so the
    bit-exact runs cannot catch a lost ``precise``: check the cross-compiled HLSL still carries it on
    every float operation of the reconstruction."""
    src = gpu.vertex_shader_source("hlsl")
    float_ops = [ln for ln in src.splitlines() if "lop_origin_half" in ln and ("*" in ln or "+" in ln)]
    assert float_ops, src
    assert all(ln.strip().startswith("precise ") for ln in float_ops), float_ops
    glsl = gpu.vertex_shader_source("glsl")
    assert glsl.count("precise vec3") >= 2


# ---- adaption (compute shaders) --------------------------------------------------------------------

def _walk(adapter, buf, sequence, scratch, plane):
    """Adapt plane by plane through ``sequence``; after every single plane, P and the tables must equal
    the CPU packing of that level from scratch."""
    for target in sequence[1:]:
        while buf.level != target:
            adapter.adapt(buf, buf.level + (1 if target > buf.level else -1), plane)
            words, vid, bid = scratch(buf.level)
            got_vid, got_bid = buf.read_tables()
            assert np.array_equal(buf.read_words(), words), f"P differs at level {buf.level}"
            assert np.array_equal(got_vid[: LEVELS + 1], vid) and np.array_equal(got_bid[: LEVELS + 1], bid), \
                f"tables differ at level {buf.level}"
            assert np.all(got_vid[LEVELS + 1:] == 0xFFFFFFFF) and np.all(got_bid[LEVELS + 1:] == 0xFFFFFFFF)


def test_adapt_sequence_synthetic(language, rng):
    bins, q, _, _ = synthetic_buffer(rng)
    vid = bins.vertex_id

    def scratch(level):
        return pack(top_bits(q, vertex_widths(vid, level)), vid, level), vid, table_bit_id(vid, level)

    def plane(p):  # uploaded at bit offset 37 of a larger section, as a renderer would slice it
        bits = np.concatenate([np.ones(37, np.uint8), plane_bits(q, vid, p).ravel()])
        bits = np.concatenate([bits, np.ones(-bits.size % 32 + 32, np.uint8)])  # foreign bits after it
        return np.packbits(bits, bitorder="little").view("<u4"), 37

    ad = gpu.adapter(language)
    buf = ad.upload(*scratch(SEQUENCE[0])[:2], SEQUENCE[0])
    try:
        ad.unpack(buf)  # U is the decoded grid (Fig. 11a), dropped bits zero
        values, widths = decode(*scratch(SEQUENCE[0]), SEQUENCE[0])
        np.testing.assert_array_equal(buf.read_unpacked(), to_grid(values, widths))
        _walk(ad, buf, SEQUENCE, scratch, plane)
    finally:
        buf.release()


@pytest.mark.parametrize("name", ["seamed_cube.glb", "unit_sphere.glb", "two_plates.glb"])
def test_adapt_sequence_fixtures(language, cooked_fixture, name):
    _, _, c = cooked_fixture(name)
    _adapt_container(language, c, range(len(c.manifest["parts"])))


def _adapt_container(language, c, parts):
    ad = gpu.adapter(language)
    for part in parts:
        def scratch(level, part=part):
            b = gpu_buffer(c, part, 0, level)
            return b.words, b.vertex_id, b.bit_id

        start = gpu_buffer(c, part, 0, SEQUENCE[0])
        buf = ad.upload(start.words, start.vertex_id, SEQUENCE[0])
        try:
            _walk(ad, buf, SEQUENCE, scratch, plane_source(c, part, 0))
        finally:
            buf.release()


@pytest.mark.parametrize("name", ["CesiumMilkTruck.glb", "chess_set_flat.usdc"])
def test_adapt_sequence_corpus(language, cooked, name):
    """6 -> 12 -> 8 -> 24 -> 1 -> 10 plane by plane on the container's own plane sections (each part's
    slice found by its bit offset): every part of the truck; the three largest and the two smallest
    of the 49 chess buffers."""
    _, _, c = cooked(name)
    sizes = [p["lods"][0]["vertices"] for p in c.manifest["parts"]]
    order = np.argsort(sizes, kind="stable")
    parts = range(len(sizes)) if len(sizes) < 10 else [*order[::-1][:3], *order[:2]]
    _adapt_container(language, c, [int(p) for p in parts])


# ---- crack-free per-vertex levels ---------------------------------------------------------------------

def _split_in_two(positions, indices):
    """Two parts sharing the vertices on the cut: triangles left / right of the median centroid x."""
    cx = positions[indices].mean(axis=1)[:, 0]
    halves = [indices[cx < np.median(cx)], indices[cx >= np.median(cx)]]
    return [np.unique(h) for h in halves]


@pytest.mark.parametrize("source,ap", [("fixtures/unit_sphere.glb", False), ("fixtures/unit_sphere.glb", True),
                                       ("stanford-bunny.obj", False), ("stanford-bunny.obj", True)])
def test_crack_free_shared_vertices(language, request, rng, source, ap):
    """Two parts sharing boundary vertices, each at its own per-buffer level (at least what its box
    needs, plus 0..7), random cameras near and far: the shared vertices decode to identical floats
    in both parts, the GPU equals the CPU mirror bit for bit, and every level meets the view's
    criterion at the vertex's true distance. ``ap``: every minimum level 1 (the paper's AP), where
    the per-buffer decode visibly cracks."""
    if source.startswith("fixtures/"):
        scene = load(FIXTURES / source.split("/", 1)[1])
    else:
        scene = load(request.getfixturevalue("corpus") / source)
    an = analyse(scene)
    part, pa = scene.parts[0], an.parts[0]
    grid = an.grid
    q, pos = pa.quantized, part.positions
    min_level = np.ones(len(q), np.int64) if ap else pa.min_level
    viewing = Viewing()
    level_dist, radius = view_tables(grid.extent, viewing, grid.origin)
    k = viewing.pixel_error * 2 * math.tan(math.radians(viewing.fov_y_deg) / 2) / viewing.viewport[1]
    pad = 2.0**-21 * (np.abs(grid.origin).max() + grid.extent)
    halves = []
    for verts in _split_in_two(pos, part.indices.astype(np.int64)):
        bins = make_bins(min_level[verts])
        halves.append((verts[bins.order], bins, pos[verts].min(axis=0), pos[verts].max(axis=0)))
    shared = np.intersect1d(halves[0][0], halves[1][0])
    assert shared.size > 10
    dec, plain = gpu.vertex_decoder(language, crack_free=True), gpu.vertex_decoder(language)
    half = np.float32(grid.cell / 2)
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    cracks_without = 0
    for trial in range(24):
        scale = 10.0 ** rng.uniform(-1.5, 2.5)
        cam = (lo + hi) / 2 + (hi - lo) * rng.uniform(-1, 1, 3) * scale
        decoded, per_buffer = [], []
        for verts, bins, blo, bhi in halves:
            need = buffer_level(cam, blo, bhi, level_dist)
            B = min(LEVELS, need + int(rng.integers(0, 8)))
            widths = vertex_widths(bins.vertex_id, B)
            values = top_bits(q[verts], widths)
            words, bid = pack(values, bins.vertex_id, B), table_bit_id(bins.vertex_id, B)
            got = dec.decode(words, bins.vertex_id, bid, B, grid.origin, half, view=(cam, level_dist, radius))
            ref_grid, ref_pos, ref_level = decode_crack_free(values, widths, bins.levels, B, grid.origin,
                                                             grid.cell, cam, level_dist, radius)
            np.testing.assert_array_equal(got.grid, ref_grid)
            np.testing.assert_array_equal(got.position.view(np.uint32), ref_pos.view(np.uint32))
            np.testing.assert_array_equal(got.level, ref_level)
            assert np.all(ref_level >= bins.levels) and np.all(ref_level <= widths)
            # the criterion at the true (source) distance, up to the documented float32 margin
            d = np.linalg.norm(pos[verts] - cam, axis=1)
            assert np.all((grid.dx(ref_level) <= k * (d + pad)) | (ref_level == LEVELS))
            inverse = np.empty(len(q), np.int64)
            inverse[verts] = np.arange(len(verts))
            decoded.append(got.position[inverse[shared]])
            per_buffer.append(plain.decode(words, bins.vertex_id, bid, B, grid.origin, half).position[inverse[shared]])
        np.testing.assert_array_equal(decoded[0].view(np.uint32), decoded[1].view(np.uint32),
                                      err_msg=f"crack at camera {cam}")
        cracks_without += not np.array_equal(per_buffer[0], per_buffer[1])
    if ap:
        assert cracks_without > 0  # without per-vertex levels the parts do crack


def test_buffer_level_is_the_half_pixel_level_or_finer(rng):
    extent = 2.5
    level_dist, _ = view_tables(extent)
    box = (np.zeros(3), np.ones(3))
    assert buffer_level(np.array([0.5, 0.5, 0.5]), *box, level_dist) == LEVELS  # inside the box
    assert buffer_level(np.array([0.0, 0.0, 1e9]), *box, level_dist) == 1
    for d in np.geomspace(1e-3, 1e5, 60):
        b = buffer_level(np.array([0.5, 0.5, 1.0 + d]), *box, level_dist)
        assert int(required_level(d, extent)) <= b <= int(required_level(d, extent)) + 1


# ---- command line and errors ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def cube_lop(tmp_path_factory):
    scene = load(FIXTURES / "seamed_cube.glb")
    path = tmp_path_factory.mktemp("verify") / "cube.lop"
    path.write_bytes(build(scene, analyse(scene)))
    return path


def test_cli_verify_json(both_languages, cube_lop, capsys):
    from lopcook.cli import main

    assert main(["verify", str(cube_lop), "--decoders", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] is True and out["container"] == str(cube_lop)
    rep = out["decoders"]
    assert rep["levels"] == list(range(1, 25)) and rep["buffers"] == 1 and rep["vertices"] == 24
    assert set(rep["languages"]) == {"glsl", "hlsl"}
    for s in rep["languages"].values():
        assert s["decoded_vertices"] == 24 * 24 and s["adapt_steps"] == 46 and s["crack_free_vertices"] == 3 * 24
        assert s["grid_mismatches"] == s["float_mismatches"] == s["level_mismatches"] == 0
        assert s["crack_free_mismatches"] == s["adapt_mismatches"] == 0
    assert {"renderer", "vendor", "version"} <= set(rep["device"])
    assert main(["-q", "verify", str(cube_lop), "--decoders", "--levels", "6,8,12", "--languages", "glsl"]) == 0
    assert capsys.readouterr().out == ""


@pytest.mark.parametrize("args", [[], ["--decoders", "--levels", "0-3"], ["--decoders", "--levels", "25"],
                                  ["--decoders", "--levels", "x"], ["--decoders", "--languages", "cuda"]])
def test_cli_verify_usage_errors_exit_2(cube_lop, capsys, args):
    from lopcook.cli import main

    assert main(["verify", str(cube_lop), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lopcook: error: usage:") and "Traceback" not in err


def test_cli_verify_detects_a_broken_decoder(gl, cube_lop, tmp_path, monkeypatch, capsys):
    """A decoder that reconstructs at the cell corner instead of its centre fails with exit 1 and
    names the mismatching vertices."""
    from lopcook.cli import main

    broken = tmp_path / "shaders"
    broken.mkdir()
    for f in gpu.shader_dir().iterdir():
        (broken / f.name).write_text(f.read_text())
    src = (broken / "decode_bitplanes.glsl").read_text()
    assert "((v << 1u) | 1u)" in src
    (broken / "decode_bitplanes.glsl").write_text(src.replace("((v << 1u) | 1u)", "(v << 1u)"))
    monkeypatch.setenv("LOPCOOK_SHADERS", str(broken))
    assert main(["verify", str(cube_lop), "--decoders", "--languages", "glsl", "--levels", "3", "--json"]) == 1
    rep = json.loads(capsys.readouterr().out)["decoders"]
    assert rep["ok"] is False and rep["languages"]["glsl"]["float_mismatches"] == 24
    assert rep["languages"]["glsl"]["grid_mismatches"] == 0 and rep["examples"][0]["kind"] == "decode"
    assert rep["languages"]["glsl"]["crack_free_mismatches"] > 0  # lop_reconstruct is shared


def test_missing_tools_name_the_packages(monkeypatch):
    import shutil

    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(LopcookError) as err:
        gpu.hlsl_to_glsl("void main() {}", "vert", "main")
    assert "glslang-tools" in str(err.value) and err.value.exit_code == 2
    assert "spirv-cross" in gpu.hlsl_tools_available()


def test_missing_egl_names_the_packages(monkeypatch):
    import moderngl

    def no_egl(**kwargs):
        raise OSError("libEGL.so.1: cannot open shared object file")

    monkeypatch.setattr(gpu, "_CONTEXT", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", no_egl)
    with pytest.raises(LopcookError) as err:
        gpu.context()
    assert "libegl1" in str(err.value) and "libgl1-mesa-dri" in str(err.value) and "EGL" in str(err.value)
