"""What ``cook`` and ``inspect`` print for a technical artist (``lopcook.lop.summary``,
``lopcook.cli.commands``): the LOD chain as a table (LOD, triangles, error, the distance it is
selected from), no rows or entries of zeros, one line for figures that do not change with the
level (and why the CAP bytes do not), counts in the right number (``lopcook.wording``), and a LOD
backend's fallback as a note unless a target is missed."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from conftest import FIXTURES
from lopcook.simplify.chain import chain_notes, chain_warnings
from lopcook.wording import length, plural


def _lopcook(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lopcook", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


def test_plural_and_length():
    assert [plural(n, "part") for n in (0, 1, 2)] == ["0 parts", "1 part", "2 parts"]
    assert plural(1, "mesh", "meshes") == "1 mesh" and plural(3, "mesh", "meshes") == "3 meshes"
    assert plural(12946, "triangle") == "12,946 triangles" and plural(1, "vertex", "vertices") == "1 vertex"
    assert [length(v) for v in (0.0, 1.38e-4, 0.0045, 0.0645, 9.41, 1080.0, 2.5e-8, math.inf)] == [
        "0", "138 µm", "4.5 mm", "64.5 mm", "9.41 m", "1.08 km", "25 nm", "inf"]


def _entries(line: str) -> list[tuple[int, int]]:
    """``k:count`` pairs of a histogram line (counts with thousands separators)."""
    return [(int(k), int(v.replace(",", ""))) for k, v in re.findall(r"\b(\d+):([\d,]+)", line)]


@pytest.fixture(scope="module")
def helmet_default(corpus, tmp_path_factory):
    """The default cook of DamagedHelmet: (cook's text, inspect's text, inspect --json)."""
    out = tmp_path_factory.mktemp("helmet") / "helmet.lop"
    cooked = _lopcook("cook", corpus / "DamagedHelmet" / "DamagedHelmet.gltf", "-o", out)
    assert cooked.returncode == 0, cooked.stderr
    shown = _lopcook("inspect", out)
    assert shown.returncode == 0, shown.stderr
    return cooked.stdout, shown.stdout, json.loads(_lopcook("inspect", out, "--json").stdout)


@pytest.mark.parametrize("which", [0, 1])
def test_default_cook_text_has_no_rows_of_zeros(helmet_default, which):
    """DamagedHelmet, cooked by default: no histogram entry of 0 (its anchor bits k reach 24 with
    16 empty values between), the unclustered bytes once (they are the same at every level), the
    CAP bytes' sameness explained by the lowest minimum level, no zero terms in the bits per vertex,
    and '1 part, 1 buffer'."""
    text, d = helmet_default[which], helmet_default[2]
    hist_lines = [ln for ln in text.splitlines() if "minimum levels (level:vertices)" in ln or "anchor bits k" in ln]
    assert len(hist_lines) == 2
    anchors = _entries(hist_lines[1].split("anchor bits k (k:components):")[1])
    assert anchors[-1][0] == 24 and len(anchors) < 24  # the range has gaps, and they are not printed
    for line in hist_lines:
        assert all(count > 0 for _, count in _entries(line.split("):", 1)[1])), line
    assert text.count("unclustered") == 1 and "unclustered, the same vertices take" in text
    caps = {r["cap_bytes"] for r in d["memory"] if 6 <= r["level"] <= 12}
    assert len(caps) == 1
    lowest = min(b for b, n in enumerate(d["parts"][0]["lods"][0]["histogram"]) if n)
    assert lowest >= 12
    assert (f"CAP bytes are the same at levels 6-12: every vertex's minimum level is {lowest} or more, so at each "
            "of these levels every\n  vertex is already at or above its minimum") in text
    bits = next(ln for ln in text.splitlines() if "bits per vertex at level" in ln)
    assert " 0.0 " not in bits and "colours" not in bits
    assert "; 1 part, 1 buffer, 14,556 vertices, 15,452 triangles;" in text
    assert "selected from" not in text  # no LOD table without LODs


def test_cook_prints_the_lod_table(tmp_path):
    """``cook --lods 1/2,1/4``: one row per LOD with its triangles, vertices, error and the distance
    it is selected from, as the manifest records them."""
    out = tmp_path / "sphere.lop"
    cooked = _lopcook("cook", FIXTURES / "unit_sphere.glb", "-o", out, "--lods", "1/2,1/4", "--lod-backend", "fast")
    assert cooked.returncode == 0, cooked.stderr
    d = json.loads(_lopcook("inspect", out, "--json").stdout)
    lines = cooked.stdout.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.split() == ["LOD", "triangles", "vertices", "error", "selected",
                                                                 "from"])
    lods = d["parts"][0]["lods"]
    assert len(lods) == 3
    for k, e in enumerate(lods):
        want = [str(k), f"{e['triangles']:,}", f"{e['vertices']:,}", *length(e["geometric_error_m"]).split(),
                *(length(e["min_distance_m"]).split() if e["min_distance_m"] else ["0", "m"])]
        assert lines[head + 1 + k].split() == want
    assert "chain stopped" not in cooked.stdout  # explicit ratios: every LOD asked for was made
    assert "; 1 part, 3 buffers," in cooked.stdout


def _spheres_obj(path, n: int) -> None:
    """An OBJ of ``n`` objects, each an icosphere with its own jitter (distinct meshes)."""
    from tests.support import fixtures as F

    sphere = F.unit_sphere(2)[0]
    rng = np.random.default_rng(7)
    lines, base = [], 1
    for i in range(n):
        p = sphere.positions * (1.0 + 0.02 * rng.standard_normal((sphere.positions.shape[0], 1))) + [3.0 * i, 0, 0]
        lines.append(f"o ball{i}")
        lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in p]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in sphere.indices]
        base += p.shape[0]
    path.write_text("\n".join(lines) + "\n")


def test_many_parts_get_one_table_by_lod(tmp_path):
    """Five parts with LODs: one row per LOD index (parts that have it, their triangles, the largest
    error, the range of selection distances) and the chains' stops grouped by reason."""
    src, out = tmp_path / "balls.obj", tmp_path / "balls.lop"
    _spheres_obj(src, 5)
    cooked = _lopcook("cook", src, "-o", out, "--lods", "auto", "--lod-backend", "fast")
    assert cooked.returncode == 0, cooked.stderr
    d = json.loads(_lopcook("inspect", out, "--json").stdout)
    lines = cooked.stdout.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.split()[:4] == ["LOD", "parts", "triangles", "largest"])
    depth = max(len(p["lods"]) for p in d["parts"])
    for k in range(depth):
        es = [p["lods"][k] for p in d["parts"] if len(p["lods"]) > k]
        row = lines[head + 1 + k].split()
        assert row[:3] == [str(k), str(len(es)), f"{sum(e['triangles'] for e in es):,}"]
        assert " ".join(row[3:5]) == length(max(e["geometric_error_m"] for e in es)) or row[3] == "0"
    stops = [p["lod_stop"]["stop"] for p in d["parts"]]
    assert stops == ["pixels"] * 5
    assert any(ln.startswith("  chains stopped (pixels): 5 parts, e.g. 'ball") for ln in lines)


