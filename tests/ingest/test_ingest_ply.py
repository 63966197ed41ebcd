"""PLY ingest (``lopcook/ingest/ply.py``): the corpus bunny written as PLY (ASCII, binary little-
and big-endian) cooks to the OBJ's bytes; small analytic cases (polygons, attributes, textures);
hostile files (truncated, lying counts, bad types, bad indices) give one error, exit 2."""

from __future__ import annotations

import io
import struct
import tracemalloc

import numpy as np
import pytest
from PIL import Image

from lopcook import DEFAULTS, cook
from lopcook.cli import main
from lopcook.errors import LopcookError
from lopcook.ingest import load, ply, sniff
from lopcook.ingest.materials import MaterialSet

_STRUCT = {"char": "b", "uchar": "B", "short": "h", "ushort": "H", "int": "i", "uint": "I", "float": "f",
           "double": "d"}


def write_ply(path, encoding: str, vertex: list[tuple[str, str, np.ndarray]], faces: list[list[int]] | None,
              *, count_type: str = "uchar", index_type: str = "int", comments=(), header_extra: str = "",
              elements_before_face=()) -> bytes:
    """Write a PLY file: ``vertex`` as (property name, type, values (n,)), ``faces`` as corner
    lists, ``elements_before_face`` as (name, [(prop, type)], rows) scalar elements. Returns the bytes."""
    n = len(vertex[0][2])
    lines = ["ply", f"format {encoding} 1.0", *(f"comment {c}" for c in comments), f"element vertex {n}"]
    lines += [f"property {t} {name}" for name, t, _ in vertex]
    for name, props, rows in elements_before_face:
        lines += [f"element {name} {len(rows)}"] + [f"property {t} {p}" for p, t in props]
    if faces is not None:
        lines += [f"element face {len(faces)}", f"property list {count_type} {index_type} vertex_indices"]
    head = ("\n".join(lines) + "\n" + header_extra + "end_header\n").encode("ascii")
    cols = [v for _, _, v in vertex]
    if encoding == "ascii":
        body = "".join(" ".join(repr(float(c[i])) if t in ("float", "double") else str(int(c[i]))
                                for (_, t, _), c in zip(vertex, cols)) + "\n" for i in range(n))
        for _, props, rows in elements_before_face:
            body += "".join(" ".join(str(x) for x in row) + "\n" for row in rows)
        body += "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces or [])
        data = head + body.encode("ascii")
    else:
        order = "<" if encoding == "binary_little_endian" else ">"
        rec = order + "".join(_STRUCT[t] for _, t, _ in vertex)
        body = b"".join(struct.pack(rec, *(c[i] for c in cols)) for i in range(n))
        for _, props, rows in elements_before_face:
            fmt = order + "".join(_STRUCT[t] for _, t in props)
            body += b"".join(struct.pack(fmt, *row) for row in rows)
        body += b"".join(struct.pack(f"{order}{_STRUCT[count_type]}{len(f)}{_STRUCT[index_type]}", len(f), *f)
                         for f in faces or [])
        data = head + body
    path.write_bytes(data)
    return data


def xyz(p: np.ndarray, t: str = "float") -> list[tuple[str, str, np.ndarray]]:
    return [("x", t, p[:, 0]), ("y", t, p[:, 1]), ("z", t, p[:, 2])]


def area(part) -> float:
    p = part.positions[part.indices.astype(np.int64)]
    return float(np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum() / 2)


def ply_error(path) -> LopcookError:
    with pytest.raises(LopcookError) as exc:
        load(path)
    assert exc.value.exit_code == 2 and str(path) in str(exc.value)
    return exc.value


# ---------------------------------------------------------------------------------------------
# the corpus bunny, OBJ and PLY
# ---------------------------------------------------------------------------------------------


def _obj_records(path) -> tuple[list[list[str]], list[list[int]]]:
    """The bunny OBJ's ``v`` tokens (as written) and faces (0-based)."""
    v, f = [], []
    for line in open(path):
        if line.startswith("v "):
            v.append(line.split()[1:4])
        elif line.startswith("f "):
            f.append([int(c.split("/")[0]) - 1 for c in line.split()[1:]])
    return v, f


def _without_source(c) -> dict:
    """The manifest without what names the source file and format."""
    m = {k: v for k, v in c.manifest.items() if k != "source"}
    m["parts"] = [{k: v for k, v in p.items() if k not in ("source", "mesh_key")} for p in m["parts"]]
    return m


