/* store/kinds/atlas_locate.c - the query's chart at triangle resolution: for each level-0 texel
 * of an atlas that a UV triangle of another chart than the texel's id reaches (a "near" texel:
 * charts touching or overlapping in UV, and the texels along every chart's border whose centre
 * lies outside it), the triangles reaching into its square, so that the sampler can find the
 * chart of the triangle that holds a query's (u, v) instead of taking the chart of the texel
 * centre (docs/sampler.md, "Chart Discard": the query's chart).
 *
 * Owns: st_atlas_build_locate / st_atlas_free_locate (st_atlas.loc and the st_chart_ids
 * pointers to it). Does not own: the chart ids (atlas.c), the lookup at sampling time
 * (sample.c, query_chart), the mesh (mesh.h).
 *
 * Texel (i, j) of level 0 is the closed square [i, i + 1] x [j, j + 1] of texel space (x = u W,
 * y = v H). A triangle reaches it when the two overlap (separating axes: the square's two and
 * the triangle's three edge normals, in double). A texel is near when a triangle of another
 * chart than its id reaches it and a point of its square may belong to that chart: the texel
 * has no id, or the chart is lower than the id (where charts overlap in UV the lowest wins, as
 * for the ids), or some texel of its 3 x 3 neighbourhood in the image has another id (the
 * texel is on its chart's border). A texel whose neighbours all share its id is taken to lie
 * inside that chart, so charts stacked on it in UV do not make it near. A near texel's list
 * holds every triangle that reaches it, its own chart's too, by chart (lowest first). The
 * lists' total is bounded by 8 entries a texel of level 0 plus 64 a triangle; a mesh that would
 * need more (huge overlapping triangles) gets none, and every query keeps the texel rule.
 */
#include "atlas.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void st_atlas_free_locate(st_atlas *a)
{
    st_atlas_locate *l = &a->loc;
    free(l->bits);
    free(l->rank);
    free(l->off);
    free(l->tri);
    free(l->xy);
    free(l->id);
    memset(l, 0, sizeof *l);
    a->ids.near_bits = NULL;
    a->ids.near_rank = a->ids.near_off = a->ids.near_tri = NULL;
    a->ids.tri_xy = NULL;
    a->ids.tri_id = NULL;
}

/* whether counter-clockwise triangle t (6 doubles) and the closed square [x0, x0 + 1] x
 * [y0, y0 + 1] overlap */
static int reaches(const double *t, double x0, double y0)
{
    double x1 = x0 + 1, y1 = y0 + 1;
    if (fmax(t[0], fmax(t[2], t[4])) < x0 || fmin(t[0], fmin(t[2], t[4])) > x1 ||
        fmax(t[1], fmax(t[3], t[5])) < y0 || fmin(t[1], fmin(t[3], t[5])) > y1)
        return 0;
    const double cx[4] = {x0, x1, x0, x1}, cy[4] = {y0, y0, y1, y1};
    for (int k = 0; k < 3; k++) {
        const double px = t[2 * k], py = t[2 * k + 1];
        const double ex = t[(2 * k + 2) % 6] - px, ey = t[(2 * k + 3) % 6] - py;
        int out = 0;
        for (int c = 0; c < 4; c++)
            out += ex * (cy[c] - py) - ey * (cx[c] - px) < 0;
        if (out == 4)
            return 0;
    }
    return 1;
}

/* the texels of level 0 that triangle t may reach: [*i0, *i1] x [*j0, *j1], clipped to the
 * image (0 when none) */
static int tri_box(const double *t, uint32_t W, uint32_t H, long *i0, long *i1, long *j0, long *j1)
{
    double minx = fmax(floor(fmin(t[0], fmin(t[2], t[4]))) - 1, 0);
    double maxx = fmin(floor(fmax(t[0], fmax(t[2], t[4]))), (double)W - 1);
    double miny = fmax(floor(fmin(t[1], fmin(t[3], t[5]))) - 1, 0);
    double maxy = fmin(floor(fmax(t[1], fmax(t[3], t[5]))), (double)H - 1);
    if (!(minx <= maxx && miny <= maxy))
        return 0;
    *i0 = (long)minx;
    *i1 = (long)maxx;
    *j0 = (long)miny;
    *j1 = (long)maxy;
    return 1;
}

/* whether texel (i, j) and its neighbours in the image (3 x 3) all have its id: then its square
 * is taken to lie inside that chart, so only a lower chart can win a point of it */
static int inside(const uint16_t *ids, uint32_t W, uint32_t H, long i, long j)
{
    uint16_t id = ids[(size_t)j * W + (size_t)i];
    for (long y = j - 1; y <= j + 1; y++)
        for (long x = i - 1; x <= i + 1; x++)
            if (x >= 0 && y >= 0 && x < (long)W && y < (long)H && ids[(size_t)y * W + (size_t)x] != id)
                return 0;
    return 1;
}

enum { PASS_MARK, PASS_COUNT, PASS_FILL };

/* Every (triangle, texel) pair where the triangle reaches the texel: PASS_MARK sets the bits of
 * the near texels; PASS_COUNT counts each near texel's triangles into off[r + 1] and the total
 * into *total (-1, stopping, past cap); PASS_FILL writes them at off[r]++. */
