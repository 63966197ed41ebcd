"""The run-time checks of a container manifest: one validator per record (docs/format.md 12).

``validate_manifest(m, path)`` is the one check every read of a container runs
(``container.from_bytes``), so that decode, inspect and verify may index the manifest without
further checks. It raises one ``LopcookError("container", path, "manifest: ...")`` naming the
first field that is wrong.

Schema level: every field a reader uses (the decoding fields, and the informative ``source``,
``generator``, ``viewing``, ``options``, ``stats`` and ``savings`` that ``inspect`` shows) has its
JSON type; integers are not booleans or floats. Semantic level: the grid finite, its extent at
least ``MIN_EXTENT`` and ``|origin| + extent <= MAX_GRID_REACH``; sections back to back in
manifest order, names unique, lengths multiples of 4, an encoded section's ``encoding`` and
``size`` within their bounds; the position sections last, mandatory then planes in level order (in
the streaming layout: the exact section list of its stages); every LOD's ``vertex_id``, ``mandatory_words``, index width, section
lengths, attribute bits (by codec: ``lopcook.lop.codecs``) and cluster records consistent; a
placement's transform, grid and level shift. This module is strict rather than the readers
tolerant: a manifest that lacks an informative field the schema requires is refused.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import LopcookError
from ..grid import MIN_EXTENT
from .codecs import CODECS, AttributeBits
from .encoding import DEFLATE_MAX_RATIO, ENCODINGS, MESHOPT, TABLE_BYTES
from .layout import is_stream, layout_of, plane_bytes
from .manifest import FORMAT, LEVELS
from .placement import level_shift, sigma, split

#: largest finite float32: every float the decoders compute with must stay below it
F32_MAX = 3.4028234663852886e38
#: |origin| + extent of any grid lopcook writes: its positions lie within
#: ``types.MAX_COORDINATE`` (2^100 m) of the origin, so the grid reaches at most twice that
MAX_GRID_REACH = 2.0 ** 102
#: fields of a placement's LOD entry that are its own; every other field names or describes the
#: buffer it shares with its owner and must equal the owner's
SHARED_OWN_FIELDS = ("geometric_error_m", "min_distance_m")


def is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def is_num(v, limit: float = F32_MAX) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and abs(v) <= limit


class _Checker:
    """The failure and typed-field helpers every validator shares (``path`` names the file;
    ``reason`` is the error class a failure reports, docs/format.md section 12.1)."""

    def __init__(self, path: str | None):
        self.path = path
        self.reason = "manifest"

    def fail(self, msg: str) -> None:
        raise LopcookError("container", self.path, f"manifest: {msg}", hint="the file is corrupt; cook it again",
                           reason=self.reason)

    def need(self, obj, key, kind, where):
        if not isinstance(obj, dict) or key not in obj:
            self.fail(f"{where}: missing {key!r}")
        val = obj[key]
        if kind is int and not is_int(val):
            self.fail(f"{where}.{key} must be an integer")
        if kind is float and not is_num(val):
            self.fail(f"{where}.{key} must be a finite number within the float32 range")
        if kind not in (int, float) and (not isinstance(val, kind) or isinstance(val, bool)):
            self.fail(f"{where}.{key} has the wrong type")
        return val

    def count(self, obj, key, where, minimum=0):
        val = self.need(obj, key, int, where)
        if val < minimum:
            self.fail(f"{where}.{key} is {val}, expected at least {minimum}")
        return val


def validate_manifest(m, path: str | None) -> None:
    """Raise LopcookError("container", path, ...) unless the manifest is sound (module doc)."""
    c = _Checker(path)
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        c.fail(f"format is not {FORMAT!r}")
    check_informative(m, c)
    length = check_sections(m, c)
    extent = check_grid(m, c)
    pos = check_positions(m, c, length)
    parts = c.need(m, "parts", list, "manifest")
    if not parts:
        c.fail("no parts")
    totals = _Totals(pos)
    for i, part in enumerate(parts):
        check_part(m, c, i, part, extent, length, totals)
    if is_stream(m):
        check_stream_layout(m, c, length, totals)
    else:
        totals.check_lengths(c, pos, length)
    check_encoded_indices(m, c)


def check_informative(m: dict, c: _Checker) -> None:
    """``generator``, ``source``, ``viewing``, ``options``, ``stats`` and ``savings``."""
    c.need(m, "generator", str, "manifest")
    src = c.need(m, "source", dict, "manifest")
    c.need(src, "file", str, "source")
    c.need(src, "format", str, "source")
    viewing = c.need(m, "viewing", dict, "manifest")
    vp = c.need(viewing, "viewport", list, "viewing")
    if len(vp) != 2 or not all(is_int(v) and v > 0 for v in vp):
        c.fail("viewing.viewport must be two positive integers")
    fov = c.need(viewing, "fov_y_deg", float, "viewing")
    if not 0 < fov < 180:
        c.fail("viewing.fov_y_deg must be in (0, 180)")
    if not c.need(viewing, "pixel_error", float, "viewing") > 0:
        c.fail("viewing.pixel_error must be > 0")
    nearest = viewing.get("nearest_m")
    if nearest is not None and not (is_num(nearest) and nearest > 0):
        c.fail("viewing.nearest_m must be a positive number or null")
    options = c.need(m, "options", dict, "manifest")
    for key in ("analyse", "ingest"):
        if key in options and not isinstance(options[key], dict):
            c.fail(f"options.{key} must be an object")
    stats = c.need(m, "stats", dict, "manifest")
    for key in ("vertices", "triangles", "float32_position_bytes"):
        c.count(stats, key, "stats")
    hist = c.need(stats, "histogram", list, "stats")
    if len(hist) != LEVELS + 1 or not all(is_int(v) and v >= 0 for v in hist):
        c.fail("stats.histogram must be 25 counts")
    savings = m.get("savings")
    if savings is not None:
        if not isinstance(savings, dict):
            c.fail("savings must be an object or null")
        c.count(savings, "bytes_saved", "savings")
        c.need(savings, "planes_dropped", list, "savings")
        c.count(savings, "lods_dropped", "savings")


def check_sections(m: dict, c: _Checker) -> dict:
    """The section table: back to back in manifest order, unique names, lengths multiples of 4,
    32-bit CRCs, an encoded section's fields (``check_encoded``). Returns ``{name: decoded
    length}`` in table order (``size`` for an encoded section, else ``length``). Failures here are
    of class ``section_table``."""
    c.reason = "section_table"
    sections = c.need(m, "sections", list, "manifest")
    length: dict = {}
    offset = 0
    for i, s in enumerate(sections):
        name = c.need(s, "name", str, f"sections[{i}]")
        for key in ("offset", "length", "crc32"):
            c.count(s, key, f"sections[{i}]")
        if s["length"] % 4:
            c.fail(f"section {name!r} length is not a multiple of 4")
        if s["offset"] != offset:
            c.fail(f"section {name!r} starts at {s['offset']}, not where the previous one ends ({offset})")
        if s["crc32"] > 0xFFFFFFFF:
            c.fail(f"section {name!r} crc32 is not a 32-bit value")
        offset += s["length"]
        if name in length:
            c.fail(f"section {name!r} appears twice")
        length[name] = check_encoded(c, s, name)
    c.reason = "manifest"
    return length


def check_encoded(c: _Checker, s: dict, name: str) -> int:
    """An encoded section's ``encoding`` and ``size`` (docs/format.md 15): both or neither, a known
    encoding, ``size`` a multiple of 4 and, for ``deflate``, at most ``DEFLATE_MAX_RATIO`` times
    the stored length. Returns the section's decoded length."""
    if "encoding" not in s and "size" not in s:
        return s["length"]
    enc = c.need(s, "encoding", str, f"section {name!r}")
    size = c.count(s, "size", f"section {name!r}")
    if enc not in ENCODINGS:
        c.fail(f"section {name!r} has the unknown encoding {enc!r} (known: {', '.join(ENCODINGS)})")
    if size % 4:
        c.fail(f"section {name!r} size is not a multiple of 4")
    if enc != MESHOPT and size > DEFLATE_MAX_RATIO * s["length"]:
        c.fail(f"section {name!r} claims {size} decoded bytes, more than {DEFLATE_MAX_RATIO} times its "
               f"{s['length']} stored bytes")
    return size


