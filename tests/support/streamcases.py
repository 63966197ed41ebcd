"""Streaming-layout containers for the conformance set (docs/format.md 14-15), and the section
surgery the tests and the fuzz corpus use to make hostile ones.

``stream_cases()``: ``(name, bytes, what it covers)`` of valid streaming files, cooked with
``lopcook cook --stream`` from ``fixtures/`` and a synthetic scene of placements (deterministic). ``stream_prefix_cases()``:
``(name, bytes, what it covers, expected stage levels or None)`` of prefixes of them (None: a reader
refuses it). ``stream_invalid_cases()``: ``(name, bytes, what it covers, error class)``, one defect
each with every checksum recomputed, so only the format's checks catch it; the classes are those
of the conformance set (``manifest``, ``section_table``, ``version``) plus ``encoding`` (a stored
stream that does not decode as section 15 says, an encoded manifest's included). A malformed
``encoding`` or ``size`` field is ``section_table`` (docs/format.md 12.1).

Surgery: ``stored_sections(data)`` splits a container into its manifest (without the table) and
its stored sections ``(name, stored bytes, {"encoding", "size"} or {})``; ``rebuild`` writes them
back with the table, header and checksums recomputed (``lopcook.lop.container.to_bytes``);
``with_section`` replaces one section's stored bytes and fields.
"""

from __future__ import annotations

import functools
import json
import struct
import zlib
from pathlib import Path

import numpy as np

from lopcook import api
from lopcook.cli.parser import build_parser, settings_from_args
from lopcook.lop.container import manifest_of, to_bytes
from lopcook.lop.encoding import deflate, encode_manifest, encode_triangles
from lopcook.types import MeshPart, Scene

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "fixtures"

#: (name, fixture, cook flags, what it covers)
VALID = (
    ("stream_plates.lop", "two_plates.glb", ("--stream", "--lods", "auto", "--clusters", "0", "--no-edges"),
     "streaming layout: two parts with LOD chains, unclustered, empty planes without sections"),
    ("stream_cube_clustered.lop", "seamed_cube.glb", ("--stream", "--lods", "1/2", "--clusters", "16",
                                                      "--cluster-all"),
     "streaming layout: clustered buffers (per-stage cluster sections)"),
    ("stream_wedges.lop", "wedges", ("--stream", "--instances", "--lods", "1/2,1/4", "--lod-backend", "fast",
                                     "--clusters", "0"),
     "streaming layout: placements of one shared buffer (stage levels with level shifts) beside a part with "
     "a LOD chain"),
    ("stream_sphere.lop", "unit_sphere.glb", ("--stream", "--lods", "1/2,1/4,1/8", "--clusters", "0"),
     "streaming layout: deflate and meshopt-deflate sections, deferred planes"),
)


def wedges() -> Scene:
    """Three copies of an asymmetric wedge (turned, scaled, moved apart: placements) and a curved
    sheet of 12 x 12 vertices (a LOD chain)."""
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0.5], [1, 0, 0.5], [0, 1, 0.5]], np.float64)
    t = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]], np.uint32)
    parts = []
    for i, (deg, scale, move) in enumerate([(0.0, 1.0, (0, 0, 0)), (90.0, 1.0, (3, 0, 0)), (30.0, 2.0, (0, 0, 4))]):
        c, sn = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        turn = np.array([[c, 0, sn], [0, 1, 0], [-sn, 0, c]])
        parts.append(MeshPart(name=f"wedge{i}", positions=(p * scale) @ turn.T + np.array(move, np.float64),
                              indices=t.copy(), source=f"wedge {i}", mesh_key="wedge"))
    u, v = np.meshgrid(np.linspace(0.0, 1.0, 12), np.linspace(0.0, 1.0, 12), indexing="ij")
    sheet = np.stack([u * 2.0 + 4.0, 0.3 * np.sin(3.0 * u) * np.cos(2.0 * v) - 1.0, v * 2.0 + 2.0], -1).reshape(-1, 3)
    q = np.array([[i * 12 + j, i * 12 + j + 1, (i + 1) * 12 + j + 1, (i + 1) * 12 + j] for i in range(11)
                  for j in range(11)])
    tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]).astype(np.uint32)
    parts.append(MeshPart(name="sheet", positions=sheet, indices=tris, source="sheet", mesh_key="sheet"))
    return Scene(parts=tuple(parts), source="wedges.synthetic", format="glb").validate()


