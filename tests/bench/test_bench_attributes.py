"""The pure parts of ``lopcook bench --attributes`` (lopcook/bench/attributes.py): GPU bytes of
every glTF attribute, gltfpack's UV transform read back, the run list, a container's bytes per
vertex, and the bench input's textured material. No peer tool, no GL, no timing."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lopcook.bench import attributes as A


def _gltf(accessors, prims):
    return {"accessors": accessors, "meshes": [{"primitives": [{"attributes": a} for a in prims]}]}


def test_attribute_bytes_round_each_element_up_to_four_bytes():
    acc = [{"count": 10, "type": "VEC3", "componentType": 5122},   # 16-bit positions: 6 -> 8 B
           {"count": 10, "type": "VEC3", "componentType": 5120},   # 8-bit normals: 3 -> 4 B
           {"count": 10, "type": "VEC2", "componentType": 5123},   # 16-bit UVs: 4 B
           {"count": 10, "type": "VEC4", "componentType": 5121},   # RGBA8: 4 B
           {"count": 5, "type": "VEC3", "componentType": 5126},    # float positions: 12 B
           {"count": 5, "type": "VEC2", "componentType": 5126}]    # float UVs: 8 B
    g = _gltf(acc, [{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "COLOR_0": 3},
                    {"POSITION": 4, "TEXCOORD_0": 5}, {"POSITION": 0, "NORMAL": 1}])  # shared accessors count once
    b, verts = A.gltf_attribute_bytes(g)
    assert verts == 15
    assert b == {"POSITION": 80 + 60, "NORMAL": 40, "TEXCOORD_0": 40 + 40, "COLOR_0": 40}


def test_texture_transform_is_read_and_rotation_refused():
    g = {"materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": {
        "KHR_texture_transform": {"offset": [0.25, -1.0], "scale": [2.0, 0.5]}}}}}]}
    off, scale = A.texture_transform(g)
    assert off.tolist() == [0.25, -1.0] and scale.tolist() == [2.0, 0.5]
    assert A.texture_transform({"materials": [{}]}) is None
    g["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"]["KHR_texture_transform"]["rotation"] = 0.5
    with pytest.raises(ValueError):
        A.texture_transform(g)


def test_configs_sweep_one_attribute_at_a_time_around_each_default():
    avail = {"gltfpack": "gp", "gltf-transform": "gt", "draco": "py"}
    cfgs = A.attribute_configs(avail)
    for tool, defaults in (("gltfpack", A.GLTFPACK_DEFAULTS), ("gltf-transform", A.GLTF_TRANSFORM_DEFAULTS),
                           ("draco", A.DRACO_DEFAULTS)):
        mine = [c for c in cfgs if c["tool"] == tool]
        assert [c["kind"] for c in mine].count("default") == 1 and mine[0]["bits"] == defaults
        for c in mine[1:]:
            changed = [k for k in defaults if c["bits"][k] != defaults[k]]
            assert len(changed) == 1 and changed[0] in ("vn", "vt")
        assert len({c["config"] for c in mine}) == len(mine)
    assert min(c["bits"]["vn"] for c in cfgs if c["tool"] == "gltf-transform") >= 8  # it refuses fewer
    gp = A.peer_argv(cfgs[0], avail, "in.glb", "in.npz", "out.glb")
    assert gp[:1] == ["gp"] and gp[gp.index("-vn") + 1] == "8" and gp[gp.index("-vt") + 1] == "12"
    assert A.attribute_configs({}) == []
    plain = A.attribute_configs(avail, normals=True, uvs=False)  # no UVs: no UV sweep
    assert all(c["bits"]["vt"] == c0["bits"]["vt"] for c in plain for c0 in plain if c0["tool"] == c["tool"])
    assert len(plain) < len(cfgs)


def test_container_bytes_per_vertex_adds_the_attribute_sections(tmp_path):
    from lopcook.api import cook, load
    from lopcook.lop.summary import memory_rows
    from tests.support.fixtures import seamed_cube, write_gltf

    write_gltf(seamed_cube(), tmp_path / "cube.gltf")
    c = cook(load(tmp_path / "cube.gltf"))
    got = A.container_bytes_per_vertex(c, 11)
    n = sum(p["lods"][0]["vertices"] for p in c.manifest["parts"])
    cap = next(r["cap_bytes"] for r in memory_rows(c, levels=[11]))
    lengths = {s["name"]: s["length"] for s in c.manifest["sections"]}
    attr = sum(lengths[v] for p in c.manifest["parts"] for k, v in p["lods"][0].items()
               if k in ("attributes", "normals", "uvs", "colors") and isinstance(v, str))
    assert attr > 0 and got["vertices"] == n
    assert got["total"] == pytest.approx((cap + attr) / n) and got["positions"] == pytest.approx(cap / n)


def test_bench_input_has_one_textured_material_on_the_parts_with_uvs(tmp_path):
    from dataclasses import replace

    from lopcook.api import load
    from lopcook.bench.common import glb_json
    from tests.support.fixtures import seamed_cube, two_plates, write_gltf

    parts = seamed_cube() + [replace(two_plates()[0], uvs=None)]  # a part without UVs gets no material
    write_gltf(parts, tmp_path / "s.gltf")
    src = load(tmp_path / "s.gltf")
    glb, npz = A.write_inputs(src, tmp_path)
    doc = glb_json(glb)
    prims = [p for m in doc["meshes"] for p in m["primitives"]]
    assert [("TEXCOORD_0" in p["attributes"], p.get("material")) for p in prims] == [(True, 0), (False, None)]
    assert len(doc["materials"]) == 1 and len(doc["images"]) == 1
    with np.load(npz) as z:
        assert "uvs_0" in z.files and "uvs_1" not in z.files
    assert json.loads(json.dumps(doc))  # plain JSON


def test_the_input_texture_is_one_white_pixel():
    """The bench's literal PNG is what the fixture writer makes of one white RGBA pixel, and reads
    back as one."""
    import io

    from PIL import Image

    from tests.support.fixtures import png_bytes

    assert A.WHITE_PNG == png_bytes(np.full((1, 1, 4), 255, np.uint8))
    img = Image.open(io.BytesIO(A.WHITE_PNG))
    assert img.size == (1, 1) and img.mode == "RGBA" and img.getpixel((0, 0)) == (255, 255, 255, 255)
