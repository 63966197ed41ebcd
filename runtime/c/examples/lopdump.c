/* lopdump: decode a .lop with lop.h and write what a renderer or a test compares.

   lopdump FILE.lop --level B [--lod K] [--prefix] [--positions OUT.f32] [--gpu OUT.bin]
           [--attributes OUT.bin] [--json] [--distance D]

   --positions  the float32 xyz (little-endian) of every vertex of every part and placement, in
                manifest order (part, then the LOD's vertex order), world metres (a placement's
                transform applied); LOD K, or a part's coarsest when it has fewer LODs (as
                `lopcook decode` draws it). Byte for byte what `lopcook decode --positions` writes.
   --gpu        per buffer (each part that owns its buffers, manifest order, the same LOD): what
                an engine uploads at level B: the LopDecode block and P in the file's own layout
                (plus the cluster records of a clustered buffer), the block and P of the binned
                layout (clustered buffers only), the block and P of AP (every vertex B bits), then
                the 64-byte LopAttributeDecode block. Little-endian uint32 words.
   --attributes per buffer (same order): the indices as uint32, then the float32 decodes of the
                normals (3, unnormalised), UVs (2), colours (4) and tangents (4) it has.
   --json       one JSON object: version, sizes, levels, the stages (each one's level L_s, its level
                in the bytes given and its buffers; one stage in the default layout), and per part
                its LODs (vertices, triangles, errors, attribute bits, stage, the level the buffer
                decodes at, and the bytes of P at level B or the buffer's level when lower) and
                `drawable`: the LOD a renderer draws for --lod K (the finest arrived at or coarser
                than K) and its level; with --distance D also `selection`: per part the LOD and
                level lop_select gives at D metres.
   --prefix     accept a prefix of a file (docs/format.md sections 8 and 14.4). Every buffer an
                output decodes (each part's LOD K, or its coarsest) must hold level B.

   Exit 0, or 2 with one line on stderr (a bad file: its error class and what is wrong). Outputs
   are written to a temporary name and renamed, so a failed run leaves none. */
#define LOP_IMPLEMENTATION
#include "../lop.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *g_file = "";

static int die(const char *fmt, const char *a, const char *b)
{
    fprintf(stderr, "lopdump: ");
    fprintf(stderr, fmt, a, b);
    fputc('\n', stderr);
    return 2;
}

static unsigned char *read_all(const char *path, size_t *size)
{
    FILE *fh = fopen(path, "rb");
    unsigned char *buf = NULL;
    size_t cap = 0, n = 0;
    if (!fh)
        return NULL;
    for (;;) {
        size_t got;
        if (n == cap) {
            unsigned char *nb;
            cap = cap ? 2 * cap : 1 << 16;
            nb = (unsigned char *)realloc(buf, cap);
            if (!nb) {
                free(buf);
                fclose(fh);
                return NULL;
            }
            buf = nb;
        }
        got = fread(buf + n, 1, cap - n, fh);
        n += got;
        if (got == 0)
            break;
    }
    if (ferror(fh)) {
        free(buf);
        fclose(fh);
        return NULL;
    }
    fclose(fh);
    *size = n;
    return buf ? buf : (unsigned char *)malloc(1);
}

/* An output written under a temporary name, renamed when complete. */
typedef struct out_file {
    FILE *fh;
    const char *path;
    char tmp[4096];
    int failed;
} out_file;

static int out_open(out_file *o, const char *path)
{
    memset(o, 0, sizeof *o);
    if (!path)
        return 1;
    o->path = path;
    if (strlen(path) + 16 > sizeof o->tmp)
        return 0;
    sprintf(o->tmp, "%s.lopdump-tmp", path);
    o->fh = fopen(o->tmp, "wb");
    return o->fh != NULL;
}

static void out_write(out_file *o, const void *data, size_t n)
{
    if (o->fh && n && fwrite(data, 1, n, o->fh) != n)
        o->failed = 1;
}

static void out_words(out_file *o, const uint32_t *w, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        unsigned char b[4];
        b[0] = (unsigned char)w[i];
        b[1] = (unsigned char)(w[i] >> 8);
        b[2] = (unsigned char)(w[i] >> 16);
        b[3] = (unsigned char)(w[i] >> 24);
        out_write(o, b, 4);
    }
}

static void out_floats(out_file *o, const float *v, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, &v[i], 4);
        out_words(o, &u, 1);
    }
}

static int out_close(out_file *o, int keep)
{
    int ok = 1;
    if (!o->fh)
        return 1;
    if (fclose(o->fh) != 0 || o->failed)
        ok = 0;
    o->fh = NULL;
    if (!keep || !ok) {
        remove(o->tmp);
        return ok;
    }
    if (rename(o->tmp, o->path) != 0) {
        remove(o->tmp);
        return 0;
    }
    return 1;
}

