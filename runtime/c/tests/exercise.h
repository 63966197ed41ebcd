/* exercise.h: use every query and decode of lop.h on an open file (lopcheck and the fuzz target).
   Include after lop.h's implementation. */
#ifndef LOP_EXERCISE_H
#define LOP_EXERCISE_H
#include <stdlib.h>

static volatile uint32_t g_sink;

/* Every query and decode of every buffer at every level it holds (few_levels: at level 0, 1, the
   buffer's level and one above it), results discarded. */
static void lop_exercise(const lop_file *f, int few_levels)
{
    uint32_t i, k;
    int level, layout;
    float cam[3] = {1.0f, 2.0f, 3.0f};
    unsigned char block[LOP_CLUSTERED_BLOCK_SIZE], view[LOP_VIEW_BLOCK_SIZE];
    lop_view_block(f, cam, view, sizeof view);
    lop_required_level(f, 10.0);
    for (i = 0; i < f->part_count; i++) {
        uint32_t lod, drawn;
        int sel, top;
        lop_select(f, i, 3.0, &lod, &sel);
        if (lop_drawable(f, i, lod, &drawn, &sel) == lop_success)
            g_sink += drawn;
        for (k = 0; k < f->parts[i].lod_count; k++) {
            const lop_lod *e = &f->parts[i].lods[k];
            size_t n = e->vertices;
            top = lop_buffer_level(f, i, k);
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
                for (level = 0; level <= top + 1; level++) {
                    if (few_levels && level > 1 && level < top)
                        continue;
                    lop_decode_positions(f, i, k, level, xyz, n, 0);
                    if (lop_decode_positions(f, i, k, level, xyz, n, LOP_LOCAL) == lop_success &&
                        lop_decode_grid(f, i, k, level, grid, wid, n) == lop_success) {
                        uint32_t u;
                        memcpy(&u, xyz, 4);
                        g_sink += u + grid[0];
                    }
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

#endif
