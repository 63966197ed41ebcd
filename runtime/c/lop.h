/* lop.h - a single-header C99 reader for lopcook's .lop containers (versions 2.x, 3.x, 4.x).

   Licence: MIT (as lopcook). Specification: docs/format.md of lopcook; this header is its C
   reference reader (docs/runtime-c.md: integration, API reference, guarantees on untrusted input,
   uniform blocks and shader bindings).

   USAGE
     In exactly one C or C++ file:
         #define LOP_IMPLEMENTATION
         #include "lop.h"
     Everywhere else include "lop.h" for the declarations.

         lop_file *f = NULL;
         lop_message msg;
         lop_result r = lop_open(bytes, size, NULL, &f, &msg);    bytes outlive f
         if (r != lop_success) { fprintf(stderr, "%s: %s\n", lop_result_name(r), msg.text); ... }
         lop_buffer_info info;
         lop_buffer(f, part, lod, level, LOP_LAYOUT_NATIVE, &info);  sizes of P, records, block
         lop_build(f, part, lod, level, LOP_LAYOUT_NATIVE, words, info.words, records, 4 * info.clusters);
         lop_decode_block(f, part, lod, level, LOP_LAYOUT_NATIVE, ubo, sizeof ubo);  the shader's UBO
         ...
         lop_close(f);

   WHAT IT DOES
     * opens a whole file, or a prefix of one (options.allow_prefix; docs/format.md section 8),
       from memory and runs every check of docs/format.md section 12 (header and CRCs, a bounded
       strict JSON parser for the manifest, the manifest's structure and semantics, section CRCs,
       index values, cluster headers, plane sizes);
     * answers queries: parts, LODs, placements and transforms, levels, attribute bits, errors,
       and the LOD and level a camera distance selects (section 9);
     * builds, for a buffer (a part's LOD) and a level B, the packed buffer P, the cluster records
       and the uniform-block bytes that shaders/decode_bitplanes.glsl and decode_attributes.glsl
       read, so an engine uploads them as they are;
     * decodes on the CPU: positions (float32, bit-identical to lopcook's reader), the attribute
       record (normals, UVs, colours, tangents) and indices.

   GUARANTEES (docs/runtime-c.md)
     * Safe on untrusted input: every function returns a result code; no input makes it read
       outside the bytes it was given, write outside the caller's buffers, abort, or allocate more
       than a bounded multiple of the manifest's size. Fuzzed (runtime/c/fuzz) and run under
       AddressSanitizer and UndefinedBehaviorSanitizer over lopcook's hostile-input corpus.
     * No global state; all memory through the caller's allocator (default malloc/free).
       A lop_file is read-only after lop_open: any number of threads may decode from it at once.
     * Decoded floats are bit-identical to lopcook's: IEEE float32 operations in the documented
       order, no fused multiply-add (the implementation turns contraction off for itself), which
       needs FLT_EVAL_METHOD == 0 (SSE2 or any non-x87 target).

   CONFIGURATION (define before including the implementation)
     LOP_STATIC             make every function static (private to one translation unit)
     LOP_JSON_MAX_DEPTH     manifest nesting limit (default 64)
     LOP_JSON_MAX_STRING    longest decoded JSON string, bytes (default 65536)
     LOP_JSON_MAX_NUMBER    longest JSON number, characters (default 800)
     LOP_JSON_MAX_ITEMS     most elements of one JSON array or object (default 16777216)
     LOP_ALLOW_EXCESS_PRECISION  compile even where FLT_EVAL_METHOD != 0 (decodes then may differ
                            from lopcook's in the last bit)
*/
#ifndef LOP_H_INCLUDED
#define LOP_H_INCLUDED

#include <stddef.h>
#include <stdint.h>

#ifndef LOPDEF
#ifdef LOP_STATIC
#if defined(__GNUC__) || defined(__clang__)
#define LOPDEF static __attribute__((unused)) /* a translation unit may use some of the API only */
#else
#define LOPDEF static
#endif
#else
#define LOPDEF extern
#endif
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define LOP_LEVELS 24                 /* bits per grid component, levels 1..24 */
#define LOP_DECODE_BLOCK_SIZE 288     /* LopDecode uniform block, bytes (unclustered, AP) */
#define LOP_CLUSTERED_BLOCK_SIZE 416  /* LopDecode with LOP_CLUSTERED */
#define LOP_ATTRIBUTE_BLOCK_SIZE 64   /* LopAttributeDecode */
#define LOP_VIEW_BLOCK_SIZE 272       /* LopView (per frame, crack-free levels) */

/* Result codes. The file errors are the error classes of docs/format.md section 12 (and of
   fixtures/conformance/): every conforming reader reports the same class for the same file. */
typedef enum lop_result {
    lop_success = 0,
    lop_error_truncated,       /* shorter than its header, manifest or file_size (or no mandatory bits in a prefix) */
    lop_error_bad_magic,       /* not "LOPC" */
    lop_error_header_crc,      /* header CRC-32 mismatch */
    lop_error_version,         /* unknown major, or a feature its version does not allow */
    lop_error_header,          /* header_size is not 32 */
    lop_error_trailing_data,   /* longer than file_size */
    lop_error_manifest_crc,    /* manifest CRC-32 mismatch */
    lop_error_manifest_json,   /* not ASCII JSON, NaN/Infinity, duplicate keys, beyond a parser bound */
    lop_error_manifest,        /* a field is missing, of the wrong type or inconsistent */
    lop_error_section_table,   /* sections not back to back, misaligned, duplicated, or not ending at file_size */
    lop_error_section_crc,     /* a section's CRC-32 mismatch */
    lop_error_indices,         /* an index is not below its buffer's vertex count */
    lop_error_clusters,        /* cluster headers, cluster word counts or clustered plane sizes wrong */
    lop_error_level,           /* request: level outside 1..24 or above the available level */
    lop_error_argument,        /* request: part/LOD out of range, a buffer too small, a NULL pointer */
    lop_error_limit,           /* request: the buffer is too large for the shaders' 32-bit tables */
    lop_error_out_of_memory,   /* the allocator returned NULL */
    lop_error_encoding         /* an encoded manifest or section that does not decode (format.md 15; 4.x) */
} lop_result;

/* How a section is stored (format.md 15): as it is, or encoded on the wire (4.x files). */
typedef enum lop_encoding { LOP_ENCODING_NONE = 0, LOP_ENCODING_DEFLATE = 1, LOP_ENCODING_MESHOPT = 2 } lop_encoding;

typedef struct lop_allocator {
    void *(*alloc)(void *user, size_t size); /* NULL: malloc */
    void (*free)(void *user, void *ptr);     /* NULL: free */
    void *user;
} lop_allocator;

typedef struct lop_options {
    lop_allocator memory;
    int allow_prefix; /* nonzero: accept a prefix of a file; lop_file.available_level tells its level */
} lop_options;

/* One line saying what is wrong (filled by lop_open on failure; may be passed as NULL). */
typedef struct lop_message {
    char text[256];
} lop_message;

typedef struct lop_section {
    const char *name;    /* NUL-terminated copy of the manifest's name */
    uint64_t offset;     /* bytes from the end of the manifest */
    uint64_t length;     /* stored bytes, padding included (multiple of 4): what crc32 covers */
    uint32_t crc32;
    lop_encoding encoding; /* LOP_ENCODING_NONE, or how the stored bytes are encoded */
    uint64_t size;       /* decoded bytes (multiple of 4): what data holds; = length when not encoded */
    const uint8_t *data; /* the decoded bytes: into the caller's bytes, or (encoded) a block lop_close frees;
                            NULL when a prefix ends before the section */
} lop_section;

/* One buffer: a part's level of detail (docs/format.md section 4, "A LOD"). Vertices are in
   binned (or cluster) order; every per-vertex array this header decodes uses that order. */
typedef struct lop_lod {
    uint32_t vertices, triangles;
    uint32_t vertex_id[LOP_LEVELS + 1];   /* VertexId[k] = vertices of minimum level <= k */
    uint32_t index_width;                 /* bytes per index: 2 or 4 */
    int32_t indices_section;              /* index into lop_file.sections */
    int32_t attributes_section;           /* -1 when record_bits is 0 */
    uint64_t mandatory_offset;            /* uint32 words into positions/mandatory */
    uint64_t mandatory_count;             /* uint32 words: P at level 1 */
    int normal_bits, uv_bits, color_bits, tangent_bits; /* bits per component, 0 = absent */
    uint32_t record_bits;                 /* S = 2 b_n + 2 b_u + 4 b_c (+ 2 b_t + 1) */
    float uv_lo[2], uv_hi[2], uv_step[2]; /* float32 uv_range and uv_step (zero without UVs) */
    double geometric_error_m;             /* metres from LOD 0 */
    double min_distance_m;                /* metres, or -1 when the manifest has none */
    uint32_t cluster_size;                /* N, 0 for an unclustered buffer */
    uint64_t cluster_words_offset;        /* uint32 words into positions/clusters */
    uint32_t cluster_count;               /* n_c, clusters of a clustered buffer */
    uint32_t cluster_id[LOP_LEVELS + 1];  /* ClusterId[k] = clusters in bins <= k */
    uint64_t cluster_p_words[LOP_LEVELS]; /* words of the clustered P at levels 1..24 */
    uint32_t cluster_plane_bits[LOP_LEVELS - 1]; /* bits of its slice of planes 2..24 */
    uint32_t stage;                       /* the stage whose sections hold it (0 in the default layout) */
    uint64_t plane_start[LOP_LEVELS + 1]; /* [p] = bit offset of this buffer's slice of its stage's plane p */
} lop_lod;

/* A stage (format.md 14): the buffers whose LOD entries name it and the position sections that
   hold their bits. The default layout is one stage at level max_level holding every buffer. Words
   (mandatory_words, cluster_words) and plane_start count from the start of the stage's sections. */
typedef struct lop_stage {
    int level;                 /* L_s: the planes up to it have sections of their own */
    int available;             /* its level in the bytes given (format.md 14.4): 0 until its buffers'
                                  sections, clusters and mandatory bits have arrived */
    uint32_t buffers;          /* stored buffers (not placements of another part) it holds */
    int32_t mandatory_section;
    int32_t clusters_section;  /* -1 when no buffer of the stage is clustered */
    int32_t deferred_section;  /* the planes L_s + 1 .. max_level; -1 when absent (or the default layout) */
    int32_t plane_section[LOP_LEVELS + 1]; /* [p]: the section holding plane p (its own or the deferred
                                              one), -1 when the plane holds no bits or p > max_level */
    uint64_t plane_offset[LOP_LEVELS + 1]; /* [p]: byte offset of plane p in that section */
    uint64_t plane_bits[LOP_LEVELS + 1];   /* [p]: bits of plane p over the stage's buffers */
} lop_stage;

typedef struct lop_part {
    const char *name;          /* NUL-terminated (a name holding \u0000 is cut there) */
    uint32_t lod_count;        /* >= 1; LOD 0 is full detail */
    lop_lod *lods;
    int32_t owner;             /* the part whose bytes hold its buffers: itself unless a placement of another */
    int is_placement;          /* it has a placement record (docs/format.md section 6.8) */
    float transform[12];       /* row-major 3 x 4 (A | t) float32, local to world; identity otherwise */
    int32_t level_shift;       /* s: a scene level B maps to clamp(B + s, 1, 24) on its mesh grid */
    double grid_origin[3];     /* the grid its buffers are quantised on: the scene's, or the mesh grid */
    double grid_extent;
    int32_t hierarchy_section; /* -1 without --hierarchy */
} lop_part;

typedef struct lop_file {
    uint16_t version_major, version_minor;
    uint64_t file_size;        /* header.file_size */
    uint64_t size;             /* bytes given to lop_open (< file_size for a prefix) */
    int complete;              /* size == file_size */
    int max_level;             /* positions.max_level: planes written up to it */
    int available_level;       /* highest level every buffer decodes at (max_level when complete; in a
                                  prefix of a streaming file the lowest stage level, perhaps 0: see
                                  lop_buffer_level for each buffer's own) */
    int stream;                /* the streaming layout (format.md 14: positions.stages) */
    uint32_t stage_count;      /* >= 1 (1 in the default layout) */
    lop_stage *stages;
    uint64_t manifest_size;    /* bytes of the manifest's JSON text (decoded when stored encoded) */
    double grid_origin[3], grid_extent;  /* the scene grid */
    uint32_t viewport[2];      /* viewing: the conditions the file was cooked for */
    double fov_y_deg, pixel_error, nearest_m; /* nearest_m -1 when null */
    const char *generator;
    uint32_t part_count;
    lop_part *parts;
    uint32_t section_count;
    lop_section *sections;
    /* the default layout's position sections (also stages[0]'s); -1 in the streaming layout */
    int32_t mandatory_section, clusters_section; /* clusters: -1 when not clustered */
    int32_t plane_section[LOP_LEVELS + 1];       /* [p], p = 2..max_level; -1 elsewhere */
    /* private */
    lop_allocator memory_;
    void *block_;
} lop_file;

/* How a buffer is laid out for the GPU. NATIVE: the container's own layout (clustered P and
   records for a clustered buffer, drawn with #define LOP_CLUSTERED; binned P otherwise: CAP).
   BINNED: the binned (unclustered) P of the same vertices, for the unclustered shader.
   UNIFORM: AP, every vertex with exactly B bits (one bin). All three decode to the same
   grid integers at max(B, m_v) bits (UNIFORM: at B bits). */
typedef enum lop_layout { LOP_LAYOUT_NATIVE = 0, LOP_LAYOUT_BINNED = 1, LOP_LAYOUT_UNIFORM = 2 } lop_layout;

typedef struct lop_buffer_info {
    uint64_t words;        /* uint32 words of P */
    uint32_t clusters;     /* cluster records (4 uint32 each), 0 unless clustered in this layout */
    uint32_t block_size;   /* bytes of its LopDecode block: 288, or 416 clustered */
    uint32_t vertices;
    int level;             /* the level B asked for */
    int clustered;         /* the layout is clustered: draw with #define LOP_CLUSTERED */
} lop_buffer_info;

/* Decoded attributes of a buffer, each array n vertices long (caller-allocated; NULL: skipped). */
typedef struct lop_attributes {
    float *normals;   /* 3 per vertex: the UNNORMALISED octahedral decode (mesh space) */
    float *uvs;       /* 2 per vertex */
    float *colors;    /* 4 per vertex, linear RGBA */
    float *tangents;  /* 4 per vertex: unnormalised xyz, w = +1 or -1 */
} lop_attributes;

/* Flags of lop_decode_positions. */
#define LOP_LOCAL 1u  /* a placement's positions on its mesh grid (no transform) */

LOPDEF const char *lop_result_name(lop_result r);

/* Open a .lop from memory. data must outlive the file (sections point into it). options may be
   NULL. On failure *out is NULL and msg (if not NULL) holds one line naming what is wrong. */
LOPDEF lop_result lop_open(const void *data, size_t size, const lop_options *options, lop_file **out,
                           lop_message *msg);
LOPDEF void lop_close(lop_file *file);

/* The level part `part` decodes its buffers at when the scene asks for `level`: the level for a
   part on the scene grid, clamp(level + level_shift, 1, 24) for a placement. */
LOPDEF int lop_part_level(const lop_file *f, uint32_t part, int level);

/* The highest level buffer (part, lod) decodes at in the bytes given: its stage's level
   (format.md 8, 14.4), available_level in the default layout; 0 when its sections have not
   arrived (a prefix of a streaming file), -1 for a part or LOD out of range. */
LOPDEF int lop_buffer_level(const lop_file *f, uint32_t part, uint32_t lod);

/* What a renderer draws of part `part` when it wants LOD `lod` (format.md 14.4: the finest LOD that
   has arrived): the finest LOD k >= lod whose buffer has arrived, and the level it decodes at. In a
   file that opened, a part's coarsest LOD is always there. */
LOPDEF lop_result lop_drawable(const lop_file *f, uint32_t part, uint32_t lod, uint32_t *drawn, int *level);

/* Section 9: the level a buffer needs at camera distance d metres from its nearest point
   (half-pixel criterion with the file's viewing, clamped to max_level), and per part the LOD
   (fewest triangles among those whose geometric error projects within pixel_error) and level. */
LOPDEF int lop_required_level(const lop_file *f, double distance_m);
LOPDEF lop_result lop_select(const lop_file *f, uint32_t part, double distance_m, uint32_t *lod, int *level);

/* GPU buffers of part `part`'s LOD `lod` at level B (a placement gives its owner's buffer). */
LOPDEF lop_result lop_buffer(const lop_file *f, uint32_t part, uint32_t lod, int level, lop_layout layout,
                             lop_buffer_info *info);
LOPDEF lop_result lop_build(const lop_file *f, uint32_t part, uint32_t lod, int level, lop_layout layout,
                            uint32_t *words, size_t word_count, uint32_t *records, size_t record_words);
LOPDEF lop_result lop_decode_block(const lop_file *f, uint32_t part, uint32_t lod, int level, lop_layout layout,
                                   void *block, size_t block_size);
LOPDEF lop_result lop_attribute_block(const lop_file *f, uint32_t part, uint32_t lod, void *block, size_t block_size);
/* The attribute record's words as stored (upload them as the LopAttributes SSBO); NULL, 0 without. */
LOPDEF lop_result lop_attribute_words(const lop_file *f, uint32_t part, uint32_t lod, const uint8_t **bytes,
                                      size_t *size);
/* LopView block (crack-free per-vertex levels): camera xyz in metres, grid space. */
LOPDEF lop_result lop_view_block(const lop_file *f, const float camera[3], void *block, size_t block_size);

/* CPU decodes. Positions: 3 float32 per vertex, world metres (LOP_LOCAL: mesh grid). Grid:
   3 top-bit values per vertex and its width max(bin, B) (widths may be NULL). */
LOPDEF lop_result lop_decode_positions(const lop_file *f, uint32_t part, uint32_t lod, int level, float *xyz,
                                       size_t vertex_count, unsigned flags);
LOPDEF lop_result lop_decode_grid(const lop_file *f, uint32_t part, uint32_t lod, int level, uint32_t *values,
                                  uint8_t *widths, size_t vertex_count);
LOPDEF lop_result lop_decode_attributes(const lop_file *f, uint32_t part, uint32_t lod, const lop_attributes *out,
                                        size_t vertex_count);
LOPDEF lop_result lop_decode_indices(const lop_file *f, uint32_t part, uint32_t lod, uint32_t *indices,
                                     size_t index_count);

#ifdef __cplusplus
}
#endif
#endif /* LOP_H_INCLUDED */

/* ============================================================================================
   Implementation
   ============================================================================================ */
#ifdef LOP_IMPLEMENTATION
#ifndef LOP_IMPLEMENTATION_DONE
#define LOP_IMPLEMENTATION_DONE

#include <float.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(FLT_EVAL_METHOD) && FLT_EVAL_METHOD > 0 && !defined(LOP_ALLOW_EXCESS_PRECISION)
#error "lop.h: float arithmetic here has excess precision (FLT_EVAL_METHOD > 0, e.g. x87): decodes would not be bit-exact. Build for SSE2 (-msse2 -mfpmath=sse) or define LOP_ALLOW_EXCESS_PRECISION."
#endif

#ifndef LOP_JSON_MAX_DEPTH
#define LOP_JSON_MAX_DEPTH 64
#endif
#ifndef LOP_JSON_MAX_STRING
#define LOP_JSON_MAX_STRING 65536
#endif
#ifndef LOP_JSON_MAX_NUMBER
#define LOP_JSON_MAX_NUMBER 800
#endif
#if LOP_JSON_MAX_NUMBER > 800
#error "lop.h: LOP_JSON_MAX_NUMBER is at most 800 (the exact decimal conversion is sized for it)"
#endif
#ifndef LOP_JSON_MAX_ITEMS
#define LOP_JSON_MAX_ITEMS 16777216u
#endif

/* Float decodes are single IEEE float32 operations in a fixed order: no contraction into fused
   multiply-adds. Each product that a sum follows goes through lop__fence, an empty asm that keeps it
   a separate value (compilers honour it even under -ffp-contract=fast, which disregards the STDC
   pragma); elsewhere a volatile round trip does the same. */
#if defined(__clang__)
#define LOP__NO_CONTRACT _Pragma("STDC FP_CONTRACT OFF")
#else
#define LOP__NO_CONTRACT
#endif

static float lop__fence(float x)
{
#if (defined(__GNUC__) || defined(__clang__)) && (defined(__x86_64__) || (defined(__i386__) && defined(__SSE__)))
    __asm__("" : "+x"(x));
#elif (defined(__GNUC__) || defined(__clang__)) && defined(__aarch64__)
    __asm__("" : "+w"(x));
#elif defined(__GNUC__) || defined(__clang__)
    __asm__("" : "+m"(x));
#else
    volatile float v = x;
    x = v;
#endif
    return x;
}
#define LOP__FENCE(x) lop__fence(x)

#define LOP__F32_MAX 3.4028234663852886e38

/* Fuzzing builds (the OSS-Fuzz convention) skip the checksum comparisons, so that mutated inputs
   reach the parser and the validator; never define it in production. */
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
#define LOP__CHECK_CRC 0
#else
#define LOP__CHECK_CRC 1
#endif
#define LOP__MIN_EXTENT 2.6469779601696886e-23 /* 2^-75 m: the smallest grid extent lopcook cooks with */
#define LOP__MAX_REACH 5.0706024009129176e30   /* 2^102 m: the largest |origin| + extent */

/* ---- memory, bytes, messages ------------------------------------------------------------- */

static void *lop__default_alloc(void *user, size_t size) { (void)user; return malloc(size ? size : 1); }
static void lop__default_free(void *user, void *ptr) { (void)user; free(ptr); }

static void *lop__alloc(const lop_allocator *a, size_t size)
{
    return a->alloc(a->user, size ? size : 1);
}

static void lop__free(const lop_allocator *a, void *p)
{
    if (p)
        a->free(a->user, p);
}

/* n * size, or 0 when that overflows size_t (an allocation of 0 is refused by the callers). */
static size_t lop__mul(size_t n, size_t size)
{
    if (size && n > (size_t)-1 / size)
        return 0;
    return n * size;
}

static uint64_t lop__sat_add(uint64_t a, uint64_t b) { return a + b < a ? UINT64_MAX : a + b; }

static uint32_t lop__rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint16_t lop__rd16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }

static uint64_t lop__rd64(const uint8_t *p) { return (uint64_t)lop__rd32(p) | (uint64_t)lop__rd32(p + 4) << 32; }

static void lop__wr32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static void lop__wrf(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    lop__wr32(p, u);
}

/* 64 bits of an LSB-first bit stream from bit `bit` on (at least 57 valid ones); bytes past
   `len` read as zero, so no load leaves the stream. */
static inline uint64_t lop__bits(const uint8_t *p, size_t len, uint64_t bit)
{
    uint64_t byte = bit >> 3, w = 0;
    if (byte + 8 <= len) {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
        memcpy(&w, p + byte, 8);
#else
        w = lop__rd64(p + byte);
#endif
    } else {
        unsigned i;
        for (i = 0; i < 8 && byte + i < len; i++)
            w |= (uint64_t)p[byte + i] << (8 * i);
    }
    return w >> (bit & 7);
}

/* `width` (0..57) bits at `bit`. */
static inline uint64_t lop__field(const uint8_t *p, size_t len, uint64_t bit, unsigned width)
{
    return lop__bits(p, len, bit) & ((UINT64_C(1) << width) - 1);
}

/* lop__bits where the caller has checked that bytes [bit / 8, bit / 8 + 8) lie in the stream. */
static inline uint64_t lop__bits_in(const uint8_t *p, uint64_t bit)
{
    uint64_t w;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    memcpy(&w, p + (bit >> 3), 8);
#else
    w = lop__rd64(p + (bit >> 3));
#endif
    return w >> (bit & 7);
}

/* lop__bits, unchecked when `in` says the caller checked the range */
static inline uint64_t lop__ld(const uint8_t *p, size_t len, uint64_t bit, int in)
{
    return in ? lop__bits_in(p, bit) : lop__bits(p, len, bit);
}

static const uint8_t lop__zeros[16] = {0};

/* Whether every 8-byte load of lop__bits_in at bits [bit, bit + nbits] stays inside len bytes. */
static int lop__loads_in(size_t len, uint64_t bit, uint64_t nbits)
{
    return ((bit + nbits) >> 3) + 8 <= (uint64_t)len;
}

typedef struct lop__err {
    lop_result code;
    lop_message *msg;
} lop__err;

static lop_result lop__fail(lop__err *e, lop_result code, const char *fmt, ...)
{
    if (e->code == lop_success) {
        e->code = code;
        if (e->msg) {
            va_list ap;
            va_start(ap, fmt);
            vsnprintf(e->msg->text, sizeof e->msg->text, fmt, ap);
            va_end(ap);
        }
    }
    return code;
}

/* lop__fail for the functions that answer 1 (sound) or 0 (the error is set) */
static int lop__fail0(lop__err *e, lop_result code, const char *fmt, ...)
{
    if (e->code == lop_success) {
        e->code = code;
        if (e->msg) {
            va_list ap;
            va_start(ap, fmt);
            vsnprintf(e->msg->text, sizeof e->msg->text, fmt, ap);
            va_end(ap);
        }
    }
    return 0;
}

/* CRC-32 (ISO-HDLC, zlib's), slicing by 8 over tables built per call site (no global state). */
typedef struct lop__crc {
    uint32_t t[8][256];
} lop__crc;

static void lop__crc_init(lop__crc *c)
{
    uint32_t i, k;
    for (i = 0; i < 256; i++) {
        uint32_t v = i;
        for (k = 0; k < 8; k++)
            v = (v >> 1) ^ (0xEDB88320u & (0u - (v & 1u)));
        c->t[0][i] = v;
    }
    for (i = 0; i < 256; i++)
        for (k = 1; k < 8; k++)
            c->t[k][i] = (c->t[k - 1][i] >> 8) ^ c->t[0][c->t[k - 1][i] & 0xFF];
}

static uint32_t lop__crc32(const lop__crc *c, const uint8_t *p, uint64_t n)
{
    uint32_t v = 0xFFFFFFFFu;
    while (n >= 8) {
        uint32_t a = v ^ lop__rd32(p), b = lop__rd32(p + 4);
        v = c->t[7][a & 0xFF] ^ c->t[6][(a >> 8) & 0xFF] ^ c->t[5][(a >> 16) & 0xFF] ^ c->t[4][a >> 24] ^
            c->t[3][b & 0xFF] ^ c->t[2][(b >> 8) & 0xFF] ^ c->t[1][(b >> 16) & 0xFF] ^ c->t[0][b >> 24];
        p += 8;
        n -= 8;
    }
    while (n--)
        v = (v >> 8) ^ c->t[0][(v ^ *p++) & 0xFF];
    return v ^ 0xFFFFFFFFu;
}

/* ---- encoded sections: raw DEFLATE and the meshopt triangle stream (format.md 15) -------------
   Both decoders read their input through bounds checks only, write at most the bytes they were
   allowed, allocate through the caller (an output that grows up to its limit) and give zlib's and
   meshoptimizer's verdict on every stream: a stream that either refuses is refused here, with the
   class lop_error_encoding. */

#define LOP__DEFLATE_MAX_RATIO 1032u /* DEFLATE expands at most 1032 times */
#define LOP__FAST_BITS 10            /* Huffman codes up to this long decode with one table lookup */

enum { LOP__Z_OK = 0, LOP__Z_DATA, LOP__Z_SHORT, LOP__Z_LONG, LOP__Z_MEMORY };

/* A canonical Huffman code: counts and symbols by length (puff's form) and a table of the codes of
   at most LOP__FAST_BITS bits, indexed by the next bits of the stream (first bit lowest): entry
   length << 9 | symbol, 0 where no code that short starts with those bits. */
