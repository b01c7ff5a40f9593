/* tests/common/pfpaths.c - fast paths against the general path (pfpaths.h). */
#include "pfpaths.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "ptexfilter_lanes.h"
#include "ptexres.h"

const unsigned st_pf_kernel_filters[ST_PF_NKERNEL_FILTERS] = {
    ST_FILTER_PTEX_BILINEAR, ST_FILTER_PTEX_BOX,        ST_FILTER_PTEX_GAUSSIAN,
    ST_FILTER_PTEX_BICUBIC,  ST_FILTER_PTEX_BSPLINE,    ST_FILTER_PTEX_CATMULLROM,
    ST_FILTER_PTEX_MITCHELL};

long st_pf_paths_agree(const st_set *s, const st_query *q, size_t n, const char *what,
                       const unsigned *filters, size_t nf)
{
    size_t nc = s->info.nchan;
    float *out[2], *cov[2];
    uint8_t *st[2];
    long done = 0;
    for (int k = 0; k < 2; k++) {
        out[k] = malloc(n * nc * sizeof(float) + 1);
        cov[k] = malloc(n * sizeof(float) + 1);
        st[k] = malloc(n + 1);
    }
    for (int k = 0; k < 2; k++)
        if (!out[k] || !cov[k] || !st[k]) {
            fprintf(stderr, "%s: out of memory\n", what);
            done = -1;
        }
    for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP && done >= 0; m++)
        for (size_t fi = 0; fi < nf && done >= 0; fi++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)filters[fi],
                                .sharpness = 0.3f};
            for (int k = 0; k < 2; k++)
                memset(out[k], 0x5a, n * nc * sizeof(float));
            int b0 = st_ptexfilter_batch(s, &o, q, n, out[0], cov[0], st[0]);
            int b1 = pf_batch_path(s, &o, q, n, out[1], cov[1], st[1], PF_PATH_GENERAL);
            if (b0 != b1) {
                fprintf(stderr, "%s mode %u filter %u: %d failed queries, the general path %d\n",
                        what, m, filters[fi], b0, b1);
                done = -1;
                break;
            }
            for (size_t i = 0; i < n; i++)
                if (memcmp(&out[0][i * nc], &out[1][i * nc], nc * sizeof(float)) ||
                    memcmp(&cov[0][i], &cov[1][i], sizeof(float)) || st[0][i] != st[1][i]) {
                    fprintf(stderr, "%s mode %u filter %u query %zu (face %u u %.9g v %.9g "
                            "dudx %.9g dvdy %.9g): %.9g != %.9g\n", what, m, filters[fi], i,
                            q[i].face, (double)q[i].u, (double)q[i].v, (double)q[i].dudx,
                            (double)q[i].dvdy, (double)out[0][i * nc], (double)out[1][i * nc]);
                    done = -1;
                    break;
                }
            /* and without the coverage array (a caller that asks none: the filters may skip
             * what only the coverage needs): the same values and statuses */
            memset(out[0], 0x5a, n * nc * sizeof(float));
            int b2 = done >= 0 ? st_ptexfilter_batch(s, &o, q, n, out[0], NULL, st[0]) : b1;
            for (size_t i = 0; done >= 0 && i < n; i++)
                if (b2 != b1 || memcmp(&out[0][i * nc], &out[1][i * nc], nc * sizeof(float)) ||
                    st[0][i] != st[1][i]) {
                    fprintf(stderr, "%s mode %u filter %u query %zu, no coverage asked: %.9g != "
                            "%.9g (status %u, %u)\n", what, m, filters[fi], i,
                            (double)out[0][i * nc], (double)out[1][i * nc], st[0][i], st[1][i]);
                    done = -1;
                }
            if (done >= 0)
                done += (long)n;
        }
    for (int k = 0; k < 2; k++) {
        free(out[k]);
        free(cov[k]);
        free(st[k]);
    }
    return done;
}

long st_pf_lanes_served(const st_set *s, const st_query *q, size_t n, unsigned ft,
                        unsigned (*serve)(const struct pf_klanes *k, void *arg), void *arg)
{
    st_error e = {0};
    pf_kernel_lanes_fn kl = pf_kernel_lanes_select(ft);
    if (!kl)
        return -1;
    const st_ptexres *t = st_ptexres_pin(s, &e);
    if (!t)
        return -1;
    pf_lanes lc = {.faces = s->faces, .lanef = t->lanef, .base = t->base, .px = t->px,
                   .nfaces = s->info.nfaces, .width = 1.0f, .blur = 0.0f};
    long served = 0;
    for (size_t i = 0; i + 8 <= n; i += 8) {
        pf_klanes k;
        kl(&lc, q + i, &k);
        served += __builtin_popcount(serve(&k, arg));
    }
    st_ptexres_unpin(t);
    return served;
}
