"""``lopcook verify --decoders``: the GLSL and HLSL decoders of ``shaders/`` against the CPU reference.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 4 (crack-free per-vertex levels), 5.3 (binned buffers) and 6 (GPU decoding and adaption).

For every part and LOD of a container and every chosen per-buffer level B, the packed buffer P is
rebuilt on the CPU (``lopcook.lop.reader.gpu_buffer``), decoded by the vertex shader of each
language through transform feedback (``lopcook.verify.gpu``) and compared with the CPU reference
(``lopcook.lop.bitplane.decode`` + ``to_grid`` + ``reconstruct_float32``): grid integers, float32
bits and the bits per component used must all be equal (tolerance: 0 ulp). At the last chosen level
the crack-free path (``lop_decode_crack_free``) is compared with its CPU mirror from three cameras
(inside, near and far from the buffer's box). With ``adapt=True`` the
compute kernels also walk every buffer through the chosen levels plane by plane, and P, VertexId and
BitId must equal the CPU's packing of each level from scratch, byte for byte.

A clustered buffer (``cook --clusters N``, ``lopcook.lop.clusters``) is uploaded as a
renderer uploads it: its clustered P and cluster records (``reader.clustered_gpu_buffer``), decoded
by the ``LOP_CLUSTERED`` vertex shader of each language (``gpu.decode_clustered``, the crack-free
path included) and compared with the same global-grid reference at max(B, m_v) bits; its adaption
runs the ``LOP_CLUSTERED`` kernels (``gpu.ClusteredAdapter``) on the file's own plane slices
(``stored_plane_source``), and P, the cluster records (word 3 = ClusterBit), VertexId, ClusterId
and BitId = ClusterBit[ClusterId[k]] must equal the CPU's at every level. The CPU clustered decode
is also compared with the unclustered one (``clustered_cpu``).

The packed vertex attribute record of every part/LOD (section ``part{i}/lod{k}/attributes``:
octahedral normals, UVs, colours at the manifest's ``attribute_bits``; Purnomo et al. 2005,
sections 3-5) is decoded by ``shaders/decode_attributes.*`` in each language and compared with
``lopcook.lop.record.decode_record``: float32 bits of the unnormalised normal, UV and colour
must be equal (0 ulp).

It also holds the CPU mirror of the shaders' crack-free per-vertex level (``view_tables``,
``buffer_level``, ``vertex_levels``): the rule of ``lopcook.viewing.per_vertex_level``,
``max(min(own, B), bin level)``, with ``own`` computed in float32 from a distance bound that every
buffer holding the vertex computes identically (see ``vertex_levels``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import LopcookError
from ..grid import dx
from ..lop.binning import LEVELS, table_bit_id
from ..lop.bitplane import decode, reconstruct_float32, to_grid
from ..lop.clusters import cluster_bit, decode_clustered
from ..lop.codecs import CODECS, AttributeBits
from ..lop.reader import (buffer_clusters, clustered_gpu_buffer, gpu_buffer, lod_entry, owner, part_grid,
                          plane_slice, plane_slice_bits, top_values)
from ..lop.record import decode_record
from ..viewing import Viewing, nearest_box_distance
from . import gpu
from .attribute_gpu import attribute_decoder

MAX_EXAMPLES = 10
LENIENCE = np.float32(1.0 + 2.0**-18)  # the shaders' 1.0 + 1.0 / 262144.0
RADIUS_REL = 2.0**-10  # block radius margin, relative
RADIUS_ABS = 2.0**-21  # block radius margin, times |origin|max + extent (covers float32 rounding of p)
DIST_REL = 2.0**-8  # level distance margin, relative


# ---- levels ---------------------------------------------------------------------------------------

def parse_levels(text: str | None, path: str | None = None) -> list[int]:
    """``"1-24"``, ``"6,8,12"`` or ``"1-4,8,20-24"`` -> sorted unique levels in [1, 24] (None: 1..24)."""
    if text is None:
        return list(range(1, LEVELS + 1))
    levels: set[int] = set()
    for item in str(text).split(","):
        item = item.strip()
        try:
            if "-" in item:
                a, b = (int(v) for v in item.split("-", 1))
                if a > b:
                    raise LopcookError("usage", path, f"--levels {text!r}: the range {a}-{b} is reversed "
                                       f"(write {b}-{a})")
                levels.update(range(a, b + 1))
            else:
                levels.add(int(item))
        except ValueError:
            raise LopcookError("usage", path, f"--levels {text!r}: expected levels or ranges in [1, 24], "
                               f"e.g. 1-24 or 6,8,12") from None
    if not levels or min(levels) < 1 or max(levels) > LEVELS:
        raise LopcookError("usage", path, f"--levels {text!r}: levels must be in [1, {LEVELS}]")
    return sorted(levels)


# ---- crack-free per-vertex levels: CPU mirror of the shaders ---------------------------------------

def view_tables(extent: float, viewing: Viewing = Viewing(), origin=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(level_dist, block_radius), each (25,) float32 (index = level, 0 unused): the LopView tables.

    ``level_dist[b]``: camera distance (metres) from which b bits are enough,
    ``dx(b) / k * (1 + 2 k) * (1 + 2^-8)`` with ``k = pixel_error * 2 tan(fov_y / 2) / height``
    (the half-pixel criterion of ``lopcook.viewing.required_level``; the factor ``1 + 2 k`` pays for
    measuring the distance from a block centre plus its radius, the last factor for float32).
    ``block_radius[L]``: ``dx(L) (1 + 2^-10) + 2^-21 (max|origin| + extent)``, the distance from a
    level-L block centre to any point of the block, with a margin larger than float32 rounding.

    Guarantee (``vertex_levels``): a vertex's level L satisfies ``dx(L) <= k (d + 2^-21 S)``, with d
    its true distance to the camera and ``S = max|origin| + extent`` (metres).
    """
    k = viewing.pixel_error * 2.0 * math.tan(math.radians(viewing.fov_y_deg) / 2.0) / float(viewing.viewport[1])
    s = float(np.max(np.abs(np.asarray(origin, dtype=np.float64)))) + float(extent)
    levels = np.arange(LEVELS + 1, dtype=np.float64)
    d = dx(levels, extent)
    level_dist = (d / k * (1.0 + 2.0 * k) * (1.0 + DIST_REL)).astype(np.float32)
    radius = (d * (1.0 + RADIUS_REL) + RADIUS_ABS * s).astype(np.float32)
    level_dist[0] = radius[0] = 0.0
    return level_dist, radius


