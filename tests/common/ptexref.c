/* tests/common/ptexref.c - one line of a Ptex reference file, and the per-filter tally of a
 * whole file (see ptexref.h). */
#include "ptexref.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

const char *const st_ptexref_filters[8] = {"point", "bilinear", "box", "gaussian", "bicubic",
                                           "bspline", "catmullrom", "mitchell"};

int st_refline_parse(const char *line, st_refline *r)
{
    memset(r, 0, sizeof *r);
    const char *p = line + strspn(line, " \t\r\n");
    if (!*p || *p == '#')
        return 0;
    char fn[32];
    int c = sscanf(p, "%u %f %f %f %f %f %f %31s -> %f %f %f %f", &r->face, &r->u, &r->v,
                   &r->dudx, &r->dvdx, &r->dudy, &r->dvdy, fn, &r->ref[0], &r->ref[1],
                   &r->ref[2], &r->ref[3]);
    if (c < 8)
        return -1;
    r->filter = -1;
    for (int i = 0; i < 8; i++)
        if (!strcmp(fn, st_ptexref_filters[i]))
            r->filter = i;
    if (r->filter < 0)
        return -1;
    r->nref = c - 8;
    return 1;
}

int st_reftally_run(const st_set *s, const char *path, int verbose, st_reftally *t)
{
    memset(t, 0, sizeof *t);
    FILE *fp = fopen(path, "r");
    if (!fp)
        return -1;
    float tol = s->info.dtype == ST_DT_U8 ? 0.5f / 255.0f : 1e-4f;
    char line[512];
    int rc = 0;
    while (rc == 0 && fgets(line, sizeof line, fp)) {
        st_refline L;
        int pr = st_refline_parse(line, &L);
        if (pr < 0) {
            rc = -1;
            break;
        }
        if (pr == 0 || L.nref < 1)
            continue;
        st_query q = {L.face, L.u, L.v, L.dudx, L.dvdx, L.dudy, L.dvdy};
        st_sample_opts o = {.mode = ST_MODE_TRAVERSE,
                            .filter = (uint8_t)(ST_FILTER_PTEX_POINT + L.filter)};
        float out[4], din[4];
        uint8_t st;
        if (st_sample_batch(s, &o, &q, 1, out, NULL, &st) != 0) {
            rc = -1;
            break;
        }
        int good = 1, fi = L.filter;
        for (int c = 0; c < L.nref && c < s->info.nchan; c++) {
            float d = fabsf(out[c] - L.ref[c]);
            if (!(d <= tol))
                good = 0;
            if (d > t->maxd[fi])
                t->maxd[fi] = d;
        }
        if (!good && verbose)
            printf("miss: %s", line);
        /* Discard stays in the face: where it answers otherwise the kernel crossed an edge */
        o.mode = ST_MODE_DISCARD;
        if (st_sample_batch(s, &o, &q, 1, din, NULL, NULL) < 0) {
            rc = -1;
            break;
        }
        t->crossing += fabsf(din[0] - out[0]) > 1e-6f;
        t->total[fi]++;
        t->ok[fi] += good;
    }
    fclose(fp);
    return rc;
}

void st_reftally_header(void)
{
    printf("%-28s %-10s %7s %8s %10s\n", "file", "filter", "queries", "match%", "max|diff|");
}

int st_reftally_print(const st_reftally *t, const char *base)
{
    int below = 0;
    for (int fi = 0; fi < 8; fi++) {
        if (!t->total[fi])
            continue;
        printf("%-28s %-10s %7d %8.2f %10.2g\n", base, st_ptexref_filters[fi], t->total[fi],
               100.0 * t->ok[fi] / t->total[fi], (double)t->maxd[fi]);
        if (!(t->ok[fi] * 1000 >= t->total[fi] * 999))
            below++;
    }
    return below;
}
