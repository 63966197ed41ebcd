"""The GL side of the render harness (lopcook.verify.renderer): framebuffers, part IDs, textures,
shading inputs. GL tests skip when EGL is missing, except under CI=true, where they fail."""

from __future__ import annotations

import io

import numpy as np
import pytest

from conftest import cook_container
from lopcook.errors import LopcookError
from lopcook.types import MeshPart, Scene, Texture
from lopcook.verify import cameras as C
from lopcook.verify import renderer as RR
from lopcook.verify.evaluate import evaluate
from lopcook.viewing import Viewing

SMALL = (320, 180)


def test_part_ids_and_images(gl, plates):
    s, c = plates
    r = evaluate(c, s, levels=[8], views=[0], resolution=SMALL, keep_images=True, image_view=0)
    im = r["images"]
    h, w = SMALL[1], SMALL[0]
    for k in ("float", "ap", "cap"):
        assert im[k].shape == (h, w, 4) and im[k].dtype == np.uint8
        assert im[f"{k}_ids"].shape == (h, w) and im[f"{k}_ids"].dtype == np.uint32
    for k in ("ap_heatmap", "cap_heatmap"):
        assert im[k].shape == (h, w, 3) and im[k].dtype == np.uint8
    ids = set(np.unique(im["float_ids"]).tolist())
    assert ids <= {0, 1, 2} and 0 in ids and len(ids) >= 2
    # the object covers what its ID covers (sample 0 within a covered pixel)
    assert np.all(im["float"][..., 3][im["float_ids"] > 0] > 0)
    assert im["level"] == 8 and im["view"] == 0


def test_textured_part_samples_its_base_colour(gl):
    """A base-colour texture reaches the render (float, AP and CAP alike); CAP at 24 still matches."""
    from PIL import Image

    from tests.support import fixtures as F

    img = np.zeros((64, 64, 3), np.uint8)
    img[:] = (230, 30, 30)
    img[:, (np.arange(64) // 8) % 2 == 1] = (30, 200, 30)  # stripes: both colours on every atlas cell
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")
    cube = F.seamed_cube()[0]
    part = MeshPart("cube", cube.positions, cube.indices, normals=cube.normals, uvs=cube.uvs,
                    texture=Texture("checker.png", buf.getvalue()))
    s = Scene((part,), "textured", "glb").validate()
    c = cook_container(s)
    r = evaluate(c, s, levels=[24, 8], camera_levels=[9, 8], views=4, resolution=SMALL, keep_images=True,
                   image_view=0, attributes="source")  # positions only: the container's UVs are quantised
    rows = r["levels"]
    assert all(p is None or p >= 60.0 for p in rows[0]["cap"]["psnr_views"])
    rgb = r["images"]["float"][..., :3].astype(int)
    covered = r["images"]["float"][..., 3] == 255
    red = (rgb[..., 0] > rgb[..., 1] + 40) & covered
    green = (rgb[..., 1] > rgb[..., 0] + 40) & covered
    assert red.sum() > 20 and green.sum() > 20



def test_bad_resolution_is_a_usage_error(gl):
    with pytest.raises(LopcookError, match="resolution"):
        RR.Renderer((0, 36))


def _facing_quad(view: int) -> Scene:
    """A 1 m square through the origin facing icosahedron view ``view``, without normals."""
    u = C.icosahedron_directions()[view]
    a = np.cross(u, [0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    b = np.cross(u, a)
    pos = 0.5 * np.array([-a - b, a - b, a + b, -a + b])
    return Scene((MeshPart("quad", pos, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), None),), "quad", "glb")


def test_flat_face_towards_the_headlight_is_ambient_plus_diffuse(gl):
    """A face normal to the light (the headlight shines from the eye's direction): N.L = 1, so with
    ks = 0 every covered pixel is base * (ambient + diffuse) = 0.8 * 0.8 = 0.64, i.e. 163 of 255;
    empty pixels are (0, 0, 0, 0) with part ID 0, covered ones carry part ID 1."""
    scene = _facing_quad(0)
    lo, hi = scene.bounds()
    viewing = Viewing(viewport=(64, 36))
    cam = C.make_camera(0, lo, hi, 1.5, viewing)
    r = RR.Renderer((64, 36), samples=4)
    tex = RR.Textures(r.ctx)
    items, owned = RR.float_items(r.ctx, r.float_program, scene, tex)
    try:
        empty_rgba, empty_ids = r.draw([], cam, RR.Shading(ks=0.0), decoded=False)
        rgba, ids = r.draw(items, cam, RR.Shading(ks=0.0), decoded=False)
    finally:
        for o in owned:
            o.release()
        tex.release()
        r.release()
    assert rgba.shape == (36, 64, 4) and ids.shape == (36, 64)
    assert not empty_rgba.any() and not empty_ids.any()
    full = rgba[..., 3] == 255
    assert full.sum() > 100 and set(np.unique(ids[full]).tolist()) == {1}
    expected = round(255 * RR.BASE_GREY * (RR.AMBIENT + RR.DIFFUSE))
    assert np.abs(rgba[full][:, :3].astype(int) - expected).max() <= 1


def test_shading_parameters_from_the_manifest():
    assert RR.Shading.from_manifest({}) == RR.Shading(ks=0.5, shininess=32.0)
    m = {"options": {"analyse": {"ks": 0.25, "shininess": 8}}}
    assert RR.Shading.from_manifest(m) == RR.Shading(ks=0.25, shininess=8.0)
    assert RR.Shading.from_manifest(m, ks=1.0, shininess=2.0) == RR.Shading(ks=1.0, shininess=2.0)
    d = RR.Shading().as_dict()
    assert d["model"] == "phong" and (d["ambient"], d["diffuse"], d["base_grey"]) == (0.15, 0.65, 0.8)
