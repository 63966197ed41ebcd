"""fixtures/conformance/ and lopcook's own reader: the set regenerates byte for byte from
tests/support/conformance.py (it cannot drift from the cooker), lopcook's reader passes it (every
verdict, error class, available level and dump hash), its error classes are those docs/format.md
names, and ``lopcook decode --positions`` writes the positions dump through the CLI."""

from __future__ import annotations

import hashlib
import re
import subprocess
import sys

import pytest

from c_tools import CONFORMANCE, conformance, expected_of, verdict, want_verdict
from conftest import REPO

from support import conformance as generator
from support import dumps

from lopcook.lop.container import from_bytes

DOCS = REPO / "docs" / "format.md"


def test_the_set_regenerates_byte_for_byte(tmp_path):
    generator.generate(tmp_path)
    made = sorted(p.name for p in tmp_path.iterdir())
    assert made == sorted(p.name for p in CONFORMANCE.iterdir() if p.name != "README.md")
    for name in made:
        assert (tmp_path / name).read_bytes() == (CONFORMANCE / name).read_bytes(), name


def test_the_set_is_small_and_covers_every_class():
    index = conformance()
    total = sum(p.stat().st_size for p in CONFORMANCE.iterdir())
    assert total < 1_000_000
    classes = {e["error"] for e in index["files"] if e["kind"] == "invalid"}
    assert classes == {"bad_magic", "header_crc", "version", "header", "trailing_data", "truncated", "manifest_crc",
                       "manifest_json", "manifest", "section_table", "section_crc", "indices", "clusters", "encoding"}
    documented = set(re.findall(r"^\| `([a-z_]+)` \|", DOCS.read_text(), flags=re.M))
    assert classes <= documented, f"classes missing from docs/format.md: {classes - documented}"
    kinds = [e["kind"] for e in index["files"]]
    assert kinds.count("valid") >= 10 and kinds.count("prefix") >= 6
    valid = [e for e in index["files"] if e["kind"] == "valid"]
    assert {"2.0", "3.0", "4.0"} <= {e["version"] for e in valid}
    assert any("stage_levels" in e for e in valid) and any("tangents" in " ".join(e["covers"]) for e in valid)
    streamed = [e for e in index["files"] if e["kind"] == "prefix" and "stage_levels" in e["prefix"]]
    assert any(0 in e["prefix"]["stage_levels"] for e in streamed), "no prefix holds only some stages"


@pytest.mark.parametrize("entry", conformance()["files"], ids=lambda e: e["file"])
def test_lopcooks_reader_passes_the_set(entry):
    index = conformance()
    data = (CONFORMANCE / entry["file"]).read_bytes()
    assert hashlib.sha256(data).hexdigest() == entry["sha256"]
    assert verdict(data, False) == want_verdict(entry)
    if "prefix" in entry:
        assert verdict(data, True) == want_verdict(entry["prefix"])
    expected = expected_of(index, entry)
    if not expected:
        return
    c = from_bytes(data, entry["file"], allow_prefix=True)
    for lod in expected:
        assert hashlib.sha256(dumps.attributes(c, lod["lod"])).hexdigest() == lod["attributes"]
        for level, hashes in lod["levels"].items():
            got = {"positions": dumps.positions(c, int(level), lod["lod"]), "gpu": dumps.gpu(c, int(level), lod["lod"])}
            assert {k: hashlib.sha256(v).hexdigest() for k, v in got.items()} == hashes, (level, lod["lod"])


def _decode(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lopcook", "decode", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def test_lopcook_decode_writes_the_positions_dump(tmp_path):
    index = conformance()
    entry = next(e for e in index["files"] if e["file"] == "placements_clustered.lop")
    out = tmp_path / "p.f32"
    run = _decode(CONFORMANCE / entry["file"], "--level", "13", "--positions", out, "-q")
    assert run.returncode == 0, run.stderr
    assert hashlib.sha256(out.read_bytes()).hexdigest() == entry["expected"][0]["levels"]["13"]["positions"]


def test_lopcook_decode_positions_refuses_with_one_line_and_no_output(tmp_path):
    out = tmp_path / "p.f32"
    for args, fragment in (((CONFORMANCE / "tetra.lop", "--level", "25"), "outside [1, 24]"),
                           ((CONFORMANCE / "tetra.lop", "--level", "3", "--lod", "2"), "no part has LOD 2"),
                           ((CONFORMANCE / "prefix_plates_mandatory.lop", "--level", "12"), "not in this file"),
                           ((CONFORMANCE / "indices.lop", "--level", "3"), "out of range"),
                           ((CONFORMANCE / "tetra.lop", "--level", "3"), "nothing to write")):
        extra = ("--positions", out) if "nothing to write" not in fragment else ()
        run = _decode(*args, *extra)
        assert run.returncode == 2 and fragment in run.stderr, run.stderr
        assert len(run.stderr.strip().splitlines()) == 1 and "Traceback" not in run.stderr
        assert not out.exists() and not list(tmp_path.iterdir())
