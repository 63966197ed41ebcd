"""The .lop container: decode at every level, the prefix property, determinism, corruption,
atomic writes, and the cook / inspect / decode commands."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import FIXTURES
from lopcook.analyse import analyse
from lopcook.emit import build
from lopcook.lop.codecs.normals_oct import normal_error_deg
from lopcook.lop.codecs.uvs_range import uv_error_bound
from lopcook.lop.binning import make_bins
from lopcook.lop.container import READABLE_MAJORS, VERSION, from_bytes
from lopcook.lop.reader import decode_positions, gpu_buffer, lod_attributes
from lopcook.errors import LopcookError
from lopcook.ingest import load

CORPUS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
          "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd", "chess_set_flat.usdc"]


def slow_read(words, vid, level, j):
    """Independent re-implementation of the paper's formula, bit by bit in plain Python."""
    k = next(k for k in range(1, 25) if vid[k - 1] <= j < vid[k])
    b = max(k, level)
    bit_id = sum(3 * max(kk, level) * (vid[kk] - vid[kk - 1]) for kk in range(1, k))
    start = 3 * b * (j - vid[k - 1]) + bit_id
    return [sum(((int(words[(start + c * b + i) // 32]) >> ((start + c * b + i) % 32)) & 1) << i
                for i in range(b)) for c in range(3)]


@pytest.fixture(scope="module")
def cooked(corpus, cooks):
    """``cooked(name)``: (scene, analysis, bytes, container) of a corpus asset, or of
    ``fixtures/NAME``, from the suite's cook cache (``cooks.analysed``)."""

    def get(name):
        path = corpus / name if not name.startswith("fixtures/") else FIXTURES / name.split("/", 1)[1]
        return cooks.analysed(path)

    return get


@pytest.mark.parametrize("name", CORPUS + ["fixtures/seamed_cube.glb", "fixtures/two_plates.usda"])
def test_every_level_decodes_exactly_and_within_dx(cooked, name, rng):
    scene, an, data, c = cooked(name)
    levels = range(1, 25) if scene.n_vertices < 100_000 else (1, 2, 6, 9, 12, 16, 20, 24)
    for i, (part, pa) in enumerate(zip(scene.parts, an.parts)):
        bins = make_bins(pa.min_level)
        src_q = pa.quantized[bins.order]
        src_p = part.positions[bins.order]
        for level in levels:
            grid_q, widths, _ = decode_positions(c, i, 0, level)
            np.testing.assert_array_equal(widths, np.maximum(bins.levels, level))
            # the kept bits are exactly the source's top bits
            s = (24 - widths)[:, None].astype(np.uint32)
            np.testing.assert_array_equal(grid_q >> s, src_q >> s)
            if level == 24:
                np.testing.assert_array_equal(grid_q, src_q)  # invariant 1: level 24 == quantized source
            _, _, p64 = decode_positions(c, i, 0, level, float32=False)
            err = np.linalg.norm(p64 - src_p, axis=1)
            assert np.all(err <= an.grid.dx(widths) * (1 + 1e-9) + 1e-12 * an.grid.extent)
            buf = gpu_buffer(c, i, 0, level)
            for j in rng.choice(part.n_vertices, size=min(20, part.n_vertices), replace=False):
                assert slow_read(buf.words, buf.vertex_id, level, int(j)) == \
                    (grid_q[j] >> s[j]).tolist()
        if len(scene.parts) > 6 and i >= 3:
            break  # the chess set: four parts at eight levels keep the suite fast


def test_attributes_round_trip(cooked):
    scene, an, _, c = cooked("fixtures/seamed_cube.glb")
    part, pa = scene.parts[0], an.parts[0]
    bins = make_bins(pa.min_level)
    a = lod_attributes(c, 0, 0, unit_directions=True)
    np.testing.assert_array_equal(bins.order[a["indices"]], part.indices)
    # each attribute within the documented bound of the bits the manifest says it was stored at
    entry = c.manifest["parts"][0]["lods"][0]
    bits = entry["attribute_bits"]
    src_n = part.normals[bins.order].astype(np.float64)
    src_n /= np.linalg.norm(src_n, axis=1, keepdims=True)
    cos = np.clip(np.einsum("ij,ij->i", a["normals"].astype(np.float64), src_n), -1.0, 1.0)
    assert np.degrees(np.arccos(cos)).max() <= normal_error_deg(bits["normals"])
    lo, hi = entry["uv_range"]
    err = np.abs(a["uvs"].astype(np.float64) - part.uvs[bins.order].astype(np.float64))
    assert np.all(err <= uv_error_bound(lo, hi, bits["uvs"]))
    assert err.max() > 0 or bits["uvs"] == 16  # the test sees the quantisation it bounds


def plane_ends(c_bytes):
    """Byte offsets at which each position section ends (mandatory, plane 2, plane 3, ...)."""
    c = from_bytes(c_bytes)
    msize = int.from_bytes(c_bytes[12:16], "little")
    base = 32 + msize
    return [(s["name"], base + s["offset"] + s["length"]) for s in c.manifest["sections"]
            if s["name"].startswith("positions/")]


@pytest.mark.parametrize("name", ["fixtures/seamed_cube.glb", "fixtures/two_plates.usda", "CesiumMilkTruck.glb"])
def test_prefix_property(cooked, name):
    scene, an, data, full = cooked(name)
    ends = plane_ends(data)
    for level, (section, end) in enumerate(ends, start=1):
        prefix = from_bytes(data[:end], allow_prefix=True)
        # empty planes (no vertex below that level) end where the previous one does: the cut then
        # holds every later empty plane too
        expect = max(lv for lv, (_, e) in enumerate(ends, start=1) if e <= end)
        assert prefix.available_level == expect, section
        level = expect
        for i in range(len(scene.parts)):
            got = decode_positions(prefix, i, 0, level)[0]
            np.testing.assert_array_equal(got, decode_positions(full, i, 0, level)[0])
        if level < 24:
            with pytest.raises(LopcookError, match="not in this file"):
                decode_positions(prefix, 0, 0, level + 1)
        # a cut inside the next non-empty section gives the same level
        if level < len(ends):
            assert from_bytes(data[:end + 1], allow_prefix=True).available_level == level
    with pytest.raises(LopcookError, match="truncated"):
        from_bytes(data[:ends[-2][1]])  # without allow_prefix a short file is an error
    # before the mandatory bits nothing can be decoded
    with pytest.raises(LopcookError):
        from_bytes(data[:ends[0][1] - 1], allow_prefix=True)


def test_same_input_same_bytes(cooked):
    scene, an, data, _ = cooked("CesiumMilkTruck.glb")
    assert build(scene, analyse(scene)) == data


def test_every_byte_flip_is_detected(cooked):
    _, _, data, _ = cooked("fixtures/two_plates.usda")
    c = from_bytes(data)
    msize = int.from_bytes(data[12:16], "little")
    positions = set(range(0, 32)) | set(range(32, 32 + msize, max(1, msize // 60)))
    base = 32 + msize
    for s in c.manifest["sections"]:
        start, end = base + s["offset"], base + s["offset"] + s["length"]
        positions |= {start, (start + end) // 2, end - 1}
    assert max(positions) == len(data) - 1
    for pos in sorted(positions):
        bad = bytearray(data)
        bad[pos] ^= 0x5A
        with pytest.raises(LopcookError):
            from_bytes(bytes(bad))
    for cut in (0, 10, 31, 32 + msize // 2, len(data) - 1):
        with pytest.raises(LopcookError):
            from_bytes(data[:cut])
    with pytest.raises(LopcookError, match="trailing"):
        from_bytes(data + b"\0\0\0\0")


def test_future_major_version_is_refused(cooked):
    import struct
    import zlib

    _, _, data, _ = cooked("fixtures/seamed_cube.glb")
    bad = bytearray(data)
    future = max(READABLE_MAJORS) + 1  # 3.0 is the clustered layout (issue 16): the next unknown major is 4
    bad[4:6] = struct.pack("<H", future)
    bad[28:32] = struct.pack("<I", zlib.crc32(bytes(bad[:28])))
    with pytest.raises(LopcookError, match=f"version {future}.0 is not supported"):
        from_bytes(bytes(bad))


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "lopcook", *map(str, args)], capture_output=True, text=True, cwd=cwd)


def test_cli_cook_inspect_decode(tmp_path):
    out = tmp_path / "cube.lop"
    proc = run("cook", FIXTURES / "seamed_cube.glb", "-o", out, "--json")
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert d["totals"]["vertices"] == 24 and d["available_level"] == 24
    assert {r["level"] for r in d["memory"]} == set(range(1, 25))
    assert set(d["timings_s"]) >= {"ingest", "analyse", "emit", "write"}
    again = tmp_path / "again.lop"
    assert run("cook", FIXTURES / "seamed_cube.glb", "-o", again).returncode == 0
    assert out.read_bytes() == again.read_bytes()  # deterministic across processes
    proc = run("inspect", out, "--json")
    assert proc.returncode == 0 and json.loads(proc.stdout)["kind"] == "container"
    glb = tmp_path / "preview.glb"
    proc = run("decode", out, "--level", "10", "-o", glb)
    assert proc.returncode == 0, proc.stderr
    back = load(glb)
    assert back.n_triangles == 12 and back.n_vertices == 24


def test_cli_failed_cook_leaves_no_file(tmp_path):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    out = tmp_path / "out.lop"
    proc = run("cook", bad, "-o", out)
    assert proc.returncode == 2 and not out.exists()
    out.write_bytes(b"previous")
    assert run("cook", bad, "-o", out).returncode == 2
    assert out.read_bytes() == b"previous"  # an earlier output is not touched
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []  # no temporary left


def test_cli_decode_errors(tmp_path):
    out = tmp_path / "c.lop"
    assert run("cook", FIXTURES / "seamed_cube.glb", "-o", out).returncode == 0
    for args, needle in ((["--level", "0"], "outside"), (["--level", "25"], "outside"),
                         (["--level", "5", "--lod", "3"], "LOD 3")):
        proc = run("decode", out, *args, "-o", tmp_path / "x.glb")
        assert proc.returncode == 2 and needle in proc.stderr and "Traceback" not in proc.stderr
    garbage = tmp_path / "g.lop"
    garbage.write_bytes(b"LOPC" + os.urandom(60))
    proc = run("inspect", garbage)
    assert proc.returncode == 2 and "g.lop" in proc.stderr


@pytest.mark.parametrize("name,level", [("CesiumMilkTruck.glb", 6), ("UtahTeapot.usd", 11), ("spot.obj", 24)])
def test_decode_output_passes_khronos_validator(corpus, tmp_path, name, level, gltf_validator):
    V = gltf_validator
    out = tmp_path / "c.lop"
    assert run("cook", corpus / name, "-o", out).returncode == 0
    glb = tmp_path / "preview.glb"
    proc = run("decode", out, "--level", level, "-o", glb)
    assert proc.returncode == 0, proc.stderr
    report = V.validate(glb)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, V.problems(report)


def test_cli_cook_depfile(corpus, tmp_path):
    out, dep = tmp_path / "helmet.lop", tmp_path / "helmet.d"
    proc = run("cook", corpus / "DamagedHelmet" / "DamagedHelmet.gltf", "-o", out, "--depfile", dep)
    assert proc.returncode == 0, proc.stderr
    text = dep.read_text()
    first = text.split("\n", 1)[0]
    assert first.startswith(str(out).replace(" ", "\\ ") + ":")
    for name in ("DamagedHelmet.gltf", "DamagedHelmet.bin", "Default_albedo.jpg"):
        assert name in text
    assert "Default_normal.jpg" not in text  # never read


def test_cli_cook_lods_and_nearest(corpus, tmp_path):
    out = tmp_path / "bunny.lop"
    proc = run("cook", corpus / "stanford-bunny.obj", "-o", out, "--lods", "1/2,1/4", "--lod-backend", "fast",
               "--nearest", "1m", "--json")
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert d["totals"]["buffers"] == 3
    tris = [lod["triangles"] for lod in d["parts"][0]["lods"]]
    assert tris[0] == 69451 and tris[0] > tris[1] > tris[2]
    assert d["max_level"] < 24 and d["savings"]["bytes_saved"] > 0
    back = tmp_path / "lod2.glb"
    assert run("decode", out, "--level", d["max_level"], "--lod", 2, "-o", back).returncode == 0
    assert load(back).n_triangles == tris[2]
    for bad in ("1/2,3/4", "2", "x"):
        proc = run("cook", corpus / "stanford-bunny.obj", "-o", tmp_path / "x.lop", "--lods", bad)
        assert proc.returncode == 2 and "--lods" in proc.stderr
