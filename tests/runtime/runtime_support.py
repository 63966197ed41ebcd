"""Containers and references for the runtime tests (tests/runtime/): the corpus cooked as the CLI
cooks it (and a few variants that reach every layout), a scene with vertex colours, tangent
containers (version 4.0, docs/format.md section 7.6) built from a cooked
container, and the Python reference digests the JavaScript reader must reproduce.

Tangent containers: ``with_tangents`` adds tangents to a cooked container's attribute records by
hand, independently of lopcook's writer, exactly as the format says (fields tangent.u,
tangent.v of b_t bits and tangent.sign of 1 bit after the colours; record_bits + 2 b_t + 1;
``attribute_bits.tangents`` in the part and each LOD; version 4.0), and returns the decoded
tangents the reader must give: the octahedral decode of the written codes
(``lopcook.lop.codecs.normals_oct.decode_normals``, the normals' decode with b_t) and w = -1 for sign 1.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np

from lopcook.lop.codecs import AttributeBits
from lopcook.lop.codecs.normals_oct import decode_normals, encode_normals
from lopcook.lop.record import record_fields, unpack_record
from lopcook.lop import reader
from lopcook.lop.container import from_bytes, to_bytes
from lopcook.errors import LopcookError

REPO = Path(__file__).resolve().parents[2]
#: every corpus asset, cooked with the CLI's defaults
CORPUS_ASSETS = ("stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
                 "CesiumMilkTruck.glb", "Duck.glb", "chess_set_flat.usdc", "UtahTeapot.usd")
#: variants that reach the other layouts: (asset, cook flags)
VARIANTS = {
    "bunny-unclustered": ("stanford-bunny.obj", ["--clusters", "0"]),  # version 2.0
    "duck-lods": ("Duck.glb", ["--lods", "1/2,1/4"]),  # a LOD chain
    "truck-all-clustered": ("CesiumMilkTruck.glb", ["--no-instances", "--cluster-all", "--clusters", "16"]),
    "spot-hierarchy": ("spot.obj", ["--hierarchy"]),  # a hierarchy section before the positions
}
#: the levels every decode is compared at
LEVELS = (6, 11, 16, 24)
IN_CI = os.environ.get("CI", "").lower() == "true"


def require(reason: str | None) -> None:
    """A missing tool (node, chromium, three): skip locally, fail under CI=true (as tests/conftest.py)."""
    import pytest

    if reason is not None:
        if IN_CI:
            pytest.fail(f"CI=true but {reason}")
        pytest.skip(reason)


def stem(asset: str) -> str:
    return Path(asset).stem


def cook(source: Path, out: Path, flags=()) -> Path:
    """``lopcook cook SOURCE -o OUT FLAGS -q`` in a subprocess (the CLI's bytes)."""
    subprocess.run([sys.executable, "-m", "lopcook", "cook", str(source), "-o", str(out), "-q", *flags],
                   check=True, timeout=600, env=dict(os.environ))
    return out


def cook_corpus(corpus: Path, cooks, out_dir: Path) -> dict[str, Path]:
    """``{name: container path}``: every corpus asset with the default cook, each variant (both
    from ``cooks``, the suite's cache: ``tests/support/cooks.py``), and the coloured scene
    (``colored_container``, written into ``out_dir``)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    jobs = {stem(a): (corpus / a, []) for a in CORPUS_ASSETS}
    jobs.update({name: (corpus / a, flags) for name, (a, flags) in VARIANTS.items()})
    out = dict(zip(jobs, cooks.cli_many(list(jobs.values()))))
    out["colored"] = colored_container(out_dir / "colored.lop")
    return out


def colored_container(path: Path) -> Path:
    """A two-part scene with vertex colours (one part also with UVs) cooked with the defaults: the
    corpus has no vertex colours."""
    from lopcook import api
    from lopcook.mesh import icosahedron
    from lopcook.types import MeshPart, Scene

    v, f = icosahedron()
    rng = np.random.default_rng(7)
    parts = []
    for k in range(2):
        pos = np.asarray(v, np.float64) * (0.5 + k) + np.array([2.0 * k, 0.0, 0.0])
        colors = rng.random((pos.shape[0], 4)).astype(np.float32)
        uvs = rng.random((pos.shape[0], 2)).astype(np.float32) if k else None
        normals = (pos - pos.mean(axis=0)).astype(np.float32)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        parts.append(MeshPart(f"ball{k}", pos, np.asarray(f, np.uint32), normals=normals, uvs=uvs, colors=colors))
    scene = Scene(parts=tuple(parts), source="colored.glb", format="glb")
    api.cook(scene).write(path)
    return path


# ---- tangents -------------------------------------------------------------------------------------

def _pack(fields: list[tuple[np.ndarray, int]], n: int) -> np.ndarray:
    """Records of ``n`` vertices, fields ``(values (n,), width)`` in order, vertex j at bit j S, LSB
    first (format.md 7.2): ``ceil(n S / 32)`` uint32 words."""
    s = sum(w for _, w in fields)
    bits = np.zeros(n * s, np.uint8)
    at = 0
    for values, width in fields:
        v = np.asarray(values, np.int64)
        assert v.min(initial=0) >= 0 and v.max(initial=0) < (1 << width)
        idx = np.arange(n, dtype=np.int64)[:, None] * s + at + np.arange(width)
        bits[idx.ravel()] = ((v[:, None] >> np.arange(width)) & 1).astype(np.uint8).ravel()
        at += width
    words = -(-n * s // 32)
    padded = np.zeros(32 * words, np.uint8)
    padded[:bits.size] = bits
    return np.packbits(padded, bitorder="little").view("<u4").astype(np.uint32)


def _tangent_codes(normals: np.ndarray | None, n: int, bits: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """(codes (n, 2), sign (n,)): unit vectors orthogonal to the normals (random directions without
    normals), encoded with the normals' octahedral encoder at ``bits``; random handedness."""
    if normals is None:
        d = rng.normal(size=(n, 3))
    else:
        nv = np.asarray(normals, np.float64)
        axis = np.where(np.abs(nv[:, 1:2]) > 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        d = np.cross(nv, axis)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return encode_normals(d, bits).astype(np.int64), rng.integers(0, 2, n)


def with_tangents(data: bytes, bits: int = 10, parts=None, major: int = 4, seed: int = 3) -> tuple[bytes, dict]:
    """``(bytes, expected)``: the container ``data`` with tangents added to the parts ``parts``
    (default every part whose buffers have an attribute record; a placement takes its owner's), as
    container version ``major``.0. ``expected[(part, lod)]`` is the (n, 4) float32 decode every
    reader must give (xyz unnormalised, w = +-1) for every part and LOD holding tangents."""
    c = from_bytes(data)
    m = copy.deepcopy(c.manifest)
    rng = np.random.default_rng(seed)
    owners = [reader.owner(c, i) for i in range(len(m["parts"]))]
    chosen = {i for i, p in enumerate(m["parts"]) if all(e.get("attributes") for e in p["lods"])}
    chosen = {owners[i] for i in (chosen if parts is None else set(parts) & chosen)}
    payloads = dict(c.sections)
    decoded = {}
    for i in sorted(chosen):
        for k, e in enumerate(m["parts"][i]["lods"]):
            n = e["vertices"]
            old = AttributeBits.of(e["attribute_bits"])
            codes = unpack_record(np.frombuffer(c.sections[e["attributes"]], "<u4"), n, old)
            normals = reader.lod_attributes(c, i, k)["normals"]
            tcodes, sign = _tangent_codes(normals, n, bits, rng)
            fields = [(codes[name][:, comp], w) for name, comp, _, w in record_fields(old)]
            fields += [(tcodes[:, 0], bits), (tcodes[:, 1], bits), (sign, 1)]
            payloads[e["attributes"]] = _pack(fields, n).tobytes()
            xyz = decode_normals(tcodes, bits)
            decoded[(i, k)] = np.concatenate([xyz, np.where(sign == 1, -1.0, 1.0).astype(np.float32)[:, None]], axis=1)
    for i, p in enumerate(m["parts"]):
        if owners[i] not in chosen:
            continue
        p["attribute_bits"]["tangents"] = bits
        for k, e in enumerate(p["lods"]):
            e["attribute_bits"]["tangents"] = bits
            e["record_bits"] += 2 * bits + 1
            decoded[(i, k)] = decoded[(owners[i], k)]
    if chosen:
        m["encodings"]["tangents"] = {"bits": [4, 16], "components": 3, "per": "vertex", "record": "attributes",
                                      "encoding": "octahedral, precise, as normals; then 1 sign bit (1: w = -1)"}
    m.pop("sections")
    blob = to_bytes(m, [(s["name"], payloads[s["name"]]) for s in c.manifest["sections"]])
    return set_version(blob, major, 0), decoded


def set_version(blob: bytes, major: int, minor: int) -> bytes:
    """``blob`` with its header's version replaced and the header CRC recomputed."""
    head = blob[:4] + struct.pack("<HH", major, minor) + blob[8:28]
    return head + struct.pack("<I", zlib.crc32(head)) + blob[32:]


def replace_manifest(blob: bytes, fn) -> bytes:
    """``blob`` with ``fn(manifest)`` applied (in place) and every checksum and size recomputed, the
    header's version kept: a lie that passes every CRC."""
    msize = struct.unpack_from("<I", blob, 12)[0]
    m = json.loads(blob[32:32 + msize])
    fn(m)
    mbytes = json.dumps(m, sort_keys=True, separators=(",", ":")).encode("ascii")
    payload = blob[32 + msize:]
    head = blob[:12] + struct.pack("<IIQ", len(mbytes), zlib.crc32(mbytes), 32 + len(mbytes) + len(payload))
    return head + struct.pack("<I", zlib.crc32(head)) + mbytes + payload


# ---- Python references ------------------------------------------------------------------------------

def sha(a) -> str | None:
    """SHA-256 (hex) of an array's little-endian bytes (float32 or uint32), None for None."""
    if a is None:
        return None
    a = np.asarray(a)
    a = a.astype("<f4") if a.dtype.kind == "f" else a.astype("<u4")
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def verdict(data: bytes, *, allow_prefix: bool = False, decode: bool = True) -> tuple[bool, int | None, str | None]:
    """``(accepted, available level, message)`` of the Python reader: ``from_bytes`` and, with
    ``decode``, every buffer's positions and attributes at its level (``Container.level_of``; a
    streaming prefix's buffers whose stage has not arrived are not decoded)."""
    try:
        c = from_bytes(data, "x.lop", allow_prefix=allow_prefix)
        if decode:
            for i, p in enumerate(c.manifest["parts"]):
                for k in range(len(p["lods"])):
                    if c.level_of(i, k):
                        reader.decode_positions(c, i, k, c.level_of(i, k))
                        reader.lod_attributes(c, i, k)
        return True, c.available_level, None
    except LopcookError as exc:
        return False, None, str(exc)


def reference(c, levels) -> list[dict]:
    """The digests ``tests/runtime/js_reader.mjs`` prints for container ``c`` (``decodeAll``), from
    lopcook's reader: per buffer its indices and attributes, per level its float32 positions, grid
    integers, packed P and (clustered) clustered P and records."""
    out = []
    for i, p in enumerate(c.manifest["parts"]):
        for k in range(len(p["lods"])):
            if not c.level_of(i, k):
                continue  # a streaming prefix: the buffer's stage has not arrived
            a = reader.lod_attributes(c, i, k)
            rec = {"part": i, "lod": k, "indices": sha(a["indices"]), "normals": sha(a["normals"]),
                   "uvs": sha(a["uvs"]), "colors": sha(a["colors"]), "tangents": None, "levels": {}}
            for b in [b for b in levels if b <= c.level_of(i, k)]:
                grid, _, pos = reader.decode_positions(c, i, k, b)
                r = {"positions": sha(pos), "grid": sha(grid)}
                if reader.owner(c, i) == i:
                    r["words"] = sha(reader.gpu_buffer(c, i, k, b).words)
                    if reader.buffer_clusters(c, i, k) is not None:
                        g = reader.clustered_gpu_buffer(c, i, k, b)
                        r["cwords"], r["records"] = sha(g.words), sha(g.records)
                rec["levels"][str(b)] = r
            out.append(rec)
    return out
