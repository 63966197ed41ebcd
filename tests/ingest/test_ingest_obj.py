"""OBJ ingest: statements, parts, per-corner split, triangulation, materials, errors, corpus files."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.ingest import obj as objmod
from lopcook.settings import IngestSettings

SMOOTH = IngestSettings(crease_angle_deg=180.0)


def write(tmp_path: Path, text: str | bytes, name: str = "model.obj") -> Path:
    p = tmp_path / name
    if isinstance(text, str):
        text = text.encode("utf-8")
    p.write_bytes(text)
    return p


def raw(path: Path, settings: IngestSettings = SMOOTH):
    """The loader's unvalidated Scene."""
    return objmod.load(str(path), fmt="obj", settings=settings)


def expect_error(path: Path, *fragments: str) -> LopcookError:
    with pytest.raises(LopcookError) as info:
        load(path)
    err = info.value
    text = str(err)
    assert err.stage == "ingest"
    assert path.name in text, text
    for frag in fragments:
        assert frag in text, f"{frag!r} not in {text!r}"
    assert "\n" not in text
    return err


def tri_area_and_normal(part):
    P = part.positions
    T = part.indices.astype(np.int64)
    cross = np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]])
    return 0.5 * np.linalg.norm(cross, axis=1), cross


TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"

# Blender's default cube: 8 v, 14 vt (cross unfolding), 6 vn, six quads
CUBE = """\
v 1 1 -1
v 1 -1 -1
v 1 1 1
v 1 -1 1
v -1 1 -1
v -1 -1 -1
v -1 1 1
v -1 -1 1
vt 0.625 0.5
vt 0.875 0.5
vt 0.875 0.75
vt 0.625 0.75
vt 0.375 0.75
vt 0.625 1.0
vt 0.375 1.0
vt 0.375 0.0
vt 0.625 0.0
vt 0.625 0.25
vt 0.375 0.25
vt 0.125 0.5
vt 0.375 0.5
vt 0.125 0.75
vn 0 1 0
vn 0 0 1
vn -1 0 0
vn 0 -1 0
vn 1 0 0
vn 0 0 -1
usemtl Material
s off
f 1/1/1 5/2/1 7/3/1 3/4/1
f 4/5/2 3/4/2 7/6/2 8/7/2
f 8/8/3 7/9/3 5/10/3 6/11/3
f 6/12/4 2/13/4 4/5/4 8/14/4
f 2/13/5 1/1/5 3/4/5 4/5/5
f 6/11/6 5/10/6 1/1/6 2/13/6
"""


def cube_corners(text: str) -> list[tuple[int, ...]]:
    out = []
    for line in text.splitlines():
        if line.startswith("f "):
            out += [tuple(int(x) for x in tok.split("/")) for tok in line.split()[1:]]
    return out


# -- parts ---------------------------------------------------------------------------------------
def test_twenty_objects_give_twenty_named_parts(tmp_path):
    lines = []
    for k in range(20):
        lines.append(f"o thing_{k}")
        lines += [f"v {k} 0 0", f"v {k + 1} 0 0", f"v {k} 1 0", "f -3 -2 -1"]
    scene = load(write(tmp_path, "\n".join(lines) + "\n"))
    assert [p.name for p in scene.parts] == [f"thing_{k}" for k in range(20)]
    for k, part in enumerate(scene.parts):
        assert part.n_vertices == 3 and part.n_triangles == 1
        np.testing.assert_array_equal(part.positions[:, 0], [k, k + 1, k])
    assert len({p.mesh_key for p in scene.parts}) == 20


def test_object_and_group_pairs(tmp_path):
    text = TRI + """\
f 1 2 3
o A
f 1 2 3
g x
f 1 2 3
g y
f 1 2 3
f 1 2 3
o B
f 1 2 3
g x
f 1 2 3
o A
g x
f 3 2 1
"""
    path = write(tmp_path, text, "pairs.obj")
    scene = load(path)
    names = [p.name for p in scene.parts]
    # faces before any o/g -> file stem; a new o resets the group; (A, x) seen again continues
    assert names == ["pairs", "A", "A/x", "A/y", "B", "B/x"]
    assert [p.n_triangles for p in scene.parts] == [1, 1, 2, 2, 1, 1]
    assert scene.parts[2].source == "o A g x"


def test_groups_alone_are_parts(tmp_path):
    scene = load(write(tmp_path, TRI + "g left\nf 1 2 3\ng right\nf 1 2 3\ng left\nf 1 2 3\n"))
    assert [p.name for p in scene.parts] == ["left", "right"]
    assert [p.n_triangles for p in scene.parts] == [2, 1]


