"""The report model: every number of ``report.json`` as plain JSON data, from a render evaluation,
the container summary and, optionally, the re-cook's analysis and timings.

``build_report`` takes a render evaluation (``lopcook.verify.evaluate.evaluate`` with images of one
view at every level: ``lopcook.report.render.render_for_report``), the container summary
(``lopcook.lop.summary.describe_container``), the uniform 16-bit baseline's evaluation, the
re-cook record (``lopcook.tune.recook.recook``) and the analysis warnings, and returns a dict of
plain Python numbers only (numpy converted, non-finite floats as None: a PSNR of None is +inf,
identical images), file names without directories and no
timestamps; ``cook_timings_s`` and ``seconds`` are the only values that vary between identical
runs. ``report_json_bytes`` serialises it deterministically (sorted keys, indent 1, UTF-8, one
final newline); the result validates against ``schema/report.schema.json``.

Uniform 16-bit quantization baseline (KHR_mesh_quantization: normalized SHORT over each part's
bounding cube, VEC3 padded to 8 bytes per vertex = 66.7 % of float32; ``lopcook.verify.baselines``):
rendered with the same cameras as AP and CAP, one PSNR row per level.

Verdict: ``verdict`` (``lopcook.report.verdict.verdict``): PASS or FAIL against ``min_psnr``, the
worst level, view and part.

Images: ``images`` records the view shown (``view_pixels``, ``view_angles``: why), one crop and one
zoom per level (``per_level``: ``level_image_record``), the worst view (``worst``:
``extra_view_record``), every LOD at its selection distance (``lods``: ``lod_render_record``), the
depth-order view (``depth``: ``depth_record``) and the heat maps' full scale; the pixels themselves
are only in the page. ``scene_parts`` lists the source's parts and their attributes (N* = normals
computed by lopcook).

LODs: ``lods`` holds the container's LOD table (``lod_table``: triangles, vertices, Hausdorff error,
selection distance range and bytes per part and LOD) and ``names``, each LOD index named one way
everywhere: "LOD 1 (1/2 of the triangles)" (``lod_name``).
"""

from __future__ import annotations

import json
import math
import os
import re

import numpy as np

from ..version import __version__
from ..analyse.summary import describe_analysis
from ..lop.codecs import CODECS
from ..lop.manifest import Manifest
from ..tune.attributes import COST_LEVEL, attribute_errors, vertex_bits
from ..verify.baselines import UNIFORM16_BYTES_PER_VERTEX
from ..verify.metrics import HEATMAP_VMAX, depth_error_mask
from .images import crop_box, squared_error, worst_window
from .verdict import DEFAULT_MIN_PSNR, verdict

#: bytes per vertex of float32 positions (3 x 4)
FLOAT32_BYTES_PER_VERTEX = 12
#: the keys of each variant's row copied from the evaluation (``lopcook.verify.evaluate.evaluate``)
VARIANT_KEYS = ("bytes", "percent_of_float32", "psnr_min", "psnr_mean", "psnr_pooled", "psnr_interior_min",
                "psnr_interior_mean", "max_error", "share_off", "pixels_off", "object_pixels",
                "depth_order_errors", "depth_order_errors_views", "part_mismatch", "psnr_views")
#: image kinds shown, in page order (``levels``: the minimum-level image, paper Fig. 7)
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
    """Warnings of ``analysis`` (an ``Analysis`` of ``scene``: the re-cook's,
    ``lopcook.tune.recook.recook``): ``available`` True, the scene's import warnings, touching and
    intersecting part pairs, and the counts of degenerate triangles, depth-capped vertices and
    vertices whose attribute bound 24 bits cannot meet."""
    d = describe_analysis(analysis, str(scene.source))
    t = d["totals"]
    ceiling = (d.get("settings") or {}).get("depth_ceiling")
    return {"available": True, "scene": [str(w) for w in scene.warnings],
            "touching": [[str(a), str(b)] for a, b in d["touching"]],
            "intersecting": [[str(a), str(b)] for a, b in d["intersecting"]],
            "degenerate_triangles": int(t["degenerate_triangles"]), "depth_capped": int(t["depth_capped"]),
            "depth_ceiling": None if ceiling is None else int(ceiling),
            "attribute_unsatisfied": int(t["attribute_unsatisfied"])}


