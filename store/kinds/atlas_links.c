/* store/kinds/atlas_links.c - chart Traverse's links: for each side of each UV seam of an
 * atlas's mesh, the texels just past that side's UV edge (outside its chart), each linked to
 * the texel its centre lands on when carried across the seam into the other side's chart
 * (docs/sampler.md, "Chart Traverse").
 *
 * Owns: st_atlas_build_links (the links of every level, sorted, in st_atlas). Does not own:
 * the chart ids (atlas.c), seam finding (seams.c), reading the links (sample_tap.c).
 *
 * The carry is the seam's unfolding: the triangle of side k (corners A, B on the seam, C off
 * it) is turned about AB into the plane of the other side's triangle (A, B, D), C landing on
 * the far side of AB from D at its own distance from AB; a point of side k's UV plane maps
 * affinely to the other side's UV plane by the map that takes side k's UVs of A, B, C to the
 * other side's UVs of A, B and the unfolded C (its barycentric coordinates in A, B, D). So a
 * straight line across the seam on the surface stays straight in both charts, whatever their
 * rotation, scale or mirroring in the atlas.
 *
 * A texel of level L is linked for chart c (the side's chart id) when its centre lies within
 * ST_CHART_LINK_BAND texels of the side's UV edge (at that level), on the far side of the edge
 * from C (or within half a texel of it), and its id is not c; its link is the texel under the
 * carried centre, kept only when that texel's id is the other side's chart. Where several seam
 * sides reach one texel for one chart, the nearest edge wins (then the lower seam index). A
 * texel past a boundary edge, or farther than the band, has no link: Traverse drops it, as
 * Ptex's Traverse does past a mesh boundary. A level whose candidates would outnumber its
 * texels plus 128 a seam, or whose bands cover more than 8 times its texels plus 512 a seam,
 * gets no links (memory and time in proportion to the image and the mesh, whatever the mesh).
 */
#include "atlas.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct cand {
    st_chart_link l;
    float d;        /* distance of the texel centre from the seam side, in texels */
    uint32_t seam;  /* for a deterministic choice on equal distances */
} cand;

typedef struct cands {
    cand  *v;
    size_t n, cap;
} cands;

static int cand_cmp(const void *a, const void *b)
{
    const cand *x = a, *y = b;
    if (x->l.texel != y->l.texel)
        return x->l.texel < y->l.texel ? -1 : 1;
    if (x->l.chart != y->l.chart)
        return x->l.chart < y->l.chart ? -1 : 1;
    if (x->d != y->d)
        return x->d < y->d ? -1 : 1;
    return x->seam < y->seam ? -1 : x->seam > y->seam;
}

static int push(cands *c, const cand *x)
{
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 256;
        cand *v = realloc(c->v, cap * sizeof *v);
        if (!v)
            return -1;
        c->v = v;
        c->cap = cap;
    }
    c->v[c->n++] = *x;
    return 0;
}

/* The corner of triangle t whose weld id is w (0..2), or 3 when none is. */
static unsigned corner_of(const st_mesh *m, uint32_t t, uint32_t w)
{
    for (unsigned k = 0; k < 3; k++)
        if (m->tri_weld[(size_t)t * 3 + k] == w)
            return k;
    return 3;
}

static const float *uv_at(const st_mesh *m, uint32_t t, unsigned k)
{
    return &m->uv[(size_t)m->tri_uv[(size_t)t * 3 + k] * 2];
}

static const float *pos_at(const st_mesh *m, uint32_t t, unsigned k)
{
    return &m->pos[(size_t)m->tri_pos[(size_t)t * 3 + k] * 3];
}

/* The affine map from side k's UV plane to the other side's (see above): x -> o + J (x - p).
 * 0, or -1 for a degenerate seam (a zero-length edge, a triangle flat in 3D or in UV). */
typedef struct seam_map { double p[2], o[2], J[2][2]; } seam_map;

