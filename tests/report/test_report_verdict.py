"""``lopcook report`` answers "does it pass?": the verdict banner and exit code (1 on FAIL), views a
person recognises (a front or three-quarter view first, the worst view second), small objects at
their native size beside the enlarged crop, every LOD rendered at its selection distance and named
one way everywhere, the terms explained where they first appear, and no repeated rows.

Corpus assets, small renders (2 or 20 views at 320x180 or 160x90): the point is the page and its
verdict, not the PSNR of a large render. Containers are cooked once per session (``cooked``)."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from conftest import REPO
from lopcook.cli import main

HARNESS = ["--views", "2", "--resolution", "320x180"]


def _report(lop, src, out, *args, capsys=None):
    """(exit code, report.json, page text, stdout) of ``lopcook -q report lop --source src -o out *args``."""
    rc = main(["-q", "report", str(lop), "--source", str(src), "-o", str(out), *args])
    stdout = capsys.readouterr().out if capsys is not None else ""
    rep = json.loads(out.with_suffix(".json").read_text())
    return rc, rep, out.read_text(), stdout


def _validate(rep):
    import jsonschema

    schema = json.loads((REPO / "schema" / "report.schema.json").read_text())
    jsonschema.validate(rep, schema, cls=jsonschema.Draft202012Validator)


def _pngs(text: str) -> dict:
    from test_report import _pngs as pngs

    return pngs(text)


def _lowest(rep) -> tuple:
    """(psnr, level, view) of the lowest CAP PSNR over the report's rows, from the rows themselves."""
    views = rep["render"]["views"]
    return min((p, r["level"], views[i]) for r in rep["levels"] for i, p in enumerate(r["cap"]["psnr_views"])
               if p is not None)


@pytest.fixture(scope="module")
def bunny_reports(corpus, gl, cooked, tmp_path_factory):
    """The bunny's default cook and its ``--eps 0.5`` cook, each reported with the small harness."""
    d = tmp_path_factory.mktemp("verdict")
    src = corpus / "stanford-bunny.obj"
    out = {}
    for name, flags in (("default", ()), ("eps", ("--eps", "0.5"))):
        lop = cooked(src, *flags)
        rc, rep, page, _ = _report(lop, src, d / f"{name}.html", *HARNESS)
        out[name] = {"lop": lop, "src": src, "rc": rc, "rep": rep, "page": page, "html": d / f"{name}.html"}
    return out


def test_default_cook_passes_and_eps_half_fails(bunny_reports):
    """The default cook: PASS, exit 0; ``--eps 0.5`` (128 times the allowed shading error): FAIL,
    exit 1. The verdict's worst (level, view) is the lowest CAP PSNR of the rows."""
    ok, bad = bunny_reports["default"], bunny_reports["eps"]
    assert ok["rc"] == 0 and ok["rep"]["verdict"]["result"] == "PASS"
    assert bad["rc"] == 1 and bad["rep"]["verdict"]["result"] == "FAIL"
    for r in (ok, bad):
        _validate(r["rep"])
        v = r["rep"]["verdict"]
        psnr, level, view = _lowest(r["rep"])
        assert (v["worst"]["psnr"], v["worst"]["level"], v["worst"]["view"]) == (psnr, level, view)
        assert v["min_psnr"] == 40.0 and (psnr >= 40.0) is (v["result"] == "PASS")
        failing = sorted({row["level"] for row in r["rep"]["levels"]
                          if any(p is not None and p < 40.0 for p in row["cap"]["psnr_views"])})
        assert v["failing_levels"] == failing
        assert v["worst"]["part"]["name"] == "stanford-bunny" and 0.5 < v["worst"]["part"]["share"] <= 1.0


