"""Summaries of a container for ``lopcook cook`` and ``lopcook inspect OUT.lop`` (text and JSON).

A prefix of a file (docs/format.md 8) is described as far as it goes: every LOD's
``available_level`` (0 when its sections have not arrived), and in the streaming layout (14)
every stage's level and the bytes a reader needs for it."""

from __future__ import annotations

import numpy as np

from .binning import LEVELS
from .clusters import k_histogram
from .codecs import CODECS, AttributeBits
from .container import Container
from .reader import buffer_clusters
from .record import aligned_waste, record_waste
from ..wording import length, plural

SUMMARY_LEVELS = range(6, 13)


def memory_rows(c: Container, levels=range(1, LEVELS + 1), lod: int = 0) -> list[dict]:
    """Per per-buffer level B: GPU-resident position bytes of LOD ``lod`` of every part (a part's
    coarsest when its chain is shorter) as CAP (binned), AP (every vertex at B bits) and float32
    (12 bytes per vertex, the baseline of the percentages), from ``Manifest``'s accounting."""
    m = c.entries
    f32 = m.float32_bytes(lod)
    clustered = m.clustered
    rows = []
    for b in levels:
        cap, ap = m.cap_bytes(b, lod), m.ap_bytes(b, lod)
        rows.append({"level": int(b), "cap_bytes": int(cap), "ap_bytes": int(ap), "float32_bytes": int(f32),
                     "cap_percent": 100.0 * cap / max(f32, 1), "ap_percent": 100.0 * ap / max(f32, 1)})
        if m.has_placements:  # cook --instances: each distinct buffer counted once; every copy for comparison
            cap_all, ap_all = m.cap_bytes_all_copies(b, lod), m.ap_bytes_all_copies(b, lod)
            rows[-1].update(cap_bytes_all_copies=int(cap_all), ap_bytes_all_copies=int(ap_all),
                            cap_saved_by_sharing_bytes=int(cap_all - cap), ap_saved_by_sharing_bytes=int(ap_all - ap))
        if clustered:  # the same vertices unclustered, for comparison (cap_bytes counts the clusters' records)
            un = m.unclustered_cap_bytes(b, lod)
            rows[-1].update(unclustered_cap_bytes=int(un), unclustered_cap_percent=100.0 * un / max(f32, 1))
    return rows


def cluster_stats(c: Container) -> dict | None:
    """Clustered buffers' figures (``inspect``'s ``clusters`` record), None when unclustered:
    ``cluster_size`` (N values used), ``buffers``, ``clusters`` (all buffers), ``k_histogram``
    (25 counts: cluster components with each common-prefix length k, x, y, z together),
    ``header_bytes`` (stored anchors, 12 per cluster) and ``record_bytes`` (GPU records, 16 per cluster)."""
    hist = np.zeros(LEVELS + 1, dtype=np.int64)
    sizes, buffers, total = set(), 0, 0
    for i, p in enumerate(c.manifest["parts"]):
        if (p.get("placement") or {}).get("of", i) != i:  # a placement draws its owner's buffers: once
            continue
        for k, e in enumerate(p["lods"]):
            if "cluster_size" not in e or c.level_of(i, k) < 1:  # a prefix: headers not arrived
                continue
            cl = buffer_clusters(c, i, k)
            sizes.add(int(e["cluster_size"]))
            buffers += 1
            total += cl.n_clusters
            hist += k_histogram(cl)
    if not buffers:
        return None
    return {"cluster_size": sorted(sizes), "buffers": buffers, "clusters": total,
            "k_histogram": [int(v) for v in hist], "header_bytes": 12 * total, "record_bytes": 16 * total}


#: stop codes (``options.lods.reports[i].stop``) by which a chain ends where its rule says: a part
#: left with LOD 0 alone by one of them is no shortfall
STOPS_BY_RULE = ("pixels", "relative_error", "view")