static void json_string(const char *s)
{
    putchar('"');
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            printf("\\%c", c);
        else if (c < 0x20 || c >= 0x7f)
            printf("\\u%04x", c);
        else
            putchar(c);
    }
    putchar('"');
}

static uint32_t lod_of(const lop_part *p, uint32_t k) { return k < p->lod_count ? k : p->lod_count - 1; }

static int write_positions(const lop_file *f, int level, uint32_t lod, out_file *o)
{
    uint32_t i;
    for (i = 0; i < f->part_count; i++) {
        uint32_t k = lod_of(&f->parts[i], lod), n = f->parts[i].lods[k].vertices;
        float *xyz = (float *)malloc(12 * (size_t)n);
        if (!xyz)
            return 0;
        if (lop_decode_positions(f, i, k, level, xyz, n, 0) != lop_success) {
            free(xyz);
            return 0;
        }
        out_floats(o, xyz, 3 * (size_t)n);
        free(xyz);
    }
    return 1;
}

static int write_layout(const lop_file *f, uint32_t i, uint32_t k, int level, lop_layout layout, out_file *o)
{
    lop_buffer_info info;
    unsigned char block[LOP_CLUSTERED_BLOCK_SIZE];
    uint32_t *words, *records;
    int ok;
    if (lop_buffer(f, i, k, level, layout, &info) != lop_success ||
        lop_decode_block(f, i, k, level, layout, block, sizeof block) != lop_success)
        return 0;
    words = (uint32_t *)malloc(4 * (size_t)info.words + 4);
    records = (uint32_t *)malloc(16 * (size_t)info.clusters + 16);
    ok = words && records &&
         lop_build(f, i, k, level, layout, words, (size_t)info.words, records, 4 * (size_t)info.clusters) == lop_success;
    if (ok) {
        out_write(o, block, info.block_size);
        out_words(o, words, (size_t)info.words);
        out_words(o, records, 4 * (size_t)info.clusters);
    }
    free(words);
    free(records);
    return ok;
}

static int write_gpu(const lop_file *f, int level, uint32_t lod, out_file *o)
{
    uint32_t i;
    for (i = 0; i < f->part_count; i++) {
        uint32_t k = lod_of(&f->parts[i], lod);
        unsigned char ab[LOP_ATTRIBUTE_BLOCK_SIZE];
        if (f->parts[i].owner != (int32_t)i)
            continue;
        if (!write_layout(f, i, k, level, LOP_LAYOUT_NATIVE, o) ||
            (f->parts[i].lods[k].cluster_size && !write_layout(f, i, k, level, LOP_LAYOUT_BINNED, o)) ||
            !write_layout(f, i, k, level, LOP_LAYOUT_UNIFORM, o) ||
            lop_attribute_block(f, i, k, ab, sizeof ab) != lop_success)
            return 0;
        out_write(o, ab, sizeof ab);
    }
    return 1;
}

static int write_attributes(const lop_file *f, uint32_t lod, out_file *o)
{
    uint32_t i;
    for (i = 0; i < f->part_count; i++) {
        uint32_t k = lod_of(&f->parts[i], lod);
        const lop_lod *e = &f->parts[i].lods[k];
        size_t n = e->vertices;
        uint32_t *idx;
        lop_attributes a;
        int ok;
        if (f->parts[i].owner != (int32_t)i)
            continue;
        idx = (uint32_t *)malloc(12 * (size_t)e->triangles);
        a.normals = e->normal_bits ? (float *)malloc(12 * n) : NULL;
        a.uvs = e->uv_bits ? (float *)malloc(8 * n) : NULL;
        a.colors = e->color_bits ? (float *)malloc(16 * n) : NULL;
        a.tangents = e->tangent_bits ? (float *)malloc(16 * n) : NULL;
        ok = idx && (!e->normal_bits || a.normals) && (!e->uv_bits || a.uvs) && (!e->color_bits || a.colors) &&
             (!e->tangent_bits || a.tangents) &&
             lop_decode_indices(f, i, k, idx, 3 * (size_t)e->triangles) == lop_success &&
             lop_decode_attributes(f, i, k, &a, n) == lop_success;
        if (ok) {
            out_words(o, idx, 3 * (size_t)e->triangles);
            if (a.normals)
                out_floats(o, a.normals, 3 * n);
            if (a.uvs)
                out_floats(o, a.uvs, 2 * n);
            if (a.colors)
                out_floats(o, a.colors, 4 * n);
            if (a.tangents)
                out_floats(o, a.tangents, 4 * n);
        }
        free(idx);
        free(a.normals);
        free(a.uvs);
        free(a.colors);
        free(a.tangents);
        if (!ok)
            return 0;
    }
    return 1;
}

