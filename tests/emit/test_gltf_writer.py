"""lopcook.emit.gltf_writer: spec-conformant, deterministic, atomic glTF 2.0 output.

Files are read back three ways: with pygltflib (structure + raw buffer bytes), with lopcook's own
importer (``lopcook.ingest.load``), and with the Khronos glTF-Validator (npm ``gltf-validator``
through ``lopcook.verify.gltf_validator``), which must report 0 errors and 0 warnings. The
validator tests skip when Node.js or the package is missing, except under ``CI=true`` (where
``.ci/run`` installs it), where they fail.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from tests.support import fixtures as F
from lopcook.emit import gltf_writer as W
from lopcook.emit.gltf_writer import write_gltf
from lopcook.ingest import load
from lopcook.verify import gltf_validator as V

from conftest import FIXTURES

COMPONENT_DTYPE = {5126: "<f4", 5123: "<u2", 5125: "<u4"}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


# ---------------------------------------------------------------------------------------------
# Test meshes
# ---------------------------------------------------------------------------------------------


def _stable_unit(rng: np.random.Generator, count: int) -> np.ndarray:
    """Random float32 unit normals (mostly +Y) that lopcook's importer, which renormalises in
    float64 and rounds to float32, returns bit for bit (about 1 in 30 random float32 unit
    vectors would move by an ulp; those are redrawn)."""
    out = np.empty((count, 3), np.float32)
    todo = np.arange(count)
    while todo.size:
        v = rng.normal(size=(todo.size, 3)) + [0.0, 3.0, 0.0]
        n32 = (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)
        n64 = n32.astype(np.float64)
        again = (n64 / np.linalg.norm(n64, axis=1, keepdims=True)).astype(np.float32)
        ok = (again == n32).all(axis=1)
        out[todo[ok]] = n32[ok]
        todo = todo[~ok]
    return out


def _grid(name: str, k: int, *, normals=False, uvs=False, colors=False, seed=0, offset=(0.0, 0.0, 0.0)) -> dict:
    """A k x k vertex grid (wavy height field), 2 (k-1)^2 CCW triangles, no degenerate triangle."""
    rng = np.random.default_rng(seed)
    t = np.arange(k, dtype=np.float64) / (k - 1)
    z, x = np.meshgrid(t, t, indexing="ij")
    y = 0.1 * np.sin(6.0 * x) * np.cos(5.0 * z) + 0.01 * rng.random(x.shape)
    pos = (np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1) + offset).astype(np.float32)
    i, j = np.meshgrid(np.arange(k - 1), np.arange(k - 1), indexing="ij")
    v00 = (i * k + j).ravel()
    v01, v10, v11 = v00 + 1, v00 + k, v00 + k + 1
    tri = np.stack([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)], axis=1).reshape(-1, 3)
    mesh = {"name": name, "positions": pos, "indices": tri.astype(np.uint32)}
    if normals:
        mesh["normals"] = _stable_unit(rng, k * k)
    if uvs:
        jitter = rng.random((k * k, 2)).astype(np.float32) * np.float32(1e-3)
        mesh["uvs"] = np.stack([x.ravel(), z.ravel()], axis=1).astype(np.float32) + jitter
    if colors:
        mesh["colors"] = rng.random((k * k, 4)).astype(np.float32)
    return mesh


def _meshes() -> list[dict]:
    """Every attribute combination, a negative-coordinate mesh and one > 65535 vertices (uint32)."""
    return [
        _grid("full", 9, normals=True, uvs=True, colors=True, seed=1),
        _grid("bare", 5, seed=2, offset=(-3.0, -2.5, 1.25)),
        _grid("normals_only", 6, normals=True, seed=3),
        _grid("uvs_colors", 7, uvs=True, colors=True, seed=4, offset=(2.0, 0.0, -1.0)),
        _grid("big", 260, normals=True, uvs=True, seed=5),  # 67600 vertices
    ]


class _Obj:
    """An object-style mesh (attributes instead of dict keys) with no colors attribute at all."""

    def __init__(self, d: dict) -> None:
        self.name, self.positions, self.indices = d["name"], d["positions"], d["indices"]
        self.normals, self.uvs = d.get("normals"), d.get("uvs")


# ---------------------------------------------------------------------------------------------
# Reading back with pygltflib
# ---------------------------------------------------------------------------------------------


def _read_pygltf(path: Path):
    g = pygltflib.GLTF2().load(str(path))
    if path.suffix == ".glb":
        blob = g.binary_blob()
    else:
        uri = g.buffers[0].uri
        assert uri and "/" not in uri and "\\" not in uri and ":" not in uri, uri
        blob = (path.parent / uri).read_bytes()
    assert len(blob) >= g.buffers[0].byteLength

    def array(index: int) -> np.ndarray:
        acc = g.accessors[index]
        view = g.bufferViews[acc.bufferView]
        assert view.byteStride is None
        assert view.byteOffset % 4 == 0 and (acc.byteOffset or 0) == 0
        dtype = np.dtype(COMPONENT_DTYPE[acc.componentType])
        width = WIDTH[acc.type]
        assert view.byteLength == acc.count * width * dtype.itemsize
        data = np.frombuffer(blob, dtype, acc.count * width, view.byteOffset)
        return data.reshape(acc.count, width) if width > 1 else data

    return g, array


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_pygltflib_reads_back_exact_arrays_and_spec_structure(tmp_path, suffix):
    meshes = _meshes()
    extras = {"lop": "level B", "n": 3, "ok": True, "list": [1.5, None]}
    path = tmp_path / f"out{suffix}"
    written = write_gltf(path, meshes, generator="lopcook test", extras=extras)
    assert written == ([str(path)] if suffix == ".glb" else [str(path), str(path.with_suffix(".bin"))])
    g, array = _read_pygltf(path)

    assert g.asset.version == "2.0" and g.asset.generator == "lopcook test" and g.asset.extras == extras
    assert g.scene == 0 and len(g.scenes) == 1
    (root,) = g.scenes[0].nodes
    assert g.nodes[root].mesh is None and g.nodes[root].matrix is None and g.nodes[root].translation is None
    assert len(g.meshes) == len(g.nodes) - 1 == len(meshes) == len(g.nodes[root].children)
    assert len(g.buffers) == 1
    for k, (mesh, ni) in enumerate(zip(meshes, g.nodes[root].children)):
        node = g.nodes[ni]
        assert node.mesh == k and node.name == mesh["name"] and not node.children
        gm = g.meshes[k]
        assert gm.name == mesh["name"] and len(gm.primitives) == 1
        prim = gm.primitives[0]
        assert prim.mode == 4 and prim.material is None
        attrs = {name: idx for name, idx in prim.attributes.__dict__.items() if idx is not None}
        expected = {"POSITION": "positions", "NORMAL": "normals", "TEXCOORD_0": "uvs", "COLOR_0": "colors"}
        assert set(attrs) == {a for a, key in expected.items() if key in mesh}
        for attr, acc_index in attrs.items():
            acc = g.accessors[acc_index]
            assert acc.componentType == 5126 and acc.normalized in (None, False)
            assert acc.type == {"POSITION": "VEC3", "NORMAL": "VEC3", "TEXCOORD_0": "VEC2",
                                "COLOR_0": "VEC4"}[attr]
            assert g.bufferViews[acc.bufferView].target == 34962
            data = array(acc_index)
            assert data.tobytes() == np.ascontiguousarray(mesh[expected[attr]], "<f4").tobytes()
        pos_acc = g.accessors[attrs["POSITION"]]
        pos = mesh["positions"]
        assert pos_acc.min == pos.min(axis=0).astype(np.float64).tolist()
        assert pos_acc.max == pos.max(axis=0).astype(np.float64).tolist()
        ind_acc = g.accessors[prim.indices]
        assert ind_acc.type == "SCALAR" and g.bufferViews[ind_acc.bufferView].target == 34963
        assert ind_acc.componentType == (5125 if len(pos) > 65535 else 5123)
        assert np.array_equal(array(prim.indices).reshape(-1, 3), mesh["indices"])


def test_index_type_boundary_65535(tmp_path):
    """UNSIGNED_SHORT while every index <= 65534; an index of 65535 (restart value) -> UNSIGNED_INT."""
    n = 65536
    pos = np.stack([np.arange(n), np.arange(n) % 3, np.zeros(n)], axis=1).astype(np.float32)
    for top, component in ((65534, 5123), (65535, 5125)):
        path = tmp_path / f"i{top}.glb"
        write_gltf(path, [{"name": "m", "positions": pos, "indices": np.array([[top - 2, top - 1, top]])}])
        g, array = _read_pygltf(path)
        acc = g.accessors[g.meshes[0].primitives[0].indices]
        assert acc.componentType == component
        assert array(g.meshes[0].primitives[0].indices).tolist() == [top - 2, top - 1, top]


# ---------------------------------------------------------------------------------------------
# Reading back with lopcook's importer
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_lopcook_ingest_round_trips_exactly(tmp_path, suffix):
    meshes = _meshes()
    path = tmp_path / f"rt{suffix}"
    write_gltf(path, meshes)
    scene = load(path)
    assert scene.format == suffix[1:]
    assert len(scene.parts) == len(meshes)
    for part, mesh in zip(scene.parts, meshes):
        assert part.name == f"{mesh['name']}/{mesh['name']}"
        assert part.positions.dtype == np.float64
        assert np.array_equal(part.positions.astype(np.float32), mesh["positions"])
        assert np.array_equal(part.positions, mesh["positions"].astype(np.float64))
        assert np.array_equal(part.indices, mesh["indices"])
        if "normals" in mesh:
            assert not part.normals_computed
            assert np.array_equal(part.normals, mesh["normals"])
        else:
            assert part.normals_computed
        for key in ("uvs", "colors"):
            if key in mesh:
                assert np.array_equal(getattr(part, key), mesh[key]), key
            else:
                assert getattr(part, key) is None, key


def test_mesh_parts_and_objects_are_accepted(tmp_path):
    """MeshPart objects (float64 positions) and plain objects work like dicts."""
    cube = F.seamed_cube()[0].as_mesh_part()
    plate = _Obj(_grid("plate", 4, normals=True, uvs=True))
    path = tmp_path / "parts.gltf"
    write_gltf(path, [cube, plate])
    scene = load(path)
    a, b = scene.parts
    assert np.array_equal(a.positions, cube.positions) and np.array_equal(a.normals, cube.normals)
    assert np.array_equal(a.uvs, cube.uvs) and np.array_equal(a.indices, cube.indices)
    assert np.array_equal(b.positions.astype(np.float32), plate.positions) and b.colors is None


# ---------------------------------------------------------------------------------------------
# Determinism and atomicity
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_same_input_gives_identical_bytes(tmp_path, suffix):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first = write_gltf(tmp_path / "a" / f"x{suffix}", _meshes(), extras={"b": 1, "a": [2]})
    second = write_gltf(tmp_path / "b" / f"x{suffix}", _meshes(), extras={"a": [2], "b": 1})
    again = write_gltf(tmp_path / "a" / f"x{suffix}", _meshes(), extras={"b": 1, "a": [2]})
    assert first == again
    for p, q in zip(first, second):
        assert Path(p).read_bytes() == Path(q).read_bytes()
    data = Path(first[0]).read_bytes()
    assert str(tmp_path).encode() not in data  # no absolute paths
    if suffix == ".glb":
        magic, version, total = struct.unpack("<4sII", data[:12])
        assert (magic, version, total) == (b"glTF", 2, len(data)) and total % 4 == 0
        jlen, jtype = struct.unpack("<I4s", data[12:20])
        assert jtype == b"JSON" and jlen % 4 == 0
        text = data[20:20 + jlen].decode("ascii")
        blen, btype = struct.unpack("<I4s", data[20 + jlen:28 + jlen])
        assert btype == b"BIN\0" and blen % 4 == 0 and 28 + jlen + blen == len(data)
    else:
        text = data.decode("ascii")
        assert text.endswith("}\n") and json.loads(text)["buffers"][0]["uri"] == "x.bin"
    doc = json.loads(text)
    if suffix == ".glb":  # compact, sorted keys, space padding
        assert text.rstrip(" ") == json.dumps(doc, sort_keys=True, separators=(",", ":"))
    else:  # sorted keys, indent 1, numeric arrays on one line
        assert text == W.gltf_json_text(doc, sort_keys=True)
    assert list(doc) == sorted(doc) and list(doc["asset"]) == sorted(doc["asset"])


def _leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize("bad", ["nan_position", "inf_uv", "index_out_of_range", "negative_index",
                                 "non_unit_normal", "color_above_one", "no_triangles", "wrong_shape",
                                 "float32_overflow", "extras_not_json", "extras_nan", "no_meshes",
                                 "name_not_str"])
def test_invalid_input_raises_before_writing(tmp_path, suffix, bad):
    meshes = _meshes()[:2]
    extras = None
    m = meshes[0]
    if bad == "nan_position":
        m["positions"] = m["positions"].copy()
        m["positions"][5, 1] = np.nan
    elif bad == "inf_uv":
        m["uvs"] = m["uvs"].copy()
        m["uvs"][0, 0] = np.inf
    elif bad == "index_out_of_range":
        m["indices"] = m["indices"].copy()
        m["indices"][-1, 2] = len(m["positions"])
    elif bad == "negative_index":
        m["indices"] = m["indices"].astype(np.int64)
        m["indices"][0, 0] = -1
    elif bad == "non_unit_normal":
        m["normals"] = m["normals"] * np.float32(1.01)
    elif bad == "color_above_one":
        m["colors"] = m["colors"] + np.float32(0.5)
    elif bad == "no_triangles":
        m["indices"] = np.zeros((0, 3), np.uint32)
    elif bad == "wrong_shape":
        m["uvs"] = m["uvs"][:-1]
    elif bad == "float32_overflow":
        m["positions"] = m["positions"].astype(np.float64)
        m["positions"][0, 0] = 1e300
    elif bad == "extras_not_json":
        extras = {"x": object()}
    elif bad == "extras_nan":
        extras = {"x": float("nan")}
    elif bad == "no_meshes":
        meshes = []
    elif bad == "name_not_str":
        m["name"] = 7
    with pytest.raises(ValueError):
        write_gltf(tmp_path / f"bad{suffix}", meshes, extras=extras)
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_failing_write_leaves_no_file_and_keeps_old_content(tmp_path, suffix, monkeypatch):
    path = tmp_path / f"x{suffix}"

    def boom(src, dst):
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(W.os, "replace", boom)
    with pytest.raises(OSError, match="simulated"):
        write_gltf(path, _meshes()[:2])
    assert _leftovers(tmp_path) == []  # no target, no temporary file
    monkeypatch.undo()

    written = write_gltf(path, _meshes()[:1])
    before = {p: Path(p).read_bytes() for p in written}
    monkeypatch.setattr(W.os, "replace", boom)
    with pytest.raises(OSError):
        write_gltf(path, _meshes()[1:3])
    monkeypatch.undo()
    assert {p: Path(p).read_bytes() for p in written} == before
    assert _leftovers(tmp_path) == sorted(Path(p).name for p in written)


def test_missing_directory_is_an_error_not_created(tmp_path):
    with pytest.raises(FileNotFoundError):
        write_gltf(tmp_path / "nope" / "x.glb", _meshes()[:1])
    assert _leftovers(tmp_path) == []


# ---------------------------------------------------------------------------------------------
# Khronos glTF-Validator
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def validator(gltf_validator):
    return gltf_validator


def _assert_clean(validator, path: Path) -> dict:
    report = validator.validate(path)
    issues = report["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, \
        f"{path.name}: " + "; ".join(validator.problems(report))
    return report


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_khronos_validator_reports_no_errors_or_warnings(tmp_path, suffix, validator):
    cases = {"all": _meshes(), "single_bare": [_grid("only", 3)], "big_only": [_grid("big", 257, uvs=True)],
             "mesh_parts": [p.as_mesh_part() for p in F.two_plates() + F.unit_sphere()]}
    for name, meshes in cases.items():
        path = tmp_path / f"{name}{suffix}"
        write_gltf(path, meshes, extras={"case": name})
        report = _assert_clean(validator, path)
        assert report["validatorVersion"] == validator.version()
        info = report["info"]
        assert info["version"] == "2.0" and info["hasDefaultScene"]
        assert info["drawCallCount"] == len(meshes)
        assert info["totalVertexCount"] == sum(len(np.asarray(W._field(m, "positions"))) for m in meshes)
        assert info["totalTriangleCount"] == sum(len(np.asarray(W._field(m, "indices"))) for m in meshes)
        if suffix == ".gltf":
            (res,) = info["resources"]
            assert res["storage"] == "external" and res["uri"] == f"{name}.bin"


def test_khronos_validator_accepts_committed_fixtures(validator):
    files = sorted(FIXTURES.glob("*.glb")) + sorted(FIXTURES.glob("*.gltf"))
    assert files
    for path in files:
        report = _assert_clean(validator, path)
        # Only INFO-level notes are expected: UNUSED_OBJECT for TEXCOORD_0 (no material uses it).
        assert {m["code"] for m in report["issues"]["messages"]} <= {"UNUSED_OBJECT"}


def test_khronos_validator_catches_a_broken_file(tmp_path, validator):
    """The harness is not vacuous: a wrong POSITION min and a missing .bin are reported."""
    path = tmp_path / "broken.gltf"
    write_gltf(path, [_grid("m", 3)])
    doc = json.loads(path.read_text())
    doc["accessors"][0]["min"][1] -= 1.0
    path.write_text(json.dumps(doc))
    report = validator.validate(path)
    assert report["issues"]["numErrors"] >= 1
    assert any(m["code"] == "ACCESSOR_MIN_MISMATCH" for m in report["issues"]["messages"])
    path.with_suffix(".bin").unlink()
    report = validator.validate(path)
    assert any(m["code"] == "IO_ERROR" for m in report["issues"]["messages"])


def test_validator_unavailable_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("GLTF_VALIDATOR_DIR", str(tmp_path / "missing"))
    assert not V.available()
    with pytest.raises(V.GltfValidatorUnavailable, match="npm install"):
        V.validate(tmp_path / "x.glb")
