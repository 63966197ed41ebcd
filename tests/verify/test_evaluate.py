"""The render check (lopcook.verify.evaluate): float source vs AP vs CAP, decoded by the shipped GLSL
decoder in the vertex shader, on a headless moderngl context (EGL); LOD k; float test scenes.

Small resolutions and few views keep this file to seconds. GL tests skip when EGL is missing, except
under CI=true, where they fail. Argument checks need no GL.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FIXTURES, cook_container
from lopcook.analyse import analyse
from lopcook.emit import build
from lopcook.lop.container import from_bytes
from lopcook.lop.summary import memory_rows
from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.settings import AnalyseSettings
from lopcook.verify import evaluate as E

SMALL = (320, 180)

# the CAP - AP PSNR margin required on the glossy crease at level 6 (measured margin: docs/measurements.md)
CREASE_MARGIN_DB = 20.0


@pytest.mark.parametrize("name", ["seamed_cube.glb", "two_plates.glb", "unit_sphere.glb", "glossy_crease.glb",
                                  "concave_ngon.gltf"])
def test_harness_sanity_cap_at_level_24_matches_float(gl, name):
    """CAP decoded with all 24 bits, seen from the level-9 distance, is the float render up to a few
    samples: >= 60 dB on every view (measured margin: docs/measurements.md), no depth-order error.
    Drawn with the source's attributes: this checks positions (the default cook's 8-bit normals
    shade a curved surface about 54 dB from the float render, by design: docs/attributes.md)."""
    s = load(str(FIXTURES / name))
    c = cook_container(s)
    r = E.evaluate(c, s, levels=[24], camera_levels=[9], views=8, resolution=SMALL, variants=("cap",),
                   attributes="source")
    row = r["levels"][0]
    assert row["camera_level"] == 9 and row["selected_level"] == 9
    assert all(p is None or p >= 60.0 for p in row["cap"]["psnr_views"]), row["cap"]["psnr_views"]
    assert row["cap"]["depth_order_errors"] == 0
    pixels = row["float_object_pixels"]
    if name in ("two_plates.glb", "concave_ngon.gltf"):  # flat, single-sided: seen from behind, culled
        assert sum(n > 100 for n in pixels) >= 3 and 0 in pixels, pixels
    else:
        assert min(pixels) > 100  # the object is there


def test_glossy_crease_ap_errs_at_the_crease_and_cap_removes_it(gl, crease):
    s, c = crease
    # positions only: the source's attributes (the container's 8-bit normals shade off by design)
    r = E.evaluate(c, s, levels=[6], views=4, resolution=SMALL, keep_images=True, attributes="source")
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
    r = E.evaluate(c, s, levels=range(6, 13), views=8, resolution=SMALL)
    ap = {row["level"]: row["ap"]["depth_order_errors"] for row in r["levels"]}
    cap = {row["level"]: row["cap"]["depth_order_errors"] for row in r["levels"]}
    assert max(ap[b] for b in (6, 7, 8, 9)) > 0, ap
    assert all(v == 0 for v in cap.values()), cap


def test_memory_columns(gl, crease):
    s, c = crease
    r = E.evaluate(c, s, levels=[6, 9], views=1, resolution=(64, 36))
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
        E.evaluate(short, s, levels=[12], views=1, resolution=(64, 36))
    with pytest.raises(LopcookError):
        E.evaluate(c, s, levels=[0], views=1, resolution=(64, 36))



def test_parse_levels():
    assert E.parse_levels([6, 7], None, 24, None) == ([6, 7], [6, 7])
    assert E.parse_levels([24, 8], 9, 24, None) == ([24, 8], [9, 9])
    assert E.parse_levels([24, 8], [9, 8], 24, None) == ([24, 8], [9, 8])
    for levels, cams, available, match in (([], None, 24, "no levels"), ([0], None, 24, "levels must be"),
                                           ([25], None, 24, "levels must be"), ([12], None, 10, "not in this file"),
                                           ([6, 7], [6], 24, "one per level"), ([6], 0, 24, "camera levels")):
        with pytest.raises(LopcookError, match=match):
            E.parse_levels(levels, cams, available, "x.lop")


def test_camera_rows_at_level_distances_or_one_fixed_distance():
    from lopcook.verify.cameras import camera_distance
    from lopcook.viewing import Viewing, required_level

    v = Viewing(viewport=(320, 180))
    rows = E.camera_rows([6, 24], [6, 9], None, 2.0, v)
    assert rows == [(6, 6, camera_distance(6, 2.0, v)), (24, 9, camera_distance(9, 2.0, v))]
    rows = E.camera_rows([6, 24], [6, 9], 3.0, 2.0, v)
    sel = int(required_level(3.0, 2.0, v))
    assert rows == [(6, sel, 3.0), (24, sel, 3.0)]
    for bad in (0.0, -1.0, float("inf"), float("nan")):
        with pytest.raises(LopcookError, match="distance"):
            E.camera_rows([6], [6], bad, 2.0, v)


def test_summarise_pools_views():
    per_view = [{"mse": 0.01, "psnr": 20.0, "object_pixels": 100, "pixels_off": 10, "sum_sq": 1.0,
                 "psnr_interior": 25.0, "interior_mse": 10 ** -2.5, "max_error": 0.5},
                {"mse": 0.0, "psnr": None, "object_pixels": 300, "pixels_off": 0, "sum_sq": 0.0,
                 "psnr_interior": None, "interior_mse": 0.0, "max_error": 0.0}]
    depth = [{"depth_order_errors": 3, "part_mismatch": 4}, {"depth_order_errors": 0, "part_mismatch": 1}]
    s = E.summarise(per_view, depth, 600, 1200)
    assert s["bytes"] == 600 and s["percent_of_float32"] == 50.0
    assert s["psnr_views"] == [20.0, None] and s["psnr_min"] == 20.0
    assert s["psnr_mean"] == pytest.approx(10 * np.log10(1 / 0.005))  # the MSE averaged over views
    assert s["psnr_pooled"] == pytest.approx(10 * np.log10(3 * 400 / 1.0))  # over all 400 pixels, 3 channels
    assert s["psnr_interior_min"] == 25.0 and s["max_error"] == 0.5
    assert (s["pixels_off"], s["object_pixels"], s["share_off"]) == (10, 400, 10 / 400)
    assert (s["depth_order_errors"], s["depth_order_errors_views"], s["part_mismatch"]) == (3, [3, 0], 5)


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
    r = E.evaluate_scene(s, s, levels=[6, 9], views=4, resolution=SMALL, extent=c.manifest["grid"]["extent"])
    ref = E.evaluate(c, s, levels=[6, 9], views=4, resolution=SMALL, variants=("cap",))
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
    r = E.evaluate(c, s, levels=[24, 10], camera_levels=9, views=4, resolution=SMALL, lod=1)
    assert r["lod"] == 1 and r["lods"] == [1]
    n1 = c.manifest["parts"][0]["lods"][1]["vertices"]
    assert r["lod_vertices"] == n1
    assert r["levels"][1]["ap"]["bytes"] == 4 * ((3 * 10 * n1 + 31) // 32)
    assert r["float32_bytes"] == 12 * s.parts[0].n_vertices  # relative to the source (LOD 0)
    b = info.buffers[0][1]
    grid = info.analysis.grid
    lod1 = Scene((MeshPart("sphere", grid.reconstruct(b.quantized, 24), b.indices,
                           normals=b.attributes.get("normals")),), "lod1", "glb")
    f = E.evaluate_scene(lod1, s, levels=[9], views=4, resolution=SMALL, extent=c.manifest["grid"]["extent"])
    assert f["levels"][0]["camera_distance_m"] == r["levels"][0]["camera_distance_m"]
    lod_psnr, float_psnr = r["levels"][0]["cap"]["psnr_mean"], f["levels"][0]["scene"]["psnr_mean"]
    assert lod_psnr is not None and abs(lod_psnr - float_psnr) < 0.5, (lod_psnr, float_psnr)
    r0 = E.evaluate(c, s, levels=[24], camera_levels=9, views=4, resolution=SMALL, variants=("cap",))
    assert r0["lods"] == [0] and (r0["levels"][0]["cap"]["psnr_mean"] is None
                                  or r0["levels"][0]["cap"]["psnr_mean"] > lod_psnr + 10.0)
    with pytest.raises(LopcookError, match="no part has a LOD 3"):
        E.evaluate(c, s, levels=[24], views=1, resolution=(64, 36), lod=3)


def test_fixed_camera_distance(gl, crease):
    s, c = crease
    r = E.evaluate(c, s, levels=[8, 12], views=2, resolution=(64, 36), distance_m=5.0, variants=("cap",))
    assert [row["camera_distance_m"] for row in r["levels"]] == [5.0, 5.0]
    assert r["levels"][0]["camera_level"] == r["levels"][0]["selected_level"]
    with pytest.raises(LopcookError, match="distance"):
        E.evaluate(c, s, levels=[8], views=1, resolution=(64, 36), distance_m=-1.0)



def test_source_check_skipped_only_for_a_container_cooked_from_the_harness_scene(gl, crease):
    """A search's probes are cooked from the harness's own scene (``cooked_from``), so the check that
    they were is skipped; otherwise (the default, or another scene named) another source is refused."""
    from lopcook.types import MeshPart, Scene
    from lopcook.verify.renderer import Harness

    s, c = crease
    p = s.parts[0]
    moved = Scene((MeshPart(p.name, p.positions + 0.01, p.indices, normals=p.normals),), "moved", "glb")
    with Harness(moved, resolution=(64, 36)) as h:
        with pytest.raises(LopcookError, match="positions differ"):
            E.harness_evaluate(h, c, levels=[6], views=1, variants=("cap",))
        with pytest.raises(LopcookError, match="positions differ"):  # not the harness's scene: checked
            E.harness_evaluate(h, c, levels=[6], views=1, variants=("cap",), cooked_from=s)
        r = E.harness_evaluate(h, c, levels=[6], views=1, variants=("cap",), cooked_from=moved)
        assert [row["level"] for row in r["levels"]] == [6]
        with pytest.raises(LopcookError, match="positions differ"):  # the source's attributes need the order
            E.harness_evaluate(h, c, levels=[6], views=1, variants=("cap",), attributes="source", cooked_from=moved)


def test_a_view_stop_keeps_the_views_before_it_whatever_was_cached(gl, crease):
    """A stop_view that ends the level at view k gives exactly views 0..k of the full render: on a
    fresh harness, with the float renders cached and with views remembered (``view_memo``)."""
    from lopcook.verify.renderer import Harness

    s, c = crease

    def stopped_at(k):
        calls = []

        def rule(metrics):
            calls.append(metrics["psnr"])
            return len(calls) == k + 1
        return rule, calls

    def psnrs(r, v):
        return r["levels"][0][v]["psnr_views"]

    with Harness(s, SMALL) as h:
        full_cap = psnrs(E.harness_evaluate(h, c, levels=[6], views=6, variants=("cap",)), "cap")
    with Harness(s, SMALL) as h:
        got = {}
        for variant, k in (("cap", 2), ("ap", 3), ("cap", 4)):  # fresh; floats cached; remembered
            rule, calls = stopped_at(k)
            got[variant, k] = psnrs(E.harness_evaluate(h, c, levels=[6], views=6, variants=(variant,),
                                                       stop_view=rule), variant)
            assert len(got[variant, k]) == k + 1 and len(calls) == k + 1
    with Harness(s, SMALL) as h:
        full_ap = psnrs(E.harness_evaluate(h, c, levels=[6], views=6, variants=("ap",)), "ap")
    assert got["cap", 2] == full_cap[:3] and got["cap", 4] == full_cap[:5] and got["ap", 3] == full_ap[:4]
    assert full_ap != full_cap  # the variants differ, so each comparison is with its own