typedef struct lop__huff {
    uint16_t fast[1 << LOP__FAST_BITS];
    uint16_t count[16];
    uint16_t symbol[288];
} lop__huff;

typedef struct lop__inflater {
    const uint8_t *in;
    size_t in_len, pos;
    uint64_t acc;     /* bits not yet used, the next one lowest */
    unsigned nbits;
    uint8_t *out;
    size_t n, cap, limit; /* bytes written, allocated, allowed */
    const lop_allocator *mem;
    lop__huff lit, dist, fixed_lit, fixed_dist;
    int have_fixed;
} lop__inflater;

/* zlib's inflate_table rules: no over-subscribed set; an incomplete one only where `incomplete_ok`
   (literal/length and distance codes) and then only a single code of length 1, or no code at all. */
static int lop__huff_build(lop__huff *h, const uint8_t *lengths, unsigned n, int incomplete_ok)
{
    uint16_t offs[16], first[16];
    int left = 1, max = 0, len;
    unsigned s, idx, code;
    memset(h->count, 0, sizeof h->count);
    for (s = 0; s < n; s++)
        h->count[lengths[s]]++;
    h->count[0] = 0;
    for (len = 1; len < 16; len++) {
        left = 2 * left - h->count[len];
        if (left < 0)
            return 0;
        if (h->count[len])
            max = len;
    }
    if (left > 0 && max > 0 && (!incomplete_ok || max != 1))
        return 0;
    if (max == 0 && !incomplete_ok)
        return 0;
    offs[1] = 0;
    for (len = 1; len < 15; len++)
        offs[len + 1] = (uint16_t)(offs[len] + h->count[len]);
    for (s = 0; s < n; s++)
        if (lengths[s])
            h->symbol[offs[lengths[s]]++] = (uint16_t)s;
    memset(h->fast, 0, sizeof h->fast);
    code = 0; /* the first code of each length (RFC 1951 3.2.2) */
    first[0] = 0;
    for (len = 1; len < 16; len++) {
        code = (code + h->count[len - 1]) << 1;
        first[len] = (uint16_t)code;
    }
    for (len = 1, idx = 0; len <= LOP__FAST_BITS; len++) {
        unsigned c;
        for (c = 0; c < h->count[len]; c++, idx++) {
            unsigned v = first[len] + c, rev = 0, b, i;
            for (b = 0; b < (unsigned)len; b++)
                rev |= ((v >> b) & 1u) << (len - 1 - b);
            for (i = rev; i < (1u << LOP__FAST_BITS); i += 1u << len)
                h->fast[i] = (uint16_t)((unsigned)len << 9 | h->symbol[idx]);
        }
    }
    return 1;
}

static void lop__refill(lop__inflater *z)
{
    while (z->nbits <= 56 && z->pos < z->in_len) {
        z->acc |= (uint64_t)z->in[z->pos++] << z->nbits;
        z->nbits += 8;
    }
}

/* k <= 32 bits (the caller refilled; LOP__Z_SHORT when the stream has fewer). */
static int lop__take(lop__inflater *z, unsigned k, uint32_t *v)
{
    if (z->nbits < k)
        return LOP__Z_SHORT;
    *v = (uint32_t)(z->acc & ((UINT64_C(1) << k) - 1));
    z->acc >>= k;
    z->nbits -= k;
    return LOP__Z_OK;
}

/* The next symbol of code h, or -LOP__Z_DATA (no such code) / -LOP__Z_SHORT (the stream ends). */
static int lop__symbol(lop__inflater *z, const lop__huff *h)
{
    unsigned e = h->fast[z->acc & ((1u << LOP__FAST_BITS) - 1)];
    int len, code = 0, first = 0, index = 0;
    if (e) {
        unsigned l = e >> 9;
        if (l > z->nbits)
            return -LOP__Z_SHORT;
        z->acc >>= l;
        z->nbits -= l;
        return (int)(e & 511u);
    }
    for (len = 1; len < 16; len++) { /* canonical decoding, one bit at a time (puff) */
        int count = h->count[len];
        if ((unsigned)len > z->nbits)
            return -LOP__Z_SHORT;
        code |= (int)((z->acc >> (len - 1)) & 1u);
        if (code - first < count) {
            z->acc >>= len;
            z->nbits -= (unsigned)len;
            return h->symbol[index + code - first];
        }
        index += count;
        first = (first + count) << 1;
        code <<= 1;
    }
    return -LOP__Z_DATA;
}

/* Room for k more output bytes: LOP__Z_LONG beyond the limit, the block grown (doubling) as needed. */
static int lop__room(lop__inflater *z, size_t k)
{
    if (k > z->limit - z->n)
        return LOP__Z_LONG;
    if (z->n + k > z->cap) {
        size_t cap = z->cap * 2 > z->n + k ? z->cap * 2 : z->n + k;
        uint8_t *grown;
        cap = cap < z->limit ? cap : z->limit;
        grown = (uint8_t *)lop__alloc(z->mem, cap);
        if (!grown)
            return LOP__Z_MEMORY;
        if (z->n)
            memcpy(grown, z->out, z->n);
        lop__free(z->mem, z->out);
        z->out = grown;
        z->cap = cap;
    }
    return LOP__Z_OK;
}

static int lop__stored(lop__inflater *z)
{
    size_t len;
    int r;
    z->pos -= z->nbits >> 3; /* give back the whole bytes held; the partial one is dropped */
    z->acc = 0;
    z->nbits = 0;
    if (z->in_len - z->pos < 4)
        return LOP__Z_SHORT;
    len = lop__rd16(z->in + z->pos);
    if (len != (unsigned)(~lop__rd16(z->in + z->pos + 2) & 0xFFFFu))
        return LOP__Z_DATA;
    z->pos += 4;
    if (z->in_len - z->pos < len)
        return LOP__Z_SHORT;
    if ((r = lop__room(z, len)) != LOP__Z_OK)
        return r;
    if (len)
        memcpy(z->out + z->n, z->in + z->pos, len);
    z->n += len;
    z->pos += len;
    return LOP__Z_OK;
}

static const uint8_t lop__clen_order[19] = {16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15};

static int lop__dynamic(lop__inflater *z)
{
    uint8_t lens[320], clen[19];
    uint32_t nlen, ndist, ncode, x, i, have = 0;
    lop__huff *cl = &z->dist; /* the code-length code is built in the distance table, used before it */
    int r;
    lop__refill(z);
    if ((r = lop__take(z, 5, &nlen)) || (r = lop__take(z, 5, &ndist)) || (r = lop__take(z, 4, &ncode)))
        return r;
    nlen += 257;
    ndist += 1;
    ncode += 4;
    if (nlen > 286 || ndist > 30)
        return LOP__Z_DATA;
    memset(clen, 0, sizeof clen);
    for (i = 0; i < ncode; i++) {
        lop__refill(z);
        if ((r = lop__take(z, 3, &x)) != LOP__Z_OK)
            return r;
        clen[lop__clen_order[i]] = (uint8_t)x;
    }
    if (!lop__huff_build(cl, clen, 19, 0))
        return LOP__Z_DATA;
    while (have < nlen + ndist) {
        int sym;
        uint32_t rep;
        uint8_t len = 0;
        lop__refill(z);
        sym = lop__symbol(z, cl);
        if (sym < 0)
            return -sym;
        if (sym < 16) {
            lens[have++] = (uint8_t)sym;
            continue;
        }
        if (sym == 16) {
            if (have == 0)
                return LOP__Z_DATA;
            len = lens[have - 1];
            if ((r = lop__take(z, 2, &rep)) != LOP__Z_OK)
                return r;
            rep += 3;
        } else if (sym == 17) {
            if ((r = lop__take(z, 3, &rep)) != LOP__Z_OK)
                return r;
            rep += 3;
        } else {
            if ((r = lop__take(z, 7, &rep)) != LOP__Z_OK)
                return r;
            rep += 11;
        }
        if (have + rep > nlen + ndist)
            return LOP__Z_DATA;
        memset(lens + have, len, rep);
        have += rep;
    }
    if (lens[256] == 0) /* no end-of-block code */
        return LOP__Z_DATA;
    if (!lop__huff_build(&z->lit, lens, nlen, 1) || !lop__huff_build(&z->dist, lens + nlen, ndist, 1))
        return LOP__Z_DATA;
    return LOP__Z_OK;
}

static const uint16_t lop__len_base[29] = {3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59,
                                           67, 83, 99, 115, 131, 163, 195, 227, 258};
static const uint8_t lop__len_extra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5,
                                           5, 0};
static const uint16_t lop__dist_base[30] = {1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, 49, 65, 97, 129, 193, 257, 385, 513, 769,
                                            1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
static const uint8_t lop__dist_extra[30] = {0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11,
                                            11, 12, 12, 13, 13};

/* The symbols of one compressed block, up to its end-of-block code. */
static int lop__codes(lop__inflater *z, const lop__huff *lit, const lop__huff *dist)
{
    for (;;) {
        int sym, ds, r;
        uint32_t len, d, extra;
        lop__refill(z);
        sym = lop__symbol(z, lit);
        if (sym < 0)
            return -sym;
        if (sym < 256) {
            if (z->n >= z->cap && (r = lop__room(z, 1)) != LOP__Z_OK)
                return r;
            z->out[z->n++] = (uint8_t)sym;
            continue;
        }
        if (sym == 256)
            return LOP__Z_OK;
        if (sym > 285)
            return LOP__Z_DATA;
        if ((r = lop__take(z, lop__len_extra[sym - 257], &extra)) != LOP__Z_OK)
            return r;
        len = lop__len_base[sym - 257] + extra;
        ds = lop__symbol(z, dist);
        if (ds < 0)
            return -ds;
        if (ds > 29)
            return LOP__Z_DATA;
        if ((r = lop__take(z, lop__dist_extra[ds], &extra)) != LOP__Z_OK)
            return r;
        d = lop__dist_base[ds] + extra;
        if (d > z->n)
            return LOP__Z_DATA; /* a distance beyond the bytes decoded */
        if ((r = lop__room(z, len)) != LOP__Z_OK)
            return r;
        {
            uint8_t *o = z->out + z->n;
            const uint8_t *from = o - d;
            if (d >= len) {
                memcpy(o, from, len);
            } else {
                uint32_t i;
                for (i = 0; i < len; i++)
                    o[i] = from[i];
            }
            z->n += len;
        }
    }
}

/* Inflate the raw DEFLATE stream at the start of in[0 .. in_len) into at most `limit` bytes
   (z->out, z->n of them; the caller frees z->out). LOP__Z_OK, or why not. *end: the bytes the
   stream occupies (the byte holding its last bit included). */
static int lop__inflate(lop__inflater *z, const uint8_t *in, size_t in_len, size_t limit, size_t first_cap,
                        const lop_allocator *mem, size_t *end)
{
    uint32_t last = 0, type;
    int r;
    z->in = in;
    z->in_len = in_len;
    z->pos = 0;
    z->acc = 0;
    z->nbits = 0;
    z->n = 0;
    z->limit = limit;
    z->mem = mem;
    z->have_fixed = 0;
    z->cap = first_cap < limit ? first_cap : limit;
    z->out = (uint8_t *)lop__alloc(mem, z->cap);
    if (!z->out)
        return LOP__Z_MEMORY;
    while (!last) {
        lop__refill(z);
        if ((r = lop__take(z, 1, &last)) != LOP__Z_OK || (r = lop__take(z, 2, &type)) != LOP__Z_OK)
            return r;
        if (type == 0) {
            r = lop__stored(z);
        } else if (type == 1) {
            if (!z->have_fixed) {
                uint8_t l[288];
                memset(l, 8, 144);
                memset(l + 144, 9, 112);
                memset(l + 256, 7, 24);
                memset(l + 280, 8, 8);
                lop__huff_build(&z->fixed_lit, l, 288, 0);
                memset(l, 5, 32);
                lop__huff_build(&z->fixed_dist, l, 32, 0);
                z->have_fixed = 1;
            }
            r = lop__codes(z, &z->fixed_lit, &z->fixed_dist);
        } else if (type == 2) {
            r = lop__dynamic(z);
            if (r == LOP__Z_OK)
                r = lop__codes(z, &z->lit, &z->dist);
        } else {
            r = LOP__Z_DATA; /* block type 3 */
        }
        if (r != LOP__Z_OK)
            return r;
    }
    *end = z->pos - (z->nbits >> 3);
    return LOP__Z_OK;
}

static const char *lop__z_why(int r)
{
    switch (r) {
    case LOP__Z_DATA: return "the deflate stream is corrupt";
    case LOP__Z_SHORT: return "the deflate stream ends before its final block";
    case LOP__Z_LONG: return "the deflate stream expands beyond its declared size";
    default: return "out of memory";
    }
}

/* The 3m indices of an EXT_meshopt_compression triangle stream E (version 1) as format.md 15.2
   writes it out, each checked below n, written as w-byte little-endian integers to out (4 ceil(3 m
   w / 4) bytes, the tail zeroed). NULL, or why the stream is refused. */
static const char *lop__triangles(const uint8_t *E, size_t len, uint32_t m, uint32_t n, unsigned w, uint8_t *out)
{
    uint32_t edge_a[16], edge_b[16], vert[16], next = 0, last = 0;
    unsigned ep = 0, vp = 0, t;
    size_t code = 1, data, end;
    const uint8_t *table;
    int k;
    if (len < 1 + (size_t)m + 16)
        return "the triangle stream is too short for its triangles";
    if (E[0] != 0xE1)
        return "the triangle stream does not start with 0xe1 (bitstream version 1)";
    end = len - 16;
    table = E + end;
    if (table[14] || table[15])
        return "the triangle stream's table does not end with two zero bytes";
    for (k = 0; k < 14; k++)
        if ((table[k] >> 4) == 15 || (table[k] & 15) == 15)
            return "the triangle stream's table has a nibble 0xF";
    data = 1 + (size_t)m;
    for (k = 0; k < 16; k++)
        edge_a[k] = edge_b[k] = vert[k] = 0xFFFFFFFFu;
#define LOP__PUSH_EDGE(x, y) (edge_a[ep] = (x), edge_b[ep] = (y), ep = (ep + 1) & 15u)
#define LOP__PUSH_VERT(x) (vert[vp] = (x), vp = (vp + 1) & 15u)
#define LOP__VERT_AT(i) vert[(vp - 1u - (unsigned)(i)) & 15u]
#define LOP__INDEX(dst)                                                                                    \
    do {                                                                                                   \
        uint32_t v_ = 0;                                                                                   \
        int j_;                                                                                            \
        for (j_ = 0; j_ < 5; j_++) {                                                                       \
            uint8_t b_;                                                                                    \
            if (data >= end)                                                                               \
                return "the triangle stream reads past its data";                                         \
            b_ = E[data++];                                                                                \
            v_ |= (uint32_t)(((uint64_t)(b_ & 127u) << (7 * j_)) & 0xFFFFFFFFu); /* bits above 31 dropped */ \
            if (b_ < 128)                                                                                  \
                break;                                                                                     \
        }                                                                                                  \
        last = last + ((v_ >> 1) ^ (0u - (v_ & 1u)));                                                      \
        (dst) = last;                                                                                      \
    } while (0)
    for (t = 0; t < m; t++) {
        uint32_t a = 0, b = 0, c = 0, x = E[code++], tri[3];
        unsigned i;
        if (x < 0xF0) {
            unsigned e = (ep - 1u - (x >> 4)) & 15u, f = x & 15u;
            a = edge_a[e];
            b = edge_b[e];
            if (f == 0) {
                c = next++;
                LOP__PUSH_VERT(c);
            } else if (f <= 12) {
                c = LOP__VERT_AT(f);
            } else if (f == 13) {
                c = last = last - 1u;
                LOP__PUSH_VERT(c);
            } else if (f == 14) {
                c = last = last + 1u;
                LOP__PUSH_VERT(c);
            } else {
                LOP__INDEX(c);
                LOP__PUSH_VERT(c);
            }
            LOP__PUSH_EDGE(c, b);
            LOP__PUSH_EDGE(a, c);
        } else {
            unsigned aux, fa, fb, fc;
            if (x < 0xFE) {
                aux = table[x & 15u];
                fa = 0;
            } else {
                if (data >= end)
                    return "the triangle stream reads past its data";
                aux = E[data++];
                fa = x == 0xFE ? 0u : 15u;
                if (aux == 0)
                    next = 0;
            }
            fb = aux >> 4;
            fc = aux & 15u;
            if (fa == 0)
                a = next++;
            if (fb == 0)
                b = next++;
            else if (fb < 15)
                b = LOP__VERT_AT(fb - 1);
            if (fc == 0)
                c = next++;
            else if (fc < 15)
                c = LOP__VERT_AT(fc - 1);
            if (fa == 15)
                LOP__INDEX(a);
            if (fb == 15)
                LOP__INDEX(b);
            if (fc == 15)
                LOP__INDEX(c);
            LOP__PUSH_VERT(a);
            if (fb == 0 || fb == 15)
                LOP__PUSH_VERT(b);
            if (fc == 0 || fc == 15)
                LOP__PUSH_VERT(c);
            LOP__PUSH_EDGE(b, a);
            LOP__PUSH_EDGE(c, b);
            LOP__PUSH_EDGE(a, c);
        }
        tri[0] = a;
        tri[1] = b;
        tri[2] = c;
        for (i = 0; i < 3; i++) {
            size_t o = ((size_t)3 * t + i) * w;
            if (tri[i] >= n)
                return "a triangle index is out of range for its vertices";
            out[o] = (uint8_t)tri[i];
            out[o + 1] = (uint8_t)(tri[i] >> 8);
            if (w == 4) {
                out[o + 2] = (uint8_t)(tri[i] >> 16);
                out[o + 3] = (uint8_t)(tri[i] >> 24);
            }
        }
    }
#undef LOP__PUSH_EDGE
#undef LOP__PUSH_VERT
#undef LOP__VERT_AT
#undef LOP__INDEX
    if (data != end)
        return "the triangle stream holds data its triangles do not read";
    return NULL;
}

/* ---- decimal to double, correctly rounded (locale-free) ------------------------------------ */

#define LOP__BIG 136 /* 32-bit words: 4352 bits, more than 10^(800 + 330) needs */

typedef struct lop__big {
    uint32_t w[LOP__BIG];
    int n; /* words in use; w[n-1] != 0 unless n == 0 */
} lop__big;

static void lop__big_trim(lop__big *a)
{
    while (a->n > 0 && a->w[a->n - 1] == 0)
        a->n--;
}

static void lop__big_muladd(lop__big *a, uint32_t m, uint32_t add)
{
    uint64_t carry = add;
    int i;
    for (i = 0; i < a->n; i++) {
        uint64_t v = (uint64_t)a->w[i] * m + carry;
        a->w[i] = (uint32_t)v;
        carry = v >> 32;
    }
    if (carry && a->n < LOP__BIG)
        a->w[a->n++] = (uint32_t)carry;
}

static int lop__big_bits(const lop__big *a)
{
    uint32_t top;
    int b = 0;
    if (a->n == 0)
        return 0;
    top = a->w[a->n - 1];
    while (top) {
        b++;
        top >>= 1;
    }
    return 32 * (a->n - 1) + b;
}

static void lop__big_shl(lop__big *a, int s)
{
    int words = s / 32, bits = s % 32, i;
    if (a->n == 0 || s <= 0)
        return;
    if (a->n + words + 1 > LOP__BIG)
        return; /* cannot happen within the bounds lop__decimal applies */
    a->w[a->n + words] = 0;
    for (i = a->n - 1; i >= 0; i--) {
        uint32_t v = a->w[i];
        if (bits) {
            a->w[i + words + 1] |= v >> (32 - bits);
            a->w[i + words] = v << bits;
        } else {
            a->w[i + words] = v;
        }
    }
    for (i = 0; i < words; i++)
        a->w[i] = 0;
    a->n += words + 1;
    lop__big_trim(a);
}

static void lop__big_shr1(lop__big *a)
{
    int i;
    for (i = 0; i < a->n; i++)
        a->w[i] = (a->w[i] >> 1) | (i + 1 < a->n ? a->w[i + 1] << 31 : 0);
    lop__big_trim(a);
}

static int lop__big_cmp(const lop__big *a, const lop__big *b)
{
    int i;
    if (a->n != b->n)
        return a->n < b->n ? -1 : 1;
    for (i = a->n - 1; i >= 0; i--)
        if (a->w[i] != b->w[i])
            return a->w[i] < b->w[i] ? -1 : 1;
    return 0;
}

static void lop__big_sub(lop__big *a, const lop__big *b) /* a -= b, a >= b */
{
    int64_t borrow = 0;
    int i;
    for (i = 0; i < a->n; i++) {
        int64_t v = (int64_t)a->w[i] - (i < b->n ? (int64_t)b->w[i] : 0) - borrow;
        borrow = v < 0;
        a->w[i] = (uint32_t)(v + (borrow ? (INT64_C(1) << 32) : 0));
    }
    lop__big_trim(a);
}

static void lop__big_pow10(lop__big *a, int e)
{
    while (e >= 9) {
        lop__big_muladd(a, 1000000000u, 0);
        e -= 9;
    }
    while (e-- > 0)
        lop__big_muladd(a, 10u, 0);
}

static double lop__from_bits(uint64_t u)
{
    double d;
    memcpy(&d, &u, 8);
    return d;
}

/* 2^e as a double, -1022 <= e <= 1023 (C++ before 17 has no hexadecimal float literals) */
#define LOP__POW2(e) lop__from_bits((uint64_t)((e) + 1023) << 52)

/* q * 2^-shift (q in [2^55, 2^57)), with `sticky` telling whether the exact value exceeds it,
   rounded to nearest even, subnormals and overflow included. */
static double lop__round_q(uint64_t q, int shift, int sticky, int negative)
{
    int qb = 0, e_val, lsb_e, drop;
    uint64_t m, rem, half, t = q, bits;
    while (t) {
        qb++;
        t >>= 1;
    }
    e_val = qb - 1 - shift;
    lsb_e = e_val - 52 < -1074 ? -1074 : e_val - 52;
    drop = lsb_e + shift;
    if (drop >= 63) {
        m = 0; /* below half the smallest subnormal */
    } else {
        m = q >> drop;
        rem = q & ((UINT64_C(1) << drop) - 1);
        half = UINT64_C(1) << (drop - 1);
        if (rem > half || (rem == half && (sticky || (m & 1))))
            m++;
        if (m == (UINT64_C(1) << 53)) {
            m >>= 1;
            lsb_e++;
        }
    }
    if (m >= (UINT64_C(1) << 52) && lsb_e + 52 > 1023)
        bits = UINT64_C(0x7FF) << 52;
    else if (m < (UINT64_C(1) << 52))
        bits = m; /* subnormal (lsb_e == -1074) or zero */
    else
        bits = (uint64_t)(lsb_e + 52 + 1023) << 52 | (m - (UINT64_C(1) << 52));
    return lop__from_bits(bits | (negative ? UINT64_C(1) << 63 : 0));
}

/* A JSON number token (validated grammar, at most LOP_JSON_MAX_NUMBER characters) as the
   nearest double, exactly as a correctly rounded strtod in the C locale. */
static double lop__decimal(const char *s, size_t n)
{
    static const double p10[23] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    char digits[LOP_JSON_MAX_NUMBER + 1];
    size_t i = 0;
    int nd = 0, negative = 0, seen_point = 0;
    long e10 = 0, ex = 0;
    if (i < n && s[i] == '-') {
        negative = 1;
        i++;
    }
    for (; i < n && (s[i] == '.' || (s[i] >= '0' && s[i] <= '9')); i++) {
        if (s[i] == '.') {
            seen_point = 1;
            continue;
        }
        if (nd == 0 && s[i] == '0') {
            if (seen_point)
                e10--;
            continue;
        }
        digits[nd++] = s[i];
        if (seen_point)
            e10--;
    }
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        int eneg = 0;
        i++;
        if (i < n && (s[i] == '+' || s[i] == '-'))
            eneg = s[i++] == '-';
        for (; i < n; i++)
            if (ex < 100000000L)
                ex = ex * 10 + (s[i] - '0');
        e10 += eneg ? -ex : ex;
    }
    while (nd > 0 && digits[nd - 1] == '0') {
        nd--;
        e10++;
    }
    if (nd == 0)
        return negative ? -0.0 : 0.0;
    if (nd + e10 > 310)
        return negative ? -lop__from_bits(UINT64_C(0x7FF) << 52) : lop__from_bits(UINT64_C(0x7FF) << 52);
    if (nd + e10 < -330)
        return negative ? -0.0 : 0.0;
    if (nd <= 15 && e10 >= -22 && e10 <= 22) { /* Clinger's fast path: both operands exact */
        uint64_t d = 0;
        double v;
        int k;
        for (k = 0; k < nd; k++)
            d = d * 10 + (uint64_t)(digits[k] - '0');
        v = e10 >= 0 ? (double)d * p10[e10] : (double)d / p10[-e10];
        return negative ? -v : v;
    }
    {
        lop__big num, den;
        uint64_t q = 0;
        int k, shift, bit;
        num.n = 0;
        den.n = 1;
        den.w[0] = 1;
        for (k = 0; k < nd; k++) {
            if (num.n == 0 && digits[k] != '0') {
                num.n = 1;
                num.w[0] = (uint32_t)(digits[k] - '0');
            } else if (num.n) {
                lop__big_muladd(&num, 10u, (uint32_t)(digits[k] - '0'));
            }
        }
        if (e10 >= 0)
            lop__big_pow10(&num, (int)e10);
        else
            lop__big_pow10(&den, (int)-e10);
        /* scale so that the quotient has 56 bits: q in [2^55, 2^57) */
        shift = 56 - (lop__big_bits(&num) - lop__big_bits(&den));
        if (shift > 0)
            lop__big_shl(&num, shift);
        else if (shift < 0)
            lop__big_shl(&den, -shift);
        lop__big_shl(&den, 56);
        for (bit = 56; bit >= 0; bit--) {
            if (lop__big_cmp(&num, &den) >= 0) {
                lop__big_sub(&num, &den);
                q |= UINT64_C(1) << bit;
            }
            lop__big_shr1(&den);
        }
        return lop__round_q(q, shift, num.n != 0, negative);
    }
}

/* ---- a bounded, strict JSON parser ---------------------------------------------------------
   Grammar of RFC 8259 as Python's json module reads it: whitespace is space, tab, CR and LF;
   no NaN or Infinity; no control characters in strings; \uXXXX escapes with surrogate pairs
   combined (a lone surrogate is kept as its 3-byte WTF-8 form); duplicate keys refused. Bounds:
   nesting depth, string bytes, number characters, items per array or object. Two passes: the
   first counts values and bytes, the second fills arrays of exactly that size. */

enum { LOPJ_NULL, LOPJ_FALSE, LOPJ_TRUE, LOPJ_INT, LOPJ_FLOAT, LOPJ_STRING, LOPJ_ARRAY, LOPJ_OBJECT };

typedef struct lopj_val {
    uint8_t type;
    uint8_t big;      /* INT outside int64 (then i is its sign, +1 or -1) */
    uint32_t key;     /* member of an object: key's offset in the pool */
    uint32_t key_len; /* ... and length; UINT32_MAX when not a member */
    uint32_t count;   /* ARRAY, OBJECT: children */
    uint32_t next;    /* index of the value after this one's subtree */
    uint32_t sorted;  /* OBJECT: its children's indices, sorted by key, from members[sorted] */
    uint32_t str;     /* STRING: pool offset; INT, FLOAT: token offset in the manifest */
    uint32_t len;     /* STRING: bytes; INT, FLOAT: token characters */
    int64_t i;        /* INT */
    double d;         /* INT, FLOAT: the value as the nearest double */
} lopj_val;

