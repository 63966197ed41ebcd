"""Scene -> container bytes with LOD chains and "no more than a scene needs" savings.

Steps of ``cook_bytes``:

1. LOD chains per part (``lopcook.simplify.chain.lod_chain``) when ``lod_ratios`` is given; the
   chain's ``max_error_m`` is the error the farthest useful view can show (``far_error_m``: the
   distance at which the whole scene spans one pixel; no cap when ``viewing.nearest_m`` is None).
2. ONE grid fitted over every position of every part and every LOD.
3. Every LOD index k analysed on that grid (``analyse(scene_k, settings, grid=grid)``, scene_k =
   the parts that have a LOD k); then co-located vertices (same quantized position, any part,
   any LOD) share the maximum of their minimum levels, so no two buffers can crack apart.
4. LODs whose selection range is empty are dropped (``lopcook.selection.selection_ranges``); the
   others record ``min_distance_m``.
5. When ``viewing.nearest_m`` is set, the highest level any view can use is
   ``required_level(nearest_m, extent, viewing)`` (the nearest camera needs the most bits);
   ``max_level`` = the larger of it and the highest minimum level of any vertex, so no vertex
   is clamped and no guarantee lost; planes above it are not written.
6. ``lopcook.emit.build``; the savings (planes not written, LODs dropped, bytes saved against the
   same container without them) go to the manifest field ``savings``.

Without ``lod_ratios`` and without ``nearest_m`` (and ``max_level``) the bytes are exactly those
of ``build(scene, analyse(scene, settings), viewing=viewing)``.
"""

from __future__ import annotations

import inspect
import time
from dataclasses import replace
from fractions import Fraction

import numpy as np

from .analyse import Grid, _colocated_max, analyse
from .grid import BITS
from .simplify import lod_chain
from .analyse.result import REASON_CODE
from .errors import LopcookError
from .memory import release_free_memory
from .settings import DEFAULT_ANALYSE, AnalyseSettings
from .types import Scene
from .viewing import Viewing, required_level


def far_error_m(extent: float, viewing: Viewing) -> float:
    """The largest geometric error (metres) any useful view can show: at the distance where the
    whole scene (``extent`` metres) spans one pixel, ``pixel_error`` pixels are
    ``pixel_error * extent`` metres. A LOD with a larger error would only be selected for a
    sub-pixel scene."""
    return float(viewing.pixel_error) * float(extent)


def view_level(extent: float, viewing: Viewing) -> int | None:
    """Highest per-buffer level any view can use: ``required_level(nearest_m)``; None when
    ``viewing.nearest_m`` is unknown."""
    if viewing.nearest_m is None:
        return None
    return int(np.asarray(required_level(float(viewing.nearest_m), extent, viewing)))


def default_lod_ratios() -> list[float]:
    """The default chain of ``lod_chain(ratios=None)`` as an explicit list: 1/2, 1/4, ... (its
    ``max_levels`` of them). ``lod_chain`` stops it at the first target under ``min_triangles`` and at
    the first LOD whose error exceeds ``max_error_m`` (``pipeline.far_error_m`` when --nearest is
    given), so the LODs are those of ``ratios=None``; ``cook_bytes`` reserves None for "no LODs"."""
    n = int(inspect.signature(lod_chain).parameters["max_levels"].default)
    return [0.5 ** k for k in range(1, n + 1)]


def parse_lod_ratios(text):
    """``--lods`` text (as ``cook`` takes it and the manifest records it in ``options.lods.ratios``):
    ``"1/2,1/4"`` -> [0.5, 0.25]; ``"auto"`` -> the default chain (``default_lod_ratios``); None
    stays None. Ratios must be in (0, 1) and decreasing."""
    if text is None:
        return None
    if text.strip().lower() == "auto":
        return default_lod_ratios()
    try:
        ratios = [float(Fraction(t.strip())) for t in text.split(",") if t.strip()]
    except (ValueError, ZeroDivisionError):
        raise LopcookError("usage", None, f"--lods {text!r}: expected auto or fractions such as 1/2,1/4,1/8") from None
    ratios = [r for r in ratios if r != 1.0]
    if not ratios or any(not 0 < r < 1 for r in ratios) or any(a <= b for a, b in zip(ratios, ratios[1:])):
        raise LopcookError("usage", None, f"--lods {text!r}: fractions must be in (0, 1) and decreasing")
    return ratios


