"""SVG charts of the report (lopcook.report.svg): axis mapping, ticks, the histogram's bars and the
infinite-PSNR band. No GL."""

from __future__ import annotations

import re

import numpy as np
import pytest

from lopcook.report import svg as S


def test_plot_maps_the_axes_linearly_and_inf_to_the_top_band():
    p = S.Plot(0, 100, 20, 60, w=560, h=320, pad=(56, 20, 28, 44))
    assert p.x(0) == 56 and p.x(100) == 560 - 20 and p.x(50) == pytest.approx((56 + 540) / 2)
    assert p.y(20) == 320 - 44 and p.y(60) == 28 and p.y(40) == pytest.approx((276 + 28) / 2)
    assert p.y(None) == 28 - 12  # above the axis top: the inf band


def test_ticks_are_round_steps_inside_the_range():
    assert S.ticks(0, 100, 5) == [0, 20, 40, 60, 80, 100]
    assert S.ticks(15, 65) == [20, 30, 40, 50, 60]
    assert S.ticks(0.0, 1.0, 4) == [0.0, 0.5, 1.0]
    assert S.ticks(3, 3) == [3]


def test_histogram_bars_are_proportional_to_the_counts():
    hist = [0] * 25
    hist[5], hist[6], hist[8] = 10, 40, 20
    text = S.histogram_svg(hist)
    bars = {int(lv): (int(n), float(h)) for lv, n, h in
            re.findall(r'<rect class="bar" data-level="(\d+)" data-count="(\d+)" [^>]*height="([\d.]+)"', text)}
    assert sorted(bars) == [5, 6, 7, 8]  # from the lowest to the highest non-empty level
    assert bars[7] == (0, 0.0)
    assert bars[6][1] == pytest.approx(4 * bars[5][1], abs=0.1) == pytest.approx(2 * bars[8][1], abs=0.1)
    fills = re.findall(r'data-level="(\d+)"[^>]*fill="(#[0-9a-f]{6})"', text)
    assert len({f for _, f in fills}) == 4  # one colour per level on the level ramp
    assert dict(fills)["5"] == S.level_fill(5, 5, 8)


def test_memory_psnr_chart_draws_every_level_and_the_float32_point():
    rep = {"levels": [{"level": 6, "ap": {"percent_of_float32": 25.0, "psnr_min": 30.0},
                       "cap": {"percent_of_float32": 40.0, "psnr_min": 50.0}},
                      {"level": 7, "ap": {"percent_of_float32": 29.2, "psnr_min": 36.0},
                       "cap": {"percent_of_float32": 44.0, "psnr_min": None}}],
           "baselines": {"uniform16": {"percent_of_float32": 200 / 3, "levels": []}}}
    text = S.memory_psnr_svg(rep)
    assert text.startswith('<svg class="chart"') and text.endswith("</svg>")
    assert text.count("<polyline") == 3  # AP, CAP, float32
    assert "not rendered" in text  # the 16-bit baseline as memory only
    assert "CAP: 44.0 %, inf dB" in text
    assert S.memory_psnr_svg(rep) == text  # deterministic


def test_calibration_chart_needs_a_curve():
    assert S.calibration_svg({}) is None
    cal = {"target_psnr": 40.0, "curve": [{"cap_percent": 30.0, "psnr_min": 35.0, "log2_sigma": 1.0},
                                          {"cap_percent": 40.0, "psnr_min": 45.0, "log2_sigma": 0.0}]}
    text = S.calibration_svg(cal)
    assert "target 40 dB" in text and text.count("<circle") == 2


def test_calibration_chart_of_a_recorded_curve():
    """``cook --target-psnr`` records each probe's CAP memory per calibrated level (a list): the
    chart plots the largest, and the record of a real calibration draws (it raised TypeError)."""
    cal = {"target_psnr": 40.0, "levels": [6, 7, 8], "curve": [
        {"cap_percent": [46.2, 46.1, 46.5], "psnr_min": 38.9, "log2_sigma": -1.5, "levels": [7]},
        {"cap_percent": [50.7, 50.8, 50.9], "psnr_min": 44.9, "log2_sigma": 0.0, "levels": [6, 7, 8]},
        {"cap_percent": [47.9, 47.8, 48.2], "psnr_min": 43.6, "log2_sigma": -1.0, "levels": [6, 7, 8]}]}
    text = S.calibration_svg(cal)
    assert text.count('<circle cx=') == 3 and "target 40 dB" in text
    assert "k_f scale: 46.5 %, 38.9 dB" in text and "k_f scale: 50.9 %, 44.9 dB" in text
    xs = [float(x) for x in re.findall(r'<circle cx="([\d.]+)"', text)]
    assert xs == sorted(xs)  # drawn in order of memory


def _texts(svg: str) -> list[tuple]:
    """(box, text, class) of every unrotated <text> of a chart, boxes from its x, y, font size and
    anchor (S.text_box: an upper estimate of the glyphs' extent)."""
    out = []
    base = float(re.search(r'<svg[^>]*font-size="([\d.]+)"', svg).group(1))
    for attrs, body in re.findall(r"<text([^>]*)>([^<]*)</text>", svg):
        if "transform=" in attrs:
            continue  # the rotated axis label, left of every tick
        a = dict(re.findall(r'([a-z-]+)="([^"]*)"', attrs))
        box = S.text_box(float(a["x"]), float(a["y"]), body, float(a.get("font-size", base)),
                         a.get("text-anchor", "start"))
        out.append((box, body, a.get("class", "")))
    return out


