"""Container lies with every checksum recomputed (issue 17): ``validate_manifest`` (run by every
read) refuses each with one line, and the decode paths never fail with a Python exception."""

from __future__ import annotations

import copy
import json
import re
import zlib

import numpy as np
import pytest

from tests.support import fuzzcases as fz
from lopcook.lop import reader
from lopcook.lop.container import from_bytes
from lopcook.errors import LopcookError

EXC_NAME = re.compile(r"\b\w+(Error|Exception)\b")


@pytest.fixture(scope="module")
def lop(tmp_path_factory):
    data = fz._lop_base(tmp_path_factory.mktemp("lop"))
    manifest, _, payload = fz._lop_split(data)
    return data, manifest, payload


def refused(blob: bytes, *fragments) -> str:
    with pytest.raises(LopcookError) as info:
        from_bytes(blob, "x.lop")
    text = str(info.value)
    assert "\n" not in text and not EXC_NAME.search(text) and "x.lop" in text, text
    for f in fragments:
        assert f in text, text
    return text


def lie(lop, fn) -> bytes:
    _, manifest, payload = lop
    m = copy.deepcopy(manifest)
    fn(m)
    return fz._lop_with(m, payload)


def test_the_base_container_reads_and_decodes(lop):
    c = from_bytes(lop[0], "x.lop")
    grid, widths, pos = reader.decode_positions(c, 0, 0, 24)
    assert np.isfinite(pos).all() and pos.shape[0] == c.manifest["parts"][0]["lods"][0]["vertices"]


@pytest.mark.parametrize("value", [1e39, 0.0, -1.0, "1", True, [1.0], None])
def test_grid_extent_lies(lop, value):
    refused(lie(lop, lambda m: m["grid"].update(extent=value)), "grid.extent")


@pytest.mark.parametrize("value", [[True, False, True], ["0", "0", "0"], [0.0, 0.0], [1e39, 0.0, 0.0],
                                   [[0.0], 0.0, 0.0], {"x": 0}])
def test_grid_origin_lies(lop, value):
    refused(lie(lop, lambda m: m["grid"].update(origin=value)), "grid.origin")


@pytest.mark.parametrize("where", ["extent", "origin", "geometric_error_m"])
@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_non_finite_numbers_are_refused_as_json(lop, where, value):
    def put(m):
        if where == "extent":
            m["grid"]["extent"] = value
        elif where == "origin":
            m["grid"]["origin"][0] = value
        else:
            m["parts"][0]["lods"][0]["geometric_error_m"] = value
    refused(lie(lop, put), "not a JSON number")
    m = copy.deepcopy(lop[1])
    put(m)
    raw = json.dumps(m, sort_keys=True, separators=(",", ":")).replace("NaN", "1e999").replace("Infinity", "1e999")
    assert "1e999" in raw
    text = refused(fz._lop_pack(raw.encode(), lop[2]), "must be")  # 1e999 parses as inf: a validator error
    assert where.split("_")[0] in text


def test_origin_plus_extent_beyond_float32(lop):
    refused(lie(lop, lambda m: m["grid"].update(origin=[3.4e38, 0.0, 0.0], extent=1e38)), "reaches beyond")
    refused(lie(lop, lambda m: m["grid"].update(origin=[3.4028234663852886e38] * 3)), "reaches beyond")


def test_extent_below_the_floor(lop):
    refused(lie(lop, lambda m: m["grid"].update(extent=1e-44)), "floor")


def test_sections_reordered(lop):
    refused(lie(lop, lambda m: m["sections"].reverse()), "section")


def test_section_offset_that_does_not_follow(lop):
    def swap(m):
        m["sections"][0]["offset"], m["sections"][1]["offset"] = m["sections"][1]["offset"], 0
    refused(lie(lop, swap), "not where the previous one ends")


@pytest.mark.parametrize("key,value", [("length", 1 << 40), ("length", 3), ("length", 4.0), ("crc32", "0"),
                                       ("name", 5), ("offset", -4)])
def test_section_entry_lies(lop, key, value):
    refused(lie(lop, lambda m: m["sections"][0].update({key: value})), "manifest")


@pytest.mark.parametrize("key,value", [("vertices", 1 << 40), ("vertices", 1.5), ("triangles", 1 << 40),
                                       ("triangles", -3), ("index_width", 3), ("indices", "nope"),
                                       ("indices", ["x"]), ("vertex_id", [False] * 25), ("vertex_id", [0, 1]),
                                       ("mandatory_words", [1 << 40, 3]), ("attributes", 3),
                                       ("attributes", "part0/lod0/nope"), ("attributes", None), ("record_bits", 7),
                                       ("attribute_bits", {"normals": 17, "uvs": None, "colors": None}),
                                       ("attribute_bits", {"normals": 8.0, "uvs": None, "colors": None}),
                                       ("attribute_bits", {"normals": 8}), ("attribute_bits", None),
                                       ("geometric_error_m", -1.0), ("uv_range", [[True, 0], [1, 1]]),
                                       ("uv_range", [[1.0, 1.0], [0.0, 0.0]]), ("uv_range", [[-1e39, 0], [1, 1]]),
                                       ("uv_step", [1.0, 1.0]), ("uv_step", None)])
