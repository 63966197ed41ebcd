"""The ``lopcook report`` page: one self-contained HTML file with inline CSS, images as PNG ``data:``
URIs and charts as inline SVG (no JavaScript library, no network; a five-line inline script only
counts decoded images into ``body[data-images-ok]`` for headless checks), written beside its
``report.json``.

Sections, in order: accuracy per level (Table 1 of Meyer et al. 2011: AP and CAP memory and PSNR,
depth-order errors, the uniform 16-bit baseline), memory vs PSNR chart, minimum-level histogram,
images of one view (float, AP, CAP, heat maps, minimum levels), levels of detail, cook (re-cook
status and stage timings), warnings, k_f calibration and byte budget when the container records
them. Input: the dict of ``lopcook.report.model.build_report``; the page is a function of it and
the images only.

Cook timings: a container holds none (deterministic bytes), so ``lopcook report`` re-cooks the
source with the recorded options (``lopcook.tune.recook.recook``), times every stage and compares
the bytes with the file (``cook.status``: identical / prefix / differs / not re-cooked).
"""

from __future__ import annotations

from pathlib import Path

from ..atomic import write_atomic
from .images import apply_crop, crop_box, png_data_uri
from .model import IMAGE_KEYS, report_json_bytes
from .svg import budget_svg, calibration_svg, histogram_svg, memory_psnr_svg
from .text import escape, fmt_pct, fmt_psnr


def budget_html(b: dict) -> str:
    """The "Byte budget" section: the definition, the chart (``budget_svg``) and the candidate table."""
    e = escape
    cam, ch = b["camera"], b["chosen"]
    base = b.get("baselines") or {}
    q, s = base.get("quantize_only"), base.get("simplify_only")
    out = [f'<h2>Byte budget</h2><p id="budget-summary">Budget <b>{b["target_bytes"]:,} bytes</b> ({e(b["scope"])}: '
           f'{100 * b.get("fraction_of_float", 0):.1f} % of the float size {b["float_bytes"]:,} B). Chosen: <b>LOD '
           f'{ch["lod"]} at level {ch["level"]}</b>, {ch["bytes"]:,} bytes, {fmt_psnr(ch["psnr_mean"])} dB. Quantize '
           f'only: ' + ("nothing fits" if not q else f'LOD 0 at level {q["level"]}, {fmt_psnr(q["psnr_mean"])} dB')
           + '; simplify only: ' + ("nothing fits" if not s else
                                   f'LOD {s["lod"]} in float32, {fmt_psnr(s["psnr_mean"])} dB') + ".</p>",
           f'<p class="note">Every candidate rendered against the float source from {len(cam["views"])} views at '
           f'{cam["resolution"][0]}x{cam["resolution"][1]}, camera {cam["distance_m"]:.4g} m from the bounding box '
           f'({e(cam["rule"])} distance; level {cam["level"]} there). PSNR of the view-averaged MSE over object '
           f'pixels (Purnomo et al. 2005, Fig. 11).</p>', budget_svg(b),
           '<table id="budget"><thead><tr><th>LOD</th><th>level</th><th>vertices</th><th>bytes</th>'
           "<th>bits/vertex</th><th>PSNR mean dB</th><th>PSNR min dB</th></tr></thead><tbody>"]
    for c in b["candidates"]:
        chosen = (c["lod"], c["level"]) == (ch["lod"], ch["level"])
        cls = ' class="chosen"' if chosen else ""
        out.append(f'<tr data-lod="{c["lod"]}" data-level="{c["level"]}"{cls}>'
                   f'<td>{c["lod"]}{" (chosen)" if chosen else ""}</td><td>{c["level"]}</td><td>{c["vertices"]:,}</td>'
                   f'<td>{c["bytes"]:,}</td><td>{c["bits_per_vertex"]:.1f}</td><td>{fmt_psnr(c["psnr_mean"])}</td>'
                   f'<td>{fmt_psnr(c.get("psnr_min"))}</td></tr>')
    out.append("</tbody></table>")
    return "".join(out)


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
    """The Table-1-like rows as displayed (also used by tests): level, AP memory %, AP PSNR min /
    mean, CAP memory %, CAP PSNR min / mean, depth-order errors AP / CAP, uniform 16-bit PSNR."""
    u16 = {r["level"]: r for r in rep["baselines"]["uniform16"].get("levels") or []}
    rows = []
    for r in rep["levels"]:
        ap, cap = r.get("ap"), r.get("cap")
        rows.append([str(r["level"]),
                     fmt_pct(ap["percent_of_float32"]) if ap else "-",
                     f"{fmt_psnr(ap['psnr_min'])} / {fmt_psnr(ap['psnr_mean'])}" if ap else "-",
                     fmt_pct(cap["percent_of_float32"]) if cap else "-",
                     f"{fmt_psnr(cap['psnr_min'])} / {fmt_psnr(cap['psnr_mean'])}" if cap else "-",
                     f"{ap['depth_order_errors'] if ap else '-'} / {cap['depth_order_errors'] if cap else '-'}",
                     f"{fmt_psnr(u16[r['level']]['psnr_min'])} / {fmt_psnr(u16[r['level']]['psnr_mean'])}"
                     if r["level"] in u16 else "-"])
    return rows