def test_repeated_names_are_made_unique(tmp_path):
    # (o a, g b) and (o a/b) are different pairs with the same display name
    scene = load(write(tmp_path, TRI + "o a\ng b\nf 1 2 3\no a/b\nf 1 2 3\n"))
    assert [p.name for p in scene.parts] == ["a/b", "a/b#2"]


# -- corner forms ---------------------------------------------------------------------------------
def test_corner_forms(tmp_path):
    head = TRI + "vt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
    s = load(write(tmp_path, head + "f 1 2 3\n", "a.obj")).parts[0]
    assert s.uvs is None and s.normals_computed
    s = load(write(tmp_path, head + "f 1/1 2/2 3/3\n", "b.obj")).parts[0]
    np.testing.assert_allclose(s.uvs, [[0, 1], [1, 1], [0, 0]])
    assert s.normals_computed
    s = load(write(tmp_path, head + "f 1//1 2//1 3//1\n", "c.obj")).parts[0]
    assert s.uvs is None and not s.normals_computed
    np.testing.assert_allclose(s.normals, [[0, 0, 1]] * 3)
    s = load(write(tmp_path, head + "f 1/1/1 2/2/1 3/3/1\n", "d.obj")).parts[0]
    assert s.uvs is not None and not s.normals_computed
    np.testing.assert_allclose(s.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    # trailing empty field "v/vt/" means no vn
    s = load(write(tmp_path, head + "f 1/1/ 2/2/ 3/3/\n", "e.obj")).parts[0]
    assert s.uvs is not None and s.normals_computed


def test_negative_indices_are_relative_to_the_line(tmp_path):
    text = TRI + "vt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nf -3/-3/-1 -2/-2/-1 -1/-1/-1\nv 1 1 0\no second\nf -3 -1 -2\n"
    scene = load(write(tmp_path, text))
    a, b = scene.parts
    np.testing.assert_allclose(a.positions[a.indices], [[[0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    np.testing.assert_allclose(a.uvs[a.indices], [[[0, 1], [1, 1], [0, 0]]])
    # -3, -1, -2 after the 4th v -> v2, v4, v3
    np.testing.assert_allclose(b.positions[b.indices], [[[1, 0, 0], [1, 1, 0], [0, 1, 0]]])


def test_per_corner_split_of_cube_with_seams(tmp_path):
    corners = cube_corners(CUBE)
    expected_vvt = len({c[:2] for c in corners})   # distinct (v, vt)
    expected_all = len(set(corners))               # distinct (v, vt, vn)
    assert (expected_vvt, expected_all) == (14, 24)
    part = load(write(tmp_path, CUBE)).parts[0]
    assert part.n_vertices == expected_all
    assert part.n_triangles == 12
    assert not part.normals_computed
    # every vertex carries the normal of its face and the flipped uv of its vt
    vts = np.array([[float(x) for x in ln.split()[1:]] for ln in CUBE.splitlines() if ln.startswith("vt ")])
    got = {(tuple(np.round(p, 6)), tuple(np.round(uv, 6))) for p, uv in zip(part.positions, part.uvs)}
    vs = np.array([[float(x) for x in ln.split()[1:]] for ln in CUBE.splitlines() if ln.startswith("v ")])
    want = {(tuple(np.round(vs[v - 1], 6)), (round(vts[t - 1, 0], 6), round(1 - vts[t - 1, 1], 6)))
            for v, t, _ in corners}
    assert got == want
    _, cross = tri_area_and_normal(part)
    centroid = part.positions[part.indices].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", cross, centroid) > 0)  # CCW seen from outside
    tri_n = part.normals[part.indices]  # (12, 3, 3): flat faces, all corners share the face normal
    np.testing.assert_allclose(tri_n, np.repeat((cross / np.linalg.norm(cross, axis=1)[:, None])[:, None], 3, 1),
                               atol=1e-7)

    # without vn: (v, vt) pairs only; smooth normals keep the 14, a crease angle splits edges
    no_vn = "\n".join(ln if not ln.startswith("f ") else
                      "f " + " ".join("/".join(t.split("/")[:2]) for t in ln.split()[1:])
                      for ln in CUBE.splitlines()) + "\n"
    path = write(tmp_path, no_vn, "cube_novn.obj")
    assert raw(path, SMOOTH).parts[0].n_vertices == expected_vvt
    flat = raw(path, IngestSettings(crease_angle_deg=60.0)).parts[0]
    assert flat.n_vertices == 24 and flat.normals_computed


def test_uv_v_is_flipped(tmp_path):
    text = TRI + "vt 0.25 0.1\nvt 0.5 0.75\nvt 1 0\nf 1/1 2/2 3/3\n"
    part = load(write(tmp_path, text)).parts[0]
    np.testing.assert_allclose(part.uvs, [[0.25, 0.9], [0.5, 0.25], [1.0, 1.0]], atol=1e-7)
    assert part.uvs.dtype == np.float32


ROTATIONS = {  # proper rotations taking +Z to the named polygon normal
    "+Z": np.eye(3),
    "+Y": np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]),
    "-Y": np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]),
    "-X": np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]]),
    "tilted": np.array([[1, 0, 0], [0, 0.8, 0.6], [0, -0.6, 0.8]]),
}


