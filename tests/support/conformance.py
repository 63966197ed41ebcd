"""Generate ``fixtures/conformance/``: the containers every .lop reader must pass (Python, runtime/c,
runtime/js), with the expected decoded bytes of each and the error class of each invalid file.

    .venv/bin/python tests/support/conformance.py [OUTDIR]   # default: fixtures/conformance

Deterministic (the cooks, the mutations and the index): ``tests/runtime/test_conformance.py``
regenerates the set and compares it byte for byte with the committed one. Three kinds of files:

* **valid** (``VALID``): small containers cooked from ``fixtures/`` and from synthetic scenes, one
  per feature (unclustered and clustered buffers, several LODs, placements, a hierarchy, a
  ``max_level`` below 24, each attribute codec at its narrowest and widest bits). The index gives,
  per LOD and level, the sha256 of the three dumps of ``tests/support/dumps.py`` (``positions``,
  ``gpu``: the uniform blocks, P in the file's layout, binned and AP, the cluster records;
  ``attributes``: indices and decoded attribute arrays).
* **prefix** (``PREFIXES``): a valid file cut at a section boundary (or inside a plane), read with
  prefixes allowed: its available level, and the same hashes for every level it holds; read as a
  whole file it is ``truncated``.
* **invalid** (``INVALID``): one defect each, every checksum that would hide it recomputed; the
  error class a reader must report (docs/format.md section 12), also with prefixes allowed.

To add a feature: add a case to ``VALID`` (a source, cook flags, what it covers); the expected
hashes follow from lopcook's reader. Files whose version lopcook cannot read yet are left out.
"""

from __future__ import annotations

import hashlib
import json
import struct
import sys
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))

from support import dumps, streamcases  # noqa: E402  (tests/ on the path: run as a script or imported by a test)

from lopcook import api  # noqa: E402
from lopcook.cli.parser import build_parser, settings_from_args  # noqa: E402
from lopcook.lop.container import from_bytes, manifest_bytes, manifest_of  # noqa: E402
from lopcook.errors import LopcookError  # noqa: E402
from lopcook.types import MeshPart, Scene  # noqa: E402

FIXTURES = REPO / "fixtures"
OUT = FIXTURES / "conformance"
INDEX = "conformance.json"
FORMAT = "lopcook.conformance/1"


# ---- sources ----------------------------------------------------------------------------------

def _grid_surface(name: str, n: int = 7) -> MeshPart:
    """A curved n x n vertex sheet with unit normals, UVs over [-0.25, 1.5] and RGBA colours."""
    u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="ij")
    x, z = u - 0.5, v - 0.5
    y = 0.25 * np.sin(3.0 * x) * np.cos(2.0 * z)
    pos = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    dydx = 0.75 * np.cos(3.0 * x) * np.cos(2.0 * z)
    dydz = -0.5 * np.sin(3.0 * x) * np.sin(2.0 * z)
    nrm = np.stack([-dydx, np.ones_like(x), -dydz], axis=-1).reshape(-1, 3)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    uvs = np.stack([1.75 * u - 0.25, 1.5 * v], axis=-1).reshape(-1, 2)
    col = np.stack([u, v, 0.5 * (u + v), 1.0 - 0.5 * u], axis=-1).reshape(-1, 4)
    quads = np.array([[i * n + j, i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j]
                      for i in range(n - 1) for j in range(n - 1)])
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.uint32)
    return MeshPart(name=name, positions=pos.astype(np.float64), indices=tris, normals=nrm.astype(np.float32),
                    uvs=uvs.astype(np.float32), colors=col.astype(np.float32), source=name, mesh_key=name)


def surface() -> Scene:
    return Scene(parts=(_grid_surface("surface"),), source="surface.synthetic", format="glb").validate()


def surface_12() -> Scene:
    """A 12 x 12 sheet: enough vertices for several LODs, bins and clusters."""
    return Scene(parts=(_grid_surface("surface", 12),), source="surface_12.synthetic", format="glb").validate()


