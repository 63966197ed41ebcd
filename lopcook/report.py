"""``lopcook report``: one self-contained HTML page (plus ``report.json``) for a cooked container.

``build_report`` turns a render evaluation (``lopcook.verify.render.evaluate``), the container
summary (``lopcook.emit.summary.describe_container``) and, optionally, a re-run analysis's warnings
into a JSON-ready dict (plain Python numbers only, file names without directories, no timestamps;
the only run-dependent values are under ``seconds``). ``write_html`` renders it as one HTML file
with inline CSS, images as PNG ``data:`` URIs and charts as inline SVG (no JavaScript library, no
network; a five-line inline script only counts decoded images into ``body[data-images-ok]`` for
headless checks).

Uniform 16-bit quantization baseline (KHR_mesh_quantization, VEC3 SHORT padded to 8 bytes per
vertex = 66.7 % of float32): it is **not rendered**. Its largest position error is given
analytically, sqrt(3) * extent * 2^-17 metres (half a cell of a 2^16 grid over the container's grid
extent, on each axis), which is exactly CAP's bound at level 16; the chart draws it as a memory-only
marker.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
import os
from pathlib import Path

import numpy as np

from . import __version__
from .atomic import write_atomic

UNIFORM16_BYTES_PER_VERTEX = 8
FLOAT32_BYTES_PER_VERTEX = 12
VARIANT_KEYS = ("bytes", "percent_of_float32", "psnr_min", "psnr_mean", "psnr_pooled", "psnr_interior_min",
                "psnr_interior_mean", "max_error", "share_off", "pixels_off", "object_pixels",
                "depth_order_errors", "depth_order_errors_views", "part_mismatch", "psnr_views")
IMAGE_KEYS = ("float", "ap", "cap", "ap_heatmap", "cap_heatmap")


def _plain(x):
    """numpy scalars/arrays -> Python; floats must be finite (None stands for +inf PSNR)."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    return x


def _name(p) -> str | None:
    return None if p is None else os.path.basename(str(p))


def analysis_warnings(scene, manifest: dict) -> dict:
    """Re-run ``lopcook.analyse.analyse`` on ``scene`` with the container's recorded settings (defaults
    where they cannot be read back) and collect its warnings."""
    from dataclasses import fields

    from .analyse import analyse
    from .analyse.summary import describe_analysis
    from .settings import AnalyseSettings

    rec = ((manifest.get("options") or {}).get("analyse") or {})
    kw = {}
    names = {f.name for f in fields(AnalyseSettings)}
    for k, v in rec.items():
        k2 = "depth_threshold" if k == "depth_threshold_m" else k
        if k2 in names and v is not None and not isinstance(v, (dict, list)):
            kw[k2] = v
    try:
        settings = AnalyseSettings(**kw)
        an = analyse(scene, settings)
    except Exception:  # recorded settings not reproducible: fall back to defaults
        settings = AnalyseSettings()
        an = analyse(scene, settings)
    d = describe_analysis(an, str(scene.source))
    t = d["totals"]
    return {"available": True, "scene": [str(w) for w in scene.warnings],
            "touching": [list(p) for p in d["touching"]], "intersecting": [list(p) for p in d["intersecting"]],
            "degenerate_triangles": int(t["degenerate_triangles"]), "depth_capped": int(t["depth_capped"]),
            "attribute_unsatisfied": int(t["attribute_unsatisfied"])}


