"""Tangents from the source (glTF ``TANGENT``): read under the node transforms (mapped by the
node's matrix, w flipped where it mirrors), carried into the container (version 4.0) and written
back by ``lopcook decode``; a TANGENT without NORMAL is dropped with a warning;
a USD ``primvars:tangents`` likewise."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from lopcook.cli import main
from lopcook.emit.gltf_writer import write_gltf
from lopcook.ingest import load
from lopcook.lop.codecs.normals_oct import normal_error_deg
from lopcook.lop.container import read


def grid(k: int = 6):
    """A k x k grid over the xz plane, bent (y = u v / 4: not flat, so that copies of it are found),
    normals +Y, UVs, tangents along +X with w alternating."""
    u, v = np.meshgrid(np.linspace(0, 1, k), np.linspace(0, 1, k))
    pos = np.stack([u.ravel(), 0.25 * (u * v).ravel(), v.ravel()], axis=1).astype(np.float32)
    tri = [[r * k + c, (r + 1) * k + c, r * k + c + 1] for r in range(k - 1) for c in range(k - 1)]
    tri += [[r * k + c + 1, (r + 1) * k + c, (r + 1) * k + c + 1] for r in range(k - 1) for c in range(k - 1)]
    tangents = np.tile([1.0, 0.0, 0.0, 1.0], (k * k, 1)).astype(np.float32)
    tangents[::2, 3] = -1.0
    return {"name": "grid", "positions": pos, "indices": np.asarray(tri, np.uint32),
            "normals": np.tile([0.0, 1.0, 0.0], (k * k, 1)).astype(np.float32),
            "uvs": np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float32), "tangents": tangents}


@pytest.fixture
def source(tmp_path):
    """Three placements of the grid: as it is, mirrored in x and turned 90 degrees about y, and
    turned and scaled (a copy that ``cook`` stores once, with a transform)."""
    path = tmp_path / "tangents.gltf"
    q = [0.0, np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)]
    write_gltf(str(path), [grid()], nodes=[{"name": "plain", "mesh": 0},
                                           {"name": "mirrored", "mesh": 0, "translation": [3.0, 0.0, 0.0],
                                            "rotation": q, "scale": [-1.0, 1.0, 1.0]},
                                           {"name": "turned", "mesh": 0, "translation": [0.0, 0.0, 5.0],
                                            "rotation": q, "scale": [2.0, 2.0, 2.0]}])
    return path


def test_tangents_are_mapped_by_the_node_and_flip_where_it_mirrors(source):
    plain, mirrored, turned = load(str(source)).parts
    g = grid()
    np.testing.assert_allclose(plain.attributes["tangents"], g["tangents"], atol=1e-7)
    # x -> -x, then 90 degrees about +y: (1, 0, 0) -> (-1, 0, 0) -> (0, 0, 1)
    np.testing.assert_allclose(mirrored.attributes["tangents"][:, :3], np.tile([0.0, 0.0, 1.0], (36, 1)), atol=1e-6)
    np.testing.assert_array_equal(mirrored.attributes["tangents"][:, 3], -g["tangents"][:, 3])
    # 90 degrees about +y: (1, 0, 0) -> (0, 0, -1); no mirror, w kept
    np.testing.assert_allclose(turned.attributes["tangents"][:, :3], np.tile([0.0, 0.0, -1.0], (36, 1)), atol=1e-6)
    np.testing.assert_array_equal(turned.attributes["tangents"][:, 3], g["tangents"][:, 3])


@pytest.mark.parametrize("flags", [["--no-instances"], []])
def test_cook_stores_them_and_decode_writes_them_back(source, tmp_path, flags):
    """Both with every copy on its own and with the turned copy stored once (a placement: its
    tangents are the shared buffer's, mapped by the placement's matrix when decoded)."""
    out, glb = tmp_path / "t.lop", tmp_path / "t.glb"
    assert main(["-q", "cook", str(source), "-o", str(out), *flags]) == 0
    c = read(str(out))
    assert any("placement" in p for p in c.manifest["parts"]) == (not flags)
    assert c.data[4:6] == bytes([4, 0])  # container 4.0: a part holds tangents
    bits = c.manifest["parts"][0]["attribute_bits"]["tangents"]
    assert main(["-q", "decode", str(out), "--level", "24", "--source", str(source), "-o", str(glb)]) == 0
    data = glb.read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    prims = [m["primitives"][0] for m in doc["meshes"]]
    assert all("TANGENT" in p["attributes"] for p in prims)
    bin_start = 20 + jlen + 8
    got = []
    for p in prims:
        acc = doc["accessors"][p["attributes"]["TANGENT"]]
        view = doc["bufferViews"][acc["bufferView"]]
        start = bin_start + view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        got.append(np.frombuffer(data, "<f4", acc["count"] * 4, start).reshape(-1, 4))
    src = load(str(source)).parts
    for t, part in zip(got, src):
        want = part.attributes["tangents"]
        # the decoded vertex order is binned: compare as sets of rows, angle within the codec's bound
        assert sorted(map(tuple, np.round(t[:, 3:], 6))) == sorted(map(tuple, np.round(want[:, 3:], 6)))
        cos = np.clip((t[:, :3].astype(np.float64) @ want[:, :3].T).max(axis=1), -1.0, 1.0)
        assert np.degrees(np.arccos(cos)).max() <= normal_error_deg(bits) + 1e-3


def test_tangent_without_normal_is_dropped_with_a_warning(tmp_path, capsys):
    path = tmp_path / "nonormal.gltf"
    doc_path = tmp_path / "with.gltf"
    write_gltf(str(doc_path), [grid()])
    doc = json.loads(doc_path.read_text())
    prim = doc["meshes"][0]["primitives"][0]
    del prim["attributes"]["NORMAL"]
    path.write_text(json.dumps(doc))
    (tmp_path / "nonormal.bin").write_bytes((tmp_path / "with.bin").read_bytes())
    doc["buffers"][0]["uri"] = "nonormal.bin"
    path.write_text(json.dumps(doc))
    scene = load(str(path))
    assert "tangents" not in scene.parts[0].attributes
    assert any("tangents without normals" in w for w in scene.warnings)


def _usda(path, tangents_type: str, tangents: str, normals: bool = True) -> None:
    """A quad (two triangles) in the xz plane, normals +Y, tangents as given, under two prims:
    one as it is and one mirrored in x (scale -1, 1, 1)."""
    n = 'normal3f[] normals = [(0, 1, 0), (0, 1, 0), (0, 1, 0), (0, 1, 0)] (interpolation = "vertex")' \
        if normals else ""
    mesh = f'''
        def Mesh "quad" {{
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0)]
            {n}
            {tangents_type} primvars:tangents = [{tangents}] (interpolation = "vertex")
        }}'''
    path.write_text(f'''#usda 1.0
(
    upAxis = "Y"
    metersPerUnit = 1
)
def Xform "plain" {{{mesh}
}}
def Xform "mirrored" {{
    double3 xformOp:scale = (-1, 1, 1)
    double3 xformOp:translate = (3, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]{mesh}
}}
''')


def test_a_usd_tangents_primvar_is_read_as_glTF_tangents(tmp_path):
    """float4 (xyz, w) as glTF's TANGENT, float3 with handedness +1 (both made unit); under a mirroring transform
    xyz is mapped and w flipped, as for glTF nodes."""
    path = tmp_path / "t.usda"
    _usda(path, "float4[]", "(1, 0, 0, 1), (1, 0, 0, -1), (1, 0, 0, 1), (1, 0, 0, -1)")
    plain, mirrored = load(str(path)).parts
    ws = sorted(plain.attributes["tangents"][:, 3])
    assert ws == [-1.0, -1.0, 1.0, 1.0]
    np.testing.assert_allclose(plain.attributes["tangents"][:, :3], np.tile([1.0, 0.0, 0.0], (4, 1)))
    np.testing.assert_allclose(mirrored.attributes["tangents"][:, :3], np.tile([-1.0, 0.0, 0.0], (4, 1)))
    # each vertex's w flips: pair them by position (the mirror maps x to 3 - x)
    key = lambda p: [tuple(np.round(r, 6)) for r in p]  # noqa: E731
    w_plain = dict(zip(key(plain.positions * [-1, 1, 1] + [3, 0, 0]), plain.attributes["tangents"][:, 3]))
    assert all(w_plain[k] == -w for k, w in zip(key(mirrored.positions), mirrored.attributes["tangents"][:, 3]))

    _usda(path, "float3[]", "(0, 0, 2), (0, 0, 2), (0, 0, 2), (0, 0, 2)")
    plain, _ = load(str(path)).parts
    np.testing.assert_allclose(plain.attributes["tangents"], np.tile([0.0, 0.0, 1.0, 1.0], (4, 1)))  # made unit


def test_a_usd_tangents_primvar_without_normals_is_dropped_with_a_warning(tmp_path):
    path = tmp_path / "t.usda"
    _usda(path, "float4[]", "(1, 0, 0, 1), (1, 0, 0, 1), (1, 0, 0, 1), (1, 0, 0, 1)", normals=False)
    scene = load(str(path))
    assert all("tangents" not in p.attributes or p.attributes["tangents"] is None for p in scene.parts)
    assert sum("tangents without normals" in w for w in scene.warnings) == 2


def test_a_usd_tangents_primvar_of_another_type_is_ignored_with_a_warning(tmp_path):
    path = tmp_path / "t.usda"
    _usda(path, "token[]", '"a", "b", "c", "d"')
    scene = load(str(path))
    assert all(p.attributes.get("tangents") is None for p in scene.parts)
    assert sum("primvars:tangents has type token[]" in w for w in scene.warnings) == 2
