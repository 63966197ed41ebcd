"""The attribute-bits search (lopcook/tune/attributes.py): the greedy operators on an analytic
error model (exact optimum known by brute force), knobs and steps, and the real search on a small
fixture (cook --vertex-bits: result <= N, the same allocation and bytes twice; bad values exit 2;
the allocation in the manifest)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from lopcook.errors import LopcookError
from lopcook.tune import attributes as TA


def parts(*rows) -> tuple:
    """An allocation's ``parts`` from rows of the first codecs' bits (normals, UVs, colours): every
    codec after them (tangents, ...) None."""
    return tuple(tuple(r) + (None,) * (len(TA.ATTRIBUTES) - len(r)) for r in rows)


class Analytic:
    """The search's interface (cost, quality, full, probes) over a separable convex model: every
    step of every knob costs 2 bits per vertex, and each error term falls 4x per step (as
    quantization MSE does per bit). Quality = -10 log10(total error)."""

    def __init__(self, weights=(1.0, 30.0, 5.0)):
        self.w = weights
        self.probes = []
        self.scene = type("S", (), {"source": "analytic"})()

    def cost(self, a: TA.Allocation) -> float:
        bn, bu = a.parts[0][:2]
        return 30.0 + 4.0 * a.x + 2.0 * bn + 2.0 * bu

    def error(self, a: TA.Allocation) -> float:
        bn, bu = a.parts[0][:2]
        return self.w[0] * 4.0 ** (-2.0 * a.x) + self.w[1] * 4.0 ** (-bn) + self.w[2] * 4.0 ** (-bu)

    def quality(self, a: TA.Allocation, step_name: str = "") -> float:
        q = -10.0 * math.log10(self.error(a))
        if all(p[0] != a.key() for p in self.probes):  # each allocation rendered once, as Search does
            self.probes.append((a.key(), step_name, q))
        return q

    def full(self) -> bool:
        return len(self.probes) >= TA.MAX_PROBES


def brute_force(model: Analytic, budget: float) -> float:
    best = -math.inf
    for x, bn, bu in itertools.product(np.arange(-8.0, 8.01, 0.5), range(4, 17), range(6, 17)):
        a = TA.Allocation(float(x), parts((bn, bu)))
        if model.cost(a) <= budget:
            best = max(best, -10.0 * math.log10(model.error(a)))
    return best


@pytest.mark.parametrize("budget", [40.0, 52.0, 64.0, 80.0])
def test_budget_search_fits_and_finds_the_brute_force_optimum(budget):
    m = Analytic()
    start = TA.Allocation(0.0, parts((12, 12)))
    got = TA.search_budget(m, start, budget)
    assert m.cost(got) <= budget
    assert -10.0 * math.log10(m.error(got)) == pytest.approx(brute_force(m, budget), abs=1e-9)


def test_budget_search_is_deterministic_and_reports_an_unreachable_budget():
    start = TA.Allocation(0.0, parts((12, 12)))
    a, b = Analytic(), Analytic()
    assert TA.search_budget(a, start, 60.0) == TA.search_budget(b, start, 60.0)
    assert a.probes == b.probes
    with pytest.raises(LopcookError) as e:
        TA.search_budget(Analytic(), start, 10.0)  # 30 - 32 + 8 + 12 = 18 bits at the minimum
    assert e.value.exit_code == 2 and "18.00 bits per vertex" in str(e.value)


def test_target_search_passes_and_costs_no_more_than_needed():
    m = Analytic(weights=(1e-4, 30.0, 5.0))  # the start passes: 40 dB
    start = TA.Allocation(0.0, parts((12, 12)))
    got, ok = TA.search_target(m, start, 30.0)
    assert ok and m.quality(got) >= 30.0
    # no single knob step down still passes (a local minimum of cost at the target)
    for k in TA.knobs(got):
        down = TA.step(got, k, -1)
        assert down is None or m.quality(down) < 30.0 or m.cost(down) >= m.cost(got)
    assert m.cost(got) <= m.cost(start)
    # a start below the target is raised until it passes
    low = TA.Allocation(-4.0, parts((4, 6)))
    got, ok = TA.search_target(Analytic(weights=m.w), low, 30.0)
    assert ok and m.quality(got) >= 30.0
    # an unreachable target reports it
    got, ok = TA.search_target(Analytic(weights=m.w), start, 500.0)
    assert not ok


def test_knobs_and_steps_respect_the_ranges():
    a = TA.Allocation(0.0, parts((16, 6), (None, None, 8)))
    names = [k.name for k in TA.knobs(a)]
    assert names == ["positions", "normals[0]", "uvs[0]", "colors[1]"]
    ks = {k.name: k for k in TA.knobs(a)}
    assert TA.step(a, ks["normals[0]"], +1) is None and TA.step(a, ks["uvs[0]"], -1) is None
    assert TA.step(a, ks["colors[1]"], -1).parts == parts((16, 6), (None, None, 7))
    assert TA.step(a, ks["positions"], -1).x == -TA.POSITION_STEP
    assert TA.step(TA.Allocation(TA.POSITION_RANGE[1], a.parts), ks["positions"], +1) is None
    many = TA.Allocation(0.0, parts(*[(10, 10)] * (TA.MAX_PART_KNOBS + 1)))
    shared = [k for k in TA.knobs(many) if k.attribute == "normals"]
    assert len(shared) == 1 and TA.step(many, shared[0], +1).parts[-1] == parts((11, 10))[0]


# ---- the real search on a small fixture (cook --vertex-bits, report) -----------------------------

HARNESS = ["--calibration-views", "2", "--calibration-resolution", "160x90", "--calibration-levels", "7,11",
           "--no-calibration-confirm"]


def _cook(src, out, *extra) -> int:
    from lopcook.cli import main

    return main(["-q", "cook", str(src), "-o", str(out), *HARNESS, *extra])


@pytest.fixture(scope="module")
def budget_cooks(gl, tmp_path_factory):
    """unit_sphere cooked by default and twice with --vertex-bits N, N 6 bits under the default's (the
    default's 8-bit normals leave 2 x 4 bits per vertex to take; the least it can take is 47.03)."""
    from conftest import FIXTURES
    from lopcook.lop.container import read

    d = tmp_path_factory.mktemp("vbits")
    src = FIXTURES / "unit_sphere.glb"
    assert _cook(src, d / "default.lop") == 0
    default = TA.vertex_bits(read(d / "default.lop"))["total"]
    n = math.floor(default) - 6
    assert _cook(src, d / "a.lop", "--vertex-bits", str(n)) == 0
    assert _cook(src, d / "b.lop", "--vertex-bits", str(n)) == 0
    return src, d, n, default