def build_report(container, scene, evaluation: dict, container_desc: dict, *, warnings: dict | None = None) -> dict:
    """Every number of the report, JSON-ready (see module docstring)."""
    ev = evaluation
    m = container.manifest
    extent = float(m["grid"]["extent"])
    options = container_desc.get("options") or {}
    levels = []
    for r in ev["levels"]:
        row = {"level": r["level"], "camera_level": r["camera_level"], "camera_distance_m": r["camera_distance_m"],
               "float_object_pixels": r["float_object_pixels"],
               "cap_max_position_error_m": math.sqrt(3.0) * extent * 2.0 ** -(r["level"] + 1)}
        for v in ("ap", "cap"):
            if v in r:
                row[v] = {k: r[v][k] for k in VARIANT_KEYS}
        levels.append(row)
    t = container_desc["totals"]
    n = int(ev["vertices"])
    u16 = {"bytes_per_vertex": UNIFORM16_BYTES_PER_VERTEX, "bytes": UNIFORM16_BYTES_PER_VERTEX * n,
           "percent_of_float32": 100.0 * UNIFORM16_BYTES_PER_VERTEX / FLOAT32_BYTES_PER_VERTEX,
           "max_position_error_m": math.sqrt(3.0) * extent * 2.0 ** -17, "equivalent_cap_level": 16,
           "psnr": None, "rendered": False,
           "note": "not rendered: KHR_mesh_quantization VEC3 SHORT padded to 8 bytes/vertex; its position error "
                   "bound equals CAP's at level 16"}
    imgs = ev.get("images")
    if warnings is None:
        warnings = {"available": False, "scene": [str(w) for w in getattr(scene, "warnings", ())],
                    "touching": [], "intersecting": [], "degenerate_triangles": None, "depth_capped": None,
                    "attribute_unsatisfied": None}
    depth_total = {v: sum(r[v]["depth_order_errors"] for r in levels if v in r) for v in ("ap", "cap")}
    rep = {
        "kind": "report",
        "generator": f"lopcook {__version__}",
        "container": _name(ev.get("container") or container.path),
        "source": _name(ev.get("source")),
        "render": {"resolution": ev["resolution"], "samples": ev["samples"], "views": ev["views"],
                   "lod": ev["lod"], "shading": ev["shading"], "viewing": ev["viewing"], "variants": ev["variants"],
                   "grid_extent_m": ev["grid_extent_m"], "box_m": ev["box_m"],
                   "device": (ev.get("device") or {}).get("renderer")},
        "parts": ev["parts"],
        "vertices": n,
        "triangles": int(t["triangles"]),
        "float32_bytes": ev["float32_bytes"],
        "available_level": int(container_desc["available_level"]),
        "levels": levels,
        "baselines": {"float32": {"percent_of_float32": 100.0, "psnr": None, "bytes": ev["float32_bytes"]},
                      "uniform16": u16},
        "histogram": [int(x) for x in t["histogram"]],
        "memory": container_desc["memory"],
        "images": None if not imgs else {"level": imgs["level"], "view": imgs["view"],
                                         "kinds": [k for k in IMAGE_KEYS if k in imgs]},
        "cook_timings_s": options.get("timings_s"),
        "warnings": warnings,
        "depth_order_errors_total": depth_total,
        "calibration": options.get("calibration"),
        "seconds": ev.get("seconds"),
    }
    return _plain(rep)


# ---- HTML ---------------------------------------------------------------------------------------------

def png_data_uri(a: np.ndarray) -> str:
    from PIL import Image

    a = np.ascontiguousarray(np.asarray(a, dtype=np.uint8))
    mode = "L"
    if a.ndim == 3 and a.shape[2] == 3:
        mode = "RGB"
    elif a.ndim == 3 and a.shape[2] == 4:
        mode = "RGBA"
    buf = io.BytesIO()
    Image.fromarray(a, mode).save(buf, format="PNG", optimize=False)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def fmt_pct(x) -> str:
    return "-" if x is None else f"{x:.1f}"


def fmt_psnr(x) -> str:
    return "inf" if x is None else f"{x:.1f}"


def _e(s) -> str:
    return html.escape(str(s), quote=True)


