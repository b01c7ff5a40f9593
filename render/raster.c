/* render/raster.c - the MSAA rasteriser of seamtex-render, modelled on a GPU's.
 *
 * Owns: the D3D standard sample patterns, coverage per sample (edge functions with the
 * top-left rule), a depth pass that gives each sample its nearest triangle, fragments (one
 * shading point per pixel and triangle with visible samples: the pixel centre, or the centroid
 * of the covered samples when the centre is outside), texture-space derivatives from 2x2
 * pixel quads with helper lanes (fine derivatives: each row's and each column's own
 * difference), and the box resolve. Does not own: sampling (the caller samples the queries this
 * file writes), the camera.
 *
 * Cost: two passes over each triangle's bounding box; per sample three edge functions in
 * double precision (exact for the 1/16-pixel sample grid and the tests' vertices).
 */
#include "render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* D3D11 standard multisample patterns (x, y in 1/16 pixel, from the pixel centre, y down). */
static const int8_t PAT1[] = { 0, 0 };
static const int8_t PAT2[] = { 4, 4, -4, -4 };
static const int8_t PAT4[] = { -2, -6, 6, -2, -6, 2, 2, 6 };
static const int8_t PAT8[] = { 1, -3, -1, 3, 5, 1, -3, -5, -5, 5, -7, -1, 3, 7, 7, -7 };

unsigned rr_pattern(unsigned msaa, const int8_t **xy)
{
    switch (msaa) {
    case 1: *xy = PAT1; return 1;
    case 2: *xy = PAT2; return 2;
    case 4: *xy = PAT4; return 4;
    case 8: *xy = PAT8; return 8;
    default: return 0;
    }
}

int rr_target_init(rr_target *t, unsigned width, unsigned height, unsigned msaa, char *msg,
                   size_t ml)
{
    const int8_t *pat;
    memset(t, 0, sizeof *t);
    unsigned ns = rr_pattern(msaa, &pat);
    if (!ns) {
        rt_say(msg, ml, "MSAA rate %u: 1, 2, 4 or 8", msaa);
        return -1;
    }
    if (width == 0 || height == 0 || width > 16384 || height > 16384 ||
        (uint64_t)width * height * ns > (1ull << 28)) {
        rt_say(msg, ml, "image %ux%u at %ux: 1..16384 per axis and at most 2^28 samples", width,
            height, msaa);
        return -1;
    }
    size_t n = (size_t)width * height * ns;
    t->width = width;
    t->height = height;
    t->msaa = msaa;
    t->nsamp = ns;
    t->depth = malloc(n * sizeof *t->depth);
    t->owner = malloc(n * sizeof *t->owner);
    if (!t->depth || !t->owner) {
        rr_target_free(t);
        rt_say(msg, ml, "out of memory for a %ux%u x%u target", width, height, msaa);
        return -1;
    }
    return 0;
}

void rr_target_free(rr_target *t)
{
    if (!t)
        return;
    free(t->depth);
    free(t->owner);
    free(t->frags);
    free(t->queries);
    memset(t, 0, sizeof *t);
}

/* A triangle set up for the current camera: screen vertices in positive orientation, edge
 * functions E_k(p) = dx_k (p.y - y_k) - dy_k (p.x - x_k) (edge k from vertex k to k+1), the
 * attributes divided by w for perspective-correct interpolation. */
typedef struct tri_setup {
    double x[3], y[3], iw[3];
    double dx[3], dy[3];
    int    tl[3];           /* top-left edge: a sample exactly on it is inside */
    double area;
    double a[3][5];         /* u/w, v/w, n/w per vertex */
    int    x0, y0, x1, y1;  /* pixel bounding box, clipped to the screen */
    int    back;            /* seen from behind: the normal is turned to the viewer */
} tri_setup;

