"""The container manifest: what it holds and the checks a reader relies on.

The full contract is ``schema/container.schema.json`` (JSON Schema 2020-12, used by the tests);
``validate_manifest`` re-checks at run time, without extra dependencies, every field the reader
uses, so a manifest that passes its CRC but is inconsistent still gives one clear error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..grid import MIN_EXTENT
from ..errors import LopcookError
from ..settings import COLOR_BITS_RANGE, NORMAL_BITS_RANGE, UV_BITS_RANGE

FORMAT = "lopcook.lop"
LEVELS = 24


#: largest finite float32: every float the decoders compute with must stay below it
F32_MAX = 3.4028234663852886e38
#: |origin| + extent of any grid lopcook writes: its positions lie within
#: ``ingest.build.MAX_COORDINATE`` (2^100 m) of the origin, so the grid reaches at most twice that
MAX_GRID_REACH = 2.0 ** 102


def validate_manifest(m, path: str | None) -> None:
    """Raise LopcookError("container", path, ...) unless the manifest is sound; the one check every read
    of a container runs (``container.from_bytes``), so that decode, inspect and verify may index
    it without further checks.

    Schema level: every field a reader uses (the decoding fields, and the informative ``source``,
    ``generator``, ``viewing``, ``options``, ``stats`` and ``savings`` that ``inspect`` shows) has
    its JSON type; integers are not booleans or floats. Semantic level: grid origin and extent
    finite, extent at least ``MIN_EXTENT`` and ``|origin| + extent <= MAX_GRID_REACH`` (2^102 m,
    far inside float32), bits 24; index values below each LOD's vertex count (checked on the
    payload by ``container.from_bytes``);
    sections back to back in manifest order (offsets are the running sum of lengths), names
    unique, lengths multiples of 4; the position sections last, mandatory then planes in level
    order; every section name a LOD or ``positions`` refers to exists; each LOD's ``vertex_id``
    25 non-decreasing counts, ``mandatory_words`` matching its bins, index width matching its
    vertex count, every section long enough for what it is said to hold; ``attribute_bits``
    within their ranges, ``record_bits`` their record size, shared by a part's LODs (the part's
    ``attribute_bits``), ``attributes`` naming a section of ``ceil(n S / 32)`` words when S > 0;
    ``uv_range`` finite float32 with lo <= hi and ``uv_step`` its float32 step at b_u bits. This module is strict rather than the readers tolerant: a manifest
    that lacks an informative field the schema requires is refused, with one message naming it.
    """

    reason = ["manifest"]  # the error class (docs/format.md section 12): the section table's checks say section_table

    def fail(msg: str) -> None:
        raise LopcookError("container", path, f"manifest: {msg}", hint="the file is corrupt; cook it again",
                           reason=reason[0])

    def is_int(v) -> bool:
        return isinstance(v, int) and not isinstance(v, bool)

    def is_num(v, limit: float = F32_MAX) -> bool:
        return (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                and abs(v) <= limit)

    def need(obj, key, kind, where):
        if not isinstance(obj, dict) or key not in obj:
            fail(f"{where}: missing {key!r}")
        val = obj[key]
        if kind is int and not is_int(val):
            fail(f"{where}.{key} must be an integer")
        if kind is float and not is_num(val):
            fail(f"{where}.{key} must be a finite number within the float32 range")
        if kind not in (int, float) and (not isinstance(val, kind) or isinstance(val, bool)):
            fail(f"{where}.{key} has the wrong type")
        return val

    def count(obj, key, where, minimum=0):
        val = need(obj, key, int, where)
        if val < minimum:
            fail(f"{where}.{key} is {val}, expected at least {minimum}")
        return val

    def check_bits(lod, where):
        from .attributes import AttributeBits

        ab = need(lod, "attribute_bits", dict, where)
        if set(ab) != {"normals", "uvs", "colors"}:
            fail(f"{where}.attribute_bits must hold exactly normals, uvs, colors")
        for key, (lo, hi) in (("normals", NORMAL_BITS_RANGE), ("uvs", UV_BITS_RANGE), ("colors", COLOR_BITS_RANGE)):
            v = ab[key]
            if v is not None and not (is_int(v) and lo <= v <= hi):
                fail(f"{where}.attribute_bits.{key} must be null or an integer in [{lo}, {hi}]")
        return AttributeBits.of(ab)

    if not isinstance(m, dict) or m.get("format") != FORMAT:
        fail(f"format is not {FORMAT!r}")
    # informative fields (shown by inspect)
    need(m, "generator", str, "manifest")
    src = need(m, "source", dict, "manifest")
    need(src, "file", str, "source")
    need(src, "format", str, "source")
    viewing = need(m, "viewing", dict, "manifest")
    vp = need(viewing, "viewport", list, "viewing")
    if len(vp) != 2 or not all(is_int(v) and v > 0 for v in vp):
        fail("viewing.viewport must be two positive integers")
    fov = need(viewing, "fov_y_deg", float, "viewing")
    if not 0 < fov < 180:
        fail("viewing.fov_y_deg must be in (0, 180)")
    if not need(viewing, "pixel_error", float, "viewing") > 0:
        fail("viewing.pixel_error must be > 0")
    nearest = viewing.get("nearest_m")
    if nearest is not None and not (is_num(nearest) and nearest > 0):
        fail("viewing.nearest_m must be a positive number or null")
    options = need(m, "options", dict, "manifest")
    for key in ("analyse", "ingest"):
        if key in options and not isinstance(options[key], dict):
            fail(f"options.{key} must be an object")
    stats = need(m, "stats", dict, "manifest")
    for key in ("vertices", "triangles", "float32_position_bytes"):
        count(stats, key, "stats")
    hist = need(stats, "histogram", list, "stats")
    if len(hist) != LEVELS + 1 or not all(is_int(v) and v >= 0 for v in hist):
        fail("stats.histogram must be 25 counts")
    savings = m.get("savings")
    if savings is not None:
        if not isinstance(savings, dict):
            fail("savings must be an object or null")
        count(savings, "bytes_saved", "savings")
        need(savings, "planes_dropped", list, "savings")
        count(savings, "lods_dropped", "savings")

    # sections: back to back in manifest order
    reason[0] = "section_table"
    sections = need(m, "sections", list, "manifest")
    names = set()
    offset = 0
    for i, s in enumerate(sections):
        name = need(s, "name", str, f"sections[{i}]")
        for key in ("offset", "length", "crc32"):
            count(s, key, f"sections[{i}]")
        if s["length"] % 4:
            fail(f"section {name!r} length is not a multiple of 4")
        if s["offset"] != offset:
            fail(f"section {name!r} starts at {s['offset']}, not where the previous one ends ({offset})")
        if s["crc32"] > 0xFFFFFFFF:
            fail(f"section {name!r} crc32 is not a 32-bit value")
        offset += s["length"]
        if name in names:
            fail(f"section {name!r} appears twice")
        names.add(name)

    reason[0] = "manifest"
    # grid: finite, representable in float32
    grid = need(m, "grid", dict, "manifest")
    origin = need(grid, "origin", list, "grid")
    if len(origin) != 3 or not all(is_num(v) for v in origin):
        fail("grid.origin must be 3 finite numbers within the float32 range")
    extent = need(grid, "extent", float, "grid")
    if not extent > 0 or need(grid, "bits", int, "grid") != LEVELS:
        fail("grid.extent must be > 0 and grid.bits 24")
    if extent < MIN_EXTENT:
        fail(f"grid.extent {extent:g} is below the {MIN_EXTENT:g} m floor lopcook cooks with (its cells "
             "would decode to subnormal float32 values)")
    if max(abs(v) for v in origin) + extent > MAX_GRID_REACH:
        fail(f"grid origin {origin} + extent {extent:g} reaches beyond {MAX_GRID_REACH:g} m (lopcook cooks "
             "positions within 2^100 m of the origin, so that float32 decoding stays finite)")

    pos = need(m, "positions", dict, "manifest")
    max_level = need(pos, "max_level", int, "positions")
    if not 1 <= max_level <= LEVELS:
        fail("positions.max_level must be in [1, 24]")
    if need(pos, "mandatory", str, "positions") not in names:
        fail("positions.mandatory names no section")
    planes = need(pos, "planes", dict, "positions")
    for p in range(2, max_level + 1):
        if not isinstance(planes.get(str(p)), str) or planes[str(p)] not in names:
            fail(f"positions.planes[{p}] names no section")
    # position sections come last, mandatory first, then planes in ascending order (prefix property)
    order = [s["name"] for s in sections]
    clustered = "clusters" in pos  # clustered position buffers (version 3): their anchors come first
    if clustered and need(pos, "clusters", str, "positions") not in names:
        fail("positions.clusters names no section")
    tail = ([pos["clusters"]] if clustered else []) + [pos["mandatory"]] + [planes[str(p)] for p in range(2, max_level + 1)]
    if order[len(order) - len(tail):] != tail:
        fail("position sections are not last and in level order")
    length = {s["name"]: s["length"] for s in sections}
    parts = need(m, "parts", list, "manifest")
    if not parts:
        fail("no parts")
    words_next, headers_next, n_clustered = 0, 0, 0
    plane_bits = {p: 0 for p in range(2, max_level + 1)}
    for i, part in enumerate(parts):
        need(part, "name", str, f"parts[{i}]")
        if part.get("hierarchy") is not None:  # optional (cook --hierarchy): lopcook.hierarchy.container
            hier = need(part, "hierarchy", dict, f"parts[{i}]")
            if need(hier, "section", str, f"parts[{i}].hierarchy") not in names or hier["section"].startswith("positions/"):
                fail(f"parts[{i}].hierarchy.section names no hierarchy section")
            for key in ("leaves", "nodes", "triangles", "connectivity_bits", "structure_bits", "vertex_map_bits",
                        "representative_bits"):
                if need(hier, key, int, f"parts[{i}].hierarchy") < 0:
                    fail(f"parts[{i}].hierarchy.{key} is negative")
        need(part, "source", str, f"parts[{i}]")
        lods = need(part, "lods", list, f"parts[{i}]")
        if not lods:
            fail(f"parts[{i}] has no LODs")
        i_bits = None
        shared_of = _check_placement(m, parts, i, part, extent, is_num, is_int, fail)
        for k, lod in enumerate(lods):
            where = f"parts[{i}].lods[{k}]"
            if not isinstance(lod, dict):
                fail(f"{where} is not an object")
            if shared_of is not None:
                ref = parts[shared_of]["lods"]
                if len(lods) != len(ref):
                    fail(f"parts[{i}] has {len(lods)} LODs, the buffers it places (parts[{shared_of}]) {len(ref)}")
                a = {key: v for key, v in lod.items() if key not in SHARED_OWN_FIELDS}
                b = {key: v for key, v in ref[k].items() if key not in SHARED_OWN_FIELDS}
                if a != b:
                    fail(f"{where} does not name the buffer of parts[{shared_of}].lods[{k}] it places")
                err = need(lod, "geometric_error_m", float, where)
                if err < 0:
                    fail(f"{where}.geometric_error_m is negative")
                i_bits = check_bits(lod, where) if i_bits is None else i_bits
                continue
            n = need(lod, "vertices", int, where)
            tri = need(lod, "triangles", int, where)
            if n < 1 or tri < 1:
                fail(f"{where} is empty")
            if n > 0xFFFFFFFF or tri > 0xFFFFFFFF:
                fail(f"{where} has more than 2^32 vertices or triangles")
            err = need(lod, "geometric_error_m", float, where)
            if err < 0:
                fail(f"{where}.geometric_error_m is negative")
            vid = need(lod, "vertex_id", list, where)
            if len(vid) != LEVELS + 1 or not all(is_int(a) for a in vid) or vid[0] != 0 or vid[-1] != n \
                    or any(a > b for a, b in zip(vid, vid[1:])):
                fail(f"{where}.vertex_id is not 25 non-decreasing counts from 0 to {n}")
            if need(lod, "index_width", int, where) not in (2, 4):
                fail(f"{where}.index_width must be 2 or 4")
            if need(lod, "indices", str, where) not in names:
                fail(f"{where}.indices names no section")
            abits = check_bits(lod, where)
            if i_bits is None:
                i_bits = abits
            rec = lod.get("attributes")
            if rec is not None and (not isinstance(rec, str) or rec not in names):
                fail(f"{where}.attributes names no section")
            if (rec is None) != (abits.record_bits == 0):
                fail(f"{where}.attributes must name a section exactly when record_bits > 0")
            if need(lod, "record_bits", int, where) != abits.record_bits:
                fail(f"{where}.record_bits is not 2 b_n + 2 b_u + 4 b_c of its attribute_bits")
            mw = need(lod, "mandatory_words", list, where)
            if len(mw) != 2 or not all(is_int(v) and v >= 0 for v in mw):
                fail(f"{where}.mandatory_words must be [offset, count]")
            # the buffer at level 1 holds sum_k 3 * k * |bin k| bits, buffers back to back
            bits = sum(3 * k * (vid[k] - vid[k - 1]) for k in range(1, LEVELS + 1))
            if "cluster_size" in lod or "cluster_words" in lod:
                # clustered (lopcook.emit.clusters): at most the unclustered bits, at least one word;
                # container.from_bytes checks the exact count against the cluster headers
                if not clustered:
                    fail(f"{where} is clustered but positions.clusters is missing")
                size = need(lod, "cluster_size", int, where)
                if not 16 <= size <= 1024:
                    fail(f"{where}.cluster_size must be in [16, 1024]")
                cw = need(lod, "cluster_words", list, where)
                n_c = sum(-(-(vid[k] - vid[k - 1]) // size) for k in range(1, LEVELS + 1))
                if len(cw) != 2 or not all(is_int(v) for v in cw) or cw != [headers_next, 3 * n_c]:
                    fail(f"{where}.cluster_words must be [offset, 3 * clusters] = [{headers_next}, {3 * n_c}]")
                headers_next += cw[1]
                n_clustered += 1
                pw = need(lod, "cluster_p_words", list, where)
                if len(pw) != LEVELS or not all(is_int(v) and v >= 1 for v in pw) or pw[0] != mw[1]:
                    fail(f"{where}.cluster_p_words must be 24 positive word counts, the first its mandatory count")
                cpb = need(lod, "cluster_plane_bits", list, where)
                if len(cpb) != LEVELS - 1 or not all(is_int(v) and 0 <= v <= 3 * vid[p - 1]
                                                     for p, v in zip(range(2, LEVELS + 1), cpb)):
                    fail(f"{where}.cluster_plane_bits must be 23 bit counts, at most 3 VertexId[p-1] each")
                for p in plane_bits:
                    plane_bits[p] += cpb[p - 2]
                if mw[0] != words_next or not 1 <= mw[1] <= max(1, (bits + 31) // 32):
                    fail(f"{where}.mandatory_words do not match its bins")
            else:
                if mw[0] != words_next or mw[1] != (bits + 31) // 32:
                    fail(f"{where}.mandatory_words do not match its bins")
                for p in plane_bits:
                    plane_bits[p] += 3 * vid[p - 1]
            words_next += mw[1]
            width = lod["index_width"]
            if (n <= 65535) != (width == 2):
                fail(f"{where}.index_width {width} does not match {n} vertices")
            if length[lod["indices"]] < 3 * tri * width:
                fail(f"{where}: index section is shorter than {tri} triangles")
            if rec is not None and length[rec] < 4 * ((n * abits.record_bits + 31) // 32):
                fail(f"{where}: attributes section is shorter than {n} records of {abits.record_bits} bits")
            if abits.uvs is not None:
                rng = need(lod, "uv_range", list, where)
                if len(rng) != 2 or not all(isinstance(r, list) and len(r) == 2 and all(is_num(v) for v in r)
                                            for r in rng):
                    fail(f"{where}.uv_range must be [[lo_u, lo_v], [hi_u, hi_v]] of finite float32 numbers")
                if not (rng[0][0] <= rng[1][0] and rng[0][1] <= rng[1][1]):
                    fail(f"{where}.uv_range has lo above hi")
                step = need(lod, "uv_step", list, where)
                if len(step) != 2 or not all(is_num(v) for v in step):
                    fail(f"{where}.uv_step must be [step_u, step_v] of finite float32 numbers")
                want = ((np.asarray(rng[1], np.float32).astype(np.float64) - np.asarray(rng[0], np.float32))
                        / float((1 << abits.uvs) - 1)).astype(np.float32)
                if not np.array_equal(np.asarray(step, np.float64), want.astype(np.float64)):
                    fail(f"{where}.uv_step is not float32((hi - lo) / (2^b_u - 1)) of its uv_range")
        pb = need(part, "attribute_bits", dict, f"parts[{i}]")
        if pb != i_bits.as_dict():
            fail(f"parts[{i}].attribute_bits is not the attribute_bits its LODs share")
    if clustered and not n_clustered:
        fail("positions.clusters is present but no buffer is clustered")
    if clustered and length[pos["clusters"]] < 4 * headers_next:
        fail("positions.clusters is shorter than the cluster headers it holds")
    if length[pos["mandatory"]] < 4 * words_next:
        fail("positions.mandatory is shorter than the buffers it holds")
    for p, bits in plane_bits.items():
        if length[planes[str(p)]] < (bits + 7) // 8:
            fail(f"refinement plane {p} is shorter than its {bits} bits")


#: fields of a placement's LOD entry that are its own; every other field names or describes the
#: buffer it shares with its owner and must equal the owner's
SHARED_OWN_FIELDS = ("geometric_error_m", "min_distance_m")


def _check_placement(m, parts, i, part, world_extent, is_num, is_int, fail) -> int | None:
    """Checks of part ``i``'s optional ``placement`` and ``grid`` records (``cook --instances``,
    ``lopcook.emit.placement``): ``of`` an earlier or the same part that owns its buffers (and is its
    own owner), ``transform`` 12 finite float32 numbers with an invertible ``A``, ``level_shift`` the
    shift ``placement.level_shift`` computes from it, ``grid`` the owner's (origin 3 numbers, extent
    at least ``MIN_EXTENT``). Returns the owner when it is another part (the LOD entries are then
    shared), else None."""
    rec = part.get("placement")
    if rec is None:
        if part.get("grid") is not None:
            fail(f"parts[{i}].grid is only allowed with a placement")
        return None
    from .placement import level_shift, sigma, split

    where = f"parts[{i}].placement"
    if not isinstance(rec, dict) or set(rec) != {"of", "transform", "level_shift"}:
        fail(f"{where} must hold exactly of, transform, level_shift")
    of = rec["of"]
    if not is_int(of) or not 0 <= of <= i:
        fail(f"{where}.of must be the index of this or an earlier part, got {of!r}")
    tf = rec["transform"]
    if not isinstance(tf, list) or len(tf) != 12 or not all(is_num(v) for v in tf):
        fail(f"{where}.transform must be 12 finite float32 numbers (3 x 4, row-major)")
    a, _ = split(tf)
    if not abs(float(np.linalg.det(a.astype(np.float64)))) > 0:
        fail(f"{where}.transform is singular")
    g = part.get("grid")
    if not isinstance(g, dict) or set(g) != {"origin", "extent"}:
        fail(f"parts[{i}].grid must hold exactly origin and extent")
    if not (isinstance(g["origin"], list) and len(g["origin"]) == 3 and all(is_num(v) for v in g["origin"])):
        fail(f"parts[{i}].grid.origin must be 3 finite numbers within the float32 range")
    if not (is_num(g["extent"]) and g["extent"] >= MIN_EXTENT
            and max(abs(v) for v in g["origin"]) + g["extent"] <= MAX_GRID_REACH):
        fail(f"parts[{i}].grid.extent must be at least {MIN_EXTENT:g} m and within {MAX_GRID_REACH:g} m")
    if not is_int(rec["level_shift"]) or rec["level_shift"] != level_shift(sigma(tf), g["extent"], world_extent):
        fail(f"{where}.level_shift is not ceil(log2(sigma E_m / E_w)) of its transform and grids")
    owner = parts[of]
    orec = owner.get("placement") if isinstance(owner, dict) else None
    if not isinstance(orec, dict) or orec.get("of") != of:
        fail(f"{where}.of names parts[{of}], which does not own its buffers")
    if owner.get("grid") != g:
        fail(f"parts[{i}].grid differs from the grid of the buffers it places (parts[{of}].grid)")
    return None if of == i else of


# --------------------------------------------------------------------------------------------
# the typed view: parts, LODs and the one definition of every byte count


FLOAT32_BYTES_PER_VERTEX = 12  # three float32 components


@dataclass(frozen=True)
class LodEntry:
    """One buffer (a part's LOD) of a container.

    vertices, triangles : counts; vertex_id : (25,) the VertexId table (vertex_id[k] = vertices
    with minimum level < k+1 ... see docs/format.md); geometric_error_m : metres from LOD 0;
    min_distance_m : camera distance (metres) from which a runtime selects it, or None;
    index_width : 2 or 4 bytes; section_bytes : stored bytes of its ``indices`` and
    ``attributes`` sections (0 when absent); attribute_bits : ``{"normals", "uvs", "colors"}``
    bits per component (None when absent); record_bits : S, bits per vertex of its attributes.
    """

    vertices: int
    triangles: int
    vertex_id: tuple
    geometric_error_m: float
    min_distance_m: float | None
    index_width: int
    section_bytes: dict
    mandatory_words: int = 0
    attribute_bits: dict | None = None
    record_bits: int = 0
    cluster_size: int | None = None
    cluster_p_words: tuple | None = None
    cluster_plane_bits: tuple | None = None

    @property
    def clustered(self) -> bool:
        return self.cluster_size is not None

    @property
    def n_clusters(self) -> int:
        """Clusters of a clustered buffer (bins cut into runs of N), 0 when unclustered."""
        if self.cluster_size is None:
            return 0
        counts = np.diff(np.asarray(self.vertex_id, dtype=np.int64))
        return int((-(-counts // int(self.cluster_size))).sum())

    def cap_bytes(self, level: int) -> int:
        """GPU-resident bytes of the binned (CAP) position buffer at per-buffer level B: every
        vertex at max(B, m_v) bits per component, whole uint32 words (Meyer et al. 2011, 5.3).
        A clustered buffer (``lopcook.emit.clusters``) counts its words of P, 16 B per cluster
        record and the 128-byte ClusterId table."""
        if self.cluster_size is not None:
            from .clusters import CLUSTER_ID_BYTES, RECORD_WORDS

            return (4 * int(self.cluster_p_words[int(level) - 1]) + 4 * RECORD_WORDS * self.n_clusters
                    + CLUSTER_ID_BYTES)
        return self.unclustered_cap_bytes(level)

    def unclustered_cap_bytes(self, level: int) -> int:
        """Bytes the same vertices take in the unclustered binned layout at level B (for comparison)."""
        from .binning import buffer_bytes

        return buffer_bytes(np.asarray(self.vertex_id, dtype=np.int64), int(level))

    @property
    def cluster_header_bytes(self) -> int:
        """Stored bytes of its cluster headers (12 per cluster in ``positions/clusters``), 0 when unclustered."""
        return 12 * self.n_clusters

    def ap_bytes(self, level: int) -> int:
        """GPU-resident bytes of the uniform (AP) position buffer at level B: B bits per component
        for every vertex, whole uint32 words."""
        return 4 * ((3 * int(level) * self.vertices + 31) // 32)

    @property
    def float32_bytes(self) -> int:
        """Bytes of the same positions as float32 (12 per vertex)."""
        return FLOAT32_BYTES_PER_VERTEX * self.vertices

    @property
    def mandatory_bytes(self) -> int:
        """Stored bytes of its mandatory bits (the packed buffer at level 1: ``cap_bytes(1)`` for
        every container the reader accepts)."""
        return 4 * self.mandatory_words

    def plane_bytes(self, max_level: int) -> int:
        """Stored bits of its refinement planes 2..max_level, in bytes rounded up per plane (the
        planes of all buffers are packed together; this is this buffer's share)."""
        if self.cluster_plane_bits is not None:
            return sum((int(self.cluster_plane_bits[p - 2]) + 7) // 8 for p in range(2, int(max_level) + 1))
        return sum((3 * int(self.vertex_id[p - 1]) + 7) // 8 for p in range(2, int(max_level) + 1))

    @property
    def index_bytes(self) -> int:
        """Stored bytes of its index section."""
        return int(self.section_bytes.get("indices", 0))

    @property
    def attribute_bytes(self) -> int:
        """Stored bytes of its vertex attributes (the packed normal/UV/colour record section,
        ``4 ceil(n S / 32)``); indices not included."""
        return int(self.section_bytes.get("attributes", 0))


@dataclass(frozen=True)
class PartEntry:
    """One part of a container: its name, source path and LODs (LOD 0 first); for a placement
    (``cook --instances``) the part owning its buffers and its level shift (``placement_of`` None
    for a part on the scene grid)."""

    name: str
    source: str
    lods: tuple
    placement_of: int | None = None
    level_shift: int = 0

    def lod(self, k: int) -> LodEntry:
        """LOD k, or the coarsest when the chain is shorter (as a renderer draws it)."""
        return self.lods[min(int(k), len(self.lods) - 1)]


@dataclass(frozen=True)
class Manifest:
    """The typed view of a validated manifest (``Manifest.of(container.manifest)``)."""

    parts: tuple
    max_level: int

    @classmethod
    def of(cls, m: dict) -> "Manifest":
        sizes = {s["name"]: int(s["length"]) for s in m.get("sections", [])}
        parts = []
        for p in m["parts"]:
            lods = tuple(LodEntry(vertices=int(e["vertices"]), triangles=int(e["triangles"]),
                                  vertex_id=tuple(int(v) for v in e["vertex_id"]),
                                  geometric_error_m=float(e.get("geometric_error_m", 0.0)),
                                  min_distance_m=e.get("min_distance_m"), index_width=int(e.get("index_width") or 0),
                                  section_bytes={k: sizes.get(e.get(k) or "", 0) for k in ("indices", "attributes")},
                                  mandatory_words=int((e.get("mandatory_words") or [0, 0])[1]),
                                  attribute_bits=e.get("attribute_bits"), record_bits=int(e.get("record_bits") or 0),
                                  cluster_size=e.get("cluster_size"),
                                  cluster_p_words=None if e.get("cluster_p_words") is None
                                  else tuple(e["cluster_p_words"]),
                                  cluster_plane_bits=None if e.get("cluster_plane_bits") is None
                                  else tuple(e["cluster_plane_bits"]))
                         for e in p["lods"])
            pl = p.get("placement")
            parts.append(PartEntry(name=str(p["name"]), source=str(p.get("source", "")), lods=lods,
                                   placement_of=None if pl is None else int(pl["of"]),
                                   level_shift=0 if pl is None else int(pl["level_shift"])))
        return cls(parts=tuple(parts), max_level=int(m["positions"]["max_level"]))

    @property
    def has_placements(self) -> bool:
        """Whether any part is a placement of shared buffers (``cook --instances``)."""
        return any(p.placement_of is not None for p in self.parts)

    def part_level(self, i: int, level: int) -> int:
        """The per-buffer level part ``i`` decodes its buffer at when the scene asks for ``level``:
        ``level`` on the scene grid, ``clamp(level + level_shift, 1, 24)`` for a placement
        (``lopcook.emit.placement.local_level``)."""
        p = self.parts[i]
        return int(level) if p.placement_of is None else int(min(max(int(level) + p.level_shift, 1), LEVELS))

    def resident(self, level: int, lod: int = 0) -> list[tuple[LodEntry, int]]:
        """Every distinct buffer of LOD ``lod`` once, with the level it is resident at when every
        part asks for ``level``: a part on the scene grid at ``level``, a shared buffer at the
        maximum ``part_level`` over its placements (``placement.resident_level``)."""
        out, owners = [], {}
        for i, p in enumerate(self.parts):
            if p.placement_of is None:
                out.append((p.lod(lod), int(level)))
                continue
            j = p.placement_of
            if j not in owners:
                owners[j] = len(out)
                out.append((self.parts[j].lod(lod), self.part_level(i, level)))
            else:
                e, b = out[owners[j]]
                out[owners[j]] = (e, max(b, self.part_level(i, level)))
        return out

    def buffers(self, lod: int = 0) -> list[LodEntry]:
        """LOD ``lod`` of every part (a part's coarsest when its chain is shorter)."""
        return [p.lod(lod) for p in self.parts]

    def cap_bytes(self, level: int, lod: int = 0) -> int:
        """GPU-resident CAP position bytes at scene level ``level``: each distinct buffer once, at
        its resident level (``resident``; without placements every part at ``level``)."""
        return sum(e.cap_bytes(b) for e, b in self.resident(level, lod))

    def ap_bytes(self, level: int, lod: int = 0) -> int:
        """As ``cap_bytes`` for the uniform (AP) buffers."""
        return sum(e.ap_bytes(b) for e, b in self.resident(level, lod))

    def cap_bytes_all_copies(self, level: int, lod: int = 0) -> int:
        """CAP bytes if every placement had a buffer of its own (each at its ``part_level``): what
        storing each copy separately on its mesh grid would cost; equals ``cap_bytes`` without
        placements."""
        return sum(p.lod(lod).cap_bytes(self.part_level(i, level)) for i, p in enumerate(self.parts))

    def ap_bytes_all_copies(self, level: int, lod: int = 0) -> int:
        """As ``cap_bytes_all_copies`` for AP."""
        return sum(p.lod(lod).ap_bytes(self.part_level(i, level)) for i, p in enumerate(self.parts))

    def unclustered_cap_bytes(self, level: int, lod: int = 0) -> int:
        """As ``cap_bytes`` with every buffer in the unclustered layout (each distinct buffer once,
        at its resident level), for comparison."""
        return sum(e.unclustered_cap_bytes(b) for e, b in self.resident(level, lod))

    @property
    def clustered(self) -> bool:
        return any(e.clustered for p in self.parts for e in p.lods)

    def float32_bytes(self, lod: int = 0) -> int:
        """float32 position bytes of LOD ``lod`` of every part, every placement counted (as a
        scene without instancing stores them): the baseline its percentages use."""
        return sum(e.float32_bytes for e in self.buffers(lod))

    @property
    def float32_bytes_all_lods(self) -> int:
        """float32 position bytes of every buffer the container holds (all parts, all LODs)."""
        return sum(e.float32_bytes for p in self.parts for e in p.lods)