static int unfold_map(const st_mesh *m, const st_seam_edge *se, int k, seam_map *M)
{
    int o = 1 - k;
    uint32_t t = se->tri[k], t2 = se->tri[o];
    unsigned ka = corner_of(m, t, se->pos[0]), kb = corner_of(m, t, se->pos[1]);
    unsigned oa = corner_of(m, t2, se->pos[0]), ob = corner_of(m, t2, se->pos[1]);
    if (ka > 2 || kb > 2 || oa > 2 || ob > 2 || ka == kb || oa == ob)
        return -1;
    unsigned kc = 3 - ka - kb, od = 3 - oa - ob;
    const float *A = pos_at(m, t, ka), *B = pos_at(m, t, kb), *C = pos_at(m, t, kc);
    const float *D = pos_at(m, t2, od);
    double e[3], ac[3], ad[3];
    for (int i = 0; i < 3; i++) {
        e[i] = (double)B[i] - A[i];
        ac[i] = (double)C[i] - A[i];
        ad[i] = (double)D[i] - A[i];
    }
    double ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
    if (!(ee > 0) || !isfinite(ee))
        return -1;
    double sc = (ac[0] * e[0] + ac[1] * e[1] + ac[2] * e[2]) / ee;
    double sd = (ad[0] * e[0] + ad[1] * e[1] + ad[2] * e[2]) / ee;
    double hc = 0, hd = 0;
    for (int i = 0; i < 3; i++) {
        double nc = ac[i] - sc * e[i], nd = ad[i] - sd * e[i];
        hc += nc * nc;
        hd += nd * nd;
    }
    hc = sqrt(hc);
    hd = sqrt(hd);
    if (!(hc > 0) || !(hd > 0) || !isfinite(hc / hd))
        return -1;
    /* unfolded C = A + sc e - (hc / hd) (D - A - sd e) = A + alpha (B - A) + beta (D - A) */
    double beta = -hc / hd, alpha = sc - beta * sd;
    const float *pa = uv_at(m, t, ka), *pb = uv_at(m, t, kb), *pc = uv_at(m, t, kc);
    const float *qa = uv_at(m, t2, oa), *qb = uv_at(m, t2, ob), *qd = uv_at(m, t2, od);
    double qc[2], S[2][2], T[2][2];
    for (int i = 0; i < 2; i++) {
        qc[i] = qa[i] + alpha * ((double)qb[i] - qa[i]) + beta * ((double)qd[i] - qa[i]);
        S[i][0] = (double)pb[i] - pa[i];   /* columns: side k's edge and its A -> C */
        S[i][1] = (double)pc[i] - pa[i];
        T[i][0] = (double)qb[i] - qa[i];   /* their images */
        T[i][1] = qc[i] - qa[i];
    }
    double det = S[0][0] * S[1][1] - S[0][1] * S[1][0];
    if (!(fabs(det) > 0) || !isfinite(det))
        return -1;
    double inv[2][2] = {{S[1][1] / det, -S[0][1] / det}, {-S[1][0] / det, S[0][0] / det}};
    for (int r = 0; r < 2; r++)
        for (int c = 0; c < 2; c++)
            M->J[r][c] = T[r][0] * inv[0][c] + T[r][1] * inv[1][c];
    M->p[0] = pa[0];
    M->p[1] = pa[1];
    M->o[0] = qa[0];
    M->o[1] = qa[1];
    return 0;
}

/* Adds the candidates of one seam side at one level (w x h texels, ids) to out; 0, ST_ENOMEM,
 * or ST_ETOOBIG when the level would hold more than cap of them or the texels looked at
 * would exceed *work (decremented by those looked at). */
