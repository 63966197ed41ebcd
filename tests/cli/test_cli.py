"""CLI behaviour: exit codes, one-line errors without traceback, --json schema, --quiet, --version."""

from __future__ import annotations

import json
import subprocess
import sys

import jsonschema
import pytest

from conftest import FIXTURES, REPO


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "lopcook", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


def assert_one_line_error(proc, name):
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert name in lines[0]
    assert lines[0].startswith("lopcook: error: ")
    assert proc.stdout == ""


def test_version():
    proc = run("--version")
    assert proc.returncode == 0 and proc.stdout.startswith("lopcook ")


def test_usage_error_exit_2():
    proc = run("inspect")
    assert proc.returncode == 2
    proc = run("frobnicate")
    assert proc.returncode == 2


BAD_INPUTS = {
    "unknown.xyz": b"v 0 0 0\n",
    "missing.obj": None,
    "empty.obj": b"",
    "notglb.glb": b"hello world, not a binary glTF",
    "truncated.glb": b"glTF\x02\x00\x00\x00\xff\x00\x00\x00JSON",
    "broken.gltf": b'{"asset": {"version": "2.0"}, "meshes": [',
    "nan.obj": b"v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n",
    "range.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
    "noface.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\n",
    "garbage.usda": b"#usda 1.0\n(\n  this is not usd )\n def Mesh {",
    "empty.usda": b'#usda 1.0\n(\n    upAxis = "Y"\n)\ndef Xform "root"\n{\n}\n',
    "garbage.usdc": b"PXR-USDC\x00\x00\x00\x00garbage",
}


@pytest.mark.parametrize("name", sorted(BAD_INPUTS))
def test_bad_input_one_clear_line(tmp_path, name):
    path = tmp_path / name
    if BAD_INPUTS[name] is not None:
        path.write_bytes(BAD_INPUTS[name])
    proc = run("inspect", path)
    assert_one_line_error(proc, name)


def test_directory_is_rejected(tmp_path):
    d = tmp_path / "scene.obj"
    d.mkdir()
    assert_one_line_error(run("inspect", d), "scene.obj")


def test_debug_shows_traceback(tmp_path):
    path = tmp_path / "range.obj"
    path.write_bytes(BAD_INPUTS["range.obj"])
    proc = run("--debug", "inspect", path)
    assert proc.returncode != 0 and "Traceback" in proc.stderr


def test_bad_flag_value():
    proc = run("inspect", FIXTURES / "seamed_cube.obj", "--crease-angle", "200")
    assert proc.returncode == 2 and "--crease-angle" in proc.stderr


