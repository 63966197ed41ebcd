"""Variable-bit encodings of the non-position vertex data of a .lop container, packed into one
record per vertex (issue 15; Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex
Compression Using Quantization and Simplification", Graphics Hardware 2005, sections 3-5).

Every encoder is vectorised numpy and deterministic (the same input gives the same bytes on every
platform: only IEEE-exact operations in a fixed order). Every **decode is defined as float32
operations** (numpy float32 arrays, each operation rounded once, no float64, no fused multiply-add),
so a shader evaluating the same expressions with ``precise`` reproduces it bit for bit. The
decoders here are the reference. The formulas are also data: :func:`attribute_specs` (the
manifest's ``encodings``).

Normals -- octahedral, ``b_n`` bits per component, 4 <= b_n <= 16
-------------------------------------------------------------------
Cigolle, Donow, Evangelakos, Mara, McGuire, Meyer, "A Survey of Efficient Representations for
Independent Unit Vectors", JCGT 3(2), 2014, *precise* variant. ``h = 2^(b_n - 1)``, ``m = h - 1``;
the signed value ``s`` is in [-m, m] and **code = s + h** (in [1, 2^b_n - 1]; code 0 reads as
s = -h and is clamped to -1).

Decode (float32; ``R = float32(1 / m)``, rounded once)::

    p  = max(float32(code - h) * R, -1.0)                     # per component
    z  = (1 - |p.x|) - |p.y|
    if z < 0: (x, y) = ((1 - |p.y|) * sgn(p.x), (1 - |p.x|) * sgn(p.y))   else (x, y) = p
    n  = (x, y, z)                                             # UNNORMALISED float32

``sgn(x)`` is +1 for x >= 0 (including -0.0), -1 otherwise. The unnormalised vector is the
bit-exact result; the renderer (fragment shader) normalises it.

Encode (direction d, any non-zero length; float64)::

    p  = (d.x, d.y) / (|d.x| + |d.y| + |d.z|)                        # onto the octahedron
    if d.z < 0: p = ((1 - |p.y|) * sgn(p.x), (1 - |p.x|) * sgn(p.y))  # fold the lower half
    s  = clip(floor(p * m) + {0, 1}, -m, m) per component: of the 4 candidates keep the one
         whose normalised decode (the float32 decode above, normalised in float64) has the
         largest dot product with d (first of equals in the order (0,0), (1,0), (0,1), (1,1))

Error: the worst-case angle is bounded by :func:`normal_error_deg` ``(b) = 2.7 * 2^(6 - b)``
degrees for b >= 6 (11.65 at 4 bits, 5.45 at 5): the largest angle measured over random
directions, the centres of the code cells (the worst case of rounding), the fold z = 0 and the
face centres is ``161-167 * 2^-b`` degrees for b >= 6, which matches Cigolle et al.'s maxima
(2.6, 0.64, 0.16, 0.039, 0.0025 degrees at 6, 8, 10, 12, 16 bits; :data:`CIGOLLE_MAX_ERROR_DEG`)
to their two printed digits; the bound adds a 3 % margin. ``tests/test_attributes.py`` checks
the codec against that table on dense direction sets.

UVs -- ``b_u`` bits per component over the buffer's range, 6 <= b_u <= 16
---------------------------------------------------------------------------
``lo``, ``hi``: float32 per component (the buffer's min/max); ``N = 2^b_u - 1``;
``step = float32((hi - lo) / N)`` (computed in float64 from the float32 lo, hi, rounded once;
the manifest's ``uv_step``)::

    q  = clip(rint((u - lo) / step), 0, N), then the best of q - 1, q, q + 1 (clipped) by decoded
         error, first of equals the lowest q                                      (float64)
    u' = lo + float32(q) * step                      (float32: one rounded product, one rounded sum)

A degenerate range (hi == lo) gives step 0, all codes 0, and decodes to lo exactly. Error per
component: :func:`uv_error_bound` ``= step / 2 + (hi - lo) * 2^-24 + ulp32(max(|lo|, |hi|))``
(half a step, the rounding of ``step`` accumulated over N steps, the float32 rounding of the
result).

Colours -- RGBA linear, ``b_c`` bits per channel, 4 <= b_c <= 8
-----------------------------------------------------------------
``N = 2^b_c - 1``: ``q = rint(clip(c, 0, 1) * N)`` (float64, half to even);
decode ``c' = float32(q) * float32(1 / N)`` (float32). Values outside [0, 1] are clamped first.
Error per channel for inputs in [0, 1]: ``1 / (2 N)`` plus float32 rounding (:func:`color_error_bound`).

The record -- one per vertex, packed LSB first
-----------------------------------------------
Fields, each present attribute only, in this order: ``normal.u, normal.v`` (b_n bits each),
``uv.u, uv.v`` (b_u each), ``color.r, g, b, a`` (b_c each). Record bits
``S = 2 b_n + 2 b_u + 4 b_c`` (<= 96). Vertex j's record starts at bit ``j * S`` of the section,
its fields consecutive, least significant bit first (bit i of the section is bit ``i & 31`` of
word ``i >> 5``), so a field may span two 32-bit words: the decoder reads word ``w = o >> 5`` and
word ``min(w + 1, words - 1)`` like the positions' ``lop_read_field``. This lifts Purnomo's
no-crossing rule (section 4: components packed into whole 32-bit words by first-fit bins) at the
cost of a second word read. The section holds ``ceil(n S / 32)`` little-endian uint32 words (no
padding word): at most 31 bits are wasted per buffer (:func:`record_waste`), against
``32 ceil(S/32) - S`` per vertex for word-aligned records (:func:`aligned_waste`, first-fit
decreasing bins of whole components).

Bound-based defaults (:func:`default_bits`, issue 15 item 3): the average-case bound
------------------------------------------------------------------------------------------
Without an image search (``lopcook.tune``), each part's normal and UV bits are the fewest whose
**root-mean-square change of a pixel's colour** stays within ``eps`` (AnalyseSettings.eps, colour
units, default 1/255: the positions' per-vertex bound, Meyer et al. 2011, section 5.1, now per
pixel on average, one eps per attribute). The verify harness measures the mean square error over
object pixels, so this is the quantity its PSNR sees: one attribute alone at eps = 1/255 costs at
most 48.1 dB. Inputs (``lopcook.analyse.attribute_bound``): the harness's headlight Phong shading
averaged over the projected-area density of facing normals, and the part's texture gradient where
its surface samples it. Pixel errors (vertex errors independent, interpolated with barycentric
weights w: E[sum w_i^2] = 1/2 over a triangle, hence the factor sqrt(1/2)):

* normals (:func:`normal_pixel_rms`): ``0.5 * slope_rms * delta_rms(b)``, ``delta_rms(b)`` the
  codec's RMS angle (:data:`NORMAL_RMS_ERROR_DEG`, radians; 0.53 x Cigolle et al.'s maxima),
  ``slope_rms`` the shading's RMS slope per radian (0.693 with ks 0.5, n 32), the 0.5 =
  sqrt(1/2) for the error's direction (only the tilt towards the light counts) times sqrt(1/2)
  for the interpolation. 1/255 gives 8 bits (0.00204; 7 bits: 0.00412).
* UVs (:func:`uv_pixel_rms`): ``lighting_rms * sqrt(1/2) * sqrt(((g_u s_u)^2 + (g_v s_v)^2) / 12)``,
  s the step over the part's range (rounding error uniform in +-s/2, variance s^2/12), g the
  texture's RMS derivative along u, v (colour per UV unit, area-weighted over the surface, at the
  mip level of the design view), lighting_rms = 0.603 the diffuse factor the base colour is
  multiplied by. An untextured part has g = 0: 6 bits. In texels: the RMS error is
  ``s R / sqrt(12)`` texels, times the gradient per texel ``g / R``.
* colours: the worst case below (unchanged).

The worst-case bound (:func:`worst_case_bits`, the default before): every vertex at its largest
error at the steepest point of the shading: normals ``ks * n * theta_max(b) <= eps`` (14 bits by
default), UVs ``max slope * |uv_error_bound(b)| <= eps`` (16 on any detailed texture), colours
``color_kf / (2 (2^b - 1)) <= eps`` (8 for 1/255). It is 40-75 % above the image search's bits
(docs/attributes.md), the average-case bound within 20 %.

Where no b in the range satisfies a bound, the largest is used. The bits chosen are recorded per
part and per LOD in the manifest (``attribute_bits``). ``docs/attributes.md`` has the derivation
in full and the measured image errors.

Indices -- uint16 or uint32 (``"<u2"`` / ``"<u4"``), 6 or 12 bytes per triangle
-------------------------------------------------------------------------------------
Layout: the triangles' corners in order, ``i0 i1 i2 i0 i1 i2 ...``. The width is 2 bytes when
``n_vertices <= 65535`` (every index <= 65534: the uint16 primitive-restart value 65535, always on
in WebGL 2 and Metal, never appears) and 4 bytes otherwise. Exact.

Non-finite input (and zero-length normals) raises ``LopcookError("emit", ...)``; bit counts out
of range raise ``LopcookError("usage", ...)``.
"""

