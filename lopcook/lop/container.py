"""The .lop container: bytes <-> (manifest, sections), with CRCs, versioning and the prefix property.

Layout (all integers little-endian; see docs/format.md and schema/container.ksy):

=========  ====  ===========================================================================
offset     size  field
=========  ====  ===========================================================================
0          4     magic ``b"LOPC"``
4          2     version major (readers refuse a major they do not know)
6          2     version minor (additions only)
8          4     header size in bytes (32)
12         4     manifest size in bytes (UTF-8 JSON)
16         4     CRC-32 of the manifest bytes
20         8     total file size in bytes
28         4     CRC-32 of header bytes 0..27
32         M     manifest: JSON (sorted keys, no whitespace), validated by schema/container.schema.json
32 + M     ...   sections, back to back, in manifest order; each section's length is a multiple of
                 4 bytes (zero padding included in its CRC-32)
=========  ====  ===========================================================================

Section offsets in the manifest are relative to the end of the manifest (``32 + M``), so the
manifest does not depend on its own size. Every byte of the file is covered by a CRC, by the
header's size field or by the file size: flipping any byte is detected.

Prefix property: the position sections come last, mandatory bits first and then refinement
planes in ascending order, so a file truncated after plane B still has a complete header,
manifest, attributes and planes up to B: ``read(..., allow_prefix=True)`` returns it with
``available_level == B`` and decodes level B exactly. In the streaming layout (version 4.0,
``lopcook.lop.layout``) every stage has its own level (``Container.stage_levels``); an encoded
section (``lopcook.lop.encoding``) is decoded as soon as it is complete.
"""

from __future__ import annotations

import json
import os
import stat
import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

from ..atomic import write_atomic  # noqa: F401  (re-exported: the writer of .lop files)
from ..errors import LopcookError
from .clusters import from_header, plane_bit, words_at
from .codecs import CODECS, AttributeBits
from .encoding import MANIFEST_MARK, EncodingError, decode_manifest, decode_section, encode_manifest
from .layout import Layout, is_stream, layout_of
from .manifest import Manifest
from .validate import validate_manifest

MAGIC = b"LOPC"
VERSION = (2, 0)  # 2.0: one packed attribute record per buffer
#: files with clustered position buffers or placement entries: a 2.x reader that
#: ignored ``cluster_size`` or ``placement`` would decode them wrongly, so they carry the next
#: major; files with neither stay 2.0, byte for byte. 3.x = may hold clusters and/or placements.
CLUSTERED_VERSION = (3, 0)
#: files in the streaming layout or with encoded sections (docs/format.md 14, 15): a 3.x reader
#: would misplace every position bit or read compressed bytes as data
STREAM_VERSION = (4, 0)
#: the minor that an earlier build wrote for placements without clusters (2.1); still read
PLACEMENT_MINOR = 1
#: majors this reader reads: 2, 3, and those that attribute codecs introduced (``Codec.format_major``)
READABLE_MAJORS = tuple(range(VERSION[0], max([STREAM_VERSION[0]] + [c.format_major for c in CODECS]) + 1))
HEADER_SIZE = 32
_HEADER = struct.Struct("<4sHHIIIQ")  # 28 bytes, then the header CRC


def _pad4(data: bytes) -> bytes:
    return data + b"\0" * (-len(data) % 4)


def manifest_bytes(manifest: dict) -> bytes:
    """Canonical JSON: sorted keys, compact separators, ASCII only (deterministic bytes)."""
    return json.dumps(manifest, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False).encode("ascii")