def _crowded_report():
    ap = [(18.8, 25.5), (21.9, 27.9), (25.0, 31.0), (28.1, 33.8), (31.2, 36.5), (34.4, 39.6)]
    cap = [(59.7, 73.8), (59.7, 71.2), (59.7, 68.1), (59.7, 62.0), (59.7, 58.3), (59.7, 55.1)]
    u16 = [55.7, 55.9, 56.2, 52.0, 52.3, 51.8]
    levels = [{"level": 6 + i, "ap": {"percent_of_float32": a[0], "psnr_min": a[1]},
               "cap": {"percent_of_float32": c[0], "psnr_min": c[1]}} for i, (a, c) in enumerate(zip(ap, cap))]
    levels[0]["cap"]["psnr_min"] = None  # identical at one level: the inf band
    return {"levels": levels, "baselines": {"uniform16": {"percent_of_float32": 200 / 3, "levels": [
        {"level": 6 + i, "psnr_min": p} for i, p in enumerate(u16)]}}}


def test_memory_psnr_labels_never_overlap_and_every_level_is_named():
    """Six levels with the 16-bit baseline's points a fraction of a dB apart and CAP at one memory
    size: no two texts of the chart (point labels, ticks, axis label, legend) overlap, no label
    covers a marker, and every level of every series is named (points on top of each other share
    one label such as 6-7)."""
    text = S.memory_psnr_svg(_crowded_report())
    texts = _texts(text)
    for i, (a, ta, _) in enumerate(texts):
        for b, tb, _ in texts[i + 1:]:
            assert not S.overlaps(a, b), (ta, tb, a, b)
    markers = [(float(x) - float(r), float(y) - float(r), float(x) + float(r), float(y) + float(r))
               for x, y, r in re.findall(r'<circle cx="([\d.]+)" cy="([\d.]+)" r="([\d.]+)"', text)]
    labels = [(box, t) for box, t, c in texts if c == "point-label"]
    for box, t in labels:
        assert not any(S.overlaps(box, m) for m in markers), t
        assert 0 <= box[0] and box[2] <= 560 and 0 <= box[1]  # inside the chart
    named = {"#d62728": set(), "#1f77b4": set(), "#7f7f7f": set()}
    for colour, t in re.findall(r'<text class="point-label" [^>]*fill="(#[0-9a-f]{6})"[^>]*>([^<]*)</text>', text):
        for part in t.split(","):
            lo, _, hi = part.partition("-")
            named[colour] |= set(range(int(lo), int(hi or lo) + 1))
    assert all(v == set(range(6, 12)) for v in named.values()), named
    # the legend sits below the plot, not over the data
    legend_top = min(box[1] for box, _, c in texts if c == "legend")
    assert legend_top > max(m[3] for m in markers)


def test_group_label_and_text_boxes():
    assert S.group_label(["6"]) == "6" and S.group_label(["6", "7", "8"]) == "6-8"
    assert S.group_label(["6", "9"]) == "6,9"
    x0, y0, x1, y1 = S.text_box(100, 50, "abcd", 10, "middle")
    assert (x1 - x0) == pytest.approx(4 * 6.2) and (x0 + x1) / 2 == pytest.approx(100) and y0 < 50 < y1
    assert S.overlaps((0, 0, 10, 10), (9, 9, 20, 20)) and not S.overlaps((0, 0, 10, 10), (10, 0, 20, 10))


def test_histogram_log_scale():
    hist = [0] * 25
    hist[5], hist[6], hist[8] = 9, 99999, 999
    lin, log = S.histogram_svg(hist), S.histogram_svg(hist, log=True)
    bars = {int(lv): float(h) for lv, h in
            re.findall(r'<rect class="bar" data-level="(\d+)" [^>]*height="([\d.]+)"', log)}
    full = bars[6]
    assert bars[5] == pytest.approx(full * 1 / 5, abs=0.1)  # log10(1 + 9) / log10(1 + 99999)
    assert bars[8] == pytest.approx(full * 3 / 5, abs=0.1)
    assert re.findall(r'<text class="tick"[^>]*>([\d,]+)</text>', log) == ["0", "10", "100", "1,000", "10,000"]
    lin_bars = dict(re.findall(r'data-level="(\d+)" [^>]*height="([\d.]+)"', lin))
    assert float(lin_bars["5"]) < 0.1  # invisible on the linear scale, a fifth of the chart on the log one
    assert 'data-scale="log"' in log and 'data-scale="linear"' in lin


def test_heatmap_scale_matches_the_colormap():
    from lopcook.verify.metrics import HEATMAP_VMAX, colormap

    text = S.heatmap_scale_svg(HEATMAP_VMAX)
    fills = re.findall(r'<rect class="ramp" [^>]*fill="#([0-9a-f]{6})"', text)
    assert len(fills) == 64
    want = colormap((np.arange(64) + 0.5) / 64)
    assert [tuple(int(f[i:i + 2], 16) for i in (0, 2, 4)) for f in fills] == [tuple(int(v) for v in c) for c in want]
    vals = [float(v) for v in re.findall(r'<text class="tick" data-value="([\d.e-]+)"', text)]
    assert vals[0] == 0.0 and vals[-1] == pytest.approx(HEATMAP_VMAX) and len(vals) == 6
    assert "0.25+" in text and "white" in text
