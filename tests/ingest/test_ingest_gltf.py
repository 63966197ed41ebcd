"""glTF/GLB ingest: synthetic files built here (JSON + binary with numpy/struct) and the corpus."""

from __future__ import annotations

import base64
import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from lopcook.errors import LopcookError
from lopcook.ingest import gltf as gltf_loader
from lopcook.ingest import load
from lopcook.settings import DEFAULT_INGEST

FLOAT, BYTE, UBYTE, SHORT, USHORT, UINT = 5126, 5120, 5121, 5122, 5123, 5125
TRI = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # CCW seen from +Z


# ---------------------------------------------------------------------- a tiny glTF writer

class Builder:
    """Collects glTF JSON and one binary buffer; writes .gltf (external or data URI) or .glb."""

    def __init__(self) -> None:
        self.doc: dict = {"asset": {"version": "2.0"}, "bufferViews": [], "accessors": [], "meshes": [],
                          "nodes": []}
        self.bin = bytearray()

    def view(self, data: bytes, stride: int | None = None) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        bv = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if stride:
            bv["byteStride"] = stride
        self.bin += data
        self.doc["bufferViews"].append(bv)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, arr, ctype: int = FLOAT, *, normalized: bool = False, stride: int | None = None,
                 **extra) -> int:
        dtype = {FLOAT: "<f4", BYTE: "<i1", UBYTE: "<u1", SHORT: "<i2", USHORT: "<u2", UINT: "<u4"}[ctype]
        a = np.asarray(arr).astype(dtype)
        a2 = a.reshape(a.shape[0], -1)
        width = a2.shape[1]
        if stride:  # pad each element to `stride` bytes
            rows = np.zeros((a2.shape[0], stride), np.uint8)
            rows[:, :a2.itemsize * width] = np.frombuffer(a2.tobytes(), np.uint8).reshape(a2.shape[0], -1)
            data = rows.tobytes()
        else:
            data = a2.tobytes()
        acc = {"bufferView": self.view(data, stride), "componentType": ctype, "count": int(a2.shape[0]),
               "type": "SCALAR" if a.ndim == 1 else f"VEC{width}"}
        if normalized:
            acc["normalized"] = True
        acc.update(extra)
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def mesh(self, *prims: dict, name: str | None = None) -> int:
        m = {"primitives": list(prims)}
        if name:
            m["name"] = name
        self.doc["meshes"].append(m)
        return len(self.doc["meshes"]) - 1

    def prim(self, positions, indices=None, *, index_type=UINT, mode=None, **attrs) -> dict:
        p = {"attributes": {"POSITION": self.accessor(positions)}}
        for k, v in attrs.items():
            p["attributes"][k] = v if isinstance(v, int) else self.accessor(v)
        if indices is not None:
            p["indices"] = self.accessor(np.asarray(indices).reshape(-1), index_type)
        if mode is not None:
            p["mode"] = mode
        return p

    def node(self, **kw) -> int:
        self.doc["nodes"].append(kw)
        return len(self.doc["nodes"]) - 1

    def scene(self, *roots: int) -> None:
        self.doc["scenes"] = [{"nodes": list(roots)}]
        self.doc["scene"] = 0

    def _json(self, uri: str | None) -> dict:
        doc = json.loads(json.dumps(self.doc))
        buf = {"byteLength": len(self.bin)}
        if uri is not None:
            buf["uri"] = uri
        doc["buffers"] = [buf]
        return doc

    def write_gltf(self, path: Path, bin_name: str | None = "data.bin", *, data_uri: bool = False) -> Path:
        if data_uri:
            doc = self._json("data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode())
        else:
            doc = self._json(urlquote(bin_name))
            (path.parent / bin_name).write_bytes(bytes(self.bin))
        path.write_text(json.dumps(doc))
        return path

    def glb_bytes(self) -> bytes:
        return make_glb(self._json(None), bytes(self.bin))

    def write_glb(self, path: Path) -> Path:
        path.write_bytes(self.glb_bytes())
        return path


def urlquote(name: str) -> str:
    from urllib.parse import quote

    return quote(name)


def make_glb(doc: dict | bytes, binary: bytes | None, version: int = 2) -> bytes:
    js = doc if isinstance(doc, bytes) else json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    out = struct.pack("<II", len(js), 0x4E4F534A) + js
    if binary is not None:
        b = binary + b"\0" * (-len(binary) % 4)
        out += struct.pack("<II", len(b), 0x004E4942) + b
    return struct.pack("<4sII", b"glTF", version, 12 + len(out)) + out


def geometric_normals(part) -> np.ndarray:
    t = part.positions[part.indices.astype(np.int64)]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def single_triangle(b: Builder, name: str | None = "tri", **attrs) -> int:
    normals = np.tile([0.0, 0.0, 1.0], (3, 1))
    return b.mesh(b.prim(TRI, [0, 1, 2], NORMAL=normals, **attrs), name=name)


# ---------------------------------------------------------------------- transforms and instancing

def test_nested_transforms_give_known_world_positions(tmp_path):
    b = Builder()
    m = single_triangle(b)
    # child: rotate +90 deg about Y (x -> -z), then translate +1 in Y
    s = np.sqrt(0.5)
    child = b.node(mesh=m, rotation=[0.0, s, 0.0, s], translation=[0.0, 1.0, 0.0], name="child")
    # parent as a column-major matrix: uniform scale 2, translation (1, 2, 3)
    parent_matrix = [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 1, 2, 3, 1]
    root = b.node(children=[child], matrix=parent_matrix, name="root")
    b.scene(root)
    scene = load(b.write_gltf(tmp_path / "nested.gltf"))
    (part,) = scene.parts
    # (0,0,0) -> (0,1,0) -> (1,4,3); (1,0,0) -> (0,0,-1)+(0,1,0) -> (1,4,1); (0,1,0) -> (0,2,0) -> (1,6,3)
    np.testing.assert_allclose(part.positions, [[1, 4, 3], [1, 4, 1], [1, 6, 3]], atol=1e-12)
    assert part.positions.dtype == np.float64
    # +Z normal rotated by +90 about Y becomes +X; winding agrees with it
    np.testing.assert_allclose(part.normals, np.tile([1.0, 0.0, 0.0], (3, 1)), atol=1e-6)
    np.testing.assert_allclose(geometric_normals(part), [[1.0, 0.0, 0.0]], atol=1e-12)
    assert part.name == "child/tri"
    assert part.source == "node 0 'child' / mesh 0 'tri' / primitive 0"
    assert part.mesh_key == "mesh0/prim0"
    assert scene.unit_scale == 1.0 and scene.up_axis == "Y" and scene.format == "gltf"


def test_normals_use_inverse_transpose_under_nonuniform_scale(tmp_path):
    b = Builder()
    pos = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # plane x+y+z=1
    n = np.tile(np.array([1.0, 1.0, 1.0]) / np.sqrt(3), (3, 1))
    m = b.mesh(b.prim(pos, [0, 1, 2], NORMAL=n))
    b.scene(b.node(mesh=m, scale=[2.0, 1.0, 0.5]))
    (part,) = load(b.write_gltf(tmp_path / "scaled.gltf")).parts
    np.testing.assert_allclose(part.positions, pos * [2.0, 1.0, 0.5])
    expected = np.array([0.5, 1.0, 2.0]) / np.linalg.norm([0.5, 1.0, 2.0])
    np.testing.assert_allclose(part.normals, np.tile(expected, (3, 1)), atol=1e-6)
    np.testing.assert_allclose(geometric_normals(part)[0], expected, atol=1e-12)


def test_instanced_mesh_gives_one_part_per_placement(tmp_path):
    b = Builder()
    m = single_triangle(b, name="wheel")
    n1 = b.node(mesh=m, translation=[-1.0, 0.0, 0.0], name="axle")
    n2 = b.node(mesh=m, translation=[2.0, 0.5, 0.0], name="axle")
    b.scene(b.node(children=[n1, n2]))
    scene = load(b.write_gltf(tmp_path / "instanced.gltf"))
    assert len(scene.parts) == 2
    a, c = scene.parts
    assert a.mesh_key == c.mesh_key == "mesh0/prim0"
    assert [a.name, c.name] == ["axle/wheel", "axle/wheel#2"]
    np.testing.assert_allclose(a.positions, TRI + [-1.0, 0.0, 0.0])
    np.testing.assert_allclose(c.positions, TRI + [2.0, 0.5, 0.0])
    np.testing.assert_array_equal(a.indices, c.indices)
    assert a.source.startswith("node 0 'axle'") and c.source.startswith("node 1 'axle'")


@pytest.mark.parametrize("required", [False, True])
def test_gpu_instancing_places_every_instance(tmp_path, required):
    """EXT_mesh_gpu_instancing: one part per instance at node world @ T @ R @ S (ROTATION as
    normalized SHORTs), sharing the mesh; used or required alike."""
    b = Builder()
    m = single_triangle(b, name="leaf")
    t = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 0.0, -3.0]])
    s = np.sqrt(0.5)
    q = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, s, s], [0.0, 0.0, 0.0, 1.0]])  # +90 deg about Z
    sc = np.array([[1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]])
    attrs = {"TRANSLATION": b.accessor(t), "ROTATION": b.accessor(np.round(q * 32767), SHORT, normalized=True),
             "SCALE": b.accessor(sc)}
    b.scene(b.node(mesh=m, translation=[0.0, 10.0, 0.0], name="tree",
                   extensions={"EXT_mesh_gpu_instancing": {"attributes": attrs}}))
    b.doc["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    if required:
        b.doc["extensionsRequired"] = ["EXT_mesh_gpu_instancing"]
    scene = load(b.write_gltf(tmp_path / "instancing.gltf"))
    assert [p.name for p in scene.parts] == ["tree/leaf/instance0", "tree/leaf/instance1", "tree/leaf/instance2"]
    assert len({p.mesh_key for p in scene.parts}) == 1
    up = np.array([0.0, 10.0, 0.0])
    np.testing.assert_allclose(scene.parts[0].positions, TRI + up, atol=1e-12)
    rot = TRI[:, [1, 0, 2]] * [-1.0, 1.0, 1.0]  # (x, y) -> (-y, x)
    np.testing.assert_allclose(scene.parts[1].positions, rot + [5.0, 0.0, 0.0] + up, atol=1e-4)
    np.testing.assert_allclose(scene.parts[2].positions, 2.0 * TRI + [0.0, 0.0, -3.0] + up, atol=1e-12)
    assert scene.parts[1].source.endswith("/ instance 1")


def test_gpu_instancing_with_mismatched_counts_is_an_error(tmp_path):
    b = Builder()
    m = single_triangle(b)
    attrs = {"TRANSLATION": b.accessor(np.zeros((3, 3))), "SCALE": b.accessor(np.ones((2, 3)))}
    b.scene(b.node(mesh=m, extensions={"EXT_mesh_gpu_instancing": {"attributes": attrs}}))
    with pytest.raises(LopcookError) as exc:
        load(b.write_gltf(tmp_path / "bad_instancing.gltf"))
    assert "different counts" in str(exc.value)


@pytest.mark.parametrize("scale", [[-1.0, 1.0, 1.0], [1.0, 1.0, -1.0], [-1.0, -1.0, -1.0]])
def test_mirrored_transform_flips_winding(tmp_path, scale):
    b = Builder()
    m = single_triangle(b)
    b.scene(b.node(mesh=m, scale=scale))
    (part,) = load(b.write_gltf(tmp_path / "mirror.gltf")).parts
    np.testing.assert_allclose(part.positions, TRI * scale)
    expected_normal = np.array([0.0, 0.0, 1.0]) * np.sign(scale[2])  # inverse transpose of diag(scale)
    np.testing.assert_allclose(part.normals[0], expected_normal, atol=1e-6)
    # the flipped winding keeps the geometric normal on the same side as the shading normal
    np.testing.assert_allclose(geometric_normals(part)[0], expected_normal, atol=1e-12)
    np.testing.assert_array_equal(part.indices, [[2, 1, 0]])


def test_unmirrored_keeps_winding(tmp_path):
    b = Builder()
    b.scene(b.node(mesh=single_triangle(b), scale=[1.0, 2.0, 3.0]))
    (part,) = load(b.write_gltf(tmp_path / "plain.gltf")).parts
    np.testing.assert_array_equal(part.indices, [[0, 1, 2]])


def test_default_scene_selection_and_no_scenes(tmp_path):
    b = Builder()
    m = single_triangle(b)
    n0 = b.node(mesh=m, translation=[10.0, 0.0, 0.0], name="in_scene0")
    n1 = b.node(mesh=m, translation=[0.0, 10.0, 0.0], name="in_scene1")
    b.doc["scenes"] = [{"nodes": [n0]}, {"nodes": [n1]}]
    b.doc["scene"] = 1
    (part,) = load(b.write_gltf(tmp_path / "scenes.gltf")).parts
    assert part.name == "in_scene1/tri"
    # without scenes every root node is drawn (children are reached through their parent only)
    del b.doc["scenes"], b.doc["scene"]
    b.node(children=[n0], name="parent")
    scene = load(b.write_gltf(tmp_path / "noscene.gltf"))
    assert sorted(p.name for p in scene.parts) == ["in_scene0/tri", "in_scene1/tri"]


# ---------------------------------------------------------------------- KHR_mesh_quantization

def test_quantized_short_positions_and_node_dequantization(tmp_path, rng):
    b = Builder()
    q = rng.integers(-32767, 32768, size=(40, 3)).astype(np.int16)
    q[0] = [-32768, 0, 32767]  # -32768 clamps to -1
    idx = np.arange(39).reshape(13, 3)
    normals_q = np.array([[0, 0, 127]] * 40, dtype=np.int8)
    normals_q[1] = [-128, 0, 0]  # -> (-1, 0, 0)
    uv_q = rng.integers(0, 256, size=(40, 2)).astype(np.uint8)
    prim = {"attributes": {
        "POSITION": b.accessor(q, SHORT, normalized=True, stride=8),  # padded to 4-byte alignment
        "NORMAL": b.accessor(normals_q, BYTE, normalized=True, stride=4),
        "TEXCOORD_0": b.accessor(uv_q, UBYTE, normalized=True, stride=4)},
        "indices": b.accessor(idx.reshape(-1), USHORT)}
    m = b.mesh(prim, name="q")
    scale, offset = np.array([3.0, 0.5, 2.0]), np.array([1.0, -2.0, 0.25])
    b.scene(b.node(mesh=m, scale=scale.tolist(), translation=offset.tolist()))
    b.doc["extensionsUsed"] = ["KHR_mesh_quantization"]
    b.doc["extensionsRequired"] = ["KHR_mesh_quantization"]
    scene = load(b.write_glb(tmp_path / "quant.glb"))
    (part,) = scene.parts
    expected = np.maximum(q / 32767.0, -1.0) * scale + offset
    np.testing.assert_allclose(part.positions, expected, atol=1e-6, rtol=0)
    assert part.positions[0, 0] == pytest.approx(-1.0 * 3.0 + 1.0, abs=1e-12)
    assert part.n_vertices == 40  # vertex 39 is unused but kept
    np.testing.assert_allclose(part.uvs, uv_q / 255.0, atol=1e-6)
    np.testing.assert_allclose(part.normals[0], [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(part.normals[1], [-1, 0, 0], atol=1e-6)
    assert scene.format == "glb"


def test_quantized_without_extension_listed_and_nonnormalized(tmp_path):
    b = Builder()
    q = np.array([[0, 0, 0], [100, 0, 0], [0, 200, 0], [7, 7, 7]], dtype=np.uint16)
    uv16 = np.array([[0, 65535], [65535, 0], [32768, 16384], [1, 2]], dtype=np.uint16)
    uvs_plain = np.array([[0, 1], [2, 3], [4, 5], [6, 7]], dtype=np.int16)
    m = b.mesh({"attributes": {"POSITION": b.accessor(q, USHORT, stride=8),
                               "TEXCOORD_0": b.accessor(uv16, USHORT, normalized=True),
                               "TEXCOORD_1": b.accessor(uvs_plain, SHORT)},
                "indices": b.accessor(np.array([0, 1, 2], np.uint8), UBYTE)})
    b.scene(b.node(mesh=m, scale=[0.01, 0.01, 0.01]))
    (part,) = load(b.write_gltf(tmp_path / "quant_plain.gltf")).parts
    np.testing.assert_allclose(part.positions, q * 0.01, atol=1e-12)
    np.testing.assert_allclose(part.uvs, uv16 / 65535.0, atol=1e-7)
    assert part.normals_computed and part.n_vertices == 4


def test_quantized_positions_need_normalized_decoding_trimesh_does_not(tmp_path):
    """Documents why the reader is our own: trimesh 5.2.0 ignores `normalized`."""
    import trimesh  # a dependency of lopcook: missing is a failure, not a skip
    b = Builder()
    q = np.array([[0, 0, 0], [32767, 0, 0], [0, 32767, 0]], dtype=np.int16)
    m = b.mesh({"attributes": {"POSITION": b.accessor(q, SHORT, normalized=True, stride=8)},
                "indices": b.accessor(np.array([0, 1, 2], np.uint16), USHORT)})
    b.scene(b.node(mesh=m))
    path = b.write_glb(tmp_path / "q.glb")
    (part,) = load(path).parts
    assert part.positions.max() == pytest.approx(1.0)
    tm = trimesh.load(path, force="scene")
    assert np.asarray(tm.bounds).max() > 100.0  # raw integers, not dequantized


# ---------------------------------------------------------------------- buffers

def test_data_uri_and_external_bin_and_glb_agree(tmp_path):
    def build():
        b = Builder()
        m = single_triangle(b, TEXCOORD_0=np.array([[0, 0], [1, 0], [0, 1]], float))
        b.scene(b.node(mesh=m, translation=[0.0, 0.0, 5.0]))
        return b

    (tmp_path / "sub dir").mkdir()
    ext = load(build().write_gltf(tmp_path / "sub dir" / "ext.gltf", bin_name="my data.bin"))
    uri = load(build().write_gltf(tmp_path / "uri.gltf", data_uri=True))
    glb = load(build().write_glb(tmp_path / "bin.glb"))
    for s in (uri, glb):
        np.testing.assert_array_equal(s.parts[0].positions, ext.parts[0].positions)
        np.testing.assert_array_equal(s.parts[0].uvs, ext.parts[0].uvs)
        np.testing.assert_array_equal(s.parts[0].indices, ext.parts[0].indices)
    np.testing.assert_allclose(ext.parts[0].positions, TRI + [0, 0, 5])


def test_gltf_extension_holding_glb_bytes(tmp_path):
    b = Builder()
    b.scene(b.node(mesh=single_triangle(b)))
    path = tmp_path / "actually_binary.gltf"
    path.write_bytes(b.glb_bytes())
    scene = load(path)
    assert scene.format == "glb" and len(scene.parts) == 1


def test_sparse_accessor(tmp_path):
    b = Builder()
    base = np.zeros((4, 3))
    bv_idx = b.view(np.array([1, 3], np.uint16).tobytes())
    bv_val = b.view(np.array([[1, 0, 0], [0, 1, 0]], np.float32).tobytes())
    pos = b.accessor(base, sparse={"count": 2, "indices": {"bufferView": bv_idx, "componentType": USHORT},
                                   "values": {"bufferView": bv_val}})
    # also an accessor without a bufferView: zeros plus sparse values
    b.doc["accessors"].append({"componentType": FLOAT, "count": 4, "type": "VEC3",
                               "sparse": {"count": 2, "indices": {"bufferView": bv_idx, "componentType": USHORT},
                                          "values": {"bufferView": bv_val}}})
    pos2 = len(b.doc["accessors"]) - 1
    idx = b.accessor(np.array([0, 1, 3], np.uint32), UINT)
    nrm = b.accessor(np.tile([0.0, 0.0, 1.0], (4, 1)))  # given normals: vertex order stays as in the file
    m = b.mesh({"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": idx},
               {"attributes": {"POSITION": pos2, "NORMAL": nrm}, "indices": idx})
    b.scene(b.node(mesh=m))
    scene = load(b.write_gltf(tmp_path / "sparse.gltf"))
    expected = [[0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 1, 0]]
    for part in scene.parts:
        np.testing.assert_array_equal(part.positions, expected)
    assert [p.name for p in scene.parts] == ["node0/mesh0/prim0", "node0/mesh0/prim1"]


# ---------------------------------------------------------------------- topology and attributes

def test_triangle_strip_and_fan(tmp_path):
    b = Builder()
    strip = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]], float)
    fan = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 1, 0]], float)
    m = b.mesh(b.prim(strip, [1, 0, 3, 2, 5, 4], index_type=UBYTE, mode=5), b.prim(fan, mode=6))
    b.scene(b.node(mesh=m))
    s_part, f_part = load(b.write_gltf(tmp_path / "stripfan.gltf")).parts
    assert s_part.n_triangles == 4 and f_part.n_triangles == 3
    # strip 1,0,3,2,5,4 -> (1,0,3), (0,2,3) [odd: i, i+2, i+1], (3,2,5), (2,4,5)
    np.testing.assert_array_equal(s_part.indices, [[1, 0, 3], [0, 2, 3], [3, 2, 5], [2, 4, 5]])
    np.testing.assert_array_equal(f_part.indices, [[1, 2, 0], [2, 3, 0], [3, 4, 0]])
    for part in (s_part, f_part):  # every triangle faces the same way (+Z here)
        np.testing.assert_allclose(geometric_normals(part), np.tile([0, 0, 1.0], (part.n_triangles, 1)), atol=1e-12)


