"""The ``lopcook report`` page: one self-contained HTML file with inline CSS, images as PNG ``data:``
URIs and charts as inline SVG (no JavaScript library, no network; a short inline script only
writes, for headless checks, into ``body``'s data attributes: ``images-ok`` / ``images-total``
(decoded images), ``scroll-width`` / ``inner-width`` (horizontal overflow) and ``text-overlaps``
(pairs of chart texts whose boxes overlap), ``text-clipped`` (chart texts reaching outside their
chart)), written beside its ``report.json``. The histogram's
log scale is a CSS-only toggle (a checkbox).

Sections, in order: the verdict banner and the terms box (``sections``), accuracy per level (Table 1
of Meyer et al. 2011: AP and CAP memory and PSNR, depth-order errors, the uniform 16-bit baseline),
memory vs PSNR chart, minimum-level histogram (linear or log), clusters, level image, images of one
view at every level (float, AP, CAP at native size and enlarged, heat maps with their colour scale,
and a zoom where the error is worst), the worst view, the level and view with the most depth-order
errors, the source's parts, levels of detail and every LOD as selected, cook (re-cook status and stage timings),
warnings (grouped and worded, ``text.warning_groups``), k_f calibration and byte budget when the
container records them. Input: the dict of ``lopcook.report.model.build_report``; the page is a
function of it and the images only.

Cook timings: a container holds none (deterministic bytes), so ``lopcook report`` re-cooks the
source with the recorded options (``lopcook.tune.recook.recook``), times every stage and compares
the bytes with the file (``cook.status``: identical / prefix / differs / not re-cooked).
"""

from __future__ import annotations

from pathlib import Path

from ..atomic import write_atomic
from ..ingest.summary import attribute_labels
from ..verify.metrics import depth_error_mask
from .images import apply_crop, crop_box, depth_overlay
from .model import lod_name, report_json_bytes
from .sections import (CAPTIONS, banner_html, clusters_html, figure, lod_renders_html, native_figure, terms_html,
                       worst_html)
from .svg import attribute_search_svg, budget_svg, calibration_svg, heatmap_scale_svg, histogram_svg, memory_psnr_svg
from .text import escape, fmt_pct, fmt_psnr, term, warning_groups


def budget_lod_name(b: dict, k: int) -> str:
    """A LOD of the byte-budget's candidate chain named as the page names LODs (``model.lod_name``:
    its share of the source's triangles, the chain's LOD 0)."""
    lods = {int(x["lod"]): x for x in b.get("lods") or []}
    if k in lods and 0 in lods:
        return lod_name(k, int(lods[k]["triangles"]), int(lods[0]["triangles"]))
    return f"LOD {k}"


