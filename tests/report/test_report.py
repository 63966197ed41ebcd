"""``lopcook report``: self-contained HTML + report.json (schema, table numbers, determinism, headless
Chromium decoding every image). Small renders (160x90, 2 views, levels 6-7) keep this to seconds.
GL tests skip when EGL is missing, except under CI=true, where they fail; the Chromium test likewise.
Module-level tests: test_report_model.py, test_report_images.py, test_report_svg.py."""

from __future__ import annotations

import base64
import html
import io
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from conftest import FIXTURES, REPO, require
from lopcook.cli import main
from lopcook.report.html import table_rows
from lopcook.report.text import fmt_pct, fmt_psnr

ARGS = ["--levels", "6-7", "--views", "2", "--resolution", "160x90"]
NAMES = ("two_plates", "glossy_crease")


@pytest.fixture(scope="module")
def reports(gl, tmp_path_factory):
    out = {}
    d = tmp_path_factory.mktemp("report")
    for name in NAMES:
        src = str(FIXTURES / f"{name}.glb")
        lop = str(d / f"{name}.lop")
        assert main(["-q", "cook", src, "-o", lop]) == 0
        html_path = d / f"{name}.html"
        assert main(["-q", "report", lop, "--source", src, "-o", str(html_path), *ARGS]) == 0
        out[name] = (src, lop, html_path, html_path.with_suffix(".json"))
    return out


def _schema():
    return json.loads((REPO / "schema" / "report.schema.json").read_text())


def _expected_images(rep) -> int:
    """Images the page shows: the level image, five per level (float, AP, CAP, two heat maps) and CAP
    at native size where the crop is enlarged, four per zoom (float, AP, CAP, the variant's heat
    map), three for the depth-order view, the worst view when it is not the shown one (float, AP,
    CAP, CAP heat map, native CAP where enlarged, three per zoom), and per LOD rendered its CAP and
    float (and native CAP where enlarged)."""
    im = rep["images"]
    n = (1 + sum(5 + (r["crop"]["scale"] > 1) for r in im["per_level"])
         + 4 * sum(1 for r in im["per_level"] if r["zoom"]) + (3 if im["depth"] else 0))
    w = im["worst"]
    if w and w["view"] != im["view"]:
        n += 4 + (w["crop"]["scale"] > 1) + (3 if w["zoom"] else 0)
    return n + sum(2 + (r["crop"]["scale"] > 1) for r in im["lods"] if r["crop"])


@pytest.mark.parametrize("name", NAMES)
def test_html_self_contained(reports, name):
    _, _, html_path, json_path = reports[name]
    text = html_path.read_text()
    rep = json.loads(json_path.read_text())
    assert "http://" not in text and "https://" not in text
    assert not re.search(r"<(script|link|iframe|img)[^>]*\s(src|href)=\"(?!data:)", text)
    srcs = re.findall(r"<img[^>]*\ssrc=\"([^\"]*)\"", text)
    assert len(srcs) == _expected_images(rep) >= 1 + 5 * 2
    for s in srcs:
        assert s.startswith("data:image/png;base64,")
    imgs = _pngs(text)  # every image decodes
    for r in rep["images"]["per_level"]:  # each level's images share that level's crop
        for k in ("float", "ap", "cap", "ap_heatmap", "cap_heatmap"):
            a = imgs[f"L{r['level']}-{k}"]
            assert (a.shape[1], a.shape[0]) == tuple(r["crop"]["size"]), (r["level"], k)
    assert text.count("<svg") >= 4  # memory-vs-PSNR chart, histogram (linear and log), heat-map scale


