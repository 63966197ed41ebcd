"""The render harness (lopcook.verify.render): float source vs AP vs CAP, decoded by the shipped GLSL
decoder in the vertex shader, on a headless moderngl context (EGL).

Small resolutions and few views keep this file to seconds. GL tests skip when EGL is missing, except
under CI=true, where they fail. Camera and view geometry tests need no GL.
"""

from __future__ import annotations

import io

import numpy as np
import pytest

from conftest import FIXTURES
from lopcook.analyse import analyse
from lopcook.emit import build
from lopcook.emit.binning import LEVELS
from lopcook.emit.bitplane import decode, reconstruct_float32
from lopcook.emit.container import from_bytes
from lopcook.emit.reader import top_values
from lopcook.emit.summary import memory_rows
from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.settings import AnalyseSettings
from lopcook.types import MeshPart, Scene, Texture
from lopcook.verify import gpu
from lopcook.verify import render as R
from lopcook.viewing import nearest_box_distance, required_level

SMALL = (320, 180)

# Measured on llvmpipe (LLVM 15, Mesa 22.3.6), glossy_crease at level 6, views 0/5/10/15, 320x180:
# AP PSNR min 29.6 dB, CAP 69.1 dB (margin 39.5 dB); 36 interior pixels of AP off by > 2/255, 0 of CAP.
CREASE_MARGIN_DB = 20.0


def _cook(scene, settings=AnalyseSettings(), viewing=None):
    a = analyse(scene, settings)
    return from_bytes(build(scene, a, options={"analyse": settings.to_record()}, viewing=viewing), scene.source)


@pytest.fixture(scope="module")
def crease():
    s = load(str(FIXTURES / "glossy_crease.glb"))
    return s, _cook(s)


@pytest.fixture(scope="module")
def plates():
    s = load(str(FIXTURES / "two_plates.glb"))
    return s, _cook(s)


# ---- views and cameras (no GL) -------------------------------------------------------------------

