"""Property-based fuzz of the container reader and of each importer (issue 17).

Each test mutates a valid input (a value anywhere in the JSON replaced by an arbitrary JSON value,
bytes flipped with the checksums recomputed, truncations, random OBJ statements, random numbers
in a usda stage) and asserts the one contract: the reader returns a result (which then decodes),
or raises one ``LopcookError`` whose message is one line without a Python exception name.
Example counts are small and the runs derandomized, so the suite is deterministic and fits CI.
"""

from __future__ import annotations

import copy
import json
import re
import zlib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support import fuzzcases as fz
from lopcook.lop import reader
from lopcook.lop.container import from_bytes
from lopcook.errors import LopcookError
from lopcook.ingest import load

EXC_NAME = re.compile(r"\b\w+(Error|Exception)\b")
FUZZ = settings(max_examples=40, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                       HealthCheck.data_too_large])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(1 << 40), 1 << 40) | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8) | st.sampled_from([0, 1, -1, 24, 65535, 1 << 31, 1e39, "", "VEC3", 5126]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=8)


def _paths(obj, prefix=()):
    """Every (key, ...) path into a JSON document, containers included."""
    out = [prefix]
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj[:6]):
            out += _paths(v, prefix + (i,))
    return out


def _replace(doc, path, value):
    """``doc`` with the value at ``path`` replaced (unchanged when an earlier mutation removed
    the path)."""
    doc = copy.deepcopy(doc)
    if not path:
        return value
    node = doc
    try:
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    except (KeyError, IndexError, TypeError):
        pass
    return doc


def _clean(exc: LopcookError) -> None:
    text = str(exc)
    assert "\n" not in text and not EXC_NAME.search(text), text


@pytest.fixture(scope="module")
def lop(tmp_path_factory):
    data = fz._lop_base(tmp_path_factory.mktemp("lop"))
    manifest, _, payload = fz._lop_split(data)
    return data, manifest, payload, _paths(manifest)


def _read_and_decode(blob: bytes) -> None:
    try:
        c = from_bytes(blob, "x.lop", allow_prefix=True)
        for i, p in enumerate(c.manifest["parts"]):
            for k in range(len(p["lods"])):
                reader.decode_positions(c, i, k, c.available_level)
                reader.lod_attributes(c, i, k)
    except LopcookError as exc:
        _clean(exc)


@FUZZ
@given(data=st.data())
def test_container_manifest_mutations(lop, data):
    _, manifest, payload, paths = lop
    path = data.draw(st.sampled_from(paths))
    value = data.draw(json_values)
    _read_and_decode(fz._lop_with(_replace(manifest, path, value), payload))


@FUZZ
@given(data=st.data())
def test_container_payload_flips_with_crcs_recomputed(lop, data):
    _, manifest, payload, _ = lop
    m = copy.deepcopy(manifest)
    pay = bytearray(payload)
    for _ in range(data.draw(st.integers(1, 8))):
        pos = data.draw(st.integers(0, len(pay) - 1))
        pay[pos] ^= data.draw(st.integers(1, 255))
    for s in m["sections"]:
        s["crc32"] = zlib.crc32(bytes(pay[s["offset"]:s["offset"] + s["length"]]))
    _read_and_decode(fz._lop_with(m, bytes(pay)))


@FUZZ
@given(cut=st.integers(0, 20000), flips=st.lists(st.tuples(st.integers(0, 20000), st.integers(1, 255)), max_size=3))
def test_container_raw_truncations_and_flips(lop, cut, flips):
    blob = bytearray(lop[0][:cut % (len(lop[0]) + 1)])
    for pos, x in flips:
        if blob:
            blob[pos % len(blob)] ^= x
    _read_and_decode(bytes(blob))


@pytest.fixture(scope="module")
def gltf_doc():
    doc, blob = fz._gltf_doc()
    doc = fz._textured(doc, {"uri": "data:image/png;base64,"})
    return doc, blob, _paths(doc)