@pytest.mark.parametrize("name", NAMES)
def test_json_schema_and_table(reports, name):
    import jsonschema

    _, _, html_path, json_path = reports[name]
    rep = json.loads(json_path.read_text())
    jsonschema.validate(rep, _schema(), cls=jsonschema.Draft202012Validator)
    assert rep["container"] == f"{name}.lop" and rep["source"] == f"{name}.glb"
    assert [r["level"] for r in rep["levels"]] == [6, 7]
    text = html_path.read_text()
    for r in rep["levels"]:
        m = re.search(rf'<tr data-level="{r["level"]}">(.*?)</tr>', text)
        assert m, r["level"]
        cells = [html.unescape(c) for c in re.findall(r"<td>(.*?)</td>", m.group(1))]
        assert cells[1] == fmt_pct(r["ap"]["percent_of_float32"])
        assert cells[2] == f"{fmt_psnr(r['ap']['psnr_min'])} / {fmt_psnr(r['ap']['psnr_mean'])}"
        assert cells[3] == fmt_pct(r["cap"]["percent_of_float32"])
        assert cells[4] == f"{fmt_psnr(r['cap']['psnr_min'])} / {fmt_psnr(r['cap']['psnr_mean'])}"
        assert cells[5] == f"{r['ap']['depth_order_errors']} / {r['cap']['depth_order_errors']}"
        mem = next(x for x in rep["memory"] if x["level"] == r["level"])
        assert r["cap"]["bytes"] == mem["cap_bytes"] and r["ap"]["bytes"] == mem["ap_bytes"]
    assert [row[0] for row in table_rows(rep)] == ["6", "7"]
    assert sum(rep["histogram"]) == rep["vertices"]
    assert rep["baselines"]["uniform16"]["percent_of_float32"] == pytest.approx(200 / 3)


def test_deterministic(reports, tmp_path):
    src, lop, _, json_path = reports["glossy_crease"]
    again = tmp_path / "again.html"
    assert main(["-q", "report", lop, "--source", src, "-o", str(again), *ARGS]) == 0
    a = json.loads(json_path.read_text())
    b = json.loads(again.with_suffix(".json").read_text())
    for k in ("seconds", "cook_timings_s"):  # the only values that vary between runs
        a.pop(k), b.pop(k)
    a["container"] = b["container"]  # same file, same name
    assert a == b


def test_bad_input(tmp_path, capsys):
    src = str(FIXTURES / "two_plates.glb")
    assert main(["report", str(tmp_path / "missing.lop"), "--source", src, "-o", str(tmp_path / "r.html")]) == 2
    assert main(["report", "x.lop", "--source", src, "-o", str(tmp_path / "no" / "r.html")]) == 2
    assert main(["report", "x.lop", "--source", src, "-o", str(tmp_path / "r.html"), "--views", "0"]) == 2
    assert main(["report", "x.lop", "--source", src, "-o", str(tmp_path / "r.txt")]) == 2
    (tmp_path / "dir.glb").mkdir()  # a source that is a directory is named as one, not "not found"
    assert main(["report", "x.lop", "--source", str(tmp_path / "dir.glb"), "-o", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 5 and all(line.startswith("lopcook: error:") for line in err)
    assert "is a directory" in err[-1]
    assert not list(tmp_path.glob("*.html")) and not list(tmp_path.glob("*.json"))


def _chromium_page(url: str, width: int, tmp_path, screenshot=None) -> dict:
    """Open ``url`` in headless Chromium inside an iframe ``width`` CSS pixels wide (headless windows are
    at least 500 wide; the iframe gives a phone's viewport) and return the report's ``body`` data
    attributes (images decoded, scroll width, inner width, chart text overlaps). ``screenshot``: also
    save a PNG of the frame's first 5000 pixels there."""
    exe = shutil.which("chromium")
    require(None if exe else "chromium is not on PATH (Debian package chromium)")
    wrap = tmp_path / f"wrap{width}.html"
    wrap.write_text(f'<!DOCTYPE html><html><body style="margin:0"><iframe id="f" src="{url}" '
                    f'style="width:{width}px;height:5000px;border:0"></iframe><script>'
                    "document.getElementById('f').addEventListener('load',function(){"
                    "var d=this.contentDocument.body.dataset;for(var k in d)document.body.dataset[k]=d[k];"
                    "document.body.dataset.done='1';});</script></body></html>")
    base = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync", "--hide-scrollbars",
            "--allow-file-access-from-files", f"--user-data-dir={tmp_path / 'profile'}",
            f"--window-size={max(width, 500)},5000"]
    r = subprocess.run(base + ["--dump-dom", wrap.as_uri()], capture_output=True, text=True, timeout=120)
    m = re.search(r"<body([^>]*)>", r.stdout)
    assert m and 'data-done="1"' in m.group(1), r.stderr[-2000:]
    if screenshot is not None:
        subprocess.run(base + [f"--screenshot={screenshot}", wrap.as_uri()], capture_output=True, timeout=120)
    return {k: v for k, v in re.findall(r'data-([a-z-]+)="([^"]*)"', m.group(1))}


@pytest.mark.parametrize("width", [1400, 390])
def test_chromium_every_image_loads_and_nothing_overflows(reports, tmp_path, width):
    """At a desktop width and a phone's, in headless Chromium: every image decodes (naturalWidth > 0),
    the page is no wider than the viewport (tables scroll inside their box, images and charts shrink)
    and no two texts of any chart overlap or reach outside their chart (their rendered boxes)."""
    _, _, html_path, json_path = reports["two_plates"]
    rep = json.loads(json_path.read_text())
    shot = tmp_path / f"report{width}.png"
    d = _chromium_page(html_path.resolve().as_uri(), width, tmp_path, screenshot=shot)
    n = _expected_images(rep)
    assert d["images-total"] == str(n) and d["images-ok"] == str(n)
    assert d["inner-width"] == str(width)
    assert int(d["scroll-width"]) <= width
    assert d["text-overlaps"] == "0" and d["text-clipped"] == "0"
    if shot.exists():
        from PIL import Image

        assert Image.open(shot).size[0] == max(width, 500)


def test_chromium_decodes(reports, tmp_path):
    exe = shutil.which("chromium")
    require(None if exe else "chromium is not on PATH (Debian package chromium)")
    _, _, html_path, json_path = reports["glossy_crease"]
    n = _expected_images(json.loads(json_path.read_text()))
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp_path / 'profile'}", "--dump-dom", html_path.resolve().as_uri()]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
    dom = r.stdout
    assert f'data-images-total="{n}"' in dom, r.stderr[-2000:]
    assert f'data-images-ok="{n}"' in dom
    assert '<table id="levels">' in dom and 'data-level="6"' in dom and 'data-level="7"' in dom


