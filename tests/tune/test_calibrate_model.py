"""lopcook.tune.calibrate.model_search on analytic PSNR curves (no render): it returns the least
passing grid point (the brute-force answer over the grid) for steep, flat, flattening and
edge-limited curves in far fewer probes than the grid has points, and a flat curve whose every point
passes ends at the low end in a few probes."""

from __future__ import annotations

import math

import pytest

from lopcook.tune import calibrate as C

LO, HI, TOL = -8.0, 8.0, 0.25
GRID = [LO + k * TOL for k in range(int((HI - LO) / TOL) + 1)]


def curves():
    return {
        "steep": lambda x: [50.0 + 6.02 * x, 52.0 + 6.02 * x],
        "flat": lambda x: [56.0 + 1.0 * x, 57.0 + 0.8 * x],
        "flattening": lambda x: [49.6 + 3.1 * x if x > -1.5 else 44.95 + 1.3 * (x + 1.5), 60.0 + 2.0 * x],
        "edge-limited": lambda x: [39.0 + 0.01 * x, 45.0],
    }


def search(curve, target, start=0.0):
    probed = []

    def run(x):
        probed.append(x)
        return {"x": x, "psnr": curve(x)}

    got = C.model_search(run, lambda p: min(p["psnr"]) >= target, LO, HI, TOL, start, lambda p: p["psnr"],
                         [target + C.MODEL_MARGIN_DB] * 2)
    return got, probed


@pytest.mark.parametrize("name", sorted(curves()))
@pytest.mark.parametrize("target", [30.0, 40.0, 46.0])
def test_the_search_finds_the_least_passing_grid_point(name, target):
    curve = curves()[name]
    passing = [x for x in GRID if min(curve(x)) >= target]
    want = passing[0] if passing else None
    got, probed = search(curve, target)
    assert got == want
    assert len(set(probed)) == len(probed)  # no grid point probed twice
    assert len(probed) <= 10  # far below the 65 grid points


def test_a_flat_curve_that_passes_everywhere_ends_at_the_low_end_in_few_probes():
    got, probed = search(curves()["flat"], 40.0)  # 48 dB at the low end
    assert got == LO
    assert probed[-1] == LO and len(probed) <= 4


def test_levels_that_k_f_does_not_move_end_the_walk():
    """A level whose PSNR is exactly the same at two probes (the same renders: edge-limited, or
    identical) sets no bound when it passes, so a curve flat at every level and passing by a hair
    ends at the low end in three probes (the slope's clip alone would walk it down a grid step at
    a time); one that fails there sends the next probe to the top of the range."""
    passing = lambda x: [40.015, 43.36]  # noqa: E731
    got, probed = search(passing, 40.0)
    assert got == LO and probed == [0.0, -0.25, LO]
    flat = [(0.0, [40.015, 43.36]), (-0.25, [40.015, 43.36])]
    assert C._predict(flat, [40.1, 40.1]) == -math.inf  # 40.015 passes 40: within the model's margin
    assert C._predict([(0.0, [39.0, 43.36]), (-0.25, [39.0, 43.36])], [40.1, 40.1]) == math.inf
    # a level that moves still bounds it: the flat one is left out, not the whole prediction
    got = C._predict([(0.0, [40.015, 43.0]), (-0.25, [40.015, 41.5])], [40.1, 40.1])
    assert got == pytest.approx(-0.25 + (40.1 - 41.5) / 6.0)