def test_vertex_bits_result_fits_and_is_recorded(budget_cooks):
    from lopcook.lop.container import read

    src, d, n, default = budget_cooks
    c = read(d / "a.lop")
    got = TA.vertex_bits(c)["total"]
    assert got <= n < default
    rec = c.manifest["options"]["attribute_search"]
    assert rec["mode"] == "budget" and rec["goal"] == n and rec["bits_per_vertex"] == pytest.approx(got, abs=1e-3)
    # the recorded choice is what the container holds, part by part
    assert TA.container_allocation(c, rec["choice"]["log2_kf_scale"]).record() == rec["choice"]
    assert all(p["bits_per_vertex"] > 0 for p in rec["probes"]) and rec["probes"][0]["step"] == "start"


def test_vertex_bits_is_deterministic(budget_cooks):
    _, d, _, _ = budget_cooks
    assert (d / "a.lop").read_bytes() == (d / "b.lop").read_bytes()


@pytest.mark.parametrize("value", ["0", "-3", "nan", "inf"])
def test_bad_vertex_bits_exit_2(tmp_path, capsys, value):
    from conftest import FIXTURES

    assert _cook(FIXTURES / "unit_sphere.glb", tmp_path / "x.lop", "--vertex-bits", value) == 2
    assert "--vertex-bits" in capsys.readouterr().err
    assert not (tmp_path / "x.lop").exists()


def test_vertex_bits_with_another_goal_or_unreachable_exits_2(gl, tmp_path, capsys):
    from conftest import FIXTURES

    src = FIXTURES / "unit_sphere.glb"
    assert _cook(src, tmp_path / "x.lop", "--vertex-bits", "64", "--target-psnr", "40") == 2
    assert _cook(src, tmp_path / "y.lop", "--vertex-bits", "1") == 2
    err = capsys.readouterr().err
    assert "the least this scene can take" in err and "Traceback" not in err
    assert not (tmp_path / "y.lop").exists()


def test_report_shows_the_allocation_and_the_curve(budget_cooks):
    import json

    from lopcook.cli import main

    src, d, n, _ = budget_cooks
    out = d / "report.html"
    rc = main(["-q", "report", str(d / "a.lop"), "--source", str(src), "-o", str(out), "--levels", "6-7",
               "--views", "2", "--resolution", "160x90"])
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rc == (1 if rep["verdict"]["result"] == "FAIL" else 0)  # a bit budget may miss 40 dB
    a = rep["attributes"]
    from lopcook.lop.container import read

    c = read(d / "a.lop")
    # the report lists every codec; the record a codec newer than the first format only where set
    chosen = c.manifest["options"]["attribute_search"]["choice"]["parts"]
    assert len(a["parts"]) == len(chosen)
    assert [{k: p["bits"][k] for k in rec} for p, rec in zip(a["parts"], chosen)] == chosen
    assert all(v is None for p, rec in zip(a["parts"], chosen) for k, v in p["bits"].items() if k not in rec)
    assert a["search"]["mode"] == "budget" and a["vertex_bits"]["total"] <= n
    assert a["errors"][0]["normal_deg_max"] >= 0.0
    text = out.read_text()
    assert 'id="attribute-search"' in text and "attribute search: image error against bits per vertex" in text
    assert text.count('class="probe"') == len(a["search"]["probes"])


