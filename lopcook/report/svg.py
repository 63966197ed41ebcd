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

from ..verify.baselines import level_colours
from ..verify.metrics import colormap
from .model import fraction_text
from .text import escape, fmt_psnr


#: chart font size (px) and point-label font size
FONT = 11
LABEL_FONT = 10
#: marker radius (px)
MARKER_R = 3.5


class Plot:
    """Linear x/y axes into an SVG viewport; ``inf`` (None) y values go to a band at the top."""

    def __init__(self, xlo, xhi, ylo, yhi, w=560, h=320, pad=(56, 20, 28, 44)):
        self.xlo, self.xhi, self.ylo, self.yhi = xlo, xhi, ylo, yhi
        self.w, self.h = w, h
        self.l, self.r, self.t, self.b = pad
        self.parts: list[str] = []
        #: boxes (x0, y0, x1, y1) of placed point labels, markers and fixed texts (axes), for ``place_label``
        self.labels: list[tuple] = []
        self.markers: list[tuple] = []
        self.fixed: list[tuple] = []
        self.pending: list = []

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
            self.fixed.append(text_box(X, y0 + 16, f"{v:g}", FONT, "middle"))
        for v in yticks:
            Y = self.y(v)
            lab = "inf" if v is None else f"{v:g}"
            p.append(f'<line x1="{x0 - 4}" y1="{Y:.1f}" x2="{x1}" y2="{Y:.1f}" stroke="#ddd"/>'
                     f'<text x="{x0 - 6}" y="{Y + 4:.1f}" text-anchor="end">{escape(lab)}</text>')
            self.fixed.append(text_box(x0 - 6, Y + 4, lab, FONT, "end"))
        p.append(f'<text x="{(x0 + x1) / 2:.1f}" y="{self.h - 6}" text-anchor="middle">{escape(xlabel)}</text>')
        self.fixed.append(text_box((x0 + x1) / 2, self.h - 6, xlabel, FONT, "middle"))
        p.append(f'<text x="14" y="{(y0 + y1) / 2:.1f}" text-anchor="middle" '
                 f'transform="rotate(-90 14 {(y0 + y1) / 2:.1f})">{escape(ylabel)}</text>')

    def series(self, pts, colour, name, labels=None, dash=""):
        """Draw ``pts`` [(x, y)] as a polyline with round markers in ``colour``, a tooltip per point,
        optional point ``labels`` (placed by ``place_label``: points whose markers overlap share one
        label, e.g. "6-8", and no label overlaps another text, marker or the plot's edge; a label
        with no free place is left out, its point keeps its tooltip) and an SVG ``dash`` pattern;
        nothing for an empty list."""
        if not pts:
            return
        d = " ".join(f"{self.x(a):.1f},{self.y(b):.1f}" for a, b in pts)
        da = f' stroke-dasharray="{dash}"' if dash else ""
        self.parts.append(f'<polyline points="{d}" fill="none" stroke="{colour}" stroke-width="1.5"{da}>'
                          f'<title>{escape(name)}</title></polyline>')
        for a, b in pts:
            X, Y = self.x(a), self.y(b)
            self.markers.append((X - MARKER_R, Y - MARKER_R, X + MARKER_R, Y + MARKER_R))
            self.parts.append(f'<circle cx="{X:.1f}" cy="{Y:.1f}" r="{MARKER_R}" fill="{colour}">'
                              f'<title>{escape(name)}: {a:.1f} %, {fmt_psnr(b)} dB</title></circle>')
        if labels:
            self.pending.append((pts, labels, colour))

    def _place_labels(self):
        """Place the pending series labels (``series``) once every marker is known."""
        for pts, labels, colour in self.pending:
            groups: list[list[int]] = []
            for i, (a, b) in enumerate(pts):
                X, Y = self.x(a), self.y(b)
                if groups:
                    j = groups[-1][-1]
                    if math.hypot(X - self.x(pts[j][0]), Y - self.y(pts[j][1])) < 2 * MARKER_R + 1:
                        groups[-1].append(i)
                        continue
                groups.append([i])
            for g in groups:
                text = group_label([labels[i] for i in g])
                X = sum(self.x(pts[i][0]) for i in g) / len(g)
                Y = sum(self.y(pts[i][1]) for i in g) / len(g)
                self.place_label(X, Y, text, colour)
        self.pending = []

    def place_label(self, X, Y, text, colour, font_size=LABEL_FONT):
        """Put ``text`` near the point (X, Y): the first of the candidate offsets (nearest first; right of
        the point first, then the other seven directions) whose box (``text_box``) stays inside the
        chart and overlaps no placed label, no marker and no axis text. Returns the box, or None when
        no candidate is free (left out)."""
        width, fs = text_width(text, font_size), float(font_size)
        for dist in (4, 8, 13, 19, 27):
            for ux, uy in ((1, 0), (1, -1), (1, 1), (-1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1)):
                x = X + dist if ux > 0 else X - dist - width if ux < 0 else X - width / 2
                y = (Y - dist - 0.25 * fs) if uy < 0 else (Y + dist + 0.8 * fs) if uy > 0 else (Y + 0.275 * fs)
                box = text_box(x, y, text, font_size)
                if box[0] < self.l + 2 or box[2] > self.w - 2 or box[1] < 1 or box[3] > self.h - self.b - 1:
                    continue
                if any(overlaps(box, o) for o in self.labels + self.markers + self.fixed):
                    continue
                self.labels.append(box)
                self.parts.append(f'<text class="point-label" x="{x:.1f}" y="{y:.1f}" fill="{colour}" '
                                  f'font-size="{font_size}">{escape(text)}</text>')
                return box
        return None

    def svg(self, title, legend=()):
        """The chart as an ``<svg>`` string with ``title`` and a legend of (name, colour) pairs in rows
        below the x axis label (never over the data)."""
        self._place_labels()
        items, x, row = [], self.l, 0
        for n, c in legend:
            width = 14 + text_width(n, FONT) + 16
            if x + width > self.w - 4 and x > self.l:
                x, row = self.l, row + 1
            y = self.h + 6 + 16 * row
            items.append(f'<rect x="{x:.1f}" y="{y}" width="10" height="10" fill="{c}"/>'
                         f'<text class="legend" x="{x + 14:.1f}" y="{y + 9}">{escape(n)}</text>')
            x += width
        height = self.h + (16 * (row + 1) + 8 if legend else 0)
        return (f'<svg class="chart" viewBox="0 0 {self.w} {height}" '
                f'width="{self.w}" height="{height}" font-size="{FONT}" role="img" aria-label="{escape(title)}">'
                f'<title>{escape(title)}</title>' + "".join(self.parts) + "".join(items) + "</svg>")




