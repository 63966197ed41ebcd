// decode_bitplanes.es.glsl: vertex-shader decoder for binned adaptive precision buffers (GLSL ES 3.00, WebGL2).
//
// GENERATED from shaders/decode_bitplanes.glsl (code sha256 75e13b7cd123d625) by
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

#ifndef LOP_WORD
uniform highp usampler2D lop_positions;  // R32UI, word i of the packed buffer P
#define LOP_WORD(i) LOP_TEXEL(lop_positions, (i)).r
#endif

#ifdef LOP_CLUSTERED
#ifndef LOP_CLUSTER
uniform highp usampler2D lop_clusters;  // RGBA32UI, cluster c's record (3 header words, ClusterBit)
#define LOP_CLUSTER(c) LOP_TEXEL(lop_clusters, (c))
#endif
#endif

// uniform block LopDecode of the GLSL twin (std140 there), as plain uniforms
uniform highp uvec4 lop_vertex_id[8];
uniform highp uvec4 lop_bit_id[8];
uniform highp vec4 lop_origin_half;
uniform highp uvec4 lop_params;
#ifdef LOP_CLUSTERED
uniform highp uvec4 lop_cluster_id[8];
#endif

#define LOP_VERTEX_ID(i) lop_vertex_id[(i) >> 2u][(i) & 3u]
#define LOP_BIT_ID(i) lop_bit_id[(i) >> 2u][(i) & 3u]
#ifdef LOP_CLUSTERED
#define LOP_CLUSTER_ID(i) lop_cluster_id[(i) >> 2u][(i) & 3u]
#endif

// Largest i in [0, 24] with VertexId[i] <= j, i.e. vertex j lies in bin k = i + 1 (j < VertexId[24]).
// Branch-free: five steps of a binary search over the 32-entry padded table (entries 25..31 are
// 0xFFFFFFFF, so no bounds test is needed).
uint lop_bin_start(uint j)
{
    uint i = 0u;
    i += (LOP_VERTEX_ID(i + 16u) <= j) ? 16u : 0u;
    i += (LOP_VERTEX_ID(i + 8u) <= j) ? 8u : 0u;
    i += (LOP_VERTEX_ID(i + 4u) <= j) ? 4u : 0u;
    i += (LOP_VERTEX_ID(i + 2u) <= j) ? 2u : 0u;
    i += (LOP_VERTEX_ID(i + 1u) <= j) ? 1u : 0u;
    return i;
}

// The b-bit field (1 <= b <= 24) at bit offset o of P, least significant bit first. A field spans at
// most two words; the second read is clamped to the last word (its bits are masked away whenever
// the field ends inside the first word), so P needs no padding word.
uint lop_read_field(uint o, uint b)
{
    uint w = o >> 5u;
    uint s = o & 31u;
    uint lo = LOP_WORD(w) >> s;
    uint hi = (LOP_WORD(min(w + 1u, lop_params.y - 1u)) << 1u) << (31u - s);  // word << (32 - s), 0 if s == 0
    return (lo | hi) & ((1u << b) - 1u);
}

#ifdef LOP_CLUSTERED
// r / n for 0 <= r < 2^26 and 16 <= n <= 1024 without an integer division (which llvmpipe, for
// one, runs lane by lane): a float32 estimate, within 1.5 of r / n (float(r) is off by at most 2,
// 1 / n and the product by a few units in the last place of 2^-23 relative), then two corrections
// each way make it exact. Any rounding or fusing of the float operations stays within that bound.
uint lop_div(uint r, uint n)
{
    uint q = uint(float(r) * (1.0 / float(n)));
    q -= (q * n > r) ? 1u : 0u;
    q -= (q * n > r) ? 1u : 0u;
    q += (r - q * n >= n) ? 1u : 0u;
    q += (r - q * n >= n) ? 1u : 0u;
    return q;
}

