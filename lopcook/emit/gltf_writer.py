"""Deterministic glTF 2.0 writer for lopcook outputs (``.glb``, or ``.gltf`` + one ``.bin``).

``write_gltf(path, meshes)`` writes decoded meshes (world space, metres, +Y up, counter-clockwise
triangles, glTF UVs, linear RGBA colours; see ``lopcook.types``) as one glTF 2.0 asset that the
Khronos glTF-Validator accepts with 0 errors and 0 warnings (checked by
``tests/emit/test_gltf_writer.py`` with ``tools/gltf_validate.mjs``):
``write_gltf("preview.glb", [{"name": "body", "positions": p, "indices": t, "normals": n}])``.

Layout (glTF 2.0 specification, https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html)
--------------------------------------------------------------------------------------
* ``scene`` 0 holds one root node ``"root"`` (no transform, no mesh) whose ``children`` are one
  node per input mesh, in input order (node k + 1 shows mesh k; node and mesh carry the input
  ``name``), or the given ``nodes`` (instancing: several nodes sharing a mesh, each with its
  TRS). Each mesh has exactly one TRIANGLES primitive, with the given ``material`` or none
  (default material); materials, textures, samplers and images are written as given, images
  embedded as bufferViews (no ``target``) after the geometry's.
* One buffer; one bufferView per accessor, each starting at a 4-byte aligned offset and tightly
  packed (``byteStride`` omitted), ``target`` 34962 (ARRAY_BUFFER) for vertex attributes and
  34963 (ELEMENT_ARRAY_BUFFER) for indices.
* Accessors: POSITION float32 VEC3 with ``min``/``max`` equal to the componentwise extremes of
  the float32 values written (exactly: JSON numbers are Python ``repr`` of those float32 values,
  which parse back to the same double), NORMAL float32 VEC3, TEXCOORD_0 float32 VEC2, COLOR_0
  float32 VEC4, TANGENT float32 VEC4; indices UNSIGNED_SHORT (5123) when every index < 65535 (65535 is the primitive
  restart value the specification forbids) else UNSIGNED_INT (5125).
* ``asset``: ``version`` "2.0", ``generator`` (default "lopcook"), optional ``extras`` (any
  JSON value; NaN/Infinity are rejected because JSON has no such numbers).
* ``.gltf``: the JSON (sorted keys, one-space indent, numeric arrays on one line, LF, trailing
  newline) references ``<stem>.bin`` by its bare (percent-encoded) file name, never a directory
  or absolute path. ``.glb``: 12-byte header, a JSON chunk (compact, sorted keys, space padded)
  and a BIN chunk (zero padded), no ``uri``.

Determinism: the bytes depend only on the arguments (no timestamps, no paths, sorted keys, fixed
float formatting), so writing the same meshes twice gives identical files.

Atomicity: everything is checked and built in memory first, then written to a temporary file and
moved into place (``.bin`` before ``.gltf``); an invalid mesh (wrong shape, NaN/Inf, index out of
range, non-unit normal) raises ``ValueError`` and leaves no file. ``BufferBuilder``, ``pack_glb``,
``gltf_json_text`` and ``atomic_write_bytes`` also write the hand-made test fixtures.
"""

from __future__ import annotations

import json
import os
import re
import struct
from collections.abc import Mapping
from pathlib import Path
from urllib.parse import quote

import numpy as np

from ..atomic import write_atomic

# glTF 2.0 constants
FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
TRIANGLES = 4
GLB_MAGIC, GLB_VERSION = b"glTF", 2
GLB_JSON, GLB_BIN = b"JSON", b"BIN\0"

#: Largest index an UNSIGNED_SHORT index accessor may hold (65535 is the primitive restart value).
MAX_USHORT_INDEX = 65534
#: Allowed | |normal| - 1 |: the tolerance of ``MeshPart.validate``. glTF-Validator 2.0.0-dev.3.10
#: reports the error ACCESSOR_VECTOR3_NON_UNIT from somewhere between 0.005 and 0.01 (measured).
NORMAL_TOLERANCE = 1e-3

#: Image types the writer embeds (the two glTF 2.0 core allows).
IMAGE_MIME = ("image/jpeg", "image/png")

_NUMBER_ARRAY = re.compile(r"\[\s+([-+0-9.eE,\s]+?)\s+\]")  # JSON arrays of numbers -> one line


# ---------------------------------------------------------------------------------------------
# Shared low-level pieces
# ---------------------------------------------------------------------------------------------


