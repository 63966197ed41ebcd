"""tests.support.fixtures: the committed files regenerate byte for byte, and the fixture data holds
the analytic facts fixtures/README.md states (counts, areas, volumes, gaps, transforms).

Importers are not tested here; the files are only read back with json/numpy/text/pxr to check
that they carry exactly the fixture data.
"""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from tests.support import fixtures as F

from conftest import FIXTURES


def _tri_normals(part: F.FixturePart) -> np.ndarray:
    a, b, c = (part.positions[part.indices[:, k]] for k in range(3))
    return np.cross(b - a, c - a)


def _edge_use(indices: np.ndarray) -> np.ndarray:
    """How often each undirected edge is used, and that directed edges are unique."""
    directed = np.concatenate([indices[:, [0, 1]], indices[:, [1, 2]], indices[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == len(directed), "a directed edge repeats: inconsistent winding"
    _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    return counts


def _all_parts() -> list[F.FixturePart]:
    fx = F.point_instancer()
    return (F.seamed_cube() + F.two_plates() + F.unit_sphere() + F.concave_ngon()
            + F.nested_transforms()[0] + F.zup_cm() + fx.prototype)


# ---------------------------------------------------------------------------------------------
# Determinism: regenerating gives the committed bytes
# ---------------------------------------------------------------------------------------------


def test_regenerated_files_are_byte_identical_to_committed(tmp_path):
    written = F.write_all(tmp_path)
    names = sorted(p.name for p in written)
    assert len(names) == len(set(names))
    committed = sorted(p.name for p in FIXTURES.iterdir() if p.is_file() and p.suffix != ".md")
    generated = set(names)
    missing = [n for n in names if not (FIXTURES / n).is_file()]
    assert not missing, f"run `python -m tests.support.fixtures` to write {missing}"
    # fixtures/ may hold other hand-made files; every file write_all makes must match exactly.
    assert generated <= set(committed)
    differ = [n for n in names if (tmp_path / n).read_bytes() != (FIXTURES / n).read_bytes()]
    assert not differ, f"regenerated fixtures differ from the committed ones: {differ}"


def test_writing_twice_gives_identical_bytes(tmp_path):
    a = F.write_all(tmp_path / "a")
    b = F.write_all(tmp_path / "b")
    assert [p.name for p in a] == [p.name for p in b]
    for pa, pb in zip(a, b):
        assert pa.read_bytes() == pb.read_bytes(), pa.name


def test_files_are_small_and_carry_no_paths(tmp_path):
    written = F.write_all(tmp_path)
    sizes = {p.name: p.stat().st_size for p in written}
    assert max(sizes.values()) < 200_000, sizes
    assert sum(sizes.values()) < 1_000_000
    for p in written:
        assert str(tmp_path).encode() not in p.read_bytes(), p.name


def test_expected_file_set():
    expected = {
        "seamed_cube.obj", "seamed_cube.gltf", "seamed_cube.bin", "seamed_cube.glb", "seamed_cube.usda",
        "seamed_cube.usdc", "seamed_cube_facevarying.usda",
        "two_plates.obj", "two_plates.gltf", "two_plates.bin", "two_plates.glb", "two_plates.usda",
        "unit_sphere.obj", "unit_sphere.glb", "unit_sphere.usda",
        "concave_ngon.obj", "concave_ngon.gltf", "concave_ngon.bin", "concave_ngon.usda",
        "nested_transforms.gltf", "nested_transforms.bin", "zup_cm.usda", "point_instancer.usda",
    }
    assert expected <= {p.name for p in FIXTURES.iterdir()}


# ---------------------------------------------------------------------------------------------
# Fixture data: analytic facts
# ---------------------------------------------------------------------------------------------


def test_parts_are_valid_mesh_parts():
    for part in _all_parts():
        part.as_mesh_part().validate()
        assert part.positions.dtype == np.float64 and part.indices.dtype == np.uint32
        if part.polygons is not None:
            assert part.polygons.counts.sum() == len(part.polygons.corners)
            assert (part.polygons.counts - 2).sum() == len(part.indices)


def test_values_are_exact_in_float32_except_the_sphere():
    for part in _all_parts():
        if part.name == "sphere":
            continue
        assert np.array_equal(part.positions.astype(np.float32).astype(np.float64), part.positions), part.name
        if part.uvs is not None:  # v flip (1 - v) is exact too
            assert np.array_equal((np.float32(1) - (np.float32(1) - part.uvs)), part.uvs)
            assert np.all(part.uvs * 1024 == np.round(part.uvs * 1024))


def test_seamed_cube():
    (cube,) = F.seamed_cube()
    assert cube.positions.shape == (24, 3) and cube.indices.shape == (12, 3)
    assert cube.signed_volume() == 1.0
    assert cube.area() == 6.0
    # 8 corners, each used by 3 vertices (the seam)
    _, counts = np.unique(cube.positions, axis=0, return_counts=True)
    assert len(counts) == 8 and np.all(counts == 3)
    assert np.all(np.abs(cube.positions) == 0.5)
    # flat outward normals: triangle normal == vertex normal == the face's outward axis
    n = _tri_normals(cube)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    for k in range(3):
        assert np.array_equal(n, cube.normals[cube.indices[:, k]].astype(np.float64))
    centroid = cube.positions[cube.indices].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", n, centroid) > 0)
    # UVs: each face fills one 0.25 x 0.25 cell, cells distinct, image not mirrored (CCW in uv
    # with glTF v pointing down means negative signed area in (u, v))
    uv = cube.uvs.reshape(6, 4, 2).astype(np.float64)
    assert np.all(uv.max(axis=1) - uv.min(axis=1) == 0.25)
    assert len({tuple(c) for c in uv.min(axis=1)}) == 6
    ua, ub, uc = (cube.uvs[cube.indices[:, k]].astype(np.float64) for k in range(3))
    e1, e2 = ub - ua, uc - ua
    assert np.all(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] == -0.0625)
    # the cross: +Y above +Z, -Y below it, -X / +X / -Z along the middle row
    assert [tuple(c) for c in uv.min(axis=1)] == [(0.5, 0.25), (0.0, 0.25), (0.25, 0.0),
                                                   (0.25, 0.5), (0.25, 0.25), (0.75, 0.25)]


def test_seamed_cube_side_scales():
    (cube,) = F.seamed_cube(side=0.5)
    assert cube.signed_volume() == 0.125 and np.abs(cube.positions).max() == 0.25


@pytest.mark.parametrize("gap", [2.0**-10, 0.25, 2.0**-20])
def test_two_plates(gap):
    lower, upper = F.two_plates(gap)
    assert (lower.name, upper.name) == ("plate_lower", "plate_upper")
    for plate in (lower, upper):
        assert plate.positions.shape == (81, 3) and plate.indices.shape == (128, 3)
        assert plate.area() == 1.0
        n = _tri_normals(plate)
        assert np.all(n[:, [0, 2]] == 0) and np.all(n[:, 1] > 0)  # all facing +Y
        assert np.all(plate.normals == np.array([0, 1, 0], np.float32))
        assert set(np.unique(plate.positions[:, 0])) == {i / 8 - 0.5 for i in range(9)}
        assert np.array_equal(plate.uvs[:, 0], plate.positions[:, 0] + 0.5)
        assert np.array_equal(plate.uvs[:, 1], plate.positions[:, 2] + 0.5)
        assert np.all(_edge_use(plate.indices) <= 2)
    assert np.all(lower.positions[:, 1] == 0.0)
    assert np.all(upper.positions[:, 1] == gap)
    assert np.all(upper.positions[:, 1] - lower.positions[:, 1] == gap)
    assert np.array_equal(lower.positions[:, [0, 2]], upper.positions[:, [0, 2]])
    assert np.array_equal(lower.indices, upper.indices)


def test_default_gap_is_exact_in_float32():
    _, upper = F.two_plates()
    assert upper.positions[0, 1] == 2.0**-10 == float(np.float32(2.0**-10))


@pytest.mark.parametrize("s", [0, 1, 3])
def test_unit_sphere(s):
    (sphere,) = F.unit_sphere(s)
    assert sphere.positions.shape == (10 * 4**s + 2, 3)
    assert sphere.indices.shape == (20 * 4**s, 3)
    assert np.abs(np.linalg.norm(sphere.positions, axis=1) - 1.0).max() < 1e-12
    assert np.array_equal(sphere.normals, sphere.positions.astype(np.float32))
    assert np.all(_edge_use(sphere.indices) == 2)  # closed, consistently wound
    assert 0 < sphere.signed_volume() < 4.0 / 3.0 * np.pi
    n = _tri_normals(sphere)
    centroid = sphere.positions[sphere.indices].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", n, centroid) > 0)  # every face outward
    assert len(np.unique(sphere.positions.round(12), axis=0)) == len(sphere.positions)


def test_unit_sphere_default_is_642_vertices():
    (sphere,) = F.unit_sphere()
    assert sphere.positions.shape == (642, 3) and sphere.indices.shape == (1280, 3)
    assert abs(sphere.signed_volume() - 4.0 / 3.0 * np.pi) < 0.05


def test_concave_ngon():
    (ngon,) = F.concave_ngon()
    assert ngon.positions.shape == (6, 3) and ngon.indices.shape == (4, 3)
    assert list(ngon.polygons.counts) == [6]
    assert list(ngon.polygons.corners) == [0, 1, 2, 3, 4, 5]
    assert np.all(ngon.positions[:, 1] == 0)
    assert ngon.area() == 3.0
    # The polygon itself: shoelace area 3, counter-clockwise seen from +Y (Newell normal +Y).
    p = ngon.positions
    q = np.roll(p, -1, axis=0)
    newell_y = np.sum((p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0]))
    assert newell_y == 6.0  # = 2 * area, positive = facing +Y
    n = _tri_normals(ngon)
    assert np.all(n[:, [0, 2]] == 0) and np.array_equal(n[:, 1], [1.0, 2.0, 2.0, 1.0])
    # one reflex corner (the origin): consecutive edges turn clockwise (cross points -Y) there only
    e0, e1 = q - p, np.roll(q - p, -1, axis=0)
    turn = np.cross(e0, e1)[:, 1]
    assert np.sum(turn < 0) == 1 and np.array_equal(p[1 + int(np.argmax(turn < 0))], [0, 0, 0])


def _quat_matrix(x, y, z, w) -> np.ndarray:
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _node_matrix(node: dict) -> np.ndarray:
    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T  # glTF: column-major
    m = np.eye(4)
    m[:3, :3] = _quat_matrix(*node.get("rotation", [0, 0, 0, 1])) @ np.diag(node.get("scale", [1, 1, 1]))
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def test_nested_transforms_expected_matches_a_node_walk():
    parts, nodes = F.nested_transforms()
    expected = F.nested_transforms_expected()
    assert set(expected) == {"chain_c", "instance"}
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", ())}
    assert sum("matrix" in n for n in nodes) == 1
    for i, node in enumerate(nodes):
        if "mesh" not in node:
            continue
        world, j = _node_matrix(node), i
        while j in parent:
            j = parent[j]
            world = _node_matrix(nodes[j]) @ world
        mesh = parts[node["mesh"]]
        got = mesh.positions @ world[:3, :3].T + world[:3, 3]
        exp = expected[node["name"]]
        assert np.abs(got - exp.positions).max() < 1e-12
        assert np.array_equal(exp.indices, mesh.indices)
        # normals follow the inverse transpose and stay perpendicular to the transformed faces
        n = _tri_normals(exp)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        assert np.abs(exp.normals[exp.indices[:, 0]] - n).max() < 1e-6
    # the chain's result worked out by hand for the tetra corners (0,0,0), (0,0.5,0), (0.25,0,0),
    # (0,0,0.75) = vertices 0, 1, 2, 5: M_c, then M_b, then M_a
    assert np.allclose(expected["chain_c"].positions[[0, 1, 2, 5]],
                       [[1.0, 1.5, -2.5], [1.0, 1.5, -2.0], [1.0, 1.375, -2.5], [0.8125, 1.5, -2.5]],
                       rtol=0, atol=1e-15)
    assert np.array_equal(expected["instance"].positions, parts[0].positions * 3 + [-3.0, 0.0, 1.0])


def test_zup_cm_converts_to_half_metre_cube():
    (src,) = F.zup_cm()
    (exp,) = F.zup_cm_expected()
    x, y, z = src.positions.T
    assert np.array_equal(np.stack([x, z, -y], axis=1) * 0.01, exp.positions)
    nx, ny, nz = src.normals.T
    assert np.array_equal(np.stack([nx, nz, -ny], axis=1), exp.normals)
    assert np.abs(src.positions).max() == 25.0
    assert exp.signed_volume() == 0.125
    (cube,) = F.seamed_cube()
    assert np.array_equal(exp.positions, cube.positions * 0.5)
    assert np.array_equal(exp.uvs, cube.uvs) and np.array_equal(src.indices, cube.indices)


def test_point_instancer_expected():
    fx = F.point_instancer()
    expected = F.point_instancer_expected()
    assert sorted(expected) == sorted(f"instance{k}/{m}" for k in range(4) for m in ("Box", "Pyramid"))
    for q, r in zip(fx.orientations, fx.rotations):
        w, x, y, z = q
        assert np.abs(_quat_matrix(x, y, z, w) - r).max() < 1e-15
    box0 = expected["instance0/Box"].positions
    assert np.array_equal(box0, fx.prototype[0].positions + [0, 1, 0])
    assert np.array_equal(expected["instance1/Box"].positions, box0 + [2, 0, 0])
    assert np.array_equal(expected["instance3/Box"].positions, fx.prototype[0].positions * 2 + [-2, 1, 0])
    # instance 2: 90 deg about +Y sends +x to -z
    rotated = expected["instance2/Pyramid"].positions
    local = fx.prototype[1].positions + [0, 0.5, 0]
    assert np.array_equal(rotated, np.stack([local[:, 2], local[:, 1], -local[:, 0]], 1) + [0, 1, -2])
    # pyramid apex sits on the box top: 0.5 + 0.25 above the instance origin (doubled for k = 3)
    assert expected["instance0/Pyramid"].positions[:, 1].max() == 1.75
    assert expected["instance3/Pyramid"].positions[:, 1].max() == 2.5
    for name, part in expected.items():
        scale = 8.0 if name.startswith("instance3") else 1.0  # S(2) scales volume by 8
        local = fx.prototype[0] if name.endswith("Box") else fx.prototype[1]
        assert abs(part.signed_volume() - scale * local.signed_volume()) < 1e-15


def test_box_and_pyramid_are_closed_and_outward():
    box, pyr = F.point_instancer().prototype
    assert box.signed_volume() == 0.125 and box.area() == 1.5
    assert pyr.signed_volume() == 0.25 * 0.25 / 3  # base 0.5 x 0.5, height 0.25
    for part in (box, pyr):
        assert np.all(_edge_use(part.indices) == 2)


# ---------------------------------------------------------------------------------------------
# The files carry exactly the fixture data (read back with plain tools, not lopcook's importers)
# ---------------------------------------------------------------------------------------------


def _read_gltf(path):
    """Minimal glTF/GLB reader: (json, {accessor index: numpy array})."""
    data = path.read_bytes()
    if path.suffix == ".glb":
        magic, version, length = struct.unpack_from("<4sII", data)
        assert (magic, version, length) == (b"glTF", 2, len(data))
        jlen, jtype = struct.unpack_from("<I4s", data, 12)
        assert jtype == b"JSON" and jlen % 4 == 0
        doc = json.loads(data[20:20 + jlen])
        blen, btype = struct.unpack_from("<I4s", data, 20 + jlen)
        assert btype == b"BIN\0" and 28 + jlen + blen == len(data)
        blob = data[28 + jlen:28 + jlen + blen]
    else:
        doc = json.loads(data)
        assert "uri" in doc["buffers"][0] and "/" not in doc["buffers"][0]["uri"]
        blob = (path.parent / doc["buffers"][0]["uri"]).read_bytes()
    assert len(blob) >= doc["buffers"][0]["byteLength"]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}
    dtypes = {5126: "<f4", 5123: "<u2", 5125: "<u4"}
    arrays = {}
    for i, acc in enumerate(doc["accessors"]):
        view = doc["bufferViews"][acc["bufferView"]]
        assert view["byteOffset"] % 4 == 0
        a = np.frombuffer(blob, dtypes[acc["componentType"]], acc["count"] * width[acc["type"]],
                          view["byteOffset"]).reshape(acc["count"], -1)
        if "min" in acc:
            assert a.min(axis=0).tolist() == acc["min"] and a.max(axis=0).tolist() == acc["max"]
        arrays[i] = a
    return doc, arrays


