/* lopcheck: drive lop.h over files and their mutations, in one process (for the sanitizer runs of
   tests/runtime/test_c_reader.py).

   lopcheck [--prefix] FILE...     open each file (with prefixes allowed), and when it opens, use
                                   every query and decode at every level it holds
   lopcheck --flips FILE           every single-byte flip (XOR 0xFF) of FILE
   lopcheck --truncations FILE     every prefix of FILE shorter than it
   lopcheck --oom FILE             fail the allocator's k-th call, for every k lop_open makes

   One line per input or mutation: `NAME VERDICT PREFIX_VERDICT`, a verdict being the error class
   (lop_result_name) or `ok:L` (opened; L the available level). Every allocation goes through a
   counting allocator: a block still held after lop_close, or a freed pointer the allocator did not
   give, is reported and makes the exit status 1. Exit 0 otherwise, whatever the verdicts. */
#define LOP_IMPLEMENTATION
#include "../lop.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct counter {
    long live, calls, fail_at; /* fail_at: the call to refuse (-1: none) */
    int bad;
} counter;

static void *count_alloc(void *user, size_t size)
{
    counter *c = (counter *)user;
    size_t *p;
    if (c->fail_at >= 0 && c->calls++ == c->fail_at)
        return NULL;
    if (c->fail_at < 0)
        c->calls++;
    p = (size_t *)malloc(size + 16);
    if (!p)
        return NULL;
    p[0] = 0x10Cc0C0Du;
    c->live++;
    return (unsigned char *)p + 16;
}

static void count_free(void *user, void *ptr)
{
    counter *c = (counter *)user;
    size_t *p = (size_t *)((unsigned char *)ptr - 16);
    if (p[0] != 0x10Cc0C0Du) {
        c->bad = 1;
        return;
    }
    p[0] = 0;
    c->live--;
    free(p);
}

static unsigned char *read_all(const char *path, size_t *size)
{
    FILE *fh = fopen(path, "rb");
    unsigned char *buf;
    long n;
    if (!fh || fseek(fh, 0, SEEK_END) != 0 || (n = ftell(fh)) < 0 || fseek(fh, 0, SEEK_SET) != 0) {
        if (fh)
            fclose(fh);
        return NULL;
    }
    buf = (unsigned char *)malloc((size_t)n + 1);
    if (!buf || fread(buf, 1, (size_t)n, fh) != (size_t)n) {
        free(buf);
        fclose(fh);
        return NULL;
    }
    fclose(fh);
    *size = (size_t)n;
    return buf;
}

static volatile uint32_t g_sink;

/* Every query and decode of every buffer at every level the file holds. */
static void exercise(const lop_file *f)
{
    uint32_t i, k;
    int level, layout;
    float cam[3] = {1.0f, 2.0f, 3.0f};
    unsigned char block[LOP_CLUSTERED_BLOCK_SIZE], view[LOP_VIEW_BLOCK_SIZE];
    lop_view_block(f, cam, view, sizeof view);
    lop_required_level(f, 10.0);
    for (i = 0; i < f->part_count; i++) {
        uint32_t lod;
        int sel;
        lop_select(f, i, 3.0, &lod, &sel);
        for (k = 0; k < f->parts[i].lod_count; k++) {
            const lop_lod *e = &f->parts[i].lods[k];
            size_t n = e->vertices;
            float *xyz = (float *)malloc(12 * n), *nrm = (float *)malloc(12 * n), *uv = (float *)malloc(8 * n);
            float *col = (float *)malloc(16 * n), *tan = (float *)malloc(16 * n);
            uint32_t *grid = (uint32_t *)malloc(12 * n), *idx = (uint32_t *)malloc(12 * (size_t)e->triangles);
            uint8_t *wid = (uint8_t *)malloc(n);
            const uint8_t *words;
            size_t bytes;
            lop_attributes a;
            a.normals = nrm;
            a.uvs = uv;
            a.colors = col;
            a.tangents = tan;
            if (xyz && nrm && uv && col && tan && grid && idx && wid) {
                lop_decode_attributes(f, i, k, &a, n);
                lop_decode_indices(f, i, k, idx, 3 * (size_t)e->triangles);
                lop_attribute_block(f, i, k, block, sizeof block);
                lop_attribute_words(f, i, k, &words, &bytes);
                for (level = 0; level <= f->available_level + 1; level++) {
                    lop_decode_positions(f, i, k, level, xyz, n, 0);
                    lop_decode_positions(f, i, k, level, xyz, n, LOP_LOCAL);
                    lop_decode_grid(f, i, k, level, grid, wid, n);
                    g_sink += n ? (uint32_t)xyz[0] + grid[0] : 0;
                    for (layout = 0; layout <= 2; layout++) {
                        lop_buffer_info info;
                        uint32_t *w, *r;
                        if (lop_buffer(f, i, k, level, (lop_layout)layout, &info) != lop_success)
                            continue;
                        w = (uint32_t *)malloc(4 * (size_t)info.words + 4);
                        r = (uint32_t *)malloc(16 * (size_t)info.clusters + 16);
                        if (w && r) {
                            lop_build(f, i, k, level, (lop_layout)layout, w, (size_t)info.words, r,
                                      4 * (size_t)info.clusters);
                            lop_decode_block(f, i, k, level, (lop_layout)layout, block, sizeof block);
                            g_sink += w[0];
                        }
                        free(w);
                        free(r);
                    }
                }
            }
            free(xyz);
            free(nrm);
            free(uv);
            free(col);
            free(tan);
            free(grid);
            free(idx);
            free(wid);
        }
    }
}