def test_calibration_and_timings_sections(reports):
    import jsonschema

    from lopcook.report.html import render_html

    rep = json.loads(reports["two_plates"][3].read_text())
    rep["calibration"] = {"target_psnr": 40.0, "statistic": "min", "reached": True, "kf": 3.0,
                          "curve": [{"cap_percent": 30.0, "psnr_min": 35.0, "log2_sigma": 1.0},
                                    {"cap_percent": 40.0, "psnr_min": 45.0, "log2_sigma": 0.0},
                                    {"cap_percent": 50.0, "psnr_min": None, "log2_sigma": -1.0}]}
    rep["cook_timings_s"] = {"ingest": 0.25, "analyse": 0.02}
    jsonschema.validate(rep, _schema(), cls=jsonschema.Draft202012Validator)
    text = render_html(rep, None)
    assert "k_f calibration" in text and text.count("<svg") == 4  # memory, histogram linear + log, calibration
    assert '<table id="timings">' in text and "0.250" in text


def _pngs(text: str) -> dict:
    """id -> (h, w, c) uint8 array of every inline image."""
    from PIL import Image

    out = {}
    for k, s in re.findall(r'<img id="img-([^"]+)"[^>]*\ssrc="data:image/png;base64,([^"]*)"', text):
        out[k] = np.asarray(Image.open(io.BytesIO(base64.b64decode(s))))
    return out