def lod_shortfalls(c: Container) -> list[str]:
    """What a container shows of its LOD chains' shortfalls: parts that got no LOD although LODs
    were asked for (``options.lods``) and no rule ended their chain there (``STOPS_BY_RULE``),
    grouped. Backend fallbacks are not stored in a container; ``cook`` prints them when they happen."""
    lods = (c.manifest.get("options") or {}).get("lods")
    if not lods:
        return []
    stops = lods.get("reports") or [] if isinstance(lods, dict) else []
    bare = [p["name"] for i, p in enumerate(c.manifest["parts"]) if len(p["lods"]) == 1
            and not (i < len(stops) and isinstance(stops[i], dict) and stops[i].get("stop") in STOPS_BY_RULE)]
    if not bare:
        return []
    more = f" and {len(bare) - 1} more" if len(bare) > 1 else ""
    return [f"part {bare[0]!r}{more}: no LODs (LOD 0 only)"]


def hierarchy_stats(c: Container, part: int) -> dict | None:
    """Part ``part``'s hierarchy figures (``inspect``'s ``hierarchy`` record), None without one:
    ``bits_per_triangle`` (the connectivity records, the paper's measure) and
    ``structure_bits_per_triangle`` (the tree shape, one bit per node) per coded triangle, and
    ``position_bits_per_vertex``: the stored bits that place the nodes, per leaf (LOD 0's
    mandatory bits and planes up to the file's highest level, which the nodes share, plus the
    section's vertex map and representative bits); ``section_bytes``, ``record_index_bits_per_triangle``
    (the random-access index), ``variant``, ``nodes``, ``triangles``."""
    rec = c.manifest["parts"][part].get("hierarchy")
    if rec is None:
        return None
    entries = c.entries
    lod = entries.parts[part].lods[0]
    shared = 8 * (lod.mandatory_bytes + lod.plane_bytes(entries.max_level))
    m = max(int(rec["triangles"]), 1)
    size = next((s["length"] for s in c.manifest["sections"] if s["name"] == rec["section"]), 0)
    return {"bits_per_triangle": rec["connectivity_bits"] / m,
            "structure_bits_per_triangle": rec["structure_bits"] / m,
            "position_bits_per_vertex": (shared + rec["vertex_map_bits"] + rec["representative_bits"])
            / max(int(rec["leaves"]), 1),
            "record_index_bits_per_triangle": rec.get("record_index_bits", 0) / m,
            "section_bytes": int(size), "variant": rec.get("variant"), "nodes": int(rec["nodes"]),
            "triangles": int(rec["triangles"])}


def _listed_codecs(c: Container) -> list:
    """The codecs ``inspect`` lists for a container: every codec of the first format, and a later
    one where some buffer holds it."""
    held = {k for p in c.manifest["parts"] for k, v in (p.get("attribute_bits") or {}).items() if v is not None}
    return [x for x in CODECS if x.format_major == 2 or x.name in held]


def _attribute_vertex_bits(bits: dict | None, codecs) -> dict:
    b = bits or {}
    return {x.name: (0 if b.get(x.name) is None else sum(x.field_widths(int(b[x.name])))) for x in codecs}