static int walk(st_atlas_locate *l, const uint16_t *ids, uint32_t W, uint32_t H, size_t ntri,
                int pass, size_t cap, size_t *total)
{
    for (size_t t = 0; t < ntri; t++) {
        long i0, i1, j0, j1;
        const double *x = &l->xy[t * 6];
        if (!l->id[t] || !tri_box(x, W, H, &i0, &i1, &j0, &j1))
            continue;
        for (long j = j0; j <= j1; j++)
            for (long i = i0; i <= i1; i++) {
                size_t k = (size_t)j * W + (size_t)i;
                int near = st_bit_get(l->bits, k);
                if (pass == PASS_MARK) {
                    if (!near && ids[k] != l->id[t] &&
                        (!ids[k] || l->id[t] < ids[k] || !inside(ids, W, H, i, j)) &&
                        reaches(x, (double)i, (double)j))
                        l->bits[k >> 6] |= UINT64_C(1) << (k & 63);
                    continue;
                }
                if (!near || !reaches(x, (double)i, (double)j))
                    continue;
                size_t r = st_bit_rank(l->bits, l->rank, k);
                if (pass == PASS_FILL) {
                    l->tri[l->off[r]++] = (uint32_t)t;
                } else {
                    if (++*total > cap || *total >= UINT32_MAX)
                        return -1;
                    l->off[r + 1]++;
                }
            }
    }
    return 0;
}

int st_atlas_build_locate(st_atlas *a, const st_set *s, st_error *e)
{
    st_atlas_free_locate(a);
    const st_mesh *m = a->mesh;
    if (!m || !m->seams || !m->seams->tri_chart || !a->ids.nlevels || !m->ntri ||
        (uint64_t)s->faces[0].w * s->faces[0].h >= UINT32_MAX)
        return ST_OK;
    st_atlas_locate *l = &a->loc;
    const uint32_t W = s->faces[0].w, H = s->faces[0].h;
    const uint16_t *ids = a->ids.level[0];
    const size_t n = (size_t)W * H, words = (n + 63) / 64, ntri = m->ntri;
    l->xy = malloc(ntri * 6 * sizeof *l->xy);
    l->id = calloc(ntri, sizeof *l->id);
    l->bits = calloc(words ? words : 1, sizeof *l->bits);
    l->rank = malloc((words + 1) * sizeof *l->rank);
    if (!l->xy || !l->id || !l->bits || !l->rank)
        goto nomem;
    /* the triangles in texel space, counter-clockwise; id 0: none (no UV, no chart, flat) */
    for (size_t t = 0; t < ntri; t++) {
        const uint32_t *u = &m->tri_uv[t * 3];
        uint32_t ch = m->seams->tri_chart[t];
        if (u[0] == ST_MESH_NO_UV || u[1] == ST_MESH_NO_UV || u[2] == ST_MESH_NO_UV ||
            ch >= m->seams->ncharts)
            continue;
        double *x = &l->xy[t * 6];
        for (int k = 0; k < 3; k++) {
            x[2 * k] = m->uv[(size_t)u[k] * 2] * (double)W;
            x[2 * k + 1] = m->uv[(size_t)u[k] * 2 + 1] * (double)H;
        }
        double area = (x[2] - x[0]) * (x[5] - x[1]) - (x[3] - x[1]) * (x[4] - x[0]);
        if (area == 0 || !isfinite(area))
            continue;
        if (area < 0) {   /* b <-> c */
            double bx = x[2], by = x[3];
            x[2] = x[4];
            x[3] = x[5];
            x[4] = bx;
            x[5] = by;
        }
        l->id[t] = (uint16_t)(ch + 1);
    }
    /* near texels */
    size_t total = 0;
    walk(l, ids, W, H, ntri, PASS_MARK, 0, &total);
    size_t nnear = 0;
    for (size_t w = 0; w < words; w++) {
        l->rank[w] = (uint32_t)nnear;
        nnear += (size_t)__builtin_popcountll(l->bits[w]);
    }
    l->rank[words] = (uint32_t)nnear;
    if (!nnear) {
        st_atlas_free_locate(a);
        return ST_OK;
    }
    l->off = calloc(nnear + 1, sizeof *l->off);
    if (!l->off)
        goto nomem;
    /* the lists: counted, bounded, filled in triangle order (each start bumped past its
     * entries, shifted back after) */
    if (walk(l, ids, W, H, ntri, PASS_COUNT, 8 * n + 64 * ntri, &total) != 0) {
        st_atlas_free_locate(a);   /* too many: the texel rule for all */
        return ST_OK;
    }
    for (size_t r = 0; r < nnear; r++)
        l->off[r + 1] += l->off[r];
    l->tri = malloc((total ? total : 1) * sizeof *l->tri);
    if (!l->tri)
        goto nomem;
    walk(l, ids, W, H, ntri, PASS_FILL, 0, &total);
    for (size_t r = nnear; r > 0; r--)
        l->off[r] = l->off[r - 1];
    l->off[0] = 0;
    /* each list by chart (then triangle): the first triangle holding a point is the answer */
    for (size_t r = 0; r < nnear; r++)
        for (uint32_t x = l->off[r] + 1; x < l->off[r + 1]; x++) {
            uint32_t t = l->tri[x], y = x;
            for (; y > l->off[r] && l->id[l->tri[y - 1]] > l->id[t]; y--)
                l->tri[y] = l->tri[y - 1];
            l->tri[y] = t;
        }
    l->bytes = words * sizeof *l->bits + (words + 1) * sizeof *l->rank +
               (nnear + 1) * sizeof *l->off + total * sizeof *l->tri +
               ntri * (6 * sizeof *l->xy + sizeof *l->id);
    a->ids.near_bits = l->bits;
    a->ids.near_rank = l->rank;
    a->ids.near_off = l->off;
    a->ids.near_tri = l->tri;
    a->ids.tri_xy = l->xy;
    a->ids.tri_id = l->id;
    return ST_OK;
nomem:
    st_atlas_free_locate(a);
    return st_fail(e, ST_ENOMEM, "out of memory for the triangle lists of a %ux%u atlas", W, H);
}
