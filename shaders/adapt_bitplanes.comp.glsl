// adapt_bitplanes.comp.glsl: data-parallel precision adaption of binned adaptive precision buffers
// (GLSL 4.30+ compute shaders).
//
// This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
// section 6.1 and Figures 10-11 (unpack P -> U with one thread per element, pack U -> P with one
// thread per system word, add a bit plane by merging an uploaded plane, remove one by zeroing it,
// keeping every bin's minimum level, tables rewritten for the new level).
//
// One file, five kernels; compile it once per kernel with exactly one of these defined:
//   LOP_KERNEL_UNPACK        P (level B) -> U              mirrors to_grid(decode(P, VertexId, BitId, B))
//   LOP_KERNEL_ADD_PLANE     U |= plane p (B -> B + 1)     mirrors lopcook.lop.bitplane.add_plane
//   LOP_KERNEL_REMOVE_PLANE  U &= ~bit of level B (B -> B - 1)   mirrors lopcook.lop.bitplane.remove_plane
//   LOP_KERNEL_TABLES        BitId for the new level       mirrors lopcook.lop.binning.table_bit_id
//   LOP_KERNEL_PACK          U -> P (new level)            mirrors lopcook.lop.bitplane.pack
// A level change B -> B' is: UNPACK at B; ADD_PLANE p = B+1 .. B' (or REMOVE_PLANE B .. B'+1), one
// dispatch per plane; TABLES at B'; PACK at B' into a buffer of ceil(BitId'[24] / 32) words. The
// result is byte-identical to packing level B' from scratch on the CPU (tests/test_gpu_decoders.py).
// VertexId never changes (VertexId[k] = vertices with minimum level <= k); BitId is rewritten on the
// GPU by LOP_KERNEL_TABLES, so no read-back is needed. The CPU only sizes the new P
// (lopcook.lop.binning.buffer_bytes: a 25-term sum over VertexId it already holds).
//
// Bindings (all std430 SSBOs of uint32 words, except the UBO):
//   SSBO 0  LopPackedIn  { uint lop_in[]; }          P at level B (read by UNPACK)
//   SSBO 1  LopUnpacked  { uint lop_u[]; }           U: 3 words per vertex (x, y, z), binned order,
//                                                    24-bit grid integers with the bits below the
//                                                    vertex's width zero (paper Fig. 11a)
//   SSBO 2  LopPlane     { uint lop_plane[]; }       uploaded plane p: bit (offset + 3 j + c) is bit
//                                                    24 - p of component c of vertex j < VertexId[p-1]
//                                                    (the .lop plane section as stored, LSB first)
//   SSBO 3  LopTables    { uint lop_vertex_id[32]; uint lop_bit_id[32]; }  256 bytes, byte-identical
//                                                    to the first 256 bytes of decode_bitplanes'
//                                                    LopDecode block: copy it there to draw
//   SSBO 4  LopPackedOut { uint lop_out[]; }         P at the new level (written by PACK)
//   UBO  0  LopAdapt (std140, 32 bytes) { uvec4 lop_adapt; uvec4 lop_adapt_first; }
//           lop_adapt.x  level: UNPACK B of lop_in; ADD_PLANE the plane p = B + 1; REMOVE_PLANE the
//                        level B being dropped; TABLES and PACK the new level
//           lop_adapt.y  threads: UNPACK n = VertexId[24]; ADD_PLANE VertexId[p-1]; REMOVE_PLANE
//                        VertexId[B-1]; TABLES 1; PACK words of lop_out
//           lop_adapt.z  ADD_PLANE: bit offset of this buffer's slice in lop_plane
//           lop_adapt.w  UNPACK: words in lop_in (>= 1)
//           lop_adapt_first.x  index of this dispatch's first thread (split work into dispatches
//                        of at most 65535 groups)
// Work groups: LOP_LOCAL_SIZE (64) threads along x; dispatch ceil(threads / 64) groups.
//
// Clustered buffers (issue 16; #define LOP_CLUSTERED as well as the kernel; layout in
// docs/format.md): every vertex of a cluster shares the top k_t bits of component t with the
// cluster's anchor a_t; only the bits below them are stored, so the same five kernels change:
//   LOP_KERNEL_UNPACK        P (level B) -> U              mirrors to_grid(decode_clustered(P, clusters, B))
//   LOP_KERNEL_ADD_PLANE     U |= plane p                  mirrors add_plane_clustered: bit 24 - p of a
//                            component with k_t < p comes from the plane, of one with k_t >= p from
//                            the anchor (bit k_t - p of a_t)
//   LOP_KERNEL_REMOVE_PLANE  U &= ~bit of level B          the unclustered kernel (the same code)
//   LOP_KERNEL_TABLES        word 3 of every cluster record = ClusterBit[c] at the new level, the
//                            plane's per-cluster bit offsets PlaneBit_p[c] (p = the new level) and
//                            BitId[k] = ClusterBit[ClusterId[k]] (BitId[24]: total bits); one work
//                            group: each thread sums a contiguous range of clusters, a scan of the
//                            partial sums in shared memory, each thread writes its range
//   LOP_KERNEL_PACK          U -> P (new level)            mirrors pack_clustered; one thread per word,
//                            each field's cluster found by binary search over ClusterBit
// A level change B -> B + 1 is: UNPACK at B; TABLES at B + 1 (PlaneBit_{B+1} is what ADD_PLANE
// reads, word 3 what PACK reads); ADD_PLANE p = B + 1; PACK at B + 1. B -> B - 1 is: UNPACK at B;
// REMOVE_PLANE B; TABLES at B - 1; PACK at B - 1. UNPACK must run before TABLES overwrites word 3.
// Extra bindings:
//   SSBO 3  LopTables gains uint lop_cluster_id[32] (ClusterId[0..24], 25..31 = 0xFFFFFFFF) after
//           lop_bit_id: 384 bytes; bytes 0..255 fill LopDecode at offset 0, bytes 256..383 at 288
//   SSBO 5  LopClusters  { uint lop_clusters[]; }    4 words per cluster (decode_bitplanes' records)
//   SSBO 6  LopPlaneBit  { uint lop_plane_bit[]; }   n_clusters + 1 words, written by TABLES
//   lop_adapt_first.y  cluster size N (16..1024);  lop_adapt_first.z  number of clusters
//   lop_adapt.y        TABLES: 1 (dispatch exactly one group); PACK: words of lop_out;
//                      ADD_PLANE: VertexId[p-1] (as unclustered); lop_adapt.z: the slice's bit offset