@dataclass
class Container:
    """A parsed container. ``manifest`` is the JSON object; ``sections`` maps name -> payload bytes
    (padding included) for every section present; ``available_level`` is the highest per-buffer
    level whose planes are all present (24, or the manifest's max level, for a complete file)."""

    manifest: dict
    sections: dict = field(default_factory=dict)
    available_level: int = 0
    path: str | None = None
    stage_levels: list = field(default_factory=list)
    data: bytes | None = field(default=None, repr=False)
    result: object = field(default=None, repr=False)

    @property
    def entries(self):
        """The typed view of the manifest (``lopcook.lop.manifest.Manifest``): parts, LODs and
        their byte accounting."""
        return Manifest.of(self.manifest)

    @property
    def file_size(self) -> int:
        """The file's size as its header gives it (more than ``len(data)`` for a prefix)."""
        return int(struct.unpack_from("<Q", self.data, 20)[0]) if self.data else 0

    @property
    def is_prefix(self) -> bool:
        """Whether these bytes are a prefix of the file (format.md 8): some sections have not arrived."""
        return self.data is not None and len(self.data) < self.file_size

    def section_end(self, name: str) -> int:
        """The file offset just after section ``name`` (where a prefix must end to hold it)."""
        base = HEADER_SIZE + int(struct.unpack_from("<I", self.data, 12)[0])
        t = next(t for t in self.manifest["sections"] if t["name"] == name)
        return base + int(t["offset"]) + int(t["length"])

    @property
    def layout(self) -> Layout:
        """Where every buffer's position bits lie (``lopcook.lop.layout``; cached)."""
        if "_layout" not in self.__dict__:
            self.__dict__["_layout"] = layout_of(self.manifest)
        return self.__dict__["_layout"]

    @property
    def stream(self) -> bool:
        """Whether the container is in the streaming layout (docs/format.md 14)."""
        return is_stream(self.manifest)

    def level_of(self, part: int, lod: int) -> int:
        """The highest level buffer (part, lod) decodes at in these bytes: its stage's level
        (``available_level`` in the default layout); 0 when its sections have not arrived."""
        k = min(int(lod), len(self.manifest["parts"][part]["lods"]) - 1)
        return int(self.stage_levels[self.layout.stage_of[(int(part), k)]])

    def write(self, path) -> None:
        """Write the container's bytes to ``path`` atomically (a temp file, then a rename)."""
        if self.data is None:
            raise LopcookError("container", self.path, "this container holds no bytes to write",
                               hint="read it with lopcook.read or cook it with lopcook.cook")
        write_atomic(str(path), self.data)

    def section(self, name: str) -> bytes:
        try:
            return self.sections[name]
        except KeyError:
            raise LopcookError("container", self.path, f"section {name!r} is missing from the container "
                               f"(the file holds levels up to {self.available_level})") from None


def section_table(sections: list[tuple]) -> tuple[list[dict], list[bytes]]:
    """The manifest's ``sections`` table (name, offset, length, crc32) and the padded stored
    payloads. ``sections``: ``(name, bytes)``, or ``(name, stored bytes, {"encoding", "size"})``
    for an encoded section (``lopcook.lop.encoding``)."""
    table = []
    offset = 0
    payloads = []
    for name, data, *fields in sections:
        data = _pad4(bytes(data))
        table.append({"name": name, "offset": offset, "length": len(data), "crc32": zlib.crc32(data),
                      **(fields[0] if fields else {})})
        payloads.append(data)
        offset += len(data)
    return table, payloads


def file_size(manifest: dict, table: list[dict]) -> int:
    """Bytes of the file ``to_bytes`` writes for ``manifest`` with the section table ``table``."""
    return HEADER_SIZE + len(manifest_bytes(dict(manifest, sections=table))) + sum(t["length"] for t in table)


def is_clustered(manifest: dict) -> bool:
    """Whether the manifest holds clustered position buffers (``positions.clusters`` present)."""
    pos = manifest.get("positions") if isinstance(manifest, dict) else None
    return isinstance(pos, dict) and "clusters" in pos


def has_placements(manifest: dict) -> bool:
    """Whether the manifest holds placement entries (``cook --instances``)."""
    parts = manifest.get("parts") if isinstance(manifest, dict) else None
    return isinstance(parts, list) and any(isinstance(p, dict) and "placement" in p for p in parts)


def attributes_major(manifest: dict) -> int:
    """The lowest major that can hold the manifest's attribute codecs (``Codec.format_major``)."""
    return max([VERSION[0]] + [AttributeBits.of(p.get("attribute_bits") or {}).format_major
                               for p in manifest.get("parts", [])])


