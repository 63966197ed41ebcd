"""Renderer culling: an item whose box lies beyond a clip plane is not drawn, and the images are the
same bits as drawing every item over the whole viewport (float and decoded items, far views where
everything is seen and close-ups where most parts are off-screen or behind the eye)."""

from __future__ import annotations

import numpy as np

from conftest import cook_container
from lopcook import fixtures as fx
from lopcook.emit.reader import gpu_buffer
from lopcook.types import MeshPart, Scene
from lopcook.verify.buffers import source_order
from lopcook.verify.cameras import camera_distance, make_camera, render_viewing
from lopcook.verify.renderer import Harness, Renderer, Shading, decoded_items


def row_of_spheres() -> Scene:
    """Seven spheres 3 m apart along x: a close camera sees one or two of them."""
    base = fx.unit_sphere(2)[0]
    parts = [MeshPart(f"s{k}", base.positions + [3.0 * k, 0.0, 0.0], base.indices, normals=base.normals)
             for k in range(7)]
    return Scene(parts=tuple(parts), source="row", format="obj").validate()


def test_culled_draws_equal_drawing_everything(gl):
    scene = row_of_spheres()
    c = cook_container(scene)
    res = (160, 90)
    culled = 0
    with Harness(scene, res) as h:
        g = c.manifest["grid"]
        viewing = render_viewing(c.manifest, res)
        shading = Shading.from_manifest(c.manifest)
        cache: dict = {}
        for level in (6, 12, 15):
            items, owned = decoded_items(h.ctx, h.renderer.decode_program, c, scene, [0] * len(scene.parts),
                                         source_order(c, scene), h.textures, gpu_buffer, level, g["origin"],
                                         np.float32(float(g["extent"]) / float(1 << 24) / 2.0), cache)
            for view in (0, 4, 9, 13):
                cam = make_camera(view, h.lo, h.hi, camera_distance(level, float(g["extent"]), viewing), viewing)
                for its, decoded in ((h.float_items, False), (items, True)):
                    culled += sum(Renderer.outside(cam, it.get("cull_box", it["box"])) for it in its)
                    got = h.renderer.draw(its, cam, shading, decoded)
                    every = h.renderer.draw([dict(it, box=None, cull_box=None) for it in its], cam, shading, decoded)
                    assert np.array_equal(got[0], every[0]) and np.array_equal(got[1], every[1])
                    assert got[0][..., 3].any()  # something was drawn
            for r in owned:
                r.release()
        for entry in cache.values():
            for b in entry[2]:
                b.release()
    assert culled > 0  # the close-ups culled parts


def test_a_box_is_outside_only_beyond_a_clip_plane(gl):
    scene = row_of_spheres()
    with Harness(scene, (64, 36)) as h:
        cam = make_camera(0, h.lo, h.hi, 1.0, render_viewing({"viewing": None}, (64, 36)))
        lo, hi = np.asarray(h.lo, float), np.asarray(h.hi, float)
        assert not Renderer.outside(cam, (lo, hi))  # the whole scene holds the view's centre
        assert not Renderer.outside(cam, None)
        eye = np.asarray(cam.eye, float)
        behind = eye + 10.0 * (eye - np.asarray(cam.centre, float)) / np.linalg.norm(eye - cam.centre)
        assert Renderer.outside(cam, (behind - 0.1, behind + 0.1))  # behind the eye


def test_float_cache_crop_keeps_everything_that_is_not_background(rng):
    """The cropped float render re-expands to the same bits: a pixel with colour but alpha 0 outside
    the object (not the clear colour) keeps the whole frame, an ID without coverage counts as object."""
    from lopcook.verify import renderer as RR

    rgba = np.zeros((40, 70, 4), np.uint8)
    ids = np.zeros((40, 70), np.uint32)
    rgba[10:20, 30:50] = rng.integers(1, 256, size=(10, 20, 4), dtype=np.uint8)
    ids[25, 5] = 3  # an ID with alpha 0
    entry = RR._crop(rgba, ids)
    assert entry[0] == (10, 26, 5, 50)
    for a, b in zip(RR._expand(entry, (70, 40)), (rgba, ids)):
        assert np.array_equal(a, b)
    rgba[35, 65, 0] = 7  # colour with alpha 0, no ID: not the clear colour
    entry = RR._crop(rgba, ids)
    assert entry[0] == (0, 40, 0, 70)
    for a, b in zip(RR._expand(entry, (70, 40)), (rgba, ids)):
        assert np.array_equal(a, b)
    only_bg = np.zeros_like(rgba)
    only_bg[0, 0, 1] = 9
    entry = RR._crop(only_bg, np.zeros_like(ids))
    assert np.array_equal(RR._expand(entry, (70, 40))[0], only_bg)