def test_non_indexed_primitive_and_unused_vertices_kept(tmp_path):
    b = Builder()
    pos = np.vstack([TRI, TRI + [0, 0, 1]])
    extra = np.vstack([TRI, [[5.0, 5.0, 5.0]]])  # vertex 3 unused by the indices
    m = b.mesh(b.prim(pos), b.prim(extra, [0, 1, 2]))
    b.scene(b.node(mesh=m))
    a, c = load(b.write_gltf(tmp_path / "nonindexed.gltf")).parts
    np.testing.assert_array_equal(a.indices, [[0, 1, 2], [3, 4, 5]])
    assert c.n_vertices == 4  # no welding, no dropping


def test_duplicate_positions_are_not_welded(tmp_path):
    b = Builder()
    pos = np.vstack([TRI, TRI])  # two identical triangles, 6 vertices
    n = np.tile([0.0, 0.0, 1.0], (6, 1))
    m = b.mesh(b.prim(pos, [0, 1, 2, 3, 4, 5], NORMAL=n))
    b.scene(b.node(mesh=m))
    (part,) = load(b.write_gltf(tmp_path / "dups.gltf")).parts
    assert part.n_vertices == 6


def test_color_0_ubyte_normalized_and_ushort_rgba(tmp_path):
    b = Builder()
    rgb = np.array([[255, 0, 0], [0, 128, 0], [0, 0, 51]], np.uint8)
    rgba = np.array([[65535, 0, 0, 32768], [0, 65535, 0, 65535], [0, 0, 0, 0]], np.uint16)
    c3 = b.accessor(rgb, UBYTE, normalized=True, stride=4)
    c4 = b.accessor(rgba, USHORT, normalized=True)
    m = b.mesh({"attributes": {"POSITION": b.accessor(TRI), "COLOR_0": c3}},
               {"attributes": {"POSITION": b.accessor(TRI), "COLOR_0": c4}})
    b.scene(b.node(mesh=m))
    a, c = load(b.write_gltf(tmp_path / "colors.gltf")).parts
    assert a.colors.shape == (3, 4) and a.colors.dtype == np.float32
    np.testing.assert_allclose(a.colors[:, :3], rgb / 255.0, atol=1e-7)
    np.testing.assert_array_equal(a.colors[:, 3], 1.0)
    np.testing.assert_allclose(c.colors, rgba / 65535.0, atol=1e-7)


