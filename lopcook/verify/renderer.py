"""The GL side of the render harness: programs, multisampled framebuffers, textures, vertex buffers
and the ``Harness`` that holds them for one source scene (moderngl on the process's EGL context,
``lopcook.verify.gpu.context``).

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 6.2 (positions decoded in the vertex shader) and Fig. 13 (renders against floating-point
vertices).

Draws: AP and CAP positions are decoded **on the GPU** by ``lop_decode`` of
``shaders/decode_bitplanes.glsl`` in the vertex shader (``lopcook.verify.glsl``), never by the
CPU; a clustered buffer (``cook --clusters N``) is uploaded as clustered P plus its cluster
records and drawn by the ``LOP_CLUSTERED`` build of that shader (``Renderer.cluster_decode_program``).
Float draws the source's normals, UVs and colours; AP and CAP the container's decoded ones (its
packed attribute record, normals normalised per vertex), all with the source's textures.

Shading (``Shading``, ``lopcook.verify.glsl.FS``): Phong with one directional headlight (light
direction = from the box centre to the eye); ambient 0.15, diffuse 0.65, ks and shininess from the
container's analysis options (``manifest["options"]["analyse"]``; defaults 0.5 and 32) so the
k_f = ks * n the analysis assumed is the one rendered. Base-colour textures are sampled with
trilinear mipmaps and repeat wrap, texel values used as they are (no sRGB decoding); vertex colours
are linear RGB as stored; grey 0.8 when a part has neither. Depth test on. Back faces
(clockwise in the window) of a single-sided part are culled, as glTF and USD renderers do for
a surface not marked ``doubleSided`` (``MeshPart.double_sided``); a double-sided part draws both
sides. The float reference and every decoded variant of a part are culled alike, so a tiny
triangle whose winding quantization flips is missing from the decoded render, as it would be
in an engine, and the metrics count it.

Coverage cull (``Coverage``, ``covering_triangles``): an item's triangles whose screen box, widened
by ``COVER_MARGIN`` pixels, holds no sample position of the viewport (and, where back faces are
culled, those facing away by more than that margin could change) are left out of the draw: the
images are the same bit for bit (``tests/verify/test_render_cull.py``; how and when: docs/verify.md).

Framebuffer: ``SAMPLES`` x MSAA (4, or the context's maximum when lower), colour RGBA8 (alpha = 1
where a sample saw the object; the background is cleared to 0, 0, 0, 0), a part-ID target R32UI
(``part index + 1``, 0 = background) written by the same fragment shader in the same pass, and a
24-bit depth buffer, all multisampled. Colour is resolved by a framebuffer blit (average of the
samples) and read back as 8 bits per channel: the images are what an 8-bit display shows, and alpha
is the pixel's coverage. The ID target is resolved by taking **sample 0** of each pixel, a
documented convention. Images are returned top row first.
"""

from __future__ import annotations

import atexit
import hashlib
import math
import zlib
from dataclasses import dataclass

import numpy as np

from ..lop.bitplane import decode, reconstruct_float32
from ..lop.clusters import decode_clustered
from ..lop.placement import split, to_world
from ..lop.reader import ClusteredGpuBuffer, lod_attributes, owner, part_grid, placement_transform, world_normals
from ..errors import LopcookError
from ..memory import available_bytes, release_free_memory
from ..settings import DEFAULTS
from . import gpu
from .buffers import resident_levels
from .cameras import Camera
from .glsl import FS, RESOLVE_FS, RESOLVE_VS, vertex_shader_source
from .gpu import check_cluster_tables, cluster_decode_block, decode_block

#: render size (width, height) in pixels by default
RESOLUTION = DEFAULTS.render.resolution
#: MSAA samples per pixel by default
SAMPLES = DEFAULTS.render.samples
#: Phong ambient and diffuse weights (dimensionless)
AMBIENT = 0.15
DIFFUSE = 0.65
#: base colour of a part with neither texture nor vertex colours (linear grey)
BASE_GREY = 0.8
#: pixels added on every side of the projected box a draw is limited to (``Renderer.screen_rect``)
RECT_MARGIN = 2
#: the most bytes a harness's float-render cache holds (cropped renders, ``Harness``)
FLOAT_CACHE_BYTES = 384 << 20
#: a draw finishes the GL queue (``glFinish``) after this many triangles, to bound llvmpipe's memory
FINISH_TRIANGLES = 1 << 18
#: the bytes of a float-render cache held uncompressed; entries past them are compressed (``_pack``)
RAW_CACHE_BYTES = 64 << 20
#: the raw share of a shared harness's float cache (``shared_harness``: the searches of a cook read
#: the watched levels' renders, small ones, at every probe; the close-ups once or twice)
SHARED_RAW_BYTES = 16 << 20
#: a draw item is culled only when its box is beyond a clip plane by this share of |w| (float32 slack)
CULL_MARGIN = 1e-4
#: pixels a triangle's screen box is widened by before the coverage test (``covering_triangles``)
COVER_MARGIN = 1.0 / 32.0
#: the coverage test runs for an item with at least this many triangles per pixel of its projected box
COVER_DENSITY = 2.0
#: ... and at least this many triangles
COVER_MIN_TRIANGLES = 4096
#: ``covering_triangles`` tests at most this many triangles at a time (its temporaries stay in the CPU's cache)
COVER_CHUNK = 1 << 16
#: candidate sample positions: multiples of 1/16 pixel (``sample_positions``)
SAMPLE_LATTICE = 16


def _crop(rgba: np.ndarray, ids: np.ndarray):
    """(box, rgba crop, ids crop) of a render: the box of its non-background pixels (alpha > 0 or a
    part ID), None when there are none; IDs as uint16 when they fit."""
    # one 32-bit word per pixel (R, G, B, A bytes): elementwise passes, no gathers
    px = np.ascontiguousarray(rgba).view(np.uint32).reshape(rgba.shape[:2])
    alpha = px & np.uint32(0xFF << 24) if np.little_endian else px & np.uint32(0xFF)
    occupied = (alpha != 0) | (ids != 0)
    rows = np.flatnonzero(occupied.any(axis=1))
    if rows.size == 0 and not px.any():
        return None, np.zeros((0, 0, 4), np.uint8), np.zeros((0, 0), np.uint16)
    if rows.size == 0 or np.any((px != 0) & ~occupied):
        box = (0, rgba.shape[0], 0, rgba.shape[1])  # background not the clear colour: keep it all
    else:
        cols = np.flatnonzero(occupied.any(axis=0))
        box = (int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1)
    crop = ids[box[0]:box[1], box[2]:box[3]]
    crop = crop.astype(np.uint16) if int(ids.max(initial=0)) < 65536 else crop.copy()
    return box, rgba[box[0]:box[1], box[2]:box[3]].copy(), crop


def _pack(entry) -> tuple:
    """A ``_crop`` entry with its two crops compressed (zlib level 1, which the background and flat
    shading suit; docs/verify.md, "Reuse"); ``_unpack`` gives back the same arrays."""
    box, rgba_c, ids_c = entry
    return (box, zlib.compress(rgba_c.tobytes(), 1), rgba_c.shape, zlib.compress(ids_c.tobytes(), 1),
            ids_c.shape, ids_c.dtype.str)


def _unpack(packed) -> tuple:
    """The ``_crop`` entry of a ``_pack`` result (arrays equal to the packed ones, bit for bit)."""
    box, rgba_z, rgba_shape, ids_z, ids_shape, ids_dtype = packed
    rgba_c = np.frombuffer(zlib.decompress(rgba_z), np.uint8).reshape(rgba_shape)
    ids_c = np.frombuffer(zlib.decompress(ids_z), np.dtype(ids_dtype)).reshape(ids_shape)
    return box, rgba_c, ids_c


def _packed_bytes(packed) -> int:
    return len(packed[1]) + len(packed[3])


def digest(*parts) -> bytes:
    """A 32-byte BLAKE2b digest of ``parts`` (numpy arrays by dtype, shape and bytes; other values by
    ``repr``), in order: the content key of what a draw reads (``decoded_items``' item digests)."""
    hsh = hashlib.blake2b(digest_size=32)
    for x in parts:
        if isinstance(x, np.ndarray):
            a = np.ascontiguousarray(x)
            hsh.update(repr((a.dtype.str, a.shape)).encode())
            hsh.update(a.tobytes())
        elif isinstance(x, (bytes, bytearray)):
            hsh.update(b"b%d:" % len(x))
            hsh.update(x)
        else:
            hsh.update(repr(x).encode())
        hsh.update(b"|")
    return hsh.digest()


def _expand(entry, size) -> tuple[np.ndarray, np.ndarray]:
    """The full (rgba, ids) render of a ``_crop`` entry at ``size`` (w, h)."""
    box, rgba_c, ids_c = entry
    w, h = size
    rgba = np.zeros((h, w, 4), np.uint8)
    ids = np.zeros((h, w), np.uint32)
    if box is not None:
        rgba[box[0]:box[1], box[2]:box[3]] = rgba_c
        ids[box[0]:box[1], box[2]:box[3]] = ids_c
    return rgba, ids


