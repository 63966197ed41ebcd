"""Hostile and malformed sources (issue 17): each gives one LopcookError naming the file, or a
warning when only a texture is bad, never a Python exception, and never reads what it must not."""

from __future__ import annotations

import base64
import copy
import json
import os
import re

import numpy as np
import pytest

from tests.support import fuzzcases as fz
from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.ingest.build import MAX_COORDINATE, MAX_PARTS, MAX_TEXTURE_PIXELS, texture_problem

EXC_NAME = re.compile(r"\b\w+(Error|Exception)\b")


@pytest.fixture(scope="module")
def cube():
    return fz._gltf_doc()


def refused(path, *fragments) -> str:
    with pytest.raises(LopcookError) as info:
        load(str(path))
    text = str(info.value)
    assert "\n" not in text and not EXC_NAME.search(text), text
    assert os.path.basename(str(path)) in text, text
    for f in fragments:
        assert f in text, text
    return text


def write_glb(tmp_path, doc, blob, name="a.glb"):
    p = tmp_path / name
    p.write_bytes(fz._glb(doc, blob))
    return p


def write_gltf(tmp_path, doc, blob=None, name="a.gltf"):
    p = tmp_path / name
    p.write_bytes(fz._gltf_text(doc, blob) if blob is not None else json.dumps(doc).encode())
    return p


# ----------------------------------------------------------------------------- lying sizes


@pytest.mark.parametrize("length", [-1, 0, "12", 1.5, True])
def test_buffer_bytelength_must_be_a_positive_integer(tmp_path, cube, length):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["buffers"][0]["byteLength"] = length
    refused(write_glb(tmp_path, doc, blob), "buffer 0", "byteLength")


@pytest.mark.parametrize("key,value", [("byteLength", -8), ("byteOffset", -4), ("byteOffset", 0.5),
                                       ("byteStride", 2), ("byteStride", 1 << 30)])
def test_buffer_view_fields_are_checked(tmp_path, cube, key, value):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["bufferViews"][0][key] = value
    refused(write_glb(tmp_path, doc, blob), "bufferView 0")


@pytest.mark.parametrize("count", [1 << 31, 30_000_000])
def test_zero_accessor_with_a_huge_count_is_refused_before_allocating(tmp_path, cube, count):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["accessors"].append({"componentType": 5126, "type": "VEC3", "count": count})
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = len(doc["accessors"]) - 1
    refused(write_glb(tmp_path, doc, blob), f"{count:,} elements without a bufferView")


@pytest.mark.parametrize("count", [1 << 31, 30_000_000])
def test_accessor_count_beyond_its_view_is_refused(tmp_path, cube, count):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["accessors"][0]["count"] = count
    refused(write_glb(tmp_path, doc, blob), "reads past the end of bufferView")


# ----------------------------------------------------------------------------- compression