from __future__ import annotations

import copy
import math
import threading
from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from ..settings import COLOR_BITS_RANGE, NORMAL_BITS_RANGE, UV_BITS_RANGE

__all__ = [
    "NORMAL_BITS", "UV_BITS", "COLOR_BITS", "DEFAULT_BITS", "CIGOLLE_MAX_ERROR_DEG",
    "AttributeBits", "bits_for", "default_bits", "worst_case_bits", "part_default_bits",
    "normal_pixel_rms", "uv_pixel_rms", "normal_rms_error_deg", "NORMAL_RMS_ERROR_DEG", "part_bits", "normal_error_deg", "uv_error_bound", "color_error_bound",
    "encode_normals", "decode_normals", "encode_uvs", "uv_step", "decode_uvs",
    "encode_colors", "decode_colors", "encode_record", "record_codes", "code_memo", "with_code_memo", "CODE_MEMO_BYTES",
    "pack_record", "decode_record", "record_fields",
    "record_waste", "aligned_waste", "record_words",
    "encode_indices", "decode_indices", "index_width", "attribute_specs",
]

#: Allowed bits per component (inclusive ranges).
NORMAL_BITS = NORMAL_BITS_RANGE
UV_BITS = UV_BITS_RANGE
COLOR_BITS = COLOR_BITS_RANGE
#: Bits used when nothing chooses them (the precision of format 1: oct 2x16, unorm16 UVs, RGBA8).
DEFAULT_BITS = (16, 16, 8)
#: Cigolle et al. 2014, precise octahedral encoding: maximum angle (degrees) at b bits per component.
CIGOLLE_MAX_ERROR_DEG = {6: 2.6, 8: 0.64, 10: 0.16, 12: 0.039, 16: 0.0025}

_F4 = np.dtype("<f4")
_U2 = np.dtype("<u2")
_U4 = np.dtype("<u4")
_F32 = np.float32


def _check_bits(b, lohi: tuple[int, int], what: str) -> int:
    if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or not lohi[0] <= int(b) <= lohi[1]:
        raise LopcookError("usage", None, f"{what} bits must be an integer in [{lohi[0]}, {lohi[1]}], got {b!r}")
    return int(b)


@dataclass(frozen=True)
class AttributeBits:
    """Bits per component of one buffer's attributes; None where the attribute is absent.

    normals in [4, 16] (per octahedral component), uvs in [6, 16] (per UV component), colors in
    [4, 8] (per RGBA channel). ``record_bits`` is ``S = 2 b_n + 2 b_u + 4 b_c``."""

    normals: int | None = None
    uvs: int | None = None
    colors: int | None = None

    def __post_init__(self) -> None:
        for name, lohi in (("normals", NORMAL_BITS), ("uvs", UV_BITS), ("colors", COLOR_BITS)):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, _check_bits(v, lohi, name[:-1] if name != "colors" else "color"))

    @property
    def record_bits(self) -> int:
        return 2 * (self.normals or 0) + 2 * (self.uvs or 0) + 4 * (self.colors or 0)

    def as_dict(self) -> dict:
        return {"normals": self.normals, "uvs": self.uvs, "colors": self.colors}

    @classmethod
    def of(cls, d: dict) -> "AttributeBits":
        return cls(normals=d.get("normals"), uvs=d.get("uvs"), colors=d.get("colors"))


def bits_for(normals: bool, uvs: bool, colors: bool, requested=(None, None, None)) -> AttributeBits:
    """The bits of a buffer with the given attributes present: ``requested`` (normal, uv, color)
    where not None, else :data:`DEFAULT_BITS`; absent attributes get None."""
    rn, ru, rc = requested
    dn, du, dc = DEFAULT_BITS
    return AttributeBits(normals=(dn if rn is None else rn) if normals else None,
                         uvs=(du if ru is None else ru) if uvs else None,
                         colors=(dc if rc is None else rc) if colors else None)