def test_color_0_integers_without_normalized_are_read_as_normalized_with_a_warning(tmp_path):
    b = Builder()
    rgb = np.array([[255, 0, 0], [0, 128, 0], [0, 0, 51]], np.uint8)
    m = b.mesh({"attributes": {"POSITION": b.accessor(TRI), "COLOR_0": b.accessor(rgb, UBYTE, stride=4)}})
    b.scene(b.node(mesh=m))
    scene = load(b.write_gltf(tmp_path / "colors_unnormalized.gltf"))
    np.testing.assert_allclose(scene.parts[0].colors[:, :3], rgb / 255.0, atol=1e-7)
    assert any("COLOR_0 accessor" in w and "without normalized" in w for w in scene.warnings)


def test_positions_far_beyond_the_limit_give_the_position_error(tmp_path):
    """1e300 m: the coordinate limit's message, not an overflow in the normals computed for it."""
    b = Builder()
    m = b.mesh(b.prim(TRI, [0, 1, 2]))
    b.scene(b.node(mesh=m, scale=[1e300, 1e300, 1e300]))
    with pytest.raises(LopcookError) as exc:
        load(b.write_gltf(tmp_path / "far.gltf"))
    assert "from the origin, beyond the" in str(exc.value)


def test_points_and_lines_skipped_with_warning(tmp_path):
    b = Builder()
    m = b.mesh(b.prim(TRI, mode=0), b.prim(TRI, [0, 1, 1, 2], mode=1), b.prim(TRI, [0, 1, 2]))
    b.scene(b.node(mesh=m))
    scene = load(b.write_gltf(tmp_path / "mixed.gltf"))
    assert [p.name for p in scene.parts] == ["node0/mesh0/prim2"]
    assert any("POINTS" in w for w in scene.warnings) and any("LINES" in w for w in scene.warnings)