def _wedge() -> tuple[np.ndarray, np.ndarray]:
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0.5], [1, 0, 0.5], [0, 1, 0.5]], np.float64)
    t = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]], np.uint32)
    return p, t


def wedges() -> Scene:
    """Three copies of an asymmetric wedge (turned, scaled, moved) and a surface: placements."""
    p, t = _wedge()
    parts = []
    for i, (deg, scale, move) in enumerate([(0.0, 1.0, (0, 0, 0)), (90.0, 1.0, (3, 0, 0)), (30.0, 2.0, (0, 0, 4))]):
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        turn = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        parts.append(MeshPart(name=f"wedge{i}", positions=(p * scale) @ turn.T + np.array(move, np.float64),
                              indices=t.copy(), source=f"wedge {i}", mesh_key="wedge"))
    sheet = _grid_surface("sheet", 5)
    parts.append(MeshPart(name="sheet", positions=sheet.positions * 2.0 + np.array([4.0, -1.0, 2.0]),
                          indices=sheet.indices, normals=sheet.normals, source="sheet", mesh_key="sheet"))
    return Scene(parts=tuple(parts), source="wedges.synthetic", format="glb").validate()


def _tetra(name: str, a=np.eye(3), t=(0.0, 0.0, 0.0)) -> MeshPart:
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float64)
    n = (p - 0.25) / np.linalg.norm(p - 0.25, axis=1, keepdims=True)
    uv = np.array([[0, 0], [1, 0], [0, 1], [0.5, 0.5]], np.float32)
    tri = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.uint32)
    return MeshPart(name=name, positions=p @ np.asarray(a, np.float64).T + np.asarray(t, np.float64), indices=tri,
                    normals=n.astype(np.float32), uvs=uv, source=name, mesh_key="tetra")


def tetra() -> Scene:
    """The smallest base for the invalid files: one tetrahedron with normals and UVs."""
    return Scene(parts=(_tetra("tetra"),), source="tetra.synthetic", format="glb").validate()


def _with_tangents(part: MeshPart) -> MeshPart:
    """``part`` with unit tangents orthogonal to its normals (the x axis, or y where the normal is
    near x, projected) and the handedness w alternating +1, -1 by vertex."""
    n = part.normals.astype(np.float64)
    a = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    t = a - (a * n).sum(axis=1, keepdims=True) * n
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    w = np.where(np.arange(len(n)) % 2 == 0, 1.0, -1.0)[:, None]
    return replace(part, tangents=np.concatenate([t, w], axis=1).astype(np.float32))


def tetra_tangents() -> Scene:
    """The tetrahedron with tangents (container 4.0)."""
    return Scene(parts=(_with_tangents(_tetra("tetra")),), source="tetra_tangents.synthetic", format="glb").validate()


def surface_tangents() -> Scene:
    """The 12 x 12 sheet with tangents: several LODs that carry them."""
    return Scene(parts=(_with_tangents(_grid_surface("surface", 12)),), source="surface_tangents.synthetic",
                 format="glb").validate()


def wedge_pair() -> Scene:
    """Two copies of the wedge, the second turned a quarter about y and moved: placements."""
    p, t = _wedge()
    turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    parts = (MeshPart(name="wedge0", positions=p, indices=t, source="wedge 0", mesh_key="wedge"),
             MeshPart(name="wedge1", positions=p @ turn.T + np.array([3.0, 0.0, 0.0]), indices=t.copy(),
                      source="wedge 1", mesh_key="wedge"))
    return Scene(parts=parts, source="wedge_pair.synthetic", format="glb").validate()


# ---- cases ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Valid:
    file: str
    source: object  # a fixture file name, or a function returning a Scene
    flags: tuple
    covers: tuple