#ifndef LOP_LOCAL_SIZE
#define LOP_LOCAL_SIZE 64
#endif

layout(local_size_x = LOP_LOCAL_SIZE) in;

layout(std430, binding = 0) readonly buffer LopPackedIn { uint lop_in[]; };
layout(std430, binding = 1) buffer LopUnpacked { uint lop_u[]; };
layout(std430, binding = 2) readonly buffer LopPlane { uint lop_plane[]; };
layout(std430, binding = 3) buffer LopTables {
    uint lop_vertex_id[32];
    uint lop_bit_id[32];
#ifdef LOP_CLUSTERED
    uint lop_cluster_id[32];
#endif
};
layout(std430, binding = 4) writeonly buffer LopPackedOut { uint lop_out[]; };
#ifdef LOP_CLUSTERED
layout(std430, binding = 5) buffer LopClusters { uint lop_clusters[]; };
layout(std430, binding = 6) buffer LopPlaneBit { uint lop_plane_bit[]; };
#endif

layout(std140, binding = 0) uniform LopAdapt {
    uvec4 lop_adapt;
    uvec4 lop_adapt_first;
};

// Largest i in [0, 24] with table[i] <= x (table padded with 0xFFFFFFFF at 25..31): five branch-free
// steps. For VertexId it finds the bin k = i + 1 of vertex x, for BitId the bin of bit offset x.
uint lop_vertex_bin_start(uint x)
{
    uint i = 0u;
    i += (lop_vertex_id[i + 16u] <= x) ? 16u : 0u;
    i += (lop_vertex_id[i + 8u] <= x) ? 8u : 0u;
    i += (lop_vertex_id[i + 4u] <= x) ? 4u : 0u;
    i += (lop_vertex_id[i + 2u] <= x) ? 2u : 0u;
    i += (lop_vertex_id[i + 1u] <= x) ? 1u : 0u;
    return i;
}