@pytest.fixture(scope="module")
def bunny(corpus, tmp_path_factory):
    src = corpus / "stanford-bunny.obj"
    tokens, faces = _obj_records(src)
    return src, tokens, faces, tmp_path_factory.mktemp("ply_bunny")


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian"])
def test_bunny_ply_cooks_to_the_obj_bytes(bunny, encoding):
    """Written with the OBJ's own numbers (ASCII: its decimal text; binary: doubles of it), the PLY
    gives the OBJ's scene and a container whose sections (positions, indices, attributes) and
    manifest are the OBJ's, apart from the source file's record."""
    src, tokens, faces, tmp = bunny
    positions = np.array(tokens, dtype=np.float64)
    path = tmp / encoding / "stanford-bunny.ply"
    path.parent.mkdir()
    if encoding == "ascii":  # the OBJ's tokens verbatim
        body = "".join(" ".join(t) + "\n" for t in tokens) + "".join(
            f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces)
        path.write_bytes((f"ply\nformat ascii 1.0\nelement vertex {len(tokens)}\nproperty float x\nproperty float y\n"
                          f"property float z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\n"
                          "end_header\n" + body).encode())
    else:
        write_ply(path, encoding, xyz(positions, "double"), faces)
    assert sniff(str(path)) == "ply"
    obj_scene, ply_scene = load(src), load(path)
    a, b = obj_scene.parts[0], ply_scene.parts[0]
    assert a.positions.shape == b.positions.shape == (34900, 3)  # 35,947 records, 1,113 unused, crease splits
    for field in ("positions", "indices", "normals"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert b.uvs is None and b.colors is None and b.normals_computed and ply_scene.warnings == ()
    c_obj, c_ply = cook(obj_scene, DEFAULTS), cook(ply_scene, DEFAULTS)
    assert c_ply.manifest["source"]["format"] == "ply"
    assert c_obj.sections == c_ply.sections
    assert _without_source(c_obj) == _without_source(c_ply)


def test_bunny_big_endian_float32_reads_the_float32_values(bunny):
    """Stanford's scans store float32 (big- or little-endian): the PLY's positions are the float32
    values exactly, and its triangles the OBJ's."""
    src, tokens, faces, tmp = bunny
    p32 = np.array(tokens, dtype=np.float32)
    path = tmp / "bunny_be.ply"
    write_ply(path, "binary_big_endian", xyz(p32), faces)
    a, b = load(src).parts[0], load(path).parts[0]
    used = np.unique(np.asarray(faces).ravel())
    assert np.array_equal(b.indices, a.indices)
    assert b.positions.dtype == np.float64 and b.positions.shape == a.positions.shape
    # the same vertices (crease splits included) as the OBJ's, at float32 precision
    assert np.array_equal(np.unique(b.positions, axis=0), np.unique(p32[used].astype(np.float64), axis=0))
    assert np.abs(b.positions - a.positions).max() <= np.abs(a.positions).max() * 2.0 ** -24


# ---------------------------------------------------------------------------------------------
# analytic cases
# ---------------------------------------------------------------------------------------------

CUBE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
CUBE_QUADS = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
#: an L-shaped hexagon (area 3) that a fan from its corner 0 gets wrong: (2, 1) does not see (1, 2)
L_HEX = np.array([[2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0], [0, 0, 0], [2, 0, 0]], float)


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_quads_become_outward_triangles(tmp_path, encoding):
    path = tmp_path / "cube.ply"
    write_ply(path, encoding, xyz(CUBE), CUBE_QUADS)
    part = load(path).parts[0]
    assert part.indices.shape == (12, 3) and area(part) == pytest.approx(6.0, abs=1e-12)
    p = part.positions[part.indices.astype(np.int64)]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (np.einsum("ij,ij->i", n, p.mean(axis=1) - 0.5) > 0).all()  # every triangle faces outwards


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian"])
def test_concave_and_mixed_polygons_are_triangulated_like_obj(tmp_path, encoding):
    """A concave hexagon, a triangle and a quad in one file (list lengths differ: the record walk):
    4 + 1 + 2 triangles, the hexagon's area exactly 3, every triangle turning like its polygon."""
    pts = np.vstack([L_HEX, [[3, 0, 0], [4, 0, 0], [4, 1, 0], [5, 0, 0], [6, 0, 0], [6, 1, 0], [5, 1, 0]]])
    faces = [[0, 1, 2, 3, 4, 5], [6, 7, 8], [9, 10, 11, 12]]
    path = tmp_path / "mixed.ply"
    write_ply(path, encoding, xyz(pts), faces, count_type="uint", index_type="uint")
    part = load(path).parts[0]
    assert part.indices.shape == (7, 3)
    p = part.positions[part.indices.astype(np.int64)]
    z = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2]
    assert (z > 0).all()
    assert z[:4].sum() / 2 == pytest.approx(3.0, abs=1e-12) and z.sum() / 2 == pytest.approx(3.0 + 0.5 + 1.0)