def has_encoded(manifest: dict) -> bool:
    """Whether a section of the manifest's table is encoded (docs/format.md 15)."""
    table = manifest.get("sections") if isinstance(manifest, dict) else None
    return isinstance(table, list) and any(isinstance(t, dict) and ("encoding" in t or "size" in t) for t in table)


def version_of(manifest: dict) -> tuple[int, int]:
    """The version a file with this manifest is written as: the oldest that reads it correctly
    (``STREAM_VERSION`` in the streaming layout or with encoded sections, ``CLUSTERED_VERSION``
    with clustered buffers or placements, else ``VERSION``; a later major when an attribute codec
    needs it)."""
    if is_stream(manifest) or has_encoded(manifest):
        base = STREAM_VERSION
    else:
        base = CLUSTERED_VERSION if is_clustered(manifest) or has_placements(manifest) else VERSION
    major = attributes_major(manifest)
    return base if major <= base[0] else (major, 0)


def to_bytes(manifest: dict, sections: list[tuple[str, bytes]], table=None) -> bytes:
    """Serialise: fills ``manifest["sections"]`` (name, offset, length, crc32) and returns the file.
    ``table``: ``section_table(sections)`` when the caller has it already."""
    table, payloads = table or section_table(sections)
    offset = sum(t["length"] for t in table)
    manifest = dict(manifest)
    manifest["sections"] = table
    mbytes = manifest_bytes(manifest)
    if is_stream(manifest):  # the one thing every reader fetches first: stored encoded (format.md 4)
        mbytes = encode_manifest(mbytes)
    total = HEADER_SIZE + len(mbytes) + offset
    major, minor = version_of(manifest)
    head = _HEADER.pack(MAGIC, major, minor, HEADER_SIZE, len(mbytes), zlib.crc32(mbytes), total)
    head += struct.pack("<I", zlib.crc32(head))
    return b"".join([head, mbytes, *payloads])


def built(manifest: dict, sections: list[tuple[str, bytes]], path: str | None = None) -> Container:
    """The Container of a manifest and sections just assembled, with its bytes, without parsing
    them back (``to_bytes`` followed by ``from_bytes`` gives an equal Container)."""
    table, payloads = section_table(sections)
    data = to_bytes(manifest, sections, (table, payloads))
    full = json.loads(manifest_bytes(dict(manifest, sections=table)))
    lods = _index_lods(full)
    decoded = {t["name"]: p if "encoding" not in t else decode_section(t, p, lods.get(t["name"]))
               for t, p in zip(table, payloads)}
    c = Container(manifest=full, sections=decoded, path=path, data=data)
    c.stage_levels = c.layout.levels(decoded)
    c.available_level = _available_level(c)
    return c


def _no_duplicates(pairs):
    obj = {}
    for key, value in pairs:
        if key in obj:
            raise ValueError(f"duplicate key {key!r}")
        obj[key] = value
    return obj


def _no_constants(name):
    raise ValueError(f"{name} is not a JSON number")


