"""Worked example of docs/format.md: cook fixtures/two_plates.glb, then read it back by hand.

Run from the repository root::

    .venv/bin/python docs/worked_example.py

It cooks ``fixtures/two_plates.glb`` exactly as ``lopcook cook fixtures/two_plates.glb -o OUT.lop --no-edges --clusters 0``
does (default options), then walks through the bytes with nothing but ``struct``, ``json``,
``zlib`` and plain integer arithmetic -- the way an engine's reader would -- and prints every
number that docs/format.md ("Worked example") shows. Float32 arithmetic uses numpy float32
scalars so that each operation is rounded to float32 exactly once, as a shader does.

At the end the hand-decoded values are cross-checked against lopcook's own reader
(``lopcook.lop.reader``); the script fails loudly if they disagree. ``tests/lop/test_container_schema.py``
runs this script and checks that its output and the block in docs/format.md agree.

Output: ``key: value`` lines; lines whose value depends on the whole manifest (its size and
CRC, the file size, the header CRC) are marked in VOLATILE below.
"""

from __future__ import annotations

import json
import os
import struct
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
FIXTURE = REPO / "fixtures" / "two_plates.glb"

#: keys whose values change whenever anything in the manifest changes (generator version,
#: encodings text, source hash, ...): the test only checks that format.md shows the same keys.
VOLATILE = ("header.bytes[12:32]", "header.manifest_size", "header.manifest_crc32", "header.file_size",
            "header.header_crc32", "manifest.bytes", "sections.base")

PART = 1          # plate_upper
LOD = 0
VERTEX = 17       # binned index j inside that buffer
LEVEL_A, LEVEL_B = 11, 12
LEVELS = 24


def out(key: str, value) -> None:
    print(f"{key}: {value}")


def cook() -> bytes:
    """The bytes ``lopcook cook fixtures/two_plates.glb -o OUT.lop --no-edges --clusters 0`` writes
    (the unclustered layout this example reads by hand)."""
    from lopcook.cli import main

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "two_plates.lop")
        rc = main(["-q", "cook", str(FIXTURE), "-o", path, "--no-edges", "--clusters", "0"])
        if rc != 0:
            raise SystemExit(f"lopcook cook failed with exit code {rc}")
        return Path(path).read_bytes()


def bits_lsb_first(value: int, width: int) -> str:
    """The field as it sits in the buffer: bit 0 first (left), bit width-1 last."""
    return "".join(str((value >> i) & 1) for i in range(width))


def read_field(words: list[int], offset: int, width: int) -> tuple[int, int, int]:
    """Field of ``width`` (<= 24) bits at bit ``offset``: (value, word index, shift)."""
    w, s = offset >> 5, offset & 31
    lo = words[w]
    hi = words[w + 1] if w + 1 < len(words) else 0
    both = lo | (hi << 32)
    return (both >> s) & ((1 << width) - 1), w, s


def vertex_id_bin(vertex_id: list[int], j: int) -> int:
    """The bin k (level) of vertex j: VertexId[k-1] <= j < VertexId[k]."""
    return next(k for k in range(1, LEVELS + 1) if vertex_id[k - 1] <= j < vertex_id[k])


def bit_id(vertex_id: list[int], level: int) -> list[int]:
    """BitId[k] = sum_{i<=k} 3 * max(i, B) * (VertexId[i] - VertexId[i-1]); BitId[0] = 0."""
    table = [0]
    for k in range(1, LEVELS + 1):
        table.append(table[-1] + 3 * max(k, level) * (vertex_id[k] - vertex_id[k - 1]))
    return table


def plane_start(m: dict, part: int, lod: int, p: int) -> int:
    """First stream bit of buffer (part, lod) in plane p: 3 * VertexId[p-1] of every earlier buffer."""
    start = 0
    for i, other_part in enumerate(m["parts"]):
        for k, other in enumerate(other_part["lods"]):
            if (i, k) == (part, lod):
                return start
            start += 3 * other["vertex_id"][p - 1]
    raise KeyError((part, lod))


