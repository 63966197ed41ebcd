"""Render reuse in the harness: draws named by content (``Harness.view_memo``), harnesses shared by
the searches of one scene (``shared_harness``), compressed float-cache entries and the queue
finishes of large draws. Each must give the same numbers and the same bits as rendering afresh."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import cook_container
from tests.support import fixtures as fx
from lopcook.settings import DEFAULT_ANALYSE, AnalyseSettings
from lopcook.types import MeshPart, Scene
from lopcook.verify import renderer as R
from lopcook.verify.cameras import camera_distance, make_camera, render_viewing
from lopcook.verify.evaluate import harness_evaluate, harness_evaluate_scene
from lopcook.verify.renderer import Harness, Shading, digest, release_shared, shared_harness

RES = (96, 54)


def spheres(n: int = 3) -> Scene:
    base = fx.unit_sphere(2)[0]
    parts = [MeshPart(f"s{k}", base.positions + [2.5 * k, 0.3 * k, 0.0], base.indices, normals=base.normals)
             for k in range(n)]
    return Scene(parts=tuple(parts), source="spheres", format="obj").validate()


def some_cameras(h: Harness, c, shading: Shading):
    """(camera, float-cache key) of views 0, 3 and 11 at camera levels 6 and 10 of container ``c``."""
    viewing = render_viewing(c.manifest, RES)
    for level in (6, 10):
        for view in (0, 3, 11):
            cam = make_camera(view, h.lo, h.hi, camera_distance(level, float(c.manifest["grid"]["extent"]), viewing),
                              viewing)
            yield cam, (cam.mvp.tobytes(), cam.eye.tobytes(), shading)


def strip(res: dict) -> dict:
    """An evaluation without its timings (the only machine-dependent keys)."""
    return {k: v for k, v in res.items() if k != "seconds"}


class Counting:
    """Counts ``Renderer.draw`` calls (decoded and float) on one harness."""

    def __init__(self, h: Harness, monkeypatch):
        self.decoded = self.float = 0
        draw = h.renderer.draw

        def counted(items, camera, shading, decoded, **kw):
            if decoded:
                self.decoded += 1
            else:
                self.float += 1
            return draw(items, camera, shading, decoded, **kw)

        monkeypatch.setattr(h.renderer, "draw", counted)


def test_a_memoised_evaluation_equals_a_fresh_one_and_renders_nothing(gl, monkeypatch):
    scene = spheres()
    c = cook_container(scene)
    levels = [6, 9, 12]
    with Harness(scene, RES) as fresh:
        want = strip(harness_evaluate(fresh, c, levels=levels, views=4))
    with Harness(scene, RES, cache_float=True) as h:
        first = strip(harness_evaluate(h, c, levels=levels, views=4))
        n = Counting(h, monkeypatch)
        again = strip(harness_evaluate(h, c, levels=levels, views=4))
        assert (n.decoded, n.float) == (0, 0)  # every (level, view) came from the memo
        assert first == want and again == want
        # a container cooked at a looser eps: its CAP draws other positions (rendered, its own
        # numbers); an AP draw is a memo hit only where its attributes (bits by eps) are the same too
        other = cook_container(scene, AnalyseSettings(eps=DEFAULT_ANALYSE.eps * 64.0))
        got = strip(harness_evaluate(h, other, levels=levels, views=4))
        assert len(levels) * 4 <= n.decoded <= 2 * len(levels) * 4
    with Harness(scene, RES) as fresh:
        assert got == strip(harness_evaluate(fresh, other, levels=levels, views=4))
        assert got["levels"][0]["cap"] != want["levels"][0]["cap"]


def test_a_stopped_evaluation_leaves_the_levels_it_rendered_memoised(gl, monkeypatch):
    scene = spheres(2)
    c = cook_container(scene)
    with Harness(scene, RES, cache_float=True) as h:
        part = strip(harness_evaluate(h, c, levels=[6, 8, 10], views=3, variants=("cap",), stop=lambda pv: True))
        assert [r["level"] for r in part["levels"]] == [6]
        n = Counting(h, monkeypatch)
        full = strip(harness_evaluate(h, c, levels=[6, 8, 10], views=3, variants=("cap",)))
        assert n.decoded == 2 * 3  # levels 8 and 10 only
        assert full["levels"][0] == part["levels"][0]
    with Harness(scene, RES) as fresh:
        assert full == strip(harness_evaluate(fresh, c, levels=[6, 8, 10], views=3, variants=("cap",)))


def test_digest_tells_dtype_shape_and_bytes_apart():
    a = np.arange(6, dtype=np.uint32)
    assert digest(a) == digest(a.copy())
    assert digest(a) != digest(a.astype(np.int32))
    assert digest(a) != digest(a.reshape(2, 3))
    b = a.copy()
    b[5] += 1
    assert digest(a) != digest(b)
    assert digest(1, 2) != digest(12) and digest(b"ab", b"c") != digest(b"a", b"bc")


def test_decoded_items_digest_follows_their_content(gl):
    scene = spheres(2)
    c = cook_container(scene)
    from lopcook.lop.reader import gpu_buffer
    from lopcook.verify.buffers import ap_buffer

    g = c.manifest["grid"]
    half = np.float32(float(g["extent"]) / float(1 << 24) / 2.0)
    with Harness(scene, RES) as h:
        keys = {}
        for name, builder in (("cap", gpu_buffer), ("ap", ap_buffer)):
            for level in (6, 7):
                cache: dict = {}
                items, owned = R.decoded_items(h.ctx, h.renderer.decode_program, c, scene, [0, 0], [None, None],
                                               h.textures, builder, level, g["origin"], half, cache)
                keys[(name, level)] = [(it["digest"], i, it["cover"].positions.tobytes()) for i, it in enumerate(items)]
                assert [it["triangles"] for it in items] == [p.n_triangles for p in scene.parts]
                for r in owned:
                    r.release()
                for entry in cache.values():
                    for b in entry[2]:
                        b.release()
        # the same key exactly when the part and the decoded positions are the same (here the
        # attributes are: one container), whatever the variant or level that decoded them
        flat = [k for ks in keys.values() for k in ks]
        for a in flat:
            for b in flat:
                assert (a[0] == b[0]) == (a[1] == b[1] and a[2] == b[2])
        assert len({k[0] for k in flat}) > len(scene.parts)  # levels and variants do decode apart


def test_shared_harness_is_kept_per_scene_and_released_for_another(gl):
    a, b = spheres(2), spheres(3)
    try:
        with shared_harness(a, RES) as h1:
            h1.memo["x"] = 1
        with shared_harness(a, RES) as h2:
            assert h2 is h1 and h2.memo == {}  # the same harness; the caller's memo is its own
            assert h2.cache_float
        with shared_harness(a, (64, 36)) as g:
            assert g is not h1 and g.renderer.size == (64, 36)
        with shared_harness(b, RES) as h3:
            assert h3 is not h1 and h3.scene is b
        assert h1._buffers == [] and g._buffers == []  # another scene released a's harnesses
    finally:
        release_shared()


def test_compressed_float_cache_gives_the_same_renders(gl, monkeypatch):
    scene = spheres()
    c = cook_container(scene)
    monkeypatch.setattr(R, "RAW_CACHE_BYTES", 0)  # every entry compressed
    with Harness(scene, RES) as plain, Harness(scene, RES, cache_float=True) as cached:
        shading = Shading.from_manifest(c.manifest)
        for cam, key in some_cameras(plain, c, shading):
            want = plain.render_float(cam, shading)
            first = cached.render_float(cam, shading, key=key)
            assert len(cached.float_cache[key]) == 6  # a packed entry
            hit = cached.render_float(cam, shading, key=key)
            for x, y, z in zip(want, first, hit):
                assert np.array_equal(x, y) and np.array_equal(x, z) and x.dtype == z.dtype
        assert 0 < cached.cached_bytes < sum(RES[0] * RES[1] * 6 for _ in range(6))


@pytest.mark.parametrize("every", [1, 10**9])
def test_finishing_the_queue_between_draws_changes_no_pixel(gl, monkeypatch, every):
    scene = spheres(4)
    c = cook_container(scene)
    with Harness(scene, RES) as h:
        viewing = render_viewing(c.manifest, RES)
        shading = Shading.from_manifest(c.manifest)
        cams = [make_camera(v, h.lo, h.hi, camera_distance(b, float(c.manifest["grid"]["extent"]), viewing), viewing)
                for b in (6, 11) for v in (0, 7)]
        want = [h.renderer.draw(h.float_items, cam, shading, False) for cam in cams]
        monkeypatch.setattr(R, "FINISH_TRIANGLES", every)  # 1: a glFinish before every item
        finishes = []
        finish = h.ctx.finish
        monkeypatch.setattr(type(h.ctx), "finish", lambda self: (finishes.append(1), finish())[1])
        got = [h.renderer.draw(h.float_items, cam, shading, False) for cam in cams]
        assert (len(finishes) > 0) == (every == 1)
        for (a, b), (x, y) in zip(want, got):
            assert np.array_equal(a, x) and np.array_equal(b, y)
        # the renderer's own threshold (the report's) overrides the module's
        finishes.clear()
        h.renderer.finish_triangles = 1 if every != 1 else 10**9
        got = [h.renderer.draw(h.float_items, cam, shading, False) for cam in cams]
        assert (len(finishes) > 0) == (every != 1)
        for (a, b), (x, y) in zip(want, got):
            assert np.array_equal(a, x) and np.array_equal(b, y)


def _tiny_calibrated(scene):
    """``cook --target-psnr 35`` of ``scene`` on small harnesses (k_f calibration, its gate, the
    attribute search and its gate), through ``lopcook.api.cook``."""
    from lopcook.api import cook
    from lopcook.settings import DEFAULTS, RenderSettings

    s = DEFAULTS.with_(tune={"target_psnr": 35.0, "calibration": RenderSettings(views=2, resolution=(80, 45)),
                             "confirm": RenderSettings(views=3, resolution=(112, 63))})
    return cook(scene, s)


def test_a_calibrated_cook_with_shared_harnesses_writes_the_same_bytes_and_reuses_renders(gl, monkeypatch):
    """The attribute search's first probe (the k_f choice with the default bits) is the k_f
    calibration's chosen cook: with the shared harness it draws nothing; without sharing (a fresh
    harness for every caller, as before) the container is the same, byte for byte."""
    from conftest import FIXTURES
    from lopcook.ingest import load
    from lopcook.tune import attributes as TA
    from lopcook.tune import calibrate as TC

    scene = load(FIXTURES / "unit_sphere.glb")
    draws = {"decoded": 0, "float": 0}
    real_draw = R.Renderer.draw

    def counted(self, items, camera, shading, decoded, **kw):
        draws["decoded" if decoded else "float"] += 1
        return real_draw(self, items, camera, shading, decoded, **kw)

    monkeypatch.setattr(R.Renderer, "draw", counted)
    at_probe = []
    real_quality = TA.Search.quality

    def quality(self, alloc, step_name=""):
        before = dict(draws)
        q = real_quality(self, alloc, step_name)
        at_probe.append((step_name, draws["decoded"] - before["decoded"], draws["float"] - before["float"]))
        return q

    monkeypatch.setattr(TA.Search, "quality", quality)
    try:
        shared = _tiny_calibrated(scene)
        assert at_probe and at_probe[0][0] == "start"
        assert at_probe[0][1:] == (0, 0)  # the k_f choice's renders, memoised on the shared harness
        shared_draws = dict(draws)
    finally:
        release_shared()

    def fresh(scene_, resolution=R.RESOLUTION, samples=R.SAMPLES):
        return R._Borrowed(Harness(scene_, resolution, samples, cache_float=True))

    monkeypatch.setattr(R, "shared_harness", fresh)
    monkeypatch.setattr(TC, "shared_harness", fresh)
    draws.update(decoded=0, float=0)
    alone = _tiny_calibrated(scene)
    assert alone.data == shared.data
    assert draws["decoded"] > shared_draws["decoded"] and draws["float"] > shared_draws["float"]



def test_kept_attributes_give_the_same_evaluations_and_follow_the_container(gl):
    """``Harness.keep_attributes`` (the report: one container, one level at a time) keeps one
    container's attribute buffers between evaluations: the same numbers and images as uploading
    them again, none uploaded twice, and another container object replaces them."""
    scene = spheres()
    c = cook_container(scene)
    other = cook_container(scene)
    with Harness(scene, RES) as fresh, Harness(scene, RES) as kept:
        kept.keep_attributes = True
        for level in (6, 9, 11):
            a = harness_evaluate(fresh, c, levels=[level], views=3, keep_images=True)
            b = harness_evaluate(kept, c, levels=[level], views=3, keep_images=True)
            ia, ib = a.pop("images"), b.pop("images")
            assert strip(a) == strip(b)
            assert all(np.array_equal(ia[k], ib[k]) for k in ia if isinstance(ia[k], np.ndarray))
            assert kept.kept_attributes[0] is c
            entries = dict(kept.kept_attributes[2])
            if level > 6:  # the same buffers as the level before
                assert all(entries[i][0] is first[i][0] for i in entries)
            first = entries
        assert strip(harness_evaluate(kept, other, levels=[9], views=3)) == \
            strip(harness_evaluate(fresh, other, levels=[9], views=3))
        assert kept.kept_attributes[0] is other
    assert kept.kept_attributes is None  # released with the harness
    # off by default: nothing is kept
    with Harness(scene, RES) as h:
        harness_evaluate(h, c, levels=[9], views=2)
        assert h.kept_attributes is None


def test_a_test_scene_draws_the_sources_index_and_attribute_buffers_it_shares(gl):
    """``evaluate_scene`` of a scene that replaces only the positions (the uniform 16-bit baseline)
    uploads its positions alone and draws the source's other buffers: the same numbers as a copy of
    it that shares no array, whose every buffer is its own."""
    from dataclasses import replace

    from lopcook.verify.baselines import uniform_quantized_scene
    from lopcook.verify.renderer import float_items

    scene = spheres()
    u16 = uniform_quantized_scene(scene)
    apart = replace(u16, parts=tuple(replace(p, indices=p.indices.copy(), normals=p.normals.copy()) for p in u16.parts))
    with Harness(scene, RES) as h:
        shared, owned = float_items(h.ctx, h.renderer.float_program, u16, h.textures, like=(h.scene, h.float_items))
        own, owned2 = float_items(h.ctx, h.renderer.float_program, apart, h.textures, like=(h.scene, h.float_items))
        for a, b, src in zip(shared, own, h.float_items):
            assert a["buffers"][0] is src["buffers"][0] and a["buffers"][1] == src["buffers"][1]
            assert b["buffers"][0] is not src["buffers"][0]
            assert all(x[0] is not y[0] for x, y in zip(b["buffers"][1], src["buffers"][1]))
        assert not any(o is src["buffers"][0] for o in owned for src in h.float_items)  # not the items' to release
        for o in owned + owned2:
            o.release()
        a = harness_evaluate_scene(h, u16, levels=[8, 12], views=3)
        b = harness_evaluate_scene(h, apart, levels=[8, 12], views=3)
        assert strip(a)["levels"] == strip(b)["levels"]


@pytest.mark.parametrize("packed", [False, True])
def test_cropped_renders_and_their_metrics_equal_the_whole_images(gl, monkeypatch, packed):
    """``draw(crop=True)`` and ``render_float(crop=True)`` (drawn, from the cache, packed or not)
    are the whole image's ``last_box`` region, with background outside it; ``_crop_metrics`` of
    two crops gives ``view_metrics`` of the two whole images (another shading and a part left out,
    so colours and part IDs differ)."""
    from lopcook.verify import metrics as M
    from lopcook.verify.evaluate import _crop_metrics

    if packed:
        monkeypatch.setattr(R, "RAW_CACHE_BYTES", 0)
    scene = spheres()
    c = cook_container(scene)
    with Harness(scene, RES) as plain, Harness(scene, RES, cache_float=True) as cached:
        shading = Shading.from_manifest(c.manifest)
        other = Shading(ks=0.1, shininess=8.0)
        checked = mismatched = 0
        scratch: dict = {}
        for cam, key in some_cameras(plain, c, shading):
            whole = plain.render_float(cam, shading)
            for _ in range(2):  # drawn, then from the cache
                crop = cached.render_float(cam, shading, key=key, crop=True)
                r0, r1, c0, c1 = cached.last_float_box
                np.testing.assert_array_equal(crop[0], whole[0][r0:r1, c0:c1])
                np.testing.assert_array_equal(crop[1], whole[1][r0:r1, c0:c1])
                outside = np.ones(whole[1].shape, bool)
                outside[r0:r1, c0:c1] = False
                assert not whole[0][outside].any() and not whole[1][outside].any()
            assert key in cached.float_cache
            fbox = cached.last_float_box
            # one sphere left out, the others with each other's part IDs
            items = [dict(it, part=(int(it["part"]) + 1) % 3) for it in plain.float_items[1:]]
            test_whole = plain.renderer.draw(items, cam, other, decoded=False)
            tbox = plain.renderer.last_box
            test_crop = plain.renderer.draw(items, cam, other, decoded=False, crop=True)
            assert plain.renderer.last_box == tbox
            np.testing.assert_array_equal(test_crop[0], test_whole[0][tbox[0]:tbox[1], tbox[2]:tbox[3]])
            np.testing.assert_array_equal(test_crop[1], test_whole[1][tbox[0]:tbox[1], tbox[2]:tbox[3]])
            got = _crop_metrics(plain.renderer.size, crop, fbox, test_crop, tbox)
            want = M.view_metrics(whole[0], test_whole[0], whole[1], test_whole[1])
            assert got == want
            # with buffers reused from view to view (other sizes, other contents before)
            assert _crop_metrics(plain.renderer.size, crop, fbox, test_crop, tbox, scratch) == want
            checked += want[0]["sum_sq"] > 0
            mismatched += want[1]["part_mismatch"] > 0
        assert checked >= 3 and mismatched >= 1
