"""Renderer culling: an item whose box lies beyond a clip plane is not drawn, and the images are the
same bits as drawing every item over the whole viewport (float and decoded items, far views where
everything is seen and close-ups where most parts are off-screen or behind the eye)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import cook_container
from tests.support import fixtures as fx
from lopcook.lop.reader import gpu_buffer
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
                    every = h.renderer.draw(_every_triangle(its), cam, shading, decoded)
                    assert np.array_equal(got[0], every[0]) and np.array_equal(got[1], every[1])
                    assert got[0][..., 3].any()  # something was drawn
            for r in owned:
                r.release()
        for entry in cache.values():
            for b in entry[2]:
                b.release()
    assert culled > 0  # the close-ups culled parts


def test_a_render_target_the_driver_cannot_make_is_a_usage_error(gl):
    from lopcook.errors import LopcookError

    with pytest.raises(LopcookError) as exc:  # llvmpipe: framebuffer incomplete; elsewhere memory
        Renderer((16384, 16384))
    assert exc.value.exit_code == 2 and "--resolution" in str(exc.value.hint)


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


def test_outside_all_gives_each_box_the_clip_plane_test(gl):
    """``outside_all`` over many boxes (with None among them) gives, box by box, the rule of
    ``outside``'s doc written out corner by corner: all 8 corners beyond one clip plane by more than
    ``CULL_MARGIN`` of their |w|; boxes on every side of the view, some straddling a plane."""
    from lopcook.verify.renderer import CULL_MARGIN, box_corners

    scene = row_of_spheres()
    rng = np.random.default_rng(3)
    with Harness(scene, (64, 36)) as h:
        cam = make_camera(0, h.lo, h.hi, 1.0, render_viewing({"viewing": None}, (64, 36)))
        centre = np.asarray(cam.centre, float)
        lo = centre + rng.normal(scale=3.0, size=(400, 3))
        hi = lo + rng.uniform(0.0, 2.0, size=(400, 3))
        boxes = [(a, b) for a, b in zip(lo, hi)]
        boxes[::37] = [None] * len(boxes[::37])
        got = Renderer.outside_all(cam, boxes)
        mvp = np.asarray(cam.mvp, float)
        want = []
        for box in boxes:
            if box is None:
                want.append(False)
                continue
            clip = np.c_[box_corners(*box), np.ones(8)] @ mvp.T
            w = clip[:, 3]
            slack = CULL_MARGIN * np.abs(w) + 1e-12
            want.append(any(np.all(clip[:, k] - w > slack) or np.all(-clip[:, k] - w > slack) for k in range(3)))
        assert got.tolist() == want
        assert 0 < got.sum() < len(boxes) - len(boxes[::37])  # both verdicts occur
        assert [Renderer.outside(cam, b) for b in boxes[:50]] == want[:50]


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


# ---- the coverage cull: triangles that cover no sample are left out, the images stay the same bits ----

def _every_triangle(its):
    """The items without culling of any kind (no box, no coverage); GL culls back faces as each item says."""
    return [dict(it, box=None, cull_box=None, cover=None) for it in its]


def test_sample_positions_are_the_contexts_own(gl):
    """The positions read off the context are its 4x pattern, and a 1-sample target's centre."""
    from lopcook.verify.renderer import sample_positions

    four = sample_positions(gl, 4)
    assert four is not None and four.shape == (4, 2)
    assert np.all((four * 16) == np.rint(four * 16))  # on the lattice
    # llvmpipe's lp_sample_pos_4x, y up from the pixel's lower left corner
    want = {(0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)}
    if "llvmpipe" in gl.info["GL_RENDERER"]:
        assert {tuple(float(v) for v in p) for p in four} == want
    one = sample_positions(gl, 0)
    assert one is not None and [tuple(p) for p in one] == [(0.5, 0.5)]