@pytest.mark.parametrize("name", ["default", "eps"])
def test_banner_names_the_worst_level_view_and_part(bunny_reports, name):
    r = bunny_reports[name]
    v, page = r["rep"]["verdict"], r["page"]
    m = re.search(r'<div id="verdict" class="verdict (pass|fail)" data-result="(PASS|FAIL)">(.*?)</div>', page, re.S)
    assert m and m.start() < page.index("<h2") and m.group(2) == v["result"] and m.group(1) == v["result"].lower()
    text = re.sub(r"<[^>]+>", "", m.group(3))
    w = v["worst"]
    assert f"{v['result']}:" in text and f"{w['psnr']:.1f} dB" in text and "40 dB" in text
    assert f"level {w['level']}, view {w['view']}" in text and "part stanford-bunny" in text
    assert ("≥" if name == "default" else "<") in text.replace("&ge;", "≥").replace("&lt;", "<")


def test_min_psnr_sets_the_threshold_and_the_exit_code(bunny_reports, tmp_path, capsys):
    """``--min-psnr`` just under the worst CAP PSNR passes (exit 0), just over it fails (exit 1); the
    FAIL line names the worst view even with -q; ``--json`` prints the report with its verdict."""
    r = bunny_reports["eps"]
    worst = r["rep"]["verdict"]["worst"]["psnr"]
    args = [*HARNESS, "--no-analyse"]
    rc, rep, _, out = _report(r["lop"], r["src"], tmp_path / "low.html", *args, "--min-psnr", f"{worst - 0.05:.3f}",
                              capsys=capsys)
    assert rc == 0 and rep["verdict"]["result"] == "PASS" and out == ""
    rc, rep, _, out = _report(r["lop"], r["src"], tmp_path / "high.html", *args, "--min-psnr", f"{worst + 0.05:.3f}",
                              capsys=capsys)
    assert rc == 1 and rep["verdict"]["result"] == "FAIL"
    w = rep["verdict"]["worst"]
    assert out.splitlines()[0].strip().startswith(f"FAIL: worst CAP PSNR {w['psnr']:.1f} dB < ")
    assert f"at level {w['level']}, view {w['view']}, part stanford-bunny" in out
    rc = main(["report", str(r["lop"]), "--source", str(r["src"]), "-o", str(tmp_path / "j.html"), *args, "--json"])
    printed = json.loads(capsys.readouterr().out)
    assert rc == 1 and printed["verdict"]["result"] == "FAIL"
    assert main(["report", str(r["lop"]), "--source", str(r["src"]), "-o", str(tmp_path / "n.html"),
                 "--min-psnr", "nan"]) == 2
    assert not (tmp_path / "n.html").exists()


def test_native_size_beside_the_enlarged_crop(bunny_reports):
    """Every level whose crop is enlarged also shows CAP at its native size: the crop's box at one
    rendered pixel per pixel, the same pixels as the enlarged image's blocks."""
    r = bunny_reports["default"]
    imgs = _pngs(r["page"])
    enlarged = [x for x in r["rep"]["images"]["per_level"] if x["crop"]["scale"] > 1]
    assert enlarged  # the bunny at level 6 is some 40 pixels tall
    for x in enlarged:
        lv, (x0, y0, x1, y1), s = x["level"], x["crop"]["box"], x["crop"]["scale"]
        native, big = imgs[f"L{lv}-native"], imgs[f"L{lv}-cap"]
        assert native.shape[:2] == (y1 - y0, x1 - x0)
        assert np.array_equal(big[::s, ::s], native)
        assert f'<figure class="native"><img id="img-L{lv}-native"' in r["page"]


def test_clusters_table_without_repeated_rows(bunny_reports):
    page = bunny_reports["default"]["page"]
    table = re.search(r'<table id="clusters">(.*?)</table>', page, re.S).group(1)
    rows = [re.findall(r"<td>(.*?)</td>", x)[1:] for x in re.findall(r"<tr data-levels[^>]*>(.*?)</tr>", table)]
    assert rows and all(a != b for a, b in zip(rows, rows[1:]))
    spans = re.findall(r'<tr data-levels="(\d+)-(\d+)"', table)
    covered = [b for lo, hi in spans for b in range(int(lo), int(hi) + 1)]
    assert covered == list(range(1, bunny_reports["default"]["rep"]["available_level"] + 1))
    anchors = re.search(r"Anchor bits k per cluster component[^<]*", page).group(0)
    assert not re.search(r"\b\d+:0\b", anchors)  # no empty entries


