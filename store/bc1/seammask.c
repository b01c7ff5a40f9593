/* store/bc1/seammask.c - seam sample points of a set and least-squares seam masking
 * (seammask.h has the definitions, the energy and the conventions).
 *
 * Owns: st_seam_sys (building, freeing), the masking system on the touched texels (its
 * product, diagonal and right-hand side; solved by the bounded CG of cg.h), seam RMS and
 * chart PSNR. Does not own: the CG iteration (cg.c, shared with bc1_seam.c),
 * seam detection on meshes (seams.c), BC1 (bc1_seam.c builds its own system on endpoints
 * from the same points).
 *
 * Cost: building is O(points log points) (the touched texels are sorted once); one CG
 * iteration is O(8 points + variables). A 4096^2 atlas with ~50k texels of seams has ~100k
 * points and ~400k variables; ~100 iterations per channel.
 */
#include "seammask.h"
#include "cg.h"

#include "atlas.h"
#include "mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_POINTS ((size_t)1 << 26)

/* ---- building ----------------------------------------------------------------------------- */

typedef struct rawpt {
    uint64_t ta[4], tb[4];
    float    wa[4], wb[4];
    float    len;
    uint32_t seam;
} rawpt;

typedef struct builder {
    rawpt  *pts;
    size_t  n, cap;
    st_seam_frame *fr;
    size_t  nfr, capfr;
} builder;

/* Records the frame of seam number sys->nseams (called before it is counted). */
static int push_frame(builder *b, const st_seam_frame *f, st_error *e)
{
    if (b->nfr == b->capfr) {
        size_t nc = b->capfr ? b->capfr * 2 : 256;
        st_seam_frame *n = realloc(b->fr, nc * sizeof *n);
        if (!n)
            return st_fail(e, ST_ENOMEM, "out of memory for seam frames");
        b->fr = n;
        b->capfr = nc;
    }
    b->fr[b->nfr++] = *f;
    return ST_OK;
}

static void set_frame_side(st_seam_frame *fr, int k, uint32_t face, double x0, double y0, double x1,
                           double y1, double ix, double iy)
{
    double tx = x1 - x0, ty = y1 - y0, L = sqrt(tx * tx + ty * ty);
    fr->face[k] = face;
    fr->org[k][0] = (float)x0;
    fr->org[k][1] = (float)y0;
    fr->len[k] = (float)L;
    if (L > 0) {
        tx /= L;
        ty /= L;
    } else {
        tx = 1;
        ty = 0;
    }
    fr->tan[k][0] = (float)tx;
    fr->tan[k][1] = (float)ty;
    /* the normal of the tangent that points to the interior point (ix, iy) */
    double nx = -ty, ny = tx;
    if ((ix - x0) * nx + (iy - y0) * ny < 0) {
        nx = -nx;
        ny = -ny;
    }
    fr->nrm[k][0] = (float)nx;
    fr->nrm[k][1] = (float)ny;
}

static int push(builder *b, const rawpt *p, st_error *e)
{
    if (b->n == b->cap) {
        size_t nc = b->cap ? b->cap * 2 : 1024;
        if (nc > MAX_POINTS)
            return st_fail(e, ST_ETOOBIG, "more than %zu seam sample points", MAX_POINTS);
        rawpt *np = realloc(b->pts, nc * sizeof *np);
        if (!np)
            return st_fail(e, ST_ENOMEM, "out of memory for %zu seam sample points", nc);
        b->pts = np;
        b->cap = nc;
    }
    b->pts[b->n++] = *p;
    return ST_OK;
}

static int64_t wrapi(int64_t i, int64_t n)
{
    int64_t r = i % n;
    return r < 0 ? r + n : r;
}