def _dist(x) -> str:
    return "inf" if x is None else f"{x:.4g}"


def lod_table_html(lods: dict) -> str:
    """The "Levels of detail" section: one table row per part and LOD (``lod_table``), then the
    savings record and any LOD notes."""
    e = escape
    how = (f"simplified with {e(lods['backend'])} at ratios {e(lods['ratios'])}" if lods.get("backend")
           else "no LOD options recorded")
    out = [f"<h2>Levels of detail</h2><p class=\"note\">{how}. Error: symmetric Hausdorff distance to LOD 0 as "
           "recorded in the container. Distances: the camera range over which lopcook.selection picks the LOD under "
           "the container's viewing. Bytes: index + attribute sections, the LOD's mandatory bits and its bits in "
           "the refinement planes.</p>",
           '<table id="lods"><thead><tr><th>part</th><th>LOD</th><th>triangles</th><th>vertices</th>'
           "<th>Hausdorff error m</th><th>selected from m</th><th>to m</th><th>bytes</th></tr></thead><tbody>"]
    for part in lods["parts"]:
        for r in part["lods"]:
            out.append(f'<tr data-part="{e(part["part"])}" data-lod="{r["lod"]}"><td>{e(part["part"])}</td>'
                       f"<td>{r['lod']}</td><td>{r['triangles']:,}</td><td>{r['vertices']:,}</td>"
                       f"<td>{r['geometric_error_m']:.4g}</td><td>{_dist(r['min_distance_m'])}</td>"
                       f"<td>{_dist(r['max_distance_m'])}</td><td>{r['bytes']:,}</td></tr>")
    out.append("</tbody></table>")
    sv = lods.get("savings")
    if sv:
        out.append(f'<p class="note">Not written (no view needs them): {sv["lods_dropped"]} LODs, planes '
                   f'{e(sv["planes_dropped"] or "none")}; {sv["bytes_saved"]:,} bytes saved.</p>')
    notes = [f"{p['part']}: {n}" for p in lods["parts"] for n in p.get("notes") or []]
    if notes:
        out.append('<ul id="lod-notes">' + "".join(f'<li class="note">{e(n)}</li>' for n in notes) + "</ul>")
    return "".join(out)


def _span(values, fmt) -> str:
    vals = [v for v in values if v is not None]
    if not vals:
        return "inf"
    lo, hi = min(vals), max(vals)
    return fmt(lo) if fmt(lo) == fmt(hi) else f"{fmt(lo)}-{fmt(hi)}"


def time_bought(rep: dict, seconds: float) -> str:
    """One sentence putting the cook time next to the accuracy it bought (CAP memory and PSNR over
    the rendered levels, AP at the same levels for comparison)."""
    rows = [r for r in rep["levels"] if "cap" in r]
    if not rows:
        return f"The cook's stages took {seconds:.2f} s."
    lv = f"{rows[0]['level']}-{rows[-1]['level']}" if len(rows) > 1 else str(rows[0]["level"])
    cap_mem = _span([r["cap"]["percent_of_float32"] for r in rows], lambda v: f"{v:.1f}")
    cap_db = _span([r["cap"]["psnr_min"] for r in rows], lambda v: f"{v:.1f}")
    text = (f"The cook's stages took {seconds:.2f} s (process start-up and imports not counted) and bought CAP at "
            f"{cap_mem} % of float32 position memory with a PSNR (min over views) of {cap_db} dB at levels {lv}")
    ap = [r["ap"]["psnr_min"] for r in rows if "ap" in r]
    if ap:
        text += f"; AP at the same levels: {_span(ap, lambda v: f'{v:.1f}')} dB"
    return text + "."