def test_inspect_json_matches_schema_and_counts():
    schema = json.loads((REPO / "schema" / "inspect.source.schema.json").read_text())
    proc = run("inspect", FIXTURES / "seamed_cube.glb", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    jsonschema.validate(data, schema)
    assert data["totals"]["parts"] == 1
    assert data["totals"]["vertices"] == 24 and data["totals"]["triangles"] == 12
    assert data["totals"]["duplicated_positions"] == 16  # 8 corners x (3 copies - 1)
    assert data["parts"][0]["normals"] == "source" and data["parts"][0]["uvs"] is True
    assert data["extent_m"] == [1.0, 1.0, 1.0]


def test_inspect_text_and_quiet():
    proc = run("inspect", FIXTURES / "two_plates.obj")
    assert proc.returncode == 0 and "2 parts" in proc.stdout and "plate_upper" in proc.stdout
    proc = run("--quiet", "inspect", FIXTURES / "two_plates.obj")
    assert proc.returncode == 0 and proc.stdout == "" and proc.stderr == ""


def test_inspect_json_corpus_schema(corpus):
    schema = json.loads((REPO / "schema" / "inspect.source.schema.json").read_text())
    for name in ["CesiumMilkTruck.glb", "UtahTeapot.usd", "spot.obj"]:
        proc = run("inspect", corpus / name, "--json")
        assert proc.returncode == 0, proc.stderr
        jsonschema.validate(json.loads(proc.stdout), schema)


def test_global_flags_after_the_command():
    proc = run("inspect", FIXTURES / "two_plates.obj", "-q")
    assert proc.returncode == 0 and proc.stdout == ""
    proc = run("inspect", "missing.obj", "--debug")
    assert proc.returncode != 0 and "Traceback" in proc.stderr


def test_cook_lods_auto_is_the_default_chain(tmp_path):
    """``--lods auto`` writes lod_chain's default chain (1/2, 1/4, ...) cut by the stop rule
    (``lopcook.simplify.stop``: the part spans at least 8 px where its coarsest LOD is selected),
    less the LODs no distance selects, and records where and why it stopped; ``--lods R1,R2``
    keeps working and bad values are one-line usage errors."""
    from lopcook.simplify import lod_chain
    from lopcook.cli import main
    from lopcook.lop.container import read
    from lopcook.ingest import load
    from lopcook.selection import selection_ranges
    from lopcook.simplify.stop import StopRule, manifest_record
    from lopcook.viewing import Viewing

    src = FIXTURES / "unit_sphere.glb"
    out = tmp_path / "auto.lop"
    assert main(["-q", "cook", str(src), "-o", str(out), "--lods", "auto", "--lod-backend", "fast"]) == 0
    m = read(str(out)).manifest
    part = load(str(src)).parts[0]
    rule = StopRule(Viewing())
    lods, report = lod_chain(part, ratios=None, backend="fast", seams="auto", stop_rule=rule)
    assert m["options"]["lods"] == {"ratios": "auto", "backend": "fast", "seams": "auto",
                                    **manifest_record([report.as_dict()], rule)}
    ranges = selection_ranges([lod.error_m for lod in lods], [lod.triangles for lod in lods], Viewing())
    expected = [(lod.triangles, lod.error_m) for k, lod in enumerate(lods) if k == 0 or ranges[k] is not None]
    got = [(e["triangles"], e["geometric_error_m"]) for e in m["parts"][0]["lods"]]
    assert got == expected
    # halvings until the first LOD the rule drops (1280 -> 640 -> ...)
    assert [lod.target_ratio for lod in lods] == [0.5 ** k for k in range(len(lods))]
    assert report.stop == "pixels" and report.dropped["error_m"] > rule.max_error_m(report.extent_m) >= lods[-1].error_m
    assert len(got) >= 5
    assert all(b[0] < a[0] and b[1] >= a[1] for a, b in zip(got, got[1:]))
    explicit = tmp_path / "explicit.lop"
    assert main(["-q", "cook", str(src), "-o", str(explicit), "--lods", "1/2,1/4", "--lod-backend", "fast"]) == 0
    assert [e["triangles"] for e in read(str(explicit)).manifest["parts"][0]["lods"]] == [t for t, _ in got[:3]]
    for bad in ("auto,1/2", "automatic", "1/4,1/2"):
        proc = run("cook", src, "-o", tmp_path / "bad.lop", "--lods", bad)
        assert_one_line_error(proc, "--lods")
    assert not (tmp_path / "bad.lop").exists()


def test_decode_lod_uses_the_coarsest_lod_of_shorter_chains(tmp_path, capsys):
    """A part whose chain stopped early (here: 2 triangles, never simplified) is decoded at its
    coarsest LOD, as a renderer selecting by distance would draw it; a LOD no part has is an error."""
    import json

    import numpy as np

    from tests.support import fixtures as F
    from lopcook.cli import main
    from lopcook.ingest import load

    sphere = F.unit_sphere()[0]
    quad = F._part("quad", [[3, 0, 0], [4, 0, 0], [4, 1, 0], [3, 1, 0]], [[0, 1, 2], [0, 2, 3]],
                   normals=[[0, 0, 1]] * 4)
    src = tmp_path / "two.glb"
    F.write_gltf([F._part("sphere", sphere.positions, sphere.indices, normals=sphere.normals), quad], src, binary=True)
    lop = tmp_path / "two.lop"
    assert main(["-q", "cook", str(src), "-o", str(lop), "--lods", "1/2,1/4", "--lod-backend", "fast"]) == 0
    out = tmp_path / "lod2.glb"
    capsys.readouterr()
    assert main(["decode", str(lop), "--level", "12", "--lod", "2", "-o", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["parts_at_coarsest_lod"] == ["quad/quad"]  # node/mesh part names
    got = load(str(out))
    assert [p.n_triangles for p in got.parts] == [sphere.indices.shape[0] // 4, 2]
    # the same corners (the default cook stores them in cluster order: Morton order within a bin)
    a, b = got.parts[1].positions, np.asarray(quad.positions)
    a, b = a[np.lexsort(np.round(a, 1).T)], b[np.lexsort(np.round(b, 1).T)]
    assert np.abs(a - b).max() < 1e-2

    def corners(pos, tri):  # each triangle as its sorted rounded corners
        return sorted(tuple(sorted(map(tuple, np.round(np.asarray(pos)[t], 1).tolist()))) for t in np.asarray(tri))

    assert corners(got.parts[1].positions, got.parts[1].indices) == corners(quad.positions, quad.indices)
    assert main(["decode", str(lop), "--level", "12", "--lod", "3", "-o", str(tmp_path / "no.glb")]) == 2
    assert "LODs 0..2" in capsys.readouterr().err and not (tmp_path / "no.glb").exists()


def test_inspect_says_which_parts_are_double_sided(tmp_path):
    schema = json.loads((REPO / "schema" / "inspect.source.schema.json").read_text())
    from tests.support import fixtures as fx

    path = fx.write_textured_gltf(tmp_path / "textured.glb")[0]  # its material is double-sided
    proc = run("inspect", path, "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    jsonschema.validate(data, schema)
    assert [p["double_sided"] for p in data["parts"]] == [True, True]
    text = run("inspect", path).stdout
    assert " 2S" in text and "2S = double-sided" in text
    plain = json.loads(run("inspect", FIXTURES / "seamed_cube.glb", "--json").stdout)
    assert plain["parts"][0]["double_sided"] is False  # no material: glTF's default
    assert "2S" not in run("inspect", FIXTURES / "seamed_cube.glb").stdout
