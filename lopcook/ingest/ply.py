"""Stanford PLY (``.ply``: ASCII, binary little- and big-endian) -> ``Scene``; the PLY ``FORMAT``.

The format is Greg Turk's (the Stanford 3D Scanning Repository ships its scans in it): a text
header ``ply`` / ``format ascii|binary_little_endian|binary_big_endian 1.0`` / ``element NAME
COUNT`` and ``property TYPE NAME`` or ``property list COUNT_TYPE ITEM_TYPE NAME`` lines /
``end_header``, then each element's records in order. Types: ``char uchar short ushort int uint
float double`` and their ``int8`` ... ``float64`` spellings.

``load(path, fmt="ply", settings) -> Scene`` (not yet validated), one part named after the file
(``mesh_key`` ``ply:<file name>``):

* ``vertex``: ``x y z`` (any numeric type) are required; ``nx ny nz`` are the normals, else they
  are computed (``build.make_part``, split at ``settings.crease_angle_deg``); ``red green blue
  [alpha]`` (or ``diffuse_red`` ...) the colours, integers divided by their type's maximum (uchar
  255), floats as stored, clipped to [0, 1] (a warning), taken as stored like OBJ's (PLY names no
  colour space); ``s t``, ``u v``, ``texture_u texture_v`` or ``texture_s texture_t`` the UVs,
  stored as ``(u, 1 - v)`` (origin top-left). Other properties (a scan's ``confidence``,
  ``intensity``) and other elements are read past, unused.
* ``face``: the ``vertex_indices`` (or ``vertex_index``) list; polygons are triangulated by
  ``polygons.triangulate`` (concave ones right, winding kept), faces of fewer than 3 corners are
  skipped (a warning). Vertices no face uses are dropped; the others keep their file order.
* ``comment TextureFile NAME``: the base-colour texture, relative to the .ply (a missing or
  undecodable image is a warning). PLY has no units: metres as written, +Y up, CCW.
* ``Scene.dependencies``: the .ply, then the texture file looked for.

Refused, each as one ``LopcookError("ingest", path, ...)``: a header that is not PLY 1.0, an
unknown type, a list whose count or index type is not an integer, a missing ``x y z``; counts
whose records cannot fit in the bytes that follow the header (checked before anything is
allocated, so a header claiming 10^12 vertices costs nothing), truncated data, an ASCII token
that is not a number or not an integer in its type's range, a face index out of range, more than
``settings.max_triangles`` triangles (counted before triangulating).

Cost: binary elements are read with one ``np.frombuffer`` each when their lists all have one
length (a triangle mesh); ASCII with one ``np.fromstring``. Lists of mixed lengths take a Python
loop over the records. ``materials(path, parts, out)``: every part gets a dielectric material
(metallic 0, roughness 1) carrying the ``TextureFile`` image, for ``lopcook decode``.
"""

from __future__ import annotations

import os
import re
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..depfile import DependencyList
from ..errors import LopcookError
from ..settings import IngestSettings
from ..types import Scene, Texture
from .build import checked_texture, make_part, regular_file_problem
from .format import Format
from .materials import MaterialSet
from .polygons import PolygonTooComplex, triangulate

#: property type names -> numpy base types (endianness applied when the data is binary)
TYPES = {name: np.dtype(t) for names, t in (
    (("char", "int8"), "i1"), (("uchar", "uint8"), "u1"), (("short", "int16"), "i2"),
    (("ushort", "uint16"), "u2"), (("int", "int32"), "i4"), (("uint", "uint32"), "u4"),
    (("float", "float32"), "f4"), (("double", "float64"), "f8")) for name in names}
#: ``format`` keyword -> numpy byte order (None: ASCII)
ENCODINGS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
#: the header must end within this many bytes
MAX_HEADER_BYTES = 1 << 20
#: vertex property names of each attribute, in order of preference
UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
COLOR_NAMES = (("red", "green", "blue", "alpha"), ("diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"))
_HINT = "fix or re-export the PLY file"