/* Bilinear taps at (u, v) of face f: repeat addressing when wrap, else clamp to the face. */
static void taps(const st_seam_sys *sys, uint32_t f, double u, double v, int wrap, uint64_t t[4],
                 float w[4])
{
    int64_t W = sys->fw[f], H = sys->fh[f];
    double x = u * (double)W - 0.5, y = v * (double)H - 0.5;
    if (!(x == x) || !(y == y))
        x = y = 0; /* NaN from a broken mesh: tap the first texel, harmless */
    if (x < -1e9 || x > 1e9 || y < -1e9 || y > 1e9)
        x = y = 0;
    double fx0 = floor(x), fy0 = floor(y);
    int64_t x0 = (int64_t)fx0, y0 = (int64_t)fy0;
    float ax = (float)(x - fx0), ay = (float)(y - fy0);
    int64_t xs[2] = {x0, x0 + 1}, ys[2] = {y0, y0 + 1};
    for (int k = 0; k < 2; k++) {
        if (wrap) {
            xs[k] = wrapi(xs[k], W);
            ys[k] = wrapi(ys[k], H);
        } else {
            xs[k] = xs[k] < 0 ? 0 : xs[k] >= W ? W - 1 : xs[k];
            ys[k] = ys[k] < 0 ? 0 : ys[k] >= H ? H - 1 : ys[k];
        }
    }
    uint64_t b = sys->base[f];
    t[0] = b + (uint64_t)(ys[0] * W + xs[0]);
    t[1] = b + (uint64_t)(ys[0] * W + xs[1]);
    t[2] = b + (uint64_t)(ys[1] * W + xs[0]);
    t[3] = b + (uint64_t)(ys[1] * W + xs[1]);
    w[0] = (1 - ax) * (1 - ay);
    w[1] = ax * (1 - ay);
    w[2] = (1 - ax) * ay;
    w[3] = ax * ay;
}

/* Corner c of the unit square, Ptex order: 0 (0,0), 1 (1,0), 2 (1,1), 3 (0,1). */
static void corner_uv(unsigned c, double *u, double *v)
{
    *u = (c == 1 || c == 2) ? 1.0 : 0.0;
    *v = (c >= 2) ? 1.0 : 0.0;
}

static int build_perface(st_seam_sys *sys, const st_set *s, float step, builder *b, st_error *e)
{
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        for (unsigned ed = 0; ed < 4; ed++) {
            int32_t g = F->adjface[ed];
            if (g < 0 || (uint32_t)g >= s->info.nfaces)
                continue;
            unsigned ge = F->adjedge[ed] & 3u;
            const st_face *G = &s->faces[g];
            /* each shared edge once; a main face / subface link may be one-sided */
            int back = G->adjface[ge] == (int32_t)f && G->adjedge[ge] == ed;
            if (back && ((uint32_t)g < f || ((uint32_t)g == f && ge < ed)))
                continue;
            double lf = (ed & 1) ? sys->fh[f] : sys->fw[f];
            double lg = (ge & 1) ? sys->fh[g] : sys->fw[g];
            if (F->flags & ST_FACE_CONSTANT)
                lf = (ed & 1) ? F->h : F->w;
            if (G->flags & ST_FACE_CONSTANT)
                lg = (ge & 1) ? G->h : G->w;
            double L = lf > lg ? lf : lg;
            size_t n = (size_t)ceil(L / step);
            if (n < 1)
                n = 1;
            double u0, v0, u1, v1, g0u, g0v, g1u, g1v;
            corner_uv(ed, &u0, &v0);
            corner_uv((ed + 1) & 3, &u1, &v1);
            corner_uv(ge, &g0u, &g0v);
            corner_uv((ge + 1) & 3, &g1u, &g1v);
            float len = (float)(0.5 * (lf + lg) / (double)n);
            st_seam_frame fr;
            memset(&fr, 0, sizeof fr);
            {
                double W0 = sys->fw[f], H0 = sys->fh[f], W1 = sys->fw[g], H1 = sys->fh[g];
                set_frame_side(&fr, 0, f, u0 * W0, v0 * H0, u1 * W0, v1 * H0, 0.5 * W0, 0.5 * H0);
                /* the shared edge runs the other way in g: start at its end corner */
                set_frame_side(&fr, 1, (uint32_t)g, g1u * W1, g1v * H1, g0u * W1, g0v * H1,
                               0.5 * W1, 0.5 * H1);
            }
            int rcf = push_frame(b, &fr, e);
            if (rcf)
                return rcf;
            for (size_t i = 0; i < n; i++) {
                double t = ((double)i + 0.5) / (double)n;
                rawpt p;
                p.seam = sys->nseams;
                taps(sys, f, u0 + (u1 - u0) * t, v0 + (v1 - v0) * t, 0, p.ta, p.wa);
                double tg = 1.0 - t; /* the shared edge runs the other way in g */
                taps(sys, (uint32_t)g, g0u + (g1u - g0u) * tg, g0v + (g1v - g0v) * tg, 0, p.tb,
                     p.wb);
                p.len = len;
                int rc = push(b, &p, e);
                if (rc)
                    return rc;
            }
            sys->nseams++;
        }
    }
    return ST_OK;
}