static int setup(const rr_target *t, const rm_mesh *m, const rc_camera *cam, uint32_t tri,
                 tri_setup *s)
{
    int order[3] = { 0, 1, 2 };
    double x[3], y[3], iw[3];
    for (int k = 0; k < 3; k++)
        if (!rr_project(cam, t->width, t->height, m->pos + 3 * m->tri[3 * tri + k], &x[k], &y[k],
                        &iw[k]))
            return 0;   /* crosses the near plane: the orbit keeps meshes in front */
    double area = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]);
    if (!(fabs(area) > 0) || !isfinite(area))
        return 0;       /* edge-on or degenerate: covers no sample */
    if (area < 0) {
        order[1] = 2;
        order[2] = 1;
        area = -area;
    }
    s->area = area;
    {
        const float *p0 = m->pos + 3 * m->tri[3 * tri], *p1 = m->pos + 3 * m->tri[3 * tri + 1],
                    *p2 = m->pos + 3 * m->tri[3 * tri + 2];
        double e1[3], e2[3], g[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = (double)p1[k] - p0[k];
            e2[k] = (double)p2[k] - p0[k];
        }
        g[0] = e1[1] * e2[2] - e1[2] * e2[1];
        g[1] = e1[2] * e2[0] - e1[0] * e2[2];
        g[2] = e1[0] * e2[1] - e1[1] * e2[0];
        s->back = g[0] * (cam->eye[0] - p0[0]) + g[1] * (cam->eye[1] - p0[1]) +
                  g[2] * (cam->eye[2] - p0[2]) < 0;
    }
    double minx = INFINITY, maxx = -INFINITY, miny = INFINITY, maxy = -INFINITY;
    for (int k = 0; k < 3; k++) {
        int c = order[k];
        s->x[k] = x[c];
        s->y[k] = y[c];
        s->iw[k] = iw[c];
        s->a[k][0] = m->uv[6 * tri + 2 * c] * iw[c];
        s->a[k][1] = m->uv[6 * tri + 2 * c + 1] * iw[c];
        const float *n = m->nrm + 3 * m->tri[3 * tri + c];
        for (int j = 0; j < 3; j++)
            s->a[k][2 + j] = n[j] * iw[c];
        minx = fmin(minx, x[c]);
        maxx = fmax(maxx, x[c]);
        miny = fmin(miny, y[c]);
        maxy = fmax(maxy, y[c]);
    }
    for (int k = 0; k < 3; k++) {
        int n = (k + 1) % 3;
        s->dx[k] = s->x[n] - s->x[k];
        s->dy[k] = s->y[n] - s->y[k];
        s->tl[k] = (s->dy[k] == 0 && s->dx[k] > 0) || s->dy[k] < 0;
    }
    /* samples lie within half a pixel of the centre */
    double bx0 = floor(minx - 1), by0 = floor(miny - 1), bx1 = ceil(maxx), by1 = ceil(maxy);
    if (bx1 < 0 || by1 < 0 || bx0 >= t->width || by0 >= t->height)
        return 0;
    s->x0 = bx0 < 0 ? 0 : (int)bx0;
    s->y0 = by0 < 0 ? 0 : (int)by0;
    s->x1 = bx1 >= t->width ? (int)t->width - 1 : (int)bx1;
    s->y1 = by1 >= t->height ? (int)t->height - 1 : (int)by1;
    return 1;
}

static inline double edge(const tri_setup *s, int k, double px, double py)
{
    return s->dx[k] * (py - s->y[k]) - s->dy[k] * (px - s->x[k]);
}

static inline int inside3(const tri_setup *s, const double e[3])
{
    for (int k = 0; k < 3; k++)
        if (!(e[k] > 0 || (e[k] == 0 && s->tl[k])))
            return 0;
    return 1;
}

/* Barycentric weights of vertices 0, 1, 2 from the edge values (edge k is opposite vertex
 * k + 2). */
static inline void bary(const tri_setup *s, const double e[3], double b[3])
{
    b[0] = e[1] / s->area;
    b[1] = e[2] / s->area;
    b[2] = e[0] / s->area;
}

/* Perspective-correct attributes at screen point (px, py); returns 1/w there. */
static double attrs_at(const tri_setup *s, double px, double py, double out[5])
{
    double e[3] = { edge(s, 0, px, py), edge(s, 1, px, py), edge(s, 2, px, py) }, b[3];
    bary(s, e, b);
    double iw = b[0] * s->iw[0] + b[1] * s->iw[1] + b[2] * s->iw[2];
    if (!(iw > 1e-30))
        iw = 1e-30;   /* a helper lane extrapolated past the horizon */
    for (int j = 0; j < 5; j++)
        out[j] = (b[0] * s->a[0][j] + b[1] * s->a[1][j] + b[2] * s->a[2][j]) / iw;
    return iw;
}

