/* tests/fuzz/fuzz_ptex.c - libFuzzer target for the Ptex reader (st_ptex_read_mem). The
 * deferred and the eager import must accept the same files and give the same texels. A file
 * that loads is also sampled with every Ptex filter in Traverse mode (hostile adjacency must
 * not crash the traversal) and written back and re-read (the writer must accept what the
 * reader built). Seeds in tests/fuzz/seeds/fuzz_ptex/ were written by st_ptex_write_mem
 * (quad and triangle meshes; a triangle file takes the triangle filter path). */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ptex.h"
#include "ptexfilter.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    st_set *s = NULL, *x = NULL;
    st_error e;
    /* the deferred import (levels past 0 made on first use) accepts exactly what the eager
     * one does, the two at most apart in time, and then holds the same texels */
    int rx = st_ptex_read_mem_eager(data, size, (size_t)32 << 20, &x, &e);
    int rs = st_ptex_read_mem(data, size, (size_t)32 << 20, &s, &e);
    if (rs == ST_OK && rx != ST_OK && st_set_levels(s, &e) == ST_OK)
        abort();
    if (rx == ST_OK && (rs != ST_OK || st_set_levels(s, &e) != ST_OK ||
                        x->texel_bytes != s->texel_bytes ||
                        memcmp(x->texels, s->texels, x->texel_bytes)))
        abort();
    st_set_free(x);
    if (rs != ST_OK)
        return 0;
    st_set_free(s);
    /* again, for the readers to be the first to use its levels */
    if (st_ptex_read_mem(data, size, (size_t)32 << 20, &s, &e) != ST_OK)
        abort();
    st_query q[6];
    for (int i = 0; i < 6; i++) {
        q[i].face = (uint32_t)i % s->info.nfaces;
        q[i].u = i * 0.23f - 0.1f;
        q[i].v = 1.05f - i * 0.2f;
        q[i].dudx = 0.02f + 0.2f * (float)(i & 1);
        q[i].dvdx = 0;
        q[i].dudy = 0;
        q[i].dvdy = 0.7f - 0.1f * (float)i;
    }
    float out[6 * ST_MAX_CHANNELS], cov[6];
    uint8_t st[6];
    st_sample_opts g = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_TRILINEAR};
    st_sample_batch(s, &g, q, 6, out, cov, st); /* a GPU-style filter first */
    for (unsigned f = ST_FILTER_PTEX_POINT; f <= ST_FILTER_PTEX_MITCHELL; f++)
        for (unsigned m = 0; m < 3; m++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)f, .sharpness = 0.5f};
            st_ptexfilter_batch(s, &o, q, 6, out, cov, st);
        }
    void *buf = NULL;
    size_t len = 0;
    if (st_ptex_write_mem(s, &buf, &len, &e) == ST_OK) {
        st_set *r = NULL;
        if (st_ptex_read_mem(buf, len, (size_t)32 << 20, &r, &e) != ST_OK)
            abort(); /* what the writer writes, the reader must read */
        st_set_free(r);
        free(buf);
    }
    st_set_free(s);
    return 0;
}