def test_draco_used_but_not_required_is_refused(tmp_path, cube):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["extensionsUsed"] = ["KHR_draco_mesh_compression"]
    doc["meshes"][0]["primitives"][0]["extensions"] = {
        "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}
    refused(write_glb(tmp_path, doc, blob), "Draco", "decompress")


@pytest.mark.parametrize("ext", ["EXT_meshopt_compression", "KHR_meshopt_compression"])
def test_meshopt_used_but_not_required_is_refused(tmp_path, cube, ext):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["extensionsUsed"] = [ext]
    doc["bufferViews"][0]["extensions"] = {ext: {"buffer": 0, "byteLength": 8, "byteStride": 12, "count": 24,
                                                 "mode": "ATTRIBUTES"}}
    refused(write_glb(tmp_path, doc, blob), ext)


# ----------------------------------------------------------------------------- JSON


def test_deeply_nested_json_is_refused_in_its_own_terms(tmp_path, cube):
    p = tmp_path / "a.gltf"
    text = fz._gltf_text(*cube).decode()
    p.write_text(text[:-1] + ', "extras": ' + "[" * 100_000 + "]" * 100_000 + "}")
    refused(p, "nested too deeply")


def test_integer_with_thousands_of_digits_is_refused(tmp_path, cube):
    text = fz._gltf_text(*cube).decode().replace('"scene": 0', '"scene": 1' + "0" * 5000)
    p = tmp_path / "a.gltf"
    p.write_text(text)
    refused(p, "invalid JSON")


# ----------------------------------------------------------------------------- scene size


def test_more_placements_than_the_limit_are_refused_before_decoding(tmp_path, cube):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["nodes"] = [{"mesh": 0} for _ in range(MAX_PARTS + 1)]
    doc["scenes"] = [{"nodes": list(range(MAX_PARTS + 1))}]
    refused(write_glb(tmp_path, doc, blob), f"{MAX_PARTS:,}")


def test_many_identical_primitives_decode_once(tmp_path, cube):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["meshes"][0]["primitives"] = doc["meshes"][0]["primitives"] * 50
    scene = load(str(write_glb(tmp_path, doc, blob)))
    assert len(scene.parts) == 50
    assert len({id(p.indices) for p in scene.parts}) <= 50
    assert all(np.array_equal(p.positions, scene.parts[0].positions) for p in scene.parts)


def test_a_long_node_chain_is_walked_iteratively(tmp_path, cube):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    depth = 20_000
    doc["nodes"] = [{"children": [i + 1], "translation": [1.0, 0, 0]} for i in range(depth)] + [{"mesh": 0}]
    doc["scenes"] = [{"nodes": [0]}]
    scene = load(str(write_glb(tmp_path, doc, blob)))
    assert scene.bounds()[0][0] == pytest.approx(depth - 0.5)


# ----------------------------------------------------------------------------- degenerate geometry


@pytest.mark.parametrize("value", [1e200, float(np.finfo(np.float32).max)])
def test_coordinates_beyond_the_float32_budget_are_refused(tmp_path, cube, value):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["nodes"][0]["scale"] = [value] * 3
    refused(write_glb(tmp_path, doc, blob), f"{MAX_COORDINATE:.3g}")


def test_a_scene_float32_cannot_resolve_is_refused(tmp_path, cube):
    doc, blob = copy.deepcopy(cube[0]), cube[1]
    doc["nodes"][0]["translation"] = [1e20, 0, 0]
    refused(write_glb(tmp_path, doc, blob), "float32", "move the scene near the origin")


# ----------------------------------------------------------------------------- textures


def test_texture_problem_names_each_defect():
    pngs = fz._bad_pngs()
    assert texture_problem(fz._png(8, 8)) is None
    for name, data in pngs.items():
        problem = texture_problem(data)
        assert problem and not EXC_NAME.search(problem), (name, problem)
    assert "empty" in texture_problem(pngs["empty_png"])
    assert f"{MAX_TEXTURE_PIXELS:,}" in texture_problem(pngs["bomb_png"])
    assert f"{MAX_TEXTURE_PIXELS:,}" in texture_problem(pngs["huge_dims_png"])


def test_pillow_limit_is_set_deliberately():
    from PIL import Image

    import lopcook.ingest  # noqa: F401

    assert Image.MAX_IMAGE_PIXELS == MAX_TEXTURE_PIXELS


@pytest.mark.parametrize("label", sorted(fz._bad_pngs()))
def test_unreadable_gltf_texture_is_a_warning_and_the_part_cooks_untextured(tmp_path, cube, label):
    data = fz._bad_pngs()[label]
    doc = fz._textured(cube[0], {"uri": "data:image/png;base64," + base64.b64encode(data).decode()})
    scene = load(str(write_glb(tmp_path, doc, cube[1])))
    assert all(p.texture is None for p in scene.parts)
    assert any("image 0" in w and "no texture" in w for w in scene.warnings), scene.warnings


def test_good_texture_is_kept(tmp_path, cube):
    doc = fz._textured(cube[0], {"uri": "t.png"})
    (tmp_path / "t.png").write_bytes(fz._png(8, 8))
    scene = load(str(write_gltf(tmp_path, doc, cube[1])))
    assert scene.parts[0].texture is not None and not scene.warnings
    assert os.path.join(str(tmp_path), "t.png") in scene.dependencies


@pytest.mark.parametrize("uri", ["/etc/passwd", "/dev/zero", "../../../../../../../etc/passwd", ".",
                                 "data:", "data:image/png;base64,@@@", "missing.png"])
def test_hostile_texture_uris_warn(tmp_path, cube, uri):
    scene = load(str(write_gltf(tmp_path, fz._textured(cube[0], {"uri": uri}), cube[1])))
    assert scene.parts[0].texture is None
    assert scene.warnings


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_texture_and_buffer_are_never_opened(tmp_path, cube):
    os.mkfifo(tmp_path / "t.png")
    scene = load(str(write_gltf(tmp_path, fz._textured(cube[0], {"uri": "t.png"}), cube[1])))
    assert any("not a regular file" in w for w in scene.warnings)
    doc = copy.deepcopy(cube[0])
    doc["buffers"][0]["uri"] = "a.bin"
    os.mkfifo(tmp_path / "a.bin")
    refused(write_gltf(tmp_path, doc, name="b.gltf"), "not a regular file")


def test_symlink_to_dev_zero_is_refused(tmp_path):
    os.symlink("/dev/zero", tmp_path / "a.glb")
    refused(tmp_path / "a.glb", "not a regular file")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_source_is_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "a.obj")
    refused(tmp_path / "a.obj", "not a regular file")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