@pytest.mark.parametrize("name,parts", [
    ("seamed_cube.gltf", F.seamed_cube()), ("seamed_cube.glb", F.seamed_cube()),
    ("two_plates.gltf", F.two_plates()), ("two_plates.glb", F.two_plates()),
    ("unit_sphere.glb", F.unit_sphere()), ("concave_ngon.gltf", F.concave_ngon()),
    ("nested_transforms.gltf", F.nested_transforms()[0]),
])
def test_gltf_files_carry_the_data(name, parts):
    doc, arrays = _read_gltf(FIXTURES / name)
    assert doc["asset"] == {"generator": "lopcook fixtures", "version": "2.0"}
    assert len(doc["meshes"]) == len(parts)
    for mesh, part in zip(doc["meshes"], parts):
        (prim,) = mesh["primitives"]
        attr = prim["attributes"]
        assert mesh["name"] == part.name and prim["mode"] == 4
        assert np.array_equal(arrays[attr["POSITION"]], part.positions.astype(np.float32))
        assert np.array_equal(arrays[prim["indices"]].reshape(-1, 3), part.indices)
        if part.normals is not None:
            assert np.array_equal(arrays[attr["NORMAL"]], part.normals)
        if part.uvs is not None:
            assert np.array_equal(arrays[attr["TEXCOORD_0"]], part.uvs)
    if name.startswith("unit_sphere"):
        assert doc["accessors"][doc["meshes"][0]["primitives"][0]["indices"]]["componentType"] == 5125
    if name.startswith("nested"):
        assert [n["name"] for n in doc["nodes"]] == ["chain_a", "chain_b", "chain_c", "instance"]
        assert doc["scenes"][0]["nodes"] == [0, 3]