def normal_pixel_rms(bits: int, slope_rms: float) -> float:
    """Root-mean-square change of a pixel's colour (colour units) caused by ``bits``-bit octahedral
    normals under a shading whose RMS slope is ``slope_rms`` (colour per radian of normal tilt,
    ``lopcook.analyse.attribute_bound.shading_rms``): ``slope_rms * sqrt(1/2) * sqrt(1/2) *
    radians(normal_rms_error_deg(bits))`` (the error's direction in the tangent plane, the
    barycentric interpolation of three independent vertex errors: module doc)."""
    return 0.5 * float(slope_rms) * math.radians(normal_rms_error_deg(bits))


def uv_pixel_rms(lo, hi, bits: int, gradient_rms, lighting_rms: float) -> float:
    """Root-mean-square change of a pixel's colour (colour units) caused by ``bits``-bit UVs over
    [lo, hi] (per component) on a texture of RMS derivatives ``gradient_rms`` = (g_u, g_v) (colour
    per UV unit, ``lopcook.analyse.attribute_bound.texture_gradient_rms``) lit by ``lighting_rms``:
    ``lighting_rms * sqrt(1/2) * sqrt((g_u step_u)^2 + (g_v step_v)^2) / sqrt(12)`` (uniform
    rounding error of variance step^2 / 12 per component, barycentric interpolation: module doc)."""
    b = _check_bits(bits, UV_BITS, "uv")
    step = uv_step(np.asarray(lo, dtype=_F4).astype(np.float64), np.asarray(hi, dtype=_F4).astype(np.float64), b)
    g = np.asarray(gradient_rms, dtype=np.float64).reshape(2)
    return float(lighting_rms) * math.sqrt(0.5 * float(np.sum((g * step.astype(np.float64)) ** 2)) / 12.0)


def default_bits(*, normals: bool, uvs, colors: bool, eps: float, normal_slope_rms: float = 0.0,
                 uv_gradient_rms=(0.0, 0.0), lighting_rms: float = 1.0, color_kf: float = 0.0) -> AttributeBits:
    """The bound-based default bits of one part (issue 15 item 3; derivation in the module doc,
    section "Bound-based defaults", and docs/attributes.md): the fewest bits whose **root-mean-square**
    change of a pixel's colour stays within ``eps`` (colour units), per attribute.

    normals : bool; smallest b_n in [4, 16] with ``normal_pixel_rms(b_n, normal_slope_rms) <= eps``.
    uvs : None or the part's (n, 2) UVs; smallest b_u in [6, 16] with
        ``uv_pixel_rms(lo, hi, b_u, uv_gradient_rms, lighting_rms) <= eps`` over the part's range
        (a zero gradient, an untextured part, gives 6).
    colors : bool; the worst case, smallest b_c in [4, 8] with ``color_kf * color_error_bound(b_c) <= eps``.
    Each is the largest allowed when none satisfies the bound."""
    if not (math.isfinite(eps) and eps > 0):
        raise LopcookError("usage", None, f"eps must be a finite number > 0, got {eps}")
    bn = bu = bc = None
    if normals:
        bn = _fewest(NORMAL_BITS, lambda b: normal_pixel_rms(b, normal_slope_rms) <= eps)
    if uvs is not None:
        lo, hi = _uv_range(uvs)
        bu = _fewest(UV_BITS, lambda b: uv_pixel_rms(lo, hi, b, uv_gradient_rms, lighting_rms) <= eps)
    if colors:
        bc = _fewest(COLOR_BITS, lambda b: float(color_kf) * color_error_bound(b) <= eps)
    return AttributeBits(normals=bn, uvs=bu, colors=bc)


def worst_case_bits(*, normals: bool, uvs, colors: bool, eps: float, normal_kf: float = 0.0,
                 uv_kf: float = 0.0, color_kf: float = 0.0) -> AttributeBits:
    """The worst-case bound's bits of one part (the module doc, section "The worst-case bound";
    no longer the default, kept for comparison): the fewest bits whose largest attribute error
    changes the shaded colour by at most ``eps`` (colour units), with the analysis's slopes k_f.

    normals : bool, the part has normals; smallest b_n in [4, 16] with
        ``normal_kf * radians(normal_error_deg(b_n)) <= eps`` (normal_kf: colour per unit normal).
    uvs : None or the part's (n, 2) UVs; smallest b_u in [6, 16] with
        ``uv_kf * |uv_error_bound(lo, hi, b_u)| <= eps`` (uv_kf: colour per UV unit, the texture's
        slope; the error vector's length over the part's range).
    colors : bool; smallest b_c in [4, 8] with ``color_kf * color_error_bound(b_c) <= eps``.
    Each is the largest allowed when none satisfies the bound."""
    if not (math.isfinite(eps) and eps > 0):
        raise LopcookError("usage", None, f"eps must be a finite number > 0, got {eps}")
    bn = bu = bc = None
    if normals:
        bn = _fewest(NORMAL_BITS, lambda b: float(normal_kf) * math.radians(normal_error_deg(b)) <= eps)
    if uvs is not None:
        lo, hi = _uv_range(uvs)
        bu = _fewest(UV_BITS, lambda b: float(uv_kf) * float(np.linalg.norm(uv_error_bound(lo, hi, b))) <= eps)
    if colors:
        bc = _fewest(COLOR_BITS, lambda b: float(color_kf) * color_error_bound(b) <= eps)
    return AttributeBits(normals=bn, uvs=bu, colors=bc)


def _fewest(bounds: tuple[int, int], ok) -> int:
    """The smallest b in [bounds[0], bounds[1]] with ``ok(b)``; bounds[1] when none has."""
    return next((b for b in range(bounds[0], bounds[1] + 1) if ok(b)), bounds[1])


def _uv_range(uvs) -> tuple[np.ndarray, np.ndarray]:
    """(2,) per-component minimum and maximum of (n, 2) UVs (zeros for no vertices)."""
    u = _float_input(uvs, 2, "uvs")
    return (u.min(axis=0), u.max(axis=0)) if u.shape[0] else (np.zeros(2), np.zeros(2))