@pytest.mark.parametrize("command", ["inspect", "cook"])
def test_cli_refuses_a_fifo_source_without_blocking(tmp_path, command):
    import subprocess
    import sys

    os.mkfifo(tmp_path / "scene.obj")
    args = [command, str(tmp_path / "scene.obj")] + (["-o", str(tmp_path / "a.lop")] if command == "cook" else [])
    r = subprocess.run([sys.executable, "-m", "lopcook", *args], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "not a regular file" in r.stderr and "Traceback" not in r.stderr


def test_absolute_buffer_uri_is_refused(tmp_path, cube):
    doc = copy.deepcopy(cube[0])
    doc["buffers"][0]["uri"] = "/etc/passwd"
    refused(write_gltf(tmp_path, doc), "absolute path")


def test_newline_in_a_dependency_is_refused(tmp_path, cube):
    (tmp_path / "t\nx.png").write_bytes(fz._png())
    doc = fz._textured(cube[0], {"uri": "t%0Ax.png"})
    refused(write_gltf(tmp_path, doc, cube[1]), "line break")


# ----------------------------------------------------------------------------- OBJ


def test_obj_continuation_inside_a_number_is_refused(tmp_path):
    p = tmp_path / "a.obj"
    p.write_text("v 0\\\n.5 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    refused(p, "line 1", "splits a number")


def test_obj_continuation_between_numbers_still_works(tmp_path):
    p = tmp_path / "a.obj"
    p.write_text("v 0.5 \\\n 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert load(str(p)).parts[0].positions[:, 0].tolist() == [0.5, 1.0, 0.0]


def test_obj_backslash_inside_a_number_is_refused(tmp_path):
    p = tmp_path / "a.obj"
    p.write_text("v 0\\.5 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    refused(p, "malformed number")


@pytest.mark.parametrize("target", ["/etc/passwd", "junk.png", "empty.png", "/dev/zero"])
def test_obj_map_kd_that_is_no_image_is_a_warning(tmp_path, target):
    (tmp_path / "junk.png").write_bytes(b"junk" * 10)
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "a.mtl").write_text(f"newmtl m\nmap_Kd {target}\n")
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                    "f 1/1 2/2 3/3\n")
    scene = load(str(tmp_path / "a.obj"))
    assert scene.parts[0].texture is None
    assert scene.warnings


_PEAK_CHILD = """
import resource, sys
from lopcook.cli import main
main(["cook", sys.argv[1], "-o", sys.argv[2]])  # a small file first: imports and caches warm
warm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
rc = main(["cook", sys.argv[3], "-o", sys.argv[4]])
print("peak_kib", warm, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, "rc", rc)
"""


def test_obj_huge_face_line_is_refused_in_bounded_memory(tmp_path):
    """One face line of 1,000,000 corners over 4 vertices (2 MB) would be a million overlapping
    triangles: refused with its line, in seconds, the cook's peak growing by under 30x the file."""
    import subprocess
    import sys

    small = tmp_path / "small.obj"
    small.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    big = tmp_path / "line.obj"
    big.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf " + " 1 2 3 4" * 250_000 + "\n")
    r = subprocess.run([sys.executable, "-c", _PEAK_CHILD, str(small), str(tmp_path / "small.lop"), str(big),
                        str(tmp_path / "a.lop")],
                       capture_output=True, text=True, timeout=60)
    errors = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(errors) == 1 and "line.obj" in errors[0] and "line 5" in errors[0], r.stderr
    assert "1,000,000 corners" in errors[0] and "4 distinct vertices" in errors[0], errors[0]
    _, warm, peak, _, rc = r.stdout.splitlines()[-1].split()
    assert rc == "2" and not (tmp_path / "a.lop").exists()  # exit 2, no partial output
    assert (int(peak) - int(warm)) * 1024 < 30 * big.stat().st_size, (warm, peak, big.stat().st_size)


# ----------------------------------------------------------------------------- messages


def test_error_messages_are_one_line():
    err = LopcookError("ingest", "a\nb.obj", "first\nsecond\r\n  third", hint="do\nthis")
    assert str(err) == "ingest: a b.obj: first second third (do this)"


def _obj(path, verts, faces):
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in verts)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))
    return path


