/* bench_c_reader: speed of runtime/c/lop.h on one core, next to memcpy of the same bytes.

   bench_c_reader FILE.lop [--levels 11,16] [--runs N]

   For each level B: builds P (the file's own layout, clustered where the file clusters, with the
   cluster records) of every distinct buffer of LOD 0 (each part owning its buffers), and decodes
   the float32 positions of every part (placements included); each timed as the median of N runs
   (default 9) of the whole set, next to memcpy of exactly as many bytes between two buffers of
   that size. Prints one JSON object per line: what, level, output bytes, seconds, GB/s (10^9 bytes
   of output per second) and the memcpy GB/s measured in the same run. benchmarks/bench_c_reader.py
   runs it on the 1.1M-triangle mesh and the chess set (docs/runtime-c.md, "Speed"). */
#define _POSIX_C_SOURCE 199309L
#define LOP_IMPLEMENTATION
#include "../runtime/c/lop.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return v[n / 2];
}

typedef struct buf {
    uint32_t part, words, records;
    uint32_t *w, *r;
} buf;

static volatile uint32_t g_sink;

int main(int argc, char **argv)
{
    const char *path = NULL;
    int levels[24], nlevels = 0, runs = 9, a, li, run;
    unsigned char *data;
    long size;
    FILE *fh;
    lop_file *f;
    lop_message msg;
    for (a = 1; a < argc; a++) {
        if (!strcmp(argv[a], "--levels") && a + 1 < argc) {
            char *s = argv[++a];
            while (*s && nlevels < 24) {
                levels[nlevels++] = (int)strtol(s, &s, 10);
                if (*s == ',')
                    s++;
            }
        } else if (!strcmp(argv[a], "--runs") && a + 1 < argc) {
            runs = atoi(argv[++a]);
        } else {
            path = argv[a];
        }
    }
    if (!nlevels) {
        levels[0] = 11;
        levels[1] = 16;
        nlevels = 2;
    }
    if (!path || runs < 1 || runs > 1000) {
        fprintf(stderr, "usage: bench_c_reader FILE.lop [--levels 11,16] [--runs N]\n");
        return 2;
    }
    fh = fopen(path, "rb");
    if (!fh || fseek(fh, 0, SEEK_END) != 0 || (size = ftell(fh)) < 0 || fseek(fh, 0, SEEK_SET) != 0) {
        fprintf(stderr, "bench_c_reader: cannot read %s\n", path);
        return 2;
    }
    data = (unsigned char *)malloc((size_t)size + 1);
    if (!data || fread(data, 1, (size_t)size, fh) != (size_t)size) {
        fprintf(stderr, "bench_c_reader: cannot read %s\n", path);
        return 2;
    }
    fclose(fh);
    {
        double t0 = now();
        lop_result r = lop_open(data, (size_t)size, NULL, &f, &msg);
        if (r != lop_success) {
            fprintf(stderr, "bench_c_reader: %s: %s: %s\n", path, lop_result_name(r), msg.text);
            return 2;
        }
        printf("{\"what\":\"open\",\"file_bytes\":%ld,\"seconds\":%.6f,\"GBps\":%.3f}\n", size, now() - t0,
               (double)size / (now() - t0) / 1e9);
    }
    for (li = 0; li < nlevels; li++) {
        int level = levels[li];
        uint32_t i, nb = 0, n = 0;
        size_t pbytes = 0, fbytes = 0, maxbytes;
        buf *bufs = (buf *)calloc(f->part_count, sizeof *bufs);
        float **pos = (float **)calloc(f->part_count, sizeof *pos);
        unsigned char *src, *dst;
        double tb[1000], tm[1000], td[1000], tdm[1000];
        if (level > f->available_level)
            continue;
        for (i = 0; i < f->part_count; i++) {
            lop_buffer_info info;
            pos[i] = (float *)malloc(12 * (size_t)f->parts[i].lods[0].vertices);
            fbytes += 12 * (size_t)f->parts[i].lods[0].vertices;
            n += f->parts[i].lods[0].vertices;
            if (f->parts[i].owner != (int32_t)i)
                continue;
            lop_buffer(f, i, 0, level, LOP_LAYOUT_NATIVE, &info);
            bufs[nb].part = i;
            bufs[nb].words = (uint32_t)info.words;
            bufs[nb].records = 4 * info.clusters;
            bufs[nb].w = (uint32_t *)malloc(4 * (size_t)info.words);
            bufs[nb].r = (uint32_t *)malloc(4 * (size_t)bufs[nb].records + 4);
            pbytes += 4 * (size_t)info.words + 4 * (size_t)bufs[nb].records;
            nb++;
        }
        maxbytes = pbytes > fbytes ? pbytes : fbytes;
        src = (unsigned char *)malloc(maxbytes);
        dst = (unsigned char *)malloc(maxbytes);
        memset(src, 0x5a, maxbytes);
        memset(dst, 0, maxbytes);
        for (run = -1; run < runs; run++) { /* run -1 warms the caches up */
            double t0 = now();
            for (i = 0; i < nb; i++)
                lop_build(f, bufs[i].part, 0, level, LOP_LAYOUT_NATIVE, bufs[i].w, bufs[i].words, bufs[i].r,
                          bufs[i].records);
            t0 = now() - t0;
            if (run >= 0)
                tb[run] = t0;
            t0 = now();
            memcpy(dst, src, pbytes);
            g_sink += dst[pbytes / 2];
            t0 = now() - t0;
            if (run >= 0)
                tm[run] = t0;
            t0 = now();
            for (i = 0; i < f->part_count; i++)
                lop_decode_positions(f, i, 0, level, pos[i], f->parts[i].lods[0].vertices, 0);
            t0 = now() - t0;
            if (run >= 0)
                td[run] = t0;
            t0 = now();
            memcpy(dst, src, fbytes);
            g_sink += dst[fbytes / 2];
            t0 = now() - t0;
            if (run >= 0)
                tdm[run] = t0;
        }
        {
            double b = median(tb, runs), m = median(tm, runs), d = median(td, runs), dm = median(tdm, runs);
            printf("{\"what\":\"build_p\",\"level\":%d,\"buffers\":%u,\"vertices\":%u,\"bytes\":%lu,\"seconds\":%.6f,"
                   "\"GBps\":%.3f,\"memcpy_GBps\":%.3f,\"ratio_to_memcpy\":%.3f}\n",
                   level, (unsigned)nb, (unsigned)n, (unsigned long)pbytes, b, pbytes / b / 1e9, pbytes / m / 1e9, m / b);
            printf("{\"what\":\"decode_positions\",\"level\":%d,\"parts\":%u,\"vertices\":%u,\"bytes\":%lu,"
                   "\"seconds\":%.6f,\"GBps\":%.3f,\"memcpy_GBps\":%.3f,\"ratio_to_memcpy\":%.3f}\n",
                   level, (unsigned)f->part_count, (unsigned)n, (unsigned long)fbytes, d, fbytes / d / 1e9,
                   fbytes / dm / 1e9, dm / d);
        }
        for (i = 0; i < nb; i++) {
            free(bufs[i].w);
            free(bufs[i].r);
        }
        for (i = 0; i < f->part_count; i++)
            free(pos[i]);
        free(bufs);
        free(pos);
        free(src);
        free(dst);
    }
    lop_close(f);
    free(data);
    return 0;
}