VALID = (
    Valid("plates_v2.lop", "two_plates.glb", ("--no-edges", "--clusters", "0"),
          ("version 2.0", "unclustered (binned) buffers", "two parts", "the worked example of docs/format.md")),
    Valid("cube_clustered.lop", "seamed_cube.glb", ("--clusters", "16", "--cluster-all"),
          ("version 3.0", "clustered buffer (cluster records, ClusterId)", "normals and UVs")),
    Valid("surface_lods.lop", surface_12, ("--lods", "1/2,1/8", "--lod-backend", "fast", "--clusters", "0"),
          ("several LODs (one part with fewer than the deepest chain: --lod K falls back to its coarsest)",
           "geometric errors and min_distance_m", "normals, UVs and colours in every LOD")),
    Valid("surface_lods_clustered.lop", surface_12,
          ("--lods", "1/2,1/8", "--lod-backend", "fast", "--clusters", "16", "--cluster-all"),
          ("clustered LODs",)),
    Valid("surface_hierarchy.lop", surface, ("--hierarchy", "--clusters", "0"),
          ("a vertex hierarchy section (partI/lod0/hierarchy), which a position reader skips",)),
    Valid("attributes_narrow.lop", surface, ("--normal-bits", "4", "--uv-bits", "6", "--color-bits", "4"),
          ("normals at 4 bits", "UVs at 6 bits over a range beyond [0, 1]", "colours at 4 bits")),
    Valid("attributes_wide.lop", surface, ("--normal-bits", "16", "--uv-bits", "16", "--color-bits", "8",
                                           "--clusters", "0"),
          ("normals at 16 bits", "UVs at 16 bits", "colours at 8 bits", "record of 96 bits")),
    Valid("placements.lop", wedges, ("--clusters", "0"),
          ("placements: copies stored once, transforms, level shifts, mesh grids",)),
    Valid("placements_clustered.lop", wedges, ("--clusters", "16", "--cluster-all"),
          ("placements of clustered buffers",)),
    Valid("tetra.lop", tetra, ("--clusters", "0", "--nearest", "50"),
          ("the smallest cooked file", "max_level below 24: planes above it not written", "savings record")),
    Valid("tetra_clustered.lop", tetra, ("--clusters", "16", "--cluster-all", "--nearest", "50"),
          ("a small clustered file",)),
    Valid("wedges_placed.lop", wedge_pair, ("--clusters", "0", "--nearest", "50"), ("two placements of one buffer",)),
    Valid("tangents_narrow.lop", tetra_tangents, ("--clusters", "0", "--nearest", "50", "--tangent-bits", "4",
                                                  "--normal-bits", "4"),
          ("version 4.0: tangents at 4 bits (sign bits of both values)", "the LopAttributeDecode block's b_t and scale")),
    Valid("tangents_wide.lop", tetra_tangents, ("--clusters", "0", "--nearest", "50", "--tangent-bits", "16"),
          ("tangents at 16 bits",)),
    Valid("stream_tangents.lop", surface_tangents, ("--stream", "--lods", "1/2,1/8", "--lod-backend", "fast",
                                                    "--clusters", "16", "--cluster-all", "--tangent-bits", "8"),
          ("streaming layout: clustered LODs with tangents, encoded sections",)),
)

#: valid files made by editing another: the informative encodings record left out (a reader must
#: not depend on it); the bases of the invalid files
TRIMMED = tuple((f"{name[:-4]}_minimal.lop", name, ("encodings",), "no encodings record (informative)")
                for name in ("tetra.lop", "tetra_clustered.lop", "wedges_placed.lop"))


@dataclass(frozen=True)
class Prefix:
    file: str
    of: str
    cut: str  # "after:SECTION", "inside:SECTION" or "byte:N"
    covers: str