def check_encoded_indices(m: dict, c: _Checker) -> None:
    """A ``meshopt-deflate`` section is a LOD's ``indices`` and nothing else, its ``size`` the
    3 m indices' bytes and its stored length enough for a triangle stream of m triangles."""
    named: dict = {}
    for part in m["parts"]:
        for e in part["lods"]:
            named.setdefault(e["indices"], e)
            if e.get("attributes"):
                named[e["attributes"]] = None
        if isinstance(part.get("hierarchy"), dict):
            named[part["hierarchy"]["section"]] = None
    for s in m["sections"]:
        if s.get("encoding") != MESHOPT:
            continue
        e = named.get(s["name"])
        if e is None:
            c.fail(f"section {s['name']!r} is encoded {MESHOPT} but is no LOD's index section")
        want = 4 * -(-3 * e["triangles"] * e["index_width"] // 4)
        if s["size"] != want:
            c.fail(f"section {s['name']!r} size {s['size']} is not the {want} bytes of its {e['triangles']} triangles")
        if e["triangles"] + 1 + TABLE_BYTES > DEFLATE_MAX_RATIO * s["length"]:
            c.fail(f"section {s['name']!r}: {s['length']} stored bytes cannot hold {e['triangles']} triangles")


def check_grid(m: dict, c: _Checker) -> float:
    """The scene grid: finite, 24 bits, representable in float32. Returns its extent."""
    grid = c.need(m, "grid", dict, "manifest")
    origin = c.need(grid, "origin", list, "grid")
    if len(origin) != 3 or not all(is_num(v) for v in origin):
        c.fail("grid.origin must be 3 finite numbers within the float32 range")
    extent = c.need(grid, "extent", float, "grid")
    if not extent > 0 or c.need(grid, "bits", int, "grid") != LEVELS:
        c.fail("grid.extent must be > 0 and grid.bits 24")
    if extent < MIN_EXTENT:
        c.fail(f"grid.extent {extent:g} is below the {MIN_EXTENT:g} m floor lopcook cooks with (its cells "
               "would decode to subnormal float32 values)")
    if max(abs(v) for v in origin) + extent > MAX_GRID_REACH:
        c.fail(f"grid origin {origin} + extent {extent:g} reaches beyond {MAX_GRID_REACH:g} m (lopcook cooks "
               "positions within 2^100 m of the origin, so that float32 decoding stays finite)")
    return extent


def check_positions(m: dict, c: _Checker, length: dict) -> dict:
    """``positions``: max level, the sections it names, and the position sections last, in
    level order (the prefix property); in the streaming layout its ``stages`` (their section
    list is checked by ``check_stream_layout``). Returns the record."""
    pos = c.need(m, "positions", dict, "manifest")
    max_level = c.need(pos, "max_level", int, "positions")
    if not 1 <= max_level <= LEVELS:
        c.fail("positions.max_level must be in [1, 24]")
    if "stages" in pos:
        return check_stages(c, pos, max_level)
    if c.need(pos, "mandatory", str, "positions") not in length:
        c.fail("positions.mandatory names no section")
    planes = c.need(pos, "planes", dict, "positions")
    for p in range(2, max_level + 1):
        if not isinstance(planes.get(str(p)), str) or planes[str(p)] not in length:
            c.fail(f"positions.planes[{p}] names no section")
    clustered = "clusters" in pos  # clustered position buffers (version 3): their anchors come first
    if clustered and c.need(pos, "clusters", str, "positions") not in length:
        c.fail("positions.clusters names no section")
    tail = ([pos["clusters"]] if clustered else []) + [pos["mandatory"]] + [planes[str(p)] for p in range(2, max_level + 1)]
    order = list(length)
    if order[len(order) - len(tail):] != tail:
        c.fail("position sections are not last and in level order")
    return pos


def check_stages(c: _Checker, pos: dict, max_level: int) -> dict:
    """The streaming layout's ``positions`` (docs/format.md 14.2): ``stages`` a non-empty list of
    ``{"level": L}`` with L in 1..max_level, and none of the default layout's section names."""
    for key in ("mandatory", "planes", "clusters"):
        if key in pos:
            c.fail(f"positions.{key} must not be given with positions.stages (the streaming layout)")
    stages = c.need(pos, "stages", list, "positions")
    if not stages:
        c.fail("positions.stages is empty")
    for s, st in enumerate(stages):
        if not isinstance(st, dict) or set(st) != {"level"}:
            c.fail(f"positions.stages[{s}] must hold exactly level")
        if not 1 <= c.need(st, "level", int, f"positions.stages[{s}]") <= max_level:
            c.fail(f"positions.stages[{s}].level must be in [1, {max_level}]")
    return pos


def check_stream_layout(m: dict, c: _Checker, length: dict, totals: "_Totals") -> None:
    """A streaming file: every stage holds a stored buffer, the section table is exactly the list
    of docs/format.md 14.3, and each stage's position sections are as long as its buffers need
    (planes and the deferred section exactly). ``check_stage`` has checked each LOD's stage."""
    lay = layout_of(m)
    empty = [st.index for st in lay.stages if not st.buffers]
    if empty:
        c.fail(f"positions.stages[{empty[0]}] holds no buffer")
    want, have = lay.expected_sections(), list(length)
    if have != want:
        at = next((j for j, (a, b) in enumerate(zip(have, want)) if a != b), min(len(have), len(want)))
        c.fail(f"the sections are not those of the streaming layout in its order: section {at} is "
               f"{have[at] if at < len(have) else 'missing'!r}, expected {want[at] if at < len(want) else 'none'!r}")
    for st in lay.stages:
        t = totals.stage(st.index)
        if st.clusters and length[st.clusters] < 4 * t.headers:
            c.fail(f"{st.clusters} is shorter than the cluster headers it holds")
        if length[st.mandatory] < 4 * t.words:
            c.fail(f"{st.mandatory} is shorter than the buffers it holds")
        for p, name in st.planes.items():
            if length[name] != plane_bytes(st.bits[p]):
                c.fail(f"{name} is not the {st.bits[p]} bits its buffers hold")
        if st.deferred:
            want_bytes = sum(plane_bytes(st.bits[p]) for p in range(st.level + 1, lay.max_level + 1))
            if length[st.deferred] != want_bytes:
                c.fail(f"{st.deferred} is not the {want_bytes} bytes of planes {st.level + 1}..{lay.max_level}")


class _StageTotals:
    """What the buffers of one stage add up to: mandatory words, cluster header words, clustered
    buffers, bits per plane."""

    def __init__(self, max_level: int):
        self.words = self.headers = self.clustered = 0
        self.plane_bits = {p: 0 for p in range(2, max_level + 1)}


class _Totals:
    """What the LODs add up to per stage (one stage in the default layout), checked against the
    position sections at the end."""

    def __init__(self, pos: dict):
        self.max_level = pos["max_level"]
        self.stages: dict = {}

    def stage(self, s: int) -> _StageTotals:
        if s not in self.stages:
            self.stages[s] = _StageTotals(self.max_level)
        return self.stages[s]

    @property
    def words(self):
        return self.stage(0).words

    @property
    def headers(self):
        return self.stage(0).headers

    @property
    def clustered(self):
        return self.stage(0).clustered

    @property
    def plane_bits(self):
        return self.stage(0).plane_bits

    def check_lengths(self, c: _Checker, pos: dict, length: dict) -> None:
        if "clusters" in pos and not self.clustered:
            c.fail("positions.clusters is present but no buffer is clustered")
        if "clusters" in pos and length[pos["clusters"]] < 4 * self.headers:
            c.fail("positions.clusters is shorter than the cluster headers it holds")
        if length[pos["mandatory"]] < 4 * self.words:
            c.fail("positions.mandatory is shorter than the buffers it holds")
        for p, bits in self.plane_bits.items():
            if length[pos["planes"][str(p)]] < (bits + 7) // 8:
                c.fail(f"refinement plane {p} is shorter than its {bits} bits")


def check_part(m: dict, c: _Checker, i: int, part, extent: float, length: dict, totals: _Totals) -> None:
    """Part ``i``: name, source, optional hierarchy and placement, its LODs, and the part's
    ``attribute_bits`` equal to what its LODs share."""
    c.need(part, "name", str, f"parts[{i}]")
    if part.get("hierarchy") is not None:
        check_hierarchy(c, i, part, length)
    c.need(part, "source", str, f"parts[{i}]")
    lods = c.need(part, "lods", list, f"parts[{i}]")
    if not lods:
        c.fail(f"parts[{i}] has no LODs")
    shared_of = check_placement(m, c, i, part, extent)
    bits = None
    stream = "stages" in m["positions"]
    for k, lod in enumerate(lods):
        where = f"parts[{i}].lods[{k}]"
        if not isinstance(lod, dict):
            c.fail(f"{where} is not an object")
        stage_index = check_stage(m, c, lod, where, k, len(lods), lods) if stream else 0
        if "stage" in lod and not stream:
            c.fail(f"{where}.stage is only allowed in the streaming layout (positions.stages)")
        if shared_of is None:
            stage = totals.stage(stage_index)
            lod_bits = check_lod(c, lod, where, length, stage, stream or "clusters" in m["positions"])
        else:
            lod_bits = check_shared_lod(c, lod, where, m["parts"][shared_of], shared_of, k, len(lods))
        bits = lod_bits if bits is None else bits
    if c.need(part, "attribute_bits", dict, f"parts[{i}]") != bits.as_dict():
        c.fail(f"parts[{i}].attribute_bits is not the attribute_bits its LODs share")


def check_stage(m: dict, c: _Checker, lod: dict, where: str, k: int, n: int, lods: list) -> int:
    """A LOD entry's ``stage`` in the streaming layout (docs/format.md 14.1): an integer naming a
    stage, 0 for the part's coarsest LOD, never below the stage of a coarser LOD of the part."""
    s = c.need(lod, "stage", int, where)
    if not 0 <= s < len(m["positions"]["stages"]):
        c.fail(f"{where}.stage {s} names no stage (the file has {len(m['positions']['stages'])})")
    if k == n - 1 and s != 0:
        c.fail(f"{where}.stage must be 0: a part's coarsest LOD is in the first stage")
    if k < n - 1 and isinstance(lods[k + 1], dict) and is_int(lods[k + 1].get("stage")) and s < lods[k + 1]["stage"]:
        c.fail(f"{where}.stage {s} comes before the stage of the coarser LOD {k + 1}")
    return s


def check_hierarchy(c: _Checker, i: int, part: dict, length: dict) -> None:
    """A part's optional ``hierarchy`` record (``cook --hierarchy``): a non-position section and
    non-negative counts."""
    hier = c.need(part, "hierarchy", dict, f"parts[{i}]")
    if c.need(hier, "section", str, f"parts[{i}].hierarchy") not in length or hier["section"].startswith("positions/"):
        c.fail(f"parts[{i}].hierarchy.section names no hierarchy section")
    for key in ("leaves", "nodes", "triangles", "connectivity_bits", "structure_bits", "vertex_map_bits",
                "representative_bits"):
        if c.need(hier, key, int, f"parts[{i}].hierarchy") < 0:
            c.fail(f"parts[{i}].hierarchy.{key} is negative")


def check_attribute_bits(c: _Checker, lod: dict, where: str) -> AttributeBits:
    """``attribute_bits``: every codec of the first format as a key, later codecs optional, each
    null or an integer in its codec's range; the codecs' LOD fields (``uv_range``, ``uv_step``)."""
    ab = c.need(lod, "attribute_bits", dict, where)
    base = {x.name for x in CODECS if x.format_major == 2}
    if not base <= set(ab) or not set(ab) <= {x.name for x in CODECS}:
        c.fail(f"{where}.attribute_bits must hold exactly {', '.join(x.name for x in CODECS if x.format_major == 2)}"
               + "".join(f" (and optionally {x.name})" for x in CODECS if x.format_major > 2))
    for codec in CODECS:
        v = ab.get(codec.name)
        lo, hi = codec.bits
        if v is not None and not (is_int(v) and lo <= v <= hi):
            c.fail(f"{where}.attribute_bits.{codec.name} must be null or an integer in [{lo}, {hi}]")
        codec.check_entry(lod, v, c.fail, where)
    return AttributeBits.of(ab)


def check_lod(c: _Checker, lod: dict, where: str, length: dict, totals: _StageTotals,
              clustered: bool) -> AttributeBits:
    """A stored buffer: counts, VertexId, indices, attribute record, mandatory words, clusters, and
    the lengths of its sections. ``totals``: its stage's running totals."""
    n = c.need(lod, "vertices", int, where)
    tri = c.need(lod, "triangles", int, where)
    if n < 1 or tri < 1:
        c.fail(f"{where} is empty")
    if n > 0xFFFFFFFF or tri > 0xFFFFFFFF:
        c.fail(f"{where} has more than 2^32 vertices or triangles")
    if c.need(lod, "geometric_error_m", float, where) < 0:
        c.fail(f"{where}.geometric_error_m is negative")
    vid = c.need(lod, "vertex_id", list, where)
    if len(vid) != LEVELS + 1 or not all(is_int(a) for a in vid) or vid[0] != 0 or vid[-1] != n \
            or any(a > b for a, b in zip(vid, vid[1:])):
        c.fail(f"{where}.vertex_id is not 25 non-decreasing counts from 0 to {n}")
    if c.need(lod, "index_width", int, where) not in (2, 4):
        c.fail(f"{where}.index_width must be 2 or 4")
    if c.need(lod, "indices", str, where) not in length:
        c.fail(f"{where}.indices names no section")
    bits = check_attribute_bits(c, lod, where)
    rec = lod.get("attributes")
    if rec is not None and (not isinstance(rec, str) or rec not in length):
        c.fail(f"{where}.attributes names no section")
    if (rec is None) != (bits.record_bits == 0):
        c.fail(f"{where}.attributes must name a section exactly when record_bits > 0")
    if c.need(lod, "record_bits", int, where) != bits.record_bits:
        c.fail(f"{where}.record_bits is not 2 b_n + 2 b_u + 4 b_c of its attribute_bits")
    mw = c.need(lod, "mandatory_words", list, where)
    if len(mw) != 2 or not all(is_int(v) and v >= 0 for v in mw):
        c.fail(f"{where}.mandatory_words must be [offset, count]")
    check_lod_positions(c, lod, where, vid, mw, totals, clustered)
    width = lod["index_width"]
    if (n <= 65535) != (width == 2):
        c.fail(f"{where}.index_width {width} does not match {n} vertices")
    if length[lod["indices"]] < 3 * tri * width:
        c.fail(f"{where}: index section is shorter than {tri} triangles")
    if rec is not None and length[rec] < 4 * ((n * bits.record_bits + 31) // 32):
        c.fail(f"{where}: attributes section is shorter than {n} records of {bits.record_bits} bits")
    return bits


def check_lod_positions(c: _Checker, lod: dict, where: str, vid: list, mw: list, totals: _StageTotals,
                        clustered: bool) -> None:
    """``mandatory_words`` (and a clustered buffer's ``cluster_*`` records) against its bins; adds
    the buffer's words, headers and plane bits to ``totals``. The buffer at level 1 holds
    ``sum_k 3 k |bin k|`` bits, buffers back to back."""
    bits = sum(3 * k * (vid[k] - vid[k - 1]) for k in range(1, LEVELS + 1))
    if "cluster_size" in lod or "cluster_words" in lod:
        # clustered (lopcook.lop.clusters): at most the unclustered bits, at least one word;
        # container.from_bytes checks the exact count against the cluster headers
        if not clustered:
            c.fail(f"{where} is clustered but positions.clusters is missing")
        size = c.need(lod, "cluster_size", int, where)
        if not 16 <= size <= 1024:
            c.fail(f"{where}.cluster_size must be in [16, 1024]")
        cw = c.need(lod, "cluster_words", list, where)
        n_c = sum(-(-(vid[k] - vid[k - 1]) // size) for k in range(1, LEVELS + 1))
        if len(cw) != 2 or not all(is_int(v) for v in cw) or cw != [totals.headers, 3 * n_c]:
            c.fail(f"{where}.cluster_words must be [offset, 3 * clusters] = [{totals.headers}, {3 * n_c}]")
        totals.headers += cw[1]
        totals.clustered += 1
        pw = c.need(lod, "cluster_p_words", list, where)
        if len(pw) != LEVELS or not all(is_int(v) and v >= 1 for v in pw) or pw[0] != mw[1]:
            c.fail(f"{where}.cluster_p_words must be 24 positive word counts, the first its mandatory count")
        cpb = c.need(lod, "cluster_plane_bits", list, where)
        if len(cpb) != LEVELS - 1 or not all(is_int(v) and 0 <= v <= 3 * vid[p - 1]
                                             for p, v in zip(range(2, LEVELS + 1), cpb)):
            c.fail(f"{where}.cluster_plane_bits must be 23 bit counts, at most 3 VertexId[p-1] each")
        for p in totals.plane_bits:
            totals.plane_bits[p] += cpb[p - 2]
        if mw[0] != totals.words or not 1 <= mw[1] <= max(1, (bits + 31) // 32):
            c.fail(f"{where}.mandatory_words do not match its bins")
    else:
        if mw[0] != totals.words or mw[1] != (bits + 31) // 32:
            c.fail(f"{where}.mandatory_words do not match its bins")
        for p in totals.plane_bits:
            totals.plane_bits[p] += 3 * vid[p - 1]
    totals.words += mw[1]


def check_shared_lod(c: _Checker, lod: dict, where: str, owner: dict, of: int, k: int, n_lods: int) -> AttributeBits:
    """A placement's LOD entry: equal to its owner's in every field but its own
    ``SHARED_OWN_FIELDS``."""
    ref = owner["lods"]
    if n_lods != len(ref):
        c.fail(f"{where.split('.')[0]} has {n_lods} LODs, the buffers it places (parts[{of}]) {len(ref)}")
    a = {key: v for key, v in lod.items() if key not in SHARED_OWN_FIELDS}
    b = {key: v for key, v in ref[k].items() if key not in SHARED_OWN_FIELDS}
    if a != b:
        c.fail(f"{where} does not name the buffer of parts[{of}].lods[{k}] it places")
    if c.need(lod, "geometric_error_m", float, where) < 0:
        c.fail(f"{where}.geometric_error_m is negative")
    return check_attribute_bits(c, lod, where)


def check_placement(m: dict, c: _Checker, i: int, part: dict, world_extent: float) -> int | None:
    """Part ``i``'s optional ``placement`` and ``grid`` records (``cook --instances``,
    ``lopcook.lop.placement``): ``of`` an earlier or the same part that owns its buffers (and is
    its own owner), ``transform`` 12 finite float32 numbers with an invertible ``A``,
    ``level_shift`` the shift ``placement.level_shift`` computes from it, ``grid`` the owner's
    (origin 3 numbers, extent at least ``MIN_EXTENT``). Returns the owner when it is another part
    (the LOD entries are then shared), else None."""
    rec = part.get("placement")
    if rec is None:
        if part.get("grid") is not None:
            c.fail(f"parts[{i}].grid is only allowed with a placement")
        return None
    where = f"parts[{i}].placement"
    if not isinstance(rec, dict) or set(rec) != {"of", "transform", "level_shift"}:
        c.fail(f"{where} must hold exactly of, transform, level_shift")
    of = rec["of"]
    if not is_int(of) or not 0 <= of <= i:
        c.fail(f"{where}.of must be the index of this or an earlier part, got {of!r}")
    tf = rec["transform"]
    if not isinstance(tf, list) or len(tf) != 12 or not all(is_num(v) for v in tf):
        c.fail(f"{where}.transform must be 12 finite float32 numbers (3 x 4, row-major)")
    a, _ = split(tf)
    if not abs(float(np.linalg.det(a.astype(np.float64)))) > 0:
        c.fail(f"{where}.transform is singular")
    g = check_placement_grid(c, i, part)
    if not is_int(rec["level_shift"]) or rec["level_shift"] != level_shift(sigma(tf), g["extent"], world_extent):
        c.fail(f"{where}.level_shift is not ceil(log2(sigma E_m / E_w)) of its transform and grids")
    owner = m["parts"][of]
    orec = owner.get("placement") if isinstance(owner, dict) else None
    if not isinstance(orec, dict) or orec.get("of") != of:
        c.fail(f"{where}.of names parts[{of}], which does not own its buffers")
    if owner.get("grid") != g:
        c.fail(f"parts[{i}].grid differs from the grid of the buffers it places (parts[{of}].grid)")
    return None if of == i else of


def check_placement_grid(c: _Checker, i: int, part: dict) -> dict:
    """A placement's mesh ``grid``: exactly origin and extent, finite, at least ``MIN_EXTENT``."""
    g = part.get("grid")
    if not isinstance(g, dict) or set(g) != {"origin", "extent"}:
        c.fail(f"parts[{i}].grid must hold exactly origin and extent")
    if not (isinstance(g["origin"], list) and len(g["origin"]) == 3 and all(is_num(v) for v in g["origin"])):
        c.fail(f"parts[{i}].grid.origin must be 3 finite numbers within the float32 range")
    if not (is_num(g["extent"]) and g["extent"] >= MIN_EXTENT
            and max(abs(v) for v in g["origin"]) + g["extent"] <= MAX_GRID_REACH):
        c.fail(f"parts[{i}].grid.extent must be at least {MIN_EXTENT:g} m and within {MAX_GRID_REACH:g} m")
    return g
