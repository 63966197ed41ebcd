"""Hostile and malformed inputs for the importers and the container reader, and the classifier
that judges how the CLI treats them (docs/ingest.md, "Hostile input and limits").

``generate(root)`` writes a deterministic corpus (every case in its own directory under ``root``)
built from the project fixtures (``tests.support.fixtures``): glTF/GLB, OBJ, USD (usda, usdc, usdz) and
``.lop`` files with truncations, byte flips, lying lengths and counts (with the checksums
recomputed so that the lie passes them), degenerate geometry, hostile texture references,
scene-graph depth and instancing bombs, and non-regular files (FIFOs, ``/dev/zero`` symlinks).
It returns one ``Case`` per CLI invocation.

``run_case(case)`` runs ``python -m lopcook <command> ...`` in a subprocess under a wall-clock
limit (``TIMEOUT_S``) and an address-space limit (``RLIMIT_AS``, ``MEMORY_BYTES``), and
``classify`` puts the outcome in exactly one class of ``CLASSES``:

=================  ==========================================================================
``ok``             exit 0 (a cook wrote a valid container; a case that must warn did warn)
``clean``          exit 2 with one line on stderr naming the file, no Python exception name
``exit3``          exit 3 (internal error)
``traceback``      a Python traceback on stderr
``signal``         killed by a signal (a native crash)
``timeout``        still running after ``TIMEOUT_S``
``memory``         ran out of memory (MemoryError, ``out of memory``, ``bad_alloc``)
``clobbered``      a failed run changed an existing output, the source changed, or a partial
                   or temporary file was left behind
``multiline``      exit 2 with more than one line on stderr
``unnamed``        exit 2 whose line does not name the file, or names a Python exception
``accepted``       exit 0 for an input that must be refused (garbage accepted silently)
``refused``        exit 2 for a valid input that must cook
``unwarned``       exit 0 for an input whose defect must be reported as a warning, without one
``other``          any other exit status
=================  ==========================================================================

Everything but ``ok`` and ``clean`` is a failure. ``python -m tests.support.fuzzcases [ROOT]`` (from
the repository root) runs the whole corpus and prints the count per class.
"""

from __future__ import annotations

import base64
import copy
import functools
import json
import os
import re
import struct
import subprocess
import sys
import zlib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lopcook.lop.container import READABLE_MAJORS, VERSION, manifest_bytes
from lopcook.emit.gltf_writer import pack_glb

from . import fixtures
from .fixtures import _gltf_document, write_gltf, write_obj, write_usd

#: wall-clock limit of one CLI run, seconds
TIMEOUT_S = 60
#: address-space limit of one CLI run (RLIMIT_AS), bytes
MEMORY_BYTES = 4 << 30

CLASSES = ("ok", "clean", "exit3", "traceback", "signal", "timeout", "memory", "clobbered",
           "multiline", "unnamed", "accepted", "refused", "unwarned", "other")
SENTINEL = b"SENTINEL: an earlier output that a failed run must leave alone\n"
_EXC_NAMES = re.compile(r"\b(\w+Error|\w+Exception|struct\.error|KeyError|StopIteration)\b")


@dataclass(frozen=True)
class Case:
    """One CLI run over one generated input.

    ``name`` is unique (``family/what``); ``directory`` holds the input and the outputs;
    ``source`` is the input's file name inside it; ``command`` is ``cook``, ``inspect`` or
    ``decode``; ``expect`` is ``clean`` (exit 0 or a clean exit 2), ``refuse`` (must exit 2),
    ``ok`` (must exit 0) or ``warn`` (must exit 0 with a warning in ``--json``).
    """

    name: str
    directory: str
    source: str
    command: str
    expect: str = "clean"
    slow: bool = False

    @property
    def run_directory(self) -> str:
        """Working directory of the run (one per command, so runs over one input never share
        outputs); the input is ``../source`` from there."""
        return os.path.join(self.directory, f"run-{self.command}")

    def argv(self) -> list[str]:
        src = os.path.join("..", self.source)
        if self.command == "cook":
            return ["cook", src, "-o", "out.lop", "--depfile", "out.d", "--json"]
        if self.command == "decode":
            return ["decode", src, "--level", "24", "-o", "out.glb", "-q"]
        return ["inspect", src]

    def outputs(self) -> list[str]:
        return {"cook": ["out.lop", "out.d"], "decode": ["out.glb"]}.get(self.command, [])


@dataclass
class Result:
    case: Case
    klass: str
    returncode: int | None
    stderr: str
    seconds: float = 0.0
    detail: str = ""


# ============================================================================ helpers


def _fixture_parts(name: str):
    return getattr(fixtures, name)()


def _gltf_doc(parts=None) -> tuple[dict, bytes]:
    return _gltf_document(parts or _fixture_parts("seamed_cube"), None, None)


def _glb(doc: dict, blob: bytes) -> bytes:
    return pack_glb(json.dumps(doc, separators=(",", ":")).encode("utf-8"), blob)


def _gltf_text(doc: dict, blob: bytes | None) -> bytes:
    doc = copy.deepcopy(doc)
    if blob is not None:
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    return json.dumps(doc).encode("utf-8")


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png(width: int = 4, height: int = 4, rows: bytes | None = None) -> bytes:
    """A small RGB PNG (or one of any size, compressed from zero rows, without allocating it)."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    comp = zlib.compressobj(9)
    row = b"\0" + (rows or bytes(3 * width))
    parts = []
    for _ in range(height):
        parts.append(comp.compress(row))
    parts.append(comp.flush())
    return b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", b"".join(parts)) + \
        _png_chunk(b"IEND", b"")


def _bomb_png(width: int = 12000, height: int = 12000) -> bytes:
    """A 1-bit greyscale PNG of ``width`` x ``height`` pixels (a decompression bomb: 12k x 12k is
    144 M pixels from about 20 KB), compressed without ever holding the image."""
    ihdr = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    comp = zlib.compressobj(1)
    row = bytes(1 + (width + 7) // 8)
    block = row * 256
    parts = [comp.compress(block) for _ in range(height // 256)]
    parts.append(comp.compress(row * (height % 256)))
    parts.append(comp.flush())
    return b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", b"".join(parts)) + \
        _png_chunk(b"IEND", b"")


@functools.lru_cache(maxsize=1)
def _bad_pngs_cached() -> tuple:
    return tuple(_make_bad_pngs().items())


def _bad_pngs() -> dict[str, bytes]:
    """Name -> encoded bytes of each defective image (truncated, bad CRC, corrupt IDAT, zeroed,
    huge declared size, junk, empty, decompression bomb)."""
    return dict(_bad_pngs_cached())


def _make_bad_pngs() -> dict[str, bytes]:
    good = _png(8, 8, bytes(range(24)))
    ihdr_end = 8 + 8 + 13 + 4
    bad_crc = bytearray(good)
    bad_crc[ihdr_end - 1] ^= 0xFF
    idat_start = ihdr_end + 8
    corrupt = bytearray(good)
    # corrupt the zlib stream and recompute the chunk CRC so that only the data is wrong
    (idat_len,) = struct.unpack_from(">I", good, ihdr_end)
    for k in range(2, idat_len):
        corrupt[idat_start + k] ^= 0x5A
    corrupt[idat_start + idat_len:idat_start + idat_len + 4] = struct.pack(
        ">I", zlib.crc32(bytes(corrupt[idat_start - 4:idat_start + idat_len])))
    huge = bytearray(good)
    huge[16:24] = struct.pack(">II", 1 << 20, 1 << 20)
    huge[29:33] = struct.pack(">I", zlib.crc32(bytes(huge[12:29])))
    return {
        "truncated_png": good[: len(good) // 2],
        "bad_crc_png": bytes(bad_crc),
        "corrupt_idat_png": bytes(corrupt),
        "zeroed_png": bytes(len(good)),
        "huge_dims_png": bytes(huge),
        "junk_png": b"this is not an image\n" * 4,
        "empty_png": b"",
        "bomb_png": _bomb_png(),
    }


def _mkfifo(path: Path) -> bool:
    try:
        os.mkfifo(path)
        return True
    except (AttributeError, OSError):
        return False


# ============================================================================ generator


class _Writer:
    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.cases: list[Case] = []

    def case(self, name: str, files: dict[str, bytes | str | None], source: str, commands=("cook",),
             expect: str = "clean", slow: bool = False, links: dict[str, str] | None = None,
             fifos: tuple[str, ...] = ()) -> None:
        d = self.root / name.replace("/", "__")
        d.mkdir(parents=True, exist_ok=True)
        for fname, data in files.items():
            p = d / fname
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
        for fname, target in (links or {}).items():
            if not (d / fname).is_symlink():
                os.symlink(target, d / fname)
        for fname in fifos:
            if not (d / fname).exists() and not _mkfifo(d / fname):
                return
        for cmd in commands:
            self.cases.append(Case(f"{name}:{cmd}", str(d), source, cmd, expect, slow))


def generate(root: str | os.PathLike, *, seed: int = 17) -> list[Case]:
    """Write the corpus under ``root`` and return its cases (deterministic for a seed)."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    w = _Writer(root)
    rng = np.random.default_rng(seed)
    _gltf_cases(w, rng)
    _obj_cases(w, rng)
    _usd_cases(w, rng)
    _lop_cases(w, rng)
    _stream_cases(w)
    names = [c.name for c in w.cases]
    assert len(names) == len(set(names)), "case names must be unique"
    return w.cases


