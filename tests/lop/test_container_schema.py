"""The .lop specification agrees with the writer: schema/container.schema.json accepts every
manifest lopcook writes and rejects broken ones, schema/container.ksy declares the header the
code packs, and docs/format.md shows what docs/worked_example.py computes."""

from __future__ import annotations

import copy
import json
import re
import struct
import subprocess
import sys

import numpy as np
import pytest
import yaml
from jsonschema import Draft202012Validator

from conftest import FIXTURES, REPO
from lopcook.cli import main as cli_main
from lopcook.emit import BufferInput, build
from lopcook.lop import container
from lopcook.lop.container import from_bytes

SCHEMA_PATH = REPO / "schema" / "container.schema.json"
KSY_PATH = REPO / "schema" / "container.ksy"
FORMAT_MD = REPO / "docs" / "format.md"
WORKED_EXAMPLE = REPO / "docs" / "worked_example.py"

FIXTURE_FILES = sorted(p.name for pattern in ("*.glb", "*.obj", "*.usda") for p in FIXTURES.glob(pattern))
CORPUS_ASSETS = ["CesiumMilkTruck.glb", "DamagedHelmet/DamagedHelmet.gltf", "UtahTeapot.usd"]


@pytest.fixture(scope="module")
def validator() -> Draft202012Validator:
    schema = json.loads(SCHEMA_PATH.read_text())
    Draft202012Validator.check_schema(schema)
    return Draft202012Validator(schema)


def cook(source, tmp_path) -> dict:
    """The manifest ``lopcook cook SOURCE -o OUT.lop`` writes (read back with the real reader)."""
    out = tmp_path / "out.lop"
    assert cli_main(["-q", "cook", str(source), "-o", str(out)]) == 0
    return from_bytes(out.read_bytes(), str(out)).manifest


def errors(validator, manifest) -> list[str]:
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(manifest)]


# --------------------------------------------------------------------------------------------
# the manifest schema

def test_schema_is_a_valid_2020_12_schema_with_descriptions():
    schema = json.loads(SCHEMA_PATH.read_text())
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    Draft202012Validator.check_schema(schema)

    missing = []

    def walk(node, where):
        if isinstance(node, dict):
            for key in ("properties", "$defs"):
                for name, sub in node.get(key, {}).items():
                    if isinstance(sub, dict) and "description" not in sub and "$ref" not in sub:
                        missing.append(f"{where}/{key}/{name}")
            for key, sub in node.items():
                if key not in ("allOf", "if", "then", "else", "not"):  # conditions restate fields
                    walk(sub, f"{where}/{key}")
        elif isinstance(node, list):
            for i, sub in enumerate(node):
                walk(sub, f"{where}/{i}")

    walk(schema, "#")
    assert not missing, f"fields without a description: {missing}"


@pytest.mark.parametrize("name", FIXTURE_FILES)
def test_every_fixture_manifest_validates(validator, name, tmp_path):
    manifest = cook(FIXTURES / name, tmp_path)
    assert errors(validator, manifest) == []


@pytest.mark.parametrize("name", CORPUS_ASSETS)
def test_corpus_manifests_validate(validator, corpus, name, tmp_path):
    manifest = cook(corpus / name, tmp_path)
    assert errors(validator, manifest) == []


def test_api_manifest_with_lods_colours_and_max_level_validates(validator):
    """build() called directly: options {}, two LODs, vertex colours, planes only up to 9."""
    from lopcook.analyse import analyse
    from lopcook.ingest import load

    scene = load(FIXTURES / "unit_sphere.glb")
    an = analyse(scene)
    part, pa = scene.parts[0], an.parts[0]
    colors = np.random.default_rng(7).random((part.n_vertices, 4)).astype(np.float32)
    lod0 = BufferInput(quantized=pa.quantized, min_level=pa.min_level, indices=part.indices,
                       attributes={"normals": part.normals, "uvs": part.uvs, "colors": colors})
    lod1 = BufferInput(quantized=pa.quantized, min_level=np.minimum(pa.min_level, 5), indices=part.indices[:100],
                       attributes={"colors": colors}, geometric_error_m=0.01)
    c = from_bytes(build(scene, an, lods=[[lod0, lod1]], max_level=9))
    m = c.manifest
    assert m["options"] == {} and m["positions"]["max_level"] == 9 and c.available_level == 9
    assert sorted(m["positions"]["planes"], key=int) == [str(p) for p in range(2, 10)]
    lod = m["parts"][0]["lods"][1]
    assert lod["attribute_bits"] == {"normals": None, "uvs": None, "colors": 8} and "uv_range" not in lod
    assert lod["attributes"] == "part0/lod1/attributes" and lod["record_bits"] == 32
    assert errors(validator, m) == []