PREFIXES = (
    Prefix("prefix_plates_mandatory.lop", "plates_v2.lop", "after:positions/mandatory",
           "cut after the mandatory bits: empty planes 2..11 count, level 11"),
    Prefix("prefix_plates_inside_plane20.lop", "plates_v2.lop", "inside:positions/plane20", "cut inside plane 20"),
    Prefix("prefix_cube_mandatory.lop", "cube_clustered.lop", "after:positions/mandatory",
           "clustered, cut after the mandatory bits"),
    Prefix("prefix_surface_lods_plane13.lop", "surface_lods_clustered.lop", "after:positions/plane13",
           "clustered LODs, cut after plane 13"),
    Prefix("prefix_placements_plane12.lop", "placements.lop", "after:positions/plane12",
           "placements, cut after plane 12"),
    Prefix("prefix_plates_inside_attributes.lop", "plates_v2.lop", "inside:part1/lod0/attributes",
           "cut inside an attribute section: no level (truncated)"),
    Prefix("prefix_cube_inside_clusters.lop", "cube_clustered.lop", "inside:positions/clusters",
           "cut inside the cluster anchors: no level (truncated)"),
    Prefix("prefix_plates_inside_manifest.lop", "plates_v2.lop", "byte:600", "cut inside the manifest (truncated)"),
    Prefix("prefix_plates_inside_header.lop", "plates_v2.lop", "byte:20", "cut inside the header (truncated)"),
)


# ---- invalid files: one defect each ----------------------------------------------------------

def _split(data: bytes) -> tuple[int, int, dict, bytes]:
    major, minor, msize = struct.unpack_from("<HHxxxxI", data, 4)
    return major, minor, json.loads(data[32:32 + msize]), data[32 + msize:]


def _pack(mbytes: bytes, payload: bytes, major: int, minor: int, *, header_size: int = 32, extra: int = 0) -> bytes:
    """A container of these bytes with every size and checksum recomputed (``extra``: added to file_size)."""
    head = struct.pack("<4sHHIIIQ", b"LOPC", major, minor, header_size, len(mbytes), zlib.crc32(mbytes),
                       32 + len(mbytes) + len(payload) + extra)
    return head + struct.pack("<I", zlib.crc32(head)) + mbytes + payload


def relabel(major: int, minor: int = 0, header_size: int = 32) -> Callable[[bytes], bytes]:
    def f(data: bytes) -> bytes:
        _, _, m, payload = _split(data)
        return _pack(data[32:32 + len(data) - len(payload) - 32], payload, major, minor, header_size=header_size)
    return f


def edit_manifest(fn, raw: Callable[[bytes], bytes] | None = None) -> Callable[[bytes], bytes]:
    """The manifest changed by ``fn(manifest)`` (canonical JSON), or its bytes by ``raw``."""
    def f(data: bytes) -> bytes:
        major, minor, m, payload = _split(data)
        if fn is not None:
            fn(m)
        mb = manifest_bytes(m)
        return _pack(raw(mb) if raw else mb, payload, major, minor)
    return f


def edit_section(name: str, fn, fix_crc: bool = True) -> Callable[[bytes], bytes]:
    """Section ``name``'s bytes changed by ``fn(bytearray)`` (same length), its crc32 recomputed."""
    def f(data: bytes) -> bytes:
        major, minor, m, payload = _split(data)
        pay = bytearray(payload)
        s = next(s for s in m["sections"] if s["name"] == name)
        body = bytearray(pay[s["offset"]:s["offset"] + s["length"]])
        fn(body)
        pay[s["offset"]:s["offset"] + s["length"]] = body
        if fix_crc:
            s["crc32"] = zlib.crc32(bytes(body))
        return _pack(manifest_bytes(m), bytes(pay), major, minor)
    return f


def grow_section(name: str, extra: bytes) -> Callable[[bytes], bytes]:
    """Section ``name`` longer by ``extra`` (the table's offsets and checksums recomputed)."""
    def f(data: bytes) -> bytes:
        major, minor, m, payload = _split(data)
        parts, offset = [], 0
        for s in m["sections"]:
            body = payload[s["offset"]:s["offset"] + s["length"]] + (extra if s["name"] == name else b"")
            s.update(offset=offset, length=len(body), crc32=zlib.crc32(body))
            offset += len(body)
            parts.append(body)
        return _pack(manifest_bytes(m), b"".join(parts), major, minor)
    return f


def flip(at: int) -> Callable[[bytes], bytes]:
    return lambda data: data[:at] + bytes([data[at] ^ 0xFF]) + data[at + 1:]


