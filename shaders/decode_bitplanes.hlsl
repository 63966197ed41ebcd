// decode_bitplanes.hlsl: vertex-shader decoder for binned adaptive precision buffers (HLSL, SM 5.0+).
//
// This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
// sections 4 (per-vertex levels against cracks), 5.3 (binned buffers, VertexId / BitId) and 6.2
// (decoding in the vertex shader with the tables as uniforms).
//
// Line-for-line the same algorithm as decode_bitplanes.glsl. Mirrors (bit for bit; checked by
// `lopcook verify OUT.lop --decoders`, which compiles this file with glslang's HLSL front end to
// SPIR-V and spirv-cross to GLSL 4.50, and by tests/test_gpu_decoders.py):
//   lop_bin_start      numpy.searchsorted(VertexId, j, side="right") - 1   (lopcook.lop.bitplane.decode)
//   lop_decode_bits    lopcook.lop.bitplane.decode        (top bits v and width b of vertex j)
//   lop_to_grid        lopcook.lop.bitplane.to_grid       (24-bit grid integers, dropped bits zero)
//   lop_reconstruct    lopcook.lop.bitplane.reconstruct_float32  (float32 metres, identical bits)
//   lop_vertex_level   lopcook.verify.decoders.vertex_levels       (crack-free per-vertex level; the
//                      rule of lopcook.viewing.per_vertex_level: max(min(own, B), bin level))
//
// Bindings (override the registers with #define before this file):
//   ByteAddressBuffer lop_words : register(LOP_POSITIONS_REGISTER = t0)   packed buffer P (uint32
//         words, little-endian; or #define LOP_WORD(i) yourself, e.g. a Buffer<uint> read, and no
//         ByteAddressBuffer is declared)
//   cbuffer LopDecode : register(LOP_DECODE_REGISTER = b0), 288 bytes, one per buffer (part LOD):
//           offset   0  uint4  lop_vertex_id[8]  VertexId[0..24]; entries 25..31 = 0xFFFFFFFF
//           offset 128  uint4  lop_bit_id[8]     BitId[0..24] at level B (bit offsets, uint32)
//           offset 256  float4 lop_origin_half   xyz: float32(grid origin), w: float32(extent / 2^25)
//           offset 272  uint4  lop_params        x: per-buffer level B (1..24), y: words in P (>= 1)
//   With #define LOP_CLUSTERED (clustered buffers, issue 16; layout in docs/format.md):
//   cbuffer LopDecode grows to 416 bytes: lop_bit_id unused (may be zero), lop_params.z = cluster
//           size N (16..1024), offset 288 uint4 lop_cluster_id[8] ClusterId[0..24] (25..31 = 0xFFFFFFFF)
//   ByteAddressBuffer lop_clusters : register(LOP_CLUSTERS_REGISTER = t3)   4 uint32 per cluster:
//         a_t | (k_t << 24) for t = x, y, z, then ClusterBit[c] at level B (or #define
//         LOP_CLUSTER(c) yourself, returning them as a uint4)
//   cbuffer LopView : register(LOP_VIEW_REGISTER = b1), 272 bytes, only for lop_vertex_level:
//           offset   0  float4 lop_camera          xyz: camera position, metres, grid space
//           offset  16  float4 lop_level_dist[8]   [b]: distance from which level b is enough
//           offset 144  float4 lop_block_radius[8] [L]: radius of a level-L block, margin included
//   (entry k of an array is lop_x[k >> 2][k & 3]; the byte layout equals the GLSL std140 blocks)
//
// Limits: a buffer holds at most 2^32 / 72 (59 652 323) vertices (BitId is a uint32 bit offset).
// Float reconstruction: exact except three IEEE float32 operations (a + b, a * b) that D3D10+
// requires to round to nearest even; `precise` forbids fusing them into an mad/fma. Integer to
// float conversions only see values below 2^24 (exact). See shaders/README.md.

#ifndef LOP_POSITIONS_REGISTER
#define LOP_POSITIONS_REGISTER t0
#endif
#ifndef LOP_DECODE_REGISTER
#define LOP_DECODE_REGISTER b0
#endif
#ifndef LOP_VIEW_REGISTER
#define LOP_VIEW_REGISTER b1
#endif