def part_default_bits(part, analyse_settings, kf: dict | None = None) -> AttributeBits:
    """:func:`default_bits` of a MeshPart under AnalyseSettings (eps, ks, shininess, color_kf):
    the shading's RMS slope and lighting from ``lopcook.analyse.attribute_bound.shading_rms``
    (the verify harness's Phong), the UVs' gradient ``texture_gradient_rms`` of the part's
    texture at the design view (0 without a texture). An explicit k_f (``analyse_settings.kf``,
    or a numeric ``texture_kf`` for UVs) is taken as the RMS slope instead (normals: colour per
    radian; UVs: the gradient's length, split equally between u and v). ``kf``: a PartAnalysis's
    k_f (only its colour entry is used), else ``lopcook.analyse.attribute_kf``."""
    from ..analyse import attribute_kf
    from ..analyse.attribute_bound import shading_rms, texture_gradient_rms

    st = analyse_settings
    kf = attribute_kf(part, st) if kf is None else kf
    slope_rms, lighting_rms = shading_rms(st.ks, st.shininess)
    if st.kf is not None:
        slope_rms = float(st.kf)
    grad = (0.0, 0.0)
    if part.uvs is not None:
        explicit = float(st.kf) if st.kf is not None else (
            float(st.texture_kf) if isinstance(st.texture_kf, (int, float)) else None)
        grad = (explicit / math.sqrt(2.0),) * 2 if explicit is not None else texture_gradient_rms(part)
    return default_bits(normals=part.normals is not None, uvs=part.uvs, colors=part.colors is not None,
                        eps=float(st.eps), normal_slope_rms=slope_rms, uv_gradient_rms=grad,
                        lighting_rms=lighting_rms, color_kf=float(kf.get("color", 0.0)))


def part_bits(settings, index: int, part, part_analysis=None) -> AttributeBits:
    """The attribute bits of scene part ``index`` (a MeshPart) under ``settings`` (a Settings):
    ``settings.attributes.requested(index)`` where given, else :func:`part_default_bits` (with
    the k_f of ``part_analysis``, its PartAnalysis, when given)."""
    try:
        req = settings.attributes.requested(index)
    except ValueError as exc:
        raise LopcookError("usage", None, str(exc), hint="give one (normal, uv, color) entry per part") from None
    if any(r is None for r, present in zip(req, (part.normals, part.uvs, part.colors)) if present is not None):
        d = part_default_bits(part, settings.analyse, None if part_analysis is None else part_analysis.kf)
        req = tuple(d_ if r is None else r for r, d_ in zip(req, (d.normals, d.uvs, d.colors)))
    return bits_for(part.normals is not None, part.uvs is not None, part.colors is not None, req)


def normal_error_deg(bits: int) -> float:
    """Worst-case angle (degrees) of the precise octahedral encoding at ``bits`` per component:
    ``2.7 * 2^(6 - bits)`` for bits >= 6 (11.65 at 4 bits, 5.45 at 5), 3 % above the largest
    angle measured on the test sets and above Cigolle et al. 2014's maxima
    (:data:`CIGOLLE_MAX_ERROR_DEG`); the error halves per added bit."""
    b = _check_bits(bits, NORMAL_BITS, "normal")
    return _SMALL_NORMAL_ERROR_DEG.get(b, 2.7 * 2.0 ** (6 - b))


#: root-mean-square angle (degrees) of the precise octahedral encoding at b bits per component,
#: measured over 20000 directions of a Fibonacci sphere (about 86 * 2^-b for b >= 8: 0.53 x the
#: maximum); tests/test_attribute_bound.py re-measures it on other directions
NORMAL_RMS_ERROR_DEG = {4: 6.081, 5: 2.855, 6: 1.384, 7: 0.6806, 8: 0.3378, 9: 0.1687, 10: 0.08388,
                        11: 0.04197, 12: 0.02096, 13: 0.01048, 14: 0.005258, 15: 0.002626, 16: 0.001311}


def normal_rms_error_deg(bits: int) -> float:
    """Root-mean-square angle (degrees) between directions and their precise octahedral decode at
    ``bits`` per component (:data:`NORMAL_RMS_ERROR_DEG`, measured)."""
    return NORMAL_RMS_ERROR_DEG[_check_bits(bits, NORMAL_BITS, "normal")]


#: below 6 bits the error grows faster than 2^-b: measured maxima 11.42 and 5.34 degrees over the
#: test sets (random directions, code-cell centres, the fold, face centres), with a 2 % margin
_SMALL_NORMAL_ERROR_DEG = {4: 11.65, 5: 5.45}


def uv_error_bound(lo, hi, bits: int) -> np.ndarray:
    """Per-component bound on ``|u' - u|`` (UV units) for values in [lo, hi]:
    ``step / 2 + (hi - lo) * 2^-24 + ulp32(max(|lo|, |hi|))`` (float64, shape (2,))."""
    b = _check_bits(bits, UV_BITS, "uv")
    lo64 = np.asarray(lo, dtype=_F4).astype(np.float64)
    hi64 = np.asarray(hi, dtype=_F4).astype(np.float64)
    step = uv_step(lo64, hi64, b).astype(np.float64)
    big = np.maximum(np.abs(lo64), np.abs(hi64)).astype(_F4)
    return step / 2.0 + (hi64 - lo64) * 2.0 ** -24 + np.spacing(big).astype(np.float64)


def color_error_bound(bits: int) -> float:
    """Bound on ``|c' - c|`` per channel for c in [0, 1]: ``1 / (2 (2^b - 1))`` plus 2^-24
    (float32 rounding of the decode)."""
    b = _check_bits(bits, COLOR_BITS, "color")
    return 1.0 / (2.0 * ((1 << b) - 1)) + 2.0 ** -24


# ---------------------------------------------------------------------------------------------
# helpers

def _float_input(a, width: int, name: str) -> np.ndarray:
    arr = np.asarray(a)
    if arr.ndim != 2 or arr.shape[1] != width:
        raise LopcookError("emit", None, f"{name} must be (n, {width}), got shape {arr.shape}")
    if arr.dtype.kind not in "fiu":
        raise LopcookError("emit", None, f"{name} must be numeric, got {arr.dtype}")
    arr = arr.astype(np.float64)
    if arr.size and not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr)).any(axis=1).sum())
        raise LopcookError("emit", None, f"{bad} {name} contain NaN or Inf",
                           hint="fix or drop the attribute before emitting")
    return arr


def _codes_input(codes, width: int, bits: int, name: str) -> np.ndarray:
    """(n, width) int64 codes from an integer array ((n, width) or flat) of values < 2^bits."""
    c = np.asarray(codes)
    if c.dtype.kind not in "iu":
        raise LopcookError("emit", None, f"{name} codes must be integers, got {c.dtype}")
    if c.ndim not in (1, 2) or (c.ndim == 2 and c.shape[1] != width) or c.size % width:
        raise LopcookError("emit", None, f"{name} codes must be (n, {width}), got {c.shape}")
    c = c.reshape(-1, width).astype(np.int64)
    if c.size and (int(c.min()) < 0 or int(c.max()) >= (1 << bits)):
        raise LopcookError("emit", None, f"{name} codes must be {bits}-bit values")
    return c