def _chains(scene: Scene, lod_ratios, backend: str, max_error_m):
    """LOD chain and report of every part, in part order. Copies of one mesh (``instances.copies``:
    same triangles and attributes, positions related by one affine map) are simplified once and
    the chain placed on every copy (``instances.placed_chain``). Serial on purpose: pymeshlab
    releases the GIL but is not thread-safe (two parts simplified in a thread pool crash the
    process, CesiumMilkTruck --lods 1/2,1/4: SIGSEGV), and fast-simplification and libigl hold
    the GIL."""
    from .simplify.instances import copies, placed_chain

    chains, reports = [None] * len(scene.parts), [None] * len(scene.parts)
    for lead, members in copies(scene.parts):
        lods, report = lod_chain(scene.parts[lead], ratios=list(lod_ratios), backend=backend, max_error_m=max_error_m)
        chains[lead], reports[lead] = lods, report
        for i, a, t in members:
            chains[i], reports[i] = placed_chain(lods, report, scene.parts[i], a, t, max_error_m)
    return chains, reports


def analyse_lods(scene: Scene, chains, settings: AnalyseSettings = DEFAULT_ANALYSE, grid: Grid | None = None):
    """Analyse every LOD level on one grid, then share levels between co-located vertices.

    chains: per part, its list of MeshParts (LOD 0 first). Returns ``(grid, analyses, levels,
    raised)``: ``analyses[k]`` the Analysis of LOD index k (parts that have one, in part order),
    ``levels[i][k]`` the final (n,) uint8 minimum levels of part i's LOD k, ``raised`` how many
    vertices the cross-LOD sharing raised beyond their own LOD's analysis."""
    grid = grid or Grid.fit([p.positions for chain in chains for p in chain])
    depth = max(len(c) for c in chains)
    analyses, members = [], []
    for k in range(depth):
        idx = [i for i, c in enumerate(chains) if len(c) > k]
        scene_k = replace(scene, parts=tuple(chains[i][k] for i in idx))
        analyses.append(analyse(scene_k, settings, grid=grid))
        members.append(idx)
    allq = np.concatenate([pa.quantized for an in analyses for pa in an.parts])
    alll = np.concatenate([pa.min_level.astype(np.int64) for an in analyses for pa in an.parts])
    shared = _colocated_max(allq, alll)
    raised = int(np.count_nonzero(shared > alll))
    levels = [[None] * len(c) for c in chains]
    start = 0
    for k, (an, idx) in enumerate(zip(analyses, members)):
        for i, pa in zip(idx, an.parts):
            n = pa.min_level.shape[0]
            final = shared[start:start + n].astype(np.uint8)
            if np.any(final > pa.min_level):
                pa.reason[final > pa.min_level] = REASON_CODE["co-located"]
                pa.min_level = final
            levels[i][k] = final
            start += n
    return grid, analyses, levels, raised