@pytest.mark.parametrize("name", NAMES)
def test_images_at_every_level_cropped_to_the_object(reports, name):
    """Every rendered level shows the same view's float, AP, CAP and heat maps, cropped to the object
    at that level and enlarged by an integer nearest-neighbour factor: at level 6 the object is some
    37 pixels tall, so it is enlarged to several times the 160x90 frame; the whole object is inside
    the crop with a background margin around it (unless the frame edge cuts it)."""
    _, _, html_path, json_path = reports[name]
    rep = json.loads(json_path.read_text())
    im = rep["images"]
    assert [r["level"] for r in im["per_level"]] == [r["level"] for r in rep["levels"]] == [6, 7]
    text = html_path.read_text()
    imgs = _pngs(text)
    levels_image = imgs.pop("levels")  # framed on its own (frame distance, own crop)
    assert levels_image.shape[2] == 4 and (levels_image[..., 3] > 0).any()
    for r in im["per_level"]:
        lv, crop = r["level"], r["crop"]
        (fw, fh), (x0, y0, x1, y1), s = crop["frame"], crop["box"], crop["scale"]
        assert (fw, fh) == (160, 90)
        assert 0 <= x0 < x1 <= fw and 0 <= y0 < y1 <= fh
        assert s >= 1 and crop["size"] == [(x1 - x0) * s, (y1 - y0) * s]
        if lv == 6:
            assert (x1 - x0) < fw / 2 and s >= 4 and max(crop["size"]) > fh  # small object, legible size
        alpha = np.zeros((y1 - y0, x1 - x0), dtype=bool)
        for k in ("float", "ap", "cap", "ap_heatmap", "cap_heatmap"):
            a = imgs[f"L{lv}-{k}"]
            assert a.shape[:2] == (crop["size"][1], crop["size"][0]), (lv, k)
            small = a[::s, ::s]
            # nearest neighbour: every s x s block is one rendered pixel
            assert np.array_equal(np.repeat(np.repeat(small, s, 0), s, 1), a), (lv, k)
            if k in ("float", "ap", "cap"):
                alpha |= small[..., 3] > 0
        assert alpha.any()
        edges = {"top": (y0 > 0, alpha[0]), "bottom": (y1 < fh, alpha[-1]), "left": (x0 > 0, alpha[:, 0]),
                 "right": (x1 < fw, alpha[:, -1])}
        for side, (inside, line) in edges.items():
            if inside:
                assert not line.any(), (lv, side)
        assert f"columns {x0}..{x1 - 1} and rows {y0}..{y1 - 1}" in text
    # the finer level is closer: the object covers more frame pixels there
    b6, b7 = (r["crop"]["box"] for r in im["per_level"])
    assert (b7[2] - b7[0]) * (b7[3] - b7[1]) > (b6[2] - b6[0]) * (b6[3] - b6[1])


@pytest.mark.parametrize("name", NAMES)
def test_zoom_is_where_the_error_is_worst(reports, name):
    """Each level's zoom window is, among all windows of its side inside the crop, the one whose CAP
    (else AP) squared error against float sums highest, recomputed here from the page's own images;
    its zoom images are those pixels, enlarged."""
    from lopcook.report.images import squared_error

    _, _, html_path, json_path = reports[name]
    rep = json.loads(json_path.read_text())
    imgs = _pngs(html_path.read_text())
    zoomed = 0
    for r in rep["images"]["per_level"]:
        z, crop, lv = r["zoom"], r["crop"], r["level"]
        if z is None:
            continue
        zoomed += 1
        s, (bx0, by0, _, _) = crop["scale"], crop["box"]
        ref = imgs[f"L{lv}-float"][::s, ::s]
        tst = imgs[f"L{lv}-{z['variant']}"][::s, ::s]
        err = squared_error(ref, tst)  # crop-local frame pixels
        x0, y0, x1, y1 = z["box"]
        side = x1 - x0
        sums = np.array([[err[y:y + side, x:x + side].sum() for x in range(err.shape[1] - side + 1)]
                         for y in range(err.shape[0] - side + 1)])
        assert err[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0].sum() == pytest.approx(sums.max(), rel=1e-9)
        assert z["sum_sq"] == pytest.approx(sums.max(), rel=1e-9) and 0 < z["share"] <= 1
        for k in ("float", "ap", "cap"):
            a = imgs[f"L{lv}-zoom-{k}"]
            assert a.shape[:2] == (z["size"][1], z["size"][0])
            want = imgs[f"L{lv}-{k}"][::s, ::s][y0 - by0:y1 - by0, x0 - bx0:x1 - bx0]
            assert np.array_equal(a[::z["scale"], ::z["scale"]], want), (lv, k)
    assert zoomed >= 1  # AP at level 6 always differs from float