@dataclass(frozen=True)
class _Property:
    """One property: a scalar (``count_type`` None) or a list of ``type`` items."""

    name: str
    type: np.dtype
    count_type: np.dtype | None = None


@dataclass(frozen=True)
class _Element:
    """One ``element NAME COUNT`` of the header and its properties, in record order."""

    name: str
    count: int
    props: tuple[_Property, ...]

    def min_bytes(self) -> int:
        """Bytes of the shortest binary record (every list empty)."""
        return sum((p.type if p.count_type is None else p.count_type).itemsize for p in self.props)


@dataclass
class _Header:
    """What the header says, and where the data starts."""

    encoding: str | None            # None: ASCII, else the numpy byte order
    elements: list[_Element]
    texture: str | None             # comment TextureFile NAME
    size: int                       # bytes up to the first byte of data


class _Malformed(Exception):
    """A problem found while reading (``load`` makes it one LopcookError naming the file)."""


# ---------------------------------------------------------------------------------------------
# Header
# ---------------------------------------------------------------------------------------------


def _read_header(data: bytes) -> _Header:
    """The header at the start of ``data`` (raises ``_Malformed``)."""
    end = re.search(rb"(^|\n)end_header[ \t]*\r?\n", data[:MAX_HEADER_BYTES])
    if not data.startswith((b"ply\n", b"ply\r\n")):
        raise _Malformed("the file does not start with the PLY magic line 'ply'")
    if end is None:
        raise _Malformed(f"no 'end_header' line within the first {MAX_HEADER_BYTES:,} bytes")
    try:
        text = data[:end.end()].decode("ascii")
    except UnicodeDecodeError as exc:
        raise _Malformed(f"the header holds a non-ASCII byte at offset {exc.start}") from None
    encoding, elements, texture, fmt_seen = None, [], None, False
    for number, line in enumerate(text.splitlines()[1:-1], start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            if len(words) >= 3 and words[0] == "comment" and words[1].lower() == "texturefile":
                texture = line.split(None, 2)[2].strip()
            continue
        where = f"header line {number}"
        if words[0] == "format":
            if len(words) != 3 or words[1] not in ENCODINGS or words[2] != "1.0":
                raise _Malformed(f"{where}: {line.strip()!r} is not 'format ascii|binary_little_endian|"
                                 "binary_big_endian 1.0'")
            encoding, fmt_seen = ENCODINGS[words[1]], True
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit() or len(words[2]) > 20:
                raise _Malformed(f"{where}: {line.strip()!r} is not 'element NAME COUNT'")
            elements.append(_Element(words[1], int(words[2]), ()))
        elif words[0] == "property":
            if not elements:
                raise _Malformed(f"{where}: a property before any element")
            prop = _property(words, where)
            last = elements[-1]
            elements[-1] = _Element(last.name, last.count, last.props + (prop,))
        else:
            raise _Malformed(f"{where}: unknown header keyword {words[0]!r}")
    if not fmt_seen:
        raise _Malformed("the header has no 'format' line")
    return _Header(encoding, elements, texture, end.end())


def _property(words: list[str], where: str) -> _Property:
    """A ``property`` line, split into words."""
    if len(words) == 5 and words[1] == "list":
        count_type, item_type = (_type(w, where) for w in words[2:4])
        if count_type.kind not in "iu":
            raise _Malformed(f"{where}: list {words[4]!r} has a count of type {words[2]!r}; it must be an integer type")
        return _Property(words[4], item_type, count_type)
    if len(words) == 3:
        return _Property(words[2], _type(words[1], where))
    raise _Malformed(f"{where}: {' '.join(words)!r} is not 'property TYPE NAME' or 'property list COUNT_TYPE "
                     "ITEM_TYPE NAME'")


def _type(word: str, where: str) -> np.dtype:
    if word not in TYPES:
        raise _Malformed(f"{where}: unknown property type {word!r} (expected one of {', '.join(TYPES)})")
    return TYPES[word]


def _check_sizes(header: _Header, available: int) -> None:
    """Refuse counts whose shortest records need more bytes than follow the header (ASCII: one
    digit per value and one separator between values), before anything is allocated."""
    need = -1 if header.encoding is None else 0
    for e in header.elements:
        if e.count and not e.props:
            raise _Malformed(f"element {e.name!r} declares {e.count:,} records but no properties")
        record = 2 * len(e.props) if header.encoding is None else e.min_bytes()
        need += e.count * record
        if need > available:
            raise _Malformed(f"element {e.name!r} declares {e.count:,} records of at least {record} bytes each; "
                             f"{available:,} bytes follow the header (a truncated file or a wrong count)")


# ---------------------------------------------------------------------------------------------
# Element data
# ---------------------------------------------------------------------------------------------


@dataclass
class _Values:
    """An element's data: per scalar property an (n,) array; per list property its lengths (n,)
    int64 and items (sum of lengths,)."""

    scalars: dict[str, np.ndarray]
    lists: dict[str, tuple[np.ndarray, np.ndarray]]


def _read_binary(data: bytes, pos: int, e: _Element, order: str) -> tuple[_Values, int]:
    """Element ``e``'s records at byte ``pos`` -> (values, the byte after them)."""
    lists = [i for i, p in enumerate(e.props) if p.count_type is not None]
    if len(lists) <= 1:
        fixed = _read_binary_fixed(data, pos, e, order, lists[0] if lists else None)
        if fixed is not None:
            return fixed
    return _read_binary_walk(data, pos, e, order)


def _read_binary_fixed(data: bytes, pos: int, e: _Element, order: str, li: int | None):
    """One ``np.frombuffer`` when every record has the same size (no list, or one list whose
    every record has the first record's length); None when the lengths differ."""
    fields, k = [], 0
    if li is not None and e.count:
        head = pos + sum(p.type.itemsize for p in e.props[:li])
        count_type = e.props[li].count_type.newbyteorder(order)
        if head + count_type.itemsize > len(data):
            raise _Malformed(f"element {e.name!r} is truncated: its first record runs past the end of the file")
        k = int(np.frombuffer(data, count_type, 1, head)[0])
        if k < 0 or head + count_type.itemsize + k * e.props[li].type.itemsize > len(data):
            return None  # the walk names the record that does not fit
    for i, p in enumerate(e.props):
        if p.count_type is None:
            fields.append((f"f{i}", p.type.newbyteorder(order)))
        else:
            fields.append((f"n{i}", p.count_type.newbyteorder(order)))
            fields.append((f"f{i}", p.type.newbyteorder(order), (k,)))
    dt = np.dtype(fields)
    if pos + e.count * dt.itemsize > len(data):
        if li is None:
            raise _Malformed(f"element {e.name!r} is truncated: {e.count:,} records of {dt.itemsize} bytes need "
                             f"{e.count * dt.itemsize:,} bytes from offset {pos:,}; the file has {len(data):,}")
        return None  # lengths differ (or the file is truncated: the walk says where)
    rec = np.frombuffer(data, dt, e.count, pos)
    if li is not None and not (rec[f"n{li}"] == k).all():
        return None
    values = _Values({}, {})
    for i, p in enumerate(e.props):
        if p.count_type is None:
            values.scalars[p.name] = rec[f"f{i}"]
        else:
            values.lists[p.name] = (np.full(e.count, k, np.int64), rec[f"f{i}"].reshape(-1))
    return values, pos + e.count * dt.itemsize


def _read_binary_walk(data: bytes, pos: int, e: _Element, order: str) -> tuple[_Values, int]:
    """Records of mixed sizes: one Python step per record finds where each property starts, then
    every property is gathered with numpy."""
    n, m = e.count, len(e.props)
    starts = np.empty((n, m), np.int64)
    lengths = np.zeros((n, m), np.int64)
    codes = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I"}
    formats = [None if p.count_type is None else struct.Struct(order + codes[p.count_type.str[1:]]) for p in e.props]
    size, at = len(data), pos
    for r in range(n):
        for j, p in enumerate(e.props):
            starts[r, j] = at
            fmt = formats[j]
            if fmt is None:
                at += p.type.itemsize
            elif at + fmt.size <= size:
                k = fmt.unpack_from(data, at)[0]
                if k < 0:
                    raise _Malformed(f"element {e.name!r} record {r:,}: list {p.name!r} has the negative length {k}")
                lengths[r, j] = k
                at += fmt.size + k * p.type.itemsize
            else:
                at = size + 1
            if at > size:
                raise _Malformed(f"element {e.name!r} is truncated: record {r:,} of {n:,} runs past the end of "
                                 "the file")
    raw = np.frombuffer(data, np.uint8)
    values = _Values({}, {})
    for j, p in enumerate(e.props):
        if p.count_type is None:
            values.scalars[p.name] = _gather(raw, starts[:, j], np.full(n, p.type.itemsize),
                                             p.type.newbyteorder(order))
        else:
            values.lists[p.name] = (lengths[:, j], _gather(raw, starts[:, j] + p.count_type.itemsize,
                                                           lengths[:, j] * p.type.itemsize, p.type.newbyteorder(order)))
    return values, at


def _ranks(lengths: np.ndarray) -> np.ndarray:
    """``[0 .. lengths[0]-1, 0 .. lengths[1]-1, ...]``."""
    total = int(lengths.sum())
    first = np.repeat(np.cumsum(lengths) - lengths, lengths)
    return np.arange(total, dtype=np.int64) - first


def _gather(raw: np.ndarray, starts: np.ndarray, nbytes: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """The values of ``dtype`` in the byte runs ``[starts, starts + nbytes)`` of ``raw``, in order
    (the runs do not overlap): one mask over the bytes, about three bytes of memory per file byte."""
    keep = nbytes > 0
    edges = np.zeros(raw.size + 1, np.int8)
    edges[starts[keep]] = 1
    edges[starts[keep] + nbytes[keep]] -= 1  # a run that starts where another ends keeps the mask on
    return raw[np.cumsum(edges[:-1], dtype=np.int8).view(bool)].view(dtype)


def _ascii_numbers(body: bytes) -> np.ndarray:
    """Every whitespace-separated token of ``body`` as float64 (raises ``_Malformed`` naming the
    first token that is not a number)."""
    raw = np.frombuffer(body, np.uint8)
    space = np.isin(raw, np.frombuffer(b" \t\r\n\v\f", np.uint8))
    n_tokens = int(np.count_nonzero(~space[:1])) + int(np.count_nonzero(space[:-1] & ~space[1:]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            vals = np.fromstring(body, dtype=np.float64, sep=" ")
        except (ValueError, DeprecationWarning):
            vals = None
    if vals is None or vals.size != n_tokens:
        for token in body.split():
            try:
                float(token)
            except ValueError:
                raise _Malformed(f"the data holds {token[:40].decode('latin-1')!r}, which is not a number") from None
        raise _Malformed("the data holds a token that is not a number")
    return vals


def _read_ascii(vals: np.ndarray, t: int, e: _Element) -> tuple[_Values, int]:
    """Element ``e``'s records from token ``t`` of ``vals`` -> (values, the token after them)."""
    lists = [i for i, p in enumerate(e.props) if p.count_type is not None]
    m = len(e.props)
    first = vals[t + lists[0]] if lists and e.count and t + lists[0] < vals.size else 0.0
    if len(lists) <= 1 and np.isfinite(first) and first >= 0 and first == int(first):
        k = int(first)  # fixed stride when every list has the first record's length
        stride = m + k
        if not lists or (t + e.count * stride <= vals.size
                         and (vals[t + lists[0]: t + e.count * stride: stride] == k).all()):
            if t + e.count * stride > vals.size:
                raise _Malformed(f"element {e.name!r} is truncated: {e.count:,} records need {e.count * stride:,} "
                                 f"values; {vals.size - t:,} remain")
            block = vals[t: t + e.count * stride].reshape(e.count, stride)
            values = _Values({}, {})
            col = 0
            for p in e.props:
                if p.count_type is None:
                    values.scalars[p.name] = _integral(block[:, col], p.type, e, p)
                    col += 1
                else:
                    values.lists[p.name] = (np.full(e.count, k, np.int64),
                                            _integral(block[:, col + 1: col + 1 + k].reshape(-1), p.type, e, p))
                    col += 1 + k
            return values, t + e.count * stride
    return _read_ascii_walk(vals, t, e)


def _read_ascii_walk(vals: np.ndarray, t: int, e: _Element) -> tuple[_Values, int]:
    """Records whose lists differ in length: one Python step per record."""
    n, m = e.count, len(e.props)
    starts = np.empty((n, m), np.int64)
    lengths = np.zeros((n, m), np.int64)
    size = vals.size
    for r in range(n):
        for j, p in enumerate(e.props):
            if t >= size:
                raise _Malformed(f"element {e.name!r} is truncated: record {r:,} of {n:,} is missing values")
            starts[r, j] = t
            if p.count_type is None:
                t += 1
                continue
            k = vals[t]
            if not (np.isfinite(k) and k >= 0 and k == int(k)):
                raise _Malformed(f"element {e.name!r} record {r:,}: list {p.name!r} has the length {k!r}")
            if t + 1 + k > size:
                raise _Malformed(f"element {e.name!r} is truncated: record {r:,} of {n:,} declares {int(k):,} "
                                 f"values in list {p.name!r}; {size - t - 1:,} remain")
            lengths[r, j] = int(k)
            t += 1 + int(k)
    if t > size:
        raise _Malformed(f"element {e.name!r} is truncated: its last record is missing values")
    values = _Values({}, {})
    for j, p in enumerate(e.props):
        if p.count_type is None:
            values.scalars[p.name] = _integral(vals[starts[:, j]], p.type, e, p)
        else:
            offs = np.repeat(starts[:, j] + 1, lengths[:, j]) + _ranks(lengths[:, j])
            values.lists[p.name] = (lengths[:, j], _integral(vals[offs], p.type, e, p))
    return values, t


def _integral(v: np.ndarray, t: np.dtype, e: _Element, p: _Property) -> np.ndarray:
    """ASCII values of property ``p``: as its integer type when it has one (they must be integers
    in that type's range), else float64 (the text's value, whatever the declared precision)."""
    if t.kind not in "iu":
        return v
    info = np.iinfo(t)
    bad = ~((v == np.floor(v)) & (v >= info.min) & (v <= info.max))
    if bad.any():
        raise _Malformed(f"element {e.name!r} property {p.name!r} ({t.name}): the value "
                         f"{v[np.flatnonzero(bad)[0]]!r} is not an integer in [{info.min}, {info.max}]")
    return v.astype(t)


# ---------------------------------------------------------------------------------------------
# Scene
# ---------------------------------------------------------------------------------------------


def load(path: str, *, fmt: str = "ply", settings: IngestSettings) -> Scene:
    """Read one PLY file into an unvalidated Scene (module doc): one part, positions (n, 3)
    float64, indices (m, 3) uint32, optional normals (n, 3), uvs (n, 2), colours (n, 4)."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise LopcookError("ingest", path, f"cannot read file: {exc.strerror or exc}",
                           hint="check the path and permissions") from None
    try:
        return _scene(path, data, settings)
    except _Malformed as exc:
        raise LopcookError("ingest", path, str(exc), hint=_HINT) from None
    except PolygonTooComplex as exc:
        raise LopcookError("ingest", path, str(exc), hint=exc.hint) from None


def _scene(path: str, data: bytes, settings: IngestSettings) -> Scene:
    """The steps of ``load``: header, element data, the one part."""
    header = _read_header(data)
    _check_sizes(header, len(data) - header.size)
    found, notes = _elements(data, header)
    deps = DependencyList(path)
    if "vertex" not in found:
        raise _Malformed("the header declares no 'vertex' element")
    vertex, face = found["vertex"], found.get("face")
    faces = None if face is None else next((face.lists[n] for n in ("vertex_indices", "vertex_index")
                                            if n in face.lists), None)
    if faces is None:
        notes.append("no 'face' element with a vertex_indices list: a point cloud, nothing to mesh")
        return Scene(parts=(), source=path, format="ply", unit_scale=1.0, up_axis="Y",
                     warnings=tuple(notes), dependencies=deps.paths())
    positions = _positions(vertex)
    tris = _triangles(faces, positions, notes, settings)
    used, tris = np.unique(tris, return_inverse=True)
    texture = _texture(path, header.texture, deps, notes)
    part = make_part(os.path.splitext(os.path.basename(path))[0] or "ply", positions[used],
                     tris.reshape(-1, 3), settings=settings, normals=_attribute(vertex, (("nx", "ny", "nz"),), used),
                     uvs=_uvs(vertex, used), colors=_colors(vertex, used, notes), source="(whole file)",
                     texture=texture, mesh_key=f"ply:{os.path.basename(path)}")
    return Scene(parts=(part,), source=path, format="ply", unit_scale=1.0, up_axis="Y",
                 warnings=tuple(notes), dependencies=deps.paths())


def _elements(data: bytes, header: _Header) -> tuple[dict[str, _Values], list[str]]:
    """``({element name: values} (the first element of a name), warnings)``; the face indices'
    item type must be an integer type."""
    for e in header.elements:
        for p in e.props:
            if e.name == "face" and p.name in ("vertex_indices", "vertex_index") and p.type.kind not in "iu":
                raise _Malformed(f"face property {p.name!r} holds items of type {p.type.name}; vertex indices "
                                 "must be of an integer type")
    found: dict[str, _Values] = {}
    notes: list[str] = []
    if header.encoding is None:
        vals, t = _ascii_numbers(data[header.size:]), 0
        for e in header.elements:
            values, t = _read_ascii(vals, t, e)
            found.setdefault(e.name, values)
        if t < vals.size:
            notes.append(f"{vals.size - t:,} values after the last element were ignored")
    else:
        pos = header.size
        for e in header.elements:
            values, pos = _read_binary(data, pos, e, header.encoding)
            found.setdefault(e.name, values)
        if pos < len(data):
            notes.append(f"{len(data) - pos:,} bytes after the last element were ignored")
    return found, notes


def _positions(vertex: _Values) -> np.ndarray:
    if not all(c in vertex.scalars for c in "xyz"):
        raise _Malformed("the vertex element has no x, y and z properties")
    return np.stack([vertex.scalars[c].astype(np.float64) for c in "xyz"], axis=1)


def _triangles(faces: tuple[np.ndarray, np.ndarray], positions: np.ndarray, notes: list[str],
               settings: IngestSettings) -> np.ndarray:
    """(T, 3) int64 vertex indices of the faces' triangles, in face order."""
    counts, corners = faces
    corners = corners.astype(np.int64)  # integers (ASCII: checked integral in their type's range)
    n = positions.shape[0]
    bad = (corners < 0) | (corners >= n)
    if bad.any():
        at = int(np.flatnonzero(bad)[0])
        face = int(np.searchsorted(np.cumsum(counts), at, side="right"))
        raise _Malformed(f"face {face:,} refers to vertex {int(corners[at])}, out of range for {n:,} vertices")
    small = counts < 3
    if small.any():
        notes.append(f"{int(small.sum()):,} faces with fewer than 3 corners skipped")
        keep = np.repeat(~small, counts)
        counts, corners = counts[~small], corners[keep]
    n_tris = int((counts - 2).sum()) if counts.size else 0
    if n_tris > settings.max_triangles:
        raise _Malformed(f"the faces make {n_tris:,} triangles, more than the {settings.max_triangles:,} "
                         "lopcook accepts (--max-triangles)")
    if counts.size and (counts == 3).all():
        return corners.reshape(-1, 3)
    tri_corners, _ = triangulate(counts, positions[corners])
    return corners[tri_corners]


def _attribute(vertex: _Values, names: tuple[tuple[str, ...], ...], used: np.ndarray) -> np.ndarray | None:
    """(len(used), k) float64 of the first name set all of whose properties the vertex has."""
    for group in names:
        if all(n in vertex.scalars for n in group):
            return np.stack([vertex.scalars[n][used].astype(np.float64) for n in group], axis=1)
    return None


def _uvs(vertex: _Values, used: np.ndarray) -> np.ndarray | None:
    uv = _attribute(vertex, UV_NAMES, used)
    if uv is not None:
        uv[:, 1] = 1.0 - uv[:, 1]
    return uv


def _colors(vertex: _Values, used: np.ndarray, notes: list[str]) -> np.ndarray | None:
    """(len(used), 3|4) colours in [0, 1]: integers over their type's maximum, floats clipped."""
    for names in COLOR_NAMES:
        have = [n for n in names if n in vertex.scalars]
        if have[:3] != list(names[:3]):
            continue
        cols = []
        for n in have:
            v = vertex.scalars[n][used]
            cols.append(v / float(np.iinfo(v.dtype).max) if v.dtype.kind in "iu" else v.astype(np.float64))
        rgba = np.stack(cols, axis=1)
        if not np.isfinite(rgba).all() or (rgba < 0).any() or (rgba > 1).any():
            notes.append("vertex colours outside [0, 1] (or not finite) were clipped")
            rgba = np.clip(np.nan_to_num(rgba, nan=0.0), 0.0, 1.0)
        return rgba
    return None


def _texture(path: str, name: str | None, deps: DependencyList, notes: list[str]) -> Texture | None:
    """The ``comment TextureFile`` image beside the .ply, or None (a warning when it is missing
    or does not decode)."""
    if not name:
        return None
    file = os.path.join(os.path.dirname(path), name.replace("\\", "/"))
    deps.add_path(file)  # listed even when missing: a build must rerun when it appears
    problem = regular_file_problem(file)
    if problem is not None:
        notes.append(f"texture {name!r} {problem}; the part has no texture")
        return None
    return checked_texture(os.path.basename(file), Path(file).read_bytes(), notes.append, f"texture {name!r}")


# ---------------------------------------------------------------------------------------------
# Materials for decoded previews (docs/format.md 9.2)
# ---------------------------------------------------------------------------------------------


def materials(path: str, parts: list[dict], out: MaterialSet) -> list[dict | None]:
    """PLY has no materials: every part gets a dielectric one (base colour white, metallic 0,
    roughness 1, so vertex colours show as stored) with the ``comment TextureFile`` image as base
    colour texture when it is there and decodes. Raises ``OSError``/``ValueError`` for an
    unreadable file."""
    with open(path, "rb") as fh:
        head = fh.read(MAX_HEADER_BYTES)
    try:
        header = _read_header(head)
    except _Malformed as exc:
        raise ValueError(str(exc)) from None
    pbr: dict = {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}
    if header.texture:
        file = os.path.join(os.path.dirname(os.path.abspath(path)), header.texture.replace("\\", "/"))
        if regular_file_problem(file) is None:
            t = out.texture(out.image(("file", os.path.realpath(file)),
                                      lambda: (Path(file).read_bytes(), os.path.basename(file))), None)
            if t is not None:
                pbr["baseColorTexture"] = {"index": t}
        else:
            out.warn(f"texture {header.texture!r} not found; left out of the preview")
    return [{"pbrMetallicRoughness": pbr} for _ in parts]


# ---------------------------------------------------------------------------------------------
# The format
# ---------------------------------------------------------------------------------------------

EXTENSIONS = {".ply": ("ply",)}


def sniff(head: bytes) -> str | None:
    """``"ply"`` for a file whose first line is ``ply``."""
    return "ply" if head.startswith((b"ply\n", b"ply\r\n")) else None


FORMAT = Format(name="ply", title="PLY", extensions=EXTENSIONS, load=load, sniff=sniff, materials=materials)

__all__ = ["load", "materials", "sniff", "EXTENSIONS", "FORMAT", "TYPES"]
