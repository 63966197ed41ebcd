"""The hierarchy in the container (lopcook.hierarchy.container, cook --hierarchy, refine, inspect).

Round trips through the container's sections, the section's byte flips, the prefix property, the
cut's edges (no holes: its boundary chain is the image of the input's), renders of cuts against
the float source at three cameras (render harness; GL skipped without EGL, a failure under
CI=true), and the CLI. The chess set is covered by benchmarks/bench_connectivity.py (its build
takes about 80 s), not here.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import FIXTURES
from lopcook import api
from lopcook.cli import main
from lopcook.lop.container import from_bytes
from lopcook.lop.summary import describe_container
from lopcook.errors import LopcookError
from lopcook.hierarchy.container import VARIANT_NAME, read_part, refine
from lopcook.hierarchy.select import select_cut
from lopcook.hierarchy.tree import boundary_vertices
from lopcook.mesh import canonical_triangles as canonical
from lopcook.settings import DEFAULTS, Settings, SimplifySettings, parse_lods

HIER = Settings(simplify=SimplifySettings(hierarchy=True))
CORPUS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
          "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd"]
RES = (320, 180)
#: camera levels of the render check (far, middle, near) and the pixel tolerance of those cuts:
#: at 0.5 px a cut's silhouette moves by up to half a pixel, which the far camera's few hundred
#: object pixels see as 26-35 dB; 0.1 px keeps every camera of every corpus asset above 40 dB
#: (docs/hierarchy.md, section 7)
CAMERA_LEVELS = (6, 8, 10)
CUT_PIXEL_ERROR = 0.1


def chain(tri) -> dict:
    """The oriented boundary chain of a triangle soup: undirected edge (a < b) -> number of times
    a->b appears minus b->a, nonzero entries only. Zero everywhere: every edge is shared by
    oppositely oriented triangles (a closed surface)."""
    t = np.asarray(tri, np.int64)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return _edge_sum(e)


def _edge_sum(e) -> dict:
    e = e[e[:, 0] != e[:, 1]]
    sign = np.where(e[:, 0] < e[:, 1], 1, -1)
    key = np.sort(e, axis=1)
    uk, inv = np.unique(key, axis=0, return_inverse=True)
    s = np.bincount(inv.ravel(), weights=sign, minlength=uk.shape[0]).astype(np.int64)
    return {(int(a), int(b)): int(v) for (a, b), v in zip(uk, s) if v}


def cut_node_of_vertex(h, cut) -> np.ndarray:
    """(n,) the cut node (preorder ID) above every LOD 0 vertex."""
    order = np.argsort(h.lo[cut.nodes])
    leaf_of_vertex = np.empty(h.n_leaves, np.int64)
    leaf_of_vertex[h.vertex_of_leaf] = np.arange(h.n_leaves)
    j = np.searchsorted(h.lo[cut.nodes][order], leaf_of_vertex, side="right") - 1
    return cut.nodes[order][j]


@pytest.fixture(scope="module")
def cooked(corpus, cooks):
    """``cooked(name)``: (scene, container) of a corpus asset cooked with a hierarchy (``cooks.api``)."""
    return lambda name: cooks.api(corpus / name, HIER)


def _lod0(c, i):
    from lopcook.lop.reader import lod_attributes

    t = lod_attributes(c, i, 0)["indices"].astype(np.int64)
    return t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])]


@pytest.mark.parametrize("name", CORPUS)
def test_corpus_triangles_round_trip_through_the_container(cooked, name):
    """Every part's LOD 0 triangles come back exactly from its section, read from the bytes."""
    _, built = cooked(name)
    c = from_bytes(built.data)
    for i, p in enumerate(c.manifest["parts"]):
        rec = p["hierarchy"]
        assert rec["section"] == f"part{i}/lod0/hierarchy" and rec["variant"] == VARIANT_NAME
        h, _, _ = read_part(c, i)
        tri = _lod0(c, i)
        assert rec["triangles"] == tri.shape[0] and rec["leaves"] == p["lods"][0]["vertices"]
        assert np.array_equal(canonical(h.triangles()), canonical(tri))
        assert rec["connectivity_bits"] == h.bits["connectivity"]
        # the boundary bits of the back-face rule are those of LOD 0's triangles
        assert np.array_equal(h.open_leaf, boundary_vertices(tri, h.n_leaves)[h.vertex_of_leaf])
    names = [s["name"] for s in c.manifest["sections"]]
    first_position = names.index("positions/mandatory")
    assert all(names.index(p["hierarchy"]["section"]) < first_position for p in c.manifest["parts"])