class BufferBuilder:
    """One glTF buffer built from arrays: one bufferView + one accessor per ``add``.

    Views start at 4-byte aligned offsets (zero padding between them), are tightly packed (no
    ``byteStride``) and carry a ``target``. The dicts keep a fixed key order (``bufferView``,
    ``componentType``, ``count``, ``type``, ``min``, ``max`` / ``buffer``, ``byteOffset``,
    ``byteLength``, ``target``) so writers that do not sort keys stay deterministic too.
    """

    def __init__(self) -> None:
        self.blob = bytearray()
        self.accessors: list[dict] = []
        self.views: list[dict] = []

    def add(self, array: np.ndarray, kind: str, component: int, target: int, minmax: bool = False) -> int:
        """Append ``array`` (already in its little-endian file dtype, first axis = count).

        ``minmax`` adds ``min``/``max`` (per component, the written values as Python floats or
        ints). Returns the accessor index.
        """
        data = np.ascontiguousarray(array).tobytes()
        self.views.append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data), "target": target})
        self.blob.extend(data)
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        acc = {"bufferView": len(self.views) - 1, "componentType": component,
               "count": int(array.shape[0]), "type": kind}
        if minmax:
            acc["min"] = [float(x) for x in array.min(axis=0)]
            acc["max"] = [float(x) for x in array.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def gltf_json_text(doc: dict, *, sort_keys: bool) -> str:
    """``.gltf`` JSON text: one-space indent, arrays of numbers on one line, trailing newline."""
    text = json.dumps(doc, indent=1, sort_keys=sort_keys, allow_nan=False)
    return _NUMBER_ARRAY.sub(lambda m: "[" + " ".join(m.group(1).split()) + "]", text) + "\n"


def pack_glb(json_bytes: bytes, blob: bytes) -> bytes:
    """GLB container: header, JSON chunk (padded with spaces), BIN chunk (padded with zeros).

    ``blob`` may be empty, in which case no BIN chunk is written.
    """
    js = json_bytes + b" " * (-len(json_bytes) % 4)
    body = struct.pack("<I4s", len(js), GLB_JSON) + js
    if blob:
        blob = bytes(blob) + b"\0" * (-len(blob) % 4)
        body += struct.pack("<I4s", len(blob), GLB_BIN) + blob
    return struct.pack("<4sII", GLB_MAGIC, GLB_VERSION, 12 + len(body)) + body


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` atomically (``lopcook.atomic.write_atomic``); returns ``Path(path)``."""
    return write_atomic(path, data)


# ---------------------------------------------------------------------------------------------
# Input checking
# ---------------------------------------------------------------------------------------------


def _field(mesh, key: str):
    if isinstance(mesh, Mapping):
        return mesh.get(key)
    return getattr(mesh, key, None)


def _float_array(mesh_label: str, key: str, value, n: int | None, width: int) -> np.ndarray:
    """``value`` as a C-contiguous little-endian float32 (n, width) array, finite."""
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise ValueError(f"{mesh_label}: {key} is not an array: {exc}") from None
    shape_ok = arr.ndim == 2 and arr.shape[1] == width and (n is None or arr.shape[0] == n)
    if arr.dtype.kind not in "fiu" or not shape_ok:
        want = f"({'n' if n is None else n}, {width})"
        raise ValueError(f"{mesh_label}: {key} must be a {want} float array, got {arr.dtype} {arr.shape}")
    with np.errstate(over="ignore", invalid="ignore"):
        out = np.ascontiguousarray(arr, dtype="<f4")
    if not np.isfinite(out).all():
        bad = int((~np.isfinite(out)).any(axis=1).sum())
        raise ValueError(f"{mesh_label}: {key} has {bad} rows with NaN or Inf (after conversion to float32)")
    return out


def _prepare(index: int, mesh) -> dict:
    """Check one input mesh; return its name and file-ready arrays."""
    name = _field(mesh, "name")
    label = f"mesh {index}" + (f" {name!r}" if isinstance(name, str) else "")
    if not isinstance(name, str):
        raise ValueError(f"{label}: name must be a str, got {type(name).__name__}")
    if _field(mesh, "positions") is None or _field(mesh, "indices") is None:
        raise ValueError(f"{label}: positions and indices are required")
    positions = _float_array(label, "positions", _field(mesh, "positions"), None, 3)
    n = positions.shape[0]
    if n == 0:
        raise ValueError(f"{label}: has no vertices (glTF accessors need count >= 1)")
    tri = np.asarray(_field(mesh, "indices"))
    if tri.dtype.kind not in "iu" or tri.ndim != 2 or tri.shape[1] != 3:
        raise ValueError(f"{label}: indices must be an (m, 3) integer array, got {tri.dtype} {tri.shape}")
    if tri.shape[0] == 0:
        raise ValueError(f"{label}: has no triangles (glTF accessors need count >= 1)")
    lo, hi = int(tri.min()), int(tri.max())
    if lo < 0 or hi >= n:
        raise ValueError(f"{label}: index {lo if lo < 0 else hi} out of range for {n} vertices")
    index_dtype, component = ("<u2", UNSIGNED_SHORT) if hi <= MAX_USHORT_INDEX else ("<u4", UNSIGNED_INT)
    out = {"name": name, "positions": positions,
           "indices": np.ascontiguousarray(tri.reshape(-1), dtype=index_dtype), "component": component}
    for key, width in (("normals", 3), ("uvs", 2), ("colors", 4)):
        value = _field(mesh, key)
        out[key] = None if value is None else _float_array(label, key, value, n, width)
    if out["normals"] is not None:
        dev = np.abs(np.linalg.norm(out["normals"].astype(np.float64), axis=1) - 1.0)
        if dev.max() > NORMAL_TOLERANCE:
            raise ValueError(f"{label}: normals must be unit length (max | |n| - 1 | = {dev.max():.3g}, "
                             f"allowed {NORMAL_TOLERANCE:g}); normalise them first")
    value = _field(mesh, "tangents")
    out["tangents"] = None if value is None else _float_array(label, "tangents", value, n, 4)
    if out["tangents"] is not None:
        t = out["tangents"]
        dev = np.abs(np.linalg.norm(t[:, :3].astype(np.float64), axis=1) - 1.0)
        if dev.max() > NORMAL_TOLERANCE or not np.isin(t[:, 3], (-1.0, 1.0)).all():
            raise ValueError(f"{label}: tangents must be unit xyz with w = +1 or -1")
        if out["normals"] is None:
            raise ValueError(f"{label}: tangents need normals")
    if out["colors"] is not None and (out["colors"].min() < 0.0 or out["colors"].max() > 1.0):
        raise ValueError(f"{label}: colors must be linear RGBA in [0, 1] "
                         f"(got [{out['colors'].min():.6g}, {out['colors'].max():.6g}])")
    return out


# ---------------------------------------------------------------------------------------------
# Writer
# ---------------------------------------------------------------------------------------------


def _check_materials(materials) -> dict:
    """``materials`` (see ``write_gltf``) checked: lists of the right types, indices in range."""
    if not isinstance(materials, Mapping):
        raise ValueError(f"materials must be a mapping, got {type(materials).__name__}")
    out = {k: list(materials.get(k) or []) for k in ("materials", "textures", "samplers", "images")}
    for i, img in enumerate(out["images"]):
        if not isinstance(img, Mapping) or not isinstance(img.get("data"), (bytes, bytearray)) or not img["data"]:
            raise ValueError(f"image {i}: needs non-empty bytes 'data'")
        if img.get("mimeType") not in IMAGE_MIME:
            raise ValueError(f"image {i}: mimeType must be one of {sorted(IMAGE_MIME)}, got {img.get('mimeType')!r}")
    for i, tex in enumerate(out["textures"]):
        if not isinstance(tex, Mapping) or not 0 <= _int(tex.get("source")) < len(out["images"]):
            raise ValueError(f"texture {i}: source must index images (0..{len(out['images']) - 1})")
        if "sampler" in tex and not 0 <= _int(tex["sampler"]) < len(out["samplers"]):
            raise ValueError(f"texture {i}: sampler {tex['sampler']!r} out of range")
    for i, mat in enumerate(out["materials"]):
        if not isinstance(mat, Mapping):
            raise ValueError(f"material {i} must be a mapping")
        for ref in _texture_refs(mat):
            if not 0 <= _int(ref.get("index")) < len(out["textures"]):
                raise ValueError(f"material {i}: texture index {ref.get('index')!r} out of range")
    return out


def _int(v) -> int:
    return v if isinstance(v, int) and not isinstance(v, bool) else -1


def _texture_refs(mat: Mapping) -> list:
    """The textureInfo objects of a core glTF material."""
    pbr = mat.get("pbrMetallicRoughness") or {}
    refs = [pbr.get("baseColorTexture"), pbr.get("metallicRoughnessTexture"), mat.get("normalTexture"),
            mat.get("occlusionTexture"), mat.get("emissiveTexture")]
    return [r for r in refs if r is not None]


def _check_nodes(nodes, n_meshes: int) -> list[dict]:
    """``nodes`` (see ``write_gltf``) checked: a mesh index each, finite TRS of the right sizes."""
    out = []
    for i, node in enumerate(nodes):
        if not isinstance(node, Mapping) or not isinstance(node.get("name"), str):
            raise ValueError(f"node {i}: needs a str 'name'")
        if not 0 <= _int(node.get("mesh")) < n_meshes:
            raise ValueError(f"node {i} {node['name']!r}: mesh must index meshes (0..{n_meshes - 1})")
        entry = {"mesh": node["mesh"], "name": node["name"]}
        for key, size in (("translation", 3), ("rotation", 4), ("scale", 3)):
            if node.get(key) is None:
                continue
            v = np.asarray(node[key], dtype=np.float64)
            if v.shape != (size,) or not np.isfinite(v).all():
                raise ValueError(f"node {i} {node['name']!r}: {key} must be {size} finite numbers")
            if key == "rotation" and abs(float(np.linalg.norm(v)) - 1.0) > 1e-6:
                raise ValueError(f"node {i} {node['name']!r}: rotation must be a unit quaternion")
            if key == "scale" and (v == 0).any():
                raise ValueError(f"node {i} {node['name']!r}: scale must be non-zero")
            entry[key] = [float(x) for x in v]
        out.append(entry)
    used = {n["mesh"] for n in out}
    if len(used) != n_meshes:
        raise ValueError(f"meshes {sorted(set(range(n_meshes)) - used)} are placed by no node")
    return out


def build_gltf(meshes, *, generator: str = "lopcook", extras=None, materials=None, nodes=None) -> tuple[dict, bytes]:
    """The glTF JSON dict (without ``buffers[0].uri``) and the binary buffer for ``meshes``.

    Raises ValueError for invalid input (see ``write_gltf``).
    """
    if not isinstance(generator, str):
        raise ValueError(f"generator must be a str, got {type(generator).__name__}")
    prepared = [_prepare(i, m) for i, m in enumerate(meshes)]
    if not prepared:
        raise ValueError("no meshes to write")
    mats = _check_materials(materials) if materials is not None else None
    for i, m in enumerate(meshes):
        mi = _field(m, "material")
        if mi is None:
            continue
        if mats is None or not 0 <= _int(mi) < len(mats["materials"]):
            raise ValueError(f"mesh {i} {prepared[i]['name']!r}: material {mi!r} does not index materials")
        if _texture_refs(mats["materials"][mi]) and prepared[i]["uvs"] is None:
            raise ValueError(f"mesh {i} {prepared[i]['name']!r}: material {mi} has textures but the mesh no UVs")
        prepared[i]["material"] = mi
    placed = _check_nodes(nodes, len(prepared)) if nodes is not None else None
    buf = BufferBuilder()
    gl_meshes = []
    for m in prepared:
        attributes = {"POSITION": buf.add(m["positions"], "VEC3", FLOAT, ARRAY_BUFFER, minmax=True)}
        if m["normals"] is not None:
            attributes["NORMAL"] = buf.add(m["normals"], "VEC3", FLOAT, ARRAY_BUFFER)
        if m["tangents"] is not None:
            attributes["TANGENT"] = buf.add(m["tangents"], "VEC4", FLOAT, ARRAY_BUFFER)
        if m["uvs"] is not None:
            attributes["TEXCOORD_0"] = buf.add(m["uvs"], "VEC2", FLOAT, ARRAY_BUFFER)
        if m["colors"] is not None:
            attributes["COLOR_0"] = buf.add(m["colors"], "VEC4", FLOAT, ARRAY_BUFFER)
        ind = buf.add(m["indices"], "SCALAR", m["component"], ELEMENT_ARRAY_BUFFER)
        prim = {"attributes": attributes, "indices": ind, "mode": TRIANGLES}
        if "material" in m:
            prim["material"] = m["material"]
        gl_meshes.append({"name": m["name"], "primitives": [prim]})
    asset = {"generator": generator, "version": "2.0"}
    if extras is not None:
        asset["extras"] = extras
    if placed is None:
        placed = [{"mesh": k, "name": m["name"]} for k, m in enumerate(prepared)]
    nodes_out = [{"children": list(range(1, len(placed) + 1)), "name": "root"}] + placed
    doc = {
        "accessors": buf.accessors,
        "asset": asset,
        "bufferViews": buf.views,
        "buffers": [],
        "meshes": gl_meshes,
        "nodes": nodes_out,
        "scene": 0,
        "scenes": [{"nodes": [0]}],
    }
    if mats is not None:
        images = []
        for img in mats["images"]:  # image bytes: bufferViews without a target, after the geometry
            data = bytes(img["data"])
            buf.views.append({"buffer": 0, "byteOffset": len(buf.blob), "byteLength": len(data)})
            buf.blob.extend(data)
            buf.blob.extend(b"\0" * (-len(buf.blob) % 4))
            entry = {"bufferView": len(buf.views) - 1, "mimeType": img["mimeType"]}
            if isinstance(img.get("name"), str):
                entry["name"] = img["name"]
            images.append(entry)
        for key, value in (("materials", mats["materials"]), ("textures", mats["textures"]),
                           ("samplers", mats["samplers"]), ("images", images)):
            if value:
                doc[key] = [dict(v) for v in value]
    doc["buffers"] = [{"byteLength": len(buf.blob)}]
    return doc, bytes(buf.blob)


def write_gltf(path, meshes, *, generator: str = "lopcook", extras=None, materials=None, nodes=None) -> list[str]:
    """Write ``meshes`` as a glTF 2.0 asset: ``.glb`` if ``path`` ends in ``.glb`` (any case),
    otherwise ``path`` (JSON) plus ``<stem>.bin`` beside it.

    Parameters
    ----------
    path : str or os.PathLike
        Destination; its directory must exist. Existing files are replaced atomically.
    meshes : sequence of objects or dicts
        Each with ``name`` (str), ``positions`` (n, 3) float (written as float32; world space,
        metres, +Y up), ``indices`` (m, 3) integers in [0, n) (counter-clockwise triangles), and
        optionally ``normals`` (n, 3) unit float32, ``uvs`` (n, 2) float32 (glTF convention,
        origin top-left) and ``colors`` (n, 4) float32 linear RGBA in [0, 1]; missing attributes
        may be absent or None. ``lopcook.types.MeshPart`` objects qualify. Optional ``tangents``
        (n, 4) float32 (unit xyz, w = +-1 the bitangent's sign; needs normals). An optional
        ``material`` (int) indexes ``materials["materials"]``; a textured material needs ``uvs``.
    generator : str
        ``asset.generator``.
    extras : JSON-able or None
        Stored as ``asset.extras`` when not None.
    materials : mapping or None
        ``{"materials": [...], "textures": [...], "samplers": [...], "images": [...]}``: glTF 2.0
        core material, texture and sampler objects (written as given, texture references index
        ``textures``, ``textures[i]["source"]`` indexes ``images``), and images as
        ``{"name", "mimeType" ("image/png" | "image/jpeg"), "data" (bytes)}``, embedded as
        bufferViews of the one buffer (also for ``.gltf``: one ``.bin`` holds everything).
    nodes : sequence of mappings or None
        The root's children: ``{"name", "mesh" (int), "translation"?, "rotation"? (unit xyzw
        quaternion), "scale"?}``; several nodes may share one mesh (instancing). Every mesh must
        be placed by a node. None: one untransformed node per mesh, in order.

    Returns
    -------
    list[str]
        The paths written, ``[glb]`` or ``[gltf, bin]`` (as ``os.fspath`` of ``path`` and its sibling).

    Raises
    ------
    ValueError
        Empty ``meshes``; a mesh without vertices or triangles; wrong shapes or dtypes;
        NaN/Inf values (also after float32 conversion); indices out of range; normals that are
        not unit length (within ``NORMAL_TOLERANCE``); colours outside [0, 1]; ``extras`` that
        is not JSON-able; materials, textures or nodes whose indices are out of range, a textured
        material on a mesh without UVs, a mesh no node places. Nothing is written then.
    OSError
        From the file system; no temporary file is left behind.
    """
    path = Path(path)
    doc, blob = build_gltf(meshes, generator=generator, extras=extras, materials=materials, nodes=nodes)
    try:
        if path.suffix.lower() == ".glb":
            data = pack_glb(json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
                            .encode("ascii"), blob)
        else:
            bin_path = path.with_suffix(".bin")
            if bin_path == path:
                raise ValueError(f"{path}: a .gltf destination must not end in .bin")
            doc["buffers"][0]["uri"] = quote(bin_path.name)
            text = gltf_json_text(doc, sort_keys=True).encode("ascii")
    except TypeError as exc:  # extras not JSON-able
        raise ValueError(f"extras are not JSON-able: {exc}") from None
    if path.suffix.lower() == ".glb":
        atomic_write_bytes(path, data)
        return [os.fspath(path)]
    atomic_write_bytes(bin_path, blob)
    atomic_write_bytes(path, text)
    return [os.fspath(path), os.fspath(bin_path)]


__all__ = ["write_gltf", "build_gltf", "BufferBuilder", "pack_glb", "gltf_json_text", "atomic_write_bytes"]
