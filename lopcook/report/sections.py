"""Sections of the report page that answer "does it pass?" and show what a person sees: the verdict
banner, the terms box, the worst view, every LOD at its selection distance, and the Clusters
table with identical rows grouped. Input: the dict of ``lopcook.report.model.build_report`` and the
images of ``lopcook.report.render.render_for_report``; every function returns HTML text.

Images: a crop enlarged with nearest-neighbour sampling (``images.apply_crop``) is shown beside
the same crop at its native size (one rendered pixel to one CSS pixel, ``native_figure``), so a
small object is seen both at the size it has on screen and large enough to judge.
"""

from __future__ import annotations

from .images import apply_crop, png_data_uri
from .text import TERMS, escape, fmt_psnr, term

#: captions of the image kinds
CAPTIONS = {"float": "float32", "ap": "AP", "cap": "CAP", "ap_heatmap": "AP error heat map",
            "cap_heatmap": "CAP error heat map"}


def figure(img_id: str, a, caption: str, alt: str | None = None) -> str:
    """One ``<figure>`` with ``a`` (an image array) as a PNG ``data:`` URI, scaled to its column."""
    e = escape
    return (f'<figure><img id="{e(img_id)}" alt="{e(alt or caption)}" width="{a.shape[1]}" height="{a.shape[0]}" '
            f'src="{png_data_uri(a)}"><figcaption>{e(caption)}</figcaption></figure>')


def native_figure(img_id: str, a, crop: dict, caption: str) -> str:
    """The crop ``crop["box"]`` of the frame-sized image ``a`` at its native size (scale 1: one
    rendered pixel is one CSS pixel, never stretched to the column), class ``native``."""
    e = escape
    x0, y0, x1, y1 = crop["box"]
    b = a[y0:y1, x0:x1]
    return (f'<figure class="native"><img id="{e(img_id)}" alt="{e(caption)}" width="{b.shape[1]}" '
            f'height="{b.shape[0]}" src="{png_data_uri(b)}"><figcaption>{e(caption)}</figcaption></figure>')


def banner_html(rep: dict) -> str:
    """The verdict banner at the top of the page (``report.json`` ``verdict``): PASS or FAIL against
    ``--min-psnr``, the worst level, view and part with its PSNR and the threshold, and which
    levels were rendered."""
    v = rep["verdict"]
    w = v["worst"]
    cls = "pass" if v["result"] == "PASS" else "fail"
    thr = f'{v["min_psnr"]:g} dB'
    if v["result"] == "PASS":
        what = f"every rendered {term('level')} and {term('view')} reaches {thr} {term('CAP')} {term('PSNR')}."
    else:
        lv = ", ".join(str(b) for b in v["failing_levels"])
        total = sum(len((r.get("cap") or {}).get("psnr_views") or []) for r in rep["levels"])
        levels = term("level", "levels" if len(v["failing_levels"]) > 1 else "level")
        what = (f'{v["failing_views"]:,} of {total:,} rendered {term("view", "views")} are under {thr} '
                f'{term("CAP")} {term("PSNR")}, at {levels} {lv}.')
    if w is None:
        worst = " Every CAP render equals the float32 render."
    else:
        part = w.get("part")
        where = "" if not part else (f', part <b>{escape(part["name"])}</b> ({100 * part["share"]:.0f} % of that '
                                     "view's error)")
        cmp = "&ge;" if w["psnr"] >= v["min_psnr"] else "&lt;"
        worst = (f' Worst: <b>{w["psnr"]:.1f} dB</b> {cmp} {thr} at <a href="#worst">level {w["level"]}, '
                 f'view {w["view"]}</a>{where}.')
    levels = [r["level"] for r in rep["levels"]]
    span = f"{levels[0]}-{levels[-1]}" if levels == list(range(levels[0], levels[-1] + 1)) else \
        ", ".join(map(str, levels))
    note = (f'Levels {span} rendered from {len(rep["render"]["views"])} views at {rep["render"]["resolution"][0]}x'
            f'{rep["render"]["resolution"][1]}; the file holds levels up to {rep["available_level"]}.')
    return (f'<div id="verdict" class="verdict {cls}" data-result="{v["result"]}"><p><b class="result">'
            f'{v["result"]}</b>: {what}{worst}</p><p class="note">{escape(note)} Threshold: lopcook report '
            f'--min-psnr (default 40 dB); the exit code is 1 on FAIL.</p></div>')