@dataclass(frozen=True)
class Shading:
    """Phong parameters (dimensionless): ambient, diffuse, ks, shininess; base grey in [0, 1]."""

    ks: float = 0.5
    shininess: float = 32.0
    ambient: float = AMBIENT
    diffuse: float = DIFFUSE
    base: float = BASE_GREY

    @classmethod
    def from_manifest(cls, manifest: dict, ks: float | None = None, shininess: float | None = None) -> "Shading":
        """Phong parameters of a container: ks and shininess from ``manifest['options']['analyse']``
        (defaults 0.5 and 32, the analysis defaults), each replaced by the argument when given;
        ambient, diffuse and base grey the module defaults."""
        a = (manifest.get("options") or {}).get("analyse") or {}
        return cls(ks=float(a.get("ks", 0.5) if ks is None else ks),
                   shininess=float(a.get("shininess", 32.0) if shininess is None else shininess))

    def as_dict(self) -> dict:
        """JSON-ready record of the shading: model, light, ks, shininess, ambient, diffuse, base grey, and
        which faces are drawn (the renderer's rule, module doc)."""
        return {"model": "phong", "light": "directional headlight (from the scene centre to the eye)",
                "ks": self.ks, "shininess": self.shininess, "ambient": self.ambient, "diffuse": self.diffuse,
                "base_grey": self.base,
                "back_faces": "culled unless the part is double-sided (glTF or USD doubleSided)"}


#: the placement rows of a part on the scene grid (the harness vertex shader's u_place0..2)
IDENTITY_ROWS = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))


# ---- the coverage cull ------------------------------------------------------------------------------

_PROBE_VS = """#version 450
in vec2 in_xy;
void main() { gl_Position = vec4(in_xy, 0.0, 1.0); }
"""
_PROBE_FS = """#version 450
layout(location = 0) out vec4 o_color;
void main() { o_color = vec4(1.0); }
"""


def sample_positions(ctx, samples: int):
    """(k, 2) float64 sample offsets (x right, y up, pixels from the pixel's lower left corner) of a
    ``samples``-sample colour target on ``ctx``, or None when they are not all found on the lattice of
    ``SAMPLE_LATTICE``-ths of a pixel.

    One draw into a 16 x 16 target: pixel (a, b) holds a triangle of radius 1/64 pixel around the
    candidate (a / 16, b / 16) (a, b in 1..15); a pixel with coverage has a sample there. The result
    is trusted only when exactly ``max(samples, 1)`` candidates are covered, each by exactly one
    sample (coverage 1 / samples); a sample off the lattice by more than 1/64 pixel is found nowhere,
    and the cull is then off."""
    import moderngl  # optional native GL binding: imported where a draw needs it, here and below

    n = SAMPLE_LATTICE
    samples = int(samples)
    r = 1.0 / 64.0
    pts = []
    for a in range(1, n):
        for b in range(1, n):
            cx, cy = a + a / n, b + b / n  # pixel (a, b), candidate (a / n, b / n)
            for x, y in ((cx - r, cy - r), (cx + r, cy - r), (cx, cy + r)):
                pts.append((x / n * 2.0 - 1.0, y / n * 2.0 - 1.0))
    owned = []
    try:
        prog = ctx.program(vertex_shader=_PROBE_VS, fragment_shader=_PROBE_FS)
        vbo = ctx.buffer(np.asarray(pts, "<f4").tobytes())
        vao = ctx.vertex_array(prog, [(vbo, "2f", "in_xy")])
        rb_ms = ctx.renderbuffer((n, n), 4, samples=samples)
        fbo_ms = ctx.framebuffer([rb_ms])
        rb = ctx.renderbuffer((n, n), 4)
        fbo = ctx.framebuffer([rb])
        owned = [prog, vbo, vao, rb_ms, fbo_ms, rb, fbo]
        fbo_ms.use()
        fbo_ms.clear(0.0, 0.0, 0.0, 0.0)
        ctx.disable(moderngl.DEPTH_TEST)
        vao.render(moderngl.TRIANGLES)
        ctx.copy_framebuffer(fbo, fbo_ms)
        alpha = np.frombuffer(fbo.read(components=4, dtype="f1"), np.uint8).reshape(n, n, 4)[..., 3]
    finally:
        for o in owned:
            o.release()

        gpu.use_default_framebuffer()
    want = max(samples, 1)
    b_idx, a_idx = np.nonzero(alpha)  # rows are y (GL: bottom row first)
    if len(a_idx) != want:
        return None
    if want > 1 and not np.all(np.abs(alpha[b_idx, a_idx].astype(np.int64) - round(255 / want)) <= 1):
        return None
    return np.stack([a_idx / n, b_idx / n], axis=1).astype(np.float64)


def covering_triangles(px: np.ndarray, py: np.ndarray, ok: np.ndarray, triangles: np.ndarray, size,
                       offsets: np.ndarray, margin: float = COVER_MARGIN,
                       cull_back: bool = False) -> np.ndarray:
    """(m,) bool: the triangles that may cover a sample of a ``size`` = (w, h) pixel viewport
    (and, with ``cull_back``, may face the viewer).

    px, py : (n,) window coordinates of the vertices, pixels (x right, y up, the viewport's lower
    left corner at 0); ok : (n,) bool, False for a vertex whose projection is not trusted (behind
    the eye, not finite): a triangle with such a vertex is kept. triangles : (m, 3) vertex indices,
    or a tuple of its three columns. offsets : (k, 2) sample offsets within a pixel, multiples of
    1 / ``SAMPLE_LATTICE`` (``sample_positions``). A triangle is dropped only when its box, widened by ``margin`` on every
    side, holds no point (i + sx, j + sy) with pixel (i, j) in the viewport: such a triangle covers
    no sample (it lies inside its box).

    In lattice units (1 / L pixel, L = ``SAMPLE_LATTICE``) the box holds the integers lo..hi of each
    axis (clipped to the viewport's), and a sample column at offset a (a lattice integer, 0 <= a < L)
    lies in it exactly when ``(a - lo) mod L <= hi - lo``; rows likewise, and columns and rows are
    independent.

    ``cull_back`` (a draw with back faces culled, counter-clockwise front): a triangle with trusted
    vertices is also dropped when it faces away beyond what moving each vertex by ``margin`` pixels
    could change: twice its signed window area, ``A = u x v`` with ``u = b - a``, ``v = c - a``, below
    ``-(2 margin (|u|_1 + |v|_1) + 8 margin^2 + 2^-20 (|u_x v_y| + |u_y v_x|))`` (the last term for
    the float32 products). GL culls it too, whatever its own rounding and snapping (within the
    margin); a triangle nearly edge-on is left to GL."""
    t = np.stack([np.asarray(x) for x in triangles], axis=1) if isinstance(triangles, tuple) else \
        np.asarray(triangles).reshape(-1, 3)
    m = t.shape[0]
    trusted = bool(ok.all())
    if m <= COVER_CHUNK:
        return _covering_chunk(px, py, ok, trusted, t, size, offsets, margin, cull_back)
    out = np.empty(m, dtype=bool)
    step = -(-m // -(-m // COVER_CHUNK))  # chunks of equal size, none above COVER_CHUNK
    for s in range(0, m, step):
        out[s:s + step] = _covering_chunk(px, py, ok, trusted, t[s:s + step], size, offsets, margin, cull_back)
    return out


def _covering_chunk(px, py, ok, trusted: bool, triangles, size, offsets, margin, cull_back):
    """``covering_triangles`` of (k, 3) ``triangles`` in one pass (k up to ``COVER_CHUNK``; ``trusted``:
    ``ok.all()``)."""
    w, h = int(size[0]), int(size[1])
    lat = SAMPLE_LATTICE
    # the corners' indices as one (3, k) intp array: one gather per axis reads all three corners
    # (numpy gathers with intp indices at a fraction of the cost of three uint32 columns)
    corners = np.array(triangles.T, dtype=np.intp, order="C")
    if trusted:  # (``Coverage.select`` tests only such items)
        hit = np.zeros(corners.shape[1], dtype=bool)
    else:
        hit = ~np.take(ok, corners).all(axis=0)

    gx = np.take(px, corners)  # (3, m): x of corners a, b, c, each row contiguous
    gy = np.take(py, corners)
    del corners
    back = None
    if cull_back:
        ux, uy = gx[1] - gx[0], gy[1] - gy[0]
        vx, vy = gx[2] - gx[0], gy[2] - gy[0]
        uv, vu = ux * vy, uy * vx
        area = uv - vu
        e = np.float32(margin)
        for d in (ux, uy, vx, vy):
            np.abs(d, out=d)
        slack = ux + uy
        slack += vx
        slack += vy
        slack *= np.float32(2.0) * e
        slack += np.float32(8.0) * e * e
        np.abs(uv, out=uv)
        np.abs(vu, out=vu)
        uv += vu
        uv *= np.float32(2.0 ** -20)
        slack += uv
        back = area < -slack
        del ux, uy, vx, vy, uv, vu, area, slack
        if not trusted:  # a triangle with an untrusted vertex (hit so far) is kept
            back &= ~hit

    def span(g, n_px):
        va, vb, vc = g
        lo = np.minimum(np.minimum(va, vb), vc)
        hi = np.maximum(np.maximum(va, vb), vc)
        del va, vb, vc
        lo -= np.float32(margin)
        lo *= np.float32(lat)
        hi += np.float32(margin)
        hi *= np.float32(lat)
        # clipped to the viewport's lattice points [0, n_px * L - 1] (float32 holds them exactly)
        np.ceil(lo, out=lo)
        np.maximum(lo, np.float32(0.0), out=lo)
        np.floor(hi, out=hi)
        np.minimum(hi, np.float32(n_px * lat - 1), out=hi)
        hi -= lo  # the span, negative when the box misses the viewport
        return lo.astype(np.int32), hi.astype(np.int32)

    x_lo, x_span = span(gx, w)
    y_lo, y_span = span(gy, h)
    del gx, gy
    k = np.rint(np.asarray(offsets, np.float64) * lat).astype(np.int32)
    d = np.empty_like(x_lo)
    for ax, ay in k:
        np.subtract(ax, x_lo, out=d)
        d &= lat - 1
        inx = d <= x_span
        np.subtract(ay, y_lo, out=d)
        d &= lat - 1
        inx &= d <= y_span
        hit |= inx
    if back is not None:
        hit &= ~back
    return hit


#: which corner of a box takes the high end of each axis (x slowest, z fastest)
_CORNER_HIGH = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=bool)


