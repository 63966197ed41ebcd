"""Describe a source scene for ``lopcook inspect``: parts, counts, attributes, bounds, defects.

The JSON form (``describe_scene``) is a stable interface, validated by
``schema/inspect.source.schema.json`` and documented in ``docs/cli.md``.
"""

from __future__ import annotations


from ..version import __version__
from ..mesh import degenerate_triangles, duplicated_positions
from ..types import Scene


def _r(x: float) -> float:
    """Round for display/JSON: 9 significant digits (sub-micrometre for metre-scale scenes)."""
    return float(f"{float(x):.9g}")


def describe_scene(scene: Scene) -> dict:
    """Summary of a Scene as plain JSON-able data (lengths in metres)."""
    parts = []
    for p in scene.parts:
        lo, hi = p.positions.min(axis=0), p.positions.max(axis=0)
        parts.append({
            "name": p.name,
            "source": p.source,
            "mesh_key": p.mesh_key,
            "vertices": p.n_vertices,
            "triangles": p.n_triangles,
            "normals": None if p.normals is None else ("computed" if p.normals_computed else "source"),
            "uvs": p.uvs is not None,
            "colors": p.colors is not None,
            "texture": None if p.texture is None else p.texture.name,
            "double_sided": bool(p.double_sided),
            "bounds_m": [[_r(v) for v in lo], [_r(v) for v in hi]],
            "degenerate_triangles": degenerate_triangles(p.positions, p.indices),
            "duplicated_positions": duplicated_positions(p.positions),
        })
    b = scene.bounds()
    return {
        "generator": f"lopcook {__version__}",
        "kind": "source",
        "file": scene.source,
        "format": scene.format,
        "unit_scale_m": _r(scene.unit_scale),
        "up_axis": scene.up_axis,
        "bounds_m": [[_r(v) for v in b[0]], [_r(v) for v in b[1]]],
        "extent_m": [_r(v) for v in (b[1] - b[0])],
        "totals": {
            "parts": len(scene.parts),
            "distinct_meshes": len({p.mesh_key or p.name for p in scene.parts}),
            "vertices": scene.n_vertices,
            "triangles": scene.n_triangles,
            "degenerate_triangles": sum(q["degenerate_triangles"] for q in parts),
            "duplicated_positions": sum(q["duplicated_positions"] for q in parts),
            "parts_with_uvs": sum(q["uvs"] for q in parts),
            "parts_with_computed_normals": sum(q["normals"] == "computed" for q in parts),
        },
        "parts": parts,
        "warnings": list(scene.warnings),
    }


def attribute_labels(q: dict, texture: str = "tex={}") -> list[str]:
    """Short labels of a part's attributes in ``describe_scene``'s record: ``N`` (``N*`` when
    lopcook computed the normals), ``UV``, ``C`` (colours), the texture (``texture`` formats its
    name) and ``2S`` for a double-sided surface."""
    attrs = []
    if q["normals"]:
        attrs.append("N*" if q["normals"] == "computed" else "N")
    if q["uvs"]:
        attrs.append("UV")
    if q["colors"]:
        attrs.append("C")
    if q["texture"]:
        attrs.append(texture.format(q["texture"]))
    if q.get("double_sided"):
        attrs.append("2S")
    return attrs


def format_scene(d: dict, max_parts: int = 40) -> str:
    """Human-readable table of ``describe_scene`` output."""
    t = d["totals"]
    ext = " x ".join(f"{v:.4g}" for v in d["extent_m"])
    lines = [
        f"{d['file']}  ({d['format']}, up {d['up_axis']}, {d['unit_scale_m']:g} m/unit)",
        f"  {t['parts']} part{'' if t['parts'] == 1 else 's'} ({t['distinct_meshes']} distinct "
        f"mesh{'' if t['distinct_meshes'] == 1 else 'es'}), {t['vertices']:,} vertices, "
        f"{t['triangles']:,} triangles, extent {ext} m",
        f"  degenerate triangles: {t['degenerate_triangles']:,}   duplicated positions: {t['duplicated_positions']:,}",
        "",
        f"  {'part':<40} {'vertices':>10} {'triangles':>10}  attributes",
    ]
    for q in d["parts"][:max_parts]:
        attrs = attribute_labels(q)
        name = q["name"] if len(q["name"]) <= 40 else "…" + q["name"][-39:]
        lines.append(f"  {name:<40} {q['vertices']:>10,} {q['triangles']:>10,}  {' '.join(attrs)}")
    if len(d["parts"]) > max_parts:
        lines.append(f"  … {len(d['parts']) - max_parts} more parts (use --json for all)")
    if any(q["normals"] == "computed" for q in d["parts"][:max_parts]):
        lines.append("  (N* = normals computed by lopcook: area-weighted, split at creases)")
    if any(q.get("double_sided") for q in d["parts"][:max_parts]):
        lines.append("  (2S = double-sided: verify and report draw both sides; other parts' back faces are culled)")
    for w in d["warnings"]:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)


__all__ = ["describe_scene", "format_scene", "attribute_labels"]