static const char *basename_of(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

/* Chart mask: texel centres covered by a UV'd triangle (repeat addressing). Not dilated (the
 * atlas's own mask is, for Discard sampling): texels of the gutter are exactly the ones the
 * masking should be free to move. */
static void raster_charts(st_seam_sys *sys, const st_mesh *m, const char *tex)
{
    int64_t W = sys->fw[0], H = sys->fh[0];
    uint8_t *in = sys->inside;
    memset(in, 0, sys->ntexels);
    for (uint32_t t = 0; t < m->ntri; t++) {
        const uint32_t *ti = &m->tri_uv[3 * t];
        if (ti[0] == ST_MESH_NO_UV || ti[1] == ST_MESH_NO_UV || ti[2] == ST_MESH_NO_UV ||
            ti[0] >= m->nuv || ti[1] >= m->nuv || ti[2] >= m->nuv)
            continue;
        if (tex) {
            uint32_t mi = m->tri_mat ? m->tri_mat[t] : 0;
            if (mi >= m->nmat || strcmp(basename_of(m->mats[mi].map_kd), tex))
                continue;
        }
        double x[3], y[3];
        for (int k = 0; k < 3; k++) {
            x[k] = m->uv[2 * ti[k]] * (double)W;
            y[k] = m->uv[2 * ti[k] + 1] * (double)H;
            if (!(x[k] > -1e7 && x[k] < 1e7 && y[k] > -1e7 && y[k] < 1e7))
                goto next;
        }
        double area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        if (area == 0)
            continue;
        double sg = area > 0 ? 1 : -1;
        int64_t xa = (int64_t)floor(fmin(x[0], fmin(x[1], x[2]))),
                xb = (int64_t)ceil(fmax(x[0], fmax(x[1], x[2])));
        int64_t ya = (int64_t)floor(fmin(y[0], fmin(y[1], y[2]))),
                yb = (int64_t)ceil(fmax(y[0], fmax(y[1], y[2])));
        if (xb - xa > 4 * W || yb - ya > 4 * H)
            continue; /* absurd triangle */
        for (int64_t j = ya; j <= yb; j++)
            for (int64_t i = xa; i <= xb; i++) {
                double px = (double)i + 0.5, py = (double)j + 0.5;
                int ok = 1;
                for (int k = 0; k < 3 && ok; k++) {
                    int k1 = (k + 1) % 3;
                    double ef = (x[k1] - x[k]) * (py - y[k]) - (y[k1] - y[k]) * (px - x[k]);
                    ok = ef * sg >= 0;
                }
                if (ok)
                    in[wrapi(j, H) * W + wrapi(i, W)] = 1;
            }
    next:;
    }
}

static int build_atlas(st_seam_sys *sys, const st_set *s, float step, builder *b, st_error *e)
{
    const st_atlas *at = st_set_ext_get(s, ST_EXT_ATLAS);
    if (!at || !at->mesh)
        return ST_OK; /* a plain image: no seams */
    const st_mesh *m = at->mesh;
    if (!m->seams)
        return ST_OK; /* the atlas finds seams when it takes a mesh (atlas.h); the set is
                         shared and read-only here, so nothing is computed into it */
    /* With several textured materials, keep the triangles that use this texture. */
    const char *tex = at->texture_name[0] ? basename_of(at->texture_name) : NULL;
    int filter = 0;
    if (tex)
        for (uint32_t i = 0; i < m->nmat; i++)
            if (m->mats[i].map_kd[0] && !strcmp(basename_of(m->mats[i].map_kd), tex))
                filter = 1;
    raster_charts(sys, m, filter ? tex : NULL);
    double W = sys->fw[0], H = sys->fh[0];
    const st_seams *S = m->seams;
    for (uint32_t k = 0; k < S->nseams; k++) {
        const st_seam_edge *se = &S->seams[k];
        if (filter) {
            int use = 1;
            for (int side = 0; side < 2; side++) {
                uint32_t t = se->tri[side];
                uint32_t mi = t < m->ntri && m->tri_mat ? m->tri_mat[t] : 0;
                if (mi >= m->nmat || strcmp(basename_of(m->mats[mi].map_kd), tex))
                    use = 0;
            }
            if (!use)
                continue;
        }
        const float(*uv)[2][2] = se->uv;
        double la = hypot((uv[0][1][0] - uv[0][0][0]) * W, (uv[0][1][1] - uv[0][0][1]) * H);
        double lb = hypot((uv[1][1][0] - uv[1][0][0]) * W, (uv[1][1][1] - uv[1][0][1]) * H);
        if (!(la == la) || !(lb == lb) || la > 1e6 || lb > 1e6)
            continue;
        double L = la > lb ? la : lb;
        if (L <= 0)
            continue;
        size_t n = (size_t)ceil(L / step);
        if (n < 1)
            n = 1;
        float len = (float)(0.5 * (la + lb) / (double)n);
        st_seam_frame fr;
        memset(&fr, 0, sizeof fr);
        fr.wrap = 1;
        for (int k = 0; k < 2; k++) {
            /* the interior point: the triangle's corner that is not on the seam */
            uint32_t t = se->tri[k];
            double ix = 0, iy = 0;
            if (t < m->ntri) {
                uint32_t c = m->tri_uv[3 * t + (se->edge[k] + 2) % 3];
                if (c < m->nuv) {
                    ix = m->uv[2 * c] * W;
                    iy = m->uv[2 * c + 1] * H;
                }
            }
            set_frame_side(&fr, k, 0, uv[k][0][0] * W, uv[k][0][1] * H, uv[k][1][0] * W,
                           uv[k][1][1] * H, ix, iy);
        }
        int rcf = push_frame(b, &fr, e);
        if (rcf)
            return rcf;
        for (size_t i = 0; i < n; i++) {
            double t = ((double)i + 0.5) / (double)n;
            rawpt p;
            p.seam = sys->nseams;
            taps(sys, 0, uv[0][0][0] + (uv[0][1][0] - uv[0][0][0]) * t,
                 uv[0][0][1] + (uv[0][1][1] - uv[0][0][1]) * t, 1, p.ta, p.wa);
            taps(sys, 0, uv[1][0][0] + (uv[1][1][0] - uv[1][0][0]) * t,
                 uv[1][0][1] + (uv[1][1][1] - uv[1][0][1]) * t, 1, p.tb, p.wb);
            p.len = len;
            int rc = push(b, &p, e);
            if (rc)
                return rc;
        }
        sys->nseams++;
    }
    return ST_OK;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint32_t find_var(const uint64_t *vars, uint32_t n, uint64_t t)
{
    uint32_t lo = 0, hi = n;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (vars[mid] < t)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

void st_seam_sys_free(st_seam_sys *sys)
{
    if (!sys)
        return;
    free(sys->fw);
    free(sys->fh);
    free(sys->base);
    free(sys->inside);
    free(sys->pts);
    free(sys->vars);
    free(sys->frames);
    free(sys);
}

int st_seam_sys_build(const st_set *s, float step, st_seam_sys **out, st_error *e)
{
    *out = NULL;
    if (!(step > 0))
        step = 0.5f;
    if (step < 0.05f)
        step = 0.05f;
    if (step > 4.0f)
        step = 4.0f;
    if (s->info.kind == ST_KIND_BC1)
        return st_fail(e, ST_EINVAL, "seams are built from the uncompressed set");
    st_seam_sys *sys = calloc(1, sizeof *sys);
    if (!sys)
        return st_fail(e, ST_ENOMEM, "out of memory for the seam system");
    uint32_t nf = s->info.nfaces;
    sys->nfaces = nf;
    sys->fw = malloc(nf * sizeof *sys->fw);
    sys->fh = malloc(nf * sizeof *sys->fh);
    sys->base = malloc(((size_t)nf + 1) * sizeof *sys->base);
    builder b = {0};
    int rc = ST_OK;
    if (!sys->fw || !sys->fh || !sys->base) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %u faces", nf);
        goto fail;
    }
    uint64_t tot = 0;
    for (uint32_t f = 0; f < nf; f++) {
        const st_face *F = &s->faces[f];
        int cst = (F->flags & ST_FACE_CONSTANT) != 0;
        sys->fw[f] = cst ? 1 : F->w;
        sys->fh[f] = cst ? 1 : F->h;
        sys->base[f] = tot;
        tot += (uint64_t)sys->fw[f] * sys->fh[f];
    }
    sys->base[nf] = tot;
    sys->ntexels = tot;
    if (tot > ((uint64_t)1 << 34)) {
        rc = st_fail(e, ST_ETOOBIG, "%llu texels is too many to mask", (unsigned long long)tot);
        goto fail;
    }
    sys->inside = malloc(tot ? tot : 1);
    if (!sys->inside) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for the chart mask");
        goto fail;
    }
    memset(sys->inside, 1, tot);
    if (s->info.kind == ST_KIND_ATLAS)
        rc = build_atlas(sys, s, step, &b, e);
    else
        rc = build_perface(sys, s, step, &b, e);
    if (rc)
        goto fail;

    /* the touched texels, sorted and unique, become the variables */
    size_t nt = b.n * 8;
    uint64_t *all = malloc((nt ? nt : 1) * sizeof *all);
    if (!all) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %zu seam taps", nt);
        goto fail;
    }
    for (size_t i = 0; i < b.n; i++)
        for (int k = 0; k < 4; k++) {
            all[8 * i + k] = b.pts[i].ta[k];
            all[8 * i + 4 + k] = b.pts[i].tb[k];
        }
    qsort(all, nt, sizeof *all, cmp_u64);
    size_t nv = 0;
    for (size_t i = 0; i < nt; i++)
        if (!nv || all[nv - 1] != all[i])
            all[nv++] = all[i];
    if (nv > UINT32_MAX) {
        free(all);
        rc = st_fail(e, ST_ETOOBIG, "too many seam texels");
        goto fail;
    }
    sys->vars = realloc(all, (nv ? nv : 1) * sizeof *all);
    if (!sys->vars)
        sys->vars = all;
    sys->nvars = (uint32_t)nv;
    sys->pts = malloc((b.n ? b.n : 1) * sizeof *sys->pts);
    if (!sys->pts) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for seam points");
        goto fail;
    }
    sys->npts = b.n;
    for (size_t i = 0; i < b.n; i++) {
        st_seam_pt *p = &sys->pts[i];
        for (int k = 0; k < 4; k++) {
            p->va[k] = find_var(sys->vars, sys->nvars, b.pts[i].ta[k]);
            p->vb[k] = find_var(sys->vars, sys->nvars, b.pts[i].tb[k]);
            p->wa[k] = b.pts[i].wa[k];
            p->wb[k] = b.pts[i].wb[k];
        }
        p->len = b.pts[i].len;
        p->seam = b.pts[i].seam;
        sys->total_len += p->len;
    }
    free(b.pts);
    sys->frames = b.fr;
    *out = sys;
    return ST_OK;