uint lop_bit_bin_start(uint x)
{
    uint i = 0u;
    i += (lop_bit_id[i + 16u] <= x) ? 16u : 0u;
    i += (lop_bit_id[i + 8u] <= x) ? 8u : 0u;
    i += (lop_bit_id[i + 4u] <= x) ? 4u : 0u;
    i += (lop_bit_id[i + 2u] <= x) ? 2u : 0u;
    i += (lop_bit_id[i + 1u] <= x) ? 1u : 0u;
    return i;
}

uint lop_thread()
{
    return lop_adapt_first.x + gl_GlobalInvocationID.x;
}

#if defined(LOP_CLUSTERED)
// Largest i in [0, 24] with ClusterId[i] <= c: cluster c lies in bin i + 1.
uint lop_cluster_bin_start(uint c)
{
    uint i = 0u;
    i += (lop_cluster_id[i + 16u] <= c) ? 16u : 0u;
    i += (lop_cluster_id[i + 8u] <= c) ? 8u : 0u;
    i += (lop_cluster_id[i + 4u] <= c) ? 4u : 0u;
    i += (lop_cluster_id[i + 2u] <= c) ? 2u : 0u;
    i += (lop_cluster_id[i + 1u] <= c) ? 1u : 0u;
    return i;
}

// Shared prefix lengths k_t and anchors a_t of cluster c (words 0-2 of its record).
uvec3 lop_cluster_k(uint c)
{
    return uvec3(lop_clusters[4u * c], lop_clusters[4u * c + 1u], lop_clusters[4u * c + 2u]) >> 24u;
}

uvec3 lop_cluster_anchor(uint c)
{
    return uvec3(lop_clusters[4u * c], lop_clusters[4u * c + 1u], lop_clusters[4u * c + 2u]) & 0xFFFFFFu;
}

// Vertices of cluster c of bin i + 1: min(N, VertexId[i+1] - VertexId[i] - (c - ClusterId[i]) N).
uint lop_cluster_count(uint c, uint i)
{
    uint n = lop_adapt_first.y;
    return min(n, lop_vertex_id[i + 1u] - lop_vertex_id[i] - (c - lop_cluster_id[i]) * n);
}

// Vertex j -> its cluster c (returned) and local index l.
uint lop_vertex_cluster(uint j, uint i, out uint l)
{
    uint r = j - lop_vertex_id[i];
    l = r % lop_adapt_first.y;
    return lop_cluster_id[i] + r / lop_adapt_first.y;
}

#if defined(LOP_KERNEL_UNPACK)
// The w-bit field (0 <= w <= 24; 0 reads 0) at bit offset o of lop_in, least significant bit first.
uint lop_read_field(uint o, uint w)
{
    uint last = (lop_adapt.w - 1u) * 32u + 31u;
    o = min(o, last);  // a 0-bit field may sit at the end of P
    uint s = o & 31u;
    uint lo = lop_in[o >> 5u] >> s;
    uint hi = (lop_in[min((o >> 5u) + 1u, lop_adapt.w - 1u)] << 1u) << (31u - s);
    return (lo | hi) & ((1u << w) - 1u);
}