# ---------------------------------------------------------------------------- glTF


def _textured(doc: dict, image: dict) -> dict:
    doc = copy.deepcopy(doc)
    doc["images"] = [image]
    doc["textures"] = [{"source": 0}]
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            prim["material"] = 0
    return doc


def _gltf_cases(w: _Writer, rng) -> None:
    doc, blob = _gltf_doc()
    pos_acc = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    idx_acc = doc["meshes"][0]["primitives"][0]["indices"]
    n_vert = doc["accessors"][pos_acc]["count"]

    def emit(name, d, b, expect="clean", formats=("glb",), slow=False, commands=("cook",)):
        if "gltf" in formats:
            w.case(f"gltf/{name}", {"a.gltf": _gltf_text(d, b)}, "a.gltf", commands, expect, slow)
        if "glb" in formats:
            w.case(f"glb/{name}", {"a.glb": _glb(d, b)}, "a.glb", commands, expect, slow)

    def mut(fn):
        d = copy.deepcopy(doc)
        b = bytearray(blob)
        fn(d, b)
        return d, bytes(b)

    def acc(i, **kw):
        return lambda d, b: d["accessors"][i].update(kw)

    # lying counts and lengths
    for label, count in (("2p31", 1 << 31), ("30M", 30_000_000), ("2p40", 1 << 40)):
        emit(f"position_count_{label}", *mut(acc(pos_acc, count=count)), "refuse")
        emit(f"index_count_{label}", *mut(acc(idx_acc, count=count)), "refuse")
        d = copy.deepcopy(doc)
        d["accessors"].append({"componentType": 5126, "type": "VEC3", "count": count})
        d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = len(d["accessors"]) - 1
        emit(f"no_view_position_count_{label}", d, blob, "refuse")
    emit("count_zero", *mut(acc(pos_acc, count=0)), "refuse")
    emit("count_string", *mut(acc(pos_acc, count="24")), "refuse")
    emit("count_float", *mut(acc(pos_acc, count=24.5)), "refuse")
    emit("count_negative", *mut(acc(pos_acc, count=-24)), "refuse")
    emit("buffer_bytelength_negative", *mut(lambda d, b: d["buffers"][0].update(byteLength=-1)), "refuse")
    emit("buffer_bytelength_huge", *mut(lambda d, b: d["buffers"][0].update(byteLength=1 << 40)), "refuse")
    emit("buffer_bytelength_string", *mut(lambda d, b: d["buffers"][0].update(byteLength="big")), "refuse")
    emit("view_bytelength_negative", *mut(lambda d, b: d["bufferViews"][0].update(byteLength=-8)), "refuse")
    emit("view_bytelength_huge", *mut(lambda d, b: d["bufferViews"][0].update(byteLength=1 << 33)), "refuse")
    emit("view_offset_negative", *mut(lambda d, b: d["bufferViews"][0].update(byteOffset=-4)), "refuse")
    emit("view_offset_float", *mut(lambda d, b: d["bufferViews"][0].update(byteOffset=0.5)), "refuse")
    emit("stride_zero_len", *mut(lambda d, b: d["bufferViews"][0].update(byteStride=1)), "refuse")
    emit("stride_huge", *mut(lambda d, b: d["bufferViews"][0].update(byteStride=1 << 30)), "refuse")
    emit("stride_negative", *mut(lambda d, b: d["bufferViews"][0].update(byteStride=-12)), "refuse")
    emit("accessor_offset_negative", *mut(acc(pos_acc, byteOffset=-12)), "refuse")
    emit("accessor_offset_huge", *mut(acc(pos_acc, byteOffset=1 << 40)), "refuse")
    emit("component_type_bad", *mut(acc(pos_acc, componentType=5127)), "refuse")
    emit("component_type_string", *mut(acc(pos_acc, componentType="FLOAT")), "refuse")
    emit("type_bad", *mut(acc(pos_acc, type="MAT4")), "refuse")
    emit("type_list", *mut(acc(pos_acc, type=["VEC3"])), "refuse")
    emit("sparse_count_huge", *mut(acc(pos_acc, sparse={
        "count": 1 << 31, "indices": {"bufferView": 0, "componentType": 5125},
        "values": {"bufferView": 0}})), "refuse")
    emit("view_index_bad", *mut(acc(pos_acc, bufferView=99)), "refuse")
    emit("view_index_bool", *mut(acc(pos_acc, bufferView=True)), "refuse")
    emit("buffer_index_bad", *mut(lambda d, b: d["bufferViews"][0].update(buffer=7)), "refuse")
    emit("index_out_of_range", *mut(lambda d, b: b.__setitem__(
        slice(d["bufferViews"][d["accessors"][idx_acc]["bufferView"]]["byteOffset"],
              d["bufferViews"][d["accessors"][idx_acc]["bufferView"]]["byteOffset"] + 2),
        struct.pack("<H", 60000))), "refuse")
    emit("index_count_not_multiple_of_3", *mut(acc(idx_acc, count=35)), "refuse")
    emit("mode_bad", *mut(lambda d, b: d["meshes"][0]["primitives"][0].update(mode=9)), "refuse")
    emit("mode_string", *mut(lambda d, b: d["meshes"][0]["primitives"][0].update(mode="TRIANGLES")),
         "refuse")
    emit("strip_one_index", *mut(lambda d, b: (d["meshes"][0]["primitives"][0].update(mode=5),
                                               d["accessors"][idx_acc].update(count=1))), "refuse")
    emit("attributes_list", *mut(lambda d, b: d["meshes"][0]["primitives"][0].update(attributes=[0])),
         "refuse")
    emit("primitives_dict", *mut(lambda d, b: d["meshes"][0].update(primitives={})), "refuse")
    emit("mesh_index_bad", *mut(lambda d, b: d["nodes"][0].update(mesh=5)), "refuse")
    emit("mesh_index_float", *mut(lambda d, b: d["nodes"][0].update(mesh=0.0)), "refuse")
    emit("node_cycle", *mut(lambda d, b: d["nodes"].append({"children": [1]}) or d["nodes"][1].update(children=[1])
                            or d["scenes"][0]["nodes"].append(1)), "refuse")
    emit("child_bad", *mut(lambda d, b: d["nodes"][0].update(children=[42])), "refuse")
    emit("children_string", *mut(lambda d, b: d["nodes"][0].update(children="1")), "refuse")
    emit("scene_bad", *mut(lambda d, b: d.update(scene=3)), "refuse")
    emit("scenes_not_list", *mut(lambda d, b: d.update(scenes={"nodes": [0]})), "refuse")
    emit("nodes_not_list", *mut(lambda d, b: d.update(nodes={"0": {}})), "refuse")
    emit("matrix_short", *mut(lambda d, b: d["nodes"][0].update(matrix=[1, 0, 0])), "refuse")
    emit("matrix_strings", *mut(lambda d, b: d["nodes"][0].update(matrix=["a"] * 16)), "refuse")
    emit("rotation_zero", *mut(lambda d, b: d["nodes"][0].update(rotation=[0, 0, 0, 0])), "refuse")
    emit("scale_1e200", *mut(lambda d, b: d["nodes"][0].update(scale=[1e200, 1e200, 1e200])), "refuse")
    emit("scale_1e300_nested", *mut(lambda d, b: (d["nodes"].append({"children": [0], "scale": [1e300] * 3}),
                                                  d["scenes"][0].update(nodes=[1]))), "refuse")
    emit("translation_1e308", *mut(lambda d, b: d["nodes"][0].update(translation=[1e308, 0, 0])), "clean")
    emit("version_3", *mut(lambda d, b: d["asset"].update(version="3.0")), "refuse")
    emit("asset_string", *mut(lambda d, b: d.update(asset="2.0")), "clean")
    emit("extensions_required_string", *mut(lambda d, b: d.update(extensionsRequired="KHR_x")), "refuse")
    emit("extensions_required_draco", *mut(lambda d, b: d.update(extensionsRequired=["KHR_draco_mesh_compression"])),
         "refuse")
    # compressed data read as if it were plain: used but not required
    emit("draco_used_not_required", *mut(lambda d, b: (
        d.update(extensionsUsed=["KHR_draco_mesh_compression"]),
        d["meshes"][0]["primitives"][0].update(extensions={"KHR_draco_mesh_compression": {
            "bufferView": 0, "attributes": {"POSITION": 0}}}))), "refuse")
    emit("meshopt_used_not_required", *mut(lambda d, b: (
        d.update(extensionsUsed=["EXT_meshopt_compression"]),
        d["bufferViews"][0].update(extensions={"EXT_meshopt_compression": {
            "buffer": 0, "byteLength": 8, "byteStride": 12, "count": n_vert, "mode": "ATTRIBUTES"}}))),
         "refuse")
    emit("khr_meshopt_used_not_required", *mut(lambda d, b: (
        d.update(extensionsUsed=["KHR_meshopt_compression"]),
        d["bufferViews"][0].update(extensions={"KHR_meshopt_compression": {
            "buffer": 0, "byteLength": 8, "byteStride": 12, "count": n_vert, "mode": "ATTRIBUTES"}}))),
         "refuse")
    # deeply nested JSON (extras)
    deep = "[" * 100_000 + "]" * 100_000
    text = _gltf_text(doc, blob).decode()
    w.case("gltf/deep_json_extras", {"a.gltf": text[:-1] + ', "extras": ' + deep + "}"}, "a.gltf",
           expect="clean")
    w.case("gltf/deep_json_top", {"a.gltf": deep}, "a.gltf", expect="refuse")
    w.case("gltf/utf16", {"a.gltf": text.encode("utf-16")}, "a.gltf", expect="refuse")
    w.case("gltf/json_array", {"a.gltf": "[1, 2, 3]"}, "a.gltf", expect="refuse")
    w.case("gltf/json_nan", {"a.gltf": text.replace('"scene": 0', '"scene": NaN')}, "a.gltf", expect="refuse")
    w.case("gltf/huge_number", {"a.gltf": text.replace('"scene": 0', '"scene": 1' + "0" * 5000)}, "a.gltf",
           expect="refuse")
    w.case("gltf/empty_object", {"a.gltf": "{}"}, "a.gltf", expect="refuse")
    # degenerate geometry: cook succeeds or refuses cleanly
    pv = doc["bufferViews"][doc["accessors"][pos_acc]["bufferView"]]
    po = pv["byteOffset"]

    def set_positions(fn):
        def f(d, b):
            p = np.frombuffer(bytes(b[po:po + 12 * n_vert]), "<f4").reshape(-1, 3).astype(np.float64)
            q = np.asarray(fn(p), dtype=np.float64)
            with np.errstate(over="ignore"):
                b[po:po + 12 * n_vert] = q.astype("<f4").tobytes()
            d["accessors"][pos_acc]["min"] = [float(x) for x in q.astype("<f4").min(axis=0)]
            d["accessors"][pos_acc]["max"] = [float(x) for x in q.astype("<f4").max(axis=0)]
        return f

    f32max = float(np.finfo(np.float32).max)
    emit("degenerate_all_indices_zero", *mut(lambda d, b: b.__setitem__(
        slice(d["bufferViews"][d["accessors"][idx_acc]["bufferView"]]["byteOffset"],
              d["bufferViews"][d["accessors"][idx_acc]["bufferView"]]["byteOffset"] + 72), bytes(72))),
         commands=("cook", "inspect"))
    emit("degenerate_identical_positions", *mut(set_positions(lambda p: np.ones_like(p) * 0.25)),
         commands=("cook", "inspect"))
    emit("offset_1e20", *mut(set_positions(lambda p: p + 1e20)), commands=("cook", "inspect"))
    emit("offset_1e30", *mut(set_positions(lambda p: p + 1e30)), commands=("cook", "inspect"))
    emit("float32_max", *mut(set_positions(lambda p: np.sign(p) * f32max)), commands=("cook", "inspect"))
    emit("float32_max_half", *mut(set_positions(lambda p: p * f32max)), commands=("cook", "inspect"))
    emit("denormal_1e-44", *mut(set_positions(lambda p: np.sign(p) * 1e-44)), commands=("cook", "inspect"))
    emit("tiny_1e-30", *mut(set_positions(lambda p: p * 1e-30)), commands=("cook", "inspect"))
    emit("flat_plane", *mut(set_positions(lambda p: p * [1, 0, 1])), commands=("cook",))
    emit("collinear", *mut(set_positions(lambda p: p * [1, 0, 0])), commands=("cook",))
    emit("nan_positions", *mut(set_positions(lambda p: p * np.nan)), "refuse", formats=("glb",))
    emit("nan_normals", *mut(lambda d, b: b.__setitem__(
        slice(d["bufferViews"][d["accessors"][1]["bufferView"]]["byteOffset"],
              d["bufferViews"][d["accessors"][1]["bufferView"]]["byteOffset"] + 12),
        np.full(3, np.nan, "<f4").tobytes())), formats=("glb",))
    # a degenerate 10,000-gon as a triangle fan
    n = 10_000
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(ang), np.zeros(n), np.sin(ang) * 1e-12], axis=1).astype("<f4")
    fan = np.arange(n, dtype="<u4")
    d2 = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
          "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 6}]}],
          "accessors": [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": n,
                         "min": ring.min(0).tolist(), "max": ring.max(0).tolist()},
                        {"bufferView": 1, "componentType": 5125, "type": "SCALAR", "count": n}],
          "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": ring.nbytes},
                          {"buffer": 0, "byteOffset": ring.nbytes, "byteLength": fan.nbytes}],
          "buffers": [{"byteLength": ring.nbytes + fan.nbytes}]}
    emit("degenerate_10000gon_fan", d2, ring.tobytes() + fan.tobytes(), formats=("glb",))
    # scene graph size: many nodes, many primitives
    big = copy.deepcopy(doc)
    big["nodes"] = [{"mesh": 0} for _ in range(200_000)]
    big["scenes"] = [{"nodes": list(range(200_000))}]
    emit("nodes_200000", big, blob, formats=("glb",), slow=True)
    chain = copy.deepcopy(doc)
    chain["nodes"] = [{"children": [i + 1]} for i in range(100_000)] + [{"mesh": 0}]
    chain["scenes"] = [{"nodes": [0]}]
    emit("node_chain_100000", chain, blob, formats=("glb",), slow=True)
    empty_nodes = copy.deepcopy(doc)
    empty_nodes["nodes"] += [{} for _ in range(200_000)]
    empty_nodes["scenes"] = [{"nodes": list(range(len(empty_nodes["nodes"])))}]
    emit("empty_nodes_200000", empty_nodes, blob, formats=("glb",), slow=True)
    prims = copy.deepcopy(doc)
    prims["meshes"][0]["primitives"] = prims["meshes"][0]["primitives"] * 20_000
    emit("primitives_20000", prims, blob, formats=("glb",), slow=True)
    # textures
    images = _bad_pngs()
    for label, data in images.items():
        w.case(f"gltf/texture_{label}", {"a.gltf": _gltf_text(_textured(doc, {"uri": "t.png"}), blob),
                                         "t.png": data}, "a.gltf", expect="warn", slow=label == "bomb_png")
        d = _textured(doc, {"uri": "data:image/png;base64," + base64.b64encode(data).decode()})
        emit(f"texture_data_uri_{label}", d, blob, "warn", formats=("glb",), slow=label == "bomb_png")
    for label, uri in (("junk_data_uri", "data:image/png;base64,@@@@not base64!!"),
                       ("empty_data_uri", "data:"), ("data_uri_no_comma", "data:image/png;base64"),
                       ("newline_data_uri", "data:image/png;base64,\n\n"),
                       ("missing_file", "missing.png"),
                       ("traversal", "../../../../../../etc/passwd"), ("absolute", "/etc/passwd"),
                       ("dev_zero", "/dev/zero"), ("proc", "/proc/self/environ"),
                       ("dev_random", "/dev/urandom"), ("remote", "https://example.com/t.png"),
                       ("file_url", "file:///etc/passwd"), ("percent_nul", "t%00.png"),
                       ("directory", "."), ("uri_number", 7), ("long_name", "x" * 5000 + ".png")):
        emit(f"texture_{label}", _textured(doc, {"uri": uri}), blob, "warn", formats=("gltf",))
    emit("texture_newline_uri", _textured(doc, {"uri": "t\nx.png"}), blob, "refuse", formats=("gltf",))
    w.case("gltf/texture_symlink_dev_zero", {"a.gltf": _gltf_text(_textured(doc, {"uri": "t.png"}), blob)},
           "a.gltf", expect="warn", links={"t.png": "/dev/zero"})
    w.case("gltf/texture_fifo", {"a.gltf": _gltf_text(_textured(doc, {"uri": "t.png"}), blob)},
           "a.gltf", expect="warn", fifos=("t.png",))
    w.case("gltf/texture_newline_file", {"a.gltf": _gltf_text(_textured(doc, {"uri": "t%0Ax.png"}), blob),
                                         "t\nx.png": _png()}, "a.gltf", expect="refuse")
    w.case("gltf/texture_view_junk", {"a.glb": _glb(_textured(doc, {"bufferView": 0, "mimeType": "image/png"}),
                                                    blob)}, "a.glb", expect="warn")
    # external buffers
    ext = copy.deepcopy(doc)
    ext["buffers"][0]["uri"] = "a.bin"
    ext_text = json.dumps(ext).encode()
    w.case("gltf/bin_missing", {"a.gltf": ext_text}, "a.gltf", expect="refuse")
    w.case("gltf/bin_truncated", {"a.gltf": ext_text, "a.bin": blob[:len(blob) // 2]}, "a.gltf",
           expect="refuse")
    w.case("gltf/bin_symlink_dev_zero", {"a.gltf": ext_text}, "a.gltf", expect="refuse",
           links={"a.bin": "/dev/zero"})
    w.case("gltf/bin_fifo", {"a.gltf": ext_text}, "a.gltf", expect="refuse", fifos=("a.bin",))
    for label, uri in (("absolute", "/etc/passwd"), ("traversal", "../../../../../../../etc/passwd"),
                       ("dev_zero", "/dev/zero"), ("directory", "."), ("newline", "a\n.bin")):
        d = copy.deepcopy(doc)
        d["buffers"][0]["uri"] = uri
        w.case(f"gltf/bin_{label}", {"a.gltf": json.dumps(d)}, "a.gltf", expect="refuse")
    # the source itself is not a regular file
    w.case("gltf/source_symlink_dev_zero", {}, "a.glb", expect="refuse", links={"a.glb": "/dev/zero"})
    w.case("gltf/source_fifo", {}, "a.gltf", expect="refuse", fifos=("a.gltf",))
    w.case("gltf/source_directory", {"a.gltf/x": b""}, "a.gltf", expect="refuse")
    # GLB container lies, truncations and byte flips
    glb = _glb(doc, blob)
    def emit_raw(name, data, expect="clean"):
        w.case(f"glb/{name}", {"a.glb": data}, "a.glb", expect=expect)
    emit_raw("header_length_short", glb[:8] + struct.pack("<I", 16) + glb[12:], "refuse")
    emit_raw("header_length_long", glb[:8] + struct.pack("<I", len(glb) + 100) + glb[12:], "refuse")
    emit_raw("version_1", glb[:4] + struct.pack("<I", 1) + glb[8:], "refuse")
    emit_raw("json_chunk_length_huge", glb[:12] + struct.pack("<I", 1 << 31) + glb[16:], "refuse")
    emit_raw("json_chunk_type_bin", glb[:16] + struct.pack("<I", 0x004E4942) + glb[20:], "refuse")
    jlen = struct.unpack_from("<I", glb, 12)[0]
    bpos = 20 + jlen
    emit_raw("bin_chunk_length_huge", glb[:bpos] + struct.pack("<I", 1 << 30) + glb[bpos + 4:], "refuse")
    emit_raw("bin_chunk_missing", glb[:8] + struct.pack("<I", bpos) + glb[12:bpos], "refuse")
    emit_raw("trailing_garbage", glb + b"\0" * 64, "clean")
    for k, cut in enumerate(sorted(set(rng.integers(1, len(glb), 8).tolist()) | {1, 11, 12, 19, 20})):
        emit_raw(f"truncated_{cut}", glb[:cut], "refuse")
    for k in range(12):
        data = bytearray(glb)
        pos = int(rng.integers(0, len(glb)))
        data[pos] ^= int(rng.integers(1, 256))
        emit_raw(f"flip_{k:02d}_at_{pos}", bytes(data), "clean")
    gtxt = _gltf_text(doc, blob)
    for k in range(6):
        cut = int(rng.integers(1, len(gtxt)))
        w.case(f"gltf/truncated_{k:02d}_{cut}", {"a.gltf": gtxt[:cut]}, "a.gltf", expect="refuse")


# ---------------------------------------------------------------------------- OBJ


def _obj_cases(w: _Writer, rng) -> None:
    tmp = w.root / "_base"
    base = write_obj(_fixture_parts("seamed_cube"), tmp / "cube.obj").read_text()
    lines = base.splitlines()
    n_v = sum(1 for ln in lines if ln.startswith("v "))

    def obj(name, text, expect="clean", files=None, commands=("cook",), slow=False, **kw):
        w.case(f"obj/{name}", {"a.obj": text, **(files or {})}, "a.obj", commands, expect, slow, **kw)

    def replace_v(fn):
        out, k = [], 0
        for ln in lines:
            if ln.startswith("v "):
                xyz = np.array([float(t) for t in ln.split()[1:4]])
                out.append("v " + " ".join(repr(float(x)) for x in fn(xyz, k)))
                k += 1
            else:
                out.append(ln)
        return "\n".join(out) + "\n"

    f32max = float(np.finfo(np.float32).max)
    obj("backslash_in_number", base.replace("v 0.5", "v 0\\.5", 1), "refuse")
    obj("backslash_continuation_in_number", base.replace("v 0.5", "v 0\\\n.5", 1), "refuse")
    obj("comma_decimal", base.replace("v 0.5", "v 0,5", 1), "refuse")
    obj("hex_float", base.replace("v 0.5", "v 0x1p-1", 1), "refuse")
    obj("vertex_1e300", replace_v(lambda p, k: p * 1e300), "refuse")
    obj("vertex_1e39", replace_v(lambda p, k: p * 1e39), "refuse")
    obj("vertex_nan", base.replace("v 0.5", "v nan", 1), "refuse")
    obj("vertex_inf", base.replace("v 0.5", "v inf", 1), "refuse")
    obj("vertex_two_values", base.replace("v 0.5 ", "v ", 1), "refuse")
    obj("offset_1e20", replace_v(lambda p, k: p + 1e20), commands=("cook", "inspect"))
    obj("float32_max", replace_v(lambda p, k: np.sign(p) * f32max), commands=("cook", "inspect"))
    obj("float64_big_1e38", replace_v(lambda p, k: p * 1e38), commands=("cook",))
    obj("denormal_1e-44", replace_v(lambda p, k: np.sign(p) * 1e-44), commands=("cook", "inspect"))
    obj("identical_positions", replace_v(lambda p, k: np.array([0.1, 0.2, 0.3])), commands=("cook", "inspect"))
    faces = [ln for ln in lines if ln.startswith("f ")]
    head = [ln for ln in lines if not ln.startswith("f ")]
    obj("all_indices_first", "\n".join(head + ["f 1/1/1 1/1/1 1/1/1"] * len(faces)) + "\n",
        commands=("cook", "inspect"))
    obj("index_zero", base.replace("f 1/", "f 0/", 1), "refuse")
    obj("index_out_of_range", base.replace("f 1/", f"f {n_v + 5}/", 1), "refuse")
    obj("index_negative_out_of_range", base.replace("f 1/", f"f -{n_v + 5}/", 1), "refuse")
    obj("index_huge", base.replace("f 1/", "f 99999999999999999999999/", 1), "refuse")
    obj("index_float", base.replace("f 1/", "f 1.5/", 1), "refuse")
    obj("index_backslash", base.replace("f 1/", "f 1\\2/", 1), "refuse")
    obj("face_two_corners", base + "f 1 2\n", "refuse")
    obj("face_slashes_only", base + "f / / /\n", "refuse")
    obj("face_too_many_slashes", base + "f 1/1/1/1 2/2/2/2 3/3/3/3\n", "refuse")
    obj("no_faces", "\n".join(head) + "\n", "refuse")
    obj("empty_name_lines", base.replace("o cube", "o\ng\nusemtl\nmtllib\n"), "clean")
    obj("nul_bytes", base.replace("v 0.5", "v 0.5\0", 1), "refuse")
    obj("utf16", base.encode("utf-16"), "refuse")
    obj("latin1_name", base.replace("o cube", "o caf\xe9").encode("latin-1"), "clean")
    obj("only_comments", "# nothing\n" * 10, "refuse")
    obj("continuation_at_eof", base + "f 1 2 3 \\", "clean")
    obj("cr_only", base.replace("\n", "\r"), "clean")
    # a 10 MB face line and a degenerate 10,000-gon
    n = 10_000
    verts = "".join(f"v {np.cos(a)!r} 0.0 {np.sin(a) * 1e-12!r}\n" for a in np.linspace(0, 6.283, n, endpoint=False))
    obj("degenerate_10000gon", verts + "f " + " ".join(str(i + 1) for i in range(n)) + "\n",
        commands=("cook", "inspect"))
    obj("point_10000gon", "v 0 0 0\n" * 3 + "f " + " ".join(str(i % 3 + 1) for i in range(n)) + "\n")
    big = " ".join(str(i % 3 + 1) for i in range(5_000_000))
    obj("face_line_10MB", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf " + big + "\n", slow=True)
    obj("comment_line_10MB", "# " + "x" * 10_000_000 + "\n" + base, slow=True)
    obj("name_line_10MB", "o " + "x" * 10_000_000 + "\n" + base, slow=True)
    obj("many_groups_50000", "\n".join(head) + "\n" + "".join(f"g g{i}\n{faces[i % len(faces)]}\n"
                                                               for i in range(50_000)), slow=True)
    # materials and textures
    textured = base.replace("o cube", "mtllib a.mtl\no cube\nusemtl m")
    pngs = _bad_pngs()
    for label, data in pngs.items():
        obj(f"map_kd_{label}", textured, "warn", files={"a.mtl": "newmtl m\nmap_Kd t.png\n", "t.png": data},
            slow=label == "bomb_png")
    for label, target in (("system_file", "/etc/passwd"), ("traversal", "../../../../../../etc/passwd"),
                          ("missing", "missing.png"), ("dev_zero", "/dev/zero"), ("directory", "."),
                          ("options_only", "-s 1 1 1"), ("proc", "/proc/self/environ")):
        obj(f"map_kd_{label}", textured, "warn", files={"a.mtl": f"newmtl m\nmap_Kd {target}\n"})
    obj("map_kd_symlink_dev_zero", textured, "warn", files={"a.mtl": "newmtl m\nmap_Kd t.png\n"},
        links={"t.png": "/dev/zero"})
    obj("map_kd_fifo", textured, "warn", files={"a.mtl": "newmtl m\nmap_Kd t.png\n"}, fifos=("t.png",))
    obj("mtllib_dev_zero", textured, "clean", links={"a.mtl": "/dev/zero"})
    obj("mtllib_fifo", textured, "clean", fifos=("a.mtl",))
    obj("mtllib_directory", textured, "clean", files={"a.mtl/x": b""})
    obj("mtllib_binary", textured, "clean", files={"a.mtl": bytes(range(256)) * 8})
    obj("mtllib_absolute", textured.replace("mtllib a.mtl", "mtllib /etc/passwd"), "clean")
    w.case("obj/source_symlink_dev_zero", {}, "a.obj", expect="refuse", links={"a.obj": "/dev/zero"})
    w.case("obj/source_fifo", {}, "a.obj", expect="refuse", fifos=("a.obj",))
    for k in range(8):
        cut = int(rng.integers(1, len(base)))
        obj(f"truncated_{k:02d}_{cut}", base[:cut], "clean")
    raw = base.encode()
    for k in range(12):
        data = bytearray(raw)
        pos = int(rng.integers(0, len(raw)))
        data[pos] = int(rng.choice(list(b"\\/-.e+0 \n\t#xf\0\xff")))
        obj(f"flip_{k:02d}_at_{pos}", bytes(data), "clean")


# ---------------------------------------------------------------------------- USD

_USDA_HEAD = '#usda 1.0\n(\n    defaultPrim = "R"\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n'
_USDA_CUBE = """def Mesh "m" {
    int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
    int[] faceVertexIndices = [0, 1, 3, 2, 2, 3, 7, 6, 6, 7, 5, 4, 4, 5, 1, 0, 2, 6, 4, 0, 7, 3, 1, 5]
    point3f[] points = [(-0.5, -0.5, 0.5), (0.5, -0.5, 0.5), (-0.5, 0.5, 0.5), (0.5, 0.5, 0.5),
                        (-0.5, -0.5, -0.5), (0.5, -0.5, -0.5), (-0.5, 0.5, -0.5), (0.5, 0.5, -0.5)]
    %s
}
"""


def _usda_mesh(extra: str = "") -> str:
    return _USDA_CUBE % extra


def _deep_xform(depth: int) -> str:
    opened = "".join(f'def Xform "x{i}" {{\n' for i in range(depth))
    return _USDA_HEAD + 'def Xform "R" {\n' + opened + _usda_mesh() + "}\n" * (depth + 1)


def _instancer_bomb(count: int) -> str:
    pos = ", ".join(f"({i % 1000}, {i // 1000}, 0)" for i in range(count))
    return _USDA_HEAD + f"""def Xform "R" {{
    def PointInstancer "pi" {{
        int[] protoIndices = [{", ".join("0" for _ in range(count))}]
        point3f[] positions = [{pos}]
        rel prototypes = </R/pi/proto>
        def Xform "proto" {{
            {_usda_mesh()}
        }}
    }}
}}
"""


def _nested_instancers(levels: int, per: int = 2) -> str:
    body = _usda_mesh()
    for k in range(levels):
        idx = ", ".join("0" for _ in range(per))
        pos = ", ".join(f"({i}, 0, 0)" for i in range(per))
        body = f"""def PointInstancer "pi{k}" {{
    int[] protoIndices = [{idx}]
    point3f[] positions = [{pos}]
    rel prototypes = <p{k}>
    def Xform "p{k}" {{
{body}
    }}
}}
"""
    return _USDA_HEAD + 'def Xform "R" {\n' + body + "}\n"


_USDA_TEXTURED = """def Xform "R" {
    def Mesh "m" (prepend apiSchemas = ["MaterialBindingAPI"]) {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (0, 1)] (interpolation = "vertex")
        rel material:binding = </R/mat>
    }
    def Material "mat" {
        token outputs:surface.connect = </R/mat/s.outputs:surface>
        def Shader "s" {
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor.connect = </R/mat/t.outputs:rgb>
            token outputs:surface
        }
        def Shader "t" {
            uniform token info:id = "UsdUVTexture"
            asset inputs:file = @FILE@
            float3 outputs:rgb
        }
    }
}
"""


def usda_textured(asset: str) -> str:
    """A usda stage: one triangle bound to a UsdPreviewSurface whose diffuseColor is a
    UsdUVTexture reading ``asset``."""
    return _USDA_HEAD + _USDA_TEXTURED.replace("FILE", asset)


def _usd_cases(w: _Writer, rng) -> None:
    tmp = w.root / "_base"
    parts = _fixture_parts("seamed_cube")
    usda = write_usd(parts, tmp / "cube.usda").read_text()
    usdc = write_usd(parts, tmp / "cube.usdc").read_bytes()
    usdz = _usdz(tmp / "cube.usdc", tmp / "cube.usdz")

    def usd(name, files, source, expect="clean", slow=False, commands=("cook",)):
        w.case(f"usd/{name}", files, source, commands, expect, slow)

    plain = _USDA_HEAD + 'def Xform "R" {\n' + _usda_mesh() + "}\n"
    usd("plain_cube", {"a.usda": plain}, "a.usda", "ok")
    usd("xform_600_deep", {"a.usda": _deep_xform(600)}, "a.usda", "ok")
    usd("xform_3000_deep", {"a.usda": _deep_xform(3000)}, "a.usda", "clean", slow=True)
    usd("xform_20000_deep", {"a.usda": _deep_xform(20000)}, "a.usda", "clean", slow=True)
    usd("instancer_1M", {"a.usda": _instancer_bomb(1_000_000)}, "a.usda", "refuse", slow=True)
    usd("instancer_nested_22", {"a.usda": _nested_instancers(22)}, "a.usda", "refuse", slow=True)
    usd("instancer_nested_3", {"a.usda": _nested_instancers(3)}, "a.usda", "ok")
    usd("instancer_proto_index_bad", {"a.usda": _instancer_bomb(2).replace("protoIndices = [0, 0]",
                                                                          "protoIndices = [0, 5]")}, "a.usda",
        "refuse")
    usd("instancer_positions_short", {"a.usda": _instancer_bomb(3).replace(", (2, 0, 0)]", "]")}, "a.usda",
        "refuse")
    usd("instancer_self_prototype", {"a.usda": _instancer_bomb(2).replace("</R/pi/proto>", "</R/pi>")},
        "a.usda", "clean")
    usd("points_nan", {"a.usda": plain.replace("(-0.5, -0.5, 0.5)", "(nan, -0.5, 0.5)")}, "a.usda", "refuse")
    usd("points_inf", {"a.usda": plain.replace("(-0.5, -0.5, 0.5)", "(inf, -0.5, 0.5)")}, "a.usda", "refuse")
    usd("points_1e300_double", {"a.usda": plain.replace("point3f[] points", "point3d[] points")
        .replace("(-0.5, -0.5, 0.5)", "(1e300, -0.5, 0.5)")}, "a.usda", "clean")
    usd("points_offset_1e20", {"a.usda": plain.replace("def Mesh", 'def Mesh').replace(
        "point3f[] points = [", "double3 xformOp:translate = (1e20, 1e20, 1e20)\n    uniform token[] "
        "xformOpOrder = [\"xformOp:translate\"]\n    point3f[] points = [")}, "a.usda", "clean",
        commands=("cook", "inspect"))
    usd("scale_1e200", {"a.usda": plain.replace("point3f[] points = [", "double3 xformOp:scale = "
        "(1e200, 1e200, 1e200)\n    uniform token[] xformOpOrder = [\"xformOp:scale\"]\n    point3f[] points = [")},
        "a.usda", "refuse")
    usd("index_out_of_range", {"a.usda": plain.replace("[0, 1, 3, 2,", "[0, 1, 3, 99,")}, "a.usda", "refuse")
    usd("index_negative", {"a.usda": plain.replace("[0, 1, 3, 2,", "[0, 1, 3, -2,")}, "a.usda", "refuse")
    usd("counts_mismatch", {"a.usda": plain.replace("[4, 4, 4, 4, 4, 4]", "[4, 4, 4, 4, 4, 40]")}, "a.usda",
        "refuse")
    usd("counts_negative", {"a.usda": plain.replace("[4, 4, 4, 4, 4, 4]", "[4, 4, 4, 4, 12, -4]")}, "a.usda",
        "refuse")
    usd("all_indices_zero", {"a.usda": re.sub(r"faceVertexIndices = \[[^\]]*\]",
                                              "faceVertexIndices = [" + ", ".join(["0"] * 24) + "]", plain)},
        "a.usda", "clean", commands=("cook", "inspect"))
    usd("degenerate_10000gon", {"a.usda": _USDA_HEAD + 'def Xform "R" {\ndef Mesh "m" {\n'
        "int[] faceVertexCounts = [10000]\nint[] faceVertexIndices = [" + ", ".join(str(i) for i in range(10000))
        + "]\npoint3f[] points = [" + ", ".join(f"({np.cos(a):.6f}, 0, 0)" for a in np.linspace(0, 6.28, 10000))
        + "]\n}\n}\n"}, "a.usda", "clean")
    usd("normals_nan", {"a.usda": plain.replace("%s", "").replace(
        "point3f[] points", "normal3f[] normals = [" + ", ".join(["(nan, 0, 0)"] * 8)
        + "] (interpolation = \"vertex\")\n    point3f[] points")}, "a.usda", "clean")
    usd("meters_per_unit_zero", {"a.usda": plain.replace("metersPerUnit = 1", "metersPerUnit = 0")}, "a.usda",
        "refuse")
    usd("meters_per_unit_1e300", {"a.usda": plain.replace("metersPerUnit = 1", "metersPerUnit = 1e300")},
        "a.usda", "refuse")
    usd("up_axis_x", {"a.usda": plain.replace('upAxis = "Y"', 'upAxis = "X"')}, "a.usda", "refuse")
    usd("reference_missing", {"a.usda": plain.replace('def Xform "R" {', 'def Xform "R" (references = '
                                                      '@missing.usda@) {')}, "a.usda", "refuse")
    usd("reference_self", {"a.usda": plain.replace('def Xform "R" {', 'def Xform "R" (references = '
                                                   '@a.usda@) {')}, "a.usda", "clean")
    usd("reference_dev_zero", {"a.usda": plain.replace('def Xform "R" {', 'def Xform "R" (references = '
                                                       '@/dev/zero@) {')}, "a.usda", "refuse")
    usd("sublayer_missing", {"a.usda": plain.replace("upAxis = \"Y\"", "upAxis = \"Y\"\n subLayers = [@f.usda@]")},
        "a.usda", "clean")
    usd("not_usda", {"a.usda": "#usda 1.0\nthis is not usd {{{\n"}, "a.usda", "refuse")
    usd("usda_binary_junk", {"a.usda": b"#usda 1.0\n" + bytes(range(256)) * 4}, "a.usda", "refuse")
    # textures through UsdPreviewSurface
    tex_doc = usda_textured("FILE")
    for label, data in _bad_pngs().items():
        usd(f"texture_{label}", {"a.usda": tex_doc.replace("FILE", "t.png"), "t.png": data}, "a.usda", "warn",
            slow=label == "bomb_png")
    for label, target in (("missing", "missing.png"), ("system_file", "/etc/passwd"),
                          ("traversal", "../../../../../../../etc/passwd"), ("dev_zero", "/dev/zero")):
        usd(f"texture_{label}", {"a.usda": tex_doc.replace("FILE", target)}, "a.usda", "warn")
    w.case("usd/texture_fifo", {"a.usda": tex_doc.replace("FILE", "t.png")}, "a.usda", expect="warn",
           fifos=("t.png",))
    w.case("usd/source_fifo", {}, "a.usda", expect="refuse", fifos=("a.usda",))
    w.case("usd/source_symlink_dev_zero", {}, "a.usdc", expect="refuse", links={"a.usdc": "/dev/zero"})
    # crate and package corruption
    usd("usdc_ok", {"a.usdc": usdc}, "a.usdc", "ok")
    usd("usdz_ok", {"a.usdz": usdz}, "a.usdz", "ok")
    for k in range(6):
        cut = int(rng.integers(8, len(usdc)))
        usd(f"usdc_truncated_{k:02d}_{cut}", {"a.usdc": usdc[:cut]}, "a.usdc", "clean")
    for k in range(8):
        data = bytearray(usdc)
        pos = int(rng.integers(8, len(usdc)))
        data[pos] ^= int(rng.integers(1, 256))
        usd(f"usdc_flip_{k:02d}_at_{pos}", {"a.usdc": bytes(data)}, "a.usdc", "clean")
    for k in range(4):
        cut = int(rng.integers(4, len(usdz)))
        usd(f"usdz_truncated_{k:02d}_{cut}", {"a.usdz": usdz[:cut]}, "a.usdz", "clean")
    for k in range(6):
        data = bytearray(usdz)
        pos = int(rng.integers(4, len(usdz)))
        data[pos] ^= int(rng.integers(1, 256))
        usd(f"usdz_flip_{k:02d}_at_{pos}", {"a.usdz": bytes(data)}, "a.usdz", "clean")
    for k in range(6):
        cut = int(rng.integers(1, len(usda)))
        usd(f"usda_truncated_{k:02d}_{cut}", {"a.usda": usda[:cut]}, "a.usda", "clean")
    # lying counts in the crate's table of contents / section sizes: large values at random u64 slots
    for k in range(6):
        data = bytearray(usdc)
        pos = int(rng.integers(8, len(usdc) - 8)) & ~7
        data[pos:pos + 8] = struct.pack("<Q", int(rng.choice([1 << 31, 1 << 40, (1 << 63) - 1, 30_000_000])))
        usd(f"usdc_lying_u64_{k:02d}_at_{pos}", {"a.usdc": bytes(data)}, "a.usdc", "clean")


def _usdz(usdc_path: Path, out: Path) -> bytes:
    from pxr import Sdf, UsdUtils

    if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(usdc_path)), str(out)):
        raise RuntimeError("cannot write the usdz fixture")
    return out.read_bytes()


# ---------------------------------------------------------------------------- .lop


def _lop_base(root: Path) -> bytes:
    src = write_gltf(_fixture_parts("two_plates"), root / "_base" / "plates.glb", binary=True)[0]
    out = root / "_base" / "plates.lop"
    env = dict(os.environ)
    subprocess.run([sys.executable, "-m", "lopcook", "cook", str(src), "-o", str(out), "-q"], check=True,
                   env=env, timeout=300)
    return out.read_bytes()


def _lop_split(data: bytes) -> tuple[dict, bytes, bytes]:
    """(manifest, raw manifest bytes, section payload bytes) of a container."""
    msize = struct.unpack_from("<I", data, 12)[0]
    mbytes = data[32:32 + msize]
    return json.loads(mbytes), mbytes, data[32 + msize:]


def _lop_pack(mbytes: bytes, payload: bytes, *, total: int | None = None) -> bytes:
    """A container with this manifest and payload, every CRC and size recomputed (the lie passes)."""
    total = 32 + len(mbytes) + len(payload) if total is None else total
    head = struct.pack("<4sHHIIIQ", b"LOPC", VERSION[0], VERSION[1], 32, len(mbytes), zlib.crc32(mbytes), total)
    return head + struct.pack("<I", zlib.crc32(head)) + mbytes + payload


def _lop_with(manifest: dict, payload: bytes) -> bytes:
    try:
        mb = manifest_bytes(manifest)
    except ValueError:  # NaN / Inf: written the way a liar would
        mb = json.dumps(manifest, sort_keys=True, separators=(",", ":")).encode()
    return _lop_pack(mb, payload)


def _lop_cases(w: _Writer, rng) -> None:
    data = _lop_base(w.root)
    manifest, mbytes, payload = _lop_split(data)

    def lop(name, blob, expect="clean", commands=("inspect", "decode")):
        w.case(f"lop/{name}", {"a.lop": blob}, "a.lop", commands, expect)

    def lie(name, fn, expect="refuse", pay=None, commands=("decode",)):
        m = copy.deepcopy(manifest)
        fn(m)
        lop(name, _lop_with(m, payload if pay is None else pay), expect, commands)

    lop("ok", data, "ok")
    part0 = manifest["parts"][0]["lods"][0]
    # grid lies
    for label, val in (("1e39", 1e39), ("inf", float("inf")), ("nan", float("nan")), ("zero", 0.0),
                       ("negative", -1.0), ("denormal", 1e-44), ("tiny_1e-30", 1e-30), ("string", "1"),
                       ("bool", True), ("list", [1.0]), ("1e308", 1e308), ("null", None)):
        lie(f"grid_extent_{label}", lambda m, v=val: m["grid"].update(extent=v))
    for label, val in (("bools", [True, False, True]), ("strings", ["0", "0", "0"]), ("two", [0.0, 0.0]),
                       ("1e39", [1e39, 0.0, 0.0]), ("nan", [float("nan"), 0.0, 0.0]),
                       ("nested", [[0.0], 0.0, 0.0]), ("dict", {"x": 0}), ("null", None),
                       ("f32max", [3.4028234663852886e38] * 3)):
        lie(f"grid_origin_{label}", lambda m, v=val: m["grid"].update(origin=v))
    lie("grid_bits_23", lambda m: m["grid"].update(bits=23))
    lie("grid_bits_bool", lambda m: m["grid"].update(bits=True))
    lie("grid_missing", lambda m: m.pop("grid"))
    lie("grid_list", lambda m: m.update(grid=[1, 2, 3]))
    # positions lies
    lie("max_level_0", lambda m: m["positions"].update(max_level=0))
    lie("max_level_25", lambda m: m["positions"].update(max_level=25))
    lie("max_level_string", lambda m: m["positions"].update(max_level="24"))
    lie("planes_list", lambda m: m["positions"].update(planes=[1, 2]))
    lie("planes_int_names", lambda m: m["positions"].update(planes={k: 1 for k in m["positions"]["planes"]}))
    lie("mandatory_int", lambda m: m["positions"].update(mandatory=3))
    # sections lies
    lie("sections_reordered", lambda m: m["sections"].reverse())
    lie("sections_swapped_planes", lambda m: m["sections"].__setitem__(
        slice(-2, None), list(reversed(m["sections"][-2:]))))
    lie("section_length_huge", lambda m: m["sections"][0].update(length=1 << 40))
    lie("section_offset_huge", lambda m: m["sections"][0].update(offset=1 << 40))
    lie("section_length_odd", lambda m: m["sections"][0].update(length=3))
    lie("section_length_float", lambda m: m["sections"][0].update(length=4.0))
    lie("section_crc_string", lambda m: m["sections"][0].update(crc32="0"))
    lie("section_name_int", lambda m: m["sections"][0].update(name=5))
    lie("section_duplicate", lambda m: m["sections"].append(copy.deepcopy(m["sections"][0])))
    lie("sections_empty", lambda m: m.update(sections=[]))
    lie("sections_dict", lambda m: m.update(sections={}))
    lie("section_entry_list", lambda m: m["sections"].__setitem__(0, [1, 2]))
    # parts / LOD lies
    lie("parts_empty", lambda m: m.update(parts=[]))
    lie("parts_dict", lambda m: m.update(parts={}))
    lie("part_not_object", lambda m: m["parts"].__setitem__(0, 7))
    lie("part_name_int", lambda m: m["parts"][0].update(name=7))
    lie("lods_empty", lambda m: m["parts"][0].update(lods=[]))
    lie("lod_vertices_huge", lambda m: m["parts"][0]["lods"][0].update(vertices=1 << 40))
    lie("lod_vertices_float", lambda m: m["parts"][0]["lods"][0].update(vertices=1.5))
    lie("lod_triangles_huge", lambda m: m["parts"][0]["lods"][0].update(triangles=1 << 40))
    lie("lod_triangles_negative", lambda m: m["parts"][0]["lods"][0].update(triangles=-3))
    lie("lod_index_width_3", lambda m: m["parts"][0]["lods"][0].update(index_width=3))
    lie("lod_indices_missing_section", lambda m: m["parts"][0]["lods"][0].update(indices="nope"))
    lie("lod_indices_list", lambda m: m["parts"][0]["lods"][0].update(indices=["x"]))
    lie("lod_vertex_id_short", lambda m: m["parts"][0]["lods"][0].update(vertex_id=[0, 1]))
    lie("lod_vertex_id_decreasing", lambda m: m["parts"][0]["lods"][0].update(
        vertex_id=list(reversed(m["parts"][0]["lods"][0]["vertex_id"]))))
    lie("lod_vertex_id_bools", lambda m: m["parts"][0]["lods"][0].update(vertex_id=[False] * 25))
    lie("lod_vertex_id_floats", lambda m: m["parts"][0]["lods"][0].update(
        vertex_id=[float(v) for v in m["parts"][0]["lods"][0]["vertex_id"]]))
    lie("lod_mandatory_words_bad", lambda m: m["parts"][0]["lods"][0].update(mandatory_words=[1 << 40, 3]))
    lie("lod_mandatory_words_str", lambda m: m["parts"][0]["lods"][0].update(mandatory_words="0,3"))
    if (part0.get("attribute_bits") or {}).get("uvs") is not None:
        lie("lod_uv_range_bools", lambda m: m["parts"][0]["lods"][0].update(uv_range=[[True, False], [True, True]]))
        lie("lod_uv_range_nan", lambda m: m["parts"][0]["lods"][0].update(
            uv_range=[[float("nan"), 0.0], [1.0, 1.0]]))
        lie("lod_uv_range_1e39", lambda m: m["parts"][0]["lods"][0].update(uv_range=[[-1e39, 0.0], [1e39, 1.0]]))
        lie("lod_uv_range_strings", lambda m: m["parts"][0]["lods"][0].update(uv_range=[["0", "0"], ["1", "1"]]))
        lie("lod_uv_range_reversed", lambda m: m["parts"][0]["lods"][0].update(uv_range=[[1.0, 1.0], [0.0, 0.0]]))
        lie("lod_uv_step_wrong", lambda m: m["parts"][0]["lods"][0].update(uv_step=[1.0, 1.0]))
        lie("lod_uv_step_missing", lambda m: m["parts"][0]["lods"][0].pop("uv_step"))
    lie("lod_attributes_int", lambda m: m["parts"][0]["lods"][0].update(attributes=3))
    lie("lod_attribute_bits_17", lambda m: m["parts"][0]["lods"][0]["attribute_bits"].update(normals=17))
    lie("lod_attribute_bits_float", lambda m: m["parts"][0]["lods"][0]["attribute_bits"].update(normals=8.0))
    lie("lod_record_bits_wrong", lambda m: m["parts"][0]["lods"][0].update(
        record_bits=m["parts"][0]["lods"][0]["record_bits"] + 1))
    lie("part_attribute_bits_differ", lambda m: m["parts"][0].update(
        attribute_bits={"normals": 5, "uvs": None, "colors": None}))
    lie("lod_not_object", lambda m: m["parts"][0]["lods"].__setitem__(0, "lod"))
    # informative fields missing or of the wrong type: inspect must not crash
    for key in ("source", "generator", "viewing", "options", "instances", "lod_notes", "analysis", "format"):
        if key in manifest or key == "format":
            lie(f"missing_{key}", lambda m, k=key: m.pop(k, None), "clean", commands=("inspect", "decode"))
            lie(f"wrong_type_{key}", lambda m, k=key: m.update({k: [[["x"]]]}), "clean",
                commands=("inspect", "decode"))
    for key in manifest:
        if key not in ("source", "generator", "viewing", "options", "format", "sections", "grid",
                       "positions", "parts"):
            lie(f"missing_other_{key}", lambda m, k=key: m.pop(k, None), "clean", commands=("inspect", "decode"))
            lie(f"null_other_{key}", lambda m, k=key: m.update({k: None}), "clean", commands=("inspect",))
    # deeply nested JSON
    deep = b'{"format":"lopcook.lop","x":' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    lop("deep_json", _lop_pack(deep, payload), "refuse")
    lop("manifest_array", _lop_pack(b"[1,2,3]", payload), "refuse")
    lop("manifest_not_ascii", _lop_pack(mbytes.replace(b'"', b'\xff', 1), payload), "refuse")
    lop("manifest_duplicate_key", _lop_pack(b'{"format":"lopcook.lop","format":"x"}', payload), "refuse")
    lop("manifest_huge_int", _lop_pack(mbytes.replace(b'"bits":24', b'"bits":' + b"9" * 5000), payload),
        "refuse")
    lop("manifest_1e999", _lop_pack(mbytes.replace(b'"bits":24', b'"bits":1e999'), payload), "refuse")
    # payload lies with section CRCs recomputed: index values out of range
    idx_sec = part0["indices"]
    m = copy.deepcopy(manifest)
    pay = bytearray(payload)
    for s in m["sections"]:
        if s["name"] == idx_sec:
            width = part0["index_width"]
            pay[s["offset"]:s["offset"] + width] = (b"\xff" * width)
            s["crc32"] = zlib.crc32(bytes(pay[s["offset"]:s["offset"] + s["length"]]))
    lop("index_value_out_of_range", _lop_with(m, bytes(pay)), "refuse")
    for k in range(6):
        m = copy.deepcopy(manifest)
        pay = bytearray(payload)
        s = m["sections"][int(rng.integers(0, len(m["sections"])))]
        if s["length"]:
            p = s["offset"] + int(rng.integers(0, s["length"]))
            pay[p] ^= 0xFF
            s["crc32"] = zlib.crc32(bytes(pay[s["offset"]:s["offset"] + s["length"]]))
        lop(f"payload_flip_crc_fixed_{k}_{s['name'].replace('/', '_')}", _lop_with(m, bytes(pay)), "clean")
    # header lies
    lop("total_size_small", _lop_pack(mbytes, payload, total=100), "refuse")
    lop("total_size_huge", _lop_pack(mbytes, payload, total=1 << 60), "refuse")
    future = struct.pack("<H", max(READABLE_MAJORS) + 1)  # the first major no reader knows
    lop("header_major_next", data[:4] + future + data[6:28] + struct.pack(
        "<I", zlib.crc32(data[:4] + future + data[6:28])) + data[32:], "refuse")
    past = struct.pack("<H", VERSION[0] - 1)  # format 1.0: fixed normals/uvs/colors sections
    lop("header_major_previous", data[:4] + past + data[6:28] + struct.pack(
        "<I", zlib.crc32(data[:4] + past + data[6:28])) + data[32:], "refuse")
    for k, cut in enumerate(sorted(set(rng.integers(1, len(data), 10).tolist()) | {4, 31, 32, 33})):
        lop(f"truncated_{cut}", data[:cut], "clean", ("decode",))  # refused by the read both commands share
    for k in range(12):
        blob = bytearray(data)
        pos = int(rng.integers(0, len(data)))
        blob[pos] ^= int(rng.integers(1, 256))
        lop(f"flip_{k:02d}_at_{pos}", bytes(blob), "refuse", ("decode",))
    lop("top_level_list", _lop_pack(b"[]", payload), "refuse")


def _stream_cases(w: _Writer) -> None:
    """Streaming-layout files (docs/format.md 14-15, ``tests.support.streamcases``): a valid one,
    prefixes (inspect reads them; decode --level 24 above a buffer's level is refused cleanly),
    and hostile ones: lying stages and section orders, encoded sections that do not decode
    (deflate streams corrupt, cut short, expanding beyond their size; triangle streams of the
    wrong version, reading past their data, indices out of range) and an encoded manifest."""
    from . import streamcases  # cooks two fixtures: only when the corpus is generated

    name, data, _ = streamcases.stream_cases()[0]
    w.case(f"stream/{name}", {"a.lop": data}, "a.lop", ("inspect", "decode"), "ok")
    for name, blob, _, levels in streamcases.stream_prefix_cases():
        w.case(f"stream/{name}", {"a.lop": blob}, "a.lop", ("inspect", "decode"), "clean")
    for name, blob, _, _ in streamcases.stream_invalid_cases():
        w.case(f"stream/{name}", {"a.lop": blob}, "a.lop", ("inspect", "decode"), "refuse")


# ============================================================================ runner


def _limit_resources() -> None:  # pragma: no cover - runs in the child
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_BYTES, MEMORY_BYTES))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))


