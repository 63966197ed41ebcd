// adapt_bitplanes.comp.hlsl: data-parallel precision adaption of binned adaptive precision buffers
// (HLSL compute shaders, SM 5.0+).
//
// This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
// section 6.1 and Figures 10-11. Line-for-line the same kernels as adapt_bitplanes.comp.glsl
// (read its header for the protocol); here each kernel is its own entry point:
//   lop_unpack_cs        P (level B) -> U              mirrors to_grid(decode(P, VertexId, BitId, B))
//   lop_add_plane_cs     U |= plane p (B -> B + 1)     mirrors lopcook.lop.bitplane.add_plane
//   lop_remove_plane_cs  U &= ~bit of level B          mirrors lopcook.lop.bitplane.remove_plane
//   lop_tables_cs        BitId for the new level       mirrors lopcook.lop.binning.table_bit_id
//   lop_pack_cs          U -> P (new level)            mirrors lopcook.lop.bitplane.pack
// BitId is rewritten on the GPU (lop_tables_cs); VertexId never changes.
//
// Bindings (register numbers are unique across t/u so that glslang's default mapping, and any
// Vulkan/OpenGL port, gets distinct storage-buffer bindings 0..4):
//   ByteAddressBuffer   lop_in     : register(t0)   P at level B (read by lop_unpack_cs)
//   RWByteAddressBuffer lop_u      : register(u1)   U: 3 uint32 per vertex, 24-bit grid integers,
//                                                   bits below the vertex's width zero
//   ByteAddressBuffer   lop_plane  : register(t2)   plane p: bit (offset + 3 j + c) = bit 24 - p of
//                                                   component c of vertex j < VertexId[p-1]
//   RWByteAddressBuffer lop_tables : register(u3)   uint VertexId[32] then uint BitId[32] (256 bytes,
//                                                   = the first 256 bytes of cbuffer LopDecode)
//   RWByteAddressBuffer lop_out    : register(u4)   P at the new level (written by lop_pack_cs)
//   cbuffer LopAdapt : register(b0)  { uint4 lop_adapt; uint4 lop_adapt_first; }  (32 bytes; fields
//                                      as in adapt_bitplanes.comp.glsl)
// [numthreads(64, 1, 1)]; dispatch ceil(threads / 64) groups (at most 65535 per dispatch: use
// lop_adapt_first.x to split).
//
// Clustered buffers (#define LOP_CLUSTERED; the protocol in adapt_bitplanes.comp.glsl): the same
// entry points run the clustered kernels, with
//   lop_tables                          gains ClusterId[32] at byte 256 (384 bytes)
//   RWByteAddressBuffer lop_clusters    : register(u5)   4 uint32 per cluster (word 3 rewritten by
//                                                        lop_tables_cs)
//   RWByteAddressBuffer lop_plane_bit   : register(u6)   PlaneBit_p, n_clusters + 1 uint32
//   lop_adapt_first.y = cluster size N, lop_adapt_first.z = number of clusters; lop_tables_cs
//   runs as one group of 64 threads.

ByteAddressBuffer lop_in : register(t0);
RWByteAddressBuffer lop_u : register(u1);
ByteAddressBuffer lop_plane : register(t2);
RWByteAddressBuffer lop_tables : register(u3);
RWByteAddressBuffer lop_out : register(u4);
#ifdef LOP_CLUSTERED
RWByteAddressBuffer lop_clusters : register(u5);
RWByteAddressBuffer lop_plane_bit : register(u6);
#endif

cbuffer LopAdapt : register(b0)
{
    uint4 lop_adapt;
    uint4 lop_adapt_first;
};

uint lop_vertex_id(uint i) { return lop_tables.Load(i << 2); }
uint lop_bit_id(uint i) { return lop_tables.Load(128u + (i << 2)); }