TERMS_FIRST = ("AP", "CAP", "PSNR", "level", "view")


def test_terms_explained_where_they_first_appear(bunny_reports):
    """The first time the page's text says AP, CAP, PSNR, level or view, the word carries its
    explanation (an ``<abbr title>``, or it is the term the Terms box explains), and the Terms box
    explains each of them."""
    from lopcook.report.text import TERMS

    page = bunny_reports["eps"]["page"]
    body = page[page.index("<body>"):]
    body = re.sub(r"<(script|style|svg)\b.*?</\1>", "", body, flags=re.S)
    marked = re.sub(r'<abbr title="[^"]*">([^<]*)</abbr>|<dt>([^<]*)</dt>', r"[[\1\2]]", body)
    text = re.sub(r"<[^>]+>", " ", marked)
    for t in TERMS_FIRST:
        m = re.search(rf"(\[\[)?\b{re.escape(t)}s?\b", text)
        assert m and m.group(1) == "[[", (t, text[max(0, m.start() - 80):m.start() + 40] if m else None)
    box = re.search(r'<details id="terms" open>(.*?)</details>', page, re.S).group(1)
    for t in TERMS:
        assert f"<dt>{t}</dt>" in box


@pytest.fixture(scope="module")
def bunny_views(corpus, gl, cooked, tmp_path_factory):
    """The bunny reported from all 20 views (tiny renders, two levels, no re-cook)."""
    src = corpus / "stanford-bunny.obj"
    out = tmp_path_factory.mktemp("views") / "views.html"
    rc, rep, page, _ = _report(cooked(src), src, out, "--views", "20", "--resolution", "160x90", "--levels", "6,9",
                               "--no-analyse")
    assert rc == 0
    return rep, page


def test_shown_view_is_front_or_three_quarter_by_projected_area(bunny_views):
    """Not from underneath (where the bunny's ears read as horns): the shown view's eye is above the
    horizon and at most 45 degrees up, on the front side (+Z), and of those views it covers the most
    pixels; the per-vertex level image is rendered from it."""
    from lopcook.verify.cameras import icosahedron_directions

    rep, page = bunny_views
    _validate(rep)
    im = rep["images"]
    views = rep["render"]["views"]
    d = icosahedron_directions()

    def recognisable(v):
        elev = math.degrees(math.asin(d[v][1]))
        return 0.0 <= elev <= 45.0 and d[v][2] > 0.0

    assert recognisable(im["view"])
    pixels = {v: im["view_pixels"][i] for i, v in enumerate(views)}
    assert pixels[im["view"]] == max(pixels[v] for v in views if recognisable(v))
    assert im["view_pixels"] == [int(x) for x in im["view_pixels"]] and len(im["view_pixels"]) == 20
    assert f'<h2>Images at every level (view {im["view"]})</h2>' in page and 'id="view-choice"' in page
    assert all(x["level"] in (6, 9) for x in im["per_level"])


def test_worst_view_shown_second(bunny_views):
    """The worst view (lowest CAP PSNR over every level and view) keeps its place, after the shown
    view: its float, AP, CAP and heat map, and its part."""
    rep, page = bunny_views
    w = rep["images"]["worst"]
    psnr, level, view = _lowest(rep)
    assert (w["psnr"], w["level"], w["view"]) == (psnr, level, view) and w["part"]["name"] == "stanford-bunny"
    assert page.index('<h2 id="worst">') > page.index("<h2>Images at every level")
    assert f'<p id="worst-view" data-level="{level}" data-view="{view}">' in page
    if view != rep["images"]["view"]:
        imgs = _pngs(page)
        for k in ("float", "ap", "cap", "cap_heatmap"):
            assert imgs[f"worst-{k}"].shape[:2] == (w["crop"]["size"][1], w["crop"]["size"][0])