def _sgn64(x: np.ndarray) -> np.ndarray:
    return np.where(x >= 0.0, 1.0, -1.0)


def _sgn32(x: np.ndarray) -> np.ndarray:
    return np.where(x >= _F32(0.0), _F32(1.0), _F32(-1.0)).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# normals

def _oct_decode32(cx: np.ndarray, cy: np.ndarray, bits: int) -> np.ndarray:
    """float32 decode of integer codes (any shape) -> (..., 3) unnormalised float32."""
    h = 1 << (bits - 1)
    r = _F32(1.0 / (h - 1))
    one = _F32(1.0)
    px = np.maximum((cx - h).astype(np.float32) * r, _F32(-1.0))
    py = np.maximum((cy - h).astype(np.float32) * r, _F32(-1.0))
    ax, ay = np.abs(px), np.abs(py)
    z = (one - ax) - ay
    neg = z < _F32(0.0)
    x = np.where(neg, (one - ay) * _sgn32(px), px).astype(np.float32)
    y = np.where(neg, (one - ax) * _sgn32(py), py).astype(np.float32)
    return np.stack([x, y, z.astype(np.float32)], axis=-1)


def encode_normals(normals, bits: int = 16) -> np.ndarray:
    """Precise octahedral codes ``(n, 2) uint16`` (values in [1, 2^bits - 1]) of ``(n, 3)``
    directions (any non-zero length). Angle to the decoded normal <= :func:`normal_error_deg`.
    Raises LopcookError for NaN/Inf or zero-length vectors, or bits outside [4, 16]."""
    b = _check_bits(bits, NORMAL_BITS, "normal")
    h = 1 << (b - 1)
    m = h - 1
    d = _float_input(normals, 3, "normals")
    n = d.shape[0]
    if n == 0:
        return np.zeros((0, 2), dtype=np.uint16)
    dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
    l1 = np.abs(dx) + np.abs(dy) + np.abs(dz)
    if not (l1 > 0.0).all():
        raise LopcookError("emit", None, f"{int((l1 <= 0.0).sum())} normals have zero length",
                           hint="recompute normals for degenerate vertices before emitting")
    px, py = dx / l1, dy / l1
    neg = dz < 0.0
    px, py = (np.where(neg, (1.0 - np.abs(py)) * _sgn64(px), px),
              np.where(neg, (1.0 - np.abs(px)) * _sgn64(py), py))
    fx = np.floor(px * m).astype(np.int64)
    fy = np.floor(py * m).astype(np.int64)
    best_x = best_y = best_dot = None
    for ox, oy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        cx = np.clip(fx + ox, -m, m) + h
        cy = np.clip(fy + oy, -m, m) + h
        v = _oct_decode32(cx, cy, b).astype(np.float64)
        dot = (v[:, 0] * dx + v[:, 1] * dy + v[:, 2] * dz) / np.sqrt((v * v).sum(axis=1))
        if best_dot is None:
            best_x, best_y, best_dot = cx, cy, dot
        else:
            better = dot > best_dot
            best_x = np.where(better, cx, best_x)
            best_y = np.where(better, cy, best_y)
            best_dot = np.where(better, dot, best_dot)
    return np.stack([best_x, best_y], axis=1).astype(np.uint16)


def decode_normals(codes, bits: int = 16) -> np.ndarray:
    """``(n, 3) float32`` UNNORMALISED octahedral normals (the float32 decode of the module doc)
    from ``(n, 2)`` integer codes of ``bits`` bits; normalise where a unit vector is needed."""
    b = _check_bits(bits, NORMAL_BITS, "normal")
    c = _codes_input(codes, 2, b, "normals")
    return _oct_decode32(c[:, 0], c[:, 1], b).reshape(-1, 3)


# ---------------------------------------------------------------------------------------------
# uvs

def uv_step(lo, hi, bits: int) -> np.ndarray:
    """``float32((hi - lo) / (2^bits - 1))`` per component, computed in float64 from the float32
    ``lo``, ``hi`` and rounded once; (2,) float32."""
    b = _check_bits(bits, UV_BITS, "uv")
    lo64 = np.asarray(lo, dtype=_F4).astype(np.float64).reshape(-1)
    hi64 = np.asarray(hi, dtype=_F4).astype(np.float64).reshape(-1)
    return ((hi64 - lo64) / float((1 << b) - 1)).astype(np.float32)


def _uv_decode32(q: np.ndarray, lo32: np.ndarray, step32: np.ndarray) -> np.ndarray:
    return (lo32 + q.astype(np.float32) * step32).astype(np.float32)