def _lod(m: dict, i: int = 0, k: int = 0) -> dict:
    return m["parts"][i]["lods"][k]


def _set_index(body: bytearray) -> None:
    body[0:2] = struct.pack("<H", 4)  # the tetrahedron has 4 vertices: index 4 is out of range


def _cluster_k(body: bytearray) -> None:
    body[3] = 25  # k_x of the first cluster: 25 > 24


@dataclass(frozen=True)
class Invalid:
    file: str
    of: str
    mutate: Callable[[bytes], bytes]
    error: str
    covers: str


#: streaming files cut at every stage boundary (stream_entries)
STAGE_CUTS = ("stream_wedges.lop", "stream_plates.lop")

#: the (valid, small) files the invalid ones are made from
BASE, CLUSTERED, PLACED = "tetra_minimal.lop", "tetra_clustered_minimal.lop", "wedges_placed_minimal.lop"

INVALID = (
    Invalid("bad_magic.lop", BASE, lambda d: b"LOPX" + d[4:], "bad_magic", "magic is not LOPC"),
    Invalid("header_crc.lop", BASE, flip(13), "header_crc", "a header byte changed, its CRC not"),
    Invalid("version_5.lop", BASE, relabel(5), "version", "an unknown major version"),
    Invalid("version_1.lop", BASE, relabel(1), "version", "format 1.0 (no reader reads it)"),
    Invalid("version_2_clustered.lop", CLUSTERED, relabel(2), "version", "clustered buffers in a 2.0 file"),
    Invalid("version_2_placements.lop", PLACED, relabel(2), "version", "placements in a 2.0 file"),
    Invalid("header_size.lop", BASE, relabel(2, 0, 40), "header", "header_size 40"),
    Invalid("trailing_data.lop", BASE, lambda d: d + b"\0\0\0\0", "trailing_data", "4 bytes past file_size"),
    Invalid("truncated.lop", BASE, lambda d: d[:-4], "truncated", "4 bytes short of file_size"),
    Invalid("manifest_crc.lop", BASE, flip(40), "manifest_crc", "a manifest byte changed, its CRC not"),
    Invalid("manifest_json_duplicate.lop", BASE,
            edit_manifest(None, lambda mb: mb.replace(b'"format":', b'"format":"lopcook.lop","format":', 1)),
            "manifest_json", "a duplicate key"),
    Invalid("manifest_json_nan.lop", BASE,
            edit_manifest(None, lambda mb: mb.replace(b'"pixel_error":0.5', b'"pixel_error":NaN', 1)),
            "manifest_json", "NaN"),
    Invalid("manifest_json_infinity.lop", BASE,
            edit_manifest(None, lambda mb: mb.replace(b'"pixel_error":0.5', b'"pixel_error":-Infinity', 1)),
            "manifest_json", "-Infinity"),
    Invalid("manifest_json_ascii.lop", BASE,
            edit_manifest(None, lambda mb: mb.replace(b'"generator":"lopcook', b'"generator":"l\xc3\xb6pcook', 1)),
            "manifest_json", "a byte above 0x7f"),
    Invalid("manifest_json_deep.lop", BASE,
            edit_manifest(None, lambda mb: mb[:-1] + b',"zz":' + b"[" * 3000 + b"]" * 3000 + b"}"),
            "manifest_json", "arrays nested 3000 deep"),
    Invalid("manifest_json_extra.lop", BASE, edit_manifest(None, lambda mb: mb + b" 1"), "manifest_json",
            "a second value after the object"),
    Invalid("manifest_json_control.lop", BASE,
            edit_manifest(None, lambda mb: mb.replace(b'"generator":"lopcook', b'"generator":"lop\tcook', 1)),
            "manifest_json", "a control character in a string"),
    Invalid("manifest_format.lop", BASE, edit_manifest(lambda m: m.update(format="lopcook.lopx")), "manifest",
            "format is not lopcook.lop"),
    Invalid("manifest_no_generator.lop", BASE, edit_manifest(lambda m: m.pop("generator")), "manifest",
            "an informative field missing"),
    Invalid("manifest_grid_extent.lop", BASE, edit_manifest(lambda m: m["grid"].update(extent=0.0)), "manifest",
            "grid.extent 0"),
    Invalid("manifest_grid_bits.lop", BASE, edit_manifest(lambda m: m["grid"].update(bits=True)), "manifest",
            "grid.bits a boolean"),
    Invalid("manifest_max_level.lop", BASE, edit_manifest(lambda m: m["positions"].update(max_level=25)),
            "manifest", "max_level 25"),
    Invalid("manifest_vertex_id.lop", BASE,
            edit_manifest(lambda m: _lod(m)["vertex_id"].__setitem__(12, _lod(m)["vertex_id"][12] + 1)), "manifest",
            "vertex_id not non-decreasing"),
    Invalid("manifest_vertices_float.lop", BASE, edit_manifest(lambda m: _lod(m).update(vertices=4.0)),
            "manifest", "vertices a float"),
    Invalid("manifest_record_bits.lop", BASE,
            edit_manifest(lambda m: _lod(m).update(record_bits=_lod(m)["record_bits"] + 1)), "manifest",
            "record_bits not 2 b_n + 2 b_u + 4 b_c"),
    Invalid("manifest_mandatory_words.lop", BASE,
            edit_manifest(lambda m: _lod(m).update(mandatory_words=[1, _lod(m)["mandatory_words"][1]])), "manifest",
            "mandatory_words offset wrong"),
    Invalid("manifest_uv_step.lop", BASE,
            edit_manifest(lambda m: _lod(m)["uv_step"].__setitem__(0, _lod(m)["uv_step"][0] * 2.0)), "manifest",
            "uv_step not the float32 step of uv_range"),
    Invalid("manifest_level_shift.lop", PLACED,
            edit_manifest(lambda m: m["parts"][1]["placement"].update(level_shift=m["parts"][1]["placement"]
                                                                       ["level_shift"] + 1)),
            "manifest", "a placement's level_shift wrong"),
    Invalid("manifest_singular.lop", PLACED,
            edit_manifest(lambda m: m["parts"][1]["placement"]["transform"].__setitem__(slice(0, 3), [0.0, 0.0, 0.0])),
            "manifest", "a singular placement transform"),
    Invalid("section_table_offset.lop", BASE,
            edit_manifest(lambda m: m["sections"][1].update(offset=m["sections"][1]["offset"] + 4)), "section_table",
            "sections not back to back"),
    Invalid("section_table_length.lop", BASE,
            edit_manifest(lambda m: m["sections"][0].update(length=m["sections"][0]["length"] - 2)), "section_table",
            "a length not a multiple of 4"),
    Invalid("section_table_duplicate.lop", BASE,
            edit_manifest(lambda m: m["sections"][2].update(name=m["sections"][1]["name"])), "section_table",
            "a section name twice"),
    Invalid("section_table_end.lop", BASE,
            lambda d: _pack(d[32:32 + _msize(d)], d[32 + _msize(d):] + b"\0\0\0\0", *_version(d)), "section_table",
            "sections end before file_size"),
    Invalid("section_crc.lop", BASE, lambda d: flip(len(d) - 1)(d), "section_crc",
            "a section byte changed, its CRC not"),
    Invalid("indices.lop", BASE, edit_section("part0/lod0/indices", _set_index), "indices",
            "an index equal to the vertex count (checksums recomputed)"),
    Invalid("clusters_k.lop", CLUSTERED, edit_section("positions/clusters", _cluster_k), "clusters",
            "a cluster header with k = 25"),
    Invalid("clusters_p_words.lop", CLUSTERED,
            edit_manifest(lambda m: _lod(m)["cluster_p_words"].__setitem__(10, _lod(m)["cluster_p_words"][10] + 1)),
            "clusters", "cluster_p_words not what the headers give"),
    Invalid("clusters_plane_length.lop", CLUSTERED, grow_section("positions/plane02", b"\0\0\0\0"),
            "clusters", "a clustered plane longer than its bits"),
)