def test_twenty_icosahedron_directions_are_unit_and_distinct():
    d = R.icosahedron_directions()
    assert d.shape == (20, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    cos = d @ d.T
    np.fill_diagonal(cos, -1.0)
    assert cos.max() < 0.8  # neighbouring face centres are 41.8 degrees apart
    nearest = np.degrees(np.arccos(cos.max(axis=1)))
    np.testing.assert_allclose(nearest, np.degrees(np.arccos(np.sqrt(5.0) / 3.0)), atol=1e-9)
    np.testing.assert_allclose(d.sum(axis=0), 0.0, atol=1e-12)  # symmetric set
    # turned away from the coordinate planes: no axis-aligned plate is seen exactly edge-on
    assert np.abs(d).min() > np.sin(np.radians(8.9))


def test_select_views():
    assert R.select_views(20) == list(range(20))
    assert R.select_views(4) == [0, 5, 10, 15]
    assert R.select_views([3, 7]) == [3, 7]
    for bad in (0, 21, [20], []):
        with pytest.raises(LopcookError):
            R.select_views(bad)


@pytest.mark.parametrize("extent", [1.0, 0.137, 42.0])
def test_distance_for_level_makes_required_level_select_it(extent):
    viewing = R.render_viewing({"viewing": {"fov_y_deg": 60.0, "pixel_error": 0.5}}, (1280, 720))
    lo, hi = np.zeros(3), np.array([extent, 0.5 * extent, 0.25 * extent])
    for level in range(1, LEVELS):
        d = R.camera_distance(level, extent, viewing)
        assert int(required_level(d, extent, viewing)) == level
        assert int(required_level(d * (1 - 1e-4), extent, viewing)) == level + 1  # d is the threshold
        for view in (0, 7, 19):
            cam = R.make_camera(view, lo, hi, d, viewing)
            assert cam.box_distance == pytest.approx(d, rel=1e-12)
            assert int(required_level(nearest_box_distance(cam.eye, lo, hi), extent, viewing)) == level
            assert 0 < cam.near < cam.far


def test_object_pixels_at_a_level_do_not_depend_on_the_resolution():
    """d_B grows with the viewport height, so the metres per pixel at the object stay the same."""
    for res in ((320, 180), (1280, 720)):
        v = R.render_viewing({}, res)
        d = R.camera_distance(6, 1.0, v)
        assert float(v.pixel_size(d)) == pytest.approx(float(R.render_viewing({}, (640, 360)).pixel_size(
            R.camera_distance(6, 1.0, R.render_viewing({}, (640, 360))))), rel=1e-12)


def test_fixture_rotation_is_the_view_rotation():
    from lopcook import fixtures as F

    np.testing.assert_array_equal(F.GLOSSY_CREASE_ROTATION, R.VIEW_ROTATION)


def test_ap_buffer_holds_b_bits_for_every_vertex(crease):
    _, c = crease
    for level in (1, 6, 12, 24):
        buf = R.ap_buffer(c, 0, 0, level)
        values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
        assert np.all(widths == level)
        top, w = top_values(c, 0, 0, 24)
        np.testing.assert_array_equal(values, top >> np.uint32(24 - level))
        n = int(buf.vertex_id[LEVELS])
        assert buf.words.size * 4 == 4 * ((3 * level * n + 31) // 32)


def test_source_order_maps_binned_vertices_to_source_vertices(crease):
    s, c = crease
    (order,) = R.source_order(c, s)
    assert sorted(order.tolist()) == list(range(s.parts[0].n_vertices))
    an = analyse(s, AnalyseSettings())
    from lopcook.emit.binning import make_bins

    np.testing.assert_array_equal(order, make_bins(an.parts[0].min_level).order)


def test_source_order_rejects_another_source(crease):
    _, c = crease
    other = load(str(FIXTURES / "unit_sphere.glb"))
    with pytest.raises(LopcookError, match="source"):
        R.source_order(c, other)
    s, _ = crease
    p = s.parts[0]
    moved = Scene((MeshPart(p.name, p.positions + 0.01, p.indices, p.normals),), "moved", "glb")
    with pytest.raises(LopcookError, match="positions differ"):
        R.source_order(c, moved)


# ---- renders (GL) --------------------------------------------------------------------------------

def test_ap_decoded_by_the_shipped_glsl_decoder_matches_the_cpu(gl, crease):
    _, c = crease
    g = c.manifest["grid"]
    cell = g["extent"] / float(1 << LEVELS)
    for level in (6, 11):
        buf = R.ap_buffer(c, 0, 0, level)
        got = gpu.vertex_decoder("glsl").decode(buf.words, buf.vertex_id, buf.bit_id, level, g["origin"],
                                                np.float32(cell / 2.0))
        values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
        ref = reconstruct_float32(values, widths, g["origin"], cell)
        np.testing.assert_array_equal(got.position.view(np.uint32), ref.view(np.uint32))


@pytest.mark.parametrize("name", ["seamed_cube.glb", "two_plates.glb", "unit_sphere.glb", "glossy_crease.glb",
                                  "concave_ngon.gltf"])
def test_harness_sanity_cap_at_level_24_matches_float(gl, name):
    """CAP decoded with all 24 bits, seen from the level-9 distance, is the float render up to a few
    samples: >= 60 dB on every view (measured: >= 88 dB on llvmpipe), no depth-order error."""
    s = load(str(FIXTURES / name))
    c = _cook(s)
    r = R.evaluate(c, s, levels=[24], camera_levels=[9], views=8, resolution=SMALL, variants=("cap",))
    row = r["levels"][0]
    assert row["camera_level"] == 9 and row["selected_level"] == 9
    assert all(p is None or p >= 60.0 for p in row["cap"]["psnr_views"]), row["cap"]["psnr_views"]
    assert row["cap"]["depth_order_errors"] == 0
    assert min(row["float_object_pixels"]) > 100  # the object is there


def test_glossy_crease_ap_errs_at_the_crease_and_cap_removes_it(gl, crease):
    s, c = crease
    r = R.evaluate(c, s, levels=[6], views=4, resolution=SMALL, keep_images=True)
    row = r["levels"][0]
    ap, cap = row["ap"], row["cap"]
    assert cap["psnr_min"] is None or cap["psnr_min"] - ap["psnr_min"] >= CREASE_MARGIN_DB, (ap["psnr_min"],
                                                                                              cap["psnr_min"])
    assert cap["psnr_mean"] is None or cap["psnr_mean"] - ap["psnr_mean"] >= CREASE_MARGIN_DB
    assert ap["percent_of_float32"] < cap["percent_of_float32"]
    # the errors are on the crease, inside the object (not only coverage at the silhouette)
    im = r["images"]
    inside = im["float"][..., 3] == 255
    pad = np.pad(inside, 1)
    for dy in range(3):
        for dx in range(3):
            inside = inside & pad[dy:dy + inside.shape[0], dx:dx + inside.shape[1]]

    def interior_off(key):
        err = np.abs(im[key][..., :3].astype(int) - im["float"][..., :3].astype(int)).max(axis=2)
        return int(np.count_nonzero((err > 2) & inside))

    assert interior_off("ap") >= 10
    assert interior_off("cap") == 0


def test_two_plates_ap_has_depth_order_errors_and_cap_none(gl, plates):
    s, c = plates
    r = R.evaluate(c, s, levels=range(6, 13), views=8, resolution=SMALL)
    ap = {row["level"]: row["ap"]["depth_order_errors"] for row in r["levels"]}
    cap = {row["level"]: row["cap"]["depth_order_errors"] for row in r["levels"]}
    assert max(ap[b] for b in (6, 7, 8, 9)) > 0, ap
    assert all(v == 0 for v in cap.values()), cap


def test_part_ids_and_images(gl, plates):
    s, c = plates
    r = R.evaluate(c, s, levels=[8], views=[0], resolution=SMALL, keep_images=True, image_view=0)
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


def test_memory_columns(gl, crease):
    s, c = crease
    r = R.evaluate(c, s, levels=[6, 9], views=1, resolution=(64, 36))
    rows = {m["level"]: m for m in memory_rows(c, levels=[6, 9])}
    n = s.parts[0].n_vertices
    for row in r["levels"]:
        b = row["level"]
        assert row["ap"]["bytes"] == 4 * ((3 * b * n + 31) // 32) == rows[b]["ap_bytes"]
        assert row["cap"]["bytes"] == rows[b]["cap_bytes"]
        assert row["cap"]["percent_of_float32"] == pytest.approx(100.0 * rows[b]["cap_bytes"] / (12 * n))
    assert r["float32_bytes"] == 12 * n and r["vertices"] == n


def test_levels_not_in_the_file_are_a_usage_error(gl, crease):
    s, c = crease
    data = build(s, analyse(s, AnalyseSettings()), max_level=10)
    short = from_bytes(data, "short.lop")
    with pytest.raises(LopcookError, match="not in this file"):
        R.evaluate(short, s, levels=[12], views=1, resolution=(64, 36))
    with pytest.raises(LopcookError):
        R.evaluate(c, s, levels=[0], views=1, resolution=(64, 36))


def test_textured_part_samples_its_base_colour(gl):
    """A base-colour texture reaches the render (float, AP and CAP alike); CAP at 24 still matches."""
    from PIL import Image

    from lopcook import fixtures as F

    img = np.zeros((64, 64, 3), np.uint8)
    img[:] = (230, 30, 30)
    img[:, (np.arange(64) // 8) % 2 == 1] = (30, 200, 30)  # stripes: both colours on every atlas cell
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")
    cube = F.seamed_cube()[0]
    part = MeshPart("cube", cube.positions, cube.indices, cube.normals, cube.uvs,
                    texture=Texture("checker.png", buf.getvalue()))
    s = Scene((part,), "textured", "glb").validate()
    c = _cook(s)
    r = R.evaluate(c, s, levels=[24, 8], camera_levels=[9, 8], views=4, resolution=SMALL, keep_images=True,
                   image_view=0)
    rows = r["levels"]
    assert all(p is None or p >= 60.0 for p in rows[0]["cap"]["psnr_views"])
    rgb = r["images"]["float"][..., :3].astype(int)
    covered = r["images"]["float"][..., 3] == 255
    red = (rgb[..., 0] > rgb[..., 1] + 40) & covered
    green = (rgb[..., 1] > rgb[..., 0] + 40) & covered
    assert red.sum() > 20 and green.sum() > 20


def test_format_table(gl, crease):
    s, c = crease
    r = R.evaluate(c, s, levels=[6, 7], views=2, resolution=(64, 36))
    text = R.format_table(r)
    assert "AP mem" in text and "CAP PSNR" in text
    assert len([ln for ln in text.splitlines() if ln.strip().startswith(("6 ", "7 "))]) == 2


# ---- LOD k and float test scenes (GL) -------------------------------------------------------------

@pytest.fixture(scope="module")
def sphere_lods():
    from lopcook.pipeline import run
    from lopcook.settings import LodSpec, Settings, SimplifySettings

    s = load(str(FIXTURES / "unit_sphere.glb"))
    info = run(s, Settings(simplify=SimplifySettings(lods=LodSpec(auto=False, ratios=(0.5, 0.25)), backend="fast")),
               keep_buffers=True)
    data = info.data
    return s, from_bytes(data, "sphere_lods.lop"), info


def test_evaluate_scene_of_the_source_itself_is_identical(gl, crease):
    s, c = crease
    r = R.evaluate_scene(s, s, levels=[6, 9], views=4, resolution=SMALL, extent=c.manifest["grid"]["extent"])
    ref = R.evaluate(c, s, levels=[6, 9], views=4, resolution=SMALL, variants=("cap",))
    n = s.parts[0].n_vertices
    for row, rrow in zip(r["levels"], ref["levels"]):
        assert row["camera_distance_m"] == rrow["camera_distance_m"]  # the same cameras
        assert all(p is None for p in row["scene"]["psnr_views"])
        assert row["scene"]["bytes"] == 12 * n and row["scene"]["depth_order_errors"] == 0
    assert r["variants"] == ["scene"] and r["test_vertices"] == n


def test_lod_k_renders_its_own_buffers(gl, sphere_lods):
    """LOD 1 of a chain container, decoded at 24 bits with its own indices and decoded normals,
    renders like the float LOD 1 mesh (within 0.5 dB against the source), and worse than LOD 0."""
    from lopcook.types import MeshPart, Scene

    s, c, info = sphere_lods
    assert len(c.manifest["parts"][0]["lods"]) == 3
    r = R.evaluate(c, s, levels=[24, 10], camera_levels=9, views=4, resolution=SMALL, lod=1)
    assert r["lod"] == 1 and r["lods"] == [1]
    n1 = c.manifest["parts"][0]["lods"][1]["vertices"]
    assert r["lod_vertices"] == n1
    assert r["levels"][1]["ap"]["bytes"] == 4 * ((3 * 10 * n1 + 31) // 32)
    assert r["float32_bytes"] == 12 * s.parts[0].n_vertices  # relative to the source (LOD 0)
    b = info["buffers"][0][1]
    grid = info["analysis"].grid
    lod1 = Scene((MeshPart("sphere", grid.reconstruct(b.quantized, 24), b.indices, b.normals),), "lod1", "glb")
    f = R.evaluate_scene(lod1, s, levels=[9], views=4, resolution=SMALL, extent=c.manifest["grid"]["extent"])
    assert f["levels"][0]["camera_distance_m"] == r["levels"][0]["camera_distance_m"]
    lod_psnr, float_psnr = r["levels"][0]["cap"]["psnr_mean"], f["levels"][0]["scene"]["psnr_mean"]
    assert lod_psnr is not None and abs(lod_psnr - float_psnr) < 0.5, (lod_psnr, float_psnr)
    r0 = R.evaluate(c, s, levels=[24], camera_levels=9, views=4, resolution=SMALL, variants=("cap",))
    assert r0["lods"] == [0] and (r0["levels"][0]["cap"]["psnr_mean"] is None
                                  or r0["levels"][0]["cap"]["psnr_mean"] > lod_psnr + 10.0)
    with pytest.raises(LopcookError, match="no part has a LOD 3"):
        R.evaluate(c, s, levels=[24], views=1, resolution=(64, 36), lod=3)


def test_fixed_camera_distance(gl, crease):
    s, c = crease
    r = R.evaluate(c, s, levels=[8, 12], views=2, resolution=(64, 36), distance_m=5.0, variants=("cap",))
    assert [row["camera_distance_m"] for row in r["levels"]] == [5.0, 5.0]
    assert r["levels"][0]["camera_level"] == r["levels"][0]["selected_level"]
    with pytest.raises(LopcookError, match="distance"):
        R.evaluate(c, s, levels=[8], views=1, resolution=(64, 36), distance_m=-1.0)