@pytest.mark.parametrize("facing", sorted(ROTATIONS))
def test_concave_l_hexagon(tmp_path, facing):
    # L shape, area 3, listed from (2, 0): a fan from the first corner would fold over
    ring = [(2, 0), (2, 1), (1, 1), (1, 2), (0, 2), (0, 0)]
    R = ROTATIONS[facing]
    pts = np.array([[x, y, 0.0] for x, y in ring]) @ R.T
    normal = R @ np.array([0.0, 0.0, 1.0])
    text = "".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in pts) + "f 1 2 3 4 5 6\n"
    part = load(write(tmp_path, text)).parts[0]
    assert part.n_triangles == 4
    area, cross = tri_area_and_normal(part)
    if facing == "tilted":
        assert area.sum() == pytest.approx(3.0, abs=1e-12)
    else:
        assert area.sum() == 3.0  # integer corners: exact
    assert np.all(cross @ normal > 0)  # every triangle CCW about the polygon normal
    assert np.all(np.isclose(cross @ normal, 2 * area))  # and lies in the polygon's plane


def comb(k: int) -> np.ndarray:
    """(k, 2) integer corners of a counter-clockwise comb: a base edge, then k - 2 teeth corners
    alternating between heights 4 and 2 (every low one reflex)."""
    x = np.arange(k - 3, -1, -1)
    top = np.stack([x, np.where(np.arange(k - 2) % 2 == 0, 4, 2)], axis=1)
    return np.vstack([[[0, 0], [k - 3, 0]], top]).astype(float)


def comb_obj(k: int, line_before: str = "") -> str:
    pts = comb(k)
    return ("".join(f"v {x:g} {y:g} 0\n" for x, y in pts) + line_before
            + "f " + " ".join(str(i) for i in range(1, k + 1)) + "\n")