class _Plot:
    """Linear x/y axes into an SVG viewport; ``inf`` (None) y values go to a band at the top."""

    def __init__(self, xlo, xhi, ylo, yhi, w=560, h=320, pad=(56, 20, 28, 44)):
        self.xlo, self.xhi, self.ylo, self.yhi = xlo, xhi, ylo, yhi
        self.w, self.h = w, h
        self.l, self.r, self.t, self.b = pad
        self.parts: list[str] = []

    def x(self, v):
        return self.l + (v - self.xlo) / (self.xhi - self.xlo or 1) * (self.w - self.l - self.r)

    def y(self, v):
        if v is None:
            return self.t - 12
        return self.h - self.b - (v - self.ylo) / (self.yhi - self.ylo or 1) * (self.h - self.t - self.b)

    def axes(self, xlabel, ylabel, xticks, yticks):
        p = self.parts
        x0, x1, y0, y1 = self.l, self.w - self.r, self.h - self.b, self.t
        p.append(f'<line x1="{x0}" y1="{y0}" x2="{x1}" y2="{y0}" stroke="#333"/>')
        p.append(f'<line x1="{x0}" y1="{y0}" x2="{x0}" y2="{y1 - 16}" stroke="#333"/>')
        for v in xticks:
            X = self.x(v)
            p.append(f'<line x1="{X:.1f}" y1="{y0}" x2="{X:.1f}" y2="{y0 + 4}" stroke="#333"/>'
                     f'<text x="{X:.1f}" y="{y0 + 16}" text-anchor="middle">{_e(f"{v:g}")}</text>')
        for v in yticks:
            Y = self.y(v)
            lab = "inf" if v is None else f"{v:g}"
            p.append(f'<line x1="{x0 - 4}" y1="{Y:.1f}" x2="{x1}" y2="{Y:.1f}" stroke="#ddd"/>'
                     f'<text x="{x0 - 6}" y="{Y + 4:.1f}" text-anchor="end">{_e(lab)}</text>')
        p.append(f'<text x="{(x0 + x1) / 2:.1f}" y="{self.h - 6}" text-anchor="middle">{_e(xlabel)}</text>')
        p.append(f'<text x="14" y="{(y0 + y1) / 2:.1f}" text-anchor="middle" '
                 f'transform="rotate(-90 14 {(y0 + y1) / 2:.1f})">{_e(ylabel)}</text>')

    def series(self, pts, colour, name, labels=None, dash=""):
        if not pts:
            return
        d = " ".join(f"{self.x(a):.1f},{self.y(b):.1f}" for a, b in pts)
        da = f' stroke-dasharray="{dash}"' if dash else ""
        self.parts.append(f'<polyline points="{d}" fill="none" stroke="{colour}" stroke-width="1.5"{da}>'
                          f'<title>{_e(name)}</title></polyline>')
        for i, (a, b) in enumerate(pts):
            self.parts.append(f'<circle cx="{self.x(a):.1f}" cy="{self.y(b):.1f}" r="3.5" fill="{colour}">'
                              f'<title>{_e(name)}: {a:.1f} %, {fmt_psnr(b)} dB</title></circle>')
            if labels:
                self.parts.append(f'<text x="{self.x(a) + 5:.1f}" y="{self.y(b) - 5:.1f}" fill="{colour}" '
                                  f'font-size="10">{_e(labels[i])}</text>')

    def svg(self, title, legend=()):
        leg = "".join(f'<rect x="{self.w - 150}" y="{24 + 14 * i}" width="10" height="10" fill="{c}"/>'
                      f'<text x="{self.w - 136}" y="{33 + 14 * i}">{_e(n)}</text>' for i, (n, c) in enumerate(legend))
        return (f'<svg class="chart" viewBox="0 0 {self.w} {self.h}" '
                f'width="{self.w}" height="{self.h}" font-size="11" role="img" aria-label="{_e(title)}">'
                f'<title>{_e(title)}</title>' + "".join(self.parts) + leg + "</svg>")


def _ticks(lo, hi, n=6):
    step = (hi - lo) / n if hi > lo else 1.0
    mag = 10 ** math.floor(math.log10(step))
    step = min((s * mag for s in (1, 2, 5, 10) if s * mag >= step), default=step)
    start = math.ceil(lo / step) * step
    out, v = [], start
    while v <= hi + 1e-9:
        out.append(round(v, 10))
        v += step
    return out


