"""Single- and double-sided parts: the importers read glTF's and USD's ``doubleSided``, and the
render harness culls the back faces of a single-sided part in the float reference and in every
decoded variant alike, as glTF and USD renderers do."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import cook_container
from tests.support import fixtures as fx
from lopcook.api import load
from lopcook.lop.reader import gpu_buffer
from lopcook.types import MeshPart, Scene
from lopcook.verify.buffers import source_order
from lopcook.verify.cameras import icosahedron_directions, make_camera, render_viewing
from lopcook.verify.renderer import Harness, Shading, decoded_items

RES = (96, 54)


def plate(double_sided: bool) -> Scene:
    """A 1 m square in z = 0, 8 x 8 quads, counter-clockwise seen from +z (its front)."""
    n = 9
    x, y = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n))
    pos = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    v = np.arange(n * n).reshape(n, n)
    a, b, c, d = v[:-1, :-1].ravel(), v[:-1, 1:].ravel(), v[1:, 1:].ravel(), v[1:, :-1].ravel()
    tri = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.uint32)
    nrm = np.tile(np.float32([0.0, 0.0, 1.0]), (n * n, 1))
    part = MeshPart("plate", pos, tri, normals=nrm, double_sided=double_sided)
    return Scene(parts=(part,), source="plate", format="obj").validate()


def views() -> list[tuple[int, bool]]:
    """(view, front seen) for the icosahedron views clearly off the plate's plane."""
    d = icosahedron_directions()
    return [(i, bool(d[i, 2] > 0)) for i in range(d.shape[0]) if abs(d[i, 2]) > 0.2]


@pytest.mark.parametrize("double_sided", [False, True])
def test_back_faces_of_a_single_sided_part_are_culled(gl, double_sided):
    scene = plate(double_sided)
    c = cook_container(scene)
    g = c.manifest["grid"]
    half = np.float32(float(g["extent"]) / float(1 << 24) / 2.0)
    vs = views()
    assert any(f for _, f in vs) and any(not f for _, f in vs)
    with Harness(scene, RES) as h:
        viewing = render_viewing(c.manifest, RES)
        shading = Shading.from_manifest(c.manifest)
        items, owned = decoded_items(h.ctx, h.renderer.decode_program, c, scene, [0], source_order(c, scene),
                                     h.textures, gpu_buffer, 12, g["origin"], half, {})
        assert items[0]["two_sided"] is double_sided and h.float_items[0]["two_sided"] is double_sided
        for view, front in vs:
            cam = make_camera(view, h.lo, h.hi, 2.0, viewing)
            for its, decoded in ((h.float_items, False), (items, True)):
                rgba, ids = h.renderer.draw(its, cam, shading, decoded)
                seen = bool(rgba[..., 3].any())
                assert seen == (front or double_sided), (view, front, decoded)
                assert bool(ids.any()) == seen
        for r in owned:
            r.release()


def test_the_draw_digest_tells_the_sides_apart(gl):
    keys = []
    for double_sided in (False, True):
        scene = plate(double_sided)
        c = cook_container(scene)
        g = c.manifest["grid"]
        with Harness(scene, RES) as h:
            items, owned = decoded_items(h.ctx, h.renderer.decode_program, c, scene, [0], source_order(c, scene),
                                         h.textures, gpu_buffer, 12, g["origin"],
                                         np.float32(float(g["extent"]) / float(1 << 24) / 2.0), {})
            keys.append(items[0]["digest"])
            for r in owned:
                r.release()
    assert keys[0] != keys[1]


def test_gltf_double_sided_is_read_per_material(tmp_path):
    path = fx.write_gltf(fx.seamed_cube(), tmp_path / "cube.gltf")[0]
    doc = json.loads(path.read_text())
    assert load(str(path)).parts[0].double_sided is False  # no material: glTF's default
    for value, expected in ((True, True), (False, False), ("yes", False)):
        doc["materials"] = [{"doubleSided": value}]
        for mesh in doc["meshes"]:
            for prim in mesh["primitives"]:
                prim["material"] = 0
        path.write_text(json.dumps(doc))
        assert load(str(path)).parts[0].double_sided is expected


def test_the_textured_fixture_keeps_its_double_sided_material(tmp_path):
    fx.write_textured_gltf(tmp_path / "textured.glb")
    scene = load(str(tmp_path / "textured.glb"))
    assert fx.TEXTURED_MATERIAL["doubleSided"] is True
    assert scene.parts and all(p.double_sided for p in scene.parts)


def test_usd_double_sided_is_read_per_mesh(tmp_path):
    from pxr import Usd, UsdGeom

    path = fx.write_usd(fx.seamed_cube() + [fx._transform_part(fx.seamed_cube()[0], fx._trs((3.0, 0.0, 0.0)),
                                                                 "other")], tmp_path / "two.usda")
    assert [p.double_sided for p in load(str(path)).parts] == [False, False]  # USD's fallback
    stage = Usd.Stage.Open(str(path))
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    UsdGeom.Mesh(meshes[1]).GetDoubleSidedAttr().Set(True)
    stage.GetRootLayer().Save()
    parts = load(str(path)).parts
    assert [p.double_sided for p in parts] == [False, True]


def test_obj_parts_are_single_sided(tmp_path):
    path = fx.write_obj(fx.seamed_cube(), tmp_path / "cube.obj")
    assert [p.double_sided for p in load(str(path)).parts] == [False]