def test_normals_colours_uvs_and_skipped_properties_are_exact(tmp_path):
    """nx ny nz are kept (not computed), uchar colours are c / 255, ``s t`` become (s, 1 - t),
    unused vertices are dropped in file order, other properties and elements are read past."""
    pts = np.array([[0, 0, 0], [9, 9, 9], [1, 0, 0], [0, 1, 0]], float)
    rgb = np.array([[255, 0, 10], [1, 2, 3], [0, 128, 255], [64, 32, 16]])
    st = np.array([[0.0, 0.0], [0.5, 0.5], [1.0, 0.25], [0.0, 1.0]])
    vertex = xyz(pts) + [("confidence", "float", np.ones(4)), ("nx", "float", np.zeros(4)),
                         ("ny", "float", np.zeros(4)), ("nz", "float", np.ones(4)),
                         ("red", "uchar", rgb[:, 0]), ("green", "uchar", rgb[:, 1]), ("blue", "uchar", rgb[:, 2]),
                         ("s", "float", st[:, 0]), ("t", "float", st[:, 1])]
    for encoding in ("ascii", "binary_little_endian"):
        path = tmp_path / f"attrs_{encoding}.ply"
        write_ply(path, encoding, vertex, [[0, 2, 3]],
                  elements_before_face=[("edge", [("vertex1", "int"), ("vertex2", "int")], [(0, 2), (2, 3)])])
        scene = load(path)
        part = scene.parts[0]
        keep = [0, 2, 3]
        assert np.array_equal(part.positions, pts[keep]) and part.indices.tolist() == [[0, 1, 2]]
        assert not part.normals_computed and np.array_equal(part.normals, np.tile([0, 0, 1], (3, 1)).astype(np.float32))
        assert np.array_equal(part.colors[:, :3], (rgb[keep] / 255.0).astype(np.float32))
        assert (part.colors[:, 3] == 1).all()
        assert np.array_equal(part.uvs, np.stack([st[keep, 0], 1 - st[keep, 1]], 1).astype(np.float32))
        assert part.name == path.stem and part.mesh_key == f"ply:{path.name}" and scene.format == "ply"


@pytest.mark.parametrize("names", [("u", "v"), ("texture_u", "texture_v")])
def test_uv_names_and_float_colours_with_alpha(tmp_path, names):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    vertex = xyz(pts) + [(names[0], "float", np.array([0.0, 1.0, 0.0])), (names[1], "float", np.array([0.0, 0.0, 1.0])),
                         ("red", "float", np.array([0.25, 1.5, 0.0])), ("green", "float", np.zeros(3)),
                         ("blue", "float", np.zeros(3)), ("alpha", "float", np.array([0.5, 1.0, 1.0]))]
    path = tmp_path / "uv.ply"
    write_ply(path, "binary_little_endian", vertex, [[0, 1, 2]])
    scene = load(path)
    part = scene.parts[0]
    assert part.uvs.tolist() == [[0.0, 1.0], [1.0, 1.0], [0.0, 0.0]]
    assert part.colors[:, 0].tolist() == [0.25, 1.0, 0.0] and part.colors[:, 3].tolist() == [0.5, 1.0, 1.0]
    assert any("clipped" in w for w in scene.warnings)


def _png(rgb=(200, 30, 40)) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", (4, 4), rgb).save(buf, format="PNG")
    return buf.getvalue()


def test_texture_file_comment_is_the_base_colour_texture(tmp_path, capsys):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    vertex = xyz(pts) + [("s", "float", pts[:, 0]), ("t", "float", pts[:, 1])]
    png = _png()
    (tmp_path / "skin.png").write_bytes(png)
    path = tmp_path / "tex.ply"
    write_ply(path, "ascii", vertex, [[0, 1, 2]], comments=["made by hand", "TextureFile skin.png"])
    scene = load(path)
    assert scene.parts[0].texture.data == png and str(tmp_path / "skin.png") in scene.dependencies
    out = MaterialSet()
    mats = ply.materials(str(path), [{"source": "(whole file)"}], out)
    assert mats[0]["pbrMetallicRoughness"]["baseColorTexture"] == {"index": 0}
    assert mats[0]["pbrMetallicRoughness"]["metallicFactor"] == 0.0 and out.images[0]["data"] == png
    # decode carries it into the preview
    lop, glb = tmp_path / "tex.lop", tmp_path / "tex_preview.glb"
    assert main(["cook", str(path), "-o", str(lop), "-q"]) == 0
    assert main(["decode", str(lop), "--level", "16", "-o", str(glb), "-q"]) == 0
    assert png in glb.read_bytes()
    (tmp_path / "skin.png").unlink()
    scene = load(path)
    assert scene.parts[0].texture is None and any("skin.png" in w and "not found" in w for w in scene.warnings)
    assert str(tmp_path / "skin.png") in scene.dependencies  # a build reruns when it appears