def _msize(d: bytes) -> int:
    return struct.unpack_from("<I", d, 12)[0]


def _version(d: bytes) -> tuple[int, int]:
    return struct.unpack_from("<HH", d, 4)


# ---- generation ---------------------------------------------------------------------------------

def cook(case: Valid) -> bytes:
    src = case.source if isinstance(case.source, str) else "synthetic.glb"
    args = build_parser().parse_args(["cook", str(FIXTURES / src), "-o", "out.lop", *case.flags])
    settings = settings_from_args(args)
    scene = api.load(FIXTURES / src, settings) if isinstance(case.source, str) else case.source()
    return api.cook(scene, settings).data


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def lod_levels(c, k: int) -> int:
    """The highest level at which every part's LOD ``k`` (or its coarsest) decodes in ``c``: the
    available level, or in a prefix of a streaming file the lowest level of their stages (0 when
    one has not arrived)."""
    return min(c.level_of(i, min(k, len(p["lods"]) - 1)) for i, p in enumerate(c.manifest["parts"]))


def expected(c) -> list[dict]:
    """Per LOD (0 .. the deepest chain - 1) that decodes in ``c`` (``lod_levels``): the sha256 of the
    attributes dump and, per level 1 .. ``lod_levels``, of the positions and gpu dumps
    (tests/support/dumps.py)."""
    deepest = max(len(p["lods"]) for p in c.manifest["parts"])
    return [{"lod": k, "attributes": sha(dumps.attributes(c, k)),
             "levels": {str(b): {"positions": sha(dumps.positions(c, b, k)), "gpu": sha(dumps.gpu(c, b, k))}
                        for b in range(1, lod_levels(c, k) + 1)}} for k in range(deepest) if lod_levels(c, k)]


