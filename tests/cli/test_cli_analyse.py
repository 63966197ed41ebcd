"""lopcook analyse: JSON against its schema, closed-form levels through the CLI, option errors."""

from __future__ import annotations

import json
import subprocess
import sys

import jsonschema
import pytest

from conftest import FIXTURES, REPO

SCHEMA = json.loads((REPO / "schema" / "analysis.schema.json").read_text())


def run(*args):
    return subprocess.run([sys.executable, "-m", "lopcook", *map(str, args)], capture_output=True, text=True)


def test_two_plates_json():
    proc = run("analyse", FIXTURES / "two_plates.glb", "--json", "--no-edges")  # depth alone (rims are edges)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    jsonschema.validate(d, SCHEMA)
    # gap 2^-10 m, extent 1 m: every vertex needs 11 bits, all for depth
    assert d["totals"]["histogram"][11] == 162 and sum(d["totals"]["histogram"]) == 162
    assert d["totals"]["reasons"]["depth"] == 162


def test_paper_fixed_depth_mode_and_off():
    d = json.loads(run("analyse", FIXTURES / "two_plates.glb", "--json", "--depth", "fixed:7",
                       "--depth-threshold", "0.01", "--no-edges").stdout)
    assert d["totals"]["histogram"][7] == 162 and d["settings"]["depth"] == "fixed:7"
    d = json.loads(run("analyse", FIXTURES / "two_plates.glb", "--json", "--depth", "off", "--no-edges").stdout)
    assert d["totals"]["histogram"][1] == 162


def test_sphere_levels_follow_kf():
    lo = json.loads(run("analyse", FIXTURES / "unit_sphere.glb", "--json", "--kf", "1").stdout)
    hi = json.loads(run("analyse", FIXTURES / "unit_sphere.glb", "--json", "--kf", "64").stdout)
    # k_f x 64 = 2^6: every level goes up by 6 (E_v, extent and eps unchanged)
    assert lo["parts"][0]["max_level"] + 6 == hi["parts"][0]["max_level"]
    assert lo["totals"]["mean_level"] + 6 == pytest.approx(hi["totals"]["mean_level"], abs=0.05)


def test_text_output():
    proc = run("analyse", FIXTURES / "two_plates.obj", "--no-edges")
    assert proc.returncode == 0
    assert "11:162" in proc.stdout and "depth 162" in proc.stdout


@pytest.mark.parametrize("flags,needle", [
    (["--depth", "fixed:30", "--depth-threshold", "0.1"], "--depth fixed:30"),
    (["--depth", "fixed:5"], "--depth-threshold"),
    (["--depth", "sometimes"], "--depth"),
    (["--eps", "0"], "eps"),
    (["--texture-kf", "lots"], "--texture-kf"),
    (["--depth-ceiling", "30"], "--depth-ceiling"),
])
def test_bad_options_exit_2(flags, needle):
    proc = run("analyse", FIXTURES / "two_plates.glb", *flags)
    assert proc.returncode == 2 and needle in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_corpus_json_schema(corpus):
    proc = run("analyse", corpus / "CesiumMilkTruck.glb", "--json")
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    jsonschema.validate(d, SCHEMA)
    assert d["intersecting"]  # the wheels overlap the body
