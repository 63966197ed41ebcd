// decode_bitplanes.glsl: vertex-shader decoder for binned adaptive precision buffers (GLSL 4.30+).
//
// This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
// sections 4 (per-vertex levels against cracks), 5.3 (binned buffers, VertexId / BitId) and 6.2
// (decoding in the vertex shader with the tables as uniforms).
//
// Mirrors (bit for bit; checked by `lopcook verify OUT.lop --decoders` and tests/test_gpu_decoders.py):
//   lop_bin_start      numpy.searchsorted(VertexId, j, side="right") - 1   (lopcook.lop.bitplane.decode)
//   lop_decode_bits    lopcook.lop.bitplane.decode        (top bits v and width b of vertex j)
//   lop_to_grid        lopcook.lop.bitplane.to_grid       (24-bit grid integers, dropped bits zero)
//   lop_reconstruct    lopcook.lop.bitplane.reconstruct_float32  (float32 metres, identical bits)
//   lop_vertex_level   lopcook.verify.decoders.vertex_levels       (crack-free per-vertex level; the
//                      rule of lopcook.viewing.per_vertex_level: max(min(own, B), bin level))
//
// Bindings (override any of them with #define before this file):
//   SSBO  binding LOP_POSITIONS_BINDING (0)  LopPositions { uint lop_words[]; }  packed buffer P
//         (or #define LOP_WORD(i) yourself, e.g. texelFetch(usamplerBuffer, int(i)).r, and no SSBO
//         is declared: the paper binds P as a buffer texture)
//   UBO   binding LOP_DECODE_UBO_BINDING (0), std140, 288 bytes, one per buffer (part LOD):
//           offset   0  uvec4 lop_vertex_id[8]  VertexId[0..24]; entries 25..31 = 0xFFFFFFFF
//           offset 128  uvec4 lop_bit_id[8]     BitId[0..24] at level B (bit offsets, uint32)
//           offset 256  vec4  lop_origin_half   xyz: float32(grid origin), w: float32(extent / 2^25)
//           offset 272  uvec4 lop_params        x: per-buffer level B (1..24), y: words in P (>= 1),
//                                               z, w: unused (0)
//           (entry k of an array is lop_x[k >> 2][k & 3]: 16-byte std140 / cbuffer array stride
//           without wasting 12 bytes per entry; the same bytes fill the HLSL cbuffer)
//   With #define LOP_CLUSTERED (clustered buffers, issue 16; layout in docs/format.md):
//   UBO   LopDecode grows to 416 bytes: lop_bit_id is unused (may be zero), lop_params.z is the
//           cluster size N (16..1024), and
//           offset 288  uvec4 lop_cluster_id[8] ClusterId[0..24] (clusters in bins <= k);
//                                               entries 25..31 = 0xFFFFFFFF
//   SSBO  binding LOP_CLUSTERS_BINDING (3)  LopClusters { uvec4 lop_clusters[]; }  4 words per
//         cluster c: word t (x, y, z) = anchor a_t | (k_t << 24) (k_t = shared prefix bits,
//         a_t = their value), word 3 = ClusterBit[c] at level B (bit offset of the cluster in P)
//         (or #define LOP_CLUSTER(c) yourself, returning those 4 words as a uvec4)
//   UBO   binding LOP_VIEW_UBO_BINDING (1), std140, 272 bytes, only for lop_vertex_level (per frame):
//           offset   0  vec4  lop_camera          xyz: camera position, metres, grid space
//           offset  16  vec4  lop_level_dist[8]   [b]: distance (metres) from which level b is
//                                                 enough (b = 1..24; lopcook.verify.decoders.view_tables)
//           offset 144  vec4  lop_block_radius[8] [L]: radius (metres) of a level-L block around its
//                                                 centre, float32 margin included
//
// Limits: a buffer holds at most 2^32 / 72 (59 652 323) vertices (BitId is a uint32 bit offset).
// Float reconstruction: every step is exact except three IEEE float32 operations that GLSL 4.x
// requires to be correctly rounded (a + b, a * b); `precise` forbids fusing them into an fma. Integer
// to float conversions only see values below 2^24 (exact), so the implementation's conversion
// rounding never matters. See shaders/README.md.

#ifndef LOP_POSITIONS_BINDING
#define LOP_POSITIONS_BINDING 0
#endif
#ifndef LOP_DECODE_UBO_BINDING
#define LOP_DECODE_UBO_BINDING 0
#endif
#ifndef LOP_VIEW_UBO_BINDING
#define LOP_VIEW_UBO_BINDING 1
#endif

#ifndef LOP_WORD
layout(std430, binding = LOP_POSITIONS_BINDING) readonly buffer LopPositions {
    uint lop_words[];
};
#define LOP_WORD(i) lop_words[(i)]
#endif

#ifdef LOP_CLUSTERED
#ifndef LOP_CLUSTERS_BINDING
#define LOP_CLUSTERS_BINDING 3
#endif
#ifndef LOP_CLUSTER
layout(std430, binding = LOP_CLUSTERS_BINDING) readonly buffer LopClusters {
    uvec4 lop_clusters[];  // 4 uint32 words per cluster (std430: 16-byte stride, no padding)
};
#define LOP_CLUSTER(c) lop_clusters[(c)]
#endif
#endif

layout(std140, binding = LOP_DECODE_UBO_BINDING) uniform LopDecode {
    uvec4 lop_vertex_id[8];
    uvec4 lop_bit_id[8];
    vec4 lop_origin_half;
    uvec4 lop_params;
#ifdef LOP_CLUSTERED
    uvec4 lop_cluster_id[8];
#endif
};

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
    precise vec3 cf = vec3(c >> 1u) * 2.0 + vec3(c & 1u);
    precise vec3 p = lop_origin_half.xyz + cf * lop_origin_half.w;
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

layout(std140, binding = LOP_VIEW_UBO_BINDING) uniform LopView {
    vec4 lop_camera;
    vec4 lop_level_dist[8];
    vec4 lop_block_radius[8];
};

#define LOP_LEVEL_DIST(i) lop_level_dist[(i) >> 2u][(i) & 3u]
#define LOP_BLOCK_RADIUS(i) lop_block_radius[(i) >> 2u][(i) & 3u]

// Smallest level b in [1, 24] that the view needs for a point at most |p - camera| + radius(L)
// metres away: 1 + the number of levels b < 24 whose distance lop_level_dist[b] the bound does not
// reach. Compared squared (no sqrt); the factor 1 + 2^-18 on the left makes the test lenient by more
// than float32 rounding, so the level never exceeds the CPU's per-buffer level for the part's box.
uint lop_own_level(vec3 p, uint L)
{
    precise vec3 d = p - lop_camera.xyz;
    precise float d2 = (d.x * d.x + d.y * d.y) + d.z * d.z;
    precise float lhs = d2 * (1.0 + 1.0 / 262144.0);
    float r = LOP_BLOCK_RADIUS(L);
    uint own = 1u;
    for (uint b = 1u; b < 24u; ++b) {
        precise float t = LOP_LEVEL_DIST(b) - r;
        precise float t2 = t * t;
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