def render_html(rep: dict, images: dict | None) -> str:
    """The report page (UTF-8 HTML text) of ``rep`` (``lopcook.report.model.build_report``) and ``images``
    (the evaluation's images of one view, or None: no image section). A function of its inputs only."""
    e = escape
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>lopcook report: {e(rep['container'])}</title><style>{_CSS}</style></head><body>",
           f"<h1>lopcook report: {e(rep['container'])}</h1>",
           f"<p>source <b>{e(rep['source'])}</b>: {rep['parts']} parts, {rep['vertices']:,} vertices, "
           f"{rep['triangles']:,} triangles; levels 1..{rep['available_level']} in the file. Rendered at "
           f"{rep['render']['resolution'][0]}x{rep['render']['resolution'][1]}, {rep['render']['samples']}x MSAA, "
           f"{len(rep['render']['views'])} views on {e(rep['render']['device'])}.</p>",
           "<h2>Accuracy per level (Table 1)</h2>",
           '<table id="levels"><thead><tr><th>level</th><th>AP memory %</th><th>AP PSNR dB min / mean</th>'
           "<th>CAP memory %</th><th>CAP PSNR dB min / mean</th><th>depth-order error px AP / CAP</th>"
           f"<th>16-bit ({rep['baselines']['uniform16']['percent_of_float32']:.1f} %) PSNR dB min / mean</th></tr>"
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
        crop = im.get("crop")
        out.append(f"<h2>Images at level {im['level']} (view {im['view']})</h2>")
        if crop:
            (fw, fh), (x0, y0, x1, y1), sc = crop["frame"], crop["box"], crop["scale"]
            whole = [x0, y0, x1, y1] == [0, 0, fw, fh]
            out.append('<p class="note" id="crop">' + (
                f"Whole {fw}x{fh} frame, shown at 1x." if whole else
                f"Every image is cropped to the same box, columns {x0}..{x1 - 1} and rows {y0}..{y1 - 1} of the "
                f"{fw}x{fh} frame (the object pixels of all renders plus a margin; the rest is background), "
                f"and shown {sc}x enlarged with nearest-neighbour sampling ({crop['size'][0]}x{crop['size'][1]} "
                f"pixels): one rendered pixel is a {sc}x{sc} block.") + "</p>")
        out.append("<div>")
        captions = {"float": "float32", "ap": "AP", "cap": "CAP", "ap_heatmap": "AP error heat map",
                    "cap_heatmap": "CAP error heat map", "levels": "minimum level per vertex (Fig. 7; camera at the frame distance)"}
        if im.get("level_range"):
            lo, hi = im["level_range"]
            captions["levels"] += f", levels {lo} (blue) to {hi} (red), colours as in the histogram"
        for k in IMAGE_KEYS:
            if k in images and images[k] is not None:
                a = apply_crop(images[k], crop if k != "levels" else crop_box({k: images[k]}))
                cropped = crop and crop["scale"] > 1 and k != "levels"
                cap_text = captions.get(k, k) + (f" (crop, {crop['scale']}x)" if cropped else "")
                out.append(f'<figure><img id="img-{k}" alt="{e(captions.get(k, k))}" width="{a.shape[1]}" '
                           f'height="{a.shape[0]}" src="{png_data_uri(a)}"><figcaption>{e(cap_text)}'
                           f"</figcaption></figure>")
        out.append("</div>")
    lods = rep.get("lods")
    if lods and lods.get("parts"):
        out.append(lod_table_html(lods))
    out.append("<h2>Cook</h2>")
    cook, tim = rep.get("cook"), rep.get("cook_timings_s")
    if cook:
        out.append(f'<p class="note" id="recook" data-status="{e(cook["status"])}">Re-cooked from the source with the '
                   f'recorded options to time the stages: <b>{e(cook["status"])}</b>; {e(cook["detail"])}.</p>')
    if tim:
        total = sum(v for k, v in tim.items() if "." not in k)
        out.append('<table id="timings"><tr><th>stage</th><th>seconds</th></tr>' + "".join(
            f"<tr><td>{e(k)}</td><td>{v:.3f}</td></tr>" for k, v in tim.items())
            + f"<tr><td><b>total</b> (stages without a dot)</td><td>{total:.3f}</td></tr></table>")
        out.append(f'<p class="note" id="bought">{e(time_bought(rep, total))}</p>')
    else:
        out.append('<p class="note">cook stage timings: not measured (the source was not re-cooked).</p>')
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
    if rep.get("budget"):
        out.append(budget_html(rep["budget"]))
    out.append(_SCRIPT + "</body></html>")
    return "\n".join(out)


def write_html(report_dict: dict, images: dict | None, path) -> tuple[Path, Path]:
    """Write ``path`` (HTML) and ``path`` with suffix ``.json`` atomically; returns both paths."""
    path = Path(path)
    jpath = path.with_suffix(".json")
    data = report_json_bytes(report_dict)
    page = render_html(report_dict, images).encode("utf-8")
    write_atomic(jpath, data)
    write_atomic(path, page)
    return path, jpath


__all__ = ["budget_html", "table_rows", "lod_table_html", "time_bought", "render_html", "write_html"]
