"""USD ingest: small stages built with pxr in tmp_path, plus the two corpus assets."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, UsdUtils, Vt  # usd-core is a dependency: no skip

from lopcook.errors import LopcookError  # noqa: E402
from lopcook.ingest import load  # noqa: E402
from lopcook.ingest import usd as usd_loader  # noqa: E402
from lopcook.settings import IngestSettings  # noqa: E402

SMOOTH = IngestSettings(crease_angle_deg=180)


# ----------------------------------------------------------------------------- helpers
def new_stage(path, up="Y", mpu=1.0):
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, up)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    return stage


def add_mesh(stage, path, points, counts, indices, **attrs):
    mesh = UsdGeom.Mesh.Define(stage, path)
    if points is not None:
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in points]))
    mesh.CreateFaceVertexCountsAttr(list(counts))
    mesh.CreateFaceVertexIndicesAttr(list(indices))
    for name, value in attrs.items():
        if name == "orientation":
            mesh.CreateOrientationAttr(value)
        elif name == "holes":
            mesh.CreateHoleIndicesAttr(list(value))
        elif name == "purpose":
            mesh.CreatePurposeAttr(value)
        else:
            raise AssertionError(name)
    return mesh


def save_and_load(stage, path, settings=SMOOTH):
    stage.GetRootLayer().Save()
    return load(str(path), settings)


def tri_normals(part):
    t = part.positions[part.indices.astype(np.int64)]
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def signed_volume(part):
    t = part.positions[part.indices.astype(np.int64)]
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)


def by_name(scene):
    return {p.name: p for p in scene.parts}


# cube with every face listed clockwise seen from outside (i.e. authored for leftHanded)
CUBE_POINTS = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]  # index = 4x + 2y + z
CUBE_CCW = [
    (0, 1, 3, 2),  # -x
    (4, 6, 7, 5),  # +x
    (0, 4, 5, 1),  # -y
    (2, 3, 7, 6),  # +y
    (0, 2, 6, 4),  # -z
    (1, 5, 7, 3),  # +z
]
CUBE_CW = [tuple(reversed(f)) for f in CUBE_CCW]


def flat(faces):
    return [i for f in faces for i in f]


# ----------------------------------------------------------------------------- topology
def test_concave_hexagon_triangulated_ccw_with_exact_area(tmp_path):
    f = tmp_path / "ngon.usda"
    st = new_stage(f)
    pts = [(0, 0, 0), (2, 0, 0), (2, 1, 0), (1, 1, 0), (1, 2, 0), (0, 2, 0)]  # L shape, area 3
    add_mesh(st, "/L", pts, [6], range(6))
    scene = save_and_load(st, f)
    assert scene.format == "usda" and len(scene.parts) == 1
    part = scene.parts[0]
    assert part.n_triangles == 4 and part.n_vertices == 6
    n = tri_normals(part)
    assert np.all(n[:, 2] > 0)  # counter-clockwise seen from +Z, like the polygon
    assert np.isclose(0.5 * np.linalg.norm(n, axis=1).sum(), 3.0, rtol=0, atol=1e-12)
    assert np.allclose(part.normals, [0, 0, 1], atol=1e-6) and part.normals_computed


def test_polygon_going_round_few_points_is_refused_naming_the_prim(tmp_path):
    f = tmp_path / "round.usda"
    st = new_stage(f)
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    add_mesh(st, "/R", pts, [400], [i % 4 for i in range(400)])  # 400 corners, 4 points
    with pytest.raises(LopcookError, match="/R.*400 corners but only 4 distinct positions") as info:
        save_and_load(st, f)
    assert "round.usda" in str(info.value) and "once" in str(info.value)


def test_hole_faces_are_dropped_with_their_unused_points(tmp_path):
    f = tmp_path / "holes.usda"
    st = new_stage(f)
    pts = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0)]
    add_mesh(st, "/Q", pts, [4, 4], [0, 1, 4, 3, 1, 2, 5, 4], holes=[1])
    part = save_and_load(st, f).parts[0]
    assert part.n_triangles == 2
    assert part.n_vertices == 4  # points 2 and 5 belong only to the hole
    assert part.positions[:, 0].max() == 1.0


def test_faces_with_fewer_than_three_corners_are_skipped_and_counted(tmp_path):
    f = tmp_path / "small.usda"
    st = new_stage(f)
    add_mesh(st, "/M", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3, 2, 1], [0, 1, 2, 0, 1, 2])
    scene = save_and_load(st, f)
    assert scene.parts[0].n_triangles == 1
    assert any("2 faces with fewer than 3 corners" in w for w in scene.warnings)


@pytest.mark.parametrize("orientation, scale", [
    ("rightHanded", (1, 1, 1)),
    ("leftHanded", (1, 1, 1)),    # leftHanded flips winding
    ("rightHanded", (-1, 1, 1)),  # a mirrored transform flips winding
    ("leftHanded", (-1, 1, 1)),   # both flips cancel
])
def test_winding_outward_for_orientation_and_mirror(tmp_path, orientation, scale):
    f = tmp_path / "cube.usda"
    st = new_stage(f)
    xf = UsdGeom.Xform.Define(st, "/X")
    xf.AddScaleOp().Set(Gf.Vec3f(*scale))
    # outward in object space under the declared orientation; the mirror must not turn it inside out
    faces = CUBE_CW if orientation == "leftHanded" else CUBE_CCW
    add_mesh(st, "/X/Cube", CUBE_POINTS, [4] * 6, flat(faces), orientation=orientation)
    part = save_and_load(st, f).parts[0]
    assert part.n_triangles == 12
    assert math.isclose(signed_volume(part), 1.0, abs_tol=1e-12)
    # every face normal points away from the cube centre, and so do the computed vertex normals
    t = part.positions[part.indices.astype(np.int64)]
    centre = part.positions.mean(axis=0)
    assert np.all(np.einsum("ij,ij->i", t.mean(axis=1) - centre, tri_normals(part)) > 0)
    assert np.all(np.einsum("ij,ij->i", part.positions - centre, part.normals) > 0)


def test_mirrored_cube_is_mirrored_not_flipped_inside_out(tmp_path):
    # the plain right-handed cube placed with scale -1 stays closed with positive volume
    f = tmp_path / "mirror.usda"
    st = new_stage(f)
    xf = UsdGeom.Xform.Define(st, "/X")
    xf.AddTranslateOp().Set(Gf.Vec3d(5, 0, 0))
    xf.AddScaleOp().Set(Gf.Vec3f(-1, 1, 1))
    add_mesh(st, "/X/Cube", CUBE_POINTS, [4] * 6, flat(CUBE_CCW))
    part = save_and_load(st, f).parts[0]
    assert np.allclose(part.positions.min(axis=0), [4, 0, 0]) and np.allclose(part.positions.max(axis=0), [5, 1, 1])
    assert math.isclose(signed_volume(part), 1.0, abs_tol=1e-12)


# ----------------------------------------------------------------------------- units, axes, transforms
def test_z_up_centimetres_become_y_up_metres(tmp_path):
    f = tmp_path / "zup.usda"
    st = new_stage(f, up="Z", mpu=0.01)
    # a triangle lying on the ground (z = 0) facing up (+Z), and a point at 100 cm height
    add_mesh(st, "/Ground", [(0, 0, 0), (100, 0, 0), (0, 100, 0)], [3], [0, 1, 2])
    add_mesh(st, "/Mast", [(0, 0, 100), (10, 0, 0), (0, 10, 0)], [3], [0, 1, 2])
    scene = save_and_load(st, f)
    assert scene.up_axis == "Z" and scene.unit_scale == 0.01
    parts = by_name(scene)
    top = parts["/Mast"].positions
    assert np.allclose(top[np.argmax(top[:, 1])], [0, 1, 0], atol=1e-12)
    ground = parts["/Ground"]
    assert np.allclose(sorted(map(tuple, ground.positions)), sorted([(0, 0, 0), (1, 0, 0), (0, 0, -1)]), atol=1e-12)
    n = tri_normals(ground)[0]
    assert n[1] > 0 and np.allclose(n / np.linalg.norm(n), [0, 1, 0])  # still CCW, now facing +Y
    assert np.allclose(ground.normals, [0, 1, 0], atol=1e-6)


def test_a_mesh_under_a_zero_scale_is_skipped_with_a_warning(tmp_path):
    """As the glTF reader: a singular world transform draws nothing, so its mesh is left out (it
    would otherwise collapse to a point and stretch the scene's grid)."""
    f = tmp_path / "zero.usda"
    st = new_stage(f)
    add_mesh(st, "/Real", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    m = add_mesh(st, "/Flat", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    UsdGeom.Xformable(m).AddTranslateOp().Set(Gf.Vec3d(50, 50, 50))
    UsdGeom.Xformable(m).AddScaleOp().Set(Gf.Vec3f(0, 0, 0))
    scene = save_and_load(st, f)
    assert [p.name for p in scene.parts] == ["/Real"]
    assert any("/Flat: world transform is singular" in w for w in scene.warnings)


def test_zero_normals_are_replaced_with_a_warning(tmp_path):
    f = tmp_path / "zero_normals.usda"
    st = new_stage(f)
    m = add_mesh(st, "/Tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    m.CreateNormalsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 1), Gf.Vec3f(0, 0, 0), Gf.Vec3f(0, 0, 1)]))
    m.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    scene = save_and_load(st, f)
    assert any("/Tri: 1 normals are zero or not finite" in w for w in scene.warnings)


def test_authored_subdivision_warns_that_the_control_mesh_is_cooked(tmp_path):
    f = tmp_path / "subdiv.usda"
    st = new_stage(f)
    poly = add_mesh(st, "/Poly", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    poly.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    add_mesh(st, "/Plain", [(2, 0, 0), (3, 0, 0), (2, 1, 0)], [3], [0, 1, 2])  # unauthored: no warning
    sub = add_mesh(st, "/Smooth", [(0, 0, 1), (1, 0, 1), (0, 1, 1)], [3], [0, 1, 2])
    sub.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.loop)
    scene = save_and_load(st, f)
    assert len(scene.parts) == 3
    assert [w for w in scene.warnings if "subdivisionScheme" in w] == [
        "/Smooth: subdivisionScheme is loop: its control mesh is cooked, not the subdivided surface (lopcook "
        "does not subdivide; re-export it subdivided, or set subdivisionScheme to none if the mesh is polygonal)"]


def test_unauthored_meters_per_unit_uses_usd_fallback_and_warns(tmp_path):
    f = tmp_path / "nompu.usda"
    st = Usd.Stage.CreateNew(str(f))
    add_mesh(st, "/T", [(0, 0, 0), (100, 0, 0), (0, 100, 0)], [3], [0, 1, 2])
    scene = save_and_load(st, f)
    assert scene.unit_scale == pytest.approx(0.01)
    assert scene.parts[0].positions.max() == pytest.approx(1.0)
    assert any("metersPerUnit is not authored" in w for w in scene.warnings)


def test_nested_xforms_compose_in_usd_order(tmp_path):
    f = tmp_path / "nested.usda"
    st = new_stage(f)
    a = UsdGeom.Xform.Define(st, "/A")
    a.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    a.AddRotateYOp().Set(90.0)
    b = UsdGeom.Xform.Define(st, "/A/B")
    b.AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
    b.AddTranslateOp(opSuffix="t").Set(Gf.Vec3d(0, 1, 0))
    add_mesh(st, "/A/B/M", [(1, 0, 0), (0, 0, -1), (0, 1, 0)], [3], [0, 1, 2])
    part = save_and_load(st, f).parts[0]
    # USD xformOpOrder [translate, rotateY] means p' = R(p) + t; B: p' = 2 * (p + (0,1,0))
    expected = []
    for p in [(1, 0, 0), (0, 0, -1), (0, 1, 0)]:
        q = 2.0 * (np.array(p, float) + [0, 1, 0])
        q = np.array([q[2], q[1], -q[0]])  # rotate +90 degrees about Y
        expected.append(q + [10, 0, 0])
    got = part.positions[np.lexsort(part.positions.T[::-1])]
    exp = np.array(expected)[np.lexsort(np.array(expected).T[::-1])]
    assert np.allclose(got, exp, atol=1e-9)
    expected_xf = np.array(UsdGeom.XformCache().GetLocalToWorldTransform(st.GetPrimAtPath("/A/B/M")))
    assert np.allclose(np.array([(1, 0, 0, 1)]) @ expected_xf, [[*expected[0], 1]])


def _asset_layer(path, offset=0.0):
    st = new_stage(path)
    root = UsdGeom.Xform.Define(st, "/Asset")
    st.SetDefaultPrim(root.GetPrim())
    add_mesh(st, "/Asset/Geom", [(offset, 0, 0), (offset + 1, 0, 0), (offset, 1, 0)], [3], [0, 1, 2])
    st.GetRootLayer().Save()
    return st


def test_references_and_payloads_to_another_layer(tmp_path):
    _asset_layer(tmp_path / "asset.usda")
    f = tmp_path / "main.usda"
    st = new_stage(f)
    r = UsdGeom.Xform.Define(st, "/R")
    r.GetPrim().GetReferences().AddReference("./asset.usda")
    r.AddTranslateOp().Set(Gf.Vec3d(0, 1, 0))
    p = UsdGeom.Xform.Define(st, "/P")
    p.GetPrim().GetPayloads().AddPayload("./asset.usda")
    p.AddTranslateOp().Set(Gf.Vec3d(0, 2, 0))
    parts = by_name(save_and_load(st, f))
    assert set(parts) == {"/R/Geom", "/P/Geom"}
    assert np.allclose(parts["/R/Geom"].positions.min(axis=0), [0, 1, 0])
    assert np.allclose(parts["/P/Geom"].positions.min(axis=0), [0, 2, 0])


def test_instanceable_prim_referenced_twice_gives_two_parts_sharing_mesh_key(tmp_path):
    _asset_layer(tmp_path / "asset.usda")
    f = tmp_path / "inst.usda"
    st = new_stage(f)
    for name, x in (("A", 5.0), ("B", -5.0)):
        x_ = UsdGeom.Xform.Define(st, f"/{name}")
        x_.GetPrim().GetReferences().AddReference("./asset.usda")
        x_.GetPrim().SetInstanceable(True)
        x_.AddTranslateOp().Set(Gf.Vec3d(x, 0, 0))
    st.GetRootLayer().Save()
    assert len(Usd.Stage.Open(str(f)).GetPrototypes()) == 1
    scene = load(str(f), SMOOTH)
    parts = by_name(scene)
    assert set(parts) == {"/A/Geom", "/B/Geom"}
    assert parts["/A/Geom"].mesh_key == parts["/B/Geom"].mesh_key != ""
    assert np.allclose(parts["/A/Geom"].positions.min(axis=0), [5, 0, 0])
    assert np.allclose(parts["/B/Geom"].positions.min(axis=0), [-5, 0, 0])


def _instancer_stage(f):
    st = new_stage(f)
    pi = UsdGeom.PointInstancer.Define(st, "/PI")
    pi.AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
    proto = UsdGeom.Xform.Define(st, "/PI/Protos/Proto")
    proto.AddTranslateOp().Set(Gf.Vec3d(0, 1, 0))  # the prototype root's own transform is included
    add_mesh(st, "/PI/Protos/Proto/A", [(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0)], [3], [0, 1, 2])
    b = UsdGeom.Xform.Define(st, "/PI/Protos/Proto/BX")
    b.AddTranslateOp().Set(Gf.Vec3d(1, 0, 0))
    add_mesh(st, "/PI/Protos/Proto/BX/B", [(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0)], [3], [0, 1, 2])
    pi.CreatePrototypesRel().SetTargets([proto.GetPath()])
    pi.CreateProtoIndicesAttr([0, 0, 0])
    pi.CreatePositionsAttr([Gf.Vec3f(0, 0, 0), Gf.Vec3f(10, 0, 0), Gf.Vec3f(0, 10, 0)])
    half = math.sqrt(0.5)
    # float quaternions (orientationsf): half-precision `orientations` would be off by ~3e-4
    pi.CreateOrientationsfAttr([Gf.Quatf(1, 0, 0, 0), Gf.Quatf(half, 0, half, 0), Gf.Quatf(1, 0, 0, 0)])
    pi.CreateScalesAttr([Gf.Vec3f(1, 1, 1), Gf.Vec3f(1, 1, 1), Gf.Vec3f(2, 2, 2)])
    return st, pi


def test_point_instancer_places_every_prototype_mesh_per_instance(tmp_path):
    f = tmp_path / "pi.usda"
    st, _ = _instancer_stage(f)
    scene = save_and_load(st, f)
    parts = by_name(scene)
    assert len(parts) == 6  # 3 instances x 2 meshes; the prototype itself is not drawn
    assert "/PI/Protos/Proto/A" not in parts
    # first point of each mesh: proto-root translate (0,1,0), mesh offset, instance S*R*T, instancer +5 z
    expected = {
        "/PI[0]/Protos/Proto/A": (0, 1, 5), "/PI[0]/Protos/Proto/BX/B": (1, 1, 5),
        "/PI[1]/Protos/Proto/A": (10, 1, 5), "/PI[1]/Protos/Proto/BX/B": (10, 1, 4),  # (1,1,0) turned 90 about Y
        "/PI[2]/Protos/Proto/A": (0, 12, 5), "/PI[2]/Protos/Proto/BX/B": (2, 12, 5),  # scaled 2 then moved
    }
    assert set(parts) == set(expected)
    for name, corner in expected.items():
        d = np.linalg.norm(parts[name].positions - corner, axis=1)
        assert d.min() < 1e-6, (name, parts[name].positions)
    assert parts["/PI[1]/Protos/Proto/A"].source == "/PI/Protos/Proto/A [instance 1]"
    keys = {p.mesh_key for p in scene.parts}
    assert keys == {"/PI/Protos/Proto/A", "/PI/Protos/Proto/BX/B"}
    # instance 2 is scaled by 2: its triangle is 4 times larger
    area = lambda p: 0.5 * np.linalg.norm(tri_normals(p), axis=1).sum()  # noqa: E731
    assert area(parts["/PI[2]/Protos/Proto/A"]) == pytest.approx(4 * area(parts["/PI[0]/Protos/Proto/A"]))


def test_point_instancer_invisible_ids_are_not_drawn(tmp_path):
    f = tmp_path / "pi_mask.usda"
    st, pi = _instancer_stage(f)
    pi.CreateInvisibleIdsAttr([1])
    names = set(by_name(save_and_load(st, f)))
    assert len(names) == 4 and not any(n.startswith("/PI[1]") for n in names)


def test_invisible_guide_and_proxy_prims_are_skipped(tmp_path):
    f = tmp_path / "vis.usda"
    st = new_stage(f)
    tri = ([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    add_mesh(st, "/Shown", *tri)
    add_mesh(st, "/Render", *tri, purpose="render")
    add_mesh(st, "/Guide", *tri, purpose="guide")
    add_mesh(st, "/Proxy", *tri, purpose="proxy")
    hidden = UsdGeom.Xform.Define(st, "/Hidden")
    hidden.CreateVisibilityAttr("invisible")
    add_mesh(st, "/Hidden/Child", *tri)
    g = UsdGeom.Xform.Define(st, "/G")
    g.CreatePurposeAttr("guide")
    add_mesh(st, "/G/Inherits", *tri)
    add_mesh(st, "/G/Overrides", *tri, purpose="render")
    add_mesh(st, "/Inactive", *tri).GetPrim().SetActive(False)
    over = st.OverridePrim("/Over")
    assert over
    scene = save_and_load(st, f)
    names = set(by_name(scene))
    assert names == {"/Shown", "/Render", "/G/Overrides"}
    # the same answer USD's own purpose/visibility computation gives
    drawn = {str(p.GetPath()) for p in st.Traverse() if p.IsA(UsdGeom.Mesh)
             and UsdGeom.Imageable(p).ComputeVisibility() != "invisible"
             and UsdGeom.Imageable(p).ComputePurpose() in ("default", "render")}
    assert names == drawn


# ----------------------------------------------------------------------------- primvars
TWO_QUADS = dict(points=[(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0)],
                 counts=[4, 4], indices=[0, 1, 4, 3, 1, 2, 5, 4])


def _two_quads(st, path):
    return add_mesh(st, path, TWO_QUADS["points"], TWO_QUADS["counts"], TWO_QUADS["indices"])


def _corner_table(part, face_of_x):
    """{(face, position tuple): uv tuple} over every triangle corner; face from the centroid x."""
    table = {}
    for tri in part.indices.astype(np.int64):
        face = face_of_x(part.positions[tri, 0].mean())
        for v in tri:
            key = (face, tuple(part.positions[v]))
            uv = tuple(part.uvs[v].tolist())
            assert table.setdefault(key, uv) == uv
    return table


def test_primvar_interpolations_and_indexed_face_varying_st(tmp_path):
    f = tmp_path / "primvars.usda"
    st = new_stage(f)
    # indexed faceVarying st: both quads map to the whole unit square, so the shared edge splits
    m = _two_quads(st, "/FV")
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    pv.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    pv.SetIndices(Vt.IntArray([0, 1, 2, 3, 0, 1, 2, 3]))
    # vertex st: one uv per point, no split
    m = _two_quads(st, "/V")
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex)
    pv.Set([(0, 0), (0.5, 0), (1, 0), (0, 0.25), (0.5, 0.25), (1, 0.25)])
    # uniform displayColor: one color per face, so the shared edge splits
    m = _two_quads(st, "/U")
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.uniform).Set([(1, 0, 0), (0, 0, 1)])
    # constant displayColor + displayOpacity
    m = _two_quads(st, "/C")
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([(0, 0.5, 0)])
    m.CreateDisplayOpacityPrimvar(UsdGeom.Tokens.constant).Set([0.25])
    # uv set named UVMap of role TextureCoordinate, non-indexed faceVarying with a blocked indices attribute
    m = _two_quads(st, "/Blocked")
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("UVMap", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    pv.Set([(0, 0), (0.5, 0), (0.5, 1), (0, 1), (0.5, 0), (1, 0), (1, 1), (0.5, 1)])
    pv.CreateIndicesAttr().Block()
    parts = by_name(save_and_load(st, f))

    fv = parts["/FV"]
    assert fv.n_vertices == 8 and fv.n_triangles == 4
    table = _corner_table(fv, lambda x: 0 if x < 1 else 1)
    # USD st (u, v) -> (u, 1 - v), exactly
    assert table == {
        (0, (0.0, 0.0, 0.0)): (0.0, 1.0), (0, (1.0, 0.0, 0.0)): (1.0, 1.0),
        (0, (1.0, 1.0, 0.0)): (1.0, 0.0), (0, (0.0, 1.0, 0.0)): (0.0, 0.0),
        (1, (1.0, 0.0, 0.0)): (0.0, 1.0), (1, (2.0, 0.0, 0.0)): (1.0, 1.0),
        (1, (2.0, 1.0, 0.0)): (1.0, 0.0), (1, (1.0, 1.0, 0.0)): (0.0, 0.0),
    }

    v = parts["/V"]
    assert v.n_vertices == 6
    assert np.array_equal(v.uvs, np.c_[v.positions[:, 0] / 2, 1 - v.positions[:, 1] / 4].astype(np.float32))

    u = parts["/U"]
    assert u.n_vertices == 8
    for tri in u.indices.astype(np.int64):
        expect = [1, 0, 0, 1] if u.positions[tri, 0].mean() < 1 else [0, 0, 1, 1]
        assert np.array_equal(u.colors[tri], np.tile(np.float32(expect), (3, 1)))

    c = parts["/C"]
    assert c.n_vertices == 6 and np.array_equal(c.colors, np.tile(np.float32([0, 0.5, 0, 0.25]), (6, 1)))

    b = parts["/Blocked"]
    assert b.n_vertices == 6  # the seam-free layout shares the middle edge
    assert np.array_equal(b.uvs, np.c_[b.positions[:, 0] / 2, 1 - b.positions[:, 1]].astype(np.float32))


def test_uv_set_preference_order(tmp_path):
    f = tmp_path / "uvsets.usda"
    st = new_stage(f)
    m = add_mesh(st, "/M", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    api = UsdGeom.PrimvarsAPI(m)
    api.CreatePrimvar("zzz", Sdf.ValueTypeNames.TexCoord2fArray, "vertex").Set([(0.5, 0.5)] * 3)
    api.CreatePrimvar("map1", Sdf.ValueTypeNames.Float2Array, "vertex").Set([(0.25, 0.25)] * 3)
    api.CreatePrimvar("rest", Sdf.ValueTypeNames.Point3fArray, "vertex").Set([(9, 9, 9)] * 3)
    part = save_and_load(st, f).parts[0]
    assert np.array_equal(part.uvs, np.full((3, 2), [0.25, 0.75], np.float32))  # map1 beats a later fallback


def test_normals_primvar_follows_rotated_and_scaled_parents(tmp_path):
    f = tmp_path / "normals.usda"
    st = new_stage(f)
    r = UsdGeom.Xform.Define(st, "/Rot")
    r.AddRotateXOp().Set(90.0)
    m = add_mesh(st, "/Rot/M", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [4], [0, 1, 2, 3])
    UsdGeom.PrimvarsAPI(m).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, "vertex").Set([(0, 0, 1)] * 4)
    s = UsdGeom.Xform.Define(st, "/Scale")
    s.AddScaleOp().Set(Gf.Vec3f(1, 2, 1))
    m = add_mesh(st, "/Scale/M", [(0, 0, 0), (1, -1, 0), (1, -1, 1)], [3], [0, 1, 2])
    m.CreateNormalsAttr([(1, 1, 0), (1, 1, 0), (1, 1, 0)])  # the plain attribute, faceVarying
    m.SetNormalsInterpolation("faceVarying")
    parts = by_name(save_and_load(st, f))
    rot = parts["/Rot/M"]
    assert not rot.normals_computed
    assert np.allclose(rot.normals, [0, -1, 0], atol=1e-6)  # +Z turned +90 degrees about X
    assert np.allclose(tri_normals(rot) / np.linalg.norm(tri_normals(rot), axis=1)[:, None], [0, -1, 0])
    sc = parts["/Scale/M"]
    expect = np.array([1, 0.5, 0]) / np.linalg.norm([1, 0.5, 0])  # inverse-transpose of diag(1, 2, 1)
    assert np.allclose(sc.normals, expect, atol=1e-6)
    # the transformed normal is still perpendicular to the (scaled) surface
    assert abs(np.dot(tri_normals(sc)[0] / np.linalg.norm(tri_normals(sc)[0]), expect)) == pytest.approx(1.0)


def test_time_sampled_points_without_default_read_at_earliest_sample(tmp_path):
    f = tmp_path / "anim.usda"
    st = new_stage(f)
    m = add_mesh(st, "/M", None, [3], [0, 1, 2])
    pts = m.CreatePointsAttr()
    pts.Set([(0, 0, 0), (1, 0, 0), (0, 1, 0)], 10.0)
    pts.Set([(0, 0, 0), (2, 0, 0), (0, 2, 0)], 20.0)
    x = UsdGeom.Xform.Define(st, "/X")
    op = x.AddTranslateOp()
    op.Set(Gf.Vec3d(1, 0, 0), 10.0)
    op.Set(Gf.Vec3d(3, 0, 0), 20.0)
    add_mesh(st, "/X/T", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    st.GetRootLayer().Save()
    parts = by_name(load(str(f), SMOOTH))
    assert parts["/M"].positions.max() == 1.0
    assert parts["/X/T"].positions[:, 0].min() == 1.0
    parts = by_name(load(str(f), IngestSettings(crease_angle_deg=180, usd_time="20")))
    assert parts["/M"].positions.max() == 2.0
    assert parts["/X/T"].positions[:, 0].min() == 3.0
    parts = by_name(load(str(f), IngestSettings(crease_angle_deg=180, usd_time="15")))
    assert parts["/M"].positions.max() == 1.5  # USD interpolates linearly between samples


def test_texture_of_preview_surface_and_usdz_package(tmp_path):
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 10, 10)).save(buf, format="PNG")
    (tmp_path / "tex.png").write_bytes(buf.getvalue())
    f = tmp_path / "textured.usda"
    st = new_stage(f)
    m = add_mesh(st, "/M", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    add_mesh(st, "/Missing", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    for name, file in (("Mat", "./tex.png"), ("Lost", "./nowhere.png")):
        mat = UsdShade.Material.Define(st, f"/{name}")
        ps = UsdShade.Shader.Define(st, f"/{name}/PS")
        ps.CreateIdAttr("UsdPreviewSurface")
        tx = UsdShade.Shader.Define(st, f"/{name}/Tex")
        tx.CreateIdAttr("UsdUVTexture")
        tx.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
        tx.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        ps.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tx.ConnectableAPI(), "rgb")
        mat.CreateSurfaceOutput().ConnectToSource(ps.ConnectableAPI(), "surface")
        target = m if name == "Mat" else UsdGeom.Mesh(st.GetPrimAtPath("/Missing"))
        UsdShade.MaterialBindingAPI.Apply(target.GetPrim()).Bind(mat)
    st.GetRootLayer().Save()
    scene = load(str(f), SMOOTH)
    parts = by_name(scene)
    assert parts["/M"].texture is not None and parts["/M"].texture.name == "tex.png"
    assert parts["/M"].texture.data == buf.getvalue()
    assert parts["/Missing"].texture is None
    assert any("nowhere.png" in w for w in scene.warnings)

    z = tmp_path / "pkg.usdz"
    st2 = new_stage(tmp_path / "pkg_src.usda")
    m2 = add_mesh(st2, "/M", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    mat = UsdShade.Material.Define(st2, "/Mat")
    ps = UsdShade.Shader.Define(st2, "/Mat/PS")
    ps.CreateIdAttr("UsdPreviewSurface")
    tx = UsdShade.Shader.Define(st2, "/Mat/Tex")
    tx.CreateIdAttr("UsdUVTexture")
    tx.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./tex.png")
    tx.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    ps.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tx.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(ps.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(m2.GetPrim()).Bind(mat)
    st2.GetRootLayer().Save()
    assert UsdUtils.CreateNewUsdzPackage(str(tmp_path / "pkg_src.usda"), str(z))
    (tmp_path / "tex.png").unlink()  # only the copy inside the package remains
    scene = load(str(z), SMOOTH)
    assert scene.format == "usdz" and len(scene.parts) == 1
    assert scene.parts[0].texture is not None and scene.parts[0].texture.data == buf.getvalue()


# ----------------------------------------------------------------------------- errors
def _expect_error(path, *fragments):
    with pytest.raises(LopcookError) as info:
        load(str(path), SMOOTH)
    text = str(info.value)
    assert info.value.stage == "ingest" and path.name in text and "\n" not in text
    for frag in fragments:
        assert frag in text, text
    return text


def test_out_of_range_index_names_prim_index_and_point_count(tmp_path):
    f = tmp_path / "range.usda"
    st = new_stage(f)
    add_mesh(st, "/Bad", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [3], [0, 1, 7])
    st.GetRootLayer().Save()
    _expect_error(f, "/Bad", "index 7", "4 points")


def test_count_mismatch(tmp_path):
    f = tmp_path / "counts.usda"
    st = new_stage(f)
    add_mesh(st, "/Bad", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [4], [0, 1, 2])
    st.GetRootLayer().Save()
    _expect_error(f, "/Bad", "sum(faceVertexCounts) = 4", "3 entries")


def test_nan_point_names_the_prim(tmp_path):
    f = tmp_path / "nan.usda"
    st = new_stage(f)
    add_mesh(st, "/Bad", [(0, 0, 0), (1, 0, 0), (0, float("nan"), 0)], [3], [0, 1, 2])
    st.GetRootLayer().Save()
    _expect_error(f, "/Bad", "NaN or Inf")


def test_primvar_length_mismatch_names_prim_and_primvar(tmp_path):
    f = tmp_path / "pvlen.usda"
    st = new_stage(f)
    m = add_mesh(st, "/Bad", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, "faceVarying").Set([(0, 0)] * 2)
    st.GetRootLayer().Save()
    _expect_error(f, "/Bad", "primvars:st", "expected 3")


def test_primvar_index_out_of_range(tmp_path):
    f = tmp_path / "pvidx.usda"
    st = new_stage(f)
    m = add_mesh(st, "/Bad", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, "faceVarying")
    pv.Set([(0, 0), (1, 0)])
    pv.SetIndices(Vt.IntArray([0, 1, 5]))
    st.GetRootLayer().Save()
    _expect_error(f, "/Bad", "primvars:st:indices", "index 5")


def test_garbage_usda_and_usdc_bytes(tmp_path, rng):
    f = tmp_path / "garbage.usda"
    f.write_bytes(b"#usda 1.0\n" + rng.integers(0, 256, 500, dtype=np.uint8).tobytes())
    _expect_error(f, "USD cannot open")
    g = tmp_path / "garbage.usdc"
    g.write_bytes(b"PXR-USDC" + rng.integers(0, 256, 500, dtype=np.uint8).tobytes())
    _expect_error(g, "USD cannot open")
    h = tmp_path / "text.usd"
    h.write_text('#usda 1.0\ndef Mesh "M" {{ points = [(0, 0, 0)\n')
    _expect_error(h, "text.usd")


def test_missing_reference_is_a_composition_error_without_stderr_noise(tmp_path, capfd):
    f = tmp_path / "dangling.usda"
    st = new_stage(f)
    x = UsdGeom.Xform.Define(st, "/X")
    x.GetPrim().GetReferences().AddReference("./not_there.usda")
    st.GetRootLayer().Save()
    capfd.readouterr()
    _expect_error(f, "composition error", "not_there.usda")
    assert capfd.readouterr().err == ""


def test_stage_without_meshes_is_rejected_by_validation(tmp_path):
    f = tmp_path / "empty.usda"
    st = new_stage(f)
    UsdGeom.Xform.Define(st, "/Nothing")
    st.GetRootLayer().Save()
    _expect_error(f, "no triangle meshes")
    scene = usd_loader.load(str(f), fmt="usda", settings=SMOOTH)
    assert scene.parts == ()


def test_bad_usd_time_setting(tmp_path):
    f = tmp_path / "t.usda"
    st = new_stage(f)
    add_mesh(st, "/M", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    st.GetRootLayer().Save()
    with pytest.raises(LopcookError, match="usd_time"):
        load(str(f), IngestSettings(usd_time="soon"))


# ----------------------------------------------------------------------------- corpus
@pytest.fixture(scope="module")
def chess(corpus):
    return load(corpus / "chess_set_flat.usdc", SMOOTH)


def test_chess_set_parts_and_triangles(chess, corpus_meta):
    meta = corpus_meta["chess_set_flat.usdc"]
    usd = meta["details"]["usd"]
    assert chess.format == "usdc" and chess.up_axis == "Y" and chess.unit_scale == 1.0
    assert len(chess.parts) == usd["rendered_mesh_instances"] == 49
    assert chess.n_triangles == usd["rendered_triangles"] == 1430784
    assert np.allclose(chess.bounds(), meta["bounds"], rtol=0, atol=1e-6)
    board = by_name(chess)["/ChessSet/Chessboard/Geom/Render"]
    width = board.positions.max(axis=0) - board.positions.min(axis=0)
    assert width[0] == pytest.approx(0.7054, abs=1e-3) and width[2] == pytest.approx(0.7054, abs=1e-3)
    assert all(p.uvs is not None and p.normals_computed for p in chess.parts)
    # per source mesh, the triangle count matches corpus.json (quads split in two, triangles kept)
    tris = {m["path"]: m["triangles"] for m in meta["details"]["meshes"]}
    for p in chess.parts:
        assert p.n_triangles == tris[p.source.split(" ")[0]]


def test_chess_pawns_are_sixteen_distinct_placements_on_the_board(chess, corpus_meta):
    lo, hi = np.array(corpus_meta["chess_set_flat.usdc"]["bounds"])
    pawns = [p for p in chess.parts if "/Pawns[" in p.name]
    assert len(pawns) == 32  # 2 instancers x 8 instances x (Geom_Top + Geom_Body)
    bodies = [p for p in pawns if p.name.endswith("/Pawn/Geom_Body/Render")]
    assert len(bodies) == 16
    assert {p.mesh_key for p in bodies} == {"/ChessSet/Black/Pawns/Pawn/Geom_Body/Render",
                                            "/ChessSet/White/Pawns/Pawn/Geom_Body/Render"}
    centres = np.array([p.positions.mean(axis=0) for p in bodies])
    xz = np.round(centres[:, [0, 2]], 6)
    assert len({tuple(c) for c in xz}) == 16
    assert np.all(centres[:, [0, 2]] > lo[[0, 2]]) and np.all(centres[:, [0, 2]] < hi[[0, 2]])
    # all pawns stand on the board, none at the instancer origin (where the bare prototype sits)
    assert np.allclose(centres[:, 1], centres[0, 1])
    assert np.all(np.linalg.norm(xz, axis=1) > 0.01)
    assert not any(p.name.startswith("/ChessSet/Black/Pawns/") for p in chess.parts)


def test_chess_left_handed_pieces_face_outward(chess, corpus_meta):
    left = {m["path"] for m in corpus_meta["chess_set_flat.usdc"]["details"]["meshes"]
            if m["orientation"] == "leftHanded"}
    assert len(left) == 17
    checked = 0
    for p in chess.parts:
        # signed volume of every closed piece (and of the board box) is positive: outward, CCW triangles
        assert signed_volume(p) > 0, p.name
        t = p.positions[p.indices.astype(np.int64)]
        outward = np.einsum("ij,ij->i", t.mean(axis=1) - p.positions.mean(axis=0), tri_normals(p))
        assert outward.sum() > 0, p.name
        checked += p.source in left
    assert checked == 17


def test_chess_vertex_split_per_uv_seam(chess, corpus, corpus_meta):
    # corpus.json's `points` (399,330 for the 21 prims, 713,770 placed) counts USD points. lopcook makes
    # one vertex per distinct (point, st) pair over the face corners, because primvars:st is faceVarying:
    # a point on a UV seam has a different st in the faces on either side and must become several
    # vertices. So every mesh has more vertices than points (e.g. the board 46,218 -> 47,665). The
    # per-corner split of the 21 meshes is recounted here independently from the raw USD arrays.
    stage = Usd.Stage.Open(str(corpus / "chess_set_flat.usdc"))
    loader = usd_loader._Loader(str(corpus / "chess_set_flat.usdc"), "usdc", SMOOTH)
    loader.open()
    loader.run()
    assert len(loader.meshes) == 21
    meta = {m["path"]: m for m in corpus_meta["chess_set_flat.usdc"]["details"]["meshes"]}
    split_total = 0
    for key, local in loader.meshes.items():
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(key))
        fvi = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), np.int64)
        st = np.asarray(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st").Get(), np.float32)
        pairs = np.unique(np.c_[fvi, st.view(np.int32).astype(np.int64)], axis=0).shape[0]
        assert local.points.shape[0] == pairs > meta[key]["points"], key
        split_total += pairs * sum(1 for p in chess.parts if p.mesh_key == key)
    # after the split: 765,607 vertices for the 49 placements (vs 713,770 points). Computed normals may add a
    # few more where welded positions make non-manifold edges (queens, bishops, pawn bodies), even at 180 deg.
    assert split_total == 765607
    assert chess.n_vertices >= split_total
    for p in chess.parts:
        if any(s in p.name for s in ("Chessboard", "King", "Knight", "Rook", "Geom_Top")):
            assert p.n_vertices == loader.meshes[p.mesh_key].points.shape[0], p.name


def test_utah_teapot_usd_extension_with_ascii_content(corpus, corpus_meta):
    meta = corpus_meta["UtahTeapot.usd"]
    scene = load(corpus / "UtahTeapot.usd", SMOOTH)
    assert scene.format == "usda"
    assert len(scene.parts) == 1
    part = scene.parts[0]
    assert part.n_triangles == meta["triangles"] == 2472
    assert part.uvs is not None and part.normals_computed
    assert np.allclose(scene.bounds(), meta["bounds"], rtol=0, atol=1e-6)
    # 1286 points become 1455 vertices: faceVarying st splits the points on UV seams
    assert part.n_vertices == 1455 > meta["vertices"]
    # its authored catmullClark scheme: the control mesh is cooked, and the warning says so
    assert len(scene.warnings) == 1 and "subdivisionScheme is catmullClark" in scene.warnings[0]
