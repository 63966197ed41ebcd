"""The harness's fused metric pass and its float-render cache give the numbers of the plain
implementation: ``metrics.view_metrics`` against ``image_metrics`` + ``depth_order_errors`` on
constructed image pairs, and ``harness_evaluate`` (cached float renders, fused metrics) against a
loop of plain ``Renderer.draw`` renders measured with the original functions, on a fixture."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FIXTURES, cook_container
from lopcook.lop.reader import gpu_buffer
from lopcook.ingest import load
from lopcook.verify import metrics as M
from lopcook.verify import renderer as RR
from lopcook.verify.buffers import source_order
from lopcook.verify.cameras import camera_distance, make_camera, render_viewing
from lopcook.verify.evaluate import harness_evaluate
from lopcook.verify.renderer import Harness, Shading, decoded_items

INT_KEYS = ("object_pixels", "pixels_off", "interior_pixels")
FLOAT_KEYS = ("sum_sq", "mse", "psnr", "max_error", "share_off", "interior_mse", "psnr_interior")


def _same(fast: dict, ref: dict) -> None:
    for k in INT_KEYS:
        assert fast[k] == ref[k], k
    for k in FLOAT_KEYS:
        if ref[k] is None:
            assert fast[k] is None, k
        else:
            assert fast[k] == pytest.approx(ref[k], rel=1e-12, abs=1e-300), k


def _pair(rng, h=61, w=97, parts=3, changed=0.05, background_noise=False):
    """A reference render (an object of ``parts`` parts over a black background, alpha 0 there) and a
    test render differing in a share ``changed`` of its pixels (colour, coverage, part)."""
    ref = np.zeros((h, w, 4), np.uint8)
    ids = np.zeros((h, w), np.uint32)
    yy, xx = np.mgrid[:h, :w]
    inside = (yy - h / 2) ** 2 / (h / 2.5) ** 2 + (xx - w / 2) ** 2 / (w / 2.5) ** 2 < 1
    inside[0, :] = inside[:, -1] = True  # the object touches the border
    ref[inside, :3] = rng.integers(0, 256, (int(inside.sum()), 3))
    ref[inside, 3] = rng.choice([64, 128, 255, 255, 255], int(inside.sum()))
    ids[inside] = 1 + (xx[inside] * parts) // w
    tst, tids = ref.copy(), ids.copy()
    flip = rng.random((h, w)) < changed
    tst[flip, :3] = np.clip(tst[flip, :3].astype(int) + rng.integers(-3, 4, (int(flip.sum()), 3)), 0, 255)
    grow = rng.random((h, w)) < changed / 2
    tst[grow, 3] = np.where(tst[grow, 3] == 0, 255, 0)
    tids[grow] = np.where(tids[grow] == 0, 1, 0)
    swap = rng.random((h, w)) < changed / 2
    tids[swap & (tids > 0)] = 1 + (tids[swap & (tids > 0)] % parts)
    if background_noise:
        tst[0, 0, :3] = (0, 9, 0)
        tst[0, 0, 3] = 0
        ref[0, 0, 3] = 0
    return ref, ids, tst, tids


@pytest.mark.parametrize("changed", [0.0, 0.002, 0.05, 0.5])
@pytest.mark.parametrize("noise", [False, True])
def test_view_metrics_equals_the_two_plain_functions(rng, changed, noise):
    ref, ids, tst, tids = _pair(rng, changed=changed, background_noise=noise)
    colour, order = M.view_metrics(ref, tst, ids, tids)
    _same(colour, M.image_metrics(ref, tst))
    assert order == M.depth_order_errors(ids, tids)


def test_view_metrics_of_empty_and_identical_images():
    z = np.zeros((8, 9, 4), np.uint8)
    zi = np.zeros((8, 9), np.uint32)
    colour, order = M.view_metrics(z, z, zi, zi)
    _same(colour, M.image_metrics(z, z))
    assert colour["psnr"] is None and order == M.depth_order_errors(zi, zi)
    one = z.copy()
    one[3, 4] = (10, 20, 30, 255)
    colour, _ = M.view_metrics(one, one, zi, zi)
    assert colour["object_pixels"] == 1 and colour["psnr"] is None and colour["sum_sq"] == 0.0


def test_float_cache_crop_round_trips_exactly(rng):
    ref, ids, _, _ = _pair(rng)
    ref[:5] = 0
    ids[:5] = 0
    entry = RR._crop(ref, ids)
    assert entry[0][0] == 5
    back = RR._expand(entry, (ref.shape[1], ref.shape[0]))
    assert np.array_equal(back[0], ref) and np.array_equal(back[1], ids) and back[1].dtype == np.uint32
    empty = RR._crop(np.zeros_like(ref), np.zeros_like(ids))
    assert empty[0] is None and not RR._expand(empty, (ref.shape[1], ref.shape[0]))[0].any()


def _plain(h: Harness, c, scene, levels, views):
    """Per level, per view: (image_metrics, depth_order_errors) of CAP against float, every render
    done afresh with ``Renderer.draw`` and measured with the plain functions."""
    shading = Shading.from_manifest(c.manifest)
    viewing = render_viewing(c.manifest, h.renderer.size)
    g = c.manifest["grid"]
    half = np.float32(float(g["extent"]) / float(1 << 24) / 2.0)
    orders = [None] * len(scene.parts)  # the container's own attributes, as the harness draws by default
    out, cache = [], {}
    try:
        for level in levels:
            items, owned = decoded_items(h.ctx, h.renderer.decode_program, c, scene, [0] * len(scene.parts), orders,
                                         h.textures, gpu_buffer, level, g["origin"], half, cache)
            dist = camera_distance(level, float(g["extent"]), viewing)
            for view in views:
                cam = make_camera(view, h.lo, h.hi, dist, viewing)
                ref = h.renderer.draw(h.float_items, cam, shading, decoded=False)
                tst = h.renderer.draw(items, cam, shading, decoded=True)
                out.append((M.image_metrics(ref[0], tst[0]), M.depth_order_errors(ref[1], tst[1])))
            for r in owned:
                r.release()
    finally:
        for entry in cache.values():
            for b in entry[2]:
                b.release()
    return out


@pytest.mark.parametrize("name", ["glossy_crease.glb", "two_plates.glb"])
def test_harness_numbers_equal_the_plain_renders(gl, name):
    scene = load(str(FIXTURES / name))
    c = cook_container(scene)
    levels, views = [6, 9, 12], [0, 7, 15]
    with Harness(scene, (160, 90), cache_float=True) as h:
        plain = _plain(h, c, scene, levels, views)
        for _ in range(2):  # the second pass reads every float render from the cache
            r = harness_evaluate(h, c, levels=levels, views=views, variants=("cap",))
            got = [(row["cap"], i) for row in r["levels"] for i in range(len(views))]
            for (row, i), (colour, order) in zip(got, plain):
                p = colour["psnr"]
                assert (row["psnr_views"][i] is None) == (p is None)
                if p is not None:
                    assert row["psnr_views"][i] == pytest.approx(p, rel=1e-12)
                assert row["depth_order_errors_views"][i] == order["depth_order_errors"]
        assert len(h.float_cache) == len(levels) * len(views)


@pytest.mark.parametrize("name", ["glossy_crease.glb", "two_plates.glb", "seamed_cube.glb"])
def test_draws_limited_to_the_screen_rect_equal_whole_viewport_draws(gl, name):
    """Clear, draw, resolve and read-back inside ``screen_rect`` give the whole-viewport render bit
    for bit (float and decoded items; far views where the rect is small, close ones where it is
    the viewport or the box reaches behind the eye)."""
    scene = load(str(FIXTURES / name))
    c = cook_container(scene)
    res = (160, 90)
    with Harness(scene, res) as h:
        g = c.manifest["grid"]
        viewing = render_viewing(c.manifest, res)
        shading = Shading.from_manifest(c.manifest)
        cache: dict = {}
        rects = set()
        for level in (6, 10, 16):
            items, owned = decoded_items(h.ctx, h.renderer.decode_program, c, scene, [0] * len(scene.parts),
                                         source_order(c, scene), h.textures, gpu_buffer, level, g["origin"],
                                         np.float32(float(g["extent"]) / float(1 << 24) / 2.0), cache)
            for view in (0, 9):
                cam = make_camera(view, h.lo, h.hi, camera_distance(level, float(g["extent"]), viewing), viewing)
                for its, decoded in ((h.float_items, False), (items, True)):
                    rects.add(h.renderer.screen_rect(cam, its))
                    boxed = h.renderer.draw(its, cam, shading, decoded)
                    whole = h.renderer.draw([dict(it, box=None) for it in its], cam, shading, decoded)
                    assert np.array_equal(boxed[0], whole[0]) and np.array_equal(boxed[1], whole[1])
            for r in owned:
                r.release()
        for entry in cache.values():
            for b in entry[2]:
                b.release()
        assert any(r is not None and r[2] * r[3] < res[0] * res[1] / 4 for r in rects)  # some draws were small


@pytest.mark.parametrize("changed", [0.0, 0.05, 0.5])
def test_view_metrics_in_a_box_equals_the_whole_frame(rng, changed):
    """Limited to a box outside which both renders are background (what ``Renderer.last_box`` and
    the float cache's crop give), the pass gives the whole frame's numbers exactly, also for
    part IDs on the box's edge (their 3 x 3 neighbourhoods reach one pixel out) and a box on the
    frame's border."""
    for r0, r1, c0, c1 in ((5, 40, 9, 60), (0, 61, 0, 97), (0, 17, 50, 97)):
        ref, rid, tst, tid = _pair(rng, changed=changed)
        outside = np.ones(ref.shape[:2], bool)
        outside[r0:r1, c0:c1] = False
        for a in (ref, tst, rid, tid):
            a[outside] = 0
        # parts that differ on the box's first and last rows (depth-order candidates at its edge)
        rid[r0, c0:c1], tid[r0, c0:c1] = 1, 2
        rid[r1 - 1, c0:c1], tid[r1 - 1, c0:c1] = 2, 1
        whole = M.view_metrics(ref, tst, rid, tid)
        boxed = M.view_metrics(ref, tst, rid, tid, box=(r0, r1, c0, c1))
        _same(boxed[0], whole[0])
        assert boxed[1] == whole[1]
    empty = np.zeros((8, 9, 4), np.uint8), np.zeros((8, 9), np.uint32)
    got = M.view_metrics(empty[0], empty[0], empty[1], empty[1], box=(0, 0, 0, 0))
    assert got == M.view_metrics(empty[0], empty[0], empty[1], empty[1])