fail:
    free(b.pts);
    free(b.fr);
    st_seam_sys_free(sys);
    return rc;
}

int st_seam_gather_rgba8(const st_set *s, const st_seam_sys *sys, uint8_t **out, st_error *e)
{
    *out = NULL;
    size_t bytes;
    if (st_mul_size((size_t)sys->ntexels, 4, &bytes))
        return st_fail(e, ST_ETOOBIG, "texel count overflows");
    uint8_t *buf = malloc(bytes ? bytes : 4);
    if (!buf)
        return st_fail(e, ST_ENOMEM, "out of memory for %zu bytes of RGBA8", bytes);
    unsigned nc = s->info.nchan, dt = s->info.dtype;
    int ac = s->info.alpha_chan;
    size_t ts = st_texel_size(s);
    for (uint32_t f = 0; f < sys->nfaces; f++) {
        const uint8_t *src = st_face_level(s, f, 0);
        uint64_t n = sys->base[f + 1] - sys->base[f];
        uint8_t *dst = buf + sys->base[f] * 4;
        for (uint64_t i = 0; i < n; i++) {
            const uint8_t *p = src + i * ts;
            float v[4] = {0, 0, 0, 1};
            unsigned colours = nc;
            if (ac >= 0 && (unsigned)ac < nc) {
                v[3] = st_channel_get(dt, p, (unsigned)ac);
                colours = nc - 1;
            }
            if (colours >= 3) {
                for (unsigned c = 0, k = 0; c < nc && k < 3; c++)
                    if ((int)c != ac)
                        v[k++] = st_channel_get(dt, p, c);
            } else {
                unsigned c0 = ac == 0 ? 1 : 0;
                float g = c0 < nc ? st_channel_get(dt, p, c0) : 0.0f;
                v[0] = v[1] = v[2] = g;
            }
            for (int k = 0; k < 4; k++)
                st_channel_put(ST_DT_U8, dst + 4 * i, (unsigned)k, v[k]);
        }
    }
    *out = buf;
    return ST_OK;
}

