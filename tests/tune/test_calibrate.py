"""lopcook.tune.calibrate: the probe (every k_f scaled by sigma = eps divided by sigma), the search
for the least passing sigma (bisection on log2 sigma), the unreachable case and require_reached's
documented error, and bad arguments. Tiny harness: glossy_crease, 2 views at 96 x 54, levels 6
and 8 (each probe is one analysis, one build and 4 renders)."""

from __future__ import annotations

import copy

import pytest

from conftest import FIXTURES
from lopcook.errors import EXIT_BAD_INPUT, EXIT_VERIFY_FAILED, LopcookError
from lopcook.ingest import load
from lopcook.settings import AnalyseSettings
from lopcook.tune import calibrate as C
from lopcook.verify.cameras import select_views
from lopcook.viewing import Viewing

LEVELS = [6, 8]
VIEWS = [0, 10]
RES = (96, 54)
KW = dict(levels=LEVELS, views=VIEWS, resolution=RES, confirm=None, search="kf", log2_range=(-4.0, 4.0))


@pytest.fixture(scope="module")
def scene():
    return load(FIXTURES / "glossy_crease.glb")


@pytest.fixture(scope="module")
def probes(gl, scene):
    """Probes at log2 sigma -4, 0, 4 with the default analysis settings."""
    with C.Harness(scene, RES, cache_float=True) as h:
        return {x: C.probe(scene, AnalyseSettings(), 2.0**x, h, levels=LEVELS, views=VIEWS, viewing=Viewing())
                for x in (-4.0, 0.0, 4.0)}


def test_probe_scales_every_kf_by_sigma(probes):
    base = AnalyseSettings()
    for x, p in probes.items():
        sigma = 2.0**x
        assert p["sigma"] == sigma and p["log2_sigma"] == x
        assert p["eps"] == pytest.approx(base.eps / sigma, rel=1e-15)
        # the paper's Phong k_f = ks * n = 0.5 * 32, scaled
        assert p["kf_normal"] == pytest.approx(sigma * base.ks * base.shininess, rel=1e-15)
        assert len(p["psnr_min_per_level"]) == len(p["cap_bytes"]) == len(LEVELS)


def test_probe_memory_grows_with_sigma(probes):
    # every minimum level is a non-decreasing function of sigma, so CAP bytes are too, per level
    lo, mid, hi = (probes[x]["cap_bytes"] for x in (-4.0, 0.0, 4.0))
    assert all(a <= b <= c for a, b, c in zip(lo, mid, hi))
    assert lo[0] < hi[0]  # the crease's normals do vary: k_f moves bits here


@pytest.fixture(scope="module")
def target(probes):
    """A target between the PSNR at the range's ends, so the search has to bisect."""
    lo, hi = probes[-4.0]["psnr_min"], probes[4.0]["psnr_min"]
    assert lo is not None and hi is not None and hi - lo > 4.0
    return 0.5 * (lo + hi)


@pytest.fixture(scope="module")
def searched(gl, scene, target):
    return C.calibrate(scene, AnalyseSettings(), target_psnr=target, tolerance=0.5, **KW)


def test_search_returns_the_least_passing_sigma_within_tolerance(searched, target):
    r = searched
    assert r["reached"] is True and r["search"] == "kf" and r["confirmation"] is None
    chosen = r["chosen"]
    assert chosen["psnr_min"] is None or chosen["psnr_min"] >= target
    assert r["sigma"] == chosen["sigma"] and r["eps"] == chosen["eps"]
    curve = r["curve"]
    assert [p["log2_sigma"] for p in curve] == sorted(p["log2_sigma"] for p in curve)
    assert 0.0 in [p["log2_sigma"] for p in curve]  # the search starts at the default cook's k_f
    # the model needs fewer probes than a bisection of the range to the same grid (2 ends + 4 halvings)
    assert len(curve) < 2 + 4
    grid = [(p["log2_sigma"] + 4.0) / 0.5 for p in curve]
    assert all(g == round(g) for g in grid)  # every probe on the grid lo + k * tolerance
    # bisection: a failing probe lies within the tolerance below the choice
    below = [p for p in curve if r["log2_sigma"] - 0.5 <= p["log2_sigma"] < r["log2_sigma"]]
    assert below and all(p["psnr_min"] is not None and p["psnr_min"] < target for p in below)
    assert -4.0 < r["log2_sigma"] <= 4.0


def test_calibrated_settings_reproduce_the_chosen_probe(gl, scene, searched):
    s = C.calibrated_settings(AnalyseSettings(), searched)
    assert s.eps == searched["eps"] and s.edge_eps == searched["edge_eps"]
    with C.Harness(scene, RES) as h:
        again = C.probe(scene, s, 1.0, h, levels=LEVELS, views=VIEWS, viewing=Viewing())
    assert again["cap_bytes"] == searched["chosen"]["cap_bytes"]
    assert again["psnr_min_per_level"] == searched["chosen"]["psnr_min_per_level"]


