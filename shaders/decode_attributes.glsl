// decode_attributes.glsl: vertex-shader decoder for the packed vertex attribute record (GLSL 4.30+).
//
// This work is based on: Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex Compression
// Using Quantization and Simplification", Graphics Hardware 2005, sections 3-5 (per-attribute bit
// widths, one packed record per vertex), with the octahedral normal of Cigolle et al., "A Survey of
// Efficient Representations for Independent Unit Vectors", JCGT 3(2), 2014 ("precise" variant).
// Unlike Purnomo's word bins, a field may cross a 32-bit word: a second word read (as the
// positions' lop_read_field), no bits lost to padding inside a word.
//
// Mirrors (bit for bit; checked by `lopcook verify OUT.lop --decoders` and
// tests/test_gpu_attribute_decoders.py): lopcook.lop.record.decode_record
//   lop_attr_read_field   the b-bit field at bit o of the section, least significant bit first
//   lop_decode_normal     record["normals"][j]  unnormalised float32 octahedral decode (normalise it
//                         where a unit vector is needed, e.g. in the fragment shader)
//   lop_decode_uv         record["uvs"][j]      lo + float32(q) * step
//   lop_decode_color      record["colors"][j]   float32(q) * float32(1 / (2^b_c - 1)), linear RGBA
//   lop_decode_tangent    record["tangents"][j] unnormalised octahedral xyz and w = +-1 (container 4.0)
//
// Record of vertex j (binned order, the positions' order): S = 2 b_n + 2 b_u + 4 b_c (+ 2 b_t + 1)
// bits from bit j * S of the section `part{i}/lod{k}/attributes`, fields in this order, each
// present attribute only (an absent attribute has b = 0 and takes no bits): normal u, v (b_n
// each), uv u, v (b_u each), colour r, g, b, a (b_c each), tangent u, v (b_t each) and its sign bit.
//
// Bindings (override any of them with #define before this file; it can be included beside
// decode_bitplanes.glsl, whose bindings it does not use):
//   SSBO  binding LOP_ATTRIBUTES_BINDING (1)  LopAttributes { uint lop_attr_words[]; }  the section's
//         uint32 words (or #define LOP_ATTR_WORD(i) yourself, e.g. a usamplerBuffer texelFetch,
//         and no SSBO is declared)
//   UBO   binding LOP_ATTR_UBO_BINDING (2), std140, 64 bytes, one per buffer (part LOD):
//           offset  0  uvec4 lop_attr_bits    x: b_n (4..16, 0: no normals), y: b_u (6..16, 0: no
//                                             UVs), z: b_c (4..8, 0: no colours), w: S (record bits)
//           offset 16  vec4  lop_attr_scale   x: float32(1 / (2^(b_n-1) - 1)), y: float32(1 / (2^b_c - 1)),
//                                             z: float32(1 / (2^(b_t-1) - 1)), w: unused (0)
//           offset 32  vec4  lop_attr_uv      xy: lo (manifest uv_range[0]), zw: step (manifest uv_step)
//           offset 48  uvec4 lop_attr_params  x: words in the section (>= 1), y: b_t (4..16, 0: no
//                                             tangents), z, w: unused (0)
//         Every float is a float32 value computed once on the CPU (lopcook.verify.attribute_gpu.attribute_block);
//         never compute them in the shader (GLSL division is not correctly rounded).
//
// Limits: a buffer holds at most 2^32 / 129 (33 294 320) vertices (j * S is a uint32 bit offset).
// Float decode: integer -> float conversions see values below 2^16 (exact); the remaining float32
// operations (a + b, a - b, a * b, max, abs, multiplication by +-1) are correctly rounded or exact
// in GLSL 4.x; `precise` forbids fusing the UV's product and sum into an fma. See shaders/README.md.

#ifndef LOP_ATTRIBUTES_BINDING
#define LOP_ATTRIBUTES_BINDING 1
#endif
#ifndef LOP_ATTR_UBO_BINDING
#define LOP_ATTR_UBO_BINDING 2
#endif

#ifndef LOP_ATTR_WORD
layout(std430, binding = LOP_ATTRIBUTES_BINDING) readonly buffer LopAttributes {
    uint lop_attr_words[];
};
#define LOP_ATTR_WORD(i) lop_attr_words[(i)]
#endif

layout(std140, binding = LOP_ATTR_UBO_BINDING) uniform LopAttributeDecode {
    uvec4 lop_attr_bits;
    vec4 lop_attr_scale;
    vec4 lop_attr_uv;
    uvec4 lop_attr_params;
};

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
    precise vec2 p = max(vec2(s) * r, vec2(-1.0));
    precise vec2 a = abs(p);
    precise float ax = 1.0 - a.x;
    precise float ay = 1.0 - a.y;
    precise float z = ax - a.y;
    vec2 xy = p;
    if (z < 0.0) {
        precise float fx = ay * lop_attr_sgn(p.x);
        precise float fy = ax * lop_attr_sgn(p.y);
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
    precise vec2 uv = lop_attr_uv.xy + vec2(q) * lop_attr_uv.zw;
    return uv;
}

// Linear RGBA colour of vertex j: float32(q) * float32(1 / (2^b_c - 1)) per channel (b = b_c).
vec4 lop_decode_color(uint j)
{
    uint b = lop_attr_bits.z;
    uint o = lop_attr_record(j) + 2u * lop_attr_bits.x + 2u * lop_attr_bits.y;
    uvec4 q = uvec4(lop_attr_read_field(o, b), lop_attr_read_field(o + b, b), lop_attr_read_field(o + 2u * b, b),
                    lop_attr_read_field(o + 3u * b, b));
    precise vec4 c = vec4(q) * lop_attr_scale.y;
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