def text_width(text: str, font_size: float) -> float:
    """An upper estimate of the rendered width (px) of ``text`` in a sans-serif font: 0.62 em per
    character (digits and lower case are about 0.55 em)."""
    return 0.62 * font_size * len(str(text))


def text_box(x: float, y: float, text: str, font_size: float, anchor: str = "start") -> tuple:
    """(x0, y0, x1, y1) of ``text`` drawn at baseline (x, y) with ``anchor`` (start, middle, end):
    from 0.8 em above the baseline to 0.25 em below, ``text_width`` wide."""
    w = text_width(text, font_size)
    x0 = x - (w / 2 if anchor == "middle" else w if anchor == "end" else 0.0)
    return (x0, y - 0.8 * font_size, x0 + w, y + 0.25 * font_size)


def overlaps(a, b) -> bool:
    """Whether the boxes ``a`` and ``b`` (x0, y0, x1, y1) share interior area."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def group_label(labels: list[str]) -> str:
    """One label for points drawn on top of each other: "6", "6-8" (consecutive integers) or "6,9"."""
    if len(labels) == 1:
        return labels[0]
    try:
        v = [int(x) for x in labels]
    except ValueError:
        return ",".join(labels)
    return f"{v[0]}-{v[-1]}" if v == list(range(v[0], v[0] + len(v))) else ",".join(labels)


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
    r, g, b, _ = (np.asarray(level_colours(np.array([level]), lo, hi))[0] * 255.0 + 0.5).astype(int)
    return f"#{r:02x}{g:02x}{b:02x}"


def histogram_svg(hist: list[int], log: bool = False) -> str:
    """Bars per minimum level, coloured as the level image (``levels``): its legend. ``log``: bar
    heights proportional to ``log10(1 + count)`` with ticks at powers of ten (a level holding a few
    vertices next to one holding millions stays visible), else to the count with round ticks."""
    nz = [b for b in range(1, len(hist)) if hist[b]]
    lo, hi = (nz[0], nz[-1]) if nz else (1, 24)
    top = max(hist) or 1
    w, h, l, b, t = 560, 220, 64, 36, 16

    def height(n):
        if log:
            return (h - b - t) * math.log10(1 + n) / math.log10(1 + top)
        return (h - b - t) * n / top

    bw = (w - l - 10) / (hi - lo + 1)
    parts = [f'<line x1="{l}" y1="{h - b}" x2="{w - 10}" y2="{h - b}" stroke="#333"/>'
             f'<line x1="{l}" y1="{h - b}" x2="{l}" y2="{t}" stroke="#333"/>']
    yt = [10 ** k for k in range(0, int(math.floor(math.log10(top))) + 1)] if log else \
        [v for v in ticks(0, top, 4) if v == int(v)]
    for v in [0] + [x for x in yt if x >= 10] if log else yt:
        Y = h - b - height(v)
        parts.append(f'<line x1="{l - 4}" y1="{Y:.1f}" x2="{w - 10}" y2="{Y:.1f}" stroke="#eee"/>'
                     f'<text class="tick" x="{l - 6}" y="{Y + 4:.1f}" text-anchor="end">{int(v):,}</text>')
    for i, lv in enumerate(range(lo, hi + 1)):
        bh = height(hist[lv])
        x = l + i * bw
        parts.append(f'<rect class="bar" data-level="{lv}" data-count="{hist[lv]}" x="{x + 1:.1f}" '
                     f'y="{h - b - bh:.1f}" width="{max(bw - 2, 1):.1f}" height="{bh:.1f}" '
                     f'fill="{level_fill(lv, lo, hi)}">'
                     f'<title>level {lv}: {hist[lv]:,} vertices</title></rect>'
                     f'<text x="{x + bw / 2:.1f}" y="{h - b + 14}" text-anchor="middle">{lv}</text>')
    scale = "log" if log else "linear"
    parts.append(f'<text x="{(l + w) / 2:.1f}" y="{h - 4}" text-anchor="middle">minimum level (bits per component)'
                 f'</text><text x="14" y="{(h - b + t) / 2:.1f}" text-anchor="middle" '
                 f'transform="rotate(-90 14 {(h - b + t) / 2:.1f})">vertices ({scale} scale)</text>')
    return (f'<svg class="chart hist-{scale}" viewBox="0 0 {w} {h}" width="{w}" height="{h}" data-scale="{scale}" '
            f'font-size="11" role="img" aria-label="minimum-level histogram, {scale} scale">'
            f'<title>minimum-level histogram ({scale} scale)</title>' + "".join(parts) + "</svg>")


def heatmap_scale_svg(vmax: float, steps: int = 64) -> str:
    """The heat maps' colour scale (``lopcook.verify.metrics.colormap``): a strip of ``steps`` colours
    from 0 to ``vmax`` (the largest channel difference per pixel, colour units 0..1; ``vmax`` and above
    is white), ticks with the difference as a fraction and in 8-bit codes, and the background swatch."""
    w, h, l, r, top, sh = 480, 58, 16, 110, 4, 16
    sw = (w - l - r) / steps
    cols = colormap((np.arange(steps) + 0.5) / steps)
    parts = [f'<rect class="ramp" x="{l + i * sw:.2f}" y="{top}" width="{sw + 0.05:.2f}" height="{sh}" '
             f'fill="#{c[0]:02x}{c[1]:02x}{c[2]:02x}"/>' for i, c in enumerate(cols)]
    for k in range(6):
        f = k / 5
        X = l + f * (w - l - r)
        v = f * vmax
        lab = f"{v:.2f}" + ("+" if k == 5 else "")
        parts.append(f'<line x1="{X:.1f}" y1="{top + sh}" x2="{X:.1f}" y2="{top + sh + 4}" stroke="#333"/>'
                     f'<text class="tick" data-value="{v:g}" x="{X:.1f}" y="{top + sh + 15}" '
                     f'text-anchor="middle">{lab}</text>')
    parts.append(f'<rect x="{w - r + 14}" y="{top}" width="{sh}" height="{sh}" fill="#181818"/>'
                 f'<text x="{w - r + 34}" y="{top + 12}">background</text>'
                 f'<text x="{l}" y="{h - 4}">largest channel difference per pixel, colour units '
                 f'(x255: 8-bit codes); {vmax:g}+ is white</text>')
    return (f'<svg class="chart heat-scale" viewBox="0 0 {w} {h}" width="{w}" height="{h}" font-size="10" '
            f'role="img" aria-label="heat map colour scale"><title>heat map colour scale: 0 (black) to {vmax:g} '
            f'and above (white)</title>' + "".join(parts) + "</svg>")


def _memory_percent(v) -> float | None:
    """A calibration probe's CAP memory (% of float32) as one number: the record holds one value per
    calibrated level (``lopcook.tune.calibrate.probe``), the chart plots the largest (the finest level's
    buffers); an older record's single number is taken as it is."""
    if isinstance(v, (list, tuple)):
        vals = [float(x) for x in v if x is not None]
        return max(vals) if vals else None
    return None if v is None else float(v)


