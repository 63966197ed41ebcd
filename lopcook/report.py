"""``lopcook report``: one self-contained HTML page (plus ``report.json``) for a cooked container.

``build_report`` turns a render evaluation (``lopcook.verify.render.evaluate``), the container
summary (``lopcook.emit.summary.describe_container``) and, optionally, a re-run analysis's warnings
into a JSON-ready dict (plain Python numbers only, file names without directories, no timestamps;
the only run-dependent values are under ``seconds``). ``write_html`` renders it as one HTML file
with inline CSS, images as PNG ``data:`` URIs and charts as inline SVG (no JavaScript library, no
network; a five-line inline script only counts decoded images into ``body[data-images-ok]`` for
headless checks).

Uniform 16-bit quantization baseline (KHR_mesh_quantization: normalized SHORT over each part's
bounding cube, VEC3 padded to 8 bytes per vertex = 66.7 % of float32; ``lopcook.verify.baselines``):
**rendered** with the same cameras as AP and CAP, one PSNR row per level, drawn in the memory vs
PSNR chart and given as the last column of the table.

Minimum levels (paper Fig. 7): the source coloured by each vertex's minimum level, rendered from
the other images' view at the distance where the object fills the frame (image kind ``levels``,
cropped on its own); the histogram bars use the same colours, so the histogram is its legend.

Cook timings: a container holds none (deterministic bytes), so ``lopcook report`` re-cooks the
source with the recorded options (``lopcook.tune.recook.recook``), times every stage and
compares the bytes with the file (``cook.status``: identical / prefix / differs / not re-cooked).
The re-cooked analysis gives the warnings and the LOD chain's notes (fallbacks, missed targets).
``cook_timings_s`` and ``seconds`` are the only values that vary between identical runs.

Images: all images of the shown view are cropped to one box around the union of their object
pixels plus a margin and, when small, enlarged by an integer factor with nearest-neighbour sampling
(``crop_box``, ``apply_crop``; at level 6 an object is ~37 pixels tall in a 1280x720 frame). The box
and factor are in ``images.crop`` and in the caption. LODs: ``lods`` holds the container's LOD table
(``lod_table``: triangles, vertices, Hausdorff error, selection distance range and bytes per part
and LOD), shown as the "Levels of detail" table.
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

from .version import __version__
from .atomic import write_atomic
from .verify.baselines import UNIFORM16_BYTES_PER_VERTEX

FLOAT32_BYTES_PER_VERTEX = 12
VARIANT_KEYS = ("bytes", "percent_of_float32", "psnr_min", "psnr_mean", "psnr_pooled", "psnr_interior_min",
                "psnr_interior_mean", "max_error", "share_off", "pixels_off", "object_pixels",
                "depth_order_errors", "depth_order_errors_views", "part_mismatch", "psnr_views")
IMAGE_KEYS = ("float", "ap", "cap", "ap_heatmap", "cap_heatmap", "levels")


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


def analysis_warnings(scene, analysis) -> dict:
    """Warnings of ``analysis`` (an ``Analysis`` of ``scene``: the re-cook's, ``reproduce.recook``)."""
    from .analyse.summary import describe_analysis

    d = describe_analysis(analysis, str(scene.source))
    t = d["totals"]
    return {"available": True, "scene": [str(w) for w in scene.warnings],
            "touching": [list(p) for p in d["touching"]], "intersecting": [list(p) for p in d["intersecting"]],
            "degenerate_triangles": int(t["degenerate_triangles"]), "depth_capped": int(t["depth_capped"]),
            "attribute_unsatisfied": int(t["attribute_unsatisfied"])}


def lod_table(manifest: dict, reports: list | None = None) -> list[dict]:
    """Per part of a container manifest, its LODs as written: ``{"part", "lods": [...], "notes"}``.

    Each LOD: ``lod`` (index), ``triangles``, ``vertices``, ``geometric_error_m`` (symmetric Hausdorff
    distance to LOD 0, metres, as recorded), ``min_distance_m`` / ``max_distance_m`` (the camera
    distances, metres, over which ``lopcook.selection.select`` picks it under the manifest's viewing:
    from its own ``min_distance_m`` to the next larger one of the part; ``max_distance_m`` None =
    no upper bound; a container cooked without LODs records no distance, and its single LOD covers
    [0, inf)), and bytes in the file: ``index_bytes``, ``attribute_bytes`` (normals, UVs, colours),
    ``mandatory_position_bytes`` (its share of the mandatory section),
    ``plane_position_bytes`` (its bits in the refinement planes 2..max_level: 3 bits per vertex
    whose minimum level is below the plane, rounded up to bytes per plane) and ``bytes``, the sum.
    ``notes``: the LOD report notes of that part: ``reports[i]["notes"]`` (``LodReport.as_dict`` of
    the re-cooked chain, ``reproduce.recook``), else those the container records
    (``options.lods.reports[i].notes``), else empty."""
    sizes = {s["name"]: int(s["length"]) for s in manifest["sections"]}
    max_level = int(manifest["positions"].get("max_level", 24))
    if not reports:
        reports = ((manifest.get("options") or {}).get("lods") or {}).get("reports") or []
    out = []
    for i, part in enumerate(manifest["parts"]):
        starts = [e.get("min_distance_m") for e in part["lods"]]
        rows = []
        for k, e in enumerate(part["lods"]):
            lo = starts[k] if starts[k] is not None else 0.0
            later = [s for s in starts if s is not None and s > lo]
            vid = e["vertex_id"]
            index_bytes = sizes.get(e["indices"], 0)
            attribute_bytes = sum(sizes.get(e.get(key) or "", 0) for key in ("normals", "uvs", "colors"))
            mandatory = 4 * int(e["mandatory_words"][1])
            planes = sum((3 * int(vid[p - 1]) + 7) // 8 for p in range(2, max_level + 1))
            rows.append({"lod": k, "triangles": int(e["triangles"]), "vertices": int(e["vertices"]),
                         "geometric_error_m": float(e.get("geometric_error_m", 0.0)),
                         "min_distance_m": float(lo), "max_distance_m": min(later) if later else None,
                         "index_bytes": index_bytes, "attribute_bytes": attribute_bytes,
                         "mandatory_position_bytes": mandatory, "plane_position_bytes": planes,
                         "bytes": index_bytes + attribute_bytes + mandatory + planes})
        rec = reports[i] if i < len(reports) and isinstance(reports[i], dict) else {}
        notes = [str(n) for n in rec.get("notes") or []]
        if rec.get("stop_reason") and rec.get("stop_reason") != "all ratios done":
            notes.append(f"chain stopped: {rec['stop_reason']}")
        out.append({"part": part["name"], "lods": rows, "notes": notes})
    return out


#: report images are cropped to the object's box plus this margin (pixels, at least) ...
CROP_MARGIN_PX = 8
#: ... or this fraction of the box's larger side, whichever is larger
CROP_MARGIN_FRACTION = 0.1
#: small crops are upscaled (nearest neighbour, integer factor) until the larger side reaches this ...
CROP_TARGET_PX = 480
#: ... by at most this factor, and never beyond the frame's size
CROP_MAX_SCALE = 8


def crop_box(images: dict | None) -> dict | None:
    """The one crop shared by every image of a view: the box around the union of object pixels
    (alpha > 0 in any RGBA image, part ID > 0 in any ID image) plus a margin (``CROP_MARGIN_PX`` or
    ``CROP_MARGIN_FRACTION`` of the box's larger side), clipped to the frame, and the integer
    nearest-neighbour upscale factor: the largest that keeps the larger side at most ``CROP_TARGET_PX``
    and the image within the frame, at most ``CROP_MAX_SCALE``, at least 1.

    Returns ``{"frame": [w, h], "box": [x0, y0, x1, y1]`` (pixels, top row 0, end exclusive),
    ``"scale": s, "size": [(x1 - x0) * s, (y1 - y0) * s]}``, or None without images. No object
    pixel anywhere: the whole frame at scale 1."""
    if not images:
        return None
    frames = [np.asarray(a) for k, a in images.items() if isinstance(a, np.ndarray) and a.ndim in (2, 3)]
    if not frames:
        return None
    h, w = frames[0].shape[:2]
    mask = np.zeros((h, w), dtype=bool)
    for a in frames:
        if a.shape[:2] != (h, w):
            continue
        if a.ndim == 3 and a.shape[2] == 4:
            mask |= a[..., 3] > 0
        elif a.ndim == 2:
            mask |= a > 0
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return {"frame": [int(w), int(h)], "box": [0, 0, int(w), int(h)], "scale": 1, "size": [int(w), int(h)]}
    y0, y1, x0, x1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    m = max(CROP_MARGIN_PX, int(math.ceil(CROP_MARGIN_FRACTION * max(x1 - x0, y1 - y0))))
    x0, y0, x1, y1 = max(0, x0 - m), max(0, y0 - m), min(w, x1 + m), min(h, y1 + m)
    cw, ch = x1 - x0, y1 - y0
    s = max(1, min(CROP_MAX_SCALE, CROP_TARGET_PX // max(cw, ch), w // cw, h // ch))
    return {"frame": [int(w), int(h)], "box": [x0, y0, x1, y1], "scale": int(s), "size": [cw * s, ch * s]}


def apply_crop(a: np.ndarray, crop: dict | None) -> np.ndarray:
    """``a`` ((h, w) or (h, w, c), the frame's size) cut to ``crop["box"]`` and repeated
    ``crop["scale"]`` times along both axes (nearest neighbour)."""
    a = np.asarray(a)
    if not crop:
        return a
    x0, y0, x1, y1 = crop["box"]
    s = int(crop["scale"])
    a = a[y0:y1, x0:x1]
    return np.repeat(np.repeat(a, s, axis=0), s, axis=1) if s > 1 else a


def uniform16_section(evaluation_16: dict | None, scene, n_vertices: int) -> dict:
    """The uniform 16-bit baseline's record: memory, its largest position error (over parts:
    sqrt(3) * half cube side / 32767 / 2, metres) and, when rendered, one row per level
    (``level``, ``psnr_min``, ``psnr_mean``, ``max_error``, ``share_off``, ``depth_order_errors``)."""
    half = max(0.5 * float((p.positions.max(axis=0) - p.positions.min(axis=0)).max()) for p in scene.parts)
    rows = []
    for r in (evaluation_16 or {}).get("levels", []):
        v = r["scene"]
        rows.append({"level": int(r["level"]), "psnr_min": v["psnr_min"], "psnr_mean": v["psnr_mean"],
                     "max_error": v["max_error"], "share_off": v["share_off"],
                     "depth_order_errors": int(v["depth_order_errors"])})
    return {"bytes_per_vertex": UNIFORM16_BYTES_PER_VERTEX, "bytes": UNIFORM16_BYTES_PER_VERTEX * int(n_vertices),
            "percent_of_float32": 100.0 * UNIFORM16_BYTES_PER_VERTEX / FLOAT32_BYTES_PER_VERTEX,
            "max_position_error_m": math.sqrt(3.0) * half / 32767.0 / 2.0, "rendered": bool(rows), "levels": rows,
            "note": "KHR_mesh_quantization normalized SHORT over each part's bounding cube (glTF-Transform "
                    "quantize's default volume), VEC3 padded to 8 bytes per vertex; rendered with the same cameras"
            if rows else "not rendered"}


def build_report(container, scene, evaluation: dict, container_desc: dict, *, warnings: dict | None = None,
                 uniform16: dict | None = None, cook: dict | None = None, level_range=None) -> dict:
    """Every number of the report, JSON-ready (see module docstring). ``uniform16``: the
    ``evaluate_scene`` result of ``baselines.uniform_quantized_scene`` (None: not rendered);
    ``cook``: ``reproduce.recook``'s result (None: not re-cooked); ``level_range``: (lo, hi) of
    the level-colour ramp of the ``levels`` image."""
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
    u16 = uniform16_section(uniform16, scene, n)
    imgs = ev.get("images")
    if warnings is None:
        warnings = {"available": False, "scene": [str(w) for w in getattr(scene, "warnings", ())],
                    "touching": [], "intersecting": [], "degenerate_triangles": None, "depth_capped": None,
                    "attribute_unsatisfied": None}
    depth_total = {v: sum(r[v]["depth_order_errors"] for r in levels if v in r) for v in ("ap", "cap")}
    images = None
    if imgs:
        images = {"level": imgs["level"], "view": imgs["view"], "kinds": [k for k in IMAGE_KEYS if k in imgs],
                  "crop": crop_box({k: v for k, v in imgs.items() if k != "levels"})}
        if "levels" in imgs and level_range is not None:
            images["level_range"] = [int(level_range[0]), int(level_range[1])]
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
        "images": images,
        "cook": None if cook is None else {"status": cook["status"], "detail": cook["detail"],
                                           "bytes": cook.get("bytes")},
        "cook_timings_s": None if cook is None else dict(cook["timings_s"]),
        "warnings": warnings,
        "depth_order_errors_total": depth_total,
        "calibration": options.get("calibration"),
        "seconds": ev.get("seconds"),
    }
    rep["lods"] = {"backend": (options.get("lods") or {}).get("backend"),
                   "ratios": (options.get("lods") or {}).get("ratios"),
                   "savings": m.get("savings"),
                   "parts": lod_table(m, None if cook is None else cook.get("lod_reports"))}
    budget = budget_section(m)
    if budget is not None:  # optional key: containers written by cook --target-bytes
        rep["budget"] = budget
    return _plain(rep)


def render_for_report(container, scene, *, levels, views, resolution) -> tuple[dict, dict, tuple[int, int] | None]:
    """All renders of a report in one GL harness: ``evaluate`` of the container with images of one
    view at the coarsest level, the uniform 16-bit scene at the same cameras
    (``baselines.uniform_quantized_scene``), and the level-coloured source (``baselines.level_scene``)
    from the images' view at the frame distance (the object fills the frame: legible at any level;
    ``lopcook.tune.budget.frame_distance``), added to the images as ``levels`` (not cropped with them).
    Returns (evaluation, uniform16 evaluation, (lo, hi) of the level ramp or None)."""
    from .tune.budget import frame_distance
    from .verify.baselines import level_scene, uniform_quantized_scene
    from .verify.render import Harness, Shading, render_viewing

    m = container.manifest
    with Harness(scene, resolution) as h:
        ev = h.evaluate(container, levels=levels, views=views, keep_images=True)
        viewing = render_viewing(m, resolution)
        shading = Shading.from_manifest(m)
        extent = float(m["grid"]["extent"])
        u16 = h.evaluate_scene(uniform_quantized_scene(scene), levels=levels, views=views, extent=extent,
                               viewing=viewing, shading=shading)
        level_range = None
        imgs = ev.get("images")
        if imgs:
            hist = [b for b, c in enumerate(m["stats"]["histogram"]) if c and b > 0]
            coloured, lo, hi = level_scene(container, scene, hist[0], hist[-1])
            box = scene.bounds()
            lv = h.evaluate_scene(coloured, levels=[imgs["level"]], views=[imgs["view"]], extent=extent,
                                  viewing=viewing, shading=Shading(ks=0.0), keep_images=True,
                                  image_view=imgs["view"],
                                  distance_m=frame_distance(box[0], box[1], viewing.fov_y_deg, resolution))
            imgs["levels"] = lv["images"]["scene"]
            level_range = (lo, hi)
    return ev, u16, level_range


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
    """Accuracy against memory: one point per level for AP, CAP and the uniform 16-bit baseline
    (when rendered), float32 at 100 % in the top (inf) band."""
    pts = {v: [(r[v]["percent_of_float32"], r[v]["psnr_min"]) for r in rep["levels"] if v in r] for v in ("ap", "cap")}
    labels = {v: [str(r["level"]) for r in rep["levels"] if v in r] for v in ("ap", "cap")}
    u = rep["baselines"]["uniform16"]
    pts["u16"] = [(u["percent_of_float32"], r["psnr_min"]) for r in u.get("levels") or []]
    labels["u16"] = [str(r["level"]) for r in u.get("levels") or []]
    finite = [b for v in pts.values() for _, b in v if b is not None]
    ylo = math.floor((min(finite) if finite else 20.0) / 5) * 5 - 5
    yhi = math.ceil((max(finite) if finite else 60.0) / 5) * 5 + 5
    p = _Plot(0, 105, ylo, yhi)
    p.axes("position memory, % of float32", "PSNR min over views, dB", _ticks(0, 100, 5), _ticks(ylo, yhi) + [None])
    p.series(pts["ap"], "#d62728", "AP", labels["ap"])
    p.series(pts["cap"], "#1f77b4", "CAP", labels["cap"])
    legend = [("AP", "#d62728"), ("CAP", "#1f77b4"), ("float32", "#2ca02c")]
    if pts["u16"]:
        p.series(pts["u16"], "#7f7f7f", "uniform 16-bit", labels["u16"], dash="2 2")
        legend.append(("uniform 16-bit", "#7f7f7f"))
    else:
        X = p.x(u["percent_of_float32"])
        p.parts.append(f'<line x1="{X:.1f}" y1="{p.t - 16}" x2="{X:.1f}" y2="{p.h - p.b}" stroke="#888" '
                       f'stroke-dasharray="4 3"><title>uniform 16-bit: {u["percent_of_float32"]:.1f} %, not rendered'
                       f'</title></line>')
        legend.append(("16-bit, memory only (dashed)", "#888"))
    p.series([(100.0, None)], "#2ca02c", "float32")
    return p.svg("memory vs PSNR per level", legend)


def _level_fill(level: int, lo: int, hi: int) -> str:
    """CSS colour of ``level`` on the ramp of the level image (``baselines.level_colours``)."""
    from .verify.baselines import level_colours

    r, g, b, _ = (np.asarray(level_colours(np.array([level]), lo, hi))[0] * 255.0 + 0.5).astype(int)
    return f"#{r:02x}{g:02x}{b:02x}"


def histogram_svg(hist: list[int]) -> str:
    """Bars per minimum level, coloured as the level image (``levels``): its legend."""
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
                     f'y="{h - b - bh:.1f}" width="{max(bw - 2, 1):.1f}" height="{bh:.1f}" fill="{_level_fill(lv, lo, hi)}">'
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


# ---- byte budget (cook --target-bytes; Purnomo et al. 2005, Fig. 11) ---------------------------------

_LOD_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")


def budget_section(manifest: dict) -> dict | None:
    """The byte-budget record of a container written by ``cook --target-bytes`` (manifest
    ``options.budget``, ``lopcook.tune.budget.budget_record``), or None for any other container."""
    b = (manifest.get("options") or {}).get("budget")
    return b if isinstance(b, dict) and b.get("candidates") else None


def budget_svg(b: dict) -> str:
    """Image error (PSNR mean over views, dB) against bits per vertex of the budget candidates: one
    series per LOD (its rendered levels), the budget curve (each LOD's largest level that fits:
    Purnomo's Fig. 11 curve for one size), the chosen candidate ringed, and the quantize-only /
    simplify-only baselines as open markers. Identical-to-source (inf) points go to the top band."""
    cands = b["candidates"]
    base = b.get("baselines") or {}
    simp = base.get("simplify_only")
    pts = [(c["bits_per_vertex"], c["psnr_mean"]) for c in cands]
    if simp:
        pts.append((simp["bits_per_vertex"], simp["psnr_mean"]))
    finite = [y for _, y in pts if y is not None]
    ylo = math.floor((min(finite) if finite else 20.0) / 5) * 5 - 5
    yhi = math.ceil((max(finite) if finite else 60.0) / 5) * 5 + 5
    xs = [x for x, _ in pts]
    xlo, xhi = 0.0, max(xs) * 1.08 + 1.0
    p = _Plot(xlo, xhi, ylo, yhi)
    p.axes("bits per vertex (8 x bytes / vertices)", "PSNR mean over views, dB", _ticks(xlo, xhi, 6),
           _ticks(ylo, yhi) + [None])
    lods = sorted({c["lod"] for c in cands})
    legend = []
    for i, k in enumerate(lods):
        colour = _LOD_COLOURS[i % len(_LOD_COLOURS)]
        series = sorted((c for c in cands if c["lod"] == k), key=lambda c: c["level"])
        p.series([(c["bits_per_vertex"], c["psnr_mean"]) for c in series], colour, f"LOD {k}",
                 [str(c["level"]) for c in series])
        legend.append((f"LOD {k}", colour))
    fit = {}
    for c in cands:
        if c["lod"] not in fit or c["level"] > fit[c["lod"]]["level"]:
            fit[c["lod"]] = c
    curve = sorted(fit.values(), key=lambda c: c["bits_per_vertex"])
    if len(curve) > 1:
        d = " ".join(f"{p.x(c['bits_per_vertex']):.1f},{p.y(c['psnr_mean']):.1f}" for c in curve)
        p.parts.append(f'<polyline class="budget-line" points="{d}" fill="none" stroke="#555" stroke-width="1" '
                       f'stroke-dasharray="5 3"><title>at the budget: each LOD at its largest level within '
                       f'{b["target_bytes"]:,} bytes</title></polyline>')
    ch = b["chosen"]
    p.parts.append(f'<circle class="chosen" cx="{p.x(ch["bits_per_vertex"]):.1f}" cy="{p.y(ch["psnr_mean"]):.1f}" '
                   f'r="8" fill="none" stroke="#000" stroke-width="2"><title>chosen: LOD {ch["lod"]} at level '
                   f'{ch["level"]}, {ch["bytes"]:,} bytes, {fmt_psnr(ch["psnr_mean"])} dB</title></circle>')
    for key, name, shape in (("quantize_only", "quantize only", "square"), ("simplify_only", "simplify only", "diamond")):
        v = base.get(key)
        if not v:
            continue
        x, y = p.x(v["bits_per_vertex"]), p.y(v["psnr_mean"])
        pts_s = (f"{x - 6:.1f},{y - 6:.1f} {x + 6:.1f},{y - 6:.1f} {x + 6:.1f},{y + 6:.1f} {x - 6:.1f},{y + 6:.1f}"
                 if shape == "square" else f"{x:.1f},{y - 7:.1f} {x + 7:.1f},{y:.1f} {x:.1f},{y + 7:.1f} {x - 7:.1f},{y:.1f}")
        p.parts.append(f'<polygon class="baseline" data-baseline="{key}" points="{pts_s}" fill="none" stroke="#000">'
                       f'<title>{name}: {fmt_psnr(v["psnr_mean"])} dB</title></polygon>'
                       f'<text x="{x + 8:.1f}" y="{y + 12:.1f}" font-size="10">{name}</text>')
    legend += [("budget curve (dashed)", "#555"), ("chosen (ring)", "#000")]
    return p.svg(f"PSNR against bits per vertex within {b['target_bytes']:,} bytes", legend)


def budget_html(b: dict) -> str:
    """The "Byte budget" section: the definition, the chart (``budget_svg``) and the candidate table."""
    e = _e
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
    e = _e
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


__all__ = ["budget_section", "budget_svg", "budget_html", "build_report", "write_html", "render_html", "analysis_warnings",
           "table_rows", "time_bought", "png_data_uri", "lod_table", "crop_box", "apply_crop", "render_for_report", "uniform16_section"]
