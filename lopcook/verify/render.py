"""Render a container against its float source: float vs AP vs CAP, headless (moderngl, EGL).

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 4 (per-buffer level by the half-pixel criterion), 5 (CAP), 6.2 (decoding in the vertex
shader) and 7 (Table 1: levels 6 to 11, memory relative to float32; Fig. 13: PSNR and heat maps
against floating-point vertices); and Purnomo et al., "Hardware-Compatible Vertex Compression Using
Quantization and Simplification", Graphics Hardware 2005, section 4.1 (20 views on an icosahedron,
error over object pixels, background excluded).

What is rendered (``evaluate``), for every per-buffer level B and every view:

* **float**: the source scene (``lopcook.types.Scene``), positions float64 rounded to float32, each
  part with its own index buffer (the same triangles, in the same order, as the container's).
* **AP** (paper section 4): every vertex decoded with B bits. The buffer is packed from the
  container's bits with all vertices in bin 1 (VertexId = [0, n, ..., n]), so the shipped decoder
  reads B bits for each: ``ap_buffer``.
* **CAP** (section 5): the container's binned buffer at B (``lopcook.emit.reader.gpu_buffer``):
  vertices of bin k > B keep k bits.

AP and CAP positions are decoded **on the GPU** by ``lop_decode`` of ``shaders/decode_bitplanes.glsl``
in the vertex shader (``gl_VertexID`` = index value, SSBO 0 = packed words, UBO 0 = tables and grid,
filled by ``lopcook.verify.gpu.decode_block``), never by the CPU. All three renders use the
**source** normals, UVs, colours and textures (permuted to the container's binned order for AP and
CAP), so only positions differ. That is LOD 0; ``evaluate(..., lod=k)`` renders the container's LOD k
(AP and CAP decoded the same way) against the same float LOD-0 source, with the LOD's own index
buffer and its normals, UVs and colours as decoded from the container (``lod_attributes``).
``evaluate_scene`` renders any float-position scene (e.g. a simplified mesh: "simplify only")
against the source with the same cameras and metrics.

Camera (units: metres, degrees, pixels):

* Views: the 20 face-centre directions of a regular icosahedron (``icosahedron_directions``, turned
  by a fixed rotation so that none is within 8.9 degrees of a coordinate plane) around the centre of
  the scene's axis-aligned bounding box (source positions). ``views=N`` takes N of them spread over
  the list (``select_views``).
* Distance for level B: ``d_B = distance_for_level(B, extent, viewing) * (1 + 2^-20)``, where
  ``extent`` is the container's grid extent and ``viewing`` the container's field of view and pixel
  error with the **render** resolution as viewport (``render_viewing``). The camera is placed on the
  view ray so that its distance to the **nearest point of the scene's bounding box** is exactly d_B
  (``place_camera``), so the half-pixel criterion (``lopcook.viewing.required_level``) selects B for
  the whole scene, and for every part (each part's box is at least that far). Since d_B grows with
  the viewport height, an object covers the same number of pixels at level B whatever the
  resolution (about 2^B / sqrt(3) pixels across at the nearest point): a smaller resolution crops,
  it does not shrink. At level 6 an object is some 37 pixels tall: that is the criterion's truth.
* Projection: perspective, vertical field of view from the container (60 degrees by default),
  aspect w/h; near = 0.9 * d_B * cos(half diagonal field of view) (no visible point is closer),
  far = |eye - centre| + 1.01 * r with r the half diagonal of the box.
* ``camera_levels`` lets the decode level and the camera level differ (e.g. decode at 24 from the
  level-8 distance: the harness sanity check).

Shading (``Shading``): Phong with one directional headlight (light direction = from the box centre to
the eye), ``colour = base * (ambient + diffuse * max(N.L, 0)) + ks * max(R.V, 0)^shininess`` (the
specular term only where N.L > 0), clamped to [0, 1]; ambient 0.15, diffuse 0.65, ks and shininess
from the container's analysis options (``manifest["options"]["analyse"]``; defaults 0.5 and 32) so
the k_f = ks * n the analysis assumed is the one rendered. ``base`` = base-colour texture (sampled
with trilinear mipmaps, repeat wrap, texel values used as they are, no sRGB decoding) times the
vertex colour (linear RGB as stored), either of them 1 when absent; grey 0.8 when a part has neither. Normals are the
interpolated source normals, renormalised; a part without normals is shaded with the face normal
(screen-space derivatives). No back-face culling (quantization may flip a tiny triangle's winding;
the paper does not cull either), depth test on.

Framebuffer: 4x MSAA (``SAMPLES``), colour RGBA8 (alpha = 1 where a sample saw the object; the
background is cleared to 0, 0, 0, 0), a part-ID target R32UI (``part index + 1``, 0 = background)
written by the same fragment shader in the same pass, and a 24-bit depth buffer, all 4x multisampled.
Colour is resolved by a framebuffer blit (average of the samples) and read back as 8 bits per channel:
the images are what an 8-bit display shows, and alpha is the pixel's coverage. The ID target is
resolved by a shader that takes **sample 0** of each pixel (integers cannot be averaged), a
documented convention. Images are returned top row first.

Metrics: ``lopcook.verify.metrics`` (PSNR over object pixels, max error, share > 1/255, depth-order
errors from the ID images).

Cost: every (level, view) renders float, AP and CAP once; GPU buffers are uploaded once per level
and reused across views. Measured on llvmpipe (Mesa 22.3.6, 2 cores): the chess set (774,281
vertices, 49 parts) at 1280 x 720, 20 views, levels 6-12 (420 renders) takes 162 s (150 s rendering,
0.36 s per render; 11 s metrics); the fixtures at 320 x 180 take well under a second. Use
``views`` / ``resolution`` (CLI ``--views N --resolution WxH``) to make it cheaper.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..emit.binning import LEVELS, buffer_bytes, table_bit_id
from ..emit.bitplane import pack
from ..emit.reader import GpuBuffer, gpu_buffer, lod_attributes, lod_entry, top_values
from ..errors import LopcookError
from ..viewing import VIEW_ROTATION, Viewing, distance_for_level, nearest_box_distance, required_level
from . import metrics as M

RESOLUTION = (1280, 720)
VIEW_COUNT = 20
DEFAULT_LEVELS = tuple(range(6, 13))
SAMPLES = 4
VARIANTS = ("ap", "cap")
DISTANCE_MARGIN = 2.0**-20  # cameras sit this much (relative) beyond d_B: required_level gives B
AMBIENT = 0.15
DIFFUSE = 0.65
BASE_GREY = 0.8
LOD = 0

_ICO_FACES = np.array([
    [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
    [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
    [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])


# ---- views and cameras ------------------------------------------------------------------------------



def icosahedron_directions() -> np.ndarray:
    """(20, 3) float64 unit vectors: the face centres of a regular icosahedron (vertices (±1, ±φ, 0)
    and cyclic permutations) rotated by ``VIEW_ROTATION``, in a fixed order. Directions point from
    the scene centre to the eye. Unrotated, 12 of the 20 lie in a coordinate plane, and a flat
    axis-aligned part (a plate, a CAD face, a chess board) seen exactly edge-on is a line of
    coverage pixels and nothing else; rotated, every direction is at least 8.9 degrees away from
    each coordinate plane."""
    t = (1.0 + 5.0**0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], np.float64)
    c = v[_ICO_FACES].sum(axis=1)
    c = c / np.linalg.norm(c, axis=1, keepdims=True)
    return c @ VIEW_ROTATION.T


def select_views(views) -> list[int]:
    """Indices into ``icosahedron_directions``: an int N in [1, 20] takes N spread over the 20
    (``floor(i * 20 / N)``), a sequence is taken as given."""
    if isinstance(views, (int, np.integer)):
        n = int(views)
        if not 1 <= n <= VIEW_COUNT:
            raise LopcookError("usage", None, f"views must be in [1, {VIEW_COUNT}], got {n}")
        return [(i * VIEW_COUNT) // n for i in range(n)]
    out = [int(v) for v in views]
    if not out or min(out) < 0 or max(out) >= VIEW_COUNT:
        raise LopcookError("usage", None, f"view indices must be in [0, {VIEW_COUNT - 1}], got {out}")
    return out


def render_viewing(manifest: dict, resolution) -> Viewing:
    """The container's viewing conditions (field of view, pixel error) with the render resolution
    as viewport: the criterion the render is judged by."""
    v = manifest.get("viewing") or {}
    return Viewing(viewport=(int(resolution[0]), int(resolution[1])), fov_y_deg=float(v.get("fov_y_deg", 60.0)),
                   pixel_error=float(v.get("pixel_error", 0.5)))


def camera_distance(level: int, extent: float, viewing: Viewing) -> float:
    """Distance (metres) from the camera to the nearest bounding-box point at which
    ``required_level`` selects ``level``: ``distance_for_level`` plus a 2^-20 relative margin."""
    return distance_for_level(int(level), float(extent), viewing) * (1.0 + DISTANCE_MARGIN)


def place_camera(direction, lo, hi, distance: float) -> np.ndarray:
    """Eye position (3,) float64 on the ray ``centre + t * direction`` (centre of the box [lo, hi])
    whose distance to the nearest box point is ``distance`` metres (bisection on t, to 1e-15 relative)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    u = np.asarray(direction, np.float64)
    u = u / np.linalg.norm(u)
    centre = 0.5 * (lo + hi)
    a, b = 0.0, float(distance) + float(np.linalg.norm(hi - lo)) + 1e-300
    for _ in range(200):
        m = 0.5 * (a + b)
        if nearest_box_distance(centre + m * u, lo, hi) < distance:
            a = m
        else:
            b = m
        if b - a <= 1e-15 * b:
            break
    return centre + b * u