// One thread per vertex j: the clustered decode of decode_bitplanes.glsl, U[j] = v << (24 - b).
void main()
{
    uint j = lop_thread();
    if (j >= lop_adapt.y)
        return;
    uint i = lop_vertex_bin_start(j);
    uint b = max(i + 1u, lop_adapt.x);
    uint l;
    uint c = lop_vertex_cluster(j, i, l);
    uvec3 k = lop_cluster_k(c);
    uvec3 kb = min(k, b);
    uvec3 w = b - kb;
    uint o = lop_clusters[4u * c + 3u] + l * (w.x + w.y + w.z);
    uvec3 f = uvec3(lop_read_field(o, w.x), lop_read_field(o + w.x, w.y), lop_read_field(o + w.x + w.y, w.z));
    uvec3 g = (((lop_cluster_anchor(c) >> (k - kb)) << w) | f) << (24u - b);
    lop_u[3u * j] = g.x;
    lop_u[3u * j + 1u] = g.y;
    lop_u[3u * j + 2u] = g.z;
}

#elif defined(LOP_KERNEL_ADD_PLANE)
// One thread per vertex j < VertexId[p-1]: bit 24 - p of each component, from the plane for the
// components the anchor does not imply (k_t < p; they follow each other at PlaneBit_p[c] + l n_c,
// n_c = #{t : k_t < p}), from the anchor for the others.
void main()
{
    uint j = lop_thread();
    if (j >= lop_adapt.y)
        return;
    uint p = lop_adapt.x;
    uint i = lop_vertex_bin_start(j);
    uint l;
    uint c = lop_vertex_cluster(j, i, l);
    uvec3 k = lop_cluster_k(c);
    uvec3 a = lop_cluster_anchor(c);
    uint stored = (k.x < p ? 1u : 0u) + (k.y < p ? 1u : 0u) + (k.z < p ? 1u : 0u);
    uint o = lop_adapt.z + lop_plane_bit[c] + l * stored;
    for (uint t = 0u; t < 3u; ++t) {
        uint bit;
        if (k[t] < p) {
            bit = (lop_plane[o >> 5u] >> (o & 31u)) & 1u;
            o += 1u;
        } else {
            bit = (a[t] >> (k[t] - p)) & 1u;
        }
        lop_u[3u * j + t] |= bit << (24u - p);
    }
}

#elif defined(LOP_KERNEL_REMOVE_PLANE)
// As unclustered: one thread per vertex j < VertexId[B-1], zero bit 24 - B (anchor bits included:
// U holds the decoded grid integers).
void main()
{
    uint j = lop_thread();
    if (j >= lop_adapt.y)
        return;
    uint keep = ~(1u << (24u - lop_adapt.x));
    for (uint c = 0u; c < 3u; ++c)
        lop_u[3u * j + c] &= keep;
}

#elif defined(LOP_KERNEL_TABLES)
shared uint lop_scan_bits[LOP_LOCAL_SIZE];
shared uint lop_scan_plane[LOP_LOCAL_SIZE];

// Bits of cluster c at the level (count s_c) and its bits in plane p = level (0 unless m_c < p).
uvec2 lop_cluster_sizes(uint c, uint level)
{
    uint i = lop_cluster_bin_start(c);
    uint b = max(i + 1u, level);
    uvec3 k = lop_cluster_k(c);
    uvec3 w = b - min(k, b);
    uint count = lop_cluster_count(c, i);
    uint stored = (k.x < level ? 1u : 0u) + (k.y < level ? 1u : 0u) + (k.z < level ? 1u : 0u);
    return uvec2(count * (w.x + w.y + w.z), (i + 1u < level) ? count * stored : 0u);
}

