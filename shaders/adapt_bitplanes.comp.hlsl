// adapt_bitplanes.comp.hlsl: data-parallel precision adaption of binned adaptive precision buffers
// (HLSL compute shaders, SM 5.0+).
//
// This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
// section 6.1 and Figures 10-11. Line-for-line the same kernels as adapt_bitplanes.comp.glsl
// (read its header for the protocol); here each kernel is its own entry point:
//   lop_unpack_cs        P (level B) -> U              mirrors to_grid(decode(P, VertexId, BitId, B))
//   lop_add_plane_cs     U |= plane p (B -> B + 1)     mirrors lopcook.emit.bitplane.add_plane
//   lop_remove_plane_cs  U &= ~bit of level B          mirrors lopcook.emit.bitplane.remove_plane
//   lop_tables_cs        BitId for the new level       mirrors lopcook.emit.binning.table_bit_id
//   lop_pack_cs          U -> P (new level)            mirrors lopcook.emit.bitplane.pack
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

ByteAddressBuffer lop_in : register(t0);
RWByteAddressBuffer lop_u : register(u1);
ByteAddressBuffer lop_plane : register(t2);
RWByteAddressBuffer lop_tables : register(u3);
RWByteAddressBuffer lop_out : register(u4);

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
