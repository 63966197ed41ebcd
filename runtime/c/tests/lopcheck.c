/* lopcheck: drive lop.h over files and their mutations, in one process (for the sanitizer runs of
   tests/runtime/test_c_reader.py).

   lopcheck [--prefix] FILE...     open each file (with prefixes allowed), and when it opens, use
                                   every query and decode at every level it holds
   lopcheck --flips FILE           every single-byte flip (XOR 0xFF) of FILE
   lopcheck --truncations FILE     every prefix of FILE shorter than it
   lopcheck --oom FILE             fail the allocator's k-th call, for every k lop_open makes

   One line per input or mutation: `NAME VERDICT PREFIX_VERDICT`, a verdict being the error class
   (lop_result_name) or `ok:L` (opened; L the available level), in the streaming layout
   `ok:L/S0,S1,...` (S the level of each stage). Every allocation goes through a
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

#include "exercise.h"

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
        size_t at = (size_t)snprintf(out, cap, "ok:%d", f->available_level);
        uint32_t s;
        for (s = 0; f->stream && s < f->stage_count && at + 16 < cap; s++) /* the stage levels */
            at += (size_t)snprintf(out + at, cap - at, "%c%d", s ? ',' : '/', f->stages[s].available);
        if (use)
            lop_exercise(f, 0);
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
    char a[4096], b[4096];
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
            char v[4096];
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