// One work group of LOP_LOCAL_SIZE threads; thread t owns clusters [t chunk, (t + 1) chunk).
void main()
{
    uint t = gl_LocalInvocationID.x;
    uint level = lop_adapt.x;
    uint nc = lop_adapt_first.z;
    uint chunk = (nc + uint(LOP_LOCAL_SIZE) - 1u) / uint(LOP_LOCAL_SIZE);
    uint start = min(t * chunk, nc);
    uint end = min(start + chunk, nc);
    uvec2 acc = uvec2(0u);
    for (uint c = start; c < end; ++c)
        acc += lop_cluster_sizes(c, level);
    lop_scan_bits[t] = acc.x;
    lop_scan_plane[t] = acc.y;
    memoryBarrierShared();
    barrier();
    if (t == 0u) {  // exclusive scan of the partial sums
        uvec2 run = uvec2(0u);
        for (uint u = 0u; u < uint(LOP_LOCAL_SIZE); ++u) {
            uvec2 x = uvec2(lop_scan_bits[u], lop_scan_plane[u]);
            lop_scan_bits[u] = run.x;
            lop_scan_plane[u] = run.y;
            run += x;
        }
    }
    memoryBarrierShared();
    barrier();
    acc = uvec2(lop_scan_bits[t], lop_scan_plane[t]);
    uint kk = 0u;  // BitId[kk] = ClusterBit[ClusterId[kk]]: written by the thread that owns that cluster
    while (kk <= 24u && lop_cluster_id[kk] < start)
        ++kk;
    for (uint c = start; c < end; ++c) {
        while (kk <= 24u && lop_cluster_id[kk] == c) {
            lop_bit_id[kk] = acc.x;
            ++kk;
        }
        lop_clusters[4u * c + 3u] = acc.x;
        lop_plane_bit[c] = acc.y;
        acc += lop_cluster_sizes(c, level);
    }
    if (t == uint(LOP_LOCAL_SIZE) - 1u) {  // its range ends at nc: the totals
        while (kk <= 24u) {
            lop_bit_id[kk] = acc.x;
            ++kk;
        }
        lop_plane_bit[nc] = acc.y;
    }
    if (t == 0u) {
        for (uint e = 25u; e < 32u; ++e) {
            lop_vertex_id[e] = 0xFFFFFFFFu;
            lop_bit_id[e] = 0xFFFFFFFFu;
        }
    }
}

#elif defined(LOP_KERNEL_PACK)
// Largest cluster c < n_clusters with ClusterBit[c] <= o (ClusterBit[0] = 0): the cluster holding
// bit o < total bits (clusters of 0 bits share their successor's offset and are skipped).
uint lop_cluster_at(uint o)
{
    uint lo = 0u;
    uint hi = lop_adapt_first.z;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) >> 1u;
        if (lop_clusters[4u * mid + 3u] <= o)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

// One thread per word w of the new P: walk the fields overlapping bits [32 w, 32 w + 32): each
// field's cluster by binary search, its vertex l and component t inside the cluster's run of
// s_c-bit vertices, then its low w_t bits from U. Bits past BitId[24] (the total) stay zero.
void main()
{
    uint w = lop_thread();
    if (w >= lop_adapt.y)
        return;
    uint level = lop_adapt.x;
    uint o = w << 5u;
    uint end = min(o + 32u, lop_bit_id[24]);
    uint word = 0u;
    while (o < end) {
        uint c = lop_cluster_at(o);
        uint i = lop_cluster_bin_start(c);
        uint b = max(i + 1u, level);
        uvec3 wd = b - min(lop_cluster_k(c), b);
        uint local = o - lop_clusters[4u * c + 3u];
        uint l = local / (wd.x + wd.y + wd.z);
        uint bit = local - l * (wd.x + wd.y + wd.z);
        uint t = (bit < wd.x) ? 0u : ((bit < wd.x + wd.y) ? 1u : 2u);
        bit -= (t == 0u) ? 0u : ((t == 1u) ? wd.x : wd.x + wd.y);
        uint vertex = lop_vertex_id[i] + (c - lop_cluster_id[i]) * lop_adapt_first.y + l;
        uint v = lop_u[3u * vertex + t] >> (24u - b);
        uint take = min(wd[t] - bit, end - o);
        word |= ((v >> bit) & ((1u << take) - 1u)) << (o & 31u);
        o += take;
    }
    lop_out[w] = word;
}

#else
#error "define one of LOP_KERNEL_UNPACK, LOP_KERNEL_ADD_PLANE, LOP_KERNEL_REMOVE_PLANE, LOP_KERNEL_TABLES, LOP_KERNEL_PACK"
#endif