def test_depth_order_view_is_shown(reports):
    """Two plates close together: the page names the level and view with the most depth-order error
    pixels and shows them as a mask whose pixel count is the table's count for that view."""
    _, _, html_path, json_path = reports["two_plates"]
    rep = json.loads(json_path.read_text())
    d = rep["images"]["depth"]
    assert d is not None and d["errors"] == d["pixels"] > 0
    row = next(r for r in rep["levels"] if r["level"] == d["level"])
    counts = [(r[v]["depth_order_errors_views"], v) for r in rep["levels"] for v in ("cap", "ap")]
    vi = rep["render"]["views"].index(d["view"])
    assert row[d["variant"]]["depth_order_errors_views"][vi] == d["errors"]
    best_cap = max(max(c) for c, v in counts if v == "cap")
    assert d["variant"] == ("cap" if best_cap > 0 else "ap")
    assert d["errors"] == max(max(c) for c, v in counts if v == d["variant"])
    text = html_path.read_text()
    assert f'<p id="depth" data-level="{d["level"]}" data-view="{d["view"]}">' in text
    mask = _pngs(text)["depth-mask"]
    s = d["crop"]["scale"]
    magenta = np.all(mask[::s, ::s] == (255, 0, 255), axis=-1)
    assert int(magenta.sum()) == d["pixels"]
    # glossy crease: one part, no depth-order errors: said so
    rep2 = json.loads(reports["glossy_crease"][3].read_text())
    assert rep2["images"]["depth"] is None
    assert "No depth-order errors at any rendered level" in reports["glossy_crease"][2].read_text()


@pytest.fixture(scope="module")
def lod_report(gl, tmp_path_factory):
    d = tmp_path_factory.mktemp("lodreport")
    src = str(FIXTURES / "unit_sphere.glb")
    lop = str(d / "sphere.lop")
    assert main(["-q", "cook", src, "-o", lop, "--lods", "auto", "--lod-backend", "fast"]) == 0
    html_path = d / "sphere.html"
    assert main(["-q", "report", lop, "--source", src, "-o", str(html_path), *ARGS]) == 0
    return lop, html_path, json.loads(html_path.with_suffix(".json").read_text())


def test_lod_table(lod_report):
    import jsonschema

    from lopcook.lop.container import read

    lop, html_path, rep = lod_report
    jsonschema.validate(rep, _schema(), cls=jsonschema.Draft202012Validator)
    c = read(lop)
    m = c.manifest
    lods = rep["lods"]
    assert lods["backend"] == "fast" and lods["ratios"] == "auto"
    assert len(lods["parts"]) == len(m["parts"]) == 1
    rows = lods["parts"][0]["lods"]
    entries = m["parts"][0]["lods"]
    assert len(rows) == len(entries) >= 4
    for r, e in zip(rows, entries):
        assert (r["triangles"], r["vertices"]) == (e["triangles"], e["vertices"])
        assert r["geometric_error_m"] == e["geometric_error_m"] and r["min_distance_m"] == e["min_distance_m"]
    # selection ranges tile [0, inf): each LOD ends where the next one starts
    assert rows[0]["min_distance_m"] == 0.0 and rows[-1]["max_distance_m"] is None
    for a, b in zip(rows, rows[1:]):
        assert a["max_distance_m"] == b["min_distance_m"] > a["min_distance_m"]
        assert b["triangles"] < a["triangles"] and b["geometric_error_m"] >= a["geometric_error_m"]
    # bytes: index and attribute sections exactly; mandatory words share the mandatory section
    sizes = {s["name"]: s["length"] for s in m["sections"]}
    lod_sections = sum(v for k, v in sizes.items() if k.rsplit("/", 1)[-1] in ("indices", "attributes"))
    assert sum(r["index_bytes"] + r["attribute_bytes"] for r in rows) == lod_sections
    assert sum(r["mandatory_position_bytes"] for r in rows) == sizes[m["positions"]["mandatory"]]
    assert all(r["bytes"] == r["index_bytes"] + r["attribute_bytes"] + r["mandatory_position_bytes"]
               + r["plane_position_bytes"] for r in rows)
    text = html_path.read_text()
    assert '<table id="lods">' in text
    for r in rows:
        m_ = re.search(rf'<tr data-part="[^"]*" data-lod="{r["lod"]}">(.*?)</tr>', text)
        cells = [html.unescape(x) for x in re.findall(r"<td[^>]*>(.*?)</td>", m_.group(1))]
        assert cells[1] == r["name"] == rep["lods"]["names"][r["lod"]]
        assert cells[2] == f"{r['triangles']:,}" and cells[7] == f"{r['bytes']:,}"
        assert cells[4] == f"{r['geometric_error_m']:.4g}"