typedef struct lopj {
    const char *s;
    size_t n, pos;
    lopj_val *v;        /* NULL in the counting pass */
    uint32_t nv;
    char *pool;
    size_t np;
    uint32_t *members;
    uint32_t nm;
    int depth;
    lop__err *err;
} lopj;

static int lopj_fail(lopj *p, const char *what)
{
    lop__fail(p->err, lop_error_manifest_json, "manifest is not valid JSON (%s at character %lu)", what,
              (unsigned long)p->pos);
    return 0;
}

static void lopj_ws(lopj *p)
{
    while (p->pos < p->n) {
        char c = p->s[p->pos];
        if (c != ' ' && c != '\t' && c != '\n' && c != '\r')
            break;
        p->pos++;
    }
}

static int lopj_hex(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

static int lopj_u4(lopj *p, size_t at, uint32_t *cp)
{
    uint32_t v = 0;
    int k;
    if (at + 4 > p->n)
        return 0;
    for (k = 0; k < 4; k++) {
        int h = lopj_hex(p->s[at + k]);
        if (h < 0)
            return 0;
        v = v << 4 | (uint32_t)h;
    }
    *cp = v;
    return 1;
}

static void lopj_put(lopj *p, size_t *len, uint8_t byte)
{
    if (p->pool)
        p->pool[p->np + *len] = (char)byte;
    (*len)++;
}

/* The string at p->pos (its opening quote): decoded into the pool; offset and length out. */
static int lopj_string(lopj *p, uint32_t *off, uint32_t *out_len)
{
    size_t len = 0;
    p->pos++;
    for (;;) {
        unsigned char c;
        if (p->pos >= p->n)
            return lopj_fail(p, "unterminated string");
        c = (unsigned char)p->s[p->pos];
        if (c == '"') {
            p->pos++;
            break;
        }
        if (c < 0x20)
            return lopj_fail(p, "control character in a string");
        if (len + 4 > LOP_JSON_MAX_STRING)
            return lopj_fail(p, "string longer than the reader's bound");
        if (c != '\\') {
            lopj_put(p, &len, c);
            p->pos++;
            continue;
        }
        if (p->pos + 1 >= p->n)
            return lopj_fail(p, "unterminated escape");
        c = (unsigned char)p->s[p->pos + 1];
        p->pos += 2;
        switch (c) {
        case '"': case '\\': case '/': lopj_put(p, &len, c); break;
        case 'b': lopj_put(p, &len, 8); break;
        case 'f': lopj_put(p, &len, 12); break;
        case 'n': lopj_put(p, &len, 10); break;
        case 'r': lopj_put(p, &len, 13); break;
        case 't': lopj_put(p, &len, 9); break;
        case 'u': {
            uint32_t cp, lo;
            if (!lopj_u4(p, p->pos, &cp))
                return lopj_fail(p, "bad \\u escape");
            p->pos += 4;
            if (cp >= 0xD800 && cp <= 0xDBFF && p->pos + 6 <= p->n && p->s[p->pos] == '\\' &&
                p->s[p->pos + 1] == 'u' && lopj_u4(p, p->pos + 2, &lo) && lo >= 0xDC00 && lo <= 0xDFFF) {
                cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
                p->pos += 6;
            }
            if (cp < 0x80) {
                lopj_put(p, &len, (uint8_t)cp);
            } else if (cp < 0x800) {
                lopj_put(p, &len, (uint8_t)(0xC0 | cp >> 6));
                lopj_put(p, &len, (uint8_t)(0x80 | (cp & 0x3F)));
            } else if (cp < 0x10000) {
                lopj_put(p, &len, (uint8_t)(0xE0 | cp >> 12));
                lopj_put(p, &len, (uint8_t)(0x80 | ((cp >> 6) & 0x3F)));
                lopj_put(p, &len, (uint8_t)(0x80 | (cp & 0x3F)));
            } else {
                lopj_put(p, &len, (uint8_t)(0xF0 | cp >> 18));
                lopj_put(p, &len, (uint8_t)(0x80 | ((cp >> 12) & 0x3F)));
                lopj_put(p, &len, (uint8_t)(0x80 | ((cp >> 6) & 0x3F)));
                lopj_put(p, &len, (uint8_t)(0x80 | (cp & 0x3F)));
            }
            break;
        }
        default:
            return lopj_fail(p, "bad escape");
        }
    }
    *off = (uint32_t)p->np;
    *out_len = (uint32_t)len;
    p->np += len;
    return 1;
}

static int lopj_digit(char c) { return c >= '0' && c <= '9'; }

static int lopj_number(lopj *p, lopj_val *v)
{
    size_t start = p->pos, i = p->pos;
    int is_int = 1;
    if (i < p->n && p->s[i] == '-')
        i++;
    if (i >= p->n || !lopj_digit(p->s[i]))
        return lopj_fail(p, "bad number");
    if (p->s[i] == '0')
        i++;
    else
        while (i < p->n && lopj_digit(p->s[i]))
            i++;
    if (i < p->n && p->s[i] == '.' && i + 1 < p->n && lopj_digit(p->s[i + 1])) {
        is_int = 0;
        i++;
        while (i < p->n && lopj_digit(p->s[i]))
            i++;
    }
    if (i < p->n && (p->s[i] == 'e' || p->s[i] == 'E')) {
        size_t j = i + 1;
        if (j < p->n && (p->s[j] == '+' || p->s[j] == '-'))
            j++;
        if (j < p->n && lopj_digit(p->s[j])) {
            is_int = 0;
            i = j;
            while (i < p->n && lopj_digit(p->s[i]))
                i++;
        }
    }
    if (i - start > LOP_JSON_MAX_NUMBER)
        return lopj_fail(p, "number longer than the reader's bound");
    p->pos = i;
    if (v) {
        const char *s = p->s + start;
        size_t n = i - start;
        v->type = is_int ? LOPJ_INT : LOPJ_FLOAT;
        v->str = (uint32_t)start;
        v->len = (uint32_t)n;
        v->d = lop__decimal(s, n);
        if (is_int) {
            size_t k = s[0] == '-';
            uint64_t mag = 0, limit = s[0] == '-' ? (UINT64_C(1) << 63) : (UINT64_C(1) << 63) - 1;
            for (; k < n; k++) {
                unsigned dgt = (unsigned)(s[k] - '0');
                if (mag > (limit - dgt) / 10) {
                    v->big = 1;
                    break;
                }
                mag = mag * 10 + dgt;
            }
            if (v->big)
                v->i = s[0] == '-' ? -1 : 1;
            else
                v->i = s[0] == '-' ? (mag == (UINT64_C(1) << 63) ? INT64_MIN : -(int64_t)mag) : (int64_t)mag;
        }
    }
    return 1;
}

static int lopj_keycmp(const lopj *p, uint32_t a, uint32_t b)
{
    const lopj_val *x = &p->v[a], *y = &p->v[b];
    uint32_t n = x->key_len < y->key_len ? x->key_len : y->key_len;
    int c = memcmp(p->pool + x->key, p->pool + y->key, n);
    if (c)
        return c;
    return x->key_len < y->key_len ? -1 : x->key_len > y->key_len;
}

/* heap sort of an object's member indices by key (no recursion, no allocation) */
static void lopj_sift(const lopj *p, uint32_t *a, size_t root, size_t n)
{
    for (;;) {
        size_t child = 2 * root + 1;
        uint32_t t;
        if (child >= n)
            return;
        if (child + 1 < n && lopj_keycmp(p, a[child], a[child + 1]) < 0)
            child++;
        if (lopj_keycmp(p, a[root], a[child]) >= 0)
            return;
        t = a[root];
        a[root] = a[child];
        a[child] = t;
        root = child;
    }
}

static void lopj_sort(const lopj *p, uint32_t *a, size_t n)
{
    size_t i;
    for (i = n / 2; i-- > 0;)
        lopj_sift(p, a, i, n);
    for (i = n; i-- > 1;) {
        uint32_t t = a[0];
        a[0] = a[i];
        a[i] = t;
        lopj_sift(p, a, 0, i);
    }
}

static int lopj_value(lopj *p, uint32_t key, uint32_t key_len)
{
    uint32_t idx;
    lopj_val *v = NULL;
    char c;
    lopj_ws(p);
    if (p->pos >= p->n)
        return lopj_fail(p, "unexpected end");
    if (p->nv >= UINT32_MAX - 1)
        return lopj_fail(p, "too many values");
    idx = p->nv++;
    if (p->v) {
        v = &p->v[idx];
        memset(v, 0, sizeof *v);
        v->key = key;
        v->key_len = key_len;
    }
    c = p->s[p->pos];
    if (c == '{' || c == '[') {
        uint32_t count = 0;
        char close = c == '{' ? '}' : ']';
        if (++p->depth > LOP_JSON_MAX_DEPTH)
            return lop__fail0(p->err, lop_error_manifest_json, "manifest JSON is nested more than %d deep",
                              LOP_JSON_MAX_DEPTH);
        p->pos++;
        lopj_ws(p);
        if (p->pos < p->n && p->s[p->pos] == close) {
            p->pos++;
        } else {
            for (;;) {
                uint32_t k = 0, kl = UINT32_MAX;
                if (count >= LOP_JSON_MAX_ITEMS)
                    return lopj_fail(p, "more items than the reader's bound");
                if (close == '}') {
                    lopj_ws(p);
                    if (p->pos >= p->n || p->s[p->pos] != '"')
                        return lopj_fail(p, "expected a key");
                    if (!lopj_string(p, &k, &kl))
                        return 0;
                    lopj_ws(p);
                    if (p->pos >= p->n || p->s[p->pos] != ':')
                        return lopj_fail(p, "expected ':'");
                    p->pos++;
                }
                if (!lopj_value(p, k, kl))
                    return 0;
                count++;
                lopj_ws(p);
                if (p->pos < p->n && p->s[p->pos] == ',') {
                    p->pos++;
                    continue;
                }
                if (p->pos < p->n && p->s[p->pos] == close) {
                    p->pos++;
                    break;
                }
                return lopj_fail(p, close == '}' ? "expected ',' or '}'" : "expected ',' or ']'");
            }
        }
        p->depth--;
        if (p->v) {
            v = &p->v[idx];
            v->type = close == '}' ? LOPJ_OBJECT : LOPJ_ARRAY;
            v->count = count;
            v->next = p->nv;
            if (close == '}') {
                uint32_t child = idx + 1, k;
                uint32_t *m = p->members + p->nm;
                v->sorted = p->nm;
                for (k = 0; k < count; k++) {
                    m[k] = child;
                    child = p->v[child].next;
                }
                lopj_sort(p, m, count);
                for (k = 1; k < count; k++)
                    if (lopj_keycmp(p, m[k - 1], m[k]) == 0) {
                        const lopj_val *d = &p->v[m[k]];
                        return lop__fail0(p->err, lop_error_manifest_json,
                                         "manifest is not valid JSON (duplicate key \"%.*s\")",
                                         (int)(d->key_len > 60 ? 60 : d->key_len), p->pool + d->key);
                    }
            }
        }
        if (close == '}')
            p->nm += count;
        return 1;
    }
    if (c == '"') {
        uint32_t off, len;
        if (!lopj_string(p, &off, &len))
            return 0;
        if (v) {
            v->type = LOPJ_STRING;
            v->str = off;
            v->len = len;
            v->next = p->nv;
        }
        return 1;
    }
    if (c == '-' || lopj_digit(c)) {
        if (!lopj_number(p, v))
            return 0;
        if (v)
            v->next = p->nv;
        return 1;
    }
    {
        static const char *const words[3] = {"null", "false", "true"};
        int w;
        for (w = 0; w < 3; w++) {
            size_t len = strlen(words[w]);
            if (p->pos + len <= p->n && memcmp(p->s + p->pos, words[w], len) == 0) {
                p->pos += len;
                if (v) {
                    v->type = (uint8_t)(LOPJ_NULL + w);
                    v->next = p->nv;
                }
                return 1;
            }
        }
    }
    return lopj_fail(p, (c == 'N' || c == 'I') ? "NaN and Infinity are not JSON numbers" : "unexpected character");
}

/* Parse the whole manifest: 1 and the arrays in *out, or 0 with the error set. */
static int lopj_parse(const char *s, size_t n, const lop_allocator *mem, lop__err *err, lopj *out)
{
    lopj p;
    size_t i;
    for (i = 0; i < n; i++)
        if ((unsigned char)s[i] >= 0x80)
            return lop__fail0(err, lop_error_manifest_json,
                             "manifest is not ASCII (byte 0x%02x at %lu)", (unsigned)(unsigned char)s[i],
                             (unsigned long)i);
    memset(&p, 0, sizeof p);
    p.s = s;
    p.n = n;
    p.err = err;
    if (!lopj_value(&p, 0, UINT32_MAX))
        return 0;
    lopj_ws(&p);
    if (p.pos != n)
        return lopj_fail(&p, "extra data after the value");
    /* second pass into arrays of exactly the counted sizes */
    {
        uint32_t nv = p.nv, nm = p.nm;
        size_t np = p.np;
        memset(&p, 0, sizeof p);
        p.s = s;
        p.n = n;
        p.err = err;
        p.v = (lopj_val *)lop__alloc(mem, lop__mul(nv, sizeof(lopj_val)));
        p.pool = (char *)lop__alloc(mem, np + 1);
        p.members = (uint32_t *)lop__alloc(mem, lop__mul(nm + 1, sizeof(uint32_t)));
        if (!p.v || !p.pool || !p.members || !lop__mul(nv, sizeof(lopj_val))) {
            lop__free(mem, p.v);
            lop__free(mem, p.pool);
            lop__free(mem, p.members);
            return lop__fail0(err, lop_error_out_of_memory, "out of memory for a %lu-byte manifest",
                             (unsigned long)n);
        }
        if (!lopj_value(&p, 0, UINT32_MAX)) {
            lop__free(mem, p.v);
            lop__free(mem, p.pool);
            lop__free(mem, p.members);
            return 0;
        }
        *out = p;
    }
    return 1;
}

static void lopj_release(lopj *p, const lop_allocator *mem)
{
    lop__free(mem, p->v);
    lop__free(mem, p->pool);
    lop__free(mem, p->members);
    p->v = NULL;
    p->pool = NULL;
    p->members = NULL;
}

/* ---- JSON accessors ------------------------------------------------------------------------ */

#define LOPJ_NONE UINT32_MAX

/* Member `key` of object `obj`, or LOPJ_NONE (also when obj is not an object). */
static uint32_t lopj_get(const lopj *p, uint32_t obj, const char *key)
{
    const lopj_val *o;
    const uint32_t *m;
    size_t lo = 0, hi, kl = strlen(key);
    if (obj == LOPJ_NONE || p->v[obj].type != LOPJ_OBJECT)
        return LOPJ_NONE;
    o = &p->v[obj];
    m = p->members + o->sorted;
    hi = o->count;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        const lopj_val *x = &p->v[m[mid]];
        size_t n = x->key_len < kl ? x->key_len : kl;
        int c = memcmp(p->pool + x->key, key, n);
        if (c == 0)
            c = x->key_len < kl ? -1 : x->key_len > kl;
        if (c == 0)
            return m[mid];
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return LOPJ_NONE;
}

static int lopj_type(const lopj *p, uint32_t v) { return v == LOPJ_NONE ? -1 : p->v[v].type; }

static int lopj_is_str(const lopj *p, uint32_t v, const char *s)
{
    size_t n = strlen(s);
    return lopj_type(p, v) == LOPJ_STRING && p->v[v].len == n && memcmp(p->pool + p->v[v].str, s, n) == 0;
}

static int lopj_is_int(const lopj *p, uint32_t v) { return lopj_type(p, v) == LOPJ_INT; }

/* is_num of lopcook's validator: int or float (not bool), finite, |v| <= limit */
static int lopj_is_num(const lopj *p, uint32_t v, double limit)
{
    int t = lopj_type(p, v);
    double d;
    if (t != LOPJ_INT && t != LOPJ_FLOAT)
        return 0;
    d = p->v[v].d;
    return d - d == 0.0 && (d < 0 ? -d : d) <= limit;
}

/* An int in [lo, hi] (big ints are outside every such range). */
static int lopj_int_in(const lopj *p, uint32_t v, int64_t lo, int64_t hi)
{
    return lopj_is_int(p, v) && !p->v[v].big && p->v[v].i >= lo && p->v[v].i <= hi;
}

/* An int >= 0 (a big positive one included). */
static int lopj_nonneg(const lopj *p, uint32_t v)
{
    return lopj_is_int(p, v) && p->v[v].i >= 0;
}

/* The exact decimal digits of a double that is an integer, into buf (no sign); its length. */
static size_t lop__integer_digits(double d, char *buf, size_t cap)
{
    uint64_t u;
    int e;
    lop__big b;
    char tmp[400];
    size_t n = 0, k;
    memcpy(&u, &d, 8);
    e = (int)((u >> 52) & 0x7FF) - 1075;
    u = (u & ((UINT64_C(1) << 52) - 1)) | (UINT64_C(1) << 52);
    b.n = 2;
    b.w[0] = (uint32_t)u;
    b.w[1] = (uint32_t)(u >> 32);
    lop__big_trim(&b);
    if (e > 0)
        lop__big_shl(&b, e);
    while (b.n > 0 && n < sizeof tmp) {
        uint64_t r = 0;
        int i;
        for (i = b.n - 1; i >= 0; i--) {
            uint64_t cur = r << 32 | b.w[i];
            b.w[i] = (uint32_t)(cur / 10);
            r = cur % 10;
        }
        lop__big_trim(&b);
        tmp[n++] = (char)('0' + r);
    }
    if (n > cap)
        return 0;
    for (k = 0; k < n; k++)
        buf[k] = tmp[n - 1 - k];
    return n;
}

/* Python's == on numbers parsed from JSON (bool is 0 or 1; int and float compare exactly). */
static int lopj_num_eq(const lopj *p, uint32_t a, uint32_t b, const char *manifest)
{
    const lopj_val *x = &p->v[a], *y = &p->v[b];
    int tx = x->type, ty = y->type;
    if (tx == LOPJ_FALSE || tx == LOPJ_TRUE) {
        if (ty == LOPJ_FALSE || ty == LOPJ_TRUE)
            return tx == ty;
        return lopj_num_eq(p, b, a, manifest);
    }
    if (ty == LOPJ_FALSE || ty == LOPJ_TRUE) {
        double want = ty == LOPJ_TRUE ? 1.0 : 0.0;
        return tx == LOPJ_INT ? (!x->big && x->i == (int64_t)want) : x->d == want;
    }
    if (tx == LOPJ_FLOAT && ty == LOPJ_FLOAT)
        return x->d == y->d;
    if (tx == LOPJ_INT && ty == LOPJ_INT) {
        if (!x->big && !y->big)
            return x->i == y->i;
        if (x->big != y->big || x->i != y->i)
            return 0;
        { /* two big ints: compare their digits (tokens without sign; ints have no leading zeros) */
            const char *sx = manifest + x->str + (x->i < 0), *sy = manifest + y->str + (y->i < 0);
            size_t nx = x->len - (x->i < 0), ny = y->len - (y->i < 0);
            return nx == ny && memcmp(sx, sy, nx) == 0;
        }
    }
    { /* one int, one float */
        const lopj_val *in = tx == LOPJ_INT ? x : y, *fl = tx == LOPJ_INT ? y : x;
        double f = fl->d;
        if (!in->big)
            return f - f == 0.0 && f < 9223372036854775808.0 && f >= -9223372036854775808.0 &&
                   f == (double)in->i && (int64_t)f == in->i;
        if (f - f != 0.0 || (f >= 0) != (in->i > 0) || (f > -9223372036854775808.0 && f < 9223372036854775808.0))
            return 0;
        {
            char digits[400];
            size_t n = lop__integer_digits(f < 0 ? -f : f, digits, sizeof digits);
            size_t nd = in->len - (in->i < 0);
            return n == nd && memcmp(digits, manifest + in->str + (in->i < 0), n) == 0;
        }
    }
}

/* Python's == on the parsed values (dicts by key sets, lists elementwise, numbers as above);
   members named in `skip` (a NULL-terminated list, at the top level only) are left out. */
static int lopj_equal(const lopj *p, uint32_t a, uint32_t b, const char *manifest, const char *const *skip)
{
    const lopj_val *x = &p->v[a], *y = &p->v[b];
    int nx = x->type >= LOPJ_FALSE && x->type <= LOPJ_FLOAT, ny = y->type >= LOPJ_FALSE && y->type <= LOPJ_FLOAT;
    if (nx || ny)
        return nx && ny && lopj_num_eq(p, a, b, manifest);
    if (x->type != y->type)
        return 0;
    switch (x->type) {
    case LOPJ_NULL:
        return 1;
    case LOPJ_STRING:
        return x->len == y->len && memcmp(p->pool + x->str, p->pool + y->str, x->len) == 0;
    case LOPJ_ARRAY: {
        uint32_t i, ca = a + 1, cb = b + 1;
        if (x->count != y->count)
            return 0;
        for (i = 0; i < x->count; i++) {
            if (!lopj_equal(p, ca, cb, manifest, NULL))
                return 0;
            ca = p->v[ca].next;
            cb = p->v[cb].next;
        }
        return 1;
    }
    default: { /* objects: both member lists are sorted by key */
        const uint32_t *ma = p->members + x->sorted, *mb = p->members + y->sorted;
        uint32_t i = 0, j = 0;
        for (;;) {
            const char *const *s;
            int skip_a = 0, skip_b = 0;
            while (i < x->count) {
                skip_a = 0;
                for (s = skip; s && *s; s++)
                    if (p->v[ma[i]].key_len == strlen(*s) && memcmp(p->pool + p->v[ma[i]].key, *s, strlen(*s)) == 0)
                        skip_a = 1;
                if (!skip_a)
                    break;
                i++;
            }
            while (j < y->count) {
                skip_b = 0;
                for (s = skip; s && *s; s++)
                    if (p->v[mb[j]].key_len == strlen(*s) && memcmp(p->pool + p->v[mb[j]].key, *s, strlen(*s)) == 0)
                        skip_b = 1;
                if (!skip_b)
                    break;
                j++;
            }
            if (i == x->count || j == y->count)
                return i == x->count && j == y->count;
            if (lopj_keycmp(p, ma[i], mb[j]) != 0 || !lopj_equal(p, ma[i], mb[j], manifest, NULL))
                return 0;
            i++;
            j++;
        }
    }
    }
}

/* ---- small float helpers (no libm) ---------------------------------------------------------- */

/* sqrt to within an ulp (Newton from above), for the placement check's largest singular value
   and the Jacobi rotations; x >= 0 and finite. */
static double lop__sqrt(double x)
{
    double y, prev = 0.0;
    int i, e = 0;
    uint64_t u;
    if (!(x > 0.0))
        return 0.0;
    while (x < LOP__POW2(-600)) {
        x *= LOP__POW2(600);
        e -= 300;
    }
    while (x > LOP__POW2(600)) {
        x *= LOP__POW2(-600);
        e += 300;
    }
    memcpy(&u, &x, 8);
    u = (u >> 1) + (UINT64_C(0x3FF0000000000000) >> 1) + (UINT64_C(1) << 51); /* >= sqrt(x) */
    y = lop__from_bits(u);
    for (i = 0; i < 60; i++) {
        prev = y;
        y = 0.5 * (y + x / y);
        if (y >= prev)
            break;
    }
    y = prev < y ? prev : y;
    while (e > 0) {
        y *= LOP__POW2(300);
        e -= 300;
    }
    while (e < 0) {
        y *= LOP__POW2(-300);
        e += 300;
    }
    return y;
}

/* tan(x) for x in (0, pi/2), to about an ulp (series after reduction to [0, pi/4]). */
static double lop__tan(double x)
{
    static const double pio2_hi = 1.5707963267948966, pio2_lo = 6.123233995736766e-17;
    int flip = 0, k;
    double s, c, term, x2;
    if (x > 0.7853981633974483) {
        x = (pio2_hi - x) + pio2_lo;
        flip = 1;
    }
    x2 = x * x;
    s = x;
    term = x;
    for (k = 1; k < 14; k++) {
        term *= -x2 / ((2.0 * k) * (2.0 * k + 1.0));
        s += term;
    }
    c = 1.0;
    term = 1.0;
    for (k = 1; k < 14; k++) {
        term *= -x2 / ((2.0 * k - 1.0) * (2.0 * k));
        c += term;
    }
    return flip ? c / s : s / c;
}

/* Largest singular value of a 3 x 3 matrix (float64): sqrt of the largest eigenvalue of A^T A by
   cyclic Jacobi rotations. */
static double lop__sigma_max(const double a[9])
{
    double m[3][3];
    int i, j, k, sweep;
    for (i = 0; i < 3; i++)
        for (j = 0; j < 3; j++) {
            double s = 0.0;
            for (k = 0; k < 3; k++)
                s += a[3 * k + i] * a[3 * k + j];
            m[i][j] = s;
        }
    for (sweep = 0; sweep < 50; sweep++) {
        double off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
        double diag = m[0][0] * m[0][0] + m[1][1] * m[1][1] + m[2][2] * m[2][2];
        if (!(off > diag * 1e-40))
            break;
        for (i = 0; i < 2; i++)
            for (j = i + 1; j < 3; j++) {
                double theta, t, c, s, apq = m[i][j];
                if (apq == 0.0)
                    continue;
                theta = (m[j][j] - m[i][i]) / (2.0 * apq);
                if (theta > 1e150 || theta < -1e150)
                    t = 0.5 / theta;
                else
                    t = (theta >= 0 ? 1.0 : -1.0) / ((theta >= 0 ? theta : -theta) + lop__sqrt(theta * theta + 1.0));
                c = 1.0 / lop__sqrt(t * t + 1.0);
                s = t * c;
                for (k = 0; k < 3; k++) { /* M <- M R (columns i, j) */
                    double mki = m[k][i], mkj = m[k][j];
                    m[k][i] = c * mki - s * mkj;
                    m[k][j] = s * mki + c * mkj;
                }
                for (k = 0; k < 3; k++) { /* M <- R^T M (rows i, j) */
                    double mik = m[i][k], mjk = m[j][k];
                    m[i][k] = c * mik - s * mjk;
                    m[j][k] = s * mik + c * mjk;
                }
            }
    }
    {
        double l = m[0][0];
        if (m[1][1] > l)
            l = m[1][1];
        if (m[2][2] > l)
            l = m[2][2];
        return lop__sqrt(l);
    }
}

/* x * 2^e, exact unless it overflows or underflows */
static double lop__ldexp(double x, int e)
{
    while (e > 1000) {
        x *= LOP__POW2(1000);
        e -= 1000;
    }
    while (e < -1000) {
        x *= LOP__POW2(-1000);
        e += 1000;
    }
    return x * lop__from_bits((uint64_t)(e + 1023) << 52);
}

/* lopcook.lop.placement.level_shift: the smallest integer s with 2^s w >= sig * mesh_extent.
   0 with *ok = 0 when the inputs are not positive and finite. */
static int lop__level_shift(double sig, double mesh_extent, double world_extent, int *ok)
{
    double r = sig * mesh_extent, w = world_extent;
    uint64_t ur, uw;
    int s;
    *ok = r > 0 && w > 0 && r - r == 0.0 && w - w == 0.0;
    if (!*ok)
        return 0;
    memcpy(&ur, &r, 8);
    memcpy(&uw, &w, 8);
    s = (int)((ur >> 52) & 0x7FF) - (int)((uw >> 52) & 0x7FF) + 1;
    while (lop__ldexp(w, s - 1) >= r)
        s--;
    while (lop__ldexp(w, s) < r)
        s++;
    return s;
}

/* ---- the manifest validator (lopcook.lop.manifest.validate_manifest, in its order) ---------- */

enum { LOPV_INT, LOPV_NUM, LOPV_STR, LOPV_OBJ, LOPV_ARR };

typedef struct lopv {
    lopj *j;
    const char *text;         /* the manifest bytes */
    lop__err *err;
    lop_file *f;
    uint32_t *names;          /* section indices sorted by name */
    uint32_t *name_val;       /* section i -> its "name" string value */
    char *strings;            /* next free byte of the file's string block */
    lop_lod *lods;            /* next free LOD slot */
    size_t lods_left;         /* LOD slots left */
    uint32_t *part_node;      /* part i -> its JSON value (placements look up their owner in O(1)) */
    uint32_t parts_cap;       /* part slots */
    int clustered, has_placements, has_tangents, has_encoded;
    lop_result klass;         /* the class lopv_fail reports: manifest, or section_table */
    struct lopv_tot *tot;     /* per stage: what its buffers add up to */
    uint32_t *stage_start;    /* stage s's buffers are order[stage_start[s] .. stage_start[s + 1]) */
    uint32_t *order;          /* (part, lod) of every stored buffer, grouped by stage, manifest order */
    const lop_lod **sec_first, **sec_last; /* section -> the first and last LOD naming it as indices */
    uint8_t *sec_other;       /* section -> named as attributes or a hierarchy */
} lopv;

/* What the stored buffers of one stage add up to (one stage in the default layout): mandatory
   words, cluster header words, clustered buffers, bits of each plane. */
typedef struct lopv_tot {
    uint64_t words, headers;
    uint32_t clustered, buffers;
    uint64_t plane_bits[LOP_LEVELS + 1];
} lopv_tot;

static int lopv_fail(lopv *v, const char *fmt, ...)
{
    if (v->err->code == lop_success) {
        v->err->code = v->klass;
        if (v->err->msg) {
            va_list ap;
            int n = snprintf(v->err->msg->text, sizeof v->err->msg->text, "manifest: ");
            va_start(ap, fmt);
            vsnprintf(v->err->msg->text + n, sizeof v->err->msg->text - (size_t)n, fmt, ap);
            va_end(ap);
        }
    }
    return 0;
}

/* need() of the validator: member `key` of `obj` with the given kind, else the error. */
static uint32_t lopv_need(lopv *v, uint32_t obj, const char *key, int kind, const char *where)
{
    uint32_t m = lopj_get(v->j, obj, key);
    int t;
    if (m == LOPJ_NONE) {
        lopv_fail(v, "%s: missing '%s'", where, key);
        return LOPJ_NONE;
    }
    t = lopj_type(v->j, m);
    if (kind == LOPV_INT && t != LOPJ_INT) {
        lopv_fail(v, "%s.%s must be an integer", where, key);
        return LOPJ_NONE;
    }
    if (kind == LOPV_NUM && !lopj_is_num(v->j, m, LOP__F32_MAX)) {
        lopv_fail(v, "%s.%s must be a finite number within the float32 range", where, key);
        return LOPJ_NONE;
    }
    if ((kind == LOPV_STR && t != LOPJ_STRING) || (kind == LOPV_OBJ && t != LOPJ_OBJECT) ||
        (kind == LOPV_ARR && t != LOPJ_ARRAY)) {
        lopv_fail(v, "%s.%s has the wrong type", where, key);
        return LOPJ_NONE;
    }
    return m;
}

/* count() of the validator: an integer >= minimum. */
static int lopv_count(lopv *v, uint32_t obj, const char *key, const char *where, int64_t minimum, int64_t *out)
{
    uint32_t m = lopv_need(v, obj, key, LOPV_INT, where);
    if (m == LOPJ_NONE)
        return 0;
    if (v->j->v[m].i < minimum)
        return lopv_fail(v, "%s.%s is %s, expected at least %ld", where, key,
                         v->j->v[m].big ? "very negative" : "below the minimum", (long)minimum);
    if (out)
        *out = v->j->v[m].big ? INT64_MAX : v->j->v[m].i;
    return 1;
}

static double lopv_d(const lopv *v, uint32_t m) { return v->j->v[m].d; }

/* The section index named by string value m, or -1. */
static int32_t lopv_section(const lopv *v, uint32_t m)
{
    const lopj_val *s = &v->j->v[m];
    size_t lo = 0, hi = v->f->section_count;
    if (s->type != LOPJ_STRING)
        return -1;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        const lopj_val *x = &v->j->v[v->name_val[v->names[mid]]];
        size_t n = x->len < s->len ? x->len : s->len;
        int c = memcmp(v->j->pool + x->str, v->j->pool + s->str, n);
        if (c == 0)
            c = x->len < s->len ? -1 : x->len > s->len;
        if (c == 0)
            return (int32_t)v->names[mid];
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return -1;
}

/* A NUL-terminated copy of string value m in the file's string block. */
static const char *lopv_copy(lopv *v, uint32_t m)
{
    char *out = v->strings;
    const lopj_val *s = &v->j->v[m];
    memcpy(out, v->j->pool + s->str, s->len);
    out[s->len] = 0;
    v->strings += s->len + 1;
    return out;
}

static int lopv_namecmp(const lopv *v, uint32_t a, uint32_t b)
{
    const lopj_val *x = &v->j->v[v->name_val[a]], *y = &v->j->v[v->name_val[b]];
    size_t n = x->len < y->len ? x->len : y->len;
    int c = memcmp(v->j->pool + x->str, v->j->pool + y->str, n);
    if (c)
        return c;
    return x->len < y->len ? -1 : x->len > y->len;
}

static void lopv_sort_names(lopv *v, uint32_t *a, size_t n)
{
    size_t i, root, child, end;
    for (i = n / 2; i-- > 0;)
        for (root = i; (child = 2 * root + 1) < n; root = child) {
            uint32_t t;
            if (child + 1 < n && lopv_namecmp(v, a[child], a[child + 1]) < 0)
                child++;
            if (lopv_namecmp(v, a[root], a[child]) >= 0)
                break;
            t = a[root];
            a[root] = a[child];
            a[child] = t;
        }
    for (end = n; end-- > 1;) {
        uint32_t t = a[0];
        a[0] = a[end];
        a[end] = t;
        for (root = 0; (child = 2 * root + 1) < end; root = child) {
            if (child + 1 < end && lopv_namecmp(v, a[child], a[child + 1]) < 0)
                child++;
            if (lopv_namecmp(v, a[root], a[child]) >= 0)
                break;
            t = a[root];
            a[root] = a[child];
            a[child] = t;
        }
    }
}

static int lopv_informative(lopv *v, uint32_t m)
{
    uint32_t src, viewing, vp, fov, pe, opt, stats, hist, sav, x;
    uint32_t k;
    if (lopv_need(v, m, "generator", LOPV_STR, "manifest") == LOPJ_NONE)
        return 0;
    if ((src = lopv_need(v, m, "source", LOPV_OBJ, "manifest")) == LOPJ_NONE ||
        lopv_need(v, src, "file", LOPV_STR, "source") == LOPJ_NONE ||
        lopv_need(v, src, "format", LOPV_STR, "source") == LOPJ_NONE)
        return 0;
    if ((viewing = lopv_need(v, m, "viewing", LOPV_OBJ, "manifest")) == LOPJ_NONE ||
        (vp = lopv_need(v, viewing, "viewport", LOPV_ARR, "viewing")) == LOPJ_NONE)
        return 0;
    for (k = 0, x = vp + 1; k < 2; k++, x = v->j->v[x].next) {
        /* positive integers (big ones too: only their sign matters to lopcook's validator) */
        if (v->j->v[vp].count != 2 || !lopj_is_int(v->j, x) || v->j->v[x].i <= 0)
            return lopv_fail(v, "viewing.viewport must be two positive integers");
        v->f->viewport[k] = v->j->v[x].big || v->j->v[x].i > (int64_t)UINT32_MAX ? UINT32_MAX : (uint32_t)v->j->v[x].i;
    }
    if ((fov = lopv_need(v, viewing, "fov_y_deg", LOPV_NUM, "viewing")) == LOPJ_NONE)
        return 0;
    if (!(lopv_d(v, fov) > 0 && lopv_d(v, fov) < 180))
        return lopv_fail(v, "viewing.fov_y_deg must be in (0, 180)");
    if ((pe = lopv_need(v, viewing, "pixel_error", LOPV_NUM, "viewing")) == LOPJ_NONE)
        return 0;
    if (!(lopv_d(v, pe) > 0))
        return lopv_fail(v, "viewing.pixel_error must be > 0");
    v->f->fov_y_deg = lopv_d(v, fov);
    v->f->pixel_error = lopv_d(v, pe);
    x = lopj_get(v->j, viewing, "nearest_m");
    v->f->nearest_m = -1.0;
    if (x != LOPJ_NONE && lopj_type(v->j, x) != LOPJ_NULL) {
        if (!lopj_is_num(v->j, x, LOP__F32_MAX) || !(lopv_d(v, x) > 0))
            return lopv_fail(v, "viewing.nearest_m must be a positive number or null");
        v->f->nearest_m = lopv_d(v, x);
    }
    if ((opt = lopv_need(v, m, "options", LOPV_OBJ, "manifest")) == LOPJ_NONE)
        return 0;
    {
        static const char *const keys[2] = {"analyse", "ingest"};
        for (k = 0; k < 2; k++) {
            x = lopj_get(v->j, opt, keys[k]);
            if (x != LOPJ_NONE && lopj_type(v->j, x) != LOPJ_OBJECT)
                return lopv_fail(v, "options.%s must be an object", keys[k]);
        }
    }
    if ((stats = lopv_need(v, m, "stats", LOPV_OBJ, "manifest")) == LOPJ_NONE ||
        !lopv_count(v, stats, "vertices", "stats", 0, NULL) || !lopv_count(v, stats, "triangles", "stats", 0, NULL) ||
        !lopv_count(v, stats, "float32_position_bytes", "stats", 0, NULL) ||
        (hist = lopv_need(v, stats, "histogram", LOPV_ARR, "stats")) == LOPJ_NONE)
        return 0;
    if (v->j->v[hist].count != LOP_LEVELS + 1)
        return lopv_fail(v, "stats.histogram must be 25 counts");
    for (k = 0, x = hist + 1; k < LOP_LEVELS + 1; k++, x = v->j->v[x].next)
        if (!lopj_nonneg(v->j, x))
            return lopv_fail(v, "stats.histogram must be 25 counts");
    sav = lopj_get(v->j, m, "savings");
    if (sav != LOPJ_NONE && lopj_type(v->j, sav) != LOPJ_NULL) {
        if (lopj_type(v->j, sav) != LOPJ_OBJECT)
            return lopv_fail(v, "savings must be an object or null");
        if (!lopv_count(v, sav, "bytes_saved", "savings", 0, NULL) ||
            lopv_need(v, sav, "planes_dropped", LOPV_ARR, "savings") == LOPJ_NONE ||
            !lopv_count(v, sav, "lods_dropped", "savings", 0, NULL))
            return 0;
    }
    x = lopv_need(v, m, "generator", LOPV_STR, "manifest");
    v->f->generator = lopv_copy(v, x);
    return 1;
}

/* An encoded section's `encoding` and `size` (format.md 15): both or neither, a known encoding,
   size a multiple of 4 and, for deflate, at most 1032 times the stored length (class section_table). */
static int lopv_encoded(lopv *v, uint32_t s, lop_section *sec)
{
    uint32_t enc, size;
    char where[96];
    if (lopj_get(v->j, s, "encoding") == LOPJ_NONE && lopj_get(v->j, s, "size") == LOPJ_NONE)
        return 1;
    snprintf(where, sizeof where, "section '%.60s'", sec->name);
    if ((enc = lopv_need(v, s, "encoding", LOPV_STR, where)) == LOPJ_NONE ||
        (size = lopv_need(v, s, "size", LOPV_INT, where)) == LOPJ_NONE)
        return 0;
    if (v->j->v[size].i < 0)
        return lopv_fail(v, "%s.size is below the minimum, expected at least 0", where);
    if (lopj_is_str(v->j, enc, "deflate"))
        sec->encoding = LOP_ENCODING_DEFLATE;
    else if (lopj_is_str(v->j, enc, "meshopt-deflate"))
        sec->encoding = LOP_ENCODING_MESHOPT;
    else
        return lopv_fail(v, "%s has an unknown encoding (known: deflate, meshopt-deflate)", where);
    if (v->j->v[size].big) /* a size past int64: no stream decodes to it */
        return lopv_fail(v, "%s claims more decoded bytes than %u times its stored bytes", where,
                         LOP__DEFLATE_MAX_RATIO);
    sec->size = (uint64_t)v->j->v[size].i;
    if (sec->size % 4)
        return lopv_fail(v, "%s size is not a multiple of 4", where);
    if (sec->encoding == LOP_ENCODING_DEFLATE && sec->length <= UINT64_MAX / LOP__DEFLATE_MAX_RATIO &&
        sec->size > LOP__DEFLATE_MAX_RATIO * sec->length)
        return lopv_fail(v, "%s claims %llu decoded bytes, more than %u times its %llu stored bytes", where,
                         (unsigned long long)sec->size, LOP__DEFLATE_MAX_RATIO, (unsigned long long)sec->length);
    v->has_encoded = 1;
    return 1;
}

/* The section table: back to back, lengths multiples of 4, names unique (class section_table). */
static int lopv_sections(lopv *v, uint32_t m)
{
    uint32_t secs, s, i;
    uint64_t offset = 0;
    char where[48];
    lop_file *f = v->f;
    secs = lopv_need(v, m, "sections", LOPV_ARR, "manifest");
    if (secs == LOPJ_NONE)
        return 0;
    for (i = 0, s = secs + 1; i < v->j->v[secs].count; i++, s = v->j->v[s].next) {
        uint32_t name;
        int64_t off = 0, len = 0, crc = 0;
        snprintf(where, sizeof where, "sections[%u]", (unsigned)i);
        if ((name = lopv_need(v, s, "name", LOPV_STR, where)) == LOPJ_NONE ||
            !lopv_count(v, s, "offset", where, 0, &off) || !lopv_count(v, s, "length", where, 0, &len) ||
            !lopv_count(v, s, "crc32", where, 0, &crc))
            return 0;
        if (len == INT64_MAX) /* a length past int64: no file has it */
            return lopv_fail(v, "section '%s' length is not a byte count", v->j->pool + v->j->v[name].str);
        v->name_val[i] = name;
        memset(&f->sections[i], 0, sizeof f->sections[i]);
        f->sections[i].name = lopv_copy(v, name);
        if (len % 4)
            return lopv_fail(v, "section '%s' length is not a multiple of 4", f->sections[i].name);
        if ((uint64_t)off != offset)
            return lopv_fail(v, "section '%s' starts at %lld, not where the previous one ends (%llu)",
                             f->sections[i].name, (long long)off, (unsigned long long)offset);
        if (crc > (int64_t)0xFFFFFFFF)
            return lopv_fail(v, "section '%s' crc32 is not a 32-bit value", f->sections[i].name);
        f->sections[i].offset = offset;
        f->sections[i].length = (uint64_t)len;
        f->sections[i].size = (uint64_t)len;
        f->sections[i].crc32 = (uint32_t)crc;
        if (!lopv_encoded(v, s, &f->sections[i]))
            return 0;
        offset = lop__sat_add(offset, (uint64_t)len);
        v->names[i] = i;
    }
    f->section_count = v->j->v[secs].count;
    lopv_sort_names(v, v->names, f->section_count);
    for (i = 1; i < f->section_count; i++)
        if (lopv_namecmp(v, v->names[i - 1], v->names[i]) == 0)
            return lopv_fail(v, "section '%s' appears twice", f->sections[v->names[i]].name);
    return 1;
}

static int lopv_grid(lopv *v, uint32_t m)
{
    uint32_t grid, origin, ext, bits, x;
    int k;
    double reach = 0.0;
    if ((grid = lopv_need(v, m, "grid", LOPV_OBJ, "manifest")) == LOPJ_NONE ||
        (origin = lopv_need(v, grid, "origin", LOPV_ARR, "grid")) == LOPJ_NONE)
        return 0;
    if (v->j->v[origin].count != 3)
        return lopv_fail(v, "grid.origin must be 3 finite numbers within the float32 range");
    for (k = 0, x = origin + 1; k < 3; k++, x = v->j->v[x].next) {
        if (!lopj_is_num(v->j, x, LOP__F32_MAX))
            return lopv_fail(v, "grid.origin must be 3 finite numbers within the float32 range");
        v->f->grid_origin[k] = lopv_d(v, x);
        if ((lopv_d(v, x) < 0 ? -lopv_d(v, x) : lopv_d(v, x)) > reach)
            reach = lopv_d(v, x) < 0 ? -lopv_d(v, x) : lopv_d(v, x);
    }
    if ((ext = lopv_need(v, grid, "extent", LOPV_NUM, "grid")) == LOPJ_NONE)
        return 0;
    if (!(lopv_d(v, ext) > 0))
        return lopv_fail(v, "grid.extent must be > 0 and grid.bits 24");
    if ((bits = lopv_need(v, grid, "bits", LOPV_INT, "grid")) == LOPJ_NONE)
        return 0;
    if (!lopj_int_in(v->j, bits, LOP_LEVELS, LOP_LEVELS))
        return lopv_fail(v, "grid.extent must be > 0 and grid.bits 24");
    if (lopv_d(v, ext) < LOP__MIN_EXTENT)
        return lopv_fail(v, "grid.extent %g is below the 2^-75 m floor lopcook cooks with", lopv_d(v, ext));
    if (reach + lopv_d(v, ext) > LOP__MAX_REACH)
        return lopv_fail(v, "grid origin + extent reaches beyond 2^102 m");
    v->f->grid_extent = lopv_d(v, ext);
    return 1;
}

/* The streaming layout's positions (format.md 14.2): `stages` a non-empty list of {"level": L},
   1 <= L <= max_level, and none of the default layout's section names. */
static int lopv_stages(lopv *v, uint32_t pos)
{
    static const char *const keys[3] = {"mandatory", "planes", "clusters"};
    lop_file *f = v->f;
    uint32_t stages, st, s;
    int k;
    for (k = 0; k < 3; k++)
        if (lopj_get(v->j, pos, keys[k]) != LOPJ_NONE)
            return lopv_fail(v, "positions.%s must not be given with positions.stages (the streaming layout)",
                             keys[k]);
    if ((stages = lopv_need(v, pos, "stages", LOPV_ARR, "positions")) == LOPJ_NONE)
        return 0;
    if (v->j->v[stages].count == 0)
        return lopv_fail(v, "positions.stages is empty");
    for (s = 0, st = stages + 1; s < v->j->v[stages].count; s++, st = v->j->v[st].next) {
        uint32_t x;
        char where[48];
        if (lopj_type(v->j, st) != LOPJ_OBJECT || v->j->v[st].count != 1 || lopj_get(v->j, st, "level") == LOPJ_NONE)
            return lopv_fail(v, "positions.stages[%u] must hold exactly level", (unsigned)s);
        snprintf(where, sizeof where, "positions.stages[%u]", (unsigned)s);
        if ((x = lopv_need(v, st, "level", LOPV_INT, where)) == LOPJ_NONE)
            return 0;
        if (!lopj_int_in(v->j, x, 1, f->max_level))
            return lopv_fail(v, "positions.stages[%u].level must be in [1, %d]", (unsigned)s, f->max_level);
        memset(&f->stages[s], 0, sizeof f->stages[s]);
        f->stages[s].level = (int)v->j->v[x].i;
    }
    f->stream = 1;
    f->stage_count = v->j->v[stages].count;
    return 1;
}

static int lopv_positions(lopv *v, uint32_t m, uint32_t *planes_out)
{
    uint32_t pos, ml, mand, planes, clus;
    int p, tail = 0;
    int32_t want[LOP_LEVELS + 2];
    char key[16];
    lop_file *f = v->f;
    if ((pos = lopv_need(v, m, "positions", LOPV_OBJ, "manifest")) == LOPJ_NONE ||
        (ml = lopv_need(v, pos, "max_level", LOPV_INT, "positions")) == LOPJ_NONE)
        return 0;
    if (!lopj_int_in(v->j, ml, 1, LOP_LEVELS))
        return lopv_fail(v, "positions.max_level must be in [1, 24]");
    f->max_level = (int)v->j->v[ml].i;
    for (p = 0; p <= LOP_LEVELS; p++)
        f->plane_section[p] = -1;
    f->mandatory_section = f->clusters_section = -1;
    if (lopj_get(v->j, pos, "stages") != LOPJ_NONE) {
        *planes_out = LOPJ_NONE;
        return lopv_stages(v, pos);
    }
    f->stage_count = 1;
    if ((mand = lopv_need(v, pos, "mandatory", LOPV_STR, "positions")) == LOPJ_NONE)
        return 0;
    if ((f->mandatory_section = lopv_section(v, mand)) < 0)
        return lopv_fail(v, "positions.mandatory names no section");
    if ((planes = lopv_need(v, pos, "planes", LOPV_OBJ, "positions")) == LOPJ_NONE)
        return 0;
    for (p = 2; p <= f->max_level; p++) {
        uint32_t x;
        snprintf(key, sizeof key, "%d", p);
        x = lopj_get(v->j, planes, key);
        if (x == LOPJ_NONE || lopj_type(v->j, x) != LOPJ_STRING || (f->plane_section[p] = lopv_section(v, x)) < 0)
            return lopv_fail(v, "positions.planes[%d] names no section", p);
    }
    v->clustered = lopj_get(v->j, pos, "clusters") != LOPJ_NONE;
    f->clusters_section = -1;
    if (v->clustered) {
        if ((clus = lopv_need(v, pos, "clusters", LOPV_STR, "positions")) == LOPJ_NONE)
            return 0;
        if ((f->clusters_section = lopv_section(v, clus)) < 0)
            return lopv_fail(v, "positions.clusters names no section");
        want[tail++] = f->clusters_section;
    }
    want[tail++] = f->mandatory_section;
    for (p = 2; p <= f->max_level; p++)
        want[tail++] = f->plane_section[p];
    if ((uint32_t)tail > f->section_count)
        return lopv_fail(v, "position sections are not last and in level order");
    for (p = 0; p < tail; p++)
        if (want[p] != (int32_t)(f->section_count - (uint32_t)tail + (uint32_t)p))
            return lopv_fail(v, "position sections are not last and in level order");
    *planes_out = planes;
    return 1;
}

/* check_bits: attribute_bits of a LOD into e; its object value in *ab. */
static int lopv_bits(lopv *v, uint32_t lod, const char *where, lop_lod *e, uint32_t *ab_out)
{
    static const char *const names[4] = {"normals", "uvs", "colors", "tangents"};
    static const int lo[4] = {4, 6, 4, 4}, hi[4] = {16, 16, 8, 16};
    int bits[4] = {0, 0, 0, 0}, k;
    uint32_t ab = lopv_need(v, lod, "attribute_bits", LOPV_OBJ, where);
    if (ab == LOPJ_NONE)
        return 0;
    {
        int has_t = lopj_get(v->j, ab, "tangents") != LOPJ_NONE;
        if (v->j->v[ab].count != 3u + (unsigned)has_t || lopj_get(v->j, ab, "normals") == LOPJ_NONE ||
            lopj_get(v->j, ab, "uvs") == LOPJ_NONE || lopj_get(v->j, ab, "colors") == LOPJ_NONE)
            return lopv_fail(v, "%s.attribute_bits must hold exactly normals, uvs, colors%s", where,
                             " (and tangents where a part has them)");
        if (has_t)
            v->has_tangents = 1;
    }
    for (k = 0; k < 4; k++) {
        uint32_t x = lopj_get(v->j, ab, names[k]);
        if (x == LOPJ_NONE)
            continue;
        if (k < 3 && lopj_type(v->j, x) == LOPJ_NULL)
            continue;
        if (!lopj_int_in(v->j, x, lo[k], hi[k]))
            return lopv_fail(v, "%s.attribute_bits.%s must be %san integer in [%d, %d]", where, names[k],
                             k < 3 ? "null or " : "", lo[k], hi[k]);
        bits[k] = (int)v->j->v[x].i;
    }
    e->normal_bits = bits[0];
    e->uv_bits = bits[1];
    e->color_bits = bits[2];
    e->tangent_bits = bits[3];
    e->record_bits = (uint32_t)(2 * bits[0] + 2 * bits[1] + 4 * bits[2] + (bits[3] ? 2 * bits[3] + 1 : 0));
    *ab_out = ab;
    return 1;
}

/* The part's attribute_bits equal (Python ==) the bits of its LODs. */
static int lopv_part_bits(lopv *v, uint32_t pb, const lop_lod *e)
{
    static const char *const names[4] = {"normals", "uvs", "colors", "tangents"};
    int bits[4], k, expect = 3 + (e->tangent_bits != 0);
    bits[0] = e->normal_bits;
    bits[1] = e->uv_bits;
    bits[2] = e->color_bits;
    bits[3] = e->tangent_bits;
    if (v->j->v[pb].count != (uint32_t)expect)
        return 0;
    for (k = 0; k < 4; k++) {
        uint32_t x = lopj_get(v->j, pb, names[k]);
        int t = lopj_type(v->j, x);
        if (k == 3 && !bits[3])
            continue;
        if (x == LOPJ_NONE)
            return 0;
        if (!bits[k]) {
            if (t != LOPJ_NULL)
                return 0;
        } else if (!((t == LOPJ_INT && !v->j->v[x].big && v->j->v[x].i == bits[k]) ||
                     (t == LOPJ_FLOAT && v->j->v[x].d == (double)bits[k]))) {
            return 0;
        }
    }
    return 1;
}

/* _check_placement: returns 1 and sets *shared_of (-1: the part owns its buffers). */
static int lopv_placement(lopv *v, uint32_t parts, uint32_t i, uint32_t part, lop_part *pt, int32_t *shared_of)
{
    uint32_t rec = lopj_get(v->j, part, "placement"), g, of, tf, go, ge, ls, owner, orec, ofv, x;
    double a[9], reach = 0.0, det, sig;
    int k, ok, shift;
    *shared_of = -1;
    if (rec != LOPJ_NONE)
        v->has_placements = 1;
    if (rec == LOPJ_NONE || lopj_type(v->j, rec) == LOPJ_NULL) {
        g = lopj_get(v->j, part, "grid");
        if (g != LOPJ_NONE && lopj_type(v->j, g) != LOPJ_NULL)
            return lopv_fail(v, "parts[%u].grid is only allowed with a placement", (unsigned)i);
        return 1;
    }
    if (lopj_type(v->j, rec) != LOPJ_OBJECT || v->j->v[rec].count != 3 || lopj_get(v->j, rec, "of") == LOPJ_NONE ||
        lopj_get(v->j, rec, "transform") == LOPJ_NONE || lopj_get(v->j, rec, "level_shift") == LOPJ_NONE)
        return lopv_fail(v, "parts[%u].placement must hold exactly of, transform, level_shift", (unsigned)i);
    of = lopj_get(v->j, rec, "of");
    if (!lopj_int_in(v->j, of, 0, (int64_t)i))
        return lopv_fail(v, "parts[%u].placement.of must be the index of this or an earlier part", (unsigned)i);
    tf = lopj_get(v->j, rec, "transform");
    if (lopj_type(v->j, tf) != LOPJ_ARRAY || v->j->v[tf].count != 12)
        return lopv_fail(v, "parts[%u].placement.transform must be 12 finite float32 numbers (3 x 4, row-major)",
                         (unsigned)i);
    for (k = 0, x = tf + 1; k < 12; k++, x = v->j->v[x].next) {
        if (!lopj_is_num(v->j, x, LOP__F32_MAX))
            return lopv_fail(v, "parts[%u].placement.transform must be 12 finite float32 numbers (3 x 4, row-major)",
                             (unsigned)i);
        pt->transform[k] = (float)lopv_d(v, x);
    }
    for (k = 0; k < 9; k++)
        a[k] = (double)pt->transform[4 * (k / 3) + k % 3];
    det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6]);
    if (!(det > 0 || det < 0))
        return lopv_fail(v, "parts[%u].placement.transform is singular", (unsigned)i);
    g = lopj_get(v->j, part, "grid");
    if (lopj_type(v->j, g) != LOPJ_OBJECT || v->j->v[g].count != 2 || lopj_get(v->j, g, "origin") == LOPJ_NONE ||
        lopj_get(v->j, g, "extent") == LOPJ_NONE)
        return lopv_fail(v, "parts[%u].grid must hold exactly origin and extent", (unsigned)i);
    go = lopj_get(v->j, g, "origin");
    if (lopj_type(v->j, go) != LOPJ_ARRAY || v->j->v[go].count != 3)
        return lopv_fail(v, "parts[%u].grid.origin must be 3 finite numbers within the float32 range", (unsigned)i);
    for (k = 0, x = go + 1; k < 3; k++, x = v->j->v[x].next) {
        double d;
        if (!lopj_is_num(v->j, x, LOP__F32_MAX))
            return lopv_fail(v, "parts[%u].grid.origin must be 3 finite numbers within the float32 range", (unsigned)i);
        d = lopv_d(v, x);
        pt->grid_origin[k] = d;
        if ((d < 0 ? -d : d) > reach)
            reach = d < 0 ? -d : d;
    }
    ge = lopj_get(v->j, g, "extent");
    if (!lopj_is_num(v->j, ge, LOP__F32_MAX) || !(lopv_d(v, ge) >= LOP__MIN_EXTENT) ||
        !(reach + lopv_d(v, ge) <= LOP__MAX_REACH))
        return lopv_fail(v, "parts[%u].grid.extent must be at least 2^-75 m and within 2^102 m", (unsigned)i);
    pt->grid_extent = lopv_d(v, ge);
    sig = lop__sigma_max(a) * (1.0 + 1e-9);
    shift = lop__level_shift(sig, pt->grid_extent, v->f->grid_extent, &ok);
    if (!ok)
        return lopv_fail(v, "parts[%u]: placement scale or extents are not positive and finite", (unsigned)i);
    ls = lopj_get(v->j, rec, "level_shift");
    if (!lopj_int_in(v->j, ls, shift, shift))
        return lopv_fail(v, "parts[%u].placement.level_shift is not ceil(log2(sigma E_m / E_w)) of its transform "
                         "and grids", (unsigned)i);
    pt->level_shift = shift;
    pt->is_placement = 1;
    ofv = (uint32_t)v->j->v[of].i;
    owner = v->part_node[ofv];
    (void)parts;
    orec = lopj_get(v->j, owner, "placement");
    x = lopj_get(v->j, orec, "of");
    if (lopj_type(v->j, orec) != LOPJ_OBJECT || x == LOPJ_NONE || !lopj_equal(v->j, x, of, v->text, NULL))
        return lopv_fail(v, "parts[%u].placement.of names parts[%u], which does not own its buffers", (unsigned)i,
                         (unsigned)ofv);
    x = lopj_get(v->j, owner, "grid");
    if (x == LOPJ_NONE || !lopj_equal(v->j, x, g, v->text, NULL))
        return lopv_fail(v, "parts[%u].grid differs from the grid of the buffers it places (parts[%u].grid)",
                         (unsigned)i, (unsigned)ofv);
    pt->owner = (int32_t)ofv;
    *shared_of = ofv == i ? -1 : (int32_t)ofv;
    return 1;
}