/* ---- solving --------------------------------------------------------------------------- */

/* y = D x + alpha S^T L S x on the variables. */
static void matvec(const st_seam_sys *sys, const float *d, float alpha, const double *x,
                   double *y)
{
    for (uint32_t i = 0; i < sys->nvars; i++)
        y[i] = d[i] * x[i];
    for (size_t k = 0; k < sys->npts; k++) {
        const st_seam_pt *p = &sys->pts[k];
        double r = 0;
        for (int j = 0; j < 4; j++)
            r += p->wa[j] * x[p->va[j]] - p->wb[j] * x[p->vb[j]];
        r *= alpha * p->len;
        for (int j = 0; j < 4; j++) {
            y[p->va[j]] += p->wa[j] * r;
            y[p->vb[j]] -= p->wb[j] * r;
        }
    }
}

/* matvec as the solver's callback (cg.h) */
typedef struct mask_mat {
    const st_seam_sys *sys;
    const float *d;
    float alpha;
} mask_mat;

static void mask_mat_apply(void *ctx, const double *x, double *y)
{
    const mask_mat *m = ctx;
    matvec(m->sys, m->d, m->alpha, x, y);
}

/* The Jacobi preconditioner of D + alpha S^T L S: 1 / its diagonal. */
static void mask_minv(const st_seam_sys *sys, const float *d, float alpha, double *minv)
{
    uint32_t n = sys->nvars;
    for (uint32_t i = 0; i < n; i++)
        minv[i] = d[i];
    for (size_t k = 0; k < sys->npts; k++) {
        const st_seam_pt *pt = &sys->pts[k];
        for (int j = 0; j < 4; j++) {
            minv[pt->va[j]] += alpha * pt->len * pt->wa[j] * pt->wa[j];
            minv[pt->vb[j]] += alpha * pt->len * pt->wb[j] * pt->wb[j];
        }
    }
    for (uint32_t i = 0; i < n; i++)
        minv[i] = minv[i] > 0 ? 1.0 / minv[i] : 0.0;
}