#elif defined(LOP_KERNEL_UNPACK)
// One thread per vertex j: gather its 3 b bits from P (as decode_bitplanes.glsl's lop_read_field).
uint lop_read_field(uint o, uint b)
{
    uint w = o >> 5u;
    uint s = o & 31u;
    uint lo = lop_in[w] >> s;
    uint hi = (lop_in[min(w + 1u, lop_adapt.w - 1u)] << 1u) << (31u - s);
    return (lo | hi) & ((1u << b) - 1u);
}

void main()
{
    uint j = lop_thread();
    if (j >= lop_adapt.y)
        return;
    uint i = lop_vertex_bin_start(j);
    uint b = max(i + 1u, lop_adapt.x);
    uint o = 3u * b * (j - lop_vertex_id[i]) + lop_bit_id[i];
    for (uint c = 0u; c < 3u; ++c)
        lop_u[3u * j + c] = lop_read_field(o + c * b, b) << (24u - b);
}

#elif defined(LOP_KERNEL_ADD_PLANE)
// One thread per vertex j < VertexId[p-1] (the vertices whose width grows): merge bit 24 - p.
void main()
{
    uint j = lop_thread();
    if (j >= lop_adapt.y)
        return;
    uint p = lop_adapt.x;
    for (uint c = 0u; c < 3u; ++c) {
        uint o = lop_adapt.z + 3u * j + c;
        uint bit = (lop_plane[o >> 5u] >> (o & 31u)) & 1u;
        lop_u[3u * j + c] |= bit << (24u - p);
    }
}

#elif defined(LOP_KERNEL_REMOVE_PLANE)
// One thread per vertex j < VertexId[B-1] (bins below B lose their lowest bit; bins at their minimum
// level keep it): zero bit 24 - B.
void main()
{
    uint j = lop_thread();
    if (j >= lop_adapt.y)
        return;
    uint keep = ~(1u << (24u - lop_adapt.x));
    for (uint c = 0u; c < 3u; ++c)
        lop_u[3u * j + c] &= keep;
}

#elif defined(LOP_KERNEL_TABLES)
// One thread: BitId[k] = sum_{i<=k} 3 max(i, B) (VertexId[i] - VertexId[i-1]); pads entries 25..31
// of both tables with 0xFFFFFFFF (the binary searches rely on it).
void main()
{
    if (lop_thread() != 0u)
        return;
    uint level = lop_adapt.x;
    uint acc = 0u;
    lop_bit_id[0] = 0u;
    for (uint k = 1u; k <= 24u; ++k) {
        acc += 3u * max(k, level) * (lop_vertex_id[k] - lop_vertex_id[k - 1u]);
        lop_bit_id[k] = acc;
    }
    for (uint k = 25u; k < 32u; ++k) {
        lop_vertex_id[k] = 0xFFFFFFFFu;
        lop_bit_id[k] = 0xFFFFFFFFu;
    }
}

#elif defined(LOP_KERNEL_PACK)
// One thread per word w of the new P: walk the fields overlapping bits [32 w, 32 w + 32), find each
// field's bin by BitId, its vertex and component, and gather its bits (paper Fig. 11b). Bits past
// BitId[24] stay zero.
void main()
{
    uint w = lop_thread();
    if (w >= lop_adapt.y)
        return;
    uint level = lop_adapt.x;
    uint o = w << 5u;
    uint end = min(o + 32u, lop_bit_id[24]);
    uint word = 0u;
    while (o < end) {
        uint i = lop_bit_bin_start(o);
        uint b = max(i + 1u, level);
        uint local = o - lop_bit_id[i];
        uint field = local / b;
        uint vertex = lop_vertex_id[i] + field / 3u;
        uint c = field - 3u * (field / 3u);
        uint bit = local - field * b;
        uint v = lop_u[3u * vertex + c] >> (24u - b);
        uint take = min(b - bit, end - o);
        word |= ((v >> bit) & ((1u << take) - 1u)) << (o & 31u);
        o += take;
    }
    lop_out[w] = word;
}

#else
#error "define one of LOP_KERNEL_UNPACK, LOP_KERNEL_ADD_PLANE, LOP_KERNEL_REMOVE_PLANE, LOP_KERNEL_TABLES, LOP_KERNEL_PACK"
#endif