static int side_cands(const st_mesh *m, const st_seam_edge *se, uint32_t seam, int k,
                      const uint16_t *ids, uint32_t w, uint32_t h, size_t cap, size_t *work,
                      cands *out)
{
    seam_map M;
    if (unfold_map(m, se, k, &M))
        return 0;
    uint32_t t = se->tri[k], t2 = se->tri[1 - k];
    unsigned ka = corner_of(m, t, se->pos[0]), kb = corner_of(m, t, se->pos[1]);
    const float *pa = uv_at(m, t, ka), *pb = uv_at(m, t, kb), *pc = uv_at(m, t, 3 - ka - kb);
    uint16_t c = (uint16_t)(m->seams->tri_chart[t] + 1);
    uint16_t c2 = (uint16_t)(m->seams->tri_chart[t2] + 1);
    /* texel space of this level */
    double ax = pa[0] * (double)w, ay = pa[1] * (double)h;
    double bx = pb[0] * (double)w, by = pb[1] * (double)h;
    double cx = pc[0] * (double)w, cy = pc[1] * (double)h;
    double ex = bx - ax, ey = by - ay, len2 = ex * ex + ey * ey;
    double side_c = ex * (cy - ay) - ey * (cx - ax);   /* C's side of the edge */
    if (!(len2 > 0) || !(side_c != 0) || !isfinite(len2) || !isfinite(side_c))
        return 0;
    const double band = ST_CHART_LINK_BAND, len = sqrt(len2);
    double minx = fmax(floor(fmin(ax, bx) - band), 0);
    double maxx = fmin(ceil(fmax(ax, bx) + band), (double)w - 1);
    double miny = fmax(floor(fmin(ay, by) - band), 0);
    double maxy = fmin(ceil(fmax(ay, by) + band), (double)h - 1);
    if (minx > maxx || miny > maxy)
        return 0;
    for (long j = (long)miny; j <= (long)maxy; j++) {
        if (!*work)
            return ST_ETOOBIG;
        (*work)--;   /* the row itself, whatever its span */
        /* the row's texels within `band` of the edge's line: an interval (the whole box's
         * width for a horizontal edge), so the work is the band's area, not the box's */
        double lo = minx, hi = maxx, py0 = j + 0.5;
        if (ey != 0) {
            double x0 = ax + (ex * (py0 - ay) - band * len) / ey - 0.5;
            double x1 = ax + (ex * (py0 - ay) + band * len) / ey - 0.5;
            lo = fmax(lo, ceil(fmin(x0, x1)));
            hi = fmin(hi, floor(fmax(x0, x1)));
        }
        if (lo <= hi) {
            size_t span = (size_t)(hi - lo) + 1;
            if (span > *work)
                return ST_ETOOBIG;
            *work -= span;
        }
        for (long i = (long)lo; lo <= hi && i <= (long)hi; i++) {
            size_t idx = (size_t)j * w + (size_t)i;
            if (ids[idx] == c)
                continue;   /* the chart's own texel: read as it is */
            double px = i + 0.5, py = j + 0.5;
            /* signed distance from the edge's line, positive on C's side */
            double sdist = (ex * (py - ay) - ey * (px - ax)) / len * (side_c > 0 ? 1 : -1);
            if (sdist > 0.5)
                continue;   /* on the chart's side of this edge: not past it */
            double tt = ((px - ax) * ex + (py - ay) * ey) / len2;
            tt = tt < 0 ? 0 : tt > 1 ? 1 : tt;
            double dx = px - (ax + tt * ex), dy = py - (ay + tt * ey);
            double d = sqrt(dx * dx + dy * dy);
            if (d > band)
                continue;
            /* carry the centre across (normalised uv), then the texel under it */
            double u = px / (double)w - M.p[0], v = py / (double)h - M.p[1];
            double u2 = M.o[0] + M.J[0][0] * u + M.J[0][1] * v;
            double v2 = M.o[1] + M.J[1][0] * u + M.J[1][1] * v;
            double x2 = floor(u2 * (double)w), y2 = floor(v2 * (double)h);
            if (!(x2 >= 0 && x2 < (double)w && y2 >= 0 && y2 < (double)h))
                continue;
            size_t to = (size_t)y2 * w + (size_t)x2;
            if (ids[to] != c2)
                continue;   /* not landing in the other chart: no link */
            /* where in texel `to` the carried centre lies, in 256ths (the read is bilinear
             * there: sample_tap.c) */
            double fu = floor((u2 * (double)w - x2) * 256.0), fv = floor((v2 * (double)h - y2) * 256.0);
            fu = fu < 0 ? 0 : fu > 255 ? 255 : fu;
            fv = fv < 0 ? 0 : fv > 255 ? 255 : fv;
            cand x = {{(uint32_t)idx, (uint32_t)to, c, (uint16_t)((unsigned)fu | (unsigned)fv << 8)},
                      (float)d, seam};
            if (out->n >= cap)
                return ST_ETOOBIG;
            if (push(out, &x))
                return ST_ENOMEM;
        }
    }
    return 0;
}