def terms_html() -> str:
    """The "Terms" box: every term of ``TERMS`` with its explanation (the same text as the
    tooltips of its first uses)."""
    items = "".join(f'<dt>{escape(k)}</dt><dd>{escape(v)}</dd>' for k, v in TERMS.items())
    return f'<details id="terms" open><summary>Terms</summary><dl>{items}</dl></details>'


def worst_html(rep: dict, images: dict) -> str:
    """The "Worst view" section: the (level, view) with the lowest CAP PSNR (``images.worst``), its
    float32, AP and CAP renders and CAP heat map, CAP at native size, and the zoom where its error is
    worst; a note instead when it is the view shown at every level, or nothing is worse than identical."""
    im = rep.get("images") or {}
    w, wi = im.get("worst"), images.get("worst")
    out = ['<h2 id="worst">Worst view</h2>']
    if not w or not wi:
        out.append('<p class="note">Every CAP render equals the float32 render: no worst view.</p>')
        return "".join(out)
    part = w.get("part")
    where = "" if not part else f'; part {escape(part["name"])} holds {100 * part["share"]:.0f} % of its squared error'
    angles = im.get("view_angles") or []
    views = list(rep["render"]["views"])
    seen = ""
    if w["view"] in views and views.index(w["view"]) < len(angles):
        elev = angles[views.index(w["view"])][0]
        seen = f' (eye {abs(elev):.0f} degrees {"above" if elev >= 0 else "below"} the horizon)'
    out.append(f'<p id="worst-view" data-level="{w["level"]}" data-view="{w["view"]}">The lowest {term("CAP")} '
               f'{term("PSNR")} of all rendered levels and views: <b>{w["psnr"]:.1f} dB</b> at level {w["level"]}, '
               f'view {w["view"]}{escape(seen)}{where}.</p>')
    if w["view"] == im.get("view"):
        out.append(f'<p class="note">It is the view shown at every level: see <a href="#level-{w["level"]}">level '
                   f'{w["level"]}</a> below.</p>')
        return "".join(out)
    imgs, crop = wi["images"], w["crop"]
    out.append('<div class="imgs">')
    if crop["scale"] > 1:
        out.append(native_figure("img-worst-native", imgs["cap"], crop, "CAP, native size"))
    for k in ("float", "ap", "cap", "cap_heatmap"):
        if imgs.get(k) is not None:
            out.append(figure(f"img-worst-{k}", apply_crop(imgs[k], crop), f"{CAPTIONS[k]}, {crop['scale']}x"))
    out.append("</div>")
    z = w.get("zoom")
    if z:
        out.append(f'<p class="note">Zoom where the {z["variant"].upper()} error is worst ({z["scale"]}x, '
                   f'{100 * z["share"]:.0f} % of this view\'s error).</p><div class="imgs">')
        for k in ("float", "cap", f'{z["variant"]}_heatmap'):
            if imgs.get(k) is not None:
                out.append(figure(f"img-worst-zoom-{k}", apply_crop(imgs[k], z), f"{CAPTIONS[k]}, zoom {z['scale']}x"))
        out.append("</div>")
    return "".join(out)


def _metres(x: float) -> str:
    return f"{x * 1000:.3g} mm" if 0 < x < 0.1 else f"{x:.3g} m"