def test_the_cli_cooks_a_ply_and_lists_it(tmp_path, capsys):
    path = tmp_path / "cube.ply"
    write_ply(path, "binary_little_endian", xyz(CUBE), CUBE_QUADS)
    assert main(["cook", str(path), "-o", str(tmp_path / "cube.lop"), "-q"]) == 0
    with pytest.raises(SystemExit):
        main(["--formats"])
    assert any(line.split()[:3] == ["ply", "PLY", ".ply"] and line.endswith("available")
               for line in capsys.readouterr().out.splitlines())


# ---------------------------------------------------------------------------------------------
# hostile files
# ---------------------------------------------------------------------------------------------


def _triangle(tmp_path, encoding="binary_little_endian", **kw) -> tuple:
    path = tmp_path / "t.ply"
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    return path, write_ply(path, encoding, xyz(pts), [[0, 1, 2]], **kw)


@pytest.mark.parametrize("cut", [1, 13, 40])
def test_truncated_binary_is_one_error(tmp_path, cut):
    path, data = _triangle(tmp_path)
    path.write_bytes(data[:-cut])
    text = str(ply_error(path))
    assert "truncated" in text or "bytes follow the header" in text


def test_truncated_ascii_is_one_error(tmp_path):
    path, data = _triangle(tmp_path, "ascii")
    path.write_bytes(data[:-4])
    assert "truncated" in str(ply_error(path))


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian"])
def test_a_lying_vertex_count_is_refused_before_allocating(tmp_path, encoding):
    path, data = _triangle(tmp_path, encoding)
    path.write_bytes(data.replace(b"element vertex 3", b"element vertex 1000000000000"))
    tracemalloc.start()
    try:
        text = str(ply_error(path))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "declares 1,000,000,000,000 records" in text and peak < 10 * len(data) + (1 << 20)


def test_a_lying_list_length_is_refused(tmp_path):
    path, data = _triangle(tmp_path)
    head = data.index(b"end_header\n") + len(b"end_header\n")
    face_at = head + 3 * 12
    path.write_bytes(data[:face_at] + bytes([255]) + data[face_at + 1:])
    assert "truncated" in str(ply_error(path))


@pytest.mark.parametrize("header, needle", [
    ("property flt w\n", "unknown property type 'flt'"),
    ("property list float int w\n", "must be an integer type"),
    ("property int\n", "is not 'property TYPE NAME'"),
    ("frobnicate 3\n", "unknown header keyword"),
])
def test_bad_property_types_and_header_lines(tmp_path, header, needle):
    path, _ = _triangle(tmp_path, header_extra=header)
    assert needle in str(ply_error(path))


def test_float_indices_and_bad_formats_are_refused(tmp_path):
    path, _ = _triangle(tmp_path, "ascii", index_type="float")
    assert "must be of an integer type" in str(ply_error(path))
    path, data = _triangle(tmp_path, "ascii")
    path.write_bytes(data.replace(b"format ascii 1.0", b"format ascii 2.0"))
    assert "is not 'format" in str(ply_error(path))
    path.write_bytes(data.replace(b"end_header", b"end_heada"))
    assert "no 'end_header'" in str(ply_error(path))
    path.write_bytes(data.replace(b"3 0 1 2", b"3 0 1.5 2"))
    assert "not an integer" in str(ply_error(path))
    path.write_bytes(data.replace(b"3 0 1 2", b"3 0 one 2"))
    assert "'one', which is not a number" in str(ply_error(path))


@pytest.mark.parametrize("face, needle", [([0, 1, 7], "refers to vertex 7, out of range for 3"),
                                          ([0, -1, 2], "refers to vertex -1")])
def test_bad_indices_name_the_face(tmp_path, face, needle):
    path = tmp_path / "bad.ply"
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    write_ply(path, "binary_little_endian", xyz(pts), [[0, 1, 2], face])
    assert f"face 1 {needle}" in str(ply_error(path))


