"""A glTF 2.0 file whose geometry is a ``.lop`` container: the materials a web page needs beside the
container (``lopcook web CONTAINER.lop -o OUT.gltf``), for ``runtime/js/three-lop.js``.

The container holds no materials (docs/format.md 9.2). This writes them the way meshopt and Draco
compressed glTF files carry their geometry: an ordinary glTF document (nodes, meshes, the
source's materials, textures and images, as ``lopcook decode`` finds them:
``lopcook.emit.preview.source_materials``) whose primitives name the container's parts through
the extension ``LOPCOOK_lop_geometry``, so a web developer loads it with three's ``GLTFLoader``
plus the LOP plugin and gets the source's materials on geometry that streams and refines:

* document ``extensions.LOPCOOK_lop_geometry``: ``{"uri": relative URI of the container,
  "byteLength": its size, "version": [major, minor]}``;
* one mesh per part, one primitive each, ``extensions.LOPCOOK_lop_geometry = {"part": i}`` (a
  placement names its own part: its transform is applied when decoding, docs/format.md 6.8);
  ``attributes`` hold accessors without a ``bufferView`` (as KHR_draco_mesh_compression's):
  POSITION (LOD 0's vertex count, min/max of its decode at the file's highest level), NORMAL,
  TEXCOORD_0, COLOR_0 and TANGENT where the part has them, so a tool sees what the part holds;
* the extension is in ``extensionsUsed`` and ``extensionsRequired``: a loader without the
  plugin refuses the file instead of drawing zeros;
* one node per part under a node ``root`` (identity transforms); images embedded in the one
  buffer (``OUT.bin`` beside a ``.gltf``, the binary chunk of a ``.glb``).

Deterministic: the same container, source and output name give the same bytes.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from urllib.parse import quote

from ..errors import LopcookError
from ..lop.container import read
from ..lop.reader import decode_positions
from . import preview
from .gltf_writer import atomic_write_bytes, gltf_json_text, pack_glb

EXTENSION = "LOPCOOK_lop_geometry"
FLOAT = 5126


def _accessor(count: int, kind: str, minmax=None) -> dict:
    acc = {"componentType": FLOAT, "count": int(count), "type": kind}
    if minmax is not None:
        acc["min"], acc["max"] = [float(v) for v in minmax[0]], [float(v) for v in minmax[1]]
    return acc


def web_document(c, container_path: str, out_path: str, source: str | None = None) -> tuple[dict, bytes, list[str]]:
    """``(glTF JSON, binary buffer, warnings)`` for container ``c`` read from ``container_path``,
    written to ``out_path`` (the container's URI is relative to it)."""
    m = c.manifest
    parts = m["parts"]
    path, reason = preview.find_source(container_path, m, source)
    warnings = [] if reason is None else [f"{reason}; the web glTF has no materials"]
    mats, per_part = {}, [None] * len(parts)
    if path is not None:
        has = lambda key: [p["attribute_bits"].get(key) is not None for p in parts]  # noqa: E731
        mats, per_part, more = preview.source_materials(path, m["source"].get("format", ""), parts, has("uvs"),
                                                        has("colors"))
        warnings += more
    accessors, meshes, nodes = [], [], [{"name": "root", "children": list(range(1, len(parts) + 1))}]
    for i, part in enumerate(parts):
        lod0 = part["lods"][0]
        _, _, pos = decode_positions(c, i, 0, c.available_level)
        attributes = {"POSITION": len(accessors)}
        accessors.append(_accessor(lod0["vertices"], "VEC3", (pos.min(axis=0), pos.max(axis=0))))
        for key, name, kind in (("normals", "NORMAL", "VEC3"), ("uvs", "TEXCOORD_0", "VEC2"),
                                ("colors", "COLOR_0", "VEC4"), ("tangents", "TANGENT", "VEC4")):
            if part["attribute_bits"].get(key) is not None:
                attributes[name] = len(accessors)
                accessors.append(_accessor(lod0["vertices"], kind))
        prim = {"attributes": attributes, "mode": 4, "extensions": {EXTENSION: {"part": i}}}
        if per_part[i] is not None:
            prim["material"] = per_part[i]
        meshes.append({"name": part["name"], "primitives": [prim]})
        nodes.append({"name": part["name"], "mesh": i})
    uri = os.path.relpath(os.path.abspath(container_path), os.path.dirname(os.path.abspath(out_path)))
    doc = {"accessors": accessors, "asset": {"generator": m["generator"], "version": "2.0"},
           "extensions": {EXTENSION: {"uri": quote(Path(uri).as_posix()), "byteLength": len(c.data),
                                      "version": [int(c.data[4]) | int(c.data[5]) << 8,
                                                  int(c.data[6]) | int(c.data[7]) << 8]}},
           "extensionsRequired": [EXTENSION], "extensionsUsed": [EXTENSION], "meshes": meshes, "nodes": nodes,
           "scene": 0, "scenes": [{"nodes": [0]}]}
    blob = bytearray()
    if mats:
        views, images = [], []
        for img in mats["images"]:
            data = bytes(img["data"])
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
            blob += data + b"\0" * (-len(data) % 4)
            entry = {"bufferView": len(views) - 1, "mimeType": img["mimeType"]}
            if isinstance(img.get("name"), str):
                entry["name"] = img["name"]
            images.append(entry)
        for key, value in (("materials", mats["materials"]), ("textures", mats["textures"]),
                           ("samplers", mats["samplers"]), ("images", images), ("bufferViews", views)):
            if value:
                doc[key] = [dict(v) for v in value]
        if blob:
            doc["buffers"] = [{"byteLength": len(blob)}]
    return doc, bytes(blob), warnings


def write_web_gltf(container_path: str, out_path: str, source: str | None = None) -> dict:
    """Write ``out_path`` (``.gltf``, plus ``<stem>.bin`` when there are images, or ``.glb``)
    referencing ``container_path``; returns ``{"written": [paths], "parts", "materials",
    "warnings"}``. LopcookError for a bad container or output name; files are written atomically."""
    out = Path(out_path)
    if out.suffix.lower() not in (".gltf", ".glb"):
        raise LopcookError("usage", str(out), "the web glTF must end in .gltf or .glb")
    c = read(str(container_path))
    doc, blob, warnings = web_document(c, str(container_path), str(out), source)
    written = []
    if out.suffix.lower() == ".glb":
        atomic_write_bytes(out, pack_glb(json.dumps(doc, sort_keys=True, separators=(",", ":")).encode("ascii"), blob))
        written.append(os.fspath(out))
    else:
        if blob:
            bin_path = out.with_suffix(".bin")
            doc["buffers"][0]["uri"] = quote(bin_path.name)
            atomic_write_bytes(bin_path, blob)
            written.append(os.fspath(bin_path))
        atomic_write_bytes(out, gltf_json_text(doc, sort_keys=True).encode("ascii"))
        written.insert(0, os.fspath(out))
    n_mats = len(doc.get("materials", []))
    return {"written": written, "parts": len(doc["meshes"]), "materials": n_mats, "warnings": warnings}


__all__ = ["EXTENSION", "web_document", "write_web_gltf"]