def vertex_bits(c: Container, levels=SUMMARY_LEVELS) -> dict:
    """Bits per vertex of a container, per part and in total (``inspect``'s ``vertex_bits``).

    ``{"parts": [per part: {"positions": {"6": ..}, "normals", "uvs", "colors", "total": {"6": ..}}],
    "total": {same keys}}``. Per part: ``positions[L]`` = 8 x the CAP bytes (whole uint32 words,
    ``LodEntry.cap_bytes``) of its LOD 0 at per-buffer level L per vertex; per listed codec
    (``_listed_codecs``) its record bits (normals 2 b_n, uvs 2 b_u, colors 4 b_c; 0 when absent);
    ``total[L]`` their sum. The total is vertex-weighted over every buffer of the file (all parts,
    all LODs)."""
    levels = [int(L) for L in levels if 1 <= int(L) <= c.manifest["positions"]["max_level"]]
    entries = c.entries
    parts = []
    tot_v = 0
    tot_pos = {L: 0 for L in levels}
    codecs = _listed_codecs(c)
    tot_attr = {x.name: 0 for x in codecs}
    for i, p in enumerate(entries.parts):
        e0 = p.lods[0]
        attr = _attribute_vertex_bits(e0.attribute_bits, codecs)
        pos = {str(L): 8.0 * e0.cap_bytes(entries.part_level(i, L)) / max(e0.vertices, 1) for L in levels}
        a_sum = sum(attr.values())
        parts.append({"positions": pos, **attr, "total": {k: v + a_sum for k, v in pos.items()}})
        if p.placement_of not in (None, i):
            continue  # a placement of another part's buffers: stored (and counted in the total) once
        for e in p.lods:
            tot_v += e.vertices
            for L in levels:
                tot_pos[L] += 8 * e.cap_bytes(L)
            for k, v in _attribute_vertex_bits(e.attribute_bits, codecs).items():
                tot_attr[k] += v * e.vertices
    n = max(tot_v, 1)
    attr_total = {k: v / n for k, v in tot_attr.items()}
    pos_total = {str(L): tot_pos[L] / n for L in levels}
    a_sum = sum(attr_total.values())
    total = {"positions": pos_total, **attr_total, "total": {k: v + a_sum for k, v in pos_total.items()}}
    return {"parts": parts, "total": total}


def attribute_waste(part: dict) -> dict:
    """Bits of a part's attribute records that hold no field: ``buffer_bits`` per LOD (the
    section's tail, < 32: fields may cross words) and ``aligned_bits_per_vertex``, what records
    of whole components packed first-fit decreasing into 32-bit words (Purnomo 2005, section 4)
    would waste per vertex."""
    bits = AttributeBits.of(part.get("attribute_bits") or {})
    return {"buffer_bits": [record_waste(int(e["vertices"]), bits) for e in part["lods"]],
            "aligned_bits_per_vertex": aligned_waste(bits)}


def stage_rows(c: Container) -> list[dict] | None:
    """Per stage of a streaming file (docs/format.md 14), None in the default layout: its
    ``level`` L_s, ``available_level`` in these bytes, ``buffers``, and ``bytes_renderable`` /
    ``bytes_at_level``: the file bytes a reader needs for the stage at level 1 / at L_s (every
    section up to its mandatory bits / up to its last stored plane)."""
    if not c.stream:
        return None
    rows = []
    for st, have in zip(c.layout.stages, c.stage_levels):
        ends = st.sections()
        rows.append({"stage": st.index, "level": st.level, "available_level": int(have), "buffers": len(st.buffers),
                     "bytes_renderable": c.section_end(st.mandatory), "bytes_at_level": c.section_end(ends[-1])})
    return rows