// Largest i in [0, 24] with table[i] <= x (tables padded with 0xFFFFFFFF at 25..31): five
// branch-free steps.
uint lop_vertex_bin_start(uint x)
{
    uint i = 0u;
    i += (lop_vertex_id(i + 16u) <= x) ? 16u : 0u;
    i += (lop_vertex_id(i + 8u) <= x) ? 8u : 0u;
    i += (lop_vertex_id(i + 4u) <= x) ? 4u : 0u;
    i += (lop_vertex_id(i + 2u) <= x) ? 2u : 0u;
    i += (lop_vertex_id(i + 1u) <= x) ? 1u : 0u;
    return i;
}

uint lop_bit_bin_start(uint x)
{
    uint i = 0u;
    i += (lop_bit_id(i + 16u) <= x) ? 16u : 0u;
    i += (lop_bit_id(i + 8u) <= x) ? 8u : 0u;
    i += (lop_bit_id(i + 4u) <= x) ? 4u : 0u;
    i += (lop_bit_id(i + 2u) <= x) ? 2u : 0u;
    i += (lop_bit_id(i + 1u) <= x) ? 1u : 0u;
    return i;
}

#ifdef LOP_CLUSTERED
uint lop_cluster_id(uint i) { return lop_tables.Load(256u + (i << 2)); }
uint lop_cluster_word(uint c, uint t) { return lop_clusters.Load((4u * c + t) << 2); }

// Largest i in [0, 24] with ClusterId[i] <= c: cluster c lies in bin i + 1.
uint lop_cluster_bin_start(uint c)
{
    uint i = 0u;
    i += (lop_cluster_id(i + 16u) <= c) ? 16u : 0u;
    i += (lop_cluster_id(i + 8u) <= c) ? 8u : 0u;
    i += (lop_cluster_id(i + 4u) <= c) ? 4u : 0u;
    i += (lop_cluster_id(i + 2u) <= c) ? 2u : 0u;
    i += (lop_cluster_id(i + 1u) <= c) ? 1u : 0u;
    return i;
}

uint3 lop_cluster_k(uint c)
{
    return uint3(lop_cluster_word(c, 0u), lop_cluster_word(c, 1u), lop_cluster_word(c, 2u)) >> 24u;
}

uint3 lop_cluster_anchor(uint c)
{
    return uint3(lop_cluster_word(c, 0u), lop_cluster_word(c, 1u), lop_cluster_word(c, 2u)) & 0xFFFFFFu;
}

uint lop_cluster_count(uint c, uint i)
{
    uint n = lop_adapt_first.y;
    return min(n, lop_vertex_id(i + 1u) - lop_vertex_id(i) - (c - lop_cluster_id(i)) * n);
}

uint lop_vertex_cluster(uint j, uint i, out uint l)
{
    uint r = j - lop_vertex_id(i);
    l = r % lop_adapt_first.y;
    return lop_cluster_id(i) + r / lop_adapt_first.y;
}

// The w-bit field (0 <= w <= 24; 0 reads 0) at bit offset o of lop_in (offset clamped to P).
uint lop_read_field(uint o, uint w)
{
    uint last = (lop_adapt.w - 1u) * 32u + 31u;
    o = min(o, last);
    uint s = o & 31u;
    uint lo = lop_in.Load((o >> 5u) << 2) >> s;
    uint hi = (lop_in.Load(min((o >> 5u) + 1u, lop_adapt.w - 1u) << 2) << 1u) << (31u - s);
    return (lo | hi) & ((1u << w) - 1u);
}