static int g_bad;

/* Open (and exercise) one input in one mode; the verdict into out. */
static void verdict(const unsigned char *data, size_t size, int prefix, char *out, size_t cap, int use)
{
    counter c;
    lop_options opt;
    lop_file *f = NULL;
    lop_message msg;
    lop_result r;
    memset(&c, 0, sizeof c);
    c.fail_at = -1;
    memset(&opt, 0, sizeof opt);
    opt.memory.alloc = count_alloc;
    opt.memory.free = count_free;
    opt.memory.user = &c;
    opt.allow_prefix = prefix;
    r = lop_open(data, size, &opt, &f, &msg);
    if (r == lop_success) {
        snprintf(out, cap, "ok:%d", f->available_level);
        if (use)
            exercise(f);
        lop_close(f);
    } else {
        snprintf(out, cap, "%s", lop_result_name(r));
        if (f || !msg.text[0] || strchr(msg.text, '\n')) {
            fprintf(stderr, "lopcheck: a failed open left a file, no message or a multi-line one (%s)\n", msg.text);
            g_bad = 1;
        }
    }
    if (c.live != 0 || c.bad) {
        fprintf(stderr, "lopcheck: %ld allocations still held after lop_close, or a bad free\n", c.live);
        g_bad = 1;
    }
}

static void line(const char *name, const unsigned char *data, size_t size, int use)
{
    char a[64], b[64];
    verdict(data, size, 0, a, sizeof a, use);
    verdict(data, size, 1, b, sizeof b, use);
    printf("%s %s %s\n", name, a, b);
}

int main(int argc, char **argv)
{
    int a, prefix = 0;
    const char *mode = NULL;
    for (a = 1; a < argc; a++) {
        unsigned char *data;
        size_t size = 0, i;
        char name[64];
        if (!strcmp(argv[a], "--prefix") || !strcmp(argv[a], "--flips") || !strcmp(argv[a], "--truncations") ||
            !strcmp(argv[a], "--oom")) {
            mode = argv[a];
            prefix = !strcmp(argv[a], "--prefix");
            continue;
        }
        data = read_all(argv[a], &size);
        if (!data) {
            fprintf(stderr, "lopcheck: cannot read %s\n", argv[a]);
            return 2;
        }
        if (!mode || prefix) {
            char v[64];
            verdict(data, size, prefix, v, sizeof v, 1);
            printf("%s %s\n", argv[a], v);
        } else if (!strcmp(mode, "--flips")) {
            for (i = 0; i < size; i++) {
                data[i] ^= 0xFF;
                sprintf(name, "flip:%lu", (unsigned long)i);
                line(name, data, size, 1);
                data[i] ^= 0xFF;
            }
        } else if (!strcmp(mode, "--truncations")) {
            for (i = 0; i < size; i++) {
                unsigned char *cut = (unsigned char *)malloc(i + 1); /* its own block: reads past it are caught */
                if (!cut)
                    return 2;
                memcpy(cut, data, i);
                sprintf(name, "cut:%lu", (unsigned long)i);
                line(name, cut, i, 1);
                free(cut);
            }
        } else { /* --oom */
            counter c;
            lop_options opt;
            lop_file *f = NULL;
            long calls, k;
            memset(&c, 0, sizeof c);
            c.fail_at = -1;
            memset(&opt, 0, sizeof opt);
            opt.memory.alloc = count_alloc;
            opt.memory.free = count_free;
            opt.memory.user = &c;
            opt.allow_prefix = 1;
            if (lop_open(data, size, &opt, &f, NULL) == lop_success)
                lop_close(f);
            calls = c.calls;
            for (k = 0; k < calls; k++) {
                lop_result r;
                memset(&c, 0, sizeof c);
                c.fail_at = k;
                f = NULL;
                r = lop_open(data, size, &opt, &f, NULL);
                printf("oom:%ld %s\n", k, lop_result_name(r));
                if (r == lop_success)
                    lop_close(f);
                if (c.live != 0 || c.bad || (r != lop_success && f)) {
                    fprintf(stderr, "lopcheck: allocation %ld refused: %ld blocks leaked\n", k, c.live);
                    g_bad = 1;
                }
            }
        }
        free(data);
    }
    return g_bad;
}
