"""Report wording (lopcook.report.text and the page sections built from it): grouped, human-worded
warnings without Python reprs; the parts table's N* legend only when some part has N*. No GL."""

from __future__ import annotations

import re

from lopcook.report.html import parts_html, warnings_html
from lopcook.report.text import plural, warning_groups

NONE = {"available": True, "scene": [], "touching": [], "intersecting": [], "degenerate_triangles": 0,
        "depth_capped": 0, "depth_ceiling": 16, "attribute_unsatisfied": 0}


def test_plural():
    assert plural(1, "vertex", "vertices") == "1 vertex" and plural(3, "vertex", "vertices") == "3 vertices"
    assert plural(1560, "triangle") == "1,560 triangles" and plural(1, "pair") == "1 pair"


def test_warnings_are_grouped_and_worded():
    w = dict(NONE, scene=["texture a.png could not be read; the part cooks untextured"] * 3 + ["other"],
             touching=[["board", "pawn"], ["board", "rook"]], intersecting=[["king", "board"]],
             degenerate_triangles=1560, depth_capped=120, attribute_unsatisfied=3)
    groups = warning_groups(w)
    assert [g["id"] for g in groups] == ["import", "touching", "intersecting", "degenerate", "attribute"]
    by = {g["id"]: g for g in groups}
    assert by["import"]["items"] == ["texture a.png could not be read; the part cooks untextured (3 times)", "other"]
    assert by["touching"]["items"] == ["board and pawn", "board and rook"]
    assert by["touching"]["summary"].startswith("2 pairs of parts touch: 120 vertices where they meet")
    assert "capped at level 16" in by["touching"]["summary"]
    assert by["intersecting"]["summary"].startswith("1 pair of parts intersect")
    assert by["degenerate"]["summary"] == ("1,560 zero-area triangles are left out of the position error bound "
                                           "(they cover no pixel).")
    assert by["attribute"]["summary"] == ("3 vertices need more than 24 bits for their attribute error; they are "
                                          "stored at full precision (24 bits).")
    one = warning_groups(dict(NONE, attribute_unsatisfied=1))[0]["summary"]
    assert one.startswith("1 vertex needs more than 24 bits for its attribute error; it is stored")
    assert warning_groups(NONE) == []


def test_warnings_section_has_no_reprs_and_collapses_long_lists():
    pairs = [[f"piece {i}", "board"] for i in range(25)]
    w = dict(NONE, touching=pairs, intersecting=pairs[:2], depth_capped=21611, attribute_unsatisfied=33865)
    text = warnings_html(w)
    assert "[[" not in text and "['" not in text and "&#x27;" not in text  # no list reprs
    assert "attribute unsatisfied" not in text and "depth capped" not in text
    assert '<div class="warn-group" id="warn-touching">' in text and "<details><summary>show all 25</summary>" in text
    assert text.count("<li>") == 25 + 2 and "<li>piece 0 and board</li>" in text
    assert "33,865 vertices need more than 24 bits" in text
    assert '<p id="warnings">none</p>' in warnings_html(NONE)
    assert "not re-run" in warnings_html(dict(NONE, available=False))


def _part(name, normals, double_sided=False):
    return {"name": name, "vertices": 3, "triangles": 1, "normals": normals, "uvs": False, "colors": False,
            "texture": None, "double_sided": double_sided}


def test_n_star_legend_only_when_a_part_has_computed_normals():
    src = parts_html({"scene_parts": [_part("a", "source"), _part("b", None)]})
    assert "N*" not in src and '<table id="parts">' in src
    comp = parts_html({"scene_parts": [_part("a", "source"), _part("b", "computed")]})
    assert re.search(r"<td class=\"name\">N\*</td>", comp)
    assert "N* = normals computed by lopcook" in comp
    many = parts_html({"scene_parts": [_part(f"p{i}", "source") for i in range(30)]})
    assert "<details><summary>show the 30 parts</summary>" in many and "30 parts in the source" in many


def test_double_sided_parts_are_labelled_and_the_culling_is_said():
    one = parts_html({"scene_parts": [_part("a", "source"), _part("b", "source", double_sided=True)]})
    assert re.search(r"<td class=\"name\">N 2S</td>", one) and "2S = double-sided" in one
    assert "cull the back faces of single-sided parts" in one
    none = parts_html({"scene_parts": [_part("a", "source")]})
    assert "2S" not in none and "cull the back faces of single-sided parts" in none