def test_target_psnr_chooses_attribute_bits_that_pass(gl, tmp_path):
    from conftest import FIXTURES
    from lopcook.lop.container import read

    out = tmp_path / "t.lop"
    assert _cook(FIXTURES / "unit_sphere.glb", out, "--target-psnr", "35") == 0
    rec = read(out).manifest["options"]["attribute_search"]
    assert rec["mode"] == "target" and rec["reached"] and rec["objective_db"] >= 35.0
    start = rec["probes"][0]
    if start["objective_db"] >= 35.0:  # the default bits pass: the search never costs more
        assert rec["bits_per_vertex"] <= start["bits_per_vertex"]
    assert TA.vertex_bits(read(out))["total"] == pytest.approx(rec["bits_per_vertex"], abs=1e-3)


def test_fallbacks_walk_back_to_the_anchor():
    start = TA.Allocation(0.0, parts((16, 12), (None, None, 8)))
    choice = TA.Allocation(-1.0, parts((8, 7), (None, None, 5)))
    got = TA.fallbacks(choice, start)
    assert [r for r, _ in got] == ["anchor positions", "halfway", "anchor"]
    assert got[0][1] == TA.Allocation(0.0, choice.parts)
    assert got[1][1] == TA.Allocation(0.0, parts((12, 10), (None, None, 7)))  # halfway, rounded up
    assert got[2][1] == start
    # a choice at the anchor's k_f skips the first step; the anchor itself has nothing to fall back to
    assert [r for r, _ in TA.fallbacks(TA.Allocation(0.0, choice.parts), start)] == ["halfway", "anchor"]
    assert TA.fallbacks(start, start) == []


@pytest.mark.parametrize("n,cut", [(1, 1), (1, 0), (2, 1), (7, 0), (7, 3), (7, 7), (16, 11), (33, 32)])
def test_last_passing_bisects_the_path(n, cut):
    # a path of n allocations whose first `cut` pass the gate (monotone verdict)
    path = [TA.Allocation(-0.5 * i, parts((8, 7))) for i in range(n)]
    calls = []

    def gate(a, k):
        assert path[k] == a
        calls.append(k)
        return k < cut

    got = TA.last_passing(path, gate)
    assert got == (cut - 1 if cut else None)
    assert calls[0] == 0 and len(calls) <= 1 + math.ceil(math.log2(n))
    assert len(set(calls)) == len(calls)  # no allocation gated twice
    assert TA.last_passing([], gate) is None


def test_moved_knobs_names_what_differs():
    a = TA.Allocation(0.0, parts((8, 7), (None, 9, 8)))
    assert TA.moved_knobs(a, a) == []
    assert TA.moved_knobs(a, TA.Allocation(-0.5, a.parts)) == ["positions"]
    assert TA.moved_knobs(a, TA.Allocation(0.0, parts((8, 6), (None, 9, 7)))) == ["uvs[0]", "colors[1]"]


def test_refine_on_gate_freezes_what_the_reduced_harness_misjudged():
    # the reduced harness is the analytic model; the gate also refuses UVs under 10 bits (as
    # DamagedHelmet's and Duck's textures at level 12 do): the search's own choice misses it
    model = Analytic()
    target = 30.0
    start = TA.Allocation(4.0, parts((16, 16)))
    choice, ok = TA.search_target(model, start, target)
    assert ok and choice.parts[0][1] < 10
    gated = []

    def gate(a, role):
        gated.append((a, role))
        return model.quality(a) >= target and a.parts[0][1] >= 10

    got = TA.refine_on_gate(model, choice, target, gate)
    assert got is not None
    best, frozen = got
    assert gate(best, "check") and "uvs[0]" in frozen
    # it is no dearer than the last choice of the first path that passed the gate
    first_path_pass = [a for a, _ in gated if a.parts[0][1] >= 10 and model.quality(a) >= target]
    assert model.cost(best) <= min(model.cost(a) for a in first_path_pass)
    # with the UVs frozen at the gate's floor the other knobs went on down
    assert best.parts[0][1] == 10 and (best.x < start.x or best.parts[0][0] < 16)
    # a gate nothing passes: None
    assert TA.refine_on_gate(model, choice, target, lambda a, role: False) is None


def test_progress_text_folds_runs_of_equal_parts():
    rec = TA.Allocation(-1.0, parts(*[(8, 6)] * 49, (None, None, 5), (8, 6))).record()
    assert TA._alloc_text(rec) == "k_f 2^-1, n/uv/c 8/6/- x49 -/-/5 8/6/-"