def test_lines_only_scene_is_empty_then_rejected(tmp_path):
    b = Builder()
    b.scene(b.node(mesh=b.mesh(b.prim(TRI, [0, 1, 1, 2], mode=1))))
    path = b.write_gltf(tmp_path / "lines_only.gltf")
    scene = gltf_loader.load(str(path), fmt="gltf", settings=DEFAULT_INGEST)
    assert scene.parts == ()
    with pytest.raises(LopcookError, match="no triangle meshes") as exc:
        load(path)
    assert "lines_only.gltf" in str(exc.value)


def test_missing_normals_are_computed(tmp_path):
    b = Builder()
    b.scene(b.node(mesh=b.mesh(b.prim(TRI, [0, 1, 2]))))
    (part,) = load(b.write_gltf(tmp_path / "nonormals.gltf")).parts
    assert part.normals_computed
    np.testing.assert_allclose(part.normals, np.tile([0, 0, 1.0], (3, 1)), atol=1e-6)


# ---------------------------------------------------------------------- textures

def png_bytes(color=(255, 0, 0)) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 2), color).save(buf, format="PNG")
    return buf.getvalue()


def test_textures_shared_missing_and_embedded(tmp_path):
    b = Builder()
    (tmp_path / "albedo.png").write_bytes(png_bytes())
    emb = b.view(png_bytes((0, 0, 255)))
    b.doc["images"] = [{"uri": "albedo.png"}, {"uri": "missing.png"}, {"bufferView": emb, "mimeType": "image/png"},
                       {"uri": "https://example.com/remote.png"}]
    b.doc["textures"] = [{"source": 0}, {"source": 1}, {"source": 2}, {"source": 0}, {"source": 3}]
    b.doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": i}}} for i in range(5)] + [{}]
    uv = np.array([[0, 0], [1, 0], [0, 1]], float)
    prims = [dict(b.prim(TRI, [0, 1, 2], TEXCOORD_0=uv), material=i) for i in range(6)]
    b.scene(b.node(mesh=b.mesh(*prims)))
    scene = load(b.write_gltf(tmp_path / "tex.gltf"))
    t = [p.texture for p in scene.parts]
    assert t[0].name == "albedo.png" and t[0].image().size == (4, 2)
    assert t[3] is t[0]  # one Texture object per image
    assert t[1] is None and any("missing.png" in w for w in scene.warnings)
    assert t[2].name == "<embedded 2>" and t[2].image().getpixel((0, 0)) == (0, 0, 255)
    assert t[4] is None and any("remote.png" in w for w in scene.warnings)
    assert t[5] is None
    assert all(p.uvs is not None for p in scene.parts)