def _read_obj(path):
    """{object name: (v, vt, vn, faces as lists of (v, vt, vn) 0-based global triples)}."""
    objects, v, vt, vn = {}, [], [], []
    for line in path.read_text().splitlines():
        key, *rest = line.split()
        if key == "o":
            objects[rest[0]] = current = {"v0": len(v), "faces": []}
        elif key in ("v", "vt", "vn"):
            {"v": v, "vt": vt, "vn": vn}[key].append([float(x) for x in rest])
        elif key == "f":
            current["faces"].append([[int(i) - 1 if i else None for i in c.split("/")] for c in rest])
    return objects, np.array(v), np.array(vt), np.array(vn)


@pytest.mark.parametrize("name,parts", [
    ("seamed_cube.obj", F.seamed_cube()), ("two_plates.obj", F.two_plates()),
    ("unit_sphere.obj", F.unit_sphere()), ("concave_ngon.obj", F.concave_ngon()),
])
def test_obj_files_carry_the_data(name, parts):
    objects, v, vt, vn = _read_obj(FIXTURES / name)
    assert list(objects) == [p.name for p in parts]
    allpos = np.concatenate([p.positions for p in parts])
    assert np.array_equal(v, allpos.astype(np.float32).astype(np.float64))  # float32 values, exactly
    for part, obj in zip(parts, objects.values()):
        faces = obj["faces"]
        assert [len(f) for f in faces] == part.faces.counts.tolist()
        corners = np.array([c for f in faces for c in f], dtype=object)
        vidx = np.array([c[0] for c in corners]) - obj["v0"]
        assert np.array_equal(vidx, part.faces.corners)
    if parts[0].uvs is not None:
        uvs = np.concatenate([p.uvs for p in parts])
        assert np.array_equal(vt[:, 0], uvs[:, 0]) and np.array_equal(1 - vt[:, 1], uvs[:, 1])
    if parts[0].normals is not None:
        assert np.array_equal(vn, np.concatenate([p.normals for p in parts]).astype(np.float64))