@FUZZ
@given(data=st.data())
def test_gltf_json_mutations(gltf_doc, tmp_path_factory, data):
    doc, blob, paths = gltf_doc
    mutated = doc
    for _ in range(data.draw(st.integers(1, 3))):
        mutated = _replace(mutated, data.draw(st.sampled_from(paths)), data.draw(json_values))
        if not isinstance(mutated, dict):
            break
    p = tmp_path_factory.mktemp("g") / "a.glb"
    p.write_bytes(fz._glb(mutated, blob) if isinstance(mutated, dict) else b"glTF" + json.dumps(mutated).encode())
    try:
        scene = load(str(p))
    except LopcookError as exc:
        _clean(exc)
    else:
        assert scene.n_triangles > 0


@FUZZ
@given(cut=st.integers(0, 4000), flips=st.lists(st.tuples(st.integers(0, 4000), st.integers(1, 255)), max_size=4))
def test_glb_bytes(gltf_doc, tmp_path_factory, cut, flips):
    glb = bytearray(fz._glb(gltf_doc[0], gltf_doc[1]))
    glb = glb[:max(cut % (len(glb) + 1), 1)]
    for pos, x in flips:
        glb[pos % len(glb)] ^= x
    p = tmp_path_factory.mktemp("b") / "a.glb"
    p.write_bytes(bytes(glb))
    try:
        load(str(p))
    except LopcookError as exc:
        _clean(exc)


number = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64).map(repr),
                   st.integers(-5, 12).map(str), st.sampled_from(["1e39", "-0", "1\\", "0x1p3", ".", "e", "+", ""]))
corner = st.one_of(number, st.tuples(st.integers(-9, 12), st.integers(-3, 4)).map(lambda t: f"{t[0]}/{t[1]}"),
                   st.integers(-9, 12).map(lambda i: f"{i}//{i}"))
obj_line = st.one_of(
    st.lists(number, min_size=0, max_size=5).map(lambda v: "v " + " ".join(v)),
    st.lists(number, min_size=0, max_size=3).map(lambda v: "vt " + " ".join(v)),
    st.lists(number, min_size=0, max_size=4).map(lambda v: "vn " + " ".join(v)),
    st.lists(corner, min_size=0, max_size=7).map(lambda v: "f " + " ".join(v)),
    st.sampled_from(["o a", "g b", "usemtl m", "mtllib a.mtl", "s 1", "l 1 2", "# c", "\\", "", "p 1",
                     "v 0 0 0", "v 1 0 0", "v 0 1 0", "f 1 2 3", "f -1 -2 -3"]),
)


@FUZZ
@given(lines=st.lists(obj_line, min_size=1, max_size=14))
def test_obj_statements(tmp_path_factory, lines):
    d = tmp_path_factory.mktemp("o")
    (d / "a.mtl").write_text("newmtl m\nmap_Kd t.png\n")
    (d / "t.png").write_bytes(b"junk")
    p = d / "a.obj"
    p.write_text("\n".join(lines) + "\n")
    try:
        scene = load(str(p))
    except LopcookError as exc:
        _clean(exc)
    else:
        assert all(part.texture is None for part in scene.parts)


@settings(max_examples=8, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(values=st.lists(number, min_size=1, max_size=6), counts=st.lists(st.integers(-2, 9), min_size=1, max_size=7))
def test_usda_numbers(tmp_path_factory, values, counts):
    points = ", ".join(f"({v}, 0, 1)" for v in values)
    text = (fz._USDA_HEAD + 'def Xform "R" {\ndef Mesh "m" {\nint[] faceVertexCounts = [' + ", ".join(map(str, counts))
            + "]\nint[] faceVertexIndices = ["
            + ", ".join(str(i % 7 - 1) for i in range(sum(max(c, 0) for c in counts)))
            + "]\npoint3f[] points = [" + points + "]\n}\n}\n")
    p = tmp_path_factory.mktemp("u") / "a.usda"
    p.write_text(text)
    try:
        load(str(p))
    except LopcookError as exc:
        _clean(exc)
