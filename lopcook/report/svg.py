"""Inline SVG charts of the report (no JavaScript, no external resources): memory against PSNR per
level (Meyer et al. 2011, Table 1 as a chart), the minimum-level histogram (coloured as the level
image, paper Fig. 7), the k_f calibration curve, and the byte-budget chart (PSNR against bits per
vertex; Purnomo et al. 2005, Fig. 11).

``Plot`` maps linear x/y axes into a ``w x h`` pixel viewport; a PSNR of None (identical to the
float render, +inf dB) is drawn in a band above the top of the y axis. Every chart is a string
``<svg class="chart" ...>...</svg>``, deterministic for the same input (coordinates to 0.1 px).
"""

from __future__ import annotations

import math

import numpy as np

from .text import escape, fmt_psnr


class Plot:
    """Linear x/y axes into an SVG viewport; ``inf`` (None) y values go to a band at the top."""

    def __init__(self, xlo, xhi, ylo, yhi, w=560, h=320, pad=(56, 20, 28, 44)):
        self.xlo, self.xhi, self.ylo, self.yhi = xlo, xhi, ylo, yhi
        self.w, self.h = w, h
        self.l, self.r, self.t, self.b = pad
        self.parts: list[str] = []

    def x(self, v):
        """SVG x (pixels) of the data value ``v``."""
        return self.l + (v - self.xlo) / (self.xhi - self.xlo or 1) * (self.w - self.l - self.r)

    def y(self, v):
        """SVG y (pixels) of the data value ``v``; None (+inf PSNR) goes to the band 12 pixels above the
        axis top."""
        if v is None:
            return self.t - 12
        return self.h - self.b - (v - self.ylo) / (self.yhi - self.ylo or 1) * (self.h - self.t - self.b)

    def axes(self, xlabel, ylabel, xticks, yticks):
        """Draw the x and y axes with their ticks (data values; None on the y axis is the inf band) and
        labels."""
        p = self.parts
        x0, x1, y0, y1 = self.l, self.w - self.r, self.h - self.b, self.t
        p.append(f'<line x1="{x0}" y1="{y0}" x2="{x1}" y2="{y0}" stroke="#333"/>')
        p.append(f'<line x1="{x0}" y1="{y0}" x2="{x0}" y2="{y1 - 16}" stroke="#333"/>')
        for v in xticks:
            X = self.x(v)
            p.append(f'<line x1="{X:.1f}" y1="{y0}" x2="{X:.1f}" y2="{y0 + 4}" stroke="#333"/>'
                     f'<text x="{X:.1f}" y="{y0 + 16}" text-anchor="middle">{escape(f"{v:g}")}</text>')
        for v in yticks:
            Y = self.y(v)
            lab = "inf" if v is None else f"{v:g}"
            p.append(f'<line x1="{x0 - 4}" y1="{Y:.1f}" x2="{x1}" y2="{Y:.1f}" stroke="#ddd"/>'
                     f'<text x="{x0 - 6}" y="{Y + 4:.1f}" text-anchor="end">{escape(lab)}</text>')
        p.append(f'<text x="{(x0 + x1) / 2:.1f}" y="{self.h - 6}" text-anchor="middle">{escape(xlabel)}</text>')
        p.append(f'<text x="14" y="{(y0 + y1) / 2:.1f}" text-anchor="middle" '
                 f'transform="rotate(-90 14 {(y0 + y1) / 2:.1f})">{escape(ylabel)}</text>')

    def series(self, pts, colour, name, labels=None, dash=""):
        """Draw ``pts`` [(x, y)] as a polyline with round markers in ``colour``, a tooltip per point,
        optional point ``labels`` and an SVG ``dash`` pattern; nothing for an empty list."""
        if not pts:
            return
        d = " ".join(f"{self.x(a):.1f},{self.y(b):.1f}" for a, b in pts)
        da = f' stroke-dasharray="{dash}"' if dash else ""
        self.parts.append(f'<polyline points="{d}" fill="none" stroke="{colour}" stroke-width="1.5"{da}>'
                          f'<title>{escape(name)}</title></polyline>')
        for i, (a, b) in enumerate(pts):
            self.parts.append(f'<circle cx="{self.x(a):.1f}" cy="{self.y(b):.1f}" r="3.5" fill="{colour}">'
                              f'<title>{escape(name)}: {a:.1f} %, {fmt_psnr(b)} dB</title></circle>')
            if labels:
                self.parts.append(f'<text x="{self.x(a) + 5:.1f}" y="{self.y(b) - 5:.1f}" fill="{colour}" '
                                  f'font-size="10">{escape(labels[i])}</text>')

    def svg(self, title, legend=()):
        """The chart as an ``<svg>`` string with ``title`` and a legend of (name, colour) pairs."""
        leg = "".join(f'<rect x="{self.w - 150}" y="{24 + 14 * i}" width="10" height="10" fill="{c}"/>'
                      f'<text x="{self.w - 136}" y="{33 + 14 * i}">{escape(n)}</text>' for i, (n, c) in enumerate(legend))
        return (f'<svg class="chart" viewBox="0 0 {self.w} {self.h}" '
                f'width="{self.w}" height="{self.h}" font-size="11" role="img" aria-label="{escape(title)}">'
                f'<title>{escape(title)}</title>' + "".join(self.parts) + leg + "</svg>")