@pytest.fixture(scope="module")
def plates_manifest(tmp_path_factory) -> dict:
    return cook(FIXTURES / "two_plates.glb", tmp_path_factory.mktemp("plates"))


def _lod(m):
    return m["parts"][1]["lods"][0]


MUTATIONS = {
    "extra top-level key": lambda m: m.update(extra=1),
    "missing sections": lambda m: m.pop("sections"),
    "wrong format": lambda m: m.update(format="lopcook.lop2"),
    "grid bits 16": lambda m: m["grid"].update(bits=16),
    "zero extent": lambda m: m["grid"].update(extent=0.0),
    "origin of two numbers": lambda m: m["grid"].update(origin=[0.0, 0.0]),
    "no parts": lambda m: m.update(parts=[]),
    "part without lods": lambda m: m["parts"][0].update(lods=[]),
    "vertex_id of 24 entries": lambda m: _lod(m).update(vertex_id=_lod(m)["vertex_id"][:24]),
    "vertex_id not starting at 0": lambda m: _lod(m)["vertex_id"].__setitem__(0, 1),
    "index_width 3": lambda m: _lod(m).update(index_width=3),
    "index_width 4 for 81 vertices": lambda m: _lod(m).update(index_width=4),
    "index_width 2 for 70000 vertices": lambda m: _lod(m).update(vertices=70000),
    "uvs without uv_range": lambda m: _lod(m).pop("uv_range"),
    "uv_range without uvs": lambda m: _lod(m)["attribute_bits"].update(uvs=None),
    "uvs without uv_step": lambda m: _lod(m).pop("uv_step"),
    "attributes section misnamed": lambda m: _lod(m).update(attributes="part1/lod0/attribute"),
    "normal bits 17": lambda m: _lod(m)["attribute_bits"].update(normals=17),
    "colour bits 3": lambda m: _lod(m)["attribute_bits"].update(colors=3),
    "record_bits 130": lambda m: _lod(m).update(record_bits=130),
    "tangent bits 3": lambda m: _lod(m)["attribute_bits"].update(tangents=3),
    "attribute_bits without colours": lambda m: _lod(m)["attribute_bits"].pop("colors"),
    "part without attribute_bits": lambda m: m["parts"][1].pop("attribute_bits"),
    "mandatory_words of one number": lambda m: _lod(m).update(mandatory_words=[84]),
    "negative triangle count": lambda m: _lod(m).update(triangles=-1),
    "max_level 25": lambda m: m["positions"].update(max_level=25),
    "plane 12 missing": lambda m: m["positions"]["planes"].pop("12"),
    "plane 24 missing (max_level 24)": lambda m: m["positions"]["planes"].pop("24"),
    "plane 25": lambda m: m["positions"]["planes"].update({"25": "positions/plane25"}),
    "plane name without two digits": lambda m: m["positions"]["planes"].update({"7": "positions/plane7"}),
    "section length not a multiple of 4": lambda m: m["sections"][0].update(length=766),
    "crc32 above 2^32": lambda m: m["sections"][0].update(crc32=1 << 32),
    "negative offset": lambda m: m["sections"][1].update(offset=-4),
    "unknown section name": lambda m: m["sections"][0].update(name="part0/lod0/tangents"),
    "histogram of 24 entries": lambda m: m["stats"].update(histogram=m["stats"]["histogram"][1:]),
    "nearest distance 0": lambda m: m["viewing"].update(nearest_m=0.0),
    "fov 180": lambda m: m["viewing"].update(fov_y_deg=180.0),
    "normals stored as 3 components": lambda m: m["encodings"]["normals"].update(components=3),
    "sha256 not hex": lambda m: m["source"].update(sha256="xyz"),
    "source format not a lower-case word": lambda m: m["source"].update(format="Stanford PLY"),
    "string where a number belongs": lambda m: m["stats"].update(vertices="162"),
}


@pytest.mark.parametrize("mutation", sorted(MUTATIONS))
def test_broken_manifests_are_rejected(validator, plates_manifest, mutation):
    assert errors(validator, plates_manifest) == []
    broken = copy.deepcopy(plates_manifest)
    MUTATIONS[mutation](broken)
    assert errors(validator, broken), f"schema accepted: {mutation}"