/* An owner's LOD entry (the buffer's own fields); e->stage is set, its totals grow. */
static int lopv_lod(lopv *v, uint32_t lod, const char *where, lop_lod *e)
{
    lop_file *f = v->f;
    lopv_tot *t = &v->tot[e->stage];
    uint32_t x, vid, mw, ab, rec;
    int64_t n, tri;
    uint64_t bits = 0;
    int k, p;
    if ((x = lopv_need(v, lod, "vertices", LOPV_INT, where)) == LOPJ_NONE)
        return 0;
    n = v->j->v[x].big ? (v->j->v[x].i > 0 ? INT64_MAX : INT64_MIN) : v->j->v[x].i;
    if ((x = lopv_need(v, lod, "triangles", LOPV_INT, where)) == LOPJ_NONE)
        return 0;
    tri = v->j->v[x].big ? (v->j->v[x].i > 0 ? INT64_MAX : INT64_MIN) : v->j->v[x].i;
    if (n < 1 || tri < 1)
        return lopv_fail(v, "%s is empty", where);
    if (n > (int64_t)0xFFFFFFFF || tri > (int64_t)0xFFFFFFFF)
        return lopv_fail(v, "%s has more than 2^32 vertices or triangles", where);
    e->vertices = (uint32_t)n;
    e->triangles = (uint32_t)tri;
    if ((x = lopv_need(v, lod, "geometric_error_m", LOPV_NUM, where)) == LOPJ_NONE)
        return 0;
    if (lopv_d(v, x) < 0)
        return lopv_fail(v, "%s.geometric_error_m is negative", where);
    e->geometric_error_m = lopv_d(v, x);
    x = lopj_get(v->j, lod, "min_distance_m");
    e->min_distance_m = lopj_is_num(v->j, x, 1.7976931348623157e308) ? lopv_d(v, x) : -1.0;
    if ((vid = lopv_need(v, lod, "vertex_id", LOPV_ARR, where)) == LOPJ_NONE)
        return 0;
    {
        int good = v->j->v[vid].count == LOP_LEVELS + 1;
        int64_t prev = 0;
        for (k = 0, x = vid + 1; good && k <= LOP_LEVELS; k++, x = v->j->v[x].next) {
            if (!lopj_int_in(v->j, x, prev, n) || (k == 0 && v->j->v[x].i != 0) || (k == LOP_LEVELS && v->j->v[x].i != n))
                good = 0;
            else
                e->vertex_id[k] = (uint32_t)(prev = v->j->v[x].i);
        }
        if (!good)
            return lopv_fail(v, "%s.vertex_id is not 25 non-decreasing counts from 0 to %lld", where, (long long)n);
    }
    if ((x = lopv_need(v, lod, "index_width", LOPV_INT, where)) == LOPJ_NONE)
        return 0;
    if (!lopj_int_in(v->j, x, 2, 2) && !lopj_int_in(v->j, x, 4, 4))
        return lopv_fail(v, "%s.index_width must be 2 or 4", where);
    e->index_width = (uint32_t)v->j->v[x].i;
    if ((x = lopv_need(v, lod, "indices", LOPV_STR, where)) == LOPJ_NONE)
        return 0;
    if ((e->indices_section = lopv_section(v, x)) < 0)
        return lopv_fail(v, "%s.indices names no section", where);
    if (!lopv_bits(v, lod, where, e, &ab))
        return 0;
    rec = lopj_get(v->j, lod, "attributes");
    e->attributes_section = -1;
    if (rec != LOPJ_NONE && lopj_type(v->j, rec) != LOPJ_NULL &&
        (lopj_type(v->j, rec) != LOPJ_STRING || (e->attributes_section = lopv_section(v, rec)) < 0))
        return lopv_fail(v, "%s.attributes names no section", where);
    if ((e->attributes_section < 0) != (e->record_bits == 0))
        return lopv_fail(v, "%s.attributes must name a section exactly when record_bits > 0", where);
    if ((x = lopv_need(v, lod, "record_bits", LOPV_INT, where)) == LOPJ_NONE)
        return 0;
    if (!lopj_int_in(v->j, x, e->record_bits, e->record_bits))
        return lopv_fail(v, "%s.record_bits is not 2 b_n + 2 b_u + 4 b_c of its attribute_bits", where);
    if ((mw = lopv_need(v, lod, "mandatory_words", LOPV_ARR, where)) == LOPJ_NONE)
        return 0;
    if (v->j->v[mw].count != 2 || !lopj_nonneg(v->j, mw + 1) || !lopj_nonneg(v->j, v->j->v[mw + 1].next))
        return lopv_fail(v, "%s.mandatory_words must be [offset, count]", where);
    {
        const lopj_val *m0 = &v->j->v[mw + 1], *m1 = &v->j->v[v->j->v[mw + 1].next];
        e->mandatory_offset = m0->big ? UINT64_MAX : (uint64_t)m0->i;
        e->mandatory_count = m1->big ? UINT64_MAX : (uint64_t)m1->i;
    }
    for (k = 1; k <= LOP_LEVELS; k++)
        bits += 3u * (uint64_t)k * (e->vertex_id[k] - e->vertex_id[k - 1]);
    if (lopj_get(v->j, lod, "cluster_size") != LOPJ_NONE || lopj_get(v->j, lod, "cluster_words") != LOPJ_NONE) {
        uint32_t cw, pw, cpb;
        uint64_t n_c = 0, maxw;
        if (!v->clustered && !f->stream)
            return lopv_fail(v, "%s is clustered but positions.clusters is missing", where);
        if ((x = lopv_need(v, lod, "cluster_size", LOPV_INT, where)) == LOPJ_NONE)
            return 0;
        if (!lopj_int_in(v->j, x, 16, 1024))
            return lopv_fail(v, "%s.cluster_size must be in [16, 1024]", where);
        e->cluster_size = (uint32_t)v->j->v[x].i;
        e->cluster_id[0] = 0;
        for (k = 1; k <= LOP_LEVELS; k++) {
            uint32_t cnt = e->vertex_id[k] - e->vertex_id[k - 1];
            n_c += (cnt + e->cluster_size - 1) / e->cluster_size;
            e->cluster_id[k] = (uint32_t)n_c;
        }
        if ((cw = lopv_need(v, lod, "cluster_words", LOPV_ARR, where)) == LOPJ_NONE)
            return 0;
        if (v->j->v[cw].count != 2 || !lopj_int_in(v->j, cw + 1, (int64_t)t->headers, (int64_t)t->headers) ||
            !lopj_int_in(v->j, v->j->v[cw + 1].next, (int64_t)(3 * n_c), (int64_t)(3 * n_c)))
            return lopv_fail(v, "%s.cluster_words must be [offset, 3 * clusters] = [%llu, %llu]", where,
                             (unsigned long long)t->headers, (unsigned long long)(3 * n_c));
        e->cluster_words_offset = t->headers;
        e->cluster_count = (uint32_t)n_c;
        t->headers = lop__sat_add(t->headers, 3 * n_c);
        t->clustered++;
        if ((pw = lopv_need(v, lod, "cluster_p_words", LOPV_ARR, where)) == LOPJ_NONE)
            return 0;
        {
            int good = v->j->v[pw].count == LOP_LEVELS;
            for (k = 0, x = pw + 1; good && k < LOP_LEVELS; k++, x = v->j->v[x].next) {
                if (!lopj_is_int(v->j, x) || v->j->v[x].i < 1)
                    good = 0;
                else /* (a big count matches no header; from_bytes refuses it as clusters) */
                    e->cluster_p_words[k] = v->j->v[x].big ? UINT64_MAX : (uint64_t)v->j->v[x].i;
            }
            if (good && e->cluster_p_words[0] != e->mandatory_count)
                good = 0;
            if (!good)
                return lopv_fail(v, "%s.cluster_p_words must be 24 positive word counts, the first its mandatory count",
                                 where);
        }
        if ((cpb = lopv_need(v, lod, "cluster_plane_bits", LOPV_ARR, where)) == LOPJ_NONE)
            return 0;
        {
            int good = v->j->v[cpb].count == LOP_LEVELS - 1;
            for (p = 2, x = cpb + 1; good && p <= LOP_LEVELS; p++, x = v->j->v[x].next) {
                if (!lopj_int_in(v->j, x, 0, 3 * (int64_t)e->vertex_id[p - 1]))
                    good = 0;
                else
                    e->cluster_plane_bits[p - 2] = (uint32_t)v->j->v[x].i;
            }
            if (!good)
                return lopv_fail(v, "%s.cluster_plane_bits must be 23 bit counts, at most 3 VertexId[p-1] each", where);
        }
        for (p = 2; p <= LOP_LEVELS; p++)
            t->plane_bits[p] = lop__sat_add(t->plane_bits[p], e->cluster_plane_bits[p - 2]);
        maxw = (bits + 31) / 32 > 1 ? (bits + 31) / 32 : 1;
        if (e->mandatory_offset != t->words || e->mandatory_count < 1 || e->mandatory_count > maxw)
            return lopv_fail(v, "%s.mandatory_words do not match its bins", where);
    } else {
        e->cluster_size = 0;
        if (e->mandatory_offset != t->words || e->mandatory_count != (bits + 31) / 32)
            return lopv_fail(v, "%s.mandatory_words do not match its bins", where);
        for (p = 2; p <= LOP_LEVELS; p++)
            t->plane_bits[p] = lop__sat_add(t->plane_bits[p], 3u * (uint64_t)e->vertex_id[p - 1]);
    }
    t->words = lop__sat_add(t->words, e->mandatory_count);
    t->buffers++;
    if ((n <= 65535) != (e->index_width == 2))
        return lopv_fail(v, "%s.index_width %u does not match %lld vertices", where, (unsigned)e->index_width,
                         (long long)n);
    if (f->sections[e->indices_section].size < 3u * (uint64_t)e->triangles * e->index_width)
        return lopv_fail(v, "%s: index section is shorter than %u triangles", where, (unsigned)e->triangles);
    if (e->attributes_section >= 0 &&
        f->sections[e->attributes_section].size < 4u * (((uint64_t)e->vertices * e->record_bits + 31) / 32))
        return lopv_fail(v, "%s: attributes section is shorter than %u records of %u bits", where,
                         (unsigned)e->vertices, (unsigned)e->record_bits);
    memset(e->uv_lo, 0, sizeof e->uv_lo);
    memset(e->uv_hi, 0, sizeof e->uv_hi);
    memset(e->uv_step, 0, sizeof e->uv_step);
    if (e->uv_bits) {
        uint32_t rng, step, r0, r1;
        int good;
        if ((rng = lopv_need(v, lod, "uv_range", LOPV_ARR, where)) == LOPJ_NONE)
            return 0;
        good = v->j->v[rng].count == 2;
        r0 = good ? rng + 1 : LOPJ_NONE;
        r1 = good ? v->j->v[r0].next : LOPJ_NONE;
        good = good && lopj_type(v->j, r0) == LOPJ_ARRAY && v->j->v[r0].count == 2 &&
               lopj_type(v->j, r1) == LOPJ_ARRAY && v->j->v[r1].count == 2 &&
               lopj_is_num(v->j, r0 + 1, LOP__F32_MAX) && lopj_is_num(v->j, v->j->v[r0 + 1].next, LOP__F32_MAX) &&
               lopj_is_num(v->j, r1 + 1, LOP__F32_MAX) && lopj_is_num(v->j, v->j->v[r1 + 1].next, LOP__F32_MAX);
        if (!good)
            return lopv_fail(v, "%s.uv_range must be [[lo_u, lo_v], [hi_u, hi_v]] of finite float32 numbers", where);
        {
            double lo0 = lopv_d(v, r0 + 1), lo1 = lopv_d(v, v->j->v[r0 + 1].next);
            double hi0 = lopv_d(v, r1 + 1), hi1 = lopv_d(v, v->j->v[r1 + 1].next);
            if (!(lo0 <= hi0 && lo1 <= hi1))
                return lopv_fail(v, "%s.uv_range has lo above hi", where);
            e->uv_lo[0] = (float)lo0;
            e->uv_lo[1] = (float)lo1;
            e->uv_hi[0] = (float)hi0;
            e->uv_hi[1] = (float)hi1;
        }
        if ((step = lopv_need(v, lod, "uv_step", LOPV_ARR, where)) == LOPJ_NONE)
            return 0;
        if (v->j->v[step].count != 2 || !lopj_is_num(v->j, step + 1, LOP__F32_MAX) ||
            !lopj_is_num(v->j, v->j->v[step + 1].next, LOP__F32_MAX))
            return lopv_fail(v, "%s.uv_step must be [step_u, step_v] of finite float32 numbers", where);
        for (k = 0; k < 2; k++) {
            double d = lopv_d(v, k ? v->j->v[step + 1].next : step + 1);
            float want = (float)(((double)e->uv_hi[k] - (double)e->uv_lo[k]) / (double)((1u << e->uv_bits) - 1));
            if (d != (double)want)
                return lopv_fail(v, "%s.uv_step is not float32((hi - lo) / (2^b_u - 1)) of its uv_range", where);
            e->uv_step[k] = want;
        }
    }
    return 1;
}