def memory_psnr_svg(rep: dict) -> str:
    pts = {v: [(r[v]["percent_of_float32"], r[v]["psnr_min"]) for r in rep["levels"] if v in r] for v in ("ap", "cap")}
    labels = {v: [str(r["level"]) for r in rep["levels"] if v in r] for v in ("ap", "cap")}
    finite = [b for v in pts.values() for _, b in v if b is not None]
    ylo = math.floor((min(finite) if finite else 20.0) / 5) * 5 - 5
    yhi = math.ceil((max(finite) if finite else 60.0) / 5) * 5 + 5
    p = _Plot(0, 105, ylo, yhi)
    p.axes("position memory, % of float32", "PSNR min over views, dB", _ticks(0, 100, 5), _ticks(ylo, yhi) + [None])
    u = rep["baselines"]["uniform16"]
    X = p.x(u["percent_of_float32"])
    p.parts.append(f'<line x1="{X:.1f}" y1="{p.t - 16}" x2="{X:.1f}" y2="{p.h - p.b}" stroke="#888" '
                   f'stroke-dasharray="4 3"><title>uniform 16-bit: {u["percent_of_float32"]:.1f} %, not rendered'
                   f'</title></line><text x="{X + 4:.1f}" y="{p.h - p.b - 6}" fill="#666" font-size="10">16-bit '
                   f'(memory only)</text>')
    p.series(pts["ap"], "#d62728", "AP", labels["ap"])
    p.series(pts["cap"], "#1f77b4", "CAP", labels["cap"])
    p.series([(100.0, None)], "#2ca02c", "float32")
    return p.svg("memory vs PSNR per level", [("AP", "#d62728"), ("CAP", "#1f77b4"), ("float32", "#2ca02c"),
                                              ("16-bit (dashed)", "#888")])


def histogram_svg(hist: list[int]) -> str:
    nz = [b for b in range(1, len(hist)) if hist[b]]
    lo, hi = (nz[0], nz[-1]) if nz else (1, 24)
    top = max(hist) or 1
    w, h, l, b, t = 560, 220, 56, 36, 16
    bw = (w - l - 10) / (hi - lo + 1)
    parts = [f'<line x1="{l}" y1="{h - b}" x2="{w - 10}" y2="{h - b}" stroke="#333"/>']
    for i, lv in enumerate(range(lo, hi + 1)):
        bh = (h - b - t) * hist[lv] / top
        x = l + i * bw
        parts.append(f'<rect class="bar" data-level="{lv}" data-count="{hist[lv]}" x="{x + 1:.1f}" '
                     f'y="{h - b - bh:.1f}" width="{max(bw - 2, 1):.1f}" height="{bh:.1f}" fill="#1f77b4">'
                     f'<title>level {lv}: {hist[lv]} vertices</title></rect>'
                     f'<text x="{x + bw / 2:.1f}" y="{h - b + 14}" text-anchor="middle">{lv}</text>')
    parts.append(f'<text x="{l - 6}" y="{t + 4}" text-anchor="end">{top}</text>'
                 f'<text x="{(l + w) / 2:.1f}" y="{h - 4}" text-anchor="middle">minimum level (bits per component)'
                 f'</text>')
    return (f'<svg class="chart" viewBox="0 0 {w} {h}" width="{w}" height="{h}" '
            f'font-size="11" role="img" aria-label="minimum-level histogram"><title>minimum-level histogram</title>'
            + "".join(parts) + "</svg>")