def test_a_texture_transform_is_reported_not_silently_ignored(tmp_path):
    b = Builder()
    (tmp_path / "albedo.png").write_bytes(png_bytes())
    b.doc["images"] = [{"uri": "albedo.png"}]
    b.doc["textures"] = [{"source": 0}]
    ref = {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [4.0, 4.0]}}}
    b.doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": ref}}]
    uv = np.array([[0, 0], [1, 0], [0, 1]], float)
    b.scene(b.node(mesh=b.mesh(dict(b.prim(TRI, [0, 1, 2], TEXCOORD_0=uv), material=0))))
    scene = load(b.write_gltf(tmp_path / "transformed.gltf"))
    np.testing.assert_allclose(scene.parts[0].uvs, uv)  # cooked as stored
    assert any("KHR_texture_transform" in w and "not applied" in w for w in scene.warnings)


# ---------------------------------------------------------------------- errors

def valid_builder() -> Builder:
    b = Builder()
    b.scene(b.node(mesh=single_triangle(b)))
    return b


def _err(path, fmt=None) -> LopcookError:
    with pytest.raises(LopcookError) as exc:
        if fmt:
            gltf_loader.load(str(path), fmt=fmt, settings=DEFAULT_INGEST)
        else:
            load(path)
    err = exc.value
    assert err.stage == "ingest" and err.exit_code == 2
    assert Path(path).name in str(err), str(err)
    return err