def inside_polygon(points: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """(n, 2) points, (k, 2) polygon -> (n,) bool by crossing number (points on no edge)."""
    a, b = ring[None, :, :], np.roll(ring, -1, axis=0)[None, :, :]
    p = points[:, None, :]
    straddles = (a[..., 1] > p[..., 1]) != (b[..., 1] > p[..., 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[..., 0] + (p[..., 1] - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    return (np.count_nonzero(straddles & (p[..., 0] < x_cross), axis=1) % 2) == 1


def test_large_concave_polygon_tiles_its_area(tmp_path):
    """A 2,000-corner comb (999 reflex corners): k - 2 counter-clockwise triangles covering the
    shoelace area, each inside the polygon."""
    k = 2000
    ring = comb(k)
    part = load(write(tmp_path, comb_obj(k))).parts[0]
    assert part.n_triangles == k - 2 and part.positions.shape[0] == k
    area, cross = tri_area_and_normal(part)
    shoelace = 0.5 * np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
    assert np.all(cross[:, 2] > 0)  # every triangle turns like the polygon (CCW about +Z)
    assert area.sum() == pytest.approx(shoelace, rel=1e-12)
    centroids = part.positions[part.indices.astype(np.int64)].mean(axis=1)[:, :2]
    assert np.all(inside_polygon(centroids, ring))


def test_concave_polygon_over_the_limit_is_refused_with_its_line(tmp_path):
    from lopcook.ingest.polygons import MAX_CONCAVE_CORNERS

    k = MAX_CONCAVE_CORNERS + 1
    path = write(tmp_path, comb_obj(k, line_before="# the face\n"), "huge.obj")
    expect_error(path, f"line {k + 2}", f"{k:,} corners", f"at most {MAX_CONCAVE_CORNERS:,}")


def test_fixture_concave_ngon_and_seamed_cube():
    from conftest import FIXTURES

    part = load(FIXTURES / "concave_ngon.obj").parts[0]
    area, cross = tri_area_and_normal(part)
    assert part.name == "lshape" and part.n_triangles == 4
    assert area.sum() == 3.0 and np.all(cross[:, 1] > 0)
    cube = load(FIXTURES / "seamed_cube.obj").parts[0]
    assert (cube.name, cube.n_vertices, cube.n_triangles) == ("cube", 24, 12)


def test_vertex_colours(tmp_path):
    text = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n"
    part = load(write(tmp_path, text)).parts[0]
    np.testing.assert_allclose(part.colors, [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]])
    np.testing.assert_allclose(part.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    # w is read and ignored
    part = load(write(tmp_path, "v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n", "w.obj")).parts[0]
    assert part.colors is None
    np.testing.assert_allclose(part.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_unused_vertices_are_dropped(tmp_path):
    text = "v 9 9 9\nv 0 0 0\nv 8 8 8\nv 1 0 0\nv 0 1 0\nv 7 7 7\nf 2 4 5\n"
    part = load(write(tmp_path, text)).parts[0]
    assert part.n_vertices == 3
    np.testing.assert_allclose(part.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_quads_and_ngons_mixed_with_triangles(tmp_path):
    text = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nv 3 0.5 0\nv 2.5 1.5 0\n"
            "f 1 2 3 4\nf 2 5 6\nf 5 7 8 6 3\n")
    part = load(write(tmp_path, text)).parts[0]
    assert part.n_triangles == 2 + 1 + 3
    _, cross = tri_area_and_normal(part)
    assert np.all(cross[:, 2] > 0)


# -- materials ------------------------------------------------------------------------------------
def tiny_png() -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (2, 2), (200, 10, 10)).save(buf, format="PNG")
    return buf.getvalue()


def test_mtllib_map_kd_becomes_texture(tmp_path):
    png = tiny_png()
    (tmp_path / "tex dir").mkdir()
    (tmp_path / "tex dir" / "red.png").write_bytes(png)
    (tmp_path / "mats.mtl").write_text(
        "newmtl plain\nKd 1 1 1\nnewmtl red\nKd 1 0 0\nmap_Kd -s 1 1 1 -bm 0.5 tex dir/red.png\n")
    text = ("mtllib mats.mtl\n" + TRI + "vt 0 0\nvt 1 0\nvt 0 1\n"
            "o a\nusemtl red\nf 1/1 2/2 3/3\no b\nusemtl plain\nf 1 2 3\n")
    scene = load(write(tmp_path, text))
    a, b = scene.parts
    assert a.texture is not None and a.texture.name == "red.png" and a.texture.data == png
    assert a.texture.image().size == (2, 2)
    assert "usemtl red" in a.source
    assert b.texture is None and "usemtl plain" in b.source
    assert scene.warnings == ()


def test_missing_mtl_and_texture_are_warnings(tmp_path):
    scene = load(write(tmp_path, "mtllib nowhere.mtl\n" + TRI + "usemtl m\nf 1 2 3\n"))
    assert scene.parts[0].texture is None
    assert any("nowhere.mtl" in w and "not found" in w for w in scene.warnings)
    (tmp_path / "m.mtl").write_text("newmtl m\nmap_Kd gone.png\n")
    scene = load(write(tmp_path, "mtllib m.mtl\n" + TRI + "usemtl m\nf 1 2 3\n", "t.obj"))
    assert scene.parts[0].texture is None
    assert any("gone.png" in w for w in scene.warnings)


# -- syntax ---------------------------------------------------------------------------------------
def test_comments_continuations_crlf_and_skipped_statements(tmp_path):
    text = ("# header\r\n  v 0 0 0 # trailing\r\nv 1 0 0\r\nv 0 1 \\\r\n 0\r\ns 1\r\nl 1 2\r\np 3\r\n"
            "vp 0.5\r\n\tf 1 2 \\\r\n3\r\n")
    scene = load(write(tmp_path, text))
    part = scene.parts[0]
    np.testing.assert_allclose(part.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert part.n_triangles == 1
    assert any("1 line (l) and 1 point (p)" in w for w in scene.warnings)
    assert any("'vp'" in w for w in scene.warnings)


def test_deep_indentation(tmp_path):
    text = "".join(" " * 40 + ln + "\n" for ln in (TRI + "o deep\nf 1 2 3").splitlines())
    part = load(write(tmp_path, text)).parts[0]
    assert part.name == "deep" and part.n_triangles == 1


def test_latin1_names_fall_back_with_warning(tmp_path):
    scene = load(write(tmp_path, TRI.encode() + b"o caf\xe9\nf 1 2 3\n"))
    assert scene.parts[0].name == "caf\u00e9"
    assert any("Latin-1" in w for w in scene.warnings)
    scene = load(write(tmp_path, TRI.encode() + "o caf\u00e9\nf 1 2 3\n".encode("utf-8"), "u.obj"))
    assert scene.parts[0].name == "caf\u00e9" and scene.warnings == ()


def test_partial_uvs_and_normals_warn(tmp_path):
    text = TRI + "v 1 1 0\nvt 0.5 0.5\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\nf 2 4 3\n"
    scene = raw(write(tmp_path, text))
    part = scene.parts[0]
    assert part.uvs is not None and part.normals_computed
    assert any("no vt" in w for w in scene.warnings)
    assert any("no vn" in w for w in scene.warnings)
    # the corner without vt has uv (0, 0)
    i4 = int(np.flatnonzero((part.positions == [1, 1, 0]).all(axis=1))[0])
    np.testing.assert_array_equal(part.uvs[i4], [0, 0])


def test_no_faces_is_an_empty_scene(tmp_path):
    path = write(tmp_path, TRI + "l 1 2\n", "points.obj")
    scene = raw(path)
    assert scene.parts == () and scene.format == "obj" and scene.unit_scale == 1.0
    expect_error(path, "no triangle meshes")


# -- errors ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, fragments", [
    (TRI + "v 1 2 x\nf 1 2 3\n", ["line 4", "'x'"]),
    ("v 0 0 0\nv 1,5 0 0\nv 0 1 0\nf 1 2 3\n", ["line 2", "malformed number"]),
    ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", ["line 2", "got 2"]),
    (TRI + "vt 0 0 0 0\nf 1/1 2/1 3/1\n", ["line 4", "vt"]),
    (TRI + "vn 0 1\nf 1//1 2//1 3//1\n", ["line 4", "vn"]),
    ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", ["line 2", "NaN or Inf"]),
    ("v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n", ["line 3", "NaN or Inf"]),
    (TRI + "vt 0 nan\nf 1/1 2/1 3/1\n", ["line 4", "NaN or Inf"]),
    (TRI + "f 1 2 0\n", ["line 4", "index 0"]),
    (TRI + "vt 0 0\nf 1/1 2/0 3/1\n", ["line 5", "vt index 0"]),
    (TRI + "\n\nf 1 2 9\n", ["line 6", "index 9", "3 v records"]),
    (TRI + "f -1 -2 -4\n", ["line 4", "index -4", "3 v records before"]),
    (TRI + "vt 0 0\nf 1/1 2/2 3/1\n", ["line 5", "vt index 2", "1 vt records"]),
    (TRI + "f 1//1 2//1 3//1\n", ["line 4", "vn index 1", "0 vn records"]),
    (TRI + "f 1 2\n", ["line 4", "2 corners"]),
    (TRI + "f\n", ["line 4", "0 corners"]),
    (TRI + "f 1 2 a\n", ["line 4", "'a'"]),
    (TRI + "f 1 2 3.0\n", ["line 4", "3.0"]),
    (TRI + "f 1 2 1-3\n", ["line 4", "1-3"]),
    (TRI + "f 1/1/1/1 2 3\n", ["line 4", "1/1/1/1"]),
    (TRI + "f /1 2 3\n", ["line 4", "/1"]),
    ("v 0 0 \\\n0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n", ["line 5", "index 5"]),  # physical line numbers
])
def test_malformed_input_names_file_and_line(tmp_path, text, fragments):
    expect_error(write(tmp_path, text, "broken.obj"), *fragments)


def test_binary_content_is_an_error(tmp_path):
    expect_error(write(tmp_path, TRI.encode("utf-16"), "wide.obj"), "NUL")
    expect_error(write(tmp_path, b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "image.obj"), "binary")


def test_unreadable_path_is_an_error(tmp_path):
    with pytest.raises(LopcookError, match="cannot read"):
        objmod.load(str(tmp_path / "missing.obj"), fmt="obj", settings=SMOOTH)


def test_fuzzed_lines_never_raise_anything_but_lopcook_error(tmp_path, rng):
    alphabet = list("0123456789 -+/.#evtnfgo\\\t") + ["nan", "\n", "f ", "v ", "vt ", "vn "]
    base = TRI + "vt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\n"
    for k in range(60):
        junk = "".join(rng.choice(alphabet, size=int(rng.integers(1, 40))))
        path = write(tmp_path, base + junk + "\n", f"fuzz{k}.obj")
        try:
            load(path)
        except LopcookError as exc:
            assert path.name in str(exc)


# -- corpus ---------------------------------------------------------------------------------------
def assert_bounds(scene, meta):
    np.testing.assert_allclose(scene.bounds(), np.array(meta["bounds"]), atol=1e-6, rtol=0)


def test_corpus_bunny(corpus, corpus_meta):
    meta = corpus_meta["stanford-bunny.obj"]
    scene = load(corpus / "stanford-bunny.obj", SMOOTH)
    assert scene.format == "obj" and scene.unit_scale == 1.0 and scene.up_axis == "Y"
    (part,) = scene.parts
    # 35947 v records, 1113 unused: the per-corner split keeps the 34834 that faces use
    assert part.n_vertices == meta["vertices"] == 34834
    assert part.n_triangles == meta["triangles"] == 69451
    assert part.normals_computed and part.uvs is None
    assert_bounds(scene, meta)
    # at the default 60-degree crease angle the few sharp scan edges split some vertices
    default = load(corpus / "stanford-bunny.obj")
    assert default.parts[0].n_vertices >= 34834
    assert default.parts[0].n_triangles == 69451
    assert_bounds(default, meta)


def test_corpus_fandisk_creases(corpus, corpus_meta):
    meta = corpus_meta["fandisk.obj"]
    smooth = load(corpus / "fandisk.obj", SMOOTH)
    assert smooth.parts[0].n_vertices == meta["vertices"] == 6475
    assert smooth.n_triangles == 12946
    assert_bounds(smooth, meta)
    scene = load(corpus / "fandisk.obj")
    part = scene.parts[0]
    assert part.n_vertices > 6475  # feature lines split vertices
    assert part.n_triangles == 12946
    assert_bounds(scene, meta)
    # co-located copies (either side of a crease) have normals more than 30 degrees apart
    P, N = part.positions, part.normals.astype(np.float64)
    _, inv, cnt = np.unique(P, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    dup = np.flatnonzero(cnt[inv] > 1)
    assert dup.size == part.n_vertices - 6475 + np.count_nonzero(cnt > 1)
    order = dup[np.argsort(inv[dup], kind="stable")]
    grp = inv[order]
    head = np.r_[True, grp[1:] != grp[:-1]]
    first = order[np.maximum.accumulate(np.where(head, np.arange(order.size), 0))]
    other = ~head
    cos = np.einsum("ij,ij->i", N[first[other]], N[order[other]])
    assert cos.size > 0
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).min() > 30.0


def test_corpus_spot(corpus, corpus_meta):
    meta = corpus_meta["spot.obj"]
    scene = load(corpus / "spot.obj", SMOOTH)
    (part,) = scene.parts
    # 2930 positions, 3225 vt: each (v, vt) pair is a vertex, as trimesh counts it
    assert part.n_vertices == meta["vertices"] == 3225
    assert part.n_triangles == meta["triangles"] == 5856
    assert part.uvs is not None and part.uvs.shape == (3225, 2)
    assert np.unique(part.positions, axis=0).shape[0] == 2930
    # the uvs are the file's vt rows, v flipped (a few vt lie slightly outside [0, 1] in the file)
    vt = np.array([ln.split()[1:3] for ln in (corpus / "spot.obj").read_text().splitlines()
                   if ln.startswith("vt ")], dtype=np.float64)
    want = np.unique(np.stack([vt[:, 0], 1.0 - vt[:, 1]], axis=1).astype(np.float32), axis=0)
    np.testing.assert_array_equal(np.unique(part.uvs, axis=0), want)
    assert part.texture is None  # spot.obj names no mtllib; its texture is only a sidecar
    assert_bounds(scene, meta)
    default = load(corpus / "spot.obj")
    assert default.parts[0].n_vertices >= 3225
    assert_bounds(default, meta)


def test_zero_length_vn_is_replaced_with_a_warning(tmp_path):
    path = write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 0\nf 1//1 2//2 3//1\n")
    scene = load(path)
    (part,) = scene.parts
    assert np.allclose(part.normals[part.indices[0, 1]], [0.0, 1.0, 0.0])
    assert any("1 vn records have zero length (first on line 5)" in w for w in scene.warnings)