void st_atlas_free_links(st_atlas *a)
{
    free(a->chart_link);
    a->chart_link = NULL;
    a->chart_link_bytes = 0;
    memset(a->ids.link, 0, sizeof a->ids.link);
    memset(a->ids.nlink, 0, sizeof a->ids.nlink);
}

int st_atlas_build_links(st_atlas *a, const st_set *s, st_error *e)
{
    st_atlas_free_links(a);
    const st_mesh *m = a->mesh;
    if (!m || !m->seams || !a->ids.nlevels || !m->tri_weld)
        return ST_OK;
    const st_face *F = &s->faces[0];
    cands lv[ST_MAX_LEVELS];
    memset(lv, 0, sizeof lv);
    size_t total = 0;
    int rc = ST_OK;
    for (unsigned l = 0; l < a->ids.nlevels && !rc; l++) {
        uint32_t w = st_level_w(F, l), h = st_level_h(F, l);
        /* a level's candidates (every seam side's band, before one per texel and chart is
         * kept) are capped at its texels plus 128 a seam, and the texels looked at to find
         * them at 8 times its texels plus 512 a seam (a side's band is at least 9 x 9): the
         * four shared textured meshes take at most 27 % and 32 % of these at any level; past
         * them (a mesh of huge overlapping seams) the level gets no links
         * - Traverse there is chart Discard - rather than memory and time out of proportion
         * to the image and the mesh */
        size_t cap = (size_t)w * h + 128 * (size_t)m->seams->nseams;
        size_t work = 8 * (size_t)w * h + 512 * (size_t)m->seams->nseams;
        int r = 0;
        for (uint32_t i = 0; i < m->seams->nseams && !r; i++)
            for (int k = 0; k < 2 && !r; k++)
                r = side_cands(m, &m->seams->seams[i], i, k, a->ids.level[l], w, h, cap, &work,
                               &lv[l]);
        if (r == ST_ETOOBIG)
            lv[l].n = 0;
        else if (r)
            rc = st_fail(e, ST_ENOMEM, "out of memory for the seam links of a %ux%u atlas", F->w,
                         F->h);
        if (rc)
            break;
        /* one link per (texel, chart): the nearest seam side's */
        qsort(lv[l].v, lv[l].n, sizeof *lv[l].v, cand_cmp);
        size_t n = 0;
        for (size_t i = 0; i < lv[l].n; i++)
            if (!n || lv[l].v[i].l.texel != lv[l].v[n - 1].l.texel ||
                lv[l].v[i].l.chart != lv[l].v[n - 1].l.chart)
                lv[l].v[n++] = lv[l].v[i];
        lv[l].n = n;
        total += n;
    }
    st_chart_link *links = rc ? NULL : malloc((total ? total : 1) * sizeof *links);
    if (!rc && !links)
        rc = st_fail(e, ST_ENOMEM, "out of memory for the seam links of a %ux%u atlas", F->w, F->h);
    size_t at = 0;
    for (unsigned l = 0; l < a->ids.nlevels; l++) {
        for (size_t i = 0; !rc && i < lv[l].n; i++)
            links[at + i] = lv[l].v[i].l;
        if (!rc) {
            a->ids.link[l] = links + at;
            a->ids.nlink[l] = lv[l].n;
            at += lv[l].n;
        }
        free(lv[l].v);
    }
    if (rc) {
        free(links);
        memset(a->ids.link, 0, sizeof a->ids.link);
        memset(a->ids.nlink, 0, sizeof a->ids.nlink);
        return rc;
    }
    a->chart_link = links;
    a->chart_link_bytes = total * sizeof *links;
    return ST_OK;
}