def budget_html(b: dict) -> str:
    """The "Byte budget" section: the definition, the chart (``budget_svg``) and the candidate table.
    The candidates' LODs are those of the fit's own chain (the file holds the chosen one as its LOD 0)."""
    e = escape
    cam, ch = b["camera"], b["chosen"]
    base = b.get("baselines") or {}
    q, s = base.get("quantize_only"), base.get("simplify_only")
    out = [f'<h2>Byte budget</h2><p id="budget-summary">Budget <b>{b["target_bytes"]:,} bytes</b> ({e(b["scope"])}: '
           f'{100 * b.get("fraction_of_float", 0):.1f} % of the float size {b["float_bytes"]:,} B). Chosen: <b>'
           f'{e(budget_lod_name(b, ch["lod"]))} at level {ch["level"]}</b>, {ch["bytes"]:,} bytes, '
           f'{fmt_psnr(ch["psnr_mean"])} dB (the file holds it as its LOD 0). Quantize only: '
           + ("nothing fits" if not q else f'{e(budget_lod_name(b, 0))} at level {q["level"]}, '
                                           f'{fmt_psnr(q["psnr_mean"])} dB')
           + '; simplify only: ' + ("nothing fits" if not s else
                                   f'{e(budget_lod_name(b, s["lod"]))} in float32, {fmt_psnr(s["psnr_mean"])} dB')
           + ".</p>",
           f'<p class="note">Every candidate rendered against the float source from {len(cam["views"])} views at '
           f'{cam["resolution"][0]}x{cam["resolution"][1]}, camera {cam["distance_m"]:.4g} m from the bounding box '
           f'({e(cam["rule"])} distance; level {cam["level"]} there). PSNR of the view-averaged MSE over object '
           f'pixels (Purnomo et al. 2005, Fig. 11). LODs of the fit\'s own chain.</p>', budget_svg(b),
           '<div class="scroll"><table id="budget"><thead><tr><th>LOD</th><th>level</th><th>vertices</th><th>bytes</th>'
           "<th>bits/vertex</th><th>PSNR mean dB</th><th>PSNR min dB</th></tr></thead><tbody>"]
    for c in b["candidates"]:
        chosen = (c["lod"], c["level"]) == (ch["lod"], ch["level"])
        cls = ' class="chosen"' if chosen else ""
        out.append(f'<tr data-lod="{c["lod"]}" data-level="{c["level"]}"{cls}>'
                   f'<td class="name">{e(budget_lod_name(b, c["lod"]))}{" (chosen)" if chosen else ""}</td>'
                   f'<td>{c["level"]}</td><td>{c["vertices"]:,}</td>'
                   f'<td>{c["bytes"]:,}</td><td>{c["bits_per_vertex"]:.1f}</td><td>{fmt_psnr(c["psnr_mean"])}</td>'
                   f'<td>{fmt_psnr(c.get("psnr_min"))}</td></tr>')
    out.append("</tbody></table></div>")
    return "".join(out)