def calibration_svg(cal: dict) -> str | None:
    """The k_f calibration curve of a ``--target-psnr`` container (``options.calibration``): CAP memory %
    of float32 (the largest over the calibrated levels, ``_memory_percent``) against PSNR min (over the
    levels each probe rendered) per k_f scale, the target as a dashed line; None without a curve."""
    curve = [dict(c, cap_percent=_memory_percent(c.get("cap_percent"))) for c in (cal or {}).get("curve") or []]
    curve = [c for c in curve if c["cap_percent"] is not None]
    if not curve:
        return None
    curve = sorted(curve, key=lambda c: c["cap_percent"])
    finite = [c["psnr_min"] for c in curve if c.get("psnr_min") is not None]
    ylo = math.floor((min(finite) if finite else 20) / 5) * 5 - 5
    yhi = math.ceil((max(finite) if finite else 60) / 5) * 5 + 5
    xs = [c["cap_percent"] for c in curve]
    xlo, xhi = max(0.0, min(xs) - 2), max(xs) + 2
    p = Plot(xlo, xhi, ylo, yhi)
    p.axes("CAP memory, % of float32 (largest over the levels)", "PSNR min, dB", ticks(xlo, xhi, 5),
           ticks(ylo, yhi) + [None])
    if cal.get("target_psnr") is not None and ylo <= cal["target_psnr"] <= yhi:
        Y = p.y(cal["target_psnr"])
        p.parts.append(f'<line x1="{p.l}" y1="{Y:.1f}" x2="{p.w - p.r}" y2="{Y:.1f}" stroke="#2ca02c" '
                       f'stroke-dasharray="4 3"><title>target {cal["target_psnr"]:g} dB</title></line>')
    p.series([(c["cap_percent"], c.get("psnr_min")) for c in curve], "#9467bd", "k_f scale",
             [f"2^{c['log2_sigma']:.2g}" if c.get("log2_sigma") is not None else "" for c in curve])
    return p.svg("k_f calibration: memory vs PSNR", [("CAP over k_f scale", "#9467bd")])


