"""``report.json`` of every corpus asset validates against ``schema/report.schema.json``: each asset is
cooked with the default cook and reported with a small harness (2 views at 320x180, levels 6 and 9).
Every asset but the chess set is re-cooked for its warnings; the milk truck's touching and
intersecting wheel parts (part-name pairs) are what the schema refused before. The chess set (its
cook alone takes tens of seconds) is reported with ``--no-analyse`` and one view."""

from __future__ import annotations

import json

import pytest

from conftest import REPO, corpus_path
from lopcook.cli import main

HARNESS = ["--views", "2", "--resolution", "320x180", "--levels", "6,9"]
#: assets reported without the re-cook, and with one view (cost)
QUICK = {"chess_set_flat.usdc"}


def _assets() -> list[str]:
    path = corpus_path()
    if path is None:
        return ["corpus-missing"]
    return [a["file"] for a in json.loads((path / "corpus.json").read_text())["assets"]]


@pytest.mark.parametrize("asset", _assets())
def test_corpus_report_validates(corpus, gl, tmp_path, asset):
    import jsonschema

    src = corpus / asset
    assert src.is_file(), src
    lop = tmp_path / "asset.lop"
    assert main(["-q", "cook", str(src), "-o", str(lop)]) == 0
    out = tmp_path / "report.html"
    args = HARNESS + (["--no-analyse", "--views", "1"] if asset in QUICK else [])
    assert main(["-q", "report", str(lop), "--source", str(src), "-o", str(out), *args]) == 0
    rep = json.loads(out.with_suffix(".json").read_text())
    schema = json.loads((REPO / "schema" / "report.schema.json").read_text())
    jsonschema.validate(rep, schema, cls=jsonschema.Draft202012Validator)
    assert [r["level"] for r in rep["images"]["per_level"]] == [6, 9]
    w = rep["warnings"]
    assert w["available"] is (asset not in QUICK)
    if asset == "CesiumMilkTruck.glb":  # touching and intersecting parts, as name pairs
        assert w["touching"] and w["intersecting"]
        seen = rep["images"]["view_parts"]  # the shown view sees the most parts of the front views
        angles = rep["images"]["view_angles"]
        front = [i for i, (e, a) in enumerate(angles) if 0 <= e <= 45 and abs(a) < 90]
        assert seen is not None and front
        assert seen[rep["render"]["views"].index(rep["images"]["view"])] == max(seen[i] for i in front) > 1
        names = {p["name"] for p in rep["scene_parts"]}
        assert all(a in names and b in names for a, b in w["touching"] + w["intersecting"])
