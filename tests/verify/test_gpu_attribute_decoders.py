"""shaders/decode_attributes.glsl and .hlsl against lopcook.lop.record.decode_record, bit for bit.

The packed vertex attribute record (issue 15, Purnomo et al. 2005 sections 3-5: octahedral normals
4..16 bits, UVs 6..16, colours 4..8 per component, fields crossing 32-bit words) is decoded in a
vertex shader through transform feedback (lopcook.verify.attribute_gpu.AttributeDecoder); every float32 must
equal the CPU reference's bits (0 ulp), the unnormalised normal included. Skips without EGL,
glslangValidator or spirv-cross, except under CI=true, where it fails.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from conftest import FIXTURES, require
from lopcook.analyse import analyse
from lopcook.emit import build
from lopcook.lop.codecs import AttributeBits
from lopcook.lop.record import decode_record, encode_record
from lopcook.lop.container import from_bytes
from lopcook.ingest import load
from lopcook.verify import attribute_gpu as AG
from lopcook.verify import gpu
from lopcook.verify.decoders import attribute_record, verify_decoders

NORMAL_BITS, UV_BITS, COLOR_BITS = range(4, 17), range(6, 17), range(4, 9)


@pytest.fixture(params=gpu.LANGUAGES)
def language(request, gl):
    if request.param == "hlsl":
        require(gpu.hlsl_tools_available())
    return request.param


@pytest.fixture(scope="session")
def both_languages(gl):
    require(gpu.hlsl_tools_available())
    return gpu.LANGUAGES


def bit_mixes(rng):
    """Every normal, UV and colour width at least once (the others random or absent), every
    attribute alone, and the all-maximum and all-minimum records (96 and 36 bits)."""
    mixes = [(b, int(rng.integers(6, 17)), int(rng.integers(4, 9))) for b in NORMAL_BITS]
    mixes += [(int(rng.integers(4, 17)), b, None) for b in UV_BITS]
    mixes += [(None, int(rng.integers(6, 17)), b) for b in COLOR_BITS]
    mixes += [(b, None, None) for b in (4, 9, 16)] + [(None, b, None) for b in (6, 11, 16)]
    mixes += [(None, None, b) for b in (4, 5, 8)] + [(16, 16, 8), (4, 6, 4), (8, 8, None), (16, None, None)]
    return mixes


def record_bits(bits) -> int:
    bn, bu, bc = (b or 0 for b in bits)
    return 2 * bn + 2 * bu + 4 * bc


def as_bits(bits) -> AttributeBits:
    return AttributeBits(*bits)


def assert_same_bits(got: dict, ref: dict, where: str) -> None:
    for name in ("normals", "uvs", "colors"):
        if ref.get(name) is None:
            assert got[name] is None, f"{name} {where}"
            continue
        want = np.ascontiguousarray(ref[name], dtype=np.float32)
        assert got[name].shape == want.shape, f"{name} {where}"
        bad = np.flatnonzero(np.any(got[name].view(np.uint32) != want.view(np.uint32), axis=1))
        assert bad.size == 0, f"{name} {where}: {bad.size} records differ, e.g. vertex {bad[0]}: " \
                              f"{got[name][bad[0]]} vs {want[bad[0]]}"


# ---- any bit pattern --------------------------------------------------------------------------------

def test_random_words_every_bit_mix(language, rng):
    """Random words read as records of every width mix: every code appears (code 0 of the normals,
    read as -1, the fold region z < 0, fields that cross a word), and the last record either ends
    exactly at the end of the words (no padding word) or inside the last word."""
    dec = AG.attribute_decoder(language)
    lo, step = np.float32([-3.7, 1000.1]), np.float32([1.0e-3, 0.7])
    for bits in bit_mixes(rng):
        s = record_bits(bits)
        for n in (4096, 4097):
            words = rng.integers(0, 2**32, -(-n * s // 32), dtype=np.uint64).astype(np.uint32)
            uv_range = [lo.tolist(), (lo + step * np.float32(2 ** (bits[1] or 6) - 1)).tolist()]
            entry = {"uv_range": uv_range, "uv_step": step.tolist()}
            ref = decode_record(words, n, as_bits(bits), entry)
            got = dec.decode(words, n, as_bits(bits), entry)
            assert_same_bits(got, ref, f"{language} bits {bits} n={n}")
        if bits[0]:
            z = got["normals"][:, 2]
            assert (z < 0).any() and (z > 0).any()  # both halves of the octahedron were decoded


# ---- encoded attributes -------------------------------------------------------------------------------

def special_normals(rng, n):
    """Random directions, the six axes, the diagonals and the fold (z = 0 and just below)."""
    d = rng.normal(size=(n, 3))
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    diag = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T.astype(np.float64)
    t = rng.uniform(0, 2 * np.pi, 200)
    fold = np.stack([np.cos(t), np.sin(t), np.where(np.arange(200) % 2, 0.0, -1e-4)], axis=1)
    out = np.concatenate([axes, diag, fold, d])
    return (out / np.linalg.norm(out, axis=1, keepdims=True)).astype(np.float32)


@pytest.mark.parametrize("degenerate_uv", [False, True])
def test_encoded_records_every_bit_mix(language, rng, degenerate_uv):
    """encode_record's own words (axes, diagonals, fold, random directions; UVs over a range or a
    degenerate one; colours including 0 and 1) decode on the GPU to decode_record's bits, and the
    normalised GPU normals point where the inputs did (so the comparison is of meaningful data)."""
    dec = AG.attribute_decoder(language)
    normals = special_normals(rng, 3000)
    n = len(normals)
    uvs = rng.uniform(-2.0, 5.0, (n, 2)).astype(np.float32)
    if degenerate_uv:
        uvs[:, 1] = np.float32(0.25)
    colors = rng.uniform(0.0, 1.0, (n, 4)).astype(np.float32)
    colors[:4] = [[0, 0, 0, 0], [1, 1, 1, 1], [0, 1, 0, 1], [1, 0, 1, 0]]
    for bits in bit_mixes(rng):
        words, meta = encode_record({"normals": normals if bits[0] else None, "uvs": uvs if bits[1] else None,
                                     "colors": colors if bits[2] else None}, as_bits(bits))
        assert words.dtype == np.uint32 and words.size == -(-n * record_bits(bits) // 32)
        ref = decode_record(words, n, as_bits(bits), meta["lod"])
        got = dec.decode(words, n, as_bits(bits), meta["lod"])
        assert_same_bits(got, ref, f"{language} bits {bits}")
        if bits[0]:
            v = got["normals"].astype(np.float64)
            d = normals.astype(np.float64)
            angle = np.arctan2(np.linalg.norm(np.cross(v, d), axis=1), np.sum(v * d, axis=1))
            assert angle.max() < 3.0 / (2 ** (bits[0] - 1) - 1)  # radians: a few code steps at most
            np.testing.assert_array_equal(got["normals"][:6], np.concatenate([np.eye(3), -np.eye(3)]))  # axes exact
        if bits[1] and degenerate_uv:
            assert np.all(got["uvs"][:, 1] == np.float32(0.25))


# ---- cooked containers ------------------------------------------------------------------------------

def _cook(scene):
    return from_bytes(build(scene, analyse(scene)), scene.source)


@pytest.mark.parametrize("bits", [(None, None), (11, 13)])
@pytest.mark.parametrize("name", ["Duck.glb", "DamagedHelmet/DamagedHelmet.gltf"])
def test_corpus_attributes_both_languages(both_languages, corpus, name, bits):
    """Every part/LOD's attribute record of a cooked corpus asset (normals and UVs, LOD chain
    included), both languages: at the default bits and at 11 + 13 bits (a 48-bit record, many
    fields crossing a word)."""
    from lopcook.api import cook
    from lopcook.settings import AttributeSettings, Settings

    c = cook(load(corpus / name), Settings(attributes=AttributeSettings.of(normal=bits[0], uv=bits[1])))
    report = verify_decoders(c, [c.available_level], both_languages, adapt=False)
    n = sum(e["vertices"] for p in c.manifest["parts"] for e in p["lods"])
    assert report["attribute_buffers"] == report["buffers"] >= 1
    for lang in both_languages:
        s = report["languages"][lang]
        assert s["attribute_vertices"] == n
        assert (s["normal_mismatches"], s["uv_mismatches"], s["color_mismatches"], s["attribute_max_ulp"]) == (0, 0, 0, 0)
    assert report["ok"] and report["examples"] == []
    words, count, got_bits, _ = attribute_record(c, 0, 0)
    assert got_bits.normals and got_bits.uvs and words.size == -(-count * got_bits.record_bits // 32)
    if bits[0]:
        assert (got_bits.normals, got_bits.uvs, got_bits.record_bits) == (11, 13, 48)


@pytest.mark.parametrize("bits", [(None, None, None), (5, 7, 4), (16, 16, 8)])
def test_cooked_colours_both_languages(both_languages, bits):
    """A fixture given vertex colours and UVs and cooked at explicit bits (or the defaults): the
    GPU decode of the container's own section equals decode_record, and the verify report says so."""
    from lopcook.api import cook
    from lopcook.settings import AttributeSettings, Settings

    scene = load(FIXTURES / "unit_sphere.glb")
    rng = np.random.default_rng(7)
    parts = []
    for p in scene.parts:
        n = len(p.positions)
        parts.append(dataclasses.replace(p, colors=rng.uniform(0, 1, (n, 4)).astype(np.float32),
                                         uvs=rng.uniform(0, 1, (n, 2)).astype(np.float32)))
    scene = dataclasses.replace(scene, parts=tuple(parts))
    settings = Settings(attributes=AttributeSettings(bits=bits))
    c = cook(scene, settings)
    report = verify_decoders(c, [1], both_languages, adapt=False)
    e = c.manifest["parts"][0]["lods"][0]
    if bits[0]:
        assert e["attribute_bits"] == as_bits(bits).as_dict()
    assert all(e["attribute_bits"][k] for k in ("normals", "uvs", "colors"))
    for lang in both_languages:
        s = report["languages"][lang]
        assert s["attribute_vertices"] > 0 and s["color_mismatches"] == s["normal_mismatches"] == s["uv_mismatches"] == 0
    assert report["ok"]