def _snapshot(directory: str, run: str) -> dict[str, bytes | None]:
    """name -> bytes of every regular file of the input directory (run directories excluded) and
    of the run directory (``run/name``); None for links, FIFOs and directories."""
    out = {}
    names = [n for n in os.listdir(directory) if not n.startswith("run-")]
    names += [os.path.join(os.path.basename(run), n) for n in os.listdir(run)]
    for name in sorted(names):
        p = os.path.join(directory, name)
        if os.path.islink(p) or not os.path.isfile(p):
            out[name] = None
        else:
            with open(p, "rb") as fh:
                out[name] = fh.read()
    return out


def run_case(case: Case, *, python: str = sys.executable, env: dict | None = None) -> Result:
    """Run one case through the CLI in a subprocess and classify it."""
    import time

    import shutil

    d, run = case.directory, case.run_directory
    shutil.rmtree(run, ignore_errors=True)
    os.makedirs(run)
    for out in case.outputs():
        with open(os.path.join(run, out), "wb") as fh:
            fh.write(SENTINEL)
    before = _snapshot(d, run)
    env = dict(os.environ if env is None else env)
    env.setdefault("PYTHONHASHSEED", "0")
    t0 = time.monotonic()
    try:
        proc = subprocess.run([python, "-m", "lopcook", *case.argv()], cwd=run, env=env, capture_output=True,
                              timeout=TIMEOUT_S, preexec_fn=_limit_resources, stdin=subprocess.DEVNULL)
        rc, stdout, stderr = proc.returncode, proc.stdout, proc.stderr.decode("utf-8", "replace")
    except subprocess.TimeoutExpired as exc:
        rc, stdout = None, exc.stdout or b""
        stderr = (exc.stderr or b"").decode("utf-8", "replace")
    seconds = time.monotonic() - t0
    after = _snapshot(d, run)
    rel = os.path.basename(run)
    before = {(k[len(rel) + 1:] if k.startswith(rel + os.sep) else k): v for k, v in before.items()}
    after = {(k[len(rel) + 1:] if k.startswith(rel + os.sep) else k): v for k, v in after.items()}
    return classify(case, rc, stdout, stderr, before, after, seconds)