def buffer_level(camera, lo, hi, level_dist) -> int:
    """Per-buffer level for a camera (paper section 4: the box point closest to the camera decides):
    the smallest b with ``distance(camera, box) >= level_dist[b]``, 24 when none. ``lo, hi`` (3,)
    metres: any box holding the buffer's vertices (source positions or level-24 decoded ones).

    At least this level in every buffer sharing a vertex makes ``vertex_levels`` equal in all of them
    (the shader never needs more bits than any such buffer holds)."""
    d = nearest_box_distance(np.asarray(camera, dtype=np.float64), np.asarray(lo), np.asarray(hi))
    table = np.asarray(level_dist, dtype=np.float64)[1:LEVELS]
    return int(1 + np.count_nonzero(d < table))


def _own_level(p: np.ndarray, L: np.ndarray, camera32, level_dist, block_radius) -> np.ndarray:
    """float32 mirror of the shaders' lop_own_level for points p (m, 3) at levels L (m,)."""
    d = p - camera32
    d2 = (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2]
    lhs = d2 * LENIENCE
    r = np.asarray(block_radius, dtype=np.float32)[L]
    t = np.asarray(level_dist, dtype=np.float32)[None, 1:LEVELS] - r[:, None]
    t2 = t * t
    return 1 + np.count_nonzero((t > np.float32(0)) & (lhs[:, None] < t2), axis=1)


def vertex_levels(values, widths, bin_levels, level: int, origin, cell: float, camera,
                  level_dist, block_radius) -> np.ndarray:
    """Crack-free per-vertex levels, bit for bit what ``lop_vertex_level`` computes.

    Parameters
    ----------
    values : (n, 3) uint32 top bits at ``widths`` (``lopcook.lop.bitplane.decode``)
    widths : (n,) bits per component, max(bin level, B)
    bin_levels : (n,) each vertex's bin (minimum) level
    level : per-buffer level B
    origin, cell : the grid (metres), as for ``reconstruct_float32``
    camera : (3,) metres; level_dist, block_radius : ``view_tables``

    Returns (n,) int64 levels in [bin level, width]: the fixed point of L -> min(own(L), B) from
    L = 1, where own(L) is the level the view needs at |p_L - camera| + block_radius[L] (p_L the
    level-L block centre, an upper bound of the vertex's distance), then max(L, bin level). It reads
    only the top L bits, so co-located vertices get the same level in every buffer whose level is
    at least ``buffer_level`` for its box, whatever those levels are.
    """
    values = np.asarray(values, dtype=np.uint32)
    widths = np.asarray(widths, dtype=np.int64)
    n = values.shape[0]
    cam = np.asarray(camera, dtype=np.float32)
    L = np.ones(n, dtype=np.int64)
    active = np.ones(n, dtype=bool)
    for _ in range(LEVELS):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        Li = L[idx]
        v = values[idx] >> (widths[idx] - Li).astype(np.uint32)[:, None]
        p = reconstruct_float32(v, Li, origin, cell)
        want = np.minimum(_own_level(p, Li, cam, level_dist, block_radius), int(level))
        grow = want > Li
        L[idx[grow]] = want[grow]
        active[idx[~grow]] = False
    return np.maximum(L, np.asarray(bin_levels, dtype=np.int64))


def decode_crack_free(values, widths, bin_levels, level: int, origin, cell: float, camera, level_dist,
                      block_radius):
    """CPU mirror of ``lop_decode_crack_free``: (grid (n, 3) uint32, positions (n, 3) float32, levels)."""
    lv = vertex_levels(values, widths, bin_levels, level, origin, cell, camera, level_dist, block_radius)
    v = np.asarray(values, dtype=np.uint32) >> (np.asarray(widths, dtype=np.int64) - lv).astype(np.uint32)[:, None]
    return to_grid(v, lv), reconstruct_float32(v, lv, origin, cell), lv