def ticks(lo, hi, n=6):
    """Round tick values from ``lo`` to ``hi`` (both included when on a step): about ``n`` steps of 1, 2 or
    5 times a power of ten."""
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
    p = Plot(0, 105, ylo, yhi)
    p.axes("position memory, % of float32", "PSNR min over views, dB", ticks(0, 100, 5), ticks(ylo, yhi) + [None])
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


def level_fill(level: int, lo: int, hi: int) -> str:
    """CSS colour of ``level`` on the ramp of the level image (``baselines.level_colours``)."""
    from ..verify.baselines import level_colours

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
                     f'y="{h - b - bh:.1f}" width="{max(bw - 2, 1):.1f}" height="{bh:.1f}" fill="{level_fill(lv, lo, hi)}">'
                     f'<title>level {lv}: {hist[lv]} vertices</title></rect>'
                     f'<text x="{x + bw / 2:.1f}" y="{h - b + 14}" text-anchor="middle">{lv}</text>')
    parts.append(f'<text x="{l - 6}" y="{t + 4}" text-anchor="end">{top}</text>'
                 f'<text x="{(l + w) / 2:.1f}" y="{h - 4}" text-anchor="middle">minimum level (bits per component)'
                 f'</text>')
    return (f'<svg class="chart" viewBox="0 0 {w} {h}" width="{w}" height="{h}" '
            f'font-size="11" role="img" aria-label="minimum-level histogram"><title>minimum-level histogram</title>'
            + "".join(parts) + "</svg>")


def calibration_svg(cal: dict) -> str | None:
    """The k_f calibration curve of a ``--target-psnr`` container (``options.calibration``): CAP memory %
    of float32 against PSNR min per k_f scale, the target as a dashed line; None without a curve."""
    curve = [c for c in (cal or {}).get("curve") or [] if c.get("cap_percent") is not None]
    if not curve:
        return None
    curve = sorted(curve, key=lambda c: c["cap_percent"])
    finite = [c["psnr_min"] for c in curve if c.get("psnr_min") is not None]
    ylo = math.floor((min(finite) if finite else 20) / 5) * 5 - 5
    yhi = math.ceil((max(finite) if finite else 60) / 5) * 5 + 5
    xs = [c["cap_percent"] for c in curve]
    xlo, xhi = max(0.0, min(xs) - 2), max(xs) + 2
    p = Plot(xlo, xhi, ylo, yhi)
    p.axes("CAP memory, % of float32", "PSNR min, dB", ticks(xlo, xhi, 5), ticks(ylo, yhi) + [None])
    if cal.get("target_psnr") is not None and ylo <= cal["target_psnr"] <= yhi:
        Y = p.y(cal["target_psnr"])
        p.parts.append(f'<line x1="{p.l}" y1="{Y:.1f}" x2="{p.w - p.r}" y2="{Y:.1f}" stroke="#2ca02c" '
                       f'stroke-dasharray="4 3"><title>target {cal["target_psnr"]:g} dB</title></line>')
    p.series([(c["cap_percent"], c.get("psnr_min")) for c in curve], "#9467bd", "k_f scale",
             [f"2^{c['log2_sigma']:.2g}" if c.get("log2_sigma") is not None else "" for c in curve])
    return p.svg("k_f calibration: memory vs PSNR", [("CAP over k_f scale", "#9467bd")])


LOD_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")


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
    p = Plot(xlo, xhi, ylo, yhi)
    p.axes("bits per vertex (8 x bytes / vertices)", "PSNR mean over views, dB", ticks(xlo, xhi, 6),
           ticks(ylo, yhi) + [None])
    lods = sorted({c["lod"] for c in cands})
    legend = []
    for i, k in enumerate(lods):
        colour = LOD_COLOURS[i % len(LOD_COLOURS)]
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


__all__ = ["Plot", "ticks", "memory_psnr_svg", "level_fill", "histogram_svg", "calibration_svg", "LOD_COLOURS",
           "budget_svg"]
