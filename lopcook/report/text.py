"""Text formatting shared by the report's HTML and SVG: numbers as the page shows them, escaping."""

from __future__ import annotations

import html


def fmt_pct(x) -> str:
    """A percentage as the page shows it: one decimal, ``-`` for None."""
    return "-" if x is None else f"{x:.1f}"


def fmt_psnr(x) -> str:
    """A PSNR in dB as the page shows it: one decimal, ``inf`` for None (identical images)."""
    return "inf" if x is None else f"{x:.1f}"


def escape(s) -> str:
    """``str(s)`` escaped for HTML text and attribute values (quotes included)."""
    return html.escape(str(s), quote=True)


#: the page's terms, each explained where it first appears (an ``<abbr>`` title, ``term``) and in
#: the "Terms" box under the verdict; the wording follows the README's glossary
TERMS = {
    "level": "bits per coordinate a vertex is drawn with, 1..24: level b is at most "
             "sqrt(3) x extent x 2^-(b+1) metres off its source position",
    "per-buffer level": "the level a renderer picks for a whole buffer from the camera distance: the fewest "
                        "bits whose position error stays under half a pixel (Meyer et al. 2011, section 4)",
    "minimum level": "the fewest bits a vertex may ever have (m_v): its shading error k_f x E_v x dx stays "
                     "under eps, and its depth order against other parts is kept",
    "AP": "adaptive precision: every vertex of a buffer at the per-buffer level. Smallest, but shading and "
          "depth order can break at low levels",
    "CAP": "constrained adaptive precision: each vertex at the larger of the per-buffer level and its minimum "
           "level. What lopcook writes, and what the verdict judges",
    "PSNR": "peak signal-to-noise ratio of a render against the float32 source's render, over object pixels, in "
            "dB; higher is closer, inf = identical; 40 dB is the quality line",
    "view": "one of 20 camera directions on an icosahedron around the object (Purnomo et al. 2005); the report "
            "renders the views given by --views",
    "LOD": "level of detail: a simplified copy of a part with fewer triangles, selected from the camera distance "
           "where its error projects to at most the pixel error. Not a level",
    "k_f": "the shader's slope: change of shaded colour per change of a shading attribute (Phong: specular "
           "coefficient x exponent; a texture: its steepest slope); cook --target-psnr calibrates it",
    "depth-order error": "a pixel where a different part shows than in the float render, away from part "
                         "outlines: parts that swap places in depth",
    "Hausdorff error": "the largest distance between a LOD's surface and LOD 0's, both ways, in metres",
    "float32": "the source's positions as 32-bit floats, 12 bytes per vertex: the reference every render is "
               "compared with",
}


def term(name: str, text: str | None = None) -> str:
    """``text`` (default ``name``) as HTML with the term's explanation (``TERMS``) as its tooltip:
    ``<abbr title="...">AP</abbr>``."""
    return f'<abbr title="{escape(TERMS[name])}">{escape(text or name)}</abbr>'


def plural(n: int, one: str, many: str | None = None) -> str:
    """``n`` with thousands separators and the noun in the right number: ``1 vertex``, ``3 vertices``."""
    return f"{n:,} {one if n == 1 else (many or one + 's')}"


def _pairs(pairs) -> list[str]:
    return [f"{a} and {b}" for a, b in pairs]


def warning_groups(w: dict) -> list[dict]:
    """The report's warnings (``report.json`` ``warnings``) grouped and worded for a reader: a list of
    ``{"id", "title", "summary", "items"}`` (``items``: the individual lines under the summary, e.g.
    the part pairs as "A and B", or identical import warnings once each with a count), in a fixed
    order: import, touching parts, intersecting parts, degenerate triangles, attribute precision.
    Empty when there is nothing to say. No Python reprs: every line is a sentence or a name pair."""
    groups = []
    scene = [str(x) for x in w.get("scene") or []]
    if scene:
        counts: dict[str, int] = {}
        for x in scene:
            counts[x] = counts.get(x, 0) + 1
        items = [x if n == 1 else f"{x} ({n} times)" for x, n in counts.items()]
        groups.append({"id": "import", "title": "Import",
                       "summary": f"The importer reported {plural(len(scene), 'warning')}:", "items": items})
    ceiling = w.get("depth_ceiling")
    at = f"level {ceiling}" if ceiling is not None else "the depth ceiling"
    if w.get("touching"):
        n = len(w["touching"])
        capped = w.get("depth_capped") or 0
        text = (f"{plural(n, 'pair')} of parts touch: " + (
            f"{plural(capped, 'vertex', 'vertices')} where they meet would need more than {at} to keep their "
            f"depth order, so their level is capped at {at} and the parts may show through each other there "
            "at close range." if capped else "their depth order may not be kept where they meet."))
        groups.append({"id": "touching", "title": "Parts that touch", "summary": text, "items": _pairs(w["touching"])})
    elif w.get("depth_capped"):
        groups.append({"id": "touching", "title": "Parts that touch",
                       "summary": f"{plural(w['depth_capped'], 'vertex', 'vertices')} lie so close to another "
                                  f"part that their depth constraint is capped at {at}.", "items": []})
    if w.get("intersecting"):
        n = len(w["intersecting"])
        groups.append({"id": "intersecting", "title": "Parts that intersect",
                       "summary": f"{plural(n, 'pair')} of parts intersect (a vertex of one lies behind the "
                                  "nearest face of the other): no precision keeps their depth order where they "
                                  "cross.", "items": _pairs(w["intersecting"])})
    if w.get("degenerate_triangles"):
        n = w["degenerate_triangles"]
        groups.append({"id": "degenerate", "title": "Degenerate triangles",
                       "summary": f"{plural(n, 'zero-area triangle')} {'is' if n == 1 else 'are'} left out of the "
                                  "position error bound (they cover no pixel).", "items": []})
    if w.get("attribute_unsatisfied"):
        n = w["attribute_unsatisfied"]
        groups.append({"id": "attribute", "title": "Attribute precision",
                       "summary": f"{plural(n, 'vertex', 'vertices')} need{'s' if n == 1 else ''} more than 24 bits "
                                  f"for {'its' if n == 1 else 'their'} attribute error; "
                                  f"{'it is' if n == 1 else 'they are'} stored at full precision (24 bits).",
                       "items": []})
    return groups


__all__ = ["TERMS", "fmt_pct", "fmt_psnr", "escape", "term", "plural", "warning_groups"]