def attribute_search_svg(search: dict) -> str | None:
    """The attribute search's probes (``options.attribute_search.probes``): image error as PSNR
    (the search's statistic, worst level, dB) against bits per vertex at level 11, Purnomo et al.
    2005 Fig. 11; the start (the default bits) as a square, the choice ringed, the goal dashed (a
    vertical line for a budget, a horizontal one for a target). None without probes."""
    probes = [q for q in (search or {}).get("probes") or [] if q.get("objective_db") is not None]
    if not probes:
        return None
    ys = [min(q["objective_db"], 150.0) for q in probes]
    xs = [q["bits_per_vertex"] for q in probes]
    goal = float(search["goal"])
    ylo = math.floor(min(ys) / 5) * 5 - 5
    yhi = math.ceil(max(ys + ([goal] if search["mode"] == "target" else [])) / 5) * 5 + 5
    xlo = max(0.0, math.floor(min(xs + ([goal] if search["mode"] == "budget" else [])) / 8) * 8 - 4)
    xhi = max(xs + ([goal] if search["mode"] == "budget" else [])) + 6
    p = Plot(xlo, xhi, ylo, yhi)
    p.axes(f"bits per vertex at level {search.get('level', 11)}", f"PSNR {search['statistic']} (worst level), dB",
           ticks(xlo, xhi, 6), ticks(ylo, yhi) + [None])
    if search["mode"] == "budget":
        X = p.x(goal)
        p.parts.append(f'<line x1="{X:.1f}" y1="{p.t}" x2="{X:.1f}" y2="{p.h - p.b}" stroke="#2ca02c" '
                       f'stroke-dasharray="4 3"><title>budget {goal:g} bits per vertex</title></line>')
    else:
        Y = p.y(goal)
        p.parts.append(f'<line x1="{p.l}" y1="{Y:.1f}" x2="{p.w - p.r}" y2="{Y:.1f}" stroke="#2ca02c" '
                       f'stroke-dasharray="4 3"><title>target {goal:g} dB</title></line>')
    for q, x, y in zip(probes, xs, ys):
        p.parts.append(f'<circle class="probe" cx="{p.x(x):.1f}" cy="{p.y(y):.1f}" r="{MARKER_R}" fill="#1f77b4">'
                       f'<title>{q.get("step") or "probe"}: {x:.2f} bits/vertex, {y:.2f} dB</title></circle>')
    start = probes[0]
    sx, sy = p.x(start["bits_per_vertex"]), p.y(min(start["objective_db"], 150.0))
    p.parts.append(f'<rect class="start" x="{sx - 6:.1f}" y="{sy - 6:.1f}" width="12" height="12" fill="none" '
                   f'stroke="#d62728" stroke-width="2"><title>start: the default bits</title></rect>')
    ch = search["choice"]
    chosen = [q for q in probes if q["allocation"] == ch]
    if chosen:
        c = chosen[0]
        p.parts.append(f'<circle class="chosen" cx="{p.x(c["bits_per_vertex"]):.1f}" '
                       f'cy="{p.y(min(c["objective_db"], 150.0)):.1f}" r="8" fill="none" stroke="#000" '
                       f'stroke-width="2"><title>chosen: {c["bits_per_vertex"]:.2f} bits/vertex</title></circle>')
    return p.svg("attribute search: image error against bits per vertex",
                 [("probes", "#1f77b4"), ("start (square)", "#d62728"), ("chosen (ring)", "#000")])


def _budget_lod(b: dict, k: int) -> str:
    """A budget candidate's LOD in the chart's legend: ``LOD 2 (1/4)``, the share of the fit chain's
    LOD 0 triangles (``lopcook.report.model.fraction_text``), or ``LOD 2`` when not recorded."""
    lods = {int(x["lod"]): x for x in b.get("lods") or []}
    if k in lods and 0 in lods:
        return f"LOD {k} ({fraction_text(int(lods[k]['triangles']), int(lods[0]['triangles']))})"
    return f"LOD {k}"


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
        name = _budget_lod(b, k)
        p.series([(c["bits_per_vertex"], c["psnr_mean"]) for c in series], colour, name,
                 [str(c["level"]) for c in series])
        legend.append((name, colour))
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


__all__ = ["Plot", "FONT", "LABEL_FONT", "MARKER_R", "text_width", "text_box", "overlaps", "group_label", "ticks",
           "memory_psnr_svg", "level_fill", "histogram_svg", "heatmap_scale_svg", "calibration_svg", "attribute_search_svg", "LOD_COLOURS",
           "budget_svg"]