#ifndef LOP_WORD
ByteAddressBuffer lop_words : register(LOP_POSITIONS_REGISTER);
#define LOP_WORD(i) lop_words.Load((i) << 2)
#endif

#ifdef LOP_CLUSTERED
#ifndef LOP_CLUSTERS_REGISTER
#define LOP_CLUSTERS_REGISTER t3
#endif
#ifndef LOP_CLUSTER
ByteAddressBuffer lop_clusters : register(LOP_CLUSTERS_REGISTER);
#define LOP_CLUSTER(c) lop_clusters.Load4((c) << 4)
#endif
#endif

cbuffer LopDecode : register(LOP_DECODE_REGISTER)
{
    uint4 lop_vertex_id[8];
    uint4 lop_bit_id[8];
    float4 lop_origin_half;
    uint4 lop_params;
#ifdef LOP_CLUSTERED
    uint4 lop_cluster_id[8];
#endif
};

#define LOP_VERTEX_ID(i) lop_vertex_id[(i) >> 2u][(i) & 3u]
#define LOP_BIT_ID(i) lop_bit_id[(i) >> 2u][(i) & 3u]
#ifdef LOP_CLUSTERED
#define LOP_CLUSTER_ID(i) lop_cluster_id[(i) >> 2u][(i) & 3u]
#endif

// Largest i in [0, 24] with VertexId[i] <= j, i.e. vertex j lies in bin k = i + 1 (j < VertexId[24]).
// Branch-free: five steps of a binary search over the 32-entry padded table.
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

// The b-bit field (1 <= b <= 24) at bit offset o of P, least significant bit first; the second word
// read is clamped to the last word (masked away when the field ends inside the first word).
uint lop_read_field(uint o, uint b)
{
    uint w = o >> 5u;
    uint s = o & 31u;
    uint lo = LOP_WORD(w) >> s;
    uint hi = (LOP_WORD(min(w + 1u, lop_params.y - 1u)) << 1u) << (31u - s);  // word << (32 - s), 0 if s == 0
    return (lo | hi) & ((1u << b) - 1u);
}