def test_lod_notes_shown_when_recorded(lod_report):
    from lopcook.report.html import render_html

    _, _, rep = lod_report
    rep = json.loads(json.dumps(rep))
    rep["lods"]["parts"][0]["notes"] = ["LOD 0.0625: fast failed: test; falling back to pymeshlab"]
    text = render_html(rep, None)
    assert '<ul id="lod-notes">' in text and "falling back to pymeshlab" in text


@pytest.mark.parametrize("name", NAMES)
def test_uniform16_rendered_at_the_same_cameras(reports, name):
    """The 16-bit baseline is rendered (not only drawn as memory): one row per level, in the table's
    last column and in the chart; on the glossy crease its error is far below AP's at level 6."""
    _, _, html_path, json_path = reports[name]
    rep = json.loads(json_path.read_text())
    u = rep["baselines"]["uniform16"]
    assert u["rendered"] and [r["level"] for r in u["levels"]] == [r["level"] for r in rep["levels"]]
    assert u["percent_of_float32"] == pytest.approx(200 / 3) and u["bytes"] == 8 * rep["vertices"]
    text = html_path.read_text()
    for row, r in zip(table_rows(rep), u["levels"]):
        assert row[-1] == f"{fmt_psnr(r['psnr_min'])} / {fmt_psnr(r['psnr_mean'])}"
        m = re.search(rf'<tr data-level="{r["level"]}">(.*?)</tr>', text)
        assert html.unescape(re.findall(r"<td>(.*?)</td>", m.group(1))[-1]) == row[-1]
    assert "uniform 16-bit" in text
    if name == "glossy_crease":
        ap6 = rep["levels"][0]["ap"]["psnr_min"]
        assert u["levels"][0]["psnr_min"] is None or u["levels"][0]["psnr_min"] > ap6 + 10


@pytest.mark.parametrize("name", NAMES)
def test_cook_timings_from_an_identical_recook(reports, name):
    _, _, html_path, json_path = reports[name]
    rep = json.loads(json_path.read_text())
    assert rep["cook"]["status"] == "identical" and rep["cook"]["bytes"] > 0
    t = rep["cook_timings_s"]
    assert {"ingest", "analyse", "emit"} <= set(t)
    text = html_path.read_text()
    for stage in t:  # every timed stage is a row of the page's table
        assert f"<tr><td>{html.escape(stage)}</td>" in text, stage
    assert 'data-status="identical"' in text and '<table id="timings">' in text and 'id="bought"' in text
    assert rep["images"]["level_range"][0] >= 1 and "levels" in rep["images"]["kinds"]


def test_no_analyse_skips_the_recook(reports, tmp_path):
    src, lop, _, _ = reports["two_plates"]
    out = tmp_path / "quick.html"
    assert main(["-q", "report", lop, "--source", src, "-o", str(out), *ARGS, "--no-analyse"]) == 0
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["cook"] is None and rep["cook_timings_s"] is None and rep["warnings"]["available"] is False
    assert "not measured" in out.read_text()


def test_progress_stages(reports, tmp_path, capsys):
    """``--progress plain``: one line per stage on stderr (ingest, every render counted, re-cook, page),
    nothing on stdout but the summary; the default off a terminal is silent."""
    src, lop, _, _ = reports["two_plates"]
    out = tmp_path / "p.html"
    assert main(["--progress", "plain", "report", lop, "--source", src, "-o", str(out), *ARGS]) == 0
    cap = capsys.readouterr()
    err = cap.err.splitlines()
    assert any(re.fullmatch(r"lopcook: ingest two_plates\.glb: in [\d.]+ s", x) for x in err), err
    # 2 levels: 2 container evaluations, 2 baseline ones, the worst view, the LOD renders, the
    # depth-order view and the level image
    assert any(re.fullmatch(r"lopcook: render: 8 of 8 in [\d.]+ s", x) for x in err), err
    assert any(x.startswith("lopcook: re-cook") for x in err) and any(x.startswith("lopcook: page:") for x in err)
    assert "lopcook:" not in cap.out and "wrote" in cap.out
    assert main(["report", lop, "--source", src, "-o", str(out), *ARGS]) == 0
    assert capsys.readouterr().err == ""