// The three fields of widths w.x, w.y, w.z (each 0..24 bits; 0 reads 0) that follow each other from
// bit offset o of P, least significant bit first: four word reads (each clamped to the last word of
// P; clamped words only feed bits past the end of P, which no field uses) give three 32-bit windows
// of the bits from o on, a = bits [o, o + 32), [o + 32, o + 64), [o + 64, o + 96); x is a.x, y
// starts at w.x, z at t = w.x + w.y (< 48: in a.x / a.y or a.y / a.z). x << 1u << (31u - s) is
// x << (32 - s), 0 when s == 0.
uvec3 lop_read_fields(uint o, uvec3 w)
{
    uint n = lop_params.y - 1u;
    uint i = o >> 5u;
    uint s = o & 31u;
    uvec4 x = uvec4(LOP_WORD(min(i, n)), LOP_WORD(min(i + 1u, n)), LOP_WORD(min(i + 2u, n)), LOP_WORD(min(i + 3u, n)));
    uvec3 a = (x.xyz >> s) | ((x.yzw << 1u) << (31u - s));
    uint t = w.x + w.y;
    uint lo = (t < 32u) ? a.x : a.y;
    uint hi = (t < 32u) ? a.y : a.z;
    uint u = t & 31u;
    uvec3 f = uvec3(a.x, (a.x >> w.x) | ((a.y << 1u) << (31u - w.x)), (lo >> u) | ((hi << 1u) << (31u - u)));
    return f & ((uvec3(1u, 1u, 1u) << w) - 1u);
}

// Vertex j (clustered order, 0 <= j < VertexId[24]) of bin k = i + 1: top bits v (b bits per
// component) and the width b = max(bin level, B), as the global grid's decode at b bits. With
// r = j - VertexId[k-1], the vertex lies in cluster c = ClusterId[k-1] + r / N at local index
// l = r % N (lop_div: N in [16, 1024]). Component t keeps k_t bits of the anchor and stores
// w_t = b - min(k_t, b) bits at ClusterBit[c] + l (w_x + w_y + w_z) (x, then y, then z):
// v_t = (a_t >> (k_t - min(k_t, b))) << w_t | field_t, the fields read together by lop_read_fields.
void lop_decode_bits(uint j, out uvec3 v, out uint b, out uint bin_level)
{
    uint i = lop_bin_start(j);
    bin_level = i + 1u;
    b = max(bin_level, lop_params.x);
    uint r = j - LOP_VERTEX_ID(i);
    uint d = lop_div(r, lop_params.z);
    uint c = LOP_CLUSTER_ID(i) + d;
    uint l = r - d * lop_params.z;
    uvec4 rec = LOP_CLUSTER(c);
    uvec3 k = rec.xyz >> 24u;
    uvec3 a = rec.xyz & 0xFFFFFFu;
    uvec3 kb = min(k, b);
    uvec3 w = b - kb;
    uint o = rec.w + l * (w.x + w.y + w.z);
    v = ((a >> (k - kb)) << w) | lop_read_fields(o, w);
}
#else
// Vertex j (binned order, 0 <= j < VertexId[24]): top bits v (b bits per component) and the width
// b = max(bin level, B). The paper's formula: 3 b (j - VertexId[k-1]) + BitId[k-1].
void lop_decode_bits(uint j, out uvec3 v, out uint b, out uint bin_level)
{
    uint i = lop_bin_start(j);
    bin_level = i + 1u;
    b = max(bin_level, lop_params.x);
    uint o = 3u * b * (j - LOP_VERTEX_ID(i)) + LOP_BIT_ID(i);
    v = uvec3(lop_read_field(o, b), lop_read_field(o + b, b), lop_read_field(o + 2u * b, b));
}
#endif

// 24-bit grid integers with the dropped bits zero (v << (24 - b)).
uvec3 lop_to_grid(uvec3 v, uint b)
{
    return v << (24u - b);
}

// Float32 position (metres) of the block centre: origin + float(c) * half_cell, with the block
// centre in half cells c = (2 v + 1) << (24 - b) < 2^25. float(c) is formed as
// float(c >> 1) * 2 + float(c & 1): both conversions are exact (< 2^24), * 2 is exact, and the
// addition rounds to nearest even exactly like numpy's float32(c); then one rounded product and one
// rounded sum. `precise` keeps the compiler from contracting them into an fma.
vec3 lop_reconstruct(uvec3 v, uint b)
{
    uvec3 c = ((v << 1u) | 1u) << (24u - b);
    vec3 cf = lop_rounded(vec3(c >> 1u) * 2.0) + vec3(c & 1u);
    vec3 p = lop_origin_half.xyz + lop_rounded(cf * lop_origin_half.w);
    return p;
}