def encode_uvs(uvs, bits: int = 16, lo=None, hi=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Codes over the buffer's range: ``(codes (n, 2) uint16, lo (2,) float32, hi (2,) float32,
    step (2,) float32)``.

    ``lo``/``hi`` default to the per-component min/max of ``uvs`` (rounded outwards to float32;
    zeros for an empty buffer);
    when given they must be finite, ``lo <= hi``, and contain every value. Error per component
    <= :func:`uv_error_bound`."""
    b = _check_bits(bits, UV_BITS, "uv")
    top = (1 << b) - 1
    u = _float_input(uvs, 2, "uvs")
    if lo is None:  # the float32 at or below the minimum (float64 input may lie between float32s)
        lo32 = np.zeros(2, dtype=_F4)
        if u.shape[0]:
            m = u.min(axis=0)
            lo32 = m.astype(_F4)
            lo32 = np.where(lo32.astype(np.float64) > m, np.nextafter(lo32, _F32(-np.inf)), lo32).astype(_F4)
    else:
        lo32 = np.asarray(lo, dtype=_F4).reshape(2)
    if hi is None:  # the float32 at or above the maximum
        hi32 = np.zeros(2, dtype=_F4)
        if u.shape[0]:
            m = u.max(axis=0)
            hi32 = m.astype(_F4)
            hi32 = np.where(hi32.astype(np.float64) < m, np.nextafter(hi32, _F32(np.inf)), hi32).astype(_F4)
    else:
        hi32 = np.asarray(hi, dtype=_F4).reshape(2)
    lo32, hi32 = (lo32 + _F32(0)).astype(np.float32), (hi32 + _F32(0)).astype(np.float32)  # -0.0 -> +0.0
    lo64, hi64 = lo32.astype(np.float64), hi32.astype(np.float64)
    if not (np.isfinite(lo64).all() and np.isfinite(hi64).all() and (lo64 <= hi64).all()):
        raise LopcookError("emit", None, f"uv range must be finite with lo <= hi, got lo={lo64}, hi={hi64}")
    if u.shape[0] and ((u < lo64).any() or (u > hi64).any()):
        raise LopcookError("emit", None, f"uvs fall outside the given range lo={lo64}, hi={hi64}",
                           hint="omit lo/hi to use the buffer's own range")
    step32 = uv_step(lo32, hi32, b)
    step64 = step32.astype(np.float64)
    safe = np.where(step64 > 0.0, step64, 1.0)
    q0 = np.where(step64 > 0.0, np.clip(np.rint((u - lo64) / safe), 0, top), 0.0).astype(np.int64)
    best_q, best_err = None, None
    for off in (-1, 0, 1):
        q = np.where(step64 > 0.0, np.clip(q0 + off, 0, top), 0)
        err = np.abs(_uv_decode32(q, lo32, step32).astype(np.float64) - u)
        if best_q is None:
            best_q, best_err = q, err
        else:
            better = err < best_err
            best_q = np.where(better, q, best_q)
            best_err = np.where(better, err, best_err)
    return best_q.astype(np.uint16), lo32, hi32, step32


def decode_uvs(codes, lo, step, bits: int = 16) -> np.ndarray:
    """``(n, 2) float32`` uvs ``lo + float32(q) * step`` (float32) from ``(n, 2)`` integer codes."""
    b = _check_bits(bits, UV_BITS, "uv")
    c = _codes_input(codes, 2, b, "uvs")
    lo32 = np.asarray(lo, dtype=_F4).reshape(2).astype(np.float32)
    step32 = np.asarray(step, dtype=_F4).reshape(2).astype(np.float32)
    return _uv_decode32(c, lo32, step32)


# ---------------------------------------------------------------------------------------------
# colors

def encode_colors(colors, bits: int = 8) -> np.ndarray:
    """RGBA codes ``(n, 4) uint16`` in [0, 2^bits - 1]; inputs clamped to [0, 1]; error <=
    :func:`color_error_bound`."""
    b = _check_bits(bits, COLOR_BITS, "color")
    c = _float_input(colors, 4, "colors")
    return np.rint(np.clip(c, 0.0, 1.0) * float((1 << b) - 1)).astype(np.uint16)


def decode_colors(codes, bits: int = 8) -> np.ndarray:
    """``(n, 4) float32`` linear RGBA ``float32(q) * float32(1 / (2^bits - 1))``."""
    b = _check_bits(bits, COLOR_BITS, "color")
    c = _codes_input(codes, 4, b, "colors")
    return (c.astype(np.float32) * _F32(1.0 / ((1 << b) - 1))).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# the record

def record_fields(bits: AttributeBits) -> list[tuple[str, int, int, int]]:
    """``(attribute, component, bit offset in the record, width)`` of every field, in record order."""
    out, off = [], 0
    for name, k, b in (("normals", 2, bits.normals), ("uvs", 2, bits.uvs), ("colors", 4, bits.colors)):
        if b is None:
            continue
        for c in range(k):
            out.append((name, c, off, int(b)))
            off += int(b)
    return out


def record_words(n: int, bits: AttributeBits) -> int:
    """uint32 words of a buffer's attributes section: ``ceil(n S / 32)``."""
    return (int(n) * bits.record_bits + 31) // 32


def record_waste(n: int, bits: AttributeBits) -> int:
    """Bits of the section not holding a field: ``32 words - n S`` (< 32 per buffer)."""
    return 32 * record_words(n, bits) - int(n) * bits.record_bits


def aligned_waste(bits: AttributeBits) -> int:
    """Wasted bits per vertex when no component may cross a 32-bit word (Purnomo 2005, section 4):
    the components packed first-fit decreasing into 32-bit bins, ``32 * bins - S``."""
    widths = sorted((w for _, _, _, w in record_fields(bits)), reverse=True)
    bins: list[int] = []
    for w in widths:
        for i, used in enumerate(bins):
            if used + w <= 32:
                bins[i] += w
                break
        else:
            bins.append(w)
    return 32 * len(bins) - bits.record_bits


class _CodeMemo:
    """The codes of ``record_codes`` by content (attribute, bits, dtype, shape, BLAKE2b of the
    bytes), least recently used dropped past ``max_bytes`` of codes."""

    def __init__(self, max_bytes: int):
        self.max_bytes, self.held, self.entries = int(max_bytes), 0, {}

    @staticmethod
    def key(name: str, bits: int, a) -> tuple:
        import hashlib

        arr = np.ascontiguousarray(a)
        return (name, int(bits), arr.dtype.str, arr.shape, hashlib.blake2b(memoryview(arr).cast("B"),
                                                                         digest_size=20).digest())

    def get(self, key):
        got = self.entries.pop(key, None)
        if got is not None:
            self.entries[key] = got  # most recently used last
        return got

    def put(self, key, value) -> None:
        size = sum(v.nbytes for v in value if isinstance(v, np.ndarray))
        if size > self.max_bytes:
            return
        self.entries[key] = value
        self.held += size
        while self.held > self.max_bytes:
            old = self.entries.pop(next(iter(self.entries)))
            self.held -= sum(v.nbytes for v in old if isinstance(v, np.ndarray))


class _Active(threading.local):
    memo = None  # this thread's open ``_CodeMemo``, or None


_ACTIVE = _Active()

#: the most bytes of codes a ``code_memo`` holds
CODE_MEMO_BYTES = 24 << 20


class code_memo:
    """Context manager: inside it, ``record_codes`` keeps the codes it computes (by content, at most
    ``max_bytes``), so cooking the same scene again with some attribute's bits unchanged encodes
    that attribute once. A search that cooks many probes of one scene (``lopcook.tune``) opens
    one; nested, the outer memo is used; each thread has its own. The codes are the same with or
    without it."""

    def __init__(self, max_bytes: int = CODE_MEMO_BYTES):
        self.max_bytes = int(max_bytes)
        self._opened = False

    def __enter__(self):
        if _ACTIVE.memo is None:
            _ACTIVE.memo = _CodeMemo(self.max_bytes)
            self._opened = True
        return self

    def __exit__(self, *exc) -> None:
        if self._opened:
            _ACTIVE.memo = None
            self._opened = False