@pytest.mark.parametrize("name,parts", [
    ("seamed_cube.usda", F.seamed_cube()), ("seamed_cube.usdc", F.seamed_cube()),
    ("two_plates.usda", F.two_plates()), ("unit_sphere.usda", F.unit_sphere()),
    ("concave_ngon.usda", F.concave_ngon()), ("zup_cm.usda", F.zup_cm()),
])
def test_usd_files_carry_the_data(name, parts):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(FIXTURES / name))
    assert stage.GetDefaultPrim().GetPath() == "/Root"
    zup = name.startswith("zup")
    assert UsdGeom.GetStageUpAxis(stage) == ("Z" if zup else "Y")
    assert UsdGeom.GetStageMetersPerUnit(stage) == (0.01 if zup else 1.0)
    for part in parts:
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/Root/{part.name}"))
        assert np.array_equal(np.array(mesh.GetPointsAttr().Get()), part.positions.astype(np.float32))
        assert list(mesh.GetFaceVertexCountsAttr().Get()) == part.faces.counts.tolist()
        assert list(mesh.GetFaceVertexIndicesAttr().Get()) == part.faces.corners.tolist()
        api = UsdGeom.PrimvarsAPI(mesh)
        if part.normals is not None:
            pv = api.GetPrimvar("normals")
            assert pv.GetInterpolation() == "vertex"
            assert np.array_equal(np.array(pv.Get()), part.normals)
        if part.uvs is not None:
            st = np.array(api.GetPrimvar("st").Get())
            assert np.array_equal(st[:, 0], part.uvs[:, 0]) and np.array_equal(1 - st[:, 1], part.uvs[:, 1])