/* Masks channel values over the variables: get(c, i) reads variable i of channel c,
 * put(c, i, v) writes the solution back. */
typedef struct chan_io {
    float   *const *planes;   /* planes mode */
    uint8_t *rgba;            /* RGBA8 mode */
} chan_io;

static double io_get(const st_seam_sys *sys, const chan_io *io, unsigned c, uint32_t i)
{
    uint64_t t = sys->vars[i];
    return io->rgba ? (double)io->rgba[t * 4 + c] : (double)io->planes[c][t];
}

static void io_put(const st_seam_sys *sys, const chan_io *io, unsigned c, uint32_t i, double v)
{
    uint64_t t = sys->vars[i];
    v = v < 0 ? 0 : v > 255 ? 255 : v;
    if (io->rgba)
        io->rgba[t * 4 + c] = (uint8_t)(int)(v + 0.5);
    else
        io->planes[c][t] = (float)v;
}

static int mask_io(const st_seam_sys *sys, float alpha, float outside_weight, unsigned nchan,
                   const chan_io *io, const volatile int *cancel, st_error *e)
{
    if (alpha <= 0)
        alpha = 2.0f;
    if (outside_weight <= 0)
        outside_weight = 0.01f;
    uint32_t n = sys->nvars;
    if (!n || !sys->npts)
        return ST_OK;
    float *d = malloc(n * sizeof *d);
    uint8_t *fixed = calloc(n, 1);
    double *rhs = malloc(n * sizeof *rhs), *x = malloc(n * sizeof *x),
           *wk = malloc(5 * (size_t)n * sizeof *wk);
    int rc = ST_OK;
    if (!d || !fixed || !rhs || !x || !wk) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %u seam variables", n);
        goto out;
    }
    for (uint32_t i = 0; i < n; i++)
        d[i] = sys->inside[sys->vars[i]] ? 1.0f : outside_weight;
    /* (D + alpha S^T L S) x = D x0, bounded to 0..255 (cg.h), warm-started at the texels x0;
     * the preconditioner does not depend on the channel */
    double *minv = wk + 4 * (size_t)n;
    mask_minv(sys, d, alpha, minv);
    mask_mat m = {sys, d, alpha};
    st_cg P = {.n = n, .matvec = mask_mat_apply, .ctx = &m, .minv = minv, .b = rhs, .lo = 0,
               .hi = 255, .rounds = 4, .tol = 1e-10, .maxit = 500, .cancel = cancel};
    for (unsigned c = 0; c < nchan; c++) {
        for (uint32_t i = 0; i < n; i++) {
            x[i] = io_get(sys, io, c, i);
            rhs[i] = d[i] * x[i]; /* D x0 */
        }
        if (st_cg_solve(&P, x, fixed, wk)) {
            rc = st_fail(e, ST_ECANCELED, "seam masking cancelled");
            goto out;
        }
        for (uint32_t i = 0; i < n; i++)
            io_put(sys, io, c, i, x[i]);
    }
