"""``--lods auto`` stops where a LOD stops paying (``lopcook.simplify.stop``): a LOD is kept only
while the part spans at least ``MIN_PIXELS`` pixels at its selection distance and its recorded
error is at most ``MAX_RELATIVE_ERROR`` of the part's largest extent; every chain records where and
why it stopped (``LodReport.stop``, the container's ``options.lods.reports``, ``inspect --json``'s
``parts[].lod_stop``), and ``cook``/``inspect`` print it.

The analytic cases compute the pixels a part spans from the half-pixel selection rule by hand
(pixel size ``2 d tan(fov/2) / height``); the corpus cases check the bunny and spot as cooked."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from tests.support import fixtures as F
from lopcook.simplify import lod_chain
from lopcook.simplify import instances as I
from lopcook.simplify.stop import MAX_RELATIVE_ERROR, MIN_PIXELS, StopRule, manifest_record, part_extent
from lopcook.types import MeshPart
from lopcook.viewing import Viewing


def _span_by_hand(error_m: float, extent_m: float, v: Viewing) -> float:
    """Pixels a part of largest extent ``extent_m`` spans where a LOD of error ``error_m`` is first
    selected: the distance d where the error is ``pixel_error`` pixels, then extent / pixel size."""
    per_metre = 2.0 * math.tan(math.radians(v.fov_y_deg) / 2.0) / v.viewport[1]  # pixel size at 1 m
    d = error_m / (v.pixel_error * per_metre)
    return extent_m / (d * per_metre)


@pytest.mark.parametrize("viewport", [(1920, 1080), (640, 480), (3840, 2160)])
@pytest.mark.parametrize("fov", [20.0, 60.0, 110.0])
@pytest.mark.parametrize("pixel_error", [0.25, 0.5, 1.0, 2.0])
def test_rule_limit_is_where_the_part_spans_min_pixels(viewport, fov, pixel_error):
    """At the limit the part spans exactly N pixels (rule 1) or its error is 10 % of its extent
    (rule 2, the tighter above pixel errors of N * 10 % = 0.8 px); the viewport and fov cancel."""
    v = Viewing(viewport=viewport, fov_y_deg=fov, pixel_error=pixel_error)
    rule = StopRule(v)
    for extent in (0.156, 2.0, 50.0):
        e = rule.max_error_m(extent)
        assert e == pytest.approx(extent * min(pixel_error / MIN_PIXELS, MAX_RELATIVE_ERROR), rel=1e-15)
        span = _span_by_hand(e, extent, v)
        assert rule.span_px(e, extent) == pytest.approx(span, rel=1e-12)
        if pixel_error <= MIN_PIXELS * MAX_RELATIVE_ERROR:
            assert rule.binding == "pixels" and span == pytest.approx(MIN_PIXELS, rel=1e-12)
        else:
            assert rule.binding == "relative_error" and span > MIN_PIXELS
            assert e == pytest.approx(MAX_RELATIVE_ERROR * extent, rel=1e-15)
        # just above the limit: fewer pixels than N, or more than 10 % of the extent
        above = e * (1 + 1e-9)
        assert _span_by_hand(above, extent, v) < MIN_PIXELS or above > MAX_RELATIVE_ERROR * extent


def test_rule_rejects_bad_numbers():
    for kw in ({"min_pixels": 0.0}, {"min_pixels": float("nan")}, {"max_relative_error": 0.0},
               {"max_relative_error": 1.5}):
        with pytest.raises(ValueError):
            StopRule(**kw)
    assert part_extent(np.array([[0.0, 0, 0], [1.0, 3.0, -2.0]])) == 3.0
    assert part_extent(np.zeros((0, 3))) == 0.0


def _sphere(name="s") -> MeshPart:
    p = F.unit_sphere(3)[0]
    return MeshPart(name, p.positions * np.array([1.0, 0.7, 1.3]), p.indices, normals=None, source=name)


@pytest.fixture(scope="module")
def free_chain():
    """The sphere's chain with fast-simplification and no limit: (part, lods)."""
    part = _sphere()
    lods, report = lod_chain(part, backend="fast", seams="ignore")
    assert report.stop in ("min_triangles", "ratios") and len(lods) >= 6
    return part, lods