@pytest.fixture(scope="module")
def spot_lods(corpus, gl, cooked, tmp_path_factory):
    """spot cooked with ``--lods auto`` (11 LODs), reported with the small harness and its re-cook
    (the LOD chain's notes)."""
    src = corpus / "spot.obj"
    lop = cooked(src, "--lods", "auto")
    out = tmp_path_factory.mktemp("lods") / "spot.html"
    rc, rep, page, _ = _report(lop, src, out, *HARNESS, "--levels", "6,9")
    assert rc in (0, 1)
    return lop, rep, page


def test_every_lod_rendered_at_its_selection_distance(spot_lods):
    from lopcook.lop.container import read
    from lopcook.verify.cameras import render_viewing
    from lopcook.viewing import required_level

    lop, rep, page = spot_lods
    _validate(rep)
    m = read(lop).manifest
    entries = m["parts"][0]["lods"]
    recs = rep["images"]["lods"]
    assert [r["lod"] for r in recs] == list(range(len(entries))) and len(entries) > 4
    scale = rep["render"]["resolution"][1] / m["viewing"]["viewport"][1]
    viewing = render_viewing(m, rep["render"]["resolution"])
    imgs = _pngs(page)
    for r, e in zip(recs, entries):
        assert (r["triangles"], r["geometric_error_m"]) == (e["triangles"], e["geometric_error_m"])
        if r["lod"] > 0:
            assert r["selection_distance_m"] == e["min_distance_m"]
            assert r["distance_m"] == pytest.approx(e["min_distance_m"] * scale, rel=1e-12)
        assert r["level"] == min(int(required_level(r["distance_m"], m["grid"]["extent"], viewing)), 24)
        sec = re.search(rf'<section class="lod" data-lod="{r["lod"]}"><h3>(.*?)</h3>', page).group(1)
        assert sec.startswith(r["name"] + ": ") and f"{r['triangles']:,} triangles" in sec
        assert "error " in sec and f"level {r['level']}" in sec
        cap = imgs[f"lod{r['lod']}-cap"]
        assert cap.shape[:2] == (r["crop"]["size"][1], r["crop"]["size"][0])
        if r["crop"]["scale"] > 1:
            x0, y0, x1, y1 = r["crop"]["box"]
            assert imgs[f"lod{r['lod']}-native"].shape[:2] == (y1 - y0, x1 - x0)
    # LOD 0 is seen nearer than where LOD 1 takes over
    assert recs[0]["distance_m"] < recs[1]["distance_m"]
    # farther LODs cover fewer pixels
    px = [r["object_pixels"] for r in recs[1:]]
    assert all(a >= b for a, b in zip(px, px[1:]))


def test_lods_named_one_way_everywhere(spot_lods):
    """Tables, notes and renders name a LOD "LOD k (share of the triangles)"; no note names one by
    its ratio ("LOD 0.25")."""
    _, rep, page = spot_lods
    names = rep["lods"]["names"]
    assert names[0] == "LOD 0 (all triangles)" and names[1] == "LOD 1 (1/2 of the triangles)"
    rows = rep["lods"]["parts"][0]["lods"]
    assert [r["name"] for r in rows] == names
    for r in rows:
        assert f'<td class="name">{r["name"]}</td>' in page.replace("&#x27;", "'")
    notes = rep["lods"]["parts"][0]["notes"]
    assert notes and any(n.startswith("LOD 1 (1/2 of the triangles): ") for n in notes)
    assert not re.search(r"\bLOD \d*\.\d", page) and not any(re.search(r"\bLOD \d*\.\d", n) for n in notes)