def test_large_buffer_needs_uint32_indices(validator, plates_manifest):
    m = copy.deepcopy(plates_manifest)
    _lod(m).update(vertices=70000, index_width=4)
    assert errors(validator, m) == []


def test_max_level_below_24_needs_exactly_its_planes(validator, plates_manifest):
    m = copy.deepcopy(plates_manifest)
    m["positions"]["max_level"] = 12
    assert errors(validator, m)  # planes 13..24 are one too many
    m["positions"]["planes"] = {str(p): f"positions/plane{p:02d}" for p in range(2, 13)}
    assert errors(validator, m) == []
    m["positions"]["max_level"] = 1
    m["positions"]["planes"] = {}
    assert errors(validator, m) == []


# --------------------------------------------------------------------------------------------
# the Kaitai Struct description

KSY_SIZES = {"u1": 1, "u2": 2, "u4": 4, "u8": 8, "s1": 1, "s2": 2, "s4": 4, "s8": 8, "f4": 4, "f8": 8}
STRUCT_FOR = {"u1": "B", "u2": "H", "u4": "I", "u8": "Q"}


@pytest.fixture(scope="module")
def ksy() -> dict:
    return yaml.safe_load(KSY_PATH.read_text())


def test_ksy_is_yaml_with_meta_and_docs(ksy):
    assert ksy["meta"]["id"] == "lopcook_lop" and ksy["meta"]["endian"] == "le"
    assert ksy["meta"]["file-extension"] == "lop"
    assert ksy["doc"].strip() and [s["id"] for s in ksy["seq"]] == ["header", "manifest", "sections"]
    undocumented = []
    for tname, t in [("(root)", ksy), *ksy["types"].items()]:
        if tname != "(root)" and not t.get("doc"):
            undocumented.append(tname)
        for item in t.get("seq", []) + t.get("params", []):
            if not item.get("doc"):
                undocumented.append(f"{tname}.{item['id']}")
        for name, inst in t.get("instances", {}).items():
            if not inst.get("doc"):
                undocumented.append(f"{tname}.{name}")
    assert not undocumented, undocumented
    # every user type a field refers to is defined
    defined = set(ksy["types"])
    for t in [ksy, *ksy["types"].values()]:
        for item in list(t.get("seq", [])) + list(t.get("instances", {}).values()):
            ref = item.get("type")
            if isinstance(ref, str) and ref not in KSY_SIZES and not re.fullmatch(r"b\d+|str", ref):
                assert ref.split("(")[0] in defined, ref


def test_ksy_header_matches_the_code(ksy):
    seq = ksy["types"]["header"]["seq"]
    offset, fmt = 0, "<"
    for field in seq:
        if "contents" in field:
            size = len(field["contents"])
            assert field["contents"].encode("ascii") == container.MAGIC
            fmt += f"{size}s"
        else:
            size = KSY_SIZES[field["type"]]
            fmt += STRUCT_FOR[field["type"]]
        # the doc of every header field states its offset
        assert re.match(rf"Offset {offset}\b", field["doc"]), (field["id"], field["doc"])
        offset += size
    assert offset == container.HEADER_SIZE == 32
    # the same layout as lopcook.lop.container: its 28-byte struct, then the header CRC (uint32)
    assert fmt == container._HEADER.format + "I"
    assert struct.calcsize(fmt) == 32
    names = [f["id"] for f in seq]
    assert names == ["magic", "version_major", "version_minor", "len_header", "len_manifest",
                     "crc32_manifest", "len_file", "crc32_header"]
    valid = {f["id"]: f.get("valid") for f in seq}
    assert valid["len_header"] == container.HEADER_SIZE
    assert valid["version_major"] == {"any-of": list(container.READABLE_MAJORS)}  # 3: clustered buffers


def test_ksy_header_parses_a_real_file(ksy, tmp_path):
    """Unpack a cooked file with the field list the .ksy declares."""
    out = tmp_path / "cube.lop"
    assert cli_main(["-q", "cook", str(FIXTURES / "seamed_cube.glb"), "-o", str(out)]) == 0
    data = out.read_bytes()
    seq = ksy["types"]["header"]["seq"]
    fmt = "<" + "".join(f"{len(f['contents'])}s" if "contents" in f else STRUCT_FOR[f["type"]] for f in seq)
    h = dict(zip([f["id"] for f in seq], struct.unpack_from(fmt, data)))
    assert h["magic"] == b"LOPC" and h["len_header"] == 32 and h["len_file"] == len(data)
    manifest = data[h["len_header"]:h["len_header"] + h["len_manifest"]]
    assert json.loads(manifest.decode("ascii"))["format"] == "lopcook.lop"