def test_node_positions_are_lod0_positions_at_every_level(cooked):
    """Nodes decode bit for bit as their LOD 0 vertex does, at every level (crack-free)."""
    from lopcook.lop.reader import decode_positions

    _, c = cooked("fandisk.obj")
    for level in (1, 7, 24):
        h, q, _ = read_part(c, 0, level)
        qq, _, _ = decode_positions(c, 0, 0, level)
        assert np.array_equal(h.node_positions, qq[h.vertex_of_leaf[h.node_leaf]])


def test_default_cook_unchanged_and_settings_round_trip(corpus):
    scene = api.load(FIXTURES / "seamed_cube.glb")
    plain, hier = api.cook(scene, DEFAULTS), api.cook(scene, HIER)
    assert "hierarchy" not in plain.manifest["options"]
    assert all("hierarchy" not in p for p in plain.manifest["parts"])
    assert not any(s["name"].endswith("hierarchy") for s in plain.manifest["sections"])
    assert hier.manifest["options"]["hierarchy"] is True
    assert api.cook(scene, HIER).data == hier.data  # deterministic
    assert Settings.from_manifest(hier.manifest) == HIER
    assert Settings.from_manifest(plain.manifest) == DEFAULTS
    # the position sections and every other section are the same bytes
    for name, data in plain.sections.items():
        assert hier.sections[name] == data
    with_lods = Settings(simplify=SimplifySettings(lods=parse_lods("1/2"), hierarchy=True))
    assert Settings.from_manifest(with_lods.to_manifest()) == with_lods
    bad = dict(hier.manifest, options=dict(hier.manifest["options"], hierarchy="yes"))
    with pytest.raises(LopcookError, match="hierarchy"):
        Settings.from_manifest(bad)


def test_manifest_matches_the_schema(cooked):
    import jsonschema
    from conftest import REPO

    schema = json.loads((REPO / "schema" / "container.schema.json").read_text())
    _, c = cooked("CesiumMilkTruck.glb")
    jsonschema.Draft202012Validator(schema).validate(c.manifest)


def test_byte_flips_in_the_section_are_detected(cooked):
    """A flip anywhere in the section fails the container's CRC; with the container CRC mended,
    the blob's own CRC (or its shape checks) still refuses it."""
    from lopcook.lop.container import to_bytes

    _, c = cooked("spot.obj")
    entry = next(s for s in c.manifest["sections"] if s["name"] == "part0/lod0/hierarchy")
    base = len(c.data) - sum(s["length"] for s in c.manifest["sections"])
    for k in np.linspace(0, entry["length"] - 5, 9).astype(int):
        data = bytearray(c.data)
        data[base + entry["offset"] + k] ^= 0x10
        with pytest.raises(LopcookError, match="part0/lod0/hierarchy.*checksum"):
            from_bytes(bytes(data))
        sections = dict(c.sections)
        blob = bytearray(sections["part0/lod0/hierarchy"])
        blob[k] ^= 0x10
        sections["part0/lod0/hierarchy"] = bytes(blob)
        manifest = {key: v for key, v in c.manifest.items() if key != "sections"}
        mended = from_bytes(to_bytes(manifest, [(s["name"], sections[s["name"]]) for s in c.manifest["sections"]]))
        with pytest.raises(LopcookError):
            read_part(mended, 0)


def test_prefix_file_still_refines(cooked):
    """A file cut after plane 16 keeps every hierarchy section and refines at levels <= 16."""
    _, c = cooked("spot.obj")
    names = [s["name"] for s in c.manifest["sections"]]
    end = sum(s["length"] for s in c.manifest["sections"][:names.index("positions/plane16") + 1])
    prefix = c.data[:len(c.data) - sum(s["length"] for s in c.manifest["sections"]) + end]
    p = from_bytes(prefix, allow_prefix=True)
    assert p.available_level == 16
    meshes = refine(p, [0.0, 0.3, 0.05], [0.0, 0.3, 0.0], viewport=(640, 480))
    assert meshes[0]["stats"]["level"] <= 16 and meshes[0]["indices"].shape[0] > 0