def test_one_mesh_is_one_mesh(tmp_path):
    out, glb = tmp_path / "s.lop", tmp_path / "s.glb"
    assert _lopcook("cook", FIXTURES / "unit_sphere.glb", "-o", out).returncode == 0
    proc = _lopcook("decode", out, "--level", "12", "-o", glb)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"{glb}: 1 mesh decoded at level 12, LOD 0"
    pos = tmp_path / "s.f32"
    proc = _lopcook("decode", out, "--level", "12", "--positions", pos)
    assert proc.stdout.strip() == f"{pos}: 642 vertices decoded at level 12, LOD 0"


_FLIP = "meshopt failed: 3 of 500 faces are flipped against the source surface; falling back to pymeshlab"


def _report(part, lods, stop="ratios", triangles=1000):
    return {"part": part, "triangles": triangles, "stop": stop, "stop_reason": f"stopped: {stop}",
            "lods": [{"notes": n} for n in lods]}


def test_a_fallback_that_reaches_its_target_is_a_note():
    """A backend that failed where its fallback reached the target is information
    (``chain_notes``); with a missed target (more than 5 % off) it is a warning with the miss; a
    part left with LOD 0 alone is a warning unless a rule ended its chain there."""
    miss = "140 triangles for a target of 125 (+12.0%)"
    reports = [_report("a", [[], [_FLIP], [_FLIP, miss]]), _report("b", [[], [_FLIP]]),
               _report("c", [[]], stop="pixels"), _report("d", [[]], stop="failed")]
    assert chain_warnings(reports) == [f"part 'a': LOD 2: {_FLIP}", f"part 'a': LOD 2: {miss}",
                                       "part 'd': no LODs (stopped: failed)"]
    assert chain_notes(reports) == [f"part 'a' and 1 more: LOD 1: {_FLIP}"]


def test_cook_prints_many_fallbacks_as_one_note():
    from lopcook.cli.commands import NOTE_LINES, _fallback_summary

    few = [f"part 'p': LOD {k}: {_FLIP}" for k in range(1, NOTE_LINES + 1)]
    assert _fallback_summary(few) == few
    many = few + [f"part 'q': LOD 1: {_FLIP}"]
    (line,) = _fallback_summary(many)
    assert line.startswith(f"{NOTE_LINES + 1} LOD backend fallbacks reached their targets anyway (first: {few[0]}")