def describe_container(c: Container, file_bytes: int | None = None) -> dict:
    """Plain-data summary of a container (JSON form of ``lopcook inspect OUT.lop --json``). Per
    part: ``lods`` (each with ``triangles``, ``vertices``, ``geometric_error_m``, ``min_distance_m``:
    the camera distance in metres from which ``lopcook.selection.select`` picks it, None when the
    file records none) and ``lod_stop``: where and why its chain stopped (``options.lods.reports[i]``
    of a ``--lods auto`` cook: ``stop``, ``stop_reason``, ``extent_m``, ``max_error_m``,
    ``dropped``), None when not recorded."""
    m = c.manifest
    sections = [{"name": s["name"], "bytes": s["length"], **({"encoding": s["encoding"], "decoded_bytes": s["size"]}
                                                             if "encoding" in s else {})} for s in m["sections"]]
    by_kind: dict = {}
    for s in m["sections"]:
        kind = s["name"].rsplit("/", 1)[-1]
        kind = "planes" if kind.startswith("plane") else kind
        by_kind[kind] = by_kind.get(kind, 0) + s["length"]
    parts = []
    vb = vertex_bits(c)
    stops = _stops({"options": m["options"], "parts": m["parts"]})
    for i, p in enumerate(m["parts"]):
        lods = [{"vertices": e["vertices"], "triangles": e["triangles"], "geometric_error_m": e["geometric_error_m"],
                 "min_distance_m": e.get("min_distance_m"),
                 "histogram": np.diff(e["vertex_id"], prepend=0).tolist(),
                 "attributes": [x.name for x in CODECS if (e.get("attribute_bits") or {}).get(x.name)],
                 "attribute_bits": e.get("attribute_bits"), "record_bits": e.get("record_bits", 0),
                 "available_level": c.level_of(i, k), "stage": c.layout.stage_of[(i, k)]}
                for k, e in enumerate(p["lods"])]
        parts.append({"name": p["name"], "source": p["source"], "lods": lods, "lod_stop": stops[i],
                      "attribute_bits": p.get("attribute_bits"), "vertex_bits": vb["parts"][len(parts)],
                      "attribute_waste": attribute_waste(p)})
        if p.get("hierarchy") is not None:
            parts[-1]["hierarchy"] = hierarchy_stats(c, len(parts) - 1)
        if p.get("placement") is not None:
            parts[-1]["placement"] = p["placement"]
            parts[-1]["grid"] = p["grid"]
    totals_extra = {}
    if m["stats"].get("placements") is not None:
        owners = {pp["placement"]["of"] for pp in m["parts"] if pp.get("placement") is not None}
        totals_extra["placements"] = dict(m["stats"]["placements"], buffer_owners=sorted(owners))
    return {
        "kind": "container",
        "file": c.path,
        "format": m["format"],
        "generator": m["generator"],
        "file_bytes": file_bytes,
        "source": m["source"],
        "grid": m["grid"],
        "viewing": m["viewing"],
        "options": m["options"],
        "available_level": c.available_level,
        "max_level": m["positions"]["max_level"],
        "layout": "stream" if c.stream else "default",
        "file_size": c.file_size,
        "prefix": c.is_prefix,
        "stages": stage_rows(c),
        # stored buffers: a placement draws its owner's buffers and owns none (cook --instances)
        "totals": {"parts": len(parts), "buffers": sum(len(p["lods"]) for i, p in enumerate(m["parts"])
                                                       if (p.get("placement") or {}).get("of", i) == i),
                   "vertices": m["stats"]["vertices"], "triangles": m["stats"]["triangles"],
                   "histogram": m["stats"]["histogram"],
                   "float32_position_bytes": m["stats"]["float32_position_bytes"],
                   "float32_position_bytes_lod0": c.entries.float32_bytes(0), **totals_extra},
        "section_bytes": by_kind,
        "sections": sections,
        "memory": memory_rows(c),
        "clusters": cluster_stats(c),
        "savings": m.get("savings"),
        "vertex_bits": vb["total"],
        "parts": parts,
        "lod_warnings": lod_shortfalls(c),
    }


#: inspect and cook print one LOD table per part up to this many parts with LODs, else one table
#: of the whole scene by LOD index
LOD_TABLE_PARTS = 4


def _hist(h, first: int = 1) -> str:
    """The non-empty entries of a histogram ``h`` (index = level or bits) from ``first`` on, as
    ``k:count``; ``(empty)`` when there is none."""
    nz = [f"{b}:{int(h[b]):,}" for b in range(first, len(h)) if h[b]]
    return " ".join(nz) if nz else "(empty)"


def _stops(d: dict) -> list:
    """Per part, its chain's stop record (``options.lods.reports[i]``: ``stop``, ``stop_reason``,
    ``extent_m``, ``max_error_m``, ``dropped``), or None where the container records none."""
    recs = ((d.get("options") or {}).get("lods") or {}).get("reports") or []
    return [recs[i] if i < len(recs) and isinstance(recs[i], dict) else None for i in range(len(d["parts"]))]


def _lod_rows(lods: list) -> list[str]:
    lines = [f"  {'LOD':>5} {'triangles':>10} {'vertices':>10} {'error':>10}  selected from"]
    for k, e in enumerate(lods):
        d = e.get("min_distance_m")
        lines.append(f"  {k:>5} {e['triangles']:>10,} {e['vertices']:>10,} {length(e['geometric_error_m']):>10}  "
                     + ("(no distance recorded)" if d is None else length(d) if d else "0 m"))
    return lines