/* A LOD entry's stage in the streaming layout (format.md 14.1): an integer naming a stage, 0 for a
   part's coarsest LOD, never below the stage of the next coarser LOD. */
static int lopv_stage(lopv *v, uint32_t lod, uint32_t k, uint32_t n, const char *where, uint32_t *out)
{
    uint32_t x = lopv_need(v, lod, "stage", LOPV_INT, where), nx;
    const lopj_val *s, *c;
    if (x == LOPJ_NONE)
        return 0;
    s = &v->j->v[x];
    if (!lopj_int_in(v->j, x, 0, (int64_t)v->f->stage_count - 1))
        return lopv_fail(v, "%s.stage names no stage (the file has %u)", where, (unsigned)v->f->stage_count);
    if (k == n - 1 && s->i != 0)
        return lopv_fail(v, "%s.stage must be 0: a part's coarsest LOD is in the first stage", where);
    if (k < n - 1) {
        nx = lopj_get(v->j, v->j->v[lod].next, "stage");
        c = nx == LOPJ_NONE ? NULL : &v->j->v[nx];
        if (c && c->type == LOPJ_INT && (c->big ? c->i > 0 : s->i < c->i))
            return lopv_fail(v, "%s.stage comes before the stage of the coarser LOD %u", where, (unsigned)k + 1);
    }
    *out = (uint32_t)s->i;
    return 1;
}

static int lopv_parts(lopv *v, uint32_t m)
{
    lop_file *f = v->f;
    uint32_t parts, part, i;
    char where[64];
    if ((parts = lopv_need(v, m, "parts", LOPV_ARR, "manifest")) == LOPJ_NONE)
        return 0;
    if (v->j->v[parts].count == 0)
        return lopv_fail(v, "no parts");
    for (i = 0, part = parts + 1; i < v->j->v[parts].count; i++, part = v->j->v[part].next) {
        lop_part tmp, *pt = &tmp;
        uint32_t name, hier, lods, lod, k, pb, ref;
        int32_t shared_of;
        const lop_lod *first = NULL;
        memset(&tmp, 0, sizeof tmp);
        v->part_node[i] = part;
        snprintf(where, sizeof where, "parts[%u]", (unsigned)i);
        if ((name = lopv_need(v, part, "name", LOPV_STR, where)) == LOPJ_NONE)
            return 0;
        pt->name = lopv_copy(v, name);
        pt->owner = (int32_t)i;
        pt->hierarchy_section = -1;
        memset(pt->transform, 0, sizeof pt->transform);
        pt->transform[0] = pt->transform[5] = pt->transform[10] = 1.0f;
        memcpy(pt->grid_origin, f->grid_origin, sizeof pt->grid_origin);
        pt->grid_extent = f->grid_extent;
        hier = lopj_get(v->j, part, "hierarchy");
        if (hier != LOPJ_NONE && lopj_type(v->j, hier) != LOPJ_NULL) {
            static const char *const keys[7] = {"leaves", "nodes", "triangles", "connectivity_bits", "structure_bits",
                                                "vertex_map_bits", "representative_bits"};
            char hw[80];
            uint32_t sec, c;
            snprintf(hw, sizeof hw, "parts[%u].hierarchy", (unsigned)i);
            if (lopv_need(v, part, "hierarchy", LOPV_OBJ, where) == LOPJ_NONE ||
                (sec = lopv_need(v, hier, "section", LOPV_STR, hw)) == LOPJ_NONE)
                return 0;
            pt->hierarchy_section = lopv_section(v, sec);
            if (pt->hierarchy_section < 0 || strncmp(f->sections[pt->hierarchy_section].name, "positions/", 10) == 0)
                return lopv_fail(v, "parts[%u].hierarchy.section names no hierarchy section", (unsigned)i);
            for (c = 0; c < 7; c++) {
                uint32_t x = lopv_need(v, hier, keys[c], LOPV_INT, hw);
                if (x == LOPJ_NONE)
                    return 0;
                if (v->j->v[x].i < 0)
                    return lopv_fail(v, "parts[%u].hierarchy.%s is negative", (unsigned)i, keys[c]);
            }
        }
        if (lopv_need(v, part, "source", LOPV_STR, where) == LOPJ_NONE ||
            (lods = lopv_need(v, part, "lods", LOPV_ARR, where)) == LOPJ_NONE)
            return 0;
        if (v->j->v[lods].count == 0)
            return lopv_fail(v, "parts[%u] has no LODs", (unsigned)i);
        if (!lopv_placement(v, parts, i, part, pt, &shared_of))
            return 0;
        pt->lods = v->lods;
        pt->lod_count = v->j->v[lods].count;
        ref = shared_of >= 0 ? lopj_get(v->j, v->part_node[shared_of], "lods") + 1 : LOPJ_NONE;
        for (k = 0, lod = lods + 1; k < pt->lod_count; k++, lod = v->j->v[lod].next) {
            lop_lod local, *e = &local;
            char lw[80];
            memset(&local, 0, sizeof local);
            snprintf(lw, sizeof lw, "parts[%u].lods[%u]", (unsigned)i, (unsigned)k);
            if (lopj_type(v->j, lod) != LOPJ_OBJECT)
                return lopv_fail(v, "%s is not an object", lw);
            if (f->stream && !lopv_stage(v, lod, k, pt->lod_count, lw, &local.stage))
                return 0;
            if (!f->stream && lopj_get(v->j, lod, "stage") != LOPJ_NONE)
                return lopv_fail(v, "%s.stage is only allowed in the streaming layout (positions.stages)", lw);
            if (shared_of >= 0) {
                static const char *const own[3] = {"geometric_error_m", "min_distance_m", NULL};
                const lop_part *op = &f->parts[shared_of];
                uint32_t x, ab;
                lop_lod bits;
                if (pt->lod_count != op->lod_count)
                    return lopv_fail(v, "parts[%u] has %u LODs, the buffers it places (parts[%d]) %u", (unsigned)i,
                                     (unsigned)pt->lod_count, (int)shared_of, (unsigned)op->lod_count);
                if (!lopj_equal(v->j, lod, ref, v->text, own))
                    return lopv_fail(v, "%s does not name the buffer of parts[%d].lods[%u] it places", lw,
                                     (int)shared_of, (unsigned)k);
                *e = op->lods[k];
                if ((x = lopv_need(v, lod, "geometric_error_m", LOPV_NUM, lw)) == LOPJ_NONE)
                    return 0;
                if (lopv_d(v, x) < 0)
                    return lopv_fail(v, "%s.geometric_error_m is negative", lw);
                e->geometric_error_m = lopv_d(v, x);
                x = lopj_get(v->j, lod, "min_distance_m");
                e->min_distance_m = lopj_is_num(v->j, x, 1.7976931348623157e308) ? lopv_d(v, x) : -1.0;
                if (!lopv_bits(v, lod, lw, &bits, &ab))
                    return 0;
                ref = v->j->v[ref].next; /* the owner's next LOD */
            } else if (!lopv_lod(v, lod, lw, e)) {
                return 0;
            }
            if (k >= v->lods_left) /* cannot happen: every LOD that validates was counted */
                return lopv_fail(v, "%s: more LODs than counted", lw);
            pt->lods[k] = local;
            e = &pt->lods[k];
            if (!first)
                first = e; /* the part's attribute_bits are its LOD 0's (lopcook checks no other LOD) */
        }
        v->lods += pt->lod_count;
        v->lods_left -= pt->lod_count;
        if ((pb = lopv_need(v, part, "attribute_bits", LOPV_OBJ, where)) == LOPJ_NONE)
            return 0;
        if (!lopv_part_bits(v, pb, first))
            return lopv_fail(v, "parts[%u].attribute_bits is not the attribute_bits its LODs share", (unsigned)i);
        if (i >= v->parts_cap) /* cannot happen: every part with LODs was counted */
            return lopv_fail(v, "parts[%u]: more parts than counted", (unsigned)i);
        f->parts[i] = tmp;
    }
    f->part_count = v->j->v[parts].count;
    return 1;
}

/* The index of the section named `name`, or -1. */
static int32_t lopv_section_named(const lopv *v, const char *name)
{
    size_t lo = 0, hi = v->f->section_count, kl = strlen(name);
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        const lopj_val *x = &v->j->v[v->name_val[v->names[mid]]];
        size_t n = x->len < kl ? x->len : kl;
        int c = memcmp(v->j->pool + x->str, name, n);
        if (c == 0)
            c = x->len < kl ? -1 : x->len > kl;
        if (c == 0)
            return (int32_t)v->names[mid];
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return -1;
}

/* Bytes of a plane section holding `bits` bits: whole uint32 words (saturating). */
static uint64_t lop__plane_bytes(uint64_t bits)
{
    return bits > UINT64_MAX - 31 ? UINT64_MAX : 4 * ((bits + 31) / 32);
}

/* The next entry of the streaming layout's section list (format.md 14.3) is section `idx`. */
static int lopv_expect(lopv *v, int32_t idx, const char *want, uint32_t *at)
{
    lop_file *f = v->f;
    if (*at >= f->section_count || idx != (int32_t)*at)
        return lopv_fail(v, "the sections are not those of the streaming layout in its order: section %u is '%.60s', "
                         "expected '%.60s'", (unsigned)*at, *at < f->section_count ? f->sections[*at].name : "missing",
                         want);
    (*at)++;
    return 1;
}

/* A stage's position section `kind` (clusters, mandatory, deferred, planePP) in the list. */
static int lopv_expect_named(lopv *v, uint32_t s, const char *kind, uint32_t *at, int32_t *out)
{
    char name[64];
    snprintf(name, sizeof name, "positions/stage%u/%s", (unsigned)s, kind);
    *out = lopv_section_named(v, name);
    return lopv_expect(v, *out, name, at);
}

/* The stored buffers grouped by stage, manifest order within each (a counting sort). */
static void lopv_group(lopv *v)
{
    lop_file *f = v->f;
    uint32_t s, i, k, S = f->stage_count;
    v->stage_start[0] = 0;
    for (s = 0; s < S; s++)
        v->stage_start[s + 1] = v->stage_start[s] + v->tot[s].buffers;
    for (i = 0; i < f->part_count; i++)
        if (f->parts[i].owner == (int32_t)i)
            for (k = 0; k < f->parts[i].lod_count; k++) {
                uint32_t b = v->stage_start[f->parts[i].lods[k].stage]++;
                v->order[2 * b] = i;
                v->order[2 * b + 1] = k;
            }
    for (s = S; s > 0; s--)
        v->stage_start[s] = v->stage_start[s - 1];
    v->stage_start[0] = 0;
}

/* The streaming layout (format.md 14.2-14.3): every stage holds a stored buffer; the section table
   is exactly the layout's list; each stage's position sections are as long as its buffers need
   (planes and the deferred section exactly). Fills f->stages. */
