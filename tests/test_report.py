"""``lopcook report``: self-contained HTML + report.json (schema, table numbers, determinism, headless
Chromium decoding every image). Small renders (160x90, 2 views, levels 6-7) keep this to seconds.
GL tests skip when EGL is missing, except under CI=true, where they fail; the Chromium test likewise."""

from __future__ import annotations

import base64
import html
import io
import json
import re
import shutil
import subprocess

import pytest

from conftest import FIXTURES, REPO, require
from lopcook.cli import main
from lopcook.report import fmt_pct, fmt_psnr, table_rows

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


@pytest.mark.parametrize("name", NAMES)
def test_html_self_contained(reports, name):
    from PIL import Image

    _, _, html_path, _ = reports[name]
    text = html_path.read_text()
    assert "http://" not in text and "https://" not in text
    assert not re.search(r"<(script|link|iframe|img)[^>]*\s(src|href)=\"(?!data:)", text)
    srcs = re.findall(r"<img[^>]*\ssrc=\"([^\"]*)\"", text)
    assert len(srcs) == 5  # float, AP, CAP, AP and CAP heat maps
    for s in srcs:
        assert s.startswith("data:image/png;base64,")
        im = Image.open(io.BytesIO(base64.b64decode(s.split(",", 1)[1])))
        im.load()
        assert im.size == (160, 90)
    assert text.count("<svg") >= 2  # memory-vs-PSNR chart, histogram


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
    a.pop("seconds"), b.pop("seconds")
    a["container"] = b["container"]  # same file, same name
    assert a == b


def test_bad_input(tmp_path, capsys):
    src = str(FIXTURES / "two_plates.glb")
    assert main(["report", str(tmp_path / "missing.lop"), "--source", src, "-o", str(tmp_path / "r.html")]) == 2
    assert main(["report", "x.lop", "--source", src, "-o", str(tmp_path / "no" / "r.html")]) == 2
    assert main(["report", "x.lop", "--source", src, "-o", str(tmp_path / "r.html"), "--views", "0"]) == 2
    assert main(["report", "x.lop", "--source", src, "-o", str(tmp_path / "r.txt")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(line.startswith("lopcook: error:") for line in err)
    assert not list(tmp_path.glob("*.html")) and not list(tmp_path.glob("*.json"))


def test_chromium_decodes(reports, tmp_path):
    exe = shutil.which("chromium")
    require(None if exe else "chromium is not on PATH (Debian package chromium)")
    _, _, html_path, _ = reports["glossy_crease"]
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp_path / 'profile'}", "--dump-dom", html_path.resolve().as_uri()]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
    dom = r.stdout
    assert 'data-images-total="5"' in dom, r.stderr[-2000:]
    assert 'data-images-ok="5"' in dom
    assert '<table id="levels">' in dom and 'data-level="6"' in dom and 'data-level="7"' in dom


def test_calibration_and_timings_sections(reports):
    import jsonschema

    from lopcook.report import render_html

    rep = json.loads(reports["two_plates"][3].read_text())
    rep["calibration"] = {"target_psnr": 40.0, "statistic": "min", "reached": True, "kf": 3.0,
                          "curve": [{"cap_percent": 30.0, "psnr_min": 35.0, "log2_sigma": 1.0},
                                    {"cap_percent": 40.0, "psnr_min": 45.0, "log2_sigma": 0.0},
                                    {"cap_percent": 50.0, "psnr_min": None, "log2_sigma": -1.0}]}
    rep["cook_timings_s"] = {"ingest": 0.25, "analyse": 0.02}
    jsonschema.validate(rep, _schema(), cls=jsonschema.Draft202012Validator)
    text = render_html(rep, None)
    assert "k_f calibration" in text and text.count("<svg") == 3
    assert '<table id="timings">' in text and "0.250" in text