def classify(case: Case, rc, stdout: bytes, stderr: str, before: dict, after: dict, seconds: float) -> Result:
    def result(klass, detail=""):
        return Result(case, klass, rc, stderr, seconds, detail)

    if rc is None:
        return result("timeout")
    if "Traceback (most recent call last)" in stderr:
        return result("traceback")
    if re.search(r"MemoryError|out of memory|more memory than is available|Cannot allocate memory", stderr) \
            or (rc != 2 and "bad_alloc" in stderr):
        return result("memory")
    if rc < 0:
        return result("signal", f"signal {-rc}")
    if rc == 3:
        return result("exit3")
    outputs = set(case.outputs())
    for name, data in before.items():
        if name in outputs and rc == 0:
            continue
        if after.get(name, b"<gone>") != data:
            return result("clobbered", f"{name} changed")
    new = sorted(set(after) - set(before))
    if new:
        return result("clobbered", f"left {new}")
    if rc == 2:
        lines = [ln for ln in stderr.splitlines() if ln.strip()]
        if len(lines) != 1:
            return result("multiline", f"{len(lines)} lines")
        if os.path.basename(case.source) not in lines[0] or _EXC_NAMES.search(lines[0]):
            return result("unnamed")
        return result("refused" if case.expect == "ok" else "clean")
    if rc == 0:
        if case.expect == "refuse":
            return result("accepted")
        if case.command == "cook":
            lop = after.get("out.lop") or b""
            if not lop.startswith(b"LOPC"):
                return result("clobbered", "exit 0 without a container")
            if case.expect == "warn":
                try:
                    warnings = json.loads(stdout).get("warnings") or []
                except (ValueError, AttributeError):
                    warnings = []
                if not warnings:
                    return result("unwarned")
        if case.command == "decode" and not (after.get("out.glb") or b"").startswith(b"glTF"):
            return result("clobbered", "exit 0 without a glb")
        return result("ok")
    return result("other", f"exit {rc}")