def _lod_scene_rows(parts: list) -> list[str]:
    """One row per LOD index over every part that has it: parts, their triangles (every part's,
    copies included), the largest error and the range of the parts' selection distances."""
    lines = [f"  {'LOD':>5} {'parts':>6} {'triangles':>11} {'largest error':>14}  "
             "selected from (nearest - farthest part)"]
    for k in range(max(len(p["lods"]) for p in parts)):
        es = [p["lods"][k] for p in parts if len(p["lods"]) > k]
        dist = [e.get("min_distance_m") for e in es if e.get("min_distance_m") is not None]
        near, far = (length(min(dist)), length(max(dist))) if dist else ("-", "-")
        where = "0 m" if far == "0" else near if near == far else f"{near} - {far}"
        lines.append(f"  {k:>5} {len(es):>6,} {sum(e['triangles'] for e in es):>11,} "
                     f"{length(max(e['geometric_error_m'] for e in es)):>14}  {where}")
    return lines


def _lod_lines(d: dict) -> list[str]:
    """The LOD chains: a table per part (LOD, triangles, vertices, error, the distance it is selected
    from) and where and why each chain stopped; with more than ``LOD_TABLE_PARTS`` parts one table
    by LOD index and the stops grouped. Nothing for a container without LODs."""
    stops = _stops(d)
    if not (any(len(p["lods"]) > 1 for p in d["parts"]) or any(stops)):
        return []
    rule = ((d.get("options") or {}).get("lods") or {}).get("stop_rule")
    head = [""] + ([f"  --lods auto keeps a LOD while its part spans {rule['min_pixels']:g} px or more where it is "
                    f"selected, its error at most {100 * rule['max_relative_error']:g}% of the part's extent"]
                   if rule else [])
    if len(d["parts"]) <= LOD_TABLE_PARTS:
        lines = []
        for p, st in zip(d["parts"], stops):
            lines += ([f"  LODs of part {p['name']!r}:"] if len(d["parts"]) > 1 else []) + _lod_rows(p["lods"])
            if st and st.get("stop_reason"):
                lines.append(f"  chain stopped: {st['stop_reason']}")
        return head + lines
    lines = head + _lod_scene_rows(d["parts"])
    groups: dict = {}
    for p, st in zip(d["parts"], stops):
        if st:
            groups.setdefault(st.get("stop") or "?", []).append((p["name"], st.get("stop_reason", "")))
    for code, members in sorted(groups.items(), key=lambda kv: -len(kv[1])):
        lines.append(f"  chains stopped ({code}): {plural(len(members), 'part')}, e.g. {members[0][0]!r}: "
                     f"{members[0][1]}")
    if groups:
        lines.append("  (every part's chain and stop: inspect --json, parts[].lods and parts[].lod_stop)")
    return lines


def _layout_lines(d: dict, max_parts: int) -> list[str]:
    """``format_container``'s lines on the streaming layout's stages and, in a prefix or a
    streaming file, every buffer's available level."""
    lines = []
    if d.get("stages"):
        size = max(d.get("file_size") or 1, 1)
        lines.append(f"  streaming layout, {plural(len(d['stages']), 'stage')} (stage 0: every part's coarsest LOD); "
                     f"first renderable at {d['stages'][0]['bytes_renderable']:,} B "
                     f"({100.0 * d['stages'][0]['bytes_renderable'] / size:.1f}%)")
        lines.append(f"  {'stage':>7} {'buffers':>8} {'level':>6} {'held':>5} {'renderable at':>14} {'at its level':>13}")
        for r in d["stages"]:
            lines.append(f"  {r['stage']:>7} {r['buffers']:>8} {r['level']:>6} {r['available_level']:>5} "
                         f"{r['bytes_renderable']:>12,} B {r['bytes_at_level']:>11,} B")
    if d.get("prefix") or d.get("stages"):
        lines.append("  available level of each buffer (LOD 0, 1, ...; 0: not arrived):")
        for p in d["parts"][:max_parts]:
            lines.append(f"    {p['name'][-48:]:<48} " + " ".join(str(e["available_level"]) for e in p["lods"]))
        if len(d["parts"]) > max_parts:
            lines.append(f"    … {plural(len(d['parts']) - max_parts, 'more part')} (use --json for all)")
    return lines