def test_format_md_header_table_matches_the_code():
    text = FORMAT_MD.read_text()
    table = text.split("## 3. Header", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| (\d+) \| (\d+) \| ([^|]+) \| `(\w+)` \|", table, flags=re.M)
    assert [(int(o), int(s)) for o, s, _, _ in rows] == [(0, 4), (4, 2), (6, 2), (8, 4), (12, 4), (16, 4), (20, 8), (28, 4)]
    assert sum(int(s) for _, s, _, _ in rows) == container.HEADER_SIZE


# --------------------------------------------------------------------------------------------
# the worked example

def parse_lines(text: str) -> dict[str, str]:
    out = {}
    for line in text.strip().splitlines():
        key, sep, value = line.partition(": ")
        assert sep, f"not a 'key: value' line: {line!r}"
        assert key not in out, f"duplicate key {key!r}"
        out[key] = value
    return out


@pytest.fixture(scope="module")
def worked_example() -> str:
    proc = subprocess.run([sys.executable, str(WORKED_EXAMPLE)], capture_output=True, text=True, cwd=REPO,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_worked_example_matches_format_md(worked_example):
    sys.path.insert(0, str(WORKED_EXAMPLE.parent))
    try:
        import worked_example as we
    finally:
        sys.path.pop(0)
    text = FORMAT_MD.read_text()
    block = re.search(r"<!-- BEGIN worked_example.py output -->\n```text\n(.*?)```\n<!-- END worked_example.py output -->",
                      text, flags=re.S)
    assert block, "docs/format.md has no worked_example.py output block"
    shown, ran = parse_lines(block.group(1)), parse_lines(worked_example)
    assert list(shown) == list(ran), "format.md shows other lines than docs/worked_example.py prints"
    stale = [k for k in ran if k not in we.VOLATILE and shown[k] != ran[k]]
    assert not stale, "docs/format.md is out of date; rerun docs/worked_example.py and paste its output: " + \
        "; ".join(f"{k}: shown {shown[k]!r}, now {ran[k]!r}" for k in stale)
    # the key numbers, spelled out
    assert ran["header.bytes[0:12]"] == "4c 4f 50 43 02 00 00 00 20 00 00 00"
    assert ran["VertexId"] == "[0] * 11 + [81] * 14"
    assert ran["BitId(B=11)"] == "[0] * 11 + [2673] * 14"
    assert ran["BitId(B=12)"] == "[0] * 11 + [2916] * 14"
    assert ran["vertex.v(B=12)"].startswith("(0xfff, 0x004, 0x200)")
    assert "= 0.4998779296875 (0x3efff000)" in ran["float.x"]
    assert "= 0.0010986328125 (0x3a900000)" in ran["float.y"]
    assert "= -0.3748779296875 (0xbebff000)" in ran["float.z"]
    # the prose quotes these numbers too
    for number in ("0.4998779296875", "2673", "2916", "561", "612", "294, 295, 296"):
        assert number in text.split("Reading it:", 1)[1], number


def test_worked_example_volatile_lines_are_consistent(worked_example):
    """The lines not compared with format.md still agree with each other and with the header."""
    ran = parse_lines(worked_example)
    header = bytes.fromhex((ran["header.bytes[0:12]"] + " " + ran["header.bytes[12:32]"]).replace(" ", ""))
    magic, major, minor, hsize, msize, mcrc, total, hcrc = struct.unpack("<4sHHIIIQI", header)
    assert (magic, major, minor, hsize) == (b"LOPC", *container.VERSION, 32)
    assert int(ran["header.manifest_size"]) == msize
    assert int(ran["header.manifest_crc32"], 16) == mcrc
    assert int(ran["header.file_size"]) == total
    assert int(ran["header.header_crc32"], 16) == hcrc
    assert ran["sections.base"].startswith(f"{32 + msize} ")


# --------------------------------------------------------------------------------------------
# the .ksy's expressions for random access compute what lopcook's decoder computes

def ks_expr_to_python(expr: str) -> str:
    """Kaitai expression -> Python: ``a ? b : c`` becomes ``(b if a else c)`` (the .ksy
    parenthesises everything else where C and Python precedence differ)."""
    out, i = "", 0
    while i < len(expr):  # convert parenthesised groups first
        if expr[i] == "(":
            depth, j = 1, i + 1
            while depth:
                depth += {"(": 1, ")": -1}.get(expr[j], 0)
                j += 1
            out += "(" + ks_expr_to_python(expr[i + 1:j - 1]) + ")"
            i = j
        else:
            out += expr[i]
            i += 1
    depth, q = 0, None
    for k, ch in enumerate(out):
        depth += {"(": 1, ")": -1}.get(ch, 0)
        if depth == 0 and ch == "?" and q is None:
            q = k
        elif depth == 0 and ch == ":" and q is not None:
            return f"(({out[q + 1:k]}) if ({out[:q]}) else ({ks_expr_to_python(out[k + 1:])}))"
    return out


def test_ksy_random_access_agrees_with_the_decoder(ksy, rng):
    from types import SimpleNamespace

    from lopcook.lop.binning import make_bins, table_bit_id, vertex_widths
    from lopcook.lop.bitplane import decode, pack, reconstruct_float64, top_bits

    vertex_t, field_t = ksy["types"]["packed_vertex"]["instances"], ksy["types"]["bit_field"]["instances"]
    py = {name: compile(ks_expr_to_python(" ".join(str(inst[key]).split())), name, "eval")
          for t in (vertex_t, field_t) for name, inst in t.items() for key in ("value",) if key in inst}
    py_if = compile(ks_expr_to_python(field_t["word_hi"]["if"]), "if", "eval")
    call = {c: re.fullmatch(r"bit_field\((.*), (.*)\)", vertex_t[c]["type"]).groups() for c in "xyz"}

    n = 300
    levels = rng.integers(1, 25, size=n)
    bins = make_bins(levels)
    q = rng.integers(0, 1 << 24, size=(n, 3)).astype(np.uint32)[bins.order]  # binned order
    origin, extent = (-1.25, 0.5, 3.0), 2.5
    for level in (1, 7, 13, 24):
        vid = [int(v) for v in bins.vertex_id]
        bit_id = [int(v) for v in table_bit_id(bins.vertex_id, level)]
        words = [int(w) for w in pack(top_bits(q, vertex_widths(bins.vertex_id, level)), bins.vertex_id, level)]
        ref, widths = decode(np.array(words, np.uint32), bins.vertex_id, np.array(bit_id), level)
        ref_pos = reconstruct_float64(ref, widths, origin, extent / (1 << 24))
        parent = SimpleNamespace(level=level, vertex_id=vid, bit_id=bit_id, origin_x=origin[0],
                                 origin_y=origin[1], origin_z=origin[2], extent=extent)
        for j in range(n):
            ns = {"j": j, "_parent": parent}
            for name in ("bin", "bits", "ofs_bit"):
                ns[name] = eval(py[name], ns)
            for c in "xyz":
                f = {"ofs_bit": eval(call[c][0], dict(ns)), "width": eval(call[c][1], dict(ns))}
                f["word_lo"] = words[f["ofs_bit"] >> 5]
                f["word_hi"] = words[(f["ofs_bit"] >> 5) + 1] if eval(py_if, dict(f)) else None
                ns[c] = SimpleNamespace(value=eval(py["value"], f))
            assert ns["bits"] == widths[j]
            assert [ns[c].value for c in "xyz"] == ref[j].tolist(), (level, j)
            s = 24 - ns["bits"]
            assert [eval(py[f"grid_{c}"], ns) for c in "xyz"] == [int(v) >> s << s for v in q[j]]
            np.testing.assert_allclose([eval(py[f"position_{c}"], ns) for c in "xyz"], ref_pos[j], rtol=0, atol=1e-12)


def test_ksy_attribute_expressions_agree_with_the_decoders(ksy, rng):
    """The attribute_record's field offsets are the codec's record layout, and its decode
    instances, evaluated in float32 one operation at a time, are bit-exact with decode_record."""
    from types import SimpleNamespace

    from lopcook.lop.codecs import AttributeBits
    from lopcook.lop.record import decode_record, pack_record, record_fields, unpack_record

    inst = ksy["types"]["attribute_record"]["instances"]
    sec = ksy["types"]["attributes_section"]["instances"]
    py = {name: compile(ks_expr_to_python(" ".join(str(i["value"]).split())), name, "eval")
          for name, i in inst.items() if "value" in i}
    sec_py = {name: compile(ks_expr_to_python(" ".join(str(i["value"]).split())), name, "eval")
              for name, i in sec.items() if "value" in i}
    call = {name: re.fullmatch(r"bit_field\((.*), (.*)\)", i["type"]).groups() for name, i in inst.items()
            if "type" in i}
    fields = {("normals", 0): "normal_u", ("normals", 1): "normal_v", ("uvs", 0): "uv_u", ("uvs", 1): "uv_v",
              ("colors", 0): "color_r", ("colors", 1): "color_g", ("colors", 2): "color_b", ("colors", 3): "color_a",
              ("tangents", 0): "tangent_u", ("tangents", 1): "tangent_v", ("tangents", 2): "tangent_sign"}
    f32 = np.float32
    for bits in (AttributeBits(4, 6, 4), AttributeBits(11, 9, 5), AttributeBits(16, 16, 8), AttributeBits(7, None, 6),
                 AttributeBits(16, 16, 8, 16), AttributeBits(5, None, None, 4), AttributeBits(9, 7, None, 13)):
        n = 60
        codes = {k: rng.integers(0, 1 << getattr(bits, k), size=(n, c)) for k, c in
                 (("normals", 2), ("uvs", 2), ("colors", 4)) if getattr(bits, k) is not None}
        if bits.tangents:
            codes["tangents"] = np.concatenate([rng.integers(0, 1 << bits.tangents, size=(n, 2)),
                                                rng.integers(0, 2, size=(n, 1))], axis=1)
        codes["normals"][:3] = [[0, 0], [1, (1 << bits.normals) - 1], [1 << (bits.normals - 1)] * 2]
        words = pack_record(codes, n, bits)
        lo, step = [f32(-0.25), f32(0.5)], [f32(1.75 / 65535), f32(0.001)]
        ref = decode_record(words, n, bits, {"uv_range": [[float(lo[0]), float(lo[1])], [0.0, 0.0]],
                                             "uv_step": [float(v) for v in step]})
        unpacked = unpack_record(words, n, bits)
        parent = SimpleNamespace(bits_normal=bits.normals or 0, bits_uv=bits.uvs or 0, bits_color=bits.colors or 0,
                                 bits_tangent=bits.tangents or 0, lo_u=lo[0], lo_v=lo[1], step_u=step[0], step_v=step[1])
        for name in ("record_bits", "ofs_uv", "ofs_color", "ofs_tangent"):
            setattr(parent, name, eval(sec_py[name], {**vars(parent)}))
        assert parent.record_bits == bits.record_bits
        for j in range(n):
            ns = {"j": j, "_parent": parent}
            ns["ofs_bit"] = eval(py["ofs_bit"], ns)
            for attr_name, c, off, width in record_fields(bits):
                fname = fields[(attr_name, c)]
                o, w = (eval(e, dict(ns)) for e in call[fname])
                assert (o, w) == (j * bits.record_bits + off, width), fname
                ns[fname] = SimpleNamespace(value=int(unpacked[attr_name][j, c]))
            out = {}
            tangent_names = ("half_t", "inv_t", "tp_x", "tp_y", "abs_tp_x", "abs_tp_y", "tangent_z", "tangent_x",
                             "tangent_y", "tangent_w")
            for name in ("half_n", "inv_n", "p_x", "p_y", "abs_p_x", "abs_p_y", "oct_z", "oct_x", "oct_y",
                         "u", "v", "inv_c", "r_f", "g_f", "b_f", "a_f") + tangent_names:
                group = {"half_n": "normals", "inv_n": "normals", "u": "uvs", "v": "uvs", "inv_c": "colors",
                         "r_f": "colors", "g_f": "colors", "b_f": "colors", "a_f": "colors",
                         **dict.fromkeys(tangent_names, "tangents")}.get(name, "normals")
                if getattr(bits, group) is None:
                    continue
                val = eval(py[name], ns)
                ns[name] = out[name] = val if name in ("half_n", "half_t") else f32(val)
            if bits.normals:
                want = ref["normals"][j]
                assert [out["oct_x"], out["oct_y"], out["oct_z"]] == want.tolist() or np.array_equal(
                    np.array([out["oct_x"], out["oct_y"], out["oct_z"]], f32).view(np.uint32), want.view(np.uint32))
            if bits.uvs:
                assert np.array_equal(np.array([out["u"], out["v"]], f32), ref["uvs"][j])
            if bits.colors:
                assert np.array_equal(np.array([out[f"{c}_f"] for c in "rgba"], f32), ref["colors"][j])
            if bits.tangents:
                got = np.array([out[f"tangent_{c}"] for c in "xyzw"], f32)
                assert np.array_equal(got.view(np.uint32), ref["tangents"][j].view(np.uint32))

