// decode_attributes.es.glsl: vertex-shader decoder for the packed vertex attribute record (GLSL ES 3.00, WebGL2).
//
// GENERATED from shaders/decode_attributes.glsl (code sha256 ab23a18ae9692910) by
// `python -m lopcook.verify.webgl --update`; do not edit (lopcook/verify/webgl.py says what
// changes: storage buffers read as integer textures, uniform blocks as plain uniforms, `precise`
// replaced by lop_rounded on every product that feeds a sum). Every function is the twin's, so
// the twin's comments and tests/test_webgl_decoders.py's transform-feedback check hold: the
// decode is bit-exact with lopcook's CPU reference and runtime/js/lop.js.
//
// Include it after `#version 300 es` and any #define (LOP_CLUSTERED, LOP_NO_VIEW, ...) in a
// vertex shader; word i of a texture is texel (i & 2047, i >> 11) (lop.js textureLayout);
// set the uniforms from lop.js decodeInputs / attributeInputs.

#ifndef LOP_ES_PRELUDE
#define LOP_ES_PRELUDE
// Texel of word (or record) i of an integer texture of rows of 2^11 texels.
#define LOP_TEXTURE_WIDTH_LOG2 11u
#define LOP_TEXEL(s, i) texelFetch(s, ivec2(int((i) & ((1u << LOP_TEXTURE_WIDTH_LOG2) - 1u)), int((i) >> LOP_TEXTURE_WIDTH_LOG2)), 0)
// Stands in for GLSL 4.x `precise`: x rounded to float32 as it is, never fused into a following
// add (lop_fma_guard is a uniform no compiler can know; leave it at its initial 0).
uniform uint lop_fma_guard;
float lop_rounded(float x) { return uintBitsToFloat(floatBitsToUint(x) ^ lop_fma_guard); }
vec2 lop_rounded(vec2 x) { return uintBitsToFloat(floatBitsToUint(x) ^ uvec2(lop_fma_guard)); }
vec3 lop_rounded(vec3 x) { return uintBitsToFloat(floatBitsToUint(x) ^ uvec3(lop_fma_guard)); }
vec4 lop_rounded(vec4 x) { return uintBitsToFloat(floatBitsToUint(x) ^ uvec4(lop_fma_guard)); }
#endif

#ifndef LOP_ATTR_WORD
uniform highp usampler2D lop_attributes;  // R32UI, word i of the attribute section
#define LOP_ATTR_WORD(i) LOP_TEXEL(lop_attributes, (i)).r
#endif

// uniform block LopAttributeDecode of the GLSL twin (std140 there), as plain uniforms
uniform highp uvec4 lop_attr_bits;
uniform highp vec4 lop_attr_scale;
uniform highp vec4 lop_attr_uv;
uniform highp uvec4 lop_attr_params;

// The b-bit field (1 <= b <= 16) at bit offset o of the section, least significant bit first. It
// spans at most two words; the second read is clamped to the last word (its bits are masked away
// whenever the field ends inside the first word), so the section needs no padding word.
uint lop_attr_read_field(uint o, uint b)
{
    uint w = o >> 5u;
    uint s = o & 31u;
    uint lo = LOP_ATTR_WORD(w) >> s;
    uint hi = (LOP_ATTR_WORD(min(w + 1u, lop_attr_params.x - 1u)) << 1u) << (31u - s);  // word << (32 - s), 0 if s == 0
    return (lo | hi) & ((1u << b) - 1u);
}

// Bit offset of vertex j's record.
uint lop_attr_record(uint j)
{
    return j * lop_attr_bits.w;
}

// +1.0 for x >= 0 (zero included), else -1.0 (GLSL's sign() would give 0 for 0).
float lop_attr_sgn(float x)
{
    return (x >= 0.0) ? 1.0 : -1.0;
}

// Octahedral direction of b bits per component at bit offset o, unnormalised float32 (code = s + h,
// h = 2^(b-1)): p = max(float(code - h) * r, -1) with r = float32(1 / (h - 1)) from the UBO (code 0
// reads as -1); z = (1 - |p.x|) - |p.y|; if z < 0 the lower half is unfolded: x = (1 - |p.y|) *
// sgn(p.x), y = (1 - |p.x|) * sgn(p.y). Every step is one correctly rounded (or exact) float32 operation.
vec3 lop_attr_oct(uint o, uint b, float r)
{
    int h = int(1u << (b - 1u));
    ivec2 s = ivec2(int(lop_attr_read_field(o, b)), int(lop_attr_read_field(o + b, b))) - h;
    vec2 p = max(vec2(s) * r, vec2(-1.0));
    vec2 a = abs(p);
    float ax = 1.0 - a.x;
    float ay = 1.0 - a.y;
    float z = ax - a.y;
    vec2 xy = p;
    if (z < 0.0) {
        float fx = ay * lop_attr_sgn(p.x);
        float fy = ax * lop_attr_sgn(p.y);
        xy = vec2(fx, fy);
    }
    return vec3(xy, z);
}

// Octahedral normal of vertex j, unnormalised float32 (b = b_n, r = lop_attr_scale.x).
vec3 lop_decode_normal(uint j)
{
    return lop_attr_oct(lop_attr_record(j), lop_attr_bits.x, lop_attr_scale.x);
}

// Texture coordinates of vertex j: lo + float32(q) * step per component (b = b_u), one rounded
// product and one rounded sum (`precise`: no fma). A degenerate range has step 0 and gives lo.
vec2 lop_decode_uv(uint j)
{
    uint b = lop_attr_bits.y;
    uint o = lop_attr_record(j) + 2u * lop_attr_bits.x;
    uvec2 q = uvec2(lop_attr_read_field(o, b), lop_attr_read_field(o + b, b));
    vec2 uv = lop_attr_uv.xy + lop_rounded(vec2(q) * lop_attr_uv.zw);
    return uv;
}

// Linear RGBA colour of vertex j: float32(q) * float32(1 / (2^b_c - 1)) per channel (b = b_c).
vec4 lop_decode_color(uint j)
{
    uint b = lop_attr_bits.z;
    uint o = lop_attr_record(j) + 2u * lop_attr_bits.x + 2u * lop_attr_bits.y;
    uvec4 q = uvec4(lop_attr_read_field(o, b), lop_attr_read_field(o + b, b), lop_attr_read_field(o + 2u * b, b),
                    lop_attr_read_field(o + 3u * b, b));
    vec4 c = vec4(q) * lop_attr_scale.y;
    return c;
}

// Tangent of vertex j: xyz the unnormalised octahedral decode (b = b_t, r = lop_attr_scale.z), w the
// handedness, -1.0 when its sign bit is set, else +1.0 (the bitangent is w * cross(normal, xyz)).
vec4 lop_decode_tangent(uint j)
{
    uint b = lop_attr_params.y;
    uint o = lop_attr_record(j) + 2u * lop_attr_bits.x + 2u * lop_attr_bits.y + 4u * lop_attr_bits.z;
    vec3 t = lop_attr_oct(o, b, lop_attr_scale.z);
    float w = (lop_attr_read_field(o + 2u * b, 1u) != 0u) ? -1.0 : 1.0;
    return vec4(t, w);
}