#ifdef LOP_CLUSTERED
// r / n for 0 <= r < 2^26 and 16 <= n <= 1024 without an integer division: a float32 estimate
// within 1.5 of r / n, then two corrections each way (see the GLSL file).
uint lop_div(uint r, uint n)
{
    uint q = uint(float(r) * (1.0f / float(n)));
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
uint3 lop_read_fields(uint o, uint3 w)
{
    uint n = lop_params.y - 1u;
    uint i = o >> 5u;
    uint s = o & 31u;
    uint4 x = uint4(LOP_WORD(min(i, n)), LOP_WORD(min(i + 1u, n)), LOP_WORD(min(i + 2u, n)), LOP_WORD(min(i + 3u, n)));
    uint3 a = (x.xyz >> s) | ((x.yzw << 1u) << (31u - s));
    uint t = w.x + w.y;
    uint lo = (t < 32u) ? a.x : a.y;
    uint hi = (t < 32u) ? a.y : a.z;
    uint u = t & 31u;
    uint3 f = uint3(a.x, (a.x >> w.x) | ((a.y << 1u) << (31u - w.x)), (lo >> u) | ((hi << 1u) << (31u - u)));
    return f & ((uint3(1u, 1u, 1u) << w) - 1u);
}

// Vertex j (clustered order) of bin k = i + 1: cluster c = ClusterId[k-1] + r / N, local index
// l = r % N (r = j - VertexId[k-1]; lop_div); component t: anchor bits and w_t = b - min(k_t, b) stored bits
// at ClusterBit[c] + l (w_x + w_y + w_z), read together by lop_read_fields (see the GLSL file).
void lop_decode_bits(uint j, out uint3 v, out uint b, out uint bin_level)
{
    uint i = lop_bin_start(j);
    bin_level = i + 1u;
    b = max(bin_level, lop_params.x);
    uint r = j - LOP_VERTEX_ID(i);
    uint d = lop_div(r, lop_params.z);
    uint c = LOP_CLUSTER_ID(i) + d;
    uint l = r - d * lop_params.z;
    uint4 rec = LOP_CLUSTER(c);
    uint3 k = rec.xyz >> 24u;
    uint3 a = rec.xyz & 0xFFFFFFu;
    uint3 kb = min(k, b);
    uint3 w = b - kb;
    uint o = rec.w + l * (w.x + w.y + w.z);
    v = ((a >> (k - kb)) << w) | lop_read_fields(o, w);
}
#else
// Vertex j (binned order): top bits v (b bits per component), width b = max(bin level, B).
void lop_decode_bits(uint j, out uint3 v, out uint b, out uint bin_level)
{
    uint i = lop_bin_start(j);
    bin_level = i + 1u;
    b = max(bin_level, lop_params.x);
    uint o = 3u * b * (j - LOP_VERTEX_ID(i)) + LOP_BIT_ID(i);
    v = uint3(lop_read_field(o, b), lop_read_field(o + b, b), lop_read_field(o + 2u * b, b));
}
#endif

// 24-bit grid integers with the dropped bits zero (v << (24 - b)).
uint3 lop_to_grid(uint3 v, uint b)
{
    return v << (24u - b);
}

// Float32 block centre (metres): origin + float(c) * half_cell, c = (2 v + 1) << (24 - b) < 2^25,
// float(c) formed as float(c >> 1) * 2 + float(c & 1) (exact conversions, one rounded addition).
float3 lop_reconstruct(uint3 v, uint b)
{
    uint3 c = ((v << 1u) | 1u) << (24u - b);
    precise float3 cf = float3(c >> 1u) * 2.0f + float3(c & 1u);
    precise float3 p = lop_origin_half.xyz + cf * lop_origin_half.w;
    return p;
}

// Decode vertex j at the per-buffer level B: grid integers, float32 position, bits used.
void lop_decode(uint j, out uint3 grid, out float3 position, out uint level)
{
    uint3 v;
    uint bin_level;
    lop_decode_bits(j, v, level, bin_level);
    grid = lop_to_grid(v, level);
    position = lop_reconstruct(v, level);
}

// ---- optional: crack-free per-vertex levels (paper section 4) ---------------------------------
#ifndef LOP_NO_VIEW

cbuffer LopView : register(LOP_VIEW_REGISTER)
{
    float4 lop_camera;
    float4 lop_level_dist[8];
    float4 lop_block_radius[8];
};

#define LOP_LEVEL_DIST(i) lop_level_dist[(i) >> 2u][(i) & 3u]
#define LOP_BLOCK_RADIUS(i) lop_block_radius[(i) >> 2u][(i) & 3u]

// Smallest level b in [1, 24] the view needs for a point at most |p - camera| + radius(L) away
// (squared comparison, lenient by 2^-18 > float32 rounding; see decode_bitplanes.glsl).
uint lop_own_level(float3 p, uint L)
{
    precise float3 d = p - lop_camera.xyz;
    precise float d2 = (d.x * d.x + d.y * d.y) + d.z * d.z;
    precise float lhs = d2 * (1.0f + 1.0f / 262144.0f);
    float r = LOP_BLOCK_RADIUS(L);
    uint own = 1u;
    [loop] for (uint b = 1u; b < 24u; ++b) {
        precise float t = LOP_LEVEL_DIST(b) - r;
        precise float t2 = t * t;
        own += (t > 0.0f && lhs < t2) ? 1u : 0u;
    }
    return own;
}

// Crack-free per-vertex level: fixed point of L -> own level of the level-L block centre, from
// L = 1; max(min(L, B), bin level). Reads only the vertex's top L bits (see the GLSL file).
uint lop_vertex_level(uint3 v, uint b, uint bin_level)
{
    uint B = lop_params.x;
    uint L = 1u;
    [loop] for (uint it = 0u; it < 24u; ++it) {
        uint want = min(lop_own_level(lop_reconstruct(v >> (b - L), L), L), B);
        if (want <= L)
            break;
        L = want;
    }
    return max(L, bin_level);
}

// Decode vertex j at its crack-free per-vertex level: the bits below it are zeroed (paper Fig. 4).
void lop_decode_crack_free(uint j, out uint3 grid, out float3 position, out uint level)
{
    uint3 v;
    uint b, bin_level;
    lop_decode_bits(j, v, b, bin_level);
    level = lop_vertex_level(v, b, bin_level);
    uint3 vl = v >> (b - level);
    grid = lop_to_grid(vl, level);
    position = lop_reconstruct(vl, level);
}

#endif  // LOP_NO_VIEW