def scene_parts(scene) -> list[dict]:
    """Per part of ``scene``: ``name``, ``vertices``, ``triangles``, ``normals`` ("source", "computed":
    by lopcook, shown as N*, or None), ``uvs``, ``colors`` (bool), ``texture`` (its name or None) and
    ``double_sided`` (bool: both sides drawn; the renders cull the back faces of the other parts)."""
    return [{"name": str(p.name), "vertices": int(p.n_vertices), "triangles": int(p.n_triangles),
             "normals": None if p.normals is None else ("computed" if p.normals_computed else "source"),
             "uvs": p.uvs is not None, "colors": p.colors is not None,
             "texture": None if p.texture is None else str(p.texture.name),
             "double_sided": bool(p.double_sided)} for p in scene.parts]


def level_image_record(images: dict) -> dict:
    """The record of one level's images (``evaluate``'s ``keep_images`` dict): ``level``, ``crop``
    (``crop_box`` of its renders) and ``zoom``: the window where the error is worst
    (``images.worst_window`` of CAP's per-pixel squared error against float, or AP's when CAP's is
    zero everywhere) with its ``variant``, or None when both match the float render exactly."""
    crop = crop_box({k: v for k, v in images.items() if k != "levels"})
    zoom = None
    for variant in ("cap", "ap"):
        if variant in images and "float" in images:
            z = worst_window(squared_error(images["float"], images[variant]), crop)
            if z is not None:
                zoom = dict(z, variant=variant)
                break
    return {"level": int(images["level"]), "crop": crop, "zoom": zoom}


def depth_record(depth: dict | None) -> dict | None:
    """The record of the depth-order view (``render.depth_target``): ``level``, ``view``, ``variant``,
    ``errors`` (pixels, as the accuracy table counts them), ``pixels`` (the mask's count, the same
    number: ``lopcook.verify.metrics.depth_error_mask``) and ``crop`` (around the object and the error pixels)."""
    if not depth:
        return None
    im = depth["images"]
    v = depth["variant"]
    mask = depth_error_mask(im["float_ids"], im[f"{v}_ids"])
    crop = crop_box({"float": im["float"], v: im[v], "mask": mask})
    return {"level": int(depth["level"]), "view": int(depth["view"]), "variant": v, "errors": int(depth["errors"]),
            "pixels": int(mask.sum()), "crop": crop}


def share_text(f: float) -> str:
    """A share in (0, 1) as the page writes it: "1/n" when within 5 % of a unit fraction (n >= 2),
    else a percentage to two significant digits ("45 %")."""
    n = round(1.0 / f) if f > 0 else 0
    if n >= 2 and abs(f * n - 1.0) <= 0.05:
        return f"1/{n}"
    return f"{100.0 * f:.2g} %"


def fraction_text(triangles: int, source_triangles: int) -> str:
    """The share of the source's triangles a LOD keeps, as the page names it: "all" (the source's
    count), else ``share_text`` ("1/4", "45 %")."""
    if source_triangles <= 0 or triangles >= source_triangles:
        return "all"
    return share_text(triangles / source_triangles)


def lod_name(k: int, triangles: int, source_triangles: int) -> str:
    """A LOD's name everywhere on the page (tables, notes, renders): ``LOD 1 (1/4 of the triangles)``,
    ``LOD 0 (all triangles)``; the share is of the source's triangles (``fraction_text``)."""
    frac = fraction_text(int(triangles), int(source_triangles))
    return f"LOD {k} (all triangles)" if frac == "all" else f"LOD {k} ({frac} of the triangles)"


#: a LOD named by its target ratio in the simplifier's notes: "LOD 0.25: ..." (``lopcook.simplify.chain``)
_RATIO_NAME = re.compile(r"\bLOD (\d+(?:\.\d+)?(?:e-?\d+)?)(?=[: ])")