def test_error_invalid_json(tmp_path):
    p = tmp_path / "badjson.gltf"
    p.write_text('{"asset": {"version": "2.0"}, "nodes": [,]}')
    assert "invalid JSON at line 1" in _err(p).message


def test_error_json_not_object_and_gltf1(tmp_path):
    p = tmp_path / "list.gltf"
    p.write_text("[1, 2]")
    assert "not an object" in _err(p, fmt="gltf").message
    p = tmp_path / "old.gltf"
    p.write_text('{"asset": {"version": "1.0"}}')
    assert "version 1.0" in _err(p).message


@pytest.mark.parametrize("case,expect", [
    ("magic", "bad GLB magic"),
    ("version", "GLB version 1"),
    ("length", "declares"),
    ("short", "header truncated"),
    ("chunk", "chunk 1 declares"),
    ("first_chunk", "expected JSON"),
    ("no_bin", "has none"),
])
def test_error_bad_glb(tmp_path, case, expect):
    data = bytearray(valid_builder().glb_bytes())
    if case == "magic":
        data[:4] = b"gLTF"
    elif case == "version":
        data[4:8] = struct.pack("<I", 1)
    elif case == "length":
        data = data[:-8]  # file shorter than the header says
    elif case == "short":
        data = data[:10]
    elif case == "chunk":
        js_len = struct.unpack_from("<I", data, 12)[0]
        pos = 20 + js_len
        data[pos:pos + 4] = struct.pack("<I", 10**6)
    elif case == "first_chunk":
        data[16:20] = struct.pack("<I", 0x004E4942)
    elif case == "no_bin":
        js_len = struct.unpack_from("<I", data, 12)[0]
        data = data[:20 + js_len]
        data[8:12] = struct.pack("<I", len(data))
    p = tmp_path / f"broken_{case}.glb"
    p.write_bytes(bytes(data))
    err = _err(p, fmt="glb")
    assert expect in err.message, err.message


def test_error_truncated_external_buffer(tmp_path):
    p = valid_builder().write_gltf(tmp_path / "trunc.gltf", bin_name="trunc.bin")
    bin_path = tmp_path / "trunc.bin"
    bin_path.write_bytes(bin_path.read_bytes()[:-10])
    err = _err(p)
    assert "buffer 0 is truncated" in err.message and "trunc.bin" in err.message