def from_bytes(data: bytes, path: str | None = None, *, allow_prefix: bool = False) -> Container:
    """Parse and check a container. Any corruption raises LopcookError (exit code 2).

    With ``allow_prefix`` a file truncated inside the position planes is accepted: sections that
    are complete and pass their CRC are kept, and ``available_level`` tells which level they hold.
    """

    def fail(reason: str, msg: str,
             hint: str = "the file is corrupt or not a lopcook container; cook it again") -> None:
        raise LopcookError("container", path, msg, hint=hint, reason=reason)

    data = bytes(data)
    if len(data) < HEADER_SIZE:
        fail("truncated", f"file is {len(data)} bytes, shorter than the {HEADER_SIZE}-byte header")
    magic, major, minor, hsize, msize, mcrc, total = _HEADER.unpack_from(data, 0)
    if magic != MAGIC:
        fail("bad_magic", f"bad magic {magic!r} (expected {MAGIC!r})", "this is not a .lop container")
    (hcrc,) = struct.unpack_from("<I", data, 28)
    if zlib.crc32(data[:28]) != hcrc:
        fail("header_crc", "header checksum mismatch")
    if major not in READABLE_MAJORS:
        fail("version", f"container version {major}.{minor} is not supported (this lopcook reads "
             f"{' and '.join(f'{v}.x' for v in READABLE_MAJORS)})",
             "use a lopcook release that reads this version, or cook the source again")
    if hsize != HEADER_SIZE:
        fail("header", f"header size {hsize} (expected {HEADER_SIZE})")
    if len(data) > total:
        fail("trailing_data", f"{len(data) - total} bytes of trailing data after the declared end ({total} bytes)")
    truncated = len(data) < total
    if truncated and not allow_prefix:
        fail("truncated", f"file is truncated: {len(data)} of {total} bytes", "the copy is incomplete; cook it again")
    if HEADER_SIZE + msize > len(data):
        fail("truncated", "manifest is truncated")
    mbytes = data[HEADER_SIZE:HEADER_SIZE + msize]
    if zlib.crc32(mbytes) != mcrc:
        fail("manifest_crc", "manifest checksum mismatch")
    manifest = _parse_manifest(mbytes, major, minor, fail)
    validate_manifest(manifest, path)
    if major == VERSION[0] and is_clustered(manifest):
        fail("version", f"container version {major}.{minor} must not hold clustered position buffers (they need 3.x)")
    if major == VERSION[0] and has_placements(manifest) and minor < PLACEMENT_MINOR:
        fail("version", f"container version {major}.{minor} must not hold placements (they need 3.x)")
    if major < attributes_major(manifest):
        fail("version", f"container version {major}.{minor} must not hold the attributes it lists (they need "
             f"{attributes_major(manifest)}.x)")
    if major < STREAM_VERSION[0] and (is_stream(manifest) or has_encoded(manifest)):
        fail("version", f"container version {major}.{minor} must not hold the streaming layout or encoded sections (they "
             f"need {STREAM_VERSION[0]}.x)")
    sections, expected_end = _read_sections(data, HEADER_SIZE + msize, manifest, truncated, fail)
    if expected_end != total:  # a prefix's manifest lists every section, so its end is known too
        fail("section_table", f"sections end at byte {expected_end}, file size says {total}")
    _check_index_values(manifest, sections, fail)
    container = Container(manifest=manifest, sections=sections, path=path, data=data)
    _check_cluster_sizes(container, fail)
    container.stage_levels = container.layout.levels(sections)
    container.available_level = _available_level(container)
    if container.stage_levels[0] < 1:
        fail("truncated", "the file ends before the first stage's mandatory position bits" if container.stream
             else "the file ends before the mandatory position bits", "the copy is incomplete; cook it again")
    return container


def manifest_text(stored: bytes, major: int = STREAM_VERSION[0]) -> bytes:
    """The JSON text of a manifest's stored bytes: as they are, or decoded when encoded (a 4.x
    file's manifest may be: docs/format.md 4). EncodingError for an encoded manifest that does not
    decode; ValueError for one in a file older than 4.x."""
    if not stored[:1] == bytes([MANIFEST_MARK]):
        return bytes(stored)
    if major < STREAM_VERSION[0]:
        raise ValueError(f"an encoded manifest needs {STREAM_VERSION[0]}.x")
    return decode_manifest(bytes(stored))


def manifest_of(data: bytes) -> dict:
    """The manifest of a container's bytes, unchecked (for tools that edit files: the checks are
    ``from_bytes``'s)."""
    msize, major = struct.unpack_from("<I", data, 12)[0], struct.unpack_from("<H", data, 4)[0]
    return json.loads(manifest_text(data[HEADER_SIZE:HEADER_SIZE + msize], major))