def rename_notes(notes: list[str], kept: list[dict], names: list[str]) -> list[str]:
    """``notes`` with every LOD named by its target ratio ("LOD 0.25") named as the page names LODs
    (``lod_name``): the LOD of ``kept`` (the chain's LOD summaries, ``target_ratio`` each, index
    order) with that ratio, or, for a ratio no kept LOD has (a LOD the chain dropped), "the dropped
    LOD (target 1/64 of the triangles)". A ratio of 1 or more is an index already and left as it is."""
    ratios = [float(x.get("target_ratio", 0.0) or 0.0) for x in kept]

    def name(mt: re.Match) -> str:
        text = mt.group(1)
        r = float(text)
        if r >= 1.0 or ("." not in text and "e" not in text):
            return mt.group(0)
        for k, t in enumerate(ratios):
            if k < len(names) and abs(t - r) <= 1e-5 * max(t, r):
                return names[k]
        return f"the dropped LOD (target {share_text(r)} of the triangles)"

    return [_RATIO_NAME.sub(name, str(n)) for n in notes]


def lod_table(manifest: dict, reports: list | None = None, source_triangles: list[int] | None = None) -> list[dict]:
    """Per part of a container manifest, its LODs as written: ``{"part", "lods": [...], "notes"}``.

    Each LOD: ``lod`` (index), ``name`` (``lod_name``: "LOD 1 (1/4 of the triangles)", the share of
    ``source_triangles[i]``, the source part's triangles; default LOD 0's), ``triangles``,
    ``vertices``, ``geometric_error_m`` (symmetric Hausdorff
    distance to LOD 0, metres, as recorded), ``min_distance_m`` / ``max_distance_m`` (the camera
    distances, metres, over which ``lopcook.selection.select`` picks it under the manifest's viewing:
    from its own ``min_distance_m`` to the next larger one of the part; ``max_distance_m`` None =
    no upper bound; a container cooked without LODs records no distance, and its single LOD covers
    [0, inf)), and bytes in the file: ``index_bytes``, ``attribute_bytes`` (normals, UVs, colours),
    ``mandatory_position_bytes`` (its share of the mandatory section),
    ``plane_position_bytes`` (its bits in the refinement planes 2..max_level: 3 bits per vertex
    whose minimum level is below the plane, rounded up to bytes per plane) and ``bytes``, the sum.
    ``notes``: the LOD report notes of that part: ``reports[i]["notes"]`` (``LodReport.as_dict`` of
    the re-cooked chain, ``lopcook.tune.recook.recook``), else those the container records
    (``options.lods.reports[i].notes``), else empty; LODs in them named as in the table
    (``rename_notes``)."""
    typed = Manifest.of(manifest)
    if not reports:
        reports = ((manifest.get("options") or {}).get("lods") or {}).get("reports") or []
    out = []
    for i, part in enumerate(manifest["parts"]):
        starts = [e.get("min_distance_m") for e in part["lods"]]
        src = int(source_triangles[i]) if source_triangles and i < len(source_triangles) else \
            int(part["lods"][0]["triangles"])
        rows = []
        for k, e in enumerate(part["lods"]):
            lo = starts[k] if starts[k] is not None else 0.0
            later = [s for s in starts if s is not None and s > lo]
            t = typed.parts[i].lods[k]
            index_bytes, attribute_bytes = t.index_bytes, t.attribute_bytes
            mandatory, planes = t.mandatory_bytes, t.plane_bytes(typed.max_level)
            rows.append({"lod": k, "name": lod_name(k, int(e["triangles"]), src),
                         "triangles": int(e["triangles"]), "vertices": int(e["vertices"]),
                         "geometric_error_m": float(e.get("geometric_error_m", 0.0)),
                         "min_distance_m": float(lo), "max_distance_m": min(later) if later else None,
                         "index_bytes": index_bytes, "attribute_bytes": attribute_bytes,
                         "mandatory_position_bytes": mandatory, "plane_position_bytes": planes,
                         "bytes": index_bytes + attribute_bytes + mandatory + planes})
        rec = reports[i] if i < len(reports) and isinstance(reports[i], dict) else {}
        notes = [str(n) for n in rec.get("notes") or []]
        if rec.get("stop_reason") and rec.get("stop_reason") != "all ratios done":
            notes.append(f"chain stopped: {rec['stop_reason']}")
        notes = rename_notes(notes, rec.get("lods") or [], [r["name"] for r in rows])
        out.append({"part": part["name"], "lods": rows, "notes": notes})
    return out


def scene_lod_names(manifest: dict, source_triangles: list[int]) -> list[str]:
    """The name of each LOD index of the whole scene (``lod_name``): LOD k draws every part at
    min(k, its last LOD) (``lopcook.verify.buffers.lod_indices``), its share of the source's triangles."""
    deepest = max(len(p["lods"]) for p in manifest["parts"])
    total = int(sum(source_triangles))
    return [lod_name(k, sum(int(p["lods"][min(k, len(p["lods"]) - 1)]["triangles"]) for p in manifest["parts"]),
                     total) for k in range(deepest)]


