"""The input-format registry (``lopcook.ingest.FORMATS``): every place that needs the input
formats reads it (sniffing, loading, output-name checks, batch discovery, CLI help and
``lopcook --formats``, decode's materials), and a format whose optional dependency is missing
fails only when used, with its install hint."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import struct

import pytest

from lopcook import ingest
from lopcook.batch import discover
from lopcook.cli import build_parser, main
from lopcook.emit.preview import source_materials
from lopcook.errors import LopcookError
from lopcook.ingest import EXTENSIONS, FORMATS, KINDS, SOURCE_EXTENSIONS, obj
from lopcook.outputs import SOURCE_EXTENSIONS as OUTPUT_FORBIDDEN

from conftest import REPO

FIXTURES = REPO / "fixtures"

#: one file per kind the registry reads: (fixture, kind its content is)
KIND_FIXTURES = [("two_plates.gltf", "gltf"), ("two_plates.glb", "glb"), ("two_plates.obj", "obj"),
                 ("two_plates.usda", "usda"), ("seamed_cube.usdc", "usdc")]


def test_every_format_module_exports_one_consistent_record():
    names = [f.name for f in FORMATS]
    assert len(set(names)) == len(names)
    for f in FORMATS:
        module = __import__(f"lopcook.ingest.{f.name}", fromlist=["FORMAT"])
        assert module.FORMAT is f and module.EXTENSIONS is f.extensions
        assert f.kinds and all(ext.startswith(".") and ext == ext.lower() for ext in f.extensions)
        for ext in f.extensions:  # an extension belongs to one format and lists that format's kinds only
            assert EXTENSIONS[ext] == f.extensions[ext]
            assert set(f.extensions[ext]) <= set(f.kinds)
        for kind in f.kinds:
            assert KINDS[kind] is f and ingest.format_of(kind) is f and ingest.format_of(kind.upper()) is f
    assert ingest.format_of("stl") is None and ingest.format_of("") is None


@pytest.mark.parametrize("name, kind", KIND_FIXTURES)
def test_sniff_finds_each_kind_from_content(name, kind, tmp_path):
    path = FIXTURES / name
    assert ingest.sniff(str(path)) == kind
    f = KINDS[kind]
    head = path.read_bytes()[:64]
    assert (f.sniff(head) if f.sniff else None) == (None if f.sniff is None else kind)
    # no other format's signature claims it
    assert all(g.sniff is None or g.sniff(head) is None for g in FORMATS if g is not f)


def test_content_not_allowed_by_the_extension_is_refused(tmp_path):
    glb_named_obj = tmp_path / "x.obj"
    glb_named_obj.write_bytes((FIXTURES / "two_plates.glb").read_bytes())
    with pytest.raises(LopcookError) as exc:
        ingest.sniff(str(glb_named_obj))
    assert "content is glb, which a .obj file cannot hold" in str(exc.value) and exc.value.exit_code == 2
    text_named_usdz = tmp_path / "x.usdz"
    text_named_usdz.write_bytes(b"v 0 0 0\n")
    with pytest.raises(LopcookError) as exc:
        ingest.sniff(str(text_named_usdz))
    assert f"content is not {ingest.describe_formats()}" in str(exc.value)


def test_output_checks_batch_and_help_read_the_registry():
    loadable = [ext for f in FORMATS for ext in f.extensions]
    sidecars = [ext for f in FORMATS for ext in f.sidecars]
    assert set(SOURCE_EXTENSIONS) == set(loadable) | set(sidecars)
    assert OUTPUT_FORBIDDEN is SOURCE_EXTENSIONS
    assert {".mtl", ".bin"} <= set(OUTPUT_FORBIDDEN)
    assert discover.SOURCE_EXTENSIONS == tuple(EXTENSIONS)
    assert all(discover.is_source_file("a/b" + ext.upper()) for ext in loadable)
    parser = build_parser()
    text = parser.format_help()
    for f in FORMATS:
        assert f.title in text
    sub = parser._subparsers._group_actions[0].choices
    for command in ("cook", "analyse", "calibrate", "report"):
        assert ingest.describe_formats() in " ".join(sub[command].format_help().split())
    inspect_help = " ".join(sub["inspect"].format_help().split())
    assert ingest.describe_formats(extensions=True) in inspect_help
    batch_help = " ".join(sub["batch"].format_help().split())
    for ext in loadable:
        assert ext in inspect_help and ext in batch_help


def test_formats_lists_every_format_and_exits_0(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--formats"])
    assert exc.value.code == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(FORMATS)
    for f, line in zip(FORMATS, lines):
        assert line.split()[0] == f.name and " ".join(f.extensions) in line
        assert line.endswith("available") == (f.missing() is None)


def test_missing_optional_dependency_fails_only_when_used(monkeypatch, capsys):
    """A format whose module is absent is listed as unavailable with its install hint, and loading
    one of its files is one error (exit 2) naming the module and the hint; other formats load."""
    absent = dataclasses.replace(obj.FORMAT, requires="lopcook_absent_module", install="pip install absent")
    assert "lopcook_absent_module" in absent.missing()
    monkeypatch.setattr(ingest, "FORMATS", tuple(absent if f is obj.FORMAT else f for f in FORMATS))
    monkeypatch.setitem(ingest.KINDS, "obj", absent)
    table = ingest.formats_table()
    assert "unavailable" in table and "pip install absent" in table
    with pytest.raises(LopcookError) as exc:
        ingest.load(FIXTURES / "two_plates.obj")
    assert exc.value.exit_code == 2 and "lopcook_absent_module" in str(exc.value)
    assert "pip install absent" in str(exc.value)
    assert ingest.load(FIXTURES / "two_plates.glb").n_triangles > 0
    rc = main(["inspect", str(FIXTURES / "two_plates.obj")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "pip install absent" in err


def test_the_schemas_admit_every_registered_kind():
    """The container manifest's and ``inspect --json``'s ``source.format`` name a kind of the
    registry: the schemas describe its shape, not a list that adding a format would have to edit."""
    for name, where in (("container.schema.json", ("properties", "source", "properties", "format")),
                        ("inspect.source.schema.json", ("properties", "format"))):
        node = json.loads((REPO / "schema" / name).read_text())
        for key in where:
            node = node[key]
        assert "enum" not in node and node["type"] == "string"
        assert all(re.fullmatch(node["pattern"], kind) for kind in KINDS), name


def test_materials_come_from_the_source_formats_reader(tmp_path):
    parts = [{"mesh_key": "mesh0/prim0", "source": "x"}]
    mats, per_part, warnings = source_materials(str(FIXTURES / "two_plates.glb"), "stl", parts, [True])
    assert (mats, per_part) == ({}, [None]) and warnings == ["no materials for source format 'stl'"]
    broken = tmp_path / "broken.glb"
    broken.write_bytes(b"glTF" + struct.pack("<II", 2, 20) + struct.pack("<I4s", 0, b"BIN\0"))
    mats, per_part, warnings = source_materials(str(broken), "glb", parts, [True])
    assert (mats, per_part) == ({}, [None]) and len(warnings) == 1 and "unreadable" in warnings[0]
    assert os.path.basename(str(broken)) in warnings[0]