// One thread per vertex j: the clustered decode, U[j] = v << (24 - b).
[numthreads(64, 1, 1)]
void lop_unpack_cs(uint3 id : SV_DispatchThreadID)
{
    uint j = lop_adapt_first.x + id.x;
    if (j >= lop_adapt.y)
        return;
    uint i = lop_vertex_bin_start(j);
    uint b = max(i + 1u, lop_adapt.x);
    uint l;
    uint c = lop_vertex_cluster(j, i, l);
    uint3 k = lop_cluster_k(c);
    uint3 kb = min(k, b);
    uint3 w = b - kb;
    uint o = lop_cluster_word(c, 3u) + l * (w.x + w.y + w.z);
    uint3 f = uint3(lop_read_field(o, w.x), lop_read_field(o + w.x, w.y), lop_read_field(o + w.x + w.y, w.z));
    uint3 g = (((lop_cluster_anchor(c) >> (k - kb)) << w) | f) << (24u - b);
    lop_u.Store((3u * j) << 2, g.x);
    lop_u.Store((3u * j + 1u) << 2, g.y);
    lop_u.Store((3u * j + 2u) << 2, g.z);
}

// One thread per vertex j < VertexId[p-1]: bit 24 - p from the plane where k_t < p, else from the anchor.
[numthreads(64, 1, 1)]
void lop_add_plane_cs(uint3 id : SV_DispatchThreadID)
{
    uint j = lop_adapt_first.x + id.x;
    if (j >= lop_adapt.y)
        return;
    uint p = lop_adapt.x;
    uint i = lop_vertex_bin_start(j);
    uint l;
    uint c = lop_vertex_cluster(j, i, l);
    uint3 k = lop_cluster_k(c);
    uint3 a = lop_cluster_anchor(c);
    uint stored = (k.x < p ? 1u : 0u) + (k.y < p ? 1u : 0u) + (k.z < p ? 1u : 0u);
    uint o = lop_adapt.z + lop_plane_bit.Load(c << 2) + l * stored;
    [unroll] for (uint t = 0u; t < 3u; ++t) {
        uint bit;
        if (k[t] < p) {
            bit = (lop_plane.Load((o >> 5u) << 2) >> (o & 31u)) & 1u;
            o += 1u;
        } else {
            bit = (a[t] >> (k[t] - p)) & 1u;
        }
        uint addr = (3u * j + t) << 2;
        lop_u.Store(addr, lop_u.Load(addr) | (bit << (24u - p)));
    }
}

// As unclustered: zero bit 24 - B of the vertices j < VertexId[B-1].
[numthreads(64, 1, 1)]
void lop_remove_plane_cs(uint3 id : SV_DispatchThreadID)
{
    uint j = lop_adapt_first.x + id.x;
    if (j >= lop_adapt.y)
        return;
    uint keep = ~(1u << (24u - lop_adapt.x));
    [unroll] for (uint c = 0u; c < 3u; ++c) {
        uint a = (3u * j + c) << 2;
        lop_u.Store(a, lop_u.Load(a) & keep);
    }
}

groupshared uint lop_scan_bits[64];
groupshared uint lop_scan_plane[64];

// Bits of cluster c at the level and its bits in plane p = level (0 unless m_c < p).
uint2 lop_cluster_sizes(uint c, uint level)
{
    uint i = lop_cluster_bin_start(c);
    uint b = max(i + 1u, level);
    uint3 k = lop_cluster_k(c);
    uint3 w = b - min(k, b);
    uint count = lop_cluster_count(c, i);
    uint stored = (k.x < level ? 1u : 0u) + (k.y < level ? 1u : 0u) + (k.z < level ? 1u : 0u);
    return uint2(count * (w.x + w.y + w.z), (i + 1u < level) ? count * stored : 0u);
}