def test_usd_facevarying_cube_is_the_same_surface():
    from pxr import Usd, UsdGeom

    (cube,) = F.seamed_cube()
    stage = Usd.Stage.Open(str(FIXTURES / "seamed_cube_facevarying.usda"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/cube"))
    points = np.array(mesh.GetPointsAttr().Get())
    fvi = np.array(mesh.GetFaceVertexIndicesAttr().Get())
    assert points.shape == (8, 3)
    corners = cube.indices.reshape(-1)
    assert np.array_equal(points[fvi], cube.positions[corners])
    api = UsdGeom.PrimvarsAPI(mesh)
    normals, st = api.GetPrimvar("normals"), api.GetPrimvar("st")
    assert normals.GetInterpolation() == st.GetInterpolation() == "faceVarying"
    assert not normals.IsIndexed() and st.IsIndexed()
    assert np.array_equal(np.array(normals.Get()), cube.normals[corners])
    flat = np.array(st.ComputeFlattened())
    assert np.array_equal(1 - flat[:, 1], cube.uvs[corners, 1])


def test_usd_point_instancer_file():
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(FIXTURES / "point_instancer.usda"))
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Root/Instancer"))
    fx = F.point_instancer()
    assert [str(t) for t in inst.GetPrototypesRel().GetTargets()] == ["/Root/Instancer/Prototypes/Proto"]
    assert np.array_equal(np.array(inst.GetPositionsAttr().Get()), fx.positions)
    # pxr's own placement (it prefers orientationsf, float32) agrees with the exact expectation
    xforms = inst.ComputeInstanceTransformsAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default())
    instancer = np.array(inst.ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
    expected = F.point_instancer_expected()
    for k, m in enumerate(xforms):
        for part in fx.prototype:
            prim = stage.GetPrimAtPath(f"/Root/Instancer/Prototypes/Proto/{part.name}")
            local = np.array(UsdGeom.Xformable(prim).GetLocalTransformation())
            pts = np.c_[np.array(UsdGeom.Mesh(prim).GetPointsAttr().Get(), np.float64), np.ones(len(part.positions))]
            world = (pts @ local @ np.array(m) @ instancer)[:, :3]  # USD: row vectors
            assert np.abs(world - expected[f"instance{k}/{part.name}"].positions).max() < 1e-7