def cook_bytes(scene: Scene, analyse_settings: AnalyseSettings = DEFAULT_ANALYSE, viewing: Viewing | None = None, *,
               lod_ratios=None, lod_backend: str = "pymeshlab", max_level: int | None = None,
               options: dict | None = None, keep_buffers: bool = False) -> tuple[bytes, dict]:
    """Container bytes for ``scene`` and an info dict (see module doc).

    lod_ratios : None (LOD 0 only) or fractions of LOD 0's triangles, e.g. [1/2, 1/4, 1/8]
    lod_backend : ``"pymeshlab"`` or ``"fast"`` (``lod_chain``)
    max_level : highest plane to write; default from ``viewing.nearest_m`` (24 when unknown).
        Given explicitly it is used as is (vertices above it are clamped, see ``build``).
    options : recorded verbatim in the manifest.
    keep_buffers : also return ``info["buffers"]``, the BufferInputs written (per part, per kept
        LOD; numpy arrays, not JSON) -- for tests and tools.

    info: ``timings_s``, ``grid_extent_m``, ``lods`` (per part: triangles, vertices, error_m,
    min_distance_m, bytes of its sections, kept), ``lod_reports``, ``view_level`` (None without
    nearest_m), ``highest_min_level``, ``max_level``, ``planes_dropped``, ``lods_dropped``,
    ``bytes``, ``bytes_without_savings``, ``bytes_saved``, ``colocated_raised_across_lods``,
    ``vertices_clamped_to_max_level``.
    """
    from .emit import BufferInput, build
    from .emit.container import from_bytes
    from .selection import selection_ranges

    viewing = viewing or Viewing()
    timings: dict = {}
    info: dict = {"timings_s": timings}
    plain = lod_ratios is None and viewing.nearest_m is None and max_level is None
    if plain:  # today's behaviour, byte for byte
        t0 = time.perf_counter()
        analysis = analyse(scene, analyse_settings)
        timings["analyse"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        data = build(scene, analysis, options=options, viewing=viewing)
        timings["emit"] = time.perf_counter() - t0
        info.update(grid_extent_m=float(analysis.grid.extent), view_level=None,
                    highest_min_level=int(max(int(pa.min_level.max()) for pa in analysis.parts)),
                    max_level=BITS, planes_dropped=[], lods_dropped=0, bytes=len(data),
                    bytes_without_savings=len(data), bytes_saved=0, colocated_raised_across_lods=0,
                    vertices_clamped_to_max_level=0, lod_reports=[],
                    lods=[[{"triangles": p.n_triangles, "vertices": p.n_vertices, "error_m": 0.0,
                            "min_distance_m": 0.0, "kept": True}] for p in scene.parts])
        if keep_buffers:
            info["buffers"] = [[BufferInput(quantized=pa.quantized, min_level=pa.min_level, indices=p.indices,
                                            normals=p.normals, uvs=p.uvs, colors=p.colors)]
                               for p, pa in zip(scene.parts, analysis.parts)]
        info["timings_s"]["total"] = sum(timings.values())
        info["analysis"] = analysis
        return data, info

    # (1) LOD chains
    t0 = time.perf_counter()
    scene_grid = Grid.fit([p.positions for p in scene.parts])
    cap = None if viewing.nearest_m is None else far_error_m(scene_grid.extent, viewing)
    if lod_ratios is not None:
        chains_lod, reports = _chains(scene, lod_ratios, lod_backend, cap)
    else:
        chains_lod, reports = [[None] for _ in scene.parts], []
    parts_chain = [[p] if c[0] is None else [lod.part for lod in c] for p, c in zip(scene.parts, chains_lod)]
    errors = [[0.0] if c[0] is None else [float(lod.error_m) for lod in c] for c in chains_lod]
    release_free_memory()  # the chains' temporaries: back to the system before the analysis
    timings["lod"] = time.perf_counter() - t0
    info["lod_reports"] = [r.as_dict() for r in reports]
    info["lod_max_error_m"] = cap

    # (2)+(3) one grid, every LOD analysed, co-located sharing across LODs
    t0 = time.perf_counter()
    grid, analyses, levels, raised = analyse_lods(scene, parts_chain, analyse_settings)
    release_free_memory()
    timings["analyse"] = time.perf_counter() - t0
    info["colocated_raised_across_lods"] = raised
    info["grid_extent_m"] = float(grid.extent)
    info["analysis"] = analyses[0]  # LOD 0 of every part (its stage timings, touching pairs)

    # (4) selection ranges; LODs never selected are dropped
    quantized = [[None] * len(c) for c in parts_chain]
    for k, an in enumerate(analyses):
        idx = [i for i, c in enumerate(parts_chain) if len(c) > k]
        for i, pa in zip(idx, an.parts):
            quantized[i][k] = pa.quantized
    all_buffers, kept_buffers, lod_info = [], [], []
    lods_dropped = 0
    for i, chain in enumerate(parts_chain):
        ranges = selection_ranges(errors[i], [p.n_triangles for p in chain], viewing)
        ranges[0] = 0.0  # LOD 0 (full detail) is always kept
        full, kept, rows = [], [], []
        for k, p in enumerate(chain):
            with_lods = lod_ratios is not None
            buf = BufferInput(quantized=quantized[i][k], min_level=levels[i][k], indices=p.indices,
                              normals=p.normals, uvs=p.uvs, colors=p.colors, geometric_error_m=errors[i][k],
                              min_distance_m=(ranges[k] if ranges[k] is not None else None) if with_lods else None)
            full.append(buf)
            if ranges[k] is not None:
                kept.append(buf)
            else:
                lods_dropped += 1
            rows.append({"triangles": p.n_triangles, "vertices": p.n_vertices, "error_m": errors[i][k],
                         "min_distance_m": ranges[k], "kept": ranges[k] is not None})
        all_buffers.append(full)
        kept_buffers.append(kept)
        lod_info.append(rows)

    # (5) the highest level any view needs
    highest_min = int(max(int(np.max(b.min_level)) for bufs in kept_buffers for b in bufs))
    vlevel = view_level(grid.extent, viewing)
    if max_level is None:
        max_level = BITS if vlevel is None else max(vlevel, highest_min)
    max_level = int(max_level)
    planes_dropped = list(range(max_level + 1, BITS + 1))

    # (6) build; the savings record states the bytes saved against the same container without them
    t0 = time.perf_counter()
    first_analysis = analyses[0]
    full_data = build(scene, first_analysis, options=options, viewing=viewing, lods=all_buffers, max_level=BITS)
    savings = None
    if planes_dropped or lods_dropped:  # recorded only when something was left out
        savings = {"planes_dropped": planes_dropped, "lods_dropped": int(lods_dropped), "bytes_saved": 0,
                   "bytes_without_savings": len(full_data), "view_level": vlevel, "highest_min_level": highest_min}
    data = build(scene, first_analysis, options=options, viewing=viewing, lods=kept_buffers,
                 max_level=max_level, savings=savings)
    for _ in range(4):  # the record's own digits change the manifest size: settle to a fixed point
        if savings is None or savings["bytes_saved"] == len(full_data) - len(data):
            break
        savings = dict(savings, bytes_saved=len(full_data) - len(data))
        data = build(scene, first_analysis, options=options, viewing=viewing, lods=kept_buffers,
                     max_level=max_level, savings=savings)
    timings["emit"] = time.perf_counter() - t0

    c = from_bytes(data)
    sizes = {s["name"]: s["length"] for s in c.manifest["sections"]}
    for i, part in enumerate(c.manifest["parts"]):
        kept_rows = [r for r in lod_info[i] if r["kept"]]
        for k, (row, e) in enumerate(zip(kept_rows, part["lods"])):
            row["attribute_bytes"] = sum(sizes.get(e.get(key) or "", 0) for key in ("indices", "normals", "uvs", "colors"))
            row["mandatory_position_bytes"] = 4 * int(e["mandatory_words"][1])
            vid = e["vertex_id"]
            row["plane_position_bytes"] = sum((3 * int(vid[p - 1]) + 7) // 8 for p in range(2, max_level + 1))
            row["lod"] = k
    info.update(lods=lod_info, view_level=vlevel, highest_min_level=highest_min, max_level=max_level,
                planes_dropped=planes_dropped, lods_dropped=int(lods_dropped), bytes=len(data),
                bytes_without_savings=len(full_data), bytes_saved=len(full_data) - len(data),
                vertices_clamped_to_max_level=int(c.manifest["stats"]["vertices_clamped_to_max_level"]))
    if keep_buffers:
        info["buffers"] = kept_buffers
    timings["total"] = sum(v for k, v in timings.items() if k != "total")
    return data, info


__all__ = ["cook_bytes", "analyse_lods", "far_error_m", "view_level", "default_lod_ratios", "parse_lod_ratios"]
