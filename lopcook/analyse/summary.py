"""Summaries of an Analysis for the CLI (text) and for JSON (``lopcook analyse --json``)."""

from __future__ import annotations

import numpy as np

from ..version import __version__
from ..grid import BITS
from .result import REASON_CLASS, REASONS, Analysis


def describe_analysis(an: Analysis, source: str) -> dict:
    """Plain-data summary: grid, per-part level histogram (index = level 0..24) and reason counts."""
    parts = []
    for name, p in zip(an.part_names, an.parts):
        reasons = p.reason_counts()
        classes: dict = {}
        for k, v in reasons.items():
            classes[REASON_CLASS[k]] = classes.get(REASON_CLASS[k], 0) + v
        parts.append({
            "name": name,
            "vertices": int(p.min_level.size),
            "histogram": p.histogram().tolist(),
            "mean_level": float(np.mean(p.min_level)) if p.min_level.size else 0.0,
            "max_level": int(p.min_level.max()) if p.min_level.size else 0,
            "reasons": reasons,
            "reason_classes": classes,
            "kf": {k: float(v) for k, v in p.kf.items()},
            "max_e_v": {k: float(v.max()) if v.size else 0.0 for k, v in p.e_v.items()},
            "degenerate_triangles": p.degenerate_triangles,
            "attribute_unsatisfied": p.attribute_unsatisfied,
            "depth_capped": p.depth_capped,
        })
    hist = an.histogram()
    n = int(hist.sum())
    return {
        "generator": f"lopcook {__version__}",
        "kind": "analysis",
        "file": source,
        "grid": {"origin_m": list(an.grid.origin), "extent_m": an.grid.extent, "bits": an.grid.bits,
                 "dx_m": [float(an.grid.dx(b)) for b in range(1, BITS + 1)]},
        "settings": an.settings.to_record(),
        "totals": {
            "parts": len(parts),
            "vertices": n,
            "histogram": hist.tolist(),
            "mean_level": float((hist * np.arange(BITS + 1)).sum() / max(n, 1)),
            "reasons": an.reason_counts(),
            "degenerate_triangles": sum(p["degenerate_triangles"] for p in parts),
            "attribute_unsatisfied": sum(p["attribute_unsatisfied"] for p in parts),
            "depth_capped": sum(p["depth_capped"] for p in parts),
            "colocated_raised": an.colocated_raised,
        },
        "touching": [list(t) for t in an.touching],
        "intersecting": [list(t) for t in an.intersecting],
        "timings_s": {k: float(v) for k, v in an.timings.items()},
        "parts": parts,
    }


def _hist_line(hist) -> str:
    nz = [b for b in range(1, BITS + 1) if hist[b]]
    if not nz:
        return "(empty)"
    return " ".join(f"{b}:{hist[b]}" for b in range(nz[0], nz[-1] + 1))


def format_analysis(d: dict, max_parts: int = 40) -> str:
    t = d["totals"]
    r = t["reasons"]
    g = d["grid"]
    lines = [
        f"{d['file']}: {t['parts']} parts, {t['vertices']:,} vertices, grid extent {g['extent_m']:.6g} m "
        f"(dx(10) = {g['dx_m'][9]:.3g} m), mean minimum level {t['mean_level']:.2f} bits",
        "  minimum level histogram (level:vertices): " + _hist_line(t["histogram"]),
        "  constrained by: " + ", ".join(f"{k} {r.get(k, 0):,}" for k in REASONS),
        f"  degenerate triangles excluded: {t['degenerate_triangles']:,}; attribute bound unreachable at 24 bits: "
        f"{t['attribute_unsatisfied']:,}; depth capped at {d['settings']['depth_ceiling']}: {t['depth_capped']:,}",
    ]
    if d["touching"]:
        lines.append(f"  touching parts (depth capped): {len(d['touching'])} pairs, e.g. "
                     + "; ".join(f"{a} | {b}" for a, b in d["touching"][:3]))
    if d["intersecting"]:
        lines.append(f"  intersecting parts: {len(d['intersecting'])} pairs, e.g. "
                     + "; ".join(f"{a} | {b}" for a, b in d["intersecting"][:3]))
    lines.append("  time: " + ", ".join(f"{k} {v:.3f} s" for k, v in d["timings_s"].items()))
    lines.append("")
    lines.append(f"  {'part':<40} {'verts':>8} {'mean':>5} {'max':>3} {'attr':>8} {'depth':>7}  levels")
    for p in d["parts"][:max_parts]:
        name = p["name"] if len(p["name"]) <= 40 else "…" + p["name"][-39:]
        rc = p["reason_classes"]
        lines.append(f"  {name:<40} {p['vertices']:>8,} {p['mean_level']:>5.1f} {p['max_level']:>3} "
                     f"{rc.get('attribute', 0):>8,} {rc.get('depth', 0):>7,}  {_hist_line(p['histogram'])}")
    if len(d["parts"]) > max_parts:
        lines.append(f"  … {len(d['parts']) - max_parts} more parts (use --json for all)")
    return "\n".join(lines)