static void depth_pass(rr_target *t, const tri_setup *s, uint32_t tri, const int8_t *pat)
{
    unsigned ns = t->nsamp;
    for (int py = s->y0; py <= s->y1; py++)
        for (int px = s->x0; px <= s->x1; px++) {
            size_t base = ((size_t)py * t->width + (size_t)px) * ns;
            for (unsigned k = 0; k < ns; k++) {
                double sx = px + 0.5 + pat[2 * k] / 16.0, sy = py + 0.5 + pat[2 * k + 1] / 16.0;
                double e[3] = { edge(s, 0, sx, sy), edge(s, 1, sx, sy), edge(s, 2, sx, sy) };
                if (!inside3(s, e))
                    continue;
                double b[3];
                bary(s, e, b);
                float iw = (float)(b[0] * s->iw[0] + b[1] * s->iw[1] + b[2] * s->iw[2]);
                if (iw > t->depth[base + k]) {
                    t->depth[base + k] = iw;
                    t->owner[base + k] = tri;
                }
            }
        }
}

static int grow(rr_target *t)
{
    size_t nc = t->cap ? t->cap * 2 : 65536;
    rr_frag *f = realloc(t->frags, nc * sizeof *f);
    if (!f)
        return -1;
    t->frags = f;
    stc_query *q = realloc(t->queries, nc * sizeof *q);
    if (!q)
        return -1;
    t->queries = q;
    t->cap = nc;
    return 0;
}

static float light_term(const rc_camera *cam, const double a[5], int back)
{
    double n[3] = { a[2], a[3], a[4] };
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(l > 0))
        return 1.0f;
    if (back)   /* two-sided: the inside of a mesh seen through a hole is lit as seen */
        l = -l;
    /* a light from above and to the left of the camera */
    double L[3];
    for (int k = 0; k < 3; k++)
        L[k] = -cam->fwd[k] + 0.6 * cam->up[k] - 0.4 * cam->right[k];
    double ll = sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2]);
    double d = (n[0] * L[0] + n[1] * L[1] + n[2] * L[2]) / (l * ll);
    return (float)(0.3 + 0.7 * (d > 0 ? d : 0));
}