def _parse_manifest(mbytes: bytes, major: int, minor: int, fail) -> dict:
    """The manifest object of its stored bytes (decoded when encoded), strict JSON."""
    try:
        text = manifest_text(mbytes, major)
    except ValueError as exc:  # EncodingError included
        if isinstance(exc, EncodingError):
            fail("encoding", f"manifest (encoded): {exc}")
        fail("version", f"container version {major}.{minor} must not hold an encoded manifest (it needs "
             f"{STREAM_VERSION[0]}.x)")
    try:
        return json.loads(text.decode("ascii"), object_pairs_hook=_no_duplicates, parse_constant=_no_constants)
    except (UnicodeDecodeError, ValueError) as exc:
        fail("manifest_json", f"manifest is not valid JSON ({' '.join(str(exc).split())[:160]})")
    except RecursionError:
        fail("manifest_json", "manifest JSON is nested too deeply")


def _index_lods(manifest: dict) -> dict:
    """{index section name: (triangles, index_width, vertices)} of every LOD (what a
    ``meshopt-deflate`` section decodes with)."""
    return {e["indices"]: (e["triangles"], e["index_width"], e["vertices"])
            for part in manifest["parts"] for e in part["lods"]}


def _read_sections(data: bytes, base: int, manifest: dict, truncated: bool, fail) -> tuple[dict, int]:
    """{name: decoded payload} of every complete section (CRC checked, encoded ones decoded), up
    to the first incomplete one in a truncated file; and where the whole table says the sections
    end (a prefix's too)."""
    sections: dict = {}
    expected_end = base
    lods = None
    arrived = True
    for entry in manifest["sections"]:
        start = base + entry["offset"]
        if start != expected_end:
            fail("section_table", f"section {entry['name']!r} does not follow the previous one")
        end = start + entry["length"]
        expected_end = end
        if arrived and end > len(data):
            if not truncated:
                fail("section_table", f"section {entry['name']!r} runs past the end of the file")
            arrived = False  # a prefix: the rest of the table is checked, not read
        if not arrived:
            continue
        payload = data[start:end]
        if zlib.crc32(payload) != entry["crc32"]:
            fail("section_crc", f"section {entry['name']!r} checksum mismatch")
        if "encoding" in entry:
            lods = lods if lods is not None else _index_lods(manifest)
            try:
                payload = decode_section(entry, payload, lods.get(entry["name"]))
            except EncodingError as exc:
                fail("encoding", f"section {entry['name']!r} ({entry['encoding']}): {exc}")
        sections[entry["name"]] = payload
    return sections, expected_end


def _check_index_values(manifest: dict, sections: dict, fail) -> None:
    """Every index of every LOD present is below its vertex count (a semantic check on the
    payload: the manifest validator has already checked the section sizes). O(indices), one
    vectorised max per LOD."""
    for i, part in enumerate(manifest["parts"]):
        for k, lod in enumerate(part["lods"]):
            data = sections.get(lod["indices"])
            if data is None:
                continue
            dtype = "<u2" if lod["index_width"] == 2 else "<u4"
            idx = np.frombuffer(data, dtype=dtype, count=3 * lod["triangles"])
            if idx.size and int(idx.max()) >= lod["vertices"]:
                fail("indices", f"part {i} LOD {k}: index {int(idx.max())} is out of range for {lod['vertices']} vertices")