def _cook(fixture: str, flags: tuple) -> bytes:
    """The bytes ``lopcook cook FIXTURE FLAGS`` writes, less ``source.path``: cooked through the API
    with the CLI's settings and no output path, so the bytes do not depend on where the
    repository lies (``source.path`` is relative to the output's folder)."""
    settings = settings_from_args(build_parser().parse_args(["cook", f"{fixture}.glb", "-o", "out.lop", *flags]))
    scene = wedges() if fixture == "wedges" else api.load(str(FIXTURES / fixture), settings)
    return api.cook(scene, settings).data


@functools.lru_cache(maxsize=None)
def cooked(name: str) -> bytes:
    """The bytes of the valid case ``name`` (cooked once per process)."""
    fixture, flags = next((f, fl) for n, f, fl, _ in VALID if n == name)
    return _cook(fixture, flags)


def stream_cases() -> list[tuple[str, bytes, str]]:
    """The valid streaming files: ``(name, bytes, what it covers)``."""
    return [(name, cooked(name), covers) for name, _, _, covers in VALID]


# ---- surgery ----------------------------------------------------------------------------------

def stored_sections(data: bytes) -> tuple[dict, list]:
    """``(manifest without its table, [(name, stored bytes, fields)])`` of a complete container."""
    msize = struct.unpack_from("<I", data, 12)[0]
    m = manifest_of(data)
    base = 32 + msize
    out = [(t["name"], data[base + t["offset"]:base + t["offset"] + t["length"]],
            {k: t[k] for k in ("encoding", "size") if k in t}) for t in m["sections"]]
    return {k: v for k, v in m.items() if k != "sections"}, out


def rebuild(manifest: dict, sections: list) -> bytes:
    """A container of these sections, table, header and checksums recomputed."""
    return to_bytes(manifest, [(n, s, f) for n, s, f in sections])


def with_section(data: bytes, name: str, stored: bytes, fields: dict) -> bytes:
    """``data`` with section ``name`` stored as ``stored`` (padded to 4) with ``fields``."""
    m, secs = stored_sections(data)
    padded = stored + b"\0" * (-len(stored) % 4)
    return rebuild(m, [(n, padded, fields) if n == name else (n, s, f) for n, s, f in secs])


def edit_manifest(data: bytes, fn) -> bytes:
    """``data`` with its manifest changed by ``fn(manifest)`` (the table kept as it is, checksums
    recomputed; encoded as it was): a lie about the sections or the layout."""
    msize = struct.unpack_from("<I", data, 12)[0]
    m = manifest_of(data)
    fn(m)
    mb = json.dumps(m, sort_keys=True, separators=(",", ":")).encode()
    if data[32] == 0:
        mb = encode_manifest(mb)
    payload = data[32 + msize:]
    major, minor = struct.unpack_from("<HH", data, 4)
    head = struct.pack("<4sHHIIIQ", b"LOPC", major, minor, 32, len(mb), zlib.crc32(mb), 32 + len(mb) + len(payload))
    return head + struct.pack("<I", zlib.crc32(head)) + mb + payload


def relabel(data: bytes, major: int, minor: int = 0) -> bytes:
    head = bytearray(data[:28])
    head[4:8] = struct.pack("<HH", major, minor)
    return bytes(head) + struct.pack("<I", zlib.crc32(bytes(head))) + data[32:]


def encoded(data: bytes, encoding: str) -> str:
    """The name of the first section of ``data`` stored with ``encoding``."""
    return next(t["name"] for t in manifest_of(data)["sections"] if t.get("encoding") == encoding)


def lod_of(data: bytes, section: str) -> dict:
    return next(e for p in manifest_of(data)["parts"] for e in p["lods"] if e["indices"] == section)