// Decode vertex j at the per-buffer level B: grid integers, float32 position, bits used.
void lop_decode(uint j, out uvec3 grid, out vec3 position, out uint level)
{
    uvec3 v;
    uint bin_level;
    lop_decode_bits(j, v, level, bin_level);
    grid = lop_to_grid(v, level);
    position = lop_reconstruct(v, level);
}

// ---- optional: crack-free per-vertex levels (paper section 4) ---------------------------------
#ifndef LOP_NO_VIEW

// uniform block LopView of the GLSL twin (std140 there), as plain uniforms
uniform highp vec4 lop_camera;
uniform highp vec4 lop_level_dist[8];
uniform highp vec4 lop_block_radius[8];

#define LOP_LEVEL_DIST(i) lop_level_dist[(i) >> 2u][(i) & 3u]
#define LOP_BLOCK_RADIUS(i) lop_block_radius[(i) >> 2u][(i) & 3u]

// Smallest level b in [1, 24] that the view needs for a point at most |p - camera| + radius(L)
// metres away: 1 + the number of levels b < 24 whose distance lop_level_dist[b] the bound does not
// reach. Compared squared (no sqrt); the factor 1 + 2^-18 on the left makes the test lenient by more
// than float32 rounding, so the level never exceeds the CPU's per-buffer level for the part's box.
uint lop_own_level(vec3 p, uint L)
{
    vec3 d = p - lop_camera.xyz;
    float d2 = (lop_rounded(d.x * d.x) + lop_rounded(d.y * d.y)) + lop_rounded(d.z * d.z);
    float lhs = d2 * (1.0 + 1.0 / 262144.0);
    float r = LOP_BLOCK_RADIUS(L);
    uint own = 1u;
    for (uint b = 1u; b < 24u; ++b) {
        float t = LOP_LEVEL_DIST(b) - r;
        float t2 = t * t;
        own += (t > 0.0 && lhs < t2) ? 1u : 0u;
    }
    return own;
}

// Crack-free per-vertex level of a vertex decoded as (v, b) in a buffer at level B, bin level m:
// the fixed point of L -> own level of the level-L block centre (upper distance bound), started at
// L = 1. It reads only the vertex's top L bits, which every buffer holding the vertex has at least
// as long as its level is at least the vertex's own need (the per-buffer rule of section 4:
// lopcook.verify.decoders.buffer_level), so co-located vertices of neighbouring buffers get the same
// level, whatever those buffers' levels. Result: max(min(L, B), m) in [m, b].
uint lop_vertex_level(uvec3 v, uint b, uint bin_level)
{
    uint B = lop_params.x;
    uint L = 1u;
    for (uint it = 0u; it < 24u; ++it) {
        uint want = min(lop_own_level(lop_reconstruct(v >> (b - L), L), L), B);
        if (want <= L)
            break;
        L = want;
    }
    return max(L, bin_level);
}

// Decode vertex j at its crack-free per-vertex level: the bits below it are zeroed (paper Fig. 4).
void lop_decode_crack_free(uint j, out uvec3 grid, out vec3 position, out uint level)
{
    uvec3 v;
    uint b, bin_level;
    lop_decode_bits(j, v, b, bin_level);
    level = lop_vertex_level(v, b, bin_level);
    uvec3 vl = v >> (b - level);
    grid = lop_to_grid(vl, level);
    position = lop_reconstruct(vl, level);
}

#endif  // LOP_NO_VIEW

// World position of a placement (container 3.0, cook --instances; lopcook.lop.placement.to_world):
// w_i = ((a_i0 p.x + a_i1 p.y) + a_i2 p.z) + t_i per row r_i = (a_i0, a_i1, a_i2, t_i), every product
// and sum rounded to float32 (no fused multiply-add); rows (1,0,0,0), (0,1,0,0), (0,0,1,0) on the
// scene grid give p back exactly.
vec3 lop_place(vec3 p, vec4 r0, vec4 r1, vec4 r2)
{
    vec3 w;
    w.x = ((lop_rounded(r0.x * p.x) + lop_rounded(r0.y * p.y)) + lop_rounded(r0.z * p.z)) + r0.w;
    w.y = ((lop_rounded(r1.x * p.x) + lop_rounded(r1.y * p.y)) + lop_rounded(r1.z * p.z)) + r1.w;
    w.z = ((lop_rounded(r2.x * p.x) + lop_rounded(r2.y * p.y)) + lop_rounded(r2.z * p.z)) + r2.w;
    return w;
}
