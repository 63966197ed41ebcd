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
//   LOP_KERNEL_ADD_PLANE     U |= plane p (B -> B + 1)     mirrors lopcook.emit.bitplane.add_plane
//   LOP_KERNEL_REMOVE_PLANE  U &= ~bit of level B (B -> B - 1)   mirrors lopcook.emit.bitplane.remove_plane
//   LOP_KERNEL_TABLES        BitId for the new level       mirrors lopcook.emit.binning.table_bit_id
//   LOP_KERNEL_PACK          U -> P (new level)            mirrors lopcook.emit.bitplane.pack
// A level change B -> B' is: UNPACK at B; ADD_PLANE p = B+1 .. B' (or REMOVE_PLANE B .. B'+1), one
// dispatch per plane; TABLES at B'; PACK at B' into a buffer of ceil(BitId'[24] / 32) words. The
// result is byte-identical to packing level B' from scratch on the CPU (tests/test_gpu_decoders.py).
// VertexId never changes (VertexId[k] = vertices with minimum level <= k); BitId is rewritten on the
// GPU by LOP_KERNEL_TABLES, so no read-back is needed. The CPU only sizes the new P
// (lopcook.emit.binning.buffer_bytes: a 25-term sum over VertexId it already holds).
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
};
layout(std430, binding = 4) writeonly buffer LopPackedOut { uint lop_out[]; };

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

#if defined(LOP_KERNEL_UNPACK)
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