def run_all(cases: list[Case], *, workers: int = 2, env: dict | None = None) -> list[Result]:
    """Run cases concurrently (``workers`` subprocesses at a time), results in case order."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        return list(pool.map(lambda c: run_case(c, env=env), cases))


def counts(results: list[Result]) -> dict[str, int]:
    c = Counter(r.klass for r in results)
    return {k: c[k] for k in CLASSES if c[k]}


def main(argv: list[str] | None = None) -> int:
    import argparse
    import tempfile

    ap = argparse.ArgumentParser(prog="python -m tests.support.fuzzcases", description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", help="corpus directory (default: a temporary one)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", default="", help="run only cases whose name contains this text")
    ap.add_argument("--show", action="store_true", help="print every failing case with its stderr")
    args = ap.parse_args(argv)
    root = args.root or tempfile.mkdtemp(prefix="lopcook-fuzz-")
    cases = [c for c in generate(root) if args.only in c.name]
    results = run_all(cases, workers=args.workers)
    for r in results:
        if r.klass not in ("ok", "clean") or args.show:
            tail = " | ".join(r.stderr.strip().splitlines()[-2:])[:300]
            print(f"{r.klass:10s} {r.seconds:6.1f}s {r.case.name}  {r.detail}  {tail}")
    print(f"{len(results)} runs over {len({c.directory for c in cases})} inputs:", json.dumps(counts(results)))
    return 0 if all(r.klass in ("ok", "clean") for r in results) else 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