def with_code_memo(f):
    """Decorator: ``f`` runs inside a ``code_memo`` (a search that cooks one scene many times)."""
    import functools

    @functools.wraps(f)
    def wrapped(*args, **kwargs):
        with code_memo():
            return f(*args, **kwargs)

    return wrapped


def _memoised(name: str, bits: int, a, encode):
    """``encode()`` (a tuple of arrays and values), through the active ``code_memo`` if any."""
    memo = _ACTIVE.memo
    if memo is None:
        return encode()
    key = memo.key(name, bits, a)
    got = memo.get(key)
    if got is None:
        got = encode()
        memo.put(key, got)
    return got


def record_codes(normals, uvs, colors, bits: AttributeBits) -> tuple[dict, dict]:
    """The integer codes of one buffer's attributes and the record's meta, as ``encode_record``
    computes them: ``({"normals": (n, 2), "uvs": (n, 2), "colors": (n, 4)}`` (uint16, present
    attributes only), meta)``. Every code depends on its own vertex alone (and the UVs' range on the
    set of values), so the codes of a permutation of the vertices are the same permutation of
    these: ``pack_record(codes[order])`` is ``encode_record(attributes[order])``'s words. Checks as
    ``encode_record``; memoised inside a ``code_memo``."""
    arrays = {"normals": normals, "uvs": uvs, "colors": colors}
    n = None
    for name, a in arrays.items():
        have_bits = getattr(bits, name) is not None
        if (a is None) == have_bits:
            raise LopcookError("emit", None, f"{name}: attribute {'absent' if a is None else 'present'} but "
                               f"bits {getattr(bits, name)!r}")
        if a is not None:
            k = np.asarray(a).shape[0]
            if n is not None and k != n:
                raise LopcookError("emit", None, f"attribute lengths differ ({n} and {k} vertices)")
            n = k
    n = n or 0
    codes = {}
    meta = {"record_bits": bits.record_bits, "uv_range": None, "uv_step": None}
    if normals is not None:
        codes["normals"] = _memoised("normals", bits.normals, normals,
                                     lambda: (encode_normals(normals, bits.normals),))[0]
    if uvs is not None:
        q, lo, hi, step = _memoised("uvs", bits.uvs, uvs, lambda: encode_uvs(uvs, bits.uvs))
        codes["uvs"] = q
        meta["uv_range"] = [[float(lo[0]), float(lo[1])], [float(hi[0]), float(hi[1])]]
        meta["uv_step"] = [float(step[0]), float(step[1])]
    if colors is not None:
        codes["colors"] = _memoised("colors", bits.colors, colors,
                                    lambda: (encode_colors(colors, bits.colors),))[0]
    meta["wasted_bits"] = record_waste(n, bits)
    return codes, meta


def encode_record(normals, uvs, colors, bits: AttributeBits) -> tuple[np.ndarray, dict]:
    """Pack one buffer's attributes (binned order) into its record section.

    normals (n, 3), uvs (n, 2), colors (n, 4) or None each, matching which of ``bits``'s fields
    are set (an attribute given with bits None, or bits given without the attribute, is an
    error). Returns ``(words (ceil(n S / 32),) "<u4", meta)`` with meta ``{"record_bits": S,
    "uv_range": [[lo_u, lo_v], [hi_u, hi_v]] | None, "uv_step": [su, sv] | None, "wasted_bits"}``
    (JSON floats of the float32 values). ``words.tobytes()`` is the section payload."""
    codes, meta = record_codes(normals, uvs, colors, bits)
    n = next((int(np.asarray(a).shape[0]) for a in (normals, uvs, colors) if a is not None), 0)
    return pack_record({k: v.astype(np.int64) for k, v in codes.items()}, n, bits), meta


def pack_record(codes: dict, n: int, bits: AttributeBits) -> np.ndarray:
    """Pack integer codes (``{"normals": (n, 2), "uvs": (n, 2), "colors": (n, 4)}``, each field
    below 2^width) into ``ceil(n S / 32)`` uint32 words, LSB first, vertex j at bit j S."""
    s = bits.record_bits
    nwords = record_words(n, bits)
    if nwords == 0:
        return np.zeros(0, dtype=_U4)
    base = np.arange(n, dtype=np.int64) * s
    idx, val = [], []
    for name, c, off, w in record_fields(bits):
        v = np.asarray(codes[name])[:, c].astype(np.int64)
        if v.size and (int(v.min()) < 0 or int(v.max()) >= (1 << w)):
            raise LopcookError("emit", None, f"{name} codes exceed {w} bits")
        pos = base + off
        wi, sh = pos >> 5, pos & 31
        idx.append(wi)
        val.append((v << sh) & 0xFFFFFFFF)
        cross = sh + w > 32
        idx.append(wi[cross] + 1)
        val.append(v[cross] >> (32 - sh[cross]))
    # the fields' bits are disjoint, so the sum per word is their OR (exact in float64: < 2^32)
    total = np.bincount(np.concatenate(idx), weights=np.concatenate(val).astype(np.float64), minlength=nwords)
    return total.astype(np.uint64).astype(_U4)


def unpack_record(words, n: int, bits: AttributeBits) -> dict:
    """Integer codes ``{"normals": (n, 2), ...}`` (int64, present attributes only) of a record
    section: the word reads of ``lop_read_field`` (second word index clamped to the last)."""
    w = np.asarray(words)
    if w.dtype.kind not in "iu" or w.ndim != 1:
        raise LopcookError("emit", None, f"attribute words must be a 1-D integer array, got {w.dtype} {w.shape}")
    need = record_words(n, bits)
    if w.size < need:
        raise LopcookError("emit", None, f"attribute section holds {w.size} words, {n} vertices need {need}")
    w = w.astype(np.uint64)
    last = max(w.size - 1, 0)
    base = np.arange(n, dtype=np.int64) * bits.record_bits
    out: dict = {}
    for name, c, off, width in record_fields(bits):
        pos = base + off
        wi, sh = pos >> 5, (pos & 31).astype(np.uint64)
        lo = w[wi] >> sh
        hi = ((w[np.minimum(wi + 1, last)] << np.uint64(1)) << (np.uint64(31) - sh)) & np.uint64(0xFFFFFFFF)
        v = ((lo | hi) & np.uint64((1 << width) - 1)).astype(np.int64)
        out.setdefault(name, [None] * (2 if name != "colors" else 4))[c] = v
    return {k: np.stack(v, axis=1) for k, v in out.items()}