def test_error_accessor_past_buffer_view(tmp_path):
    b = valid_builder()
    b.doc["accessors"][0]["count"] = 1000
    err = _err(b.write_gltf(tmp_path / "pastview.gltf"))
    assert "accessor 0 reads past the end of bufferView 0" in err.message


def test_error_buffer_view_past_buffer(tmp_path):
    b = valid_builder()
    b.doc["bufferViews"][0]["byteLength"] = 10**6
    err = _err(b.write_glb(tmp_path / "pastbuf.glb"))
    assert "bufferView 0" in err.message and "runs past the end of buffer 0" in err.message


def test_error_missing_external_bin(tmp_path):
    p = valid_builder().write_gltf(tmp_path / "nobin.gltf", bin_name="gone.bin")
    (tmp_path / "gone.bin").unlink()
    err = _err(p)
    assert "gone.bin" in err.message and "not found" in err.message


def test_error_index_out_of_range(tmp_path):
    b = Builder()
    b.scene(b.node(mesh=b.mesh(b.prim(TRI, [0, 1, 2]), b.prim(TRI, [0, 1, 7]))))
    err = _err(b.write_gltf(tmp_path / "oob.gltf"))
    assert "mesh 0 primitive 1" in err.message
    assert "index 7 out of range" in err.message and "3 vertices" in err.message


def test_error_index_count_not_multiple_of_3(tmp_path):
    b = Builder()
    b.scene(b.node(mesh=b.mesh(b.prim(TRI, [0, 1, 2, 0]))))
    err = _err(b.write_gltf(tmp_path / "notmult.gltf"))
    assert "4 indices" in err.message and "not a multiple of 3" in err.message
    assert err.hint and "triangulated" in err.hint


@pytest.mark.parametrize("ctype", [5124, 5130, "FLOAT"])
def test_error_unsupported_component_type(tmp_path, ctype):
    b = valid_builder()
    b.doc["accessors"][0]["componentType"] = ctype
    err = _err(b.write_gltf(tmp_path / "ctype.gltf"))
    assert "unsupported componentType" in err.message and "accessor 0" in err.message


def test_error_uint_positions_and_float_indices(tmp_path):
    b = Builder()
    m = b.mesh({"attributes": {"POSITION": b.accessor(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), UINT)}})
    b.scene(b.node(mesh=m))
    assert "POSITION cannot use" in _err(b.write_gltf(tmp_path / "uintpos.gltf")).message
    b = Builder()
    m = b.mesh({"attributes": {"POSITION": b.accessor(TRI)}, "indices": b.accessor(np.array([0.0, 1.0, 2.0]))})
    b.scene(b.node(mesh=m))
    assert "indices accessor 1 must be SCALAR" in _err(b.write_gltf(tmp_path / "floatidx.gltf")).message


def test_error_nan_positions_names_accessor(tmp_path):
    b = Builder()
    pos = TRI.copy()
    pos[1, 2] = np.nan
    b.scene(b.node(mesh=b.mesh(b.prim(pos, [0, 1, 2]))))
    err = _err(b.write_gltf(tmp_path / "nan.gltf"))
    assert "POSITION accessor 0" in err.message and "NaN or Inf" in err.message


@pytest.mark.parametrize("ext", ["KHR_draco_mesh_compression", "EXT_meshopt_compression", "EXT_made_up"])
def test_error_unsupported_required_extension(tmp_path, ext):
    b = valid_builder()
    b.doc["extensionsUsed"] = [ext, "KHR_mesh_quantization"]
    b.doc["extensionsRequired"] = ["KHR_mesh_quantization", ext]
    err = _err(b.write_glb(tmp_path / "compressed.glb"))
    assert ext in err.message
    if ext != "EXT_made_up":
        assert "decompress" in err.hint and "gltf-transform" in err.hint


def test_supported_required_extensions_load(tmp_path):
    b = valid_builder()
    b.doc["extensionsRequired"] = ["KHR_mesh_quantization", "KHR_materials_unlit"]
    assert len(load(b.write_glb(tmp_path / "ok.glb")).parts) == 1


@pytest.mark.parametrize("mutate,expect", [
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(POSITION=99), "accessor 99"),
    (lambda d: d["accessors"][0].pop("count"), "accessor 0 lacks the required property 'count'"),
    (lambda d: d["bufferViews"][1].pop("byteLength"), "bufferView 1 lacks the required property"),
    (lambda d: d["nodes"][0].update(mesh=-1), "mesh -1"),
    (lambda d: d["nodes"][0].update(children=[0]), "reached twice"),
    (lambda d: d["nodes"][0].update(rotation=[0, 0, 0]), "3/4/3"),
    (lambda d: d["nodes"][0].update(matrix=[1, 0, 0]), "16"),
    (lambda d: d.update(scene=4), "scene 4"),
    (lambda d: d["meshes"][0]["primitives"][0].update(mode=9), "invalid mode"),
    (lambda d: d["accessors"][0].update(type="MAT4"), "MAT4"),
    (lambda d: d["bufferViews"][0].update(byteStride=4), "byteStride 4"),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(NORMAL=2), "NORMAL accessor 2"),
    (lambda d: d.update(meshes="nope"), "mesh 0"),
])
def test_error_malformed_structure(tmp_path, mutate, expect):
    b = valid_builder()
    mutate(b.doc)
    err = _err(b.write_gltf(tmp_path / "malformed.gltf"))
    assert expect in err.message, err.message