static int lopv_stream_layout(lopv *v)
{
    lop_file *f = v->f;
    uint32_t s, b, at = 0, S = f->stage_count;
    int p;
    for (s = 0; s < S; s++)
        if (!v->tot[s].buffers)
            return lopv_fail(v, "positions.stages[%u] holds no buffer", (unsigned)s);
    for (s = 0; s < S; s++) {
        lop_stage *st = &f->stages[s];
        const lopv_tot *t = &v->tot[s];
        for (b = v->stage_start[s]; b < v->stage_start[s + 1]; b++) {
            const lop_part *pt = &f->parts[v->order[2 * b]];
            const lop_lod *e = &pt->lods[v->order[2 * b + 1]];
            if (!lopv_expect(v, e->indices_section, f->sections[e->indices_section].name, &at) ||
                (e->attributes_section >= 0 &&
                 !lopv_expect(v, e->attributes_section, f->sections[e->attributes_section].name, &at)) ||
                (v->order[2 * b + 1] == 0 && pt->hierarchy_section >= 0 &&
                 !lopv_expect(v, pt->hierarchy_section, f->sections[pt->hierarchy_section].name, &at)))
                return 0;
        }
        st->buffers = t->buffers;
        st->clusters_section = st->deferred_section = -1;
        if (t->clustered && !lopv_expect_named(v, s, "clusters", &at, &st->clusters_section))
            return 0;
        if (!lopv_expect_named(v, s, "mandatory", &at, &st->mandatory_section))
            return 0;
        for (p = 0; p <= LOP_LEVELS; p++) {
            st->plane_section[p] = -1;
            st->plane_offset[p] = 0;
            st->plane_bits[p] = p >= 2 && p <= f->max_level ? t->plane_bits[p] : 0;
        }
        for (p = 2; p <= st->level; p++) {
            char kind[16];
            snprintf(kind, sizeof kind, "plane%02d", p);
            if (st->plane_bits[p] && !lopv_expect_named(v, s, kind, &at, &st->plane_section[p]))
                return 0;
        }
    }
    for (s = 0; s < S; s++) {
        lop_stage *st = &f->stages[s];
        uint64_t offset = 0;
        for (p = st->level + 1; p <= f->max_level; p++)
            if (st->plane_bits[p] && st->deferred_section < 0 && !lopv_expect_named(v, s, "deferred", &at, &st->deferred_section))
                return 0;
        for (p = st->level + 1; p <= f->max_level && st->deferred_section >= 0; p++) {
            st->plane_offset[p] = offset;
            if (st->plane_bits[p])
                st->plane_section[p] = st->deferred_section;
            offset = lop__sat_add(offset, lop__plane_bytes(st->plane_bits[p]));
        }
    }
    if (at != f->section_count)
        return lopv_expect(v, -1, "none", &at);
    for (s = 0; s < S; s++) {
        const lop_stage *st = &f->stages[s];
        const lopv_tot *t = &v->tot[s];
        uint64_t deferred = 0;
        if (st->clusters_section >= 0 &&
            (t->headers > UINT64_MAX / 4 || f->sections[st->clusters_section].size < 4 * t->headers))
            return lopv_fail(v, "%s is shorter than the cluster headers it holds", f->sections[st->clusters_section].name);
        if (t->words > UINT64_MAX / 4 || f->sections[st->mandatory_section].size < 4 * t->words)
            return lopv_fail(v, "%s is shorter than the buffers it holds", f->sections[st->mandatory_section].name);
        for (p = 2; p <= st->level; p++)
            if (st->plane_section[p] >= 0 && f->sections[st->plane_section[p]].size != lop__plane_bytes(st->plane_bits[p]))
                return lopv_fail(v, "%s is not the %llu bits its buffers hold", f->sections[st->plane_section[p]].name,
                                 (unsigned long long)st->plane_bits[p]);
        for (p = st->level + 1; p <= f->max_level; p++)
            deferred = lop__sat_add(deferred, lop__plane_bytes(st->plane_bits[p]));
        if (st->deferred_section >= 0 && f->sections[st->deferred_section].size != deferred)
            return lopv_fail(v, "%s is not the %llu bytes of planes %d..%d", f->sections[st->deferred_section].name,
                             (unsigned long long)deferred, st->level + 1, f->max_level);
    }
    return 1;
}

/* The default layout's position sections as long as their buffers need; its one stage. */
static int lopv_default_layout(lopv *v)
{
    lop_file *f = v->f;
    lop_stage *st = &f->stages[0];
    const lopv_tot *t = &v->tot[0];
    int p;
    if (v->clustered && !t->clustered)
        return lopv_fail(v, "positions.clusters is present but no buffer is clustered");
    if (v->clustered && (t->headers > UINT64_MAX / 4 || f->sections[f->clusters_section].size < 4 * t->headers))
        return lopv_fail(v, "positions.clusters is shorter than the cluster headers it holds");
    if (t->words > UINT64_MAX / 4 || f->sections[f->mandatory_section].size < 4 * t->words)
        return lopv_fail(v, "positions.mandatory is shorter than the buffers it holds");
    for (p = 2; p <= f->max_level; p++)
        if (f->sections[f->plane_section[p]].size < (t->plane_bits[p] / 8 + (t->plane_bits[p] % 8 != 0)))
            return lopv_fail(v, "refinement plane %d is shorter than its %llu bits", p,
                             (unsigned long long)t->plane_bits[p]);
    memset(st, 0, sizeof *st);
    st->level = f->max_level;
    st->buffers = t->buffers;
    st->mandatory_section = f->mandatory_section;
    st->clusters_section = f->clusters_section;
    st->deferred_section = -1;
    for (p = 0; p <= LOP_LEVELS; p++) {
        st->plane_section[p] = f->plane_section[p];
        st->plane_bits[p] = p >= 2 && p <= f->max_level ? t->plane_bits[p] : 0;
    }
    return 1;
}

/* A meshopt-deflate section is a LOD's indices and nothing else, its size the 3 m indices' bytes,
   its stored bytes enough for a triangle stream of m triangles (format.md 15.2). Also notes, per
   section, the last LOD naming it as indices (the one a meshopt-deflate section decodes with). */
static int lopv_encoded_indices(lopv *v)
{
    lop_file *f = v->f;
    uint32_t i, k, j;
    if (!v->has_encoded)
        return 1;
    for (j = 0; j < f->section_count; j++) {
        v->sec_first[j] = v->sec_last[j] = NULL;
        v->sec_other[j] = 0;
    }
    for (i = 0; i < f->part_count; i++) {
        const lop_part *pt = &f->parts[i];
        for (k = 0; k < pt->lod_count; k++) {
            const lop_lod *e = &pt->lods[k];
            if (!v->sec_first[e->indices_section])
                v->sec_first[e->indices_section] = e;
            v->sec_last[e->indices_section] = e;
            if (e->attributes_section >= 0)
                v->sec_other[e->attributes_section] = 1;
        }
        if (pt->hierarchy_section >= 0)
            v->sec_other[pt->hierarchy_section] = 1;
    }
    for (j = 0; j < f->section_count; j++) {
        const lop_section *s = &f->sections[j];
        const lop_lod *e = v->sec_first[j];
        uint64_t want;
        if (s->encoding != LOP_ENCODING_MESHOPT)
            continue;
        if (!e || v->sec_other[j])
            return lopv_fail(v, "section '%s' is encoded meshopt-deflate but is no LOD's index section", s->name);
        want = 4 * ((3u * (uint64_t)e->triangles * e->index_width + 3) / 4);
        if (s->size != want)
            return lopv_fail(v, "section '%s' size %llu is not the %llu bytes of its %u triangles", s->name,
                             (unsigned long long)s->size, (unsigned long long)want, (unsigned)e->triangles);
        if (s->length <= UINT64_MAX / LOP__DEFLATE_MAX_RATIO &&
            (uint64_t)e->triangles + 17 > LOP__DEFLATE_MAX_RATIO * s->length)
            return lopv_fail(v, "section '%s': %llu stored bytes cannot hold %u triangles", s->name,
                             (unsigned long long)s->length, (unsigned)e->triangles);
    }
    return 1;
}

static int lopv_manifest(lopv *v, uint32_t root)
{
    uint32_t planes;
    v->klass = lop_error_manifest;
    if (lopj_type(v->j, root) != LOPJ_OBJECT || !lopj_is_str(v->j, lopj_get(v->j, root, "format"), "lopcook.lop"))
        return lopv_fail(v, "format is not 'lopcook.lop'");
    if (!lopv_informative(v, root))
        return 0;
    v->klass = lop_error_section_table;
    if (!lopv_sections(v, root))
        return 0;
    v->klass = lop_error_manifest;
    if (!lopv_grid(v, root) || !lopv_positions(v, root, &planes) || !lopv_parts(v, root))
        return 0;
    lopv_group(v);
    if (!(v->f->stream ? lopv_stream_layout(v) : lopv_default_layout(v)))
        return 0;
    (void)planes;
    return lopv_encoded_indices(v);
}

/* ---- lop_open -------------------------------------------------------------------------------- */

LOPDEF const char *lop_result_name(lop_result r)
{
    switch (r) {
    case lop_success: return "success";
    case lop_error_truncated: return "truncated";
    case lop_error_bad_magic: return "bad_magic";
    case lop_error_header_crc: return "header_crc";
    case lop_error_version: return "version";
    case lop_error_header: return "header";
    case lop_error_trailing_data: return "trailing_data";
    case lop_error_manifest_crc: return "manifest_crc";
    case lop_error_manifest_json: return "manifest_json";
    case lop_error_manifest: return "manifest";
    case lop_error_section_table: return "section_table";
    case lop_error_section_crc: return "section_crc";
    case lop_error_indices: return "indices";
    case lop_error_clusters: return "clusters";
    case lop_error_level: return "level";
    case lop_error_argument: return "argument";
    case lop_error_limit: return "limit";
    case lop_error_out_of_memory: return "out_of_memory";
    case lop_error_encoding: return "encoding";
    }
    return "unknown";
}

/* Every index of every buffer present is below its vertex count. */
static int lop__check_indices(const lop_file *f, lop__err *err)
{
    uint32_t i, k, t;
    for (i = 0; i < f->part_count; i++) {
        const lop_part *pt = &f->parts[i];
        if (pt->owner != (int32_t)i)
            continue; /* a placement's entries are its owner's */
        for (k = 0; k < pt->lod_count; k++) {
            const lop_lod *e = &pt->lods[k];
            const uint8_t *d = f->sections[e->indices_section].data;
            uint32_t worst = 0;
            if (!d)
                continue;
            if (e->index_width == 2) {
                for (t = 0; t < 3 * e->triangles; t++) {
                    uint32_t x = lop__rd16(d + 2 * (size_t)t);
                    worst = x > worst ? x : worst;
                }
            } else {
                for (t = 0; t < 3 * e->triangles; t++) {
                    uint32_t x = lop__rd32(d + 4 * (size_t)t);
                    worst = x > worst ? x : worst;
                }
            }
            if (worst >= e->vertices)
                return lop__fail0(err, lop_error_indices, "part %u LOD %u: index %u is out of range for %u vertices",
                                 (unsigned)i, (unsigned)k, (unsigned)worst, (unsigned)e->vertices);
        }
    }
    return 1;
}

/* Cluster headers sound (k <= 24, anchors within k bits), cluster_p_words and cluster_plane_bits
   what the headers give, for the buffers of every stage whose cluster headers have arrived; in the
   default layout every plane present exactly as long as its buffers' bits (the streaming layout's
   plane lengths follow from the manifest, which the validator checked). */
static int lop__check_clusters(lop_file *f, lop__err *err)
{
    uint32_t i, k;
    int p;
    for (i = 0; i < f->part_count; i++) {
        const lop_part *pt = &f->parts[i];
        if (pt->owner != (int32_t)i)
            continue;
        for (k = 0; k < pt->lod_count; k++) {
            const lop_lod *e = &pt->lods[k];
            const lop_stage *st = &f->stages[e->stage];
            const lop_section *hs = st->clusters_section >= 0 ? &f->sections[st->clusters_section] : NULL;
            uint64_t words[LOP_LEVELS + 1], plane[LOP_LEVELS + 1], head_words;
            uint32_t c = 0;
            int bin, b;
            if (!e->cluster_size || !hs || !hs->data)
                continue;
            head_words = hs->size / 4;
            if (e->cluster_words_offset + 3u * (uint64_t)e->cluster_count > head_words)
                return lop__fail0(err, lop_error_clusters, "part %u LOD %u: cluster headers: %llu words past the "
                                 "section", (unsigned)i, (unsigned)k,
                                 (unsigned long long)(e->cluster_words_offset + 3u * (uint64_t)e->cluster_count -
                                                      head_words));
            memset(words, 0, sizeof words);
            memset(plane, 0, sizeof plane);
            for (bin = 1; bin <= LOP_LEVELS; bin++) {
                uint32_t left = e->vertex_id[bin] - e->vertex_id[bin - 1];
                while (left) {
                    uint32_t count = left < e->cluster_size ? left : e->cluster_size;
                    const uint8_t *h = hs->data + 4 * (e->cluster_words_offset + 3u * (uint64_t)c);
                    int kt[3], t;
                    for (t = 0; t < 3; t++) {
                        uint32_t w = lop__rd32(h + 4 * t);
                        kt[t] = (int)(w >> 24);
                        if (kt[t] > LOP_LEVELS || ((w & 0xFFFFFFu) >> kt[t]) != 0)
                            return lop__fail0(err, lop_error_clusters, "part %u LOD %u: cluster headers: a cluster "
                                             "header has k > 24 or an anchor wider than k bits", (unsigned)i,
                                             (unsigned)k);
                    }
                    for (b = 1; b <= LOP_LEVELS; b++) {
                        int w = bin > b ? bin : b, s = 0;
                        for (t = 0; t < 3; t++)
                            s += w > kt[t] ? w - kt[t] : 0;
                        words[b] += (uint64_t)count * (uint64_t)s;
                    }
                    for (p = bin + 1; p <= LOP_LEVELS; p++)
                        plane[p] += (uint64_t)count * (uint64_t)((kt[0] < p) + (kt[1] < p) + (kt[2] < p));
                    left -= count;
                    c++;
                }
            }
            for (b = 1; b <= LOP_LEVELS; b++) {
                uint64_t w = (words[b] + 31) / 32;
                if ((w ? w : 1) != e->cluster_p_words[b - 1])
                    return lop__fail0(err, lop_error_clusters, "part %u LOD %u: cluster_p_words (mandatory_words count "
                                     "%llu) do not match its clusters (%llu words at level 1)", (unsigned)i,
                                     (unsigned)k, (unsigned long long)e->mandatory_count,
                                     (unsigned long long)((words[1] + 31) / 32 ? (words[1] + 31) / 32 : 1));
            }
            for (p = 2; p <= LOP_LEVELS; p++)
                if (plane[p] != e->cluster_plane_bits[p - 2])
                    return lop__fail0(err, lop_error_clusters, "part %u LOD %u: cluster_plane_bits do not match its "
                                     "clusters", (unsigned)i, (unsigned)k);
        }
    }
    if (f->stream || f->clusters_section < 0 || !f->sections[f->clusters_section].data)
        return 1;
    for (p = 2; p <= f->max_level; p++) { /* the stage's plane bits are the manifest's, now the headers' */
        const lop_section *s = &f->sections[f->plane_section[p]];
        if (s->data && s->size != lop__plane_bytes(f->stages[0].plane_bits[p]))
            return lop__fail0(err, lop_error_clusters, "refinement plane %d is not the %llu bits its buffers hold", p,
                             (unsigned long long)f->stages[0].plane_bits[p]);
    }
    return 1;
}

/* Each buffer's bit offset in every plane of its stage (the stage's earlier buffers' slices); a
   placement's are its owner's. */
static void lop__plane_starts(lop_file *f, const uint32_t *stage_start, const uint32_t *order)
{
    uint32_t s, b, i, k;
    int p;
    for (s = 0; s < f->stage_count; s++) {
        uint64_t start[LOP_LEVELS + 1];
        memset(start, 0, sizeof start);
        for (b = stage_start[s]; b < stage_start[s + 1]; b++) {
            lop_lod *e = &f->parts[order[2 * b]].lods[order[2 * b + 1]];
            e->plane_start[0] = e->plane_start[1] = 0;
            for (p = 2; p <= LOP_LEVELS; p++) {
                e->plane_start[p] = start[p];
                start[p] = lop__sat_add(start[p], e->cluster_size ? e->cluster_plane_bits[p - 2]
                                                                   : 3u * (uint64_t)e->vertex_id[p - 1]);
            }
        }
    }
    for (i = 0; i < f->part_count; i++) {
        lop_part *pt = &f->parts[i];
        if (pt->owner != (int32_t)i)
            for (k = 0; k < pt->lod_count; k++)
                memcpy(pt->lods[k].plane_start, f->parts[pt->owner].lods[k].plane_start, sizeof pt->lods[k].plane_start);
    }
}

/* Every stage's level in the bytes given (format.md 8, 14.4), and the available level (the lowest). */
static void lop__stage_levels(lop_file *f, const uint32_t *stage_start, const uint32_t *order)
{
    uint32_t s, b, i;
    int p;
    f->available_level = LOP_LEVELS;
    for (s = 0; s < f->stage_count; s++) {
        lop_stage *st = &f->stages[s];
        int ok = f->sections[st->mandatory_section].data && (st->clusters_section < 0 || f->sections[st->clusters_section].data);
        if (f->stream) {
            for (b = stage_start[s]; ok && b < stage_start[s + 1]; b++) {
                const lop_part *pt = &f->parts[order[2 * b]];
                const lop_lod *e = &pt->lods[order[2 * b + 1]];
                ok = f->sections[e->indices_section].data &&
                     (e->attributes_section < 0 || f->sections[e->attributes_section].data) &&
                     (order[2 * b + 1] != 0 || pt->hierarchy_section < 0 || f->sections[pt->hierarchy_section].data);
            }
        } else {
            for (i = 0; ok && i < f->section_count; i++)
                ok = f->sections[i].data || strncmp(f->sections[i].name, "positions/", 10) == 0;
        }
        st->available = 0;
        if (ok) {
            st->available = 1;
            for (p = 2; p <= st->level; p++) {
                int32_t x = st->plane_section[p];
                if (x >= 0 && (f->stream ? x != st->deferred_section : 1) && !f->sections[x].data)
                    break;
                st->available = p;
            }
            if (st->available == st->level && st->level < f->max_level &&
                (st->deferred_section < 0 || f->sections[st->deferred_section].data))
                st->available = f->max_level;
        }
        if (st->available < f->available_level)
            f->available_level = st->available;
    }
}

/* Decode encoded section i (its stored bytes at `stored`) into a block of its own, or set the error.
   A meshopt-deflate section decodes with the LOD `lod` names it as indices. */
static int lop__decode_section(lop_file *f, uint32_t i, const uint8_t *stored, const lop_lod *lod,
                               lop__inflater **z, const lop_allocator *mem, lop__err *err)
{
    lop_section *s = &f->sections[i];
    size_t end = 0, k, limit, first;
    uint8_t *out;
    const char *why = NULL;
    int r;
    if (!*z && !(*z = (lop__inflater *)lop__alloc(mem, sizeof **z)))
        return lop__fail0(err, lop_error_out_of_memory, "out of memory");
    if (s->size > (uint64_t)(size_t)-1 || s->length > (uint64_t)(size_t)-1)
        return lop__fail0(err, lop_error_out_of_memory, "section '%s' is too large for this machine", s->name);
    if (s->encoding == LOP_ENCODING_DEFLATE) {
        limit = first = (size_t)s->size;
    } else { /* a triangle stream reads at most 16 data bytes per triangle: |E| <= 17 m + 17 */
        uint64_t most = 17u * (uint64_t)lod->triangles + 17;
        if (s->length <= UINT64_MAX / LOP__DEFLATE_MAX_RATIO && LOP__DEFLATE_MAX_RATIO * s->length < most)
            most = LOP__DEFLATE_MAX_RATIO * s->length;
        limit = most > (uint64_t)(size_t)-1 ? (size_t)-1 : (size_t)most;
        first = 4 * (size_t)s->length + 1024;
    }
    r = lop__inflate(*z, stored, (size_t)s->length, limit, first, mem, &end);
    out = (*z)->out;
    (*z)->out = NULL;
    if (r == LOP__Z_MEMORY) {
        lop__free(mem, out);
        return lop__fail0(err, lop_error_out_of_memory, "out of memory decoding section '%s'", s->name);
    }
    if (r != LOP__Z_OK)
        why = lop__z_why(r);
    else if (s->encoding == LOP_ENCODING_DEFLATE && (*z)->n != s->size)
        why = "the deflate stream gives fewer bytes than its size says";
    else if ((uint64_t)s->length != 4 * (((uint64_t)end + 3) / 4))
        why = "the deflate stream does not end in the last word of its stored bytes";
    for (k = end; !why && k < (size_t)s->length; k++)
        if (stored[k])
            why = "the bytes after the deflate stream are not zero padding";
    if (!why && s->encoding == LOP_ENCODING_MESHOPT) {
        uint8_t *idx = (uint8_t *)lop__alloc(mem, (size_t)s->size);
        if (!idx) {
            lop__free(mem, out);
            return lop__fail0(err, lop_error_out_of_memory, "out of memory decoding section '%s'", s->name);
        }
        memset(idx, 0, (size_t)s->size);
        why = lop__triangles(out, (*z)->n, lod->triangles, lod->vertices, lod->index_width, idx);
        lop__free(mem, out);
        out = idx;
    }
    if (why) {
        lop__free(mem, out);
        return lop__fail0(err, lop_error_encoding, "section '%s' (%s): %s", s->name,
                          s->encoding == LOP_ENCODING_DEFLATE ? "deflate" : "meshopt-deflate", why);
    }
    s->data = out;
    return 1;
}

/* The JSON text of an encoded manifest (format.md 4: 0x00, its size D, a DEFLATE stream giving
   exactly D bytes and ending at the manifest's last byte) into *text (the caller frees it). */
static int lop__decode_manifest(const uint8_t *m, uint32_t msize, lop__inflater **z, const lop_allocator *mem,
                                uint8_t **text, size_t *tsize, lop__err *err)
{
    uint32_t d;
    size_t end = 0;
    int r;
    if (msize < 5)
        return lop__fail0(err, lop_error_encoding, "manifest (encoded): an encoded manifest starts with 0x00 and its "
                         "4-byte size");
    d = lop__rd32(m + 1);
    if ((uint64_t)d > (uint64_t)LOP__DEFLATE_MAX_RATIO * (msize - 5))
        return lop__fail0(err, lop_error_encoding, "manifest (encoded): it claims %u bytes, more than %u times its %u "
                         "stored bytes", (unsigned)d, LOP__DEFLATE_MAX_RATIO, (unsigned)(msize - 5));
    if (!*z && !(*z = (lop__inflater *)lop__alloc(mem, sizeof **z)))
        return lop__fail0(err, lop_error_out_of_memory, "out of memory");
    r = lop__inflate(*z, m + 5, msize - 5, d, d, mem, &end);
    *text = (*z)->out;
    (*z)->out = NULL;
    *tsize = (*z)->n;
    if (r == LOP__Z_MEMORY)
        return lop__fail0(err, lop_error_out_of_memory, "out of memory for the manifest");
    if (r != LOP__Z_OK)
        return lop__fail0(err, lop_error_encoding, "manifest (encoded): %s", lop__z_why(r));
    if (*tsize != d)
        return lop__fail0(err, lop_error_encoding, "manifest (encoded): the deflate stream gives %lu bytes, not the %u "
                         "its size says", (unsigned long)*tsize, (unsigned)d);
    if (end != msize - 5)
        return lop__fail0(err, lop_error_encoding, "manifest (encoded): the deflate stream ends at byte %lu of its %u",
                         (unsigned long)end, (unsigned)(msize - 5));
    return 1;
}

/* Upper bounds of what the manifest can hold, from its JSON shape (before validation). */
static void lop__capacities(const lopj *j, uint32_t root, size_t *parts, size_t *lods, size_t *sections,
                            size_t *stages)
{
    uint32_t ps = lopj_get(j, root, "parts"), ss = lopj_get(j, root, "sections"), p, i;
    uint32_t st = lopj_get(j, lopj_get(j, root, "positions"), "stages");
    *parts = *lods = *sections = 0;
    *stages = lopj_type(j, st) == LOPJ_ARRAY && j->v[st].count ? j->v[st].count : 1;
    if (lopj_type(j, ss) == LOPJ_ARRAY)
        *sections = j->v[ss].count;
    if (lopj_type(j, ps) != LOPJ_ARRAY)
        return;
    for (i = 0, p = ps + 1; i < j->v[ps].count; i++, p = j->v[p].next) {
        uint32_t ls = lopj_get(j, p, "lods"), l, k;
        if (lopj_type(j, ls) != LOPJ_ARRAY || j->v[ls].count == 0)
            continue;
        (*parts)++;
        for (k = 0, l = ls + 1; k < j->v[ls].count; k++, l = j->v[l].next) {
            uint32_t vid = lopj_get(j, l, "vertex_id");
            if (lopj_type(j, vid) == LOPJ_ARRAY && j->v[vid].count == LOP_LEVELS + 1)
                (*lods)++;
        }
    }
}

/* Frees a file (or one lop_open gave up on): the decoded sections, then its block. */
static void lop__free_file(const lop_allocator *mem, lop_file *f)
{
    uint32_t i;
    if (!f)
        return;
    for (i = 0; i < f->section_count; i++)
        if (f->sections[i].encoding != LOP_ENCODING_NONE && f->sections[i].data)
            lop__free(mem, (void *)(uintptr_t)f->sections[i].data);
    lop__free(mem, f->block_);
}

/* The file's block (lop_file, parts, LODs, sections, stages, strings) and lop_open's scratch (the
   validator's tables), sized from the parsed manifest; 0 when out of memory. */
static int lop__allocate(const lopj *j, const lop_allocator *mem, lop_file **fo, void **scratch, lopv *v)
{
    size_t np, nl, ns, nst, parts_all, need, u32s, sz;
    uint32_t ps = lopj_get(j, 0, "parts");
    lop_file *f;
    char *at;
    lop__capacities(j, 0, &np, &nl, &ns, &nst);
    parts_all = lopj_type(j, ps) == LOPJ_ARRAY ? j->v[ps].count : 0;
    need = sizeof(lop_file);
    need = lop__sat_add(need, lop__mul(np, sizeof(lop_part)));
    need = lop__sat_add(need, lop__mul(nl, sizeof(lop_lod)));
    need = lop__sat_add(need, lop__mul(ns, sizeof(lop_section)));
    need = lop__sat_add(need, lop__mul(nst, sizeof(lop_stage)));
    need = lop__sat_add(need, (uint64_t)j->np + j->nv + 8);
    u32s = 2 * ns + parts_all + (nst + 1) + 2 * nl;
    sz = lop__mul(nst, sizeof(lopv_tot));
    sz = lop__sat_add(sz, lop__mul(2 * ns, sizeof(const lop_lod *)));
    sz = lop__sat_add(sz, lop__mul(u32s, sizeof(uint32_t)));
    sz = lop__sat_add(sz, ns + 8);
    if (need > (uint64_t)(size_t)-1 / 2 || sz > (uint64_t)(size_t)-1 / 2 || !lop__mul(nl, sizeof(lop_lod)) != !nl ||
        !lop__mul(ns, sizeof(lop_section)) != !ns)
        return 0;
    *fo = f = (lop_file *)lop__alloc(mem, need);
    if (f) { /* lop__free_file reads section_count and block_ if the scratch allocation fails */
        memset(f, 0, sizeof *f);
        f->block_ = f;
    }
    *scratch = lop__alloc(mem, sz);
    if (!f || !*scratch)
        return 0;
    f->parts = (lop_part *)(f + 1);
    f->sections = (lop_section *)(f->parts + np);
    f->stages = (lop_stage *)(f->sections + ns);
    memset(f->sections, 0, ns * sizeof(lop_section)); /* data stays NULL until a section is read */
    memset(f->stages, 0, nst * sizeof(lop_stage));
    f->stage_count = 1;
    v->lods = (lop_lod *)(f->stages + nst);
    v->strings = (char *)(v->lods + nl);
    v->lods_left = nl;
    v->parts_cap = (uint32_t)np;
    at = (char *)*scratch;
    v->tot = (lopv_tot *)at;
    memset(v->tot, 0, nst * sizeof(lopv_tot));
    at += nst * sizeof(lopv_tot);
    v->sec_first = (const lop_lod **)at;
    v->sec_last = v->sec_first + ns;
    at += 2 * ns * sizeof(const lop_lod *);
    v->names = (uint32_t *)at;
    v->name_val = v->names + ns;
    v->part_node = v->name_val + ns;
    v->stage_start = v->part_node + parts_all;
    v->order = v->stage_start + nst + 1;
    v->sec_other = (uint8_t *)(v->order + 2 * nl);
    return 1;
}