// One group of 64 threads: ClusterBit (word 3), PlaneBit_level and BitId[k] = ClusterBit[ClusterId[k]].
[numthreads(64, 1, 1)]
void lop_tables_cs(uint3 gid : SV_GroupThreadID)
{
    uint t = gid.x;
    uint level = lop_adapt.x;
    uint nc = lop_adapt_first.z;
    uint chunk = (nc + 63u) / 64u;
    uint start = min(t * chunk, nc);
    uint end = min(start + chunk, nc);
    uint2 acc = uint2(0u, 0u);
    [loop] for (uint c = start; c < end; ++c)
        acc += lop_cluster_sizes(c, level);
    lop_scan_bits[t] = acc.x;
    lop_scan_plane[t] = acc.y;
    GroupMemoryBarrierWithGroupSync();
    if (t == 0u) {
        uint2 run = uint2(0u, 0u);
        for (uint u = 0u; u < 64u; ++u) {
            uint2 x = uint2(lop_scan_bits[u], lop_scan_plane[u]);
            lop_scan_bits[u] = run.x;
            lop_scan_plane[u] = run.y;
            run += x;
        }
    }
    GroupMemoryBarrierWithGroupSync();
    acc = uint2(lop_scan_bits[t], lop_scan_plane[t]);
    uint kk = 0u;
    [loop] while (kk <= 24u && lop_cluster_id(kk) < start)
        ++kk;
    [loop] for (uint c2 = start; c2 < end; ++c2) {
        [loop] while (kk <= 24u && lop_cluster_id(kk) == c2) {
            lop_tables.Store(128u + (kk << 2), acc.x);
            ++kk;
        }
        lop_clusters.Store((4u * c2 + 3u) << 2, acc.x);
        lop_plane_bit.Store(c2 << 2, acc.y);
        acc += lop_cluster_sizes(c2, level);
    }
    if (t == 63u) {
        [loop] while (kk <= 24u) {
            lop_tables.Store(128u + (kk << 2), acc.x);
            ++kk;
        }
        lop_plane_bit.Store(nc << 2, acc.y);
    }
    if (t == 0u) {
        for (uint e = 25u; e < 32u; ++e) {
            lop_tables.Store(e << 2, 0xFFFFFFFFu);
            lop_tables.Store(128u + (e << 2), 0xFFFFFFFFu);
        }
    }
}