def verdict(data: bytes, allow_prefix: bool) -> dict:
    """What lopcook's reader says: ``{"error": class}`` or ``{"available_level": L}`` (and in the
    streaming layout ``"stage_levels"``, each stage's level)."""
    try:
        c = from_bytes(data, "x.lop", allow_prefix=allow_prefix)
    except LopcookError as exc:
        if exc.reason is None:
            raise
        return {"error": exc.reason}
    return {"available_level": c.available_level, **({"stage_levels": c.stage_levels} if c.stream else {})}


def _cut(data: bytes, spec: str) -> bytes:
    kind, _, what = spec.partition(":")
    if kind == "byte":
        return data[:int(what)]
    _, _, m, _ = _split(data)
    s = next(s for s in m["sections"] if s["name"] == what)
    start = 32 + _msize(data) + s["offset"]
    return data[:start + s["length"]] if kind == "after" else data[:start + s["length"] // 2]


def _valid(name: str, data: bytes, covers: list) -> dict:
    c = from_bytes(data, name)
    return {"file": name, "kind": "valid", "covers": covers, "sha256": sha(data),
            "version": "%d.%d" % struct.unpack_from("<HH", data, 4), "max_level": c.manifest["positions"]["max_level"],
            **verdict(data, False), "expected": expected(c)}


def _prefix(name: str, of: str, cut: str, data: bytes, covers: str) -> dict:
    entry = {"file": name, "kind": "prefix", "of": of, "cut": cut, "bytes": len(data), "covers": covers,
             "sha256": sha(data), **verdict(data, False), "prefix": verdict(data, True)}
    if "available_level" in entry["prefix"]:
        entry["expected"] = expected(from_bytes(data, name, allow_prefix=True))
    return entry


def _invalid(name: str, of: str, data: bytes, covers: str, error: str) -> dict:
    got = verdict(data, False)
    if got != {"error": error}:
        raise AssertionError(f"{name}: lopcook's reader says {got}, the case expects {error}")
    return {"file": name, "kind": "invalid", "of": of, "covers": covers, "sha256": sha(data), "error": error,
            "prefix": verdict(data, True)}


def _stage_cuts(data: bytes) -> list[tuple[str, int]]:
    """Where a streaming file's stages end: after each stage's last section before the deferred
    planes, and after each deferred section but the last (the end of the file)."""
    m = manifest_of(data)
    base = 32 + struct.unpack_from("<I", data, 12)[0]
    ends: dict = {}
    for t in m["sections"]:
        stage = t["name"].split("/")[1] if t["name"].startswith("positions/stage") else None
        if stage is not None:
            key = t["name"] if t["name"].endswith("/deferred") else stage
            ends[key] = base + t["offset"] + t["length"]
    return [(k.replace("positions/", "").replace("/", "_"), v) for k, v in ends.items() if v < len(data)]


def stream_entries(files: dict) -> list[dict]:
    """The streaming layout's share (docs/format.md 14-15; tests/support/streamcases.py): its valid
    files, prefixes (streamcases' and a cut at every stage boundary of STAGE_CUTS), hostile files."""
    entries = []
    for name, data, covers in streamcases.stream_cases():
        files[name] = data
        entries.append(_valid(name, data, [covers]))
    for name, data, covers, levels in streamcases.stream_prefix_cases():
        if data in files.values():
            continue  # the whole file
        files[name] = data
        entries.append(_prefix(name, "stream_sphere.lop", f"byte:{len(data)}", data, covers))
        if entries[-1]["prefix"].get("stage_levels") != levels:
            raise AssertionError(f"{name}: lopcook's reader gives {entries[-1]['prefix']}, the case expects {levels}")
    for of in STAGE_CUTS:
        for label, cut in _stage_cuts(files[of]):
            name = f"prefix_{of[:-4]}_{label}.lop"
            files[name] = files[of][:cut]
            entries.append(_prefix(name, of, f"byte:{cut}", files[name], f"cut after {label.replace('_', ' ')}"))
    for name, data, covers, error in streamcases.stream_invalid_cases():
        files[name] = data
        entries.append(_invalid(name, "stream_plates.lop", data, covers, error))
    return entries


def generate(out: Path = OUT) -> dict:
    """Write every file and ``conformance.json`` into ``out``; return the index."""
    out.mkdir(parents=True, exist_ok=True)
    files, made, entries = {}, [], []
    for case in VALID:
        data = cook(case)
        files[case.file] = data
        entries.append(_valid(case.file, data, list(case.covers)))
    for name, of, drop, covers in TRIMMED:
        data = edit_manifest(lambda m: [m.pop(k) for k in drop])(files[of])
        files[name] = data
        entry = _valid(name, data, [covers])
        if entry.pop("expected") != next(e for e in entries if e["file"] == of)["expected"]:
            raise AssertionError(f"{name} does not decode as {of}")
        entries.append(dict(entry, expected_as=of))
    for case in PREFIXES:
        files[case.file] = _cut(files[case.of], case.cut)
        entries.append(_prefix(case.file, case.of, case.cut, files[case.file], case.covers))
    for case in INVALID:
        files[case.file] = case.mutate(files[case.of])
        entries.append(_invalid(case.file, case.of, files[case.file], case.covers, case.error))
    entries += stream_entries(files)
    for name, data in files.items():
        (out / name).write_bytes(data)
        made.append(name)
    index = {"format": FORMAT, "generator": "tests/support/conformance.py", "readme": "README.md",
             "dumps": "tests/support/dumps.py; runtime/c/examples/lopdump --positions --gpu --attributes",
             "files": entries}
    head = json.dumps({k: v for k, v in index.items() if k != "files"}, sort_keys=True, separators=(",", ":"))
    lines = [json.dumps(e, sort_keys=True, separators=(",", ":")) for e in entries]
    (out / INDEX).write_text(head[:-1] + ',"files":[\n' + ",\n".join(lines) + "\n]}\n")
    return index


def main(argv: list[str]) -> int:
    index = generate(Path(argv[1]) if len(argv) > 1 else OUT)
    kinds = [e["kind"] for e in index["files"]]
    print(f"{len(kinds)} files: {kinds.count('valid')} valid, {kinds.count('prefix')} prefixes, "
          f"{kinds.count('invalid')} invalid")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