def test_faces_of_fewer_than_three_corners(tmp_path):
    path = tmp_path / "short.ply"
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    write_ply(path, "ascii", xyz(pts), [[0, 1], [0, 1, 2], [2]])
    scene = load(path)
    assert scene.n_triangles == 1 and any("2 faces with fewer than 3 corners skipped" in w for w in scene.warnings)
    write_ply(path, "ascii", xyz(pts), [[0, 1], [2]])
    ply_error(path)  # no triangle at all


def test_hostile_ply_through_the_cli_is_one_line_exit_2(tmp_path, capsys):
    path, data = _triangle(tmp_path)
    path.write_bytes(data.replace(b"element vertex 3", b"element vertex 99999999999"))
    rc = main(["cook", str(path), "-o", str(tmp_path / "t.lop")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err and not (tmp_path / "t.lop").exists()
    glb_named_ply = tmp_path / "x.ply"
    glb_named_ply.write_bytes(b"glTF" + bytes(60))
    with pytest.raises(LopcookError) as exc:
        sniff(str(glb_named_ply))
    assert "content is glb, which a .ply file cannot hold" in str(exc.value)


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_mutated_files_give_a_scene_or_one_lopcook_error(tmp_path, encoding):
    """500 seeded mutations (bytes flipped, cut, inserted) of a small PLY with attributes and mixed
    polygons: the reader itself (``ply.load``, before the generic safety net of ``ingest.load``)
    returns a scene or raises LopcookError, never anything else."""
    from lopcook.settings import DEFAULT_INGEST

    pts = np.vstack([L_HEX, [[3, 0, 0], [4, 0, 0], [4, 1, 0]]])
    vertex = xyz(pts) + [("nx", "float", np.zeros(9)), ("ny", "float", np.zeros(9)), ("nz", "float", np.ones(9)),
                         ("red", "uchar", np.arange(9) * 20), ("green", "uchar", np.zeros(9, int)),
                         ("blue", "uchar", np.zeros(9, int))]
    clean = write_ply(tmp_path / "clean.ply", encoding, vertex, [[0, 1, 2, 3, 4, 5], [6, 7, 8]])
    rng = np.random.default_rng(41)
    path = tmp_path / "m.ply"
    outcomes = {"scene": 0, "error": 0}
    for _ in range(500):
        data = bytearray(clean)
        for _ in range(int(rng.integers(1, 4))):
            at = int(rng.integers(0, len(data)))
            kind = int(rng.integers(0, 3))
            if kind == 0:
                data[at] = int(rng.integers(0, 256))
            elif kind == 1:
                del data[at:]
                data += bytes(1) if not data else b""
            else:
                data[at:at] = bytes(rng.integers(0, 256, int(rng.integers(1, 9)), dtype=np.uint8))
        path.write_bytes(bytes(data))
        try:
            ply.load(str(path), settings=DEFAULT_INGEST)
            outcomes["scene"] += 1
        except LopcookError as exc:
            assert exc.exit_code == 2 and str(path) in str(exc)
            outcomes["error"] += 1
    assert outcomes["scene"] > 0 and outcomes["error"] > 0


def test_face_records_with_scalars_around_a_list_of_mixed_lengths(tmp_path):
    """``uchar flags``, the list, ``float quality`` per face, lengths 3 and 4 (the record walk):
    the lists are read between the scalars, in both byte orders and in ASCII."""
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], float)
    faces = [[0, 1, 2, 3], [1, 4, 2]]
    for encoding in ("ascii", "binary_little_endian", "binary_big_endian"):
        head = (f"ply\nformat {encoding} 1.0\nelement vertex 5\nproperty double x\nproperty double y\n"
                "property double z\nelement face 2\nproperty uchar flags\nproperty list uchar ushort vertex_indices\n"
                "property float quality\nend_header\n").encode()
        if encoding == "ascii":
            body = "".join(f"{x} {y} {z}\n" for x, y, z in pts) + "7 4 0 1 2 3 0.5\n9 3 1 4 2 0.25\n"
            data = head + body.encode()
        else:
            o = "<" if encoding == "binary_little_endian" else ">"
            data = head + b"".join(struct.pack(o + "ddd", *p) for p in pts)
            data += b"".join(struct.pack(f"{o}BB{len(f)}Hf", flag, len(f), *f, q)
                             for flag, f, q in ((7, faces[0], 0.5), (9, faces[1], 0.25)))
        path = tmp_path / f"scalars_{encoding}.ply"
        path.write_bytes(data)
        part = load(path).parts[0]
        assert part.indices.shape == (3, 3) and area(part) == pytest.approx(1.5, abs=1e-12)
        assert np.array_equal(part.positions, pts)