/* The version rules of format.md 11 on a validated manifest (class version). */
static int lop__version_rules(const lop_file *f, const lopv *v, lop__err *err)
{
    unsigned major = f->version_major, minor = f->version_minor;
    if (major == 2 && v->clustered)
        return lop__fail0(err, lop_error_version, "container version %u.%u must not hold clustered position buffers "
                         "(they need 3.x)", major, minor);
    if (major == 2 && v->has_placements && minor < 1)
        return lop__fail0(err, lop_error_version, "container version %u.%u must not hold placements (they need 3.x)",
                         major, minor);
    if (major < 4 && v->has_tangents)
        return lop__fail0(err, lop_error_version, "container version %u.%u must not hold tangents (they need 4.x)",
                         major, minor);
    if (major < 4 && (f->stream || v->has_encoded))
        return lop__fail0(err, lop_error_version, "container version %u.%u must not hold the streaming layout or "
                         "encoded sections (they need 4.x)", major, minor);
    return 1;
}

/* Every section complete in the bytes given: its CRC, then (encoded) its decoding; 0 with the error
   set. *end: where the table says the sections end. */
static int lop__read_sections(lop_file *f, const uint8_t *b, size_t size, uint64_t base, const lop__crc *crc,
                              const lopv *v, lop__inflater **z, const lop_allocator *mem, lop__err *err, uint64_t *end)
{
    uint32_t i;
    *end = base;
    for (i = 0; i < f->section_count; i++) {
        lop_section *s = &f->sections[i];
        uint64_t start = base + s->offset;
        *end = lop__sat_add(start, s->length);
        if (*end > (uint64_t)size) {
            if (!f->complete)
                break;
            return lop__fail0(err, lop_error_section_table, "section '%s' runs past the end of the file", s->name);
        }
        if (LOP__CHECK_CRC && lop__crc32(crc, b + start, s->length) != s->crc32)
            return lop__fail0(err, lop_error_section_crc, "section '%s' checksum mismatch", s->name);
        if (s->encoding == LOP_ENCODING_NONE)
            s->data = b + start;
        else if (!lop__decode_section(f, i, b + start, v->sec_last[i], z, mem, err))
            return 0;
    }
    if (f->section_count) /* a prefix's table lists every section: where they end is known */
        *end = lop__sat_add(base + f->sections[f->section_count - 1].offset,
                            f->sections[f->section_count - 1].length);
    return 1;
}

LOPDEF lop_result lop_open(const void *data, size_t size, const lop_options *options, lop_file **out,
                           lop_message *msg)
{
    const uint8_t *b = (const uint8_t *)data;
    lop__err err;
    lop_allocator mem;
    lop__crc *crc = NULL;
    lop__inflater *z = NULL;
    lopj j;
    lopv v;
    lop_file *f = NULL;
    void *scratch = NULL;
    uint8_t *mtext = NULL;
    const char *text;
    size_t tsize;
    uint16_t major, minor;
    uint32_t msize;
    uint64_t total, end;
    int truncated, allow_prefix = options ? options->allow_prefix : 0;
    err.code = lop_success;
    err.msg = msg;
    if (msg)
        msg->text[0] = 0;
    memset(&j, 0, sizeof j);
    memset(&v, 0, sizeof v);
    mem.alloc = options && options->memory.alloc ? options->memory.alloc : lop__default_alloc;
    mem.free = options && options->memory.free ? options->memory.free : lop__default_free;
    mem.user = options ? options->memory.user : NULL;
    if (!out)
        return lop__fail(&err, lop_error_argument, "no place for the result (out is NULL)");
    *out = NULL;
    if (!b && size)
        return lop__fail(&err, lop_error_argument, "data is NULL");
    if (size < 32)
        return lop__fail(&err, lop_error_truncated, "file is %lu bytes, shorter than the 32-byte header",
                         (unsigned long)size);
    if (memcmp(b, "LOPC", 4) != 0)
        return lop__fail(&err, lop_error_bad_magic, "bad magic %02x %02x %02x %02x (expected 'LOPC'): not a .lop "
                         "container", b[0], b[1], b[2], b[3]);
    crc = (lop__crc *)lop__alloc(&mem, sizeof *crc);
    if (!crc)
        return lop__fail(&err, lop_error_out_of_memory, "out of memory");
    lop__crc_init(crc);
    major = lop__rd16(b + 4);
    minor = lop__rd16(b + 6);
    msize = lop__rd32(b + 12);
    total = lop__rd64(b + 20);
    if (LOP__CHECK_CRC && lop__crc32(crc, b, 28) != lop__rd32(b + 28)) {
        lop__fail(&err, lop_error_header_crc, "header checksum mismatch");
        goto fail;
    }
    if (major < 2 || major > 4) {
        lop__fail(&err, lop_error_version, "container version %u.%u is not supported (this reader reads 2.x, 3.x and "
                  "4.x)", (unsigned)major, (unsigned)minor);
        goto fail;
    }
    if (lop__rd32(b + 8) != 32) {
        lop__fail(&err, lop_error_header, "header size %u (expected 32)", (unsigned)lop__rd32(b + 8));
        goto fail;
    }
    if ((uint64_t)size > total) {
        lop__fail(&err, lop_error_trailing_data, "%llu bytes of trailing data after the declared end (%llu bytes)",
                  (unsigned long long)((uint64_t)size - total), (unsigned long long)total);
        goto fail;
    }
    truncated = (uint64_t)size < total;
    if (truncated && !allow_prefix) {
        lop__fail(&err, lop_error_truncated, "file is truncated: %llu of %llu bytes", (unsigned long long)size,
                  (unsigned long long)total);
        goto fail;
    }
    if (32 + (uint64_t)msize > (uint64_t)size) {
        lop__fail(&err, lop_error_truncated, "manifest is truncated");
        goto fail;
    }
    if (LOP__CHECK_CRC && lop__crc32(crc, b + 32, msize) != lop__rd32(b + 16)) {
        lop__fail(&err, lop_error_manifest_crc, "manifest checksum mismatch");
        goto fail;
    }
    text = (const char *)b + 32;
    tsize = msize;
    if (msize > 0 && b[32] == 0) { /* an encoded manifest (format.md 4) */
        if (major < 4) {
            lop__fail(&err, lop_error_version, "container version %u.%u must not hold an encoded manifest (it needs "
                      "4.x)", (unsigned)major, (unsigned)minor);
            goto fail;
        }
        if (!lop__decode_manifest(b + 32, msize, &z, &mem, &mtext, &tsize, &err))
            goto fail;
        text = (const char *)mtext;
    }
    if (!lopj_parse(text, tsize, &mem, &err, &j))
        goto fail;
    if (!lop__allocate(&j, &mem, &f, &scratch, &v)) {
        lop__fail(&err, lop_error_out_of_memory, "out of memory for the manifest's %lu values", (unsigned long)j.nv);
        goto fail;
    }
    v.j = &j;
    v.text = text;
    v.err = &err;
    v.f = f;
    f->memory_ = mem;
    f->version_major = major;
    f->version_minor = minor;
    f->file_size = total;
    f->size = size;
    f->complete = !truncated;
    f->manifest_size = tsize;
    if (!lopv_manifest(&v, 0) || !lop__version_rules(f, &v, &err))
        goto fail;
    if (!lop__read_sections(f, b, size, 32 + (uint64_t)msize, crc, &v, &z, &mem, &err, &end))
        goto fail;
    if (end != total) {
        lop__fail(&err, lop_error_section_table, "sections end at byte %llu, file size says %llu",
                  (unsigned long long)end, (unsigned long long)total);
        goto fail;
    }
    if (!lop__check_indices(f, &err) || !lop__check_clusters(f, &err))
        goto fail;
    lop__plane_starts(f, v.stage_start, v.order);
    lop__stage_levels(f, v.stage_start, v.order);
    if (f->stages[0].available < 1) {
        lop__fail(&err, lop_error_truncated, f->stream ? "the file ends before the first stage's mandatory position bits"
                                                       : "the file ends before the mandatory position bits");
        goto fail;
    }
    lopj_release(&j, &mem);
    lop__free(&mem, scratch);
    lop__free(&mem, crc);
    lop__free(&mem, mtext);
    lop__free(&mem, z);
    *out = f;
    return lop_success;
fail:
    lopj_release(&j, &mem);
    lop__free(&mem, scratch);
    lop__free(&mem, crc);
    lop__free(&mem, mtext);
    if (z)
        lop__free(&mem, z->out);
    lop__free(&mem, z);
    lop__free_file(&mem, f);
    return err.code;
}

LOPDEF void lop_close(lop_file *f)
{
    if (f) {
        lop_allocator mem = f->memory_;
        lop__free_file(&mem, f);
    }

}

/* ---- queries --------------------------------------------------------------------------------- */

static lop_result lop__lookup(const lop_file *f, uint32_t part, uint32_t lod, const lop_part **pt, const lop_lod **e)
{
    if (!f || part >= f->part_count || lod >= f->parts[part].lod_count)
        return lop_error_argument;
    *pt = &f->parts[part];
    *e = &f->parts[part].lods[lod];
    return lop_success;
}

/* Level B of buffer e: in 1..24 and at most its stage's level in the bytes given. */
static lop_result lop__level_ok(const lop_file *f, const lop_lod *e, int level)
{
    return level >= 1 && level <= LOP_LEVELS && level <= f->stages[e->stage].available ? lop_success : lop_error_level;
}

LOPDEF int lop_buffer_level(const lop_file *f, uint32_t part, uint32_t lod)
{
    if (!f || part >= f->part_count || lod >= f->parts[part].lod_count)
        return -1;
    return f->stages[f->parts[part].lods[lod].stage].available;
}

LOPDEF lop_result lop_drawable(const lop_file *f, uint32_t part, uint32_t lod, uint32_t *drawn, int *level)
{
    const lop_part *pt;
    uint32_t k;
    if (!f || part >= f->part_count || !drawn || !level)
        return lop_error_argument;
    pt = &f->parts[part];
    for (k = lod < pt->lod_count ? lod : pt->lod_count - 1; k < pt->lod_count; k++)
        if (f->stages[pt->lods[k].stage].available >= 1) {
            *drawn = k;
            *level = f->stages[pt->lods[k].stage].available;
            return lop_success;
        }
    return lop_error_level; /* cannot happen in a file that opened: the coarsest LOD is in stage 0 */
}

LOPDEF int lop_part_level(const lop_file *f, uint32_t part, int level)
{
    int b;
    if (!f || part >= f->part_count || !f->parts[part].is_placement)
        return level;
    b = level + f->parts[part].level_shift;
    return b < 1 ? 1 : (b > LOP_LEVELS ? LOP_LEVELS : b);
}

/* pixel_error * (metres per pixel at 1 m): lopcook.viewing.Viewing.pixel_size(1) * pixel_error */
static double lop__per_metre(const lop_file *f)
{
    double t = lop__tan(f->fov_y_deg * (3.141592653589793 / 180.0) / 2.0);
    return f->pixel_error * ((2.0 * 1.0 * t) / (double)f->viewport[1]);
}

LOPDEF int lop_required_level(const lop_file *f, double distance_m)
{
    double t, allowed, dx;
    int b;
    if (!f || !(distance_m >= 0))
        return LOP_LEVELS;
    t = lop__tan(f->fov_y_deg * (3.141592653589793 / 180.0) / 2.0);
    allowed = f->pixel_error * (((2.0 * distance_m) * t) / (double)f->viewport[1]);
    dx = 1.7320508075688772 * f->grid_extent;
    for (b = 1; b <= LOP_LEVELS; b++)
        if (dx * lop__ldexp(1.0, -(b + 1)) <= allowed)
            break;
    if (b > LOP_LEVELS)
        b = LOP_LEVELS;
    return b < f->max_level ? b : f->max_level;
}

LOPDEF lop_result lop_select(const lop_file *f, uint32_t part, double distance_m, uint32_t *lod, int *level)
{
    const lop_part *pt;
    uint32_t k, best = 0;
    int have = 0;
    double per;
    if (!f || part >= f->part_count || !(distance_m >= 0) || !lod || !level)
        return lop_error_argument;
    pt = &f->parts[part];
    per = lop__per_metre(f);
    for (k = 0; k < pt->lod_count; k++)
        if (pt->lods[k].geometric_error_m / per <= distance_m &&
            (!have || pt->lods[k].triangles < pt->lods[best].triangles)) {
            best = k;
            have = 1;
        }
    *lod = best;
    *level = lop_required_level(f, distance_m);
    return lop_success;
}

/* ---- walking a buffer: top bits of every vertex, a chunk at a time ---------------------------- */

#define LOP__CHUNK 1024

/* A run of vertices that share a bin and, when clustered, a cluster. `val` holds their top bits at
   the level (NULL when the sink asked for none and `raw_bits` is nonzero: then the run's fields in
   P equal its level-1 fields, `raw_bits` bits from bit `raw_bit` of the mandatory words). */
typedef struct lop__chunk {
    uint32_t j0, n;      /* vertices [j0, j0 + n) */
    int bin, width;      /* their bin and bits per component max(bin, B) */
    const uint32_t *val; /* 3 n top-bit values, x y z */
    int clustered;       /* a cluster of a clustered buffer: */
    uint32_t header[3];  /* its header words a_t | k_t << 24 */
    int kt[3];
    const uint8_t *raw;  /* the mandatory words of the buffer */
    size_t raw_len;
    uint64_t raw_bit, raw_bits;
} lop__chunk;

typedef int (*lop__sink)(void *ctx, const lop__chunk *ch);

typedef struct lop__srcs {
    const uint8_t *mand;
    size_t mand_len;
    const uint8_t *plane[LOP_LEVELS + 1];
    size_t plane_len[LOP_LEVELS + 1];
    const uint8_t *head;
    size_t head_len;
} lop__srcs;

static const uint64_t lop__spread[8] = {
    0, 1, UINT64_C(1) << 21, 1 | UINT64_C(1) << 21, UINT64_C(1) << 42, 1 | UINT64_C(1) << 42,
    UINT64_C(1) << 21 | UINT64_C(1) << 42, 1 | UINT64_C(1) << 21 | UINT64_C(1) << 42};

/* The bytes buffer e reads at level B: its stage's mandatory words from its own, each plane 2..B
   (a plane's bytes: its section, or its part of the stage's deferred section), its cluster headers. */
static void lop__sources(const lop_file *f, const lop_lod *e, int level, lop__srcs *s)
{
    const lop_stage *st = &f->stages[e->stage];
    const lop_section *m = &f->sections[st->mandatory_section];
    int p;
    uint64_t off = 4 * e->mandatory_offset;
    s->mand = m->data + off;
    s->mand_len = (size_t)(m->size - off);
    for (p = 0; p <= LOP_LEVELS; p++) {
        s->plane[p] = NULL;
        s->plane_len[p] = 0;
    }
    for (p = 2; p <= level; p++) {
        const lop_section *ps;
        if (st->plane_section[p] < 0)
            continue; /* a plane without bits: no buffer reads it */
        ps = &f->sections[st->plane_section[p]];
        s->plane[p] = ps->data + st->plane_offset[p];
        s->plane_len[p] = (size_t)(f->stream ? lop__plane_bytes(st->plane_bits[p]) : ps->size);
    }
    s->head = NULL;
    s->head_len = 0;
    if (e->cluster_size) {
        const lop_section *h = &f->sections[st->clusters_section];
        s->head = h->data + 4 * e->cluster_words_offset;
        s->head_len = (size_t)(12u * (uint64_t)e->cluster_count);
    }
}

/* Unclustered: vertices [j, j + n) of bin k at level B (section 6.6), their level-1 fields from
   bit o of the mandatory words. */
/* Append plane bits to the lanes of n vertices, plane after plane (plane-major: one running bit
   offset and one 8-entry table per plane). lanes[l] holds x, y, z at bits 0, 21, 42. A plane q
   gives `nb[q]` (0..3) bits per vertex from bit `at[q]` of `pl[q]`, mapped through `tab[q]`. */
static void lop__lanes(uint64_t *lanes, uint32_t n, int np, const uint8_t *const *pl, const size_t *len,
                       const uint64_t *at, const unsigned *nb, const uint64_t (*tab)[8], int in)
{
    int q;
    uint32_t l;
    for (l = 0; l < n; l++)
        lanes[l] = 0;
    for (q = 0; q < np; q++) {
        const uint8_t *p = pl[q];
        const uint64_t *t = tab[q];
        uint64_t bit = at[q];
        unsigned step = nb[q], m = (1u << nb[q]) - 1u;
        if (!step) {
            for (l = 0; l < n; l++)
                lanes[l] = lanes[l] << 1 | t[0];
        } else if (in) {
            for (l = 0; l < n; l++, bit += step)
                lanes[l] = lanes[l] << 1 | t[(unsigned)lop__bits_in(p, bit) & m];
        } else {
            for (l = 0; l < n; l++, bit += step)
                lanes[l] = lanes[l] << 1 | t[(unsigned)lop__bits(p, len[q], bit) & m];
        }
    }
}

static void lop__unpack_bin(const lop_lod *e, const lop__srcs *s, int B, int k, uint64_t o, uint32_t j, uint32_t n,
                            uint32_t *val)
{
    uint64_t lanes[LOP__CHUNK], at[LOP_LEVELS], tab[LOP_LEVELS][8];
    const uint8_t *pl[LOP_LEVELS];
    size_t len[LOP_LEVELS];
    unsigned nb[LOP_LEVELS];
    uint32_t i, mk = (1u << k) - 1;
    int np = B > k ? B - k : 0, q, in;
    in = lop__loads_in(s->mand_len, o, 3u * (uint64_t)k * n);
    for (q = 0; q < np; q++) {
        int r;
        pl[q] = s->plane[k + 1 + q];
        len[q] = s->plane_len[k + 1 + q];
        at[q] = e->plane_start[k + 1 + q] + 3u * (uint64_t)j;
        nb[q] = 3;
        for (r = 0; r < 8; r++)
            tab[q][r] = lop__spread[r];
        in = in && lop__loads_in(len[q], at[q], 3u * (uint64_t)n);
    }
    if (np && np <= 21)
        lop__lanes(lanes, n, np, pl, len, at, nb, (const uint64_t(*)[8])tab, in);
    for (i = 0; i < n; i++, o += 3u * (uint64_t)k) {
        uint32_t x, y, z;
        if (k <= 19) {
            uint64_t m = lop__ld(s->mand, s->mand_len, o, in) & ((UINT64_C(1) << (3 * k)) - 1);
            x = (uint32_t)m & mk;
            y = (uint32_t)(m >> k) & mk;
            z = (uint32_t)(m >> (2 * k));
        } else {
            x = (uint32_t)lop__field(s->mand, s->mand_len, o, (unsigned)k);
            y = (uint32_t)lop__field(s->mand, s->mand_len, o + (unsigned)k, (unsigned)k);
            z = (uint32_t)lop__field(s->mand, s->mand_len, o + 2u * (unsigned)k, (unsigned)k);
        }
        if (np && np <= 21) {
            uint64_t acc = lanes[i], lane = (UINT64_C(1) << np) - 1;
            x = x << np | (uint32_t)(acc & lane);
            y = y << np | (uint32_t)((acc >> 21) & lane);
            z = z << np | (uint32_t)(acc >> 42);
        } else {
            for (q = 0; q < np; q++) {
                unsigned raw = (unsigned)lop__bits(pl[q], len[q], at[q] + 3u * i) & 7u;
                x = x << 1 | (raw & 1u);
                y = y << 1 | ((raw >> 1) & 1u);
                z = z << 1 | (raw >> 2);
            }
        }
        val[3 * i] = x;
        val[3 * i + 1] = y;
        val[3 * i + 2] = z;
    }
}

static int lop__walk_binned(const lop_lod *e, const lop__srcs *s, int B, int need_values, lop__sink sink, void *ctx)
{
    uint32_t val[3 * LOP__CHUNK];
    uint64_t bit1 = 0;
    int k;
    lop__chunk ch;
    memset(&ch, 0, sizeof ch);
    ch.raw = s->mand;
    ch.raw_len = s->mand_len;
    for (k = 1; k <= LOP_LEVELS; k++) {
        uint32_t j = e->vertex_id[k - 1], end = e->vertex_id[k];
        while (j < end) {
            uint32_t n = end - j < LOP__CHUNK ? end - j : LOP__CHUNK;
            uint64_t o = bit1 + 3u * (uint64_t)k * (j - e->vertex_id[k - 1]);
            ch.j0 = j;
            ch.n = n;
            ch.bin = k;
            ch.width = k > B ? k : B;
            ch.raw_bit = o;
            ch.raw_bits = k >= B ? 3u * (uint64_t)k * n : 0;
            ch.val = NULL;
            if (need_values || !ch.raw_bits) {
                lop__unpack_bin(e, s, B, k, o, j, n, val);
                ch.val = val;
            }
            if (!sink(ctx, &ch))
                return 0;
            j += n;
        }
        bit1 += 3u * (uint64_t)k * (end - e->vertex_id[k - 1]);
    }
    return 1;
}

/* Clustered (section 6.9): cluster after cluster, the level-1 fields then plane bits (stored for
   components with k_t < p, the anchor's otherwise). */
static int lop__walk_clustered(const lop_lod *e, const lop__srcs *s, int B, int need_values, lop__sink sink, void *ctx)
{
    uint32_t val[3 * 1024];
    uint64_t table[8][8];
    uint64_t mand_bit = 0, pbit[LOP_LEVELS + 1];
    uint32_t c = 0;
    int bin, pat, raw, p;
    lop__chunk ch;
    memset(&ch, 0, sizeof ch);
    memset(pbit, 0, sizeof pbit);
    ch.clustered = 1;
    ch.raw = s->mand;
    ch.raw_len = s->mand_len;
    for (pat = 0; pat < 8; pat++) /* raw stored bits -> lanes of the components pattern stores */
        for (raw = 0; raw < 8; raw++) {
            uint64_t lanes = 0;
            int t, used = 0;
            for (t = 0; t < 3; t++)
                if (pat >> t & 1)
                    lanes |= (uint64_t)((raw >> used++) & 1) << (21 * t);
            table[pat][raw] = lanes;
        }
    for (bin = 1; bin <= LOP_LEVELS; bin++) {
        uint32_t j = e->vertex_id[bin - 1], end = e->vertex_id[bin];
        while (j < end) {
            uint32_t n = end - j < e->cluster_size ? end - j : e->cluster_size, l, a[3], base[3], mask[3];
            int kt[3], t, b = bin > B ? bin : B, w1[3], s1 = 0, np = b - bin;
            int pattern[LOP_LEVELS + 1], nbits[LOP_LEVELS + 1];
            uint64_t anchor_bits[LOP_LEVELS + 1];
            for (t = 0; t < 3; t++) {
                uint32_t h = lop__rd32(s->head + 12u * (uint64_t)c + 4u * (unsigned)t);
                ch.header[t] = h;
                kt[t] = (int)(h >> 24);
                a[t] = h & 0xFFFFFFu;
                ch.kt[t] = kt[t];
                w1[t] = bin > kt[t] ? bin - kt[t] : 0;
                base[t] = bin > kt[t] ? a[t] << w1[t] : a[t] >> (kt[t] - bin);
                mask[t] = (1u << w1[t]) - 1;
                s1 += w1[t];
            }
            for (p = bin + 1; p <= LOP_LEVELS; p++)
                nbits[p] = (kt[0] < p) + (kt[1] < p) + (kt[2] < p);
            for (p = bin + 1; p <= b && (need_values || np); p++) {
                pattern[p] = (kt[0] < p) | (kt[1] < p) << 1 | (kt[2] < p) << 2;
                anchor_bits[p] = 0;
                for (t = 0; t < 3; t++)
                    if (kt[t] >= p)
                        anchor_bits[p] |= (uint64_t)((a[t] >> (kt[t] - p)) & 1u) << (21 * t);
            }
            ch.j0 = j;
            ch.n = n;
            ch.bin = bin;
            ch.width = b;
            ch.raw_bit = mand_bit;
            ch.raw_bits = np == 0 ? (uint64_t)n * (uint64_t)s1 : 0;
            ch.val = NULL;
            if (need_values || np) {
                const uint8_t *pp[LOP_LEVELS];
                uint64_t pb[LOP_LEVELS], ptab[LOP_LEVELS][8], m1 = s1 <= 57 ? (UINT64_C(1) << s1) - 1 : 0;
                uint64_t lanes[1024];
                size_t pl[LOP_LEVELS];
                unsigned pn[LOP_LEVELS];
                int q, in = lop__loads_in(s->mand_len, mand_bit, (uint64_t)n * (uint64_t)s1);
                for (q = 0; q < np && np <= 21; q++) {
                    p = bin + 1 + q;
                    pn[q] = (unsigned)nbits[p];
                    for (raw = 0; raw < 8; raw++)
                        ptab[q][raw] = table[pattern[p]][raw] | anchor_bits[p];
                    pp[q] = pn[q] ? s->plane[p] : lop__zeros;
                    pl[q] = pn[q] ? s->plane_len[p] : sizeof lop__zeros;
                    pb[q] = pn[q] ? e->plane_start[p] + pbit[p] : 0;
                    in = in && (!pn[q] || lop__loads_in(pl[q], pb[q], (uint64_t)n * pn[q]));
                }
                if (np > 0 && np <= 21)
                    lop__lanes(lanes, n, np, pp, pl, pb, pn, (const uint64_t(*)[8])ptab, in);
                for (l = 0; l < n; l++) {
                    uint64_t o = mand_bit + (uint64_t)l * (uint64_t)s1;
                    uint32_t v[3];
                    if (s1 <= 57) {
                        uint64_t m = lop__ld(s->mand, s->mand_len, o, in) & m1;
                        v[0] = base[0] | ((uint32_t)m & mask[0]);
                        v[1] = base[1] | ((uint32_t)(m >> w1[0]) & mask[1]);
                        v[2] = base[2] | (uint32_t)(m >> (w1[0] + w1[1]));
                    } else {
                        for (t = 0; t < 3; t++) {
                            v[t] = base[t] | (uint32_t)lop__field(s->mand, s->mand_len, o, (unsigned)w1[t]);
                            o += (unsigned)w1[t];
                        }
                    }
                    if (np > 0 && np <= 21) {
                        uint64_t acc = lanes[l], lane = (UINT64_C(1) << np) - 1;
                        v[0] = v[0] << np | (uint32_t)(acc & lane);
                        v[1] = v[1] << np | (uint32_t)((acc >> 21) & lane);
                        v[2] = v[2] << np | (uint32_t)(acc >> 42);
                    } else if (np > 21) {
                        for (p = bin + 1; p <= b; p++) {
                            unsigned r = 0;
                            uint64_t lns;
                            if (nbits[p])
                                r = (unsigned)lop__field(s->plane[p], s->plane_len[p],
                                                         e->plane_start[p] + pbit[p] + (uint64_t)l * (unsigned)nbits[p],
                                                         (unsigned)nbits[p]);
                            lns = table[pattern[p]][r] | anchor_bits[p];
                            for (t = 0; t < 3; t++)
                                v[t] = v[t] << 1 | (uint32_t)((lns >> (21 * t)) & 1u);
                        }
                    }
                    val[3 * l] = v[0];
                    val[3 * l + 1] = v[1];
                    val[3 * l + 2] = v[2];
                }
                ch.val = val;
            }
            if (!sink(ctx, &ch))
                return 0;
            mand_bit += (uint64_t)n * (uint64_t)s1;
            for (p = bin + 1; p <= LOP_LEVELS; p++)
                pbit[p] += (uint64_t)n * (uint64_t)nbits[p];
            j += n;
            c++;
        }
    }
    return 1;
}

