"""Byte-budget fit: the LOD and per-buffer level with the least image error within N bytes.

This work is based on: Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex Compression
Using Quantization and Simplification", Graphics Hardware 2005, section 5 (quantization and
simplification under one total size; Figs. 8, 11, 12) and section 4.1 (image-space error over
20 views); the positions are Meyer et al. 2011's binned adaptive precision buffers
(``lopcook.emit``). The steps in full: docs/budget.md, "The fit, step by step".

``fit(scene, target_bytes, settings) -> (container bytes, info)``:

1. The LOD chain is cooked on one grid (``lopcook.pipeline.run``; default ratios
   ``default_ratios``: 1/2, 1/4, ... as ``lod_chain`` makes them).
2. A candidate (k, B) is LOD k alone with every vertex at B bits per component: planes above B
   are not written, vertices whose minimum level is above B are stored at B
   (``clamped_vertices``). Its GPU buffer at B is AP at B of the chain's LOD k.
3. Its bytes (``candidate_bytes``), by ``scope`` (``SCOPES``): ``"positions"`` the GPU-resident
   position buffer at B in the cook's cluster layout (float size: 12 bytes per LOD-0 vertex);
   ``"vertices"`` plus the stored attribute records (float: float32 normals, UVs, colours);
   ``"all"`` plus the stored index buffer (float: 32-bit indices of LOD 0).
4. Its image error: rendered against the float source (LOD 0) from ``views`` at ``resolution``,
   every candidate at one camera distance (``camera_distance``); the score is ``psnr_mean``, the
   PSNR of the view-averaged MSE over object pixels (dB; None = identical).
5. Rendered per LOD: the largest fitting level (``level_fit``) and ``levels_per_lod - 1`` below
   it; a LOD that fits at the file's highest level dominates every coarser one.
6. The choice: the highest ``psnr_mean`` (ties: fewer bytes, then the finer LOD), written from the
   same buffers (one LOD per part, planes 2..B); the record (``budget_record``, with the
   quantize-only and simplify-only baselines) goes to the manifest's ``options.budget``.

Nothing fits (not even the coarsest LOD at level 1): ``LopcookError`` (exit 2) naming the smallest
candidate's bytes. The same scene, target and settings give the same bytes (the renderer is
deterministic). Measured costs: docs/budget.md.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..emit import PositionSizer, build
from ..errors import LopcookError
from ..lop.binning import LEVELS
from ..lop.manifest import FLOAT32_BYTES_PER_VERTEX
from ..pipeline import run
from ..settings import DEFAULT_LOD_LEVELS, DEFAULTS, BudgetScope, LodSpec, Settings, halvings
from ..simplify import MIN_SIMPLIFY_TRIANGLES
from ..types import MeshPart, Scene
from ..verify.buffers import lod_indices
from ..verify.evaluate import harness_evaluate, harness_evaluate_scene
from ..verify.renderer import Harness, Shading
from ..viewing import Viewing

SCOPES = tuple(s.value for s in BudgetScope)
DEFAULT_SCOPE = DEFAULTS.tune.budget_scope.value
DEFAULT_RESOLUTION = DEFAULTS.tune.budget.resolution
DEFAULT_VIEWS = DEFAULTS.tune.budget.views
DEFAULT_LEVELS_PER_LOD = DEFAULTS.tune.budget_levels
#: float32 bytes per vertex of each attribute (what "float size" counts)
FLOAT_ATTRIBUTE_BYTES = {"normals": 12, "uvs": 8, "colors": 16}
#: bytes per triangle of a 32-bit index buffer
FLOAT_INDEX_BYTES = 12
#: PSNR values recorded in the manifest are rounded to this many decimals (dB)
PSNR_DECIMALS = 4


# ---- sizes ---------------------------------------------------------------------------------------

def default_ratios(scene: Scene, max_levels: int = DEFAULT_LOD_LEVELS) -> list[float]:
    """1/2, 1/4, 1/8, ... while the largest part's target keeps at least ``MIN_SIMPLIFY_TRIANGLES``
    triangles (at most ``max_levels`` ratios): ``lod_chain``'s default chain; smaller parts stop
    earlier on their own."""
    return halvings(max_levels, max((p.n_triangles for p in scene.parts), default=0), MIN_SIMPLIFY_TRIANGLES)


def float_bytes(scene: Scene, scope: str = DEFAULT_SCOPE) -> int:
    """The scene's float size in bytes under ``scope`` (see module doc, step 3): float32 positions,
    plus float32 normals / UVs / colours ("vertices"), plus 32-bit indices ("all")."""
    _check_scope(scope)
    total = 0
    for p in scene.parts:
        total += FLOAT32_BYTES_PER_VERTEX * p.n_vertices
        if scope != "positions":
            total += sum(FLOAT_ATTRIBUTE_BYTES[k] * p.n_vertices for k in FLOAT_ATTRIBUTE_BYTES
                         if getattr(p, k) is not None)
        if scope == "all":
            total += FLOAT_INDEX_BYTES * p.n_triangles
    return int(total)


def _check_scope(scope: str) -> None:
    if scope not in SCOPES:
        raise LopcookError("usage", None, f"budget scope {scope!r}: expected one of {', '.join(SCOPES)}")


def candidate_bytes(c, lods: list[int], level: int, scope: str = DEFAULT_SCOPE, position_bytes=None) -> dict:
    """Bytes of candidate (LOD, level B) of container ``c`` (part i at LOD ``lods[i]``).

    ``position_bytes(i, k, B)``: GPU-resident position bytes of part i's LOD k written at highest
    plane B (``fit`` passes ``lopcook.emit.PositionSizer``'s); None: unclustered, 3 B bits per
    vertex in whole uint32 words per buffer.
    Returns ``position_bytes`` (the positions as written),
    ``attribute_bytes`` (normals / UVs / colours sections as stored), ``index_bytes`` (index
    section as stored), ``bytes`` (the sum of what ``scope`` counts), ``vertices``, ``triangles``
    and ``clamped_vertices`` (vertices whose minimum level is above B)."""
    _check_scope(scope)
    pos = attrs = idx = n = m = clamped = 0
    parts = c.entries.parts
    for i, k in enumerate(lods):
        e = parts[i].lods[k]
        pos += e.ap_bytes(level) if position_bytes is None else position_bytes(i, k, int(level))
        attrs += e.attribute_bytes
        idx += e.index_bytes
        n += e.vertices
        m += e.triangles
        clamped += e.vertices - int(e.vertex_id[int(level)])
    total = pos + (attrs if scope != "positions" else 0) + (idx if scope == "all" else 0)
    return {"position_bytes": int(pos), "attribute_bytes": int(attrs), "index_bytes": int(idx), "bytes": int(total),
            "vertices": int(n), "triangles": int(m), "clamped_vertices": int(clamped)}


def lod_float_bytes(c, lods: list[int], scope: str = DEFAULT_SCOPE) -> int:
    """Float size of the LOD itself ("simplify only"): float32 positions, plus float32 attributes the
    LOD has ("vertices"), plus 32-bit indices ("all")."""
    total = 0
    parts = c.entries.parts
    for i, k in enumerate(lods):
        e = parts[i].lods[k]
        total += e.float32_bytes
        if scope != "positions":
            total += sum(FLOAT_ATTRIBUTE_BYTES[key] * e.vertices for key in FLOAT_ATTRIBUTE_BYTES
                         if e.section_bytes.get(key))
        if scope == "all":
            total += FLOAT_INDEX_BYTES * e.triangles
    return int(total)


def level_fit(c, lods: list[int], target: int, scope: str = DEFAULT_SCOPE, position_bytes=None) -> int | None:
    """The largest level B in [1, highest level in the file] such that the candidates at every
    level up to B fit in ``target`` bytes (bytes grow with B), or None when even level 1 does not.
    ``position_bytes``: as for ``candidate_bytes``."""
    best = None
    for b in range(1, int(c.available_level) + 1):
        if candidate_bytes(c, lods, b, scope, position_bytes)["bytes"] <= target:
            best = b
        else:
            break
    return best


# ---- camera ----------------------------------------------------------------------------------------

def frame_distance(lo, hi, fov_y_deg: float, resolution) -> float:
    """Metres from the eye to the nearest point of the box [lo, hi] at which the box's bounding
    sphere (radius r = half diagonal) fits in the smaller field of view ``a``: ``r / sin(a / 2)``
    (the eye is then at least that far from the centre, so nothing is cut off)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    r = 0.5 * float(np.linalg.norm(hi - lo))
    w, h = int(resolution[0]), int(resolution[1])
    t = math.tan(math.radians(fov_y_deg) / 2.0)
    half = math.atan(t * min(1.0, w / h))
    return max(r, 1e-9) / math.sin(half)


def camera_distance(scene: Scene, viewing: Viewing, resolution) -> tuple[float, str]:
    """The one camera distance every candidate is judged at (metres, eye to the nearest box point)
    and its rule: ``"nearest"`` (``viewing.nearest_m``) or ``"frame"`` (``frame_distance``)."""
    if viewing.nearest_m is not None:
        return float(viewing.nearest_m), "nearest"
    lo, hi = scene.bounds()
    return frame_distance(lo, hi, viewing.fov_y_deg, resolution), "frame"


# ---- the fit -----------------------------------------------------------------------------------------

def _psnr_key(p):
    return math.inf if p is None else float(p)


def _round(p):
    return None if p is None else round(float(p), PSNR_DECIMALS)


def _simplified_scene(scene: Scene, grid, buffers, lods: list[int]) -> Scene:
    """The float scene of LOD ``lods[i]`` per part: 24-bit grid positions, float attributes."""
    parts = []
    for i, (p, k) in enumerate(zip(scene.parts, lods)):
        b = buffers[i][k]
        pos = grid.reconstruct(b.quantized, LEVELS)
        parts.append(MeshPart(p.name, pos, np.asarray(b.indices, np.uint32), dict(b.attributes),
                              source=p.source, normals_computed=p.normals_computed,
                              texture=p.texture if b.attributes.get("uvs") is not None else None, mesh_key=p.mesh_key,
                              double_sided=p.double_sided))
    return replace(scene, parts=tuple(parts))


def fit(scene: Scene, target_bytes: int, settings: Settings = DEFAULTS, *, scope: str = DEFAULT_SCOPE,
        views=DEFAULT_VIEWS, resolution=DEFAULT_RESOLUTION, levels_per_lod: int = DEFAULT_LEVELS_PER_LOD,
        samples: int = 4, options: dict | None = None, progress=None) -> tuple[bytes, dict]:
    """Container bytes of the best (LOD, level) within ``target_bytes`` and an info dict.

    Parameters
    ----------
    scene : the source (LOD 0; the float reference of every render).
    target_bytes : N, the budget in bytes under ``scope`` (int > 0).
    settings : the cook's: analysis settings and viewing conditions (recorded; ``viewing.nearest_m``
        also fixes the camera distance and which planes exist), the chain's ratios
        (``simplify.lods``, default ``default_ratios``) and backend (``simplify.backend``), the
        position layout (``emit.clusters``, ``emit.cluster_all``).
    scope : ``"positions"``, ``"vertices"`` or ``"all"`` (module doc, step 3).
    views : N icosahedron views or a list of indices; resolution : (w, h) pixels of the renders.
    levels_per_lod : levels rendered per LOD, the largest fitting one and those below it (>= 1).
    samples : MSAA samples of the renders.
    options : manifest options of the written container (``budget`` is added).
    progress : optional callable(str) for stage lines.

    Returns ``(data, info)``: ``info["budget"]`` is the record written to ``options.budget``
    (``budget_record``), ``info["cook"]`` the chain's ``lopcook.pipeline.CookResult``,
    ``info["timings_s"]`` (``cook``, ``render``, ``emit``).
    """
    _check_scope(scope)
    target = int(target_bytes)
    if target <= 0:
        raise LopcookError("usage", None, f"target bytes must be a positive integer, got {target_bytes}")
    if int(levels_per_lod) < 1:
        raise LopcookError("usage", None, f"levels per LOD must be >= 1, got {levels_per_lod}")
    viewing = settings.viewing
    lod_backend = settings.simplify.backend.value
    lod_ratios = None if settings.simplify.lods is None else settings.simplify.lods.resolved()
    say = progress or (lambda _msg: None)
    timings: dict = {}

    # (1) the chain, every LOD on one grid
    t0 = time.perf_counter()
    ratios = default_ratios(scene) if lod_ratios is None else [float(r) for r in lod_ratios]
    say(f"budget: LOD chain ({lod_backend}, {len(ratios)} ratios)")
    chain = settings.with_(simplify={"lods": LodSpec(auto=False, ratios=tuple(ratios))})
    cooked = run(scene, chain, options=options, keep_buffers=True)
    c = cooked.container
    timings["cook"] = time.perf_counter() - t0
    n_cluster, every = settings.emit.clusters, settings.emit.cluster_all
    position_bytes = _position_bytes(cooked.buffers, n_cluster, every)
    fsize = float_bytes(scene, scope)

    # (2)+(3) bytes of every candidate; the largest fitting level per LOD
    lod_rows, plan = _plan(c, target, scope, position_bytes, levels_per_lod, scene.source)

    # (4)+(5) render the candidates (and the simplify-only baseline) at one camera distance
    t0 = time.perf_counter()
    distance, rule = camera_distance(scene, viewing, resolution)
    candidates, simplify, view_ids, camera_level = _render(scene, cooked, plan, lod_rows, target, scope,
                                                           position_bytes, views, resolution, samples, distance,
                                                           viewing, say)
    timings["render"] = time.perf_counter() - t0

    # (6) the choice, written from the same buffers
    best = min(candidates, key=lambda x: (-_psnr_key(x["psnr_mean"]), x["bytes"], x["lod"], -x["level"]))
    quantize = next((x for x in candidates if x["lod"] == 0 and x["level"] == lod_rows[0]["level_fit"]), None)
    record = budget_record(target=target, scope=scope, float_size=fsize, distance=distance, rule=rule,
                           camera_level=camera_level, views=view_ids, resolution=resolution, samples=samples,
                           ratios=ratios, backend=lod_backend, lod_rows=lod_rows, candidates=candidates,
                           chosen=best, quantize=quantize, simplify=simplify, levels_per_lod=levels_per_lod)
    t0 = time.perf_counter()
    chosen_lods = lod_indices(c, best["lod"])
    buffers = [[replace(cooked.buffers[i][k], min_distance_m=0.0)] for i, k in enumerate(chosen_lods)]
    opts = dict(options or {})
    opts["budget"] = record
    data = build(scene, cooked.analysis, options=opts, viewing=viewing, lods=buffers, max_level=best["level"],
                 cluster_size=n_cluster, cluster_all=every)
    timings["emit"] = time.perf_counter() - t0
    say(f"budget: chose LOD {best['lod']} at level {best['level']}: {best['bytes']:,} of {target:,} bytes")
    return data, {"budget": record, "cook": cooked, "analysis": cooked.analysis, "timings_s": timings}


def _position_bytes(buffers, n_cluster, every: bool):
    """``position_bytes(i, k, b)``: bytes of part i's LOD k positions written at highest plane b,
    as ``build`` will write them (``lopcook.emit.PositionSizer`` over ``buffers[i][k]``, the
    chain's BufferInputs, in the layout of ``n_cluster`` / ``every``); each memoised."""
    sizers: dict = {}
    sizes: dict = {}

    def position_bytes(i: int, k: int, b: int) -> int:
        if (i, k, b) not in sizes:
            if (i, k) not in sizers:
                sizers[i, k] = PositionSizer(buffers[i][k], n_cluster, cluster_all=every)
            sizes[i, k, b] = sizers[i, k].bytes_at(b)
        return sizes[i, k, b]

    return position_bytes


def _plan(c, target: int, scope: str, position_bytes, levels_per_lod: int, source) -> tuple[list, list]:
    """Steps (2)+(3) and (5): per LOD of the chain's container ``c`` its row for the record (lod,
    vertices, triangles, geometric_error_m, level_fit, bytes_at_level_1, float_bytes, status
    rendered / does not fit / dominated) and the plan ``[(k, lods, levels to render)]``.
    LopcookError (budget, exit 2) when no LOD fits even at level 1 (``source``: the scene's file)."""
    depth = max(len(p["lods"]) for p in c.manifest["parts"])
    available = int(c.available_level)
    lod_rows, plan = [], []
    dominated = False
    for k in range(depth):
        lods = lod_indices(c, k)
        b_fit = level_fit(c, lods, target, scope, position_bytes)
        smallest = candidate_bytes(c, lods, 1, scope, position_bytes)
        row = {"lod": k, "lods": lods, "vertices": smallest["vertices"], "triangles": smallest["triangles"],
               "geometric_error_m": max(float(c.manifest["parts"][i]["lods"][j]["geometric_error_m"])
                                        for i, j in enumerate(lods)),
               "level_fit": b_fit, "bytes_at_level_1": smallest["bytes"],
               "float_bytes": lod_float_bytes(c, lods, scope)}
        if b_fit is None:
            row["status"] = "does not fit"
        elif dominated:
            row["status"] = "dominated"
        else:
            row["status"] = "rendered"
            levels = [b_fit] if b_fit == available else [b for b in range(b_fit, b_fit - int(levels_per_lod), -1)
                                                         if b >= 1]
            plan.append((k, lods, levels))
            if b_fit == available:
                dominated = True  # every coarser LOD has fewer triangles and no more bits to gain
        lod_rows.append(row)
    if not plan:
        smallest = min(lod_rows, key=lambda r: (r["bytes_at_level_1"], r["lod"]))
        raise LopcookError("budget", source,
                           f"nothing fits in {target:,} bytes ({scope} scope): the smallest candidate, LOD "
                           f"{smallest['lod']} ({smallest['vertices']:,} vertices) at level 1, takes "
                           f"{smallest['bytes_at_level_1']:,} bytes",
                           hint=f"give --target-bytes {smallest['bytes_at_level_1']} or more, coarser --lods, "
                                f"or a narrower --budget-scope")
    return lod_rows, plan


def _render(scene: Scene, cooked, plan: list, lod_rows: list, target: int, scope: str, position_bytes, views,
            resolution, samples: int, distance: float, viewing: Viewing, say):
    """Step (4): every planned candidate of the chain ``cooked`` (a CookResult) rendered as AP at
    its level against the float source at ``distance`` metres, and the simplify-only baseline (the
    finest LOD whose float size fits ``target``, rendered as a float scene under ``viewing``), on
    one harness.
    Returns ``(candidates, simplify-only record or None, the view indices, the camera's level)``."""
    c = cooked.container
    extent = float(c.manifest["grid"]["extent"])
    available = int(c.available_level)
    candidates = []
    simplify = None
    with Harness(scene, resolution, samples, cache_float=True) as h:
        for k, lods, levels in plan:
            say(f"budget: render LOD {k} at levels {levels}")
            r = harness_evaluate(h, c, levels=levels, views=views, variants=("ap",), lod=k, distance_m=distance)
            for row in r["levels"]:
                b = row["level"]
                cb = candidate_bytes(c, lods, b, scope, position_bytes)
                ap = row["ap"]
                candidates.append({"lod": k, "level": b, **cb,
                                   "bits_per_vertex": 8.0 * cb["bytes"] / max(cb["vertices"], 1),
                                   "psnr_mean": _round(ap["psnr_mean"]), "psnr_min": _round(ap["psnr_min"]),
                                   "depth_order_errors": int(ap["depth_order_errors"])})
        view_ids = r["views"]
        camera_level = r["levels"][0]["camera_level"]
        fits = [row for row in lod_rows if row["float_bytes"] <= target]
        if fits:
            row = fits[0]
            say(f"budget: render simplify-only LOD {row['lod']} (float)")
            test = _simplified_scene(scene, cooked.analysis.grid, cooked.buffers, row["lods"])
            rs = harness_evaluate_scene(h, test, levels=[available], views=views, distance_m=distance,
                                        extent=extent, viewing=viewing, shading=Shading.from_manifest(c.manifest))
            s = rs["levels"][0]["scene"]
            simplify = {"lod": row["lod"], "vertices": row["vertices"], "triangles": row["triangles"],
                        "bytes": row["float_bytes"], "bits_per_vertex": 8.0 * row["float_bytes"] / max(row["vertices"], 1),
                        "psnr_mean": _round(s["psnr_mean"]), "psnr_min": _round(s["psnr_min"])}
    return candidates, simplify, view_ids, camera_level


def budget_record(*, target, scope, float_size, distance, rule, camera_level, views, resolution, samples, ratios,
                  backend, lod_rows, candidates, chosen, quantize, simplify, levels_per_lod) -> dict:
    """The JSON record of a fit (manifest ``options.budget``; ``lopcook cook --json`` ``budget``).

    Keys: ``target_bytes``, ``scope``, ``float_bytes`` (the scene's float size under the scope),
    ``fraction_of_float`` (target / float size), ``camera`` {``distance_m``, ``rule``
    ("nearest"/"frame"), ``level`` (what the half-pixel criterion selects there at the render
    resolution), ``views``, ``resolution``, ``samples``}, ``metric``, ``lod_chain`` {``ratios``,
    ``backend``}, ``levels_per_lod``, ``lods`` (per LOD: ``lod``, ``vertices``, ``triangles``,
    ``geometric_error_m``, ``level_fit``, ``bytes_at_level_1``, ``float_bytes``, ``status``:
    rendered / does not fit / dominated), ``candidates`` (rendered: ``lod``, ``level``, ``bytes``,
    ``position_bytes``, ``attribute_bytes``, ``index_bytes``, ``vertices``, ``triangles``,
    ``clamped_vertices``, ``bits_per_vertex``, ``psnr_mean``, ``psnr_min``, ``depth_order_errors``),
    ``chosen`` (one of the candidates), ``baselines`` {``quantize_only``: LOD 0 at its largest
    fitting level or None, ``simplify_only``: the finest LOD whose float buffer fits, rendered in
    float, or None}. PSNR in dB, rounded to 4 decimals; None = identical to the source."""
    return {
        "target_bytes": int(target),
        "scope": scope,
        "float_bytes": int(float_size),
        "fraction_of_float": float(target) / max(float_size, 1),
        "camera": {"distance_m": float(distance), "rule": rule, "level": int(camera_level), "views": list(views),
                   "resolution": [int(resolution[0]), int(resolution[1])], "samples": int(samples)},
        "metric": "psnr_mean: PSNR of the mean over views of the MSE over object pixels (dB, higher is better)",
        "lod_chain": {"ratios": [float(r) for r in ratios], "backend": backend},
        "levels_per_lod": int(levels_per_lod),
        "lods": [{k: v for k, v in row.items() if k != "lods"} for row in lod_rows],
        "candidates": candidates,
        "chosen": dict(chosen),
        "baselines": {"quantize_only": None if quantize is None else dict(quantize), "simplify_only": simplify},
    }


def format_budget(record: dict) -> str:
    """Text summary of a budget record (``lopcook cook --target-bytes`` without ``--json``)."""
    cam = record["camera"]
    ch = record["chosen"]

    def ps(v):
        return "inf" if v is None else f"{v:.2f}"

    lines = [f"budget: {record['target_bytes']:,} bytes ({record['scope']}; {100 * record['fraction_of_float']:.1f}% "
             f"of the float size {record['float_bytes']:,} B); {len(cam['views'])} views at "
             f"{cam['resolution'][0]}x{cam['resolution'][1]}, camera {cam['distance_m']:.4g} m ({cam['rule']}, "
             f"level {cam['level']})",
             "    LOD  level   vertices      bytes  bits/vertex  PSNR mean dB"]
    for x in record["candidates"]:
        mark = "  <- chosen" if (x["lod"], x["level"]) == (ch["lod"], ch["level"]) else ""
        lines.append(f"  {x['lod']:>5}  {x['level']:>5}  {x['vertices']:>9,}  {x['bytes']:>9,}  "
                     f"{x['bits_per_vertex']:>11.1f}  {ps(x['psnr_mean']):>12}{mark}")
    q, s = record["baselines"]["quantize_only"], record["baselines"]["simplify_only"]
    lines.append("  quantize only: " + ("none fits" if q is None else
                                        f"LOD 0 at level {q['level']}, {ps(q['psnr_mean'])} dB"))
    lines.append("  simplify only: " + ("none fits" if s is None else
                                        f"LOD {s['lod']} in float32 ({s['bytes']:,} B), {ps(s['psnr_mean'])} dB"))
    lines.append(f"  chosen: LOD {ch['lod']} at level {ch['level']}, {ch['bytes']:,} bytes, {ps(ch['psnr_mean'])} dB"
                 + (f" ({ch['clamped_vertices']:,} vertices stored below their minimum level)"
                    if ch["clamped_vertices"] else ""))
    return "\n".join(lines)


__all__ = ["fit", "float_bytes", "candidate_bytes", "lod_float_bytes", "level_fit", "default_ratios",
           "frame_distance", "camera_distance", "budget_record", "format_budget", "SCOPES", "DEFAULT_SCOPE",
           "DEFAULT_RESOLUTION", "DEFAULT_VIEWS", "DEFAULT_LEVELS_PER_LOD"]
