"""SVG charts of the report (lopcook.report.svg): axis mapping, ticks, the histogram's bars and the
infinite-PSNR band. No GL."""

from __future__ import annotations

import re

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