out:
    free(d);
    free(fixed);
    free(rhs);
    free(x);
    free(wk);
    return rc;
}

int st_seam_mask_planes(const st_seam_sys *sys, float alpha, float outside_weight,
                        unsigned nchan, float *const *planes, const volatile int *cancel,
                        st_error *e)
{
    chan_io io = {planes, NULL};
    return mask_io(sys, alpha, outside_weight, nchan, &io, cancel, e);
}

int st_seam_mask_rgba8(const st_seam_sys *sys, float alpha, float outside_weight, uint8_t *rgba,
                       const volatile int *cancel, st_error *e)
{
    chan_io io = {NULL, rgba};
    return mask_io(sys, alpha, outside_weight, 3, &io, cancel, e);
}

double st_seam_rms_rgba8(const st_seam_sys *sys, const uint8_t *rgba)
{
    if (!sys->npts || sys->total_len <= 0)
        return 0;
    double acc = 0;
    for (size_t k = 0; k < sys->npts; k++) {
        const st_seam_pt *p = &sys->pts[k];
        for (int c = 0; c < 3; c++) {
            double r = 0;
            for (int j = 0; j < 4; j++)
                r += p->wa[j] * rgba[sys->vars[p->va[j]] * 4 + (uint64_t)c] -
                     p->wb[j] * rgba[sys->vars[p->vb[j]] * 4 + (uint64_t)c];
            acc += p->len * r * r;
        }
    }
    return sqrt(acc / (3.0 * sys->total_len));
}

double st_seam_psnr_inside(const st_seam_sys *sys, const uint8_t *a, const uint8_t *b)
{
    double se = 0;
    uint64_t n = 0;
    for (uint64_t i = 0; i < sys->ntexels; i++) {
        if (sys->inside && !sys->inside[i])
            continue;
        /* punch-through: a texel the source has transparent (alpha < 128) that b has
         * transparent too is what BC1 stores for it (transparent black), no colour error;
         * one whose alpha class b got wrong counts its colour difference */
        if (a[4 * i + 3] < 128 && b[4 * i + 3] < 128)
            continue;
        n++;
        for (int c = 0; c < 3; c++) {
            int d = (int)a[4 * i + c] - (int)b[4 * i + c];
            se += d * d;
        }
    }
    if (!n || se == 0)
        return 99.0;
    return 10.0 * log10(255.0 * 255.0 / (se / (3.0 * (double)n)));
}
