// decode_attributes.hlsl: vertex-shader decoder for the packed vertex attribute record (HLSL, SM 5.0+).
//
// This work is based on: Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex Compression
// Using Quantization and Simplification", Graphics Hardware 2005, sections 3-5 (per-attribute bit
// widths, one packed record per vertex), with the octahedral normal of Cigolle et al., "A Survey of
// Efficient Representations for Independent Unit Vectors", JCGT 3(2), 2014 ("precise" variant).
// Unlike Purnomo's word bins, a field may cross a 32-bit word (a second word read).
//
// Line-for-line the same algorithm as decode_attributes.glsl. Mirrors (bit for bit; checked by
// `lopcook verify OUT.lop --decoders`, which compiles this file with glslang's HLSL front end to
// SPIR-V and spirv-cross to GLSL 4.50, and by tests/test_gpu_attribute_decoders.py):
// lopcook.lop.record.decode_record
//   lop_attr_read_field   the b-bit field at bit o of the section, least significant bit first
//   lop_decode_normal     record["normals"][j]  unnormalised float32 octahedral decode
//   lop_decode_uv         record["uvs"][j]      lo + float32(q) * step
//   lop_decode_color      record["colors"][j]   float32(q) * float32(1 / (2^b_c - 1)), linear RGBA
//   lop_decode_tangent    record["tangents"][j] unnormalised octahedral xyz and w = +-1 (container 4.0)
//
// Record of vertex j (binned order): S = 2 b_n + 2 b_u + 4 b_c (+ 2 b_t + 1) bits from bit j * S of
// the section, fields normal u, v (b_n each), uv u, v (b_u each), colour r, g, b, a (b_c each),
// tangent u, v (b_t each) and its sign bit, present ones only.
//
// Bindings (override the registers with #define before this file; they do not collide with
// decode_bitplanes.hlsl's t0, b0, b1):
//   ByteAddressBuffer lop_attr_words : register(LOP_ATTRIBUTES_REGISTER = t1)   the section's uint32
//         words, little-endian (or #define LOP_ATTR_WORD(i) yourself, e.g. a Buffer<uint> read, and
//         no ByteAddressBuffer is declared)
//   cbuffer LopAttributeDecode : register(LOP_ATTR_REGISTER = b2), 64 bytes, one per buffer:
//           offset  0  uint4  lop_attr_bits    x: b_n (0: no normals), y: b_u (0: no UVs), z: b_c
//                                              (0: no colours), w: S (record bits)
//           offset 16  float4 lop_attr_scale   x: float32(1 / (2^(b_n-1) - 1)), y: float32(1 / (2^b_c - 1)),
//                                              z: float32(1 / (2^(b_t-1) - 1))
//           offset 32  float4 lop_attr_uv      xy: lo (manifest uv_range[0]), zw: step (manifest uv_step)
//           offset 48  uint4  lop_attr_params  x: words in the section (>= 1), y: b_t (0: no tangents)
//   (the byte layout equals the GLSL std140 block; lopcook.verify.attribute_gpu.attribute_block builds it)
//
// Limits: a buffer holds at most 2^32 / 129 (33 294 320) vertices (j * S is a uint32 bit offset).
// Float decode: conversions see values below 2^16 (exact); the other float32 operations round to
// nearest even (D3D10+) or are exact; `precise` forbids fusing the UV's product and sum into an
// mad/fma. See shaders/README.md.

#ifndef LOP_ATTRIBUTES_REGISTER
#define LOP_ATTRIBUTES_REGISTER t1
#endif
#ifndef LOP_ATTR_REGISTER
#define LOP_ATTR_REGISTER b2
#endif

#ifndef LOP_ATTR_WORD
ByteAddressBuffer lop_attr_words : register(LOP_ATTRIBUTES_REGISTER);
#define LOP_ATTR_WORD(i) lop_attr_words.Load((i) << 2)
#endif

cbuffer LopAttributeDecode : register(LOP_ATTR_REGISTER)
{
    uint4 lop_attr_bits;
    float4 lop_attr_scale;
    float4 lop_attr_uv;
    uint4 lop_attr_params;
};

// The b-bit field (1 <= b <= 16) at bit offset o of the section, least significant bit first; the
// second word read is clamped to the last word (masked away when the field ends inside the first).
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

// +1.0 for x >= 0 (zero included), else -1.0 (sign() would give 0 for 0).
float lop_attr_sgn(float x)
{
    return (x >= 0.0f) ? 1.0f : -1.0f;
}

// Octahedral direction of b bits per component at bit offset o, unnormalised float32, as
// decode_attributes.glsl's lop_attr_oct (r = float32(1 / (2^(b-1) - 1)) from the cbuffer).
float3 lop_attr_oct(uint o, uint b, float r)
{
    int h = int(1u << (b - 1u));
    int2 s = int2(int(lop_attr_read_field(o, b)), int(lop_attr_read_field(o + b, b))) - h;
    precise float2 p = max(float2(s) * r, float2(-1.0f));
    precise float2 a = abs(p);
    precise float ax = 1.0f - a.x;
    precise float ay = 1.0f - a.y;
    precise float z = ax - a.y;
    float2 xy = p;
    if (z < 0.0f) {
        precise float fx = ay * lop_attr_sgn(p.x);
        precise float fy = ax * lop_attr_sgn(p.y);
        xy = float2(fx, fy);
    }
    return float3(xy, z);
}

// Octahedral normal of vertex j, unnormalised float32 (b = b_n, r = lop_attr_scale.x).
float3 lop_decode_normal(uint j)
{
    return lop_attr_oct(lop_attr_record(j), lop_attr_bits.x, lop_attr_scale.x);
}

// Texture coordinates of vertex j: lo + float32(q) * step per component (`precise`: no fma).
float2 lop_decode_uv(uint j)
{
    uint b = lop_attr_bits.y;
    uint o = lop_attr_record(j) + 2u * lop_attr_bits.x;
    uint2 q = uint2(lop_attr_read_field(o, b), lop_attr_read_field(o + b, b));
    precise float2 uv = lop_attr_uv.xy + float2(q) * lop_attr_uv.zw;
    return uv;
}

// Linear RGBA colour of vertex j: float32(q) * float32(1 / (2^b_c - 1)) per channel.
float4 lop_decode_color(uint j)
{
    uint b = lop_attr_bits.z;
    uint o = lop_attr_record(j) + 2u * lop_attr_bits.x + 2u * lop_attr_bits.y;
    uint4 q = uint4(lop_attr_read_field(o, b), lop_attr_read_field(o + b, b), lop_attr_read_field(o + 2u * b, b),
                    lop_attr_read_field(o + 3u * b, b));
    precise float4 c = float4(q) * lop_attr_scale.y;
    return c;
}

// Tangent of vertex j: xyz the unnormalised octahedral decode (b = b_t, r = lop_attr_scale.z), w the
// handedness, -1.0 when its sign bit is set, else +1.0.
float4 lop_decode_tangent(uint j)
{
    uint b = lop_attr_params.y;
    uint o = lop_attr_record(j) + 2u * lop_attr_bits.x + 2u * lop_attr_bits.y + 4u * lop_attr_bits.z;
    float3 t = lop_attr_oct(o, b, lop_attr_scale.z);
    float w = (lop_attr_read_field(o + 2u * b, 1u) != 0u) ? -1.0f : 1.0f;
    return float4(t, w);
}