@pytest.mark.parametrize("cut", [2, 4])
def test_chain_stops_at_the_first_lod_under_min_pixels(free_chain, cut):
    """With N between the spans of LOD ``cut`` and ``cut + 1``, the chain keeps LODs 0..cut, the
    same LODs as without the rule, and records LOD cut + 1 as dropped, with the pixels it spans."""
    part, free = free_chain
    extent = part_extent(part.positions)
    assert extent == pytest.approx(2.6, rel=1e-3)
    v = Viewing(viewport=(1280, 720), fov_y_deg=45.0)
    spans = [_span_by_hand(lod.error_m, extent, v) for lod in free[1:]]
    n = math.sqrt(spans[cut - 1] * spans[cut])  # between the kept and the dropped LOD's span
    rule = StopRule(v, min_pixels=n, max_relative_error=1.0)
    lods, report = lod_chain(part, backend="fast", seams="ignore", stop_rule=rule)
    assert [(x.triangles, x.error_m) for x in lods] == [(x.triangles, x.error_m) for x in free[:cut + 1]]
    assert report.stop == "pixels" and report.extent_m == extent
    assert report.max_error_m == pytest.approx(v.pixel_error * extent / n, rel=1e-12)
    assert report.dropped["triangles"] == free[cut + 1].triangles
    assert report.dropped["error_m"] == free[cut + 1].error_m
    assert _span_by_hand(lods[-1].error_m, extent, v) >= n > _span_by_hand(report.dropped["error_m"], extent, v)
    assert f"LOD {cut + 1} ({free[cut + 1].triangles:,} triangles" in report.stop_reason
    assert f"where the part spans {_span_by_hand(report.dropped['error_m'], extent, v):.3g} px" in report.stop_reason
    rec = manifest_record([report.as_dict()], rule)
    assert rec["stop_rule"] == {"min_pixels": n, "max_relative_error": 1.0}
    assert rec["reports"] == [{"stop": "pixels", "stop_reason": report.stop_reason, "extent_m": extent,
                               "max_error_m": report.max_error_m,
                               "dropped": {"triangles": free[cut + 1].triangles, "error_m": free[cut + 1].error_m}}]


def test_chain_stops_at_ten_percent_of_the_extent(free_chain):
    """A pixel error large enough that rule 2 binds: the chain stops at the first LOD whose error
    is above 10 % of the part's extent, and says so."""
    part, free = free_chain
    extent = part_extent(part.positions)
    rule = StopRule(Viewing(pixel_error=4.0))
    assert rule.binding == "relative_error"
    k = next(i for i, lod in enumerate(free) if lod.error_m > MAX_RELATIVE_ERROR * extent)
    lods, report = lod_chain(part, backend="fast", seams="ignore", stop_rule=rule)
    assert len(lods) == k and report.stop == "relative_error"
    assert lods[-1].error_m <= MAX_RELATIVE_ERROR * extent < report.dropped["error_m"]
    assert f"of the part's {extent:.3g} m extent (more than 10%)" in report.stop_reason


def test_a_tighter_view_cap_names_itself(free_chain):
    """The view cap (``max_error_m``, from ``--nearest``) below the rule's limit ends the chain as
    ``view``."""
    part, free = free_chain
    lods, report = lod_chain(part, backend="fast", seams="ignore", stop_rule=StopRule(),
                             max_error_m=0.5 * (free[1].error_m + free[2].error_m))
    assert len(lods) == 2 and report.stop == "view" and "exceeds max_error_m" in report.stop_reason


