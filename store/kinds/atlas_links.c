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
 * carried centre, kept only when that texel's id is the other side's chart. Near a seam's end
 * (a UV vertex where several seams meet, as at a chart corner) the carried centre can land past
 * the other chart's own border: then it is carried once more, across a seam side of that chart
 * at the same vertex whose edge it lies past (within the band), and linked when it lands in
 * that side's other chart (not the texel's own: a vertex whose charts' angles sum to less
 * than a turn has no surface there). Where several seam sides reach one texel for one chart, a
 * single carry wins over two, then the nearest edge (then the lower seam index). A texel past
 * a boundary edge, or farther than the band, has no link: Traverse drops it, as Ptex's
 * Traverse does past a mesh boundary. A level whose candidates would outnumber its
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
    uint32_t hops;  /* 1, or 2 when carried across a second seam at a vertex */
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
    if (x->hops != y->hops)
        return x->hops < y->hops ? -1 : 1;
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

/* A seam side's UV edge in texels of one level (w x h): A, the edge A -> B, its length, and
 * the sign that makes a signed distance positive on C's side. 0, or -1 when degenerate. */
typedef struct edge_tx { double ax, ay, ex, ey, len2, len, sgn; } edge_tx;

static int edge_in_texels(const float *pa, const float *pb, const float *pc, uint32_t w,
                          uint32_t h, edge_tx *E)
{
    E->ax = pa[0] * (double)w;
    E->ay = pa[1] * (double)h;
    E->ex = pb[0] * (double)w - E->ax;
    E->ey = pb[1] * (double)h - E->ay;
    E->len2 = E->ex * E->ex + E->ey * E->ey;
    double side_c = E->ex * (pc[1] * (double)h - E->ay) - E->ey * (pc[0] * (double)w - E->ax);
    if (!(E->len2 > 0) || !(side_c != 0) || !isfinite(E->len2) || !isfinite(side_c))
        return -1;
    E->len = sqrt(E->len2);
    E->sgn = side_c > 0 ? 1 : -1;
    return 0;
}

/* The distance (texels) of point (px, py) from the edge's segment when the point is past the
 * edge's line (at most half a texel on C's side) and within the band; -1 otherwise. *tt: where
 * along the edge its nearest point is (0 at A, 1 at B). */
static double past_edge(const edge_tx *E, double px, double py, double *tt)
{
    double sdist = (E->ex * (py - E->ay) - E->ey * (px - E->ax)) / E->len * E->sgn;
    if (sdist > 0.5)
        return -1;   /* on the chart's side of this edge: not past it */
    double t = ((px - E->ax) * E->ex + (py - E->ay) * E->ey) / E->len2;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double dx = px - (E->ax + t * E->ex), dy = py - (E->ay + t * E->ey);
    double d = sqrt(dx * dx + dy * dy);
    *tt = t;
    return d > ST_CHART_LINK_BAND ? -1 : d;
}

/* Carries normalised (u, v) across the seam: M's image. */
static void carry(const seam_map *M, double u, double v, double *u2, double *v2)
{
    u -= M->p[0];
    v -= M->p[1];
    *u2 = M->o[0] + M->J[0][0] * u + M->J[0][1] * v;
    *v2 = M->o[1] + M->J[1][0] * u + M->J[1][1] * v;
}

/* What a second carry needs: every seam side's map (2 per seam: seam * 2 + k; ok[] 0 for a
 * degenerate one) and, per weld id, the seam sides that end there (CSR: at[v] .. at[v + 1]). */
typedef struct hops {
    seam_map *map;
    uint8_t  *ok;
    uint32_t *at, *side;
} hops;

static void hops_free(hops *H)
{
    free(H->map);
    free(H->ok);
    free(H->at);
    free(H->side);
    memset(H, 0, sizeof *H);
}

