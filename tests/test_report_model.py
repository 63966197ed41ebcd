"""The report model (lopcook.report.model): LOD table bytes and selection ranges, the 16-bit
baseline record, deterministic JSON. No GL."""

from __future__ import annotations

import json
import math

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


def test_choose_view_shows_the_most_parts_then_the_worst_error():
    from lopcook.report.render import choose_view

    assert choose_view([3, 5, 5, 2], [30.0, 25.0, 20.0, 10.0], 3) == 2  # most parts, then lowest PSNR
    assert choose_view([3, 5, 5, 2], [30.0, 25.0, 20.0, 10.0], 1) == 1  # the worst view kept when it shows them
    assert choose_view([4, 4], [None, None], 5) == 0  # identical everywhere: the first
    assert choose_view([2, 2, 2], [40.0, None, 35.0], 7) == 2


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