def _cameras(scene, c):
    from lopcook.verify.cameras import camera_distance, make_camera
    from lopcook.viewing import Viewing

    lo = np.min([p.positions.min(axis=0) for p in scene.parts], axis=0)
    hi = np.max([p.positions.max(axis=0) for p in scene.parts], axis=0)
    v = Viewing(viewport=RES)
    extent = float(c.manifest["grid"]["extent"])
    return [(level, make_camera(0, lo, hi, camera_distance(level, extent, v), v)) for level in CAMERA_LEVELS]


@pytest.mark.parametrize("name", ["stanford-bunny.obj", "fandisk.obj"])
def test_cut_has_no_holes(cooked, name):
    """At each camera the cut's oriented boundary chain is the image of LOD 0's boundary under
    the cut's vertex clustering: every edge of the cut is shared exactly as in the full mesh
    (a closed region stays closed, nothing opens), and its triangles are the clustered input."""
    scene, c = cooked(name)
    h, _, _ = read_part(c, 0)
    tri = _lod0(c, 0)
    full_boundary = chain(tri)
    for _, cam in _cameras(scene, c):
        cut = select_cut(h, cam.eye, cam.centre, viewport=RES, pixel_error=CUT_PIXEL_ERROR, backface=True)
        assert 0 < cut.triangles.shape[0] < tri.shape[0]
        node = cut_node_of_vertex(h, cut)
        got = chain(cut.nodes[cut.triangles])
        edges = np.array(list(full_boundary), np.int64).reshape(-1, 2)
        mult = np.array(list(full_boundary.values()), np.int64)
        image = node[np.repeat(edges, np.abs(mult), axis=0)]
        image[np.repeat(mult, np.abs(mult)) < 0] = image[np.repeat(mult, np.abs(mult)) < 0][:, ::-1]
        assert got == _edge_sum(image)
        mapped = node[tri]
        keep = (mapped[:, 0] != mapped[:, 1]) & (mapped[:, 1] != mapped[:, 2]) & (mapped[:, 0] != mapped[:, 2])
        assert np.array_equal(canonical(cut.nodes[cut.triangles]), canonical(mapped[keep]))


@pytest.mark.parametrize("backface", [False, True])
@pytest.mark.parametrize("name", ["stanford-bunny.obj", "fandisk.obj", "CesiumMilkTruck.glb"])
def test_cut_renders_within_40_db_of_float(gl, cooked, name, backface):
    """refine's meshes for a far, a middle and a near camera render at >= 40 dB against the
    float source at that camera (the harness's shading and metrics; UVs, colours and textures
    kept), with and without Hoppe's back-face test; with it (refine's default) the far cut has
    fewer triangles than LOD 0, and under 70 % of them on the closed bunny and fandisk
    (measured: 62 % and 61 %). The truck's parts are open along their UV seams almost
    everywhere, where the back-face test does not apply (its far camera gave 35.9 dB when it
    did: docs/hierarchy.md, section 5)."""
    from lopcook.types import MeshPart, Scene
    from lopcook.verify.evaluate import evaluate_scene

    scene, c = cooked(name)
    extent = float(c.manifest["grid"]["extent"])
    textures = {p.name: p.texture for p in scene.parts}
    counts = []
    for level, cam in _cameras(scene, c):
        meshes = refine(c, cam.eye, cam.centre, fov=60.0, viewport=RES, pixel_error=CUT_PIXEL_ERROR,
                        backface=backface)
        test = Scene(tuple(MeshPart(m["name"], m["positions"].astype(np.float64), m["indices"].astype(np.uint32),
                                    normals=m["normals"], uvs=m["uvs"], colors=m["colors"],
                                    texture=textures.get(m["name"])) for m in meshes), "cut", "glb")
        r = evaluate_scene(test, scene, levels=[level], views=[0], resolution=RES, extent=extent)
        psnr = r["levels"][0]["scene"]["psnr_min"]
        assert psnr is None or psnr >= 40.0, (level, psnr)
        assert r["levels"][0]["scene"]["object_pixels"] > 100
        counts.append(sum(m["stats"]["triangles"] for m in meshes))
    lod0 = sum(p["lods"][0]["triangles"] for p in c.manifest["parts"])
    assert counts[0] <= lod0
    if backface:  # without it, 0.1 px at this far camera keeps (nearly) every triangle
        assert counts[0] < lod0, (counts, lod0)
        if name != "CesiumMilkTruck.glb":
            assert counts[0] < 0.7 * lod0, (counts, lod0)