def test_copies_keep_the_stop_of_their_mesh(free_chain):
    """A copy scaled by 2 (a similarity) is cut where its mesh is (errors and extent scale
    together) and carries the dropped LOD's error scaled; its report says where."""
    part, free = free_chain
    v = Viewing()
    extent = part_extent(part.positions)
    n = math.sqrt(_span_by_hand(free[3].error_m, extent, v) * _span_by_hand(free[4].error_m, extent, v))
    rule = StopRule(v, min_pixels=n)
    lods, report = lod_chain(part, backend="fast", seams="ignore", stop_rule=rule)
    a, t = 2.0 * np.eye(3), np.array([5.0, 0.0, 0.0])
    copy = replace(part, name="copy", positions=part.positions @ a.T + t)
    placed, prep = I.placed_chain(lods, report, copy, a, t, None, rule)
    assert len(placed) == len(lods) == 4 and prep.stop == "pixels" and prep.extent_m == pytest.approx(2 * extent)
    assert prep.dropped["error_m"] == pytest.approx(2 * report.dropped["error_m"], rel=1e-12)
    # a copy whose own extent makes the rule tighter is cut there, with its own dropped LOD
    flat = np.diag([1.0, 1.0, 0.05])
    squashed = replace(part, name="flat", positions=part.positions @ flat.T)
    cut, crep = I.placed_chain(lods, report, squashed, flat, np.zeros(3), None, StopRule(v, min_pixels=4 * n))
    assert len(cut) < len(lods) and crep.stop == "pixels" and crep.dropped["triangles"] == lods[len(cut)].triangles


# ---- the corpus, through the command line -------------------------------------------------------

def _lopcook(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lopcook", *map(str, args)], capture_output=True, text=True)


@pytest.mark.parametrize("asset", ["stanford-bunny.obj", "spot.obj"])
def test_corpus_lods_auto_stops_by_the_rule(corpus, tmp_path, asset):
    """``cook --lods auto`` of the bunny and spot: the coarsest LOD is selected where the part still
    spans at least 8 px (the manifest's viewing, by hand) with an error of at most 10 % of its
    largest extent (from the source); the recorded stop names the dropped LOD, which breaks the
    rule; ``inspect`` prints the table and where the chain stopped."""
    from lopcook.ingest import load

    extent = part_extent(load(str(corpus / asset)).parts[0].positions)
    out = tmp_path / "auto.lop"
    cooked = _lopcook("cook", corpus / asset, "-o", out, "--lods", "auto")
    assert cooked.returncode == 0, cooked.stderr
    proc = _lopcook("inspect", out, "--json")
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    vw = d["viewing"]
    v = Viewing(viewport=tuple(vw["viewport"]), fov_y_deg=vw["fov_y_deg"], pixel_error=vw["pixel_error"])
    (part,) = d["parts"]
    last = part["lods"][-1]
    assert len(part["lods"]) >= 4
    assert last["geometric_error_m"] <= MAX_RELATIVE_ERROR * extent
    per_metre = 2.0 * math.tan(math.radians(v.fov_y_deg) / 2.0) / v.viewport[1]
    assert extent / (last["min_distance_m"] * per_metre) >= MIN_PIXELS
    stop = part["lod_stop"]
    assert stop["stop"] == "pixels" and stop["extent_m"] == pytest.approx(extent, rel=1e-12)
    assert _span_by_hand(stop["dropped"]["error_m"], extent, v) < MIN_PIXELS
    assert stop["dropped"]["triangles"] < last["triangles"]
    assert d["options"]["lods"]["stop_rule"] == {"min_pixels": MIN_PIXELS, "max_relative_error": MAX_RELATIVE_ERROR}
    text = _lopcook("inspect", out).stdout
    assert f"chain stopped: LOD {len(part['lods'])} ({stop['dropped']['triangles']:,} triangles" in text
    assert "px (fewer than 8); dropped" in text
    for k, e in enumerate(part["lods"]):  # the LOD table: index, triangles, vertices
        assert any(line.split()[:3] == [str(k), f"{e['triangles']:,}", f"{e['vertices']:,}"]
                   for line in text.splitlines())