def _memory_lines(d: dict) -> list[str]:
    """The CAP/AP table at the summary levels the file holds. Where the CAP bytes are the same on
    every row, a note says why (every vertex is at or above its minimum level already); the
    unclustered comparison is one column when it varies, else one line."""
    rows = [r for r in d["memory"] if r["level"] in SUMMARY_LEVELS and r["level"] <= d["available_level"]]
    un = [r["unclustered_cap_bytes"] for r in rows if "unclustered_cap_bytes" in r]
    un_column = len(set(un)) > 1
    lines = [f"  {'level':>5} {'CAP bytes':>12} {'CAP %':>6} {'AP bytes':>12} {'AP %':>6}   (GPU-resident positions of "
             f"{'LOD 0' if any(len(p['lods']) > 1 for p in d['parts']) else 'every part'} vs their float32 "
             f"{d['memory'][0]['float32_bytes'] if d['memory'] else 0:,} B)"]
    for r in rows:
        lines.append(f"  {r['level']:>5} {r['cap_bytes']:>12,} {r['cap_percent']:>5.1f}% {r['ap_bytes']:>12,} "
                     f"{r['ap_percent']:>5.1f}%" + (f"   unclustered {r['unclustered_cap_bytes']:,} B "
                                                    f"{r['unclustered_cap_percent']:.1f}%" if un_column else ""))
    if len(rows) > 1 and len({r["cap_bytes"] for r in rows}) == 1:
        lowest = min((b for p in d["parts"] for b, n in enumerate(p["lods"][0]["histogram"]) if n), default=0)
        lines.append(f"  CAP bytes are the same at levels {rows[0]['level']}-{rows[-1]['level']}"
                     + (f": every vertex's minimum level is {lowest} or more, so at each of these levels every\n"
                        f"  vertex is already at or above its minimum, and CAP stores it at its minimum"
                        if lowest >= rows[-1]["level"] else ""))
    if un and not un_column:
        r = next(r for r in rows if "unclustered_cap_bytes" in r)
        at = "every level shown" if len(rows) > 1 else "this level"
        lines.append(f"  unclustered, the same vertices take {r['unclustered_cap_bytes']:,} B "
                     f"({r['unclustered_cap_percent']:.1f}%) at {at}")
    return lines


def _placement_lines(d: dict) -> list[str]:
    pl = d["totals"].get("placements")
    if not pl:
        return []
    shown = [r for r in d["memory"] if r["level"] in SUMMARY_LEVELS and r["level"] <= d["available_level"]
             and "cap_bytes_all_copies" in r]
    lines = [f"  copies stored once: {plural(pl['parts'], 'placement')} of {plural(pl['groups'], 'mesh', 'meshes')} "
             f"({pl['vertices_all_copies']:,} vertices placed)"]
    if shown:
        lo, hi = shown[0], shown[-1]
        lines.append(f"  CAP bytes at levels {lo['level']}-{hi['level']}: {lo['cap_bytes']:,}-{hi['cap_bytes']:,} "
                     f"with each mesh once, {lo['cap_bytes_all_copies']:,}-{hi['cap_bytes_all_copies']:,} with "
                     f"every copy: saves {100.0 * lo['cap_saved_by_sharing_bytes'] / max(lo['cap_bytes_all_copies'], 1):.1f}%"
                     f"-{100.0 * hi['cap_saved_by_sharing_bytes'] / max(hi['cap_bytes_all_copies'], 1):.1f}%")
    return lines


