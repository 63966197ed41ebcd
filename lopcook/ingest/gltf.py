"""glTF 2.0 (``.gltf`` JSON, ``.glb`` binary) -> ``Scene``; the glTF ``FORMAT`` of the registry.

Specification: https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html (section numbers below).
The reader is our own (``json``/``struct``/numpy; why not trimesh, and what each section means
in detail: docs/ingest.md, "glTF").

``load(path, fmt="gltf"|"glb", settings) -> Scene`` (not yet validated):

* one ``MeshPart`` per (node, triangle primitive) of the default scene (else scene 0, else every
  root node); world = parent @ local, local = ``matrix`` or T * R * S (3.5.2). Modes 4-6 become
  triangles (3.7.2.1), points and lines are skipped with a warning; vertices are never merged
  (vertex count = accessor count). ``mesh_key`` is ``mesh{mi}/prim{k}``.
* attributes: POSITION, NORMAL, TANGENT (by the node's matrix, w flipped where it mirrors),
  TEXCOORD_n (n = the base-colour texture's ``texCoord``), COLOR_0 (linear RGBA), in every
  component type of core glTF and KHR_mesh_quantization, normalized or not (3.11 decoding),
  strided, sparse or without a bufferView (zeros).
* ``EXT_mesh_gpu_instancing``: one part per instance and primitive (``.../instance<i>``), at the
  node's world matrix @ TRANSLATION @ ROTATION @ SCALE; copies share ``mesh_key``.
* the base-colour image (bufferView, data URI or relative file) is the part's ``texture``,
  decoded once (``build.checked_texture``; an unreadable one is a warning).
* units: metres, +Y up (3.4): ``unit_scale`` 1.0. Positions in float64; normals by the inverse
  transpose; a mirroring matrix (det < 0) flips the winding. Skins and morph targets are not
  applied (a warning).
* ``Scene.dependencies``: the source, then every external buffer and used base-colour image (a
  missing one too), in first-use order; remote URLs are refused.

Refused, each as one ``LopcookError("ingest", path, ...)`` naming the object read: malformed
JSON, GLB header or chunks; integers that are not JSON integers in range (``byteLength`` >= 1,
``byteStride`` a multiple of 4 in [4, 252], ...); accessor bytes beyond their view (checked before
allocating; a data-less accessor may declare at most as many elements as the file has bytes,
``ZERO_ACCESSOR_MIN`` at least); required extensions other than ``SUPPORTED_REQUIRED``, and
Draco or meshopt data even when only used; absolute or non-regular-file URIs of buffers; more
than ``build.MAX_PARTS`` placements or ``settings.max_triangles`` triangles (counted before
decoding). Identical primitives are decoded once.

``materials(path, parts, out)`` reads each part's material again for ``lopcook decode``
(docs/format.md 9.2); ``sniff(head)`` tells GLB from JSON.
"""

from __future__ import annotations

import base64
import binascii
import json
import os
import re
import struct
import urllib.parse
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..depfile import DependencyList
from ..errors import LopcookError
from ..settings import IngestSettings
from ..types import MeshPart, Scene, Texture
from .build import (MAX_PARTS, bad_path_characters, checked_texture, make_part, placed_tangents,
                    regular_file_problem, unique_names, usable_tangents)
from .format import Format
from .materials import MaterialSet

GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942

#: componentType -> little-endian numpy dtype (glTF 2.0 3.6.2.2)
COMPONENT_DTYPES = {
    5120: np.dtype("<i1"),
    5121: np.dtype("<u1"),
    5122: np.dtype("<i2"),
    5123: np.dtype("<u2"),
    5125: np.dtype("<u4"),
    5126: np.dtype("<f4"),
}
COMPONENT_NAMES = {5120: "BYTE", 5121: "UNSIGNED_BYTE", 5122: "SHORT", 5123: "UNSIGNED_SHORT",
                   5125: "UNSIGNED_INT", 5126: "FLOAT"}
TYPE_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
MODE_NAMES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP", 4: "TRIANGLES",
              5: "TRIANGLE_STRIP", 6: "TRIANGLE_FAN"}

#: extensions that may appear in extensionsRequired and are handled (or harmless) here
SUPPORTED_REQUIRED = frozenset({"KHR_mesh_quantization", "EXT_mesh_gpu_instancing"})
SUPPORTED_REQUIRED_PREFIXES = ("KHR_materials_",)

#: accepted componentTypes per attribute (core glTF + KHR_mesh_quantization); UNSIGNED_INT never
ATTR_COMPONENTS = {
    "POSITION": (5126, 5120, 5121, 5122, 5123),
    "NORMAL": (5126, 5120, 5122),
    "TANGENT": (5126, 5120, 5122),
    "TEXCOORD": (5126, 5120, 5121, 5122, 5123),
    "COLOR": (5126, 5121, 5123),
    # EXT_mesh_gpu_instancing: float, or KHR_mesh_quantization's types (ROTATION normalized)
    "TRANSLATION": (5126, 5120, 5121, 5122, 5123),
    "ROTATION": (5126, 5120, 5122),
    "SCALE": (5126, 5120, 5121, 5122, 5123),
}

#: the node extension whose per-instance TRANSLATION / ROTATION / SCALE place a mesh many times
GPU_INSTANCING = "EXT_mesh_gpu_instancing"

#: an accessor without a bufferView (all zeros) may declare at most this many elements, or as many
#: as the file and its external buffers have bytes, whichever is larger
ZERO_ACCESSOR_MIN = 1 << 16

DECOMPRESS_HINT = ("decompress the file first (e.g. with gltf-transform, or re-export without "
                   "Draco/meshopt compression)")