static void print_json(const lop_file *f, int level, uint32_t lod, double distance)
{
    uint32_t i, k;
    uint64_t positions = 0;
    printf("{\"file\":");
    json_string(g_file);
    printf(",\"version\":\"%u.%u\",\"file_size\":%llu,\"size\":%llu,\"complete\":%s,\"max_level\":%d,"
           "\"available_level\":%d,\"level\":%d,\"lod\":%u,\"generator\":",
           (unsigned)f->version_major, (unsigned)f->version_minor, (unsigned long long)f->file_size,
           (unsigned long long)f->size, f->complete ? "true" : "false", f->max_level, f->available_level, level,
           (unsigned)lod);
    json_string(f->generator);
    printf(",\"stream\":%s,\"stages\":[", f->stream ? "true" : "false");
    for (i = 0; i < f->stage_count; i++)
        printf("%s{\"level\":%d,\"available\":%d,\"buffers\":%u}", i ? "," : "", f->stages[i].level,
               f->stages[i].available, (unsigned)f->stages[i].buffers);
    printf("],\"parts\":[");
    for (i = 0; i < f->part_count; i++) {
        const lop_part *p = &f->parts[i];
        printf("%s{\"name\":", i ? "," : "");
        json_string(p->name);
        printf(",\"owner\":%d,\"placement\":%s,\"level_shift\":%d,\"lods\":[", (int)p->owner,
               p->is_placement ? "true" : "false", (int)p->level_shift);
        for (k = 0; k < p->lod_count; k++) {
            const lop_lod *e = &p->lods[k];
            lop_buffer_info info;
            memset(&info, 0, sizeof info);
            int have = lop_buffer_level(f, i, k), want = lop_part_level(f, i, level);
            memset(&info, 0, sizeof info);
            lop_buffer(f, i, k, want < have ? want : have, LOP_LAYOUT_NATIVE, &info);
            printf("%s{\"vertices\":%u,\"triangles\":%u,\"geometric_error_m\":%.17g,\"cluster_size\":%u,"
                   "\"attribute_bits\":{\"normals\":%d,\"uvs\":%d,\"colors\":%d,\"tangents\":%d},\"record_bits\":%u,"
                   "\"stage\":%u,\"level\":%d,\"p_level\":%d,\"p_bytes\":%llu,\"cluster_record_bytes\":%llu}",
                   k ? "," : "", (unsigned)e->vertices, (unsigned)e->triangles, e->geometric_error_m,
                   (unsigned)e->cluster_size, e->normal_bits, e->uv_bits, e->color_bits, e->tangent_bits,
                   (unsigned)e->record_bits, (unsigned)e->stage, have, info.level,
                   (unsigned long long)(4 * info.words), (unsigned long long)(16 * (uint64_t)info.clusters));
        }
        {
            uint32_t drawn = 0;
            int at = 0;
            lop_drawable(f, i, lod_of(p, lod), &drawn, &at);
            printf("],\"drawable\":[%u,%d]}", (unsigned)drawn, at);
        }
        positions += 12u * (uint64_t)p->lods[lod_of(p, lod)].vertices;
    }
    printf("],\"positions_bytes\":%llu", (unsigned long long)positions);
    if (distance >= 0) {
        printf(",\"distance\":%.17g,\"required_level\":%d,\"selection\":[", distance, lop_required_level(f, distance));
        for (i = 0; i < f->part_count; i++) {
            uint32_t sl = 0;
            int sv = 0;
            lop_select(f, i, distance, &sl, &sv);
            printf("%s[%u,%d]", i ? "," : "", (unsigned)sl, sv);
        }
        printf("]");
    }
    printf("}\n");
}