// Largest cluster c < n_clusters with ClusterBit[c] <= o.
uint lop_cluster_at(uint o)
{
    uint lo = 0u;
    uint hi = lop_adapt_first.z;
    [loop] while (hi - lo > 1u) {
        uint mid = (lo + hi) >> 1u;
        if (lop_cluster_word(mid, 3u) <= o)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

// One thread per word w of the new P: each field's cluster by binary search, then its bits from U.
[numthreads(64, 1, 1)]
void lop_pack_cs(uint3 id : SV_DispatchThreadID)
{
    uint w = lop_adapt_first.x + id.x;
    if (w >= lop_adapt.y)
        return;
    uint level = lop_adapt.x;
    uint o = w << 5u;
    uint end = min(o + 32u, lop_bit_id(24u));
    uint word = 0u;
    [loop] while (o < end) {
        uint c = lop_cluster_at(o);
        uint i = lop_cluster_bin_start(c);
        uint b = max(i + 1u, level);
        uint3 wd = b - min(lop_cluster_k(c), b);
        uint local = o - lop_cluster_word(c, 3u);
        uint l = local / (wd.x + wd.y + wd.z);
        uint bit = local - l * (wd.x + wd.y + wd.z);
        uint t = (bit < wd.x) ? 0u : ((bit < wd.x + wd.y) ? 1u : 2u);
        bit -= (t == 0u) ? 0u : ((t == 1u) ? wd.x : wd.x + wd.y);
        uint vertex = lop_vertex_id(i) + (c - lop_cluster_id(i)) * lop_adapt_first.y + l;
        uint v = lop_u.Load((3u * vertex + t) << 2) >> (24u - b);
        uint take = min(wd[t] - bit, end - o);
        word |= ((v >> bit) & ((1u << take) - 1u)) << (o & 31u);
        o += take;
    }
    lop_out.Store(w << 2, word);
}

#else
uint lop_read_field(uint o, uint b)
{
    uint w = o >> 5u;
    uint s = o & 31u;
    uint lo = lop_in.Load(w << 2) >> s;
    uint hi = (lop_in.Load(min(w + 1u, lop_adapt.w - 1u) << 2) << 1u) << (31u - s);
    return (lo | hi) & ((1u << b) - 1u);
}

// One thread per vertex j: U[j] = its decoded grid integers (dropped bits zero).
[numthreads(64, 1, 1)]
void lop_unpack_cs(uint3 id : SV_DispatchThreadID)
{
    uint j = lop_adapt_first.x + id.x;
    if (j >= lop_adapt.y)
        return;
    uint i = lop_vertex_bin_start(j);
    uint b = max(i + 1u, lop_adapt.x);
    uint o = 3u * b * (j - lop_vertex_id(i)) + lop_bit_id(i);
    [unroll] for (uint c = 0u; c < 3u; ++c)
        lop_u.Store((3u * j + c) << 2, lop_read_field(o + c * b, b) << (24u - b));
}

// One thread per vertex j < VertexId[p-1]: merge bit 24 - p from the uploaded plane.
[numthreads(64, 1, 1)]
void lop_add_plane_cs(uint3 id : SV_DispatchThreadID)
{
    uint j = lop_adapt_first.x + id.x;
    if (j >= lop_adapt.y)
        return;
    uint p = lop_adapt.x;
    [unroll] for (uint c = 0u; c < 3u; ++c) {
        uint o = lop_adapt.z + 3u * j + c;
        uint bit = (lop_plane.Load((o >> 5u) << 2) >> (o & 31u)) & 1u;
        uint a = (3u * j + c) << 2;
        lop_u.Store(a, lop_u.Load(a) | (bit << (24u - p)));
    }
}

// One thread per vertex j < VertexId[B-1]: zero bit 24 - B (bins at their minimum level keep it).
[numthreads(64, 1, 1)]
void lop_remove_plane_cs(uint3 id : SV_DispatchThreadID)
{
    uint j = lop_adapt_first.x + id.x;
    if (j >= lop_adapt.y)
        return;
    uint keep = ~(1u << (24u - lop_adapt.x));
    [unroll] for (uint c = 0u; c < 3u; ++c) {
        uint a = (3u * j + c) << 2;
        lop_u.Store(a, lop_u.Load(a) & keep);
    }
}

// One thread: BitId for the new level; pads entries 25..31 of both tables with 0xFFFFFFFF.
[numthreads(64, 1, 1)]
void lop_tables_cs(uint3 id : SV_DispatchThreadID)
{
    if (lop_adapt_first.x + id.x != 0u)
        return;
    uint level = lop_adapt.x;
    uint acc = 0u;
    lop_tables.Store(128u, 0u);
    for (uint k = 1u; k <= 24u; ++k) {
        acc += 3u * max(k, level) * (lop_vertex_id(k) - lop_vertex_id(k - 1u));
        lop_tables.Store(128u + (k << 2), acc);
    }
    for (uint p = 25u; p < 32u; ++p) {
        lop_tables.Store(p << 2, 0xFFFFFFFFu);
        lop_tables.Store(128u + (p << 2), 0xFFFFFFFFu);
    }
}

// One thread per word w of the new P: gather the fields overlapping bits [32 w, 32 w + 32).
[numthreads(64, 1, 1)]
void lop_pack_cs(uint3 id : SV_DispatchThreadID)
{
    uint w = lop_adapt_first.x + id.x;
    if (w >= lop_adapt.y)
        return;
    uint level = lop_adapt.x;
    uint o = w << 5u;
    uint end = min(o + 32u, lop_bit_id(24u));
    uint word = 0u;
    [loop] while (o < end) {
        uint i = lop_bit_bin_start(o);
        uint b = max(i + 1u, level);
        uint local = o - lop_bit_id(i);
        uint field = local / b;
        uint vertex = lop_vertex_id(i) + field / 3u;
        uint c = field - 3u * (field / 3u);
        uint bit = local - field * b;
        uint v = lop_u.Load((3u * vertex + c) << 2) >> (24u - b);
        uint take = min(b - bit, end - o);
        word |= ((v >> bit) & ((1u << take) - 1u)) << (o & 31u);
        o += take;
    }
    lop_out.Store(w << 2, word);
}
#endif  // LOP_CLUSTERED