/* Every vertex of a buffer at level B, in order, to `sink`. need_values 0: a run whose fields in P
   equal its level-1 fields is passed as raw bits, without its values. */
static int lop__walk(const lop_file *f, const lop_lod *e, int B, int need_values, lop__sink sink, void *ctx)
{
    lop__srcs s;
    lop__sources(f, e, B, &s);
    return e->cluster_size ? lop__walk_clustered(e, &s, B, need_values, sink, ctx)
                           : lop__walk_binned(e, &s, B, need_values, sink, ctx);
}

/* ---- packing P ----------------------------------------------------------------------------- */

typedef struct lop__bw {
    uint32_t *out;
    uint64_t cap, pos; /* words */
    uint64_t acc;
    unsigned n;        /* bits in acc */
    uint64_t total;    /* bits written */
} lop__bw;

static inline void lop__put(lop__bw *w, uint64_t v, unsigned bits) /* bits <= 57, v < 2^bits */
{
    w->acc |= v << w->n;
    w->total += bits;
    if (w->n + bits >= 64) {
        unsigned used = 64 - w->n;
        if (w->pos + 2 <= w->cap) {
            w->out[w->pos] = (uint32_t)w->acc;
            w->out[w->pos + 1] = (uint32_t)(w->acc >> 32);
        }
        w->pos += 2;
        w->acc = used < 64 ? v >> used : 0;
        w->n = w->n + bits - 64;
    } else {
        w->n += bits;
    }
}

/* nbits bits of a bit stream from bit `bit` on: 64 at a time while the source and the output have
   room (one shift-merge of two loads per output word), the rest 56 at a time. */
static void lop__put_bits(lop__bw *w, const uint8_t *src, size_t len, uint64_t bit, uint64_t nbits)
{
    unsigned sh = (unsigned)(bit & 7), n = w->n;
    uint64_t acc = w->acc, pos = w->pos, cap = w->cap;
    uint32_t *out = w->out;
    uint64_t words = 0;
    /* (locals: stores to out[] cannot alias the writer's state) */
    while (nbits >= 64 && (bit >> 3) + 9 <= (uint64_t)len && pos + 2 <= cap) {
        uint64_t v = lop__bits_in(src, bit), o;
        if (sh)
            v |= (uint64_t)src[(bit >> 3) + 8] << (64 - sh);
        o = acc | v << n;
        out[pos] = (uint32_t)o;
        out[pos + 1] = (uint32_t)(o >> 32);
        pos += 2;
        acc = n ? v >> (64 - n) : 0;
        bit += 64;
        nbits -= 64;
        words++;
    }
    w->acc = acc;
    w->pos = pos;
    w->total += 64 * words;
    while (nbits >= 56) {
        lop__put(w, lop__bits(src, len, bit) & ((UINT64_C(1) << 56) - 1), 56);
        bit += 56;
        nbits -= 56;
    }
    if (nbits)
        lop__put(w, lop__field(src, len, bit, (unsigned)nbits), (unsigned)nbits);
}

static void lop__flush(lop__bw *w)
{
    while (w->n > 0) {
        if (w->pos < w->cap)
            w->out[w->pos] = (uint32_t)w->acc;
        w->pos++;
        w->acc >>= 32;
        w->n = w->n > 32 ? w->n - 32 : 0;
    }
    while (w->pos < w->cap)
        w->out[w->pos++] = 0;
}

typedef struct lop__pack {
    lop__bw w;
    int level;
    lop_layout layout;
    uint32_t *records;
    uint64_t record_words, cluster;
} lop__pack;

static int lop__sink_pack(void *ctx, const lop__chunk *ch)
{
    lop__pack *pk = (lop__pack *)ctx;
    const uint32_t *v = ch->val;
    uint32_t i;
    if (pk->layout == LOP_LAYOUT_UNIFORM) {
        unsigned b = (unsigned)pk->level, down = (unsigned)(ch->width - pk->level);
        for (i = 0; i < ch->n; i++, v += 3) {
            if (b <= 19)
                lop__put(&pk->w, (uint64_t)(v[0] >> down) | (uint64_t)(v[1] >> down) << b | (uint64_t)(v[2] >> down) << 2 * b, 3 * b);
            else {
                lop__put(&pk->w, v[0] >> down, b);
                lop__put(&pk->w, v[1] >> down, b);
                lop__put(&pk->w, v[2] >> down, b);
            }
        }
        return 1;
    }
    if (pk->layout == LOP_LAYOUT_NATIVE && ch->clustered) {
        unsigned wt[3], t;
        uint32_t mask[3];
        if (pk->records && 4 * pk->cluster + 4 <= pk->record_words) {
            uint32_t *r = pk->records + 4 * pk->cluster;
            r[0] = ch->header[0];
            r[1] = ch->header[1];
            r[2] = ch->header[2];
            r[3] = (uint32_t)pk->w.total;
        }
        pk->cluster++;
        if (!v) { /* the cluster's fields at its own level: as stored */
            lop__put_bits(&pk->w, ch->raw, ch->raw_len, ch->raw_bit, ch->raw_bits);
            return 1;
        }
        for (t = 0; t < 3; t++) {
            wt[t] = ch->width > ch->kt[t] ? (unsigned)(ch->width - ch->kt[t]) : 0u;
            mask[t] = (uint32_t)((UINT64_C(1) << wt[t]) - 1);
        }
        if (wt[0] + wt[1] + wt[2] <= 57) {
            for (i = 0; i < ch->n; i++, v += 3)
                lop__put(&pk->w, (uint64_t)(v[0] & mask[0]) | (uint64_t)(v[1] & mask[1]) << wt[0] |
                                     (uint64_t)(v[2] & mask[2]) << (wt[0] + wt[1]), wt[0] + wt[1] + wt[2]);
        } else {
            for (i = 0; i < ch->n; i++, v += 3)
                for (t = 0; t < 3; t++)
                    lop__put(&pk->w, v[t] & mask[t], wt[t]);
        }
        return 1;
    }
    if (!v) { /* a bin at or above B: its fields as stored */
        lop__put_bits(&pk->w, ch->raw, ch->raw_len, ch->raw_bit, ch->raw_bits);
        return 1;
    }
    {
        unsigned b = (unsigned)ch->width;
        for (i = 0; i < ch->n; i++, v += 3) {
            if (b <= 19)
                lop__put(&pk->w, (uint64_t)v[0] | (uint64_t)v[1] << b | (uint64_t)v[2] << 2 * b, 3 * b);
            else {
                lop__put(&pk->w, v[0], b);
                lop__put(&pk->w, v[1], b);
                lop__put(&pk->w, v[2], b);
            }
        }
    }
    return 1;
}

/* Bits of P in a layout at level B: binned BitId_B[24], uniform 3 B n, clustered ClusterBit[n_c]. */
static uint64_t lop__p_bits(const lop_file *f, const lop_lod *e, int B, lop_layout layout)
{
    uint64_t bits = 0;
    int k;
    if (layout == LOP_LAYOUT_UNIFORM)
        return 3u * (uint64_t)B * e->vertices;
    if (layout == LOP_LAYOUT_NATIVE && e->cluster_size) {
        const lop_section *h = &f->sections[f->stages[e->stage].clusters_section];
        uint32_t c = 0;
        for (k = 1; k <= LOP_LEVELS; k++) {
            uint32_t left = e->vertex_id[k] - e->vertex_id[k - 1];
            int b = k > B ? k : B;
            while (left) {
                uint32_t count = left < e->cluster_size ? left : e->cluster_size;
                const uint8_t *hd = h->data + 4 * (e->cluster_words_offset + 3u * (uint64_t)c);
                int t, s = 0;
                for (t = 0; t < 3; t++) {
                    int kt = (int)(lop__rd32(hd + 4 * t) >> 24);
                    s += b > kt ? b - kt : 0;
                }
                bits += (uint64_t)count * (uint64_t)s;
                left -= count;
                c++;
            }
        }
        return bits;
    }
    for (k = 1; k <= LOP_LEVELS; k++)
        bits += 3u * (uint64_t)(k > B ? k : B) * (e->vertex_id[k] - e->vertex_id[k - 1]);
    return bits;
}

LOPDEF lop_result lop_buffer(const lop_file *f, uint32_t part, uint32_t lod, int level, lop_layout layout,
                             lop_buffer_info *info)
{
    const lop_part *pt;
    const lop_lod *e;
    lop_result r = lop__lookup(f, part, lod, &pt, &e);
    uint64_t bits;
    int clustered;
    if (r != lop_success || !info || (unsigned)layout > LOP_LAYOUT_UNIFORM)
        return lop_error_argument;
    if ((r = lop__level_ok(f, e, level)) != lop_success)
        return r;
    clustered = layout == LOP_LAYOUT_NATIVE && e->cluster_size;
    bits = lop__p_bits(f, e, level, layout);
    info->words = (bits + 31) / 32;
    if (clustered && info->words == 0)
        info->words = 1;
    info->clusters = clustered ? e->cluster_count : 0;
    info->block_size = clustered ? LOP_CLUSTERED_BLOCK_SIZE : LOP_DECODE_BLOCK_SIZE;
    info->vertices = e->vertices;
    info->level = level;
    info->clustered = clustered;
    return lop_success;
}

LOPDEF lop_result lop_build(const lop_file *f, uint32_t part, uint32_t lod, int level, lop_layout layout,
                            uint32_t *words, size_t word_count, uint32_t *records, size_t record_words)
{
    lop_buffer_info info;
    lop__pack pk;
    const lop_part *pt = NULL;
    const lop_lod *e = NULL;
    lop_result r = lop_buffer(f, part, lod, level, layout, &info);
    if (r != lop_success)
        return r;
    lop__lookup(f, part, lod, &pt, &e);
    if (!words || word_count < info.words || (info.clusters && (!records || record_words < 4u * (uint64_t)info.clusters)))
        return lop_error_argument;
    memset(&pk, 0, sizeof pk);
    pk.w.out = words;
    pk.w.cap = info.words;
    pk.level = level;
    pk.layout = layout;
    pk.records = info.clusters ? records : NULL;
    pk.record_words = info.clusters ? record_words : 0;
    lop__walk(f, e, level, layout == LOP_LAYOUT_UNIFORM || (layout == LOP_LAYOUT_BINNED && e->cluster_size),
              lop__sink_pack, &pk);
    lop__flush(&pk.w);
    return lop_success;
}

/* ---- float decodes --------------------------------------------------------------------------- */

typedef struct lop__floats {
    float *out;
    float origin[3], half;
    const float *tf; /* NULL: no placement transform */
} lop__floats;

/* Section 6.7 then 6.8: c = (2 v + 1) << (24 - b); p = origin + float32(c) * half (each operation
   one float32 rounding); a placement then ((a0 p0 + a1 p1) + a2 p2) + t per row. */
static int lop__sink_floats(void *ctx, const lop__chunk *ch)
{
    LOP__NO_CONTRACT
    const lop__floats *fl = (const lop__floats *)ctx;
    const uint32_t *v = ch->val;
    float *o = fl->out + 3 * (size_t)ch->j0;
    const float ox = fl->origin[0], oy = fl->origin[1], oz = fl->origin[2], h = fl->half;
    unsigned s = (unsigned)(LOP_LEVELS - ch->width);
    uint32_t i;
    if (!fl->tf) {
        for (i = 0; i < ch->n; i++, v += 3, o += 3) {
            float cx = (float)(((v[0] << 1) | 1u) << s), cy = (float)(((v[1] << 1) | 1u) << s);
            float cz = (float)(((v[2] << 1) | 1u) << s);
            float tx = LOP__FENCE(cx * h), ty = LOP__FENCE(cy * h), tz = LOP__FENCE(cz * h);
            o[0] = ox + tx;
            o[1] = oy + ty;
            o[2] = oz + tz;
        }
    } else {
        const float a00 = fl->tf[0], a01 = fl->tf[1], a02 = fl->tf[2], t0 = fl->tf[3];
        const float a10 = fl->tf[4], a11 = fl->tf[5], a12 = fl->tf[6], t1 = fl->tf[7];
        const float a20 = fl->tf[8], a21 = fl->tf[9], a22 = fl->tf[10], t2 = fl->tf[11];
        for (i = 0; i < ch->n; i++, v += 3, o += 3) {
            float cx = (float)(((v[0] << 1) | 1u) << s), cy = (float)(((v[1] << 1) | 1u) << s);
            float cz = (float)(((v[2] << 1) | 1u) << s);
            float tx = LOP__FENCE(cx * h), ty = LOP__FENCE(cy * h), tz = LOP__FENCE(cz * h);
            float px = ox + tx, py = oy + ty, pz = oz + tz;
            float x0 = LOP__FENCE(a00 * px), x1 = LOP__FENCE(a01 * py), x2 = LOP__FENCE(a02 * pz);
            float y0 = LOP__FENCE(a10 * px), y1 = LOP__FENCE(a11 * py), y2 = LOP__FENCE(a12 * pz);
            float z0 = LOP__FENCE(a20 * px), z1 = LOP__FENCE(a21 * py), z2 = LOP__FENCE(a22 * pz);
            float sx = x0 + x1, sy = y0 + y1, sz = z0 + z1;
            sx = sx + x2;
            sy = sy + y2;
            sz = sz + z2;
            o[0] = sx + t0;
            o[1] = sy + t1;
            o[2] = sz + t2;
        }
    }
    return 1;
}

LOPDEF lop_result lop_decode_positions(const lop_file *f, uint32_t part, uint32_t lod, int level, float *xyz,
                                       size_t vertex_count, unsigned flags)
{
    const lop_part *pt;
    const lop_lod *e;
    lop__floats fl;
    lop_result r = lop__lookup(f, part, lod, &pt, &e);
    if (r != lop_success || !xyz)
        return lop_error_argument;
    if ((r = lop__level_ok(f, e, level)) != lop_success)
        return r;
    if (vertex_count < e->vertices)
        return lop_error_argument;
    fl.out = xyz;
    fl.origin[0] = (float)pt->grid_origin[0];
    fl.origin[1] = (float)pt->grid_origin[1];
    fl.origin[2] = (float)pt->grid_origin[2];
    fl.half = (float)(pt->grid_extent / 16777216.0 / 2.0);
    fl.tf = pt->is_placement && !(flags & LOP_LOCAL) ? pt->transform : NULL;
    lop__walk(f, e, level, 1, lop__sink_floats, &fl);
    return lop_success;
}

typedef struct lop__grid {
    uint32_t *values;
    uint8_t *widths;
} lop__grid;

static int lop__sink_grid(void *ctx, const lop__chunk *ch)
{
    lop__grid *g = (lop__grid *)ctx;
    memcpy(g->values + 3 * (size_t)ch->j0, ch->val, 12 * (size_t)ch->n);
    if (g->widths)
        memset(g->widths + ch->j0, ch->width, ch->n);
    return 1;
}

LOPDEF lop_result lop_decode_grid(const lop_file *f, uint32_t part, uint32_t lod, int level, uint32_t *values,
                                  uint8_t *widths, size_t vertex_count)
{
    const lop_part *pt;
    const lop_lod *e;
    lop__grid g;
    lop_result r = lop__lookup(f, part, lod, &pt, &e);
    if (r != lop_success || !values)
        return lop_error_argument;
    if ((r = lop__level_ok(f, e, level)) != lop_success)
        return r;
    if (vertex_count < e->vertices)
        return lop_error_argument;
    g.values = values;
    g.widths = widths;
    lop__walk(f, e, level, 1, lop__sink_grid, &g);
    return lop_success;
}

/* ---- uniform blocks ---------------------------------------------------------------------------- */

static lop_result lop__table32(uint8_t *out, const uint64_t *t)
{
    int k;
    for (k = 0; k < 32; k++) {
        uint64_t x = k <= LOP_LEVELS ? t[k] : 0xFFFFFFFFu;
        if (x > 0xFFFFFFFFu)
            return lop_error_limit;
        lop__wr32(out + 4 * k, (uint32_t)x);
    }
    return lop_success;
}

LOPDEF lop_result lop_decode_block(const lop_file *f, uint32_t part, uint32_t lod, int level, lop_layout layout,
                                   void *block, size_t block_size)
{
    const lop_part *pt = NULL;
    const lop_lod *e = NULL;
    lop_buffer_info info;
    uint8_t *out = (uint8_t *)block;
    uint64_t vid[LOP_LEVELS + 1], bid[LOP_LEVELS + 1];
    int k;
    lop_result r = lop_buffer(f, part, lod, level, layout, &info);
    if (r != lop_success)
        return r;
    lop__lookup(f, part, lod, &pt, &e);
    if (!block || block_size < info.block_size)
        return lop_error_argument;
    bid[0] = 0;
    for (k = 0; k <= LOP_LEVELS; k++) {
        if (layout == LOP_LAYOUT_UNIFORM)
            vid[k] = k ? e->vertices : 0;
        else
            vid[k] = e->vertex_id[k];
        if (k)
            bid[k] = info.clustered ? 0 : bid[k - 1] + 3u * (uint64_t)(layout == LOP_LAYOUT_UNIFORM || k < level ? level : k) *
                                                           (vid[k] - vid[k - 1]);
    }
    if (lop__table32(out, vid) != lop_success || lop__table32(out + 128, bid) != lop_success ||
        info.words > 0xFFFFFFFFu)
        return lop_error_limit;
    lop__wrf(out + 256, (float)pt->grid_origin[0]);
    lop__wrf(out + 260, (float)pt->grid_origin[1]);
    lop__wrf(out + 264, (float)pt->grid_origin[2]);
    lop__wrf(out + 268, (float)(pt->grid_extent / 16777216.0 / 2.0));
    lop__wr32(out + 272, (uint32_t)level);
    lop__wr32(out + 276, (uint32_t)(info.words ? info.words : 1));
    lop__wr32(out + 280, info.clustered ? e->cluster_size : 0u);
    lop__wr32(out + 284, 0);
    if (info.clustered) {
        uint64_t cid[LOP_LEVELS + 1];
        for (k = 0; k <= LOP_LEVELS; k++)
            cid[k] = e->cluster_id[k];
        if (e->vertices >= (1u << 26))
            return lop_error_limit; /* the clustered decoder's lop_div holds for r < 2^26 */
        lop__table32(out + 288, cid);
    }
    return lop_success;
}

LOPDEF lop_result lop_attribute_words(const lop_file *f, uint32_t part, uint32_t lod, const uint8_t **bytes,
                                      size_t *size)
{
    const lop_part *pt;
    const lop_lod *e;
    if (lop__lookup(f, part, lod, &pt, &e) != lop_success || !bytes || !size)
        return lop_error_argument;
    *bytes = NULL;
    *size = 0;
    if (e->attributes_section >= 0 && !f->sections[e->attributes_section].data)
        return lop_error_level; /* its stage has not arrived */
    if (e->attributes_section >= 0) {
        *bytes = f->sections[e->attributes_section].data;
        *size = (size_t)f->sections[e->attributes_section].size;
    }
    return lop_success;
}

LOPDEF lop_result lop_attribute_block(const lop_file *f, uint32_t part, uint32_t lod, void *block, size_t block_size)
{
    const lop_part *pt;
    const lop_lod *e;
    uint8_t *out = (uint8_t *)block;
    uint64_t words;
    if (lop__lookup(f, part, lod, &pt, &e) != lop_success || !block || block_size < LOP_ATTRIBUTE_BLOCK_SIZE)
        return lop_error_argument;
    words = e->attributes_section >= 0 ? f->sections[e->attributes_section].size / 4 : 0;
    if (words > 0xFFFFFFFFu || (uint64_t)e->vertices * e->record_bits >= (UINT64_C(1) << 32))
        return lop_error_limit;
    lop__wr32(out, (uint32_t)e->normal_bits);
    lop__wr32(out + 4, (uint32_t)e->uv_bits);
    lop__wr32(out + 8, (uint32_t)e->color_bits);
    lop__wr32(out + 12, e->record_bits);
    lop__wrf(out + 16, e->normal_bits ? (float)(1.0 / (double)((1 << (e->normal_bits - 1)) - 1)) : 0.0f);
    lop__wrf(out + 20, e->color_bits ? (float)(1.0 / (double)((1 << e->color_bits) - 1)) : 0.0f);
    lop__wrf(out + 24, e->tangent_bits ? (float)(1.0 / (double)((1 << (e->tangent_bits - 1)) - 1)) : 0.0f);
    lop__wrf(out + 28, 0.0f);
    lop__wrf(out + 32, e->uv_lo[0]);
    lop__wrf(out + 36, e->uv_lo[1]);
    lop__wrf(out + 40, e->uv_step[0]);
    lop__wrf(out + 44, e->uv_step[1]);
    lop__wr32(out + 48, (uint32_t)(words ? words : 1));
    lop__wr32(out + 52, (uint32_t)e->tangent_bits);
    lop__wr32(out + 56, 0);
    lop__wr32(out + 60, 0);
    return lop_success;
}

/* lopcook.verify.decoders.view_tables and gpu.view_block */
LOPDEF lop_result lop_view_block(const lop_file *f, const float camera[3], void *block, size_t block_size)
{
    uint8_t *out = (uint8_t *)block;
    double k, s = 0.0;
    int b, i;
    if (!f || !camera || !block || block_size < LOP_VIEW_BLOCK_SIZE)
        return lop_error_argument;
    memset(out, 0, LOP_VIEW_BLOCK_SIZE);
    k = f->pixel_error * 2.0 * lop__tan(f->fov_y_deg * (3.141592653589793 / 180.0) / 2.0) / (double)f->viewport[1];
    for (i = 0; i < 3; i++) {
        double o = f->grid_origin[i] < 0 ? -f->grid_origin[i] : f->grid_origin[i];
        s = o > s ? o : s;
        lop__wrf(out + 4 * i, camera[i]);
    }
    s += f->grid_extent;
    for (b = 1; b <= LOP_LEVELS; b++) {
        double d = 1.7320508075688772 * f->grid_extent * lop__ldexp(1.0, -(b + 1));
        lop__wrf(out + 16 + 4 * b, (float)(d / k * (1.0 + 2.0 * k) * (1.0 + LOP__POW2(-8))));
        lop__wrf(out + 144 + 4 * b, (float)(d * (1.0 + LOP__POW2(-10)) + LOP__POW2(-21) * s));
    }
    return lop_success;
}

/* ---- attributes and indices ------------------------------------------------------------------- */

/* The w-bit field at bit o of a record section of `words` words (the shaders' read, second word
   clamped to the last). */
static uint32_t lop__attr_field(const uint8_t *d, uint64_t words, uint64_t o, unsigned w)
{
    uint64_t w0 = o >> 5, w1 = w0 + 1 < words ? w0 + 1 : words - 1;
    unsigned s = (unsigned)(o & 31);
    uint32_t lo = lop__rd32(d + 4 * w0) >> s;
    uint32_t hi = (lop__rd32(d + 4 * w1) << 1) << (31 - s);
    return (lo | hi) & (uint32_t)((UINT64_C(1) << w) - 1);
}

static void lop__oct(uint32_t cx, uint32_t cy, int bits, float *n)
{
    LOP__NO_CONTRACT
    int h = 1 << (bits - 1);
    float r = (float)(1.0 / (double)(h - 1));
    float px = (float)((int)cx - h) * r, py = (float)((int)cy - h) * r;
    float ax, ay, z;
    px = px < -1.0f ? -1.0f : px;
    py = py < -1.0f ? -1.0f : py;
    ax = px < 0 ? -px : px;
    ay = py < 0 ? -py : py;
    z = (1.0f - ax) - ay;
    if (z < 0.0f) {
        n[0] = (1.0f - ay) * (px >= 0.0f ? 1.0f : -1.0f);
        n[1] = (1.0f - ax) * (py >= 0.0f ? 1.0f : -1.0f);
    } else {
        n[0] = px;
        n[1] = py;
    }
    n[2] = z;
}

static void lop__uv(uint32_t q0, uint32_t q1, const lop_lod *e, float *uv)
{
    LOP__NO_CONTRACT
    float p0 = LOP__FENCE((float)q0 * e->uv_step[0]);
    float p1 = LOP__FENCE((float)q1 * e->uv_step[1]);
    uv[0] = e->uv_lo[0] + p0;
    uv[1] = e->uv_lo[1] + p1;
}

LOPDEF lop_result lop_decode_attributes(const lop_file *f, uint32_t part, uint32_t lod, const lop_attributes *out,
                                        size_t vertex_count)
{
    const lop_part *pt;
    const lop_lod *e;
    const uint8_t *d;
    uint64_t words, o;
    uint32_t j;
    float cscale;
    if (lop__lookup(f, part, lod, &pt, &e) != lop_success || !out || vertex_count < e->vertices)
        return lop_error_argument;
    if (!f->sections[e->indices_section].data || (e->attributes_section >= 0 && !f->sections[e->attributes_section].data))
        return lop_error_level; /* its stage has not arrived */
    if (e->attributes_section < 0)
        return lop_success;
    d = f->sections[e->attributes_section].data;
    words = f->sections[e->attributes_section].size / 4;
    cscale = e->color_bits ? (float)(1.0 / (double)((1 << e->color_bits) - 1)) : 0.0f;
    for (j = 0, o = 0; j < e->vertices; j++, o += e->record_bits) {
        uint64_t at = o;
        unsigned bn = (unsigned)e->normal_bits, bu = (unsigned)e->uv_bits, bc = (unsigned)e->color_bits;
        unsigned bt = (unsigned)e->tangent_bits;
        if (bn) {
            if (out->normals)
                lop__oct(lop__attr_field(d, words, at, bn), lop__attr_field(d, words, at + bn, bn), (int)bn,
                         out->normals + 3 * (size_t)j);
            at += 2 * bn;
        }
        if (bu) {
            if (out->uvs)
                lop__uv(lop__attr_field(d, words, at, bu), lop__attr_field(d, words, at + bu, bu), e,
                        out->uvs + 2 * (size_t)j);
            at += 2 * bu;
        }
        if (bc) {
            if (out->colors) {
                int t;
                for (t = 0; t < 4; t++)
                    out->colors[4 * (size_t)j + (size_t)t] = (float)lop__attr_field(d, words, at + (unsigned)t * bc, bc) * cscale;
            }
            at += 4 * bc;
        }
        if (bt && out->tangents) {
            float *tg = out->tangents + 4 * (size_t)j;
            lop__oct(lop__attr_field(d, words, at, bt), lop__attr_field(d, words, at + bt, bt), (int)bt, tg);
            tg[3] = lop__attr_field(d, words, at + 2 * bt, 1) ? -1.0f : 1.0f;
        }
    }
    return lop_success;
}

LOPDEF lop_result lop_decode_indices(const lop_file *f, uint32_t part, uint32_t lod, uint32_t *indices,
                                     size_t index_count)
{
    const lop_part *pt;
    const lop_lod *e;
    const uint8_t *d;
    uint64_t t, n;
    if (lop__lookup(f, part, lod, &pt, &e) != lop_success || !indices)
        return lop_error_argument;
    n = 3u * (uint64_t)e->triangles;
    if (index_count < n)
        return lop_error_argument;
    d = f->sections[e->indices_section].data;
    if (!d)
        return lop_error_level; /* its stage has not arrived */
    if (e->index_width == 2)
        for (t = 0; t < n; t++)
            indices[t] = lop__rd16(d + 2 * t);
    else
        for (t = 0; t < n; t++)
            indices[t] = lop__rd32(d + 4 * t);
    return lop_success;
}

#endif /* LOP_IMPLEMENTATION_DONE */
#endif /* LOP_IMPLEMENTATION */