int main(int argc, char **argv)
{
    const char *path = NULL, *pos_path = NULL, *gpu_path = NULL, *attr_path = NULL;
    int level = 0, json = 0, prefix = 0, ok = 1, a;
    double distance = -1.0;
    long lod = 0;
    unsigned char *data;
    size_t size = 0;
    uint32_t i, deepest = 0;
    lop_file *f = NULL;
    lop_message msg;
    lop_options opt;
    lop_result r;
    out_file o_pos, o_gpu, o_attr;
    for (a = 1; a < argc; a++) {
        const char *s = argv[a];
        char *end;
        if (!strcmp(s, "--level") && a + 1 < argc) {
            long v = strtol(argv[++a], &end, 10);
            if (*end || v < -1000 || v > 1000)
                return die("--level %s: expected an integer%s", argv[a], "");
            level = (int)v;
        } else if (!strcmp(s, "--lod") && a + 1 < argc) {
            lod = strtol(argv[++a], &end, 10);
            if (*end || lod < 0 || lod > 1000000)
                return die("--lod %s: expected a LOD index >= 0%s", argv[a], "");
        } else if (!strcmp(s, "--positions") && a + 1 < argc) {
            pos_path = argv[++a];
        } else if (!strcmp(s, "--gpu") && a + 1 < argc) {
            gpu_path = argv[++a];
        } else if (!strcmp(s, "--attributes") && a + 1 < argc) {
            attr_path = argv[++a];
        } else if (!strcmp(s, "--distance") && a + 1 < argc) {
            distance = strtod(argv[++a], &end);
            if (*end || !(distance >= 0))
                return die("--distance %s: expected a distance >= 0 in metres%s", argv[a], "");
        } else if (!strcmp(s, "--json")) {
            json = 1;
        } else if (!strcmp(s, "--prefix")) {
            prefix = 1;
        } else if (s[0] == '-' || path) {
            return die("unknown or incomplete argument %s (usage: lopdump FILE.lop --level B [--lod K] [--prefix] "
                       "[--positions OUT.f32] [--gpu OUT.bin] [--attributes OUT.bin] [--json])%s", s, "");
        } else {
            path = s;
        }
    }
    if (!path)
        return die("no FILE.lop given (usage: lopdump FILE.lop --level B [--lod K] [--positions OUT.f32] [--json])%s%s",
                   "", "");
    g_file = path;
    if (level < 1 || level > LOP_LEVELS)
        return die("--level %s: give a level B in [1, 24]%s", level ? "outside [1, 24]" : "missing", "");
    data = read_all(path, &size);
    if (!data)
        return die("%s: cannot read the file%s", path, "");
    memset(&opt, 0, sizeof opt);
    opt.allow_prefix = prefix;
    r = lop_open(data, size, &opt, &f, &msg);
    if (r != lop_success) {
        fprintf(stderr, "lopdump: %s: %s: %s (the file is corrupt or not a lopcook container)\n", path,
                lop_result_name(r), msg.text);
        free(data);
        return 2;
    }
    for (i = 0; i < f->part_count; i++)
        deepest = f->parts[i].lod_count > deepest ? f->parts[i].lod_count : deepest;
    if ((uint32_t)lod >= deepest) {
        fprintf(stderr, "lopdump: %s: --lod %ld: no part has LOD %ld (the file has LODs 0..%u)\n", path, lod, lod,
                (unsigned)deepest - 1);
        lop_close(f);
        free(data);
        return 2;
    }
    if (pos_path || gpu_path || attr_path) { /* every buffer these outputs decode holds the level */
        for (i = 0; i < f->part_count; i++) {
            uint32_t k = lod_of(&f->parts[i], (uint32_t)lod);
            int have = lop_buffer_level(f, i, k);
            if (level > have) {
                if (f->stream)
                    fprintf(stderr, "lopdump: %s: level %d of part %u LOD %u is not in this file (%s %d)\n", path,
                            level, (unsigned)i, (unsigned)k, have ? "its stage holds levels up to" : "its stage has not "
                            "arrived: level", have);
                else
                    fprintf(stderr, "lopdump: %s: level %d is not in this file (it holds levels up to %d)\n", path,
                            level, have);
                lop_close(f);
                free(data);
                return 2;
            }
        }
    }
    if (!out_open(&o_pos, pos_path) || !out_open(&o_gpu, gpu_path) || !out_open(&o_attr, attr_path)) {
        fprintf(stderr, "lopdump: cannot write the outputs\n");
        out_close(&o_pos, 0);
        out_close(&o_gpu, 0);
        out_close(&o_attr, 0);
        lop_close(f);
        free(data);
        return 2;
    }
    if (pos_path)
        ok = ok && write_positions(f, level, (uint32_t)lod, &o_pos);
    if (gpu_path)
        ok = ok && write_gpu(f, level, (uint32_t)lod, &o_gpu);
    if (attr_path)
        ok = ok && write_attributes(f, (uint32_t)lod, &o_attr);
    ok = out_close(&o_pos, ok) && ok;
    ok = out_close(&o_gpu, ok) && ok;
    ok = out_close(&o_attr, ok) && ok;
    if (!ok)
        fprintf(stderr, "lopdump: %s: could not decode or write the outputs (out of memory or disk full)\n", path);
    else if (json)
        print_json(f, level, (uint32_t)lod, distance);
    lop_close(f);
    free(data);
    return ok ? 0 : 2;
}