def calibration_svg(cal: dict) -> str | None:
    curve = [c for c in (cal or {}).get("curve") or [] if c.get("cap_percent") is not None]
    if not curve:
        return None
    curve = sorted(curve, key=lambda c: c["cap_percent"])
    finite = [c["psnr_min"] for c in curve if c.get("psnr_min") is not None]
    ylo = math.floor((min(finite) if finite else 20) / 5) * 5 - 5
    yhi = math.ceil((max(finite) if finite else 60) / 5) * 5 + 5
    xs = [c["cap_percent"] for c in curve]
    xlo, xhi = max(0.0, min(xs) - 2), max(xs) + 2
    p = _Plot(xlo, xhi, ylo, yhi)
    p.axes("CAP memory, % of float32", "PSNR min, dB", _ticks(xlo, xhi, 5), _ticks(ylo, yhi) + [None])
    if cal.get("target_psnr") is not None and ylo <= cal["target_psnr"] <= yhi:
        Y = p.y(cal["target_psnr"])
        p.parts.append(f'<line x1="{p.l}" y1="{Y:.1f}" x2="{p.w - p.r}" y2="{Y:.1f}" stroke="#2ca02c" '
                       f'stroke-dasharray="4 3"><title>target {cal["target_psnr"]:g} dB</title></line>')
    p.series([(c["cap_percent"], c.get("psnr_min")) for c in curve], "#9467bd", "k_f scale",
             [f"2^{c['log2_sigma']:.2g}" if c.get("log2_sigma") is not None else "" for c in curve])
    return p.svg("k_f calibration: memory vs PSNR", [("CAP over k_f scale", "#9467bd")])


_CSS = """body{font-family:system-ui,sans-serif;margin:2em;max-width:1200px;color:#222}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f4f4f4}figure{display:inline-block;margin:0 1em 1em 0;vertical-align:top}
figure img{image-rendering:pixelated;border:1px solid #ccc;background:#fff}
figcaption{font-size:0.85em;color:#555}.warn{color:#a40}.note{font-size:0.85em;color:#555}
svg.chart{border:1px solid #eee;margin:0.5em 1em 0.5em 0}"""

_SCRIPT = """<script>window.addEventListener('load',function(){var n=0;
document.querySelectorAll('img').forEach(function(i){if(i.complete&&i.naturalWidth>0)n++;});
document.body.dataset.imagesOk=String(n);document.body.dataset.imagesTotal=String(document.images.length);});
</script>"""


def table_rows(rep: dict) -> list[list[str]]:
    """The Table-1-like rows as displayed (also used by tests)."""
    rows = []
    for r in rep["levels"]:
        ap, cap = r.get("ap"), r.get("cap")
        rows.append([str(r["level"]),
                     fmt_pct(ap["percent_of_float32"]) if ap else "-",
                     f"{fmt_psnr(ap['psnr_min'])} / {fmt_psnr(ap['psnr_mean'])}" if ap else "-",
                     fmt_pct(cap["percent_of_float32"]) if cap else "-",
                     f"{fmt_psnr(cap['psnr_min'])} / {fmt_psnr(cap['psnr_mean'])}" if cap else "-",
                     f"{ap['depth_order_errors'] if ap else '-'} / {cap['depth_order_errors'] if cap else '-'}"])
    return rows