def test_covering_triangles_equals_a_sample_by_sample_count(rng):
    """Against a direct count of the sample points inside each widened box (float64, pixel by
    pixel): the same verdict for tiny, pixel-sized and large boxes, boxes that straddle or miss the
    viewport, boxes whose edge lies on a sample, and untrusted vertices."""
    from lopcook.verify.renderer import COVER_MARGIN, covering_triangles

    offsets = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
    size = (23, 17)
    n = 3000
    centre = rng.uniform(-3.0, 26.0, (n // 3, 2)).repeat(3, axis=0)
    spread = 10.0 ** rng.uniform(-3.0, 0.7, (n // 3, 1)).repeat(3, axis=0)
    xy = (centre + rng.normal(0.0, 1.0, (n, 2)) * spread).astype(np.float32)
    # a fifth of the vertices sit exactly a margin away from a sample's coordinate
    on = rng.random(n) < 0.2
    k = rng.integers(0, 4, on.sum())
    xy[on, 0] = (np.floor(xy[on, 0]) + offsets[k, 0] + rng.choice([-1.0, 1.0], on.sum()) * COVER_MARGIN).astype(np.float32)
    ok = rng.random(n) > 0.02
    tri = np.concatenate([np.arange(n).reshape(-1, 3), rng.integers(0, n, (500, 3))])
    got = covering_triangles(xy[:, 0], xy[:, 1], ok, tri, size, offsets)
    m = np.float32(COVER_MARGIN)
    want = np.zeros(len(tri), bool)
    for t, (a, b, c) in enumerate(tri):
        if not (ok[a] and ok[b] and ok[c]):
            want[t] = True
            continue
        x0, x1 = float(min(xy[[a, b, c], 0]) - m), float(max(xy[[a, b, c], 0]) + m)
        y0, y1 = float(min(xy[[a, b, c], 1]) - m), float(max(xy[[a, b, c], 1]) + m)
        for i in range(max(0, int(np.floor(x0)) - 1), min(size[0], int(np.ceil(x1)) + 1)):
            for j in range(max(0, int(np.floor(y0)) - 1), min(size[1], int(np.ceil(y1)) + 1)):
                if any(x0 <= i + sx <= x1 and y0 <= j + sy <= y1 for sx, sy in offsets):
                    want[t] = True
    assert np.array_equal(got, want)
    assert 0.1 < got.mean() < 0.9  # both verdicts are exercised


def test_back_faces_left_out_are_back_faces_under_any_snapping(rng):
    """With ``cull_back`` a triangle is left out only when it covers no sample or faces away (clockwise
    in the window) for every move of its vertices by up to ``COVER_MARGIN`` pixels (checked in float64
    at the corners of that move); a counter-clockwise or nearly edge-on one is kept as without it."""
    from lopcook.verify.renderer import COVER_MARGIN, covering_triangles

    offsets = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
    size = (64, 48)
    n = 6000
    centre = rng.uniform(0.0, 64.0, (n // 3, 2)).repeat(3, axis=0)
    spread = 10.0 ** rng.uniform(-3.0, 1.0, (n // 3, 1)).repeat(3, axis=0)
    xy = (centre + rng.normal(0.0, 1.0, (n, 2)) * spread).astype(np.float32)
    ok = np.ones(n, bool)
    tri = np.arange(n).reshape(-1, 3)
    plain = covering_triangles(xy[:, 0], xy[:, 1], ok, tri, size, offsets)
    culled = covering_triangles(xy[:, 0], xy[:, 1], ok, tri, size, offsets, cull_back=True)
    assert not np.any(culled & ~plain)
    p = xy.astype(np.float64)[tri]
    u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    m = float(COVER_MARGIN)
    worst = area + 2.0 * m * (np.abs(u).sum(1) + np.abs(v).sum(1)) + 8.0 * m * m  # the largest area within the move
    gone = plain & ~culled
    assert gone.sum() > 100 and np.all(worst[gone] < 0.0)
    assert np.all(culled[plain & (area >= 0.0)])
    edge_on = plain & (area < 0.0) & (worst >= 0.0)
    assert edge_on.any() and np.all(culled[edge_on])
    # an untrusted vertex keeps its triangle whatever its (meaningless) area
    ok[tri[gone][:5, 0]] = False
    again = covering_triangles(xy[:, 0], xy[:, 1], ok, tri, size, offsets, cull_back=True)
    assert np.all(again[np.flatnonzero(gone)[:5]])


def test_window_coordinates_distrust_vertices_behind_the_eye(gl):
    from lopcook.verify.renderer import window_coordinates

    cam = make_camera(0, np.zeros(3), np.ones(3), 2.0, render_viewing({"viewing": None}, (64, 36)))
    eye, centre = np.asarray(cam.eye, float), np.asarray(cam.centre, float)
    pts = np.array([centre, eye + (eye - centre), [np.nan, 0.0, 0.0]], np.float32)
    px, py, ok = window_coordinates(pts, cam.mvp, (64, 36))
    assert ok.tolist() == [True, False, False]
    assert abs(float(px[0]) - 32.0) < 1e-3 and abs(float(py[0]) - 18.0) < 1e-3  # the centre is mid-frame


def _dense_scenes(tmp):
    """A sphere row (float and decoded, binned), the instanced and clustered procedural scene (a
    plate without normals: face normals from screen-space derivatives), and the textured fixture."""
    from lopcook.pipeline import run
    from lopcook.settings import EmitSettings, Settings, SimplifySettings
    from tests.emit.test_instances_stored_once import procedural_scene  # the instance tests' scene

    row = row_of_spheres()
    yield row, cook_container(row)
    inst = procedural_scene()
    yield inst, run(inst, Settings(simplify=SimplifySettings(instances=True),
                                   emit=EmitSettings(clusters=64, cluster_all=True))).container
    from lopcook.ingest import load

    fx.write_textured_gltf(tmp / "textured.glb")
    tex = load(tmp / "textured.glb")
    yield tex, run(tex, Settings()).container


@pytest.mark.parametrize("which", [0, 1, 2])
def test_coverage_cull_draws_the_same_bits(gl, monkeypatch, tmp_path, which):
    """With the cull forced on every item (no size threshold), float, AP and CAP draws of far and
    close views, at two resolutions, equal the draws of every triangle bit for bit, and the far
    views leave most triangles out."""
    from lopcook.verify import renderer as RR
    from lopcook.verify.buffers import ap_buffer, cap_buffer

    monkeypatch.setattr(RR, "COVER_MIN_TRIANGLES", 0)
    monkeypatch.setattr(RR, "COVER_DENSITY", 0.0)
    scene, c = list(_dense_scenes(tmp_path))[which]
    dropped = kept = 0
    for res in ((160, 90), (97, 61)):
        with Harness(scene, res) as h:
            assert h.renderer.sample_offsets is not None
            g = c.manifest["grid"]
            viewing = render_viewing(c.manifest, res)
            shading = Shading.from_manifest(c.manifest)
            cache: dict = {}
            orders = [None] * len(scene.parts)
            for level in (2, 7, 12):
                for builder in (ap_buffer, cap_buffer):
                    items, owned = decoded_items(h.ctx, h.renderer.decode_program, c, scene, [0] * len(scene.parts),
                                                 orders, h.textures, builder, level, g["origin"],
                                                 np.float32(float(g["extent"]) / float(1 << 24) / 2.0), cache,
                                                 cluster_program=h.renderer.cluster_decode_program)
                    for view in (0, 6, 13):
                        cam = make_camera(view, h.lo, h.hi, camera_distance(level, float(g["extent"]), viewing),
                                          viewing)
                        for its, decoded in ((h.float_items, False), (items, True)):
                            got = h.renderer.draw(its, cam, shading, decoded)
                            every = h.renderer.draw(_every_triangle(its), cam, shading, decoded)
                            assert np.array_equal(got[0], every[0]) and np.array_equal(got[1], every[1])
                            assert got[0][..., 3].any() or level == 2  # level 2: AP may collapse it all
                            for it in its:
                                picked = it["cover"].select(cam, res, h.renderer.sample_offsets)
                                n = it["cover"].count
                                k = n if picked is None else picked[1] // 3  # None: every triangle drawn
                                if level == 2:  # the far views
                                    kept += k
                                    dropped += n - k
                    for r in owned:
                        r.release()
            for entry in cache.values():
                for b in entry[2]:
                    b.release()
    assert dropped > 0 and kept > 0
    if which == 0:  # 2,240 triangles a few pixels across: most cover no sample
        assert dropped > kept


# ---- shared culls: a test scene near the source draws the float draws' culls ----

def test_projected_slack_bounds_every_move(gl, rng):
    """Moving any point of an item's box by up to ``slack_m`` per axis moves its window coordinates
    by no more than ``projected_slack`` (float64, random points, moves at the corners of the cube)."""
    from lopcook.verify.renderer import Coverage, window_coordinates

    scene = row_of_spheres()
    p = scene.parts[2].positions
    cover = Coverage(None, None, [], scene.parts[2].indices, p)
    cover._box = (p.min(axis=0), p.max(axis=0))  # (select sets it on its first call)
    size = (320, 180)
    viewing = render_viewing({"viewing": None}, size)
    checked = False
    for view, dist in ((0, 1.5), (5, 4.0), (11, 30.0)):
        cam = make_camera(view, p.min(axis=0), p.max(axis=0), dist, viewing)
        for s in (1e-4, 1e-2, 0.2):
            cover.slack_m = s
            px, py, ok = window_coordinates(p, cam.mvp, size)
            bound = cover.projected_slack(cam, size, px, py)
            if bound is None:
                continue
            mvp = np.asarray(cam.mvp, np.float64)

            def ndc(q):
                c = np.c_[q, np.ones(len(q))] @ mvp.T
                return c[:, :2] / c[:, 3:]

            pts = p[rng.integers(0, len(p), 200)]
            for d in np.array([[x, y, z] for x in (-s, s) for y in (-s, s) for z in (-s, s)]):
                shift = np.abs(ndc(pts + d) - ndc(pts)) * 0.5 * np.asarray(size, np.float64)
                assert shift.max() <= bound * (1 + 1e-9) + 1e-9
                checked = True
    assert checked
    # a move that reaches the eye plane has no bound
    cam = make_camera(0, p.min(axis=0), p.max(axis=0), 0.5, viewing)
    cover.slack_m = 1e3
    px, py, ok = window_coordinates(p, cam.mvp, size)
    assert cover.projected_slack(cam, size, px, py) is None


@pytest.mark.parametrize("slack", [0.0, 2e-4, 0.03])
def test_shared_culls_draw_the_same_bits(gl, monkeypatch, rng, slack):
    """A test scene whose positions differ from the source's by up to ``slack`` m per axis, drawn with
    the float draws' remembered culls (``Harness.share_culls``), equals its draw of every triangle bit
    for bit, and never computed a cull of its own; the float draws keep their own bits too."""
    from dataclasses import replace

    from lopcook.verify import renderer as RR
    from lopcook.verify.renderer import float_items

    monkeypatch.setattr(RR, "COVER_MIN_TRIANGLES", 0)
    monkeypatch.setattr(RR, "COVER_DENSITY", 0.0)
    scene = row_of_spheres()
    moved = replace(scene, parts=tuple(replace(p, positions=p.positions + rng.uniform(-slack, slack, p.positions.shape))
                                       for p in scene.parts))
    res = (160, 90)
    with Harness(scene, res) as h:
        h.share_culls(moved)
        items, owned = float_items(h.ctx, h.renderer.float_program, moved, h.textures)
        assert h.link_culls(moved, items) == len(scene.parts)
        viewing = render_viewing({"viewing": None}, res)
        shading = Shading()
        used = 0
        for dist in (2.0, 12.0, 60.0):
            for view in (0, 6, 13):
                cam = make_camera(view, h.lo, h.hi, dist, viewing)
                got = h.renderer.draw(h.float_items, cam, shading, False)
                every = h.renderer.draw(_every_triangle(h.float_items), cam, shading, False)
                assert np.array_equal(got[0], every[0]) and np.array_equal(got[1], every[1])
                got = h.renderer.draw(items, cam, shading, False)
                every = h.renderer.draw(_every_triangle(items), cam, shading, False)
                assert np.array_equal(got[0], every[0]) and np.array_equal(got[1], every[1])
                used += sum(len(it["cover"].twin.memo) for it in items)
                h.clear_float_cache()
        assert used > 0
        assert all(it["cover"]._box is None for it in items)  # drew the twins' culls, computed none
        for r in owned:
            r.release()


def test_covering_triangles_in_chunks_equals_one_pass(monkeypatch, rng):
    """Triangles tested in chunks of equal size (``COVER_CHUNK``) get the verdicts of one pass, with and
    without back faces and with untrusted vertices."""
    from lopcook.verify import renderer as RR

    offsets = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
    n, m = 5000, 20011
    centre = rng.uniform(-5.0, 90.0, (n // 8, 2)).repeat(8, axis=0)  # groups of 8 vertices ...
    px, py = (centre + rng.normal(0.0, 0.3, (n, 2))).astype(np.float32).T  # ... about a pixel across
    group = rng.integers(0, n // 8, m) * 8
    tri = (group[:, None] + rng.integers(0, 8, (m, 3))).astype(np.uint32)  # triangles within a group
    for ok in (np.ones(n, bool), rng.random(n) > 0.01):
        for back in (False, True):
            monkeypatch.setattr(RR, "COVER_CHUNK", 1 << 30)
            whole = RR.covering_triangles(px, py, ok, tri, (85, 55), offsets, cull_back=back)
            monkeypatch.setattr(RR, "COVER_CHUNK", 997)
            parts = RR.covering_triangles(px, py, ok, tri, (85, 55), offsets, cull_back=back)
            assert np.array_equal(whole, parts) and 0.05 < whole.mean() < 0.95, whole.mean()


def test_flushing_after_each_item_draws_the_same_bits(gl, monkeypatch):
    # the renderer flushes after every item so llvmpipe rasterises while the next one is prepared;
    # the images must be those of one unflushed frame (GL keeps the order of commands)
    from lopcook.verify import gpu

    assert gpu._resolve_flush() is not False  # Mesa's EGL gives glFlush: the overlap is in use
    calls = []
    real = gpu.flush
    monkeypatch.setattr(gpu, "flush", lambda: (calls.append(1), real()))
    scene = row_of_spheres()
    res = (160, 90)
    with Harness(scene, res) as h:
        shading = Shading()
        viewing = render_viewing({}, res)
        for view in (0, 5, 11):
            cam = make_camera(view, h.lo, h.hi, 6.0, viewing)
            calls.clear()
            flushed = h.renderer.draw(h.float_items, cam, shading, False)
            assert len(calls) >= 2  # one flush per drawn item
            monkeypatch.setattr(gpu, "_FLUSH", False)  # glFlush unavailable: the same draw, unflushed
            plain = h.renderer.draw(h.float_items, cam, shading, False)
            monkeypatch.setattr(gpu, "_FLUSH", None)
            assert np.array_equal(flushed[0], plain[0]) and np.array_equal(flushed[1], plain[1])
            assert flushed[0][..., 3].any()