@pytest.mark.parametrize("good_at", [0, 4095, 4096, 9999])
def test_one_spanning_triangle_anywhere_is_enough(tmp_path, good_at):
    """The degeneracy check samples the first triangles before a full pass: a lone good triangle
    inside the sample, at its edge or after it is found either way (10,000 triangles)."""
    verts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
    faces = [(0, 0, 0)] * 10_000
    faces[good_at] = (0, 1, 2)
    scene = load(str(_obj(tmp_path / "mostly_degenerate.obj", verts, faces)))
    assert scene.n_triangles >= 1


def test_only_degenerate_triangles_beyond_the_sample_are_refused(tmp_path):
    verts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
    with pytest.raises(LopcookError, match="degenerate"):
        load(str(_obj(tmp_path / "all_degenerate.obj", verts, [(0, 0, 0), (1, 1, 1)] * 5_000)))


@pytest.mark.parametrize("faces", [[(0, 1, 2), (1, 2, 3), (0, 2, 3)],      # collinear corners
                                   [(0, 0, 0), (1, 1, 1), (0, 1, 0)]])      # repeated indices
def test_triangles_that_span_cells_but_have_no_area_are_refused(tmp_path, faces):
    verts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (2.0, 0.0, 0.0), (3.0, 0.0, 0.0)]
    with pytest.raises(LopcookError, match="no area") as exc:
        load(str(_obj(tmp_path / "flat.obj", verts, faces)))
    assert exc.value.exit_code == 2


@pytest.mark.parametrize("cap", [None, 700_000_000])
def test_a_usd_crash_under_a_memory_cap_names_the_cap(monkeypatch, cap):
    from conftest import FIXTURES
    from lopcook import isolate, memory

    def crash(*args, **kwargs):
        raise isolate.ChildFailed("the worker process ended without a result (killed by signal 11)")

    monkeypatch.setattr(isolate, "call", crash)
    monkeypatch.setattr(isolate, "call_fresh", crash)
    monkeypatch.setattr(memory, "address_space_limit", lambda: cap)
    src = next(iter(sorted(FIXTURES.glob("*.usda"))))
    with pytest.raises(LopcookError) as exc:
        load(str(src))
    text = str(exc.value)
    assert exc.value.exit_code == 2 and "signal 11" in text
    assert ("0.7 GB address-space limit" in text) == (cap is not None) and ("corrupt" in text)