def _check_cluster_sizes(c: Container, fail) -> None:
    """With clustered buffers, per stage whose cluster headers have arrived: every header is sound
    (k <= 24, anchors within k bits), and ``cluster_p_words``, ``cluster_plane_bits`` and every
    plane present are exactly what the headers say (the manifest alone cannot say it).
    Vectorised per buffer."""
    sections, max_level = c.sections, c.layout.max_level
    for st in c.layout.stages:
        if st.clusters is None or st.clusters not in sections:
            continue
        head = np.frombuffer(sections[st.clusters], "<u4")
        for i, k, lod in st.buffers:
            if "cluster_size" not in lod:
                continue
            vid = np.asarray(lod["vertex_id"], dtype=np.int64)
            off, count = lod["cluster_words"]
            try:
                cl = from_header(head[off:off + count], vid, lod["cluster_size"])
            except ValueError as exc:
                fail("clusters", f"part {i} LOD {k}: cluster headers: {exc}")
            if lod["cluster_p_words"] != [words_at(cl, b) for b in range(1, 25)]:
                fail("clusters", f"part {i} LOD {k}: cluster_p_words (mandatory_words count {lod['mandatory_words'][1]}) "
                     f"do not match its clusters ({words_at(cl, 1)} words at level 1)")
            if lod["cluster_plane_bits"] != [int(plane_bit(cl, p)[-1]) for p in range(2, 25)]:
                fail("clusters", f"part {i} LOD {k}: cluster_plane_bits do not match its clusters")
        if c.layout.stream:
            continue  # validate_manifest checked every plane's exact length against cluster_plane_bits
        for p in range(2, max_level + 1):
            name = st.planes[p]
            if name in sections and len(sections[name]) != 4 * ((st.bits[p] + 31) // 32):
                fail("clusters", f"refinement plane {p} is not the {st.bits[p]} bits its buffers hold")


def _available_level(c: Container) -> int:
    """The level every buffer decodes at: the default layout's one stage level; in the streaming
    layout the lowest stage level (0 while a stage has not arrived; ``Container.level_of`` gives
    each buffer's own)."""
    return int(min(c.stage_levels))


#: the largest file ``read`` takes, bytes (16 GiB): about twice the largest container of a scene
#: at ingest's limits (``types.MAX_TRIANGLES`` = 50M triangles of unshared vertices, every position
#: plane, a 129-bit attribute record and 4-byte indices: 4.4 GB, a full LOD chain at most doubling
#: it); a larger file is refused before any of it is read, as sources over their limits are
MAX_FILE_BYTES = 1 << 34


def read(path: str, *, allow_prefix: bool = False) -> Container:
    """Read and check a .lop file (see from_bytes). Like a source (``ingest.sniff``), it must be a
    regular file of at most ``MAX_FILE_BYTES``: a FIFO, a device (``/dev/zero``) or a socket, also
    through a symlink, is refused without a byte read from it (opened non-blocking, so a FIFO
    with no writer cannot hang the read). A file whose header shows it is no container (too short,
    bad magic, header CRC) is refused on those 32 bytes, with the class the whole file would get;
    any other is read once, up to the size it had when opened (a file that grows meanwhile
    cannot grow the read)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise LopcookError("container", path, "file not found", hint="check the path") from None
    except IsADirectoryError:
        raise LopcookError("container", path, "is a directory, not a .lop file") from None
    except OSError as exc:
        raise LopcookError("container", path, f"cannot be read ({exc.strerror or 'error'})",
                           hint="check the path and permissions") from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        if stat.S_ISDIR(st.st_mode):
            raise LopcookError("container", path, "is a directory, not a .lop file")
        if not stat.S_ISREG(st.st_mode):
            raise LopcookError("container", path, "is not a regular file (a device, FIFO or socket)",
                               hint="give the path of a .lop file on disk")
        if st.st_size > MAX_FILE_BYTES:
            raise LopcookError("container", path, f"file is {st.st_size:,} bytes, more than the {MAX_FILE_BYTES:,} "
                               "a container may have", hint="the file is not a lopcook container, or is corrupt")
        try:
            head = fh.read(HEADER_SIZE)
            if len(head) < HEADER_SIZE or head[:4] != MAGIC or zlib.crc32(head[:28]) != struct.unpack_from(
                    "<I", head, 28)[0]:
                return from_bytes(head, path, allow_prefix=allow_prefix)  # refused on these bytes alone
            data = head + fh.read(st.st_size + 1 - HEADER_SIZE)  # one byte more: a file that grew shows it
        except MemoryError:
            raise LopcookError("container", path, f"its {st.st_size:,} bytes do not fit in the memory this "
                               "process may use", hint="free memory or raise the limit, then read it again") from None
        except OSError as exc:
            raise LopcookError("container", path, f"cannot be read ({exc.strerror or 'error'})") from None
    return from_bytes(data, path, allow_prefix=allow_prefix)