# ---- command line, broken decoders, translation ------------------------------------------------------

@pytest.fixture(scope="module")
def cube_lop(tmp_path_factory):
    scene = load(FIXTURES / "seamed_cube.glb")
    path = tmp_path_factory.mktemp("verify-attributes") / "cube.lop"
    path.write_bytes(build(scene, analyse(scene)))
    return path


def test_cli_verify_reports_attributes(both_languages, cube_lop, capsys):
    from lopcook.cli import main

    assert main(["verify", str(cube_lop), "--decoders", "--levels", "8", "--no-adapt", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)["decoders"]
    assert rep["attribute_buffers"] == 1
    for s in rep["languages"].values():
        assert s["attribute_vertices"] == 24 and s["attribute_max_ulp"] == 0
        assert s["normal_mismatches"] == s["uv_mismatches"] == s["color_mismatches"] == 0
    assert main(["verify", str(cube_lop), "--decoders", "--levels", "8", "--no-adapt"]) == 0
    text = capsys.readouterr().out
    assert "glsl attributes: 24 records in 1 buffers, 0 mismatches" in text
    assert "hlsl attributes: 24 records in 1 buffers, 0 mismatches" in text


@pytest.mark.parametrize("old, new, field", [
    ("precise float ax = 1.0 - a.x;", "precise float ax = 1.0 - a.y;", "normal_mismatches"),
    ("lop_attr_uv.xy + vec2(q) * lop_attr_uv.zw", "lop_attr_uv.xy + vec2(q + 1u) * lop_attr_uv.zw", "uv_mismatches"),
])
def test_cli_verify_detects_a_broken_attribute_decoder(gl, cube_lop, tmp_path, monkeypatch, capsys, old, new, field):
    from lopcook.cli import main

    broken = tmp_path / "shaders"
    broken.mkdir()
    for f in gpu.shader_dir().iterdir():
        (broken / f.name).write_text(f.read_text())
    src = (broken / "decode_attributes.glsl").read_text()
    assert old in src
    (broken / "decode_attributes.glsl").write_text(src.replace(old, new))
    monkeypatch.setenv("LOPCOOK_SHADERS", str(broken))
    assert main(["verify", str(cube_lop), "--decoders", "--languages", "glsl", "--levels", "3", "--no-adapt",
                 "--json"]) == 1
    rep = json.loads(capsys.readouterr().out)["decoders"]
    s = rep["languages"]["glsl"]
    assert rep["ok"] is False and s[field] > 0 and s["float_mismatches"] == 0
    assert rep["examples"][0]["kind"] == "attributes"


def test_hlsl_translation_keeps_precise(both_languages):
    """llvmpipe never fuses, so check the cross-compiled HLSL still marks the UV's product and sum
    (the one multiply-add of the record) and the colour product precise."""
    src = AG.attribute_shader_source("hlsl")
    ops = [ln for ln in src.splitlines() if ("lop_attr_uv" in ln or "lop_attr_scale.y" in ln)
           and ("*" in ln or "+" in ln) and "_data[" not in ln]
    assert len(ops) >= 2, src
    assert all(ln.strip().startswith("precise ") for ln in ops), ops
    assert AG.attribute_shader_source("glsl").count("precise ") >= 8


def test_bad_bits_and_short_words_are_errors(gl):
    with pytest.raises(ValueError, match=r"normals: 17 bits"):
        AG.attribute_block((17, None, None), {}, 1)
    with pytest.raises(ValueError, match=r"colors: 3 bits"):
        AG.attribute_bits({"normals": None, "uvs": 8, "colors": 3})
    with pytest.raises(ValueError, match="need 4 words, got 3"):
        AG.attribute_decoder("glsl").decode(np.zeros(3, np.uint32), 2, (16, None, 8))
    with pytest.raises(ValueError, match="uvs need their uv_range"):
        AG.attribute_decoder("glsl").decode(np.zeros(4, np.uint32), 2, (16, 16, None))


_BOTH_GLSL_MAIN = """
out vec3 lop_out_position;
out vec3 lop_out_normal;
out vec2 lop_out_uv;
void main()
{
    uvec3 grid; vec3 position; uint bits;
    lop_decode(uint(gl_VertexID), grid, position, bits);
    lop_out_position = position;
    lop_out_normal = lop_decode_normal(uint(gl_VertexID));
    lop_out_uv = lop_decode_uv(uint(gl_VertexID));
}
"""

_BOTH_HLSL_MAIN = """
struct LopBothOut { float3 position : LOP_POSITION; float3 normal : LOP_NORMAL; float2 uv : LOP_UV; };
LopBothOut lop_both_vs(uint j : SV_VertexID)
{
    LopBothOut o;
    uint3 grid; uint bits;
    lop_decode(j, grid, o.position, bits);
    o.normal = lop_decode_normal(j);
    o.uv = lop_decode_uv(j);
    return o;
}
"""


def test_position_and_attribute_decoders_in_one_shader(language, cube_lop):
    """Both files included in one vertex shader (as shaders/README.md shows) with their default
    bindings: positions and attributes of the cooked cube decode to the CPU references together."""
    import moderngl

    from lopcook.lop.bitplane import decode, reconstruct_float32
    from lopcook.lop.container import read
    from lopcook.lop.reader import gpu_buffer

    c = read(str(cube_lop))
    varyings = ("lop_out_position", "lop_out_normal", "lop_out_uv")
    if language == "glsl":
        src = ("#version 450\n#define LOP_NO_VIEW\n" + gpu.shader_source("decode_bitplanes.glsl")
               + gpu.shader_source("decode_attributes.glsl") + _BOTH_GLSL_MAIN)
    else:
        src = gpu.hlsl_to_glsl(gpu.shader_source("decode_bitplanes.hlsl") + gpu.shader_source("decode_attributes.hlsl")
                               + _BOTH_HLSL_MAIN, "vert", "lop_both_vs", defines=("LOP_NO_VIEW",),
                               rename_outputs=varyings, name="both.hlsl")
    ctx = gpu.context()
    prog = ctx.program(vertex_shader=src, varyings=varyings)
    vao = ctx.vertex_array(prog, [])
    level = 12
    g = c.manifest["grid"]
    cell = g["extent"] / 2**24
    buf = gpu_buffer(c, 0, 0, level)
    words, n, bits, entry = attribute_record(c, 0, 0)
    res = [ctx.buffer(buf.words.tobytes()), ctx.buffer(gpu.decode_block(buf.vertex_id, buf.bit_id, level, g["origin"],
                                                                        np.float32(cell / 2), buf.words.size)),
           ctx.buffer(words.tobytes()), ctx.buffer(AG.attribute_block(bits, entry, words.size))]
    res[0].bind_to_storage_buffer(0)
    res[1].bind_to_uniform_block(0)
    res[2].bind_to_storage_buffer(1)
    res[3].bind_to_uniform_block(2)
    out = ctx.buffer(reserve=n * 32)
    try:
        vao.transform(out, mode=moderngl.POINTS, vertices=n)
        got = np.frombuffer(out.read(), dtype=np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("uv", "<f4", 2)]))
    finally:
        for r in [out, *res]:
            r.release()
        vao.release()
        prog.release()
    values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
    ref = decode_record(words, n, bits, entry)
    np.testing.assert_array_equal(got["p"].view(np.uint32),
                                  reconstruct_float32(values, widths, g["origin"], cell).view(np.uint32))
    np.testing.assert_array_equal(got["n"].view(np.uint32), ref["normals"].view(np.uint32))
    np.testing.assert_array_equal(got["uv"].view(np.uint32), ref["uvs"].view(np.uint32))