def look_at(eye, target, up=None) -> np.ndarray:
    """(4, 4) float64 view matrix (right-handed, camera looks down -z). ``up`` defaults to +Y, or +Z
    when the view direction is within about 8 degrees of the Y axis."""
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    f = target - eye
    f /= np.linalg.norm(f)
    if up is None:
        up = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.99 else np.array([0.0, 0.0, 1.0])
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """(4, 4) float64 OpenGL projection matrix (clip z in [-w, w])."""
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2.0)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


@dataclass
class Camera:
    """One view: eye (3,) metres, direction index, mvp (4, 4) float64, near/far metres, and the
    distance from the eye to the nearest box point (metres)."""

    view: int
    eye: np.ndarray
    centre: np.ndarray
    mvp: np.ndarray
    near: float
    far: float
    box_distance: float


def make_camera(view: int, lo, hi, distance: float, viewing: Viewing) -> Camera:
    """The camera of icosahedron view ``view`` at ``distance`` metres from the box [lo, hi]."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    eye = place_camera(icosahedron_directions()[view], lo, hi, distance)
    w, h = viewing.viewport
    aspect = float(w) / float(h)
    t = math.tan(math.radians(viewing.fov_y_deg) / 2.0)
    cos_diag = 1.0 / math.sqrt(1.0 + t * t * (1.0 + aspect * aspect))
    span = float(np.linalg.norm(eye - centre)) + 1.01 * radius
    near = 0.9 * distance * cos_diag if distance > 0 else 1e-4 * max(radius, 1e-9)
    near = max(near, span * 1e-7)
    far = span
    mvp = perspective(viewing.fov_y_deg, aspect, near, far) @ look_at(eye, centre)
    return Camera(view=int(view), eye=eye, centre=centre, mvp=mvp, near=near, far=far,
                  box_distance=nearest_box_distance(eye, lo, hi))


# ---- buffers ----------------------------------------------------------------------------------------

def ap_buffer(c, part: int, lod: int, level: int) -> GpuBuffer:
    """AP at per-buffer level B: every vertex with exactly B bits per component (its top B bits of
    the container's grid integers), packed as one bin (VertexId = [0, n, n, ..., n]), decoded by the
    same ``lop_decode`` (bin level 1, width max(1, B) = B)."""
    values, widths = top_values(c, part, lod, level)
    shift = (widths.astype(np.int64) - int(level)).astype(np.uint32)[:, None]
    values = (values >> shift).astype(np.uint32)
    n = values.shape[0]
    vid = np.full(LEVELS + 1, n, dtype=np.int64)
    vid[0] = 0
    return GpuBuffer(words=pack(values, vid, level), vertex_id=vid, bit_id=table_bit_id(vid, level), level=int(level))


def source_order(c, scene, lod: int = LOD) -> list[np.ndarray]:
    """Per part: ``order`` (n,) int64 with ``order[j]`` = the source vertex of container vertex j
    (binned order), recovered from the index buffers (emit keeps the triangle order and only remaps
    indices) and checked against the quantized positions (the top bits of both must agree).
    Raises LopcookError (exit 2) when the container was not cooked from this source."""
    parts = c.manifest["parts"]
    if len(parts) != len(scene.parts):
        raise LopcookError("verify", c.path, f"the container has {len(parts)} parts, the source "
                           f"{scene.source!r} has {len(scene.parts)}",
                           hint="give the source the container was cooked from")
    g = c.manifest["grid"]
    origin = np.asarray(g["origin"], np.float64)
    cell = float(g["extent"]) / float(1 << LEVELS)
    level = min(LEVELS, int(c.available_level))
    out = []
    for i, (pm, sp) in enumerate(zip(parts, scene.parts)):
        e = lod_entry(c, i, lod)
        if e["triangles"] != sp.n_triangles or e["vertices"] != sp.n_vertices:
            raise LopcookError("verify", c.path, f"part {pm['name']!r}: {e['vertices']} vertices and "
                               f"{e['triangles']} triangles in the container, {sp.n_vertices} and "
                               f"{sp.n_triangles} in the source", hint="give the source the container was cooked from")
        idx = lod_attributes(c, i, lod)["indices"].astype(np.int64).ravel()
        src = np.asarray(sp.indices, np.int64).ravel()
        order = np.zeros(e["vertices"], dtype=np.int64)
        order[idx] = src
        if not np.array_equal(order[idx], src):
            raise LopcookError("verify", c.path, f"part {pm['name']!r}: the triangles differ from the source's",
                               hint="give the source the container was cooked from")
        values, widths = top_values(c, i, lod, level)
        q = np.clip(np.floor((sp.positions[order] - origin) / cell), 0, (1 << LEVELS) - 1).astype(np.int64)
        used = np.zeros(e["vertices"], dtype=bool)
        used[idx] = True
        top = q >> (LEVELS - widths.astype(np.int64))[:, None]
        if not np.array_equal(top[used], values.astype(np.int64)[used]):
            raise LopcookError("verify", c.path, f"part {pm['name']!r}: the positions differ from the source's",
                               hint="give the source the container was cooked from")
        out.append(order)
    return out


# ---- shaders ----------------------------------------------------------------------------------------

_VS_MAIN = """
uniform mat4 u_mvp;
in vec3 in_normal;
in vec2 in_uv;
in vec4 in_color;
#ifdef LOP_FLOAT_POSITIONS
in vec3 in_position;
#endif
out vec3 v_pos;
out vec3 v_normal;
out vec2 v_uv;
out vec4 v_color;

void main()
{
    vec3 p;
#ifdef LOP_FLOAT_POSITIONS
    p = in_position;
#else
    uvec3 grid;
    uint bits;
    lop_decode(uint(gl_VertexID), grid, p, bits);
#endif
    v_pos = p;
    v_normal = in_normal;
    v_uv = in_uv;
    v_color = in_color;
    gl_Position = u_mvp * vec4(p, 1.0);
}
"""

_FS = """#version 450
in vec3 v_pos;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_color;
uniform vec3 u_eye;
uniform vec3 u_light;          // unit, towards the light
uniform vec4 u_phong;          // ambient, diffuse, ks, shininess
uniform vec3 u_base;
uniform int u_has_normal;
uniform int u_has_texture;
uniform int u_has_color;
uniform uint u_part;
uniform sampler2D u_texture;
layout(location = 0) out vec4 o_color;
layout(location = 1) out uint o_part;

void main()
{
    vec3 V = normalize(u_eye - v_pos);
    vec3 N;
    float len = length(v_normal);
    if (u_has_normal != 0 && len > 1e-12) {
        N = v_normal / len;
    } else {
        N = normalize(cross(dFdx(v_pos), dFdy(v_pos)));
        N = dot(N, V) < 0.0 ? -N : N;
    }
    vec3 base = u_has_texture != 0 ? texture(u_texture, v_uv).rgb : (u_has_color != 0 ? vec3(1.0) : u_base);
    if (u_has_color != 0)
        base *= v_color.rgb;
    float nl = dot(N, u_light);
    vec3 R = reflect(-u_light, N);
    float spec = nl > 0.0 ? u_phong.z * pow(max(dot(R, V), 0.0), u_phong.w) : 0.0;
    vec3 c = base * (u_phong.x + u_phong.y * max(nl, 0.0)) + vec3(spec);
    o_color = vec4(clamp(c, 0.0, 1.0), 1.0);
    o_part = u_part;
}
"""

_RESOLVE_VS = """#version 450
void main()
{
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    gl_Position = vec4(p, 0.0, 1.0);
}
"""

_RESOLVE_FS = """#version 450
uniform usampler2DMS u_ids;
layout(location = 0) out uint o_part;
void main()
{
    o_part = texelFetch(u_ids, ivec2(gl_FragCoord.xy), 0).r;
}
"""


def vertex_shader_source(decoded: bool) -> str:
    """GLSL 4.50 vertex shader: ``decoded`` = the shipped ``decode_bitplanes.glsl`` (LOP_NO_VIEW) with
    ``lop_decode(gl_VertexID)`` for the position; else a float32 ``in_position`` attribute."""
    from .gpu import shader_source

    if decoded:
        return "#version 450\n#define LOP_NO_VIEW\n#line 1\n" + shader_source("decode_bitplanes.glsl") + _VS_MAIN
    return "#version 450\n#define LOP_FLOAT_POSITIONS\n" + _VS_MAIN


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
        a = (manifest.get("options") or {}).get("analyse") or {}
        return cls(ks=float(a.get("ks", 0.5) if ks is None else ks),
                   shininess=float(a.get("shininess", 32.0) if shininess is None else shininess))

    def as_dict(self) -> dict:
        return {"model": "phong", "light": "directional headlight (from the scene centre to the eye)",
                "ks": self.ks, "shininess": self.shininess, "ambient": self.ambient, "diffuse": self.diffuse,
                "base_grey": self.base}


# ---- the renderer -----------------------------------------------------------------------------------

class Renderer:
    """Programs and framebuffers for one resolution on the process's EGL context
    (``lopcook.verify.gpu.context``). ``draw(items, camera, shading)`` renders a list of
    ``(vao, part_index, has_normal, has_texture, has_color, texture)`` and returns
    ``(rgba (h, w, 4) uint8, ids (h, w) uint32)``, top row first."""

    def __init__(self, resolution=RESOLUTION, samples: int = SAMPLES):
        from . import gpu

        self.ctx = ctx = gpu.context()
        w, h = (int(resolution[0]), int(resolution[1]))
        if w < 1 or h < 1:
            raise LopcookError("usage", None, f"resolution must be positive, got {w}x{h}")
        self.size = (w, h)
        samples = int(min(samples, ctx.max_samples, ctx.max_integer_samples))
        self.samples = samples
        self.float_program = ctx.program(vertex_shader=vertex_shader_source(False), fragment_shader=_FS)
        self.decode_program = ctx.program(vertex_shader=vertex_shader_source(True), fragment_shader=_FS)
        self.resolve_program = ctx.program(vertex_shader=_RESOLVE_VS, fragment_shader=_RESOLVE_FS)
        self.resolve_vao = ctx.vertex_array(self.resolve_program, [])
        self._colour_ms = ctx.renderbuffer((w, h), 4, samples=samples)
        self._ids_ms = ctx.texture((w, h), 1, dtype="u4", samples=samples)
        self._depth_ms = ctx.depth_renderbuffer((w, h), samples=samples)
        self.fbo_ms = ctx.framebuffer([self._colour_ms, self._ids_ms], self._depth_ms)
        self.fbo_ms_colour = ctx.framebuffer([self._colour_ms])  # the blit source (same renderbuffer)
        self._colour = ctx.renderbuffer((w, h), 4)
        self.fbo_colour = ctx.framebuffer([self._colour])
        self._ids = ctx.texture((w, h), 1, dtype="u4")
        self.fbo_ids = ctx.framebuffer([self._ids])
        self._resources = [self.float_program, self.decode_program, self.resolve_program, self.resolve_vao,
                           self.fbo_ms, self.fbo_ms_colour, self._colour_ms, self._ids_ms, self._depth_ms,
                           self.fbo_colour, self._colour, self.fbo_ids, self._ids]

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

    def draw(self, items, camera: Camera, shading: Shading, decoded: bool):
        import moderngl

        ctx = self.ctx
        program = self.decode_program if decoded else self.float_program
        self._uniforms(program, camera, shading)
        self.fbo_ms.use()
        self.fbo_ms.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        for it in items:
            if decoded:
                it["ssbo"].bind_to_storage_buffer(0)
                it["ubo"].bind_to_uniform_block(0)
            program["u_part"].value = int(it["part"]) + 1
            program["u_has_normal"].value = int(it["has_normal"])
            program["u_has_texture"].value = int(it["texture"] is not None)
            program["u_has_color"].value = int(it["has_color"])
            if it["texture"] is not None:
                it["texture"].use(location=0)
            it["vao"].render(moderngl.TRIANGLES)
        # resolve: colour by a blit (average of samples), part IDs by sample 0
        ctx.copy_framebuffer(self.fbo_colour, self.fbo_ms_colour)
        self.fbo_ids.use()
        ctx.disable(moderngl.DEPTH_TEST)
        self._ids_ms.use(location=1)
        self.resolve_program["u_ids"].value = 1
        self.resolve_vao.render(moderngl.TRIANGLES, vertices=3)
        w, h = self.size
        rgba = np.frombuffer(self.fbo_colour.read(components=4, dtype="f1"), np.uint8).reshape(h, w, 4)[::-1].copy()
        ids = np.frombuffer(self._ids.read(), "<u4").reshape(h, w)[::-1].copy()
        from . import gpu

        if gpu._FRAMEBUFFER is not None:  # leave the context as gpu.py expects it (1x1 default target)
            gpu._FRAMEBUFFER.use()
        return rgba, ids

    def release(self) -> None:
        for r in self._resources:
            r.release()
        self._resources = []


class _Textures:
    """moderngl textures of the scene's base-colour images, by content digest (shared by parts)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.cache: dict = {}

    def get(self, texture):
        import moderngl

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
        for t in self.cache.values():
            t.release()
        self.cache = {}


def _attribute_vbos(ctx, normals, uvs, colors, order=None) -> tuple[list, list]:
    """VBO specs (buffer, format, name) of normals (n, 3) / uvs (n, 2) / colours (n, 4) float32 (each
    optional; permuted by ``order`` when given) and the list of buffers to release."""
    specs, bufs = [], []
    for name, arr, fmt in (("in_normal", normals, "3f"), ("in_uv", uvs, "2f"), ("in_color", colors, "4f")):
        if arr is None:
            continue
        a = np.asarray(arr, np.float32)
        if order is not None:
            a = a[order]
        b = ctx.buffer(np.ascontiguousarray(a, dtype="<f4").tobytes())
        bufs.append(b)
        specs.append((b, fmt, name))
    return specs, bufs


def _attribute_buffers(ctx, part, order=None) -> tuple[list, list]:
    """VBO specs (buffer, format, name) of a part's source normals / uvs / colours (permuted by
    ``order`` for binned buffers) and the list of buffers to release."""
    return _attribute_vbos(ctx, part.normals, part.uvs, part.colors, order)


def _float_items(ctx, program, scene, textures) -> tuple[list, list]:
    """Draw items (float32 positions) of every part of ``scene`` and the GL objects to release."""
    items, owned = [], []
    for i, p in enumerate(scene.parts):
        pos = ctx.buffer(np.ascontiguousarray(p.positions, dtype="<f4").tobytes())
        ibo = ctx.buffer(np.ascontiguousarray(p.indices, dtype="<u4").tobytes())
        specs, bufs = _attribute_buffers(ctx, p)
        vao = ctx.vertex_array(program, [(pos, "3f", "in_position"), *specs], index_buffer=ibo,
                               index_element_size=4)
        owned += [pos, ibo, *bufs, vao]
        items.append({"vao": vao, "part": i, "has_normal": p.normals is not None,
                      "has_color": p.colors is not None, "texture": textures.get(p.texture)})
    return items, owned


class Harness:
    """GPU state for one source scene at one resolution: the renderer, float-position draws of the
    source parts, textures, and an optional cache of float renders (``cache_float=True``: keyed by
    the camera matrix, eye and shading, reused across containers of the same scene, e.g. by the k_f
    calibration or the byte-budget fit; about 8 bytes per pixel per cached view)."""

    def __init__(self, scene, resolution=RESOLUTION, samples: int = SAMPLES, cache_float: bool = False):
        from . import gpu

        self.ctx = gpu.context()
        self.scene = scene
        self.renderer = Renderer(resolution, samples)
        self.textures = _Textures(self.ctx)
        self.cache_float = cache_float
        self.float_cache: dict = {}
        lo, hi = scene.bounds()
        self.lo, self.hi = lo, hi
        self.float_items, self._buffers = _float_items(self.ctx, self.renderer.float_program, scene, self.textures)

    def release(self) -> None:
        for b in self._buffers:
            b.release()
        self._buffers = []
        self.textures.release()
        self.renderer.release()
        self.float_cache = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()

    def render_float(self, camera: Camera, shading: Shading, key=None):
        if self.cache_float and key is not None and key in self.float_cache:
            return self.float_cache[key]
        out = self.renderer.draw(self.float_items, camera, shading, decoded=False)
        if self.cache_float and key is not None:
            self.float_cache[key] = out
        return out

    def evaluate(self, container, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, camera_levels=None,
                 variants=VARIANTS, ks: float | None = None, shininess: float | None = None,
                 keep_images: bool = False, image_view: int | None = None, lod: int = LOD,
                 distance_m: float | None = None) -> dict:
        """See the module function ``evaluate``."""
        return _evaluate(self, container, levels=levels, views=views, camera_levels=camera_levels,
                         variants=variants, ks=ks, shininess=shininess, keep_images=keep_images,
                         image_view=image_view, lod=lod, distance_m=distance_m)

    def evaluate_scene(self, test_scene, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, camera_levels=None,
                       distance_m: float | None = None, extent: float | None = None,
                       viewing: Viewing | None = None, shading: Shading | None = None,
                       keep_images: bool = False, image_view: int | None = None) -> dict:
        """Render ``test_scene`` (a ``lopcook.types.Scene`` with **float** positions, e.g. a simplified
        LOD chain level: "simplify only") against this harness's source scene, with the cameras
        ``evaluate`` uses, and measure it like a decoded variant.

        Parameters
        ----------
        test_scene : Scene whose part i stands for source part i (same order: part-ID depth-order
            errors compare part indices); positions float64 metres (rendered as float32), its own
            indices, normals, UVs, colours; textures: each test part's own ``texture``.
        levels : per-buffer levels B (ints in [1, 24]) whose camera distances to use: one row per
            level, the camera where the half-pixel criterion selects B (``camera_distance``); nothing
            is decoded. ``camera_levels`` overrides the camera level per row as in ``evaluate``.
        views : int N in [1, 20] or a list of icosahedron view indices (as ``evaluate``).
        distance_m : when given, every row's camera sits this many metres from the nearest point
            of the source's bounding box instead (its ``camera_level`` is then the level selected there).
        extent : grid extent in metres for the distances (default: ``Grid.fit`` over the source
            positions, the extent a container cooked without LODs has; pass a container's
            ``manifest["grid"]["extent"]`` to use exactly its cameras).
        viewing : field of view and pixel error (default ``Viewing()``: 60 degrees, half a pixel);
            the viewport is always the render resolution (``render_viewing``).
        shading : Phong parameters (default ``Shading()``: ks 0.5, shininess 32).
        keep_images, image_view : as ``evaluate`` (image keys ``float``, ``scene``, ``float_ids``,
            ``scene_ids``, ``scene_heatmap``).

        Returns the dict ``evaluate`` returns (same top-level keys; ``container`` None, ``lod`` None,
        ``variants`` ["scene"]) whose level rows hold one variant, ``"scene"``, with the same metrics
        as ``"ap"``/``"cap"`` (``psnr_mean`` etc.); its ``bytes`` are the test scene's float32
        positions (12 per vertex) and ``percent_of_float32`` is relative to the source's float32
        positions (``float32_bytes``). Also ``test_source``, ``test_vertices``, ``test_triangles``.
        """
        return _evaluate_scene(self, test_scene, levels=levels, views=views, camera_levels=camera_levels,
                               distance_m=distance_m, extent=extent, viewing=viewing, shading=shading,
                               keep_images=keep_images, image_view=image_view)


def lod_indices(c, lod: int) -> list[int]:
    """Per part of container ``c``: the LOD index rendered for LOD ``lod`` -- ``lod`` itself, or the
    part's last (coarsest) LOD when its chain is shorter (a part that stopped simplifying)."""
    if int(lod) < 0:
        raise LopcookError("usage", c.path, f"LOD must be >= 0, got {lod}")
    out = [min(int(lod), len(p["lods"]) - 1) for p in c.manifest["parts"]]
    if int(lod) > 0 and max(out, default=0) < int(lod):
        raise LopcookError("usage", c.path, f"no part has a LOD {lod} (the deepest has "
                           f"{max(out, default=0) + 1} LODs)")
    return out


def lod0_is_source(c) -> bool:
    """Whether LOD 0 of container ``c`` holds the source's own vertices (True unless the container
    was written by the byte-budget fit with a simplified LOD as its only LOD:
    ``options.budget.chosen.lod`` > 0, see ``lopcook.tune.budget``)."""
    chosen = (((c.manifest.get("options") or {}).get("budget") or {}).get("chosen") or {})
    return int(chosen.get("lod", 0) or 0) == 0


def _decoded_items(ctx, program, c, scene, lods, orders, textures, buffers_of, level: int, origin, half_cell,
                   attr_cache: dict) -> tuple[list, list]:
    """Draw items of the decoded variant for every part at ``level``; ``buffers_of(c, part, lod, B)``
    gives the GpuBuffer (AP or CAP); ``lods[i]`` is part i's LOD index. Part i's attributes are the
    source's permuted by ``orders[i]`` when that is not None (LOD 0 of a container cooked from this
    source), else the container's own (``lod_attributes``: normals, UVs, colours as decoded from the
    file). Attribute VBOs and index buffers come from ``attr_cache``."""
    from .gpu import decode_block

    items, owned = [], []
    for i, p in enumerate(scene.parts):
        k = lods[i]
        if i not in attr_cache:
            a = lod_attributes(c, i, k)
            ibo = ctx.buffer(np.ascontiguousarray(a["indices"], dtype="<u4").tobytes())
            if orders[i] is not None:
                specs, bufs = _attribute_buffers(ctx, p, orders[i])
                flags = (p.normals is not None, p.colors is not None, textures.get(p.texture))
            else:
                specs, bufs = _attribute_vbos(ctx, a["normals"], a["uvs"], a["colors"])
                flags = (a["normals"] is not None, a["colors"] is not None,
                         textures.get(p.texture) if a["uvs"] is not None else None)
            attr_cache[i] = (ibo, specs, [ibo, *bufs], flags)
        ibo, specs, _, (has_normal, has_color, texture) = attr_cache[i]
        buf = buffers_of(c, i, k, level)
        words = np.ascontiguousarray(buf.words, dtype="<u4")
        ssbo = ctx.buffer(words.tobytes() if words.size else b"\0\0\0\0")
        ubo = ctx.buffer(decode_block(buf.vertex_id, buf.bit_id, level, origin, half_cell, words.size))
        vao = ctx.vertex_array(program, list(specs), index_buffer=ibo, index_element_size=4)
        owned += [ssbo, ubo, vao]
        items.append({"vao": vao, "ssbo": ssbo, "ubo": ubo, "part": i, "has_normal": has_normal,
                      "has_color": has_color, "texture": texture})
    return items, owned


def _parse_levels(levels, camera_levels, available: int, path) -> tuple[list[int], list[int]]:
    lv = [int(b) for b in levels]
    if not lv:
        raise LopcookError("usage", path, "no levels to render")
    if min(lv) < 1 or max(lv) > LEVELS:
        raise LopcookError("usage", path, f"levels must be in [1, {LEVELS}], got {lv}")
    if max(lv) > available:
        raise LopcookError("usage", path, f"level {max(lv)} is not in this file (it holds levels up to {available})",
                           hint=f"use --levels up to {available}")
    if camera_levels is None:
        cl = list(lv)
    elif isinstance(camera_levels, (int, np.integer)):
        cl = [int(camera_levels)] * len(lv)
    else:
        cl = [int(b) for b in camera_levels]
        if len(cl) != len(lv):
            raise LopcookError("usage", path, "camera_levels must be one level or one per level")
    if min(cl) < 1 or max(cl) > LEVELS:
        raise LopcookError("usage", path, f"camera levels must be in [1, {LEVELS}], got {cl}")
    return lv, cl


def _summary(per_view: list[dict], depth: list[dict], nbytes: int, f32: int) -> dict:
    mses = [m["mse"] for m in per_view]
    psnrs = [m["psnr"] for m in per_view]
    finite = [p for p in psnrs if p is not None]
    obj = sum(m["object_pixels"] for m in per_view)
    off = sum(m["pixels_off"] for m in per_view)
    return {
        "bytes": int(nbytes),
        "percent_of_float32": 100.0 * nbytes / max(f32, 1),
        "psnr_views": psnrs,
        "psnr_min": min(finite) if finite else None,
        "psnr_mean": M.mean_mse_psnr(mses),
        "psnr_pooled": M.pooled_psnr(sum(m["sum_sq"] for m in per_view), obj),
        "psnr_interior_min": min((m["psnr_interior"] for m in per_view if m["psnr_interior"] is not None),
                                 default=None),
        "psnr_interior_mean": M.mean_mse_psnr([m["interior_mse"] for m in per_view]),
        "max_error": max((m["max_error"] for m in per_view), default=0.0),
        "share_off": off / obj if obj else 0.0,
        "pixels_off": int(off),
        "object_pixels": int(obj),
        "depth_order_errors": int(sum(d["depth_order_errors"] for d in depth)),
        "depth_order_errors_views": [int(d["depth_order_errors"]) for d in depth],
        "part_mismatch": int(sum(d["part_mismatch"] for d in depth)),
    }


def _position_bytes(c, lods: list[int], level: int) -> dict:
    """GPU-resident position bytes at per-buffer level B over all parts (part i's LOD ``lods[i]``):
    ``cap`` (binned buffers, ``buffer_bytes``) and ``ap`` (every vertex B bits, whole words per
    buffer), as ``lopcook.emit.summary.memory_rows`` counts them for LOD 0."""
    cap = ap = 0
    for i, k in enumerate(lods):
        vid = np.asarray(lod_entry(c, i, k)["vertex_id"], dtype=np.int64)
        cap += buffer_bytes(vid, level)
        ap += 4 * ((3 * int(level) * int(vid[LEVELS]) + 31) // 32)
    return {"cap": int(cap), "ap": int(ap)}


def _camera_rows(lv, cl, distance_m, extent, viewing) -> list[tuple[int, int, float]]:
    """(decode level, camera level, camera distance m) per row; a fixed ``distance_m`` replaces the
    level distances and its camera level is the level selected there."""
    if distance_m is None:
        return [(b, cb, camera_distance(cb, extent, viewing)) for b, cb in zip(lv, cl)]
    d = float(distance_m)
    if not d > 0.0 or not math.isfinite(d):
        raise LopcookError("usage", None, f"camera distance must be a positive number of metres, got {distance_m}")
    sel = int(np.asarray(required_level(d, extent, viewing)))
    return [(b, sel, d) for b in lv]


def _render_rows(h: Harness, *, plan, view_ids, viewing, extent, shading, draws, variants, keep_images,
                 image_view, seconds) -> tuple[list, dict | None]:
    """The per-level render loop shared by ``evaluate`` and ``evaluate_scene``.

    plan : [(level, camera level, distance m)]; draws(level) -> ({variant: (items, decoded)}, owned GL
    objects released after the level). Returns (rows without the variants' bytes: per variant
    ``(per_view metrics, depth metrics)`` under ``"_raw"``, images or None)."""
    rows = []
    images = None
    coarsest = min(b for b, _, _ in plan)
    best_score = -1.0
    for level, cam_level, distance in plan:
        t0 = time.perf_counter()
        drawn, owned_all = draws(level)
        seconds["upload"] += time.perf_counter() - t0
        per_view = {v: [] for v in variants}
        depth = {v: [] for v in variants}
        cams, float_pixels = [], []
        try:
            for view in view_ids:
                cam = make_camera(view, h.lo, h.hi, distance, viewing)
                cams.append(cam)
                t0 = time.perf_counter()
                key = (cam.mvp.tobytes(), cam.eye.tobytes(), shading)
                ref_rgba, ref_ids = h.render_float(cam, shading, key=key)
                outs = {v: h.renderer.draw(drawn[v][0], cam, shading, decoded=drawn[v][1]) for v in variants}
                seconds["render"] += time.perf_counter() - t0
                t0 = time.perf_counter()
                float_pixels.append(int(np.count_nonzero(ref_rgba[..., 3])))
                for v in variants:
                    per_view[v].append(M.image_metrics(ref_rgba, outs[v][0]))
                    depth[v].append(M.depth_order_errors(ref_ids, outs[v][1]))
                seconds["metrics"] += time.perf_counter() - t0
                if keep_images and level == coarsest:
                    score = per_view[variants[0]][-1]["sum_sq"]
                    chosen = view == image_view if image_view is not None else score > best_score
                    if chosen:
                        best_score = score
                        images = {"level": level, "view": int(view), "float": ref_rgba, "float_ids": ref_ids}
                        for v in variants:
                            images[v] = outs[v][0]
                            images[f"{v}_ids"] = outs[v][1]
                            images[f"{v}_heatmap"] = M.difference_heatmap(ref_rgba, outs[v][0])
        finally:
            for r in owned_all:
                r.release()
        rows.append({
            "level": int(level),
            "camera_level": int(cam_level),
            "camera_distance_m": float(distance),
            "selected_level": int(required_level(distance, extent, viewing)),
            "eye_distance_m": [float(np.linalg.norm(cm.eye - cm.centre)) for cm in cams],
            "near_far_m": [[cm.near, cm.far] for cm in cams],
            "float_object_pixels": float_pixels,
            "_raw": {v: (per_view[v], depth[v]) for v in variants},
        })
    return rows, images


def _header(h: Harness, view_ids, viewing, extent, shading, variants, f32, seconds) -> dict:
    from . import gpu

    return {
        "source": str(h.scene.source),
        "resolution": [int(h.renderer.size[0]), int(h.renderer.size[1])],
        "samples": int(h.renderer.samples),
        "views": view_ids,
        "view_directions": [[float(x) for x in icosahedron_directions()[v]] for v in view_ids],
        "viewing": viewing.as_dict(),
        "grid_extent_m": extent,
        "box_m": [[float(x) for x in h.lo], [float(x) for x in h.hi]],
        "shading": shading.as_dict(),
        "variants": list(variants),
        "parts": len(h.scene.parts),
        "vertices": int(f32 // 12),
        "float32_bytes": int(f32),
        "seconds": {k: round(v, 4) for k, v in seconds.items()},
        "device": gpu.context_info(),
    }


def _evaluate(h: Harness, c, *, levels, views, camera_levels, variants, ks, shininess, keep_images,
              image_view, lod=LOD, distance_m=None) -> dict:
    t_start = time.perf_counter()
    scene = h.scene
    variants = tuple(variants)
    for v in variants:
        if v not in VARIANTS:
            raise LopcookError("usage", c.path, f"unknown variant {v!r} (expected ap and/or cap)")
    lv, cl = _parse_levels(levels, camera_levels, int(c.available_level), c.path)
    view_ids = select_views(views)
    if image_view is not None and int(image_view) not in view_ids:
        raise LopcookError("usage", c.path, f"image view {image_view} is not among the rendered views {view_ids}")
    lods = lod_indices(c, lod)
    if len(c.manifest["parts"]) != len(scene.parts):
        raise LopcookError("verify", c.path, f"the container has {len(c.manifest['parts'])} parts, the source "
                           f"{scene.source!r} has {len(scene.parts)}",
                           hint="give the source the container was cooked from")
    # source attributes where the container's buffer is the source mesh (LOD 0), its own elsewhere
    use_source = lod0_is_source(c) and any(k == 0 for k in lods)
    src_orders = source_order(c, scene) if use_source else [None] * len(lods)
    orders = [o if k == 0 else None for o, k in zip(src_orders, lods)]
    shading = Shading.from_manifest(c.manifest, ks, shininess)
    viewing = render_viewing(c.manifest, h.renderer.size)
    g = c.manifest["grid"]
    extent = float(g["extent"])
    origin = g["origin"]
    half_cell = np.float32(extent / float(1 << LEVELS) / 2.0)
    f32 = 12 * sum(int(lod_entry(c, i, 0)["vertices"]) for i in range(len(c.manifest["parts"])))
    builders = {"ap": ap_buffer, "cap": gpu_buffer}
    ctx = h.ctx
    attr_cache: dict = {}
    seconds = {"upload": 0.0, "render": 0.0, "metrics": 0.0}
    plan = _camera_rows(lv, cl, distance_m, extent, viewing)

    def draws(level):
        drawn, owned_all = {}, []
        for v in variants:
            items, owned = _decoded_items(ctx, h.renderer.decode_program, c, scene, lods, orders, h.textures,
                                          builders[v], level, origin, half_cell, attr_cache)
            drawn[v] = (items, True)
            owned_all += owned
        return drawn, owned_all

    try:
        rows, images = _render_rows(h, plan=plan, view_ids=view_ids, viewing=viewing, extent=extent,
                                    shading=shading, draws=draws, variants=variants, keep_images=keep_images,
                                    image_view=image_view, seconds=seconds)
    finally:
        for entry in attr_cache.values():
            for b in entry[2]:
                b.release()
    for row in rows:
        raw = row.pop("_raw")
        row["float32_bytes"] = int(f32)
        mem = _position_bytes(c, lods, row["level"])
        for v in variants:
            row[v] = _summary(raw[v][0], raw[v][1], mem[v], f32)
    seconds["total"] = time.perf_counter() - t_start
    out = _header(h, view_ids, viewing, extent, shading, variants, f32, seconds)
    out.update({"container": None if c.path is None else str(c.path), "lod": int(lod), "lods": lods,
                "lod_vertices": int(sum(int(lod_entry(c, i, k)["vertices"]) for i, k in enumerate(lods))),
                "levels": rows})
    if keep_images:
        out["images"] = images
    return out


def _evaluate_scene(h: Harness, test, *, levels, views, camera_levels, distance_m, extent, viewing, shading,
                    keep_images, image_view) -> dict:
    from ..analyse import Grid

    t_start = time.perf_counter()
    lv, cl = _parse_levels(levels, camera_levels, LEVELS, None)
    view_ids = select_views(views)
    if image_view is not None and int(image_view) not in view_ids:
        raise LopcookError("usage", None, f"image view {image_view} is not among the rendered views {view_ids}")
    if not test.parts:
        raise LopcookError("usage", test.source, "the test scene has no parts")
    base = viewing or Viewing()
    viewing = Viewing(viewport=h.renderer.size, fov_y_deg=base.fov_y_deg, pixel_error=base.pixel_error)
    shading = shading or Shading()
    if extent is None:
        extent = float(Grid.fit([p.positions for p in h.scene.parts]).extent)
    extent = float(extent)
    f32 = 12 * sum(p.n_vertices for p in h.scene.parts)
    test_bytes = 12 * sum(p.n_vertices for p in test.parts)
    seconds = {"upload": 0.0, "render": 0.0, "metrics": 0.0}
    plan = _camera_rows(lv, cl, distance_m, extent, viewing)
    t0 = time.perf_counter()
    items, owned = _float_items(h.ctx, h.renderer.float_program, test, h.textures)
    seconds["upload"] += time.perf_counter() - t0
    try:
        rows, images = _render_rows(h, plan=plan, view_ids=view_ids, viewing=viewing, extent=extent,
                                    shading=shading, draws=lambda level: ({"scene": (items, False)}, []),
                                    variants=("scene",), keep_images=keep_images, image_view=image_view,
                                    seconds=seconds)
    finally:
        for r in owned:
            r.release()
    for row in rows:
        raw = row.pop("_raw")
        row["float32_bytes"] = int(f32)
        row["scene"] = _summary(raw["scene"][0], raw["scene"][1], test_bytes, f32)
    seconds["total"] = time.perf_counter() - t_start
    out = _header(h, view_ids, viewing, extent, shading, ("scene",), f32, seconds)
    out.update({"container": None, "lod": None, "test_source": str(test.source),
                "test_vertices": int(sum(p.n_vertices for p in test.parts)),
                "test_triangles": int(sum(p.n_triangles for p in test.parts)), "levels": rows})
    if keep_images:
        out["images"] = images
    return out


def evaluate(container, scene, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, resolution=RESOLUTION,
             keep_images: bool = False, camera_levels=None, variants=VARIANTS, samples: int = SAMPLES,
             ks: float | None = None, shininess: float | None = None, image_view: int | None = None,
             lod: int = LOD, distance_m: float | None = None) -> dict:
    """Render ``container`` (a ``lopcook.emit.container.Container``) against its float ``scene``
    (``lopcook.types.Scene``, the source it was cooked from) and measure AP and CAP.

    Parameters
    ----------
    levels : per-buffer levels B to decode (default 6..12); each must be in the file.
    views : int N in [1, 20] (N icosahedron views spread over the 20) or a list of view indices.
    resolution : (width, height) pixels (default 1280 x 720).
    keep_images : also return images of one view at the coarsest level (``images`` below).
    camera_levels : None (camera at the distance of each level), one level for all, or one per level.
    variants : subset of ("ap", "cap") to render (the float source is always rendered).
    samples : MSAA samples (default 4). ks, shininess : override the manifest's Phong parameters.
    image_view : the view kept with ``keep_images`` (default: the view with the largest AP error,
        or CAP when AP is not rendered).
    lod : the container's LOD to render (default 0), always against the float **source** (LOD 0).
        A part with fewer LODs renders its last one (``lod_indices``). LOD 0 of a container cooked
        from this source is drawn with the source's normals, UVs and colours (permuted to the binned
        order, ``source_order``: only positions differ); any other LOD with the container's own
        decoded attributes and index buffer (``lopcook.emit.reader.lod_attributes``), and the
        source part's texture. Part IDs are part indices, so depth-order errors work at every LOD.
    distance_m : None (camera at each level's distance, see the module doc), or one camera
        distance in metres (eye to the nearest point of the source's bounding box) for every row;
        each row's ``camera_level`` is then the level the half-pixel criterion selects there.

    Returns a JSON-ready dict (``images`` excepted):

    * ``container``, ``source`` (paths), ``lod`` (the LOD asked for), ``lods`` [per part, the LOD
      index rendered], ``lod_vertices`` (vertices of those buffers), ``resolution`` [w, h],
      ``samples``, ``views`` [indices], ``view_directions`` [[x, y, z]] (unit, scene centre to eye),
      ``viewing`` (the Viewing the distances use: render resolution, container fov and pixel error),
      ``grid_extent_m``, ``box_m`` [[lo], [hi]] (the scene's bounding box, metres),
      ``shading`` (Phong parameters), ``variants``, ``parts``, ``vertices``, ``float32_bytes``
      (12 bytes per vertex of LOD 0), ``device`` (GL renderer), ``seconds`` (upload, render,
      metrics, total).
    * ``levels``: one dict per level, in the order given:
      ``level`` (decode level B), ``camera_level``, ``camera_distance_m`` (eye to nearest box point),
      ``selected_level`` (``required_level`` at that distance: equals camera_level),
      ``eye_distance_m`` [per view] (eye to box centre), ``near_far_m`` [[near, far] per view],
      ``float_object_pixels`` [per view], ``float32_bytes``, and for each variant ``"ap"`` / ``"cap"``:

      - ``bytes``: GPU-resident position bytes at B over all parts of the rendered LOD
        (as ``lopcook.emit.summary.memory_rows`` counts LOD 0), ``percent_of_float32`` (of LOD 0's);
      - ``psnr_views`` [dB or None per view], ``psnr_min`` (min over views; None when every view is
        identical), ``psnr_mean`` (PSNR of the view-averaged MSE), ``psnr_pooled`` (PSNR of the
        squared errors pooled over all object pixels of all views); ``psnr_interior_min``,
        ``psnr_interior_mean``: the same over pixels fully covered in both images (shading error
        without coverage error, ``metrics.image_metrics``);
      - ``max_error`` (largest channel difference, [0, 1]), ``share_off`` (object pixels off by more
        than 1/255, pooled over views), ``pixels_off``, ``object_pixels`` (summed over views);
      - ``depth_order_errors`` (pixels, summed over views), ``depth_order_errors_views`` [per view],
        ``part_mismatch`` (pixels whose visible part differs, coverage included).

      PSNR, errors and pixel classes are defined in ``lopcook.verify.metrics``.
    * ``images`` (only with ``keep_images``; None if nothing was rendered): ``level`` (the coarsest),
      ``view``, ``float``, ``ap``, ``cap`` ((h, w, 4) uint8 RGBA, top row first, alpha = coverage),
      ``float_ids``, ``ap_ids``, ``cap_ids`` ((h, w) uint32 part index + 1, 0 = background),
      ``ap_heatmap``, ``cap_heatmap`` ((h, w, 3) uint8, ``metrics.difference_heatmap``, full scale
      0.25). Keys of variants not rendered are absent.

    Raises LopcookError: no EGL context (exit 2), levels not in the file, bad views or a LOD no
    part has (usage, exit 2), a source that does not match the container (exit 2).
    """
    with Harness(scene, resolution, samples) as h:
        return h.evaluate(container, levels=levels, views=views, camera_levels=camera_levels, variants=variants,
                          ks=ks, shininess=shininess, keep_images=keep_images, image_view=image_view, lod=lod,
                          distance_m=distance_m)


def evaluate_scene(test_scene, scene, *, levels=DEFAULT_LEVELS, views=VIEW_COUNT, resolution=RESOLUTION,
                   samples: int = SAMPLES, **kw) -> dict:
    """``Harness(scene, resolution, samples).evaluate_scene(test_scene, levels=..., views=..., **kw)``:
    a float-position ``test_scene`` rendered against the float source ``scene`` with ``evaluate``'s
    cameras; see ``Harness.evaluate_scene``."""
    with Harness(scene, resolution, samples) as h:
        return h.evaluate_scene(test_scene, levels=levels, views=views, **kw)


def _fmt_psnr(v) -> str:
    return "inf" if v is None else f"{v:.1f}"


def format_table(result: dict) -> str:
    """Table-1-like text: level, AP memory %, AP PSNR (min / mean over views), CAP memory %, CAP
    PSNR, depth-order error pixels (AP / CAP)."""
    w, hgt = result["resolution"]
    lines = [f"render check: {result['source']} vs {result['container']}",
             f"  {len(result['views'])} views, {w}x{hgt}, {result['samples']}x MSAA, "
             f"Phong ks {result['shading']['ks']:g} n {result['shading']['shininess']:g}; "
             f"PSNR in dB over object pixels (min / mean over views); memory vs float32 "
             f"({result['float32_bytes']:,} bytes)",
             "  level  AP mem  AP PSNR min/mean  CAP mem  CAP PSNR min/mean  depth-order px AP/CAP  distance m"]
    for r in result["levels"]:
        ap, cap = r.get("ap"), r.get("cap")
        apm = f"{ap['percent_of_float32']:5.1f}%" if ap else "     -"
        app = f"{_fmt_psnr(ap['psnr_min']):>6} / {_fmt_psnr(ap['psnr_mean']):<6}" if ap else f"{'-':>15}"
        capm = f"{cap['percent_of_float32']:5.1f}%" if cap else "     -"
        capp = f"{_fmt_psnr(cap['psnr_min']):>6} / {_fmt_psnr(cap['psnr_mean']):<6}" if cap else f"{'-':>15}"
        dep = f"{ap['depth_order_errors'] if ap else '-'} / {cap['depth_order_errors'] if cap else '-'}"
        lv = f"{r['level']}" if r["camera_level"] == r["level"] else f"{r['level']}@{r['camera_level']}"
        lines.append(f"  {lv:>5}  {apm:>6}  {app:>16}  {capm:>7}  {capp:>17}  {dep:>21}  {r['camera_distance_m']:.4g}")
    s = result["seconds"]
    lines.append(f"  {s['total']:.1f} s (render {s['render']:.1f} s, metrics {s['metrics']:.1f} s) on "
                 f"{result['device']['renderer']}")
    return "\n".join(lines)


__all__ = ["RESOLUTION", "VIEW_COUNT", "DEFAULT_LEVELS", "SAMPLES", "VARIANTS", "VIEW_ROTATION",
           "icosahedron_directions", "select_views", "render_viewing", "camera_distance", "place_camera", "look_at",
           "perspective", "Camera", "make_camera", "ap_buffer", "source_order", "vertex_shader_source", "Shading",
           "Renderer", "Harness", "evaluate", "evaluate_scene", "lod_indices", "lod0_is_source", "format_table"]