def triangles_stream(data: bytes, section: str) -> bytes:
    """The inflated EXT_meshopt_compression triangle stream of a ``meshopt-deflate`` section."""
    _, secs = stored_sections(data)
    stored = next(s for n, s, _ in secs if n == section)
    z = zlib.decompressobj(-15)
    return z.decompress(stored)


# ---- prefixes and hostile files -------------------------------------------------------------------

def _ends(data: bytes) -> dict:
    msize = struct.unpack_from("<I", data, 12)[0]
    return {t["name"]: 32 + msize + t["offset"] + t["length"] for t in manifest_of(data)["sections"]}


def stream_prefix_cases() -> list[tuple[str, bytes, str, list | None]]:
    """Prefixes of ``stream_sphere.lop``: ``(name, bytes, covers, stage levels or None)``."""
    data = cooked("stream_sphere.lop")
    end = _ends(data)
    msize = struct.unpack_from("<I", data, 12)[0]
    m = manifest_of(data)
    levels = [st["level"] for st in m["positions"]["stages"]]
    top = m["positions"]["max_level"]
    full = [top] * len(levels)
    first = [levels[0]] + [0] * (len(levels) - 1)
    two = levels[:2] + [0] * (len(levels) - 2)
    return [
        ("stream_prefix_inside_manifest.lop", data[:32 + msize // 2], "cut inside the manifest", None),
        ("stream_prefix_stage0_indices.lop", data[:end["part0/lod3/indices"]],
         "cut before stage 0's mandatory bits: refused", None),
        ("stream_prefix_stage0.lop", data[:end["positions/stage0/mandatory"]],
         "stage 0 renderable: first renderable state", first),
        ("stream_prefix_inside_stage1.lop", data[:end["positions/stage1/mandatory"] - 2],
         "cut inside stage 1's mandatory bits: stage 0 only", first),
        ("stream_prefix_stage1.lop", data[:end[_last_of_stage(m, 1)]], "stages 0 and 1 at their levels", two),
        ("stream_prefix_before_deferred.lop", data[:min(end[n] for n in end if n.endswith("/deferred")) - 4],
         "every stage at its level, the deferred planes not arrived", levels),
        ("stream_prefix_complete.lop", data, "the whole file", full),
    ]


def _last_of_stage(m: dict, s: int) -> str:
    prefix = f"positions/stage{s}/"
    return [t["name"] for t in m["sections"] if t["name"].startswith(prefix) and not t["name"].endswith("deferred")][-1]


def _lie_size(data: bytes, name: str, delta: int) -> bytes:
    def fn(m):
        t = next(t for t in m["sections"] if t["name"] == name)
        t["size"] += delta
    return edit_manifest(data, fn)


def _meshopt_variant(data: bytes, name: str, fn) -> bytes:
    """``data`` with meshopt-deflate section ``name``'s triangle stream changed by ``fn(bytearray)``."""
    stream = bytearray(triangles_stream(data, name))
    fn(stream)
    m, secs = stored_sections(data)
    size = next(f["size"] for n, _, f in secs if n == name)
    return with_section(data, name, deflate(bytes(stream)), {"encoding": "meshopt-deflate", "size": size})


def stream_invalid_cases() -> list[tuple[str, bytes, str, str]]:
    """Hostile streaming files made from ``stream_plates.lop``: ``(name, bytes, covers, error class)``."""
    data = cooked("stream_plates.lop")
    dfl, mo = encoded(data, "deflate"), encoded(data, "meshopt-deflate")
    lod = lod_of(data, mo)
    m, secs = stored_sections(data)
    stored = next(s for n, s, _ in secs if n == dfl)
    raw = zlib.decompressobj(-15).decompress(stored)
    big = np.full(3 * lod["triangles"], lod["vertices"], np.uint32)  # every index out of range
    wide = np.arange(3 * lod["triangles"], dtype=np.uint32) % lod["vertices"] + 65536
    out = [
        ("stream_as_3_0.lop", relabel(data, 3), "a streaming file labelled 3.0 (its encoded manifest refused)",
         "version"),
        ("stream_json_as_3_0.lop", relabel(_plain_manifest(data), 3),
         "a streaming file with a JSON manifest labelled 3.0", "version"),
        ("manifest_encoded_size.lop", _manifest_size_lie(data), "an encoded manifest whose size lies", "encoding"),
        ("manifest_encoded_corrupt.lop", _manifest_block_type_3(data), "an encoded manifest whose deflate stream "
         "holds block type 3", "encoding"),
        ("stream_sections_swapped.lop", rebuild(m, [secs[1], secs[0], *secs[2:]]),
         "two sections in another order than the layout's (table and checksums consistent)", "manifest"),
        ("stream_stage_level_25.lop", edit_manifest(data, lambda mm: mm["positions"]["stages"][0].update(level=25)),
         "a stage level above max_level", "manifest"),
        ("stream_no_stages.lop", edit_manifest(data, lambda mm: mm["positions"].update(stages=[])),
         "positions.stages empty", "manifest"),
        ("stream_coarsest_not_first.lop", edit_manifest(data, lambda mm: mm["parts"][0]["lods"][-1].update(stage=1)),
         "a part's coarsest LOD outside stage 0", "manifest"),
        ("stream_finer_first.lop", edit_manifest(data, lambda mm: mm["parts"][0]["lods"][0].update(stage=0)),
         "a finer LOD in an earlier stage than a coarser one", "manifest"),
        ("stream_stage_missing.lop", edit_manifest(data, lambda mm: mm["parts"][1]["lods"][0].pop("stage")),
         "a LOD entry without its stage", "manifest"),
        ("encoding_unknown.lop", with_section(data, dfl, stored, {"encoding": "lzma", "size": len(raw)}),
         "an unknown encoding", "section_table"),
        ("encoding_no_size.lop", edit_manifest(data, lambda mm: next(
            t for t in mm["sections"] if t["name"] == dfl).pop("size")), "encoding without size", "section_table"),
        ("encoding_expands.lop", with_section(data, dfl, deflate(raw + bytes(4)), {"encoding": "deflate",
                                                                                  "size": len(raw)}),
         "a deflate stream expanding beyond its size", "encoding"),
        ("encoding_size_large.lop", _lie_size(data, dfl, 4), "a deflate stream shorter than its size", "encoding"),
        ("encoding_size_bomb.lop", _lie_size(data, dfl, 2000 * len(stored)), "a size beyond 1032 times the stored bytes",
         "section_table"),
        ("encoding_distance_far.lop", with_section(data, dfl, _far_match(), {"encoding": "deflate", "size": len(raw)}),
         "a deflate match reaching before the first byte decoded", "encoding"),
        ("encoding_stored_length.lop", with_section(data, dfl, b"\x01\x04\x00\x00\x00" + raw[:4],
                                                    {"encoding": "deflate", "size": len(raw)}),
         "a stored block whose NLEN is not the complement of LEN", "encoding"),
        ("encoding_corrupt.lop", with_section(data, dfl, bytes([0xFF]) * len(stored), {"encoding": "deflate",
                                                                                       "size": len(raw)}),
         "a corrupt deflate stream (block type 3)", "encoding"),
        ("encoding_truncated.lop", with_section(data, dfl, stored[:len(stored) // 2], {"encoding": "deflate",
                                                                                      "size": len(raw)}),
         "a deflate stream cut short", "encoding"),
        ("encoding_trailing.lop", with_section(data, dfl, deflate(raw) + b"\0\0\0\0\x01", {"encoding": "deflate",
                                                                                          "size": len(raw)}),
         "bytes after the deflate stream that are not its padding", "encoding"),
        ("meshopt_header.lop", _meshopt_variant(data, mo, lambda s: s.__setitem__(0, 0xE0)),
         "a triangle stream of version 0", "encoding"),
        ("meshopt_table.lop", _meshopt_variant(data, mo, lambda s: s.__setitem__(-3, 0x0F)),
         "a triangle stream whose table holds a nibble 0xF", "encoding"),
        ("meshopt_short.lop", _meshopt_variant(data, mo, lambda s: s.__delitem__(slice(-17, -16))),
         "a triangle stream that reads past its data", "encoding"),
        ("meshopt_extra.lop", _meshopt_variant(data, mo, lambda s: s.__setitem__(slice(-16, -16), b"\0")),
         "a triangle stream with data its triangles do not read", "encoding"),
        ("meshopt_fifo_unwritten.lop", _meshopt_variant(data, mo, lambda s: s.__setitem__(1, 0x01)),
         "a first triangle reading FIFO entries never written (index 0xFFFFFFFF)", "encoding"),
        ("meshopt_range.lop", with_section(data, mo, deflate(encode_triangles(big)[0]),
                                           {"encoding": "meshopt-deflate", "size": _index_size(lod)}),
         "triangle indices equal to the vertex count", "encoding"),
        ("meshopt_wide.lop", with_section(data, mo, deflate(encode_triangles(wide)[0]),
                                          {"encoding": "meshopt-deflate", "size": _index_size(lod)}),
         "triangle indices above 65535 that a 16-bit narrowing would hide", "encoding"),
        ("meshopt_on_attributes.lop", _on_attributes(data), "meshopt-deflate on an attribute section", "manifest"),
    ]
    return out


def _plain_manifest(data: bytes) -> bytes:
    """``data`` with its manifest stored as JSON text (a 4.x reader reads either)."""
    msize = struct.unpack_from("<I", data, 12)[0]
    mb = json.dumps(manifest_of(data), sort_keys=True, separators=(",", ":")).encode()
    head = bytearray(data[:28])
    head[12:20] = struct.pack("<II", len(mb), zlib.crc32(mb))
    head[20:28] = struct.pack("<Q", len(data) - msize + len(mb))
    return bytes(head) + struct.pack("<I", zlib.crc32(bytes(head))) + mb + data[32 + msize:]


def _manifest_size_lie(data: bytes) -> bytes:
    msize = struct.unpack_from("<I", data, 12)[0]
    mb = bytearray(data[32:32 + msize])
    mb[1:5] = struct.pack("<I", struct.unpack_from("<I", mb, 1)[0] + 1)
    head = bytearray(data[:28])
    head[16:20] = struct.pack("<I", zlib.crc32(bytes(mb)))
    return bytes(head) + struct.pack("<I", zlib.crc32(bytes(head))) + bytes(mb) + data[32 + msize:]


def _manifest_block_type_3(data: bytes) -> bytes:
    """``data`` with its encoded manifest's first DEFLATE block header set to block type 3 (the
    manifest's CRC and the header recomputed)."""
    msize = struct.unpack_from("<I", data, 12)[0]
    mb = bytearray(data[32:32 + msize])
    mb[5] |= 0x06
    head = bytearray(data[:28])
    head[16:20] = struct.pack("<I", zlib.crc32(bytes(mb)))
    return bytes(head) + struct.pack("<I", zlib.crc32(bytes(head))) + bytes(mb) + data[32 + msize:]


def _far_match() -> bytes:
    """A raw DEFLATE stream (one fixed-Huffman block) whose first symbol is a match of length 3 at
    distance 1: nothing has been decoded for it to copy."""
    bits = [1, 1, 0]  # BFINAL, BTYPE = 01 (least significant bit first)
    bits += [0, 0, 0, 0, 0, 0, 1]  # literal/length 257 (7-bit code 0000001, most significant bit first)
    bits += [0, 0, 0, 0, 0]  # distance code 0: distance 1
    bits += [0] * 7  # end of block (256)
    out = bytearray((len(bits) + 7) // 8)
    for i, b in enumerate(bits):
        out[i // 8] |= b << (i % 8)
    return bytes(out)


def _index_size(lod: dict) -> int:
    return 4 * -(-3 * lod["triangles"] * lod["index_width"] // 4)


def _on_attributes(data: bytes) -> bytes:
    m, secs = stored_sections(data)
    name, stored, fields = next(x for x in secs if x[0].endswith("/attributes"))
    payload = zlib.decompressobj(-15).decompress(stored) if fields else stored
    return with_section(data, name, deflate(payload), {"encoding": "meshopt-deflate", "size": len(payload)})


__all__ = ["stream_cases", "stream_prefix_cases", "stream_invalid_cases", "stored_sections", "rebuild",
           "with_section", "edit_manifest", "relabel", "cooked", "VALID"]