def extra_view_record(d: dict | None) -> dict | None:
    """The record of the worst view (``render_for_report``'s ``worst``): ``level``, ``view``, ``psnr``
    (CAP, dB), ``part`` (``verdict.worst_part``), ``crop`` and ``zoom`` (as ``level_image_record``)."""
    if not d:
        return None
    rec = level_image_record(dict(d["images"], level=d["level"]))
    return {"level": int(d["level"]), "view": int(d["view"]), "psnr": float(d["psnr"]), "part": d.get("part"),
            "crop": rec["crop"], "zoom": rec["zoom"]}


def lod_render_record(r: dict, names: list[str], manifest: dict) -> dict:
    """One LOD render's record (``render._lod_renders``): ``lod``, ``name``, ``triangles`` (all parts at
    that LOD), ``geometric_error_m`` (the largest over parts), ``selection_distance_m`` (None: LOD 0
    or never selected), ``distance_m`` (the render's camera), ``level``, ``psnr`` (CAP against float
    LOD 0, dB; None: identical), ``object_pixels`` (the float render's) and ``crop`` (None: not rendered)."""
    k = int(r["lod"])
    entries = [p["lods"][min(k, len(p["lods"]) - 1)] for p in manifest["parts"]]
    imgs = r.get("images")
    crop = None if not imgs else crop_box({x: imgs[x] for x in ("float", "cap") if imgs.get(x) is not None})
    return {"lod": k, "name": names[k], "triangles": int(sum(int(e["triangles"]) for e in entries)),
            "geometric_error_m": float(max(float(e.get("geometric_error_m", 0.0)) for e in entries)),
            "selection_distance_m": r["selection_distance_m"], "distance_m": r["distance_m"], "level": r["level"],
            "psnr": r["psnr"], "object_pixels": r["object_pixels"], "crop": crop}