static int frag_pass(rr_target *t, const tri_setup *s, uint32_t tri, uint32_t face,
                     const rc_camera *cam, const int8_t *pat)
{
    unsigned ns = t->nsamp;
    for (int qy = s->y0 & ~1; qy <= s->y1; qy += 2)
        for (int qx = s->x0 & ~1; qx <= s->x1; qx += 2) {
            uint8_t vis[4] = { 0, 0, 0, 0 };
            int any = 0;
            for (int l = 0; l < 4; l++) {
                unsigned px = (unsigned)qx + (l & 1), py = (unsigned)qy + (l >> 1);
                if (px >= t->width || py >= t->height)
                    continue;
                const uint32_t *o = t->owner + ((size_t)py * t->width + px) * ns;
                for (unsigned k = 0; k < ns; k++)
                    if (o[k] == tri)
                        vis[l] |= (uint8_t)(1u << k);
                any |= vis[l];
            }
            if (!any)
                continue;
            /* every lane of the quad, helpers included, at its pixel centre */
            double c[4][5];
            for (int l = 0; l < 4; l++)
                attrs_at(s, qx + (l & 1) + 0.5, qy + (l >> 1) + 0.5, c[l]);
            for (int l = 0; l < 4; l++) {
                if (!vis[l]) {
                    t->helper_lanes++;
                    continue;
                }
                int row = l >> 1, col = l & 1;
                double dudx = c[2 * row + 1][0] - c[2 * row][0];
                double dvdx = c[2 * row + 1][1] - c[2 * row][1];
                double dudy = c[2 + col][0] - c[col][0];
                double dvdy = c[2 + col][1] - c[col][1];
                /* A helper lane past the plane's horizon (or within 1e-30 of it) is
                 * extrapolated to huge uv: derivatives of 1e26 and beyond, which the sampler
                 * refuses (BAD_FOOTPRINT over 1e4, NONFINITE once the float overflows). Scale
                 * the four together, keeping the footprint's shape, so that none exceeds
                 * RR_MAX_DERIV: the lookup then lands on the coarsest level, as a GPU's clamped
                 * LOD does. */
                double dmax = fmax(fmax(fabs(dudx), fabs(dvdx)), fmax(fabs(dudy), fabs(dvdy)));
                if (!(dmax <= RR_MAX_DERIV)) {
                    double k = isfinite(dmax) ? RR_MAX_DERIV / dmax : 0;
                    dudx *= k, dvdx *= k, dudy *= k, dvdy *= k;
                    t->clamped_derivs++;
                }
                double px = qx + col + 0.5, py = qy + row + 0.5;
                double e[3] = { edge(s, 0, px, py), edge(s, 1, px, py), edge(s, 2, px, py) };
                double a[5];
                uint8_t centroid = 0;
                if (inside3(s, e)) {
                    memcpy(a, c[l], sizeof a);
                } else {
                    /* centroid of the samples the triangle covers (visible or not) */
                    double sx = 0, sy = 0;
                    unsigned nc = 0;
                    for (unsigned k = 0; k < ns; k++) {
                        double x = px + pat[2 * k] / 16.0, y = py + pat[2 * k + 1] / 16.0;
                        double ek[3] = { edge(s, 0, x, y), edge(s, 1, x, y), edge(s, 2, x, y) };
                        if (inside3(s, ek)) {
                            sx += x;
                            sy += y;
                            nc++;
                        }
                    }
                    attrs_at(s, sx / nc, sy / nc, a);
                    centroid = 1;
                }
                if (t->nfrag == t->cap && grow(t) != 0)
                    return -1;
                rr_frag *f = &t->frags[t->nfrag];
                f->pixel = (uint32_t)((qy + row) * t->width + (unsigned)(qx + col));
                f->mask = vis[l];
                f->centroid = centroid;
                f->light = light_term(cam, a, s->back);
                t->queries[t->nfrag] = (stc_query){ face, (float)a[0], (float)a[1], (float)dudx,
                                                    (float)dvdx, (float)dudy, (float)dvdy };
                t->nfrag++;
            }
        }
    return 0;
}

int rr_rasterise(rr_target *t, const rm_mesh *m, const rc_camera *cam, char *msg, size_t ml)
{
    const int8_t *pat;
    rr_pattern(t->msaa, &pat);
    size_t n = (size_t)t->width * t->height * t->nsamp;
    memset(t->depth, 0, n * sizeof *t->depth);
    memset(t->owner, 0xff, n * sizeof *t->owner);
    t->nfrag = 0;
    t->helper_lanes = 0;
    t->clamped_derivs = 0;
    tri_setup s;
    for (uint32_t i = 0; i < m->ntris; i++)
        if (setup(t, m, cam, i, &s))
            depth_pass(t, &s, i, pat);
    for (uint32_t i = 0; i < m->ntris; i++)
        if (setup(t, m, cam, i, &s) && frag_pass(t, &s, i, m->face[i], cam, pat) != 0) {
            rt_say(msg, ml, "out of memory for %zu fragments", t->nfrag);
            return -1;
        }
    return 0;
}

void rr_resolve(const rr_target *t, const float *frag_rgba, const float bg[3], float *rgb)
{
    unsigned ns = t->nsamp;
    size_t np = (size_t)t->width * t->height;
    float inv = 1.0f / ns;
    for (size_t p = 0; p < np; p++) {
        unsigned empty = 0;
        for (unsigned k = 0; k < ns; k++)
            empty += t->owner[p * ns + k] == UINT32_MAX;
        for (int c = 0; c < 3; c++)
            rgb[3 * p + c] = bg[c] * (float)empty * inv;
    }
    for (size_t i = 0; i < t->nfrag; i++) {
        const rr_frag *f = &t->frags[i];
        float w = (float)__builtin_popcount(f->mask) * inv * f->light;
        for (int c = 0; c < 3; c++)
            rgb[3 * (size_t)f->pixel + c] += w * frag_rgba[4 * i + c];
    }
}