def render_html(rep: dict, images: dict | None) -> str:
    e = _e
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>lopcook report: {e(rep['container'])}</title><style>{_CSS}</style></head><body>",
           f"<h1>lopcook report: {e(rep['container'])}</h1>",
           f"<p>source <b>{e(rep['source'])}</b>: {rep['parts']} parts, {rep['vertices']:,} vertices, "
           f"{rep['triangles']:,} triangles; levels 1..{rep['available_level']} in the file. Rendered at "
           f"{rep['render']['resolution'][0]}x{rep['render']['resolution'][1]}, {rep['render']['samples']}x MSAA, "
           f"{len(rep['render']['views'])} views on {e(rep['render']['device'])}.</p>",
           "<h2>Accuracy per level (Table 1)</h2>",
           '<table id="levels"><thead><tr><th>level</th><th>AP memory %</th><th>AP PSNR dB min / mean</th>'
           "<th>CAP memory %</th><th>CAP PSNR dB min / mean</th><th>depth-order error px AP / CAP</th></tr>"
           "</thead><tbody>"]
    for row in table_rows(rep):
        out.append(f'<tr data-level="{e(row[0])}">' + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>")
    out.append(f'</tbody></table><p class="note">Memory: GPU-resident position bytes vs float32 '
               f'({rep["float32_bytes"]:,} B). PSNR over object pixels against the float render; inf = identical.</p>')
    out.append("<h2>Memory vs PSNR</h2>" + memory_psnr_svg(rep))
    u = rep["baselines"]["uniform16"]
    out.append(f'<p class="note">float32 (100 %, PSNR inf) is drawn in the top band. Uniform 16-bit quantization '
               f'({u["bytes_per_vertex"]} B/vertex = {u["percent_of_float32"]:.1f} %): {e(u["note"])}; max position '
               f'error {u["max_position_error_m"]:.3g} m.</p>')
    out.append("<h2>Minimum-level histogram</h2>" + histogram_svg(rep["histogram"]))
    if images and rep.get("images"):
        im = rep["images"]
        out.append(f"<h2>Images at level {im['level']} (view {im['view']})</h2><div>")
        captions = {"float": "float32", "ap": "AP", "cap": "CAP", "ap_heatmap": "AP error heat map",
                    "cap_heatmap": "CAP error heat map"}
        for k in IMAGE_KEYS:
            if k in images and images[k] is not None:
                a = np.asarray(images[k])
                out.append(f'<figure><img id="img-{k}" alt="{e(captions[k])}" width="{a.shape[1]}" '
                           f'height="{a.shape[0]}" src="{png_data_uri(a)}"><figcaption>{e(captions[k])}'
                           f"</figcaption></figure>")
        out.append("</div>")
    out.append("<h2>Cook</h2>")
    tim = rep.get("cook_timings_s")
    if tim:
        out.append('<table id="timings"><tr><th>stage</th><th>seconds</th></tr>' + "".join(
            f"<tr><td>{e(k)}</td><td>{v:.3f}</td></tr>" for k, v in tim.items()) + "</table>")
    else:
        out.append('<p class="note">cook stage timings: not recorded in the container.</p>')
    w = rep["warnings"]
    items = [f"scene: {x}" for x in w["scene"]]
    if w["touching"]:
        items.append(f"{len(w['touching'])} touching part pairs: {w['touching']}")
    if w["intersecting"]:
        items.append(f"{len(w['intersecting'])} intersecting part pairs: {w['intersecting']}")
    for k in ("degenerate_triangles", "depth_capped", "attribute_unsatisfied"):
        if w.get(k):
            items.append(f"{w[k]} {k.replace('_', ' ')}")
    out.append("<h2>Warnings</h2>")
    if not w["available"]:
        out.append('<p class="note">analysis not re-run; only scene warnings are shown.</p>')
    out.append('<ul id="warnings">' + "".join(f'<li class="warn">{e(x)}</li>' for x in items) + "</ul>"
               if items else '<p id="warnings">none</p>')
    cal = rep.get("calibration")
    if cal:
        svg = calibration_svg(cal)
        out.append(f"<h2>k_f calibration</h2><p>target {e(cal.get('target_psnr'))} dB "
                   f"({e(cal.get('statistic'))}), reached: {e(cal.get('reached'))}, k_f {e(cal.get('kf'))}</p>"
                   + (svg or ""))
    out.append(_SCRIPT + "</body></html>")
    return "\n".join(out)


def report_json_bytes(rep: dict) -> bytes:
    return (json.dumps(rep, indent=1, sort_keys=True, allow_nan=False) + "\n").encode("utf-8")


def write_html(report_dict: dict, images: dict | None, path) -> tuple[Path, Path]:
    """Write ``path`` (HTML) and ``path`` with suffix ``.json`` atomically; returns both paths."""
    path = Path(path)
    jpath = path.with_suffix(".json")
    data = report_json_bytes(report_dict)
    page = render_html(report_dict, images).encode("utf-8")
    write_atomic(jpath, data)
    write_atomic(path, page)
    return path, jpath


__all__ = ["build_report", "write_html", "render_html", "analysis_warnings", "table_rows", "png_data_uri"]