def _storage_lines(d: dict, max_parts: int) -> list[str]:
    """Clusters, what the viewing conditions saved, hierarchies and the bits per vertex (terms of
    zero bits left out)."""
    lines = []
    cs = d.get("clusters")
    if cs:
        lines.append(f"  clusters: {cs['clusters']:,} of N = {'/'.join(str(v) for v in cs['cluster_size'])} in "
                     f"{plural(cs['buffers'], 'buffer')} (CAP counts their {cs['record_bytes']:,} B of records and "
                     f"128 B ClusterId per buffer); anchor bits k (k:components): " + _hist(cs["k_histogram"], 0))
    if d.get("savings"):
        sv = d["savings"]
        planes = sv["planes_dropped"]
        what = [f"planes {planes[0]}-{planes[-1]} not written" if len(planes) > 1 else
                f"plane {planes[0]} not written"] if planes else []
        if sv["lods_dropped"]:
            what.append(f"{plural(sv['lods_dropped'], 'LOD')} no distance selects dropped")
        lines.append(f"  saved {sv['bytes_saved']:,} B by what no view needs: {', '.join(what)}")
    for p in d["parts"][:max_parts]:
        hs = p.get("hierarchy")
        if hs:
            lines.append(f"  hierarchy {p['name'][-32:]}: {hs['nodes']:,} nodes, {hs['bits_per_triangle']:.2f} bits/triangle "
                         f"connectivity + {hs['structure_bits_per_triangle']:.2f} structure, "
                         f"{hs['position_bits_per_vertex']:.1f} position bits/vertex, {hs['section_bytes']:,} B")
    vb = d.get("vertex_bits")
    if vb and vb["positions"]:
        top = max(vb["positions"], key=int)
        terms = "".join(f" + {x.label} {vb[x.name]:.1f}" for x in CODECS if vb.get(x.name))
        lines.append(f"  bits per vertex at level {top}: positions {vb['positions'][top]:.1f}{terms} = "
                     f"{vb['total'][top]:.1f}")
    return lines


def format_container(d: dict, *, timings: dict | None = None, max_parts: int = 20) -> str:
    """``describe_container``'s record as the text ``inspect`` and ``cook`` print: the file, its
    minimum levels and sections, the LOD chains (``_lod_lines``), the memory table, storage
    figures, LOD warnings, stage timings (``timings``, seconds) and up to ``max_parts`` parts."""
    t = d["totals"]
    size = (f"{d['file_bytes'] or 0:,} of {d['file_size']:,} bytes (a prefix)" if d.get("prefix")
            else f"{d['file_bytes'] or 0:,} bytes")
    lines = [
        f"{d['file']}: {d['format']} by {d['generator']}, {size}, levels 1..{d['available_level']}",
        f"  source {d['source']['file']} ({d['source']['format']}); {plural(t['parts'], 'part')}, "
        f"{plural(t['buffers'], 'buffer')}, {plural(t['vertices'], 'vertex', 'vertices')}, "
        f"{plural(t['triangles'], 'triangle')}; grid extent {d['grid']['extent']:.6g} m",
        "  minimum levels (level:vertices): " + _hist(t["histogram"]),
        "  sections: " + ", ".join(f"{k} {v:,} B" for k, v in sorted(d["section_bytes"].items())),
        *_layout_lines(d, max_parts),
        *_lod_lines(d),
        "",
        *_memory_lines(d),
        *_placement_lines(d),
        *_storage_lines(d, max_parts),
    ]
    for w in d.get("lod_warnings") or []:
        lines.append(f"  LOD warning: {w}")
    if timings:
        lines.append("")
        lines.append("  time: " + ", ".join(f"{k} {v:.3f} s" for k, v in timings.items()))
    if len(d["parts"]) > 1:
        lines.append("")
        for p in d["parts"][:max_parts]:
            e = p["lods"][0]
            lines.append(f"  {p['name'][-48:]:<48} {e['vertices']:>9,} v {e['triangles']:>9,} t  "
                         f"{' '.join(e['attributes'])}")
        if len(d["parts"]) > max_parts:
            lines.append(f"  … {plural(len(d['parts']) - max_parts, 'more part')} (use --json for all)")
    return "\n".join(lines)