# ---- the verification --------------------------------------------------------------------------------

def _ulp_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Elementwise distance in float32 units in the last place (ordered integer representation)."""
    def ordered(x):
        i = np.ascontiguousarray(x, dtype=np.float32).view(np.int32).astype(np.int64)
        return np.where(i < 0, -(i & 0x7FFFFFFF), i)

    return np.abs(ordered(a) - ordered(b))


def plane_source(c, part: int, lod: int):
    """``plane(p) -> (words, bit_offset)``: the container's plane section p as uint32 words and the bit
    offset of buffer (part, lod) inside it (buffers in manifest order), as a renderer uploads it
    (a clustered buffer's slice is ``reader.plane_slice_bits`` long)."""
    part = owner(c, part)  # a placement's buffer is its owner's
    if buffer_clusters(c, part, lod) is not None:
        # a clustered buffer's stored slice skips anchor-implied components: the unclustered
        # kernels get the unclustered plane of the same vertices (bit 24 - p of each component)
        vid = np.asarray(lod_entry(c, part, lod)["vertex_id"], dtype=np.int64)

        def unclustered(p: int):
            values, _ = top_values(c, part, lod, p)
            bits = (values[: int(vid[p - 1])] & 1).astype(np.uint8).ravel()
            padded = np.zeros(-(-max(bits.size, 1) // 32) * 32, np.uint8)
            padded[: bits.size] = bits
            return np.packbits(padded, bitorder="little").view("<u4").astype(np.uint32), 0

        return unclustered
    return stored_plane_source(c, part, lod)


def stored_plane_source(c, part: int, lod: int):
    """``plane(p) -> (words, bit_offset)``: the container's plane p as stored (uint32 words; in the
    streaming layout the plane of the buffer's stage) and the bit offset of buffer (part, lod)'s
    slice inside it (buffers in manifest order, each ``reader.plane_slice_bits`` long). For a
    clustered buffer this is the slice the
    ``LOP_CLUSTERED`` add-plane kernel reads (anchor-implied components skipped)."""
    part = owner(c, part)  # a placement's buffer is its owner's
    lod_entry(c, part, lod)  # LopcookError for a part or LOD that does not exist

    def plane(p: int):
        data, start = plane_slice(c, part, lod, p)  # the buffer's stage's plane (docs/format.md 14)
        return np.frombuffer(data.tobytes(), dtype="<u4"), start

    return plane


def _buffers(c):
    """(part, lod) of every distinct buffer: a placement sharing another part's buffers
    (``cook --instances``) is decoded once, through its owner, on the owner's mesh grid."""
    for i, p in enumerate(c.manifest["parts"]):
        if owner(c, i) != i:
            continue
        for k, _ in enumerate(p["lods"]):
            yield i, k


def verify_decoders(c, levels=None, languages=("glsl", "hlsl"), *, adapt: bool = True,
                    max_examples: int = MAX_EXAMPLES) -> dict:
    """Decode every part/LOD of container ``c`` at ``levels`` with each language and compare.

    Returns a report dict (JSON-ready, sorted keys when dumped): ``ok``, per-language counts under
    ``languages`` (``_language_stats``: vertices decoded, grid / float / level mismatches, max float
    distance in ulp, adaption steps and mismatches, attribute records decoded and their normal / UV
    / colour mismatches and max ulp; ``clustered_decoded_vertices`` / ``clustered_adapt_steps``:
    those done by the ``LOP_CLUSTERED`` shaders; ``per_level[str(B)]``: vertex decodes and decode
    mismatches (grid, float or bits wrong) at level B, and adaption checks on arriving at B and
    their mismatches); ``attribute_buffers`` counts the buffers with an attribute record; the first
    ``max_examples`` mismatches under ``examples``, the context (``device``) and tool versions.
    Raises LopcookError when GL or the HLSL tools are missing or a level is not in the file.

    Per distinct buffer (``_buffers``): (1) every chosen level decoded and compared, the crack-free
    path at the last (``_verify_decodes``); (2) with ``adapt``, the kernels' walk through the levels
    (``_verify_adapt`` / ``_verify_clustered_adapt``); (3) the attribute record
    (``_verify_attributes``).
    """
    levels = _checked_levels(c, levels, languages)
    cluster_stats = {"decoded_vertices": 0, "mismatches": 0}
    stats = {lang: _language_stats(levels) for lang in languages}
    examples: list[dict] = []
    buffers = list(_buffers(c))
    vertices = 0
    attribute_buffers = 0
    clustered_buffers = 0
    for part, lod in buffers:
        grid = part_grid(c, part)  # the scene grid, or a shared buffer's mesh grid
        clustered = buffer_clusters(c, part, lod) is not None
        clustered_buffers += clustered
        vertices += _verify_decodes(c, part, lod, levels, languages, grid, clustered, stats, cluster_stats,
                                    examples, max_examples)
        if adapt and levels:
            if clustered:
                _verify_clustered_adapt(c, part, lod, levels, languages, stats, examples, max_examples)
            else:
                _verify_adapt(c, part, lod, levels, languages, stats, examples, max_examples)
        attribute_buffers += _verify_attributes(c, part, lod, languages, stats, examples, max_examples)
    ok = all(s["grid_mismatches"] == 0 and s["float_mismatches"] == 0 and s["level_mismatches"] == 0
             and s["crack_free_mismatches"] == 0 and s["adapt_mismatches"] == 0
             and all(s[key] == 0 for _, key in ATTRIBUTE_OUTPUTS) for s in stats.values())
    ok = ok and cluster_stats["mismatches"] == 0
    for s in stats.values():
        s["decode_seconds"] = round(s["decode_seconds"], 4)
        s["adapt_seconds"] = round(s["adapt_seconds"], 4)
        s["attribute_seconds"] = round(s["attribute_seconds"], 4)
    return {
        "container": None if c.path is None else str(c.path),
        "levels": levels,
        "buffers": len(buffers),
        "clustered_buffers": int(clustered_buffers),
        "attribute_buffers": attribute_buffers,
        "vertices": vertices,
        "float_ulp_tolerance": 0,
        "languages": stats,
        "clustered_cpu": cluster_stats,
        "examples": examples,
        "ok": bool(ok),
        "device": gpu.context_info(),
        "tools": gpu.tool_versions() if "hlsl" in languages else {},
    }


def _checked_levels(c, levels, languages) -> list[int]:
    """The sorted distinct levels to verify (None: 1..24), after checking that each is in [1, 24]
    and in the file, that every language is known, that the HLSL tools are there when asked for
    and that a GL context opens; each failure is a LopcookError."""
    levels = parse_levels(None, c.path) if levels is None else sorted(set(int(v) for v in levels))
    if levels and (levels[0] < 1 or levels[-1] > LEVELS):
        raise LopcookError("usage", c.path, f"levels must be in [1, {LEVELS}], got {levels}")
    if levels and levels[-1] > c.available_level:
        raise LopcookError("usage", c.path, f"level {levels[-1]} is not in this file (it holds levels up to "
                           f"{c.available_level})", hint=f"use --levels 1-{c.available_level}")
    for lang in languages:
        if lang not in gpu.LANGUAGES:
            raise LopcookError("usage", c.path, f"unknown shader language {lang!r} (expected glsl or hlsl)")
    if "hlsl" in languages:
        gpu.require_hlsl_tools()
    gpu.context()
    return levels


def _language_stats(levels: list[int]) -> dict:
    """One language's zeroed counters (``verify_decoders``'s ``languages[lang]``); times in seconds."""
    return {"decoded_vertices": 0, "grid_mismatches": 0, "float_mismatches": 0, "level_mismatches": 0,
            "max_float_ulp": 0, "decode_seconds": 0.0, "crack_free_vertices": 0, "crack_free_mismatches": 0,
            "adapt_steps": 0, "adapt_mismatches": 0, "adapt_seconds": 0.0, "attribute_vertices": 0,
            **{key: 0 for _, key in ATTRIBUTE_OUTPUTS}, "attribute_max_ulp": 0,
            "attribute_seconds": 0.0, "clustered_decoded_vertices": 0, "clustered_adapt_steps": 0,
            "per_level": {str(v): {"decoded_vertices": 0, "decode_mismatches": 0, "adapt_checks": 0,
                                   "adapt_mismatches": 0} for v in levels}}


def _verify_decodes(c, part, lod, levels, languages, grid, clustered: bool, stats, cluster_stats, examples,
                    max_examples) -> int:
    """Buffer (part, lod) decoded at every level of ``levels`` by each language and compared with
    the CPU reference; at the last level the crack-free path too (``_verify_crack_free``).
    ``grid``: (origin (3,), extent) metres of the buffer's grid. A clustered buffer's CPU decode
    is first compared with the unclustered one (``cluster_stats``), then the ``LOP_CLUSTERED``
    shaders decode it. Returns the buffer's vertex count."""
    origin, extent = grid
    cell = extent / float(1 << LEVELS)
    half = np.float32(cell / 2.0)
    vertices = 0
    for level in levels:
        buf = gpu_buffer(c, part, lod, level)
        values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
        cbuf = None
        if clustered:  # the clustered CPU decode must equal the unclustered one exactly
            cbuf = clustered_gpu_buffer(c, part, lod, level)
            cvals, cwidths = decode_clustered(cbuf.words, cbuf.clusters, level)
            bad = np.any(cvals != values, axis=1) | (cwidths != widths)
            cluster_stats["decoded_vertices"] += int(widths.size)
            cluster_stats["mismatches"] += int(bad.sum())
        ref = (to_grid(values, widths), reconstruct_float32(values, widths, origin, cell), widths)
        if level == levels[0]:
            vertices += int(buf.vertex_id[LEVELS])
        for lang in languages:
            _compare_decode(c, part, lod, level, lang, buf, cbuf, (origin, half), ref, stats[lang], examples,
                            max_examples)
        if level == levels[-1] and widths.size:
            _verify_crack_free(c, part, lod, buf, values, widths, ref[1], languages, stats, examples,
                               max_examples, cbuf)
    return vertices


def _compare_decode(c, part, lod, level: int, lang: str, buf, cbuf, grid, ref, s: dict, examples: list,
                    max_examples: int) -> None:
    """One language's vertex decode of buffer (part, lod) at ``level`` against the CPU reference,
    counted into that language's stats ``s`` (and ``s["per_level"]``); mismatches are added to
    ``examples`` while fewer than ``max_examples`` are held.

    ``buf``: the ``GpuBuffer``; ``cbuf``: its ``ClusteredGpuBuffer`` (then the ``LOP_CLUSTERED``
    shader decodes what a renderer uploads: clustered P and its records) or None. ``grid``:
    (origin (3,) metres, half cell float32 metres). ``ref``: (grid integers (n, 3) uint32,
    float32 positions (n, 3), bits per component (n,))."""
    origin, half = grid
    ref_grid, ref_pos, widths = ref
    t0 = time.perf_counter()
    if cbuf is None:
        got = gpu.vertex_decoder(lang).decode(buf.words, buf.vertex_id, buf.bit_id, level, origin, half)
    else:  # what a renderer uploads for a clustered buffer: clustered P and its records
        got = _decode_clustered(c, part, lod, lang, cbuf, origin, half)
        s["clustered_decoded_vertices"] += int(widths.size)
    s["decode_seconds"] += time.perf_counter() - t0
    bad_grid = np.any(got.grid != ref_grid, axis=1)
    bad_float = np.any(got.position.view(np.uint32) != ref_pos.view(np.uint32), axis=1)
    bad_level = got.level.astype(np.int64) != widths
    s["decoded_vertices"] += int(widths.size)
    s["grid_mismatches"] += int(bad_grid.sum())
    s["float_mismatches"] += int(bad_float.sum())
    s["level_mismatches"] += int(bad_level.sum())
    per = s["per_level"][str(level)]
    per["decoded_vertices"] += int(widths.size)
    per["decode_mismatches"] += int((bad_grid | bad_float | bad_level).sum())
    if widths.size:
        s["max_float_ulp"] = max(s["max_float_ulp"], int(_ulp_distance(got.position, ref_pos).max()))
    for j in np.flatnonzero(bad_grid | bad_float | bad_level)[: max(0, max_examples - len(examples))]:
        examples.append({"language": lang, "kind": "decode", "part": part, "lod": lod, "level": level,
                         "clustered": cbuf is not None, "vertex": int(j), "expected_grid": ref_grid[j].tolist(),
                         "got_grid": got.grid[j].tolist(),
                         "expected_position": [float(v) for v in ref_pos[j]],
                         "got_position": [float(v) for v in got.position[j]],
                         "expected_bits": int(widths[j]), "got_bits": int(got.level[j])})


# ---- clustered buffers (LOP_CLUSTERED) ------------------------------------------------------------

def verify_clustered_decode(words, records, cluster_id, vertex_id, cluster_size: int, level: int, origin, cell: float,
                            values, widths, languages=("glsl", "hlsl")) -> dict:
    """Decode one clustered buffer with the ``LOP_CLUSTERED`` vertex shader of each language and
    compare with the CPU reference's decode ``(values, widths)`` (top bits (n, 3) and bits per
    component (n,), e.g. ``lopcook.lop.clusters.decode_clustered``): grid integers
    (``to_grid``), float32 bits (``reconstruct_float32``, 0 ulp) and widths.

    ``words``: P at ``level``; ``records``: (n_c, 4) uint32 with word 3 = ClusterBit at ``level``;
    ``cluster_id``, ``vertex_id``: (25,); ``cell``: extent / 2^24 metres. Returns ``{language:
    {decoded_vertices, grid_mismatches, float_mismatches, level_mismatches, max_float_ulp}}``, the
    per-language counters of ``verify_decoders``, so a container walk can add them up."""
    values = np.asarray(values, dtype=np.uint32)
    widths = np.asarray(widths, dtype=np.int64)
    ref_grid = to_grid(values, widths)
    ref_pos = reconstruct_float32(values, widths, origin, cell)
    half = np.float32(cell / 2.0)
    out = {}
    for lang in languages:
        got = gpu.decode_clustered(lang, words, records, cluster_id, vertex_id, cluster_size, level, origin, half)
        out[lang] = {
            "decoded_vertices": int(widths.size),
            "grid_mismatches": int(np.any(got.grid != ref_grid, axis=1).sum()),
            "float_mismatches": int(np.any(got.position.view(np.uint32) != ref_pos.view(np.uint32), axis=1).sum()),
            "level_mismatches": int((got.level.astype(np.int64) != widths).sum()),
            "max_float_ulp": int(_ulp_distance(got.position, ref_pos).max()) if widths.size else 0,
        }
    return out


def verify_clustered_adapt(words_at, records_at, cluster_id, vertex_id, cluster_size: int, levels, plane,
                           languages=("glsl", "hlsl")) -> dict:
    """Walk one clustered buffer through ``adapt_walk(levels)`` plane by plane with the
    ``LOP_CLUSTERED`` kernels of each language; after every step P and the cluster records must
    equal the CPU's from scratch. ``words_at(B)`` / ``records_at(B)``: the CPU's P and (n_c, 4)
    records at level B; ``plane(p)``: (uint32 words, bit offset) of this buffer's slice of plane
    p. Returns ``{language: {adapt_steps, adapt_mismatches}}``."""
    chosen = sorted(set(int(v) for v in levels))
    walk = [chosen[0], *adapt_walk(chosen)]
    out = {}
    for lang in languages:
        ad = gpu.clustered_adapter(lang)
        steps = bad = 0
        buf = ad.upload(words_at(walk[0]), records_at(walk[0]), cluster_id, vertex_id, cluster_size, walk[0])
        try:
            for target in walk[1:]:
                while buf.level != target:
                    ad.adapt(buf, buf.level + (1 if target > buf.level else -1), plane)
                    steps += 1
                    bad += not (np.array_equal(buf.read_words(), np.asarray(words_at(buf.level), dtype=np.uint32))
                                and np.array_equal(buf.read_records(), np.asarray(records_at(buf.level))))
        finally:
            buf.release()
        out[lang] = {"adapt_steps": steps, "adapt_mismatches": bad}
    return out


CAMERA_DISTANCES = (0.25, 4.0, 64.0)  # in grid extents from the buffer's box centre: inside, near, far


def _verify_crack_free(c, part, lod, buf, values, widths, positions, languages, stats, examples,
                       max_examples, cbuf=None) -> None:
    """``lop_decode_crack_free`` against ``decode_crack_free`` at the buffer's level, from three
    cameras (inside the box, near, far) looking along +z; viewing conditions from the manifest.
    ``cbuf``: the buffer's ``ClusteredGpuBuffer`` at that level, decoded by the ``LOP_CLUSTERED``
    crack-free path instead (same reference)."""
    origin, extent = part_grid(c, part)
    cell = extent / float(1 << LEVELS)
    viewing = _manifest_viewing(c)
    level_dist, radius = view_tables(extent, viewing, origin)
    counts = np.diff(np.asarray(buf.vertex_id, dtype=np.int64), prepend=0)
    counts[0] = 0
    bin_levels = np.repeat(np.arange(LEVELS + 1), counts)
    centre = (positions.min(axis=0).astype(np.float64) + positions.max(axis=0)) / 2.0
    for f in CAMERA_DISTANCES:
        camera = centre + np.array([0.0, 0.0, f * extent])
        ref_grid, ref_pos, ref_level = decode_crack_free(values, widths, bin_levels, buf.level, origin, cell, camera,
                                                         level_dist, radius)
        for lang in languages:
            view = (camera, level_dist, radius)
            if cbuf is None:
                got = gpu.vertex_decoder(lang, crack_free=True).decode(
                    buf.words, buf.vertex_id, buf.bit_id, buf.level, origin, np.float32(cell / 2.0), view=view)
            else:
                got = _decode_clustered(c, part, lod, lang, cbuf, origin, np.float32(cell / 2.0), view=view)
            bad = (np.any(got.grid != ref_grid, axis=1) | np.any(got.position.view(np.uint32) != ref_pos.view(np.uint32),
                                                                   axis=1) | (got.level.astype(np.int64) != ref_level))
            stats[lang]["crack_free_vertices"] += int(bad.size)
            stats[lang]["crack_free_mismatches"] += int(bad.sum())
            for j in np.flatnonzero(bad)[: max(0, max_examples - len(examples))]:
                examples.append({"language": lang, "kind": "crack_free", "clustered": cbuf is not None,
                                 "part": part, "lod": lod,
                                 "level": int(buf.level), "camera": [float(v) for v in camera], "vertex": int(j),
                                 "expected_level": int(ref_level[j]), "got_level": int(got.level[j]),
                                 "expected_position": [float(v) for v in ref_pos[j]],
                                 "got_position": [float(v) for v in got.position[j]]})


#: per codec, the count of vertices whose decode differs: "normal_mismatches", "uv_mismatches", ...
ATTRIBUTE_OUTPUTS = tuple((c.name, f"{c.singular}_mismatches") for c in CODECS)


def attribute_record(c, part: int, lod: int):
    """``(words, n, bits, entry)`` of buffer (part, lod)'s packed attribute record as a renderer
    uploads it: the section's uint32 words, the vertex count, the manifest's ``attribute_bits`` as
    ``lopcook.lop.codecs.AttributeBits`` and the LOD entry (the codecs' LOD fields): the arguments
    of ``decode_record``. None when the LOD has no attribute record."""
    e = lod_entry(c, part, lod)
    if e.get("attributes") is None:
        return None
    words = np.frombuffer(c.section(e["attributes"]), dtype="<u4")
    return words, int(e["vertices"]), AttributeBits.of(e.get("attribute_bits") or {}), e


def _verify_attributes(c, part, lod, languages, stats, examples, max_examples) -> int:
    """``shaders/decode_attributes.*`` against ``decode_record`` for one buffer: float32 bits of every
    present attribute (0 ulp). Returns 1 when the buffer has an attribute record, else 0."""
    rec = attribute_record(c, part, lod)
    if rec is None:
        return 0
    words, n, bits, entry = rec
    ref = decode_record(words, n, bits, entry)
    for lang in languages:
        s = stats[lang]
        t0 = time.perf_counter()
        got = attribute_decoder(lang).decode(words, n, bits, entry)
        s["attribute_seconds"] += time.perf_counter() - t0
        s["attribute_vertices"] += n
        for name, key in ATTRIBUTE_OUTPUTS:
            want = ref.get(name)
            if want is None or got[name] is None:
                if (want is None) != (got[name] is None):
                    s[key] += n
                continue
            want = np.ascontiguousarray(want, dtype=np.float32)
            bad = np.any(got[name].view(np.uint32) != want.view(np.uint32), axis=1)
            s[key] += int(bad.sum())
            if n:
                s["attribute_max_ulp"] = max(s["attribute_max_ulp"], int(_ulp_distance(got[name], want).max()))
            for j in np.flatnonzero(bad)[: max(0, max_examples - len(examples))]:
                examples.append({"language": lang, "kind": "attributes", "attribute": name, "part": part,
                                 "lod": lod, "vertex": int(j), "expected": [float(v) for v in want[j]],
                                 "got": [float(v) for v in got[name][j]]})
    return 1


def _manifest_viewing(c) -> Viewing:
    """The viewing conditions recorded in the container (defaults where absent or invalid)."""
    v = c.manifest.get("viewing") or {}
    try:
        return Viewing(viewport=tuple(v.get("viewport", (1920, 1080))), fov_y_deg=float(v.get("fov_y_deg", 60.0)),
                       pixel_error=float(v.get("pixel_error", 0.5)))
    except (TypeError, ValueError):
        return Viewing()


def adapt_walk(levels: list[int]) -> list[int]:
    """Levels visited by the adaption check: the chosen levels in order, then back to the first."""
    return list(levels[1:]) + ([levels[0]] if len(levels) > 1 else [])


def _verify_adapt(c, part, lod, levels, languages, stats, examples, max_examples) -> None:
    """The adaption kernels walk an unclustered buffer through ``adapt_walk(levels)`` one plane at
    a time, fed ``plane_source``; after each chosen level P, VertexId and BitId must equal the
    CPU's (``reader.gpu_buffer`` at that level)."""
    first = gpu_buffer(c, part, lod, levels[0])
    if int(first.vertex_id[LEVELS]) == 0:
        return
    plane = plane_source(c, part, lod)
    for lang in languages:
        ad = gpu.adapter(lang)
        s = stats[lang]
        t0 = time.perf_counter()
        buf = ad.upload(first.words, first.vertex_id, levels[0])
        try:
            for target in adapt_walk(levels):
                s["adapt_steps"] += abs(target - buf.level)
                ad.adapt(buf, target, plane)
                ref = gpu_buffer(c, part, lod, target)
                vid, bid = buf.read_tables()
                words = buf.read_words()
                same = (np.array_equal(words, ref.words) and np.array_equal(vid[: LEVELS + 1], ref.vertex_id)
                        and np.array_equal(bid[: LEVELS + 1], table_bit_id(ref.vertex_id, target)))
                _record_adapt(s, target, same, examples, max_examples,
                              lambda: _adapt_example(lang, part, lod, target, ref.words, words))
        finally:
            buf.release()
        s["adapt_seconds"] += time.perf_counter() - t0


def _record_adapt(s: dict, target: int, same: bool, examples: list, max_examples: int, example) -> None:
    """Count one adaption check at ``target`` in language stats ``s``; a mismatch adds
    ``example()`` to ``examples`` while fewer than ``max_examples`` are held."""
    per = s["per_level"][str(target)]
    per["adapt_checks"] += 1
    if not same:
        s["adapt_mismatches"] += 1
        per["adapt_mismatches"] += 1
        if len(examples) < max_examples:
            examples.append(example())


def _adapt_example(lang, part, lod, target, expected, got, **extra) -> dict:
    """One adaption mismatch as the report lists it: the word counts and the first differing word
    (None when the counts differ), plus ``extra`` keys."""
    return {"language": lang, "kind": "adapt", **({"clustered": True} if extra.pop("clustered", False) else {}),
            "part": part, "lod": lod, "level": target, "words_expected": int(expected.size),
            "words_got": int(got.size),
            "first_bad_word": int(np.argmax(got[: expected.size] != expected)) if got.size == expected.size else None,
            **extra}


def _decode_clustered(c, part, lod, lang, cbuf, origin, half_cell, view=None):
    """``gpu.decode_clustered`` of a container's ClusteredGpuBuffer; a buffer outside what the
    clustered decoder accepts (2^26 vertices or more) is a LopcookError naming it."""
    cl = cbuf.clusters
    try:
        return gpu.decode_clustered(lang, cbuf.words, cbuf.records, cl.cluster_id, cl.vertex_id, cl.size, cbuf.level,
                                    origin, half_cell, view=view)
    except ValueError as exc:
        raise LopcookError("verify", c.path, f"part {part} LOD {lod}: the clustered decoder cannot take this "
                           f"buffer: {exc}", hint="cook it unclustered (--clusters 0) or with fewer vertices "
                           "per part") from None


def _verify_clustered_adapt(c, part, lod, levels, languages, stats, examples, max_examples) -> None:
    """The ``LOP_CLUSTERED`` kernels walk a clustered buffer through ``adapt_walk(levels)`` one
    plane at a time, fed the file's own plane slices; after each chosen level P, the cluster
    records, VertexId, ClusterId and BitId (= ClusterBit[ClusterId[k]]) must equal the CPU's
    (``reader.clustered_gpu_buffer`` at that level)."""
    first = clustered_gpu_buffer(c, part, lod, levels[0])
    cl = first.clusters
    if cl.n == 0:
        return
    plane = stored_plane_source(c, part, lod)
    refs: dict = {}
    for lang in languages:
        ad = gpu.clustered_adapter(lang)
        s = stats[lang]
        t0 = time.perf_counter()
        buf = ad.upload(first.words, first.records, cl.cluster_id, cl.vertex_id, cl.size, levels[0])
        try:
            for target in adapt_walk(levels):
                steps = abs(target - buf.level)
                s["adapt_steps"] += steps
                s["clustered_adapt_steps"] += steps
                ad.adapt(buf, target, plane)
                if target not in refs:
                    refs[target] = clustered_gpu_buffer(c, part, lod, target)
                ref = refs[target]
                vid, bid, cid = buf.read_tables()
                words, rec = buf.read_words(), buf.read_records()
                same = (np.array_equal(words, ref.words) and np.array_equal(rec, ref.records)
                        and np.array_equal(vid[: LEVELS + 1], cl.vertex_id)
                        and np.array_equal(cid[: LEVELS + 1], cl.cluster_id)
                        and np.array_equal(bid[: LEVELS + 1], cluster_bit(cl, target)[cl.cluster_id]))
                _record_adapt(s, target, same, examples, max_examples,
                              lambda: _adapt_example(lang, part, lod, target, ref.words, words, clustered=True,
                                                     records_equal=bool(np.array_equal(rec, ref.records))))
        finally:
            buf.release()
        s["adapt_seconds"] += time.perf_counter() - t0


def format_report(report: dict) -> str:
    """Human-readable summary: one line per language, then the first mismatches."""
    lines = [f"{report['container']}: {report['buffers']} buffers, {report['vertices']:,} vertices, levels "
             f"{_levels_text(report['levels'])} on {report['device']['renderer']}"]
    for lang, s in report["languages"].items():
        bad = s["grid_mismatches"] + s["float_mismatches"] + s["level_mismatches"]
        lines.append(f"  {lang}: {s['decoded_vertices']:,} vertex decodes, {bad} mismatches "
                     f"(grid {s['grid_mismatches']}, float {s['float_mismatches']}, bits {s['level_mismatches']}; "
                     f"max {s['max_float_ulp']} ulp) in {s['decode_seconds']:.2f} s; crack-free: "
                     f"{s['crack_free_vertices']:,} decodes, {s['crack_free_mismatches']} mismatches; adaption: {s['adapt_steps']} "
                     f"plane steps, {s['adapt_mismatches']} mismatches in {s['adapt_seconds']:.2f} s")
        bad_levels = [f"{b}: {v['decode_mismatches']} decode, {v['adapt_mismatches']} adapt"
                      for b, v in (s.get("per_level") or {}).items() if v["decode_mismatches"] or v["adapt_mismatches"]]
        if bad_levels:
            lines.append(f"  {lang} mismatches by level: " + "; ".join(bad_levels))
        attr_bad = sum(s[key] for _, key in ATTRIBUTE_OUTPUTS)
        each = ", ".join(f"{key.split('_')[0]} {s[key]}" for _, key in ATTRIBUTE_OUTPUTS)
        lines.append(f"  {lang} attributes: {s['attribute_vertices']:,} records in {report['attribute_buffers']} buffers, "
                     f"{attr_bad} mismatches ({each}; max {s['attribute_max_ulp']} ulp) in {s['attribute_seconds']:.2f} s")
    if report.get("clustered_buffers"):
        lines.append(f"  clustered buffers: {report['clustered_buffers']} of {report['buffers']}, decoded by the "
                     "LOP_CLUSTERED shaders: " + "; ".join(
                         f"{lang} {s['clustered_decoded_vertices']:,} vertex decodes, {s['clustered_adapt_steps']} "
                         "plane steps" for lang, s in report["languages"].items()))
    cs = report.get("clustered_cpu") or {}
    if cs.get("decoded_vertices"):
        lines.append(f"  clustered CPU decode: {cs['decoded_vertices']:,} vertex decodes, {cs['mismatches']} "
                     "mismatches against the unclustered reference")
    for e in report["examples"]:
        lines.append(f"  mismatch: {e}")
    lines.append("  ok: decoders are bit-exact" if report["ok"] else "  FAILED: decoders differ from the CPU reference")
    return "\n".join(lines)


def _levels_text(levels: list[int]) -> str:
    """Sorted levels as runs: ``[1, 2, 3, 6, 8, 9]`` -> ``"1-3,6,8-9"``; ``"none"`` when empty."""
    if not levels:
        return "none"
    runs, start, prev = [], levels[0], levels[0]
    for v in levels[1:] + [None]:
        if v is not None and v == prev + 1:
            prev = v
            continue
        runs.append(f"{start}-{prev}" if prev > start else f"{start}")
        if v is not None:
            start = prev = v
    return ",".join(runs)


__all__ = ["verify_clustered_decode", "verify_clustered_adapt", "parse_levels", "view_tables", "buffer_level", "vertex_levels", "decode_crack_free", "plane_source", "stored_plane_source",
           "attribute_record", "verify_decoders", "adapt_walk", "format_report"]
