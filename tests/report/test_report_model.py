"""The report model (lopcook.report.model): LOD table bytes and selection ranges, the 16-bit
baseline record, deterministic JSON. No GL."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from lopcook.report import model as RM
from lopcook.types import MeshPart, Scene


def _manifest():
    vid = [0] + [2] * 3 + [5] * 21  # 2 vertices at level <= 3, 5 in all
    return {
        "sections": [{"name": "p/0/indices", "length": 36}, {"name": "p/0/attributes", "length": 60},
                     {"name": "p/1/indices", "length": 12}],
        "positions": {"max_level": 4},
        "parts": [{"name": "p", "lods": [
            {"vertex_id": vid, "indices": "p/0/indices", "attributes": "p/0/attributes",
             "attribute_bits": {"normals": 16, "uvs": 16, "colors": 8}, "record_bits": 96, "mandatory_words": [0, 3],
             "triangles": 3, "vertices": 5, "geometric_error_m": 0.0, "min_distance_m": None},
            {"vertex_id": [0] + [3] * 24, "indices": "p/1/indices", "mandatory_words": [3, 2],
             "triangles": 1, "vertices": 3, "geometric_error_m": 0.01, "min_distance_m": 2.5}]}],
        "options": {"lods": {"reports": [{"notes": ["a note"], "stop_reason": "error bound"}]}},
    }


def test_lod_table_bytes_and_ranges():
    (part,) = RM.lod_table(_manifest())
    lod0, lod1 = part["lods"]
    # planes 2..4: ceil(3 * vid[p - 1] / 8) bytes each: vid[1], vid[2], vid[3] = 2, 2, 2
    assert lod0["plane_position_bytes"] == 3 * math.ceil(3 * 2 / 8)
    assert (lod0["index_bytes"], lod0["attribute_bytes"], lod0["mandatory_position_bytes"]) == (36, 60, 12)
    assert lod0["bytes"] == 36 + 60 + 12 + lod0["plane_position_bytes"]
    assert lod1["plane_position_bytes"] == 3 * math.ceil(3 * 3 / 8)
    assert (lod1["index_bytes"], lod1["attribute_bytes"], lod1["mandatory_position_bytes"]) == (12, 0, 8)
    # LOD 0 from 0 m to where LOD 1 starts, LOD 1 without an upper bound
    assert (lod0["min_distance_m"], lod0["max_distance_m"]) == (0.0, 2.5)
    assert (lod1["min_distance_m"], lod1["max_distance_m"]) == (2.5, None)
    assert part["notes"] == ["a note", "chain stopped: error bound"]
    # the re-cook's reports replace the recorded ones
    (part,) = RM.lod_table(_manifest(), [{"notes": [], "stop_reason": "all ratios done"}])
    assert part["notes"] == []


def test_uniform16_section_error_bound_and_memory():
    pos = np.array([[0.0, 0.0, 0.0], [2.0, 1.0, 0.5], [1.0, 0.5, 0.25]])
    scene = Scene((MeshPart("t", pos, np.array([[0, 1, 2]], np.uint32), None),), "t", "glb")
    u = RM.uniform16_section(None, scene, 3)
    assert u["bytes"] == 8 * 3 and u["percent_of_float32"] == pytest.approx(200 / 3)
    assert u["max_position_error_m"] == pytest.approx(math.sqrt(3.0) * 1.0 / 32767.0 / 2.0)  # half side 1 m
    assert not u["rendered"] and u["levels"] == [] and u["note"] == "not rendered"


def test_report_json_bytes_are_sorted_and_refuse_nan():
    data = RM.report_json_bytes({"b": 1, "a": [1.5, None]})
    assert data == b'{\n "a": [\n  1.5,\n  null\n ],\n "b": 1\n}\n'
    assert json.loads(data) == {"a": [1.5, None], "b": 1}
    with pytest.raises(ValueError):
        RM.report_json_bytes({"x": float("nan")})


def test_budget_section_only_for_budget_containers():
    assert RM.budget_section({}) is None
    assert RM.budget_section({"options": {"budget": {"candidates": []}}}) is None
    b = {"candidates": [{"lod": 0}], "chosen": {"lod": 0}}
    assert RM.budget_section({"options": {"budget": b}}) is b


def _frame(ids_box=None):
    rgba = np.zeros((90, 160, 4), np.uint8)
    rgba[30:60, 40:100] = (120, 120, 120, 255)
    ids = np.zeros((90, 160), np.uint32)
    ids[30:60, 40:70], ids[30:60, 70:100] = 1, 2
    return rgba, ids


def test_level_image_record_zooms_on_cap_else_ap_else_none():
    f, fid = _frame()
    ap, cap = f.copy(), f.copy()
    ap[40:44, 50:54, 0] = 250  # AP errs on the left
    rec = RM.level_image_record({"level": 7, "view": 3, "float": f, "float_ids": fid, "ap": ap, "cap": cap})
    assert rec["level"] == 7 and rec["zoom"]["variant"] == "ap"  # CAP is exact: AP's error is zoomed
    x0, y0, x1, y1 = rec["zoom"]["box"]
    assert x0 <= 50 and x1 >= 54 and y0 <= 40 and y1 >= 44
    cap[50:52, 90:92, 1] = 10  # a small CAP error on the right wins over AP's larger one
    rec = RM.level_image_record({"level": 7, "view": 3, "float": f, "float_ids": fid, "ap": ap, "cap": cap})
    assert rec["zoom"]["variant"] == "cap" and rec["zoom"]["box"][2] >= 92
    assert RM.level_image_record({"level": 6, "view": 0, "float": f, "ap": f, "cap": f})["zoom"] is None


def test_depth_record_counts_the_mask():
    f, fid = _frame()
    cid = fid.copy()
    cid[35:45, 66:69] = 2  # part 2 in front of part 1, inside part 1
    rec = RM.depth_record({"level": 8, "view": 5, "variant": "cap", "errors": 7,
                           "images": {"float": f, "float_ids": fid, "cap": f, "cap_ids": cid}})
    from lopcook.verify.metrics import depth_order_errors

    assert rec["pixels"] == depth_order_errors(fid, cid)["depth_order_errors"] > 0
    assert (rec["level"], rec["view"], rec["variant"], rec["errors"]) == (8, 5, "cap", 7)
    assert RM.depth_record(None) is None


def test_depth_target_prefers_cap_then_the_largest_view():
    from lopcook.report.render import depth_target

    rows = [{"level": 6, "ap": {"depth_order_errors_views": [5, 9]}, "cap": {"depth_order_errors_views": [0, 0]}},
            {"level": 7, "ap": {"depth_order_errors_views": [1, 0]}, "cap": {"depth_order_errors_views": [0, 0]}}]
    assert depth_target(rows) == (6, 1, "ap", 9)
    rows[1]["cap"]["depth_order_errors_views"] = [2, 3]
    assert depth_target(rows) == (7, 1, "cap", 3)  # CAP's errors are what ships
    rows[1]["cap"]["depth_order_errors_views"] = [3, 3]
    assert depth_target(rows) == (7, 0, "cap", 3)  # the first of equal counts
    for r in rows:
        r["ap"]["depth_order_errors_views"] = r["cap"]["depth_order_errors_views"] = [0, 0]
    assert depth_target(rows) is None


def test_choose_view_a_front_or_three_quarter_view_by_projected_area():
    """A view a person recognises: never from below the horizon nor from high above while a front or
    three-quarter view was rendered, then the most parts seen, then the largest projected area."""
    from lopcook.report.render import choose_view

    below, high, front, three_q, back = (-53.0, 20.0), (77.0, 45.0), (9.0, 9.0), (35.0, 45.0), (17.0, 150.0)
    # the view from below covers the most pixels (a bunny's flat underside): not shown first
    assert choose_view([below, front, three_q], [900, 500, 600]) == 2
    assert choose_view([below, high, front], [900, 950, 400]) == 2
    # the back is a candidate only when no front-side view at that elevation was rendered
    assert choose_view([back, front], [900, 100]) == 1
    assert choose_view([below, back], [900, 100]) == 1
    assert choose_view([below, high], [900, 100]) == 1  # from above, before from below
    assert choose_view([below], [10]) == 0
    # parts seen decide among the candidates before the area; equal areas: the first
    assert choose_view([front, three_q, below], [500, 400, 900], visible=[3, 5, 9]) == 1
    assert choose_view([front, three_q], [500, 500]) == 0


def test_view_angles_of_the_icosahedron_views():
    from lopcook.report.render import view_angles
    from lopcook.verify.cameras import icosahedron_directions

    d = icosahedron_directions()
    for v, (elev, az) in zip(range(20), view_angles(range(20))):
        assert math.sin(math.radians(elev)) == pytest.approx(d[v][1], abs=1e-12)
        assert math.atan2(d[v][0], d[v][2]) == pytest.approx(math.radians(az), abs=1e-12)
    (e0, a0), (e10, _) = view_angles([0, 10])
    assert 0 < e0 < 45 and abs(a0) < 90 and e10 < 0  # the 2-view harness: a front view and one from below


def test_worst_view_is_the_lowest_cap_psnr():
    from lopcook.report.verdict import worst_view

    rows = [{"level": 6, "cap": {"psnr_views": [45.0, 41.0, None]}},
            {"level": 7, "cap": {"psnr_views": [44.0, 41.0, 50.0]}}]
    assert worst_view(rows, [0, 7, 13]) == {"level": 6, "view": 7, "psnr": 41.0}  # the first of equal values
    rows[1]["cap"]["psnr_views"][2] = 30.5
    assert worst_view(rows, [0, 7, 13]) == {"level": 7, "view": 13, "psnr": 30.5}
    assert worst_view([{"level": 6, "cap": {"psnr_views": [None, None]}}], [0, 10]) is None


def test_verdict_pass_fail_and_threshold():
    from lopcook.report.verdict import verdict, verdict_line

    rows = [{"level": 6, "cap": {"psnr_views": [45.0, 39.9]}}, {"level": 7, "cap": {"psnr_views": [44.0, None]}},
            {"level": 8, "cap": {"psnr_views": [38.0, 41.0]}}]
    part = {"index": 0, "name": "body", "share": 0.75}
    v = verdict(rows, [0, 10], 40.0, {"level": 8, "view": 0, "part": part})
    assert v["result"] == "FAIL" and v["failing_levels"] == [6, 8] and v["failing_views"] == 2
    assert v["worst"] == {"level": 8, "view": 0, "psnr": 38.0, "part": part}
    line = verdict_line(v)
    assert line.startswith("FAIL: worst CAP PSNR 38.0 dB < 40 dB at level 8, view 0, part body")
    v = verdict(rows, [0, 10], 38.0, {"level": 6, "view": 10, "part": part})  # another view: its part unknown
    assert v["result"] == "PASS" and v["failing_views"] == 0 and v["worst"]["part"] is None
    assert verdict_line(v).startswith("PASS: worst CAP PSNR 38.0 dB >= 38 dB at level 8, view 0")
    same = verdict([{"level": 6, "cap": {"psnr_views": [None]}}], [0], 40.0)
    assert same["result"] == "PASS" and same["worst"] is None


def test_worst_part_holds_the_largest_share_of_the_error():
    from lopcook.report.verdict import worst_part

    f = np.zeros((8, 8, 4), np.uint8)
    f[..., 3] = 255
    f[..., :3] = 100
    c = f.copy()
    ids = np.zeros((8, 8), np.uint32)
    ids[:, :4], ids[:, 4:] = 1, 2
    c[0, 0, :3] = 110  # part 0: one pixel off by 10
    c[0, 6, :3] = 130  # part 1: one pixel off by 30
    cap_ids = ids.copy()
    cap_ids[7, 7] = 0  # background in CAP only: the float render's part counts
    c[7, 7, 3] = 0
    got = worst_part({"float": f, "cap": c, "float_ids": ids, "cap_ids": cap_ids}, ["a", "b"])
    e_a, e_b = 3 * (10 / 255) ** 2, 3 * (30 / 255) ** 2
    assert got["index"] == 1 and got["name"] == "b" and got["share"] == pytest.approx(e_b / (e_a + e_b))
    assert worst_part({"float": f, "cap": f, "float_ids": ids, "cap_ids": ids}, ["a", "b"]) is None
    assert worst_part(None, ["a"]) is None
    # an outline pixel both ID images show as background (multisampled colour, one ID sample) counts
    # for the part next to it
    bg = np.zeros((8, 8), np.uint32)
    bg[3:5, 5:7] = 2
    c2 = f.copy()
    c2[3, 4, :3] = 160
    got = worst_part({"float": f, "cap": c2, "float_ids": bg, "cap_ids": bg}, ["a", "b"])
    assert got == {"index": 1, "name": "b", "share": 1.0}


def test_lod_names_one_way_everywhere():
    assert RM.fraction_text(69451, 69451) == "all"
    assert RM.fraction_text(34725, 69451) == "1/2" and RM.fraction_text(271, 69451) == "1/256"
    assert RM.fraction_text(30, 100) == "30 %" and RM.fraction_text(45, 100) == "45 %"
    assert RM.fraction_text(7, 1000) == "1/143"  # small shares are all near a unit fraction
    assert RM.lod_name(0, 10, 10) == "LOD 0 (all triangles)"
    assert RM.lod_name(2, 1250, 5000) == "LOD 2 (1/4 of the triangles)"
    kept = [{"target_ratio": 1.0}, {"target_ratio": 0.5}, {"target_ratio": 0.25}]
    names = ["LOD 0 (all triangles)", "LOD 1 (1/2 of the triangles)", "LOD 2 (1/4 of the triangles)"]
    notes = ["LOD 0.25: 3 faces face against the source surface", "LOD 0.0625: fast failed: x; falling back",
             "chain stopped: LOD 0.0625 could not be produced; previous LODs kept", "LOD 2: kept as it is",
             "no UVs: LOD 0 parametrised with xatlas", "LOD 0.0009765625: dropped"]
    out = RM.rename_notes(notes, kept, names)
    assert out[0] == "LOD 2 (1/4 of the triangles): 3 faces face against the source surface"
    assert out[1] == "the dropped LOD (target 1/16 of the triangles): fast failed: x; falling back"
    assert out[2] == ("chain stopped: the dropped LOD (target 1/16 of the triangles) could not be produced; "
                      "previous LODs kept")
    assert out[3:5] == notes[3:5]  # indices and LOD 0 as they are
    assert out[5] == "the dropped LOD (target 1/1024 of the triangles): dropped"  # the ratio's own fraction


def test_lod_table_names_and_renamed_notes():
    m = _manifest()
    m["options"]["lods"]["reports"] = [{"notes": ["LOD 0.25: a note"], "stop_reason": "all ratios done",
                                        "lods": [{"target_ratio": 1.0}, {"target_ratio": 0.25}]}]
    (part,) = RM.lod_table(m, None, [12])
    assert [r["name"] for r in part["lods"]] == ["LOD 0 (1/4 of the triangles)", "LOD 1 (1/12 of the triangles)"]
    assert part["notes"] == ["LOD 1 (1/12 of the triangles): a note"]
    (part,) = RM.lod_table(m)  # no source count: LOD 0's
    assert part["lods"][0]["name"] == "LOD 0 (all triangles)"
    # a part with fewer LODs counts with its last one
    assert RM.scene_lod_names({"parts": [m["parts"][0], {"lods": [{"triangles": 5}]}]}, [3, 5]) == \
        ["LOD 0 (all triangles)", "LOD 1 (75 % of the triangles)"]


def test_lod_plan_renders_each_lod_where_it_is_first_selected():
    """LOD k at its selection distance scaled to the render's height (the same pixels as in the
    container's viewport), at the level selected there; LOD 0 at the frame distance; a LOD no
    distance selects is not rendered; the deepest part decides how many LODs there are."""
    from lopcook.report.render import lod_plan
    from lopcook.verify.cameras import render_viewing
    from lopcook.viewing import required_level

    m = {"viewing": {"viewport": [1920, 1080], "fov_y_deg": 60.0, "pixel_error": 0.5}, "grid": {"extent": 0.2},
         "positions": {"max_level": 20},
         "parts": [{"lods": [{"min_distance_m": None}, {"min_distance_m": 2.0}, {"min_distance_m": None}]},
                   {"lods": [{"min_distance_m": None}, {"min_distance_m": 1.5}]}]}
    plan = lod_plan(m, (640, 360), 0.4)
    assert [p["lod"] for p in plan] == [0, 1, 2]
    assert plan[0]["selection_distance_m"] is None and plan[0]["distance_m"] == 0.4  # the frame distance
    near = lod_plan(m, (640, 360), 0.6)  # LOD 1 takes over nearer than the frame distance: LOD 0 just short of it
    assert near[0]["distance_m"] == pytest.approx(1.5 * 360 / 1080) and near[0]["distance_m"] < near[1]["distance_m"]
    assert plan[1]["selection_distance_m"] == 1.5 and plan[1]["distance_m"] == pytest.approx(1.5 * 360 / 1080)
    v = render_viewing(m, (640, 360))
    for p in plan[:2] + near[:1]:
        assert p["level"] == min(20, int(required_level(p["distance_m"], 0.2, v)))
    assert plan[2] == {"lod": 2, "selection_distance_m": None, "distance_m": None, "level": None}
    assert max(p["level"] for p in lod_plan(m, (640, 360), 0.4, available=3)[:2]) <= 3  # a file cut short
    # the same pixels: the object's size in pixels at the render distance equals the container's
    assert v.pixel_size(plan[1]["distance_m"]) == pytest.approx(
        render_viewing(m, (1920, 1080)).pixel_size(1.5))


def test_levels_in_file_are_the_default_levels_it_holds():
    from lopcook.verify.evaluate import levels_in_file

    assert levels_in_file(range(6, 13), 24) == list(range(6, 13))
    assert levels_in_file(range(6, 13), 10) == [6, 7, 8, 9, 10]  # a --target-bytes file
    assert levels_in_file(range(6, 13), 4) == [4]


def test_clusters_rows_grouped_with_their_count():
    from lopcook.report.sections import clusters_html, group_rows

    rows = [{"level": b, "cap_bytes": 100 if b <= 13 else 100 + b, "cap_percent": 1.0,
             "unclustered_cap_bytes": 120 if b <= 13 else 120 + b, "unclustered_cap_percent": 1.2}
            for b in range(1, 25)]
    groups = group_rows(rows, ("cap_bytes", "unclustered_cap_bytes"))
    assert [(a, b) for a, b, _ in groups] == [(1, 13)] + [(b, b) for b in range(14, 25)]
    rep = {"clusters": {"clusters": 5, "cluster_size": [64], "buffers": 1, "record_bytes": 80,
                        "k_histogram": [0, 3] + [0] * 22 + [2]}, "memory": rows, "available_level": 24}
    text = "".join(clusters_html(rep))
    body = re.findall(r"<tr data-levels=[^>]*>(.*?)</tr>", text)
    assert len(body) == 12 and "1-13 (13 levels)" in body[0]
    cells = [tuple(re.findall(r"<td>(.*?)</td>", r)[1:]) for r in body]
    assert all(a != b for a, b in zip(cells, cells[1:]))  # no two neighbouring rows alike
    assert "1:3 24:2" in text and " 0:" not in text  # only the k that occur


def test_compact_ids_keeps_the_values_in_the_smallest_type():
    """The report keeps every level's part-ID images as uint8 (< 256 parts) or uint16 (< 65,536):
    the same values, so the same crops and depth masks; wider IDs and other images are untouched."""
    from lopcook.report.render import compact_ids
    from lopcook.report.images import crop_box
    from lopcook.verify.metrics import depth_error_mask

    rng = np.random.default_rng(3)
    rgba = np.zeros((40, 60, 4), np.uint8)
    rgba[10:20, 5:30] = 200
    small = rng.integers(0, 50, (40, 60)).astype(np.uint32)
    mid = rng.integers(0, 3000, (40, 60)).astype(np.uint32)
    wide = np.full((40, 60), 70_000, np.uint32)
    imgs = {"level": 6, "float": rgba, "float_ids": small, "cap_ids": mid, "ap_ids": wide}
    out = compact_ids(imgs)
    assert out["float_ids"].dtype == np.uint8 and out["cap_ids"].dtype == np.uint16 and out["ap_ids"].dtype == np.uint32
    for k in ("float_ids", "cap_ids", "ap_ids"):
        assert np.array_equal(out[k], imgs[k])
    assert out["float"] is rgba and imgs["float_ids"].dtype == np.uint32  # the input dict is not changed
    assert crop_box(out) == crop_box(imgs)
    assert np.array_equal(depth_error_mask(out["float_ids"], out["cap_ids"]), depth_error_mask(small, mid))
    assert compact_ids(None) is None