def test_an_easy_target_takes_the_lower_end(gl, scene, probes):
    # the default's k_f passes by a margin the model (6 dB per doubling) reads as room past the
    # range's end: the lower end is probed next, and passes
    easy = probes[-4.0]["psnr_min"] - 10.0
    assert (probes[0.0]["psnr_min"] - easy) / C.SLOPE_DB > 4.0
    r = C.calibrate(scene, AnalyseSettings(), target_psnr=easy, **KW)
    assert r["reached"] and r["log2_sigma"] == -4.0
    assert [p["log2_sigma"] for p in r["curve"]] == [-4.0, 0.0]
    C.require_reached(r)  # reached: no error


def test_unreachable_target_fails_with_the_documented_error(gl, scene, probes):
    r = C.calibrate(scene, AnalyseSettings(), target_psnr=200.0, **KW)
    assert r["reached"] is False and len(r["curve"]) == 2
    assert r["log2_sigma"] == 4.0  # unreachable: the largest probed sigma is reported
    with pytest.raises(LopcookError, match="no k_f reaches 200 dB") as exc:
        C.require_reached(r, "scene.glb")
    assert exc.value.exit_code == EXIT_VERIFY_FAILED
    best = max(p["psnr_min"] for p in r["curve"])
    assert f"{best:.1f} dB" in str(exc.value) and "scene.glb" in str(exc.value)
    assert "NOT reached" in C.format_calibration(r)


def test_require_reached_names_a_failed_confirmation(searched):
    r = copy.deepcopy(searched)
    r["reached"] = False
    r["confirmation"] = {"views": 20, "resolution": [1280, 720], "passed": False, "probes": [r["chosen"]]}
    with pytest.raises(LopcookError, match="gate's 20 views at 1280x720") as exc:
        C.require_reached(r)
    assert exc.value.exit_code == EXIT_VERIFY_FAILED


def test_format_marks_the_choice(searched):
    text = C.format_calibration(searched)
    lines = text.splitlines()
    assert len(lines) == 2 + len(searched["curve"]) + 1
    marked = [line for line in lines if line.endswith("<-")]
    assert len(marked) == 1 and f"{searched['log2_sigma']:.3f}" in marked[0]
    assert "reached: sigma" in lines[-1]


@pytest.mark.parametrize("kw, match", [
    (dict(target_psnr=0.0), "positive number of dB"),
    (dict(target_psnr=float("nan")), "positive number of dB"),
    (dict(target_psnr=40.0, statistic="median"), "statistic must be one of"),
    (dict(target_psnr=40.0, search="edges"), "search must be one of"),
    (dict(target_psnr=40.0, log2_range=(2.0, 2.0)), "lo < hi"),
])
def test_bad_arguments_are_usage_errors(scene, kw, match):
    with pytest.raises(LopcookError, match=match) as exc:
        C.calibrate(scene, AnalyseSettings(), **kw)
    assert exc.value.exit_code == EXIT_BAD_INPUT


def test_a_gate_probe_stops_at_its_first_failing_level(gl, scene, probes):
    """``stop_below``: renders end after the first level that misses the target (the probe fails
    anyway); a target every level reaches renders everything, with the same numbers."""
    full = probes[0.0]
    with C.Harness(scene, RES, cache_float=True) as h:
        high = C.probe(scene, AnalyseSettings(), 1.0, h, levels=LEVELS, views=VIEWS, viewing=Viewing(),
                       stop_below=(max(full["psnr_min_per_level"]) + 1.0, "min"))
        low = C.probe(scene, AnalyseSettings(), 1.0, h, levels=LEVELS, views=VIEWS, viewing=Viewing(),
                      stop_below=(min(full["psnr_min_per_level"]) - 1.0, "min"))
    assert high["complete"] is False and high["psnr_min_per_level"] == full["psnr_min_per_level"][:1]
    assert not C._passes(high, max(full["psnr_min_per_level"]) + 1.0)
    assert low["complete"] is True and low["psnr_min_per_level"] == full["psnr_min_per_level"]
    assert low["cap_bytes"] == full["cap_bytes"]


def test_probes_with_the_same_minimum_levels_share_their_renders(gl, scene, probes):
    """Two probes that draw the same buffers and attributes (here: the same sigma, and a sigma a
    hair away) render once (``Harness.view_memo``) and report the same numbers as a fresh probe."""
    with C.Harness(scene, RES, cache_float=True) as h:
        a = C.probe(scene, AnalyseSettings(), 1.0, h, levels=LEVELS, views=VIEWS, viewing=Viewing())
        n = len(h.view_memo)
        b = C.probe(scene, AnalyseSettings(), 1.0 + 1e-12, h, levels=LEVELS, views=VIEWS, viewing=Viewing())
        assert n == len(LEVELS) * len(select_views(VIEWS)) and len(h.view_memo) == n  # nothing new drawn
    assert a["psnr_min_per_level"] == b["psnr_min_per_level"] == probes[0.0]["psnr_min_per_level"]
    assert a["cap_bytes"] == b["cap_bytes"] == probes[0.0]["cap_bytes"]