def test_error_bad_data_uri(tmp_path):
    b = valid_builder()
    p = tmp_path / "baduri.gltf"
    doc = b._json("data:application/octet-stream,notbase64")
    p.write_text(json.dumps(doc))
    assert "not base64" in _err(p).message


def test_corrupted_files_never_raise_other_exceptions(tmp_path, rng):
    b = Builder()
    m = b.mesh(b.prim(np.vstack([TRI, TRI + 1]), [0, 1, 2, 3, 4, 5], NORMAL=np.tile([0, 0, 1.0], (6, 1)),
                      TEXCOORD_0=np.zeros((6, 2))), name="m")
    b.scene(b.node(mesh=m, children=[b.node(mesh=m, translation=[1, 2, 3])]))
    good = b.glb_bytes()
    js_len = struct.unpack_from("<I", good, 12)[0]
    p = tmp_path / "fuzz.glb"
    outcomes = {"ok": 0, "error": 0}
    for trial in range(300):
        data = bytearray(good)
        if trial % 3 == 0:
            data = data[: int(rng.integers(0, len(data)))]
        else:
            lo, hi = (20, 20 + js_len) if trial % 3 == 1 else (0, len(data))
            for pos in rng.integers(lo, hi, size=int(rng.integers(1, 4))):
                data[pos] = int(rng.integers(0, 256)) if trial % 2 else data[pos] ^ 0x01
        p.write_bytes(bytes(data))
        try:
            load(p)
            outcomes["ok"] += 1
        except LopcookError as exc:
            assert "fuzz.glb" in str(exc)
            outcomes["error"] += 1
    assert outcomes["error"] > 50


# ---------------------------------------------------------------------- corpus

def _check_common(scene, meta):
    scene.validate()
    np.testing.assert_allclose(scene.bounds(), meta["bounds"], atol=1e-4)
    for part in scene.parts:
        assert part.normals is not None and not part.normals_computed
        np.testing.assert_allclose(np.linalg.norm(part.normals, axis=1), 1.0, atol=1e-5)
    assert scene.unit_scale == 1.0 and scene.up_axis == "Y"


def test_corpus_damaged_helmet(corpus, corpus_meta):
    name = "DamagedHelmet/DamagedHelmet.gltf"
    scene = load(corpus / name)
    meta = corpus_meta[name]
    assert len(scene.parts) == 1
    (part,) = scene.parts
    assert part.n_vertices == 14556 == meta["vertices"]
    assert part.n_triangles == 15452 == meta["triangles"]
    _check_common(scene, meta)
    assert part.uvs is not None
    assert part.texture is not None and part.texture.name == "Default_albedo.jpg"
    assert part.texture.image().size == (2048, 2048)
    # +90 deg about X: the helmet's raw accessor z range becomes world -y (symmetric), raw y becomes z
    assert scene.bounds()[1, 2] == pytest.approx(0.812845, abs=1e-5)
    assert scene.format == "gltf" and scene.warnings == ()


def test_corpus_cesium_milk_truck(corpus, corpus_meta):
    name = "CesiumMilkTruck.glb"
    scene = load(corpus / name)
    meta = corpus_meta[name]
    assert len(scene.parts) == meta["instances"] == 5
    assert len({p.mesh_key for p in scene.parts}) == meta["parts"] == 4
    assert scene.n_vertices == 3564 == meta["details"]["trimesh"]["instanced_vertices"]
    assert scene.n_triangles == 3624 == meta["details"]["trimesh"]["instanced_faces"]
    _check_common(scene, meta)
    wheels = [p for p in scene.parts if p.mesh_key == "mesh1/prim0"]
    assert len(wheels) == 2 and wheels[0].name != wheels[1].name
    assert not np.allclose(wheels[0].positions, wheels[1].positions)
    np.testing.assert_array_equal(wheels[0].indices, wheels[1].indices)
    # per unique primitive: (vertices, has uv) as corpus.json lists per trimesh geometry
    ours = sorted({p.mesh_key: (p.n_vertices, p.uvs is not None) for p in scene.parts}.values())
    theirs = sorted((g["vertices"], g["uv"]) for g in meta["details"]["trimesh"]["per_geometry"].values())
    assert ours == theirs
    textured = [p for p in scene.parts if p.texture is not None]
    assert len(textured) == 3 and len({id(p.texture) for p in textured}) == 1  # one shared image


def test_corpus_duck(corpus, corpus_meta):
    name = "Duck.glb"
    scene = load(corpus / name)
    meta = corpus_meta[name]
    (part,) = scene.parts
    assert part.n_vertices == meta["vertices"] == 2399 and part.n_triangles == meta["triangles"] == 4212
    _check_common(scene, meta)
    extent = scene.bounds()[1] - scene.bounds()[0]
    assert extent[1] == pytest.approx(1.54, abs=0.01)  # 0.01 root scale applied
    assert part.uvs is not None
    img = part.texture.image()
    assert img.format == "PNG" and img.size[0] > 0
    assert part.texture.name == "<embedded 0>"


def test_zero_scale_node_is_skipped_with_warning(tmp_path):
    b = Builder()
    m = single_triangle(b)
    b.scene(b.node(mesh=m, scale=[0.0, 0.0, 0.0], name="hidden"), b.node(mesh=m, name="shown"))
    scene = load(b.write_gltf(tmp_path / "zero.gltf"))
    assert [p.name for p in scene.parts] == ["shown/tri"]
    assert any("singular" in w for w in scene.warnings)