def decode_record(words, n: int, bits: AttributeBits, uv_range=None, uv_step=None) -> dict:
    """``{"normals", "uvs", "colors"}``: float32 decodes (normals unnormalised; None for an absent
    attribute) of a record section of ``n`` vertices. ``uv_range`` ``[[lo_u, lo_v], [hi_u, hi_v]]``
    and ``uv_step`` ``[su, sv]`` are needed when ``bits.uvs`` is set."""
    codes = unpack_record(words, n, bits)
    out = {"normals": None, "uvs": None, "colors": None}
    if bits.normals is not None:
        out["normals"] = _oct_decode32(codes["normals"][:, 0], codes["normals"][:, 1], bits.normals).reshape(-1, 3)
    if bits.uvs is not None:
        if uv_range is None or uv_step is None:
            raise LopcookError("emit", None, "uv codes need their uv_range and uv_step")
        out["uvs"] = decode_uvs(codes["uvs"], np.asarray(uv_range[0], _F4), np.asarray(uv_step, _F4), bits.uvs)
    if bits.colors is not None:
        out["colors"] = decode_colors(codes["colors"], bits.colors)
    return out


# ---------------------------------------------------------------------------------------------
# specs

_SPECS = {
    "normals": {
        "encoding": "octahedral, precise (best of 4 neighbouring codes; Cigolle et al. 2014), b bits per "
                    "component: h = 2^(b-1), m = h - 1, code = s + h; decode float32: "
                    "p = max(float32(code - h) * float32(1/m), -1); z = (1 - |p.x|) - |p.y|; "
                    "if z < 0: (x, y) = ((1 - |p.y|) sgn(p.x), (1 - |p.x|) sgn(p.y)); (x, y, z) unnormalised",
        "components": 2, "bits": list(NORMAL_BITS), "per": "vertex", "record": "attributes",
        "max_error": "2.7 * 2^(6 - b) (b >= 6); 11.65 (b = 4); 5.45 (b = 5)", "unit": "degrees",
    },
    "uvs": {
        "encoding": "b bits per component over the buffer range (uv_range): step = float32((hi - lo) / (2^b - 1)) "
                    "(uv_step); decode float32: u = lo + float32(q) * step",
        "components": 2, "bits": list(UV_BITS), "per": "vertex", "record": "attributes",
        "max_error": "step / 2 + (hi - lo) * 2^-24 + ulp32(max(|lo|, |hi|))",
        "unit": "UV units per component",
    },
    "colors": {
        "encoding": "RGBA linear, b bits per channel, inputs clamped to [0, 1]: q = rint(c (2^b - 1)); "
                    "decode float32: c = float32(q) * float32(1 / (2^b - 1))",
        "components": 4, "bits": list(COLOR_BITS), "per": "vertex", "record": "attributes",
        "max_error": "1 / (2 (2^b - 1)) + 2^-24", "unit": "linear [0, 1] per channel",
    },
    "attributes": {
        "encoding": "one record per vertex (binned order) of the present fields normal.u, normal.v, uv.u, uv.v, "
                    "color.r, g, b, a; S = 2 b_n + 2 b_u + 4 b_c bits; vertex j at bit j S; fields "
                    "consecutive, least significant bit first, a field may span two 32-bit words",
        "dtype": "<u4", "per": "buffer", "words": "ceil(n S / 32)",
    },
    "indices": {
        "encoding": "uint16 when n_vertices <= 65535 (so 65535, the primitive-restart value, never appears), else uint32; i0 i1 i2 per triangle",
        "dtype": "<u2 or <u4", "components": 3, "bits": 16, "bits_large": 32,
        "bytes_per": 6, "bytes_per_large": 12, "per": "triangle",
        "max_error": 0, "unit": "exact",
    },
}


def attribute_specs() -> dict:
    """Encodings and their worst-case errors as JSON-ready data (a fresh copy): ``"normals"``,
    ``"uvs"``, ``"colors"`` (``bits`` the allowed [min, max] per component, ``max_error`` the
    bound as a formula of b), ``"attributes"`` (the record layout) and ``"indices"``."""
    return copy.deepcopy(_SPECS)


def index_width(n_vertices: int) -> int:
    """Bytes per index: 2 when ``n_vertices <= 65535`` (indices <= 65534, never the uint16
    primitive-restart value 65535), else 4."""
    if n_vertices < 0:
        raise LopcookError("emit", None, f"n_vertices must be >= 0, got {n_vertices}")
    return 2 if n_vertices <= 65535 else 4


# ---------------------------------------------------------------------------------------------
# indices

def encode_indices(indices, n_vertices: int) -> tuple[np.ndarray, int]:
    """Flat index buffer ``(3m,)`` in ``"<u2"`` or ``"<u4"`` and its width in bytes (2 or 4).

    The width is :func:`index_width` ``(n_vertices)``; every index must be in [0, n_vertices).
    """
    t = np.asarray(indices)
    if t.ndim != 2 or t.shape[1] != 3 or (t.size and t.dtype.kind not in "iu"):
        raise LopcookError("emit", None, f"indices must be (m, 3) integers, got {t.dtype} {t.shape}")
    width = index_width(int(n_vertices))
    if t.size and (int(t.min()) < 0 or int(t.max()) >= n_vertices):
        raise LopcookError("emit", None,
                           f"index range [{int(t.min())}, {int(t.max())}] not within [0, {n_vertices})")
    return t.reshape(-1).astype(_U2 if width == 2 else _U4), width


def decode_indices(data, width: int, m: int) -> np.ndarray:
    """``(m, 3) uint32`` triangles from an encoded index buffer: an integer array of ``width``-byte
    index values, or bytes-like data (bytes, bytearray, memoryview, uint8 array) in ``"<u2"``/``"<u4"``."""
    if width not in (2, 4):
        raise LopcookError("emit", None, f"index width must be 2 or 4 bytes, got {width}")
    dtype = _U2 if width == 2 else _U4
    if isinstance(data, np.ndarray) and data.dtype != np.uint8:
        if data.dtype.kind not in "iu" or data.dtype.itemsize != width:
            raise LopcookError("emit", None, f"index array dtype {data.dtype} does not match width {width}")
        flat = data.reshape(-1)
    else:
        raw = np.ascontiguousarray(data).reshape(-1) if isinstance(data, np.ndarray) else memoryview(data).cast("B")
        if raw.nbytes % width:
            raise LopcookError("emit", None, f"index data is {raw.nbytes} bytes, not a multiple of {width}")
        flat = np.frombuffer(raw, dtype=dtype)
    if flat.size != 3 * m:
        raise LopcookError("emit", None, f"index data holds {flat.size} indices, expected {3 * m}")
    return flat.reshape(m, 3).astype(np.uint32)