def pack(values: list[list[int]], widths: list[int]) -> list[int]:
    """Pack fields LSB first into uint32 words (the buffer P)."""
    acc, nbits = 0, 0
    for (x, y, z), b in zip(values, widths):
        for v in (x, y, z):
            acc |= v << nbits
            nbits += b
    return [(acc >> (32 * i)) & 0xFFFFFFFF for i in range((nbits + 31) // 32)]


def compact(table: list[int]) -> str:
    """A 25-entry table written as runs: '[0] * 11 + [81] * 14'."""
    runs: list[list[int]] = []
    for v in table:
        if runs and runs[-1][0] == v:
            runs[-1][1] += 1
        else:
            runs.append([v, 1])
    return " + ".join(f"[{v}] * {n}" if n > 1 else f"[{v}]" for v, n in runs)


def f32hex(x: np.float32) -> str:
    return "0x" + struct.pack(">f", float(x)).hex()


def main() -> int:
    data = cook()

    # ---- header -----------------------------------------------------------------------------
    out("file", "fixtures/two_plates.glb cooked with --no-edges --clusters 0 (depth levels only, unclustered)")
    out("header.bytes[0:12]", data[0:12].hex(" "))
    out("header.bytes[12:32]", data[12:32].hex(" "))
    magic, major, minor, hsize, msize, mcrc, total = struct.unpack_from("<4sHHIIIQ", data, 0)
    (hcrc,) = struct.unpack_from("<I", data, 28)
    assert magic == b"LOPC" and hsize == 32 and total == len(data)
    assert zlib.crc32(data[:28]) == hcrc
    out("header.magic", magic.decode("ascii"))
    out("header.version", f"{major}.{minor}")
    out("header.header_size", hsize)
    out("header.manifest_size", msize)
    out("header.manifest_crc32", f"0x{mcrc:08x}")
    out("header.file_size", total)
    out("header.header_crc32", f"0x{hcrc:08x}")

    # ---- manifest ---------------------------------------------------------------------------
    mbytes = data[32:32 + msize]
    assert zlib.crc32(mbytes) == mcrc
    m = json.loads(mbytes.decode("ascii"))
    base = 32 + msize
    out("manifest.bytes", f"{msize} bytes of ASCII JSON at file offset 32")
    out("sections.base", f"{base} (= 32 + manifest_size; section offsets are relative to it)")
    out("manifest.format", m["format"])
    out("manifest.grid", json.dumps(m["grid"], sort_keys=True))
    out("manifest.positions.max_level", m["positions"]["max_level"])
    out("manifest.stats.histogram", compact(m["stats"]["histogram"]))
    for i, p in enumerate(m["parts"]):
        e = p["lods"][0]
        out(f"manifest.parts[{i}]", f"{p['name']!r}: {e['vertices']} vertices, {e['triangles']} triangles, "
                                    f"mandatory_words {e['mandatory_words']}, index_width {e['index_width']}")
    sec = {s["name"]: s for s in m["sections"]}
    for s in m["sections"]:
        if s["name"].startswith("positions/plane") and int(s["name"][-2:]) not in (2, 11, 12, 13, 24):
            continue  # abridged
        payload = data[base + s["offset"]:base + s["offset"] + s["length"]]
        assert zlib.crc32(payload) == s["crc32"]
        out(f"section {s['name']}", f"offset {s['offset']}, length {s['length']}, crc32 0x{s['crc32']:08x}")

    # ---- the buffer: part 1, LOD 0 ----------------------------------------------------------
    e = m["parts"][PART]["lods"][LOD]
    vid = e["vertex_id"]
    out("buffer", f"part {PART} ({m['parts'][PART]['name']!r}) LOD {LOD}, n = {e['vertices']}")
    out("VertexId", compact(vid))
    for level in (LEVEL_A, LEVEL_B):
        table = bit_id(vid, level)
        nbits = table[LEVELS]
        out(f"BitId(B={level})", compact(table))
        out(f"P(B={level}).size", f"{nbits} bits = {(nbits + 31) // 32} words = {4 * ((nbits + 31) // 32)} bytes")

    # ---- vertex j from the mandatory words (P at level 1) ------------------------------------
    j = VERTEX
    k = vertex_id_bin(vid, j)
    out("vertex.j", j)
    out("vertex.bin", f"k = {k} (VertexId[{k - 1}] = {vid[k - 1]} <= {j} < VertexId[{k}] = {vid[k]})")
    woff, wcount = e["mandatory_words"]
    msec = sec[m["positions"]["mandatory"]]
    mand = struct.unpack_from(f"<{wcount}I", data, base + msec["offset"] + 4 * woff)
    mand = list(mand)
    b1 = max(k, 1)
    t1 = bit_id(vid, 1)
    o1 = 3 * b1 * (j - vid[k - 1]) + t1[k - 1]
    out("mandatory.words", f"words {woff}..{woff + wcount - 1} of section positions/mandatory "
                           f"(byte {4 * woff} of the section)")
    out("mandatory.offset", f"o = 3*{b1}*({j} - {vid[k - 1]}) + BitId_1[{k - 1}] = {o1}")
    v1 = []
    for c, name in enumerate("xyz"):
        v, w, s = read_field(mand, o1 + c * b1, b1)
        v1.append(v)
        out(f"mandatory.{name}", f"bit {o1 + c * b1} = word {w} shift {s}"
                                 f"{' (spans words %d, %d)' % (w, w + 1) if s + b1 > 32 else ''}; "
                                 f"P[{w}] = 0x{mand[w]:08x}"
                                 f"{', P[%d] = 0x%08x' % (w + 1, mand[w + 1]) if s + b1 > 32 else ''}; "
                                 f"field (LSB first) {bits_lsb_first(v, b1)} = {v} = 0x{v:x}")

    # ---- refinement planes 2..12 -----------------------------------------------------------
    # Every buffer's bits follow each other in manifest order; buffer (PART, LOD) starts after
    # 3 * VertexId_other[p-1] bits of every buffer before it.
    values = list(v1)
    skipped = []
    for p in range(2, LEVEL_B + 1):
        count = 3 * vid[p - 1]
        if vid[p - 1] <= j:
            skipped.append(p)  # only vertices j < VertexId[p-1] (level < p) have a bit in plane p
            continue
        start = plane_start(m, PART, LOD, p)
        ps = sec[m["positions"]["planes"][str(p)]]
        plane = data[base + ps["offset"]:base + ps["offset"] + ps["length"]]
        got = []
        for c, name in enumerate("xyz"):
            bit = start + 3 * j + c
            byte, shift = bit >> 3, bit & 7
            got.append((plane[byte] >> shift) & 1)
            out(f"plane{p:02d}.{name}", f"buffer starts at bit {start}; bit {start} + 3*{j} + {c} = {bit} = "
                                        f"byte {byte} (0x{plane[byte]:02x}) bit {shift} -> {got[-1]}")
        values = [(v << 1) | g for v, g in zip(values, got)]
        out(f"plane{p:02d}.count", f"{count} bits for this buffer")
    if skipped:
        out("planes.skipped", f"planes {skipped[0]}..{skipped[-1]}: VertexId[p-1] <= {j}, vertex {j} gains no bit "
                              f"(lengths {sorted({sec[m['positions']['planes'][str(p)]]['length'] for p in skipped})})")
    width = max(k, LEVEL_B)
    out(f"vertex.v(B={LEVEL_B})", f"({', '.join('0x%03x' % v for v in values)}) = {tuple(values)}, {width} bits each")

    # ---- the packed buffer P at level 12 and the paper's random access ----------------------
    # unpack everything at level 1, add the planes, pack at level 12 (what a GPU upload does)
    n = e["vertices"]
    allv = []
    for jj in range(n):
        kk = vertex_id_bin(vid, jj)
        bb = max(kk, 1)
        oo = 3 * bb * (jj - vid[kk - 1]) + t1[kk - 1]
        allv.append([read_field(mand, oo + c * bb, bb)[0] for c in range(3)])
    for p in range(2, LEVEL_B + 1):
        if vid[p - 1] == 0:
            continue
        start = plane_start(m, PART, LOD, p)
        ps = sec[m["positions"]["planes"][str(p)]]
        plane = data[base + ps["offset"]:base + ps["offset"] + ps["length"]]
        for jj in range(vid[p - 1]):
            for c in range(3):
                bit = start + 3 * jj + c
                allv[jj][c] = (allv[jj][c] << 1) | ((plane[bit >> 3] >> (bit & 7)) & 1)
    widths = [max(vertex_id_bin(vid, jj), LEVEL_B) for jj in range(n)]
    P = pack(allv, widths)
    t12 = bit_id(vid, LEVEL_B)
    o12 = 3 * width * (j - vid[k - 1]) + t12[k - 1]
    out(f"P(B={LEVEL_B}).offset", f"o = 3*{width}*({j} - {vid[k - 1]}) + BitId_{LEVEL_B}[{k - 1}] = {o12}")
    for c, name in enumerate("xyz"):
        v, w, s = read_field(P, o12 + c * width, width)
        assert v == values[c]
        out(f"P(B={LEVEL_B}).{name}", f"bit {o12 + c * width} = word {w} shift {s}; P[{w}] = 0x{P[w]:08x}, "
                                      f"P[{w + 1}] = 0x{P[w + 1]:08x}; "
                                      f"(P[{w}] >> {s} | P[{w + 1}] << {32 - s}) & 0x{(1 << width) - 1:x} = {v}")

    # ---- float reconstruction ----------------------------------------------------------------
    g = m["grid"]
    origin32 = [np.float32(o) for o in g["origin"]]
    half32 = np.float32(g["extent"] / float(1 << LEVELS) / 2.0)
    out("grid.half_cell", f"float32(extent / 2^24 / 2) = {float(half32)!r} ({f32hex(half32)})")
    pos = []
    s = LEVELS - width
    for c, name in enumerate("xyz"):
        cc = ((2 * values[c] + 1) << s)
        prod = np.float32(np.float32(cc) * half32)
        p32 = np.float32(origin32[c] + prod)
        pos.append(p32)
        out(f"float.{name}", f"c = (2*{values[c]} + 1) << {s} = {cc}; float32(c) * half = {float(prod)!r}; "
                             f"+ origin {float(origin32[c])!r} = {float(p32)!r} ({f32hex(p32)})")

    # ---- the source vertex and the error bound ----------------------------------------------
    from lopcook.ingest import load

    scene = load(str(FIXTURE))
    src = scene.parts[PART].positions[j]  # binned order == source order here (one bin)
    err = float(np.linalg.norm(np.array([float(v) for v in pos]) - src))
    dxb = float(np.sqrt(3.0) * g["extent"] * 2.0 ** -(width + 1))
    out("source.position", f"({', '.join(repr(float(v)) for v in src)})")
    out("error", f"|decoded - source| = {err:.6e} m <= dx({width}) = {dxb:.6e} m")

    # ---- the attributes of vertex j and the first triangle ------------------------------------
    isec = sec[e["indices"]]
    tri = struct.unpack_from("<3H" if e["index_width"] == 2 else "<3I", data, base + isec["offset"])
    out("indices.triangle0", f"section {e['indices']}, {e['index_width']} bytes per index: {tri}")
    # the attribute record: fields normal.u, normal.v (b_n bits), uv.u, uv.v (b_u bits), LSB first,
    # vertex j at bit j * S; a field may span two words
    ab = e["attribute_bits"]
    bn, bu, S = ab["normals"], ab["uvs"], e["record_bits"]
    asec = sec[e["attributes"]]
    words = struct.unpack_from(f"<{asec['length'] // 4}I", data, base + asec["offset"])

    def field(o, b):
        w, s = o >> 5, o & 31
        lo = words[w] >> s
        hi = (words[min(w + 1, len(words) - 1)] << 1 << (31 - s)) & 0xFFFFFFFF
        return (lo | hi) & ((1 << b) - 1)

    o = j * S
    cu, cv = field(o, bn), field(o + bn, bn)
    f32 = np.float32
    h = 1 << (bn - 1)
    r = f32(1.0 / (h - 1))
    px, py = max(f32(cu - h) * r, f32(-1.0)), max(f32(cv - h) * r, f32(-1.0))
    nz = (f32(1) - abs(px)) - abs(py)
    nx, ny = (px, py) if nz >= 0 else ((f32(1) - abs(py)) * (f32(1) if px >= 0 else f32(-1)),
                                        (f32(1) - abs(px)) * (f32(1) if py >= 0 else f32(-1)))
    normal = [float(v) for v in (nx, ny, nz)]
    out("normal", f"bits {o}..{o + 2 * bn - 1} of {e['attributes']} (S = {S}): codes ({cu}, {cv}) -> s = "
                  f"({cu - h}, {cv - h}) -> p = ({float(px)!r}, {float(py)!r}) -> n = ({', '.join(map(repr, normal))})"
                  " (unnormalised)")
    qu, qv = field(o + 2 * bn, bu), field(o + 2 * bn + bu, bu)
    (lo_u, lo_v), _ = e["uv_range"]
    su, sv = e["uv_step"]
    uv = [float(f32(lo) + f32(q) * f32(st)) for q, lo, st in ((qu, lo_u, su), (qv, lo_v, sv))]
    out("uv", f"bits {o + 2 * bn}..{o + 2 * bn + 2 * bu - 1}: codes ({qu}, {qv}), uv_range {e['uv_range']}, "
              f"uv_step {e['uv_step']} -> ({uv[0]!r}, {uv[1]!r})")

    # ---- cross-check against lopcook's own reader ---------------------------------------------
    from lopcook.lop.container import from_bytes
    from lopcook.lop.reader import decode_positions, gpu_buffer, lod_attributes

    cont = from_bytes(data)
    buf = gpu_buffer(cont, PART, LOD, LEVEL_B)
    assert [int(w) for w in buf.words] == P, "hand-packed P differs from lopcook.lop.reader.gpu_buffer"
    assert [int(v) for v in buf.bit_id] == t12
    _, _, ref = decode_positions(cont, PART, LOD, LEVEL_B)
    assert [float(v) for v in ref[j]] == [float(v) for v in pos], (ref[j], pos)
    attrs = lod_attributes(cont, PART, LOD)
    assert [int(v) for v in attrs["indices"][0]] == list(tri)
    assert [float(v) for v in attrs["normals"][j]] == normal
    assert [float(v) for v in attrs["uvs"][j]] == uv
    out("check", "hand decode == lopcook.lop.reader (P words, BitId, float32 position, attributes)")

    # ---- a hand-made buffer with several bins ------------------------------------------------
    levels = [3, 3, 5, 5, 5, 8]
    hv = [sum(1 for lv in levels if lv <= kk) for kk in range(LEVELS + 1)]
    out("handmade.min_levels", levels)
    out("handmade.VertexId", compact(hv))
    for level in (4, 6):
        out(f"handmade.BitId(B={level})", compact(bit_id(hv, level)))
    jj = 3
    kk = vertex_id_bin(hv, jj)
    bb = max(kk, 6)
    out("handmade.vertex3(B=6)", f"bin {kk}, b = {bb}, o = 3*{bb}*({jj} - {hv[kk - 1]}) + BitId[{kk - 1}] = "
                                 f"{3 * bb * (jj - hv[kk - 1]) + bit_id(hv, 6)[kk - 1]}")
    out("handmade.plane_counts", ", ".join(f"p{p}: {hv[p - 1]}" for p in range(2, 10)))

    from lopcook.lop.binning import table_bit_id, table_vertex_id

    assert [int(v) for v in table_vertex_id(np.array(levels))] == hv
    for level in (4, 6):
        assert [int(v) for v in table_bit_id(np.array(hv), level)] == bit_id(hv, level)
    return 0


if __name__ == "__main__":
    sys.exit(main())