def box_corners(lo, hi) -> np.ndarray:
    """(..., 8, 3) float64 corners of the boxes ``lo``..``hi`` ((..., 3) each; one box: (8, 3)),
    x slowest, z fastest."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return np.where(_CORNER_HIGH, hi[..., None, :], lo[..., None, :])


def window_coordinates(positions: np.ndarray, mvp: np.ndarray, size):
    """(px, py, ok) of ``positions`` (n, 3) float32 metres under ``mvp`` (4, 4), both in float32 as
    the vertex shader has them, in a ``size`` viewport: window x, y (float32 pixels, origin lower
    left) and whether each is trusted (w > 0 and finite). The float32 arithmetic here and the
    shader's differ by a few units in the last place of the clip coordinates: far below
    ``COVER_MARGIN`` at any viewport this harness renders."""
    m = np.asarray(mvp, np.float64).astype(np.float32)
    p = np.asarray(positions, np.float32)
    q = m[(0, 1, 3), :3] @ p.T  # (3, n): x, y and w of the clip coordinates, each row contiguous
    q += m[(0, 1, 3), 3][:, None]
    with np.errstate(all="ignore"):
        cw = q[2]
        ok = cw > np.float32(0.0)
        inv = np.float32(1.0) / (cw if ok.all() else np.where(ok, cw, np.float32(1.0)))
        px, py = q[0], q[1]  # (x / w + 1) * w_px / 2, in place, in that order (float32)
        px *= inv
        px += np.float32(1.0)
        px *= np.float32(0.5 * float(size[0]))
        py *= inv
        py += np.float32(1.0)
        py *= np.float32(0.5 * float(size[1]))
        ok &= (np.abs(px) < np.float32(1e30)) & (np.abs(py) < np.float32(1e30))  # finite, and not huge
    if not ok.all():
        px[~ok] = 0.0
        py[~ok] = 0.0
    return px, py, ok


class Coverage:
    """What the coverage cull needs of one draw item: its triangles (m, 3) in draw order (the caller's
    array, kept by reference), the positions (n, 3) float32 metres its vertex shader computes (an
    array, or a function giving it once, on first use), and the program and vertex specs its VAO
    was made with (a second VAO reads the kept triangles from a scratch index buffer: the
    renderer's ``Scratch``, or one of its own). ``release`` frees what it made.

    Shared culls (``Harness.share_culls``): with ``slack_m`` > 0 every cull of this item also holds
    each triangle that a copy of the item with every position moved by up to ``slack_m`` metres per
    axis could need (the margin grows by a bound on how far such a move projects,
    ``projected_slack``), and is remembered in ``memo`` (camera key -> packed bits). An item whose
    ``twin`` is such a Coverage -- the same triangles, positions within the twin's ``slack_m`` --
    draws the twin's remembered cull for that camera instead of computing its own."""

    def __init__(self, ctx, program, specs, triangles, positions):
        self.ctx, self.program, self.specs = ctx, program, list(specs)
        self._triangles = triangles  # the caller's index array, not copied
        self.count = int(np.asarray(triangles).size // 3)
        self._positions = positions
        self._box = None  # (lo, hi) of the positions, or False when there are none
        self._corners = None  # (8, 3) float32 corners of the box
        self._ibo = self._vao = None  # the scratch buffer the VAO reads, and the VAO
        self._own = None  # a Scratch of this item's own, when select() is given none
        #: metres per axis that a twin's positions may differ by (0: culls are not shared)
        self.slack_m = 0.0
        #: {(camera matrix bytes, size, cull_back): np.packbits(keep)} of culls a twin may read, or None
        self.memo = None
        #: a Coverage whose remembered culls this item draws (same triangles, positions within its slack)
        self.twin = None

    @property
    def triangles(self) -> np.ndarray:
        """(m, 3) vertex indices in draw order (a view of the caller's array)."""
        return np.asarray(self._triangles).reshape(-1, 3)

    @property
    def positions(self) -> np.ndarray:
        """(n, 3) positions, metres (float32 as uploaded, or the float64 they were rounded from)."""
        if callable(self._positions):
            self._positions = np.asarray(self._positions(), np.float32)
        return self._positions

    def projected_slack(self, camera: Camera, size, px, py) -> float | None:
        """Pixels (a bound, in x and y alike) by which moving any position of this item by up to
        ``slack_m`` metres per axis moves its window coordinates from ``camera`` in a ``size``
        viewport; None when no bound holds (the box reaches within that move of the eye plane).

        With clip coordinates X = r0 . p + t0, W = r3 . p + t3 and a move d (|d_i| <= s), the
        normalised x moves by |(r0 . d - x_ndc r3 . d) / (W + r3 . d)| <= (a + |x_ndc| b) / (W_min - b),
        a = |r0|_1 s, b = |r3|_1 s, W_min the least W over the box's corners (W is affine), |x_ndc| at
        most its largest over the vertices (from ``px``; likewise y): times half the viewport."""
        s = float(self.slack_m)
        mvp = np.asarray(camera.mvp, np.float64)
        lo, hi = self._box
        corners = box_corners(lo, hi)
        b = float(np.abs(mvp[3, :3]).sum()) * s
        w_min = float((corners @ mvp[3, :3]).min() + mvp[3, 3]) - b
        if not w_min > 0.0:
            return None
        out = 0.0
        for row, coords, n_px in ((0, px, size[0]), (1, py, size[1])):
            half = 0.5 * float(n_px)
            ndc = max(abs(float(coords.max()) / half - 1.0), abs(float(coords.min()) / half - 1.0))
            a = float(np.abs(mvp[row, :3]).sum()) * s
            out = max(out, half * (a + ndc * b) / w_min)
        return out if math.isfinite(out) else None

    def select(self, camera: Camera, size, offsets, scratch: "Scratch | None" = None,
               cull_back: bool = False) -> tuple | None:
        """(VAO, index count) drawing only the triangles that may cover a sample from ``camera``, or
        None when the test would not pay (``COVER_MIN_TRIANGLES``, ``COVER_DENSITY``: the item then
        draws its own VAO). ``scratch``: the renderer's index buffer shared by every item (GL
        keeps a draw's indices whatever is written to its buffer after it), else one of this item's
        own. ``cull_back``: the draw culls back faces, so clearly back-facing triangles are left
        out too (``covering_triangles``). A ``twin``'s remembered cull from this camera is drawn
        as it is (class doc)."""
        m = self.count
        if m < COVER_MIN_TRIANGLES:
            return None
        key = (np.asarray(camera.mvp).tobytes(), tuple(size), bool(cull_back))
        twin = self.twin
        if twin is not None and twin.memo is not None and twin.count == m:
            bits = twin.memo.get(key)
            if bits is not None:
                keep = np.unpackbits(bits, count=m).view(bool)
                return self._upload(np.compress(keep, self.triangles, axis=0), scratch)
        if self._box is None:
            p = self.positions
            self._box = (p.min(axis=0).astype(np.float64), p.max(axis=0).astype(np.float64)) if p.size else False
            if self._box is not False:  # its 8 corners, float32
                lo, hi = self._box
                self._corners = box_corners(lo, hi).astype(np.float32)
        if self._box is False:
            return None
        # the projected box first (8 corners): most items of a close view are not worth testing
        cx, cy, cok = window_coordinates(self._corners, camera.mvp, size)
        if cok.all():
            w, h = float(size[0]), float(size[1])
            area = max(0.0, min(w, float(cx.max())) - max(0.0, float(cx.min())) + 2.0) * \
                max(0.0, min(h, float(cy.max())) - max(0.0, float(cy.min())) + 2.0)
            if m < COVER_DENSITY * max(area, 1.0):
                return None
        px, py, ok = window_coordinates(self.positions, camera.mvp, size)
        if not ok.all():
            return None
        w, h = float(size[0]), float(size[1])
        area = max(0.0, min(w, float(px.max())) - max(0.0, float(px.min())) + 2.0) * \
            max(0.0, min(h, float(py.max())) - max(0.0, float(py.min())) + 2.0)
        if m < COVER_DENSITY * max(area, 1.0):
            return None
        t = self.triangles
        margin, remember = COVER_MARGIN, False
        if self.memo is not None:
            extra = self.projected_slack(camera, size, px, py) if self.slack_m > 0.0 else 0.0
            if extra is not None:
                margin, remember = COVER_MARGIN + extra, True
        keep = covering_triangles(px, py, ok, t, size, offsets, margin=margin, cull_back=cull_back)
        if remember:
            self.memo[key] = np.packbits(keep)
        return self._upload(np.compress(keep, t, axis=0), scratch)  # (compress: a tenth of t[keep]'s time)

    def _upload(self, kept: np.ndarray, scratch: "Scratch | None") -> tuple:
        """(VAO, index count) drawing the (k, 3) triangles ``kept`` from the scratch index buffer."""
        if kept.dtype != np.dtype("<u4"):
            kept = kept.astype("<u4")
        if scratch is None:
            scratch = self._own = self._own or Scratch(self.ctx)
        ibo = scratch.fit(kept.nbytes)
        if self._vao is None or self._ibo is not ibo:  # a VAO on the scratch buffer as it is now
            if self._vao is not None:
                self._vao.release()
            self._ibo = ibo
            self._vao = self.ctx.vertex_array(self.program, self.specs, index_buffer=ibo, index_element_size=4)
        if kept.size:
            ibo.write(kept.tobytes())
        return self._vao, int(kept.size)

    def release(self) -> None:
        if self._vao is not None:
            self._vao.release()
        if self._own is not None:
            self._own.release()
        self._ibo = self._vao = self._own = None


class Scratch:
    """One index buffer the coverage cull writes each item's kept triangles to, grown (replaced) to
    the most bytes asked for; ``fit(n)`` returns it, at least ``n`` bytes long."""

    def __init__(self, ctx):
        self.ctx, self.buffer = ctx, None

    def fit(self, nbytes: int):
        if self.buffer is None or self.buffer.size < nbytes:
            if self.buffer is not None:
                self.buffer.release()
            self.buffer = self.ctx.buffer(reserve=max(12, int(nbytes) + int(nbytes) // 4))
        return self.buffer

    def release(self) -> None:
        if self.buffer is not None:
            self.buffer.release()
            self.buffer = None


# ---- the renderer -----------------------------------------------------------------------------------

class Renderer:
    """Programs and framebuffers for one resolution ``(w, h)`` pixels on the process's EGL context
    (``lopcook.verify.gpu.context``), with ``samples`` MSAA samples (at most the context's maximum
    for colour and integer targets). ``draw`` renders draw items and returns the resolved colour and
    part-ID images. Raises LopcookError (usage, exit 2) for a resolution below 1 x 1."""

    def __init__(self, resolution=RESOLUTION, samples: int = SAMPLES):
        self.ctx = ctx = gpu.context()
        w, h = (int(resolution[0]), int(resolution[1]))
        if w < 1 or h < 1:
            raise LopcookError("usage", None, f"resolution must be positive, got {w}x{h}")
        self.size = (w, h)
        samples = int(min(samples, ctx.max_samples, ctx.max_integer_samples))
        self.samples = samples
        self.float_program = ctx.program(vertex_shader=vertex_shader_source(False), fragment_shader=FS)
        self.decode_program = ctx.program(vertex_shader=vertex_shader_source(True), fragment_shader=FS)
        self.resolve_program = ctx.program(vertex_shader=RESOLVE_VS, fragment_shader=RESOLVE_FS)
        self.resolve_vao = ctx.vertex_array(self.resolve_program, [])
        # colour, part IDs and depth at every sample, then the resolved colour and IDs: 4 bytes each,
        # in the process's own memory where the renderer is software (llvmpipe)
        need = w * h * (12 * samples + 8)
        renderer = str(ctx.info.get("GL_RENDERER", "")).lower()
        software = any(name in renderer for name in ("llvmpipe", "softpipe", "swrast"))
        avail = available_bytes() if software else None
        if avail is not None and need > avail:
            raise LopcookError("usage", None, f"a {w}x{h} render with {samples}x MSAA needs {need / 1e9:.1f} GB of "
                               f"framebuffers; {avail / 1e9:.1f} GB are available", hint="use a smaller --resolution")
        try:
            self._colour_ms = ctx.renderbuffer((w, h), 4, samples=samples)
            self._ids_ms = ctx.texture((w, h), 1, dtype="u4", samples=samples)
            self._depth_ms = ctx.depth_renderbuffer((w, h), samples=samples)
            self.fbo_ms = ctx.framebuffer([self._colour_ms, self._ids_ms], self._depth_ms)
            self.fbo_ms_colour = ctx.framebuffer([self._colour_ms])  # the blit source (same renderbuffer)
            self._colour = ctx.renderbuffer((w, h), 4)
            self.fbo_colour = ctx.framebuffer([self._colour])
            self._ids = ctx.texture((w, h), 1, dtype="u4")
            self.fbo_ids = ctx.framebuffer([self._ids])
        except Exception as exc:  # noqa: BLE001 - the driver's limit (framebuffer incomplete, out of memory)
            raise LopcookError("usage", None, f"OpenGL ({ctx.info.get('GL_RENDERER', '?')}) cannot make a {w}x{h} "
                               f"render target with {samples}x MSAA ({exc})",
                               hint="use a smaller --resolution") from None
        self._resources = [self.float_program, self.decode_program, self.resolve_program, self.resolve_vao,
                           self.fbo_ms, self.fbo_ms_colour, self._colour_ms, self._ids_ms, self._depth_ms,
                           self.fbo_colour, self._colour, self.fbo_ids, self._ids]
        #: the sample offsets the coverage cull tests against (None: every triangle is drawn)
        self.sample_offsets = sample_positions(ctx, samples)
        #: the index buffer the cull writes every item's kept triangles to
        self.scratch = Scratch(ctx)
        #: ``draw``'s finish threshold: None for ``FINISH_TRIANGLES`` (a caller may bound memory further)
        self.finish_triangles = None

    @property
    def cluster_decode_program(self):
        """The decode program built with ``LOP_CLUSTERED`` (clustered buffers; compiled on first use)."""
        if getattr(self, "_cluster_program", None) is None:
            self._cluster_program = self.ctx.program(vertex_shader=vertex_shader_source(True, clustered=True),
                                                     fragment_shader=FS)
            self._resources.append(self._cluster_program)
        return self._cluster_program

    def _uniforms(self, program, camera: Camera, shading: Shading) -> None:
        program["u_mvp"].write(camera.mvp.T.astype("<f4").tobytes())
        light = camera.eye - camera.centre
        light = light / np.linalg.norm(light)
        for name, value in (("u_eye", tuple(float(v) for v in camera.eye)),
                            ("u_light", tuple(float(v) for v in light)),
                            ("u_phong", (shading.ambient, shading.diffuse, shading.ks, shading.shininess)),
                            ("u_base", (shading.base,) * 3), ("u_texture", 0)):
            if name in program:
                program[name].value = value

    def screen_rect(self, camera: Camera, items):
        """(x, y, w, h) pixels (GL convention, origin bottom left) holding every fragment of
        ``items``: the projection of the union of their boxes (each item's ``box`` = (lo, hi) world
        metres bounding every position it can draw) widened by ``RECT_MARGIN`` pixels and clipped
        to the viewport; None (the whole viewport) when an item has no box or a box corner is not
        in front of the eye."""
        boxes = [it.get("box") for it in items]
        w, h = self.size
        if not boxes or any(b is None for b in boxes):
            return None
        lo = np.min([b[0] for b in boxes], axis=0).astype(np.float64)
        hi = np.max([b[1] for b in boxes], axis=0).astype(np.float64)
        corners = np.c_[box_corners(lo, hi), np.ones(8)]
        clip = corners @ np.asarray(camera.mvp, np.float64).T
        if not np.all(clip[:, 3] > 1e-6 * np.abs(clip[:, :3]).max(initial=1.0)) or not np.all(np.isfinite(clip)):
            return None
        px = (clip[:, 0] / clip[:, 3] + 1.0) * 0.5 * w
        py = (clip[:, 1] / clip[:, 3] + 1.0) * 0.5 * h
        x0 = max(0, int(math.floor(px.min())) - RECT_MARGIN)
        x1 = min(w, int(math.ceil(px.max())) + RECT_MARGIN)
        y0 = max(0, int(math.floor(py.min())) - RECT_MARGIN)
        y1 = min(h, int(math.ceil(py.max())) + RECT_MARGIN)
        if x1 <= x0 or y1 <= y0:
            return (0, 0, 1, 1)
        return (x0, y0, x1 - x0, y1 - y0)

    @staticmethod
    def outside(camera: Camera, box) -> bool:
        """Whether no point of ``box`` = (lo, hi) world metres can be inside ``camera``'s clip volume:
        all 8 corners lie beyond one clip plane (-w <= x, y, z <= w) by more than ``CULL_MARGIN`` of
        their |w| (the box is convex, so every point of it, and every triangle drawn inside it, is
        clipped away whole: a draw that skips it gives the same pixels). False for no box."""
        return bool(Renderer.outside_all(camera, [box])[0])

    @staticmethod
    def outside_all(camera: Camera, boxes) -> np.ndarray:
        """(k,) bool: ``outside(camera, box)`` of each of the k ``boxes`` (each (lo, hi) or None), in
        one pass (a draw asks it of every item)."""
        out = np.zeros(len(boxes), dtype=bool)
        have = [i for i, b in enumerate(boxes) if b is not None]
        if not have:
            return out
        lo = np.array([np.asarray(boxes[i][0], np.float64) for i in have])  # (m, 3)
        hi = np.array([np.asarray(boxes[i][1], np.float64) for i in have])
        corners = box_corners(lo, hi)  # (m, 8, 3)
        mvp = np.asarray(camera.mvp, np.float64)
        clip = corners @ mvp[:, :3].T + mvp[:, 3]  # (m, 8, 4), as [corner, 1] @ mvp.T
        finite = np.isfinite(clip).all(axis=(1, 2))
        w = clip[..., 3]
        slack = CULL_MARGIN * np.abs(w) + 1e-12
        beyond = np.zeros(len(have), dtype=bool)
        for k in range(3):
            beyond |= np.all(clip[..., k] - w > slack, axis=1) | np.all(-clip[..., k] - w > slack, axis=1)
        out[np.asarray(have)] = beyond & finite
        return out

    def draw(self, items, camera: Camera, shading: Shading, decoded: bool, crop: bool = False):
        """Render ``items`` (dicts with ``vao``, ``part``, ``has_normal``, ``has_color``, ``texture``, and
        ``ssbo`` / ``ubo`` when ``decoded``; a clustered item also ``clusters`` (the records SSBO,
        binding 3) and ``program`` (the program its ``vao`` was made with); optional ``box``) from
        ``camera`` with ``shading``, depth
        test on, back faces culled unless the item is ``two_sided`` (default True: both sides drawn).
        Returns ``(rgba (h, w, 4) uint8, ids (h, w) uint32)``, top row first:
        the MSAA-averaged colour (alpha = coverage, background 0) and sample 0 of the part-ID target
        (part index + 1, 0 = background). Clear, draw, resolve and read-back are limited to
        ``screen_rect`` (outside it no fragment can land: the pixels there are the background the
        whole-viewport render would give, filled in on the CPU). An item whose ``cull_box`` (world
        metres bounding every position it can draw; default its ``box``) is ``outside`` the view is
        not drawn (it could not put a fragment in the image); an item's ``cover`` (a ``Coverage``)
        leaves out the triangles that cover no sample, and those GL would cull as back faces (module
        doc, "Coverage cull"). Before an item, once ``FINISH_TRIANGLES`` (or the renderer's
        ``finish_triangles``) triangles (items' ``triangles``) have been drawn since the last one,
        the context is finished (``glFinish``): the pixels are the same (GL keeps the order of the
        draws), and llvmpipe's binned scene, which otherwise holds every triangle of the frame until
        the read-back (docs/verify.md, "Flush after every item"), holds about that many. After every item
        the context is flushed (``gpu.flush``: llvmpipe rasterises that item while this process
        culls and binds the next; the pixels are the same). Leaves the context's default 1x1
        framebuffer bound. ``crop``: only the region read back, ``(rgba (r1 - r0, c1 - c0, 4), ids)``
        for ``last_box`` = (r0, r1, c0, c1) (outside it the whole image is background), with no
        whole-image arrays made (read-only views of the read-back, not C-contiguous)."""
        import moderngl  # optional native GL binding, imported where a draw needs it

        ctx = self.ctx
        program = self.decode_program if decoded else self.float_program
        self._uniforms(program, camera, shading)
        base, primed = program, {id(program)}
        rect = self.screen_rect(camera, items)
        full = (0, 0, self.size[0], self.size[1])
        region = full if rect is None else rect
        for fbo in (self.fbo_ms, self.fbo_ms_colour, self.fbo_colour, self.fbo_ids):
            fbo.scissor = None if rect is None else rect
        self.fbo_ms.use()
        self.fbo_ms.clear(0.0, 0.0, 0.0, 0.0, depth=1.0, viewport=None if rect is None else rect)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        ctx.front_face, ctx.cull_face = "ccw", "back"
        culling = False  # the context's CULL_FACE as set
        queued = 0  # triangles drawn since the last finish
        gone = self.outside_all(camera, [it.get("cull_box", it.get("box")) for it in items])
        for it, skip in zip(items, gone):
            if skip:
                continue
            cull = not it.get("two_sided", True)
            if cull != culling:
                (ctx.enable if cull else ctx.disable)(moderngl.CULL_FACE)
                culling = cull
            vao, count = it["vao"], None
            cover = it.get("cover")
            if cover is not None and self.sample_offsets is not None:
                picked = cover.select(camera, self.size, self.sample_offsets, self.scratch, cull_back=cull)
                if picked is not None:
                    vao, count = picked
                    if count == 0:  # no triangle covers a sample: nothing to draw
                        continue
            if queued >= (FINISH_TRIANGLES if self.finish_triangles is None else self.finish_triangles):
                ctx.finish()
                queued = 0
            queued += int(it.get("triangles", 0)) if count is None else count // 3
            prog = base if it.get("program") is None else it["program"]
            if id(prog) not in primed:
                self._uniforms(prog, camera, shading)
                primed.add(id(prog))
            self._bind_item(prog, it, decoded)
            if count is None:
                vao.render(moderngl.TRIANGLES)
            else:
                vao.render(moderngl.TRIANGLES, vertices=count)
            gpu.flush()  # llvmpipe rasterises it while the next item is culled and bound
        if culling:
            ctx.disable(moderngl.CULL_FACE)
        return self._read_back(region, crop)

    @staticmethod
    def _bind_item(program, it: dict, decoded: bool) -> None:
        """Bind item ``it``'s buffers (decoded: SSBO 0, UBO 0, cluster records SSBO 3) and texture
        (unit 0), and set its per-item uniforms on ``program`` (part ID, placement rows, flags)."""
        if decoded:
            it["ssbo"].bind_to_storage_buffer(0)
            it["ubo"].bind_to_uniform_block(0)
            if it.get("clusters") is not None:
                it["clusters"].bind_to_storage_buffer(3)
        program["u_part"].value = int(it["part"]) + 1
        if decoded:
            rows = it.get("place", IDENTITY_ROWS)
            for r in range(3):
                program[f"u_place{r}"].value = rows[r]
        program["u_has_normal"].value = int(it["has_normal"])
        program["u_has_texture"].value = int(it["texture"] is not None)
        program["u_has_color"].value = int(it["has_color"])
        if it["texture"] is not None:
            it["texture"].use(location=0)

    def _read_back(self, region, crop: bool):
        """``draw``'s resolve and read-back of ``region`` (x, y, w, h in GL window coordinates):
        ``(rgba, ids)`` as ``draw`` returns them; sets ``last_box``."""
        import moderngl  # optional native GL binding, imported where a draw needs it

        ctx = self.ctx
        # resolve: colour by a blit (average of samples), part IDs by sample 0
        self.fbo_colour.use()
        ctx.copy_framebuffer(self.fbo_colour, self.fbo_ms_colour)
        self.fbo_ids.use()
        ctx.disable(moderngl.DEPTH_TEST)
        self._ids_ms.use(location=1)
        self.resolve_program["u_ids"].value = 1
        self.resolve_vao.render(moderngl.TRIANGLES, vertices=3)
        w, h = self.size
        x0, y0, rw, rh = region
        #: (row0, row1, col0, col1) of the image outside which this draw left background
        self.last_box = (h - y0 - rh, h - y0, x0, x0 + rw)
        got_rgba = np.frombuffer(self.fbo_colour.read(viewport=region, components=4, dtype="f1"),
                                 np.uint8).reshape(rh, rw, 4)[::-1]
        got_ids = np.frombuffer(self.fbo_ids.read(viewport=region, components=1, dtype="u4"), "<u4").reshape(rh, rw)[::-1]
        for fbo in (self.fbo_ms, self.fbo_ms_colour, self.fbo_colour, self.fbo_ids):
            fbo.scissor = None
        gpu.use_default_framebuffer()  # leave the context as gpu.py expects it (1x1 default target)
        if crop:  # views of the read-back bytes, rows flipped (no copy)
            return got_rgba, got_ids
        rgba = np.zeros((h, w, 4), np.uint8)
        ids = np.zeros((h, w), np.uint32)
        rgba[h - y0 - rh:h - y0, x0:x0 + rw] = got_rgba
        ids[h - y0 - rh:h - y0, x0:x0 + rw] = got_ids
        return rgba, ids

    def release(self) -> None:
        """Release the GL objects this holds; it is unusable afterwards."""
        for r in self._resources:
            r.release()
        self._resources = []
        self.scratch.release()


class Textures:
    """moderngl textures of the scene's base-colour images, by content digest (shared by parts)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.cache: dict = {}

    def get(self, texture):
        """The texture of a ``lopcook.types.Texture`` (None for None), built once per content digest: RGBA8
        with mipmaps, trilinear filtering, repeat wrap. Raises LopcookError (exit 2) when the
        image does not decode."""
        import moderngl  # optional native GL binding, imported where a draw needs it

        if texture is None:
            return None
        key = texture.digest
        if key not in self.cache:
            try:
                img = texture.image().convert("RGBA")
            except Exception as exc:
                raise LopcookError("verify", texture.name, f"cannot decode the base-colour texture ({exc})") from None
            tex = self.ctx.texture(img.size, 4, img.tobytes())
            tex.build_mipmaps()
            tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = True
            self.cache[key] = tex
        return self.cache[key]

    def release(self) -> None:
        """Release the GL objects this holds; it is unusable afterwards."""
        for t in self.cache.values():
            t.release()
        self.cache = {}


def attribute_vbos(ctx, normals, uvs, colors, order=None) -> tuple[list, list]:
    """VBO specs (buffer, format, name) of normals (n, 3) / uvs (n, 2) / colours (n, 4) float32 (each
    optional; permuted by ``order`` when given) and the list of buffers to release."""
    specs, bufs = [], []
    for name, a, fmt in vbo_arrays(normals, uvs, colors, order):
        b = ctx.buffer(a.tobytes())
        bufs.append(b)
        specs.append((b, fmt, name))
    return specs, bufs


def vbo_arrays(normals, uvs, colors, order=None) -> list[tuple[str, np.ndarray, str]]:
    """(attribute name, contiguous little-endian float32 array, format) of each attribute given, as
    ``attribute_vbos`` uploads them (permuted by ``order`` when given)."""
    out = []
    for name, arr, fmt in (("in_normal", normals, "3f"), ("in_uv", uvs, "2f"), ("in_color", colors, "4f")):
        if arr is None:
            continue
        a = np.asarray(arr, np.float32)
        if order is not None:
            a = a[order]
        out.append((name, np.ascontiguousarray(a, dtype="<f4"), fmt))
    return out


def attribute_buffers(ctx, part, order=None) -> tuple[list, list]:
    """VBO specs (buffer, format, name) of a part's source normals / uvs / colours (permuted by
    ``order`` for binned buffers) and the list of buffers to release."""
    return attribute_vbos(ctx, part.normals, part.uvs, part.colors, order)


def float_items(ctx, program, scene, textures, like=None) -> tuple[list, list]:
    """Draw items (float32 positions) of every part of ``scene`` and the GL objects to release.

    ``like``: (scene, items) of float items already uploaded (the harness's source draws); part i
    then draws their index buffer and attribute buffers where its arrays are the very same objects
    (a test scene that replaces only the positions, ``uniform_quantized_scene``): only its positions
    are uploaded, and the shared buffers stay the other items' to release."""
    items, owned = [], []
    for i, p in enumerate(scene.parts):
        src = None
        if like is not None and i < len(like[0].parts):
            q, it = like[0].parts[i], like[1][i]
            if "buffers" in it:
                src = it["buffers"]
                same_ibo = q.indices is p.indices
                same_attr = q.normals is p.normals and q.uvs is p.uvs and q.colors is p.colors
                src = (src[0] if same_ibo else None, src[1] if same_attr else None)
        pos = ctx.buffer(np.ascontiguousarray(p.positions, dtype="<f4").tobytes())
        if src is not None and src[0] is not None:
            ibo = src[0]
        else:
            ibo = ctx.buffer(np.ascontiguousarray(p.indices, dtype="<u4").tobytes())
            owned.append(ibo)
        if src is not None and src[1] is not None:
            specs = src[1]
        else:
            specs, bufs = attribute_buffers(ctx, p)
            owned += bufs
        vao = ctx.vertex_array(program, [(pos, "3f", "in_position"), *specs], index_buffer=ibo,
                               index_element_size=4)
        owned += [pos, vao]
        box = None
        if p.positions.size:
            f = np.asarray(p.positions, np.float32).astype(np.float64)
            box = (f.min(axis=0), f.max(axis=0))
        cover = Coverage(ctx, program, [(pos, "3f", "in_position"), *specs], p.indices, p.positions)
        owned.append(cover)
        items.append({"vao": vao, "part": i, "has_normal": p.normals is not None,
                      "has_color": p.colors is not None, "texture": textures.get(p.texture), "box": box,
                      "triangles": int(p.n_triangles), "cover": cover, "two_sided": bool(p.double_sided),
                      "buffers": (ibo, list(specs))})
    return items, owned


class Harness:
    """GPU state for one source scene at one resolution: the renderer, float-position draws of the
    source parts, textures, and an optional cache of float renders (``cache_float=True``: keyed by
    the camera matrix, eye and shading, reused across containers of the same scene, e.g. by the k_f
    calibration or the byte-budget fit). A cached render keeps only the box of its object pixels
    (outside it the image is background: RGBA 0 and part ID 0, exactly what the renderer clears to),
    at 4 bytes per pixel of colour and 2 (or 4, past 65535 parts) of part ID; once the cache holds
    ``raw_bytes`` (default ``RAW_CACHE_BYTES``) further entries are zlib-compressed (``_pack``;
    expanding costs time, which only a large cache is worth: docs/verify.md, "Reuse"); renders
    past ``cache_bytes`` (default ``FLOAT_CACHE_BYTES``, counted as stored) are not cached. A hit
    returns the same arrays a fresh render would (re-expanded to the full size).

    ``view_memo``: the per-view metrics of decoded draws by content (``evaluate``: the digest of
    every item's GPU inputs, ``decoded_items``, with the camera and shading), so that a later
    evaluation that would draw exactly the same thing -- another probe of a search, or the same
    container cooked again -- takes the numbers instead of rendering (the renderer is
    deterministic: the same inputs give the same pixels)."""

    def __init__(self, scene, resolution=RESOLUTION, samples: int = SAMPLES, cache_float: bool = False,
                 cache_bytes: int | None = None, raw_bytes: int | None = None):
        self.ctx = gpu.context()
        self.scene = scene
        self.renderer = Renderer(resolution, samples)
        self.textures = Textures(self.ctx)
        self.cache_float = cache_float
        self.float_cache: dict = {}
        self.cache_bytes = FLOAT_CACHE_BYTES if cache_bytes is None else int(cache_bytes)
        self.raw_bytes = RAW_CACHE_BYTES if raw_bytes is None else int(raw_bytes)
        self.cached_bytes = 0
        #: results callers keep by what they rendered (the calibration: probes whose containers have
        #: the same minimum levels, so the same decoded positions, render the same)
        self.memo: dict = {}
        #: (variant content key, camera key) -> (colour metrics, depth metrics, float object pixels)
        self.view_memo: dict = {}
        lo, hi = scene.bounds()
        self.lo, self.hi = lo, hi
        self.float_items, self._buffers = float_items(self.ctx, self.renderer.float_program, scene, self.textures)
        #: keep a container's attribute and index buffers from one ``evaluate`` to the next of the
        #: same container object (``lopcook report``: one level at a time); off by default, as a
        #: search evaluates a new container at every probe
        self.keep_attributes = False
        #: (container, how it was drawn, {part: attribute entry}) kept, or None
        self.kept_attributes = None
        #: (test scene, {part: the float draw's Coverage it may share}) from ``share_culls``, or None
        self.cull_twins = None

    def release_kept_attributes(self) -> None:
        """Release the attribute buffers kept for ``keep_attributes`` (and the container reference)."""
        kept, self.kept_attributes = self.kept_attributes, None
        if kept is not None:
            release_attributes(kept[2])

    def attribute_cache(self, container, sig) -> dict:
        """The ``decoded_items`` attribute cache for an evaluation of ``container`` drawn the way
        ``sig`` says: the one kept from the last evaluation of the same container object drawn the
        same way, else a new one (kept in turn when ``keep_attributes``; any other kept one is
        released). Give it back with ``release_attribute_cache``."""
        kept = self.kept_attributes
        if kept is not None and kept[0] is container and kept[1] == sig:
            return kept[2]
        self.release_kept_attributes()
        cache: dict = {}
        if self.keep_attributes:
            self.kept_attributes = (container, sig, cache)
        return cache

    def release_attribute_cache(self, cache: dict) -> None:
        """Release the buffers of an ``attribute_cache`` unless this harness keeps them."""
        if self.kept_attributes is None or self.kept_attributes[2] is not cache:
            release_attributes(cache)

    def release(self) -> None:
        """Release the GL objects this holds; it is unusable afterwards."""
        self.release_kept_attributes()
        for b in self._buffers:
            b.release()
        self._buffers = []
        self.textures.release()
        self.renderer.release()
        self.float_cache = {}
        self.cached_bytes = 0
        self.view_memo = {}
        self.memo = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()

    def render_float(self, camera: Camera, shading: Shading, key=None, crop: bool = False):
        """``draw`` of the source's float items from ``camera``; with ``cache_float`` and a ``key``
        (hashable: camera matrix, eye and shading) the result is computed once and reused.
        ``crop``: only the pixels in ``last_float_box`` (as ``draw(crop=True)``; the part IDs may
        then be uint16), no whole-image arrays."""
        if self.cache_float and key is not None and key in self.float_cache:
            entry = self.float_cache[key]
            box = entry[0]
            self.last_float_box = (0, 0, 0, 0) if box is None else tuple(box)
            entry = entry if len(entry) == 3 else _unpack(entry)
            return (entry[1], entry[2]) if crop else _expand(entry, self.renderer.size)
        out = self.renderer.draw(self.float_items, camera, shading, decoded=False, crop=crop)
        #: (row0, row1, col0, col1) outside which the last float render is background
        self.last_float_box = self.renderer.last_box
        if self.cache_float and key is not None:
            entry = _crop(*out)
            if crop and entry[0] is not None:  # the crop's box in the whole image
                r0, c0 = self.last_float_box[0], self.last_float_box[2]
                b = entry[0]
                entry = ((b[0] + r0, b[1] + r0, b[2] + c0, b[3] + c0), entry[1], entry[2])
            size = entry[1].nbytes + entry[2].nbytes
            if self.cached_bytes + size > self.raw_bytes:  # past the raw share: compressed
                entry = _pack(entry)
                size = _packed_bytes(entry)
            if self.cached_bytes + size <= self.cache_bytes:
                self.float_cache[key] = entry
                self.cached_bytes += size
        return out

    def clear_float_cache(self) -> None:
        """Empty the float-render cache (its bytes are freed), and the float draws' remembered culls
        (``share_culls``)."""
        self.float_cache, self.cached_bytes = {}, 0
        for it in self.float_items:
            cover = it.get("cover")
            if cover is not None and cover.memo is not None:
                cover.memo = {}

    def share_culls(self, test_scene) -> None:
        """Let ``evaluate_scene(test_scene)`` draw the coverage culls of the source's float draws
        (``Coverage`` "Shared culls"; the images are the same). Part i of ``test_scene`` shares part
        i's culls where it has the same triangles, sidedness and vertex count: each such float draw's
        cull then also holds what part i's float32 positions (within the largest difference from
        the source's, per axis) could need, and is remembered until ``clear_float_cache``. Meant
        for a test scene close to the source (a uniform 16-bit baseline: a small fraction of a
        pixel at the cameras that matter); a far one only widens the float draws' culls."""
        shared = {}
        for i, (p, q, it) in enumerate(zip(self.scene.parts, test_scene.parts, self.float_items)):
            cover = it.get("cover")
            if cover is None or p.positions.shape != q.positions.shape or bool(p.double_sided) != bool(q.double_sided):
                continue
            if p.indices is not q.indices and not np.array_equal(p.indices, q.indices):
                continue
            if p.positions.size == 0:
                continue
            d = np.asarray(q.positions, np.float32).astype(np.float64) - np.asarray(p.positions, np.float32)
            slack = float(np.abs(d).max())
            if not math.isfinite(slack):
                continue
            cover.slack_m, cover.memo = slack, {}
            shared[i] = cover
        self.cull_twins = (test_scene, shared)

    def link_culls(self, test_scene, items) -> int:
        """Give ``items`` (``float_items`` of ``test_scene``, in part order) the float draws' culls
        when ``share_culls(test_scene)`` was called (the same scene object); returns how many."""
        twins = self.cull_twins
        if twins is None or twins[0] is not test_scene:
            return 0
        n = 0
        for i, it in enumerate(items):
            if i in twins[1] and it.get("cover") is not None:
                it["cover"].twin = twins[1][i]
                n += 1
        return n


def trim_heap() -> None:
    """Return the C heap's free pages to the system (``lopcook.memory.release_free_memory``): after
    an evaluation, the freed GL buffers and llvmpipe's scene blocks would otherwise stay in the
    process's resident memory and add to the next evaluation's peak."""
    release_free_memory()


# ---- harnesses shared by the searches of one scene ------------------------------------------------

#: open harnesses by (id(scene), (w, h), samples): every one belongs to the same scene object
_SHARED: dict = {}


class _Borrowed:
    """``with shared_harness(...) as h``: the harness stays open when the block ends."""

    def __init__(self, harness: Harness):
        self.harness = harness

    def __enter__(self) -> Harness:
        return self.harness

    def __exit__(self, *exc) -> None:
        return None


def shared_harness(scene, resolution=RESOLUTION, samples: int = SAMPLES) -> _Borrowed:
    """A ``Harness(scene, resolution, samples, cache_float=True)`` kept open for later callers with
    the **same scene object** (``scene is``), as a context manager that does not release it: the
    k_f calibration, its confirmation, the attribute search and its gate renders of one cook share
    the float-render caches and ``view_memo`` of their two harnesses (the reduced one and the
    gate's), so a float render or a decoded draw made by one is not made again by the next. Asking
    for another scene releases every shared harness of the previous one (``release_shared``), so at
    most one scene's harnesses are held; the results equal those of fresh harnesses (cached and
    memoised renders are exactly what a new draw gives). ``Harness.memo`` (results a caller keys by
    what it cooked, not by content) is emptied on each call: it belongs to one search. Like the
    process's GL context it serves, the pool is for one thread."""
    res = (int(resolution[0]), int(resolution[1]))
    key = (id(scene), res, int(samples))
    h = _SHARED.get(key)
    if h is None or h.scene is not scene:
        if any(v.scene is not scene for v in _SHARED.values()) or h is not None:
            release_shared()
        h = Harness(scene, res, samples, cache_float=True, raw_bytes=SHARED_RAW_BYTES)
        _SHARED[key] = h
    h.memo = {}
    return _Borrowed(h)


def release_shared() -> None:
    """Release every harness ``shared_harness`` holds (their caches and GL objects)."""
    while _SHARED:
        _, h = _SHARED.popitem()
        h.release()


atexit.register(release_shared)


def _decoded_positions(buf, level: int, origin, half_cell, place):
    """A function giving the (n, 3) float32 positions the decoding vertex shader computes for ``buf``
    (a ``GpuBuffer`` or ``ClusteredGpuBuffer``) at ``level`` on the grid (``origin``, ``half_cell``),
    mapped by the placement rows ``place`` when given: the reference decoder's (``decode`` /
    ``decode_clustered``, ``reconstruct_float32``, ``placement.to_world``). The decoded integers
    are the buffer's ``decoded`` where it carries them (the values its words were packed from:
    the pack and the reference decode round-trip exactly, ``tests/emit/test_clusters.py`` and
    ``tests/lop/test_bitplane.py``), else the reference decode of its words."""
    def positions():
        if buf.decoded is not None:
            values, widths = buf.decoded
        elif isinstance(buf, ClusteredGpuBuffer):
            values, widths = decode_clustered(np.asarray(buf.words, np.uint32), buf.clusters, int(level))
        else:
            values, widths = decode(np.asarray(buf.words, np.uint32), buf.vertex_id, buf.bit_id, int(level))
        pos = reconstruct_float32(values, widths, origin, 2.0 * float(half_cell))
        if place is not None:
            pos = to_world(pos, np.asarray(place, np.float64).reshape(3, 4))
        return pos

    return positions


def _once(f):
    """``f`` (a function of no arguments) called at most once: later calls return its first result."""
    held = []

    def once():
        if not held:
            held.append(f())
        return held[0]

    return once


def _placed_positions(local, place):
    """A function giving ``local()`` (the positions of a ``_decoded_positions`` function without
    placement, through ``_once``: one decode shared by every caller) mapped by the placement rows
    ``place`` (``placement.to_world``, float32), or ``local`` itself when ``place`` is None: the
    positions ``_decoded_positions(..., place)`` gives."""
    if place is None:
        return local

    def positions():
        return to_world(local(), np.asarray(place, np.float64).reshape(3, 4))

    return positions


def release_attributes(attr_cache: dict) -> None:
    """Release the GL buffers of a ``decoded_items`` attribute cache (each entry's third field)."""
    for entry in attr_cache.values():
        for b in entry[2]:
            b.release()


def _attribute_entry(ctx, c, i: int, k: int, p, order, textures, decoded_attributes: dict) -> tuple:
    """``decoded_items``' attribute cache entry of part ``i`` (source part ``p``) at LOD ``k``:
    ``(index buffer, VBO specs, GL objects, (has normal, has colour, texture), source box or None,
    content digest, index count, index words)``. The source's attributes permuted by ``order``
    when that is not None, else the container's own (``decoded_attributes``: (owner, LOD) ->
    ``lod_attributes``, filled here)."""
    # unit normals, as a vertex shader normalises the octahedral decode before the
    # interpolation (an unnormalised one would weight the vertices by its length)
    o = (owner(c, i), k)  # a placement's LOD entry is its owner's: one decode for all of them
    if o not in decoded_attributes:
        decoded_attributes[o] = lod_attributes(c, i, k, unit_directions=True)
    a = decoded_attributes[o]
    index_words = np.ascontiguousarray(a["indices"], dtype="<u4")
    ibo = ctx.buffer(index_words.tobytes())
    if order is not None:
        arrays = vbo_arrays(p.normals, p.uvs, p.colors, order)
        flags = (p.normals is not None, p.colors is not None, textures.get(p.texture))
        tex = p.texture
    else:
        nrm = world_normals(c, i, a["normals"])  # a placement's: A^-T n, unit
        arrays = vbo_arrays(nrm, a["uvs"], a["colors"])
        flags = (a["normals"] is not None, a["colors"] is not None,
                 textures.get(p.texture) if a["uvs"] is not None else None)
        tex = p.texture if a["uvs"] is not None else None
    bufs = [ctx.buffer(arr.tobytes()) for _, arr, _ in arrays]
    specs = [(b, fmt, name) for b, (name, _, fmt) in zip(bufs, arrays)]
    src_box = None
    if order is not None and p.positions.size:  # the source's positions, in binned order
        f = np.asarray(p.positions, np.float64)
        src_box = (f.min(axis=0), f.max(axis=0))
    key = digest(i, index_words, *[x for name, arr, fmt in arrays for x in (name, fmt, arr)],
                 bool(flags[0]), bool(flags[1]), None if tex is None else tex.digest,
                 None if src_box is None else np.asarray(src_box, np.float64), bool(p.double_sided))
    return ibo, specs, [ibo, *bufs], flags, src_box, key, int(index_words.shape[0]), index_words


def _placement_geometry(c, i: int, tf) -> tuple:
    """Placement ``i``'s mesh grid and where it can draw: ``(grid origin, half a 24-bit cell
    (float32), culling box (lo, hi) in world metres: the mapped mesh-grid cube, placement rows)``."""
    p_origin, p_extent = part_grid(c, i)
    p_half = np.float32(p_extent / float(1 << 24) / 2.0)
    a, t = (x.astype(np.float64) for x in split(tf))
    o = np.asarray(p_origin, np.float64)
    corners = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]) * p_extent * \
        (1.0 + 2.0 ** -20) + o
    world = corners @ a.T + t
    span = float(np.abs(world).max()) * 2.0 ** -20
    rows = tuple(tuple(float(v) for v in np.asarray(tf, np.float64).reshape(3, 4)[r]) for r in range(3))
    return p_origin, p_half, (world.min(axis=0) - span, world.max(axis=0) + span), rows


def _shared_buffer(ctx, c, i: int, k: int, p_level: int, p_origin, p_half, buf, program, cluster_program,
                   owned: list) -> tuple:
    """GPU buffer ``buf`` (part ``i``'s at LOD ``k``, level ``p_level``) uploaded once for every
    item that reads it: ``(SSBO, UBO, program, cluster records SSBO or None, positions())``; the GL
    objects are appended to ``owned``."""
    words = np.ascontiguousarray(buf.words, dtype="<u4")
    ssbo = ctx.buffer(words.tobytes() if words.size else b"\0\0\0\0")
    prog, clusters = program, None
    if isinstance(buf, ClusteredGpuBuffer):
        if cluster_program is None:
            raise ValueError("a clustered buffer needs the LOP_CLUSTERED program (cluster_program)")
        cl = buf.clusters
        try:
            rec, _, _ = check_cluster_tables(buf.records, cl.cluster_id, cl.vertex_id, cl.size)
        except ValueError as exc:
            raise LopcookError("verify", c.path, f"part {i} LOD {k}: the clustered decoder cannot take "
                               f"this buffer: {exc}", hint="cook it unclustered (--clusters 0)") from None
        clusters = ctx.buffer(rec.astype("<u4").tobytes() if rec.size else b"\0" * 16)
        ubo = ctx.buffer(cluster_decode_block(cl.vertex_id, cl.cluster_id, p_level, p_origin, p_half,
                                              words.size, cl.size))
        prog = cluster_program
        owned.append(clusters)
    else:
        ubo = ctx.buffer(decode_block(buf.vertex_id, buf.bit_id, p_level, p_origin, p_half, words.size))
    owned += [ssbo, ubo]
    return ssbo, ubo, prog, clusters, _once(_decoded_positions(buf, p_level, p_origin, p_half, None))


def decoded_items(ctx, program, c, scene, lods, orders, textures, buffers_of, level: int, origin, half_cell,
                   attr_cache: dict, cluster_program=None) -> tuple[list, list]:
    """Draw items of the decoded variant for every part at ``level``; ``buffers_of(c, part, lod, B)``
    gives the GpuBuffer (AP or CAP) or, for a clustered buffer, the ``ClusteredGpuBuffer``
    (``lopcook.verify.buffers.cap_buffer``), drawn with ``cluster_program`` (the ``LOP_CLUSTERED``
    build; ValueError when it is needed and None); for a placement it must give its owner's buffer
    (``lop.reader.owner``; as every reader function does), which is built, uploaded and decoded
    once for all the placements of that owner at one level; ``lods[i]`` is part i's LOD index. Part i's attributes are the
    source's permuted by ``orders[i]`` when that is not None (LOD 0 of a container cooked from this
    source), else the container's own (``lod_attributes``: normals, UVs, colours as decoded from the
    file, normals normalised per vertex; a placement's mapped by A^-T). Attribute VBOs and index
    buffers come from ``attr_cache``.

    Each item carries ``digest``: the content key (``digest``) of what its draw depends on -- part
    index, index buffer, attribute arrays as uploaded, flags, texture content digest, culling box, sidedness,
    and the float32 world positions its vertex shader computes (the reference decode of the packed
    words at the level on its grid, i.e. the values they were packed from (``_decoded_positions``),
    mapped by a placement's transform: bit for bit what either
    decoder gives, ``lopcook verify --decoders``) -- so two items with equal digests, drawn with the
    same camera and shading, give the same pixels, whatever layout (clustered or binned) or minimum
    levels gave those positions."""
    items, owned = [], []
    shared: dict = {}  # (owner, LOD, level, grid) -> GL buffers, program and local positions of one buffer
    decoded_attributes: dict = {}  # (owner, LOD) -> lod_attributes (read only here)
    # every decoded position lies in the grid's cube (24-bit integers, at most 2^24 - 1, plus half a cell)
    lo = np.asarray(origin, np.float64)
    grid_box = (lo, lo + float(half_cell) * 2.0 * float(1 << 24))
    resident = resident_levels(c, lods, level) if c.entries.has_placements else {}
    for i, p in enumerate(scene.parts):
        k = lods[i]
        tf = placement_transform(c, i)
        if i not in attr_cache:
            attr_cache[i] = _attribute_entry(ctx, c, i, k, p, orders[i], textures, decoded_attributes)
        ibo, specs, _, (has_normal, has_color, texture), src_box, attr_key, n_tri, index_words = attr_cache[i]
        cull_box = None
        if src_box is not None:
            # decoded with >= level bits: within half a level-B cell of the 24-bit grid point, itself
            # within half a 24-bit cell of the source position; widened by two level-B cells
            pad = 2.0 * float(half_cell) * 2.0 * float(1 << (24 - int(level))) + 4.0 * float(half_cell)
            cull_box = (src_box[0] - pad, src_box[1] + pad)
        extra = {}
        p_level, p_origin, p_half = level, origin, half_cell
        if tf is not None:
            # a placement: its shared buffer at the resident level, on its mesh grid, mapped by
            # its transform
            p_level = resident[(owner(c, i), k)]
            p_origin, p_half, cull_box, extra["place"] = _placement_geometry(c, i, tf)
        # the placements of one mesh read one buffer (their owner's, ``buffers_of`` contract): it is
        # built, uploaded and decoded once per level; each placement has its own VAO and positions
        share_key = (owner(c, i), k, int(p_level), tuple(float(v) for v in p_origin), float(p_half))
        if share_key not in shared:
            shared[share_key] = _shared_buffer(ctx, c, i, k, p_level, p_origin, p_half, buffers_of(c, i, k, p_level),
                                               program, cluster_program, owned)
        ssbo, ubo, prog, clusters, local = shared[share_key]
        vao = ctx.vertex_array(prog, list(specs), index_buffer=ibo, index_element_size=4)
        cover = Coverage(ctx, prog, specs, index_words, _placed_positions(local, extra.get("place")))
        owned += [vao, cover]
        # named by what the vertex shader outputs: the decoded world positions (the reference decode,
        # bit-exact with both decoders), so two buffers that decode alike at this level -- clustered
        # or not, minimum levels that differ only at or below it -- share their renders
        key = digest(attr_key, cover.positions)
        items.append({"vao": vao, "ssbo": ssbo, "ubo": ubo, "part": i, "has_normal": has_normal,
                      "has_color": has_color, "texture": texture, "program": prog, "clusters": clusters,
                      "box": grid_box if cull_box is None else cull_box, "cull_box": cull_box, "digest": key,
                      "triangles": n_tri, "cover": cover, "two_sided": bool(p.double_sided), **extra})
    return items, owned


__all__ = ["RESOLUTION", "SAMPLES", "RECT_MARGIN", "COVER_MARGIN", "COVER_DENSITY", "COVER_MIN_TRIANGLES",
           "SAMPLE_LATTICE", "sample_positions", "covering_triangles", "box_corners", "window_coordinates", "Coverage", "Scratch", "FLOAT_CACHE_BYTES", "RAW_CACHE_BYTES", "FINISH_TRIANGLES", "CULL_MARGIN", "AMBIENT", "DIFFUSE", "BASE_GREY", "Shading", "Renderer", "Textures",
           "attribute_vbos", "attribute_buffers", "vbo_arrays", "float_items", "decoded_items", "release_attributes",
           "Harness",
           "shared_harness", "release_shared", "digest", "trim_heap"]