def lod_renders_html(rep: dict, images: dict) -> str:
    """The "LODs as selected" section: every LOD of the file rendered at the distance where it is
    first selected (LOD 0 where the object fills the frame), CAP at native size and enlarged beside
    the float32 source at the same distance, with its triangles, recorded error, level and PSNR."""
    recs = (rep.get("images") or {}).get("lods") or []
    shots = images.get("lods") or []
    if not recs:
        return ""
    vp = rep["render"].get("viewing") or {}
    out = [f'<h2 id="lod-renders">{term("LOD", "LODs")} as selected</h2><p class="note">Each LOD rendered from view '
           f'{rep["images"]["view"]} at the camera distance where it is first selected (the container\'s '
           "selection distance, scaled by the render's height over the container's viewport height so that the "
           "object covers the pixels it covers there); LOD 0 where the object fills the frame, or just short of "
           "where LOD 1 takes over when that is nearer. CAP at the "
           f"{term('per-buffer level')} selected there, against the float32 source (LOD 0) at the same distance: "
           "this PSNR counts the simplification as well as the precision (the verdict judges LOD 0's precision). "
           f"Error: the recorded {term('Hausdorff error')}.</p>"]
    for r, s in zip(recs, shots):
        name = escape(r["name"])
        if r["crop"] is None:
            out.append(f'<section class="lod" data-lod="{r["lod"]}"><h3>{name}</h3><p class="note">'
                       "No camera distance selects it: not rendered.</p></section>")
            continue
        sel = (f'selected from {r["selection_distance_m"]:.4g} m' if r["selection_distance_m"] is not None
               else "selected from 0 m")
        head = (f'{r["name"]}: {r["triangles"]:,} triangles, error {_metres(r["geometric_error_m"])}, {sel}; '
                f'level {r["level"]}, PSNR {fmt_psnr(r["psnr"])} dB, {r["object_pixels"]:,} object pixels')
        crop, imgs = r["crop"], s["images"]
        out.append(f'<section class="lod" data-lod="{r["lod"]}"><h3>{escape(head)}</h3><div class="imgs">')
        if crop["scale"] > 1:
            out.append(native_figure(f"img-lod{r['lod']}-native", imgs["cap"], crop,
                                     f"LOD {r['lod']} CAP, native size"))
        out.append(figure(f"img-lod{r['lod']}-cap", apply_crop(imgs["cap"], crop),
                          f"LOD {r['lod']} CAP, {crop['scale']}x"))
        out.append(figure(f"img-lod{r['lod']}-float", apply_crop(imgs["float"], crop),
                          f"float32 source, {crop['scale']}x"))
        out.append("</div></section>")
    if vp.get("viewport"):
        w, h = rep["render"]["resolution"]
        out.append(f'<p class="note">Render viewport {w}x{h}, field of view {vp.get("fov_y_deg", 60):g} degrees.</p>')
    return "".join(out)


def group_rows(rows: list[dict], keys: tuple) -> list[tuple[int, int, dict]]:
    """Consecutive ``rows`` (each with ``level``) whose values under ``keys`` are equal, as (first
    level, last level, the first row of the run)."""
    out: list = []
    for r in rows:
        if out and all(out[-1][2][k] == r[k] for k in keys) and r["level"] == out[-1][1] + 1:
            out[-1] = (out[-1][0], r["level"], out[-1][2])
        else:
            out.append((r["level"], r["level"], r))
    return out


def clusters_html(rep: dict) -> list[str]:
    """Clustered buffers (cook --clusters N): memory per level clustered (P, records, ClusterId)
    against the same vertices unclustered, identical consecutive levels as one row with their count,
    and the anchors' k (only the k that occur); [] when unclustered."""
    cs = rep.get("clusters")
    if not cs:
        return []
    e = escape
    rows = [r for r in rep.get("memory") or [] if "unclustered_cap_bytes" in r and r["level"] <= rep["available_level"]]
    out = [f"<h2>Clusters</h2><p>{cs['clusters']:,} clusters of N = {e('/'.join(str(v) for v in cs['cluster_size']))} "
           f"vertices in {cs['buffers']:,} buffer{'' if cs['buffers'] == 1 else 's'}; the clustered memory counts P, "
           f"{cs['record_bytes']:,} B of cluster records and 128 B of ClusterId per buffer. Levels with the same "
           "bytes share a row.</p>",
           '<div class="scroll"><table id="clusters"><thead><tr><th>levels</th><th>clustered B</th><th>%</th>'
           "<th>unclustered B</th><th>%</th></tr></thead><tbody>"]
    for lo, hi, r in group_rows(rows, ("cap_bytes", "unclustered_cap_bytes")):
        lv = str(lo) if lo == hi else f"{lo}-{hi} ({hi - lo + 1} levels)"
        out.append(f'<tr data-levels="{lo}-{hi}"><td>{lv}</td><td>{r["cap_bytes"]:,}</td>'
                   f'<td>{r["cap_percent"]:.1f}</td><td>{r["unclustered_cap_bytes"]:,}</td>'
                   f'<td>{r["unclustered_cap_percent"]:.1f}</td></tr>')
    hist = cs["k_histogram"]
    out.append("</tbody></table></div><p>Anchor bits k per cluster component (k: count; k not listed: none): "
               + e(" ".join(f"{k}:{v}" for k, v in enumerate(hist) if v)) + "</p>")
    return out


__all__ = ["CAPTIONS", "figure", "native_figure", "banner_html", "terms_html", "worst_html", "lod_renders_html",
           "group_rows", "clusters_html"]