class _Malformed(Exception):
    """Internal: a structural problem found while parsing (turned into LopcookError)."""

    def __init__(self, message: str, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint


def load(path: str, *, fmt: str, settings: IngestSettings) -> Scene:
    """Read a glTF 2.0 ``.gltf`` or ``.glb`` file into an unvalidated ``Scene``.

    Parameters
    ----------
    path : str
        The file as the user gave it (external buffers and images resolve relative to it).
    fmt : str
        ``"gltf"`` (JSON) or ``"glb"`` (binary container), decided from content by the caller.
    settings : IngestSettings
        Only ``crease_angle_deg`` matters (used when a primitive has no NORMAL).

    Returns
    -------
    Scene with one part per (node, triangle primitive) of the default scene, positions (n, 3)
    float64 in world metres, +Y up; ``unit_scale`` 1.0, ``up_axis`` "Y". ``parts`` is empty when
    the scene has no triangle primitives (``Scene.validate`` then reports it).

    Raises
    ------
    LopcookError
        ("ingest", path, ...) for malformed files, unsupported required extensions, missing or
        truncated buffers, out-of-range indices, bad index counts and non-finite positions.
    """
    reader = _GltfReader(path, fmt, settings)
    try:
        return reader.read()
    except LopcookError:
        raise
    except _Malformed as exc:
        raise LopcookError("ingest", path, exc.message, hint=exc.hint) from None
    except (KeyError, IndexError, ValueError, TypeError, AttributeError, OverflowError,
            struct.error, binascii.Error, UnicodeDecodeError, RecursionError) as exc:
        where = reader.where or "file"
        if isinstance(exc, KeyError) and exc.args:
            message = f"malformed glTF: {where} lacks the required property {exc.args[0]!r}"
        elif isinstance(exc, RecursionError):
            message = f"malformed glTF: {where} is nested too deeply"
        elif isinstance(exc, (TypeError, AttributeError)):
            message = f"malformed glTF: a property of {where} has the wrong JSON type"
        elif isinstance(exc, IndexError):
            message = f"malformed glTF: {where} refers to an element that does not exist"
        else:
            detail = " ".join(str(exc).split())[:160] or "malformed value"
            message = f"malformed glTF in {where} ({detail})"
        raise LopcookError("ingest", path, message,
                           hint="the file does not follow the glTF 2.0 specification; "
                                "check it with the Khronos glTF validator") from None
    except OSError as exc:
        raise LopcookError("ingest", path, f"cannot read file: {exc.strerror or exc}",
                           hint="check the path and permissions") from None


class _GltfReader:
    """Stateful parser for one file: JSON, buffers, accessors and texture caches."""

    def __init__(self, path: str, fmt: str, settings: IngestSettings) -> None:
        self.path = path
        self.fmt = fmt
        self.settings = settings
        self.base_dir = os.path.dirname(os.path.abspath(path))
        self.where = ""  # what is being read, for messages about malformed data
        self.warnings: list[str] = []
        self.deps = DependencyList(path)  # files opened or looked for, in first-use order
        self.gltf: dict = {}
        self.bin_chunk: bytes | None = None
        self._buffers: dict[int, bytes] = {}
        self._views: dict[int, memoryview] = {}
        self._accessors: dict[int, tuple[np.ndarray, bool, int]] = {}
        self._textures: dict[int, Texture | None] = {}
        self._geometry: dict = {}  # primitive JSON -> decoded local geometry

    # ------------------------------------------------------------------ helpers

    def warn(self, message: str) -> None:
        if message not in self.warnings:
            self.warnings.append(message)

    def uint(self, obj: dict, key: str, default: int | None = None, minimum: int = 0) -> int:
        """``obj[key]`` as a JSON integer >= ``minimum`` (``default`` when absent and not None)."""
        if key not in obj and default is not None:
            return default
        val = obj[key]
        if isinstance(val, bool) or not isinstance(val, int) or val < minimum:
            raise _Malformed(f"{self.where or 'file'}: {key} {val!r} is not an integer >= {minimum}",
                             "the file is corrupt or was written by a broken exporter")
        return val

    def item(self, collection: str, index, what: str | None = None) -> dict:
        """``gltf[collection][index]`` with a clear error for a bad reference."""
        items = self.gltf.get(collection)
        what = what or collection.rstrip("s")
        if not isinstance(items, list) or isinstance(index, bool) or not isinstance(index, int) \
                or not 0 <= index < len(items):
            n = len(items) if isinstance(items, list) else 0
            raise _Malformed(f"{self.where or 'file'} refers to {what} {index!r}, but the file has "
                             f"{n} {collection}", "the file is corrupt or was written by a broken exporter")
        obj = items[index]
        if not isinstance(obj, dict):
            raise _Malformed(f"{what} {index} is not a JSON object")
        return obj

    # ------------------------------------------------------------------ container

    def read(self) -> Scene:
        with open(self.path, "rb") as fh:
            data = fh.read()
        self.data_bytes = len(data)
        json_bytes = self._split_glb(data) if self.fmt == "glb" else data
        self._parse_json(json_bytes)
        self._check_extensions()
        parts = self._walk_scene()
        names = unique_names([p.name for p in parts])
        parts = [p if p.name == n else _rename(p, n) for p, n in zip(parts, names)]
        return Scene(parts=tuple(parts), source=self.path, format=self.fmt, unit_scale=1.0,
                     up_axis="Y", warnings=tuple(self.warnings), dependencies=self.deps.paths())

    def _split_glb(self, data: bytes) -> bytes:
        """GLB (spec 4.4): return the JSON chunk, keep the BIN chunk in ``self.bin_chunk``."""
        self.where = "GLB header"
        if len(data) < 12:
            raise _Malformed(f"GLB header truncated: the file has {len(data)} bytes, the header needs 12",
                             "the file is truncated; re-export or re-download it")
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        if magic != GLB_MAGIC:
            raise _Malformed(f"bad GLB magic {magic!r}, expected b'glTF'", "the file is not a GLB")
        if version != 2:
            raise _Malformed(f"GLB version {version} is not supported, only glTF 2.0",
                             "convert the file to glTF 2.0 (e.g. with gltf-pipeline)")
        if length > len(data):
            raise _Malformed(f"GLB header declares {length} bytes but the file has {len(data)}",
                             "the file is truncated; re-export or re-download it")
        if length < 20:
            raise _Malformed(f"GLB header declares {length} bytes, too short for a JSON chunk",
                             "the file is corrupt; re-export it")
        if length < len(data):
            self.warn(f"GLB: {len(data) - length} bytes after the declared length {length} were ignored")
        pos = 12
        json_chunk = None
        k = 0
        while pos < length:
            self.where = f"GLB chunk {k}"
            if pos + 8 > length:
                raise _Malformed(f"GLB chunk {k} header at byte {pos} runs past the end ({length} bytes)",
                                 "the file is truncated or corrupt; re-export it")
            clen, ctype = struct.unpack_from("<II", data, pos)
            start, end = pos + 8, pos + 8 + clen
            if end > length:
                raise _Malformed(f"GLB chunk {k} declares {clen} bytes but only {length - start} remain",
                                 "the file is truncated or corrupt; re-export it")
            if k == 0:
                if ctype != CHUNK_JSON:
                    raise _Malformed(f"GLB first chunk has type 0x{ctype:08x}, expected JSON (0x{CHUNK_JSON:08x})",
                                     "the file is corrupt; re-export it")
                json_chunk = data[start:end]
            elif ctype == CHUNK_BIN and self.bin_chunk is None:
                self.bin_chunk = data[start:end]
            pos = end  # chunk lengths include their padding (spec 4.4.3)
            k += 1
        self.where = ""
        if json_chunk is None:
            raise _Malformed("GLB has no JSON chunk", "the file is corrupt; re-export it")
        return json_chunk

    def _parse_json(self, raw: bytes) -> None:
        self.where = "JSON"
        try:
            text = raw.decode("utf-8-sig").rstrip("\x00 \t\r\n")
        except UnicodeDecodeError as exc:
            raise _Malformed(f"JSON is not valid UTF-8 (byte {exc.start})", "the file is corrupt") from None
        try:
            gltf = json.loads(text, parse_constant=_no_constant)
        except json.JSONDecodeError as exc:
            raise _Malformed(f"invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}",
                             "the file is corrupt or not glTF; re-export it") from None
        except RecursionError:
            raise _Malformed("JSON is nested too deeply to read",
                             "the file is corrupt or hostile; re-export it") from None
        except ValueError as exc:  # e.g. an integer with thousands of digits, NaN / Infinity
            raise _Malformed(f"invalid JSON ({' '.join(str(exc).split())[:120]})",
                             "the file is corrupt or not glTF; re-export it") from None
        if not isinstance(gltf, dict):
            raise _Malformed("JSON top level is not an object", "the file is not glTF")
        asset = gltf.get("asset")
        version = str(asset.get("version", "")) if isinstance(asset, dict) else ""
        if version and not version.startswith("2"):
            raise _Malformed(f"glTF version {version} is not supported, only 2.0",
                             "convert the file to glTF 2.0 (e.g. with gltf-pipeline)")
        self.gltf = gltf
        self.where = ""

    def _refuse_compressed(self, what: str, ext: str) -> None:
        raise _Malformed(f"{what} uses {ext}, which lopcook cannot decode; reading its fallback as plain "
                         "data would give wrong geometry", DECOMPRESS_HINT)

    def _check_extensions(self) -> None:
        required = self.gltf.get("extensionsRequired") or []
        if not isinstance(required, list):
            raise _Malformed("extensionsRequired is not a list")
        bad = [e for e in required if not (e in SUPPORTED_REQUIRED
                                           or str(e).startswith(SUPPORTED_REQUIRED_PREFIXES))]
        if bad:
            names = ", ".join(map(str, bad))
            compressed = any(("draco" in str(e).lower() or "meshopt" in str(e).lower()) for e in bad)
            hint = DECOMPRESS_HINT if compressed else \
                "re-export the file without it (lopcook supports KHR_mesh_quantization and KHR_materials_*)"
            raise _Malformed(f"required extension {names} is not supported", hint)

    # ------------------------------------------------------------------ buffers

    def buffer(self, index: int) -> bytes:
        if index in self._buffers:
            return self._buffers[index]
        buf = self.item("buffers", index)
        self.where = f"buffer {index}"
        declared = self.uint(buf, "byteLength", minimum=1)
        if "EXT_meshopt_compression" in (buf.get("extensions") or {}) or \
                "KHR_meshopt_compression" in (buf.get("extensions") or {}):
            self._refuse_compressed(f"buffer {index}", "meshopt compression")
        uri = buf.get("uri")
        if uri is None:
            if self.fmt != "glb" or index != 0:
                raise _Malformed(f"buffer {index} has no uri (only buffer 0 of a GLB may use the BIN chunk)",
                                 "the file is corrupt; re-export it")
            if self.bin_chunk is None:
                raise _Malformed("buffer 0 refers to the GLB BIN chunk, but the file has none",
                                 "the file is truncated or corrupt; re-export it")
            data = self.bin_chunk
            origin = "the GLB BIN chunk"
        else:
            data, origin = self._read_uri(uri, f"buffer {index}")
            if data is None:
                raise _Malformed(f"buffer {index}: external file {origin!r} not found",
                                 "keep the .bin file next to the .gltf (paths are relative to it) or "
                                 "pack everything into one .glb")
        if len(data) < declared:
            raise _Malformed(f"buffer {index} is truncated: {origin} has {len(data)} bytes, "
                             f"byteLength says {declared}",
                             "the file is truncated; re-export or re-download it")
        self._buffers[index] = data
        return data

    def _read_uri(self, uri: str, what: str) -> tuple[bytes | None, str]:
        """Return (bytes or None when the file is missing, description)."""
        if not isinstance(uri, str):
            raise _Malformed(f"{what}: uri is not a string")
        if uri.startswith("data:"):
            head, sep, payload = uri.partition(",")
            if not sep or not head.endswith(";base64"):
                raise _Malformed(f"{what}: data URI is not base64 encoded",
                                 "embed binary data as data:...;base64,...")
            try:
                return base64.b64decode(payload, validate=False), "data URI"
            except (binascii.Error, ValueError):
                raise _Malformed(f"{what}: data URI holds invalid base64", "the file is corrupt") from None
        scheme = urllib.parse.urlsplit(uri).scheme
        if scheme and len(scheme) > 1:
            raise _Malformed(f"{what}: uri {uri!r} is not a relative file path",
                             "download the resource and refer to it by a relative path")
        rel = urllib.parse.unquote(uri)
        if bad_path_characters(rel):
            raise LopcookError("ingest", self.path, f"{what}: uri {uri!r} names a file with a line break or NUL",
                               hint="rename the file and the uri: such a name cannot be listed in a depfile")
        if os.path.isabs(rel) or rel.startswith("\\") or (len(scheme) == 1 and os.name == "nt"):
            raise _Malformed(f"{what}: uri {uri!r} is an absolute path; glTF uris are relative to the file",
                             "copy the file next to the glTF and refer to it by a relative path")
        full = os.path.join(self.base_dir, rel)
        self.deps.add(rel)  # listed even when missing: a build must rerun when it appears
        problem = regular_file_problem(full)
        if problem == "not found":
            return None, rel
        if problem is not None:
            raise _Malformed(f"{what}: {rel!r} {problem}", "refer to a regular file next to the glTF")
        with open(full, "rb") as fh:
            return fh.read(), rel

    def view(self, index: int) -> memoryview:
        if index in self._views:
            return self._views[index]
        v = self.item("bufferViews", index, "bufferView")
        where, self.where = self.where, f"bufferView {index}"
        for ext in ("EXT_meshopt_compression", "KHR_meshopt_compression"):
            if ext in (v.get("extensions") or {}):
                self._refuse_compressed(f"bufferView {index}", ext)
        off = self.uint(v, "byteOffset", 0)
        length = self.uint(v, "byteLength", minimum=1)
        if "byteStride" in v:
            stride = self.uint(v, "byteStride", minimum=4)
            if stride > 252 or stride % 4:
                raise _Malformed(f"bufferView {index}: byteStride {stride} is not a multiple of 4 in [4, 252]",
                                 "the file is corrupt or was written by a broken exporter")
        data = self.buffer(v["buffer"])
        self.where = f"bufferView {index}"
        if off + length > len(data):
            raise _Malformed(f"bufferView {index} (bytes {off}..{off + length}) runs past the end of "
                             f"buffer {v['buffer']} ({len(data)} bytes)",
                             "the file is truncated or corrupt; re-export it")
        mv = memoryview(data)[off:off + length]
        self._views[index] = mv
        self.where = where
        return mv

    # ------------------------------------------------------------------ accessors

    def accessor(self, index: int) -> tuple[np.ndarray, bool, int]:
        """Raw accessor data: ((count, width) array in the component dtype, normalized, componentType).

        Handles strided views, accessors without bufferView (zeros) and sparse substitution.
        """
        if index in self._accessors:
            return self._accessors[index]
        a = self.item("accessors", index, "accessor")
        self.where = f"accessor {index}"
        ctype = a["componentType"]
        if ctype not in COMPONENT_DTYPES:
            raise _Malformed(f"accessor {index}: unsupported componentType {ctype!r}",
                             "glTF 2.0 allows 5120, 5121, 5122, 5123, 5125 and 5126")
        dtype = COMPONENT_DTYPES[ctype]
        atype = a["type"]
        if atype not in TYPE_WIDTH:
            raise _Malformed(f"accessor {index}: type {atype!r} cannot be used for mesh data",
                             "expected SCALAR, VEC2, VEC3 or VEC4")
        width = TYPE_WIDTH[atype]
        count = a["count"]
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise _Malformed(f"accessor {index}: count {count!r} is not a positive integer")
        elem = width * dtype.itemsize
        if "bufferView" in a:
            bv = a["bufferView"]
            mv = self.view(bv)
            self.where = f"accessor {index}"
            stride = int(self.gltf["bufferViews"][bv].get("byteStride") or elem)
            off = self.uint(a, "byteOffset", 0)
            if stride < elem:
                raise _Malformed(f"accessor {index}: byteStride {stride} of bufferView {bv} is smaller "
                                 f"than one element ({elem} bytes)")
            need = off + stride * (count - 1) + elem
            if off < 0 or need > len(mv):
                raise _Malformed(f"accessor {index} reads past the end of bufferView {bv}: needs {need} bytes, "
                                 f"the view has {len(mv)}", "the file is truncated or corrupt; re-export it")
            arr = np.ndarray((count, width), dtype=dtype, buffer=mv, offset=off,
                             strides=(stride, dtype.itemsize)).copy()
        else:
            # all zeros (spec 3.6.2.4): bound the count by the bytes the file has, so a lying count
            # cannot allocate gigabytes from a few bytes of JSON
            limit = max(ZERO_ACCESSOR_MIN, self.data_bytes + self._external_bytes())
            if count > limit:
                raise _Malformed(f"accessor {index} declares {count:,} elements without a bufferView; lopcook "
                                 f"accepts at most {limit:,} (the bytes in the file and its buffers)",
                                 "the count is corrupt; re-export the file")
            arr = np.zeros((count, width), dtype=dtype)
        sparse = a.get("sparse")
        if sparse is not None:
            arr = self._apply_sparse(index, arr, sparse, dtype, width)
        result = (arr, bool(a.get("normalized", False)), ctype)
        self._accessors[index] = result
        self.where = ""
        return result

    def _external_bytes(self) -> int:
        """Total size of the external buffer files that exist (for the zero-accessor bound)."""
        total = 0
        for buf in self.gltf.get("buffers") or []:
            uri = buf.get("uri") if isinstance(buf, dict) else None
            if isinstance(uri, str) and not uri.startswith("data:"):
                try:
                    total += os.path.getsize(os.path.join(self.base_dir, urllib.parse.unquote(uri)))
                except (OSError, ValueError):
                    pass
            elif isinstance(uri, str):
                total += len(uri)
        return total

    def _apply_sparse(self, index: int, arr: np.ndarray, sparse: dict, dtype: np.dtype,
                      width: int) -> np.ndarray:
        """Spec 3.6.2.3: substitute ``sparse.count`` elements at ``sparse.indices``."""
        n = sparse["count"]
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise _Malformed(f"accessor {index}: sparse count {n!r} is not a positive integer")
        si, sv = sparse["indices"], sparse["values"]
        ictype = si["componentType"]
        if ictype not in (5121, 5123, 5125):
            raise _Malformed(f"accessor {index}: sparse indices componentType {ictype!r} is not "
                             "UNSIGNED_BYTE/SHORT/INT")
        idx = self._packed(index, "sparse indices", si, COMPONENT_DTYPES[ictype], n, 1).reshape(-1)
        vals = self._packed(index, "sparse values", sv, dtype, n, width)
        if idx.size and int(idx.max()) >= arr.shape[0]:
            raise _Malformed(f"accessor {index}: sparse index {int(idx.max())} out of range for "
                             f"count {arr.shape[0]}", "the file is corrupt; re-export it")
        arr = arr.copy()
        arr[idx.astype(np.int64)] = vals
        return arr

    def _packed(self, index: int, what: str, ref: dict, dtype: np.dtype, count: int, width: int) -> np.ndarray:
        bv = ref["bufferView"]
        mv = self.view(bv)
        self.where = f"accessor {index}"
        off = self.uint(ref, "byteOffset", 0)
        need = off + count * width * dtype.itemsize
        if off < 0 or need > len(mv):
            raise _Malformed(f"accessor {index}: {what} read past the end of bufferView {bv}: needs {need} "
                             f"bytes, the view has {len(mv)}", "the file is truncated or corrupt; re-export it")
        return np.frombuffer(mv, dtype=dtype, count=count * width, offset=off).reshape(count, width).copy()

    def floats(self, index: int, semantic: str, widths: tuple[int, ...], what: str) -> np.ndarray:
        """Accessor decoded to (count, width) float64 (normalized integers per spec 3.11)."""
        arr, normalized, ctype = self.accessor(index)
        kind = semantic.split("_")[0]
        if ctype not in ATTR_COMPONENTS[kind]:
            raise _Malformed(f"{what}: {semantic} accessor {index} has componentType "
                             f"{COMPONENT_NAMES.get(ctype, ctype)}, which {semantic} cannot use",
                             "re-export with float or KHR_mesh_quantization-compatible attributes")
        if arr.shape[1] not in widths:
            raise _Malformed(f"{what}: {semantic} accessor {index} has {arr.shape[1]} components, "
                             f"expected {' or '.join(map(str, widths))}")
        out = arr.astype(np.float64)
        if normalized and ctype != 5126:
            info = np.iinfo(arr.dtype)
            out /= float(info.max)
            if info.min < 0:
                np.maximum(out, -1.0, out=out)
        return out

    def indices(self, index: int, what: str) -> np.ndarray:
        arr, _, ctype = self.accessor(index)
        if ctype not in (5121, 5123, 5125) or arr.shape[1] != 1:
            raise _Malformed(f"{what}: indices accessor {index} must be SCALAR UNSIGNED_BYTE/SHORT/INT, got "
                             f"{COMPONENT_NAMES.get(ctype, ctype)} with {arr.shape[1]} components")
        return arr.reshape(-1).astype(np.int64)

    # ------------------------------------------------------------------ textures

    def double_sided(self, material_index) -> bool:
        """The material's ``doubleSided`` (glTF's default, false, without a material or the key; a
        value other than true counts as false)."""
        if material_index is None:
            return False
        return self.item("materials", material_index, "material").get("doubleSided") is True

    def base_color(self, material_index) -> tuple[Texture | None, int]:
        """(shared Texture or None, texCoord set) for a material's base-colour texture."""
        if material_index is None:
            return None, 0
        mat = self.item("materials", material_index, "material")
        ref = (mat.get("pbrMetallicRoughness") or {}).get("baseColorTexture")
        if not isinstance(ref, dict) or "index" not in ref:
            return None, 0
        tex_coord = int(ref.get("texCoord", 0))
        if "KHR_texture_transform" in (ref.get("extensions") or {}):
            self.warn(f"material {material_index}: KHR_texture_transform on the base colour texture is not "
                      f"applied: the UVs are cooked as stored, and the texture's precision estimate (--texture-kf "
                      f"image) does not see the transform's scale")
        tex = self.item("textures", ref["index"], "texture")
        src = tex.get("source")
        if src is None:
            for ext in ("EXT_texture_webp", "KHR_texture_basisu", "MSFT_texture_dds"):
                src = ((tex.get("extensions") or {}).get(ext) or {}).get("source", src)
        if src is None:
            self.warn(f"texture {ref['index']} has no image source; base colour texture ignored")
            return None, tex_coord
        if src not in self._textures:
            self._textures[src] = self._load_image(src)
        return self._textures[src], tex_coord

    def _load_image(self, index: int) -> Texture | None:
        where = self.where
        img = self.item("images", index, "image")
        self.where = f"image {index}"
        if "uri" in img:
            try:
                data, origin = self._read_uri(img["uri"], f"image {index}")
            except _Malformed as exc:  # a remote URL or a broken data URI: the geometry is still good
                self.warn(f"{exc.message}; the parts using it have no texture")
                self.where = where
                return None
            if data is None:
                self.warn(f"image {index}: file {origin!r} not found; the parts using it have no texture")
                self.where = where
                return None
            name = f"<embedded {index}>" if origin == "data URI" else os.path.basename(origin)
            what = f"image {index} ({origin})"
        elif "bufferView" in img:
            data = bytes(self.view(img["bufferView"]))
            name = f"<embedded {index}>"
            what = f"image {index} (bufferView {img['bufferView']})"
        else:
            raise _Malformed(f"image {index} has neither uri nor bufferView")
        self.where = where
        return checked_texture(name, data, self.warn, what)

    # ------------------------------------------------------------------ scene graph

    def _walk_scene(self) -> list[MeshPart]:
        self.where = "scenes"
        nodes = self.gltf.get("nodes") or []
        scenes = self.gltf.get("scenes") or []
        if scenes:
            scene_index = self.gltf.get("scene", 0)
            roots = self.item("scenes", scene_index, "scene").get("nodes") or []
        else:
            children = {c for n in nodes if isinstance(n, dict) for c in (n.get("children") or [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        parts: list[MeshPart] = []
        visited: set[int] = set()
        if not isinstance(roots, list) or not isinstance(nodes, list):
            raise _Malformed("scene nodes or nodes is not a JSON array")
        self._count_placements(nodes, roots)
        stack = [(r, np.eye(4)) for r in reversed(list(roots))]
        while stack:
            ni, parent = stack.pop()
            self.where = "scene"
            node = self.item("nodes", ni, "node")
            if ni in visited:
                raise _Malformed(f"node {ni} is reached twice in the node hierarchy (a cycle or two parents)",
                                 "each node must have exactly one parent; re-export the file")
            visited.add(ni)
            self.where = f"node {ni}"
            world = parent @ _local_matrix(node, ni)
            if "mesh" in node:
                instances = self._instance_matrices(ni, node)
                if instances is None:
                    parts.extend(self._node_parts(ni, node, world))
                else:  # one placed copy of the mesh per instance: node world @ instance TRS
                    for i, local in enumerate(instances):
                        parts.extend(replace(p, name=f"{p.name}/instance{i}", source=f"{p.source} / instance {i}")
                                     for p in self._node_parts(ni, node, world @ local))
            for c in reversed(list(node.get("children") or [])):
                stack.append((c, world))
        self.where = ""
        return parts

    def _count_placements(self, nodes: list, roots: list) -> None:
        """Refuse, before anything is decoded, a scene graph that places more than ``MAX_PARTS``
        primitives or more than ``MAX_TRIANGLES`` triangles (declared index or vertex counts)."""
        reached, stack, seen = 0, list(roots), set()
        triangles = 0
        while stack:
            ni = stack.pop()
            if isinstance(ni, bool) or not isinstance(ni, int) or not 0 <= ni < len(nodes) or ni in seen:
                continue  # reported with its context by the walk
            seen.add(ni)
            node = nodes[ni]
            if not isinstance(node, dict):
                continue
            children = node.get("children") or []
            if isinstance(children, list):
                stack.extend(children)
            mi = node.get("mesh")
            meshes = self.gltf.get("meshes") or []
            if isinstance(mi, int) and not isinstance(mi, bool) and isinstance(meshes, list) \
                    and 0 <= mi < len(meshes) and isinstance(meshes[mi], dict):
                prims = meshes[mi].get("primitives") or []
                if isinstance(prims, list):
                    copies = self._declared_instances(node)
                    reached += copies * len(prims)
                    triangles += copies * sum(self._declared_triangles(p) for p in prims)
            if reached > MAX_PARTS:
                raise _Malformed(f"the scene places more than {MAX_PARTS:,} primitives (nodes x GPU instances x "
                                 f"primitives); lopcook accepts at most {MAX_PARTS:,} parts",
                                 "merge meshes or split the scene")
            if triangles > self.settings.max_triangles:
                cap = self.settings.max_triangles
                raise _Malformed(f"the scene places more than {cap:,} triangles (declared counts); "
                                 f"lopcook accepts at most {cap:,}", "simplify or split the scene, or raise "
                                 "--max-triangles")

    def _declared_instances(self, node: dict) -> int:
        """How many copies a node's ``EXT_mesh_gpu_instancing`` declares (the largest count of its
        attribute accessors), 1 without it."""
        attrs = _instancing_attributes(node)
        if not isinstance(attrs, dict) or not attrs:
            return 1
        accessors = self.gltf.get("accessors") or []
        counts = [accessors[a].get("count") for a in attrs.values()
                  if isinstance(a, int) and not isinstance(a, bool) and isinstance(accessors, list)
                  and 0 <= a < len(accessors) and isinstance(accessors[a], dict)]
        counts = [c for c in counts if isinstance(c, int) and not isinstance(c, bool)]
        return max(counts, default=1)

    def _instance_matrices(self, ni: int, node: dict) -> list[np.ndarray] | None:
        """The (4, 4) local transforms T @ R @ S of a node's ``EXT_mesh_gpu_instancing`` instances,
        applied in the node's space before its world transform (the extension's order), or None
        when the node has no such extension. Attributes it does not use (custom ``_ID`` and the
        like) are ignored."""
        ext = node.get("extensions")
        if not isinstance(ext, dict) or GPU_INSTANCING not in ext:
            return None
        where = f"node {ni} {GPU_INSTANCING}"
        attrs = _instancing_attributes(node)
        if not isinstance(attrs, dict):
            raise _Malformed(f"{where}: attributes is not a JSON object")
        trs = {}
        for name, width in (("TRANSLATION", 3), ("ROTATION", 4), ("SCALE", 3)):
            if name in attrs:
                trs[name] = self.floats(attrs[name], name, (width,), where)
        counts = {a.shape[0] for a in trs.values()}
        if len(counts) > 1:
            raise _Malformed(f"{where}: TRANSLATION, ROTATION and SCALE have different counts {sorted(counts)}",
                             "every instance attribute must have one value per instance")
        if not trs:
            self.warn(f"{where}: no TRANSLATION, ROTATION or SCALE; the mesh is placed once")
            return None
        n = counts.pop()
        t = trs.get("TRANSLATION", np.zeros((n, 3)))
        q = trs.get("ROTATION", np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))
        sc = trs.get("SCALE", np.ones((n, 3)))
        return [_trs(t[i], q[i], sc[i], f"{where} instance {i}") for i in range(n)]

    def _declared_triangles(self, prim) -> int:
        """Triangles a primitive declares (from its index or POSITION count), 0 when unknown."""
        if not isinstance(prim, dict):
            return 0
        acc = prim.get("indices", (prim.get("attributes") or {}).get("POSITION") if isinstance(
            prim.get("attributes"), dict) else None)
        accessors = self.gltf.get("accessors") or []
        if isinstance(acc, bool) or not isinstance(acc, int) or not isinstance(accessors, list) \
                or not 0 <= acc < len(accessors) or not isinstance(accessors[acc], dict):
            return 0
        count = accessors[acc].get("count")
        if isinstance(count, bool) or not isinstance(count, int):
            return 0
        return count // 3 if prim.get("mode", 4) == 4 else max(count - 2, 0)

    def _node_parts(self, ni: int, node: dict, world: np.ndarray) -> list[MeshPart]:
        mi = node["mesh"]
        mesh = self.item("meshes", mi, "mesh")
        self.where = f"mesh {mi}"
        prims = mesh["primitives"]
        if not isinstance(prims, list):
            raise _Malformed(f"mesh {mi}: primitives is not a list")
        self.where = f"node {ni}"
        if "skin" in node:
            self.warn(f"node {ni}: skin ignored; the mesh is cooked in its bind pose under the node transform")
        if any(w for w in (mesh.get("weights") or [])) or any(w for w in (node.get("weights") or [])):
            self.warn(f"mesh {mi}: morph target weights ignored; the base shape is cooked")
        lin = world[:3, :3]
        det = float(np.linalg.det(lin))
        if not np.isfinite(world).all():
            raise _Malformed(f"node {ni}: world transform contains NaN or Inf",
                             "fix the node transforms in the authoring tool")
        if det == 0.0:
            self.warn(f"node {ni}: world transform is singular (zero scale); its mesh is skipped")
            return []
        normal_matrix = np.linalg.inv(lin)  # n_world = n @ inv(A)  ==  (inv(A).T @ n.T).T
        identity = bool(np.array_equal(lin, np.eye(3)))
        node_name = node.get("name") or f"node{ni}"
        mesh_name = mesh.get("name") or f"mesh{mi}"
        out = []
        for k, prim in enumerate(prims):
            geom = self._geometry_of(mi, k, prim, mesh)
            if geom is None:
                continue
            if identity:  # the product would add only zeros: the same bits, without a BLAS call
                pos = geom["positions"] + world[:3, 3]
            else:
                pos = geom["positions"] @ lin.T + world[:3, 3]
            tri = geom["triangles"]
            if det < 0:
                tri = tri[:, ::-1]
            normals = None if geom["normals"] is None else geom["normals"] @ normal_matrix
            tangents = None if geom["tangents"] is None else placed_tangents(geom["tangents"], lin.T, det)
            name = f"{node_name}/{mesh_name}" + (f"/prim{k}" if len(prims) > 1 else "")
            label = f"node {ni}" + (f" {node['name']!r}" if node.get("name") else "")
            mlabel = f"mesh {mi}" + (f" {mesh['name']!r}" if mesh.get("name") else "")
            out.append(make_part(name, pos, tri, settings=self.settings, normals=normals, uvs=geom["uvs"],
                                 colors=geom["colors"], extra={"tangents": tangents},
                                 source=f"{label} / {mlabel} / primitive {k}",
                                 texture=geom["texture"], mesh_key=f"mesh{mi}/prim{k}",
                                 double_sided=geom["double_sided"]))
        return out

    def _geometry_of(self, mi: int, k: int, prim: dict, mesh: dict) -> dict | None:
        """Local-space arrays of one primitive, decoded once and shared by every placement.

        Returns None (with a warning) for non-triangle or empty primitives. Keys: positions (n, 3)
        float64, triangles (m, 3) int64 CCW, normals (n, 3) float64 | None, uvs (n, 2) | None,
        colors (n, 3|4) in [0, 1] | None, texture.
        """
        # identical primitives (same accessors, mode and material) are decoded once
        key = json.dumps(prim, sort_keys=True, default=str) if isinstance(prim, dict) else (mi, k)
        if key in self._geometry:
            return self._geometry[key]
        what = f"mesh {mi} primitive {k}"
        self.where = what
        if not isinstance(prim, dict):
            raise _Malformed(f"{what} is not a JSON object")
        mode = prim.get("mode", 4)
        geom = None
        if mode not in MODE_NAMES:
            raise _Malformed(f"{what}: invalid mode {mode!r}", "glTF 2.0 modes are 0..6")
        attrs = prim.get("attributes") or {}
        if not isinstance(attrs, dict):
            raise _Malformed(f"{what}: attributes is not a JSON object")
        if "KHR_draco_mesh_compression" in (prim.get("extensions") or {}):
            self._refuse_compressed(what, "Draco compression (KHR_draco_mesh_compression)")
        if mode < 4:
            self.warn(f"{what}: mode {mode} ({MODE_NAMES[mode]}) skipped; only triangle primitives are cooked")
        elif "POSITION" not in attrs:
            self.warn(f"{what}: no POSITION attribute; skipped")
        else:
            geom = self._decode_primitive(what, prim, attrs, mode)
        self._geometry[key] = geom
        return geom

    def _decode_primitive(self, what: str, prim: dict, attrs: dict, mode: int) -> dict | None:
        pacc = attrs["POSITION"]
        positions = self.floats(pacc, "POSITION", (3,), what)
        n = positions.shape[0]
        if not np.isfinite(positions).all():
            bad = int((~np.isfinite(positions)).any(axis=1).sum())
            raise _Malformed(f"{what}: POSITION accessor {pacc} has {bad} NaN or Inf positions",
                             "fix the mesh in the authoring tool")

        def attribute(semantic: str, widths: tuple[int, ...]) -> np.ndarray | None:
            if semantic not in attrs:
                return None
            arr = self.floats(attrs[semantic], semantic, widths, what)
            if arr.shape[0] != n:
                raise _Malformed(f"{what}: {semantic} accessor {attrs[semantic]} has {arr.shape[0]} elements, "
                                 f"POSITION has {n}", "the file is corrupt; re-export it")
            return arr

        normals = attribute("NORMAL", (3,))
        if normals is not None:
            length = np.linalg.norm(normals, axis=1)
            bad = int((~(length > 1e-20)).sum() + (~np.isfinite(length)).sum())
            if bad:
                self.warn(f"{what}: {bad} normals are zero or not finite (replaced by +Y)")
        tangents = usable_tangents(attribute("TANGENT", (4,)), normals, self.warn, what)
        texture, tex_coord = self.base_color(prim.get("material"))
        self.where = what
        uv_name = f"TEXCOORD_{tex_coord}"
        if uv_name not in attrs and tex_coord != 0:
            self.warn(f"{what}: base colour texture uses {uv_name}, which is missing; TEXCOORD_0 used")
            uv_name = "TEXCOORD_0"
        uvs = attribute(uv_name, (2,))
        colors = attribute("COLOR_0", (3, 4))
        if colors is not None:
            cacc = attrs["COLOR_0"]
            _, normalized, ctype = self.accessor(cacc)
            if ctype != 5126 and not normalized:
                # the spec requires normalized integer colours; exporters that forget the flag mean
                # 0..255 (0..65535), not 0..1: read them as normalized, as viewers do
                scale = float(np.iinfo(COMPONENT_DTYPES[ctype]).max)
                colors = colors / scale
                self.warn(f"{what}: COLOR_0 accessor {cacc} is {COMPONENT_NAMES.get(ctype, ctype)} without "
                          f"normalized: true (required by glTF); read as normalized (value / {scale:g})")
            colors = np.clip(colors, 0.0, 1.0)

        if "indices" in prim:
            iacc = prim["indices"]
            flat = self.indices(iacc, what)
            self.where = what
            src = f"indices accessor {iacc}"
        else:
            flat = np.arange(n, dtype=np.int64)
            src = "implicit indices"
        if flat.size and int(flat.max()) >= n:
            raise _Malformed(f"{what}: index {int(flat.max())} out of range ({src}, {n} vertices, "
                             f"max allowed {n - 1})", "the file is corrupt; re-export it")
        triangles = _triangulate(flat, mode, what, src)
        if triangles.shape[0] == 0:
            self.warn(f"{what}: no triangles; skipped")
            return None
        return {"positions": positions, "triangles": triangles, "normals": normals, "uvs": uvs,
                "colors": colors, "tangents": tangents, "texture": texture, "double_sided": self.double_sided(prim.get("material"))}


# ---------------------------------------------------------------------- pure functions

def _triangulate(flat: np.ndarray, mode: int, what: str, src: str) -> np.ndarray:
    """(k,) vertex indices of a TRIANGLES/STRIP/FAN primitive -> (m, 3) int64 CCW triangles.

    Spec 3.7.2.1: strip triangle i = (v_i, v_{i+1+i%2}, v_{i+2-i%2}); fan triangle i =
    (v_{i+1}, v_{i+2}, v_0).
    """
    k = flat.size
    if mode == 4:
        if k % 3:
            raise _Malformed(f"{what}: {k} indices ({src}), not a multiple of 3 for TRIANGLES",
                             "re-export the file with triangulated primitives")
        return flat.reshape(-1, 3)
    m = max(k - 2, 0)
    i = np.arange(m)
    if mode == 5:
        odd = i % 2
        return np.stack([flat[i], flat[i + 1 + odd], flat[i + 2 - odd]], axis=1)
    return np.stack([flat[i + 1], flat[i + 2], np.full(m, flat[0] if k else 0)], axis=1)


def _local_matrix(node: dict, index: int) -> np.ndarray:
    """(4, 4) float64 local transform of a node (spec 3.5.3): ``matrix`` or T @ R @ S."""
    if "matrix" in node:
        m = np.asarray(node["matrix"], dtype=np.float64)
        if m.shape != (16,):
            raise _Malformed(f"node {index}: matrix has {m.size} values, expected 16")
        out = m.reshape(4, 4).T  # column-major
    else:
        t = np.asarray(node.get("translation", (0.0, 0.0, 0.0)), dtype=np.float64)
        q = np.asarray(node.get("rotation", (0.0, 0.0, 0.0, 1.0)), dtype=np.float64)
        s = np.asarray(node.get("scale", (1.0, 1.0, 1.0)), dtype=np.float64)
        if t.shape != (3,) or q.shape != (4,) or s.shape != (3,):
            raise _Malformed(f"node {index}: translation/rotation/scale must have 3/4/3 values")
        out = _trs(t, q, s, f"node {index}")
    if not np.isfinite(out).all():
        raise _Malformed(f"node {index}: transform contains NaN or Inf",
                         "fix the node transform in the authoring tool")
    return out


def _instancing_attributes(node: dict):
    """The ``attributes`` value of a node's ``EXT_mesh_gpu_instancing`` as written (any JSON value),
    or None when the node has no such object."""
    ext = node.get("extensions")
    inst = ext.get(GPU_INSTANCING) if isinstance(ext, dict) else None
    return inst.get("attributes") if isinstance(inst, dict) else None


def _trs(t: np.ndarray, q: np.ndarray, s: np.ndarray, what: str) -> np.ndarray:
    """(4, 4) float64 T @ R @ S from a translation (3,), a quaternion (4,) x, y, z, w (normalised
    here) and a scale (3,); ``what`` names it in the error for a quaternion of zero or non-finite
    length."""
    q = np.asarray(q, dtype=np.float64)
    qn = np.linalg.norm(q)
    if not np.isfinite(qn) or qn == 0.0:
        raise _Malformed(f"{what}: rotation quaternion {q.tolist()} is not a unit quaternion",
                         "fix the transform in the authoring tool")
    x, y, z, w = q / qn
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    out = np.eye(4)
    out[:3, :3] = r * np.asarray(s, dtype=np.float64)[None, :]
    out[:3, 3] = np.asarray(t, dtype=np.float64)
    if not np.isfinite(out).all():
        raise _Malformed(f"{what}: transform contains NaN or Inf", "fix the transform in the authoring tool")
    return out


def _no_constant(name: str):
    raise ValueError(f"{name} is not a JSON number")


def _rename(part: MeshPart, name: str) -> MeshPart:
    return replace(part, name=name)


# ---------------------------------------------------------------------------------------------
# Materials for decoded previews (docs/format.md 9.2)
# ---------------------------------------------------------------------------------------------


def materials(path: str, parts: list[dict], out: MaterialSet) -> list[dict | None]:
    """The source's own glTF material of each manifest part, found by its ``mesh_key``
    ``mesh{mi}/prim{k}`` (None: the primitive has no material, or the key is not glTF's).

    Carried: base colour (factor, texture), metallic-roughness (factors, texture), normal (with
    ``scale``), occlusion (with ``strength``), emissive (factor, texture), ``alphaMode``,
    ``alphaCutoff`` (MASK only), ``doubleSided``. Images (bufferView, data URI or relative file)
    go to ``out`` as bytes. Left out with a warning in ``out``: material extensions, a texture read
    through another UV set than the base colour's (the one set the container keeps), a texture
    without a source, an image that is not a readable PNG/JPEG or not a relative file. This is a
    lenient second reading of a file ``load`` accepted: a malformed file raises ``ValueError``,
    ``KeyError``, ``IndexError``, ``TypeError`` or ``struct.error``.
    """
    reader = _MaterialReader(path, out)
    cache: dict = {}
    per_part = []
    for p in parts:
        mk = re.fullmatch(r"mesh(\d+)/prim(\d+)", str(p.get("mesh_key", "")))
        mat = None
        if mk:
            prim = reader.doc["meshes"][int(mk.group(1))]["primitives"][int(mk.group(2))]
            mi = prim.get("material")
            if mi is not None:
                if mi not in cache:
                    cache[mi] = reader.material(mi)
                mat = cache[mi]
        per_part.append(mat)
    if reader.dropped_ext:
        out.warn(f"material extensions not carried into the preview: {', '.join(sorted(reader.dropped_ext))}")
    return per_part


class _MaterialReader:
    """The JSON, buffers and images of one glTF file, read for its materials."""

    def __init__(self, path: str, out: MaterialSet) -> None:
        raw = Path(path).read_bytes()
        self.bin_chunk = None
        if raw[:4] == GLB_MAGIC:
            jlen, jtype = struct.unpack_from("<I4s", raw, 12)
            if jtype != b"JSON":
                raise ValueError("GLB has no JSON chunk first")
            self.doc = json.loads(raw[20:20 + jlen])
            off = 20 + jlen
            if off + 8 <= len(raw):
                blen, btype = struct.unpack_from("<I4s", raw, off)
                if btype == b"BIN\0":
                    self.bin_chunk = raw[off + 8: off + 8 + blen]
        else:
            self.doc = json.loads(raw)
        self.base = os.path.dirname(os.path.abspath(path))
        self.out = out
        self.buffers: dict = {}
        self.samplers = self.doc.get("samplers") or []
        self.dropped_ext: set = set()

    def uri_bytes(self, uri: str, what: str) -> bytes | None:
        """The bytes a data URI holds or a relative file has; None (and a warning) otherwise."""
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            return base64.b64decode(payload) if head.endswith(";base64") else \
                urllib.parse.unquote(payload).encode("latin-1")
        rel = urllib.parse.unquote(uri)
        if "://" in rel or os.path.isabs(rel):
            self.out.warn(f"{what}: URI {uri!r} is not a relative file; left out of the preview")
            return None
        p = os.path.join(self.base, rel)
        if not os.path.isfile(p):
            self.out.warn(f"{what}: file {rel!r} not found; left out of the preview")
            return None
        return Path(p).read_bytes()

    def buffer(self, i: int) -> bytes | None:
        if i not in self.buffers:
            b = self.doc["buffers"][i]
            self.buffers[i] = self.uri_bytes(b["uri"], f"buffer {i}") if "uri" in b else self.bin_chunk
        return self.buffers[i]

    def image(self, i: int) -> tuple[bytes, str] | None:
        """``(encoded bytes, name)`` of image ``i``, or None."""
        img = self.doc["images"][i]
        name = img.get("name") or (os.path.basename(urllib.parse.unquote(img["uri"]))
                                   if "uri" in img and not img["uri"].startswith("data:") else f"image{i}")
        if "uri" in img:
            data = self.uri_bytes(img["uri"], f"image {i}")
        else:
            v = self.doc["bufferViews"][img["bufferView"]]
            b = self.buffer(v["buffer"])
            data = None if b is None else b[v.get("byteOffset", 0): v.get("byteOffset", 0) + v["byteLength"]]
        return None if not data else (bytes(data), name)

    def tex_ref(self, ref, uv_set: int, what: str) -> dict | None:
        """A material's texture reference ``ref`` as the preview's (index into ``out``), or None."""
        if not isinstance(ref, dict) or "index" not in ref:
            return None
        if ref.get("texCoord", 0) != uv_set:
            self.out.warn(f"{what} reads TEXCOORD_{ref.get('texCoord', 0)}, the container keeps "
                          f"TEXCOORD_{uv_set} only; left out of the preview")
            return None
        self.dropped_ext.update((ref.get("extensions") or {}).keys())
        tex = self.doc["textures"][ref["index"]]
        if "source" not in tex:
            self.out.warn(f"{what}: texture {ref['index']} has no PNG/JPEG source; left out of the preview")
            return None
        smp = None
        if "sampler" in tex:
            s = self.samplers[tex["sampler"]]
            smp = {k: s[k] for k in ("magFilter", "minFilter", "wrapS", "wrapT") if k in s}
        t = self.out.texture(self.out.image(("gltf", tex["source"]), lambda: self.image(tex["source"])), smp)
        if t is None:
            return None
        res = {"index": t}
        for k in ("scale", "strength"):
            if k in ref:
                res[k] = ref[k]
        return res

    def material(self, mi: int) -> dict:
        """Material ``mi`` as glTF 2.0 core (see ``materials``)."""
        m = self.doc["materials"][mi]
        self.dropped_ext.update((m.get("extensions") or {}).keys())
        pbr_in = m.get("pbrMetallicRoughness") or {}
        uv_set = int((pbr_in.get("baseColorTexture") or {}).get("texCoord", 0))
        what = f"material {mi}" + (f" {m['name']!r}" if m.get("name") else "")
        res: dict = {"name": m["name"]} if isinstance(m.get("name"), str) else {}
        pbr = {k: pbr_in[k] for k in ("baseColorFactor", "metallicFactor", "roughnessFactor") if k in pbr_in}
        for k in ("baseColorTexture", "metallicRoughnessTexture"):
            r = self.tex_ref(pbr_in.get(k), uv_set, f"{what} {k}")
            if r is not None:
                pbr[k] = r
        res["pbrMetallicRoughness"] = pbr
        for k in ("normalTexture", "occlusionTexture", "emissiveTexture"):
            r = self.tex_ref(m.get(k), uv_set, f"{what} {k}")
            if r is not None:
                res[k] = r
        for k in ("emissiveFactor", "alphaMode", "alphaCutoff", "doubleSided"):
            if k in m:
                res[k] = m[k]
        if res.get("alphaMode") != "MASK":
            res.pop("alphaCutoff", None)
        return res


# ---------------------------------------------------------------------------------------------
# The format
# ---------------------------------------------------------------------------------------------

#: extension -> the kinds a file so named may hold (a .gltf may hold GLB bytes and vice versa)
EXTENSIONS = {".gltf": ("gltf", "glb"), ".glb": ("glb", "gltf")}


def sniff(head: bytes) -> str | None:
    """``"glb"`` for the GLB magic, ``"gltf"`` for JSON (``{`` after a BOM and whitespace)."""
    if head.startswith(GLB_MAGIC):
        return "glb"
    if head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{"):
        return "gltf"
    return None


FORMAT = Format(name="gltf", title="glTF/GLB", extensions=EXTENSIONS, load=load, sniff=sniff,
                materials=materials, sidecars=(".bin",))

__all__ = ["load", "materials", "sniff", "EXTENSIONS", "FORMAT"]
