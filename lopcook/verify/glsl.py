"""GLSL 4.50 sources of the render harness: the vertex shader (float32 or GPU-decoded positions),
the Phong fragment shader with its part-ID target, and the part-ID resolve pass.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 6.2 (positions decoded in the vertex shader).

* ``vertex_shader_source(decoded=True)``: the shipped ``shaders/decode_bitplanes.glsl`` (with
  ``LOP_NO_VIEW``) followed by ``VS_MAIN``; the position is ``lop_decode(gl_VertexID)`` (index value
  = vertex), read from SSBO 0 (packed words) and UBO 0 (tables and grid,
  ``lopcook.verify.gpu.decode_block``), then mapped by the placement rows ``u_place0..2`` (the
  3 x 4 transform of a ``cook --instances`` placement, identity otherwise) in the float32 order of
  ``lopcook.lop.placement.to_world``. ``clustered=True`` adds ``LOP_CLUSTERED``: the clustered
  layout of docs/format.md 6.9 (SSBO 0 clustered P, SSBO 3 the cluster records, UBO 0
  ``lopcook.verify.gpu.cluster_decode_block``). ``decoded=False``: a float32 ``in_position`` attribute.
  Both pass the source normals, UVs and colours through unchanged.
* ``FS`` (shading): ``colour = base * (ambient + diffuse * max(N.L, 0)) + ks * max(R.V, 0)^shininess``
  (the specular term only where N.L > 0), clamped to [0, 1]; uniforms ``u_phong`` = (ambient,
  diffuse, ks, shininess), ``u_light`` the unit direction towards the light, ``u_eye`` the eye in
  metres. ``base`` = base-colour texture times vertex colour (either 1 when absent), ``u_base`` when
  a part has neither. Normals are the interpolated ones, renormalised; a part without normals uses
  the face normal from screen-space derivatives, turned towards the eye. Output 0 is RGBA (alpha 1),
  output 1 (R32UI) the uniform ``u_part`` (part index + 1; 0 stays background).
* ``RESOLVE_VS`` / ``RESOLVE_FS``: one full-screen triangle that copies **sample 0** of each pixel
  of the multisampled part-ID texture (integers cannot be averaged).
"""

from __future__ import annotations

from .gpu import shader_source

VS_MAIN = """
uniform mat4 u_mvp;
uniform vec4 u_place0;         // placement rows (A | t), identity on the scene grid
uniform vec4 u_place1;
uniform vec4 u_place2;
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
    // placement (cook --instances): world = ((a0 p.x + a1 p.y) + a2 p.z) + t per row, float32,
    // no fused multiply-add (lopcook.lop.placement.to_world); the identity on the scene grid
    precise vec3 w;
    w.x = ((u_place0.x * p.x + u_place0.y * p.y) + u_place0.z * p.z) + u_place0.w;
    w.y = ((u_place1.x * p.x + u_place1.y * p.y) + u_place1.z * p.z) + u_place1.w;
    w.z = ((u_place2.x * p.x + u_place2.y * p.y) + u_place2.z * p.z) + u_place2.w;
    p = w;
#endif
    v_pos = p;
    v_normal = in_normal;
    v_uv = in_uv;
    v_color = in_color;
    gl_Position = u_mvp * vec4(p, 1.0);
}
"""

FS = """#version 450
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

RESOLVE_VS = """#version 450
void main()
{
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    gl_Position = vec4(p, 0.0, 1.0);
}
"""

RESOLVE_FS = """#version 450
uniform usampler2DMS u_ids;
layout(location = 0) out uint o_part;
void main()
{
    o_part = texelFetch(u_ids, ivec2(gl_FragCoord.xy), 0).r;
}
"""


def vertex_shader_source(decoded: bool, clustered: bool = False) -> str:
    """GLSL 4.50 vertex shader: ``decoded`` = the shipped ``decode_bitplanes.glsl`` (LOP_NO_VIEW, and
    LOP_CLUSTERED with ``clustered``) with ``lop_decode(gl_VertexID)`` for the position; else a
    float32 ``in_position`` attribute."""
    if decoded:
        head = "#version 450\n#define LOP_NO_VIEW\n" + ("#define LOP_CLUSTERED\n" if clustered else "")
        return head + "#line 1\n" + shader_source("decode_bitplanes.glsl") + VS_MAIN
    return "#version 450\n#define LOP_FLOAT_POSITIONS\n" + VS_MAIN


__all__ = ["VS_MAIN", "FS", "RESOLVE_VS", "RESOLVE_FS", "vertex_shader_source"]