static int hops_build(const st_mesh *m, hops *H)
{
    const st_seams *S = m->seams;
    size_t ns = S->nseams, nw = m->nweld;
    size_t nside = ns ? 2 * ns : 1;   /* at least one byte: malloc(0) may be NULL */
    H->map = malloc(nside * sizeof *H->map);
    H->ok = malloc(nside);
    H->at = calloc(nw + 2, sizeof *H->at);
    H->side = malloc(2 * nside * sizeof *H->side);
    if (!H->map || !H->ok || !H->at || !H->side)
        return -1;
    for (size_t i = 0; i < ns; i++)
        for (int k = 0; k < 2; k++)
            H->ok[2 * i + (size_t)k] = unfold_map(m, &S->seams[i], k, &H->map[2 * i + (size_t)k]) == 0;
    for (size_t i = 0; i < ns; i++)
        for (int e = 0; e < 2; e++)
            if (S->seams[i].pos[e] < nw)
                H->at[S->seams[i].pos[e] + 2] += 2;   /* its two sides */
    for (size_t v = 0; v < nw; v++)
        H->at[v + 2] += H->at[v + 1];
    for (size_t i = 0; i < ns; i++)
        for (int e = 0; e < 2; e++) {
            uint32_t v = S->seams[i].pos[e];
            if (v < nw)
                for (int k = 0; k < 2; k++)
                    H->side[H->at[v + 1]++] = (uint32_t)(2 * i) + (uint32_t)k;
        }
    return 0;
}

/* The texel and the point (normalised u, v) where (u, v) of chart c2's UV plane - carried there
 * across seam `from` of chart c, near its end at weld id `vert`, and past c2's own border -
 * lands when carried across a seam side of chart c2 that ends at `vert` and whose edge it is
 * past: the nearest such edge's, when it lands in that side's other chart, which is not c.
 * 1 found, 0 none, ST_ETOOBIG past the work budget (a side looked at is a unit of it). */
static int second_carry(const st_mesh *m, const hops *H, uint32_t from, uint32_t vert,
                        uint16_t c, uint16_t c2, double u, double v, const uint16_t *ids,
                        uint32_t w, uint32_t h, size_t *work, size_t *to, double *uo,
                        double *vo)
{
    const st_seams *S = m->seams;
    if (vert >= m->nweld)
        return 0;
    double best = -1;
    for (uint32_t a = H->at[vert]; a < H->at[vert + 1]; a++) {
        if (!*work)
            return ST_ETOOBIG;
        (*work)--;
        uint32_t sd = H->side[a], seam = sd / 2;
        int k = (int)(sd % 2);
        const st_seam_edge *se = &S->seams[seam];
        if (seam == from || !H->ok[sd] || S->tri_chart[se->tri[k]] + 1 != c2)
            continue;
        uint16_t c3 = (uint16_t)(S->tri_chart[se->tri[1 - k]] + 1);
        if (c3 == c || c3 == c2)
            continue;
        uint32_t t = se->tri[k];
        unsigned ka = corner_of(m, t, se->pos[0]), kb = corner_of(m, t, se->pos[1]);
        edge_tx E;
        if (ka > 2 || kb > 2 || ka == kb ||
            edge_in_texels(uv_at(m, t, ka), uv_at(m, t, kb), uv_at(m, t, 3 - ka - kb), w, h, &E))
            continue;
        double tt, d = past_edge(&E, u * (double)w, v * (double)h, &tt);
        if (d < 0 || (best >= 0 && d >= best))
            continue;
        double u3, v3;
        carry(&H->map[sd], u, v, &u3, &v3);
        double x3 = floor(u3 * (double)w), y3 = floor(v3 * (double)h);
        if (!(x3 >= 0 && x3 < (double)w && y3 >= 0 && y3 < (double)h))
            continue;
        size_t at = (size_t)y3 * w + (size_t)x3;
        if (ids[at] != c3)
            continue;
        best = d;
        *to = at;
        *uo = u3;
        *vo = v3;
    }
    return best >= 0;
}

/* Adds the candidates of one seam side at one level (w x h texels, ids) to out; 0, ST_ENOMEM,
 * or ST_ETOOBIG when the level would hold more than cap of them or the texels (and second
 * carries' seam sides) looked at would exceed *work (decremented by those looked at). */