def images_section(imgs: dict | None, level_range, names: list[str] | None = None, manifest: dict | None = None):
    """The ``images`` record of ``report.json`` from ``render_for_report``'s images (None: None)."""
    if not imgs:
        return None
    per_level = imgs.get("per_level") or [imgs]
    skip = ("levels", "per_level", "depth", "worst", "lods")
    images = {"level": imgs["level"], "view": imgs["view"], "kinds": [k for k in IMAGE_KEYS if k in imgs],
              "crop": crop_box({k: v for k, v in imgs.items() if k not in skip}),
              "per_level": [level_image_record(x) for x in per_level],
              "depth": depth_record(imgs.get("depth")),
              "heatmap_vmax": float(HEATMAP_VMAX), "view_parts": imgs.get("view_parts"),
              "view_pixels": imgs.get("view_pixels"), "view_angles": imgs.get("view_angles"),
              "worst": extra_view_record(imgs.get("worst")),
              "lods": [lod_render_record(r, names, manifest) for r in imgs.get("lods") or []]
              if names is not None and manifest is not None else []}
    if "levels" in imgs and level_range is not None:
        images["level_range"] = [int(level_range[0]), int(level_range[1])]
    return images


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
                 uniform16: dict | None = None, cook: dict | None = None, level_range=None,
                 min_psnr: float = DEFAULT_MIN_PSNR) -> dict:
    """Every number of the report, JSON-ready (see module docstring). ``uniform16``: the
    ``evaluate_scene`` result of ``baselines.uniform_quantized_scene`` (None: not rendered);
    ``cook``: ``lopcook.tune.recook.recook``'s result (None: not re-cooked); ``level_range``: (lo, hi) of
    the level-colour ramp of the ``levels`` image; ``min_psnr``: the verdict's threshold, dB
    (``lopcook.report.verdict``)."""
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
                    "depth_ceiling": None, "attribute_unsatisfied": None}
    depth_total = {v: sum(r[v]["depth_order_errors"] for r in levels if v in r) for v in ("ap", "cap")}
    src_tri = [p.n_triangles for p in scene.parts]
    names = scene_lod_names(m, src_tri)
    images = images_section(imgs, level_range, names, m)
    rep = {
        "kind": "report",
        "verdict": verdict(ev["levels"], list(ev["views"]), min_psnr, (imgs or {}).get("worst")),
        "generator": f"lopcook {__version__}",
        "container": _name(ev.get("container") or container.path),
        "source": _name(ev.get("source")),
        "render": {"resolution": ev["resolution"], "samples": ev["samples"], "views": ev["views"],
                   "lod": ev["lod"], "shading": ev["shading"], "viewing": ev["viewing"], "variants": ev["variants"],
                   "grid_extent_m": ev["grid_extent_m"], "box_m": ev["box_m"],
                   "device": (ev.get("device") or {}).get("renderer")},
        "parts": ev["parts"],
        "scene_parts": scene_parts(scene),
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
    if container_desc.get("clusters") is not None:  # clustered containers only: unclustered reports keep their keys
        rep["clusters"] = container_desc["clusters"]
    rep["lods"] = {"backend": (options.get("lods") or {}).get("backend"),
                   "ratios": (options.get("lods") or {}).get("ratios"),
                   "savings": m.get("savings"),
                   "names": names,
                   "parts": lod_table(m, None if cook is None else cook.get("lod_reports"), src_tri)}
    budget = budget_section(m)
    if budget is not None:  # optional key: containers written by cook --target-bytes
        rep["budget"] = budget
    rep["attributes"] = attributes_section(container, scene)
    return _plain(rep)


def attributes_section(container, scene) -> dict:
    """The "Vertex attributes" section: per part the bits per component of its normals,
    UVs and colours (LOD 0's ``attribute_bits``; None where absent or not recorded) and its record
    bits, the container's bits per vertex at ``lopcook.tune.attributes.COST_LEVEL`` (positions' CAP
    plus records), the attribute-space errors against the source (normal degrees max / mean, UV
    error in texels: ``lopcook.tune.attributes.attribute_errors``; None when the scene does not match
    the container), and the attribute search's record (manifest ``options.attribute_search``:
    allocation, probes = the error-against-bits curve of Purnomo et al. 2005, Fig. 11) or None."""
    m = container.manifest
    parts = []
    for i, part in enumerate(m["parts"]):
        lod = part["lods"][0]
        bits = part.get("attribute_bits") or lod.get("attribute_bits") or {}
        # every codec of the first format, a newer one only where the part has it (as the attribute
        # search's allocation record: ``lopcook.tune.attributes.Allocation.record``)
        shown = {c.name: bits.get(c.name) for c in CODECS if c.format_major == 2 or bits.get(c.name) is not None}
        parts.append({"part": i, "name": part.get("name"), "vertices": int(lod["vertices"]),
                      "bits": shown, "record_bits": lod.get("record_bits")})
    try:
        errors = attribute_errors(container, scene)
    except Exception:  # noqa: BLE001 -- a scene that is not the container's source: no attribute errors
        errors = None
    vb = vertex_bits(container, COST_LEVEL)
    return {"level": COST_LEVEL, "parts": parts, "errors": errors,
            "vertex_bits": {k: vb[k] for k in ("positions", "attributes", "total")},
            "search": (m.get("options") or {}).get("attribute_search")}


def budget_section(manifest: dict) -> dict | None:
    """The byte-budget record of a container written by ``cook --target-bytes`` (manifest
    ``options.budget``, ``lopcook.tune.budget.budget_record``), or None for any other container."""
    b = (manifest.get("options") or {}).get("budget")
    return b if isinstance(b, dict) and b.get("candidates") else None


def report_json_bytes(rep: dict) -> bytes:
    """``rep`` as report.json bytes: JSON with sorted keys, indent 1, no NaN or infinity (ValueError),
    UTF-8, one final newline. The same dict gives the same bytes."""
    return (json.dumps(rep, indent=1, sort_keys=True, allow_nan=False) + "\n").encode("utf-8")


__all__ = ["FLOAT32_BYTES_PER_VERTEX", "VARIANT_KEYS", "IMAGE_KEYS", "analysis_warnings", "scene_parts",
           "level_image_record", "depth_record", "lod_table", "fraction_text", "lod_name", "rename_notes",
           "scene_lod_names", "extra_view_record", "lod_render_record", "images_section", "share_text",
           "uniform16_section", "build_report", "budget_section", "attributes_section", "report_json_bytes"]