def test_cli_cook_inspect_refine(tmp_path, gltf_validator, capsys):
    src = str(FIXTURES / "seamed_cube.glb")
    out = tmp_path / "h.lop"
    assert main(["-q", "cook", src, "-o", str(out), "--hierarchy"]) == 0
    capsys.readouterr()
    assert main(["inspect", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    hs = d["parts"][0]["hierarchy"]
    rec = from_bytes(out.read_bytes()).manifest["parts"][0]["hierarchy"]
    assert hs["bits_per_triangle"] == rec["connectivity_bits"] / rec["triangles"]
    assert hs["structure_bits_per_triangle"] == rec["nodes"] / rec["triangles"]
    assert hs["position_bits_per_vertex"] > 3  # at least the mandatory bits
    assert describe_container(from_bytes(out.read_bytes()))["parts"][0]["hierarchy"] == hs
    glb = tmp_path / "view.glb"
    assert main(["refine", str(out), "--camera", "2,1.5,3", "--target", "0,0,0", "--viewport", "640x480",
                 "-o", str(glb), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["written"] == [str(glb)] and 0 < r["triangles"] <= r["lod0_triangles"]
    report = gltf_validator.validate(glb)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, \
        gltf_validator.problems(report)


def test_cli_refine_bad_input(tmp_path, capsys):
    src = str(FIXTURES / "seamed_cube.glb")
    plain = tmp_path / "plain.lop"
    assert main(["-q", "cook", src, "-o", str(plain)]) == 0
    glb = str(tmp_path / "v.glb")
    cases = [(["--camera", "1,2", "--target", "0,0,0"], "--camera"),
             (["--camera", "1,2,3", "--target", "0,0,nan"], "--target"),
             (["--camera", "1,2,3", "--target", "0,0,0", "--fov", "200"], "--fov"),
             (["--camera", "1,2,3", "--target", "0,0,0", "--pixel-error", "0"], "--pixel-error"),
             (["--camera", "1,2,3", "--target", "0,0,0"], "no hierarchy")]
    for extra, what in cases:
        assert main(["refine", str(plain), *extra, "-o", glb]) == 2
        assert what in capsys.readouterr().err
    assert main(["refine", str(plain), "--camera", "0,0,0", "--target", "0,0,0", "-o", str(tmp_path / "v.txt")]) == 2


def test_bench_connectivity_writes_json_and_chart(tmp_path, corpus):
    """``lopcook bench --connectivity`` on one small asset: the results and the chart; the index
    shrinks as the random-access unit grows (fewer nodes hold an entry)."""
    for module in ("meshoptimizer", "DracoPy", "matplotlib"):
        pytest.importorskip(module)
    assert main(["-q", "bench", "--connectivity", "-o", str(tmp_path), str(corpus / "UtahTeapot.usd")]) == 0
    (res,) = json.loads((tmp_path / "connectivity.json").read_text()).values()
    index = [res["index_bits_per_triangle"][str(u)] for u in (1, 8, 64, 512, 4096)]
    assert all(a >= b for a, b in zip(index, index[1:])) and index[0] > index[-1]
    assert res["bits_per_triangle"]["proposed_plus"]["bits"] < res["bits_per_triangle"]["proposed"]["bits"]
    assert (tmp_path / "connectivity_unit_size.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_hierarchy_with_lods_and_dropped_planes():
    """With a LOD chain and a nearest distance (the savings path) the hierarchy is LOD 0's, the
    savings record counts it on both sides, and LOD 0's triangles still round-trip."""
    from dataclasses import replace

    scene = api.load(FIXTURES / "unit_sphere.glb")
    s = Settings(simplify=SimplifySettings(lods=parse_lods("1/2"), hierarchy=True))
    s = replace(s, viewing=replace(s.viewing, nearest_m=5.0))
    c = from_bytes(api.cook(scene, s).data)
    plain = from_bytes(api.cook(scene, replace(s, simplify=replace(s.simplify, hierarchy=False))).data)
    added = len(c.sections["part0/lod0/hierarchy"])
    assert len(c.data) - len(plain.data) >= added
    assert c.manifest["positions"]["max_level"] < 24 and len(c.manifest["parts"][0]["lods"]) == 2
    assert c.manifest["savings"]["bytes_without_savings"] - plain.manifest["savings"]["bytes_without_savings"] \
        == len(c.data) - len(plain.data)
    h, _, _ = read_part(c, 0)
    assert np.array_equal(canonical(h.triangles()), canonical(_lod0(c, 0)))