def test_lod_lies(lop, key, value):
    refused(lie(lop, lambda m: m["parts"][0]["lods"][0].update({key: value})), "parts[0].lods[0]")


@pytest.mark.parametrize("key", ["source", "generator", "viewing", "options", "stats"])
def test_missing_informative_fields_are_refused_by_the_strict_validator(lop, key):
    refused(lie(lop, lambda m: m.pop(key)), repr(key))


@pytest.mark.parametrize("key", ["source", "generator", "viewing", "options", "stats", "savings"])
def test_wrong_type_informative_fields_are_refused(lop, key):
    refused(lie(lop, lambda m: m.update({key: [[["x"]]]})), key)


def test_deeply_nested_manifest(lop):
    deep = b'{"format":"lopcook.lop","x":' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    refused(fz._lop_pack(deep, lop[2]), "nested too deeply")


@pytest.mark.parametrize("raw", [b"[]", b'{"format":"lopcook.lop","format":"x"}', b'{"bits":1e999}',
                                 b'{"bits":NaN}', b'{"bits":' + b"9" * 5000 + b"}"])
def test_malformed_manifest_json(lop, raw):
    refused(fz._lop_pack(raw, lop[2]), "manifest")


def test_index_values_out_of_range_are_refused_on_read(lop):
    _, manifest, payload = lop
    m = copy.deepcopy(manifest)
    lod = m["parts"][0]["lods"][0]
    pay = bytearray(payload)
    for s in m["sections"]:
        if s["name"] == lod["indices"]:
            pay[s["offset"]:s["offset"] + lod["index_width"]] = b"\xff" * lod["index_width"]
            s["crc32"] = zlib.crc32(bytes(pay[s["offset"]:s["offset"] + s["length"]]))
    refused(fz._lop_with(m, bytes(pay)), "part 0 LOD 0: index", "out of range")


def test_every_complete_lie_in_the_fuzz_corpus_fails_or_decodes(lop, tmp_path):
    """Every .lop of the generated corpus either reads and decodes at every level, or raises one
    LopcookError: never another exception."""
    cases = [c for c in fz.generate(tmp_path) if c.name.startswith("lop/") and c.command == "decode"]
    assert len(cases) > 100
    for case in cases:
        with open(f"{case.directory}/{case.source}", "rb") as fh:
            blob = fh.read()
        try:
            c = from_bytes(blob, "x.lop", allow_prefix=True)
            for i, p in enumerate(c.manifest["parts"]):
                for k in range(len(p["lods"])):
                    reader.decode_positions(c, i, k, c.available_level)
                    reader.lod_attributes(c, i, k)
        except LopcookError as exc:
            assert "\n" not in str(exc) and not EXC_NAME.search(str(exc)), (case.name, str(exc))


def test_manifest_json_is_parsed_without_constants(lop):
    _, manifest, payload = lop
    text = json.dumps(manifest).replace('"bits": 24', '"bits": Infinity')
    refused(fz._lop_pack(text.encode(), payload), "manifest")


# ---- the read path: what is not a regular file, or too large, is refused before it is read ----

def _inspect(path, capsys):
    from lopcook.cli import main

    rc = main(["inspect", str(path)])
    err = capsys.readouterr().err.strip().splitlines()
    return rc, err


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="needs FIFOs")
def test_inspect_of_a_fifo_is_refused_without_blocking(tmp_path, capsys):
    """A named pipe with no writer: the read used to block for ever."""
    import os
    import time

    os.mkfifo(tmp_path / "a.lop")
    t0 = time.monotonic()
    rc, err = _inspect(tmp_path / "a.lop", capsys)
    assert rc == 2 and len(err) == 1 and "not a regular file" in err[0] and "a.lop" in err[0], err
    assert time.monotonic() - t0 < 5


def test_inspect_of_a_link_to_dev_zero_is_refused_before_reading(tmp_path, capsys):
    """It used to read 3.3 GB of zeros and end in an internal error."""
    import os

    os.symlink("/dev/zero", tmp_path / "a.lop")
    rc, err = _inspect(tmp_path / "a.lop", capsys)
    assert rc == 2 and len(err) == 1 and "not a regular file" in err[0], err


def test_a_file_larger_than_any_container_is_refused_unread(tmp_path, capsys, monkeypatch):
    """A (sparse) file past ``MAX_FILE_BYTES`` is refused on its size, before a byte is read."""
    from lopcook.lop import container

    monkeypatch.setattr(container, "MAX_FILE_BYTES", 1 << 20)
    path = tmp_path / "a.lop"
    with open(path, "wb") as fh:
        fh.truncate((1 << 20) + 1)
    read = []
    monkeypatch.setattr(container, "from_bytes", lambda *a, **k: read.append(a) or None)
    rc, err = _inspect(path, capsys)
    assert rc == 2 and len(err) == 1 and "more than the 1,048,576" in err[0], err
    assert not read