def _num(v, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def attributes_html(a: dict) -> str:
    """The "Vertex attributes" section: bits per component per part, bits per vertex, attribute-space
    errors, and the attribute search's record and curve (``attribute_search_svg``) when it ran."""
    e = escape
    vb = a["vertex_bits"]
    errs = {r["part"]: r for r in (a.get("errors") or [])}
    out = [f'<h2>Vertex attributes</h2><p id="attributes-summary">Bits per vertex at level {a["level"]}: '
           f'<b>{vb["total"]:.2f}</b> (positions\' CAP {vb["positions"]:.2f}, attribute records '
           f'{vb["attributes"]:.2f}).</p>',
           '<div class="scroll"><table id="attributes"><thead><tr><th>part</th><th>vertices</th><th>normal bits</th>'
           "<th>UV bits</th><th>colour bits</th><th>record bits</th><th>normal error deg max / mean</th>"
           "<th>UV error max / mean</th></tr></thead><tbody>"]
    for p in a["parts"]:
        b = p["bits"]
        r = errs.get(p["part"], {})
        nerr = ("-" if r.get("normal_deg_max") is None else
                f'{r["normal_deg_max"]:.3g} / {r["normal_deg_mean"]:.3g}')
        uerr = ("-" if r.get("uv_error_max") is None else
                f'{r["uv_error_max"]:.3g} / {r["uv_error_mean"]:.3g} {e(r["uv_error_unit"])}')
        out.append(f'<tr data-part="{p["part"]}"><td class="name">{e(p["name"] or p["part"])}</td>'
                   f'<td>{p["vertices"]:,}</td><td>{_num(b["normals"], "d")}</td><td>{_num(b["uvs"], "d")}</td>'
                   f'<td>{_num(b["colors"], "d")}</td><td>{_num(p["record_bits"], "d")}</td><td>{nerr}</td>'
                   f"<td>{uerr}</td></tr>")
    out.append('</tbody></table></div><p class="note">Bits per component: normals octahedral (2 components), UVs '
               '(2) over the part\'s range, colours (4 channels). Errors of the decoded LOD 0 against the source: '
               'the angle between normals, the UV difference times the texture\'s size (texels; UV units without '
               'a texture).</p>')
    s = a.get("search")
    if s:
        goal = f'{s["goal"]:g} bits per vertex' if s["mode"] == "budget" else f'{s["goal"]:g} dB'
        out.append(f'<p id="attribute-search">Attribute search ({e(s["mode"])}: {e(goal)}): {len(s["probes"])} '
                   f'probes on {s["harness"]["views"]} views at {s["harness"]["resolution"][0]}x'
                   f'{s["harness"]["resolution"][1]}; chosen {s["bits_per_vertex"]:.2f} bits per vertex (the default '
                   f'bits: {s["start_bits_per_vertex"]:.2f}), positions\' k_f scale 2^{s["choice"]["log2_kf_scale"]:g}, '
                   f'reached: {e(s["reached"])}.</p>')
        svg = attribute_search_svg(dict(s, level=a["level"]))
        if svg:
            out.append(svg)
    else:
        out.append('<p class="note" id="attribute-search">No attribute search (cook --vertex-bits N or '
                   '--target-psnr DB runs one): the bound-based default bits.</p>')
    return "".join(out)


_CSS = """*{box-sizing:border-box}
body{font-family:system-ui,sans-serif;margin:0 auto;padding:1em 2em;max-width:1400px;color:#222;
overflow-wrap:anywhere;line-height:1.35}
@media (max-width:700px){body{padding:0.5em 0.6em}h1{font-size:1.3em}h2{font-size:1.15em}
.imgs{grid-template-columns:repeat(2,minmax(0,1fr))!important}}
.scroll{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;margin:0.6em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right;
overflow-wrap:normal}td{white-space:nowrap}
td.name{text-align:left;white-space:nowrap}th{background:#f4f4f4}
img{max-width:100%;height:auto}svg.chart{display:block;max-width:100%;height:auto;border:1px solid #eee;margin:0.5em 0}
.imgs{display:grid;grid-template-columns:repeat(auto-fill,minmax(min(100%,220px),1fr));gap:0.6em;margin:0.4em 0}
figure{margin:0}figure img{width:100%;image-rendering:pixelated;border:1px solid #ccc;background:#fff}
figcaption{font-size:0.85em;color:#555}.warn{color:#a40}.note{font-size:0.85em;color:#555}
.hist .hist-log{display:none}#hist-log:checked~.hist-linear{display:none}#hist-log:checked~.hist-log{display:block}
.warn-group h3{margin:0.8em 0 0.2em;font-size:1em}.warn-group p{margin:0.2em 0}
section.level{border-top:1px solid #ddd;margin-top:0.8em}
figure.native img{width:auto;max-width:100%;image-rendering:auto}
.verdict{border:2px solid;border-radius:4px;padding:0.3em 0.9em;margin:0.6em 0}.verdict p{margin:0.3em 0}
.verdict.pass{border-color:#2a7a2a;background:#eef8ee}.verdict.fail{border-color:#b00020;background:#fdecee}
.verdict .result{font-size:1.3em}.verdict.pass .result{color:#2a7a2a}.verdict.fail .result{color:#b00020}
abbr[title]{text-decoration:underline dotted;cursor:help}
#terms{font-size:0.9em;margin:0.5em 0}#terms dl{display:grid;grid-template-columns:max-content 1fr;gap:0.15em 0.8em;
margin:0.4em 0}#terms dt{font-weight:bold}#terms dd{margin:0}
@media (max-width:700px){#terms dl{grid-template-columns:1fr}}"""

_SCRIPT = """<script>window.addEventListener('load',function(){var n=0,b=document.body.dataset;
document.querySelectorAll('img').forEach(function(i){if(i.complete&&i.naturalWidth>0)n++;});
b.imagesOk=String(n);b.imagesTotal=String(document.images.length);
b.scrollWidth=String(document.documentElement.scrollWidth);b.innerWidth=String(window.innerWidth);
var o=0,x=0;document.querySelectorAll('svg.chart').forEach(function(s){var q=s.getBoundingClientRect();
var r=[].map.call(s.querySelectorAll('text'),function(t){return t.getBoundingClientRect();}).filter(function(r){
if(r.width>0&&(r.left<q.left-0.5||r.right>q.right+0.5||r.top<q.top-0.5||r.bottom>q.bottom+0.5))x++;return r.width>0;});
for(var i=0;i<r.length;i++)for(var j=i+1;j<r.length;j++){var a=r[i],c=r[j];
if(a.left<c.right-0.5&&c.left<a.right-0.5&&a.top<c.bottom-0.5&&c.top<a.bottom-0.5)o++;}});
b.textOverlaps=String(o);b.textClipped=String(x);});
</script>"""

#: image kinds shown at every level, in order
LEVEL_KINDS = ("float", "ap", "cap", "ap_heatmap", "cap_heatmap")
#: at most this many names are listed openly under a warning; more go in a collapsed list
OPEN_ITEMS = 6


def _box_text(box) -> str:
    x0, y0, x1, y1 = box
    return f"columns {x0}..{x1 - 1} and rows {y0}..{y1 - 1}"


def crop_note(crop: dict) -> str:
    """The sentence saying how a level's images are cropped and enlarged."""
    (fw, fh), box, sc = crop["frame"], crop["box"], crop["scale"]
    if list(box) == [0, 0, fw, fh] and sc == 1:
        return f"Whole {fw}x{fh} frame, shown at 1x."
    return (f"Cropped to {_box_text(box)} of the {fw}x{fh} frame (the object pixels of all renders plus a margin) "
            f"and shown {sc}x enlarged with nearest-neighbour sampling ({crop['size'][0]}x{crop['size'][1]} pixels): "
            f"one rendered pixel is a {sc}x{sc} block.")


def view_note(rep: dict) -> str:
    """Why the shown view was chosen (``lopcook.report.render.choose_view``), with its angles."""
    im = rep["images"]
    i = per_view_index(rep, im["view"])
    angles = im.get("view_angles")
    if i is None or not angles:
        return f"View {im['view']}."
    elev, az = angles[i]
    parts = " after the most parts seen" if im.get("view_parts") else ""
    if not 0.0 <= elev <= 45.0:
        return (f"View {im['view']} (eye {elev:.0f} degrees above the horizon): no front or three-quarter view was "
                f"rendered (see --views); of the rendered views, the one covering the most pixels{parts}.")
    return (f"View {im['view']} (eye {elev:.0f} degrees above the horizon, {abs(az):.0f} degrees from the front): "
            f"a view a person recognises, chosen among the front and three-quarter views (eye at most 45 degrees "
            f"above the horizon, never below) as the one covering the most pixels at the coarsest level{parts}.")


def level_images_html(rep: dict, images: dict) -> str:
    """The "Images at every level" section: per level, the float, AP, CAP renders and both heat maps
    (one crop per level, ``images.per_level[i].crop``), then the zoom on the window where the error
    is worst (``zoom``); the heat maps' colour scale once above."""
    e = escape
    im = rep["images"]
    per = images.get("per_level") or [images]
    rows = {r["level"]: r for r in rep["levels"]}
    out = [f'<h2>Images at every level (view {im["view"]})</h2>',
           f'<p class="note" id="view-choice">{e(view_note(rep))} Every level shows the same view, its camera at the '
           f"distance where the half-pixel criterion selects that level; the worst view is shown "
           '<a href="#worst">below</a>. Heat maps: the largest channel difference per pixel against float32. '
           "Small objects are shown at their native size (one rendered pixel to one screen pixel) beside the "
           "enlarged crop.</p>",
           '<div class="heat-legend">' + heatmap_scale_svg(im.get("heatmap_vmax", 0.25)) + "</div>"]
    for rec, imgs in zip(im.get("per_level") or [], per):
        lv, crop, zoom = rec["level"], rec["crop"], rec["zoom"]
        r = rows.get(lv, {})
        cap = r.get("cap") or {}
        head = f"Level {lv}"
        if r:
            head += f": camera {r['camera_distance_m']:.4g} m"
        vi = per_view_index(rep, im["view"])
        if cap.get("psnr_views") and vi is not None:
            head += f", CAP PSNR {fmt_psnr(cap['psnr_views'][vi])} dB in this view"
        out.append(f'<section class="level" id="level-{lv}" data-level="{lv}"><h3>{e(head)}</h3>'
                   f'<p class="note crop">{e(crop_note(crop))}</p><div class="imgs">')
        if crop["scale"] > 1 and imgs.get("cap") is not None:
            out.append(native_figure(f"img-L{lv}-native", imgs["cap"], crop, "CAP, native size"))
        for k in LEVEL_KINDS:
            if imgs.get(k) is not None:
                out.append(figure(f"img-L{lv}-{k}", apply_crop(imgs[k], crop), CAPTIONS[k]))
        out.append("</div>")
        if zoom:
            v = zoom["variant"]
            side = zoom["box"][2] - zoom["box"][0]
            out.append(f'<p class="note zoom" data-level="{lv}">Zoom where the {v.upper()} error is worst: '
                       f"{_box_text(zoom['box'])} ({side}x{side} frame pixels, shown {zoom['scale']}x), "
                       f"{100 * zoom['share']:.0f} % of this view's {v.upper()} squared error.</p><div class=\"imgs\">")
            for k in ("float", "ap", "cap", f"{v}_heatmap"):
                if imgs.get(k) is not None:
                    out.append(figure(f"img-L{lv}-zoom-{k}", apply_crop(imgs[k], zoom),
                                       f"{CAPTIONS[k]}, zoom {zoom['scale']}x"))
            out.append("</div>")
        else:
            out.append('<p class="note zoom">AP and CAP match the float render exactly in this view: no zoom.</p>')
        out.append("</section>")
    return "".join(out)


def per_view_index(rep: dict, view: int):
    """Index of ``view`` among the rendered views, or None."""
    views = list(rep["render"]["views"])
    return views.index(view) if view in views else None


def depth_html(rep: dict, images: dict) -> str:
    """The "Depth-order errors" section: the level and view with the most depth-order error pixels,
    the float render, the variant's render and the error pixels in magenta over the float render."""
    e = escape
    d = (rep.get("images") or {}).get("depth")
    total = rep.get("depth_order_errors_total") or {}
    out = ["<h2>Depth-order errors</h2>"]
    if not d or not images.get("depth"):
        out.append(f'<p id="depth" class="note">No depth-order errors at any rendered level and view '
                   f'(AP {total.get("ap", 0)}, CAP {total.get("cap", 0)} pixels).</p>')
        return "".join(out)
    im = images["depth"]["images"]
    v = d["variant"]
    mask = depth_error_mask(im["float_ids"], im[f"{v}_ids"])
    crop = d["crop"]
    out.append(f'<p id="depth" data-level="{d["level"]}" data-view="{d["view"]}">Most depth-order errors: '
               f'<b>level {d["level"]}</b>, view {d["view"]}, {v.upper()}: {d["errors"]:,} pixels show another part '
               f'than the float render inside a part (magenta below). Over all levels and views: AP '
               f'{total.get("ap", 0):,}, CAP {total.get("cap", 0):,} pixels.</p>'
               f'<p class="note">{e(crop_note(crop))}</p><div class="imgs">')
    out.append(figure("img-depth-float", apply_crop(im["float"], crop), "float32"))
    out.append(figure(f"img-depth-{v}", apply_crop(im[v], crop), CAPTIONS[v]))
    out.append(figure("img-depth-mask", apply_crop(depth_overlay(im["float"], mask), crop),
                       f"depth-order error pixels of {v.upper()} (magenta)"))
    out.append("</div>")
    return "".join(out)


def parts_html(rep: dict) -> str:
    """The "Parts" table of the source (``scene_parts``): vertices, triangles and attributes, N* for
    normals lopcook computed; the N* legend only when some part has N*."""
    e = escape
    parts = rep.get("scene_parts") or []
    if not parts:
        return ""
    rows = []
    for q in parts:
        attrs = attribute_labels(q, texture="texture {}")
        rows.append(f'<tr><td class="name">{e(q["name"])}</td><td>{q["vertices"]:,}</td><td>{q["triangles"]:,}</td>'
                    f'<td class="name">{e(" ".join(attrs) or "-")}</td></tr>')
    table = ('<div class="scroll"><table id="parts"><thead><tr><th>part</th><th>vertices</th><th>triangles</th>'
             "<th>attributes</th></tr></thead><tbody>" + "".join(rows) + "</tbody></table></div>")
    n = len(parts)
    out = [f"<h2>Parts</h2><p>{n:,} part{'' if n == 1 else 's'} in the source.</p>"]
    out.append(table if n <= 12 else f"<details><summary>show the {n:,} parts</summary>{table}</details>")
    keys = ["N = normals from the source"]
    if any(q["normals"] == "computed" for q in parts):
        keys.append("N* = normals computed by lopcook (area-weighted, split at creases)")
    keys += ["UV = texture coordinates", "C = vertex colours"]
    if any(q.get("double_sided") for q in parts):
        keys.append("2S = double-sided: both sides drawn")
    keys.append("the renders cull the back faces of single-sided parts, as glTF and USD renderers do")
    out.append(f'<p class="note" id="parts-legend">{e("; ".join(keys))}.</p>')
    return "".join(out)


def warnings_html(w: dict) -> str:
    """The "Warnings" section: ``text.warning_groups`` as headed paragraphs, long lists collapsed."""
    e = escape
    out = ["<h2>Warnings</h2>"]
    if not w["available"]:
        out.append('<p class="note">The analysis was not re-run (--no-analyse): only the importer\'s warnings are '
                   "shown.</p>")
    groups = warning_groups(w)
    if not groups:
        out.append('<p id="warnings">none</p>')
        return "".join(out)
    out.append('<div id="warnings">')
    for g in groups:
        out.append(f'<div class="warn-group" id="warn-{g["id"]}"><h3>{e(g["title"])}</h3>'
                   f'<p class="warn">{e(g["summary"])}</p>')
        items = g["items"]
        if items:
            ul = "<ul>" + "".join(f"<li>{e(x)}</li>" for x in items) + "</ul>"
            out.append(ul if len(items) <= OPEN_ITEMS else f"<details><summary>show all {len(items):,}</summary>{ul}"
                       "</details>")
        out.append("</div>")
    out.append("</div>")
    return "".join(out)


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
    out = [f"<h2>Levels of detail</h2><p class=\"note\">{how}. {term('LOD', 'LODs')} are named by their share "
           "of the source's triangles, the same way in this table, the notes and the renders. Error: symmetric "
           f"{term('Hausdorff error', 'Hausdorff distance')} to LOD 0 as "
           "recorded in the container. Distances: the camera range over which lopcook.selection picks the LOD under "
           "the container's viewing. Bytes: index + attribute sections, the LOD's mandatory bits and its bits in "
           "the refinement planes.</p>",
           '<div class="scroll"><table id="lods"><thead><tr><th>part</th><th>LOD</th><th>triangles</th>'
           '<th>vertices</th>'
           "<th>Hausdorff error m</th><th>selected from m</th><th>to m</th><th>bytes</th></tr></thead><tbody>"]
    for part in lods["parts"]:
        for r in part["lods"]:
            out.append(f'<tr data-part="{e(part["part"])}" data-lod="{r["lod"]}"><td>{e(part["part"])}</td>'
                       f"<td class=\"name\">{e(r.get('name') or r['lod'])}</td><td>{r['triangles']:,}</td>"
                       f"<td>{r['vertices']:,}</td>"
                       f"<td>{r['geometric_error_m']:.4g}</td><td>{_dist(r['min_distance_m'])}</td>"
                       f"<td>{_dist(r['max_distance_m'])}</td><td>{r['bytes']:,}</td></tr>")
    out.append("</tbody></table></div>")
    sv = lods.get("savings")
    if sv:
        out.append(f'<p class="note">Not written (no view needs them): {sv["lods_dropped"]} LODs, planes '
                   f'{e(sv["planes_dropped"] or "none")}; {sv["bytes_saved"]:,} bytes saved.</p>')
    one = len(lods["parts"]) == 1  # one part: its name is the table's, not repeated on every note
    notes = [n if one else f"{p['part']}: {n}" for p in lods["parts"] for n in p.get("notes") or []]
    if notes:
        ul = '<ul id="lod-notes">' + "".join(f'<li class="note">{e(n)}</li>' for n in notes) + "</ul>"
        out.append(ul if len(notes) <= OPEN_ITEMS else
                   f"<details><summary>the LOD chain's {len(notes):,} notes</summary>{ul}</details>")
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


def _source_triangles(rep: dict) -> int:
    """The source's triangles (every part once), or the file's when the parts are not recorded."""
    parts = rep.get("scene_parts") or []
    return sum(int(p["triangles"]) for p in parts) if parts else int(rep["triangles"])


def _lod_count(rep: dict) -> str:
    """" and 10 LODs (138,881 triangles in all)" for a file with LODs, else ""."""
    names = (rep.get("lods") or {}).get("names") or []
    if len(names) <= 1:
        return ""
    return f" and {len(names)} LODs ({rep['triangles']:,} triangles in all)"


def _head_html(rep: dict) -> list[str]:
    """The page's start: the document head, the title, the verdict banner, the source line, the
    terms box and the accuracy table (Table 1)."""
    e = escape
    nparts = rep["parts"]
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           f"<title>lopcook report: {e(rep['container'])}</title><style>{_CSS}</style></head><body>",
           f"<h1>lopcook report: {e(rep['container'])}</h1>", banner_html(rep),
           f"<p>source <b>{e(rep['source'])}</b>: {nparts:,} part{'' if nparts == 1 else 's'}, {rep['vertices']:,} "
           f"vertices, {_source_triangles(rep):,} triangles; the file holds levels 1..{rep['available_level']}"
           f"{_lod_count(rep)}. Rendered at "
           f"{rep['render']['resolution'][0]}x{rep['render']['resolution'][1]}, {rep['render']['samples']}x MSAA, "
           f"{len(rep['render']['views'])} views on {e(rep['render']['device'])}.</p>",
           terms_html(),
           "<h2>Accuracy per level (Table 1)</h2>",
           f'<div class="scroll"><table id="levels"><thead><tr><th>{term("level")}</th><th>{term("AP")} memory %</th>'
           f"<th>AP {term('PSNR')} dB min / mean</th><th>{term('CAP')} memory %</th><th>CAP PSNR dB min / mean</th>"
           f"<th>{term('depth-order error')} px AP / CAP</th>"
           f"<th>16-bit ({rep['baselines']['uniform16']['percent_of_float32']:.1f} %) PSNR dB min / mean</th></tr>"
           "</thead><tbody>"]
    for row in table_rows(rep):
        out.append(f'<tr data-level="{e(row[0])}">' + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>")
    out.append(f'</tbody></table></div><p class="note">Memory: GPU-resident position bytes vs float32 '
               f'({rep["float32_bytes"]:,} B). PSNR over object pixels against the float render; inf = identical.</p>')
    return out


def render_html(rep: dict, images: dict | None) -> str:
    """The report page (UTF-8 HTML text) of ``rep`` (``lopcook.report.model.build_report``) and ``images``
    (``render_for_report``'s images: every level's, the depth-order view's and the level image, or
    None: no image sections). A function of its inputs only. The page fits any width from a phone's
    up: tables scroll sideways inside their box, images and charts shrink to the column."""
    e = escape
    out = _head_html(rep)
    shared = [r for r in rep.get("memory") or [] if "cap_bytes_all_copies" in r and 6 <= r["level"] <= 11]
    if shared:  # cook --instances: each distinct mesh stored once
        lo, hi = shared[0], shared[-1]
        out.append(f'<p class="note" id="copies">Copies stored once: GPU-resident CAP position bytes at levels '
                   f'{lo["level"]}-{hi["level"]} count each distinct mesh once, {lo["cap_bytes"]:,}-{hi["cap_bytes"]:,} B '
                   f'against {lo["cap_bytes_all_copies"]:,}-{hi["cap_bytes_all_copies"]:,} B with every copy stored: '
                   f'{lo["cap_saved_by_sharing_bytes"]:,}-{hi["cap_saved_by_sharing_bytes"]:,} B saved '
                   f'({100.0 * lo["cap_saved_by_sharing_bytes"] / max(lo["cap_bytes_all_copies"], 1):.1f} %).</p>')
    out.append("<h2>Memory vs PSNR</h2>" + memory_psnr_svg(rep))
    u = rep["baselines"]["uniform16"]
    out.append(f'<p class="note">Labels: the level of each point (points drawn on top of each other share one label, '
               f'e.g. 6-8). float32 (100 %, PSNR inf) is drawn in the top band. Uniform 16-bit quantization '
               f'({u["bytes_per_vertex"]} B/vertex = {u["percent_of_float32"]:.1f} %): {e(u["note"])}; max position '
               f'error {u["max_position_error_m"]:.3g} m.</p>')
    out.append('<h2>Minimum-level histogram</h2><div class="hist"><input type="checkbox" id="hist-log">'
               '<label for="hist-log"> log scale</label><div class="hist-linear">' + histogram_svg(rep["histogram"])
               + '</div><div class="hist-log">' + histogram_svg(rep["histogram"], log=True) + "</div></div>")
    out.extend(clusters_html(rep))
    im = rep.get("images")
    if images and im:
        if images.get("levels") is not None:
            cap_text = "minimum level per vertex (Fig. 7; camera at the frame distance)"
            if im.get("level_range"):
                lo, hi = im["level_range"]
                cap_text += f", levels {lo} (blue) to {hi} (red), colours as in the histogram"
            a = apply_crop(images["levels"], crop_box({"levels": images["levels"]}))
            out.append('<div class="imgs">' + figure("img-levels", a, cap_text) + "</div>")
        out.append(level_images_html(rep, images))
        out.append(worst_html(rep, images))
        out.append(depth_html(rep, images))
    out.append(parts_html(rep))
    lods = rep.get("lods")
    if lods and lods.get("parts"):
        out.append(lod_table_html(lods))
    if images and im:
        out.append(lod_renders_html(rep, images))
    out.append("<h2>Cook</h2>")
    cook, tim = rep.get("cook"), rep.get("cook_timings_s")
    if cook:
        out.append(f'<p class="note" id="recook" data-status="{e(cook["status"])}">Re-cooked from the source with the '
                   f'recorded options to time the stages: <b>{e(cook["status"])}</b>; {e(cook["detail"])}.</p>')
    if tim:
        total = sum(v for k, v in tim.items() if "." not in k)
        out.append('<div class="scroll"><table id="timings"><tr><th>stage</th><th>seconds</th></tr>' + "".join(
            f"<tr><td>{e(k)}</td><td>{v:.3f}</td></tr>" for k, v in tim.items())
            + f"<tr><td><b>total</b> (stages without a dot)</td><td>{total:.3f}</td></tr></table></div>")
        out.append(f'<p class="note" id="bought">{e(time_bought(rep, total))}</p>')
    else:
        out.append('<p class="note">cook stage timings: not measured (the source was not re-cooked).</p>')
    out.append(warnings_html(rep["warnings"]))
    cal = rep.get("calibration")
    if cal:
        svg = calibration_svg(cal)
        out.append(f"<h2>{term('k_f')} calibration</h2><p>target {e(cal.get('target_psnr'))} dB "
                   f"({e(cal.get('statistic'))}), reached: {e(cal.get('reached'))}, k_f {e(cal.get('kf'))}</p>"
                   + (svg or ""))
    if rep.get("budget"):
        out.append(budget_html(rep["budget"]))
    if rep.get("attributes"):
        out.append(attributes_html(rep["attributes"]))
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


__all__ = ["budget_html", "table_rows", "crop_note", "level_images_html", "per_view_index", "depth_html", "parts_html",
           "warnings_html", "lod_table_html", "time_bought", "render_html", "write_html"]