static int side_cands(const st_mesh *m, const hops *H, uint32_t seam, int k, const uint16_t *ids,
                      uint32_t w, uint32_t h, size_t cap, size_t *work, cands *out)
{
    const st_seam_edge *se = &m->seams->seams[seam];
    const seam_map *M = &H->map[2 * (size_t)seam + (size_t)k];
    if (!H->ok[2 * (size_t)seam + (size_t)k])
        return 0;
    uint32_t t = se->tri[k], t2 = se->tri[1 - k];
    unsigned ka = corner_of(m, t, se->pos[0]), kb = corner_of(m, t, se->pos[1]);
    uint16_t c = (uint16_t)(m->seams->tri_chart[t] + 1);
    uint16_t c2 = (uint16_t)(m->seams->tri_chart[t2] + 1);
    edge_tx E;   /* texel space of this level */
    if (edge_in_texels(uv_at(m, t, ka), uv_at(m, t, kb), uv_at(m, t, 3 - ka - kb), w, h, &E))
        return 0;
    const double band = ST_CHART_LINK_BAND;
    double bx = E.ax + E.ex, by = E.ay + E.ey;
    double minx = fmax(floor(fmin(E.ax, bx) - band), 0);
    double maxx = fmin(ceil(fmax(E.ax, bx) + band), (double)w - 1);
    double miny = fmax(floor(fmin(E.ay, by) - band), 0);
    double maxy = fmin(ceil(fmax(E.ay, by) + band), (double)h - 1);
    if (minx > maxx || miny > maxy)
        return 0;
    for (long j = (long)miny; j <= (long)maxy; j++) {
        if (!*work)
            return ST_ETOOBIG;
        (*work)--;   /* the row itself, whatever its span */
        /* the row's texels within `band` of the edge's line: an interval (the whole box's
         * width for a horizontal edge), so the work is the band's area, not the box's */
        double lo = minx, hi = maxx, py0 = j + 0.5;
        if (E.ey != 0) {
            double x0 = E.ax + (E.ex * (py0 - E.ay) - band * E.len) / E.ey - 0.5;
            double x1 = E.ax + (E.ex * (py0 - E.ay) + band * E.len) / E.ey - 0.5;
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
            double px = i + 0.5, py = j + 0.5, tt;
            double d = past_edge(&E, px, py, &tt);
            if (d < 0)
                continue;
            /* carry the centre across (normalised uv), then the texel under it */
            double u2, v2;
            carry(M, px / (double)w, py / (double)h, &u2, &v2);
            double x2 = floor(u2 * (double)w), y2 = floor(v2 * (double)h);
            size_t to = 0;
            uint32_t hops_n = 1;
            int lands = x2 >= 0 && x2 < (double)w && y2 >= 0 && y2 < (double)h;
            if (lands)
                to = (size_t)y2 * w + (size_t)x2;
            if (!lands || ids[to] != c2) {
                /* past the other chart's own border: near an end of the seam, carried across
                 * one of that chart's seams at that vertex (see above) */
                int r = second_carry(m, H, seam, se->pos[tt < 0.5 ? 0 : 1], c, c2, u2, v2, ids,
                                     w, h, work, &to, &u2, &v2);
                if (r < 0)
                    return r;
                if (!r)
                    continue;   /* not landing in another chart: no link */
                hops_n = 2;
            }
            /* where in texel `to` the carried centre lies, in 256ths (the read is bilinear
             * there: sample_tap.c) */
            double fu = floor((u2 * (double)w - (double)(to % w)) * 256.0);
            double fv = floor((v2 * (double)h - (double)(to / w)) * 256.0);
            fu = fu < 0 ? 0 : fu > 255 ? 255 : fu;
            fv = fv < 0 ? 0 : fv > 255 ? 255 : fv;
            cand x = {{(uint32_t)idx, (uint32_t)to, c, (uint16_t)((unsigned)fu | (unsigned)fv << 8)},
                      (float)d, seam, hops_n};
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
    hops H = {0};
    if (hops_build(m, &H)) {
        hops_free(&H);
        return st_fail(e, ST_ENOMEM, "out of memory for the seam links of a %ux%u atlas", F->w,
                       F->h);
    }
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
                r = side_cands(m, &H, i, k, a->ids.level[l], w, h, cap, &work, &lv[l]);
        if (r == ST_ETOOBIG)
            lv[l].n = 0;
        else if (r)
            rc = st_fail(e, ST_ENOMEM, "out of memory for the seam links of a %ux%u atlas", F->w,
                         F->h);
        if (rc)
            break;
        /* one link per (texel, chart): the nearest seam side's */
        if (lv[l].n > 1) /* lv[l].v is NULL when a level has no candidates */
            qsort(lv[l].v, lv[l].n, sizeof *lv[l].v, cand_cmp);
        size_t n = 0;
        for (size_t i = 0; i < lv[l].n; i++)
            if (!n || lv[l].v[i].l.texel != lv[l].v[n - 1].l.texel ||
                lv[l].v[i].l.chart != lv[l].v[n - 1].l.chart)
                lv[l].v[n++] = lv[l].v[i];
        lv[l].n = n;
        total += n;
    }
    hops_free(&H);
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
